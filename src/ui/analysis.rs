//! The analyses the warm-up checklist and the depth-of-cut panel run on the session's
//! full-rate samples: friction fingerprint, backlash and the maximum rough-cut depth.
//!
//! The UI thread only copies the few columns an analysis needs out of the history's full-rate
//! ring ([`super::history::History::raw_since`]); the analysis itself runs as a
//! [`super::jobs::Job`] with progress and cancel, so the UI never waits for it.

use serde::Serialize;

use super::history::History;
use super::jobs::{JobContext, JobStop};
use crate::estimators::backlash::{BacklashReport, analyse_backlash};
use crate::estimators::depth_of_cut::{
    DepthOfCutError, DepthOfCutRecommendation, recommend_depth_of_cut,
};
use crate::estimators::fingerprint::{FrictionFingerprint, fingerprint};
use crate::profile::{AxisKind, MachineProfile};
use crate::signal::channel::{CUT_DEPTH, TIME};
use crate::signal::{AxisId, Quantity, Recording, axis_column};

/// Why an analysis input could not be taken from the history.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum InputError {
    /// The link does not carry a column the analysis needs.
    #[error("the link has no `{0}` column, which {1} needs")]
    MissingColumn(String, &'static str),
    /// No full-rate samples in the window.
    #[error("no samples at full rate since {0:.1} s yet")]
    Empty(f64),
    /// The columns do not make a recording (a name given twice).
    #[error("{0}")]
    Columns(String),
}

/// A recording of `columns` (all present in the history) from machine time `t0` on, at full
/// rate, with a note saying what it covers.
pub fn recording_since(
    history: &History,
    columns: &[String],
    t0: f64,
    source: &str,
) -> Result<(Recording, String), InputError> {
    let indices: Vec<usize> = columns
        .iter()
        .filter_map(|c| history.channel_index(c))
        .collect();
    debug_assert_eq!(indices.len(), columns.len(), "callers check the columns");
    let raw = history.raw_since(&indices, t0);
    let n = raw.time_s.len();
    if n == 0 {
        return Err(InputError::Empty(t0));
    }
    let mut names = vec![TIME.to_string()];
    names.extend(columns.iter().cloned());
    let mut recording =
        Recording::new(source, names).map_err(|e| InputError::Columns(e.to_string()))?;
    let mut row = vec![0.0; columns.len() + 1];
    for i in 0..n {
        row[0] = raw.time_s[i];
        for (slot, column) in row[1..].iter_mut().zip(&raw.values) {
            *slot = column[i];
        }
        if recording.push_row(&row).is_err() {
            // A sample that breaks the format (NaN while the link was down): left out, the
            // analyses need only the usable ones.
            continue;
        }
    }
    let note = format!(
        "{} samples at full rate from {:.1} s to {:.1} s{}",
        recording.len(),
        raw.time_s[0],
        raw.time_s[n - 1],
        if raw.complete {
            String::new()
        } else {
            " (older samples are only on disk: the in-memory full-rate record is shorter than asked)"
                .to_string()
        }
    );
    Ok((recording, note))
}

fn require(history: &History, name: String, purpose: &'static str) -> Result<String, InputError> {
    match history.channel_index(&name) {
        Some(_) => Ok(name),
        None => Err(InputError::MissingColumn(name, purpose)),
    }
}

/// What the warm-up analysis works on.
#[derive(Debug, Clone)]
pub struct WarmupInput {
    /// The feed axis.
    pub axis: AxisId,
    /// Its screw lead, mm (turns feeds into motor speeds for the backlash test).
    pub lead_mm: f64,
    /// Speed, torque, command, position, current of the axis (and the depth of cut, so that
    /// cutting samples stay out of the fingerprint).
    pub recording: Recording,
    /// What the recording covers.
    pub note: String,
}

impl WarmupInput {
    /// Takes the samples since `t0` of the columns the fingerprint and the backlash test need.
    pub fn from_history(
        history: &History,
        axis: AxisId,
        lead_mm: f64,
        t0: f64,
    ) -> Result<WarmupInput, InputError> {
        let purpose = "the warm-up analysis";
        let mut columns = Vec::new();
        for quantity in [
            Quantity::Speed,
            Quantity::Torque,
            Quantity::Command,
            Quantity::Position,
            Quantity::Current,
        ] {
            columns.push(require(history, axis_column(axis, quantity), purpose)?);
        }
        if history.channel_index(CUT_DEPTH).is_some() {
            columns.push(CUT_DEPTH.to_string());
        }
        let (recording, note) = recording_since(history, &columns, t0, "the session")?;
        Ok(WarmupInput {
            axis,
            lead_mm,
            recording,
            note,
        })
    }
}

/// The warm-up analysis: fingerprint and backlash, each with its own success or reason.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct WarmupAnalysis {
    /// The axis.
    pub axis: AxisId,
    /// The friction fingerprint of the warm-up moves, or why it could not be taken.
    pub fingerprint: Result<FrictionFingerprint, String>,
    /// The backlash test's result, or why there is none.
    pub backlash: Result<BacklashReport, String>,
    /// What the samples cover.
    pub note: String,
}

/// Runs the fingerprint and the backlash analysis (a job's work).
pub fn run_warmup_analysis(
    input: WarmupInput,
    context: &JobContext<WarmupAnalysis>,
) -> Result<WarmupAnalysis, JobStop> {
    context.check()?;
    context.progress("friction fingerprint of the warm-up moves", Some(0.1));
    let fingerprint = fingerprint(&input.recording, input.axis).map_err(|e| e.to_string());
    context.check()?;
    context.progress("backlash from the reciprocating moves", Some(0.4));
    let backlash = reciprocating_segment(&input.recording, input.axis)
        .map_err(|e| e.to_string())
        .and_then(|segment| {
            analyse_backlash(&segment, input.axis, input.lead_mm).map_err(|e| e.to_string())
        });
    context.check()?;
    Ok(WarmupAnalysis {
        axis: input.axis,
        fingerprint,
        backlash,
        note: input.note,
    })
}

/// How far the command may wander from where a backlash test started, mm: the test
/// reciprocates by at most a few hundred micrometres around its centre.
const BACKLASH_TEST_SPAN_MM: f64 = 1.0;

/// The backlash test's part of a window that also holds other moves (the fingerprint's
/// full-stroke passes): the longest stretch in which the command stays within
/// `BACKLASH_TEST_SPAN_MM` of where the stretch began. The backlash fit searches up to the
/// largest move's amplitude, so a full-stroke pass left in would make it search metres in
/// 0.1 µm steps and drown the test's small moves.
pub fn reciprocating_segment(
    recording: &Recording,
    axis: AxisId,
) -> Result<Recording, crate::signal::RecordingError> {
    let command =
        recording.column_for(&axis_column(axis, Quantity::Command), "the backlash test")?;
    let (mut best, mut start, mut anchor) = ((0, 0), 0, command.first().copied().unwrap_or(0.0));
    for (i, c) in command.iter().enumerate() {
        if (c - anchor).abs() > BACKLASH_TEST_SPAN_MM {
            start = i;
            anchor = *c;
        }
        if i + 1 - start > best.1 - best.0 {
            best = (start, i + 1);
        }
    }
    let mut segment = Recording::with_schema(recording.source(), recording.schema().clone());
    let mut row = Vec::new();
    for i in best.0..best.1 {
        recording.row_into(i, &mut row);
        segment.push_row(&row)?;
    }
    Ok(segment)
}

/// What the depth-of-cut recommendation works on.
#[derive(Debug, Clone)]
pub struct DepthInput {
    /// The machine.
    pub profile: MachineProfile,
    /// Depth of cut and the spindle's and feed axes' speed and torque.
    pub recording: Recording,
    /// Diameter being turned, mm.
    pub workpiece_diameter_mm: f64,
    /// What the recording covers.
    pub note: String,
}

impl DepthInput {
    /// Takes every full-rate sample the history still holds of the columns the
    /// recommendation needs.
    pub fn from_history(
        history: &History,
        profile: &MachineProfile,
        workpiece_diameter_mm: f64,
    ) -> Result<DepthInput, InputError> {
        let purpose = "the depth-of-cut recommendation";
        let mut columns = vec![require(history, CUT_DEPTH.to_string(), purpose)?];
        for (axis, a) in &profile.axes {
            for quantity in [Quantity::Speed, Quantity::Torque] {
                let name = axis_column(*axis, quantity);
                match (a.kind, history.channel_index(&name)) {
                    (_, Some(_)) => columns.push(name),
                    // The spindle is required; a feed axis without signals is left out.
                    (AxisKind::Spindle, None) => {
                        return Err(InputError::MissingColumn(name, purpose));
                    }
                    (AxisKind::Feed, None) => {}
                }
            }
        }
        let t0 = history.oldest_raw_time_s().unwrap_or(0.0);
        let (recording, note) = recording_since(history, &columns, t0, "the session")?;
        Ok(DepthInput {
            profile: profile.clone(),
            recording,
            workpiece_diameter_mm,
            note,
        })
    }
}

/// How the depth-of-cut recommendation came out.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "outcome", rename_all = "snake_case")]
pub enum DepthOutcome {
    /// A recommendation.
    Ready {
        /// The recommendation with every component's limit.
        recommendation: DepthOfCutRecommendation,
        /// What the samples cover.
        note: String,
        /// Diameter it was computed for, mm.
        workpiece_diameter_mm: f64,
    },
    /// Too few cuts at different depths so far.
    NotEnoughData {
        /// Why, in words.
        reason: String,
        /// What the samples cover.
        note: String,
    },
}

/// Runs the recommendation (a job's work); too few cuts is an outcome, not a failure.
pub fn run_depth_of_cut(
    input: DepthInput,
    context: &JobContext<DepthOutcome>,
) -> Result<DepthOutcome, JobStop> {
    context.check()?;
    context.progress("regressing component loads on the chip section", Some(0.2));
    let result = recommend_depth_of_cut(
        &input.profile,
        &input.recording,
        input.workpiece_diameter_mm,
    );
    context.check()?;
    match result {
        Ok(recommendation) => Ok(DepthOutcome::Ready {
            recommendation,
            note: input.note,
            workpiece_diameter_mm: input.workpiece_diameter_mm,
        }),
        Err(DepthOfCutError::TooFewCuts(_, samples)) => Ok(DepthOutcome::NotEnoughData {
            reason: format!(
                "{samples} cutting samples so far; the recommendation needs at least 20 at \
                 three or more different depths: run a few roughing and finishing cuts"
            ),
            note: input.note,
        }),
        Err(error) => Err(JobStop::Failed(error.to_string())),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ui::history::HistoryConfig;

    #[test]
    fn missing_columns_are_named_and_samples_are_copied_at_full_rate() {
        let names: Vec<String> = ["X.speed_rpm", "X.torque_Nm"]
            .iter()
            .map(|s| s.to_string())
            .collect();
        let mut history = History::new(names, HistoryConfig::for_budget(2, 1 << 20));
        for i in 0..100 {
            let t = f64::from(i) * 0.01;
            history.push(t, &[100.0 * t, 0.5 + t]);
        }
        let err = WarmupInput::from_history(&history, AxisId::X, 10.0, 0.0).unwrap_err();
        assert!(err.to_string().contains("X.command_mm"), "{err}");
        let (recording, note) =
            recording_since(&history, &["X.torque_Nm".to_string()], 0.5, "s").unwrap();
        assert_eq!(recording.len(), 50);
        assert!((recording.time()[0] - 0.5).abs() < 1e-12);
        let torque = recording.column("X.torque_Nm").unwrap();
        assert!((torque[10] - 1.1).abs() < 1e-6, "{}", torque[10]);
        assert!(note.starts_with("50 samples"), "{note}");
        assert_eq!(
            recording_since(&history, &["X.torque_Nm".to_string()], 5.0, "s").unwrap_err(),
            InputError::Empty(5.0)
        );
    }

    #[test]
    fn the_backlash_segment_leaves_out_long_moves() {
        let mut recording = Recording::new("r", vec![TIME.into(), "X.command_mm".into()]).unwrap();
        let mut t = 0.0;
        // A full-stroke pass, then small reciprocation around 200 mm, then another pass.
        for x in (0..=40).map(|k| 10.0 * f64::from(k)) {
            recording.push_row(&[t, x]).unwrap();
            t += 0.1;
        }
        for k in 0..200 {
            recording
                .push_row(&[t, 200.0 + 0.001 * f64::from(k % 50)])
                .unwrap();
            t += 0.1;
        }
        for x in (0..=40).map(|k| 400.0 - 10.0 * f64::from(k)) {
            recording.push_row(&[t, x]).unwrap();
            t += 0.1;
        }
        let segment = reciprocating_segment(&recording, AxisId::X).unwrap();
        assert_eq!(segment.len(), 200);
        let command = segment.column("X.command_mm").unwrap();
        assert!(command.iter().all(|c| (c - 200.0).abs() < 0.1));
    }
}
