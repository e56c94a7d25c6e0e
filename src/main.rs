//! The `servosight` binary: the HMI and every headless analysis behind one CLI.

fn main() -> std::process::ExitCode {
    servosight_cli::run()
}

#[path = "cli/mod.rs"]
mod servosight_cli;
