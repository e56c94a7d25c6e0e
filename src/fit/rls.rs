//! Online recalibration: recursive least squares (RLS) with a forgetting factor.
//!
//! The paper updates the digital model "by comparing its results with actual machining
//! results". A deployed estimator starts from the batch OLS coefficients and folds in each new
//! reference measurement as it arrives, in O(p²) per measurement, without keeping the history.
//! With forgetting factor λ = 1 every measurement counts the same, and RLS started from a batch
//! fit reproduces the batch fit of all the data; with λ < 1 old measurements fade with weight
//! λᵏ (memory ≈ 1/(1 − λ) measurements), so the model follows a machine that changes.

use faer::Mat;

use super::error::FitError;
use super::ols::OlsFit;

/// Recursive least squares with exponential forgetting.
#[derive(Debug, Clone)]
pub struct RecursiveLeastSquares {
    coefficients: Vec<f64>,
    /// P, proportional to the covariance of the coefficients: (Σ λ^k x xᵀ)⁻¹.
    covariance: Mat<f64>,
    forgetting_factor: f64,
    updates: u64,
    /// Scratch for P x, kept to avoid allocating per update.
    p_x: Vec<f64>,
}

impl RecursiveLeastSquares {
    /// An estimator of `n_coefficients` coefficients starting at zero with no information:
    /// P = `initial_variance` · I. A large `initial_variance` (e.g. 1e6 in the squared units of
    /// the coefficients) lets the first measurements decide.
    pub fn new(
        n_coefficients: usize,
        forgetting_factor: f64,
        initial_variance: f64,
    ) -> Result<Self, FitError> {
        check_forgetting_factor(forgetting_factor)?;
        if !(initial_variance > 0.0 && initial_variance.is_finite()) {
            return Err(FitError::InvalidParameter {
                name: "initial_variance",
                value: initial_variance,
                requirement: "must be a positive finite number",
            });
        }
        let mut covariance = Mat::<f64>::zeros(n_coefficients, n_coefficients);
        for i in 0..n_coefficients {
            covariance[(i, i)] = initial_variance;
        }
        Ok(RecursiveLeastSquares {
            coefficients: vec![0.0; n_coefficients],
            covariance,
            forgetting_factor,
            updates: 0,
            p_x: vec![0.0; n_coefficients],
        })
    }

    /// An estimator that continues a batch fit: coefficients from `fit`, P = (XᵀX)⁻¹ of the
    /// batch data, so new measurements are weighed against everything the batch already knew.
    pub fn from_fit(fit: &OlsFit, forgetting_factor: f64) -> Result<Self, FitError> {
        check_forgetting_factor(forgetting_factor)?;
        let p = fit.coefficients.len();
        Ok(RecursiveLeastSquares {
            coefficients: fit.estimates(),
            covariance: fit.normalized_cov.clone(),
            forgetting_factor,
            updates: 0,
            p_x: vec![0.0; p],
        })
    }

    /// Folds in one measurement: regressor row `x` (intercept entry included, in the model's
    /// term order) and measured target `y`. Returns the prediction error before the update.
    /// A row of the wrong length or a non-finite value is refused and leaves the state as it
    /// was.
    pub fn update(&mut self, x: &[f64], y: f64) -> Result<f64, FitError> {
        let p = self.coefficients.len();
        if x.len() != p {
            return Err(FitError::Dimension {
                what: "an RLS regressor row",
                expected: p,
                found: x.len(),
            });
        }
        if let Some(bad) = x.iter().chain([&y]).find(|v| !v.is_finite()) {
            return Err(FitError::InvalidParameter {
                name: "RLS measurement",
                value: *bad,
                requirement: "every regressor and the target must be finite",
            });
        }
        for i in 0..p {
            self.p_x[i] = (0..p).map(|j| self.covariance[(i, j)] * x[j]).sum();
        }
        let denominator =
            self.forgetting_factor + x.iter().zip(&self.p_x).map(|(a, b)| a * b).sum::<f64>();
        let error = y - self.predict_unchecked(x);
        for i in 0..p {
            self.coefficients[i] += self.p_x[i] / denominator * error;
        }
        // P ← (P − P x xᵀ P / denominator) / λ, kept exactly symmetric against rounding drift.
        for i in 0..p {
            for j in i..p {
                let value = (self.covariance[(i, j)] - self.p_x[i] * self.p_x[j] / denominator)
                    / self.forgetting_factor;
                self.covariance[(i, j)] = value;
                self.covariance[(j, i)] = value;
            }
        }
        self.updates += 1;
        Ok(error)
    }

    /// The current coefficients, in the model's term order.
    pub fn coefficients(&self) -> &[f64] {
        &self.coefficients
    }

    /// The prediction for a regressor row.
    pub fn predict(&self, x: &[f64]) -> Result<f64, FitError> {
        if x.len() != self.coefficients.len() {
            return Err(FitError::Dimension {
                what: "an RLS regressor row",
                expected: self.coefficients.len(),
                found: x.len(),
            });
        }
        Ok(self.predict_unchecked(x))
    }

    fn predict_unchecked(&self, x: &[f64]) -> f64 {
        x.iter().zip(&self.coefficients).map(|(a, b)| a * b).sum()
    }

    /// P: the coefficient covariance up to the noise variance.
    pub fn covariance(&self) -> faer::MatRef<'_, f64> {
        self.covariance.as_ref()
    }

    /// λ.
    pub fn forgetting_factor(&self) -> f64 {
        self.forgetting_factor
    }

    /// Measurements folded in so far.
    pub fn updates(&self) -> u64 {
        self.updates
    }
}

fn check_forgetting_factor(value: f64) -> Result<(), FitError> {
    if value > 0.0 && value <= 1.0 {
        Ok(())
    } else {
        Err(FitError::InvalidParameter {
            name: "forgetting_factor",
            value,
            requirement: "must lie in (0, 1]",
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::design::Design;
    use crate::fit::ols::ols;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    fn data(n: usize, seed: u64, coefficients: impl Fn(usize) -> [f64; 3]) -> Design {
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let normal = Normal::new(0.0, 1.0).unwrap();
        let a: Vec<f64> = (0..n)
            .map(|_| 30.0 + 5.0 * normal.sample(&mut rng))
            .collect();
        let b: Vec<f64> = (0..n).map(|_| normal.sample(&mut rng)).collect();
        let y = (0..n)
            .map(|i| {
                let [c0, c1, c2] = coefficients(i);
                c0 + c1 * a[i] + c2 * b[i] + 0.1 * normal.sample(&mut rng)
            })
            .collect();
        Design::from_columns("y", y, vec![("a".into(), a), ("b".into(), b)]).unwrap()
    }

    #[test]
    fn continuing_a_batch_fit_with_lambda_one_equals_the_batch_fit_of_all_data() {
        let design = data(400, 5, |_| [1.0, 0.5, -2.0]);
        let first = ols(&design.with_rows(|i| i < 50)).unwrap();
        let mut rls = RecursiveLeastSquares::from_fit(&first, 1.0).unwrap();
        let mut row = Vec::new();
        for i in 50..400 {
            design.row_into(i, &mut row);
            rls.update(&row, design.y()[i]).unwrap();
        }
        let batch = ols(&design).unwrap();
        for (online, batch) in rls.coefficients().iter().zip(batch.estimates()) {
            assert!(
                (online - batch).abs() < 1e-8 * batch.abs(),
                "{online} vs {batch}"
            );
        }
        assert_eq!(rls.updates(), 350);
    }

    #[test]
    fn from_scratch_with_lambda_one_converges_to_batch_ols() {
        let design = data(2000, 8, |_| [1.0, 0.5, -2.0]);
        let mut rls = RecursiveLeastSquares::new(3, 1.0, 1e8).unwrap();
        let mut row = Vec::new();
        for i in 0..design.n_rows() {
            design.row_into(i, &mut row);
            rls.update(&row, design.y()[i]).unwrap();
        }
        let batch = ols(&design).unwrap();
        for (online, coefficient) in rls.coefficients().iter().zip(&batch.coefficients) {
            // The prior P₀ = 1e8·I acts as a ridge penalty of 1e-8: a tiny, known bias.
            let tolerance = 1e-3 * coefficient.std_error;
            assert!(
                (online - coefficient.estimate).abs() < tolerance,
                "{online} vs {coefficient:?}"
            );
        }
    }

    #[test]
    fn forgetting_tracks_a_step_change_that_batch_ols_averages_away() {
        let before = [1.0, 0.5, -2.0];
        let after = [1.0, 0.8, -1.0];
        let design = data(1000, 9, |i| if i < 500 { before } else { after });
        let mut rls = RecursiveLeastSquares::new(3, 0.99, 1e6).unwrap();
        let mut row = Vec::new();
        for i in 0..design.n_rows() {
            design.row_into(i, &mut row);
            rls.update(&row, design.y()[i]).unwrap();
        }
        let batch = ols(&design).unwrap().estimates();
        for k in 1..3 {
            let online_error = (rls.coefficients()[k] - after[k]).abs();
            let batch_error = (batch[k] - after[k]).abs();
            assert!(
                online_error < 0.03,
                "coefficient {k}: {:?}",
                rls.coefficients()
            );
            assert!(batch_error > 0.1, "batch {batch:?}");
        }
    }

    #[test]
    fn bad_measurements_are_refused_without_changing_state() {
        let mut rls = RecursiveLeastSquares::new(2, 0.99, 100.0).unwrap();
        rls.update(&[1.0, 2.0], 3.0).unwrap();
        let before = rls.coefficients().to_vec();
        assert!(rls.update(&[1.0], 3.0).is_err());
        assert!(rls.update(&[1.0, f64::NAN], 3.0).is_err());
        assert!(rls.update(&[1.0, 2.0], f64::INFINITY).is_err());
        assert_eq!(rls.coefficients(), before);
        assert!(RecursiveLeastSquares::new(2, 1.5, 1.0).is_err());
        assert!(RecursiveLeastSquares::new(2, 0.9, 0.0).is_err());
    }
}
