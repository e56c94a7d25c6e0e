//! The Overview: one card per axis with its live servo readings and a normal / warning / fault
//! light with the reasons.
#![allow(non_snake_case)] // unit suffixes are part of the names

use serde::Serialize;

use super::{channel_label, number, quantity_label};
use crate::link::ConnectionState;
use crate::signal::channel::{AMBIENT, COOLANT, CUT_DEPTH};
use crate::signal::{AxisId, Quantity};
use crate::ui::state::{HmiState, Severity};

/// One reading on a card.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Reading {
    /// "stator temperature".
    pub label: String,
    /// "41.3".
    pub value: String,
    /// "°C".
    pub unit: String,
    /// How the value compares with its limits (normal when it has none).
    pub severity: Severity,
}

/// The light of a card and why it shows that colour.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Light {
    /// The worst of the reasons.
    pub severity: Severity,
    /// Every reason, worst first.
    pub reasons: Vec<String>,
}

/// One axis.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AxisCard {
    /// "X".
    pub axis: String,
    /// "X — linear feed axis".
    pub title: String,
    /// The light.
    pub light: Light,
    /// The live readings.
    pub readings: Vec<Reading>,
    /// True when the readings are the last known ones, not live (link stale or down).
    pub readings_are_old: bool,
}

/// The Overview.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct OverviewView {
    /// The machine's overall light (the worst card).
    pub machine: Light,
    /// One card per axis the link carries.
    pub cards: Vec<AxisCard>,
    /// Machine-level readings (room temperature, coolant, depth of cut).
    pub machine_readings: Vec<Reading>,
}

/// Judges one axis: link state, then its readings against the thresholds. The Overview's
/// light and the condition events both come from here.
pub fn axis_condition(state: &HmiState, axis: AxisId) -> Light {
    let mut reasons: Vec<(Severity, String)> = Vec::new();
    match state.link.state {
        ConnectionState::Connected => {}
        ConnectionState::Stale => reasons.push((
            Severity::Warning,
            format!(
                "link stale: last sample {} s ago, values are not live",
                number(state.link.last_frame_age_s, 1)
            ),
        )),
        ConnectionState::Disconnected => reasons.push((
            Severity::Fault,
            format!(
                "link disconnected{}",
                state
                    .link
                    .last_error
                    .as_ref()
                    .map(|e| format!(": {e}"))
                    .unwrap_or_default()
            ),
        )),
    }
    if state.latest.row.is_empty() {
        reasons.push((Severity::Warning, "no data received yet".into()));
    }
    let limits = state.thresholds.stator_temp_c;
    if let Some(stator) = state.latest.servo(axis, Quantity::StatorTemp) {
        if stator >= limits.fault {
            reasons.push((
                Severity::Fault,
                format!(
                    "stator {stator:.1} °C at or above the fault limit {:.0} °C",
                    limits.fault
                ),
            ));
        } else if stator >= limits.warning {
            reasons.push((
                Severity::Warning,
                format!(
                    "stator {stator:.1} °C at or above the warning limit {:.0} °C",
                    limits.warning
                ),
            ));
        }
    }
    for (reading, severity, limit) in estimate_readings(state, axis) {
        if let Some(limit) = limit.filter(|_| severity != Severity::Normal) {
            let word = if severity == Severity::Fault {
                "fault"
            } else {
                "warning"
            };
            reasons.push((
                severity,
                format!(
                    "{} {} {} at or above the {word} limit {limit:.0} {}",
                    reading.label, reading.value, reading.unit, reading.unit
                ),
            ));
        }
    }
    for (reading, reason) in load_readings(state, axis) {
        if let Some(reason) = reason {
            reasons.push((reading.severity, reason));
        }
    }
    if let Some((reading, Some(reason))) = preload_reading(state, axis) {
        reasons.push((reading.severity, reason));
    }
    if let Some((reading, Some(reason))) = abnormality_reading(state, axis) {
        reasons.push((reading.severity, reason));
    }
    reasons.sort_by_key(|r| std::cmp::Reverse(r.0));
    let severity = reasons.first().map_or(Severity::Normal, |r| r.0);
    let reasons = if reasons.is_empty() {
        vec!["all readings within limits".to_string()]
    } else {
        reasons.into_iter().map(|r| r.1).collect()
    };
    Light { severity, reasons }
}

/// The estimates of one axis worth a card line (temperatures, elongation, straightness zones),
/// each judged against the profile's limits: the reading, its severity and the limit crossed.
fn estimate_readings(state: &HmiState, axis: AxisId) -> Vec<(Reading, Severity, Option<f64>)> {
    let prefix = format!("{}{axis}.", super::ESTIMATE_PREFIX);
    let limits = state.estimate_limits.get(&axis);
    state
        .latest
        .names
        .iter()
        .filter_map(|name| {
            let quantity = name.strip_prefix(&prefix)?;
            let shown = quantity.ends_with("_temp_C")
                || quantity == "elongation_um"
                || quantity.ends_with("_zone_um");
            if !shown {
                return None;
            }
            let value = state.latest.get(name);
            let threshold = limits.and_then(|l| match quantity {
                "motor_flange_temp_C" => Some(l.motor_temp_C),
                "front_bearing_temp_C" | "back_bearing_temp_C" => Some(l.bearing_temp_C),
                "nut_temp_C" => Some(l.nut_temp_C),
                "elongation_um" => l.elongation_um,
                _ => None,
            });
            let magnitude = value.map(f64::abs);
            let (severity, limit) = match (threshold, magnitude) {
                (Some(t), Some(v)) if v >= t.fault => (Severity::Fault, Some(t.fault)),
                (Some(t), Some(v)) if v >= t.warning => (Severity::Warning, Some(t.warning)),
                _ => (Severity::Normal, None),
            };
            let label = super::channel_label(name);
            Some((
                Reading {
                    label: label.trim_start_matches(&format!("{axis} ")).to_string(),
                    value: number(value, 1),
                    unit: super::unit(name),
                    severity,
                },
                severity,
                limit,
            ))
        })
        .collect()
}

/// The axial load on a feed axis's front (fixed) bearing and nut as a share of their ratings,
/// from the estimated nut torque (the torque split) and the profile: the readings, each with a
/// reason for the light when it is at or above a limit. The warning is the profile's
/// depth-of-cut margin of the limit (what the depth recommendation allows itself), the fault the
/// limit: the bearing's static safety C₀ / s₀ and the load at which the nut loses its preload.
/// Empty without a profile, a nut or a live split estimate: no number is better than a made-up
/// one.
fn load_readings(state: &HmiState, axis: AxisId) -> Vec<(Reading, Option<String>)> {
    use crate::estimators::depth_of_cut::{axial_load_from_nut_torque_N, axial_load_limits};
    let Some(profile) = state.profile.as_ref() else {
        return Vec::new();
    };
    let Some(axis_profile) = profile.axes.get(&axis) else {
        return Vec::new();
    };
    let settings = &profile.depth_of_cut;
    let nut_torque = state
        .latest
        .get(&format!("{}{axis}.nut_torque_Nm", super::ESTIMATE_PREFIX))
        .filter(|v| v.is_finite());
    let (Some(load_N), Some(limits)) = (
        nut_torque.and_then(|t| axial_load_from_nut_torque_N(axis_profile, t)),
        axial_load_limits(axis_profile, settings.bearing_static_safety),
    ) else {
        return Vec::new();
    };
    let judge = |label: &str, limit_N: f64, limit_name: String| {
        let (severity, share) = if load_N >= limit_N {
            (Severity::Fault, String::new())
        } else if load_N >= settings.margin * limit_N {
            (
                Severity::Warning,
                format!("{:.0} % of ", 100.0 * settings.margin),
            )
        } else {
            return (Severity::Normal, None);
        };
        let reason = format!(
            "{label} (estimated) {load_N:.0} N axial at or above {share}{limit_name} {limit_N:.0} N"
        );
        (severity, Some(reason))
    };
    let bearing_C = axis_profile.front_bearing.dynamic_load_rating_N;
    let (bearing_severity, bearing_reason) = judge(
        "front bearing load",
        limits.fixed_bearing_static_N,
        format!(
            "the bearing's static-safety limit C₀/{}",
            settings.bearing_static_safety
        ),
    );
    let (nut_severity, nut_reason) = judge(
        "nut load",
        limits.nut_preload_loss_N,
        "the nut's preload-loss limit".into(),
    );
    vec![
        (
            Reading {
                label: "front bearing load (estimated)".into(),
                value: number(Some(100.0 * load_N / bearing_C), 1),
                unit: format!("% of rating C ({load_N:.0} N axial)"),
                severity: bearing_severity,
            },
            bearing_reason,
        ),
        (
            Reading {
                label: "nut load (estimated)".into(),
                value: number(Some(100.0 * load_N / limits.nut_preload_loss_N), 1),
                // The axial newtons are on the bearing's line: the same load, said once.
                unit: "% of preload-loss limit".into(),
                severity: nut_severity,
            },
            nut_reason,
        ),
    ]
}

/// The preload state of a feed axis from the shift's warm-up analysis (its friction fingerprint
/// against the stored healthy baseline): the reading, and a reason for the light when the
/// diagnosis is not normal. `None` for axes without a screw in the profile.
fn preload_reading(state: &HmiState, axis: AxisId) -> Option<(Reading, Option<String>)> {
    use crate::estimators::fingerprint::{PreloadState, diagnose_preload};
    let axis_profile = state.profile.as_ref()?.axes.get(&axis)?;
    axis_profile.nut.as_ref()?;
    let reading = |value: String, unit: &str, severity| Reading {
        label: "preload".into(),
        value,
        unit: unit.into(),
        severity,
    };
    let analysed = state
        .warmup
        .analysis
        .as_ref()
        .filter(|a| a.axis == axis)
        .and_then(|a| a.fingerprint.as_ref().ok());
    let Some(current) = analysed else {
        return Some((
            reading(
                "not measured (warm-up analysis)".into(),
                "",
                Severity::Normal,
            ),
            None,
        ));
    };
    let Some(baseline) = state.warmup.baselines.get(&axis) else {
        return Some((
            reading(
                "no healthy baseline to compare".into(),
                "",
                Severity::Normal,
            ),
            None,
        ));
    };
    let diagnosis = diagnose_preload(current, baseline, axis_profile)?;
    let percent = format!("{:.0} % of nominal", 100.0 * diagnosis.preload_ratio);
    Some(match diagnosis.state {
        PreloadState::Normal => (reading(percent, "", Severity::Normal), None),
        PreloadState::PreloadLoss => (
            reading(format!("{percent}, preload loss"), "", Severity::Warning),
            Some(format!("preload loss on {axis}: {}", diagnosis.evidence)),
        ),
        PreloadState::FrictionRise => (
            reading(format!("{percent}, friction rise"), "", Severity::Warning),
            Some(format!(
                "friction rise on {axis} (wear, contamination or tired lubricant): {}",
                diagnosis.evidence
            )),
        ),
    })
}

/// The motor abnormality score of an axis (excess friction torque against its healthy ideal
/// torque, `est.<axis>.abnormality_pct`), judged against the profile's levels: the reading and,
/// at or beyond the warning level, the reason for the light. `None` when the pipeline has no
/// abnormality model for the axis.
fn abnormality_reading(state: &HmiState, axis: AxisId) -> Option<(Reading, Option<String>)> {
    use crate::estimators::abnormality::{AbnormalityState, classify, likely_cause};
    let column = format!("{}{axis}.abnormality_pct", super::ESTIMATE_PREFIX);
    if !state.latest.names.contains(&column) {
        return None;
    }
    let levels = state.estimate_limits.get(&axis)?.abnormality;
    let pct = state.latest.get(&column).unwrap_or(f64::NAN);
    let abnormality = classify(pct, levels);
    let severity = match abnormality {
        AbnormalityState::NotYetKnown | AbnormalityState::Normal => Severity::Normal,
        AbnormalityState::Warning => Severity::Warning,
        AbnormalityState::Fault => Severity::Fault,
    };
    let reading = Reading {
        label: "abnormality (friction vs healthy)".into(),
        value: if pct.is_finite() {
            format!("{pct:+.1}")
        } else {
            "not yet known (needs steady running)".into()
        },
        unit: if pct.is_finite() { "%" } else { "" }.into(),
        severity,
    };
    let reason = (severity != Severity::Normal).then(|| {
        let level = if severity == Severity::Fault {
            format!("fault level ±{:.0} %", levels.fault)
        } else {
            format!("warning level ±{:.0} %", levels.warning)
        };
        format!(
            "motor abnormality on {axis}: friction torque {pct:+.1} % against the healthy model \
             (beyond the {level}): {}",
            likely_cause(pct)
        )
    });
    Some((reading, reason))
}

fn stator_severity(state: &HmiState, value: Option<f64>) -> Severity {
    let limits = state.thresholds.stator_temp_c;
    match value {
        Some(v) if v >= limits.fault => Severity::Fault,
        Some(v) if v >= limits.warning => Severity::Warning,
        _ => Severity::Normal,
    }
}

/// Builds the Overview.
pub fn build(state: &HmiState) -> OverviewView {
    let old = state.link.state != ConnectionState::Connected;
    let cards: Vec<AxisCard> = state
        .latest
        .axes()
        .into_iter()
        .map(|axis| {
            let kind = if axis == AxisId::S {
                "spindle"
            } else if axis.is_linear() {
                "linear feed axis"
            } else {
                "rotary axis"
            };
            let readings = [
                (Quantity::StatorTemp, 1),
                (Quantity::Load, 1),
                (Quantity::Torque, 2),
                (Quantity::Current, 2),
                (Quantity::Speed, 0),
                (Quantity::Position, 3),
            ]
            .into_iter()
            .filter(|(q, _)| {
                state
                    .latest
                    .names
                    .contains(&crate::signal::axis_column(axis, *q))
            })
            .map(|(quantity, decimals)| {
                let name = crate::signal::axis_column(axis, quantity);
                let value = state.latest.servo(axis, quantity);
                Reading {
                    label: quantity_label(quantity).to_string(),
                    value: number(value, decimals),
                    unit: super::unit(&name),
                    severity: if quantity == Quantity::StatorTemp {
                        stator_severity(state, value)
                    } else {
                        Severity::Normal
                    },
                }
            })
            .chain(estimate_readings(state, axis).into_iter().map(|r| r.0))
            .chain(load_readings(state, axis).into_iter().map(|r| r.0))
            .chain(preload_reading(state, axis).map(|r| r.0))
            .chain(abnormality_reading(state, axis).map(|r| r.0))
            .collect();
            AxisCard {
                axis: axis.to_string(),
                title: format!("{axis} — {kind}"),
                light: axis_condition(state, axis),
                readings,
                readings_are_old: old,
            }
        })
        .collect();
    let machine_readings = [(AMBIENT, 1), (COOLANT, 0), (CUT_DEPTH, 2)]
        .into_iter()
        .filter(|(name, _)| state.latest.names.iter().any(|n| n == name))
        .map(|(name, decimals)| {
            let value = state.latest.get(name);
            Reading {
                label: channel_label(name),
                value: if name == COOLANT {
                    match value {
                        Some(v) if v >= 0.5 => "on".into(),
                        Some(_) => "off".into(),
                        None => "–".into(),
                    }
                } else {
                    number(value, decimals)
                },
                unit: if name == COOLANT {
                    String::new()
                } else {
                    super::unit(name)
                },
                severity: Severity::Normal,
            }
        })
        .collect();
    let machine = cards
        .iter()
        .map(|c| &c.light)
        .max_by_key(|l| l.severity)
        .cloned()
        .unwrap_or_else(|| axis_condition(state, AxisId::X));
    OverviewView {
        machine,
        cards,
        machine_readings,
    }
}
