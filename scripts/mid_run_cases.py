#!/usr/bin/env python3
"""Recordings that start mid-run, cut from the independent check's pairs.

A simulation started from the machine's state at the first row is what a twin run for the
recorded window gives; a recording cut out of a longer run is not. This script takes the
independent check's pairs of seeds 2 and 3 (`python3 scripts/independent_cases.py CASES 2,3`
writes them) and cuts 13 large effects and 3 nothing-left-out targets four ways: both files
to their last 90, 80 and 60 % (`both10`, `both20`, `both40`), and the real one alone to its
last 80 % with the simulation whole (`real_only20`, which compares the same overlap as
`both20`). Each cut pair is asked about its target, as a user would:

    SERVOSIGHT_BINARY=target/release/servosight python3 scripts/mid_run_cases.py CASES OUT

It prints what was named per case and cut, then per cut how many large effects were named
first, how many nothing-left-out pairs stayed `consistent`, and the held-out RMSE over the
sample noise (median and worst over the large effects). docs/discrepancy.md (*A recording
that starts mid-run*) gives the figures.
"""

import json
import os
import statistics
import subprocess
import sys

CASES = [
    ("ambient_temperature-3", "X.stator_temp_C"),
    ("thermal_inertia-3", "ref.S.front_bearing_temp_C"),
    ("speed_dependent_cooling-3", "S.stator_temp_C"),
    ("lubricant_viscosity-3", "S.torque_Nm"),
    ("copper_loss-3", "X.stator_temp_C"),
    ("coolant-3", "ref.S.elongation_um"),
    ("coulomb_reversal-3", "X.torque_Nm"),
    ("coulomb_reversal-2", "ref.X.nut_temp_C"),
    ("signal_delay-3", "S.current_A"),
    ("signal_delay-2", "X.current_A"),
    ("sensor_offset_drift-3", "X.torque_Nm"),
    ("ambient_temperature-2", "ref.X.nut_temp_C"),
    ("thermal_inertia-2", "X.stator_temp_C"),
    ("nothing-3", "X.torque_Nm"),
    ("nothing-2", "ref.X.nut_temp_C"),
    ("nothing-3", "S.stator_temp_C"),
]

CUTS = [("both10", 0.1, True), ("both20", 0.2, True), ("both40", 0.4, True), ("real_only20", 0.2, False)]


def read(path):
    """(lines before the header, the header, the rows as lines)."""
    with open(path) as f:
        lines = f.read().splitlines()
    at = next(i for i, line in enumerate(lines) if not line.startswith("#"))
    return lines[:at], lines[at], [line for line in lines[at + 1:] if line]


def write(path, meta, header, rows):
    with open(path, "w") as f:
        f.write("\n".join(meta + [header] + rows) + "\n")


def from_time(rows, t0):
    return [r for r in rows if float(r.split(",", 1)[0]) >= t0]


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    cases_dir, out = sys.argv[1], sys.argv[2]
    binary = os.environ.get("SERVOSIGHT_BINARY", "target/release/servosight")
    results = []
    for case, target in CASES:
        sim = read(os.path.join(cases_dir, case, "sim.csv"))
        real = read(os.path.join(cases_dir, case, "real.csv"))
        end = float(real[2][-1].split(",", 1)[0])
        for name, share, both in CUTS:
            cut = share * end
            where = os.path.join(out, case, name)
            os.makedirs(where, exist_ok=True)
            write(os.path.join(where, "sim.csv"), sim[0], sim[1], from_time(sim[2], cut) if both else sim[2])
            write(os.path.join(where, "real.csv"), real[0], real[1], from_time(real[2], cut))
            report = os.path.join(where, "report.json")
            run = subprocess.run(
                [binary, "discrepancy", "--sim", os.path.join(where, "sim.csv"),
                 "--real", os.path.join(where, "real.csv"), "--target", target, "--json", report],
                capture_output=True, text=True)
            if run.returncode != 0:
                sys.exit(f"{case} {name}: {run.stderr.strip()}")
            with open(report) as f:
                r = json.load(f)
            named = [x["physics"] for x in r["findings"]]
            sigma = r["improved"]["rmse"] / r["noise_floor"]["sample_noise_rms"]
            results.append((name, case, named, sigma))
            print(f"{case:<28} {target:<28} {name:<12} {','.join(named) or 'consistent':<50} {sigma:6.1f} σ", flush=True)
    for name, _, _ in CUTS:
        rows = [r for r in results if r[0] == name]
        large = [r for r in rows if not r[1].startswith("nothing")]
        first = sum(r[2][:1] == [r[1].rsplit("-", 1)[0]] for r in large)
        quiet = sum(not r[2] for r in rows if r[1].startswith("nothing"))
        sigmas = [r[3] for r in large]
        print(f"{name}: {first}/{len(large)} named first, {quiet}/{len(rows) - len(large)} nothing left out consistent, "
              f"held out {statistics.median(sigmas):.1f} σ median, {max(sigmas):.1f} σ worst")


if __name__ == "__main__":
    main()
