"""The Cortex-M4 system control space (ARMv7-M ARM B3): NVIC, SCB, SysTick, DWT, the
debug control block and the FPU's control registers; and the exception model that uses
them (priorities, pending, active, BASEPRI/PRIMASK masking)."""

from .regs import Peripheral

# STM32F4 implements 4 priority bits (PM0214 4.3.7)
PRIO_MASK = 0xF0
IRQS = 82


class Scs(Peripheral):
    """0xE000E000..0xE000F000: ICTR, SysTick, NVIC, SCB, FPU, STIR."""

    name = "SCS"
    size = 0x1000

    def define(self):
        r = self.reg
        r(0x004, "ICTR", 2)
        r(0x008, "ACTLR", 0)
        r(0x010, "SYST_CSR", 0)
        r(0x014, "SYST_RVR", 0, 0x00FF_FFFF)
        r(0x018, "SYST_CVR", 0)
        r(0x01C, "SYST_CALIB", 0x4000_0000 | 20_999)
        for i in range(3):
            r(0x100 + 4 * i, f"ISER{i}")
            r(0x180 + 4 * i, f"ICER{i}")
            r(0x200 + 4 * i, f"ISPR{i}")
            r(0x280 + 4 * i, f"ICPR{i}")
            r(0x300 + 4 * i, f"IABR{i}")
        for i in range(21):
            r(0x400 + 4 * i, f"IPR{i}")
        r(0xD00, "CPUID", 0x410F_C241)
        r(0xD04, "ICSR", 0)
        r(0xD08, "VTOR", 0, 0xFFFF_FE00)
        r(0xD0C, "AIRCR", 0xFA05_0000)
        r(0xD10, "SCR", 0, 0x16)
        r(0xD14, "CCR", 0x200, 0x31B)
        r(0xD18, "SHPR1", 0)
        r(0xD1C, "SHPR2", 0)
        r(0xD20, "SHPR3", 0)
        r(0xD24, "SHCSR", 0)
        r(0xD28, "CFSR", 0)
        r(0xD2C, "HFSR", 0)
        r(0xD30, "DFSR", 0)
        r(0xD34, "MMFAR", 0)
        r(0xD38, "BFAR", 0)
        r(0xD3C, "AFSR", 0)
        r(0xD88, "CPACR", 0)
        r(0xDF0, "DHCSR", 0)
        r(0xDF4, "DCRSR", 0)
        r(0xDF8, "DCRDR", 0)
        r(0xDFC, "DEMCR", 0)
        r(0xF00, "STIR", 0)
        r(0xF34, "FPCCR", 0xC000_0000)
        r(0xF38, "FPCAR", 0)
        r(0xF3C, "FPDSCR", 0)
        # the priority registers themselves (`priority` reads them at every look at what
        # is pending)
        self.ipr = [self.by_name[f"IPR{i}"] for i in range(21)]
        self.shpr = [self.by_name[f"SHPR{i}"] for i in range(1, 4)]
        self.aircr = self.by_name["AIRCR"]
        self.enabled = [False] * IRQS
        self.pending = set()  # exception numbers
        self.active = []  # stack of exception numbers
        self.syst_base = None  # (s, reload) when SysTick was (re)loaded

    # --- NVIC -----------------------------------------------------------------
    def _irq_bits(self, idx, v, setit, attr):
        for b in range(32):
            if v >> b & 1:
                n = idx * 32 + b
                if n >= IRQS:
                    continue
                if attr == "en":
                    self.enabled[n] = setit
                elif setit:
                    self.pending.add(16 + n)
                else:
                    self.pending.discard(16 + n)
        self.twin.reschedule()

    def read32(self, off):
        if 0x100 <= off < 0x30C:
            idx = (off & 0x7F) // 4
            base = off & ~0x7F
            if base in (0x100, 0x180):
                return sum(1 << b for b in range(32) if idx * 32 + b < IRQS and self.enabled[idx * 32 + b])
            if base in (0x200, 0x280):
                return sum(1 << b for b in range(32) if 16 + idx * 32 + b in self.pending)
            if base == 0x300:
                return sum(1 << b for b in range(32) if 16 + idx * 32 + b in self.active)
        return super().read32(off)

    def write32(self, off, value, lane_mask=0xFFFFFFFF):
        if 0x100 <= off < 0x30C:
            self.lookup(off)
            idx = (off & 0x7F) // 4
            base = off & ~0x7F
            v = value & lane_mask
            {
                0x100: lambda: self._irq_bits(idx, v, True, "en"),
                0x180: lambda: self._irq_bits(idx, v, False, "en"),
                0x200: lambda: self._irq_bits(idx, v, True, "pend"),
                0x280: lambda: self._irq_bits(idx, v, False, "pend"),
                0x300: lambda: None,
            }[base]()
            return
        if 0x400 <= off < 0x454 or 0xD0C <= off <= 0xD20:
            # IPR, AIRCR (PRIGROUP), SHPR: a priority that changes while an exception
            # waits may make an instruction that lowers BASEPRI or PRIMASK let it in,
            # where the chunk runs without exits (`Twin._exits_for_chunk`): then the
            # chunk ends after the store, and the next looks again
            super().write32(off, value, lane_mask)
            tw = self.twin
            if tw.in_chunk and tw.exits_now is tw.no_exits and tw._exits_for_chunk() is not tw.no_exits:
                tw.reschedule()
            return
        super().write32(off, value, lane_mask)

    def on_write_STIR(self, v, _lanes):
        n = v & 0x1FF
        if n < IRQS:
            self.pending.add(16 + n)
            self.twin.reschedule()

    def priority(self, exc):
        """Configured priority of exception number `exc` (lower = more urgent)."""
        if exc == 1:
            return -3
        if exc == 2:
            return -2
        if exc == 3:
            return -1
        if exc >= 16:
            n = exc - 16
            return (self.ipr[n // 4].value >> (8 * (n % 4))) & PRIO_MASK
        shpr = self.shpr[(exc - 4) // 4].value
        return (shpr >> (8 * (exc % 4))) & PRIO_MASK

    def group(self, prio):
        """Group (preemption) priority under AIRCR.PRIGROUP."""
        if prio < 0:
            return prio
        pg = self.aircr.value >> 8 & 7
        return prio & ~((1 << (pg + 1)) - 1) & 0xFF

    def exception_enabled(self, exc):
        if exc >= 16:
            return self.enabled[exc - 16]
        return True

    # --- SCB ------------------------------------------------------------------
    def on_read_ICSR(self):
        v = self["ICSR"] & 0
        if self.active:
            v |= self.active[-1]
        if 14 in self.pending:
            v |= 1 << 28
        if 15 in self.pending:
            v |= 1 << 26
        pend = [e for e in self.pending]
        if pend:
            v |= min(pend) << 12
            v |= 1 << 22
        if len(self.active) <= 1:
            v |= 1 << 11  # RETTOBASE
        return v

    def on_write_ICSR(self, v, _lanes):
        if v & (1 << 31):
            self.pending.add(2)
        if v & (1 << 28):
            self.pending.add(14)
        if v & (1 << 27):
            self.pending.discard(14)
        if v & (1 << 26):
            self.pending.add(15)
        if v & (1 << 25):
            self.pending.discard(15)
        self.twin.reschedule()

    def on_write_AIRCR(self, v, _lanes):
        if v >> 16 != 0x05FA:
            return  # writes without VECTKEY are ignored (ARMv7-M B3.2.6)
        self["AIRCR"] = 0xFA05_0000 | (v & 0x700)
        if v & 4:
            self.twin.request_reset("SYSRESETREQ")

    def on_write_CFSR(self, v, _lanes):
        self["CFSR"] &= ~v

    def on_write_HFSR(self, v, _lanes):
        self["HFSR"] &= ~v

    def on_write_CPACR(self, v, _lanes):
        self.store("CPACR", v)

    # --- SysTick (PM0214 4.5) -------------------------------------------------
    # the counter as (time it held `syst_v0`, that value); `syst_next`: its next 1 -> 0
    syst_t0 = syst_v0 = syst_next = None

    def _syst_hz(self):
        h = self.twin.rcc.hclk_hz()
        return h if self["SYST_CSR"] & 4 else h / 8

    def _syst_start(self, value):
        rvr = self["SYST_RVR"]
        # a current value of 0 loads the reload value at the first tick
        v0 = value if value else rvr + 1
        self.syst_t0, self.syst_v0 = self.twin.now_s(), v0
        self.syst_next = self.syst_t0 + v0 / self._syst_hz() if rvr or value else None
        self.twin.reschedule()

    def on_write_SYST_CSR(self, v, _lanes):
        was = self["SYST_CSR"] & 1
        if was:
            self["SYST_CVR"] = self.on_read_SYST_CVR()
        self["SYST_CSR"] = (self["SYST_CSR"] & (1 << 16)) | (v & 7)
        if v & 1:
            self._syst_start(self["SYST_CVR"])
        else:
            self.syst_t0 = self.syst_next = None

    def on_read_SYST_CSR(self):
        v = self["SYST_CSR"]
        self["SYST_CSR"] = v & ~(1 << 16)
        return v

    def on_write_SYST_CVR(self, _v, _lanes):
        self["SYST_CVR"] = 0
        self["SYST_CSR"] &= ~(1 << 16)
        if self["SYST_CSR"] & 1:
            self._syst_start(0)

    def on_read_SYST_CVR(self):
        if self.syst_t0 is None:
            return self["SYST_CVR"]
        k = int((self.twin.now_s() - self.syst_t0) * self._syst_hz())
        return max(0, min(self.syst_v0 - k, self["SYST_RVR"]))

    def events(self):
        return self.syst_next

    def tick(self, now_s):
        if self.syst_next is None or now_s < self.syst_next:
            return
        self["SYST_CSR"] |= 1 << 16
        if self["SYST_CSR"] & 2:
            self.pending.add(15)
        rvr = self["SYST_RVR"]
        self.syst_t0, self.syst_v0 = self.syst_next, rvr + 1
        self.syst_next = self.syst_next + (rvr + 1) / self._syst_hz() if rvr else None

    def clocks_changed(self):
        if self.syst_t0 is not None:
            self._syst_start(self.on_read_SYST_CVR())


class Dwt(Peripheral):
    """DWT (0xE0001000): the cycle counter the firmware's `isr_cyc` counts with."""

    name = "DWT"
    size = 0x1000

    def define(self):
        self.reg(0x000, "CTRL", 0x4000_0000)
        self.reg(0x004, "CYCCNT", 0)
        self.reg(0xFB0, "LAR", 0)
        self.reg(0xFB4, "LSR", 3)
        self.base_cycles = 0

    def on_read_CYCCNT(self):
        if self["CTRL"] & 1 and self.twin.scs["DEMCR"] & (1 << 24):
            return (self.twin.now_cycles() - self.base_cycles) & 0xFFFFFFFF
        return self["CYCCNT"]

    def on_write_CYCCNT(self, v, _lanes):
        self["CYCCNT"] = v
        self.base_cycles = self.twin.now_cycles() - v

    def on_write_CTRL(self, v, _lanes):
        was = self["CTRL"] & 1
        if was and not v & 1:
            self["CYCCNT"] = self.on_read_CYCCNT()
        if v & 1 and not was:
            self.base_cycles = self.twin.now_cycles() - self["CYCCNT"]
        self["CTRL"] = 0x4000_0000 | (v & 0x3FFF_FFFF)

    def on_write_LAR(self, v, _lanes):
        self["LSR"] = 1 if v == 0xC5ACCE55 else 3
