//! The ball-screw feed axis: motion planning, servo following, the backlash dead zone between
//! nut and table, friction and load torques split into support-bearing and nut torque, motor
//! losses, a nine-node thermal network and the thermal bending of the bed that gives the
//! straightness of the table's path at each node along the stroke.

use super::effects::{Effect, EffectSet};
use super::machine::{CoolantParams, FeedAxisParams};
use super::physics::{
    motor_operating_point, palmgren_torque_nm, screw_preload_drag_nm, smooth_sign, viscosity_cst,
};
use super::scenario::{Move, TrapezoidMove, XActivity};
use super::thermal::{StepInputs, ThermalNetwork};

const STATOR: usize = 0;
const FLANGE: usize = 1;
const FRONT: usize = 2;
const BACK: usize = 3;
const NUT: usize = 4;
const SCREW: usize = 5;
const BED_FRONT: usize = 6;
const BED_BACK: usize = 7;
const BASE: usize = 8;
const NODES: usize = 9;

const STEEL_DENSITY: f64 = 7850.0;
const GRAVITY: f64 = 9.81;

/// A move being executed, with when it started.
#[derive(Debug, Clone, Copy)]
struct ActiveMove {
    start_s: f64,
    profile: TrapezoidMove,
    end_s: f64,
    dwell_end_s: f64,
    cutting: bool,
}

/// Turns block activities into a continuous commanded trajectory.
#[derive(Debug, Clone)]
struct MotionPlanner {
    current: Option<ActiveMove>,
    previous: Option<ActiveMove>,
    rest_mm: f64,
    /// Next index into an explicit move list, and the direction of the next traverse/facing move.
    list_index: usize,
    forward: bool,
    acceleration: f64,
    rapid_mm_per_s: f64,
    /// When the planner was last asked for a move.
    checked_s: f64,
}

impl MotionPlanner {
    /// Commanded (position, velocity, acceleration, cutting) at time `t`.
    fn at(&self, t: f64) -> (f64, f64, f64, bool) {
        for m in [self.current, self.previous].into_iter().flatten() {
            if t >= m.start_s {
                let (x, v, a) = m.profile.at(t - m.start_s);
                return (x, v, a, m.cutting && t < m.end_s);
            }
        }
        (self.rest_mm, 0.0, 0.0, false)
    }

    /// True while a move or its dwell is still running at `t`.
    fn busy(&self, t: f64) -> bool {
        self.current.is_some_and(|m| t < m.dwell_end_s)
    }

    /// Starts the next move of `activity` at time `t` if the axis is free. Returns false when an
    /// explicit move list has been played to the end.
    fn plan(
        &mut self,
        t: f64,
        activity: &XActivity,
        feed_per_rev_mm: f64,
        spindle_rpm: f64,
    ) -> bool {
        let checked_s = std::mem::replace(&mut self.checked_s, t);
        if self.busy(t) {
            return true;
        }
        // The controller starts the next move the moment the axis is free, not at the next
        // sub-step: quantising every move to the sub-step grid would make cycle times whole
        // multiples of it, locked in phase to the recording's sample times, and a 1 Hz recording
        // would then see the same instant of every cycle (aliasing that a real machine does not
        // have).
        let start_s = match self.current {
            Some(m) if m.dwell_end_s > checked_s => m.dwell_end_s,
            _ => t,
        };
        let here = self
            .current
            .map_or(self.rest_mm, |m| m.profile.at(f64::INFINITY).0);
        self.rest_mm = here;
        let next = match activity {
            XActivity::Hold { at_mm } => ((here - at_mm).abs() > 1e-9).then_some(Move {
                target_mm: *at_mm,
                feed_mm_per_min: self.rapid_mm_per_s * 60.0,
                dwell_s: 0.0,
                cutting: false,
            }),
            XActivity::Traverse {
                from_mm,
                to_mm,
                feed_mm_per_min,
                dwell_s,
            } => {
                let at_end = (here - to_mm).abs() < 1e-9;
                let at_start = (here - from_mm).abs() < 1e-9;
                let target = if !at_end && (at_start || self.forward) {
                    *to_mm
                } else {
                    *from_mm
                };
                self.forward = target != *from_mm;
                Some(Move {
                    target_mm: target,
                    feed_mm_per_min: *feed_mm_per_min,
                    dwell_s: *dwell_s,
                    cutting: false,
                })
            }
            XActivity::Facing { from_mm, to_mm } => {
                if (here - from_mm).abs() < 1e-9 {
                    let feed = (feed_per_rev_mm * spindle_rpm).max(1.0);
                    Some(Move {
                        target_mm: *to_mm,
                        feed_mm_per_min: feed,
                        dwell_s: 0.2,
                        cutting: spindle_rpm > 1.0,
                    })
                } else {
                    Some(Move {
                        target_mm: *from_mm,
                        feed_mm_per_min: self.rapid_mm_per_s * 60.0,
                        dwell_s: 0.3,
                        cutting: false,
                    })
                }
            }
            XActivity::Moves(list) => {
                let m = list.get(self.list_index).copied();
                self.list_index += 1;
                if m.is_none() {
                    return false;
                }
                m
            }
        };
        if let Some(m) = next {
            let speed = (m.feed_mm_per_min / 60.0).min(self.rapid_mm_per_s);
            let profile = TrapezoidMove::new(here, m.target_mm - here, speed, self.acceleration);
            let end_s = start_s + profile.duration_s();
            self.previous = self.current;
            self.current = Some(ActiveMove {
                start_s,
                profile,
                end_s,
                dwell_end_s: end_s + m.dwell_s,
                cutting: m.cutting,
            });
        }
        true
    }

    /// A new block starts: explicit move lists start from their first move.
    fn new_block(&mut self) {
        self.list_index = 0;
    }
}

/// What acts on the axis during one sub-step besides the program.
#[derive(Debug, Clone, Copy)]
pub struct FeedAxisLoad {
    /// Feed (thrust) force from the cut while a cutting move runs, N.
    pub cutting_force_N: f64,
}

/// The axis's state at one instant, before noise.
#[derive(Debug, Clone, Default)]
pub struct FeedAxisReading {
    /// Commanded position, mm.
    pub command_mm: f64,
    /// Motor encoder position, mm (semi-closed loop).
    pub position_mm: f64,
    /// Table position, mm.
    pub table_mm: f64,
    /// Motor speed, rpm.
    pub speed_rpm: f64,
    /// Motor torque, N·m.
    pub torque_Nm: f64,
    /// Motor current, A.
    pub current_A: f64,
    /// Load, % of rated torque.
    pub load_pct: f64,
    /// Front (fixed-side) support bearing torque, N·m.
    pub front_bearing_torque_Nm: f64,
    /// Back (floating-side) support bearing torque, N·m.
    pub back_bearing_torque_Nm: f64,
    /// Nut torque (preload drag plus thrust), N·m.
    pub nut_torque_Nm: f64,
    /// Nut preload at the current position, N.
    pub nut_preload_N: f64,
    /// Axial load through nut and fixed bearing, N.
    pub axial_load_N: f64,
    /// A cutting move is running.
    pub cutting: bool,
    /// Node temperatures, °C: stator, motor flange, front bearing, back bearing, nut.
    pub stator_C: f64,
    /// Motor flange, °C.
    pub flange_C: f64,
    /// Front bearing, °C.
    pub front_bearing_C: f64,
    /// Back bearing, °C.
    pub back_bearing_C: f64,
    /// Nut, °C.
    pub nut_C: f64,
    /// Screw, °C.
    pub screw_C: f64,
    /// Horizontal straightness deviation per node, µm.
    pub straightness_h_um: Vec<f64>,
    /// Vertical straightness deviation per node, µm.
    pub straightness_v_um: Vec<f64>,
}

/// The feed axis model.
#[derive(Debug, Clone)]
pub struct FeedAxisModel {
    params: FeedAxisParams,
    coolant: CoolantParams,
    effects: EffectSet,
    planner: MotionPlanner,
    network: ThermalNetwork<NODES>,
    table_mm: f64,
    /// Extra motor travel at reversals, mm (the controller's backlash compensation).
    backlash_compensation_mm: f64,
    last_direction: f64,
    screw_inertia_kgm2: f64,
    heat_J: [f64; NODES],
    speed_integral: f64,
    accumulated_s: f64,
    /// Table position integrated over the thermal step (where the nut's heat enters the bed).
    position_integral: f64,
    previous_motor_mm: f64,
    reading: FeedAxisReading,
}

impl FeedAxisModel {
    /// An axis soaked at `initial_C`, standing at `start_mm`.
    pub fn new(
        params: FeedAxisParams,
        coolant: CoolantParams,
        effects: EffectSet,
        initial_C: f64,
        start_mm: f64,
    ) -> Self {
        let c = &params.capacity_J_per_K;
        let inertia = effects.has(Effect::ThermalInertia);
        let structure = |value: f64| if inertia { value } else { 0.0 };
        let capacity = [
            c.stator,
            c.motor_flange,
            c.front_bearing,
            c.back_bearing,
            c.nut,
            structure(c.screw),
            structure(c.bed_front),
            structure(c.bed_back),
            structure(c.base),
        ];
        let d = params.screw_diameter_mm / 1000.0;
        let screw_inertia_kgm2 =
            STEEL_DENSITY * std::f64::consts::PI * d.powi(4) * (params.screw_length_mm / 1000.0)
                / 32.0;
        let nodes = params.straightness_nodes;
        let planner = MotionPlanner {
            current: None,
            previous: None,
            rest_mm: start_mm,
            list_index: 0,
            forward: true,
            acceleration: params.acceleration_mm_per_s2,
            rapid_mm_per_s: params.rapid_mm_per_min / 60.0,
            checked_s: f64::NEG_INFINITY,
        };
        FeedAxisModel {
            planner,
            network: ThermalNetwork::new(capacity, initial_C),
            // Start with the lash taken up on the negative side, as after a homing move.
            table_mm: start_mm,
            backlash_compensation_mm: 0.0,
            last_direction: 1.0,
            screw_inertia_kgm2,
            heat_J: [0.0; NODES],
            speed_integral: 0.0,
            accumulated_s: 0.0,
            position_integral: 0.0,
            previous_motor_mm: start_mm,
            reading: FeedAxisReading {
                command_mm: start_mm,
                position_mm: start_mm,
                table_mm: start_mm,
                stator_C: initial_C,
                flange_C: initial_C,
                front_bearing_C: initial_C,
                back_bearing_C: initial_C,
                nut_C: initial_C,
                screw_C: initial_C,
                straightness_h_um: vec![0.0; nodes],
                straightness_v_um: vec![0.0; nodes],
                ..FeedAxisReading::default()
            },
            params,
            coolant,
            effects,
        }
    }

    /// Sets the controller's backlash compensation, µm: extra motor travel at each reversal.
    pub fn set_backlash_compensation_um(&mut self, value_um: f64) {
        self.backlash_compensation_mm = value_um.max(0.0) / 1000.0;
    }

    /// A new program block begins.
    pub fn new_block(&mut self) {
        self.planner.new_block();
    }

    /// Plans the next move if the axis is free. False when an explicit move list is finished.
    pub fn plan(
        &mut self,
        t: f64,
        activity: &XActivity,
        feed_per_rev_mm: f64,
        spindle_rpm: f64,
    ) -> bool {
        self.planner.plan(t, activity, feed_per_rev_mm, spindle_rpm)
    }

    /// True while a move or dwell is running.
    pub fn busy(&self, t: f64) -> bool {
        self.planner.busy(t)
    }

    /// Advances the mechanics to time `t` (a sub-step of `dt`) and accumulates heat.
    pub fn substep(&mut self, t: f64, dt: f64, load: FeedAxisLoad) -> &FeedAxisReading {
        let p = &self.params;
        let lead_m = p.screw_lead_mm / 1000.0;
        let (command_mm, command_v, _, _) = self.planner.at(t);
        let lag = 1.0 / p.position_gain_per_s;
        let (mut motor_mm, motor_v, motor_a, cutting) = self.planner.at(t - lag);
        // Backlash compensation: the controller adds half the compensation in the direction of
        // travel, switching at each commanded reversal.
        if command_v.abs() > 1e-9 {
            self.last_direction = command_v.signum();
        }
        motor_mm += self.last_direction * 0.5 * self.backlash_compensation_mm;
        let motor_step_v = (motor_mm - self.previous_motor_mm) / dt;
        self.previous_motor_mm = motor_mm;
        // Velocity used for friction: the planned one, plus the compensation jump spread over
        // the sub-step (it is a real motion of the motor).
        let motor_v = if (motor_step_v - motor_v).abs() > 1e-6 {
            motor_step_v
        } else {
            motor_v
        };

        // Dead zone between nut and table.
        let half_gap = if self.effects.has(Effect::Backlash) {
            0.5 * p.backlash_um / 1000.0
        } else {
            0.0
        };
        let gap = motor_mm - self.table_mm;
        let engaged = if gap > half_gap {
            self.table_mm = motor_mm - half_gap;
            true
        } else if gap < -half_gap {
            self.table_mm = motor_mm + half_gap;
            true
        } else {
            false
        };
        let (table_v, table_a) = if engaged {
            (motor_v, motor_a)
        } else {
            (0.0, 0.0)
        };

        let omega = motor_v / lead_m * 2.0 * std::f64::consts::PI / 1000.0;
        let alpha = motor_a / lead_m * 2.0 * std::f64::consts::PI / 1000.0;
        let speed_rpm = motor_v / p.screw_lead_mm * 60.0;
        let direction = smooth_sign(motor_v, 0.01);
        let table_direction = smooth_sign(table_v, 0.01);

        // Table-side forces, through the nut.
        let mut table_force = 0.0;
        if engaged {
            table_force += p.table_mass_kg * table_a / 1000.0;
            table_force +=
                p.guide_friction_coefficient * p.table_mass_kg * GRAVITY * table_direction;
            table_force += p.viscous_N_per_mm_per_s * table_v;
            if self.effects.has(Effect::CoulombReversal) {
                let stribeck =
                    p.stribeck_friction_N * (-(table_v.abs() / p.stribeck_speed_mm_per_s)).exp();
                table_force += (p.seal_friction_N + stribeck) * table_direction;
            }
        }
        let cut_force = if cutting { load.cutting_force_N } else { 0.0 };
        // The feed force resists the feed motion.
        table_force += cut_force * direction;
        let axial_load = table_force;

        let temps = *self.network.temperatures();
        let viscous = self.effects.has(Effect::LubricantViscosity);
        let front_torque = palmgren_torque_nm(
            &p.front_bearing,
            viscosity_cst(&p.lubricant, temps[FRONT], viscous),
            speed_rpm,
            axial_load,
        ) * direction;
        let back_torque = palmgren_torque_nm(
            &p.back_bearing,
            viscosity_cst(&p.lubricant, temps[BACK], viscous),
            speed_rpm,
            0.0,
        ) * direction;
        let position_factor = if self.effects.has(Effect::PositionDependent) {
            let s = (self.table_mm / p.stroke_mm).clamp(0.0, 1.0);
            1.0 - p.nut_preload_variation * (std::f64::consts::PI * s).sin()
        } else {
            1.0 - p.nut_preload_variation * 2.0 / std::f64::consts::PI
        };
        let nut_preload = p.nut_preload_N * position_factor;
        let preload_drag =
            screw_preload_drag_nm(nut_preload, p.screw_lead_mm, p.screw_diameter_mm) * direction;
        let thrust_ideal = axial_load * lead_m / (2.0 * std::f64::consts::PI);
        let thrust = if thrust_ideal * motor_v >= 0.0 {
            thrust_ideal / p.screw_efficiency
        } else {
            thrust_ideal * p.screw_efficiency
        };
        let nut_torque = preload_drag + thrust;
        let inertia_torque = (p.motor.rotor_inertia_kgm2 + self.screw_inertia_kgm2) * alpha;
        let torque = inertia_torque + front_torque + back_torque + nut_torque;
        let op = motor_operating_point(&p.motor, torque, speed_rpm, temps[STATOR], true);

        self.heat_J[STATOR] += op.stator_heat_W(self.effects) * dt;
        self.heat_J[FRONT] += (front_torque * omega).abs() * dt;
        self.heat_J[BACK] += (back_torque * omega).abs() * dt;
        let nut_loss = (preload_drag * omega).abs() + (thrust - thrust_ideal).abs() * omega.abs();
        self.heat_J[NUT] += nut_loss * dt;
        // Guideway and seal friction heat the bed where the table is.
        let guide_heat = if engaged {
            ((table_force - cut_force * direction - p.table_mass_kg * table_a / 1000.0) * table_v
                / 1000.0)
                .abs()
        } else {
            0.0
        };
        let s = (self.table_mm / p.stroke_mm).clamp(0.0, 1.0);
        self.heat_J[BED_FRONT] += guide_heat * (1.0 - s) * dt;
        self.heat_J[BED_BACK] += guide_heat * s * dt;
        self.speed_integral += speed_rpm.abs() * dt;
        self.position_integral += s * dt;
        self.accumulated_s += dt;

        let r = &mut self.reading;
        r.command_mm = command_mm;
        r.position_mm = motor_mm;
        r.table_mm = self.table_mm;
        r.speed_rpm = speed_rpm;
        r.torque_Nm = torque;
        r.current_A = op.current_A;
        r.load_pct = op.load_pct;
        r.front_bearing_torque_Nm = front_torque;
        r.back_bearing_torque_Nm = back_torque;
        r.nut_torque_Nm = nut_torque;
        r.nut_preload_N = nut_preload;
        r.axial_load_N = axial_load;
        r.cutting = cutting;
        &self.reading
    }

    /// Integrates the thermal network over the accumulated sub-steps and updates straightness.
    pub fn thermal_step(&mut self, room_C: f64, coolant_C: f64, coolant_on: bool) {
        if self.accumulated_s <= 0.0 {
            return;
        }
        let p = &self.params;
        let g = &p.conductance_W_per_K;
        let dt = self.accumulated_s;
        let mean_rpm = self.speed_integral / dt;
        let rapid_rpm = p.rapid_mm_per_min / p.screw_lead_mm;
        let convection = if self.effects.has(Effect::SpeedDependentCooling) {
            1.0 + g.speed_cooling_gain * (mean_rpm / rapid_rpm).clamp(0.0, 1.0).powf(0.8)
        } else {
            1.0
        };
        let nut_share = if self.effects.has(Effect::PositionDependent) {
            self.position_integral / dt
        } else {
            0.5
        };
        let links = [
            (STATOR, FLANGE, g.stator_flange),
            (FLANGE, BED_FRONT, g.flange_bed_front),
            (FRONT, BED_FRONT, g.front_bearing_bed_front),
            (FRONT, SCREW, g.front_bearing_screw),
            (BACK, BED_BACK, g.back_bearing_bed_back),
            (BACK, SCREW, g.back_bearing_screw),
            (NUT, SCREW, g.nut_screw),
            (NUT, BED_FRONT, g.nut_bed * (1.0 - nut_share)),
            (NUT, BED_BACK, g.nut_bed * nut_share),
            (BED_FRONT, BED_BACK, g.bed_front_bed_back),
            (BED_FRONT, BASE, g.bed_front_base),
            (BED_BACK, BASE, g.bed_back_base),
        ];
        let mut environment = vec![
            (STATOR, g.stator_air, room_C),
            (FLANGE, g.flange_air, room_C),
            (NUT, g.nut_air * convection, room_C),
            (SCREW, g.screw_air * convection, room_C),
            (BED_FRONT, g.bed_air, room_C),
            (BED_BACK, g.bed_air, room_C),
            (BASE, g.base_air, room_C),
        ];
        if coolant_on && self.effects.has(Effect::Coolant) {
            environment.push((BED_FRONT, 0.5 * self.coolant.bed_W_per_K, coolant_C));
            environment.push((BED_BACK, 0.5 * self.coolant.bed_W_per_K, coolant_C));
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
        self.heat_J = [0.0; NODES];
        self.speed_integral = 0.0;
        self.position_integral = 0.0;
        self.accumulated_s = 0.0;

        let t = *self.network.temperatures();
        let r = &mut self.reading;
        r.stator_C = t[STATOR];
        r.flange_C = t[FLANGE];
        r.front_bearing_C = t[FRONT];
        r.back_bearing_C = t[BACK];
        r.nut_C = t[NUT];
        r.screw_C = t[SCREW];
        straightness(p, &t, &mut r.straightness_h_um, &mut r.straightness_v_um);
    }

    /// The latest reading.
    pub fn reading(&self) -> &FeedAxisReading {
        &self.reading
    }
}

/// Thermal bending of the bed under the stroke, per node, µm.
///
/// The bed is a beam of length L on supports at its ends. A temperature difference ΔT across a
/// section of depth h bends it with curvature κ = α ΔT / h. With ΔT varying linearly from the
/// motor end (κ₀) to the far end (κ₁), w'' = −κ and w(0) = w(L) = 0 give
/// w(s) = κ₀ s (L − s) / 2 + (κ₁ − κ₀) s (L² − s²) / (6 L).
/// Heat enters the bed where the motor and the bearings are bolted to it (the paper's reason
/// why straightness follows motor and bearing temperatures): the top of the section at each end
/// runs a share of the mounted parts' temperature rise above the base. Vertically both mounts
/// sit on top; horizontally the motor and screw are on one side of the bed, so mostly the motor
/// flange pulls that side.
fn straightness(p: &FeedAxisParams, t: &[f64; NODES], h_um: &mut [f64], v_um: &mut [f64]) {
    const ALPHA: f64 = 11.0e-6; // cast iron, 1/K
    /// Share of a mounted part's rise over the base that reaches the bed surface under it.
    const MOUNT_SHARE: f64 = 1.0;
    let length = p.bed_length_mm / 1000.0;
    let offset = 0.5 * (p.bed_length_mm - p.stroke_mm) / 1000.0;
    let deflection = |k0: f64, k1: f64, s: f64| {
        k0 * s * (length - s) / 2.0 + (k1 - k0) * s * (length * length - s * s) / (6.0 * length)
    };
    let height = p.bed_height_mm / 1000.0;
    let width = p.bed_width_mm / 1000.0;
    let rise = |i: usize| MOUNT_SHARE * (t[i] - t[BASE]);
    let kv0 = ALPHA * 0.5 * (rise(FLANGE) + rise(FRONT)) / height;
    let kv1 = ALPHA * rise(BACK) / height;
    let kh0 = ALPHA * (0.8 * rise(FLANGE) + 0.2 * rise(FRONT)) / width;
    let kh1 = ALPHA * 0.3 * rise(BACK) / width;
    let nodes = h_um.len();
    for k in 0..nodes {
        let s = offset + (p.stroke_mm / 1000.0) * k as f64 / (nodes - 1) as f64;
        v_um[k] = deflection(kv0, kv1, s) * 1e6;
        h_um[k] = deflection(kh0, kh1, s) * 1e6;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::machine::MachineParams;

    fn axis(effects: EffectSet) -> FeedAxisModel {
        let m = MachineParams::default();
        FeedAxisModel::new(m.x_axis, m.coolant, effects, 20.0, 100.0)
    }

    /// Constant-velocity move, nothing but friction: torque = bearing drags + preload drag +
    /// (guide + seal friction + viscous) · lead / (2π η), with no inertia term.
    #[test]
    fn friction_only_move_gives_the_closed_form_torque() {
        let machine = MachineParams::default();
        let p = machine.x_axis.clone();
        let mut x = axis(EffectSet::all().without(Effect::Backlash));
        let activity = XActivity::Traverse {
            from_mm: 100.0,
            to_mm: 300.0,
            feed_mm_per_min: 3000.0,
            dwell_s: 1.0,
        };
        let dt = 0.001;
        let mut t = 0.0;
        x.plan(t, &activity, 0.0, 0.0);
        // Mid-move at constant speed (accel phase lasts 25 ms).
        while t < 2.0 {
            t += dt;
            x.substep(
                t,
                dt,
                FeedAxisLoad {
                    cutting_force_N: 0.0,
                },
            );
        }
        let r = x.reading().clone();
        let v = 50.0; // mm/s
        let n = v / p.screw_lead_mm * 60.0;
        let nu = viscosity_cst(&p.lubricant, 20.0, true);
        let s = r.table_mm / p.stroke_mm;
        let preload =
            p.nut_preload_N * (1.0 - p.nut_preload_variation * (std::f64::consts::PI * s).sin());
        let force = p.guide_friction_coefficient * p.table_mass_kg * GRAVITY
            + p.viscous_N_per_mm_per_s * v
            + p.seal_friction_N
            + p.stribeck_friction_N * (-(v / p.stribeck_speed_mm_per_s)).exp();
        let expected = palmgren_torque_nm(&p.front_bearing, nu, n, force)
            + palmgren_torque_nm(&p.back_bearing, nu, n, 0.0)
            + screw_preload_drag_nm(preload, p.screw_lead_mm, p.screw_diameter_mm)
            + force * p.screw_lead_mm / 1000.0 / (2.0 * std::f64::consts::PI) / p.screw_efficiency;
        assert!((r.speed_rpm - n).abs() < 1e-9, "{}", r.speed_rpm);
        assert!(
            (r.torque_Nm - expected).abs() < 1e-9,
            "{} vs {expected}",
            r.torque_Nm
        );
    }

    /// Inside the dead zone the table stands still and the motor torque drops by the table's
    /// friction share; the encoder (motor) position moves the full amount.
    #[test]
    fn small_reversal_inside_backlash_does_not_move_the_table() {
        let mut x = axis(EffectSet::all());
        let backlash_mm = MachineParams::default().x_axis.backlash_um / 1000.0;
        let moves = XActivity::Moves(vec![
            Move {
                target_mm: 101.0,
                feed_mm_per_min: 60.0,
                dwell_s: 0.1,
                cutting: false,
            },
            Move {
                target_mm: 101.0 - 0.5 * backlash_mm,
                feed_mm_per_min: 20.0,
                dwell_s: 0.1,
                cutting: false,
            },
        ]);
        let (dt, mut t) = (0.0005, 0.0);
        let mut table_after_first = None;
        while t < 2.0 {
            t += dt;
            x.plan(t, &moves, 0.0, 0.0);
            x.substep(
                t,
                dt,
                FeedAxisLoad {
                    cutting_force_N: 0.0,
                },
            );
            if table_after_first.is_none() && t > 1.15 {
                table_after_first = Some(x.reading().table_mm);
            }
        }
        let r = x.reading();
        assert!((r.position_mm - (101.0 - 0.5 * backlash_mm)).abs() < 1e-9);
        assert_eq!(
            Some(r.table_mm),
            table_after_first,
            "table moved inside the lash"
        );
    }
}
