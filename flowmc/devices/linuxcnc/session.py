"""One headless LinuxCNC session: a fresh directory, the ``linuxcnc`` script, and a clean end.

LinuxCNC allows one session per machine (its lock file /tmp/linuxcnc.lock, fixed
shared-memory keys), so sessions from this process or any other flowmc process
wait for each other on /tmp/flowmc-linuxcnc.lock. Every process a session starts
inherits the environment variable FLOWMC_LINUXCNC_RUN=<its directory>, even the
realtime ``rtapi_app`` that puts itself in a session of its own; that is how we
find, and if need be kill, exactly our processes and no others.

As root, LinuxCNC runs its realtime part as an unprivileged uid (RTAPI_UID,
nobody by default, or FLOWMC_RTAPI_UID) with its socket (RTAPI_FIFO_PATH) in a
directory that uid owns.
"""

from __future__ import annotations

import fcntl
import json
import os
import shutil
import signal
import subprocess
import tempfile
import time
from contextlib import contextmanager
from pathlib import Path
from typing import Callable

from flowmc.errors import DeviceError

__all__ = ["Session", "exclusive", "our_processes", "LINUXCNC_LOCK", "SESSION_LOCK"]

LINUXCNC_LOCK = Path("/tmp/linuxcnc.lock")
SESSION_LOCK = Path(tempfile.gettempdir()) / "flowmc-linuxcnc.lock"
SYSTEM_PYTHON = "/usr/bin/python3"
MARKER = "FLOWMC_LINUXCNC_RUN"
# LinuxCNC's System V shared memory: the NML buffers of linuxcnc.nml (keys 1001-1005), HAL ("HAL2")
# and RTAPI. Removed after a session only if the linuxcnc script could not remove them itself.
_IPC_KEYS = {1001, 1002, 1003, 1004, 1005, 0x48414C32, 0x90280A48}


def our_processes(run_dir: str) -> list[int]:
    """Pids of live processes whose environment carries this run's marker."""
    needle = f"{MARKER}={run_dir}\0".encode()
    pids = []
    for entry in os.scandir("/proc"):
        if not entry.name.isdigit() or int(entry.name) == os.getpid():
            continue
        try:
            with open(f"/proc/{entry.name}/environ", "rb") as f:
                env = f.read()
            with open(f"/proc/{entry.name}/stat", "rb") as f:
                state = f.read().rsplit(b")", 1)[1].split()[0]
        except OSError:
            continue
        if needle in env and state != b"Z":
            pids.append(int(entry.name))
    return pids


def _signal(pids: list[int], sig: int) -> None:
    for pid in pids:
        try:
            os.kill(pid, sig)
        except ProcessLookupError:
            pass


def _remove_ipc() -> None:
    """Remove LinuxCNC's leftover shared memory segments (only its fixed keys, only if unattached)."""
    try:
        listing = subprocess.run(["ipcs", "-m"], capture_output=True, text=True, timeout=10).stdout
    except (OSError, subprocess.TimeoutExpired):
        return
    for row in listing.splitlines():
        cols = row.split()
        if len(cols) >= 6 and cols[0].startswith("0x") and int(cols[0], 16) in _IPC_KEYS and cols[5] == "0":
            subprocess.run(["ipcrm", "-m", cols[1]], capture_output=True, timeout=10)


@contextmanager
def exclusive(timeout: float):
    """Hold the machine-wide flowmc LinuxCNC lock: no other session runs (or is being torn down) meanwhile."""
    SESSION_LOCK.touch(exist_ok=True)
    with open(SESSION_LOCK) as lock:
        deadline = time.monotonic() + timeout
        while True:
            try:
                fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
                break
            except BlockingIOError:
                if time.monotonic() > deadline:
                    raise DeviceError("timed out waiting for another flowmc LinuxCNC session to end",
                                      where="linuxcnc") from None
                time.sleep(0.1)
        yield  # closing the file releases the lock


class Session:
    """A fresh run directory (``write`` files into it); ``run(ini)`` starts LinuxCNC and waits for it to end.

    The display program's events (JSON lines in ``events.jsonl``) go to ``on_event`` as they come.
    """

    def __init__(self, *, keep: bool = False):
        if shutil.which("linuxcnc") is None or shutil.which("halsampler") is None:
            raise DeviceError("LinuxCNC is not installed (Debian package linuxcnc-uspace)", where="linuxcnc")
        if not Path(SYSTEM_PYTHON).exists():
            raise DeviceError(f"LinuxCNC's Python ({SYSTEM_PYTHON}) is missing", where="linuxcnc")
        self.keep = keep
        self.dir = Path(tempfile.mkdtemp(prefix="flowmc-linuxcnc-"))
        os.chmod(self.dir, 0o755)  # the realtime uid must reach its socket directory
        self.log = ""
        self.proc: subprocess.Popen | None = None

    def path(self, name: str) -> Path:
        return self.dir / name

    def write(self, name: str, text: str, executable: bool = False) -> Path:
        """Put a file into the run directory; returns its absolute path."""
        target = self.dir / name
        target.write_text(text)
        if executable:
            target.chmod(0o755)
        return target

    def display_wrapper(self, script: Path) -> Path:
        """An executable that runs ``script`` under the system Python (LinuxCNC's DISPLAY must be one program)."""
        return self.write("display", f'#!/bin/sh\nexec {SYSTEM_PYTHON} "{script}" "$@"\n', executable=True)

    def _environment(self) -> dict[str, str]:
        rtapi = self.dir / "rtapi"
        rtapi.mkdir(exist_ok=True)
        env = {k: v for k, v in os.environ.items()
               if k not in ("DISPLAY", "PYTHONPATH", "PYTHONHOME", "PYENV_VERSION", "VIRTUAL_ENV")}
        env["PATH"] = "/usr/bin:/bin:" + env.get("PATH", "")
        env["HOME"] = str(self.dir)  # where the linuxcnc script copies its logs after a failure
        env["RTAPI_FIFO_PATH"] = str(rtapi / "rtapi.sock")
        if os.geteuid() == 0:
            uid = int(os.environ.get("FLOWMC_RTAPI_UID", "65534"))
            os.chown(rtapi, uid, -1)
            env["RTAPI_UID"] = str(uid)
        env[MARKER] = str(self.dir)
        return env

    # ------------------------------------------------------------------ run

    def run(self, ini: Path, timeout: float, on_event: Callable[[dict], None] | None = None,
            on_poll: Callable[[], None] | None = None) -> None:
        """Start LinuxCNC, follow its events, and return once every process of ours has ended.

        ``on_poll()`` is called every 20 ms meanwhile (to ``send`` commands to the display program).

        ``timeout`` (s) covers start-up, the program and shut-down, but not the time the program is
        held (paused, as the display program's events say). Past it, or on any error here,
        the session is torn down (display first, so LinuxCNC shuts itself down; then SIGKILL) and
        DeviceError raised.
        """
        with exclusive(timeout):
            if LINUXCNC_LOCK.exists():
                raise DeviceError(f"another LinuxCNC session is running ({LINUXCNC_LOCK} exists; remove it if "
                                  "no LinuxCNC is running)", where="linuxcnc")
            try:
                self._run(ini, self._environment(), timeout, on_event, on_poll)
            finally:
                self._teardown()

    def send(self, command: str) -> None:
        """Append one command line to the run's ``commands`` file, which the display program follows."""
        with open(self.path("commands"), "a") as f:
            f.write(command + "\n")

    def _run(self, ini: Path, env: dict[str, str], timeout: float, on_event, on_poll) -> None:
        log = open(self.path("linuxcnc.log"), "w")
        try:
            proc = subprocess.Popen(["linuxcnc", "-r", str(ini)], cwd=self.dir, env=env,
                                    stdin=subprocess.DEVNULL, stdout=log, stderr=subprocess.STDOUT,
                                    start_new_session=True)
        finally:
            log.close()
        self.proc = proc
        deadline = time.monotonic() + timeout
        events = self.path("events.jsonl")
        offset = 0
        paused, last_poll = False, time.monotonic()
        while True:
            now = time.monotonic()
            if paused:
                deadline += now - last_poll  # a held program: the operator's time, not LinuxCNC's
            last_poll = now
            done = proc.poll() is not None
            if events.exists():
                with open(events) as f:
                    f.seek(offset)
                    chunk = f.read()
                complete = chunk[: chunk.rfind("\n") + 1]
                offset += len(complete.encode())
                for line in complete.splitlines():
                    event = json.loads(line)
                    paused = bool(event.get("paused", event.get("state") == "held" or paused))
                    if on_event is not None:
                        on_event(event)
            if done:
                return
            if on_poll is not None:
                on_poll()
            if time.monotonic() > deadline:
                raise DeviceError(f"LinuxCNC did not finish within {timeout:g} s; it was shut down",
                                  where="linuxcnc")
            time.sleep(0.02)

    def _teardown(self) -> None:
        """Make sure nothing of this session is left: processes, lock file, shared memory."""
        run_dir = str(self.dir)
        proc = self.proc
        if proc is not None and proc.poll() is None:
            # Ending the display makes the linuxcnc script shut LinuxCNC down in order.
            display = [p for p in our_processes(run_dir) if _is_display(p, self.dir)]
            _signal(display, signal.SIGTERM)
            try:
                proc.wait(20.0)
            except subprocess.TimeoutExpired:
                pass
        stray = our_processes(run_dir)
        if stray:
            _signal(stray, signal.SIGKILL)
            for _ in range(100):
                if not our_processes(run_dir):
                    break
                time.sleep(0.05)
        if proc is not None:
            try:
                proc.wait(5.0)
            except subprocess.TimeoutExpired:
                pass
        if stray or (proc is not None and proc.returncode not in (0, None)):
            # The script's own cleanup did not run to the end: finish its job.
            LINUXCNC_LOCK.unlink(missing_ok=True)
            _remove_ipc()
        if self.path("linuxcnc.log").exists():
            self.log = self.path("linuxcnc.log").read_text(errors="replace")

    def cleanup(self) -> None:
        """Remove the run directory (unless asked to keep it)."""
        if not self.keep:
            shutil.rmtree(self.dir, ignore_errors=True)


def _is_display(pid: int, run_dir: Path) -> bool:
    """The display program: our display.py, or whatever the run directory's ``display`` wrapper runs."""
    try:
        with open(f"/proc/{pid}/cmdline", "rb") as f:
            args = f.read().split(b"\0")
    except OSError:
        return False
    return any(a.endswith(b"display.py") or a == str(run_dir / "display").encode() for a in args)
