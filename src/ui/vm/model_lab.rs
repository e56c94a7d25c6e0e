//! Model lab: fit a model from a database with its sensitivity ranking (the fit runs off the
//! UI thread with progress and cancel).

use serde::Serialize;

use super::{probability, statistic};
use crate::ui::state::{HmiState, JobProgress};

/// One coefficient row.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CoefficientRow {
    /// The term (`const` for the intercept).
    pub term: String,
    /// Estimate.
    pub estimate: String,
    /// Standard error.
    pub std_error: String,
    /// t.
    pub t: String,
    /// p-value.
    pub p_value: String,
    /// 95 % interval.
    pub interval: String,
}

/// One sensitivity row, most important first.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SensitivityRow {
    /// 1 for the most important.
    pub rank: usize,
    /// The term.
    pub term: String,
    /// Drop-one partial R².
    pub partial_r2: String,
    /// Standardised coefficient.
    pub standardized: String,
    /// 0–1 bar length (partial R² relative to the top term).
    pub bar: f32,
}

/// A finished fit.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FitView {
    /// The database.
    pub data: String,
    /// The target column.
    pub target: String,
    /// "n = 86400, R² = 0.9981, adj. R² = …, RMSE = …, F = … (p …)".
    pub summary: String,
    /// Coefficients.
    pub coefficients: Vec<CoefficientRow>,
    /// Sensitivity ranking.
    pub sensitivity: Vec<SensitivityRow>,
}

/// The Model lab.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ModelLabView {
    /// The running fit's progress.
    pub running: Option<JobProgress>,
    /// The last fit.
    pub result: Option<FitView>,
    /// Why the last fit failed or stopped.
    pub error: Option<String>,
}

/// Builds the Model lab.
pub fn build(state: &HmiState) -> ModelLabView {
    let lab = &state.model_lab;
    let result = lab.result.as_ref().map(|outcome| {
        let r = &outcome.report;
        let top = r
            .sensitivity
            .iter()
            .map(|s| s.partial_r2)
            .fold(0.0f64, f64::max);
        FitView {
            data: outcome.request.data.display().to_string(),
            target: r.target.clone(),
            summary: format!(
                "n = {}, R² = {}, adj. R² = {}, RMSE = {}, F = {} (p {})",
                r.n,
                statistic(r.r2),
                statistic(r.adj_r2),
                statistic(r.rmse),
                statistic(r.f_statistic),
                probability(r.f_p_value)
            ),
            coefficients: r
                .coefficients
                .iter()
                .map(|c| CoefficientRow {
                    term: c.term.clone(),
                    estimate: statistic(c.estimate),
                    std_error: statistic(c.std_error),
                    t: statistic(c.t),
                    p_value: probability(c.p_value),
                    interval: format!("[{}, {}]", statistic(c.ci_low), statistic(c.ci_high)),
                })
                .collect(),
            sensitivity: r
                .sensitivity
                .iter()
                .map(|s| SensitivityRow {
                    rank: s.rank,
                    term: s.term.clone(),
                    partial_r2: statistic(s.partial_r2),
                    standardized: statistic(s.standardized),
                    // Two decimals are all a bar can show (and keep snapshots exact).
                    bar: if top > 0.0 {
                        ((s.partial_r2 / top * 100.0).round() / 100.0) as f32
                    } else {
                        0.0
                    },
                })
                .collect(),
        }
    });
    ModelLabView {
        running: lab.running.clone(),
        result,
        error: lab.error.clone(),
    }
}
