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

With `--pairs` it conceals every pair of the ten effects at once on the same columns and scores
each effect of the pair by its own size there (from the single sweep's runs):

- both large: both must be named (in any order);
- one large, the other absent: the large one must be named and the absent one must not;
- otherwise: listed, not scored.

Either way it lists every finding whose sign (or, for the room, gain) contradicts the physics
it names, read back from the reports' parameters: a cooling that warms, negative I²R heat.

Usage (after `cargo build --release`; about 3 minutes on 2 cores, 12 with `--pairs`, which runs
the single sweep's simulations first if they are missing):

    python3 scripts/discrepancy_sweep.py [--pairs] [OUT_DIR] [SEEDS]   (default /tmp/sweep 301,302)

SERVOSIGHT_BINARY=PATH runs another build of the command (e.g. a copy of the previous one)
on the same recordings; scripts/independent_cases.py takes it too.
"""
import concurrent.futures
import csv
import functools
import itertools
import json
import math
import os
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
# SERVOSIGHT_BINARY runs another build (e.g. a copy of the previous one, to compare on the same
# recordings while the tree is rebuilt).
BINARY = os.environ.get("SERVOSIGHT_BINARY",
                        os.path.join(ROOT, "target", "release", "servosight"))
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
    for effect in [without] if isinstance(without, str) else without or []:
        cmd += ["--without", effect]
    if noise is not None:
        cmd += ["--noise", str(noise)]
    for s in settings:
        cmd += ["--set", s]
    subprocess.run(cmd, check=True, capture_output=True)


@functools.lru_cache(maxsize=3)
def columns(path):
    """Every target column of a recording (read once: the pair sweep asks for each many times)."""
    with open(path) as f:
        rows = csv.reader(line for line in f if not line.startswith("#"))
        header = next(rows)
        index = [header.index(t) for t in TARGETS]
        values = [[] for _ in TARGETS]
        for r in rows:
            for v, i in zip(values, index):
                v.append(float(r[i]))
    return dict(zip(TARGETS, values))


def column(path, name):
    return columns(path)[name]


def rms(values):
    mean = sum(values) / len(values)
    return math.sqrt(sum((v - mean) ** 2 for v in values) / len(values))


def analyse(d, target):
    """The CLI's report on one (sim, real) pair, or its error message."""
    report_path = os.path.join(d, target.replace("#", "_") + ".json")
    if not os.path.exists(report_path):
        run = subprocess.run([BINARY, "discrepancy", "--sim", f"{d}/sim.csv", "--real",
                              f"{d}/real.csv", "--target", target, "--json", report_path],
                             capture_output=True, text=True)
        if run.returncode != 0:
            return None, run.stderr.strip()
    return json.load(open(report_path)), None


def against_physics(report, target):
    """The findings of a report whose sign (or the room's gain) contradicts the physics they
    name: the limits the joint model keeps (docs/discrepancy.md, "Corrections keep within their
    physics"), read back from the reported parameters."""
    temperature = target.endswith("temp_C")
    broken = []
    for f in report["findings"]:
        p, kind = f["parameters"], f["physics"]
        if temperature and kind == "ambient_temperature" and not 0 < p["gain_per_K"] <= 1.05:
            broken.append(f"room gain {p['gain_per_K']:.4f} K/K")
        flowing = p.get("gain_per_K_while_coolant_flows")
        if temperature and kind == "ambient_temperature" and flowing is not None \
                and not 0 < flowing <= 1.05:
            broken.append(f"room gain while the coolant flows {flowing:.4f} K/K")
        if temperature and kind == "copper_loss" and p["per_A2"] <= 0:
            broken.append(f"I²R heating {p['per_A2']:.3g} °C/A²")
        if (temperature and kind == "speed_dependent_cooling" and "simulated_at_rpm" not in p
                and p["relative_change_at_1000rpm"] >= 0):
            broken.append(f"cooling {p['relative_change_at_1000rpm']:+.3f} at 1000 rpm")
        if temperature and kind == "coulomb_reversal" and min(
                p.get("per_krpm", 1), p.get("per_A2", 1)) <= 0:
            broken.append("negative friction heat")
        if kind == "lubricant_viscosity" and p.get("temperature_coefficient_per_K", -1) > 0:
            broken.append("friction rising as the lubricant warms")
    return broken


def single_runs(out, effect, seed):
    d = os.path.join(out, f"{effect}-{seed}")
    os.makedirs(d, exist_ok=True)
    extra = REAL_ONLY.get(effect, [])
    simulate(f"{d}/sim.csv", seed, without=effect, noise=0)
    simulate(f"{d}/real.csv", seed, settings=extra)
    simulate(f"{d}/clean.csv", seed, noise=0, settings=extra)
    return d


def effect_size(out, effect, target, seed):
    """The concealed effect's RMS on the target over the instrument's white-noise σ."""
    d = single_runs(out, effect, seed)
    sim, real, clean = (column(f"{d}/{n}.csv", target) for n in ("sim", "real", "clean"))
    effect_rms = rms([c - s for c, s in zip(clean, sim)])
    # The instrument's white noise, from successive differences of (real − clean).
    noise = [r - c for r, c in zip(real, clean)]
    sigma = math.sqrt(sum((b - a) ** 2 for a, b in zip(noise, noise[1:])) / (2 * len(noise) - 2))
    return effect_rms / max(sigma, 1e-12)


def one_case(out, effect, target, seed):
    d = single_runs(out, effect, seed)
    report, error = analyse(d, target)
    if report is None:
        return effect, target, seed, None, error, 0.0, []
    named = [f["physics"] for f in report["findings"]]
    return (effect, target, seed, report["verdict"], named,
            effect_size(out, effect, target, seed), against_physics(report, target))


def pair_case(out, pair, target, seed):
    a, b = pair
    d = os.path.join(out, f"{a}+{b}-{seed}")
    os.makedirs(d, exist_ok=True)
    extra = REAL_ONLY.get(a, []) + REAL_ONLY.get(b, [])
    simulate(f"{d}/sim.csv", seed, without=[a, b], noise=0)
    simulate(f"{d}/real.csv", seed, settings=extra)
    report, error = analyse(d, target)
    if report is None:
        return None, error, []
    return report, None, [f["physics"] for f in report["findings"]]


def pairs_main(out, seeds):
    cases = [(p, t, s) for p in itertools.combinations(EFFECTS, 2) for t in TARGETS
             for s in seeds]
    # Each effect's own size, read effect by effect so that each recording is parsed once.
    size = {(e, t, s): effect_size(out, e, t, s) for e in EFFECTS for s in seeds for t in TARGETS}
    both = [0, 0]
    one = [0, 0]
    broken = []
    print("| outcome | concealed | target | seed | sizes / σ | named | indistinguishable |")
    print("|---|---|---|---|---|---|---|")
    with concurrent.futures.ThreadPoolExecutor(2) as pool:
        for (pair, target, seed), (report, error, named) in zip(cases, pool.map(
                lambda c: pair_case(out, *c), cases)):
            label = " + ".join(f"`{e}`" for e in pair)
            if report is None:
                print(f"| error | {label} | `{target}` | {seed} | | {error} | |")
                continue
            broken += [f"{label} on `{target}`, seed {seed}: {b}"
                       for b in against_physics(report, target)]
            sizes = [size[(e, target, seed)] for e in pair]
            large = [e for e, z in zip(pair, sizes) if z >= LARGE]
            absent = [e for e, z in zip(pair, sizes) if z < ABSENT]
            if len(large) == 2:
                both[0] += 1
                ok = all(e in named for e in pair)
                both[1] += ok
                outcome = "both named" if ok else "**not both**"
            elif len(large) == 1 and len(absent) == 1:
                one[0] += 1
                ok = large[0] in named and absent[0] not in named
                one[1] += ok
                outcome = "the large one" if ok else "**missed**"
            else:
                continue
            if not ok:
                alike = sorted({a for f in report["findings"]
                                for a in f.get("indistinguishable_from") or []})
                print(f"| {outcome} | {label} | `{target}` | {seed} | "
                      f"{' / '.join(f'{z:.1f}' for z in sizes)} | {', '.join(named) or '—'} "
                      f"| {', '.join(alike) or '—'} |")
    print(f"\nboth large (each ≥ {LARGE} σ alone): {both[1]}/{both[0]} both named")
    print(f"one large, one absent (< {ABSENT} σ): {one[1]}/{one[0]} the large one named "
          f"and the absent one not")
    print_against_physics(broken, len(cases))


def command_line(default_out, default_seeds):
    """`[--pairs] [OUT_DIR] [SEEDS]`: whether pairs are asked for, the directory, the seeds."""
    args = [a for a in sys.argv[1:] if a != "--pairs"]
    out = args[0] if args else default_out
    seeds = [int(s) for s in (args[1] if len(args) > 1 else default_seeds).split(",")]
    return "--pairs" in sys.argv, out, seeds


def main():
    pairs, out, seeds = command_line("/tmp/sweep", "301,302")
    if pairs:
        pairs_main(out, seeds)
        return
    cases = [(e, t, s) for e in EFFECTS for t in TARGETS for s in seeds]
    absent = [0, 0]
    large = [0, 0]
    broken = []
    print("| outcome | concealed | target | seed | effect RMS / σ | verdict | named |")
    print("|---|---|---|---|---|---|---|")
    with concurrent.futures.ThreadPoolExecutor(2) as pool:
        for effect, target, seed, verdict, named, size, against in pool.map(
                lambda c: one_case(out, *c), cases):
            broken += [f"`{effect}` on `{target}`, seed {seed}: {b}" for b in against]
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
    print_against_physics(broken, len(cases))


def print_against_physics(broken, reports):
    print(f"findings against their physics' sign or range: {len(broken)} in {reports} reports")
    for b in broken:
        print(f"- {b}")


if __name__ == "__main__":
    main()
