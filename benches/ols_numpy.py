#!/usr/bin/env python3
"""The numpy side of benches/ols.rs: numpy.linalg.lstsq on 1,000,000 x 30 (intercept + 29
standard-normal regressors), and statsmodels OLS with its summary for reference when installed.

    python3 benches/ols_numpy.py            # numpy with its default BLAS threads
    OPENBLAS_NUM_THREADS=1 python3 benches/ols_numpy.py   # one core, like the Rust benchmark
"""

import statistics
import time

import numpy as np

ROWS, COEFFICIENTS, REPEATS = 1_000_000, 30, 7

rng = np.random.default_rng(3)
X = np.column_stack([np.ones(ROWS), rng.standard_normal((ROWS, COEFFICIENTS - 1))])
y = X @ rng.standard_normal(COEFFICIENTS) + rng.standard_normal(ROWS)


def timed(label, run, repeats=REPEATS):
    run()  # warm-up
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        run()
        times.append(time.perf_counter() - start)
    print(f"{label}: median {statistics.median(times):.3f} s, min {min(times):.3f} s over {repeats} runs")


timed("numpy.linalg.lstsq 1M x 30", lambda: np.linalg.lstsq(X, y, rcond=None))

try:
    import statsmodels.api as sm
except ImportError:
    print("statsmodels not installed: skipped")
else:
    timed("statsmodels OLS fit + summary 1M x 30", lambda: sm.OLS(y, X).fit().summary(), repeats=3)

try:
    from threadpoolctl import threadpool_info

    for pool in threadpool_info():
        print(f"BLAS: {pool.get('internal_api')} {pool.get('version')}, {pool.get('num_threads')} threads")
except ImportError:
    pass
