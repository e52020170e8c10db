"""The board's register configuration after init, as data (`expect.toml` beside this
package), checked against the twin after boot. A mismatch fails the check, except for
an entry that names the known defect it records (`defect = "..."`): that one must still
mismatch (a fixed defect whose entry stays fails too, so the table stays true)."""

import os
import tomllib


TABLE = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "expect.toml")


def _field(value, spec):
    """`spec` = "bits:lo:width" or a whole register."""
    if isinstance(spec, str) and spec.startswith("bits:"):
        _, lo, width = spec.split(":")
        return value >> int(lo) & ((1 << int(width)) - 1)
    return value


def read(t, periph, reg):
    if periph.startswith("GPIO"):
        return t.gpio[periph[4]][reg]
    if periph.startswith("TIM"):
        return t.tim[periph][reg]
    if periph == "NVIC_IPR":
        return t.scs.priority(16 + int(reg))
    p = {"USART2": t.usart2, "IWDG": t.iwdg, "RCC": t.rcc, "SCB": t.scs, "FLASH": t.flash,
         "SYSCFG": t.syscfg, "EXTI": t.exti}[periph]
    if periph == "FLASH" and reg == "BOR_LEV":
        return p.bor_level()
    return p[reg]


def check_after_boot(t, control_hz):
    with open(TABLE, "rb") as f:
        table = tomllib.load(f)
    out = []
    for e in table["register"]:
        v = _field(read(t, e["periph"], e["reg"]), e.get("field"))
        want = e["value"] if "value" in e else e["tick_clock_hz"] // control_hz - 1
        e = {**e, "value": want}
        ok = v == want
        name = f"{e['periph']}.{e['reg']}{'[' + e['field'] + ']' if 'field' in e else ''} ({e['what']})"
        if "defect" in e:
            out.append({"check": name, "value": hex(v), "bound": f"{hex(e['value'])}: known defect, {e['defect']}",
                        "pass": not ok, "defect": e["defect"]})
        else:
            out.append({"check": name, "value": hex(v), "bound": hex(e["value"]), "pass": ok})
    for pin in table["pin"]:
        port, n = pin["pin"][1], int(pin["pin"][2:])
        g = t.gpio[port]
        got = {
            "mode": g.mode(n),
            "af": g.af(n),
            "pull": g.pull(n),
            "otype": g["OTYPER"] >> n & 1,
        }
        want = {k: pin[k] for k in ("mode", "af", "pull", "otype") if k in pin}
        diff = {k: got[k] for k in want if got[k] != want[k]}
        out.append({"check": f"{pin['pin']} ({pin['what']})", "value": diff or "as expected", "bound": want, "pass": not diff})
    return out
