//! The instrument's floor: a real signal recorded as a magnitude (a drive's current, a load
//! percentage) cannot read below zero. Where the true value sits at that floor — a spindle at
//! standstill — the instrument shows its noise cut off at the floor, so the recording's mean
//! lies about 0.4 σ above the truth there while a noiseless simulation shows the floor itself.
//! Compared as they are, the two differ by a step wherever the machine stops, and every
//! correction that switches with motion (viscous drag, Coulomb friction…) would be named for
//! it. The simulation is instead compared as the instrument would read it: the expected
//! reading E[max(floor, sim + e)] with e ~ N(0, σ²), σ estimated from the rows where the
//! simulation sits at the floor.

use statrs::distribution::{ContinuousCDF, Normal};

use crate::fit::distributions::{standard_normal_cdf, standard_normal_pdf};

/// Fewest readings at the floor that identify one (and estimate the noise there).
const MIN_AT_FLOOR: usize = 30;
/// Smallest share of all rows at the floor.
const MIN_SHARE: f64 = 0.01;
/// The floor must hold this many times more readings than any other single value: a
/// quantised signal (a temperature logged to 0.1 K) repeats its minimum too, but no more often
/// than its other levels.
const POINT_MASS_RATIO: usize = 5;

/// A real recording censored at a floor, and the noise that is cut off there.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Censoring {
    /// The floor, in the target's unit.
    pub floor: f64,
    /// Share of the real rows that read exactly the floor.
    pub share_at_floor: f64,
    /// Standard deviation of the instrument's noise, estimated where the simulation sits at
    /// the floor, in the target's unit.
    pub sigma: f64,
}

impl Censoring {
    /// Detects a floor in `real` and estimates its noise where `sim` is at the floor. `None`
    /// when the real recording has no point mass at its minimum, the simulation is never at
    /// the floor, or there is no noise to cut off.
    pub fn detect(real: &[f64], sim: &[f64]) -> Option<Censoring> {
        let floor = real
            .iter()
            .copied()
            .filter(|v| v.is_finite())
            .fold(f64::INFINITY, f64::min);
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
        // Where the simulation is at (or below) the floor, the reading is max(floor, μ + e):
        // the share p₀ at the floor and the mean excess m give z = (floor − μ)/σ = Φ⁻¹(p₀)
        // and σ = m / (φ(z) − z Φ(−z)). A real standstill offset (μ above the floor) moves
        // z, not σ, and is left for the analysis to find.
        let (mut n, mut zeros, mut excess) = (0usize, 0usize, 0.0);
        for (&r, &s) in real.iter().zip(sim) {
            if s <= floor && r.is_finite() {
                n += 1;
                if r == floor {
                    zeros += 1;
                }
                excess += r - floor;
            }
        }
        if n < MIN_AT_FLOOR {
            return None;
        }
        let p0 = zeros as f64 / n as f64;
        if !(0.02..=0.98).contains(&p0) {
            return None;
        }
        let z = Normal::standard().inverse_cdf(p0);
        let denominator = standard_normal_pdf(z) - z * standard_normal_cdf(-z);
        let sigma = (excess / n as f64) / denominator;
        (sigma.is_finite() && sigma > 0.0).then_some(Censoring {
            floor,
            share_at_floor: at_floor as f64 / real.len() as f64,
            sigma,
        })
    }

    /// The reading an instrument with this floor and noise shows for the true value `value`:
    /// E[max(floor, value + e)] = floor + s Φ(s/σ) + σ φ(s/σ), s = value − floor.
    pub fn expected_reading(&self, value: f64) -> f64 {
        let s = value - self.floor;
        let u = s / self.sigma;
        self.floor + s * standard_normal_cdf(u) + self.sigma * standard_normal_pdf(u)
    }
}

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
