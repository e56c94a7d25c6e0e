//! Sensitivity analysis: which terms matter most (the paper's "parameters that have the
//! strongest impact"), as standardized coefficients and drop-one partial R².

use super::design::Design;
use super::ols::OlsFit;

/// How much one term matters in a fitted model.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TermSensitivity {
    /// The term.
    pub term: String,
    /// β · sd(term) / sd(target): the change in the target, in its standard deviations, for a
    /// one-standard-deviation change of the term with the others held fixed.
    pub standardized: f64,
    /// Drop-one partial R²: (SSE without the term − SSE with it) / SSE without it, the share
    /// of what the other terms leave unexplained that this term explains.
    pub partial_r2: f64,
    /// 1 for the most important term (largest partial R²).
    pub rank: usize,
}

/// Standardized coefficients and partial R² for every term but the intercept, most important
/// first (by partial R²; ties keep design order).
///
/// The drop-one increase in SSE comes from the full fit without refitting:
/// `SSE₋ⱼ − SSE = βⱼ² / [(XᵀX)⁻¹]ⱼⱼ` (= tⱼ² · MSE), exact for least squares. `fit` must be
/// the fit of `design`.
pub fn sensitivity(fit: &OlsFit, design: &Design) -> Vec<TermSensitivity> {
    let y_sd = sample_sd(design.y());
    let mut out: Vec<TermSensitivity> = fit
        .coefficients
        .iter()
        .enumerate()
        .skip(1)
        .map(|(j, coefficient)| {
            let increase = coefficient.estimate * coefficient.estimate / fit.normalized_cov[(j, j)];
            TermSensitivity {
                term: coefficient.term.clone(),
                standardized: coefficient.estimate * sample_sd(design.column(j)) / y_sd,
                partial_r2: increase / (fit.ss_error + increase),
                rank: 0,
            }
        })
        .collect();
    // NaN (only possible for degenerate fits) sorts last.
    out.sort_by(|a, b| {
        let key = |s: &TermSensitivity| {
            if s.partial_r2.is_nan() {
                f64::NEG_INFINITY
            } else {
                s.partial_r2
            }
        };
        key(b).total_cmp(&key(a))
    });
    for (i, s) in out.iter_mut().enumerate() {
        s.rank = i + 1;
    }
    out
}

/// The sample standard deviation (n − 1 in the denominator); its choice cancels in the
/// standardized coefficient as long as term and target use the same.
fn sample_sd(values: &[f64]) -> f64 {
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    (values.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / (n - 1.0)).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::ols::ols;

    #[test]
    fn partial_r2_equals_a_real_drop_one_refit_and_ranks() {
        let n = 200;
        let a: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).sin() * 5.0).collect();
        let b: Vec<f64> = (0..n).map(|i| (i as f64 * 0.11).cos()).collect();
        let c: Vec<f64> = (0..n).map(|i| ((i * 7919) % 101) as f64 / 101.0).collect();
        let y: Vec<f64> = (0..n)
            .map(|i| {
                1.0 + 0.2 * a[i] + 3.0 * b[i] + 0.05 * c[i] + 0.3 * ((i * 31 % 17) as f64 / 17.0)
            })
            .collect();
        let design = Design::from_columns(
            "y",
            y,
            vec![("a".into(), a), ("b".into(), b), ("c".into(), c)],
        )
        .unwrap();
        let fit = ols(&design).unwrap();
        let ranked = sensitivity(&fit, &design);
        assert_eq!(
            ranked.iter().map(|s| s.term.as_str()).collect::<Vec<_>>(),
            ["b", "a", "c"]
        );
        assert_eq!(ranked.iter().map(|s| s.rank).collect::<Vec<_>>(), [1, 2, 3]);
        for s in &ranked {
            let j = design.term_index(&s.term).unwrap();
            let others: Vec<usize> = (1..4).filter(|&k| k != j).collect();
            let reduced = ols(&design.with_terms(&others)).unwrap();
            let expected = (reduced.ss_error - fit.ss_error) / reduced.ss_error;
            assert!(
                (s.partial_r2 - expected).abs() < 1e-10 * expected.max(1e-300),
                "{s:?}"
            );
        }
    }
}
