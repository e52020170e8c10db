"""Scenarios the board twin runs against the release ELF, each a list of checks with the
measured value and its bound."""

import re
import struct
import time

from unicorn.arm_const import UC_ARM_REG_LR, UC_ARM_REG_R0, UC_ARM_REG_SP

from . import board, expect
from .machine import SRAM_BASE, Twin
from .regs import TwinError
from .rcc import CSR_BORRSTF, CSR_IWDGRSTF, CSR_PINRSTF, CSR_PORRSTF
from .rtt import RttReader

TIM4_EXC = 16 + 30
# UART4: the dispatcher of the priority-2 tasks (link, button)
UART4_EXC = 16 + 52
# the control rate of a default `cargo fw` (firmware/src/config.rs, GANTRY_CONTROL_HZ)
CONTROL_HZ = 10_000
# machine time a boot scenario runs: the boot (about 0.1 s, most of it the settings
# store's scan of its two erased sectors) and 0.2 s of control periods
BOOT_RUN_S = 0.3


def check(name, value, bound, ok):
    return {"check": name, "value": value, "bound": bound, "pass": bool(ok)}


def boot(elf, log_path):
    """Power on with healthy inputs and an erased settings store: the firmware boots,
    every output stays off, the control interrupt runs at its rate, the watchdog is fed."""
    t = Twin(elf)
    rtt = RttReader(t, elf, log_path)
    w = time.time()
    t.run(BOOT_RUN_S - 0.1, poll=rtt.poll)
    ms_tasks0 = t.entries.get(UART4_EXC, 0)
    t.run(BOOT_RUN_S, poll=rtt.poll)
    ms_tasks = t.entries.get(UART4_EXC, 0) - ms_tasks0
    wall = time.time() - w
    rtt.poll()
    lines = rtt.close()
    out = []
    out.append(check("HardFaults", len(t.faults), 0, not t.faults))
    resets = [hex(f) for _, f in t.resets]
    out.append(check("resets (RCC_CSR flags)", resets, "power-on only", t.resets == [(0.0, CSR_PORRSTF | CSR_BORRSTF | CSR_PINRSTF)]))
    out.append(_no_output_active(t, "outputs driven active from reset on"))
    low = [tt for tt, k, v in t.log if k.startswith(("enable.", "brake.")) and v == 0]
    floating_s = min(low) if low else None
    out.append(check("enables and brakes floating after reset, ms",
                     None if floating_s is None else round(floating_s * 1e3, 3),
                     "driven low by the end", floating_s is not None))
    entries = t.entries.get(TIM4_EXC, 0)
    first = t.first_entry.get(TIM4_EXC)
    expected = (BOOT_RUN_S - first) * CONTROL_HZ if first is not None else 0
    out.append(check("control interrupts", entries, f"{expected:.0f} ± 1 %",
                     first is not None and abs(entries - expected) <= 0.01 * expected + 1))
    out.append(check("watchdog running and fed", t.iwdg.running, True, t.iwdg.running))
    # the link and button tasks (UART4's dispatcher) each wait for the next millisecond;
    # they run in one dispatch or two: 1,000 to 2,000 dispatches a second
    out.append(check("1 ms tasks' dispatches in the last 0.1 s", ms_tasks, "100..200", 100 <= ms_tasks <= 200))
    cause = [l.split("reset cause: ")[1] for l in lines if "reset cause: " in l]
    out.append(check("reset cause logged", cause, ["power-on"], cause == ["power-on"]))
    bor = [l.split("brown-out reset: ")[1] for l in lines if "brown-out reset: " in l]
    out.append(check("brown-out level at the factory option bytes", bor, "programmed to 2.7 V",
                     len(bor) == 1 and bor[0].startswith("programmed to 2.7 V")))
    selfcheck = [l.split("board configuration: ")[1] for l in lines if "board configuration: " in l]
    out.append(check("the firmware's boot self-check of the register table", selfcheck,
                     "N register fields as expected", len(selfcheck) == 1 and selfcheck[0].endswith("register fields as expected")))
    errors = [l for l in lines if " ERROR " in l or l.startswith("ERROR")]
    out.append(check("defmt errors", errors or "none", "none", not errors))
    out.extend(expect.check_after_boot(t, CONTROL_HZ))
    info = {
        "machine_s": BOOT_RUN_S,
        "boot_ms": round(first * 1e3, 3) if first is not None else None,
        "speed_x_real_time": round(BOOT_RUN_S / wall, 3),
        "cycles": t.cycles,
        "log_lines": len(lines),
    }
    return out, info


# DS8626 table 25: the LSI is 17–47 kHz; the IWDG's timeout at the slowest LSI
LSI_MIN_HZ = 17_000


def watchdog(elf, log_path):
    """The control loop stops (its interrupt is no longer taken) 0.15 s after power-on:
    the IWDG resets the chip within its timeout, every output stays off through the
    reset, and the firmware boots again and runs its control loop."""
    t = Twin(elf)
    rtt = RttReader(t, elf, log_path)
    t.run(0.15, poll=rtt.poll)
    hang_s = t.t_s
    t.blocked.add(TIM4_EXC)
    t.run(0.6, poll=rtt.poll)
    rtt.poll()
    lines = rtt.close()
    out = []
    out.extend(_one_iwdg_reset(t, hang_s, "resets after the hang", "reset after the last feed, ms"))
    out.append(_no_output_active(t))
    after = t.entries.get(TIM4_EXC, 0) - t.entries_at_reset.get(TIM4_EXC, 0)
    out.append(check("control interrupts after the reboot", after, "> 0", after > 0))
    ups = [l for l in lines if "firmware up" in l]
    out.append(check("boots logged", len(ups), 2, len(ups) == 2))
    cause = [l.split("reset cause: ")[1] for l in lines if "reset cause: " in l]
    out.append(check("reset cause logged at each boot", cause, ["power-on", "watchdog"], cause == ["power-on", "watchdog"]))
    bor = [l.split("brown-out reset: ")[1] for l in lines if "brown-out reset: " in l]
    out.append(check("brown-out level kept through the reset", bor[1:], ["2.7 V"], bor[1:] == ["2.7 V"]))
    return out, {"machine_s": 0.6, "hang_at_ms": round(hang_s * 1e3, 3)}


def _one_iwdg_reset(t, since_s, resets_name, after_name):
    """Exactly one reset after power-on, by the IWDG, within its timeout at the slowest LSI
    plus one period (the first update the control task misses is at most one period
    after `since_s`)."""
    resets = t.resets[1:]
    iwdg = [r for r in resets if r[1] & CSR_IWDGRSTF]
    out = [check(resets_name, [hex(f) for _, f in resets], "one IWDG reset", len(resets) == 1 and len(iwdg) == 1)]
    if iwdg and since_s is not None:
        timeout_s = (t.iwdg["RLR"] + 1) * (4 << t.iwdg["PR"]) / LSI_MIN_HZ
        after_ms = (iwdg[0][0] - since_s) * 1e3
        bound_ms = (timeout_s + 1 / CONTROL_HZ) * 1e3
        out.append(check(after_name, round(after_ms, 3), f"<= {bound_ms:.3f} (RLR at 17 kHz + 1 period)", after_ms <= bound_ms))
    return out


def _no_output_active(t, name="outputs driven active"):
    """No enable, brake, MOE or PWM duty driven active at any time of the run."""
    active = sorted({k for _, k, v in t.log if (k.split(".")[0] in ("enable", "brake") or k == "moe") and v == 1}
                    | {k for _, k, v in t.log if k.startswith("pwm.") and v not in (0, None, 0.0)})
    return check(name, active or "none", "none", not active)


# USART2's interrupt (its handler runs above the control interrupt)
USART2_EXC = 16 + 38
# USART2 interrupts a storm would take in the scenario's 0.1 s; a byte takes one or two
STORM_ENTRIES = 50


def uart_overrun(elf, log_path):
    """A host byte completes between the USART2 handler's read of SR and its read of DR
    (board review D9): that read clears RXNE but not ORE, and RXNEIE raises the interrupt
    on ORE too. The handler must clear ORE (SR then DR): left set, the line never drops,
    the handler runs again at once above the control interrupt until the watchdog resets
    the chip."""
    t = Twin(elf)
    rtt = RttReader(t, elf, log_path)
    t.run(0.15, poll=rtt.poll)
    u0, c0 = t.entries.get(USART2_EXC, 0), t.entries.get(TIM4_EXC, 0)
    t.usart2.race_after_sr = True
    t.usart2.send(b"\x00")
    t.run(0.25, poll=rtt.poll)
    rtt.poll()
    rtt.close()
    out = []
    raced = not t.usart2.race_after_sr
    out.append(check("the race happened (ORE set after the SR read)", raced, True, raced))
    resets = [hex(f) for _, f in t.resets[1:]]
    out.append(check("resets after the overrun", resets or "none", "none", not resets))
    ore = bool(t.usart2["SR"] & 0x8)
    out.append(check("ORE at the end", ore, False, not ore))
    uart = t.entries.get(USART2_EXC, 0) - u0
    out.append(check("USART2 interrupts in the 0.1 s after", uart, f"< {STORM_ENTRIES}", uart < STORM_ENTRIES))
    control = t.entries.get(TIM4_EXC, 0) - c0
    expected = 0.1 * CONTROL_HZ
    out.append(check("control interrupts in the 0.1 s after", control, f"{expected:.0f} ± 1 %",
                     abs(control - expected) <= 0.01 * expected + 1))
    return out, {"machine_s": 0.25}


# the registers a fault handler's outputs-off stores write (firmware board/shutdown.rs)
TIM1_BDTR = 0x4001_0044
GPIOD_BSRR = 0x4002_0C18
BDTR_MOE = 1 << 15
# the drive enables (PD0-2) and brakes (PD4-6): the pins the stores drive low
OFF_PINS = 0b111_0111
# the control interrupt is entered this long after power-on before a fault is injected
FAULT_AT_S = 0.15
# instructions into the control interrupt at which the injected faults happen (the
# servo step is under way: about 1,400 instructions a period at rest)
FAULT_AFTER_INSNS = 300
# the outputs-off stores are the handler's first instructions: well under a microsecond
OFF_STORES_BOUND_US = 1.0
# after the fault: the watchdog's timeout, the reboot (0.11 s) and some periods
FAULT_RUN_S = 0.4


def _fault_scenario(elf, log_path, inject, logged, hard=True):
    """Power on, inject a fault into the control interrupt at FAULT_AT_S (`inject(twin)`,
    called at that interrupt's entry), and check what the board's fault path promises:
    the HardFault or panic handler makes the outputs-off stores at once (TIM1 MOE off,
    every drive enable and brake low), nothing is driven active, the firmware stops
    feeding the IWDG, which resets the chip within its timeout, and it boots again with
    `reset cause: watchdog`; the log names the fault (`logged`)."""
    t = Twin(elf)
    rtt = RttReader(t, elf, log_path)
    t.run(FAULT_AT_S, poll=rtt.poll)
    t.trace_regs = {TIM1_BDTR, GPIOD_BSRR}
    injected = []

    def at_entry(tw):
        injected.append(tw.now_s())
        inject(tw)

    t.on_enter[TIM4_EXC] = at_entry
    faults0 = len(t.faults)
    t.run(FAULT_RUN_S, poll=rtt.poll)
    rtt.poll()
    lines = rtt.close()
    out = []
    faults = t.faults[faults0:]
    if hard:
        fault_s = faults[0][0] if faults else None
    else:
        fault_s = t.panicked_at_s
    out.append(check("fault injected in the control interrupt", bool(injected), True, bool(injected)))
    out.extend(_outputs_off_after(t, fault_s, "HardFault taken" if hard else "panic entered"))
    out.extend(_one_iwdg_reset(t, fault_s, "resets after the fault", "IWDG reset after the fault, ms"))
    out.append(_no_output_active(t))
    named = [l for l in lines if logged in l]
    out.append(check(f"log names the fault ({logged!r})", len(named), 1, len(named) == 1))
    cause = [l.split("reset cause: ")[1] for l in lines if "reset cause: " in l]
    out.append(check("reset cause logged at each boot", cause, ["power-on", "watchdog"], cause == ["power-on", "watchdog"]))
    after = t.entries.get(TIM4_EXC, 0) - t.entries_at_reset.get(TIM4_EXC, 0)
    out.append(check("control interrupts after the reboot", after, "> 0", after > 0))
    info = {"machine_s": FAULT_RUN_S, "fault_at_ms": None if fault_s is None else round(fault_s * 1e3, 4),
            "faults": [(round(ts * 1e3, 4), what, hex(pc)) for ts, what, pc in faults]}
    return out, info, t


def _outputs_off_after(t, fault_s, taken):
    """The first TIM1 BDTR and GPIOD BSRR stores after the fault: MOE off, every enable
    and brake reset, each within OFF_STORES_BOUND_US."""
    out = [check(taken, fault_s is not None, True, fault_s is not None)]
    if fault_s is None:
        return out
    for reg, name, ok in ((TIM1_BDTR, "TIM1 BDTR store with MOE off", lambda v: not v & BDTR_MOE),
                          (GPIOD_BSRR, "GPIOD BSRR store resetting every enable and brake", lambda v: (v >> 16) & OFF_PINS == OFF_PINS)):
        after = [(ts, v) for ts, a, v in t.trace if a == reg and ts >= fault_s]
        first = after[0] if after else None
        us = None if first is None else round((first[0] - fault_s) * 1e6, 3)
        good = first is not None and ok(first[1]) and us <= OFF_STORES_BOUND_US
        out.append(check(f"{name} after the fault, µs", us, f"<= {OFF_STORES_BOUND_US}", good))
    return out


def hardfault(elf, log_path):
    """An imprecise bus fault (a buffered store that errors), escalated to HardFault,
    FAULT_AFTER_INSNS instructions into a control interrupt."""

    def inject(tw):
        tw.call_after_insns = (FAULT_AFTER_INSNS, lambda tw: tw.hard_fault(tw.pc, "injected: an imprecise bus fault"))

    out, info, _ = _fault_scenario(elf, log_path, inject, "HardFault at pc=")
    return out, info


# where the panic scenario builds its core::panic::Location: the painted, never-reached
# bottom of the stack (the deepest stack is 18 of its 40 KiB)
PANIC_LOCATION_OFFSET = 0x100
PANIC_FILE = b"injected-by-the-board-twin.rs"


def panic(elf, log_path):
    """A panic in the control interrupt: FAULT_AFTER_INSNS instructions in, the core calls
    the release ELF's own `core::panicking::panic_const::panic_const_div_by_zero` (what a
    division by zero there compiles to; the firmware has no path to it, check-no-panic)
    with a `Location` the twin writes into unused RAM."""

    def inject(tw):
        def call_panic(tw):
            names = [n for n in tw.symbols if "panic_const_div_by_zero" in n]
            if not names:
                raise TwinError("the ELF has no panic_const_div_by_zero")
            loc = tw.symbols["_stack_end"] + PANIC_LOCATION_OFFSET
            file_at = loc + 16
            # Location { file: &str (pointer, length), line, col }
            tw.uc.mem_write(loc, struct.pack("<4I", file_at, len(PANIC_FILE), 1, 1) + PANIC_FILE)
            tw.uc.reg_write(UC_ARM_REG_R0, loc)
            tw.uc.reg_write(UC_ARM_REG_LR, tw.pc | 1)
            tw.pc = tw.symbols[names[0]] & ~1
            tw.panicked_at_s = tw.now_s()

        tw.call_after_insns = (FAULT_AFTER_INSNS, call_panic)

    out, info, _ = _fault_scenario(elf, log_path, inject, f"panic: outputs off: panicked at {PANIC_FILE.decode()}:1:1", hard=False)
    return out, info


# the stack pointer a stack overflow scenario leaves the control interrupt's handler
# with: this far above the stack's bottom, less than its first push
OVERFLOW_SP_ABOVE_BOTTOM = 16


def stack_overflow(elf, log_path):
    """The stack has grown to within OVERFLOW_SP_ABOVE_BOTTOM bytes of its bottom when a
    control interrupt comes: its handler's first pushes go below it. With the stack at the
    bottom of SRAM that is a bus fault (the reserved region below SRAM): a HardFault with
    the stacking lost, the outputs off, a reset; with the statics below the stack they
    would be overwritten and nothing would notice."""
    t_syms = {}

    def inject(tw):
        t_syms.update(bottom=tw.symbols["_stack_end"])
        tw.uc.reg_write(UC_ARM_REG_SP, tw.symbols["_stack_end"] + OVERFLOW_SP_ABOVE_BOTTOM)

    out, info, t = _fault_scenario(elf, log_path, inject, "stack overflow (frame at")
    bottom = t.symbols.get("_stack_end")
    out.insert(0, check("RAM below the stack's bottom", hex(bottom), f"none (0x{SRAM_BASE:08x})", bottom == SRAM_BASE))
    stacked = [f for _, _, f in t.stack_faults]
    out.insert(1, check("HardFault entry stacked below SRAM (BFSR.STKERR)", [hex(f) for f in stacked], "one frame", len(stacked) == 1))
    return out, info


def board_config(elf, log_path):
    """A configuration that does not take: GPIOA's AFRH ignores every write (as on a port
    whose configuration is locked), so PA15 (X encoder A) keeps its reset function. The
    firmware's boot self-check (the register table, firmware/src/board/self_check.rs) must
    name that field and latch `board_config`; the outputs stay off."""
    t = Twin(elf)
    t.frozen_regs.add(("GPIOA", "AFRH"))
    rtt = RttReader(t, elf, log_path)
    t.run(BOOT_RUN_S, poll=rtt.poll)
    rtt.poll()
    lines = rtt.close()
    out = []
    named = [l for l in lines if "board configuration: 0x40020024 bits 28+4 = 0x0, expected 0x1 (PA15 af" in l and "board_config fault latched" in l]
    out.append(check("the self-check names GPIOA AFRH's PA15 field", len(named), 1, len(named) == 1))
    ok_lines = [l for l in lines if "register fields as expected" in l]
    out.append(check("no 'as expected' line", len(ok_lines), 0, not ok_lines))
    out.append(_no_output_active(t))
    out.append(check("HardFaults", len(t.faults), 0, not t.faults))
    return out, {"machine_s": BOOT_RUN_S}


# the encoders' index pulses: each axis pushed through several revolutions by an external
# force while the board is disarmed (its servo checks the index in every state): (axis,
# mm/s², s), 27–37 mm each (5 to 7 pulses), at rest again by the end. X and Y have no
# brake; Z's holds it until a hard push breaks it away (Z falls through its 16-bit
# counter's negative counts)
INDEX_PUSH = (("x", 3000.0, 0.1), ("y", -1800.0, 0.1), ("z", -40000.0, 0.025))
INDEX_PUSH_AT_S = 0.15
INDEX_RUN_S = 0.8
# glitches injected after the axis' first index pulse (before its second): X's 3 counts
# are within `safety.index_max_correction_counts` (16): corrected at the next pulse; Y's
# 40 are not: `encoder_index` on y. Z gets none.
INDEX_GLITCH = {"x": 3, "y": 40}
INDEX_COUNTS_PER_MM = 1600
# exception number of EXTI1 (IRQ 7): the firmware's y_index task
EXTI1_EXC = 16 + 7


def index(elf, log_path):
    """The encoders' index pulses from the closed loop's plant (`twin-plant`, controller-
    core's sim world: one pulse per 8000 counts): the board, disarmed, its axes pushed
    through several revolutions. X's and Z's pulses are captured by TIM2/TIM3 channel 3
    (CCR3 latches CNT), Y's raise EXTI1, whose task reads TIM5_CNT; each capture must be
    the count the timer holds at the pulse, exactly, and reach the servo's index check:
    a glitch of 3 counts on X is corrected at the next pulse (X's position then agrees
    with the plant's count less the glitch), one of 40 on Y faults `encoder_index`, Z
    (no glitch) ends where the plant says."""
    from .plant import Plant
    t = Twin(elf)
    rtt = RttReader(t, elf, log_path)
    t.plant = Plant(t)
    try:
        t.run(INDEX_PUSH_AT_S, poll=rtt.poll)
        for a, acc, for_s in INDEX_PUSH:
            t.plant.inject({"external_accel": {"axis": a, "accel_mm_s2": acc, "for_s": for_s}})
        glitched = {}
        while t.t_s < INDEX_RUN_S:
            t.run(min(INDEX_RUN_S, t.t_s + 1e-3), poll=rtt.poll)
            for a, n in INDEX_GLITCH.items():
                pulses = [p for p in t.index_log if p[1] == a]
                if a not in glitched and pulses:
                    t.plant.inject({"encoder_jump": {"axis": a, "counts": n}})
                    glitched[a] = (t.t_s, len(pulses))
        counts = list(t.plant.counts)
        rtt.poll()
    finally:
        t.plant.close()
    lines = rtt.close()
    out = []
    period_s = 1 / CONTROL_HZ
    for i, a in enumerate(("x", "y", "z")):
        pulses = [p for p in t.index_log if p[1] == a]
        out.append(check(f"{a}: index pulses from the plant", len(pulses), ">= 3", len(pulses) >= 3))
        expected = [p[3] for p in pulses]
        timer = {"x": "TIM2", "y": "TIM5", "z": "TIM3"}[a]
        if a == "y":
            # EXTI1's task reads TIM5_CNT while the pulse is up
            reads = [v for _, tm, v, exc in t.cnt_reads_in_pulse if tm == timer and exc == EXTI1_EXC]
            out.append(check("y: TIM5_CNT read by the EXTI1 task at each pulse = the count there",
                             _firsts(reads), _firsts(expected), reads == expected))
            edges = [e for e in t.exti.edges if e[1] == 1 and e[2]]
            out.append(check("y: EXTI1 rising edges (pending bits set)", len(edges), len(pulses), len(edges) == len(pulses)))
        else:
            caps = [c for c in t.captures if c[1] == timer and c[2] == 2]
            got = [c[3] for c in caps]
            out.append(check(f"{a}: {timer}_CCR3 captures at each pulse = CNT there", _firsts(got), _firsts(expected),
                             got == expected))
            over = [c for c in caps if c[4]]
            out.append(check(f"{a}: {timer} overcaptures (CC3OF)", len(over), 0, not over))
            reads = [r for r in t.ccr_reads if r[1] == timer and r[2] == 2 and r[4]]
            late = [round((r[0] - c[0]) * 1e6, 3) for r, c in zip(reads, caps)]
            out.append(check(f"{a}: {timer}_CCR3 read by the control interrupt, each capture once, µs after it",
                             _firsts(late), f"{len(caps)} reads, each < {period_s * 1e6:.0f} µs",
                             [r[3] for r in reads] == got and all(0 <= d < period_s * 1e6 for d in late)))
        pos = _last_pos(lines)
        n = None if pos is None else round(pos[i] * INDEX_COUNTS_PER_MM)
        if a == "x":
            want, what = counts[i] - INDEX_GLITCH["x"], "the plant's count less the glitch (corrected)"
        else:
            want, what = counts[i], "the plant's count"
        out.append(check(f"{a}: position at rest, counts (the firmware's telemetry)", n, f"{want}: {what}", n == want))
    # the servo's fault records: kind, axis and the phase error it measured, counts
    faults = []
    for l in lines:
        if "FAULT, outputs off: " in l:
            m = re.search(r"kind: (\w+), axis: (?:Some\()?(\w+)\)?\s*\}, period: \d+, value: ([-\d.]+)", l)
            faults.append((m.group(1), m.group(2), float(m.group(3))) if m else l)
    want = [("EncoderIndex", "Y", float(INDEX_GLITCH["y"]))]
    out.append(check("faults logged (kind, axis, the index check's error in counts)", faults, want, faults == want))
    levels = {a: t.gpio[p[0]].level(p[1]) for a, p in board.INDEX.items()}
    out.append(check("index pins at the end (IDR)", levels, "all low", not any(levels.values())))
    info = {"machine_s": INDEX_RUN_S, "glitches_at_s": {a: round(g[0], 4) for a, g in glitched.items()},
            "pulses": len(t.index_log), "counts": counts}
    return out, info


def _firsts(v, n=4):
    return v if len(v) <= n else v[:n] + [f"… {len(v)} in all"]


def _last_pos(lines):
    """The axes' positions, mm, of the last telemetry line."""
    for l in reversed(lines):
        if " pos=[" in l:
            return [float(x) for x in l.split(" pos=[")[1].split("]")[0].split(",")]
    return None


ALL = {"boot": boot, "board_config": board_config, "watchdog": watchdog, "uart_overrun": uart_overrun,
       "hardfault": hardfault, "panic": panic, "stack_overflow": stack_overflow, "index": index}
