//! The Warm-up panel: the checklist's steps with their live values, status and reason, the
//! actions each step needs, and the operator's sign-off.

use eframe::egui;

use super::{Forms, UiCommand, labelled_text, severity_color};
use crate::ui::state::Severity;
use crate::ui::vm::warmup::{StepId, StepStatus, WarmupView};

fn status_badge(ui: &mut egui::Ui, status: StepStatus) {
    ui.label(
        egui::RichText::new(status.word())
            .strong()
            .monospace()
            .color(severity_color(status.severity())),
    );
}

/// Draws the Warm-up panel.
pub fn warmup_ui(
    ui: &mut egui::Ui,
    view: &WarmupView,
    forms: &mut Forms,
    commands: &mut Vec<UiCommand>,
) {
    egui::ScrollArea::vertical().show(ui, |ui| {
        ui.horizontal_wrapped(|ui| {
            ui.heading("Shift-start warm-up checklist");
            ui.separator();
            status_badge(ui, view.verdict);
            ui.label(&view.verdict_text);
        });
        ui.horizontal_wrapped(|ui| {
            ui.weak(format!(
                "Analyses use the samples from {} on{}.",
                view.started_at,
                view.axis
                    .as_ref()
                    .map(|a| format!(" (feed axis {a})"))
                    .unwrap_or_default()
            ));
            if ui.button("Restart checklist").clicked() {
                commands.push(UiCommand::RestartWarmup);
            }
        });
        for step in &view.steps {
            ui.separator();
            ui.horizontal(|ui| {
                status_badge(ui, step.status);
                ui.label(egui::RichText::new(&step.title).strong().size(16.0));
            });
            ui.weak(&step.instruction);
            ui.label(&step.reason);
            if !step.values.is_empty() {
                egui::Grid::new(("step values", step.title.as_str()))
                    .num_columns(3)
                    .spacing([12.0, 2.0])
                    .show(ui, |ui| {
                        for v in &step.values {
                            ui.label(&v.label);
                            ui.monospace(&v.value);
                            ui.label(&v.unit);
                            ui.end_row();
                        }
                    });
            }
            ui.horizontal(|ui| match step.id {
                StepId::FrictionFingerprint => {
                    let running = view.running.is_some();
                    if ui
                        .add_enabled(!running, egui::Button::new("Analyse warm-up moves"))
                        .clicked()
                    {
                        commands.push(UiCommand::AnalyseWarmup);
                    }
                    if ui
                        .add_enabled(
                            view.can_save_baseline,
                            egui::Button::new("Save as baseline"),
                        )
                        .on_hover_text("Only on a machine known to be healthy")
                        .clicked()
                    {
                        commands.push(UiCommand::SaveBaseline);
                    }
                    if let Some(progress) = &view.running {
                        ui.add(
                            egui::ProgressBar::new(progress.fraction.unwrap_or(0.0))
                                .desired_width(200.0)
                                .text(&progress.stage),
                        );
                    }
                }
                StepId::ElongationCompensated => {
                    if ui.button("Tool measured").clicked() {
                        commands.push(UiCommand::ToolMeasured);
                    }
                    if ui.button("Open compensation proposals").clicked() {
                        commands.push(UiCommand::SelectTab(super::Tab::Compensation));
                    }
                }
                _ => {}
            });
        }
        if let Some(note) = &view.analysis_note {
            ui.weak(format!("Last analysis: {note}"));
        }
        ui.separator();
        ui.heading("Sign-off");
        ui.horizontal_wrapped(|ui| {
            labelled_text(ui, "Signed off by", &mut forms.checklist_operator, 200.0);
            let enabled = view.sign_off_blocked.is_none();
            if ui
                .add_enabled(enabled, egui::Button::new("Sign off and save report"))
                .clicked()
            {
                commands.push(UiCommand::SignOffWarmup);
            }
            if let Some(reason) = &view.sign_off_blocked {
                ui.weak(reason);
            }
        });
        if let Some(notice) = &view.notice {
            ui.colored_label(severity_color(Severity::Fault), notice);
        }
        if let Some(saved) = &view.signed {
            ui.colored_label(
                severity_color(Severity::Normal),
                format!(
                    "Signed off by {} at {} UTC; report saved: {} and {}",
                    saved.operator, saved.time_utc, saved.json_path, saved.text_path
                ),
            );
        }
    });
}
