//! The HMI's command line: `servosight` with no subcommand opens the window on the embedded
//! twin; `--replay FILE` or `--port DEV` choose the other sources.

use std::path::PathBuf;
use std::time::Duration;

use anyhow::Context;
use servosight::link::{ReplayOptions, ReplaySpeed};
use servosight::profile::MachineProfile;
use servosight::sim::{ScenarioKind, TwinConfig};
use servosight::ui::state::{StatusThresholds, Threshold};
use servosight::ui::{HmiOptions, SessionConfig, SourceSpec};

/// Options of the HMI (given without a subcommand).
#[derive(Debug, Clone, clap::Args)]
pub struct Args {
    /// Replay this recording (CSV v1) instead of running the embedded twin. Several files are
    /// the pieces of one recording in the order they were recorded (the recorder starts a new
    /// one every hour: `shift.csv shift-0001.csv …`), replayed as one.
    #[arg(long, value_name = "FILE", num_args = 1.., conflicts_with = "port")]
    pub replay: Option<Vec<PathBuf>>,
    // With --replay only (checked in `run`); its help is the subcommands'.
    #[command(flatten)]
    pub pieces: super::pieces::LaterPieces,
    /// Read a controller over Modbus RTU on this serial device instead of the twin.
    #[arg(long, value_name = "DEV")]
    pub port: Option<String>,
    /// Seconds of machine time per second of wall clock (twin and replay).
    #[arg(long, default_value_t = 1.0)]
    pub speed: f64,
    /// The twin's program: warmup, production, backlash-test or doe.
    #[arg(long, default_value = "production", value_parser = parse_scenario)]
    pub scenario: ScenarioKind,
    /// The twin's sample rate, Hz.
    #[arg(long, default_value_t = 10.0)]
    pub rate: f64,
    /// The twin's seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Serial line settings (with --port).
    #[command(flatten)]
    pub line: super::serial_args::SerialLineArgs,
    /// Where recordings, the users file, the audit log, warm-up reports (`warmup/`) and
    /// friction-fingerprint baselines (`baselines/`) live (default: the user's data
    /// directory, e.g. ~/.local/share/servosight).
    #[arg(long, value_name = "DIR")]
    pub data_dir: Option<PathBuf>,
    /// Record into this directory (default: DATA_DIR/recordings). A replay (--replay) is
    /// recorded only into a directory given here: it is on disk already.
    #[arg(long, value_name = "DIR")]
    pub record_dir: Option<PathBuf>,
    /// Start with the recorder off (a controller connected from the Source window too).
    #[arg(long)]
    pub no_record: bool,
    /// The users file (default: DATA_DIR/users.toml; add users with `compensate set-user`).
    #[arg(long, value_name = "FILE")]
    pub users: Option<PathBuf>,
    /// The compensation audit log (default: DATA_DIR/audit.jsonl).
    #[arg(long, value_name = "FILE")]
    pub audit: Option<PathBuf>,
    /// A TOML file with a `[compensation_limits]` table; conservative built-in limits
    /// otherwise.
    #[arg(long, value_name = "FILE")]
    pub limits: Option<PathBuf>,
    /// The calibrated machine profile (TOML) whose estimators run on the live frames; the
    /// embedded twin uses the shipped twin profile unless this is given.
    #[arg(long, value_name = "FILE")]
    pub profile: Option<PathBuf>,
    /// Layout and theme file (default: ~/.config/servosight/hmi.json).
    #[arg(long, value_name = "FILE")]
    pub settings: Option<PathBuf>,
    /// Stator temperature warning limit, °C.
    #[arg(long, default_value_t = StatusThresholds::default().stator_temp_c.warning)]
    pub stator_warning_c: f64,
    /// Stator temperature fault limit, °C.
    #[arg(long, default_value_t = StatusThresholds::default().stator_temp_c.fault)]
    pub stator_fault_c: f64,
}

fn parse_scenario(s: &str) -> Result<ScenarioKind, String> {
    s.parse()
}

fn home_dir(var: &str, fallback: &str) -> Option<PathBuf> {
    std::env::var_os(var)
        .filter(|v| !v.is_empty())
        .map(PathBuf::from)
        .or_else(|| {
            std::env::var_os("HOME")
                .filter(|v| !v.is_empty())
                .map(|h| PathBuf::from(h).join(fallback))
        })
}

/// Opens the HMI.
pub fn run(args: Args) -> anyhow::Result<()> {
    if !(args.speed.is_finite() && args.speed > 0.0) {
        anyhow::bail!("--speed must be a positive number (got {})", args.speed);
    }
    let ordered = args.stator_warning_c.partial_cmp(&args.stator_fault_c);
    if ordered.is_none_or(|o| o.is_ge()) {
        anyhow::bail!("--stator-warning-c must be below --stator-fault-c");
    }
    let data_dir = args
        .data_dir
        .clone()
        .or_else(|| home_dir("XDG_DATA_HOME", ".local/share").map(|d| d.join("servosight")))
        .unwrap_or_else(|| PathBuf::from("servosight-data"));
    let settings_path = args.settings.clone().or_else(|| {
        home_dir("XDG_CONFIG_HOME", ".config").map(|d| d.join("servosight").join("hmi.json"))
    });
    anyhow::ensure!(
        !args.pieces.with_later_pieces || args.replay.is_some(),
        "--with-later-pieces adds the later pieces of the recording --replay gives, and no \
         --replay is given"
    );
    let speed = ReplaySpeed::Factor(args.speed);
    let source = match (&args.replay, &args.port) {
        (Some(pieces), _) => SourceSpec::Replay {
            // Without the flag the replay says what it leaves out, as an event in the window.
            pieces: if args.pieces.with_later_pieces {
                super::pieces::recording_files(pieces, &args.pieces, "--replay")?.0
            } else {
                pieces.clone()
            },
            options: ReplayOptions {
                speed,
                ..ReplayOptions::default()
            },
        },
        (None, Some(port)) => SourceSpec::Serial(args.line.config(port)),
        (None, None) => {
            let mut config = TwinConfig::new(args.scenario, None, args.seed);
            config.rate_hz = args.rate;
            SourceSpec::Twin {
                config: Box::new(config),
                speed,
            }
        }
    };
    let profile = match (&args.profile, &source) {
        (Some(path), _) => Some(MachineProfile::load(path)?),
        // Built in, so the default HMI shows estimates anywhere.
        (None, SourceSpec::Twin { .. }) => Some(MachineProfile::twin_calibrated()?),
        (None, _) => None,
    };
    let users_path = args
        .users
        .clone()
        .unwrap_or_else(|| data_dir.join("users.toml"));
    let audit_path = args
        .audit
        .clone()
        .unwrap_or_else(|| data_dir.join("audit.jsonl"));
    let limits = super::compensate::load_limits(args.limits.as_deref())?;
    // Where the machine (the twin or a controller, also one connected from the Source window)
    // is recorded. A recording replayed is on disk already: it is copied only into a
    // directory given for it.
    let machine_record_dir = (!args.no_record).then(|| {
        args.record_dir
            .clone()
            .unwrap_or_else(|| data_dir.join("recordings"))
    });
    let record_dir = match &source {
        SourceSpec::Replay { .. } => args.record_dir.clone().filter(|_| !args.no_record),
        _ => machine_record_dir.clone(),
    };
    let session = SessionConfig {
        source,
        record_dir,
        users_path: users_path.clone(),
        audit_path: audit_path.clone(),
        limits,
        profile,
        data_dir: data_dir.clone(),
    };
    let options = HmiOptions {
        settings_path,
        history_budget_bytes: servosight::ui::history::DEFAULT_HISTORY_BUDGET_BYTES,
        thresholds: StatusThresholds {
            stator_temp_c: Threshold {
                warning: args.stator_warning_c,
                fault: args.stator_fault_c,
            },
        },
        machine_record_dir,
        users_path,
        audit_path,
        limits,
        ingest_budget: Duration::from_millis(4),
    };
    servosight::ui::run(session, options).context("the HMI")?;
    Ok(())
}
