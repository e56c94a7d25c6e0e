//! The full estimator pipeline on a 5-axis frame (DESIGN target: ≥ 2 M frames/s on one core).
//!
//! The machine: three feed axes (X, Y, Z) with every feed-axis estimator (motor flange, torque
//! split, front/back bearing and nut heat and temperature, straightness at 5 nodes H and V with
//! the ISO 1101 zone and the motor abnormality score), a spindle S with thermal elongation and
//! the abnormality score, and a rotary C axis in the frame.
//! Models are the shipped calibration of the twin's machine (`assets/it25-twin.toml`, fitted by
//! `scripts/accuracy.sh` on a 48 h database and an 8 h experiment, so they read every input its
//! selection found worth reading), X's copied to Y and Z.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use servosight::estimators::EstimatorPipeline;
use servosight::profile::MachineProfile;
use servosight::signal::{AxisId, Quantity, Recording, Schema, axis_column};
use servosight::sim::{ScenarioKind, TwinConfig, simulate};

fn five_axis_setup() -> (MachineProfile, Schema, Vec<Vec<f64>>) {
    let mut profile = MachineProfile::twin_calibrated().expect("the shipped profile loads");
    let mut calibration = profile
        .calibration
        .take()
        .expect("the shipped profile is calibrated");
    for axis in [AxisId::Y, AxisId::Z] {
        let x_models = calibration.axes[&AxisId::X].clone();
        calibration.axes.insert(axis, x_models);
        let x_profile = profile.axes[&AxisId::X].clone();
        profile.axes.insert(axis, x_profile);
    }
    profile.calibration = Some(calibration);
    // A 5-axis frame layout: X, Y, Z, S, C servo columns plus the room, the coolant and the
    // depth of cut.
    let source: Recording =
        simulate(TwinConfig::new(ScenarioKind::Production, Some(2.0), 4)).expect("twin runs");
    let mut names = vec!["time_s".to_string()];
    let quantities = [
        Quantity::Position,
        Quantity::Speed,
        Quantity::Torque,
        Quantity::Current,
        Quantity::Load,
        Quantity::StatorTemp,
    ];
    let axes = [AxisId::X, AxisId::Y, AxisId::Z, AxisId::S, AxisId::C];
    for axis in axes {
        for q in quantities {
            names.push(axis_column(axis, q));
        }
    }
    names.push("ambient_C".into());
    names.push("coolant_on".into());
    names.push("cut_depth_mm".into());
    let schema = Schema::new(names.clone(), "bench").expect("valid names");
    let frames = (0..source.len())
        .map(|i| {
            names
                .iter()
                .map(|name| {
                    let machine_level = ["time_s", "ambient_C", "coolant_on", "cut_depth_mm"];
                    let from = if machine_level.contains(&name.as_str()) {
                        name.clone()
                    } else {
                        // Y, Z and C replay X's and S's signals.
                        name.replacen("Y.", "X.", 1)
                            .replacen("Z.", "X.", 1)
                            .replacen("C.", "S.", 1)
                    };
                    source.try_column(&from).map_or(0.0, |c| c[i])
                })
                .collect()
        })
        .collect();
    (profile, schema, frames)
}

fn pipeline(c: &mut Criterion) {
    let (profile, schema, frames) = five_axis_setup();
    let mut pipeline = EstimatorPipeline::new(&profile, &schema).expect("binds");
    let mut group = c.benchmark_group("estimator_pipeline");
    group.throughput(Throughput::Elements(frames.len() as u64));
    group.bench_function("five_axis_frames", |b| {
        b.iter(|| {
            for frame in &frames {
                pipeline.update(frame);
            }
            pipeline.feed_axis(AxisId::Z).map(|e| e.nut_C)
        })
    });
    // The same frames stamped 1 ms apart, as a 1 kHz recording counts them: the abnormality
    // scores then close a 1 s block on one frame in a thousand, where on the twin's 1 s rows
    // every frame closes one, and the steps differ by a few ulp from frame to frame.
    let live: Vec<Vec<f64>> = frames
        .iter()
        .enumerate()
        .map(|(i, frame)| {
            let mut frame = frame.clone();
            frame[0] = i as f64 * 1e-3;
            frame
        })
        .collect();
    let mut pipeline = EstimatorPipeline::new(&profile, &schema).expect("binds");
    group.bench_function("five_axis_frames_at_1khz", |b| {
        b.iter(|| {
            for frame in &live {
                pipeline.update(frame);
            }
            pipeline.feed_axis(AxisId::Z).map(|e| e.nut_C)
        })
    });
    group.finish();
}

criterion_group!(benches, pipeline);
criterion_main!(benches);
