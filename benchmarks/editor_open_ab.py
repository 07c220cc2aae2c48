"""First opens of the editor page from two (or more) checkouts, alternating in one run (benchmarks/editor.py's
open row measures one checkout at a time; on a shared machine only a side-by-side run compares).

Each checkout serves the same generated graph from a process of its own (this file with ``--serve``, that
checkout's ``flowmc`` on the path); one headless Chromium opens each in a fresh context in turn, the order
reversed every round, round 0 a warm-up. An open is ``page.goto`` until the frame in which every node body is in the
scene and the camera is locked has been drawn (as ``EditorPage.open``). Beside it, the CPU time Chromium's processes
spent during the open (read from /proc: the browser, its GPU process, the page's renderer, utilities), and the GPU
process's share.

Run: ``python3 benchmarks/editor_open_ab.py [--rounds 6] [--nodes 120] A=/path/to/checkout B=/other/checkout``
(``git archive HEAD | tar -x -C /tmp/base`` makes a checkout of a commit). Prints each open and a table of medians.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
_TICK = os.sysconf("SC_CLK_TCK")


def serve(root: Path, nodes: int) -> None:
    """Serve ``nodes`` nodes (4: the example graph) from the checkout at ``root`` until stdin closes."""
    sys.path[:0] = [str(root), str(root / "tests" / "ui")]
    from editor_graphs import chain_file, example_file
    from flowmc.ui.app import Editor

    folder = Path(tempfile.mkdtemp())
    editor = Editor(chain_file(folder, nodes) if nodes > 4 else example_file(folder), port=0)
    print("EDITOR", editor.url, len(editor.canvas.boxes), flush=True)
    sys.stdin.read()
    editor.close()


def _processes() -> dict[int, tuple[int, str]]:
    """pid -> (parent pid, command line) of every process this user can see."""
    out = {}
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                stat = (entry / "stat").read_text()
                cmd = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
            except OSError:
                continue
            out[int(entry.name)] = (int(stat[stat.rindex(")") + 2:].split()[1]), cmd)
    return out


def chromium_cpu() -> dict[int, tuple[str, float]]:
    """pid -> (kind, CPU seconds) of the Chromium processes below this one (kind: browser, gpu-process, ...)."""
    procs, mine, out = _processes(), {os.getpid()}, {}
    changed = True
    while changed:
        grown = {pid for pid, (parent, _cmd) in procs.items() if parent in mine} - mine
        changed, mine = bool(grown), mine | grown
    for pid in mine:
        cmd = procs.get(pid, (0, ""))[1]
        if "chrom" not in cmd.split(" ")[0]:
            continue
        try:
            fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        kind = next((a[7:] for a in cmd.split() if a.startswith("--type=")), "browser")
        out[pid] = (kind, (int(fields[11]) + int(fields[12])) / _TICK)
    return out


def spent(before: dict[int, tuple[str, float]], after: dict[int, tuple[str, float]]) -> tuple[float, float]:
    """(all Chromium processes, the GPU process) CPU seconds between two readings."""
    total = gpu = 0.0
    for pid, (kind, cpu) in after.items():
        delta = cpu - before.get(pid, (kind, 0.0))[1]
        total += delta
        gpu += delta if kind == "gpu-process" else 0.0
    return total, gpu


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=6)
    parser.add_argument("--nodes", type=int, default=120)
    parser.add_argument("--serve", nargs=2, metavar=("ROOT", "NODES"), help=argparse.SUPPRESS)
    parser.add_argument("checkouts", nargs="*", metavar="LABEL=PATH")
    args = parser.parse_args()
    if args.serve:
        serve(Path(args.serve[0]), int(args.serve[1]))
        return 0
    if len(args.checkouts) < 2 or any("=" not in c for c in args.checkouts):
        parser.error("give two or more LABEL=PATH checkouts")
    sys.path[:0] = [str(ROOT / "tests" / "ui")]
    from browser_helpers import NEXT_FRAME, VIEWPORT, chromium, opened

    servers = []
    for spec in args.checkouts:
        label, path = spec.split("=", 1)
        proc = subprocess.Popen([sys.executable, str(Path(__file__).resolve()), "--serve", path, str(args.nodes)],
                                stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, cwd=tempfile.gettempdir())
        while not (line := proc.stdout.readline()).startswith("EDITOR"):
            if not line:
                raise SystemExit(f"{label}: the editor from {path} did not start")
        _tag, url, count = line.split()
        servers.append((label, proc, url, int(count)))
    samples: dict[str, list[tuple[float, float, float]]] = {label: [] for label, *_rest in servers}
    loads = []
    try:
        with chromium() as browser:
            for rnd in range(args.rounds + 1):
                for label, _proc, url, count in servers if rnd % 2 else servers[::-1]:
                    page = browser.new_page(viewport=VIEWPORT)
                    before, start = chromium_cpu(), time.perf_counter()
                    page.goto(url)
                    page.wait_for_function(opened(count), timeout=120000)
                    page.evaluate(NEXT_FRAME)
                    wall = time.perf_counter() - start
                    cpu, gpu = spent(before, chromium_cpu())
                    page.close()
                    if rnd:
                        samples[label].append((wall, cpu, gpu))
                        print(f"round {rnd} {label}: open {wall:.2f} s, browser CPU {cpu:.2f} s (GPU process {gpu:.2f} s)",
                              flush=True)
                loads.append(os.getloadavg()[0])
    finally:
        for _label, proc, *_rest in servers:
            proc.stdin.close()
            proc.wait(30)
    print(f"\nfirst opens, {args.nodes} nodes, {args.rounds} rounds alternating, load {min(loads):.1f}-{max(loads):.1f}"
          " (medians)\n")
    print(f"{'checkout':<12} {'open':>8} {'CPU':>8} {'GPU proc':>9}   raw opens")
    for label, rows in samples.items():
        wall, cpu, gpu = (statistics.median(col) for col in zip(*rows))
        print(f"{label:<12} {wall:>6.2f} s {cpu:>6.2f} s {gpu:>7.2f} s   {' '.join(f'{r[0]:.2f}' for r in rows)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
