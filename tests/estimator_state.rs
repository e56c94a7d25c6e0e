//! How well estimators that carry on from a saved state follow the machine after a break (the
//! HMI closed while the machine went on), against estimators started afresh at the same frame,
//! and how well estimators follow it after a gap in their frames, stepped over or started
//! again: the tables in docs/accuracy.md (*An HMI restarted mid-shift*, *A gap in the frames*).
//!
//! `cargo test --release --test tests estimator_state -- --ignored --nocapture`

use servosight::estimators::EstimatorPipeline;
use servosight::estimators::state::{Clock, SavedState};
use servosight::profile::MachineProfile;
use servosight::signal::Recording;
use servosight::sim::{ScenarioKind, TwinConfig, simulate};

/// Every output after each frame of `rows` (NaN as `None`).
fn run(
    pipeline: &mut EstimatorPipeline,
    recording: &Recording,
    rows: impl Iterator<Item = usize>,
) -> Vec<Vec<Option<f64>>> {
    let (mut frame, mut out) = (Vec::new(), Vec::new());
    rows.map(|i| {
        recording.row_into(i, &mut frame);
        pipeline.update(&frame);
        pipeline.write_outputs(&mut out);
        out.iter().map(|v| v.is_finite().then_some(*v)).collect()
    })
    .collect()
}

/// Mean absolute difference of output `j` between two runs over the frames both have.
fn mean_difference(a: &[Vec<Option<f64>>], b: &[Vec<Option<f64>>], j: usize) -> f64 {
    let d: Vec<f64> = a
        .iter()
        .zip(b)
        .filter_map(|(x, y)| Some((x[j]? - y[j]?).abs()))
        .collect();
    d.iter().sum::<f64>() / d.len().max(1) as f64
}

/// The estimates the tables compare.
const COLUMNS: [&str; 7] = [
    "est.X.motor_flange_temp_C",
    "est.X.front_bearing_temp_C",
    "est.X.back_bearing_temp_C",
    "est.X.nut_temp_C",
    "est.X.straightness_h_zone_um",
    "est.X.straightness_v_zone_um",
    "est.S.elongation_um",
];

/// Eight hours of the twin's production program at 1 Hz for seeds 1 to 3.
fn production_shifts() -> Vec<Recording> {
    (1..=3)
        .map(|seed| {
            let mut config = TwinConfig::new(ScenarioKind::Production, Some(8.0), seed);
            config.rate_hz = 1.0;
            simulate(config).unwrap()
        })
        .collect()
}

#[test]
#[ignore = "a table for docs/accuracy.md (a few seconds in release)"]
fn estimates_after_a_break_carried_on_and_afresh() {
    let profile = MachineProfile::twin_calibrated().unwrap();
    let columns = COLUMNS;
    println!("| break | {} |", columns.join(" | "));
    println!("|---|{}", "---|".repeat(columns.len()));
    let recordings = production_shifts();
    for break_s in [60usize, 120, 179, 240, 299] {
        // Per column: (carried on, afresh) summed over cases.
        let mut sums = vec![(0.0, 0.0); columns.len()];
        let mut cases = 0;
        for recording in &recordings {
            let schema = recording.schema();
            for saved_at in [2 * 3600, 4 * 3600, 6 * 3600] {
                let back_at = saved_at + break_s;
                let hour = back_at..back_at + 3600;
                let mut through = EstimatorPipeline::new(&profile, schema).unwrap();
                run(&mut through, recording, 0..saved_at);
                let mut frame = Vec::new();
                recording.row_into(saved_at - 1, &mut frame);
                let saved: SavedState = through.save_state(&frame).unwrap();
                let expected = run(&mut through, recording, saved_at..back_at + 3600);
                let expected = &expected[break_s..];
                recording.row_into(back_at, &mut frame);
                let resume = saved
                    .check_resume(schema, &frame, Clock::Continued)
                    .expect("within the break's tolerance");
                assert_eq!(resume.gap_s, (break_s + 1) as f64);
                let mut carried = EstimatorPipeline::new(&profile, schema).unwrap();
                carried.restore_state(&saved).unwrap();
                carried.carry_on(&resume);
                let carried = run(&mut carried, recording, hour.clone());
                let mut afresh = EstimatorPipeline::new(&profile, schema).unwrap();
                let afresh = run(&mut afresh, recording, hour);
                let outputs: Vec<String> =
                    through.outputs().into_iter().map(|o| o.column).collect();
                for (k, column) in columns.iter().enumerate() {
                    let j = outputs.iter().position(|c| c == column).unwrap();
                    sums[k].0 += mean_difference(&carried, expected, j);
                    sums[k].1 += mean_difference(&afresh, expected, j);
                }
                cases += 1;
            }
        }
        let cells: Vec<String> = sums
            .iter()
            .map(|(c, a)| format!("{:.3} / {:.3}", c / cases as f64, a / cases as f64))
            .collect();
        println!("| {break_s} s | {} |", cells.join(" | "));
    }
}

/// A gap in the frames (a link down, a piece of the recording missing): estimators that step
/// over it, holding the inputs of the first frame after it across it, against the pipeline as
/// built, which steps over gaps of up to five minutes and starts the feed axes' heat and lags
/// again after longer ones (the elongation stepping over every gap); both against estimators
/// that saw every frame, over the hour after the gap. Also the elongation's worst error
/// stepped over.
#[test]
#[ignore = "a table for docs/accuracy.md (a few seconds in release)"]
fn estimates_after_a_gap_in_the_frames_stepped_over_and_started_again() {
    let profile = MachineProfile::twin_calibrated().unwrap();
    let columns = COLUMNS;
    println!("| gap | {} | elongation, worst |", columns.join(" | "));
    println!("|---|{}---|", "---|".repeat(columns.len()));
    let recordings = production_shifts();
    for gap_s in [120usize, 300, 600, 1200, 1800, 3600] {
        // Per column: (stepped over, as built) summed over cases.
        let mut sums = vec![(0.0, 0.0); columns.len()];
        let mut worst: f64 = 0.0;
        let mut cases = 0;
        for recording in &recordings {
            let schema = recording.schema();
            for gap_from in [2 * 3600, 3 * 3600 + 1200, 5 * 3600] {
                // The step from the last frame before the gap to the first after it.
                let back_at = gap_from - 1 + gap_s;
                let mut through = EstimatorPipeline::new(&profile, schema).unwrap();
                let expected = run(&mut through, recording, 0..back_at + 3600);
                let expected = &expected[back_at..];
                let rows = || (0..gap_from).chain(back_at..back_at + 3600);
                let mut stepped = EstimatorPipeline::new(&profile, schema).unwrap();
                stepped.step_over_gaps_up_to(f64::INFINITY);
                let stepped = run(&mut stepped, recording, rows());
                let mut built = EstimatorPipeline::new(&profile, schema).unwrap();
                let built = run(&mut built, recording, rows());
                let (stepped, built) = (&stepped[gap_from..], &built[gap_from..]);
                let outputs: Vec<String> =
                    through.outputs().into_iter().map(|o| o.column).collect();
                let index = |column: &str| outputs.iter().position(|c| c == column).unwrap();
                for (k, column) in columns.iter().enumerate() {
                    sums[k].0 += mean_difference(stepped, expected, index(column));
                    sums[k].1 += mean_difference(built, expected, index(column));
                }
                let j = index("est.S.elongation_um");
                worst = stepped
                    .iter()
                    .zip(expected)
                    .filter_map(|(a, b)| Some((a[j]? - b[j]?).abs()))
                    .fold(worst, f64::max);
                cases += 1;
            }
        }
        let cells: Vec<String> = sums
            .iter()
            .map(|(c, a)| format!("{:.3} / {:.3}", c / cases as f64, a / cases as f64))
            .collect();
        println!("| {gap_s} s | {} | {worst:.1} |", cells.join(" | "));
    }
}
