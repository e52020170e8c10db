"""Scenarios the board twin runs against the release ELF, each a list of checks with the
measured value and its bound."""

import time

from . import expect
from .machine import Twin
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
    active = sorted({k for _, k, v in t.log if k.split(".")[0] in ("enable", "brake") and v == 1}
                    | {k for _, k, v in t.log if k.startswith("pwm.") and v not in (0, None, 0.0)}
                    | {k for _, k, v in t.log if k == "moe" and v == 1})
    out.append(check("outputs driven active from reset on", active or "none", "none", not active))
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
    errors = [l for l in lines if " ERROR " in l or l.startswith("ERROR")]
    out.append(check("defmt errors", errors or "none", "none", not errors))
    out.extend(expect.check_after_boot(t))
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
    resets = t.resets[1:]
    iwdg = [r for r in resets if r[1] & CSR_IWDGRSTF]
    timeout_s = (t.iwdg["RLR"] + 1) * (4 << t.iwdg["PR"]) / LSI_MIN_HZ if iwdg else None
    out.append(check("resets after the hang", [hex(f) for _, f in resets], "one IWDG reset", len(resets) == 1 and len(iwdg) == 1))
    if iwdg:
        after_ms = (iwdg[0][0] - hang_s) * 1e3
        # the first update the control task misses is at most one period after the hang
        bound_ms = (timeout_s + 1 / CONTROL_HZ) * 1e3
        out.append(check("reset after the last feed, ms", round(after_ms, 3), f"<= {bound_ms:.3f} (RLR at 17 kHz + 1 period)", after_ms <= bound_ms))
    active = sorted({k for _, k, v in t.log if (k.split(".")[0] in ("enable", "brake") or k == "moe") and v == 1}
                    | {k for _, k, v in t.log if k.startswith("pwm.") and v not in (0, None, 0.0)})
    out.append(check("outputs driven active", active or "none", "none", not active))
    after = t.entries.get(TIM4_EXC, 0) - t.entries_at_reset.get(TIM4_EXC, 0)
    out.append(check("control interrupts after the reboot", after, "> 0", after > 0))
    ups = [l for l in lines if "firmware up" in l]
    out.append(check("boots logged", len(ups), 2, len(ups) == 2))
    cause = [l.split("reset cause: ")[1] for l in lines if "reset cause: " in l]
    out.append(check("reset cause logged at each boot", cause, ["power-on", "watchdog"], cause == ["power-on", "watchdog"]))
    bor = [l.split("brown-out reset: ")[1] for l in lines if "brown-out reset: " in l]
    out.append(check("brown-out level kept through the reset", bor[1:], ["2.7 V"], bor[1:] == ["2.7 V"]))
    return out, {"machine_s": 0.6, "hang_at_ms": round(hang_s * 1e3, 3)}


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


ALL = {"boot": boot, "watchdog": watchdog, "uart_overrun": uart_overrun}
