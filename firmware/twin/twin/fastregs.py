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


def _untyped(name):
    """`name` of the same libunicorn without the binding's argtypes: every argument the
    twin passes is already a ctypes object of the C type (a handle, an array, a c_int),
    and ctypes' per-call conversion through argtypes (`from_param` of each) doubled the
    cost of a register batch (0.77 against 0.37 µs)."""
    f = getattr(ctypes.CDLL(uclib._name), name)
    f.restype = ctypes.c_int
    return f


_reg_read_batch = _untyped("uc_reg_read_batch")
_reg_write_batch = _untyped("uc_reg_write_batch")


def engine_handle(uc):
    """The `uc_engine *` behind a Python `Uc` (also what counter.py reads the counter from)."""
    h = uc._uch
    return h.value if hasattr(h, "value") else int(h)


class Memory:
    """Reads and writes of emulated memory through the C API with buffers made once (the
    binding's mem_read builds a string buffer and a bytearray each call)."""

    def __init__(self, uc):
        self.uch = ctypes.c_void_p(engine_handle(uc))
        self.word = ctypes.c_uint32()
        self.word_p = ctypes.cast(ctypes.pointer(self.word), ctypes.POINTER(ctypes.c_char))
        self.bufs = {}

    def read_u32(self, addr):
        if uclib.uc_mem_read(self.uch, addr, self.word_p, 4) != 0:
            raise TwinError(f"unicorn: read of 0x{addr:08x} failed")
        return self.word.value

    def read(self, addr, size):
        buf = self.bufs.get(size)
        if buf is None:
            buf = self.bufs[size] = ctypes.create_string_buffer(size)
        if uclib.uc_mem_read(self.uch, addr, buf, size) != 0:
            raise TwinError(f"unicorn: read of {size} bytes at 0x{addr:08x} failed")
        return buf.raw

    def write(self, addr, data):
        if uclib.uc_mem_write(self.uch, addr, data, len(data)) != 0:
            raise TwinError(f"unicorn: write of {len(data)} bytes at 0x{addr:08x} failed")


class Exits:
    """uc_ctl(UC_CTL_UC_EXITS) with each set's array built once (the binding builds it,
    and the control code, on every call: some four times a control period)."""

    def __init__(self, uc):
        from unicorn import unicorn_const as uc_const

        self.uch = ctypes.c_void_p(engine_handle(uc))
        self.code = (uc_const.UC_CTL_IO_WRITE << 30) | (2 << 26) | uc_const.UC_CTL_UC_EXITS
        self.arrays = {}

    def set(self, exits):
        key = id(exits)
        a = self.arrays.get(key)
        if a is None or a[0] is not exits:
            arr = (ctypes.c_uint64 * max(1, len(exits)))(*exits)
            a = self.arrays[key] = (exits, ctypes.cast(arr, ctypes.c_void_p), ctypes.c_size_t(len(exits)), arr)
        if uclib.uc_ctl(self.uch, self.code, a[1], a[2]) != 0:
            raise TwinError("unicorn: setting the exits failed")


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
        if _reg_read_batch(self.uch, self.ids, self.ptrs, self.n) != 0:
            raise TwinError("unicorn: register batch read failed")
        return self.vals[:]

    def write(self, values):
        self.vals[:] = values
        if _reg_write_batch(self.uch, self.ids, self.ptrs, self.n) != 0:
            raise TwinError("unicorn: register batch write failed")
