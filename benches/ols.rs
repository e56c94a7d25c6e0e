//! OLS on 1,000,000 rows × 30 coefficients with every statistic (DESIGN.md target: no slower
//! than numpy.linalg.lstsq on the same machine; `benches/ols_numpy.py` times the numpy side).
//!
//! Run with `cargo bench --bench ols`; figures go to `docs/performance.md`.

use std::hint::black_box;
use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};
use servosight::fit::{Design, ols};

const ROWS: usize = 1_000_000;
const COEFFICIENTS: usize = 30;

/// The intercept plus 29 standard-normal regressors, y = Xβ + noise: the shape numpy gets.
fn design() -> Design {
    let mut rng = rand::rngs::StdRng::seed_from_u64(3);
    let normal = Normal::new(0.0, 1.0).expect("valid normal");
    let columns: Vec<(String, Vec<f64>)> = (1..COEFFICIENTS)
        .map(|j| {
            let values = (0..ROWS).map(|_| normal.sample(&mut rng)).collect();
            (format!("x{j}"), values)
        })
        .collect();
    let beta: Vec<f64> = (0..COEFFICIENTS).map(|_| normal.sample(&mut rng)).collect();
    let y = (0..ROWS)
        .map(|i| {
            beta[0]
                + columns
                    .iter()
                    .zip(&beta[1..])
                    .map(|((_, x), b)| b * x[i])
                    .sum::<f64>()
                + normal.sample(&mut rng)
        })
        .collect();
    Design::from_columns("y", y, columns).expect("valid design")
}

fn bench_ols(c: &mut Criterion) {
    let design = design();
    let mut group = c.benchmark_group("ols");
    group.sample_size(10);
    group.measurement_time(Duration::from_secs(15));
    group.bench_function("1M rows x 30 coefficients, full statistics", |b| {
        b.iter(|| ols(black_box(&design)).expect("well-posed fit"))
    });
    group.finish();
}

criterion_group!(benches, bench_ols);
criterion_main!(benches);
