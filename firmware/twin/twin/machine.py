"""The board twin: the release firmware ELF on an emulated STM32F407 (unicorn for the
Cortex-M4 core, the peripherals modelled here at register level), from reset.

Time: the core executes one instruction per cycle of HCLK (the cycle model of
docs/board-twin.md); a run goes in chunks that end at the next peripheral event (a
timer update, a SysTick wrap, a UART byte, the watchdog's expiry), when the core sleeps
(WFI) or when software changes what may interrupt it."""

import bisect
import math
import mmap
import ctypes

from capstone import CS_ARCH_ARM, CS_MODE_MCLASS, CS_MODE_THUMB, Cs
from elftools.elf.elffile import ELFFile
from unicorn import (
    UC_ARCH_ARM,
    UC_HOOK_INTR,
    UC_HOOK_MEM_WRITE,
    UC_MODE_MCLASS,
    UC_MODE_THUMB,
    UC_PROT_ALL,
    UC_PROT_READ,
    UC_PROT_WRITE,
    UC_PROT_EXEC,
    Uc,
    UcError,
)
from unicorn import arm_const
from unicorn.unicorn_py3.unicorn import HOOK_INTR_CFUNC as _HOOK_INTR, MMIO_READ_CFUNC as _MMIO_READ, MMIO_WRITE_CFUNC as _MMIO_WRITE, uclib
from unicorn.arm_const import (
    UC_ARM_REG_BASEPRI,
    UC_ARM_REG_MSP,
    UC_ARM_REG_PC,
    UC_ARM_REG_PRIMASK,
    UC_ARM_REG_SP,
    UC_ARM_REG_XPSR,
    UC_ARM_REG_FAULTMASK,
)

from . import board, exceptions
from .fastregs import Batch, Exits, Memory
from .counter import Counter
from .exti import Exti, Syscfg
from .flash import FLASH_BASE, FLASH_SIZE, OPTCR_FACTORY, Flash
from .gpio import Gpio
from .iwdg import LSI_TYPICAL_HZ, Iwdg
from .rcc import CSR_BORRSTF, CSR_PINRSTF, CSR_PORRSTF, CSR_IWDGRSTF, CSR_SFTRSTF, Pwr, Rcc
from .regs import Peripheral, TwinError
from .scs import Dwt, Scs
from .timers import ADVANCED, GP16, GP32, Timer
from .usart import Usart

SRAM_BASE, SRAM_SIZE = 0x2000_0000, 0x2_0000
CCM_BASE, CCM_SIZE = 0x1000_0000, 0x1_0000
PERIPH_PAGES = [(0x4000_0000, 0x8000), (0x4001_0000, 0x6000), (0x4002_0000, 0x6000)]
BITBAND_BASE, BITBAND_SIZE = 0x4200_0000, 0x0200_0000
# system memory, OTP, option bytes: read-only information the HAL may look at
SYSMEM_BASE, SYSMEM_SIZE = 0x1FFF_0000, 0x1_0000
MAX_CHUNK = 2_000_000
EXCP_UDEF, EXCP_SWI, EXCP_BKPT, EXCP_EXCEPTION_EXIT = 1, 2, 7, 8
HARDFAULT = 3



_SPECIAL = {"basepri": UC_ARM_REG_BASEPRI, "primask": UC_ARM_REG_PRIMASK, "faultmask": UC_ARM_REG_FAULTMASK}
_REG_ALIASES = {"sb": "r9", "sl": "r10", "fp": "r11", "ip": "r12"}


def _exit_instruction(ins):
    """What the twin executes itself (`Twin._at_exit`) at this instruction, or None: every
    instruction that may lower the execution priority (CPSIE; MSR to BASEPRI, PRIMASK or
    FAULTMASK: a pending exception is taken at once after it; BASEPRI_MAX only raises).
    ("msr", special register, source register, size) or ("cpsie", flags, size)."""
    if ins.mnemonic == "cpsie":
        return ("cpsie", ins.op_str.strip(), ins.size)
    if ins.mnemonic == "msr":
        special, _, reg = ins.op_str.replace(" ", "").partition(",")
        if special in _SPECIAL:
            reg = _REG_ALIASES.get(reg, reg)
            return ("msr", _SPECIAL[special], getattr(arm_const, f"UC_ARM_REG_{reg.upper()}"), ins.size)
    return None

# the machine's outputs `Twin._record` logs: (signal, port, pin, TIM1 channel or None)
_OUTPUTS = []
for _a in board.AXES:
    for _kind, _table in (("enable", board.ENABLE), ("brake", board.BRAKE), ("dir", board.DIRECTION)):
        _OUTPUTS.append((f"{_kind}.{_a}", *_table[_a], None))
    _OUTPUTS.append((f"pwm.{_a}", *board.PWM[_a]))
_OUTPUT_KEYS = [o[0] for o in _OUTPUTS] + ["moe"]
# the ports TIM1's channels drive pins of (a change of its outputs changes their IDR)
_TIM1_PORTS = sorted({port for (port, _pin, _af), sig in board.AF_OUTPUTS.items() if sig[0] == "TIM1"})

# the bits of an access of 1, 2, 4 bytes
_SIZE_MASK = (0, 0xFF, 0xFFFF, 0, 0xFFFF_FFFF)


def _clocked(twin, p):
    """`p`'s clock is on, by the enable bit `Peripheral.clock_on` found last time (False:
    ask `clock_on`, which finds it again and records an access with the clock off)."""
    c = p._clk
    return c is not None and c[0] is twin.rcc and c[1].value >> c[2] & 1


class Twin:
    def __init__(self, elf, hse_hz=8_000_000, lsi_hz=LSI_TYPICAL_HZ, flash_image=None, option_bytes=OPTCR_FACTORY):
        self.elf_path = elf
        self.hse_hz = hse_hz
        self.lsi_hz = lsi_hz
        self.option_bytes = option_bytes
        self.flash_mm = mmap.mmap(-1, FLASH_SIZE)
        self.flash_mem = memoryview(self.flash_mm)
        self.flash_mem[:] = b"\xff" * FLASH_SIZE
        self.sram_keep = None
        self.symbols = {}
        self._load_elf(elf, flash_image)
        self.resets = []  # (time, cause)
        self.t_s = 0.0
        self.cycles = 0
        self.log = []  # (t_s, signal, value): every change of a machine output
        self.faults = []  # (t_s, exception, pc)
        self.stack_faults = []  # (t_s, exception, frame): frames stacked outside SRAM
        # one-shot scenario hooks, called right after an exception's entry (its handler's
        # first instruction not yet run): exception number -> fn(twin)
        self.on_enter = {}
        # what a scenario does after this many more instructions: (n, fn(twin)), e.g. a
        # fault it injects
        self.call_after_insns = None
        self.panicked_at_s = None  # when a scenario made the core call the panic path
        # (t_s, register, value) of every write to the registers named in `trace_regs`
        # (the outputs-off stores of a fault handler, which change nothing at rest)
        self.trace_regs = set()
        # (peripheral, register) whose writes a scenario makes the chip ignore (a
        # configuration that does not take; kept through resets: GPIO ports only)
        self.frozen_regs = set()
        self.trace = []
        self.external = {}  # (port, pin) -> level driven by the outside
        for p, lv in board.HEALTHY_INPUTS:
            self.external[p] = lv
        self.encoder = {n: 0 for n in board.ENCODER_TIMER.values()}
        # the encoders' index pulses (`index_pulse`): every pulse as (t_s, axis, the
        # encoder's count at the index, the timer's CNT then), the timers' input captures
        # (t_s, timer, channel, CCR, overcapture), the firmware's reads of a capturing CCR
        # (t_s, timer, channel, value, CCxIF was set) and its reads of an encoder timer's
        # CNT while a pulse is up (t_s, timer, value, active exception)
        self.index_log = []
        self.captures = []
        self.ccr_reads = []
        self.cnt_reads_in_pulse = []
        self.index_pulse = None
        self.rtt_bytes = bytearray()
        self.unclocked = []  # (t_s, read/write, peripheral) with its clock off
        self.entries = {}  # exception number -> times entered
        self.port_generation = {letter: 0 for letter in "ABCDE"}
        self.first_entry = {}  # exception number -> time first entered
        # a power-on leaves PORRSTF, BORRSTF and PINRSTF (RCC_CSR's reset value, RM0090 6.3.21)
        self.power_on(reset_flags=CSR_PORRSTF | CSR_BORRSTF | CSR_PINRSTF)

    # --- image -----------------------------------------------------------------
    def _load_elf(self, path, flash_image):
        with open(path, "rb") as f:
            elf = ELFFile(f)
            self.load = []
            for seg in elf.iter_segments():
                if seg["p_type"] != "PT_LOAD" or seg["p_filesz"] == 0:
                    continue
                pa = seg["p_paddr"]
                if not FLASH_BASE <= pa < FLASH_BASE + FLASH_SIZE:
                    raise TwinError(f"ELF segment at 0x{pa:08x} is not in flash")
                self.flash_mem[pa - FLASH_BASE : pa - FLASH_BASE + seg["p_filesz"]] = seg.data()
            symtab = elf.get_section_by_name(".symtab")
            for s in symtab.iter_symbols():
                if s.name:
                    self.symbols[s.name] = s["st_value"]
            text = elf.get_section_by_name(".text")
            md = Cs(CS_ARCH_ARM, CS_MODE_THUMB | CS_MODE_MCLASS)
            md.skipdata = True
            self.exits = {}
            for ins in md.disasm(text.data(), text["sh_addr"]):
                exit_ = _exit_instruction(ins)
                if exit_ is not None:
                    self.exits[ins.address] = exit_
            self.wfi_addrs = {ins.address for ins in md.disasm(text.data(), text["sh_addr"]) if ins.mnemonic == "wfi"}
            self.all_exits = sorted(self.exits)
        self._check_layout()
        if flash_image is not None:
            for off, data in flash_image:
                self.flash_mem[off : off + len(data)] = data

    def _check_layout(self):
        """cortex-m-rt's reset handler copies __sidata to __sdata..__edata and zeroes
        __sbss..__ebss with loops that end only at equality: bounds outside SRAM or in the
        wrong order make it run off the end of RAM (the .ccmdata defect of memory.x)."""
        sym = self.symbols
        for lo, hi in (("__sdata", "__edata"), ("__sbss", "__ebss")):
            a, b = sym.get(lo), sym.get(hi)
            if a is None or b is None:
                raise TwinError(f"ELF: no {lo}/{hi} (not a cortex-m-rt image)")
            if not (SRAM_BASE <= a <= b <= SRAM_BASE + SRAM_SIZE):
                raise TwinError(f"ELF: {lo} 0x{a:08x} .. {hi} 0x{b:08x} is not a range in SRAM: the reset handler's loop would never end")

    # --- power and reset ------------------------------------------------------------
    def power_on(self, reset_flags):
        """A reset: the core and every peripheral to their reset state; flash keeps its
        contents, SRAM keeps its contents across a system reset (not across power)."""
        if getattr(self, "index_pulse", None) is not None:
            self.end_index_pulse()  # (the encoders count on through a reset)
        sram = None
        ccm = None
        if hasattr(self, "uc"):
            sram = bytes(self.uc.mem_read(SRAM_BASE, SRAM_SIZE))
            ccm = bytes(self.uc.mem_read(CCM_BASE, CCM_SIZE))
        self.uc = uc = Uc(UC_ARCH_ARM, UC_MODE_THUMB | UC_MODE_MCLASS)
        self.mmio_words = {}
        self.counter = Counter(uc)
        self.xregs = exceptions.Registers(uc)
        self.pc_sp = Batch(uc, (UC_ARM_REG_PC, UC_ARM_REG_SP))
        self.pc_write = Batch(uc, (UC_ARM_REG_PC,))
        self.mem = Memory(uc)
        self.one_reg = {}
        self.exits_ctl = Exits(uc)
        self.masks = Batch(uc, (UC_ARM_REG_BASEPRI, UC_ARM_REG_PRIMASK, UC_ARM_REG_FAULTMASK))
        self.in_chunk = False
        self.sleeping = False
        self.reset_pending = None
        self.stop_reason = None
        self.pending_stores = []
        self.irq_lines = set()
        # exceptions a scenario keeps from being taken (a hung control loop); a reset
        # clears them, as it clears the software state that hung
        self.blocked = set()
        ptr = ctypes.addressof(ctypes.c_char.from_buffer(self.flash_mm))
        uc.mem_map_ptr(0x0000_0000, FLASH_SIZE, UC_PROT_READ | UC_PROT_EXEC, ptr)
        uc.mem_map_ptr(FLASH_BASE, FLASH_SIZE, UC_PROT_ALL, ptr)
        uc.mem_map(SRAM_BASE, SRAM_SIZE)
        uc.mem_map(CCM_BASE, CCM_SIZE, UC_PROT_READ | UC_PROT_WRITE)
        if sram is not None:
            uc.mem_write(SRAM_BASE, sram)
            uc.mem_write(CCM_BASE, ccm)
        self._peripherals(reset_flags)
        # the peripheral pages' accesses come straight from unicorn's C callback (through
        # ctypes, not the Python binding's wrappers: an access is a Python call either way)
        self.mmio_callbacks = []
        for base, size in PERIPH_PAGES + [(0xE000_0000, 0x10_0000)]:
            rd, wr = self._mmio_callbacks(base)
            self.mmio_callbacks.append((rd, wr))
            if uclib.uc_mmio_map(uc._uch, base, size, rd, None, wr, None) != 0:
                raise TwinError(f"unicorn: mmio_map of 0x{base:08x} failed")
        uc.mmio_map(BITBAND_BASE, BITBAND_SIZE, self._bb_read, None, self._bb_write, None)
        uc.mem_map(SYSMEM_BASE, SYSMEM_SIZE, UC_PROT_READ)
        uc.mem_write(0x1FFF_7A22, (1024).to_bytes(2, "little"))  # flash size in KiB
        # straight through ctypes, as the peripheral pages (`_mmio_callbacks`)
        self.intr_callback = _HOOK_INTR(self._intr_cb)
        self.intr_hook = ctypes.c_size_t()
        if uclib.uc_hook_add(uc._uch, ctypes.byref(self.intr_hook), UC_HOOK_INTR, self.intr_callback, None, 1, 0) != 0:
            raise TwinError("unicorn: hook_add of the interrupt hook failed")
        uc.hook_add(UC_HOOK_MEM_WRITE, self._flash_store, begin=FLASH_BASE, end=FLASH_BASE + FLASH_SIZE - 1)
        # the core stops before each unmasking instruction (`_at_exit`): unicorn checks
        # exits when it translates, where a code hook at each (35 in the release ELF)
        # cost every instruction a walk over all hooks (10 instead of 50 million
        # instructions a second). But every run invalidates the translated code at each
        # exit (it is retranslated with the check), so they are exits only while an
        # exception waits that one could let in (`_exits_for_chunk`). (A WFI needs
        # neither: unicorn ends the run after it.)
        uc.ctl_exits_enabled(True)
        self.no_exits = self.exits_now = []
        uc.ctl_set_exits(self.exits_now)
        sp = self.read_u32(0)
        pc = self.read_u32(4)
        uc.reg_write(UC_ARM_REG_MSP, sp)
        uc.reg_write(UC_ARM_REG_SP, sp)
        uc.reg_write(UC_ARM_REG_XPSR, 1 << 24)
        self.pc = pc
        self.resets.append((self.t_s, reset_flags))
        self.entries_at_reset = dict(self.entries)
        self.pins_changed()

    def _peripherals(self, reset_flags):
        self.rcc = Rcc(self, 0x4002_3800, self.hse_hz, reset_flags)
        self.flash = Flash(self, 0x4002_3C00, self.option_bytes)
        self.pwr = Pwr(self, 0x4000_7000)
        self.scs = Scs(self, 0xE000_E000)
        self.dwt = Dwt(self, 0xE000_1000)
        self.gpio = {}
        for i, letter in enumerate("ABCDE"):
            self.gpio[letter] = Gpio(self, 0x4002_0000 + 0x400 * i, letter, i)
        for (port, pin), lv in self.external.items() if hasattr(self, "external") else []:
            self.gpio[port].external[pin] = lv
        self.tim = {
            "TIM1": Timer(self, 0x4001_0000, "TIM1", ADVANCED, ("APB2ENR", 0), 2, 27),
            "TIM2": Timer(self, 0x4000_0000, "TIM2", GP32, ("APB1ENR", 0), 1, 28),
            "TIM3": Timer(self, 0x4000_0400, "TIM3", GP16, ("APB1ENR", 1), 1, 29),
            "TIM4": Timer(self, 0x4000_0800, "TIM4", GP16, ("APB1ENR", 2), 1, 30),
            "TIM5": Timer(self, 0x4000_0C00, "TIM5", GP32, ("APB1ENR", 3), 1, 50),
        }
        self.usart2 = Usart(self, 0x4000_4400, "USART2", ("APB1ENR", 17), 38)
        self.iwdg = Iwdg(self, 0x4000_3000, self.lsi_hz)
        self.syscfg = Syscfg(self, 0x4001_3800)
        self.exti = Exti(self, 0x4001_3C00)
        self.periphs = [self.rcc, self.flash, self.pwr, self.scs, self.dwt, *self.gpio.values(), *self.tim.values(),
                        self.usart2, self.iwdg, self.syscfg, self.exti]
        self._periphs_changed()
        self.outputs_seen = {}

    def _periphs_changed(self):
        self.by_base = sorted(((p.base, p) for p in self.periphs), key=lambda bp: bp[0])
        self.bases = [b for b, _ in self.by_base]
        # word address -> (peripheral, offset): what an access resolves to (filled as the
        # firmware touches registers; emptied when a peripheral object is rebuilt)
        self.mmio_words.clear()
        # the peripherals with a time of their own (`events`, `tick`), in `periphs`' order:
        # the others' are the base class's no-ops
        self.tickers = [p for p in self.periphs if type(p).tick is not Peripheral.tick]
        self.event_sources = [p for p in self.periphs if type(p).events is not Peripheral.events]

    def reset_peripheral(self, name):
        """An RCC reset of one peripheral: every register back to its reset value."""
        old = next(p for p in self.periphs if p.name == name)
        if isinstance(old, Gpio):
            new = Gpio(self, old.base, old.letter, "ABCDE".index(old.letter))
            new.external = old.external
            self.gpio[old.letter] = new
        elif isinstance(old, Timer):
            new = Timer(self, old.base, old.name, old.kind, old.clock, old.apb, old.irq)
            self.tim[name] = new
        elif isinstance(old, Usart):
            new = Usart(self, old.base, old.name, old.clock, old.irq)
            self.usart2 = new
        elif isinstance(old, Syscfg):
            new = self.syscfg = Syscfg(self, old.base)
        elif isinstance(old, Pwr):
            new = self.pwr = Pwr(self, old.base)
        else:
            raise TwinError(f"RCC reset of {name}: not modelled")
        self.periphs[self.periphs.index(old)] = new
        self._periphs_changed()
        self.irq_level(getattr(old, "irq", -1), False) if hasattr(old, "irq") else None
        self.pins_changed()

    def request_reset(self, cause):
        self.reset_pending = cause
        self._stop()

    def _stop(self):
        """End the core's run at this instruction (a run that ends early otherwise halted
        at a WFI, `_chunk`)."""
        self.stopped = True
        self.uc.emu_stop()

    # --- time -------------------------------------------------------------------
    def now_s(self):
        if self.in_chunk:
            # (the counter's cell read in place: Counter.read without the call)
            c, n = self.counter.cell.value, self.chunk_n
            return self.chunk_t0 + (c if c < n else n) / self.chunk_hz
        return self.t_s

    def now_cycles(self):
        if self.in_chunk:
            c, n = self.counter.cell.value, self.chunk_n
            return self.chunk_c0 + (c if c < n else n)
        return self.cycles

    def stall(self, seconds, _what):
        """The core waits `seconds` (a flash operation): time passes, nothing executes."""
        self.stall_s += seconds

    stall_s = 0.0

    def reschedule(self):
        # a register write changed what may interrupt the core or when: the chunk ends
        # after that store (see _mmio_write)
        if self.in_chunk:
            self.want_stop = True

    want_stop = False
    replay = None

    def clocks_changed(self):
        for p in self.periphs:
            p.clocks_changed()
        self.reschedule()

    # --- memory-mapped peripherals -------------------------------------------------
    def _periph_at(self, addr):
        i = bisect.bisect_right(self.bases, addr) - 1
        if i >= 0:
            base, p = self.by_base[i]
            if addr < base + p.size:
                return p
        raise TwinError(f"access to 0x{addr:08x}: no peripheral the twin models")

    def _word(self, word):
        """What an access to the register at `word` (an aligned address) resolves to:
        (peripheral, offset, register, read hook, write hook, its clock, whether reads /
        writes go through the peripheral's own read32 / write32). The peripheral pages'
        callbacks (`_mmio_callbacks`) do what `Peripheral.read32` / `write32` do with
        these, without the calls; a peripheral that overrides them (the SCS's NVIC
        banks, the RCC), or an offset it does not model (the failure), goes through them."""
        p = self._periph_at(word)
        off = word - p.base
        r = p.regs.get(off)
        cls = type(p)
        w = self.mmio_words[word] = (
            p, off, r, p.read_hooks.get(off), p.write_hooks.get(off), p.clock,
            r is None or cls.read32 is not Peripheral.read32,
            r is None or cls.write32 is not Peripheral.write32,
        )
        return w

    def _hook_failed(self, e):
        # what unicorn's Python binding does with an exception in a callback: kept, the
        # run stopped, raised by emu_start
        if self.uc._hook_exception is None:
            self.uc._hook_exception = e
        self.uc.emu_stop()

    def _mmio_callbacks(self, region):
        """The read and write callbacks of the peripheral page at `region` (ctypes
        function pointers for uc_mmio_map). A store goes through `_store`'s rules."""
        words = self.mmio_words

        def read(_uch, off, size, _ud):
            try:
                if self.pending_stores:
                    self._apply_stores()
                addr = region + off
                w = words.get(addr & ~3)
                if w is None:
                    w = self._word(addr & ~3)
                p, o, r, hook, _wh, clock, generic, _gw = w
                if generic:
                    v = p.read32(o)
                elif clock is not None and not _clocked(self, p) and not p.clock_on("read"):
                    v = 0
                elif hook is not None:
                    v = hook() & 0xFFFFFFFF
                else:
                    v = r.value
                return (v >> (8 * (addr & 3))) & _SIZE_MASK[size]
            except TwinError as e:
                self.fail(e)
                return 0
            except BaseException as e:
                self._hook_failed(e)
                return 0

        def write(_uch, off, size, value, _ud):
            try:
                addr = region + off
                if self.replay is not None and self._replayed(addr, value):
                    return
                try:
                    if self.pending_stores:
                        self._apply_stores()
                    w = words.get(addr & ~3)
                    if w is None:
                        w = self._word(addr & ~3)
                    p, o, r, _rh, hook, clock, _gr, generic = w
                    lane = 8 * (addr & 3)
                    value_l = (value << lane) & 0xFFFFFFFF
                    lane_mask = _SIZE_MASK[size] << lane
                    if generic:
                        p.write32(o, value_l, lane_mask)
                    elif clock is None or _clocked(self, p) or p.clock_on("write"):
                        new = (r.value & ~lane_mask) | (value_l & lane_mask)
                        if hook is not None:
                            hook(new & 0xFFFFFFFF, lane_mask)
                        else:
                            r.value = (r.value & ~r.wmask) | (new & r.wmask)
                    if addr in self.trace_regs:
                        self.trace.append((self.now_s(), addr, value))
                except TwinError as e:
                    self.fail(e)
                if self.want_stop and self.in_chunk:
                    self._stop_after_store(addr, value)
            except BaseException as e:
                self._hook_failed(e)

        return _MMIO_READ(read), _MMIO_WRITE(write)

    def _replayed(self, addr, value):
        """The store unicorn restarts after a chunk that it ended (`_store`): True to skip it."""
        # the restarted store is the one at that pc on that stack: an exception taken
        # at the chunk's end runs its handler first, whose stores are not it
        here = tuple(self.pc_sp.read())
        if here == self.replay[0]:
            again = self.replay[1] == (addr, value)
            self.replay = None
            return again
        return False

    def _stop_after_store(self, addr, value):
        self.want_stop = False
        # (and the exception depth it was made at: handlers taken before it resumes
        # run chunks of their own)
        self.replay = (tuple(self.pc_sp.read()), (addr, value), len(self.scs.active))
        self._stop()

    def _store(self, uc, addr, value, apply):
        """A store into a peripheral: `apply()` does it, once. unicorn stops a run inside a
        store by restarting that store, so a chunk that a store ends (it changed what may
        interrupt the core) sees the same store again first: that one is skipped."""
        if self.replay is not None and self._replayed(addr, value):
            return
        try:
            self._apply_stores()
            apply()
        except TwinError as e:
            self.fail(e)
        if self.want_stop and self.in_chunk:
            self._stop_after_store(addr, value)

    def _bb_target(self, off):
        return 0x4000_0000 + (off >> 5), (off >> 2) & 7

    def _bb_read(self, uc, off, size, _u):
        addr, bit = self._bb_target(off)
        return self._read_word(addr & ~3) >> (bit + 8 * (addr & 3)) & 1

    def _read_word(self, addr):
        try:
            p = self._periph_at(addr)
            return p.read32(addr - p.base)
        except TwinError as e:
            self.fail(e)
            return 0

    def _bb_write(self, uc, off, size, value, _u):
        addr, bit = self._bb_target(off)
        bit += 8 * (addr & 3)

        def apply():
            p = self._periph_at(addr & ~3)
            p.write32((addr & ~3) - p.base, (value & 1) << bit, 1 << bit)

        self._store(uc, BITBAND_BASE + off, value, apply)

    def fail(self, e):
        if self.stop_reason is None:
            self.stop_reason = e
        self._stop()

    def read_u32(self, addr):
        return self.mem.read_u32(addr)

    # --- flash stores ---------------------------------------------------------------
    def _flash_store(self, uc, _access, addr, size, value, _u):
        off = addr - FLASH_BASE
        # applied at the next register access (the firmware polls FLASH_SR after every
        # store) or at the end of the chunk
        self.pending_stores.append((addr, size, value, bytes(self.flash_mem[off : off + size])))

    def _apply_stores(self):
        while self.pending_stores:
            addr, size, value, old = self.pending_stores.pop(0)
            self.flash.program_store(addr, size, value, old)

    # --- pins ---------------------------------------------------------------------------
    def drive(self, pin, level):
        """The outside drives `pin` = (port, n) to `level` (0/1). A change of the pin's
        level is an edge for what listens to it: the EXTI line its SYSCFG_EXTICR routes it
        to, the timer channel its alternate function takes it into."""
        g = self.gpio[pin[0]]
        before = g.level(pin[1])
        self.external[pin] = level
        g.external[pin[1]] = level
        self.pins_changed()
        after = g.level(pin[1])
        if before is not None and after is not None and before != after:
            self.pin_edge(pin[0], pin[1], bool(after))

    def pin_edge(self, port, pin, rising):
        g = self.gpio[port]
        mode = g.mode(pin)
        if mode == 3:
            return  # analog: the Schmitt trigger is off (RM0090 8.3.12)
        if self.syscfg.port_of_line(pin) == "ABCDE".index(port):
            self.exti.edge(pin, rising)
        if mode == 2:
            sig = board.AF_INPUTS.get((port, pin, g.af(pin)))
            if sig is not None:
                self.tim[sig[0]].input_edge(sig[1], rising)

    # --- the encoders' index pulses ---------------------------------------------------------
    def index_pulses(self, at_index, end):
        """A plant step that passed index pulses (`at_index`: axis -> the encoder's count at
        its index; `end`: axis -> the count at the step's end) lands in two parts. The
        encoder timers count at each step (the plant's step lands at once), so the pulse
        is put where the count passes through the index: first the counts at the index
        with the index pins high (the rising edge: TIM2/TIM3 capture CNT, EXTI1 pends),
        then the step's end counts with the pins low. The pulse lasts while the core runs
        the exceptions its edge made it take at once (`end_index_pulse`: EXTI1's task
        reads TIM5_CNT at the index, as the board's does within 0.2 µs of the edge); it
        ends at once when none is taken."""
        self.end_index_pulse()
        for a, n in at_index.items():
            timer = board.ENCODER_TIMER[a]
            self.encoder[timer] = n
            self.index_log.append((self.now_s(), a, n, self.tim[timer].cnt()))
        self.index_pulse = (dict(end), len(self.scs.active))
        for a in at_index:
            self.drive(board.INDEX[a], 1)

    def end_index_pulse(self):
        if self.index_pulse is None:
            return
        end, _ = self.index_pulse
        self.index_pulse = None
        for a, n in end.items():
            self.encoder[board.ENCODER_TIMER[a]] = n
        for a in end:
            self.drive(board.INDEX[a], 0)

    def _land_step(self):
        """The plant's step under way lands between two runs of the core, where an
        exception its index pulse raises can be taken before the next instruction."""
        self.plant.settle(between_runs=True)
        if self.index_pulse is None:
            return
        while self._take_pending():
            pass
        if self.index_pulse is not None and len(self.scs.active) <= self.index_pulse[1]:
            self.end_index_pulse()

    def af_level(self, port, pin, af):
        sig = board.AF_OUTPUTS.get((port, pin, af))
        if sig is None:
            return None
        if sig[0] == "TIM1":
            return 1 if self.tim["TIM1"].channel_duty(sig[1]) > 0 else 0
        if sig[0] == "USART2_TX":
            return 1
        return None

    def bkin_level(self):
        port, pin = board.ESTOP
        g = self.gpio[port]
        if g.mode(pin) != 2 or g.af(pin) != 1:
            return None
        return g.level(pin)

    pin_generation = 0
    # per port, what IDR's cache keys on (`Gpio.on_read_IDR`): a change of that port's
    # pins or registers, of a pin driven from outside, or of TIM1's outputs for the ports
    # its channels are on
    port_generation = None
    usart_overruns = 0  # bytes from the host lost to ORE (RXNE still set)

    def pins_changed(self, port=None):
        self.pin_generation += 1
        pg = self.port_generation
        if port is None:
            for k in pg:
                pg[k] += 1
        else:
            pg[port] += 1
        if not hasattr(self, "tim"):
            return
        if port in (None, "B"):
            self.tim["TIM1"].inputs_changed()
        if port in (None, "D", "E"):
            self._record()

    def outputs_changed(self, _timer, t_s):
        self.pin_generation += 1
        pg = self.port_generation
        for k in _TIM1_PORTS:
            pg[k] += 1
        self._record(t_s)

    def _record(self, t_s=None):
        t = self.now_s() if t_s is None else t_s
        gpio = self.gpio
        tim1 = self.tim["TIM1"]
        seen = self.outputs_seen
        log = self.log
        # every signal first, then the changes, in the order the log has always had them
        # (per axis enable, brake, dir, pwm; then moe)
        now = []
        for key, port, pin, ch in _OUTPUTS:
            g = gpio[port]
            if ch is not None and g.mode(pin) == 2 and g.af(pin) == 1:
                now.append(round(tim1.channel_duty(ch), 6))
            else:
                now.append(g.level(pin))
        now.append(tim1["BDTR"] >> 15 & 1)
        for key, v in zip(_OUTPUT_KEYS, now):
            if seen.get(key, "unset") != v:
                seen[key] = v
                log.append((t, key, v))

    plant = None  # the closed loop (plant.Plant), attached by a scenario or --serve

    def control_update(self, rate_hz):
        if self.plant is not None:
            self.plant.control_update(round(rate_hz))

    def symbol_at(self, addr):
        """The ELF symbol `addr` is in (nearest below), as name+offset."""
        if not hasattr(self, "_sym_sorted"):
            self._sym_sorted = sorted((a & ~1, n) for n, a in self.symbols.items() if 0x0800_0000 <= a < 0x0810_0000)
            self._sym_addrs = [a for a, _ in self._sym_sorted]
        i = bisect.bisect_right(self._sym_addrs, addr) - 1
        if i < 0:
            return f"0x{addr:08x}"
        a, n = self._sym_sorted[i]
        return f"{n}+0x{addr - a:x}"

    def describe(self):
        """Where the core is: for a look at a run that stopped making progress."""
        uc = self.uc
        sp = uc.reg_read(UC_ARM_REG_SP)
        n = max(0, min(256, (SRAM_BASE + SRAM_SIZE - sp) // 4))
        words = [int.from_bytes(uc.mem_read(sp + 4 * i, 4), "little") for i in range(n)]
        code = [self.symbol_at(w & ~1) for w in words if 0x0800_0000 <= w < 0x0810_0000 and w & 1]
        return (f"t {self.t_s:.4f} s pc {self.symbol_at(self.pc)} sleeping {self.sleeping} active {self.scs.active} "
                f"pending {sorted(self.scs.pending)} lines {sorted(self.irq_lines)} basepri 0x{uc.reg_read(UC_ARM_REG_BASEPRI):02x} "
                f"primask {uc.reg_read(UC_ARM_REG_PRIMASK)} entries {dict(sorted(self.entries.items()))} stack code addresses {code[:12]}")

    def encoder_counts(self, timer):
        if self.plant is not None:
            self.plant.settle()
        return self.encoder[timer]

    def cnt_read(self, timer, value):
        """The core read an encoder timer's CNT (recorded while an index pulse is up)."""
        if self.index_pulse is not None:
            self.cnt_reads_in_pulse.append((self.now_s(), timer, value, self.scs.active[-1] if self.scs.active else None))

    def inputs_read(self):
        """The core reads an input port: the plant's step under way lands first."""
        if self.plant is not None:
            self.plant.settle()

    # --- interrupts -----------------------------------------------------------------------
    def irq_level(self, irq, level):
        if level:
            if irq not in self.irq_lines:
                self.irq_lines.add(irq)
                self.scs.pending.add(16 + irq)
                self.reschedule()
        else:
            self.irq_lines.discard(irq)

    def _exec_priority(self):
        prio = 256
        for e in self.scs.active:
            prio = min(prio, self.scs.group(self.scs.priority(e)))
        basepri, primask, faultmask = self.masks.read()
        basepri &= 0xF0
        if basepri:
            prio = min(prio, self.scs.group(basepri))
        if primask & 1:
            prio = min(prio, 0)
        if faultmask & 1:
            prio = min(prio, -1)
        return prio

    def _preempting(self):
        """The pending exception the core takes now, if any (PM0214 2.3.6)."""
        scs = self.scs
        active = scs.active
        pending = scs.pending
        for irq in self.irq_lines:
            if 16 + irq not in active:
                pending.add(16 + irq)
        blocked = self.blocked
        enabled = scs.exception_enabled
        priority = scs.priority
        group = scs.group
        best = best_key = None
        for e in pending:
            if e in active or e in blocked or not enabled(e):
                continue
            prio = priority(e)
            key = (group(prio), prio, e)
            if best_key is None or key < best_key:
                best, best_key = e, key
        if best is None:
            return None
        # the active exceptions' priority first: only an exception above it needs the
        # masks read (BASEPRI, PRIMASK, FAULTMASK can only raise the execution priority)
        g = best_key[0]
        for e in active:
            if g >= group(priority(e)):
                return None
        if g >= self._exec_priority():
            return None
        return best

    def _wakes(self):
        """WFI ends on any enabled pending interrupt, masked or not (PM0214 2.5.2)."""
        return any(self.scs.exception_enabled(e) and e not in self.blocked for e in self.scs.pending)

    def _take_pending(self):
        if not self.scs.pending and not self.irq_lines:
            return False
        best = self._preempting()
        if best is None:
            return False
        self.scs.pending.discard(best)
        self._enter(best, self.pc)
        return True

    def _enter(self, exc, return_pc):
        self.escalate_after_entry = False
        self.pc = exceptions.enter(self, exc, return_pc)
        self.scs.active.append(exc)
        self.sleeping = False
        self.entries[exc] = self.entries.get(exc, 0) + 1
        self.first_entry.setdefault(exc, self.t_s)
        if self.escalate_after_entry:
            # the stacking BusFault, escalated, arrives late: HardFault is taken before
            # the handler's first instruction
            self.hard_fault(self.pc, "bus fault on exception entry (stacking)")
            return
        hook = self.on_enter.pop(exc, None)
        if hook is not None:
            hook(self)

    @staticmethod
    def in_sram(addr, size):
        return SRAM_BASE <= addr and addr + size <= SRAM_BASE + SRAM_SIZE

    def stacking_fault(self, frame, exc):
        """Exception entry stacked (part of) its frame outside SRAM: BFSR.STKERR, and a
        BusFault that escalates to HardFault (BusFault is not enabled) unless HardFault is
        the exception being entered (a fault of the same kind does not escalate again)."""
        self.stack_faults.append((self.t_s, exc, frame))
        self.scs["CFSR"] |= 1 << 12
        if exc != HARDFAULT:
            self.escalate_after_entry = True

    def _intr_cb(self, _uch, intno, _ud):
        try:
            self._intr(self.uc, intno, None)
        except BaseException as e:
            self._hook_failed(e)

    def _intr(self, uc, intno, _u):
        pc = self.pc_sp.read()[0]
        if intno == EXCP_EXCEPTION_EXIT:
            exc_return = 0xFFFF_FF00 | (pc & 0xFF) | 1
            try:
                self.scs.active.pop()
                if self.index_pulse is not None and len(self.scs.active) <= self.index_pulse[1]:
                    # the exception the index pulse's edge raised returns: the pulse ends
                    self.end_index_pulse()
                self.pc = exceptions.exit_(self, exc_return)
            except (TwinError, IndexError) as e:
                self.fail(TwinError(f"exception return at 0x{pc:08x}: {e}"))
                return
            if self._return_in_chunk():
                return
            self.resume_pc = self.pc
            self._stop()
            return
        if intno in (EXCP_UDEF, EXCP_BKPT):
            # no debugger attached: UsageFault / DebugMonitor escalate to HardFault
            self.fault_pc = pc
            self.resume_pc = ("fault", pc, "udf" if intno == EXCP_UDEF else "bkpt")
            self._stop()
            return
        self.fail(TwinError(f"CPU exception {intno} at 0x{pc:08x}"))

    def _at_exit(self):
        """The core stands at an instruction that may lower the execution priority
        (`_exit_instruction`): the twin executes it, so that a pending exception it
        unmasks is taken before the next instruction."""
        what = self.exits[self.pc]
        if what[0] == "cpsie":
            for flag in what[1]:
                self._reg(UC_ARM_REG_PRIMASK if flag == "i" else UC_ARM_REG_FAULTMASK).write((0,))
        else:
            _, special, reg, _size = what
            v = self._reg(reg).read()[0]
            # BASEPRI keeps its 8 bits (the unimplemented low ones read as written, as
            # unicorn's own MSR does); PRIMASK and FAULTMASK are one bit
            self._reg(special).write((v & (0xFF if special == UC_ARM_REG_BASEPRI else 1),))
        self.pc += what[-1]
        hz = self.rcc.hclk_hz()
        self.cycles += 1
        self.t_s += 1 / hz

    def _reg(self, reg):
        """A one-register batch (every register `_at_exit` touches is a 32-bit one)."""
        b = self.one_reg.get(reg)
        if b is None:
            b = self.one_reg[reg] = Batch(self.uc, (reg,))
        return b

    # --- the run loop ---------------------------------------------------------------------
    def _next_event(self):
        ev = None
        for p in self.event_sources:
            t = p.events()
            if t is not None and (ev is None or t < ev):
                ev = t
        return ev

    def run(self, until_s, poll=None, poll_every_s=1e-3):
        self._next_poll = self.t_s
        self._run_ctx = (until_s, poll, poll_every_s)
        try:
            while self.t_s < until_s:
                plan = self._iteration(until_s, poll, poll_every_s)
                if plan is None:
                    continue
                if plan is False:
                    break
                self._run_planned(*plan)
                while self.deferred is not None:
                    # the chunk an exception return planned (`_return_in_chunk`) that
                    # its run could not go on with
                    plan, self.deferred = self.deferred, None
                    self._run_planned(*plan)
        finally:
            self._run_ctx = None

    _run_ctx = None
    deferred = None
    # the chunk under way was ended (and the next one planned) inside a callback
    chunk_done = False

    def _iteration(self, until_s, poll, poll_every_s):
        """One turn of the run loop up to the chunk it plans: (instructions, HCLK), None
        to turn again, False to end the run."""
        if self.stop_reason is not None:
            raise self.stop_reason
        if self.reset_pending is not None:
            cause = self.reset_pending
            flags = {"IWDG": CSR_IWDGRSTF, "SYSRESETREQ": CSR_SFTRSTF}[cause] | CSR_PINRSTF
            self.power_on(flags)
            return None
        for p in self.tickers:
            p.tick(self.t_s)
        if not self.sleeping and self.pc in self.exits:
            self._at_exit()
        if self.scs.pending or self.irq_lines:
            while self._take_pending():
                pass
        if self.plant is not None and self.plant.pending:
            self._land_step()
        ev = None
        for p in self.event_sources:
            t = p.events()
            if t is not None and (ev is None or t < ev):
                ev = t
        if self.sleeping:
            if self._wakes():
                self.sleeping = False
            else:
                if ev is None or ev > until_s:
                    self.t_s = until_s
                    return False
                self.t_s = max(self.t_s, ev)
                return None
        if poll is not None and self.t_s >= self._next_poll:
            poll(self)
            self._next_poll = self.t_s + poll_every_s
        hz = self.rcc.hclk_hz()
        # (the earliest of the next event, the end of the run and the next poll)
        horizon = ev if ev is not None else until_s
        if until_s < horizon:
            horizon = until_s
        if poll and self._next_poll < horizon:
            horizon = self._next_poll
        n = math.ceil((horizon - self.t_s) * hz)
        return (1 if n < 1 else MAX_CHUNK if n > MAX_CHUNK else n), hz

    def _run_planned(self, n, hz):
        if self.call_after_insns is not None:
            left, fn = self.call_after_insns
            c0 = self.cycles
            self._chunk(max(1, min(n, left)), hz)
            left -= min(self.cycles - c0, left)
            self.call_after_insns = (left, fn) if left else None
            if not left:
                fn(self)
            return
        self._chunk(n, hz)

    def _exits_for_chunk(self):
        """The exits a chunk runs with: all of them while an exception waits that an
        unmasking instruction could let in, none otherwise. An instruction that lowers
        BASEPRI, PRIMASK or FAULTMASK cannot lower the execution priority below the
        active exceptions' (only their return can, `_intr`): an exception that waits
        with a group priority no higher than theirs, or disabled, or held by a scenario,
        cannot be let in by one, and with only such exceptions waiting the chunk runs
        without exits. (Every run with exits ends by invalidating the translated code at
        each one, which is retranslated: with exits whenever anything waited, the TIM4
        handler ran with them, its own line high and then its software task pending
        below it; a third of the twin's time.) What pends an exception or changes a
        priority from here on ends the chunk (a store to the NVIC or SCB, a
        peripheral's event, `Scs.write32`). (A run can still stop at an unmasking
        instruction translated while they were exits; `_at_exit` executes it all the
        same.)"""
        scs = self.scs
        if not scs.pending and not self.irq_lines:
            return self.no_exits
        floor = 256
        for e in scs.active:
            floor = min(floor, scs.group(scs.priority(e)))
        for e in list(scs.pending) + [16 + i for i in self.irq_lines]:
            if e in scs.active or e in self.blocked or not scs.exception_enabled(e):
                continue
            if scs.group(scs.priority(e)) < floor:
                return self.all_exits
        return self.no_exits

    def _start_chunk(self, n, hz):
        self.chunk_t0, self.chunk_c0, self.chunk_n, self.chunk_hz = self.t_s, self.cycles, n, hz
        self.resume_pc = None
        self.stopped = False
        self.in_chunk = True

    def _chunk(self, n, hz):
        self._start_chunk(n, hz)
        exits = self._exits_for_chunk()
        if exits is not self.exits_now:
            self.exits_ctl.set(exits)
            self.exits_now = exits
        err = None
        try:
            self.uc.emu_start(self.pc | 1, 0, count=n)
        except UcError as e:
            err = e
        if self.chunk_done:
            self.chunk_done = False
            return
        self._finish_chunk(err)

    def _finish_chunk(self, err):
        n, hz = self.chunk_n, self.chunk_hz
        executed = min(self.counter.read(), n)
        self.in_chunk = False
        # a stalled core still counts cycles (the DWT counter runs on HCLK)
        self.cycles += executed + int(self.stall_s * hz)
        self.t_s += executed / hz + self.stall_s
        self.stall_s = 0.0
        self._apply_stores()
        if self.stop_reason is not None:
            raise self.stop_reason
        if err is not None:
            pc = self.uc.reg_read(UC_ARM_REG_PC)
            self.hard_fault(pc, f"bus fault ({err})")
            return
        if isinstance(self.resume_pc, tuple):
            _, pc, what = self.resume_pc
            self.hard_fault(pc, what)
            return
        self.pc = self.resume_pc if self.resume_pc is not None else self.pc_sp.read()[0]
        if not self.stopped and executed < n and self.pc not in self.exits:
            # unicorn ends a run after a WFI by itself (and for nothing else the twin does
            # not ask for)
            if self.pc - 2 not in self.wfi_addrs:
                raise TwinError(f"the core stopped at 0x{self.pc:08x} for no reason the twin knows")
            self.sleeping = True
        if self.replay is not None and len(self.scs.active) <= self.replay[2] and self.pc != self.replay[0][0]:
            # the store that ended the chunk completed (unicorn resumes after it): nothing
            # to skip. Kept, the next store of the same value from the same place (two
            # equal bytes into USART2's DR) was dropped as its replay. A chunk of a handler
            # taken before the store resumed (it stops at a WFI or an unmasking
            # instruction, `_at_exit`) says nothing about it.
            self.replay = None

    def _return_in_chunk(self):
        """An exception return inside a run of the core: end the chunk there and plan the
        next one as the run loop does (`_finish_chunk`, `_iteration`: the same steps on
        the same numbers, so time and every decision stay the same to the bit), and let
        unicorn go on with it instead of stopping and starting again. True if it goes on;
        False leaves the return to the run loop, untouched; a chunk planned that the run
        cannot go on with (its exits differ, a scenario's instruction count, a reset)
        ends the run and waits in `deferred`."""
        ctx = self._run_ctx
        if (ctx is None or not self.in_chunk or self.stopped or self.stop_reason is not None
                or self.reset_pending is not None or self.call_after_insns is not None
                or self.pending_stores or self.stall_s):
            return False
        until_s, poll, poll_every_s = ctx
        t_after = self.t_s + min(self.counter.read(), self.chunk_n) / self.chunk_hz
        if not t_after < until_s or (poll is not None and t_after >= self._next_poll):
            return False
        self.resume_pc = self.pc
        self.stopped = True
        self._finish_chunk(None)
        self.stopped = False  # (set again by anything in the turn that stops the run)
        plan = self._iteration(until_s, poll, poll_every_s)
        if not isinstance(plan, tuple):
            raise TwinError(f"the run loop planned {plan!r} after an exception return")
        if (self.stopped or self.stop_reason is not None or self.reset_pending is not None
                or self.call_after_insns is not None or self._exits_for_chunk() is not self.exits_now):
            self.deferred = plan
            self.chunk_done = True
            self.uc.emu_stop()
            return True
        n, hz = plan
        self._start_chunk(n, hz)
        self.counter.restart(n)
        self.pc_write.write((self.pc | 1,))
        return True

    def hard_fault(self, pc, what):
        self.faults.append((self.t_s, what, pc))
        if HARDFAULT in self.scs.active:
            raise TwinError(f"lockup: {what} at 0x{pc:08x} inside the HardFault handler")
        self.scs["HFSR"] |= 1 << 30
        self._enter(HARDFAULT, pc)
