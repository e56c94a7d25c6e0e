//! The one integration-test binary (egui and friends are linked once, see DESIGN.md).

mod cli_misuse;
mod common;
mod discrepancy;
mod discrepancy_other_machine;
mod discrepancy_spindle;
mod estimator_state;
mod estimators_cli;
mod fit;
mod link_replay;
mod modbus_peer;
mod recording_format;
mod sensor_zero;
mod simulate_cli;
mod ui_hmi;
mod ui_view_models;
