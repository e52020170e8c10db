"""GPIO ports A–E (RM0090 §8): mode, type, pulls, alternate functions; the level of
every pin as the outside sees it, logged on every change of an output."""

from .regs import Peripheral


class Gpio(Peripheral):
    size = 0x400

    def __init__(self, twin, base, letter, index):
        self.letter = letter
        self.name = f"GPIO{letter}"
        self.clock = ("AHB1ENR", index)
        # levels the outside world drives on input pins (None: not connected)
        self.external = [None] * 16
        super().__init__(twin, base)

    def define(self):
        # reset values: port A/B keep the debug pins' alternate functions (RM0090 8.4)
        moder = {"A": 0xA800_0000, "B": 0x0000_0280}.get(self.letter, 0)
        speed = {"A": 0x0C00_0000, "B": 0x0000_00C0}.get(self.letter, 0)
        pupd = {"A": 0x6400_0000, "B": 0x0000_0100}.get(self.letter, 0)
        r = self.reg
        r(0x00, "MODER", moder)
        r(0x04, "OTYPER", 0, 0xFFFF)
        r(0x08, "OSPEEDR", speed)
        r(0x0C, "PUPDR", pupd)
        r(0x10, "IDR", 0, 0)
        r(0x14, "ODR", 0, 0xFFFF)
        r(0x18, "BSRR", 0)
        r(0x1C, "LCKR", 0)
        r(0x20, "AFRL", 0)
        r(0x24, "AFRH", 0)

    def mode(self, pin):
        return self["MODER"] >> (2 * pin) & 3

    def af(self, pin):
        reg = "AFRL" if pin < 8 else "AFRH"
        return self[reg] >> (4 * (pin % 8)) & 0xF

    def pull(self, pin):
        return self["PUPDR"] >> (2 * pin) & 3

    def level(self, pin):
        """The pin's level: driven by the port, by its alternate function, by the outside,
        or by its pull (None: floating)."""
        m = self.mode(pin)
        if m == 1:
            return self["ODR"] >> pin & 1
        if m == 2:
            drv = self.twin.af_level(self.letter, pin, self.af(pin))
            if drv is not None:
                return drv
        if self.external[pin] is not None:
            return self.external[pin]
        p = self.pull(pin)
        return {1: 1, 2: 0}.get(p)

    def on_read_IDR(self):
        self.twin.inputs_read()
        # the levels change only when a pin, a port register or TIM1's outputs do
        # (Twin.pin_generation counts those): the control interrupt reads IDR many times
        gen = self.twin.pin_generation
        if self._idr_cache is not None and self._idr_cache[0] == gen:
            return self._idr_cache[1]
        v = 0
        for pin in range(16):
            lv = self.level(pin)
            if lv:
                v |= 1 << pin
        self._idr_cache = (gen, v)
        return v

    _idr_cache = None

    def _changed(self):
        self.twin.pins_changed(self.letter)

    def _store_changed(self, name, v):
        if (self.name, name) in self.twin.frozen_regs:
            return
        old = self[name]
        self.store(name, v)
        if self[name] != old:
            self._changed()

    def on_write_ODR(self, v, _lanes):
        self._store_changed("ODR", v)

    def on_write_BSRR(self, v, _lanes):
        odr = (self["ODR"] & ~(v >> 16)) | (v & 0xFFFF)
        self._store_changed("ODR", odr & 0xFFFF)

    def on_write_MODER(self, v, _lanes):
        self._store_changed("MODER", v)

    def on_write_PUPDR(self, v, _lanes):
        self._store_changed("PUPDR", v)

    def on_write_AFRL(self, v, _lanes):
        self._store_changed("AFRL", v)

    def on_write_AFRH(self, v, _lanes):
        self._store_changed("AFRH", v)

    def on_read_BSRR(self):
        return 0
