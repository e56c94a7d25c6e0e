#!/usr/bin/env bash
# Reproduces docs/accuracy.md: calibrate on twin data (a DOE database + one experiment: a single
# 8 h production shift recorded with reference sensors),
# validate on a different seed and scenario with noise, and measure backlash on test runs from
# 5 to 60 µm at two noise levels. Takes about 3 minutes after the release build.
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-target/accuracy}
mkdir -p "$out"
cargo build --release --quiet
S=target/release/servosight

$S simulate --scenario doe --hours 48 --seed 1 -o "$out/db.csv"
$S simulate --scenario production --hours 8 --seed 2 -o "$out/experiment.csv"
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
        $S backlash --recording "$out/lash.csv" --axis X --json "$out/lash.json" > /dev/null
        found=$(python3 -c "import json, sys; print('%.3f' % json.load(open(sys.argv[1]))['backlash_um'])" "$out/lash.json")
        printf '%s\t%s\t%s\n' "$truth" "$noise" "$found" | tee -a "$out/backlash.tsv"
    done
done
awk -F'\t' '{ n++; t[n]=$1; f[n]=$3; s+=$1 } END {
    m = s / n; for (i = 1; i <= n; i++) { sse += (t[i]-f[i])^2; sst += (t[i]-m)^2;
    e = t[i]-f[i]; if (e < 0) e = -e; if (e > worst) worst = e }
    printf "backlash R² %.5f, RMSE %.3f µm, worst error %.3f µm over %d runs\n", 1 - sse/sst, sqrt(sse/n), worst, n }' "$out/backlash.tsv"

echo
echo "motor abnormality: run, injected change, axis, state, excess friction % ± standard error"
: > "$out/abnormality.tsv"
abnormality() { # name, scenario, hours, seed, injected change ("-" for none)
    local name=$1 scenario=$2 hours=$3 seed=$4 change=$5 set=()
    [ "$change" != "-" ] && set=(--set "$change")
    $S simulate --scenario "$scenario" --hours "$hours" --seed "$seed" "${set[@]}" \
        -o "$out/abn.csv" 2> /dev/null
    $S estimate --profile "$out/profile.toml" --recording "$out/abn.csv" --json "$out/abn.json" > /dev/null
    python3 - "$name" "$change" "$out/abn.json" <<'PY' | tee -a "$out/abnormality.tsv"
import json, sys
name, change, path = sys.argv[1:4]
for row in json.load(open(path))["abnormality"]:
    pct, se = row["excess_pct"], row["standard_error_pct"]
    shown = "—" if pct is None else f"{pct:+.1f} ± {se:.1f}"
    print(f"{name}\t{change}\t{row['axis']}\t{row['state']}\t{shown}")
PY
}
for seed in 7 41 42 43; do abnormality "production seed $seed" production 8 "$seed" -; done
for seed in 51 52 53; do abnormality "warm-up seed $seed" warmup 0.75 "$seed" -; done
abnormality "production seed 44" production 8 44 spindle.front_bearing.f0=1.6
abnormality "production seed 45" production 8 45 spindle.front_bearing.f0=2.4
abnormality "production seed 46" production 8 46 spindle.rear_bearing.f0=2.0
abnormality "warm-up seed 54" warmup 0.75 54 spindle.front_bearing.f0=1.6
abnormality "production seed 47" production 8 47 x_axis.front_bearing.f0=8
abnormality "production seed 48" production 8 48 x_axis.back_bearing.f0=6
abnormality "production seed 49" production 8 49 x_axis.nut_preload_N=900
abnormality "production seed 50" production 8 50 x_axis.nut_preload_N=2250
abnormality "warm-up seed 55" warmup 0.75 55 x_axis.front_bearing.f0=8
