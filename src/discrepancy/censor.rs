//! The instrument's floor: a real signal recorded as a magnitude (a drive's current, a load
//! percentage) cannot read below zero. Where the true value sits at that floor — a spindle at
//! standstill — the instrument shows its noise cut off at the floor, so the recording's mean
//! lies about 0.4 σ above the truth there while a noiseless simulation shows the floor itself.
//! Compared as they are, the two differ by a step wherever the machine stops, and every
//! correction that switches with motion (viscous drag, Coulomb friction…) would be named for
//! it. The simulation is instead compared as the instrument would read it.
//!
//! The noise is not assumed stationary: an instrument's offset that wanders over an hour is
//! followed by the running readings both ways but by the standstill readings only above the
//! floor, and a single cut-off model turns that wander into a contrast between running and
//! standing that only a speed-switched correction can fit. So each stretch where the
//! simulation sits at the floor (a *standstill span*) gets its own latent level μ — the mean
//! the instrument would read there without its floor — and the simulation is raised there by
//! what the floor adds to the span's mean reading: the residual is μ plus the readings' own
//! scatter, on the same footing as the running rows' residual. μ comes from the span's own
//! readings (a censored-normal fit) when they are enough and not nearly all cut off; when they
//! are, they only bound μ from above, and each reading at the floor is taken at its expected
//! value below it given the level of the running rows beside the span — the data cannot tell
//! the two apart there, so the analysis is not handed a contrast the readings do not show.
//!
//! A recording that trails the simulation (a transport delay) stops late: the first rows of
//! each simulated standstill still read a running current. The spans are therefore found on
//! the simulation shifted onto the real standstills ([`Censoring::standstill_lag_rows`]); the
//! delay itself is left in the residual for the analysis to name.

use statrs::distribution::{ContinuousCDF, Normal};

use crate::fit::autocorrelation::white_noise_of_steps;
use crate::fit::distributions::{standard_normal_cdf, standard_normal_pdf};

/// Fewest readings at the floor that identify one (and estimate the noise there).
const MIN_AT_FLOOR: usize = 30;
/// Smallest share of all rows at the floor.
const MIN_SHARE: f64 = 0.01;
/// The floor must hold this many times more readings than any other single value: a
/// quantised signal (a temperature logged to 0.1 K) repeats its minimum too, but no more often
/// than its other levels.
const POINT_MASS_RATIO: usize = 5;
/// Share of readings at the floor inside which a span's noise is measured from the cut-off
/// itself (outside it, the share or the excess carries too little to separate level and
/// scatter).
const MEASURABLE_SHARE: std::ops::RangeInclusive<f64> = 0.02..=0.98;
/// A standstill span measures its own level when no more than this share of its readings sit
/// at the floor; beyond it the few readings above the floor say too little.
const OWN_LEVEL_MAX_CUT_SHARE: f64 = 0.9;
/// Largest shift, in rows, tried between the simulated and the real standstills.
const MAX_STANDSTILL_LAG_ROWS: usize = 600;
/// Running rows whose simulation lies this many σ above the floor are never cut off: their
/// residual is the instrument's level as it is.
const UNCLIPPED_SIGMAS: f64 = 3.0;

/// A real recording censored at a floor, and the noise that is cut off there.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Censoring {
    /// The floor, in the target's unit.
    pub floor: f64,
    /// Share of the real rows that read exactly the floor.
    pub share_at_floor: f64,
    /// Standard deviation of the instrument's noise about its level within a standstill span,
    /// in the target's unit.
    pub sigma: f64,
    /// Stretches of consecutive rows where the simulation sits at the floor.
    pub standstill_spans: usize,
    /// Of those, the spans too short (under 30 readings) or too cut off (over 90 % at the
    /// floor) to measure their own level: their readings at the floor stand for their expected
    /// value below it, given the level of the running rows beside the span.
    pub spans_levelled_beside: usize,
    /// Standard deviation of the whole noise at the floor (slow wander included), estimated
    /// from every reading where the simulation is at the floor; how far a span's level may
    /// plausibly sit from the running rows beside it.
    pub sigma_overall: f64,
    /// Rows by which the real standstills trail the simulated ones (a delayed recording; 0
    /// when on time). The spans are taken from the simulation shifted by it, so a delay's
    /// running rows are not read as standstill noise; the delay itself is left in the
    /// residual for the analysis to name.
    pub standstill_lag_rows: isize,
}

/// The least share of rows, and number, that must be silent standstills for them to count.
const SILENT_SHARE: f64 = 0.05;
const SILENT_ROWS: usize = 30;

/// The smallest finite value (+∞ when there is none).
fn lowest(values: &[f64]) -> f64 {
    values
        .iter()
        .copied()
        .filter(|v| v.is_finite())
        .fold(f64::INFINITY, f64::min)
}

/// Where an instrument reads (1) and where it is silent (0), when it is silent somewhere: a
/// reading exactly at its floor wherever the simulation stands still, with no noise there at
/// all (where there is noise, the floor is a cut-off reading: [`Censoring`]), comes from a
/// drive that is switched off. An offset or drift of its sensor shows only where it reads.
pub fn reading_rows(real: &[f64], sim: &[f64]) -> Option<Vec<f64>> {
    let n = real.len().min(sim.len());
    let (real, sim) = (&real[..n], &sim[..n]);
    let (floor, sim_floor) = (lowest(real), lowest(sim));
    if !floor.is_finite() || !sim_floor.is_finite() {
        return None;
    }
    let silent_at = |i: usize| sim[i] <= sim_floor && real[i] == floor;
    let standstills = sim.iter().filter(|s| **s <= sim_floor).count();
    let silent = (0..n).filter(|&i| silent_at(i)).count();
    let enough = silent >= SILENT_ROWS && silent as f64 >= SILENT_SHARE * n as f64;
    // Every standstill reading at the floor, bar a few rows where the drive switches.
    if !enough || (silent as f64) < 0.99 * standstills as f64 {
        return None;
    }
    Some(
        (0..n)
            .map(|i| if silent_at(i) { 0.0 } else { 1.0 })
            .collect(),
    )
}

/// The floor of a recording read as a magnitude: its lowest value when that is a point mass
/// (at least [`MIN_AT_FLOOR`] readings and [`MIN_SHARE`] of them, [`POINT_MASS_RATIO`] times
/// more than any other single value, so that a quantised signal does not qualify).
pub fn floor_of(real: &[f64]) -> Option<f64> {
    let floor = lowest(real);
    if !floor.is_finite() {
        return None;
    }
    let at_floor = real.iter().filter(|&&v| v == floor).count();
    if at_floor < MIN_AT_FLOOR || (at_floor as f64) < MIN_SHARE * real.len() as f64 {
        return None;
    }
    if most_repeated_other_value(real, floor) * POINT_MASS_RATIO > at_floor {
        return None;
    }
    Some(floor)
}

impl Censoring {
    /// Detects a floor in `real` and estimates its noise where `sim` is at the floor. `None`
    /// when the real recording has no point mass at its minimum or there is no noise to cut
    /// off. A simulation that never sits at the floor (an axis holding its position draws a
    /// current) leaves the readings there to a sensor whose zero lies below it: the noise is
    /// then measured from sample to sample between readings above the floor.
    pub fn detect(real: &[f64], sim: &[f64]) -> Option<Censoring> {
        let n = real.len().min(sim.len());
        let (real, sim) = (&real[..n], &sim[..n]);
        let floor = floor_of(real)?;
        let at_floor = real.iter().filter(|&&v| v == floor).count();
        let standstill_lag_rows = standstill_lag(real, sim, floor);
        let shifted = shift(sim, standstill_lag_rows);
        let sim = shifted.as_slice();
        let standstill_readings = real
            .iter()
            .zip(sim)
            .filter(|(_, s)| **s <= floor)
            .map(|(r, _)| *r);
        let sigma_overall = match cut_off_fit(standstill_readings, floor) {
            Some(fit) => fit.sigma,
            None if sim.iter().all(|s| *s > floor) => {
                let above = |i: usize| real[i] > floor && real[i].is_finite() && sim[i].is_finite();
                let steps: Vec<f64> = (1..n)
                    .filter(|&i| above(i) && above(i - 1))
                    .map(|i| (real[i] - sim[i]) - (real[i - 1] - sim[i - 1]))
                    .collect();
                if steps.len() < MIN_AT_FLOOR {
                    return None;
                }
                Some(white_noise_of_steps(steps)).filter(|s| *s > 0.0)?
            }
            None => return None,
        };
        // The scatter about the level is measured span by span, so that a level wandering
        // from one standstill to the next is not counted as scatter.
        let spans = standstill_spans(sim, floor);
        let (mut weight, mut variance) = (0.0, 0.0);
        let mut spans_levelled_beside = 0;
        for span in &spans {
            match own_fit(&real[span.clone()], floor) {
                Some(fit) => {
                    weight += span.len() as f64;
                    variance += span.len() as f64 * fit.sigma * fit.sigma;
                }
                None => spans_levelled_beside += 1,
            }
        }
        let sigma = if weight > 0.0 {
            (variance / weight).sqrt()
        } else {
            sigma_overall
        };
        Some(Censoring {
            floor,
            share_at_floor: at_floor as f64 / n as f64,
            sigma,
            standstill_spans: spans.len(),
            spans_levelled_beside,
            sigma_overall,
            standstill_lag_rows,
        })
    }

    /// The reading an instrument with this floor and noise shows for the true value `value`:
    /// E[max(floor, value + e)] = floor + s Φ(s/σ) + σ φ(s/σ), s = value − floor.
    pub fn expected_reading(&self, value: f64) -> f64 {
        let s = value - self.floor;
        let u = s / self.sigma;
        self.floor + s * standard_normal_cdf(u) + self.sigma * standard_normal_pdf(u)
    }

    /// The simulation as this instrument would read it, row by row, expressed so that the
    /// instrument's latent level μ stays in the residual. In a standstill span the simulation
    /// is raised by what the floor adds to the span's mean reading, mean(real − sim) − μ, so
    /// the residual there is μ plus the readings' own scatter; between spans μ is carried
    /// linearly and the simulation is compared as E[max(floor, sim + μ + e)] − μ, which is the
    /// simulation itself once it is a few σ above the floor.
    pub fn simulation_as_read(&self, real: &[f64], sim: &[f64]) -> Vec<f64> {
        let n = real.len().min(sim.len());
        let (real, sim) = (&real[..n], &sim[..n]);
        // Spans, levels and lifts come from the simulation shifted onto the real standstills;
        // the lift is added to the simulation as it is, so a delay stays for the analysis.
        let aligned = shift(sim, self.standstill_lag_rows);
        let spans = standstill_spans(&aligned, self.floor);
        let levels: Vec<f64> = spans
            .iter()
            .map(|span| {
                let beside = self.running_level(real, &aligned, span);
                self.span_level(&real[span.clone()], &aligned[span.clone()], beside)
            })
            .collect();
        let mut compared: Vec<f64> = Vec::with_capacity(n);
        let mut next = 0usize;
        for (i, &s) in sim.iter().enumerate() {
            while next < spans.len() && spans[next].end <= i {
                next += 1;
            }
            let level = match (next.checked_sub(1), spans.get(next)) {
                (_, Some(span)) if span.contains(&i) => {
                    if i == span.start {
                        let lift = mean_difference(&real[span.clone()], &aligned[span.clone()])
                            .map_or(0.0, |mean| mean - levels[next]);
                        compared.extend(sim[span.clone()].iter().map(|s| s + lift));
                    }
                    continue;
                }
                (Some(before), Some(after)) => {
                    let (a, b) = (spans[before].end - 1, after.start);
                    let f = (i - a) as f64 / (b - a) as f64;
                    levels[before] + f * (levels[next] - levels[before])
                }
                (Some(before), None) => levels[before],
                (None, Some(_)) => levels[next],
                (None, None) => 0.0,
            };
            compared.push(self.expected_reading(s + level) - level);
        }
        compared
    }

    /// The residual's level on the running rows beside `span` — as many on each side as the
    /// span is long (at least [`MIN_AT_FLOOR`]) — that the instrument never cuts off: their
    /// median, so that a start or stop the simulation places a little differently does not
    /// move it; 0 when there are none.
    fn running_level(&self, real: &[f64], sim: &[f64], span: &std::ops::Range<usize>) -> f64 {
        let reach = span.len().max(MIN_AT_FLOOR);
        let before = span.start.saturating_sub(reach)..span.start;
        let after = span.end..(span.end + reach).min(sim.len());
        let clear = self.floor + UNCLIPPED_SIGMAS * self.sigma_overall;
        let mut residuals: Vec<f64> = before
            .chain(after)
            .filter(|&i| sim[i] > clear && real[i].is_finite())
            .map(|i| real[i] - sim[i])
            .collect();
        if residuals.is_empty() {
            return 0.0;
        }
        residuals.sort_by(f64::total_cmp);
        let mid = residuals.len() / 2;
        if residuals.len() % 2 == 1 {
            residuals[mid]
        } else {
            0.5 * (residuals[mid - 1] + residuals[mid])
        }
    }

    /// The latent level μ of one standstill span: the mean of what the instrument would read
    /// there without its floor, less the simulation. Measured from the span's own readings
    /// when they are enough and not too cut off ([`own_fit`]); otherwise each reading at the
    /// floor is replaced by its expected value below it, E[x | x ≤ floor − sim], given the
    /// running rows' level `beside` and the scatter σ — which can never lift a span above
    /// what its readings allow.
    fn span_level(&self, real: &[f64], sim: &[f64], beside: f64) -> f64 {
        let rows = || real.iter().zip(sim).filter(|(r, _)| r.is_finite());
        let n = rows().count();
        if n == 0 {
            return beside;
        }
        if let Some(fit) = own_fit(real, self.floor) {
            let mean_sim = rows().map(|(_, s)| s).sum::<f64>() / n as f64;
            return fit.level - mean_sim;
        }
        let sigma = self.sigma;
        let total: f64 = rows()
            .map(|(&r, &s)| {
                if r <= self.floor {
                    let c = self.floor - s;
                    beside - sigma * inverse_mills_ratio((c - beside) / sigma)
                } else {
                    r - s
                }
            })
            .sum();
        total / n as f64
    }
}

/// A standstill span's own cut-off fit, when its readings are enough and no more than
/// [`OWN_LEVEL_MAX_CUT_SHARE`] of them sit at the floor (beyond that a few readings above it
/// decide both the level and the scatter).
fn own_fit(readings: &[f64], floor: f64) -> Option<CutOffFit> {
    let finite = readings.iter().filter(|r| r.is_finite());
    let n = finite.clone().count();
    let cut = finite.clone().filter(|r| **r <= floor).count();
    if n == 0 || cut as f64 > OWN_LEVEL_MAX_CUT_SHARE * n as f64 {
        return None;
    }
    cut_off_fit(finite.copied(), floor)
}

/// Mean of real − sim over the rows where the reading is finite.
fn mean_difference(real: &[f64], sim: &[f64]) -> Option<f64> {
    let (mut n, mut sum) = (0usize, 0.0);
    for (r, s) in real.iter().zip(sim).filter(|(r, _)| r.is_finite()) {
        n += 1;
        sum += r - s;
    }
    (n > 0).then(|| sum / n as f64)
}

/// A floor's cut-off fitted to readings whose truth is one level: the noise and that level.
#[derive(Debug, Clone, Copy)]
struct CutOffFit {
    /// Standard deviation of the noise.
    sigma: f64,
    /// The mean the instrument would read without its floor.
    level: f64,
}

/// The noise σ and level ℓ of readings taken where the truth sits at one level, from the share
/// p₀ of them at the floor and their mean excess m: z = (floor − ℓ)/σ = Φ⁻¹(p₀) and
/// σ = m / (φ(z) − z Φ(−z)). A level above the floor moves z, not σ. `None` with too few
/// readings or a share at the floor too close to 0 or 1 to tell level from scatter.
fn cut_off_fit(readings: impl Iterator<Item = f64>, floor: f64) -> Option<CutOffFit> {
    let (mut n, mut zeros, mut excess) = (0usize, 0usize, 0.0);
    for r in readings.filter(|r| r.is_finite()) {
        n += 1;
        if r == floor {
            zeros += 1;
        }
        excess += r - floor;
    }
    if n < MIN_AT_FLOOR {
        return None;
    }
    let p0 = zeros as f64 / n as f64;
    if !MEASURABLE_SHARE.contains(&p0) {
        return None;
    }
    let z = Normal::standard().inverse_cdf(p0);
    let denominator = standard_normal_pdf(z) - z * standard_normal_cdf(-z);
    let sigma = (excess / n as f64) / denominator;
    (sigma.is_finite() && sigma > 0.0).then_some(CutOffFit {
        sigma,
        level: floor - z * sigma,
    })
}

/// The shift, in rows, that best puts the simulation's standstills on the real ones: the lag
/// L (|L| ≤ [`MAX_STANDSTILL_LAG_ROWS`], and a tenth of the record) that maximises the real
/// readings at the floor where sim[i − L] is at the floor less those where it runs; the
/// smallest |L| among equals. 0 for a recording on time; a delayed recording stops late, and
/// without the shift its first rows after each simulated stop would be running currents
/// taken for the standstill's noise.
fn standstill_lag(real: &[f64], sim: &[f64], floor: f64) -> isize {
    let n = real.len().min(sim.len());
    let limit = MAX_STANDSTILL_LAG_ROWS.min(n / 10) as isize;
    let at_floor: Vec<usize> = (0..n).filter(|&i| real[i] == floor).collect();
    let score = |lag: isize| -> i64 {
        at_floor
            .iter()
            .filter_map(|&i| usize::try_from(i as isize - lag).ok().filter(|&j| j < n))
            .map(|j| if sim[j] <= floor { 1 } else { -1 })
            .sum()
    };
    let mut best = (score(0), 0isize);
    for magnitude in 1..=limit {
        for lag in [magnitude, -magnitude] {
            let candidate = score(lag);
            if candidate > best.0 {
                best = (candidate, lag);
            }
        }
    }
    best.1
}

/// `sim` delayed by `lag` rows (advanced when negative), its ends held.
fn shift(sim: &[f64], lag: isize) -> Vec<f64> {
    let last = sim.len().saturating_sub(1) as isize;
    (0..sim.len() as isize)
        .map(|i| sim[(i - lag).clamp(0, last) as usize])
        .collect()
}

/// Maximal runs of consecutive rows where the simulation sits at (or below) the floor.
fn standstill_spans(sim: &[f64], floor: f64) -> Vec<std::ops::Range<usize>> {
    let mut spans = Vec::new();
    let mut start = None;
    for (i, &s) in sim.iter().enumerate() {
        match (s <= floor, start) {
            (true, None) => start = Some(i),
            (false, Some(a)) => {
                spans.push(a..i);
                start = None;
            }
            _ => {}
        }
    }
    if let Some(a) = start {
        spans.push(a..sim.len());
    }
    spans
}

/// φ(z)/Φ(z), kept finite far in the lower tail where Φ underflows (there it tends to −z).
fn inverse_mills_ratio(z: f64) -> f64 {
    inverse_mills_ratio_given(z, standard_normal_cdf(z))
}

/// [`inverse_mills_ratio`] where Φ(z) is already known (`cdf`): the distribution function
/// is most of its cost.
pub(super) fn inverse_mills_ratio_given(z: f64, cdf: f64) -> f64 {
    if z > NORMAL_TAIL_FROM {
        standard_normal_pdf(z) / cdf
    } else {
        let w = 1.0 / (z * z);
        -z / (1.0 - w + 3.0 * w * w - 15.0 * w * w * w)
    }
}

/// Below this z, Φ(z) is taken through its asymptotic tail form (it underflows soon after).
pub(super) const NORMAL_TAIL_FROM: f64 = -30.0;

/// How many times the most frequent value other than `floor` occurs.
fn most_repeated_other_value(values: &[f64], floor: f64) -> usize {
    let mut others: Vec<f64> = values
        .iter()
        .copied()
        .filter(|v| v.is_finite() && *v != floor)
        .collect();
    others.sort_by(f64::total_cmp);
    let mut best = 0;
    let mut run = 0;
    for i in 0..others.len() {
        run = if i > 0 && others[i] == others[i - 1] {
            run + 1
        } else {
            1
        };
        best = best.max(run);
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng, rngs::StdRng};
    use rand_distr::StandardNormal;

    /// Exact zeros wherever the simulation stands still mark a silent instrument; zeros that
    /// are only the cut-off half of the noise there do not.
    #[test]
    fn a_drive_switched_off_is_silent_and_a_noisy_floor_is_not() {
        let sim: Vec<f64> = (0..1000)
            .map(|i| if i % 200 < 60 { 0.0 } else { 5.0 })
            .collect();
        let off: Vec<f64> = sim
            .iter()
            .map(|s| if *s > 0.0 { s - 0.3 } else { 0.0 })
            .collect();
        let reading = reading_rows(&off, &sim).expect("silent standstills");
        assert_eq!(reading.iter().filter(|r| **r == 0.0).count(), 300);
        assert!(
            sim.iter()
                .zip(&reading)
                .all(|(s, r)| (*s > 0.0) == (*r == 1.0))
        );
        let mut rng = StdRng::seed_from_u64(4);
        let noisy: Vec<f64> = sim
            .iter()
            .map(|s| (s + 0.1 * rng.sample::<f64, _>(StandardNormal)).max(0.0))
            .collect();
        assert_eq!(reading_rows(&noisy, &sim), None);
    }

    /// A drive current that stands still half the time, read by an instrument that clips at 0.
    fn clipped_current(sigma: f64, standstill_offset: f64) -> (Vec<f64>, Vec<f64>) {
        let mut rng = StdRng::seed_from_u64(7);
        let sim: Vec<f64> = (0..20_000)
            .map(|i| if (i / 500) % 2 == 0 { 0.0 } else { 12.0 })
            .collect();
        let real = sim
            .iter()
            .map(|&s| {
                let e: f64 = rng.sample(StandardNormal);
                let truth = if s == 0.0 { standstill_offset } else { s };
                (truth + sigma * e).max(0.0)
            })
            .collect();
        (real, sim)
    }

    #[test]
    fn finds_the_floor_and_the_noise_cut_off_there() {
        let (real, sim) = clipped_current(0.3, 0.0);
        let c = Censoring::detect(&real, &sim).expect("a floor");
        assert_eq!(c.floor, 0.0);
        assert!((c.share_at_floor - 0.25).abs() < 0.02, "{c:?}");
        assert!((c.sigma - 0.3).abs() < 0.015, "{c:?}");
        // At the floor the expected reading is σ/√(2π); far above it, the value itself.
        assert!(
            (c.expected_reading(0.0) - c.sigma / (2.0 * std::f64::consts::PI).sqrt()).abs() < 1e-12
        );
        assert!((c.expected_reading(12.0) - 12.0).abs() < 1e-12);
        // Both halves of the record now agree with the instrument on average.
        let standstill: Vec<f64> = real
            .iter()
            .zip(&sim)
            .filter(|(_, s)| **s == 0.0)
            .map(|(r, _)| *r)
            .collect();
        let mean = standstill.iter().sum::<f64>() / standstill.len() as f64;
        assert!((mean - c.expected_reading(0.0)).abs() < 0.01, "{mean}");
    }

    #[test]
    fn a_standstill_offset_is_not_taken_for_noise() {
        // The real drive draws 0.2 A at standstill: σ is still 0.3, the offset stays a finding.
        let (real, sim) = clipped_current(0.3, 0.2);
        let c = Censoring::detect(&real, &sim).expect("a floor");
        assert!((c.sigma - 0.3).abs() < 0.02, "{c:?}");
        assert_eq!(c.spans_levelled_beside, 0, "{c:?}");
        let compared = c.simulation_as_read(&real, &sim);
        let (standing, running) = mean_residuals(&real, &sim, &compared);
        assert!((standing - 0.2).abs() < 0.01, "{standing}");
        assert!(running.abs() < 0.01, "{running}");
    }

    /// Mean residual (real − compared) where the simulation stands and where it runs.
    fn mean_residuals(real: &[f64], sim: &[f64], compared: &[f64]) -> (f64, f64) {
        let mean = |standing: bool| {
            let values: Vec<f64> = (0..real.len())
                .filter(|&i| (sim[i] <= 0.0) == standing)
                .map(|i| real[i] - compared[i])
                .collect();
            values.iter().sum::<f64>() / values.len() as f64
        };
        (mean(true), mean(false))
    }

    /// A spindle that stands for 300 s and runs for 300 s, read at 1 Hz through a floor at 0
    /// with fast noise σ, an instrument offset `offset(t)` that both halves share, and `drag`
    /// added only while it runs. Returns (real, sim, the offset at each row).
    fn wandering_current(
        sigma: f64,
        offset: impl Fn(f64) -> f64,
        drag: f64,
    ) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        let mut rng = StdRng::seed_from_u64(11);
        let sim: Vec<f64> = (0..36_000)
            .map(|i| if (i / 300) % 2 == 0 { 0.0 } else { 12.0 })
            .collect();
        let offsets: Vec<f64> = (0..sim.len()).map(|i| offset(i as f64)).collect();
        let real = sim
            .iter()
            .zip(&offsets)
            .map(|(&s, &d)| {
                let e: f64 = rng.sample(StandardNormal);
                let running = if s > 0.0 { drag } else { 0.0 };
                (s + running + d + sigma * e).max(0.0)
            })
            .collect();
        (real, sim, offsets)
    }

    /// Root mean square over the standstill spans of (the span's mean residual − the truth
    /// there), where the truth is the instrument's offset (plus `drag` nowhere: it only runs).
    /// With `measured_only`, only over the spans that measure their own level.
    fn standstill_error(
        real: &[f64],
        sim: &[f64],
        compared: &[f64],
        offsets: &[f64],
        measured_only: bool,
    ) -> f64 {
        let spans: Vec<_> = standstill_spans(sim, 0.0)
            .into_iter()
            .filter(|span| !measured_only || own_fit(&real[span.clone()], 0.0).is_some())
            .collect();
        let squares: f64 = spans
            .iter()
            .map(|span| {
                let n = span.len() as f64;
                let residual: f64 = span.clone().map(|i| real[i] - compared[i]).sum::<f64>() / n;
                let truth: f64 = span.clone().map(|i| offsets[i]).sum::<f64>() / n;
                (residual - truth).powi(2)
            })
            .sum();
        (squares / spans.len() as f64).sqrt()
    }

    #[test]
    fn an_offset_wandering_for_hours_reaches_the_residual_at_standstill_too() {
        // The offset swings ±4 σ over two hours: many standstills are cut off entirely, others
        // not at all. Compared with one stationary cut-off, the residual at standstill sits at
        // ≈ max(0, offset) and the running-vs-standing contrast follows the wander; with a level
        // per span it follows the offset as the running rows do.
        let sigma = 0.05;
        let (real, sim, offsets) = wandering_current(
            sigma,
            |t| 4.0 * sigma * (t / 7200.0 * std::f64::consts::TAU).sin(),
            0.0,
        );
        let c = Censoring::detect(&real, &sim).expect("a floor");
        assert!(c.spans_levelled_beside > 5, "{c:?}");
        assert!((c.sigma / sigma - 1.0).abs() < 0.25, "{c:?}");
        let compared = c.simulation_as_read(&real, &sim);
        let per_span = standstill_error(&real, &sim, &compared, &offsets, false);
        let stationary: Vec<f64> = sim.iter().map(|&s| c.expected_reading(s)).collect();
        let before = standstill_error(&real, &sim, &stationary, &offsets, false);
        assert!(per_span < 0.2 * sigma, "{per_span} against σ {sigma}");
        assert!(
            before > 1.5 * sigma,
            "the stationary model's error {before}"
        );
    }

    #[test]
    fn a_drag_only_while_running_keeps_its_contrast_where_standstills_are_cut_off() {
        // A real running-only drag of 10 σ with the offset wandering below the floor half the
        // time: the running rows beside a cut-off standstill carry the drag, but the cut-off
        // readings cannot be lifted above the floor, so the standstill residual stays near
        // the offset and the drag stays visible as the contrast.
        let sigma = 0.05;
        let drag = 10.0 * sigma;
        let (real, sim, offsets) = wandering_current(
            sigma,
            |t| 4.0 * sigma * (t / 7200.0 * std::f64::consts::TAU).sin(),
            drag,
        );
        let c = Censoring::detect(&real, &sim).expect("a floor");
        let compared = c.simulation_as_read(&real, &sim);
        let (standing, running) = mean_residuals(&real, &sim, &compared);
        let offset_mean = offsets.iter().sum::<f64>() / offsets.len() as f64;
        let contrast = running - standing;
        assert!(
            (contrast - drag).abs() < 0.15 * drag,
            "contrast {contrast} against {drag}"
        );
        // Where a standstill shows its own level it is kept; where it is cut off entirely the
        // level is only bounded, and it is put near the floor, not at the running rows' level.
        let measured = standstill_error(&real, &sim, &compared, &offsets, true);
        assert!(measured < 0.2 * sigma, "{measured}");
        let highest = standstill_spans(&sim, 0.0)
            .into_iter()
            .map(|span| {
                let n = span.len() as f64;
                span.map(|i| real[i] - compared[i]).sum::<f64>() / n
            })
            .fold(f64::NEG_INFINITY, f64::max);
        assert!(highest < 4.0 * sigma + 0.2 * drag, "{highest}");
        assert!(offset_mean.abs() < 0.01);
    }

    #[test]
    fn a_delayed_recording_has_its_standstills_found_where_they_are() {
        // The real current trails the simulation by 12 rows: the first 12 rows of every
        // simulated standstill still read a running current. Taken as standstill noise they
        // would make σ tens of times too large; shifted, the noise is the instrument's.
        let (real, sim) = clipped_current(0.3, 0.0);
        let mut delayed = vec![real[0]; 12];
        delayed.extend_from_slice(&real[..real.len() - 12]);
        let c = Censoring::detect(&delayed, &sim).expect("a floor");
        assert_eq!(c.standstill_lag_rows, 12, "{c:?}");
        assert!((c.sigma - 0.3).abs() < 0.015, "{c:?}");
        // The delay itself stays in the residual: 12 A over just after each simulated stop,
        // 12 A short just after each restart, and the standstill level unbiased where both
        // the simulation and the recording stand.
        let compared = c.simulation_as_read(&delayed, &sim);
        assert!((delayed[1005] - compared[1005] - 12.0).abs() < 2.0);
        assert!((delayed[505] - compared[505] + 12.0).abs() < 2.0);
        let both_standing: Vec<f64> = (12..delayed.len())
            .filter(|&i| sim[i] == 0.0 && sim[i - 12] == 0.0)
            .map(|i| delayed[i] - compared[i])
            .collect();
        let standing = both_standing.iter().sum::<f64>() / both_standing.len() as f64;
        assert!(standing.abs() < 0.02, "{standing}");
        // On time, no shift.
        assert_eq!(
            Censoring::detect(&real, &sim).map(|c| c.standstill_lag_rows),
            Some(0)
        );
    }

    #[test]
    fn quantised_and_unclipped_signals_have_no_floor() {
        let mut rng = StdRng::seed_from_u64(3);
        let sim: Vec<f64> = (0..5_000)
            .map(|i| 20.0 + (i as f64 / 800.0).sin())
            .collect();
        let noisy: Vec<f64> = sim
            .iter()
            .map(|s| s + 0.05 * rng.sample::<f64, _>(StandardNormal))
            .collect();
        assert_eq!(Censoring::detect(&noisy, &sim), None);
        // Logged to 0.1 K: the minimum repeats, but so does every level.
        let quantised: Vec<f64> = noisy.iter().map(|v| (v * 10.0).round() / 10.0).collect();
        assert_eq!(Censoring::detect(&quantised, &sim), None);
        // A noiseless recording at the floor: nothing is cut off.
        let (_, current) = clipped_current(0.3, 0.0);
        assert_eq!(Censoring::detect(&current, &current), None);
    }
}
