//! The *Source* window: what runs now, and opening a recording in its place (or going back
//! to the source the HMI was started on).

use serde::Serialize;

use crate::link::ConnectionState;
use crate::ui::state::{HmiState, JobProgress};

/// What the *Source* window shows.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SourceView {
    /// "the recording shift.csv — connected".
    pub current: String,
    /// What a blank profile field means: the running session's profile, or none.
    pub profile_hint: String,
    /// Why a change is refused now (the buttons are off and this is shown).
    pub refused: Option<String>,
    /// The change being made and how far it is.
    pub running: Option<JobProgress>,
    /// Why the last change failed or stopped.
    pub error: Option<String>,
    /// "Back to the embedded twin", while another source runs.
    pub return_label: Option<String>,
    /// The last change.
    pub last_change: Option<String>,
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
    SourceView {
        current: format!("{} — {link_state}", state.link.source),
        profile_hint,
        refused: state.source_change_refused(),
        running: state
            .source
            .running
            .as_ref()
            .map(|(what, progress)| JobProgress {
                stage: format!("{what}: {}", progress.stage),
                fraction: progress.fraction,
            }),
        error: state.source.error.clone(),
        return_label: state
            .source
            .start_source
            .as_ref()
            .map(|source| format!("Back to {source}")),
        last_change: state.source.last_change.clone(),
    }
}
