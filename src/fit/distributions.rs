//! The F and Student t tail probabilities and quantiles the statistics need, from statrs.
//!
//! Tail probabilities go straight through statrs' regularized incomplete beta function rather
//! than `1 − cdf`: a p-value of 1e-40 must come out as 1e-40, not as 1 − (1 − 1e-40) = 0.

use statrs::distribution::{ContinuousCDF, StudentsT};
use statrs::function::beta::checked_beta_reg;

/// Two-sided p-value of a t statistic with `df` degrees of freedom: `P(|T| ≥ |t|)`.
/// NaN when `t` is NaN or `df` is not positive.
pub fn student_t_two_sided_p(t: f64, df: f64) -> f64 {
    if t.is_nan() || df <= 0.0 {
        return f64::NAN;
    }
    if t.is_infinite() {
        return 0.0;
    }
    // P(|T| ≥ |t|) = I_x(df/2, 1/2) with x = df / (df + t²).
    let x = df / (df + t * t);
    checked_beta_reg(df / 2.0, 0.5, x).unwrap_or(f64::NAN)
}

/// Upper tail of the F distribution with (`d1`, `d2`) degrees of freedom: `P(F ≥ f)`.
/// NaN when `f` is NaN or a degree of freedom is not positive.
pub fn f_survival(f: f64, d1: f64, d2: f64) -> f64 {
    if f.is_nan() || d1 <= 0.0 || d2 <= 0.0 {
        return f64::NAN;
    }
    if f <= 0.0 {
        return 1.0;
    }
    if f.is_infinite() {
        return 0.0;
    }
    // P(F ≥ f) = I_x(d2/2, d1/2) with x = d2 / (d2 + d1 f), computed without cancellation.
    let x = d2 / (d2 + d1 * f);
    checked_beta_reg(d2 / 2.0, d1 / 2.0, x).unwrap_or(f64::NAN)
}

/// The Student t quantile: `q` with `P(T ≤ q) = probability` for `df` degrees of freedom.
/// NaN for a probability outside (0, 1) or `df` not positive.
pub fn student_t_quantile(probability: f64, df: f64) -> f64 {
    if !(probability > 0.0 && probability < 1.0) || df <= 0.0 || df.is_nan() {
        return f64::NAN;
    }
    let Ok(distribution) = StudentsT::new(0.0, 1.0, df) else {
        return f64::NAN;
    };
    // statrs inverts the incomplete beta function iteratively; two Newton steps on the cdf
    // polish the result to full double precision so confidence limits match scipy's.
    let mut q = distribution.inverse_cdf(probability);
    for _ in 0..2 {
        let density = statrs::distribution::Continuous::pdf(&distribution, q);
        if density.is_nan() || density <= 0.0 {
            break;
        }
        let step = (distribution.cdf(q) - probability) / density;
        if !step.is_finite() {
            break;
        }
        q -= step;
    }
    q
}

/// The standard normal distribution function Φ(x), through the complementary error function
/// so that the far lower tail keeps its digits.
pub fn standard_normal_cdf(x: f64) -> f64 {
    0.5 * statrs::function::erf::erfc(-x / std::f64::consts::SQRT_2)
}

/// The standard normal density φ(x).
pub fn standard_normal_pdf(x: f64) -> f64 {
    (-0.5 * x * x).exp() / (2.0 * std::f64::consts::PI).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    // Reference values from scipy.stats.norm (cdf, pdf).
    #[test]
    fn normal_matches_scipy() {
        let close = |a: f64, b: f64, rel: f64| (a - b).abs() <= rel * b.abs();
        // statrs' erfc carries ~5e-12 relative error; the censoring model needs far less.
        assert!(close(standard_normal_cdf(0.0), 0.5, 1e-15));
        assert!(close(standard_normal_cdf(1.3), 0.9031995154143897, 1e-10));
        assert!(close(
            standard_normal_cdf(-8.0),
            6.22096057427174e-16,
            1e-10
        ));
        assert!(close(standard_normal_pdf(0.7), 0.31225393336676127, 1e-14));
    }

    // Reference values from scipy.stats (t.sf, f.sf, t.ppf).
    #[test]
    fn matches_scipy() {
        let close = |a: f64, b: f64, rel: f64| (a - b).abs() <= rel * b.abs();
        // 2 * scipy.stats.t.sf(2.1, 12)
        assert!(close(
            student_t_two_sided_p(2.1, 12.0),
            0.057544938734951125,
            1e-10
        ));
        // 2 * scipy.stats.t.sf(17.36, 590): a tiny p-value keeps its digits.
        assert!(close(
            student_t_two_sided_p(17.36, 590.0),
            7.667815337963999e-55,
            1e-9
        ));
        // scipy.stats.f.sf(3.2, 5, 9)
        assert!(close(
            f_survival(3.2, 5.0, 9.0),
            0.061924315959291425,
            1e-10
        ));
        // scipy.stats.t.ppf(0.975, 9), (0.975, 590)
        assert!(close(
            student_t_quantile(0.975, 9.0),
            2.262157162798205,
            1e-13
        ));
        assert!(close(
            student_t_quantile(0.975, 590.0),
            1.9639929039913906,
            1e-13
        ));
        // The benchmark's shape: a million residual degrees of freedom.
        let df = 999970.0;
        assert!(close(
            student_t_two_sided_p(2.0, df),
            0.045500533859418116,
            1e-9
        ));
        assert!(close(f_survival(1.5, 29.0, df), 0.040909169149367396, 1e-9));
        // statrs' incomplete beta carries ~1e-11 relative error at such df; the quantile
        // inherits it (far inside the 1e-6 parity budget).
        assert!(close(
            student_t_quantile(0.975, df),
            1.959966356885277,
            1e-10
        ));
    }

    #[test]
    fn degenerate_inputs() {
        assert!(student_t_two_sided_p(f64::NAN, 3.0).is_nan());
        assert_eq!(student_t_two_sided_p(f64::INFINITY, 3.0), 0.0);
        assert_eq!(student_t_two_sided_p(0.0, 3.0), 1.0);
        assert_eq!(f_survival(0.0, 2.0, 3.0), 1.0);
        assert!(f_survival(1.0, 0.0, 3.0).is_nan());
        assert!(student_t_quantile(1.0, 3.0).is_nan());
    }
}
