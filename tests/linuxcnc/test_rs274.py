"""LinuxCNC's standalone interpreter (rs274) as flowmc's reference: moves, events, lines and errors.

Programs are small and written here; expected values come from hand geometry.
"""

import numpy as np
import pytest

from flowmc.devices.linuxcnc.rs274 import ARC, FEED, NURBS, TRAVERSE, number_lines, parse_canon, run_rs274, run_rs274_file
from flowmc.errors import GcodeError

pytestmark = pytest.mark.linuxcnc


def test_lines_and_traverses_in_mm_with_feed_in_mm_per_s_and_source_lines():
    prog = run_rs274("G21 G90\n\n(a comment)\nG0 X5 Y5\nG1 X10 F600\nY20 Z-1\nM2\n", name="p.ngc")
    assert prog.kind.tolist() == [TRAVERSE, FEED, FEED]
    np.testing.assert_allclose(prog.start, [[0, 0, 0], [5, 5, 0], [10, 5, 0]])
    np.testing.assert_allclose(prog.end, [[5, 5, 0], [10, 5, 0], [10, 20, -1]])
    assert np.isnan(prog.feed[0]) and prog.feed[1:].tolist() == [10.0, 10.0]  # F600 mm/min
    assert prog.line.tolist() == [4, 5, 6]
    assert np.all(prog.normal_axis == -1) and np.all(np.isnan(prog.center))
    np.testing.assert_allclose(prog.end_position, [10, 20, -1])


def test_arcs_in_each_plane_have_centre_normal_axis_and_signed_turn():
    text = "\n".join([
        "G21 G90 G17",
        "G1 X10 F1200",
        "G3 X0 Y10 I-10 J0",          # quarter circle ccw about the origin, XY
        "G18 G2 X10 Z10 I10 K0",      # from (0,10,0): centre (10,10,0) in XZ
        "G19 G3 Y0 Z0 J-5 K-5",       # from (10,10,10): centre (10,5,5) in YZ
        "G17 G2 X10 Y0 Z-3 I-5 J0 P2",  # helix, two turns clockwise
        "M2",
    ])
    prog = run_rs274(text)
    assert prog.kind.tolist() == [FEED, ARC, ARC, ARC, ARC]
    np.testing.assert_allclose(prog.center[1], [0, 0, 0])
    np.testing.assert_allclose(prog.center[2], [10, 10, 0])
    np.testing.assert_allclose(prog.center[3], [10, 5, 5])
    np.testing.assert_allclose(prog.center[4], [5, 0, 0])  # normal coordinate: the start's
    assert prog.normal_axis[1:].tolist() == [2, 1, 0, 2]
    assert prog.turn[1:].tolist() == [1, -1, 1, -2]
    np.testing.assert_allclose(prog.end[1:], [[0, 10, 0], [10, 10, 10], [10, 0, 0], [10, 0, -3]])
    for k in range(1, 5):  # every arc ends on its circle (radius measured in its plane)
        plane = [i for i in range(3) if i != prog.normal_axis[k]]
        r0 = np.linalg.norm((prog.start[k] - prog.center[k])[plane])
        r1 = np.linalg.norm((prog.end[k] - prog.center[k])[plane])
        assert r0 == pytest.approx(r1, abs=1e-4)


def test_radius_form_arc_centre_is_equidistant_and_on_the_clockwise_side():
    prog = run_rs274("G21 G90\nG1 X0 Y0 F600\nG2 X10 Y0 R5\nG2 X20 Y0 R5.590170\nM2\n")
    np.testing.assert_allclose(prog.center[1], [5, 0, 0], atol=1e-4)
    # chord 10, R = 5.59017: centre 2.5 off the chord's middle, below it for a short clockwise arc
    np.testing.assert_allclose(prog.center[2], [15, -2.5, 0], atol=1e-4)


def test_inch_programs_come_back_in_mm():
    prog = run_rs274("G20 G90\nG1 X1 Y-0.5 F10\nG21\nG1 X30\nM2\n")
    np.testing.assert_allclose(prog.end, [[25.4, -12.7, 0], [30, -12.7, 0]])
    assert prog.feed[0] == pytest.approx(25.4 * 10 / 60)
    assert prog.feed[1] == pytest.approx(25.4 * 10 / 60)  # F10 in/min stays that speed after G21


def test_dwell_spindle_and_outputs_are_events_in_order_between_moves():
    text = "G21\nG1 X1 F60\nM62 P1\nM65 P2\nM67 E0 Q2.5\nM68 E1 Q-3\nS1200 M4\nG4 P0.5\nG1 X2\nM5\nM2\n"
    prog = run_rs274(text)
    wanted = {
        "SET_MOTION_OUTPUT_BIT": (3, (1.0,)),
        "CLEAR_AUX_OUTPUT_BIT": (4, (2.0,)),
        "SET_MOTION_OUTPUT_VALUE": (5, (0.0, 2.5)),
        "SET_AUX_OUTPUT_VALUE": (6, (1.0, -3.0)),
        "SET_SPINDLE_SPEED": (7, (0.0, 1200.0)),
        "START_SPINDLE_COUNTERCLOCKWISE": (7, (0.0,)),
        "DWELL": (8, (0.5,)),
    }
    got = {e.name: e for e in prog.events if e.name in wanted}
    for name, (line, values) in wanted.items():
        assert got[name].line == line and got[name].values == values, name
        assert got[name].index == 1  # after the first move, before the second
    stop = [e for e in prog.events if e.name == "STOP_SPINDLE_TURNING" and e.line == 10]
    assert stop and stop[0].index == 2


def test_tool_changes_leave_the_path_alone():
    prog = run_rs274("G21 G90\nT3 M6\nG43 H3\nG1 X5 Z1 F600\nG49\nM2\n")
    np.testing.assert_allclose(prog.end, [[5, 0, 1]])


def test_existing_n_words_block_delete_and_percent_lines_keep_file_line_numbers():
    text = "%\nN10 G21 G90\n/N20 G1 X1 F60\nn 3 0 G1 X2\n\nG1 X3\n%\n"
    numbered = number_lines(text).splitlines()
    assert numbered[0] == "%" and numbered[6] == "%"
    assert numbered[1] == "N2 G21 G90" and numbered[2] == "/N3 G1 X1 F60" and numbered[3] == "N4 G1 X2"
    prog = run_rs274(text)
    assert prog.line.tolist() == [3, 4, 6]


def test_line_numbers_past_99999_are_kept():
    text = "G21 G90\n" + "(x)\n" * 100_010 + "G1 X1 F60\nM2\n"
    prog = run_rs274(text)
    assert prog.line.tolist() == [100_012]


@pytest.mark.parametrize("text, line, words", [
    ("G21\nG1 X1 F60\nG1 X2 Q\nM2\n", 3, "reading real value"),
    ("G21\nG1 X1 F60\nG1 X2 ZZ\nM2\n", 3, "unary operation"),
    ("G21\nG1 X10 F60\nG2 X40 Y0 I1 J0\nM2\n", 3, "Radius to end of arc differs"),
    ("G21\nG1 X10 F60\nG2 X40 Y0 R1\nM2\n", 3, "Arc radius too small"),
    ("G21\nG7.5 X1\nM2\n", 2, "Unknown g code"),
    ("G21\nG1 X1\nM2\n", 2, "zero feed rate"),
])
def test_refused_programs_raise_gcode_error_naming_the_line(text, line, words):
    with pytest.raises(GcodeError) as err:
        run_rs274(text, name="bad.ngc")
    assert err.value.where == f"bad.ngc:{line}"
    assert words in err.value.message
    assert "N" + str(line) not in err.value.message  # our numbering is not shown


def test_files_are_named_in_errors(tmp_path):
    f = tmp_path / "part.ngc"
    f.write_text("G21\nG1 X1 F60\nG2 X5 Y0 I10 J0\nM2\n")
    with pytest.raises(GcodeError) as err:
        run_rs274_file(f)
    assert err.value.where == "part.ngc:3"
    with pytest.raises(GcodeError) as err:
        run_rs274_file(tmp_path / "missing.ngc")
    assert "missing.ngc" in str(err.value)


def test_splines_are_moves_without_geometry_because_rs274_prints_no_control_points():
    prog = run_rs274("G21 G90 G1 X0 F600\nG5 X10 Y10 I5 J0 P5 Q0\nG1 X20\nM2\n", name="s.ngc")
    assert list(prog.kind) == [FEED, NURBS, FEED] and list(prog.line) == [1, 2, 3]
    assert np.isnan(prog.end[1]).all() and np.isnan(prog.start[2]).all()
    np.testing.assert_allclose(prog.end[2], [20, 10, 0])  # the interpreter knows where the spline ended


def test_a_rigid_tap_goes_down_and_back_and_synchronised_moves_have_no_f_feed():
    prog = run_rs274("G21 G90 S500 M3 F600\nG0 X1 Y1 Z2\nG33.1 Z-5 K1\nG33 Z-6 K1\nG1 Z0\nM2\n")
    assert list(prog.kind) == [TRAVERSE, FEED, FEED, FEED, FEED]
    np.testing.assert_allclose(prog.end[1:4], [[1, 1, -5], [1, 1, 2], [1, 1, -6]])
    assert np.isnan(prog.feed[1:4]).all() and prog.feed[4] == pytest.approx(10.0)


def test_parse_canon_reads_a_listing_without_running_anything():
    listing = "\n".join([
        "    1 N..... USE_LENGTH_UNITS(CANON_UNITS_MM)",
        "    2 N7     SET_FEED_RATE(300.0000)",
        "    3 N7     STRAIGHT_FEED(3.0000, 4.0000, 0.0000, 0.0000, 0.0000, 0.0000)",
        "    4 N8     ARC_FEED(0.0000, 5.0000, 0.0000, 0.0000, 1, 0.0000, 0.0000, 0.0000, 0.0000)",
        "    5 N9     DWELL(1.5000)",
    ])
    prog = parse_canon(listing, name="x")
    assert prog.line.tolist() == [7, 8] and prog.feed.tolist() == [5.0, 5.0]
    np.testing.assert_allclose(prog.start[1], [3, 4, 0])
    np.testing.assert_allclose(prog.center[1], [0, 0, 0])
    assert prog.turn[1] == 1 and prog.normal_axis[1] == 2
    assert [(e.name, e.index, e.line, e.values) for e in prog.events] == [("DWELL", 2, 9, (1.5,))]


def test_runs_at_the_same_time_do_not_crash_each_other():
    """rs274 maps its tool table at $HOME/.tool.mmap after truncating it; runs that shared one HOME died
    with SIGBUS ("rs274 failed without a message") when tests or sweep workers ran them side by side."""
    from concurrent.futures import ThreadPoolExecutor

    text = "G21 G90\n" + "".join(f"G1 X{i % 7} Y{i % 5} F600\n" for i in range(200)) + "M2\n"
    with ThreadPoolExecutor(16) as pool:
        runs = list(pool.map(lambda _: run_rs274(text, name="same.ngc"), range(48)))
    assert all(len(prog.kind) == 200 for prog in runs)
