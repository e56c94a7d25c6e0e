//! The twin: runs a scenario on the machine model and produces recording rows.

use super::SimError;
use super::effects::{Effect, EffectSet};
use super::feed_axis::{FeedAxisLoad, FeedAxisModel};
use super::machine::MachineParams;
use super::measurement::{ColumnMeasurement, MeasurementChain, MeasurementSettings};
use super::scenario::{Block, ScenarioGenerator, ScenarioKind, XActivity};
use super::spindle::{SpindleCommand, SpindleModel};
use crate::signal::channel::{
    AMBIENT, AxisId, COOLANT, CUT_DEPTH, Quantity, TIME, axis_column, reference_column,
};
use crate::signal::{Recording, Schema};

/// Longest mechanical sub-step, s: resolves acceleration phases and short rapid moves well
/// enough for their heat, while a simulated day still runs in a fraction of a second.
const MAX_SUBSTEP_S: f64 = 0.05;
/// Thermal networks are integrated at least this often, s.
const THERMAL_STEP_S: f64 = 1.0;

/// Everything that defines a twin run.
#[derive(Debug, Clone)]
pub struct TwinConfig {
    /// The machine.
    pub machine: MachineParams,
    /// Which effects are simulated.
    pub effects: EffectSet,
    /// The program.
    pub scenario: ScenarioKind,
    /// Program length, hours; `None` runs until the scenario ends (endless for production and
    /// DOE, which repeat day after day).
    pub hours: Option<f64>,
    /// Output sample rate, Hz.
    pub rate_hz: f64,
    /// Seed of the program and of the noise.
    pub seed: u64,
}

impl TwinConfig {
    /// The default machine with every effect, for `scenario` at its usual rate.
    pub fn new(scenario: ScenarioKind, hours: Option<f64>, seed: u64) -> Self {
        TwinConfig {
            machine: MachineParams::default(),
            effects: EffectSet::all(),
            scenario,
            hours,
            rate_hz: scenario.default_rate_hz(),
            seed,
        }
    }
}

/// Where an output column's value comes from.
#[derive(Debug, Clone, Copy)]
enum Source {
    Time,
    SpindleSpeed,
    SpindleTorque,
    SpindleCurrent,
    SpindleLoad,
    SpindleStator,
    SpindlePosition,
    XCommand,
    XPosition,
    XSpeed,
    XTorque,
    XCurrent,
    XLoad,
    XStator,
    Ambient,
    Coolant,
    CutDepth,
    SpindleElongation,
    SpindleFrontBearingTemp,
    SpindleRearBearingTemp,
    SpindleHousingTemp,
    SpindleFrontBearingTorque,
    SpindleRearBearingTorque,
    XFlangeTemp,
    XFrontBearingTemp,
    XBackBearingTemp,
    XNutTemp,
    XScrewTemp,
    XFrontBearingTorque,
    XBackBearingTorque,
    XNutTorque,
    XNutPreload,
    XAxialLoad,
    XTablePosition,
    XBacklash,
    StraightnessH(usize),
    StraightnessV(usize),
}

/// The running twin. Call [`Twin::next_row`] for each sample.
pub struct Twin {
    config: TwinConfig,
    schema: Schema,
    sources: Vec<Source>,
    measurement: MeasurementChain,
    program: ScenarioGenerator,
    block: Option<Block>,
    block_end_s: f64,
    spindle: SpindleModel,
    x: FeedAxisModel,
    /// Rows emitted so far; time is `sample × dt` (never accumulated, so it stays exact).
    sample: u64,
    t_s: f64,
    dt_s: f64,
    thermal_accumulated_s: f64,
    room_C: f64,
    cut_depth_mm: f64,
    finished: bool,
    program_end_s: f64,
    truth: Vec<f64>,
}

impl Twin {
    /// Builds a twin; fails on invalid parameters or rates.
    pub fn new(config: TwinConfig) -> Result<Twin, SimError> {
        config
            .machine
            .validate()
            .map_err(SimError::InvalidMachine)?;
        if !(config.rate_hz.is_finite() && config.rate_hz > 0.0 && config.rate_hz <= 20_000.0) {
            return Err(SimError::InvalidRate(config.rate_hz));
        }
        if let Some(h) = config.hours
            && !(h.is_finite() && h > 0.0)
        {
            return Err(SimError::InvalidHours(h));
        }
        let m = &config.machine;
        let (names, columns, sources) = layout(m);
        let schema =
            Schema::new(names, "twin").map_err(|e| SimError::InvalidMachine(e.to_string()))?;
        let dt_s = 1.0 / config.rate_hz;
        let effects = config.effects;
        let measurement = MeasurementChain::new(
            columns,
            MeasurementSettings {
                dt_s,
                noise_scale: m.measurement.noise_scale,
                correlated_fraction: m.measurement.correlated_fraction,
                correlation_time_s: m.measurement.correlation_time_s,
                delay_s: if effects.has(Effect::SignalDelay) {
                    m.measurement.delay_s
                } else {
                    0.0
                },
                offset: if effects.has(Effect::SensorOffsetDrift) {
                    m.measurement.offset
                } else {
                    0.0
                },
                drift_per_hour: if effects.has(Effect::SensorOffsetDrift) {
                    m.measurement.drift_per_hour
                } else {
                    0.0
                },
            },
            config.seed,
        );
        let program = ScenarioGenerator::new(config.scenario, m, config.seed, config.hours);
        let room_C = room_temperature(m, effects, 0.0);
        let spindle = SpindleModel::new(m.spindle.clone(), m.coolant.clone(), effects, room_C);
        let x = FeedAxisModel::new(
            m.x_axis.clone(),
            m.coolant.clone(),
            effects,
            room_C,
            0.5 * m.x_axis.stroke_mm,
        );
        let mut twin = Twin {
            truth: vec![0.0; sources.len()],
            sources,
            schema,
            measurement,
            program,
            block: None,
            block_end_s: 0.0,
            spindle,
            x,
            sample: 0,
            t_s: 0.0,
            dt_s,
            thermal_accumulated_s: 0.0,
            room_C,
            cut_depth_mm: 0.0,
            finished: false,
            program_end_s: f64::INFINITY,
            config,
        };
        twin.advance_block(0.0);
        twin.prime();
        Ok(twin)
    }

    /// The output columns.
    pub fn schema(&self) -> &Schema {
        &self.schema
    }

    /// Metadata describing the run, for the recording header.
    pub fn metadata(&self) -> Vec<(String, String)> {
        let c = &self.config;
        let missing: Vec<&str> = c.effects.missing().iter().map(|e| e.id()).collect();
        vec![
            ("source".into(), "servosight twin".into()),
            ("machine".into(), c.machine.name.clone()),
            ("scenario".into(), c.scenario.name().into()),
            ("seed".into(), c.seed.to_string()),
            ("rate_hz".into(), c.rate_hz.to_string()),
            (
                "start_clock_h".into(),
                c.machine.room.start_hour.to_string(),
            ),
            (
                "effects_off".into(),
                if missing.is_empty() {
                    "none".into()
                } else {
                    missing.join(" ")
                },
            ),
        ]
    }

    /// Simulated time of the next row, s.
    pub fn time_s(&self) -> f64 {
        self.t_s
    }

    /// What the program is doing now ("roughing", "lunch break", …).
    pub fn activity(&self) -> &'static str {
        self.block.as_ref().map_or("finished", |b| b.label)
    }

    /// Sets the controller's X backlash compensation, µm (as the controller would apply it).
    pub fn set_backlash_compensation_um(&mut self, value_um: f64) {
        self.x.set_backlash_compensation_um(value_um);
    }

    /// Writes the next sample into `out` (cleared first) and advances by one sample interval.
    /// Returns false, leaving `out` empty, once the program is over.
    pub fn next_row(&mut self, out: &mut Vec<f64>) -> bool {
        out.clear();
        // Rows are written at every grid time up to the end of the program.
        if self.finished && self.t_s > self.program_end_s + 1e-9 {
            return false;
        }
        self.fill_truth();
        self.measurement.measure(self.t_s, &self.truth, out);
        // Load is what the drive computes from its own torque reading.
        let m = &self.config.machine;
        for (load, torque, rated) in [
            (
                Source::SpindleLoad,
                Source::SpindleTorque,
                m.spindle.motor.rated_torque_Nm,
            ),
            (
                Source::XLoad,
                Source::XTorque,
                m.x_axis.motor.rated_torque_Nm,
            ),
        ] {
            if let (Some(l), Some(t)) = (self.index_of(load), self.index_of(torque)) {
                out[l] = 100.0 * out[t] / rated;
            }
        }
        if self.finished {
            self.t_s = f64::INFINITY;
        } else {
            self.advance();
        }
        true
    }

    /// Runs the whole program into a recording.
    pub fn run_to_recording(mut self) -> Result<Recording, SimError> {
        let mut recording = Recording::with_schema("twin", self.schema.clone());
        for (k, v) in self.metadata() {
            recording.set_metadata(&k, &v);
        }
        if self.config.hours.is_none() && self.config.scenario != ScenarioKind::BacklashTest {
            return Err(SimError::Endless(self.config.scenario));
        }
        let mut row = Vec::with_capacity(self.schema.len());
        while self.next_row(&mut row) {
            recording.push_row(&row).map_err(SimError::Output)?;
        }
        Ok(recording)
    }

    /// Evaluates the mechanics once at t = 0 so the first row shows the standing machine
    /// (holding current, preload) rather than zeros. The sub-step is too short to add heat.
    fn prime(&mut self) {
        let (rpm, activity, feed) = match &self.block {
            Some(b) => (b.spindle_rpm, b.x.clone(), b.feed_per_rev_mm),
            None => return,
        };
        self.x.plan(0.0, &activity, feed, rpm);
        self.x.substep(
            0.0,
            1e-9,
            FeedAxisLoad {
                cutting_force_N: 0.0,
            },
        );
        self.spindle.substep(
            1e-9,
            SpindleCommand {
                speed_rpm: 0.0,
                cutting_torque_Nm: 0.0,
                radial_load_N: 0.0,
            },
        );
    }

    fn index_of(&self, wanted: Source) -> Option<usize> {
        self.sources
            .iter()
            .position(|s| std::mem::discriminant(s) == std::mem::discriminant(&wanted))
    }

    fn advance_block(&mut self, t: f64) {
        match self.program.next_block() {
            Some(block) => {
                // Program time, not simulation time: blocks chain exactly, whatever the sub-step.
                self.block_end_s += block.duration_s;
                self.block = Some(block);
                self.x.new_block();
            }
            None => {
                // A timed block ended at its end time; a move list ended now.
                self.program_end_s = self.block_end_s.min(t);
                self.block = None;
                self.finished = true;
            }
        }
    }

    fn advance(&mut self) {
        let dt = self.dt_s;
        let substeps = (dt / MAX_SUBSTEP_S).ceil().max(1.0) as usize;
        let h = dt / substeps as f64;
        let start = self.sample as f64;
        self.sample += 1;
        for j in 1..=substeps {
            let t = (start + j as f64 / substeps as f64) * dt;
            // Move on to the next block when this one's time is up, or when its move list has
            // been played out.
            while let Some(block) = &self.block {
                let ran_out = t > self.block_end_s + 1e-9;
                let list_done = matches!(block.x, XActivity::Moves(_))
                    && !self.x.busy(t)
                    && !self
                        .x
                        .plan(t, &block.x, block.feed_per_rev_mm, block.spindle_rpm);
                if ran_out || list_done {
                    self.advance_block(t);
                } else {
                    break;
                }
            }
            let Some(block) = &self.block else {
                // The program ended during this interval; the next grid time is past its end.
                self.t_s = (start + 1.0) * dt;
                break;
            };
            let (spindle_rpm, depth, feed) = (
                block.spindle_rpm,
                block.depth_of_cut_mm,
                block.feed_per_rev_mm,
            );
            let coolant = block.coolant;
            self.x.plan(t, &block.x, feed, spindle_rpm);
            let cutting_force = self.config.machine.cutting.specific_force_N_per_mm2 * depth * feed;
            let x_reading = self.x.substep(
                t,
                h,
                FeedAxisLoad {
                    cutting_force_N: self.config.machine.cutting.feed_force_ratio * cutting_force,
                },
            );
            let cutting = x_reading.cutting && depth > 0.0;
            self.cut_depth_mm = if cutting { depth } else { 0.0 };
            let radius_m = self.config.machine.cutting.workpiece_diameter_mm / 2000.0;
            self.spindle.substep(
                h,
                SpindleCommand {
                    speed_rpm: spindle_rpm,
                    cutting_torque_Nm: if cutting {
                        cutting_force * radius_m
                    } else {
                        0.0
                    },
                    radial_load_N: if cutting { cutting_force } else { 0.0 },
                },
            );
            self.t_s = t;
            self.thermal_accumulated_s += h;
            if self.thermal_accumulated_s >= THERMAL_STEP_S - 1e-9 {
                self.thermal_step(coolant);
            }
        }
        if dt >= THERMAL_STEP_S {
            let coolant = self.block.as_ref().is_some_and(|b| b.coolant);
            self.thermal_step(coolant);
        }
    }

    fn thermal_step(&mut self, coolant: bool) {
        let m = &self.config.machine;
        self.room_C = room_temperature(m, self.config.effects, self.t_s);
        let coolant_C = self.room_C + m.coolant.offset_from_room_K;
        self.spindle.thermal_step(self.room_C, coolant_C, coolant);
        self.x.thermal_step(self.room_C, coolant_C, coolant);
        self.thermal_accumulated_s = 0.0;
    }

    fn fill_truth(&mut self) {
        let s = self.spindle.reading();
        let x = self.x.reading();
        let coolant = self.block.as_ref().is_some_and(|b| b.coolant);
        let backlash = if self.config.effects.has(Effect::Backlash) {
            self.config.machine.x_axis.backlash_um
        } else {
            0.0
        };
        for (value, source) in self.truth.iter_mut().zip(&self.sources) {
            *value = match *source {
                Source::Time => self.t_s,
                Source::SpindleSpeed => s.speed_rpm,
                Source::SpindleTorque => s.torque_Nm,
                Source::SpindleCurrent => s.current_A,
                Source::SpindleLoad => s.load_pct,
                Source::SpindleStator => s.stator_C,
                Source::SpindlePosition => s.position_deg,
                Source::XCommand => x.command_mm,
                Source::XPosition => x.position_mm,
                Source::XSpeed => x.speed_rpm,
                Source::XTorque => x.torque_Nm,
                Source::XCurrent => x.current_A,
                Source::XLoad => x.load_pct,
                Source::XStator => x.stator_C,
                Source::Ambient => self.room_C,
                Source::Coolant => f64::from(u8::from(coolant)),
                Source::CutDepth => self.cut_depth_mm,
                Source::SpindleElongation => s.elongation_um,
                Source::SpindleFrontBearingTemp => s.front_bearing_C,
                Source::SpindleRearBearingTemp => s.rear_bearing_C,
                Source::SpindleHousingTemp => s.housing_C,
                Source::SpindleFrontBearingTorque => s.front_bearing_torque_Nm,
                Source::SpindleRearBearingTorque => s.rear_bearing_torque_Nm,
                Source::XFlangeTemp => x.flange_C,
                Source::XFrontBearingTemp => x.front_bearing_C,
                Source::XBackBearingTemp => x.back_bearing_C,
                Source::XNutTemp => x.nut_C,
                Source::XScrewTemp => x.screw_C,
                Source::XFrontBearingTorque => x.front_bearing_torque_Nm,
                Source::XBackBearingTorque => x.back_bearing_torque_Nm,
                Source::XNutTorque => x.nut_torque_Nm,
                Source::XNutPreload => x.nut_preload_N,
                Source::XAxialLoad => x.axial_load_N,
                Source::XTablePosition => x.table_mm,
                Source::XBacklash => backlash,
                Source::StraightnessH(k) => x.straightness_h_um[k],
                Source::StraightnessV(k) => x.straightness_v_um[k],
            };
        }
    }
}

/// Room temperature at `t_s` after the start: the daily swing plus a slow drift. With the
/// ambient effect off the twin assumes a constant room at the base temperature.
fn room_temperature(m: &MachineParams, effects: EffectSet, t_s: f64) -> f64 {
    let r = &m.room;
    if !effects.has(Effect::AmbientTemperature) {
        return r.base_C;
    }
    let hour = r.start_hour + t_s / 3600.0;
    let phase = 2.0 * std::f64::consts::PI * (hour - r.warmest_hour) / 24.0;
    r.base_C + r.daily_amplitude_K * phase.cos() + r.drift_K_per_h * t_s / 3600.0
}

/// The output columns: names, how each is measured, and where its value comes from.
fn layout(m: &MachineParams) -> (Vec<String>, Vec<ColumnMeasurement>, Vec<Source>) {
    let n = &m.measurement;
    let temperature = ColumnMeasurement::measured(n.temperature_noise_K);
    let reference_temperature = ColumnMeasurement {
        drifts: true,
        ..temperature
    };
    let displacement = ColumnMeasurement {
        drifts: true,
        ..ColumnMeasurement::measured(n.displacement_noise_um)
    };
    let magnitude = |sigma: f64| ColumnMeasurement {
        non_negative: true,
        ..ColumnMeasurement::measured(sigma)
    };
    let s_motor = &m.spindle.motor;
    let x_motor = &m.x_axis.motor;
    let (s, x) = (AxisId::S, AxisId::X);
    let refx = |q: &str| reference_column(x, q, None);
    let mut columns: Vec<(String, ColumnMeasurement, Source)> = vec![
        (TIME.into(), ColumnMeasurement::EXACT, Source::Time),
        (
            axis_column(s, Quantity::Speed),
            ColumnMeasurement::measured(n.speed_noise_rpm),
            Source::SpindleSpeed,
        ),
        (
            axis_column(s, Quantity::Torque),
            ColumnMeasurement::measured(n.torque_noise_fraction * s_motor.rated_torque_Nm),
            Source::SpindleTorque,
        ),
        (
            axis_column(s, Quantity::Current),
            magnitude(
                n.current_noise_fraction * s_motor.rated_torque_Nm
                    / s_motor.torque_constant_Nm_per_A,
            ),
            Source::SpindleCurrent,
        ),
        (
            axis_column(s, Quantity::Load),
            ColumnMeasurement::measured(0.0),
            Source::SpindleLoad,
        ),
        (
            axis_column(s, Quantity::StatorTemp),
            temperature,
            Source::SpindleStator,
        ),
        (
            axis_column(s, Quantity::Position),
            ColumnMeasurement::measured(0.0),
            Source::SpindlePosition,
        ),
        (
            axis_column(x, Quantity::Command),
            ColumnMeasurement::EXACT,
            Source::XCommand,
        ),
        (
            axis_column(x, Quantity::Position),
            ColumnMeasurement::measured(n.position_noise_mm),
            Source::XPosition,
        ),
        (
            axis_column(x, Quantity::Speed),
            ColumnMeasurement::measured(n.speed_noise_rpm),
            Source::XSpeed,
        ),
        (
            axis_column(x, Quantity::Torque),
            ColumnMeasurement::measured(n.torque_noise_fraction * x_motor.rated_torque_Nm),
            Source::XTorque,
        ),
        (
            axis_column(x, Quantity::Current),
            magnitude(
                n.current_noise_fraction * x_motor.rated_torque_Nm
                    / x_motor.torque_constant_Nm_per_A,
            ),
            Source::XCurrent,
        ),
        (
            axis_column(x, Quantity::Load),
            ColumnMeasurement::measured(0.0),
            Source::XLoad,
        ),
        (
            axis_column(x, Quantity::StatorTemp),
            temperature,
            Source::XStator,
        ),
        (AMBIENT.into(), temperature, Source::Ambient),
        (COOLANT.into(), ColumnMeasurement::EXACT, Source::Coolant),
        (CUT_DEPTH.into(), ColumnMeasurement::EXACT, Source::CutDepth),
        (
            reference_column(s, "elongation_um", None),
            displacement,
            Source::SpindleElongation,
        ),
        (
            reference_column(s, "front_bearing_temp_C", None),
            reference_temperature,
            Source::SpindleFrontBearingTemp,
        ),
        (
            reference_column(s, "rear_bearing_temp_C", None),
            reference_temperature,
            Source::SpindleRearBearingTemp,
        ),
        (
            reference_column(s, "housing_temp_C", None),
            reference_temperature,
            Source::SpindleHousingTemp,
        ),
        (
            reference_column(s, "front_bearing_torque_Nm", None),
            ColumnMeasurement::EXACT,
            Source::SpindleFrontBearingTorque,
        ),
        (
            reference_column(s, "rear_bearing_torque_Nm", None),
            ColumnMeasurement::EXACT,
            Source::SpindleRearBearingTorque,
        ),
        (
            refx("motor_flange_temp_C"),
            reference_temperature,
            Source::XFlangeTemp,
        ),
        (
            refx("front_bearing_temp_C"),
            reference_temperature,
            Source::XFrontBearingTemp,
        ),
        (
            refx("back_bearing_temp_C"),
            reference_temperature,
            Source::XBackBearingTemp,
        ),
        (refx("nut_temp_C"), reference_temperature, Source::XNutTemp),
        (
            refx("screw_temp_C"),
            reference_temperature,
            Source::XScrewTemp,
        ),
        (
            refx("front_bearing_torque_Nm"),
            ColumnMeasurement::EXACT,
            Source::XFrontBearingTorque,
        ),
        (
            refx("back_bearing_torque_Nm"),
            ColumnMeasurement::EXACT,
            Source::XBackBearingTorque,
        ),
        (
            refx("nut_torque_Nm"),
            ColumnMeasurement::EXACT,
            Source::XNutTorque,
        ),
        (
            refx("nut_preload_N"),
            ColumnMeasurement::EXACT,
            Source::XNutPreload,
        ),
        (
            refx("axial_load_N"),
            ColumnMeasurement::EXACT,
            Source::XAxialLoad,
        ),
        (
            refx("table_position_mm"),
            ColumnMeasurement::EXACT,
            Source::XTablePosition,
        ),
        (
            refx("backlash_um"),
            ColumnMeasurement::EXACT,
            Source::XBacklash,
        ),
    ];
    for k in 0..m.x_axis.straightness_nodes {
        columns.push((
            reference_column(x, "straightness_h_um", Some(k + 1)),
            displacement,
            Source::StraightnessH(k),
        ));
    }
    for k in 0..m.x_axis.straightness_nodes {
        columns.push((
            reference_column(x, "straightness_v_um", Some(k + 1)),
            displacement,
            Source::StraightnessV(k),
        ));
    }
    let mut names = Vec::with_capacity(columns.len());
    let mut measurements = Vec::with_capacity(columns.len());
    let mut sources = Vec::with_capacity(columns.len());
    for (name, measurement, source) in columns {
        names.push(name);
        measurements.push(measurement);
        sources.push(source);
    }
    (names, measurements, sources)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::signal::channel::reference_column;

    fn run(config: TwinConfig) -> Recording {
        Twin::new(config).unwrap().run_to_recording().unwrap()
    }

    #[test]
    fn same_seed_gives_the_same_recording_and_noise_does_not_change_the_program() {
        let config = TwinConfig::new(ScenarioKind::Production, Some(1.0), 5);
        assert_eq!(run(config.clone()), run(config.clone()));
        let mut quiet = config.clone();
        quiet.machine.measurement.noise_scale = 0.0;
        let noisy = run(config);
        let exact = run(quiet);
        assert_eq!(
            noisy.column("X.command_mm").unwrap(),
            exact.column("X.command_mm").unwrap()
        );
        assert_ne!(
            noisy.column("S.torque_Nm").unwrap(),
            exact.column("S.torque_Nm").unwrap()
        );
    }

    /// The recording rate samples the machine; it must not change what the machine does. A
    /// 1 Hz recording of a cycle that is a whole number of seconds long would see the same
    /// instant of every cycle, and the current it samples would misstate the copper heat.
    #[test]
    fn a_slow_recording_samples_the_same_motion_and_heat_as_a_fast_one() {
        let rate = |rate_hz: f64| {
            let mut config = TwinConfig::new(ScenarioKind::Production, Some(1.0), 5);
            config.rate_hz = rate_hz;
            config.machine.measurement.noise_scale = 0.0;
            run(config)
        };
        let (slow, fast) = (rate(1.0), rate(20.0));
        let (slow_position, fast_position) = (
            slow.column("X.position_mm").unwrap(),
            fast.column("X.position_mm").unwrap(),
        );
        let mut gaps: Vec<f64> = slow_position
            .iter()
            .zip(fast_position.iter().step_by(20))
            .map(|(a, b)| (a - b).abs())
            .collect();
        gaps.sort_by(f64::total_cmp);
        let median_gap = gaps[gaps.len() / 2];
        assert!(median_gap < 0.5, "median position gap {median_gap} mm");
        // Mean I² (the copper heat) over each 10-minute window: the 1 Hz samples against the
        // 20 Hz record's average.
        let squared = |r: &Recording| -> Vec<f64> {
            r.column("X.current_A")
                .unwrap()
                .iter()
                .map(|i| i * i)
                .collect()
        };
        let (slow_heat, fast_heat) = (squared(&slow), squared(&fast));
        for (window, (s, f)) in slow_heat[..3600]
            .chunks(600)
            .zip(fast_heat[..72_000].chunks(12_000))
            .enumerate()
        {
            let (s, f) = (
                s.iter().sum::<f64>() / s.len() as f64,
                f.iter().sum::<f64>() / f.len() as f64,
            );
            assert!(
                (s / f - 1.0).abs() < 0.05,
                "window {window}: 1 Hz mean I² {s:.3} A², 20 Hz {f:.3} A²"
            );
        }
    }

    #[test]
    fn a_production_day_grows_the_spindle_by_the_papers_tens_of_micrometres() {
        let rec = run(TwinConfig::new(ScenarioKind::Production, Some(8.0), 3));
        let e = rec
            .column(&reference_column(AxisId::S, "elongation_um", None))
            .unwrap();
        let range = e.iter().cloned().fold(f64::NEG_INFINITY, f64::max)
            - e.iter().cloned().fold(f64::INFINITY, f64::min);
        // Paper Table 2: 29–45 µm over a day with a lunch break.
        assert!((20.0..70.0).contains(&range), "elongation range {range} µm");
        assert_eq!(rec.len(), 8 * 3600 + 1);
    }

    #[test]
    fn switching_an_effect_off_changes_only_its_physics() {
        let all = TwinConfig::new(ScenarioKind::Production, Some(2.0), 9);
        let mut no_room = all.clone();
        no_room.effects = EffectSet::all().without(Effect::AmbientTemperature);
        let (a, b) = (run(all), run(no_room));
        let room_b = b.column(AMBIENT).unwrap();
        let spread = room_b.iter().cloned().fold(f64::NEG_INFINITY, f64::max)
            - room_b.iter().cloned().fold(f64::INFINITY, f64::min);
        assert!(
            spread < 0.5,
            "a constant room only shows sensor noise: {spread}"
        );
        assert_eq!(
            a.column("S.speed_rpm").unwrap().len(),
            b.column("S.speed_rpm").unwrap().len()
        );
        assert_eq!(a.metadata_value("effects_off"), Some("none"));
        assert_eq!(b.metadata_value("effects_off"), Some("ambient_temperature"));
    }

    #[test]
    fn backlash_test_ends_by_itself_and_reports_the_configured_backlash() {
        let mut config = TwinConfig::new(ScenarioKind::BacklashTest, None, 1);
        config.machine.x_axis.backlash_um = 25.0;
        config.rate_hz = 200.0;
        let rec = run(config);
        assert!(
            rec.duration_s() < 600.0 && rec.duration_s() > 60.0,
            "{} s",
            rec.duration_s()
        );
        assert!(
            rec.column("ref.X.backlash_um")
                .unwrap()
                .iter()
                .all(|&b| b == 25.0)
        );
    }

    #[test]
    fn invalid_settings_are_refused() {
        let mut config = TwinConfig::new(ScenarioKind::Doe, Some(1.0), 1);
        config.rate_hz = 0.0;
        assert!(matches!(
            Twin::new(config.clone()),
            Err(SimError::InvalidRate(_))
        ));
        config.rate_hz = 1.0;
        config.hours = Some(-1.0);
        assert!(matches!(Twin::new(config), Err(SimError::InvalidHours(_))));
        let endless = TwinConfig::new(ScenarioKind::Production, None, 1);
        assert!(matches!(
            Twin::new(endless).unwrap().run_to_recording(),
            Err(SimError::Endless(_))
        ));
    }
}
