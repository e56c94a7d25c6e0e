//! The physics twin: a lumped-parameter thermal and friction model of a lathe's spindle and a
//! ball-screw feed axis. It plays the role of the paper's FEA database (milliseconds per simulated
//! hour instead of hours per case) and of the "real machine" in sim-vs-real tests, since every
//! effect can be switched off by name ([`Effect`]).
//!
//! - [`machine`]: every parameter, its unit and its source; `--set` overrides.
//! - [`physics`]: Palmgren bearing torque, ball-screw preload drag, viscosity, motor losses.
//! - [`thermal`]: lumped networks, backward Euler.
//! - [`spindle`], [`feed_axis`]: the two axes.
//! - [`scenario`]: warm-up, production day, backlash test, design of experiments.
//! - [`measurement`]: noise, delay, drift.
//! - [`twin`]: ties them together and produces recording rows.
#![allow(non_snake_case)] // unit suffixes (`_C`, `_N`, `_W_per_K`) are part of the names

pub mod effects;
pub mod feed_axis;
pub mod machine;
pub mod measurement;
pub mod physics;
pub mod scenario;
pub mod spindle;
pub mod thermal;
pub mod twin;

pub use effects::{Effect, EffectSet};
pub use machine::MachineParams;
pub use scenario::{BacklashTestPlan, ScenarioKind};
pub use twin::{Twin, TwinConfig};

/// Why a twin could not run.
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    /// A machine parameter is out of its meaningful range.
    #[error("invalid machine: {0}")]
    InvalidMachine(String),
    /// The sample rate is not a positive number up to 20 kHz.
    #[error("invalid sample rate {0} Hz (must be above 0 and at most 20000)")]
    InvalidRate(f64),
    /// The duration is not positive.
    #[error("invalid duration {0} h (must be above 0)")]
    InvalidHours(f64),
    /// A whole recording of an endless program was asked for.
    #[error("the {0} scenario runs forever: give a duration in hours")]
    Endless(ScenarioKind),
    /// A produced row was rejected by the recording (a bug or an extreme parameter choice).
    #[error("twin output rejected: {0}")]
    Output(crate::signal::RecordingError),
}

/// Runs a twin to the end of its program and returns the recording.
pub fn simulate(config: TwinConfig) -> Result<crate::signal::Recording, SimError> {
    Twin::new(config)?.run_to_recording()
}
