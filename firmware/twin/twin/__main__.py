"""`firmware/twin/run [--elf ELF] [--scenario NAME] [--json OUT]`: run the board twin's
scenarios against the release firmware ELF; exit 1 if a check fails, 2 on bad input."""

import argparse
import json
import os
import sys
import time

from .regs import TwinError
from . import scenarios


def default_elf():
    target = os.environ.get("CARGO_TARGET_DIR", "target")
    return os.path.join(target, "thumbv7em-none-eabihf", "release", "firmware")


def main(argv=None):
    ap = argparse.ArgumentParser(prog="firmware/twin/run", description=__doc__)
    ap.add_argument("--elf", default=default_elf(), help="the firmware ELF (default: cargo fw's)")
    ap.add_argument("--scenario", action="append", choices=sorted(scenarios.ALL),
                    help="scenario to run (repeatable; default: all)")
    ap.add_argument("--json", help="write the checks as JSON here")
    ap.add_argument("--serve", metavar="PTY", help="instead of the scenarios: boot and serve USART2 at this pseudo-terminal")
    ap.add_argument("--flash", metavar="FILE", help="--serve: the settings store's sectors and the option bytes, loaded at power-on (if the file exists) and written back when the twin stops")
    ap.add_argument("--seconds", type=float, default=600.0, help="machine seconds --serve runs (default 600)")
    ap.add_argument("--log-dir", default=os.path.join(os.environ.get("CARGO_TARGET_DIR", "target"), "twin"),
                    help="where the decoded defmt logs go")
    a = ap.parse_args(argv)
    if not os.path.isfile(a.elf):
        print(f"--elf {a.elf}: not a file (build it with `cargo fw`)", file=sys.stderr)
        return 2
    os.makedirs(a.log_dir, exist_ok=True)
    if a.serve:
        if not (a.seconds > 0 and a.seconds < 1e6):
            print(f"--seconds {a.seconds}: must be a positive number of machine seconds", file=sys.stderr)
            return 2
        from .serve import serve
        t, wall = serve(a.elf, a.serve, a.seconds, os.path.join(a.log_dir, "serve.log"), a.flash)
        t.flash._cache_check()
        print(f"twin: {t.flash.summary()}")
        print(f"twin: served {t.t_s:.3f} machine s in {wall:.1f} s")
        return 0
    names = a.scenario or sorted(scenarios.ALL)
    report = []
    failed = 0
    for name in names:
        w = time.time()
        try:
            checks, info = scenarios.ALL[name](a.elf, os.path.join(a.log_dir, f"{name}.log"))
        except TwinError as e:
            checks, info = [{"check": "the run", "value": str(e), "bound": "no twin error", "pass": False}], {}
        info["wall_s"] = round(time.time() - w, 2)
        for c in checks:
            mark = "ok  " if c["pass"] else "FAIL"
            print(f"{mark} {name}: {c['check']}: {c['value']} (bound: {c['bound']})")
            failed += not c["pass"]
        print(f"     {name}: " + ", ".join(f"{k} {v}" for k, v in info.items()))
        report.append({"scenario": name, "checks": checks, **info})
    if a.json:
        with open(a.json, "w") as f:
            json.dump(report, f, indent=1)
    print(f"{len(names)} scenario(s), {failed} failed check(s)")
    return 1 if failed else 0


sys.exit(main())
