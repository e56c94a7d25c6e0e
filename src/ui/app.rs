//! The application: drains the session under a time budget in `logic`, builds the view model
//! of the open panel, draws it, and carries out the commands the drawing returned.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use eframe::egui;
use serde::{Deserialize, Serialize};

use super::analysis::{DepthInput, DepthOutcome, WarmupAnalysis, WarmupInput};
use super::export_png::{PngFigure, PngOutcome, PngRequest};
use super::jobs::{FitOutcome, FitRequest, Job, JobMessage, run_fit};
use super::panels::{self, Forms, Tab, UiCommand};
use super::session::{Session, SessionCommand, SessionConfig, SourceSpec, pace_of};
use super::sim_vs_real::{
    DiscrepancyOutcome, DiscrepancyRequest, SavedDiscrepancyReport, SharedColumns, parse_average,
    read_shared_columns, run_discrepancy, run_save_report,
};
use super::source::{
    Endings, ProfileChoice, SourceChange, SwitchContext, Switched, parse_connect_form,
    parse_open_form, parse_speed, run_switch,
};
use super::state::{
    CompensationState, Event, EventKind, HmiState, JobProgress, LinkSnapshot, PushFlow, Severity,
    SourceChangeProgress, StatusThresholds,
};
use super::vm;
use super::vm::events::EventFilter;
use super::vm::trends::TrendsSettings;
use crate::compensation::{
    CompensationId, CompensationLimits, CompensationValues, Proposal, Request, rollback_proposal,
};
use crate::signal::{AxisId, Quantity, axis_column};

/// Layout, theme and choices that survive a restart.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Settings {
    /// The open tab.
    pub tab: Tab,
    /// Dark theme (true) or light.
    pub dark: bool,
    /// The Trends panel's choices.
    pub trends: TrendsSettings,
    /// The Events panel's filter.
    pub events: EventFilter,
    /// Text of the forms worth keeping (operator name, paths, terms).
    pub forms: Forms,
    /// The window's inner size, points.
    pub window_size: Option<[f32; 2]>,
    /// The window's position on the desktop (outer top-left corner), points.
    pub window_pos: Option<[f32; 2]>,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            tab: Tab::Overview,
            dark: true,
            trends: TrendsSettings::default(),
            events: EventFilter::default(),
            forms: Forms::default(),
            window_size: None,
            window_pos: None,
        }
    }
}

impl Settings {
    /// Reads settings; a missing or unreadable file gives the defaults (a broken settings
    /// file must never keep the HMI from starting).
    pub fn load(path: &std::path::Path) -> Settings {
        std::fs::read_to_string(path)
            .ok()
            .and_then(|text| serde_json::from_str(&text).ok())
            .unwrap_or_default()
    }

    /// Writes settings (creating the directory).
    pub fn save(&self, path: &std::path::Path) -> std::io::Result<()> {
        if let Some(parent) = path.parent() {
            std::fs::create_dir_all(parent)?;
        }
        let text = serde_json::to_string_pretty(self).map_err(std::io::Error::other)?;
        std::fs::write(path, text)
    }
}

/// How the app is set up.
#[derive(Debug, Clone)]
pub struct HmiOptions {
    /// Where settings persist (`None`: nothing is saved).
    pub settings_path: Option<PathBuf>,
    /// Memory for the history pyramid.
    pub history_budget_bytes: usize,
    /// Limits of the live readings.
    pub thresholds: StatusThresholds,
    /// Where a controller opened from the *Source* window is recorded (`None`: the HMI was
    /// started with the recorder off).
    pub machine_record_dir: Option<PathBuf>,
    /// The users file shown in the Compensation panel.
    pub users_path: PathBuf,
    /// The audit log shown in the Compensation panel.
    pub audit_path: PathBuf,
    /// Compensation limits (shown beside the values).
    pub limits: CompensationLimits,
    /// Time per frame for taking in session updates.
    pub ingest_budget: Duration,
}

/// Most events listed at once.
const EVENT_ROWS: usize = 2000;
/// Points per series on the Trends plots.
const TREND_POINTS: usize = 1000;
/// Points per line on the Model lab's sim-vs-real plots.
const DISCREPANCY_POINTS: usize = 1500;
/// Width of the sim-vs-real PNG, pixels (as `servosight discrepancy --plot` draws it).
const DISCREPANCY_PNG_WIDTH: u32 = 1400;
/// Points per line in the sim-vs-real PNG (about one per pixel of its plots).
const DISCREPANCY_PNG_POINTS: usize = 1400;
/// How long the exit, or a cancelled change's follower, waits for a source change to end
/// (a controller's answer is waited for 3 s, a previous session's end as long as it takes).
const JOB_END_WAIT: Duration = Duration::from_secs(30);
/// How often settings are saved while running.
const SAVE_EVERY: Duration = Duration::from_secs(10);

/// The HMI.
pub struct HmiApp {
    session: Session,
    /// Everything the panels show.
    pub state: HmiState,
    /// Layout and choices.
    pub settings: Settings,
    settings_path: Option<PathBuf>,
    saved_settings: Settings,
    last_save: Instant,
    fit_job: Option<Job<FitOutcome>>,
    warmup_job: Option<Job<WarmupAnalysis>>,
    depth_job: Option<Job<DepthOutcome>>,
    png_job: Option<Job<PngOutcome>>,
    discrepancy_job: Option<Job<DiscrepancyOutcome>>,
    /// Drawing the sim-vs-real analysis into a PNG.
    discrepancy_png_job: Option<Job<PngOutcome>>,
    /// Saving the sim-vs-real analysis's report.
    discrepancy_report_job: Option<Job<SavedDiscrepancyReport>>,
    columns_job: Option<Job<SharedColumns>>,
    /// The (simulation, real, later pieces looked for) whose shared columns were last asked for.
    columns_asked: Option<(String, String, bool)>,
    /// When the depth of cut was last recomputed on its own (wall clock).
    depth_refreshed: Option<Instant>,
    export_note: Option<String>,
    ingest_budget: Duration,
    applied_theme: Option<bool>,
    /// How the app was set up (a new source's state is built from it).
    options: HmiOptions,
    /// The session the HMI was started on, to go back to from another source.
    start_config: SessionConfig,
    /// What its link called it.
    start_label: String,
    /// Starting another source while the running one goes on.
    switch_job: Option<Job<Switched>>,
    /// Sessions ending off the UI thread (the next change and the exit wait for them).
    endings: Endings,
}

impl HmiApp {
    /// The app on a running session.
    pub fn new(session: Session, options: HmiOptions) -> HmiApp {
        let mut state = fresh_state(&session, &options);
        state.source.blank_controller_profile = match &session.config().source {
            SourceSpec::Serial(_) => format!(
                "blank: the one the HMI was started with on its controller ({})",
                session
                    .profile()
                    .map_or("none".to_string(), |p| format!("`{}`", p.name))
            ),
            _ => "blank: refused (the HMI was not started on a controller): give this \
                  machine's (TOML), or `none` for no estimators"
                .into(),
        };
        let names = state.latest.names.clone();
        let mut settings = options
            .settings_path
            .as_deref()
            .map(Settings::load)
            .unwrap_or_default();
        fit_trends_to(&mut settings.trends, &names);
        if settings.forms.export_path.is_empty() {
            settings.forms.export_path = std::env::temp_dir()
                .join("servosight-trends.csv")
                .display()
                .to_string();
        }
        if settings.forms.png_path.is_empty() {
            settings.forms.png_path = std::env::temp_dir()
                .join("servosight-trends.png")
                .display()
                .to_string();
        }
        if settings.forms.disc_png_path.is_empty() {
            settings.forms.disc_png_path = std::env::temp_dir()
                .join("servosight-sim-vs-real.png")
                .display()
                .to_string();
        }
        if settings.forms.disc_report_path.is_empty() {
            settings.forms.disc_report_path = std::env::temp_dir()
                .join("servosight-sim-vs-real.json")
                .display()
                .to_string();
        }
        if settings.forms.workpiece_diameter_mm.is_empty() {
            settings.forms.workpiece_diameter_mm = "80".into();
        }
        HmiApp {
            start_config: session.config().clone(),
            start_label: session.source().to_string(),
            endings: Endings::default(),
            session,
            state,
            saved_settings: settings.clone(),
            settings,
            settings_path: options.settings_path.clone(),
            last_save: Instant::now(),
            fit_job: None,
            warmup_job: None,
            depth_job: None,
            png_job: None,
            discrepancy_job: None,
            discrepancy_png_job: None,
            discrepancy_report_job: None,
            columns_job: None,
            columns_asked: None,
            depth_refreshed: None,
            export_note: None,
            ingest_budget: options.ingest_budget,
            applied_theme: None,
            options,
            switch_job: None,
        }
    }

    /// Non-drawing work of a frame: takes in session updates for at most the ingest budget
    /// (the rest waits for the next frame), follows the fit job, logs condition changes,
    /// saves settings now and then, and schedules the next frame.
    pub fn logic(&mut self, ctx: &egui::Context) {
        let started = Instant::now();
        while started.elapsed() < self.ingest_budget {
            match self.session.try_recv() {
                Some(update) => self.state.apply(update),
                None => break,
            }
        }
        self.poll_fit_job();
        self.poll_switch_job();
        self.poll_analysis_jobs();
        self.poll_discrepancy_jobs();
        self.refresh_shared_columns();
        self.refresh_depth_of_cut();
        self.log_condition_changes();
        if self.applied_theme != Some(self.settings.dark) {
            ctx.set_theme(if self.settings.dark {
                egui::Theme::Dark
            } else {
                egui::Theme::Light
            });
            self.applied_theme = Some(self.settings.dark);
        }
        if let Some(rect) = ctx.input(|i| i.viewport().inner_rect) {
            self.settings.window_size = Some([rect.width(), rect.height()]);
        }
        if let Some(rect) = ctx.input(|i| i.viewport().outer_rect) {
            self.settings.window_pos = Some([rect.min.x, rect.min.y]);
        }
        if self.last_save.elapsed() >= SAVE_EVERY {
            self.save_settings();
        }
        // Live data: about 30 frames per second keeps sample-to-screen latency near 35 ms
        // without spinning the CPU; a quiet link needs only a slow refresh of its ages.
        let live = self.state.link.state == crate::link::ConnectionState::Connected
            || self.fit_job.is_some()
            || self.warmup_job.is_some()
            || self.depth_job.is_some()
            || self.png_job.is_some()
            || self.discrepancy_job.is_some()
            || self.discrepancy_png_job.is_some()
            || self.discrepancy_report_job.is_some()
            || self.columns_job.is_some()
            || self.switch_job.is_some();
        ctx.request_repaint_after(if live {
            Duration::from_millis(33)
        } else {
            Duration::from_millis(250)
        });
    }

    /// Saves the settings if they changed.
    pub fn save_settings(&mut self) {
        self.last_save = Instant::now();
        let Some(path) = &self.settings_path else {
            return;
        };
        if self.settings != self.saved_settings {
            // Settings are a convenience: failing to save them must not disturb operation.
            if self.settings.save(path).is_ok() {
                self.saved_settings = self.settings.clone();
            }
        }
    }

    fn log_condition_changes(&mut self) {
        for axis in self.state.latest.axes() {
            let light = vm::overview::axis_condition(&self.state, axis);
            let before = self.state.conditions.insert(axis, light.severity);
            if before.is_some_and(|b| b != light.severity) {
                let text = light.reasons.join("; ");
                self.state.events.push(Event::now(
                    EventKind::Condition,
                    light.severity,
                    format!("{axis}: {text}"),
                ));
            }
        }
    }

    fn poll_fit_job(&mut self) {
        let Some(job) = &self.fit_job else {
            return;
        };
        while let Some(message) = job.try_next() {
            let lab = &mut self.state.model_lab;
            let (finished, event) = match message {
                JobMessage::Progress(progress) => {
                    lab.running = Some(progress);
                    (false, None)
                }
                JobMessage::Done(outcome) => {
                    let text = format!("{}: R² = {}", job.title, vm::statistic(outcome.report.r2));
                    lab.result = Some(outcome);
                    lab.error = None;
                    (true, Some((Severity::Normal, text)))
                }
                JobMessage::Failed(reason) => {
                    let text = format!("{} failed: {reason}", job.title);
                    lab.error = Some(reason);
                    (true, Some((Severity::Warning, text)))
                }
                JobMessage::Cancelled => {
                    lab.error = Some("cancelled".into());
                    (
                        true,
                        Some((Severity::Normal, format!("{} cancelled", job.title))),
                    )
                }
            };
            if let Some((severity, text)) = event {
                self.state
                    .events
                    .push(Event::now(EventKind::Job, severity, text));
            }
            if finished {
                self.state.model_lab.running = None;
                self.fit_job = None;
                return;
            }
        }
    }

    fn job_event(&mut self, severity: Severity, text: String) {
        self.state
            .events
            .push(Event::now(EventKind::Job, severity, text));
    }

    /// Follows the warm-up, depth-of-cut and PNG jobs.
    fn poll_analysis_jobs(&mut self) {
        if let Some(end) = poll_job(&mut self.warmup_job, &mut self.state.warmup.running) {
            match end {
                Ok(analysis) => {
                    let text = format!(
                        "warm-up analysis of {}: fingerprint {}, backlash {}",
                        analysis.axis,
                        if analysis.fingerprint.is_ok() {
                            "taken"
                        } else {
                            "not possible"
                        },
                        match &analysis.backlash {
                            Ok(b) => format!("{:.1} µm", b.backlash_um),
                            Err(_) => "not found".into(),
                        }
                    );
                    self.state.warmup.analysis = Some(analysis);
                    self.state.warmup.analysis_error = None;
                    self.job_event(Severity::Normal, text);
                }
                Err(reason) => {
                    self.job_event(
                        Severity::Warning,
                        format!("warm-up analysis stopped: {reason}"),
                    );
                    self.state.warmup.analysis_error = Some(reason);
                }
            }
        }
        if let Some(end) = poll_job(&mut self.depth_job, &mut self.state.depth.running) {
            match end {
                Ok(outcome) => {
                    if let DepthOutcome::Ready { recommendation, .. } = &outcome {
                        let text = format!(
                            "depth of cut: {:.1} mm, limited by {}",
                            recommendation.recommended_depth_mm, recommendation.limiting_component
                        );
                        self.job_event(Severity::Normal, text);
                    }
                    self.state.depth.outcome = Some(outcome);
                    self.state.depth.error = None;
                }
                Err(reason) => self.state.depth.error = Some(reason),
            }
        }
        if let Some(note) = poll_png_export(&mut self.png_job) {
            self.export_note = Some(note);
        }
    }

    /// Starts `change` on a job; the running source goes on until the new one has started.
    fn start_switch(&mut self, change: SourceChange) {
        if self.switch_job.is_some() || self.leaving_controller_unconfirmed() {
            return;
        }
        if let Some(reason) = self
            .state
            .source_change_refused()
            .or_else(|| self.same_line(&change))
        {
            self.state.source.error = Some(reason);
            return;
        }
        let what = match &change {
            SourceChange::Open(request) => format!("opening {}", request.recording.display()),
            SourceChange::Connect { modbus, .. } => format!("connecting to {}", modbus.port),
            SourceChange::Return => format!("going back to {}", self.start_label),
        };
        // Asked now, so the state is saved from where the running session is; the job waits
        // for it only if the new session takes up the same file.
        let (saved_tx, saved_rx) = std::sync::mpsc::sync_channel(1);
        let running_saved = self
            .session
            .send(SessionCommand::SaveStateNow(saved_tx))
            .is_ok()
            .then_some(saved_rx);
        let inputs = SwitchContext {
            running: self.session.config().clone(),
            start: self.start_config.clone(),
            machine_record_dir: self.options.machine_record_dir.clone(),
            earlier_endings: std::mem::take(&mut self.endings),
            running_saved,
        };
        match Job::spawn(what.clone(), move |c| run_switch(change, inputs, c)) {
            Ok(job) => {
                self.state.source.running = Some(SourceChangeProgress {
                    what,
                    progress: JobProgress {
                        stage: "starting".into(),
                        fraction: Some(0.0),
                    },
                });
                self.state.source.error = None;
                self.switch_job = Some(job);
            }
            Err(error) => {
                self.state.source.error = Some(format!("cannot start {what}: {error}"));
            }
        }
    }

    /// Why `change` cannot be made while the running controller holds its serial line (the
    /// line is opened for one user at a time, and the running session lets it go only once
    /// the new one runs).
    fn same_line(&self, change: &SourceChange) -> Option<String> {
        let SourceSpec::Serial(running) = &self.session.config().source else {
            return None;
        };
        let port = match change {
            SourceChange::Connect { modbus, .. } => &modbus.port,
            SourceChange::Return => match &self.start_config.source {
                SourceSpec::Serial(start) => &start.port,
                _ => return None,
            },
            SourceChange::Open(_) => return None,
        };
        (*port == running.port).then(|| {
            format!(
                "{port} is the running controller's line: to reach it with other settings, \
                 first open another source here (a recording, or Back to the start source)"
            )
        })
    }

    /// Whether the running source is a controller the operator has not agreed to stop
    /// monitoring (and says so: the change waits for the tick).
    fn leaving_controller_unconfirmed(&mut self) -> bool {
        let Some(controller) = &self.state.controller else {
            return false;
        };
        if self.settings.forms.open_leave_controller {
            return false;
        }
        self.state.source.error = Some(format!(
            "tick “stop monitoring the controller” first: once the other source runs, \
             {controller} is neither watched nor recorded"
        ));
        true
    }

    /// Stops opening a source: the job is asked to stop (a session it starts after this is
    /// ended there) and dropped, so the running source stays. A session it had already
    /// started is ended off the UI thread.
    fn cancel_switch(&mut self) {
        let Some(job) = self.switch_job.take() else {
            return;
        };
        job.cancel();
        self.state.source.running = None;
        self.state.source.error = Some(format!("{}: cancelled", job.title));
        // A session the job started all the same is ended off the UI thread.
        let ended = self.endings.run(move || {
            if let Some(JobMessage::Done(switched)) = job.wait_end(JOB_END_WAIT) {
                drop(switched);
            }
        });
        if let Err(error) = ended {
            self.job_event(
                Severity::Warning,
                format!("the cancelled change is followed on the UI thread: {error}"),
            );
        }
    }

    /// Follows the source change; once the new session runs, it takes the old one's place.
    fn poll_switch_job(&mut self) {
        let title = match &self.switch_job {
            Some(job) => job.title.clone(),
            None => return,
        };
        let mut progress = None;
        let end = poll_job(&mut self.switch_job, &mut progress);
        if let Some(progress) = progress {
            self.state.source.running = Some(SourceChangeProgress {
                what: title.clone(),
                progress,
            });
        }
        let reason = match end {
            None => return,
            Some(Ok(switched)) => match self.state.source_change_refused() {
                None => return self.take_session(switched),
                // Requests are refused while the change runs; should one have begun all the
                // same, it stays with the source it was made on.
                Some(reason) => {
                    self.end_off_the_ui_thread(switched.session, None);
                    reason
                }
            },
            Some(Err(reason)) => reason,
        };
        self.state.source.running = None;
        let text = format!(
            "{title} failed: {reason}; {} runs on",
            self.session.source()
        );
        self.state.source.error = Some(text.clone());
        self.job_event(Severity::Warning, text);
    }

    /// Ends `session` (joining its threads, finishing its recorder file) and frees `state`
    /// (its history may hold hundreds of megabytes) on a thread of their own; the next source
    /// change, and the app's exit, wait for it. Without a thread they end here.
    fn end_off_the_ui_thread(&mut self, session: Session, state: Option<HmiState>) {
        if let Err(error) = self.endings.run(move || drop((session, state))) {
            self.job_event(
                Severity::Warning,
                format!("the previous source was ended on the UI thread: {error}"),
            );
        }
    }

    /// Puts a newly started session in place of the running one. What belonged to the old
    /// source starts afresh (readings, history, checklist, depth of cut, compensation draft);
    /// the events, the Model lab, the forms and the Trends choices stay.
    fn take_session(&mut self, switched: Switched) {
        let Switched {
            session,
            summary,
            is_start,
            early_updates,
        } = switched;
        let mut old = std::mem::replace(&mut self.session, session);
        // What the old session still had to say (a recorder or link fault) is kept, as much
        // as one frame's ingest budget takes: a fast replay could keep it talking.
        let started = Instant::now();
        while started.elapsed() < self.ingest_budget
            && let Some(update) = old.try_recv()
        {
            if let super::session::SessionUpdate::Event(event) = update {
                self.state.events.push(event);
            }
        }
        // Work on the old source's samples would be about another source: let it go.
        let warmup = self.warmup_job.take().map(|job| {
            job.cancel();
            job.title
        });
        let depth = self.depth_job.take().map(|job| {
            job.cancel();
            job.title
        });
        for title in [warmup, depth].into_iter().flatten() {
            self.job_event(
                Severity::Normal,
                format!("{title} stopped: its samples were of the previous source"),
            );
        }
        self.depth_refreshed = None;
        let drafted = self.state.compensation.draft_changes.iter().count();
        let mut state = fresh_state(&self.session, &self.options);
        state.events = std::mem::take(&mut self.state.events);
        state.model_lab = std::mem::take(&mut self.state.model_lab);
        state.source = std::mem::take(&mut self.state.source);
        let old_state = std::mem::replace(&mut self.state, state);
        self.end_off_the_ui_thread(old, Some(old_state));
        let names = self.state.latest.names.clone();
        let trends = &mut self.settings.trends;
        // The choices are kept for the source they name (a way back finds them); only if
        // none of them is a column here are the stator temperatures added.
        if !trends.selected.iter().any(|n| names.contains(n)) {
            trends.selected.extend(default_trend_channels(&names));
        }
        trends.follow_live = true;
        trends.view = None;
        let mut text = format!("source: {summary}");
        if drafted > 0 {
            text.push_str(&format!(
                "; the compensation draft ({drafted} change(s)) and its why and evidence were \
                 left behind: they were made on the previous source"
            ));
            self.settings.forms.why.clear();
            self.settings.forms.evidence.clear();
        }
        let source = &mut self.state.source;
        source.running = None;
        source.error = None;
        source.start_source_label = (!is_start).then(|| self.start_label.clone());
        source.last_change = Some(text.clone());
        self.settings.forms.open_leave_controller = false;
        self.state
            .events
            .push(Event::now(EventKind::Link, Severity::Normal, text));
        for update in early_updates {
            self.state.apply(update);
        }
    }

    /// Follows the sim-vs-real analysis and the header read behind its target choice.
    fn poll_discrepancy_jobs(&mut self) {
        let lab = &mut self.state.model_lab.discrepancy;
        let title = self
            .discrepancy_job
            .as_ref()
            .map(|job| job.title.clone())
            .unwrap_or_default();
        if let Some(end) = poll_job(&mut self.discrepancy_job, &mut lab.running) {
            match end {
                Ok(outcome) => {
                    let text = format!(
                        "{title}: {} finding(s), R² {} before → {} after (held out)",
                        outcome.report.findings.len(),
                        vm::statistic(outcome.report.baseline.r2),
                        vm::statistic(outcome.report.improved.r2)
                    );
                    lab.result = Some(outcome);
                    lab.error = None;
                    // The notes told of the last result's exports, not of this one.
                    lab.png_note = None;
                    lab.report_note = None;
                    self.job_event(Severity::Normal, text);
                }
                Err(reason) => {
                    let text = format!("{title} stopped: {reason}");
                    lab.error = Some(reason);
                    self.job_event(Severity::Warning, text);
                }
            }
        }
        if let Some(note) = poll_png_export(&mut self.discrepancy_png_job) {
            self.state.model_lab.discrepancy.png_note = Some(note);
        }
        let mut ignored = None;
        if let Some(end) = poll_job(&mut self.discrepancy_report_job, &mut ignored) {
            self.state.model_lab.discrepancy.report_note = Some(match end {
                Ok(saved) => format!(
                    "report written to {} and {}",
                    saved.json.display(),
                    saved.text.display()
                ),
                Err(reason) => format!("the report was not saved: {reason}"),
            });
        }
        let mut ignored = None;
        if let Some(end) = poll_job(&mut self.columns_job, &mut ignored) {
            let lab = &mut self.state.model_lab.discrepancy;
            match end {
                Ok(columns) => {
                    lab.columns = Some(columns);
                    lab.columns_error = None;
                }
                Err(reason) => {
                    lab.columns = None;
                    lab.columns_error = Some(reason);
                }
            }
        }
    }

    /// Reads the two files' headers (on a job, since even a header is file I/O) whenever the
    /// sim-vs-real section is open and its paths changed, so the shared columns are offered.
    fn refresh_shared_columns(&mut self) {
        let forms = &self.settings.forms;
        if self.settings.tab != Tab::ModelLab
            || forms.lab_section != panels::LabSection::Discrepancy
            || self.columns_job.is_some()
        {
            return;
        }
        let asked = (
            forms.disc_sim.trim().to_string(),
            forms.disc_real.trim().to_string(),
            !forms.disc_real_this_file_only,
        );
        if asked.0.is_empty() || asked.1.is_empty() || self.columns_asked.as_ref() == Some(&asked) {
            return;
        }
        let (sim, real, find_later) = (PathBuf::from(&asked.0), PathBuf::from(&asked.1), asked.2);
        self.columns_asked = Some(asked);
        let read = move |c: &_| read_shared_columns(sim, real, find_later, c);
        match Job::spawn("shared columns", read) {
            Ok(job) => self.columns_job = Some(job),
            Err(error) => {
                self.state.model_lab.discrepancy.columns_error =
                    Some(format!("cannot start reading the headers: {error}"));
            }
        }
    }

    fn start_discrepancy(&mut self) {
        if self.discrepancy_job.is_some() {
            return;
        }
        let forms = &self.settings.forms;
        let lab = &mut self.state.model_lab.discrepancy;
        let average_s = match parse_average(&forms.disc_average_s) {
            Ok(average_s) => average_s,
            Err(reason) => {
                lab.error = Some(reason);
                return;
            }
        };
        let request = DiscrepancyRequest {
            sim: PathBuf::from(forms.disc_sim.trim()),
            real: vec![PathBuf::from(forms.disc_real.trim())],
            find_later_pieces: !forms.disc_real_this_file_only,
            target: forms.disc_target.trim().to_string(),
            average_s,
        };
        let title = format!(
            "discrepancy of {} ({} vs {})",
            request.target,
            request.sim.display(),
            forms.disc_real.trim()
        );
        match Job::spawn(title.clone(), move |c| run_discrepancy(request, c)) {
            Ok(job) => {
                lab.running = Some(super::state::JobProgress {
                    stage: "starting".into(),
                    fraction: Some(0.0),
                });
                lab.error = None;
                self.discrepancy_job = Some(job);
                self.job_event(Severity::Normal, format!("{title} started"));
            }
            Err(error) => lab.error = Some(format!("cannot start the analysis: {error}")),
        }
    }

    /// Cancels the analysis and frees the panel at once: the job is asked to stop (the
    /// analysis stops at its next stopping point) and dropped, so nothing it still sends is
    /// taken.
    fn cancel_discrepancy(&mut self) {
        if let Some(job) = self.discrepancy_job.take() {
            job.cancel();
            let lab = &mut self.state.model_lab.discrepancy;
            lab.running = None;
            lab.error = Some("cancelled".into());
            let text = format!("{} cancelled", job.title);
            self.job_event(Severity::Normal, text);
        }
    }

    /// Recomputes the depth-of-cut recommendation while its panel is open: first when it
    /// is opened, then once a minute of machine time (and at most every ten seconds, since
    /// a fast replay would otherwise copy the full-rate columns every frame), so new cuts
    /// count.
    fn refresh_depth_of_cut(&mut self) {
        if self.settings.tab != Tab::DepthOfCut
            || self.depth_job.is_some()
            || self.state.depth.error.is_some()
            || self
                .depth_refreshed
                .is_some_and(|t| t.elapsed() < Duration::from_secs(10))
        {
            return;
        }
        let newest = self.state.history.newest_time_s();
        let due = match (self.state.depth.computed_at_s, newest) {
            (_, None) => false,
            (None, Some(_)) => true,
            (Some(at), Some(now)) => now - at >= 60.0,
        };
        if due {
            self.depth_refreshed = Some(Instant::now());
            self.start_depth_of_cut();
        }
    }

    fn start_depth_of_cut(&mut self) {
        if self.depth_job.is_some() {
            return;
        }
        let depth = &mut self.state.depth;
        let Some(profile) = &self.state.profile else {
            depth.error = Some("no machine profile: the component ratings are unknown".into());
            return;
        };
        let text = self
            .settings
            .forms
            .workpiece_diameter_mm
            .trim()
            .replace(',', ".");
        let diameter = match text.parse::<f64>() {
            Ok(d) if d.is_finite() && d > 0.0 => d,
            _ => {
                depth.error = Some(format!(
                    "`{text}` is not a workpiece diameter: give a positive number of millimetres"
                ));
                return;
            }
        };
        depth.computed_at_s = self.state.history.newest_time_s();
        let input = match DepthInput::from_history(&self.state.history, profile, diameter) {
            Ok(input) => input,
            Err(error) => {
                depth.error = Some(error.to_string());
                return;
            }
        };
        match Job::spawn("depth of cut", move |c| {
            super::analysis::run_depth_of_cut(input, c)
        }) {
            Ok(job) => {
                depth.running = Some(super::state::JobProgress {
                    stage: "starting".into(),
                    fraction: Some(0.0),
                });
                depth.error = None;
                self.depth_job = Some(job);
            }
            Err(error) => depth.error = Some(format!("cannot start: {error}")),
        }
    }

    fn start_warmup_analysis(&mut self) {
        if self.warmup_job.is_some() {
            return;
        }
        let warmup = &mut self.state.warmup;
        let Some((axis, lead)) = self
            .state
            .profile
            .as_ref()
            .and_then(vm::warmup::checklist_axis)
        else {
            warmup.analysis_error =
                Some("no machine profile with a feed axis: nothing to analyse".into());
            return;
        };
        let history = &self.state.history;
        let t0 = warmup
            .started_at_s
            .or_else(|| history.oldest_raw_time_s())
            .unwrap_or(0.0);
        let input = match WarmupInput::from_history(history, axis, lead, t0) {
            Ok(input) => input,
            Err(error) => {
                warmup.analysis_error = Some(error.to_string());
                return;
            }
        };
        match Job::spawn("warm-up analysis", move |c| {
            super::analysis::run_warmup_analysis(input, c)
        }) {
            Ok(job) => {
                warmup.running = Some(super::state::JobProgress {
                    stage: "starting".into(),
                    fraction: Some(0.0),
                });
                warmup.analysis_error = None;
                self.warmup_job = Some(job);
            }
            Err(error) => warmup.analysis_error = Some(format!("cannot start: {error}")),
        }
    }

    fn sign_off_warmup(&mut self) {
        let operator = self.settings.forms.checklist_operator.trim().to_string();
        let view = vm::warmup::build(&self.state);
        let warmup = &mut self.state.warmup;
        if self.switch_job.is_some() {
            warmup.notice = Some(
                "the source is changing (Source window): sign off once it has, on the source \
                 that then runs"
                    .into(),
            );
            return;
        }
        if operator.is_empty() {
            warmup.notice = Some("enter your name to sign the checklist off".into());
            return;
        }
        if let Some(reason) = view.sign_off_blocked {
            warmup.notice = Some(reason);
            return;
        }
        let report = vm::warmup::WarmupReport::new(
            &view,
            &self.state,
            &operator,
            crate::compensation::audit::utc_now(),
        );
        match self
            .session
            .send(SessionCommand::SaveWarmupReport(Box::new(report)))
        {
            Ok(()) => {
                self.state.warmup.saving = true;
                self.state.warmup.notice = None;
            }
            Err(error) => self.state.warmup.notice = Some(error.to_string()),
        }
    }

    fn export_png(&mut self) {
        if self.png_job.is_some() {
            return;
        }
        let view = vm::trends::build(&self.state, &self.settings.trends, TREND_POINTS);
        let height =
            90 + 360 * view.plots.len() as u32 + if view.straightness.is_empty() { 0 } else { 300 };
        let request = PngRequest {
            figure: PngFigure::Trends {
                view,
                size: [1600, height],
            },
            dark: self.settings.dark,
            path: PathBuf::from(self.settings.forms.png_path.trim()),
        };
        let (job, note) = start_png_export("PNG export", request);
        self.png_job = job;
        self.export_note = Some(note);
    }

    /// Draws the last sim-vs-real analysis into the Model lab's PNG file, on a job.
    fn export_discrepancy_png(&mut self) {
        if self.discrepancy_png_job.is_some() {
            return;
        }
        let lab = &mut self.state.model_lab.discrepancy;
        let Some(outcome) = &lab.result else {
            lab.png_note = Some("nothing to export: run an analysis first".into());
            return;
        };
        let request = PngRequest {
            figure: PngFigure::Discrepancy {
                view: Box::new(vm::discrepancy::result_view(
                    outcome,
                    DISCREPANCY_PNG_POINTS,
                )),
                width: DISCREPANCY_PNG_WIDTH,
            },
            dark: self.settings.dark,
            path: PathBuf::from(self.settings.forms.disc_png_path.trim()),
        };
        let (job, note) = start_png_export("sim-vs-real PNG", request);
        self.discrepancy_png_job = job;
        lab.png_note = Some(note);
    }

    /// Saves the last sim-vs-real analysis's report (JSON and text) on a job.
    fn save_discrepancy_report(&mut self) {
        if self.discrepancy_report_job.is_some() {
            return;
        }
        let lab = &mut self.state.model_lab.discrepancy;
        let Some(outcome) = &lab.result else {
            lab.report_note = Some("nothing to save: run an analysis first".into());
            return;
        };
        let report = outcome.report.clone();
        let json = PathBuf::from(self.settings.forms.disc_report_path.trim());
        match Job::spawn("sim-vs-real report", move |c| {
            run_save_report(report, json, c)
        }) {
            Ok(job) => {
                self.discrepancy_report_job = Some(job);
                lab.report_note = Some("writing the report…".into());
            }
            Err(error) => lab.report_note = Some(format!("cannot start saving: {error}")),
        }
    }

    fn use_proposal(&mut self, id: &str) {
        let proposals = vm::compensation::estimate_proposals(&self.state);
        let comp = &mut self.state.compensation;
        let Some(proposal) = proposals.into_iter().find(|p| p.id.to_string() == id) else {
            comp.notice = Some(format!("no proposal for {id} any more"));
            return;
        };
        if let Some(why) = &proposal.withheld {
            comp.notice = Some(format!("{id} is not proposed: {why}"));
            return;
        }
        let limit = comp.limits.of(proposal.id.kind()).absolute_um;
        if proposal.value_um.abs() > limit {
            comp.notice = Some(format!(
                "{id} = {:.1} µm is beyond its limit of ±{limit} µm",
                proposal.value_um
            ));
            return;
        }
        comp.notice = None;
        comp.draft_changes.set(proposal.id, proposal.value_um);
        let forms = &mut self.settings.forms;
        if forms.why.trim().is_empty() {
            forms.why = "compensation from the live estimates".into();
        }
        let evidence = format!("{id}: {}", proposal.basis);
        if !forms.evidence.contains(&evidence) {
            if !forms.evidence.trim().is_empty() {
                forms.evidence.push_str("; ");
            }
            forms.evidence.push_str(&evidence);
        }
    }

    /// Draws the whole window.
    pub fn show(&mut self, ui: &mut egui::Ui) {
        let mut commands = Vec::new();
        let status = vm::status::build(&self.state);
        egui::Panel::top("tabs").show(ui, |ui| {
            ui.horizontal(|ui| {
                ui.heading("servosight");
                ui.separator();
                for tab in Tab::ALL {
                    if ui
                        .selectable_label(self.settings.tab == tab, tab.label())
                        .clicked()
                    {
                        commands.push(UiCommand::SelectTab(tab));
                    }
                }
                ui.separator();
                let theme = if self.settings.dark {
                    "Light theme"
                } else {
                    "Dark theme"
                };
                if ui.button(theme).clicked() {
                    commands.push(UiCommand::SetDark(!self.settings.dark));
                }
                if ui
                    .selectable_label(self.settings.forms.source_window, "Source…")
                    .clicked()
                {
                    commands.push(UiCommand::ToggleSourceWindow);
                }
            });
        });
        if self.settings.forms.source_window {
            let view = vm::source::build(&self.state);
            panels::source::source_ui(ui.ctx(), &view, &mut self.settings.forms, &mut commands);
        }
        egui::Panel::bottom("status").show(ui, |ui| {
            panels::status::status_ui(ui, &status, &mut commands);
        });
        let forms = &mut self.settings.forms;
        match self.settings.tab {
            Tab::Overview => {
                let view = vm::overview::build(&self.state);
                egui::CentralPanel::default()
                    .show(ui, |ui| panels::overview::overview_ui(ui, &view));
            }
            Tab::Warmup => {
                let view = vm::warmup::build(&self.state);
                egui::CentralPanel::default().show(ui, |ui| {
                    panels::warmup::warmup_ui(ui, &view, forms, &mut commands);
                });
            }
            Tab::DepthOfCut => {
                let view = vm::depth::build(&self.state);
                egui::CentralPanel::default().show(ui, |ui| {
                    panels::depth::depth_ui(ui, &view, forms, &mut commands);
                });
            }
            Tab::Trends => {
                let view = vm::trends::build(&self.state, &self.settings.trends, TREND_POINTS);
                let note = self.export_note.as_deref();
                egui::CentralPanel::default().show(ui, |ui| {
                    panels::trends::trends_ui(ui, &view, forms, note, &mut commands);
                });
            }
            Tab::Compensation => {
                let view = vm::compensation::build(&self.state);
                if forms.change_id.is_empty()
                    && let Some(first) = view.ids.first()
                {
                    forms.change_id = first.clone();
                }
                egui::CentralPanel::default().show(ui, |ui| {
                    panels::compensation::compensation_ui(ui, &view, forms, &mut commands);
                });
            }
            Tab::ModelLab => {
                egui::CentralPanel::default().show(ui, |ui| {
                    panels::model_lab::section_ui(ui, forms);
                    match forms.lab_section {
                        panels::LabSection::Fit => {
                            let view = vm::model_lab::build(&self.state);
                            panels::model_lab::model_lab_ui(ui, &view, forms, &mut commands);
                        }
                        panels::LabSection::Discrepancy => {
                            let view = vm::discrepancy::build(&self.state, DISCREPANCY_POINTS);
                            panels::model_lab::discrepancy_ui(ui, &view, forms, &mut commands);
                        }
                    }
                });
            }
            Tab::Events => {
                let mut filter = self.settings.events.clone();
                filter.text = forms.event_text.clone();
                let view = vm::events::build(&self.state, &filter, EVENT_ROWS);
                egui::CentralPanel::default().show(ui, |ui| {
                    panels::events::events_ui(ui, &view, forms, &mut commands);
                });
            }
        }
        for command in commands {
            self.execute(command);
        }
    }

    /// Carries out one operator command.
    pub fn execute(&mut self, command: UiCommand) {
        match command {
            UiCommand::SelectTab(tab) => self.settings.tab = tab,
            UiCommand::SetDark(dark) => self.settings.dark = dark,
            UiCommand::ToggleChannel(name) => {
                let selected = &mut self.settings.trends.selected;
                match selected.iter().position(|n| *n == name) {
                    Some(i) => {
                        selected.remove(i);
                    }
                    None => selected.push(name),
                }
            }
            UiCommand::SetPreset(preset) => {
                self.settings.trends.preset = preset;
                self.settings.trends.follow_live = true;
                self.settings.trends.view = None;
            }
            UiCommand::FollowLive => {
                self.settings.trends.follow_live = true;
                self.settings.trends.view = None;
            }
            UiCommand::SetView(t0, t1) => {
                self.settings.trends.follow_live = false;
                self.settings.trends.view = Some((t0, t1));
            }
            UiCommand::SetSeriesHidden(name, hidden) => {
                let set = &mut self.settings.trends.hidden;
                if hidden {
                    set.insert(name);
                } else {
                    set.remove(&name);
                }
            }
            UiCommand::SetGroupOpen(title, open) => {
                self.settings.trends.groups_open.insert(title, open);
            }
            UiCommand::SetPickerWidth(width) => self.settings.trends.picker_width = Some(width),
            UiCommand::ExportTrends => {
                let view = vm::trends::build(&self.state, &self.settings.trends, TREND_POINTS);
                let path = PathBuf::from(&self.settings.forms.export_path);
                self.export_note = Some(match vm::trends::export_csv(&view, &path) {
                    Ok(rows) => format!("{rows} rows written to {}", path.display()),
                    Err(error) => format!("export failed: {error}"),
                });
            }
            UiCommand::ExportTrendsPng => self.export_png(),
            UiCommand::RestartWarmup => {
                let warmup = &mut self.state.warmup;
                warmup.started_at_s = self.state.latest.time_s();
                warmup.analysis = None;
                warmup.analysis_error = None;
                warmup.signed = None;
                warmup.notice = None;
            }
            UiCommand::AnalyseWarmup => self.start_warmup_analysis(),
            UiCommand::SaveBaseline => {
                let fingerprint = self
                    .state
                    .warmup
                    .analysis
                    .as_ref()
                    .and_then(|a| a.fingerprint.as_ref().ok())
                    .cloned();
                if let Some(fingerprint) = fingerprint {
                    self.send(SessionCommand::SaveBaseline(Box::new(fingerprint)));
                }
            }
            UiCommand::ToolMeasured => {
                // Until the estimators count from the measurement, nothing counted before it
                // may be proposed.
                let spindles: Vec<AxisId> = self.state.elongation_origins.keys().copied().collect();
                for axis in spindles {
                    self.state.elongation_restarted(axis);
                }
                self.send(SessionCommand::ResetToolCalibration);
            }
            UiCommand::SignOffWarmup => self.sign_off_warmup(),
            UiCommand::ComputeDepth => {
                self.state.depth.error = None;
                self.start_depth_of_cut();
            }
            UiCommand::UseProposal(id) => self.use_proposal(&id),
            UiCommand::AddChange => self.add_change(),
            UiCommand::RemoveChange(id) => {
                let mut kept = CompensationValues::new();
                for (k, v) in self.state.compensation.draft_changes.iter() {
                    if k.to_string() != id {
                        kept.set(k, v);
                    }
                }
                self.state.compensation.draft_changes = kept;
            }
            UiCommand::RequestPush => {
                let forms = &self.settings.forms;
                let proposal = Proposal {
                    changes: self.state.compensation.draft_changes.clone(),
                    why: forms.why.trim().to_string(),
                    evidence: forms.evidence.trim().to_string(),
                    action: "adjust".into(),
                };
                self.request(proposal);
            }
            UiCommand::Rollback(request_id) => {
                match rollback_proposal(&self.state.compensation.audit, Some(&request_id)) {
                    Ok(proposal) => self.request(proposal),
                    Err(error) => self.state.compensation.notice = Some(error.to_string()),
                }
            }
            UiCommand::SubmitApproval => self.submit_approval(),
            UiCommand::CancelRequest => {
                if let PushFlow::AwaitingApproval { request, .. } = &self.state.compensation.flow {
                    let request = request.clone();
                    let _ = self.session.send(SessionCommand::Withdraw {
                        request,
                        reason: "withdrawn at the approval dialog".into(),
                    });
                    self.state.compensation.flow = PushFlow::Idle;
                }
                self.settings.forms.password.clear();
            }
            UiCommand::DismissResult => self.state.compensation.flow = PushFlow::Idle,
            UiCommand::Refresh => {
                self.send(SessionCommand::Refresh);
            }
            UiCommand::StartFit => self.start_fit(),
            UiCommand::CancelFit => {
                if let Some(job) = &self.fit_job {
                    job.cancel();
                    if let Some(running) = self.state.model_lab.running.as_mut() {
                        running.stage = format!("cancelling ({})", running.stage);
                    }
                }
            }
            UiCommand::StartDiscrepancy => self.start_discrepancy(),
            UiCommand::ExportDiscrepancyPng => self.export_discrepancy_png(),
            UiCommand::SaveDiscrepancyReport => self.save_discrepancy_report(),
            UiCommand::CancelDiscrepancy => self.cancel_discrepancy(),
            UiCommand::SetRecording(on) => {
                self.send(SessionCommand::SetRecording(on));
            }
            UiCommand::ToggleEventKind(kind) => {
                let hidden = &mut self.settings.events.hidden;
                let label = kind.label().to_string();
                if !hidden.remove(&label) {
                    hidden.insert(label);
                }
            }
            UiCommand::SetProblemsOnly(on) => self.settings.events.problems_only = on,
            UiCommand::ToggleSourceWindow => {
                self.settings.forms.source_window = !self.settings.forms.source_window;
            }
            UiCommand::ConnectController => {
                let forms = &self.settings.forms;
                let line = match (&self.start_config.source, &self.session.config().source) {
                    (SourceSpec::Serial(line), _) | (_, SourceSpec::Serial(line)) => line.clone(),
                    _ => crate::link::ModbusConfig::new(""),
                };
                match parse_connect_form(
                    &line,
                    &forms.connect_device,
                    &forms.connect_baud,
                    &forms.connect_parity,
                    &forms.connect_slave,
                ) {
                    Ok(modbus) => {
                        let profile = ProfileChoice::from_field(&forms.open_profile);
                        self.start_switch(SourceChange::Connect { modbus, profile });
                    }
                    Err(reason) => self.state.source.error = Some(reason),
                }
            }
            UiCommand::OpenRecording => {
                let forms = &self.settings.forms;
                match parse_open_form(
                    &forms.open_recording,
                    forms.open_this_file_only,
                    &forms.open_speed,
                    &forms.open_profile,
                ) {
                    Ok(request) => self.start_switch(SourceChange::Open(request)),
                    Err(reason) => self.state.source.error = Some(reason),
                }
            }
            UiCommand::ReturnToStartSource => self.start_switch(SourceChange::Return),
            UiCommand::CancelSourceChange => self.cancel_switch(),
            UiCommand::SetPaused(paused) => {
                // The pace shown is what the link was asked for, so only once it was asked.
                if self.state.pace.is_some() && self.send(SessionCommand::SetPaused(paused)) {
                    if let Some(pace) = self.state.pace.as_mut() {
                        pace.paused = paused;
                    }
                    let word = if paused { "paused" } else { "resumed" };
                    let text = format!("{} {word}", self.session.source());
                    self.state
                        .events
                        .push(Event::now(EventKind::Link, Severity::Normal, text));
                }
            }
            UiCommand::SetSpeed => match parse_speed(&self.settings.forms.running_speed) {
                Ok(factor) => {
                    let speed = crate::link::ReplaySpeed::Factor(factor);
                    if self.state.pace.is_some() && self.send(SessionCommand::SetSpeed(speed)) {
                        if let Some(pace) = self.state.pace.as_mut() {
                            pace.speed = speed;
                        }
                        self.state.source.error = None;
                        let text =
                            format!("{} runs at {factor} × real time", self.session.source());
                        self.state
                            .events
                            .push(Event::now(EventKind::Link, Severity::Normal, text));
                    }
                }
                Err(reason) => self.state.source.error = Some(reason),
            },
        }
    }

    /// Sends `command` to the session; a refusal goes into the events and gives `false`.
    fn send(&mut self, command: SessionCommand) -> bool {
        match self.session.send(command) {
            Ok(()) => true,
            Err(error) => {
                self.state.events.push(Event::now(
                    EventKind::Link,
                    Severity::Fault,
                    error.to_string(),
                ));
                false
            }
        }
    }

    fn add_change(&mut self) {
        let forms = &self.settings.forms;
        let comp = &mut self.state.compensation;
        let id: CompensationId = match forms.change_id.parse() {
            Ok(id) => id,
            Err(error) => {
                comp.notice = Some(error);
                return;
            }
        };
        let value: f64 = match forms.change_value.trim().replace(',', ".").parse::<f64>() {
            Ok(v) if v.is_finite() => v,
            _ => {
                comp.notice = Some(format!(
                    "`{}` is not a number of micrometres",
                    forms.change_value.trim()
                ));
                return;
            }
        };
        let limit = comp.limits.of(id.kind()).absolute_um;
        if value.abs() > limit {
            comp.notice = Some(format!(
                "{id} = {value} µm is beyond its limit of ±{limit} µm"
            ));
            return;
        }
        comp.notice = None;
        comp.draft_changes.set(id, value);
    }

    fn request(&mut self, proposal: Proposal) {
        let comp = &mut self.state.compensation;
        if self.switch_job.is_some() {
            comp.notice = Some(
                "the source is changing (Source window): request once it has, on the source \
                 that then runs"
                    .into(),
            );
            return;
        }
        let operator = self.settings.forms.operator.trim().to_string();
        if operator.is_empty() {
            comp.notice = Some("enter the operator's name before requesting".into());
            return;
        }
        if !comp.users.iter().any(|(name, _)| *name == operator) {
            comp.notice = Some(format!("`{operator}` is not a user in {}", comp.users_path));
            return;
        }
        if proposal.why.is_empty() {
            comp.notice = Some("say why the change is needed".into());
            return;
        }
        match Request::new(proposal, &operator) {
            Ok(request) => {
                comp.notice = None;
                comp.flow = PushFlow::AwaitingApproval {
                    request,
                    refusal: None,
                };
                self.settings.forms.password.clear();
            }
            Err(error) => comp.notice = Some(error.to_string()),
        }
    }

    fn submit_approval(&mut self) {
        let PushFlow::AwaitingApproval { request, .. } = &self.state.compensation.flow else {
            return;
        };
        if self.switch_job.is_some() {
            self.state.compensation.notice = Some(
                "the source is changing (Source window): approve once it has, or withdraw".into(),
            );
            return;
        }
        let request = request.clone();
        let approver = self.settings.forms.approver.trim().to_string();
        let password = std::mem::take(&mut self.settings.forms.password);
        self.state.compensation.flow = PushFlow::Writing {
            request: request.clone(),
            approver: approver.clone(),
        };
        if let Err(error) = self.session.send(SessionCommand::ApproveAndApply {
            request: request.clone(),
            approver,
            password,
        }) {
            self.state.compensation.flow = PushFlow::AwaitingApproval {
                request,
                refusal: Some(error.to_string()),
            };
        }
    }

    fn start_fit(&mut self) {
        if self.fit_job.is_some() {
            return;
        }
        let forms = &self.settings.forms;
        let request = FitRequest {
            data: PathBuf::from(forms.fit_data.trim()),
            target: forms.fit_target.trim().to_string(),
            terms: forms.fit_terms.trim().to_string(),
        };
        let title = format!("fit of {} on {}", request.target, request.terms);
        match Job::spawn(title.clone(), move |context| run_fit(request, context)) {
            Ok(job) => {
                self.state.model_lab.running = Some(super::state::JobProgress {
                    stage: "starting".into(),
                    fraction: Some(0.0),
                });
                self.state.model_lab.error = None;
                self.state.events.push(Event::now(
                    EventKind::Job,
                    Severity::Normal,
                    format!("{title} started"),
                ));
                self.fit_job = Some(job);
            }
            Err(error) => {
                self.state.model_lab.error = Some(format!("cannot start the fit: {error}"));
            }
        }
    }
}

/// An empty state on `session`'s columns, with the limits and profile it runs with.
fn fresh_state(session: &Session, options: &HmiOptions) -> HmiState {
    let compensation = CompensationState::new(
        options.users_path.display().to_string(),
        options.audit_path.display().to_string(),
        options.limits,
    );
    let mut state = HmiState::new(
        session.schema().names().to_vec(),
        LinkSnapshot::starting(session.source()),
        options.history_budget_bytes,
        compensation,
    );
    state.thresholds = options.thresholds;
    state.profile = session.profile().cloned();
    state.pace = pace_of(&session.config().source);
    state.controller = matches!(session.config().source, SourceSpec::Serial(_))
        .then(|| session.source().to_string());
    state.estimate_limits = session
        .profile()
        .map(crate::profile::MachineProfile::axis_limits)
        .unwrap_or_default();
    state
}

/// Keeps the Trends choices that name one of `names`; with none left it draws the stator
/// temperatures, so the Trends panel is never empty.
fn fit_trends_to(trends: &mut TrendsSettings, names: &[String]) {
    trends.selected.retain(|n| names.contains(n));
    trends.hidden.retain(|n| names.contains(n));
    if trends.selected.is_empty() {
        trends.selected = default_trend_channels(names);
    }
}

/// The stator temperatures among `names`: what the Trends panel draws when nothing chosen is
/// there.
fn default_trend_channels(names: &[String]) -> Vec<String> {
    AxisId::ALL
        .into_iter()
        .map(|a| axis_column(a, Quantity::StatorTemp))
        .filter(|n| names.contains(n))
        .collect()
}

/// Starts drawing `request` into its PNG on a job; returns the job (`None` when it could not
/// start) and the note the operator reads meanwhile.
fn start_png_export(title: &str, request: PngRequest) -> (Option<Job<PngOutcome>>, String) {
    match Job::spawn(title, move |c| {
        super::export_png::run_png_export(request, c)
    }) {
        Ok(job) => (Some(job), "PNG export: drawing…".into()),
        Err(error) => (None, format!("cannot start the export: {error}")),
    }
}

/// Follows a PNG export: the note the operator reads now (its stage, or how it ended), or
/// `None` when nothing changed.
fn poll_png_export(job: &mut Option<Job<PngOutcome>>) -> Option<String> {
    let mut progress = None;
    match poll_job(job, &mut progress) {
        Some(Ok(done)) => Some(format!(
            "{}×{} px PNG written to {}",
            done.size[0],
            done.size[1],
            done.path.display()
        )),
        Some(Err(reason)) => Some(format!("PNG export failed: {reason}")),
        None => progress.map(|p| format!("PNG export: {}", p.stage)),
    }
}

/// Takes a job's waiting messages: progress goes into `running`; when the job ends it is
/// dropped and its result (or why it stopped) returned.
fn poll_job<T: Send + 'static>(
    job: &mut Option<Job<T>>,
    running: &mut Option<super::state::JobProgress>,
) -> Option<Result<T, String>> {
    let current = job.as_ref()?;
    while let Some(message) = current.try_next() {
        let end = match message {
            JobMessage::Progress(progress) => {
                *running = Some(progress);
                continue;
            }
            JobMessage::Done(value) => Ok(value),
            JobMessage::Failed(reason) => Err(reason),
            JobMessage::Cancelled => Err("cancelled".to_string()),
        };
        *running = None;
        *job = None;
        return Some(end);
    }
    None
}

impl eframe::App for HmiApp {
    fn logic(&mut self, ctx: &egui::Context, _frame: &mut eframe::Frame) {
        HmiApp::logic(self, ctx);
    }

    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
        self.show(ui);
    }

    fn on_exit(&mut self, _gl: Option<&eframe::glow::Context>) {
        self.last_save = Instant::now() - SAVE_EVERY;
        self.save_settings();
        // A session ending since a source change, or started by a change still running,
        // finishes its recorder file and saves its estimators' state before the process goes.
        if let Some(job) = self.switch_job.take() {
            job.cancel();
            if let Some(JobMessage::Done(switched)) = job.wait_end(JOB_END_WAIT) {
                drop(switched);
            }
        }
        self.endings.wait();
    }
}
