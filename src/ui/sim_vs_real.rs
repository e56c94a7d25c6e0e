//! The Model lab's sim-vs-real discrepancy job: read a simulation and a real recording, run
//! [`crate::discrepancy::analyse`] on them, and put the plot-ready series into a small
//! decimation pyramid (the same [`History`] the Trends panel draws from), all on the job's
//! thread. Also the cheap companion job that reads the two files' headers so the panel can
//! offer the columns they share as targets.
//!
//! The job reports reading both files and then the analysis's own progress (its phases and
//! selection steps, through [`analyse_observed`]); a cancel stops the analysis at its next
//! stopping point, and the app drops a cancelled job at once, so the panel is free even in
//! the moment before the thread notices.

use std::path::{Path, PathBuf};

use super::history::{History, HistoryConfig};
use super::jobs::{JobContext, JobStop, RowLimit, read_with_progress};
use crate::discrepancy::{
    DiscrepancyError, DiscrepancyReport, Options, RowBudget, analyse_observed,
};
use crate::signal::channel::TIME;
#[cfg(doc)]
use crate::signal::later_pieces;
use crate::signal::{RecordingPieces, RecordingReader, with_later_pieces};

/// What the Model lab asks the discrepancy analysis for.
#[derive(Debug, Clone, PartialEq)]
pub struct DiscrepancyRequest {
    /// The simulation (CSV v1).
    pub sim: PathBuf,
    /// The real recording (CSV v1): one file, or the pieces of one recording in the order they
    /// were recorded, read as one.
    pub real: Vec<PathBuf>,
    /// Read, after the first real file, the pieces the recorder continued it in, found beside
    /// it ([`later_pieces`]) instead of the rest of `real`: the Model lab's default, since a
    /// recorder starts a new file every hour and a slow effect needs the whole shift.
    pub find_later_pieces: bool,
    /// The column compared.
    pub target: String,
    /// Read both recordings averaged over blocks of this many seconds (as
    /// `servosight discrepancy --average` does); `None` reads them at their own rate.
    pub average_s: Option<f64>,
}

/// The Model lab's "Average over (s)" field as a block length: blank reads the recordings at
/// their own rate, a positive number of seconds averages them; anything else is refused with
/// a message that quotes it.
pub fn parse_average(text: &str) -> Result<Option<f64>, String> {
    let text = text.trim();
    if text.is_empty() {
        return Ok(None);
    }
    match text.parse::<f64>() {
        Ok(s) if s.is_finite() && s > 0.0 => Ok(Some(s)),
        _ => Err(format!(
            "average over: `{text}` is not a positive number of seconds (leave it blank to \
             read the recordings at their own rate)"
        )),
    }
}

/// The channels of [`DiscrepancyOutcome::plot`], in storage order.
pub const PLOT_CHANNELS: [&str; 5] = [
    "real",
    "sim",
    "corrected",
    "residual_before",
    "residual_after",
];

impl DiscrepancyRequest {
    /// The real recording's files to read: `real`, or its first file and the later pieces found
    /// beside it. Lists a directory, so only on a job's thread.
    pub fn real_pieces(&self) -> Result<Vec<PathBuf>, String> {
        match self.real.first() {
            Some(first) if self.find_later_pieces => with_later_pieces(first, true),
            _ => Ok(self.real.clone()),
        }
    }
}

/// A finished analysis with its source.
#[derive(Debug, Clone)]
pub struct DiscrepancyOutcome {
    /// What was asked.
    pub request: DiscrepancyRequest,
    /// The real recording's files that were read.
    pub real_read: Vec<PathBuf>,
    /// The report (its `plot` holds the library's plot-ready series).
    pub report: DiscrepancyReport,
    /// The report's plot series ([`PLOT_CHANNELS`]) in a decimation pyramid, so each frame
    /// draws a window of at most a few thousand points without touching the full series.
    pub plot: History,
}

impl DiscrepancyOutcome {
    /// The outcome of `request` on the real files `real_read`, its plot series put into their
    /// pyramid.
    pub fn new(
        request: DiscrepancyRequest,
        real_read: Vec<PathBuf>,
        report: DiscrepancyReport,
    ) -> DiscrepancyOutcome {
        let plot = plot_history(&report);
        DiscrepancyOutcome {
            request,
            real_read,
            report,
            plot,
        }
    }
}

/// The plot series of `report` in a [`History`] that holds every point at full rate (the
/// library already bins them to a few thousand) with one coarser level above.
pub fn plot_history(report: &DiscrepancyReport) -> History {
    let p = &report.plot;
    let n = p.time_s.len();
    let config = HistoryConfig {
        raw_capacity: n.max(16),
        factor: 8,
        level_capacities: Vec::new(),
    };
    let mut history = History::new(
        PLOT_CHANNELS.iter().map(|c| c.to_string()).collect(),
        config,
    );
    let columns = [
        &p.real,
        &p.sim,
        &p.corrected,
        &p.residual_before,
        &p.residual_after,
    ];
    let mut row = [0.0f64; PLOT_CHANNELS.len()];
    for (i, &t) in p.time_s.iter().enumerate() {
        for (value, column) in row.iter_mut().zip(columns) {
            // A series shorter than the time axis would be a library bug; draw a gap.
            *value = column.get(i).copied().unwrap_or(f64::NAN);
        }
        history.push(t, &row);
    }
    history
}

/// Share of the job's progress bar the analysis takes (reading the files takes the first 40 %,
/// the plots the last 5 %).
const ANALYSIS_SPAN: std::ops::Range<f32> = 0.4..0.95;

/// Reads both files and analyses them with the default [`Options`] (what the proof in
/// `docs/discrepancy.md` ran), reporting the reading and the analysis's progress and stopping
/// when cancelled; the library's errors (target missing, no overlap in time, too short) come
/// back as the job's failure, word for word.
pub fn run_discrepancy(
    request: DiscrepancyRequest,
    context: &JobContext<DiscrepancyOutcome>,
) -> Result<DiscrepancyOutcome, JobStop> {
    if request.target.is_empty() {
        return Err(JobStop::Failed("choose the column to compare".into()));
    }
    context.progress("reading the simulation", Some(0.0));
    // Never more rows than the analysis takes: a recording too long for it is refused while
    // it is read, before it fills the memory the HMI shares with the live machine's history.
    // Fewer where the memory free now would not hold the analysis beside the live machine.
    let budget = RowBudget::now();
    let advice = if request.average_s.is_some() {
        "average them over longer blocks of time (Average over)"
    } else {
        "read them averaged over blocks of a few seconds (Average over), which a temperature \
         that moves over minutes does not notice"
    };
    let limit = RowLimit {
        rows: budget.rows,
        advice: format!("{}; {advice}", budget.reason()),
    };
    let real_read = request.real_pieces().map_err(JobStop::Failed)?;
    let sim = read_with_progress(
        std::slice::from_ref(&request.sim),
        context,
        "reading the simulation",
        0.0..0.2,
        Some(&limit),
        request.average_s,
    )?;
    context.progress("reading the real recording", Some(0.2));
    let real = read_with_progress(
        &real_read,
        context,
        "reading the real recording",
        0.2..0.4,
        Some(&limit),
        request.average_s,
    )?;
    let observer = |fraction: f32, stage: &str| {
        let span = ANALYSIS_SPAN.end - ANALYSIS_SPAN.start;
        context.progress(
            &format!("analysing: {stage}"),
            Some(ANALYSIS_SPAN.start + span * fraction),
        );
        context.check().is_ok()
    };
    let report = analyse_observed(&sim, &real, &request.target, &Options::default(), &observer)
        .map_err(|e| match e {
            DiscrepancyError::Cancelled => JobStop::Cancelled,
            other => JobStop::Failed(other.to_string()),
        })?;
    context.check()?;
    context.progress("preparing the plots", Some(0.95));
    Ok(DiscrepancyOutcome::new(request, real_read, report))
}

/// Where [`save_report`] wrote a report.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SavedDiscrepancyReport {
    /// The JSON report, as `servosight discrepancy --json` writes it.
    pub json: PathBuf,
    /// The readable report beside it, as the command prints it.
    pub text: PathBuf,
}

/// The readable report's file for the JSON report at `json`: the same name ending `.txt`.
pub fn text_path_beside(json: &Path) -> PathBuf {
    json.with_extension("txt")
}

/// Writes `report` as the command's JSON contract to `json` and its readable text (what
/// `servosight discrepancy` prints) beside it ([`text_path_beside`]), each to a temporary
/// file in the same directory that is renamed into place once whole, so a failed save never
/// leaves half a report where an earlier one was. A path that names no file, or whose text
/// report would be the JSON itself (a `.txt` name), is refused before anything is written.
pub fn save_report(
    report: &DiscrepancyReport,
    json: &Path,
) -> Result<SavedDiscrepancyReport, String> {
    if json.as_os_str().is_empty() || json.file_name().is_none() {
        return Err("choose a file for the report (its JSON; the text goes beside it)".into());
    }
    let text = text_path_beside(json);
    if text == json {
        return Err(format!(
            "{}: the readable report would overwrite the JSON; give the JSON file a .json name",
            json.display()
        ));
    }
    let contract = serde_json::to_string_pretty(report)
        .map_err(|e| format!("cannot serialise the report: {e}"))?
        + "\n";
    for (path, body) in [(json, contract), (text.as_path(), report.summary())] {
        write_whole(path, body.as_bytes()).map_err(|e| format!("{}: {e}", path.display()))?;
    }
    Ok(SavedDiscrepancyReport {
        json: json.to_path_buf(),
        text,
    })
}

/// Writes `bytes` to `path` through a temporary file beside it, synced and then renamed.
fn write_whole(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    use std::io::Write as _;
    let mut name = path.file_name().unwrap_or_default().to_os_string();
    name.push(".partial");
    let partial = path.with_file_name(name);
    let written = std::fs::File::create(&partial).and_then(|mut file| {
        file.write_all(bytes)?;
        file.sync_all()
    });
    match written.and_then(|()| std::fs::rename(&partial, path)) {
        Ok(()) => Ok(()),
        Err(e) => {
            // Best effort: the partial file is ours and worthless; the error is what matters.
            let _ = std::fs::remove_file(&partial);
            Err(e)
        }
    }
}

/// Saves the last analysis's report on a job thread (file I/O stays off the UI thread).
pub fn run_save_report(
    report: DiscrepancyReport,
    json: PathBuf,
    context: &JobContext<SavedDiscrepancyReport>,
) -> Result<SavedDiscrepancyReport, JobStop> {
    context.progress("writing the report", None);
    save_report(&report, &json).map_err(JobStop::Failed)
}

/// The columns two recordings share (besides `time_s`), in the real recording's order.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SharedColumns {
    /// The simulation that was read.
    pub sim: PathBuf,
    /// The real recording that was asked for.
    pub real: PathBuf,
    /// Whether the later pieces beside it were looked for.
    pub find_later_pieces: bool,
    /// Its files whose headers were read: `real`, then the later pieces found.
    pub real_pieces: Vec<PathBuf>,
    /// What both have.
    pub columns: Vec<String>,
}

/// Reads only the headers of both recordings (a few kilobytes each) for the target choice;
/// given `find_later_pieces`, also finds the pieces the recorder continued the real one in and
/// checks that each has its columns, so the panel can say what the analysis will read.
pub fn read_shared_columns(
    sim: PathBuf,
    real: PathBuf,
    find_later_pieces: bool,
    context: &JobContext<SharedColumns>,
) -> Result<SharedColumns, JobStop> {
    context.progress("reading the headers", None);
    let in_sim = RecordingReader::open(&sim)
        .map(|reader| reader.schema().names().to_vec())
        .map_err(|e| JobStop::Failed(e.to_string()))?;
    context.check()?;
    let real_pieces = with_later_pieces(&real, find_later_pieces).map_err(JobStop::Failed)?;
    let in_real = RecordingPieces::open(&real_pieces)
        .map(|pieces| pieces.schema().names().to_vec())
        .map_err(|e| JobStop::Failed(e.to_string()))?;
    let columns = in_real
        .into_iter()
        .filter(|c| c != TIME && in_sim.contains(c))
        .collect();
    Ok(SharedColumns {
        sim,
        real,
        find_later_pieces,
        real_pieces,
        columns,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::discrepancy::PlotData;

    /// The report is written as the command's JSON and text, the text beside the JSON, with
    /// nothing else left in the directory; a second save replaces both. A path the text would
    /// share with the JSON, or no file at all, is refused before anything is written, and a
    /// directory that does not exist is named in the error.
    #[test]
    fn a_saved_report_is_the_commands_json_and_text_side_by_side() {
        let dir = tempfile::tempdir().unwrap();
        let report = consistent_report(10);
        let json = dir.path().join("bearing.json");
        let saved = save_report(&report, &json).unwrap();
        assert_eq!(saved.text, dir.path().join("bearing.txt"));
        let written: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
        assert_eq!(written, serde_json::to_value(&report).unwrap());
        assert_eq!(
            std::fs::read_to_string(&saved.text).unwrap(),
            report.summary()
        );
        let mut other = consistent_report(20);
        other.target = "S.torque_Nm".into();
        save_report(&other, &json).unwrap();
        let written: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
        assert_eq!(written["target"], "S.torque_Nm");
        let mut names: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .collect();
        names.sort();
        assert_eq!(names, ["bearing.json", "bearing.txt"]);

        let error = save_report(&report, &dir.path().join("notes.txt")).unwrap_err();
        assert!(
            error.contains("notes.txt: the readable report would overwrite"),
            "{error}"
        );
        let error = save_report(&report, Path::new("")).unwrap_err();
        assert!(error.starts_with("choose a file for the report"), "{error}");
        let missing = dir.path().join("no-such-dir").join("r.json");
        let error = save_report(&report, &missing).unwrap_err();
        assert!(error.contains("no-such-dir"), "{error}");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 2);
    }

    /// Blank reads every row; a positive number of seconds (spaces around it allowed) is a
    /// block; zero, negative, not-a-number, infinite and words are refused, quoted.
    #[test]
    fn the_average_field_is_blank_or_a_positive_number_of_seconds() {
        assert_eq!(parse_average(""), Ok(None));
        assert_eq!(parse_average("  "), Ok(None));
        assert_eq!(parse_average(" 2.5 "), Ok(Some(2.5)));
        assert_eq!(parse_average("1e-3"), Ok(Some(0.001)));
        for bad in ["0", "-1", "NaN", "inf", "ten", "1 s"] {
            let error = parse_average(bad).unwrap_err();
            assert!(
                error.contains(&format!("`{bad}` is not a positive number of seconds")),
                "{error}"
            );
        }
    }

    /// A consistent report of `n` rows without plot series.
    fn consistent_report(n: usize) -> DiscrepancyReport {
        crate::discrepancy::DiscrepancyReport {
            target: "S.stator_temp_C".into(),
            rows: n,
            verdict: crate::discrepancy::Verdict::Consistent,
            baseline: crate::discrepancy::FitQuality { r2: 1.0, rmse: 0.0 },
            improved: crate::discrepancy::FitQuality { r2: 1.0, rmse: 0.0 },
            calibrated: crate::discrepancy::FitQuality { r2: 1.0, rmse: 0.0 },
            mismatch_regions: Vec::new(),
            agreement_regions: Vec::new(),
            findings: Vec::new(),
            calibration: crate::discrepancy::Calibration {
                offset: 0.0,
                gain: 1.0,
                gain_absorbed: false,
                explanation: String::new(),
                indistinguishable_from: Vec::new(),
                alternatives: Vec::new(),
            },
            noise_floor: crate::discrepancy::NoiseFloor {
                rms: 0.0,
                correlation_time_s: 1.0,
                sample_noise_rms: 0.0,
                window_s: 1.0,
            },
            alignment: crate::discrepancy::Alignment {
                resampled: false,
                on_simulation_grid: false,
                placed_by_speed: 0,
                note: String::new(),
                start_s: 0.0,
                end_s: 999.0,
                censoring: None,
                read_later_s: None,
                readings_as_bounds: None,
            },
            not_tested: Vec::new(),
            method: crate::discrepancy::Method {
                folds: 2,
                surrogates: 1,
                alpha: 0.01,
                selection_rows: n,
                candidates: 0,
                steps: Vec::new(),
            },
            plot: PlotData::default(),
        }
    }

    #[test]
    fn the_plot_pyramid_keeps_every_series_and_decimates_on_request() {
        let n = 1000;
        let time_s: Vec<f64> = (0..n).map(|i| i as f64).collect();
        let ramp: Vec<f64> = time_s.iter().map(|t| t * 0.5).collect();
        let mut report = consistent_report(n);
        report.plot = PlotData {
            target: report.target.clone(),
            time_s: time_s.clone(),
            real: ramp.clone(),
            sim: vec![0.0; n],
            corrected: ramp.clone(),
            residual_before: ramp.clone(),
            residual_after: vec![0.0; n],
            regions: Vec::new(),
        };
        let history = plot_history(&report);
        assert_eq!(history.channels().len(), PLOT_CHANNELS.len());
        let all: Vec<usize> = (0..PLOT_CHANNELS.len()).collect();
        let full = history.window(&all, 0.0, 999.0, 2000);
        assert_eq!(full.len(), n, "every point when the budget allows");
        assert_eq!(full.series[0].mean[10], 5.0);
        let coarse = history.window(&all, 0.0, 999.0, 50);
        assert!(coarse.len() <= 50 && coarse.len() >= 25, "{}", coarse.len());
        // Bucket means of a ramp stay on the ramp.
        for (t, v) in coarse.time_s.iter().zip(&coarse.series[3].mean) {
            assert!((f64::from(*v) - 0.5 * t).abs() < 1.0, "{t} {v}");
        }
    }
}
