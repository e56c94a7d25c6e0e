#!/usr/bin/env bash
# How well do the estimates read a recording that starts mid-shift, on a machine that has been
# working for hours? Cuts three production days no calibration saw (seeds 7, 8, 9; 10 h,
# default noise) to start at each whole hour from 1 to 8, and estimates every cut with the
# shipped profile (assets/it25-twin.toml) and with the same profile without its warm starts
# (every part's heat starting at rest, as before the warm start existed). Prints, per estimate
# and profile, the median, mean and worst R² over the 24 cuts against the noisy reference and
# against the noise-free one, and the RMSE. Takes about a minute after the release build.
#
#     bash scripts/mid_shift.sh [OUT_DIR]
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-target/mid-shift}
mkdir -p "$out"
cargo build --release --quiet
S=target/release/servosight
P=assets/it25-twin.toml

# The shipped profile without its `[...warm_start]` tables.
awk '/^\[/ { skip = ($0 ~ /\.warm_start(\.per_K)?\][[:space:]]*(#.*)?\r?$/) } !skip' "$P" \
    > "$out/at-rest.toml"
for day in 7 8 9; do
    $S simulate --scenario production --hours 10 --seed "$day" -o "$out/day$day.csv" 2> /dev/null
    for hour in 1 2 3 4 5 6 7 8; do
        cut="$out/day$day-from${hour}h.csv"
        awk -v from=$((hour * 3600)) -F, '
            /^#/ || !header { print; if ($0 !~ /^#/) header = 1; next }
            $1 >= from' "$out/day$day.csv" > "$cut"
        for profile in warm at-rest; do
            path=$P
            [ "$profile" = warm ] || path="$out/at-rest.toml"
            $S estimate --profile "$path" --recording "$cut" \
                --json "$out/accuracy-$profile-day$day-from${hour}h.json" > /dev/null
        done
        rm -f "$cut"
    done
done
python3 - "$out" <<'PY'
import collections, glob, json, statistics, sys

estimates = ["motor_flange_temp", "front_bearing_temp", "back_bearing_temp", "nut_temp",
             "spindle_elongation",
             "straightness_h", "straightness_v"]
print("R² and RMSE over 24 cuts (days 7, 8, 9 from each hour 1..8); straightness pools its 5")
print("nodes. Noise-free: R² against the noise-free reference, where the reference varies more")
print("than its noise (a cut's last hours may not).")
print("| estimate | profile | R² median | R² mean | R² worst | RMSE median | RMSE worst | noise-free R² median |")
print("|---|---|---|---|---|---|---|---|")
for estimate in estimates:
    for profile in ["at-rest", "warm"]:
        rows = []
        for path in sorted(glob.glob(f"{sys.argv[1]}/accuracy-{profile}-day*-from*h.json")):
            rows += [r for r in json.load(open(path))["accuracy"]
                     if r["estimate"].split("#")[0] == estimate]
        # R² is null where the reference did not vary; noise-free R² is absent where it varied
        # less than its noise.
        r2 = [r["r2"] for r in rows if r.get("r2") is not None]
        rmse = [r["rmse"] for r in rows if r.get("rmse") is not None]
        clean = [r["r2_noise_corrected"] for r in rows if r.get("r2_noise_corrected") is not None]
        name = "warm start" if profile == "warm" else "at rest"
        if not r2:
            print(f"| {estimate} | {name} | no cut scored it | | | | | |")
            continue
        clean_median = f"{statistics.median(clean):.3f}" if clean else "—"
        print(f"| {estimate} | {name} | {statistics.median(r2):.3f} | {statistics.fmean(r2):.3f} "
              f"| {min(r2):.3f} | {statistics.median(rmse):.3f} | {max(rmse):.3f} "
              f"| {clean_median} |")
PY
