//! The Model lab panel: fitting a model from a database, and the sim-vs-real discrepancy
//! analysis of two recordings (one section at a time, chosen at the top).

use eframe::egui;
use egui_plot::{Legend, Line, Plot, PlotPoints, Span};

use super::{Forms, LabSection, UiCommand, error_line, job_row, labelled_text};
use crate::ui::vm::discrepancy::{DiscrepancyResultView, DiscrepancyView};
use crate::ui::vm::model_lab::ModelLabView;

/// Draws the section chooser; the app then builds and draws the chosen section.
pub fn section_ui(ui: &mut egui::Ui, forms: &mut Forms) {
    ui.horizontal(|ui| {
        for (section, label) in [
            (LabSection::Fit, "Fit a model"),
            (LabSection::Discrepancy, "Sim vs real"),
        ] {
            if ui
                .selectable_label(forms.lab_section == section, label)
                .clicked()
            {
                forms.lab_section = section;
            }
        }
    });
    ui.separator();
}

/// Draws the fit section.
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
    super::form_grid("fit form", ui, |ui| {
        labelled_text(ui, "Database (CSV v1)", &mut forms.fit_data, 420.0);
        ui.end_row();
        labelled_text(ui, "Target column", &mut forms.fit_target, 420.0);
        ui.end_row();
        labelled_text(ui, "Terms", &mut forms.fit_terms, 420.0);
        ui.end_row();
    });
    job_row(
        ui,
        view.running.as_ref(),
        ("Fit", UiCommand::StartFit),
        UiCommand::CancelFit,
        commands,
    );
    error_line(ui, view.error.as_ref());
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

/// Draws the sim-vs-real section.
pub fn discrepancy_ui(
    ui: &mut egui::Ui,
    view: &DiscrepancyView,
    forms: &mut Forms,
    commands: &mut Vec<UiCommand>,
) {
    ui.heading("Sim vs real: where the simulation misses, and which physics it left out");
    ui.label(
        "Residual real − sim on the compared column, mismatch regions, the missing physics \
         named with fitted parameters, and the fit before and after (held out), as \
         `servosight discrepancy` computes it.",
    );
    super::form_grid("discrepancy form", ui, |ui| {
        labelled_text(ui, "Simulation (CSV v1)", &mut forms.disc_sim, 420.0);
        ui.end_row();
        labelled_text(ui, "Real recording (CSV v1)", &mut forms.disc_real, 420.0);
        ui.end_row();
        ui.label("");
        ui.vertical(|ui| {
            ui.checkbox(&mut forms.disc_real_this_file_only, "this file only")
                .on_hover_text(
                    "otherwise the pieces the recorder continued it in (NAME-0001.csv, \
                         NAME-0002.csv, … beside it) are read after it, as one recording",
                );
            if let Some(pieces) = &view.real_pieces {
                ui.label(pieces);
            }
        });
        ui.end_row();
        let label = ui.label("Compared column");
        ui.horizontal(|ui| {
            ui.add(egui::TextEdit::singleline(&mut forms.disc_target).desired_width(300.0))
                .labelled_by(label.id);
            egui::ComboBox::from_id_salt("shared columns")
                .selected_text(if view.shared_columns.is_empty() {
                    "no shared columns yet".to_string()
                } else {
                    format!("{} shared columns", view.shared_columns.len())
                })
                .show_ui(ui, |ui| {
                    for column in &view.shared_columns {
                        ui.selectable_value(&mut forms.disc_target, column.clone(), column);
                    }
                });
        });
        ui.end_row();
        let label = ui.label("Average over (s)");
        ui.horizontal(|ui| {
            ui.add(
                egui::TextEdit::singleline(&mut forms.disc_average_s)
                    .hint_text("every row")
                    .desired_width(80.0),
            )
            .labelled_by(label.id);
            ui.label(
                "blank reads every row; a few seconds reads a long, fast recording \
                     averaged over blocks of that length",
            );
        });
        ui.end_row();
    });
    if let Some(error) = &view.columns_error {
        ui.label(format!("cannot offer the shared columns: {error}"));
    }
    job_row(
        ui,
        view.running.as_ref(),
        ("Analyse", UiCommand::StartDiscrepancy),
        UiCommand::CancelDiscrepancy,
        commands,
    );
    error_line(ui, view.error.as_ref());
    let Some(result) = &view.result else {
        return;
    };
    ui.separator();
    ui.horizontal_wrapped(|ui| {
        labelled_text(ui, "Figure (PNG)", &mut forms.disc_png_path, 320.0);
        if ui.button("Export PNG").clicked() {
            commands.push(UiCommand::ExportDiscrepancyPng);
        }
        if let Some(note) = &view.png_note {
            ui.label(note);
        }
    });
    ui.horizontal_wrapped(|ui| {
        labelled_text(ui, "Report (JSON)", &mut forms.disc_report_path, 320.0);
        if ui.button("Save report").clicked() {
            commands.push(UiCommand::SaveDiscrepancyReport);
        }
        if let Some(note) = &view.report_note {
            ui.label(note);
        }
    });
    egui::ScrollArea::vertical().show(ui, |ui| result_ui(ui, result));
}

/// A finished analysis: verdict, fit before and after, findings, notes, and the residual and
/// overlay plots (also what `servosight discrepancy --plot` draws into its PNG).
pub fn result_ui(ui: &mut egui::Ui, r: &DiscrepancyResultView) {
    let severity = if r.missing_physics {
        crate::ui::state::Severity::Warning
    } else {
        crate::ui::state::Severity::Normal
    };
    ui.label(
        egui::RichText::new(&r.verdict)
            .strong()
            .color(super::severity_color(severity)),
    );
    ui.label(format!("{} — sim {} vs real {}", r.target, r.sim, r.real));
    ui.label(&r.alignment);
    ui.label(&r.calibration);
    egui::Grid::new("discrepancy quality")
        .striped(true)
        .num_columns(3)
        .show(ui, |ui| {
            for header in ["", "R²", "RMSE"] {
                ui.label(egui::RichText::new(header).strong());
            }
            ui.end_row();
            for row in &r.quality {
                ui.label(&row.stage);
                ui.monospace(&row.r2);
                ui.monospace(&row.rmse);
                ui.end_row();
            }
        });
    ui.label(&r.noise_floor);
    if !r.findings.is_empty() {
        ui.heading("Missing physics, strongest first");
    }
    for f in &r.findings {
        ui.label(
            egui::RichText::new(format!(
                "{}. {}   ΔR² {}, p {}",
                f.rank, f.physics, f.delta_r2, f.p_value
            ))
            .strong(),
        );
        ui.label(&f.explanation);
        let parameters: Vec<String> = f
            .parameters
            .iter()
            .map(|p| format!("{} = {}", p.name, p.value))
            .collect();
        ui.monospace(parameters.join(";  "));
        ui.label(format!("signals: {}", f.signals));
        for note in [
            &f.indistinguishable,
            &f.masked_by,
            &f.judged_after_refit,
            &f.judged_on_bounds,
        ]
        .into_iter()
        .flatten()
        {
            ui.label(note);
        }
    }
    for note in &r.notes {
        ui.label(note);
    }
    let p = &r.plots;
    let y_label = if p.unit.is_empty() {
        "value".to_string()
    } else {
        format!("[{}]", p.unit)
    };
    ui.heading("Residual over time (mismatch regions shaded)");
    super::readable_value_axis(Plot::new("discrepancy residual"))
        .height(220.0)
        .legend(Legend::default())
        .link_axis(egui::Id::unique("discrepancy time axis"), [true, false])
        .x_axis_label("time [s]")
        .y_axis_label(y_label.clone())
        .show(ui, |plot_ui| {
            let shade = egui::Color32::from_rgba_unmultiplied(0xe0, 0x9a, 0x00, 40);
            for region in &p.regions {
                plot_ui
                    .span(Span::new("mismatch region", region.start_s..=region.end_s).fill(shade));
            }
            for (line, color) in [
                (&p.residual, egui::Color32::from_rgb(0xd0, 0x30, 0x30)),
                (&p.residual_after, egui::Color32::from_rgb(0x2e, 0xa0, 0x43)),
            ] {
                plot_ui.line(
                    Line::new(line.label.clone(), PlotPoints::new(line.points.clone()))
                        .color(color)
                        .width(1.2),
                );
            }
        });
    for region in &p.regions {
        ui.label(&region.text);
    }
    ui.heading("Before and after: real, sim, sim + corrections");
    super::readable_value_axis(Plot::new("discrepancy overlay"))
        .height(240.0)
        .legend(Legend::default())
        .link_axis(egui::Id::unique("discrepancy time axis"), [true, false])
        .x_axis_label("time [s]")
        .y_axis_label(y_label)
        .show(ui, |plot_ui| {
            for line in &p.overlay {
                plot_ui.line(
                    Line::new(line.label.clone(), PlotPoints::new(line.points.clone())).width(1.2),
                );
            }
        });
    ui.label(&p.decimation);
}
