//! `servosight backlash` and `servosight backlash-program`: the paper's servo-signal backlash test.

use std::path::PathBuf;

use crate::servosight_cli::pieces::{LaterPieces, recording_files};
use crate::servosight_cli::{emit_report, out, outln, refuse_overwriting_inputs};
use anyhow::Context;
use servosight::estimators::backlash::{analyse_backlash, nc_program};
use servosight::profile::MachineProfile;
use servosight::signal::{AxisId, Quantity, read_pieces};
use servosight::sim::BacklashTestPlan;

/// Arguments of `servosight backlash`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// A recording of the backlash test (command, position and current at ≥ 200 Hz); several
    /// files are the pieces of one recording, read as one in the order given (a test the
    /// recorder's hourly new piece cut in two: test.csv test-0001.csv).
    #[arg(long, required = true, num_args = 1..)]
    pub recording: Vec<PathBuf>,
    #[command(flatten)]
    pub pieces: LaterPieces,
    /// The axis tested.
    #[arg(long, value_parser = parse_axis)]
    pub axis: AxisId,
    /// Machine profile (for the screw lead); default: the twin's machine.
    #[arg(long)]
    pub profile: Option<PathBuf>,
    /// Write `{axis, backlash_um, by_speed, confidence}` as JSON ("-" for stdout).
    #[arg(long)]
    pub json: Option<PathBuf>,
}

/// Arguments of `servosight backlash-program`.
#[derive(Debug, clap::Args)]
pub struct ProgramArgs {
    /// The axis to test.
    #[arg(long, value_parser = parse_axis)]
    pub axis: AxisId,
    /// Where the test runs, mm.
    #[arg(long, default_value_t = 200.0)]
    pub centre_mm: f64,
    /// The controller's minimum increment, µm (the first amplitude).
    #[arg(long, default_value_t = 1.0)]
    pub min_increment_um: f64,
    /// Largest amplitude, µm.
    #[arg(long, default_value_t = 100.0)]
    pub max_amplitude_um: f64,
    /// Feeds to test, mm/min (comma separated).
    #[arg(long, value_delimiter = ',', default_value = "20,60,200")]
    pub feeds: Vec<f64>,
    /// Axis acceleration for the time estimate, mm/s².
    #[arg(long, default_value_t = 2000.0)]
    pub acceleration: f64,
    /// Write the program here instead of stdout.
    #[arg(short = 'o', long = "output")]
    pub output: Option<PathBuf>,
}

fn parse_axis(s: &str) -> Result<AxisId, String> {
    s.parse()
}

pub fn run(mut args: Args) -> anyhow::Result<()> {
    args.recording = recording_files(&args.recording, &args.pieces, "--recording")?.0;
    let mut inputs: Vec<&std::path::Path> = args.recording.iter().map(PathBuf::as_path).collect();
    inputs.extend(args.profile.as_deref());
    refuse_overwriting_inputs(&inputs, &[args.json.as_deref()])?;
    let profile = match &args.profile {
        Some(path) => MachineProfile::load(path)?,
        None => MachineProfile::twin_default(),
    };
    let lead = profile
        .axis(args.axis)
        .and_then(|a| a.screw.as_ref())
        .map(|s| s.lead_mm)
        .with_context(|| format!("the profile has no ball screw for axis {}", args.axis))?;
    let recording = read_pieces(&args.recording).context("cannot read recording")?;
    let report = analyse_backlash(&recording, args.axis, lead)?;
    emit_report(args.json.as_deref(), &report, || {
        outln!(
            "{} axis backlash: {:.1} µm (confidence {:.2}), from a {:.1} min test",
            report.axis,
            report.backlash_um,
            report.confidence,
            report.test_duration_s / 60.0
        )?;
        outln!(
            "{:>10} {:>10} {:>12} {:>20} {:>12}",
            "feed",
            "motor rpm",
            "backlash µm",
            "95 % interval µm",
            "rise A (t)"
        )?;
        for b in &report.by_speed {
            outln!(
                "{:>10.0} {:>10.1} {:>12.1} {:>9.1} – {:<8.1} {:>6.3} ({:.0})",
                b.feed_mm_per_min,
                b.speed_rpm,
                b.backlash_um,
                b.ci_low_um,
                b.ci_high_um,
                b.current_rise_a,
                b.rise_t
            )?;
        }
        for feed in &report.feeds_without_a_rise {
            outln!(
                "{feed:>10.0}  no rise of the current: no knee at this feed (counted against the confidence)"
            )?;
        }
        Ok(())
    })
}

pub fn run_program(args: ProgramArgs) -> anyhow::Result<()> {
    let plan = BacklashTestPlan {
        centre_mm: args.centre_mm,
        min_increment_um: args.min_increment_um,
        max_amplitude_um: args.max_amplitude_um,
        feeds_mm_per_min: args.feeds.clone(),
        ..BacklashTestPlan::default()
    };
    anyhow::ensure!(
        matches!(args.axis, AxisId::X | AxisId::Y | AxisId::Z),
        "the backlash test drives a linear feed axis (X, Y or Z), not {}",
        args.axis
    );
    let (low, high) = Quantity::Position.plausible_range();
    anyhow::ensure!(
        args.centre_mm.is_finite() && (low..=high).contains(&args.centre_mm),
        "--centre-mm must be a position on the axis, between {low} and {high} mm, not {}",
        args.centre_mm
    );
    anyhow::ensure!(
        plan.min_increment_um.is_finite()
            && plan.max_amplitude_um.is_finite()
            && plan.min_increment_um > 0.0
            && plan.max_amplitude_um >= plan.min_increment_um,
        "the amplitudes must run from a positive minimum increment up to the maximum"
    );
    anyhow::ensure!(
        !plan.feeds_mm_per_min.is_empty()
            && plan
                .feeds_mm_per_min
                .iter()
                .all(|f| f.is_finite() && *f > 0.0),
        "feeds must be positive numbers of mm/min"
    );
    anyhow::ensure!(
        args.acceleration.is_finite() && args.acceleration > 0.0,
        "--acceleration must be a positive number of mm/s², not {}",
        args.acceleration
    );
    // Checked before anything is written: a program too long to run is not left behind.
    let minutes = plan.duration_s(args.acceleration) / 60.0;
    anyhow::ensure!(
        minutes < 10.0,
        "this test would take {minutes:.1} min: reduce the amplitudes or feeds"
    );
    let program = nc_program(&plan, args.axis, args.acceleration);
    match &args.output {
        Some(path) => {
            std::fs::write(path, &program)
                .with_context(|| format!("cannot write {}", path.display()))?;
            eprintln!(
                "wrote {} ({minutes:.1} min of machine time)",
                path.display()
            );
        }
        None => out!("{program}")?,
    }
    Ok(())
}
