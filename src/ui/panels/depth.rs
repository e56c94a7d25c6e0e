//! The Depth-of-cut panel: the recommendation, the limiting component, a margin bar per
//! component and the derivation.

use eframe::egui;

use super::{Forms, UiCommand, labelled_text, severity_color};
use crate::ui::state::Severity;
use crate::ui::vm::depth::DepthView;

/// Draws the Depth-of-cut panel.
pub fn depth_ui(
    ui: &mut egui::Ui,
    view: &DepthView,
    forms: &mut Forms,
    commands: &mut Vec<UiCommand>,
) {
    egui::ScrollArea::vertical().show(ui, |ui| {
        ui.heading("Maximum rough-cut depth");
        ui.horizontal_wrapped(|ui| {
            labelled_text(
                ui,
                "Workpiece diameter [mm]",
                &mut forms.workpiece_diameter_mm,
                70.0,
            );
            let running = view.running.is_some();
            if ui
                .add_enabled(
                    !running,
                    egui::Button::new("Recalculate from the session's cuts"),
                )
                .clicked()
            {
                commands.push(UiCommand::ComputeDepth);
            }
            if let Some(progress) = &view.running {
                ui.add(
                    egui::ProgressBar::new(progress.fraction.unwrap_or(0.0))
                        .desired_width(200.0)
                        .text(&progress.stage),
                );
            }
        });
        if let Some(error) = &view.error {
            ui.colored_label(severity_color(Severity::Fault), error);
        }
        if let Some(reason) = &view.not_enough_data {
            ui.add_space(8.0);
            ui.colored_label(
                severity_color(Severity::Warning),
                egui::RichText::new(reason).size(16.0),
            );
        }
        if let (Some(depth), Some(limiting)) = (&view.recommended, &view.limiting_component) {
            ui.add_space(6.0);
            ui.label(
                egui::RichText::new(format!("{depth}  — limited by {limiting}"))
                    .size(28.0)
                    .strong(),
            );
            if let Some(conditions) = &view.conditions {
                ui.label(conditions);
            }
            if let Some(reason) = &view.reason {
                ui.label(reason);
            }
            ui.separator();
            ui.heading("Components (load at the recommended depth, of the rating)");
            let margin = view.margin.unwrap_or(1.0) as f32;
            egui::Grid::new("depth components")
                .striped(true)
                .num_columns(8)
                .spacing([10.0, 4.0])
                .show(ui, |ui| {
                    for header in [
                        "component",
                        "load / rating",
                        "load at depth",
                        "idle",
                        "per mm",
                        "limit",
                        "max depth",
                        "R²",
                    ] {
                        ui.label(egui::RichText::new(header).strong());
                    }
                    ui.end_row();
                    for c in &view.components {
                        let name = if c.limiting {
                            egui::RichText::new(format!("{} (limiting)", c.component)).strong()
                        } else {
                            egui::RichText::new(&c.component)
                        };
                        ui.label(name).on_hover_text(&c.why);
                        let fraction = c.fraction_of_rating as f32;
                        let colour = if fraction >= margin {
                            severity_color(Severity::Warning)
                        } else {
                            severity_color(Severity::Normal)
                        };
                        let bar = ui.add(
                            egui::ProgressBar::new(fraction.clamp(0.0, 1.0))
                                .desired_width(180.0)
                                .fill(colour)
                                .text(&c.headroom),
                        );
                        // The margin line: loads beyond it use the reserve the profile keeps.
                        let x = bar.rect.left() + bar.rect.width() * margin.clamp(0.0, 1.0);
                        ui.painter().vline(
                            x,
                            bar.rect.y_range(),
                            egui::Stroke::new(2.0, ui.visuals().strong_text_color()),
                        );
                        ui.monospace(&c.load_at_recommended);
                        ui.monospace(&c.idle_load);
                        ui.monospace(&c.load_per_mm);
                        ui.monospace(&c.limit).on_hover_text(&c.why);
                        ui.monospace(&c.max_depth);
                        ui.monospace(&c.r2);
                        ui.end_row();
                    }
                });
            ui.weak(format!(
                "The vertical line on each bar is the margin: {:.0} % of the rating.",
                100.0 * margin
            ));
        }
        if !view.derivation.is_empty() {
            ui.separator();
            ui.heading("How it was derived");
            for line in &view.derivation {
                ui.label(line);
            }
        }
        if let Some(note) = &view.data_note {
            ui.weak(format!("Data: {note}"));
        }
        if let Some(computed) = &view.computed {
            ui.weak(format!("Computed {computed}"));
        }
    });
}
