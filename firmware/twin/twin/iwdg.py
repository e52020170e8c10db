"""The independent watchdog (RM0090 §19): keys, prescaler, reload, the PVU/RVU busy
flags, and a reset of the whole chip on expiry. Its clock is the LSI, whose frequency
the scenario sets within DS8626's 17–47 kHz (32 kHz typical)."""

from .regs import Peripheral

LSI_TYPICAL_HZ = 32_000
# PR/RLR reach the LSI domain after 5 LSI cycles (RM0090 19.4.4: "up to 5 RC 40 kHz cycles")
UPDATE_LSI_CYCLES = 5


class Iwdg(Peripheral):
    name = "IWDG"

    def __init__(self, twin, base, lsi_hz):
        self.lsi_hz = lsi_hz
        self.running = False
        self.unlocked = False
        self.deadline = None
        self.busy_until = 0.0
        super().__init__(twin, base)

    def define(self):
        self.reg(0x00, "KR", 0, 0)
        self.reg(0x04, "PR", 0, 7)
        self.reg(0x08, "RLR", 0xFFF, 0xFFF)
        self.reg(0x0C, "SR", 0, 0)

    def _timeout_s(self):
        div = 4 << min(self["PR"], 6)
        return (self["RLR"] + 1) * div / self.lsi_hz

    def on_write_KR(self, v, _lanes):
        key = v & 0xFFFF
        now = self.twin.now_s()
        if key == 0xCCCC:
            self.running = True
            self.deadline = now + self._timeout_s()
        elif key == 0xAAAA:
            self.unlocked = False
            if self.running:
                self.deadline = now + self._timeout_s()
        elif key == 0x5555:
            self.unlocked = True
        else:
            self.unlocked = False
        self.twin.reschedule()

    def _write_locked(self, name, v):
        if self.unlocked:
            self.store(name, v)
            self.busy_until = self.twin.now_s() + UPDATE_LSI_CYCLES / self.lsi_hz

    def on_write_PR(self, v, _lanes):
        self._write_locked("PR", v)

    def on_write_RLR(self, v, _lanes):
        self._write_locked("RLR", v)

    def on_read_SR(self):
        return 3 if self.twin.now_s() < self.busy_until else 0

    def events(self):
        return self.deadline if self.running else None

    def tick(self, now_s):
        if self.running and now_s >= self.deadline:
            self.twin.request_reset("IWDG")
