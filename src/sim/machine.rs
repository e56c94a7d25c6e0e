//! The twin's machine: every parameter with its unit and where its value comes from.
//!
//! The default is the paper's IT-25 lathe (ITRI; spindle motor 15/18.5 kW, 3,500 rpm max, A2-8
//! nose, 10" chuck — seed paper Fig. 1(b)) with an X feed axis driven by a Ø32 × 10 mm ball screw.
//! Where the paper gives no figure, values are typical catalogue data for parts of that size
//! (named per field) and the thermal conductances are chosen so that the twin reproduces the
//! paper's magnitudes: bearing heat of 120–140 W at top speed (paper Fig. 3(a): 138 W front,
//! 120 W rear), and a spindle thermal elongation of 29–45 µm over an operating day (Table 2).
//!
//! Every field can be overridden from the command line (`--set spindle.front_bearing.preload_N=3000`).

#![allow(non_snake_case)] // unit suffixes (`_C`, `_N`, `_W_per_K`) are part of the names

use serde::{Deserialize, Serialize};

/// The whole machine.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MachineParams {
    /// A name for recordings' metadata.
    pub name: String,
    /// The room around the machine.
    pub room: RoomParams,
    /// Coolant and oil chiller.
    pub coolant: CoolantParams,
    /// Cutting-force model for turning.
    pub cutting: CuttingParams,
    /// The spindle (rotational axis S).
    pub spindle: SpindleParams,
    /// The X feed axis.
    pub x_axis: FeedAxisParams,
    /// Sensor noise, delay and drift.
    pub measurement: MeasurementParams,
}

/// Room temperature over the day.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RoomParams {
    /// Daily mean room temperature, °C.
    pub base_C: f64,
    /// Half the peak-to-peak daily swing, K (an unconditioned shop: 1–3 K).
    pub daily_amplitude_K: f64,
    /// Hour of the day when the room is warmest.
    pub warmest_hour: f64,
    /// Clock hour at which a recording starts.
    pub start_hour: f64,
    /// Slow linear drift of the room, K per hour (weather).
    pub drift_K_per_h: f64,
}

/// Coolant / oil chiller.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CoolantParams {
    /// Coolant temperature relative to the room, K (a chiller holds it slightly below).
    pub offset_from_room_K: f64,
    /// Headstock jacket conductance to the coolant while it flows, W/K.
    pub spindle_jacket_W_per_K: f64,
    /// Spindle front-bearing conductance to the coolant while it flows, W/K.
    pub spindle_bearing_W_per_K: f64,
    /// Bed conductance to the coolant (flood coolant over the slideways), W/K.
    pub bed_W_per_K: f64,
}

/// Turning cutting-force model: F_c = k_c · a_p · f.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CuttingParams {
    /// Specific cutting force of the workpiece material, N/mm² (medium-carbon steel ≈ 2000).
    pub specific_force_N_per_mm2: f64,
    /// Workpiece diameter being turned, mm (the IT-25 bar capacity is 81 mm).
    pub workpiece_diameter_mm: f64,
    /// Feed force on the X axis as a fraction of the cutting force (≈ 0.3–0.5 for turning).
    pub feed_force_ratio: f64,
}

/// A motor: electrical, magnetic and mechanical constants.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MotorParams {
    /// Rated (continuous) torque, N·m.
    pub rated_torque_Nm: f64,
    /// Rated power, W.
    pub rated_power_W: f64,
    /// Maximum speed, rpm.
    pub max_speed_rpm: f64,
    /// Torque per torque-producing (q-axis) rms phase ampere, N·m/A.
    pub torque_constant_Nm_per_A: f64,
    /// Magnetising (d-axis) current while energised, A rms.
    pub magnetising_current_A: f64,
    /// Phase resistance at 20 °C, Ω.
    pub phase_resistance_ohm: f64,
    /// Hysteresis loss, W per 1000 rpm.
    pub hysteresis_W_per_krpm: f64,
    /// Eddy-current loss, W per (1000 rpm)².
    pub eddy_W_per_krpm2: f64,
    /// Rotor inertia, kg·m².
    pub rotor_inertia_kgm2: f64,
}

/// A rolling bearing (or a matched set), for Palmgren's friction-torque model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BearingParams {
    /// Pitch diameter d_m, mm.
    pub pitch_diameter_mm: f64,
    /// Palmgren's load-independent factor f₀ (oil-air angular contact ≈ 1.5–2, grease ≈ 2–4,
    /// multiplied by the number of rows).
    pub f0: f64,
    /// Palmgren's load-dependent factor f₁ (angular contact ≈ 0.001).
    pub f1: f64,
    /// Axial preload, N.
    pub preload_N: f64,
    /// Basic dynamic load rating C, N.
    pub dynamic_load_rating_N: f64,
    /// Basic static load rating C₀, N.
    pub static_load_rating_N: f64,
}

/// Lubricant viscosity against temperature: ν = ν₄₀ · exp(−k (T − 40 °C)).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LubricantParams {
    /// Kinematic viscosity at 40 °C, mm²/s (ISO VG grade).
    pub viscosity_40C_cSt: f64,
    /// Exponential temperature coefficient, 1/K (mineral oils ≈ 0.025–0.035).
    pub temperature_coefficient_per_K: f64,
}

/// The spindle (rotational axis): motor, bearings, thermal network, elongation.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpindleParams {
    /// The spindle motor.
    pub motor: MotorParams,
    /// Spindle, chuck and workpiece inertia seen by the motor, kg·m².
    pub inertia_kgm2: f64,
    /// Speed ramp of the drive, rpm per second.
    pub acceleration_rpm_per_s: f64,
    /// Viscous drag (seals, windage), N·m per 1000 rpm.
    pub viscous_Nm_per_krpm: f64,
    /// Front bearing set.
    pub front_bearing: BearingParams,
    /// Rear bearing set.
    pub rear_bearing: BearingParams,
    /// Bearing lubricant.
    pub lubricant: LubricantParams,
    /// Heat capacity of the stator, J/K.
    pub stator_J_per_K: f64,
    /// Heat capacity of the front bearing and its seat, J/K.
    pub front_bearing_J_per_K: f64,
    /// Heat capacity of the rear bearing and its seat, J/K.
    pub rear_bearing_J_per_K: f64,
    /// Heat capacity of the headstock housing, J/K.
    pub housing_J_per_K: f64,
    /// Heat capacity of the bed and turret slide that carry the tool, J/K.
    pub bed_J_per_K: f64,
    /// Stator to housing, W/K.
    pub stator_housing_W_per_K: f64,
    /// Stator to room air at standstill (fan off), W/K.
    pub stator_air_W_per_K: f64,
    /// Front bearing to housing, W/K.
    pub front_bearing_housing_W_per_K: f64,
    /// Rear bearing to housing, W/K.
    pub rear_bearing_housing_W_per_K: f64,
    /// Front to rear bearing along the shaft, W/K.
    pub shaft_W_per_K: f64,
    /// Each bearing to room air along the shaft and nose at standstill, W/K.
    pub bearing_air_W_per_K: f64,
    /// Housing to room air, W/K.
    pub housing_air_W_per_K: f64,
    /// Housing to the bed it stands on, W/K.
    pub housing_bed_W_per_K: f64,
    /// Bed to room air, W/K.
    pub bed_air_W_per_K: f64,
    /// How much convection grows at maximum speed: G(n) = G₀ (1 + gain · (n/n_max)^0.8).
    pub speed_cooling_gain: f64,
    /// Effective shaft length whose growth moves the spindle nose relative to the tool, mm.
    /// The tool sits on the bed, whose growth over the same height moves it the same way, so
    /// elongation is α (L_shaft ΔT_shaft + L_housing ΔT_housing − (L_shaft + L_housing) ΔT_bed).
    pub shaft_length_mm: f64,
    /// Effective housing length whose growth moves the spindle nose, mm.
    pub housing_length_mm: f64,
    /// Linear expansion coefficient of steel / cast iron, 1/K.
    pub expansion_per_K: f64,
}

/// A ball-screw feed axis: motor, support bearings, nut, table, bed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FeedAxisParams {
    /// The servo motor.
    pub motor: MotorParams,
    /// Screw lead, mm per revolution.
    pub screw_lead_mm: f64,
    /// Screw nominal diameter, mm.
    pub screw_diameter_mm: f64,
    /// Screw length between supports, mm.
    pub screw_length_mm: f64,
    /// Usable stroke, mm.
    pub stroke_mm: f64,
    /// Number of straightness nodes along the stroke (equally spaced, ends included).
    pub straightness_nodes: usize,
    /// Moving mass (table, slide, turret), kg.
    pub table_mass_kg: f64,
    /// Mechanical efficiency of the screw (forward drive).
    pub screw_efficiency: f64,
    /// Fixed-side support bearing set (takes the axial load).
    pub front_bearing: BearingParams,
    /// Floating-side support bearing.
    pub back_bearing: BearingParams,
    /// Support bearing grease base oil.
    pub lubricant: LubricantParams,
    /// Nut preload, N.
    pub nut_preload_N: f64,
    /// Nut basic dynamic load rating, N.
    pub nut_dynamic_load_rating_N: f64,
    /// Relative drop of the preload in the middle of the stroke (wear where the nut works most).
    pub nut_preload_variation: f64,
    /// Slideway friction coefficient (linear guides ≈ 0.003–0.01).
    pub guide_friction_coefficient: f64,
    /// Direction-dependent seal and wiper friction, N.
    pub seal_friction_N: f64,
    /// Extra friction at very low speed (Stribeck), N.
    pub stribeck_friction_N: f64,
    /// Speed at which the Stribeck excess has fallen to 1/e, mm/s.
    pub stribeck_speed_mm_per_s: f64,
    /// Viscous friction, N per mm/s.
    pub viscous_N_per_mm_per_s: f64,
    /// Lost motion between nut and table, µm.
    pub backlash_um: f64,
    /// Position-loop gain K_v, 1/s (following error = speed / K_v).
    pub position_gain_per_s: f64,
    /// Acceleration of programmed moves, mm/s².
    pub acceleration_mm_per_s2: f64,
    /// Rapid traverse, mm/min.
    pub rapid_mm_per_min: f64,
    /// Heat capacities, J/K: stator, motor flange, front bearing, back bearing, nut, screw,
    /// bed near the motor, bed at the far end, base.
    pub capacity_J_per_K: FeedAxisCapacities,
    /// Conductances, W/K.
    pub conductance_W_per_K: FeedAxisConductances,
    /// Height of the bed section that bends vertically, mm.
    pub bed_height_mm: f64,
    /// Width of the bed section that bends horizontally, mm.
    pub bed_width_mm: f64,
    /// Length of the bed carrying the stroke, mm.
    pub bed_length_mm: f64,
}

/// Heat capacities of the feed-axis nodes, J/K.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[allow(missing_docs)]
pub struct FeedAxisCapacities {
    pub stator: f64,
    pub motor_flange: f64,
    pub front_bearing: f64,
    pub back_bearing: f64,
    pub nut: f64,
    pub screw: f64,
    pub bed_front: f64,
    pub bed_back: f64,
    pub base: f64,
}

/// Conductances of the feed-axis network, W/K. `*_air` links go to the room and grow with speed
/// where the part moves (nut, screw, motor fan-less convection does not).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[allow(missing_docs)]
pub struct FeedAxisConductances {
    pub stator_flange: f64,
    pub stator_air: f64,
    pub flange_air: f64,
    pub flange_bed_front: f64,
    pub front_bearing_bed_front: f64,
    pub front_bearing_screw: f64,
    pub back_bearing_bed_back: f64,
    pub back_bearing_screw: f64,
    pub nut_screw: f64,
    pub nut_air: f64,
    pub nut_bed: f64,
    pub screw_air: f64,
    pub bed_front_bed_back: f64,
    pub bed_front_base: f64,
    pub bed_back_base: f64,
    pub bed_air: f64,
    pub base_air: f64,
    /// Convection growth at rapid traverse speed for the moving parts (nut, screw).
    pub speed_cooling_gain: f64,
}

/// Sensor noise, transport delay and instrument drift.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MeasurementParams {
    /// Multiplies every noise level below; 0 gives noiseless output.
    pub noise_scale: f64,
    /// Share of the noise variance that is correlated in time (AR(1)), 0–1.
    pub correlated_fraction: f64,
    /// Correlation time of the correlated part, s.
    pub correlation_time_s: f64,
    /// Temperature sensors (stator, PT100 references, room), K (1σ).
    pub temperature_noise_K: f64,
    /// Torque, fraction of the rated torque (1σ).
    pub torque_noise_fraction: f64,
    /// Speed, rpm (1σ).
    pub speed_noise_rpm: f64,
    /// Current, fraction of the rated current (rated torque / torque constant) (1σ).
    pub current_noise_fraction: f64,
    /// Encoder position, mm (1σ).
    pub position_noise_mm: f64,
    /// Displacement references (eddy-current, laser), µm (1σ).
    pub displacement_noise_um: f64,
    /// Delay of every measured signal when `signal_delay` is on, s.
    pub delay_s: f64,
    /// Constant offset of the reference instruments when `sensor_offset_drift` is on, in each
    /// channel's unit (K or µm).
    pub offset: f64,
    /// Linear drift of the reference instruments when `sensor_offset_drift` is on, unit per hour.
    pub drift_per_hour: f64,
}

impl Default for MachineParams {
    fn default() -> Self {
        MachineParams {
            name: "IT-25 lathe (twin)".into(),
            room: RoomParams {
                base_C: 20.0,
                daily_amplitude_K: 1.0,
                warmest_hour: 15.0,
                start_hour: 7.0,
                drift_K_per_h: 0.02,
            },
            coolant: CoolantParams {
                offset_from_room_K: -1.5,
                spindle_jacket_W_per_K: 10.0,
                spindle_bearing_W_per_K: 3.0,
                bed_W_per_K: 12.0,
            },
            cutting: CuttingParams {
                specific_force_N_per_mm2: 2000.0,
                workpiece_diameter_mm: 80.0,
                feed_force_ratio: 0.4,
            },
            spindle: SpindleParams {
                // 15 kW continuous / 18.5 kW 30-min induction spindle motor (paper Fig. 1(b));
                // base speed 1,500 rpm → 95.5 N·m rated.
                motor: MotorParams {
                    rated_torque_Nm: 95.5,
                    rated_power_W: 15_000.0,
                    max_speed_rpm: 3_500.0,
                    torque_constant_Nm_per_A: 2.5,
                    magnetising_current_A: 12.0,
                    phase_resistance_ohm: 0.08,
                    hysteresis_W_per_krpm: 40.0,
                    eddy_W_per_krpm2: 8.0,
                    rotor_inertia_kgm2: 0.08,
                },
                // A2-8 spindle with a 10" chuck and a bar workpiece.
                inertia_kgm2: 0.25,
                acceleration_rpm_per_s: 1_200.0,
                viscous_Nm_per_krpm: 0.35,
                // Front: a 100 mm bore angular-contact set (three rows), oil-air lubricated.
                // f₀ ≈ 0.8 for oil-air; f₁ = 0.001 (P₀/C₀)^0.33 ≈ 0.0003 at this preload.
                front_bearing: BearingParams {
                    pitch_diameter_mm: 125.0,
                    f0: 0.8,
                    f1: 0.0003,
                    preload_N: 2_400.0,
                    dynamic_load_rating_N: 150_000.0,
                    static_load_rating_N: 180_000.0,
                },
                // Rear: a 90 mm bore double-row cylindrical roller bearing.
                rear_bearing: BearingParams {
                    pitch_diameter_mm: 112.0,
                    f0: 1.0,
                    f1: 0.0003,
                    preload_N: 1_500.0,
                    dynamic_load_rating_N: 120_000.0,
                    static_load_rating_N: 160_000.0,
                },
                // ISO VG 22 spindle oil.
                lubricant: LubricantParams {
                    viscosity_40C_cSt: 22.0,
                    temperature_coefficient_per_K: 0.03,
                },
                stator_J_per_K: 18_000.0,
                front_bearing_J_per_K: 9_000.0,
                rear_bearing_J_per_K: 7_000.0,
                housing_J_per_K: 160_000.0,
                bed_J_per_K: 450_000.0,
                stator_housing_W_per_K: 4.0,
                stator_air_W_per_K: 6.0,
                front_bearing_housing_W_per_K: 9.0,
                rear_bearing_housing_W_per_K: 8.0,
                shaft_W_per_K: 3.0,
                bearing_air_W_per_K: 1.2,
                housing_air_W_per_K: 22.0,
                housing_bed_W_per_K: 4.0,
                bed_air_W_per_K: 40.0,
                speed_cooling_gain: 1.5,
                shaft_length_mm: 270.0,
                housing_length_mm: 300.0,
                expansion_per_K: 11.5e-6,
            },
            x_axis: FeedAxisParams {
                // A 1.8 kW, 8 N·m, 3,000 rpm AC servo (e.g. the αiF 8 class).
                motor: MotorParams {
                    rated_torque_Nm: 8.0,
                    rated_power_W: 1_800.0,
                    max_speed_rpm: 3_000.0,
                    torque_constant_Nm_per_A: 1.2,
                    magnetising_current_A: 0.3,
                    phase_resistance_ohm: 0.45,
                    hysteresis_W_per_krpm: 4.0,
                    eddy_W_per_krpm2: 1.5,
                    rotor_inertia_kgm2: 0.0012,
                },
                screw_lead_mm: 10.0,
                screw_diameter_mm: 32.0,
                screw_length_mm: 600.0,
                stroke_mm: 400.0,
                straightness_nodes: 5,
                table_mass_kg: 180.0,
                screw_efficiency: 0.9,
                // Fixed side: a 25 mm bore angular-contact pair (DB), grease.
                front_bearing: BearingParams {
                    pitch_diameter_mm: 40.0,
                    f0: 4.0,
                    f1: 0.001,
                    preload_N: 2_000.0,
                    dynamic_load_rating_N: 26_000.0,
                    static_load_rating_N: 23_000.0,
                },
                // Floating side: a 20 mm deep-groove bearing.
                back_bearing: BearingParams {
                    pitch_diameter_mm: 33.0,
                    f0: 2.0,
                    f1: 0.0007,
                    preload_N: 300.0,
                    dynamic_load_rating_N: 12_700.0,
                    static_load_rating_N: 6_200.0,
                },
                // Lithium grease, ISO VG 100 base oil.
                lubricant: LubricantParams {
                    viscosity_40C_cSt: 100.0,
                    temperature_coefficient_per_K: 0.035,
                },
                // Ø32 × 10 double nut: C_a ≈ 30 kN, preload ≈ 5 % of C_a.
                nut_preload_N: 1_500.0,
                nut_dynamic_load_rating_N: 30_000.0,
                nut_preload_variation: 0.15,
                guide_friction_coefficient: 0.005,
                seal_friction_N: 60.0,
                stribeck_friction_N: 30.0,
                stribeck_speed_mm_per_s: 0.5,
                viscous_N_per_mm_per_s: 0.15,
                backlash_um: 12.0,
                position_gain_per_s: 30.0,
                acceleration_mm_per_s2: 2_000.0,
                rapid_mm_per_min: 20_000.0,
                capacity_J_per_K: FeedAxisCapacities {
                    stator: 2_500.0,
                    motor_flange: 3_000.0,
                    front_bearing: 1_500.0,
                    back_bearing: 1_000.0,
                    nut: 1_800.0,
                    screw: 2_200.0,
                    bed_front: 60_000.0,
                    bed_back: 60_000.0,
                    base: 60_000.0,
                },
                conductance_W_per_K: FeedAxisConductances {
                    stator_flange: 2.0,
                    stator_air: 0.4,
                    flange_air: 0.8,
                    flange_bed_front: 1.0,
                    front_bearing_bed_front: 1.2,
                    front_bearing_screw: 0.6,
                    back_bearing_bed_back: 1.0,
                    back_bearing_screw: 0.5,
                    nut_screw: 1.5,
                    nut_air: 0.6,
                    nut_bed: 1.0,
                    screw_air: 0.8,
                    bed_front_bed_back: 2.0,
                    bed_front_base: 6.0,
                    bed_back_base: 6.0,
                    bed_air: 8.0,
                    base_air: 40.0,
                    speed_cooling_gain: 1.0,
                },
                bed_height_mm: 150.0,
                bed_width_mm: 200.0,
                bed_length_mm: 700.0,
            },
            measurement: MeasurementParams {
                noise_scale: 1.0,
                correlated_fraction: 0.0,
                correlation_time_s: 120.0,
                temperature_noise_K: 0.05,
                torque_noise_fraction: 0.004,
                speed_noise_rpm: 0.5,
                current_noise_fraction: 0.004,
                position_noise_mm: 0.0002,
                displacement_noise_um: 0.2,
                delay_s: 0.0,
                offset: 0.0,
                drift_per_hour: 0.0,
            },
        }
    }
}

/// A `--set` override that could not be applied.
#[derive(Debug, thiserror::Error)]
pub enum OverrideError {
    /// Not `path=value`.
    #[error("`{0}` is not `path=value` (e.g. spindle.front_bearing.preload_N=3000)")]
    Syntax(String),
    /// The path names no parameter.
    #[error("`{path}`: no such parameter (at `{at}`); known here: {known}")]
    UnknownPath {
        /// The full path.
        path: String,
        /// The first segment that did not match.
        at: String,
        /// Keys available at that level.
        known: String,
    },
    /// The value does not fit the parameter.
    #[error("`{path}`: {message}")]
    BadValue {
        /// The full path.
        path: String,
        /// What is wrong.
        message: String,
    },
}

impl MachineParams {
    /// Applies `path=value` overrides (dot-separated paths into the parameter tree). The value
    /// is parsed as a number, `true`/`false`, or else taken as text; the result must still be a
    /// valid machine.
    pub fn with_overrides(&self, overrides: &[String]) -> Result<MachineParams, OverrideError> {
        let mut tree = serde_json::to_value(self).map_err(|e| OverrideError::BadValue {
            path: String::new(),
            message: e.to_string(),
        })?;
        for item in overrides {
            let (path, value) = item
                .split_once('=')
                .ok_or_else(|| OverrideError::Syntax(item.clone()))?;
            let path = path.trim();
            let value = value.trim();
            let mut node = &mut tree;
            for segment in path.split('.') {
                let known = node
                    .as_object()
                    .map(|o| o.keys().cloned().collect::<Vec<_>>().join(", "))
                    .unwrap_or_default();
                node = node
                    .get_mut(segment)
                    .ok_or_else(|| OverrideError::UnknownPath {
                        path: path.to_string(),
                        at: segment.to_string(),
                        known,
                    })?;
            }
            if node.is_object() {
                return Err(OverrideError::BadValue {
                    path: path.to_string(),
                    message: "is a group of parameters, not one value".into(),
                });
            }
            let parsed: serde_json::Value = if let Ok(x) = value.parse::<f64>() {
                if !x.is_finite() {
                    return Err(OverrideError::BadValue {
                        path: path.to_string(),
                        message: format!("{value} is not a finite number"),
                    });
                }
                if node.is_u64() && x >= 0.0 && x.fract() == 0.0 {
                    serde_json::Value::from(x as u64)
                } else {
                    serde_json::Value::from(x)
                }
            } else if let Ok(b) = value.parse::<bool>() {
                serde_json::Value::from(b)
            } else {
                serde_json::Value::from(value)
            };
            *node = parsed;
        }
        let params: MachineParams =
            serde_json::from_value(tree).map_err(|e| OverrideError::BadValue {
                path: overrides.join(" "),
                message: e.to_string(),
            })?;
        params
            .validate()
            .map_err(|message| OverrideError::BadValue {
                path: overrides.join(" "),
                message,
            })?;
        Ok(params)
    }

    /// Checks that every parameter is physically meaningful.
    pub fn validate(&self) -> Result<(), String> {
        let positive = [
            ("spindle.inertia_kgm2", self.spindle.inertia_kgm2),
            (
                "spindle.acceleration_rpm_per_s",
                self.spindle.acceleration_rpm_per_s,
            ),
            (
                "spindle.motor.torque_constant_Nm_per_A",
                self.spindle.motor.torque_constant_Nm_per_A,
            ),
            (
                "spindle.motor.max_speed_rpm",
                self.spindle.motor.max_speed_rpm,
            ),
            (
                "spindle.motor.rated_torque_Nm",
                self.spindle.motor.rated_torque_Nm,
            ),
            (
                "x_axis.motor.torque_constant_Nm_per_A",
                self.x_axis.motor.torque_constant_Nm_per_A,
            ),
            (
                "x_axis.motor.max_speed_rpm",
                self.x_axis.motor.max_speed_rpm,
            ),
            (
                "x_axis.motor.rated_torque_Nm",
                self.x_axis.motor.rated_torque_Nm,
            ),
            ("x_axis.screw_lead_mm", self.x_axis.screw_lead_mm),
            ("x_axis.stroke_mm", self.x_axis.stroke_mm),
            ("x_axis.screw_efficiency", self.x_axis.screw_efficiency),
            (
                "x_axis.position_gain_per_s",
                self.x_axis.position_gain_per_s,
            ),
            (
                "x_axis.acceleration_mm_per_s2",
                self.x_axis.acceleration_mm_per_s2,
            ),
            ("x_axis.rapid_mm_per_min", self.x_axis.rapid_mm_per_min),
            ("x_axis.bed_height_mm", self.x_axis.bed_height_mm),
            ("x_axis.bed_width_mm", self.x_axis.bed_width_mm),
            ("x_axis.bed_length_mm", self.x_axis.bed_length_mm),
            (
                "spindle.housing_air_W_per_K",
                self.spindle.housing_air_W_per_K,
            ),
            (
                "x_axis.conductance_W_per_K.base_air",
                self.x_axis.conductance_W_per_K.base_air,
            ),
            (
                "measurement.correlation_time_s",
                self.measurement.correlation_time_s,
            ),
        ];
        for (name, value) in positive {
            if !(value.is_finite() && value > 0.0) {
                return Err(format!("{name} must be positive, is {value}"));
            }
        }
        if self.x_axis.screw_efficiency > 1.0 {
            return Err("x_axis.screw_efficiency must be at most 1".into());
        }
        if self.x_axis.straightness_nodes < 2 {
            return Err("x_axis.straightness_nodes must be at least 2".into());
        }
        if self.x_axis.bed_length_mm < self.x_axis.stroke_mm {
            return Err("x_axis.bed_length_mm must be at least the stroke".into());
        }
        if !(0.0..=1.0).contains(&self.measurement.correlated_fraction) {
            return Err("measurement.correlated_fraction must be between 0 and 1".into());
        }
        if !(self.measurement.noise_scale.is_finite() && self.measurement.noise_scale >= 0.0) {
            return Err(format!(
                "measurement.noise_scale must be 0 (noise-free) or positive, is {}",
                self.measurement.noise_scale
            ));
        }
        if self.measurement.delay_s < 0.0 || self.x_axis.backlash_um < 0.0 {
            return Err("measurement.delay_s and x_axis.backlash_um cannot be negative".into());
        }
        if !(0.0..1.0).contains(&self.x_axis.nut_preload_variation) {
            return Err("x_axis.nut_preload_variation must be in [0, 1)".into());
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_machine_is_valid_and_overrides_apply() {
        let base = MachineParams::default();
        base.validate().unwrap();
        let changed = base
            .with_overrides(&["x_axis.backlash_um=35".into(), "name=test rig".into()])
            .unwrap();
        assert_eq!(changed.x_axis.backlash_um, 35.0);
        assert_eq!(changed.name, "test rig");
        let changed = base
            .with_overrides(&["x_axis.straightness_nodes=7".into()])
            .unwrap();
        assert_eq!(changed.x_axis.straightness_nodes, 7);
    }

    #[test]
    fn bad_overrides_say_what_is_wrong() {
        let base = MachineParams::default();
        let err = base
            .with_overrides(&["x_axis.backlash=3".into()])
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("no such parameter") && err.contains("backlash_um"),
            "{err}"
        );
        let err = base
            .with_overrides(&["x_axis.stroke_mm=-1".into()])
            .unwrap_err()
            .to_string();
        assert!(err.contains("must be positive"), "{err}");
        let err = base
            .with_overrides(&["spindle=1".into()])
            .unwrap_err()
            .to_string();
        assert!(err.contains("group"), "{err}");
        assert!(base.with_overrides(&["nonsense".into()]).is_err());
    }
}
