"""``flowmc sweep`` from the command line: tables and report, exit codes, Ctrl-C and --resume."""

from __future__ import annotations

import csv
import os
import re
import signal
import subprocess
import sys
import time

import pyarrow.parquet as pq
import pytest
from sweep_helpers import ARM, gcode_graph, journal, run_cli


def read_csv(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def test_a_sweep_writes_csv_parquet_and_a_report(tmp_path):
    graph = gcode_graph(tmp_path, max_cycle_time=5.87)
    (tmp_path / "rules.csv").write_text("rule,plan.tolerance\nblend,0.05\njunction_deviation,0.02\n")
    proc = run_cli("sweep", graph, "--over", "gcode.file=programs/*.ngc", "--table", "rules.csv", "--workers", "2",
                   "--pareto", "cycle_time,max:plan.tolerance", "--plot", "cycle_time", cwd=tmp_path)
    assert proc.returncode == 1, proc.stderr  # the chamfered square fails its check: exit 1, rows written
    out = tmp_path / "gcode-sweep"
    rows = read_csv(out / "rows.csv")
    assert len(rows) == 6 and [r["variant"] for r in rows] == [str(k) for k in range(6)]
    assert list(rows[0])[:10] == ["variant", "status", "error", "duration_s", "ran", "cached", "worker",
                                  "gcode.file", "rule", "plan.tolerance"]
    assert [r["status"] for r in rows] == ["done", "done", "failed", "failed", "done", "done"]
    assert "check failed: cycle time = 6.496" in rows[2]["error"] and rows[2]["out.checked"] == ""
    assert float(rows[2]["out.cycle_time"]) == pytest.approx(6.496, abs=0.01)
    assert pq.read_table(out / "rows.parquet").to_pylist()[0]["out.cycle_time"] == float(rows[0]["out.cycle_time"])
    report = (out / "report.html").read_text()
    assert "Pareto front" in report and "cycle_time against gcode.file" in report and "Plotly.newPlot" in report
    assert "6 variants: 4 done, 2 failed" in proc.stdout
    assert "variant 2 failed: node 'check'" in proc.stderr
    again = run_cli("sweep", graph, "--over", "gcode.file=programs/*.ngc", cwd=tmp_path)
    assert again.returncode == 2 and "holds the rows of an earlier sweep: --resume" in again.stderr


def test_progress_shows_done_failed_left_and_the_rate(tmp_path):
    """A tqdm bar on a terminal (a pseudo-terminal here), a plain line in logs."""
    import fcntl
    import pty
    import struct
    import termios

    args = ["sweep", str(ARM), "--grid", "lookahead.tolerance=0.001,0.08", "--grid", "rule=blend,junction_deviation",
            "--workers", "1"]
    leader, follower = pty.openpty()
    fcntl.ioctl(follower, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 120, 0, 0))  # a 120-column terminal
    proc = subprocess.Popen([sys.executable, "-m", "flowmc", *args, "--out", str(tmp_path / "tty")],
                            stdout=subprocess.DEVNULL, stderr=follower, stdin=subprocess.DEVNULL)
    os.close(follower)
    shown = b""
    while True:
        try:
            chunk = os.read(leader, 4096)
        except OSError:  # the sweep ended and closed the terminal
            break
        if not chunk:
            break
        shown += chunk
    os.close(leader)
    assert proc.wait(timeout=60) == 1  # variant 0 fails the graph's check
    text = shown.decode(errors="replace")
    assert "4/4" in text and "done 3, failed 1, left 0" in text and "variant/s" in text, text
    logged = run_cli(*args, "--out", tmp_path / "log")
    assert re.search(r"\[4/4\] done 3, failed 1, left 0, [0-9.]+ variants/s", logged.stderr), logged.stderr


@pytest.mark.parametrize("args, message", [
    ((), "say what to sweep"),
    (("--grid", "lookahead.tolerance=0.1", "--workers", "0"), "--workers must be at least 1"),
    (("--grid", "lookahead.tolerance=0.1", "--devices", "maybe"), "invalid choice: 'maybe'"),
    (("--grid", "lookahead.tolerance=0.1", "--scheduler", "tcp://127.0.0.1:1"), "--scheduler goes with --executor dask"),
])
def test_bad_arguments_exit_2(tmp_path, args, message):
    proc = run_cli("sweep", ARM, "--out", tmp_path / "out", *args, cwd=tmp_path)
    assert proc.returncode == 2 and message in proc.stderr and "Traceback" not in proc.stderr


def test_an_unknown_output_to_plot_is_named(tmp_path):
    proc = run_cli("sweep", ARM, "--grid", "lookahead.tolerance=0.05", "--plot", "speed", "--out", tmp_path / "o",
                   "--workers", "1")
    assert proc.returncode == 2
    assert "--plot: no output 'speed' (outputs: stop_and_go_s, lookahead_s, ratio, metrics.cycle_time" in proc.stderr
    assert (tmp_path / "o" / "rows.csv").exists()


@pytest.mark.parametrize("executor", ["local", "dask"])
def test_ctrl_c_keeps_the_rows_done_and_resume_finishes(tmp_path, executor):
    out = tmp_path / "out"
    args = [sys.executable, "-m", "flowmc", "sweep", str(ARM), "--grid", "lookahead.tolerance=0.002:0.1:0.002",
            "--grid", "rule=blend,junction_deviation", "--executor", executor, "--workers", "2", "--batch", "2",
            "--out", str(out)]
    proc = subprocess.Popen(args, start_new_session=True, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and len(journal(out) if (out / "rows.jsonl").exists() else []) < 10:
        time.sleep(0.05)
    os.killpg(proc.pid, signal.SIGINT)  # Ctrl-C at a terminal reaches the whole process group
    _stdout, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 130, stderr
    assert "interrupted:" in stderr and "--resume" in stderr and "Traceback" not in stderr
    kept = journal(out)
    assert 10 <= len(kept) < 100
    assert len(read_csv(out / "rows.csv")) == len(kept)
    resumed = run_cli("sweep", ARM, "--grid", "lookahead.tolerance=0.002:0.1:0.002", "--grid",
                      "rule=blend,junction_deviation", "--executor", executor, "--workers", "2", "--out", out, "--resume")
    assert f"({len(kept)} from an earlier run)" in resumed.stdout
    rows = journal(out)
    assert len(rows) == 100 and len({r["key"] for r in rows}) == 100  # nothing ran twice
    assert rows[:len(kept)] == kept
    table = read_csv(out / "rows.csv")
    assert [int(r["variant"]) for r in table] == list(range(100))
    failed = any(r["status"] != "done" for r in table)
    assert resumed.returncode == (1 if failed else 0), resumed.stderr


def test_a_worker_that_dies_leaves_lost_rows_that_resume_runs_again(tmp_path):
    import psutil

    out = tmp_path / "out"
    args = ["sweep", str(ARM), "--grid", "lookahead.tolerance=0.002:0.1:0.002", "--grid", "rule=blend,junction_deviation",
            "--workers", "2", "--batch", "2", "--out", str(out)]
    proc = subprocess.Popen([sys.executable, "-m", "flowmc", *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and len(journal(out) if (out / "rows.jsonl").exists() else []) < 6:
        time.sleep(0.05)
    workers = [p for p in psutil.Process(proc.pid).children(recursive=True) if "spawn_main" in " ".join(p.cmdline())]
    assert workers
    workers[0].kill()  # a worker process dies mid-sweep
    _stdout, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 1 and "Traceback" not in stderr
    table = read_csv(out / "rows.csv")
    lost = [r for r in table if r["status"] == "lost"]
    assert lost and "the worker running it was lost" in lost[0]["error"]
    resumed = run_cli(*args, "--resume")
    assert resumed.returncode in (0, 1), resumed.stderr
    table = read_csv(out / "rows.csv")
    assert len(table) == 100 and not [r for r in table if r["status"] == "lost"]
