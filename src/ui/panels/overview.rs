//! The Overview panel.

use eframe::egui;

use super::{light, severity_color};
use crate::ui::state::Severity;
use crate::ui::vm::overview::{AxisCard, OverviewView, Reading};

fn reading_row(ui: &mut egui::Ui, reading: &Reading, old: bool) {
    ui.label(&reading.label);
    let shown = format!("{} {}", reading.value, reading.unit);
    let mut text = egui::RichText::new(shown.trim_end()).monospace();
    text = if old {
        text.weak()
    } else if reading.severity == Severity::Normal {
        text.strong()
    } else {
        text.strong().color(severity_color(reading.severity))
    };
    ui.label(text);
    ui.end_row();
}

fn card_ui(ui: &mut egui::Ui, card: &AxisCard) {
    egui::Frame::group(ui.style())
        .inner_margin(10.0)
        .show(ui, |ui| {
            // Cards sit in a wrapping row; their content runs top to bottom.
            ui.vertical(|ui| card_content(ui, card));
        });
}

fn card_content(ui: &mut egui::Ui, card: &AxisCard) {
    ui.set_width(300.0);
    ui.heading(&card.title);
    ui.horizontal(|ui| light(ui, card.light.severity, 18.0));
    for reason in &card.light.reasons {
        ui.label(reason);
    }
    if card.readings_are_old {
        ui.weak("last known values (not live)");
    }
    ui.separator();
    egui::Grid::new(("axis readings", &card.axis))
        .num_columns(2)
        .spacing([16.0, 4.0])
        .show(ui, |ui| {
            for reading in &card.readings {
                reading_row(ui, reading, card.readings_are_old);
            }
        });
}

/// Draws the Overview.
pub fn overview_ui(ui: &mut egui::Ui, view: &OverviewView) {
    ui.horizontal(|ui| {
        ui.heading("Machine");
        light(ui, view.machine.severity, 20.0);
        if let Some(first) = view.machine.reasons.first() {
            ui.label(first);
        }
    });
    if !view.machine_readings.is_empty() {
        ui.horizontal_wrapped(|ui| {
            for reading in &view.machine_readings {
                ui.label(format!("{}:", reading.label));
                let shown = format!("{} {}", reading.value, reading.unit);
                ui.label(egui::RichText::new(shown.trim_end()).monospace().strong());
                ui.add_space(12.0);
            }
        });
    }
    ui.add_space(8.0);
    egui::ScrollArea::vertical().show(ui, |ui| {
        ui.horizontal_wrapped(|ui| {
            for card in &view.cards {
                card_ui(ui, card);
            }
        });
        if view.cards.is_empty() {
            ui.label("The link carries no servo axis columns.");
        }
    });
}
