//! View models: for each panel, a plain serialisable struct computed from the [`HmiState`]
//! (and the panel's settings) before anything is drawn. The `*_ui` functions in
//! [`super::panels`] only draw these; tests snapshot them as YAML.
//!
//! Numbers a person reads are formatted here, with their units, so that what is tested is what
//! is shown (and tiny p-values do not turn into hundreds of digits in a snapshot).
//!
//! [`HmiState`]: super::state::HmiState

pub mod compensation;
pub mod depth;
pub mod discrepancy;
pub mod events;
pub mod model_lab;
pub mod overview;
pub mod source;
pub mod status;
pub mod trends;
pub mod warmup;

use crate::signal::channel::{CUT_DEPTH, Channel, Quantity};

/// A number with `decimals` decimals; `–` for a value that is not available.
pub fn number(value: Option<f64>, decimals: usize) -> String {
    match value {
        Some(v) if v.is_finite() => format!("{v:.decimals$}"),
        _ => "–".to_string(),
    }
}

/// A probability as a person reads it: four decimals, or scientific notation when tiny.
pub fn probability(p: f64) -> String {
    if !p.is_finite() {
        "–".into()
    } else if p == 0.0 {
        "< 1e-308".into()
    } else if p < 1e-4 {
        format!("{p:.2e}")
    } else {
        format!("{p:.4}")
    }
}

/// A statistic with four significant figures (scientific when very large or small).
pub fn statistic(value: f64) -> String {
    if !value.is_finite() {
        "–".into()
    } else if value != 0.0 && (value.abs() >= 1e6 || value.abs() < 1e-3) {
        format!("{value:.3e}")
    } else {
        format!("{value:.4}")
    }
}

/// Seconds as "12.3 s", "4 min 05 s", "2 h 05 min".
pub fn duration(seconds: f64) -> String {
    if !seconds.is_finite() || seconds < 0.0 {
        "–".into()
    } else if seconds >= 3600.0 {
        let minutes = (seconds / 60.0).round() as u64;
        format!("{} h {:02} min", minutes / 60, minutes % 60)
    } else if seconds >= 60.0 {
        let s = seconds.round() as u64;
        format!("{} min {:02} s", s / 60, s % 60)
    } else {
        format!("{seconds:.1} s")
    }
}

/// The unit of a column, from its name (`°C`, `rpm`, …; empty when the name has none).
pub fn unit(name: &str) -> String {
    Channel::unit_of(name).unwrap_or("").to_string()
}

/// What a servo quantity is called on screen.
pub fn quantity_label(quantity: Quantity) -> &'static str {
    match quantity {
        Quantity::Position => "position",
        Quantity::Command => "command",
        Quantity::Speed => "speed",
        Quantity::Torque => "torque",
        Quantity::Current => "current",
        Quantity::Load => "load",
        Quantity::StatorTemp => "stator temperature",
    }
}

/// Prefix of the estimator output columns (`est.X.nut_temp_C`).
pub const ESTIMATE_PREFIX: &str = "est.";

/// A column's name as a person reads it: `X.stator_temp_C` → "X stator temperature",
/// `est.X.nut_temp_C` → "X nut temperature (estimated)".
pub fn channel_label(name: &str) -> String {
    if let Some(rest) = name.strip_prefix(ESTIMATE_PREFIX) {
        return format!("{} (estimated)", estimate_label(rest));
    }
    match Channel::parse(name) {
        Channel::Time => "time".into(),
        Channel::Servo { axis, quantity } => format!("{axis} {}", quantity_label(quantity)),
        Channel::Ambient => "ambient temperature".into(),
        Channel::Coolant => "coolant on".into(),
        Channel::Reference {
            axis,
            quantity,
            node,
        } => {
            let base = quantity
                .rsplit_once('_')
                .map_or(quantity.as_str(), |(q, _)| q)
                .replace('_', " ");
            match node {
                Some(k) => format!("{axis} {base} node {k} (reference)"),
                None => format!("{axis} {base} (reference)"),
            }
        }
        Channel::Unknown if name == CUT_DEPTH => "depth of cut".into(),
        Channel::Unknown if name.starts_with(ESTIMATE_PREFIX) => name.to_string(),
        Channel::Unknown => name.to_string(),
    }
}

/// `X.nut_temp_C` → "X nut temperature", `X.straightness_h_um#3` → "X straightness h node 3".
fn estimate_label(rest: &str) -> String {
    let (axis, quantity) = rest.split_once('.').unwrap_or(("", rest));
    let (quantity, node) = match quantity.split_once('#') {
        Some((q, k)) => (q, Some(k)),
        None => (quantity, None),
    };
    let base = quantity
        .rsplit_once('_')
        .map_or(quantity, |(q, _)| q)
        .replace("_temp", " temperature")
        .replace('_', " ");
    match node {
        Some(k) => format!("{axis} {base} node {k}"),
        None => format!("{axis} {base}"),
    }
}
