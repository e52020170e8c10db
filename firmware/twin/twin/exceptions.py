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
    UC_ARM_REG_PC,
    UC_ARM_REG_R0,
    UC_ARM_REG_R1,
    UC_ARM_REG_R2,
    UC_ARM_REG_R3,
    UC_ARM_REG_R12,
    UC_ARM_REG_S0,
    UC_ARM_REG_SP,
    UC_ARM_REG_XPSR,
)

from .regs import TwinError

BASIC = (UC_ARM_REG_R0, UC_ARM_REG_R1, UC_ARM_REG_R2, UC_ARM_REG_R3, UC_ARM_REG_R12, UC_ARM_REG_LR)


def enter(twin, exc, return_pc):
    uc = twin.uc
    control = uc.reg_read(UC_ARM_REG_CONTROL)
    if control & 2 and (uc.reg_read(UC_ARM_REG_XPSR) & 0x1FF) == 0:
        raise TwinError("exception entry from a thread on the PSP: not modelled (the firmware uses the MSP)")
    fp = bool(control & 4)
    xpsr = uc.reg_read(UC_ARM_REG_XPSR)
    handler = (xpsr & 0x1FF) != 0
    sp = uc.reg_read(UC_ARM_REG_SP)
    size = 0x68 if fp else 0x20
    align = sp >> 2 & 1
    frame = (sp - size) & ~(align << 2)
    twin.check_stack(frame, exc)
    words = [uc.reg_read(r) for r in BASIC] + [return_pc & ~1, (xpsr & ~(1 << 9)) | (align << 9)]
    data = struct.pack("<8I", *words)
    if fp:
        s = [uc.reg_read(UC_ARM_REG_S0 + i) for i in range(16)]
        data += struct.pack("<16I", *s) + struct.pack("<2I", uc.reg_read(UC_ARM_REG_FPSCR), 0)
    uc.mem_write(frame, data)
    uc.reg_write(UC_ARM_REG_SP, frame)
    exc_return = 0xFFFF_FFE1 if fp else 0xFFFF_FFF1
    if not handler:
        exc_return |= 8
    uc.reg_write(UC_ARM_REG_LR, exc_return)
    uc.reg_write(UC_ARM_REG_CONTROL, control & ~4)
    uc.reg_write(UC_ARM_REG_XPSR, (xpsr & ~0x1FF & ~0x0600_FC00) | exc | (1 << 24))
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
    sp = uc.reg_read(UC_ARM_REG_MSP)
    size = 0x68 if fp else 0x20
    raw = bytes(uc.mem_read(sp, size))
    words = struct.unpack_from("<8I", raw)
    for r, v in zip(BASIC, words[:6]):
        uc.reg_write(r, v)
    if fp:
        s = struct.unpack_from("<18I", raw, 0x20)
        for i in range(16):
            uc.reg_write(UC_ARM_REG_S0 + i, s[i])
        uc.reg_write(UC_ARM_REG_FPSCR, s[16])
    xpsr = words[7]
    sp += size + ((xpsr >> 9 & 1) << 2)
    uc.reg_write(UC_ARM_REG_SP, sp)
    control = uc.reg_read(UC_ARM_REG_CONTROL)
    uc.reg_write(UC_ARM_REG_CONTROL, (control & ~4) | (4 if fp else 0))
    uc.reg_write(UC_ARM_REG_XPSR, xpsr & ~(1 << 9))
    to_thread = bool(exc_return & 8)
    if to_thread != ((xpsr & 0x1FF) == 0):
        raise TwinError(f"exception return 0x{exc_return:08x} to a frame of exception {xpsr & 0x1FF}")
    return words[6]
