//! `servosight inspect FILE.csv [PIECE.csv…]`: what is in a recording (or in the pieces of
//! one, read as one), or exactly where it is broken.

use std::path::PathBuf;

use crate::servosight_cli::pieces::{LaterPieces, recording_files};
use crate::servosight_cli::{out, outln, refuse_overwriting_inputs};
use anyhow::Context;
use servosight::signal::{Channel, Recording, RecordingError, RecordingPieces};

/// Arguments of `servosight inspect`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The recording to summarise (CSV v1); several files are the pieces of one recording,
    /// summarised as one in the order given (the recorder starts a new piece every hour:
    /// shift.csv shift-0001.csv …), so a piece missing between them shows as a gap.
    #[arg(required = true, num_args = 1..)]
    pub file: Vec<PathBuf>,
    #[command(flatten)]
    pub pieces: LaterPieces,
    /// Report a gap where the time step exceeds this many median steps.
    #[arg(long, default_value_t = 3.0)]
    pub gap_factor: f64,
    /// Write the summary as JSON to this file ("-" for stdout) instead of the table.
    #[arg(long)]
    pub json: Option<PathBuf>,
}

/// The summary of one column.
#[derive(Debug, serde::Serialize)]
struct ColumnSummary {
    name: String,
    unit: Option<&'static str>,
    kind: &'static str,
    min: f64,
    max: f64,
    mean: f64,
}

/// The summary of a recording.
#[derive(Debug, serde::Serialize)]
struct Summary {
    file: String,
    rows: usize,
    columns: usize,
    duration_s: f64,
    sample_rate_hz: Option<f64>,
    metadata: Vec<(String, String)>,
    gaps: Vec<Gap>,
    column_summaries: Vec<ColumnSummary>,
    /// The file ended in the middle of a line (a recorder stopped by a power loss) and that
    /// line was left out.
    last_line_cut_short: bool,
}

#[derive(Debug, serde::Serialize)]
struct Gap {
    after_s: f64,
    length_s: f64,
}

pub fn run(mut args: Args) -> anyhow::Result<()> {
    args.file = recording_files(&args.file, &args.pieces, "FILE")?.0;
    anyhow::ensure!(
        args.gap_factor.is_finite() && args.gap_factor > 1.0,
        "--gap-factor must be a number above 1 (a gap is a step longer than that many median \
         steps), not {}",
        args.gap_factor
    );
    let inputs: Vec<&std::path::Path> = args.file.iter().map(PathBuf::as_path).collect();
    refuse_overwriting_inputs(&inputs, &[args.json.as_deref()])?;
    let (mut summary, cut_short) = summarise_allowing_a_cut_last_line(&args.file, args.gap_factor)?;
    if let Some(note) = &cut_short {
        eprintln!("warning: {note}");
    }
    summary.last_line_cut_short = cut_short.is_some();
    anyhow::ensure!(
        summary.rows > 0,
        "{} has a header but no data rows: nothing to summarise",
        RecordingPieces::name(&args.file)
    );
    match &args.json {
        Some(path) => crate::servosight_cli::write_json(path, &summary)?,
        None => print_table(&summary)?,
    }
    Ok(())
}

/// A summary built row by row: each column's least, greatest and sum, and the time column
/// alone (the median step and the gaps need every step), so a recording is summarised
/// holding 8 bytes a row instead of 8 bytes a value (a 46-column recording: a 46th).
struct SummaryBuilder {
    names: Vec<String>,
    /// Per column: least, greatest, sum.
    columns: Vec<(f64, f64, f64)>,
    time: Recording,
}

impl SummaryBuilder {
    fn new(source: &str, names: &[String]) -> anyhow::Result<SummaryBuilder> {
        Ok(SummaryBuilder {
            names: names.to_vec(),
            columns: vec![(f64::INFINITY, f64::NEG_INFINITY, 0.0); names.len()],
            time: Recording::new(source, vec![servosight::signal::channel::TIME.to_string()])?,
        })
    }

    fn push(&mut self, row: &[f64]) -> anyhow::Result<()> {
        for ((lo, hi, sum), &v) in self.columns.iter_mut().zip(row) {
            (*lo, *hi, *sum) = (lo.min(v), hi.max(v), *sum + v);
        }
        self.time.push_row(&row[..1])?;
        Ok(())
    }

    fn finish(self, metadata: Vec<(String, String)>, gap_factor: f64) -> Summary {
        let rows = self.time.len();
        let column_summaries = self
            .names
            .iter()
            .zip(&self.columns)
            .map(|(name, &(min, max, sum))| ColumnSummary {
                name: name.clone(),
                unit: Channel::unit_of(name),
                kind: kind_of(&Channel::parse(name)),
                min: if rows == 0 { 0.0 } else { min },
                max: if rows == 0 { 0.0 } else { max },
                mean: sum / rows.max(1) as f64,
            })
            .collect();
        let time = self.time.time();
        Summary {
            file: self.time.source().to_string(),
            rows,
            columns: self.names.len(),
            duration_s: self.time.duration_s(),
            sample_rate_hz: self.time.sample_rate_hz(),
            metadata,
            gaps: self
                .time
                .gaps(gap_factor)
                .into_iter()
                .map(|(i, length_s)| Gap {
                    after_s: time[i],
                    length_s,
                })
                .collect(),
            column_summaries,
            last_line_cut_short: false,
        }
    }
}

/// Summarises a recording (or the pieces of one, as one) as it is read, never holding it
/// whole; when the only fault is a last line cut short in the last piece (a recorder that lost
/// power mid-write), summarises everything before it and says so. Any other fault is an error
/// as usual.
fn summarise_allowing_a_cut_last_line(
    paths: &[PathBuf],
    gap_factor: f64,
) -> anyhow::Result<(Summary, Option<RecordingError>)> {
    let name = RecordingPieces::name(paths);
    // Every row of `pieces` into a new summary of `name`.
    let stream = |pieces: &[PathBuf]| -> anyhow::Result<(SummaryBuilder, Vec<(String, String)>)> {
        let mut reader = RecordingPieces::open(pieces)?;
        let metadata = reader.metadata().to_vec();
        let mut builder = SummaryBuilder::new(&name, reader.schema().names())?;
        let mut row = Vec::new();
        while reader.read_row(&mut row)? {
            builder.push(&row)?;
        }
        Ok((builder, metadata))
    };
    let error = match stream(paths) {
        Ok((builder, metadata)) => return Ok((builder.finish(metadata, gap_factor), None)),
        Err(error) => error,
    };
    let Some((last, earlier)) = paths.split_last() else {
        return Err(error).context("cannot read recording");
    };
    let Ok((cut_piece, Some(cut))) = servosight::link::recorder::read_possibly_truncated(last)
    else {
        return Err(error).context("cannot read recording");
    };
    let (mut builder, metadata) = if earlier.is_empty() {
        let builder = SummaryBuilder::new(&name, cut_piece.names())?;
        (builder, cut_piece.metadata().to_vec())
    } else {
        // The pieces before it whole, then what the cut piece holds (every header checked).
        if let Err(error) = RecordingPieces::open(paths) {
            return Err(error).context("cannot read recording");
        }
        stream(earlier).context("cannot read recording")?
    };
    let mut row = Vec::new();
    for i in 0..cut_piece.len() {
        cut_piece.row_into(i, &mut row);
        builder.push(&row).with_context(|| {
            format!(
                "{}: this piece starts before the piece before it ends: give the pieces in the \
                 order they were recorded",
                last.display()
            )
        })?;
    }
    Ok((builder.finish(metadata, gap_factor), Some(cut)))
}

fn kind_of(channel: &Channel) -> &'static str {
    match channel {
        Channel::Time => "time",
        Channel::Servo { .. } => "servo",
        Channel::Ambient | Channel::Coolant => "machine",
        Channel::Reference { .. } => "reference",
        Channel::Unknown => "other",
    }
}

fn print_table(summary: &Summary) -> anyhow::Result<()> {
    outln!("{}", summary.file)?;
    outln!(
        "  {} rows × {} columns, {:.1} s ({})",
        summary.rows,
        summary.columns,
        summary.duration_s,
        crate::servosight_cli::human_duration(summary.duration_s)
    )?;
    match summary.sample_rate_hz {
        Some(rate) => outln!(
            "  sample rate {rate:.4} Hz (median step {:.6} s)",
            1.0 / rate
        )?,
        None => outln!("  sample rate: fewer than two distinct times")?,
    }
    for (key, value) in &summary.metadata {
        if key.is_empty() {
            outln!("  # {value}")?;
        } else {
            outln!("  {key}: {value}")?;
        }
    }
    if summary.gaps.is_empty() {
        outln!("  no gaps")?;
    } else {
        outln!("  {} gap(s):", summary.gaps.len())?;
        for gap in summary.gaps.iter().take(20) {
            outln!(
                "    after t = {:.3} s: {:.3} s without samples",
                gap.after_s,
                gap.length_s
            )?;
        }
        if summary.gaps.len() > 20 {
            outln!("    … {} more", summary.gaps.len() - 20)?;
        }
    }
    let width = summary
        .column_summaries
        .iter()
        .map(|c| c.name.len())
        .max()
        .unwrap_or(6)
        .max(6);
    outln!(
        "  {:<width$}  {:>5}  {:>9}  {:>14}  {:>14}  {:>14}",
        "column",
        "unit",
        "kind",
        "min",
        "max",
        "mean"
    )?;
    for c in &summary.column_summaries {
        outln!(
            "  {:<width$}  {:>5}  {:>9}  {:>14.6}  {:>14.6}  {:>14.6}",
            c.name,
            c.unit.unwrap_or(""),
            c.kind,
            c.min,
            c.max,
            c.mean
        )?;
    }
    Ok(())
}

/// An hour-by-hour summary of a shift on the twin: what ran, how hot it got, how far the spindle
/// grew. Columns a recording lacks are left out of the table.
pub fn print_day_summary(recording: &Recording) -> anyhow::Result<()> {
    use servosight::signal::{AxisId, Quantity, axis_column, reference_column};
    let time = recording.time();
    let wanted = [
        ("S rpm", axis_column(AxisId::S, Quantity::Speed)),
        ("S load %", axis_column(AxisId::S, Quantity::Load)),
        ("S stator °C", axis_column(AxisId::S, Quantity::StatorTemp)),
        ("X stator °C", axis_column(AxisId::X, Quantity::StatorTemp)),
        ("X nut °C", reference_column(AxisId::X, "nut_temp_C", None)),
        ("room °C", servosight::signal::channel::AMBIENT.to_string()),
        (
            "S elong. µm",
            reference_column(AxisId::S, "elongation_um", None),
        ),
    ];
    let columns: Vec<(&str, &[f64])> = wanted
        .iter()
        .filter_map(|(label, name)| recording.try_column(name).map(|c| (*label, c)))
        .collect();
    let start_h: f64 = recording
        .metadata_value("start_clock_h")
        .and_then(|v| v.parse().ok())
        .unwrap_or(0.0);
    out!("{:>7}", "clock")?;
    for (label, _) in &columns {
        out!("  {label:>11}")?;
    }
    outln!()?;
    let hours = (recording.duration_s() / 3600.0).ceil() as usize;
    for hour in 0..hours {
        let (from, to) = (hour as f64 * 3600.0, (hour + 1) as f64 * 3600.0);
        let rows: Vec<usize> = (0..time.len())
            .filter(|&i| time[i] >= from && time[i] < to)
            .collect();
        if rows.is_empty() {
            continue;
        }
        let clock = start_h + hour as f64;
        out!("{:>4}:00", clock as u32 % 24)?;
        for (_, values) in &columns {
            let mean = rows.iter().map(|&i| values[i]).sum::<f64>() / rows.len() as f64;
            out!("  {mean:>11.2}")?;
        }
        outln!()?;
    }
    if let Some(elongation) =
        recording.try_column(&reference_column(AxisId::S, "elongation_um", None))
    {
        let (lo, hi) = elongation
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &v| {
                (l.min(v), h.max(v))
            });
        outln!(
            "spindle thermal elongation over the shift: {lo:.1} to {hi:.1} µm (range {:.1} µm)",
            hi - lo
        )?;
    }
    Ok(())
}
