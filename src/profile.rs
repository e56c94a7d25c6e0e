//! The machine profile: what servosight knows about one machine.
//!
//! Geometry and ratings come from the builder's documentation, limits from the shop's rules,
//! and the fitted coefficients of every estimator from `servosight calibrate`. It is a TOML file
//! (the twin's machine ships as `assets/it25-twin.toml`) and is validated on load, so a typo or
//! a nonsensical value is an error naming the field, never a silently wrong estimate.
#![allow(non_snake_case)] // unit suffixes are part of the names

use std::collections::BTreeMap;
use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::signal::AxisId;

/// Everything about one machine.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MachineProfile {
    /// The machine's name.
    pub name: String,
    /// The axes, by id.
    pub axes: BTreeMap<AxisId, AxisProfile>,
    /// Depth-of-cut recommendation settings.
    pub depth_of_cut: DepthOfCutSettings,
    /// Pass / warn / fail limits of the shift-start warm-up checklist (the built-in defaults
    /// when the file has no `[warmup]` table).
    #[serde(default)]
    pub warmup: WarmupSettings,
    /// Fitted estimator coefficients; absent until the machine is calibrated.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub calibration: Option<crate::estimators::models::Calibration>,
}

/// What kind of axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum AxisKind {
    /// A ball-screw feed axis.
    Feed,
    /// A spindle (or rotary axis).
    Spindle,
}

/// One axis.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AxisProfile {
    /// Feed or spindle.
    pub kind: AxisKind,
    /// The motor's ratings.
    pub motor: MotorRating,
    /// Ball screw geometry (feed axes).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub screw: Option<ScrewProfile>,
    /// Front (fixed-side) bearing.
    pub front_bearing: BearingRating,
    /// Back / rear bearing.
    pub back_bearing: BearingRating,
    /// Ball-screw nut (feed axes).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub nut: Option<NutRating>,
    /// Bearing lubricant.
    pub lubricant: LubricantProfile,
    /// Warning and fault thresholds.
    pub limits: AxisLimits,
}

/// Motor ratings from the data sheet.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MotorRating {
    /// Rated (continuous) torque, N·m.
    pub rated_torque_Nm: f64,
    /// Rated power, W.
    pub rated_power_W: f64,
    /// Maximum speed, rpm.
    pub max_speed_rpm: f64,
    /// Torque constant, N·m/A.
    pub torque_constant_Nm_per_A: f64,
}

/// Ball screw geometry.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScrewProfile {
    /// Lead, mm per revolution.
    pub lead_mm: f64,
    /// Nominal diameter, mm.
    pub diameter_mm: f64,
    /// Stroke, mm.
    pub stroke_mm: f64,
    /// Mechanical efficiency (forward drive).
    pub efficiency: f64,
    /// Positions of the straightness nodes along the stroke, mm (node 1 first).
    pub node_positions_mm: Vec<f64>,
}

/// A bearing's ratings and the constants of its friction model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BearingRating {
    /// Basic dynamic load rating C, N.
    pub dynamic_load_rating_N: f64,
    /// Basic static load rating C₀, N.
    pub static_load_rating_N: f64,
    /// Nominal preload, N.
    pub preload_N: f64,
    /// Pitch diameter, mm.
    pub pitch_diameter_mm: f64,
    /// Palmgren's load-independent factor f₀.
    pub f0: f64,
    /// Palmgren's load-dependent factor f₁.
    pub f1: f64,
}

/// Ball-screw nut ratings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NutRating {
    /// Basic dynamic load rating C_a, N.
    pub dynamic_load_rating_N: f64,
    /// Nominal preload, N.
    pub preload_N: f64,
    /// Axial load above which the preload is lost, as a multiple of the preload (≈ 2.8 for a
    /// double nut: one half unloads completely at 2^(3/2) F_p).
    pub preload_loss_factor: f64,
}

/// Lubricant viscosity against temperature (for Palmgren's speed term).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LubricantProfile {
    /// Kinematic viscosity at 40 °C, mm²/s.
    pub viscosity_40C_cSt: f64,
    /// Exponential temperature coefficient, 1/K.
    pub temperature_coefficient_per_K: f64,
}

/// Warning and fault thresholds of one axis.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AxisLimits {
    /// Motor (flange) temperature warning / fault, °C.
    pub motor_temp_C: Threshold,
    /// Bearing temperature warning / fault, °C.
    pub bearing_temp_C: Threshold,
    /// Nut temperature warning / fault, °C.
    pub nut_temp_C: Threshold,
    /// Motor abnormality warning / fault: excess friction torque, % of the healthy ideal
    /// friction torque (either way).
    pub abnormality: Threshold,
    /// Relative preload drop that counts as preload loss (e.g. 0.25 = 25 %).
    pub preload_loss_fraction: f64,
    /// Relative friction rise that counts as wear (e.g. 0.25).
    pub friction_rise_fraction: f64,
    /// Relative drift of a friction-fingerprint figure from its baseline that warns.
    pub fingerprint_drift_fraction: f64,
    /// Spindle elongation warning / fault, µm (spindle axes).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub elongation_um: Option<Threshold>,
}

/// A warning and a fault level.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Threshold {
    /// Above this: warning.
    pub warning: f64,
    /// Above this: fault.
    pub fault: f64,
}

/// Settings of the depth-of-cut recommendation.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DepthOfCutSettings {
    /// Fraction of each component's limit that may be used (e.g. 0.8).
    pub margin: f64,
    /// Static safety factor required of the bearings (C₀ / P₀), e.g. 4 for a spindle.
    pub bearing_static_safety: f64,
    /// Smallest depth the recommendation will state, mm (below: "do not rough").
    pub min_depth_mm: f64,
}

/// Limits of the shift-start warm-up checklist.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct WarmupSettings {
    /// Window over which the temperature rates are measured, min.
    pub settle_window_min: f64,
    /// Rate of change of any estimated (or stator) temperature, °C/min: above `warning` the
    /// machine is still warming up, above `fault` it is far from thermal equilibrium.
    pub settle_rate_C_per_min: Threshold,
    /// Measured backlash, µm: above `warning` it needs attention, above `fault` the axis
    /// needs maintenance.
    pub backlash_um: Threshold,
    /// Difference between the measured backlash and the controller's backlash compensation
    /// that calls for a new compensation value, µm.
    pub backlash_compensation_tolerance_um: f64,
    /// Smallest confidence (0–1) of a backlash measurement that counts. The default is low on
    /// purpose: the backlash analysis multiplies the share of feeds with a clear current rise
    /// by how well their intervals agree, and the fastest feed of the standard test resolves
    /// the lash poorly, so a sound test scores about 0.1–0.2 (the twin's own: 0.12).
    pub min_backlash_confidence: f64,
    /// Spindle elongation left uncompensated (estimate minus the controller's thermal offset)
    /// that is still acceptable, µm.
    pub elongation_tolerance_um: f64,
}

impl Default for WarmupSettings {
    fn default() -> Self {
        WarmupSettings {
            settle_window_min: 5.0,
            settle_rate_C_per_min: Threshold {
                warning: 0.1,
                fault: 0.5,
            },
            backlash_um: Threshold {
                warning: 20.0,
                fault: 40.0,
            },
            backlash_compensation_tolerance_um: 2.0,
            min_backlash_confidence: 0.1,
            elongation_tolerance_um: 5.0,
        }
    }
}

/// A profile that could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum ProfileError {
    /// The file could not be read or written.
    // The operating system's error is part of the message and not also its `source`: the
    // command line prints an error's whole chain, which then said it twice.
    #[error("{path}: {error}")]
    Io {
        /// The file.
        path: String,
        /// The operating system's error.
        error: std::io::Error,
    },
    /// The TOML does not parse or does not match the profile's fields.
    #[error("{path}: {message}")]
    Parse {
        /// The file.
        path: String,
        /// The parser's message (with line and column).
        message: String,
    },
    /// A value is out of its meaningful range.
    #[error("{path}: {field}: {message}")]
    Invalid {
        /// The file.
        path: String,
        /// The dotted field name.
        field: String,
        /// What is wrong.
        message: String,
    },
}

impl MachineProfile {
    /// Each axis's limits (warning and fault thresholds of its estimates), by axis: what the
    /// HMI judges the estimates against.
    pub fn axis_limits(&self) -> BTreeMap<AxisId, AxisLimits> {
        self.axes
            .iter()
            .map(|(axis, a)| (*axis, a.limits.clone()))
            .collect()
    }

    /// Reads and validates a profile file.
    pub fn load(path: &Path) -> Result<MachineProfile, ProfileError> {
        let name = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|error| ProfileError::Io {
            path: name.clone(),
            error,
        })?;
        Self::from_toml(&text, &name)
    }

    /// Parses and validates a profile; `source` names it in errors.
    pub fn from_toml(text: &str, source: &str) -> Result<MachineProfile, ProfileError> {
        let profile: MachineProfile = toml::from_str(text).map_err(|e| ProfileError::Parse {
            path: source.to_string(),
            message: e.to_string().trim_end().replace('\n', " "),
        })?;
        profile.validate(source)?;
        Ok(profile)
    }

    /// Writes the profile as TOML.
    pub fn save(&self, path: &Path) -> Result<(), ProfileError> {
        let name = path.display().to_string();
        let text = toml::to_string_pretty(self).map_err(|e| ProfileError::Parse {
            path: name.clone(),
            message: e.to_string(),
        })?;
        std::fs::write(path, text).map_err(|error| ProfileError::Io { path: name, error })
    }

    /// The twin's machine as shipped, calibrated by `scripts/accuracy.sh`
    /// (`assets/it25-twin.toml`, built in): what the HMI estimates with on the embedded twin.
    pub fn twin_calibrated() -> Result<MachineProfile, ProfileError> {
        MachineProfile::from_toml(
            include_str!("../assets/it25-twin.toml"),
            "assets/it25-twin.toml (built in)",
        )
    }

    /// The profile of the twin's default machine, without calibration.
    pub fn twin_default() -> MachineProfile {
        let machine = crate::sim::MachineParams::default();
        let bearing = |b: &crate::sim::machine::BearingParams| BearingRating {
            dynamic_load_rating_N: b.dynamic_load_rating_N,
            static_load_rating_N: b.static_load_rating_N,
            preload_N: b.preload_N,
            pitch_diameter_mm: b.pitch_diameter_mm,
            f0: b.f0,
            f1: b.f1,
        };
        let motor = |m: &crate::sim::machine::MotorParams| MotorRating {
            rated_torque_Nm: m.rated_torque_Nm,
            rated_power_W: m.rated_power_W,
            max_speed_rpm: m.max_speed_rpm,
            torque_constant_Nm_per_A: m.torque_constant_Nm_per_A,
        };
        let lubricant = |l: &crate::sim::machine::LubricantParams| LubricantProfile {
            viscosity_40C_cSt: l.viscosity_40C_cSt,
            temperature_coefficient_per_K: l.temperature_coefficient_per_K,
        };
        let x = &machine.x_axis;
        let s = &machine.spindle;
        let nodes = x.straightness_nodes;
        let feed_limits = AxisLimits {
            motor_temp_C: Threshold {
                warning: 60.0,
                fault: 80.0,
            },
            bearing_temp_C: Threshold {
                warning: 45.0,
                fault: 60.0,
            },
            nut_temp_C: Threshold {
                warning: 45.0,
                fault: 60.0,
            },
            // A feed axis's friction is mostly the nut's preload drag and the guides, so a
            // bearing's friction doubling moves the total by well under 10 %; its healthy
            // model scatters by well under 1 % (docs/accuracy.md).
            abnormality: Threshold {
                warning: 4.0,
                fault: 12.0,
            },
            preload_loss_fraction: 0.25,
            friction_rise_fraction: 0.25,
            fingerprint_drift_fraction: 0.2,
            elongation_um: None,
        };
        let mut axes = BTreeMap::new();
        axes.insert(
            AxisId::X,
            AxisProfile {
                kind: AxisKind::Feed,
                motor: motor(&x.motor),
                screw: Some(ScrewProfile {
                    lead_mm: x.screw_lead_mm,
                    diameter_mm: x.screw_diameter_mm,
                    stroke_mm: x.stroke_mm,
                    efficiency: x.screw_efficiency,
                    node_positions_mm: (0..nodes)
                        .map(|k| x.stroke_mm * k as f64 / (nodes - 1) as f64)
                        .collect(),
                }),
                front_bearing: bearing(&x.front_bearing),
                back_bearing: bearing(&x.back_bearing),
                nut: Some(NutRating {
                    dynamic_load_rating_N: x.nut_dynamic_load_rating_N,
                    preload_N: x.nut_preload_N,
                    preload_loss_factor: 2.8,
                }),
                lubricant: lubricant(&x.lubricant),
                limits: feed_limits.clone(),
            },
        );
        axes.insert(
            AxisId::S,
            AxisProfile {
                kind: AxisKind::Spindle,
                motor: motor(&s.motor),
                screw: None,
                front_bearing: bearing(&s.front_bearing),
                back_bearing: bearing(&s.rear_bearing),
                nut: None,
                lubricant: lubricant(&s.lubricant),
                limits: AxisLimits {
                    motor_temp_C: Threshold {
                        warning: 90.0,
                        fault: 120.0,
                    },
                    bearing_temp_C: Threshold {
                        warning: 55.0,
                        fault: 70.0,
                    },
                    elongation_um: Some(Threshold {
                        warning: 40.0,
                        fault: 60.0,
                    }),
                    // The spindle's healthy model scatters by ≈ 1.5 % (docs/accuracy.md).
                    abnormality: Threshold {
                        warning: 8.0,
                        fault: 25.0,
                    },
                    ..feed_limits
                },
            },
        );
        MachineProfile {
            name: machine.name,
            axes,
            depth_of_cut: DepthOfCutSettings {
                margin: 0.8,
                bearing_static_safety: 4.0,
                min_depth_mm: 0.2,
            },
            warmup: WarmupSettings::default(),
            calibration: None,
        }
    }

    /// Checks every value; the error names the field.
    pub fn validate(&self, source: &str) -> Result<(), ProfileError> {
        let invalid = |field: String, message: String| ProfileError::Invalid {
            path: source.to_string(),
            field,
            message,
        };
        let positive = |field: String, value: f64| {
            if value.is_finite() && value > 0.0 {
                Ok(())
            } else {
                Err(invalid(
                    field,
                    format!("must be a positive number, is {value}"),
                ))
            }
        };
        if self.axes.is_empty() {
            return Err(invalid("axes".into(), "no axis defined".into()));
        }
        for (id, axis) in &self.axes {
            let f = |name: &str| format!("axes.{id}.{name}");
            positive(f("motor.rated_torque_Nm"), axis.motor.rated_torque_Nm)?;
            positive(f("motor.rated_power_W"), axis.motor.rated_power_W)?;
            positive(f("motor.max_speed_rpm"), axis.motor.max_speed_rpm)?;
            positive(
                f("motor.torque_constant_Nm_per_A"),
                axis.motor.torque_constant_Nm_per_A,
            )?;
            for (name, b) in [
                ("front_bearing", &axis.front_bearing),
                ("back_bearing", &axis.back_bearing),
            ] {
                positive(
                    f(&format!("{name}.dynamic_load_rating_N")),
                    b.dynamic_load_rating_N,
                )?;
                positive(
                    f(&format!("{name}.static_load_rating_N")),
                    b.static_load_rating_N,
                )?;
                positive(f(&format!("{name}.pitch_diameter_mm")), b.pitch_diameter_mm)?;
                positive(f(&format!("{name}.f1")), b.f1)?;
                if !(b.preload_N.is_finite() && b.preload_N >= 0.0) {
                    return Err(invalid(
                        f(&format!("{name}.preload_N")),
                        "must be zero or positive".into(),
                    ));
                }
            }
            positive(
                f("lubricant.viscosity_40C_cSt"),
                axis.lubricant.viscosity_40C_cSt,
            )?;
            for (name, t) in [
                ("motor_temp_C", axis.limits.motor_temp_C),
                ("bearing_temp_C", axis.limits.bearing_temp_C),
                ("nut_temp_C", axis.limits.nut_temp_C),
                ("abnormality", axis.limits.abnormality),
            ] {
                if !(t.warning.is_finite() && t.fault.is_finite() && t.warning < t.fault) {
                    return Err(invalid(
                        f(&format!("limits.{name}")),
                        format!("warning {} must be below fault {}", t.warning, t.fault),
                    ));
                }
            }
            match axis.kind {
                AxisKind::Feed => {
                    let screw = axis
                        .screw
                        .as_ref()
                        .ok_or_else(|| invalid(f("screw"), "a feed axis needs its screw".into()))?;
                    positive(f("screw.lead_mm"), screw.lead_mm)?;
                    positive(f("screw.diameter_mm"), screw.diameter_mm)?;
                    positive(f("screw.stroke_mm"), screw.stroke_mm)?;
                    if !(screw.efficiency > 0.0 && screw.efficiency <= 1.0) {
                        return Err(invalid(f("screw.efficiency"), "must be in (0, 1]".into()));
                    }
                    if screw.node_positions_mm.len() < 2
                        || !screw.node_positions_mm.windows(2).all(|w| w[1] > w[0])
                    {
                        return Err(invalid(
                            f("screw.node_positions_mm"),
                            "needs at least two strictly increasing positions".into(),
                        ));
                    }
                    let nut = axis
                        .nut
                        .as_ref()
                        .ok_or_else(|| invalid(f("nut"), "a feed axis needs its nut".into()))?;
                    positive(f("nut.preload_N"), nut.preload_N)?;
                    positive(f("nut.dynamic_load_rating_N"), nut.dynamic_load_rating_N)?;
                    positive(f("nut.preload_loss_factor"), nut.preload_loss_factor)?;
                }
                AxisKind::Spindle => {}
            }
        }
        let d = &self.depth_of_cut;
        if !(d.margin > 0.0 && d.margin <= 1.0) {
            return Err(invalid(
                "depth_of_cut.margin".into(),
                "must be in (0, 1]".into(),
            ));
        }
        positive(
            "depth_of_cut.bearing_static_safety".into(),
            d.bearing_static_safety,
        )?;
        let w = &self.warmup;
        positive("warmup.settle_window_min".into(), w.settle_window_min)?;
        positive(
            "warmup.elongation_tolerance_um".into(),
            w.elongation_tolerance_um,
        )?;
        positive(
            "warmup.backlash_compensation_tolerance_um".into(),
            w.backlash_compensation_tolerance_um,
        )?;
        for (name, t) in [
            ("settle_rate_C_per_min", w.settle_rate_C_per_min),
            ("backlash_um", w.backlash_um),
        ] {
            if !(t.warning.is_finite()
                && t.fault.is_finite()
                && 0.0 < t.warning
                && t.warning < t.fault)
            {
                return Err(invalid(
                    format!("warmup.{name}"),
                    format!(
                        "warning {} must be positive and below fault {}",
                        t.warning, t.fault
                    ),
                ));
            }
        }
        if !(0.0..=1.0).contains(&w.min_backlash_confidence) {
            return Err(invalid(
                "warmup.min_backlash_confidence".into(),
                "must be in [0, 1]".into(),
            ));
        }
        if let Some(calibration) = &self.calibration {
            calibration
                .validate()
                .map_err(|(field, message)| invalid(format!("calibration.{field}"), message))?;
        }
        Ok(())
    }

    /// The profile of an axis, or an error naming it.
    pub fn axis(&self, id: AxisId) -> Option<&AxisProfile> {
        self.axes.get(&id)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn twin_profile_round_trips_through_toml() {
        let profile = MachineProfile::twin_default();
        let text = toml::to_string_pretty(&profile).unwrap();
        let back = MachineProfile::from_toml(&text, "p.toml").unwrap();
        assert_eq!(back, profile);
    }

    #[test]
    fn invalid_values_are_named() {
        let mut profile = MachineProfile::twin_default();
        profile
            .axes
            .get_mut(&AxisId::X)
            .unwrap()
            .limits
            .bearing_temp_C = Threshold {
            warning: 70.0,
            fault: 60.0,
        };
        let text = toml::to_string_pretty(&profile).unwrap();
        let err = MachineProfile::from_toml(&text, "p.toml")
            .unwrap_err()
            .to_string();
        assert!(err.contains("axes.X.limits.bearing_temp_C"), "{err}");

        let err = MachineProfile::from_toml("name = 3", "p.toml")
            .unwrap_err()
            .to_string();
        assert!(err.starts_with("p.toml:"), "{err}");
        let text = toml::to_string_pretty(&MachineProfile::twin_default())
            .unwrap()
            .replace("lead_mm = 10.0", "lead_mm = -10.0");
        let err = MachineProfile::from_toml(&text, "p.toml")
            .unwrap_err()
            .to_string();
        assert!(err.contains("axes.X.screw.lead_mm"), "{err}");
        // A warm start that would start a part with negative or undefined heat.
        let shipped = include_str!("../assets/it25-twin.toml");
        for bad in ["-0.1", "nan", "inf"] {
            let text = shipped.replacen("\nheat = ", &format!("\nheat = {bad} # "), 1);
            let err = MachineProfile::from_toml(&text, "p.toml")
                .unwrap_err()
                .to_string();
            assert!(
                err.contains("calibration.axes.X.front_bearing_temp.warm_start")
                    && err.contains("`heat` must be a non-negative number"),
                "{bad}: {err}"
            );
        }
        // …or that names an accumulation the part does not have.
        let text = shipped.replacen("\nheat = ", "\nheat_fast = ", 1);
        let err = MachineProfile::from_toml(&text, "p.toml")
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("warm_start") && err.contains("`heat_fast` is not an accumulation"),
            "{err}"
        );
    }
}
