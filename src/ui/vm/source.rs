//! The *Source* window: what runs now, and opening a recording in its place (or going back
//! to the source the HMI was started on).

use serde::Serialize;

use crate::link::{ConnectionState, ReplaySpeed};
use crate::ui::state::{HmiState, JobProgress};

/// What the *Source* window shows.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SourceView {
    /// "the recording shift.csv — connected".
    pub current: String,
    /// What a blank profile field means for a recording: the running session's profile, or
    /// none.
    pub profile_hint: String,
    /// What it means for a controller: the profile the HMI was started with on a
    /// controller, or a refusal.
    pub controller_profile_hint: String,
    /// Why a change is refused now (the buttons are off and this is shown).
    pub refused: Option<String>,
    /// The change being made and how far it is.
    pub running: Option<JobProgress>,
    /// Why the last change failed or stopped.
    pub error: Option<String>,
    /// "Back to the start source (embedded twin)", while another source runs.
    pub return_label: Option<String>,
    /// On a controller: what opening a recording stops (the operator ticks that they know).
    pub leaves_controller: Option<String>,
    /// The last change.
    pub last_change: Option<String>,
    /// The running replay's or twin's pace (`None`: a controller, which runs at its own).
    pub pace: Option<PaceView>,
}

/// How the running replay or twin is paced.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PaceView {
    /// Paused.
    pub paused: bool,
    /// "60 × real time, paused".
    pub text: String,
}

/// Builds the *Source* window.
pub fn build(state: &HmiState) -> SourceView {
    let link_state = match state.link.state {
        ConnectionState::Connected => "connected",
        ConnectionState::Stale => "stale",
        ConnectionState::Disconnected => "disconnected",
    };
    let profile_hint = match &state.profile {
        Some(profile) => format!("blank: the running profile `{}`", profile.name),
        None => "blank: no estimators (the running source has no profile)".into(),
    };
    let back = if state.source.start_source_label.is_none() {
        "Back to the start source"
    } else {
        "connecting to it again"
    };
    SourceView {
        current: format!("{} — {link_state}", state.link.source),
        profile_hint: format!("for a recording, {profile_hint}; `none`: no estimators"),
        controller_profile_hint: state.source.blank_controller_profile.clone(),
        refused: state.source_change_refused(),
        running: state.source.running.as_ref().map(|change| JobProgress {
            stage: format!("{}: {}", change.what, change.progress.stage),
            fraction: change.progress.fraction,
        }),
        error: state.source.error.clone(),
        return_label: state
            .source
            .start_source_label
            .as_ref()
            .map(|source| format!("Back to the start source ({source})")),
        leaves_controller: state.controller.as_ref().map(|controller| {
            format!(
                "changing the source stops monitoring the controller ({controller}): it is \
                 neither watched nor recorded until it runs here again ({back})"
            )
        }),
        last_change: state.source.last_change.clone(),
        pace: state.pace.map(|pace| {
            let speed = match pace.speed {
                ReplaySpeed::Factor(factor) => format!("{factor} × real time"),
                ReplaySpeed::AsFastAsPossible => "as fast as the frames are taken".into(),
            };
            PaceView {
                paused: pace.paused,
                text: if pace.paused {
                    format!("{speed}, paused")
                } else {
                    speed
                },
            }
        }),
    }
}
