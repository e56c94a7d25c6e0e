//! The `servosight` binary: the HMI and every headless analysis behind one CLI.

fn main() -> std::process::ExitCode {
    restore_default_sigpipe();
    servosight_cli::run()
}

/// Rust ignores SIGPIPE, so `println!` panics when the reader of a pipe goes away
/// (`servosight inspect day.csv | head`). A command-line filter should end quietly instead,
/// like every other Unix tool.
fn restore_default_sigpipe() {
    #[cfg(unix)]
    // SAFETY: called first thing in `main`, before any other thread exists; it only resets the
    // disposition of one signal to the system default.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}

#[path = "cli/mod.rs"]
mod servosight_cli;
