#!/usr/bin/env bash
# How much of docs/accuracy.md's Table 3 comparison survives another draw of the data?
# Calibrates on several DOE databases (different seeds, 48 h each) with the same one-shift
# experiment (seed 2), validates each calibration on three production days no calibration saw
# (seeds 7, 8, 9; 10 h, default noise), and prints per estimate the mean, the worst and the
# best R² over every (database, day) pair. Takes about 5 minutes after the release build.
#
#     bash scripts/accuracy_seeds.sh [OUT_DIR] [DATABASE_SEEDS...]   (default seeds: 1 3 4 5)
#
# With EXPERIMENT_FROM_S=7200 the experiment is the shift's rows from 2 h on: an experiment
# that begins on a warm machine (docs/accuracy.md, *An experiment that begins warm*).
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-target/accuracy-seeds}
shift || true
seeds=("$@")
[ ${#seeds[@]} -gt 0 ] || seeds=(1 3 4 5)
mkdir -p "$out"
cargo build --release --quiet
S=target/release/servosight

$S simulate --scenario production --hours 8 --seed 2 -o "$out/experiment.csv" 2> /dev/null
if [ -n "${EXPERIMENT_FROM_S:-}" ]; then
    # The experiment as a recording that begins mid-shift: its rows from that time on.
    awk -F, -v from="$EXPERIMENT_FROM_S" '/^#/ || !header++ || $1 >= from' \
        "$out/experiment.csv" > "$out/experiment-cut.csv"
    mv "$out/experiment-cut.csv" "$out/experiment.csv"
fi
for day in 7 8 9; do
    $S simulate --scenario production --hours 10 --seed "$day" -o "$out/day$day.csv" 2> /dev/null
done
for seed in "${seeds[@]}"; do
    $S simulate --scenario doe --hours 48 --seed "$seed" -o "$out/db.csv" 2> /dev/null
    $S calibrate --database "$out/db.csv" --experiments "$out/experiment.csv" \
        -o "$out/profile$seed.toml" > /dev/null
    for day in 7 8 9; do
        $S estimate --profile "$out/profile$seed.toml" --recording "$out/day$day.csv" \
            --json "$out/accuracy-db$seed-day$day.json" > /dev/null
    done
done
rm -f "$out/db.csv"
python3 - "$out" <<'PY'
import collections, glob, json, sys

paper = {"motor_flange_temp": 0.92, "front_bearing_temp": 0.88, "back_bearing_temp": 0.88,
         "nut_temp": 0.90, "straightness_h": 0.93, "straightness_v": 0.94,
         "spindle_elongation": 0.92}
rows = collections.defaultdict(list)
runs = sorted(glob.glob(sys.argv[1] + "/accuracy-db*-day*.json"))
for path in runs:
    for row in json.load(open(path))["accuracy"]:
        estimate = row["estimate"].split("#")[0]
        if estimate in paper:
            rows[estimate].append(row)


def ceiling(row):
    """R² of a perfect estimate against this noisy reference: 1 − σ²/Var(reference)."""
    variance = row["rmse"] ** 2 / (1.0 - row["r2"])
    return 1.0 - row["reference_noise"] ** 2 / variance


print(f"R² over {len(runs)} (database, validation day) pairs; straightness pools its 5 nodes")
print("Attainable: pairs where a perfect estimate would reach the paper against the noisy")
print("reference (1 − σ²/Var ≥ paper); noise-free: R² against the noise-free reference.")
print("| estimate | paper | mean | worst | best | at or above the paper | attainable | met where attainable | noise-free mean | noise-free worst |")
print("|---|---|---|---|---|---|---|---|---|---|")
for estimate, target in paper.items():
    values = [r["r2"] for r in rows[estimate]]
    clean = [r["r2_noise_corrected"] for r in rows[estimate]]
    attainable = [r for r in rows[estimate] if ceiling(r) >= target]
    met = sum(r["r2"] >= target for r in attainable)
    above = sum(v >= target for v in values)
    n = len(values)
    print(f"| {estimate} | {target:.2f} | {sum(values) / n:.3f} | {min(values):.3f} "
          f"| {max(values):.3f} | {above}/{n} | {len(attainable)}/{n} | {met}/{len(attainable)} "
          f"| {sum(clean) / n:.3f} | {min(clean):.3f} |")
PY
