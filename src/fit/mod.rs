//! Regression: the paper's multiple regression (Eq. 1) with its F-test and R² (Eqs. 2–4),
//! statsmodels-compatible statistics, a terms language for polynomial and dynamic features,
//! sensitivity analysis, model selection and online recalibration.
//!
//! The usual path: [`parse_terms`] → [`Design::from_recording`] → [`ols()`] → [`sensitivity()`] →
//! [`FitReport`]; or [`select()`] first to choose the terms.
//!
//! ```
//! use servosight::fit::{Design, ols, parse_terms, sensitivity};
//! use servosight::signal::Recording;
//!
//! let mut rec = Recording::new(
//!     "db",
//!     vec!["time_s".into(), "X.stator_temp_C".into(), "ref.X.motor_flange_temp_C".into()],
//! )?;
//! for (i, stator) in [30.0, 31.0, 33.0, 36.0, 40.0, 41.0].into_iter().enumerate() {
//!     let noise = [0.1, -0.1, 0.05, 0.0, -0.05, 0.02][i];
//!     rec.push_row(&[i as f64, stator, 2.0 + 0.9 * stator + noise])?;
//! }
//! let terms = parse_terms("X.stator_temp_C")?; // Eq. 7: T_motor = C0 + C1·T_stator
//! let design = Design::from_recording(&rec, "ref.X.motor_flange_temp_C", &terms)?;
//! let fit = ols(&design)?;
//! assert!((fit.coefficients[1].estimate - 0.9).abs() < 0.05);
//! assert!(fit.r2 > 0.99);
//! let ranked = sensitivity(&fit, &design);
//! assert_eq!(ranked[0].term, "X.stator_temp_C");
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod autocorrelation;
pub mod design;
pub mod distributions;
pub mod error;
pub mod minimise;
pub mod ols;
pub mod report;
pub mod rls;
pub mod selection;
pub mod sensitivity;
pub mod terms;

pub use design::Design;
pub use error::{FitError, TermError};
pub use ols::{Coefficient, OlsFit, OlsOptions, ols, ols_with, wls};
pub use report::FitReport;
pub use rls::RecursiveLeastSquares;
pub use selection::{
    Criterion, CvScore, Direction, Selection, SelectionOptions, blocked_cross_validation, select,
};
pub use sensitivity::{TermSensitivity, sensitivity};
pub use terms::{Expr, INTERCEPT, Term, parse_terms};
