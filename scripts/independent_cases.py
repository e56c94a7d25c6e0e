#!/usr/bin/env python3
"""Concealed-effect pairs from a machine model written here, independent of the twin.

The proof grid and the sweeps make their pairs with servosight's own twin (`src/sim/`), so
they cannot show that the discrepancy command works on a simulation it was not built beside.
This script writes a different machine from the vocabulary's physics alone (DESIGN.md): its
own lumped thermal network (stator, housing, front bearing of a spindle; motor and nut of a
ball-screw feed axis), its own friction laws, its own operating program, noise (white, or
white plus an AR(1) drift with a time constant of minutes), sample rates and an FEA-like
coarse simulation grid in some cases. Nothing of the repository is used but the
`servosight discrepancy` command under test (run, and scored, as the sweep runs it).

For each seed it builds one operating program, runs the model with every effect present
("real", with noise) and with one effect left out ("sim", noise-free, as a simulation is),
and asks the command about each of nine targets. An effect's size on a target is the RMS of
(real without noise − sim) over the target's noise σ:

- absent (below 0.05 σ): the effect does not reach the target; the verdict must be
  `consistent` and anything named is a false discovery;
- large (at least 3 σ): the concealed effect should be named first;
- between: listed, not scored.

`nothing` cases leave nothing out: every target must be `consistent`.

With `--pairs` every pair of the ten effects is left out at once, and each effect of the pair
is sized by its own case (the effect left out alone, same seed), as the pair sweep scores:

- both large: both must be named (in any order);
- one large, the other absent: the large one must be named and the absent one must not;
- otherwise: listed, not scored.

Usage (after `cargo build --release`, with numpy installed; a few minutes on 2 cores, about
ten per seed with `--pairs`):

    python3 scripts/independent_cases.py [--pairs] [OUT_DIR] [SEEDS]
                                                    (default /tmp/independent 1,2,3)

`--long SEED EFFECT HOURS OUT_DIR` writes one case seeded like SEED but run for HOURS at 2 Hz in
both files, to OUT_DIR/EFFECT-SEED-longHOURSh, to time the command on a long recording
(docs/performance.md).
"""
import concurrent.futures
import itertools
import json
import math
import os
import sys

import numpy as np

# The command is run, and its outcomes sized, as the sweep does (same effects, same thresholds).
from discrepancy_sweep import ABSENT, EFFECTS, LARGE, analyse, command_line

TARGETS = ["S.stator_temp_C", "X.stator_temp_C", "S.torque_Nm", "X.torque_Nm", "S.current_A",
           "X.current_A", "ref.S.front_bearing_temp_C", "ref.S.elongation_um",
           "ref.X.nut_temp_C"]
# The measurement noise of each target: (white σ, correlated σ) in its unit.
NOISE = {"S.stator_temp_C": (0.05, 0.05), "X.stator_temp_C": (0.05, 0.05),
         "S.torque_Nm": (0.08, 0.04), "X.torque_Nm": (0.03, 0.015),
         "S.current_A": (0.1, 0.05), "X.current_A": (0.03, 0.015),
         "ref.S.front_bearing_temp_C": (0.03, 0.03), "ref.S.elongation_um": (0.25, 0.25),
         "ref.X.nut_temp_C": (0.03, 0.03)}
# How large a measurement offset / drift per hour is on each target, in its unit.
SCALE = {"S.stator_temp_C": 1.0, "X.stator_temp_C": 1.0, "S.torque_Nm": 0.4,
         "X.torque_Nm": 0.15, "S.current_A": 0.6, "X.current_A": 0.15,
         "ref.S.front_bearing_temp_C": 0.6, "ref.S.elongation_um": 4.0,
         "ref.X.nut_temp_C": 0.6}
OPERATING = ["S.speed_rpm", "X.speed_rpm", "X.position_mm", "coolant_on", "ambient_C"]
DT = 0.5  # the model's integration step, s


def program(rng, hours):
    """A shift's operating program on the internal grid: spindle speed and cut, X feed, coolant,
    room temperature."""
    n = int(hours * 3600 / DT)
    speed = np.zeros(n)
    cut = np.zeros(n)
    feed_rate = np.zeros(n)  # mm/min while the table moves
    half_period = np.ones(n)  # samples between programmed reversals
    coolant = np.zeros(n)
    i = 0
    while i < n:
        length = min(int(rng.uniform(3, 25) * 60 / DT), n - i)
        if rng.random() > 0.25:
            speed[i:i + length] = round(rng.uniform(500, 9000), -2)
            if rng.random() < 0.6:
                cut[i:i + length] = rng.uniform(2, 25) * (
                    1 + 0.05 * rng.standard_normal(length))
                feed_rate[i:i + length] = rng.uniform(500, 4000)
                half_period[i:i + length] = int(rng.uniform(20, 90) / DT)
                coolant[i:i + length] = 1.0 if rng.random() < 0.7 else 0.0
        i += length
    lo, hi = rng.uniform(20, 100), rng.uniform(300, 480)
    position = np.empty(n)
    feed = np.zeros(n)  # signed
    x, direction, since = (lo + hi) / 2, 1.0, 0
    for k in range(n):
        if feed_rate[k] > 0:
            since += 1
            if since >= half_period[k]:
                direction, since = -direction, 0
            x += direction * feed_rate[k] / 60 * DT
            if x >= hi or x <= lo:  # the stroke's ends reverse the table too
                x = min(max(x, lo), hi)
                direction, since = -direction, 0
            feed[k] = direction * feed_rate[k]
        position[k] = x
    t = np.arange(n) * DT
    room = (20 + rng.uniform(1.5, 3.0) * np.sin(2 * math.pi * t / 86400 + rng.uniform(0, 6.3))
            + rng.uniform(-0.4, 0.4) * t / 3600)
    walk = np.cumsum(rng.standard_normal(n)) * 0.004
    room += walk - lag(walk, 1800)
    return {"t": t, "speed": speed, "cut": cut, "feed": feed, "position": position,
            "coolant": coolant, "room": room, "lo": lo, "hi": hi}


def lag(x, tau):
    """A first-order lag of x with time constant tau (s), exact for a piecewise-constant input."""
    a = math.exp(-DT / tau)
    y = np.empty_like(x)
    s = x[0]
    for k, v in enumerate(x):
        s = a * s + (1 - a) * v
        y[k] = s
    return y


def machine(p, without, inertia):
    """Every signal of the machine on the internal grid, noise-free, with the physics in
    `without` left out. `inertia` scales every heat capacity when thermal inertia is present."""
    has = lambda e: e not in without  # noqa: E731
    c_scale = inertia if has("thermal_inertia") else 1.0
    n = len(p["t"])
    room = p["room"] if has("ambient_temperature") else np.full(n, p["room"][0])
    mid, half = (p["lo"] + p["hi"]) / 2, (p["hi"] - p["lo"]) / 2
    # Spindle: stator, housing and front bearing nodes (W, W/K, J/K).
    c_stator, c_housing, c_bearing = 9000 * c_scale, 60000 * c_scale, 2500 * c_scale
    g_stator0, g_bearing, g_housing = 12.0, 3.0, 9.0
    g_coolant, t_coolant = 14.0, 21.0
    # X axis: motor and nut nodes.
    c_xmotor, c_nut = 1500 * c_scale, 1200 * c_scale
    g_xmotor, g_nut, g_nut_coolant = 0.8, 0.6, 0.5
    ts = th = tb = tx = tn = room[0]
    out = {k: np.empty(n) for k in ["S.torque_Nm", "S.current_A", "S.stator_temp_C",
                                    "ref.S.front_bearing_temp_C", "ref.S.elongation_um",
                                    "X.torque_Nm", "X.current_A", "X.stator_temp_C",
                                    "ref.X.nut_temp_C"]}
    th0, tb0 = th, tb
    for k in range(n):
        s = p["speed"][k]
        running = s > 0
        # Lubricant viscosity: friction falls as the bearing warms (reference 30 °C).
        visc = math.exp(-(tb - 30.0) / 25.0) if has("lubricant_viscosity") else 1.0
        friction = (0.3 + 0.25 * s / 1000) * visc if running else 0.0
        torque = p["cut"][k] + friction if running else 0.0
        current = math.sqrt((torque / 0.5) ** 2 + 3.0 ** 2) if running else 0.0
        omega = s * 2 * math.pi / 60
        copper = 0.08 * current ** 2 if has("copper_loss") else 0.0
        iron = 8.0 * (s / 1000) ** 1.5
        bearing_heat = 0.02 * friction * omega
        # Convection in the air gap grows with speed; without it, the value at 3000 rpm.
        sc = (s if has("speed_dependent_cooling") else 3000.0) / 6000
        g_stator = g_stator0 * (1 + 0.8 * sc ** 0.8)
        cool = p["coolant"][k] if has("coolant") else 0.0
        d_ts = (copper + iron - g_stator * (ts - th) - cool * g_coolant * (ts - t_coolant))
        d_tb = bearing_heat - g_bearing * (tb - th)
        d_th = g_stator * (ts - th) + g_bearing * (tb - th) - g_housing * (th - room[k])
        ts += DT * d_ts / c_stator
        tb += DT * d_tb / c_bearing
        th += DT * d_th / c_housing
        # X axis: Coulomb, preload drag along the screw, viscous and cutting-force torques.
        v = p["feed"][k]
        direction = math.copysign(1.0, v) if v != 0 else 0.0
        rpm = v / 10.0  # 10 mm lead
        along = (p["position"][k] - mid) / half
        preload = 0.15 * ((1 + 0.6 * along) if has("position_dependent") else 1.0)
        coulomb = 0.35 if has("coulomb_reversal") else 0.0
        visc_x = math.exp(-(tn - 30.0) / 25.0) if has("lubricant_viscosity") else 1.0
        x_friction = direction * (coulomb + preload) + 0.0008 * rpm * visc_x
        x_torque = x_friction + direction * 0.04 * p["cut"][k]
        x_current = abs(x_torque) / 1.0
        x_copper = 1.5 * x_current ** 2 if has("copper_loss") else 0.0
        nut_heat = 0.5 * abs(x_friction * rpm * 2 * math.pi / 60) * (
            (1 + 0.6 * along) if has("position_dependent") else 1.0)
        tx += DT * (x_copper - g_xmotor * (tx - room[k])) / c_xmotor
        tn += DT * (nut_heat - g_nut * (tn - room[k]) - cool * g_nut_coolant * (tn - t_coolant)) \
            / c_nut
        out["S.torque_Nm"][k] = torque
        out["S.current_A"][k] = current
        out["S.stator_temp_C"][k] = ts
        out["ref.S.front_bearing_temp_C"][k] = tb
        out["ref.S.elongation_um"][k] = 3.5 * (th - th0) + 1.2 * (tb - tb0)
        out["X.torque_Nm"][k] = x_torque
        out["X.current_A"][k] = x_current
        out["X.stator_temp_C"][k] = tx
        out["ref.X.nut_temp_C"][k] = tn
    out["S.speed_rpm"] = p["speed"]
    out["X.speed_rpm"] = p["feed"] / 10.0
    out["X.position_mm"] = p["position"]
    out["coolant_on"] = p["coolant"]
    out["ambient_C"] = room
    return out


def ar1(rng, n, sigma, tau):
    a = math.exp(-DT / tau)
    e = rng.standard_normal(n) * sigma * math.sqrt(1 - a * a)
    y = np.empty(n)
    s = rng.standard_normal() * sigma
    for k in range(n):
        s = a * s + e[k]
        y[k] = s
    return y


def left_out(case):
    """The effects a case leaves out: one effect, a pair `a+b`, or none (`nothing`)."""
    return set(case.split("+")) & set(EFFECTS)


def measured(rng, clean, effect, correlated, delay_s, offsets):
    """The real recording: the clean signals through the instruments."""
    out = dict(clean)
    n = len(clean["ambient_C"])
    for name in TARGETS:
        x = clean[name].copy()
        if "signal_delay" in left_out(effect):
            shift = int(round(delay_s / DT))
            x = np.concatenate([np.full(shift, x[0]), x[:-shift]])
        if "sensor_offset_drift" in left_out(effect):
            offset, drift = offsets[name]
            x = x + offset + drift * clean_hours(n)
        white, corr = NOISE[name]
        x = x + rng.standard_normal(n) * white
        if correlated:
            x = x + ar1(rng, n, corr, rng.uniform(120, 900))
        if name.endswith("current_A"):
            x = np.maximum(x, 0.0)  # a drive reports the current's magnitude
        out[name] = x
    return out


def clean_hours(n):
    return np.arange(n) * DT / 3600


def write(path, signals, every, columns, start=0, time_offsets=None,
          source="scripts/independent_cases.py"):
    """Every `every`-th row from `start`, with `time_offsets` (one per row written) added to
    the time stamps, written to the 0.1 ms then."""
    rows = np.column_stack([np.arange(len(signals["ambient_C"])) * DT]
                           + [signals[c] for c in columns])[start::every]
    fmt = "%.6g"
    if time_offsets is not None:
        rows[:, 0] = np.maximum(rows[:, 0] + time_offsets[:len(rows)], 0.0)
        fmt = ["%.4f"] + ["%.6g"] * len(columns)
    with open(path, "w") as f:
        f.write(f"# source: {source}\n")
        f.write(",".join(["time_s"] + columns) + "\n")
        np.savetxt(f, rows, delimiter=",", fmt=fmt)


def draw_case(seed, effect, long_hours=None):
    """A case's draws from `seed` (the machine with everything, without `effect`, and as
    recorded) and each target's effect size over its noise σ: the signals on the internal
    grid, the sample steps it drew (every how many grid steps each file is written), its
    metadata and sizes."""
    rng = np.random.default_rng(seed)
    hours = rng.uniform(4, 8)
    if long_hours is not None:
        hours = long_hours
    p = program(rng, hours)
    inertia = rng.choice([rng.uniform(0.55, 0.75), rng.uniform(1.35, 1.8)])
    delay_s = rng.uniform(6, 40)
    offsets = {t: (rng.choice([-1, 1]) * rng.uniform(0.5, 1.5) * SCALE[t],
                   rng.choice([-1, 1]) * rng.uniform(0.3, 1.0) * SCALE[t]) for t in TARGETS}
    correlated = seed % 2 == 0
    real_every = int(rng.choice([1, 2, 2, 4]))  # 2 Hz, 1 Hz or 0.5 Hz
    sim_every = real_every * (int(rng.choice([1, 1, 5])))  # sometimes an FEA-like coarse export
    if long_hours is not None:
        real_every = sim_every = 1
    full = machine(p, set(), inertia)
    sim = machine(p, left_out(effect), inertia)
    noise_rng = np.random.default_rng(noise_seed(seed, effect))
    real = measured(noise_rng, full, effect, correlated, delay_s, offsets)
    sizes = {}
    for t in TARGETS:
        effect_signal = measured_clean(full, t, effect, delay_s, offsets) - sim[t]
        white, corr = NOISE[t]
        sigma = math.hypot(white, corr) if correlated else white
        sizes[t] = float(np.sqrt(np.mean((effect_signal - effect_signal.mean()) ** 2)) / sigma) \
            if "sensor_offset_drift" not in left_out(effect) else float(
                np.sqrt(np.mean(effect_signal ** 2)) / sigma)
    meta = {"hours": hours, "inertia": inertia, "delay_s": delay_s, "correlated": correlated,
            "real_step_s": real_every * DT, "sim_step_s": sim_every * DT}
    return {"real": real, "sim": sim, "real_every": real_every, "sim_every": sim_every,
            "meta": meta, "sizes": sizes}


def make_case(out, seed, effect, long_hours=None):
    """One case; with `long_hours`, a case seeded like `seed` but run that long at 2 Hz in both
    files, in a directory of its own (a long recording for timing the command, not scored):
    its program begins as the seed's does, and the machine's other draws differ."""
    d = os.path.join(out, f"{effect}-{seed}" if long_hours is None
                     else f"{effect}-{seed}-long{long_hours:g}h")
    if os.path.exists(os.path.join(d, "sizes.json")):
        return d
    os.makedirs(d, exist_ok=True)
    case = draw_case(seed, effect, long_hours)
    columns = OPERATING + TARGETS
    write(os.path.join(d, "real.csv"), case["real"], case["real_every"], columns)
    write(os.path.join(d, "sim.csv"), case["sim"], case["sim_every"], columns)
    json.dump({"sizes": case["sizes"], "case": case["meta"]},
              open(os.path.join(d, "sizes.json"), "w"))
    return d


def noise_seed(seed, effect):
    """The seed of a case's measurement noise: its own for every effect and every pair."""
    if effect in EFFECTS:
        return seed * 7919 + EFFECTS.index(effect)
    if effect == "nothing":
        return seed * 7919 + 99
    a, b = effect.split("+")
    return seed * 7919 + 100 + 10 * EFFECTS.index(a) + EFFECTS.index(b)


def measured_clean(full, name, effect, delay_s, offsets):
    x = full[name]
    if "signal_delay" in left_out(effect):
        shift = int(round(delay_s / DT))
        x = np.concatenate([np.full(shift, x[0]), x[:-shift]])
    if "sensor_offset_drift" in left_out(effect):
        offset, drift = offsets[name]
        x = x + offset + drift * clean_hours(len(x))
    return x


def pairs_main(out, seeds):
    pairs = ["+".join(p) for p in itertools.combinations(EFFECTS, 2)]
    with concurrent.futures.ProcessPoolExecutor(2) as pool:
        # The single cases size each effect of a pair on its own.
        cases = [(e, s) for e in EFFECTS + pairs for s in seeds]
        dirs = dict(zip(cases, pool.map(make_case, *zip(*[(out, s, e) for e, s in cases]))))
    cases = [(p, s, t) for p in pairs for s in seeds for t in TARGETS]
    with concurrent.futures.ThreadPoolExecutor(2) as pool:
        results = list(pool.map(lambda c: analyse(dirs[(c[0], c[1])], c[2]), cases))
    size = {}
    for e in EFFECTS:
        for s in seeds:
            size[(e, s)] = json.load(open(os.path.join(dirs[(e, s)], "sizes.json")))["sizes"]
    both, one = [0, 0], [0, 0]
    print("| outcome | concealed | target | seed | sizes / σ | verdict | named |")
    print("|---|---|---|---|---|---|---|")
    for (pair, seed, target), (report, error) in zip(cases, results):
        effects = pair.split("+")
        sizes = [size[(e, seed)][target] for e in effects]
        shown = " + ".join(f"{v:.2f}" for v in sizes)
        if report is None:
            print(f"| **error** | `{pair}` | `{target}` | {seed} | {shown} | {error} | |")
            continue
        named = [f["physics"] for f in report["findings"]]
        large = [e for e, v in zip(effects, sizes) if v >= LARGE]
        absent = [e for e, v in zip(effects, sizes) if v < ABSENT]
        if len(large) == 2:
            bucket, ok = both, all(e in named for e in effects)
            outcome = "both named" if ok else "**not both**"
        elif len(large) == 1 and len(absent) == 1:
            bucket, ok = one, large[0] in named and absent[0] not in named
            outcome = "the large one" if ok else "**wrong**"
        else:
            bucket, ok, outcome = None, False, "(not scored)"
        if bucket is not None:
            bucket[0] += 1
            bucket[1] += ok
        print(f"| {outcome} | `{pair}` | `{target}` | {seed} | {shown} | {report['verdict']} | "
              f"{', '.join(named) or '—'} |")
    print(f"\nboth large (each ≥ {LARGE} σ alone): {both[1]}/{both[0]} both named")
    print(f"one large, one absent (< {ABSENT} σ): {one[1]}/{one[0]} the large one named "
          f"and the absent one not")


def main():
    if "--long" in sys.argv:
        usage = "usage: independent_cases.py --long SEED EFFECT HOURS OUT_DIR"
        if len(sys.argv) != 6 or sys.argv[1] != "--long":
            sys.exit(usage)
        _, _, seed, effect, hours, out = sys.argv
        if effect not in EFFECTS + ["nothing"]:
            sys.exit(f"{usage}\nunknown effect {effect!r}; one of {', '.join(EFFECTS)}, nothing")
        try:
            seed, hours = int(seed), float(hours)
        except ValueError:
            sys.exit(f"{usage}\nSEED must be a whole number and HOURS a number")
        if not hours > 0:
            sys.exit(f"{usage}\nHOURS must be positive")
        print(make_case(out, seed, effect, hours))
        return
    pairs, out, seeds = command_line("/tmp/independent", "1,2,3")
    if pairs:
        pairs_main(out, seeds)
        return
    effects = EFFECTS + ["nothing"]
    with concurrent.futures.ProcessPoolExecutor(2) as pool:
        dirs = dict(zip([(e, s) for e in effects for s in seeds],
                        pool.map(make_case, *zip(*[(out, s, e) for e in effects
                                                   for s in seeds]))))
    cases = [(e, s, t) for e in effects for s in seeds for t in TARGETS]
    with concurrent.futures.ThreadPoolExecutor(2) as pool:
        results = list(pool.map(lambda c: analyse(dirs[(c[0], c[1])], c[2]), cases))
    tally = {"absent": [0, 0], "large": [0, 0], "nothing": [0, 0]}
    print("| outcome | concealed | target | seed | size / σ | verdict | named |")
    print("|---|---|---|---|---|---|---|")
    for (effect, seed, target), (report, error) in zip(cases, results):
        info = json.load(open(os.path.join(dirs[(effect, seed)], "sizes.json")))
        size = info["sizes"][target] if effect != "nothing" else 0.0
        if report is None:
            print(f"| **error** | `{effect}` | `{target}` | {seed} | {size:.2f} | {error} | |")
            continue
        named = [f["physics"] for f in report["findings"]]
        if effect == "nothing":
            bucket, ok = "nothing", report["verdict"] == "consistent"
        elif size < ABSENT:
            bucket, ok = "absent", report["verdict"] == "consistent"
        elif size >= LARGE:
            bucket, ok = "large", bool(named) and named[0] == effect
        else:
            print(f"| (between) | `{effect}` | `{target}` | {seed} | {size:.2f} | "
                  f"{report['verdict']} | {', '.join(named) or '—'} |")
            continue
        tally[bucket][0] += 1
        tally[bucket][1] += ok
        outcome = {"nothing": "consistent", "absent": "consistent",
                   "large": "named first"}[bucket] if ok else "**wrong**"
        print(f"| {outcome} | `{effect}` | `{target}` | {seed} | {size:.2f} | "
              f"{report['verdict']} | {', '.join(named) or '—'} |")
    print(f"\nnothing concealed: {tally['nothing'][1]}/{tally['nothing'][0]} consistent")
    print(f"absent (< {ABSENT} σ): {tally['absent'][1]}/{tally['absent'][0]} consistent")
    print(f"large (≥ {LARGE} σ): {tally['large'][1]}/{tally['large'][0]} named first")


if __name__ == "__main__":
    main()
