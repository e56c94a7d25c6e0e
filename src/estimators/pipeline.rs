//! The estimator pipeline: every estimator of every axis, bound to a frame layout once, then
//! updated frame by frame without allocating.
#![allow(non_snake_case)] // unit suffixes (`_C`, `_Nm`) are part of the names

use crate::profile::{AxisKind, MachineProfile};
use crate::signal::channel::{AMBIENT, COOLANT, CUT_DEPTH};
use crate::signal::{AxisId, Quantity, Schema, axis_column, reference_column};

use super::abnormality::{AbnormalityScore, MotorAbnormalityEstimator, TorqueSample};
use super::models::{
    AMBIENT_LAG_FEATURES, AxisModels, BED_LAG_TAUS_S, STATOR_LAG_TAUS_S, WARM_START_FLOOR_K,
    WarmStart, warm_excess,
};
use super::state::{
    Clock, MAX_RESUME_GAP_S, Resume, STATE_FORMAT, SavedReading, SavedSpindle, SavedState,
    StateError, StateWalk, WalkState, calibration_fingerprint,
};
use super::streaming::{
    BedLags, ComponentThermalEstimator, ElongationInputs, MAX_NODES, MotorFlangeEstimator,
    RoomLags, SettledLags, SpeedHeat, SpindleElongationEstimator, StraightnessEstimator,
    StraightnessInputs, ThermalSurroundings, TorqueSplit, TorqueSplitEstimator,
    minimum_zone_straightness, straightness_features,
};

/// Why a pipeline could not be built.
#[derive(Debug, thiserror::Error)]
pub enum PipelineError {
    /// The profile has no calibration.
    #[error("the profile `{0}` is not calibrated: run `servosight calibrate` first")]
    NotCalibrated(String),
    /// A model in the profile is malformed.
    #[error("axis {axis}: {what}: {message}")]
    Model {
        /// The axis.
        axis: AxisId,
        /// Which model.
        what: &'static str,
        /// What is wrong.
        message: String,
    },
    /// The frames lack a column an estimator needs.
    #[error("no column `{column}` in the frames (needed for {purpose})")]
    MissingColumn {
        /// The column.
        column: String,
        /// What needs it.
        purpose: String,
    },
}

/// Estimates of one feed axis at one instant. `NaN` marks an estimate the profile has no model for.
#[derive(Debug, Clone, Copy)]
pub struct FeedAxisEstimate {
    /// Motor flange temperature, °C.
    pub motor_flange_C: f64,
    /// Motor torque split.
    pub split: TorqueSplit,
    /// Front bearing temperature, °C.
    pub front_bearing_C: f64,
    /// Back bearing temperature, °C.
    pub back_bearing_C: f64,
    /// Nut temperature, °C.
    pub nut_C: f64,
    /// Horizontal straightness deviation per node, µm (first `nodes` entries).
    pub straightness_h_um: [f64; MAX_NODES],
    /// Vertical straightness deviation per node, µm.
    pub straightness_v_um: [f64; MAX_NODES],
    /// Number of straightness nodes (0 without straightness models).
    pub nodes: usize,
    /// Positions of the nodes along the stroke, mm.
    pub node_positions_mm: [f64; MAX_NODES],
    /// Motor abnormality score.
    pub abnormality: AbnormalityScore,
}

impl FeedAxisEstimate {
    /// ISO 1101 horizontal straightness over the nodes (minimum zone), µm.
    pub fn straightness_h_zone_um(&self) -> f64 {
        self.zone(&self.straightness_h_um)
    }

    /// ISO 1101 vertical straightness over the nodes (minimum zone), µm.
    pub fn straightness_v_zone_um(&self) -> f64 {
        self.zone(&self.straightness_v_um)
    }

    fn zone(&self, deviations: &[f64; MAX_NODES]) -> f64 {
        if self.nodes < 2 {
            return f64::NAN;
        }
        minimum_zone_straightness(
            &self.node_positions_mm[..self.nodes],
            &deviations[..self.nodes],
        )
    }
}

impl Default for FeedAxisEstimate {
    fn default() -> Self {
        FeedAxisEstimate {
            motor_flange_C: f64::NAN,
            split: TorqueSplit {
                bearing_Nm: f64::NAN,
                front_bearing_Nm: f64::NAN,
                back_bearing_Nm: f64::NAN,
                nut_Nm: f64::NAN,
            },
            front_bearing_C: f64::NAN,
            back_bearing_C: f64::NAN,
            nut_C: f64::NAN,
            straightness_h_um: [f64::NAN; MAX_NODES],
            straightness_v_um: [f64::NAN; MAX_NODES],
            nodes: 0,
            node_positions_mm: [f64::NAN; MAX_NODES],
            abnormality: AbnormalityScore::default(),
        }
    }
}

/// Estimates of the spindle at one instant.
#[derive(Debug, Clone, Copy)]
pub struct SpindleEstimate {
    /// Thermal elongation since the tool calibration, µm.
    pub elongation_um: f64,
    /// Motor abnormality score.
    pub abnormality: AbnormalityScore,
}

/// Where a spindle's elongation counts from: the estimate is the growth since then, and a
/// tool-length correction built on it is right only if the tool was measured then, or on a
/// spindle as cold as it was then. In JSON: `{"kind": "first_frame_warm", "time_s": …,
/// "excess_K": …}`.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum ElongationOrigin {
    /// The first frame, with the stator no more than [`WARM_START_FLOOR_K`] above the room: a
    /// spindle at rest, as it is when a tool is measured at the start of a shift.
    FirstFrameAtRest {
        /// Machine time of the frame, s.
        time_s: f64,
    },
    /// The first frame, with the stator warm: the spindle had grown by an amount the estimate
    /// does not know, so the growth since the tool measurement is unknown until it is taken
    /// again.
    FirstFrameWarm {
        /// Machine time of the frame, s.
        time_s: f64,
        /// The stator's excess over the room, K.
        excess_K: f64,
    },
    /// The first frame, without a room or stator reading that says whether the spindle was at
    /// rest.
    FirstFrameUnread {
        /// Machine time of the frame, s.
        time_s: f64,
    },
    /// An earlier count, with a gap in the frames since that was longer than
    /// [`MAX_RESUME_GAP_S`]: the estimate stepped over it with the inputs of the first frame
    /// after it, so how far the spindle grew or shrank in it is unknown until the tool is
    /// measured again (over the twin's production program, up to 9 µm after a gap of 10 to 30
    /// minutes and 15 µm after an hour: docs/accuracy.md, *A gap in the frames*).
    AcrossGap {
        /// Machine time the estimate counts from (the earlier count's), s.
        time_s: f64,
        /// Machine time of the first frame after the gap, s.
        gap_end_s: f64,
        /// How long the gap was, s.
        gap_s: f64,
    },
    /// The first frame after the operator said the tool was measured.
    ToolMeasured {
        /// Machine time of the frame, s.
        time_s: f64,
        /// The stator's excess over the room when the estimates started, K, if the spindle was
        /// warm then: the elongation model's heat started at rest, so for the first hours it
        /// may read growth a spindle already in balance does not show.
        started_warm_K: Option<f64>,
    },
}

impl ElongationOrigin {
    /// What a first frame with this stator and room reading says about the spindle.
    pub fn at_first_frame(time_s: f64, stator_C: f64, room_C: f64) -> Self {
        if !(stator_C.is_finite() && room_C.is_finite()) {
            ElongationOrigin::FirstFrameUnread { time_s }
        } else if let Some(excess_K) = warm_excess(stator_C, room_C) {
            ElongationOrigin::FirstFrameWarm { time_s, excess_K }
        } else {
            ElongationOrigin::FirstFrameAtRest { time_s }
        }
    }

    /// The stator's excess over the room of a start on a warm spindle, K.
    pub fn warm_excess_K(&self) -> Option<f64> {
        match *self {
            ElongationOrigin::FirstFrameWarm { excess_K, .. } => Some(excess_K),
            _ => None,
        }
    }

    /// Moves the origin's machine time by `shift_s` (onto another clock).
    pub fn shift_time(&mut self, shift_s: f64) {
        match self {
            ElongationOrigin::FirstFrameAtRest { time_s }
            | ElongationOrigin::FirstFrameWarm { time_s, .. }
            | ElongationOrigin::FirstFrameUnread { time_s }
            | ElongationOrigin::ToolMeasured { time_s, .. } => *time_s += shift_s,
            ElongationOrigin::AcrossGap {
                time_s, gap_end_s, ..
            } => {
                *time_s += shift_s;
                *gap_end_s += shift_s;
            }
        }
    }

    /// Machine time the elongation counts from, s.
    pub fn time_s(&self) -> f64 {
        match *self {
            ElongationOrigin::FirstFrameAtRest { time_s }
            | ElongationOrigin::FirstFrameWarm { time_s, .. }
            | ElongationOrigin::FirstFrameUnread { time_s }
            | ElongationOrigin::AcrossGap { time_s, .. }
            | ElongationOrigin::ToolMeasured { time_s, .. } => time_s,
        }
    }

    /// Whether the estimate is the growth since a known tool length: the tool was measured
    /// then, or the spindle was at rest, as it is when a shift's tool is measured.
    pub fn is_known(&self) -> bool {
        matches!(
            self,
            ElongationOrigin::FirstFrameAtRest { .. } | ElongationOrigin::ToolMeasured { .. }
        )
    }
}

/// Where an axis's servo signals are in the frame.
#[derive(Debug, Clone, Copy)]
struct AxisChannels {
    speed: usize,
    torque: usize,
    load: Option<usize>,
    stator: usize,
    position: Option<usize>,
    current: Option<usize>,
}

impl AxisChannels {
    fn resolve(schema: &Schema, axis: AxisId) -> Result<Self, PipelineError> {
        let need = |q: Quantity| {
            let name = axis_column(axis, q);
            schema.index_of(&name).ok_or(PipelineError::MissingColumn {
                column: name,
                purpose: format!("the {axis} axis estimators"),
            })
        };
        Ok(AxisChannels {
            speed: need(Quantity::Speed)?,
            torque: need(Quantity::Torque)?,
            load: schema.index_of(&axis_column(axis, Quantity::Load)),
            stator: need(Quantity::StatorTemp)?,
            position: schema.index_of(&axis_column(axis, Quantity::Position)),
            current: schema.index_of(&axis_column(axis, Quantity::Current)),
        })
    }
}

#[derive(Clone)]
struct FeedAxisPipeline {
    axis: AxisId,
    channels: AxisChannels,
    flange: Option<MotorFlangeEstimator>,
    split: Option<TorqueSplitEstimator>,
    front: Option<ComponentThermalEstimator>,
    back: Option<ComponentThermalEstimator>,
    nut: Option<ComponentThermalEstimator>,
    straightness_h: Option<StraightnessEstimator>,
    straightness_v: Option<StraightnessEstimator>,
    abnormality: Option<MotorAbnormalityEstimator>,
    stroke_mm: f64,
    /// The stator through the lags the flange and component models may read.
    stator_lags: SettledLags<3>,
    /// The bed's slow state the straightness models may read.
    bed: BedLags,
    /// What the straightness models read this frame (kept for calibration).
    thermal_state: StraightnessInputs,
    estimate: FeedAxisEstimate,
}

impl FeedAxisPipeline {
    /// The parts whose heat the axis estimates, named.
    fn parts(&self) -> impl Iterator<Item = (&'static str, &ComponentThermalEstimator)> {
        [
            ("front bearing", &self.front),
            ("back bearing", &self.back),
            ("nut", &self.nut),
        ]
        .into_iter()
        .filter_map(|(name, part)| Some((name, part.as_ref()?)))
    }
}

struct SpindlePipeline {
    axis: AxisId,
    channels: AxisChannels,
    elongation: Option<SpindleElongationEstimator>,
    abnormality: Option<MotorAbnormalityEstimator>,
    estimate: SpindleEstimate,
    /// Where the elongation counts from; `None` until its first finite estimate after a start
    /// or a tool measurement.
    elongation_origin: Option<ElongationOrigin>,
    /// The operator measured the tool and the elongation has not counted from it yet (also
    /// before the first frame).
    tool_measured_pending: bool,
    /// What the spindle was at the elongation's first finite estimate since the start: a later
    /// tool measurement carries its warmth (the model's heat started at rest).
    start: Option<ElongationOrigin>,
}

/// A pipeline's feed axes and the machine's lags before any frame.
struct ThermalStart {
    feed: Vec<FeedAxisPipeline>,
    room: RoomLags,
    coolant_lags: SettledLags<2>,
}

/// Every estimator of a machine.
pub struct EstimatorPipeline {
    feed: Vec<FeedAxisPipeline>,
    spindles: Vec<SpindlePipeline>,
    ambient: Option<usize>,
    coolant: Option<usize>,
    /// The room through the lags the heat and straightness models may read.
    room: RoomLags,
    /// The coolant's on/off state through the lags the component and straightness models may
    /// read.
    coolant_lags: SettledLags<2>,
    cut_depth: Option<usize>,
    previous_time: Option<f64>,
    notes: Vec<String>,
    /// The feed axes and the machine's lags as they were built, before any frame: what they
    /// start again from after a gap in the frames ([`Self::start_again_after_gap`]).
    thermal_start: Box<ThermalStart>,
    /// The longest gap in the frames the estimators step over ([`MAX_RESUME_GAP_S`]).
    longest_step_s: f64,
    /// The room's lags as the spindles read them, once a gap started the feed axes' room lags
    /// again (the elongation steps over gaps); until then the spindles read [`Self::room`].
    spindle_room: Option<RoomLags>,
    /// The profile's name and its calibration's fingerprint, which a saved state must carry
    /// (`None`: the calibration cannot be fingerprinted, and no state is saved or taken up).
    profile_name: String,
    calibration_sha256: Option<String>,
}

impl EstimatorPipeline {
    /// Binds the profile's calibrated models to frames laid out as `schema`.
    pub fn new(profile: &MachineProfile, schema: &Schema) -> Result<Self, PipelineError> {
        let calibration = profile
            .calibration
            .as_ref()
            .ok_or_else(|| PipelineError::NotCalibrated(profile.name.clone()))?;
        let ambient = schema.index_of(AMBIENT);
        let coolant = schema.index_of(COOLANT);
        let cut_depth = schema.index_of(CUT_DEPTH);
        let mut notes = Vec::new();
        // (column, what reads it) for model inputs the frames lack: gathered over every axis so
        // that one error names everything a missing column leaves without its input.
        let mut unmet: Vec<(String, String)> = Vec::new();
        let mut feed = Vec::new();
        let mut spindles = Vec::new();
        for (&axis, axis_profile) in &profile.axes {
            let Some(models) = calibration.axes.get(&axis) else {
                continue;
            };
            if uses_ambient(models) && ambient.is_none() {
                return Err(PipelineError::MissingColumn {
                    column: AMBIENT.into(),
                    purpose: format!(
                        "the {axis} axis models, which were fitted with the room temperature"
                    ),
                });
            }
            let channels = AxisChannels::resolve(schema, axis)?;
            let model_err = |what: &'static str| {
                move |message: String| PipelineError::Model {
                    axis,
                    what,
                    message,
                }
            };
            let abnormality = match (&models.abnormality, cut_depth) {
                (Some(model), Some(_)) => Some(
                    MotorAbnormalityEstimator::new(
                        model,
                        axis_profile.limits.abnormality.warning / 4.0,
                    )
                    .map_err(model_err("abnormality"))?,
                ),
                (Some(_), None) => {
                    notes.push(format!(
                        "{axis}: no abnormality score: the frames have no `{CUT_DEPTH}` column, \
                         and without it cutting torque would be scored as friction"
                    ));
                    None
                }
                (None, _) => None,
            };
            match axis_profile.kind {
                AxisKind::Feed => {
                    let split = match (&models.nut_bearing_ratio, &models.back_front_ratio) {
                        (Some(nb), Some(bf)) => Some(
                            TorqueSplitEstimator::new(nb, bf).map_err(model_err("torque split"))?,
                        ),
                        _ => None,
                    };
                    let thermal = |m: &Option<super::models::HeatModel>, what: &'static str| {
                        m.as_ref()
                            .map(|m| ComponentThermalEstimator::new(m).map_err(model_err(what)))
                            .transpose()
                    };
                    let positions = axis_profile
                        .screw
                        .as_ref()
                        .map(|s| s.node_positions_mm.clone())
                        .unwrap_or_default();
                    let straightness = |m: &Vec<super::models::LinearModel>, what: &'static str| {
                        if m.is_empty() {
                            Ok(None)
                        } else {
                            StraightnessEstimator::new(m, &positions)
                                .map(Some)
                                .map_err(model_err(what))
                        }
                    };
                    let front = thermal(&models.front_bearing_temp, "front bearing temperature")?;
                    let back = thermal(&models.back_bearing_temp, "back bearing temperature")?;
                    let nut = thermal(&models.nut_temp, "nut temperature")?;
                    let straightness_h =
                        straightness(&models.straightness_h, "horizontal straightness")?;
                    let straightness_v =
                        straightness(&models.straightness_v, "vertical straightness")?;
                    let reads = |prefix: &str| {
                        [&straightness_h, &straightness_v].iter().any(|e| {
                            e.as_ref()
                                .is_some_and(|e| e.uses_features_starting_with(prefix))
                        })
                    };
                    let part_reads_coolant = |part: &Option<ComponentThermalEstimator>| {
                        part.as_ref()
                            .is_some_and(|e| e.uses_features_starting_with("coolant"))
                    };
                    let coolant_readers = [
                        (reads("coolant"), "straightness models"),
                        (
                            part_reads_coolant(&front),
                            "front bearing temperature model",
                        ),
                        (part_reads_coolant(&back), "back bearing temperature model"),
                        (part_reads_coolant(&nut), "nut temperature model"),
                    ];
                    if coolant.is_none() {
                        for (_, what) in coolant_readers.iter().filter(|(reads, _)| *reads) {
                            unmet.push((COOLANT.into(), format!("the {axis} {what}")));
                        }
                    }
                    if reads("nut") && models.nut_temp.is_none() {
                        return Err(PipelineError::Model {
                            axis,
                            what: "straightness",
                            message: "the models read the nut temperature, but the profile has \
                                      no nut temperature model"
                                .into(),
                        });
                    }
                    feed.push(FeedAxisPipeline {
                        axis,
                        channels,
                        flange: models
                            .motor_flange
                            .as_ref()
                            .map(|m| {
                                MotorFlangeEstimator::new(m).map_err(model_err("motor flange"))
                            })
                            .transpose()?,
                        front,
                        back,
                        nut,
                        split,
                        straightness_h,
                        straightness_v,
                        abnormality,
                        stroke_mm: axis_profile
                            .screw
                            .as_ref()
                            .map_or(f64::NAN, |s| s.stroke_mm),
                        stator_lags: SettledLags::new(STATOR_LAG_TAUS_S),
                        bed: BedLags::default(),
                        thermal_state: StraightnessInputs::default(),
                        estimate: {
                            let mut estimate = FeedAxisEstimate::default();
                            for (slot, x) in estimate.node_positions_mm.iter_mut().zip(&positions) {
                                *slot = *x;
                            }
                            estimate
                        },
                    });
                }
                AxisKind::Spindle => {
                    let elongation = models
                        .elongation
                        .as_ref()
                        .map(|m| {
                            SpindleElongationEstimator::new(m).map_err(model_err("elongation"))
                        })
                        .transpose()?;
                    if let Some(e) = &elongation {
                        let needs = [
                            (
                                "copper_heat",
                                axis_column(axis, Quantity::Current),
                                channels.current,
                            ),
                            ("coolant", COOLANT.to_string(), coolant),
                        ];
                        for (prefix, column, index) in needs {
                            if e.uses_features_starting_with(prefix) && index.is_none() {
                                unmet.push((column, format!("the {axis} elongation model")));
                            }
                        }
                    }
                    if elongation.is_some() || abnormality.is_some() {
                        spindles.push(SpindlePipeline {
                            axis,
                            channels,
                            elongation,
                            abnormality,
                            estimate: SpindleEstimate {
                                elongation_um: f64::NAN,
                                abnormality: AbnormalityScore::default(),
                            },
                            elongation_origin: None,
                            tool_measured_pending: false,
                            start: None,
                        });
                    }
                }
            }
        }
        if let Some((column, _)) = unmet.first() {
            let column = column.clone();
            let readers: Vec<&str> = unmet
                .iter()
                .filter(|(c, _)| *c == column)
                .map(|(_, reader)| reader.as_str())
                .collect();
            let listed = match readers.split_last() {
                Some((last, rest)) if !rest.is_empty() => format!("{} and {last}", rest.join(", ")),
                _ => readers.join(""),
            };
            return Err(PipelineError::MissingColumn {
                purpose: format!("{listed}: they were fitted with it"),
                column,
            });
        }
        if ambient.is_none() {
            for axis in &feed {
                if axis.parts().any(|(_, p)| p.warm_start().is_some()) {
                    notes.push(format!(
                        "{}: no `{AMBIENT}` column: the bearing and nut heat starts at rest \
                         however warm the machine is (the profile's warm start reads the \
                         stator's excess over the room)",
                        axis.axis
                    ));
                }
            }
        }
        let thermal_start = Box::new(ThermalStart {
            feed: feed.clone(),
            room: RoomLags::default(),
            coolant_lags: SettledLags::new(BED_LAG_TAUS_S),
        });
        Ok(EstimatorPipeline {
            feed,
            spindles,
            ambient,
            coolant,
            room: thermal_start.room.clone(),
            coolant_lags: thermal_start.coolant_lags.clone(),
            cut_depth,
            previous_time: None,
            notes,
            thermal_start,
            longest_step_s: MAX_RESUME_GAP_S,
            spindle_room: None,
            profile_name: profile.name.clone(),
            calibration_sha256: calibration_fingerprint(calibration),
        })
    }

    /// The abnormality score of every axis that has one.
    pub fn abnormality_scores(&self) -> Vec<(AxisId, AbnormalityScore)> {
        let feed = self
            .feed
            .iter()
            .filter(|a| a.abnormality.is_some())
            .map(|a| (a.axis, a.estimate.abnormality));
        let spindles = self
            .spindles
            .iter()
            .filter(|s| s.abnormality.is_some())
            .map(|s| (s.axis, s.estimate.abnormality));
        feed.chain(spindles).collect()
    }

    /// What the pipeline could not estimate from these frames, and why.
    pub fn notes(&self) -> &[String] {
        &self.notes
    }

    /// Updates every estimator with one frame (column 0 is `time_s`).
    pub fn update(&mut self, frame: &[f64]) {
        let t = frame[0];
        // The step since the last frame, which the spindles take even across a gap.
        let step_s = self.previous_time.map_or(0.0, |p| (t - p).max(0.0));
        let after_gap = step_s > self.longest_step_s;
        if after_gap {
            self.start_again_after_gap(t, step_s);
        }
        let first = self.previous_time.is_none();
        let dt = if first { 0.0 } else { step_s };
        self.previous_time = Some(t);
        let ambient = self.ambient.map_or(f64::NAN, |i| frame[i]);
        let room = self.room.update(ambient, dt);
        let spindle_room = match &mut self.spindle_room {
            Some(lags) => lags.update(ambient, step_s),
            None => room,
        };
        let coolant = self.coolant.map_or(f64::NAN, |i| frame[i]);
        let coolant_lags = self.coolant_lags.update(coolant, dt);
        let cutting = self.cut_depth.is_some_and(|i| frame[i] > 0.0);
        let sample = |c: &AxisChannels, stroke_fraction: f64| TorqueSample {
            time_s: t,
            speed_rpm: frame[c.speed],
            torque_Nm: frame[c.torque],
            stator_C: frame[c.stator],
            ambient_C: ambient,
            stroke_fraction,
            cutting,
        };
        for axis in &mut self.feed {
            let c = axis.channels;
            let (torque, stator) = (frame[c.torque], frame[c.stator]);
            if let Some(abnormality) = &mut axis.abnormality {
                let x = c.position.map_or(f64::NAN, |i| frame[i] / axis.stroke_mm);
                axis.estimate.abnormality = abnormality.update(&sample(&c, x));
            }
            let speed = SpeedHeat::of(frame[c.speed]);
            let surroundings = ThermalSurroundings {
                stator_C: stator,
                stator_lags_C: axis.stator_lags.update(stator, dt),
                room,
                coolant_lags,
            };
            let e = &mut axis.estimate;
            if let Some(flange) = &axis.flange {
                e.motor_flange_C = flange.update(&surroundings);
            }
            if let Some(split) = &axis.split {
                e.split = split.update(torque);
                if let Some(front) = &mut axis.front {
                    e.front_bearing_C =
                        front.update(e.split.front_bearing_Nm, &speed, &surroundings, dt);
                }
                if let Some(back) = &mut axis.back {
                    e.back_bearing_C =
                        back.update(e.split.back_bearing_Nm, &speed, &surroundings, dt);
                }
                if let Some(nut) = &mut axis.nut {
                    e.nut_C = nut.update(e.split.nut_Nm, &speed, &surroundings, dt);
                }
            }
            {
                let states = |c: &Option<ComponentThermalEstimator>| {
                    c.as_ref()
                        .map_or((f64::NAN, f64::NAN), |c| (c.heat(), c.load_heat()))
                };
                let (front_heat, front_load_heat) = states(&axis.front);
                let (back_heat, back_load_heat) = states(&axis.back);
                let (motor_lags_C, back_lags_C) =
                    axis.bed.update(e.motor_flange_C, e.back_bearing_C, dt);
                let inputs = StraightnessInputs {
                    front_C: e.front_bearing_C,
                    back_C: e.back_bearing_C,
                    motor_C: e.motor_flange_C,
                    ambient_C: ambient,
                    ambient_lags_C: room.lags_C,
                    stator_C: stator,
                    front_heat,
                    front_load_heat,
                    back_heat,
                    back_load_heat,
                    nut_C: e.nut_C,
                    motor_lags_C,
                    back_lags_C,
                    coolant_lags,
                };
                axis.thermal_state = inputs;
                let features = straightness_features(&inputs);
                for (estimator, out) in [
                    (&axis.straightness_h, &mut e.straightness_h_um),
                    (&axis.straightness_v, &mut e.straightness_v_um),
                ] {
                    if let Some(estimator) = estimator {
                        e.nodes = estimator.nodes();
                        estimator.update(&features, out);
                    }
                }
            }
        }
        for spindle in &mut self.spindles {
            let c = spindle.channels;
            let load = c.load.map_or(0.0, |i| frame[i]);
            if let Some(elongation) = &mut spindle.elongation {
                let inputs = ElongationInputs {
                    stator_C: frame[c.stator],
                    speed_rpm: frame[c.speed],
                    load_pct: load,
                    current_A: c.current.map_or(f64::NAN, |i| frame[i]),
                    coolant_on: coolant,
                    room: spindle_room,
                };
                spindle.estimate.elongation_um = elongation.update(&inputs, step_s);
                // The estimate counts from its first finite value, as the estimator's zero
                // does.
                if spindle.elongation_origin.is_none() && spindle.estimate.elongation_um.is_finite()
                {
                    let start = *spindle.start.get_or_insert_with(|| {
                        ElongationOrigin::at_first_frame(t, frame[c.stator], ambient)
                    });
                    spindle.elongation_origin = Some(if spindle.tool_measured_pending {
                        ElongationOrigin::ToolMeasured {
                            time_s: t,
                            started_warm_K: start.warm_excess_K(),
                        }
                    } else {
                        start
                    });
                    spindle.tool_measured_pending = false;
                }
            }
            if let Some(abnormality) = &mut spindle.abnormality {
                spindle.estimate.abnormality = abnormality.update(&sample(&c, f64::NAN));
            }
        }
        if first {
            self.note_warm_start(frame, ambient, after_gap);
        }
    }

    /// Steps over gaps in the frames of up to `gap_s` instead of [`MAX_RESUME_GAP_S`]
    /// (infinity: every gap), holding the next frame's inputs through them: what the table in
    /// docs/accuracy.md, *A gap in the frames*, compares starting again with. The HMI and the
    /// commands keep the default.
    pub fn step_over_gaps_up_to(&mut self, gap_s: f64) {
        self.longest_step_s = gap_s;
    }

    /// After a gap in the frames longer than [`MAX_RESUME_GAP_S`] (a link down, a piece of a
    /// recording missing), the feed axes' heat, the bed's lags and the room's, stators' and
    /// coolant's lags start again as at a first frame (from the profile's warm start), since
    /// stepping over the gap holds the next frame's inputs through it, which the machine need
    /// not have done: over the twin's production program a fresh start follows the bearings,
    /// the nut and the straightness closer from gaps of ten minutes on (the nut 0.12 K off on
    /// average over the next hour against 0.44–0.60 K stepped over, docs/accuracy.md, *A gap
    /// in the frames*). The spindle's elongation has no warm start and steps over the gap; it
    /// still counts from where it did, but its growth in the gap is unknown
    /// ([`ElongationOrigin::AcrossGap`]). The abnormality averages are kept (friction does not
    /// change in a gap), their blocks started again.
    #[cold]
    fn start_again_after_gap(&mut self, t: f64, gap_s: f64) {
        let start = &self.thermal_start;
        for (axis, fresh) in self.feed.iter_mut().zip(&start.feed) {
            let abnormality = axis.abnormality.take();
            *axis = fresh.clone();
            axis.abnormality = abnormality;
        }
        let stepping = std::mem::replace(&mut self.room, start.room.clone());
        self.spindle_room.get_or_insert(stepping);
        self.coolant_lags = start.coolant_lags.clone();
        self.start_abnormality_blocks_again();
        let mut across = Vec::new();
        for spindle in &mut self.spindles {
            if let Some(origin) = spindle.elongation_origin {
                spindle.elongation_origin = Some(ElongationOrigin::AcrossGap {
                    time_s: origin.time_s(),
                    gap_end_s: t,
                    gap_s,
                });
                across.push(spindle.axis.to_string());
            }
        }
        let elongation = match across.as_slice() {
            [] => String::new(),
            axes => format!(
                "; the {} elongation stepped over it and counts from where it did, but its \
                 growth in the gap is unknown: measure the tool before its thermal offset is \
                 used again",
                axes.join(", ")
            ),
        };
        self.notes.push(format!(
            "a gap of {gap_s:.0} s in the frames before machine time {t:.1} s, longer than the \
             {:.0} s the estimators step over: what the machine did in it is unknown, so the \
             parts' heat and the lags started again as at a first frame{elongation}",
            self.longest_step_s
        ));
        self.previous_time = None;
    }

    /// Says, for each axis whose stator was above the room in the first frame by more than
    /// [`WARM_START_FLOOR_K`], how its accumulated heat started: a feed axis's parts from the
    /// profile's warm start or (a profile calibrated without one) at rest, a spindle's at rest
    /// (it has no warm start). Heat started at rest reads low until it has built up.
    #[cold]
    fn note_warm_start(&mut self, frame: &[f64], ambient_C: f64, after_gap: bool) {
        let first_frame = if after_gap {
            "the first frame after the gap"
        } else {
            "the first frame"
        };
        let mut notes = Vec::new();
        for axis in &self.feed {
            let stator_C = frame[axis.channels.stator];
            let Some(excess) = warm_excess(stator_C, ambient_C) else {
                continue;
            };
            let (seeded, at_rest): (Vec<_>, Vec<_>) =
                axis.parts().partition(|(_, p)| p.warm_start().is_some());
            if seeded.is_empty() && at_rest.is_empty() {
                continue;
            }
            let names = |list: &[(&str, &ComponentThermalEstimator)]| {
                list.iter().map(|(n, _)| *n).collect::<Vec<_>>().join(", ")
            };
            let a = axis.axis;
            let warm = format!(
                "{a}: the machine was warm at {first_frame} (stator {excess:.1} K above the room)"
            );
            let beyond = seeded
                .iter()
                .find_map(|(_, p)| p.warm_start())
                .filter(|w| {
                    w.seeded_excess(stator_C, ambient_C)
                        < WarmStart::counted_excess(stator_C, ambient_C)
                })
                .map_or_else(String::new, |w| {
                    let largest = w.largest_excess_K + WARM_START_FLOOR_K;
                    format!(
                        "; beyond the {largest:.1} K the calibration recordings showed, it was \
                         seeded as for {largest:.1} K"
                    )
                });
            let seeded_note = format!(
                "the {} heat started where the profile's warm start puts it, an estimate from the \
                 stator alone, until the parts' own heat takes over (about two time \
                 constants){beyond}",
                names(&seeded)
            );
            let at_rest_note = format!(
                "the profile has no warm start for the {} heat, which started at rest and reads \
                 low until it has built up (about two time constants); calibrate the profile \
                 again to get one",
                names(&at_rest)
            );
            notes.push(match (seeded.is_empty(), at_rest.is_empty()) {
                (false, true) => format!("{warm}: {seeded_note}"),
                (true, _) => format!("{warm}, but {at_rest_note}"),
                (false, false) => format!("{warm}: {seeded_note}; but {at_rest_note}"),
            });
        }
        // After a gap the elongation stepped over it rather than starting again.
        let starting = self
            .spindles
            .iter()
            .filter(|s| !after_gap && s.elongation.is_some());
        for spindle in starting {
            if let Some(excess) = warm_excess(frame[spindle.channels.stator], ambient_C) {
                notes.push(format!(
                    "{}: the spindle was warm at the first frame (stator {excess:.1} K above the \
                     room): its elongation model's heat starts at rest, so for the first hours \
                     the elongation since the tool calibration may read growth a spindle already \
                     in balance does not show (no warm start is fitted for it: seeded from the \
                     stator it read worse, docs/accuracy.md)",
                    spindle.axis
                ));
            }
        }
        self.notes.extend(notes);
    }

    /// The estimators' state after `frame` (the latest frame updated, laid out as the schema
    /// the pipeline was built for), for a later session to take up ([`Self::restore_state`]);
    /// `None` before the first frame. Saving walks the state as restoring does
    /// ([`StateWalk`]), hence `&mut`; it changes nothing.
    pub fn save_state(&mut self, frame: &[f64]) -> Option<SavedState> {
        let time_s = self.previous_time?;
        let calibration_sha256 = self.calibration_sha256.clone()?;
        let mut walk = StateWalk::saving();
        self.walk_state(&mut walk);
        let values = walk
            .into_saved()
            .into_iter()
            .map(|v| v.is_finite().then_some(v))
            .collect();
        Some(SavedState {
            format: STATE_FORMAT,
            profile: self.profile_name.clone(),
            calibration_sha256,
            outputs: self.outputs().into_iter().map(|o| o.column).collect(),
            time_s,
            frame_unix_s: None,
            readings: self.resume_readings(frame),
            values,
            spindles: self
                .spindles
                .iter()
                .map(|s| SavedSpindle {
                    axis: s.axis,
                    origin: s.elongation_origin,
                    start: s.start,
                    tool_measured_pending: s.tool_measured_pending,
                })
                .collect(),
        })
    }

    /// Takes up a state saved by [`Self::save_state`] from the same calibration and the same
    /// estimates, as if the frames had run on here: the next frame's step is the machine time
    /// since the state's last frame. Whether the machine is still where the state left it is
    /// for [`SavedState::check_resume`] to say on the first frame, before this pipeline takes
    /// it, and [`Self::carry_on`] to carry it across the break.
    /// On an error the pipeline must not be used (part of the state may be restored).
    pub fn restore_state(&mut self, saved: &SavedState) -> Result<(), StateError> {
        if saved.format != STATE_FORMAT {
            return Err(StateError::Format {
                found: saved.format,
            });
        }
        if self.calibration_sha256.as_ref() != Some(&saved.calibration_sha256) {
            return Err(StateError::Calibration {
                saved: saved.profile.clone(),
            });
        }
        let now: Vec<String> = self.outputs().into_iter().map(|o| o.column).collect();
        if saved.outputs != now {
            return Err(StateError::Outputs {
                saved: saved.outputs.clone(),
                now,
            });
        }
        let values = saved.walk_values();
        let mut walk = StateWalk::restoring(&values);
        self.walk_state(&mut walk);
        walk.finish()?;
        for spindle in &mut self.spindles {
            if let Some(s) = saved.spindles.iter().find(|s| s.axis == spindle.axis) {
                spindle.elongation_origin = s.origin;
                spindle.start = s.start;
                spindle.tool_measured_pending = s.tool_measured_pending;
            }
        }
        // Not `None`: the first frame is not a start (no warm-start note, no seeding).
        self.previous_time = Some(saved.time_s);
        Ok(())
    }

    /// Carries a restored state on across the break `resume` measured
    /// ([`SavedState::check_resume`]): its machine times move onto the clock of the frames to
    /// come, so that the next frame's step is the time passed; where that clock started again,
    /// the abnormality scores' blocks start again too (a block is a span of machine time). (Starting the parts' heat again
    /// from the warm start after a longer break, the rest carried on, was tried: it followed the
    /// machine worse than either, the warm start being fitted for lags that start settled.)
    pub fn carry_on(&mut self, resume: &Resume) {
        self.shift_machine_time(resume.time_shift_s);
        if matches!(resume.clock, Clock::Restarted { .. }) {
            self.start_abnormality_blocks_again();
        }
    }

    /// Starts every abnormality score's blocks again (a block is a span of machine time, which
    /// a clock started again or a gap in the frames breaks); the averages stay.
    fn start_abnormality_blocks_again(&mut self) {
        let feed = self.feed.iter_mut().map(|a| &mut a.abnormality);
        let spindles = self.spindles.iter_mut().map(|s| &mut s.abnormality);
        for abnormality in feed.chain(spindles).flatten() {
            abnormality.start_blocks_again();
        }
    }

    /// Moves the machine times the pipeline keeps (its last frame's, where each elongation
    /// counts from) by `shift_s`.
    fn shift_machine_time(&mut self, shift_s: f64) {
        if let Some(t) = self.previous_time.as_mut() {
            *t += shift_s;
        }
        for spindle in &mut self.spindles {
            for origin in [&mut spindle.elongation_origin, &mut spindle.start]
                .into_iter()
                .flatten()
            {
                origin.shift_time(shift_s);
            }
        }
    }

    /// The readings a resumed state is checked by: each axis's stator and the room.
    fn resume_readings(&self, frame: &[f64]) -> Vec<SavedReading> {
        let axes = self
            .feed
            .iter()
            .map(|a| (a.axis, a.channels.stator))
            .chain(self.spindles.iter().map(|s| (s.axis, s.channels.stator)));
        axes.map(|(axis, index)| (axis_column(axis, Quantity::StatorTemp), Some(index)))
            .chain(self.ambient.map(|i| (AMBIENT.to_string(), Some(i))))
            .map(|(column, index)| SavedReading {
                column,
                value: index
                    .and_then(|i| frame.get(i))
                    .copied()
                    .filter(|v| v.is_finite()),
            })
            .collect()
    }

    /// The latest estimates of a feed axis.
    pub fn feed_axis(&self, axis: AxisId) -> Option<&FeedAxisEstimate> {
        self.feed
            .iter()
            .find(|a| a.axis == axis)
            .map(|a| &a.estimate)
    }

    /// The estimated temperatures and thermal states the straightness models of a feed axis
    /// read on the latest frame.
    pub fn straightness_inputs(&self, axis: AxisId) -> Option<&StraightnessInputs> {
        self.feed
            .iter()
            .find(|a| a.axis == axis)
            .map(|a| &a.thermal_state)
    }

    /// The latest estimates of a spindle.
    pub fn spindle(&self, axis: AxisId) -> Option<&SpindleEstimate> {
        self.spindles
            .iter()
            .find(|a| a.axis == axis)
            .map(|a| &a.estimate)
    }

    /// The operator measured the tool: spindle elongation counts from the next frame.
    pub fn reset_tool_calibration(&mut self) {
        for spindle in &mut self.spindles {
            if let Some(elongation) = &mut spindle.elongation {
                elongation.reset_tool_calibration();
                spindle.elongation_origin = None;
                spindle.tool_measured_pending = true;
            }
        }
    }

    /// Where each spindle's elongation counts from, `None` for one that has not counted a
    /// frame since the start or the last tool measurement. Only spindles with an elongation
    /// model are listed.
    pub fn elongation_origins(&self) -> Vec<(AxisId, Option<ElongationOrigin>)> {
        self.spindles
            .iter()
            .filter(|s| s.elongation.is_some())
            .map(|s| (s.axis, s.elongation_origin))
            .collect()
    }

    /// The estimates this pipeline produces, as (estimate id, output column, reference column).
    pub fn outputs(&self) -> Vec<EstimateOutput> {
        let mut out = Vec::new();
        for axis in &self.feed {
            let a = axis.axis;
            let mut push = |id: String, est: String, reference: String| {
                out.push(EstimateOutput {
                    id,
                    column: est,
                    reference,
                    counts_from_first_row: false,
                })
            };
            if axis.flange.is_some() {
                push(
                    "motor_flange_temp".into(),
                    format!("est.{a}.motor_flange_temp_C"),
                    reference_column(a, "motor_flange_temp_C", None),
                );
            }
            if axis.split.is_some() {
                for (id, q) in [
                    ("front_bearing_torque", "front_bearing_torque_Nm"),
                    ("back_bearing_torque", "back_bearing_torque_Nm"),
                    ("nut_torque", "nut_torque_Nm"),
                ] {
                    push(
                        id.into(),
                        format!("est.{a}.{q}"),
                        reference_column(a, q, None),
                    );
                }
            }
            for (present, id, q) in [
                (
                    axis.front.is_some(),
                    "front_bearing_temp",
                    "front_bearing_temp_C",
                ),
                (
                    axis.back.is_some(),
                    "back_bearing_temp",
                    "back_bearing_temp_C",
                ),
                (axis.nut.is_some(), "nut_temp", "nut_temp_C"),
            ] {
                if present {
                    push(
                        id.into(),
                        format!("est.{a}.{q}"),
                        reference_column(a, q, None),
                    );
                }
            }
            for (estimator, hv) in [(&axis.straightness_h, "h"), (&axis.straightness_v, "v")] {
                if let Some(s) = estimator {
                    for k in 1..=s.nodes() {
                        let q = format!("straightness_{hv}_um");
                        push(
                            format!("straightness_{hv}#{k}"),
                            format!("est.{a}.{q}#{k}"),
                            reference_column(a, &q, Some(k)),
                        );
                    }
                    push(
                        format!("straightness_{hv}_zone"),
                        format!("est.{a}.straightness_{hv}_zone_um"),
                        String::new(),
                    );
                }
            }
            if axis.abnormality.is_some() {
                out.push(abnormality_output(a));
            }
        }
        for spindle in &self.spindles {
            let a = spindle.axis;
            if spindle.elongation.is_some() {
                out.push(EstimateOutput {
                    id: "spindle_elongation".into(),
                    column: format!("est.{a}.elongation_um"),
                    reference: reference_column(a, "elongation_um", None),
                    counts_from_first_row: true,
                });
            }
            if spindle.abnormality.is_some() {
                out.push(abnormality_output(a));
            }
        }
        out
    }

    /// Writes the latest estimates in the order of [`Self::outputs`].
    pub fn write_outputs(&self, out: &mut Vec<f64>) {
        out.clear();
        for axis in &self.feed {
            let e = &axis.estimate;
            if axis.flange.is_some() {
                out.push(e.motor_flange_C);
            }
            if axis.split.is_some() {
                out.extend([
                    e.split.front_bearing_Nm,
                    e.split.back_bearing_Nm,
                    e.split.nut_Nm,
                ]);
            }
            for (present, value) in [
                (axis.front.is_some(), e.front_bearing_C),
                (axis.back.is_some(), e.back_bearing_C),
                (axis.nut.is_some(), e.nut_C),
            ] {
                if present {
                    out.push(value);
                }
            }
            for (estimator, values, zone) in [
                (
                    &axis.straightness_h,
                    &e.straightness_h_um,
                    e.straightness_h_zone_um(),
                ),
                (
                    &axis.straightness_v,
                    &e.straightness_v_um,
                    e.straightness_v_zone_um(),
                ),
            ] {
                if let Some(s) = estimator {
                    out.extend_from_slice(&values[..s.nodes()]);
                    out.push(zone);
                }
            }
            if axis.abnormality.is_some() {
                out.push(e.abnormality.excess_pct);
            }
        }
        for spindle in &self.spindles {
            if spindle.elongation.is_some() {
                out.push(spindle.estimate.elongation_um);
            }
            if spindle.abnormality.is_some() {
                out.push(spindle.estimate.abnormality.excess_pct);
            }
        }
    }
}

impl WalkState for EstimatorPipeline {
    fn walk_state(&mut self, walk: &mut StateWalk<'_>) {
        self.room.walk_state(walk);
        self.coolant_lags.walk_state(walk);
        for axis in &mut self.feed {
            axis.stator_lags.walk_state(walk);
            axis.bed.walk_state(walk);
            axis.front.walk_state(walk);
            axis.back.walk_state(walk);
            axis.nut.walk_state(walk);
            axis.abnormality.walk_state(walk);
        }
        for spindle in &mut self.spindles {
            spindle.elongation.walk_state(walk);
            spindle.abnormality.walk_state(walk);
        }
        walk.optional_state(&mut self.spindle_room);
    }
}

/// The abnormality score's output: no reference instrument measures it.
fn abnormality_output(axis: AxisId) -> EstimateOutput {
    EstimateOutput {
        id: "motor_abnormality".into(),
        column: format!("est.{axis}.abnormality_pct"),
        reference: String::new(),
        counts_from_first_row: false,
    }
}

/// One estimate the pipeline writes.
#[derive(Debug, Clone, PartialEq)]
pub struct EstimateOutput {
    /// The estimate id of DESIGN.md (`nut_temp`, `straightness_h#3`, …).
    pub id: String,
    /// The output column (`est.X.nut_temp_C`).
    pub column: String,
    /// The reference column it is validated against (empty if none can exist).
    pub reference: String,
    /// The estimate counts from the first row, as the spindle elongation counts from the
    /// tool-calibration moment: it is scored against the reference's change since that row,
    /// not against its value (which counts from a machine at rest, and which a recording that
    /// starts mid-shift does not start from).
    pub counts_from_first_row: bool,
}

fn uses_ambient(models: &AxisModels) -> bool {
    let uses = |m: &super::models::LinearModel| {
        m.terms
            .iter()
            .any(|t| t == "ambient" || AMBIENT_LAG_FEATURES.contains(&t.as_str()))
    };
    models.motor_flange.as_ref().is_some_and(uses)
        || [
            &models.front_bearing_temp,
            &models.back_bearing_temp,
            &models.nut_temp,
        ]
        .iter()
        .any(|m| m.as_ref().is_some_and(|h| uses(&h.temperature)))
        || models
            .straightness_h
            .iter()
            .chain(&models.straightness_v)
            .any(uses)
        || models.elongation.as_ref().is_some_and(|e| uses(&e.model))
        || models
            .abnormality
            .as_ref()
            .is_some_and(MotorAbnormalityEstimator::uses_ambient)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::estimators::models::LinearModel;
    use crate::estimators::state::{Clock, Resume};
    use crate::signal::Recording;
    use crate::sim::{ScenarioKind, TwinConfig, simulate};

    /// The twin's profile with the X front bearing's temperature read by `terms` alone.
    fn profile_with_front_bearing(terms: &[&str], coefficients: &[f64]) -> MachineProfile {
        let mut profile = MachineProfile::twin_calibrated().unwrap();
        let calibration = profile.calibration.as_mut().unwrap();
        let front = calibration
            .axes
            .get_mut(&AxisId::X)
            .and_then(|m| m.front_bearing_temp.as_mut())
            .unwrap();
        front.temperature = LinearModel::with_terms(terms, coefficients);
        profile
    }

    fn short_recording() -> Recording {
        simulate(TwinConfig::new(ScenarioKind::Production, Some(0.02), 1)).unwrap()
    }

    /// A bearing whose model reads the stator's 15 min lag and the coolant's 30 min lag sees
    /// both start settled at their first readings and follow a step as first-order lags do.
    #[test]
    fn a_bearing_reads_the_stator_and_the_coolant_through_the_axis_lags() {
        let profile = profile_with_front_bearing(
            &["const", "stator_lag_15min", "coolant_lag_30min"],
            &[1.0, 0.5, 2.0],
        );
        let recording = short_recording();
        let schema = recording.schema();
        let stator = schema
            .index_of(&axis_column(AxisId::X, Quantity::StatorTemp))
            .unwrap();
        let coolant = schema.index_of(COOLANT).unwrap();
        let mut pipeline = EstimatorPipeline::new(&profile, schema).unwrap();
        let mut frame = Vec::new();
        recording.row_into(0, &mut frame);
        let front = |p: &EstimatorPipeline| p.feed_axis(AxisId::X).unwrap().front_bearing_C;
        frame[0] = 0.0;
        frame[stator] = 20.0;
        frame[coolant] = 0.0;
        pipeline.update(&frame);
        assert!((front(&pipeline) - (1.0 + 0.5 * 20.0)).abs() < 1e-12);
        for second in 1..=900 {
            frame[0] = second as f64;
            frame[stator] = 30.0;
            frame[coolant] = 1.0;
            pipeline.update(&frame);
        }
        let stator_lag = 30.0 - 10.0 * (-1.0f64).exp();
        let coolant_lag = 1.0 - (-0.5f64).exp();
        let expected = 1.0 + 0.5 * stator_lag + 2.0 * coolant_lag;
        assert!(
            (front(&pipeline) - expected).abs() < 1e-9,
            "{} against {expected}",
            front(&pipeline)
        );
    }

    /// The elongation counts from the first frame, which says whether the spindle was at rest
    /// then (within the warm-start floor of the room), warm, or unread; after a tool
    /// measurement it counts from the next frame.
    #[test]
    fn the_elongation_says_where_it_counts_from() {
        let profile = MachineProfile::twin_calibrated().unwrap();
        let recording = short_recording();
        let schema = recording.schema();
        let stator = schema
            .index_of(&axis_column(AxisId::S, Quantity::StatorTemp))
            .unwrap();
        let room = schema.index_of(AMBIENT).unwrap();
        let mut frame = Vec::new();
        recording.row_into(0, &mut frame);
        let first = |time_s: f64, stator_C: f64, room_C: f64| {
            let mut pipeline = EstimatorPipeline::new(&profile, schema).unwrap();
            assert_eq!(pipeline.elongation_origins(), vec![(AxisId::S, None)]);
            let mut frame = frame.clone();
            frame[0] = time_s;
            frame[stator] = stator_C;
            frame[room] = room_C;
            pipeline.update(&frame);
            let origins = pipeline.elongation_origins();
            assert_eq!(origins.len(), 1);
            // It counts from the estimate's first value, as the estimator's zero does.
            let estimate = pipeline.spindle(AxisId::S).unwrap().elongation_um;
            assert_eq!(origins[0].1.is_some(), estimate.is_finite(), "{estimate}");
            (pipeline, origins[0].1)
        };
        let floor = WARM_START_FLOOR_K;
        assert_eq!(
            first(5.0, 22.0 + floor, 22.0).1,
            Some(ElongationOrigin::FirstFrameAtRest { time_s: 5.0 })
        );
        assert_eq!(
            first(5.0, 18.0, 22.0).1,
            Some(ElongationOrigin::FirstFrameAtRest { time_s: 5.0 })
        );
        assert_eq!(
            first(5.0, 30.0, 22.0).1,
            Some(ElongationOrigin::FirstFrameWarm {
                time_s: 5.0,
                excess_K: 8.0
            })
        );
        // Unread where the model gives a value without the reading; nothing where it does not.
        for (stator_C, room_C) in [(f64::NAN, 22.0), (30.0, f64::NAN), (f64::INFINITY, 22.0)] {
            let origin = first(5.0, stator_C, room_C).1;
            assert!(
                origin.is_none_or(|o| o == ElongationOrigin::FirstFrameUnread { time_s: 5.0 }),
                "{stator_C} {room_C}: {origin:?}"
            );
        }
        assert_eq!(
            ElongationOrigin::at_first_frame(5.0, f64::NAN, 22.0),
            ElongationOrigin::FirstFrameUnread { time_s: 5.0 }
        );
        let (mut pipeline, origin) = first(5.0, 30.0, 22.0);
        let origin = origin.unwrap();
        assert!(!origin.is_known());
        pipeline.reset_tool_calibration();
        assert_eq!(pipeline.elongation_origins(), vec![(AxisId::S, None)]);
        frame[0] = 6.0;
        pipeline.update(&frame);
        let measured = pipeline.elongation_origins()[0].1.unwrap();
        assert_eq!(
            measured,
            ElongationOrigin::ToolMeasured {
                time_s: 6.0,
                started_warm_K: Some(8.0)
            }
        );
        assert!(measured.is_known());
        // Later frames keep the origin.
        frame[0] = 7.0;
        pipeline.update(&frame);
        assert_eq!(pipeline.elongation_origins()[0].1, Some(measured));
        // The tool measured before the first frame: the first frame counts from it.
        let mut early = EstimatorPipeline::new(&profile, schema).unwrap();
        early.reset_tool_calibration();
        frame[0] = 3.0;
        frame[stator] = 30.0;
        frame[room] = 22.0;
        early.update(&frame);
        assert_eq!(
            early.elongation_origins(),
            vec![(
                AxisId::S,
                Some(ElongationOrigin::ToolMeasured {
                    time_s: 3.0,
                    started_warm_K: Some(8.0)
                })
            )]
        );
    }

    /// Frames without the coolant column are refused by a profile whose bearing model reads
    /// the coolant, and the error names that model beside the others that read it.
    #[test]
    fn a_bearing_model_that_reads_the_coolant_refuses_frames_without_it() {
        let profile = profile_with_front_bearing(&["const", "coolant_lag_90min"], &[20.0, 1.0]);
        let recording = short_recording();
        let names: Vec<String> = recording
            .schema()
            .names()
            .iter()
            .filter(|name| name.as_str() != COOLANT)
            .cloned()
            .collect();
        let schema = Schema::new(names, "no-coolant.csv").unwrap();
        let Err(error) = EstimatorPipeline::new(&profile, &schema) else {
            panic!("frames without the coolant were accepted");
        };
        let message = error.to_string();
        assert!(
            message.contains(COOLANT) && message.contains("X front bearing temperature model"),
            "{message}"
        );
        let front_without_coolant = profile_with_front_bearing(&["const", "stator"], &[1.0, 1.0]);
        let Err(error) = EstimatorPipeline::new(&front_without_coolant, &schema) else {
            panic!("frames without the coolant were accepted, though the straightness reads it");
        };
        assert!(!error.to_string().contains("front bearing"), "{error}");
    }

    /// Three hours of the production program at 1 Hz, every effect on.
    fn shift_at_1_hz() -> Recording {
        let mut config = TwinConfig::new(ScenarioKind::Production, Some(3.0), 4);
        config.rate_hz = 1.0;
        simulate(config).unwrap()
    }

    /// Every output of the pipeline after each frame of `rows`, NaN as `None` (so that equal
    /// runs compare equal).
    fn run(
        pipeline: &mut EstimatorPipeline,
        recording: &Recording,
        rows: std::ops::Range<usize>,
    ) -> Vec<Vec<Option<f64>>> {
        let mut frame = Vec::new();
        let mut out = Vec::new();
        rows.map(|i| {
            recording.row_into(i, &mut frame);
            pipeline.update(&frame);
            pipeline.write_outputs(&mut out);
            out.iter().map(|v| (!v.is_nan()).then_some(*v)).collect()
        })
        .collect()
    }

    /// A state saved after two hours, written as JSON and read back into a new pipeline, gives
    /// the very estimates the pipeline that never stopped gives, frame for frame, with the tool
    /// measurement the elongation counted from.
    #[test]
    fn a_pipeline_that_takes_up_a_saved_state_goes_on_as_if_it_had_never_stopped() {
        let profile = MachineProfile::twin_calibrated().unwrap();
        let recording = shift_at_1_hz();
        let schema = recording.schema();
        let (measured, saved_at, end) = (1800, 7200, recording.len());
        let mut through = EstimatorPipeline::new(&profile, schema).unwrap();
        let mut first = EstimatorPipeline::new(&profile, schema).unwrap();
        for pipeline in [&mut through, &mut first] {
            run(pipeline, &recording, 0..measured);
            pipeline.reset_tool_calibration();
            run(pipeline, &recording, measured..saved_at);
        }
        let mut frame = Vec::new();
        recording.row_into(saved_at - 1, &mut frame);
        let saved = first.save_state(&frame).expect("frames were taken");
        let text = serde_json::to_string(&saved).unwrap();
        let read: SavedState = serde_json::from_str(&text).unwrap();
        assert_eq!(read, saved);
        let mut next = EstimatorPipeline::new(&profile, schema).unwrap();
        next.restore_state(&read).expect("the same calibration");
        assert_eq!(next.elongation_origins(), through.elongation_origins());
        assert!(matches!(
            next.elongation_origins()[0].1,
            Some(ElongationOrigin::ToolMeasured { time_s, .. }) if time_s == measured as f64
        ));
        let expected = run(&mut through, &recording, saved_at..end);
        let resumed = run(&mut next, &recording, saved_at..end);
        assert_eq!(resumed, expected);
        assert!(next.notes().is_empty(), "not a start: {:?}", next.notes());
        // A fresh pipeline from the same frame does not give them (the test can tell).
        let mut fresh = EstimatorPipeline::new(&profile, schema).unwrap();
        assert_ne!(run(&mut fresh, &recording, saved_at..end), expected);
    }

    /// A state saved with another calibration, or for other estimates, is not taken up; one
    /// whose machine reads elsewhere, whose clock went back or that is too old is refused at the
    /// first frame.
    #[test]
    fn a_saved_state_is_taken_up_only_by_its_models_on_a_machine_where_it_left_it() {
        let profile = MachineProfile::twin_calibrated().unwrap();
        let recording = short_recording();
        let schema = recording.schema();
        let mut pipeline = EstimatorPipeline::new(&profile, schema).unwrap();
        let mut frame = Vec::new();
        assert!(pipeline.save_state(&frame).is_none(), "no frame yet");
        run(&mut pipeline, &recording, 0..60);
        recording.row_into(59, &mut frame);
        let saved = pipeline.save_state(&frame).unwrap();
        let other = profile_with_front_bearing(&["const", "stator"], &[1.0, 0.9]);
        let mut elsewhere = EstimatorPipeline::new(&other, schema).unwrap();
        assert!(matches!(
            elsewhere.restore_state(&saved),
            Err(StateError::Calibration { .. })
        ));
        let mut fewer = saved.clone();
        fewer.values.pop();
        let mut same = EstimatorPipeline::new(&profile, schema).unwrap();
        assert!(matches!(
            same.restore_state(&fewer),
            Err(StateError::Length { .. })
        ));
        let mut renamed = saved.clone();
        renamed.outputs[0] = "est.Y.motor_flange_temp_C".into();
        assert!(matches!(
            same.restore_state(&renamed),
            Err(StateError::Outputs { .. })
        ));
        let mut newer = saved.clone();
        newer.format += 1;
        assert!(matches!(
            same.restore_state(&newer),
            Err(StateError::Format { .. })
        ));

        let stator = schema
            .index_of(&axis_column(AxisId::S, Quantity::StatorTemp))
            .unwrap();
        let at = |time_s: f64, stator_step_K: f64| {
            let mut next = frame.clone();
            next[0] = time_s;
            next[stator] += stator_step_K;
            saved.check_resume(schema, &next, Clock::Continued)
        };
        let t = saved.time_s;
        let resume = |gap_s: f64, time_shift_s: f64, clock: Clock| {
            Ok(Resume {
                gap_s,
                time_shift_s,
                clock,
            })
        };
        let continued = |gap_s: f64| resume(gap_s, 0.0, Clock::Continued);
        // In two minutes a stator may move 1 K + 1.5 K/min × 2 min.
        assert_eq!(at(t + 120.0, 3.9), continued(120.0));
        assert_eq!(at(t + 120.0, -3.9), continued(120.0));
        assert!(matches!(
            at(t + 120.0, 4.1),
            Err(StateError::Moved { column, allowed_K, .. })
                if column == "S.stator_temp_C" && (allowed_K - 4.0).abs() < 1e-9
        ));
        assert!(matches!(at(t + 1.0, -1.1), Err(StateError::Moved { .. })));
        assert!(matches!(
            at(t + 120.0, f64::NAN),
            Err(StateError::Unread { .. })
        ));
        assert!(matches!(
            at(t + MAX_RESUME_GAP_S + 1.0, 0.0),
            Err(StateError::TooLong { .. })
        ));
        assert!(matches!(at(f64::NAN, 0.0), Err(StateError::NoTime)));
        // A recording's clock behind the state's: another recording, or the same one again.
        assert!(matches!(at(2.0, 0.0), Err(StateError::ClockBehind { .. })));
        // A live link's clock counts from its start: the wall clock says how long ago the
        // state's last frame was, whatever the frames' time.
        assert!(matches!(
            saved.check_resume(schema, &frame, Clock::Restarted { now_unix_s: 1.0e9 }),
            Err(StateError::NoWallClock)
        ));
        let mut stamped = saved.clone();
        stamped.frame_unix_s = Some(1.0e9);
        let restarted = |time_s: f64, now_unix_s: f64| {
            let mut next = frame.clone();
            next[0] = time_s;
            stamped.check_resume(schema, &next, Clock::Restarted { now_unix_s })
        };
        let wall = |now_unix_s| Clock::Restarted { now_unix_s };
        assert_eq!(
            restarted(2.0, 1.0e9 + 90.0),
            resume(90.0, (2.0 - 90.0) - t, wall(1.0e9 + 90.0))
        );
        // A link started again a day later whose time happens to read past the state's.
        assert!(matches!(
            restarted(t + 50.0, 1.0e9 + 86_400.0),
            Err(StateError::TooLong { .. })
        ));
        assert!(matches!(
            restarted(2.0, 1.0e9 - 1.0),
            Err(StateError::WallClockBehind)
        ));
        let mut unread = saved.clone();
        unread.readings[0].value = None;
        assert!(matches!(
            unread.check_resume(schema, &frame, Clock::Continued),
            Err(StateError::UnreadThen { .. })
        ));
        // Taken up on the new clock, the state's times move with it.
        let mut next = EstimatorPipeline::new(&profile, schema).unwrap();
        next.restore_state(&saved).unwrap();
        let before = next.elongation_origins()[0]
            .1
            .expect("counted from the first frame");
        next.carry_on(&Resume {
            gap_s: 10.0,
            time_shift_s: -1000.0,
            clock: wall(1.0e9 + 10.0),
        });
        let after = next.elongation_origins()[0].1.unwrap();
        assert_eq!(after.time_s(), before.time_s() - 1000.0);
        // The file: its layout's version read first, a damaged one named as such.
        let text = serde_json::to_string(&newer).unwrap();
        assert!(matches!(
            SavedState::from_json(&text),
            Err(StateError::Format { found }) if found == STATE_FORMAT + 1
        ));
        let text = serde_json::to_string(&saved).unwrap();
        assert_eq!(SavedState::from_json(&text), Ok(saved.clone()));
        assert!(matches!(
            SavedState::from_json(&text[..text.len() / 2]),
            Err(StateError::Damaged(_))
        ));
        let readings: Vec<&str> = saved.readings.iter().map(|r| r.column.as_str()).collect();
        assert_eq!(
            readings,
            ["X.stator_temp_C", "S.stator_temp_C", "ambient_C"]
        );
    }

    /// After a break of two minutes (the HMI closed, the machine running on), the state taken
    /// up follows the pipeline that saw every frame closer than a fresh start does.
    #[test]
    fn a_state_taken_up_after_a_break_follows_the_machine_closer_than_a_fresh_start() {
        let profile = MachineProfile::twin_calibrated().unwrap();
        let recording = shift_at_1_hz();
        let schema = recording.schema();
        let (saved_at, back_at, end) = (7200, 7320, recording.len());
        let mut through = EstimatorPipeline::new(&profile, schema).unwrap();
        run(&mut through, &recording, 0..saved_at);
        let mut frame = Vec::new();
        recording.row_into(saved_at - 1, &mut frame);
        let saved = through.save_state(&frame).unwrap();
        let expected = run(&mut through, &recording, saved_at..end);
        recording.row_into(back_at, &mut frame);
        let gap_s = saved
            .check_resume(schema, &frame, Clock::Continued)
            .expect("the machine is where it was")
            .gap_s;
        let mut resumed = EstimatorPipeline::new(&profile, schema).unwrap();
        resumed.restore_state(&saved).unwrap();
        let resumed = run(&mut resumed, &recording, back_at..end);
        let mut fresh = EstimatorPipeline::new(&profile, schema).unwrap();
        let fresh = run(&mut fresh, &recording, back_at..end);
        assert_eq!(gap_s, 121.0);
        let expected = &expected[back_at - saved_at..];
        // Mean absolute difference from the pipeline that saw every frame, per output.
        let mean_error = |run: &[Vec<Option<f64>>], j: usize| {
            let errors: Vec<f64> = run
                .iter()
                .zip(expected)
                .filter_map(|(a, b)| Some((a[j]? - b[j]?).abs()))
                .collect();
            errors.iter().sum::<f64>() / errors.len() as f64
        };
        let mut compared = 0;
        for (j, output) in through.outputs().into_iter().enumerate() {
            if output.column.contains("torque") || output.column.contains("abnormality") {
                // A frame's torque split holds no state; the score is not known yet.
                continue;
            }
            let (after_break, afresh) = (mean_error(&resumed, j), mean_error(&fresh, j));
            assert!(
                after_break < afresh,
                "{}: {after_break} against {afresh}",
                output.column
            );
            compared += 1;
        }
        assert_eq!(compared, 17);
        // The elongation since the first frame (at rest): 0.34 µm off on average, where a fresh
        // start counts from its own first frame and misses the 17 µm grown before.
        let elongation = through
            .outputs()
            .iter()
            .position(|o| o.column == "est.S.elongation_um")
            .unwrap();
        assert!(mean_error(&resumed, elongation) < 0.5);
        assert!(mean_error(&fresh, elongation) > 10.0);
    }

    /// A gap in the frames longer than five minutes (a link down, a piece of the recording
    /// missing) starts the feed axes' heat, their lags and the room's and coolant's as at a
    /// first frame: after it every feed-axis estimate is the one a pipeline started at that
    /// frame gives. The elongation steps over it and counts on from the first frame, known no
    /// more; the abnormality averages are kept. A gap of five minutes is stepped over.
    #[test]
    fn a_gap_in_the_frames_longer_than_five_minutes_starts_the_heat_again() {
        let profile = MachineProfile::twin_calibrated().unwrap();
        let recording = shift_at_1_hz();
        let schema = recording.schema();
        let end = recording.len();
        let columns: Vec<String> = EstimatorPipeline::new(&profile, schema)
            .unwrap()
            .outputs()
            .into_iter()
            .map(|o| o.column)
            .collect();
        let feed_axis = |c: &String| c.starts_with("est.X.") && !c.contains("abnormality");
        let column = |name: &str| columns.iter().position(|c| c == name).unwrap();
        let elongation = column("est.S.elongation_um");
        for (gap_from, back_at) in [(7200, 7801), (7200, 7499)] {
            let gap_s = (back_at - gap_from + 1) as f64;
            let mut gappy = EstimatorPipeline::new(&profile, schema).unwrap();
            run(&mut gappy, &recording, 0..gap_from);
            let after = run(&mut gappy, &recording, back_at..end);
            let mut fresh = EstimatorPipeline::new(&profile, schema).unwrap();
            let fresh = run(&mut fresh, &recording, back_at..end);
            let same = |j: usize| after.iter().zip(&fresh).all(|(a, b)| a[j] == b[j]);
            let restarted: Vec<&String> = (0..columns.len())
                .filter(|&j| feed_axis(&columns[j]) && same(j))
                .map(|j| &columns[j])
                .collect();
            let feed_columns = columns.iter().filter(|c| feed_axis(c)).count();
            assert!(!same(elongation), "the elongation steps over the gap");
            // Exactly as a pipeline that steps over every gap has it.
            let mut stepping = EstimatorPipeline::new(&profile, schema).unwrap();
            stepping.step_over_gaps_up_to(f64::INFINITY);
            run(&mut stepping, &recording, 0..gap_from);
            let stepped = run(&mut stepping, &recording, back_at..end);
            let column_of = |rows: &[Vec<Option<f64>>], j: usize| -> Vec<Option<f64>> {
                rows.iter().map(|r| r[j]).collect()
            };
            assert_eq!(
                column_of(&after, elongation),
                column_of(&stepped, elongation)
            );
            let origin = gappy.elongation_origins()[0].1.expect("counted");
            if gap_s > MAX_RESUME_GAP_S {
                assert_eq!(restarted.len(), feed_columns, "{restarted:?}");
                assert_eq!(
                    origin,
                    ElongationOrigin::AcrossGap {
                        time_s: 0.0,
                        gap_end_s: back_at as f64,
                        gap_s,
                    }
                );
                assert!(!origin.is_known());
                let note = format!("a gap of {gap_s:.0} s in the frames before machine time");
                assert!(
                    gappy.notes().iter().any(|n| n.contains(&note)),
                    "{:?}",
                    gappy.notes()
                );
                // A state saved after the gap goes on as the pipeline does (the spindles' own
                // room lags included).
                let mut through = EstimatorPipeline::new(&profile, schema).unwrap();
                run(&mut through, &recording, 0..gap_from);
                let saved_at = back_at + 600;
                run(&mut through, &recording, back_at..saved_at);
                let mut frame = Vec::new();
                recording.row_into(saved_at - 1, &mut frame);
                let saved = through.save_state(&frame).unwrap();
                let mut resumed = EstimatorPipeline::new(&profile, schema).unwrap();
                resumed.restore_state(&saved).unwrap();
                assert_eq!(
                    run(&mut resumed, &recording, saved_at..end),
                    after[saved_at - back_at..]
                );
                // The abnormality averages carried over: the score is not a fresh start's.
                assert_ne!(
                    format!("{:?}", gappy.abnormality_scores()),
                    format!("{:?}", fresh_scores(&profile, &recording, back_at)),
                );
            } else {
                // Stepped over: only the split of a frame's torque, which holds no state,
                // equals a fresh start's.
                assert!(
                    restarted.iter().all(|c| c.contains("torque")),
                    "{restarted:?}"
                );
                assert_eq!(origin, ElongationOrigin::FirstFrameAtRest { time_s: 0.0 });
                assert!(gappy.notes().is_empty(), "{:?}", gappy.notes());
            }
        }
    }

    /// The abnormality scores of a pipeline started at row `from` of `recording`, at its end.
    fn fresh_scores(
        profile: &MachineProfile,
        recording: &Recording,
        from: usize,
    ) -> Vec<(AxisId, AbnormalityScore)> {
        let mut fresh = EstimatorPipeline::new(profile, recording.schema()).unwrap();
        run(&mut fresh, recording, from..recording.len());
        fresh.abnormality_scores()
    }
}
