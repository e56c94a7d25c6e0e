//! Drawing: each `*_ui` function draws one view model and returns the operator's actions as
//! [`UiCommand`]s; none of them changes shared state. Text being typed lives in [`Forms`].

pub mod compensation;
pub mod events;
pub mod model_lab;
pub mod overview;
pub mod status;
pub mod trends;

use eframe::egui;
use serde::{Deserialize, Serialize};

use super::state::{EventKind, Severity};
use super::vm::trends::WindowPreset;

/// The panels.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Tab {
    /// Axis cards.
    Overview,
    /// Time series.
    Trends,
    /// Controller values, approval, audit.
    Compensation,
    /// Fitting models.
    ModelLab,
    /// The event list.
    Events,
}

impl Tab {
    /// Every tab, in the order of the tab bar.
    pub const ALL: [Tab; 5] = [
        Tab::Overview,
        Tab::Trends,
        Tab::Compensation,
        Tab::ModelLab,
        Tab::Events,
    ];

    /// The tab's label.
    pub fn label(self) -> &'static str {
        match self {
            Tab::Overview => "Overview",
            Tab::Trends => "Trends",
            Tab::Compensation => "Compensation",
            Tab::ModelLab => "Model lab",
            Tab::Events => "Events",
        }
    }
}

/// What the operator did.
#[derive(Debug, Clone, PartialEq)]
pub enum UiCommand {
    /// Open a tab.
    SelectTab(Tab),
    /// Dark (true) or light theme.
    SetDark(bool),
    /// Draw or stop drawing a channel.
    ToggleChannel(String),
    /// Choose a window preset (and follow live).
    SetPreset(WindowPreset),
    /// Follow the newest sample again.
    FollowLive,
    /// The operator zoomed or panned the plots to this time range.
    SetView(f64, f64),
    /// Write what the Trends panel shows to the export path.
    ExportTrends,
    /// Add the change in the proposal form to the draft.
    AddChange,
    /// Remove a change from the draft.
    RemoveChange(String),
    /// The operator requests a push of the draft.
    RequestPush,
    /// The approver submits their credential.
    SubmitApproval,
    /// Withdraw the pending request.
    CancelRequest,
    /// Close the finished push's result.
    DismissResult,
    /// Request a rollback of an applied push.
    Rollback(String),
    /// Read the controller, audit log and users again.
    Refresh,
    /// Start the fit in the Model lab form.
    StartFit,
    /// Cancel the running fit.
    CancelFit,
    /// Switch the recorder on or off.
    SetRecording(bool),
    /// Show or hide a kind of event.
    ToggleEventKind(EventKind),
    /// Show only warnings and faults.
    SetProblemsOnly(bool),
}

/// Text the operator is typing (UI-local widget state, never shared).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Forms {
    /// The compensation id of the change being added.
    pub change_id: String,
    /// Its new value, µm.
    pub change_value: String,
    /// Why the proposal is made.
    pub why: String,
    /// What supports it.
    pub evidence: String,
    /// Who requests.
    pub operator: String,
    /// Who approves.
    #[serde(skip)]
    pub approver: String,
    /// The approver's password (never persisted).
    #[serde(skip)]
    pub password: String,
    /// Where Trends exports go.
    pub export_path: String,
    /// The Model lab's database.
    pub fit_data: String,
    /// The Model lab's target column.
    pub fit_target: String,
    /// The Model lab's terms.
    pub fit_terms: String,
    /// The Events panel's text filter.
    #[serde(skip)]
    pub event_text: String,
}

/// The colour of a severity.
pub fn severity_color(severity: Severity) -> egui::Color32 {
    match severity {
        Severity::Normal => egui::Color32::from_rgb(0x2e, 0xa0, 0x43),
        Severity::Warning => egui::Color32::from_rgb(0xe0, 0x9a, 0x00),
        Severity::Fault => egui::Color32::from_rgb(0xd0, 0x30, 0x30),
    }
}

/// The word for a severity.
pub fn severity_word(severity: Severity) -> &'static str {
    match severity {
        Severity::Normal => "NORMAL",
        Severity::Warning => "WARNING",
        Severity::Fault => "FAULT",
    }
}

/// A round light with its word beside it.
pub fn light(ui: &mut egui::Ui, severity: Severity, size: f32) {
    let (rect, _) = ui.allocate_exact_size(egui::vec2(size, size), egui::Sense::hover());
    ui.painter()
        .circle_filled(rect.center(), size * 0.45, severity_color(severity));
    ui.label(
        egui::RichText::new(severity_word(severity))
            .strong()
            .color(severity_color(severity)),
    );
}

/// A single-line text field with a label that names it (for screen readers and tests).
pub fn labelled_text(
    ui: &mut egui::Ui,
    label: &str,
    text: &mut String,
    width: f32,
) -> egui::Response {
    let label = ui.label(label);
    ui.add(egui::TextEdit::singleline(text).desired_width(width))
        .labelled_by(label.id)
}
