//! Calibration, the paper's way: fit every estimator's model on a large simulation database,
//! then let a few real experiments correct it.
//!
//! Models are fitted in the order they depend on each other: motor flange and torque ratios
//! from raw servo signals; bearing and nut temperatures from the heat of the *estimated* split
//! torques (so a model is fitted on the inputs it will see in service); straightness from the
//! *estimated* temperatures; spindle elongation from the spindle's signals. Time constants of
//! heat accumulation and whether the room temperature enters a model are chosen by time-blocked
//! cross-validation (neighbouring samples are correlated, so random folds would flatter).
//!
//! Experiments correct the database the way the paper does it: each model's predictions on the
//! experiment recordings are regressed on the measured values, y = a + b·ŷ; when that correction
//! helps on experiment data it was not fitted on (see [`ExperimentCorrection`]) it is folded
//! into the model's coefficients. Where an offset or a gain cannot mend the database's response
//! (the twin's DOE sweeps speeds, loads and coolant far from a production day's mix), the
//! experiments may instead join the fit, weighted to count as much as the whole database, when
//! blocked cross-validation over them says that predicts them better.
#![allow(non_snake_case)] // unit suffixes (`_C`, `_Nm`) are part of the names

use std::collections::{BTreeMap, BTreeSet};

use crate::discrepancy::series::{rms, span};
use crate::fit::autocorrelation::mean_above_zero;
use crate::fit::{Design, FitError, OlsFit, OlsOptions, blocked_cross_validation, ols, wls};
use crate::profile::{AxisKind, MachineProfile};
use crate::signal::channel::{AMBIENT, COOLANT};
use crate::signal::{AxisId, Quantity, Recording, axis_column, reference_column};

use super::abnormality::{self, TorqueBlock};
use super::models::{
    AMBIENT_LAG_FEATURES, AMBIENT_LAG_TAUS_S, AbnormalityModel, AxisModels, BED_LAG_FEATURES,
    BED_LAG_TAUS_S, COOLANT_LAG_FEATURES, Calibration, ELONGATION_FEATURES, ELONGATION_TAU_NAMES,
    ElongationModel, FAST_HEAT_DIVISOR, HeatModel, IDEAL_TORQUE_FEATURES, LinearModel,
    PART_ACCUMULATIONS, STATOR_LAG_FEATURES, STATOR_LAG_TAUS_S, WarmStart, warm_excess,
};
use super::pipeline::EstimatorPipeline;
use super::streaming::{
    ElongationFeatures, ElongationInputs, HeatAccumulator, HeatInputs, RoomLags, SettledLags,
    SpeedHeat, StraightnessInputs, TorqueSplitEstimator, heat_inputs,
};
use crate::parallel::parallel_map;

/// Candidate heat-accumulation time constants, s.
const HEAT_TAUS_S: &[f64] = &[300.0, 600.0, 900.0, 1200.0, 1800.0, 2700.0, 3600.0];
/// Candidate (fast, middle, slow) time constants of the elongation model's speed and load
/// heat, s. Each is tried with the fast and slow terms only and with all three.
const ELONGATION_TAUS_S: &[(f64, f64, f64)] = &[
    (200.0, 1000.0, 5000.0),
    (300.0, 1800.0, 7200.0),
    (600.0, 2400.0, 9600.0),
    (900.0, 3600.0, 7200.0),
    (1200.0, 3600.0, 5400.0),
    (1800.0, 3600.0, 7200.0),
];
/// Time constants of the elongation's full heat bank (every input of
/// `ELONGATION_HEAT_INPUTS` over each), s: from the bearings' minutes to the bed's hours.
const ELONGATION_BANK_TAUS_S: [f64; 4] = [600.0, 1800.0, 5400.0, 16200.0];
/// `ModelReport::selected_by` of a model the experiments were fitted into.
const SELECTED_BY_JOINED: &str = "experiments_joined";
/// Blocks of the time-blocked cross-validation.
const CV_FOLDS: usize = 5;
/// Rows dropped on each side of a held-out block (at 1 Hz: 10 minutes).
const CV_GAP_ROWS: usize = 600;
/// Significance a correction's held-out improvement needs before it is applied.
const CORRECTION_ALPHA: f64 = 0.05;
/// Experiments correct a model only with at least this many reference samples.
const MIN_EXPERIMENT_ROWS: usize = 30;
/// Time constants of the free start of an experiment that begins on a warm machine, s: from
/// a part's fast heat (τ / 4 of `HEAT_TAUS_S`, 75–900 s) to the room's hours, three apart
/// (an experiment keeps those no longer than itself). Every model's accumulations and lags begin that recording from
/// rest (or settled) where the machine held heat they never saw; in a model linear in them,
/// each state's unknown start adds its own decay, e^(−(t − t₀)/τ), at its own τ, and a sum of
/// decays three apart stands for any mixture of those.
const START_DECAY_TAUS_S: [f64; 5] = [150.0, 450.0, 1350.0, 4050.0, 12150.0];
/// The prefix of the free-start terms ([`START_DECAY_TAUS_S`]), which are fitted and never
/// kept in a model (a machine's start is its own, not the model's).
const START_TERM: &str = "warm_start_decay";

/// Why calibration failed.
#[derive(Debug, thiserror::Error)]
pub enum CalibrationError {
    /// No database recording.
    #[error("no database recording given")]
    NoDatabase,
    /// A database recording has no reference instrument columns to fit the estimators to.
    #[error(
        "{recording} has no reference columns (ref.*): the estimators are fitted to the \
         reference instruments of the database, so there is nothing to calibrate from it"
    )]
    NoReferences {
        /// The recording's source.
        recording: String,
    },
    /// A regression failed.
    // The regression's error is part of the message and not a `source`, so that a chain
    // printed whole (`{:#}`) does not say it twice.
    #[error("{estimate}: {error}")]
    Fit {
        /// The model being fitted.
        estimate: String,
        /// The regression's error.
        error: FitError,
    },
    /// A recording lacks what a model needs.
    #[error("{0}")]
    Recording(#[from] crate::signal::RecordingError),
    /// The fitted models do not form a working pipeline.
    #[error("{0}")]
    Pipeline(#[from] super::pipeline::PipelineError),
    /// The database gives nothing to fit for a model the profile needs.
    #[error("{estimate}: {message}")]
    NoData {
        /// The model.
        estimate: String,
        /// Why.
        message: String,
    },
}

/// One fitted model in the calibration report (DESIGN.md's contract plus the out-of-sample R²).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ModelReport {
    /// Which estimate (`motor_flange_temp`, `straightness_h#3`, …) and axis.
    pub estimate: String,
    /// The fitted equation with its coefficients.
    pub equation: String,
    /// Samples.
    pub n: usize,
    /// In-sample R².
    pub r2: f64,
    /// F statistic (Eq. 3).
    pub f_statistic: f64,
    /// Its p-value.
    pub f_p_value: f64,
    /// Time-blocked cross-validated R².
    pub cv_r2: f64,
    /// How the model form (time constants, optional terms) was chosen: on the `experiments`
    /// (a database fit), by `blocked_cv` on the database, or `experiments_joined` (fitted on
    /// the database and the experiments together, scored by blocked cross-validation over the
    /// experiments; no correction follows, the experiments are already in the fit).
    pub selected_by: &'static str,
    /// The R² that chose it (on the experiments, or cross-validated).
    pub selection_r2: f64,
    /// The correction the experiments made, if any.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub experiment_correction: Option<ExperimentCorrection>,
    /// What the database lacks for this model, when calibration can tell (the motor
    /// abnormality's steady running at a single speed, or none at all), whatever the held-out
    /// figure: the model then rests on the experiments, and a held-out block of theirs is
    /// predicted from what the database lacks. Says what a better database holds.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub coverage: Option<String>,
}

/// How experiments corrected a model: measured = offset + gain · database prediction.
///
/// The form is chosen by how well each predicts experiment data it was not fitted on (each
/// experiment's halves held out in turn): a correction fitted to a short cold-start run often
/// only describes that run's transient, and an F-test on thousands of autocorrelated samples
/// calls every such correction significant.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ExperimentCorrection {
    /// Experiment samples used.
    pub n: usize,
    /// The form applied.
    pub form: CorrectionForm,
    /// Offset a (0 unless applied).
    pub offset: f64,
    /// Gain b (1 unless a gain correction is applied).
    pub gain: f64,
    /// Held-out RMSE on the experiments without a correction.
    pub cv_rmse_none: f64,
    /// Held-out RMSE with an offset correction (NaN where an offset cannot apply).
    pub cv_rmse_offset: f64,
    /// Held-out RMSE with a gain-only correction (NaN where it is not considered).
    pub cv_rmse_gain: f64,
    /// Held-out RMSE with a gain and offset correction.
    pub cv_rmse_gain_offset: f64,
    /// One-sided p-value that the best form's held-out improvement is real (Diebold–Mariano
    /// on squared errors with the effective sample size); NaN when no form beat none.
    pub improvement_p_value: f64,
    /// RMSE on the experiments before the correction.
    pub rmse_before: f64,
    /// RMSE on the experiments after it (fitted on all of them).
    pub rmse_after: f64,
    /// Whether a correction was applied.
    pub applied: bool,
    /// Whether it was weighed on experiments that begin warm with their start taken out
    /// (an estimate counted from the first row, where no experiment from rest teaches it):
    /// the start was fitted with the gain on every row, and the RMSEs above are against the
    /// reference without it.
    pub warm_start_taken_out: bool,
}

/// The corrections experiments can make to a database model.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum CorrectionForm {
    /// The database model stands.
    None,
    /// measured = a + predicted.
    Offset,
    /// measured = b·predicted (for estimators zeroed at a calibration moment).
    Gain,
    /// measured = a + b·predicted.
    GainOffset,
}

impl CorrectionForm {
    /// Fits the form on `(predicted, measured)` pairs: (offset, gain).
    fn fit(self, predicted: &[f64], measured: &[f64]) -> Option<(f64, f64)> {
        let n = predicted.len() as f64;
        match self {
            CorrectionForm::None => Some((0.0, 1.0)),
            CorrectionForm::Offset => {
                let mean = predicted
                    .iter()
                    .zip(measured)
                    .map(|(p, m)| m - p)
                    .sum::<f64>()
                    / n;
                mean.is_finite().then_some((mean, 1.0))
            }
            CorrectionForm::Gain => {
                let pp: f64 = predicted.iter().map(|p| p * p).sum();
                let pm: f64 = predicted.iter().zip(measured).map(|(p, m)| p * m).sum();
                let gain = pm / pp;
                (gain.is_finite() && gain > 0.0).then_some((0.0, gain))
            }
            CorrectionForm::GainOffset => {
                let mp = predicted.iter().sum::<f64>() / n;
                let mm = measured.iter().sum::<f64>() / n;
                let (mut sxy, mut sxx) = (0.0, 0.0);
                for (p, m) in predicted.iter().zip(measured) {
                    sxy += (p - mp) * (m - mm);
                    sxx += (p - mp) * (p - mp);
                }
                let gain = sxy / sxx;
                // A negative gain would turn the model upside down: not a correction.
                (gain.is_finite() && gain > 0.0).then_some((mm - gain * mp, gain))
            }
        }
    }
}

/// Sum of squared errors of `offset + gain·predicted` against `measured`.
fn corrected_sse(predicted: &[f64], measured: &[f64], (offset, gain): (f64, f64)) -> f64 {
    predicted
        .iter()
        .zip(measured)
        .map(|(p, m)| (m - offset - gain * p).powi(2))
        .sum()
}

/// Held-out errors of a correction form: every block is predicted by the form fitted on the
/// others. `None` when a fit is impossible (fewer than two blocks, a degenerate gain).
fn held_out_errors(blocks: &[(&[f64], &[f64])], form: CorrectionForm) -> Option<Vec<f64>> {
    if blocks.len() < 2 {
        return None;
    }
    let mut errors = Vec::new();
    for held_out in 0..blocks.len() {
        let (mut predicted, mut measured) = (Vec::new(), Vec::new());
        for (i, (p, m)) in blocks.iter().enumerate() {
            if i != held_out {
                predicted.extend_from_slice(p);
                measured.extend_from_slice(m);
            }
        }
        let (offset, gain) = form.fit(&predicted, &measured)?;
        let (p, m) = blocks[held_out];
        errors.extend(p.iter().zip(m).map(|(p, m)| m - offset - gain * p));
    }
    Some(errors)
}

/// The calibration report.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct CalibrationReport {
    /// One entry per fitted model.
    pub models: Vec<ModelReport>,
}

/// The axes whose stator stood more than the floor above the room ([`warm_excess`]) in the
/// first row of `recording` where both are known, with that excess: the recording begins on a
/// warm machine. Calibration accumulates every heat term from rest at a recording's first row:
/// a database recording that begins warm fits the heat models to heat it does not show. An
/// experiment's start is fitted free for the flange, bearing and nut models, the straightness
/// reads the estimators' own temperatures over it, and the spindle elongation uses it as
/// [`warm_experiment_for_elongation`] says.
pub fn warm_at_first_row(recording: &Recording) -> Vec<(AxisId, f64)> {
    AxisId::ALL
        .into_iter()
        .filter_map(|axis| first_row_excess(recording, axis).map(|excess| (axis, excess)))
        .collect()
}

/// What calibration makes of an experiment for the spindle elongation, which counts from the
/// tool measurement at the experiment's first row.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ElongationExperiment {
    /// It does not carry the elongation's reference.
    NoReference,
    /// It begins at rest and is used as any experiment is.
    FromRest,
    /// It begins warm, and an experiment from rest carries the reference: the elongation is
    /// calibrated without this one.
    LeftOut,
    /// It begins warm, and no experiment from rest carries the reference: it chooses among the
    /// database's fits and weighs a correction of their gain, its start fitted free
    /// ([`WarmExperiment::ScoresOnly`]).
    ScoresAndGain,
}

/// What calibration makes of `recording`, one of `experiments`, for the spindle elongation
/// (the first elongation reference it carries).
pub fn warm_experiment_for_elongation(
    recording: &Recording,
    experiments: &[Recording],
) -> ElongationExperiment {
    let Some(target) = recording
        .names()
        .iter()
        .find(|name| name.starts_with("ref.") && name.ends_with(".elongation_um"))
    else {
        return ElongationExperiment::NoReference;
    };
    if !starts_warm(recording) {
        ElongationExperiment::FromRest
    } else if experiments.iter().any(|r| teaches_from_rest(r, target)) {
        ElongationExperiment::LeftOut
    } else {
        ElongationExperiment::ScoresAndGain
    }
}

/// Whether `recording` is an experiment from rest that carries `target` over enough rows to
/// teach a model: where one does, an experiment that begins warm is not needed for a model
/// that counts from its first row.
fn teaches_from_rest(recording: &Recording, target: &str) -> bool {
    !starts_warm(recording)
        && recording
            .try_column(target)
            .is_some_and(|values| values.len() >= MIN_EXPERIMENT_ROWS)
}

/// `axis`'s stator excess over the room in the first row of `recording` where both are read,
/// when it is above the floor ([`warm_excess`]).
fn first_row_excess(recording: &Recording, axis: AxisId) -> Option<f64> {
    let room = recording.try_column(AMBIENT)?;
    let stator = recording.try_column(&axis_column(axis, Quantity::StatorTemp))?;
    let (&stator_C, &room_C) = stator
        .iter()
        .zip(room)
        .find(|(s, r)| (*s - *r).is_finite())?;
    warm_excess(stator_C, room_C)
}

/// Fits every model the profile's axes need. Returns the calibration (to store in the profile)
/// and the report.
pub fn calibrate(
    profile: &MachineProfile,
    database: &[Recording],
    experiments: &[Recording],
) -> Result<(Calibration, CalibrationReport), CalibrationError> {
    let first = database.first().ok_or(CalibrationError::NoDatabase)?;
    if let Some(bare) = database.iter().find(|r| {
        !r.names()
            .iter()
            .any(|n| n.starts_with(crate::signal::channel::REFERENCE_PREFIX))
    }) {
        return Err(CalibrationError::NoReferences {
            recording: bare.source().to_string(),
        });
    }
    let fitted_rate_hz = first.sample_rate_hz().unwrap_or(1.0);
    let mut calibration = Calibration {
        fitted_rate_hz,
        database: database.iter().map(|r| r.source().to_string()).collect(),
        experiments: experiments.iter().map(|r| r.source().to_string()).collect(),
        axes: BTreeMap::new(),
    };
    let mut report = CalibrationReport { models: Vec::new() };
    let recordings = || database.iter().chain(experiments);
    let has_ambient = recorded_and_varying(recordings(), AMBIENT);
    let has_coolant = recorded_and_varying(recordings(), COOLANT);

    // Stage 1: models of raw servo signals.
    for (&axis, axis_profile) in &profile.axes {
        let mut models = AxisModels::default();
        match axis_profile.kind {
            AxisKind::Feed => {
                let target = reference_column(axis, "motor_flange_temp_C", None);
                if database.iter().all(|r| r.try_column(&target).is_some()) {
                    let stator = axis_column(axis, Quantity::StatorTemp);
                    let fitted = fit_best(
                        &format!("{axis}.motor_flange_temp"),
                        "T_flange",
                        database,
                        experiments,
                        &target,
                        &|_, _, r| {
                            let stator = r.column_for(&stator, "the motor flange model")?;
                            let base = vec![("stator".to_string(), stator.to_vec())];
                            let mut lagged = base.clone();
                            lagged.extend(stator_lag_columns(r.time(), stator));
                            let mut candidates = with_room_variant(base, r, has_ambient)?;
                            candidates.extend(with_room_and_lag_variants(lagged, r, has_ambient)?);
                            Ok(candidates)
                        },
                        ExperimentUse {
                            scoring: Scoring::Absolute,
                            warm: WarmExperiment::FreeStart,
                        },
                    )?;
                    models.motor_flange = Some(fitted.model.clone());
                    report.models.push(fitted.report);
                }
                if let Some((nut_bearing, back_front, reports)) = fit_torque_ratios(axis, database)?
                {
                    models.nut_bearing_ratio = Some(nut_bearing);
                    models.back_front_ratio = Some(back_front);
                    report.models.extend(reports);
                }
            }
            AxisKind::Spindle => {
                if let Some((model, model_report)) =
                    fit_elongation(axis, database, experiments, has_ambient, has_coolant)?
                {
                    models.elongation = Some(model);
                    report.models.push(model_report);
                }
            }
        }
        calibration.axes.insert(axis, models);
    }

    // Stage 2: component temperatures from the heat of the estimated split torques.
    for (&axis, axis_profile) in &profile.axes {
        if axis_profile.kind != AxisKind::Feed {
            continue;
        }
        let Some(models) = calibration.axes.get(&axis) else {
            continue;
        };
        let (Some(nb), Some(bf)) = (&models.nut_bearing_ratio, &models.back_front_ratio) else {
            continue;
        };
        let split =
            TorqueSplitEstimator::new(nb, bf).map_err(|message| CalibrationError::NoData {
                estimate: format!("{axis}.torque_split"),
                message,
            })?;
        let mut fitted = Vec::new();
        for (component, label) in [
            (Component::FrontBearing, "front_bearing_temp"),
            (Component::BackBearing, "back_bearing_temp"),
            (Component::Nut, "nut_temp"),
        ] {
            let target = reference_column(axis, &format!("{label}_C"), None);
            if !database.iter().all(|r| r.try_column(&target).is_some()) {
                continue;
            }
            let (model, model_report) = fit_heat_model(
                HeatFit {
                    axis,
                    label,
                    component,
                    split: &split,
                    target: &target,
                    has_ambient,
                    has_coolant,
                },
                database,
                experiments,
            )?;
            fitted.push((component, model));
            report.models.push(model_report);
        }
        let models = calibration.axes.entry(axis).or_default();
        for (component, model) in fitted {
            match component {
                Component::FrontBearing => models.front_bearing_temp = Some(model),
                Component::BackBearing => models.back_bearing_temp = Some(model),
                Component::Nut => models.nut_temp = Some(model),
            }
        }
    }
    apply_experiments(
        profile,
        &mut calibration,
        &mut report,
        experiments,
        Stage::Components,
    )?;

    // Stage 3: straightness from the estimated temperatures.
    for (&axis, axis_profile) in &profile.axes {
        let Some(screw) = &axis_profile.screw else {
            continue;
        };
        let nodes = screw.node_positions_mm.len();
        let first_ref = reference_column(axis, "straightness_h_um", Some(1));
        if !database.iter().all(|r| r.try_column(&first_ref).is_some()) {
            continue;
        }
        let estimate_all = |recordings: &[Recording]| {
            recordings
                .iter()
                .map(|r| estimated_temperatures(profile, &calibration, r, axis))
                .collect::<Result<Vec<_>, _>>()
        };
        let estimated = estimate_all(database)?;
        let estimated_experiments = estimate_all(experiments)?;
        // The bed's state needs a nut model everywhere it is fitted (the coolant's lags join it
        // where the coolant is recorded and switches).
        let has_bed_state = estimated
            .iter()
            .chain(&estimated_experiments)
            .flatten()
            .all(|i| i.nut_C.is_finite());
        // Every (node, direction) is a fit of its own; they run side by side and are kept in
        // node order, horizontal before vertical.
        let fits: Vec<(usize, bool)> = (1..=nodes).flat_map(|k| [(k, false), (k, true)]).collect();
        let fitted = parallel_map(&fits, |&(k, vertical)| {
            let hv = if vertical { "v" } else { "h" };
            let target = reference_column(axis, &format!("straightness_{hv}_um"), Some(k));
            let label = format!("{axis}.straightness_{hv}#{k}");
            let symbol = format!("δ_{}{k}", hv.to_uppercase());
            fit_best(
                &label,
                &symbol,
                database,
                experiments,
                &target,
                &|side, index, r| {
                    let inputs = match side {
                        Side::Database => &estimated[index],
                        Side::Experiment => &estimated_experiments[index],
                    };
                    straightness_candidates(inputs, r, has_ambient, has_bed_state, has_coolant)
                },
                ExperimentUse {
                    scoring: Scoring::Absolute,
                    warm: WarmExperiment::AsItIs,
                },
            )
        });
        let (mut h, mut v) = (Vec::new(), Vec::new());
        for (&(_, vertical), fitted) in fits.iter().zip(fitted) {
            let fitted = fitted?;
            let direction = if vertical { &mut v } else { &mut h };
            direction.push(fitted.model);
            report.models.push(fitted.report);
        }
        let models = calibration.axes.entry(axis).or_default();
        models.straightness_h = h;
        models.straightness_v = v;
    }
    apply_experiments(
        profile,
        &mut calibration,
        &mut report,
        experiments,
        Stage::Straightness,
    )?;

    // The healthy ideal torque for the abnormality score, on the database and the machine's
    // own (healthy) experiments together.
    for (&axis, axis_profile) in &profile.axes {
        let stroke_mm = axis_profile.screw.as_ref().map(|s| s.stroke_mm);
        if let Some((model, model_report)) =
            fit_abnormality(axis, stroke_mm, database, experiments, has_ambient)?
        {
            calibration.axes.entry(axis).or_default().abnormality = Some(model);
            report.models.push(model_report);
        }
    }
    Ok((calibration, report))
}

/// Steady blocks needed before an ideal-torque model is fitted.
const MIN_STEADY_BLOCKS: usize = 100;

/// The ideal torque of a healthy, steadily running axis (see [`super::abnormality`]); `None`
/// when the recordings lack the depth of cut or hold too little steady running.
fn fit_abnormality(
    axis: AxisId,
    stroke_mm: Option<f64>,
    database: &[Recording],
    experiments: &[Recording],
    has_ambient: bool,
) -> Result<Option<(AbnormalityModel, ModelReport)>, CalibrationError> {
    let mut blocks = Vec::new();
    let mut database_blocks = 0;
    let tagged = (database.iter().map(|r| (r, false))).chain(experiments.iter().map(|r| (r, true)));
    for (recording, is_experiment) in tagged {
        let Some(samples) = abnormality::recording_samples(recording, axis, stroke_mm) else {
            // The database must cover the model; an experiment without the columns adds nothing.
            if is_experiment {
                continue;
            }
            return Ok(None);
        };
        blocks.extend(abnormality::steady_blocks(samples));
        if !is_experiment {
            database_blocks = blocks.len();
        }
    }
    if blocks.len() < MIN_STEADY_BLOCKS {
        return Ok(None);
    }
    let has_position = blocks.iter().all(|b| b.mean.stroke_fraction.is_finite());
    let features: Vec<_> = blocks
        .iter()
        .map(|b| abnormality::ideal_torque_features(&b.mean))
        .collect();
    let columns: Vec<(String, Vec<f64>)> =
        abnormality::ideal_torque_terms(has_ambient, has_position)
            .into_iter()
            .filter_map(|term| {
                let index = IDEAL_TORQUE_FEATURES.iter().position(|f| *f == term)?;
                let values: Vec<f64> = features.iter().map(|f| f[index]).collect();
                // A direction that never changes (a spindle) is the constant again.
                let varies = values.iter().any(|v| (v - values[0]).abs() > 1e-12);
                varies.then(|| (term.to_string(), values))
            })
            .collect();
    let y: Vec<f64> = blocks.iter().map(|b| b.mean.torque_Nm).collect();
    let estimate = format!("{axis}.motor_abnormality");
    let mut fitted = fit_columns(&estimate, "τ_ideal", "motor torque", y, columns)?;
    fitted.report.coverage =
        single_speed_coverage(&blocks[..database_blocks], &blocks[database_blocks..]);
    Ok(Some((
        AbnormalityModel {
            ideal_torque: fitted.model,
        },
        fitted.report,
    )))
}

/// Above this ratio of the fastest to the slowest steady speed, the database's steady running
/// spans more than one speed and can separate the friction's speed terms from its constant.
const ONE_SPEED_SPAN: f64 = 1.25;

/// Says so when the database's steady running is at one speed (its fastest block at most
/// [`ONE_SPEED_SPAN`] times its slowest) or absent: the ideal torque's speed and churning
/// terms are then nearly the direction again, fixed only by the experiments (if, with the
/// database, they span more than one speed), and a held-out block of theirs is predicted from
/// the database's single speed. `None` when the database spans several speeds.
fn single_speed_coverage(database: &[TorqueBlock], experiments: &[TorqueBlock]) -> Option<String> {
    // `None` for no blocks: there is no speed to span.
    let speed_span = |blocks: &[TorqueBlock]| {
        let speeds: Vec<f64> = blocks.iter().map(|b| b.mean.speed_rpm.abs()).collect();
        (!speeds.is_empty()).then(|| span(&speeds))
    };
    let several = |(lo, hi): (f64, f64)| hi > ONE_SPEED_SPAN * lo;
    let experiment_span = speed_span(experiments);
    let Some((slowest, fastest)) = speed_span(database) else {
        let rests_on = match experiment_span {
            Some((lo, hi)) => format!(
                "the fit rests on the experiments' {} steady blocks at {lo:.0}–{hi:.0} rpm",
                experiments.len()
            ),
            None => "nothing fixes the model".to_string(),
        };
        return Some(format!(
            "the database holds no steady non-cutting running: {rests_on}; a database with steady \
             running at several speeds pins it down"
        ));
    };
    if several((slowest, fastest)) {
        return None;
    }
    let widened = experiment_span.filter(|&(lo, hi)| several((lo.min(slowest), hi.max(fastest))));
    let experiments = match widened {
        Some((lo, hi)) => format!(
            "the model's speed dependence comes from the experiments' {} steady blocks at \
             {lo:.0}–{hi:.0} rpm",
            experiments.len()
        ),
        None => "nothing else fixes the model's speed dependence".to_string(),
    };
    Some(format!(
        "the database's {} steady non-cutting blocks all run at {slowest:.0}–{fastest:.0} rpm, one \
         speed: {experiments}; a database with steady running at several speeds pins it down",
        database.len()
    ))
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Component {
    FrontBearing,
    BackBearing,
    Nut,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Stage {
    Components,
    Straightness,
}

/// A fitted model and its report line.
struct Fitted {
    model: LinearModel,
    report: ModelReport,
    cv_r2: f64,
}

/// Which recordings a candidate-building closure is asked about.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Side {
    Database,
    Experiment,
}

/// How a candidate's predictions on an experiment are compared with its reference.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Scoring {
    /// As they are.
    Absolute,
    /// Counted from the recording's first sample, as an estimator that is zeroed at a
    /// calibration moment (spindle elongation from the tool measurement) reports them.
    FromFirstSample,
}

/// What calibration makes of the start of an experiment that begins on a warm machine
/// ([`starts_warm`]).
#[derive(Debug, Clone, Copy, PartialEq)]
enum WarmExperiment {
    /// Its start is fitted free ([`START_DECAY_TAUS_S`]): the model's heat is accumulated from
    /// rest at the experiment's first row, where the machine held heat the accumulations never
    /// saw. Across four databases and three days (docs/accuracy.md) it took a warm
    /// experiment's front bearing from 0.924 to 0.978 and its nut from 0.911 to 0.985.
    FreeStart,
    /// Taken as it is: the model reads the estimators' outputs over the experiment, which
    /// start warm as they do in service (the straightness).
    AsItIs,
    /// Left out: what [`WarmExperiment::ScoresOnly`] becomes where an experiment from rest
    /// carries the target ([`teaches_from_rest`]), which teaches the model better.
    LeftOut,
    /// Scores only (the elongation where every experiment that carries its target begins
    /// warm): the warm experiments choose among the database's fits, each scored with the
    /// experiment's start fitted free and a level per experiment (its reference counts from
    /// cold, the estimate from the tool measurement), and join none. Across the twelve pairs
    /// (docs/accuracy.md) joined as they were they chose by comparing a change since the first
    /// row with a growth from cold (−0.215 on average); joined with a free start the model's
    /// many slow terms traded with the start (0.39 on one pair); left out, 0.567; scoring only,
    /// 0.682, and 0.821 with the gain the experiment then corrects ([`without_warm_start`]).
    ScoresOnly,
}

/// How a model learns from the experiments.
#[derive(Debug, Clone, Copy, PartialEq)]
struct ExperimentUse {
    /// How its predictions are compared with their reference.
    scoring: Scoring,
    /// What it makes of one that begins warm.
    warm: WarmExperiment,
}

/// Named regressor columns.
type Columns = Vec<(String, Vec<f64>)>;

/// Builds candidate column sets for one recording (same names and order for every recording).
type Candidates<'a> =
    dyn Fn(Side, usize, &Recording) -> Result<Vec<Columns>, CalibrationError> + 'a;

/// Fits each candidate column set on the stacked database and keeps the one that predicts best
/// where it matters: on the experiments (real data the database never saw) when they carry the
/// target, otherwise by time-blocked cross-validation on the database.
///
/// When the experiments carry the target, each candidate is also offered fitted on the
/// database and the experiments together ([`fit_joined`]), scored by time-blocked
/// cross-validation over the experiments. The database's response can differ from the real
/// machine's in ways an offset or a gain cannot mend (the twin's DOE sweeps speeds, loads and
/// coolant far from a production day's mix); then the joined fit predicts the held-out
/// experiment blocks better and is chosen, and no correction follows it. Warm experiments
/// under [`WarmExperiment::ScoresOnly`] join no fit: they only score the database's.
fn fit_best(
    estimate: &str,
    symbol: &str,
    database: &[Recording],
    experiments: &[Recording],
    target: &str,
    candidates: &Candidates<'_>,
    experiment_use: ExperimentUse,
) -> Result<Fitted, CalibrationError> {
    let ExperimentUse {
        scoring,
        warm: warm_experiment,
    } = experiment_use;
    let mut per_recording = Vec::with_capacity(database.len());
    let mut y = Vec::new();
    for (index, recording) in database.iter().enumerate() {
        per_recording.push(candidates(Side::Database, index, recording)?);
        y.extend_from_slice(recording.column_for(target, estimate)?);
    }
    let mut per_experiment = Vec::new();
    let mut y_experiment = Vec::new();
    let mut experiment_starts = Vec::new();
    let mut with_target = Vec::new();
    let any_from_rest = experiments.iter().any(|r| teaches_from_rest(r, target));
    let warm_experiment = match warm_experiment {
        WarmExperiment::ScoresOnly if any_from_rest => WarmExperiment::LeftOut,
        other => other,
    };
    for (index, recording) in experiments.iter().enumerate() {
        if warm_experiment == WarmExperiment::LeftOut && starts_warm(recording) {
            continue;
        }
        if let Some(values) = recording.try_column(target) {
            per_experiment.push(candidates(Side::Experiment, index, recording)?);
            experiment_starts.push(y_experiment.len());
            y_experiment.extend_from_slice(values);
            with_target.push(recording);
        }
    }
    let count = per_recording.first().map_or(0, Vec::len);
    let warm: Vec<bool> = with_target
        .iter()
        .map(|r| {
            matches!(
                warm_experiment,
                WarmExperiment::FreeStart | WarmExperiment::ScoresOnly
            ) && starts_warm(r)
        })
        .collect();
    let mut free_start = start_columns(&with_target, &warm, y_experiment.len());
    if warm_experiment == WarmExperiment::ScoresOnly {
        // Every experiment here begins warm, and each reference counts from cold while the
        // estimate counts from that experiment's first row: each has its own level (the
        // first one's is the fit's constant).
        free_start.extend(level_columns(&experiment_starts, y_experiment.len()));
        // Without a start to fit (an experiment shorter than the fastest decay, a degenerate
        // fit), a change since the first row would be scored against a growth from cold: the
        // experiments then score nothing, and the database's own blocks choose.
        let has_decay = free_start
            .iter()
            .any(|(name, _)| !name.starts_with(LEVEL_TERM));
        if !has_decay || fitted_start(&y_experiment, &free_start, true).is_none() {
            y_experiment.clear();
            free_start.clear();
        }
    }
    let mut best: Option<(f64, Fitted)> = None;
    let mut last_error = None;
    for c in 0..count {
        let columns = stack(&per_recording, c);
        if y_experiment.len() >= MIN_EXPERIMENT_ROWS
            && warm_experiment != WarmExperiment::ScoresOnly
        {
            let experiment = Rows {
                y: &y_experiment,
                columns: &stack(&per_experiment, c),
                starts: &experiment_starts,
                free_start: &free_start,
            };
            let database = Rows {
                y: &y,
                columns: &columns,
                starts: &[0],
                free_start: &Vec::new(),
            };
            match fit_joined(estimate, symbol, target, &database, &experiment, scoring) {
                Ok(joined) => {
                    let score = joined.report.selection_r2;
                    if best.as_ref().is_none_or(|(b, _)| score > *b + 1e-4) {
                        best = Some((score, joined));
                    }
                }
                Err(e) => last_error = Some(e),
            }
        }
        // A candidate whose terms are collinear on this database (the room term can be a
        // combination of estimated temperatures) is not an error while another one fits.
        let mut fitted = match fit_columns(estimate, symbol, target, y.clone(), columns) {
            Ok(fitted) => fitted,
            Err(e) => {
                last_error = Some(e);
                continue;
            }
        };
        let score = if y_experiment.len() >= MIN_EXPERIMENT_ROWS {
            let columns = stack(&per_experiment, c);
            let mut predicted = predict(&fitted.model.coefficients, &columns, y_experiment.len());
            if scoring == Scoring::FromFirstSample {
                for (start, end) in stacked_blocks(&experiment_starts, predicted.len()) {
                    let Some(&first) = predicted.get(start) else {
                        continue;
                    };
                    for p in &mut predicted[start..end] {
                        *p -= first;
                    }
                }
            }
            // The database's model cannot know the heat a warm experiment began with: that
            // start is fitted to what it leaves on every row, as the joined fit's score takes
            // it (a start is not predicted from later hours: held out, its decays fitted where
            // they have died out were extrapolated tenfold and more).
            if !free_start.is_empty() {
                let residual: Vec<f64> = y_experiment
                    .iter()
                    .zip(&predicted)
                    .map(|(y, p)| y - p)
                    .collect();
                let with_level = warm_experiment == WarmExperiment::ScoresOnly;
                if let Some(start) = fitted_start(&residual, &free_start, with_level) {
                    for (p, s) in predicted.iter_mut().zip(start) {
                        *p += s;
                    }
                }
                fitted.report.equation = format!(
                    "{} (fitted on the database; chosen on the experiments, the start of those \
                     that begin warm fitted free in the score)",
                    fitted.report.equation
                );
            }
            fitted.report.selected_by = "experiments";
            r_squared(&y_experiment, &predicted)
        } else {
            fitted.cv_r2
        };
        fitted.report.selection_r2 = score;
        if best.as_ref().is_none_or(|(b, _)| score > *b + 1e-4) {
            best = Some((score, fitted));
        }
    }
    match (best, last_error) {
        (Some((_, fitted)), _) => Ok(fitted),
        (None, Some(error)) => Err(error),
        (None, None) => Err(CalibrationError::NoData {
            estimate: estimate.to_string(),
            message: "no candidate model".into(),
        }),
    }
}

/// A target and its candidate columns over stacked recordings that start at `starts`, with
/// the free start of those that begin warm ([`start_columns`]; none for the database).
struct Rows<'a> {
    y: &'a [f64],
    columns: &'a Columns,
    starts: &'a [usize],
    free_start: &'a Columns,
}

impl Rows<'_> {
    /// Where the recording holding row `i` starts.
    fn start_of(&self, i: usize) -> usize {
        let k = self.starts.partition_point(|&s| s <= i);
        self.starts[k.saturating_sub(1)]
    }
}

/// One candidate fitted on the database and the experiments together by weighted least
/// squares, every experiment row weighing n_database / n_experiment so that the experiments
/// count as much as the whole database. Its selection score is the R² on the experiments of
/// time-blocked cross-validation over them: each block is predicted by a fit on the database
/// and the experiment rows outside the block and its `CV_GAP_ROWS` neighbours.
fn fit_joined(
    estimate: &str,
    symbol: &str,
    target: &str,
    database: &Rows<'_>,
    experiment: &Rows<'_>,
    scoring: Scoring,
) -> Result<Fitted, CalibrationError> {
    let err = |error: FitError| CalibrationError::Fit {
        estimate: estimate.to_string(),
        error,
    };
    let (n_db, n_exp) = (database.y.len(), experiment.y.len());
    let experiment_weight = n_db as f64 / n_exp as f64;
    let weights: Vec<f64> = (0..n_db + n_exp)
        .map(|i| if i < n_db { 1.0 } else { experiment_weight })
        .collect();
    let model_columns: Columns = database
        .columns
        .iter()
        .zip(experiment.columns)
        .map(|((name, d), (_, e))| (name.clone(), [d.as_slice(), e].concat()))
        .collect();
    // A warm experiment's free start is fitted with the model on every row and taken as
    // known while the model's own terms are held out: a start is not predicted from later
    // hours (its decays, fitted where they have died out, were extrapolated tenfold and
    // more), and the database's models are scored with their start fitted the same way.
    let free_start: Columns = experiment
        .free_start
        .iter()
        .map(|(name, e)| (name.clone(), [vec![0.0; n_db].as_slice(), e].concat()))
        .collect();
    let y = [database.y, experiment.y].concat();
    let model_count = model_columns.len();
    // The model's own terms over every row, and what the free start explains of each
    // experiment row (none without one).
    let (cv_design, fit, start) = if free_start.is_empty() {
        let design = Design::from_columns(target, y, model_columns).map_err(err)?;
        let fit = wls(&design, &weights, &OlsOptions::default()).map_err(err)?;
        (design, fit, vec![0.0; n_exp])
    } else {
        let all = [model_columns.clone(), free_start.clone()].concat();
        let design = Design::from_columns(target, y.clone(), all).map_err(err)?;
        let fit = wls(&design, &weights, &OlsOptions::default()).map_err(err)?;
        let start = start_of_rows(
            &free_start,
            &fit.estimates()[1 + model_count..],
            n_db + n_exp,
        );
        let cv_y = y.iter().zip(&start).map(|(y, s)| y - s).collect();
        let cv_design = Design::from_columns(target, cv_y, model_columns).map_err(err)?;
        (cv_design, fit, start[n_db..].to_vec())
    };
    let mut held_out = vec![f64::NAN; n_exp];
    for (start_row, end, gap) in experiment_folds(n_exp) {
        let keep = |i: usize| i < n_db || i - n_db + gap < start_row || i - n_db >= end + gap;
        let training = cv_design.with_rows(keep);
        let training_weights: Vec<f64> = (0..weights.len())
            .filter(|&i| keep(i))
            .map(|i| weights[i])
            .collect();
        let block_fit = wls(&training, &training_weights, &OlsOptions::default()).map_err(err)?;
        let mut predicted = predict(&block_fit.estimates(), experiment.columns, n_exp);
        for (p, s) in predicted.iter_mut().zip(&start) {
            *p += s;
        }
        for (j, slot) in held_out.iter_mut().enumerate().take(end).skip(start_row) {
            let zero = match scoring {
                Scoring::Absolute => 0.0,
                Scoring::FromFirstSample => predicted[experiment.start_of(j)],
            };
            *slot = predicted[j] - zero;
        }
    }
    let score = r_squared(experiment.y, &held_out);
    let model = linear_model(symbol, &fit);
    let warm_experiments: BTreeSet<&str> = experiment
        .free_start
        .iter()
        .filter_map(|(name, _)| start_term_experiment(name))
        .collect();
    let warm_note = match warm_experiments.len() {
        0 => String::new(),
        1 => "; the start of the experiment that begins warm fitted free, which its R² and F count"
            .to_string(),
        n => format!(
            "; the start of the {n} experiments that begin warm fitted free, which its R² and F count"
        ),
    };
    let report = ModelReport {
        estimate: estimate.to_string(),
        equation: format!(
            "{} (fitted on the database and the experiments, weighted 1 : {experiment_weight:.2} per row{warm_note})",
            model.equation
        ),
        n: fit.n,
        r2: fit.r2,
        f_statistic: fit.f_statistic,
        f_p_value: fit.f_p_value,
        cv_r2: score,
        selected_by: SELECTED_BY_JOINED,
        selection_r2: score,
        experiment_correction: None,
        coverage: None,
    };
    Ok(Fitted {
        model,
        report,
        cv_r2: score,
    })
}

/// The time blocks of cross-validation over `rows` stacked experiment rows: each block's
/// first and end row, and the rows dropped on each side of it.
fn experiment_folds(rows: usize) -> Vec<(usize, usize, usize)> {
    let folds = CV_FOLDS.min(rows / 10).max(2);
    let gap = CV_GAP_ROWS.min(rows / (4 * folds));
    (0..folds)
        .map(|fold| (fold * rows / folds, (fold + 1) * rows / folds, gap))
        .collect()
}

/// c₀ + Σ cᵢ·xᵢ for every row.
fn predict(coefficients: &[f64], columns: &[(String, Vec<f64>)], rows: usize) -> Vec<f64> {
    (0..rows)
        .map(|i| {
            coefficients[0]
                + columns
                    .iter()
                    .zip(&coefficients[1..])
                    .map(|((_, x), c)| c * x[i])
                    .sum::<f64>()
        })
        .collect()
}

/// 1 − SSE/SST.
fn r_squared(y: &[f64], predicted: &[f64]) -> f64 {
    let mean = y.iter().sum::<f64>() / y.len().max(1) as f64;
    let sse: f64 = y.iter().zip(predicted).map(|(a, b)| (a - b).powi(2)).sum();
    let sst: f64 = y.iter().map(|a| (a - mean).powi(2)).sum();
    if sst > 0.0 { 1.0 - sse / sst } else { f64::NAN }
}

/// The candidates `[base]` and, when the room temperature is recorded, `[base + ambient]`.
fn with_room_variant(
    base: Vec<(String, Vec<f64>)>,
    recording: &Recording,
    has_ambient: bool,
) -> Result<Vec<Columns>, CalibrationError> {
    let mut candidates = vec![base.clone()];
    if has_ambient {
        let mut with_room = base;
        with_room.push(("ambient".to_string(), recording.column(AMBIENT)?.to_vec()));
        candidates.push(with_room);
    }
    Ok(candidates)
}

/// The candidates of [`with_room_variant`] and, when the room temperature is recorded,
/// `[base + ambient + the room through each lag of AMBIENT_LAG_TAUS_S]`: for the parts bolted
/// to the bed, which follows the room slowly.
fn with_room_and_lag_variants(
    base: Vec<(String, Vec<f64>)>,
    recording: &Recording,
    has_ambient: bool,
) -> Result<Vec<Columns>, CalibrationError> {
    let mut candidates = with_room_variant(base, recording, has_ambient)?;
    if has_ambient && let Some(with_room) = candidates.last() {
        let mut with_lags = with_room.clone();
        for (name, column) in AMBIENT_LAG_FEATURES
            .iter()
            .zip(ambient_lag_columns(recording)?)
        {
            with_lags.push((name.to_string(), column));
        }
        candidates.push(with_lags);
    }
    Ok(candidates)
}

/// Concatenates candidate `c` of every recording, column by column.
fn stack(per_recording: &[Vec<Columns>], c: usize) -> Columns {
    let mut columns: Vec<(String, Vec<f64>)> = per_recording[0][c]
        .iter()
        .map(|(name, _)| (name.clone(), Vec::new()))
        .collect();
    for candidates in per_recording {
        for (slot, (_, values)) in columns.iter_mut().zip(&candidates[c]) {
            slot.1.extend_from_slice(values);
        }
    }
    columns
}

/// Whether `recording` begins on a warm machine ([`warm_at_first_row`]).
fn starts_warm(recording: &Recording) -> bool {
    !warm_at_first_row(recording).is_empty()
}

/// The free-start columns ([`START_DECAY_TAUS_S`]) of the experiments that begin warm, over
/// their rows stacked in order (`rows` in all), zero on every other experiment's rows. Each
/// warm experiment of at least `MIN_EXPERIMENT_ROWS` rows has its own, named
/// `warm_start_decay#<its index>_<τ>s`, for the time constants no longer than it lasts:
/// over a shorter span a decay is a ramp the others and the offset already make.
fn start_columns(experiments: &[&Recording], warm: &[bool], rows: usize) -> Columns {
    let mut columns = Vec::new();
    let mut at = 0;
    for (index, (recording, &warm)) in experiments.iter().zip(warm).enumerate() {
        let time = recording.time();
        let (t0, t_end) = span(time);
        if warm && time.len() >= MIN_EXPERIMENT_ROWS {
            for tau in START_DECAY_TAUS_S
                .into_iter()
                .filter(|&tau| tau <= t_end - t0)
            {
                let mut column = vec![0.0; rows];
                for (slot, &t) in column[at..].iter_mut().zip(time) {
                    *slot = (-(t - t0) / tau).exp();
                }
                columns.push((start_term(index, tau), column));
            }
        }
        at += time.len();
    }
    columns
}

/// The prefix of the level of each stacked warm experiment after the first
/// ([`level_columns`]), fitted beside the free start and never kept.
const LEVEL_TERM: &str = "warm_start_level";

/// One column per stacked recording after the first, 1 on its rows (`starts` are the
/// recordings' first rows, `rows` the stacked length) and 0 elsewhere.
fn level_columns(starts: &[usize], rows: usize) -> Columns {
    stacked_blocks(starts, rows)
        .enumerate()
        .skip(1)
        .map(|(index, (start, end))| {
            let mut column = vec![0.0; rows];
            column[start..end].fill(1.0);
            (format!("{LEVEL_TERM}#{index}"), column)
        })
        .collect()
}

/// The rows of each stacked recording, (first, end), from the recordings' first rows
/// `starts` and the stacked length `rows`.
fn stacked_blocks(starts: &[usize], rows: usize) -> impl Iterator<Item = (usize, usize)> + '_ {
    let ends = starts.iter().skip(1).copied().chain([rows]);
    starts.iter().copied().zip(ends)
}

/// The name of experiment `index`'s free-start term at `tau_s`.
fn start_term(index: usize, tau_s: f64) -> String {
    format!("{START_TERM}#{index}_{tau_s}s")
}

/// The experiment (its index) a free-start term's name ([`start_term`]) belongs to.
fn start_term_experiment(name: &str) -> Option<&str> {
    let (_, rest) = name.strip_prefix(START_TERM)?.split_once('#')?;
    rest.split_once('_').map(|(index, _)| index)
}

/// The free start ([`start_columns`]) fitted by least squares to `residual` on every row:
/// what it explains of each, beside an offset over all the rows (returned with it when
/// `with_level`; otherwise the start is the decays alone). None when the fit is degenerate.
fn fitted_start(residual: &[f64], free_start: &Columns, with_level: bool) -> Option<Vec<f64>> {
    let (estimates, start) = fit_beside_start(residual, Vec::new(), free_start)?;
    let level = if with_level { estimates[0] } else { 0.0 };
    Some(start.into_iter().map(|s| s + level).collect())
}

/// Least squares of `y` on a constant, the `leading` columns and the free start
/// ([`start_columns`]): the coefficients in that order, and what the free start explains of
/// each row. None when the fit is degenerate.
fn fit_beside_start(
    y: &[f64],
    leading: Columns,
    free_start: &Columns,
) -> Option<(Vec<f64>, Vec<f64>)> {
    let first_start = 1 + leading.len();
    let columns = [leading, free_start.clone()].concat();
    let design = Design::from_columns("y", y.to_vec(), columns).ok()?;
    let estimates = ols(&design).ok()?.estimates().to_vec();
    let start = start_of_rows(free_start, &estimates[first_start..], y.len());
    Some((estimates, start))
}

/// Σ sₖ·startₖ for every row: what the free start with coefficients `s` (in its order; any
/// more are ignored) explains.
fn start_of_rows(free_start: &Columns, s: &[f64], rows: usize) -> Vec<f64> {
    (0..rows)
        .map(|i| free_start.iter().zip(s).map(|((_, c), b)| b * c[i]).sum())
        .collect()
}

fn fit_columns(
    estimate: &str,
    symbol: &str,
    target: &str,
    y: Vec<f64>,
    columns: Vec<(String, Vec<f64>)>,
) -> Result<Fitted, CalibrationError> {
    let err = |error: FitError| CalibrationError::Fit {
        estimate: estimate.to_string(),
        error,
    };
    let design = Design::from_columns(target, y, columns).map_err(err)?;
    let fit = ols(&design).map_err(err)?;
    let folds = CV_FOLDS.min(design.n_rows() / 10).max(2);
    let gap = CV_GAP_ROWS.min(design.n_rows() / (4 * folds));
    let cv_r2 = blocked_cross_validation(&design, folds, gap)
        .map_err(err)?
        .r2;
    let model = linear_model(symbol, &fit);
    let report = ModelReport {
        estimate: estimate.to_string(),
        equation: model.equation.clone(),
        n: fit.n,
        r2: fit.r2,
        f_statistic: fit.f_statistic,
        f_p_value: fit.f_p_value,
        cv_r2,
        selected_by: "blocked_cv",
        selection_r2: cv_r2,
        experiment_correction: None,
        coverage: None,
    };
    Ok(Fitted {
        model,
        report,
        cv_r2,
    })
}

/// The fitted model, without the free start of warm experiments ([`START_TERM`]), which
/// belongs to those recordings and not to the model.
fn linear_model(symbol: &str, fit: &OlsFit) -> LinearModel {
    let kept: Vec<_> = fit
        .coefficients
        .iter()
        .filter(|c| !c.term.starts_with(START_TERM))
        .collect();
    let mut equation = format!("{symbol} =");
    for (i, c) in kept.iter().enumerate() {
        let sign = if c.estimate < 0.0 {
            "−"
        } else if i == 0 {
            ""
        } else {
            "+"
        };
        let value = format!("{:.6e}", c.estimate.abs());
        if c.term == "const" {
            equation.push_str(&format!(" {sign}{value}"));
        } else {
            equation.push_str(&format!(" {sign} {value}·{}", c.term));
        }
    }
    LinearModel {
        equation,
        terms: kept.iter().map(|c| c.term.clone()).collect(),
        coefficients: kept.iter().map(|c| c.estimate).collect(),
        r2: fit.r2,
        n: fit.n,
        f_statistic: fit.f_statistic,
        f_p_value: fit.f_p_value,
        rmse: fit.rmse,
    }
}

/// Eq. 8: the nut-to-bearing and back-to-front torque ratios as cubics in the motor torque,
/// fitted on moving samples where the reference torques are large enough for a ratio to mean
/// something.
fn fit_torque_ratios(
    axis: AxisId,
    database: &[Recording],
) -> Result<Option<(LinearModel, LinearModel, Vec<ModelReport>)>, CalibrationError> {
    let names = [
        reference_column(axis, "front_bearing_torque_Nm", None),
        reference_column(axis, "back_bearing_torque_Nm", None),
        reference_column(axis, "nut_torque_Nm", None),
    ];
    if !database
        .iter()
        .all(|r| names.iter().all(|n| r.try_column(n).is_some()))
    {
        return Ok(None);
    }
    let mut torque = Vec::new();
    let (mut r_nb, mut r_bf) = (Vec::new(), Vec::new());
    for r in database {
        let motor = r.column_for(&axis_column(axis, Quantity::Torque), "the torque split")?;
        let speed = r.column_for(&axis_column(axis, Quantity::Speed), "the torque split")?;
        let front = r.column(&names[0])?;
        let back = r.column(&names[1])?;
        let nut = r.column(&names[2])?;
        let max_speed = speed.iter().fold(0.0_f64, |m, s| m.max(s.abs()));
        for i in 0..r.len() {
            let bearing = front[i] + back[i];
            if speed[i].abs() > 0.02 * max_speed && bearing.abs() > 0.01 && front[i].abs() > 0.005 {
                torque.push(motor[i]);
                r_nb.push(nut[i] / bearing);
                r_bf.push(back[i] / front[i]);
            }
        }
    }
    if torque.len() < 20 {
        return Err(CalibrationError::NoData {
            estimate: format!("{axis}.torque_split"),
            message: format!(
                "only {} moving samples with reference torques",
                torque.len()
            ),
        });
    }
    let cubic = |t: &[f64]| {
        vec![
            ("torque".to_string(), t.to_vec()),
            ("torque^2".to_string(), t.iter().map(|v| v * v).collect()),
            (
                "torque^3".to_string(),
                t.iter().map(|v| v * v * v).collect(),
            ),
        ]
    };
    let nb = fit_columns(
        &format!("{axis}.nut_bearing_torque_ratio"),
        "r_BN",
        "r_BN",
        r_nb,
        cubic(&torque),
    )?;
    let bf = fit_columns(
        &format!("{axis}.back_front_torque_ratio"),
        "r_BF",
        "r_BF",
        r_bf,
        cubic(&torque),
    )?;
    Ok(Some((nb.model, bf.model, vec![nb.report, bf.report])))
}

/// The heat input series of a component (see
/// [`super::streaming::ComponentThermalEstimator`]), from the estimated split torque and the
/// sampled speed, exactly as the streaming estimator computes them.
fn component_heat_inputs(
    split: &TorqueSplitEstimator,
    component: Component,
    recording: &Recording,
    axis: AxisId,
    purpose: &str,
) -> Result<Vec<HeatInputs>, CalibrationError> {
    let torque = recording.column_for(&axis_column(axis, Quantity::Torque), purpose)?;
    let speed = recording.column_for(&axis_column(axis, Quantity::Speed), purpose)?;
    Ok(torque
        .iter()
        .zip(speed)
        .map(|(&torque, &speed)| {
            let s = split.update(torque);
            let tau = match component {
                Component::FrontBearing => s.front_bearing_Nm,
                Component::BackBearing => s.back_bearing_Nm,
                Component::Nut => s.nut_Nm,
            };
            heat_inputs(tau, &SpeedHeat::of(speed))
        })
        .collect())
}

/// The room through the lags of [`AMBIENT_LAG_TAUS_S`] over a recording, exactly as the
/// pipeline's [`RoomLags`] follows it: one column per lag.
fn ambient_lag_columns(recording: &Recording) -> Result<[Vec<f64>; 3], CalibrationError> {
    Ok(settled_lag_columns(
        recording.time(),
        recording.column(AMBIENT)?,
        AMBIENT_LAG_TAUS_S,
    ))
}

/// `values` through first-order lags of `taus_s` over the recording's time, exactly as the
/// estimators' [`SettledLags`] follow a signal: one column per lag.
fn settled_lag_columns<const N: usize>(
    time: &[f64],
    values: &[f64],
    taus_s: [f64; N],
) -> [Vec<f64>; N] {
    let mut lags = SettledLags::new(taus_s);
    let mut columns: [Vec<f64>; N] = std::array::from_fn(|_| Vec::with_capacity(values.len()));
    let mut previous = time.first().copied().unwrap_or(0.0);
    for (&t, &v) in time.iter().zip(values) {
        let dt = (t - previous).max(0.0);
        previous = t;
        for (column, value) in columns.iter_mut().zip(lags.update(v, dt)) {
            column.push(value);
        }
    }
    columns
}

/// Accumulates `input` with time constant `tau_s` over the recording's own time steps.
fn accumulate(time: &[f64], input: &[f64], tau_s: f64) -> Vec<f64> {
    let mut acc = HeatAccumulator::new(tau_s);
    let mut previous = time.first().copied().unwrap_or(0.0);
    time.iter()
        .zip(input)
        .map(|(&t, &u)| {
            let dt = (t - previous).max(0.0);
            previous = t;
            acc.update(u, dt)
        })
        .collect()
}

/// The stator through each lag of [`STATOR_LAG_TAUS_S`] over a recording, named as
/// [`STATOR_LAG_FEATURES`], exactly as the pipeline's stator lags follow it.
fn stator_lag_columns(time: &[f64], stator: &[f64]) -> Columns {
    STATOR_LAG_FEATURES
        .iter()
        .map(|name| name.to_string())
        .zip(settled_lag_columns(time, stator, STATOR_LAG_TAUS_S))
        .collect()
}

/// A part's surroundings over a recording, as [`super::streaming::ThermalSurroundings`] holds
/// them.
struct SurroundingsColumns {
    /// The stator through each lag of [`STATOR_LAG_TAUS_S`].
    stator: Columns,
    /// The coolant's on/off state through each lag of [`BED_LAG_TAUS_S`] (empty where the
    /// coolant is not offered).
    coolant: Columns,
}

impl SurroundingsColumns {
    fn of(
        recording: &Recording,
        stator: &str,
        with_coolant: bool,
        purpose: &str,
    ) -> Result<Self, CalibrationError> {
        let time = recording.time();
        let coolant = if with_coolant {
            let lags = settled_lag_columns(
                time,
                recording.column_for(COOLANT, purpose)?,
                BED_LAG_TAUS_S,
            );
            COOLANT_LAG_FEATURES
                .iter()
                .map(|name| name.to_string())
                .zip(lags)
                .collect()
        } else {
            Vec::new()
        };
        Ok(SurroundingsColumns {
            stator: stator_lag_columns(time, recording.column_for(stator, purpose)?),
            coolant,
        })
    }
}

/// True when every recording has `column` and its value changes somewhere among them. A signal
/// that never changes (the coolant of a shop that machines dry, a room reading held fixed) is
/// the intercept over again: a model term built on it would make its fit collinear, so
/// calibration offers no such terms.
fn recorded_and_varying<'a>(
    mut recordings: impl Iterator<Item = &'a Recording> + Clone,
    column: &str,
) -> bool {
    if !recordings.clone().all(|r| r.try_column(column).is_some()) {
        return false;
    }
    let mut first = None;
    recordings.any(|r| {
        r.try_column(column).is_some_and(|values| {
            values
                .iter()
                .filter(|v| v.is_finite())
                .any(|&v| *first.get_or_insert(v) != v)
        })
    })
}

/// What a heat-model fit is about.
struct HeatFit<'a> {
    axis: AxisId,
    label: &'a str,
    component: Component,
    split: &'a TorqueSplitEstimator,
    target: &'a str,
    has_ambient: bool,
    /// The coolant is recorded everywhere and switches ([`recorded_and_varying`]).
    has_coolant: bool,
}

/// Eqs. 9–12 for one component: T = c0 + c_SB·T_stator + c_H·H(τ), optionally with the load
/// heat c_L·H_load(τ) and the churning heat c_C·H_churning(τ), with the room c_room·T_room and
/// the room through the lags of `AMBIENT_LAG_TAUS_S`, and with the part's surroundings (the
/// stator's lags, then also the coolant's: [`SurroundingsColumns`]), the most surrounded of
/// each form once more with the drag and load heat over τ / [`FAST_HEAT_DIVISOR`]; τ and the
/// optional terms are chosen on the experiments (or by blocked cross-validation).
fn fit_heat_model(
    fit: HeatFit<'_>,
    database: &[Recording],
    experiments: &[Recording],
) -> Result<(HeatModel, ModelReport), CalibrationError> {
    let estimate = format!("{}.{}", fit.axis, fit.label);
    let inputs_of = |recordings: &[Recording]| {
        recordings
            .iter()
            .map(|r| component_heat_inputs(fit.split, fit.component, r, fit.axis, &estimate))
            .collect::<Result<Vec<_>, _>>()
    };
    let db_inputs = inputs_of(database)?;
    let experiment_inputs = inputs_of(experiments)?;
    let stator_name = axis_column(fit.axis, Quantity::StatorTemp);
    let has_coolant = fit.has_coolant;
    // The part's surroundings (the stator's and the coolant's lags) do not depend on τ.
    let surroundings_of = |recordings: &[Recording]| {
        recordings
            .iter()
            .map(|r| SurroundingsColumns::of(r, &stator_name, has_coolant, &estimate))
            .collect::<Result<Vec<_>, _>>()
    };
    let db_surroundings = surroundings_of(database)?;
    let experiment_surroundings = surroundings_of(experiments)?;
    // Each τ is a fit of its own; they run side by side, and the best is chosen in τ's order.
    let per_tau = parallel_map(HEAT_TAUS_S, |&tau| {
        fit_best(
            &estimate,
            "T",
            database,
            experiments,
            fit.target,
            &|side, index, r| {
                let (inputs, surroundings) = match side {
                    Side::Database => (&db_inputs[index], &db_surroundings[index]),
                    Side::Experiment => {
                        (&experiment_inputs[index], &experiment_surroundings[index])
                    }
                };
                let stator = r.column_for(&stator_name, &estimate)?.to_vec();
                let [heat, load_heat, churning_heat, heat_fast, load_heat_fast] =
                    part_accumulation_columns(r.time(), inputs, tau);
                let fast_heat = [heat_fast, load_heat_fast];
                let stator = ("stator".to_string(), stator);
                let mut candidates = Vec::new();
                for base in [
                    vec![stator.clone(), heat.clone()],
                    vec![stator.clone(), heat.clone(), load_heat.clone()],
                    vec![
                        stator.clone(),
                        heat.clone(),
                        load_heat.clone(),
                        churning_heat.clone(),
                    ],
                ] {
                    // The fullest variant (the last) again with the surroundings: the stator's
                    // lags, then also the coolant's where it is offered; the most surrounded
                    // of those again with the heat over τ/4.
                    let variants = with_room_and_lag_variants(base, r, fit.has_ambient)?;
                    let surrounded = variants.last().map(|fullest| {
                        let with_stator = [fullest.as_slice(), &surroundings.stator].concat();
                        let with_coolant = (!surroundings.coolant.is_empty())
                            .then(|| [with_stator.as_slice(), &surroundings.coolant].concat());
                        (with_stator, with_coolant)
                    });
                    candidates.extend(variants);
                    if let Some((with_stator, with_coolant)) = surrounded {
                        let surrounded_most = with_coolant.as_ref().unwrap_or(&with_stator);
                        let with_fast = [surrounded_most.as_slice(), &fast_heat].concat();
                        candidates.push(with_stator);
                        candidates.extend(with_coolant);
                        candidates.push(with_fast);
                    }
                }
                Ok(candidates)
            },
            ExperimentUse {
                scoring: Scoring::Absolute,
                warm: WarmExperiment::FreeStart,
            },
        )
    });
    let mut best: Option<(f64, f64, Fitted)> = None;
    for (&tau, fitted) in HEAT_TAUS_S.iter().zip(per_tau) {
        let fitted = fitted?;
        let score = fitted.report.selection_r2;
        if best.as_ref().is_none_or(|(b, _, _)| score > *b + 1e-4) {
            best = Some((score, tau, fitted));
        }
    }
    let (_, tau, fitted) = best.ok_or_else(|| CalibrationError::NoData {
        estimate: estimate.clone(),
        message: "no time constant could be fitted".into(),
    })?;
    let rate = database[0].sample_rate_hz().unwrap_or(1.0);
    // The excess needs the room recorded, not varying: a steady room is still the reference.
    let room_recorded = database
        .iter()
        .chain(experiments)
        .all(|r| r.try_column(AMBIENT).is_some());
    let warm_start = if room_recorded {
        let recordings = database.iter().zip(&db_inputs);
        // An experiment that begins warm accumulates from rest a heat its machine already
        // held: its accumulations say too little per kelvin of excess.
        let experiments = experiments.iter().zip(&experiment_inputs);
        let recordings = recordings.chain(experiments.filter(|(r, _)| !starts_warm(r)));
        fit_part_warm_start(recordings, &stator_name, tau, &estimate)?
    } else {
        None
    };
    let model = HeatModel {
        tau_s: tau,
        c_bh: HeatAccumulator::c_bh_at_rate(tau, rate),
        temperature: fitted.model,
        warm_start,
    };
    let mut report = fitted.report;
    let fast_note = if model.reads_fast_heat() {
        format!(" (the `_quarter_tau` terms over τ/{FAST_HEAT_DIVISOR})")
    } else {
        String::new()
    };
    report.equation = format!(
        "{}; H ← H(1 − C_BH) + C_BH·H′ with H′ ∝ n (drag), n·|τ| (load) and |n|^(5/3) (churning), τ = {tau} s{fast_note}",
        report.equation
    );
    Ok((model, report))
}

/// A part's accumulations over a recording at `tau_s`, in the order and with the names of
/// [`PART_ACCUMULATIONS`]: the drag, load and churning heat over τ, the drag and load heat over
/// τ / [`FAST_HEAT_DIVISOR`] (what [`ComponentThermalEstimator`] accumulates).
fn part_accumulation_columns(
    time: &[f64],
    inputs: &[HeatInputs],
    tau_s: f64,
) -> [(String, Vec<f64>); PART_ACCUMULATIONS.len()] {
    type Input = fn(&HeatInputs) -> f64;
    let fast_tau_s = tau_s / FAST_HEAT_DIVISOR;
    let sources: [(Input, f64); PART_ACCUMULATIONS.len()] = [
        (|i| i.drag, tau_s),
        (|i| i.load, tau_s),
        (|i| i.churning, tau_s),
        (|i| i.drag, fast_tau_s),
        (|i| i.load, fast_tau_s),
    ];
    let mut feature = PART_ACCUMULATIONS.iter();
    sources.map(|(input, tau)| {
        let series: Vec<f64> = inputs.iter().map(input).collect();
        let name = feature.next().map_or_else(String::new, |f| f.to_string());
        (name, accumulate(time, &series, tau))
    })
}

/// The stator's excess over the room in each row of a recording, as a [`WarmStart`] counts it.
fn counted_excess_column(
    recording: &Recording,
    stator: &str,
    purpose: &str,
) -> Result<Vec<f64>, CalibrationError> {
    let stator = recording.column_for(stator, purpose)?;
    let room = recording.column_for(AMBIENT, purpose)?;
    Ok(stator
        .iter()
        .zip(room)
        .map(|(&s, &r)| WarmStart::counted_excess(s, r))
        .collect())
}

/// A [`WarmStart`]: each accumulation over the calibration recordings, fitted through the origin
/// on the counted stator excess of the same rows (those where the accumulation is a number).
/// Each item is one recording's excess ([`counted_excess_column`]) and its accumulations by
/// feature. None where the stator never rose past the floor: the recordings then say nothing
/// about a warm machine.
fn fit_warm_start(recordings: impl IntoIterator<Item = (Vec<f64>, Columns)>) -> Option<WarmStart> {
    let mut largest_excess_K: f64 = 0.0;
    // Per feature: Σ excess·accumulation and Σ excess² over the same rows.
    let mut sums: BTreeMap<String, (f64, f64)> = BTreeMap::new();
    for (excess, accumulations) in recordings {
        largest_excess_K = excess.iter().copied().fold(largest_excess_K, f64::max);
        for (feature, accumulated) in accumulations {
            let (cross, squared) = sums.entry(feature).or_default();
            for (e, a) in excess
                .iter()
                .zip(&accumulated)
                .filter(|(_, a)| a.is_finite())
            {
                *cross += e * a;
                *squared += e * e;
            }
        }
    }
    (largest_excess_K > 0.0).then(|| WarmStart {
        largest_excess_K,
        per_K: sums
            .into_iter()
            .map(|(feature, (cross, squared))| {
                let per_K = if squared > 0.0 { cross / squared } else { 0.0 };
                (feature, per_K.max(0.0))
            })
            .collect(),
    })
}

/// A part's [`WarmStart`] over its accumulations at `tau_s` ([`part_accumulation_columns`]).
fn fit_part_warm_start<'a>(
    recordings: impl Iterator<Item = (&'a Recording, &'a Vec<HeatInputs>)>,
    stator: &str,
    tau_s: f64,
    purpose: &str,
) -> Result<Option<WarmStart>, CalibrationError> {
    let per_recording = recordings
        .map(|(recording, inputs)| {
            let columns = part_accumulation_columns(recording.time(), inputs, tau_s).into();
            Ok((counted_excess_column(recording, stator, purpose)?, columns))
        })
        .collect::<Result<Vec<_>, CalibrationError>>()?;
    Ok(fit_warm_start(per_recording))
}

/// Eq. 15 for a spindle: ΔT_stator, speed and load plus heat accumulated from the speed
/// (bearing friction) and, as a candidate, from the load (copper losses), over two or three
/// time constants, with or without the room. Where the recordings carry the current, the
/// coolant and the room, the full heat bank is a candidate too: every input of
/// `ELONGATION_HEAT_INPUTS` over the four `ELONGATION_BANK_TAUS_S`, with and without the room
/// and its lags. The form is chosen like every other model (experiments, else blocked
/// cross-validation), and the experiments may join the fit.
fn fit_elongation(
    axis: AxisId,
    database: &[Recording],
    experiments: &[Recording],
    has_ambient: bool,
    has_coolant: bool,
) -> Result<Option<(ElongationModel, ModelReport)>, CalibrationError> {
    let target = reference_column(axis, "elongation_um", None);
    if !database.iter().all(|r| r.try_column(&target).is_some()) {
        return Ok(None);
    }
    let estimate = format!("{axis}.spindle_elongation");
    let current = axis_column(axis, Quantity::Current);
    let has_bank_inputs = has_ambient
        && database
            .iter()
            .chain(experiments)
            .all(|r| r.try_column(&current).is_some());
    let names = |list: &[&str]| list.iter().map(|n| n.to_string()).collect::<Vec<_>>();
    let base = names(&["delta_stator", "speed", "load"]);
    let mut families: Vec<([f64; 4], Vec<Vec<String>>)> = ELONGATION_TAUS_S
        .iter()
        .map(|&(fast, mid, slow)| {
            let mut sets = Vec::new();
            for taus in [&["fast", "slow"][..], &["fast", "mid", "slow"][..]] {
                let heat = |input: &'static str| taus.iter().map(move |t| format!("{input}_{t}"));
                let speed_only: Vec<String> = base.iter().cloned().chain(heat("heat")).collect();
                let with_load: Vec<String> = speed_only
                    .iter()
                    .cloned()
                    .chain(heat("load_heat"))
                    .collect();
                for set in [speed_only, with_load] {
                    if has_ambient {
                        let mut with_room = set.clone();
                        with_room.push("ambient".to_string());
                        sets.push(with_room);
                    }
                    sets.push(set);
                }
            }
            ([fast, mid, slow, ELONGATION_BANK_TAUS_S[3]], sets)
        })
        .collect();
    if has_bank_inputs {
        // ELONGATION_FEATURES ends with the room and its three lags.
        let room_start = ELONGATION_FEATURES.len() - 4;
        // Without a coolant that switches, the bank's coolant inputs are constant: left out.
        let bank_features = |range: std::ops::Range<usize>| {
            ELONGATION_FEATURES[range]
                .iter()
                .filter(|name| has_coolant || !name.starts_with("coolant"))
                .map(|name| name.to_string())
                .collect::<Vec<_>>()
        };
        let bank = bank_features(1..room_start);
        let with_room = bank_features(1..ELONGATION_FEATURES.len());
        families.push((ELONGATION_BANK_TAUS_S, vec![with_room, bank]));
    }
    let mut best: Option<([f64; 4], Fitted)> = None;
    for (taus, sets) in &families {
        let fitted = fit_best(
            &estimate,
            "δ_R",
            database,
            experiments,
            &target,
            &|_, _, r| {
                let features = elongation_columns(axis, r, *taus, &estimate)?;
                sets.iter()
                    .map(|set| {
                        set.iter()
                            .map(|name| {
                                features
                                    .iter()
                                    .find(|(n, _)| n == name)
                                    .cloned()
                                    .ok_or_else(|| CalibrationError::NoData {
                                        estimate: estimate.clone(),
                                        message: format!("no elongation feature `{name}`"),
                                    })
                            })
                            .collect()
                    })
                    .collect()
            },
            ExperimentUse {
                scoring: Scoring::FromFirstSample,
                warm: WarmExperiment::ScoresOnly,
            },
        )?;
        if best
            .as_ref()
            .is_none_or(|(_, b)| fitted.report.selection_r2 > b.report.selection_r2 + 1e-4)
        {
            best = Some((*taus, fitted));
        }
    }
    Ok(best.map(|(taus, fitted)| {
        let mut report = fitted.report;
        let used: Vec<String> = ELONGATION_TAU_NAMES
            .iter()
            .zip(taus)
            .filter(|(name, _)| {
                let suffix = format!("_{name}");
                fitted.model.terms.iter().any(|t| t.ends_with(&suffix))
            })
            .map(|(_, tau)| format!("{tau} s"))
            .collect();
        if !used.is_empty() {
            report.equation = format!(
                "{}; heat terms accumulated with τ = {}",
                report.equation,
                used.join(", ")
            );
        }
        let [fast, mid, slow, long] = taus;
        (
            ElongationModel {
                fast_tau_s: fast,
                mid_tau_s: mid,
                slow_tau_s: slow,
                long_tau_s: long,
                model: fitted.model,
            },
            report,
        )
    }))
}

/// Every feature of `ELONGATION_FEATURES` but the constant over a recording, computed by the
/// streaming estimator's own [`ElongationFeatures`] (current, coolant and room are NaN where
/// the recording lacks them; only candidates that need them read them).
fn elongation_columns(
    axis: AxisId,
    recording: &Recording,
    taus: [f64; 4],
    estimate: &str,
) -> Result<Columns, CalibrationError> {
    let stator = recording.column_for(&axis_column(axis, Quantity::StatorTemp), estimate)?;
    let speed = recording.column_for(&axis_column(axis, Quantity::Speed), estimate)?;
    let load = recording.column_for(&axis_column(axis, Quantity::Load), estimate)?;
    let optional = |name: &str| recording.try_column(name);
    let current = optional(&axis_column(axis, Quantity::Current));
    let coolant = optional(COOLANT);
    let ambient = optional(AMBIENT);
    let at = |column: Option<&[f64]>, i: usize| column.map_or(f64::NAN, |c| c[i]);
    let time = recording.time();
    let mut room = RoomLags::default();
    let mut features = ElongationFeatures::new(taus);
    let mut columns: Columns = ELONGATION_FEATURES[1..]
        .iter()
        .map(|name| (name.to_string(), Vec::with_capacity(time.len())))
        .collect();
    let mut previous = time.first().copied().unwrap_or(0.0);
    for (i, &t) in time.iter().enumerate() {
        let dt = (t - previous).max(0.0);
        previous = t;
        let inputs = ElongationInputs {
            stator_C: stator[i],
            speed_rpm: speed[i],
            load_pct: load[i],
            current_A: at(current, i),
            coolant_on: at(coolant, i),
            room: room.update(at(ambient, i), dt),
        };
        for ((_, column), value) in columns.iter_mut().zip(&features.update(&inputs, dt)[1..]) {
            column.push(*value);
        }
    }
    Ok(columns)
}

/// What the straightness models read (estimated temperatures and thermal states) over a
/// recording, from the models fitted so far.
fn estimated_temperatures(
    profile: &MachineProfile,
    calibration: &Calibration,
    recording: &Recording,
    axis: AxisId,
) -> Result<Vec<StraightnessInputs>, CalibrationError> {
    let mut partial = profile.clone();
    let mut stage = calibration.clone();
    // Straightness models are being fitted; the pipeline must not need them yet.
    for models in stage.axes.values_mut() {
        models.straightness_h.clear();
        models.straightness_v.clear();
    }
    partial.calibration = Some(stage);
    let mut pipeline = EstimatorPipeline::new(&partial, recording.schema())?;
    let mut row = Vec::with_capacity(recording.schema().len());
    let mut out = Vec::with_capacity(recording.len());
    for i in 0..recording.len() {
        recording.row_into(i, &mut row);
        pipeline.update(&row);
        let inputs =
            pipeline
                .straightness_inputs(axis)
                .ok_or_else(|| CalibrationError::NoData {
                    estimate: format!("{axis}.straightness"),
                    message: "no temperature models for this axis".into(),
                })?;
        if [
            inputs.front_C,
            inputs.back_C,
            inputs.motor_C,
            inputs.front_heat,
            inputs.back_heat,
        ]
        .iter()
        .any(|v| v.is_nan())
        {
            return Err(CalibrationError::NoData {
                estimate: format!("{axis}.straightness"),
                message:
                    "straightness needs front-bearing, back-bearing and motor temperature models"
                        .into(),
            });
        }
        out.push(*inputs);
    }
    Ok(out)
}

/// Reads one value of [`StraightnessInputs`].
type Reading = fn(&StraightnessInputs) -> f64;

/// The straightness candidates of one recording: the paper's cubics in the estimated
/// temperatures, the same linear, linear in the thermal states, and (`has_bed_state`) linear in
/// the temperatures plus the bed's own state ([`BED_LAG_FEATURES`]) — each with and without the
/// room.
fn straightness_candidates(
    inputs: &[StraightnessInputs],
    recording: &Recording,
    has_ambient: bool,
    has_bed_state: bool,
    has_coolant: bool,
) -> Result<Vec<Columns>, CalibrationError> {
    let column = |name: &str, f: &dyn Fn(&StraightnessInputs) -> f64| {
        (name.to_string(), inputs.iter().map(f).collect::<Vec<f64>>())
    };
    let temperatures: [(&str, Reading); 3] = [
        ("front", |i| i.front_C),
        ("back", |i| i.back_C),
        ("motor", |i| i.motor_C),
    ];
    let mut cubic = Vec::new();
    let mut linear = Vec::new();
    for (name, f) in temperatures {
        linear.push(column(name, &f));
        cubic.push(column(name, &f));
        cubic.push(column(&format!("{name}^2"), &|i| f(i).powi(2)));
        cubic.push(column(&format!("{name}^3"), &|i| f(i).powi(3)));
    }
    let states = vec![
        column("stator", &|i| i.stator_C),
        column("front_heat", &|i| i.front_heat),
        column("front_load_heat", &|i| i.front_load_heat),
        column("back_heat", &|i| i.back_heat),
        column("back_load_heat", &|i| i.back_load_heat),
    ];
    let bed_state: [Reading; 7] = [
        |i| i.nut_C,
        |i| i.motor_lags_C[0],
        |i| i.motor_lags_C[1],
        |i| i.back_lags_C[0],
        |i| i.back_lags_C[1],
        |i| i.coolant_lags[0],
        |i| i.coolant_lags[1],
    ];
    let mut with_bed = linear.clone();
    for (name, f) in BED_LAG_FEATURES.iter().zip(bed_state) {
        if has_coolant || !COOLANT_LAG_FEATURES.contains(name) {
            with_bed.push(column(name, &f));
        }
    }
    let mut candidates = with_room_variant(cubic, recording, has_ambient)?;
    candidates.extend(with_room_and_lag_variants(linear, recording, has_ambient)?);
    candidates.extend(with_room_and_lag_variants(states, recording, has_ambient)?);
    if has_bed_state {
        candidates.extend(with_room_and_lag_variants(
            with_bed,
            recording,
            has_ambient,
        )?);
    }
    Ok(candidates)
}

/// Lets the experiments correct the models of one stage: for every estimate the pipeline
/// produces whose reference the experiments have, choose among no correction, an offset and a
/// gain with an offset by time-blocked cross-validation over the experiments (each one's first
/// and second half held out in turn), and fold the winner into the model. An estimate counted
/// from the first row (the elongation) reads warm experiments only where no experiment from
/// rest teaches it ([`teaches_from_rest`]), with their start taken out
/// ([`without_warm_start`]).
fn apply_experiments(
    profile: &MachineProfile,
    calibration: &mut Calibration,
    report: &mut CalibrationReport,
    experiments: &[Recording],
    stage: Stage,
) -> Result<(), CalibrationError> {
    if experiments.is_empty() {
        return Ok(());
    }
    let mut current = profile.clone();
    current.calibration = Some(calibration.clone());
    // (predicted, measured) per estimate, one entry per experiment.
    let mut pairs: BTreeMap<String, Vec<PredictedMeasured>> = BTreeMap::new();
    let mut warm_pairs: BTreeMap<String, Vec<PredictedMeasured>> = BTreeMap::new();
    for recording in experiments {
        let series = super::accuracy::run(&current, recording)?;
        let warm = starts_warm(recording);
        for (output, values) in series.outputs.iter().zip(&series.values) {
            let Some(measured) = recording.try_column(&output.reference) else {
                continue;
            };
            // An estimate that counts from a warm first row (the elongation from the tool
            // measurement) is not told the heat the part held then: the reference's growth
            // from cold is not what it estimates, and its change since then only partly.
            // Its gain is read there only with that heat's decay fitted free, and only
            // where no experiment from rest reads it.
            if output.counts_from_first_row && warm {
                if model_slot(&output.column, stage).is_none() {
                    continue;
                }
                if let Some(pair) = without_warm_start(values, measured, recording) {
                    warm_pairs
                        .entry(output.column.clone())
                        .or_default()
                        .push(pair);
                }
                continue;
            }
            pairs
                .entry(output.column.clone())
                .or_default()
                .push((values.clone(), measured.to_vec()));
        }
    }
    let mut warm_start_taken_out = BTreeSet::new();
    for (column, warm) in warm_pairs {
        let from_rest = pairs.entry(column.clone()).or_default();
        if from_rest.iter().all(|(p, _)| p.len() < MIN_EXPERIMENT_ROWS) {
            *from_rest = warm;
            warm_start_taken_out.insert(column);
        }
    }
    for (column, per_experiment) in pairs {
        let Some((axis, slot)) = model_slot(&column, stage) else {
            continue;
        };
        let joined = report
            .models
            .iter()
            .any(|m| slot.matches(axis, &m.estimate) && m.selected_by == SELECTED_BY_JOINED);
        if joined {
            continue;
        }
        let n: usize = per_experiment.iter().map(|(p, _)| p.len()).sum();
        if n < MIN_EXPERIMENT_ROWS {
            continue;
        }
        let mut correction = choose_correction(&per_experiment, slot.zeroed_at_calibration());
        correction.warm_start_taken_out = warm_start_taken_out.contains(&column);
        let (applied, offset, gain) = (correction.applied, correction.offset, correction.gain);
        if applied {
            let models = calibration.axes.entry(axis).or_default();
            if let Some(model) = slot.model_mut(models) {
                for c in model.coefficients.iter_mut() {
                    *c *= gain;
                }
                model.coefficients[0] += offset;
                model.equation = format!(
                    "{} (corrected by experiments: {offset:+.4} + {gain:.4}×)",
                    model.equation
                );
            }
        }
        if let Some(entry) = report
            .models
            .iter_mut()
            .find(|m| slot.matches(axis, &m.estimate))
        {
            entry.experiment_correction = Some(correction);
        }
    }
    Ok(())
}

/// An estimate's series over one experiment and the reference it is scored against.
type PredictedMeasured = (Vec<f64>, Vec<f64>);

/// An estimate counted from the first row of an experiment that begins warm, and its
/// reference with the warm start taken out: the reference is fitted on every row as a level,
/// a gain on the estimate's change since the first row and the free start's decays
/// ([`start_columns`]), and keeps what the gain and the estimate explain. The start is taken
/// as known, fitted with the gain on every row, so the correction's held-out halves then ask
/// whether that gain holds in both halves, and its RMSE before and after is against this
/// reference. None when the experiment is too short or the fit degenerate.
fn without_warm_start(
    predicted: &[f64],
    measured: &[f64],
    recording: &Recording,
) -> Option<PredictedMeasured> {
    let first = *predicted.first()?;
    let change: Vec<f64> = predicted.iter().map(|p| p - first).collect();
    let free_start = start_columns(&[recording], &[true], change.len());
    if free_start.is_empty() {
        return None;
    }
    let estimate = vec![("estimate".to_string(), change.clone())];
    let (estimates, start) = fit_beside_start(measured, estimate, &free_start)?;
    let reference = measured
        .iter()
        .zip(&start)
        .map(|(m, s)| m - estimates[0] - s)
        .collect();
    Some((change, reference))
}

/// Chooses and fits the experiments' correction of one estimate from its (predicted,
/// measured) series, one pair per experiment: the form with the smallest held-out RMSE (each
/// experiment's halves held out in turn), kept only when its improvement over no correction
/// passes a one-sided Diebold–Mariano test at `CORRECTION_ALPHA` with the effective sample size.
fn choose_correction(
    per_experiment: &[PredictedMeasured],
    zeroed_at_calibration: bool,
) -> ExperimentCorrection {
    let n: usize = per_experiment.iter().map(|(p, _)| p.len()).sum();
    let blocks: Vec<(&[f64], &[f64])> = per_experiment
        .iter()
        .flat_map(|(p, m)| {
            let half = p.len() / 2;
            [(&p[..half], &m[..half]), (&p[half..], &m[half..])]
        })
        .filter(|(p, _)| !p.is_empty())
        .collect();
    // An estimator zeroed at a calibration moment (elongation from the tool measurement)
    // cancels any offset: only its gain can be corrected.
    let forms: &[CorrectionForm] = if zeroed_at_calibration {
        &[CorrectionForm::None, CorrectionForm::Gain]
    } else {
        &[
            CorrectionForm::None,
            CorrectionForm::Offset,
            CorrectionForm::GainOffset,
        ]
    };
    let errors: Vec<Option<Vec<f64>>> = forms
        .iter()
        .map(|&form| held_out_errors(&blocks, form))
        .collect();
    let cv = |i: usize| errors[i].as_deref().map_or(f64::INFINITY, rms);
    let cv_of = |form: CorrectionForm| forms.iter().position(|&f| f == form).map_or(f64::NAN, cv);
    // The simplest form wins ties: a correction must earn its place out of sample.
    let mut chosen = 0;
    for candidate in 1..forms.len() {
        if cv(candidate) < cv(chosen) {
            chosen = candidate;
        }
    }
    // ...and the improvement must be more than the residuals' slow wander: a one-sided
    // Diebold–Mariano test on the held-out squared errors, counting only the effective
    // (autocorrelation-corrected) number of samples.
    let improvement_p_value = match (&errors[0], &errors[chosen]) {
        (Some(none), Some(corrected)) if chosen != 0 => {
            let gain_in_loss: Vec<f64> = none
                .iter()
                .zip(corrected)
                .map(|(a, b)| a * a - b * b)
                .collect();
            mean_above_zero(&gain_in_loss).p_value
        }
        _ => f64::NAN,
    };
    let form = if chosen != 0 && improvement_p_value < CORRECTION_ALPHA {
        forms[chosen]
    } else {
        CorrectionForm::None
    };
    let (cv_none, cv_offset, cv_gain, cv_gain_offset) = (
        cv(0),
        cv_of(CorrectionForm::Offset),
        cv_of(CorrectionForm::Gain),
        cv_of(CorrectionForm::GainOffset),
    );
    let predicted: Vec<f64> = per_experiment.iter().flat_map(|(p, _)| p.clone()).collect();
    let measured: Vec<f64> = per_experiment.iter().flat_map(|(_, m)| m.clone()).collect();
    let (offset, gain) = form.fit(&predicted, &measured).unwrap_or((0.0, 1.0));
    let rows = n as f64;
    let applied = form != CorrectionForm::None;
    ExperimentCorrection {
        n,
        form,
        offset,
        gain,
        cv_rmse_none: cv_none,
        cv_rmse_offset: cv_offset,
        cv_rmse_gain: cv_gain,
        cv_rmse_gain_offset: cv_gain_offset,
        improvement_p_value,
        rmse_before: (corrected_sse(&predicted, &measured, (0.0, 1.0)) / rows).sqrt(),
        rmse_after: (corrected_sse(&predicted, &measured, (offset, gain)) / rows).sqrt(),
        applied,
        warm_start_taken_out: false,
    }
}

/// Which stored model an estimate column belongs to.
#[derive(Debug, Clone, Copy)]
enum ModelSlot {
    Flange,
    Front,
    Back,
    Nut,
    StraightnessH(usize),
    StraightnessV(usize),
    Elongation,
}

impl ModelSlot {
    /// Whether the estimator reports values counted from a calibration moment.
    fn zeroed_at_calibration(self) -> bool {
        matches!(self, ModelSlot::Elongation)
    }

    fn model_mut(self, m: &mut AxisModels) -> Option<&mut LinearModel> {
        match self {
            ModelSlot::Flange => m.motor_flange.as_mut(),
            ModelSlot::Front => m.front_bearing_temp.as_mut().map(|h| &mut h.temperature),
            ModelSlot::Back => m.back_bearing_temp.as_mut().map(|h| &mut h.temperature),
            ModelSlot::Nut => m.nut_temp.as_mut().map(|h| &mut h.temperature),
            ModelSlot::StraightnessH(k) => m.straightness_h.get_mut(k - 1),
            ModelSlot::StraightnessV(k) => m.straightness_v.get_mut(k - 1),
            ModelSlot::Elongation => m.elongation.as_mut().map(|e| &mut e.model),
        }
    }

    fn matches(self, axis: AxisId, estimate: &str) -> bool {
        let name = match self {
            ModelSlot::Flange => "motor_flange_temp".to_string(),
            ModelSlot::Front => "front_bearing_temp".into(),
            ModelSlot::Back => "back_bearing_temp".into(),
            ModelSlot::Nut => "nut_temp".into(),
            ModelSlot::StraightnessH(k) => format!("straightness_h#{k}"),
            ModelSlot::StraightnessV(k) => format!("straightness_v#{k}"),
            ModelSlot::Elongation => "spindle_elongation".into(),
        };
        estimate == format!("{axis}.{name}")
    }
}

/// Maps an estimate column (`est.X.nut_temp_C`) to its model, if it belongs to `stage`.
fn model_slot(column: &str, stage: Stage) -> Option<(AxisId, ModelSlot)> {
    let rest = column.strip_prefix("est.")?;
    let (axis, quantity) = rest.split_once('.')?;
    let axis: AxisId = axis.parse().ok()?;
    let slot = match (quantity, stage) {
        ("motor_flange_temp_C", Stage::Components) => ModelSlot::Flange,
        ("front_bearing_temp_C", Stage::Components) => ModelSlot::Front,
        ("back_bearing_temp_C", Stage::Components) => ModelSlot::Back,
        ("nut_temp_C", Stage::Components) => ModelSlot::Nut,
        ("elongation_um", Stage::Components) => ModelSlot::Elongation,
        (q, Stage::Straightness) => {
            let (name, node) = q.split_once('#')?;
            let k: usize = node.parse().ok()?;
            match name {
                "straightness_h_um" => ModelSlot::StraightnessH(k),
                "straightness_v_um" => ModelSlot::StraightnessV(k),
                _ => return None,
            }
        }
        _ => return None,
    };
    Some((axis, slot))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::estimators::models::WARM_START_FLOOR_K;

    /// A seeded stream of roughly normal numbers (sum of uniforms), unit variance.
    fn noise(seed: u64) -> impl FnMut() -> f64 {
        let mut state = seed;
        move || {
            let mut sum = 0.0;
            for _ in 0..12 {
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                sum += (state >> 11) as f64 / (1u64 << 53) as f64;
            }
            sum - 6.0
        }
    }

    /// A 4 h experiment at 1 Hz: a slow "true" signal the database model predicts, and the
    /// measured reference = truth + `offset` + `wander` (slow AR(1) error of the model) + white
    /// instrument noise.
    fn experiment(offset: f64, wander: f64, seed: u64) -> Vec<(Vec<f64>, Vec<f64>)> {
        let mut draw = noise(seed);
        let n = 4 * 3600;
        let phi = (-1.0f64 / 2400.0).exp();
        let mut slow = 0.0;
        let (mut predicted, mut measured) = (Vec::with_capacity(n), Vec::with_capacity(n));
        for i in 0..n {
            let truth = 25.0 + 3.0 * (1.0 - (-(i as f64) / 3000.0).exp());
            slow = phi * slow + (1.0 - phi * phi).sqrt() * draw();
            predicted.push(truth);
            measured.push(truth + offset + wander * slow + 0.05 * draw());
        }
        vec![(predicted, measured)]
    }

    /// Steady blocks at `speeds_rpm`, alternating direction.
    fn blocks_at(speeds_rpm: &[f64]) -> Vec<TorqueBlock> {
        speeds_rpm
            .iter()
            .enumerate()
            .map(|(i, &rpm)| {
                let speed_rpm = if i % 2 == 0 { rpm } else { -rpm };
                TorqueBlock {
                    mean: abnormality::TorqueSample {
                        time_s: i as f64,
                        speed_rpm,
                        torque_Nm: 0.6 * speed_rpm.signum(),
                        stator_C: 22.0,
                        ambient_C: 20.0,
                        stroke_fraction: 0.5,
                        cutting: false,
                    },
                    speed_range_rpm: (speed_rpm, speed_rpm),
                    samples: 1000,
                }
            })
            .collect()
    }

    /// A database whose steady running is all at one speed (the twin's DOE seed 4: 1 273 X
    /// blocks at 431–436 rpm, held-out R² −2752 when the experiments' blocks were predicted
    /// from it), or that has none, is named as the reason, with what the experiments add; one
    /// that spans several speeds is not.
    #[test]
    fn a_database_that_runs_steady_at_one_speed_is_named_as_the_reason() {
        let one_speed = blocks_at(&[431.0, 433.0, 435.0, 432.0]);
        let note = single_speed_coverage(&one_speed, &blocks_at(&[332.0, 500.0, 777.0]))
            .expect("one speed is named");
        assert!(
            note.contains("4 steady non-cutting blocks all run at 431–435 rpm"),
            "{note}"
        );
        assert!(
            note.contains("the experiments' 3 steady blocks at 332–777 rpm"),
            "{note}"
        );
        let alone = single_speed_coverage(&one_speed, &[]).expect("one speed is named");
        assert!(alone.contains("nothing else fixes"), "{alone}");
        let near = single_speed_coverage(&one_speed, &blocks_at(&[500.0, 510.0]));
        assert!(
            near.is_some_and(|n| n.contains("nothing else fixes")),
            "experiments near the database's speed do not widen it"
        );
        let apart = single_speed_coverage(&one_speed, &blocks_at(&[900.0, 905.0]));
        assert!(
            apart.is_some_and(|n| n.contains("the experiments' 2 steady blocks at 900–905 rpm")),
            "experiments at one speed of their own, far from the database's, widen it"
        );
        assert!(
            single_speed_coverage(&blocks_at(&[400.0, 500.0]), &[]).is_some(),
            "a span of exactly {ONE_SPEED_SPAN} is still one speed"
        );
        assert_eq!(
            single_speed_coverage(&blocks_at(&[400.0, 501.0]), &[]),
            None,
            "just beyond it the database pins the speed terms down"
        );
        let none = single_speed_coverage(&[], &blocks_at(&[332.0, 777.0])).expect("named");
        assert!(
            none.contains("no steady non-cutting running: the fit rests on the experiments' 2"),
            "{none}"
        );
    }

    /// An X axis that runs steady at each of `speeds_rpm` in turn for five minutes, reversing
    /// every minute, with a friction torque that grows with speed; `with_cut_depth` false leaves
    /// out the depth of cut (such a recording cannot tell friction from cutting).
    fn steady_running(speeds_rpm: &[f64], with_cut_depth: bool, seed: u64) -> Recording {
        let mut names = vec![
            "time_s".to_string(),
            axis_column(AxisId::X, Quantity::Speed),
            axis_column(AxisId::X, Quantity::Torque),
            axis_column(AxisId::X, Quantity::StatorTemp),
            AMBIENT.to_string(),
        ];
        if with_cut_depth {
            names.push(crate::signal::channel::CUT_DEPTH.to_string());
        }
        let mut recording = Recording::new(format!("steady-{seed}"), names).unwrap();
        let mut draw = noise(seed);
        let mut i = 0;
        for &rpm in speeds_rpm {
            for _ in 0..300 {
                let direction = if (i / 60) % 2 == 0 { 1.0 } else { -1.0 };
                let speed = direction * rpm;
                let torque = direction * (0.5 + 0.0002 * rpm) + 0.01 * draw();
                // The stator warms and the room wanders, as on a machine at work.
                let stator_C = 22.0 + (i as f64 / 600.0).sqrt() + 0.05 * draw();
                let room_C = 20.0 + 0.5 * (i as f64 / 500.0).sin();
                let mut row = vec![i as f64, speed, torque, stator_C, room_C];
                if with_cut_depth {
                    row.push(0.0);
                }
                recording.push_row(&row).unwrap();
                i += 1;
            }
        }
        recording
    }

    /// The coverage note counts the blocks of every database recording as the database's and
    /// only the experiments that can be scored as the experiments' (one without a depth of cut
    /// adds nothing).
    #[test]
    fn the_coverage_note_counts_each_recordings_blocks_on_its_own_side() {
        let database = [
            steady_running(&[433.0; 2], true, 1),
            steady_running(&[435.0; 2], true, 2),
        ];
        let experiments = [
            steady_running(&[150.0, 800.0], false, 3),
            steady_running(&[200.0, 700.0], true, 4),
        ];
        let (_, report) = fit_abnormality(AxisId::X, None, &database, &experiments, true)
            .unwrap()
            .expect("enough steady blocks");
        let note = report.coverage.expect("one database speed is named");
        let blocks = |r: &Recording| {
            abnormality::steady_blocks(abnormality::recording_samples(r, AxisId::X, None).unwrap())
                .len()
        };
        let database_blocks = blocks(&database[0]) + blocks(&database[1]);
        assert!(
            note.contains(&format!(
                "the database's {database_blocks} steady non-cutting blocks all run at 433–435 rpm"
            )),
            "{note}"
        );
        assert!(
            note.contains(&format!(
                "the experiments' {} steady blocks at 200–700 rpm",
                blocks(&experiments[1])
            )),
            "{note}"
        );
    }

    #[test]
    fn a_real_offset_is_found_and_applied() {
        let c = choose_correction(&experiment(0.3, 0.02, 1), false);
        assert_eq!(c.form, CorrectionForm::Offset, "{c:?}");
        assert!((c.offset - 0.3).abs() < 0.02, "{c:?}");
        assert!(c.applied && c.improvement_p_value < CORRECTION_ALPHA);
        assert!(c.rmse_after < c.rmse_before);
    }

    #[test]
    fn slow_model_error_without_an_offset_is_not_corrected() {
        // The model's error wanders by ±0.3 over tens of minutes: any 4 h window has a mean
        // that an F-test over 14 400 samples calls significant; counted honestly it is not.
        let mut applied = 0;
        for seed in 0..20 {
            let c = choose_correction(&experiment(0.0, 0.3, seed), false);
            applied += usize::from(c.applied);
        }
        assert!(applied <= 1, "{applied} of 20 spurious corrections applied");
    }

    #[test]
    fn a_zeroed_estimator_only_gets_a_gain() {
        let mut pairs = experiment(0.0, 0.0, 3);
        for (predicted, measured) in &mut pairs {
            let (p0, m0) = (predicted[0], measured[0]);
            for (p, m) in predicted.iter_mut().zip(measured.iter_mut()) {
                *p -= p0;
                *m = 1.2 * (*m - m0);
            }
        }
        let c = choose_correction(&pairs, true);
        assert_eq!(c.form, CorrectionForm::Gain, "{c:?}");
        // The zeroed reference carries its first sample's noise, which biases a gain a little.
        assert!((c.gain - 1.2).abs() < 0.05, "{c:?}");
        assert_eq!(c.offset, 0.0);
        assert!(c.cv_rmse_offset.is_nan());
    }
    /// An 8 h recording at 1 Hz of an X front bearing whose temperature is the room's plus 1.5 K
    /// per krpm of drag heat accumulated over 20 min, less `cooling` K through the bed's 90 min
    /// lag of the coolant, read with 0.02 K of noise; the speed and the coolant change in blocks of
    /// 10–60 min that do not line up, and the stator follows the speed.
    fn cooled_bearing_recording(cooling: f64, seed: u64) -> Recording {
        let speed = axis_column(AxisId::X, Quantity::Speed);
        let torque = axis_column(AxisId::X, Quantity::Torque);
        let stator = axis_column(AxisId::X, Quantity::StatorTemp);
        let target = reference_column(AxisId::X, "front_bearing_temp_C", None);
        let names = vec![
            "time_s".to_string(),
            speed,
            torque,
            stator,
            AMBIENT.to_string(),
            COOLANT.to_string(),
            target,
        ];
        let mut recording = Recording::new(format!("cooled-bearing-{seed}"), names).unwrap();
        let mut draw = noise(seed);
        let mut lengths = noise(seed + 1000);
        let mut levels = noise(seed + 2000);
        // A block of 10–60 min, and a speed level (the streams are about normal within ±6).
        let mut block = move || 600 + ((lengths() + 6.0) / 12.0 * 3000.0) as usize;
        let mut level = move || ((levels() + 6.0) / 12.0 * 4.0) as usize % 4;
        let (mut speed_rpm, mut coolant) = (0.0, 0.0);
        let (mut next_speed, mut next_coolant) = (0, 0);
        let mut heat = HeatAccumulator::new(1200.0);
        let mut stator_lag = HeatAccumulator::new(450.0);
        let mut coolant_lags = SettledLags::new(BED_LAG_TAUS_S);
        for i in 0..8 * 3600 {
            let dt = if i == 0 { 0.0 } else { 1.0 };
            if i == next_speed {
                speed_rpm = [0.0, 400.0, 1500.0, 2500.0][level()];
                next_speed = i + block();
            }
            if i == next_coolant {
                coolant = if coolant == 0.0 { 1.0 } else { 0.0 };
                next_coolant = i + block();
            }
            let drag = heat.update(speed_rpm / 1000.0, dt);
            let stator_C = 20.0 + 4.0 * stator_lag.update(speed_rpm / 1000.0, dt) + 0.05 * draw();
            let [_, coolant_90] = coolant_lags.update(coolant, dt);
            let room_C = 20.0 + 0.5 * (i as f64 / 5000.0).sin();
            let bearing_C = room_C + 1.5 * drag - cooling * coolant_90 + 0.02 * draw();
            let torque_Nm = if speed_rpm > 0.0 { 0.6 } else { 0.0 };
            recording
                .push_row(&[
                    i as f64, speed_rpm, torque_Nm, stator_C, room_C, coolant, bearing_C,
                ])
                .unwrap();
        }
        recording
    }

    /// A machine whose part reads `gain` × its heat over 1800 s above the room, recorded at 1 Hz
    /// from `from_s` of a run that started at rest: the rows of a recording that begins there.
    /// Its columns are the part's heat as calibration computes it (accumulated from the
    /// recording's first row), the room, the X stator and the part.
    fn part_heat_recording(gain: f64, hours: f64, from_s: f64, seed: u64) -> Recording {
        let names = ["time_s", "heat", AMBIENT, "X.stator_temp_C", "part"]
            .map(String::from)
            .to_vec();
        let mut recording = Recording::new(format!("part-{seed}"), names).unwrap();
        let mut draw = noise(seed);
        let (mut part_heat, mut stator_heat) =
            (HeatAccumulator::new(1800.0), HeatAccumulator::new(600.0));
        let mut from_first_row = HeatAccumulator::new(1800.0);
        let (mut power, mut next_change) = (0.0, 0usize);
        for i in 0..(hours * 3600.0) as usize {
            if i == next_change {
                power = (0.5 + 0.5 * draw()).clamp(0.0, 1.5);
                next_change = i + 300 + (900.0 * (0.5 + 0.3 * draw()).clamp(0.0, 1.0)) as usize;
            }
            let t = i as f64;
            let heat = part_heat.update(power, 1.0);
            let stator = stator_heat.update(power, 1.0);
            if t < from_s {
                continue;
            }
            let counted = from_first_row.update(power, if t == from_s { 0.0 } else { 1.0 });
            let room = 20.0 + 0.3 * (t / 7000.0).sin();
            recording
                .push_row(&[
                    t,
                    counted,
                    room,
                    room + 3.0 * stator,
                    room + gain * heat + 0.02 * draw(),
                ])
                .unwrap();
        }
        recording
    }

    /// An experiment that begins on a warm machine calibrates as one from rest does: the heat
    /// it held at its first row, which its accumulations never saw, is fitted as a free start
    /// (decays and no term of the model). The database's part reads 1.6 × the heat, the
    /// machine's 2 ×, so the experiment is fitted into the model: 1.84 × from the experiment
    /// from rest, 1.79 × from the warm one (1.34 × without the free start).
    #[test]
    fn an_experiment_that_begins_warm_calibrates_as_one_from_rest() {
        let database = part_heat_recording(1.6, 8.0, 0.0, 1);
        let gain = |experiment: &Recording| {
            let fitted = fit_named(&database, experiment, "part", &["heat", AMBIENT]);
            let model = fitted.model;
            assert_eq!(
                model.terms,
                ["const", "heat", AMBIENT],
                "{}",
                model.equation
            );
            assert_eq!(fitted.report.selected_by, SELECTED_BY_JOINED);
            model.coefficients[1]
        };
        let from_rest = part_heat_recording(2.0, 6.0, 0.0, 2);
        let warm = part_heat_recording(2.0, 8.0, 7200.0, 2);
        assert!(!starts_warm(&from_rest));
        assert!(starts_warm(&warm));
        let (rest_gain, warm_gain) = (gain(&from_rest), gain(&warm));
        assert!(
            (warm_gain - rest_gain).abs() < 0.05 * rest_gain,
            "from rest {rest_gain:.3}, warm {warm_gain:.3}"
        );
    }

    /// An estimate counted from the first row of an experiment that begins warm (the
    /// elongation from the tool measurement) has its gain corrected as from rest: the heat the
    /// part held then is taken out as a free start. The database's model reads 1.6 × the
    /// heat, the machine 2 ×: the correction is 1.25 ×, read as 1.252 × from the warm
    /// experiment. The reference's change since the first row, taken alone, reads −0.06 ×:
    /// over the first hours the heat held then leaves as fast as the counted heat comes.
    #[test]
    fn a_warm_experiment_corrects_the_gain_of_an_estimate_counted_from_its_first_row() {
        let warm = part_heat_recording(2.0, 8.0, 7200.0, 2);
        assert!(starts_warm(&warm));
        let counted = warm.try_column("heat").unwrap();
        let predicted: Vec<f64> = counted.iter().map(|h| 1.6 * h).collect();
        let room = warm.try_column(AMBIENT).unwrap();
        let growth: Vec<f64> = (warm.try_column("part").unwrap().iter())
            .zip(room)
            .map(|(part, room)| part - room)
            .collect();
        let pair = without_warm_start(&predicted, &growth, &warm).unwrap();
        let correction = choose_correction(&[pair], true);
        assert!(correction.applied, "{correction:?}");
        assert_eq!(correction.form, CorrectionForm::Gain);
        assert!(
            (correction.gain - 1.25).abs() < 0.03 * 1.25,
            "{correction:?}"
        );
        let change: Vec<f64> = growth.iter().map(|g| g - growth[0]).collect();
        let naive = predicted
            .iter()
            .zip(&change)
            .map(|(p, c)| p * c)
            .sum::<f64>()
            / predicted.iter().map(|p| p * p).sum::<f64>();
        assert!(naive < 0.5 * 1.25, "{naive}");
    }

    /// Each stacked recording after the first has its own level column, 1 on its rows: the
    /// first one's level is the fit's constant.
    #[test]
    fn each_stacked_recording_after_the_first_has_a_level_of_its_own() {
        let levels = level_columns(&[0, 3, 5], 8);
        let names: Vec<&str> = levels.iter().map(|(name, _)| name.as_str()).collect();
        assert_eq!(
            names,
            [format!("{LEVEL_TERM}#1"), format!("{LEVEL_TERM}#2")]
        );
        assert_eq!(levels[0].1, [0.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 0.0]);
        assert_eq!(levels[1].1, [0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0]);
        assert!(level_columns(&[0], 8).is_empty());
    }

    /// Two experiments that begin warm, whose references count from cold each from its own
    /// zero (the second's 3 K higher), choose among the database's fits of an estimate that
    /// counts from each one's first row: the part's heat, not the room alone, scored well
    /// above the room's with each start and level fitted free. They join no fit.
    #[test]
    fn warm_experiments_choose_among_the_databases_fits_each_from_its_own_level() {
        let database = part_heat_recording(1.6, 8.0, 0.0, 1);
        let shifted = |recording: Recording, by: f64| {
            let part = recording.names().iter().position(|n| n == "part").unwrap();
            let mut out = Recording::new("shifted", recording.names().to_vec()).unwrap();
            let mut row = Vec::new();
            for i in 0..recording.len() {
                recording.row_into(i, &mut row);
                row[part] += by;
                out.push_row(&row).unwrap();
            }
            out
        };
        let experiments = [
            part_heat_recording(1.6, 8.0, 7200.0, 2),
            shifted(part_heat_recording(1.6, 9.0, 10800.0, 3), 3.0),
        ];
        assert!(experiments.iter().all(starts_warm));
        let candidate = |names: &'static [&'static str]| {
            move |r: &Recording| -> Result<Columns, CalibrationError> {
                names
                    .iter()
                    .map(|&name| Ok((name.to_string(), r.column_for(name, "test")?.to_vec())))
                    .collect()
            }
        };
        let (heat, room) = (candidate(&["heat", AMBIENT]), candidate(&[AMBIENT]));
        let fitted = fit_best(
            "test",
            "y",
            std::slice::from_ref(&database),
            &experiments,
            "part",
            &|_, _, r| Ok(vec![room(r)?, heat(r)?]),
            ExperimentUse {
                scoring: Scoring::FromFirstSample,
                warm: WarmExperiment::ScoresOnly,
            },
        )
        .unwrap();
        assert_eq!(fitted.report.selected_by, "experiments");
        assert_eq!(fitted.model.terms, ["const", "heat", AMBIENT]);
        assert!(
            fitted.report.selection_r2 > 0.99,
            "{}",
            fitted.report.selection_r2
        );
    }

    /// A warm experiment is left out of the elongation only for an experiment from rest that
    /// carries its reference over enough rows to teach it; a few rows from rest do not hide a
    /// warm shift.
    #[test]
    fn a_warm_experiment_is_left_out_of_the_elongation_only_beside_one_from_rest_that_teaches() {
        let target = reference_column(AxisId::S, "elongation_um", None);
        let with_reference = |recording: Recording, rows: usize| {
            let mut names = recording.names().to_vec();
            names.push(target.clone());
            let mut out = Recording::new("with reference", names).unwrap();
            let mut row = Vec::new();
            for i in 0..rows.min(recording.len()) {
                recording.row_into(i, &mut row);
                row.push(0.1 * i as f64);
                out.push_row(&row).unwrap();
            }
            out
        };
        let warm = with_reference(part_heat_recording(2.0, 4.0, 7200.0, 2), usize::MAX);
        let long_from_rest = with_reference(part_heat_recording(2.0, 1.0, 0.0, 3), usize::MAX);
        let short_from_rest = with_reference(part_heat_recording(2.0, 1.0, 0.0, 3), 10);
        let use_of = |others: &[Recording]| warm_experiment_for_elongation(&warm, others);
        assert_eq!(
            use_of(&[warm.clone(), long_from_rest.clone()]),
            ElongationExperiment::LeftOut
        );
        assert_eq!(
            use_of(&[warm.clone(), short_from_rest]),
            ElongationExperiment::ScoresAndGain
        );
        assert_eq!(
            warm_experiment_for_elongation(&long_from_rest, std::slice::from_ref(&warm)),
            ElongationExperiment::FromRest
        );
        let without = part_heat_recording(2.0, 1.0, 7200.0, 4);
        assert_eq!(
            warm_experiment_for_elongation(&without, &[warm]),
            ElongationExperiment::NoReference
        );
    }

    /// A bearing that the coolant cools through the bed has that read by its calibrated model,
    /// the coolant's lags taking off about as much as the truth; a bearing the coolant does not
    /// reach gets no coolant term worth the name.
    #[test]
    fn a_bearing_the_coolant_cools_reads_the_coolant_through_the_beds_lags() {
        let ratio = LinearModel::with_terms(
            crate::estimators::models::RATIO_FEATURES,
            &[1.0, 0.0, 0.0, 0.0],
        );
        let split = TorqueSplitEstimator::new(&ratio, &ratio).unwrap();
        let target = reference_column(AxisId::X, "front_bearing_temp_C", None);
        for (cooling, seed) in [(0.8, 3), (0.0, 4)] {
            let database = cooled_bearing_recording(cooling, seed);
            let (model, _) = fit_heat_model(
                HeatFit {
                    axis: AxisId::X,
                    label: "front_bearing_temp",
                    component: Component::FrontBearing,
                    split: &split,
                    target: &target,
                    has_ambient: true,
                    has_coolant: true,
                },
                std::slice::from_ref(&database),
                &[],
            )
            .unwrap();
            let terms = &model.temperature.terms;
            let coolant_share: f64 = terms
                .iter()
                .zip(&model.temperature.coefficients)
                .filter(|(term, _)| term.starts_with("coolant"))
                .map(|(_, c)| c)
                .sum();
            assert!(
                (coolant_share + cooling).abs() < 0.1,
                "cooling {cooling} K: the coolant's lags take {coolant_share} K ({})",
                model.temperature.equation
            );
            if cooling > 0.0 {
                assert!(
                    terms.iter().any(|t| t == "coolant_lag_90min"),
                    "{}",
                    model.temperature.equation
                );
            }
        }
    }

    /// A recording of `y = 1 + 2·x1 + slope_x2·x2 + noise` at 1 Hz with two slow drivers.
    fn linear_recording(rows: usize, slope_x2: f64, seed: u64) -> Recording {
        let names = ["time_s", "x1", "x2", "y"].map(String::from).to_vec();
        let mut recording = Recording::new(format!("synthetic-{seed}"), names).unwrap();
        let mut draw = noise(seed);
        let phase = seed as f64;
        for i in 0..rows {
            let t = i as f64;
            let x1 = (t / 90.0 + phase).sin();
            let x2 = (t / 230.0 + 2.0 * phase).cos();
            let y = 1.0 + 2.0 * x1 + slope_x2 * x2 + 0.05 * draw();
            recording.push_row(&[t, x1, x2, y]).unwrap();
        }
        recording
    }

    /// [`fit_best`] of `target` on one candidate, the recordings' columns `names`, with one
    /// database recording and one experiment.
    fn fit_named(
        database: &Recording,
        experiment: &Recording,
        target: &str,
        names: &[&str],
    ) -> Fitted {
        let columns = |r: &Recording| -> Result<Vec<Columns>, CalibrationError> {
            let candidate = names
                .iter()
                .map(|&name| Ok((name.to_string(), r.column_for(name, "test")?.to_vec())))
                .collect::<Result<Columns, CalibrationError>>()?;
            Ok(vec![candidate])
        };
        fit_best(
            "test",
            "y",
            std::slice::from_ref(database),
            std::slice::from_ref(experiment),
            target,
            &|_, _, r| columns(r),
            ExperimentUse {
                scoring: Scoring::Absolute,
                warm: WarmExperiment::FreeStart,
            },
        )
        .unwrap()
    }

    fn fit_x1_x2(database: &Recording, experiment: &Recording) -> Fitted {
        fit_named(database, experiment, "y", &["x1", "x2"])
    }

    /// The real machine responds to x2 the other way round from the database: no offset or
    /// gain mends that, but fitting the experiments in does, and they count as much as the
    /// database (which is five times longer), so the x2 slope lands half way.
    #[test]
    fn experiments_join_the_fit_when_the_database_response_differs() {
        let database = linear_recording(20_000, 0.5, 1);
        let experiment = linear_recording(4_000, -0.5, 2);
        let joined = fit_x1_x2(&database, &experiment);
        assert_eq!(joined.report.selected_by, SELECTED_BY_JOINED);
        let slope = |f: &Fitted, term: &str| {
            let i = f.model.terms.iter().position(|t| t == term).unwrap();
            f.model.coefficients[i]
        };
        assert!(slope(&joined, "x2").abs() < 0.1, "{:?}", joined.model);
        assert!((slope(&joined, "x1") - 2.0).abs() < 0.05);
        // The database fit alone, scored on the whole experiment, is what it beat.
        let column = |r: &Recording, name: &str| r.column_for(name, "test").unwrap().to_vec();
        let names = |r: &Recording| {
            vec![
                ("x1".into(), column(r, "x1")),
                ("x2".into(), column(r, "x2")),
            ]
        };
        let database_only =
            fit_columns("test", "y", "y", column(&database, "y"), names(&database)).unwrap();
        assert!((slope(&database_only, "x2") - 0.5).abs() < 0.02);
        let predicted = predict(
            &database_only.model.coefficients,
            &names(&experiment),
            4_000,
        );
        let database_score = r_squared(&column(&experiment, "y"), &predicted);
        assert!(
            joined.report.selection_r2 > database_score + 0.02,
            "joined {} vs database only {database_score}",
            joined.report.selection_r2
        );
    }

    /// When the database already describes the machine, whichever fit wins keeps its slopes.
    #[test]
    fn a_database_that_describes_the_machine_keeps_its_slopes() {
        let database = linear_recording(20_000, 0.5, 3);
        let experiment = linear_recording(4_000, 0.5, 4);
        let fitted = fit_x1_x2(&database, &experiment);
        assert!(fitted.report.selection_r2 > 0.99, "{:?}", fitted.report);
        for (term, slope) in [("x1", 2.0), ("x2", 0.5)] {
            let i = fitted.model.terms.iter().position(|t| t == term).unwrap();
            assert!((fitted.model.coefficients[i] - slope).abs() < 0.01);
        }
    }

    /// A part's warm start is the least-squares ratio of each accumulation to the stator's
    /// excess over the room above the floor: on a recording where that excess is exactly twice
    /// the accumulated drag heat and ten times the accumulated load heat, it is 1/2 and 1/10
    /// per kelvin; on recordings where the stator never passes the floor there is none.
    #[test]
    fn a_warm_start_is_the_accumulated_heat_per_kelvin_of_stator_excess() {
        let names = vec![
            "time_s".to_string(),
            axis_column(AxisId::X, Quantity::StatorTemp),
            AMBIENT.to_string(),
        ];
        let tau_s = 600.0;
        let speed = SpeedHeat::of(1500.0);
        let inputs = vec![heat_inputs(2.0, &speed); 3600];
        let drag: Vec<f64> = inputs.iter().map(|i| i.drag).collect();
        let time: Vec<f64> = (0..3600).map(f64::from).collect();
        let accumulated = accumulate(&time, &drag, tau_s);
        let recording_with = |excess: &dyn Fn(f64) -> f64| {
            let mut recording = Recording::new("warming", names.clone()).unwrap();
            for (&t, &h) in time.iter().zip(&accumulated) {
                let room_C = 20.0 + t / 3600.0;
                recording
                    .push_row(&[t, room_C + excess(h), room_C])
                    .unwrap();
            }
            recording
        };
        let warming = recording_with(&|h| WARM_START_FLOOR_K + 2.0 * h);
        let stator = axis_column(AxisId::X, Quantity::StatorTemp);
        let fitted = fit_part_warm_start([(&warming, &inputs)].into_iter(), &stator, tau_s, "t")
            .unwrap()
            .expect("the stator rose past the floor");
        assert!((fitted.per_K("heat") - 0.5).abs() < 1e-12, "{fitted:?}");
        let load_ratio = inputs[0].load / inputs[0].drag;
        assert!(
            (fitted.per_K("load_heat") - 0.5 * load_ratio).abs() < 1e-12,
            "{fitted:?}"
        );
        // Over τ/4 the heat leads the stator: a ratio, but not the same one.
        assert!(fitted.per_K("heat_quarter_tau") > 0.5, "{fitted:?}");
        fitted.check(&PART_ACCUMULATIONS).unwrap();
        let largest = 2.0 * accumulated.iter().copied().fold(0.0, f64::max);
        assert!(
            (fitted.largest_excess_K - largest).abs() < 1e-12,
            "{fitted:?}"
        );
        let at_rest = recording_with(&|_| WARM_START_FLOOR_K * 0.9);
        let none = fit_part_warm_start([(&at_rest, &inputs)].into_iter(), &stator, tau_s, "t");
        assert_eq!(none.unwrap(), None);
    }
}
