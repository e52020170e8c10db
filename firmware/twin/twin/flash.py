"""The flash interface (RM0090 §3): ACR (latency, ART accelerator), the key sequences,
sector erase and programming with their busy times, 1 -> 0 programming, the error
flags, and the option bytes (BOR level). The memory array itself is shared with the CPU
(`Twin.flash_mem`); stores into it are checked here after they happen.

While an erase or a program runs, every fetch from flash stalls the CPU (the program
runs from flash): the twin stalls the core for the busy time, with the peripherals,
timers and the watchdog running on."""

from .regs import Peripheral, PowerCut, TwinError

FLASH_BASE = 0x0800_0000
FLASH_SIZE = 0x10_0000
# sector layout of a 1 MiB STM32F407: 4 x 16 KiB, 64 KiB, 7 x 128 KiB
SECTORS = [(0x0000, 0x4000), (0x4000, 0x4000), (0x8000, 0x4000), (0xC000, 0x4000), (0x10000, 0x10000)] + [
    (0x20000 * i, 0x20000) for i in range(1, 8)
]
# DS8626 table 41 (x32 parallelism, 2.7–3.6 V): word program 16 µs typical; sector erase
# 16 KiB 400 ms, 64 KiB 1200 ms, 128 KiB 2000 ms typical (the twin uses the typical)
PROGRAM_S = 16e-6
ERASE_S = {0x4000: 0.4, 0x10000: 1.2, 0x20000: 2.0}
KEY1, KEY2 = 0x4567_0123, 0xCDEF_89AB
OPTKEY1, OPTKEY2 = 0x0819_2A3B, 0x4C5D_6E7F
# factory option bytes: BOR off (BOR_LEV = 11), RDP level 0 (0xAA), no write protection
OPTCR_FACTORY = 0x0FFF_AAED


class Flash(Peripheral):
    name = "FLASH"

    def __init__(self, twin, base, optcr):
        self.optcr_stored = optcr
        self.key_state = 0
        self.opt_key_state = 0
        self.locked_until_reset = False
        self.erases = []  # (time, sector, dcache on, icache on)
        self.writes = 0
        # a power cut a scenario has armed: ("erase",) cuts the next sector erase half way
        # through, ("program", n) the n-th program from now (`power_cut`)
        self.cut = None
        self.power_cuts = []  # (t_s, what)
        super().__init__(twin, base)

    def define(self):
        r = self.reg
        r(0x00, "ACR", 0, 0x1F07)
        r(0x04, "KEYR", 0, 0)
        r(0x08, "OPTKEYR", 0, 0)
        r(0x0C, "SR", 0, 0)
        r(0x10, "CR", 0x8000_0000, 0)
        r(0x14, "OPTCR", self.optcr_stored | 1, 0)

    def on_write_ACR(self, v, _l):
        acr = v & 0x1F07
        # ICRST (bit 11) / DCRST (bit 12) may only be set with their cache, ICEN (bit 9) /
        # DCEN (bit 10), off (RM0090 3.5.2, 3.9.1)
        if acr & (1 << 12) and acr & (1 << 10):
            raise TwinError("FLASH: ACR.DCRST set with the data cache on (RM0090 3.5.2)")
        if acr & (1 << 11) and acr & (1 << 9):
            raise TwinError("FLASH: ACR.ICRST set with the instruction cache on (RM0090 3.5.2)")
        self["ACR"] = acr
        if acr & (1 << 12):
            self.dcache_flushed = True

    dcache_flushed = True
    # erases after which the core went on to another flash operation, or stopped, with
    # the data cache (on during the erase) never reset: lines of the erased sector may
    # still be served from it (board review D4; the twin does not model the stale reads)
    unflushed_erases = 0

    def _cache_check(self):
        if not self.dcache_flushed and self.erases and self.erases[-1][2]:
            self.unflushed_erases += 1
        self.dcache_flushed = True

    def summary(self):
        return (f"flash: {len(self.erases)} sector erase(s), {self.unflushed_erases} not followed by a data "
                f"cache reset, {self.writes} program(s), SR 0x{self['SR']:02x}")

    def on_write_KEYR(self, v, _l):
        if self.locked_until_reset:
            return
        if self.key_state == 0 and v == KEY1:
            self.key_state = 1
        elif self.key_state == 1 and v == KEY2:
            self.key_state = 0
            self["CR"] &= ~(1 << 31)
        else:
            # a wrong sequence locks FLASH_CR until the next reset (and is a bus error)
            self.locked_until_reset = True
            raise TwinError(f"FLASH: wrong key 0x{v:08x} (FLASH_CR locked until reset)")

    def on_write_OPTKEYR(self, v, _l):
        if self.opt_key_state == 0 and v == OPTKEY1:
            self.opt_key_state = 1
        elif self.opt_key_state == 1 and v == OPTKEY2:
            self.opt_key_state = 0
            self["OPTCR"] &= ~1
        else:
            raise TwinError(f"FLASH: wrong option key 0x{v:08x}")

    def on_write_SR(self, v, _l):
        self["SR"] &= ~(v & 0xF3)  # EOP, OPERR, WRPERR, PGAERR, PGPERR, PGSERR: rc_w1

    def on_write_CR(self, v, _l):
        cr = self["CR"]
        if cr & (1 << 31):
            if v & (1 << 31):
                return
            raise TwinError("FLASH: FLASH_CR written while locked")
        if self["SR"] & (1 << 16):
            raise TwinError("FLASH: FLASH_CR written while BSY")
        self["CR"] = v & 0x8301_03FF | (cr & 0)
        if v & (1 << 16):  # STRT
            self["CR"] &= ~(1 << 16)
            self._erase(v)

    def _erase(self, cr):
        if self["SR"] & 0xF0:
            # an operation with an error flag set is not started (RM0090 3.6.4)
            self["SR"] |= 0x80 if not self["SR"] & 0x80 else 0
            return
        if cr & 4:  # MER
            raise TwinError("FLASH: mass erase (the firmware erases only its settings sectors)")
        if not cr & 2:
            self["SR"] |= 0x80  # PGSERR: STRT without an operation
            return
        snb = cr >> 3 & 0xF
        if snb >= len(SECTORS):
            raise TwinError(f"FLASH: erase of sector {snb} (a 1 MiB part has 0-11)")
        start, size = SECTORS[snb]
        self._cache_check()
        if self.cut == ("erase",):
            # half the busy time, then the power goes: an interrupted erase leaves the
            # sector undefined; here its first half erased, the rest as it was
            self.twin.flash_mem[start : start + size // 2] = b"\xff" * (size // 2)
            self.twin.stall(ERASE_S[size] / 2, f"erase of sector {snb}")
            self._power_cut(f"half way through the erase of sector {snb}")
            return
        self.twin.flash_mem[start : start + size] = b"\xff" * size
        dc = bool(self["ACR"] & (1 << 10))
        ic = bool(self["ACR"] & (1 << 9))
        self.erases.append((self.twin.now_s(), snb, dc, ic))
        self.dcache_flushed = False
        self.twin.stall(ERASE_S[size], f"erase of sector {snb}")
        self["SR"] |= 1 if self["CR"] & (1 << 24) else 0

    def program_store(self, addr, size, value, old):
        """A CPU store into the flash array happened: apply what the hardware would do."""
        off = addr - FLASH_BASE
        cr, sr = self["CR"], self["SR"]
        psize = 1 << (cr >> 8 & 3)
        ok = not cr & (1 << 31) and cr & 1 and not sr & 0xF0
        if not ok:
            self["SR"] |= 0x80  # PGSERR
            self.twin.flash_mem[off : off + size] = old
            return
        if size != psize:
            self["SR"] |= 0x40  # PGPERR
            self.twin.flash_mem[off : off + size] = old
            return
        if addr % size:
            self["SR"] |= 0x20  # PGAERR
            self.twin.flash_mem[off : off + size] = old
            return
        self._cache_check()
        new = value.to_bytes(size, "little")
        if self.cut is not None and self.cut[0] == "program":
            if self.cut[1] <= 1:
                # a torn program: the power goes while the word is programmed, its first
                # half programmed, the rest as it was
                half = max(1, size // 2)
                self.twin.flash_mem[off : off + size] = old
                self.twin.flash_mem[off : off + half] = bytes(a & b for a, b in zip(old[:half], new[:half]))
                self.twin.stall(PROGRAM_S / 2, None)
                self._power_cut(f"while programming the word at 0x{addr:08x}")
                return
            self.cut = ("program", self.cut[1] - 1)
        self.twin.flash_mem[off : off + size] = bytes(a & b for a, b in zip(old, new))
        self.writes += 1
        self.twin.stall(PROGRAM_S * max(1, size // 4 if size >= 4 else 1), None)
        self["SR"] |= 1 if cr & (1 << 24) else 0

    def power_cut(self, what):
        """Arm a power cut: `erase` (the next sector erase, half way through) or `program N`
        (the N-th program from now, half its bytes programmed)."""
        kind, *n = what.split()
        if kind == "erase" and not n:
            self.cut = ("erase",)
        elif kind == "program" and len(n) == 1 and n[0].isdigit() and int(n[0]) >= 1:
            self.cut = ("program", int(n[0]))
        else:
            raise ValueError("want `power-cut erase` or `power-cut program N` (N >= 1)")

    def _power_cut(self, what):
        self.cut = None
        self.power_cuts.append((self.twin.now_s(), what))
        self.twin.fail(PowerCut(f"power cut {what}"))

    def on_write_OPTCR(self, v, _l):
        cur = self["OPTCR"]
        if cur & 1:
            if v & 1:
                return
            raise TwinError("FLASH: FLASH_OPTCR written while locked")
        self["OPTCR"] = (v & 0x0FFF_FFFE) | (cur & 1)
        if v & 2:  # OPTSTRT: program the option bytes
            self["OPTCR"] &= ~2
            self.optcr_stored = v & 0x0FFF_FFEC | 0x1 & 0
            self.twin.option_bytes = self.optcr_stored
            self.twin.stall(0.016, "option bytes")

    def bor_level(self):
        """BOR_LEV of the loaded option bytes: 3 = off, 2 = 2.1 V, 1 = 2.4 V, 0 = 2.7 V."""
        return self.optcr_stored >> 2 & 3
