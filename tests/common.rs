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

/// Every test of the one integration binary shares its process. A test that judges the
/// process's memory (the Modbus soak reads its own RSS) holds this for its whole run, and a
/// test that allocates tens of megabytes holds it too, so neither counts the other's memory.
pub static PROCESS_MEMORY: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// Takes [`PROCESS_MEMORY`] (a test that panicked while holding it leaves it usable).
pub fn hold_process_memory() -> std::sync::MutexGuard<'static, ()> {
    PROCESS_MEMORY
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
}
