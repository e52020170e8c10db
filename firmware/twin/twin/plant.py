"""The closed loop: the board's drive pins → the amplifiers and axes of `gantry --sim`
(controller-core's `sim` world, run by the `twin-plant` helper: host-sim/src/twin_plant.rs
has its protocol) → quadrature counts into the encoder timers, limit switches and
amplifier faults onto their input pins, and the index pulses the step passed onto the
index pins with the count each came at (`Twin.index_pulses`).

The plant integrates one control period per step, at each of TIM4's update events (the
control tick): it holds, over the period that just ended, the drive the pins give at its
end (the duty the firmware wrote early in that period), the way host-sim holds the
servo's effort over a period. Its rate is TIM4's, derived from the clocks the firmware
programmed, so a 20 kHz build gets a 20 kHz plant."""

import json
import os
import struct
import subprocess

from . import board
from .regs import TwinError

STEP = struct.Struct("<cBB3d")
SENSED = struct.Struct("<3qBBB3q")
TRUTH = struct.Struct("<6d")


def default_helper():
    root = os.path.normpath(os.path.join(os.path.dirname(__file__), "..", "..", ".."))
    target = os.environ.get("CARGO_TARGET_DIR", os.path.join(root, "target"))
    return os.environ.get("TWIN_PLANT", os.path.join(target, "release", "twin-plant"))


class Plant:
    def __init__(self, twin, helper=None):
        self.twin = twin
        self.helper = helper or default_helper()
        if not os.path.isfile(self.helper):
            raise TwinError(f"the plant helper {self.helper} is missing: build it with `cargo build -p host-sim --release --bin twin-plant`")
        self.proc = None
        self.rate_hz = None
        self.steps = 0
        self.counts = [0, 0, 0]
        self.levels = {}

    def _start(self, rate_hz):
        self.rate_hz = rate_hz
        self.proc = subprocess.Popen([self.helper, "--rate-hz", str(rate_hz)], stdin=subprocess.PIPE,
                                     stdout=subprocess.PIPE, bufsize=0)
        self.w, self.r = self.proc.stdin, self.proc.stdout
        self.wfd, self.rfd = self.w.fileno(), self.r.fileno()
        # the helper is woken by every step the twin writes: as a batch task it does not
        # preempt the twin on that wake-up (the twin went on waiting for the CPU inside
        # the write, up to a millisecond on a loaded machine); it runs beside it, or
        # when the twin next waits for its answer. Nothing of the exchange changes.
        try:
            os.sched_setscheduler(self.proc.pid, os.SCHED_BATCH, os.sched_param(0))
        except (AttributeError, OSError):
            pass

    def _read(self, n):
        b = b""
        while len(b) < n:
            part = os.read(self.rfd, n - len(b))
            if not part:
                code = self.proc.poll()
                raise TwinError(f"the plant helper ended (exit {code})")
            b += part
        return b

    def drive(self):
        """The drive the pins give now: enables, brakes, and per axis the duty signed by DIR
        (high drives towards negative positions, firmware/src/drive.rs)."""
        t = self.twin
        # the pins change far less often than the plant steps
        if self._drive is not None and self._drive[0] == t.pin_generation:
            return self._drive[1]
        en = br = 0
        duty = []
        for i, a in enumerate(board.AXES):
            port, pin = board.ENABLE[a]
            en |= (t.gpio[port].level(pin) or 0) << i
            port, pin = board.BRAKE[a]
            br |= (t.gpio[port].level(pin) or 0) << i
            port, pin, ch = board.PWM[a]
            g = t.gpio[port]
            d = t.tim["TIM1"].channel_duty(ch) if g.mode(pin) == 2 and g.af(pin) == 1 else 0.0
            port, pin = board.DIRECTION[a]
            duty.append(-d if t.gpio[port].level(pin) else d)
        self._drive = (t.pin_generation, (en, br, duty))
        return en, br, duty

    _drive = None

    def control_update(self, rate_hz):
        """TIM4's update: one period of the plant. Its answer is taken when the board next
        looks at an input (`settle`): the helper integrates while the core enters the
        control interrupt."""
        self.settle()
        if self.proc is None:
            self._start(rate_hz)
        en, br, duty = self.drive()
        # (a pipe takes the 27 bytes whole; os.write without the file object's layer)
        if os.write(self.wfd, STEP.pack(b"S", en, br, *duty)) != STEP.size:
            raise TwinError("the plant helper's pipe took a step in part")
        self.pending = True

    pending = False

    def settle(self, between_runs=False):
        """The step under way, onto the board's inputs: the counts into the encoder timers,
        the switches and amplifier faults onto their pins, the index pulses onto theirs.
        `between_runs`: the run loop lands it where the core can take what the index
        pulse raises before its next instruction (`Twin._land_step`); anywhere else (an
        access of the core, a scenario between runs) the pulse ends at once."""
        if not self.pending:
            return
        self.pending = False
        v = SENSED.unpack(self._read(SENSED.size))
        counts, limits, faults, index, at_index = v[:3], v[3], v[4], v[5], v[6:]
        self.steps += 1
        t = self.twin
        # (an index pulse still up ends first: its step's counts land before this one's)
        t.end_index_pulse()
        passed = {a: at_index[i] for i, a in enumerate(board.AXES) if index >> i & 1}
        for a, c in zip(board.AXES, counts):
            if a not in passed:
                t.encoder[board.ENCODER_TIMER[a]] = c
        self.counts = list(counts)
        want = {}
        for i, a in enumerate(board.AXES):
            want[board.LIMITS[f"{a}-"]] = limits >> (2 * i) & 1
            want[board.LIMITS[f"{a}+"]] = limits >> (2 * i + 1) & 1
            want[board.AMP_FAULT[a]] = faults >> i & 1
        for pin, lv in want.items():
            if self.levels.get(pin) != lv:
                self.levels[pin] = lv
                t.drive(pin, lv)
        if passed:
            t.index_pulses(passed, {a: counts[board.AXES.index(a)] for a in passed})
            if not between_runs:
                t.end_index_pulse()

    def truth(self):
        """The axes' true positions (mm) and velocities (mm/s)."""
        self.settle()
        if self.proc is None:
            return [0.0] * 3, [0.0] * 3
        self.w.write(b"T")
        v = TRUTH.unpack(self._read(TRUTH.size))
        return list(v[:3]), list(v[3:])

    def inject(self, injection):
        """A fault in the machine (controller-core's `Injection`, e.g. {"encoder_stuck": {"axis": "x"}})."""
        self.settle()
        if self.proc is None:
            raise TwinError("an injection before the control tick started")
        b = json.dumps(injection).encode()
        self.w.write(b"J" + struct.pack("<H", len(b)) + b)
        if self._read(1) != b"\0":
            raise TwinError(f"the plant refused the injection {injection}")

    def close(self):
        self.settle()
        if self.proc is not None:
            self.proc.stdin.close()
            self.proc.wait(timeout=10)
            self.proc = None
