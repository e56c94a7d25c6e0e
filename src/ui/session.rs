//! The session worker: the one place that owns the controller link, the recorder and the
//! audit log, on its own named thread (`servosight-session`) with a small tokio runtime.
//!
//! The UI thread never touches the link: it sends [`SessionCommand`]s and drains
//! [`SessionUpdate`]s, both through bounded channels and without ever waiting. The worker wakes
//! on a frame, a command or a 100 ms tick; it writes every frame to disk first (full rate) and
//! then forwards it to the UI. Commands that must wait for the controller (reading the
//! compensation table, an approved push with its read-back) run here between wake-ups; the
//! link keeps buffering frames meanwhile ([`crate::link::FRAME_CHANNEL_CAPACITY`] frames, four
//! seconds at 1 kHz), so nothing is lost.

use std::path::PathBuf;
use std::sync::{Arc, OnceLock};
use std::time::{Duration, Instant};

use tokio::sync::mpsc;

use super::state::{
    Event, EventKind, LinkSnapshot, PushResult, PushedValue, RecorderSnapshot, RecorderState,
    SavedReport, Severity,
};
use super::vm::warmup::WarmupReport;
use crate::compensation::{
    self, AuditEntry, AuditLog, CompensationLimits, CompensationValues, Credentials, Request, Role,
};
use crate::estimators::EstimatorPipeline;
use crate::estimators::fingerprint::FrictionFingerprint;
use crate::estimators::pipeline::ElongationOrigin;
use crate::estimators::state::{Clock, SavedState, StateError, unix_now_s};
use crate::link::{
    ConnectionState, ControllerLink, LinkError, ModbusConfig, Recorder, RecorderConfig,
    ReplayOptions, ReplaySpeed,
};
use crate::profile::MachineProfile;
use crate::signal::AxisId;
use crate::signal::Schema;
use crate::sim::TwinConfig;

/// Where frames come from.
#[derive(Debug, Clone)]
pub enum SourceSpec {
    /// The embedded physics twin, paced at `speed`.
    Twin {
        /// The twin's machine, program and rate.
        config: Box<TwinConfig>,
        /// Simulated seconds per wall-clock second.
        speed: ReplaySpeed,
    },
    /// A recording replayed as if live.
    Replay {
        /// The CSV v1 file, or the pieces of one recording in the order they were recorded.
        pieces: Vec<PathBuf>,
        /// Speed, pause and staleness.
        options: ReplayOptions,
    },
    /// A controller over Modbus RTU.
    Serial(ModbusConfig),
}

/// Everything the session needs.
#[derive(Debug, Clone)]
pub struct SessionConfig {
    /// The source.
    pub source: SourceSpec,
    /// Record every frame into this directory (a new timestamped file per start); `None`
    /// starts with the recorder off.
    pub record_dir: Option<PathBuf>,
    /// The users file (TOML with Argon2 hashes); read at every approval, so users added with
    /// `servosight compensate set-user` count at once.
    pub users_path: PathBuf,
    /// The compensation audit log.
    pub audit_path: PathBuf,
    /// Compensation write limits.
    pub limits: CompensationLimits,
    /// The calibrated machine profile: its estimators run on every frame and their outputs
    /// (`est.*` columns) follow the link's columns. `None` shows the servo signals only.
    pub profile: Option<MachineProfile>,
    /// Where warm-up reports (`warmup/`) and friction-fingerprint baselines (`baselines/`)
    /// are kept.
    pub data_dir: PathBuf,
}

/// The file a feed axis's healthy-machine friction fingerprint is kept in (the same JSON as
/// `servosight fingerprint --save-baseline` writes, so either can make it).
pub fn baseline_path(data_dir: &std::path::Path, axis: AxisId) -> PathBuf {
    data_dir
        .join("baselines")
        .join(format!("{axis}-fingerprint.json"))
}

/// The file the estimators' state is kept in between sessions on this kind of source
/// ([`crate::estimators::state`]), and the clock its frames are on: one file per kind, so a
/// session on a replay does not overwrite what a session on the machine left. `None` for the
/// embedded twin, whose program starts every session on a machine at rest at time zero: no
/// state of an earlier session is its.
pub fn estimator_state_path(
    data_dir: &std::path::Path,
    source: &SourceSpec,
) -> Option<(PathBuf, StateClock)> {
    let (kind, clock) = match source {
        SourceSpec::Twin { .. } => return None,
        SourceSpec::Replay { .. } => ("replay", StateClock::Continues),
        SourceSpec::Serial(_) => ("controller", StateClock::Restarts),
    };
    Some((data_dir.join(format!("estimator-state-{kind}.json")), clock))
}

/// How a source's time is paced: a replay and the twin can be paused and sped up; a
/// controller runs at its own pace (`None`).
pub fn pace_of(source: &SourceSpec) -> Option<Pace> {
    match source {
        SourceSpec::Twin { speed, .. } => Some(Pace {
            paused: false,
            speed: *speed,
        }),
        SourceSpec::Replay { options, .. } => Some(Pace {
            paused: options.paused,
            speed: options.speed,
        }),
        SourceSpec::Serial(_) => None,
    }
}

/// A replay's or the twin's pace, as last asked for.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pace {
    /// Paused.
    pub paused: bool,
    /// Seconds of machine time per second of wall clock.
    pub speed: ReplaySpeed,
}

/// How a source's time runs from one session to the next.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StateClock {
    /// A recording's time: a replay of its continuation goes on from it.
    Continues,
    /// A live link's time, which counts from the link's start: the wall clock tells the time
    /// between sessions.
    Restarts,
}

/// How often the session saves the estimators' state (and once more when it ends): a crash
/// loses at most this much of it.
const SAVE_STATE_EVERY: Duration = Duration::from_secs(60);

/// Why a session could not start.
#[derive(Debug, thiserror::Error)]
pub enum SessionError {
    /// The link could not be started (missing replay file, bad twin settings, …).
    #[error(transparent)]
    Link(#[from] LinkError),
    /// The worker thread could not be started.
    #[error("cannot start the session thread: {0}")]
    Thread(std::io::Error),
    /// The worker is gone, or its command queue is full.
    #[error("the session is not taking commands: {0}")]
    NotTaking(&'static str),
}

/// What the UI asks the session to do.
#[derive(Debug)]
pub enum SessionCommand {
    /// Read the controller's compensation table, the audit log and the users file again.
    Refresh,
    /// Check the approver's credential and, if it holds, push the request (bounded, written,
    /// read back, verified, audited).
    ApproveAndApply {
        /// The operator's request.
        request: Request,
        /// Who approves.
        approver: String,
        /// Their password (kept only for the check).
        password: String,
    },
    /// Record a refusal of the request in the audit log (the approver cancelled it).
    Withdraw {
        /// The request.
        request: Request,
        /// Why.
        reason: String,
    },
    /// Switch the recorder on (new file) or off.
    SetRecording(bool),
    /// Save the estimators' state now and say so on `done` (a session about to take up the
    /// same state file waits for it).
    SaveStateNow(std::sync::mpsc::SyncSender<()>),
    /// Pause (true) or resume a replay or the twin (a controller runs on regardless).
    SetPaused(bool),
    /// Change a replay's or the twin's speed.
    SetSpeed(ReplaySpeed),
    /// The operator measured the tool: spindle elongation counts from zero again.
    ResetToolCalibration,
    /// Keep this fingerprint as its axis's healthy-machine baseline.
    SaveBaseline(Box<FrictionFingerprint>),
    /// Write the signed-off warm-up report (JSON and text) into the data directory.
    SaveWarmupReport(Box<WarmupReport>),
}

/// Frames the session forwards to the UI in one message.
#[derive(Debug, Clone)]
pub struct FrameBatch {
    /// Rows in the link's schema order, `time_s` first.
    pub rows: Vec<Vec<f64>>,
    /// When the session received the first of them (for the sample-to-screen latency).
    pub received_at: Instant,
    /// Frames the UI never got because its queue was full (they are on disk).
    pub dropped_before: u64,
}

/// What the session tells the UI.
#[derive(Debug)]
pub enum SessionUpdate {
    /// New frames.
    Frames(FrameBatch),
    /// The link's state now.
    Link(LinkSnapshot),
    /// The recorder's state now.
    Recorder(RecorderSnapshot),
    /// The controller's compensation table, or why it cannot be read.
    Compensation(Result<CompensationValues, String>),
    /// The audit log, or why it cannot be read.
    Audit(Result<Vec<AuditEntry>, String>),
    /// The users file's names and roles, or why it cannot be read.
    Users(Result<Vec<(String, Role)>, String>),
    /// The approver's credential was refused; nothing was written.
    ApprovalRefused {
        /// The request.
        request_id: String,
        /// Why.
        reason: String,
    },
    /// The push ended (verified or not).
    PushFinished(PushResult),
    /// Something worth an entry in the event list.
    Event(Event),
    /// The friction-fingerprint baselines per feed axis (`None`: none saved yet).
    Baselines(Vec<(AxisId, Result<Option<FrictionFingerprint>, String>)>),
    /// Where each spindle's elongation counts from (re-sent every tick, like the link's state;
    /// `None` for a tool measurement not yet counted).
    ElongationOrigins(Vec<(AxisId, Option<ElongationOrigin>)>),
    /// The warm-up report was written (or why not).
    WarmupReportSaved(Result<SavedReport, String>),
}

/// The UI's handle on the session worker.
pub struct Session {
    schema: Schema,
    source: String,
    /// What the session was started with (the HMI opens another source on its settings).
    config: SessionConfig,
    /// Why its profile's estimators do not run on this link (`None`: they run, or there is
    /// no profile).
    estimators_off: Option<String>,
    commands: mpsc::Sender<SessionCommand>,
    updates: mpsc::Receiver<SessionUpdate>,
    thread: Option<std::thread::JoinHandle<()>>,
    /// The first file its recorder opened, set by the worker as it opens it.
    first_recording: Arc<OnceLock<PathBuf>>,
}

/// Messages queued from the session to the UI before it has to hold frames back.
const UPDATE_CHANNEL_CAPACITY: usize = 8192;
/// What a replay leaves out of the recording it starts: the pieces the recorder continued its
/// first file in that lie beside it and were not given, so that an operator who opened one
/// hour of a shift knows the rest is there (`None` when none is left out, or the directory
/// cannot be listed: the replay itself is not affected).
fn pieces_left_out(pieces: &[PathBuf]) -> Option<String> {
    let first = pieces.first()?;
    let left_out = crate::signal::pieces_left_out(pieces).ok()?;
    (!left_out.is_empty()).then(|| {
        format!(
            "replay: the recorder continued {} in {} beside it that this replay leaves out: \
             give them after it (in the order recorded), or --with-later-pieces, to replay \
             the whole recording",
            first.display(),
            crate::signal::RecordingPieces::short_name(&left_out)
        )
    })
}

/// How often the link and recorder state are published and the recorder is flushed.
const TICK: Duration = Duration::from_millis(100);
/// Frames held for a UI that is not draining before the oldest are let go (they are on disk).
const MAX_HELD_FRAMES: usize = 1 << 20;

impl Session {
    /// Starts the link and the worker thread.
    pub fn start(config: SessionConfig) -> Result<Session, SessionError> {
        let link = match &config.source {
            SourceSpec::Twin { config, speed } => {
                ControllerLink::twin((**config).clone(), *speed, Duration::from_secs(1))?
            }
            SourceSpec::Replay { pieces, options } => ControllerLink::replay(pieces, *options)?,
            SourceSpec::Serial(modbus) => ControllerLink::modbus(modbus.clone())?,
        };
        let source = link.status().source;
        // The estimators run here, beside the recorder (which keeps the link's own columns);
        // a profile that does not fit this link is reported, and the servo signals still flow.
        let (pipeline, pipeline_error) = match &config.profile {
            None => (None, None),
            Some(profile) => match EstimatorPipeline::new(profile, link.schema()) {
                Ok(pipeline) => (Some(pipeline), None),
                Err(error) => (
                    None,
                    Some(format!("estimators off ({}): {error}", profile.name)),
                ),
            },
        };
        let state_file = estimator_state_path(&config.data_dir, &config.source);
        let (pending_state, state_note) = match (&pipeline, &config.profile, &state_file) {
            (Some(_), Some(profile), Some((path, _))) => {
                take_up_saved_state(path, profile, link.schema())
            }
            _ => (None, None),
        };
        let mut names = link.schema().names().to_vec();
        if let Some(pipeline) = &pipeline {
            names.extend(pipeline.outputs().into_iter().map(|o| o.column));
        }
        let schema = Schema::new(names, &source).map_err(LinkError::from)?;
        let (command_tx, command_rx) = mpsc::channel(64);
        let (update_tx, update_rx) = mpsc::channel(UPDATE_CHANNEL_CAPACITY);
        let runtime = tokio::runtime::Builder::new_current_thread()
            .enable_time()
            .build()
            .map_err(SessionError::Thread)?;
        let first_recording = Arc::new(OnceLock::new());
        let mut worker = Worker {
            link,
            recorder: None,
            first_recording: Arc::clone(&first_recording),
            recorder_snapshot: RecorderSnapshot::off(),
            record_dir: config.record_dir.clone(),
            audit: None,
            users_path: config.users_path.clone(),
            audit_path: config.audit_path.clone(),
            limits: config.limits,
            updates: update_tx,
            held: None,
            dropped_frames: 0,
            last_state: None,
            compensation_read_once: false,
            pipeline,
            estimates: Vec::new(),
            data_dir: config.data_dir.clone(),
            feed_axes: config
                .profile
                .iter()
                .flat_map(|p| p.axes.iter())
                .filter(|(_, a)| a.kind == crate::profile::AxisKind::Feed)
                .map(|(id, _)| *id)
                .collect(),
            last_time_s: None,
            notes_said: 0,
            pending_state,
            state_file,
            last_row: Vec::new(),
            last_row_unix_s: None,
            state_saved_at: Instant::now(),
            state_save_failed: false,
        };
        if let Some(error) = &pipeline_error {
            worker.event(EventKind::Condition, Severity::Warning, error.clone());
        }
        if let Some(note) = state_note {
            worker.event(EventKind::Condition, Severity::Warning, note);
        }
        if let SourceSpec::Replay { pieces, .. } = &config.source
            && let Some(note) = pieces_left_out(pieces)
        {
            worker.event(EventKind::Condition, Severity::Warning, note);
        }
        // What the estimators cannot do on this link (e.g. no abnormality score without the
        // depth of cut) is said once, so a missing reading is never a mystery.
        worker.say_new_notes();
        let thread = std::thread::Builder::new()
            .name("servosight-session".into())
            .spawn(move || worker.run(&runtime, command_rx))
            .map_err(SessionError::Thread)?;
        Ok(Session {
            schema,
            source,
            config,
            estimators_off: pipeline_error,
            commands: command_tx,
            updates: update_rx,
            thread: Some(thread),
            first_recording,
        })
    }

    /// The link's columns, `time_s` first.
    pub fn schema(&self) -> &Schema {
        &self.schema
    }

    /// What the link reads from.
    pub fn source(&self) -> &str {
        &self.source
    }

    /// The machine profile the session's estimators run with.
    pub fn profile(&self) -> Option<&MachineProfile> {
        self.config.profile.as_ref()
    }

    /// What the session was started with.
    pub fn config(&self) -> &SessionConfig {
        &self.config
    }

    /// What runs on the frames: "the estimators of profile `…`", or why none do.
    pub fn estimators(&self) -> String {
        match (&self.config.profile, &self.estimators_off) {
            (None, _) => "no estimators (no machine profile)".into(),
            // `why` says "estimators off (profile): …" already.
            (Some(_), Some(why)) => why.clone(),
            (Some(profile), None) => format!("the estimators of profile `{}`", profile.name),
        }
    }

    /// Queues a command; never waits.
    pub fn send(&self, command: SessionCommand) -> Result<(), SessionError> {
        self.commands.try_send(command).map_err(|e| match e {
            mpsc::error::TrySendError::Full(_) => SessionError::NotTaking("its queue is full"),
            mpsc::error::TrySendError::Closed(_) => SessionError::NotTaking("it has ended"),
        })
    }

    /// The next update if one is waiting; never waits.
    pub fn try_recv(&mut self) -> Option<SessionUpdate> {
        self.updates.try_recv().ok()
    }

    /// Ends the session as dropping it does (its recorder file finished) and says which file
    /// its recorder opened first, if it opened one: known even when the session ends before
    /// it reported its recorder.
    pub fn end(self) -> Option<PathBuf> {
        let first = Arc::clone(&self.first_recording);
        drop(self);
        first.get().cloned()
    }
}

impl Drop for Session {
    fn drop(&mut self) {
        // Closing both channels ends the worker's loop; it finishes the recorder file and
        // drops the link (which joins the link thread).
        self.updates.close();
        let (closed, _) = mpsc::channel(1);
        self.commands = closed;
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

/// What woke the worker.
enum Wake {
    Frame(Option<crate::link::Frame>),
    Command(Option<SessionCommand>),
    Tick,
}

struct Worker {
    link: ControllerLink,
    recorder: Option<Recorder>,
    /// Shared with the [`Session`] ([`Session::end`]).
    first_recording: Arc<OnceLock<PathBuf>>,
    recorder_snapshot: RecorderSnapshot,
    record_dir: Option<PathBuf>,
    audit: Option<AuditLog>,
    users_path: PathBuf,
    audit_path: PathBuf,
    limits: CompensationLimits,
    updates: mpsc::Sender<SessionUpdate>,
    /// Frames the UI has not taken yet because its queue was full.
    held: Option<FrameBatch>,
    dropped_frames: u64,
    last_state: Option<ConnectionState>,
    compensation_read_once: bool,
    /// The estimators, when a profile was given and fits the link.
    pipeline: Option<EstimatorPipeline>,
    /// Scratch row of estimator outputs.
    estimates: Vec<f64>,
    /// Reports and baselines live here.
    data_dir: PathBuf,
    /// The profile's feed axes (each may have a fingerprint baseline).
    feed_axes: Vec<AxisId>,
    /// Machine time of the newest frame.
    last_time_s: Option<f64>,
    /// How many of the pipeline's notes have been said as events: it adds one when a frame
    /// shows something (a machine already warm at the first frame).
    notes_said: usize,
    /// A pipeline that took up the state the last session saved, and that state: it replaces
    /// `pipeline` if the first frame shows the machine where the state left it.
    pending_state: Option<(EstimatorPipeline, SavedState)>,
    /// Where the estimators' state is saved, and how the source's clock runs between sessions
    /// (`None`: not saved).
    state_file: Option<(PathBuf, StateClock)>,
    /// The newest frame, in the link's columns (what a saved state is checked by), and when it
    /// arrived (wall clock, s since 1970).
    last_row: Vec<f64>,
    last_row_unix_s: Option<f64>,
    /// When the state was last saved.
    state_saved_at: Instant,
    /// Saving failed and was said (said once, until a save succeeds again).
    state_save_failed: bool,
}

impl Worker {
    fn run(
        mut self,
        runtime: &tokio::runtime::Runtime,
        mut commands: mpsc::Receiver<SessionCommand>,
    ) {
        if self.record_dir.is_some() {
            self.start_recording();
        }
        self.open_audit();
        self.send_users();
        self.send_baselines();
        let mut source_open = true;
        let mut next_tick = tokio::time::Instant::now();
        loop {
            let link = &mut self.link;
            let wake = runtime.block_on(async {
                tokio::select! {
                    biased;
                    command = commands.recv() => Wake::Command(command),
                    frame = link.next_frame(), if source_open => Wake::Frame(frame),
                    _ = tokio::time::sleep_until(next_tick) => Wake::Tick,
                }
            });
            match wake {
                Wake::Command(None) => break,
                Wake::Command(Some(command)) => self.handle(command),
                Wake::Frame(None) => {
                    source_open = false;
                    self.publish_status();
                }
                Wake::Frame(Some(first)) => {
                    let mut frames = vec![first];
                    // Take what else is waiting, so a burst becomes one message.
                    while frames.len() < 4096 {
                        match self.link.try_next_frame() {
                            Some(frame) => frames.push(frame),
                            None => break,
                        }
                    }
                    self.take_frames(frames);
                }
                Wake::Tick => {}
            }
            // Also after frames: a source that always has a frame waiting (a replay as fast as
            // possible) would otherwise never let the tick win the select.
            if tokio::time::Instant::now() >= next_tick {
                next_tick = tokio::time::Instant::now() + TICK;
                self.publish_status();
                if self.state_saved_at.elapsed() >= SAVE_STATE_EVERY {
                    self.save_state();
                }
            }
            if self.updates.is_closed() {
                break;
            }
        }
        self.save_state();
        if let Some(recorder) = self.recorder.take() {
            let _ = recorder.finish();
        }
    }

    /// Takes up the last session's state if the first frame shows the machine where it was
    /// left, and says either way.
    fn resume_or_start_afresh(&mut self, first: &[f64]) {
        let Some((restored, saved)) = self.pending_state.take() else {
            return;
        };
        let clock = match self.state_file.as_ref().map(|(_, clock)| *clock) {
            Some(StateClock::Restarts) => {
                unix_now_s().map(|now_unix_s| Clock::Restarted { now_unix_s })
            }
            _ => Some(Clock::Continued),
        };
        let checked = clock
            .ok_or(StateError::NoWallClock)
            .and_then(|clock| saved.check_resume(self.link.schema(), first, clock));
        match checked {
            Ok(resume) => {
                let mut restored = restored;
                restored.carry_on(&resume);
                let gap_s = resume.gap_s;
                self.pipeline = Some(restored);
                self.event(
                    EventKind::Condition,
                    Severity::Normal,
                    format!(
                        "estimators: carried on from the state the last session saved, {gap_s:.0} s \
                         before this session's first frame (the inputs of that frame held over \
                         the break)"
                    ),
                );
            }
            Err(why) => self.event(
                EventKind::Condition,
                Severity::Warning,
                format!(
                    "estimators: started afresh, not from the state saved at machine time \
                     {:.1} s: {why}",
                    saved.time_s
                ),
            ),
        }
    }

    /// Writes the estimators' state after the newest frame (replacing the file whole, so a
    /// crash mid-write leaves the previous one); says a failure once.
    fn save_state(&mut self) {
        self.state_saved_at = Instant::now();
        let Some((path, _)) = &self.state_file else {
            return;
        };
        let Some(mut saved) = self
            .pipeline
            .as_mut()
            .and_then(|p| p.save_state(&self.last_row))
        else {
            return;
        };
        saved.frame_unix_s = self.last_row_unix_s;
        match write_state(path, &saved) {
            Ok(()) => self.state_save_failed = false,
            Err(error) if !self.state_save_failed => {
                self.state_save_failed = true;
                self.event(
                    EventKind::Condition,
                    Severity::Warning,
                    format!(
                        "estimators: their state cannot be saved ({error}); a restarted HMI \
                         will start them afresh"
                    ),
                );
            }
            Err(_) => {}
        }
    }

    fn send(&self, update: SessionUpdate) {
        // Status updates are re-sent every tick, so one lost to a full queue is replaced at
        // once; frames never go this way (see `forward`).
        let _ = self.updates.try_send(update);
    }

    fn event(&self, kind: EventKind, severity: Severity, message: impl Into<String>) {
        self.send(SessionUpdate::Event(Event::now(kind, severity, message)));
    }

    fn take_frames(&mut self, frames: Vec<crate::link::Frame>) {
        let received_at = Instant::now();
        if let Some(recorder) = self.recorder.as_mut() {
            let mut failure = None;
            for frame in &frames {
                if let Err(error) = recorder.record(frame) {
                    failure = Some(error.to_string());
                    break;
                }
            }
            if let Some(error) = failure {
                self.stop_recording(Some(error));
            }
        }
        let mut rows: Vec<Vec<f64>> = frames.into_iter().map(|f| f.row).collect();
        if let Some(first) = rows.first() {
            self.resume_or_start_afresh(first);
        }
        if let Some(last) = rows.last() {
            self.last_time_s = last.first().copied();
            self.last_row.clone_from(last);
            self.last_row_unix_s = unix_now_s();
        }
        if let Some(pipeline) = self.pipeline.as_mut() {
            for row in &mut rows {
                pipeline.update(row);
                pipeline.write_outputs(&mut self.estimates);
                row.extend_from_slice(&self.estimates);
            }
        }
        self.say_new_notes();
        self.forward(rows, received_at);
    }

    /// Says each of the pipeline's notes not said yet as a warning event, once.
    fn say_new_notes(&mut self) {
        let notes = self.pipeline.as_ref().map_or(&[][..], |p| p.notes());
        let count = notes.len();
        for note in notes.get(self.notes_said..).unwrap_or_default() {
            self.event(
                EventKind::Condition,
                Severity::Warning,
                format!("estimators: {note}"),
            );
        }
        self.notes_said = count;
    }

    /// Hands rows to the UI; when its queue is full they wait here (merged), and only beyond
    /// [`MAX_HELD_FRAMES`] are the oldest let go and counted.
    fn forward(&mut self, rows: Vec<Vec<f64>>, received_at: Instant) {
        let mut batch = match self.held.take() {
            Some(mut held) => {
                held.rows.extend(rows);
                held
            }
            None => FrameBatch {
                rows,
                received_at,
                dropped_before: 0,
            },
        };
        if batch.rows.len() > MAX_HELD_FRAMES {
            let excess = batch.rows.len() - MAX_HELD_FRAMES;
            batch.rows.drain(..excess);
            self.dropped_frames += excess as u64;
        }
        if batch.rows.is_empty() {
            return;
        }
        batch.dropped_before = std::mem::take(&mut self.dropped_frames);
        match self.updates.try_send(SessionUpdate::Frames(batch)) {
            Ok(()) => {}
            Err(mpsc::error::TrySendError::Full(SessionUpdate::Frames(batch)))
            | Err(mpsc::error::TrySendError::Closed(SessionUpdate::Frames(batch))) => {
                self.dropped_frames += batch.dropped_before;
                self.held = Some(batch);
            }
            Err(_) => {}
        }
    }

    fn publish_status(&mut self) {
        if self.held.is_some() {
            self.forward(Vec::new(), Instant::now());
        }
        let status = self.link.status();
        if self.last_state != Some(status.state) {
            let (severity, text) = match status.state {
                ConnectionState::Connected => (Severity::Normal, "connected".to_string()),
                ConnectionState::Stale => (
                    Severity::Warning,
                    "stale: no fresh sample within the staleness limit".to_string(),
                ),
                ConnectionState::Disconnected => (
                    Severity::Fault,
                    format!(
                        "disconnected{}",
                        status
                            .last_error
                            .as_ref()
                            .map(|e| format!(": {e}"))
                            .unwrap_or_default()
                    ),
                ),
            };
            self.event(
                EventKind::Link,
                severity,
                format!("{} {text}", status.source),
            );
            self.last_state = Some(status.state);
            if status.state == ConnectionState::Connected && !self.compensation_read_once {
                self.compensation_read_once = true;
                self.send_compensation();
            }
        }
        self.send(SessionUpdate::Link(LinkSnapshot::from_status(&status)));
        if let Some(pipeline) = &self.pipeline {
            self.send(SessionUpdate::ElongationOrigins(
                pipeline.elongation_origins(),
            ));
        }
        if let Some(recorder) = self.recorder.as_mut() {
            if let Err(error) = recorder.flush_if_due() {
                self.stop_recording(Some(error.to_string()));
            } else {
                let stats = recorder.stats();
                self.recorder_snapshot.rows = stats.rows;
                self.recorder_snapshot.files = stats.files;
                self.recorder_snapshot.frames_not_written = stats.frames_not_written;
                self.recorder_snapshot.path =
                    recorder.paths().last().map(|p| p.display().to_string());
            }
        }
        self.send(SessionUpdate::Recorder(self.recorder_snapshot.clone()));
    }

    fn start_recording(&mut self) {
        let Some(dir) = self.record_dir.clone() else {
            self.event(
                EventKind::Recorder,
                Severity::Warning,
                "this session has no recording directory (--record-dir; a recording opened \
                 from the Source window is not recorded again: it is on disk already)",
            );
            return;
        };
        if let Err(error) = std::fs::create_dir_all(&dir) {
            self.stop_recording(Some(format!("cannot create {}: {error}", dir.display())));
            return;
        }
        let stamp: String = compensation::audit::utc_now()
            .chars()
            .map(|c| if c == ':' || c == '.' { '-' } else { c })
            .collect();
        let path = dir.join(format!("recording-{stamp}.csv"));
        let mut config = RecorderConfig::new(&path);
        config.metadata = vec![("source".into(), self.link.status().source)];
        match Recorder::create(config, self.link.schema(), self.link.has_sequence()) {
            Ok(recorder) => {
                self.recorder = Some(recorder);
                let _ = self.first_recording.set(path.clone());
                self.recorder_snapshot = RecorderSnapshot {
                    state: RecorderState::Recording,
                    path: Some(path.display().to_string()),
                    rows: 0,
                    files: 1,
                    frames_not_written: 0,
                    error: None,
                };
                self.event(
                    EventKind::Recorder,
                    Severity::Normal,
                    format!("recording to {}", path.display()),
                );
            }
            Err(error) => self.stop_recording(Some(error.to_string())),
        }
    }

    fn stop_recording(&mut self, error: Option<String>) {
        if let Some(recorder) = self.recorder.take() {
            let stats = recorder.stats().clone();
            self.recorder_snapshot.rows = stats.rows;
            self.recorder_snapshot.frames_not_written = stats.frames_not_written;
            if let Err(finish_error) = recorder.finish()
                && error.is_none()
            {
                self.recorder_snapshot.error = Some(finish_error.to_string());
            }
        }
        match error {
            Some(error) => {
                self.recorder_snapshot.state = RecorderState::Failed;
                self.event(
                    EventKind::Recorder,
                    Severity::Fault,
                    format!("recording stopped: {error}"),
                );
                self.recorder_snapshot.error = Some(error);
            }
            None => {
                self.recorder_snapshot.state = RecorderState::Off;
                self.event(EventKind::Recorder, Severity::Normal, "recording stopped");
            }
        }
        self.send(SessionUpdate::Recorder(self.recorder_snapshot.clone()));
    }

    fn open_audit(&mut self) {
        if let Some(parent) = self.audit_path.parent()
            && !parent.as_os_str().is_empty()
        {
            let _ = std::fs::create_dir_all(parent);
        }
        match AuditLog::open(&self.audit_path) {
            Ok(log) => {
                self.audit = Some(log);
                self.send_audit();
            }
            Err(error) => {
                self.send(SessionUpdate::Audit(Err(error.to_string())));
                self.event(
                    EventKind::Write,
                    Severity::Fault,
                    format!("audit log unusable, compensation writes are blocked: {error}"),
                );
            }
        }
    }

    fn send_audit(&self) {
        let entries = match &self.audit {
            Some(log) => log.entries().map_err(|e| e.to_string()),
            None => Err(format!("{} could not be opened", self.audit_path.display())),
        };
        self.send(SessionUpdate::Audit(entries));
    }

    fn send_users(&self) {
        let users = Credentials::load(&self.users_path)
            .map(|c| c.users.into_iter().map(|u| (u.name, u.role)).collect())
            .map_err(|e| e.to_string());
        self.send(SessionUpdate::Users(users));
    }

    fn send_compensation(&self) {
        let table = self
            .link
            .read_compensation()
            .wait()
            .map_err(|e| e.to_string());
        self.send(SessionUpdate::Compensation(table));
    }

    fn handle(&mut self, command: SessionCommand) {
        match command {
            SessionCommand::Refresh => {
                self.send_compensation();
                self.send_audit();
                self.send_users();
            }
            SessionCommand::SaveStateNow(done) => {
                self.save_state();
                let _ = done.try_send(());
            }
            // The link applies these at once (a controller's link ignores them); the UI shows
            // what it asked for.
            SessionCommand::SetPaused(paused) => self.link.set_paused(paused),
            SessionCommand::SetSpeed(speed) => self.link.set_speed(speed),
            SessionCommand::SetRecording(on) => {
                if on && self.recorder.is_none() {
                    self.start_recording();
                } else if !on && self.recorder.is_some() {
                    self.stop_recording(None);
                }
            }
            SessionCommand::Withdraw { request, reason } => {
                let controller = self.link.status().source;
                if let Some(audit) = self.audit.as_mut()
                    && let Err(error) =
                        compensation::record_refusal(audit, &request, None, &controller, &reason)
                {
                    self.event(EventKind::Write, Severity::Fault, error.to_string());
                }
                self.event(
                    EventKind::Write,
                    Severity::Normal,
                    format!("request {} withdrawn: {reason}", request.id()),
                );
                self.send_audit();
            }
            SessionCommand::ApproveAndApply {
                request,
                approver,
                password,
            } => {
                self.approve_and_apply(request, &approver, &password);
                self.send_compensation();
                self.send_audit();
            }
            SessionCommand::ResetToolCalibration => {
                // Before the first frame the pipeline may yet be replaced by the one that took
                // up the saved state: the measurement holds for either.
                if let Some((restored, _)) = self.pending_state.as_mut() {
                    restored.reset_tool_calibration();
                }
                if let Some(pipeline) = self.pipeline.as_mut() {
                    pipeline.reset_tool_calibration();
                    let origins = pipeline.elongation_origins();
                    self.send(SessionUpdate::ElongationOrigins(origins));
                    self.event(
                        EventKind::Condition,
                        Severity::Normal,
                        format!(
                            "tool measured: spindle elongation counts from zero at {} s",
                            crate::ui::vm::number(self.last_time_s, 1)
                        ),
                    );
                } else {
                    self.event(
                        EventKind::Condition,
                        Severity::Warning,
                        "no estimators run, so there is no elongation to reset",
                    );
                }
            }
            SessionCommand::SaveBaseline(fingerprint) => {
                let path = baseline_path(&self.data_dir, fingerprint.axis);
                let written = path
                    .parent()
                    .map_or(Ok(()), std::fs::create_dir_all)
                    .and_then(|()| {
                        let text = serde_json::to_string_pretty(&*fingerprint)
                            .map_err(std::io::Error::other)?;
                        std::fs::write(&path, text + "\n")
                    });
                match written {
                    Ok(()) => self.event(
                        EventKind::Condition,
                        Severity::Normal,
                        format!(
                            "{} friction fingerprint saved as the baseline {}",
                            fingerprint.axis,
                            path.display()
                        ),
                    ),
                    Err(error) => self.event(
                        EventKind::Condition,
                        Severity::Fault,
                        format!("cannot save the baseline {}: {error}", path.display()),
                    ),
                }
                self.send_baselines();
            }
            SessionCommand::SaveWarmupReport(report) => {
                let saved = save_warmup_report(&self.data_dir, &report);
                match &saved {
                    Ok(s) => self.event(
                        EventKind::Condition,
                        match report.verdict {
                            crate::ui::vm::warmup::StepStatus::Pass => Severity::Normal,
                            crate::ui::vm::warmup::StepStatus::Fail => Severity::Fault,
                            _ => Severity::Warning,
                        },
                        format!(
                            "warm-up checklist signed off by {}: {}; report {}",
                            report.signed_off_by, report.verdict_text, s.json_path
                        ),
                    ),
                    Err(error) => self.event(
                        EventKind::Condition,
                        Severity::Fault,
                        format!("the warm-up report was not saved: {error}"),
                    ),
                }
                self.send(SessionUpdate::WarmupReportSaved(saved));
            }
        }
    }

    fn send_baselines(&self) {
        let baselines = self
            .feed_axes
            .iter()
            .map(|&axis| {
                let path = baseline_path(&self.data_dir, axis);
                let loaded = match std::fs::read_to_string(&path) {
                    Ok(text) => serde_json::from_str::<FrictionFingerprint>(&text)
                        .map(Some)
                        .map_err(|e| format!("{}: {e}", path.display())),
                    Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
                    Err(e) => Err(format!("{}: {e}", path.display())),
                };
                (axis, loaded)
            })
            .collect();
        self.send(SessionUpdate::Baselines(baselines));
    }

    fn approve_and_apply(&mut self, request: Request, approver: &str, password: &str) {
        // The log is taken out for the push so that events can be sent meanwhile.
        if let Some(mut audit) = self.audit.take() {
            self.approve_and_apply_logged(&mut audit, request, approver, password);
            self.audit = Some(audit);
        } else {
            self.send(SessionUpdate::ApprovalRefused {
                request_id: request.id().to_string(),
                reason: format!(
                    "the audit log {} is not usable, so nothing may be written",
                    self.audit_path.display()
                ),
            });
        }
    }

    fn approve_and_apply_logged(
        &mut self,
        audit: &mut AuditLog,
        request: Request,
        approver: &str,
        password: &str,
    ) {
        let controller = self.link.status().source;
        let refused = |audit: &mut AuditLog, reason: String| {
            let recorded =
                compensation::record_refusal(audit, &request, Some(approver), &controller, &reason);
            match recorded {
                Ok(_) => reason,
                Err(error) => format!("{reason} (and the audit log failed: {error})"),
            }
        };
        let credentials = match Credentials::load(&self.users_path) {
            Ok(credentials) => credentials,
            Err(error) => {
                let reason = refused(audit, format!("cannot read the users file: {error}"));
                self.send(SessionUpdate::ApprovalRefused {
                    request_id: request.id().to_string(),
                    reason,
                });
                return;
            }
        };
        let approved = match request.approve(&credentials, approver, password) {
            Ok(approved) => approved,
            Err(error) => {
                let reason = refused(audit, error.to_string());
                self.event(
                    EventKind::Write,
                    Severity::Warning,
                    format!("request {}: approval refused: {reason}", request.id()),
                );
                self.send(SessionUpdate::ApprovalRefused {
                    request_id: request.id().to_string(),
                    reason,
                });
                return;
            }
        };
        self.event(
            EventKind::Write,
            Severity::Normal,
            format!(
                "request {} by {} approved by {approver}; writing",
                request.id(),
                request.operator()
            ),
        );
        let changes = request.proposal().changes.clone();
        let result = compensation::apply(&self.link, &self.limits, audit, approved);
        let read_back = self.link.read_compensation().wait().ok();
        let pushed = |old: Option<&CompensationValues>| -> Vec<PushedValue> {
            changes
                .iter()
                .map(|(id, requested)| PushedValue {
                    id: id.to_string(),
                    old_um: old.and_then(|o| o.get(id)),
                    requested_um: requested,
                    read_back_um: read_back.as_ref().and_then(|r| r.get(id)),
                })
                .collect()
        };
        let result = match result {
            Ok(report) => {
                let message = if report.steps == 0 {
                    "nothing to write: the controller already applies these values".to_string()
                } else {
                    format!(
                        "written in {} step(s), read back and verified",
                        report.steps
                    )
                };
                PushResult {
                    request_id: report.request_id.clone(),
                    action: request.proposal().action.clone(),
                    verified: true,
                    steps: report.steps,
                    values: pushed(Some(&report.old)),
                    message,
                }
            }
            Err(error) => PushResult {
                request_id: request.id().to_string(),
                action: request.proposal().action.clone(),
                verified: false,
                steps: 0,
                values: pushed(None),
                message: error.to_string(),
            },
        };
        self.event(
            EventKind::Write,
            if result.verified {
                Severity::Normal
            } else {
                Severity::Fault
            },
            format!("request {}: {}", result.request_id, result.message),
        );
        self.send(SessionUpdate::PushFinished(result));
    }
}

/// The state the last session saved at `path`, taken up by a pipeline of `profile` on
/// `schema`, or why not (`None` and nothing to say when there is no file).
fn take_up_saved_state(
    path: &std::path::Path,
    profile: &MachineProfile,
    schema: &Schema,
) -> (Option<(EstimatorPipeline, SavedState)>, Option<String>) {
    let text = match std::fs::read_to_string(path) {
        Ok(text) => text,
        Err(error) if error.kind() == std::io::ErrorKind::NotFound => return (None, None),
        Err(error) => {
            let note = format!("estimators: started afresh: {}: {error}", path.display());
            return (None, Some(note));
        }
    };
    let taken = SavedState::from_json(&text)
        .map_err(|e| e.to_string())
        .and_then(|saved| {
            let mut pipeline =
                EstimatorPipeline::new(profile, schema).map_err(|e| e.to_string())?;
            pipeline.restore_state(&saved).map_err(|e| e.to_string())?;
            Ok((pipeline, saved))
        });
    match taken {
        Ok(pending) => (Some(pending), None),
        Err(why) => (
            None,
            Some(format!(
                "estimators: started afresh, not from the state in {}: {why}",
                path.display()
            )),
        ),
    }
}

/// Writes a saved state to a file beside `path` (named for this process and this write, so
/// neither two HMIs on one data directory nor two sessions of one HMI write into each
/// other's), makes it durable, and renames it over `path`: a power cut leaves the old state
/// or the new one, never a part of either.
fn write_state(path: &std::path::Path, saved: &SavedState) -> Result<(), String> {
    let at = |e: std::io::Error| format!("{}: {e}", path.display());
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).map_err(at)?;
    }
    let text = serde_json::to_string(saved).map_err(|e| e.to_string())? + "\n";
    static WRITES: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let write = WRITES.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let partial = path.with_extension(format!("json.partial-{}-{write}", std::process::id()));
    let mut file = std::fs::File::create(&partial).map_err(at)?;
    std::io::Write::write_all(&mut file, text.as_bytes())
        .and_then(|()| file.sync_all())
        .map_err(at)?;
    std::fs::rename(&partial, path).map_err(at)
}

/// Writes a signed-off warm-up report as `warmup/warmup-<time>.json` and `.txt` in the data
/// directory; an existing file is never overwritten.
fn save_warmup_report(
    data_dir: &std::path::Path,
    report: &WarmupReport,
) -> Result<SavedReport, String> {
    let dir = data_dir.join("warmup");
    std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let stamp: String = report
        .signed_utc
        .chars()
        .map(|c| if c == ':' || c == '.' { '-' } else { c })
        .collect();
    let json_path = dir.join(format!("warmup-{stamp}.json"));
    let text_path = dir.join(format!("warmup-{stamp}.txt"));
    let json = serde_json::to_string_pretty(report).map_err(|e| e.to_string())? + "\n";
    for (path, text) in [(&json_path, json), (&text_path, report.to_text())] {
        let mut file = std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(path)
            .map_err(|e| format!("{}: {e}", path.display()))?;
        std::io::Write::write_all(&mut file, text.as_bytes())
            .and_then(|()| file.sync_all())
            .map_err(|e| format!("{}: {e}", path.display()))?;
    }
    Ok(SavedReport {
        json_path: json_path.display().to_string(),
        text_path: text_path.display().to_string(),
        operator: report.signed_off_by.clone(),
        time_utc: report.signed_utc.clone(),
    })
}
