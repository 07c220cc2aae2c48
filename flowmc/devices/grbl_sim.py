"""A GRBL 1.1 *protocol* simulator on a pseudo-terminal, for testing the streamer without a board.

Run it as ``python3 -m flowmc.devices.grbl_sim`` (it prints the pty path to open) or start it from a
test with ``GrblSimulator().start()``. It stops by itself after ``idle_timeout`` seconds without
traffic or ``lifetime`` seconds in all, and when ``stop()`` is called.

What it models
--------------
- The serial link: a pty in raw mode; the board's 128-byte receive buffer. Bytes that arrive while
  the buffer is full are dropped, as GRBL drops them, and ``overflowed`` records it, so a test can
  prove a host's character counting never overruns. ``max_rx_fill`` is the fullest it got.
- Line processing at a fixed pace (``line_time`` seconds a line), so the buffer really fills.
- Responses: ``ok``; ``error:N`` for lines it cannot take (1 no letter, 2 bad number, 3 bad ``$``
  command, 9 locked by an alarm, 11 line longer than 80 characters, 20 unsupported G/M code or
  word, 15 jog target outside the travel, 22 feed not set for G1/G2/G3, 26 G4 without P);
  ``ALARM:2`` when a move's target leaves the travel box (soft limits), after which it is locked
  (``error:9``) until ``$X`` or a soft reset, and its receive buffer is flushed, as GRBL does.
- Injected faults: ``error_at={line: code}``, ``alarm_at={line: code}``, and ``vanish_after=N``
  (the port disappears once line N has been answered). Lines count from 1 after each reset.
- ``trace``: what it executed, as (time, machine position, spindle M3/M4/M5, S, coolant M7/M8/M9)
  each time one of them changed (every 1-2 ms while the motion model moves, and every block's end
  point), so a test can check
  from the raw record where the machine went and in which state.
- Real-time bytes, acted on at once and never buffered: ``?`` status report
  (``<Idle|MPos:x,y,z|Bf:15,free|FS:feed,rpm>``, state Idle, Run while lines wait, Hold:0, Alarm),
  ``!`` feed hold (line processing pauses), ``~`` resume, Ctrl-X soft reset (buffer cleared,
  banner ``Grbl 1.1h ['$' for help]`` sent again).
- ``$X`` unlock, ``$$`` a few settings, ``$H`` homing (MPos set to 0 at once), ``$J=`` jogging.
- Modal state: G0/G1/G2/G3 motion, G90/G91, G20/G21, F, S, M3/M4/M5, M7/M8/M9.
- M0 program pause: once the motion before it has run (M-codes wait for the planner to empty), the
  state is ``Hold:0`` until cycle start ``~``, as GRBL 1.1 does. M1 is accepted and ignored (GRBL
  has no optional-stop switch); M6 is refused (error:20), as GRBL 1.1 refuses it.

What it does not model
----------------------
Motion timing and the planner: a move's target becomes the machine position as soon as its line is
processed, so status reports never show intermediate positions and Hold stops only line
processing. No acceleration, no arc geometry checks (I/J/R are accepted as given), no hard-limit
switches, no probing, no work offsets (G54-G59 are accepted and ignored), no EEPROM. Timing is wall
clock, so it is a protocol test bed, not a motion simulator (the simulated card is that).
"""

from __future__ import annotations

import argparse
import os
import re
import select
import threading
import time
import tty

from flowmc.devices.grbl_sim_motion import OVERRIDE_BYTES, MotionModel

__all__ = ["GrblSimulator", "RX_BUFFER_SIZE", "LINE_MAX"]

RX_BUFFER_SIZE = 128
LINE_MAX = 80  # characters per line after spaces and comments are removed
BANNER = b"\r\nGrbl 1.1h ['$' for help]\r\n"
_WORD = re.compile(r"([A-Z])([-+]?(?:\d+\.?\d*|\.\d+))")
_G_OK = {0, 1, 2, 3, 4, 17, 18, 19, 20, 21, 54, 55, 56, 57, 58, 59, 90, 91, 93, 94}
_M_OK = {0, 1, 2, 3, 4, 5, 7, 8, 9, 30}
_LETTERS_OK = set("GMXYZIJKRFSPNTL")
_RESET, _STATUS, _HOLD, _RESUME = 0x18, ord("?"), ord("!"), ord("~")


def _strip(line: str) -> str:
    """Upper case, no spaces, no ``( )`` or ``;`` comments: what GRBL keeps of a line."""
    line = re.sub(r"\([^)]*\)", "", line.split(";", 1)[0])
    return "".join(line.split()).upper()


class GrblSimulator:
    """The simulator; ``start()`` returns the pty path. Attributes after a run describe what it saw."""

    def __init__(self, *, error_at: dict[int, int] | None = None, alarm_at: dict[int, int] | None = None,
                 vanish_after: int | None = None, travel: tuple[tuple[float, float], ...] = ((-200.0, 200.0),) * 3,
                 line_time: float = 0.001, idle_timeout: float = 30.0, lifetime: float = 600.0,
                 motion: bool = False, accel: float = 200.0, rapid_rate: float = 6000.0):
        self.error_at = dict(error_at or {})
        self.alarm_at = dict(alarm_at or {})
        self.vanish_after = vanish_after
        self.travel = tuple(travel)
        self.line_time = float(line_time)
        self.idle_timeout = float(idle_timeout)
        self.lifetime = float(lifetime)
        self.received: list[str] = []  # every line processed since start (raw text)
        self.max_rx_fill = 0
        self.overflowed = False
        self.resets = 0
        self._master = self._slave = -1
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self.mpos = [0.0, 0.0, 0.0]  # machine position survives a soft reset, as on GRBL
        self.model = MotionModel(self.mpos, accel=accel, rapid_rate=rapid_rate) if motion else None
        self.bytes_seen: list[tuple[float, int]] = []  # (monotonic time, byte) of every real-time byte
        #: (monotonic time, (x, y, z), spindle M3/M4/M5, S, coolant M7/M8/M9), each time one of them changed
        self.trace: list[tuple[float, tuple[float, ...], int, float, int]] = []
        self._reset_state()
        self.alarm = 0

    # ------------------------------------------------------------ lifecycle
    def start(self) -> str:
        """Open the pty, send the banner and serve in a background thread; returns the port path."""
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)
        os.set_blocking(self._master, False)  # a host that stops reading must not hang the simulator
        self.port = os.ttyname(self._slave)
        self._write(BANNER)
        self._thread = threading.Thread(target=self._serve, name="grbl-sim", daemon=True)
        self._thread.start()
        return self.port

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=5.0)
        self._close()

    def __enter__(self) -> "GrblSimulator":
        self.start()
        return self

    def __exit__(self, *exc) -> None:
        self.stop()

    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    def _close(self) -> None:
        for fd in (self._master, self._slave):
            if fd >= 0:
                try:
                    os.close(fd)
                except OSError:
                    pass
        self._master = self._slave = -1

    # ------------------------------------------------------------ state
    def _reset_state(self) -> None:
        self.rx = bytearray()
        self.line_no = 0
        self.hold = False
        self.absolute = True
        self.inches = False
        self.motion = 0
        self.feed = 0.0
        self.spindle = 0.0
        self.spindle_dir = 5
        self.coolant = 9

    def _write(self, data: bytes) -> None:
        if self._master >= 0:
            try:
                os.write(self._master, data)
            except BlockingIOError:  # the host is not reading: the bytes are lost, as on a real link
                pass

    def _reply(self, text: str) -> None:
        self._write(text.encode() + b"\r\n")

    def _status(self) -> str:
        model = self.model
        if model is None:
            state = "Alarm" if self.alarm else "Hold:0" if self.hold else "Run" if b"\n" in self.rx else "Idle"
            rpm = self.spindle if self.spindle_dir in (3, 4) else 0.0
            return (f"<{state}|MPos:{','.join(f'{v:.3f}' for v in self.mpos)}|Bf:15,{RX_BUFFER_SIZE - len(self.rx)}"
                    f"|FS:{self.feed:.0f},{rpm:.0f}>")
        state = "Alarm" if self.alarm else model.state()
        if state == "Idle" and b"\n" in self.rx:
            state = "Run"
        ov = model.overrides
        rpm = self.spindle * ov["spindle"] / 100.0 if self.spindle_dir in (3, 4) else 0.0
        acc = {3: "S", 4: "C"}.get(self.spindle_dir, "") + {8: "F", 7: "M"}.get(self.coolant, "")
        free = 15 - len(model.queue) - (model.block is not None)
        return (f"<{state}|MPos:{','.join(f'{v:.3f}' for v in model.position)}|Bf:{free},{RX_BUFFER_SIZE - len(self.rx)}"
                f"|FS:{model.speed * 60:.0f},{rpm:.0f}|Ov:{ov['feed']},{ov['rapid']},{ov['spindle']}"
                + (f"|A:{acc}" if acc else "") + ">")

    # ------------------------------------------------------------ serving
    def _serve(self) -> None:
        started = last_traffic = last_line = last_step = time.monotonic()
        try:
            while not self._stop.is_set():
                now = time.monotonic()
                if now - last_traffic > self.idle_timeout or now - started > self.lifetime:
                    break
                ready, _, _ = select.select([self._master], [], [], min(self.line_time, 0.002 if self.model else 0.01))
                if ready:
                    try:
                        data = os.read(self._master, 1024)
                    except OSError:  # nobody has the port open right now
                        data = b""
                    if data:
                        last_traffic = time.monotonic()
                        self._receive(data)
                if self.model is not None:
                    now = time.monotonic()
                    self.model.advance(now - last_step)
                    last_step = now
                    for end in self.model.ends:  # every corner, even one passed within a step
                        self._record(end)
                    self.model.ends.clear()
                    self.mpos = self.model.position
                if (not self.hold and b"\n" in self.rx and time.monotonic() - last_line >= self.line_time
                        and self._may_process()):
                    last_line = time.monotonic()
                    if not self._process_line():
                        break
                self._record()
        finally:
            self._close()

    def _record(self, position=None) -> None:
        state = (tuple(self.mpos if position is None else position), self.spindle_dir, self.spindle, self.coolant)
        if not self.trace or self.trace[-1][1:] != state:
            self.trace.append((time.monotonic(), *state))

    def _may_process(self) -> bool:
        """With the motion model: a move waits for room in the planner; M-codes and dwells wait until it
        has run empty (GRBL synchronises them with motion)."""
        model = self.model
        if model is None:
            return True
        line = _strip(bytes(self.rx[:self.rx.index(b"\n")]).decode("ascii", errors="replace"))
        if not model.room:
            return False
        return not (("M" in line or "G4" in line) and model.busy)

    def _receive(self, data: bytes) -> None:
        for byte in data:
            if byte in (_RESET, _STATUS, _HOLD, _RESUME) or byte >= 0x80:
                self.bytes_seen.append((time.monotonic(), byte))
            if byte == _RESET:
                moving = self.model is not None and self.model.moving
                if self.model is not None:
                    self.model.clear()
                    self.mpos = self.model.position
                self._reset_state()
                if moving:  # GRBL loses its position when reset while moving: alarm 3, locked
                    self.alarm = 3
                self.resets += 1
                if self.alarm not in (1, 2, 3):  # hard/soft-limit alarms survive a reset
                    self.alarm = 0
                elif self.alarm == 3 and not moving:
                    self.alarm = 0
                self._write(BANNER)
                if self.alarm:
                    self._reply("[MSG:'$H'|'$X' to unlock]")
            elif byte == _STATUS:
                self._reply(self._status())
            elif byte == _HOLD:
                self.hold = self.hold or b"\n" in self.rx or (self.model is not None and self.model.busy)
                if self.model is not None:
                    self.model.hold = self.hold
            elif byte == _RESUME:
                self.hold = False
                if self.model is not None:
                    self.model.hold = False
            elif byte in OVERRIDE_BYTES:
                if self.model is not None:
                    self.model.override(byte)
            elif byte >= 0x80:
                pass  # another real-time byte GRBL knows (safety door, jog cancel, ...): not modelled
            elif len(self.rx) >= RX_BUFFER_SIZE:
                self.overflowed = True
            else:
                self.rx.append(byte)
                self.max_rx_fill = max(self.max_rx_fill, len(self.rx))

    def _process_line(self) -> bool:
        """Take one line from the buffer and answer it; False when the port should vanish."""
        end = self.rx.index(b"\n")
        raw = self.rx[:end].decode("ascii", errors="replace").rstrip("\r")
        del self.rx[:end + 1]
        if self.vanish_after is not None and self.line_no >= self.vanish_after:
            time.sleep(0.3)  # let the host read the answers already written, then pull the plug
            return False
        self.line_no += 1
        self.received.append(raw)
        if self.line_no in self.alarm_at:
            self._raise_alarm(self.alarm_at[self.line_no])
            return True
        if self.line_no in self.error_at:
            self._reply(f"error:{self.error_at[self.line_no]}")
            return True
        answer = self._execute(_strip(raw))
        if answer is not None:
            self._reply(answer)
        return True

    def _raise_alarm(self, code: int) -> None:
        self.alarm = code
        self.rx.clear()  # GRBL resets on an alarm: whatever was buffered is gone
        self.hold = False
        self._reply(f"ALARM:{code}")

    # ------------------------------------------------------------ G-code
    def _execute(self, line: str, jog: bool = False) -> str | None:
        if len(line) > LINE_MAX - 1:
            return "error:11"
        if line.startswith("$"):
            return self._system(line)
        if self.alarm:
            return "error:9"
        if not line:
            return "ok"
        pos = 0
        words: list[tuple[str, float]] = []
        for m in _WORD.finditer(line):
            if m.start() != pos:
                return "error:1" if not line[pos].isalpha() else "error:2"
            words.append((m.group(1), float(m.group(2))))
            pos = m.end()
        if pos != len(line):
            return "error:2" if line[pos].isalpha() else "error:1"
        return self._words(words, jog)

    def _system(self, line: str) -> str | None:
        if line == "$X":
            self.alarm = 0
            self._reply("[MSG:Caution: Unlocked]")
            return "ok"
        if line == "$H":
            self.alarm = 0
            self.mpos = [0.0, 0.0, 0.0]
            if self.model is not None:
                self.model.position = list(self.mpos)
            return "ok"
        if line == "$$":
            for text in ("$20=1", "$21=0", "$22=1", "$110=6000.000", "$120=200.000",
                         *(f"$13{i}={hi - lo:.3f}" for i, (lo, hi) in enumerate(self.travel))):
                self._reply(text)
            return "ok"
        if line.startswith("$J="):
            if self.alarm:
                return "error:9"
            return self._execute_jog(line[3:])
        return "error:3"

    def _execute_jog(self, body: str) -> str | None:
        saved = (self.absolute, self.motion, self.feed)
        answer = self._execute("G1" + body, jog=True)
        self.absolute, self.motion, self.feed = saved
        return answer

    def _words(self, words: list[tuple[str, float]], jog: bool = False) -> str | None:
        target: dict[int, float] = {}
        dwell_p = None
        motion_seen = None
        for letter, value in words:
            if letter not in _LETTERS_OK:
                return "error:20"
            if letter == "G":
                code = int(value) if value == int(value) else None
                if code not in _G_OK:
                    return "error:20"
                if code in (0, 1, 2, 3):
                    motion_seen = code
                elif code in (90, 91):
                    self.absolute = code == 90
                elif code in (20, 21):
                    self.inches = code == 20
                elif code == 4:
                    motion_seen = 4
            elif letter == "M":
                code = int(value) if value == int(value) else None
                if code not in _M_OK:
                    return "error:20"
                if code == 0:  # program pause: a feed hold at rest, until cycle start
                    self.hold = True
                    if self.model is not None:
                        self.model.hold = True
                elif code in (3, 4, 5):
                    self.spindle_dir = code
                elif code in (7, 8, 9):
                    self.coolant = code
            elif letter in "XYZ":
                target["XYZ".index(letter)] = value * (25.4 if self.inches else 1.0)
            elif letter == "F":
                self.feed = value * (25.4 if self.inches else 1.0)
            elif letter == "S":
                self.spindle = value
            elif letter == "P":
                dwell_p = value
        if motion_seen == 4:
            if dwell_p is not None and self.model is not None:
                self.model.dwell(dwell_p)
            return "ok" if dwell_p is not None else "error:26"
        if motion_seen is not None:
            self.motion = motion_seen
        if not target:
            return "ok"
        if self.motion in (1, 2, 3) and self.feed <= 0:
            return "error:22"
        base = self.model.planned_end() if self.model is not None else self.mpos
        new = list(base)
        for axis, value in target.items():
            new[axis] = value if self.absolute else base[axis] + value
        for axis, (lo, hi) in enumerate(self.travel):
            if not lo <= new[axis] <= hi:
                if jog:  # a jog past the travel is refused, not an alarm
                    return "error:15"
                self._raise_alarm(2)
                return None
        if self.model is not None:
            self.model.move(new, self.feed, rapid=self.motion == 0 and not jog)
        self.mpos = new if self.model is None else self.mpos
        return "ok"


def _pairs(text: str) -> dict[int, int]:
    out = {}
    for item in filter(None, text.split(",")):
        line, _, code = item.partition(":")
        out[int(line)] = int(code)
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python3 -m flowmc.devices.grbl_sim",
                                     description="GRBL 1.1 protocol simulator on a pseudo-terminal.")
    parser.add_argument("--error-at", default="", help="inject errors: LINE:CODE[,LINE:CODE...]")
    parser.add_argument("--alarm-at", default="", help="inject alarms: LINE:CODE[,...]")
    parser.add_argument("--vanish-after", type=int, default=None, help="close the port after this line")
    parser.add_argument("--line-time", type=float, default=0.001, help="seconds to process one line")
    parser.add_argument("--idle-timeout", type=float, default=60.0, help="stop after this long without traffic")
    parser.add_argument("--lifetime", type=float, default=3600.0, help="stop after this long in all")
    args = parser.parse_args(argv)
    sim = GrblSimulator(error_at=_pairs(args.error_at), alarm_at=_pairs(args.alarm_at),
                        vanish_after=args.vanish_after, line_time=args.line_time,
                        idle_timeout=args.idle_timeout, lifetime=args.lifetime)
    print(sim.start(), flush=True)
    try:
        while sim.running:
            time.sleep(0.2)
    except KeyboardInterrupt:
        pass
    finally:
        sim.stop()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
