"""Register reads and writes in batches straight through unicorn's C API.

unicorn's Python `reg_read_batch`/`reg_write_batch` build their ctypes arrays, pick a
register class and convert every value on each call: with a batch at every exception
entry and return (some 30 000 a machine second while axes move and telemetry streams)
they were a third of the twin's time (py-spy). Here the arrays are built once per
register set and reused; every register read or written this way is a 32-bit one (core
registers, S0–S15, FPSCR, the special registers), which `uc_reg_read`/`uc_reg_write`
take as a `uint32_t`."""

import ctypes

from unicorn.unicorn_py3.unicorn import uclib

from .regs import TwinError


def engine_handle(uc):
    """The `uc_engine *` behind a Python `Uc` (also what counter.py reads the counter from)."""
    h = uc._uch
    return h.value if hasattr(h, "value") else int(h)


class Batch:
    """A fixed set of 32-bit registers of one engine, read or written in one call."""

    def __init__(self, uc, regs):
        n = len(regs)
        self.uch = ctypes.c_void_p(engine_handle(uc))
        self.n = ctypes.c_int(n)
        self.ids = (ctypes.c_int * n)(*regs)
        self.vals = (ctypes.c_uint32 * n)()
        base = ctypes.addressof(self.vals)
        self.ptrs = (ctypes.c_void_p * n)(*(base + 4 * i for i in range(n)))

    def read(self):
        if uclib.uc_reg_read_batch(self.uch, self.ids, self.ptrs, self.n) != 0:
            raise TwinError("unicorn: register batch read failed")
        return self.vals[:]

    def write(self, values):
        self.vals[:] = values
        if uclib.uc_reg_write_batch(self.uch, self.ids, self.ptrs, self.n) != 0:
            raise TwinError("unicorn: register batch write failed")
