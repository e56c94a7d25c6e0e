//! The warm-up checklist: the operator's shift-start routine as five guided steps, each
//! judged pass / warn / fail from live values and the warm-up analysis, with the reason; then
//! the operator's sign-off, saved as a report ([`WarmupReport`]).
//!
//! The steps and their limits (all from the machine profile's `[warmup]` table and axis
//! limits):
//! 1. temperatures settled — the fastest-changing estimated (or stator) temperature over the
//!    last `settle_window_min` minutes against `settle_rate_C_per_min`;
//! 2. friction fingerprint — the warm-up moves' fingerprint against the axis's saved
//!    baseline: drift beyond `fingerprint_drift_fraction` warns, a preload diagnosis other
//!    than normal fails;
//! 3. backlash measured — the backlash test's result against `backlash_um`, its confidence,
//!    and the controller's backlash compensation;
//! 4. no abnormality — every axis's light (link, stator, estimated temperatures, loads,
//!    elongation, motor abnormality score);
//! 5. elongation compensated — the spindle elongation left after the controller's thermal
//!    offset, against `elongation_tolerance_um`.

use serde::{Deserialize, Serialize};

use super::{channel_label, number};
use crate::compensation::CompensationId;
use crate::estimators::fingerprint::{PreloadState, diagnose_preload, drift};
use crate::link::ConnectionState;
use crate::profile::{AxisKind, MachineProfile, WarmupSettings};
use crate::signal::AxisId;
use crate::ui::state::{HmiState, JobProgress, SavedReport, Severity};

/// How a step stands.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum StepStatus {
    /// Not judged yet (waiting for data or for the operator).
    Pending,
    /// Within limits.
    Pass,
    /// Needs attention; production may start.
    Warn,
    /// Out of limits.
    Fail,
}

impl StepStatus {
    /// The word shown.
    pub fn word(self) -> &'static str {
        match self {
            StepStatus::Pending => "PENDING",
            StepStatus::Pass => "PASS",
            StepStatus::Warn => "WARN",
            StepStatus::Fail => "FAIL",
        }
    }

    /// The severity colour of the status (pending shows as a warning).
    pub fn severity(self) -> Severity {
        match self {
            StepStatus::Pass => Severity::Normal,
            StepStatus::Pending | StepStatus::Warn => Severity::Warning,
            StepStatus::Fail => Severity::Fault,
        }
    }
}

/// A value shown with a step.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StepValue {
    /// What it is.
    pub label: String,
    /// Formatted number.
    pub value: String,
    /// Unit (empty for ratios given as words).
    pub unit: String,
}

fn value(label: impl Into<String>, value: String, unit: &str) -> StepValue {
    StepValue {
        label: label.into(),
        value,
        unit: unit.to_string(),
    }
}

/// Which step.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum StepId {
    /// Temperatures settled.
    TemperaturesSettled,
    /// Friction fingerprint against the baseline.
    FrictionFingerprint,
    /// Backlash measured.
    Backlash,
    /// No abnormality.
    NoAbnormality,
    /// Spindle elongation compensated.
    ElongationCompensated,
}

/// One step of the checklist.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StepView {
    /// Which step.
    pub id: StepId,
    /// "1. Temperatures settled".
    pub title: String,
    /// What the operator does for it.
    pub instruction: String,
    /// Pass, warn, fail or pending.
    pub status: StepStatus,
    /// Why, in words.
    pub reason: String,
    /// The live values it was judged on.
    pub values: Vec<StepValue>,
}

/// The Warm-up panel.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct WarmupView {
    /// The feed axis the moves are analysed on.
    pub axis: Option<String>,
    /// The steps in order.
    pub steps: Vec<StepView>,
    /// The worst step.
    pub verdict: StepStatus,
    /// "ready for production", ….
    pub verdict_text: String,
    /// Machine time the analyses take samples from, s.
    pub started_at: String,
    /// What the last analysis covered (or why it could not run).
    pub analysis_note: Option<String>,
    /// The analysis in progress.
    pub running: Option<JobProgress>,
    /// Whether the current fingerprint can be saved as the baseline.
    pub can_save_baseline: bool,
    /// Why the sign-off button is off, when it is.
    pub sign_off_blocked: Option<String>,
    /// The saved report.
    pub signed: Option<SavedReport>,
    /// A problem with the last sign-off.
    pub notice: Option<String>,
}

/// The report the operator signs off (saved as JSON and as text).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WarmupReport {
    /// The machine (profile name).
    pub machine: String,
    /// What the link reads from.
    pub source: String,
    /// The operator.
    pub signed_off_by: String,
    /// When, UTC.
    pub signed_utc: String,
    /// Machine time of the newest sample at sign-off, s.
    pub machine_time_s: Option<f64>,
    /// The worst step.
    pub verdict: StepStatus,
    /// The verdict in words.
    pub verdict_text: String,
    /// Every step with its values and reason.
    pub steps: Vec<StepView>,
}

impl WarmupReport {
    /// The report from the checklist as shown.
    pub fn new(view: &WarmupView, state: &HmiState, operator: &str, time_utc: String) -> Self {
        WarmupReport {
            machine: state
                .profile
                .as_ref()
                .map_or_else(|| "(no machine profile)".into(), |p| p.name.clone()),
            source: state.link.source.clone(),
            signed_off_by: operator.to_string(),
            signed_utc: time_utc,
            machine_time_s: state.latest.time_s(),
            verdict: view.verdict,
            verdict_text: view.verdict_text.clone(),
            steps: view.steps.clone(),
        }
    }

    /// The readable form.
    pub fn to_text(&self) -> String {
        let mut out = String::new();
        out.push_str("SHIFT-START WARM-UP CHECKLIST\n\n");
        out.push_str(&format!("Machine:        {}\n", self.machine));
        out.push_str(&format!("Source:         {}\n", self.source));
        out.push_str(&format!("Signed off by:  {}\n", self.signed_off_by));
        out.push_str(&format!("Signed (UTC):   {}\n", self.signed_utc));
        out.push_str(&format!(
            "Machine time:   {} s\n",
            number(self.machine_time_s, 1)
        ));
        out.push_str(&format!(
            "Verdict:        {} — {}\n",
            self.verdict.word(),
            self.verdict_text
        ));
        for step in &self.steps {
            out.push_str(&format!("\n{}  [{}]\n", step.title, step.status.word()));
            out.push_str(&format!("  {}\n", step.reason));
            for v in &step.values {
                let unit = if v.unit.is_empty() {
                    String::new()
                } else {
                    format!(" {}", v.unit)
                };
                out.push_str(&format!("  - {}: {}{unit}\n", v.label, v.value));
            }
        }
        out
    }
}

/// The feed axis whose moves the checklist analyses: the profile's first feed axis.
pub fn checklist_axis(profile: &MachineProfile) -> Option<(AxisId, f64)> {
    profile
        .axes
        .iter()
        .filter(|(_, a)| a.kind == AxisKind::Feed)
        .find_map(|(id, a)| a.screw.as_ref().map(|s| (*id, s.lead_mm)))
}

fn live_problem(state: &HmiState) -> Option<String> {
    match state.link.state {
        ConnectionState::Connected if !state.latest.row.is_empty() => None,
        ConnectionState::Connected => Some("no data received yet".into()),
        ConnectionState::Stale => Some("link stale: the values are not live".into()),
        ConnectionState::Disconnected => Some(format!(
            "link disconnected{}: the values are not live",
            state
                .link
                .last_error
                .as_ref()
                .map(|e| format!(" ({e})"))
                .unwrap_or_default()
        )),
    }
}

/// Least-squares slope of `points`, per minute.
fn slope_per_min(points: &[(f64, f64)]) -> Option<f64> {
    if points.len() < 3 {
        return None;
    }
    let n = points.len() as f64;
    let (mt, mv) = points
        .iter()
        .fold((0.0, 0.0), |(a, b), (t, v)| (a + t / n, b + v / n));
    let (mut sxy, mut sxx) = (0.0, 0.0);
    for (t, v) in points {
        sxy += (t - mt) * (v - mv);
        sxx += (t - mt) * (t - mt);
    }
    (sxx > 0.0).then(|| 60.0 * sxy / sxx)
}

fn temperatures_settled(state: &HmiState, settings: &WarmupSettings) -> StepView {
    let window_s = settings.settle_window_min * 60.0;
    let limits = settings.settle_rate_C_per_min;
    let mut step = StepView {
        id: StepId::TemperaturesSettled,
        title: "1. Temperatures settled".into(),
        instruction: format!(
            "Run the warm-up program until no estimated temperature changes faster than {} °C/min over {} min.",
            limits.warning, settings.settle_window_min
        ),
        status: StepStatus::Pending,
        reason: String::new(),
        values: Vec::new(),
    };
    let history = &state.history;
    let columns: Vec<usize> = history
        .channels()
        .iter()
        .enumerate()
        .filter(|(_, n)| {
            (n.starts_with(super::ESTIMATE_PREFIX) && n.ends_with("_temp_C"))
                || n.ends_with(".stator_temp_C") && !n.starts_with("ref.")
        })
        .map(|(i, _)| i)
        .collect();
    let (Some(newest), Some(oldest)) = (history.newest_time_s(), history.oldest_time_s()) else {
        step.reason = "no data received yet".into();
        return step;
    };
    if columns.is_empty() {
        step.reason = "the link carries no temperature to judge".into();
        return step;
    }
    let have = newest - oldest;
    if have < 0.95 * window_s {
        step.reason = format!(
            "collecting: {} of the {} needed to judge the rates",
            super::duration(have),
            super::duration(window_s)
        );
        return step;
    }
    let window = history.window(&columns, newest - window_s, newest, 300);
    let mut rates: Vec<(String, f64)> = columns
        .iter()
        .zip(&window.series)
        .filter_map(|(&c, series)| {
            let points: Vec<(f64, f64)> = window
                .time_s
                .iter()
                .zip(&series.mean)
                .filter(|(_, v)| v.is_finite())
                .map(|(t, v)| (*t, f64::from(*v)))
                .collect();
            slope_per_min(&points).map(|r| (history.channels()[c].clone(), r))
        })
        .collect();
    rates.sort_by(|a, b| b.1.abs().total_cmp(&a.1.abs()));
    let Some((fastest, rate)) = rates.first().cloned() else {
        step.reason = "no finite temperature in the window".into();
        return step;
    };
    step.values = rates
        .iter()
        .take(4)
        .map(|(name, r)| value(channel_label(name), format!("{r:+.3}"), "°C/min"))
        .collect();
    step.values.push(value(
        "limit (warning / fault)",
        format!("{} / {}", limits.warning, limits.fault),
        "°C/min",
    ));
    let label = channel_label(&fastest);
    let magnitude = rate.abs();
    (step.status, step.reason) = if magnitude > limits.fault {
        (
            StepStatus::Fail,
            format!(
                "{label} changes {rate:+.3} °C/min, above the fault limit {} °C/min: far from thermal equilibrium, keep warming up",
                limits.fault
            ),
        )
    } else if magnitude > limits.warning {
        (
            StepStatus::Warn,
            format!(
                "{label} still changes {rate:+.3} °C/min, above {} °C/min: not settled yet",
                limits.warning
            ),
        )
    } else {
        (
            StepStatus::Pass,
            format!(
                "every temperature changes less than {} °C/min over the last {} (fastest: {label}, {rate:+.3} °C/min)",
                limits.warning,
                super::duration(window_s)
            ),
        )
    };
    if let Some(problem) = live_problem(state) {
        step.status = StepStatus::Fail;
        step.reason = format!("{problem}; {}", step.reason);
    }
    step
}

fn friction_fingerprint(state: &HmiState, axis: Option<AxisId>) -> StepView {
    let mut step = StepView {
        id: StepId::FrictionFingerprint,
        title: "2. Friction fingerprint vs baseline".into(),
        instruction: "Run the warm-up moves (constant-speed passes in both directions), then press Analyse warm-up moves.".into(),
        status: StepStatus::Pending,
        reason: "not analysed yet".into(),
        values: Vec::new(),
    };
    let (Some(axis), Some(profile)) = (axis, state.profile.as_ref()) else {
        step.reason = "no machine profile with a feed axis: nothing to fingerprint".into();
        return step;
    };
    let Some(analysis) = &state.warmup.analysis else {
        return step;
    };
    let current = match &analysis.fingerprint {
        Ok(f) => f,
        Err(reason) => {
            step.status = StepStatus::Fail;
            step.reason = reason.clone();
            return step;
        }
    };
    step.values = vec![
        value(
            "Coulomb friction",
            format!("{:.3}", current.coulomb_Nm),
            "N·m",
        ),
        value(
            "viscous friction",
            format!("{:.3}", current.viscous_Nm_per_krpm),
            "N·m/krpm",
        ),
        value(
            "friction at 1000 rpm",
            format!("{:.3}", current.friction_at_reference_Nm()),
            "N·m",
        ),
        value("coherence R²", format!("{:.3}", current.coherence), ""),
    ];
    let Some(baseline) = state.warmup.baselines.get(&axis) else {
        step.status = StepStatus::Warn;
        step.reason = format!(
            "no baseline for {axis} yet: if the machine is known healthy, save this fingerprint as the baseline"
        );
        return step;
    };
    let Some(axis_profile) = profile.axis(axis) else {
        step.reason = format!("the profile has no axis {axis}");
        return step;
    };
    let limit = axis_profile.limits.fingerprint_drift_fraction;
    let drifts = drift(current, baseline, limit);
    for d in &drifts {
        if d.figure == "friction_at_1000rpm_Nm" {
            step.values.push(value(
                "friction change vs baseline",
                format!("{:+.1}", 100.0 * d.change),
                "%",
            ));
        }
    }
    let diagnosis = diagnose_preload(current, baseline, axis_profile);
    if let Some(d) = &diagnosis {
        step.values.push(value(
            "preload (of nominal)",
            format!("{:.0}", 100.0 * d.preload_ratio),
            "%",
        ));
    }
    let drifted: Vec<String> = drifts
        .iter()
        .filter(|d| d.warning)
        .map(|d| format!("{} {:+.0} %", d.figure, 100.0 * d.change))
        .collect();
    (step.status, step.reason) = match diagnosis.as_ref().map(|d| d.state) {
        Some(PreloadState::PreloadLoss) => (
            StepStatus::Fail,
            format!(
                "preload loss on {axis}: {}",
                diagnosis.as_ref().map_or("", |d| d.evidence.as_str())
            ),
        ),
        Some(PreloadState::FrictionRise) => (
            StepStatus::Fail,
            format!(
                "friction rise on {axis} (wear, contamination or tired lubricant): {}",
                diagnosis.as_ref().map_or("", |d| d.evidence.as_str())
            ),
        ),
        _ if !drifted.is_empty() => (
            StepStatus::Warn,
            format!(
                "drift beyond {:.0} % of the baseline: {}",
                100.0 * limit,
                drifted.join(", ")
            ),
        ),
        _ => (
            StepStatus::Pass,
            format!(
                "every figure within {:.0} % of the baseline ({}); preload normal",
                100.0 * limit,
                baseline.source
            ),
        ),
    };
    step
}

fn backlash(state: &HmiState, settings: &WarmupSettings, axis: Option<AxisId>) -> StepView {
    let mut step = StepView {
        id: StepId::Backlash,
        title: "3. Backlash measured".into(),
        instruction: "Run the backlash test program (servosight backlash-program), then press Analyse warm-up moves.".into(),
        status: StepStatus::Pending,
        reason: "not analysed yet".into(),
        values: Vec::new(),
    };
    let Some(axis) = axis else {
        step.reason = "no machine profile with a feed axis".into();
        return step;
    };
    let Some(analysis) = &state.warmup.analysis else {
        return step;
    };
    let report = match &analysis.backlash {
        Ok(r) => r,
        Err(reason) => {
            step.status = StepStatus::Fail;
            step.reason = reason.clone();
            return step;
        }
    };
    let controller = state
        .compensation
        .controller
        .as_ref()
        .and_then(|c| c.get(CompensationId::Backlash(axis)));
    step.values = vec![
        value("backlash", format!("{:.1}", report.backlash_um), "µm"),
        value("confidence", format!("{:.2}", report.confidence), ""),
        value("controller compensation", number(controller, 1), "µm"),
        value(
            "limit (warning / fault)",
            format!(
                "{} / {}",
                settings.backlash_um.warning, settings.backlash_um.fault
            ),
            "µm",
        ),
    ];
    let b = report.backlash_um;
    let limits = settings.backlash_um;
    (step.status, step.reason) = if b > limits.fault {
        (
            StepStatus::Fail,
            format!(
                "{axis} backlash {b:.1} µm is above the fault limit {} µm: the axis needs maintenance",
                limits.fault
            ),
        )
    } else if report.confidence < settings.min_backlash_confidence {
        (
            StepStatus::Warn,
            format!(
                "the measurement is unsure (confidence {:.2} < {}): repeat the backlash test",
                report.confidence, settings.min_backlash_confidence
            ),
        )
    } else if b > limits.warning {
        (
            StepStatus::Warn,
            format!(
                "{axis} backlash {b:.1} µm is above the warning limit {} µm: plan maintenance",
                limits.warning
            ),
        )
    } else if controller.is_none_or(|c| (c - b).abs() > settings.backlash_compensation_tolerance_um)
    {
        (
            StepStatus::Warn,
            format!(
                "{axis} backlash {b:.1} µm, the controller compensates {} µm: request backlash.{axis} = {b:.1} µm on the Compensation panel",
                number(controller, 1)
            ),
        )
    } else {
        (
            StepStatus::Pass,
            format!(
                "{axis} backlash {b:.1} µm, compensated by the controller within {} µm",
                settings.backlash_compensation_tolerance_um
            ),
        )
    };
    step
}

fn no_abnormality(state: &HmiState) -> StepView {
    let mut step = StepView {
        id: StepId::NoAbnormality,
        title: "4. No abnormality".into(),
        instruction: "Every axis light must be normal: stator, estimated temperatures, loads and elongation within the profile's limits, friction torque within the abnormality levels of the healthy model, link live.".into(),
        status: StepStatus::Pending,
        reason: String::new(),
        values: Vec::new(),
    };
    let axes = state.latest.axes();
    if state.latest.row.is_empty() {
        step.reason = "no data received yet".into();
        if state.link.state == ConnectionState::Disconnected {
            step.status = StepStatus::Fail;
            step.reason = live_problem(state).unwrap_or_default();
        }
        return step;
    }
    let mut worst = Severity::Normal;
    let mut reasons = Vec::new();
    for axis in axes {
        let light = super::overview::axis_condition(state, axis);
        step.values.push(value(
            format!("{axis} axis"),
            match light.severity {
                Severity::Normal => "normal",
                Severity::Warning => "warning",
                Severity::Fault => "fault",
            }
            .to_string(),
            "",
        ));
        if light.severity != Severity::Normal {
            reasons.push(format!("{axis}: {}", light.reasons.join("; ")));
        }
        worst = worst.max(light.severity);
    }
    step.status = match worst {
        Severity::Normal => StepStatus::Pass,
        Severity::Warning => StepStatus::Warn,
        Severity::Fault => StepStatus::Fail,
    };
    step.reason = if reasons.is_empty() {
        "every axis within its limits".into()
    } else {
        reasons.join(" | ")
    };
    step
}

fn elongation(state: &HmiState, settings: &WarmupSettings) -> StepView {
    let mut step = StepView {
        id: StepId::ElongationCompensated,
        title: "5. Elongation compensated".into(),
        instruction: "Measure the tool and press Tool measured, or push the proposed thermal offset on the Compensation panel.".into(),
        status: StepStatus::Pending,
        reason: String::new(),
        values: Vec::new(),
    };
    let spindle = state.profile.as_ref().and_then(|p| {
        p.axes
            .iter()
            .find(|(_, a)| a.kind == AxisKind::Spindle)
            .map(|(id, a)| (*id, a.limits.elongation_um))
    });
    let Some((axis, limit)) = spindle else {
        step.reason = "no spindle in the machine profile".into();
        return step;
    };
    let column = format!("{}{axis}.elongation_um", super::ESTIMATE_PREFIX);
    let Some(e) = state.latest.get(&column).filter(|v| v.is_finite()) else {
        step.reason = "no spindle elongation estimate yet".into();
        return step;
    };
    let offset = state
        .compensation
        .controller
        .as_ref()
        .and_then(|c| c.get(CompensationId::ThermalOffset(axis)));
    // The thermal offset is the tool-length correction for the elongation it names: what is
    // left uncompensated is the estimate minus the offset (no table read: nothing corrected).
    let residual = e - offset.unwrap_or(0.0);
    step.values = vec![
        value("estimated elongation", format!("{e:.1}"), "µm"),
        value("controller thermal offset", number(offset, 1), "µm"),
        value("uncompensated", format!("{residual:.1}"), "µm"),
        value(
            "counted from machine time",
            number(state.elongation_origin(axis).map(|o| o.time_s()), 1),
            "s",
        ),
    ];
    let tolerance = settings.elongation_tolerance_um;
    let counted_from = super::compensation::elongation_counted_from(state, axis);
    (step.status, step.reason) = if limit.is_some_and(|l| residual.abs() >= l.fault) {
        (
            StepStatus::Fail,
            format!(
                "{residual:.1} µm of elongation uncompensated, at or above the fault limit {} µm",
                limit.map_or(f64::NAN, |l| l.fault)
            ),
        )
    } else if let Err(why) = counted_from {
        (
            StepStatus::Warn,
            format!("the estimate is not the growth since the tool measurement: {why}"),
        )
    } else if residual.abs() > tolerance {
        (
            StepStatus::Warn,
            format!(
                "{residual:.1} µm of elongation uncompensated (tolerance {tolerance} µm): measure the tool or push thermal_offset.{axis} = {e:.1} µm"
            ),
        )
    } else {
        (
            StepStatus::Pass,
            format!("uncompensated elongation {residual:.1} µm, within {tolerance} µm"),
        )
    };
    if let Some(problem) = live_problem(state) {
        step.status = StepStatus::Fail;
        step.reason = format!("{problem}; {}", step.reason);
    }
    step
}

/// Builds the checklist.
pub fn build(state: &HmiState) -> WarmupView {
    let default_settings = WarmupSettings::default();
    let settings = state
        .profile
        .as_ref()
        .map_or(&default_settings, |p| &p.warmup);
    let axis = state
        .profile
        .as_ref()
        .and_then(checklist_axis)
        .map(|(a, _)| a);
    let steps = vec![
        temperatures_settled(state, settings),
        friction_fingerprint(state, axis),
        backlash(state, settings, axis),
        no_abnormality(state),
        elongation(state, settings),
    ];
    // A failed step decides the verdict; otherwise an open step leaves it pending.
    let worst = steps
        .iter()
        .map(|s| s.status)
        .max()
        .unwrap_or(StepStatus::Pending);
    let verdict =
        if worst != StepStatus::Fail && steps.iter().any(|s| s.status == StepStatus::Pending) {
            StepStatus::Pending
        } else {
            worst
        };
    let pending: Vec<&str> = steps
        .iter()
        .filter(|s| s.status == StepStatus::Pending)
        .map(|s| s.title.as_str())
        .collect();
    let verdict_text = match verdict {
        StepStatus::Pending => format!("not complete: {}", pending.join(", ")),
        StepStatus::Pass => "ready for production".into(),
        StepStatus::Warn => "ready for production, with the warnings noted".into(),
        StepStatus::Fail => "NOT ready for production".into(),
    };
    let w = &state.warmup;
    let sign_off_blocked = if !pending.is_empty() {
        Some(format!(
            "complete every step first ({})",
            pending.join(", ")
        ))
    } else if w.running.is_some() {
        Some("wait for the analysis to finish".into())
    } else if w.saving {
        Some("saving the report".into())
    } else {
        None
    };
    let can_save_baseline = w
        .analysis
        .as_ref()
        .is_some_and(|a| a.fingerprint.is_ok() && Some(a.axis) == axis);
    WarmupView {
        axis: axis.map(|a| a.to_string()),
        steps,
        verdict,
        verdict_text,
        started_at: match w.started_at_s {
            Some(t) => format!("{t:.1} s"),
            None => "the oldest sample in memory".into(),
        },
        analysis_note: match (&w.analysis_error, &w.analysis) {
            (Some(error), _) => Some(error.clone()),
            (None, Some(a)) => Some(a.note.clone()),
            (None, None) => None,
        },
        running: w.running.clone(),
        can_save_baseline,
        sign_off_blocked,
        signed: w.signed.clone(),
        notice: w.notice.clone(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slope_is_per_minute() {
        let points: Vec<(f64, f64)> = (0..10)
            .map(|i| (f64::from(i) * 6.0, 0.1 * f64::from(i)))
            .collect();
        let s = slope_per_min(&points).unwrap();
        assert!((s - 1.0).abs() < 1e-12, "{s}");
        assert_eq!(slope_per_min(&points[..2]), None);
    }

    #[test]
    fn the_text_report_names_every_step_and_the_verdict() {
        let report = WarmupReport {
            machine: "m".into(),
            source: "twin".into(),
            signed_off_by: "otto".into(),
            signed_utc: "2026-03-02T06:00:00.000Z".into(),
            machine_time_s: Some(12.0),
            verdict: StepStatus::Warn,
            verdict_text: "ready, with warnings".into(),
            steps: vec![StepView {
                id: StepId::Backlash,
                title: "3. Backlash measured".into(),
                instruction: String::new(),
                status: StepStatus::Warn,
                reason: "unsure".into(),
                values: vec![value("backlash", "12.0".into(), "µm")],
            }],
        };
        let text = report.to_text();
        assert!(text.contains("Signed off by:  otto"), "{text}");
        assert!(text.contains("3. Backlash measured  [WARN]"), "{text}");
        assert!(text.contains("- backlash: 12.0 µm"), "{text}");
    }
}
