//! Depth of cut: the recommended maximum rough-cut depth, the component that limits it, a
//! margin bar per component and how the number was derived
//! ([`crate::estimators::depth_of_cut`] on the session's cuts).

use serde::Serialize;

use crate::ui::analysis::DepthOutcome;
use crate::ui::state::{HmiState, JobProgress};

/// One component's line.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ComponentView {
    /// "S motor torque".
    pub component: String,
    /// True for the component that limits the depth.
    pub limiting: bool,
    /// Load without a chip, with unit.
    pub idle_load: String,
    /// Load added per mm of depth (the regression's slope at the roughing feed), with unit.
    pub load_per_mm: String,
    /// The limit (rating × margin), with unit.
    pub limit: String,
    /// What the limit is.
    pub why: String,
    /// Depth at which the load reaches the limit.
    pub max_depth: String,
    /// Load at the recommended depth, with unit.
    pub load_at_recommended: String,
    /// Load at the recommended depth as a fraction of the rating (the bar's length; the
    /// margin line sits at the profile's margin).
    pub fraction_of_rating: f64,
    /// "26 % of the rating left".
    pub headroom: String,
    /// R² of the load regression.
    pub r2: String,
}

/// The Depth-of-cut panel.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DepthView {
    /// "3.4 mm", when there is a recommendation.
    pub recommended: Option<String>,
    /// The limiting component.
    pub limiting_component: Option<String>,
    /// Why, in words.
    pub reason: Option<String>,
    /// "f = 0.25 mm/rev at 1500 rpm on Ø80 mm".
    pub conditions: Option<String>,
    /// How the number was derived, step by step.
    pub derivation: Vec<String>,
    /// Every component, the limiting one first.
    pub components: Vec<ComponentView>,
    /// The profile's margin (fraction of each rating that may be used).
    pub margin: Option<f64>,
    /// Why there is no recommendation yet (too few cuts).
    pub not_enough_data: Option<String>,
    /// What the samples covered.
    pub data_note: Option<String>,
    /// "machine time 733.1 s (newest sample 745.0 s)".
    pub computed: Option<String>,
    /// The computation in progress.
    pub running: Option<JobProgress>,
    /// Why the last computation failed.
    pub error: Option<String>,
}

fn with_unit(value: f64, unit: &str) -> String {
    let decimals = if value.abs() >= 100.0 { 0 } else { 2 };
    format!("{value:.decimals$} {unit}")
}

/// Builds the panel.
pub fn build(state: &HmiState) -> DepthView {
    let d = &state.depth;
    let margin = state.profile.as_ref().map(|p| p.depth_of_cut.margin);
    let mut view = DepthView {
        recommended: None,
        limiting_component: None,
        reason: None,
        conditions: None,
        derivation: Vec::new(),
        components: Vec::new(),
        margin,
        not_enough_data: None,
        data_note: None,
        computed: d.computed_at_s.map(|t| {
            format!(
                "from the samples up to machine time {t:.1} s (newest now {} s)",
                super::number(state.history.newest_time_s(), 1)
            )
        }),
        running: d.running.clone(),
        error: d.error.clone(),
    };
    if state.profile.is_none() {
        view.not_enough_data = Some("no machine profile: the component ratings are unknown".into());
        return view;
    }
    match &d.outcome {
        None => {
            view.not_enough_data = Some("not computed yet".into());
        }
        Some(DepthOutcome::NotEnoughData { reason, note }) => {
            view.not_enough_data = Some(format!("Not enough cutting data yet: {reason}"));
            view.data_note = Some(note.clone());
        }
        Some(DepthOutcome::Ready {
            recommendation: r,
            note,
            workpiece_diameter_mm,
        }) => {
            let margin = margin.unwrap_or(1.0);
            view.recommended = Some(format!("{:.1} mm", r.recommended_depth_mm));
            view.limiting_component = Some(r.limiting_component.clone());
            view.reason = Some(r.reason.clone());
            view.conditions = Some(format!(
                "f = {:.3} mm/rev at {:.0} rpm on Ø{workpiece_diameter_mm} mm",
                r.feed_per_rev_mm, r.spindle_rpm
            ));
            view.data_note = Some(note.clone());
            view.derivation = vec![
                format!(
                    "1. {} cutting samples: each component's load regressed on the chip section a_p·f (cutting force F_c = k_c·a_p·f).",
                    r.cutting_samples
                ),
                format!(
                    "2. The slope × the roughing feed {:.3} mm/rev gives the load added per mm of depth.",
                    r.feed_per_rev_mm
                ),
                format!(
                    "3. Each load is extrapolated to its limit: the rating × the margin {:.0} % (bearings: static safety from the profile).",
                    100.0 * margin
                ),
                "4. The smallest of these depths wins, rounded down to 0.1 mm; below the profile's minimum depth the advice is not to rough-cut.".to_string(),
            ];
            view.components = r
                .components
                .iter()
                .enumerate()
                .map(|(i, c)| {
                    let load = c.idle_load + c.load_per_mm * r.recommended_depth_mm;
                    let rating = c.limit / margin;
                    let fraction = if rating > 0.0 {
                        load / rating
                    } else {
                        f64::NAN
                    };
                    ComponentView {
                        component: c.component.clone(),
                        limiting: i == 0,
                        idle_load: with_unit(c.idle_load, c.unit),
                        load_per_mm: with_unit(c.load_per_mm, &format!("{}/mm", c.unit)),
                        limit: with_unit(c.limit, c.unit),
                        why: c.why.clone(),
                        max_depth: if c.max_depth_mm.is_finite() {
                            format!("{:.2} mm", c.max_depth_mm)
                        } else {
                            "no limit (the load does not grow with depth)".into()
                        },
                        load_at_recommended: with_unit(load, c.unit),
                        fraction_of_rating: fraction,
                        headroom: format!("{:.0} % of the rating left", 100.0 * (1.0 - fraction)),
                        r2: format!("{:.3}", c.r2),
                    }
                })
                .collect();
        }
    }
    view
}
