//! Snapshots of every panel's view model in the normal, warning, fault, disconnected and
//! awaiting-approval states, built from hand-made state snapshots (no window, no link).

use std::path::PathBuf;

use servosight::compensation::{
    AuditEntry, CompensationId, CompensationLimits, CompensationValues, Outcome, Proposal, Request,
    Role,
};
use servosight::fit::{Design, FitReport, ols, parse_terms, sensitivity};
use servosight::link::ConnectionState;
use servosight::signal::channel::{AMBIENT, COOLANT, CUT_DEPTH, TIME};
use servosight::signal::{AxisId, Quantity, Recording, axis_column};
use servosight::ui::jobs::{FitOutcome, FitRequest};
use servosight::ui::state::{
    CompensationState, Event, EventKind, HmiState, JobProgress, LinkSnapshot, PushFlow,
    RecorderSnapshot, RecorderState, Severity,
};
use servosight::ui::vm;
use servosight::ui::vm::events::EventFilter;
use servosight::ui::vm::trends::{TrendsSettings, WindowPreset};

/// The states every panel is snapshotted in.
const STATES: [&str; 5] = [
    "normal",
    "warning",
    "fault",
    "disconnected",
    "awaiting_approval",
];

fn names() -> Vec<String> {
    let mut names = vec![TIME.to_string()];
    for axis in [AxisId::X, AxisId::S] {
        for quantity in Quantity::ALL {
            names.push(axis_column(axis, quantity));
        }
    }
    names.extend([
        AMBIENT.to_string(),
        COOLANT.to_string(),
        CUT_DEPTH.to_string(),
    ]);
    // Estimator outputs, as the session appends them when a profile is loaded.
    names.extend([
        "est.X.motor_flange_temp_C".to_string(),
        "est.X.nut_temp_C".to_string(),
        "est.X.straightness_h_um#2".to_string(),
        "est.S.elongation_um".to_string(),
    ]);
    names
}

/// A row at time `t` with the given stator and estimated nut temperatures.
fn row(t: f64, x_stator: f64, s_stator: f64, nut: f64) -> Vec<f64> {
    let mut row = vec![t];
    // X: position, command, speed, torque, current, load, stator.
    row.extend([120.0 + t, 120.5 + t, 600.0, 1.25, 2.5, 18.0, x_stator]);
    // S: position, command, speed, torque, current, load, stator.
    row.extend([
        (t * 360.0) % 360.0,
        (t * 360.0) % 360.0,
        2400.0,
        8.5,
        14.0,
        42.0,
        s_stator,
    ]);
    row.extend([21.5, 1.0, 1.5]);
    row.extend([44.0, nut, 3.25, 18.5]);
    row
}

fn zero_table() -> CompensationValues {
    servosight::link::register_map::compensation_ids()
        .into_iter()
        .take(4)
        .map(|id| (id, 0.0))
        .collect()
}

fn audit_entry(index: u64, outcome: Outcome, approver: Option<&str>) -> AuditEntry {
    AuditEntry {
        index,
        time_utc: format!("2026-03-02T06:1{index}:00.000Z"),
        request_id: "a1b2c3d4e5f6".into(),
        action: "adjust".into(),
        operator: "otto".into(),
        approver: approver.map(str::to_string),
        why: "backlash measured at shift start".into(),
        evidence: "backlash test 2026-03-02".into(),
        step: (outcome == Outcome::Applied).then_some((1, 1)),
        controller: "embedded twin".into(),
        old: [(CompensationId::Backlash(AxisId::X), 0.0)]
            .into_iter()
            .collect(),
        new: [(CompensationId::Backlash(AxisId::X), 4.0)]
            .into_iter()
            .collect(),
        outcome,
        detail: match outcome {
            Outcome::Applied => "read back and verified, controller generation 1".into(),
            _ => "not approved: unknown user or wrong password for `maria`".into(),
        },
        prev_hash: "0".repeat(64),
        hash: "1".repeat(64),
    }
}

fn fit_outcome() -> FitOutcome {
    let mut recording = Recording::new(
        "db",
        vec![
            TIME.into(),
            "X.stator_temp_C".into(),
            "X.speed_rpm".into(),
            "ref.X.motor_flange_temp_C".into(),
        ],
    )
    .expect("valid names");
    for i in 0..40 {
        let stator = 25.0 + f64::from(i) * 0.5;
        let speed = f64::from((i * 37) % 11) * 100.0;
        let noise = f64::from((i * 7919) % 13) / 13.0 - 0.5;
        recording
            .push_row(&[
                f64::from(i),
                stator,
                speed,
                3.0 + 0.8 * stator + 0.001 * speed + 0.05 * noise,
            ])
            .expect("row fits");
    }
    let terms = parse_terms("X.stator_temp_C, X.speed_rpm").expect("terms parse");
    let design =
        Design::from_recording(&recording, "ref.X.motor_flange_temp_C", &terms).expect("design");
    let fit = ols(&design).expect("fit");
    FitOutcome {
        request: FitRequest {
            data: PathBuf::from("database.csv"),
            target: "ref.X.motor_flange_temp_C".into(),
            terms: "X.stator_temp_C, X.speed_rpm".into(),
        },
        report: FitReport::new(&fit, sensitivity(&fit, &design)),
    }
}

fn event(kind: EventKind, severity: Severity, minute: u32, message: &str) -> Event {
    Event {
        time_utc: format!("2026-03-02T06:{minute:02}:00.000Z"),
        kind,
        severity,
        message: message.into(),
    }
}

/// The state snapshot for one of [`STATES`].
fn state(which: &str) -> HmiState {
    let connected = LinkSnapshot {
        source: "embedded twin".into(),
        state: ConnectionState::Connected,
        in_state_s: 754.0,
        last_frame_age_s: Some(0.1),
        last_error: None,
        frames: 7540,
        lost_samples: 0,
        timeouts: 0,
        crc_errors: 0,
        reconnects: 0,
    };
    let mut compensation = CompensationState::new(
        "/data/users.toml".into(),
        "/data/audit.jsonl".into(),
        CompensationLimits::default(),
    );
    compensation.controller = Some(zero_table());
    compensation.users = vec![
        ("otto".into(), Role::Operator),
        ("maria".into(), Role::Approver),
    ];
    compensation.audit = vec![
        audit_entry(0, Outcome::Refused, Some("maria")),
        audit_entry(1, Outcome::Applied, Some("maria")),
    ];
    let mut s = HmiState::new(names(), connected, 1 << 20, compensation);
    let profile = servosight::profile::MachineProfile::load(std::path::Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/assets/it25-twin.toml"
    )))
    .expect("twin profile");
    s.estimate_limits = profile
        .axes
        .iter()
        .map(|(axis, a)| (*axis, a.limits.clone()))
        .collect();
    s.recorder = RecorderSnapshot {
        state: RecorderState::Recording,
        path: Some("/data/recordings/recording-2026-03-02T06-00-00-000Z.csv".into()),
        rows: 7540,
        files: 1,
        frames_not_written: 0,
        error: None,
    };
    let (x_stator, s_stator, nut) = match which {
        "warning" => (104.2, 55.0, 47.5),
        "fault" => (48.0, 133.7, 30.0),
        _ => (41.3, 55.0, 30.0),
    };
    for i in 0..=20 {
        let t = 700.0 + f64::from(i) * 0.5;
        let ramp = f64::from(i) * 0.05;
        s.push_row(&row(t, x_stator - 1.0 + ramp, s_stator - 1.0 + ramp, nut));
    }
    s.events.push(event(
        EventKind::Link,
        Severity::Normal,
        0,
        "embedded twin connected",
    ));
    s.events.push(event(
        EventKind::Recorder,
        Severity::Normal,
        0,
        "recording to /data/recordings/recording-2026-03-02T06-00-00-000Z.csv",
    ));
    s.events.push(event(
        EventKind::Write,
        Severity::Normal,
        11,
        "request a1b2c3d4e5f6: written in 1 step(s), read back and verified",
    ));
    s.model_lab.result = Some(fit_outcome());
    match which {
        "warning" => {
            s.events.push(event(
                EventKind::Condition,
                Severity::Warning,
                12,
                "X: stator 104.2 °C at or above the warning limit 100 °C",
            ));
            s.model_lab.running = Some(JobProgress {
                stage: "reading the database (16384 rows)".into(),
                fraction: Some(0.42),
            });
        }
        "fault" => {
            s.events.push(event(
                EventKind::Condition,
                Severity::Fault,
                13,
                "S: stator 133.7 °C at or above the fault limit 130 °C",
            ));
            s.recorder.state = RecorderState::Failed;
            s.recorder.error = Some("No space left on device (os error 28)".into());
            s.model_lab.result = None;
            s.model_lab.error = Some("database.csv: line 5, column 3: `x` is not a number".into());
        }
        "disconnected" => {
            s.link.state = ConnectionState::Disconnected;
            s.link.in_state_s = 12.0;
            s.link.last_frame_age_s = Some(12.0);
            s.link.last_error = Some("serial port /dev/ttyUSB0: No such device".into());
            s.link.timeouts = 3;
            s.link.reconnects = 2;
            s.compensation.controller_error = Some("controller request failed: timeout".into());
            s.events.push(event(
                EventKind::Link,
                Severity::Fault,
                14,
                "Modbus RTU /dev/ttyUSB0 disconnected: No such device",
            ));
            s.frames_not_shown = 0;
        }
        "awaiting_approval" => {
            let proposal = Proposal {
                changes: [(CompensationId::Backlash(AxisId::X), 6.5)]
                    .into_iter()
                    .collect(),
                why: "backlash grew to 6.5 µm".into(),
                evidence: "backlash test at shift start".into(),
                action: "adjust".into(),
            };
            s.compensation.draft_changes = proposal.changes.clone();
            let request = Request::new(proposal, "otto").expect("valid request");
            s.compensation.flow = PushFlow::AwaitingApproval {
                request,
                refusal: Some("not approved: unknown user or wrong password for `maria`".into()),
            };
        }
        _ => {}
    }
    s
}

fn trends_settings() -> TrendsSettings {
    TrendsSettings {
        selected: vec![
            axis_column(AxisId::X, Quantity::StatorTemp),
            axis_column(AxisId::S, Quantity::StatorTemp),
            axis_column(AxisId::S, Quantity::Load),
        ],
        preset: WindowPreset::Minute,
        follow_live: true,
        view: None,
    }
}

#[test]
fn overview_view_models() {
    for which in STATES {
        let view = vm::overview::build(&state(which));
        insta::assert_yaml_snapshot!(format!("overview_{which}"), view);
    }
}

#[test]
fn status_bar_view_models() {
    for which in STATES {
        let view = vm::status::build(&state(which));
        insta::assert_yaml_snapshot!(format!("status_{which}"), view);
    }
}

#[test]
fn trends_view_models() {
    for which in STATES {
        let view = vm::trends::build(&state(which), &trends_settings(), 1000);
        insta::assert_yaml_snapshot!(format!("trends_{which}"), view);
    }
}

#[test]
fn compensation_view_models() {
    for which in STATES {
        let view = vm::compensation::build(&state(which));
        // The request id hashes the time of the request, so it differs on every run.
        insta::assert_yaml_snapshot!(format!("compensation_{which}"), view, {
            ".flow.request.request_id" => "[request id]",
        });
    }
}

#[test]
fn model_lab_view_models() {
    for which in STATES {
        let view = vm::model_lab::build(&state(which));
        insta::assert_yaml_snapshot!(format!("model_lab_{which}"), view);
    }
}

#[test]
fn events_view_models() {
    let filters = [
        EventFilter::default(),
        EventFilter {
            problems_only: true,
            ..EventFilter::default()
        },
    ];
    for which in STATES {
        for (k, filter) in filters.iter().enumerate() {
            let view = vm::events::build(&state(which), filter, 100);
            let name = if k == 0 { "all" } else { "problems" };
            insta::assert_yaml_snapshot!(format!("events_{which}_{name}"), view);
        }
    }
}

#[test]
fn the_light_follows_the_link_and_the_thresholds() {
    use servosight::ui::vm::overview::axis_condition;
    assert_eq!(
        axis_condition(&state("normal"), AxisId::X).severity,
        Severity::Normal
    );
    assert_eq!(
        axis_condition(&state("warning"), AxisId::X).severity,
        Severity::Warning
    );
    assert_eq!(
        axis_condition(&state("fault"), AxisId::S).severity,
        Severity::Fault
    );
    assert_eq!(
        axis_condition(&state("fault"), AxisId::X).severity,
        Severity::Normal
    );
    let down = state("disconnected");
    let light = axis_condition(&down, AxisId::X);
    assert_eq!(light.severity, Severity::Fault);
    assert!(light.reasons[0].contains("No such device"), "{light:?}");
    let mut stale = state("normal");
    stale.link.state = ConnectionState::Stale;
    assert_eq!(
        axis_condition(&stale, AxisId::X).severity,
        Severity::Warning
    );
}

#[test]
fn trends_export_writes_what_is_shown() {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("shown.csv");
    let view = vm::trends::build(&state("normal"), &trends_settings(), 1000);
    let rows = vm::trends::export_csv(&view, &path).expect("export");
    assert_eq!(rows, 21);
    let recording = servosight::signal::read_recording(&path).expect("reads back as CSV v1");
    assert_eq!(recording.len(), 21);
    let stator = recording
        .column(&axis_column(AxisId::X, Quantity::StatorTemp))
        .expect("column");
    assert!((stator[0] - 40.3).abs() < 1e-4, "{}", stator[0]);
    let empty = vm::trends::build(&state("normal"), &TrendsSettings::default(), 1000);
    assert!(vm::trends::export_csv(&empty, &path).is_err());
}
