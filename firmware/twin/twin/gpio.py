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
        # the registers a pin's level is made of, held (not looked up by name per pin)
        r = self.by_name
        self.r_moder, self.r_odr, self.r_pupdr = r["MODER"], r["ODR"], r["PUPDR"]
        self.r_afr = (r["AFRL"], r["AFRH"])

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
        return self.r_moder.value >> (2 * pin) & 3

    def af(self, pin):
        return self.r_afr[pin >> 3].value >> (4 * (pin & 7)) & 0xF

    def pull(self, pin):
        return self.r_pupdr.value >> (2 * pin) & 3

    def level(self, pin):
        """The pin's level: driven by the port, by its alternate function, by the outside,
        or by its pull (None: floating)."""
        m = self.r_moder.value >> (2 * pin) & 3
        if m == 1:
            return self.r_odr.value >> pin & 1
        if m == 2:
            drv = self.twin.af_level(self.letter, pin, self.r_afr[pin >> 3].value >> (4 * (pin & 7)) & 0xF)
            if drv is not None:
                return drv
        ext = self.external[pin]
        if ext is not None:
            return ext
        p = self.r_pupdr.value >> (2 * pin) & 3
        return 1 if p == 1 else 0 if p == 2 else None

    def on_read_IDR(self):
        self.twin.inputs_read()
        # the levels change only when a pin, a port register or TIM1's outputs do
        # (Twin.port_generation counts those per port: TIM1's move port E's, where its
        # channels are): the control interrupt reads IDR many times
        gen = self.twin.port_generation[self.letter]
        if self._idr_cache is not None and self._idr_cache[0] == gen:
            return self._idr_cache[1]
        v = 0
        level = self.level
        for pin in range(16):
            if level(pin):
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
