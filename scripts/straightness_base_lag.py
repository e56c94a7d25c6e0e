#!/usr/bin/env python3
"""Does a lagged room temperature (a slow state for the bed's base) help the X straightness?

Measures, for nodes V#3 and H#3, the validation-day R² of Eq. 13/14's linear form (motor
flange, front and back bearing temperatures, room) with and without lag(room, τ), fitted
(a) on the reference temperatures of the experiment shift, (b) on the estimated temperatures
of the experiment shift, and (c) on the estimated temperatures of the DOE database — (c) is
how `servosight calibrate` fits. Run `bash scripts/accuracy.sh` first; needs numpy.

    python3 scripts/straightness_base_lag.py [target/accuracy]
"""

import os
import subprocess
import sys

import numpy as np

OUT = sys.argv[1] if len(sys.argv) > 1 else "target/accuracy"
SERVOSIGHT = "target/release/servosight"


def load(path):
    with open(path) as f:
        lines = [line for line in f if not line.startswith("#")]
    header = lines[0].strip().split(",")
    data = np.genfromtxt(lines[1:], delimiter=",")
    return {name: data[:, i] for i, name in enumerate(header)}


def estimates(recording):
    path = os.path.join(OUT, f"est_{recording}.csv")
    if not os.path.exists(path):
        subprocess.run(
            [SERVOSIGHT, "estimate", "--profile", os.path.join(OUT, "profile.toml"),
             "--recording", os.path.join(OUT, f"{recording}.csv"), "-o", path],
            check=True, stdout=subprocess.DEVNULL)
    return load(path)


def lag(x, t, tau):
    y = np.empty_like(x)
    y[0] = x[0]
    a = np.exp(-np.diff(t) / tau)
    for i in range(1, len(x)):
        y[i] = a[i - 1] * y[i - 1] + (1 - a[i - 1]) * x[i]
    return y


def design(recording, temperatures, prefix, tau):
    columns = [np.ones_like(recording["time_s"])]
    for name in ("motor_flange_temp_C", "front_bearing_temp_C", "back_bearing_temp_C"):
        columns.append(temperatures[prefix + name])
    columns.append(recording["ambient_C"])
    if tau:
        columns.append(lag(recording["ambient_C"], recording["time_s"], tau))
    return np.column_stack(columns)


def r2(y, predicted):
    return 1 - np.sum((y - predicted) ** 2) / np.sum((y - y.mean()) ** 2)


validation = load(os.path.join(OUT, "validation.csv"))
validation_estimates = estimates("validation")
experiment = load(os.path.join(OUT, "experiment.csv"))
database = load(os.path.join(OUT, "db.csv"))
fits = [
    ("reference temperatures, experiment", experiment, experiment, "ref.X.", validation),
    ("estimated temperatures, experiment", experiment, estimates("experiment"), "est.X.",
     validation_estimates),
    ("estimated temperatures, DOE database", database, estimates("db"), "est.X.",
     validation_estimates),
]
print("node | fitted on | no lag | τ 20 min | τ 30 min | τ 60 min")
for node in ("v_um#3", "h_um#3"):
    for label, train, train_temperatures, prefix, validation_temperatures in fits:
        y_train = train["ref.X.straightness_" + node]
        y_validation = validation["ref.X.straightness_" + node]
        row = []
        for tau in (None, 1200, 1800, 3600):
            beta = np.linalg.lstsq(design(train, train_temperatures, prefix, tau), y_train,
                                   rcond=None)[0]
            validation_prefix = "ref.X." if prefix == "ref.X." else "est.X."
            source = validation if prefix == "ref.X." else validation_temperatures
            x = design(validation, source, validation_prefix, tau)
            row.append(f"{r2(y_validation, x @ beta):.3f}")
        print(f"{node} | {label} | " + " | ".join(row))
