//! Helpers shared by the integration tests.

use std::path::Path;
use std::process::{Command, Output};

/// Runs the `servosight` binary with `args` and returns its output.
pub fn servosight(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_servosight"))
        .args(args)
        .output()
        .expect("the servosight binary runs")
}

/// Standard error as text.
pub fn stderr(output: &Output) -> String {
    String::from_utf8_lossy(&output.stderr).into_owned()
}

/// Standard output as text.
pub fn stdout(output: &Output) -> String {
    String::from_utf8_lossy(&output.stdout).into_owned()
}

/// A path inside a temporary directory, as a string argument.
pub fn arg(path: &Path) -> &str {
    path.to_str().expect("temporary paths are UTF-8")
}
