"""The G and M codes flowmc knows, by modal group (LinuxCNC's groups), and why the others are refused."""

from __future__ import annotations

import math

__all__ = ["G_GROUP", "M_GROUP", "G_GROUP_NAMES", "M_GROUP_NAMES", "g_refusal", "m_refusal", "code_name",
           "AXIS_USERS", "CYCLES", "InterpError"]


class InterpError(Exception):
    """An error on the current line; the interpreter adds file and line."""


# G groups (LinuxCNC's numbers).
NONMODAL, MOTION, PLANE, DISTANCE, ARC_DISTANCE, FEED_MODE, UNITS, COMP, LENGTH, RETRACT, COORD, PATH, \
    SPINDLE_MODE, LATHE = 0, 1, 2, 3, 4, 5, 6, 7, 8, 10, 12, 13, 14, 15
G_GROUP_NAMES = {NONMODAL: "non-modal", MOTION: "motion", PLANE: "plane", DISTANCE: "distance mode",
                 ARC_DISTANCE: "arc distance mode", FEED_MODE: "feed mode", UNITS: "units",
                 COMP: "cutter compensation", LENGTH: "tool length offset", RETRACT: "canned-cycle return mode",
                 COORD: "coordinate system", PATH: "path control", SPINDLE_MODE: "spindle speed mode",
                 LATHE: "lathe diameter mode"}

#: Canned cycles (code * 10).
CYCLES = frozenset({730, 740, 810, 820, 830, 840, 850, 860, 870, 880, 890})

#: G code * 10 -> group, for every code flowmc runs.
G_GROUP: dict[int, int] = {}
for _codes, _group in (
    ((0, 10, 20, 30, 50, 51, 330, 331, 760, 800, 700, 710, 711, 712, 720, 721, 722, *CYCLES), MOTION),
    ((40, 100, 280, 281, 300, 301, 520, 530, 920, 921, 922, 923), NONMODAL),
    ((170, 180, 190), PLANE),
    ((900, 910), DISTANCE),
    ((901, 911), ARC_DISTANCE),
    ((930, 940, 950), FEED_MODE),
    ((200, 210), UNITS),
    ((400, 410, 411, 420, 421), COMP),
    ((430, 431, 432, 490), LENGTH),
    ((980, 990), RETRACT),
    ((540, 550, 560, 570, 580, 590, 591, 592, 593), COORD),
    ((610, 611, 640), PATH),
    ((960, 970), SPINDLE_MODE),
    ((70, 80), LATHE),
):
    for _code in _codes:
        G_GROUP[_code] = _group

#: Non-modal codes that take the line's axis words (a motion on the same line then may not).
AXIS_USERS = frozenset({100, 280, 300, 520, 920})

# M groups.
M_STOP, M_IO, M_TOOL, M_SPINDLE, M_COOLANT, M_OVERRIDE, M_STATE = 4, 5, 6, 7, 8, 9, 11
M_GROUP_NAMES = {M_STOP: "stopping", M_IO: "I/O", M_TOOL: "tool change", M_SPINDLE: "spindle",
                 M_COOLANT: "coolant", M_OVERRIDE: "override switches", M_STATE: "modal state"}
M_GROUP: dict[int, int] = {}
for _codes, _group in (
    ((0, 1, 2, 30, 60), M_STOP),
    ((62, 63, 64, 65, 67, 68), M_IO),
    ((6, 61), M_TOOL),
    ((3, 4, 5), M_SPINDLE),
    ((7, 8, 9), M_COOLANT),
    ((48, 49, 50, 51, 52, 53), M_OVERRIDE),
    ((70, 71, 72, 73), M_STATE),
):
    for _code in _codes:
        M_GROUP[_code] = _group

_G_REFUSED = [
    ((52, 53), "NURBS (G5.2/G5.3) are not supported: use the NURBS node"),
    ((382, 383, 384, 385), "probing (G38.x) is not supported: flowmc plans paths ahead of time and cannot "
                           "wait for a probe to trip"),
    ((171, 181, 191), "the UVW planes (G17.1, G18.1, G19.1) are not supported (flowmc paths have X, Y and Z)"),
    ((150, 160), "polar coordinates (G15/G16) are not supported"),
    ((681, 682), "plane rotation (G68) is not supported"),
]
_M_REFUSED = [
    ((19,), "spindle orientation (M19) is not supported"),
    ((66,), "waiting on inputs (M66) is not supported: flowmc plans paths ahead of time"),
    ((98, 99), "Fanuc-style subprograms (M98/M99) are not supported: use O-word subroutines"),
]


def code_name(letter: str, value: float) -> str:
    if math.isfinite(value) and abs(value - round(value)) < 1e-9:
        return f"{letter}{int(round(value))}"
    return f"{letter}{value:g}"


def g_refusal(value: float) -> str:
    name = code_name("G", value)
    code = round(value * 10) if math.isfinite(value) else -1
    if abs(value * 10 - code) < 1e-3:
        for codes, hint in _G_REFUSED:
            if code in codes:
                return f"{name} is not supported ({hint})"
    return f"{name} is not a G-code LinuxCNC or flowmc knows"


def m_refusal(value: float) -> str:
    name = code_name("M", value)
    if math.isfinite(value) and abs(value - round(value)) < 1e-4:
        code = int(round(value))
        if 100 <= code <= 199:
            return f"{name} is not supported (user-defined M codes run programs on the machine)"
        for codes, hint in _M_REFUSED:
            if code in codes:
                return f"{name} is not supported ({hint})"
    return f"{name} is not an M-code LinuxCNC or flowmc knows"
