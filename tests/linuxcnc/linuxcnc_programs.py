"""Programs and measures shared by the LinuxCNC tests: the reference paths, the machine, distances."""

import json
import os
from pathlib import Path as FsPath

import numpy as np

from flowmc.devices.linuxcnc.session import exclusive
from flowmc.motion.machine import Axis, Machine
from flowmc.motion.metrics import programmed_polyline
from flowmc.motion.path import Line, Path
from flowmc.motion.segment_table import path_from_rows

REFERENCE = FsPath(__file__).resolve().parents[1] / "data" / "reference"
TOL = 0.05
#: LinuxCNC 2.9's feed-move cycle times on the reference paths (the issue's measured figures).
MEASURED = {"mixed": 7.47, "star10": 11.89, "zigzag40": 10.95, "ellipse200": 5.27}
LINUXCNC_PROCESSES = {"linuxcnc", "linuxcncsvr", "milltask", "rtapi_app", "io", "halsampler", "halcmd"}


def machine() -> Machine:
    return Machine(axes=tuple(Axis(name=n, min=-500, max=500, vmax=200, amax=200) for n in "XYZ"), period=0.001)


def reference_path(name: str) -> Path:
    pts = np.array(json.loads((REFERENCE / "paths" / f"{name}.json").read_text())["points"], dtype=float)
    pts = np.c_[pts, np.zeros(len(pts))]
    return Path([Line(a, b, feed=200.0) for a, b in zip(pts[:-1], pts[1:])])


def thesis_path() -> Path:
    data = json.loads((REFERENCE / "thesis_pattern.json").read_text())
    return path_from_rows(data["segments"], start=data["start"], feed=200.0)


def distance_to(polyline: np.ndarray, points: np.ndarray, chunk: int = 1000) -> np.ndarray:
    """Distance from each point to the polyline (every segment tried, in chunks of points)."""
    a, b = polyline[:-1], polyline[1:]
    ab = b - a
    denom = np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-300)
    out = np.empty(len(points))
    for lo in range(0, len(points), chunk):
        q = points[lo:lo + chunk, None, :]
        t = np.clip(np.einsum("kij,ij->ki", q - a, ab) / denom, 0.0, 1.0)
        out[lo:lo + chunk] = np.linalg.norm(q - (a + t[..., None] * ab), axis=2).min(axis=1)
    return out


def programmed(path: Path) -> np.ndarray:
    """What the G-code programs: a traverse from home (the origin) to the start, then the path."""
    return np.vstack([np.zeros((1, 3)), programmed_polyline(path)])


def live_linuxcnc_processes() -> list[str]:
    """LinuxCNC's processes still running (zombies waiting for init to reap them do not count).

    Taken while holding flowmc's session lock, so a session another test process runs meanwhile
    cannot be mistaken for a stray of ours.
    """
    with exclusive(600.0):
        return running_now()


def running_now() -> list[str]:
    """LinuxCNC's live processes; the caller holds the session lock (``exclusive``)."""
    found = []
    for entry in os.scandir("/proc"):
        if entry.name.isdigit():
            try:
                stat = FsPath(f"/proc/{entry.name}/stat").read_text()
            except OSError:
                continue
            comm, state = stat[stat.index("(") + 1: stat.rindex(")")], stat[stat.rindex(")") + 2]
            if comm in LINUXCNC_PROCESSES and state != "Z":
                found.append(f"{entry.name} {comm}")
    return found
