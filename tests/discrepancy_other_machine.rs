//! Sim-vs-real discrepancy on a machine that is not the twin: a small feed axis written here
//! from the vocabulary's physics alone (Coulomb and viscous friction on a reversing axis, a
//! motor winding heated by I²R and a ball-screw nut heated by its friction, both shedding heat
//! to the room), driven through the command like a user would. Its recordings start mid-cut, and its current is a magnitude read as zero at
//! standstill: two things every twin run happened not to do. `scripts/independent_cases.py`
//! runs a larger machine of the same kind over every effect and target.

use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Normal};

use crate::discrepancy::{discrepancy_json, pair_paths};

/// What the feed axis's run has.
#[derive(Debug, Clone, Copy)]
struct Physics {
    /// Coulomb friction (N·m) that flips with the direction of motion.
    coulomb_nm: f64,
    /// The winding's I²R heating.
    copper_loss: bool,
    /// Measurement noise.
    noisy: bool,
    /// The drive is switched off in dwells: its current reads exactly zero there.
    drive_off_in_dwells: bool,
    /// The current sensor's offset (A) and drift (A/h) wherever it reads.
    current_offset_drift: (f64, f64),
    /// How the nut sheds heat to the air.
    nut_convection: Convection,
    /// Coolant flows over the nut in most cuts (1.0 W/K while it flows), and the recording
    /// has its `coolant_on` column.
    nut_coolant: bool,
    /// The coolant's temperature when a chiller holds it (°C); `None`: at room temperature.
    coolant_held_c: Option<f64>,
    /// The nut's heat capacity as a multiple of 1200 J/K.
    nut_capacity_scale: f64,
    /// The room's daily swing (K): 21 °C + swing · sin(2π t / 24 h). A simulation without a
    /// room model has none.
    room_swing_k: f64,
}

/// The nut's heat transfer to the air around it.
#[derive(Debug, Clone, Copy)]
enum Convection {
    /// Still air at every speed: 0.6 W/K.
    StillAir,
    /// Forced convection as the nut travels: 0.6 W/K × (1 + (n / 150 rpm)^0.8).
    GrowingWithSpeed,
    /// The forced convection's value at one speed (rpm), kept at every speed: what a
    /// simulation with a constant coefficient has.
    FixedAt(f64),
}

impl Convection {
    /// W/K at `rpm`.
    fn conductance(self, rpm: f64) -> f64 {
        let forced = |n: f64| 0.6 * (1.0 + (n.abs() / 150.0).powf(0.8));
        match self {
            Convection::StillAir => 0.6,
            Convection::GrowingWithSpeed => forced(rpm),
            Convection::FixedAt(nominal) => forced(nominal),
        }
    }
}

const COLUMNS: &str = "time_s,X.speed_rpm,X.position_mm,X.torque_Nm,X.current_A,X.stator_temp_C,ref.X.nut_temp_C,ambient_C";

/// Three hours at 1 Hz of a feed axis working through cuts and dwells, starting mid-cut; the
/// same `seed` gives the same program whatever the physics.
fn feed_axis_csv(seed: u64, physics: Physics) -> String {
    let mut program = rand::rngs::StdRng::seed_from_u64(seed);
    let mut noise = rand::rngs::StdRng::seed_from_u64(seed ^ 0x5eed);
    let mut nut_noise = rand::rngs::StdRng::seed_from_u64(seed ^ 0x0b17);
    // Its own stream, so that the program is the same with the coolant or without.
    let mut coolant_program = rand::rngs::StdRng::seed_from_u64(seed ^ 0xc001);
    let white = |sigma: f64| Normal::new(0.0, sigma).expect("a positive σ");
    let (torque_noise, current_noise, temperature_noise) = (white(0.02), white(0.02), white(0.03));
    let (capacity_j_per_k, conductance_w_per_k, resistance_ohm, torque_constant) =
        (1500.0, 0.8, 2.0, 0.9);
    let mut out = if physics.nut_coolant {
        format!("{COLUMNS},coolant_on\n")
    } else {
        format!("{COLUMNS}\n")
    };
    let (mut position, mut direction, mut since_reversal) = (200.0_f64, 1.0_f64, 0);
    let mut winding = 21.0_f64;
    let mut nut = 21.0_f64;
    let mut segment_left = 0;
    let (mut feed_rpm, mut cut_nm, mut half_period) = (0.0_f64, 0.0_f64, 1);
    let mut coolant_flows = false;
    for k in 0..3 * 3600 {
        let t = k as f64;
        if segment_left == 0 {
            segment_left = program.random_range(120..600);
            let cutting = program.random_bool(0.6);
            feed_rpm = if cutting {
                program.random_range(100.0..400.0)
            } else {
                0.0
            };
            cut_nm = program.random_range(0.3..1.2);
            half_period = program.random_range(30..60);
            if k == 0 {
                // The recording opens in the middle of a heavy cut.
                (segment_left, feed_rpm, cut_nm) = (900, 300.0, 1.5);
            }
            coolant_flows =
                physics.nut_coolant && feed_rpm > 0.0 && coolant_program.random_bool(0.7);
        }
        segment_left -= 1;
        let moving = feed_rpm > 0.0;
        if moving {
            since_reversal += 1;
            if since_reversal >= half_period {
                direction = -direction;
                since_reversal = 0;
            }
            position += direction * feed_rpm * 10.0 / 60.0; // 10 mm lead
        }
        let d = if moving { direction } else { 0.0 };
        let speed = d * feed_rpm;
        let torque = d * (physics.coulomb_nm + 0.1 + cut_nm) + 0.001 * speed;
        let current = torque.abs() / torque_constant;
        let room = 21.0 + physics.room_swing_k * (2.0 * std::f64::consts::PI * t / 86_400.0).sin();
        let heat = if physics.copper_loss {
            resistance_ohm * current * current
        } else {
            0.0
        };
        winding += (heat - conductance_w_per_k * (winding - room)) / capacity_j_per_k;
        // A fifth of the friction's work (Coulomb, preload and viscous drag) heats the nut.
        let friction_nm = if moving {
            physics.coulomb_nm + 0.1 + 0.001 * feed_rpm
        } else {
            0.0
        };
        let friction_heat = 0.2 * friction_nm * feed_rpm * std::f64::consts::PI / 30.0;
        let coolant_w_per_k = if coolant_flows { 1.0 } else { 0.0 };
        let coolant_c = physics.coolant_held_c.unwrap_or(room);
        nut += (friction_heat
            - physics.nut_convection.conductance(speed) * (nut - room)
            - coolant_w_per_k * (nut - coolant_c))
            / (1200.0 * physics.nut_capacity_scale);
        let mut sample = |sigma: &Normal<f64>| {
            if physics.noisy {
                sigma.sample(&mut noise)
            } else {
                0.0
            }
        };
        let measured_torque = torque + sample(&torque_noise);
        // A drive reports the current's magnitude: its noise is cut off at zero.
        let (offset, drift) = physics.current_offset_drift;
        let measured_current = if physics.drive_off_in_dwells && !moving {
            0.0
        } else {
            (current + offset + drift * t / 3600.0 + sample(&current_noise)).max(0.0)
        };
        let measured_winding = winding + sample(&temperature_noise);
        let measured_nut = nut
            + if physics.noisy {
                temperature_noise.sample(&mut nut_noise)
            } else {
                0.0
            };
        out.push_str(&format!(
            "{t},{speed:.3},{position:.4},{measured_torque:.5},{measured_current:.5},{measured_winding:.5},{measured_nut:.5},{room:.5}"
        ));
        if physics.nut_coolant {
            out.push_str(if coolant_flows { ",1\n" } else { ",0\n" });
        } else {
            out.push('\n');
        }
    }
    out
}

/// The report of `servosight discrepancy` on the pair.
fn compare(sim: &str, real: &str, target: &str) -> serde_json::Value {
    let (_dir, sim_path, real_path) = pair_paths();
    std::fs::write(&sim_path, sim).expect("the simulation written");
    std::fs::write(&real_path, real).expect("the recording written");
    discrepancy_json(&sim_path, &real_path, target, &[])
}

/// The simulation of `REAL`'s run `seed` without its Coulomb friction (and noise-free).
fn without_coulomb(seed: u64) -> String {
    feed_axis_csv(
        seed,
        Physics {
            coulomb_nm: 0.0,
            noisy: false,
            ..REAL
        },
    )
}

/// The report on `target` when the simulation leaves the friction of `REAL` out.
fn coulomb_left_out(seed: u64, target: &str) -> serde_json::Value {
    compare(&without_coulomb(seed), &feed_axis_csv(seed, REAL), target)
}

fn assert_named_first(report: &serde_json::Value, physics: &str) {
    assert_eq!(
        named(report).first().map(String::as_str),
        Some(physics),
        "{report}"
    );
}

/// Out of sample, the corrected simulation is within 1.5 × the thermometers' noise (0.03 °C).
fn assert_held_out_within_the_thermometer_noise(report: &serde_json::Value) {
    let rmse = report["improved"]["rmse"].as_f64().expect("improved.rmse");
    assert!(rmse < 1.5 * 0.03, "held-out RMSE {rmse} °C");
}

fn named(report: &serde_json::Value) -> Vec<String> {
    report["findings"]
        .as_array()
        .map(|f| {
            f.iter()
                .filter_map(|f| f["physics"].as_str().map(str::to_string))
                .collect()
        })
        .unwrap_or_default()
}

const REAL: Physics = Physics {
    coulomb_nm: 0.35,
    copper_loss: true,
    noisy: true,
    drive_off_in_dwells: false,
    current_offset_drift: (0.0, 0.0),
    nut_convection: Convection::StillAir,
    nut_coolant: false,
    coolant_held_c: None,
    nut_capacity_scale: 1.0,
    room_swing_k: 1.0,
};

/// The winding's copper heat, left out of a simulation of a recording that opens mid-cut, has
/// added nothing at the first row and builds from there. Lags started in equilibrium with the
/// first row's current claimed a lag's worth of heat already present: the best member fitted
/// 0.83 of the residual and was not significant (verdict `consistent` at 20 σ).
#[test]
fn copper_heat_left_out_of_a_run_that_opens_mid_cut_is_named_and_fitted() {
    let sim = feed_axis_csv(
        7,
        Physics {
            copper_loss: false,
            noisy: false,
            ..REAL
        },
    );
    let report = compare(&sim, &feed_axis_csv(7, REAL), "X.stator_temp_C");
    assert_named_first(&report, "copper_loss");
    assert_held_out_within_the_thermometer_noise(&report);
}

/// Coulomb friction adds to the current's magnitude whichever way the axis moves (the drive
/// pushes against it both ways). Taken as a term that changes sign with the direction, as for a
/// torque, it could not fit a magnitude and the effect went unnamed.
#[test]
fn coulomb_friction_left_out_is_named_on_a_current_magnitude() {
    let report = coulomb_left_out(8, "X.current_A");
    assert_named_first(&report, "coulomb_reversal");
}

/// Coulomb friction the simulation lacks makes the drive draw more current whichever way the
/// axis moves, and the winding's I²R heat grows with it. On the winding's temperature that is
/// the only trace of the friction: the extra current is found by comparing the two
/// recordings' currents, and its step is the friction's.
#[test]
fn coulomb_friction_left_out_is_named_on_the_winding_through_the_current_it_draws() {
    assert_friction_named_on_the_winding(&coulomb_left_out(11, "X.stator_temp_C"));
}

/// Coulomb friction named first on the winding, its step the friction's within a quarter
/// (0.35 N·m at 0.9 N·m/A: 0.39 A more current while the axis moves), and the held-out error
/// within the thermometer's noise.
fn assert_friction_named_on_the_winding(report: &serde_json::Value) {
    assert_named_first(report, "coulomb_reversal");
    let step = report["findings"][0]["parameters"]["current_step_A"]
        .as_f64()
        .expect("current_step_A");
    assert!(
        (step - 0.35 / 0.9).abs() < 0.25 * 0.35 / 0.9,
        "step {step} A"
    );
    assert_held_out_within_the_thermometer_noise(report);
}

/// The same friction left out of a simulation exported every 5 s beside a recording at 1 Hz:
/// the corrections are built on the real recording's own rows and read at the simulation's
/// instants. The friction step read once for the simulation's rows was handed to the real
/// rows too, where its length did not fit, and the winding's Coulomb heat was not offered at
/// all (copper loss named in its place, as on the independent check's seeds 7 and 10).
#[test]
fn coulomb_friction_left_out_of_a_coarse_export_is_named_on_the_winding() {
    let exported: String = without_coulomb(11)
        .lines()
        .enumerate()
        .filter(|(k, _)| *k == 0 || (k - 1) % 5 == 0)
        .map(|(_, l)| format!("{l}\n"))
        .collect();
    let report = compare(&exported, &feed_axis_csv(11, REAL), "X.stator_temp_C");
    assert_eq!(report["alignment"]["on_simulation_grid"], true, "{report}");
    assert_named_first(&report, "coulomb_reversal");
    assert_held_out_within_the_thermometer_noise(&report);
}

/// Coulomb friction left out while the real current sensor's zero drifts (0.1 A at the start,
/// 0.3 A/h) and the simulation's stays put: the drift moves the currents' difference too.
/// Read beside the offset and the scale alone, the friction step explained 41 % of it, below
/// the gate, so the winding's Coulomb heat was not offered and iron loss was named in its
/// place (0.085 °C held out). Read beside a line in time as well, the step is the friction's
/// (0.388 A against 0.389), it explains 90 %, and the winding names it first (0.030 °C).
#[test]
fn coulomb_friction_beside_a_drifting_current_sensor_is_named_on_the_winding() {
    let report = coulomb_on_the_winding_beside_a_current_sensor_drifting((0.1, 0.3));
    let share = report["findings"][0]["parameters"]["step_share_of_current_difference"]
        .as_f64()
        .expect("step_share_of_current_difference");
    assert!(share >= 0.5, "share {share}");
}

/// The winding's report with the friction of `REAL` left out of the simulation while the real
/// current sensor reads with `offset_drift` (A, A/h), checked for what every such case must
/// show ([`assert_friction_named_on_the_winding`]).
fn coulomb_on_the_winding_beside_a_current_sensor_drifting(
    offset_drift: (f64, f64),
) -> serde_json::Value {
    let real = Physics {
        current_offset_drift: offset_drift,
        ..REAL
    };
    let report = compare(
        &without_coulomb(11),
        &feed_axis_csv(11, real),
        "X.stator_temp_C",
    );
    assert_friction_named_on_the_winding(&report);
    report
}

/// The same friction left out while the current sensor's zero falls through its floor (from
/// +0.1 A by 0.3 A/h): from the first half hour on, the dwells and then the lighter cuts read
/// 0 A, which says only that the current plus the sensor's zero is at or below it. Taken as
/// values, those readings bent the line the step is read beside: the step explained 14 % of
/// the currents' difference, the winding's Coulomb heat was not offered, and iron loss was
/// named (0.085 °C held out). With the readings at the floor taken as bounds the step reads
/// 0.457 A against 0.389 (the dwells, nearly all at the floor, tell the step from the
/// sensor's level only loosely), explains 81 %, and Coulomb friction is named (0.030 °C).
#[test]
fn coulomb_friction_beside_a_current_sensor_zero_falling_through_its_floor_is_named_on_the_winding()
{
    coulomb_on_the_winding_beside_a_current_sensor_drifting((0.1, -0.3));
}

/// `csv` exported half a second later: each row's values at `time_s` + 0.5. The axis holds
/// its state through each second, so these are the machine's values at those instants, on a
/// grid that shares none of the real recording's.
fn half_a_sample_later(csv: &str) -> String {
    csv.lines()
        .enumerate()
        .map(|(k, line)| match line.split_once(',') {
            Some((t, rest)) if k > 0 => {
                let t: f64 = t.parse().expect("a time");
                format!("{},{rest}\n", t + 0.5)
            }
            _ => format!("{line}\n"),
        })
        .collect()
}

/// A simulation exported half a sample off the real grid, interpolated onto it, read the
/// torque halfway through every reversal: this test's torque was 0.23 N·m off held out with
/// nothing left out (11 × the noise), and the independent check's named a position profile
/// and lubricant viscosity. Placed by the speeds, it is consistent, and friction left out is
/// named as friction.
#[test]
fn a_simulation_exported_half_a_sample_off_the_grid_is_compared_where_the_speeds_place_it() {
    let real = feed_axis_csv(9, REAL);
    let simulated = |physics: Physics| {
        half_a_sample_later(&feed_axis_csv(
            9,
            Physics {
                noisy: false,
                ..physics
            },
        ))
    };
    let sim = simulated(REAL);
    for target in ["X.torque_Nm", "X.current_A", "X.stator_temp_C"] {
        let report = compare(&sim, &real, target);
        assert_eq!(report["verdict"], "consistent", "{target}: {report}");
        // Held out, the simulation as it is agrees to the sensors' noise (0.02 N·m, 0.02 A,
        // 0.03 °C).
        let rmse = report["improved"]["rmse"].as_f64().expect("improved.rmse");
        assert!(rmse < 0.035, "{target}: held-out RMSE {rmse}");
        let placed = report["alignment"]["placed_by_speed"]
            .as_u64()
            .expect("placed_by_speed");
        assert!(placed > 100, "{target}: {placed} rows placed");
    }
    let report = compare(
        &simulated(Physics {
            coulomb_nm: 0.0,
            ..REAL
        }),
        &real,
        "X.torque_Nm",
    );
    assert_named_first(&report, "coulomb_reversal");
}

/// Two hours of a feed axis reversing every 7 s (a quarter of a second into a second), as
/// `time_s,X.speed_rpm,X.position_mm,X.torque_Nm` at `times`: its torque steps with the
/// direction and carries a cutting load that changes every half second (the same load for a
/// given instant, whatever the grid), read `delay_s` late and with white noise of `noise`
/// N·m.
fn rippling_axis_csv(times: impl Iterator<Item = f64>, delay_s: f64, noise: f64) -> String {
    let mut load = rand::rngs::StdRng::seed_from_u64(41);
    let ripple: Vec<f64> = (0..2 * 7300)
        .map(|_| load.random_range(-0.3..0.3))
        .collect();
    let direction = |t: f64| {
        if ((t - 0.25) / 7.0).floor().rem_euclid(2.0) == 0.0 {
            1.0
        } else {
            -1.0
        }
    };
    let torque = |t: f64| {
        let half_seconds = (2.0 * t).floor().max(0.0) as usize;
        0.6 * direction(t) + ripple.get(half_seconds).copied().unwrap_or(0.0)
    };
    let mut noise_draws = rand::rngs::StdRng::seed_from_u64(43);
    let white = Normal::new(0.0, noise.max(1e-12)).expect("a positive σ");
    let mut out = String::from("time_s,X.speed_rpm,X.position_mm,X.torque_Nm\n");
    for t in times {
        let measured = torque(t - delay_s)
            + if noise > 0.0 {
                white.sample(&mut noise_draws)
            } else {
                0.0
            };
        // 300 rpm on a 10 mm lead: 50 mm/s along a 350 mm stroke.
        let position = 100.0 + 50.0 * (t - 0.25).rem_euclid(7.0) * (direction(t) + 1.0) / 2.0;
        out.push_str(&format!(
            "{t},{},{position},{measured}\n",
            300.0 * direction(t)
        ));
    }
    out
}

/// A simulation exported half a second off the real 1 Hz grid has a sample 3.5 s before
/// every real instant, and a torque measured 3.5 s late is that sample. Read from the rows,
/// each the simulation already interpolated (placed) once, the delay missed the cutting load
/// between them by about its own size and left a second finding beside it on the
/// independent check's machine; read from the samples, it is the only finding and the
/// corrected simulation is within the noise.
#[test]
fn a_torque_read_late_by_a_delay_that_lands_on_the_simulations_samples_is_matched_there() {
    let sim = rippling_axis_csv((0..7200).map(|k| f64::from(k) + 0.5), 0.0, 0.0);
    // The trace starts ten seconds after the simulation, so that every instant it is
    // compared at has a simulated one 3.5 s before.
    let real = rippling_axis_csv((10..7200).map(f64::from), 3.5, 0.02);
    let report = compare(&sim, &real, "X.torque_Nm");
    assert_eq!(named(&report), ["signal_delay"], "{report}");
    let delay = report["findings"][0]["parameters"]["delay_s"]
        .as_f64()
        .expect("delay_s");
    assert!((delay - 3.5).abs() < 0.01, "delay {delay} s");
    let rmse = report["improved"]["rmse"].as_f64().expect("improved.rmse");
    assert!(rmse < 1.5 * 0.02, "held-out RMSE {rmse} N·m");
}

/// The physics a report says it did not try, with the reasons.
fn not_tested(report: &serde_json::Value) -> Vec<(String, String)> {
    report["not_tested"]
        .as_array()
        .expect("not_tested")
        .iter()
        .filter_map(|n| Some((n["physics"].as_str()?.into(), n["reason"].as_str()?.into())))
        .collect()
}

/// Where `X.torque_Nm` sits among [`COLUMNS`].
fn torque_column() -> usize {
    COLUMNS
        .split(',')
        .position(|c| c == "X.torque_Nm")
        .expect("a torque column")
}

/// `csv` with the torque of every data row `k` (from 1, after the header) replaced by
/// `torque(k, row)`.
fn with_torque(csv: &str, torque: impl Fn(usize, &[String]) -> String) -> String {
    csv.lines()
        .enumerate()
        .map(|(k, line)| {
            let mut row: Vec<String> = line.split(',').map(str::to_string).collect();
            if k > 0 {
                row[torque_column()] = torque(k, &row);
            }
            row.join(",") + "\n"
        })
        .collect()
}

/// `csv` with its drive's torque and current read `rows` rows late (a transport delay of the
/// drive's data; the speed and the position are on time), the first row's held before.
fn drive_read_late(csv: &str, rows: usize) -> String {
    let header = COLUMNS.split(',').collect::<Vec<_>>();
    let late: Vec<usize> = ["X.torque_Nm", "X.current_A"]
        .iter()
        .map(|c| header.iter().position(|h| h == c).expect("a drive column"))
        .collect();
    let lines: Vec<Vec<String>> = csv
        .lines()
        .map(|line| line.split(',').map(str::to_string).collect())
        .collect();
    lines
        .iter()
        .enumerate()
        .map(|(k, row)| {
            let mut row = row.clone();
            if k > 0 {
                let from = &lines[k.saturating_sub(rows).max(1)];
                for &c in &late {
                    row[c] = from[c].clone();
                }
            }
            row.join(",") + "\n"
        })
        .collect()
}

/// Coulomb friction left out of the simulation of a drive whose data arrive 20 s late: its
/// 0.39 A step on the current's magnitude is added while the drive pushes the way the axis
/// moves, and whether it pushes was read from the measured torque, which in the 20 s after
/// each reversal still has the old sign (the axis reverses every 30–60 s). The step's
/// column was then wrong on about half the moving rows and only the delay was named (the
/// independent check's seeds 1 and 2). Read from the simulated torque, on the speed's
/// timing, both are named.
#[test]
fn coulomb_friction_on_a_current_recorded_late_is_named_beside_the_delay() {
    let real = drive_read_late(&feed_axis_csv(8, REAL), 20);
    let report = compare(&without_coulomb(8), &real, "X.current_A");
    let named = named(&report);
    assert!(
        named.iter().any(|n| n == "coulomb_reversal") && named.iter().any(|n| n == "signal_delay"),
        "named {named:?}"
    );
}

/// A torque has no heat capacity: a lead-lag of it, offered as one, took the part of a delay
/// that interpolation leaves and was named beside it. The report says why it is not tried.
#[test]
fn a_heat_capacity_is_not_offered_on_a_torque() {
    let report = coulomb_left_out(9, "X.torque_Nm");
    assert_named_first(&report, "coulomb_reversal");
    let skipped = not_tested(&report);
    let inertia = skipped
        .iter()
        .find(|(physics, _)| physics == "thermal_inertia")
        .unwrap_or_else(|| panic!("thermal inertia tried on a torque: {skipped:?}"));
    assert!(inertia.1.contains("no heat capacity"), "{}", inertia.1);
}

/// A simulation exported once a minute holds nothing of a torque that reverses every 30–60 s
/// between its instants: a shifted copy of it would interpolate across the very reversals it
/// moves (on the independent check's 10 s export such a shift fitted 141 s to a true 14 s).
/// The real recording, sampled every second, can be moved instead: the torque that trails the
/// simulation by 15 s is read 15 s later and compared at the export's instants, the delay is
/// named with its length, and what it leaves is the sensor's noise. The same export of a
/// torque that does not trail is consistent: reading it later only moves its reversals away
/// from the simulation's. A heat capacity is still not tried on the export, and the report
/// says why.
#[test]
fn a_delay_behind_a_simulation_exported_too_coarsely_to_move_is_read_on_the_real_samples() {
    let real = feed_axis_csv(5, REAL);
    let measured: Vec<String> = real
        .lines()
        .map(|line| {
            line.split(',')
                .nth(torque_column())
                .unwrap_or("")
                .to_string()
        })
        .collect();
    let delay_rows = 15;
    let delayed = with_torque(&real, |k, _| {
        measured[k.saturating_sub(delay_rows).max(1)].clone()
    });
    let simulated = feed_axis_csv(
        5,
        Physics {
            noisy: false,
            ..REAL
        },
    );
    // The header, then a row a minute.
    let exported: String = simulated
        .lines()
        .enumerate()
        .filter(|(k, _)| *k == 0 || (k - 1) % 60 == 0)
        .map(|(_, l)| format!("{l}\n"))
        .collect();
    let report = compare(&exported, &delayed, "X.torque_Nm");
    assert_eq!(report["alignment"]["on_simulation_grid"], true);
    assert_eq!(report["verdict"], "missing_physics", "{report}");
    assert_named_first(&report, "signal_delay");
    assert_eq!(report["alignment"]["read_later_s"], 15.0, "{report}");
    assert!(
        report["alignment"]["note"]
            .as_str()
            .is_some_and(|n| n.contains("the real target was read 15.00 s later")),
        "{report}"
    );
    let delay = &report["findings"][0];
    let delay_s = parameter(delay, "delay_s");
    assert!((delay_s - 15.0).abs() <= 0.5, "delay {delay_s} s: {report}");
    assert_eq!(parameter(delay, "resolution_s"), 1.0, "{report}");
    assert!(
        delay["explanation"]
            .as_str()
            .is_some_and(|e| e.contains("trails the simulated one by 15.0 s")
                && e.contains("real recording's own samples")),
        "{report}"
    );
    // Out of sample, within 1.5 × the torque sensor's noise (0.02 N·m).
    let rmse = report["improved"]["rmse"].as_f64().expect("improved.rmse");
    assert!(rmse < 1.5 * 0.02, "held-out RMSE {rmse} N·m: {report}");
    // The figures before any correction are the recording's as it was taken.
    let baseline = report["baseline"]["rmse"].as_f64().expect("baseline.rmse");
    assert!(baseline > 10.0 * rmse, "baseline {baseline}: {report}");
    let skipped = not_tested(&report);
    assert!(
        !skipped.iter().any(|(p, _)| p == "signal_delay"),
        "{skipped:?}"
    );
    let (_, reason) = skipped
        .iter()
        .find(|(p, _)| p == "thermal_inertia")
        .unwrap_or_else(|| panic!("thermal_inertia tried: {skipped:?}"));
    assert!(
        reason.contains("every 60.000 s does not hold X.torque_Nm"),
        "{reason}"
    );
    // Between the instants nothing says where the simulation is right.
    assert_eq!(
        report["agreement_regions"],
        serde_json::json!([]),
        "{report}"
    );

    let on_time = compare(&exported, &real, "X.torque_Nm");
    assert_eq!(on_time["verdict"], "consistent", "{on_time}");
    assert_eq!(
        on_time["alignment"]["read_later_s"],
        serde_json::Value::Null
    );
}

/// A torque that swings by ±0.3 N·m every ten minutes for no reason the vocabulary knows
/// leaves a gross mismatch everywhere (the sensor's noise is 0.02 N·m). No span of it is
/// called right: below a threshold set by what the corrections leave is not near the noise.
#[test]
fn no_span_is_called_right_where_what_is_left_is_far_above_the_noise() {
    let real = feed_axis_csv(6, REAL);
    let swinging = with_torque(&real, |_, row| {
        let t: f64 = row[0].parse().expect("a time");
        let measured: f64 = row[torque_column()].parse().expect("a torque");
        let swing = 0.3 * (2.0 * std::f64::consts::PI * t / 600.0).sin();
        format!("{:.5}", measured + swing)
    });
    let simulated = feed_axis_csv(
        6,
        Physics {
            noisy: false,
            ..REAL
        },
    );
    let report = compare(&simulated, &swinging, "X.torque_Nm");
    let floor = &report["noise_floor"];
    let sample_noise = floor["sample_noise_rms"]
        .as_f64()
        .expect("noise_floor.sample_noise_rms");
    let left = floor["rms"].as_f64().expect("noise_floor.rms");
    assert!(left > 4.0 * sample_noise, "{floor}");
    for right in report["agreement_regions"]
        .as_array()
        .expect("agreement_regions")
    {
        let rms = right["rms_residual"].as_f64().expect("rms_residual");
        assert!(rms < 4.0 * sample_noise, "called right at {rms}: {right}");
    }
}

/// The ball-screw nut is heated by its own friction, in proportion to the speed for a friction
/// of constant force. Before the library knew that, the motor's iron loss (heat ∝ n and n²)
/// and its copper loss were offered on the nut, and named in its place; they are not offered
/// there now, and the report says why.
#[test]
fn coulomb_friction_left_out_is_named_on_the_nut_it_heats() {
    let report = coulomb_left_out(12, "ref.X.nut_temp_C");
    assert_named_first(&report, "coulomb_reversal");
    let not_tested: Vec<&str> = report["not_tested"]
        .as_array()
        .expect("not_tested")
        .iter()
        .filter_map(|n| n["physics"].as_str())
        .collect();
    for motor_loss in ["iron_loss", "copper_loss"] {
        assert!(not_tested.contains(&motor_loss), "{not_tested:?}");
    }
    assert_held_out_within_the_thermometer_noise(&report);
}

/// A feed screw that never runs faster than 400 rpm: its friction heat per 1000 rpm is also
/// given at the fastest speed it runs, which is what the nut actually sees.
#[test]
fn a_figure_per_1000_rpm_is_also_given_at_the_fastest_speed_the_axis_runs() {
    let report = coulomb_left_out(12, "ref.X.nut_temp_C");
    assert_named_first(&report, "coulomb_reversal");
    let finding = &report["findings"][0];
    let top = parameter(finding, "top_running_rpm");
    assert!(
        (300.0..=400.0).contains(&top),
        "top running speed {top} rpm"
    );
    let per_krpm = parameter(finding, "per_krpm");
    let at_top = parameter(finding, "at_top_running_speed");
    assert!((at_top - per_krpm * top / 1000.0).abs() < 1e-9 * per_krpm.abs().max(1.0));
    assert_explains(
        finding,
        &format!("at {top:.0} rpm, the fastest it runs here"),
    );
}

/// A simulation that gives the nut one convection coefficient, right for 250 rpm, against a
/// nut whose convection grows as it travels faster: the real nut runs cooler than simulated
/// at high feed and warmer at low feed and standstill. Cooling that only grows from still air
/// could not fit the part that changes sign, and the lubricant's drag heat was named instead.
/// (Over seeds 13–19 this pair is named so in 5 of 7; in the other two the nut's larger
/// share of the change is between standstill and motion, and a missing heat capacity, a
/// simpler correction, predicts the held-out blocks as well and is named with the convection
/// listed as indistinguishable.)
#[test]
fn convection_kept_at_a_nominal_speed_is_named_with_that_speed() {
    let real = Physics {
        nut_convection: Convection::GrowingWithSpeed,
        ..REAL
    };
    let sim = feed_axis_csv(
        13,
        Physics {
            nut_convection: Convection::FixedAt(250.0),
            noisy: false,
            ..real
        },
    );
    let report = compare(&sim, &feed_axis_csv(13, real), "ref.X.nut_temp_C");
    assert_named_first(&report, "speed_dependent_cooling");
    let nominal = report["findings"][0]["parameters"]["simulated_at_rpm"]
        .as_f64()
        .expect("simulated_at_rpm");
    assert!(
        (nominal - 250.0).abs() < 0.3 * 250.0,
        "nominal {nominal} rpm"
    );
    assert_held_out_within_the_thermometer_noise(&report);
}

/// A current sensor's offset and drift show only while the drive is on: switched off in the
/// dwells, it reads exactly zero. A drift over every row could not fit that, and a drift ten
/// times the noise was taken for noise (verdict `consistent`).
#[test]
fn a_current_sensor_drifting_only_while_its_drive_is_on_is_named_with_its_size() {
    let machine = Physics {
        drive_off_in_dwells: true,
        ..REAL
    };
    let sim = feed_axis_csv(
        10,
        Physics {
            noisy: false,
            ..machine
        },
    );
    let real = feed_axis_csv(
        10,
        Physics {
            current_offset_drift: (-0.1, -0.05),
            ..machine
        },
    );
    let report = compare(&sim, &real, "X.current_A");
    assert_eq!(
        named(&report),
        vec!["sensor_offset_drift".to_string()],
        "{report}"
    );
    let parameters = &report["findings"][0]["parameters"];
    let drift = parameters["drift_per_hour"]
        .as_f64()
        .expect("drift_per_hour");
    let offset = parameters["offset_while_reading"]
        .as_f64()
        .expect("offset_while_reading");
    assert!((drift + 0.05).abs() < 0.01, "drift {drift} A/h");
    assert!((offset + 0.1).abs() < 0.02, "offset {offset} A");
    // The noise from sample to sample is the sensor's, measured where the drive is on.
    assert_sample_noise_near(&report, 0.02, 0.004);
}

/// A current sensor whose zero falls through the floor: from +0.1 A by 0.3 A/h over three
/// hours, so that it reads 0 A through every dwell after the first twenty minutes and then
/// through the lighter cuts too. Fitted with each 0 A taken as its value, 0.032 A was left
/// held out, slow (a correlation time of 8 min) beside 0.02 A of noise: the readings at 0 A
/// stand for currents below it. Fitted to them as bounds, 0.016 A is left, from sample to
/// sample (less than the noise, which the floor cuts off).
#[test]
fn a_current_sensors_zero_falling_through_its_floor_is_fitted_from_the_readings_as_bounds() {
    let sim = feed_axis_csv(
        12,
        Physics {
            noisy: false,
            ..REAL
        },
    );
    let real = feed_axis_csv(
        12,
        Physics {
            current_offset_drift: (0.1, -0.3),
            ..REAL
        },
    );
    let report = compare(&sim, &real, "X.current_A");
    assert_named_first(&report, "sensor_offset_drift");
    let drift = parameter(&report["findings"][0], "drift_per_hour");
    assert!((drift + 0.3).abs() < 0.03, "drift {drift} A/h");
    let bounds = &report["alignment"]["readings_as_bounds"];
    assert!(bounds.is_object(), "{report}");
    let rmse = report["improved"]["rmse"].as_f64().expect("improved.rmse");
    assert!(rmse < 1.25 * 0.02, "held-out RMSE {rmse} A");
    // The noise from sample to sample is measured where the sensor reads above its floor.
    assert_sample_noise_near(&report, 0.02, 0.005);
}

/// The report's noise from sample to sample is `sigma` (A) to within `within`.
fn assert_sample_noise_near(report: &serde_json::Value, sigma: f64, within: f64) {
    let sample_noise = report["noise_floor"]["sample_noise_rms"]
        .as_f64()
        .expect("sample_noise_rms");
    assert!(
        (sample_noise - sigma).abs() < within,
        "sample noise {sample_noise} A"
    );
}

/// Nothing left out: the same machine's simulation and recording are consistent, its drive
/// left on in the dwells (the current's noise cut off at zero there) or switched off.
#[test]
fn the_other_machine_with_nothing_left_out_is_consistent() {
    for drive_off_in_dwells in [false, true] {
        let machine = Physics {
            drive_off_in_dwells,
            ..REAL
        };
        let sim = feed_axis_csv(
            9,
            Physics {
                noisy: false,
                ..machine
            },
        );
        let real = feed_axis_csv(9, machine);
        for target in [
            "X.stator_temp_C",
            "ref.X.nut_temp_C",
            "X.current_A",
            "X.torque_Nm",
        ] {
            let report = compare(&sim, &real, target);
            assert_eq!(
                report["verdict"], "consistent",
                "{target}, drive off in dwells {drive_off_in_dwells}: {report}"
            );
        }
    }
}

/// A nut heavier than simulated (1.6 × its heat capacity) that coolant cools in most cuts: it
/// settles faster while the coolant flows (0.6 W/K to the air, 1.6 W/K with the coolant), so
/// the lag through which it follows the simulated nut must run faster then too: 1.00 σ held
/// out, where a lag of one rate leaves 1.33 σ (and 2.2–5.6 σ on the independent check's nut).
#[test]
fn a_heavier_nut_that_the_coolant_cools_is_named_as_thermal_inertia_and_fitted() {
    let cooled = Physics {
        nut_coolant: true,
        ..REAL
    };
    // A lag of one rate leaves 1.33 × the thermometer's noise.
    let inertia = nut_finding_named_and_fitted(
        29,
        Physics {
            noisy: false,
            ..cooled
        },
        Physics {
            nut_capacity_scale: 1.6,
            ..cooled
        },
        "thermal_inertia",
    );
    assert!(parameter(&inertia, "coolant_speedup") > 0.0, "{inertia}");
    assert_explains(&inertia, "faster while the coolant");
}

/// The room's daily swing (3 K) left out of a simulation of a nut that the coolant, at room
/// temperature, cools in most cuts: the nut follows the room one to one, but 2.7 × faster
/// while the coolant flows. A lag of one rate leaves 1.9 σ held out; one that runs faster
/// while the coolant flows, and a coolant that takes nothing from how far the nut follows
/// the room, 1.0 σ.
#[test]
fn the_room_on_a_nut_the_coolant_cools_is_named_and_fitted() {
    let cooled = Physics {
        nut_coolant: true,
        ..REAL
    };
    let room = nut_finding_named_and_fitted(
        31,
        Physics {
            noisy: false,
            room_swing_k: 0.0,
            ..cooled
        },
        Physics {
            room_swing_k: 3.0,
            ..cooled
        },
        "ambient_temperature",
    );
    assert!(parameter(&room, "coolant_speedup") > 0.0, "{room}");
    // As far with the coolant flowing as with it off.
    let following =
        parameter(&room, "gain_per_K_while_coolant_flows") / parameter(&room, "gain_per_K");
    assert!((0.9..1.1).contains(&following), "{room}");
}

/// The room left out of a simulation of a nut that coolant cools in most cuts, over three
/// hours in which the room rises 2 K almost in a straight line. Held at 21 °C by a chiller, the
/// coolant lets the nut follow the room only 0.6 / 1.6 as far while it flows; at room
/// temperature, as far; either way 2.7 × faster. Through a lag of one rate the room fitted no
/// better than a thermometer drifting in a straight line, which was named in its place (here,
/// and on the independent check's nut, seed 33: drift at 25 σ); through lags that run faster
/// while the coolant flows, offered to the selection since 2026-11-29, the room is named alone,
/// as far as the nut follows it in each half. Over seeds 40–51 and three
/// coolants (36 pairs) the room was named first in 29 before and in 36 now.
#[test]
fn the_room_on_a_nut_the_coolant_cools_is_named_rather_than_a_drift() {
    for (seed, coolant_held_c, following_while_flowing) in
        [(45, Some(21.0), 0.6 / 1.6), (40, None, 1.0)]
    {
        let cooled = Physics {
            nut_coolant: true,
            coolant_held_c,
            room_swing_k: 3.0,
            ..REAL
        };
        let sim = Physics {
            noisy: false,
            room_swing_k: 0.0,
            ..cooled
        };
        let room = nut_finding_named_and_fitted(seed, sim, cooled, "ambient_temperature");
        let report = compare(
            &feed_axis_csv(seed, sim),
            &feed_axis_csv(seed, cooled),
            "ref.X.nut_temp_C",
        );
        assert_eq!(named(&report), ["ambient_temperature"], "{report}");
        assert!(parameter(&room, "coolant_speedup") > 0.0, "{room}");
        let off = parameter(&room, "gain_per_K");
        let flowing = parameter(&room, "gain_per_K_while_coolant_flows");
        assert!((0.85..1.05).contains(&off), "{room}");
        assert!(
            (flowing / off - following_while_flowing).abs() < 0.15,
            "{following_while_flowing:.3} in the machine: {room}"
        );
    }
}

/// Coolant at room temperature left out of a simulation of a nut that it cools in most cuts,
/// while the air cools the nut faster the faster it travels (forced convection, 1 + (n /
/// 150 rpm)^0.8 times its still-air conductance, in both runs): the heat the coolant takes
/// leaves the nut up to 3.2 × as fast at its top feed as at rest, so the lag through which the
/// correction acts must speed up with the feed too: 1.01 σ held out, where a lag of one rate
/// leaves 1.56 σ.
#[test]
fn coolant_on_a_nut_the_air_cools_faster_at_speed_is_named_and_fitted() {
    let convected = Physics {
        nut_convection: Convection::GrowingWithSpeed,
        ..REAL
    };
    let coolant = nut_finding_named_and_fitted(
        37,
        Physics {
            noisy: false,
            ..convected
        },
        Physics {
            nut_coolant: true,
            ..convected
        },
        "coolant",
    );
    assert!(parameter(&coolant, "convection_speedup") > 0.0, "{coolant}");
    assert_explains(&coolant, "`X.speed_rpm`");
}

/// Coolant held at 21 °C by a chiller, left out of a simulation of a nut it cools in most cuts
/// while the room swings by 3 K a day (in both runs): the coolant takes more heat from the nut
/// as the room, and the nut with it, warms above the coolant. A coolant that followed the room
/// would take the same at any room temperature, so the coolant is found held at its own
/// temperature, near the chiller's setpoint: 1.0 σ held out, where coolant taken to follow
/// the room leaves 4.8 σ.
#[test]
fn coolant_a_chiller_holds_is_named_with_its_temperature() {
    let swinging = Physics {
        room_swing_k: 3.0,
        ..REAL
    };
    let coolant = nut_finding_named_and_fitted(
        41,
        Physics {
            noisy: false,
            ..swinging
        },
        Physics {
            nut_coolant: true,
            coolant_held_c: Some(21.0),
            ..swinging
        },
        "coolant",
    );
    let held_at = parameter(&coolant, "coolant_temperature_C");
    assert!((held_at - 21.0).abs() < 0.5, "{coolant}");
    assert_explains(&coolant, "not following the room");
}

/// The nut's first finding for the simulation `sim` and the real run `real` of the feed axis
/// (both of seed `seed`), after checking that it names `physics` and that the corrected
/// simulation predicts the held-out blocks within 1.2 × the thermometer's noise (0.03 °C).
fn nut_finding_named_and_fitted(
    seed: u64,
    sim: Physics,
    real: Physics,
    physics: &str,
) -> serde_json::Value {
    let report = compare(
        &feed_axis_csv(seed, sim),
        &feed_axis_csv(seed, real),
        "ref.X.nut_temp_C",
    );
    assert_named_first(&report, physics);
    let rmse = report["improved"]["rmse"].as_f64().expect("improved.rmse");
    assert!(rmse < 1.2 * 0.03, "held-out RMSE {rmse} °C");
    report["findings"][0].clone()
}

/// A finding's parameter `name`, which it must report.
fn parameter(finding: &serde_json::Value, name: &str) -> f64 {
    finding["parameters"][name]
        .as_f64()
        .unwrap_or_else(|| panic!("no {name} in {finding}"))
}

/// The finding's explanation says `text`.
fn assert_explains(finding: &serde_json::Value, text: &str) {
    assert!(
        finding["explanation"]
            .as_str()
            .is_some_and(|e| e.contains(text)),
        "{finding}"
    );
}

/// Coolant that flows over the nut in most cuts takes its heat away 1.0 W/K faster beside its
/// 0.6 W/K to the still air: the friction heat the simulation lacks leaves through a lag that
/// runs 2.7 × faster while the coolant flows. A lag of one rate fitted neither half, and the
/// lubricant's drag heat, whose warmth term bends the same way, was named in the friction's
/// place on the independent check's nut (seeds 3 and 7).
#[test]
fn coulomb_heat_on_a_nut_the_coolant_cools_is_named_with_the_share_the_coolant_takes() {
    let real = Physics {
        nut_coolant: true,
        ..REAL
    };
    let sim = feed_axis_csv(
        12,
        Physics {
            coulomb_nm: 0.0,
            noisy: false,
            ..real
        },
    );
    let report = compare(&sim, &feed_axis_csv(12, real), "ref.X.nut_temp_C");
    assert_eq!(
        named(&report),
        vec!["coulomb_reversal".to_string()],
        "{report}"
    );
    // Held with the coolant flowing, the nut settles at 0.6 / 1.6 of its rise in still air.
    let share = parameter(&report["findings"][0], "coolant_share_of_rise");
    assert!((share - 0.625).abs() < 0.1, "coolant's share {share}");
    assert_explains(&report["findings"][0], "flowing coolant takes");
    assert_held_out_within_the_thermometer_noise(&report);
}
