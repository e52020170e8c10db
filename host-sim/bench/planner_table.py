#!/usr/bin/env python3
"""The benchmark program set through `cargo sim gcode`, as one markdown table.

Writes the set with `host-sim bench-programs` (`--huge`: the 170,000-line program too),
runs every program with `host-sim gcode … --json`, and prints, per program: moves and the
segments the planner got (after path compression: arcs and lines merged), path length,
machine time, the time bound and the ratio to it, the feed ratio (over the achievable
feed), the largest deviation of the executed reference from the programmed path against
the program's tolerance, tolerance violations, the simulated machine's contour error, and
the host's compute times. Extra `--set KEY=VALUE` are passed to every run.

    cargo build -p host-sim --release
    python3 host-sim/bench/planner_table.py [--huge] [--out DIR] [--json FILE] [--set K=V]

Needs only Python 3 (no packages). The release binary is target/release/host-sim.
"""

import argparse
import json
import os
import subprocess
import sys

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
BIN = os.path.join(ROOT, "target", "release", "host-sim")
ORDER = [
    "circle_chords",
    "collinear_tiny",
    "surfacing_3d",
    "spiral_arcs",
    "zigzag",
    "dense_curve_3d",
    "huge",
]


def run(args):
    return subprocess.run(args, cwd=ROOT, check=False, capture_output=True, text=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--huge", action="store_true", help="include the 170,000-line program")
    ap.add_argument("--out", default=os.path.join(ROOT, "out", "bench"), help="where the programs and JSON go")
    ap.add_argument("--json", help="all reports as one JSON file")
    ap.add_argument("--set", action="append", default=[], help="a settings override for every run")
    a = ap.parse_args()
    if not os.path.exists(BIN):
        sys.exit("build first: cargo build -p host-sim --release")
    os.makedirs(a.out, exist_ok=True)
    gen = [BIN, "bench-programs", "--out", a.out] + (["--huge"] if a.huge else [])
    r = run(gen)
    if r.returncode != 0:
        sys.exit("bench-programs failed: " + r.stderr)
    reports = {}
    for name in ORDER:
        prog = os.path.join(a.out, name + ".nc")
        if not os.path.exists(prog):
            continue
        out = os.path.join(a.out, name + ".json")
        cmd = [BIN, "gcode", prog, "--no-plots", "--json", out]
        for s in a.set:
            cmd += ["--set", s]
        r = run(cmd)
        if not os.path.exists(out):
            sys.exit(f"{name}: no report ({r.stderr.strip()})")
        with open(out) as f:
            reports[name] = json.load(f)
    print(
        "| program | moves | segments (arcs, lines merged) | path mm | duration s | "
        "bound s | ratio | feed ratio | deviation µm (tolerance) | violations | "
        "contour max / RMS µm | parse + compress s | sim speed |"
    )
    print("| --- " * 13 + "|")
    for name, d in reports.items():
        c = d["compression"]
        comp = d["compute"]
        print(
            f"| `{name}` | {d['moves']} | {d['segments']} ({c['arcs']}, {c['lines']}) | "
            f"{d['path_length_mm']:.1f} | {d['duration_s']:.3f} | {d['time_bound_s']:.3f} | "
            f"{d['time_ratio_to_bound']:.3f} | {d['feed_ratio_mean']:.3f} | "
            f"{d['corner_deviation_max_mm'] * 1e3:.2f} ({d['tolerance_mm'] * 1e3:g}) | "
            f"{d['tolerance_violations']} | "
            f"{d['contour_max_mm'] * 1e3:.2f} / {d['contour_rms_mm'] * 1e3:.2f} | "
            f"{comp['parse_s'] + comp['compress_s']:.2f} | {d['realtime_ratio']:.0f}x |"
        )
    if a.json:
        with open(a.json, "w") as f:
            json.dump(reports, f, indent=1)


if __name__ == "__main__":
    main()
