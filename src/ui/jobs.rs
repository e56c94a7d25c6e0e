//! Long work off the UI thread, with progress and cancel: one named thread per job
//! (`servosight-job`), progress through a bounded channel, cancel through a shared flag that
//! the job checks between steps.

use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc;

use super::state::JobProgress;
use crate::fit::{Design, FitReport, ols, parse_terms, sensitivity};
#[cfg(doc)]
use crate::signal::RecordingReader;
use crate::signal::{Recording, RecordingError, RecordingPieces};

/// What a job reports.
#[derive(Debug)]
pub enum JobMessage<T> {
    /// How far it has got.
    Progress(JobProgress),
    /// It finished.
    Done(T),
    /// It failed.
    Failed(String),
    /// It stopped because it was cancelled.
    Cancelled,
}

/// A running job.
pub struct Job<T> {
    messages: mpsc::Receiver<JobMessage<T>>,
    cancel: Arc<AtomicBool>,
    /// What the job does, for the event list.
    pub title: String,
}

impl<T: Send + 'static> Job<T> {
    /// Starts `work` on its own thread. `work` gets a [`JobContext`] to report progress and
    /// check for cancellation.
    pub fn spawn(
        title: impl Into<String>,
        work: impl FnOnce(&JobContext<T>) -> Result<T, JobStop> + Send + 'static,
    ) -> std::io::Result<Job<T>> {
        let (tx, rx) = mpsc::sync_channel(64);
        let cancel = Arc::new(AtomicBool::new(false));
        let context = JobContext {
            messages: tx,
            cancel: Arc::clone(&cancel),
        };
        std::thread::Builder::new()
            .name("servosight-job".into())
            .spawn(move || {
                let outcome = match work(&context) {
                    Ok(value) => JobMessage::Done(value),
                    Err(JobStop::Cancelled) => JobMessage::Cancelled,
                    Err(JobStop::Failed(reason)) => JobMessage::Failed(reason),
                };
                // The final message must arrive even when the UI is slow to drain: wait.
                let _ = context.messages.send(outcome);
            })?;
        Ok(Job {
            messages: rx,
            cancel,
            title: title.into(),
        })
    }

    /// Asks the job to stop at its next check.
    pub fn cancel(&self) {
        self.cancel.store(true, Ordering::Relaxed);
    }

    /// Waits (at most `limit`) for the job's end and returns its final message, skipping its
    /// progress; `None` if it has not ended by then. Not for the UI thread.
    pub fn wait_end(&self, limit: std::time::Duration) -> Option<JobMessage<T>> {
        let deadline = std::time::Instant::now() + limit;
        loop {
            let left = deadline.saturating_duration_since(std::time::Instant::now());
            match self.messages.recv_timeout(left) {
                Ok(JobMessage::Progress(_)) => {}
                Ok(end) => return Some(end),
                Err(mpsc::RecvTimeoutError::Timeout) => return None,
                Err(mpsc::RecvTimeoutError::Disconnected) => {
                    return Some(JobMessage::Failed(
                        "the job thread ended without a result".into(),
                    ));
                }
            }
        }
    }

    /// The next message, if one is waiting; never waits.
    pub fn try_next(&self) -> Option<JobMessage<T>> {
        match self.messages.try_recv() {
            Ok(message) => Some(message),
            Err(mpsc::TryRecvError::Empty) => None,
            Err(mpsc::TryRecvError::Disconnected) => Some(JobMessage::Failed(
                "the job thread ended without a result".into(),
            )),
        }
    }
}

/// Why a job stopped early.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum JobStop {
    /// The operator cancelled it.
    Cancelled,
    /// It failed, with the reason.
    Failed(String),
}

/// The job's end of the channel.
pub struct JobContext<T> {
    messages: mpsc::SyncSender<JobMessage<T>>,
    cancel: Arc<AtomicBool>,
}

impl<T> JobContext<T> {
    /// A context for running a job's work on the current thread (headless use, tests):
    /// messages go to `messages`, and the work stops once `cancel` is set.
    pub fn new(messages: mpsc::SyncSender<JobMessage<T>>, cancel: Arc<AtomicBool>) -> Self {
        JobContext { messages, cancel }
    }

    /// Reports progress; a full queue skips this report (a newer one follows).
    pub fn progress(&self, stage: &str, fraction: Option<f32>) {
        let _ = self.messages.try_send(JobMessage::Progress(JobProgress {
            stage: stage.to_string(),
            fraction,
        }));
    }

    /// `Err(JobStop::Cancelled)` once cancel was asked for.
    pub fn check(&self) -> Result<(), JobStop> {
        if self.cancel.load(Ordering::Relaxed) {
            Err(JobStop::Cancelled)
        } else {
            Ok(())
        }
    }
}

/// What the Model lab asks for.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FitRequest {
    /// The database (CSV v1).
    pub data: PathBuf,
    /// The column to explain.
    pub target: String,
    /// Terms in the `servosight fit` language.
    pub terms: String,
}

/// A fit with its source, for the Model lab.
#[derive(Debug, Clone)]
pub struct FitOutcome {
    /// What was asked.
    pub request: FitRequest,
    /// The report (statistics, coefficients, sensitivity ranking).
    pub report: FitReport,
}

/// The most rows a job reads of a recording, and what the message that refuses more tells
/// the user to do.
#[derive(Debug, Clone)]
pub struct RowLimit {
    /// The most rows read.
    pub rows: usize,
    /// Why no more, and what to do with a longer file.
    pub advice: String,
}

/// Reads a recording on a job's thread — one file, or the pieces of one recording in the order
/// they were recorded, read as one ([`RecordingPieces`]) — whole or (given `average_s`)
/// averaged over blocks of that many seconds as [`RecordingReader::read_averaged`] does,
/// reporting `stage (N rows)` with a fraction that moves through `span` as the bytes are read,
/// and stopping within [`RecordingReader::OBSERVED_EVERY`] rows of a cancel. Given a
/// [`RowLimit`], a recording with more rows (or blocks) fails the job at the row past them,
/// before the rest is read.
pub fn read_with_progress<T>(
    pieces: &[PathBuf],
    context: &JobContext<T>,
    stage: &str,
    span: std::ops::Range<f32>,
    limit: Option<&RowLimit>,
    average_s: Option<f64>,
) -> Result<Recording, JobStop> {
    let reader = RecordingPieces::open(pieces).map_err(|e| JobStop::Failed(e.to_string()))?;
    let progress = reader.progress();
    let averaging = average_s.map_or(String::new(), |s| format!(", averaging over {s} s"));
    // `false` (stop) once the job is cancelled.
    let mut observe = |rows: u64| {
        let fraction = progress.fraction();
        context.progress(
            &format!("{stage} ({rows} rows{averaging})"),
            Some(span.start + (span.end - span.start) * fraction),
        );
        context.check().is_ok()
    };
    let most = limit.map_or(usize::MAX, |l| l.rows);
    match reader.read_observed(most, average_s, &mut observe) {
        Ok(recording) => {
            context.check()?;
            Ok(recording)
        }
        Err(RecordingError::Stopped { .. }) => Err(JobStop::Cancelled),
        Err(e @ RecordingError::TooManyRows { .. }) => {
            let advice = limit.map_or("", |l| &l.advice);
            Err(JobStop::Failed(format!("{e}; {advice}")))
        }
        Err(e) => Err(JobStop::Failed(e.to_string())),
    }
}

/// Reads the database and fits the model, reporting progress; cancellable while the file is
/// read and between the fitting stages (a single QR of a million rows takes about half a
/// second and is not interrupted).
pub fn run_fit(
    request: FitRequest,
    context: &JobContext<FitOutcome>,
) -> Result<FitOutcome, JobStop> {
    let failed = |e: &dyn std::fmt::Display| JobStop::Failed(e.to_string());
    let terms = parse_terms(&request.terms).map_err(|e| failed(&e))?;
    if terms.is_empty() {
        return Err(JobStop::Failed(
            "the terms list only `const`: give at least one term to fit".into(),
        ));
    }
    context.progress("reading the database", Some(0.0));
    let recording = read_with_progress(
        std::slice::from_ref(&request.data),
        context,
        "reading the database",
        0.0..0.8,
        None,
        None,
    )?;
    let rows = recording.len();
    context.check()?;
    context.progress(&format!("building the design ({rows} rows)"), Some(0.8));
    let design =
        Design::from_recording(&recording, &request.target, &terms).map_err(|e| failed(&e))?;
    drop(recording);
    context.check()?;
    context.progress("fitting (QR least squares)", Some(0.85));
    let fit = ols(&design).map_err(|e| failed(&e))?;
    context.check()?;
    context.progress("sensitivity ranking", Some(0.95));
    let report = FitReport::new(&fit, sensitivity(&fit, &design));
    Ok(FitOutcome { request, report })
}
