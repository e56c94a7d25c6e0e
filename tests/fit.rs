//! The regression engine against statsmodels, and `servosight fit` driven like a user drives it.
//!
//! Fixtures live in `tests/fixtures/fit/`; `make_fixtures.py` there regenerated them with
//! statsmodels (it is not run here). Every figure must match within 1e-6 relative; p-values
//! within 1e-8 absolute + 1e-4 relative.

use std::path::{Path, PathBuf};
use std::process::Command;

use serde_json::Value;
use servosight::fit::{
    Design, FitError, FitReport, OlsOptions, ols, parse_terms, sensitivity, wls,
};
use servosight::signal::read_recording;

const RELATIVE: f64 = 1e-6;
const P_ABSOLUTE: f64 = 1e-8;
const P_RELATIVE: f64 = 1e-4;

fn fixture_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/fit")
}

fn expected(name: &str) -> Value {
    let path = fixture_dir().join(format!("{name}.expected.json"));
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// Compares every field of `expected` (recursively) with `actual`. Returns the worst relative
/// error over the non-p-value figures, or the path of the first mismatch.
fn compare(expected: &Value, actual: &Value, path: &str) -> Result<f64, String> {
    let mut worst: f64 = 0.0;
    match expected {
        Value::Object(fields) => {
            for (key, value) in fields {
                if matches!(key.as_str(), "fixture" | "terms") {
                    continue;
                }
                let found = actual
                    .get(key)
                    .ok_or_else(|| format!("{path}.{key} missing from the report"))?;
                worst = worst.max(compare(value, found, &format!("{path}.{key}"))?);
            }
        }
        Value::Array(items) => {
            let found = actual
                .as_array()
                .ok_or_else(|| format!("{path} is not an array"))?;
            if items.len() != found.len() {
                return Err(format!(
                    "{path}: {} items, expected {}",
                    found.len(),
                    items.len()
                ));
            }
            for (i, (e, a)) in items.iter().zip(found).enumerate() {
                worst = worst.max(compare(e, a, &format!("{path}[{i}]"))?);
            }
        }
        Value::Number(number) => {
            let e = number.as_f64().unwrap();
            let a = actual
                .as_f64()
                .ok_or_else(|| format!("{path}: expected {e}, found {actual}"))?;
            if path.ends_with("p_value") {
                if (a - e).abs() > P_ABSOLUTE + P_RELATIVE * e.abs() {
                    return Err(format!("{path}: {a} vs statsmodels {e}"));
                }
            } else {
                let error = if e == 0.0 {
                    a.abs()
                } else {
                    (a - e).abs() / e.abs()
                };
                if error > RELATIVE {
                    return Err(format!(
                        "{path}: {a} vs statsmodels {e} (relative {error:.2e})"
                    ));
                }
                worst = error;
            }
        }
        other if other == actual => {}
        other => return Err(format!("{path}: {actual} vs statsmodels {other}")),
    }
    Ok(worst)
}

fn report_for(name: &str) -> (Value, Value) {
    let expected = expected(name);
    let recording = read_recording(&fixture_dir().join(format!("{name}.csv"))).unwrap();
    let terms = parse_terms(expected["terms"].as_str().unwrap()).unwrap();
    let design =
        Design::from_recording(&recording, expected["target"].as_str().unwrap(), &terms).unwrap();
    let fit = ols(&design).unwrap();
    let report = FitReport::new(&fit, sensitivity(&fit, &design));
    (expected, serde_json::to_value(&report).unwrap())
}

fn check_parity(name: &str) {
    let (expected, actual) = report_for(name);
    let worst = compare(&expected, &actual, name).unwrap_or_else(|mismatch| panic!("{mismatch}"));
    // Shown with --nocapture; docs/performance.md and the issue report quote these.
    eprintln!("{name}: worst relative error against statsmodels {worst:.2e}");
}

#[test]
fn fit_parity_ill_conditioned_cubic_in_three_temperatures() {
    check_parity("cubic_straightness");
}

#[test]
fn fit_parity_large_linear_set() {
    check_parity("linear_large");
}

#[test]
fn fit_parity_tiny_set() {
    check_parity("tiny");
}

#[test]
fn fit_parity_dynamic_features_on_irregular_time_steps() {
    check_parity("dynamic_features");
}

/// The weighted fixture's design and its `weight` column.
fn weighted_fixture() -> (Value, Design, Vec<f64>) {
    let expected = expected("weighted");
    let recording = read_recording(&fixture_dir().join("weighted.csv")).unwrap();
    let terms = parse_terms(expected["terms"].as_str().unwrap()).unwrap();
    let design =
        Design::from_recording(&recording, expected["target"].as_str().unwrap(), &terms).unwrap();
    let weights = recording.column("weight").unwrap().to_vec();
    (expected, design, weights)
}

#[test]
fn fit_parity_weighted_least_squares_against_statsmodels_wls() {
    let (expected, design, weights) = weighted_fixture();
    let fit = wls(&design, &weights, &OlsOptions::default()).unwrap();
    let actual = serde_json::to_value(FitReport::new(&fit, Vec::new())).unwrap();
    let worst =
        compare(&expected, &actual, "weighted").unwrap_or_else(|mismatch| panic!("{mismatch}"));
    eprintln!("weighted: worst relative error against statsmodels WLS {worst:.2e}");
    // The weights matter here: the unweighted fit is measurably different.
    let unweighted = ols(&design).unwrap();
    let speed = |f: &servosight::fit::OlsFit| f.coefficient("S.speed_rpm").unwrap().estimate;
    assert!((speed(&fit) - speed(&unweighted)).abs() > 1e-4);
}

#[test]
fn weighted_fit_with_equal_weights_is_the_ordinary_fit() {
    let (_, design, weights) = weighted_fixture();
    let equal = vec![2.5; weights.len()];
    let weighted = wls(&design, &equal, &OlsOptions::default()).unwrap();
    let ordinary = ols(&design).unwrap();
    for (w, o) in weighted.coefficients.iter().zip(&ordinary.coefficients) {
        assert!((w.estimate - o.estimate).abs() <= 1e-10 * o.estimate.abs().max(1.0));
        assert!((w.std_error - o.std_error).abs() <= 1e-9 * o.std_error);
    }
    assert!((weighted.r2 - ordinary.r2).abs() < 1e-12);
}

#[test]
fn weighted_fit_refuses_a_bad_weight_and_names_it() {
    let (_, design, mut weights) = weighted_fixture();
    weights[7] = f64::NAN;
    let error = wls(&design, &weights, &OlsOptions::default()).unwrap_err();
    assert!(
        matches!(error, FitError::InvalidParameter { name: "weight", .. }),
        "{error}"
    );
    weights[7] = 0.0;
    assert!(wls(&design, &weights, &OlsOptions::default()).is_err());
    let error = wls(&design, &weights[..10], &OlsOptions::default()).unwrap_err();
    assert!(matches!(error, FitError::Dimension { .. }), "{error}");
}

#[test]
fn fit_parity_comparison_detects_a_wrong_figure() {
    // The comparison itself must be able to fail: nudge one estimate by 1e-5 relative.
    let (expected, mut actual) = report_for("tiny");
    let estimate = actual["coefficients"][2]["estimate"].as_f64().unwrap();
    actual["coefficients"][2]["estimate"] = Value::from(estimate * (1.0 + 1e-5));
    let mismatch = compare(&expected, &actual, "tiny").unwrap_err();
    assert!(
        mismatch.starts_with("tiny.coefficients[2].estimate"),
        "{mismatch}"
    );
    let pristine = report_for("tiny").1;
    assert!(compare(&expected, &pristine, "tiny").is_ok());
}

// ---- the binary -------------------------------------------------------------------------------

fn servosight(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_servosight"))
        .args(args)
        .output()
        .unwrap()
}

fn path_str(path: &Path) -> &str {
    path.to_str().unwrap()
}

#[test]
fn fit_cli_prints_a_summary_and_writes_the_json_contract() {
    let dir = tempfile::tempdir().unwrap();
    let json = dir.path().join("fit.json");
    let expected = expected("tiny");
    let data = fixture_dir().join("tiny.csv");
    let output = servosight(&[
        "fit",
        "--data",
        path_str(&data),
        "--target",
        expected["target"].as_str().unwrap(),
        "--terms",
        expected["terms"].as_str().unwrap(),
        "--json",
        path_str(&json),
    ]);
    let stdout = String::from_utf8(output.stdout).unwrap();
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    for needle in [
        "OLS Regression Results",
        "R-squared:",
        "F-statistic:",
        "P>|t|",
        "[0.025",
        "X.speed_rpm*X.torque_Nm",
        "partial R²",
    ] {
        assert!(stdout.contains(needle), "missing {needle}:\n{stdout}");
    }
    let written: Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    // The contract's fields, exactly named.
    for key in [
        "n",
        "df_model",
        "df_resid",
        "r2",
        "adj_r2",
        "rmse",
        "f_statistic",
        "f_p_value",
    ] {
        assert!(written[key].is_number(), "{key}");
    }
    for key in [
        "term",
        "estimate",
        "std_error",
        "t",
        "p_value",
        "ci_low",
        "ci_high",
    ] {
        assert!(written["coefficients"][0].get(key).is_some(), "{key}");
    }
    for key in ["term", "standardized", "partial_r2"] {
        assert!(written["sensitivity"][0].get(key).is_some(), "{key}");
    }
    assert_eq!(written["coefficients"][0]["term"], "const");
    compare(&expected, &written, "cli").unwrap_or_else(|mismatch| panic!("{mismatch}"));
}

#[test]
fn fit_cli_json_to_stdout_is_pure_json() {
    let data = fixture_dir().join("tiny.csv");
    let output = servosight(&[
        "fit",
        "--data",
        path_str(&data),
        "--target",
        "ref.X.motor_flange_temp_C",
        "--terms",
        "const, X.stator_temp_C",
        "--json",
        "-",
    ]);
    assert!(output.status.success());
    let report: Value = serde_json::from_slice(&output.stdout).unwrap();
    assert_eq!(report["df_model"], 1);
    assert_eq!(report["n"], 15);
}

/// Runs a command that must fail and returns its one stderr line.
fn fails_with_one_line(args: &[&str]) -> String {
    let output = servosight(args);
    assert!(!output.status.success(), "{args:?} succeeded");
    let stderr = String::from_utf8(output.stderr).unwrap();
    assert_eq!(stderr.trim_end().lines().count(), 1, "{args:?}: {stderr}");
    assert!(stderr.starts_with("error: "), "{stderr}");
    stderr.trim_end().to_string()
}

#[test]
fn fit_cli_bad_input_is_one_clear_line_and_a_failure() {
    let data = fixture_dir().join("tiny.csv");
    let data = path_str(&data);
    let target = "ref.X.motor_flange_temp_C";

    let line = fails_with_one_line(&[
        "fit",
        "--data",
        data,
        "--target",
        "ref.X.nope_C",
        "--terms",
        "X.speed_rpm",
    ]);
    assert!(
        line.contains("no column `ref.X.nope_C` (needed for the fit target)"),
        "{line}"
    );

    let line = fails_with_one_line(&[
        "fit",
        "--data",
        data,
        "--target",
        target,
        "--terms",
        "X.speed_rpm,lag(X.nope_rpm,3)",
    ]);
    assert!(
        line.contains("no column `X.nope_rpm` (needed for term `lag(X.nope_rpm,3)`)"),
        "{line}"
    );

    let line = fails_with_one_line(&[
        "fit",
        "--data",
        data,
        "--target",
        target,
        "--terms",
        "X.speed_rpm,lag(X.torque_Nm,)",
    ]);
    assert!(
        line.contains("malformed term `lag(X.torque_Nm,)` at position 29"),
        "{line}"
    );

    let line = fails_with_one_line(&[
        "fit",
        "--data",
        data,
        "--target",
        target,
        "--terms",
        "X.speed_rpm^2^3",
    ]);
    assert!(
        line.contains("malformed term `X.speed_rpm^2^3` at position 14"),
        "{line}"
    );

    let line = fails_with_one_line(&[
        "fit",
        "--data",
        data,
        "--target",
        target,
        "--terms",
        "X.speed_rpm,X.speed_rpm",
    ]);
    assert!(line.contains("listed twice"), "{line}");

    let line = fails_with_one_line(&[
        "fit",
        "--data",
        "/no/such/db.csv",
        "--target",
        target,
        "--terms",
        "a",
    ]);
    assert!(line.contains("/no/such/db.csv"), "{line}");

    // 15 rows, a lag of 13 minutes leaves 2: fewer rows than coefficients.
    let line = fails_with_one_line(&[
        "fit",
        "--data",
        data,
        "--target",
        target,
        "--terms",
        "X.speed_rpm,lag(X.torque_Nm,780)",
    ]);
    assert!(
        line.contains("only 2 usable rows for 3 coefficients"),
        "{line}"
    );
    assert!(line.contains("13 rows were dropped"), "{line}");
}

#[test]
fn fit_cli_names_a_collinear_term() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("few.csv");
    std::fs::write(
        &data,
        "time_s,a,b,y\n0,1,2,5\n1,2,4,7\n2,3,6,8.5\n3,4,8,11\n4,5,10,12.9\n",
    )
    .unwrap();
    let line = fails_with_one_line(&[
        "fit",
        "--data",
        path_str(&data),
        "--target",
        "y",
        "--terms",
        "a,b",
    ]);
    assert!(
        line.contains("term `b` is a linear combination of `a`"),
        "{line}"
    );
    let line = fails_with_one_line(&[
        "fit",
        "--data",
        path_str(&data),
        "--target",
        "y",
        "--terms",
        "a,a^2,a^3,a^4",
    ]);
    assert!(
        line.contains("only 5 usable rows for 5 coefficients (need at least 6)"),
        "{line}"
    );
}

/// A recording where y = 4 + 2a − 3b + 1.5ab + noise, with junk columns beside.
fn write_selection_recording(path: &Path) {
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};
    let mut rng = rand::rngs::StdRng::seed_from_u64(42);
    let normal = Normal::new(0.0, 1.0).unwrap();
    let mut text = String::from("time_s,X.speed_rpm,X.torque_Nm,junk.one,junk.two#2,y\n");
    let mut drift: f64 = 0.0;
    for i in 0..1200 {
        let a: f64 = normal.sample(&mut rng);
        let b: f64 = normal.sample(&mut rng);
        let junk: f64 = normal.sample(&mut rng);
        drift += 0.05 * normal.sample(&mut rng);
        let y = 4.0 + 2.0 * a - 3.0 * b + 1.5 * a * b + 0.5 * normal.sample(&mut rng);
        text.push_str(&format!("{i}.0,{a},{b},{junk},{drift},{y}\n"));
    }
    std::fs::write(path, text).unwrap();
}

#[test]
fn fit_cli_selection_recovers_the_true_terms_and_rejects_junk() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("db.csv");
    write_selection_recording(&data);
    let terms = "X.speed_rpm,X.torque_Nm,junk.one,junk.two#2,X.speed_rpm^2,X.speed_rpm*X.torque_Nm,junk.one*junk.two#2,lag(junk.one,3)";
    for method in ["stepwise", "bic"] {
        let json = dir.path().join(format!("{method}.json"));
        let output = servosight(&[
            "fit",
            "--data",
            path_str(&data),
            "--target",
            "y",
            "--terms",
            terms,
            "--select",
            method,
            "--p-enter",
            "0.001",
            "--p-remove",
            "0.002",
            "--json",
            path_str(&json),
        ]);
        let stdout = String::from_utf8_lossy(&output.stdout);
        assert!(
            output.status.success(),
            "{}",
            String::from_utf8_lossy(&output.stderr)
        );
        assert!(
            stdout.contains(&format!("Selection by {method}")),
            "{stdout}"
        );
        let report: Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
        let chosen: Vec<&str> = report["selection"]["chosen"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_str().unwrap())
            .collect();
        assert_eq!(
            chosen,
            ["X.speed_rpm", "X.torque_Nm", "X.speed_rpm*X.torque_Nm"],
            "{method}"
        );
        let fitted: Vec<&str> = report["coefficients"]
            .as_array()
            .unwrap()
            .iter()
            .map(|c| c["term"].as_str().unwrap())
            .collect();
        assert_eq!(
            fitted,
            [
                "const",
                "X.speed_rpm",
                "X.torque_Nm",
                "X.speed_rpm*X.torque_Nm"
            ]
        );
        let cv = &report["selection"]["cv"];
        assert!(cv["r2"].as_f64().unwrap() > 0.95, "{cv}");
        assert_eq!(cv["folds"], 5);
        let estimate = |term: &str| {
            report["coefficients"]
                .as_array()
                .unwrap()
                .iter()
                .find(|c| c["term"] == term)
                .unwrap()["estimate"]
                .as_f64()
                .unwrap()
        };
        assert!((estimate("X.speed_rpm*X.torque_Nm") - 1.5).abs() < 0.1);
    }
}
