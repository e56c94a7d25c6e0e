#!/usr/bin/env python3
"""The independent check's machine with its simulation exported half a sample off the real grid.

A simulation and a recording seldom share their instants: an export starts when the solver
started, a trace when the operator pressed the button. This script writes the cases of
`scripts/independent_cases.py` (every effect and `nothing`, the same machine, program, noise
and seeds) with the real recording at 1 Hz (`--every 2`, the default) or 0.5 Hz (`--every 4`)
and the simulation at the same rate but half a sample later: its values are the machine's
own at those instants, not an interpolation, so nothing but the grid differs. With
`--jitter SECONDS` the simulation stays on the regular grid and the real recording's time
stamps are jittered instead, each by a uniform draw within ±SECONDS (a trace whose samples
are not taken exactly on time). Each pair is asked about the nine targets, as a user would:

    SERVOSIGHT_BINARY=target/release/servosight python3 scripts/shifted_grid_cases.py OUT 1,2,3,4 [--every 4] [--jitter 0.1]

(about five minutes per rate on 2 cores). It prints one line per report, then how many large
effects (at least 3 σ) were named first, how many reports where the effect does not reach the
target (below 0.05 σ) and with nothing left out stayed `consistent`, scored as the independent
check scores. docs/discrepancy.md (*Alignment*) gives the figures.
"""

import concurrent.futures
import json
import os
import sys

import numpy as np

import independent_cases as ic
from discrepancy_sweep import ABSENT, EFFECTS, LARGE, analyse

def make_case(out, seed, effect, every, jitter):
    """One case of `independent_cases.py` (the same draws), both files every `every` steps of
    its grid, the simulation's rows half that later or, with `jitter`, the real one's time
    stamps jittered."""
    d = os.path.join(out, f"{effect}-{seed}-every{every}" + (f"-jitter{jitter:g}" if jitter else ""))
    if os.path.exists(os.path.join(d, "sizes.json")):
        return d
    os.makedirs(d, exist_ok=True)
    # The independent check's own draws; its choice of sample steps is not used.
    case = ic.draw_case(seed, effect)
    real, sim = case["real"], case["sim"]
    columns = ic.OPERATING + ic.TARGETS
    here = "scripts/shifted_grid_cases.py"
    if jitter:
        rows = len(real["ambient_C"]) // every + 1
        late = np.random.default_rng(seed + 1000).uniform(-jitter, jitter, rows)
        ic.write(os.path.join(d, "real.csv"), real, every, columns, time_offsets=late,
                 source=here)
        ic.write(os.path.join(d, "sim.csv"), sim, every, columns, source=here)
    else:
        ic.write(os.path.join(d, "real.csv"), real, every, columns, source=here)
        ic.write(os.path.join(d, "sim.csv"), sim, every, columns, start=every // 2,
                 source=here)
    json.dump({"sizes": case["sizes"]}, open(os.path.join(d, "sizes.json"), "w"))
    return d


def main():
    args = [a for a in sys.argv[1:]]
    every, jitter = 2, 0.0
    try:
        if "--every" in args:
            at = args.index("--every")
            every = int(args[at + 1])
            del args[at:at + 2]
        if "--jitter" in args:
            at = args.index("--jitter")
            jitter = float(args[at + 1])
            del args[at:at + 2]
        seeds = [int(s) for s in args[1].split(",")] if len(args) == 2 else []
    except (IndexError, ValueError):
        sys.exit("usage: shifted_grid_cases.py OUT SEEDS [--every EVEN_STEPS] [--jitter SECONDS]")
    if not seeds or every < 2 or every % 2 or not 0 <= jitter < every * ic.DT / 2:
        sys.exit("usage: shifted_grid_cases.py OUT SEEDS [--every EVEN_STEPS] [--jitter SECONDS]"
                 " (a jitter below half a sample)")
    out = args[0]
    cases = [(s, e) for s in seeds for e in EFFECTS + ["nothing"]]
    with concurrent.futures.ProcessPoolExecutor(2) as pool:
        dirs = list(pool.map(make_case, [out] * len(cases), *zip(*cases), [every] * len(cases),
                             [jitter] * len(cases)))
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
