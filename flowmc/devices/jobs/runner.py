"""The JobRunner: streams one job to its device at the device's pace, owns the job's state machine,
takes commands (hold, resume, stop, e-stop, overrides, single block, optional stop) from any thread, and tells
listeners what happens (``JobEvent``).

States: queued -> running -> (holding -> held -> running)* -> done; stop: stopping -> aborted;
e-stop: aborted at once; a device fault: faulted. Every abort, e-stop and fault leaves the outputs
safe (``Job.safe``). Two jobs never drive one device at once: a job claims its device (by spec) for
as long as it runs, in this process and, for real hardware, across processes (a lock file).

Paces: ``instant`` (the simulated card computes the whole operation at once, as tests and headless
runs want; commands have nothing to act on), ``realtime`` (the card's periods follow the wall clock,
times ``speed``), ``virtual`` (as realtime, but the clock is the card's own and never waits: tests
script commands at card times with ``at(t, command)``). GRBL and LinuxCNC run at their own pace.
"""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import tempfile
import threading
import time
from dataclasses import replace
from pathlib import Path
from typing import Callable, Iterator

from flowmc.devices.backends import open_device
from flowmc.devices.jobs.job import ACTIVE, FINAL, Job, JobEvent, JobStatus
from flowmc.devices.log import DeviceLog
from flowmc.errors import DeviceError, FlowmcError

__all__ = ["JobRunner", "claim", "PACES", "FEED_RANGE", "RAPID_STEPS", "SPINDLE_RANGE"]

PACES = ("instant", "realtime", "virtual")
FEED_RANGE = (10.0, 200.0)
RAPID_STEPS = (25.0, 50.0, 100.0)
SPINDLE_RANGE = (50.0, 200.0)

_claims: dict[str, str] = {}
_claims_lock = threading.Lock()


def _hardware(spec: str) -> bool:
    return spec.partition(":")[0] not in ("sim", "grbl-sim")


@contextlib.contextmanager
def claim(spec: str, holder: str) -> Iterator[None]:
    """Hold ``spec`` for one job; DeviceError naming the job that has it when it is taken."""
    with _claims_lock:
        if spec in _claims:
            raise DeviceError(f"the device is busy with {_claims[spec]}; two jobs never drive one device at once",
                              where=spec)
        _claims[spec] = holder
    lock_file = None
    try:
        if _hardware(spec):  # another process (a second editor, a CLI run) must not drive it either
            name = hashlib.sha1(spec.encode()).hexdigest()[:16]
            lock_file = open(Path(tempfile.gettempdir()) / f"flowmc-device-{name}.lock", "a+")
            try:
                fcntl.flock(lock_file, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                raise DeviceError("the device is busy with a job in another flowmc process", where=spec) from None
        yield
    finally:
        if lock_file is not None:
            lock_file.close()
        with _claims_lock:
            _claims.pop(spec, None)


class JobRunner:
    """Runs ``job`` once. ``after``: the log of the device operation before it (the simulated card
    carries on from its end state). ``start_at``: start from this segment (0-based; the state there is
    rebuilt and the tool approaches safely, see ``restart``). ``optional_stop``: the program's M1 stops
    (M0, M60 and M6 always do; see ``pauses``). ``start_line``: start at this G-code line instead
    (its segment, or the next line's that moves; said in ``assumptions``). ``tick_hz``: how often position events go out.
    ``record``: keep every commanded setpoint before the card rounds it to steps (``setpoints()``), so
    tests and benchmarks can check limits from the raw samples.
    """

    def __init__(self, job: Job, *, after: DeviceLog | None = None, pace: str = "instant", speed: float = 1.0,
                 start_at: int | None = None, single_block: bool = False, tick_hz: float = 50.0,
                 record: bool = False, optional_stop: bool = False, start_line: int | None = None):
        if pace not in PACES:
            raise DeviceError(f"unknown pace {pace!r}; known: {', '.join(PACES)}", where="job")
        if not speed > 0:
            raise DeviceError(f"the speed factor must be > 0, got {speed}", where="job")
        self.job = job
        self.after = after
        self.pace = pace
        self.speed = float(speed)
        self.start_at = start_at
        self.line_note = ""
        if start_line is not None:  # start at a G-code line: the segment it is (or the next with motion)
            if start_at is not None:
                raise DeviceError("start at a segment or at a G-code line, not both", where="job")
            self.start_at, self.line_note = job.segment_at_line(int(start_line))
        self.tick_hz = float(tick_hz)
        self.log: DeviceLog | None = None
        self.message = ""
        self.extra: dict = {}
        self.assumptions: list[str] = []
        self.trace: list | None = [] if record else None
        self._status = JobStatus(axes=job.machine.names, single_block=single_block, optional_stop=optional_stop)
        self._listeners: list[Callable[[JobEvent], None]] = []
        self._commands: list[tuple[str, object]] = []
        self._scheduled: list[tuple[float, str, object]] = []
        self._lock = threading.RLock()
        self._wake = threading.Event()
        self._finished = threading.Event()
        self._thread: threading.Thread | None = None
        self.command_times: dict[str, float] = {}  # wall time each command was given (latency benchmarks)

    # ------------------------------------------------------------------ what it says
    @property
    def state(self) -> str:
        return self._status.state

    @property
    def status(self) -> JobStatus:
        return self._status

    @property
    def finished(self) -> bool:
        return self._finished.is_set()

    def subscribe(self, listener: Callable[[JobEvent], None]) -> Callable[[], None]:
        """Call ``listener(event)`` for every event (on the job's thread); returns an unsubscribe."""
        with self._lock:
            self._listeners.append(listener)

        def unsubscribe() -> None:
            with self._lock:
                if listener in self._listeners:
                    self._listeners.remove(listener)

        return unsubscribe

    def emit(self, kind: str, text: str = "", change=None, **status) -> None:
        """Update the status and tell the listeners (drivers call this)."""
        with self._lock:
            if status:
                self._status = _replace(self._status, **status)
            event = JobEvent(kind, self._status, text, change)
            listeners = tuple(self._listeners)
        for listener in listeners:
            try:
                listener(event)
            except Exception:  # a listener (a closed page) must never stop a machine's job
                with self._lock:
                    if listener in self._listeners:
                        self._listeners.remove(listener)

    def set_state(self, state: str, message: str = "") -> None:
        if state != self._status.state:
            self.emit("state", message, state=state, message=message)

    def setpoints(self):
        """The commanded setpoints so far (rows of mm per axis, one per period), when recording."""
        import numpy as np

        if not self.trace:
            return np.zeros((0, len(self.job.machine.axes)))
        return np.vstack(self.trace)

    # ------------------------------------------------------------------ commands (any thread)
    def hold(self) -> None:
        """Feed hold: decelerate along the path within the acceleration limits, stop on it, keep position."""
        self._command("hold")

    def resume(self) -> None:
        """Carry on after a feed hold (or the next block in single block)."""
        self._command("resume")

    def stop(self) -> None:
        """Controlled stop: decelerate along the path, then clear the rest; outputs safe."""
        self._command("stop")

    def estop(self) -> None:
        """E-stop: the device's immediate stop; outputs safe."""
        self._command("estop")

    def set_overrides(self, feed: float | None = None, rapid: float | None = None, spindle: float | None = None) -> None:
        """Feed 10-200 %, rapid 25/50/100 %, spindle 50-200 %, applied live to the rest of the job."""
        if feed is not None:
            if not FEED_RANGE[0] <= feed <= FEED_RANGE[1]:
                raise DeviceError(f"feed override {feed:g} % outside {FEED_RANGE[0]:g}-{FEED_RANGE[1]:g} %", where="job")
            self._command("feed", float(feed))
        if rapid is not None:
            if rapid not in RAPID_STEPS:
                raise DeviceError(f"rapid override is 25, 50 or 100 %, not {rapid:g}", where="job")
            self._command("rapid", float(rapid))
        if spindle is not None:
            if not SPINDLE_RANGE[0] <= spindle <= SPINDLE_RANGE[1]:
                raise DeviceError(f"spindle override {spindle:g} % outside {SPINDLE_RANGE[0]:g}-{SPINDLE_RANGE[1]:g} %",
                                  where="job")
            self._command("spindle", float(spindle))

    def set_single_block(self, on: bool) -> None:
        """Single block: stop (held) at the end of every segment; Resume runs the next one."""
        self._command("single_block", bool(on))

    def set_optional_stop(self, on: bool) -> None:
        """Optional stop: the program's M1 stops (held) only while this is on."""
        self._command("optional_stop", bool(on))

    def at(self, t: float, command: str, value: object = None) -> None:
        """Give ``command`` when the job's clock reaches ``t`` s (tests on the virtual pace)."""
        with self._lock:
            self._scheduled.append((float(t), command, value))
            self._scheduled.sort(key=lambda c: c[0])

    def _command(self, name: str, value: object = None) -> None:
        with self._lock:
            self.command_times.setdefault(name, time.perf_counter())
            self._commands.append((name, value))
        self._wake.set()

    def take_commands(self, clock: float | None = None) -> list[tuple[str, object]]:
        """Commands given since the last call, and scheduled ones due by ``clock`` (drivers call this)."""
        with self._lock:
            out, self._commands = self._commands, []
            while clock is not None and self._scheduled and self._scheduled[0][0] <= clock + 1e-12:
                _t, name, value = self._scheduled.pop(0)
                out.append((name, value))
            self._wake.clear()
        return out

    def sleep(self, seconds: float) -> None:
        """Wait up to ``seconds``, or less when a command arrives (drivers call this)."""
        if seconds > 0:
            self._wake.wait(seconds)

    # ------------------------------------------------------------------ running
    def start(self) -> threading.Thread:
        """Run in a background thread (the editor); ``wait()`` for it."""
        self._thread = threading.Thread(target=self._run_quietly, name=f"flowmc-job-{self.job.name or 'job'}",
                                        daemon=True)
        self._thread.start()
        return self._thread

    def _run_quietly(self) -> None:
        try:
            self.run()
        except FlowmcError:
            pass  # the state (faulted) and the message say it

    def wait(self, timeout: float | None = None) -> bool:
        return self._finished.wait(timeout)

    def run(self) -> DeviceLog:
        """Run the job to its end here (blocking); returns the device log. A fault raises DeviceError
        (its ``.log`` is what the device did); a stop or e-stop returns the log with the state aborted."""
        from flowmc.devices.jobs.drivers import driver_for

        if self.state != "queued":
            raise DeviceError("a job runs once; prepare it again to run it again", where="job")
        try:
            with claim(self.job.device, f"job {self.job.name!r}" if self.job.name else "another job"):
                options = replace(self.job.options, resume=self.after.state if self.after is not None else None)
                self.set_state("running", f"started: {self.job.describe()}")
                with open_device(self.job.device, self.job.machine, options) as card:
                    driver = driver_for(self, card)
                    self.log = driver.run()
                if self.state not in FINAL:
                    self.set_state("done", self.message or "done")
        except FlowmcError as err:
            self.log = getattr(err, "log", None) or self.log
            self.message = str(err)
            self.emit("fault", self.message)
            self.set_state("faulted", self.message)
            raise
        finally:
            if self.state in ACTIVE or self.state == "queued":
                self.set_state("faulted", self.message or "the job ended unexpectedly")
            self._finished.set()
        return self.log


def _replace(status: JobStatus, **changes) -> JobStatus:
    return replace(status, **changes)

