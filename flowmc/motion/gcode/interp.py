"""The interpreter: LinuxCNC's RS274/NGC semantics, block by block, into machine-coordinate moves.

Each line is read (``lexer``), its values evaluated (``expr``, ``params``), its parameter settings
made, and its words executed in LinuxCNC's order of execution: comment/message, feed mode, F, S,
T, I/O (M62-M68), tool change (M6, M61), spindle, modal state (M70-M73), coolant, overrides,
dwell, plane, units, cutter compensation, tool length offset, coordinate system, path control,
distance mode, retract mode, non-modal codes (G10, G28, G30, G52, G53, G92...), motion, stop.

Positions: ``mx, my, mz`` is where the machine is (mm, machine coordinates); the program
position ``x, y, z`` is that point in the active coordinate system (mm): machine = rotate(program
+ G92/G52 offset, XY rotation) + G54..G59.3 offset + tool length offset, as LinuxCNC's canon layer
applies them. When an offset changes the machine stays put and the program position changes.
Cutter compensation (``comp``) and canned cycles (``cycles``) emit through the same move calls.
"""

from __future__ import annotations

import bisect
import math
import re
from dataclasses import dataclass

import flowmc.budget as budget
import flowmc.motion.gcode.codes as C
import flowmc.motion.gcode.expr as X
from flowmc.errors import GcodeError
from flowmc.motion.gcode.arcs import SPIRAL_WARN_MM, ArcError, centre_ijk, centre_r
from flowmc.motion.gcode.bodies import compile_body
from flowmc.motion.gcode.canon import Canon
from flowmc.motion.gcode.codegen import compile_block, value_function, value_list
from flowmc.motion.gcode.codes import InterpError
from flowmc.motion.gcode.expr import EvalError, evaluate
from flowmc.motion.gcode.fastpath import run_plain
from flowmc.motion.gcode.lathe import LATHE_CYCLES, run_g7x
from flowmc.motion.gcode.lexer import Block
from flowmc.motion.gcode.params import _COMPUTED, Parameters
from flowmc.motion.gcode.program import Source, read_program_file, subroutine_file
from flowmc.motion.gcode.templates import Templates
from flowmc.motion.gcode.threading_cycle import run_g76
from flowmc.motion.gcode.tools import Tool, ToolTable
from flowmc.motion.path import PLANES, PathEvent

__all__ = ["GcodeOptions", "Interpreter", "InterpError"]

_VERSION_MAJOR, _VERSION_MINOR = 2.9, 0.0
_MAX_CALL_LEVEL = 9  # rs274 2.9 runs 9 nested calls and refuses the 10th
_PLANE_CODE = {2: 170.0, 1: 180.0, 0: 190.0}
_UV = {k: PLANES[k][1] for k in PLANES}
_ACTIVE_COMMENT = re.compile(r"\s*(MSG|DEBUG|PRINT|LOGOPEN|LOGAPPEND|LOGCLOSE|LOG|PROBEOPEN|PROBECLOSE)\s*(,|$)",
                             re.IGNORECASE)
_COMMENT_PARAM = re.compile(r"#<([^>]*)>|#(\d+)")


@dataclass(frozen=True)
class GcodeOptions:
    """How to read a program.

    ``rapid_feed``: feed given to G0 moves (mm/s). ``block_delete``: skip lines starting with '/'.
    ``tool_table``: tools for T/M6/G43/G41 (none: every tool has zero length and diameter).
    ``parameters``: numbered parameters at start (a parameter file's, in machine units).
    ``machine_units_mm``: mm per machine unit, the unit of the parameter file's coordinate
    systems and homes (1: a mm machine; 25.4: inches, as LinuxCNC's standalone rs274).
    ``subroutine_dirs``: folders searched for ``<name>.ngc`` when ``o<name> call`` finds no
    definition. ``flood_output``/``mist_output``: digital outputs that M8/M7 switch (M9 both off).
    ``max_blocks``/``max_segments``: budgets against endless loops and runaway programs (None: from
    the memory budget, ``flowmc.budget``: the segments one node may make, and ten lines run per segment).
    """

    rapid_feed: float = 200.0
    block_delete: bool = False
    tool_table: ToolTable | None = None
    parameters: dict[int, float] | None = None
    machine_units_mm: float = 1.0
    subroutine_dirs: tuple = ()
    flood_output: int = 1
    mist_output: int = 2
    max_blocks: int | None = None
    max_segments: int | None = None
    max_warnings: int = 100


class _Frame:
    """One subroutine call: where to return, the caller's #1-#30 and locals, open loops (a plain
    class with slots: one is made for every call)."""

    __slots__ = ("source", "return_line", "saved", "locals", "label", "return_source", "loops", "autorestore",
                 "saved_state")

    def __init__(self, source: Source, return_line: int, saved: list, locals: dict, label, return_source: Source):
        self.source = source
        self.return_line = return_line
        self.saved = saved
        self.locals = locals
        self.label = label
        self.return_source = return_source
        self.loops: dict = {}
        self.autorestore: dict | None = None
        self.saved_state: dict | None = None


def _rotate(x: float, y: float, c: float, s: float) -> tuple[float, float]:
    return c * x - s * y, s * x + c * y


_UNREAD = Block()  # a line not in a file's cache yet


def _too_many_lines(limit: int) -> str:
    return (f"the program runs more than {limit} lines (an endless loop?); split it, or raise the memory "
            "budget (flowmc run --memory-mb, FLOWMC_MEMORY_MB) if it is meant to")


def _too_many_segments(limit: int) -> str:
    return (f"the program makes more than {limit:,} segments, over the budget: split it, or raise the memory "
            "budget (flowmc run --memory-mb, FLOWMC_MEMORY_MB) if it is meant to")


class Interpreter:
    """Runs one program. ``run(text, name)`` -> the Canon (columns of segments)."""

    def __init__(self, options: GcodeOptions):
        self.max_blocks = options.max_blocks or 10 * budget.cap("segments")
        self.options = options
        self.tools = options.tool_table or ToolTable()
        self.machine_mm = float(options.machine_units_mm)
        self.params = Parameters(self, options.parameters)
        self.canon = Canon(options.rapid_feed)
        self.sources: list[Source] = []
        self.frames: list[_Frame] = []
        self.loops: dict = {}  # top level's open loops
        self.warnings: list[tuple[str, str]] = []
        self.warning_count = 0
        self.messages: list[tuple[str, str]] = []
        self.blocks_run = 0
        self.ended = False
        self.subs: dict = {}  # label -> (source, line of 'sub')
        self.bodies: dict = {}  # (file index, line of 'sub') -> its compiled body, or None (see ``bodies``)
        self.value = 0.0
        self.value_returned = 0.0
        self.pending_message = ""
        self.saved_state: dict | None = None
        # Modal state.
        self.motion = 800  # no motion mode (code * 10), as LinuxCNC starts
        self.plane = 2
        self.scale = 1.0  # mm per program unit
        self.incremental = False
        self.arc_incremental = True
        self.feed_mode = 940
        self.feed_word = 0.0  # F as programmed (program units per minute, or 1/min in G93)
        self.feed = 0.0  # mm/s
        self.speed = 0.0
        self.spindle_dir = 0
        self.mist = False
        self.flood = False
        self.path_mode = 640
        self.retract_mode = 990  # LinuxCNC starts in G99 (retract to R)
        self.spindle_mode = 970
        self.diameter_mode = False
        self.comp_mode = 400
        self.comp = None  # flowmc.motion.gcode.comp.CutterComp while G41/G42 is on with a radius > 0
        self.arc_not_allowed = False
        self.warned_sync = False
        self.spline_ij = None
        self.slow_until = 0  # lines before this are read one by one (a run the fast path gave up on)
        self.extra_axes = None  # A/B/C/U/V/W words of the current line
        self.extra_pos: dict = {}
        self.tlo = [0.0, 0.0, 0.0]
        self.tlo_mode = 490
        self.current_tool = 0
        self.selected_tool = -1
        self.cycle = {}  # sticky canned-cycle words (mm / seconds)
        self.cycle_il = None  # the hole axis where a run of canned cycles started
        self.file_index = 0
        self.line_no = 0
        # Offsets (mm) and position.
        self.mx = self.my = self.mz = 0.0
        self.origin_index = 1
        self.g5x = [0.0, 0.0, 0.0]
        self.rotation = 0.0
        self._cos, self._sin = 1.0, 0.0
        self.g92 = [0.0, 0.0, 0.0]
        num = self.params.num
        index = int(round(num[5220])) if 1 <= num[5220] <= 9 else 1
        self._select_origin(index)
        if num[5210] == 1.0:
            self.g92 = [num[5211 + k] * self.machine_mm for k in range(3)]
        self._sync_program_position()

    def _tool(self, number: int) -> Tool | None:
        """A tool's table entry; without a tool table every tool is known, with zero length and size."""
        entry = self.tools.get(number)
        if entry is None and self.options.tool_table is None:
            return Tool(number, number)
        return entry

    # Positions and offsets --------------------------------------------------------------------
    def to_machine(self, x: float, y: float, z: float) -> tuple[float, float, float]:
        px, py = x + self.g92[0], y + self.g92[1]
        if self._sin != 0.0 or self._cos != 1.0:
            px, py = _rotate(px, py, self._cos, self._sin)
        return (px + self.g5x[0] + self.tlo[0], py + self.g5x[1] + self.tlo[1],
                z + self.g92[2] + self.g5x[2] + self.tlo[2])

    def to_program(self, mx: float, my: float, mz: float) -> tuple[float, float, float]:
        px, py = mx - self.g5x[0] - self.tlo[0], my - self.g5x[1] - self.tlo[1]
        if self._sin != 0.0 or self._cos != 1.0:
            px, py = _rotate(px, py, self._cos, -self._sin)
        return px - self.g92[0], py - self.g92[1], mz - self.g5x[2] - self.tlo[2] - self.g92[2]

    def _sync_program_position(self) -> None:
        self.x, self.y, self.z = self.to_program(self.mx, self.my, self.mz)

    def _set_rotation(self, degrees: float) -> None:
        self.rotation = degrees
        if degrees == 0.0:
            self._cos, self._sin = 1.0, 0.0
        else:
            r = math.radians(degrees)
            self._cos, self._sin = math.cos(r), math.sin(r)

    def _select_origin(self, index: int) -> None:
        base = 5201 + 20 * index
        num = self.params.num
        self.origin_index = index
        self.g5x = [num[base + k] * self.machine_mm for k in range(3)]
        self._set_rotation(num[base + 9])
        num[5220] = float(index)

    # Parameters the interpreter computes -------------------------------------------------------
    def computed(self, index: int) -> float:
        s = self.scale
        if 5420 <= index <= 5428:
            k = index - 5420
            return (self.x, self.y, self.z)[k] / s if k < 3 else 0.0
        if 5021 <= index <= 5029:
            k = index - 5021
            return (self.mx, self.my, self.mz)[k] / s if k < 3 else 0.0
        if 5081 <= index <= 5089:
            k = index - 5081
            return self.tlo[k] / s if k < 3 else 0.0
        tool = self._tool(self.current_tool) or Tool(self.current_tool)
        if index == 5400:
            return float(self.current_tool)
        if 5401 <= index <= 5409:
            k = index - 5401
            return tool.offset[k] / self.machine_mm if k < 3 else 0.0
        if index == 5410:
            return tool.diameter / self.machine_mm
        if index == 5411:
            return tool.front_angle
        if index == 5412:
            return tool.back_angle
        if index == 5413:
            return float(tool.orientation)
        return 0.0

    def predefined(self, name: str) -> float | None:
        if name == "_value":  # read after every call that returns one: answered first
            return self.value
        s = self.scale
        simple = {
            "_vmajor": _VERSION_MAJOR, "_vminor": _VERSION_MINOR, "_line": float(self.line_no),
            "_motion_mode": float(self.motion), "_plane": _PLANE_CODE[self.plane], "_ccomp": float(self.comp_mode),
            "_metric": float(s == 1.0), "_imperial": float(s != 1.0), "_absolute": float(not self.incremental),
            "_incremental": float(self.incremental), "_inverse_time": float(self.feed_mode == 930),
            "_units_per_minute": float(self.feed_mode == 940), "_units_per_rev": float(self.feed_mode == 950),
            "_coord_system": (540.0, 550.0, 560.0, 570.0, 580.0, 590.0, 591.0, 592.0, 593.0)[self.origin_index - 1],
            "_tool_offset": float(self.tlo_mode != 490), "_retract_r_plane": float(self.retract_mode == 990),
            "_retract_old_z": float(self.retract_mode == 980), "_spindle_rpm_mode": float(self.spindle_mode == 970),
            "_spindle_css_mode": float(self.spindle_mode == 960),
            "_ijk_absolute_mode": float(not self.arc_incremental),
            "_lathe_diameter_mode": float(self.diameter_mode), "_lathe_radius_mode": float(not self.diameter_mode),
            "_spindle_on": float(self.spindle_dir != 0), "_spindle_cw": float(self.spindle_dir > 0),
            "_mist": float(self.mist), "_flood": float(self.flood), "_speed_override": 1.0, "_feed_override": 1.0,
            "_adaptive_feed": 0.0, "_feed_hold": 0.0, "_feed": self.feed_word, "_rpm": self.speed,
            "_x": self.x / s, "_y": self.y / s, "_z": self.z / s, "_a": 0.0, "_b": 0.0, "_c": 0.0, "_u": 0.0,
            "_v": 0.0, "_w": 0.0, "_abs_x": self.mx / s, "_abs_y": self.my / s, "_abs_z": self.mz / s,
            "_abs_a": 0.0, "_abs_b": 0.0, "_abs_c": 0.0, "_abs_u": 0.0, "_abs_v": 0.0, "_abs_w": 0.0,
            "_current_tool": float(self.current_tool), "_current_pocket": float(self.current_tool),
            "_selected_tool": float(self.selected_tool), "_selected_pocket": float(self.selected_tool),
            "_value": self.value, "_value_returned": self.value_returned, "_task": 0.0,
            "_call_level": float(len(self.frames)), "_remap_level": 0.0,
        }
        return simple.get(name)

    def call_level(self) -> int:
        return len(self.frames)

    # Messages and warnings ---------------------------------------------------------------------
    def warn(self, where: str, message: str) -> None:
        self.warning_count += 1
        if len(self.warnings) < self.options.max_warnings:
            self.warnings.append((where, message))

    # Running -----------------------------------------------------------------------------------
    def run(self, text: str, name: str) -> Canon:
        main = Source(name, 0, text)
        self.sources.append(main)
        self.src = main
        self.pc = main.first
        self._loop()
        return self.canon

    def _error(self, src: Source, line: int, message: str) -> GcodeError:
        err = src.error(line, message)
        if self.frames:
            chain = ", ".join(f.return_source.where(f.return_line - 1) for f in reversed(self.frames[-3:]))
            err = GcodeError(f"{err.message} [called from {chain}]", where=err.where)
        return err

    def _loop(self) -> None:
        max_segments = self.max_segments = self.options.max_segments or budget.cap("segments")
        self.max_blocks = self.options.max_blocks or 10 * budget.cap("segments")
        block_delete = self.options.block_delete
        canon = self.canon
        templates = Templates(self.params, _COMPUTED)
        main = self.sources[0]
        run_ends = main.plain_run_ends() if len(main.lines) >= _FAST_MIN_LINES else None
        while not self.ended:
            src = self.src
            i = self.pc
            if i >= src.end:
                if self.frames:
                    frame = self.frames[-1]
                    raise self._error(src, src.end - 1 if src.end else 0,
                                      f"the file ends inside subroutine o{_label_text(frame.label)} "
                                      f"(its endsub is missing)")
                if self.loops:
                    label, (kind, at) = next(iter(self.loops.items()))
                    raise self._error(src, at, f"the file ends inside 'o{_label_text(label)} {kind}' "
                                               f"(its closing O-word is missing)")
                self._finish(src, max(src.end - 1, 0))
                return
            if run_ends is not None and run_ends[i] - i >= _FAST_MIN_RUN and i >= self.slow_until \
                    and not self.frames and not self.loops and src is main and self._fast_ready():
                stop = min(run_ends[i], (i // _FAST_MAX_RUN + 1) * _FAST_MAX_RUN)  # a fixed grid: reread tokens stay cached
                done = run_plain(self, src, i, stop)
                if done < 0:
                    self.slow_until = stop
                elif done:
                    self.pc = i + done
                    self.blocks_run += done
                    if len(canon) > max_segments:
                        raise self._error(src, i + done - 1, _too_many_segments(max_segments))
                    continue
            self.pc = i + 1
            if self.frames or self.loops:
                block = src.cache.get(i, _UNREAD)
                if block is _UNREAD:
                    block = self.cached_block(src, i)
            else:
                if src is main and self._run_top(src, i, templates, run_ends):
                    continue
                block = templates.block(src, i)
                if block is None:
                    block = src.parse(i)
            if block is None:
                continue
            if block.delete and block_delete:
                continue
            self.blocks_run += 1
            if self.blocks_run > self.max_blocks:
                raise self._error(src, i, _too_many_lines(self.max_blocks))
            self.line_no = i + 1
            self.file_index = src.index
            self._run_line(block, src, i)
            if canon.sealed + len(canon.kind) > max_segments:
                raise self._error(src, i, _too_many_segments(max_segments))

    def _run_top(self, src: Source, i: int, templates: Templates, run_ends) -> int:
        """Top-level lines from ``i`` through their templates in one Python loop, not one trip round the
        main loop a line: moves, settings and calls of compiled subroutines, each with the main loop's
        line and segment budgets, line number and errors. Stops (returning how many lines it ran, with
        ``pc`` past them) before a line it does not take, the start of a plain run, or the end of the
        chunk; after a call that leaves a frame open, and at the program's end."""
        first, keys, numbers, ends = templates.split(src, i)[1:]
        stop = min(first + len(keys), src.end)
        if self.options.block_delete or self.loops:
            return 0
        canon, max_blocks, max_segments = self.canon, self.max_blocks, self.max_segments
        shapes, shape_of = templates.shapes, templates.shape
        done = 0
        for j in range(i, stop):
            key = keys[j - first]
            if key is None or (run_ends is not None and run_ends[j] - j >= _FAST_MIN_RUN):
                break
            shape = shapes.get(key)
            if shape is None:
                shape = shape_of(key)  # a new shape compiled, or None again: a shape not taken
            if shape is None:
                break
            block, slots = shape
            oword = block.oword
            if block.delete or (oword is not None and oword[1] != "call"):
                break
            if slots is not None:
                end = ends[j - first]
                slots[:] = numbers[end - len(slots):end]
            self.pc = j + 1
            done += 1
            self.blocks_run += 1
            if self.blocks_run > max_blocks:
                raise self._error(src, j, _too_many_lines(max_blocks))
            self.line_no = j + 1
            self.file_index = src.index
            self._run_line(block, src, j)
            if canon.sealed + len(canon.kind) > max_segments:
                raise self._error(src, j, _too_many_segments(max_segments))
            if self.ended or self.frames or self.loops:
                break
        return done

    def _run_line(self, block: Block, src: Source, i: int) -> None:
        """Line i's block: an O-word (a call runs its body), a compiled line, or a parsed one; its errors name the line."""
        try:
            if block.oword is not None:
                self._oword(block, src, i)
                if block.oword[1] == "call":
                    self._run_body()
            elif block.run is not None:
                rest = block.run(self, src, i, True)
                if rest is not None:
                    words, gvals, mvals = rest
                    self._run_values(block, words, gvals, mvals, src, i)
            else:
                self._block(block, src, i)
        except (InterpError, EvalError, ArcError) as exc:  # CompError is an InterpError
            raise self._error(src, i, str(exc)) from None

    def cached_block(self, src: Source, i: int) -> Block | None:
        """Line i of src parsed and, when it has values to work out or is an O-word, compiled; kept,
        as a loop or a subroutine runs it again."""
        block = src.cache.get(i, _UNREAD)
        if block is _UNREAD:
            block = src.parse(i)
            if block is not None and (not block.const or block.oword is not None):
                self._compile(block)
            src.cache[i] = block
        return block

    def _run_body(self) -> None:
        """Right after a call: the subroutine's body as one compiled function when it has one."""
        src, at = self.src, self.pc - 1
        key = (src.index, at)
        body = self.bodies.get(key, _UNREAD)
        if body is _UNREAD:
            body = self.bodies[key] = compile_body(self, src, at, self.frames[-1].label, _COMPUTED)
        if body is not None:
            body(self, src)

    def over_lines(self, src: Source, i: int) -> GcodeError:
        return self._error(src, i, _too_many_lines(self.max_blocks))

    def over_segments(self, src: Source, i: int) -> GcodeError:
        return self._error(src, i, _too_many_segments(self.max_segments))

    def count_block(self, src: Source, i: int) -> None:
        """One more line run; the budget stops endless loops."""
        self.blocks_run += 1
        if self.blocks_run > self.max_blocks:
            raise self._error(src, i, _too_many_lines(self.max_blocks))

    def _fast_ready(self) -> bool:
        """Whether a run of plain lines may be read at once (nothing special in force)."""
        canon = self.canon
        return (self.comp_mode == 400 and self.feed_mode == 940 and not self.diameter_mode and self.rotation == 0.0
                and not self.arc_not_allowed and not (canon.sync_out or canon.sync_an or canon.now_out
                                                      or canon.now_an))

    def _compile(self, block) -> None:
        """Turn a kept line into a generated function (it will run again: a loop or a subroutine)."""
        params, computed = self.params, _COMPUTED
        if block.oword is not None:
            label, keyword, args = block.oword
            label = label if type(label) in (str, int) else value_function(label, params, computed)
            if keyword == "call":  # its arguments are read by ``run`` only, in one function
                block.oword = (label, keyword, args)
                block.run = value_list(args, params, computed)
            else:
                block.oword = (label, keyword, [value_function(a, params, computed) for a in args])
        else:
            block.run = compile_block(block, params, computed)

    def _finish(self, src: Source, line: int) -> None:
        if self.comp is not None:
            self.comp.flush()
        self.canon.finish(self.feed, self._spindle_rpm(), src.index, line + 1)
        self.ended = True

    # O-words ------------------------------------------------------------------------------------
    def _label(self, label):
        if type(label) is str or type(label) is int:
            return label
        return X.label_number(evaluate(label, self.params))

    def _read_oword_line(self, src: Source, k: int) -> Block | None:
        """A line found while looking for O-words, parsed, compiled (loops pass it again) and kept."""
        block = src.parse(k)
        if block is not None and block.oword is not None:
            self._compile(block)
        src.cache[k] = block
        return block

    def _oword_at(self, src: Source, k: int):
        """(label, keyword) of the O-word on line k of src, or None."""
        block = src.cache.get(k, _UNREAD)
        if block is _UNREAD:
            block = self._read_oword_line(src, k)
        if block is None or block.oword is None:
            return None
        return self._label(block.oword[0]), block.oword[1]

    def _scan(self, src: Source, start: int, label, keywords: tuple) -> tuple[int, str]:
        """The next line at or after ``start`` with an O-word of ``label`` and a keyword in ``keywords``
        (remembered per file when every label on the way is a constant, as loops ask again)."""
        memo_key = (start, label, keywords)
        found = src.scans.get(memo_key)
        if found is not None:
            return found
        lines = src.oword_lines()
        constant = True
        for j in range(bisect.bisect_left(lines, start), len(lines)):
            k = lines[j]
            block = src.cache.get(k, _UNREAD)
            if block is _UNREAD:
                block = self._read_oword_line(src, k)
            if block is None or block.oword is None:
                continue
            raw = block.oword[0]
            if type(raw) is not str and type(raw) is not int:
                constant = False
            if self._label(raw) == label and block.oword[1] in keywords:
                if constant:
                    src.scans[memo_key] = (k, block.oword[1])
                return k, block.oword[1]
        raise InterpError(f"no matching 'o{_label_text(label)} {' / '.join(keywords)}' follows")

    def _open_loops(self) -> dict:
        return self.frames[-1].loops if self.frames else self.loops

    def _oword(self, block, src: Source, i: int) -> None:
        label_node, keyword, args = block.oword
        label = self._label(label_node)
        if keyword == "call":
            run = block.run  # a compiled call's arguments in one call
            self._call(label, run() if run is not None else [evaluate(a, self.params) for a in args], src, i)
            return
        loops = self._open_loops()
        if keyword == "sub":
            if label not in self.subs:
                self.subs[label] = (src, i)
            end, _ = self._scan(src, i + 1, label, ("endsub",))
            self.pc = end + 1
            return
        if keyword in ("endsub", "return"):
            if not self.frames or self.frames[-1].label != label:
                if keyword == "return" and self.frames:
                    raise InterpError(f"'o{_label_text(label)} return' inside subroutine "
                                      f"o{_label_text(self.frames[-1].label)}")
                raise InterpError(f"'o{_label_text(label)} {keyword}' outside its subroutine")
            value = evaluate(args[0], self.params) if args else None
            self._return(value)
            return
        if keyword == "if":
            if evaluate(args[0], self.params) != 0.0:
                return
            self._skip_if(src, i + 1, label)
            return
        if keyword in ("elseif", "else"):
            # Reached from a branch that ran: skip to endif.
            end, _ = self._scan(src, i + 1, label, ("endif",))
            self.pc = end + 1
            return
        if keyword == "endif":
            return
        if keyword == "do":
            loops[label] = ("do", i)
            return
        if keyword == "while":
            opened = loops.get(label)
            if opened is not None and opened[0] == "do" and opened[1] < i:
                if evaluate(args[0], self.params) != 0.0:
                    self.pc = opened[1] + 1
                else:
                    del loops[label]
                return
            if evaluate(args[0], self.params) != 0.0:
                loops[label] = ("while", i)
                return
            loops.pop(label, None)
            end, _ = self._scan(src, i + 1, label, ("endwhile",))
            self.pc = end + 1
            return
        if keyword == "endwhile":
            opened = loops.get(label)
            if opened is None or opened[0] != "while":
                raise InterpError(f"'o{_label_text(label)} endwhile' without its while")
            self.pc = opened[1]
            return
        if keyword == "repeat":
            opened = loops.get(label)
            if opened is None or opened[0] != "repeat" or opened[1] != i:
                count = evaluate(args[0], self.params)
                remaining = int(math.floor(count + 0.5)) if count > 0 else 0
                if remaining <= 0:
                    end, _ = self._scan(src, i + 1, label, ("endrepeat",))
                    self.pc = end + 1
                    return
                loops[label] = ("repeat", i, remaining)
            return
        if keyword == "endrepeat":
            opened = loops.get(label)
            if opened is None or opened[0] != "repeat":
                raise InterpError(f"'o{_label_text(label)} endrepeat' without its repeat")
            remaining = opened[2] - 1
            if remaining > 0:
                loops[label] = ("repeat", opened[1], remaining)
                self.pc = opened[1] + 1
            else:
                del loops[label]
            return
        if keyword in ("break", "continue"):
            opened = loops.get(label)
            if opened is None:
                raise InterpError(f"'o{_label_text(label)} {keyword}' outside a loop with that label")
            kind = opened[0]
            if keyword == "continue":
                if kind == "while":
                    self.pc = opened[1]
                elif kind == "do":
                    end, _ = self._scan(src, i + 1, label, ("while",))
                    self.pc = end
                else:
                    end, _ = self._scan(src, i + 1, label, ("endrepeat",))
                    self.pc = end
                return
            closer = {"while": ("endwhile",), "do": ("while",), "repeat": ("endrepeat",)}[kind]
            end, _ = self._scan(src, i + 1, label, closer)
            del loops[label]
            self.pc = end + 1
            return
        raise InterpError(f"unknown O-word keyword {keyword!r}")

    def _skip_if(self, src: Source, start: int, label) -> None:
        """A false condition: on to the next elseif that holds, the else, or past endif."""
        k = start
        while True:
            at, key = self._scan(src, k, label, ("elseif", "else", "endif"))
            if key == "endif":
                self.pc = at + 1
                return
            if key == "else":
                self.pc = at + 1
                return
            block = src.cache.get(at) or src.parse(at)
            self.line_no = at + 1
            try:
                holds = evaluate(block.oword[2][0], self.params) != 0.0
            except EvalError as exc:
                raise self._error(src, at, str(exc)) from None
            if holds:
                self.pc = at + 1
                return
            k = at + 1

    def _find_sub(self, label, src: Source) -> tuple[Source, int]:
        found = self.subs.get(label)
        if found is not None:
            return found
        # Defined further down the calling file (LinuxCNC looks ahead for it).
        for source in {id(s): s for s in (src, self.sources[0])}.values():
            for k in source.oword_lines():
                at = self._oword_at(source, k)
                if at is not None and at[0] == label and at[1] == "sub":
                    self.subs[label] = (source, k)
                    return source, k
        name = label if isinstance(label, str) else str(label)
        path = subroutine_file(name, self.options.subroutine_dirs)
        if path is None:
            folders = ", ".join(str(f) for f in self.options.subroutine_dirs) or "none configured"
            raise InterpError(f"subroutine o{_label_text(label)} is not defined here, and no file {name}.ngc "
                              f"is in the subroutine folders ({folders})")
        text = read_program_file(path, path.name)
        source = Source(path.name, len(self.sources), text)
        self.sources.append(source)
        for k in source.oword_lines():
            at = self._oword_at(source, k)
            if at is not None and at[0] == label and at[1] == "sub":
                self.subs[label] = (source, k)
                return source, k
        raise InterpError(f"{path.name} does not define 'o{_label_text(label)} sub'")

    def _call(self, label, args: list[float], src: Source, i: int) -> None:
        if len(self.frames) >= _MAX_CALL_LEVEL:
            raise InterpError(f"too many nested subroutine calls (LinuxCNC allows {_MAX_CALL_LEVEL})")
        source, at = self._find_sub(label, src)
        num = self.params.num
        saved = num[1:31]
        num[1:len(args) + 1] = args
        frame = _Frame(source, i + 1, saved, self.params.locals, label, src)
        self.params.locals = {}
        self.value = 0.0
        self.value_returned = 0.0
        self.frames.append(frame)
        self.src = source
        self.pc = at + 1

    def _return(self, value) -> None:
        frame = self.frames.pop()
        self.params.num[1:31] = frame.saved
        self.params.locals = frame.locals
        if value is not None:
            self.value = value
            self.value_returned = 1.0
        if frame.autorestore is not None:
            self._restore_state(frame.autorestore)
        self.src = frame.return_source
        self.pc = frame.return_line

    # Blocks -------------------------------------------------------------------------------------
    def _block(self, b, src: Source, i: int) -> None:
        words, gvals, mvals = self.values(b)
        self._run_values(b, words, gvals, mvals, src, i)

    def _run_values(self, b, words: dict, gvals: list, mvals: list, src: Source, i: int) -> None:
        """A block's evaluated words and G and M values, its settings made."""
        if b.comment is not None:
            self._comment(b.comment, src, i)
        if not words and not gvals and not mvals:
            return
        if not mvals and len(gvals) <= 1 and self.comp_mode == 400 and self.feed_mode == 940 and not self.diameter_mode:
            keys = words.keys()
            if keys <= _XYZF:
                if self._fast_move(words, gvals, src, i):
                    return
            elif keys <= _ARC_WORDS and self._fast_arc(words, gvals, src, i):
                return
        for value in words.values():
            if value != value or value in (math.inf, -math.inf):
                raise InterpError("number too large")
        # G and M codes by group.
        g = {}
        for value in gvals:
            code = _code10(value, "G")
            group = C.G_GROUP.get(code)
            if group is None:
                raise InterpError(C.g_refusal(value))
            if group in g:
                raise InterpError(f"two G codes from the same group ({C.G_GROUP_NAMES[group]}) on one line")
            g[group] = code
        m = {}
        if mvals:
            if len(mvals) > 4:
                raise InterpError("more than four M words on one line")
            for value in mvals:
                code = _int_code(value, "M")
                group = C.M_GROUP.get(code)
                if group is None:
                    raise InterpError(C.m_refusal(value))
                if group in m and not (group == C.M_COOLANT and {m[group], code} == {7, 8}):
                    raise InterpError(f"two M codes from the same group ({C.M_GROUP_NAMES[group]}) on one line")
                if group == C.M_COOLANT and group in m:
                    m[group] = 78
                else:
                    m[group] = code
        extra = None
        for letter in words:
            if letter in "ABCUVW" and g.get(C.MOTION) not in LATHE_CYCLES:  # G7x take U, W, A and C
                extra = {k: v for k, v in words.items() if k in "ABCUVW"}
                words = {k: v for k, v in words.items() if k not in "ABCUVW"}
                break
        self.extra_axes = extra
        self._execute(words, g, m, src, i)
        if self.extra_axes:
            self._index_axes(None, src, i)

    def values(self, b) -> tuple[dict, list, list]:
        """A block's words, G and M values, evaluated; its parameter assignments done."""
        params = self.params
        if b.const:
            words, gvals, mvals = b.words, b.g, b.m
            assigns = b.assign
        elif b.run is not None:
            return b.run(self, None, 0, False)
        else:
            words = {k: (v if type(v) is float else v() if type(v) is not tuple else evaluate(v, params))
                     for k, v in b.words.items()}
            gvals = [v if type(v) is float else evaluate(v, params) for v in b.g]
            mvals = [v if type(v) is float else evaluate(v, params) for v in b.m]
            assigns = [(t if type(t) is not tuple else X.param_index(evaluate(t[1], params)),
                        v if type(v) is float else evaluate(v, params)) for t, v in b.assign]
        if assigns:
            for target, value in assigns:
                if value - value != 0.0:
                    raise InterpError("number too large (a parameter cannot hold it)")
                if type(target) is int:
                    params.set_number(target, value)
                else:
                    params.set_named(target, value)
        return words, gvals, mvals

    def _index_axes(self, target, src: Source, i: int, motion: int | None = None) -> None:
        """A, B, C, U, V, W words. flowmc paths have X, Y and Z: a word that leaves its axis where it is
        does nothing; a G0/G1 that moves only such axes is an indexing move, and becomes a pause
        event asking for the axis to be indexed (as an operator does for a manual indexer); any
        other motion of them is refused."""
        words, self.extra_axes = self.extra_axes, None
        moves = {}
        for letter, value in words.items():
            now = self.extra_pos.get(letter, 0.0)
            new = now + value if self.incremental else value
            if letter in "UVW":
                new_units = new * self.scale
            else:
                new_units = new
            if new_units != now:
                moves[letter] = new_units
        if not moves:
            if target is not None:
                self._straight(*target, motion == 0, src, i)  # G0 B0 where B is: a zero-length move
            return
        if target is None or motion not in (0, 10) or target != (self.x, self.y, self.z):
            what = " ".join(f"{k}{v:g}" for k, v in moves.items())
            raise InterpError(f"axis {next(iter(moves))} is not supported: flowmc paths have X, Y and Z, and {what} "
                              f"would move it with them (only a G0/G1 that moves nothing but a rotary axis is "
                              f"taken, as an indexing stop)")
        self.extra_pos.update(moves)
        what = ", ".join(f"{k} to {v:g}{' deg' if k in 'ABC' else ' mm'}" for k, v in moves.items())
        self.canon.dwell(0.0, self.feed, self._spindle_rpm(), src.index, i + 1,
                         PathEvent("index", f"index {what}: flowmc has no such axis, so the job stops for it",
                                   axes=tuple(sorted(self.extra_pos.items()))))

    def _fast_motion(self, gvals: list, codes: dict) -> int | None:
        """The motion of a line with at most one G code when it is one of ``codes`` (G value ->
        motion mode), or, without a G code, when the mode in force is; else None."""
        if gvals:
            return codes.get(gvals[0])
        return self.motion if self.motion in codes.values() else None

    def _fast_feed(self, w: dict) -> None:
        """A fast line's words are finite numbers; its F word sets the feed (G94)."""
        for value in w.values():
            if value - value != 0.0:
                raise InterpError("number too large")
        if "F" in w:
            f = w["F"]
            if f < 0:
                raise InterpError("negative F word (feed)")
            self.feed_word = f
            self.feed = f * self.scale / 60.0

    def _fast_move(self, w: dict, gvals: list, src: Source, i: int) -> bool:
        """The common block, G0/G1 with X/Y/Z/F words only, without the full order of execution;
        False leaves the block to ``_execute``."""
        motion = self._fast_motion(gvals, _STRAIGHT)
        if motion is None:
            return False
        self._fast_feed(w)
        scale = self.scale
        has_axis = "X" in w or "Y" in w or "Z" in w
        if not gvals and not has_axis:
            return True
        x, y, z = self.x, self.y, self.z
        if self.incremental:
            if "X" in w:
                x += w["X"] * scale
            if "Y" in w:
                y += w["Y"] * scale
            if "Z" in w:
                z += w["Z"] * scale
        else:
            if "X" in w:
                x = w["X"] * scale
            if "Y" in w:
                y = w["Y"] * scale
            if "Z" in w:
                z = w["Z"] * scale
        if motion == 10 and not self.feed > 0:
            raise InterpError("G1 with no feed rate: program an F word first")
        self.arc_not_allowed = False
        self.cycle_il = None
        self._straight(x, y, z, motion == 0, src, i)
        self.motion = motion
        return True

    def _fast_arc(self, w: dict, gvals: list, src: Source, i: int) -> bool:
        """G2/G3 with X/Y/Z, I/J/K or R, F and P words only (the rest of ``_execute`` has nothing to
        do for it); False leaves the block to ``_execute``."""
        motion = self._fast_motion(gvals, _ARCS)
        if motion is None or not (gvals or "X" in w or "Y" in w or "Z" in w):
            return False
        self._fast_feed(w)
        self.cycle_il = None
        self._arc(motion == 30, w, src, i)
        self.motion = motion
        return True

    def _comment(self, text: str, src: Source, i: int) -> None:
        match = _ACTIVE_COMMENT.match(text)
        if match is None:
            return
        kind = match.group(1).upper()
        body = text[match.end():]
        where = src.where(i)
        if kind == "MSG":
            self.messages.append((where, body.strip()))
            self.pending_message = body.strip()
        elif kind in ("DEBUG", "PRINT"):
            self.messages.append((where, self._expand(body).strip()))
        # LOG*/PROBE* would write files on the machine: a program read here never writes files.

    def _expand(self, text: str) -> str:
        def value(match):
            try:
                if match.group(1) is not None:
                    return f"{self.params.named(match.group(1).replace(' ', '').lower()):.6f}"
                index = int(match.group(2))
                return f"{self.params.number(index):.6f}" if 1 <= index <= X.NUM_PARAMS else match.group(0)
            except EvalError:
                return "######"
        return _COMMENT_PARAM.sub(value, text)

    def _spindle_rpm(self) -> float:
        return self.speed * self.spindle_dir + 0.0

    def _execute(self, w: dict, g: dict, m: dict, src: Source, i: int) -> None:
        """One block's words, in LinuxCNC's order of execution."""
        scale = self.scale
        canon = self.canon
        # 3. feed mode; 4. F; 5. S.
        feed_mode = g.get(C.FEED_MODE)
        if feed_mode is not None:
            self.feed_mode = feed_mode
            if feed_mode != 930:  # LinuxCNC zeroes the feed rate on G94 and G95
                self.feed_word = 0.0
                self.feed = 0.0
        if "F" in w:
            f = w["F"]
            if f < 0:
                raise InterpError("negative F word (feed)")
            self.feed_word = f
            if self.feed_mode == 940:
                self.feed = f * scale / 60.0
        if "S" in w:
            s = w["S"]
            if s < 0:
                raise InterpError("negative S word (spindle speed)")
            self.speed = s
        if self.feed_mode == 950:
            self.feed = self.feed_word * scale * self.speed / 60.0
        # 6. T.
        if "T" in w:
            tool = _integer(w["T"], "tool number (T)")
            if tool < 0:
                raise InterpError("tool number (T) must be >= 0")
            if tool != 0 and self._tool(tool) is None:
                raise InterpError(f"tool T{tool} is not in the tool table")
            self.selected_tool = tool
        # 7. I/O.
        io = m.get(C.M_IO)
        if io is not None:
            self._io(io, w)
        # 8. Tool change.
        change = m.get(C.M_TOOL)
        if change == 6:
            self._tool_change(src, i)
        elif change == 61:
            if "Q" not in w:
                raise InterpError("M61 needs a Q word (the tool now in the spindle)")
            tool = _integer(w["Q"], "M61 tool number (Q)")
            if tool < 0 or (tool != 0 and self._tool(tool) is None):
                raise InterpError(f"tool T{tool} is not in the tool table")
            self.current_tool = tool
            self._synch()
        # 9. Spindle.
        spin = m.get(C.M_SPINDLE)
        if spin is not None:
            self.spindle_dir = {3: 1, 4: -1, 5: 0}[spin]
        # 10. Modal state.
        state = m.get(C.M_STATE)
        if state is not None:
            self._modal_state(state)
        # 11. Coolant.
        cool = m.get(C.M_COOLANT)
        if cool is not None:
            self._coolant(cool, i)
        # 14. Dwell.
        nonmodal = g.get(C.NONMODAL)
        if nonmodal == 40:
            if "P" not in w:
                raise InterpError("G4 needs a P word (seconds)")
            if w["P"] < 0:
                raise InterpError("G4 dwell time (P) must be >= 0 seconds")
            seconds, feed, rpm = w["P"], self.feed, self._spindle_rpm()

            def dwell(seconds=seconds, feed=feed, rpm=rpm, file=src.index, line=i + 1):
                canon.dwell(seconds, feed, rpm, file, line)

            if self.comp is None or not self.comp.hold(dwell):
                dwell()
        # 15. Plane; 16. units.
        plane = g.get(C.PLANE)
        if plane is not None:
            new_plane = {170: 2, 180: 1, 190: 0}[plane]
            if self.comp_mode != 400 and new_plane != self.plane:
                raise InterpError("the plane cannot change while cutter compensation is on")
            self.plane = new_plane
        units = g.get(C.UNITS)
        if units is not None:
            new_scale = 25.4 if units == 200 else 1.0
            if new_scale != scale:
                self._change_units(new_scale)
                scale = new_scale
        lathe = g.get(C.LATHE)
        if lathe is not None:
            self.diameter_mode = lathe == 70
        # 17. Cutter compensation.
        comp = g.get(C.COMP)
        if comp is not None:
            self._set_comp(comp, w)
        # 18. Tool length offset.
        length = g.get(C.LENGTH)
        if length is not None:
            self._tool_length(length, w)
        # 19. Coordinate system.
        coord = g.get(C.COORD)
        if coord is not None:
            if self.comp_mode != 400:
                raise InterpError("the coordinate system cannot change while cutter compensation is on")
            index = (540, 550, 560, 570, 580, 590, 591, 592, 593).index(coord) + 1
            self._select_origin(index)
            self._sync_program_position()
        # 20. Path control.
        path_mode = g.get(C.PATH)
        if path_mode is not None:
            self.path_mode = path_mode
        # 21. Distance modes; 22. retract mode; spindle mode.
        distance = g.get(C.DISTANCE)
        if distance is not None:
            self.incremental = distance == 910
        arc_distance = g.get(C.ARC_DISTANCE)
        if arc_distance is not None:
            self.arc_incremental = arc_distance == 911
        retract = g.get(C.RETRACT)
        if retract is not None:
            self.retract_mode = retract
        spindle_mode = g.get(C.SPINDLE_MODE)
        if spindle_mode is not None:
            self.spindle_mode = spindle_mode
        # 23. Non-modal codes with axis words.
        motion = g.get(C.MOTION)
        has_axis = "X" in w or "Y" in w or "Z" in w or "@" in w or "^" in w or bool(self.extra_axes)
        axes_used = nonmodal in C.AXIS_USERS or (length in (431, 432) and has_axis)
        if nonmodal is not None and nonmodal != 40:
            self._nonmodal(nonmodal, w, motion, src, i)
        # 24. Motion.
        if motion is None:
            if has_axis and not axes_used:
                motion = self.motion
                if motion == 800:
                    raise InterpError("X/Y/Z words with no motion mode in force (G0, G1, G2, G3 or a canned cycle)")
            elif self.motion in (20, 30) and not axes_used and ("I" in w or "J" in w or "K" in w):
                motion = self.motion
        self._check_unused(w, motion, nonmodal, m, g)
        if motion is not None:
            if motion not in C.CYCLES:
                self.cycle_il = None
            if motion == 800:
                if has_axis and not axes_used:
                    raise InterpError("X/Y/Z words with G80 (cancel motion): nothing would use them")
            elif not (axes_used and motion == self.motion and C.MOTION not in g):
                self._motion(motion, w, nonmodal == 530, src, i)
            if motion not in LATHE_CYCLES:  # after G7x the profile's last motion mode stays in force
                self.motion = motion
        elif nonmodal == 530:
            raise InterpError("G53 needs a G0 or G1 move on its line")
        # 25. Stop.
        stop = m.get(C.M_STOP)
        if stop is not None:
            self._stop(stop, src, i)

    # Pieces of a block ----------------------------------------------------------------------
    def _io(self, code: int, w: dict) -> None:
        canon = self.canon
        if code in (62, 63, 64, 65):
            if "P" not in w:
                raise InterpError(f"M{code} needs a P word (output number)")
            channel = w["P"]
            if channel < 0 or channel != math.floor(channel):
                raise InterpError(f"M{code} output number (P) must be a whole number >= 0")
            canon.set_output(int(channel), code in (62, 64), code in (62, 63), self.file_index, self.line_no)
        else:
            if "E" not in w:
                raise InterpError(f"M{code} needs an E word (analog output number)")
            channel = w["E"]
            if channel < 0 or channel != math.floor(channel):
                raise InterpError(f"M{code} analog output number (E) must be a whole number >= 0")
            if "Q" not in w:
                raise InterpError(f"M{code} needs a Q word (volts)")
            canon.set_analog(int(channel), float(w["Q"]), code == 67, self.file_index, self.line_no)

    def _coolant(self, code: int, i: int) -> None:
        mist, flood = self.mist, self.flood
        if code == 9:
            mist = flood = False
        if code in (7, 78):
            mist = True
        if code in (8, 78):
            flood = True
        opts = self.options
        changes = []
        if mist != self.mist:
            changes.append((opts.mist_output, mist))
        if flood != self.flood:
            changes.append((opts.flood_output, flood))
        self.mist, self.flood = mist, flood

        def switch(changes=changes, file=self.file_index, line=i + 1):
            for channel, on in changes:
                self.canon.set_output(channel, on, False, file, line)

        if changes and (self.comp is None or not self.comp.hold(switch)):
            switch()

    def _tool_change(self, src: Source, i: int) -> None:
        if self.comp_mode != 400:
            raise InterpError("a tool change (M6) is not allowed while cutter compensation is on")
        tool = self.selected_tool if self.selected_tool >= 0 else self.current_tool
        self.spindle_dir = 0  # LinuxCNC stops the spindle for a tool change
        entry = self._tool(tool)
        if tool == 0:
            message = "unload the tool (T0)"
        else:
            detail = []
            if entry is not None and entry.comment:
                detail.append(entry.comment)
            if entry is not None and entry.diameter:
                detail.append(f"diameter {entry.diameter:g} mm")
            if entry is not None and entry.offset[2]:
                detail.append(f"length {entry.offset[2]:g} mm")
            message = f"change to tool T{tool}" + (f" ({', '.join(detail)})" if detail else "")
        if self.pending_message:
            message = f"{self.pending_message}: {message}"
            self.pending_message = ""
        self.canon.dwell(0.0, self.feed, 0.0, src.index, i + 1, PathEvent("tool_change", message, tool))
        self.current_tool = tool
        self._synch()

    def _synch(self) -> None:
        """After a tool change LinuxCNC re-reads where the machine is: the program position becomes
        the last point the machine was sent to (after G40 that is the compensated point), in the
        offsets now in force."""
        canon = self.canon
        last = canon.last_end()
        if last is not None:
            self.mx, self.my, self.mz = last
        self._sync_program_position()

    def _stop(self, code: int, src: Source, i: int) -> None:
        if code in (2, 30):
            if self.comp is not None:
                self.comp.flush()
            self.comp = None
            self.comp_mode = 400
            if self.mist or self.flood:
                self._coolant(9, i)
            self.spindle_dir = 0
            self.canon.finish(self.feed, 0.0, src.index, i + 1)
            self.ended = True
            return
        kind = {0: "pause", 1: "optional_pause", 60: "pallet_change"}[code]
        event = PathEvent(kind, self.pending_message)
        self.pending_message = ""
        feed, rpm = self.feed, self._spindle_rpm()

        def stop(feed=feed, rpm=rpm, file=src.index, line=i + 1):
            self.canon.dwell(0.0, feed, rpm, file, line, event)

        if self.comp is None or not self.comp.hold(stop):
            stop()

    def _modal_state(self, code: int) -> None:
        if code in (70, 73):
            state = self._save_state()
            if code == 73:
                if not self.frames:
                    raise InterpError("M73 (save and auto-restore) only works inside a subroutine")
                self.frames[-1].autorestore = state
            elif self.frames:
                self.frames[-1].saved_state = state
            else:
                self.saved_state = state
            return
        holder = self.frames[-1] if self.frames else None
        state = holder.saved_state if holder is not None else self.saved_state
        if state is None:
            raise InterpError(f"M{code}: no modal state was saved with M70 at this call level")
        if code == 71:
            if holder is not None:
                holder.saved_state = None
            else:
                self.saved_state = None
            return
        self._restore_state(state)

    def _save_state(self) -> dict:
        return {"plane": self.plane, "scale": self.scale, "incremental": self.incremental,
                "arc_incremental": self.arc_incremental, "feed_mode": self.feed_mode, "feed_word": self.feed_word,
                "feed": self.feed, "speed": self.speed, "spindle_dir": self.spindle_dir, "mist": self.mist,
                "flood": self.flood, "path_mode": self.path_mode, "retract_mode": self.retract_mode,
                "spindle_mode": self.spindle_mode, "origin_index": self.origin_index,
                "diameter_mode": self.diameter_mode}

    def _restore_state(self, state: dict) -> None:
        if state["scale"] != self.scale:
            self._change_units(state["scale"])
        if state["origin_index"] != self.origin_index:
            self._select_origin(state["origin_index"])
            self._sync_program_position()
        if (state["mist"], state["flood"]) != (self.mist, self.flood):
            mist, flood = state["mist"], state["flood"]
            opts = self.options
            if mist != self.mist:
                self.canon.set_output(opts.mist_output, mist, False, self.file_index, self.line_no)
            if flood != self.flood:
                self.canon.set_output(opts.flood_output, flood, False, self.file_index, self.line_no)
        for key in ("plane", "incremental", "arc_incremental", "feed_mode", "feed_word", "feed", "speed",
                    "spindle_dir", "mist", "flood", "path_mode", "retract_mode", "spindle_mode", "diameter_mode"):
            setattr(self, key, state[key])

    def _change_units(self, new_scale: float) -> None:
        # A feed keeps its speed (LinuxCNC converts it); the sticky cycle words are in mm already.
        self.feed_word = self.feed_word * self.scale / new_scale if self.feed_mode != 930 else self.feed_word
        self.scale = new_scale

    def _set_comp(self, code: int, w: dict) -> None:
        from flowmc.motion.gcode.comp import CutterComp

        if code == 400:
            if self.comp is not None:
                self.comp.end()
            self.comp = None
            self.comp_mode = 400
            return
        if self.comp_mode != 400:
            raise InterpError(f"G{code / 10:g} while cutter compensation is already on: program G40 first")
        if self.plane == 0:
            raise InterpError("cutter compensation works in the XY (G17) and XZ (G18) planes, not in G19")
        if code in (410, 420):
            number = self.current_tool
            if "D" in w:
                number = _integer(w["D"], "D word (tool number)")
                if number < 0:
                    raise InterpError("D word (tool number) must be >= 0")
            entry = self._tool(number)
            if entry is None:
                raise InterpError(f"tool T{number} (D word) is not in the tool table")
            radius = entry.diameter / 2.0
            orientation = entry.orientation
            if self.plane != 1 and orientation not in (0, 9):
                raise InterpError(f"G{code / 10:g} with a lathe tool (orientation {orientation}) needs the XZ "
                                  f"plane (G18)")
        else:
            if "D" not in w:
                raise InterpError(f"G{code / 10:g} needs a D word (the tool diameter)")
            radius = w["D"] * self.scale / 2.0
            orientation = 0
            if "L" in w:
                if self.plane != 1:
                    raise InterpError(f"G{code / 10:g} with an L word (tool orientation) needs the XZ plane (G18)")
                orientation = _integer(w["L"], "L word (tool orientation)")
        self.comp_mode = code
        if radius != 0.0:
            self.comp = CutterComp(self, left=code in (410, 411), radius=radius, orientation=orientation)

    def _tool_length(self, code: int, w: dict) -> None:
        if self.comp_mode != 400:
            raise InterpError("the tool length offset cannot change while cutter compensation is on")
        old = list(self.tlo)
        if code == 490:
            self.tlo = [0.0, 0.0, 0.0]
        elif code == 430:
            number = self.current_tool
            if "H" in w:
                number = _integer(w["H"], "H word (tool number)")
            entry = self._tool(number)
            if entry is None:
                raise InterpError(f"tool T{number} (H word) is not in the tool table")
            self.tlo = list(entry.offset)
        elif code == 431:
            self.tlo = [w.get("X", 0.0) * self.scale, w.get("Y", 0.0) * self.scale, w.get("Z", 0.0) * self.scale]
        elif code == 432:
            if "H" in w:
                entry = self._tool(_integer(w["H"], "H word (tool number)"))
                if entry is None:
                    raise InterpError(f"tool T{_integer(w['H'], 'H')} (H word) is not in the tool table")
                add = entry.offset
            else:
                add = (w.get("X", 0.0) * self.scale, w.get("Y", 0.0) * self.scale, w.get("Z", 0.0) * self.scale)
            self.tlo = [self.tlo[k] + add[k] for k in range(3)]
        self.tlo_mode = code
        if self.tlo != old:
            self._sync_program_position()

    def _axis_targets(self, w: dict, machine: bool = False) -> tuple[float, float, float]:
        """Where the axis words on this line point (program coordinates, mm); missing axes stay.
        Under cutter compensation they count from the programmed point, not the tool's."""
        s = self.scale
        x, y, z = (self.x, self.y, self.z) if self.comp is None else self.comp.base()
        if machine:
            x, y, z = self.mx, self.my, self.mz
            return (w["X"] * s if "X" in w else x, w["Y"] * s if "Y" in w else y, w["Z"] * s if "Z" in w else z)
        inc = self.incremental
        if "@" in w or "^" in w:
            x, y = self._polar(w, x, y)
        elif "X" in w:
            v = w["X"] * s
            if self.diameter_mode:
                v /= 2.0
            x = x + v if inc else v
        if "Y" in w:
            v = w["Y"] * s
            y = y + v if inc else v
        if "Z" in w:
            v = w["Z"] * s
            z = z + v if inc else v
        return x, y, z

    def _polar(self, w: dict, x: float, y: float) -> tuple[float, float]:
        """@ (distance) and ^ (angle, degrees) from the XY origin of the active coordinate system;
        in G91 they add to the current point's distance and angle."""
        if "X" in w or "Y" in w:
            raise InterpError("X or Y words cannot be mixed with polar coordinates (@ ^)")
        radius, theta = math.hypot(x, y), math.atan2(y, x)
        if self.incremental:
            if radius == 0.0:
                raise InterpError("an incremental polar move (G91 @ ^) cannot start at the origin")
            radius += w.get("@", 0.0) * self.scale
            theta += math.radians(w.get("^", 0.0))
        else:
            if "@" in w:
                radius = w["@"] * self.scale
            if "^" in w:
                theta = math.radians(w["^"])
        return radius * math.cos(theta), radius * math.sin(theta)

    def _nonmodal(self, code: int, w: dict, motion, src: Source, i: int) -> None:
        num = self.params.num
        mm = self.machine_mm
        if code in (100, 280, 300, 920, 921, 922, 923, 520) and self.comp_mode != 400:
            raise InterpError(f"G{code / 10:g} is not allowed while cutter compensation is on")
        if motion is not None and code in C.AXIS_USERS and ("X" in w or "Y" in w or "Z" in w):
            raise InterpError(f"G{code / 10:g} and a motion code on one line both use the axis words")
        if code == 100:
            self._g10(w)
        elif code in (280, 300):
            # A rapid to the intermediate point (where the axis words say; here, without any), then
            # to the stored position: only the named axes, or all of them when none is named.
            base = 5161 if code == 280 else 5181
            x, y, z = self._axis_targets(w)
            self._straight(x, y, z, True, src, i)
            home = [num[base + k] * mm for k in range(3)]
            named = "X" in w or "Y" in w or "Z" in w
            mx = home[0] if "X" in w or not named else self.mx
            my = home[1] if "Y" in w or not named else self.my
            mz = home[2] if "Z" in w or not named else self.mz
            self._straight(*self.to_program(mx, my, mz), True, src, i)
        elif code in (281, 301):
            base = 5161 if code == 281 else 5181
            for k, v in enumerate((self.mx, self.my, self.mz)):
                num[base + k] = v / mm
        elif code in (920, 520):
            if not ("X" in w or "Y" in w or "Z" in w):
                raise InterpError(f"G{code / 10:g} needs at least one axis word")
            s = self.scale
            for k, letter in enumerate("XYZ"):
                if letter not in w:
                    continue
                value = w[letter] * s
                if code == 920:
                    current = (self.x, self.y, self.z)[k] + self.g92[k]
                    self.g92[k] = current - value
                else:
                    self.g92[k] = value
                num[5211 + k] = self.g92[k] / mm
            num[5210] = 1.0
            self._sync_program_position()
        elif code in (921, 922):
            self.g92 = [0.0, 0.0, 0.0]
            if code == 921:
                for k in range(9):
                    num[5211 + k] = 0.0
            num[5210] = 0.0
            self._sync_program_position()
        elif code == 923:
            self.g92 = [num[5211 + k] * mm for k in range(3)]
            num[5210] = 1.0
            self._sync_program_position()

    def _g10(self, w: dict) -> None:
        num = self.params.num
        mm = self.machine_mm
        s = self.scale
        if "L" not in w:
            raise InterpError("G10 needs an L word (L1, L2, L10, L11 or L20)")
        level = _integer(w["L"], "G10 L word")
        if level == 0:
            return  # reload the tool table: flowmc's table is the one given
        if "P" not in w:
            raise InterpError(f"G10 L{level} needs a P word")
        p = _integer(w["P"], f"G10 L{level} P word")
        if level in (2, 20):
            if not 0 <= p <= 9:
                raise InterpError(f"G10 L{level} P must be 0 (the active system) to 9, got {p}")
            index = p or self.origin_index
            base = 5201 + 20 * index
            if level == 20:
                if "R" in w:
                    raise InterpError("G10 L20 takes no R word")
                machine = (self.mx - self.tlo[0], self.my - self.tlo[1], self.mz - self.tlo[2])
                for k, letter in enumerate("XYZ"):
                    if letter in w:
                        # Offset so that the current point reads the given value (no rotation).
                        num[base + k] = (machine[k] - self.g92[k] - w[letter] * s) / mm
            else:
                for k, letter in enumerate("XYZ"):
                    if letter in w:
                        num[base + k] = w[letter] * s / mm
                if "R" in w:
                    num[base + 9] = w["R"]
            if index == self.origin_index:
                self._select_origin(index)
                self._sync_program_position()
            return
        if level in (1, 10, 11):
            entry = self._tool(p)
            if p <= 0 or entry is None:
                entry = Tool(p, p)
            offset = list(entry.offset)
            if level == 1:
                for k, letter in enumerate("XYZ"):
                    if letter in w:
                        offset[k] = w[letter] * s
            else:
                for k, letter in enumerate("XYZ"):
                    if letter in w:
                        prog = (self.x, self.y, self.z)[k] + self.tlo[k]
                        offset[k] = prog - w[letter] * s
            diameter = w["R"] * 2.0 * s if "R" in w else entry.diameter
            new = Tool(p, entry.pocket, tuple(offset), diameter, w.get("I", entry.front_angle),
                       w.get("J", entry.back_angle), int(w.get("Q", entry.orientation)), entry.comment)
            self.tools = self.tools.with_tool(new)
            return
        raise InterpError(f"G10 L{level} is not supported (L1, L2, L10, L11 and L20 are)")

    # Motion ---------------------------------------------------------------------------------
    def _motion(self, motion: int, w: dict, g53: bool, src: Source, i: int) -> None:
        if g53:
            if motion not in (0, 10):
                raise InterpError("G53 works with G0 or G1 only")
            if self.comp_mode != 400:
                raise InterpError("G53 is not allowed while cutter compensation is on")
            if self.incremental:
                raise InterpError("G53 is not allowed in incremental mode (G91)")
            mx, my, mz = self._axis_targets(w, machine=True)
            x, y, z = self.to_program(mx, my, mz)
            if motion == 10:
                self._require_feed("G1")
            self._straight(x, y, z, motion == 0, src, i)
            return
        if motion == 0 or motion == 10:
            x, y, z = self._axis_targets(w)
            if self.extra_axes:
                if (x, y, z) == (self.x, self.y, self.z) and self.comp_mode == 400:
                    self._index_axes((x, y, z), src, i, motion)
                    return
                self._index_axes(None, src, i)
            if motion == 10:
                self._require_feed("G1")
                if self.feed_mode == 930:
                    self._inverse_time(w, math.dist((x, y, z), (self.x, self.y, self.z)))
            self.arc_not_allowed = False
            if self.comp is not None:
                self.comp.straight((x, y, z), motion == 0, src, i)
            else:
                self._straight(x, y, z, motion == 0, src, i)
            return
        if motion == 20 or motion == 30:
            self._arc(motion == 30, w, src, i)
            return
        if motion in LATHE_CYCLES:
            run_g7x(self, motion, w, src, i)
            return
        if motion in C.CYCLES:
            from flowmc.motion.gcode.cycles import run_cycle

            run_cycle(self, motion, w, src, i)
            return
        if motion in (50, 51):
            self._spline(motion, w, src, i)
            return
        if motion == 330:
            self._synchronised(w, src, i)
            return
        if motion == 331:
            self._rigid_tap(w, src, i)
            return
        if motion == 760:
            run_g76(self, w, src, i)
            return
        raise InterpError(f"motion G{motion / 10:g} is not supported")

    def _synchronised(self, w: dict, src: Source, i: int) -> None:
        """G33: a line synchronised with the spindle, K per revolution. flowmc cuts it as a line at
        K x S (it cannot wait for the spindle's index pulse), and says so once."""
        if "K" not in w or w["K"] <= 0:
            raise InterpError("G33 needs a K word > 0 (the distance per spindle revolution)")
        if self.comp_mode != 400:
            raise InterpError("G33 cannot be used while cutter compensation is on")
        if self.spindle_dir == 0 or self.speed <= 0:
            raise InterpError("G33 needs the spindle turning (M3 or M4 with S > 0)")
        if not self.warned_sync:
            self.warned_sync = True
            self.warn(src.where(i), "G33 spindle-synchronised moves are cut as lines at K x S; flowmc does not "
                                    "synchronise them to the spindle's index pulse")
        x, y, z = self._axis_targets(w)
        saved = self.feed
        self.feed = w["K"] * self.scale * self.speed / 60.0
        self._straight(x, y, z, False, src, i)
        self.feed = saved

    def _rigid_tap(self, w: dict, src: Source, i: int) -> None:
        """G33.1: in to the point at K per revolution, spindle reversed, back out to where it started."""
        if "K" not in w or w["K"] <= 0:
            raise InterpError("G33.1 needs a K word > 0 (the distance per spindle revolution)")
        if self.comp_mode != 400:
            raise InterpError("G33.1 cannot be used while cutter compensation is on")
        if self.spindle_dir == 0 or self.speed <= 0:
            raise InterpError("G33.1 needs the spindle turning (M3 or M4 with S > 0)")
        if not self.warned_sync:
            self.warned_sync = True
            self.warn(src.where(i), "G33/G33.1 spindle-synchronised moves are cut as lines at K x S; flowmc does "
                                    "not synchronise them to the spindle's index pulse")
        start = (self.x, self.y, self.z)
        target = self._axis_targets(w)
        saved, direction = self.feed, self.spindle_dir
        self.feed = w["K"] * self.scale * self.speed / 60.0
        self._straight(*target, False, src, i)
        self.spindle_dir = -direction
        self._straight(*start, False, src, i)
        self.spindle_dir = direction
        self.feed = saved

    def _spline(self, motion: int, w: dict, src: Source, i: int) -> None:
        """G5 (cubic) and G5.1 (quadratic) splines in the XY plane: exact NURBS segments."""
        name = "G5" if motion == 50 else "G5.1"
        if self.comp_mode != 400:
            raise InterpError(f"{name} cannot be used while cutter compensation is on")
        if self.plane != 2:
            raise InterpError(f"{name} splines must be in the XY plane (G17)")
        if "Z" in w:
            raise InterpError(f"{name} splines may not move Z")
        self._require_feed(name)
        s = self.scale
        x0, y0, z = self.x, self.y, self.z
        x, y, _ = self._axis_targets(w)
        if motion == 51:
            if "I" not in w or "J" not in w:
                raise InterpError("G5.1 needs both I and J (the control point, from the start)")
            ctrl = [(x0, y0), (x0 + w["I"] * s, y0 + w["J"] * s), (x, y)]
        else:
            if ("I" in w) != ("J" in w):
                raise InterpError("G5 needs both I and J, or neither (then the last P and Q continue the curve)")
            if "I" in w:
                i1, j1 = w["I"] * s, w["J"] * s
            else:
                if self.spline_ij is None:
                    raise InterpError("G5 without I and J needs a G5 before it")
                i1, j1 = self.spline_ij
            if "P" not in w or "Q" not in w:
                raise InterpError("G5 needs both P and Q (the control point, from the end)")
            p, q = w["P"] * s, w["Q"] * s
            ctrl = [(x0, y0), (x0 + i1, y0 + j1), (x + p, y + q), (x, y)]
            self.spline_ij = (-p, -q)
        points = [self.to_machine(u, v, z) for u, v in ctrl]
        self.canon.nurbs_to(points, len(ctrl) - 1, self.feed, self._spindle_rpm(), src.index, i + 1)
        self.x, self.y = x, y
        self.mx, self.my, self.mz = points[-1]

    def _require_feed(self, name: str) -> None:
        if self.feed_mode == 930:
            return
        if not self.feed > 0:
            raise InterpError(f"{name} with no feed rate: program an F word first")

    def _inverse_time(self, w: dict, length: float) -> None:
        if "F" not in w:
            raise InterpError("inverse time feed (G93) needs an F word on every G1, G2 and G3 line")
        if w["F"] <= 0:
            raise InterpError("inverse time feed (G93): F must be > 0")
        self.feed = length * w["F"] / 60.0

    def _straight(self, x: float, y: float, z: float, rapid: bool, src: Source, i: int) -> None:
        """A line to program position (x, y, z), mm."""
        if self._sin == 0.0 and self._cos == 1.0:
            g92, g5x, tlo = self.g92, self.g5x, self.tlo
            mx, my, mz = (x + g92[0] + g5x[0] + tlo[0], y + g92[1] + g5x[1] + tlo[1],
                          z + g92[2] + g5x[2] + tlo[2])
        else:
            mx, my, mz = self.to_machine(x, y, z)
        self.canon.line_to(mx, my, mz, rapid, self.feed, self.speed * self.spindle_dir + 0.0, src.index, i + 1)
        self.x, self.y, self.z = x, y, z
        self.mx, self.my, self.mz = mx, my, mz

    def _arc(self, ccw: bool, w: dict, src: Source, i: int) -> None:
        g = "G3" if ccw else "G2"
        plane = self.plane
        iu, iv = _UV[plane]
        offset_letters = "IJK"
        normal_letter = offset_letters[plane]
        if normal_letter in w:
            raise InterpError(f"{normal_letter} word given for an arc in the {PLANES[plane][0]} "
                              f"(G{ {2: 17, 1: 18, 0: 19}[plane]}) plane")
        has_r = "R" in w
        has_c = offset_letters[iu] in w or offset_letters[iv] in w
        if not has_r and not has_c:
            raise InterpError(f"{g} needs a centre (I, J, K) or a radius (R)")
        if has_r and has_c:
            raise InterpError(f"{g} has both a radius (R) and a centre (I, J, K)")
        self._require_feed(g)
        turns = 0
        if "P" in w:
            p = w["P"]
            if p != math.floor(p) or p < 1:
                raise InterpError(f"P on {g} must be a whole number of turns, 1 or more")
            turns = int(p) - 1
        x, y, z = self._axis_targets(w)
        if self.comp is not None:
            self.comp.arc(ccw, w, (x, y, z), turns, self.scale, not self.arc_incremental, src, i)
            return
        if self.arc_not_allowed:
            raise InterpError("the move just after cutter compensation is turned off must be straight, not an arc")
        start = (self.x, self.y, self.z)
        end = (x, y, z)
        su, sv, eu, ev = start[iu], start[iv], end[iu], end[iv]
        s = self.scale
        if has_r:
            cu, cv = centre_r(su, sv, eu, ev, w["R"] * s, not ccw, s)
        else:
            if not self.arc_incremental:
                for letter in (offset_letters[iu], offset_letters[iv]):
                    if letter not in w:
                        raise InterpError(f"{letter} word missing in an absolute-centre arc (G90.1)")
                cu, cv = w[offset_letters[iu]] * s, w[offset_letters[iv]] * s
            else:
                cu = su + w.get(offset_letters[iu], 0.0) * s
                cv = sv + w.get(offset_letters[iv], 0.0) * s
            diff = centre_ijk(su, sv, eu, ev, cu, cv, s)
            if diff > SPIRAL_WARN_MM:
                self.warn_spiral(g, diff, src, i)
        if self.feed_mode == 930:
            r = math.hypot(su - cu, sv - cv)
            a0 = math.atan2(sv - cv, su - cu)
            a1 = math.atan2(ev - cv, eu - cu)
            sweep = (a1 - a0) % (2 * math.pi) if ccw else (a0 - a1) % (2 * math.pi)
            if sweep < 1e-12:
                sweep = 2 * math.pi
            sweep += 2 * math.pi * turns
            self._inverse_time(w, math.hypot(r * sweep, end[plane] - start[plane]))
        centre = list(start)
        centre[iu], centre[iv] = cu, cv
        self._emit_arc(end, centre, ccw, turns, src, i)

    def warn_spiral(self, g: str, diff: float, src: Source, i: int) -> None:
        self.warn(src.where(i), f"{g} end point is {diff:.6f} mm off the circle through its start; "
                                "accepted as LinuxCNC accepts it (the arc blends its radius: a spiral)")

    def _emit_arc(self, end, centre, ccw: bool, turns: int, src: Source, i: int, plane: int | None = None) -> None:
        plane = self.plane if plane is None else plane
        if plane != 2 and self.rotation != 0.0:
            raise InterpError("an arc in the XZ or YZ plane cannot be cut in a rotated coordinate system "
                              "(G10 L2 R): flowmc arcs stay in the XY, XZ or YZ planes")
        mx, my, mz = self.to_machine(*end)
        cx, cy, cz = self.to_machine(*centre)
        self.canon.arc_to(mx, my, mz, (cx, cy, cz), plane, ccw, turns, self.feed, self._spindle_rpm(), src.index,
                          i + 1)
        self.x, self.y, self.z = end
        self.mx, self.my, self.mz = mx, my, mz

    def emit_straight(self, end, rapid: bool, feed: float, spindle: float, file: int, line: int) -> None:
        """A finished compensated line to program point ``end`` (called by CutterComp)."""
        mx, my, mz = self.to_machine(*end)
        self.canon.line_to(mx, my, mz, rapid, feed, spindle, file, line)

    def emit_arc(self, end, centre, ccw: bool, turns: int, plane: int, feed: float, spindle: float, file: int,
                 line: int) -> None:
        """A finished compensated arc (called by CutterComp)."""
        if plane != 2 and self.rotation != 0.0:
            raise InterpError("an arc in the XZ plane cannot be cut in a rotated coordinate system (G10 L2 R)")
        mx, my, mz = self.to_machine(*end)
        cx, cy, cz = self.to_machine(*centre)
        self.canon.arc_to(mx, my, mz, (cx, cy, cz), plane, ccw, turns, feed, spindle, file, line)

    def _check_unused(self, w: dict, motion, nonmodal, m: dict, g: dict) -> None:
        if motion in LATHE_CYCLES:
            for letter in "HJKL":
                if letter in w:
                    raise InterpError(f"{letter} word with nothing to use it (G70-G72 take D, E, I, P, Q, R, U "
                                      f"and W)")
            return
        if motion == 760:
            if "D" in w:
                raise InterpError("D word with nothing to use it (G76 takes P, I, J, K, R, Q, H, E and L)")
            return
        arc = motion in (20, 30)
        cycle = motion in C.CYCLES
        g10 = nonmodal == 100
        if ("I" in w or "J" in w or "K" in w) and not (arc or motion in (870, 50, 51, 330, 331) or g10):
            letter = next(c for c in "IJK" if c in w)
            raise InterpError(f"{letter} word with no G2 or G3 to use it")
        if "R" in w and not (arc or cycle or g10):
            raise InterpError("R word with no G2 or G3 to use it")
        io = m.get(C.M_IO)
        p_users = (nonmodal == 40) + arc + (g.get(C.PATH) == 640) + (io in (62, 63, 64, 65)) + \
            (motion in (820, 860, 880, 890, 830, 730, 50)) + g10
        if "P" in w and p_users == 0:
            raise InterpError("P word with nothing to use it (G4, G2/G3, G64, G10, canned cycles and M62-M65 use P)")
        if nonmodal == 40 and arc:
            raise InterpError(f"G4 and G{motion / 10:g} on one line: both would use the P word")
        if "P" in w and p_users > 1 and not g10:
            raise InterpError("P word claimed by two codes on this line")
        if "E" in w and io not in (67, 68):
            raise InterpError("E word with nothing to use it (M67/M68 use E)")
        q_users = (io in (67, 68)) + (g.get(C.PATH) == 640) + (motion in (730, 830, 50)) + \
            (m.get(C.M_TOOL) == 61) + g10
        if "Q" in w and q_users == 0:
            raise InterpError("Q word with nothing to use it (M67/M68, M61, G64, G73/G83 and G10 use Q)")
        if "L" in w and not (g10 or motion in C.CYCLES or g.get(C.COMP) in (411, 421)):
            raise InterpError("L word with nothing to use it (G10 and canned cycles use L)")
        if "H" in w and g.get(C.LENGTH) not in (430, 432):
            raise InterpError("H word with nothing to use it (G43 and G43.2 use H)")
        if "D" in w and g.get(C.COMP) not in (410, 420, 411, 421):
            raise InterpError("D word with nothing to use it (G41/G42 use D)")


_XYZF = frozenset("XYZF")
_ARC_WORDS = frozenset("XYZIJKRFP")
_STRAIGHT = {0.0: 0, 1.0: 10}  # G value -> motion mode, for the fast lines
_ARCS = {2.0: 20, 3.0: 30}
_FAST_MIN_LINES = 200  # files shorter than this are read line by line
_FAST_MIN_RUN = 32  # plain runs shorter than this too
_FAST_MAX_RUN = 50_000  # runs are read in blocks of this many lines (bounds the working arrays)


def _label_text(label) -> str:
    return f"<{label}>" if isinstance(label, str) else str(label)


def _code10(value: float, letter: str) -> int:
    if not math.isfinite(value):
        raise InterpError(f"{letter} word is not a finite number")
    code = round(value * 10)
    if abs(value * 10 - code) > 0.001:
        raise InterpError(C.g_refusal(value) if letter == "G" else f"{letter}{value:g} is not a code")
    return int(code)


def _int_code(value: float, letter: str) -> int:
    if not math.isfinite(value):
        raise InterpError(f"{letter} word is not a finite number")
    code = round(value)
    if abs(value - code) > 0.0001:
        raise InterpError(C.m_refusal(value))
    return int(code)


def _integer(value: float, what: str) -> int:
    try:
        return X.integer(value, what)
    except EvalError as exc:
        raise InterpError(str(exc)) from None


def files_of(interp: Interpreter) -> list[str]:
    return [s.name for s in interp.sources]

