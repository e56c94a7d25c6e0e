//! Regression: the paper's multiple regression (Eq. 1) with its F-test and R² (Eqs. 2–4),
//! statsmodels-compatible statistics, a terms language for polynomial and dynamic features,
//! sensitivity analysis, model selection and online recalibration.

pub mod design;
pub mod distributions;
pub mod error;
pub mod ols;
pub mod rls;
pub mod selection;
pub mod sensitivity;
pub mod terms;

pub use design::Design;
pub use error::{FitError, TermError};
pub use ols::{Coefficient, OlsFit, OlsOptions, ols, ols_with};
pub use rls::RecursiveLeastSquares;
pub use selection::{
    Criterion, CvScore, Direction, Selection, SelectionOptions, blocked_cross_validation, select,
};
pub use sensitivity::{TermSensitivity, sensitivity};
pub use terms::{Expr, INTERCEPT, Term, parse_terms};
