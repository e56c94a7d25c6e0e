//! Snapshots of every panel's view model in the normal, warning, fault, disconnected and
//! awaiting-approval states, built from hand-made state snapshots (no window, no link).
#![allow(non_snake_case)] // unit suffixes are part of the names

use std::path::PathBuf;

use servosight::compensation::{
    AuditEntry, CompensationId, CompensationLimits, CompensationValues, Outcome, Proposal, Request,
    Role,
};
use servosight::estimators::pipeline::ElongationOrigin;
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
    s.estimate_limits = profile.axis_limits();
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
        ..TrendsSettings::default()
    }
}

#[test]
fn overview_view_models() {
    for which in STATES {
        let view = vm::overview::build(&state(which));
        insta::assert_yaml_snapshot!(format!("overview_{which}"), view);
    }
}

/// The Overview card of a feed axis shows its preload state from the warm-up analysis against
/// the healthy baseline, and a friction rise turns the light to warning with the evidence.
#[test]
fn overview_shows_the_preload_state() {
    let preload = |s: &HmiState| {
        let view = vm::overview::build(s);
        let card = view
            .cards
            .into_iter()
            .find(|c| c.axis == "X")
            .expect("an X card");
        let reading = card
            .readings
            .iter()
            .find(|r| r.label == "preload")
            .cloned()
            .expect("a preload reading");
        (reading, card.light)
    };
    let healthy = warmup_state("pass");
    let (reading, light) = preload(&healthy);
    assert!(reading.value.contains("% of nominal"), "{reading:?}");
    assert_eq!(reading.severity, Severity::Normal);
    assert!(
        !light.reasons.iter().any(|r| r.contains("preload")),
        "{light:?}"
    );

    let mut worn = warmup_state("pass");
    if let Some(a) = worn.warmup.analysis.as_mut() {
        a.fingerprint = Ok(fingerprint(0.70));
    }
    let (reading, light) = preload(&worn);
    assert!(reading.value.ends_with("friction rise"), "{reading:?}");
    assert_eq!(reading.severity, Severity::Warning);
    assert_eq!(light.severity, Severity::Warning);
    assert!(
        light
            .reasons
            .iter()
            .any(|r| r.starts_with("friction rise on X")),
        "{light:?}"
    );
    insta::assert_yaml_snapshot!("overview_preload_friction_rise", preload(&worn).0);

    let mut unmeasured = warmup_state("pass");
    unmeasured.warmup.analysis = None;
    let (reading, _) = preload(&unmeasured);
    assert_eq!(reading.value, "not measured (warm-up analysis)");
}

/// The "normal" state with the machine profile and the torque split's estimates, the X nut
/// carrying `nut_Nm` (the X motor its torque plus the bearings' friction).
fn loaded_state(nut_Nm: f64) -> HmiState {
    let base = state("normal");
    let split = [
        "est.X.front_bearing_torque_Nm",
        "est.X.back_bearing_torque_Nm",
        "est.X.nut_torque_Nm",
    ];
    let mut names = names();
    names.extend(split.map(String::from));
    let column = |name: String| names.iter().position(|n| *n == name).expect("a column");
    let (torque, current, load) = (
        column(axis_column(AxisId::X, Quantity::Torque)),
        column(axis_column(AxisId::X, Quantity::Current)),
        column(axis_column(AxisId::X, Quantity::Load)),
    );
    let mut s = HmiState::new(names.clone(), base.link.clone(), 1 << 20, base.compensation);
    s.profile = Some(twin_profile());
    s.estimate_limits = base.estimate_limits;
    for i in 0..=20 {
        let t = 700.0 + f64::from(i) * 0.5;
        let mut row = row(t, 41.3, 55.0, 30.0);
        let (front_Nm, back_Nm) = (0.16, 0.06);
        row[torque] = nut_Nm + front_Nm + back_Nm;
        // The twin's X motor: 8 N·m rated, 1.2 N·m/A.
        row[current] = row[torque] / 1.2;
        row[load] = 100.0 * row[torque] / 8.0;
        row.extend([front_Nm, back_Nm, nut_Nm]);
        s.push_row(&row);
    }
    s
}

/// A state whose estimates include each axis's motor abnormality score (`NaN`: not yet known).
fn abnormality_state(x_pct: f64, s_pct: f64) -> HmiState {
    let base = state("normal");
    let mut names = names();
    names.extend(["est.X.abnormality_pct", "est.S.abnormality_pct"].map(String::from));
    let mut s = HmiState::new(names, base.link.clone(), 1 << 20, base.compensation);
    s.profile = Some(twin_profile());
    s.estimate_limits = base.estimate_limits;
    for i in 0..=20 {
        let mut row = row(700.0 + f64::from(i) * 0.5, 41.3, 55.0, 30.0);
        row.extend([x_pct, s_pct]);
        s.push_row(&row);
    }
    s
}

/// Each card shows its axis's motor abnormality score — the friction torque against the
/// healthy model — judged against the profile's levels (X ±4 / ±12 %, spindle ±8 / ±25 %): not
/// yet known until enough steady running, a warning with the likely cause, a fault either way
/// (less friction than healthy is lost preload). The warm-up checklist's "no abnormality" step
/// follows the lights.
#[test]
fn overview_shows_the_motor_abnormality_score() {
    let card = |s: &HmiState, axis: &str| {
        vm::overview::build(s)
            .cards
            .into_iter()
            .find(|c| c.axis == axis)
            .unwrap_or_else(|| panic!("a {axis} card"))
    };
    let reading = |card: &vm::overview::AxisCard| {
        card.readings
            .iter()
            .find(|r| r.label == "abnormality (friction vs healthy)")
            .cloned()
            .unwrap_or_else(|| panic!("no abnormality line on {card:?}"))
    };
    let healthy = abnormality_state(f64::NAN, 1.4);
    let x = card(&healthy, "X");
    assert_eq!(reading(&x).value, "not yet known (needs steady running)");
    assert_eq!(x.light.severity, Severity::Normal, "{:?}", x.light);
    let s = card(&healthy, "S");
    assert_eq!(
        (reading(&s).value.as_str(), reading(&s).unit.as_str()),
        ("+1.4", "%")
    );
    assert_eq!(s.light.severity, Severity::Normal, "{:?}", s.light);

    let worn = abnormality_state(-21.0, 19.7);
    let s = card(&worn, "S");
    assert_eq!(reading(&s).severity, Severity::Warning);
    assert!(
        s.light.reasons.iter().any(|r| r
            == "motor abnormality on S: friction torque +19.7 % against the healthy model \
                (beyond the warning level ±8 %): wear, damage or failing lubrication?"),
        "{:?}",
        s.light
    );
    let x = card(&worn, "X");
    assert_eq!(x.light.severity, Severity::Fault);
    assert!(
        x.light
            .reasons
            .iter()
            .any(|r| r.contains("friction torque -21.0 %")
                && r.ends_with("fault level ±12 %): lost preload?")),
        "{:?}",
        x.light
    );
    insta::assert_yaml_snapshot!("overview_abnormality", vm::overview::build(&worn));
    let step = vm::warmup::build(&worn)
        .steps
        .into_iter()
        .find(|s| s.title.starts_with("4."))
        .expect("the no-abnormality step");
    assert!(
        step.reason.contains("motor abnormality on X"),
        "{}",
        step.reason
    );
}

/// A feed axis's card shows the axial load on its front bearing (as a share of the bearing's
/// dynamic rating C) and on its nut (as a share of the load at which it loses its preload),
/// from the estimated nut torque; at the depth-of-cut margin of a limit the light warns, at the
/// limit it is a fault. Without a profile or a split estimate there is no such line.
#[test]
fn overview_shows_bearing_and_nut_load() {
    let x_card = |s: &HmiState| {
        vm::overview::build(s)
            .cards
            .into_iter()
            .find(|c| c.axis == "X")
            .expect("an X card")
    };
    let load = |card: &vm::overview::AxisCard, label: &str| {
        card.readings
            .iter()
            .find(|r| r.label == label)
            .cloned()
            .unwrap_or_else(|| panic!("no {label} on {card:?}"))
    };
    // During a cut: (1.6 − 0.378 N·m preload drag) · 2π · 0.9 / 10 mm = 691 N axial,
    // 2.7 % of the bearing's C = 26 kN and 16.4 % of 2.8 × 1500 N.
    let cutting = loaded_state(1.6);
    let card = x_card(&cutting);
    let bearing = load(&card, "front bearing load (estimated)");
    assert_eq!(
        (bearing.value.as_str(), bearing.unit.as_str()),
        ("2.7", "% of rating C (691 N axial)")
    );
    assert_eq!(load(&card, "nut load (estimated)").value, "16.4");
    assert_eq!(card.light.severity, Severity::Normal, "{:?}", card.light);
    insta::assert_yaml_snapshot!("overview_loads_normal", vm::overview::build(&cutting));

    // 3518 N: beyond 80 % of the nut's 4200 N, within 80 % of the bearing's C₀/4 = 5750 N.
    let heavy = loaded_state(6.6);
    let card = x_card(&heavy);
    assert_eq!(
        load(&card, "nut load (estimated)").severity,
        Severity::Warning
    );
    assert_eq!(
        load(&card, "front bearing load (estimated)").severity,
        Severity::Normal
    );
    assert_eq!(card.light.severity, Severity::Warning);
    assert!(
        card.light.reasons.iter().any(|r| r
            == "nut load (estimated) 3518 N axial at or above 80 % of the nut's preload-loss limit 4200 N"),
        "{:?}",
        card.light
    );
    insta::assert_yaml_snapshot!("overview_loads_warning", vm::overview::build(&heavy));

    // 4649 N: the nut's preload is gone (fault), the bearing is past 80 % of C₀/4 (warning).
    let card = x_card(&loaded_state(8.6));
    assert_eq!(
        load(&card, "nut load (estimated)").severity,
        Severity::Fault
    );
    assert_eq!(
        load(&card, "front bearing load (estimated)").severity,
        Severity::Warning
    );
    assert_eq!(card.light.severity, Severity::Fault);

    // No profile, or no split estimate: no load lines at all.
    let mut unprofiled = loaded_state(1.6);
    unprofiled.profile = None;
    let mut unsplit = state("normal");
    unsplit.profile = Some(twin_profile());
    for s in [unprofiled, unsplit] {
        let card = x_card(&s);
        assert!(
            !card
                .readings
                .iter()
                .any(|r| r.label.contains("load (estimated)")),
            "{:?}",
            card.readings
        );
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

/// The Trends view carries the saved layout to the panel: folded groups, series switched off
/// in the legend (still chosen, with their data) and the picker's width within sane bounds.
#[test]
fn trends_view_follows_the_saved_layout() {
    let s = state("normal");
    let mut settings = trends_settings();
    settings.groups_open.insert("X axis".into(), false);
    settings.hidden.insert("S.load_pct".into());
    settings.picker_width = Some(310.0);
    let view = vm::trends::build(&s, &settings, 1000);
    let open: Vec<(&str, bool)> = view
        .groups
        .iter()
        .map(|g| (g.title.as_str(), g.open))
        .collect();
    assert_eq!(open[0], ("X axis", false));
    assert!(open[1..].iter().all(|(_, o)| *o), "{open:?}");
    let series: Vec<(&str, bool, usize)> = view
        .plots
        .iter()
        .flat_map(|p| &p.series)
        .map(|s| (s.channel.as_str(), s.hidden, s.points.len()))
        .collect();
    assert_eq!(
        series,
        [
            ("X.stator_temp_C", false, 21),
            ("S.stator_temp_C", false, 21),
            ("S.load_pct", true, 21)
        ]
    );
    assert_eq!(view.picker_width, 310.0);
    for (saved, shown) in [
        (None, vm::trends::PICKER_WIDTH),
        (Some(5000.0), 800.0),
        (Some(f32::NAN), vm::trends::PICKER_WIDTH),
    ] {
        settings.picker_width = saved;
        assert_eq!(vm::trends::build(&s, &settings, 1000).picker_width, shown);
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

/// The Source window in every state, then while a recording opens, after it failed, and on
/// a recording opened from it (with the way back to the start source). A push that waits for
/// its approver refuses the change (the awaiting-approval state).
#[test]
fn source_window_view_models() {
    for which in STATES {
        let s = state(which);
        let mut view = vm::source::build(&s);
        // The request id hashes the time of the request, so it differs on every run.
        if let (PushFlow::AwaitingApproval { request, .. }, Some(refused)) =
            (&s.compensation.flow, view.refused.as_mut())
        {
            *refused = refused.replace(request.id(), "[request id]");
        }
        assert_eq!(
            view.refused.is_some(),
            which == "awaiting_approval",
            "{which}: {:?}",
            view.refused
        );
        // The other states differ from the normal one only in the link's word.
        if matches!(which, "normal" | "awaiting_approval") {
            insta::assert_yaml_snapshot!(format!("source_{which}"), view);
        }
    }
    let mut s = state("normal");
    s.source.running = Some(servosight::ui::state::SourceChangeProgress {
        what: "opening /data/shift.csv".into(),
        progress: JobProgress {
            stage: "reading the recording's headers".into(),
            fraction: Some(0.3),
        },
    });
    insta::assert_yaml_snapshot!("source_opening", vm::source::build(&s));
    s.source.running = None;
    s.source.error = Some(
        "opening /data/shfit.csv failed: /data/shfit.csv: No such file or directory (os error \
         2); embedded twin runs on"
            .into(),
    );
    insta::assert_yaml_snapshot!("source_failed", vm::source::build(&s));
    let mut s = state("normal");
    s.link.source = "replay of /data/shift.csv".into();
    s.profile = Some(twin_profile());
    s.source.start_source_label = Some("embedded twin".into());
    s.pace = Some(servosight::ui::session::Pace {
        paused: true,
        speed: servosight::link::ReplaySpeed::Factor(60.0),
    });
    s.source.last_change = Some(
        "source: replaying /data/shift.csv … /data/shift-0002.csv (3 pieces) at 60 × real \
         time with the estimators of profile `IT-25 lathe (twin)`, not recorded again (it is on \
         disk)"
            .into(),
    );
    let view = vm::source::build(&s);
    assert_eq!(
        view.return_label.as_deref(),
        Some("Back to the start source (embedded twin)")
    );
    assert_eq!(
        view.pace.as_ref().map(|p| p.text.as_str()),
        Some("60 × real time, paused")
    );
    insta::assert_yaml_snapshot!("source_on_a_recording", view);
    insta::assert_yaml_snapshot!("status_away_from_start", vm::status::build(&s));
    // On a controller, opening a recording says what it stops.
    let mut s = state("normal");
    s.link.source = "Modbus RTU /dev/ttyUSB0 @ 115200 baud, slave 1".into();
    s.controller = Some(s.link.source.clone());
    s.source.blank_controller_profile =
        "blank: the one the HMI was started with on its controller (none)".into();
    let view = vm::source::build(&s);
    assert!(view.pace.is_none(), "a controller runs at its own pace");
    insta::assert_yaml_snapshot!("source_on_a_controller", view);
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

fn twin_profile() -> servosight::profile::MachineProfile {
    servosight::profile::MachineProfile::load(std::path::Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/assets/it25-twin.toml"
    )))
    .expect("twin profile")
}

fn fingerprint(coulomb: f64) -> servosight::estimators::fingerprint::FrictionFingerprint {
    servosight::estimators::fingerprint::FrictionFingerprint {
        axis: AxisId::X,
        source: "the session".into(),
        coulomb_Nm: coulomb,
        coulomb_positive_Nm: coulomb + 0.01,
        coulomb_negative_Nm: coulomb - 0.01,
        viscous_Nm_per_krpm: 0.05,
        inertia_kgm2: 0.0,
        offset_Nm: 0.01,
        coherence: 0.97,
        samples: 4800,
    }
}

fn backlash_report(um: f64) -> servosight::estimators::backlash::BacklashReport {
    use servosight::estimators::backlash::{BacklashAtSpeed, BacklashReport};
    BacklashReport {
        axis: AxisId::X,
        backlash_um: um,
        by_speed: vec![BacklashAtSpeed {
            speed_rpm: 2.0,
            feed_mm_per_min: 20.0,
            backlash_um: um,
            ci_low_um: um - 0.3,
            ci_high_um: um + 0.3,
            current_rise_a: 0.1,
            rise_t: 200.0,
            samples: 20000,
        }],
        feeds_without_a_rise: Vec::new(),
        confidence: 0.6,
        test_duration_s: 167.0,
    }
}

/// A controller table with every value, at these backlash.X and thermal_offset.S values.
fn full_table(backlash_x: f64, offset_s: f64) -> CompensationValues {
    servosight::link::register_map::compensation_ids()
        .into_iter()
        .map(|id| {
            let v = match id {
                CompensationId::Backlash(AxisId::X) => backlash_x,
                CompensationId::ThermalOffset(AxisId::S) => offset_s,
                _ => 0.0,
            };
            (id, v)
        })
        .collect()
}

/// The warm-up checklist's states: the base state plus six more minutes of history (the
/// stator of X rising at `rate` °C/min), the profile, an analysis and a controller table.
fn warmup_state(which: &str) -> HmiState {
    use servosight::ui::analysis::WarmupAnalysis;
    let base = match which {
        "fail" => "fault",
        "disconnected" => "disconnected",
        _ => "normal",
    };
    let mut s = state(base);
    s.profile = Some(twin_profile());
    let (rate, s_stator) = match which {
        "warn" => (0.3, 55.0),
        "fail" => (1.2, 133.7),
        _ => (0.0, 55.0),
    };
    for i in 1..=100 {
        let t = 710.0 + f64::from(i) * 4.0;
        let x_stator = 41.3 + rate * (t - 710.0) / 60.0;
        s.push_row(&row(t, x_stator, s_stator, 30.0));
    }
    s.compensation.controller = Some(match which {
        "warn" => full_table(11.6, 0.0),
        _ => full_table(11.6, 18.4),
    });
    s.warmup.started_at_s = Some(700.0);
    let current = fingerprint(0.42);
    s.warmup.analysis = Some(WarmupAnalysis {
        axis: AxisId::X,
        fingerprint: match which {
            "fail" => Err("the session: only 3 moving samples without cutting (3 positive, 0 negative); the fingerprint needs the warm-up moves in both directions".into()),
            _ => Ok(current.clone()),
        },
        backlash: Ok(backlash_report(match which {
            "warn" => 25.0,
            "fail" => 45.0,
            _ => 11.6,
        })),
        note: "84210 samples at full rate from 700.0 s to 1110.0 s".into(),
    });
    if which != "warn" {
        s.warmup.baselines.insert(AxisId::X, fingerprint(0.43));
    }
    s.elongation_origins.insert(
        AxisId::S,
        Some(ElongationOrigin::ToolMeasured {
            time_s: 702.5,
            started_warm_K: None,
        }),
    );
    s
}

#[test]
fn warmup_view_models() {
    use servosight::ui::vm::warmup::StepStatus;
    for (which, verdict) in [
        ("pass", StepStatus::Pass),
        ("warn", StepStatus::Warn),
        ("fail", StepStatus::Fail),
        ("disconnected", StepStatus::Fail),
    ] {
        let view = vm::warmup::build(&warmup_state(which));
        assert_eq!(view.verdict, verdict, "{which}: {view:#?}");
        insta::assert_yaml_snapshot!(format!("warmup_{which}"), view);
    }
    // Before any analysis: the analysed steps wait, and sign-off is blocked.
    let mut fresh = warmup_state("pass");
    fresh.warmup.analysis = None;
    let view = vm::warmup::build(&fresh);
    assert_eq!(view.verdict, StepStatus::Pending);
    assert!(
        view.sign_off_blocked
            .as_deref()
            .is_some_and(|r| r.contains("2. Friction fingerprint")),
        "{view:?}"
    );
    // A drifted fingerprint (friction well above the baseline) fails on friction rise.
    let mut worn = warmup_state("pass");
    if let Some(a) = worn.warmup.analysis.as_mut() {
        a.fingerprint = Ok(fingerprint(0.70));
    }
    let view = vm::warmup::build(&worn);
    assert_eq!(
        view.steps[1].status,
        StepStatus::Fail,
        "{:?}",
        view.steps[1]
    );
    assert!(
        view.steps[1].reason.contains("friction rise"),
        "{}",
        view.steps[1].reason
    );
}

#[test]
fn compensation_proposals_come_from_the_estimates() {
    let s = warmup_state("warn");
    let view = vm::compensation::build(&s);
    insta::assert_yaml_snapshot!("compensation_proposals", view.proposals);
    let ids: Vec<&str> = view.proposals.iter().map(|p| p.id.as_str()).collect();
    assert_eq!(ids, vec!["thermal_offset.S", "backlash.X"]);
    // The elongation estimate of the rows is 18.5 µm.
    assert_eq!(view.proposals[0].proposed_um, "18.5");
    assert_eq!(view.proposals[1].proposed_um, "25.0");
    // Nothing is proposed without the controller's table.
    let mut no_table = s.clone();
    no_table.compensation.controller = None;
    assert!(vm::compensation::build(&no_table).proposals.is_empty());
}

/// The thermal offset corrects the tool length measured when the elongation started counting:
/// an estimate that started on a warm spindle does not know the growth before it, nor one whose
/// frames stopped for more than five minutes the growth in the gap, so its offset is shown but
/// cannot be used, and the warm-up step says what to do.
#[test]
fn a_thermal_offset_is_proposed_only_from_a_known_tool_length() {
    use servosight::ui::vm::warmup::StepStatus;
    let origins = [
        (
            Some(ElongationOrigin::ToolMeasured {
                time_s: 702.5,
                started_warm_K: None,
            }),
            None,
        ),
        (
            Some(ElongationOrigin::FirstFrameAtRest { time_s: 0.0 }),
            None,
        ),
        (
            Some(ElongationOrigin::FirstFrameWarm {
                time_s: 700.0,
                excess_K: 6.4,
            }),
            Some("6.4 K above the room"),
        ),
        (
            Some(ElongationOrigin::FirstFrameUnread { time_s: 3.0 }),
            Some("no room or spindle stator reading"),
        ),
        (
            Some(ElongationOrigin::AcrossGap {
                time_s: 0.0,
                gap_end_s: 700.0,
                gap_s: 600.0,
            }),
            Some("the frames stopped for 10 min 00 s before machine time 700.0 s"),
        ),
        (None, Some("not yet counted a frame")),
    ];
    for (origin, withheld) in origins {
        // The offset applied is the estimate: compensated if the origin is known.
        let mut s = warmup_state("pass");
        s.elongation_origins.insert(AxisId::S, origin);
        let view = vm::compensation::build(&s);
        let offset = &view.proposals[0];
        assert_eq!(offset.id, "thermal_offset.S");
        let step = &vm::warmup::build(&s).steps[4];
        match withheld {
            None => {
                assert_eq!(offset.blocked, None, "{origin:?}");
                assert!(offset.basis.contains("counted from"), "{}", offset.basis);
                assert_eq!(step.status, StepStatus::Pass, "{origin:?}: {step:?}");
            }
            Some(why) => {
                let blocked = offset.blocked.as_deref().unwrap_or_default();
                assert!(blocked.contains(why), "{origin:?}: {blocked}");
                assert!(
                    offset
                        .basis
                        .contains("not counted from a known tool length"),
                    "{}",
                    offset.basis
                );
                assert_eq!(step.status, StepStatus::Warn, "{origin:?}: {step:?}");
                assert!(step.reason.contains(why), "{}", step.reason);
            }
        }
        let counted_from = step
            .values
            .iter()
            .find(|v| v.label == "counted from machine time")
            .map(|v| v.value.clone());
        assert_eq!(
            counted_from,
            Some(servosight::ui::vm::number(origin.map(|o| o.time_s()), 1))
        );
    }
    // A tool measured in the last session, whose state this one carried on from: usable, and
    // the basis says the time is before this session's clock.
    let mut carried = warmup_state("pass");
    carried.elongation_origins.insert(
        AxisId::S,
        Some(ElongationOrigin::ToolMeasured {
            time_s: -2400.0,
            started_warm_K: None,
        }),
    );
    let offset = &vm::compensation::build(&carried).proposals[0];
    assert_eq!(offset.blocked, None);
    assert!(
        offset.basis.contains(
            "at machine time -2400.0 s (before this session's clock started: carried over from the last session)"
        ),
        "{}",
        offset.basis
    );
    // The same estimate on a session that started warm: listed with its reason, never usable.
    let mut warm = warmup_state("warn");
    warm.elongation_origins.insert(
        AxisId::S,
        Some(ElongationOrigin::FirstFrameWarm {
            time_s: 700.0,
            excess_K: 6.4,
        }),
    );
    let proposals = vm::compensation::estimate_proposals(&warm);
    assert!(proposals[0].withheld.is_some(), "{proposals:?}");
    assert_eq!(
        proposals[1].withheld, None,
        "the backlash test is not affected"
    );

    // Measured on a spindle that started warm: usable, with the caution about the first hours.
    let mut measured = warmup_state("pass");
    measured.elongation_origins.insert(
        AxisId::S,
        Some(ElongationOrigin::ToolMeasured {
            time_s: 702.5,
            started_warm_K: Some(6.4),
        }),
    );
    let offset = &vm::compensation::build(&measured).proposals[0];
    assert_eq!(offset.blocked, None);
    assert!(
        offset.basis.contains("6.4 K above the room"),
        "{}",
        offset.basis
    );
    // An origin newer than the newest frame belongs to estimates not shown yet.
    let mut ahead = warmup_state("pass");
    ahead.elongation_origins.insert(
        AxisId::S,
        Some(ElongationOrigin::ToolMeasured {
            time_s: 2000.0,
            started_warm_K: None,
        }),
    );
    let offset = &vm::compensation::build(&ahead).proposals[0];
    assert!(
        offset
            .blocked
            .as_deref()
            .is_some_and(|b| b.contains("from before the count")),
        "{offset:?}"
    );
}

/// A thermal offset in the draft was computed from the elongation as it counted then: when the
/// count starts again (the tool was measured) it is taken out of the draft, saying so, and the
/// offset is withheld until the new count has reached the screen.
#[test]
fn a_tool_measurement_takes_the_old_thermal_offset_out_of_the_draft() {
    use servosight::ui::session::SessionUpdate;
    let id = CompensationId::ThermalOffset(AxisId::S);
    let mut s = warmup_state("pass");
    s.compensation.draft_changes.set(id, 18.5);
    s.compensation
        .draft_changes
        .set(CompensationId::Backlash(AxisId::X), 11.6);
    // The same origin again (every tick) changes nothing.
    s.apply(SessionUpdate::ElongationOrigins(vec![(
        AxisId::S,
        Some(ElongationOrigin::ToolMeasured {
            time_s: 702.5,
            started_warm_K: None,
        }),
    )]));
    assert_eq!(s.compensation.draft_changes.get(id), Some(18.5));
    // The operator's press: the draft loses the offset at once, before the session answers.
    let mut pressed = s.clone();
    pressed.elongation_restarted(AxisId::S);
    assert_eq!(pressed.compensation.draft_changes.get(id), None);
    assert_eq!(
        pressed
            .compensation
            .draft_changes
            .get(CompensationId::Backlash(AxisId::X)),
        Some(11.6)
    );
    assert!(
        pressed
            .compensation
            .notice
            .as_deref()
            .is_some_and(|n| n.contains("thermal_offset.S taken out of the draft")),
        "{:?}",
        pressed.compensation.notice
    );
    assert!(
        vm::compensation::build(&pressed).proposals[0]
            .blocked
            .is_some()
    );
    // The session says the count started again: the same.
    s.apply(SessionUpdate::ElongationOrigins(vec![(
        AxisId::S,
        Some(ElongationOrigin::ToolMeasured {
            time_s: 1000.0,
            started_warm_K: None,
        }),
    )]));
    assert_eq!(s.compensation.draft_changes.get(id), None);
}

/// The first two hours of the twin's production day (spindle warm-up, then roughing and
/// finishing cuts), fed through an HMI state as the session would.
fn production_state() -> HmiState {
    use servosight::sim::{ScenarioKind, TwinConfig};
    let recording =
        servosight::sim::simulate(TwinConfig::new(ScenarioKind::Production, Some(2.0), 3))
            .expect("the twin runs");
    let names = recording.names().to_vec();
    let mut s = HmiState::new(
        names,
        state("normal").link,
        64 << 20,
        state("normal").compensation,
    );
    s.profile = Some(twin_profile());
    let mut row = Vec::new();
    for i in 0..recording.len() {
        recording.row_into(i, &mut row);
        s.push_row(&row);
    }
    s
}

fn compute_depth(s: &mut HmiState, diameter: f64) {
    use servosight::ui::analysis::{DepthInput, run_depth_of_cut};
    use servosight::ui::jobs::JobContext;
    use std::sync::{Arc, atomic::AtomicBool};
    let profile = s.profile.clone().expect("profile");
    let input = DepthInput::from_history(&s.history, &profile, diameter).expect("input");
    let (tx, _rx) = std::sync::mpsc::sync_channel(64);
    let context = JobContext::new(tx, Arc::new(AtomicBool::new(false)));
    s.depth.outcome = Some(run_depth_of_cut(input, &context).expect("runs"));
    s.depth.computed_at_s = s.history.newest_time_s();
}

#[test]
fn depth_of_cut_view_models() {
    let mut ready = production_state();
    compute_depth(&mut ready, 80.0);
    let view = vm::depth::build(&ready);
    // The same recommendation as the library computes from the recording directly.
    let recording = servosight::sim::simulate(servosight::sim::TwinConfig::new(
        servosight::sim::ScenarioKind::Production,
        Some(2.0),
        3,
    ))
    .expect("the twin runs");
    let direct = servosight::estimators::depth_of_cut::recommend_depth_of_cut(
        &twin_profile(),
        &recording,
        80.0,
    )
    .expect("recommendation");
    assert_eq!(
        view.recommended.as_deref(),
        Some(format!("{:.1} mm", direct.recommended_depth_mm).as_str())
    );
    assert_eq!(
        view.limiting_component.as_deref(),
        Some(direct.limiting_component.as_str())
    );
    assert!(view.components[0].limiting && view.components.len() >= 4);
    insta::assert_yaml_snapshot!("depth_of_cut_normal", view);

    // Few cuts: says so clearly.
    let mut few = state("normal");
    few.profile = Some(twin_profile());
    compute_depth(&mut few, 80.0);
    let view = vm::depth::build(&few);
    assert!(view.recommended.is_none());
    assert!(
        view.not_enough_data
            .as_deref()
            .is_some_and(|r| r.starts_with("Not enough cutting data yet")),
        "{view:?}"
    );
    insta::assert_yaml_snapshot!("depth_of_cut_not_enough_data", view);
    let mut down = state("disconnected");
    down.profile = Some(twin_profile());
    insta::assert_yaml_snapshot!("depth_of_cut_disconnected", vm::depth::build(&down));
}

#[test]
fn trends_show_the_straightness_profile_and_export_a_png() {
    let mut s = state("normal");
    s.profile = Some(twin_profile());
    // The per-node estimates of the session: a bow along the 400 mm stroke.
    let mut names = names();
    let nodes: Vec<String> = (1..=5)
        .flat_map(|k| {
            [
                format!("est.X.straightness_h_um#{k}"),
                format!("est.X.straightness_v_um#{k}"),
            ]
        })
        .collect();
    names.retain(|n| n != "est.X.straightness_h_um#2");
    names.extend(nodes.iter().cloned());
    let mut t = HmiState::new(names, s.link.clone(), 1 << 20, s.compensation.clone());
    t.profile = s.profile.clone();
    for i in 0..=20 {
        let time = 700.0 + f64::from(i) * 0.5;
        let mut r = row(time, 41.3, 55.0, 30.0);
        r.remove(r.len() - 2); // the node-2 column dropped above
        for k in 0..5 {
            let x = f64::from(k) / 4.0;
            r.push(4.0 * x * (1.0 - x)); // H: 1 µm bow at the middle
            r.push(-2.0 * x); // V: a straight slope is straight (zone 0)
        }
        t.push_row(&r);
    }
    let view = vm::trends::build(&t, &trends_settings(), 1000);
    assert_eq!(view.straightness.len(), 2);
    assert_eq!(view.straightness[0].zone, "1.00 µm");
    assert_eq!(view.straightness[1].zone, "0.00 µm");
    assert_eq!(view.straightness[0].points[2], [200.0, 1.0]);
    insta::assert_yaml_snapshot!("trends_straightness", view.straightness);

    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("trends.png");
    let canvas =
        servosight::ui::export_png::render_trends(&view, false, [900, 900]).expect("rendered");
    canvas.save_png(&path).expect("written");
    let image = image::open(&path).expect("a PNG that decodes").to_rgba8();
    assert_eq!(image.dimensions(), (900, 900));
    // The first series' colour (the Trends palette's blue: ten seconds of X stator in a
    // one-minute window) and the straightness profile's red are drawn, and the light
    // theme's background fills most of the image: a real plot, not a blank or black page.
    let blue = crate::common::pixels_near(&image, [0x1f, 0x77, 0xb4]);
    assert!(blue > 100, "{blue} blue pixels");
    let red = crate::common::pixels_near(&image, [0xd6, 0x27, 0x28]);
    assert!(red > 500, "{red} red pixels");
    let light = crate::common::light_pixels(&image);
    assert!(light > 900 * 900 / 2, "{light} light pixels");
    let empty = vm::trends::build(&state("normal"), &TrendsSettings::default(), 1000);
    assert!(servosight::ui::export_png::render_trends(&empty, false, [100, 100]).is_err());
}

/// A discrepancy outcome as the job makes it, from a twin pair of `tests/discrepancy.rs`
/// (fixed file names so the snapshot does not carry temporary paths).
fn discrepancy_outcome(
    pair: &crate::discrepancy::Pair,
    target: &str,
) -> servosight::ui::sim_vs_real::DiscrepancyOutcome {
    use servosight::ui::sim_vs_real::{DiscrepancyOutcome, DiscrepancyRequest};
    let report = servosight::discrepancy::analyse(
        &pair.sim,
        &pair.real,
        target,
        &servosight::discrepancy::Options::default(),
    )
    .expect("the analysis runs");
    DiscrepancyOutcome::new(
        DiscrepancyRequest {
            sim: "sim.csv".into(),
            real: vec!["real.csv".into()],
            find_later_pieces: true,
            target: target.into(),
            average_s: None,
        },
        vec!["real.csv".into()],
        report,
    )
}

/// The sim-vs-real part of the Model lab: a consistent pair, a pair whose simulation omits
/// copper loss (findings and mismatch regions), the library's error, and a running analysis.
#[test]
fn discrepancy_view_models() {
    use crate::discrepancy::{Noise, case_for, make_pair};
    use servosight::sim::Effect;
    use servosight::ui::sim_vs_real::SharedColumns;
    // Few points per line keep the snapshots readable; the app draws 1500.
    const POINTS: usize = 24;
    let missing = case_for(Effect::CopperLoss, 4, Noise::White, 3.0);
    let missing_pair = make_pair(&missing);
    let consistent = crate::discrepancy::Case {
        omitted: Vec::new(),
        ..missing.clone()
    };
    let consistent_pair = make_pair(&consistent);
    // The real recording was recorded in three pieces.
    let columns = SharedColumns {
        sim: "sim.csv".into(),
        real: "real.csv".into(),
        find_later_pieces: true,
        real_pieces: ["real.csv", "real-0001.csv", "real-0002.csv"]
            .map(std::path::PathBuf::from)
            .to_vec(),
        columns: vec![missing.target.clone(), "X.torque_Nm".into()],
    };
    let mut s = state("normal");
    s.model_lab.discrepancy.columns = Some(columns);

    s.model_lab.discrepancy.result = Some(discrepancy_outcome(&missing_pair, &missing.target));
    s.model_lab.discrepancy.report_note =
        Some("report written to /tmp/copper.json and /tmp/copper.txt".into());
    let view = vm::discrepancy::build(&s, POINTS);
    let result = view.result.as_ref().expect("a result");
    assert!(result.missing_physics);
    assert_eq!(result.findings[0].physics, "copper_loss");
    assert!(!result.plots.regions.is_empty(), "regions to shade");
    assert!(result.plots.residual.points.len() <= POINTS);
    insta::assert_yaml_snapshot!("discrepancy_missing_physics", view);

    // A new result clears the notes of the last one's exports.
    s.model_lab.discrepancy.report_note = None;
    s.model_lab.discrepancy.result =
        Some(discrepancy_outcome(&consistent_pair, &consistent.target));
    let view = vm::discrepancy::build(&s, POINTS);
    let result = view.result.as_ref().expect("a result");
    assert!(!result.missing_physics);
    assert!(result.findings.is_empty());
    insta::assert_yaml_snapshot!("discrepancy_consistent", view);

    let error = servosight::discrepancy::analyse(
        &missing_pair.sim,
        &missing_pair.real,
        "ref.S.no_such_column_um",
        &servosight::discrepancy::Options::default(),
    )
    .expect_err("the target is missing");
    s.model_lab.discrepancy.result = None;
    s.model_lab.discrepancy.error = Some(error.to_string());
    let view = vm::discrepancy::build(&s, POINTS);
    assert!(
        view.error
            .as_deref()
            .is_some_and(|e| e.contains("ref.S.no_such_column_um"))
    );
    insta::assert_yaml_snapshot!("discrepancy_error", view);

    s.model_lab.discrepancy.error = None;
    s.model_lab.discrepancy.running = Some(JobProgress {
        stage: "reading the real recording (8192 rows)".into(),
        fraction: Some(0.3),
    });
    insta::assert_yaml_snapshot!("discrepancy_running", vm::discrepancy::build(&s, POINTS));
}
