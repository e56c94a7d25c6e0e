//! Opening another source in the running HMI: a recording chosen in the *Source* window, or
//! the source the HMI was started on. The new session is started on a job's thread while the
//! current one keeps running; the app swaps them only once the new one has started, so a
//! mistyped path or a broken file leaves the machine on screen as it was.

use std::path::PathBuf;

use super::jobs::{JobContext, JobStop};
use super::session::{Session, SessionConfig, SourceSpec};
use super::sim_vs_real::real_pieces;
use crate::link::{ReplayOptions, ReplaySpeed};
use crate::profile::MachineProfile;
use crate::signal::RecordingPieces;

/// Which machine profile the opened recording's estimators run with.
#[derive(Debug, Clone, PartialEq)]
pub enum ProfileChoice {
    /// The profile the running session has (none if it has none).
    Running,
    /// A profile file (TOML), loaded and validated on the job's thread.
    File(PathBuf),
}

/// What the *Source* window asks for.
#[derive(Debug, Clone, PartialEq)]
pub struct OpenRequest {
    /// The recording (CSV v1), its first file when it was recorded in pieces.
    pub recording: PathBuf,
    /// Replay after it the pieces the recorder continued it in, found beside it
    /// ([`crate::signal::later_pieces`]).
    pub find_later_pieces: bool,
    /// Seconds of recording per second of wall clock.
    pub speed: f64,
    /// The estimators' profile.
    pub profile: ProfileChoice,
}

/// The *Source* window's form as a request; anything it cannot use is refused with a message
/// that quotes it.
pub fn parse_open_form(
    recording: &str,
    this_file_only: bool,
    speed: &str,
    profile: &str,
) -> Result<OpenRequest, String> {
    let recording = recording.trim();
    if recording.is_empty() {
        return Err("give the recording to open (a CSV v1 file)".into());
    }
    let speed_text = speed.trim();
    let speed = if speed_text.is_empty() {
        1.0
    } else {
        match speed_text.parse::<f64>() {
            Ok(s) if s.is_finite() && s > 0.0 => s,
            _ => {
                return Err(format!(
                    "speed: `{speed_text}` is not a positive number (seconds of recording per \
                     second; blank replays in real time)"
                ));
            }
        }
    };
    let profile = profile.trim();
    Ok(OpenRequest {
        recording: PathBuf::from(recording),
        find_later_pieces: !this_file_only,
        speed,
        profile: if profile.is_empty() {
            ProfileChoice::Running
        } else {
            ProfileChoice::File(PathBuf::from(profile))
        },
    })
}

/// What the app asks the job to start.
#[derive(Debug, Clone)]
pub enum SourceChange {
    /// A recording from the *Source* window, on the running session's other settings.
    Open(OpenRequest),
    /// Back to the source the HMI was started on.
    Return,
}

/// A started session and what the operator should be told about it.
pub struct Switched {
    /// The new session, running.
    pub session: Session,
    /// "replaying shift.csv … shift-0002.csv (3 pieces) at 60 × with the estimators of …".
    pub summary: String,
    /// Whether this session is the one the HMI was started on.
    pub is_home: bool,
}

impl std::fmt::Debug for Switched {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Switched")
            .field("source", &self.session.source())
            .field("summary", &self.summary)
            .field("is_home", &self.is_home)
            .finish()
    }
}

/// The job: checks the recording (every piece's header) and the profile, then starts the new
/// session. `running` is the current session's configuration (its recorder, users, audit log,
/// limits and data directory carry over), `home` the one the HMI was started on.
pub fn run_switch(
    change: SourceChange,
    running: SessionConfig,
    home: SessionConfig,
    context: &JobContext<Switched>,
) -> Result<Switched, JobStop> {
    let (config, summary, is_home) = match change {
        SourceChange::Return => {
            let summary = format!("back on {}", source_label(&home.source));
            (home, summary, true)
        }
        SourceChange::Open(request) => {
            let (config, summary) = replay_config(&request, running, context)?;
            (config, summary, false)
        }
    };
    context.check()?;
    context.progress("starting the session", Some(0.8));
    let session = Session::start(config).map_err(|e| JobStop::Failed(e.to_string()))?;
    // A session started after a cancel is dropped here (its recorder file is finished).
    context.check()?;
    Ok(Switched {
        session,
        summary,
        is_home,
    })
}

/// The session configuration that replays `request`, and its one-line summary.
fn replay_config(
    request: &OpenRequest,
    running: SessionConfig,
    context: &JobContext<Switched>,
) -> Result<(SessionConfig, String), JobStop> {
    context.progress("looking for the recording's pieces", Some(0.1));
    let pieces =
        real_pieces(&request.recording, request.find_later_pieces).map_err(JobStop::Failed)?;
    context.check()?;
    context.progress("reading the recording's headers", Some(0.3));
    // Every piece's header now, so a missing piece or one with other columns is refused
    // before the running source is let go (the link reads them again as it starts).
    let schema = RecordingPieces::open(&pieces)
        .map(|opened| opened.schema().clone())
        .map_err(|e| JobStop::Failed(e.to_string()))?;
    context.check()?;
    let profile = match &request.profile {
        ProfileChoice::Running => running.profile.clone(),
        ProfileChoice::File(path) => {
            context.progress("loading the machine profile", Some(0.5));
            Some(MachineProfile::load(path).map_err(|e| JobStop::Failed(e.to_string()))?)
        }
    };
    let estimators = match &profile {
        None => "no estimators (no machine profile)".to_string(),
        Some(profile) => match crate::estimators::EstimatorPipeline::new(profile, &schema) {
            Ok(_) => format!("the estimators of profile `{}`", profile.name),
            // The session starts anyway and says so: the servo signals are worth seeing.
            Err(error) => format!("no estimators (profile `{}`: {error})", profile.name),
        },
    };
    let summary = format!(
        "replaying {} at {} × real time with {estimators}",
        RecordingPieces::short_name(&pieces),
        request.speed
    );
    let config = SessionConfig {
        source: SourceSpec::Replay {
            pieces,
            options: ReplayOptions {
                speed: ReplaySpeed::Factor(request.speed),
                ..ReplayOptions::default()
            },
        },
        profile,
        ..running
    };
    Ok((config, summary))
}

/// How a source is named to the operator before its link names it.
pub fn source_label(source: &SourceSpec) -> String {
    match source {
        SourceSpec::Twin { .. } => "the embedded twin".into(),
        SourceSpec::Replay { pieces, .. } => {
            format!("the recording {}", RecordingPieces::short_name(pieces))
        }
        SourceSpec::Serial(modbus) => format!("the controller on {}", modbus.port),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_form_is_read_or_refused_with_what_was_typed() {
        let request = parse_open_form(" shift.csv ", false, "", "").expect("valid");
        assert_eq!(request.recording, PathBuf::from("shift.csv"));
        assert!(request.find_later_pieces);
        assert_eq!(request.speed, 1.0);
        assert_eq!(request.profile, ProfileChoice::Running);
        let request = parse_open_form("a.csv", true, "60", "p.toml").expect("valid");
        assert!(!request.find_later_pieces);
        assert_eq!(request.speed, 60.0);
        assert_eq!(request.profile, ProfileChoice::File("p.toml".into()));
        assert!(parse_open_form("  ", false, "", "").is_err());
        for bad in ["0", "-2", "fast", "inf", "NaN"] {
            let error = parse_open_form("a.csv", false, bad, "").expect_err(bad);
            assert!(error.contains(&format!("`{bad}`")), "{error}");
        }
    }
}
