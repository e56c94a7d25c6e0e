//! Runs the estimator pipeline over a recording and scores every estimate against its
//! reference column, like the paper's Table 3.

use crate::fit::autocorrelation::white_noise_from_differences;
use crate::profile::MachineProfile;
use crate::signal::{AxisId, Recording, RecordingError, RowSource};

use super::abnormality::AbnormalityScore;

use super::pipeline::{ElongationOrigin, EstimateOutput, EstimatorPipeline, PipelineError};

/// Every estimate over a recording, column by column.
#[derive(Debug, Clone)]
pub struct EstimateSeries {
    /// What each column is.
    pub outputs: Vec<EstimateOutput>,
    /// One vector per output, one value per recording row.
    pub values: Vec<Vec<f64>>,
    /// Each axis's motor abnormality score at the end of the recording.
    pub abnormality: Vec<(AxisId, AbnormalityScore)>,
    /// What could not be estimated, and why.
    pub notes: Vec<String>,
}

/// Runs the profile's pipeline over every row of `recording`.
pub fn run(
    profile: &MachineProfile,
    recording: &Recording,
) -> Result<EstimateSeries, PipelineError> {
    let mut pipeline = EstimatorPipeline::new(profile, recording.schema())?;
    let outputs = pipeline.outputs();
    let mut values = vec![Vec::with_capacity(recording.len()); outputs.len()];
    let (mut row, mut out) = (
        Vec::with_capacity(recording.schema().len()),
        Vec::with_capacity(outputs.len()),
    );
    for i in 0..recording.len() {
        recording.row_into(i, &mut row);
        pipeline.update(&row);
        pipeline.write_outputs(&mut out);
        for (column, &v) in values.iter_mut().zip(&out) {
            column.push(v);
        }
    }
    Ok(EstimateSeries {
        outputs,
        values,
        abnormality: pipeline.abnormality_scores(),
        notes: pipeline.notes().to_vec(),
    })
}

/// What [`run_streaming`] keeps of a run: the scores and the end state, not the rows.
#[derive(Debug, Clone)]
pub struct StreamedRun {
    /// What each estimate is, in the order the rows hand them over.
    pub outputs: Vec<EstimateOutput>,
    /// Rows estimated.
    pub rows: usize,
    /// Every estimate whose reference column the recording has, scored as [`accuracy`] scores
    /// it.
    pub accuracy: Vec<AccuracyRow>,
    /// Per output: whether it was unknown (not finite) in some row.
    pub unknown_somewhere: Vec<bool>,
    /// Each axis's motor abnormality score at the end of the recording.
    pub abnormality: Vec<(AxisId, AbnormalityScore)>,
    /// Where each spindle's elongation counts from at the end of the recording (`None`: no
    /// finite estimate yet).
    pub elongation_origins: Vec<(AxisId, Option<ElongationOrigin>)>,
    /// What could not be estimated, and why.
    pub notes: Vec<String>,
}

/// Why a streamed run stopped.
#[derive(Debug, thiserror::Error)]
pub enum StreamError {
    /// The profile's pipeline cannot run on the recording's columns.
    #[error(transparent)]
    Pipeline(#[from] PipelineError),
    /// A row could not be read, or what was made of it not written.
    #[error(transparent)]
    Recording(#[from] RecordingError),
}

/// What [`run_streaming`] hands each row's time and estimates to; an error (a row that could
/// not be written) stops the run.
pub type RowSink<'a> = dyn FnMut(f64, &[f64]) -> Result<(), RecordingError> + 'a;

/// Runs the profile's pipeline over every row `reader` (a recording, or the pieces of one) has
/// left, handing each row's time and
/// estimates (in [`StreamedRun::outputs`] order) to `each` as they are made. Only what scores
/// the estimates against the reference columns the recording has is kept (two numbers a row
/// for each), so a recording without references (a real machine's) is estimated in constant
/// memory however long it is: hours of a servo drive's 1 kHz data. The scores are those of
/// [`accuracy`] on the same rows.
pub fn run_streaming<S: RowSource>(
    profile: &MachineProfile,
    mut reader: S,
    each: &mut RowSink<'_>,
) -> Result<StreamedRun, StreamError> {
    let mut pipeline = EstimatorPipeline::new(profile, reader.schema())?;
    let outputs = pipeline.outputs();
    // The outputs scored, with the index of their reference column, and their pairs.
    let scored: Vec<(usize, usize)> = outputs
        .iter()
        .enumerate()
        .filter_map(|(i, o)| Some((i, reader.schema().index_of(&o.reference)?)))
        .collect();
    let mut pairs = vec![(Vec::new(), Vec::new()); scored.len()];
    let mut unknown_somewhere = vec![false; outputs.len()];
    let (mut row, mut out) = (Vec::new(), Vec::with_capacity(outputs.len()));
    let mut rows = 0;
    while reader.read_row(&mut row)? {
        pipeline.update(&row);
        pipeline.write_outputs(&mut out);
        for (unknown, v) in unknown_somewhere.iter_mut().zip(&out) {
            *unknown |= !v.is_finite();
        }
        for ((output, reference), (estimates, references)) in scored.iter().zip(&mut pairs) {
            estimates.push(out[*output]);
            references.push(row[*reference]);
        }
        each(row[0], &out)?;
        rows += 1;
    }
    let accuracy = scored
        .iter()
        .zip(&pairs)
        .map(|((output, _), (estimates, references))| {
            let o = &outputs[*output];
            score(o, estimates, references)
        })
        .collect();
    Ok(StreamedRun {
        abnormality: pipeline.abnormality_scores(),
        elongation_origins: pipeline.elongation_origins(),
        notes: pipeline.notes().to_vec(),
        outputs,
        rows,
        accuracy,
        unknown_somewhere,
    })
}

/// Accuracy of one estimate against its reference (DESIGN.md's contract).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct AccuracyRow {
    /// Estimate id (`nut_temp`, `straightness_h#3`, …).
    pub estimate: String,
    /// The reference column.
    pub reference: String,
    /// What was subtracted from the reference for an estimate that counts from the first row
    /// (the spindle elongation: the reference at the tool-calibration moment); absent otherwise.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reference_offset: Option<f64>,
    /// Samples compared.
    pub n: usize,
    /// 1 − SSE/SST of the reference: the share of the reference's variance the estimate explains.
    pub r2: f64,
    /// Root mean squared error, in the reference's unit.
    pub rmse: f64,
    /// Largest absolute error.
    pub max_abs_error: f64,
    /// The reference instrument's white noise, estimated from the reference's own sample-to-
    /// sample differences (robustly: median absolute difference / (0.6745·√2)). Meaningful for
    /// references that change slowly between samples (temperatures, thermal displacements).
    pub reference_noise: f64,
    /// R² against the noise-free reference, `1 − (MSE − σ²)/(Var − σ²)` with σ =
    /// `reference_noise`: how much of the *true* variation the estimate explains, which a noisy
    /// reference caps below 1. `None` when the noise is not small against the variation.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub r2_noise_corrected: Option<f64>,
}

/// Scores every estimate whose reference column exists in `recording`.
pub fn accuracy(series: &EstimateSeries, recording: &Recording) -> Vec<AccuracyRow> {
    series
        .outputs
        .iter()
        .zip(&series.values)
        .filter_map(|(output, estimate)| {
            let reference = recording.try_column(&output.reference)?;
            Some(score(output, estimate, reference))
        })
        .collect()
}

/// R², RMSE and maximum error of `estimate` against `reference` (rows where either is not finite
/// are skipped). An output that [counts from the first row](EstimateOutput::counts_from_first_row)
/// is scored against the reference's change since the first row where both are known.
pub fn score(output: &EstimateOutput, estimate: &[f64], reference: &[f64]) -> AccuracyRow {
    let mut pairs: Vec<(f64, f64)> = estimate
        .iter()
        .zip(reference)
        .filter(|(e, r)| e.is_finite() && r.is_finite())
        .map(|(&e, &r)| (e, r))
        .collect();
    let reference_offset = output
        .counts_from_first_row
        .then(|| pairs.first().map(|&(_, r)| r))
        .flatten();
    if let Some(offset) = reference_offset {
        for (_, r) in &mut pairs {
            *r -= offset;
        }
    }
    let n = pairs.len();
    let mean = pairs.iter().map(|(_, r)| r).sum::<f64>() / n.max(1) as f64;
    let sse: f64 = pairs.iter().map(|(e, r)| (r - e).powi(2)).sum();
    let sst: f64 = pairs.iter().map(|(_, r)| (r - mean).powi(2)).sum();
    let reference: Vec<f64> = pairs.iter().map(|(_, r)| *r).collect();
    let reference_noise = white_noise_from_differences(&reference);
    let (mse, variance) = (sse / n.max(1) as f64, sst / n.max(1) as f64);
    let noise_variance = reference_noise * reference_noise;
    let r2_noise_corrected = (noise_variance < 0.5 * variance)
        .then(|| 1.0 - (mse - noise_variance).max(0.0) / (variance - noise_variance));
    AccuracyRow {
        estimate: output.id.clone(),
        reference: output.reference.clone(),
        reference_offset,
        n,
        r2: if sst > 0.0 { 1.0 - sse / sst } else { f64::NAN },
        rmse: (sse / n.max(1) as f64).sqrt(),
        max_abs_error: pairs.iter().map(|(e, r)| (r - e).abs()).fold(0.0, f64::max),
        reference_noise,
        r2_noise_corrected,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng, rngs::StdRng};
    use rand_distr::StandardNormal;

    /// Row by row from the file, the run scores every estimate as the run over the whole
    /// recording does, to the bit, hands over every row's estimates as they are, and says
    /// which were unknown somewhere.
    #[test]
    fn a_streamed_run_matches_the_run_over_the_whole_recording() {
        use crate::sim::{ScenarioKind, TwinConfig, simulate};
        let profile = MachineProfile::twin_calibrated().unwrap();
        let recording = simulate(TwinConfig::new(ScenarioKind::Production, Some(0.5), 5)).unwrap();
        let whole = run(&profile, &recording).unwrap();
        let mut text = Vec::new();
        crate::signal::write_recording_to(&mut text, &recording).unwrap();
        let reader =
            crate::signal::RecordingReader::from_reader(text.as_slice(), "twin.csv").unwrap();
        let mut handed: Vec<Vec<f64>> = Vec::new();
        let streamed = run_streaming(&profile, reader, &mut |time, values| {
            handed.push(
                std::iter::once(time)
                    .chain(values.iter().copied())
                    .collect(),
            );
            Ok(())
        })
        .unwrap();
        assert_eq!(streamed.rows, recording.len());
        assert_eq!(streamed.outputs, whole.outputs);
        let scores = accuracy(&whole, &recording);
        assert!(scores.len() > 10, "{} scored", scores.len());
        assert_eq!(format!("{:?}", streamed.accuracy), format!("{scores:?}"));
        for (i, row) in handed.iter().enumerate() {
            assert_eq!(row[0].to_bits(), recording.time()[i].to_bits());
            for (v, column) in row[1..].iter().zip(&whole.values) {
                assert_eq!(v.to_bits(), column[i].to_bits());
            }
        }
        let unknown: Vec<bool> = whole
            .values
            .iter()
            .map(|v| v.iter().any(|x| !x.is_finite()))
            .collect();
        assert_eq!(streamed.unknown_somewhere, unknown);
        assert!(
            unknown.iter().any(|&u| u),
            "the abnormality score starts unknown"
        );
        assert_eq!(streamed.notes, whole.notes);
    }

    /// An output named `x`, scored against `ref.x`.
    fn output(counts_from_first_row: bool) -> EstimateOutput {
        EstimateOutput {
            id: "x".into(),
            column: "est.x".into(),
            reference: "ref.x".into(),
            counts_from_first_row,
        }
    }

    #[test]
    fn score_matches_hand_computation() {
        let row = score(&output(false), &[1.0, 2.0, 4.0], &[1.0, 3.0, 5.0]);
        assert_eq!(row.reference_offset, None);
        // mean 3, SST = 4 + 0 + 4 = 8, SSE = 0 + 1 + 1 = 2.
        assert_eq!(row.n, 3);
        assert!((row.r2 - 0.75).abs() < 1e-12);
        assert!((row.rmse - (2.0_f64 / 3.0).sqrt()).abs() < 1e-12);
        assert_eq!(row.max_abs_error, 1.0);
    }

    /// An estimate that counts from the first row (the elongation since the tool calibration)
    /// is scored against the reference's change since the first row where both are known: a
    /// reference that starts at 5 µm and grows as the estimate does is met exactly.
    #[test]
    fn an_estimate_counted_from_the_first_row_meets_the_references_change() {
        let estimate = [f64::NAN, 0.0, 1.0, 3.0];
        let reference = [4.0, 5.0, 6.0, 8.0];
        let row = score(&output(true), &estimate, &reference);
        assert_eq!(row.reference_offset, Some(5.0));
        assert_eq!(
            (row.n, row.r2, row.rmse, row.max_abs_error),
            (3, 1.0, 0.0, 0.0)
        );
        // Scored against the value instead, the same pairs miss by 5 everywhere.
        let row = score(&output(false), &estimate, &reference);
        assert_eq!(row.max_abs_error, 5.0);
        assert!(row.r2 < -10.0, "{row:?}");
    }

    #[test]
    fn noise_of_a_slow_reference_is_recovered_and_removed_from_r2() {
        // A slow sine measured with σ = 0.2 white noise (a seeded stream) and an estimate that
        // is the noiseless sine itself: R² against the noisy reference is capped below 1,
        // against the noise-free one it is 1.
        let mut rng = StdRng::seed_from_u64(42);
        let n = 20_000;
        let truth: Vec<f64> = (0..n).map(|i| (i as f64 / 3000.0).sin() * 0.6).collect();
        let reference: Vec<f64> = truth
            .iter()
            .map(|t| t + 0.2 * rng.sample::<f64, _>(StandardNormal))
            .collect();
        let row = score(&output(false), &truth, &reference);
        assert!((row.reference_noise - 0.2).abs() < 0.01, "{row:?}");
        assert!(row.r2 < 0.85, "{row:?}");
        let corrected = row
            .r2_noise_corrected
            .expect("noise is small against the variation");
        assert!((corrected - 1.0).abs() < 0.02, "{row:?}");
    }
}
