//! Opening another source in the running HMI: a recording or a controller chosen in the
//! *Source* window, or the source the HMI was started on. The new session is started on a
//! job's thread while the current one keeps running; the app swaps them only once the new one
//! runs (a controller: once it has answered), so a mistyped path, a broken file or a silent
//! line leaves the source on screen as it was. A recording opened here is not recorded again;
//! a controller is recorded where the HMI records the machine.

use std::path::PathBuf;

use super::jobs::{JobContext, JobStop};
use super::session::{Session, SessionConfig, SessionUpdate, SourceSpec, estimator_state_path};
use crate::link::{ConnectionState, ModbusConfig, Parity, ReplayOptions, ReplaySpeed};
use crate::profile::MachineProfile;
use crate::signal::{RecordingPieces, with_later_pieces};

/// Which machine profile the new source's estimators run with.
#[derive(Debug, Clone, PartialEq)]
pub enum ProfileChoice {
    /// The field left blank: for a recording, the running session's profile; for a
    /// controller, the profile the HMI was started with on a controller (no other profile is
    /// known to be a machine's: the default twin's on a real machine would judge it by the
    /// twin).
    Default,
    /// `none`: no estimators.
    Without,
    /// A profile file (TOML), loaded and validated on the job's thread.
    File(PathBuf),
}

impl ProfileChoice {
    /// The *Source* window's profile field: blank, `none`, or a file.
    pub fn from_field(text: &str) -> ProfileChoice {
        match text.trim() {
            "" => ProfileChoice::Default,
            "none" => ProfileChoice::Without,
            path => ProfileChoice::File(PathBuf::from(path)),
        }
    }
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
    let speed = if speed.trim().is_empty() {
        1.0
    } else {
        parse_speed(speed)?
    };
    Ok(OpenRequest {
        recording: PathBuf::from(recording),
        find_later_pieces: !this_file_only,
        speed,
        profile: ProfileChoice::from_field(profile),
    })
}

/// A speed typed by the operator: seconds of recording per second of wall clock, a positive
/// number; anything else is refused with a message that quotes it.
pub fn parse_speed(text: &str) -> Result<f64, String> {
    let text = text.trim();
    // A decimal comma is read as a point, as the other number fields read it.
    match text.replace(',', ".").parse::<f64>() {
        Ok(s) if s.is_finite() && s > 0.0 => Ok(s),
        _ => Err(format!(
            "speed: `{text}` is not a positive number (seconds of recording per second of \
             wall clock; 1 is real time)"
        )),
    }
}

/// The *Source* window's controller form as the link's settings; anything it cannot use is
/// refused with a message that quotes it. What the form does not set (stop bits, polling,
/// timeouts) and blank fields come from `base`: the line the HMI was started on, or the
/// defaults of `servosight --port` (115200 baud, no parity, slave 1).
pub fn parse_connect_form(
    base: &ModbusConfig,
    device: &str,
    baud: &str,
    parity: &str,
    slave: &str,
) -> Result<ModbusConfig, String> {
    let device = device.trim();
    if device.is_empty() {
        return Err("give the controller's serial device (e.g. /dev/ttyUSB0)".into());
    }
    let mut config = ModbusConfig {
        port: device.to_string(),
        ..base.clone()
    };
    let baud = baud.trim();
    if !baud.is_empty() {
        config.baud = baud
            .parse::<u32>()
            .ok()
            .filter(|b| *b > 0)
            .ok_or_else(|| format!("baud: `{baud}` is not a positive whole number"))?;
    }
    let parity = parity.trim();
    if !parity.is_empty() {
        config.parity = parity.parse::<Parity>()?;
    }
    let slave = slave.trim();
    if !slave.is_empty() {
        config.slave = slave
            .parse::<u8>()
            .ok()
            .filter(|id| (1..=247).contains(id))
            .ok_or_else(|| format!("slave id: `{slave}` is not a Modbus slave id (1 to 247)"))?;
    }
    Ok(config)
}

/// What the app asks the job to start.
#[derive(Debug, Clone)]
pub enum SourceChange {
    /// A recording from the *Source* window, on the running session's other settings.
    Open(OpenRequest),
    /// A controller from the *Source* window, with the estimators of `profile`.
    Connect {
        /// The serial line and the controller on it.
        modbus: ModbusConfig,
        /// The estimators' profile.
        profile: ProfileChoice,
    },
    /// Back to the source the HMI was started on.
    Return,
}

/// Everything the job needs besides the change itself.
pub(crate) struct SwitchContext {
    /// The running session's configuration (its users, audit log, limits and data directory
    /// carry over to the new source).
    pub running: SessionConfig,
    /// The configuration the HMI was started on.
    pub start: SessionConfig,
    /// Where the machine is recorded (`None`: the HMI was started with the recorder off).
    pub machine_record_dir: Option<PathBuf>,
    /// Earlier sessions still ending (joining their threads, finishing their recorder files):
    /// waited for before the new one starts, so a serial port they hold is free again.
    pub earlier_endings: Endings,
    /// Says when the running session has saved its estimators' state: waited for (a little)
    /// when the new session takes up the same state file, so that it carries on from where
    /// the running one is rather than from its last periodic save.
    pub running_saved: Option<std::sync::mpsc::Receiver<()>>,
}

/// How long the job waits for the running session to save its estimators' state.
const SAVE_WAIT: std::time::Duration = std::time::Duration::from_secs(2);
/// How long a controller has to answer before the change is given up.
pub const ANSWER_WAIT: std::time::Duration = std::time::Duration::from_secs(3);

/// A started session and what the operator should be told about it.
pub struct Switched {
    /// The new session, running.
    pub session: Session,
    /// "replaying shift.csv … shift-0002.csv (3 pieces) at 60 × real time with the
    /// estimators of profile `…`".
    pub summary: String,
    /// Whether this session is the one the HMI was started on.
    pub is_start: bool,
    /// What the session said while the job waited for it to answer, in order (the app takes
    /// them in as if they had come after the change).
    pub early_updates: Vec<SessionUpdate>,
}

/// The job: checks the recording (every piece's header) or the device, and the profile;
/// waits for earlier sessions to end; starts the new session and, for a controller, waits
/// for it to answer.
pub(crate) fn run_switch(
    change: SourceChange,
    inputs: SwitchContext,
    context: &JobContext<Switched>,
) -> Result<Switched, JobStop> {
    // Waited for even when the job stops early (`Endings` joins on drop).
    let SwitchContext {
        running,
        start,
        machine_record_dir,
        mut earlier_endings,
        running_saved,
    } = inputs;
    let (config, kind) = match change {
        SourceChange::Return => (start, Kind::Start),
        SourceChange::Open(request) => {
            let config = replay_config(&request, running.clone(), context)?;
            (config, Kind::Replay(request.speed))
        }
        SourceChange::Connect { modbus, profile } => {
            std::fs::metadata(&modbus.port).map_err(|e| {
                JobStop::Failed(format!("no serial device at {}: {e}", modbus.port))
            })?;
            let profile = controller_profile(&profile, &start, &running, context)?;
            let config = SessionConfig {
                source: SourceSpec::Serial(modbus),
                profile,
                record_dir: machine_record_dir,
                ..running.clone()
            };
            (config, Kind::Controller)
        }
    };
    context.check()?;
    context.progress("waiting for the previous source to close", Some(0.6));
    earlier_endings.wait();
    let same_state_file = estimator_state_path(&config.data_dir, &config.source)
        .zip(estimator_state_path(&running.data_dir, &running.source))
        .is_some_and(|((new, _), (old, _))| new == old);
    if same_state_file && let Some(saved) = running_saved {
        context.progress("saving the estimators' state", Some(0.7));
        // A session that cannot save in time is carried on from its last periodic save.
        let _ = saved.recv_timeout(SAVE_WAIT);
    }
    context.check()?;
    context.progress("starting the session", Some(0.8));
    let mut session = Session::start(config).map_err(|e| JobStop::Failed(e.to_string()))?;
    let mut early_updates = Vec::new();
    let estimators = session.estimators();
    let summary = match kind {
        Kind::Replay(speed) => format!(
            "{} at {speed} × real time with {estimators}, not recorded again (it is on disk)",
            session.source(),
        ),
        Kind::Controller => {
            context.progress("waiting for the controller to answer", Some(0.9));
            match wait_for_an_answer(&mut session, context) {
                Ok(updates) => early_updates = updates,
                Err(stop) => {
                    // Its recorder file is finished first; read again, one without a row is
                    // only this attempt's header, and goes (a row that came at the last
                    // moment keeps it). The session names it even when the change was
                    // cancelled before the session reported its recorder.
                    if let Some(path) = session.end()
                        && has_no_row(&path)
                    {
                        let _ = std::fs::remove_file(path);
                    }
                    return Err(stop);
                }
            }
            format!(
                "on {} with {estimators}, {}",
                session.source(),
                match &session.config().record_dir {
                    Some(dir) => format!("recorded into {}", dir.display()),
                    None => "not recorded (the HMI was started with the recorder off)".into(),
                }
            )
        }
        Kind::Start => format!("back on {} with {estimators}", session.source()),
    };
    // A session started after a cancel is dropped here (its recorder file is finished).
    context.check()?;
    Ok(Switched {
        session,
        summary,
        is_start: matches!(kind, Kind::Start),
        early_updates,
    })
}

/// Whether the recording at `path` reads whole and holds no row.
fn has_no_row(path: &std::path::Path) -> bool {
    let mut row = Vec::new();
    crate::signal::RecordingReader::open(path)
        .and_then(|mut reader| reader.read_row(&mut row))
        .is_ok_and(|more| !more)
}

/// Waits (at most [`ANSWER_WAIT`]) for a controller's first fresh sample, keeping what the
/// session says meanwhile. A line on which nothing answers (a wrong device, baud rate,
/// parity or slave id) fails the change, so the source that was running stays.
fn wait_for_an_answer(
    session: &mut Session,
    context: &JobContext<Switched>,
) -> Result<Vec<SessionUpdate>, JobStop> {
    let deadline = std::time::Instant::now() + ANSWER_WAIT;
    let mut updates = Vec::new();
    let mut last_error = None;
    while std::time::Instant::now() < deadline {
        context.check()?;
        while let Some(update) = session.try_recv() {
            match &update {
                SessionUpdate::Link(link) if link.state == ConnectionState::Connected => {
                    updates.push(update);
                    return Ok(updates);
                }
                SessionUpdate::Link(link) => last_error.clone_from(&link.last_error),
                _ => {}
            }
            updates.push(update);
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    let line = match &session.config().source {
        SourceSpec::Serial(modbus) => format!(
            "{} baud, parity {:?}, {} stop bit(s), slave {}",
            modbus.baud, modbus.parity, modbus.stop_bits, modbus.slave
        ),
        _ => String::new(),
    };
    Err(JobStop::Failed(format!(
        "nothing answered on {} ({line}) within {} s{}: check the device and the line \
         settings",
        session.source(),
        ANSWER_WAIT.as_secs(),
        last_error.map_or(String::new(), |e| format!(" (last error: {e})"))
    )))
}

/// What a change starts, for its summary.
#[derive(Clone, Copy)]
enum Kind {
    /// The source the HMI was started on.
    Start,
    /// A recording, at this speed.
    Replay(f64),
    /// A controller.
    Controller,
}

/// The profile `choice` names for a controller: blank is the profile the HMI was started with
/// on a controller, and is refused otherwise.
fn controller_profile(
    choice: &ProfileChoice,
    start: &SessionConfig,
    running: &SessionConfig,
    context: &JobContext<Switched>,
) -> Result<Option<MachineProfile>, JobStop> {
    if *choice != ProfileChoice::Default {
        return chosen_profile(choice, running, context);
    }
    if matches!(start.source, SourceSpec::Serial(_)) {
        return Ok(start.profile.clone());
    }
    let running_profile = running
        .profile
        .as_ref()
        .map_or("no profile".to_string(), |p| {
            format!("profile `{}`", p.name)
        });
    Err(JobStop::Failed(format!(
        "give the machine profile (TOML) of this controller, or `none` for no estimators: the \
         HMI was not started on a controller, and the running {running_profile} is not known \
         to be this machine's"
    )))
}

/// The profile `choice` names: blank is the running session's, or one loaded from its file.
fn chosen_profile(
    choice: &ProfileChoice,
    running: &SessionConfig,
    context: &JobContext<Switched>,
) -> Result<Option<MachineProfile>, JobStop> {
    match choice {
        ProfileChoice::Default => Ok(running.profile.clone()),
        ProfileChoice::Without => Ok(None),
        ProfileChoice::File(path) => {
            context.progress("loading the machine profile", Some(0.5));
            MachineProfile::load(path)
                .map(Some)
                .map_err(|e| JobStop::Failed(e.to_string()))
        }
    }
}

/// Sessions ending on threads of their own (joining their threads, finishing their recorder
/// files, saving their estimators' state), joined when waited for or dropped.
#[derive(Default)]
pub(crate) struct Endings(Vec<std::thread::JoinHandle<()>>);

impl Endings {
    /// Runs `ending` (a session's drop, or following a cancelled change to its end) on a
    /// thread of its own; without a thread it does not run, and the error says why (the
    /// caller then lets it end where it is).
    pub(crate) fn run(&mut self, ending: impl FnOnce() + Send + 'static) -> std::io::Result<()> {
        let handle = std::thread::Builder::new()
            .name("servosight-session-end".into())
            .spawn(ending)?;
        self.0.push(handle);
        Ok(())
    }

    /// Waits until every one has ended.
    pub(crate) fn wait(&mut self) {
        for ending in self.0.drain(..) {
            let _ = ending.join();
        }
    }
}

impl Drop for Endings {
    fn drop(&mut self) {
        self.wait();
    }
}

/// The session configuration that replays `request`.
fn replay_config(
    request: &OpenRequest,
    running: SessionConfig,
    context: &JobContext<Switched>,
) -> Result<SessionConfig, JobStop> {
    context.progress("looking for the recording's pieces", Some(0.1));
    let pieces = with_later_pieces(&request.recording, request.find_later_pieces)
        .map_err(JobStop::Failed)?;
    context.check()?;
    context.progress("reading the recording's headers", Some(0.3));
    // Every piece's header now, so a missing piece or one with other columns is refused
    // before the running source is let go (the link reads them again as it starts).
    RecordingPieces::open(&pieces).map_err(|e| JobStop::Failed(e.to_string()))?;
    context.check()?;
    let profile = chosen_profile(&request.profile, &running, context)?;
    Ok(SessionConfig {
        source: SourceSpec::Replay {
            pieces,
            options: ReplayOptions {
                speed: ReplaySpeed::Factor(request.speed),
                ..ReplayOptions::default()
            },
        },
        profile,
        // A recording is on disk already: recording its replay would only copy it, into the
        // machine's recordings, under the names the machine's own recordings take.
        record_dir: None,
        ..running
    })
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
        assert_eq!(request.profile, ProfileChoice::Default);
        let request = parse_open_form("a.csv", true, "60", "p.toml").expect("valid");
        assert!(!request.find_later_pieces);
        assert_eq!(request.speed, 60.0);
        assert_eq!(request.profile, ProfileChoice::File("p.toml".into()));
        let request = parse_open_form("a.csv", true, "", " none ").expect("valid");
        assert_eq!(request.profile, ProfileChoice::Without);
        assert!(parse_open_form("  ", false, "", "").is_err());
        assert_eq!(parse_speed(" 0.5 "), Ok(0.5));
        assert_eq!(parse_speed("1,5"), Ok(1.5));
        assert!(parse_speed("").is_err());
    }

    #[test]
    fn the_controller_form_takes_defaults_or_refuses_with_what_was_typed() {
        let defaults = ModbusConfig::new("");
        let config = parse_connect_form(&defaults, " /dev/ttyUSB0 ", "", "", "").expect("valid");
        assert_eq!(config, ModbusConfig::new("/dev/ttyUSB0"));
        let config =
            parse_connect_form(&defaults, "/dev/ttyS1", "19200", "even", "7").expect("valid");
        assert_eq!(
            (config.baud, config.parity, config.slave),
            (19200, Parity::Even, 7)
        );
        // The line the HMI was started on fills what the form leaves blank or does not set.
        let mut started = ModbusConfig::new("/dev/ttyS0");
        started.baud = 38400;
        started.stop_bits = 2;
        started.poll_hz = 20.0;
        let config = parse_connect_form(&started, "/dev/ttyS1", "", "odd", "").expect("valid");
        assert_eq!(
            (
                config.port.as_str(),
                config.baud,
                config.stop_bits,
                config.poll_hz
            ),
            ("/dev/ttyS1", 38400, 2, 20.0)
        );
        assert_eq!(config.parity, Parity::Odd);
        assert!(parse_connect_form(&defaults, " ", "", "", "").is_err());
        for (baud, parity, slave, quoted) in [
            ("0", "", "", "`0`"),
            ("fast", "", "", "`fast`"),
            ("", "mark", "", "`mark`"),
            ("", "", "248", "`248`"),
            ("", "", "0", "`0`"),
        ] {
            let error =
                parse_connect_form(&defaults, "/dev/ttyS1", baud, parity, slave).expect_err(quoted);
            assert!(error.contains(quoted), "{error}");
        }
        for bad in ["0", "-2", "fast", "inf", "NaN"] {
            let error = parse_open_form("a.csv", false, bad, "").expect_err(bad);
            assert!(error.contains(&format!("`{bad}`")), "{error}");
        }
    }
}
