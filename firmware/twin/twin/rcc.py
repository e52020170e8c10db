"""RCC and PWR (RM0090 §6, §5): the clock tree the firmware programs. Ready flags follow
their enables after the oscillator's start-up time; SYSCLK, HCLK, PCLK1/2 and the timer
clocks are derived from what was written, and every timer and UART runs from them."""

from .regs import Peripheral, TwinError

HSI_HZ = 16_000_000
# DS8626 tSU(HSE): 2 ms typical for an 8 MHz crystal; tLOCK of the PLL: 100 µs max (§5.3.10)
HSE_STARTUP_S = 0.002
PLL_LOCK_S = 100e-6
HSI_STARTUP_S = 2e-6

# reset flags of RCC_CSR (bits 24..31): RMVF 24, BORRSTF 25, PINRSTF 26, PORRSTF 27,
# SFTRSTF 28, IWDGRSTF 29, WWDGRSTF 30, LPWRRSTF 31
CSR_BORRSTF, CSR_PINRSTF, CSR_PORRSTF, CSR_SFTRSTF, CSR_IWDGRSTF = (
    1 << 25,
    1 << 26,
    1 << 27,
    1 << 28,
    1 << 29,
)


class Rcc(Peripheral):
    name = "RCC"

    def __init__(self, twin, base, hse_hz, reset_flags):
        self.hse_hz = hse_hz
        self.reset_flags = reset_flags
        self.on_since = {}  # oscillator -> cycle its enable was set
        super().__init__(twin, base)

    def define(self):
        r = self.reg
        r(0x00, "CR", 0x0000_0083)
        r(0x04, "PLLCFGR", 0x2400_3010)
        r(0x08, "CFGR", 0)
        r(0x0C, "CIR", 0)
        r(0x10, "AHB1RSTR", 0)
        r(0x14, "AHB2RSTR", 0)
        r(0x18, "AHB3RSTR", 0)
        r(0x20, "APB1RSTR", 0)
        r(0x24, "APB2RSTR", 0)
        r(0x30, "AHB1ENR", 0x0010_0000)
        r(0x34, "AHB2ENR", 0)
        r(0x38, "AHB3ENR", 0)
        r(0x40, "APB1ENR", 0)
        r(0x44, "APB2ENR", 0)
        r(0x50, "AHB1LPENR", 0x7E67_91FF)
        r(0x54, "AHB2LPENR", 0xF1)
        r(0x58, "AHB3LPENR", 1)
        r(0x60, "APB1LPENR", 0x36FE_C9FF)
        r(0x64, "APB2LPENR", 0x0007_5F33)
        r(0x70, "BDCR", 0)
        r(0x74, "CSR", 0x0E00_0000)
        r(0x80, "SSCGR", 0)
        r(0x84, "PLLI2SCFGR", 0x2000_3000)
        self["CSR"] = self.reset_flags

    # --- clocks ---------------------------------------------------------------
    def clocked(self, reg, bit):
        return bool(self[reg] >> bit & 1)

    def _ready(self, osc, startup_s):
        since = self.on_since.get(osc)
        if since is None:
            return False
        if osc == "HSE" and self.hse_hz is None:
            return False  # no crystal (or a dead one): never ready
        return self.twin.now_s() - since >= startup_s

    def on_read_CR(self):
        v = self["CR"] & ~((1 << 1) | (1 << 17) | (1 << 25) | (1 << 27))
        if v & 1 and self._ready("HSI", HSI_STARTUP_S):
            v |= 1 << 1
        if v & (1 << 16) and self._ready("HSE", HSE_STARTUP_S):
            v |= 1 << 17
        if v & (1 << 24) and self._ready("PLL", PLL_LOCK_S):
            v |= 1 << 25
        return v

    def on_write_CR(self, v, _lanes):
        old = self["CR"]
        for bit, osc in ((0, "HSI"), (16, "HSE"), (24, "PLL")):
            if v >> bit & 1 and not old >> bit & 1:
                self.on_since[osc] = self.twin.now_s()
            if not v >> bit & 1:
                self.on_since.pop(osc, None)
        if v & (1 << 24) and not old & (1 << 24):
            if self._pll_in_hz() is None:
                raise TwinError("RCC: PLL enabled with its source oscillator off")
        self.store("CR", v & 0x0F0F_FFF9 | (v & 0xF8))

    def on_write_PLLCFGR(self, v, _lanes):
        if self["CR"] & (1 << 24):
            raise TwinError("RCC: PLLCFGR written with the PLL on (RM0090 6.3.2)")
        self.store("PLLCFGR", v)

    def on_read_CFGR(self):
        v = self["CFGR"]
        return (v & ~0xC) | (self.sws << 2)

    def on_write_CFGR(self, v, _lanes):
        sw = v & 3
        if sw == 3:
            raise TwinError("RCC: CFGR.SW = 11 (not allowed)")
        src = ("HSI", "HSE", "PLL")[sw]
        ready = {
            "HSI": self._ready("HSI", 0) or self["CR"] & 1,
            "HSE": self._ready("HSE", HSE_STARTUP_S),
            "PLL": self._ready("PLL", PLL_LOCK_S),
        }[src]
        self.store("CFGR", v)
        if ready:
            self.sws = sw
            self._check_limits()
            self.twin.clocks_changed()

    sws = 0

    # peripheral resets (RM0090 6.3.5-6.3.8): a set bit holds the peripheral in its reset
    # state; the twin rebuilds it with its reset values when the bit is set
    RESETS = {
        "AHB1RSTR": {0: "GPIOA", 1: "GPIOB", 2: "GPIOC", 3: "GPIOD", 4: "GPIOE"},
        "APB1RSTR": {0: "TIM2", 1: "TIM3", 2: "TIM4", 3: "TIM5", 17: "USART2", 28: "PWR"},
        "APB2RSTR": {0: "TIM1", 14: "SYSCFG"},
    }

    def _reset_bits(self, name, v):
        old = self[name]
        self.store(name, v)
        for bit, periph in self.RESETS[name].items():
            if v >> bit & 1 and not old >> bit & 1:
                self.twin.reset_peripheral(periph)

    def on_write_AHB1RSTR(self, v, _l):
        self._reset_bits("AHB1RSTR", v)

    def on_write_APB1RSTR(self, v, _l):
        self._reset_bits("APB1RSTR", v)

    def on_write_APB2RSTR(self, v, _l):
        self._reset_bits("APB2RSTR", v)

    def on_write_CSR(self, v, _lanes):
        # RMVF clears every reset flag; LSION/LSIRDY in bits 0/1
        flags = self["CSR"] & 0xFE00_0000
        if v & (1 << 24):
            flags = 0
        lsi = v & 1
        self["CSR"] = flags | lsi | (lsi << 1)

    def on_write_CIR(self, v, _lanes):
        self["CIR"] = v & 0x0000_3F00  # interrupt enables; the C bits only clear flags

    # --- derived frequencies -------------------------------------------------
    def _pll_in_hz(self):
        src_hse = self["PLLCFGR"] >> 22 & 1
        if src_hse:
            return self.hse_hz if (self["CR"] >> 16 & 1) else None
        return HSI_HZ if self["CR"] & 1 else None

    def pll_hz(self):
        c = self["PLLCFGR"]
        m, n, p = c & 0x3F, c >> 6 & 0x1FF, 2 * ((c >> 16 & 3) + 1)
        fin = self._pll_in_hz() or 0
        if m < 2 or n < 50 or n > 432:
            raise TwinError(f"RCC: PLLCFGR M={m} N={n} out of range (RM0090 6.3.2)")
        vco_in = fin / m
        vco = vco_in * n
        if not (0.95e6 <= vco_in <= 2.1e6) or not (100e6 <= vco <= 432e6):
            raise TwinError(f"RCC: PLL VCO input {vco_in/1e6} MHz / output {vco/1e6} MHz out of range")
        return int(vco // p)

    def sysclk_hz(self):
        return (HSI_HZ, self.hse_hz or HSI_HZ, None)[self.sws] or self.pll_hz()

    _hclk = None
    # the bus and timer clocks as computed (they follow CFGR and HCLK: dropped with it)
    _derived = None

    def write32(self, off, value, lane_mask=0xFFFFFFFF):
        self._hclk = None
        self._derived = None
        super().write32(off, value, lane_mask)

    def _cached(self, key, fn):
        d = self._derived
        if d is None:
            d = self._derived = {}
        v = d.get(key)
        if v is None:
            v = d[key] = fn()
        return v

    def hclk_hz(self):
        if self._hclk is None:
            self._hclk = self._hclk_now()
        return self._hclk

    def _hclk_now(self):
        hpre = self["CFGR"] >> 4 & 0xF
        div = 1 if hpre < 8 else (2, 4, 8, 16, 64, 128, 256, 512)[hpre - 8]
        return self.sysclk_hz() // div

    def _apb_div(self, shift):
        ppre = self["CFGR"] >> shift & 7
        return 1 if ppre < 4 else (2, 4, 8, 16)[ppre - 4]

    def pclk1_hz(self):
        return self._cached("pclk1", lambda: self.hclk_hz() // self._apb_div(10))

    def pclk2_hz(self):
        return self._cached("pclk2", lambda: self.hclk_hz() // self._apb_div(13))

    def timclk1_hz(self):
        return self._cached("timclk1", lambda: self.pclk1_hz() * (1 if self._apb_div(10) == 1 else 2))

    def timclk2_hz(self):
        return self._cached("timclk2", lambda: self.pclk2_hz() * (1 if self._apb_div(13) == 1 else 2))

    def _check_limits(self):
        """DS8626: HCLK ≤ 168 MHz, PCLK1 ≤ 42 MHz, PCLK2 ≤ 84 MHz; the flash latency must
        cover HCLK at 2.7–3.6 V (30 MHz per wait state, RM0090 table 10)."""
        h = self.hclk_hz()
        if h > 168_000_000 or self.pclk1_hz() > 42_000_000 or self.pclk2_hz() > 84_000_000:
            raise TwinError(f"RCC: HCLK {h} / PCLK1 {self.pclk1_hz()} / PCLK2 {self.pclk2_hz()} Hz above DS8626's limits")
        ws = self.twin.flash["ACR"] & 7
        if h > 30_000_000 * (ws + 1):
            raise TwinError(f"FLASH: {ws} wait states at HCLK {h} Hz (RM0090 table 10 needs {-(-h // 30_000_000) - 1})")


class Pwr(Peripheral):
    name = "PWR"
    clock = ("APB1ENR", 28)

    def define(self):
        self.reg(0x00, "CR", 0x0000_C000)
        self.reg(0x04, "CSR", 0)

    def on_read_CSR(self):
        # VOSRDY (bit 14) once the regulator's scale is set and the PLL is on
        v = self["CSR"] & ~(1 << 14)
        if self.twin.rcc["CR"] & (1 << 24):
            v |= 1 << 14
        return v
