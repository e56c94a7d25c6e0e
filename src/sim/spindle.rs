//! The spindle: speed ramp, bearing and cutting torques, motor losses, a four-node thermal
//! network (stator, front bearing, rear bearing, headstock housing) and the thermal elongation
//! of the spindle nose.

use super::effects::{Effect, EffectSet};
use super::machine::{CoolantParams, SpindleParams};
use super::physics::{
    MotorOperatingPoint, RPM_TO_RAD_PER_S, motor_operating_point, palmgren_torque_nm, smooth_sign,
    viscosity_cst,
};
use super::thermal::{StepInputs, ThermalNetwork};

const STATOR: usize = 0;
const FRONT: usize = 1;
const REAR: usize = 2;
const HOUSING: usize = 3;
const BED: usize = 4;

/// What the spindle is told during one sub-step.
#[derive(Debug, Clone, Copy)]
pub struct SpindleCommand {
    /// Speed command, rpm.
    pub speed_rpm: f64,
    /// Cutting torque at the spindle, N·m (0 when not cutting).
    pub cutting_torque_Nm: f64,
    /// Radial cutting load carried by the bearings, N.
    pub radial_load_N: f64,
}

/// The spindle's state at one instant, as instruments would read it (before noise).
#[derive(Debug, Clone, Copy, Default)]
pub struct SpindleReading {
    /// Motor speed, rpm.
    pub speed_rpm: f64,
    /// Motor torque, N·m.
    pub torque_Nm: f64,
    /// Motor current, A.
    pub current_A: f64,
    /// Load, % of rated torque.
    pub load_pct: f64,
    /// Spindle angle, degrees in [0, 360).
    pub position_deg: f64,
    /// Stator temperature, °C.
    pub stator_C: f64,
    /// Front bearing temperature, °C.
    pub front_bearing_C: f64,
    /// Rear bearing temperature, °C.
    pub rear_bearing_C: f64,
    /// Housing temperature, °C.
    pub housing_C: f64,
    /// Front bearing friction torque, N·m.
    pub front_bearing_torque_Nm: f64,
    /// Rear bearing friction torque, N·m.
    pub rear_bearing_torque_Nm: f64,
    /// Nose displacement since the start (tool calibration), µm.
    pub elongation_um: f64,
}

/// The spindle model.
#[derive(Debug, Clone)]
pub struct SpindleModel {
    params: SpindleParams,
    coolant: CoolantParams,
    effects: EffectSet,
    network: ThermalNetwork<5>,
    speed_rpm: f64,
    angle_deg: f64,
    /// Heat energy per node accumulated since the last thermal step, J.
    heat_J: [f64; 5],
    /// Speed integrated since the last thermal step, rpm·s (for the mean convection).
    speed_integral: f64,
    accumulated_s: f64,
    /// Temperatures at the tool calibration moment (the start).
    reference_C: [f64; 5],
    reading: SpindleReading,
}

/// Spindle-nose displacement relative to the tool, mm, from node temperatures `t` and their
/// values at tool calibration `reference`.
fn elongation_mm(p: &SpindleParams, t: &[f64; 5], reference: &[f64; 5]) -> f64 {
    let rise = |i: usize| t[i] - reference[i];
    let shaft = 0.5 * (rise(FRONT) + rise(REAR));
    p.expansion_per_K
        * (p.shaft_length_mm * (shaft - rise(BED))
            + p.housing_length_mm * (rise(HOUSING) - rise(BED)))
}

impl SpindleModel {
    /// A spindle soaked at `initial_C`.
    pub fn new(
        params: SpindleParams,
        coolant: CoolantParams,
        effects: EffectSet,
        initial_C: f64,
    ) -> Self {
        let inertia = effects.has(Effect::ThermalInertia);
        let structure = |value: f64| if inertia { value } else { 0.0 };
        let capacity = [
            params.stator_J_per_K,
            params.front_bearing_J_per_K,
            params.rear_bearing_J_per_K,
            structure(params.housing_J_per_K),
            structure(params.bed_J_per_K),
        ];
        SpindleModel {
            network: ThermalNetwork::new(capacity, initial_C),
            params,
            coolant,
            effects,
            speed_rpm: 0.0,
            angle_deg: 0.0,
            heat_J: [0.0; 5],
            speed_integral: 0.0,
            accumulated_s: 0.0,
            reference_C: [initial_C; 5],
            reading: SpindleReading {
                stator_C: initial_C,
                front_bearing_C: initial_C,
                rear_bearing_C: initial_C,
                housing_C: initial_C,
                ..SpindleReading::default()
            },
        }
    }

    /// Advances the mechanics by `dt` seconds and accumulates the heat they generate.
    pub fn substep(&mut self, dt: f64, command: SpindleCommand) -> SpindleReading {
        let p = &self.params;
        let max_change = p.acceleration_rpm_per_s * dt;
        let target = command.speed_rpm.clamp(0.0, p.motor.max_speed_rpm);
        let previous = self.speed_rpm;
        self.speed_rpm += (target - previous).clamp(-max_change, max_change);
        let n = self.speed_rpm;
        let omega = n * RPM_TO_RAD_PER_S;
        let alpha = (n - previous) * RPM_TO_RAD_PER_S / dt;
        self.angle_deg = (self.angle_deg + n * 6.0 * dt).rem_euclid(360.0);

        let temps = *self.network.temperatures();
        let viscous = self.effects.has(Effect::LubricantViscosity);
        let nu_front = viscosity_cst(&p.lubricant, temps[FRONT], viscous);
        let nu_rear = viscosity_cst(&p.lubricant, temps[REAR], viscous);
        let turning = smooth_sign(n, 1.0);
        // The front set carries most of the radial cutting load; model it as 70/30.
        let front_torque =
            palmgren_torque_nm(&p.front_bearing, nu_front, n, 0.7 * command.radial_load_N)
                * turning;
        let rear_torque =
            palmgren_torque_nm(&p.rear_bearing, nu_rear, n, 0.3 * command.radial_load_N) * turning;
        let drag = p.viscous_Nm_per_krpm * n / 1000.0;
        let cutting = if n > 1.0 {
            command.cutting_torque_Nm
        } else {
            0.0
        };
        let inertia = (p.inertia_kgm2 + p.motor.rotor_inertia_kgm2) * alpha;
        let torque = inertia + front_torque + rear_torque + drag + cutting;
        let energised = n > 0.5 || target > 0.0;
        let op: MotorOperatingPoint =
            motor_operating_point(&p.motor, torque, n, temps[STATOR], energised);

        self.heat_J[STATOR] += op.stator_heat_W(self.effects) * dt;
        self.heat_J[FRONT] += (front_torque * omega).abs() * dt;
        self.heat_J[REAR] += (rear_torque * omega).abs() * dt;
        self.speed_integral += n * dt;
        self.accumulated_s += dt;

        self.reading = SpindleReading {
            speed_rpm: n,
            torque_Nm: torque,
            current_A: op.current_A,
            load_pct: op.load_pct,
            position_deg: self.angle_deg,
            front_bearing_torque_Nm: front_torque,
            rear_bearing_torque_Nm: rear_torque,
            ..self.reading
        };
        self.reading
    }

    /// Integrates the thermal network over the sub-steps accumulated since the last call.
    pub fn thermal_step(&mut self, room_C: f64, coolant_C: f64, coolant_on: bool) {
        if self.accumulated_s <= 0.0 {
            return;
        }
        let p = &self.params;
        let dt = self.accumulated_s;
        let mean_rpm = self.speed_integral / dt;
        let convection = if self.effects.has(Effect::SpeedDependentCooling) {
            1.0 + p.speed_cooling_gain * (mean_rpm / p.motor.max_speed_rpm).max(0.0).powf(0.8)
        } else {
            1.0
        };
        let links = [
            (STATOR, HOUSING, p.stator_housing_W_per_K),
            (FRONT, HOUSING, p.front_bearing_housing_W_per_K),
            (REAR, HOUSING, p.rear_bearing_housing_W_per_K),
            (FRONT, REAR, p.shaft_W_per_K),
            (HOUSING, BED, p.housing_bed_W_per_K),
        ];
        let cooled = coolant_on && self.effects.has(Effect::Coolant);
        let mut environment = vec![
            (STATOR, p.stator_air_W_per_K * convection, room_C),
            (FRONT, p.bearing_air_W_per_K * convection, room_C),
            (REAR, p.bearing_air_W_per_K * convection, room_C),
            (HOUSING, p.housing_air_W_per_K, room_C),
            (BED, p.bed_air_W_per_K, room_C),
        ];
        if cooled {
            environment.push((HOUSING, self.coolant.spindle_jacket_W_per_K, coolant_C));
            environment.push((FRONT, self.coolant.spindle_bearing_W_per_K, coolant_C));
        }
        let heat = self.heat_J.map(|q| q / dt);
        self.network.step(
            dt,
            &StepInputs {
                links: &links,
                to_environment: &environment,
                heat,
            },
        );
        self.heat_J = [0.0; 5];
        self.speed_integral = 0.0;
        self.accumulated_s = 0.0;
        let t = *self.network.temperatures();
        let growth_mm = elongation_mm(p, &t, &self.reference_C);
        self.reading.stator_C = t[STATOR];
        self.reading.front_bearing_C = t[FRONT];
        self.reading.rear_bearing_C = t[REAR];
        self.reading.housing_C = t[HOUSING];
        self.reading.elongation_um = growth_mm * 1000.0;
    }

    /// The latest reading.
    pub fn reading(&self) -> SpindleReading {
        self.reading
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::machine::MachineParams;

    /// Shaft and housing 10 K warmer than the bed that carries the tool: α·(L_shaft + L_housing)·ΔT.
    #[test]
    fn warm_headstock_on_a_cold_bed_grows_alpha_l_delta_t() {
        let p = MachineParams::default().spindle;
        let reference = [20.0; 5];
        let warm = [25.0, 30.0, 30.0, 30.0, 20.0];
        let expected = p.expansion_per_K * (p.shaft_length_mm + p.housing_length_mm) * 10.0;
        assert!((elongation_mm(&p, &warm, &reference) - expected).abs() < 1e-15);
    }

    /// A machine soaked to a new room temperature grows as a whole: the tool moves with the
    /// nose and the elongation returns to zero.
    #[test]
    fn uniform_soak_cancels_between_nose_and_tool() {
        let m = MachineParams::default();
        let mut spindle =
            SpindleModel::new(m.spindle.clone(), m.coolant.clone(), EffectSet::all(), 20.0);
        let stop = SpindleCommand {
            speed_rpm: 0.0,
            cutting_torque_Nm: 0.0,
            radial_load_N: 0.0,
        };
        for _ in 0..(4 * 24 * 3600) {
            spindle.substep(1.0, stop);
            spindle.thermal_step(30.0, 30.0, false);
        }
        assert!((spindle.reading().housing_C - 30.0).abs() < 1e-3);
        let e = spindle.reading().elongation_um;
        assert!(e.abs() < 1e-3, "{e} µm");
    }

    /// Without copper loss the stator runs cooler at the same load; the torque is unchanged.
    #[test]
    fn copper_loss_heats_the_stator_without_changing_the_torque() {
        let m = MachineParams::default();
        let run = |effects: EffectSet| {
            let mut spindle =
                SpindleModel::new(m.spindle.clone(), m.coolant.clone(), effects, 20.0);
            let cut = SpindleCommand {
                speed_rpm: 1500.0,
                cutting_torque_Nm: 60.0,
                radial_load_N: 1500.0,
            };
            for _ in 0..3600 {
                spindle.substep(1.0, cut);
                spindle.thermal_step(20.0, 18.5, false);
            }
            spindle.reading()
        };
        let with = run(EffectSet::all());
        let without = run(EffectSet::all().without(Effect::CopperLoss));
        assert!(
            with.stator_C > without.stator_C + 3.0,
            "{} vs {}",
            with.stator_C,
            without.stator_C
        );
        assert!((with.torque_Nm - without.torque_Nm).abs() < 0.2);
    }
}
