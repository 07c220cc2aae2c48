"""G-code in and out: each word and mode of the subset, each error with its line, and the round trip."""

import math

import numpy as np
import pytest

from flowmc.errors import GcodeError
from flowmc.motion.gcode import RAPID_FEED, parse_gcode, read_gcode
from flowmc.motion.gcode_write import path_to_gcode, write_gcode
from flowmc.motion.path import Arc, Dwell, EllipseArc, Line, NurbsCurve, Path, PathEvent


def moves(path: Path) -> list:
    return [s for s in path if not isinstance(s, Dwell)]


def close(a, b, tol=1e-9):
    np.testing.assert_allclose(np.asarray(a, dtype=float), np.asarray(b, dtype=float), rtol=0, atol=tol)


# ------------------------------------------------------------------ motion words

def test_rapid_and_feed_lines_start_at_the_origin_with_feed_in_mm_per_s():
    p = parse_gcode("G0 X1 Y2\nG1 Z-1 F600\nX5\n", "t.ngc")
    assert [s.kind for s in p] == ["line"] * 3
    close(p[0].start, [0, 0, 0])
    close(p[0].end, [1, 2, 0])
    assert p[0].rapid and not p[0].tool_down and p[0].feed == RAPID_FEED
    close(p[1].end, [1, 2, -1])
    assert not p[1].rapid and p[1].tool_down and p[1].feed == pytest.approx(10.0)
    close(p[2].start, p[1].end)
    close(p[2].end, [5, 2, -1])  # G1 stays in force for a line with only axis words
    assert [s.source for s in p] == ["t.ngc:1", "t.ngc:2", "t.ngc:3"]


def test_rapid_feed_is_a_parameter():
    p = parse_gcode("G0 X1", rapid_feed=55.0)
    assert p[0].feed == 55.0
    with pytest.raises(GcodeError, match="rapid feed"):
        parse_gcode("G0 X1", rapid_feed=0)


def test_a_motion_code_alone_is_a_zero_length_move_and_modal_lines_without_axes_are_not():
    p = parse_gcode("G1 X10 F100\nG1\nF200\nS100\nG0\n")
    assert len(p) == 3
    close(p[1].start, p[1].end)
    assert p[1].length == 0 and not p[1].rapid
    assert p[2].rapid and p[2].length == 0


@pytest.mark.parametrize("code, ccw", [("G2", False), ("G3", True)])
def test_ijk_arc_centre_is_relative_to_the_start(code, ccw):
    p = parse_gcode(f"G1 X10 F60\n{code} X20 I5 J0\n")
    arc = p[1]
    assert isinstance(arc, Arc) and arc.ccw is ccw and arc.normal_axis == 2 and arc.turns == 0
    close(arc.center, [15, 0, 0])
    assert arc.sweep == pytest.approx(math.pi if ccw else -math.pi)


@pytest.mark.parametrize("code, r, cy", [("G2", 6, -math.sqrt(11)), ("G2", -6, math.sqrt(11)),
                                         ("G3", 6, math.sqrt(11)), ("G3", -6, -math.sqrt(11))])
def test_r_arcs_take_the_short_way_for_positive_r_and_the_long_way_for_negative_r(code, r, cy):
    arc = parse_gcode(f"G1 X10 F60\n{code} X20 R{r}\n")[1]
    close(arc.center, [15, cy, 0], 1e-12)
    assert arc.radius == pytest.approx(6)
    assert (abs(arc.sweep) < math.pi) == (r > 0)


def test_r_arc_a_hair_short_of_half_the_chord_is_a_semicircle_as_in_linuxcnc():
    arc = parse_gcode("G1 X10 F60\nG2 X20 R4.999\n")[1]
    close(arc.center, [15, 0, 0])
    assert arc.sweep == pytest.approx(-math.pi)


def test_full_circle_helix_and_turns():
    p = parse_gcode("G1 X10 F60\nG3 X10 I5\nG2 I5 Z-3 P3\nG91 G3 I-5 Z1\n")
    full, helix, rel = p[1], p[2], p[3]
    close(full.center, [15, 0, 0])
    assert full.sweep == pytest.approx(2 * math.pi) and full.rise == 0
    assert helix.turns == 2 and helix.sweep == pytest.approx(-6 * math.pi) and helix.rise == pytest.approx(-3)
    close(helix.end, [10, 0, -3])
    close(rel.end, [10, 0, -2])
    assert rel.ccw and rel.sweep == pytest.approx(2 * math.pi)


def test_a_centre_word_alone_continues_an_arc_mode_as_in_linuxcnc():
    p = parse_gcode("G2 X20 I10 F60\nI5\n")
    assert len(p) == 2 and isinstance(p[1], Arc)
    close(p[1].center, [25, 0, 0])


@pytest.mark.parametrize("plane, words, normal, centre", [
    ("G18", "X20 I5 K0", 1, [15, 0, 0]),
    ("G18", "X20 Z0 K0 I5", 1, [15, 0, 0]),
    ("G19", "Y20 J5 K0", 0, [0, 15, 0]),
])
def test_arcs_in_the_xz_and_yz_planes(plane, words, normal, centre):
    start = "G1 X10 F60" if plane == "G18" else "G1 Y10 F60"
    arc = parse_gcode(f"{start}\n{plane} G2 {words}\n")[1]
    assert arc.normal_axis == normal and not arc.ccw
    close(arc.center, centre)


def test_g18_arc_direction_follows_rs274_plane_order():
    # In G18 the plane's (first, second) axes are (Z, X): G3 (ccw seen from +Y) from X10 to X20
    # about X15 turns from -X towards +Z, so it passes Z = +5.
    arc = parse_gcode("G1 X10 F60\nG18 G3 X20 R5\n")[1]
    mid = arc.point_at(arc.length / 2)
    close(mid, [15, 0, 5], 1e-9)


def test_g20_converts_coordinates_centres_radii_and_feed_to_mm():
    p = parse_gcode("G20\nG1 X1 F10\nG2 X2 R0.5\nG3 X3 I0.5 J0\n")
    close(p[0].end, [25.4, 0, 0])
    assert p[0].feed == pytest.approx(25.4 * 10 / 60)
    close(p[1].center, [38.1, 0, 0])
    close(p[2].center, [63.5, 0, 0])


def test_feed_is_converted_with_the_units_in_force_when_it_is_read_as_in_linuxcnc():
    # A later G20 keeps the speed; F on a G20 line is read before G20 takes effect.
    p = parse_gcode("G21 F600 G1 X1\nG20 X1\nF10 X2\nG21 G1 X3\nG20 F10 X4\n")
    assert [s.feed for s in p] == pytest.approx([10.0, 10.0, 25.4 * 10 / 60, 25.4 * 10 / 60, 10 / 60])


def test_g91_incremental_moves_and_arcs():
    p = parse_gcode("G0 X1 Y1\nG91 G1 X2 Y3 F60\nX1\nG2 X10 I5\nG90 G1 X0 Y0\n")
    close(p[1].end, [3, 4, 0])
    close(p[2].end, [4, 4, 0])
    close(p[3].end, [14, 4, 0])
    close(p[3].center, [9, 4, 0])
    close(p[4].end, [0, 0, 0])  # back to absolute


def test_g90_1_takes_arc_centres_as_absolute_and_g91_1_restores_relative():
    p = parse_gcode("G1 X10 Y10 F60\nG90.1 G2 X20 I15 J10\nG91.1 G3 X10 I-5 J0\n")
    close(p[1].center, [15, 10, 0])
    close(p[2].center, [15, 10, 0])


def test_g4_dwell_at_the_current_point_before_the_move_on_its_line():
    p = parse_gcode("G1 X5 F60\nG4 P1.5 G1 X7\n")
    assert [s.kind for s in p] == ["line", "dwell", "line"]
    assert p[1].seconds == 1.5
    close(p[1].start, [5, 0, 0])
    assert p[1].source == "<text>:2"


def test_spindle_words_give_signed_rpm_on_the_following_segments():
    p = parse_gcode("G1 X1 F60\nS1000 M3\nX2\nM4\nX3\nS200\nX4\nM5\nX5 M3\n")
    assert [s.spindle for s in p] == [0.0, 1000.0, -1000.0, -200.0, 200.0]  # M5 keeps S for the next M3
    assert parse_gcode("M3 S50 G1 X1 F60")[0].spindle == 50.0  # same line: the spindle starts first


def test_m3_on_the_line_of_a_move_applies_to_that_move():
    p = parse_gcode("G1 X1 F60\nS300 G1 X2 M3\n")
    assert [s.spindle for s in p] == [0.0, 300.0]


def test_synchronised_outputs_ride_on_the_next_move():
    p = parse_gcode("M62 P1\nM67 E2 Q3.5\nG1 X1 F60\nG1 X2 M63 P1\nG1 X3\n")
    assert len(p) == 3
    assert p[0].outputs == ((1, True),) and p[0].analog == ((2, 3.5),)
    assert p[1].outputs == ((1, False),) and p[1].analog == ()
    assert p[2].outputs == ()


def test_immediate_outputs_ride_on_the_next_dwell_or_a_zero_dwell():
    p = parse_gcode("G1 X1 F60\nM64 P3\nM68 E0 Q1.25\nG1 X2\nM65 P3\nG4 P2\nG1 X3\n")
    assert [s.kind for s in p] == ["line", "dwell", "line", "dwell", "line"]
    assert p[1].seconds == 0 and p[1].outputs == ((3, True),) and p[1].analog == ((0, 1.25),)
    assert p[1].source == "<text>:2"  # named after its first change
    close(p[1].start, [1, 0, 0])
    assert p[3].seconds == 2 and p[3].outputs == ((3, False),)
    assert p[2].outputs == () and p[4].outputs == ()


def test_output_changes_after_the_last_move_are_kept_on_a_final_dwell():
    p = parse_gcode("G1 X1 F60\nM62 P4\nM64 P5\nM2\n")
    assert [s.kind for s in p] == ["line", "dwell"]
    assert dict(p[1].outputs) == {4: True, 5: True}
    close(p[1].start, [1, 0, 0])


def test_the_last_change_to_a_channel_before_a_move_wins():
    p = parse_gcode("M62 P1\nM63 P1\nG1 X1 F60\n")
    assert p[0].outputs == ((1, False),)


def test_m2_and_m30_end_reading():
    assert len(parse_gcode("G1 X1 F60\nM2\nG1 X2\nthis is not g-code\n")) == 1
    assert len(parse_gcode("G1 X1 F60 M30\nG41\n")) == 1


def test_comments_line_numbers_case_spaces_and_percent_delimiters():
    text = ("%\n"
            "(header comment)\n"
            "N10 g1 x 1 0 . 5 f 6 0 (inline) ; trailing\n"
            "n20 Y2 (MSG, hello)\n"
            "%\n"
            "G1 X1000\n")
    p = parse_gcode(text, "c.ngc")
    assert len(p) == 2
    close(p[0].end, [10.5, 0, 0])
    close(p[1].end, [10.5, 2, 0])
    assert p[1].source == "c.ngc:4"


def test_block_delete_runs_slashed_lines_unless_switched_on():
    text = "G1 X1 F60\n/G1 X2\nG1 X3\n"
    assert len(parse_gcode(text)) == 3
    p = parse_gcode(text, block_delete=True)
    assert len(p) == 2
    close(p[1].start, [1, 0, 0])


def test_windows_line_ends_and_noop_mode_codes():
    p = parse_gcode("G17 G21 G40 G49 G54 G64 P0.05 Q0.01 G80 G90 G94\r\nG1 X1 F60\r\nG61.1\r\nG61 X2\r\n")
    assert len(p) == 2 and p[1].source == "<text>:4"


def test_read_gcode_names_the_file(tmp_path):
    f = tmp_path / "part.ngc"
    f.write_text("G1 X1 F60\nG1 X2\n")
    p = read_gcode(f)
    assert [s.source for s in p] == ["part.ngc:1", "part.ngc:2"]
    with pytest.raises(GcodeError) as err:
        read_gcode(tmp_path / "missing.ngc")
    assert "missing.ngc" in str(err.value)


def test_an_empty_program_is_an_empty_path():
    assert len(parse_gcode("")) == 0
    assert len(parse_gcode("%\n(nothing)\n\n%\n")) == 0


# ------------------------------------------------------------------ errors name the line

@pytest.mark.parametrize("text, line, message", [
    ("G1 X1 F60\nG41 D-1\n", 2, "D word (tool number) must be >= 0"),
    ("G1 X1 F60\nG1.5 X2\n", 2, "G1.5 is not a G-code LinuxCNC or flowmc knows"),
    ("G1 X1 F60\nG38.2 Z-5\n", 2, "G38.2 is not supported (probing (G38.x) is not supported"),
    ("G0 X1\nG33 Z-5 K1\n", 2, "G33 needs the spindle turning"),
    ("G0 X1\nG33.1 Z-5 K1\n", 2, "G33.1 needs the spindle turning"),
    ("G0 X1\nG76 P1 Z-1 I-1 J1 K1\n", 2, "G76 needs the spindle turning"),
    ("G0 X1\nG1 X2 A90 F100\n", 2, "axis A is not supported"),
    ("G81 X1 Y1 Z-1 R1\n", 1, "G81 with no feed rate"),
    ("M6 T-2\n", 1, "tool number (T) must be >= 0"),
    ("M123\n", 1, "user-defined"),
    ("M66 P0 L0\n", 1, "M66 is not supported (waiting on inputs"),
    ("T-1\n", 1, "tool number (T) must be >= 0"),
    ("G0 X1 A90\n", 1, "axis A is not supported"),
    ("G0 X1\nG2 X3 I1 U1 F10\n", 2, "axis U is not supported"),
    ("o100 sub\n", 1, "no matching 'o100 endsub' follows"),
    ("o100 call\n", 1, "subroutine o100 is not defined here"),
    ("o<a> endsub\n", 1, "'o<a> endsub' outside its subroutine"),
    ("o1 while [1]\no1 endwhile\n", 1, "the program runs more than 1000 lines"),
    ("G0 X#<nope>\n", 1, "named parameter #<nope> is not defined"),
    ("G0 X[1/0]\n", 1, "division by zero"),
    ("G0 X[SQRT[-1]]\n", 1, "square root of a negative number"),
    ("#1=[1+]\n", 1, "a value is missing before"),
    ("G0 X[1+2\n", 1, "expression is not closed"),
    ("#6000=1\n", 1, "parameter number #6000 is out of range"),
    ("#5420=1\n", 1, "parameter #5420 is read-only"),
    ("G0 X1 @1 ^2\n", 1, "X or Y words cannot be mixed with polar coordinates"),
    ("G91 G0 @1\n", 1, "an incremental polar move (G91 @ ^) cannot start at the origin"),
    ("G0 X1.2.3\n", 1, "malformed number after X"),
    ("G0 X1\nG0 X\n", 2, "X word has no number"),
    ("G0 X1\n12 G0 X1\n", 2, "has no letter before it"),
    ("G0 X1 (open comment\n", 1, "comment is not closed"),
    ("G0 X1 ) \n", 1, "')' without a '('"),
    ("G0 X1 $\n", 1, "unexpected character '$'"),
    ("G0 X1 X2\n", 1, "two X words on one line"),
    ("G0 G1 X2 F60\n", 1, "two G codes from the same group (motion)"),
    ("G17 G18\n", 1, "two G codes from the same group (plane)"),
    ("M3 M5\n", 1, "two M codes from the same group (spindle)"),
    ("M62 P1 M67 E0 Q1\n", 1, "two M codes from the same group (I/O)"),
    ("G0 X1 N5\n", 1, "N word (line number) must come first"),
    ("X1\n", 1, "X/Y/Z words with no motion mode"),
    ("G1 X1 F10\nG94 G1 X2\n", 2, "G1 with no feed rate"),
    ("G1 X1 F60\nG80\nY1\n", 3, "X/Y/Z words with no motion mode"),
    ("G0 X1\nG1 X2\n", 2, "G1 with no feed rate"),
    ("G0 X1\nG2 X2 I1 F0\n", 2, "G2 with no feed rate"),
    ("G1 X1 F-5\n", 1, "negative F"),
    ("S-5 M3\n", 1, "negative S"),
    ("G1 X1 F60\nG2 X20 R4\n", 2, "arc radius R4 is too small to reach the end point"),
    ("G1 X1 F60\nG2 X1 Y0 R5\n", 2, "an R arc cannot end where it starts"),
    ("G1 X10 F60\nG2 X20 I5.1\n", 2, "radius to the end of the arc differs from radius to its start"),
    ("G1 X10 F60\nG2 X20 I0 J0\n", 2, "zero-radius arc"),
    ("G1 X10 F60\nG2 X20 I5 K1\n", 2, "K word given for an arc in the XY (G17) plane"),
    ("G1 X10 F60\nG18 G2 X20 I5 J1\n", 2, "J word given for an arc in the XZ (G18) plane"),
    ("G1 Y10 F60\nG19 G2 Y20 I5 J1\n", 2, "I word given for an arc in the YZ (G19) plane"),
    ("G1 X10 F60\nG2 X20 I5 R5\n", 2, "both a radius (R) and a centre"),
    ("G1 X10 F60\nG2 X20\n", 2, "G2 needs a centre (I, J, K) or a radius (R)"),
    ("G1 X10 F60\nG90.1 G2 X20 I15\n", 2, "J word missing in an absolute-centre arc (G90.1)"),
    ("G1 X10 F60\nX20 I5\n", 2, "I word with no G2 or G3"),
    ("G1 X10 F60\nX20 R5\n", 2, "R word with no G2 or G3"),
    ("G4\n", 1, "G4 needs a P word"),
    ("G4 P-1\n", 1, "G4 dwell time (P) must be >= 0"),
    ("G1 X10 F60\nG2 X20 I5 P1.5\n", 2, "P on G2 must be a whole number of turns"),
    ("G1 X10 F60\nG3 X20 I5 P0\n", 2, "P on G3 must be a whole number of turns"),
    ("G1 X10 F60\nG2 X20 I5 P2 G4\n", 2, "G4 and G2 on one line"),
    ("G1 X10 P2 F60\n", 1, "P word with nothing to use it"),
    ("G64 P0.1 M62 P1\n", 1, "two P words on one line"),
    ("G1 X10 F60 G64 M62 P1\n", 1, "P word claimed by two codes"),
    ("M62\n", 1, "M62 needs a P word"),
    ("M65 P1.5\n", 1, "M65 output number (P) must be a whole number"),
    ("M67 Q1\n", 1, "M67 needs an E word"),
    ("M68 E1\n", 1, "M68 needs a Q word"),
    ("M67 E-1 Q1\n", 1, "M67 analog output number (E) must be a whole number"),
    ("G0 X1 E2\n", 1, "E word with nothing to use it"),
    ("G0 X1 Q2\n", 1, "Q word with nothing to use it"),
    ("G0 X1" + "0" * 400 + "\n", 1, "number too large"),
    ("%\nG0 X1\n%\n", None, None),
    ("G0 X1\n%\n", 2, "'%' may only open and close the program"),
])
def test_bad_input_is_an_error_naming_the_line(text, line, message):
    if message is None:
        parse_gcode(text, "bad.ngc")
        return
    with pytest.raises(GcodeError) as err:
        parse_gcode(text, "bad.ngc", max_blocks=1000)
    assert err.value.where == f"bad.ngc:{line}"
    assert message in err.value.message
    assert str(err.value).startswith(f"bad.ngc:{line}: ")


def test_with_a_tool_table_an_unknown_tool_is_refused_and_without_one_every_tool_is_known():
    from flowmc.motion.gcode import parse_tool_table

    table = parse_tool_table("T1 P1 Z0.5 D6 ;six\n", "t.tbl")
    with pytest.raises(GcodeError, match="tool T2 is not in the tool table"):
        parse_gcode("T2 M6\n", "x.ngc", tool_table=table)
    with pytest.raises(GcodeError, match="tool T3 .D word. is not in the tool table"):
        parse_gcode("G41 D3\n", "x.ngc", tool_table=table)
    path = parse_gcode("T2 M6\nG43\nG0 Z1\n", "x.ngc")
    assert path.events()[0][1].tool == 2 and path[-1].end[2] == 1.0


def test_error_messages_quote_the_line():
    with pytest.raises(GcodeError, match=r"\(in: G2 X20 R4\)$"):
        parse_gcode("G1 X1 F60\nG2 X20 R4\n")


def test_error_messages_never_echo_terminal_escapes():
    with pytest.raises(GcodeError) as err:
        parse_gcode("G1 X1 F60\nG1 X\x1b]0;pwned\x07\x1b[2J\n")
    text = str(err.value)
    assert "\x1b" not in text and "\x07" not in text and "\\x1b]0;pwned\\x07\\x1b[2J" in text


def test_the_earliest_problem_is_reported_whatever_kind_it_is():
    # A word outside the subset before a line that does not even read, and the other way round.
    with pytest.raises(GcodeError) as err:
        parse_gcode("G0 X1\nG38.2 Z1\nG0 X$\n")
    assert err.value.where == "<text>:2"
    with pytest.raises(GcodeError) as err:
        parse_gcode("G0 X1\nG0 X$\nG38.2 Z1\n")
    assert err.value.where == "<text>:2" and "X word has no number" in err.value.message
    with pytest.raises(GcodeError) as err:
        parse_gcode("G1 X1 F60\nG2 X30 R1\nG0 X1 X2\n")
    assert err.value.where == "<text>:2"


def test_nothing_after_the_program_end_is_checked():
    p = parse_gcode("G0 X1\nM2\nG41 $$$ (\n")
    assert len(p) == 1


def test_segments_are_the_same_as_the_public_constructors_make():
    # The reader builds segments without their constructors (for speed); rebuilding each one
    # through Line/Arc/Dwell (which re-check everything) must give identical segments.
    text = """G21 G90 F600 S1000 M3
G0 X5 Y5 Z2
G1 Z-1 M62 P1
G2 X15 Y5 I5 J0 P2
G3 X25 Y5 R5 Z-2
M64 P2
G18 G2 X35 Z-2 I5 K0
G19 G3 Y15 Z-2 R5
G17 G91 G1 X1 Y1
G20 G2 X0.1 Y0 I0.05 J0
G4 P1 M67 E0 Q2
G21 G90 G0 X0 Y0 Z5
M2
"""
    path = parse_gcode(text, "b.ngc")
    state = ("feed", "rapid", "tool_down", "spindle", "outputs", "analog", "source")
    rebuilt = []
    for s in path:
        kw = {k: getattr(s, k) for k in state}
        if isinstance(s, Arc):
            rebuilt.append(Arc(s.start, s.end, s.center, s.normal_axis, s.ccw, s.turns, **kw))
        elif isinstance(s, Line):
            rebuilt.append(Line(s.start, s.end, **kw))
        else:
            rebuilt.append(Dwell(s.start, s.seconds, **kw))
    assert Path(rebuilt).digest() == path.digest()
    assert {s.kind for s in path} == {"line", "arc", "dwell"}
    for s in path:
        assert s.start.dtype == float and s.start.shape == (3,) and not s.start.flags.writeable
        assert type(s.feed) is float and type(s.spindle) is float and type(s.rapid) is bool
    assert path.gaps() == []


# ------------------------------------------------------------------ G-code out

def rich_path() -> Path:
    """Lines, rapids, arcs in every plane with helix and turns, full circles, dwells and tool state."""
    segs = []
    here = np.zeros(3)

    def add(seg):
        nonlocal here
        segs.append(seg)
        here = seg.end

    add(Line(here, (10, 5, 2), rapid=True, tool_down=False, feed=RAPID_FEED))
    add(Line(here, (10, 5, -1), feed=5.0, spindle=12000.0))
    add(Arc(here, (20, 5, -1), (15, 5, -1), normal_axis=2, ccw=False, feed=12.5, spindle=12000.0,
            outputs=((1, True),)))
    add(Arc(here, (20, 5, -3), (17, 5 + math.sqrt(3), 0), normal_axis=2, ccw=True, turns=2, feed=12.5,
            spindle=12000.0))
    add(Arc(here, (26.123456, 5, -3.5), (23.0617280, 5, -3.25), normal_axis=1, ccw=True, feed=7.0,
            spindle=-300.0, analog=((0, 2.5),)))
    add(Dwell(here, 1.25, feed=7.0, spindle=-300.0, outputs=((1, False), (2, True)), analog=((1, 0.75),)))
    add(Arc(here, (26.123456, 13, 0.5), (26.123456, 9, -1.5), normal_axis=0, ccw=False, feed=7.0,
            spindle=-300.0))
    add(Arc(here, here, here + np.array([0, -2.5, 0]), normal_axis=0, ccw=True, feed=7.0, spindle=0.0))
    add(Line(here, here, feed=7.0))
    add(Dwell(here, 0.0, feed=7.0, outputs=((2, False),)))
    add(Line(here, (0, 0, 5), rapid=True, tool_down=False, feed=RAPID_FEED))
    return Path(segs)


def assert_same_path(a: Path, b: Path, tol=1e-6):
    assert len(a) == len(b)
    for i, (s, t) in enumerate(zip(a, b)):
        assert s.kind == t.kind, i
        close(s.start, t.start, tol)
        close(s.end, t.end, tol)
        assert s.rapid == t.rapid and s.spindle == pytest.approx(t.spindle), i
        assert s.outputs == t.outputs, i
        assert [c for c, _ in s.analog] == [c for c, _ in t.analog], i
        close([v for _, v in s.analog], [v for _, v in t.analog], tol)
        if not s.rapid and not isinstance(s, Dwell):
            assert s.feed == pytest.approx(t.feed, rel=1e-9), i
        if isinstance(s, Arc):
            close(s.center, t.center, tol)
            assert (s.normal_axis, s.ccw, s.turns) == (t.normal_axis, t.ccw, t.turns), i
            assert s.sweep == pytest.approx(t.sweep, abs=1e-6), i
        if isinstance(s, Dwell):
            assert s.seconds == pytest.approx(t.seconds), i


def test_export_then_import_gives_back_the_same_path():
    path = rich_path()
    text = path_to_gcode(path)
    back = parse_gcode(text, "out.ngc")
    assert_same_path(path, back)
    again = path_to_gcode(back)
    assert again == text


def test_exported_text_uses_the_documented_header_and_words():
    text = path_to_gcode(rich_path(), blend_tolerance=0.05)
    lines = text.splitlines()
    assert lines[0] == "G21 G90 G91.1 G17 G94"
    assert lines[1] == "G64 P0.05"
    assert lines[-1] == "M2"
    assert "G0 X10 Y5 Z2" in lines
    assert "S12000 M3" in lines and "S300 M4" in lines and "M5" in lines
    assert "M62 P1" in lines and "M67 E0 Q2.5" in lines
    assert "M63 P1" not in lines and "M65 P1" in lines and "M64 P2" in lines and "M68 E1 Q0.75" in lines
    assert any(line.startswith("G18 G3 ") for line in lines)
    assert any(line.startswith("G19 G2 ") for line in lines)
    assert any(line.startswith("G3 ") and " P3" in line for line in lines)
    assert "G4 P1.25" in lines
    assert "G1" in lines  # a zero-length line keeps its explicit G1


def test_a_path_away_from_the_origin_starts_with_a_rapid_and_gaps_become_rapids():
    path = Path([Line((5, 5, 0), (6, 5, 0), feed=10.0), Line((7, 5, 0), (8, 5, 0), feed=10.0)])
    back = parse_gcode(path_to_gcode(path))
    assert [s.rapid for s in back] == [True, False, True, False]
    close(back[0].end, [5, 5, 0])
    close(back[2].start, [6, 5, 0])
    assert_same_path(path, Path([back[1], back[3]]))


def test_ellipses_and_nurbs_are_written_as_chords_within_tolerance():
    ellipse = EllipseArc.from_axes((0, 0, 0), 20.0, 8.0, 0.3, 0.0, math.pi, feed=10.0)
    # two spans: not what one G5 says
    nurbs = NurbsCurve([(0, 0, 0), (10, 20, 0), (20, 0, 0), (30, -20, 0), (40, 0, 0)], feed=10.0)
    tol = 0.01
    for seg in (ellipse, nurbs):
        path = Path([Line((0, 0, 0), seg.start, rapid=True, tool_down=False), seg])
        back = parse_gcode(path_to_gcode(path, chord_tolerance=tol))
        chords = moves(back)[1:]
        assert len(chords) > 10 and all(isinstance(c, Line) and not c.rapid for c in chords)
        close(chords[-1].end, seg.end, 1e-6)
        # every point of the curve is within tol of the chord polyline
        pts = seg.point_at(np.linspace(0, seg.length, 2000))
        a = np.array([c.start for c in chords])
        b = np.array([c.end for c in chords])
        ab = b - a
        t = np.clip(np.einsum("pkd,kd->pk", pts[:, None, :] - a[None], ab) / np.einsum("kd,kd->k", ab, ab), 0, 1)
        dist = np.linalg.norm(pts[:, None, :] - (a[None] + t[..., None] * ab[None]), axis=2).min(axis=1)
        assert dist.max() <= tol + 1e-6


def test_an_arc_too_small_to_print_is_written_as_a_line_not_a_full_circle():
    tiny = Arc((1, 0, 0), (math.cos(1e-8), math.sin(1e-8), 0), (0, 0, 0), feed=10.0)
    full = Arc((1, 0, 0), (1, 0, 0), (0, 0, 0), feed=10.0)
    back = parse_gcode(path_to_gcode(Path([Line((0, 0, 0), (1, 0, 0), feed=10.0), tiny, full])))
    assert [s.kind for s in back] == ["line", "line", "arc"]
    assert back[2].sweep == pytest.approx(2 * math.pi)


def test_single_bezier_spans_are_written_as_g5_and_g5_1_and_read_back_exactly():
    cubic = NurbsCurve([(1, 1, -1), (11, 21, -1), (31, -19, -1), (41, 1, -1)], degree=3, feed=10.0)
    quad = NurbsCurve([(41, 1, -1), (45, 10, -1), (50, 1, -1)], degree=2, feed=5.0)
    tilted = NurbsCurve([(50, 1, -1), (55, 5, 0), (60, 1, -1)], degree=2, feed=5.0)  # not in an XY plane
    path = Path([Line((0, 0, 0), (1, 1, -1), feed=10.0), cubic, quad, tilted])
    text = path_to_gcode(path, chord_tolerance=0.01)
    assert "\nG5 X41 I10 J20 P-10 Q-20\nG5.1 X50 I4 J9 F300\n" in text
    back = moves(parse_gcode(text))
    assert [s.kind for s in back[:3]] == ["line", "nurbs", "nurbs"] and len(back) > 10
    for ours, seg in zip(back[1:3], (cubic, quad)):
        assert ours.degree == seg.degree
        close(ours.control_points, seg.control_points)
        assert ours.feed == pytest.approx(seg.feed)


def test_path_events_are_written_as_the_codes_that_make_them_and_read_back():
    events = [PathEvent("pause", "check the clamps"), PathEvent("optional_pause"), PathEvent("pallet_change"),
              PathEvent("tool_change", "change to tool T3", 3), PathEvent("index", "index B", axes=(("B", 45.0),))]
    segs = []
    for k, event in enumerate(events):
        segs += [Line((k, 0, 0), (k + 1, 0, 0), feed=10.0), Dwell((k + 1, 0, 0), 0.0, event)]
    text = path_to_gcode(Path(segs))
    for code in ("(MSG, check the clamps)\nM0", "\nM1\n", "\nM60\n", "\nT3 M6\n", "\nG0 B45\n"):
        assert code in text
    assert "G4" not in text
    back = [s.event for s in parse_gcode(text) if isinstance(s, Dwell)]
    assert [(e.kind, e.tool, e.axes) for e in back] == [(e.kind, e.tool, e.axes) for e in events]
    assert back[0].message == "check the clamps"
    # for a machine that runs the path straight through (the LinuxCNC card, flowmc compare): dwells
    straight = path_to_gcode(Path(segs), events="dwells")
    assert straight.count("G4 P0\n") == len(events) and not any(c in straight for c in ("M0", "M6", "B45"))
    with pytest.raises(GcodeError, match="events must be"):
        path_to_gcode(Path(segs), events="skip")


def test_an_arc_whose_radius_prints_as_zero_is_written_as_a_line():
    # cutter compensation with a tool the size of the hole: a helix of zero radius down the hole's axis
    helix = Arc((0, 0, 0), (0, 0, -1), (1e-8, 0, 0), feed=10.0)
    back = moves(parse_gcode(path_to_gcode(Path([helix]))))
    assert [s.kind for s in back] == ["line"]
    close(back[0].end, (0, 0, -1))


def test_decimals_control_the_printed_precision():
    path = Path([Line((0, 0, 0), (1 / 3, 0, 0), feed=10.0)])
    assert "X0.333 " in path_to_gcode(path, decimals=3) or "X0.333\n" in path_to_gcode(path, decimals=3)
    with pytest.raises(GcodeError, match="decimals"):
        path_to_gcode(path, decimals=0)


def test_bad_output_channel_is_an_error_naming_the_segment():
    path = Path([Line((0, 0, 0), (1, 0, 0), feed=10.0, outputs=((-1, True),), source="row 1")])
    with pytest.raises(GcodeError, match=r"^segment 1 \(row 1\): output channel"):
        path_to_gcode(path)


def test_write_gcode_is_atomic_and_reads_back(tmp_path):
    target = tmp_path / "out.ngc"
    target.write_text("old contents\n")
    write_gcode(rich_path(), target)
    assert_same_path(rich_path(), read_gcode(target))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.ngc"]
    with pytest.raises(GcodeError) as err:
        write_gcode(rich_path(), tmp_path / "no" / "such" / "dir.ngc")
    assert "dir.ngc" in str(err.value)
    # a failed export leaves the old file as it was
    with pytest.raises(GcodeError):
        write_gcode(rich_path(), target, decimals=99)
    assert_same_path(rich_path(), read_gcode(target))
