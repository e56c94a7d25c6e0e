#!/usr/bin/env python3
"""The independent check's machine with its simulation exported half a sample off the real grid.

A simulation and a recording seldom share their instants: an export starts when the solver
started, a trace when the operator pressed the button. This script writes the cases of
`scripts/independent_cases.py` (every effect and `nothing`, the same machine, program, noise
and seeds) with the real recording at 1 Hz (`--every 2`, the default) or 0.5 Hz (`--every 4`)
and the simulation at the same rate but half a sample later: its values are the machine's
own at those instants, not an interpolation, so nothing but the grid differs. Each pair is
asked about the nine targets, as a user would:

    SERVOSIGHT_BINARY=target/release/servosight python3 scripts/shifted_grid_cases.py OUT 1,2,3,4 [--every 4]

(about five minutes per rate on 2 cores). It prints one line per report, then how many large
effects (at least 3 σ) were named first, how many reports where the effect does not reach the
target (below 0.05 σ) and with nothing left out stayed `consistent`, scored as the independent
check scores. docs/discrepancy.md (*Alignment*) gives the figures.
"""

import concurrent.futures
import json
import math
import os
import subprocess
import sys

import numpy as np

import independent_cases as ic
from discrepancy_sweep import ABSENT, EFFECTS, LARGE

BINARY = os.environ.get("SERVOSIGHT_BINARY", "target/release/servosight")


def write(path, signals, every, start, columns):
    rows = np.column_stack([np.arange(len(signals["ambient_C"])) * ic.DT]
                           + [signals[c] for c in columns])[start::every]
    with open(path, "w") as f:
        f.write("# source: scripts/shifted_grid_cases.py\n")
        f.write(",".join(["time_s"] + columns) + "\n")
        np.savetxt(f, rows, delimiter=",", fmt="%.6g")


def make_case(out, seed, effect, every):
    """One case of `independent_cases.py` (the same draws), both files every `every` steps of
    its grid, the simulation's rows half that later."""
    d = os.path.join(out, f"{effect}-{seed}-every{every}")
    if os.path.exists(os.path.join(d, "sizes.json")):
        return d
    os.makedirs(d, exist_ok=True)
    rng = np.random.default_rng(seed)
    hours = rng.uniform(4, 8)
    p = ic.program(rng, hours)
    inertia = rng.choice([rng.uniform(0.55, 0.75), rng.uniform(1.35, 1.8)])
    delay_s = rng.uniform(6, 40)
    offsets = {t: (rng.choice([-1, 1]) * rng.uniform(0.5, 1.5) * ic.SCALE[t],
                   rng.choice([-1, 1]) * rng.uniform(0.3, 1.0) * ic.SCALE[t])
               for t in ic.TARGETS}
    correlated = seed % 2 == 0
    full = ic.machine(p, set(), inertia)
    sim = ic.machine(p, ic.left_out(effect), inertia)
    noise_rng = np.random.default_rng(ic.noise_seed(seed, effect))
    real = ic.measured(noise_rng, full, effect, correlated, delay_s, offsets)
    columns = ic.OPERATING + ic.TARGETS
    write(os.path.join(d, "real.csv"), real, every, 0, columns)
    write(os.path.join(d, "sim.csv"), sim, every, every // 2, columns)
    sizes = {}
    for t in ic.TARGETS:
        effect_signal = ic.measured_clean(full, t, effect, delay_s, offsets) - sim[t]
        white, corr = ic.NOISE[t]
        sigma = math.hypot(white, corr) if correlated else white
        centred = effect_signal if "sensor_offset_drift" in ic.left_out(effect) \
            else effect_signal - effect_signal.mean()
        sizes[t] = float(np.sqrt(np.mean(centred ** 2)) / sigma)
    json.dump({"sizes": sizes}, open(os.path.join(d, "sizes.json"), "w"))
    return d


def analyse(d, target):
    report_path = os.path.join(d, target + ".json")
    if not os.path.exists(report_path):
        run = subprocess.run([BINARY, "discrepancy", "--sim", f"{d}/sim.csv", "--real",
                              f"{d}/real.csv", "--target", target, "--json", report_path],
                             capture_output=True, text=True)
        if run.returncode != 0:
            return None, run.stderr.strip()
    return json.load(open(report_path)), None


def main():
    args = [a for a in sys.argv[1:]]
    every = 2
    if "--every" in args:
        at = args.index("--every")
        every = int(args[at + 1])
        del args[at:at + 2]
    if len(args) != 2 or every < 2 or every % 2:
        sys.exit("usage: shifted_grid_cases.py OUT SEEDS [--every EVEN_STEPS]")
    out, seeds = args[0], [int(s) for s in args[1].split(",")]
    cases = [(s, e) for s in seeds for e in EFFECTS + ["nothing"]]
    with concurrent.futures.ProcessPoolExecutor(2) as pool:
        dirs = list(pool.map(make_case, [out] * len(cases), *zip(*cases), [every] * len(cases)))
    jobs = [(d, e, t) for d, (_, e) in zip(dirs, cases) for t in ic.TARGETS]
    with concurrent.futures.ThreadPoolExecutor(2) as pool:
        reports = list(pool.map(lambda j: analyse(j[0], j[2]), jobs))
    named_first = large = quiet = quiet_ok = 0
    for (d, effect, target), (report, error) in zip(jobs, reports):
        size = json.load(open(os.path.join(d, "sizes.json")))["sizes"][target]
        if report is None:
            print(f"{os.path.basename(d)} {target}: error {error}")
            continue
        named = [f["physics"] for f in report["findings"]]
        print(f"{os.path.basename(d)} {target} {size:.2f} σ: {report['verdict']} "
              f"{', '.join(named)} (held out {report['improved']['rmse']:.4g})")
        if effect == "nothing" or size < ABSENT:
            quiet += 1
            quiet_ok += report["verdict"] == "consistent"
        elif size >= LARGE:
            large += 1
            named_first += bool(named) and named[0] == effect
    print(f"large effects named first: {named_first} / {large}; "
          f"nothing left out or not reaching the target, consistent: {quiet_ok} / {quiet}")


if __name__ == "__main__":
    main()
