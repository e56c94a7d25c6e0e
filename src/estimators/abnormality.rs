//! Motor abnormality (paper Sect. 3.1, step 5): the ideal torque is reverse-calculated from the
//! motion and compared with the measured torque; a lasting excess is the abnormality.
//!
//! The ideal torque of a steadily turning, non-cutting axis is its friction: Palmgren's bearing
//! drag grows with (ν·n)^(2/3), where the lubricant's viscosity ν falls as the axis warms; the
//! ball-screw preload drag varies along the stroke; seals and guides add a constant and a
//! viscous part. The model is therefore linear in the direction, the speed, the "churning" term
//! direction·|n|^(2/3) and that term times the stator's rise over the room (a stand-in for the
//! unmeasured lubricant temperature), plus position terms on feed axes. It is fitted on healthy
//! data (the simulation database and the machine's own experiments) at calibration.
//!
//! Only steady, non-cutting running is scored: at 1 Hz the torque during a speed ramp cannot
//! be reconstructed from the sampled speed (the mean acceleration over a sample is not the one
//! the torque saw), and a cut's torque is not friction. Frames are first averaged into blocks of
//! [`BLOCK_S`] so the same rule holds at 1 Hz and at 1 kHz; a block counts as steady when its
//! speed, and its neighbours' on both sides, stay within [`STEADY_RPM`] (so a block is judged one
//! block late).
//!
//! The score is the excess friction torque — measured minus ideal, signed so that more
//! resistance is positive — as a percentage of the ideal friction torque, averaged
//! exponentially over [`WINDOW_S`] of steady running. It holds its value while the axis cuts or
//! stands. It is reported only once its standard error is below a quarter of the warning
//! level, so noise alone cannot raise a warning.
#![allow(non_snake_case)] // unit suffixes (`_C`, `_Nm`) are part of the names

use crate::profile::Threshold;
use crate::signal::channel::{AMBIENT, CUT_DEPTH};
use crate::signal::{AxisId, Quantity, Recording, axis_column};

use super::models::{AbnormalityModel, BoundModel, IDEAL_TORQUE_FEATURES};
use super::state::{StateWalk, WalkState};

/// Length of the blocks frames are averaged into before scoring, s.
pub const BLOCK_S: f64 = 1.0;
/// A block is steady when its speed, and the step to each neighbour, stay within this, rpm.
pub const STEADY_RPM: f64 = 20.0;
/// Averaging time constant of the score, s of steady running.
pub const WINDOW_S: f64 = 300.0;
/// Slowest speed scored, rpm: below it the friction is in its boundary-lubrication regime.
pub const MIN_SPEED_RPM: f64 = 50.0;

/// One sample of an axis as the abnormality estimator reads it.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct TorqueSample {
    /// Time, s.
    pub time_s: f64,
    /// Motor speed, rpm.
    pub speed_rpm: f64,
    /// Motor torque, N·m.
    pub torque_Nm: f64,
    /// Stator temperature, °C.
    pub stator_C: f64,
    /// Room temperature, °C (`NaN` if not recorded).
    pub ambient_C: f64,
    /// Position along the stroke, 0–1 (`NaN` on a spindle or without a position channel).
    pub stroke_fraction: f64,
    /// True while the tool is in the cut.
    pub cutting: bool,
}

/// One block of averaged samples.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct TorqueBlock {
    /// Mean of the samples (`cutting`: any sample cutting).
    pub mean: TorqueSample,
    /// Lowest and highest speed in the block, rpm.
    pub speed_range_rpm: (f64, f64),
    /// Samples in the block.
    pub samples: usize,
}

/// Averages samples into blocks of [`BLOCK_S`] by their time stamps.
#[derive(Debug, Clone, Default)]
pub struct BlockAverager {
    block: Option<i64>,
    sum: [f64; 6],
    min_rpm: f64,
    max_rpm: f64,
    cutting: bool,
    samples: usize,
}

impl BlockAverager {
    /// Adds a sample; returns the block it closed, if the sample starts a new one.
    pub fn push(&mut self, s: &TorqueSample) -> Option<TorqueBlock> {
        let index = (s.time_s / BLOCK_S).floor() as i64;
        let closed = match self.block {
            Some(b) if b != index => self.finish(),
            _ => None,
        };
        if self.block != Some(index) {
            self.block = Some(index);
            self.sum = [0.0; 6];
            self.min_rpm = f64::INFINITY;
            self.max_rpm = f64::NEG_INFINITY;
            self.cutting = false;
            self.samples = 0;
        }
        for (slot, v) in self.sum.iter_mut().zip([
            s.time_s,
            s.speed_rpm,
            s.torque_Nm,
            s.stator_C,
            s.ambient_C,
            s.stroke_fraction,
        ]) {
            *slot += v;
        }
        self.min_rpm = self.min_rpm.min(s.speed_rpm);
        self.max_rpm = self.max_rpm.max(s.speed_rpm);
        self.cutting |= s.cutting;
        self.samples += 1;
        closed
    }

    fn finish(&self) -> Option<TorqueBlock> {
        if self.samples == 0 {
            return None;
        }
        let k = self.samples as f64;
        let m = |i: usize| self.sum[i] / k;
        Some(TorqueBlock {
            mean: TorqueSample {
                time_s: m(0),
                speed_rpm: m(1),
                torque_Nm: m(2),
                stator_C: m(3),
                ambient_C: m(4),
                stroke_fraction: m(5),
                cutting: self.cutting,
            },
            speed_range_rpm: (self.min_rpm, self.max_rpm),
            samples: self.samples,
        })
    }
}

/// Picks the steady, non-cutting blocks, one block late (it needs the next block's speed).
#[derive(Debug, Clone, Default)]
pub struct SteadyBlockGate {
    before: Option<TorqueBlock>,
    candidate: Option<TorqueBlock>,
}

impl SteadyBlockGate {
    /// Adds a block; returns the previous one if it was steady.
    pub fn push(&mut self, next: TorqueBlock) -> Option<TorqueBlock> {
        let judged = match (self.before, self.candidate) {
            (Some(before), Some(candidate)) => {
                Self::is_steady(&before, &candidate, &next).then_some(candidate)
            }
            _ => None,
        };
        self.before = self.candidate;
        self.candidate = Some(next);
        judged
    }

    fn is_steady(before: &TorqueBlock, candidate: &TorqueBlock, next: &TorqueBlock) -> bool {
        let calm = candidate.speed_range_rpm.1 - candidate.speed_range_rpm.0 <= STEADY_RPM;
        let step = |a: &TorqueBlock, b: &TorqueBlock| {
            (a.mean.speed_rpm - b.mean.speed_rpm).abs() <= STEADY_RPM
        };
        calm && step(before, candidate)
            && step(candidate, next)
            && !(before.mean.cutting || candidate.mean.cutting || next.mean.cutting)
            && candidate.mean.speed_rpm.abs() >= MIN_SPEED_RPM
            && [
                candidate.mean.speed_rpm,
                candidate.mean.torque_Nm,
                candidate.mean.stator_C,
            ]
            .iter()
            .all(|v| v.is_finite())
    }
}

/// The steady, non-cutting blocks of a run of samples (what calibration fits on).
pub fn steady_blocks(samples: impl IntoIterator<Item = TorqueSample>) -> Vec<TorqueBlock> {
    let mut averager = BlockAverager::default();
    let mut gate = SteadyBlockGate::default();
    samples
        .into_iter()
        .filter_map(|s| averager.push(&s))
        .filter_map(|b| gate.push(b))
        .collect()
}

/// The samples of `axis` in a recording, for calibration: `None` when the recording lacks a
/// servo channel of the axis or the depth of cut (without it, cuts would be scored as
/// friction). `stroke_mm` (feed axes) turns the position into a fraction of the stroke.
pub fn recording_samples(
    recording: &Recording,
    axis: AxisId,
    stroke_mm: Option<f64>,
) -> Option<Vec<TorqueSample>> {
    let column = |q: Quantity| recording.try_column(&axis_column(axis, q));
    let speed = column(Quantity::Speed)?;
    let torque = column(Quantity::Torque)?;
    let stator = column(Quantity::StatorTemp)?;
    let cut = recording.try_column(CUT_DEPTH)?;
    let ambient = recording.try_column(AMBIENT);
    let position = stroke_mm.and_then(|_| column(Quantity::Position));
    let time = recording.time();
    Some(
        (0..recording.len())
            .map(|i| TorqueSample {
                time_s: time[i],
                speed_rpm: speed[i],
                torque_Nm: torque[i],
                stator_C: stator[i],
                ambient_C: ambient.map_or(f64::NAN, |a| a[i]),
                stroke_fraction: match (position, stroke_mm) {
                    (Some(x), Some(stroke)) => x[i] / stroke,
                    _ => f64::NAN,
                },
                cutting: cut[i] > 0.0,
            })
            .collect(),
    )
}

/// The ideal-torque terms a calibration fits: the room-referenced form when the room
/// temperature is recorded, the stator form otherwise; position terms on feed axes.
pub fn ideal_torque_terms(has_ambient: bool, has_position: bool) -> Vec<&'static str> {
    let mut terms = vec!["direction", "speed", "churning"];
    if has_ambient {
        terms.extend(["churning*rise", "churning*rise^2", "churning*ambient"]);
    } else {
        terms.extend(["churning*stator", "churning*stator^2"]);
    }
    if has_position {
        terms.extend(["direction*position", "direction*position^2"]);
    }
    terms
}

/// Number of ideal-torque features.
pub const FEATURES: usize = 11;

/// The ideal-torque feature vector of a block, in the order of [`IDEAL_TORQUE_FEATURES`].
pub fn ideal_torque_features(s: &TorqueSample) -> [f64; FEATURES] {
    let direction = s.speed_rpm.signum();
    let churning = direction * s.speed_rpm.abs().powf(2.0 / 3.0);
    let rise = s.stator_C - s.ambient_C;
    let x = s.stroke_fraction;
    [
        1.0,
        direction,
        s.speed_rpm,
        churning,
        churning * rise,
        churning * rise * rise,
        churning * s.ambient_C,
        churning * s.stator_C,
        churning * s.stator_C * s.stator_C,
        direction * x,
        direction * x * x,
    ]
}

/// What the estimator reports.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AbnormalityScore {
    /// Excess friction torque, % of the ideal friction torque (`NaN` until the score is
    /// trustworthy: enough steady running for its standard error to be small).
    pub excess_pct: f64,
    /// Excess friction torque, N·m (averaged like `excess_pct`, reported as soon as there is one
    /// steady block).
    pub excess_Nm: f64,
    /// The ideal friction torque it is relative to, N·m.
    pub ideal_Nm: f64,
    /// Standard error of `excess_pct` from the model's residual scatter, %.
    pub standard_error_pct: f64,
    /// Steady blocks scored so far.
    pub steady_blocks: u64,
}

impl Default for AbnormalityScore {
    fn default() -> Self {
        AbnormalityScore {
            excess_pct: f64::NAN,
            excess_Nm: f64::NAN,
            ideal_Nm: f64::NAN,
            standard_error_pct: f64::NAN,
            steady_blocks: 0,
        }
    }
}

/// The streaming motor abnormality estimator of one axis.
#[derive(Debug, Clone)]
pub struct MotorAbnormalityEstimator {
    ideal: BoundModel,
    residual_sd_Nm: f64,
    report_below_se_pct: f64,
    averager: BlockAverager,
    gate: SteadyBlockGate,
    /// Exponentially weighted sums: excess, ideal, weight, squared weight.
    excess: f64,
    ideal_sum: f64,
    weight: f64,
    weight_sq: f64,
    score: AbnormalityScore,
}

impl MotorAbnormalityEstimator {
    /// An estimator for `model`; the score is reported once its standard error is below
    /// `report_below_se_pct`.
    pub fn new(model: &AbnormalityModel, report_below_se_pct: f64) -> Result<Self, String> {
        if !(model.ideal_torque.rmse.is_finite() && model.ideal_torque.rmse >= 0.0) {
            return Err("the ideal-torque model's rmse must be a non-negative number".into());
        }
        Ok(MotorAbnormalityEstimator {
            ideal: BoundModel::bind(&model.ideal_torque, IDEAL_TORQUE_FEATURES)?,
            residual_sd_Nm: model.ideal_torque.rmse,
            report_below_se_pct,
            averager: BlockAverager::default(),
            gate: SteadyBlockGate::default(),
            excess: 0.0,
            ideal_sum: 0.0,
            weight: 0.0,
            weight_sq: 0.0,
            score: AbnormalityScore::default(),
        })
    }

    /// True if the model reads the room temperature.
    pub fn uses_ambient(model: &AbnormalityModel) -> bool {
        model
            .ideal_torque
            .terms
            .iter()
            .any(|t| t.contains("rise") || t.contains("ambient"))
    }

    /// Adds a sample; returns the score so far.
    pub fn update(&mut self, sample: &TorqueSample) -> AbnormalityScore {
        if let Some(block) = self.averager.push(sample)
            && let Some(steady) = self.gate.push(block)
        {
            self.score_block(&steady);
        }
        self.score
    }

    fn score_block(&mut self, block: &TorqueBlock) {
        let s = &block.mean;
        let direction = s.speed_rpm.signum();
        let ideal = self.ideal.eval(&ideal_torque_features(s));
        let excess = (s.torque_Nm - ideal) * direction;
        let ideal_friction = ideal * direction;
        if !(excess.is_finite() && ideal_friction.is_finite()) {
            return;
        }
        // Only steady blocks age the average, so the score holds through cuts and stops.
        let keep = (-BLOCK_S / WINDOW_S).exp();
        let new = 1.0 - keep;
        self.excess = keep * self.excess + new * excess;
        self.ideal_sum = keep * self.ideal_sum + new * ideal_friction;
        self.weight = keep * self.weight + new;
        self.weight_sq = keep * keep * self.weight_sq + new * new;
        let excess_Nm = self.excess / self.weight;
        let ideal_Nm = self.ideal_sum / self.weight;
        let effective_blocks = self.weight * self.weight / self.weight_sq;
        let se_Nm = self.residual_sd_Nm / effective_blocks.sqrt();
        let (pct, se_pct) = if ideal_Nm > 0.0 {
            (100.0 * excess_Nm / ideal_Nm, 100.0 * se_Nm / ideal_Nm)
        } else {
            (f64::NAN, f64::NAN)
        };
        self.score = AbnormalityScore {
            excess_pct: if se_pct <= self.report_below_se_pct {
                pct
            } else {
                f64::NAN
            },
            excess_Nm,
            ideal_Nm,
            standard_error_pct: se_pct,
            steady_blocks: self.score.steady_blocks + 1,
        };
    }

    /// The score so far.
    pub fn score(&self) -> AbnormalityScore {
        self.score
    }
}

impl WalkState for MotorAbnormalityEstimator {
    fn walk_state(&mut self, walk: &mut StateWalk<'_>) {
        self.averager.walk_state(walk);
        self.gate.walk_state(walk);
        walk.value(&mut self.excess);
        walk.value(&mut self.ideal_sum);
        walk.value(&mut self.weight);
        walk.value(&mut self.weight_sq);
        let score = &mut self.score;
        walk.value(&mut score.excess_pct);
        walk.value(&mut score.excess_Nm);
        walk.value(&mut score.ideal_Nm);
        walk.value(&mut score.standard_error_pct);
        walk.count(&mut score.steady_blocks);
    }
}

impl MotorAbnormalityEstimator {
    /// Drops the block being averaged and the blocks waiting to be judged: for frames whose
    /// clock started again, on which a block (a span of machine time) cannot go on.
    pub fn start_blocks_again(&mut self) {
        self.averager = BlockAverager::default();
        self.gate = SteadyBlockGate::default();
    }
}

impl WalkState for BlockAverager {
    fn walk_state(&mut self, walk: &mut StateWalk<'_>) {
        let mut block = self.block.map(|b| b as f64);
        walk.optional(&mut block);
        self.block = block.map(|b| b as i64);
        walk.values(&mut self.sum);
        walk.value(&mut self.min_rpm);
        walk.value(&mut self.max_rpm);
        walk.flag(&mut self.cutting);
        walk.count_usize(&mut self.samples);
    }
}

impl WalkState for SteadyBlockGate {
    fn walk_state(&mut self, walk: &mut StateWalk<'_>) {
        walk.optional_state(&mut self.before);
        walk.optional_state(&mut self.candidate);
    }
}

impl WalkState for TorqueBlock {
    fn walk_state(&mut self, walk: &mut StateWalk<'_>) {
        let s = &mut self.mean;
        walk.value(&mut s.time_s);
        walk.value(&mut s.speed_rpm);
        walk.value(&mut s.torque_Nm);
        walk.value(&mut s.stator_C);
        walk.value(&mut s.ambient_C);
        walk.value(&mut s.stroke_fraction);
        walk.flag(&mut s.cutting);
        walk.value(&mut self.speed_range_rpm.0);
        walk.value(&mut self.speed_range_rpm.1);
        walk.count_usize(&mut self.samples);
    }
}

/// How an abnormality score is judged (worst last).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum AbnormalityState {
    /// Not enough steady running yet for a trustworthy score.
    NotYetKnown,
    /// Within the warning level.
    Normal,
    /// At or beyond the warning level.
    Warning,
    /// At or beyond the fault level.
    Fault,
}

impl AbnormalityState {
    /// The state in words.
    pub fn label(self) -> &'static str {
        match self {
            AbnormalityState::NotYetKnown => "not yet known",
            AbnormalityState::Normal => "normal",
            AbnormalityState::Warning => "warning",
            AbnormalityState::Fault => "fault",
        }
    }
}

/// The state of a known excess friction `pct` against the profile's levels (either way).
pub fn classify(pct: f64, levels: Threshold) -> AbnormalityState {
    if !pct.is_finite() {
        AbnormalityState::NotYetKnown
    } else if pct.abs() >= levels.fault {
        AbnormalityState::Fault
    } else if pct.abs() >= levels.warning {
        AbnormalityState::Warning
    } else {
        AbnormalityState::Normal
    }
}

/// What an abnormal excess friction most likely means, in words.
pub fn likely_cause(pct: f64) -> &'static str {
    if pct > 0.0 {
        "wear, damage or failing lubrication?"
    } else {
        "lost preload?"
    }
}

/// Judges a score against the profile's levels (in % of the ideal friction torque, either
/// way: more friction than healthy is wear or damage, less is lost preload); the state and the
/// reason in words.
pub fn judge(score: &AbnormalityScore, levels: Threshold) -> (AbnormalityState, String) {
    let pct = score.excess_pct;
    if !pct.is_finite() {
        return (
            AbnormalityState::NotYetKnown,
            format!(
                "{} steady non-cutting seconds so far; the score is shown once its uncertainty \
                 is below {:.1} %",
                score.steady_blocks,
                levels.warning / 4.0
            ),
        );
    }
    let state = classify(pct, levels);
    let mut reason = format!(
        "friction torque {pct:+.1} % ± {:.1} % against the healthy model ({:+.3} N·m on {:.3} N·m)",
        score.standard_error_pct, score.excess_Nm, score.ideal_Nm
    );
    if state > AbnormalityState::Normal {
        reason.push_str(": ");
        reason.push_str(likely_cause(pct));
    }
    (state, reason)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::estimators::models::LinearModel;

    fn sample(t: f64, rpm: f64, torque: f64, cutting: bool) -> TorqueSample {
        TorqueSample {
            time_s: t,
            speed_rpm: rpm,
            torque_Nm: torque,
            stator_C: 30.0,
            ambient_C: 20.0,
            stroke_fraction: f64::NAN,
            cutting,
        }
    }

    /// Friction 0.5 N·m + 0.01 N·m per rpm^(2/3), turning forwards.
    fn model(rmse: f64) -> AbnormalityModel {
        AbnormalityModel {
            ideal_torque: LinearModel {
                rmse,
                ..LinearModel::with_terms(&["const", "direction", "churning"], &[0.0, 0.5, 0.01])
            },
        }
    }

    fn friction(rpm: f64) -> f64 {
        0.5 + 0.01 * rpm.powf(2.0 / 3.0)
    }

    #[test]
    fn steady_blocks_exclude_ramps_cuts_and_their_neighbours() {
        let speeds = [0.0, 500.0, 1000.0, 1000.0, 1000.0, 1000.0, 1000.0, 1500.0];
        let cutting = [false, false, false, false, true, false, false, false];
        let samples: Vec<_> = speeds
            .iter()
            .zip(cutting)
            .enumerate()
            .map(|(t, (&n, c))| sample(t as f64, n, friction(n), c))
            .collect();
        let kept: Vec<f64> = steady_blocks(samples)
            .iter()
            .map(|b| b.mean.time_s)
            .collect();
        // t = 3 borders the cut at 4, t = 5 too, t = 6 borders the ramp to 1500.
        assert_eq!(kept, Vec::<f64>::new());
        let samples: Vec<_> = (0..10)
            .map(|t| sample(t as f64, 1000.0, friction(1000.0), false))
            .collect();
        let kept: Vec<f64> = steady_blocks(samples)
            .iter()
            .map(|b| b.mean.time_s)
            .collect();
        // Blocks 0–8 closed (9 is still open); all but the first (no predecessor) and the
        // last closed one (no successor yet) are steady.
        assert_eq!(kept, (1..8).map(f64::from).collect::<Vec<_>>());
    }

    #[test]
    fn fast_samples_are_averaged_into_one_second_blocks() {
        let mut averager = BlockAverager::default();
        let mut closed = Vec::new();
        for i in 0..3000 {
            let t = i as f64 * 0.001;
            if let Some(b) = averager.push(&sample(t, 1000.0 + (i % 2) as f64, 2.0, false)) {
                closed.push(b);
            }
        }
        assert_eq!(closed.len(), 2);
        assert_eq!(closed[0].samples, 1000);
        assert!((closed[0].mean.speed_rpm - 1000.5).abs() < 1e-9);
        assert_eq!(closed[0].speed_range_rpm, (1000.0, 1001.0));
    }

    #[test]
    fn a_healthy_axis_scores_zero_and_a_friction_rise_scores_its_percentage() {
        let rpm = 1000.0;
        for (extra, expected_pct) in [(0.0, 0.0), (0.2 * friction(1000.0), 20.0)] {
            let mut estimator = MotorAbnormalityEstimator::new(&model(0.05), 2.5).unwrap();
            let mut score = AbnormalityScore::default();
            for t in 0..2000 {
                score = estimator.update(&sample(t as f64, rpm, friction(rpm) + extra, t > 1500));
            }
            assert!(
                (score.excess_pct - expected_pct).abs() < 1e-6,
                "{score:?} for +{extra} N·m"
            );
            // Scoring stopped with the cut: blocks 1–1499 (block 0 has no predecessor, block
            // 1500 borders the cut).
            assert_eq!(score.steady_blocks, 1499);
        }
    }

    #[test]
    fn the_score_is_withheld_until_its_standard_error_is_small() {
        // rmse 1 N·m against 1.5 N·m of friction: one block's standard error is ~67 %.
        let mut estimator = MotorAbnormalityEstimator::new(&model(1.0), 3.0).unwrap();
        let first = (0..5)
            .map(|t| estimator.update(&sample(t as f64, 1000.0, friction(1000.0), false)))
            .last()
            .unwrap();
        assert!(first.excess_pct.is_nan());
        assert!(first.excess_Nm.abs() < 1e-12);
        assert!(first.standard_error_pct > 3.0);
        let later = (5..5000)
            .map(|t| estimator.update(&sample(t as f64, 1000.0, friction(1000.0), false)))
            .last()
            .unwrap();
        // The effective count of an exponential average over 300 blocks is ≈ 600: 67 %/√600.
        assert!(later.standard_error_pct < 3.0 && later.excess_pct.abs() < 1e-9);
    }

    #[test]
    fn judging_names_the_state_and_the_likely_cause() {
        let levels = Threshold {
            warning: 8.0,
            fault: 25.0,
        };
        let score = |pct: f64| AbnormalityScore {
            excess_pct: pct,
            excess_Nm: pct / 100.0,
            ideal_Nm: 1.0,
            standard_error_pct: 1.5,
            steady_blocks: 900,
        };
        let (state, reason) = judge(&score(2.0), levels);
        assert_eq!(state, AbnormalityState::Normal);
        assert!(!reason.contains('?'), "{reason}");
        let (state, reason) = judge(&score(19.7), levels);
        assert_eq!(state, AbnormalityState::Warning);
        assert!(reason.contains("+19.7 % ± 1.5 %") && reason.contains("wear"));
        let (state, reason) = judge(&score(-30.0), levels);
        assert_eq!(state, AbnormalityState::Fault);
        assert!(reason.contains("lost preload"), "{reason}");
        let (state, reason) = judge(&score(f64::NAN), levels);
        assert_eq!(state, AbnormalityState::NotYetKnown);
        assert!(reason.contains("900 steady"), "{reason}");
    }

    #[test]
    fn reverse_running_counts_resistance_as_positive() {
        let mut estimator = MotorAbnormalityEstimator::new(&model(0.01), 5.0).unwrap();
        // Reverse: ideal torque is −(0.5 + 0.01·|n|^(2/3)); measured 10 % more negative.
        let ideal = -friction(500.0);
        let score = (0..1000)
            .map(|t| estimator.update(&sample(t as f64, -500.0, 1.1 * ideal, false)))
            .last()
            .unwrap();
        assert!((score.excess_pct - 10.0).abs() < 1e-6, "{score:?}");
    }
}
