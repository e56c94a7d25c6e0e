//! How many independent samples an autocorrelated series is worth, and the mean test that
//! follows from it.
//!
//! Servo and temperature residuals at 1 Hz are correlated over minutes to hours: 14 400 samples
//! of a four-hour run may carry the evidence of ten. Tests that count every sample call any
//! drift significant; these count what the data can support. And how much of a series'
//! noise is white: what changes from one sample to the next.

use super::distributions::student_t_two_sided_p;

/// Effective sample size of a series, `n / (1 + 2 Σ ρ_k)`, with the autocorrelation sum cut by
/// Geyer's initial positive sequence (pairs `ρ_k + ρ_{k+1}` are summed while positive), so
/// estimation noise in the far lags does not count. At least 1 for a non-empty series; the
/// series length when it has no variance.
pub fn effective_sample_size(series: &[f64]) -> f64 {
    let n = series.len();
    if n < 3 {
        return n as f64;
    }
    let mean = series.iter().sum::<f64>() / n as f64;
    let centred: Vec<f64> = series.iter().map(|x| x - mean).collect();
    let variance: f64 = centred.iter().map(|x| x * x).sum();
    if variance <= 0.0 || !variance.is_finite() {
        return n as f64;
    }
    let rho = |lag: usize| -> f64 {
        centred[..n - lag]
            .iter()
            .zip(&centred[lag..])
            .map(|(a, b)| a * b)
            .sum::<f64>()
            / variance
    };
    let mut sum = 0.0;
    let mut lag = 1;
    while lag + 1 < n {
        let pair = rho(lag) + rho(lag + 1);
        if pair <= 0.0 {
            break;
        }
        sum += pair;
        lag += 2;
    }
    (n as f64 / (1.0 + 2.0 * sum)).clamp(1.0, n as f64)
}

/// One-sided test that the mean of an autocorrelated series is above zero: the t statistic
/// with the standard error of the mean taken over the effective sample size, and its p-value
/// with `n_eff − 1` degrees of freedom. NaN when fewer than two effective samples remain.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeanTest {
    /// The series mean.
    pub mean: f64,
    /// Effective sample size.
    pub n_eff: f64,
    /// t statistic.
    pub t: f64,
    /// P(T ≥ t).
    pub p_value: f64,
}

/// [`MeanTest`] of `series`.
pub fn mean_above_zero(series: &[f64]) -> MeanTest {
    let n = series.len();
    let mean = series.iter().sum::<f64>() / n.max(1) as f64;
    let n_eff = effective_sample_size(series);
    let variance = series.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n.max(2) - 1) as f64;
    let t = mean / (variance / n_eff).sqrt();
    let p_value = if n_eff < 2.0 || !t.is_finite() {
        f64::NAN
    } else {
        let two_sided = student_t_two_sided_p(t, n_eff - 1.0);
        if t > 0.0 {
            two_sided / 2.0
        } else {
            1.0 - two_sided / 2.0
        }
    };
    MeanTest {
        mean,
        n_eff,
        t,
        p_value,
    }
}

/// White-noise σ of a slowly varying series from its first differences: a difference of two
/// samples carries √2·σ of white noise and almost none of what varies slowly (correlated
/// noise, drift, heat), and the median ignores the few real steps. 0 for fewer than two
/// samples, and for a series quantised so coarsely that most samples repeat the one before.
pub fn white_noise_from_differences(series: &[f64]) -> f64 {
    white_noise_of_steps(series.windows(2).map(|w| w[1] - w[0]).collect())
}

/// [`white_noise_from_differences`] of chosen sample-to-sample `differences` (those between
/// rows a caller trusts, e.g. an axis's while it moves).
pub fn white_noise_of_steps(differences: Vec<f64>) -> f64 {
    let mut differences: Vec<f64> = differences.into_iter().map(f64::abs).collect();
    if differences.is_empty() {
        return 0.0;
    }
    let middle = differences.len() / 2;
    let (_, median, _) = differences.select_nth_unstable_by(middle, f64::total_cmp);
    // The median of |N(0, 2σ²)| is 0.6745 · √2 · σ.
    *median / (0.674_489_75 * std::f64::consts::SQRT_2)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng, rngs::StdRng};
    use rand_distr::StandardNormal;

    /// A seeded AR(1) series x_k = φ x_{k−1} + e_k (uniform innovations scaled to unit variance).
    fn ar1(phi: f64, n: usize, seed: u64) -> Vec<f64> {
        let mut state = seed;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 12f64.sqrt()
        };
        let mut x = 0.0;
        (0..n)
            .map(|_| {
                x = phi * x + next();
                x
            })
            .collect()
    }

    #[test]
    fn white_noise_is_worth_about_every_sample() {
        let n_eff = effective_sample_size(&ar1(0.0, 20_000, 1));
        assert!((n_eff / 20_000.0 - 1.0).abs() < 0.1, "n_eff = {n_eff}");
    }

    #[test]
    fn ar1_matches_its_closed_form() {
        // For AR(1), n_eff = n (1 − φ) / (1 + φ): φ = 0.9 gives n / 19.
        let n = 200_000;
        let n_eff = effective_sample_size(&ar1(0.9, n, 7));
        let expected = n as f64 * 0.1 / 1.9;
        assert!(
            (n_eff / expected - 1.0).abs() < 0.2,
            "n_eff = {n_eff}, closed form {expected}"
        );
    }

    #[test]
    fn a_slow_drift_is_not_significant_where_counting_samples_would_say_so() {
        // A slow random walk-like series: thousands of samples, a nonzero mean, few
        // independent pieces of evidence.
        let series = ar1(0.999, 14_400, 3);
        let test = mean_above_zero(&series);
        let naive_t = test.mean
            / (series.iter().map(|x| (x - test.mean).powi(2)).sum::<f64>()
                / (series.len() - 1) as f64
                / series.len() as f64)
                .sqrt();
        assert!(test.n_eff < 200.0, "n_eff = {}", test.n_eff);
        assert!(test.t.abs() < naive_t.abs() / 5.0);
    }

    #[test]
    fn a_clear_offset_in_white_noise_is_significant() {
        let series: Vec<f64> = ar1(0.0, 1_000, 5).iter().map(|x| x + 0.5).collect();
        let test = mean_above_zero(&series);
        assert!(test.p_value < 1e-6, "{test:?}");
        let negative: Vec<f64> = series.iter().map(|x| -x).collect();
        assert!(mean_above_zero(&negative).p_value > 0.99);
    }

    #[test]
    fn the_white_part_of_a_series_is_told_from_its_slow_part_and_its_steps() {
        // σ = 0.3 Gaussian noise on a slow AR(1) wander larger than it (correlation time
        // 10 000 samples, so it changes by 0.02 from one sample to the next), with four steps
        // of 10: the successive differences see the 0.3 alone.
        let mut rng = StdRng::seed_from_u64(11);
        let slow = ar1(0.9999, 50_000, 9);
        let series: Vec<f64> = slow
            .iter()
            .enumerate()
            .map(|(k, s)| {
                let gaussian: f64 = rng.sample(StandardNormal);
                let steps = 10.0 * (k / 10_000) as f64;
                0.02 * s + 0.3 * gaussian + steps
            })
            .collect();
        let slow_spread = {
            let part: Vec<f64> = slow.iter().map(|s| 0.02 * s).collect();
            let m = part.iter().sum::<f64>() / part.len() as f64;
            (part.iter().map(|v| (v - m).powi(2)).sum::<f64>() / part.len() as f64).sqrt()
        };
        assert!(
            slow_spread > 0.6,
            "the wander is larger than the noise: {slow_spread}"
        );
        let white = white_noise_from_differences(&series);
        assert!((white / 0.3 - 1.0).abs() < 0.05, "{white}");
        assert_eq!(white_noise_from_differences(&[1.0]), 0.0);
    }
}
