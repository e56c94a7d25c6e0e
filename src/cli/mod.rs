//! The command-line interface: one module per subcommand, each with its clap `Args` and a `run`.
//!
//! Library code returns typed errors (`thiserror`); this is the edge where they become
//! `anyhow` errors and one clear line on stderr with a non-zero exit status.

use std::process::ExitCode;

use clap::{Parser, Subcommand};

mod audit;
mod backlash;
mod calibrate;
mod compensate;
mod depth_of_cut;
mod discrepancy;
mod estimate;
mod fingerprint;
mod fit;
mod hmi;
pub mod inspect;
mod pieces;
mod record;
mod register_map;
mod serial_args;
mod sim_controller;
mod simulate;

/// servosight: sensorless machine-tool condition monitoring from servo drive signals.
#[derive(Debug, Parser)]
#[command(name = "servosight", version, about, long_about = None)]
#[command(args_conflicts_with_subcommands = true)]
struct Cli {
    /// With no subcommand: open the HMI (on the embedded twin unless --replay or --port).
    #[command(flatten)]
    hmi: hmi::Args,
    #[command(subcommand)]
    command: Option<Command>,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Run the physics twin and write a recording (CSV v1).
    Simulate(simulate::Args),
    /// Summarise a recording: columns, rate, duration, min/max/mean, gaps. Fails on bad input.
    Inspect(inspect::Args),
    /// Multiple regression with F-test, R², t/p/CI, sensitivity and optional term selection.
    Fit(fit::Args),
    /// Measure backlash from a backlash-test recording (current rise once the table is driven).
    Backlash(backlash::Args),
    /// Write the NC program of the backlash test (under 10 minutes of machine time).
    BacklashProgram(backlash::ProgramArgs),
    /// Fit every estimator from a simulation database and a few experiments (Eqs. 7–15).
    Calibrate(calibrate::Args),
    /// Recommend the maximum rough-cut depth from the loads measured during cuts.
    DepthOfCut(depth_of_cut::Args),
    /// Run every estimator over a recording; score against reference columns (Table 3).
    Estimate(estimate::Args),
    /// Friction fingerprint of an axis from its warm-up moves, trended, with the preload diagnosis.
    Fingerprint(fingerprint::Args),
    /// Print the Modbus register map (JSON, or the Markdown tables of docs/register-map.md).
    RegisterMap(register_map::Args),
    /// Record every frame a controller sends (Modbus RTU) to a CSV v1 file.
    Record(record::Args),
    /// Propose, apply (approved, bounded, verified, audited) and roll back compensation values.
    Compensate(compensate::Args),
    /// Check the compensation audit log.
    Audit(audit::Args),
    /// Sim vs real: locate the mismatch, name the missing physics, fit it, show the improvement.
    Discrepancy(discrepancy::Args),
    /// Serve a recording as a Modbus RTU controller speaking the register map.
    SimController(sim_controller::Args),
    /// Headless: simulate a 10-hour production day on the twin and summarise it.
    DaySummary,
}

/// Parses the command line, runs the command, and maps errors to one line on stderr.
pub fn run() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Some(Command::Simulate(args)) => simulate::run(args),
        Some(Command::Inspect(args)) => inspect::run(args),
        Some(Command::Fit(args)) => fit::run(args),
        Some(Command::Backlash(args)) => backlash::run(args),
        Some(Command::BacklashProgram(args)) => backlash::run_program(args),
        Some(Command::Calibrate(args)) => calibrate::run(args),
        Some(Command::DepthOfCut(args)) => depth_of_cut::run(args),
        Some(Command::Estimate(args)) => estimate::run(args),
        Some(Command::Fingerprint(args)) => fingerprint::run(args),
        Some(Command::RegisterMap(args)) => register_map::run(args),
        Some(Command::Record(args)) => record::run(args),
        Some(Command::Compensate(args)) => compensate::run(args),
        Some(Command::Audit(args)) => audit::run(args),
        Some(Command::Discrepancy(args)) => discrepancy::run(args),
        Some(Command::SimController(args)) => sim_controller::run(args),
        Some(Command::DaySummary) => simulate::run_default_day(),
        None => hmi::run(cli.hmi),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            // `{:#}` prints the whole context chain on one line: "reading p.csv: line 5, ...".
            eprintln!("error: {error:#}");
            ExitCode::from(2)
        }
    }
}

/// `println!` that returns an error instead of panicking when standard output cannot be
/// written (a full disk, a closed file): `outln!(...)?`. A reader that goes away (a pipe into
/// `head`) still ends the process quietly through SIGPIPE (see `main`).
macro_rules! outln {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        writeln!(std::io::stdout(), $($arg)*)
            .map_err(|error| anyhow::anyhow!("cannot write to standard output: {error}"))
    }};
}
pub(crate) use outln;

/// `print!` that returns an error instead of panicking, as [`outln!`].
macro_rules! out {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        write!(std::io::stdout(), $($arg)*)
            .map_err(|error| anyhow::anyhow!("cannot write to standard output: {error}"))
    }};
}
pub(crate) use out;

/// True when `path` names standard output (`-`).
pub fn is_stdout(path: &std::path::Path) -> bool {
    path.as_os_str() == "-"
}

/// Whether a command prints its text report: not when its JSON goes to standard output, which
/// must then hold the JSON alone so that it can be parsed.
pub fn text_report_wanted(json: Option<&std::path::Path>) -> bool {
    !json.is_some_and(is_stdout)
}

/// Refuses, before anything is written, an output that is the same file as one of the inputs
/// (`-o day.csv` for the recording being read, `--json audit.jsonl` for the audit log): writing
/// it would destroy data the command was asked to read. Standard output (`-`) and outputs that
/// do not exist yet are never an input. Two outputs naming one file, or standard output twice,
/// are refused too.
pub fn refuse_overwriting_inputs(
    inputs: &[&std::path::Path],
    outputs: &[Option<&std::path::Path>],
) -> anyhow::Result<()> {
    let (to_stdout, files): (Vec<&std::path::Path>, Vec<&std::path::Path>) = outputs
        .iter()
        .flatten()
        .copied()
        .partition(|o| is_stdout(o));
    if to_stdout.len() > 1 {
        anyhow::bail!("only one output can go to standard output (-)");
    }
    if let Some((output, _)) = repeated(&files) {
        anyhow::bail!(
            "{} is given for two outputs of this command: one would overwrite the other",
            output.display()
        );
    }
    for output in &files {
        for input in inputs {
            if same_file(input, output) {
                anyhow::bail!(
                    "{} is both an input and an output of this command: writing it would destroy \
                     the data being read; choose another output path",
                    output.display()
                );
            }
        }
    }
    Ok(())
}

/// The first of `paths` that names the same file as an earlier one (spelled alike, or one file
/// reached two ways), with that earlier one.
pub fn repeated<'a>(
    paths: &[&'a std::path::Path],
) -> Option<(&'a std::path::Path, &'a std::path::Path)> {
    paths.iter().enumerate().find_map(|(i, path)| {
        paths[..i]
            .iter()
            .find(|earlier| *earlier == path || same_file(earlier, path))
            .map(|earlier| (*path, *earlier))
    })
}

/// Two paths that name one existing file (through links, `..` or hard links on Unix).
pub fn same_file(a: &std::path::Path, b: &std::path::Path) -> bool {
    let (Ok(meta_a), Ok(meta_b)) = (std::fs::metadata(a), std::fs::metadata(b)) else {
        return false;
    };
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        meta_a.dev() == meta_b.dev() && meta_a.ino() == meta_b.ino()
    }
    #[cfg(not(unix))]
    {
        let _ = (meta_a, meta_b);
        matches!(
            (std::fs::canonicalize(a), std::fs::canonicalize(b)),
            (Ok(x), Ok(y)) if x == y
        )
    }
}

/// A command's report: its text on standard output, then its JSON where `--json` asks. With
/// `--json -` the JSON alone goes to standard output, so that it can be parsed.
pub fn emit_report<T: serde::Serialize>(
    json: Option<&std::path::Path>,
    value: &T,
    text: impl FnOnce() -> anyhow::Result<()>,
) -> anyhow::Result<()> {
    if text_report_wanted(json) {
        text()?;
    }
    match json {
        Some(path) => write_json(path, value),
        None => Ok(()),
    }
}

/// Writes `value` as pretty JSON to `path`, or to stdout when `path` is `-`.
pub fn write_json<T: serde::Serialize>(path: &std::path::Path, value: &T) -> anyhow::Result<()> {
    use anyhow::Context;
    let text = serde_json::to_string_pretty(value).context("serialising the JSON report")?;
    if is_stdout(path) {
        outln!("{text}")?;
    } else {
        std::fs::write(path, text + "\n")
            .with_context(|| format!("cannot write JSON report {}", path.display()))?;
    }
    Ok(())
}

/// "2 h 05 min", "3 min 20 s", "12.5 s": durations as an operator reads them.
pub fn human_duration(seconds: f64) -> String {
    if seconds >= 3600.0 {
        let minutes = (seconds / 60.0).round() as u64;
        format!("{} h {:02} min", minutes / 60, minutes % 60)
    } else if seconds >= 60.0 {
        let s = seconds.round() as u64;
        format!("{} min {:02} s", s / 60, s % 60)
    } else {
        format!("{seconds:.1} s")
    }
}
