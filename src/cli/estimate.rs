//! `servosight estimate`: run every estimator over a recording; score against references.

use std::path::PathBuf;

use anyhow::Context;
use servosight::estimators::accuracy::{AccuracyRow, accuracy, run as run_estimators};
use servosight::profile::MachineProfile;
use servosight::signal::{Recording, read_recording, write_recording};

/// Arguments of `servosight estimate`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// A calibrated machine profile.
    #[arg(long)]
    pub profile: PathBuf,
    /// The recording to estimate over.
    #[arg(long)]
    pub recording: PathBuf,
    /// Write the estimates (time plus one column per estimate) to this CSV.
    #[arg(short = 'o', long = "output")]
    pub output: Option<PathBuf>,
    /// Write `{rows, accuracy: [...]}` as JSON to this file ("-" for stdout).
    #[arg(long)]
    pub json: Option<PathBuf>,
}

/// The JSON report.
#[derive(Debug, serde::Serialize)]
struct Report {
    rows: usize,
    accuracy: Vec<AccuracyRow>,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let profile = MachineProfile::load(&args.profile)?;
    let recording = read_recording(&args.recording).context("cannot read recording")?;
    let series = run_estimators(&profile, &recording)?;
    let rows = accuracy(&series, &recording);
    if let Some(path) = &args.output {
        let mut names = vec!["time_s".to_string()];
        names.extend(series.outputs.iter().map(|o| o.column.clone()));
        let mut out = Recording::new(path.display().to_string(), names)?;
        out.set_metadata("estimated_from", recording.source());
        out.set_metadata("profile", &args.profile.display().to_string());
        let mut row = Vec::with_capacity(series.outputs.len() + 1);
        for i in 0..recording.len() {
            row.clear();
            row.push(recording.time()[i]);
            row.extend(series.values.iter().map(|v| v[i]));
            out.push_row(&row)?;
        }
        write_recording(path, &out)?;
    }
    if rows.is_empty() {
        println!(
            "{} rows estimated; the recording has no reference columns to score against",
            recording.len()
        );
    } else {
        println!(
            "{:<24} {:>8} {:>8} {:>10} {:>10}  reference",
            "estimate", "n", "R²", "RMSE", "max |err|"
        );
        for r in &rows {
            println!(
                "{:<24} {:>8} {:>8.4} {:>10.4} {:>10.4}  {}",
                r.estimate, r.n, r.r2, r.rmse, r.max_abs_error, r.reference
            );
        }
    }
    if let Some(path) = &args.json {
        crate::servosight_cli::write_json(
            path,
            &Report {
                rows: recording.len(),
                accuracy: rows,
            },
        )?;
    }
    Ok(())
}
