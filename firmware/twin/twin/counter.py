"""The executed-instruction count of a unicorn run.

unicorn stops a run after `count` instructions (a C counter, fast) but reports neither
how many ran when a run stops early nor the count so far inside a callback. The twin
needs both (the DWT cycle counter the firmware reads, the time of a register access), so
it reads the engine's own counter, `uc_struct.emu_counter`: its offset is found once per
process by a probe run whose count is known, and checked on a second probe, so a unicorn
whose layout differs fails at start-up instead of counting wrong."""

import ctypes
import struct

from unicorn import UC_ARCH_ARM, UC_HOOK_CODE, UC_MODE_MCLASS, UC_MODE_THUMB, Uc

from .fastregs import engine_handle
from .regs import TwinError

_OFFSET = None
_PROBE_COUNT = 123_457


def _probe(adds):
    uc = Uc(UC_ARCH_ARM, UC_MODE_THUMB | UC_MODE_MCLASS)
    uc.mem_map(0x0800_0000, 0x1000)
    uc.mem_write(0x0800_0000, bytes.fromhex("0130") * adds + bytes.fromhex("00bffee7"))
    stop_at = 0x0800_0000 + 2 * adds

    def stop(u, _a, _s, _d):
        u.emu_stop()

    uc.hook_add(UC_HOOK_CODE, stop, begin=stop_at, end=stop_at)
    uc.emu_start(0x0800_0001, 0, count=_PROBE_COUNT)
    return uc


def offset():
    global _OFFSET
    if _OFFSET is None:
        uc = _probe(37)
        raw = ctypes.string_at(engine_handle(uc), 1 << 16)
        found = [
            off
            for off in range(0, len(raw) - 16, 8)
            if struct.unpack_from("<QQ", raw, off) == (38, _PROBE_COUNT)
        ]
        if len(found) != 1:
            raise TwinError(f"unicorn: emu_counter not found ({len(found)} candidates)")
        _OFFSET = found[0]
        uc2 = _probe(91)
        if struct.unpack_from("<Q", ctypes.string_at(engine_handle(uc2) + _OFFSET, 8))[0] != 92:
            raise TwinError("unicorn: emu_counter check failed")
    return _OFFSET


class Counter:
    """Instructions started in the current run of `uc` (the one executing included)."""

    def __init__(self, uc):
        self.addr = engine_handle(uc) + offset()
        # the counter's own memory, read in place (one object, not one a read)
        self.cell = ctypes.c_uint64.from_address(self.addr)
        self.limit = ctypes.c_uint64.from_address(self.addr + 8)

    def read(self):
        return self.cell.value

    def restart(self, count):
        """What uc_emu_start does to the count: the run goes on as a new one of `count`
        instructions (emu_count follows emu_counter in uc_struct, unicorn 2.1.4's
        include/uc_priv.h)."""
        self.cell.value = 0
        self.limit.value = count
