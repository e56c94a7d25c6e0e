//! The Overview: one card per axis with its live servo readings and a normal / warning / fault
//! light with the reasons.

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
    reasons.sort_by_key(|r| std::cmp::Reverse(r.0));
    let severity = reasons.first().map_or(Severity::Normal, |r| r.0);
    let reasons = if reasons.is_empty() {
        vec!["all readings within limits".to_string()]
    } else {
        reasons.into_iter().map(|r| r.1).collect()
    };
    Light { severity, reasons }
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
