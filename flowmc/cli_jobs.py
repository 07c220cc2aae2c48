"""``flowmc run``'s jobs: the explicit Start on the command line, a progress bar per job on a terminal,
and Ctrl-C as a controlled stop.

The jobs run on a worker thread while the main thread waits, so Ctrl-C (a KeyboardInterrupt, which
Python raises in the main thread) is caught here and turned into a stop: the running job decelerates
along its path and leaves the outputs safe, and no other job starts. A second Ctrl-C is an e-stop.
The caller exits with 130 and says where it stopped.

The bar is rich's: rich is already installed with viser (no new dependency), and its ``Progress``
takes custom columns, so the bar shows the job's own time left at the current overrides (what the
runner computes from the program) rather than an estimate from the speed so far, and the segment or
G-code line it is on. Off a terminal, each job's state changes are printed as lines instead. A
program stop (M0, M6, M1 with ``--optional-stop``) on a paced run waits for Enter.
"""

from __future__ import annotations

import sys
import threading
from typing import Any, TextIO

__all__ = ["JobConsole"]


class JobConsole:
    """Starts a prepared run and shows its jobs; ``interrupted`` tells whether Ctrl-C stopped it."""

    def __init__(self, stream: TextIO | None = None, *, bar: bool | None = None, quiet: bool = False):
        self.stream = stream or sys.stderr
        self.bar = (self.stream.isatty() if bar is None else bar) and not quiet
        self.quiet = quiet
        self.runners: list[tuple[str, Any]] = []
        self.interrupted = False
        self._progress: Any = None
        self._lock = threading.Lock()

    def _say(self, text: str) -> None:
        if self._progress is not None:
            self._progress.console.print(text, markup=False, highlight=False)
        elif not self.quiet:
            print(text, file=self.stream, flush=True)

    def on_job(self, node_id: str, runner: Any) -> None:
        """The Start's hook: follow each job as it starts."""
        with self._lock:
            self.runners.append((node_id, runner))
        task = None
        if self._progress is not None:
            task = self._progress.add_task(node_id, total=1.0, left="", where="")

        def follow(event: Any) -> None:
            status = event.status
            if event.kind == "state":
                self._say(f"job {node_id}: {status.state}" + (f" ({event.message})" if event.message else ""))
                if status.state == "held" and event.message.endswith("Resume carries on"):
                    self._wait_for_resume(node_id, runner)
            elif event.kind == "log" and event.message:
                self._say(f"job {node_id}: {event.message}")
            if task is not None and event.kind in ("tick", "state"):
                left = f"{status.time_left:6.1f} s left" if status.time_left is not None else ""
                where = status.where + (f", line {status.line}" if status.line is not None else "")
                self._progress.update(task, completed=status.progress, left=left, where=where)

        runner.subscribe(follow)

    def _wait_for_resume(self, node_id: str, runner: Any) -> None:
        """A program stop (M0, M6, ...): Enter on the terminal resumes; without one only Ctrl-C ends it."""
        if not sys.stdin.isatty():
            self._say(f"job {node_id}: waiting for the operator, but there is no terminal to resume from; Ctrl-C stops")
            return
        self._say(f"job {node_id}: press Enter to resume")
        threading.Thread(target=lambda: (sys.stdin.readline(), runner.resume()), daemon=True).start()

    def start(self, runtime: Any, prepared: Any, options: dict[str, Any]) -> Any:
        """Start ``prepared`` (a run of ``runtime``) and wait for it; Ctrl-C stops it as described above."""
        from flowmc.runtime import Start

        start = Start(options, on_job=self.on_job)
        done: dict[str, Any] = {}
        finished = threading.Event()  # not Thread.join: a KeyboardInterrupt inside join() can leave it lying

        def work() -> None:
            try:
                done["result"] = runtime.start(prepared, start)
            except BaseException as exc:  # handed to the main thread, which raises it
                done["error"] = exc
            finally:
                finished.set()

        with self._bars():
            threading.Thread(target=work, name="flowmc-start", daemon=True).start()
            while not finished.is_set():
                try:
                    finished.wait(0.1)
                except KeyboardInterrupt:
                    self._interrupt(start)
        if "error" in done:
            raise done["error"]
        return done["result"]

    def _interrupt(self, start: Any) -> None:
        start.stop()
        running = [runner for _node, runner in self.runners if not runner.finished]
        if self.interrupted:
            self._say("Ctrl-C again: e-stop")
            for runner in running:
                runner.estop()
            return
        self.interrupted = True
        self._say("Ctrl-C: stopping (decelerating along the path); Ctrl-C again for an e-stop")
        for runner in running:
            runner.stop()

    def where_stopped(self) -> list[str]:
        """For each job a stop or e-stop ended: what its runner said, and where the tool was."""
        lines = []
        for node_id, runner in self.runners:
            if runner.state in ("aborted", "faulted"):
                status = runner.status
                at = ", ".join(f"{a} {v:.3f}" for a, v in zip(status.axes, status.commanded))
                lines.append(f"job {node_id}: {runner.state}: {runner.message}" + (f"; tool at {at} mm" if at else "")
                             + "; outputs left safe")
        return lines

    def _bars(self) -> Any:
        import contextlib

        if not self.bar:
            return contextlib.nullcontext()
        from rich.console import Console
        from rich.progress import BarColumn, Progress, TaskProgressColumn, TextColumn

        self._progress = Progress(TextColumn("[bold]{task.description}"), BarColumn(), TaskProgressColumn(),
                                  TextColumn("{task.fields[left]}"), TextColumn("{task.fields[where]}"),
                                  console=Console(file=self.stream), refresh_per_second=10)
        return self._progress
