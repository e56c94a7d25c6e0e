//! Streaming estimators: each takes one frame and returns its estimate, allocating nothing.
//!
//! One type per estimate, as in the paper's model table. They are pure functions of the frames
//! they have seen plus their fitted models, so the same code runs live at 1 kHz, over a replayed
//! recording, and in benchmarks.
#![allow(non_snake_case)] // unit suffixes (`_C`, `_Nm`) are part of the names

use super::models::{
    AMBIENT_LAG_TAUS_S, BED_LAG_TAUS_S, BoundModel, ELONGATION_FEATURES, ElongationModel,
    FAST_HEAT_DIVISOR, FLANGE_FEATURES, HEAT_FEATURES, HeatModel, LaneModels, LinearModel,
    PART_ACCUMULATIONS, RATIO_FEATURES, STRAIGHTNESS_FEATURES, WarmStart,
};
use super::state::{StateWalk, WalkState};

/// rpm → rad/s.
const RPM_TO_RAD_PER_S: f64 = std::f64::consts::PI / 30.0;

/// Relative difference under which a step reuses the cached factor of
/// [`HeatAccumulator`]. The time stamps of a steady rate differ from step to step by a few
/// ulp (`i as f64 / 1000.0`, or decimal text read back), which an exact comparison takes for a
/// new step, paying an `exp` on every accumulator of every frame: at 1 kHz that was a fifth of
/// the pipeline's time. A factor reused for a step 1e-9 off is 1e-9 off itself, far below what
/// any sensor resolves. The ulp of a time stamp grows with it, so late in a long run (past
/// 2¹³ s at 1 kHz) and on a live link, whose stamps are arrival times that jitter by
/// microseconds, steps still miss the cache: [`lag_factor`] makes a miss cheap there.
const SAME_STEP: f64 = 1e-9;

/// Below this Δt/τ, [`lag_factor`] sums the series instead of calling `exp`.
const SERIES_BELOW: f64 = 1e-4;

/// The share of the way a first-order lag of time constant `tau_s` moves towards its input in
/// `dt_s`, 1 − e^(−Δt/τ). For the short steps of a fast sample rate (Δt/τ below
/// [`SERIES_BELOW`]) the series x − x²/2 + x³/6 − x⁴/24 is exact to rounding (the next term is
/// x⁴/120 of the sum, under 1e-18) and both cheaper than `exp` and more accurate than
/// `1 − e^(−x)`, which loses the digits of x that cancel against the 1.
#[inline]
pub fn lag_factor(dt_s: f64, tau_s: f64) -> f64 {
    let x = dt_s / tau_s;
    if x < SERIES_BELOW {
        x * (1.0 - x * (0.5 - x * (1.0 / 6.0 - x / 24.0)))
    } else {
        1.0 - (-x).exp()
    }
}

/// First-order accumulation with time constant τ: x ← x + (1 − e^(−Δt/τ))(u − x), exact for
/// any step up to the [`SAME_STEP`] by which a reused factor's step may differ. The factor is
/// cached for the current step, so a steady sample rate computes it once.
#[derive(Debug, Clone)]
pub struct HeatAccumulator {
    tau_s: f64,
    value: f64,
    cached_dt: f64,
    cached_factor: f64,
}

impl HeatAccumulator {
    /// An empty accumulator (a machine at rest) with time constant `tau_s`.
    pub fn new(tau_s: f64) -> Self {
        HeatAccumulator {
            tau_s,
            value: 0.0,
            cached_dt: f64::NAN,
            cached_factor: 0.0,
        }
    }

    /// The paper's C_BH at a sample rate, `1 − e^(−1/(rate·τ))`: the coefficient fitted at one
    /// rate is rescaled to another through τ.
    pub fn c_bh_at_rate(tau_s: f64, rate_hz: f64) -> f64 {
        lag_factor(1.0 / rate_hz, tau_s)
    }

    /// Adds one sample of heat input `current` over `dt` seconds; returns the accumulated heat.
    #[inline]
    pub fn update(&mut self, current: f64, dt: f64) -> f64 {
        // Strict, so that neither a NaN cache (the first step) nor an infinite one (∞ < ∞
        // fails) takes a later step for its own; a zero step then recomputes its zero factor.
        let same_step = (dt - self.cached_dt).abs() < SAME_STEP * self.cached_dt;
        if !same_step {
            self.cached_dt = dt;
            self.cached_factor = if dt > 0.0 {
                lag_factor(dt, self.tau_s)
            } else {
                0.0
            };
        }
        self.value += self.cached_factor * (current - self.value);
        self.value
    }

    /// The accumulated heat.
    pub fn value(&self) -> f64 {
        self.value
    }

    /// Sets the accumulated value, as if the input had been `value` for a long time.
    pub fn settle_at(&mut self, value: f64) {
        self.value = value;
    }
}

/// The room temperature now and through the lags of [`AMBIENT_LAG_TAUS_S`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Room {
    /// Room temperature, °C (NaN when the recording has none).
    pub ambient_C: f64,
    /// The room through each lag, °C, in the order of [`AMBIENT_LAG_TAUS_S`].
    pub lags_C: [f64; 3],
}

/// A signal through first-order lags of fixed time constants that start settled at its first
/// finite reading: a machine that has stood still is at rest with its surroundings, so starting
/// the lags at zero would invent a warm-up. A missing reading (NaN) leaves them where they were
/// rather than poisoning them (and reads NaN until the first finite one).
#[derive(Debug, Clone)]
pub struct SettledLags<const N: usize> {
    lags: [HeatAccumulator; N],
    started: bool,
}

impl<const N: usize> SettledLags<N> {
    /// Lags of time constants `taus_s`, not yet started.
    pub fn new(taus_s: [f64; N]) -> Self {
        SettledLags {
            lags: taus_s.map(HeatAccumulator::new),
            started: false,
        }
    }

    /// Takes one reading over `dt` seconds; returns the signal through each lag.
    #[inline]
    pub fn update(&mut self, value: f64, dt: f64) -> [f64; N] {
        if !value.is_finite() {
            return if self.started {
                self.lags.each_ref().map(HeatAccumulator::value)
            } else {
                [f64::NAN; N]
            };
        }
        if !self.started {
            self.started = true;
            for lag in &mut self.lags {
                lag.settle_at(value);
            }
        }
        self.lags.each_mut().map(|lag| lag.update(value, dt))
    }
}

/// Follows the room through the slow lags of the machine's mass ([`AMBIENT_LAG_TAUS_S`]),
/// settled at the first room reading ([`SettledLags`]).
#[derive(Debug, Clone)]
pub struct RoomLags {
    lags: SettledLags<3>,
}

impl Default for RoomLags {
    fn default() -> Self {
        RoomLags {
            lags: SettledLags::new(AMBIENT_LAG_TAUS_S),
        }
    }
}

impl RoomLags {
    /// Takes one room reading over `dt` seconds.
    #[inline]
    pub fn update(&mut self, ambient_C: f64, dt: f64) -> Room {
        let lags_C = self.lags.update(ambient_C, dt);
        Room {
            ambient_C: if ambient_C.is_finite() {
                ambient_C
            } else {
                f64::NAN
            },
            lags_C,
        }
    }
}

/// The bed's slow state as the straightness models read it: the estimated motor and
/// back-bearing temperatures through the lags of [`BED_LAG_TAUS_S`], settled at their first
/// values ([`SettledLags`]). The coolant's lags are the machine's, kept by the pipeline.
#[derive(Debug, Clone)]
pub struct BedLags {
    motor: SettledLags<2>,
    back: SettledLags<2>,
}

impl Default for BedLags {
    fn default() -> Self {
        BedLags {
            motor: SettledLags::new(BED_LAG_TAUS_S),
            back: SettledLags::new(BED_LAG_TAUS_S),
        }
    }
}

impl BedLags {
    /// Takes one frame's estimated motor and back-bearing temperatures over `dt` seconds;
    /// returns them through each lag, °C.
    #[inline]
    pub fn update(&mut self, motor_C: f64, back_C: f64, dt: f64) -> ([f64; 2], [f64; 2]) {
        (self.motor.update(motor_C, dt), self.back.update(back_C, dt))
    }
}

/// What a feed axis's thermal models read besides their own heat, taken once per axis and
/// frame so that the flange and every component share the same lags.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ThermalSurroundings {
    /// The axis's stator temperature, °C.
    pub stator_C: f64,
    /// The stator through the lags of
    /// [`STATOR_LAG_TAUS_S`](super::models::STATOR_LAG_TAUS_S), °C (settled at its first
    /// reading).
    pub stator_lags_C: [f64; 3],
    /// The room now and through its lags.
    pub room: Room,
    /// The coolant's on/off state (0–1) through the lags of [`BED_LAG_TAUS_S`] (NaN when the
    /// recording has no coolant column).
    pub coolant_lags: [f64; 2],
}

/// Motor flange temperature from the stator temperature (Eq. 7), and, where the model reads
/// them, the stator through the lags of
/// [`STATOR_LAG_TAUS_S`](super::models::STATOR_LAG_TAUS_S) and the room through its lags.
#[derive(Debug, Clone)]
pub struct MotorFlangeEstimator {
    model: BoundModel,
}

impl MotorFlangeEstimator {
    /// Binds the fitted model.
    pub fn new(model: &LinearModel) -> Result<Self, String> {
        Ok(MotorFlangeEstimator {
            model: BoundModel::bind(model, FLANGE_FEATURES)?,
        })
    }

    /// °C from one frame's surroundings (the flange has no heat of its own).
    #[inline]
    pub fn update(&self, s: &ThermalSurroundings) -> f64 {
        let [stator_5, stator_15, stator_45] = s.stator_lags_C;
        let [room_30, room_90, room_270] = s.room.lags_C;
        self.model.eval(&[
            1.0,
            s.stator_C,
            s.room.ambient_C,
            stator_5,
            stator_15,
            stator_45,
            room_30,
            room_90,
            room_270,
        ])
    }
}

/// The motor torque split into front bearing, back bearing and nut torque (Eq. 8).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct TorqueSplit {
    /// Both support bearings, N·m.
    pub bearing_Nm: f64,
    /// Front (fixed-side) bearing, N·m.
    pub front_bearing_Nm: f64,
    /// Back bearing, N·m.
    pub back_bearing_Nm: f64,
    /// Nut, N·m.
    pub nut_Nm: f64,
}

/// Splits motor torque with the fitted ratio cubics: τ_B = τ_M / (1 + r_BN), τ_N = τ_M − τ_B,
/// and the bearings the same way with the back-to-front ratio.
#[derive(Debug, Clone)]
pub struct TorqueSplitEstimator {
    nut_bearing: BoundModel,
    back_front: BoundModel,
}

impl TorqueSplitEstimator {
    /// Binds the two ratio models.
    pub fn new(nut_bearing: &LinearModel, back_front: &LinearModel) -> Result<Self, String> {
        Ok(TorqueSplitEstimator {
            nut_bearing: BoundModel::bind(nut_bearing, RATIO_FEATURES)?,
            back_front: BoundModel::bind(back_front, RATIO_FEATURES)?,
        })
    }

    /// Splits `motor_Nm`. Ratios are kept non-negative: a negative fitted ratio at the edge of
    /// the calibrated range would flip a component's torque, which no physics allows.
    #[inline]
    pub fn update(&self, motor_Nm: f64) -> TorqueSplit {
        let t = motor_Nm;
        let features = [1.0, t, t * t, t * t * t];
        let r_nb = self.nut_bearing.eval(&features).max(0.0);
        let r_bf = self.back_front.eval(&features).max(0.0);
        let bearing = t / (1.0 + r_nb);
        let front = bearing / (1.0 + r_bf);
        TorqueSplit {
            bearing_Nm: bearing,
            front_bearing_Nm: front,
            back_bearing_Nm: bearing - front,
            nut_Nm: t - bearing,
        }
    }
}

/// Component temperature from accumulated friction heat (Eqs. 9–12).
///
/// Eq. 11's heat H′ = C_HB·τ·n has three parts here. The preload drag torque of a bearing or
/// nut is nearly constant, so its heat is ∝ n; the load-dependent part is ∝ n·|τ|; and a
/// bearing's load-free (churning) torque grows as (ν·n)^(2/3) (Palmgren), so its heat as
/// |n|^(5/3). Each is accumulated with the fitted τ (Eq. 10). `n` is the sampled speed, taken
/// at the same instant as the torque: at 1 Hz one sample of a short rapid move is noisy, but
/// a sampler that is not locked to the program's cycle sees each phase of it equally often,
/// and the accumulation averages it out. (The encoder's travel over the interval, used
/// before, is blind to a move and its return within one interval and makes |n|^(5/3) of an
/// average speed, which understates a rapid's churning.) The drag and load heat are also
/// accumulated over τ / [`FAST_HEAT_DIVISOR`] when the model reads them
/// ([`FAST_HEAT_FEATURES`](super::models::FAST_HEAT_FEATURES)).
#[derive(Debug, Clone)]
pub struct ComponentThermalEstimator {
    heat: HeatAccumulator,
    load_heat: HeatAccumulator,
    churning_heat: HeatAccumulator,
    /// The drag and load heat over the fast τ, only where the model reads either.
    fast_heat: Option<[HeatAccumulator; 2]>,
    model: BoundModel,
    warm_start: Option<WarmStart>,
    /// False until the first sample, which seeds the accumulators ([`WarmStart`]).
    started: bool,
}

impl ComponentThermalEstimator {
    /// Binds a fitted heat model. The accumulators use the model's τ (the fast ones τ /
    /// [`FAST_HEAT_DIVISOR`]), which is what rescales C_BH to the live sample rate.
    pub fn new(model: &HeatModel) -> Result<Self, String> {
        let bound = BoundModel::bind(&model.temperature, HEAT_FEATURES)?;
        let reads_fast = model.reads_fast_heat();
        let fast_tau_s = model.tau_s / FAST_HEAT_DIVISOR;
        Ok(ComponentThermalEstimator {
            heat: HeatAccumulator::new(model.tau_s),
            load_heat: HeatAccumulator::new(model.tau_s),
            churning_heat: HeatAccumulator::new(model.tau_s),
            fast_heat: reads_fast.then(|| {
                [
                    HeatAccumulator::new(fast_tau_s),
                    HeatAccumulator::new(fast_tau_s),
                ]
            }),
            model: bound,
            warm_start: model.warm_start.clone(),
            started: false,
        })
    }

    /// Seeds the accumulators from the first sample's stator excess over the room, where the
    /// model has a [`WarmStart`]; a first sample without a room or stator reading starts the
    /// part at rest. Only ever at the first sample: seeding later would overwrite heat the
    /// estimator has accumulated itself.
    #[cold]
    fn start(&mut self, surroundings: &ThermalSurroundings) {
        self.started = true;
        let Some(warm) = &self.warm_start else {
            return;
        };
        let [heat, load_heat, churning_heat, heat_fast, load_heat_fast] = warm.seeds(
            &PART_ACCUMULATIONS,
            surroundings.stator_C,
            surroundings.room.ambient_C,
        );
        self.heat.settle_at(heat);
        self.load_heat.settle_at(load_heat);
        self.churning_heat.settle_at(churning_heat);
        if let Some([drag, load]) = &mut self.fast_heat {
            drag.settle_at(heat_fast);
            load.settle_at(load_heat_fast);
        }
    }

    /// The model's [`WarmStart`], if it has one (it seeds the heat on a warm machine).
    pub fn warm_start(&self) -> Option<&WarmStart> {
        self.warm_start.as_ref()
    }

    /// °C after one sample, from the component's torque, the axis's sampled speed (as
    /// [`SpeedHeat`], computed once per axis and frame) and the axis's surroundings.
    #[inline]
    pub fn update(
        &mut self,
        torque_Nm: f64,
        speed: &SpeedHeat,
        surroundings: &ThermalSurroundings,
        dt: f64,
    ) -> f64 {
        if !self.started {
            self.start(surroundings);
        }
        let inputs = heat_inputs(torque_Nm, speed);
        let h = self.heat.update(inputs.drag, dt);
        let l = self.load_heat.update(inputs.load, dt);
        let c = self.churning_heat.update(inputs.churning, dt);
        let [h_fast, l_fast] = match &mut self.fast_heat {
            Some([drag, load]) => [drag.update(inputs.drag, dt), load.update(inputs.load, dt)],
            // The model has no such terms and never reads these slots.
            None => [0.0; 2],
        };
        let s = surroundings;
        let [room_30, room_90, room_270] = s.room.lags_C;
        let [stator_5, stator_15, stator_45] = s.stator_lags_C;
        let [coolant_30, coolant_90] = s.coolant_lags;
        // Typed to the feature list's length, so a feature added there fails to compile here.
        let features: [f64; HEAT_FEATURES.len()] = [
            1.0,
            s.stator_C,
            s.room.ambient_C,
            h,
            l,
            c,
            h_fast,
            l_fast,
            room_30,
            room_90,
            room_270,
            stator_5,
            stator_15,
            stator_45,
            coolant_30,
            coolant_90,
        ];
        self.model.eval(&features)
    }

    /// True if the model reads a feature whose name starts with `prefix` (to check that the
    /// recording has the signals it needs).
    pub fn uses_features_starting_with(&self, prefix: &str) -> bool {
        self.model
            .uses_features_starting_with(HEAT_FEATURES, prefix)
    }

    /// The accumulated drag heat.
    pub fn heat(&self) -> f64 {
        self.heat.value()
    }

    /// The accumulated load heat.
    pub fn load_heat(&self) -> f64 {
        self.load_heat.value()
    }
}

/// The heat inputs of a component in one sample (see [`ComponentThermalEstimator`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeatInputs {
    /// Drag heat ∝ speed, krpm.
    pub drag: f64,
    /// Load heat ∝ speed × |torque|, kW-like units (N·m · rad/s / 1000).
    pub load: f64,
    /// Churning heat ∝ |speed|^(5/3), krpm^(5/3).
    pub churning: f64,
}

/// The speed-dependent part of the heat inputs, shared by every component of an axis (the
/// churning term's cube root is the costliest operation of a frame, so it is taken once).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpeedHeat {
    /// The sampled speed, rpm.
    pub speed_rpm: f64,
    /// |n|, krpm.
    pub krpm: f64,
    /// |n|^(5/3), krpm^(5/3).
    pub churning: f64,
}

impl SpeedHeat {
    /// The speed terms of one sample.
    #[inline]
    pub fn of(speed_rpm: f64) -> Self {
        let krpm = speed_rpm.abs() / 1000.0;
        SpeedHeat {
            speed_rpm,
            krpm,
            churning: krpm * cube_root(krpm).powi(2),
        }
    }
}

/// ∛x to within an ulp or two of `f64::cbrt`, in half its time.
///
/// The churning term takes a cube root per axis and frame, and the toolchain's `cbrt` is
/// libm's correctly rounded one, which profiling showed as a fifth of the estimator pipeline's
/// time. Here the exponent is divided by three on the bit pattern (the classic first guess,
/// within a few percent), two Halley steps (cubic convergence: 3 % → 1e-5 → 1e-15) and a
/// Newton step polish it. Zero, subnormals, infinities, NaN and magnitudes above 1e300 (whose
/// cube the steps would overflow) go to `f64::cbrt`.
#[inline]
pub fn cube_root(x: f64) -> f64 {
    if !x.is_normal() || x.abs() > 1e300 {
        return x.cbrt();
    }
    let a = x.abs();
    let mut y = f64::from_bits(a.to_bits() / 3 + 0x2A9F_7893_782D_A1CE);
    for _ in 0..2 {
        let y3 = y * y * y;
        y *= (y3 + 2.0 * a) / (2.0 * y3 + a);
    }
    y -= (y * y * y - a) / (3.0 * y * y);
    y.copysign(x)
}

/// The heat inputs of a component from its torque and the axis's sampled speed.
#[inline]
pub fn heat_inputs(torque_Nm: f64, speed: &SpeedHeat) -> HeatInputs {
    HeatInputs {
        drag: speed.krpm,
        load: (torque_Nm * speed.speed_rpm * RPM_TO_RAD_PER_S).abs() / 1000.0,
        churning: speed.churning,
    }
}

/// What the straightness models read: the estimated temperatures and the thermal states
/// behind them (see [`STRAIGHTNESS_FEATURES`]).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StraightnessInputs {
    /// Estimated front-bearing temperature, °C.
    pub front_C: f64,
    /// Estimated back-bearing temperature, °C.
    pub back_C: f64,
    /// Estimated motor (flange) temperature, °C.
    pub motor_C: f64,
    /// Room temperature, °C.
    pub ambient_C: f64,
    /// The room through the lags of [`AMBIENT_LAG_TAUS_S`], °C.
    pub ambient_lags_C: [f64; 3],
    /// Stator temperature, °C.
    pub stator_C: f64,
    /// Front bearing's accumulated drag heat.
    pub front_heat: f64,
    /// Front bearing's accumulated load heat.
    pub front_load_heat: f64,
    /// Back bearing's accumulated drag heat.
    pub back_heat: f64,
    /// Back bearing's accumulated load heat.
    pub back_load_heat: f64,
    /// Estimated nut temperature, °C (NaN without a nut model).
    pub nut_C: f64,
    /// The estimated motor temperature through the lags of [`BED_LAG_TAUS_S`], °C.
    pub motor_lags_C: [f64; 2],
    /// The estimated back-bearing temperature through the lags of [`BED_LAG_TAUS_S`], °C.
    pub back_lags_C: [f64; 2],
    /// The coolant's on/off state (0–1) through the lags of [`BED_LAG_TAUS_S`] (NaN when the
    /// recording has no coolant column).
    pub coolant_lags: [f64; 2],
}

/// Number of [`STRAIGHTNESS_FEATURES`].
pub const STRAIGHTNESS_FEATURE_COUNT: usize = STRAIGHTNESS_FEATURES.len();

/// The values of [`STRAIGHTNESS_FEATURES`], in its order, from what the models read: built
/// once per axis and frame, and read by both directions' [`StraightnessEstimator`]s.
#[inline]
pub fn straightness_features(inputs: &StraightnessInputs) -> [f64; STRAIGHTNESS_FEATURE_COUNT] {
    let i = inputs;
    let (f2, b2, m2) = (
        i.front_C * i.front_C,
        i.back_C * i.back_C,
        i.motor_C * i.motor_C,
    );
    [
        1.0,
        i.front_C,
        f2,
        f2 * i.front_C,
        i.back_C,
        b2,
        b2 * i.back_C,
        i.motor_C,
        m2,
        m2 * i.motor_C,
        i.ambient_C,
        i.stator_C,
        i.front_heat,
        i.front_load_heat,
        i.back_heat,
        i.back_load_heat,
        i.ambient_lags_C[0],
        i.ambient_lags_C[1],
        i.ambient_lags_C[2],
        i.nut_C,
        i.motor_lags_C[0],
        i.motor_lags_C[1],
        i.back_lags_C[0],
        i.back_lags_C[1],
        i.coolant_lags[0],
        i.coolant_lags[1],
    ]
}

/// Largest number of straightness nodes an axis may have.
pub const MAX_NODES: usize = 16;

/// Straightness deviation per node from estimated temperatures (Eqs. 13–14), and the ISO 1101
/// minimum-zone straightness value over the nodes.
///
/// The nodes of a direction are evaluated together, eight to a block ([`LaneModels`]): the
/// shipped calibration gives every node the same terms, and summed one node at a time the
/// nodes were the pipeline's costliest step (a third of its `perf` samples).
#[derive(Debug, Clone)]
pub struct StraightnessEstimator {
    nodes: LaneModels<8>,
    positions_mm: Vec<f64>,
}

impl StraightnessEstimator {
    /// Binds one model per node.
    pub fn new(models: &[LinearModel], positions_mm: &[f64]) -> Result<Self, String> {
        if models.len() != positions_mm.len() {
            return Err(format!(
                "{} straightness models for {} nodes",
                models.len(),
                positions_mm.len()
            ));
        }
        if models.len() > MAX_NODES {
            return Err(format!("at most {MAX_NODES} straightness nodes"));
        }
        let models = models
            .iter()
            .map(|m| BoundModel::bind(m, STRAIGHTNESS_FEATURES))
            .collect::<Result<_, _>>()?;
        Ok(StraightnessEstimator {
            nodes: LaneModels::new(models),
            positions_mm: positions_mm.to_vec(),
        })
    }

    /// Fills `out` with each node's deviation, µm, from the frame's
    /// [`straightness_features`]. The ISO 1101 value is a pure function of these and is
    /// computed when read ([`minimum_zone_straightness`]), not on every frame.
    #[inline]
    pub fn update(&self, features: &[f64; STRAIGHTNESS_FEATURE_COUNT], out: &mut [f64; MAX_NODES]) {
        self.nodes.eval_shared(features, out.as_mut_slice());
    }

    /// True if a node's model reads a feature whose name starts with `prefix` (to check that
    /// the recording and the profile provide what it needs).
    pub fn uses_features_starting_with(&self, prefix: &str) -> bool {
        self.nodes
            .models()
            .iter()
            .any(|m| m.uses_features_starting_with(STRAIGHTNESS_FEATURES, prefix))
    }

    /// Node positions along the stroke, mm.
    pub fn positions_mm(&self) -> &[f64] {
        &self.positions_mm
    }

    /// Number of nodes.
    pub fn nodes(&self) -> usize {
        self.nodes.models().len()
    }
}

/// ISO 1101 straightness of a profile given as deviations `d` at positions `x`: the smallest
/// distance, measured in the direction of the deviation, between two parallel lines enclosing
/// every point (the minimum zone). The optimal pair of lines is parallel to a line through two
/// of the points (a vertex of the convex hull), so trying every pair is exact; it is O(n³),
/// which for the handful of nodes of an axis is a few hundred operations.
pub fn minimum_zone_straightness(x: &[f64], d: &[f64]) -> f64 {
    let n = x.len().min(d.len());
    if n < 2 {
        return 0.0;
    }
    let width = |slope: f64| {
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for i in 0..n {
            let r = d[i] - slope * x[i];
            lo = lo.min(r);
            hi = hi.max(r);
        }
        hi - lo
    };
    let mut best = f64::INFINITY;
    for i in 0..n {
        for j in (i + 1)..n {
            let dx = x[j] - x[i];
            if dx.abs() > 1e-12 {
                best = best.min(width((d[j] - d[i]) / dx));
            }
        }
    }
    best
}

/// One frame of what the spindle elongation reads.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ElongationInputs {
    /// Stator temperature, °C.
    pub stator_C: f64,
    /// Spindle speed, rpm.
    pub speed_rpm: f64,
    /// Load, % of rated (0 when the recording has none).
    pub load_pct: f64,
    /// Motor current, A (NaN when the recording has none).
    pub current_A: f64,
    /// Coolant on (1) or off (0) (NaN when the recording has none).
    pub coolant_on: f64,
    /// The room now and through its lags.
    pub room: Room,
}

/// Number of [`ELONGATION_FEATURES`].
const ELONGATION_FEATURE_COUNT: usize = 32;

/// The values of [`ELONGATION_FEATURES`] frame by frame, ΔT and the room counted from the
/// tool-calibration moment. Calibration builds its regressor columns with this same type, so
/// the fitted coefficients meet exactly the features they were fitted on.
#[derive(Debug, Clone)]
pub struct ElongationFeatures {
    /// One accumulator per input of [`super::models::ELONGATION_HEAT_INPUTS`] and time
    /// constant of [`super::models::ELONGATION_TAU_NAMES`].
    heat: [[HeatAccumulator; 4]; 6],
    stator_at_calibration: Option<f64>,
    /// The room and its lags at the calibration moment (the first finite room reading since).
    room_at_calibration: Option<(f64, [f64; 3])>,
    values: [f64; ELONGATION_FEATURE_COUNT],
}

impl ElongationFeatures {
    /// A spindle at rest, with heat accumulated over `taus_s` (fast, mid, slow, long).
    pub fn new(taus_s: [f64; 4]) -> Self {
        ElongationFeatures {
            heat: [(); 6].map(|_| taus_s.map(HeatAccumulator::new)),
            stator_at_calibration: None,
            room_at_calibration: None,
            values: [0.0; ELONGATION_FEATURE_COUNT],
        }
    }

    /// The time constants of a fitted model.
    pub fn for_model(model: &ElongationModel) -> Self {
        ElongationFeatures::new([
            model.fast_tau_s,
            model.mid_tau_s,
            model.slow_tau_s,
            model.long_tau_s,
        ])
    }

    /// ΔT and the room count from the next frame.
    pub fn reset_tool_calibration(&mut self) {
        self.stator_at_calibration = None;
        self.room_at_calibration = None;
    }

    /// Takes one frame over `dt` seconds; returns the features in [`ELONGATION_FEATURES`]'
    /// order.
    #[inline]
    pub fn update(
        &mut self,
        inputs: &ElongationInputs,
        dt: f64,
    ) -> &[f64; ELONGATION_FEATURE_COUNT] {
        let speed = SpeedHeat::of(inputs.speed_rpm);
        let load = inputs.load_pct.abs();
        let room = inputs.room.ambient_C;
        let drivers = [
            speed.krpm,
            load,
            speed.churning,
            inputs.current_A * inputs.current_A / 100.0,
            inputs.coolant_on,
            inputs.coolant_on * (inputs.stator_C - room),
        ];
        let stator_reference = *self.stator_at_calibration.get_or_insert(inputs.stator_C);
        if self.room_at_calibration.is_none() && room.is_finite() {
            self.room_at_calibration = Some((room, inputs.room.lags_C));
        }
        let (room_reference, lags_reference) = self
            .room_at_calibration
            .unwrap_or((f64::NAN, [f64::NAN; 3]));
        let v = &mut self.values;
        v[0] = 1.0;
        v[1] = inputs.stator_C - stator_reference;
        v[2] = speed.krpm;
        v[3] = load;
        for (k, (accumulators, driver)) in self.heat.iter_mut().zip(drivers).enumerate() {
            for (j, accumulator) in accumulators.iter_mut().enumerate() {
                v[4 + 4 * k + j] = accumulator.update(driver, dt);
            }
        }
        v[28] = room - room_reference;
        for (j, (lag, reference)) in inputs.room.lags_C.iter().zip(lags_reference).enumerate() {
            v[29 + j] = lag - reference;
        }
        &self.values
    }
}

/// Spindle thermal elongation (Eq. 15) since the tool-calibration moment, which the operator
/// can reset.
#[derive(Debug, Clone)]
pub struct SpindleElongationEstimator {
    model: BoundModel,
    features: ElongationFeatures,
    elongation_at_calibration: Option<f64>,
}

impl SpindleElongationEstimator {
    /// Binds the fitted model.
    pub fn new(model: &ElongationModel) -> Result<Self, String> {
        Ok(SpindleElongationEstimator {
            model: BoundModel::bind(&model.model, ELONGATION_FEATURES)?,
            features: ElongationFeatures::for_model(model),
            elongation_at_calibration: None,
        })
    }

    /// True if the model reads a feature whose name starts with `prefix` (to check that the
    /// recording has the signals it needs).
    pub fn uses_features_starting_with(&self, prefix: &str) -> bool {
        self.model
            .uses_features_starting_with(ELONGATION_FEATURES, prefix)
    }

    /// The operator measured the tool length now: elongation counts from here. Takes effect on
    /// the next frame.
    pub fn reset_tool_calibration(&mut self) {
        self.features.reset_tool_calibration();
        self.elongation_at_calibration = None;
    }

    /// µm since the tool calibration (NaN until the model can be evaluated, e.g. before the
    /// first room reading of a model that reads the room).
    #[inline]
    pub fn update(&mut self, inputs: &ElongationInputs, dt: f64) -> f64 {
        let value = self.model.eval(self.features.update(inputs, dt));
        if self.elongation_at_calibration.is_none() && value.is_finite() {
            self.elongation_at_calibration = Some(value);
        }
        value - self.elongation_at_calibration.unwrap_or(f64::NAN)
    }
}

impl WalkState for HeatAccumulator {
    fn walk_state(&mut self, walk: &mut StateWalk<'_>) {
        // The cached factor belongs to τ and the step, not to the state.
        walk.value(&mut self.value);
    }
}

impl<const N: usize> WalkState for SettledLags<N> {
    fn walk_state(&mut self, walk: &mut StateWalk<'_>) {
        self.lags.walk_state(walk);
        walk.flag(&mut self.started);
    }
}

impl WalkState for RoomLags {
    fn walk_state(&mut self, walk: &mut StateWalk<'_>) {
        self.lags.walk_state(walk);
    }
}

impl WalkState for BedLags {
    fn walk_state(&mut self, walk: &mut StateWalk<'_>) {
        self.motor.walk_state(walk);
        self.back.walk_state(walk);
    }
}

impl WalkState for ComponentThermalEstimator {
    fn walk_state(&mut self, walk: &mut StateWalk<'_>) {
        self.heat.walk_state(walk);
        self.load_heat.walk_state(walk);
        self.churning_heat.walk_state(walk);
        self.fast_heat.walk_state(walk);
        // Restored as started, a part is never seeded again from the warm start.
        walk.flag(&mut self.started);
    }
}

impl WalkState for ElongationFeatures {
    fn walk_state(&mut self, walk: &mut StateWalk<'_>) {
        self.heat.walk_state(walk);
        walk.optional(&mut self.stator_at_calibration);
        let mut room = self.room_at_calibration.map(|(room, _)| room);
        let mut lags = self
            .room_at_calibration
            .map_or([f64::NAN; 3], |(_, lags)| lags);
        walk.optional(&mut room);
        walk.values(&mut lags);
        self.room_at_calibration = room.map(|room| (room, lags));
    }
}

impl WalkState for SpindleElongationEstimator {
    fn walk_state(&mut self, walk: &mut StateWalk<'_>) {
        self.features.walk_state(walk);
        walk.optional(&mut self.elongation_at_calibration);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::estimators::models::{STATOR_LAG_TAUS_S, WARM_START_FLOOR_K};

    #[test]
    fn minimum_zone_of_a_straight_line_is_zero_and_of_a_bow_is_its_sag() {
        let x = [0.0, 100.0, 200.0, 300.0, 400.0];
        assert!(minimum_zone_straightness(&x, &[1.0, 3.0, 5.0, 7.0, 9.0]).abs() < 1e-12);
        // A symmetric bow 0, 3, 4, 3, 0: the zone is the 4 µm sag (end points on one line).
        assert!((minimum_zone_straightness(&x, &[0.0, 3.0, 4.0, 3.0, 0.0]) - 4.0).abs() < 1e-12);
        // A tilted bow has the same straightness.
        let tilted: Vec<f64> = [0.0, 3.0, 4.0, 3.0, 0.0]
            .iter()
            .zip(&x)
            .map(|(d, x)| d + 0.01 * x)
            .collect();
        assert!((minimum_zone_straightness(&x, &tilted) - 4.0).abs() < 1e-9);
    }

    fn straightness_inputs(seed: f64) -> StraightnessInputs {
        let v = |k: f64| 20.0 + (seed * 7.3 + k * 1.9).sin() * 3.0;
        StraightnessInputs {
            front_C: v(1.0),
            back_C: v(2.0),
            motor_C: v(3.0),
            ambient_C: v(4.0),
            ambient_lags_C: [v(5.0), v(6.0), v(7.0)],
            stator_C: v(8.0),
            front_heat: v(9.0) / 40.0,
            front_load_heat: v(10.0) / 90.0,
            back_heat: v(11.0) / 40.0,
            back_load_heat: v(12.0) / 90.0,
            nut_C: v(13.0),
            motor_lags_C: [v(14.0), v(15.0)],
            back_lags_C: [v(16.0), v(17.0)],
            coolant_lags: [0.3, 0.6],
        }
    }

    /// The nodes are summed together, a block of them per fetched feature; each node's value
    /// must be its own model's sum, bit for bit where the nodes list their terms in the same
    /// order (as calibration writes them), across a block boundary (nine nodes), with nodes
    /// that read different terms, and with the slots past the last node left alone.
    #[test]
    fn straightness_nodes_summed_together_equal_each_nodes_own_model() {
        let shared = [
            "const",
            "front",
            "back",
            "motor",
            "nut",
            "ambient_lag_90min",
        ];
        let mut models: Vec<LinearModel> = (0..9)
            .map(|k| {
                let k = k as f64;
                let c: Vec<f64> = (0..shared.len())
                    .map(|j| (k + 1.0) * 0.37 - j as f64 * 0.11)
                    .collect();
                LinearModel::with_terms(&shared, &c)
            })
            .collect();
        // Node 4 reads fewer terms, node 7 one no other node reads.
        models[3] = LinearModel::with_terms(&["const", "back"], &[0.5, -1.25]);
        models[6] = LinearModel::with_terms(&["const", "front", "stator"], &[0.1, 2.0, -0.7]);
        let positions: Vec<f64> = (0..9).map(|k| k as f64 * 50.0).collect();
        let estimator = StraightnessEstimator::new(&models, &positions).expect("binds");
        let bound: Vec<BoundModel> = models
            .iter()
            .map(|m| BoundModel::bind(m, STRAIGHTNESS_FEATURES).expect("binds"))
            .collect();
        for seed in 0..20 {
            let inputs = straightness_inputs(seed as f64);
            let mut out = [-999.0; MAX_NODES];
            let features = straightness_features(&inputs);
            estimator.update(&features, &mut out);
            for (k, model) in bound.iter().enumerate() {
                let own = model.eval(&features);
                assert_eq!(out[k].to_bits(), own.to_bits(), "node {}", k + 1);
            }
            assert!(
                out[9..].iter().all(|&v| v == -999.0),
                "slots past the nodes"
            );
        }
    }

    /// A reading the models cannot have (the nut's estimate missing) makes the nodes that read
    /// it unknown and leaves the others their value: a zero coefficient must not carry the NaN.
    #[test]
    fn a_missing_feature_leaves_the_nodes_that_do_not_read_it_their_value() {
        let models = [
            LinearModel::with_terms(&["const", "front", "nut"], &[1.0, 0.5, 0.25]),
            LinearModel::with_terms(&["const", "front"], &[1.0, 0.5]),
        ];
        let estimator = StraightnessEstimator::new(&models, &[0.0, 100.0]).expect("binds");
        let mut inputs = straightness_inputs(1.0);
        let mut out = [f64::NAN; MAX_NODES];
        estimator.update(&straightness_features(&inputs), &mut out);
        assert!(out[0].is_finite() && out[1].is_finite());
        for missing in [f64::NAN, f64::INFINITY] {
            inputs.nut_C = missing;
            estimator.update(&straightness_features(&inputs), &mut out);
            assert!(!out[0].is_finite());
            assert_eq!(out[1], 1.0 + 0.5 * inputs.front_C);
        }
    }

    /// The minimum zone never exceeds the zone around the end-point line and is never negative.
    #[test]
    fn minimum_zone_is_at_most_the_end_point_zone() {
        let x = [0.0, 50.0, 120.0, 260.0, 300.0, 410.0];
        let d = [0.3, -1.2, 2.5, 0.1, -0.7, 1.9];
        let slope = (d[5] - d[0]) / (x[5] - x[0]);
        let residuals: Vec<f64> = (0..6).map(|i| d[i] - slope * x[i]).collect();
        let end_point = residuals.iter().cloned().fold(f64::NEG_INFINITY, f64::max)
            - residuals.iter().cloned().fold(f64::INFINITY, f64::min);
        let zone = minimum_zone_straightness(&x, &d);
        assert!(zone >= 0.0 && zone <= end_point + 1e-12);
    }

    /// Time stamps of a steady 1 kHz rate, as floating point makes them (`i / 1000`), step by
    /// a few ulp more or less each sample: they are one rate, whose factor is computed once,
    /// and the accumulation follows the closed form 1 − e^(−t/τ) to far below any sensor's
    /// resolution. A step that is truly different (a millionth longer) gets its own factor,
    /// and an infinite step does not stand for every step after it.
    #[test]
    fn steps_that_differ_by_rounding_alone_accumulate_as_one_rate() {
        let tau = 120.0;
        let mut acc = HeatAccumulator::new(tau);
        let mut previous = 0.0;
        for i in 1..=200_000 {
            let t = i as f64 / 1000.0;
            acc.update(1.0, t - previous);
            assert_eq!(
                acc.cached_dt, 0.001,
                "the step at {t} s was taken for a new one"
            );
            previous = t;
        }
        let exact = -(-200.0_f64 / tau).exp_m1();
        assert!(
            (acc.value() - exact).abs() < 1e-9 * exact,
            "{} against {exact}",
            acc.value()
        );
        let mut acc = HeatAccumulator::new(tau);
        acc.update(1.0, 1.0);
        acc.update(1.0, 1.000_001);
        let exact = -(-2.000_001_f64 / tau).exp_m1();
        assert!(
            (acc.value() - exact).abs() < 1e-15,
            "{} against {exact}",
            acc.value()
        );
        let mut acc = HeatAccumulator::new(tau);
        acc.update(1.0, f64::INFINITY);
        acc.update(0.0, 1.0);
        let exact = (-1.0 / tau).exp();
        assert!(
            (acc.value() - exact).abs() < 1e-15,
            "{} against {exact}",
            acc.value()
        );
    }

    /// The lag's factor for the short steps of a fast rate is the series, exact to rounding
    /// against `exp_m1` (which `1 − e^(−x)` is not: at x = 1e-7 it is 1e-9 off), and continuous
    /// where it hands over to `exp`.
    #[test]
    fn the_short_step_factor_is_exact_to_rounding() {
        for k in 0..2000 {
            let x = SERIES_BELOW * (k as f64 + 0.5) / 2000.0 * 10f64.powi(-(k % 9));
            let exact = -(-x).exp_m1();
            let factor = lag_factor(x, 1.0);
            assert!(
                (factor - exact).abs() <= 2.0 * f64::EPSILON * exact,
                "x = {x}: {factor} against {exact}"
            );
        }
        let below = lag_factor(SERIES_BELOW * (1.0 - 1e-12), 1.0);
        let above = lag_factor(SERIES_BELOW, 1.0);
        assert!((above - below).abs() < 1e-15, "{below} then {above}");
    }

    /// A machine that has stood in its room is at the room's temperature: the lags start there
    /// rather than at zero, follow a step with their own time constants, and hold through a
    /// missing reading instead of taking it in.
    #[test]
    fn room_lags_start_settled_follow_a_step_and_hold_through_a_gap() {
        let mut room = RoomLags::default();
        let first = room.update(20.0, 0.0);
        assert_eq!(first.lags_C, [20.0; 3]);
        let mut last = first;
        for _ in 0..1800 {
            last = room.update(22.0, 1.0);
        }
        for (lag, tau) in last.lags_C.iter().zip(AMBIENT_LAG_TAUS_S) {
            let expected = 22.0 - 2.0 * (-1800.0 / tau).exp();
            assert!((lag - expected).abs() < 1e-9, "{lag} against {expected}");
        }
        let gap = room.update(f64::NAN, 1.0);
        assert!(gap.ambient_C.is_nan());
        assert_eq!(gap.lags_C, last.lags_C);
        assert!(room.update(22.0, 1.0).lags_C.iter().all(|v| v.is_finite()));
        assert!(RoomLags::default().update(f64::NAN, 1.0).lags_C[0].is_nan());
    }

    /// A flange model that reads the stator through its 15 min lag starts at the stator's
    /// first reading and follows a 10 K step of the stator as a first-order lag does, while the
    /// static term follows at once.
    #[test]
    fn the_motor_flange_follows_the_stator_through_its_lag() {
        let model =
            LinearModel::with_terms(&["const", "stator", "stator_lag_15min"], &[1.0, 0.25, 0.5]);
        let flange = MotorFlangeEstimator::new(&model).unwrap();
        let mut room = RoomLags::default();
        let mut stator_lags = SettledLags::new(STATOR_LAG_TAUS_S);
        let mut at = |stator_C: f64, dt: f64| ThermalSurroundings {
            stator_C,
            stator_lags_C: stator_lags.update(stator_C, dt),
            room: room.update(20.0, dt),
            coolant_lags: [f64::NAN; 2],
        };
        let first = flange.update(&at(20.0, 0.0));
        assert!((first - (1.0 + 0.25 * 20.0 + 0.5 * 20.0)).abs() < 1e-12);
        let mut last = first;
        for _ in 0..900 {
            last = flange.update(&at(30.0, 1.0));
        }
        let lag = 30.0 - 10.0 * (-1.0f64).exp();
        assert!(
            (last - (1.0 + 0.25 * 30.0 + 0.5 * lag)).abs() < 1e-9,
            "{last}"
        );
    }

    /// The bed's lags start at the first estimated temperatures (a bed at rest is as warm as
    /// what is bolted to it) and follow the motor and the back bearing separately, each with
    /// the closed form of a first-order lag.
    #[test]
    fn bed_lags_start_at_the_first_estimates_and_follow_each_part() {
        let mut bed = BedLags::default();
        assert_eq!(bed.update(25.0, 21.0, 0.0), ([25.0; 2], [21.0; 2]));
        let mut last = ([0.0; 2], [0.0; 2]);
        for _ in 0..3600 {
            last = bed.update(30.0, 21.0, 1.0);
        }
        for (lag, tau) in last.0.iter().zip(BED_LAG_TAUS_S) {
            let expected = 30.0 - 5.0 * (-3600.0 / tau).exp();
            assert!((lag - expected).abs() < 1e-9, "{lag} against {expected}");
        }
        assert_eq!(last.1, [21.0; 2]);
    }

    /// Palmgren's load-free torque ∝ (ν·n)^(2/3), so its heat ∝ |n|^(5/3): doubling the speed
    /// multiplies it by 2^(5/3), whichever the direction.
    #[test]
    fn churning_heat_grows_as_the_five_thirds_power_of_speed() {
        let slow = heat_inputs(0.5, &SpeedHeat::of(1000.0));
        let fast = heat_inputs(0.5, &SpeedHeat::of(-2000.0));
        assert!((slow.churning - 1.0).abs() < 1e-12);
        assert!((fast.churning / slow.churning - 2f64.powf(5.0 / 3.0)).abs() < 1e-12);
        assert!((fast.drag / slow.drag - 2.0).abs() < 1e-12);
        assert!((fast.load / slow.load - 2.0).abs() < 1e-12);
    }

    /// The fast cube root agrees with the library's to 2 ulp from the smallest normal number to
    /// the largest, keeps the sign, and passes the edge values through.
    #[test]
    fn cube_root_matches_the_library_everywhere() {
        use proptest::prelude::*;
        let within_two_ulp = |x: f64| {
            let (ours, library) = (cube_root(x), x.cbrt());
            (ours - library).abs() <= 2.0 * f64::EPSILON * library.abs()
        };
        for x in [
            f64::MIN_POSITIVE,
            1e-300,
            1e-3,
            1.0,
            8.0,
            27.0,
            3.5,
            1e300,
            f64::MAX,
        ] {
            assert!(within_two_ulp(x) && within_two_ulp(-x), "{x}");
        }
        assert_eq!(cube_root(8.0), 2.0);
        assert_eq!(cube_root(-27.0), -3.0);
        assert_eq!(cube_root(0.0), 0.0);
        assert!(cube_root(-0.0).is_sign_negative());
        assert_eq!(cube_root(f64::INFINITY), f64::INFINITY);
        assert!(cube_root(f64::NAN).is_nan());
        assert_eq!(cube_root(1e-310), 1e-310f64.cbrt());
        proptest!(|(x in proptest::num::f64::NORMAL)| {
            prop_assert!(within_two_ulp(x), "{} against {}", cube_root(x), x.cbrt());
        });
    }

    /// A model that reads the fast heat accumulates the drag and load heat over τ/4 beside τ:
    /// after ten minutes of steady running each follows its own closed form.
    #[test]
    fn a_part_reads_its_heat_over_a_second_faster_time_constant() {
        let model = HeatModel {
            tau_s: 1200.0,
            c_bh: HeatAccumulator::c_bh_at_rate(1200.0, 1.0),
            temperature: LinearModel::with_terms(
                &["const", "heat", "heat_quarter_tau", "load_heat_quarter_tau"],
                &[20.0, 1.0, 2.0, 3.0],
            ),
            warm_start: None,
        };
        let mut part = ComponentThermalEstimator::new(&model).unwrap();
        let mut room = RoomLags::default();
        let surroundings = ThermalSurroundings {
            stator_C: 25.0,
            stator_lags_C: [25.0; 3],
            room: room.update(20.0, 0.0),
            coolant_lags: [f64::NAN; 2],
        };
        let speed = SpeedHeat::of(1000.0);
        let load = heat_inputs(2.0, &speed).load;
        let mut last = f64::NAN;
        for _ in 0..600 {
            last = part.update(2.0, &speed, &surroundings, 1.0);
        }
        let reached = |tau: f64| 1.0 - (-600.0 / tau).exp();
        let expected = 20.0 + reached(1200.0) + 2.0 * reached(300.0) + 3.0 * load * reached(300.0);
        assert!((last - expected).abs() < 1e-9, "{last} against {expected}");
        // Without the fast terms the same heat reaches the model over τ alone.
        let slow_only = HeatModel {
            temperature: LinearModel::with_terms(&["const", "heat"], &[20.0, 1.0]),
            ..model
        };
        let mut part = ComponentThermalEstimator::new(&slow_only).unwrap();
        for _ in 0..600 {
            last = part.update(2.0, &speed, &surroundings, 1.0);
        }
        assert!((last - (20.0 + reached(1200.0))).abs() < 1e-9, "{last}");
    }

    /// A part whose estimator starts on a warm machine starts its heat where the profile's
    /// warm start puts it for the stator's excess over the room in the first sample, and then
    /// accumulates from there, never beyond the largest excess calibration saw; a stator within
    /// [`WARM_START_FLOOR_K`] of the room, or a reading that is not a number, starts it at rest;
    /// and only the first sample seeds.
    #[test]
    fn a_part_started_on_a_warm_machine_starts_with_heat_in_it() {
        let warm_start = WarmStart {
            largest_excess_K: 4.0,
            per_K: PART_ACCUMULATIONS
                .iter()
                .zip([0.1, 0.01, 0.2, 0.3, 0.02])
                .map(|(name, per_K)| (name.to_string(), per_K))
                .collect(),
        };
        let model = HeatModel {
            tau_s: 1800.0,
            c_bh: HeatAccumulator::c_bh_at_rate(1800.0, 1.0),
            temperature: LinearModel::with_terms(
                &[
                    "const",
                    "heat",
                    "load_heat",
                    "churning_heat",
                    "heat_quarter_tau",
                    "load_heat_quarter_tau",
                ],
                &[20.0, 1.0, 10.0, 100.0, 1000.0, 10000.0],
            ),
            warm_start: Some(warm_start),
        };
        let at = |stator_C: f64, ambient_C: f64| ThermalSurroundings {
            stator_C,
            stator_lags_C: [stator_C; 3],
            room: RoomLags::default().update(ambient_C, 0.0),
            coolant_lags: [f64::NAN; 2],
        };
        let standing = SpeedHeat::of(0.0);
        // 2 K above the room counts 1.5 K above the floor.
        let counted = 2.0 - WARM_START_FLOOR_K;
        let seeded =
            20.0 + counted * (0.1 + 10.0 * 0.01 + 100.0 * 0.2 + 1000.0 * 0.3 + 10000.0 * 0.02);
        let mut part = ComponentThermalEstimator::new(&model).unwrap();
        assert!(part.warm_start().is_some());
        let first = part.update(0.0, &standing, &at(24.0, 22.0), 0.0);
        assert!((first - seeded).abs() < 1e-9, "{first} against {seeded}");
        assert!((part.heat() - 0.1 * counted).abs() < 1e-12);
        // Standing still, the seeded heat decays as any accumulated heat does, each over its
        // own τ; a later sample with a hotter stator seeds nothing more.
        let later = part.update(0.0, &standing, &at(40.0, 22.0), 600.0);
        let kept = |tau: f64| (-600.0 / tau).exp();
        let expected = 20.0
            + counted
                * ((0.1 + 10.0 * 0.01 + 100.0 * 0.2) * kept(1800.0)
                    + (1000.0 * 0.3 + 10000.0 * 0.02) * kept(450.0));
        assert!(
            (later - expected).abs() < 1e-9,
            "{later} against {expected}"
        );
        // A stator hotter than any the calibration saw (or a spiked first reading) seeds as
        // the hottest it saw: 4 K above the floor.
        let mut part = ComponentThermalEstimator::new(&model).unwrap();
        part.update(0.0, &standing, &at(80.0, 22.0), 0.0);
        assert!((part.heat() - 0.1 * 4.0).abs() < 1e-12, "{}", part.heat());
        let within_floor = 22.0 + WARM_START_FLOOR_K;
        for (stator, ambient) in [
            (21.0, 22.0),
            (within_floor, 22.0),
            (24.0, f64::NAN),
            (f64::NAN, 22.0),
            (f64::INFINITY, 22.0),
        ] {
            let mut part = ComponentThermalEstimator::new(&model).unwrap();
            part.update(0.0, &standing, &at(stator, ambient), 0.0);
            assert_eq!(part.heat(), 0.0, "stator {stator}, room {ambient}");
        }
        // A profile without a warm start starts at rest however warm the machine is.
        let cold = HeatModel {
            warm_start: None,
            ..model
        };
        let mut part = ComponentThermalEstimator::new(&cold).unwrap();
        assert!(part.warm_start().is_none());
        assert_eq!(part.update(0.0, &standing, &at(30.0, 22.0), 0.0), 20.0);
    }

    #[test]
    fn heat_accumulator_rescales_with_the_sample_rate() {
        // One hour of constant input at 1 Hz and at 1 kHz reaches the same value.
        let mut slow = HeatAccumulator::new(900.0);
        let mut fast = HeatAccumulator::new(900.0);
        for _ in 0..3600 {
            slow.update(50.0, 1.0);
        }
        for _ in 0..3_600_000 {
            fast.update(50.0, 0.001);
        }
        let expected = 50.0 * (1.0 - (-4.0_f64).exp());
        assert!((slow.value() - expected).abs() < 1e-9);
        assert!((fast.value() - expected).abs() < 1e-6);
        let c1 = HeatAccumulator::c_bh_at_rate(900.0, 1.0);
        let c1000 = HeatAccumulator::c_bh_at_rate(900.0, 1000.0);
        assert!(((1.0 - c1000).powf(1000.0) - (1.0 - c1)).abs() < 1e-12);
    }
    /// The feature vector's layout is the one `ELONGATION_FEATURES` names: the heat terms
    /// input-major over the time constants, then the room and its lags.
    #[test]
    fn elongation_feature_names_follow_the_inputs_and_time_constants() {
        use super::super::models::{
            AMBIENT_LAG_FEATURES, ELONGATION_HEAT_INPUTS, ELONGATION_TAU_NAMES,
        };
        let mut expected = vec!["const", "delta_stator", "speed", "load"]
            .into_iter()
            .map(String::from)
            .collect::<Vec<_>>();
        for input in ELONGATION_HEAT_INPUTS {
            for tau in ELONGATION_TAU_NAMES {
                expected.push(format!("{input}_{tau}"));
            }
        }
        expected.push("ambient".into());
        expected.extend(AMBIENT_LAG_FEATURES.map(String::from));
        assert_eq!(ELONGATION_FEATURES, expected);
        assert_eq!(ELONGATION_FEATURE_COUNT, ELONGATION_FEATURES.len());
    }

    /// ΔT and the room count from the calibration moment; each heat term follows the closed
    /// form u·(1 − e^(−t/τ)) of a constant input; the coolant's cooling term is the coolant
    /// times the stator's rise over the room; a reset counts from the next frame.
    #[test]
    fn elongation_features_count_from_calibration_and_accumulate_in_closed_form() {
        let taus = [600.0, 1800.0, 5400.0, 16200.0];
        let mut features = ElongationFeatures::new(taus);
        let mut room = RoomLags::default();
        let frame = |stator_C: f64, ambient_C: f64, room: &mut RoomLags| ElongationInputs {
            stator_C,
            speed_rpm: -3000.0,
            load_pct: 40.0,
            current_A: 20.0,
            coolant_on: 1.0,
            room: room.update(ambient_C, 1.0),
        };
        let first = *features.update(&frame(30.0, 21.0, &mut room), 0.0);
        assert_eq!(first[1], 0.0, "ΔT at the calibration moment");
        assert_eq!(
            &first[28..],
            &[0.0; 4],
            "room terms at the calibration moment"
        );
        let mut last = first;
        for _ in 0..3600 {
            last = *features.update(&frame(30.0, 21.0, &mut room), 1.0);
        }
        let krpm: f64 = 3.0;
        let drivers = [krpm, 40.0, krpm.powf(5.0 / 3.0), 4.0, 1.0, 9.0];
        for (k, driver) in drivers.iter().enumerate() {
            for (j, tau) in taus.iter().enumerate() {
                let expected = driver * (1.0 - (-3600.0 / tau).exp());
                let got = last[4 + 4 * k + j];
                assert!(
                    (got - expected).abs() < 1e-9 * driver.max(1.0),
                    "{k},{j}: {got} vs {expected}"
                );
            }
        }
        let warmer = *features.update(&frame(33.0, 22.0, &mut room), 1.0);
        assert_eq!(warmer[1], 3.0);
        assert_eq!(warmer[28], 1.0);
        features.reset_tool_calibration();
        let reset = *features.update(&frame(33.0, 22.0, &mut room), 1.0);
        assert_eq!(reset[1], 0.0);
        assert_eq!(&reset[28..], &[0.0; 4]);
    }
}
