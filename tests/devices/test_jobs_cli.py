"""``flowmc run`` is the explicit Start on the command line: a progress bar on a terminal, lines off it,
and Ctrl-C a controlled stop (exit 130, saying where it stopped, outputs safe)."""

import os
import pty
import re
import select
import signal
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
GRAPH = str(REPO / "graphs" / "thesis_3axis.flowmc.json")


def _on_a_terminal(args, interrupt_after: float | None = None, timeout: float = 60.0,
                   once: bytes = b"") -> tuple[int, str]:
    """Run ``flowmc`` on a pseudo-terminal; SIGINT (what Ctrl-C sends) ``interrupt_after`` s after the
    output first shows ``once`` (so a loaded machine cannot send it before the job runs)."""
    pid, fd = pty.fork()
    if pid == 0:  # the child: flowmc on the terminal
        # as a terminal's foreground job has it: a suite started in the background (`pytest &`) ignores
        # SIGINT, and Python keeps an inherited SIG_IGN, so Ctrl-C would not reach flowmc at all
        signal.signal(signal.SIGINT, signal.SIG_DFL)
        os.execv(sys.executable, [sys.executable, "-m", "flowmc", *args])
    out, t0, seen, sent = b"", time.monotonic(), None, False
    while time.monotonic() - t0 < timeout:
        ready, _, _ = select.select([fd], [], [], 0.1)
        if ready:
            try:
                data = os.read(fd, 4096)
            except OSError:
                break
            if not data:
                break
            out += data
        if seen is None and once in out:
            seen = time.monotonic()
        if interrupt_after is not None and not sent and seen is not None and time.monotonic() - seen > interrupt_after:
            os.kill(pid, signal.SIGINT)
            sent = True
    _, status = os.waitpid(pid, 0)
    return os.waitstatus_to_exitcode(status), out.decode(errors="replace")


def test_ctrl_c_is_a_controlled_stop_with_exit_130_saying_where():
    code, text = _on_a_terminal(["run", GRAPH, "--realtime", "--speed", "2"], interrupt_after=1.0,
                                once="s left".encode())
    assert code == 130, text
    assert "stopped by Ctrl-C: job card: aborted: stopped by the operator at segment" in text
    assert "outputs left safe" in text and "Traceback" not in text
    assert "━" in text and "s left" in text  # the progress bar was drawn


def test_off_a_terminal_each_job_says_its_state_and_the_run_ends_done():
    proc = subprocess.run([sys.executable, "-m", "flowmc", "run", GRAPH, "--realtime", "--speed", "20"],
                          capture_output=True, text=True, timeout=120, cwd=REPO)
    assert proc.returncode == 0, proc.stderr
    assert "job card: running" in proc.stderr and "job card: done" in proc.stderr
    assert "━" not in proc.stderr
    assert '"outcome": "done"' in proc.stdout


def test_start_at_needs_a_program_job():
    proc = subprocess.run([sys.executable, "-m", "flowmc", "run", GRAPH, "--start-at", "home:2"],
                          capture_output=True, text=True, timeout=120, cwd=REPO)
    assert proc.returncode == 2 and "'home' is not a program job (program jobs: card)" in proc.stderr


def test_start_line_names_the_job_and_a_program_without_gcode_lines_says_so():
    proc = subprocess.run([sys.executable, "-m", "flowmc", "run", GRAPH, "--start-line", "home:2"],
                          capture_output=True, text=True, timeout=120, cwd=REPO)
    assert proc.returncode == 2 and "--start-line home:2: 'home' is not a program job" in proc.stderr
    proc = subprocess.run([sys.executable, "-m", "flowmc", "run", GRAPH, "--start-line", "3"],
                          capture_output=True, text=True, timeout=120, cwd=REPO)
    assert proc.returncode != 0 and "no motion at G-code line 3 or after it" in proc.stderr


def test_start_line_runs_on_the_grbl_simulator_graph_from_that_line():
    """The teaching machine streams to the GRBL protocol simulator: --start-line starts it at that line."""
    graph = str(REPO / "graphs" / "teaching_machine.flowmc.json")
    proc = subprocess.run([sys.executable, "-m", "flowmc", "run", graph, "--start-line", "7"],
                          capture_output=True, text=True, timeout=120, cwd=REPO)
    assert proc.returncode == 0, proc.stderr
    # line 7 is G1 X0 Y30 after an arc ending at (30, 30): the blended path (tolerance 0.01 mm) enters it
    # a little after the corner, on the line, and the job starts at its first setpoint there
    at = re.search(r"job grbl: started at segment 5 \(text:7\) at X ([-\d.]+), Y ([-\d.]+), Z ([-\d.]+) mm", proc.stderr)
    assert at, proc.stderr
    x, y, z = map(float, at.groups())
    assert 29.9 < x < 30.0 and abs(y - 30.0) <= 0.01 and z == 0.0, (x, y, z)
    sent = re.search(r"job grbl: sent to GRBL as: G0 X([-\d.]+) Y([-\d.]+) ", proc.stderr)
    assert sent and round(float(sent[1]), 3) == x and round(float(sent[2]), 3) == y, proc.stderr
    assert "job grbl: done" in proc.stderr
    assert '"outcome": "done"' in proc.stdout
