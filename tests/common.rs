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

/// Runs the `servosight` binary with `args` and the environment variables `env` set.
pub fn servosight_with_env(args: &[&str], env: &[(&str, &str)]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_servosight"))
        .args(args)
        .envs(env.iter().copied())
        .output()
        .expect("the servosight binary runs")
}

/// Standard error as text.
pub fn stderr(output: &Output) -> String {
    String::from_utf8_lossy(&output.stderr).into_owned()
}

/// The one line a command that must fail wrote on stderr (asserting it failed and wrote one).
pub fn one_line_failure(output: &Output) -> String {
    assert!(!output.status.success(), "the command succeeded");
    let err = stderr(output);
    assert_eq!(err.lines().count(), 1, "{err}");
    err
}

/// Standard output as text.
pub fn stdout(output: &Output) -> String {
    String::from_utf8_lossy(&output.stdout).into_owned()
}

/// A path inside a temporary directory, as a string argument.
pub fn arg(path: &Path) -> &str {
    path.to_str().expect("temporary paths are UTF-8")
}

/// How many pixels of `image` are within 12 of `colour` in each of red, green and blue (a
/// drawn line's anti-aliased core).
pub fn pixels_near(image: &image::RgbaImage, colour: [u8; 3]) -> usize {
    image
        .pixels()
        .filter(|p| (0..3).all(|k| (i32::from(p[k]) - i32::from(colour[k])).abs() <= 12))
        .count()
}

/// How many pixels of `image` are light (every channel above 200): a light theme's page.
pub fn light_pixels(image: &image::RgbaImage) -> usize {
    image
        .pixels()
        .filter(|p| p[0] > 200 && p[1] > 200 && p[2] > 200)
        .count()
}

/// Set in a child process started by [`in_own_process`]: the test runs its body there.
const OWN_PROCESS_VARIABLE: &str = "SERVOSIGHT_TEST_IN_OWN_PROCESS";

/// Runs the test `test_path` (e.g. `modbus_peer::soak_short_no_sample_lost_memory_flat`) alone
/// in a fresh process of this test binary, for a test that judges the process's own memory:
/// every other test of the one integration binary shares the process and would be counted.
///
/// Returns `true` in that child, where the caller runs its body; in the parent it waits for the
/// child, fails the test with the child's output if the child failed, and returns `false`.
pub fn in_own_process(test_path: &str) -> bool {
    if std::env::var_os(OWN_PROCESS_VARIABLE).is_some() {
        return true;
    }
    let output = Command::new(std::env::current_exe().expect("the test binary knows its path"))
        .args([
            test_path,
            "--exact",
            "--include-ignored",
            "--nocapture",
            "--test-threads=1",
        ])
        .env(OWN_PROCESS_VARIABLE, "1")
        .output()
        .expect("the test binary runs again");
    let out = stdout(&output);
    let err = stderr(&output);
    eprintln!("{err}");
    println!("{out}");
    assert!(
        output.status.success(),
        "{test_path} failed in its own process"
    );
    assert!(
        out.contains("1 passed"),
        "{test_path} did not run in its own process: {out}"
    );
    false
}

/// The rows of the recording at `path` from `from_s` up to `until_s` (its metadata and header
/// kept), written to `out`: a recording that starts mid-shift, or a piece of one.
pub fn rows_between(path: &std::path::Path, out: &std::path::Path, from_s: f64, until_s: f64) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut past_header = false;
    let kept: String = text
        .lines()
        .filter(|line| {
            let keep = line.starts_with('#')
                || !past_header
                || line
                    .split(',')
                    .next()
                    .map(|t| t.parse::<f64>().unwrap())
                    .is_some_and(|t| t >= from_s && t < until_s);
            past_header |= line.starts_with("time_s");
            keep
        })
        .map(|line| format!("{line}\n"))
        .collect();
    std::fs::write(out, kept).unwrap();
}
