//! The one integration-test binary (egui and friends are linked once, see DESIGN.md).

mod common;
mod fit;
mod recording_format;
mod simulate_cli;
