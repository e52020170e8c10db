"""USART2 (RM0090 §30): the host link. Bytes leave at the baud rate BRR gives from PCLK1
(TXE/TC follow the shift register), arrive from the host into RDR with RXNE, and an
arrival with RXNE still set is an overrun (ORE; the byte is lost), as the hardware
does. The interrupt line is (RXNEIE and (RXNE or ORE)) or (TXEIE and TXE) or (TCIE and TC)."""

from collections import deque

from .regs import Peripheral, TwinError


class Usart(Peripheral):
    def __init__(self, twin, base, name, clock, irq):
        self.name = name
        self.clock = clock
        self.irq = irq
        self.tx_busy_until = None
        self.tx_pending = None  # byte in TDR waiting for the shift register
        self.rx = deque()  # bytes from the host, in order
        self.next_rx = None
        self.sent = bytearray()
        self.ore_read_sr = False
        super().__init__(twin, base)
        self.r_sr, self.r_cr1 = self.by_name["SR"], self.by_name["CR1"]

    def define(self):
        r = self.reg
        r(0x00, "SR", 0x00C0, 0)
        r(0x04, "DR", 0, 0x1FF)
        r(0x08, "BRR", 0, 0xFFFF)
        r(0x0C, "CR1", 0, 0xBFFF)
        r(0x10, "CR2", 0, 0x7F7F)
        r(0x14, "CR3", 0, 0x0FFF)
        r(0x18, "GTPR", 0, 0xFFFF)

    def byte_s(self):
        brr = self["BRR"]
        if brr == 0:
            raise TwinError(f"{self.name}: transmission with BRR = 0")
        over8 = self.r_cr1.value >> 15 & 1
        # USARTDIV = BRR with the fraction in 4 bits (OVER8 = 0): baud = fck / BRR
        baud = self.twin.rcc.pclk1_hz() / brr * (2 if over8 else 1) / 1
        return 10 / baud

    def enabled(self):
        return self.r_cr1.value & (1 << 13)

    # a scenario's overrun race: the next byte arrives after the handler's read of SR
    # (which saw RXNE, no ORE) and before its read of DR
    race_after_sr = False

    def on_read_SR(self):
        self._advance()
        self.ore_read_sr = bool(self.r_sr.value & 0x8)
        return self.r_sr.value

    def on_write_SR(self, v, _l):
        # rc_w0 bits: CTS, LBD, TC, RXNE
        keep = ~0x0360 | v
        self.r_sr.value &= keep
        self._irq()

    def on_read_DR(self):
        self._advance()
        if self.race_after_sr and self.r_sr.value & 0x20 and not self.ore_read_sr:
            self.race_after_sr = False
            self.r_sr.value |= 0x8  # the arrival with RXNE set: an overrun
            self.twin.usart_overruns += 1
        v = self["DR"]
        sr = self.r_sr.value & ~0x20  # RXNE cleared by the read
        if self.ore_read_sr:
            sr &= ~0x8  # ORE cleared by a read of SR then DR
            self.ore_read_sr = False
        self.r_sr.value = sr
        self._irq()
        return v

    def on_write_DR(self, v, _l):
        if not self.enabled() or not self.r_cr1.value & 0x8:
            raise TwinError(f"{self.name}: byte written with the transmitter off")
        self._advance()
        if self.tx_busy_until is None:
            self._start_tx(v & 0xFF)
        else:
            self.tx_pending = v & 0xFF
            self.r_sr.value &= ~0x80  # TXE
        self.r_sr.value &= ~0x40  # TC
        self._irq()

    def _start_tx(self, byte):
        now = self.twin.now_s()
        self.tx_busy_until = now + self.byte_s()
        self.sent.append(byte)
        self._out(byte)
        self.twin.reschedule()

    def _out(self, byte):
        # the twin's sink outlives this object (an RCC reset rebuilds the peripheral)
        sink = getattr(self.twin, self.name.lower() + "_sink", None)
        if sink is not None:
            sink(byte)

    def _advance(self):
        now = self.twin.now_s()
        while self.tx_busy_until is not None and now >= self.tx_busy_until:
            if self.tx_pending is not None:
                b, self.tx_pending = self.tx_pending, None
                t = self.tx_busy_until
                self.tx_busy_until = t + self.byte_s()
                self.sent.append(b)
                self._out(b)
                self.r_sr.value |= 0x80
            else:
                self.tx_busy_until = None
                self.r_sr.value |= 0xC0
        while self.rx and self.next_rx is not None and now >= self.next_rx:
            b = self.rx.popleft()
            if self.enabled() and self.r_cr1.value & 0x4:
                if self.r_sr.value & 0x20:
                    self.r_sr.value |= 0x8  # overrun: RDR keeps the old byte
                    self.twin.usart_overruns += 1
                else:
                    self["DR"] = b
                    self.r_sr.value |= 0x20
            self.next_rx = self.next_rx + self.byte_s() if self.rx else None

    def send(self, data):
        """The host sends `data` (bytes back to back from now)."""
        if not self.rx:
            self.next_rx = self.twin.now_s() + self.byte_s() if self["BRR"] else None
        self.rx.extend(data)
        self.twin.reschedule()

    def _irq(self):
        sr, cr1 = self.r_sr.value, self.r_cr1.value
        line = bool(
            (cr1 & 0x20 and sr & 0x28) or (cr1 & 0x80 and sr & 0x80) or (cr1 & 0x40 and sr & 0x40)
        )
        self.twin.irq_level(self.irq, line)

    def on_write_CR1(self, v, _l):
        self.store("CR1", v)
        self._irq()

    def events(self):
        a, b = self.tx_busy_until, self.next_rx
        if a is None:
            return b
        if b is None:
            return a
        return b if b < a else a

    def tick(self, now_s):
        self._advance()
        self._irq()
