//! The Trends panel: channel picker, window presets, stacked plots (one per unit, x axes
//! linked), CSV export.

use eframe::egui;
use egui_plot::{ColorConflictHandling, ItemId, Legend, Line, Plot, PlotPoints};

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
    let picker = egui::Panel::left("trend channels")
        .resizable(true)
        // Only the first frame takes it (egui keeps the width from then on): the width the
        // operator left it at in the last session.
        .default_size(view.picker_width)
        .show(ui, |ui| {
            // Fill the width given: otherwise the panel shrinks to its widest label and the
            // width the operator left it at is not the width it keeps.
            ui.set_min_width(ui.available_width());
            ui.heading("Channels");
            egui::ScrollArea::vertical().show(ui, |ui| {
                for group in &view.groups {
                    let folding = egui::CollapsingHeader::new(&group.title)
                        .open(Some(group.open))
                        .show(ui, |ui| {
                            for choice in &group.channels {
                                let mut selected = choice.selected;
                                if ui.checkbox(&mut selected, &choice.label).changed() {
                                    commands.push(UiCommand::ToggleChannel(choice.name.clone()));
                                }
                            }
                        });
                    // The settings hold whether a group is open, so it survives a restart.
                    if folding.header_response.clicked() {
                        commands.push(UiCommand::SetGroupOpen(group.title.clone(), !group.open));
                    }
                }
            });
        });
    let width = picker.response.rect.width();
    if (width - view.picker_width).abs() >= 0.5 {
        commands.push(UiCommand::SetPickerWidth(width));
    }
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
            labelled_text(ui, "PNG file", &mut forms.png_path, 260.0);
            if ui.button("Export PNG").clicked() {
                commands.push(UiCommand::ExportTrendsPng);
            }
            if let Some(note) = export_note {
                ui.label(note);
            }
        });
        ui.weak("Drag to pan, scroll or pinch to zoom, double-click to reset.");
        if view.plots.is_empty() && view.straightness.is_empty() {
            ui.add_space(20.0);
            ui.label("Choose channels on the left to draw them.");
            return;
        }
        egui::ScrollArea::vertical().show(ui, |ui| {
            plots_ui(ui, view, false, Some(commands));
        });
    });
}

/// Draws the time plots (one per unit, x axes linked) and the straightness profiles; the
/// screen and the PNG export both draw through here, so the PNG is what is shown. With
/// `fixed_window` the time axes show exactly the view's window (the export); otherwise they
/// follow live or keep the operator's zoom, and zooming or panning is reported in `commands`.
pub fn plots_ui(
    ui: &mut egui::Ui,
    view: &TrendsView,
    fixed_window: bool,
    mut commands: Option<&mut Vec<UiCommand>>,
) {
    let straightness_height = if view.straightness.is_empty() {
        0.0
    } else {
        240.0
    };
    let plot_count = view.plots.len().max(1) as f32;
    let spacing = ui.spacing().item_spacing.y;
    let height = ((ui.available_height() - straightness_height - spacing * plot_count)
        / plot_count)
        .max(120.0);
    let mut colour = 0usize;
    for plot_view in &view.plots {
        let first_colour = colour;
        colour += plot_view.series.len();
        let plot_id = egui::Id::unique(("trend plot", &plot_view.unit));
        // The settings say which series are off (the plot's own memory would forget it at a
        // restart); the legend keeps listing them, unticked, and the plot leaves out what its
        // memory of the previous pass says is hidden (so on a window's very first frame a
        // hidden series shows for that one frame). Items are known by their name.
        let hidden = plot_view
            .series
            .iter()
            .filter(|s| s.hidden)
            .map(|s| ItemId::new(&s.label));
        let response = Plot::new(("trend plot", &plot_view.unit))
            .id(plot_id)
            .height(height)
            .legend(
                // The band shares its series' name; the legend shows the line's colour.
                Legend::default()
                    .color_conflict_handling(ColorConflictHandling::PickFirst)
                    .hidden_items(hidden),
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
                if view.follow_live || fixed_window {
                    plot_ui.set_plot_bounds_x(view.t0..=view.t1);
                    plot_ui.set_auto_bounds([false, true]);
                }
                for (k, series) in plot_view.series.iter().enumerate() {
                    let color = PALETTE[(first_colour + k) % PALETTE.len()];
                    plot_ui.line(
                        Line::new(series.label.clone(), PlotPoints::new(series.points.clone()))
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
        if let Some(commands) = commands.as_deref_mut() {
            // A click in the legend changed the plot's memory of hidden items this frame.
            if let Some(memory) = egui_plot::PlotMemory::load(ui.ctx(), plot_id) {
                for series in &plot_view.series {
                    let hidden = memory.hidden_items.contains(&ItemId::new(&series.label));
                    if hidden != series.hidden {
                        commands.push(UiCommand::SetSeriesHidden(series.channel.clone(), hidden));
                    }
                }
            }
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
    }
    if view.straightness.is_empty() {
        return;
    }
    ui.add_space(6.0);
    let zones: Vec<String> = view
        .straightness
        .iter()
        .map(|s| format!("{} {}: {}", s.axis, s.direction, s.zone))
        .collect();
    ui.label(
        egui::RichText::new(format!(
            "Straightness along the stroke (estimated, ISO 1101 minimum zone) — {}",
            zones.join(", ")
        ))
        .strong(),
    );
    Plot::new("straightness profile")
        .height(straightness_height - 30.0)
        .legend(Legend::default())
        .x_axis_label("position along the stroke [mm]")
        .y_axis_label("deviation [µm]")
        .show(ui, |plot_ui| {
            for (k, s) in view.straightness.iter().enumerate() {
                let name = format!("{} {} (zone {})", s.axis, s.direction, s.zone);
                let color = PALETTE[(k + 3) % PALETTE.len()];
                plot_ui.line(
                    Line::new(name.clone(), PlotPoints::new(s.points.clone()))
                        .color(color)
                        .width(2.0),
                );
                plot_ui.points(
                    egui_plot::Points::new(name, PlotPoints::new(s.points.clone()))
                        .color(color)
                        .radius(3.5),
                );
            }
        });
}
