"""TIM1 (advanced: PWM, BDTR with its write-once LOCK, the break input) and TIM2–TIM5
(general purpose: encoder mode, input capture of the encoders' index pulses, the control
tick's update interrupt), RM0090 §17–18.

A timer counts up at its kernel clock / (PSC + 1) from the RCC's timer clock; PSC, ARR
(with ARPE) and CCRx (with OCxPE) are preloaded and take effect at the update event, as
the hardware does. TIM1's outputs are computed when asked (the PWM is 20 kHz: nothing
schedules its updates), with every change of what a channel drives logged in time."""

from .regs import Peripheral, TwinError

ADVANCED, GP32, GP16 = "advanced", "gp32", "gp16"


class Timer(Peripheral):
    def __init__(self, twin, base, name, kind, clock, apb, irq):
        self.name = name
        self.kind = kind
        self.clock = clock
        self.apb = apb
        self.irq = irq
        self.cnt_t0 = 0.0  # time the counter held cnt_v0 (while counting)
        self.cnt_v0 = 0
        self.psc_active = 0
        self.arr_active = 0xFFFF if kind != GP32 else 0xFFFF_FFFF
        self.ccr_active = [0, 0, 0, 0]
        self.enc_offset = 0  # encoder mode: CNT = offset + the axis' counts
        self.ic_edges = [0, 0, 0, 0]  # input capture: edges counted by each prescaler
        self.bdtr_written = False
        self.next_update = None
        super().__init__(twin, base)
        # the registers the counting and compare paths read, held (not looked up by name)
        r = self.by_name
        self.r_cr1, self.r_smcr, self.r_sr = r["CR1"], r["SMCR"], r["SR"]
        self.r_ccr = [r[f"CCR{i + 1}"] for i in range(4)]
        self.r_ccmr = [r["CCMR1"], r["CCMR2"]]

    def define(self):
        top = 0xFFFF_FFFF if self.kind == GP32 else 0xFFFF
        r = self.reg
        r(0x00, "CR1", 0, 0x3FF)
        r(0x04, "CR2", 0, 0x7FFD if self.kind == ADVANCED else 0xF8)
        r(0x08, "SMCR", 0, 0xFFF7)
        r(0x0C, "DIER", 0, 0x7FFF if self.kind == ADVANCED else 0x5F5F)
        r(0x10, "SR", 0)
        r(0x14, "EGR", 0, 0)
        r(0x18, "CCMR1", 0)
        r(0x1C, "CCMR2", 0)
        r(0x20, "CCER", 0, 0x3FFF if self.kind == ADVANCED else 0xBBBB)
        r(0x24, "CNT", 0, top)
        r(0x28, "PSC", 0, 0xFFFF)
        r(0x2C, "ARR", top, top)
        for i in range(4):
            r(0x34 + 4 * i, f"CCR{i + 1}", 0, top)
        r(0x48, "DCR", 0)
        r(0x4C, "DMAR", 0)
        if self.kind == ADVANCED:
            r(0x30, "RCR", 0, 0xFF)
            r(0x44, "BDTR", 0)
        if self.name in ("TIM2", "TIM5"):
            r(0x50, "OR", 0)

    # --- clocks and counting ----------------------------------------------------
    def _hz(self):
        rcc = self.twin.rcc
        f = rcc.timclk2_hz() if self.apb == 2 else rcc.timclk1_hz()
        return f / (self.psc_active + 1)

    def encoder_mode(self):
        return 1 <= (self.r_smcr.value & 7) <= 3

    def counting(self):
        return bool(self.r_cr1.value & 1) and not 1 <= (self.r_smcr.value & 7) <= 3

    def _top(self):
        return 0xFFFF_FFFF if self.kind == GP32 else 0xFFFF

    def _ticks(self, now_s):
        return int((now_s - self.cnt_t0) * self._hz() + 1e-6)

    def _catch_up(self):
        """Apply the update events that passed since the counter was last looked at."""
        if not self.counting():
            return
        now = self.twin.now_s()
        while True:
            period = self.arr_active + 1
            k = self._ticks(now)
            if self.cnt_v0 + k < period:
                break
            # an update: at tick `period - cnt_v0`
            t_up = self.cnt_t0 + (period - self.cnt_v0) / self._hz()
            self._update_event(t_up, from_overflow=True)

    def _update_event(self, t_s, from_overflow):
        if not (from_overflow and self["CR1"] & 2):  # UDIS
            self.psc_active = self["PSC"]
            self.arr_active = self["ARR"]
            self._transfer_ccr(t_s)
            if not (self["CR1"] & 4 and not from_overflow):  # URS: UG sets no UIF
                self["SR"] |= 1
        self.cnt_t0, self.cnt_v0 = t_s, 0
        self._schedule()
        if self.name == "TIM4" and from_overflow:
            self.twin.control_update(self._hz() / (self.arr_active + 1))

    def _transfer_ccr(self, t_s):
        for i in range(4):
            ccmr = self.r_ccmr[i >> 1].value >> (8 * (i & 1))
            if ccmr & 0x08:  # OCxPE
                if self.ccr_active[i] != self.r_ccr[i].value:
                    self.ccr_active[i] = self.r_ccr[i].value
                    self.twin.outputs_changed(self, t_s)

    def on_read_CNT(self):
        v = self.cnt()
        if self.twin.index_pulse is not None and self.encoder_mode():
            self.twin.cnt_read(self.name, v)
        return v

    def cnt(self):
        """CNT now."""
        if self.encoder_mode():
            return (self.enc_offset + self.twin.encoder_counts(self.name)) % (self.arr_active + 1)
        if not self.counting():
            return self["CNT"]
        self._catch_up()
        return min(self.cnt_v0 + self._ticks(self.twin.now_s()), self.arr_active)

    def on_write_CNT(self, v, _lanes):
        v &= self._top()
        if self.encoder_mode():
            self.enc_offset = v - self.twin.encoder_counts(self.name)
        self["CNT"] = v
        self.cnt_t0, self.cnt_v0 = self.twin.now_s(), v
        self._schedule()

    def on_write_CR1(self, v, _lanes):
        was = self.counting()
        cnt = self.cnt() if was else self["CNT"]
        self.store("CR1", v)
        if self.counting() and not was:
            self.cnt_t0, self.cnt_v0 = self.twin.now_s(), cnt
        if was and not self.counting():
            self["CNT"] = cnt
        self._schedule()

    def on_write_ARR(self, v, _lanes):
        self.store("ARR", v)
        if not self["CR1"] & 0x80:  # ARPE off: at once
            self._catch_up()
            self.arr_active = self["ARR"]
            self._schedule()

    def on_write_SMCR(self, v, _lanes):
        self.store("SMCR", v)
        if self.encoder_mode():
            self.enc_offset = self["CNT"] - self.twin.encoder_counts(self.name)

    def on_write_EGR(self, v, _lanes):
        if v & 1:  # UG
            self._update_event(self.twin.now_s(), from_overflow=False)
            self["CNT"] = 0
        if v & 0x80 and self.kind == ADVANCED:  # BG: a software break
            self._break()

    def on_read_SR(self):
        self._catch_up()
        return self["SR"]

    def on_write_SR(self, v, _lanes):
        self._catch_up()
        # rc_w0: writing 0 clears, 1 leaves
        self["SR"] &= v
        self.twin.irq_level(self.irq, self._irq_line())

    def on_write_DIER(self, v, _lanes):
        self.store("DIER", v)
        self._schedule()
        self.twin.irq_level(self.irq, self._irq_line())

    def on_write_PSC(self, v, _lanes):
        self.store("PSC", v)

    def _irq_line(self):
        return bool(self["SR"] & self["DIER"] & 0x1F)

    def _schedule(self):
        """Only a timer whose update interrupt is enabled is an event source."""
        if self.counting() and self["DIER"] & 1:
            period = self.arr_active + 1
            self.next_update = self.cnt_t0 + (period - self.cnt_v0) / self._hz()
        else:
            self.next_update = None
        self.twin.reschedule()

    def events(self):
        return self.next_update

    def tick(self, now_s):
        if self.next_update is not None and now_s >= self.next_update:
            self._catch_up()
            self.twin.irq_level(self.irq, self._irq_line())

    def clocks_changed(self):
        if self.counting():
            self._catch_up()
            cnt = self.cnt()
            self.cnt_t0, self.cnt_v0 = self.twin.now_s(), cnt
            self._schedule()

    # --- compare outputs (TIM1) ---------------------------------------------------
    def on_write_CCR1(self, v, _l):
        self._ccr(0, v)

    def on_write_CCR2(self, v, _l):
        self._ccr(1, v)

    def on_write_CCR3(self, v, _l):
        self._ccr(2, v)

    def on_write_CCR4(self, v, _l):
        self._ccr(3, v)

    def _capturing(self, i):
        """Channel `i` is an input (CCxS != 00): its CCR is read-only (RM0090 18.4.14)."""
        return bool(self["CCMR1" if i < 2 else "CCMR2"] >> (8 * (i % 2)) & 3)

    def _ccr(self, i, v):
        if self._capturing(i):
            return
        self._catch_up()
        r = self.r_ccr[i]
        r.value = (r.value & ~r.wmask) | (v & r.wmask)
        ccmr = self.r_ccmr[i >> 1].value >> (8 * (i & 1))
        if not ccmr & 0x08 and self.ccr_active[i] != r.value:
            self.ccr_active[i] = r.value
            self.twin.outputs_changed(self, self.twin.now_s())

    def on_read_CCR1(self):
        return self._read_ccr(0)

    def on_read_CCR2(self):
        return self._read_ccr(1)

    def on_read_CCR3(self):
        return self._read_ccr(2)

    def on_read_CCR4(self):
        return self._read_ccr(3)

    def _read_ccr(self, i):
        v = self[f"CCR{i + 1}"]
        if self._capturing(i):
            flag = 1 << (i + 1)
            self.twin.ccr_reads.append((self.twin.now_s(), self.name, i, v, bool(self["SR"] & flag)))
            # CCxIF is cleared by software reading CCRx (RM0090 18.4.5)
            self["SR"] &= ~flag
            self.twin.irq_level(self.irq, self._irq_line())
        return v

    # --- input capture (TIM2–TIM5, RM0090 18.3.5) -------------------------------------
    def input_edge(self, i, rising):
        """An edge on the pin routed to channel `i`'s input TIi. With CCxS = 01 (ICx mapped
        on TIx) and CCxE = 1, an edge of the polarity CCxP/CCxNP select (00 rising, 01
        falling, 11 both), divided by ICxPSC, latches CNT into CCRx and sets CCxIF, and
        CCxOF if CCxIF was still set (the previous capture not read). The input filter
        ICxF delays the edge as much as A/B's (the same filter on the board), so the
        capture holds the count the edge comes with: not modelled further. ICx mapped on
        the other channel's input or on TRC (CCxS = 10/11) does not see this pin."""
        if self.kind == ADVANCED:
            return
        ccmr = self["CCMR1" if i < 2 else "CCMR2"] >> (8 * (i % 2)) & 0xFF
        ccer = self["CCER"] >> (4 * i) & 0xF
        if ccmr & 3 != 1 or not ccer & 1:
            return
        pol = (ccer >> 1 & 1, ccer >> 3 & 1)  # (CCxP, CCxNP)
        if pol == (0, 1):
            raise TwinError(f"{self.name}: CC{i + 1}P/CC{i + 1}NP = 0/1, a reserved configuration (RM0090 18.4.9)")
        if not (pol == (1, 1) or rising == (pol == (0, 0))):
            return
        self.ic_edges[i] += 1
        if self.ic_edges[i] % (1 << (ccmr >> 2 & 3)):
            return  # ICxPSC: one capture every 2, 4 or 8 edges
        self._catch_up()
        cnt = self.cnt()
        flag = 1 << (i + 1)
        over = bool(self["SR"] & flag)
        if over:
            self["SR"] |= 1 << (i + 9)  # CCxOF
        self[f"CCR{i + 1}"] = cnt
        self["SR"] |= flag
        self.twin.captures.append((self.twin.now_s(), self.name, i, cnt, over))
        self.twin.irq_level(self.irq, self._irq_line())

    def on_write_CCER(self, v, _l):
        old = self["CCER"]
        self.store("CCER", v)
        for i in range(4):
            if not self["CCER"] >> (4 * i) & 1:
                self.ic_edges[i] = 0  # the prescaler is reset while CCxE = 0
        if self["CCER"] != old:
            self.twin.outputs_changed(self, self.twin.now_s())

    def on_write_CCMR1(self, v, _l):
        self._ccmr("CCMR1", v)

    def on_write_CCMR2(self, v, _l):
        self._ccmr("CCMR2", v)

    def _ccmr(self, name, v):
        if self.kind == ADVANCED and self.lock_level() >= 3:
            keep = 0x7878  # OCxM, OCxPE
            v = (v & ~keep) | (self[name] & keep)
        self.store(name, v)
        self.twin.outputs_changed(self, self.twin.now_s())

    # --- BDTR: LOCK is write-once after reset (RM0090 17.4.18) -----------------------
    def lock_level(self):
        return self["BDTR"] >> 8 & 3 if self.kind == ADVANCED else 0

    def on_write_BDTR(self, v, _l):
        old = self["BDTR"]
        lvl = self.lock_level()
        # level 1: DTG, BKE, BKP, AOE (and OISx in CR2); level 2 adds OSSR/OSSI
        protected = {0: 0, 1: 0x70FF, 2: 0x7CFF, 3: 0x7CFF}[lvl]
        new = (v & ~protected) | (old & protected)
        if self.bdtr_written:
            new = (new & ~0x300) | (old & 0x300)  # LOCK only once
        self.bdtr_written = True
        self["BDTR"] = new & 0xFFFF
        if new & 0x8000 and self._break_active():
            self["BDTR"] &= ~0x8000  # MOE cannot be set while the break input is active
        if self["BDTR"] != old:
            self.twin.outputs_changed(self, self.twin.now_s())

    def _break_active(self):
        if not self["BDTR"] & 0x1000:  # BKE
            return False
        lv = self.twin.bkin_level()
        if lv is None:
            return False
        bkp = bool(self["BDTR"] & 0x2000)
        return lv == (1 if bkp else 0)

    def _break(self):
        self["BDTR"] &= ~0x8000
        self["SR"] |= 0x80  # BIF
        self.twin.irq_level(self.irq, self._irq_line())
        self.twin.outputs_changed(self, self.twin.now_s())

    def inputs_changed(self):
        """The break input is level-sensitive and acts without the CPU (asynchronous)."""
        if self.kind == ADVANCED and self._break_active() and self["BDTR"] & 0x8000:
            self._break()

    def channel_duty(self, i):
        """Fraction of the PWM period channel `i` drives high (0 when off or idle)."""
        self._catch_up()
        if not self["BDTR"] & 0x8000 or not self["CCER"] >> (4 * i) & 1:
            return 0.0
        ccmr = self["CCMR1" if i < 2 else "CCMR2"] >> (8 * (i % 2))
        mode = ccmr >> 4 & 7
        period = self.arr_active + 1
        ccr = min(self.ccr_active[i], period)
        pol = self["CCER"] >> (4 * i + 1) & 1
        if mode == 6:
            d = ccr / period
        elif mode == 7:
            d = 1 - ccr / period
        elif mode == 5:
            d = 1.0
        elif mode == 4:
            d = 0.0
        else:
            raise TwinError(f"{self.name}: CH{i + 1} in output mode {mode} (the board uses PWM mode 1)")
        return 1 - d if pol else d
