//! `servosight simulate` and `servosight inspect`, driven as a user would.

use servosight::signal::channel::{AMBIENT, COOLANT, CUT_DEPTH, TIME};
use servosight::signal::{AxisId, Quantity, axis_column, read_recording, reference_column};

use crate::common::{arg, servosight, stderr, stdout};

#[test]
fn a_two_hour_production_run_writes_every_standard_column() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("p.csv");
    let run = servosight(&[
        "simulate",
        "--scenario",
        "production",
        "--hours",
        "2",
        "--seed",
        "3",
        "-o",
        arg(&out),
    ]);
    assert!(run.status.success(), "{}", stderr(&run));
    let rec = read_recording(&out).unwrap();
    assert_eq!(rec.len(), 7201);
    let mut expected = vec![
        TIME.to_string(),
        AMBIENT.into(),
        COOLANT.into(),
        CUT_DEPTH.into(),
    ];
    for axis in [AxisId::S, AxisId::X] {
        for q in [
            Quantity::Speed,
            Quantity::Torque,
            Quantity::Current,
            Quantity::Load,
            Quantity::StatorTemp,
            Quantity::Position,
        ] {
            expected.push(axis_column(axis, q));
        }
    }
    expected.push(axis_column(AxisId::X, Quantity::Command));
    expected.push(reference_column(AxisId::S, "elongation_um", None));
    for q in [
        "motor_flange_temp_C",
        "front_bearing_temp_C",
        "back_bearing_temp_C",
        "nut_temp_C",
        "backlash_um",
    ] {
        expected.push(reference_column(AxisId::X, q, None));
    }
    for k in 1..=5 {
        expected.push(reference_column(AxisId::X, "straightness_h_um", Some(k)));
        expected.push(reference_column(AxisId::X, "straightness_v_um", Some(k)));
    }
    for name in &expected {
        assert!(rec.try_column(name).is_some(), "missing column {name}");
    }
    assert_eq!(rec.metadata_value("scenario"), Some("production"));
    assert_eq!(rec.metadata_value("seed"), Some("3"));

    let inspect = servosight(&["inspect", arg(&out)]);
    assert!(inspect.status.success(), "{}", stderr(&inspect));
    let text = stdout(&inspect);
    assert!(
        text.contains("7201 rows") && text.contains("sample rate 1.0000 Hz"),
        "{text}"
    );
}

#[test]
fn the_same_seed_writes_the_same_file_and_without_changes_the_physics() {
    let dir = tempfile::tempdir().unwrap();
    let paths: Vec<_> = ["a.csv", "b.csv", "c.csv"]
        .iter()
        .map(|n| dir.path().join(n))
        .collect();
    for (path, extra) in paths
        .iter()
        .zip([&[][..], &[][..], &["--without", "copper_loss"][..]])
    {
        let mut args = vec![
            "simulate",
            "--scenario",
            "warmup",
            "--hours",
            "0.5",
            "--seed",
            "11",
            "-o",
            arg(path),
        ];
        args.extend_from_slice(extra);
        let run = servosight(&args);
        assert!(run.status.success(), "{}", stderr(&run));
    }
    let read = |p: &std::path::Path| std::fs::read(p).unwrap();
    assert_eq!(read(&paths[0]), read(&paths[1]));
    let with = read_recording(&paths[0]).unwrap();
    let without = read_recording(&paths[2]).unwrap();
    let last =
        |r: &servosight::signal::Recording| *r.column("S.stator_temp_C").unwrap().last().unwrap();
    assert!(
        last(&with) > last(&without) + 1.0,
        "copper loss heats the stator"
    );
    assert_eq!(without.metadata_value("effects_off"), Some("copper_loss"));
}

#[test]
fn inspect_names_the_line_of_a_non_numeric_cell() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.csv");
    std::fs::write(
        &path,
        "# machine: test\ntime_s,X.speed_rpm\n0,1\n1,2\n2,fast\n3,4\n",
    )
    .unwrap();
    let run = servosight(&["inspect", arg(&path)]);
    assert!(!run.status.success());
    let err = stderr(&run);
    assert!(
        err.contains("line 5")
            && err.contains("`fast` is not a number")
            && err.contains("X.speed_rpm"),
        "{err}"
    );
    assert_eq!(err.lines().count(), 1, "one clear line: {err}");
}

#[test]
fn inspect_rejects_time_going_backwards_naming_the_line() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("back.csv");
    std::fs::write(&path, "time_s,ambient_C\n0,20\n1,20\n0.5,20\n").unwrap();
    let run = servosight(&["inspect", arg(&path)]);
    assert!(!run.status.success());
    let err = stderr(&run);
    assert!(
        err.contains("line 4") && err.contains("time goes backwards"),
        "{err}"
    );
}

#[test]
fn inspect_reports_missing_files_and_gaps() {
    let run = servosight(&["inspect", "/nonexistent/day.csv"]);
    assert!(!run.status.success());
    assert!(stderr(&run).contains("/nonexistent/day.csv"));

    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("gap.csv");
    std::fs::write(&path, "time_s,a\n0,1\n1,1\n2,1\n12,1\n13,1\n").unwrap();
    let run = servosight(&["inspect", arg(&path), "--json", "-"]);
    assert!(run.status.success(), "{}", stderr(&run));
    let report: serde_json::Value = serde_json::from_str(&stdout(&run)).unwrap();
    assert_eq!(report["gaps"][0]["after_s"], 2.0);
    assert_eq!(report["gaps"][0]["length_s"], 10.0);
}

#[test]
fn simulate_refuses_unknown_effects_and_parameters_with_one_clear_line() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x.csv");
    let run = servosight(&[
        "simulate",
        "--scenario",
        "doe",
        "--without",
        "gravity",
        "-o",
        arg(&out),
    ]);
    assert!(!run.status.success());
    assert!(
        stderr(&run).contains("unknown effect `gravity`"),
        "{}",
        stderr(&run)
    );
    let run = servosight(&[
        "simulate",
        "--scenario",
        "doe",
        "--set",
        "x_axis.lash=3",
        "-o",
        arg(&out),
    ]);
    assert!(!run.status.success());
    assert!(
        stderr(&run).contains("no such parameter"),
        "{}",
        stderr(&run)
    );
    assert!(!out.exists(), "nothing written on bad input");
}

#[test]
fn every_subcommand_has_useful_help() {
    for sub in ["simulate", "inspect"] {
        let run = servosight(&[sub, "--help"]);
        assert!(run.status.success());
        assert!(stdout(&run).len() > 200, "{sub} --help is too thin");
    }
}

#[test]
fn inspect_into_a_closed_pipe_ends_quietly() {
    use std::io::Read;
    use std::process::{Command, Stdio};
    // Without the SIGPIPE fix in main.rs this test sees `println!` panic (checked by hand).
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("p.csv");
    let run = servosight(&[
        "simulate",
        "--scenario",
        "warmup",
        "--hours",
        "0.2",
        "-o",
        arg(&out),
    ]);
    assert!(run.status.success(), "{}", stderr(&run));
    let mut child = Command::new(env!("CARGO_BIN_EXE_servosight"))
        .args(["inspect", arg(&out)])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Close the reading end before the report is written, as `… | head -c0` would.
    drop(child.stdout.take());
    let mut err = String::new();
    child
        .stderr
        .take()
        .unwrap()
        .read_to_string(&mut err)
        .unwrap();
    child.wait().unwrap();
    assert!(!err.contains("panicked"), "{err}");
}

/// A recorder that lost power leaves a last line cut short: inspect still reads the rest and
/// says what it left out. A complete last line without a line end is simply read.
#[test]
fn inspect_reads_a_file_whose_last_line_was_cut_short() {
    let dir = tempfile::tempdir().unwrap();
    let cut = dir.path().join("cut.csv");
    // Cut inside the last row: its second field is missing.
    std::fs::write(&cut, "time_s,X.speed_rpm\n0,1\n1,2\n2,3.5\n3").unwrap();
    let run = servosight(&["inspect", arg(&cut), "--json", "-"]);
    assert!(run.status.success(), "{}", stderr(&run));
    assert!(stderr(&run).contains("cut short"), "{}", stderr(&run));
    let report: serde_json::Value = serde_json::from_str(&stdout(&run)).unwrap();
    assert_eq!(report["rows"], 3);
    assert_eq!(report["last_line_cut_short"], true);

    let complete = dir.path().join("complete.csv");
    std::fs::write(&complete, "time_s,X.speed_rpm\n0,1\n1,2").unwrap();
    let run = servosight(&["inspect", arg(&complete), "--json", "-"]);
    assert!(run.status.success(), "{}", stderr(&run));
    assert!(stderr(&run).is_empty(), "{}", stderr(&run));
    let report: serde_json::Value = serde_json::from_str(&stdout(&run)).unwrap();
    assert_eq!(report["rows"], 2);

    // A bad row before the last line is still an error.
    let bad = dir.path().join("bad.csv");
    std::fs::write(&bad, "time_s,X.speed_rpm\n0,x\n1,2\n2").unwrap();
    let run = servosight(&["inspect", arg(&bad)]);
    assert!(!run.status.success());
    assert!(stderr(&run).contains("line 2"), "{}", stderr(&run));
}

/// The pieces of a recording are summarised as one: the rows and the duration of all of them,
/// a piece missing between two others shown as a gap, a last line cut short in the last piece
/// still forgiven (and only there), and pieces out of order refused with the file named.
#[test]
fn inspect_summarises_the_pieces_of_a_recording_as_one() {
    let dir = tempfile::tempdir().unwrap();
    let first = dir.path().join("shift.csv");
    let piece = |k: u32, from: u32, to: u32, tail: &str| {
        let path = servosight::signal::piece_path(&first, k);
        let mut text = format!("# part: {k}\ntime_s,X.speed_rpm\n");
        for t in from..to {
            text.push_str(&format!("{t},{}\n", t % 7));
        }
        text.push_str(tail);
        std::fs::write(&path, text).unwrap();
        path
    };
    let pieces = [
        piece(0, 0, 100, ""),
        piece(1, 100, 200, ""),
        piece(2, 300, 400, "400,"),
    ];
    let summary = |paths: &[&std::path::Path]| {
        let mut args = vec!["inspect"];
        args.extend(paths.iter().map(|p| arg(p)));
        args.extend(["--json", "-"]);
        servosight(&args)
    };
    let run = summary(&[&pieces[0], &pieces[1], &pieces[2]]);
    assert!(run.status.success(), "{}", stderr(&run));
    assert!(stderr(&run).contains("cut short"), "{}", stderr(&run));
    let report: serde_json::Value = serde_json::from_str(&stdout(&run)).unwrap();
    assert_eq!(report["rows"], 300);
    assert_eq!(report["duration_s"], 399.0);
    assert_eq!(report["last_line_cut_short"], true);
    assert_eq!(report["gaps"][0]["after_s"], 199.0);
    assert_eq!(report["gaps"][0]["length_s"], 101.0);
    assert_eq!(report["metadata"][0][1], "0", "the first piece's metadata");
    assert_eq!(
        report["file"],
        format!(
            "{}, {}, {}",
            pieces[0].display(),
            pieces[1].display(),
            pieces[2].display()
        )
    );

    // A cut line is forgiven only at the end of the last piece.
    let run = summary(&[&pieces[2], &pieces[0]]);
    assert!(!run.status.success());
    assert!(
        stderr(&run).contains(&pieces[2].display().to_string()),
        "{}",
        stderr(&run)
    );
    // Out of order, the piece is named.
    let run = summary(&[&pieces[1], &pieces[0]]);
    assert!(!run.status.success());
    let said = stderr(&run);
    assert!(
        said.contains(&pieces[0].display().to_string())
            && said.contains("give the pieces in the order they were recorded"),
        "{said}"
    );
    // Out of order into a cut last piece, too.
    let run = summary(&[&pieces[1], &pieces[0], &pieces[2]]);
    assert!(!run.status.success());
    assert!(
        stderr(&run).contains("give the pieces in the order they were recorded"),
        "{}",
        stderr(&run)
    );
}
