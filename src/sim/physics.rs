//! Closed-form physics shared by the spindle and the feed axis: lubricant viscosity, rolling
//! bearing friction (Palmgren), ball-screw preload drag (catalogue formula), and the motor's
//! torque ↔ current and loss model.

use super::effects::{Effect, EffectSet};
use super::machine::{BearingParams, LubricantParams, MotorParams};

/// rpm → rad/s.
pub const RPM_TO_RAD_PER_S: f64 = std::f64::consts::PI / 30.0;

/// Kinematic viscosity, mm²/s, at `temperature_C`: ν₄₀ · exp(−k (T − 40)). With the effect off
/// the viscosity stays at its 40 °C value whatever the temperature.
pub fn viscosity_cst(
    lubricant: &LubricantParams,
    temperature_C: f64,
    temperature_dependent: bool,
) -> f64 {
    if temperature_dependent {
        lubricant.viscosity_40C_cSt
            * (-lubricant.temperature_coefficient_per_K * (temperature_C - 40.0)).exp()
    } else {
        lubricant.viscosity_40C_cSt
    }
}

/// Palmgren's bearing friction torque magnitude, N·m, at `speed_rpm` with lubricant viscosity
/// `viscosity_cst` and an external axial load on top of the preload.
///
/// M = M₀ + M₁ with M₀ = 10⁻⁷ f₀ (ν n)^(2/3) d_m³ (ν n ≥ 2000; 160·10⁻⁷ f₀ d_m³ below) and
/// M₁ = f₁ P₁ d_m, in N·mm with d_m in mm (SKF / Harris, "Rolling Bearing Analysis").
pub fn palmgren_torque_nm(
    bearing: &BearingParams,
    viscosity_cst: f64,
    speed_rpm: f64,
    axial_load_N: f64,
) -> f64 {
    let dm = bearing.pitch_diameter_mm;
    let nu_n = viscosity_cst * speed_rpm.abs();
    let m0 = if nu_n >= 2000.0 {
        1e-7 * bearing.f0 * nu_n.powf(2.0 / 3.0) * dm.powi(3)
    } else {
        160e-7 * bearing.f0 * dm.powi(3)
    };
    let p1 = bearing.preload_N + axial_load_N.abs();
    let m1 = bearing.f1 * p1 * dm;
    (m0 + m1) / 1000.0
}

/// Ball-screw preload drag torque, N·m: T_d = 0.05 (tan β)^(−1/2) F_a0 l / (2π) with lead
/// angle β = atan(l / (π d)) (THK / HIWIN catalogue formula).
pub fn screw_preload_drag_nm(preload_N: f64, lead_mm: f64, diameter_mm: f64) -> f64 {
    let tan_beta = lead_mm / (std::f64::consts::PI * diameter_mm);
    0.05 / tan_beta.sqrt() * preload_N * (lead_mm / 1000.0) / (2.0 * std::f64::consts::PI)
}

/// A smooth sign: ±1 away from zero, linear within ±`epsilon`. Friction torques use it so a
/// standing axis does not chatter between ±friction.
pub fn smooth_sign(x: f64, epsilon: f64) -> f64 {
    (x / epsilon).clamp(-1.0, 1.0)
}

/// What a motor draws and dissipates at one operating point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MotorOperatingPoint {
    /// Phase current, A rms.
    pub current_A: f64,
    /// Copper loss, W.
    pub copper_loss_W: f64,
    /// Iron loss, W.
    pub iron_loss_W: f64,
    /// Load, % of rated torque.
    pub load_pct: f64,
}

impl MotorOperatingPoint {
    /// Heat into the stator, W: the copper and iron losses the twin simulates.
    pub fn stator_heat_W(&self, effects: EffectSet) -> f64 {
        let copper = if effects.has(Effect::CopperLoss) {
            self.copper_loss_W
        } else {
            0.0
        };
        let iron = if effects.has(Effect::IronLoss) {
            self.iron_loss_W
        } else {
            0.0
        };
        copper + iron
    }
}

/// The motor at `torque_Nm` and `speed_rpm` with the stator at `stator_C`.
///
/// The current is the vector sum of the torque-producing part τ/K_t and the magnetising part
/// (present while the drive is energised). Copper loss is 3 R(T) I² with copper's resistance
/// rising 0.393 %/K; iron loss is hysteresis (∝ n) plus eddy currents (∝ n²).
pub fn motor_operating_point(
    motor: &MotorParams,
    torque_Nm: f64,
    speed_rpm: f64,
    stator_C: f64,
    energised: bool,
) -> MotorOperatingPoint {
    if !energised {
        return MotorOperatingPoint {
            current_A: 0.0,
            copper_loss_W: 0.0,
            iron_loss_W: 0.0,
            load_pct: 0.0,
        };
    }
    let iq = torque_Nm / motor.torque_constant_Nm_per_A;
    let current_A = (iq * iq + motor.magnetising_current_A.powi(2)).sqrt();
    let resistance = motor.phase_resistance_ohm * (1.0 + 0.00393 * (stator_C - 20.0));
    let krpm = speed_rpm.abs() / 1000.0;
    MotorOperatingPoint {
        current_A,
        copper_loss_W: 3.0 * resistance * current_A * current_A,
        iron_loss_W: motor.hysteresis_W_per_krpm * krpm + motor.eddy_W_per_krpm2 * krpm * krpm,
        load_pct: 100.0 * torque_Nm / motor.rated_torque_Nm,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::machine::MachineParams;

    #[test]
    fn screw_drag_matches_the_catalogue_example() {
        // Ø32 × 10, 1,500 N preload: tan β = 10 / (π·32) = 0.0995 → T_d ≈ 0.378 N·m.
        let t = screw_preload_drag_nm(1500.0, 10.0, 32.0);
        assert!((t - 0.0378 * 10.0).abs() < 0.002, "{t}");
    }

    #[test]
    fn spindle_bearing_heat_is_the_papers_magnitude_at_top_speed() {
        // Paper Fig. 3(a): 138 W front, 120 W rear bearing heat.
        let s = MachineParams::default().spindle;
        let nu = viscosity_cst(&s.lubricant, 35.0, true);
        let omega = 3500.0 * RPM_TO_RAD_PER_S;
        let front = palmgren_torque_nm(&s.front_bearing, nu, 3500.0, 0.0) * omega;
        let rear = palmgren_torque_nm(&s.rear_bearing, nu, 3500.0, 0.0) * omega;
        assert!((110.0..170.0).contains(&front), "front {front} W");
        assert!((95.0..150.0).contains(&rear), "rear {rear} W");
    }

    #[test]
    fn warmer_oil_means_less_friction() {
        let s = MachineParams::default().spindle;
        let cold = palmgren_torque_nm(
            &s.front_bearing,
            viscosity_cst(&s.lubricant, 20.0, true),
            2000.0,
            0.0,
        );
        let warm = palmgren_torque_nm(
            &s.front_bearing,
            viscosity_cst(&s.lubricant, 45.0, true),
            2000.0,
            0.0,
        );
        assert!(warm < cold);
        let fixed = viscosity_cst(&s.lubricant, 45.0, false);
        assert_eq!(fixed, s.lubricant.viscosity_40C_cSt);
    }

    #[test]
    fn motor_current_is_the_vector_sum_and_copper_loss_is_3_i2_r() {
        let m = MachineParams::default().x_axis.motor;
        let op = motor_operating_point(&m, 2.4, 1000.0, 20.0, true);
        let iq = 2.4 / m.torque_constant_Nm_per_A;
        let i = (iq * iq + m.magnetising_current_A.powi(2)).sqrt();
        assert!((op.current_A - i).abs() < 1e-12);
        assert!((op.copper_loss_W - 3.0 * m.phase_resistance_ohm * i * i).abs() < 1e-12);
        assert!((op.load_pct - 30.0).abs() < 1e-12);
        assert_eq!(
            motor_operating_point(&m, 2.4, 1000.0, 20.0, false).current_A,
            0.0
        );
    }
}
