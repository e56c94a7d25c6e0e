//! Drawing: each `*_ui` function draws one view model and returns the operator's actions as
//! [`UiCommand`]s; none of them changes shared state. Text being typed lives in [`Forms`].

pub mod compensation;
pub mod depth;
pub mod events;
pub mod model_lab;
pub mod overview;
pub mod source;
pub mod status;
pub mod trends;
pub mod warmup;

use eframe::egui;
use serde::{Deserialize, Serialize};

use super::state::{EventKind, Severity};
use super::vm::trends::WindowPreset;

/// The panels.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Tab {
    /// Axis cards.
    Overview,
    /// The shift-start warm-up checklist.
    Warmup,
    /// Time series.
    Trends,
    /// The maximum rough-cut depth.
    DepthOfCut,
    /// Controller values, approval, audit.
    Compensation,
    /// Fitting models.
    ModelLab,
    /// The event list.
    Events,
}

impl Tab {
    /// Every tab, in the order of the tab bar.
    pub const ALL: [Tab; 7] = [
        Tab::Overview,
        Tab::Warmup,
        Tab::Trends,
        Tab::DepthOfCut,
        Tab::Compensation,
        Tab::ModelLab,
        Tab::Events,
    ];

    /// The tab's label.
    pub fn label(self) -> &'static str {
        match self {
            Tab::Overview => "Overview",
            Tab::Warmup => "Warm-up",
            Tab::Trends => "Trends",
            Tab::DepthOfCut => "Depth of cut",
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
    /// A series was switched off (true) or on in its plot's legend (by column name).
    SetSeriesHidden(String, bool),
    /// A group of the channel picker was unfolded (true) or folded (by title).
    SetGroupOpen(String, bool),
    /// The channel picker was resized to this width, points.
    SetPickerWidth(f32),
    /// Write what the Trends panel shows to the export path.
    ExportTrends,
    /// Draw what the Trends panel shows into the PNG file.
    ExportTrendsPng,
    /// Start the warm-up checklist afresh: the analyses take samples from now on.
    RestartWarmup,
    /// Analyse the warm-up moves (friction fingerprint, backlash) since the checklist started.
    AnalyseWarmup,
    /// Keep the analysed fingerprint as the axis's healthy baseline.
    SaveBaseline,
    /// The operator measured the tool: count spindle elongation from zero.
    ToolMeasured,
    /// The operator signs the checklist off (name in the form); the report is saved.
    SignOffWarmup,
    /// Compute the depth-of-cut recommendation from the session's cuts.
    ComputeDepth,
    /// Put an estimate-based proposal (by compensation id) into the draft.
    UseProposal(String),
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
    /// Start the sim-vs-real analysis in the Model lab form.
    StartDiscrepancy,
    /// Draw the last sim-vs-real analysis into the Model lab's PNG file.
    ExportDiscrepancyPng,
    /// Save the last sim-vs-real analysis's report (JSON and text) to the Model lab's file.
    SaveDiscrepancyReport,
    /// Cancel the running sim-vs-real analysis (the panel is free at once).
    CancelDiscrepancy,
    /// Switch the recorder on or off.
    SetRecording(bool),
    /// Show or hide a kind of event.
    ToggleEventKind(EventKind),
    /// Show only warnings and faults.
    SetProblemsOnly(bool),
    /// Show or hide the *Source* window.
    ToggleSourceWindow,
    /// Open the recording in the *Source* window's form in place of the running source.
    OpenRecording,
    /// Connect to the controller in the *Source* window's form in place of the running source.
    ConnectController,
    /// Go back to the source the HMI was started on.
    ReturnToStartSource,
    /// Stop opening a source (the running one stays).
    CancelSourceChange,
    /// Pause (true) or resume the running replay or twin.
    SetPaused(bool),
    /// Run the replay or twin at the speed in the *Source* window's form.
    SetSpeed,
}

/// The Model lab's sections.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum LabSection {
    /// Fit a model from a database.
    #[default]
    Fit,
    /// Sim-vs-real discrepancy of two recordings.
    Discrepancy,
}

/// Text the operator is typing (UI-local widget state, never shared). Fields missing from a
/// settings file written by an older version take their defaults.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
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
    /// Where the Trends PNG export goes.
    pub png_path: String,
    /// Who signs the warm-up checklist off.
    pub checklist_operator: String,
    /// Diameter being turned for the depth-of-cut recommendation, mm.
    pub workpiece_diameter_mm: String,
    /// The Model lab's database.
    pub fit_data: String,
    /// The Model lab's target column.
    pub fit_target: String,
    /// The Model lab's terms.
    pub fit_terms: String,
    /// The Model lab's open section.
    pub lab_section: LabSection,
    /// The sim-vs-real simulation file.
    pub disc_sim: String,
    /// The sim-vs-real real recording.
    pub disc_real: String,
    /// Read only the chosen real file, not the pieces the recorder continued it in.
    pub disc_real_this_file_only: bool,
    /// The sim-vs-real compared column.
    pub disc_target: String,
    /// The sim-vs-real blocks of time (seconds) both recordings are averaged over; blank
    /// reads them at their own rate.
    pub disc_average_s: String,
    /// Where the sim-vs-real PNG export goes.
    pub disc_png_path: String,
    /// Where the sim-vs-real report's JSON goes (its text beside it).
    pub disc_report_path: String,
    /// The Events panel's text filter.
    #[serde(skip)]
    pub event_text: String,
    /// The recording the *Source* window opens.
    pub open_recording: String,
    /// Open only that file, not the pieces the recorder continued it in.
    pub open_this_file_only: bool,
    /// Its replay speed, × real time (blank: real time).
    pub open_speed: String,
    /// The machine profile a recording's or controller's estimators run with (blank: the
    /// running session's).
    pub open_profile: String,
    /// The serial device of a controller to connect to.
    pub connect_device: String,
    /// Its baud rate (blank: 115200).
    pub connect_baud: String,
    /// Its parity: none, even or odd (blank: none).
    pub connect_parity: String,
    /// Its Modbus slave id (blank: 1).
    pub connect_slave: String,
    /// Whether the *Source* window is shown.
    #[serde(skip)]
    pub source_window: bool,
    /// The speed the running replay or twin is to run at, × real time.
    #[serde(skip)]
    pub running_speed: String,
    /// The operator confirmed that opening a recording stops monitoring the controller.
    #[serde(skip)]
    pub open_leave_controller: bool,
}

/// `plot` with its value axis on steps of 1, 2 and 5 × 10ⁿ, labelled with as many decimals
/// as the step needs. egui_plot's default grid steps by powers of ten only, so a plot whose
/// range spans a few tenths (a residual at the noise floor, ±0.05 °C on 190 points of
/// height) puts its hundredths 20 points apart, too close for a label, and shows no value but
/// "0" on its axis.
pub fn readable_value_axis(plot: egui_plot::Plot<'_>) -> egui_plot::Plot<'_> {
    plot.y_grid_spacer(egui_plot::uniform_grid_spacer(|input| {
        grid_steps(input.base_step_size)
    }))
    .y_axis_formatter(|mark, _| tick_label(mark.value, mark.step_size))
}

/// The value axis's three grid levels from the finest step the plot can show: each a 1, 2 or
/// 5 × 10ⁿ step and a whole multiple of the one below (1 → 2 → 10, 2 → 10 → 20,
/// 5 → 10 → 20), so every coarser line is also a finer one. Levels that do not nest (2 and 5)
/// put labels of both on the axis, 24 and 25 a step apart.
fn grid_steps(base_step: f64) -> [f64; 3] {
    let finest = nice_step_at_least(base_step);
    let coarser = |step: f64| {
        let decade = 10f64.powf(step.log10().floor());
        let leading = (step / decade).round();
        if leading == 2.0 {
            5.0 * step
        } else {
            2.0 * step
        }
    };
    let middle = coarser(finest);
    [finest, middle, coarser(middle)]
}

/// The smallest of 1, 2 and 5 × 10ⁿ that is at least `step` (1 for a step that is not a
/// positive number).
fn nice_step_at_least(step: f64) -> f64 {
    if !(step.is_finite() && step > 0.0) {
        return 1.0;
    }
    let decade = 10f64.powf(step.log10().floor());
    [1.0, 2.0, 5.0, 10.0]
        .into_iter()
        .map(|m| m * decade)
        .find(|candidate| *candidate >= step * (1.0 - 1e-9))
        .unwrap_or(10.0 * decade)
}

/// A tick's value with the decimals its step needs (0.05 → 2, 0.5 → 1, 5 → 0).
fn tick_label(value: f64, step: f64) -> String {
    let decimals = if step > 0.0 {
        (-step.log10() - 1e-9).ceil().clamp(0.0, 12.0) as usize
    } else {
        0
    };
    // -0.00 reads as a sign error on an axis.
    let value = if value.abs() < 0.5 * step { 0.0 } else { value };
    format!("{value:.decimals$}")
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

/// A form's fields: a label and its input per row, laid out alike in every panel.
pub(super) fn form_grid<R>(
    id: &str,
    ui: &mut egui::Ui,
    add_rows: impl FnOnce(&mut egui::Ui) -> R,
) -> egui::InnerResponse<R> {
    egui::Grid::new(id)
        .num_columns(2)
        .spacing([8.0, 6.0])
        .show(ui, add_rows)
}

/// A job's progress bar with its Cancel button, or the start button.
pub(super) fn job_row(
    ui: &mut egui::Ui,
    running: Option<&super::state::JobProgress>,
    start: (&str, UiCommand),
    cancel: UiCommand,
    commands: &mut Vec<UiCommand>,
) {
    match running {
        Some(progress) => progress_row(ui, progress, cancel, commands),
        None => {
            if ui.button(start.0).clicked() {
                commands.push(start.1);
            }
        }
    }
}

/// A running job's progress bar with its Cancel button.
pub(super) fn progress_row(
    ui: &mut egui::Ui,
    progress: &super::state::JobProgress,
    cancel: UiCommand,
    commands: &mut Vec<UiCommand>,
) {
    ui.horizontal(|ui| {
        let bar = egui::ProgressBar::new(progress.fraction.unwrap_or(0.0))
            .text(&progress.stage)
            .desired_width(420.0)
            .animate(true);
        ui.add(bar);
        if ui.button("Cancel").clicked() {
            commands.push(cancel);
        }
    });
}

/// Something the operator should heed before acting, in the warning colour.
pub(super) fn warning_line(ui: &mut egui::Ui, text: &str) {
    ui.colored_label(severity_color(Severity::Warning), text);
}

/// A failed job's reason, in the fault colour.
pub(super) fn error_line(ui: &mut egui::Ui, error: Option<&String>) {
    if let Some(error) = error {
        ui.colored_label(severity_color(Severity::Fault), error);
    }
}

#[cfg(test)]
mod tests {
    use super::{grid_steps, nice_step_at_least, tick_label};

    #[test]
    fn value_axis_steps_are_one_two_five_nest_and_are_labelled_to_their_decimals() {
        let steps: Vec<f64> = [0.0042, 0.0075, 0.015, 0.2, 0.21, 3.0, 7.0, 1.0]
            .into_iter()
            .map(nice_step_at_least)
            .collect();
        let expected = [0.005, 0.01, 0.02, 0.2, 0.5, 5.0, 10.0, 1.0];
        for (got, want) in steps.iter().zip(expected) {
            assert!((got - want).abs() < 1e-12 * want, "{got} vs {want}");
        }
        assert_eq!(nice_step_at_least(f64::NAN), 1.0);
        for (base, want) in [
            (0.9, [1.0, 2.0, 10.0]),
            (0.015, [0.02, 0.1, 0.2]),
            (3.0, [5.0, 10.0, 20.0]),
        ] {
            let got = grid_steps(base);
            for (g, w) in got.iter().zip(want) {
                assert!((g - w).abs() < 1e-12 * w, "{base}: {got:?} vs {want:?}");
            }
        }
        // Every coarser level lies on the finer one's lines, whatever the plot's scale.
        for k in -40..40 {
            let steps = grid_steps(1.37_f64.powi(k));
            for pair in steps.windows(2) {
                let ratio = pair[1] / pair[0];
                assert!((ratio - ratio.round()).abs() < 1e-9, "{steps:?}");
            }
        }
        assert_eq!(tick_label(0.04, 0.02), "0.04");
        assert_eq!(tick_label(-0.05, 0.05), "-0.05");
        assert_eq!(tick_label(0.5, 0.5), "0.5");
        assert_eq!(tick_label(-3.0, 1.0), "-3");
        assert_eq!(tick_label(40.0, 10.0), "40");
        assert_eq!(tick_label(-1e-18, 0.01), "0.00");
    }
}
