//! Ordinary least squares by Householder QR (faer), with the statistics statsmodels' `OLS`
//! reports.
//!
//! Why QR and column scaling: the paper's straightness model is a cubic in three uncentred
//! temperatures (20–50 °C), whose design has a condition number around 10⁷–10⁸. The normal
//! equations square that (10¹⁵: no correct digits left); Householder QR works with the matrix
//! itself. Scaling every column to unit norm first makes the triangular factor's diagonal a
//! direct measure of how independent each term is of the ones before it, which is how rank
//! deficiency is found and named.
//!
//! Definitions (statsmodels' names in brackets; the paper's Eqs. 3–4 use SSR for regression):
//! - `ss_error` = Σ residual² \[`ssr`\], `ss_total` = Σ (y − ȳ)² \[`centered_tss`\],
//!   `ss_regression` = `ss_total − ss_error` \[`ess`\].
//! - `df_model` = coefficients − 1, `df_resid` = n − coefficients.
//! - `mse_resid` = `ss_error / df_resid` \[`mse_resid`, `scale`\]; **`rmse` = √`mse_resid`**,
//!   the residual standard error (statsmodels has no field called rmse; this is the estimate of
//!   the noise σ, which uses the residual degrees of freedom, not n).
//! - F = `mse_model / mse_resid` on (`df_model`, `df_resid`) degrees of freedom \[`fvalue`\].
//! - standard errors = √(`mse_resid` · diag((XᵀX)⁻¹)) \[`bse`\]; t = estimate / std error;
//!   p two-sided Student t on `df_resid`; confidence interval estimate ± t₁₋α/₂ · std error.
//! - log-likelihood, AIC = −2 llf + 2k, BIC = −2 llf + k ln n with k = coefficients \[`llf`,
//!   `aic`, `bic`\].

use faer::Mat;
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::qr::no_pivoting::factor::{
    qr_in_place, qr_in_place_scratch, recommended_block_size,
};

use super::design::Design;
use super::distributions::{f_survival, student_t_quantile, student_t_two_sided_p};
use super::error::FitError;

/// Options of an OLS fit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OlsOptions {
    /// Confidence level of the coefficient intervals (0.95 → 95 %).
    pub confidence: f64,
    /// A term whose column keeps less than this fraction of its norm after removing what the
    /// earlier terms explain counts as linearly dependent. `None` uses
    /// `√p · max(n, p) · ε`, the same rule numpy's `matrix_rank` applies to singular values.
    pub rank_tolerance: Option<f64>,
}

impl Default for OlsOptions {
    fn default() -> Self {
        OlsOptions {
            confidence: 0.95,
            rank_tolerance: None,
        }
    }
}

/// One coefficient with its inference, as statsmodels' summary table shows it.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Coefficient {
    /// The term (`const` for the intercept).
    pub term: String,
    /// The estimate β.
    pub estimate: f64,
    /// Its standard error.
    pub std_error: f64,
    /// t = estimate / std_error.
    pub t: f64,
    /// Two-sided p-value of t on `df_resid` degrees of freedom.
    pub p_value: f64,
    /// Lower confidence limit.
    pub ci_low: f64,
    /// Upper confidence limit.
    pub ci_high: f64,
}

/// A fitted OLS model: coefficients, fitted values, residuals and every statistic.
#[derive(Debug, Clone)]
pub struct OlsFit {
    /// The target's name.
    pub target: String,
    /// One entry per design column, in design order (`const` first).
    pub coefficients: Vec<Coefficient>,
    /// Observations used.
    pub n: usize,
    /// Model degrees of freedom: coefficients − 1.
    pub df_model: usize,
    /// Residual degrees of freedom: n − coefficients.
    pub df_resid: usize,
    /// R² = 1 − SSE/SST (Eq. 4).
    pub r2: f64,
    /// Adjusted R² = 1 − (n − 1)/df_resid · (1 − R²).
    pub adj_r2: f64,
    /// √(SSE / df_resid): the residual standard error.
    pub rmse: f64,
    /// F = MSR / MSE (Eq. 3).
    pub f_statistic: f64,
    /// P(F ≥ f_statistic) under H₀: all slopes zero (Eq. 2).
    pub f_p_value: f64,
    /// Regression sum of squares SSR = SST − SSE (statsmodels: `ess`).
    pub ss_regression: f64,
    /// Error (residual) sum of squares SSE (statsmodels: `ssr`).
    pub ss_error: f64,
    /// Total sum of squares about the mean SST (statsmodels: `centered_tss`).
    pub ss_total: f64,
    /// MSR = SSR / df_model.
    pub mse_model: f64,
    /// MSE = SSE / df_resid.
    pub mse_resid: f64,
    /// Gaussian log-likelihood at the estimate.
    pub log_likelihood: f64,
    /// Akaike information criterion.
    pub aic: f64,
    /// Bayesian information criterion.
    pub bic: f64,
    /// Confidence level of the intervals.
    pub confidence: f64,
    /// Rows of the source left out (lags without a value).
    pub rows_dropped: usize,
    /// X β for every row.
    pub fitted: Vec<f64>,
    /// y − X β for every row.
    pub residuals: Vec<f64>,
    /// (XᵀX)⁻¹, the unscaled covariance of the estimates (multiply by `mse_resid` for the
    /// covariance).
    pub normalized_cov: Mat<f64>,
}

impl OlsFit {
    /// The estimates β in design order.
    pub fn estimates(&self) -> Vec<f64> {
        self.coefficients.iter().map(|c| c.estimate).collect()
    }

    /// The coefficient of a term, if the model has it.
    pub fn coefficient(&self, term: &str) -> Option<&Coefficient> {
        self.coefficients.iter().find(|c| c.term == term)
    }

    /// The prediction for one regressor row (intercept entry included, design order).
    pub fn predict_row(&self, x: &[f64]) -> Result<f64, FitError> {
        if x.len() != self.coefficients.len() {
            return Err(FitError::Dimension {
                what: "a regressor row",
                expected: self.coefficients.len(),
                found: x.len(),
            });
        }
        Ok(x.iter()
            .zip(&self.coefficients)
            .map(|(x, c)| x * c.estimate)
            .sum())
    }

    /// Predictions for every row of a design with the same terms.
    pub fn predict(&self, design: &Design) -> Result<Vec<f64>, FitError> {
        let same_terms = design
            .terms()
            .iter()
            .eq(self.coefficients.iter().map(|c| &c.term));
        if !same_terms {
            return Err(FitError::Dimension {
                what: "terms of the design to predict",
                expected: self.coefficients.len(),
                found: design.n_coefficients(),
            });
        }
        Ok(linear_combination(design, &self.estimates()))
    }
}

/// Fits `design` by OLS with default options (95 % intervals).
pub fn ols(design: &Design) -> Result<OlsFit, FitError> {
    ols_with(design, &OlsOptions::default())
}

/// Fits `design` by OLS.
///
/// Errors, each naming the term: fewer rows than coefficients + 1, a constant term, two
/// identical terms, a term that is a linear combination of earlier ones, a constant target.
pub fn ols_with(design: &Design, options: &OlsOptions) -> Result<OlsFit, FitError> {
    least_squares(design, None, options)
}

/// Fits `design` by weighted least squares: minimises Σ wᵢ (yᵢ − xᵢβ)², as statsmodels' `WLS`
/// does, and reports its statistics: sums of squares are weighted (SST about the weighted mean),
/// the log-likelihood gains ½ Σ ln wᵢ, and `fitted` and `residuals` are on the data's own scale.
/// Weights are relative (scaling them all changes no estimate, standard error or p-value).
///
/// Used where two sources of rows deserve different trust, e.g. a large simulated database and
/// a few real experiments that must count as much as the database does.
///
/// Errors: the errors of [`ols_with`], and a weight that is not finite and positive, or a
/// weight count other than the row count.
pub fn wls(design: &Design, weights: &[f64], options: &OlsOptions) -> Result<OlsFit, FitError> {
    if weights.len() != design.n_rows() {
        return Err(FitError::Dimension {
            what: "regression weights",
            expected: design.n_rows(),
            found: weights.len(),
        });
    }
    if let Some(&bad) = weights.iter().find(|w| !(w.is_finite() && **w > 0.0)) {
        return Err(FitError::InvalidParameter {
            name: "weight",
            value: bad,
            requirement: "every weight must be finite and positive",
        });
    }
    least_squares(design, Some(weights), options)
}

/// OLS (`weights` None) or WLS: the weighted problem is solved as OLS on rows scaled by √wᵢ
/// (the whitened design), and its statistics are stated on the weighted sums of squares.
fn least_squares(
    design: &Design,
    weights: Option<&[f64]>,
    options: &OlsOptions,
) -> Result<OlsFit, FitError> {
    if !(options.confidence > 0.0 && options.confidence < 1.0) {
        return Err(FitError::InvalidParameter {
            name: "confidence",
            value: options.confidence,
            requirement: "must lie strictly between 0 and 1",
        });
    }
    let n = design.n_rows();
    let p = design.n_coefficients();
    if n < p + 1 {
        return Err(FitError::NotEnoughRows {
            rows: n,
            coefficients: p,
            needed: p + 1,
            dropped: design.rows_dropped(),
        });
    }
    check_constant_and_duplicate_terms(design)?;
    let weight = |i: usize| weights.map_or(1.0, |w| w[i]);
    let y = design.y();
    let weight_total: f64 = (0..n).map(weight).sum();
    let y_mean = y
        .iter()
        .enumerate()
        .map(|(i, v)| weight(i) * v)
        .sum::<f64>()
        / weight_total;
    let ss_total: f64 = y
        .iter()
        .enumerate()
        .map(|(i, v)| weight(i) * (v - y_mean) * (v - y_mean))
        .sum();
    if ss_total == 0.0 {
        return Err(FitError::ConstantTarget {
            target: design.target().to_string(),
            value: y_mean,
        });
    }

    let solution = match weights {
        None => solve_least_squares(design, options)?,
        Some(w) => solve_least_squares(&design.with_row_scales(w), options)?,
    };
    let estimates = solution.estimates;
    let fitted = linear_combination(design, &estimates);
    let residuals: Vec<f64> = y.iter().zip(&fitted).map(|(y, f)| y - f).collect();
    let ss_error: f64 = residuals
        .iter()
        .enumerate()
        .map(|(i, r)| weight(i) * r * r)
        .sum();

    let nf = n as f64;
    let df_model = p - 1;
    let df_resid = n - p;
    let ss_regression = ss_total - ss_error;
    let mse_model = ss_regression / df_model as f64;
    let mse_resid = ss_error / df_resid as f64;
    let f_statistic = mse_model / mse_resid;
    let r2 = 1.0 - ss_error / ss_total;
    let log_weights: f64 = weights.map_or(0.0, |w| w.iter().map(|w| w.ln()).sum());
    let log_likelihood =
        -nf / 2.0 * (2.0 * std::f64::consts::PI).ln() - nf / 2.0 * (ss_error / nf).ln() - nf / 2.0
            + 0.5 * log_weights;
    let quantile = student_t_quantile(1.0 - (1.0 - options.confidence) / 2.0, df_resid as f64);
    let coefficients = design
        .terms()
        .iter()
        .enumerate()
        .map(|(j, term)| {
            let estimate = estimates[j];
            let std_error = (mse_resid * solution.normalized_cov[(j, j)]).sqrt();
            let t = estimate / std_error;
            Coefficient {
                term: term.clone(),
                estimate,
                std_error,
                t,
                p_value: student_t_two_sided_p(t, df_resid as f64),
                ci_low: estimate - quantile * std_error,
                ci_high: estimate + quantile * std_error,
            }
        })
        .collect();
    Ok(OlsFit {
        target: design.target().to_string(),
        coefficients,
        n,
        df_model,
        df_resid,
        r2,
        adj_r2: 1.0 - (nf - 1.0) / df_resid as f64 * (1.0 - r2),
        rmse: mse_resid.sqrt(),
        f_statistic,
        f_p_value: f_survival(f_statistic, df_model as f64, df_resid as f64),
        ss_regression,
        ss_error,
        ss_total,
        mse_model,
        mse_resid,
        log_likelihood,
        aic: -2.0 * log_likelihood + 2.0 * p as f64,
        bic: -2.0 * log_likelihood + p as f64 * nf.ln(),
        confidence: options.confidence,
        rows_dropped: design.rows_dropped(),
        fitted,
        residuals,
        normalized_cov: solution.normalized_cov,
    })
}

/// X β, accumulated column by column (each column is contiguous).
fn linear_combination(design: &Design, beta: &[f64]) -> Vec<f64> {
    let mut out = vec![0.0; design.n_rows()];
    for (j, &b) in beta.iter().enumerate() {
        for (o, x) in out.iter_mut().zip(design.column(j)) {
            *o += b * x;
        }
    }
    out
}

/// Constant and exactly duplicated columns get their own, plainer messages before the QR.
fn check_constant_and_duplicate_terms(design: &Design) -> Result<(), FitError> {
    let terms = design.terms();
    for (j, term) in terms.iter().enumerate().skip(1) {
        let column = design.column(j);
        let first = column[0];
        if column.iter().all(|&v| v == first) {
            return Err(FitError::ConstantTerm {
                term: term.clone(),
                value: first,
            });
        }
        for (k, earlier) in terms.iter().enumerate().take(j).skip(1) {
            // Distinct columns almost always differ in their first rows, so this is cheap.
            if design.column(k) == column {
                return Err(FitError::DuplicateTerm {
                    term: term.clone(),
                    of: earlier.clone(),
                });
            }
        }
    }
    Ok(())
}

/// The least-squares solution and (XᵀX)⁻¹.
struct Solution {
    estimates: Vec<f64>,
    normalized_cov: Mat<f64>,
}

/// QR of the column-scaled, target-augmented matrix `[X S⁻¹ | y/‖y‖]`.
///
/// With `X S⁻¹ = Q R`, the last column of the factor holds `Qᵀy` in its first p rows, so
/// `β = S⁻¹ R⁻¹ (Qᵀy)` needs no second pass over the data, and `(XᵀX)⁻¹ = S⁻¹ R⁻¹ R⁻ᵀ S⁻¹`.
fn solve_least_squares(design: &Design, options: &OlsOptions) -> Result<Solution, FitError> {
    let n = design.n_rows();
    let p = design.n_coefficients();
    let scales: Vec<f64> = (0..p)
        .map(|j| design.column(j).iter().map(|v| v * v).sum::<f64>().sqrt())
        .collect();
    let y_scale = design.y().iter().map(|v| v * v).sum::<f64>().sqrt();
    // A zero target (possible after centring) still needs a finite scale.
    let y_scale = if y_scale > 0.0 { y_scale } else { 1.0 };

    let mut work = Mat::<f64>::zeros(n, p + 1);
    for (j, &scale) in scales.iter().enumerate() {
        for (w, x) in work.col_as_slice_mut(j).iter_mut().zip(design.column(j)) {
            *w = x / scale;
        }
    }
    for (w, y) in work.col_as_slice_mut(p).iter_mut().zip(design.y()) {
        *w = y / y_scale;
    }
    let block_size = recommended_block_size::<f64>(n, p + 1);
    let mut householder = Mat::<f64>::zeros(block_size, p + 1);
    let par = faer::Par::Seq;
    let mut scratch = MemBuffer::new(qr_in_place_scratch::<f64>(
        n,
        p + 1,
        block_size,
        par,
        Default::default(),
    ));
    qr_in_place(
        work.as_mut(),
        householder.as_mut(),
        par,
        MemStack::new(&mut scratch),
        Default::default(),
    );
    let r = |i: usize, j: usize| work[(i, j)];

    let tolerance = options
        .rank_tolerance
        .unwrap_or_else(|| (p as f64).sqrt() * n.max(p) as f64 * f64::EPSILON);
    for k in 1..p {
        let independence = r(k, k).abs();
        if independence < tolerance || !independence.is_finite() {
            return Err(collinear_term(design, &work, k, independence, tolerance));
        }
    }

    // R⁻¹ by back substitution, one column at a time (p is small).
    let mut r_inverse = Mat::<f64>::zeros(p, p);
    for col in 0..p {
        for row in (0..=col).rev() {
            let identity = if row == col { 1.0 } else { 0.0 };
            let mut sum = identity;
            for k in row + 1..=col {
                sum -= r(row, k) * r_inverse[(k, col)];
            }
            r_inverse[(row, col)] = sum / r(row, row);
        }
    }
    let estimates = (0..p)
        .map(|j| {
            let scaled: f64 = (j..p).map(|k| r_inverse[(j, k)] * r(k, p)).sum();
            scaled * y_scale / scales[j]
        })
        .collect();
    let mut normalized_cov = Mat::<f64>::zeros(p, p);
    for i in 0..p {
        for j in i..p {
            let product: f64 = (j..p).map(|k| r_inverse[(i, k)] * r_inverse[(j, k)]).sum();
            let value = product / (scales[i] * scales[j]);
            normalized_cov[(i, j)] = value;
            normalized_cov[(j, i)] = value;
        }
    }
    Ok(Solution {
        estimates,
        normalized_cov,
    })
}

/// The error for term `k` whose scaled column is (nearly) in the span of the columns before
/// it: names the earlier terms that make it up, found by solving `R₁₁ c = r₁ₖ`.
fn collinear_term(
    design: &Design,
    factor: &Mat<f64>,
    k: usize,
    independence: f64,
    tolerance: f64,
) -> FitError {
    let mut c = vec![0.0; k];
    for i in (0..k).rev() {
        let mut sum = factor[(i, k)];
        for (m, cm) in c.iter().enumerate().skip(i + 1) {
            sum -= factor[(i, m)] * cm;
        }
        c[i] = sum / factor[(i, i)];
    }
    // Columns are unit-norm here, so |c_i| is the share of term k that term i carries.
    let combination_of = c
        .iter()
        .enumerate()
        .filter(|(_, ci)| ci.abs() > 1e-6)
        .map(|(i, _)| design.terms()[i].clone())
        .collect();
    FitError::CollinearTerm {
        term: design.terms()[k].clone(),
        combination_of,
        independence,
        tolerance,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn design(columns: &[(&str, Vec<f64>)], y: Vec<f64>) -> Design {
        Design::from_columns(
            "y",
            y,
            columns
                .iter()
                .map(|(n, v)| (n.to_string(), v.clone()))
                .collect(),
        )
        .unwrap()
    }

    #[test]
    fn exact_line_is_recovered_with_zero_residuals() {
        let x: Vec<f64> = (0..10).map(|i| i as f64).collect();
        let y: Vec<f64> = x.iter().map(|x| 3.0 - 2.0 * x).collect();
        let fit = ols(&design(&[("x", x)], y)).unwrap();
        assert!((fit.coefficients[0].estimate - 3.0).abs() < 1e-12);
        assert!((fit.coefficients[1].estimate + 2.0).abs() < 1e-12);
        assert!(fit.ss_error < 1e-20);
        assert!((fit.r2 - 1.0).abs() < 1e-12);
    }

    #[test]
    fn textbook_simple_regression_statistics() {
        // y = 1 + 2x with residuals ±1 alternating, x = 1..6: hand-checkable sums.
        let x = vec![1.0, 2.0, 3.0, 4.0, 5.0, 6.0];
        let noise = [1.0, -1.0, 1.0, -1.0, 1.0, -1.0];
        let y: Vec<f64> = x
            .iter()
            .zip(noise)
            .map(|(x, e)| 1.0 + 2.0 * x + e)
            .collect();
        let fit = ols(&design(&[("x", x.clone())], y.clone())).unwrap();
        // Closed forms: slope = Sxy/Sxx, intercept = ȳ − slope·x̄.
        let xm = 3.5;
        let ym = y.iter().sum::<f64>() / 6.0;
        let sxx: f64 = x.iter().map(|x| (x - xm) * (x - xm)).sum();
        let sxy: f64 = x.iter().zip(&y).map(|(x, y)| (x - xm) * (y - ym)).sum();
        let slope = sxy / sxx;
        assert!((fit.coefficients[1].estimate - slope).abs() < 1e-12);
        assert!((fit.coefficients[0].estimate - (ym - slope * xm)).abs() < 1e-12);
        let sse: f64 = fit.residuals.iter().map(|r| r * r).sum();
        let se_slope = (sse / 4.0 / sxx).sqrt();
        assert!((fit.coefficients[1].std_error - se_slope).abs() < 1e-12);
        assert_eq!((fit.n, fit.df_model, fit.df_resid), (6, 1, 4));
        // One slope: F equals t².
        assert!((fit.f_statistic - fit.coefficients[1].t.powi(2)).abs() < 1e-9 * fit.f_statistic);
        assert!((fit.f_p_value - fit.coefficients[1].p_value).abs() < 1e-12);
    }

    #[test]
    fn rank_problems_are_named() {
        let a: Vec<f64> = (0..20).map(|i| (i as f64).sin()).collect();
        let b: Vec<f64> = (0..20).map(|i| (i as f64 * 0.7).cos()).collect();
        let y: Vec<f64> = (0..20).map(|i| i as f64).collect();
        let err = ols(&design(
            &[("a", a.clone()), ("k", vec![4.0; 20])],
            y.clone(),
        ))
        .unwrap_err();
        assert_eq!(
            err.to_string(),
            "term `k` is constant (4) over the fitted rows, so it duplicates the intercept `const`"
        );
        let err = ols(&design(
            &[("a", a.clone()), ("b", b.clone()), ("a2", a.clone())],
            y.clone(),
        ))
        .unwrap_err();
        assert_eq!(
            err.to_string(),
            "term `a2` has exactly the same values as term `a`"
        );
        let combo: Vec<f64> = a.iter().zip(&b).map(|(a, b)| 2.0 * a - b + 1.0).collect();
        let err = ols(&design(&[("a", a), ("b", b), ("c", combo)], y)).unwrap_err();
        match err {
            FitError::CollinearTerm {
                term,
                combination_of,
                ..
            } => {
                assert_eq!(term, "c");
                assert_eq!(combination_of, ["const", "a", "b"]);
            }
            other => panic!("{other}"),
        }
    }

    #[test]
    fn too_few_rows_and_constant_target() {
        let err = ols(&design(&[("a", vec![1.0, 2.0])], vec![1.0, 3.0])).unwrap_err();
        assert_eq!(
            err.to_string(),
            "only 2 usable rows for 2 coefficients (need at least 3)"
        );
        let err = ols(&design(&[("a", vec![1.0, 2.0, 4.0])], vec![5.0; 3])).unwrap_err();
        assert!(matches!(err, FitError::ConstantTarget { .. }), "{err}");
    }
}
