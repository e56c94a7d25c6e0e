//! The fit report: the JSON contract of `servosight fit` (DESIGN.md) and a readable summary
//! table in the spirit of statsmodels' `summary()`.

use std::fmt::Write as _;

use super::ols::{Coefficient, OlsFit};
use super::selection::Selection;
use super::sensitivity::TermSensitivity;

/// Everything `servosight fit` reports. The fields of DESIGN.md's contract come first; the
/// rest are additions the contract allows.
///
/// Non-finite figures (e.g. F of a perfect fit) serialise as JSON `null`; p-values too small
/// for an f64 are 0.
#[derive(Debug, Clone, serde::Serialize)]
pub struct FitReport {
    /// Observations used.
    pub n: usize,
    /// Coefficients − 1.
    pub df_model: usize,
    /// n − coefficients.
    pub df_resid: usize,
    /// R².
    pub r2: f64,
    /// Adjusted R².
    pub adj_r2: f64,
    /// √(SSE / df_resid), the residual standard error.
    pub rmse: f64,
    /// F = MSR / MSE.
    pub f_statistic: f64,
    /// P(F ≥ f_statistic).
    pub f_p_value: f64,
    /// Coefficients in model order, `const` first.
    pub coefficients: Vec<Coefficient>,
    /// Sensitivity per term (the intercept excluded), most important first.
    pub sensitivity: Vec<TermSensitivity>,
    /// The target column.
    pub target: String,
    /// Regression sum of squares (SST − SSE).
    pub ss_regression: f64,
    /// Error sum of squares.
    pub ss_error: f64,
    /// Total sum of squares about the mean.
    pub ss_total: f64,
    /// SSR / df_model.
    pub mse_model: f64,
    /// SSE / df_resid.
    pub mse_resid: f64,
    /// Gaussian log-likelihood.
    pub log_likelihood: f64,
    /// Akaike information criterion.
    pub aic: f64,
    /// Bayesian information criterion.
    pub bic: f64,
    /// Confidence level of `ci_low`/`ci_high`.
    pub confidence: f64,
    /// Source rows left out because a lag had no value there.
    pub rows_dropped: usize,
    /// How the terms were chosen, when a selection ran.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub selection: Option<Selection>,
}

impl FitReport {
    /// The report of a fit and its sensitivity analysis.
    pub fn new(fit: &OlsFit, sensitivity: Vec<TermSensitivity>) -> FitReport {
        FitReport {
            n: fit.n,
            df_model: fit.df_model,
            df_resid: fit.df_resid,
            r2: fit.r2,
            adj_r2: fit.adj_r2,
            rmse: fit.rmse,
            f_statistic: fit.f_statistic,
            f_p_value: fit.f_p_value,
            coefficients: fit.coefficients.clone(),
            sensitivity,
            target: fit.target.clone(),
            ss_regression: fit.ss_regression,
            ss_error: fit.ss_error,
            ss_total: fit.ss_total,
            mse_model: fit.mse_model,
            mse_resid: fit.mse_resid,
            log_likelihood: fit.log_likelihood,
            aic: fit.aic,
            bic: fit.bic,
            confidence: fit.confidence,
            rows_dropped: fit.rows_dropped,
            selection: None,
        }
    }

    /// The same report, recording how its terms were selected.
    pub fn with_selection(mut self, selection: Selection) -> FitReport {
        self.selection = Some(selection);
        self
    }

    /// A plain-text summary: model statistics, the coefficient table, sensitivity and (when
    /// present) the selection trace.
    pub fn summary_table(&self) -> String {
        let term_width = self
            .coefficients
            .iter()
            .map(|c| c.term.chars().count())
            .max()
            .unwrap_or(5)
            .max(5);
        let width = (term_width + 68).max(78);
        let heavy = "=".repeat(width);
        let light = "-".repeat(width);
        let mut out = String::new();
        let title = "OLS Regression Results";
        let _ = writeln!(out, "{title:^width$}");
        let _ = writeln!(out, "{heavy}");
        let half = width / 2;
        let pairs = [
            (
                ("Dep. Variable:", self.target.clone()),
                ("R-squared:", number(self.r2)),
            ),
            (
                ("Model:", "OLS (QR)".into()),
                ("Adj. R-squared:", number(self.adj_r2)),
            ),
            (
                ("No. Observations:", self.n.to_string()),
                ("F-statistic:", number(self.f_statistic)),
            ),
            (
                ("Df Residuals:", self.df_resid.to_string()),
                ("Prob (F-statistic):", p_value(self.f_p_value)),
            ),
            (
                ("Df Model:", self.df_model.to_string()),
                ("Log-Likelihood:", number(self.log_likelihood)),
            ),
            (
                ("RMSE √(SSE/df):", number(self.rmse)),
                ("AIC:", number(self.aic)),
            ),
            (
                ("Rows dropped (lag):", self.rows_dropped.to_string()),
                ("BIC:", number(self.bic)),
            ),
        ];
        for ((left_key, left_value), (right_key, right_value)) in pairs {
            let left = key_value(left_key, &left_value, half - 2);
            let right = key_value(right_key, &right_value, width - half);
            let _ = writeln!(out, "{left}  {right}");
        }
        let _ = writeln!(out, "{heavy}");
        let low = format!("[{:.3}", (1.0 - self.confidence) / 2.0);
        let high = format!("{:.3}]", 1.0 - (1.0 - self.confidence) / 2.0);
        let _ = writeln!(
            out,
            "{:<term_width$} {:>12} {:>12} {:>10} {:>9} {:>11} {:>11}",
            "", "coef", "std err", "t", "P>|t|", low, high
        );
        let _ = writeln!(out, "{light}");
        for c in &self.coefficients {
            let _ = writeln!(
                out,
                "{:<term_width$} {:>12} {:>12} {:>10} {:>9} {:>11} {:>11}",
                c.term,
                number(c.estimate),
                number(c.std_error),
                fixed(c.t, 3),
                p_value(c.p_value),
                number(c.ci_low),
                number(c.ci_high)
            );
        }
        let _ = writeln!(out, "{heavy}");
        if !self.sensitivity.is_empty() {
            let _ = writeln!(out, "Sensitivity (ranked by drop-one partial R²)");
            let _ = writeln!(
                out,
                "{:>4}  {:<term_width$} {:>13} {:>11}",
                "rank", "term", "standardized", "partial R²"
            );
            for s in &self.sensitivity {
                let _ = writeln!(
                    out,
                    "{:>4}  {:<term_width$} {:>13} {:>11}",
                    s.rank,
                    s.term,
                    fixed(s.standardized, 4),
                    fixed(s.partial_r2, 4)
                );
            }
            let _ = writeln!(out, "{heavy}");
        }
        if let Some(selection) = &self.selection {
            write_selection(&mut out, selection, term_width);
            let _ = writeln!(out, "{heavy}");
        }
        out
    }
}

fn write_selection(out: &mut String, selection: &Selection, term_width: usize) {
    let _ = writeln!(
        out,
        "Selection by {} from {} candidates ({}-fold time-blocked CV, gap {} rows)",
        selection.method,
        selection.candidates.len(),
        selection.cv.folds,
        selection.cv.gap_rows
    );
    for step in &selection.steps {
        let sign = if step.action == "added" { '+' } else { '-' };
        let _ = writeln!(
            out,
            "  {sign} {:<term_width$}  p = {:>9}   BIC after = {}",
            step.term,
            p_value(step.p_value),
            number(step.bic)
        );
    }
    if selection.steps.is_empty() {
        let _ = writeln!(out, "  (no term changed the model)");
    }
    for unusable in &selection.unusable {
        let _ = writeln!(out, "  skipped {}: {}", unusable.term, unusable.reason);
    }
    let chosen = if selection.chosen.is_empty() {
        "(intercept only)".to_string()
    } else {
        selection.chosen.join(", ")
    };
    let _ = writeln!(out, "  chosen: {chosen}");
    let _ = write!(
        out,
        "  out-of-sample RMSE {} (R² {})",
        number(selection.cv.rmse),
        fixed(selection.cv.r2, 4)
    );
    match &selection.all_candidates_cv {
        Some(all) => {
            let _ = writeln!(
                out,
                "; with all candidates {} (R² {})",
                number(all.rmse),
                fixed(all.r2, 4)
            );
        }
        None => {
            let _ = writeln!(out, "; the model with all candidates cannot be fitted");
        }
    }
}

/// `key` left-aligned and `value` right-aligned in `width` characters (wider if they need it).
fn key_value(key: &str, value: &str, width: usize) -> String {
    let room = width
        .saturating_sub(key.chars().count())
        .max(value.chars().count() + 1);
    format!("{key}{value:>room$}")
}

/// A number with four significant digits, in scientific notation when very large or small.
fn number(value: f64) -> String {
    if !value.is_finite() {
        return value.to_string();
    }
    let magnitude = value.abs();
    if magnitude == 0.0 {
        "0".to_string()
    } else if (1e-3..1e7).contains(&magnitude) {
        let decimals = (3 - magnitude.log10().floor() as i32).max(0) as usize;
        format!("{value:.decimals$}")
    } else {
        format!("{value:.3e}")
    }
}

fn fixed(value: f64, decimals: usize) -> String {
    format!("{value:.decimals$}")
}

/// p-values: fixed decimals while readable, scientific below 1e-4.
fn p_value(value: f64) -> String {
    if value.is_nan() {
        "nan".to_string()
    } else if value == 0.0 {
        "0".to_string()
    } else if value < 1e-4 {
        format!("{value:.2e}")
    } else {
        format!("{value:.4}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_read_well() {
        assert_eq!(number(0.001038623), "0.001039");
        assert_eq!(number(-53.5177), "-53.52");
        assert_eq!(number(8693.139), "8693");
        assert_eq!(number(1.2e-9), "1.200e-9");
        assert_eq!(number(f64::INFINITY), "inf");
        assert_eq!(p_value(1.3e-41), "1.30e-41");
        assert_eq!(p_value(0.0421), "0.0421");
    }
}
