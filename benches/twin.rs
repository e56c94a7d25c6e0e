//! Twin speed: simulated hours per wall-clock second (issue target: a day well under a second).

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use servosight::sim::{ScenarioKind, Twin, TwinConfig};

fn simulate_hours(scenario: ScenarioKind, hours: f64) -> usize {
    let mut twin = Twin::new(TwinConfig::new(scenario, Some(hours), 1)).expect("valid config");
    let mut row = Vec::new();
    let mut rows = 0;
    while twin.next_row(&mut row) {
        rows += 1;
    }
    rows
}

fn twin_speed(c: &mut Criterion) {
    let mut group = c.benchmark_group("twin");
    group.sample_size(10);
    // Throughput in "elements" = simulated seconds, so criterion reports simulated s per s.
    group.throughput(Throughput::Elements(24 * 3600));
    group.bench_function("production_24h_at_1hz", |b| {
        b.iter(|| simulate_hours(ScenarioKind::Production, 24.0))
    });
    group.bench_function("doe_24h_at_1hz", |b| {
        b.iter(|| simulate_hours(ScenarioKind::Doe, 24.0))
    });
    group.finish();
}

criterion_group!(benches, twin_speed);
criterion_main!(benches);
