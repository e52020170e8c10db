#!/usr/bin/env python3
"""Rest-to-rest lines: the planner's time against ruckig's time-optimal move.

For every rest-to-rest case of `host_sim::bench_programs` (lengths 0.1-300 mm along X, at
45 degrees in XY and along the space diagonal (1, -1, 1)/sqrt(3), those that stay inside
the default machine's travel from the origin), this script

1. runs the planner on the line on the simulated machine:
   `host-sim gcode r2r_<dir>_<len>.nc --json OUT --no-plots --set planner.servo_reserve=R`
   and takes `duration_s` (control periods of 0.1 ms from `Run` until the planner is idle
   again: the machine at rest at the end point);
2. computes ruckig's time-optimal duration of the same line with the per-axis limits of
   that run (the JSON's `limits`: velocity, acceleration, jerk), the jerk times (1 - R)
   (the planner leaves R of each axis' jerk to the servo along the path), the program's
   feed as a limit on the path speed (each axis' velocity limit at most feed * |u_axis|:
   F15000 = 250 mm/s binds before the axes at 45 degrees and along the diagonal), with
   `Synchronization.Phase` so that the axes stay on the straight line; the unsynchronized
   (`Synchronization.No`: every axis on its own, the slowest one's time) and the
   time-synchronized durations are printed for reference;
3. reports planner, ruckig, their ratio and the difference in control periods as a
   markdown table and a JSON file.

Two passes: R = 0 (the planner's full per-axis limits against ruckig with the same ones)
and R = the factory value (`gantry --sim --factory settings get planner.servo_reserve`,
controller-core's GANTRY_PLANNER.servo_reserve, 0.75).

The end point is read back from the program (4 decimals: 0.1 mm along the diagonal is
0.09994 mm), so both sides move the same displacement. The planner's duration is a whole
number of periods (up to one period, 0.1 ms, above the continuous time).

Needs Python 3 and `pip install ruckig` (0.19 tested); CI does not run it. Build first:
`cargo build -p host-sim --release`. Usage (from the repository root):

    python3 host-sim/bench/ruckig_lines.py [--json out/bench/ruckig_lines.json]
        [--markdown FILE] [--bin-dir target/release] [--programs DIR]
"""

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile

try:
    from ruckig import InputParameter, Result, Ruckig, Synchronization, Trajectory
except ImportError:  # pragma: no cover - a message instead of a traceback
    sys.exit("ruckig_lines.py needs ruckig: pip install ruckig")

AXES = 3
# The cases' program names: r2r_<dir>_<len>.nc as `host-sim bench-programs` writes them.
PREFIX = "r2r_"
DIRECTIONS = ["x", "xy", "xyz"]
# The default machine's control period (10 kHz), s: `duration_s` is a whole number of them.
PERIOD_S = 1e-4
# Words of a G-code line this script reads back.
AXIS_WORDS = "XYZ"


def run(cmd):
    """Run a command; its stdout, or exit with its stderr."""
    p = subprocess.run(cmd, capture_output=True, text=True)
    if p.returncode != 0:
        sys.exit(f"{' '.join(cmd)} failed ({p.returncode}):\n{p.stderr}{p.stdout}")
    return p.stdout


def factory_reserve(bin_dir):
    """planner.servo_reserve of the factory settings, as the gantry CLI reports it."""
    gantry = os.path.join(bin_dir, "gantry")
    out = run([gantry, "--sim", "--factory", "settings", "get", "planner.servo_reserve"])
    return float(out.strip().split()[-1])


def read_line(path):
    """(end point mm, feed mm/min) of the program's one G1 line (from the origin, G21)."""
    end, feed = None, None
    with open(path) as f:
        for raw in f:
            line = raw.split("(")[0].strip()
            words = line.split()
            if not words or words[0] != "G1":
                continue
            end = [0.0] * AXES
            for w in words[1:]:
                if w[0] in AXIS_WORDS:
                    end[AXIS_WORDS.index(w[0])] = float(w[1:])
                elif w[0] == "F":
                    feed = float(w[1:])
    if end is None or feed is None:
        sys.exit(f"{path}: no G1 line with a feed")
    return end, feed


def ruckig_duration(end, limits, jerk_scale, feed_mm_s, sync):
    """Time-optimal duration (s) from rest at the origin to rest at `end`."""
    length = math.sqrt(sum(e * e for e in end))
    inp = InputParameter(AXES)
    inp.current_position = [0.0] * AXES
    inp.current_velocity = [0.0] * AXES
    inp.current_acceleration = [0.0] * AXES
    inp.target_position = list(end)
    inp.target_velocity = [0.0] * AXES
    inp.target_acceleration = [0.0] * AXES
    vel = []
    for a in range(AXES):
        u = abs(end[a]) / length
        # the feed bounds the path speed: on the line, axis a moves at |u_a| of it
        vel.append(min(limits["vel"][a], feed_mm_s * u) if u > 0 else limits["vel"][a])
    inp.max_velocity = vel
    inp.max_acceleration = list(limits["acc"])
    inp.max_jerk = [j * jerk_scale for j in limits["jerk"]]
    inp.synchronization = sync
    otg = Ruckig(AXES)
    traj = Trajectory(AXES)
    res = otg.calculate(inp, traj)
    if res not in (Result.Working, Result.Finished):
        sys.exit(f"ruckig failed on {end}: {res}")
    return traj.duration


def planner_run(bin_dir, program, reserve, out_dir):
    """The report of `host-sim gcode` on `program` with planner.servo_reserve = reserve."""
    host_sim = os.path.join(bin_dir, "host-sim")
    stem = os.path.splitext(os.path.basename(program))[0]
    out = os.path.join(out_dir, f"{stem}_R{reserve}.json")
    run([host_sim, "gcode", program, "--json", out, "--no-plots",
         "--set", f"planner.servo_reserve={reserve}"])
    with open(out) as f:
        rep = json.load(f)
    if rep["status"] != "completed":
        sys.exit(f"{program}: {rep['status']} {rep.get('error') or rep.get('fault')}")
    return rep


def cases(programs):
    """(name, dir, nominal length) of every r2r program in `programs`, in table order."""
    found = []
    for name in os.listdir(programs):
        if not (name.startswith(PREFIX) and name.endswith(".nc")):
            continue
        d, l = name[len(PREFIX):-3].split("_", 1)
        found.append((name, d, float(l)))
    found.sort(key=lambda c: (DIRECTIONS.index(c[1]), c[2]))
    return found


def one_pass(bin_dir, programs, reserve, out_dir):
    rows = []
    for name, d, nominal in cases(programs):
        path = os.path.join(programs, name)
        end, feed_mm_min = read_line(path)
        rep = planner_run(bin_dir, path, reserve, out_dir)
        limits = rep["limits"]
        scale = 1.0 - reserve
        feed = feed_mm_min / 60.0
        phase = ruckig_duration(end, limits, scale, feed, Synchronization.Phase)
        time_sync = ruckig_duration(end, limits, scale, feed, Synchronization.Time)
        no_sync = ruckig_duration(end, limits, scale, feed, Synchronization.No)
        planner = rep["duration_s"]
        rows.append({
            "program": name[:-3],
            "direction": d,
            "length_mm": math.sqrt(sum(e * e for e in end)),
            "nominal_length_mm": nominal,
            "servo_reserve": reserve,
            "planner_duration_s": planner,
            "planner_periods": round(planner / PERIOD_S),
            "ruckig_phase_s": phase,
            "ruckig_time_sync_s": time_sync,
            "ruckig_no_sync_s": no_sync,
            "ratio": planner / phase,
            # the planner's time over ruckig's in control periods
            "excess_periods": (planner - phase) / PERIOD_S,
            "limits": limits,
            "ruckig_jerk_mm_s3": [j * scale for j in limits["jerk"]],
        })
    return rows


def markdown(rows, reserve):
    lines = [
        f"servo_reserve R = {reserve:g} (ruckig's jerk = {1 - reserve:g} x the axis jerk)",
        "",
        "| direction | length mm | planner s | ruckig (phase) s | ratio | excess periods "
        "| ruckig time-sync s | ruckig no-sync s |",
        "| --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for r in rows:
        lines.append(
            f"| {r['direction']} | {r['nominal_length_mm']:g} | {r['planner_duration_s']:.4f} "
            f"| {r['ruckig_phase_s']:.5f} | {r['ratio']:.4f} | {r['excess_periods']:.1f} "
            f"| {r['ruckig_time_sync_s']:.5f} | {r['ruckig_no_sync_s']:.5f} |"
        )
    worst = max(rows, key=lambda r: r["ratio"])
    best = min(rows, key=lambda r: r["ratio"])
    lines.append("")
    lines.append(
        f"ratio {best['ratio']:.4f} ({best['program']}) to {worst['ratio']:.4f} "
        f"({worst['program']})"
    )
    return "\n".join(lines)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--bin-dir", default="target/release",
                    help="where host-sim and gantry are (default target/release)")
    ap.add_argument("--programs",
                    help="a folder written by `host-sim bench-programs` (default: a fresh one)")
    ap.add_argument("--json", default="out/bench/ruckig_lines.json", help="JSON output")
    ap.add_argument("--markdown", help="also write the tables to this file")
    args = ap.parse_args()

    with tempfile.TemporaryDirectory() as tmp:
        programs = args.programs
        if programs is None:
            programs = os.path.join(tmp, "programs")
            run([os.path.join(args.bin_dir, "host-sim"), "bench-programs", "--out", programs])
        factory = factory_reserve(args.bin_dir)
        passes = {}
        for reserve in (0.0, factory):
            passes[f"{reserve:g}"] = one_pass(args.bin_dir, programs, reserve, tmp)

    text = "\n\n".join(markdown(rows, float(r)) for r, rows in passes.items())
    print(text)
    os.makedirs(os.path.dirname(os.path.abspath(args.json)), exist_ok=True)
    with open(args.json, "w") as f:
        json.dump({"factory_servo_reserve": factory, "passes": passes}, f, indent=2)
    print(f"\nJSON: {args.json}")
    if args.markdown:
        with open(args.markdown, "w") as f:
            f.write(text + "\n")


if __name__ == "__main__":
    main()
