//! The Model lab panel.

use eframe::egui;

use super::{Forms, UiCommand, labelled_text};
use crate::ui::vm::model_lab::ModelLabView;

/// Draws the Model lab.
pub fn model_lab_ui(
    ui: &mut egui::Ui,
    view: &ModelLabView,
    forms: &mut Forms,
    commands: &mut Vec<UiCommand>,
) {
    ui.heading("Fit a model from a database");
    ui.label(
        "Multiple regression with the F-test, R² and a sensitivity ranking, as \
         `servosight fit` computes it. Terms: a, a^2, a*b, lag(a,SECONDS), lowpass(a,TAU), delta(a).",
    );
    egui::Grid::new("fit form")
        .num_columns(2)
        .spacing([8.0, 6.0])
        .show(ui, |ui| {
            labelled_text(ui, "Database (CSV v1)", &mut forms.fit_data, 420.0);
            ui.end_row();
            labelled_text(ui, "Target column", &mut forms.fit_target, 420.0);
            ui.end_row();
            labelled_text(ui, "Terms", &mut forms.fit_terms, 420.0);
            ui.end_row();
        });
    ui.horizontal(|ui| match &view.running {
        Some(progress) => {
            let bar = egui::ProgressBar::new(progress.fraction.unwrap_or(0.0))
                .text(&progress.stage)
                .desired_width(360.0)
                .animate(true);
            ui.add(bar);
            if ui.button("Cancel").clicked() {
                commands.push(UiCommand::CancelFit);
            }
        }
        None => {
            if ui.button("Fit").clicked() {
                commands.push(UiCommand::StartFit);
            }
        }
    });
    if let Some(error) = &view.error {
        ui.colored_label(
            super::severity_color(crate::ui::state::Severity::Fault),
            error,
        );
    }
    let Some(fit) = &view.result else {
        return;
    };
    ui.separator();
    ui.label(egui::RichText::new(format!("{} from {}", fit.target, fit.data)).strong());
    ui.label(&fit.summary);
    egui::ScrollArea::vertical().show(ui, |ui| {
        ui.heading("Sensitivity ranking");
        egui::Grid::new("sensitivity")
            .striped(true)
            .num_columns(5)
            .show(ui, |ui| {
                for header in ["rank", "term", "partial R²", "standardised", ""] {
                    ui.label(egui::RichText::new(header).strong());
                }
                ui.end_row();
                for row in &fit.sensitivity {
                    ui.label(row.rank.to_string());
                    ui.monospace(&row.term);
                    ui.monospace(&row.partial_r2);
                    ui.monospace(&row.standardized);
                    ui.add(egui::ProgressBar::new(row.bar).desired_width(160.0));
                    ui.end_row();
                }
            });
        ui.heading("Coefficients");
        egui::Grid::new("coefficients")
            .striped(true)
            .num_columns(6)
            .show(ui, |ui| {
                for header in ["term", "estimate", "std. error", "t", "p", "95 % interval"] {
                    ui.label(egui::RichText::new(header).strong());
                }
                ui.end_row();
                for row in &fit.coefficients {
                    ui.monospace(&row.term);
                    ui.monospace(&row.estimate);
                    ui.monospace(&row.std_error);
                    ui.monospace(&row.t);
                    ui.monospace(&row.p_value);
                    ui.monospace(&row.interval);
                    ui.end_row();
                }
            });
    });
}
