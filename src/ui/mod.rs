//! The HMI: an eframe/egui desktop app on the same link path as the headless tools.
//!
//! Threads and data flow (the rerun viewer's pattern):
//! - [`session`]: a named worker thread owns the [`crate::link::ControllerLink`], the recorder
//!   (every frame to disk at full rate) and the compensation audit log. The UI talks to it only
//!   through bounded channels: [`session::SessionCommand`]s in, [`session::SessionUpdate`]s out.
//! - [`app`]: on the UI thread, `logic` drains updates under a time budget into the
//!   [`state::HmiState`]; `show` builds the open panel's view model ([`vm`]) and draws it
//!   ([`panels`]); drawing returns [`panels::UiCommand`]s that the app carries out.
//! - [`history`]: the in-memory decimation pyramid behind the Trends panel.
//! - [`jobs`]: long work (fitting a model from a big database) on its own thread with progress
//!   and cancel.
//! - [`source`]: opening a recording (or going back to the start source) in the running HMI,
//!   the new session started on a job while the old one runs on.
//! - [`sim_vs_real`]: the Model lab's sim-vs-real discrepancy analysis as a job, and the
//!   header read that offers the target columns both files share.
//! - [`analysis`]: the warm-up checklist's friction fingerprint and backlash analyses and the
//!   depth-of-cut recommendation, run as jobs on full-rate samples copied from the history.
//! - [`export_png`]: the Trends plots and a sim-vs-real analysis drawn into a PNG without a
//!   window or GPU.
//!
//! With a calibrated machine profile the session runs the [`crate::estimators`] pipeline on
//! every frame; its outputs (`est.*` columns: motor flange, bearing and nut temperatures,
//! torque split, straightness per node and its ISO 1101 zone, spindle elongation) join the
//! history, and the Overview judges them against the profile's limits.

pub mod analysis;
pub mod app;
pub mod export_png;
pub mod history;
pub mod jobs;
pub mod panels;
pub mod session;
pub mod sim_vs_real;
pub mod source;
pub mod state;
pub mod vm;

pub use app::{HmiApp, HmiOptions, Settings};
pub use session::{Session, SessionConfig, SourceSpec};

use eframe::egui;

/// Why the HMI could not run.
#[derive(Debug, thiserror::Error)]
pub enum UiError {
    /// The session (link, recorder) could not start.
    #[error(transparent)]
    Session(#[from] session::SessionError),
    /// The window could not be opened (no display, no OpenGL).
    #[error("cannot open the HMI window: {0}")]
    Window(String),
}

/// egui's own fonts, with its monospace font behind the proportional one for the characters
/// the proportional font lacks: the physics library writes "∝" in its explanations, which
/// egui's default proportional font has no glyph for (drawn as an empty box before).
pub fn install_fonts(ctx: &egui::Context) {
    let mut fonts = egui::FontDefinitions::default();
    let monospace = fonts
        .families
        .get(&egui::FontFamily::Monospace)
        .and_then(|names| names.first().cloned());
    if let (Some(name), Some(proportional)) = (
        monospace,
        fonts.families.get_mut(&egui::FontFamily::Proportional),
    ) && !proportional.contains(&name)
    {
        proportional.push(name);
    }
    ctx.set_fonts(fonts);
}

/// Opens the HMI window on a new session and runs until the window is closed.
pub fn run(config: SessionConfig, options: HmiOptions) -> Result<(), UiError> {
    let session = Session::start(config)?;
    let saved = options.settings_path.as_deref().map(Settings::load);
    let size = saved
        .as_ref()
        .and_then(|s| s.window_size)
        .filter(|[w, h]| *w >= 400.0 && *h >= 300.0)
        .unwrap_or([1280.0, 820.0]);
    let mut viewport = egui::ViewportBuilder::default()
        .with_title("servosight")
        .with_app_id("servosight")
        .with_inner_size(size)
        .with_min_inner_size([640.0, 420.0]);
    // A position far off any plausible desktop (a monitor since unplugged) is not restored:
    // the window manager places the window instead of it opening out of sight.
    if let Some([x, y]) = saved.and_then(|s| s.window_pos).filter(|[x, y]| {
        x.is_finite()
            && y.is_finite()
            && (-100.0..8000.0).contains(x)
            && (-100.0..8000.0).contains(y)
    }) {
        viewport = viewport.with_position([x, y]);
    }
    let native = eframe::NativeOptions {
        viewport,
        ..Default::default()
    };
    eframe::run_native(
        "servosight",
        native,
        Box::new(move |creation| {
            install_fonts(&creation.egui_ctx);
            Ok(Box::new(HmiApp::new(session, options)))
        }),
    )
    .map_err(|e| UiError::Window(e.to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every character the physics library writes into its explanations has a glyph in the
    /// font the panels write them in.
    #[test]
    fn the_explanations_characters_can_be_drawn() {
        let ctx = egui::Context::default();
        install_fonts(&ctx);
        ctx.run_ui(egui::RawInput::default(), |_| {})
            .textures_delta
            .clear();
        let font = egui::FontId::proportional(14.0);
        let missing: String = "τ²∝–≈×…—Δ·µ±°≥≤−"
            .chars()
            .filter(|c| !ctx.fonts_mut(|f| f.has_glyph(&font, *c)))
            .collect();
        assert_eq!(missing, "");
    }
}
