//! The HMI's state: plain data that the session worker's updates and the operator's commands
//! change, and that the view models in [`super::vm`] read. Nothing here draws or does I/O.

use std::collections::VecDeque;

use serde::Serialize;

use crate::compensation::{AuditEntry, CompensationLimits, CompensationValues, Request, Role};
use crate::link::ConnectionState;
use crate::signal::{AxisId, Channel, Quantity};

/// A warning and a fault level of one reading (above `warning`: warning; above `fault`: fault).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, serde::Deserialize)]
pub struct Threshold {
    /// Warning level.
    pub warning: f64,
    /// Fault level.
    pub fault: f64,
}

/// The limits the Overview judges live servo readings against.
///
/// Until the machine profile (with its per-axis limits) is part of the crate, these are
/// conservative defaults for servo motors with class F insulation (155 °C): drives commonly
/// warn around 100 °C winding temperature and trip near 140 °C.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, serde::Deserialize)]
pub struct StatusThresholds {
    /// Stator winding temperature, °C.
    pub stator_temp_c: Threshold,
}

impl Default for StatusThresholds {
    fn default() -> Self {
        StatusThresholds {
            stator_temp_c: Threshold {
                warning: 100.0,
                fault: 130.0,
            },
        }
    }
}

/// The link as the HMI shows it (a [`crate::link::LinkStatus`] with times made relative, so
/// that snapshots of it are plain data).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LinkSnapshot {
    /// What the link reads from.
    pub source: String,
    /// Connected, stale or disconnected.
    pub state: ConnectionState,
    /// Seconds in that state.
    pub in_state_s: f64,
    /// Seconds since the last fresh frame.
    pub last_frame_age_s: Option<f64>,
    /// The most recent error.
    pub last_error: Option<String>,
    /// Frames delivered.
    pub frames: u64,
    /// Samples the controller published that never arrived.
    pub lost_samples: u64,
    /// Requests without a reply in time.
    pub timeouts: u64,
    /// Replies with a bad CRC.
    pub crc_errors: u64,
    /// Times the line was reopened.
    pub reconnects: u64,
}

impl LinkSnapshot {
    /// A link's status as it is now.
    pub fn from_status(status: &crate::link::LinkStatus) -> LinkSnapshot {
        let in_state_s = std::time::SystemTime::now()
            .duration_since(status.since)
            .map_or(0.0, |d| d.as_secs_f64());
        LinkSnapshot {
            source: status.source.clone(),
            state: status.state,
            in_state_s,
            last_frame_age_s: status.last_frame_age_s,
            last_error: status.last_error.clone(),
            frames: status.stats.frames,
            lost_samples: status.stats.lost_samples,
            timeouts: status.stats.timeouts,
            crc_errors: status.stats.crc_errors,
            reconnects: status.stats.reconnects,
        }
    }

    /// Before the session has reported anything.
    pub fn starting(source: &str) -> LinkSnapshot {
        LinkSnapshot {
            source: source.to_string(),
            state: ConnectionState::Disconnected,
            in_state_s: 0.0,
            last_frame_age_s: None,
            last_error: None,
            frames: 0,
            lost_samples: 0,
            timeouts: 0,
            crc_errors: 0,
            reconnects: 0,
        }
    }
}

/// Whether frames are being written to disk.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum RecorderState {
    /// Not recording (switched off).
    Off,
    /// Every frame goes to disk.
    Recording,
    /// Recording stopped on an error.
    Failed,
}

/// The recorder as the HMI shows it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RecorderSnapshot {
    /// Off, recording or failed.
    pub state: RecorderState,
    /// The file being written (the newest part).
    pub path: Option<String>,
    /// Rows written over all parts.
    pub rows: u64,
    /// Parts written.
    pub files: u64,
    /// Frames that could not be written.
    pub frames_not_written: u64,
    /// Why recording failed.
    pub error: Option<String>,
}

impl RecorderSnapshot {
    /// Not recording.
    pub fn off() -> RecorderSnapshot {
        RecorderSnapshot {
            state: RecorderState::Off,
            path: None,
            rows: 0,
            files: 0,
            frames_not_written: 0,
            error: None,
        }
    }
}

/// The newest frame, with the link's column names.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct LatestValues {
    /// Column names, `time_s` first.
    pub names: Vec<String>,
    /// The newest row, in `names` order; empty before the first frame.
    pub row: Vec<f64>,
}

impl LatestValues {
    /// The newest value of a column.
    pub fn get(&self, name: &str) -> Option<f64> {
        let i = self.names.iter().position(|n| n == name)?;
        self.row.get(i).copied()
    }

    /// The newest value of a servo quantity.
    pub fn servo(&self, axis: AxisId, quantity: Quantity) -> Option<f64> {
        self.get(&crate::signal::axis_column(axis, quantity))
    }

    /// Machine time of the newest frame.
    pub fn time_s(&self) -> Option<f64> {
        self.row.first().copied()
    }

    /// The axes whose servo columns the link carries, in the format's order.
    pub fn axes(&self) -> Vec<AxisId> {
        let mut axes: Vec<AxisId> = self
            .names
            .iter()
            .filter_map(|n| match Channel::parse(n) {
                Channel::Servo { axis, .. } => Some(axis),
                _ => None,
            })
            .collect();
        axes.sort();
        axes.dedup();
        axes
    }
}

/// How bad something is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Severity {
    /// Everything within limits; information.
    Normal,
    /// Attention needed.
    Warning,
    /// Stop and act.
    Fault,
}

/// What an event is about (the Events panel filters by this).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum EventKind {
    /// The link changed state or reported an error.
    Link,
    /// A reading crossed a threshold (or came back).
    Condition,
    /// A compensation request, approval, refusal, write or rollback.
    Write,
    /// The recorder started, stopped or failed.
    Recorder,
    /// A background job (model fit, sim-vs-real analysis, warm-up analysis) started,
    /// finished, failed or was cancelled.
    Job,
}

impl EventKind {
    /// Every kind, in the order the filter shows them.
    pub const ALL: [EventKind; 5] = [
        EventKind::Link,
        EventKind::Condition,
        EventKind::Write,
        EventKind::Recorder,
        EventKind::Job,
    ];

    /// The name shown in the filter.
    pub fn label(self) -> &'static str {
        match self {
            EventKind::Link => "link",
            EventKind::Condition => "condition",
            EventKind::Write => "writes",
            EventKind::Recorder => "recorder",
            EventKind::Job => "jobs",
        }
    }
}

/// One entry of the event list.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Event {
    /// When, UTC (`YYYY-MM-DDTHH:MM:SS.mmmZ`).
    pub time_utc: String,
    /// What it is about.
    pub kind: EventKind,
    /// How bad.
    pub severity: Severity,
    /// What happened, in words.
    pub message: String,
}

impl Event {
    /// An event stamped now.
    pub fn now(kind: EventKind, severity: Severity, message: impl Into<String>) -> Event {
        Event {
            time_utc: crate::compensation::audit::utc_now(),
            kind,
            severity,
            message: message.into(),
        }
    }
}

/// The most recent events (oldest forgotten beyond [`EventLog::CAPACITY`]).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct EventLog {
    entries: VecDeque<Event>,
    forgotten: u64,
}

impl EventLog {
    /// Events kept.
    pub const CAPACITY: usize = 10_000;

    /// Adds an event.
    pub fn push(&mut self, event: Event) {
        if self.entries.len() == Self::CAPACITY {
            self.entries.pop_front();
            self.forgotten += 1;
        }
        self.entries.push_back(event);
    }

    /// Events, oldest first.
    pub fn iter(&self) -> impl DoubleEndedIterator<Item = &Event> {
        self.entries.iter()
    }

    /// Events kept.
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    /// True when there is no event.
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    /// Events dropped because the log was full.
    pub fn forgotten(&self) -> u64 {
        self.forgotten
    }
}

/// Where the compensation push stands.
#[derive(Debug, Clone, PartialEq)]
pub enum PushFlow {
    /// No request pending.
    Idle,
    /// An operator requested a push; an approver must give their credential.
    AwaitingApproval {
        /// The request.
        request: Request,
        /// Why the last approval attempt was refused.
        refusal: Option<String>,
    },
    /// Approved; the session is checking the credential, writing and reading back.
    Writing {
        /// The request.
        request: Request,
        /// Who approves.
        approver: String,
    },
    /// The push ended (applied and verified, or stopped).
    Finished(PushResult),
}

/// How a push ended.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PushResult {
    /// The request id.
    pub request_id: String,
    /// `adjust` or `rollback of …`.
    pub action: String,
    /// True when every step was written, read back and verified.
    pub verified: bool,
    /// Steps written.
    pub steps: u32,
    /// Per changed value: before, asked for, read back.
    pub values: Vec<PushedValue>,
    /// What happened, in words.
    pub message: String,
}

/// One value of a push.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PushedValue {
    /// `backlash.X`, `thermal_offset.S`, ….
    pub id: String,
    /// Before the push, µm.
    pub old_um: Option<f64>,
    /// Asked for, µm.
    pub requested_um: f64,
    /// What the controller reports applying after the push, µm.
    pub read_back_um: Option<f64>,
}

/// Everything the Compensation panel shows.
#[derive(Debug, Clone, PartialEq)]
pub struct CompensationState {
    /// The table the controller applies now (as last read).
    pub controller: Option<CompensationValues>,
    /// Why the table could not be read (a replay has no controller, the line is down).
    pub controller_error: Option<String>,
    /// The proposal being put together: changes, why and evidence.
    pub draft_changes: CompensationValues,
    /// Where the push stands.
    pub flow: PushFlow,
    /// The audit log, oldest first.
    pub audit: Vec<AuditEntry>,
    /// Why the audit log could not be read.
    pub audit_error: Option<String>,
    /// Users and roles in the users file.
    pub users: Vec<(String, Role)>,
    /// Why the users file could not be read.
    pub users_error: Option<String>,
    /// The users file.
    pub users_path: String,
    /// The audit log file.
    pub audit_path: String,
    /// The write limits.
    pub limits: CompensationLimits,
    /// A problem with the last thing the operator tried (an invalid value, no operator name).
    pub notice: Option<String>,
}

impl CompensationState {
    /// Nothing read yet.
    pub fn new(users_path: String, audit_path: String, limits: CompensationLimits) -> Self {
        CompensationState {
            controller: None,
            controller_error: None,
            draft_changes: CompensationValues::new(),
            flow: PushFlow::Idle,
            audit: Vec::new(),
            audit_error: None,
            users: Vec::new(),
            users_error: None,
            users_path,
            audit_path,
            limits,
            notice: None,
        }
    }
}

/// Progress of a background job.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct JobProgress {
    /// What it is doing now.
    pub stage: String,
    /// 0–1, when known.
    pub fraction: Option<f32>,
}

/// The Model lab's state: the running fit, its last result, and the sim-vs-real analysis.
#[derive(Debug, Clone, Default)]
pub struct ModelLabState {
    /// Progress of the running fit.
    pub running: Option<JobProgress>,
    /// The last fit.
    pub result: Option<super::jobs::FitOutcome>,
    /// Why the last fit failed or stopped.
    pub error: Option<String>,
    /// The sim-vs-real discrepancy analysis.
    pub discrepancy: DiscrepancyState,
}

/// The Model lab's sim-vs-real part.
#[derive(Debug, Clone, Default)]
pub struct DiscrepancyState {
    /// Progress of the running analysis.
    pub running: Option<JobProgress>,
    /// The last analysis.
    pub result: Option<super::sim_vs_real::DiscrepancyOutcome>,
    /// Why the last analysis failed or stopped (the library's message).
    pub error: Option<String>,
    /// The columns the chosen files share, once their headers were read.
    pub columns: Option<super::sim_vs_real::SharedColumns>,
    /// Why the headers could not be read.
    pub columns_error: Option<String>,
    /// How the last PNG export of the result went (or how far it is).
    pub png_note: Option<String>,
    /// How the last save of the result's report went (or that it is being written).
    pub report_note: Option<String>,
}

/// A warm-up report the operator signed off, as saved.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SavedReport {
    /// The JSON report.
    pub json_path: String,
    /// The same report as readable text.
    pub text_path: String,
    /// Who signed it off.
    pub operator: String,
    /// When, UTC.
    pub time_utc: String,
}

/// The warm-up checklist's state (the steps themselves are judged in
/// [`super::vm::warmup`] from this and the live values).
#[derive(Debug, Clone, Default)]
pub struct WarmupState {
    /// Machine time from which the analyses take their samples (the checklist's start).
    pub started_at_s: Option<f64>,
    /// Progress of the running analysis.
    pub running: Option<JobProgress>,
    /// The last analysis of the warm-up moves.
    pub analysis: Option<super::analysis::WarmupAnalysis>,
    /// Why the last analysis could not run.
    pub analysis_error: Option<String>,
    /// Healthy-machine fingerprints per feed axis, from the data directory.
    pub baselines:
        std::collections::BTreeMap<AxisId, crate::estimators::fingerprint::FrictionFingerprint>,
    /// A problem reading or saving a baseline.
    pub baseline_note: Option<String>,
    /// The report, once signed off and saved.
    pub signed: Option<SavedReport>,
    /// Sign-off sent to the session, waiting for the file to be written.
    pub saving: bool,
    /// Why the last sign-off could not be saved, or what is missing for it.
    pub notice: Option<String>,
}

/// The depth-of-cut panel's state.
#[derive(Debug, Clone, Default)]
pub struct DepthState {
    /// Progress of the running recommendation.
    pub running: Option<JobProgress>,
    /// The last recommendation (or why there is none yet).
    pub outcome: Option<super::analysis::DepthOutcome>,
    /// Why the last recommendation failed.
    pub error: Option<String>,
    /// Machine time of the newest sample the last recommendation saw.
    pub computed_at_s: Option<f64>,
}

/// Everything the panels show, in one place. The session's updates and the operator's
/// commands change it; the view models read it.
#[derive(Debug, Clone)]
pub struct HmiState {
    /// The link.
    pub link: LinkSnapshot,
    /// The recorder.
    pub recorder: RecorderSnapshot,
    /// The newest frame.
    pub latest: LatestValues,
    /// Every channel's history (time excluded).
    pub history: super::history::History,
    /// Limits of the live readings.
    pub thresholds: StatusThresholds,
    /// Where each spindle's elongation estimate counts from (`None`: a tool measurement not yet
    /// counted), as the session's estimators last said.
    pub elongation_origins:
        std::collections::BTreeMap<AxisId, Option<crate::estimators::pipeline::ElongationOrigin>>,
    /// Limits of the estimated temperatures and elongation per axis, from the machine
    /// profile (empty without one).
    pub estimate_limits: std::collections::BTreeMap<AxisId, crate::profile::AxisLimits>,
    /// The compensation panel's state.
    pub compensation: CompensationState,
    /// The event list.
    pub events: EventLog,
    /// The Model lab.
    pub model_lab: ModelLabState,
    /// Frames the UI never received (its queue was full); they are in the recording.
    pub frames_not_shown: u64,
    /// Age of the newest frames when they reached the UI, ms (session receipt to UI).
    pub ingest_latency_ms: Option<f64>,
    /// Each axis's condition as last judged, to log changes as events.
    pub conditions: std::collections::BTreeMap<AxisId, Severity>,
    /// The machine profile the estimators run with (ratings, limits, warm-up settings).
    pub profile: Option<crate::profile::MachineProfile>,
    /// The warm-up checklist.
    pub warmup: WarmupState,
    /// The depth-of-cut recommendation.
    pub depth: DepthState,
    /// Opening another source from the *Source* window.
    pub source: SourceState,
    /// The running replay's or twin's pace (`None` on a controller).
    pub pace: Option<super::session::Pace>,
    /// The running controller, when the source is one (leaving it stops watching the
    /// machine, so the operator confirms it).
    pub controller: Option<String>,
}

/// The *Source* window's state: kept when the source changes, like the events.
#[derive(Debug, Clone, Default)]
pub struct SourceState {
    /// The change being made and how far it is.
    pub running: Option<SourceChangeProgress>,
    /// Why the last change failed or stopped (the running source stayed).
    pub error: Option<String>,
    /// The source the HMI was started on, while another one runs (`None`: on it).
    pub start_source_label: Option<String>,
    /// The last change, as told in the events.
    pub last_change: Option<String>,
    /// What a blank profile field means for a controller connected from the window.
    pub blank_controller_profile: String,
}

/// A source change on its way.
#[derive(Debug, Clone)]
pub struct SourceChangeProgress {
    /// "opening shift.csv".
    pub what: String,
    /// Its stage.
    pub progress: JobProgress,
}

impl HmiState {
    /// Why the source may not be changed now (`None`: it may). A push waiting for its
    /// approver or being written belongs to the running controller: it is finished or
    /// withdrawn first, so no approval ever meets another source. A signed-off warm-up
    /// report being written is waited for, so its confirmation is not lost.
    pub fn source_change_refused(&self) -> Option<String> {
        match &self.compensation.flow {
            PushFlow::AwaitingApproval { request, .. } => Some(format!(
                "request {} waits for its approver: approve or withdraw it first (Compensation)",
                request.id()
            )),
            PushFlow::Writing { request, .. } => Some(format!(
                "request {} is being written to the controller: wait for its read-back",
                request.id()
            )),
            PushFlow::Idle | PushFlow::Finished(_) if self.warmup.saving => {
                Some("the warm-up report is being saved: wait for it (Warm-up)".into())
            }
            PushFlow::Idle | PushFlow::Finished(_) => None,
        }
    }

    /// Where `axis`'s elongation estimate counts from, if the estimators have said.
    pub fn elongation_origin(
        &self,
        axis: AxisId,
    ) -> Option<crate::estimators::pipeline::ElongationOrigin> {
        self.elongation_origins.get(&axis).copied().flatten()
    }

    /// The operator measured the tool: until the estimators count `axis`'s elongation from it,
    /// it counts from nothing known, and a thermal offset in the draft, computed from the old
    /// count, is taken out.
    pub fn elongation_restarted(&mut self, axis: AxisId) {
        self.elongation_origins.insert(axis, None);
        self.drop_thermal_offset_draft(axis);
    }

    /// Takes `axis`'s thermal offset out of the draft, saying so: it was computed from an
    /// elongation that counts from somewhere else now.
    fn drop_thermal_offset_draft(&mut self, axis: AxisId) {
        let id = crate::compensation::CompensationId::ThermalOffset(axis);
        if self.compensation.draft_changes.remove(id).is_some() {
            self.compensation.notice = Some(format!(
                "{id} taken out of the draft: the elongation it was computed from now counts from \
                 a new tool measurement"
            ));
        }
    }

    /// An empty state for a link with these columns (`time_s` first).
    pub fn new(
        names: Vec<String>,
        link: LinkSnapshot,
        history_budget_bytes: usize,
        compensation: CompensationState,
    ) -> HmiState {
        let channels: Vec<String> = names.iter().skip(1).cloned().collect();
        let config =
            super::history::HistoryConfig::for_budget(channels.len(), history_budget_bytes);
        HmiState {
            link,
            recorder: RecorderSnapshot::off(),
            latest: LatestValues {
                names,
                row: Vec::new(),
            },
            history: super::history::History::new(channels, config),
            thresholds: StatusThresholds::default(),
            elongation_origins: Default::default(),
            estimate_limits: Default::default(),
            compensation,
            events: EventLog::default(),
            model_lab: ModelLabState::default(),
            frames_not_shown: 0,
            ingest_latency_ms: None,
            conditions: Default::default(),
            profile: None,
            warmup: WarmupState::default(),
            depth: DepthState::default(),
            source: SourceState::default(),
            pace: None,
            controller: None,
        }
    }

    /// Takes one frame row (`time_s` first) into the latest values and the history.
    pub fn push_row(&mut self, row: &[f64]) {
        if let Some((&t, values)) = row.split_first() {
            self.history.push(t, values);
            self.latest.row.clear();
            self.latest.row.extend_from_slice(row);
        }
    }

    /// Applies an update from the session.
    pub fn apply(&mut self, update: super::session::SessionUpdate) {
        use super::session::SessionUpdate;
        match update {
            SessionUpdate::Frames(batch) => {
                for row in &batch.rows {
                    self.push_row(row);
                }
                self.frames_not_shown += batch.dropped_before;
                self.ingest_latency_ms = Some(batch.received_at.elapsed().as_secs_f64() * 1e3);
            }
            SessionUpdate::Link(link) => self.link = link,
            SessionUpdate::Recorder(recorder) => self.recorder = recorder,
            SessionUpdate::Compensation(Ok(values)) => {
                self.compensation.controller = Some(values);
                self.compensation.controller_error = None;
            }
            SessionUpdate::Compensation(Err(error)) => {
                self.compensation.controller_error = Some(error);
            }
            SessionUpdate::Audit(Ok(entries)) => {
                self.compensation.audit = entries;
                self.compensation.audit_error = None;
            }
            SessionUpdate::Audit(Err(error)) => self.compensation.audit_error = Some(error),
            SessionUpdate::Users(Ok(users)) => {
                self.compensation.users = users;
                self.compensation.users_error = None;
            }
            SessionUpdate::Users(Err(error)) => self.compensation.users_error = Some(error),
            SessionUpdate::ApprovalRefused { request_id, reason } => {
                if let PushFlow::Writing { request, .. } = &self.compensation.flow
                    && request.id() == request_id
                {
                    self.compensation.flow = PushFlow::AwaitingApproval {
                        request: request.clone(),
                        refusal: Some(reason),
                    };
                }
            }
            SessionUpdate::PushFinished(result) => {
                if result.verified {
                    self.compensation.draft_changes = CompensationValues::new();
                }
                self.compensation.flow = PushFlow::Finished(result);
            }
            SessionUpdate::Event(event) => self.events.push(event),
            SessionUpdate::Baselines(baselines) => {
                let mut notes = Vec::new();
                for (axis, baseline) in baselines {
                    match baseline {
                        Ok(Some(fingerprint)) => {
                            self.warmup.baselines.insert(axis, fingerprint);
                        }
                        Ok(None) => {
                            self.warmup.baselines.remove(&axis);
                        }
                        Err(error) => notes.push(error),
                    }
                }
                self.warmup.baseline_note = (!notes.is_empty()).then(|| notes.join("; "));
            }
            SessionUpdate::ElongationOrigins(origins) => {
                for (axis, origin) in origins {
                    let before = self.elongation_origins.insert(axis, origin);
                    if before.flatten().is_some_and(|b| Some(b) != origin) {
                        self.drop_thermal_offset_draft(axis);
                    }
                }
            }
            SessionUpdate::WarmupReportSaved(result) => {
                self.warmup.saving = false;
                match result {
                    Ok(saved) => {
                        self.warmup.notice = None;
                        self.warmup.signed = Some(saved);
                    }
                    Err(error) => {
                        self.warmup.notice = Some(format!("the report was not saved: {error}"))
                    }
                }
            }
        }
    }
}
