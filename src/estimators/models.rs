//! Fitted models as the machine profile stores them, and their fast evaluation.
//!
//! A model is a list of named terms with coefficients. Each estimator has a fixed feature
//! vector (`FLANGE_FEATURES`, `HEAT_FEATURES`, …); binding a model to it turns term names into
//! indices once, so evaluating it per frame is a handful of multiply-adds with no lookups and no
//! allocation.
#![allow(non_snake_case)] // unit suffixes (`_C`, `_Nm`) are part of the names

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use crate::signal::AxisId;

/// Motor flange temperature (Eq. 7): constant, stator temperature, room temperature — and, as
/// calibration may choose, the stator through the lags of [`STATOR_LAG_TAUS_S`] (the flange is
/// a mass of its own that the stator's heat reaches through the housing, so it follows the
/// stator late, not at once) and the room through the lags of [`AMBIENT_LAG_TAUS_S`]. A fitted
/// model uses a subset.
pub const FLANGE_FEATURES: &[&str] = &[
    "const",
    "stator",
    "ambient",
    "stator_lag_5min",
    "stator_lag_15min",
    "stator_lag_45min",
    "ambient_lag_30min",
    "ambient_lag_90min",
    "ambient_lag_270min",
];
/// Time constants of the stator lags the motor flange, bearing and nut models may read.
pub const STATOR_LAG_TAUS_S: [f64; 3] = [300.0, 900.0, 2700.0];
/// The feature names of [`STATOR_LAG_TAUS_S`], in the same order.
pub const STATOR_LAG_FEATURES: [&str; 3] =
    ["stator_lag_5min", "stator_lag_15min", "stator_lag_45min"];
/// Torque ratios (Eq. 8): a cubic in the motor torque.
pub const RATIO_FEATURES: &[&str] = &["const", "torque", "torque^2", "torque^3"];
/// Bearing and nut temperature (Eqs. 9–12): constant, stator (the initial temperature),
/// room, accumulated drag heat (∝ speed: the preload drag torque is nearly constant),
/// accumulated load heat (∝ speed × the component's estimated torque), accumulated churning
/// heat (∝ |n|^(5/3): Palmgren's load-free bearing torque grows as (ν·n)^(2/3)), the room
/// through the slow lags of the machine's mass ([`AMBIENT_LAG_FEATURES`]) — and, as
/// calibration may choose, the part's surroundings: the stator through the lags of
/// [`STATOR_LAG_TAUS_S`] (the motor's heat reaches a bearing late, through the flange, the bed
/// and the screw) and the coolant's on/off state through the lags of [`BED_LAG_TAUS_S`] (the
/// coolant washes the bed the bearings sit on, which passes its cooling on slowly), and the
/// drag and load heat accumulated again over τ / [`FAST_HEAT_DIVISOR`] ([`FAST_HEAT_FEATURES`]).
/// A fitted model uses a subset.
pub const HEAT_FEATURES: &[&str] = &[
    "const",
    "stator",
    "ambient",
    "heat",
    "load_heat",
    "churning_heat",
    "heat_quarter_tau",
    "load_heat_quarter_tau",
    "ambient_lag_30min",
    "ambient_lag_90min",
    "ambient_lag_270min",
    "stator_lag_5min",
    "stator_lag_15min",
    "stator_lag_45min",
    "coolant_lag_30min",
    "coolant_lag_90min",
];
/// The drag and load heat of [`HEAT_FEATURES`] accumulated a second time, over
/// τ / [`FAST_HEAT_DIVISOR`]. A part's heat reaches it through more than one mass: the rolling
/// elements, rings and nut warm within minutes, the housing and the bed they sit in over the
/// part's τ, which one accumulation cannot follow both of (docs/accuracy.md, *A part's heat
/// arrives over two time constants*). Named for the divisor, so a profile's term keeps its
/// meaning (the elongation's `heat_fast` is another quantity, over its own `fast_tau_s`).
pub const FAST_HEAT_FEATURES: [&str; 2] = ["heat_quarter_tau", "load_heat_quarter_tau"];
/// τ of [`FAST_HEAT_FEATURES`] is the part's τ divided by this (the features' names say it).
pub const FAST_HEAT_DIVISOR: f64 = 4.0;
/// The coolant features of [`HEAT_FEATURES`] and [`STRAIGHTNESS_FEATURES`]: its on/off state
/// through each lag of [`BED_LAG_TAUS_S`].
pub const COOLANT_LAG_FEATURES: [&str; 2] = ["coolant_lag_30min", "coolant_lag_90min"];
/// The room temperature through first-order lags of these time constants: the bed, the base
/// and the housings follow the room slowly, and a component bolted to them with it.
pub const AMBIENT_LAG_TAUS_S: [f64; 3] = [1800.0, 5400.0, 16200.0];
/// The feature names of [`AMBIENT_LAG_TAUS_S`], in the same order.
pub const AMBIENT_LAG_FEATURES: [&str; 3] = [
    "ambient_lag_30min",
    "ambient_lag_90min",
    "ambient_lag_270min",
];
/// Straightness per node (Eqs. 13–14): cubics in front-bearing, back-bearing and motor
/// temperatures, and the room (now and through the lags of [`AMBIENT_LAG_TAUS_S`]: the bed's
/// base, whose temperature the bending is measured against, follows the room slowly) — or, as
/// the alternative calibration may choose, linear in the thermal states those temperatures are
/// built from (stator temperature and the bearings' accumulated drag and load heat), which
/// keeps the temperature models' errors out of the bending estimate — or linear in the
/// temperatures plus the bed's own state ([`BED_LAG_FEATURES`]): the bed and its base warm
/// through the parts bolted to them (the motor flange and the back bearing at the ends, the nut
/// through the screw and the table) and the coolant washes the bed, all slowly. A fitted model
/// uses a subset.
pub const STRAIGHTNESS_FEATURES: &[&str] = &[
    "const",
    "front",
    "front^2",
    "front^3",
    "back",
    "back^2",
    "back^3",
    "motor",
    "motor^2",
    "motor^3",
    "ambient",
    "stator",
    "front_heat",
    "front_load_heat",
    "back_heat",
    "back_load_heat",
    "ambient_lag_30min",
    "ambient_lag_90min",
    "ambient_lag_270min",
    "nut",
    "motor_lag_30min",
    "motor_lag_90min",
    "back_lag_30min",
    "back_lag_90min",
    "coolant_lag_30min",
    "coolant_lag_90min",
];
/// Time constants of the bed's state as the straightness models read it: the estimated motor
/// and back-bearing temperatures and the coolant's on/off state through first-order lags (the
/// bearing and nut models read the coolant through the same lags).
pub const BED_LAG_TAUS_S: [f64; 2] = [1800.0, 5400.0];
/// The bed-state features of [`STRAIGHTNESS_FEATURES`]: the estimated nut temperature, then the
/// motor, the back bearing and the coolant through each lag of [`BED_LAG_TAUS_S`].
pub const BED_LAG_FEATURES: [&str; 7] = [
    "nut",
    "motor_lag_30min",
    "motor_lag_90min",
    "back_lag_30min",
    "back_lag_90min",
    "coolant_lag_30min",
    "coolant_lag_90min",
];
/// Spindle elongation (Eq. 15): ΔT of the stator since tool calibration, speed, load; heat
/// accumulated over a fast, a middle, a slow and a long time constant (Eq. 10's form applied to
/// the spindle's losses) of each of [`ELONGATION_HEAT_INPUTS`]; the room and the room through
/// the lags of [`AMBIENT_LAG_TAUS_S`] (the bed that carries the tool follows it slowly). The
/// room terms are counted from the tool-calibration moment like ΔT. A fitted model uses a
/// subset; the names are `{input}_{tau}` in the order input-major, then
/// [`ELONGATION_TAU_NAMES`].
pub const ELONGATION_FEATURES: &[&str] = &[
    "const",
    "delta_stator",
    "speed",
    "load",
    "heat_fast",
    "heat_mid",
    "heat_slow",
    "heat_long",
    "load_heat_fast",
    "load_heat_mid",
    "load_heat_slow",
    "load_heat_long",
    "churning_heat_fast",
    "churning_heat_mid",
    "churning_heat_slow",
    "churning_heat_long",
    "copper_heat_fast",
    "copper_heat_mid",
    "copper_heat_slow",
    "copper_heat_long",
    "coolant_fast",
    "coolant_mid",
    "coolant_slow",
    "coolant_long",
    "coolant_cooling_fast",
    "coolant_cooling_mid",
    "coolant_cooling_slow",
    "coolant_cooling_long",
    "ambient",
    "ambient_lag_30min",
    "ambient_lag_90min",
    "ambient_lag_270min",
];
/// What the spindle's heat terms accumulate, as feature-name prefixes: `heat`, the speed
/// (bearing drag and seals); `load_heat`, the load (cutting torque, through the bearings);
/// `churning_heat`, |n|^(5/3) (Palmgren's load-free bearing torque grows as (ν·n)^(2/3));
/// `copper_heat`, the current squared (I²R losses reaching the housing through the stator);
/// `coolant`, the coolant being on; `coolant_cooling`, the coolant being on times the
/// stator's rise over the room (the jacket takes heat in proportion to how warm the headstock
/// runs above the coolant, which a chiller holds near the room).
pub const ELONGATION_HEAT_INPUTS: [&str; 6] = [
    "heat",
    "load_heat",
    "churning_heat",
    "copper_heat",
    "coolant",
    "coolant_cooling",
];
/// Suffixes of the elongation's accumulation time constants, shortest first.
pub const ELONGATION_TAU_NAMES: [&str; 4] = ["fast", "mid", "slow", "long"];
/// Ideal (friction) torque of a steadily running axis, for the abnormality score (see
/// [`super::abnormality`]): constant, direction, speed, the churning term direction·|n|^(2/3)
/// and it times the stator's rise over the room (and its square) or, without a room
/// temperature, times the stator temperature, and position terms along the stroke. A fitted
/// model uses a subset.
pub const IDEAL_TORQUE_FEATURES: &[&str] = &[
    "const",
    "direction",
    "speed",
    "churning",
    "churning*rise",
    "churning*rise^2",
    "churning*ambient",
    "churning*stator",
    "churning*stator^2",
    "direction*position",
    "direction*position^2",
];

/// A linear model over named terms.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LinearModel {
    /// The equation in words, for reports ("T_flange = c0 + c1·T_stator").
    pub equation: String,
    /// Term names, `const` first.
    pub terms: Vec<String>,
    /// One coefficient per term.
    pub coefficients: Vec<f64>,
    /// R² of the fit.
    pub r2: f64,
    /// Samples it was fitted on.
    pub n: usize,
    /// The regression F statistic.
    pub f_statistic: f64,
    /// Its p-value.
    pub f_p_value: f64,
    /// Residual standard deviation, in the target's unit.
    pub rmse: f64,
}

#[cfg(test)]
impl LinearModel {
    /// A model with these terms and coefficients and placeholder fit statistics, for tests of
    /// the estimators that evaluate it.
    pub(crate) fn with_terms(terms: &[&str], coefficients: &[f64]) -> LinearModel {
        LinearModel {
            equation: String::new(),
            terms: terms.iter().map(|s| s.to_string()).collect(),
            coefficients: coefficients.to_vec(),
            r2: 1.0,
            n: 10,
            f_statistic: 1.0,
            f_p_value: 0.0,
            rmse: 0.0,
        }
    }
}

/// A heat-accumulation model (Eqs. 10–12): H ← H(1 − C_BH) + C_BH·H′ for each heat input H′
/// (drag ∝ |n|, load ∝ |τ·n|, churning ∝ |n|^(5/3), all with the one τ, and the drag and load
/// again over τ / [`FAST_HEAT_DIVISOR`] where the model reads [`FAST_HEAT_FEATURES`]), then a
/// linear model over `HEAT_FEATURES`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HeatModel {
    /// Time constant of the heat accumulation, s.
    pub tau_s: f64,
    /// C_BH at the rate the model was fitted at (1 − e^(−Δt/τ)); rescaled for other rates.
    pub c_bh: f64,
    /// The temperature model.
    pub temperature: LinearModel,
    /// How the accumulated heat starts on a machine that is already warm (profiles calibrated
    /// before it existed, or without a room column, start every part at rest).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub warm_start: Option<WarmStart>,
}

/// The stator's excess over the room that a [`WarmStart`] reads as none: a stator sensor and a
/// room sensor disagree by a few tenths of a kelvin on a machine at rest (noise, offsets), and
/// a seed from that would start a cold machine warm. Seeds and their fit both count only the
/// excess above it; the twin's X stator is 1.0–1.9 K above the room after an hour or more of
/// production (docs/accuracy.md, *A recording that starts mid-shift*).
pub const WARM_START_FLOOR_K: f64 = 0.5;

/// The stator's excess over the room when it is above [`WARM_START_FLOOR_K`]: the machine was
/// warm. None for a stator within the floor of the room, or a reading that is not a number.
pub fn warm_excess(stator_C: f64, room_C: f64) -> Option<f64> {
    let excess = stator_C - room_C;
    (excess.is_finite() && excess > WARM_START_FLOOR_K).then_some(excess)
}

/// The accumulations of a bearing's or the nut's heat model, by the feature that reads each
/// ([`HEAT_FEATURES`]): what a [`WarmStart`] of a part may seed.
pub const PART_ACCUMULATIONS: [&str; 5] = [
    "heat",
    "load_heat",
    "churning_heat",
    "heat_quarter_tau",
    "load_heat_quarter_tau",
];

/// Where accumulated heat starts when its estimator starts: each accumulation's value per
/// kelvin of the stator's excess over the room in the first frame (counted above
/// [`WARM_START_FLOOR_K`]), by the feature that reads it, fitted on the calibration recordings
/// (least squares through the origin). An accumulation it does not name starts at zero.
///
/// An accumulation that started at zero would read a machine that has run for hours as one
/// just switched on, and a recording or a session that starts mid-shift would under-read every
/// part for about 2τ (docs/accuracy.md, *A recording that starts mid-shift*). The stator is
/// the only part the drives measure whose excess over the room says how hard the axis has been
/// working lately: it warms with the same moves that heat the bearings and the nut. (The
/// spindle elongation has none: its heat bank seeded so read worse, docs/accuracy.md.) A stator
/// within the floor of the room seeds nothing, so a machine at rest starts as
/// before.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WarmStart {
    /// The largest counted excess the calibration recordings showed, K: a larger one (a
    /// hotter machine than any calibrated, or a spiked first reading) seeds as this one, since
    /// the fit says nothing beyond it.
    pub largest_excess_K: f64,
    /// Accumulated value per kelvin of counted excess, by the feature that reads it.
    pub per_K: BTreeMap<String, f64>,
}

impl WarmStart {
    /// The accumulated value per kelvin for `feature` (zero for one it does not name).
    pub fn per_K(&self, feature: &str) -> f64 {
        self.per_K.get(feature).copied().unwrap_or(0.0)
    }

    /// The excess a warm start counts for a stator `stator_C` and a room `room_C`: what is
    /// above [`WARM_START_FLOOR_K`] ([`warm_excess`]), zero for a machine that was not warm.
    pub fn counted_excess(stator_C: f64, room_C: f64) -> f64 {
        warm_excess(stator_C, room_C).map_or(0.0, |excess| excess - WARM_START_FLOOR_K)
    }

    /// The excess the seeds are made for: [`WarmStart::counted_excess`], at most
    /// [`WarmStart::largest_excess_K`].
    pub fn seeded_excess(&self, stator_C: f64, room_C: f64) -> f64 {
        Self::counted_excess(stator_C, room_C).min(self.largest_excess_K)
    }

    /// The starting values of `features`' accumulations for a stator `stator_C` and a room
    /// `room_C` ([`WarmStart::seeded_excess`]).
    pub fn seeds<const N: usize>(
        &self,
        features: &[&str; N],
        stator_C: f64,
        room_C: f64,
    ) -> [f64; N] {
        let excess = self.seeded_excess(stator_C, room_C);
        features.map(|feature| self.per_K(feature) * excess)
    }

    /// Checks that every feature named is one of `accumulations` and every value a
    /// non-negative number (heat never accumulates below zero).
    pub fn check(&self, accumulations: &[&str]) -> Result<(), String> {
        if !(self.largest_excess_K.is_finite() && self.largest_excess_K > 0.0) {
            return Err(format!(
                "largest_excess_K must be a positive number, not {}",
                self.largest_excess_K
            ));
        }
        for (feature, value) in &self.per_K {
            if !accumulations.contains(&feature.as_str()) {
                return Err(format!(
                    "`{feature}` is not an accumulation this model starts (one of {})",
                    accumulations.join(", ")
                ));
            }
            if !(value.is_finite() && *value >= 0.0) {
                return Err(format!(
                    "`{feature}` must be a non-negative number (heat never accumulates below \
                     zero), not {value}"
                ));
            }
        }
        Ok(())
    }
}

impl HeatModel {
    /// True if the temperature model reads the heat over τ / [`FAST_HEAT_DIVISOR`]
    /// ([`FAST_HEAT_FEATURES`]), which is then accumulated too.
    pub fn reads_fast_heat(&self) -> bool {
        let terms = &self.temperature.terms;
        FAST_HEAT_FEATURES
            .iter()
            .any(|name| terms.iter().any(|term| term == name))
    }
}

/// The spindle elongation model: time constants of the heat terms and the linear model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ElongationModel {
    /// Time constant of the `*_fast` heat terms, s.
    pub fast_tau_s: f64,
    /// Time constant of the `*_mid` heat terms, s.
    pub mid_tau_s: f64,
    /// Time constant of the `*_slow` heat terms, s.
    pub slow_tau_s: f64,
    /// Time constant of the `*_long` heat terms, s (profiles from before it existed use none
    /// of them).
    #[serde(default = "default_long_tau_s")]
    pub long_tau_s: f64,
    /// The model over `ELONGATION_FEATURES`.
    pub model: LinearModel,
}

/// The long time constant of a profile written before the elongation had one, s.
fn default_long_tau_s() -> f64 {
    16200.0
}

/// The motor abnormality model: the healthy axis's ideal torque when running steadily.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AbnormalityModel {
    /// The ideal torque over `IDEAL_TORQUE_FEATURES`, fitted on steady non-cutting blocks; its
    /// `rmse` is the block-to-block scatter the score's standard error is built from.
    pub ideal_torque: LinearModel,
}

/// Every fitted model of one axis.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AxisModels {
    /// Motor flange temperature (Eq. 7).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub motor_flange: Option<LinearModel>,
    /// Nut-to-bearing torque ratio r_BN (Eq. 8).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub nut_bearing_ratio: Option<LinearModel>,
    /// Back-to-front bearing torque ratio (the same method, Sect. 3.2).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub back_front_ratio: Option<LinearModel>,
    /// Front bearing temperature.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub front_bearing_temp: Option<HeatModel>,
    /// Back bearing temperature.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub back_bearing_temp: Option<HeatModel>,
    /// Nut temperature.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub nut_temp: Option<HeatModel>,
    /// Horizontal straightness per node (Eq. 13), node 1 first.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub straightness_h: Vec<LinearModel>,
    /// Vertical straightness per node (Eq. 14).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub straightness_v: Vec<LinearModel>,
    /// Spindle thermal elongation (Eq. 15).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub elongation: Option<ElongationModel>,
    /// Ideal torque of the healthy axis, for the abnormality score.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub abnormality: Option<AbnormalityModel>,
}

/// The fitted part of a machine profile.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Calibration {
    /// Sample rate of the database the models were fitted on, Hz.
    pub fitted_rate_hz: f64,
    /// The database files.
    pub database: Vec<String>,
    /// The experiment files that corrected it.
    #[serde(default)]
    pub experiments: Vec<String>,
    /// Models per axis.
    pub axes: BTreeMap<AxisId, AxisModels>,
}

impl Calibration {
    /// Checks every model's shape against its feature set: (field, message) on error.
    pub fn validate(&self) -> Result<(), (String, String)> {
        if !(self.fitted_rate_hz.is_finite() && self.fitted_rate_hz > 0.0) {
            return Err(("fitted_rate_hz".into(), "must be positive".into()));
        }
        for (axis, m) in &self.axes {
            let check = |name: String, model: &LinearModel, features: &[&str]| {
                BoundModel::bind(model, features)
                    .map(|_| ())
                    .map_err(|e| (name, e))
            };
            let p = |field: &str| format!("axes.{axis}.{field}");
            if let Some(model) = &m.motor_flange {
                check(p("motor_flange"), model, FLANGE_FEATURES)?;
            }
            for (field, model) in [
                ("nut_bearing_ratio", &m.nut_bearing_ratio),
                ("back_front_ratio", &m.back_front_ratio),
            ] {
                if let Some(model) = model {
                    check(p(field), model, RATIO_FEATURES)?;
                }
            }
            for (field, model) in [
                ("front_bearing_temp", &m.front_bearing_temp),
                ("back_bearing_temp", &m.back_bearing_temp),
                ("nut_temp", &m.nut_temp),
            ] {
                if let Some(heat) = model {
                    if !(heat.tau_s > 0.0 && heat.c_bh > 0.0 && heat.c_bh <= 1.0) {
                        return Err((p(field), "tau_s must be positive and c_bh in (0, 1]".into()));
                    }
                    check(p(field), &heat.temperature, HEAT_FEATURES)?;
                    if let Some(warm) = &heat.warm_start {
                        warm.check(&PART_ACCUMULATIONS)
                            .map_err(|e| (p(&format!("{field}.warm_start")), e))?;
                    }
                }
            }
            for (k, model) in m.straightness_h.iter().enumerate() {
                check(
                    p(&format!("straightness_h[{k}]")),
                    model,
                    STRAIGHTNESS_FEATURES,
                )?;
            }
            for (k, model) in m.straightness_v.iter().enumerate() {
                check(
                    p(&format!("straightness_v[{k}]")),
                    model,
                    STRAIGHTNESS_FEATURES,
                )?;
            }
            if let Some(e) = &m.elongation {
                if !(e.fast_tau_s > 0.0 && e.mid_tau_s > 0.0 && e.slow_tau_s > 0.0) {
                    return Err((p("elongation"), "time constants must be positive".into()));
                }
                check(p("elongation"), &e.model, ELONGATION_FEATURES)?;
            }
            if let Some(a) = &m.abnormality {
                if !(a.ideal_torque.rmse.is_finite() && a.ideal_torque.rmse >= 0.0) {
                    return Err((
                        p("abnormality"),
                        "rmse must be a non-negative number".into(),
                    ));
                }
                check(
                    p("abnormality.ideal_torque"),
                    &a.ideal_torque,
                    IDEAL_TORQUE_FEATURES,
                )?;
            }
        }
        Ok(())
    }
}

/// A model bound to a feature vector: evaluation is Σ cᵢ·`x[idxᵢ]`.
#[derive(Debug, Clone)]
pub struct BoundModel {
    terms: Vec<(usize, f64)>,
}

impl BoundModel {
    /// Binds `model`'s terms to positions in `features`; unknown terms, duplicates, a missing
    /// `const`, a length mismatch or a non-finite coefficient are errors.
    pub fn bind(model: &LinearModel, features: &[&str]) -> Result<BoundModel, String> {
        if model.terms.len() != model.coefficients.len() {
            return Err(format!(
                "{} terms but {} coefficients",
                model.terms.len(),
                model.coefficients.len()
            ));
        }
        if model.terms.first().map(String::as_str) != Some("const") {
            return Err("the first term must be `const`".into());
        }
        let mut terms = Vec::with_capacity(model.terms.len());
        for (name, &c) in model.terms.iter().zip(&model.coefficients) {
            let index = features
                .iter()
                .position(|f| f == name)
                .ok_or_else(|| format!("unknown term `{name}` (known: {})", features.join(", ")))?;
            if terms.iter().any(|(i, _)| *i == index) {
                return Err(format!("term `{name}` listed twice"));
            }
            if !c.is_finite() {
                return Err(format!("coefficient of `{name}` is not finite"));
            }
            terms.push((index, c));
        }
        Ok(BoundModel { terms })
    }

    /// Evaluates the model on a feature vector whose first entry is 1.
    #[inline]
    pub fn eval(&self, features: &[f64]) -> f64 {
        self.terms.iter().map(|&(i, c)| c * features[i]).sum()
    }

    /// The (feature index, coefficient) pairs, in the model's term order.
    pub fn terms(&self) -> &[(usize, f64)] {
        &self.terms
    }

    /// The coefficient of feature `index`, if the model reads it.
    pub fn coefficient(&self, index: usize) -> Option<f64> {
        self.terms
            .iter()
            .find(|(i, _)| *i == index)
            .map(|&(_, c)| c)
    }

    /// True if the model uses feature `index`.
    pub fn uses(&self, index: usize) -> bool {
        self.coefficient(index).is_some()
    }

    /// True if the model, bound to `features`, reads one whose name starts with `prefix` (to
    /// check that a recording has the signals it needs).
    pub fn uses_features_starting_with(&self, features: &[&str], prefix: &str) -> bool {
        features
            .iter()
            .enumerate()
            .any(|(i, name)| name.starts_with(prefix) && self.uses(i))
    }
}

/// Models that read one feature vector, bound to be evaluated together, `L` of them (lanes) at
/// a time: each feature any of them reads is fetched once and multiplied into `L` sums, a model
/// that does not read it holding a zero coefficient. Summed one model at a time, the gathers,
/// index checks and dependent additions cost several times the multiply-adds themselves; with
/// a fixed `L` the compiler turns a feature's `L` products into vector arithmetic.
///
/// Each model's value is the sum of its terms in the order the features first appear across
/// the models, so it equals [`BoundModel::eval`] bit for bit (up to the sign of a zero sum)
/// when each model lists its terms in that order — as when every model has the same terms in
/// the same order, which is what the shipped calibration's straightness nodes have; otherwise
/// it equals it to rounding.
#[derive(Debug, Clone)]
pub struct LaneModels<const L: usize> {
    models: Vec<BoundModel>,
    /// The features any model reads, in the order the models list them.
    read: Vec<usize>,
    /// Per block of `L` models, per feature of `read`: each model's coefficient (zero where it
    /// does not read the feature, and in the lanes past the last model).
    blocks: Vec<Vec<[f64; L]>>,
    /// True if some model does not read every feature of `read`: a non-finite feature would
    /// then turn its zero coefficient's product into NaN, so a frame with a non-finite feature
    /// is summed model by model.
    lanes_differ: bool,
}

impl<const L: usize> LaneModels<L> {
    /// Lays out bound models for evaluation together.
    pub fn new(models: Vec<BoundModel>) -> Self {
        const { assert!(L > 0, "a block has at least one lane") };
        let mut read: Vec<usize> = Vec::new();
        for model in &models {
            for &(index, _) in model.terms() {
                if !read.contains(&index) {
                    read.push(index);
                }
            }
        }
        let blocks = models
            .chunks(L)
            .map(|block| {
                read.iter()
                    .map(|&index| {
                        let mut lanes = [0.0; L];
                        for (lane, model) in lanes.iter_mut().zip(block) {
                            if let Some(c) = model.coefficient(index) {
                                *lane = c;
                            }
                        }
                        lanes
                    })
                    .collect()
            })
            .collect();
        let lanes_differ = models.iter().any(|m| m.terms().len() != read.len());
        LaneModels {
            models,
            read,
            blocks,
            lanes_differ,
        }
    }

    /// The models, in lane order.
    pub fn models(&self) -> &[BoundModel] {
        &self.models
    }

    /// False if the lanes differ (`lanes_differ`) and a feature some model reads is not
    /// finite: the frame is then summed model by model.
    #[inline]
    fn together(&self, finite: impl Fn(usize) -> bool) -> bool {
        !self.lanes_differ || self.read.iter().all(|&k| finite(k))
    }

    /// Every model on the one feature vector `features`, into `out[..models]` (the rest of
    /// `out` is left alone).
    ///
    /// # Panics
    ///
    /// If `out` is shorter than the number of models, or `features` than a model reads.
    #[inline]
    pub fn eval_shared(&self, features: &[f64], out: &mut [f64]) {
        let out = &mut out[..self.models.len()];
        if !self.together(|k| features[k].is_finite()) {
            for (slot, model) in out.iter_mut().zip(&self.models) {
                *slot = model.eval(features);
            }
            return;
        }
        for (block, slots) in self.blocks.iter().zip(out.chunks_mut(L)) {
            let mut sums = [0.0; L];
            for (&index, coefficients) in self.read.iter().zip(block) {
                let x = features[index];
                for (sum, c) in sums.iter_mut().zip(coefficients) {
                    *sum += c * x;
                }
            }
            for (slot, sum) in slots.iter_mut().zip(sums) {
                *slot = sum;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The estimators pass the room, stator and coolant lags as the last eight features of
    /// the heat vector, the heat over τ/4 just before them, and the room lags, followed by the
    /// bed's state, as the last of the straightness vector, in the order of `AMBIENT_LAG_TAUS_S`, `STATOR_LAG_TAUS_S` and
    /// `BED_LAG_TAUS_S`; the names there must be the same, or a fitted lag would bind to the
    /// wrong value.
    #[test]
    fn lag_features_sit_where_the_estimators_put_them() {
        assert_eq!(FLANGE_FEATURES[3..6], STATOR_LAG_FEATURES);
        assert_eq!(FLANGE_FEATURES[6..], AMBIENT_LAG_FEATURES);
        let heat_lags = HEAT_FEATURES.len() - 8;
        assert_eq!(
            HEAT_FEATURES[heat_lags..heat_lags + 3],
            AMBIENT_LAG_FEATURES
        );
        assert_eq!(
            HEAT_FEATURES[heat_lags + 3..heat_lags + 6],
            STATOR_LAG_FEATURES
        );
        assert_eq!(HEAT_FEATURES[heat_lags + 6..], COOLANT_LAG_FEATURES);
        assert_eq!(HEAT_FEATURES[heat_lags - 2..heat_lags], FAST_HEAT_FEATURES);
        assert_eq!(HEAT_FEATURES[3..heat_lags], PART_ACCUMULATIONS);
        assert_eq!(BED_LAG_FEATURES[5..], COOLANT_LAG_FEATURES);
        let bed = STRAIGHTNESS_FEATURES.len() - BED_LAG_FEATURES.len();
        assert_eq!(STRAIGHTNESS_FEATURES[bed..], BED_LAG_FEATURES);
        assert_eq!(STRAIGHTNESS_FEATURES[bed - 3..bed], AMBIENT_LAG_FEATURES);
        for (k, tau) in BED_LAG_TAUS_S.iter().enumerate() {
            let minutes = format!("_{}min", tau / 60.0);
            for name in [
                &BED_LAG_FEATURES[1 + k],
                &BED_LAG_FEATURES[3 + k],
                &BED_LAG_FEATURES[5 + k],
            ] {
                assert!(name.ends_with(&minutes), "{name} is not the {minutes} lag");
            }
        }
    }

    fn model(terms: &[&str], coefficients: &[f64]) -> LinearModel {
        LinearModel::with_terms(terms, coefficients)
    }

    #[test]
    fn binding_maps_names_to_features_and_evaluates() {
        let bound = BoundModel::bind(
            &model(&["const", "ambient", "stator"], &[1.0, 2.0, 3.0]),
            FLANGE_FEATURES,
        )
        .unwrap();
        assert_eq!(
            bound.eval(&[1.0, 10.0, 100.0]),
            1.0 + 3.0 * 10.0 + 2.0 * 100.0
        );
    }

    #[test]
    fn binding_refuses_malformed_models() {
        assert!(
            BoundModel::bind(&model(&["const", "rotor"], &[1.0, 2.0]), FLANGE_FEATURES)
                .unwrap_err()
                .contains("unknown term `rotor`")
        );
        assert!(BoundModel::bind(&model(&["stator"], &[1.0]), FLANGE_FEATURES).is_err());
        assert!(BoundModel::bind(&model(&["const", "stator"], &[1.0]), FLANGE_FEATURES).is_err());
        assert!(
            BoundModel::bind(
                &model(&["const", "stator", "stator"], &[1.0, 1.0, 1.0]),
                FLANGE_FEATURES
            )
            .is_err()
        );
        assert!(BoundModel::bind(&model(&["const"], &[f64::NAN]), FLANGE_FEATURES).is_err());
    }
}
