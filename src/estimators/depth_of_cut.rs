//! The maximum rough-cut depth (paper Sect. 2.4, "cutting depth parameter assistance").
//!
//! During cuts the loads on the spindle motor, the spindle bearings, the feed-axis motor, its
//! nut and its fixed bearing grow with the chip cross-section a_p·f (cutting force
//! F_c = k_c·a_p·f). Each load is regressed on a_p·f over the cutting samples of a recording,
//! extrapolated at the roughing feed to the component's limit (rating × the profile's margin),
//! and the smallest depth wins — named, with the reason.
#![allow(non_snake_case)] // unit suffixes are part of the names

use super::fingerprint::nut_preload_drag_Nm;
use crate::fit::{Design, ols};
use crate::profile::{AxisKind, AxisProfile, MachineProfile, ScrewProfile};
use crate::signal::channel::CUT_DEPTH;
use crate::signal::{AxisId, Quantity, Recording, axis_column};

/// One component's limit.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ComponentLimit {
    /// Which component (`spindle motor torque`, `X nut preload`, …).
    pub component: String,
    /// The unit of `idle_load`, `load_per_mm` and `limit`.
    pub unit: &'static str,
    /// Load with no chip (the regression's intercept).
    pub idle_load: f64,
    /// Load added per mm of depth at the roughing feed.
    pub load_per_mm: f64,
    /// The limit: rating × margin.
    pub limit: f64,
    /// The depth at which the load reaches the limit, mm (∞ when the load does not grow).
    pub max_depth_mm: f64,
    /// R² of the load regression.
    pub r2: f64,
    /// What the limit is.
    pub why: String,
}

/// The recommendation.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct DepthOfCutRecommendation {
    /// Recommended maximum rough-cut depth, mm (0 when even the minimum is not safe).
    pub recommended_depth_mm: f64,
    /// The component that limits it.
    pub limiting_component: String,
    /// Why, in words.
    pub reason: String,
    /// Feed per revolution the recommendation is for, mm.
    pub feed_per_rev_mm: f64,
    /// Spindle speed the recommendation is for, rpm.
    pub spindle_rpm: f64,
    /// Cutting samples used.
    pub cutting_samples: usize,
    /// Every component, smallest depth first.
    pub components: Vec<ComponentLimit>,
}

/// Why no recommendation could be made.
#[derive(Debug, thiserror::Error)]
pub enum DepthOfCutError {
    /// A needed column is missing.
    #[error(transparent)]
    Recording(#[from] crate::signal::RecordingError),
    /// Not enough cuts at different depths.
    #[error(
        "{0}: too few cutting samples at different depths ({1}); record a few roughing and finishing cuts"
    )]
    TooFewCuts(String, usize),
    /// The profile lacks a spindle.
    #[error("the profile has no spindle axis")]
    NoSpindle,
    /// A workpiece diameter nobody turns: the cutting force (torque over radius) would be
    /// nonsense.
    #[error("the workpiece diameter must be between 1 and 10000 mm, not {0}")]
    ImplausibleDiameter(f64),
    /// A regression failed.
    #[error("{0}")]
    Fit(#[from] crate::fit::FitError),
}

/// Axial load through a ball screw per N·m of thrust torque at the nut, N/(N·m): the thrust
/// torque is τ = F·l / (2π·η) while the motor drives the load (a cutting force resists the
/// feed, so during cuts it does).
pub fn screw_thrust_N_per_Nm(screw: &ScrewProfile) -> f64 {
    2.0 * std::f64::consts::PI * screw.efficiency / (screw.lead_mm / 1000.0)
}

/// The axial-load limits of a feed axis, before the profile's margin.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct AxialLoadLimits {
    /// The nut loses its preload above this axial load: preload_loss_factor × preload, N.
    pub nut_preload_loss_N: f64,
    /// The fixed (front) bearing's static-safety limit C₀ / s₀, N.
    pub fixed_bearing_static_N: f64,
}

/// The axial-load limits of a feed axis with the bearing static safety factor `static_safety`
/// (the profile's `depth_of_cut.bearing_static_safety`); `None` for an axis without a nut.
pub fn axial_load_limits(axis: &AxisProfile, static_safety: f64) -> Option<AxialLoadLimits> {
    let nut = axis.nut.as_ref()?;
    Some(AxialLoadLimits {
        nut_preload_loss_N: nut.preload_loss_factor * nut.preload_N,
        fixed_bearing_static_N: axis.front_bearing.static_load_rating_N / static_safety,
    })
}

/// The axial load on a feed axis's nut, N, from the nut's share of the motor torque (the
/// estimated torque split, Eq. 8): what is left after the nominal preload drag is thrust
/// torque. The fixed (front) bearing reacts the same axial load — its own split torque is
/// friction, not load, and too small for the split to track (docs/accuracy.md). `None` for an
/// axis without screw or nut.
pub fn axial_load_from_nut_torque_N(axis: &AxisProfile, nut_torque_Nm: f64) -> Option<f64> {
    let screw = axis.screw.as_ref()?;
    let nut = axis.nut.as_ref()?;
    let thrust_Nm = (nut_torque_Nm.abs() - nut_preload_drag_Nm(screw, nut)).max(0.0);
    Some(thrust_Nm * screw_thrust_N_per_Nm(screw))
}

/// Recommends the maximum rough-cut depth from the cuts in `recording`.
pub fn recommend_depth_of_cut(
    profile: &MachineProfile,
    recording: &Recording,
    workpiece_diameter_mm: f64,
) -> Result<DepthOfCutRecommendation, DepthOfCutError> {
    // From a watch screw to the largest lathes' swing.
    if !(workpiece_diameter_mm.is_finite() && (1.0..=10_000.0).contains(&workpiece_diameter_mm)) {
        return Err(DepthOfCutError::ImplausibleDiameter(workpiece_diameter_mm));
    }
    let (spindle_axis, spindle) = profile
        .axes
        .iter()
        .find(|(_, a)| a.kind == AxisKind::Spindle)
        .ok_or(DepthOfCutError::NoSpindle)?;
    let depth = recording.column_for(CUT_DEPTH, "the depth-of-cut recommendation")?;
    let s_speed = recording.column_for(
        &axis_column(*spindle_axis, Quantity::Speed),
        "the depth-of-cut recommendation",
    )?;
    let s_torque = recording.column_for(
        &axis_column(*spindle_axis, Quantity::Torque),
        "the depth-of-cut recommendation",
    )?;
    let feed_axes: Vec<(AxisId, &crate::profile::AxisProfile)> = profile
        .axes
        .iter()
        .filter(|(_, a)| a.kind == AxisKind::Feed)
        .map(|(id, a)| (*id, a))
        .collect();
    // The feed axis that feeds during the cut: the one moving while cutting.
    let mut feeding: Option<(AxisId, &[f64], &[f64])> = None;
    for (id, _) in &feed_axes {
        let speed = recording.try_column(&axis_column(*id, Quantity::Speed));
        let torque = recording.try_column(&axis_column(*id, Quantity::Torque));
        if let (Some(speed), Some(torque)) = (speed, torque) {
            let moving = (0..depth.len())
                .filter(|&i| depth[i] > 0.0 && speed[i].abs() > 0.1)
                .count();
            if moving
                > feeding.map_or(0, |(_, s, _)| {
                    (0..depth.len())
                        .filter(|&i| depth[i] > 0.0 && s[i].abs() > 0.1)
                        .count()
                })
            {
                feeding = Some((*id, speed, torque));
            }
        }
    }
    let lead = |id: AxisId| {
        profile
            .axis(id)
            .and_then(|a| a.screw.as_ref())
            .map(|s| s.lead_mm)
    };
    // Cutting samples with a measurable feed per revolution.
    let mut rows = Vec::new();
    for i in 0..depth.len() {
        if depth[i] <= 0.0 || s_speed[i].abs() < 10.0 {
            continue;
        }
        let feed_per_rev = match feeding {
            Some((id, speed, _)) => lead(id).map(|l| speed[i].abs() * l / s_speed[i].abs()),
            None => None,
        };
        if let Some(f) = feed_per_rev
            && f > 0.0
        {
            rows.push((i, depth[i], f));
        }
    }
    let distinct_depths = {
        let mut d: Vec<i64> = rows
            .iter()
            .map(|(_, d, _)| (d * 10.0).round() as i64)
            .collect();
        d.sort_unstable();
        d.dedup();
        d.len()
    };
    if rows.len() < 20 || distinct_depths < 3 {
        return Err(DepthOfCutError::TooFewCuts(
            recording.source().to_string(),
            rows.len(),
        ));
    }
    // The roughing condition: median feed and speed of the deeper half of the cuts.
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let depth_median = median(rows.iter().map(|r| r.1).collect());
    let rough: Vec<&(usize, f64, f64)> = rows.iter().filter(|r| r.1 >= depth_median).collect();
    let feed_r = median(rough.iter().map(|r| r.2).collect());
    let rpm_r = median(rough.iter().map(|r| s_speed[r.0].abs()).collect());
    let omega_r = rpm_r * std::f64::consts::PI / 30.0;
    let section: Vec<f64> = rows.iter().map(|r| r.1 * r.2).collect();
    let fit_load = |name: &str, load: Vec<f64>| -> Result<(f64, f64, f64), DepthOfCutError> {
        let design =
            Design::from_columns(name, load, vec![("chip_section".into(), section.clone())])?;
        let fit = ols(&design)?;
        Ok((
            fit.coefficients[0].estimate,
            fit.coefficients[1].estimate,
            fit.r2,
        ))
    };
    let margin = profile.depth_of_cut.margin;
    let s0 = profile.depth_of_cut.bearing_static_safety;
    let mut components = Vec::new();
    let mut push = |component: String,
                    unit: &'static str,
                    idle: f64,
                    slope_per_section: f64,
                    limit: f64,
                    r2: f64,
                    why: String| {
        let per_mm = slope_per_section * feed_r;
        let max_depth_mm = if per_mm > 1e-12 {
            ((limit - idle) / per_mm).max(0.0)
        } else {
            f64::INFINITY
        };
        components.push(ComponentLimit {
            component,
            unit,
            idle_load: idle,
            load_per_mm: per_mm,
            limit,
            max_depth_mm,
            r2,
            why,
        });
    };

    // Spindle motor: torque and power.
    let torque: Vec<f64> = rows.iter().map(|r| s_torque[r.0].abs()).collect();
    let (idle, slope, r2) = fit_load("spindle torque", torque)?;
    let rated = spindle.motor.rated_torque_Nm;
    push(
        format!("{spindle_axis} motor torque"),
        "N·m",
        idle,
        slope,
        margin * rated,
        r2,
        format!("{:.0} % of the rated {rated:.1} N·m", 100.0 * margin),
    );
    let power = spindle.motor.rated_power_W;
    push(
        format!("{spindle_axis} motor power"),
        "W",
        idle * omega_r,
        slope * omega_r,
        margin * power,
        r2,
        format!(
            "{:.0} % of the rated {:.1} kW at {rpm_r:.0} rpm",
            100.0 * margin,
            power / 1000.0
        ),
    );
    // Spindle front bearing: the cutting force on the workpiece radius loads it radially.
    let radius_m = workpiece_diameter_mm / 2000.0;
    let c0 = spindle.front_bearing.static_load_rating_N;
    push(
        format!("{spindle_axis} front bearing"),
        "N",
        0.0,
        slope / radius_m,
        margin * c0 / s0,
        r2,
        format!(
            "static safety C₀/P₀ ≥ {s0} (C₀ = {:.0} kN), cutting force from torque on Ø{workpiece_diameter_mm} mm",
            c0 / 1000.0
        ),
    );
    // Feed axis: motor torque, and the axial load on nut and fixed bearing.
    if let Some((id, _, x_torque)) = feeding
        && let Some(axis) = profile.axis(id)
    {
        let torque: Vec<f64> = rows.iter().map(|r| x_torque[r.0].abs()).collect();
        let (idle, slope, r2) = fit_load("feed torque", torque)?;
        let rated = axis.motor.rated_torque_Nm;
        push(
            format!("{id} motor torque"),
            "N·m",
            idle,
            slope,
            margin * rated,
            r2,
            format!("{:.0} % of the rated {rated:.1} N·m", 100.0 * margin),
        );
        if let (Some(screw), Some(nut), Some(limits)) =
            (&axis.screw, &axis.nut, axial_load_limits(axis, s0))
        {
            // Newtons of axial load per N·m of torque the cut adds.
            let newtons_per_Nm = screw_thrust_N_per_Nm(screw);
            push(
                format!("{id} nut preload"),
                "N",
                0.0,
                slope * newtons_per_Nm,
                margin * limits.nut_preload_loss_N,
                r2,
                format!(
                    "the preload ({:.0} N) is lost above {:.1}× it in axial load",
                    nut.preload_N, nut.preload_loss_factor
                ),
            );
            let c0 = axis.front_bearing.static_load_rating_N;
            push(
                format!("{id} fixed bearing"),
                "N",
                0.0,
                slope * newtons_per_Nm,
                margin * limits.fixed_bearing_static_N,
                r2,
                format!("static safety C₀/P₀ ≥ {s0} (C₀ = {:.0} kN)", c0 / 1000.0),
            );
        }
    }
    components.sort_by(|a, b| a.max_depth_mm.total_cmp(&b.max_depth_mm));
    let limiting = &components[0];
    let min_depth = profile.depth_of_cut.min_depth_mm;
    let recommended = if limiting.max_depth_mm < min_depth {
        0.0
    } else {
        (limiting.max_depth_mm * 10.0).floor() / 10.0
    };
    let reason = if recommended == 0.0 {
        format!(
            "{} is at its limit already ({:.1} of {:.1} {} without a chip): do not rough-cut",
            limiting.component, limiting.idle_load, limiting.limit, limiting.unit
        )
    } else {
        format!(
            "{} reaches {:.1} {} ({}) at {:.2} mm depth with f = {:.2} mm/rev: it grows {:.2} {} per mm",
            limiting.component,
            limiting.limit,
            limiting.unit,
            limiting.why,
            limiting.max_depth_mm,
            feed_r,
            limiting.load_per_mm,
            limiting.unit
        )
    };
    Ok(DepthOfCutRecommendation {
        recommended_depth_mm: recommended,
        limiting_component: limiting.component.clone(),
        reason,
        feed_per_rev_mm: feed_r,
        spindle_rpm: rpm_r,
        cutting_samples: rows.len(),
        components,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::profile::NutRating;

    /// An X axis with round numbers: Ø32 × 10 screw at η = 0.9, 1500 N nut preload lost at
    /// 2.8×, front bearing C = 26 kN and C₀ = 23 kN.
    fn axis() -> AxisProfile {
        let mut axis = MachineProfile::twin_default().axes[&AxisId::X].clone();
        let screw = axis.screw.as_mut().expect("the twin's X has a screw");
        screw.lead_mm = 10.0;
        screw.diameter_mm = 32.0;
        screw.efficiency = 0.9;
        axis.nut = Some(NutRating {
            dynamic_load_rating_N: 30_000.0,
            preload_N: 1500.0,
            preload_loss_factor: 2.8,
        });
        axis.front_bearing.dynamic_load_rating_N = 26_000.0;
        axis.front_bearing.static_load_rating_N = 23_000.0;
        axis
    }

    /// By hand: tan β = 10 / (32π) = 0.099472; preload drag T_d = 0.05 / √tan β · 1500 N ·
    /// 0.010 m / 2π = 0.378470 N·m; 2π · 0.9 / 0.010 m = 565.487 N per N·m; so 2 N·m at the nut
    /// is (2 − 0.378470) · 565.487 = 916.954 N of axial load: 21.83 % of the 4200 N at which
    /// the preload is lost and 3.527 % of the bearing's C.
    #[test]
    fn nut_torque_becomes_axial_load_by_the_thrust_formula() {
        let axis = axis();
        let load = axial_load_from_nut_torque_N(&axis, 2.0).expect("a feed axis");
        assert!((load - 916.953_681).abs() < 1e-5, "{load}");
        // The direction of travel does not change the load's size.
        let reverse = axial_load_from_nut_torque_N(&axis, -2.0).expect("a feed axis");
        assert_eq!(load, reverse);
        // Below the preload drag there is no thrust.
        assert_eq!(axial_load_from_nut_torque_N(&axis, 0.3), Some(0.0));

        let limits = axial_load_limits(&axis, 4.0).expect("a nut");
        assert_eq!(limits.nut_preload_loss_N, 4200.0);
        assert_eq!(limits.fixed_bearing_static_N, 5750.0);
        assert!((100.0 * load / limits.nut_preload_loss_N - 21.832_23).abs() < 1e-4);
        assert!((100.0 * load / axis.front_bearing.dynamic_load_rating_N - 3.526_745).abs() < 1e-5);
    }

    #[test]
    fn an_axis_without_a_nut_has_no_axial_load() {
        let spindle = MachineProfile::twin_default().axes[&AxisId::S].clone();
        assert_eq!(axial_load_from_nut_torque_N(&spindle, 2.0), None);
        assert_eq!(axial_load_limits(&spindle, 4.0), None);
    }
}
