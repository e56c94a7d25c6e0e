//! `servosight simulate`: run the physics twin and write a recording.

use std::path::PathBuf;

use crate::servosight_cli::outln;
use anyhow::Context;
use servosight::signal::{RecordingWriter, read_recording};
use servosight::sim::{Effect, EffectSet, MachineParams, ScenarioKind, Twin, TwinConfig};

/// Arguments of `servosight simulate`.
#[derive(Debug, clap::Args)]
#[command(
    after_help = "Examples:\n  servosight simulate --scenario production --hours 2 --seed 3 -o p.csv\n  \
servosight simulate --scenario doe --hours 48 --seed 1 -o db.csv\n  \
servosight simulate --scenario production --hours 8 --seed 3 --without ambient_temperature --noise 0 -o sim.csv\n  \
servosight simulate --scenario backlash-test --set x_axis.backlash_um=25 -o lash.csv"
)]
pub struct Args {
    /// The program: warmup, production, backlash-test or doe.
    #[arg(long, value_parser = parse_scenario)]
    pub scenario: ScenarioKind,
    /// Program length in hours (default: 0.75 for warmup, 8 for production, 24 for doe; the
    /// backlash test runs to its end).
    #[arg(long)]
    pub hours: Option<f64>,
    /// Seed of the program and the noise: the same seed gives the same file.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Sample rate in Hz (default: 1 for thermal scenarios, 500 for the backlash test).
    #[arg(long)]
    pub rate: Option<f64>,
    /// Leave an effect out of the physics (repeatable). Effects: ambient_temperature,
    /// thermal_inertia, speed_dependent_cooling, lubricant_viscosity, copper_loss, iron_loss,
    /// coolant, coulomb_reversal, position_dependent, backlash, signal_delay,
    /// sensor_offset_drift.
    #[arg(long = "without", value_name = "EFFECT", value_parser = parse_effect)]
    pub without: Vec<Effect>,
    /// Override a machine parameter, e.g. `x_axis.backlash_um=25` (repeatable).
    /// `--print-machine` lists them all.
    #[arg(long = "set", value_name = "PATH=VALUE")]
    pub set: Vec<String>,
    /// Multiply every sensor's noise (0 = noiseless).
    #[arg(long)]
    pub noise: Option<f64>,
    /// Share of the noise variance that is correlated in time (0–1).
    #[arg(long)]
    pub correlated_noise: Option<f64>,
    /// Print the machine parameters (with overrides applied) as JSON and exit.
    #[arg(long)]
    pub print_machine: bool,
    /// Output recording (CSV v1).
    #[arg(
        short = 'o',
        long = "output",
        required_unless_present = "print_machine"
    )]
    pub output: Option<PathBuf>,
}

fn parse_scenario(s: &str) -> Result<ScenarioKind, String> {
    s.parse()
}

fn parse_effect(s: &str) -> Result<Effect, String> {
    s.parse()
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let mut overrides = args.set.clone();
    if let Some(scale) = args.noise {
        overrides.push(format!("measurement.noise_scale={scale}"));
    }
    if let Some(fraction) = args.correlated_noise {
        overrides.push(format!("measurement.correlated_fraction={fraction}"));
    }
    let machine = MachineParams::default()
        .with_overrides(&overrides)
        .context("invalid --set/--noise")?;
    if args.print_machine {
        outln!("{}", serde_json::to_string_pretty(&machine)?)?;
        return Ok(());
    }
    let hours = args.hours.or(match args.scenario {
        ScenarioKind::Warmup => Some(0.75),
        ScenarioKind::Production => Some(8.0),
        ScenarioKind::Doe => Some(24.0),
        ScenarioKind::BacklashTest => None,
    });
    let effects = args
        .without
        .iter()
        .fold(EffectSet::all(), |set, effect| set.without(*effect));
    let config = TwinConfig {
        machine,
        effects,
        scenario: args.scenario,
        hours,
        rate_hz: args.rate.unwrap_or(args.scenario.default_rate_hz()),
        seed: args.seed,
    };
    let output = args
        .output
        .context("an output file is required (-o FILE.csv)")?;
    anyhow::ensure!(
        !crate::servosight_cli::is_stdout(&output),
        "-o - is not supported: the twin writes its recording to a file (-o FILE.csv)"
    );
    let started = std::time::Instant::now();
    let rows = write_simulation(config, &output)?;
    eprintln!(
        "wrote {} rows to {} in {:.2} s",
        rows,
        output.display(),
        started.elapsed().as_secs_f64()
    );
    Ok(())
}

/// Streams a twin run to a file, row by row (a long DOE never has to fit in memory).
pub fn write_simulation(config: TwinConfig, output: &std::path::Path) -> anyhow::Result<u64> {
    let mut twin = Twin::new(config).context("cannot start the twin")?;
    let mut writer = RecordingWriter::create(output, &twin.metadata(), twin.schema())?;
    let mut row = Vec::with_capacity(twin.schema().len());
    while twin.next_row(&mut row) {
        writer.write_row(&row)?;
    }
    let rows = writer.rows_written();
    writer.finish()?;
    Ok(rows)
}

/// `servosight day-summary`: the headless equivalent of the HMI — simulate a production day and summarise it.
pub fn run_default_day() -> anyhow::Result<()> {
    // A directory of this run's own: `create_dir` fails on a name somebody else took, so the
    // day is never written through a link planted under a shared, predictable name. It is
    // removed once summarised (a 10 h recording per run would pile up in the temp directory);
    // `simulate --scenario production -o FILE` keeps one.
    let stamp = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos());
    let dir = std::env::temp_dir().join(format!("servosight-day-{}-{stamp}", std::process::id()));
    std::fs::create_dir(&dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let path = dir.join("production-day.csv");
    let simulated = (|| {
        let config = TwinConfig::new(ScenarioKind::Production, Some(10.0), 1);
        let rows = write_simulation(config, &path)?;
        anyhow::Ok((rows, read_recording(&path)?))
    })();
    // Removed before anything is printed: a reader that goes away (`| head`) ends the process
    // at the next write. Best effort: a directory left behind holds nothing anybody asked for.
    let _ = std::fs::remove_dir_all(&dir);
    let (rows, recording) = simulated?;
    outln!("Simulated a production day on the twin: {rows} rows")?;
    crate::servosight_cli::inspect::print_day_summary(&recording)
}
