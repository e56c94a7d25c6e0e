#!/usr/bin/env bash
# Runs the HMI on the embedded twin in a virtual X server and saves screenshots of it.
#
#   apt-get install -y xvfb imagemagick      # once (Debian packages)
#   bash scripts/hmi-screenshot.sh           # → docs/screenshot.png, docs/screenshot-{trends,warmup,depth}.png
#
# The twin runs at 120× real time so that a few seconds show tens of minutes of warm-up.
# Everything the run writes (recording, audit log, settings) goes to a temporary directory.
set -euo pipefail
cd "$(dirname "$0")/.."
wait_s=${WAIT_S:-15}
display=${DISPLAY_NUMBER:-:97}

cargo build --release --locked --bin servosight

work=$(mktemp -d)
export XDG_RUNTIME_DIR="$work/runtime"
mkdir -m 700 "$XDG_RUNTIME_DIR"
cleanup() {
    [ -n "${app:-}" ] && kill "$app" 2>/dev/null || true
    [ -n "${xvfb:-}" ] && kill "$xvfb" 2>/dev/null || true
    rm -rf "$work"
}
trap cleanup EXIT

Xvfb "$display" -screen 0 1400x900x24 -nolisten tcp &
xvfb=$!
export DISPLAY=$display
sleep 1

shot() { # shot TAB OUTPUT [SECONDS]
    cat >"$work/hmi.json" <<JSON
{"tab": "$1", "window_size": [1400, 900],
 "trends": {"preset": "ten_minutes",
            "selected": ["X.stator_temp_C", "est.X.motor_flange_temp_C", "est.X.nut_temp_C",
                         "est.X.front_bearing_temp_C", "S.stator_temp_C", "est.S.elongation_um"]}}
JSON
    target/release/servosight --speed 120 --data-dir "$work/data" --settings "$work/hmi.json" \
        >"$work/app.log" 2>&1 &
    app=$!
    sleep "${3:-$wait_s}"
    import -window root "$2"
    kill "$app"
    wait "$app" 2>/dev/null || true
    app=
    echo "saved $2"
}

shot Overview docs/screenshot.png
shot Trends docs/screenshot-trends.png
shot Warmup docs/screenshot-warmup.png
# The production day cuts from 07:15 on (15 min into the run): give it time to cut at a few depths.
shot DepthOfCut docs/screenshot-depth.png $((wait_s * 3))
