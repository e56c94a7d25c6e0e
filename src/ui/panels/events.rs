//! The Events panel.

use eframe::egui;

use super::{Forms, UiCommand, labelled_text, severity_color, severity_word};
use crate::ui::vm::events::EventsView;

/// Draws the Events panel.
pub fn events_ui(
    ui: &mut egui::Ui,
    view: &EventsView,
    forms: &mut Forms,
    commands: &mut Vec<UiCommand>,
) {
    ui.horizontal_wrapped(|ui| {
        ui.label("Show:");
        for choice in &view.kinds {
            let mut shown = choice.shown;
            if ui
                .checkbox(&mut shown, format!("{} ({})", choice.label, choice.count))
                .changed()
            {
                commands.push(UiCommand::ToggleEventKind(choice.kind));
            }
        }
        ui.separator();
        let mut problems = view.problems_only;
        if ui
            .checkbox(&mut problems, "warnings and faults only")
            .changed()
        {
            commands.push(UiCommand::SetProblemsOnly(problems));
        }
        ui.separator();
        labelled_text(ui, "Containing", &mut forms.event_text, 180.0);
    });
    ui.weak(&view.summary);
    ui.separator();
    egui::ScrollArea::vertical().show(ui, |ui| {
        egui::Grid::new("events")
            .striped(true)
            .num_columns(4)
            .spacing([12.0, 4.0])
            .show(ui, |ui| {
                for row in &view.rows {
                    ui.monospace(&row.time_utc);
                    ui.label(crate::ui::state::EventKind::label(row.kind));
                    ui.colored_label(severity_color(row.severity), severity_word(row.severity));
                    ui.label(&row.message);
                    ui.end_row();
                }
            });
    });
}
