//! Localisation: where in time the simulation misses, against a noise floor estimated from the
//! data, and the operating conditions there and where the simulation is right.
//!
//! The noise floor is the power of the final out-of-sample residual — what is left once every
//! significant correction is in — so its level and its autocorrelation both come from the data:
//! with correlated noise a window's mean power fluctuates more and the threshold rises with it. A region is a run of windows whose mismatch power (windowed mean
//! square of the part of the real signal the calibrated simulation does not explain) clears that
//! threshold. Power rather than mean is compared, so effects that flip sign within a window
//! (direction-dependent friction) are found as well as slow offsets.

use std::collections::BTreeMap;

use super::series::{mean, moving_average, rms};
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
    // The noise floor's power and how fast it decorrelates, from the held-out residual.
    let noise_power_series: Vec<f64> = noise.iter().map(|v| v * v).collect();
    let typical = mean(&noise_power_series);
    let spread = super::series::std_dev(&noise_power_series);
    let correlation =
        super::series::integrated_autocorrelation(&noise_power_series, (n / 4).max(2)).max(1.0);
    let mismatch_power: Vec<f64> = mismatch.iter().map(|v| v * v).collect();
    // Several scales: short windows find strong, brief mismatches; long ones find weak,
    // persistent ones. A window's mean noise power has a spread of σ·√(τ/W) (τ the integrated
    // autocorrelation time of the power), and a window is flagged five of those above the
    // typical noise power.
    let mut runs: Vec<(usize, usize)> = Vec::new();
    let mut threshold = f64::INFINITY;
    for scale in [50, 12, 4] {
        let w = (n / scale).clamp(10, 20_000).min(n.max(1));
        let level = typical + 5.0 * spread * (correlation / w as f64).sqrt().min(1.0);
        if scale == 50 {
            threshold = level;
        }
        let power = moving_average(&mismatch_power, w);
        let mut start: Option<usize> = None;
        for (i, p) in power.iter().enumerate() {
            match (start, *p > level) {
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
    }
    runs.sort();
    // Bridge short gaps and drop runs shorter than half a window: both are noise.
    let mut merged: Vec<(usize, usize)> = Vec::new();
    for run in runs {
        match merged.last_mut() {
            Some(last) if run.0 <= last.1 + window => last.1 = last.1.max(run.1),
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
