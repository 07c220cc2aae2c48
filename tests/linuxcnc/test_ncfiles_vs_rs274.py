"""Every program LinuxCNC installs in its ncfiles, read by flowmc and by rs274, move by move.

The programs counted are those rs274 interprets to the end with motion, without remaps, Python or
probing, each with the sample configuration it was written for: LinuxCNC's sim/axis ``lathe.tbl``
for the lathe programs (lathe*.ngc, g76.ngc, threading.ngc), its ``sim.tbl`` for the rest, and the
ncfiles folder as the subroutine folder; where rs274 refuses a program with that table, flowmc's own
(tools 1-9, no offsets or diameters) is tried. rs274 reads tables and parameter files in inches.
At least 90 % of them must agree move by move within 1e-4 mm (inch programs to rs274's printed
precision, 0.00005 inch), and so must the round trip: flowmc's G-code out of what it read, read by
rs274 again, makes the same moves, rotary indexing and stops as the original. The others are
listed in KNOWN_DIFFERENCES, with the reason docs/gcode.md gives, and each must still differ for
exactly that reason (so the list stays true).
"""

from __future__ import annotations

import functools
import re
from pathlib import Path as FsPath

import numpy as np
import pytest

from flowmc.devices.linuxcnc.rs274 import MACHINE_UNITS_MM, TOOL_TABLE, run_rs274
from flowmc.errors import GcodeError
from flowmc.motion.gcode import GcodeOptions, ToolTable, interpret
from flowmc.motion.gcode_write import path_to_gcode
from gcode_compare import assert_same_canon, assert_same_moves

pytestmark = pytest.mark.linuxcnc

NCFILES = FsPath("/usr/share/linuxcnc/ncfiles")
SIM = FsPath("/usr/share/doc/linuxcnc/examples/sample-configs/sim/axis")
DOCS = FsPath(__file__).parents[2] / "docs" / "gcode.md"
LATHE_PROGRAMS = {"g76.ngc", "threading.ngc"}
MM_TOL = 1e-4
INCH_TOL = 0.5e-4 * 25.4 + 1e-9
MM_PRINT = 0.5e-4 + 1e-9

#: Programs in the count that flowmc does not read as rs274 does: name -> (what differs, why).
KNOWN_DIFFERENCES = {
    "daisy.ngc": ("axis A is not supported", "a 4-axis program: it turns the A axis with X, Y and Z; flowmc paths "
                                             "have X, Y and Z, so flowmc refuses it on the first such move"),
    "skeleton.ngc": ("end ", "'T1 M06 G43 H1' on one line: rs274's stand-alone canon re-reads the position after "
                             "the tool change without the new tool length offset and moves Z on the next XY move; "
                             "LinuxCNC's machine (its task, checked with the simulator) and flowmc keep Z where it "
                             "was"),
}


def programs() -> list[FsPath]:
    return sorted(NCFILES.rglob("*.ngc"))


def tool_table(file: FsPath) -> FsPath:
    lathe = file.name.startswith("lathe") or file.name in LATHE_PROGRAMS
    return SIM / ("lathe.tbl" if lathe else "sim.tbl")


def is_inch(text: str) -> bool:
    return re.search(r"g0*20(?![0-9.])", text, re.IGNORECASE) is not None


@functools.cache
def outcome(rel: str) -> tuple[str, str]:
    """(category, detail): "excluded" (why), "same", or "different" (what differs)."""
    file = NCFILES / rel
    text = file.read_text(errors="replace")
    table = tool_table(file)
    if re.search(r"g\s*3\s*8\s*\.\s*[2-5]", text, re.IGNORECASE):
        return "excluded", "probing (G38)"
    try:
        ref = run_rs274(text, name=file.name, tool_table=table, subroutine_dir=NCFILES)
    except GcodeError as err:
        try:  # e.g. g76.ngc: its tools' sample diameters make its comp entry move too short
            table = TOOL_TABLE
            ref = run_rs274(text, name=file.name, tool_table=table, subroutine_dir=NCFILES)
        except GcodeError:
            return "excluded", f"rs274 refuses it: {err.message}"
    if len(ref) == 0:
        return "excluded", "no motion"
    options = GcodeOptions(tool_table=ToolTable.load(table, units_mm=MACHINE_UNITS_MM),
                           machine_units_mm=MACHINE_UNITS_MM, subroutine_dirs=(NCFILES,))
    tol = INCH_TOL if is_inch(text) else MM_TOL
    machine = ref.in_machine_coordinates()
    try:
        result = interpret(text, file.name, options)
        assert_same_moves(result.path, machine, tol, lines=False)
    except (GcodeError, AssertionError) as err:
        return "different", str(err).splitlines()[0]
    try:  # G-code in -> G-code out, and rs274 reads the output as it read the original
        written = path_to_gcode(result.path)
        # Both sides are rs274's prints: the original's rounding, and 0.00005 mm on our mm output.
        assert_same_canon(run_rs274(written, name=f"out-{file.name}", tool_table=table), machine,
                          tol + MM_PRINT)
    except (GcodeError, AssertionError) as err:
        return "different", "round trip: " + str(err).splitlines()[0]
    return "same", f"{len(ref)} moves"


def test_linuxcnc_ships_its_example_programs():
    assert len(programs()) > 100


@pytest.mark.parametrize("file", programs(), ids=lambda f: str(f.relative_to(NCFILES)))
def test_each_program_is_read_as_rs274_reads_it_or_is_a_known_difference(file):
    rel = str(file.relative_to(NCFILES))
    category, detail = outcome(rel)
    if category == "excluded":
        assert file.name not in KNOWN_DIFFERENCES
        assert detail in ("no motion", "probing (G38)") or detail.startswith("rs274 refuses it"), detail
        return
    if file.name in KNOWN_DIFFERENCES:
        assert category == "different", f"{rel} now agrees with rs274: take it off KNOWN_DIFFERENCES"
        assert KNOWN_DIFFERENCES[file.name][0] in detail, detail
    else:
        assert category == "same", f"{rel}: {detail}"


def test_at_least_nine_in_ten_counted_programs_agree_with_rs274():
    counted = [outcome(str(f.relative_to(NCFILES)))[0] for f in programs()]
    counted = [c for c in counted if c != "excluded"]
    same = counted.count("same")
    assert len(counted) >= 29
    assert same / len(counted) >= 0.9, f"{same} of {len(counted)} agree"


def test_the_docs_list_every_known_difference_with_its_reason():
    text = DOCS.read_text()
    for name in KNOWN_DIFFERENCES:
        assert f"`{name}`" in text, name


def test_the_lathe_programs_use_linuxcncs_lathe_table_and_the_rest_its_mill_table():
    assert tool_table(NCFILES / "lathe_pawn.ngc").name == "lathe.tbl"
    assert tool_table(NCFILES / "comp.ngc").name == "sim.tbl"
    assert np.isclose(MACHINE_UNITS_MM, 25.4, rtol=1e-12)


# (useful-subroutines.ngc is left to the test above: its entry move is exactly the tool radius, which
# rs274's inch factor, 1/0.03937007874016, tips one way and the node's exact 25.4 the other.)
@pytest.mark.parametrize("name", ["b-index.ngc", "systems.ngc", "tort.ngc", "plasmatest.ngc", "arcspiral.ngc",
                                  "g76.ngc"])
def test_the_round_trip_through_a_gcode_in_gcode_out_graph_agrees_with_rs274(name, tmp_path):
    """As a user does it: a graph reads the program (with the sample tool table, in inches) and writes
    it back out; rs274 reads the written file as it read the original (pauses, tool changes and the
    rotary indexing included)."""
    import flowmc

    file = NCFILES / name
    table = tool_table(file) if name != "g76.ngc" else TOOL_TABLE
    (tmp_path / name).write_bytes(file.read_bytes())
    (tmp_path / "tools.tbl").write_bytes(table.read_bytes())
    g = flowmc.GraphBuilder()
    src = g.add("path.gcode_in", id="in", file=name, tool_table="tools.tbl", machine_units="inch",
                subroutine_folder=".")
    out = g.add("path.gcode_out", id="out", file="out.ngc")
    g.wire(src.path, out.path)
    g.save(tmp_path / "graph.flowmc.json")
    result = flowmc.run(tmp_path / "graph.flowmc.json")
    assert result.ok, result.errors
    text = file.read_text(errors="replace")
    original = run_rs274(text, name=name, tool_table=table, subroutine_dir=NCFILES).in_machine_coordinates()
    written = run_rs274((tmp_path / "out.ngc").read_text(), name="out.ngc", tool_table=table)
    assert_same_canon(written, original, (INCH_TOL if is_inch(text) else MM_TOL) + MM_PRINT)
