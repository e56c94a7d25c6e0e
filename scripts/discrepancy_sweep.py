#!/usr/bin/env python3
"""Every vocabulary effect concealed on every target, not only where the proof grid puts it.

The proof grid (tests/discrepancy.rs) conceals each effect on the one target where it shows
best. A user (and an independent check) will point the command at other columns too, so this
sweep conceals each of the ten effects on each of 16 measured and reference columns, through
the CLI, and sorts the outcomes by how large the concealed effect is on that column:

- absent (its RMS below 0.05 of the target's noise σ: the effect does not reach the column):
  the pair must be `consistent`; anything named is a false discovery;
- large (RMS at least 3 σ): the concealed effect should be named first;
- in between: listed, not scored (a small effect may or may not be found).

Usage (after `cargo build --release`; about 3 minutes on 2 cores):

    python3 scripts/discrepancy_sweep.py [OUT_DIR] [SEEDS]      (default /tmp/sweep 301,302)
"""
import concurrent.futures
import csv
import json
import math
import os
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BINARY = os.path.join(ROOT, "target", "release", "servosight")
EFFECTS = ["ambient_temperature", "thermal_inertia", "speed_dependent_cooling",
           "lubricant_viscosity", "copper_loss", "coolant", "coulomb_reversal",
           "position_dependent", "signal_delay", "sensor_offset_drift"]
TARGETS = ["S.stator_temp_C", "X.stator_temp_C", "S.torque_Nm", "X.torque_Nm", "S.current_A",
           "X.current_A", "ref.S.front_bearing_temp_C", "ref.S.rear_bearing_temp_C",
           "ref.S.housing_temp_C", "ref.S.elongation_um", "ref.X.motor_flange_temp_C",
           "ref.X.front_bearing_temp_C", "ref.X.back_bearing_temp_C", "ref.X.nut_temp_C",
           "ref.X.screw_temp_C", "ref.X.straightness_v_um#3"]
# The measurement effects have no size by default: the real run gets one.
REAL_ONLY = {"signal_delay": ["measurement.delay_s=12"],
             "sensor_offset_drift": ["measurement.offset=1.0", "measurement.drift_per_hour=0.8"]}
HOURS = "5"
ABSENT, LARGE = 0.05, 3.0


def simulate(path, seed, without=None, noise=None, settings=()):
    if os.path.exists(path):
        return
    cmd = [BINARY, "simulate", "--scenario", "production", "--hours", HOURS, "--seed", str(seed),
           "-o", path]
    if without:
        cmd += ["--without", without]
    if noise is not None:
        cmd += ["--noise", str(noise)]
    for s in settings:
        cmd += ["--set", s]
    subprocess.run(cmd, check=True, capture_output=True)


def column(path, name):
    with open(path) as f:
        rows = csv.reader(line for line in f if not line.startswith("#"))
        header = next(rows)
        i = header.index(name)
        return [float(r[i]) for r in rows]


def rms(values):
    mean = sum(values) / len(values)
    return math.sqrt(sum((v - mean) ** 2 for v in values) / len(values))


def one_case(out, effect, target, seed):
    d = os.path.join(out, f"{effect}-{seed}")
    os.makedirs(d, exist_ok=True)
    extra = REAL_ONLY.get(effect, [])
    simulate(f"{d}/sim.csv", seed, without=effect, noise=0)
    simulate(f"{d}/real.csv", seed, settings=extra)
    simulate(f"{d}/clean.csv", seed, noise=0, settings=extra)
    report_path = os.path.join(d, target.replace("#", "_") + ".json")
    run = subprocess.run([BINARY, "discrepancy", "--sim", f"{d}/sim.csv", "--real",
                          f"{d}/real.csv", "--target", target, "--json", report_path],
                         capture_output=True, text=True)
    if run.returncode != 0:
        return effect, target, seed, None, run.stderr.strip(), 0.0
    report = json.load(open(report_path))
    sim, real, clean = (column(f"{d}/{n}.csv", target) for n in ("sim", "real", "clean"))
    effect_rms = rms([c - s for c, s in zip(clean, sim)])
    # The instrument's white noise, from successive differences of (real − clean).
    noise = [r - c for r, c in zip(real, clean)]
    sigma = math.sqrt(sum((b - a) ** 2 for a, b in zip(noise, noise[1:])) / (2 * len(noise) - 2))
    named = [f["physics"] for f in report["findings"]]
    return effect, target, seed, report["verdict"], named, effect_rms / max(sigma, 1e-12)


def main():
    out = sys.argv[1] if len(sys.argv) > 1 else "/tmp/sweep"
    seeds = [int(s) for s in (sys.argv[2] if len(sys.argv) > 2 else "301,302").split(",")]
    cases = [(e, t, s) for e in EFFECTS for t in TARGETS for s in seeds]
    absent = [0, 0]
    large = [0, 0]
    print("| outcome | concealed | target | seed | effect RMS / σ | verdict | named |")
    print("|---|---|---|---|---|---|---|")
    with concurrent.futures.ThreadPoolExecutor(2) as pool:
        for effect, target, seed, verdict, named, size in pool.map(
                lambda c: one_case(out, *c), cases):
            if verdict is None:
                print(f"| error | `{effect}` | `{target}` | {seed} | | | {named} |")
                continue
            if size < ABSENT:
                absent[0] += 1
                ok = not named
                absent[1] += ok
                outcome = "consistent" if ok else "**false discovery**"
            elif size >= LARGE:
                large[0] += 1
                ok = bool(named) and named[0] == effect
                large[1] += ok
                outcome = "named first" if ok else "**missed**"
            else:
                outcome = "small"
            if outcome != "consistent":
                print(f"| {outcome} | `{effect}` | `{target}` | {seed} | {size:.2f} | {verdict} "
                      f"| {', '.join(named) or '—'} |")
    print(f"\nabsent effects (RMS < {ABSENT} σ): {absent[1]}/{absent[0]} consistent")
    print(f"large effects (RMS ≥ {LARGE} σ): {large[1]}/{large[0]} named first")


if __name__ == "__main__":
    main()
