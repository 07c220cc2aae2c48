"""flowmc's LinuxCNC display program: runs one G-code file headless, then exits.

LinuxCNC starts this as its [DISPLAY] program (``display.py -ini FILE``) under the
system Python (/usr/bin/python3), which has LinuxCNC's ``linuxcnc`` module; it
never imports flowmc. What it needs comes from the INI's [FLOWMC] section. It
switches the machine on, homes in place, restores the outputs and spindle of the
previous operation, starts ``halsampler`` on the sampler FIFO, runs the program,
and writes events (JSON lines: state, progress, position, errors) and a final result
(JSON) for flowmc's backend to read. When it exits, the ``linuxcnc`` script shuts the
whole machine down.

The program runs in this process, so flowmc's commands come in through a file: while
the program runs, each new line of [FLOWMC] COMMANDS is one command, given to the task
as an operator would (``pause``: AUTO_PAUSE, a feed hold that decelerates along the
path; ``resume``: AUTO_RESUME; ``abort``: the task's abort, a stop along the path within
the acceleration limits that clears the rest, then spindle and outputs off; ``estop``:
the machine's e-stop state at once, then the same outputs off; ``feed P``, ``rapid P``,
``spindle P``: the overrides, P in %; ``optional_stop 0|1``: whether the program's M1 stops, which
LinuxCNC reads as it reaches each M1; its value at the start is [FLOWMC] OPTIONAL_STOP, off unless
asked, where LinuxCNC's own default is on). A pause of the program's own (M0, M1) is reported as
``held`` like a feed hold, with the motion line it rests after.
"""

import json
import os
import signal
import subprocess
import sys
import time


def getp(name):
    """A HAL pin or parameter's value, as halcmd prints it."""
    return subprocess.run(["halcmd", "getp", name], capture_output=True, text=True, check=True).stdout.strip()


class Run:
    """One program run; ``emit`` appends an event line the backend follows."""

    def __init__(self, ini_path):
        import linuxcnc

        self.lc = linuxcnc
        ini = linuxcnc.ini(ini_path)
        self.program = ini.find("FLOWMC", "PROGRAM")
        self.events_path = ini.find("FLOWMC", "EVENTS")
        self.result_path = ini.find("FLOWMC", "RESULT")
        self.samples_path = ini.find("FLOWMC", "SAMPLES")
        self.timeout = float(ini.find("FLOWMC", "TIMEOUT"))
        self.settle = float(ini.find("FLOWMC", "SETTLE_TIME"))
        self.dout = [v == "1" for v in ini.find("FLOWMC", "DOUT").split()]
        self.aout = [float(v) for v in ini.find("FLOWMC", "AOUT").split()]
        self.spindle_rpm = float(ini.find("FLOWMC", "SPINDLE_RPM"))
        self.stat = linuxcnc.stat()
        self.command = linuxcnc.command()
        self.errors = linuxcnc.error_channel()
        self.messages = []
        self.sampler = None
        self.events = open(self.events_path, "a", buffering=1)
        self.commands_path = ini.find("FLOWMC", "COMMANDS")
        self.commands_offset = 0
        self.keep_on = [int(v) for v in (ini.find("FLOWMC", "KEEP_ON") or "").split()]
        self.optional_stop = (ini.find("FLOWMC", "OPTIONAL_STOP") or "0") == "1"

    def emit(self, kind, **data):
        data.update(kind=kind, t=time.time())
        self.events.write(json.dumps(data) + "\n")

    def poll_errors(self):
        """Drain LinuxCNC's error channel; return the new operator errors."""
        new = []
        while True:
            msg = self.errors.poll()
            if not msg:
                return new
            kind, text = msg
            error = kind in (self.lc.OPERATOR_ERROR, self.lc.NML_ERROR)
            self.stat.poll()
            entry = {"error": error, "text": text, "read_line": self.stat.read_line,
                     "motion_line": self.stat.motion_line, "current_line": self.stat.current_line}
            self.messages.append(entry)
            self.emit("message", **entry)
            if error:
                new.append(entry)

    def wait(self, what, done, timeout):
        deadline = time.time() + timeout
        while time.time() < deadline:
            self.stat.poll()
            if done(self.stat):
                return
            if self.poll_errors():
                raise RuntimeError(f"LinuxCNC refused while {what}")
            time.sleep(0.005)
        raise TimeoutError(f"LinuxCNC did not finish {what} within {timeout:g} s")

    def start_sampler(self):
        self.sampler = subprocess.Popen(["halsampler", "-t", self.samples_path],
                                        stdin=subprocess.DEVNULL)
        subprocess.run(["halcmd", "setp", "sampler.0.enable", "1"], check=True)

    def stop_sampler(self):
        """Stop sampling, let halsampler drain the FIFO, then end it; returns samples lost."""
        subprocess.run(["halcmd", "setp", "sampler.0.enable", "0"], check=False)
        deadline = time.time() + 10.0
        while time.time() < deadline and int(getp("sampler.0.curr-depth")) > 0:
            time.sleep(0.01)
        time.sleep(0.05)
        self.sampler.send_signal(signal.SIGTERM)
        try:
            self.sampler.wait(5.0)
        except subprocess.TimeoutExpired:
            self.sampler.kill()
            self.sampler.wait()
        return int(getp("sampler.0.overruns"))

    def machine_on(self):
        lc, c = self.lc, self.command
        c.state(lc.STATE_ESTOP_RESET)
        c.state(lc.STATE_ON)
        self.wait("switching on", lambda s: s.task_state == lc.STATE_ON, 10.0)
        c.mode(lc.MODE_MANUAL)
        c.home(-1)
        self.wait("homing", lambda s: all(s.homed[j] for j in range(s.joints)), 10.0)
        self.restore_outputs()
        c.mode(lc.MODE_AUTO)
        self.wait("entering auto mode", lambda s: s.task_mode == lc.MODE_AUTO, 10.0)

    def restore_outputs(self):
        """Outputs and spindle as the previous operation left them, before anything is sampled."""
        lc, c = self.lc, self.command
        for i, on in enumerate(self.dout):
            c.set_digital_output(i, int(on))
        for i, volts in enumerate(self.aout):
            c.set_analog_output(i, volts)
        if self.spindle_rpm:
            c.spindle(lc.SPINDLE_FORWARD if self.spindle_rpm > 0 else lc.SPINDLE_REVERSE, abs(self.spindle_rpm))
        self.wait("restoring outputs", lambda s: (
            [bool(v) for v in s.dout[:len(self.dout)]] == self.dout
            and all(abs(a - b) < 1e-9 for a, b in zip(s.aout, self.aout))
            and abs(s.spindle[0]["speed"] - self.spindle_rpm) < 1e-6), 10.0)

    def take_commands(self):
        """New lines of the command file (complete lines only)."""
        try:
            with open(self.commands_path) as f:
                f.seek(self.commands_offset)
                chunk = f.read()
        except OSError:
            return []
        complete = chunk[: chunk.rfind("\n") + 1]
        self.commands_offset += len(complete.encode())
        return [line.split() for line in complete.splitlines() if line.strip()]

    def operator(self, name, *value):
        """One operator command while the program runs; returns how the run ends ("aborted"/"estop") or None."""
        lc, c, s = self.lc, self.command, self.stat
        s.poll()
        self.emit("message", error=False, text=f"{' '.join([name, *value])} at line {s.motion_line}")
        if name == "optional_stop":  # the program's M1 stops while on (checked as LinuxCNC reaches each M1)
            c.set_optional_stop(value[0] == "1")
            return None
        if name in ("feed", "rapid", "spindle"):  # overrides, in %
            scale = float(value[0]) / 100.0
            {"feed": c.feedrate, "rapid": c.rapidrate, "spindle": c.spindleoverride}[name](scale)
            return None
        if name == "pause" and not s.paused:
            c.auto(lc.AUTO_PAUSE)
            self.emit("state", state="holding", line=s.motion_line)
        elif name == "resume" and s.paused:
            c.auto(lc.AUTO_RESUME)
            self.emit("state", state="running", line=s.motion_line)
        elif name == "abort":
            self.emit("state", state="stopping", line=s.motion_line)
            c.abort()
            self.wait("stopping", lambda st: st.current_vel == 0.0 and st.exec_state == lc.EXEC_DONE, 10.0)
            self.make_safe()
            return "aborted"
        elif name == "estop":
            c.state(lc.STATE_ESTOP)
            self.wait("the e-stop", lambda st: st.task_state == lc.STATE_ESTOP, 10.0)
            self.make_safe()
            return "estop"
        return None

    def make_safe(self):
        """Spindle off, analog outputs 0 V, digital outputs off but the kept ones; waits until HAL shows it."""
        lc, c = self.lc, self.command
        self.stat.poll()
        if self.stat.task_state == lc.STATE_ESTOP:  # motion's outputs still take commands once reset and on
            c.state(lc.STATE_ESTOP_RESET)
            c.state(lc.STATE_ON)
            self.wait("switching on after the e-stop", lambda st: st.task_state == lc.STATE_ON, 10.0)
        c.mode(lc.MODE_MANUAL)
        c.wait_complete(5.0)
        c.spindle(lc.SPINDLE_OFF)
        for i in range(len(self.dout)):
            c.set_digital_output(i, int(i + 1 in self.keep_on))
        for i in range(len(self.aout)):
            c.set_analog_output(i, 0.0)
        self.wait("making the outputs safe", lambda st: st.spindle[0]["speed"] == 0.0 and not any(
            st.dout[i] for i in range(len(self.dout)) if i + 1 not in self.keep_on), 10.0)
        self.emit("state", state="safe")

    def run_program(self):
        lc, c = self.lc, self.command
        c.program_open(self.program)
        c.wait_complete(10.0)
        if self.poll_errors():
            raise RuntimeError("LinuxCNC refused the program")
        c.set_optional_stop(self.optional_stop)  # LinuxCNC's own default is on
        c.wait_complete(5.0)
        c.auto(lc.AUTO_RUN, 0)
        # Not wait_complete(): the task answers AUTO_RUN only once the program has ended. Wait until
        # the interpreter runs (a short program may already be over; the loop below sees that).
        deadline = time.time() + 1.0
        while time.time() < deadline:
            self.stat.poll()
            if self.stat.interp_state != lc.INTERP_IDLE:
                break
            time.sleep(0.005)
        self.emit("state", state="running")
        started = time.time()
        seen_busy = False
        last_line = -1
        last_position = 0.0
        held = False
        last_loop = time.time()
        while True:
            time.sleep(0.01)
            now = time.time()
            if self.stat.paused:
                started += now - last_loop  # time spent held does not count against the timeout
            last_loop = now
            for words in self.take_commands():
                ended = self.operator(*words)
                if ended:
                    return ended
            self.stat.poll()
            s = self.stat
            if self.poll_errors():
                raise RuntimeError("LinuxCNC refused the program")
            if s.paused and s.current_vel == 0.0 and not held:
                self.emit("state", state="held", line=s.motion_line, current_line=s.current_line,
                          position=list(s.position[:3]))
            held = bool(s.paused and s.current_vel == 0.0)
            if time.time() - last_position >= 0.04:  # 25 Hz position readout
                last_position = time.time()
                self.emit("position", position=list(s.position[:3]), line=s.motion_line,
                          velocity=s.current_vel, paused=bool(s.paused))
            if s.paused:
                continue  # held on the path: not the program's end
            busy = s.interp_state != lc.INTERP_IDLE or s.queue > 0 or not s.inpos
            seen_busy = seen_busy or busy
            if s.motion_line != last_line:
                last_line = s.motion_line
                self.emit("progress", line=s.motion_line, read_line=s.read_line)
            if seen_busy and not busy and s.exec_state == lc.EXEC_DONE:
                return "done"
            if not seen_busy and time.time() - started > 2.0:
                return "done"  # a program without motion ends before we see it busy
            if time.time() - started > self.timeout:
                raise TimeoutError(f"the program did not finish within {self.timeout:g} s")

    def stop_machine(self):
        lc, c = self.lc, self.command
        try:
            c.abort()
            c.state(lc.STATE_OFF)
            c.state(lc.STATE_ESTOP)
            c.wait_complete(2.0)
        except Exception as exc:  # the machine is going down with us anyway
            self.emit("message", error=False, text=f"stopping: {exc}")

    def main(self):
        result = {"status": "error", "errors": [], "position": None, "overruns": None, "messages": []}
        self.emit("state", state="started", pid=os.getpid())
        try:
            self.machine_on()
            self.start_sampler()
            result["status"] = self.run_program()
            time.sleep(self.settle)
        except TimeoutError as exc:
            result["status"] = "timeout"
            result["errors"].append({"text": str(exc)})
        except Exception as exc:
            result["errors"].append({"text": str(exc)})
        finally:
            self.stat.poll()
            result["position"] = list(self.stat.position[:3])
            result["messages"] = self.messages
            # On success the record ends as the program left the machine; after a failure the
            # abort (motion stopping, outputs as they were) is recorded too.
            ended = result["status"] in ("done", "aborted", "estop")
            if not ended:
                self.stop_machine()
            if self.sampler is not None:
                result["overruns"] = self.stop_sampler()
            if ended:
                self.stop_machine()
            tmp = self.result_path + ".part"
            with open(tmp, "w") as f:
                json.dump(result, f)
            os.replace(tmp, self.result_path)
            self.emit("state", state="finished", status=result["status"])
            self.events.close()


if __name__ == "__main__":
    Run(sys.argv[sys.argv.index("-ini") + 1]).main()
