//! The *Source* window: the running source (with pause and speed for a replay or the twin), a
//! recording or a controller to run in its place, and the way back to the source the HMI was
//! started on.

use eframe::egui;

use super::{Forms, UiCommand, error_line, labelled_text, progress_row};
use crate::ui::vm::source::SourceView;

/// Draws the window while `forms.source_window` is set (its close button clears it).
pub fn source_ui(
    ctx: &egui::Context,
    view: &SourceView,
    forms: &mut Forms,
    commands: &mut Vec<UiCommand>,
) {
    let mut open = forms.source_window;
    egui::Window::new("Source")
        .open(&mut open)
        .resizable(false)
        .default_width(560.0)
        .show(ctx, |ui| {
            ui.label(format!("Running: {}", view.current));
            if let Some(change) = &view.last_change {
                ui.small(change);
            }
            if let Some(pace) = &view.pace {
                ui.horizontal(|ui| {
                    let (label, paused) = if pace.paused {
                        ("Resume", false)
                    } else {
                        ("Pause", true)
                    };
                    if ui.button(label).clicked() {
                        commands.push(UiCommand::SetPaused(paused));
                    }
                    labelled_text(
                        ui,
                        "Running speed (× real time)",
                        &mut forms.running_speed,
                        70.0,
                    );
                    if ui.button("Set speed").clicked() {
                        commands.push(UiCommand::SetSpeed);
                    }
                    ui.small(format!("now {}", pace.text));
                });
            }
            ui.separator();
            ui.label(
                "Another source runs in place of this one, on the same users and audit log; \
                 the readings, trends, checklist and depth of cut start afresh on it.",
            );
            super::form_grid("source profile", ui, |ui| {
                labelled_text(ui, "Machine profile (TOML)", &mut forms.open_profile, 380.0);
                ui.end_row();
                ui.label("");
                ui.small(&view.profile_hint);
                ui.end_row();
            });
            if let Some(warning) = &view.leaves_controller {
                super::warning_line(ui, warning);
                ui.checkbox(
                    &mut forms.open_leave_controller,
                    "stop monitoring the controller",
                );
            }
            if let Some(reason) = &view.refused {
                super::warning_line(ui, reason);
            }
            ui.add_space(4.0);
            ui.strong("A recording");
            ui.small(
                "The pieces the recorder continued it in (NAME-0001.csv, … beside it) follow \
                 it. It is not recorded again.",
            );
            super::form_grid("open recording form", ui, |ui| {
                labelled_text(ui, "Recording (CSV)", &mut forms.open_recording, 380.0);
                ui.end_row();
                ui.label("");
                ui.checkbox(&mut forms.open_this_file_only, "this file only");
                ui.end_row();
                labelled_text(ui, "Speed (× real time)", &mut forms.open_speed, 80.0);
                ui.end_row();
            });
            change_button(ui, view, "Open", UiCommand::OpenRecording, commands);
            ui.add_space(4.0);
            ui.strong("A controller (Modbus RTU)");
            ui.small(format!(
                "Recorded where the HMI records the machine. Profile {}. It must answer within \
                 {} s, or the running source stays.",
                view.controller_profile_hint,
                crate::ui::source::ANSWER_WAIT.as_secs()
            ));
            super::form_grid("connect controller form", ui, |ui| {
                labelled_text(ui, "Serial device", &mut forms.connect_device, 240.0);
                ui.end_row();
                labelled_text(ui, "Baud", &mut forms.connect_baud, 80.0);
                ui.end_row();
                labelled_text(
                    ui,
                    "Parity (none, even, odd)",
                    &mut forms.connect_parity,
                    80.0,
                );
                ui.end_row();
                labelled_text(ui, "Slave id", &mut forms.connect_slave, 80.0);
                ui.end_row();
            });
            change_button(ui, view, "Connect", UiCommand::ConnectController, commands);
            if let Some(progress) = &view.running {
                ui.separator();
                progress_row(ui, progress, UiCommand::CancelSourceChange, commands);
            }
            error_line(ui, view.error.as_ref());
            if let Some(label) = &view.return_label {
                ui.separator();
                change_button(ui, view, label, UiCommand::ReturnToStartSource, commands);
            }
        });
    if open != forms.source_window {
        commands.push(UiCommand::ToggleSourceWindow);
    }
}

/// A button that starts a change: off while one may not start (the reason is shown once,
/// above) or one is running (its progress is shown once, below).
fn change_button(
    ui: &mut egui::Ui,
    view: &SourceView,
    label: &str,
    command: UiCommand,
    commands: &mut Vec<UiCommand>,
) {
    let enabled = view.refused.is_none() && view.running.is_none();
    if ui.add_enabled(enabled, egui::Button::new(label)).clicked() {
        commands.push(command);
    }
}
