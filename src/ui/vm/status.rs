//! The status bar: link and recorder state, always visible whatever panel is open.

use serde::Serialize;

use super::{duration, number};
use crate::link::ConnectionState;
use crate::ui::state::{HmiState, RecorderState, Severity};

/// What the status bar shows.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StatusView {
    /// Connected, stale or disconnected.
    pub link_state: ConnectionState,
    /// How that looks: normal when connected, warning when stale, fault when disconnected.
    pub link_severity: Severity,
    /// "embedded twin — connected for 2 min 05 s".
    pub link_text: String,
    /// Counters and the last error.
    pub link_detail: String,
    /// Off, recording or failed.
    pub recorder_state: RecorderState,
    /// Normal when recording, warning when off, fault when failed.
    pub recorder_severity: Severity,
    /// "recording 12345 rows to /path/file.csv".
    pub recorder_text: String,
    /// Machine time of the newest frame.
    pub machine_time: String,
    /// Frames the screen missed (they are on disk), when any.
    pub frames_not_shown: Option<String>,
    /// While a source opened from the *Source* window runs: that the start source is not
    /// (a machine left this way is neither watched nor recorded).
    pub away_from_start: Option<String>,
}

/// Builds the status bar.
pub fn build(state: &HmiState) -> StatusView {
    let link = &state.link;
    let (link_severity, state_word) = match link.state {
        ConnectionState::Connected => (Severity::Normal, "connected"),
        ConnectionState::Stale => (Severity::Warning, "stale"),
        ConnectionState::Disconnected => (Severity::Fault, "disconnected"),
    };
    let link_text = format!(
        "{} — {state_word} for {}",
        link.source,
        duration(link.in_state_s)
    );
    let mut detail = vec![format!("{} frames", link.frames)];
    if let Some(age) = link.last_frame_age_s {
        detail.push(format!("last frame {} ago", duration(age)));
    }
    for (count, what) in [
        (link.lost_samples, "lost samples"),
        (link.timeouts, "timeouts"),
        (link.crc_errors, "CRC errors"),
        (link.reconnects, "reconnects"),
    ] {
        if count > 0 {
            detail.push(format!("{count} {what}"));
        }
    }
    if let Some(error) = &link.last_error {
        detail.push(format!("last error: {error}"));
    }
    if let Some(latency) = state.ingest_latency_ms {
        detail.push(format!(
            "newest frames reached the screen {latency:.0} ms after they arrived"
        ));
    }
    let recorder = &state.recorder;
    let (recorder_severity, recorder_text) = match recorder.state {
        RecorderState::Recording => (
            Severity::Normal,
            format!(
                "recording {} rows to {}",
                recorder.rows,
                recorder.path.as_deref().unwrap_or("?")
            ),
        ),
        RecorderState::Off => (Severity::Warning, "not recording".to_string()),
        RecorderState::Failed => (
            Severity::Fault,
            format!(
                "recording failed after {} rows: {}",
                recorder.rows,
                recorder.error.as_deref().unwrap_or("unknown error")
            ),
        ),
    };
    StatusView {
        link_state: link.state,
        link_severity,
        link_text,
        link_detail: detail.join(", "),
        recorder_state: recorder.state,
        recorder_severity,
        recorder_text,
        machine_time: format!("t = {} s", number(state.latest.time_s(), 1)),
        frames_not_shown: (state.frames_not_shown > 0).then(|| {
            format!(
                "{} frames not shown (the screen fell behind; they are in the recording)",
                state.frames_not_shown
            )
        }),
        away_from_start: state
            .source
            .start_source_label
            .as_ref()
            .map(|start| format!("{start} is not running: Source… goes back to it")),
    }
}
