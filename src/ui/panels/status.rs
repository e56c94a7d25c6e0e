//! The status bar.

use eframe::egui;

use super::{UiCommand, light};
use crate::ui::state::RecorderState;
use crate::ui::vm::status::StatusView;

/// Draws the status bar.
pub fn status_ui(ui: &mut egui::Ui, view: &StatusView, commands: &mut Vec<UiCommand>) {
    ui.horizontal_wrapped(|ui| {
        ui.label(egui::RichText::new("Link").strong());
        light(ui, view.link_severity, 14.0);
        ui.label(&view.link_text).on_hover_text(&view.link_detail);
        ui.separator();
        ui.label(egui::RichText::new("Recorder").strong());
        light(ui, view.recorder_severity, 14.0);
        ui.label(&view.recorder_text);
        let recording = view.recorder_state == RecorderState::Recording;
        let label = if recording {
            "Stop recording"
        } else {
            "Start recording"
        };
        if ui.button(label).clicked() {
            commands.push(UiCommand::SetRecording(!recording));
        }
        ui.separator();
        ui.label(&view.machine_time);
        if let Some(away) = &view.away_from_start {
            ui.separator();
            super::warning_line(ui, away);
        }
        if let Some(missed) = &view.frames_not_shown {
            ui.separator();
            super::warning_line(ui, missed);
        }
    });
    ui.small(&view.link_detail);
}
