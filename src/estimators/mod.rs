//! The paper's estimators and the analyses built on them.
//!
//! - [`models`]: fitted models as stored in the machine profile, and their fast evaluation.
//! - [`streaming`]: one streaming estimator per estimate (Eqs. 7–15).
//! - [`pipeline`]: every estimator of a machine, bound to a frame layout.
//! - [`calibration`]: fits the models from a simulation database and a few experiments.
//! - [`abnormality`]: the motor abnormality score (ideal versus measured torque).
//! - [`backlash`]: backlash from a reciprocating test (Sect. 3.3) and its NC program.
//! - [`fingerprint`]: friction fingerprint, its trend, and the preload diagnosis.
//! - [`depth_of_cut`]: the maximum rough-cut depth and the component that limits it.
//! - [`accuracy`]: runs the pipeline over a recording and scores it against reference columns.
//! - [`state`]: the estimators' state saved by one HMI session and taken up by the next.

pub mod abnormality;
pub mod accuracy;
pub mod backlash;
pub mod calibration;
pub mod depth_of_cut;
pub mod fingerprint;
pub mod models;
pub mod pipeline;
pub mod state;
pub mod streaming;

pub use pipeline::{EstimatorPipeline, PipelineError};
