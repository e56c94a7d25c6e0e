//! The application: drains the session under a time budget in `logic`, builds the view model
//! of the open panel, draws it, and carries out the commands the drawing returned.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use eframe::egui;
use serde::{Deserialize, Serialize};

use super::jobs::{FitOutcome, FitRequest, Job, JobMessage, run_fit};
use super::panels::{self, Forms, Tab, UiCommand};
use super::session::{Session, SessionCommand};
use super::state::{
    CompensationState, Event, EventKind, HmiState, LinkSnapshot, PushFlow, Severity,
    StatusThresholds,
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
    /// Limits of the estimates per axis (from the machine profile).
    pub estimate_limits: std::collections::BTreeMap<AxisId, crate::profile::AxisLimits>,
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
    export_note: Option<String>,
    ingest_budget: Duration,
    applied_theme: Option<bool>,
}

impl HmiApp {
    /// The app on a running session.
    pub fn new(session: Session, options: HmiOptions) -> HmiApp {
        let names = session.schema().names().to_vec();
        let compensation = CompensationState::new(
            options.users_path.display().to_string(),
            options.audit_path.display().to_string(),
            options.limits,
        );
        let mut state = HmiState::new(
            names.clone(),
            LinkSnapshot::starting(session.source()),
            options.history_budget_bytes,
            compensation,
        );
        state.thresholds = options.thresholds;
        state.estimate_limits = options.estimate_limits;
        let mut settings = options
            .settings_path
            .as_deref()
            .map(Settings::load)
            .unwrap_or_default();
        // A first start draws the stator temperatures, so the Trends panel is never empty.
        settings.trends.selected.retain(|n| names.contains(n));
        if settings.trends.selected.is_empty() {
            settings.trends.selected = AxisId::ALL
                .into_iter()
                .map(|a| axis_column(a, Quantity::StatorTemp))
                .filter(|n| names.contains(n))
                .collect();
        }
        if settings.forms.export_path.is_empty() {
            settings.forms.export_path = std::env::temp_dir()
                .join("servosight-trends.csv")
                .display()
                .to_string();
        }
        HmiApp {
            session,
            state,
            saved_settings: settings.clone(),
            settings,
            settings_path: options.settings_path,
            last_save: Instant::now(),
            fit_job: None,
            export_note: None,
            ingest_budget: options.ingest_budget,
            applied_theme: None,
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
        if self.last_save.elapsed() >= SAVE_EVERY {
            self.save_settings();
        }
        // Live data: about 30 frames per second keeps sample-to-screen latency near 35 ms
        // without spinning the CPU; a quiet link needs only a slow refresh of its ages.
        let live = self.state.link.state == crate::link::ConnectionState::Connected
            || self.fit_job.is_some();
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
            });
        });
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
                let view = vm::model_lab::build(&self.state);
                egui::CentralPanel::default().show(ui, |ui| {
                    panels::model_lab::model_lab_ui(ui, &view, forms, &mut commands);
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
            UiCommand::ExportTrends => {
                let view = vm::trends::build(&self.state, &self.settings.trends, TREND_POINTS);
                let path = PathBuf::from(&self.settings.forms.export_path);
                self.export_note = Some(match vm::trends::export_csv(&view, &path) {
                    Ok(rows) => format!("{rows} rows written to {}", path.display()),
                    Err(error) => format!("export failed: {error}"),
                });
            }
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
            UiCommand::Refresh => self.send(SessionCommand::Refresh),
            UiCommand::StartFit => self.start_fit(),
            UiCommand::CancelFit => {
                if let Some(job) = &self.fit_job {
                    job.cancel();
                    if let Some(running) = self.state.model_lab.running.as_mut() {
                        running.stage = format!("cancelling ({})", running.stage);
                    }
                }
            }
            UiCommand::SetRecording(on) => self.send(SessionCommand::SetRecording(on)),
            UiCommand::ToggleEventKind(kind) => {
                let hidden = &mut self.settings.events.hidden;
                let label = kind.label().to_string();
                if !hidden.remove(&label) {
                    hidden.insert(label);
                }
            }
            UiCommand::SetProblemsOnly(on) => self.settings.events.problems_only = on,
        }
    }

    fn send(&mut self, command: SessionCommand) {
        if let Err(error) = self.session.send(command) {
            self.state.events.push(Event::now(
                EventKind::Link,
                Severity::Fault,
                error.to_string(),
            ));
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
    }
}
