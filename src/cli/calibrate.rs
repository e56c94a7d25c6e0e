//! `servosight calibrate`: fit every estimator from a simulation database and a few experiments.

use std::path::PathBuf;

use anyhow::Context;
use servosight::estimators::calibration::calibrate;
use servosight::profile::MachineProfile;
use servosight::signal::read_recording;

/// Arguments of `servosight calibrate`.
#[derive(Debug, clap::Args)]
#[command(
    after_help = "Example:\n  servosight simulate --scenario doe --hours 48 --seed 1 -o db.csv\n  \
servosight simulate --scenario production --hours 4 --seed 2 -o exp.csv\n  \
servosight calibrate --database db.csv --experiments exp.csv -o profile.toml --json report.json"
)]
pub struct Args {
    /// Simulation database recordings (CSV v1 with reference columns), repeatable.
    #[arg(long = "database", required = true, num_args = 1..)]
    pub database: Vec<PathBuf>,
    /// Experiment recordings that correct the database, repeatable.
    #[arg(long = "experiments", num_args = 1..)]
    pub experiments: Vec<PathBuf>,
    /// Machine profile to start from (geometry, ratings, limits); default: the twin's machine.
    #[arg(long)]
    pub profile: Option<PathBuf>,
    /// Where to write the calibrated profile (TOML).
    #[arg(short = 'o', long = "output")]
    pub output: PathBuf,
    /// Write the calibration report as JSON to this file ("-" for stdout).
    #[arg(long)]
    pub json: Option<PathBuf>,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let mut profile = match &args.profile {
        Some(path) => MachineProfile::load(path)?,
        None => MachineProfile::twin_default(),
    };
    let read_all = |paths: &[PathBuf]| {
        paths
            .iter()
            .map(|p| read_recording(p).with_context(|| "cannot read recording".to_string()))
            .collect::<anyhow::Result<Vec<_>>>()
    };
    let database = read_all(&args.database)?;
    let experiments = read_all(&args.experiments)?;
    let (calibration, report) =
        calibrate(&profile, &database, &experiments).context("calibration failed")?;
    profile.calibration = Some(calibration);
    profile.validate("the calibrated profile")?;
    profile.save(&args.output)?;
    println!(
        "{:<34} {:>8} {:>8} {:>8} {:>12}  equation",
        "model", "n", "R²", "CV R²", "F"
    );
    for m in &report.models {
        println!(
            "{:<34} {:>8} {:>8.4} {:>8.4} {:>12.4e}  {}",
            m.estimate, m.n, m.r2, m.cv_r2, m.f_statistic, m.equation
        );
        if let Some(c) = &m.experiment_correction {
            println!(
                "{:<34} experiments: n = {}, measured = {:+.4} + {:.4}·predicted, p = {:.2e}, RMSE {:.4} → {:.4} ({})",
                "",
                c.n,
                c.offset,
                c.gain,
                c.p_value,
                c.rmse_before,
                c.rmse_after,
                if c.applied {
                    "applied"
                } else {
                    "not significant, not applied"
                }
            );
        }
    }
    println!("calibrated profile written to {}", args.output.display());
    if let Some(path) = &args.json {
        crate::servosight_cli::write_json(path, &report)?;
    }
    Ok(())
}
