#!/usr/bin/env bash
# Reproduces docs/accuracy.md: calibrate on twin data (a DOE database + one short experiment),
# validate on a different seed and scenario with noise, and measure backlash on test runs from
# 5 to 60 µm at two noise levels. Takes about a minute after the release build.
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-target/accuracy}
mkdir -p "$out"
cargo build --release --quiet
S=target/release/servosight

$S simulate --scenario doe --hours 48 --seed 1 -o "$out/db.csv"
$S simulate --scenario production --hours 4 --seed 2 -o "$out/experiment.csv"
$S simulate --scenario production --hours 10 --seed 7 -o "$out/validation.csv"
$S calibrate --database "$out/db.csv" --experiments "$out/experiment.csv" \
    -o "$out/profile.toml" --json "$out/calibration.json" > "$out/calibration.txt"
$S estimate --profile "$out/profile.toml" --recording "$out/validation.csv" \
    -o "$out/estimates.csv" --json "$out/accuracy.json" | tee "$out/accuracy.txt"

echo
echo "backlash: true µm, noise ×, found µm"
: > "$out/backlash.tsv"
seed=10
for truth in 5 10 20 30 45 60; do
    for noise in 1 3; do
        seed=$((seed + 1))
        $S simulate --scenario backlash-test --set "x_axis.backlash_um=$truth" --noise "$noise" \
            --seed "$seed" -o "$out/lash.csv" 2> /dev/null
        found=$($S backlash --recording "$out/lash.csv" --axis X | sed -nE '1s/.*backlash: ([0-9.]+) µm.*/\1/p')
        printf '%s\t%s\t%s\n' "$truth" "$noise" "$found" | tee -a "$out/backlash.tsv"
    done
done
awk -F'\t' '{ n++; t[n]=$1; f[n]=$3; s+=$1 } END {
    m = s / n; for (i = 1; i <= n; i++) { sse += (t[i]-f[i])^2; sst += (t[i]-m)^2;
    e = t[i]-f[i]; if (e < 0) e = -e; if (e > worst) worst = e }
    printf "backlash R² %.4f, RMSE %.2f µm, worst error %.2f µm over %d runs\n", 1 - sse/sst, sqrt(sse/n), worst, n }' "$out/backlash.tsv"
