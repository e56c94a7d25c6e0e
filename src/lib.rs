//! servosight: sensorless machine-tool condition monitoring from the signals a CNC controller's
//! servo drives already measure.
//!
//! Data flows one way (see `DESIGN.md`): a link produces frames, pure streaming estimators turn
//! them into a machine state, view models turn the state into panels. This crate is organised the
//! same way:
//!
//! - [`signal`]: channel names and units, the columnar [`signal::Recording`], the CSV v1 format.
//! - [`fit`]: regression (OLS by QR with statsmodels' statistics, terms language, sensitivity,
//!   selection, recursive least squares) that turns a database into estimator coefficients.
//! - [`estimators`]: the paper's estimators (Eqs. 7–15), calibration and accuracy.
//! - [`profile`]: the machine profile: geometry, ratings, limits, fitted coefficients.
//! - [`sim`]: the lumped-parameter physics twin that stands in for the paper's FEA database.
//! - [`link`]: frame sources (replay, embedded twin, Modbus RTU controller), the register map,
//!   the recorder, and the controller end of the map (`sim-controller`).
//! - [`compensation`]: approved, bounded, verified and audited compensation writes.
//! - [`discrepancy`]: sim-vs-real analysis: locate the mismatch, name the missing physics, model
//!   it and show the fit improve out of sample.
//! - [`parallel`]: a map over a few scoped threads, shared by calibration and discrepancy work.
//! - [`ui`]: the HMI (eframe/egui): session worker, decimated history, view models, panels.

pub mod compensation;
pub mod discrepancy;
pub mod estimators;
pub mod fit;
pub mod link;
pub mod parallel;
pub mod profile;
pub mod signal;
pub mod sim;
pub mod ui;
