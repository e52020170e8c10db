"""SYSCFG (the EXTI line multiplexer, RM0090 §9) and EXTI (§12): edge detection on the
lines the board routes (Y's index on PB1), pending bits, and the interrupt lines."""

from .regs import Peripheral

# EXTI lines 0..4 have their own interrupts (EXTI0..EXTI4: IRQ 6..10)
EXTI_IRQ = {0: 6, 1: 7, 2: 8, 3: 9, 4: 10}


class Syscfg(Peripheral):
    name = "SYSCFG"
    clock = ("APB2ENR", 14)

    def define(self):
        r = self.reg
        r(0x00, "MEMRMP", 0, 7)
        r(0x04, "PMC", 0, 1 << 23)
        for i in range(4):
            r(0x08 + 4 * i, f"EXTICR{i + 1}", 0, 0xFFFF)
        r(0x20, "CMPCR", 0, 1)

    def port_of_line(self, line):
        return self[f"EXTICR{line // 4 + 1}"] >> (4 * (line % 4)) & 0xF


class Exti(Peripheral):
    name = "EXTI"

    def define(self):
        r = self.reg
        r(0x00, "IMR", 0, 0x7F_FFFF)
        r(0x04, "EMR", 0, 0x7F_FFFF)
        r(0x08, "RTSR", 0, 0x7F_FFFF)
        r(0x0C, "FTSR", 0, 0x7F_FFFF)
        r(0x10, "SWIER", 0, 0x7F_FFFF)
        r(0x14, "PR", 0, 0)
        self.edges = []  # (t_s, line, rising) of every edge that set a pending bit

    def edge(self, line, rising):
        """An edge on `line`: with its trigger selected (RTSR/FTSR) and the line unmasked
        (IMR: the pending request is gated by the mask, RM0090 Figure 41), the pending
        bit and the line's interrupt."""
        if (self["RTSR"] if rising else self["FTSR"]) >> line & 1 and self["IMR"] >> line & 1:
            self["PR"] |= 1 << line
            self.edges.append((self.twin.now_s(), line, rising))
            self._irq(line)

    def _irq(self, line):
        if line in EXTI_IRQ:
            self.twin.irq_level(EXTI_IRQ[line], bool(self["PR"] & self["IMR"] & (1 << line)))

    def on_write_PR(self, v, _l):
        self["PR"] &= ~v
        for line in EXTI_IRQ:
            self._irq(line)

    def on_write_IMR(self, v, _l):
        self.store("IMR", v)
        for line in EXTI_IRQ:
            self._irq(line)
