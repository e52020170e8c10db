#!/usr/bin/env python3
"""Run the Cortex-M4 (and Cortex-M3) kernels of insns/kernels in the unicorn emulator.

Usage (normally through `cargo insns`, which builds the ELFs and calls this):
  count.py ELF count                    one line per kernel:
                                        `<name> instructions=<N> cycles_est=<M>`
  count.py ELF profile NAME             exclusive instructions per function of one kernel
  count.py ELF parts NAME               one `servo_period` by part of the period
  count.py ELF replay NAME IN N OUT     run `insns_replay_<NAME>` on N records read
                                        from IN (f32 little-endian), write the raw
                                        outputs to OUT

The core is read from the ELF: a hard-float ELF (`thumbv7em-none-eabihf`) is a
Cortex-M4F, a soft-float one (`thumbv7m-none-eabi`) a Cortex-M3 (the cycle model
differs in the long multiplies, see below).

Kernels are discovered by symbol: every `insns_kernel_<name>` with a matching
`insns_setup_<name>`. The emulator first runs the binary's reset handler up to `main`
(cortex-m-rt: .data/.bss initialisation, FPU enable), then calls each setup (not
counted) and each kernel once (counted: every instruction from the kernel's entry to
its return, callees included).

Instruction count: instructions issued. Unicorn does not report instructions skipped
inside an IT block; they are added back (the core still issues them, as no-ops).

Cycle estimate (Cortex-M4 TRM, table 3-1; zero-wait-state memory, i.e. code and data
in single-cycle SRAM/flash with ART hits, no interrupts, no bus contention):
  1   every instruction not listed below (ALU, MUL, SMULL/UMULL/SMLAL/UMLAL/UMAAL,
      VADD/VSUB/VMUL/VNEG/VABS/VCVT/VCMP/VMOV, VMRS, IT, not-taken branches)
  2   LDR*/STR* (single register, incl. literal loads), MLA/MLS, VLDR/VSTR,
      VMOV between two core registers and a double/two singles
  3   LDRD/STRD
  1+N LDM/STM/PUSH/POP, VLDM/VSTM/VPUSH/VPOP (N = registers transferred)
  3   VMLA/VMLS/VNMLA/VNMLS/VFMA/VFMS/VFNMA/VFNMS (chained 3-cycle FP MAC)
  12  SDIV/UDIV (upper bound of 2..12)
  14  VDIV.F32, VSQRT.F32
  +P  pipeline refill for every taken branch, BL/BLX, BX, POP/LDM into PC:
      P = 3, the upper bound of the TRM's 1..3
The estimate is therefore an upper bound for zero-wait-state memory; with the STM32F407
at 168 MHz from flash (5 wait states, ART accelerator) straight-line code fetched from
flash can cost more on ART misses.

Cortex-M3 (TRM table 18-1): the same, except UMULL/SMULL 5 and UMLAL/SMLAL 7 cycles
(the upper bounds of 3..5 and 4..7: early termination on small operands), and no FPU
(every float operation is a call into compiler-builtins' soft float).
"""

import os
import struct
import sys

try:
    from capstone import CS_ARCH_ARM, CS_MODE_MCLASS, CS_MODE_THUMB, Cs
    from elftools.elf.elffile import ELFFile
    from unicorn import UC_ARCH_ARM, UC_HOOK_CODE, UC_MODE_MCLASS, UC_MODE_THUMB, Uc
    from unicorn import arm_const as A
except ImportError as exc:  # pragma: no cover - environment problem
    sys.stderr.write(
        "insns: missing Python package (%s).\n"
        "Install: python3 -m pip install unicorn capstone pyelftools\n" % exc
    )
    sys.exit(2)

FLASH = (0x0800_0000, 1024 * 1024)
# 512 KiB at the SRAM's address: room for every kernel's state at once and the setups' stack
# (kernels/memory.x)
RAM = (0x2000_0000, 512 * 1024)
# Private peripheral bus (SCB: CPACR for the FPU enable in the reset handler).
PPB = (0xE000_0000, 0x10_0000)
# Return address for called functions: an unused, mapped flash word (emulation stops
# when PC reaches it, before it executes).
RET_ADDR = FLASH[0] + FLASH[1] - 0x100
STACK_TOP = RAM[0] + RAM[1]
# Scratch buffers for the replay: an extra RAM region (the FSMC window on the STM32F4),
# so a replay of any length does not compete with the binary's RAM.
REPLAY = (0x6000_0000, 16 * 1024 * 1024)
REFILL = 3
MAX_INSNS = 50_000_000
# Instructions an uncounted setup may run: setups run without the counting hook, at the
# emulator's own speed (the `machine_period_*` setups run the machine closed-loop on the
# simulated world, its physics in soft-float f64, for thousands of periods; the shaped
# one twice as many, its program reaching feed later).
SETUP_MAX_INSNS = 4_000_000_000


def load(path):
    with open(path, "rb") as f:
        elf = ELFFile(f)
        segs = [
            (s["p_vaddr"], s["p_paddr"], s.data())
            for s in elf.iter_segments()
            if s["p_type"] == "PT_LOAD"
        ]
        symtab = elf.get_section_by_name(".symtab")
        syms = {}
        global FUNCS
        FUNCS = []
        for s in symtab.iter_symbols():
            if s.name and s["st_info"]["type"] == "STT_FUNC":
                syms[s.name] = s["st_value"] & ~1
                FUNCS.append((s["st_value"] & ~1, s["st_size"], s.name))
        FUNCS.sort()
    return segs, syms


FUNCS = []


def demangle_short(name):
    """A readable short form of a mangled Rust symbol (no external tools needed)."""
    if not name.startswith("_ZN"):
        return name
    parts, i = [], 3
    while i < len(name) and name[i].isdigit():
        j = i
        while name[j].isdigit():
            j += 1
        n = int(name[i:j])
        parts.append(name[j:j + n])
        i = j + n
    parts = [p for p in parts if not (p.startswith("h") and len(p) == 17)]
    return "::".join(parts[-3:])


def demangle(name):
    """Full path of a mangled Rust symbol (legacy mangling), generics kept."""
    if not name.startswith("_ZN"):
        return name
    parts, i = [], 3
    while i < len(name) and name[i].isdigit():
        j = i
        while name[j].isdigit():
            j += 1
        n = int(name[i:j])
        parts.append(name[j:j + n])
        i = j + n
    parts = [p for p in parts if not (p.startswith("h") and len(p) == 17)]
    out = "::".join(parts)
    for a, b in (("$LT$", "<"), ("$GT$", ">"), ("$u20$", " "), ("$C$", ","), ("$RF$", "&"),
                 ("..", "::"), ("_$", "$")):
        out = out.replace(a, b)
    return out


def make_emu(segs):
    uc = Uc(UC_ARCH_ARM, UC_MODE_THUMB | UC_MODE_MCLASS)
    for base, size in (FLASH, RAM, PPB, REPLAY):
        uc.mem_map(base, size)
    for vaddr, paddr, data in segs:
        for a in {vaddr, paddr}:
            if FLASH[0] <= a < FLASH[0] + FLASH[1] or RAM[0] <= a < RAM[0] + RAM[1]:
                uc.mem_write(a, data)
    return uc


class Counter:
    """Code hook: counts instructions, IT-skipped instructions and estimated cycles."""

    def __init__(self, uc, core="m4"):
        self.cs = Cs(CS_ARCH_ARM, CS_MODE_THUMB | CS_MODE_MCLASS)
        self.uc = uc
        self.core = core
        self.cache = {}
        self.handle = None
        self.reset()

    def attach(self):
        """Install the code hook (only around counted runs: a Python call per
        instruction is what makes the emulator slow)."""
        if self.handle is None:
            self.handle = self.uc.hook_add(UC_HOOK_CODE, self.hook)

    def detach(self):
        if self.handle is not None:
            self.uc.hook_del(self.handle)
            self.handle = None

    def reset(self):
        self.insns = 0
        self.cycles = 0
        self.it_skipped = 0  # instructions added back from IT blocks
        self.prev = None  # (address, size, mnemonic, is_branch_like)
        self.it_pending = []
        self.it_addr = None  # the IT instruction of `it_pending`
        self.active = False
        self.profile = None
        # parts mode: `attrib(addr)` names the part an instruction belongs to
        self.attrib = None
        self.parts = None
        self.cycles_by_part = {}
        self.it_part = None
        self.prev_part = None

    def decode(self, addr, size):
        d = self.cache.get(addr)
        if d is None:
            code = bytes(self.uc.mem_read(addr, size))
            ins = next(self.cs.disasm(code, addr), None)
            if ins is None:
                d = ("?", "", 1)
            else:
                d = (ins.mnemonic, ins.op_str, ins.size)
            self.cache[addr] = d
        return d

    def it_block(self, addr, mnemonic):
        """Addresses of the instructions an IT instruction at addr conditions."""
        n = len(mnemonic) - 1  # it, itt, ite, ittt, ...
        out, a = [], addr + 2
        for _ in range(n):
            code = bytes(self.uc.mem_read(a, 4))
            ins = next(self.cs.disasm(code, a), None)
            size = ins.size if ins else 2
            out.append(a)
            a += size
        return out

    def base_cycles(self, m, ops):
        m = m.split(".")[0]
        if self.core == "m3" and m in ("umull", "smull"):
            return 5
        if self.core == "m3" and m in ("umlal", "smlal"):
            return 7
        if m in ("sdiv", "udiv"):
            return 12
        if m in ("vdiv", "vsqrt"):
            return 14
        if m in ("vmla", "vmls", "vnmla", "vnmls", "vfma", "vfms", "vfnma", "vfnms"):
            return 3
        if m in ("push", "pop", "ldm", "stm", "ldmia", "stmia", "ldmdb", "stmdb",
                 "vpush", "vpop", "vldmia", "vstmia", "vldmdb", "vstmdb", "vldm", "vstm"):
            regs = ops[ops.find("{") + 1:ops.find("}")]
            n = 0
            for r in regs.split(","):
                r = r.strip()
                if "-" in r:  # register range d8-d11
                    lo, hi = r.split("-")
                    n += int(hi.strip()[1:]) - int(lo[1:]) + 1
                elif r:
                    n += 1
            return 1 + n
        if m in ("ldrd", "strd"):
            return 3
        if m.startswith("ldr") or m.startswith("str") or m in ("vldr", "vstr"):
            return 2
        if m in ("mla", "mls"):
            return 2
        if m == "vmov" and ops.count(",") >= 2:
            return 2
        return 1

    def hook(self, uc, addr, size, _):
        if not self.active:
            return
        if self.profile is not None:
            self.profile[addr] = self.profile.get(addr, 0) + 1
        part = None
        if self.attrib is not None:
            part = self.attrib(addr)
            self.parts[part] = self.parts.get(part, 0) + 1
        m, ops, _ = self.decode(addr, size)
        # IT bookkeeping: instructions of the block that were not reported were skipped.
        if self.it_pending:
            if addr in self.it_pending:
                self.it_pending.remove(addr)
            else:
                self.add_skipped()
        # Taken branch (or any control transfer): refill penalty on the previous one.
        if self.prev is not None:
            pa, ps = self.prev
            if addr != pa + ps:
                self.cycles += REFILL
                self.part_cycles(self.prev_part, REFILL)
        self.insns += 1
        c = self.base_cycles(m, ops)
        self.cycles += c
        self.part_cycles(part, c)
        if m[:2] == "it" and set(m[2:]) <= {"t", "e"}:
            self.it_pending = self.it_block(addr, m)
            self.it_addr = addr
            self.it_part = part
        self.prev = (addr, size)
        self.prev_part = part
        if self.insns > MAX_INSNS:
            uc.emu_stop()

    def part_cycles(self, part, c):
        if self.parts is not None:
            self.cycles_by_part[part] = self.cycles_by_part.get(part, 0) + c

    def add_skipped(self):
        """Count the instructions of the pending IT block that were not reported (skipped:
        the core still issues them), in the IT instruction's function and part."""
        skipped = len(self.it_pending)
        self.it_skipped += skipped
        self.insns += skipped
        self.cycles += skipped
        if self.profile is not None:
            self.profile[self.it_addr] = self.profile.get(self.it_addr, 0) + skipped
        if self.parts is not None:
            self.parts[self.it_part] = self.parts.get(self.it_part, 0) + skipped
            self.part_cycles(self.it_part, skipped)
        self.it_pending = []

    def finish(self):
        """Account for the final return (taken branch) and unflushed IT entries."""
        self.cycles += REFILL
        self.part_cycles(self.prev_part, REFILL)
        if self.it_pending:
            self.add_skipped()


def call(uc, counter, addr, args=(), count=False, limit=None):
    """Call the function at `addr`; counted (the hook installed) when `count`. `limit`:
    instructions at most (default MAX_INSNS counted, SETUP_MAX_INSNS otherwise; 0: no
    limit)."""
    if limit is None:
        limit = MAX_INSNS if count else SETUP_MAX_INSNS
    regs = [A.UC_ARM_REG_R0, A.UC_ARM_REG_R1, A.UC_ARM_REG_R2, A.UC_ARM_REG_R3]
    for r, v in zip(regs, args):
        uc.reg_write(r, v)
    uc.reg_write(A.UC_ARM_REG_SP, STACK_TOP)
    uc.reg_write(A.UC_ARM_REG_LR, RET_ADDR | 1)
    counter.reset()
    counter.active = count
    if count:
        counter.attach()
    try:
        uc.emu_start(addr | 1, RET_ADDR, count=limit)
    finally:
        counter.active = False
        counter.detach()
    if uc.reg_read(A.UC_ARM_REG_PC) & ~1 != RET_ADDR:
        raise RuntimeError("function at 0x%08x did not return" % addr)
    return uc.reg_read(A.UC_ARM_REG_R0)


def core_of(elf_path):
    """`m4` for a hard-float ELF (EF_ARM_ABI_FLOAT_HARD), else `m3`."""
    with open(elf_path, "rb") as f:
        return "m4" if ELFFile(f)["e_flags"] & 0x400 else "m3"


def boot(elf_path):
    """The emulator after the reset handler. The counting hook is installed only while a
    kernel is counted (`Counter.attach`); everything else runs at the emulator's own
    speed. A panic (`core::panicking::panic_fmt`) or a HardFault stops the emulation (the
    call then fails)."""
    segs, syms = load(elf_path)
    uc = make_emu(segs)
    counter = Counter(uc, core_of(elf_path))
    stops = [a for n, a in syms.items() if n.endswith("9panicking9panic_fmt") or n == "HardFault"]
    for a in stops:
        uc.hook_add(UC_HOOK_CODE, lambda u, *_: u.emu_stop(), begin=a, end=a)
    # Reset handler up to main: initialises .data/.bss, enables the FPU.
    sp0, reset = struct.unpack("<II", bytes(uc.mem_read(FLASH[0], 8)))
    uc.reg_write(A.UC_ARM_REG_SP, sp0)
    uc.emu_start(reset | 1, syms["main"], count=MAX_INSNS)
    return uc, counter, syms


def cmd_count(elf_path):
    uc, counter, syms = boot(elf_path)
    names = sorted(n[len("insns_kernel_"):] for n in syms if n.startswith("insns_kernel_"))
    failed = False
    for name in names:
        setup = syms.get("insns_setup_" + name)
        try:
            built = setup is not None and call(uc, counter, setup) == 1
        except RuntimeError:  # a panic, or the instruction limit
            built = False
        if not built:
            print("%s setup failed" % name)
            failed = True
            continue
        call(uc, counter, syms["insns_kernel_" + name], count=True)
        counter.finish()
        print("%s instructions=%d cycles_est=%d" % (name, counter.insns, counter.cycles))
        if os.environ.get("INSNS_VERBOSE"):
            print("  (%d of them skipped in IT blocks and added back)" % counter.it_skipped)
    return 1 if failed else 0


def cmd_profile(elf_path, name, top=25):
    """Exclusive instructions per function symbol for one step of kernel `name`."""
    import bisect
    uc, counter, syms = boot(elf_path)
    if call(uc, counter, syms["insns_setup_" + name]) != 1:
        raise SystemExit("%s setup failed" % name)
    counter.reset()
    counter.profile = {}
    prof = counter.profile
    counter.active = True
    counter.attach()
    uc.reg_write(A.UC_ARM_REG_SP, STACK_TOP)
    uc.reg_write(A.UC_ARM_REG_LR, RET_ADDR | 1)
    uc.emu_start(syms["insns_kernel_" + name] | 1, RET_ADDR, count=MAX_INSNS)
    counter.detach()
    counter.active = False
    counter.finish()
    starts = [f[0] for f in FUNCS]
    per = {}
    for addr, n in prof.items():
        k = bisect.bisect_right(starts, addr) - 1
        fn = "?"
        if k >= 0 and addr < FUNCS[k][0] + max(FUNCS[k][1], 1):
            fn = demangle_short(FUNCS[k][2])
        per[fn] = per.get(fn, 0) + n
    total = sum(per.values())
    print("%s: %d instructions (exclusive per function, inlined code counts in its caller)" % (name, total))
    for fn, n in sorted(per.items(), key=lambda x: -x[1])[:top]:
        print("%7d %5.1f%%  %s" % (n, 100.0 * n / total, fn))
    return 0


# Parts of the control period (`count.py ELF parts servo_period`): every instruction of
# one `Servo::period` is attributed to the part of the period it belongs to, from the
# DWARF inline tree of the real, optimised code (no separate kernel, so the parts add up
# to the `servo_period` count exactly). An instruction belongs to the first part below
# whose patterns match the qualified name of any function it was inlined from (or, for
# code outside `Servo::period`, of the function `Servo::period` called, or of a function
# inlined at that call); what matches none is the period's own body: state machine,
# saturation, output write, snapshot.
PERIOD_ROOT = "5servo14Servo$LT$R$GT$6period"
PERIOD_PARTS = [
    ("io (the kernel's stub): inputs, counters, outputs", ["read_inputs", "read_counters",
                                                          "write_outputs", "disable_outputs"]),
    ("checks (encoder, overrun, tracking, non-finite)", ["servo::monitor::", "unhealthy_axis"]),
    ("encoder counts (wrap extension)", ["estimator::wide::"]),
    ("estimators (positions, PLL)", ["estimator::", "bank::"]),
    ("reference (motion, trajectory, sin/cos)", ["servo::motion::", "motion::trajectory::",
                                                 "sin_cos"]),
    ("coupling (contour error, cross-coupling)", ["coupling::"]),
    ("laws (3 axes: evaluate, commit)", ["law::", "num::powers", "num::shared_root",
                                         "root_abs", "controller::"]),
]
BODY_PART = "servo body: states, commands, saturation, snapshot"


def _strip_generics(name):
    """`a::b<f32, c::D>::e` -> `a::b::e`: match on paths, not on type arguments."""
    out, depth = [], 0
    for ch in name:
        if ch == "<":
            depth += 1
        elif ch == ">":
            depth = max(depth - 1, 0)
        elif depth == 0:
            out.append(ch)
    return "".join(out)


def _die_name(die):
    """Qualified name of a DWARF subprogram DIE (namespaces from its declaration)."""
    seen = 0
    while seen < 4 and "DW_AT_name" not in die.attributes:
        for a in ("DW_AT_specification", "DW_AT_abstract_origin"):
            if a in die.attributes:
                die = die.get_DIE_from_attribute(a)
                break
        else:
            break
        seen += 1
    name = die.attributes.get("DW_AT_name")
    parts = [name.value.decode() if name else "?"]
    p = die.get_parent()
    while p is not None and p.tag != "DW_TAG_compile_unit":
        a = p.attributes.get("DW_AT_name")
        if a is not None:
            parts.append(a.value.decode())
        p = p.get_parent()
    return _strip_generics("::".join(reversed(parts)))


def _die_ranges(dw, cu, die):
    at = die.attributes
    if "DW_AT_low_pc" in at and "DW_AT_high_pc" in at:
        lo = at["DW_AT_low_pc"].value
        hi = at["DW_AT_high_pc"]
        hi = hi.value if hi.form == "DW_FORM_addr" else lo + hi.value
        return [(lo, hi)]
    if "DW_AT_ranges" in at:
        base = cu.get_top_DIE().attributes.get("DW_AT_low_pc")
        base = base.value if base is not None else 0
        out = []
        for e in dw.range_lists().get_range_list_at_offset(at["DW_AT_ranges"].value):
            if hasattr(e, "base_address"):
                base = e.base_address
            else:
                off = 0 if getattr(e, "is_absolute", False) else base
                out.append((e.begin_offset + off, e.end_offset + off))
        return out
    return []


def inline_trees(elf_path):
    """{function start: [(lo, hi, depth, qualified name)]}: every inlined call of every
    out-of-line function, from the DWARF of the ELF."""
    from elftools.elf.elffile import ELFFile
    trees = {}
    with open(elf_path, "rb") as f:
        dw = ELFFile(f).get_dwarf_info()
        for cu in dw.iter_CUs():
            for die in cu.iter_DIEs():
                if die.tag != "DW_TAG_subprogram":
                    continue
                lo = die.attributes.get("DW_AT_low_pc")
                if lo is None or lo.value == 0:
                    continue
                out = trees.setdefault(lo.value & ~1, [])

                def walk(d, depth):
                    for c in d.iter_children():
                        if c.tag == "DW_TAG_inlined_subroutine":
                            name = _die_name(c)
                            for a, b in _die_ranges(dw, cu, c):
                                out.append((a, b, depth, name))
                            walk(c, depth + 1)
                        elif c.tag == "DW_TAG_lexical_block":
                            walk(c, depth)

                walk(die, 0)
    return trees


def _is_return(m, ops):
    """A function return (the instruction was issued: unicorn does not report skipped
    ones)."""
    if m in ("bx",) and ops.strip() == "lr":
        return True
    if m.split(".")[0] in ("pop", "ldm", "ldmia") and "pc" in ops:
        return True
    return m.split(".")[0] == "ldr" and ops.startswith("pc,")


def cmd_parts(elf_path, name, root=PERIOD_ROOT, rules=PERIOD_PARTS, body=BODY_PART):
    """Instructions of one step of kernel `name` per part of `root` (see PERIOD_PARTS).

    Every instruction issued inside the dynamic extent of `root` gets the names of the
    functions it runs in: for each call on the way down from `root`, the function and
    everything inlined at the call site, then the current function and what is inlined at
    the instruction. A return-address stack (pushed on BL/BLX, popped on returns) keeps
    the call sites."""
    import bisect
    uc, counter, syms = boot(elf_path)
    roots = [f for f in FUNCS if root in f[2]]
    if len(roots) != 1:
        raise SystemExit("expected one function matching %s, found %d" % (root, len(roots)))
    r_lo = roots[0][0]
    trees = inline_trees(elf_path)
    starts = [f[0] for f in FUNCS]

    def function(addr):
        k = bisect.bisect_right(starts, addr) - 1
        if k >= 0 and addr < FUNCS[k][0] + max(FUNCS[k][1], 1):
            return FUNCS[k]
        return (addr, 0, "?")

    def classify(names):
        for part, pats in rules:
            if any(p in n for n in names for p in pats):
                return part
        return body

    here_cache = {}

    def here(addr):
        """Names at `addr` within its own function: the function, then its inlined calls
        outermost first."""
        h = here_cache.get(addr)
        if h is None:
            lo, _, sym = function(addr)
            inl = sorted((t for t in trees.get(lo, ()) if t[0] <= addr < t[1]),
                         key=lambda t: t[2])
            h = [demangle(sym).replace("<", "").replace(">", "")] + [t[3] for t in inl]
            here_cache[addr] = h
        return h

    # stack of call sites: None outside `root`, else the names at the call
    stack = [None]
    detail = {} if os.environ.get("INSNS_VERBOSE") else None

    def attrib(addr):
        site = stack[-1]
        if addr == r_lo and site is None:
            stack[-1] = []  # entered the root: its callees' names start here
            site = []
        if site is None:
            part = "kernel entry (outside the period)"
            names = None
        else:
            names = site + here(addr)
            part = classify(names)
            if detail is not None:
                key = (part, " > ".join(n.split("::")[-1] for n in names[:6]))
                detail[key] = detail.get(key, 0) + 1
        m, ops, _ = counter.decode(addr, 4)
        if m.split(".")[0] in ("bl", "blx"):
            stack.append(names)
        elif _is_return(m, ops):
            if len(stack) > 1:
                stack.pop()
            elif site is not None:
                stack[-1] = None  # the root returned
        return part

    if call(uc, counter, syms["insns_setup_" + name]) != 1:
        raise SystemExit("%s setup failed" % name)
    counter.reset()
    counter.attrib = attrib
    counter.parts = {}
    counter.active = True
    counter.attach()
    uc.reg_write(A.UC_ARM_REG_SP, STACK_TOP)
    uc.reg_write(A.UC_ARM_REG_LR, RET_ADDR | 1)
    uc.emu_start(syms["insns_kernel_" + name] | 1, RET_ADDR, count=MAX_INSNS)
    counter.detach()
    counter.active = False
    counter.finish()
    total = counter.insns
    print("%s: %d instructions, %d cycles_est, by part of %s (DWARF inline tree)"
          % (name, total, counter.cycles, demangle_short(roots[0][2])))
    print("  insns cycles_est  share  part")
    order = [p for p, _ in rules] + [body, "kernel entry (outside the period)"]
    for part in order:
        n = counter.parts.get(part, 0)
        if n:
            print("%7d %10d %5.1f%%  %s" % (n, counter.cycles_by_part.get(part, 0),
                                           100.0 * n / total, part))
    if detail:
        for (part, chain_), n in sorted(detail.items(), key=lambda x: (x[0][0], -x[1])):
            print("  %5d  %-20.20s %s" % (n, part, chain_))
    return 0


def cmd_replay(elf_path, name, in_path, n, out_path, in_rec=7, out_rec=9):
    uc, counter, syms = boot(elf_path)
    data = open(in_path, "rb").read()
    if len(data) != n * in_rec * 4:
        raise SystemExit("replay input has %d bytes, expected %d" % (len(data), n * in_rec * 4))
    out_addr = (REPLAY[0] + len(data) + 64) & ~7
    if out_addr + n * out_rec * 8 > REPLAY[0] + REPLAY[1]:
        raise SystemExit("replay too long for the emulated buffer region")
    uc.mem_write(REPLAY[0], data)
    # no instruction limit: soft-float replays on the Cortex-M3 run tens of millions
    ran = call(uc, counter, syms["insns_replay_" + name], (REPLAY[0], n, out_addr), limit=0)
    if ran != n:
        raise SystemExit("replay ran %d of %d steps" % (ran, n))
    with open(out_path, "wb") as f:
        f.write(bytes(uc.mem_read(out_addr, n * out_rec * 8)))
    return 0


def main(argv):
    if len(argv) >= 3 and argv[2] == "count":
        return cmd_count(argv[1])
    if len(argv) == 4 and argv[2] == "profile":
        return cmd_profile(argv[1], argv[3])
    if len(argv) == 4 and argv[2] == "parts":
        return cmd_parts(argv[1], argv[3])
    if len(argv) == 7 and argv[2] == "replay":
        return cmd_replay(argv[1], argv[3], argv[4], int(argv[5]), argv[6])
    sys.stderr.write(__doc__)
    return 2


if __name__ == "__main__":
    sys.exit(main(sys.argv))
