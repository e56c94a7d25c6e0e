//! The Trends panel: channel picker, window presets, stacked plots (one per unit, x axes
//! linked), CSV export.

use eframe::egui;
use egui_plot::{ColorConflictHandling, Legend, Line, Plot, PlotPoints};

use super::{Forms, UiCommand, labelled_text};
use crate::ui::vm::trends::{TrendsView, WindowPreset};

/// Distinct colours for series, in order.
const PALETTE: [egui::Color32; 8] = [
    egui::Color32::from_rgb(0x1f, 0x77, 0xb4),
    egui::Color32::from_rgb(0xff, 0x7f, 0x0e),
    egui::Color32::from_rgb(0x2c, 0xa0, 0x2c),
    egui::Color32::from_rgb(0xd6, 0x27, 0x28),
    egui::Color32::from_rgb(0x94, 0x67, 0xbd),
    egui::Color32::from_rgb(0x8c, 0x56, 0x4b),
    egui::Color32::from_rgb(0xe3, 0x77, 0xc2),
    egui::Color32::from_rgb(0x17, 0xbe, 0xcf),
];

/// Draws the Trends panel. `export_note` is the result of the last export.
pub fn trends_ui(
    ui: &mut egui::Ui,
    view: &TrendsView,
    forms: &mut Forms,
    export_note: Option<&str>,
    commands: &mut Vec<UiCommand>,
) {
    egui::Panel::left("trend channels")
        .resizable(true)
        .default_size(230.0)
        .show(ui, |ui| {
            ui.heading("Channels");
            egui::ScrollArea::vertical().show(ui, |ui| {
                for group in &view.groups {
                    egui::CollapsingHeader::new(&group.title)
                        .default_open(!group.title.contains("reference"))
                        .show(ui, |ui| {
                            for choice in &group.channels {
                                let mut selected = choice.selected;
                                if ui.checkbox(&mut selected, &choice.label).changed() {
                                    commands.push(UiCommand::ToggleChannel(choice.name.clone()));
                                }
                            }
                        });
                }
            });
        });
    egui::CentralPanel::default().show(ui, |ui| {
        ui.horizontal_wrapped(|ui| {
            ui.label("Window:");
            for preset in WindowPreset::ALL {
                let active = view.follow_live && view.preset == preset;
                if ui.selectable_label(active, preset.label()).clicked() {
                    commands.push(UiCommand::SetPreset(preset));
                }
            }
            ui.separator();
            if view.follow_live {
                ui.label("following live");
            } else if ui.button("Follow live").clicked() {
                commands.push(UiCommand::FollowLive);
            }
            ui.separator();
            ui.weak(&view.resolution);
        });
        ui.horizontal_wrapped(|ui| {
            labelled_text(ui, "Export to", &mut forms.export_path, 260.0);
            if ui.button("Export CSV").clicked() {
                commands.push(UiCommand::ExportTrends);
            }
            if let Some(note) = export_note {
                ui.label(note);
            }
        });
        ui.weak("Drag to pan, scroll or pinch to zoom, double-click to reset.");
        if view.plots.is_empty() {
            ui.add_space(20.0);
            ui.label("Choose channels on the left to draw them.");
            return;
        }
        let plot_count = view.plots.len() as f32;
        let spacing = ui.spacing().item_spacing.y;
        let height = ((ui.available_height() - spacing * plot_count) / plot_count).max(120.0);
        let mut colour = 0usize;
        egui::ScrollArea::vertical().show(ui, |ui| {
            for plot_view in &view.plots {
                let first_colour = colour;
                colour += plot_view.series.len();
                let response = Plot::new(("trend plot", &plot_view.unit))
                    .height(height)
                    .legend(
                        // The band shares its series' name; the legend shows the line's colour.
                        Legend::default().color_conflict_handling(ColorConflictHandling::PickFirst),
                    )
                    .link_axis(egui::Id::unique("trend time axis"), [true, false])
                    .link_cursor(egui::Id::unique("trend time axis"), [true, false])
                    .x_axis_label("machine time [s]")
                    .y_axis_label(if plot_view.unit.is_empty() {
                        "value".to_string()
                    } else {
                        format!("[{}]", plot_view.unit)
                    })
                    .show(ui, |plot_ui| {
                        if view.follow_live {
                            plot_ui.set_plot_bounds_x(view.t0..=view.t1);
                            plot_ui.set_auto_bounds([false, true]);
                        }
                        for (k, series) in plot_view.series.iter().enumerate() {
                            let color = PALETTE[(first_colour + k) % PALETTE.len()];
                            plot_ui.line(
                                Line::new(
                                    series.label.clone(),
                                    PlotPoints::new(series.points.clone()),
                                )
                                .color(color)
                                .width(1.5),
                            );
                            if let Some((min, max)) = &series.band {
                                let faint = color.gamma_multiply(0.35);
                                plot_ui.line(
                                    Line::new(series.label.clone(), PlotPoints::new(min.clone()))
                                        .color(faint)
                                        .width(1.0),
                                );
                                plot_ui.line(
                                    Line::new(series.label.clone(), PlotPoints::new(max.clone()))
                                        .color(faint)
                                        .width(1.0),
                                );
                            }
                        }
                    });
                let interacted = response.response.dragged()
                    || (response.response.hovered()
                        && ui.input(|i| {
                            i.smooth_scroll_delta != egui::Vec2::ZERO || i.zoom_delta() != 1.0
                        }));
                let bounds = response.transform.bounds();
                let (t0, t1) = (bounds.min()[0], bounds.max()[0]);
                let moved = (t0 - view.t0).abs() + (t1 - view.t1).abs()
                    > 1e-9 * (view.t1 - view.t0).abs().max(1.0);
                if (interacted || (!view.follow_live && moved)) && t1 > t0 {
                    commands.push(UiCommand::SetView(t0, t1));
                }
            }
        });
    });
}
