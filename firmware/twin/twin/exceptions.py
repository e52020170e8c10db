"""Exception entry and return on the ARMv7-M (ARMv7-M ARM B1.5.6–B1.5.8), done by the
twin because unicorn models the M-profile core but not its NVIC: the 8-word frame, the
26-word frame when CONTROL.FPCA is set (the FP registers are stacked eagerly: what lazy
stacking saves is the same), 8-byte stack alignment with xPSR bit 9, EXC_RETURN, and the
return that unicorn raises as EXCP_EXCEPTION_EXIT."""

import struct

from unicorn.arm_const import (
    UC_ARM_REG_CONTROL,
    UC_ARM_REG_FPSCR,
    UC_ARM_REG_LR,
    UC_ARM_REG_MSP,
    UC_ARM_REG_R0,
    UC_ARM_REG_R1,
    UC_ARM_REG_R2,
    UC_ARM_REG_R3,
    UC_ARM_REG_R12,
    UC_ARM_REG_S0,
    UC_ARM_REG_SP,
    UC_ARM_REG_XPSR,
)

from .fastregs import Batch
from .regs import TwinError

BASIC = (UC_ARM_REG_R0, UC_ARM_REG_R1, UC_ARM_REG_R2, UC_ARM_REG_R3, UC_ARM_REG_R12, UC_ARM_REG_LR)


# read in one batch at entry (unicorn's per-register calls dominate the twin's cost)
ENTRY_READ = (UC_ARM_REG_CONTROL, UC_ARM_REG_XPSR, UC_ARM_REG_SP, *BASIC,
              *(UC_ARM_REG_S0 + i for i in range(16)), UC_ARM_REG_FPSCR)
ENTRY_WRITE = (UC_ARM_REG_SP, UC_ARM_REG_LR, UC_ARM_REG_CONTROL, UC_ARM_REG_XPSR)
EXIT_READ = (UC_ARM_REG_MSP, UC_ARM_REG_CONTROL)
FP_REGS = (*(UC_ARM_REG_S0 + i for i in range(16)), UC_ARM_REG_FPSCR)
TAIL = (UC_ARM_REG_SP, UC_ARM_REG_CONTROL, UC_ARM_REG_XPSR)
EXIT_WRITE = (*BASIC, *TAIL)
EXIT_WRITE_FP = (*BASIC, *FP_REGS, *TAIL)


class Registers:
    """The register batches of entry and return for one engine (twin/fastregs.py)."""

    def __init__(self, uc):
        self.entry_read = Batch(uc, ENTRY_READ)
        self.entry_write = Batch(uc, ENTRY_WRITE)
        self.exit_read = Batch(uc, EXIT_READ)
        self.exit_write = Batch(uc, EXIT_WRITE)
        self.exit_write_fp = Batch(uc, EXIT_WRITE_FP)


def enter(twin, exc, return_pc):
    uc = twin.uc
    control, xpsr, sp, *rest = twin.xregs.entry_read.read()
    if control & 2 and (xpsr & 0x1FF) == 0:
        raise TwinError("exception entry from a thread on the PSP: not modelled (the firmware uses the MSP)")
    fp = bool(control & 4)
    handler = (xpsr & 0x1FF) != 0
    size = 0x68 if fp else 0x20
    align = sp >> 2 & 1
    frame = (sp - size) & ~(align << 2)
    words = rest[:6] + [return_pc & ~1, (xpsr & ~(1 << 9)) | (align << 9)]
    data = struct.pack("<8I", *words)
    if fp:
        data += struct.pack("<16I", *rest[6:22]) + struct.pack("<2I", rest[22], 0)
    if twin.in_sram(frame, len(data)):
        twin.mem.write(frame, data)
    else:
        # a stack that ran out of SRAM: the words outside it are lost (a bus error each),
        # the entry goes on with SP at the frame (Cortex-M4 TRM 5.12.1: a fault on
        # stacking does not stop the handler; its stacked values are corrupt)
        twin.stacking_fault(frame, exc)
        for i in range(0, len(data), 4):
            if twin.in_sram(frame + i, 4):
                uc.mem_write(frame + i, data[i : i + 4])
    exc_return = 0xFFFF_FFE1 if fp else 0xFFFF_FFF1
    if not handler:
        exc_return |= 8
    twin.xregs.entry_write.write((frame, exc_return, control & ~4, (xpsr & ~0x1FF & ~0x0600_FC00) | exc | (1 << 24)))
    vector = twin.read_u32(twin.scs["VTOR"] + 4 * exc)
    if not vector & 1:
        raise TwinError(f"vector {exc} = 0x{vector:08x} is not a thumb address")
    return vector


def exit_(twin, exc_return):
    """Unstack the frame; returns the address execution continues at."""
    uc = twin.uc
    if exc_return & 4:
        raise TwinError("exception return to the PSP: not modelled (the firmware uses the MSP)")
    fp = not exc_return & 0x10
    sp, control = twin.xregs.exit_read.read()
    size = 0x68 if fp else 0x20
    raw = twin.mem.read(sp, size)
    words = struct.unpack_from("<8I", raw)
    values = list(words[:6])
    if fp:
        values += struct.unpack_from("<17I", raw, 0x20)
    xpsr = words[7]
    sp += size + ((xpsr >> 9 & 1) << 2)
    to_thread = bool(exc_return & 8)
    if to_thread != ((xpsr & 0x1FF) == 0):
        raise TwinError(f"exception return 0x{exc_return:08x} to a frame of exception {xpsr & 0x1FF}")
    values += (sp, (control & ~4) | (4 if fp else 0), xpsr & ~(1 << 9))
    (twin.xregs.exit_write_fp if fp else twin.xregs.exit_write).write(values)
    return words[6]
