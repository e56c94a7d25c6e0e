//! Localisation: where in time the simulation misses, against a noise floor estimated from the
//! data, and the operating conditions there and where the simulation is right.
//!
//! The noise floor is the windowed mean square of the final out-of-sample residual — what is
//! left once every significant correction is in — so its level and its autocorrelation both come
//! from the data: with correlated noise the windowed mean square fluctuates more and the
//! threshold rises with it. A region is a run of windows whose mismatch power (windowed mean
//! square of the part of the real signal the calibrated simulation does not explain) clears that
//! threshold. Power rather than mean is compared, so effects that flip sign within a window
//! (direction-dependent friction) are found as well as slow offsets.

use std::collections::BTreeMap;

use super::series::{mean, median, moving_average, rms, robust_sigma};
use crate::signal::channel::{AMBIENT, COOLANT, CUT_DEPTH};
use crate::signal::{AxisId, Quantity, axis_column};

/// A span of the recording with the residual there and the operating conditions.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Region {
    /// Start, s.
    pub start_s: f64,
    /// End, s.
    pub end_s: f64,
    /// Mean of the mismatch (real minus calibrated simulation), target unit.
    pub mean_residual: f64,
    /// RMS of the mismatch, target unit.
    pub rms_residual: f64,
    /// Operating conditions: mean |speed| and |load| per axis, share of time moving, coolant
    /// share, mean depth of cut, mean room temperature (keys are column names).
    pub conditions: BTreeMap<String, f64>,
}

/// The real recording's operating signals on the aligned rows.
#[derive(Debug, Clone, Default)]
pub struct Conditions {
    columns: Vec<(String, Vec<f64>, Summary)>,
}

#[derive(Debug, Clone, Copy)]
enum Summary {
    MeanAbs,
    Mean,
    MovingShare,
}

impl Conditions {
    /// Collects the operating signals that exist in the real recording.
    pub fn new(aligned: &super::align::Aligned<'_>) -> Conditions {
        let mut columns = Vec::new();
        for axis in AxisId::ALL {
            let speed_name = axis_column(axis, Quantity::Speed);
            if let Some(speed) = aligned.real_column(&speed_name) {
                let top = speed.iter().fold(0.0_f64, |a, v| a.max(v.abs()));
                let moving: Vec<f64> = speed
                    .iter()
                    .map(|v| f64::from(u8::from(v.abs() > 0.02 * top)))
                    .collect();
                columns.push((speed_name.clone(), speed, Summary::MeanAbs));
                columns.push((
                    format!("{speed_name}:moving_share"),
                    moving,
                    Summary::MovingShare,
                ));
            }
            let load_name = axis_column(axis, Quantity::Load);
            if let Some(load) = aligned.real_column(&load_name) {
                columns.push((load_name, load, Summary::MeanAbs));
            }
        }
        for name in [COOLANT, CUT_DEPTH, AMBIENT] {
            if let Some(values) = aligned.real_column(name) {
                columns.push((name.to_string(), values, Summary::Mean));
            }
        }
        Conditions { columns }
    }

    /// The conditions over rows `range`.
    pub fn over(&self, range: std::ops::Range<usize>) -> BTreeMap<String, f64> {
        self.columns
            .iter()
            .map(|(name, values, summary)| {
                let slice = &values[range.clone()];
                let value = match summary {
                    Summary::MeanAbs => mean(&slice.iter().map(|v| v.abs()).collect::<Vec<_>>()),
                    Summary::Mean | Summary::MovingShare => mean(slice),
                };
                (name.clone(), value)
            })
            .collect()
    }
}

/// The outcome of localisation.
#[derive(Debug, Clone)]
pub struct Localisation {
    /// Where the simulation misses.
    pub mismatch: Vec<Region>,
    /// Where it is right (the spans between mismatch regions).
    pub agreement: Vec<Region>,
    /// Window of the power estimates, s.
    pub window_s: f64,
    /// Mean-square threshold a window must clear, target unit².
    pub threshold: f64,
}

/// Most regions of each kind reported (the largest by mismatch energy when there are more).
const MAX_REGIONS: usize = 40;

/// Finds the mismatch regions of `mismatch` given the out-of-sample residual `noise`.
pub fn localise(
    time: &[f64],
    mismatch: &[f64],
    noise: &[f64],
    conditions: &Conditions,
) -> Localisation {
    let n = time.len();
    let window = (n / 50).clamp(10, 3600).min(n.max(1));
    let step = if n > 1 {
        (time[n - 1] - time[0]) / (n - 1) as f64
    } else {
        1.0
    };
    let noise_power = moving_average(&noise.iter().map(|v| v * v).collect::<Vec<_>>(), window);
    let typical = median(&noise_power);
    let threshold = typical + 5.0 * robust_sigma(&noise_power);
    let power = moving_average(&mismatch.iter().map(|v| v * v).collect::<Vec<_>>(), window);
    let mut runs: Vec<(usize, usize)> = Vec::new();
    let mut start: Option<usize> = None;
    for (i, p) in power.iter().enumerate() {
        match (start, *p > threshold) {
            (None, true) => start = Some(i),
            (Some(s), false) => {
                runs.push((s, i));
                start = None;
            }
            _ => {}
        }
    }
    if let Some(s) = start {
        runs.push((s, n));
    }
    // Bridge short gaps and drop runs shorter than half a window: both are noise.
    let mut merged: Vec<(usize, usize)> = Vec::new();
    for run in runs {
        match merged.last_mut() {
            Some(last) if run.0 - last.1 < window => last.1 = run.1,
            _ => merged.push(run),
        }
    }
    merged.retain(|(a, b)| b - a >= window / 2);
    if merged.len() > MAX_REGIONS {
        let energy = |&(a, b): &(usize, usize)| mismatch[a..b].iter().map(|v| v * v).sum::<f64>();
        merged.sort_by(|x, y| energy(y).total_cmp(&energy(x)));
        merged.truncate(MAX_REGIONS);
        merged.sort();
    }
    let region = |(a, b): (usize, usize)| Region {
        start_s: time[a],
        end_s: time[b - 1],
        mean_residual: mean(&mismatch[a..b]),
        rms_residual: rms(&mismatch[a..b]),
        conditions: conditions.over(a..b),
    };
    let mismatch_regions: Vec<Region> = merged.iter().map(|&r| region(r)).collect();
    let mut gaps = Vec::new();
    let mut cursor = 0usize;
    for &(a, b) in &merged {
        if a > cursor {
            gaps.push((cursor, a));
        }
        cursor = b;
    }
    if cursor < n {
        gaps.push((cursor, n));
    }
    gaps.retain(|(a, b)| b - a >= window.min(n));
    if gaps.len() > MAX_REGIONS {
        gaps.sort_by_key(|(a, b)| std::cmp::Reverse(b - a));
        gaps.truncate(MAX_REGIONS);
        gaps.sort();
    }
    Localisation {
        mismatch: mismatch_regions,
        agreement: gaps.into_iter().map(region).collect(),
        window_s: window as f64 * step,
        threshold,
    }
}
