//! Errors of the regression engine. Each names the term (or the column) at fault, because the
//! person reading it wrote the terms string and needs to know which part to change.

use crate::signal::RecordingError;

/// A terms string that does not parse: which term, where, and what was expected.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("malformed term `{term}` at position {position}: {message}")]
pub struct TermError {
    /// The comma-separated item of the terms string the problem is in (trimmed).
    pub term: String,
    /// 1-based character position in the whole terms string.
    pub position: usize,
    /// What is wrong and what was expected instead.
    pub message: String,
}

/// Everything that can stop a fit.
#[derive(Debug, thiserror::Error)]
pub enum FitError {
    /// The terms string does not parse.
    #[error(transparent)]
    Term(#[from] TermError),
    /// A column the target or a term needs is missing from the recording.
    #[error(transparent)]
    Recording(#[from] RecordingError),
    /// A value so large that the sums of squares behind every statistic would overflow.
    #[error(
        "`{column}` is {value:e} in its data row {}: values beyond ±1e100 overflow the fit's \
         sums of squares (a wrong unit or a garbled cell?)",
        row + 1
    )]
    TooLarge {
        /// The target or term.
        column: String,
        /// Row index (0-based) among the values given.
        row: usize,
        /// The value.
        value: f64,
    },
    /// Two design columns have the same name.
    #[error("term `{term}` is listed twice")]
    RepeatedTerm {
        /// The repeated term.
        term: String,
    },
    /// A term is the target itself, which would "explain" the target perfectly.
    #[error("the target `{target}` is also listed as a term")]
    TargetAsTerm {
        /// The target.
        target: String,
    },
    /// The target does not vary, so there is nothing to explain (R² is undefined).
    #[error("the target `{target}` is constant ({value}) over the fitted rows")]
    ConstantTarget {
        /// The target.
        target: String,
        /// Its value.
        value: f64,
    },
    /// Fewer usable rows than the model has coefficients plus one: no residual degrees of
    /// freedom, so no statistics.
    #[error(
        "only {rows} usable rows for {coefficients} coefficients (need at least {needed}){}",
        dropped_note(*.dropped)
    )]
    NotEnoughRows {
        /// Rows left for the fit.
        rows: usize,
        /// Coefficients in the model, the intercept included.
        coefficients: usize,
        /// Rows needed: coefficients + 1.
        needed: usize,
        /// Rows dropped because a `lag` term had no value there.
        dropped: usize,
    },
    /// A term's column does not vary, so it cannot be told apart from the intercept.
    #[error(
        "term `{term}` is constant ({value}) over the fitted rows, so it duplicates the intercept `const`"
    )]
    ConstantTerm {
        /// The constant term.
        term: String,
        /// Its value.
        value: f64,
    },
    /// Two terms have identical columns.
    #[error("term `{term}` has exactly the same values as term `{of}`")]
    DuplicateTerm {
        /// The later of the two terms.
        term: String,
        /// The earlier one.
        of: String,
    },
    /// A term is (numerically) a linear combination of the terms before it: the design is rank
    /// deficient and its coefficients would be arbitrary.
    #[error(
        "term `{term}` is a linear combination of {} (relative independent part {independence:.1e}, below the tolerance {tolerance:.1e}): drop one of them",
        list_terms(.combination_of)
    )]
    CollinearTerm {
        /// The dependent term.
        term: String,
        /// The earlier terms it is (nearly) a combination of.
        combination_of: Vec<String>,
        /// The norm of the part of the term's column that the earlier terms do not explain,
        /// relative to the column's norm (0 = exactly dependent).
        independence: f64,
        /// The threshold below which a term counts as dependent.
        tolerance: f64,
    },
    /// A computed term overflowed or a value was not a number.
    #[error("term `{term}` is not a finite number at row {row} (time {time_s} s)")]
    NonFinite {
        /// The term.
        term: String,
        /// 0-based row in the recording.
        row: usize,
        /// The row's time.
        time_s: f64,
    },
    /// A cross-validation training set could not be fitted (a term constant outside the
    /// held-out block, say).
    #[error("cross-validation fold {fold} of {folds}: {reason}")]
    CrossValidationFold {
        /// 1-based fold number, in time order.
        fold: usize,
        /// Number of folds.
        folds: usize,
        /// Why the training fit failed (kept in the message, not as an error source, so it is
        /// printed once).
        reason: Box<FitError>,
    },
    /// Vectors or matrices of mismatched sizes were handed to the engine.
    #[error("{what}: expected {expected} values, got {found}")]
    Dimension {
        /// Which input.
        what: &'static str,
        /// The size required.
        expected: usize,
        /// The size given.
        found: usize,
    },
    /// A tuning parameter outside its valid range.
    #[error("{name} = {value} is invalid: {requirement}")]
    InvalidParameter {
        /// The parameter.
        name: &'static str,
        /// The value given.
        value: f64,
        /// What it must satisfy.
        requirement: &'static str,
    },
}

fn dropped_note(dropped: usize) -> String {
    if dropped == 0 {
        String::new()
    } else {
        format!(
            "; {dropped} rows were dropped because a lag reaches back before the recording starts"
        )
    }
}

fn list_terms(terms: &[String]) -> String {
    match terms {
        [] => "the earlier terms".to_string(),
        [only] => format!("`{only}`"),
        many => many
            .iter()
            .map(|t| format!("`{t}`"))
            .collect::<Vec<_>>()
            .join(", "),
    }
}
