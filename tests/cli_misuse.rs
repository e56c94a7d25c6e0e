//! A user who mistypes a path or an option loses nothing and reads one clear line: an output
//! that would overwrite an input is refused before anything is written, standard output that
//! cannot be written is an error and not a panic, JSON sent to standard output is JSON alone,
//! and option values nobody can mean are refused instead of producing a result.

use std::path::{Path, PathBuf};

use crate::common::{arg, one_line_failure, servosight, stderr, stdout};

/// A short twin recording written by the CLI, as a user makes one (seed 3).
fn simulate(dir: &Path, name: &str, scenario: &str, hours: &str) -> PathBuf {
    simulate_with(
        dir,
        name,
        &["--scenario", scenario, "--hours", hours, "--seed", "3"],
    )
}

/// A twin recording written by `servosight simulate` with `options`.
fn simulate_with(dir: &Path, name: &str, options: &[&str]) -> PathBuf {
    let path = dir.join(name);
    let mut args = vec!["simulate"];
    args.extend_from_slice(options);
    args.extend(["-o", arg(&path)]);
    let run = servosight(&args);
    assert!(run.status.success(), "{}", stderr(&run));
    path
}

/// Runs `args`, which must fail with one line on stderr that contains `expected`.
fn assert_refused(args: &[&str], expected: &str) {
    let run = servosight(args);
    let error = one_line_failure(&run);
    assert!(error.contains(expected), "{args:?}: {error}");
}

fn twin_profile() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/it25-twin.toml")
}

#[test]
fn an_output_that_is_one_of_the_inputs_is_refused_and_the_input_kept() {
    let dir = tempfile::tempdir().unwrap();
    let day = simulate(dir.path(), "day.csv", "production", "0.1");
    let warmup = simulate(dir.path(), "warmup.csv", "warmup", "0.2");
    let before = std::fs::read(&day).unwrap();
    let warmup_before = std::fs::read(&warmup).unwrap();
    let profile = twin_profile();
    // The same file under another name (`./x/../day.csv`) is the same file.
    let aliased = dir.path().join("x").join("..").join("day.csv");
    std::fs::create_dir(dir.path().join("x")).unwrap();
    let attempts: Vec<Vec<&str>> = vec![
        vec![
            "estimate",
            "--profile",
            arg(&profile),
            "--recording",
            arg(&day),
            "-o",
            arg(&day),
        ],
        vec![
            "estimate",
            "--profile",
            arg(&profile),
            "--recording",
            arg(&day),
            "--json",
            arg(&aliased),
        ],
        vec!["inspect", arg(&day), "--json", arg(&day)],
        vec![
            "fit",
            "--data",
            arg(&day),
            "--target",
            "X.stator_temp_C",
            "--terms",
            "X.torque_Nm",
            "--json",
            arg(&day),
        ],
        vec![
            "discrepancy",
            "--sim",
            arg(&day),
            "--real",
            arg(&day),
            "--target",
            "X.stator_temp_C",
            "--plot-data",
            arg(&day),
        ],
        vec![
            "fingerprint",
            "--recording",
            arg(&warmup),
            "--axis",
            "X",
            "--save-baseline",
            arg(&warmup),
        ],
        vec!["calibrate", "--database", arg(&day), "-o", arg(&day)],
        vec![
            "compensate",
            "propose",
            "--set",
            "backlash.X=12",
            "--why",
            "measured",
            "--evidence",
            arg(&day),
            "-o",
            arg(&day),
        ],
    ];
    for attempt in &attempts {
        let run = servosight(attempt);
        let error = one_line_failure(&run);
        assert!(
            error.contains("both an input and an output"),
            "{attempt:?}: {error}"
        );
        assert_eq!(std::fs::read(&day).unwrap(), before, "{attempt:?}");
        assert_eq!(
            std::fs::read(&warmup).unwrap(),
            warmup_before,
            "{attempt:?}"
        );
    }
}

/// Before, `println!` panicked (exit 101, a backtrace hint) when standard output was a full
/// disk or a closed file.
#[cfg(target_os = "linux")]
#[test]
fn standard_output_that_cannot_be_written_is_one_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let day = simulate(dir.path(), "day.csv", "production", "0.05");
    let full = std::fs::File::options()
        .write(true)
        .open("/dev/full")
        .unwrap();
    let run = std::process::Command::new(env!("CARGO_BIN_EXE_servosight"))
        .args(["inspect", arg(&day)])
        .stdout(full)
        .output()
        .unwrap();
    assert_eq!(run.status.code(), Some(2), "{}", stderr(&run));
    let error = one_line_failure(&run);
    assert!(
        error.contains("cannot write to standard output") && !error.contains("panicked"),
        "{error}"
    );
}

#[test]
fn json_sent_to_standard_output_is_the_json_alone() {
    let dir = tempfile::tempdir().unwrap();
    let day = simulate(dir.path(), "day.csv", "production", "0.1");
    let warmup = simulate(dir.path(), "warmup.csv", "warmup", "0.2");
    let profile = twin_profile();
    let runs = [
        servosight(&[
            "estimate",
            "--profile",
            arg(&profile),
            "--recording",
            arg(&day),
            "--json",
            "-",
        ]),
        servosight(&[
            "fingerprint",
            "--recording",
            arg(&warmup),
            "--axis",
            "X",
            "--json",
            "-",
        ]),
    ];
    for run in &runs {
        assert!(run.status.success(), "{}", stderr(run));
        let text = stdout(run);
        serde_json::from_str::<serde_json::Value>(&text)
            .unwrap_or_else(|e| panic!("stdout is not JSON alone ({e}): {text}"));
    }
}

#[test]
fn option_values_nobody_can_mean_are_refused_and_nothing_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let day = simulate(dir.path(), "day.csv", "production", "0.1");
    let program = dir.path().join("test.nc");
    let cases: Vec<(Vec<&str>, &str)> = vec![
        // The spindle's S word is its speed: an "S199.5" move would set the spindle speed.
        (
            vec!["backlash-program", "--axis", "S", "-o", arg(&program)],
            "linear feed axis",
        ),
        (
            vec!["backlash-program", "--axis", "X", "--feeds", "inf"],
            "feeds must be positive",
        ),
        (
            vec!["backlash-program", "--axis", "X", "--centre-mm", "1e20"],
            "--centre-mm",
        ),
        // Too long a test is refused before the program is written.
        (
            vec![
                "backlash-program",
                "--axis",
                "X",
                "--max-amplitude-um",
                "5000",
                "-o",
                arg(&program),
            ],
            "would take",
        ),
        // With 19 surrogates the smallest p-value is 0.05: nothing could pass alpha = 0.01.
        (
            vec![
                "discrepancy",
                "--sim",
                arg(&day),
                "--real",
                arg(&day),
                "--target",
                "X.stator_temp_C",
                "--surrogates",
                "19",
            ],
            "surrogates",
        ),
        (
            vec!["inspect", arg(&day), "--gap-factor=-1"],
            "--gap-factor",
        ),
        (
            vec![
                "simulate",
                "--scenario",
                "warmup",
                "--noise=-1",
                "-o",
                arg(&program),
            ],
            "noise_scale",
        ),
        (
            vec![
                "calibrate",
                "--database",
                arg(&day),
                "--experiments",
                arg(&day),
                "-o",
                arg(&program),
            ],
            "given twice",
        ),
        (
            vec![
                "compensate",
                "propose",
                "--set",
                "backlash.X=12",
                "--set",
                "backlash.X=15",
                "--why",
                "measured",
                "--evidence",
                "test",
                "-o",
                arg(&program),
            ],
            "set twice",
        ),
        (
            vec![
                "compensate",
                "propose",
                "--set",
                "backlash.X=12",
                "--why",
                " ",
                "--evidence",
                "test",
                "-o",
                arg(&program),
            ],
            "does not say why",
        ),
    ];
    for (args, expected) in &cases {
        assert_refused(args, expected);
        assert!(!program.exists(), "{args:?} wrote {}", program.display());
    }
}

#[test]
fn recordings_that_cannot_be_analysed_are_refused_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let day = simulate(dir.path(), "day.csv", "production", "0.1");
    let text = std::fs::read_to_string(&day).unwrap();
    // The header alone, and every row at one instant.
    let header_only = dir.path().join("header_only.csv");
    let header_end = text.lines().position(|l| l.starts_with("time_s")).unwrap();
    let kept: Vec<&str> = text.lines().take(header_end + 1).collect();
    std::fs::write(&header_only, kept.join("\n") + "\n").unwrap();
    let frozen = dir.path().join("frozen.csv");
    let frozen_text: Vec<String> = text
        .lines()
        .enumerate()
        .map(|(i, l)| match l.split_once(',') {
            Some((_, rest)) if i > header_end => format!("5,{rest}"),
            _ => l.to_string(),
        })
        .collect();
    std::fs::write(&frozen, frozen_text.join("\n") + "\n").unwrap();
    // A database without reference instruments has nothing to calibrate the estimators to.
    let no_references = dir.path().join("no_ref.csv");
    let header = kept[header_end];
    let keep: Vec<usize> = header
        .split(',')
        .enumerate()
        .filter(|(_, name)| !name.starts_with("ref."))
        .map(|(i, _)| i)
        .collect();
    let stripped: Vec<String> = text
        .lines()
        .enumerate()
        .map(|(i, l)| {
            if i < header_end {
                l.to_string()
            } else {
                let cells: Vec<&str> = l.split(',').collect();
                keep.iter().map(|&k| cells[k]).collect::<Vec<_>>().join(",")
            }
        })
        .collect();
    std::fs::write(&no_references, stripped.join("\n") + "\n").unwrap();
    let profile = twin_profile();
    let out = dir.path().join("out.toml");
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (vec!["inspect", arg(&header_only)], "no data rows"),
        (
            vec![
                "estimate",
                "--profile",
                arg(&profile),
                "--recording",
                arg(&header_only),
            ],
            "no data rows",
        ),
        (
            vec![
                "discrepancy",
                "--sim",
                arg(&day),
                "--real",
                arg(&frozen),
                "--target",
                "X.stator_temp_C",
            ],
            "does not advance in time",
        ),
        (
            vec![
                "calibrate",
                "--database",
                arg(&no_references),
                "-o",
                arg(&out),
            ],
            "has no reference columns",
        ),
    ];
    for (args, expected) in &cases {
        assert_refused(args, expected);
    }
    assert!(!out.exists());
}

/// The backlash test at 200 Hz: the fastest feed's moves show no rise of the current (the
/// current fell where the table should be driven). Before, its split was reported as a
/// 383 µm backlash, more than the test's largest move.
#[test]
fn a_feed_whose_current_never_rises_reports_no_backlash() {
    let dir = tempfile::tempdir().unwrap();
    let test = simulate_with(
        dir.path(),
        "lash.csv",
        &[
            "--scenario",
            "backlash-test",
            "--seed",
            "1",
            "--rate",
            "200",
        ],
    );
    let run = servosight(&[
        "backlash",
        "--recording",
        arg(&test),
        "--axis",
        "X",
        "--json",
        "-",
    ]);
    assert!(run.status.success(), "{}", stderr(&run));
    let report: serde_json::Value = serde_json::from_str(&stdout(&run)).unwrap();
    let rows = report["by_speed"].as_array().unwrap();
    assert!(!rows.is_empty());
    for row in rows {
        assert!(row["current_rise_A"].as_f64().unwrap() > 0.0, "{row}");
        assert!(row["backlash_um"].as_f64().unwrap() < 100.0, "{row}");
    }
    let without = report["feeds_without_a_rise"].as_array().unwrap();
    assert_eq!(without.len(), 1, "{report}");
    assert!(
        (without[0].as_f64().unwrap() - 200.0).abs() < 1.0,
        "{report}"
    );
    // A feed that found nothing still counts against the confidence.
    assert!(report["confidence"].as_f64().unwrap() < 0.8, "{report}");
}

/// Half an hour of DOE cannot pin down the room's 4.5 h lag: the profile is written (it is the
/// best those data allow) and stderr says why its estimates may extrapolate.
#[test]
fn a_database_shorter_than_the_lags_its_models_read_is_warned_of() {
    let dir = tempfile::tempdir().unwrap();
    let database = simulate_with(
        dir.path(),
        "db.csv",
        &["--scenario", "doe", "--hours", "0.5", "--seed", "1"],
    );
    let profile = dir.path().join("profile.toml");
    let run = servosight(&[
        "calibrate",
        "--database",
        arg(&database),
        "-o",
        arg(&profile),
    ]);
    assert!(run.status.success(), "{}", stderr(&run));
    assert!(profile.exists());
    let warning = stderr(&run);
    assert!(
        warning.contains("warning: the database spans 0.5 h, less than the slowest lag"),
        "{warning}"
    );
}

#[test]
fn proposals_and_baselines_that_cannot_be_meant_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let proposal = dir.path().join("p.json");
    // A negative backlash compensation would overshoot at every reversal: refused when the
    // proposal is written, not only when it is pushed.
    let run = servosight(&[
        "compensate",
        "propose",
        "--set",
        "backlash.X=-5",
        "--why",
        "measured",
        "--evidence",
        "test",
        "-o",
        arg(&proposal),
    ]);
    let error = one_line_failure(&run);
    assert!(error.contains("never negative"), "{error}");
    assert!(!proposal.exists());

    // A stored baseline with a negative friction is not a baseline to trend against.
    let warmup = simulate(dir.path(), "warmup.csv", "warmup", "0.2");
    let baseline = dir.path().join("baseline.json");
    let run = servosight(&[
        "fingerprint",
        "--recording",
        arg(&warmup),
        "--axis",
        "X",
        "--save-baseline",
        arg(&baseline),
    ]);
    assert!(run.status.success(), "{}", stderr(&run));
    let mut stored: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&baseline).unwrap()).unwrap();
    stored["coulomb_Nm"] = serde_json::json!(-0.2);
    std::fs::write(&baseline, stored.to_string()).unwrap();
    let run = servosight(&[
        "fingerprint",
        "--recording",
        arg(&warmup),
        "--axis",
        "X",
        "--baseline",
        arg(&baseline),
    ]);
    let error = one_line_failure(&run);
    assert!(
        error.contains("coulomb_Nm") && error.contains("never negative"),
        "{error}"
    );
}

#[test]
fn two_outputs_naming_one_file_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let day = simulate(dir.path(), "day.csv", "production", "0.05");
    let out = dir.path().join("out.json");
    let profile = twin_profile();
    let run = servosight(&[
        "estimate",
        "--profile",
        arg(&profile),
        "--recording",
        arg(&day),
        "-o",
        arg(&out),
        "--json",
        arg(&out),
    ]);
    let error = one_line_failure(&run);
    assert!(error.contains("two outputs"), "{error}");
    assert!(!out.exists());
    let run = servosight(&[
        "discrepancy",
        "--sim",
        arg(&day),
        "--real",
        arg(&day),
        "--target",
        "X.stator_temp_C",
        "--json",
        "-",
        "--plot-data",
        "-",
    ]);
    let error = one_line_failure(&run);
    assert!(error.contains("only one output"), "{error}");
}
