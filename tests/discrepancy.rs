//! Sim-vs-real discrepancy (issue 5): a generator of concealed-effect pairs made with the twin,
//! the detection / false-discovery proof, and the `servosight discrepancy` command driven like a
//! user.
//!
//! The "real" run has every effect and realistic (white or AR(1)-correlated) noise; the "sim"
//! run omits one or two effects and is noiseless. The analysis sees only the two recordings —
//! never the generator's metadata (the metadata lines are removed before it runs).

use std::collections::BTreeMap;

use rand::{Rng, SeedableRng};
use servosight::discrepancy::{DiscrepancyReport, Options, Verdict, analyse};
use servosight::signal::{AxisId, Quantity, Recording, axis_column, reference_column};
use servosight::sim::{Effect, EffectSet, MachineParams, ScenarioKind, TwinConfig, simulate};

use crate::common::{arg, servosight, stderr, stdout};

/// The noise of the real run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Noise {
    /// White measurement noise at the twin's default levels.
    White,
    /// 90 % of the noise variance AR(1)-correlated with a 10-minute correlation time.
    Correlated,
}

/// One concealed-effect case.
#[derive(Debug, Clone)]
pub struct Case {
    /// Effects the simulation omits (empty: a negative control).
    pub omitted: Vec<Effect>,
    /// The column compared.
    pub target: String,
    /// Parameter draws applied to both runs (the machine), e.g. a stronger seal friction.
    pub machine: Vec<String>,
    /// Settings that only the real run has (delay, offset, drift: measurement effects).
    pub real_only: Vec<String>,
    /// Noise of the real run.
    pub noise: Noise,
    /// Simulated hours.
    pub hours: f64,
    /// Seed of the program and the noise.
    pub seed: u64,
}

/// The pair of recordings and the noiseless real run (for the truth of the effect).
pub struct Pair {
    /// The simulation.
    pub sim: Recording,
    /// The real recording (noisy).
    pub real: Recording,
    /// The real run without noise: real_clean − sim is the concealed effect itself.
    pub real_clean: Recording,
    /// The target's measurement noise σ in the real run.
    pub noise_sigma: f64,
}

fn strip_metadata(recording: Recording) -> Recording {
    let mut bare =
        Recording::with_schema(recording.source().to_string(), recording.schema().clone());
    let mut row = Vec::new();
    for i in 0..recording.len() {
        recording.row_into(i, &mut row);
        bare.push_row(&row).expect("rows of a valid recording");
    }
    bare
}

/// Makes the pair for `case`.
pub fn make_pair(case: &Case) -> Pair {
    let base = MachineParams::default()
        .with_overrides(&case.machine)
        .expect("valid machine draws");
    let mut real_settings = case.real_only.clone();
    if case.noise == Noise::Correlated {
        real_settings.push("measurement.correlated_fraction=0.9".into());
        real_settings.push("measurement.correlation_time_s=600".into());
    }
    let real_machine = base
        .with_overrides(&real_settings)
        .expect("valid real settings");
    let run = |machine: MachineParams, effects: EffectSet, noise: f64| {
        let machine = machine
            .with_overrides(&[format!("measurement.noise_scale={noise}")])
            .expect("noise scale");
        let config = TwinConfig {
            machine,
            effects,
            scenario: ScenarioKind::Production,
            hours: Some(case.hours),
            rate_hz: 1.0,
            seed: case.seed,
        };
        strip_metadata(simulate(config).expect("the twin runs"))
    };
    let sim_effects = case
        .omitted
        .iter()
        .fold(EffectSet::all(), |set, e| set.without(*e));
    let real = run(real_machine.clone(), EffectSet::all(), 1.0);
    let real_clean = run(real_machine, EffectSet::all(), 0.0);
    let sim = run(base.clone(), sim_effects, 0.0);
    let n = &base.measurement;
    let noise_sigma = if case.target.ends_with("_um") {
        n.displacement_noise_um
    } else if case.target.ends_with("_C") {
        n.temperature_noise_K
    } else if case.target.starts_with("X.torque") {
        n.torque_noise_fraction * base.x_axis.motor.rated_torque_Nm
    } else if case.target.starts_with("S.torque") {
        n.torque_noise_fraction * base.spindle.motor.rated_torque_Nm
    } else if case.target.starts_with("X.current") {
        n.current_noise_fraction * base.x_axis.motor.rated_torque_Nm
            / base.x_axis.motor.torque_constant_Nm_per_A
    } else {
        n.current_noise_fraction * base.spindle.motor.rated_torque_Nm
            / base.spindle.motor.torque_constant_Nm_per_A
    };
    Pair {
        sim,
        real,
        real_clean,
        noise_sigma,
    }
}

/// The target on which each effect is looked for, and a parameter draw for `seed`.
pub fn case_for(effect: Effect, seed: u64, noise: Noise, hours: f64) -> Case {
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed.wrapping_mul(7919) ^ effect as u64);
    let mut draw = |lo: f64, hi: f64| rng.random_range(lo..hi);
    let s_stator = axis_column(AxisId::S, Quantity::StatorTemp);
    let x_torque = axis_column(AxisId::X, Quantity::Torque);
    let elongation = reference_column(AxisId::S, "elongation_um", None);
    let (target, machine, real_only): (String, Vec<String>, Vec<String>) = match effect {
        Effect::AmbientTemperature => (
            reference_column(AxisId::X, "nut_temp_C", None),
            vec![
                format!("room.daily_amplitude_K={:.2}", draw(1.5, 3.0)),
                format!("room.drift_K_per_h={:.3}", draw(-0.1, 0.1)),
            ],
            vec![],
        ),
        Effect::ThermalInertia => (
            reference_column(AxisId::S, "housing_temp_C", None),
            vec![format!(
                "spindle.housing_J_per_K={:.0}",
                draw(120_000.0, 250_000.0)
            )],
            vec![],
        ),
        Effect::SpeedDependentCooling => (
            s_stator,
            vec![format!("spindle.speed_cooling_gain={:.2}", draw(1.0, 2.5))],
            vec![],
        ),
        Effect::LubricantViscosity => (
            axis_column(AxisId::S, Quantity::Torque),
            vec![format!(
                "spindle.lubricant.temperature_coefficient_per_K={:.3}",
                draw(0.025, 0.04)
            )],
            vec![],
        ),
        Effect::CopperLoss => (
            s_stator,
            vec![format!(
                "spindle.motor.phase_resistance_ohm={:.3}",
                draw(0.06, 0.12)
            )],
            vec![],
        ),
        Effect::Coolant => (
            reference_column(AxisId::S, "front_bearing_temp_C", None),
            vec![format!(
                "coolant.spindle_bearing_W_per_K={:.2}",
                draw(2.0, 5.0)
            )],
            vec![],
        ),
        Effect::CoulombReversal => (
            x_torque,
            vec![format!("x_axis.seal_friction_N={:.1}", draw(40.0, 90.0))],
            vec![],
        ),
        Effect::PositionDependent => (
            x_torque,
            vec![format!(
                "x_axis.nut_preload_variation={:.3}",
                draw(0.12, 0.25)
            )],
            vec![],
        ),
        Effect::SignalDelay => (
            x_torque,
            vec![],
            vec![format!(
                "measurement.delay_s={:.0}",
                draw(3.0, 40.0).round()
            )],
        ),
        Effect::SensorOffsetDrift => (
            elongation,
            vec![],
            vec![
                format!("measurement.offset={:.2}", draw(0.5, 3.0)),
                format!("measurement.drift_per_hour={:.2}", draw(0.4, 1.5)),
            ],
        ),
        Effect::IronLoss => (s_stator, vec![], vec![]),
        Effect::Backlash => (x_torque, vec![], vec![]),
    };
    Case {
        omitted: vec![effect],
        target,
        machine,
        real_only,
        noise,
        hours,
        seed,
    }
}

/// The vocabulary's effects (DESIGN.md), in its order.
pub const VOCABULARY: [Effect; 10] = [
    Effect::AmbientTemperature,
    Effect::ThermalInertia,
    Effect::SpeedDependentCooling,
    Effect::LubricantViscosity,
    Effect::CopperLoss,
    Effect::Coolant,
    Effect::CoulombReversal,
    Effect::PositionDependent,
    Effect::SignalDelay,
    Effect::SensorOffsetDrift,
];

/// What one analysis of a case showed.
#[derive(Debug, Clone)]
pub struct Outcome {
    /// The case.
    pub label: String,
    /// Ids named, strongest first.
    pub named: Vec<String>,
    /// Held-out RMSE after correction over the target's noise σ.
    pub rmse_over_noise: f64,
    /// Parameters of the findings.
    pub parameters: BTreeMap<String, BTreeMap<String, f64>>,
    /// Whether the largest mismatch region overlaps where the effect acts.
    pub regions_overlap: bool,
    /// The report.
    pub report: DiscrepancyReport,
}

/// Runs the analysis on a pair made for `case`.
pub fn analyse_pair(case: &Case, pair: &Pair, options: &Options) -> Outcome {
    let report = analyse(&pair.sim, &pair.real, &case.target, options).expect("analysis runs");
    let effect = true_effect(case, pair);
    let time = pair.real.time().to_vec();
    let regions_overlap = regions_overlap(&report, &time, &effect);
    Outcome {
        label: format!(
            "{} on {} seed {} ({:?})",
            if case.omitted.is_empty() {
                "nothing".to_string()
            } else {
                case.omitted
                    .iter()
                    .map(|e| e.id())
                    .collect::<Vec<_>>()
                    .join("+")
            },
            case.target,
            case.seed,
            case.noise
        ),
        named: report.findings.iter().map(|f| f.physics.clone()).collect(),
        rmse_over_noise: report.improved.rmse / pair.noise_sigma,
        parameters: servosight::discrepancy::parameters_by_physics(&report),
        regions_overlap,
        report,
    }
}

/// True when some mismatch region covers a time where the true effect (minus its mean, since
/// an offset is calibration) is larger than its median magnitude.
fn regions_overlap(report: &DiscrepancyReport, time: &[f64], effect: &[f64]) -> bool {
    let m = effect.iter().sum::<f64>() / effect.len() as f64;
    let magnitude: Vec<f64> = effect.iter().map(|e| (e - m).abs()).collect();
    let mut sorted = magnitude.clone();
    sorted.sort_by(f64::total_cmp);
    let median = sorted[sorted.len() / 2];
    report.mismatch_regions.iter().any(|r| {
        time.iter()
            .zip(&magnitude)
            .any(|(t, m)| *t >= r.start_s && *t <= r.end_s && *m > median)
    })
}

fn print_outcome(o: &Outcome) {
    let steps: Vec<String> = o
        .report
        .method
        .steps
        .iter()
        .map(|s| format!("{}:{:.3}:p{:.2}", s.physics, s.relative_gain, s.p_value))
        .collect();
    eprintln!(
        "{:<70} named {:<55} rmse/noise {:5.2} regions {} steps {steps:?} {:?}",
        o.label,
        o.named.join(","),
        o.rmse_over_noise,
        o.regions_overlap,
        o.parameters
    );
}

/// The truth a finding's parameters are checked against, where the physics gives one.
fn check_parameters(case: &Case, outcome: &Outcome, pair_effect_range: f64) -> Vec<String> {
    let mut problems = Vec::new();
    let Some(id) = case.omitted.first().map(|e| e.id()) else {
        return problems;
    };
    let Some(found) = outcome.parameters.get(id) else {
        return vec![format!("{id} not found")];
    };
    let setting = |key: &str| -> f64 {
        case.machine
            .iter()
            .chain(&case.real_only)
            .find_map(|s| s.strip_prefix(key)?.strip_prefix('=')?.parse().ok())
            .unwrap_or(f64::NAN)
    };
    let mut near = |name: &str, value: f64, truth: f64, tolerance: f64| {
        if value.is_nan() || (value - truth).abs() > tolerance {
            problems.push(format!(
                "{name} = {value:.4}, truth {truth:.4} ± {tolerance:.4}"
            ));
        }
    };
    let get = |name: &str| found.get(name).copied().unwrap_or(f64::NAN);
    let machine = MachineParams::default();
    match case.omitted[0] {
        Effect::SignalDelay => near(
            "delay_s",
            get("delay_s"),
            setting("measurement.delay_s"),
            1.0,
        ),
        Effect::SensorOffsetDrift => {
            let drift = setting("measurement.drift_per_hour");
            near("drift_per_hour", get("drift_per_hour"), drift, 0.25 * drift);
            near(
                "offset_at_start",
                get("offset_at_start"),
                setting("measurement.offset"),
                0.5,
            );
        }
        Effect::AmbientTemperature => near("gain_per_K", get("gain_per_K"), 1.0, 0.2),
        Effect::CoulombReversal => {
            // Seal friction through the screw: F · lead / (2π η).
            let x = &machine.x_axis;
            let truth = setting("x_axis.seal_friction_N") * x.screw_lead_mm
                / 1000.0
                / (2.0 * std::f64::consts::PI)
                / x.screw_efficiency;
            near("friction_step", get("friction_step"), truth, 0.25 * truth);
        }
        _ => {}
    }
    // Every correction's size must match the concealed effect's.
    near(
        "effect_range",
        get("effect_range"),
        pair_effect_range,
        0.3 * pair_effect_range,
    );
    problems
}

/// Analyses a case and checks it; returns the problems (empty when everything holds).
fn verify_case(case: &Case, options: &Options) -> (Outcome, Vec<String>) {
    let pair = make_pair(case);
    let outcome = analyse_pair(case, &pair, options);
    let mut problems = Vec::new();
    let effect = true_effect(case, &pair);
    let lo_hi = {
        let mut sorted = effect.clone();
        sorted.sort_by(f64::total_cmp);
        let q = |p: f64| sorted[((sorted.len() - 1) as f64 * p).round() as usize];
        q(0.99) - q(0.01)
    };
    if case.omitted.is_empty() {
        if outcome.report.verdict != Verdict::Consistent || !outcome.named.is_empty() {
            problems.push(format!("false discovery: {:?}", outcome.named));
        }
        return (outcome, problems);
    }
    let wanted: Vec<&str> = case.omitted.iter().map(|e| e.id()).collect();
    if outcome.report.verdict != Verdict::MissingPhysics {
        problems.push("verdict is not missing_physics".into());
    }
    if wanted.len() == 1 && outcome.named.first().map(String::as_str) != Some(wanted[0]) {
        problems.push(format!(
            "named {:?}, wanted {} first",
            outcome.named, wanted[0]
        ));
    }
    for w in &wanted {
        if !outcome.named.iter().any(|n| n == w) {
            problems.push(format!("{w} not named ({:?})", outcome.named));
        }
    }
    if outcome.rmse_over_noise > 1.5 {
        problems.push(format!(
            "held-out RMSE {:.2}× the noise",
            outcome.rmse_over_noise
        ));
    }
    let m = effect.iter().sum::<f64>() / effect.len() as f64;
    let effect_rms =
        (effect.iter().map(|e| (e - m).powi(2)).sum::<f64>() / effect.len() as f64).sqrt();
    if effect_rms > 0.5 * pair.noise_sigma && !outcome.regions_overlap {
        problems.push("no mismatch region where the effect acts".into());
    }
    if wanted.len() == 1 {
        problems.extend(check_parameters(case, &outcome, lo_hi));
    }
    (outcome, problems)
}

/// The concealed effect itself: noiseless real minus sim.
fn true_effect(case: &Case, pair: &Pair) -> Vec<f64> {
    pair.real_clean
        .column(&case.target)
        .unwrap()
        .iter()
        .zip(pair.sim.column(&case.target).unwrap())
        .map(|(r, s)| r - s)
        .collect()
}

#[test]
#[ignore = "exploration: prints the analysis of one case per effect"]
fn explore_one_seed_per_effect() {
    for noise in [Noise::White, Noise::Correlated] {
        for effect in VOCABULARY {
            let case = case_for(effect, 1, noise, 5.0);
            let started = std::time::Instant::now();
            let (outcome, problems) = verify_case(&case, &Options::default());
            print_outcome(&outcome);
            eprintln!("   {:.1} s {problems:?}", started.elapsed().as_secs_f64());
        }
    }
}

/// Cases of the default test run: every vocabulary effect, once with white and once with
/// correlated noise, on short recordings.
#[test]
fn every_concealed_effect_is_named_first_fitted_and_localised() {
    let mut failures = Vec::new();
    for (i, effect) in VOCABULARY.into_iter().enumerate() {
        for (noise, seed) in [
            (Noise::White, 11 + i as u64),
            (Noise::Correlated, 31 + i as u64),
        ] {
            let case = case_for(effect, seed, noise, 4.0);
            let (outcome, problems) = verify_case(&case, &Options::default());
            print_outcome(&outcome);
            if !problems.is_empty() {
                failures.push(format!("{}: {}", outcome.label, problems.join("; ")));
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// Negative controls: nothing omitted, white and strongly correlated noise: consistent, no
/// findings.
#[test]
fn negative_controls_are_consistent() {
    let mut failures = Vec::new();
    let targets = [
        axis_column(AxisId::S, Quantity::StatorTemp),
        axis_column(AxisId::X, Quantity::Torque),
        reference_column(AxisId::S, "elongation_um", None),
    ];
    for (k, target) in targets.iter().enumerate() {
        for noise in [Noise::White, Noise::Correlated] {
            let case = Case {
                omitted: vec![],
                target: target.clone(),
                machine: vec![],
                real_only: vec![],
                noise,
                hours: 4.0,
                seed: 50 + k as u64,
            };
            let (outcome, problems) = verify_case(&case, &Options::default());
            print_outcome(&outcome);
            if !problems.is_empty() {
                failures.push(format!("{}: {}", outcome.label, problems.join("; ")));
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// The cases with two effects concealed at once.
pub fn two_effect_cases(seed: u64, noise: Noise) -> Vec<Case> {
    vec![
        Case {
            omitted: vec![Effect::AmbientTemperature, Effect::CopperLoss],
            target: axis_column(AxisId::S, Quantity::StatorTemp),
            machine: vec!["room.daily_amplitude_K=2.5".into()],
            real_only: vec![],
            noise,
            hours: 5.0,
            seed,
        },
        Case {
            omitted: vec![Effect::CoulombReversal, Effect::PositionDependent],
            target: axis_column(AxisId::X, Quantity::Torque),
            machine: vec![],
            real_only: vec![],
            noise,
            hours: 4.0,
            seed,
        },
        Case {
            omitted: vec![Effect::SensorOffsetDrift, Effect::AmbientTemperature],
            target: reference_column(AxisId::X, "nut_temp_C", None),
            machine: vec!["room.daily_amplitude_K=2.0".into()],
            real_only: vec![
                "measurement.offset=0.3".into(),
                "measurement.drift_per_hour=0.15".into(),
            ],
            noise,
            hours: 5.0,
            seed,
        },
    ]
}

#[test]
fn two_concealed_effects_are_both_named() {
    let mut failures = Vec::new();
    for case in two_effect_cases(7, Noise::White) {
        let (outcome, problems) = verify_case(&case, &Options::default());
        print_outcome(&outcome);
        if !problems.is_empty() {
            failures.push(format!("{}: {}", outcome.label, problems.join("; ")));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn the_command_reports_bad_input_in_one_line() {
    let dir = tempfile::tempdir().unwrap();
    let a = dir.path().join("a.csv");
    let b = dir.path().join("b.csv");
    std::fs::write(&a, "time_s,S.stator_temp_C\n0,20\n1,20.1\n2,20.2\n").unwrap();
    std::fs::write(&b, "time_s,S.stator_temp_C\n100,20\n101,20.1\n").unwrap();
    let run = servosight(&[
        "discrepancy",
        "--sim",
        arg(&a),
        "--real",
        arg(&b),
        "--target",
        "S.stator_temp_C",
    ]);
    assert!(!run.status.success());
    let err = stderr(&run);
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.contains("do not overlap"), "{err}");
    let missing = servosight(&[
        "discrepancy",
        "--sim",
        arg(&a),
        "--real",
        arg(&a),
        "--target",
        "X.torque_Nm",
    ]);
    assert!(!missing.status.success());
    let err = stderr(&missing);
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(
        err.contains("X.torque_Nm") && err.contains("not a column"),
        "{err}"
    );
    let _ = stdout(&missing);
}
