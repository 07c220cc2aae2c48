"""GRBL over serial: stream G-code with character-counting flow control, behind the MotionCard interface.

Flow control (GRBL's own recommendation for fast streaming): GRBL's receive buffer holds 128 bytes.
The host keeps the lengths of the lines it has sent but GRBL has not yet answered; it sends the
next line only while their sum plus the new line fits in 128 bytes, and each ``ok`` or ``error:N``
frees the oldest line. Real-time bytes (``?`` status, ``!`` feed hold, ``~`` resume, Ctrl-X soft
reset) bypass the buffer and are sent at any time.

On ``error:N`` the streamer stops sending, soft-resets GRBL (so lines already in its buffer do not
run) and raises a DeviceError naming the failing line; on ``ALARM:N`` likewise. A port that
vanishes (unplugged cable) is a DeviceError naming the last acknowledged line. Every error carries
``.log``, the DeviceLog of what happened up to then.
"""

from __future__ import annotations

import collections
import time
from dataclasses import dataclass, field

import numpy as np

from flowmc.devices.card import MotionCard
from flowmc.devices.grbl_program import ProgramLine, check_pen_commands, motion_gcode, text_gcode
from flowmc.devices.log import DeviceLog, Event
from flowmc.devices.preflight import preflight
from flowmc.devices.ranges import CardRanges
from flowmc.errors import DeviceError
from flowmc.motion.machine import Machine
from flowmc.motion.trajectory import Signal, Steps, Trajectory

__all__ = ["GrblStreamer", "GrblCard", "Stream", "parse_status", "GRBL_RANGES", "ERRORS", "ALARMS"]

RX_BUFFER_SIZE = 128
#: GRBL drives a spindle (S, M3/M4/M5) and a flood-coolant pin (output 1); no PWM or DA of its own.
GRBL_RANGES = CardRanges(inputs=0, outputs=1, analog="da")

ERRORS = {
    1: "expected a command letter", 2: "bad number format", 3: "invalid $ statement", 4: "negative value",
    5: "homing not enabled", 8: "not idle", 9: "G-code locked by an alarm or jog", 10: "soft limits need homing",
    11: "line too long", 14: "line too long for EEPROM", 15: "jog target beyond travel", 16: "invalid jog",
    20: "unsupported command", 21: "modal group violation", 22: "feed rate not set", 23: "value not an integer",
    24: "axis words conflict", 25: "repeated word", 26: "no axis words", 27: "invalid line number",
    28: "value word missing", 29: "work offset not supported", 30: "G53 needs G0 or G1", 31: "axis words not used",
    32: "arc without axis words in plane", 33: "invalid motion target", 34: "arc radius error",
    35: "arc without offsets in plane", 36: "unused words", 37: "tool length offset axis", 38: "tool number too big",
}
ALARMS = {
    1: "hard limit", 2: "soft limit: target beyond travel", 3: "reset while moving", 4: "probe fail",
    5: "probe fail", 6: "homing fail: reset", 7: "homing fail: door", 8: "homing fail: pull-off",
    9: "homing fail: switch not found",
}


def parse_status(text: str) -> dict:
    """``<Run|MPos:1.000,2.000,0.000|FS:600,0|Pn:X>`` -> {"state": "Run", "MPos": [1.0, 2.0, 0.0], ...}."""
    fields = text.strip().lstrip("<").rstrip(">").split("|")
    out: dict = {"state": fields[0]}
    for item in fields[1:]:
        key, _, value = item.partition(":")
        if key == "Pn":
            out[key] = value
        else:
            try:
                out[key] = [float(v) for v in value.split(",")]
            except ValueError:
                out[key] = value
    return out


@dataclass
class Stream:
    """What a streaming run saw: lines acknowledged, status reports (wall time, state, MPos), events."""

    acked: int = 0
    sent: int = 0
    reports: list = field(default_factory=list)
    events: list = field(default_factory=list)
    status: dict = field(default_factory=dict)  # the last status report, parsed


class GrblStreamer:
    """The serial conversation with one GRBL board."""

    def __init__(self, port: str, baud: int = 115200, *, timeout: float = 10.0, poll: float = 0.2,
                 idle_timeout: float = 600.0):
        self.port = port
        self.baud = baud
        self.timeout = timeout
        self.poll = poll
        self.idle_timeout = idle_timeout
        self._serial = None
        self._pending = bytearray()
        self._t0 = time.monotonic()
        self._control = None

    # ------------------------------------------------------------ link
    def connect(self) -> None:
        import serial  # pyserial; imported here so flowmc imports without it

        try:
            self._serial = serial.Serial(self.port, self.baud, timeout=0.02, write_timeout=self.timeout)
        except (serial.SerialException, OSError) as exc:
            raise DeviceError(f"cannot open serial port: {exc}", where=self.port) from None
        self.soft_reset()

    def close(self) -> None:
        if self._serial is not None:
            try:
                self._serial.close()
            except OSError:
                pass
            self._serial = None

    def _vanished(self, exc: Exception, stream: Stream | None, lines=()) -> DeviceError:
        last = (f"line {stream.acked} ({lines[stream.acked - 1].source}: {lines[stream.acked - 1].text!r})"
                if stream is not None and stream.acked and lines else "none")
        self.close()
        return DeviceError(f"the serial port vanished ({exc}); last acknowledged: {last}", where=self.port)

    def _write(self, data: bytes) -> None:
        if self._serial is None:
            raise DeviceError("not connected", where=self.port)
        self._serial.write(data)
        self._serial.flush()

    def _read_line(self, wait: float) -> str | None:
        """One response line, or None if none came within ``wait`` seconds."""
        if self._serial is None:
            raise DeviceError("not connected", where=self.port)
        deadline = time.monotonic() + wait
        while True:
            if b"\n" in self._pending:
                end = self._pending.index(b"\n")
                line = self._pending[:end].decode("ascii", errors="replace").strip()
                del self._pending[:end + 1]
                if line:
                    return line
                continue
            if time.monotonic() >= deadline:
                return None
            self._pending += self._serial.read(256)

    # ------------------------------------------------------------ real-time commands
    def soft_reset(self) -> None:
        """Ctrl-X: GRBL stops at once, drops its buffers and greets again."""
        import serial

        try:
            self._serial.reset_input_buffer()
            self._pending.clear()
            self._write(b"\x18")
            deadline = time.monotonic() + self.timeout
            while time.monotonic() < deadline:
                line = self._read_line(deadline - time.monotonic())
                if line is not None and line.startswith("Grbl"):
                    return
        except (serial.SerialException, OSError) as exc:
            raise self._vanished(exc, None) from None
        raise DeviceError(f"no GRBL greeting within {self.timeout:g} s after a soft reset", where=self.port)

    def feed_hold(self) -> None:
        self._write(b"!")

    def realtime(self, data: bytes) -> None:
        """Real-time bytes (hold, resume, reset, overrides): GRBL acts on them at once, outside its buffer."""
        self._write(data)

    def resume(self) -> None:
        self._write(b"~")

    def status(self) -> dict:
        """Ask ``?`` and parse the report."""
        import serial

        try:
            self._write(b"?")
            deadline = time.monotonic() + self.timeout
            while time.monotonic() < deadline:
                line = self._read_line(deadline - time.monotonic())
                if line is not None and line.startswith("<"):
                    return parse_status(line)
        except (serial.SerialException, OSError) as exc:
            raise self._vanished(exc, None) from None
        raise DeviceError(f"no status report within {self.timeout:g} s", where=self.port)

    # ------------------------------------------------------------ streaming
    def stream(self, lines: list[ProgramLine], wait_idle: bool = True, control=None, until=None) -> Stream:
        """Send ``lines`` with character counting; raise DeviceError on error, alarm, silence or a lost port.

        ``control(stream)``: called between reads (every 50 ms or sooner) and after each status report, so a
        job can send real-time bytes and follow the reports; what it raises ends the stream. The error's
        ``.stream`` holds what was seen up to then. ``until()``: how many lines may be sent by now (None:
        all; a job's single block holds the rest back while status polling and ``control`` go on).
        """
        import serial

        data = [(line.text + "\n").encode("ascii") for line in lines]
        for i, raw in enumerate(data):
            if len(raw) > RX_BUFFER_SIZE:
                raise DeviceError(f"line is {len(raw)} bytes, more than GRBL's {RX_BUFFER_SIZE}-byte buffer",
                                  where=f"line {i + 1} ({lines[i].source})")
        st = Stream()
        self._control = control
        in_flight: collections.deque[int] = collections.deque()
        buffered = 0
        last_poll = last_answer = time.monotonic()
        try:
            while st.acked < len(lines):
                end = len(lines) if until is None or until() is None else min(until(), len(lines))
                while st.sent < end and buffered + len(data[st.sent]) <= RX_BUFFER_SIZE:
                    self._write(data[st.sent])
                    in_flight.append(len(data[st.sent]))
                    buffered += len(data[st.sent])
                    st.sent += 1
                now = time.monotonic()
                if now - last_poll >= self.poll:
                    self._write(b"?")
                    last_poll = now
                reply = self._read_line(0.05)
                if control is not None:
                    control(st)
                if reply is None:
                    if time.monotonic() - last_answer > self.timeout:
                        self._fail(st, lines, f"GRBL stopped answering for {self.timeout:g} s", st.acked + 1)
                    continue
                last_answer = time.monotonic()
                if reply == "ok" and in_flight:
                    buffered -= in_flight.popleft()
                    st.acked += 1
                elif reply.startswith("error:"):
                    code = int(reply[6:]) if reply[6:].isdigit() else -1
                    self._fail(st, lines, f"GRBL error:{code} ({ERRORS.get(code, 'unknown')})", st.acked + 1)
                elif reply.startswith("ALARM:"):
                    code = int(reply[6:]) if reply[6:].isdigit() else -1
                    self._fail(st, lines, f"GRBL ALARM:{code} ({ALARMS.get(code, 'unknown')})", st.acked + 1)
                elif reply.startswith("<"):
                    self._report(st, reply)
            while wait_idle:
                state = self._wait_report(st)
                if state.startswith("Idle"):
                    break
                if state.startswith("Alarm"):
                    self._fail(st, lines, "GRBL went into alarm after the last line", len(lines))
        except (serial.SerialException, OSError) as exc:
            err = self._vanished(exc, st, lines)
            err.stream = st
            raise err from None
        finally:
            self._control = None
        return st

    def _report(self, st: Stream, reply: str) -> str:
        status = st.status = parse_status(reply)
        pos = status.get("MPos") or status.get("WPos") or []
        st.reports.append((time.monotonic() - self._t0, status["state"], list(pos)))
        return status["state"]

    def _wait_report(self, st: Stream) -> str:
        deadline = time.monotonic() + self.idle_timeout
        while time.monotonic() < deadline:
            self._write(b"?")
            reply = self._read_line(self.poll)
            while reply is not None:
                if reply.startswith("<"):
                    state = self._report(st, reply)
                    if self._control is not None:
                        self._control(st)
                    return state
                if reply.startswith("ALARM:"):
                    return "Alarm"
                reply = self._read_line(0.0)
        raise DeviceError(f"GRBL did not come to rest within {self.idle_timeout:g} s", where=self.port)

    def _fail(self, st: Stream, lines: list[ProgramLine], what: str, number: int) -> None:
        """Stop: feed hold, soft reset (flushes what GRBL still holds), raise naming the line."""
        self.feed_hold()
        self.soft_reset()
        self._write(b"?")  # where it stopped, for the log
        reply = self._read_line(self.timeout)
        if reply is not None and reply.startswith("<"):
            self._report(st, reply)
        number = min(number, len(lines))
        line = lines[number - 1]
        unsent = len(lines) - st.sent
        discarded = st.sent - number
        st.events.append(Event("error", time.monotonic() - self._t0, "", f"{what} at line {number}"))
        err = DeviceError(f"{what} on {line.text!r}; stopped: {number - 1} lines before it acknowledged, "
                          f"{discarded} sent after it cut off by a soft reset (GRBL may have started them), "
                          f"{unsent} not sent",
                          where=f"line {number} ({line.source})")
        err.stream = st
        err.line = number
        raise err

    def command(self, text: str) -> str:
        """Send one line (e.g. ``$H``, ``$J=...``, ``M8``) and return GRBL's answer (ok, or raise)."""
        st = self.stream([ProgramLine(text, "command")], wait_idle=True)
        return "ok" if st.acked else ""


class GrblCard(MotionCard):
    """A GRBL board on a serial port as a MotionCard (axes X, Y, Z).

    ``pen``: the (down, up) commands a program's tool signal becomes (default M3 S1000 / M5, the pen
    on the spindle output as GRBL plotters have it), or None to send none.
    """

    def __init__(self, port: str, machine: Machine | None = None, *, baud: int = 115200, tolerance: float = 0.01,
                 timeout: float = 10.0, poll: float = 0.2, pen: tuple[str, str] | None = None):
        self.machine = machine if machine is not None else Machine()
        self.spec = f"grbl:{port}"
        self.ranges = GRBL_RANGES
        self.tolerance = tolerance
        self.pen = check_pen_commands(pen)
        self.streamer = GrblStreamer(port, baud, timeout=timeout, poll=poll)
        self._outputs = [False]

    def connect(self) -> None:
        self.streamer.connect()

    def close(self) -> None:
        self.streamer.close()

    def _log(self, st: Stream, outcome: str = "done", events=()) -> DeviceLog:
        names = self.machine.names
        if st.reports:
            t = np.array([r[0] for r in st.reports])
            pos = np.array([[r[2][i] if i < len(r[2]) else 0.0 for i in range(len(names))] for r in st.reports])
        else:  # no report came (a one-line command, or the port went away)
            t, pos = np.zeros(1), np.full((1, len(names)), np.nan)
        return DeviceLog(self.spec, names, 0.0, t, np.zeros(pos.shape, dtype=np.int32), pos, None, (),
                         list(st.events) + list(events), outcome,
                         {"device": "grbl", "acknowledged": st.acked, "sent": st.sent})

    def _stream(self, lines: list[ProgramLine], events=()) -> DeviceLog:
        try:
            st = self.streamer.stream(lines)
        except DeviceError as err:
            st = getattr(err, "stream", None)
            if st is not None:
                err.log = self._log(st, "alarm" if "ALARM" in err.message else "error")
            raise
        return self._log(st, "done", [*events, Event("done", st.reports[-1][0] if st.reports else 0.0, "",
                                                     f"{st.acked} lines acknowledged")])

    def run(self, motion: Trajectory | Steps | str, signals: Signal | None = None, *, check: bool = True) -> DeviceLog:
        """Stream a program; ``motion`` may also be G-code text (sent as written, after comments are removed)."""
        if isinstance(motion, str):
            return self._stream(text_gcode(motion))
        if check:
            preflight(motion, self.machine, signals, ranges=self.ranges)
        return self._stream(motion_gcode(motion, self.machine, signals, self.tolerance, self.pen))

    def check_program(self, motion: Trajectory | Steps, signals: Signal | None = None):
        report = self.check(motion, signals)
        motion_gcode(motion, self.machine, signals, self.tolerance, self.pen)  # what GRBL cannot do is refused
        return report

    def home(self, axes: tuple[str, ...] | None = None, method: str = "switch") -> DeviceLog:
        if method != "switch":
            raise DeviceError("GRBL homes with its own switch cycle ($H) only", where=self.spec)
        if axes and set(axes) != set(self.machine.names):
            raise DeviceError("GRBL homes all its axes together ($H)", where=self.spec)
        return self._stream([ProgramLine("$H", "home")])

    def jog(self, axis: str, distance: float, speed: float) -> DeviceLog:
        if axis not in ("X", "Y", "Z"):
            raise DeviceError(f"GRBL jogs X, Y or Z, not {axis!r}", where=self.spec)
        return self._stream([ProgramLine(f"$J=G91 G21 {axis}{distance:.4f} F{speed * 60:.1f}", "jog")])

    def estop(self) -> DeviceLog:
        self.streamer.soft_reset()
        return self._log(Stream(), "estop", [Event("estop", 0.0, "", "soft reset (Ctrl-X): GRBL stopped")])

    def reset(self) -> DeviceLog:
        """Soft reset (Ctrl-X), then ``$X`` to unlock an alarm (GRBL refuses G-code until then)."""
        self.streamer.soft_reset()
        return self._stream([ProgramLine("$X", "unlock")],
                            [Event("reset", 0.0, "", "soft reset and $X: alarm lock cleared")])

    def set_output(self, channel: int, on: bool) -> DeviceLog:
        if channel != 1:
            raise DeviceError(f"GRBL has one output flowmc drives (1: flood coolant M8/M9), not {channel}",
                              where=self.spec)
        return self._stream([ProgramLine("M8" if on else "M9", "output 1")])

    def read_inputs(self) -> dict[int, bool]:
        """GRBL's pins from the status report: X/Y/Z limits as inputs 9, 12, 15 (the card's axis switch
        places), probe as 1, door 2, hold 3, reset 4, cycle start 5."""
        pins = self.streamer.status().get("Pn", "")
        places = {"X": 9, "Y": 12, "Z": 15, "P": 1, "D": 2, "H": 3, "R": 4, "S": 5}
        return {ch: letter in pins for letter, ch in places.items()}

    def set_pwm(self, freq: float, duty: float) -> DeviceLog:
        raise DeviceError("GRBL's PWM is its spindle output at a frequency fixed in firmware; use set_spindle",
                          where=self.spec)

    def set_da(self, volts: float) -> DeviceLog:
        raise DeviceError("GRBL has no analog output", where=self.spec)

    def set_spindle(self, rpm: float) -> DeviceLog:
        text = "M5" if rpm == 0 else f"{'M3' if rpm > 0 else 'M4'} S{abs(rpm):.0f}"
        return self._stream([ProgramLine(text, "spindle")])

    def position(self) -> np.ndarray:
        pos = self.streamer.status().get("MPos", [])
        return np.array([pos[i] if i < len(pos) else 0.0 for i in range(len(self.machine.names))])

    def status(self) -> dict:
        return {"device": "grbl", "port": self.streamer.port, **self.streamer.status()}
