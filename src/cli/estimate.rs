//! `servosight estimate`: run every estimator over a recording; score against references.
#![allow(non_snake_case)] // unit suffixes are part of the JSON field names

use std::path::PathBuf;

use crate::servosight_cli::pieces::{LaterPieces, recording_files};
use crate::servosight_cli::{emit_report, outln, refuse_overwriting_inputs};
use anyhow::Context;
use servosight::estimators::abnormality::{AbnormalityState, judge};
use servosight::estimators::accuracy::{AccuracyRow, StreamError, StreamedRun, run_streaming};
use servosight::estimators::models::WARM_START_FLOOR_K;
use servosight::estimators::pipeline::ElongationOrigin;
use servosight::profile::MachineProfile;
use servosight::signal::{RecordingPieces, RecordingWriter, Schema};

/// Arguments of `servosight estimate`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// A calibrated machine profile.
    #[arg(long)]
    pub profile: PathBuf,
    /// The recording to estimate over; several files are the pieces of one recording, read as
    /// one in the order given (the recorder starts a new piece every hour: shift.csv,
    /// shift-0001.csv, …): the estimators carry on from piece to piece.
    #[arg(long, required = true, num_args = 1..)]
    pub recording: Vec<PathBuf>,
    #[command(flatten)]
    pub pieces: LaterPieces,
    /// Write the estimates (time plus one column per estimate) to this CSV. An estimate that is
    /// not known in every row is 0 where unknown and has a `<column>_valid` 0/1 column.
    #[arg(short = 'o', long = "output")]
    pub output: Option<PathBuf>,
    /// Write `{rows, accuracy: [...]}` as JSON to this file ("-" for stdout).
    #[arg(long)]
    pub json: Option<PathBuf>,
}

/// The JSON report.
#[derive(Debug, serde::Serialize)]
struct Report<'a> {
    rows: usize,
    accuracy: &'a [AccuracyRow],
    abnormality: Vec<AbnormalityRow>,
    elongation_origins: Vec<ElongationOriginRow>,
    notes: Vec<String>,
}

/// Where a spindle's estimated elongation counts from: the growth before then is not in it.
#[derive(Debug, serde::Serialize)]
struct ElongationOriginRow {
    axis: String,
    /// `null` while no finite estimate has been made.
    counted_from: Option<ElongationOrigin>,
}

/// [`ElongationOriginRow`] in words.
fn describe_origin(origin: Option<ElongationOrigin>) -> String {
    match origin {
        Some(ElongationOrigin::FirstFrameAtRest { time_s }) => format!(
            "the first estimate, at machine time {time_s:.1} s, the spindle at rest then (its stator no more than {WARM_START_FLOOR_K} K above the room)"
        ),
        Some(ElongationOrigin::FirstFrameWarm { time_s, excess_K }) => format!(
            "the first estimate, at machine time {time_s:.1} s, the spindle {excess_K:.1} K above the room then: the growth before then is not in it"
        ),
        Some(ElongationOrigin::FirstFrameUnread { time_s }) => format!(
            "the first estimate, at machine time {time_s:.1} s, without a room or stator reading that says whether the spindle was at rest"
        ),
        Some(ElongationOrigin::AcrossGap {
            time_s,
            gap_end_s,
            gap_s,
        }) => format!(
            "machine time {time_s:.1} s, with a gap of {gap_s:.0} s in the recording before {gap_end_s:.1} s: the growth in the gap is not known"
        ),
        Some(ElongationOrigin::ToolMeasured { time_s, .. }) => {
            format!("the tool measurement at machine time {time_s:.1} s")
        }
        None => "nothing yet: no finite estimate".into(),
    }
}

/// One axis's motor abnormality score at the end of the recording.
#[derive(Debug, serde::Serialize)]
struct AbnormalityRow {
    axis: String,
    state: AbnormalityState,
    /// `null` until the score is trustworthy.
    excess_pct: Option<f64>,
    standard_error_pct: Option<f64>,
    excess_Nm: Option<f64>,
    ideal_Nm: Option<f64>,
    steady_blocks: u64,
    reason: String,
}

/// The columns of the estimates file: time, then each estimate, followed by its
/// `<column>_valid` where it was unknown in some row. The format has no empty cells, so such
/// an estimate (the abnormality score before enough steady running) is written as 0 where
/// unknown, and its valid column is 1 where it is known.
fn estimate_columns(run: &StreamedRun) -> Vec<String> {
    let mut names = vec!["time_s".to_string()];
    for (output, &gappy) in run.outputs.iter().zip(&run.unknown_somewhere) {
        names.push(output.column.clone());
        if gappy {
            names.push(format!("{}_valid", output.column));
        }
    }
    names
}

/// Runs the pipeline over the recording again and writes the estimates row by row as they
/// are made: the first pass (`first`) said which estimates were unknown somewhere, which
/// the header must name before the first row. Only the rows the first pass read are written
/// (a recording still being recorded grows between the passes), and an estimate unknown
/// where the first pass knew it stops the write rather than being written as a silent zero.
fn write_estimates(
    path: &std::path::Path,
    args: &Args,
    profile: &MachineProfile,
    first: &StreamedRun,
) -> anyhow::Result<()> {
    let schema = Schema::new(estimate_columns(first), &path.display().to_string())?;
    let metadata = [
        (
            "estimated_from".to_string(),
            RecordingPieces::name(&args.recording),
        ),
        ("profile".to_string(), args.profile.display().to_string()),
    ];
    let mut writer = RecordingWriter::create(path, &metadata, &schema)?;
    let mut row = Vec::with_capacity(schema.len());
    let reader = RecordingPieces::open(&args.recording).context("cannot read recording")?;
    let gappy = &first.unknown_somewhere;
    let mut written = 0;
    run_streaming(profile, reader, &mut |time, values| {
        if written == first.rows {
            return Ok(());
        }
        written += 1;
        if let Some(output) = values
            .iter()
            .zip(gappy)
            .position(|(v, &gappy)| !v.is_finite() && !gappy)
        {
            return Err(servosight::signal::RecordingError::Io {
                source_name: RecordingPieces::name(&args.recording),
                error: std::io::Error::other(format!(
                    "the recording changed while it was estimated: `{}` is unknown at {time} s \
                     on the second pass, known on the first",
                    first.outputs[output].column
                )),
            });
        }
        row.clear();
        row.push(time);
        for (&v, &gappy) in values.iter().zip(gappy) {
            row.push(if v.is_finite() { v } else { 0.0 });
            if gappy {
                row.push(if v.is_finite() { 1.0 } else { 0.0 });
            }
        }
        writer.write_row(&row)
    })?;
    writer.finish()?;
    Ok(())
}

pub fn run(mut args: Args) -> anyhow::Result<()> {
    let (files, left_out) = recording_files(&args.recording, &args.pieces, "--recording")?;
    args.recording = files;
    anyhow::ensure!(
        !args
            .output
            .as_deref()
            .is_some_and(crate::servosight_cli::is_stdout),
        "-o - is not supported: the estimates go to a file (-o EST.csv)"
    );
    let inputs: Vec<&std::path::Path> = std::iter::once(args.profile.as_path())
        .chain(args.recording.iter().map(PathBuf::as_path))
        .collect();
    refuse_overwriting_inputs(&inputs, &[args.output.as_deref(), args.json.as_deref()])?;
    let profile = MachineProfile::load(&args.profile)?;
    // Row by row, never the whole recording in memory (hours of 1 kHz servo data are
    // gigabytes); the estimates file, if asked for, in a second pass.
    let reader = RecordingPieces::open(&args.recording).context("cannot read recording")?;
    let series = run_streaming(&profile, reader, &mut |_, _| Ok(())).map_err(|e| match e {
        StreamError::Recording(e) => anyhow::Error::new(e).context("cannot read recording"),
        other => other.into(),
    })?;
    anyhow::ensure!(
        series.rows > 0,
        "{} has a header but no data rows: nothing to estimate",
        RecordingPieces::name(&args.recording)
    );
    let rows = &series.accuracy;
    let finite = |v: f64| v.is_finite().then_some(v);
    let abnormality: Vec<AbnormalityRow> = series
        .abnormality
        .iter()
        .map(|(axis, score)| {
            let levels = profile
                .axis(*axis)
                .map(|a| a.limits.abnormality)
                .context("abnormality score of an axis the profile does not have")?;
            let (state, reason) = judge(score, levels);
            Ok(AbnormalityRow {
                axis: axis.to_string(),
                state,
                excess_pct: finite(score.excess_pct),
                standard_error_pct: finite(score.standard_error_pct),
                excess_Nm: finite(score.excess_Nm),
                ideal_Nm: finite(score.ideal_Nm),
                steady_blocks: score.steady_blocks,
                reason,
            })
        })
        .collect::<anyhow::Result<_>>()?;
    if let Some(path) = &args.output {
        write_estimates(path, &args, &profile, &series)?;
    }
    let report = Report {
        rows: series.rows,
        accuracy: rows,
        abnormality,
        elongation_origins: series
            .elongation_origins
            .iter()
            .map(|&(axis, counted_from)| ElongationOriginRow {
                axis: axis.to_string(),
                counted_from,
            })
            .collect(),
        // What was left out of the recording first: it bears on every figure after it.
        notes: left_out
            .into_iter()
            .chain(series.notes.iter().cloned())
            .collect(),
    };
    emit_report(args.json.as_deref(), &report, || {
        if rows.is_empty() {
            outln!(
                "{} rows estimated; the recording has no reference columns to score against",
                series.rows
            )?;
        } else {
            outln!(
                "{:<24} {:>8} {:>8} {:>10} {:>10} {:>9} {:>10}  reference",
                "estimate",
                "n",
                "R²",
                "RMSE",
                "max |err|",
                "ref σ",
                "R² true"
            )?;
            for r in rows {
                let corrected = r
                    .r2_noise_corrected
                    .map_or_else(|| "—".to_string(), |v| format!("{v:.4}"));
                outln!(
                    "{:<24} {:>8} {:>8.4} {:>10.4} {:>10.4} {:>9.4} {:>10}  {}",
                    r.estimate,
                    r.n,
                    r.r2,
                    r.rmse,
                    r.max_abs_error,
                    r.reference_noise,
                    corrected,
                    match r.reference_offset {
                        Some(offset) if offset < 0.0 => {
                            format!("{} + {:.4} (its first row)", r.reference, -offset)
                        }
                        Some(offset) => format!("{} − {offset:.4} (its first row)", r.reference),
                        None => r.reference.clone(),
                    }
                )?;
            }
            outln!(
                "R² true: against the noise-free reference, with the reference's white noise (ref σ) estimated from its sample-to-sample differences"
            )?;
        }
        for row in &report.abnormality {
            outln!(
                "motor abnormality {}: {} — {}",
                row.axis,
                row.state.label(),
                row.reason
            )?;
        }
        for row in &report.elongation_origins {
            outln!(
                "elongation {} counted from {}",
                row.axis,
                describe_origin(row.counted_from)
            )?;
        }
        for note in &series.notes {
            outln!("note: {note}")?;
        }
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use servosight::signal::{read_recording, write_recording};
    use servosight::sim::{ScenarioKind, TwinConfig, simulate};

    /// The second pass writes only the rows the first one read, so a recording that grew
    /// between them (still being recorded) gets estimates for what was scored; an estimate
    /// unknown where the first pass knew it stops the write instead of becoming a silent 0.
    #[test]
    fn the_estimates_file_holds_the_first_passs_rows_and_no_silent_zero() {
        let dir = tempfile::tempdir().unwrap();
        let profile_path =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/it25-twin.toml");
        let profile = MachineProfile::load(&profile_path).unwrap();
        let recording = dir.path().join("r.csv");
        let short = simulate(TwinConfig::new(ScenarioKind::Production, Some(0.1), 3)).unwrap();
        write_recording(&recording, &short).unwrap();
        let reader = servosight::signal::RecordingReader::open(&recording).unwrap();
        let first = run_streaming(&profile, reader, &mut |_, _| Ok(())).unwrap();
        // The recording grows before the second pass.
        let long = simulate(TwinConfig::new(ScenarioKind::Production, Some(0.2), 3)).unwrap();
        write_recording(&recording, &long).unwrap();
        let output = dir.path().join("est.csv");
        let args = Args {
            profile: profile_path,
            recording: vec![recording.clone()],
            output: Some(output.clone()),
            json: None,
            pieces: LaterPieces::default(),
        };
        write_estimates(&output, &args, &profile, &first).unwrap();
        assert!(long.len() > first.rows);
        assert_eq!(read_recording(&output).unwrap().len(), first.rows);

        let mut sure = first.clone();
        sure.unknown_somewhere.iter_mut().for_each(|u| *u = false);
        let error = write_estimates(&output, &args, &profile, &sure).unwrap_err();
        assert!(
            format!("{error:#}").contains("the recording changed while it was estimated"),
            "{error:#}"
        );
    }
}
