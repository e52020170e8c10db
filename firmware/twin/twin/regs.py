"""Register files: a peripheral is a set of named registers at offsets; an access to an
offset it does not name fails the run with the address (the twin never guesses)."""


class TwinError(Exception):
    """The run is invalid: an unmodelled access, a missing clock, a broken rule of RM0090."""


class PowerCut(Exception):
    """The board's power went off (a scenario's `power-cut`): the run ends, the flash keeps
    what it held at that instant."""


class Reg:
    """One 32-bit register: reset value, the bits software may write, the bits that read as
    the last written value. Behaviour beyond storage lives in the peripheral's hooks."""

    __slots__ = ("name", "reset", "wmask", "value")

    def __init__(self, name, reset=0, wmask=0xFFFFFFFF):
        self.name = name
        self.reset = reset
        self.wmask = wmask
        self.value = reset


class Peripheral:
    """A peripheral at `base`: `regs` maps offsets to `Reg`s. Subclasses override `read`
    / `write` hooks (`on_read_<name>`, `on_write_<name>`) for registers with behaviour."""

    name = "?"
    size = 0x400
    # RCC enable register and bit that clock this peripheral (None: always clocked)
    clock = None

    def __init__(self, twin, base):
        self.twin = twin
        self.base = base
        self.regs = {}
        self.by_name = {}
        self.define()
        # the hooks of each offset, looked up once (an access is a dict lookup, not a
        # getattr of a built name: the control interrupt makes some 40 a period)
        self.read_hooks = {}
        self.write_hooks = {}
        for off, r in self.regs.items():
            h = getattr(self, "on_read_" + r.name, None)
            if h is not None:
                self.read_hooks[off] = h
            h = getattr(self, "on_write_" + r.name, None)
            if h is not None:
                self.write_hooks[off] = h

    def define(self):
        raise NotImplementedError

    def reg(self, off, name, reset=0, wmask=0xFFFFFFFF):
        self.regs[off] = Reg(name, reset, wmask)
        self.by_name[name] = self.regs[off]

    def __getitem__(self, name):
        return self.by_name[name].value

    def __setitem__(self, name, value):
        self.by_name[name].value = value & 0xFFFFFFFF

    def lookup(self, off):
        r = self.regs.get(off & ~3)
        if r is None:
            raise TwinError(
                f"access to {self.name}+0x{off:03x} (0x{self.base + off:08x}): a register the twin does not model"
            )
        return r

    # (the RCC, its enable register, the bit) this peripheral's clock is read from
    _clk = None

    def clock_on(self, what):
        """An access with the peripheral's clock off does nothing (reads give 0), as on
        the chip; the twin records it (the scenario decides whether that is a defect)."""
        if self.clock is None:
            return True
        c = self._clk
        rcc = self.twin.rcc
        if c is None or c[0] is not rcc:
            c = self._clk = (rcc, rcc.by_name[self.clock[0]], self.clock[1])
        if not c[1].value >> c[2] & 1:
            self.twin.unclocked.append((self.twin.now_s(), what, self.name))
            return False
        return True

    def read32(self, off):
        off &= ~3
        r = self.regs.get(off)
        if r is None:
            self.lookup(off)
        if self.clock is not None and not self.clock_on("read"):
            return 0
        hook = self.read_hooks.get(off)
        if hook is not None:
            return hook() & 0xFFFFFFFF
        return r.value

    def write32(self, off, value, lane_mask=0xFFFFFFFF):
        off &= ~3
        r = self.regs.get(off)
        if r is None:
            self.lookup(off)
        if self.clock is not None and not self.clock_on("write"):
            return
        new = (r.value & ~lane_mask) | (value & lane_mask)
        hook = self.write_hooks.get(off)
        if hook is not None:
            hook(new & 0xFFFFFFFF, lane_mask)
        else:
            r.value = (r.value & ~r.wmask) | (new & r.wmask)

    def store(self, name, new):
        """Default write semantics for a hook that only adds side effects."""
        r = self.by_name[name]
        r.value = (r.value & ~r.wmask) | (new & r.wmask)

    def events(self):
        """Cycle at which this peripheral next needs `tick`, or None."""
        return None

    def tick(self, now):
        pass

    def clocks_changed(self):
        pass
