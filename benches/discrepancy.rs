//! Discrepancy analysis speed (issue 5 target: 100,000 rows analysed in ≤ 2 s).
//!
//! Each pair: a 100,000 s production run of the twin at 1 Hz (all effects, realistic noise) as
//! the real recording, and the same program without one effect, noiseless, as the simulation;
//! target `S.stator_temp_C`. The whole analysis is timed: alignment, the physics library,
//! stepwise selection with 99 surrogates per step, refit, held-out figures and localisation.
//!
//! Two effects: copper loss, whose correction is built once, and speed-dependent cooling,
//! the dearest kind — its correction acts on the part's own temperature, so the joint refit
//! rebuilds its whole family on the corrected state, round after round.
//!
//! And a censored target: the spindle's current (a magnitude, at 0 A while the spindle stands)
//! read by a sensor whose zero falls 0.05 A/h through that floor, against the simulation
//! without sensor drift — the step that ends the selection is asked again on the readings as
//! bounds, and every held-out figure is a refit on bounds fold by fold.

use criterion::{Criterion, criterion_group, criterion_main};
use servosight::discrepancy::{Options, analyse};
use servosight::signal::{AxisId, Quantity, Recording, axis_column};
use servosight::sim::{Effect, EffectSet, ScenarioKind, TwinConfig, simulate};

#[path = "../tests/sensor_zero.rs"]
mod sensor_zero;
use sensor_zero::with_zero_falling;

/// The simulation without `effect` and the real run, 100,000 rows each.
fn pair(effect: Effect) -> (Recording, Recording) {
    let hours = 100_000.0 / 3600.0;
    let real_config = TwinConfig::new(ScenarioKind::Production, Some(hours), 11);
    let mut sim_config = real_config.clone();
    sim_config.effects = EffectSet::all().without(effect);
    sim_config.machine.measurement.noise_scale = 0.0;
    let real = simulate(real_config).expect("twin runs");
    let sim = simulate(sim_config).expect("twin runs");
    (sim, real)
}

fn discrepancy_speed(c: &mut Criterion) {
    let target = axis_column(AxisId::S, Quantity::StatorTemp);
    let options = Options::default();
    let mut group = c.benchmark_group("discrepancy");
    group.sample_size(10);
    let current = axis_column(AxisId::S, Quantity::Current);
    for (name, effect, target) in [
        ("analyse_100k_rows", Effect::CopperLoss, &target),
        (
            "analyse_100k_rows_state_dependent",
            Effect::SpeedDependentCooling,
            &target,
        ),
        (
            "analyse_100k_rows_current_at_its_floor",
            Effect::SensorOffsetDrift,
            &current,
        ),
    ] {
        let (sim, mut real) = pair(effect);
        if target == &current {
            real = with_zero_falling(&real, target, 0.05);
        }
        let started = std::time::Instant::now();
        let check = analyse(&sim, &real, target, &options).expect("analysis runs");
        eprintln!(
            "{name}: {} rows in {:.2} s: named {:?}",
            check.rows,
            started.elapsed().as_secs_f64(),
            check
                .findings
                .iter()
                .map(|f| &f.physics)
                .collect::<Vec<_>>()
        );
        group.bench_function(name, |b| {
            b.iter(|| analyse(&sim, &real, target, &options).expect("analysis runs"))
        });
    }
    group.finish();
}

criterion_group!(benches, discrepancy_speed);
criterion_main!(benches);
