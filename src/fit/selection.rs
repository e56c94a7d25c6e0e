//! Model selection: which candidate terms to keep.
//!
//! Two criteria, each searched forward, backward or both ways (stepwise):
//! - **F-test** (the paper's Eq. 3 applied one term at a time): a term enters when its partial
//!   F-test p-value is below `p_enter`, leaves when it rises above `p_remove`. For one term the
//!   partial F equals the square of its t statistic, so the p-value is the coefficient's.
//! - **BIC**: take the single addition or removal that lowers BIC most, until none does.
//!
//! The chosen model is then scored by **time-blocked cross-validation**: the rows (in time
//! order) are cut into contiguous blocks; each block is predicted by a model fitted on the
//! others, optionally leaving a gap of rows on both sides of the block out of training.
//! Neighbouring samples of a recording are strongly correlated, so random K-fold would let the
//! model see almost the same rows it is tested on and report an optimistic score.
//!
//! Every model in the search is fitted on the same rows, those where every candidate has a
//! value (a `lag` candidate drops the first rows for all of them), so BIC and p-values compare
//! like with like. Terms are treated independently: selection may keep `a^2` without `a`. Candidates that
//! cannot be added because they are constant or collinear with the current model are skipped
//! and listed in [`Selection::unusable`].

use super::design::Design;
use super::error::FitError;
use super::ols::{OlsFit, ols};

/// What decides whether a term is in the model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Criterion {
    /// Partial F-test p-values.
    FTest {
        /// A term enters when its p-value is below this.
        p_enter: f64,
        /// A term leaves when its p-value is above this (must be ≥ `p_enter`, or the search
        /// could add and remove the same term forever).
        p_remove: f64,
    },
    /// The Bayesian information criterion, lower is better.
    Bic,
}

impl Criterion {
    /// The classic stepwise thresholds: enter below 0.05, leave above 0.10.
    pub const STEPWISE_DEFAULT: Criterion = Criterion::FTest {
        p_enter: 0.05,
        p_remove: 0.10,
    };

    /// A short name for reports: `stepwise` or `bic`.
    pub fn name(&self) -> &'static str {
        match self {
            Criterion::FTest { .. } => "stepwise",
            Criterion::Bic => "bic",
        }
    }
}

/// Which moves the search may make.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Direction {
    /// Start from the intercept alone and only add.
    Forward,
    /// Start from all candidates and only remove.
    Backward,
    /// Start from the intercept alone; after every step, both additions and removals are
    /// considered (classic stepwise).
    Both,
}

/// Options of [`select`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SelectionOptions {
    /// The criterion.
    pub criterion: Criterion,
    /// The search direction.
    pub direction: Direction,
    /// Number of contiguous cross-validation blocks (≥ 2).
    pub cv_folds: usize,
    /// Rows left out of training on each side of the held-out block, to keep autocorrelated
    /// neighbours from leaking into the score.
    pub cv_gap_rows: usize,
}

impl Default for SelectionOptions {
    fn default() -> Self {
        SelectionOptions {
            criterion: Criterion::STEPWISE_DEFAULT,
            direction: Direction::Both,
            cv_folds: 5,
            cv_gap_rows: 0,
        }
    }
}

/// One move of the search.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct SelectionStep {
    /// `added` or `removed`.
    pub action: &'static str,
    /// The term.
    pub term: String,
    /// Its partial F-test p-value at the time of the move (in the larger of the two models).
    pub p_value: f64,
    /// BIC of the model after the move.
    pub bic: f64,
}

/// A candidate that could not be used, and why.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct UnusableTerm {
    /// The term.
    pub term: String,
    /// The fit error that excluded it.
    pub reason: String,
}

/// An out-of-sample score from time-blocked cross-validation.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct CvScore {
    /// Number of blocks.
    pub folds: usize,
    /// Rows left out of training on each side of the held-out block.
    pub gap_rows: usize,
    /// √(mean squared out-of-sample error) over all rows.
    pub rmse: f64,
    /// 1 − Σ out-of-sample error² / Σ (y − ȳ)²; can be negative for a useless model.
    pub r2: f64,
    /// RMSE of each block, in time order.
    pub fold_rmse: Vec<f64>,
}

/// The result of [`select`].
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Selection {
    /// `stepwise` or `bic`.
    pub method: &'static str,
    /// All candidate terms (the design's terms except `const`).
    pub candidates: Vec<String>,
    /// The chosen terms, in candidate order (the intercept is implied).
    pub chosen: Vec<String>,
    /// The moves, in order.
    pub steps: Vec<SelectionStep>,
    /// Candidates skipped because they were constant or collinear with the model.
    pub unusable: Vec<UnusableTerm>,
    /// Cross-validation score of the chosen model.
    pub cv: CvScore,
    /// Cross-validation score of the model with every candidate, for comparison; `None` when
    /// that model cannot be fitted (collinear candidates).
    pub all_candidates_cv: Option<CvScore>,
}

/// Chooses terms among the design's columns (the intercept is always kept) and scores the
/// result by time-blocked cross-validation.
pub fn select(design: &Design, options: &SelectionOptions) -> Result<Selection, FitError> {
    check_options(options)?;
    let candidates: Vec<usize> = (1..design.n_coefficients()).collect();
    let mut search = Search {
        design,
        current: match options.direction {
            Direction::Backward => candidates.clone(),
            Direction::Forward | Direction::Both => Vec::new(),
        },
        steps: Vec::new(),
        unusable: Vec::new(),
    };
    let may_add = options.direction != Direction::Backward;
    let may_remove = options.direction != Direction::Forward;
    // Each term can enter and leave a bounded number of times; this only stops pathological
    // cycles the thresholds should already prevent.
    let max_moves = 4 * candidates.len() + 4;
    while search.steps.len() < max_moves {
        let moved = match options.criterion {
            Criterion::FTest { p_enter, p_remove } => {
                let added = may_add && search.f_test_add(p_enter)?;
                let removed = may_remove && search.f_test_remove(p_remove)?;
                added || removed
            }
            Criterion::Bic => search.bic_move(may_add, may_remove)?,
        };
        if !moved {
            break;
        }
    }
    let mut chosen = search.current.clone();
    chosen.sort_unstable();
    let cv = blocked_cross_validation(
        &design.with_terms(&chosen),
        options.cv_folds,
        options.cv_gap_rows,
    )?;
    let all_candidates_cv = blocked_cross_validation(
        &design.with_terms(&candidates),
        options.cv_folds,
        options.cv_gap_rows,
    )
    .ok();
    Ok(Selection {
        method: options.criterion.name(),
        candidates: candidates
            .iter()
            .map(|&j| design.terms()[j].clone())
            .collect(),
        chosen: chosen.iter().map(|&j| design.terms()[j].clone()).collect(),
        steps: search.steps,
        unusable: search.unusable,
        cv,
        all_candidates_cv,
    })
}

fn check_options(options: &SelectionOptions) -> Result<(), FitError> {
    if let Criterion::FTest { p_enter, p_remove } = options.criterion {
        if !(p_enter > 0.0 && p_enter < 1.0) {
            return Err(FitError::InvalidParameter {
                name: "p_enter",
                value: p_enter,
                requirement: "must lie strictly between 0 and 1",
            });
        }
        if !(p_remove >= p_enter && p_remove < 1.0) {
            return Err(FitError::InvalidParameter {
                name: "p_remove",
                value: p_remove,
                requirement: "must be at least p_enter and below 1",
            });
        }
    }
    if options.cv_folds < 2 {
        return Err(FitError::InvalidParameter {
            name: "cv_folds",
            value: options.cv_folds as f64,
            requirement: "must be at least 2",
        });
    }
    Ok(())
}

struct Search<'a> {
    design: &'a Design,
    /// Design columns in the model, besides the intercept.
    current: Vec<usize>,
    steps: Vec<SelectionStep>,
    unusable: Vec<UnusableTerm>,
}

impl Search<'_> {
    fn fit(&self, columns: &[usize]) -> Result<OlsFit, FitError> {
        ols(&self.design.with_terms(columns))
    }

    fn name(&self, column: usize) -> String {
        self.design.terms()[column].clone()
    }

    /// The p-value of `column` in the fit of `columns` (which contains it).
    fn p_value(&self, fit: &OlsFit, column: usize) -> f64 {
        let name = &self.design.terms()[column];
        fit.coefficient(name).map_or(f64::NAN, |c| c.p_value)
    }

    /// Fits of every model one addition away; candidates that cannot be fitted are recorded as
    /// unusable and skipped. Errors that are not about the candidate (too few rows) abort.
    fn additions(&mut self) -> Result<Vec<(usize, OlsFit)>, FitError> {
        let mut out = Vec::new();
        for column in 1..self.design.n_coefficients() {
            if self.current.contains(&column) {
                continue;
            }
            let mut columns = self.current.clone();
            columns.push(column);
            match self.fit(&columns) {
                Ok(fit) => out.push((column, fit)),
                Err(
                    error @ (FitError::ConstantTerm { .. }
                    | FitError::DuplicateTerm { .. }
                    | FitError::CollinearTerm { .. }),
                ) => {
                    let term = self.name(column);
                    self.unusable.retain(|u| u.term != term);
                    self.unusable.push(UnusableTerm {
                        term,
                        reason: error.to_string(),
                    });
                }
                Err(other) => return Err(other),
            }
        }
        Ok(out)
    }

    fn record(&mut self, action: &'static str, column: usize, p_value: f64, bic: f64) {
        let term = self.name(column);
        self.steps.push(SelectionStep {
            action,
            term,
            p_value,
            bic,
        });
    }

    fn f_test_add(&mut self, p_enter: f64) -> Result<bool, FitError> {
        let best = self
            .additions()?
            .into_iter()
            .map(|(column, fit)| (column, self.p_value(&fit, column), fit.bic))
            .filter(|(_, p, _)| !p.is_nan())
            .min_by(|a, b| a.1.total_cmp(&b.1));
        match best {
            Some((column, p_value, bic)) if p_value < p_enter => {
                self.current.push(column);
                self.record("added", column, p_value, bic);
                Ok(true)
            }
            _ => Ok(false),
        }
    }

    fn f_test_remove(&mut self, p_remove: f64) -> Result<bool, FitError> {
        if self.current.is_empty() {
            return Ok(false);
        }
        let fit = self.fit(&self.current)?;
        let worst = self
            .current
            .iter()
            .map(|&column| (column, self.p_value(&fit, column)))
            .max_by(|a, b| a.1.total_cmp(&b.1));
        match worst {
            Some((column, p_value)) if p_value > p_remove => {
                self.current.retain(|&c| c != column);
                let bic = self.fit(&self.current)?.bic;
                self.record("removed", column, p_value, bic);
                Ok(true)
            }
            _ => Ok(false),
        }
    }

    fn bic_move(&mut self, may_add: bool, may_remove: bool) -> Result<bool, FitError> {
        let current_bic = self.fit(&self.current)?.bic;
        // (column, added?, p-value of the term in the larger model, BIC after the move)
        let mut best: Option<(usize, bool, f64, f64)> = None;
        let mut consider = |candidate: (usize, bool, f64, f64)| {
            if best.is_none_or(|b| candidate.3 < b.3) {
                best = Some(candidate);
            }
        };
        if may_add {
            for (column, fit) in self.additions()? {
                consider((column, true, self.p_value(&fit, column), fit.bic));
            }
        }
        if may_remove && !self.current.is_empty() {
            let full = self.fit(&self.current)?;
            for &column in &self.current {
                let without: Vec<usize> = self
                    .current
                    .iter()
                    .copied()
                    .filter(|&c| c != column)
                    .collect();
                let bic = self.fit(&without)?.bic;
                consider((column, false, self.p_value(&full, column), bic));
            }
        }
        match best {
            Some((column, added, p_value, bic)) if bic < current_bic => {
                if added {
                    self.current.push(column);
                    self.record("added", column, p_value, bic);
                } else {
                    self.current.retain(|&c| c != column);
                    self.record("removed", column, p_value, bic);
                }
                Ok(true)
            }
            _ => Ok(false),
        }
    }
}

/// Time-blocked cross-validation of the full `design`: `folds` contiguous blocks of rows (in
/// time order); each is predicted by an OLS fit on the rows outside it, leaving `gap_rows`
/// more rows on each side of the block out of training.
pub fn blocked_cross_validation(
    design: &Design,
    folds: usize,
    gap_rows: usize,
) -> Result<CvScore, FitError> {
    let n = design.n_rows();
    if folds < 2 || folds > n {
        return Err(FitError::InvalidParameter {
            name: "cv_folds",
            value: folds as f64,
            requirement: "must be at least 2 and at most the number of rows",
        });
    }
    let y = design.y();
    let y_mean = y.iter().sum::<f64>() / n as f64;
    let ss_total: f64 = y.iter().map(|v| (v - y_mean) * (v - y_mean)).sum();
    let mut squared_error_sum = 0.0;
    let mut fold_rmse = Vec::with_capacity(folds);
    for fold in 0..folds {
        let start = fold * n / folds;
        let end = (fold + 1) * n / folds;
        let train_start = start.saturating_sub(gap_rows);
        let train_end = end.saturating_add(gap_rows);
        let training = design.with_rows(|i| i < train_start || i >= train_end);
        let fit = ols(&training).map_err(|reason| FitError::CrossValidationFold {
            fold: fold + 1,
            folds,
            reason: Box::new(reason),
        })?;
        let held_out = design.with_rows(|i| (start..end).contains(&i));
        let predicted = fit.predict(&held_out)?;
        let fold_sum: f64 = predicted
            .iter()
            .zip(held_out.y())
            .map(|(p, y)| (y - p) * (y - p))
            .sum();
        squared_error_sum += fold_sum;
        fold_rmse.push((fold_sum / (end - start) as f64).sqrt());
    }
    Ok(CvScore {
        folds,
        gap_rows,
        rmse: (squared_error_sum / n as f64).sqrt(),
        r2: 1.0 - squared_error_sum / ss_total,
        fold_rmse,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    /// y = 2 + 3a − 1.5b + 0.8ab + noise, with junk candidates: white noise, a random walk
    /// (autocorrelated, the kind that fools random K-fold) and a square of a junk term.
    fn synthetic(seed: u64, n: usize) -> Design {
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let normal = Normal::new(0.0, 1.0).unwrap();
        let mut draw = || normal.sample(&mut rng);
        let a: Vec<f64> = (0..n).map(|_| draw()).collect();
        let b: Vec<f64> = (0..n).map(|_| draw()).collect();
        let junk: Vec<f64> = (0..n).map(|_| draw()).collect();
        let mut walk = vec![0.0; n];
        for i in 1..n {
            walk[i] = walk[i - 1] + 0.1 * draw();
        }
        let y: Vec<f64> = (0..n)
            .map(|i| 2.0 + 3.0 * a[i] - 1.5 * b[i] + 0.8 * a[i] * b[i] + 0.5 * draw())
            .collect();
        let ab: Vec<f64> = a.iter().zip(&b).map(|(a, b)| a * b).collect();
        let a2: Vec<f64> = a.iter().map(|a| a * a).collect();
        let junk2: Vec<f64> = junk.iter().map(|j| j * j).collect();
        Design::from_columns(
            "y",
            y,
            vec![
                ("junk".into(), junk),
                ("a".into(), a),
                ("walk".into(), walk),
                ("b".into(), b),
                ("a^2".into(), a2),
                ("a*b".into(), ab),
                ("junk^2".into(), junk2),
            ],
        )
        .unwrap()
    }

    #[test]
    fn every_criterion_and_direction_recovers_the_true_terms() {
        let design = synthetic(7, 1500);
        let strict = Criterion::FTest {
            p_enter: 0.001,
            p_remove: 0.002,
        };
        for criterion in [strict, Criterion::Bic] {
            for direction in [Direction::Forward, Direction::Backward, Direction::Both] {
                let options = SelectionOptions {
                    criterion,
                    direction,
                    ..SelectionOptions::default()
                };
                let selection = select(&design, &options).unwrap();
                assert_eq!(
                    selection.chosen,
                    ["a", "b", "a*b"],
                    "{criterion:?} {direction:?}: {:?}",
                    selection.steps
                );
                let all = selection.all_candidates_cv.unwrap();
                // Junk can only hurt out of sample.
                assert!(
                    selection.cv.rmse <= all.rmse,
                    "{:?} vs {all:?}",
                    selection.cv
                );
                assert!(selection.cv.r2 > 0.95, "{:?}", selection.cv);
            }
        }
    }

    #[test]
    fn backward_steps_remove_only_junk() {
        let design = synthetic(11, 1500);
        let options = SelectionOptions {
            criterion: Criterion::Bic,
            direction: Direction::Backward,
            ..SelectionOptions::default()
        };
        let selection = select(&design, &options).unwrap();
        let mut removed: Vec<&str> = selection.steps.iter().map(|s| s.term.as_str()).collect();
        removed.sort_unstable();
        assert_eq!(removed, ["a^2", "junk", "junk^2", "walk"]);
        assert!(selection.steps.iter().all(|s| s.action == "removed"));
        // BIC falls with every accepted move.
        assert!(selection.steps.windows(2).all(|w| w[1].bic < w[0].bic));
    }

    #[test]
    fn collinear_candidates_are_skipped_and_reported() {
        let base = synthetic(3, 400);
        let copy = base.column(base.term_index("a").unwrap()).to_vec();
        let mut columns: Vec<(String, Vec<f64>)> = (1..base.n_coefficients())
            .map(|j| (base.terms()[j].clone(), base.column(j).to_vec()))
            .collect();
        columns.push(("a_copy".into(), copy));
        let design = Design::from_columns("y", base.y().to_vec(), columns).unwrap();
        let selection = select(&design, &SelectionOptions::default()).unwrap();
        assert!(selection.chosen.contains(&"a".to_string()));
        assert!(!selection.chosen.contains(&"a_copy".to_string()));
        assert!(
            selection
                .unusable
                .iter()
                .any(|u| u.term == "a_copy" && u.reason.contains("same values as term `a`")),
            "{:?}",
            selection.unusable
        );
        assert_eq!(selection.all_candidates_cv, None);
    }

    #[test]
    fn blocked_cv_uses_contiguous_blocks_and_gaps() {
        // A target that drifts in time: a block held out from the end is predicted by
        // extrapolation, which a contiguous split exposes (random folds would interpolate).
        let n = 100;
        let t: Vec<f64> = (0..n).map(|i| i as f64).collect();
        let y: Vec<f64> = t.iter().map(|t| 0.01 * t * t).collect();
        let design = Design::from_columns("y", y, vec![("t".into(), t)]).unwrap();
        let score = blocked_cross_validation(&design, 4, 0).unwrap();
        assert_eq!(score.fold_rmse.len(), 4);
        // The curvature makes the outer blocks (extrapolated) worse than the inner ones.
        assert!(score.fold_rmse[0] > score.fold_rmse[1]);
        assert!(score.fold_rmse[3] > score.fold_rmse[2]);
        let gapped = blocked_cross_validation(&design, 4, 10).unwrap();
        assert!(gapped.rmse > score.rmse);
        let err = blocked_cross_validation(&design, 1, 0).unwrap_err();
        assert!(err.to_string().contains("cv_folds = 1"), "{err}");
    }

    #[test]
    fn invalid_thresholds_are_rejected() {
        let design = synthetic(1, 50);
        let options = SelectionOptions {
            criterion: Criterion::FTest {
                p_enter: 0.1,
                p_remove: 0.05,
            },
            ..SelectionOptions::default()
        };
        let err = select(&design, &options).unwrap_err();
        assert!(err.to_string().contains("p_remove = 0.05"), "{err}");
    }
}
