//! The real widgets, driven through egui_kittest (no renderer): the compensation approval flow
//! on the embedded twin — a wrong credential is refused and writes nothing, the right one
//! writes and shows the read-back — plus the Trends and Events panels' controls.

use std::time::{Duration, Instant};

use egui_kittest::Harness;
use egui_kittest::kittest::Queryable;
use servosight::compensation::{
    AuditLog, CompensationId, CompensationLimits, Credentials, Outcome, Role as UserRole,
};
use servosight::estimators::pipeline::ElongationOrigin;
use servosight::link::{ConnectionState, ReplaySpeed};
use servosight::signal::AxisId;
use servosight::sim::{ScenarioKind, TwinConfig};
use servosight::ui::panels::Tab;
use servosight::ui::state::{PushFlow, StatusThresholds};
use servosight::ui::{HmiApp, HmiOptions, Session, SessionConfig, SourceSpec};

struct Fixture {
    _dir: tempfile::TempDir,
    audit_path: std::path::PathBuf,
    record_dir: std::path::PathBuf,
    harness: Harness<'static, HmiApp>,
}

fn twin_profile() -> servosight::profile::MachineProfile {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/assets/it25-twin.toml");
    servosight::profile::MachineProfile::load(std::path::Path::new(path)).expect("twin profile")
}

fn start() -> Fixture {
    let mut twin = TwinConfig::new(ScenarioKind::Production, None, 7);
    twin.rate_hz = 20.0;
    let source = SourceSpec::Twin {
        config: Box::new(twin),
        speed: ReplaySpeed::Factor(1.0),
    };
    start_on(
        tempfile::tempdir().expect("temp dir"),
        source,
        twin_profile(),
        16 << 20,
    )
}

fn start_on(
    dir: tempfile::TempDir,
    source: SourceSpec,
    profile: servosight::profile::MachineProfile,
    history_budget_bytes: usize,
) -> Fixture {
    let users_path = dir.path().join("users.toml");
    let audit_path = dir.path().join("audit.jsonl");
    let record_dir = dir.path().join("recordings");
    let mut credentials = Credentials::default();
    credentials
        .set_user("otto", UserRole::Operator, "otto-pw")
        .expect("hash");
    credentials
        .set_user("maria", UserRole::Approver, "maria-pw")
        .expect("hash");
    credentials.save(&users_path).expect("users file");
    let config = SessionConfig {
        source,
        record_dir: Some(record_dir.clone()),
        users_path: users_path.clone(),
        audit_path: audit_path.clone(),
        limits: CompensationLimits::default(),
        profile: Some(profile.clone()),
        data_dir: dir.path().join("data"),
    };
    let session = Session::start(config).expect("session starts");
    let app = HmiApp::new(
        session,
        HmiOptions {
            settings_path: None,
            history_budget_bytes,
            thresholds: StatusThresholds::default(),
            machine_record_dir: Some(record_dir.clone()),
            users_path,
            audit_path: audit_path.clone(),
            limits: CompensationLimits::default(),
            ingest_budget: Duration::from_millis(4),
        },
    );
    let harness = Harness::builder()
        .with_size([1400.0, 1000.0])
        .build_ui_state(
            |ui, app: &mut HmiApp| {
                let ctx = ui.ctx().clone();
                app.logic(&ctx);
                app.show(ui);
            },
            app,
        );
    Fixture {
        _dir: dir,
        audit_path,
        record_dir,
        harness,
    }
}

/// Steps the UI until `done` holds (the session answers on its own thread).
fn step_until(harness: &mut Harness<'static, HmiApp>, what: &str, done: impl Fn(&HmiApp) -> bool) {
    step_until_within(harness, what, 20, done);
}

fn step_until_within(
    harness: &mut Harness<'static, HmiApp>,
    what: &str,
    seconds: u64,
    done: impl Fn(&HmiApp) -> bool,
) {
    let deadline = Instant::now() + Duration::from_secs(seconds);
    loop {
        harness.step();
        if done(harness.state()) {
            return;
        }
        assert!(Instant::now() < deadline, "timed out waiting for {what}");
        std::thread::sleep(Duration::from_millis(20));
    }
}

fn type_into(harness: &mut Harness<'static, HmiApp>, label: &str, text: &str) {
    harness.get_by_label(label).focus();
    harness.step();
    harness.step();
    harness.get_by_label(label).type_text(text);
    harness.step();
}

/// Clicks a widget (through AccessKit, as assistive technology does, so a dialog that is still
/// settling its position cannot make the click miss) and lets three frames pass: the click's
/// frame carries out the command, the next lays out its result (a new dialog is measured
/// invisibly first), the third shows it.
fn click(harness: &mut Harness<'static, HmiApp>, label: &str) {
    harness.get_by_label(label).click_accesskit();
    settle(harness);
}

fn settle(harness: &mut Harness<'static, HmiApp>) {
    for _ in 0..3 {
        harness.step();
    }
}

/// True when some widget shows `text` (as its label or, for plain labels, its value).
fn shows(harness: &Harness<'static, HmiApp>, text: &str) -> bool {
    harness
        .query_all_by(|node| {
            node.label().is_some_and(|l| l.contains(text))
                || node.value().is_some_and(|v| v.contains(text))
        })
        .next()
        .is_some()
}

fn backlash_x(app: &HmiApp) -> Option<f64> {
    app.state
        .compensation
        .controller
        .as_ref()
        .and_then(|t| t.get(CompensationId::Backlash(AxisId::X)))
}

#[test]
fn approval_refuses_a_wrong_credential_and_writes_with_the_right_one() {
    let mut f = start();
    let h = &mut f.harness;
    step_until(h, "live data, users and the controller table", |app| {
        app.state.link.state == ConnectionState::Connected
            && app.state.compensation.controller.is_some()
            && !app.state.compensation.users.is_empty()
    });
    assert_eq!(backlash_x(h.state()), Some(0.0));

    click(h, "Compensation");
    assert_eq!(h.state().settings.tab, Tab::Compensation);
    // The first value in the list (backlash.X) is preselected.
    type_into(h, "New value [µm]", "4");
    click(h, "Add change");
    assert!(shows(h, "backlash.X = 4.0 µm"));
    type_into(h, "Why", "backlash grew at shift start");
    type_into(h, "Evidence", "backlash test on the twin");
    type_into(h, "Operator", "otto");
    click(h, "Request push");
    assert!(matches!(
        h.state().state.compensation.flow,
        PushFlow::AwaitingApproval { .. }
    ));
    assert!(shows(h, "Approve compensation push"));

    // Wrong password: refused, nothing written.
    type_into(h, "Approver", "maria");
    type_into(h, "Password", "not-her-password");
    click(h, "Approve and write");
    step_until(h, "the refusal", |app| {
        matches!(
            &app.state.compensation.flow,
            PushFlow::AwaitingApproval {
                refusal: Some(_),
                ..
            }
        )
    });
    h.step();
    assert!(
        shows(
            h,
            "Refused: not approved: unknown user or wrong password for `maria`"
        ),
        "the dialog shows the refusal"
    );
    h.get_by_label("Refresh").click();
    step_until(h, "the audit log after the refusal", |app| {
        !app.state.compensation.audit.is_empty()
    });
    assert_eq!(backlash_x(h.state()), Some(0.0), "nothing was written");

    // The right password: written, read back and shown.
    type_into(h, "Password", "maria-pw");
    click(h, "Approve and write");
    step_until(h, "the push result", |app| {
        matches!(app.state.compensation.flow, PushFlow::Finished(_))
    });
    let PushFlow::Finished(result) = &h.state().state.compensation.flow else {
        unreachable!("checked above");
    };
    assert!(result.verified, "{result:?}");
    assert_eq!(result.values[0].read_back_um, Some(4.0));
    step_until(h, "the new controller table", |app| {
        backlash_x(app) == Some(4.0)
    });
    h.step();
    assert!(
        shows(h, "read back and verified"),
        "the panel shows the verified read-back"
    );
    assert!(shows(h, "Roll back"));

    let entries = AuditLog::open(&f.audit_path)
        .expect("audit log")
        .entries()
        .expect("verified chain");
    let outcomes: Vec<Outcome> = entries.iter().map(|e| e.outcome).collect();
    assert_eq!(outcomes, vec![Outcome::Refused, Outcome::Applied]);
    assert_eq!(entries[1].approver.as_deref(), Some("maria"));

    // Roll back through the same dialog.
    click(h, "Close result");
    h.get_by_label_contains("Roll back").click();
    settle(h);
    assert!(matches!(
        h.state().state.compensation.flow,
        PushFlow::AwaitingApproval { .. }
    ));
    type_into(h, "Password", "maria-pw");
    click(h, "Approve and write");
    step_until(h, "the rollback", |app| {
        matches!(app.state.compensation.flow, PushFlow::Finished(_)) && backlash_x(app) == Some(0.0)
    });
    assert!(
        std::fs::read_dir(&f.record_dir)
            .expect("recordings")
            .next()
            .is_some(),
        "the session records to disk"
    );
}

/// Once the controller's table and the users are read, otto drafts backlash.X = 2.5 µm with
/// its why, ready to request.
fn draft_backlash_x(h: &mut Harness<'static, HmiApp>) {
    step_until(h, "the controller's table and the users", |app| {
        app.state.compensation.controller.is_some() && !app.state.compensation.users.is_empty()
    });
    click(h, "Compensation");
    type_into(h, "New value [µm]", "2.5");
    click(h, "Add change");
    type_into(h, "Why", "test");
    type_into(h, "Operator", "otto");
}

/// [`draft_backlash_x`], then the request: it waits for its approver.
fn request_a_push_of_backlash_x(h: &mut Harness<'static, HmiApp>) {
    draft_backlash_x(h);
    click(h, "Request push");
    assert!(matches!(
        h.state().state.compensation.flow,
        PushFlow::AwaitingApproval { .. }
    ));
}

#[test]
fn cancelling_the_dialog_writes_nothing_and_is_audited() {
    let mut f = start();
    let h = &mut f.harness;
    request_a_push_of_backlash_x(h);
    click(h, "Cancel request");
    assert!(matches!(h.state().state.compensation.flow, PushFlow::Idle));
    h.get_by_label("Refresh").click();
    step_until(h, "the withdrawal in the audit log", |app| {
        app.state.compensation.audit.len() == 1
    });
    assert_eq!(
        h.state().state.compensation.audit[0].outcome,
        Outcome::Refused
    );
    assert_eq!(backlash_x(h.state()), Some(0.0));
}

#[test]
fn an_operator_who_is_not_a_user_cannot_request() {
    let mut f = start();
    let h = &mut f.harness;
    step_until(h, "users", |app| {
        app.state.compensation.controller.is_some() && !app.state.compensation.users.is_empty()
    });
    click(h, "Compensation");
    type_into(h, "New value [µm]", "1");
    click(h, "Add change");
    type_into(h, "Why", "test");
    type_into(h, "Operator", "mallory");
    click(h, "Request push");
    assert!(matches!(h.state().state.compensation.flow, PushFlow::Idle));
    assert!(shows(h, "`mallory` is not a user"));
}

#[test]
fn trends_and_events_controls_work() {
    let mut f = start();
    let png = f._dir.path().join("shown.png");
    let h = &mut f.harness;
    step_until(h, "some history", |app| app.state.history.samples() > 5);
    // The estimators run on the live frames: the Overview shows their outputs.
    settle(h);
    assert!(shows(h, "nut temperature (estimated)"));
    assert!(shows(h, "elongation (estimated)"));
    click(h, "Trends");
    // The stator temperatures are drawn on first start; add the X load.
    let before = h.state().settings.trends.selected.len();
    assert!(before >= 2);
    click(h, "X load [%]");
    assert_eq!(h.state().settings.trends.selected.len(), before + 1);
    click(h, "1 h");
    assert_eq!(
        h.state().settings.trends.preset,
        servosight::ui::vm::trends::WindowPreset::Hour
    );
    click(h, "Export CSV");
    assert!(shows(h, "rows written to"));
    // The PNG is drawn on a job thread; the note says when it is written.
    h.state_mut().settings.forms.png_path = png.display().to_string();
    click(h, "Export PNG");
    let deadline = Instant::now() + Duration::from_secs(30);
    while !shows(h, "px PNG written to") {
        assert!(Instant::now() < deadline, "timed out waiting for the PNG");
        h.step();
        std::thread::sleep(Duration::from_millis(20));
    }
    let image = image::open(&png).expect("a PNG that decodes");
    assert_eq!(image.width(), 1600);

    click(h, "Events");
    assert!(shows(h, "embedded twin connected"));
    h.get_by_label_contains("link (").click();
    settle(h);
    assert!(!shows(h, "embedded twin connected"));
}

/// The Trends layout lives in the settings (egui would forget it at a restart): the picker's
/// width as it was left, its folded groups and the series switched off in a plot's legend.
#[test]
fn the_trends_layout_is_kept_in_the_settings() {
    let mut f = start();
    let h = &mut f.harness;
    // As restored from the settings file: the picker opens at the width it was left at.
    h.state_mut().settings.trends.picker_width = Some(300.0);
    step_until(h, "some history", |app| app.state.history.samples() > 5);
    click(h, "Trends");
    let width = h.state().settings.trends.picker_width.expect("a width");
    assert!((width - 300.0).abs() < 0.5, "the picker is {width} wide");

    click(h, "X axis");
    assert_eq!(
        h.state().settings.trends.groups_open.get("X axis"),
        Some(&false)
    );
    assert!(!shows(h, "X load [%]"), "the X group is folded");
    click(h, "X axis");
    assert_eq!(
        h.state().settings.trends.groups_open.get("X axis"),
        Some(&true)
    );

    // The drawn series's legend entry is the one right of the picker.
    let click_legend_entry = |h: &mut Harness<'static, HmiApp>| {
        let label = "X stator temperature [°C]";
        assert_eq!(
            h.query_all_by_label(label).count(),
            2,
            "a picker entry and a legend entry"
        );
        h.query_all_by_label(label)
            .max_by(|a, b| a.rect().min.x.total_cmp(&b.rect().min.x))
            .expect("two entries")
            .click();
        settle(h);
    };
    click_legend_entry(h);
    let trends = &h.state().settings.trends;
    assert!(trends.hidden.contains("X.stator_temp_C"), "{trends:?}");
    assert!(trends.selected.contains(&"X.stator_temp_C".to_string()));
    // Still in the legend, unticked: a second click brings it back.
    click_legend_entry(h);
    assert!(h.state().settings.trends.hidden.is_empty());
}

/// A DOE database from the twin, written as CSV v1.
fn database(dir: &std::path::Path, hours: f64) -> std::path::PathBuf {
    let path = dir.join("doe.csv");
    let recording = servosight::sim::simulate(TwinConfig::new(ScenarioKind::Doe, Some(hours), 1))
        .expect("the twin runs");
    servosight::signal::write_recording(&path, &recording).expect("database written");
    path
}

#[test]
fn the_model_lab_fits_off_the_ui_thread_and_shows_the_ranking() {
    let mut f = start();
    let data = database(f._dir.path(), 1.0);
    let h = &mut f.harness;
    click(h, "Model lab");
    type_into(h, "Database (CSV v1)", data.to_str().expect("utf-8 path"));
    type_into(h, "Target column", "ref.X.motor_flange_temp_C");
    type_into(h, "Terms", "X.stator_temp_C, X.speed_rpm, ambient_C");
    click(h, "Fit");
    step_until(h, "the fit", |app| {
        app.state.model_lab.result.is_some() || app.state.model_lab.error.is_some()
    });
    settle(h);
    let lab = &h.state().state.model_lab;
    assert_eq!(lab.error, None);
    let report = &lab.result.as_ref().expect("a result").report;
    assert_eq!(report.n, 3601, "0 s to 3600 s inclusive");
    // The same numbers as the library computes directly from the file.
    let recording = servosight::signal::read_recording(&data).expect("database reads");
    let terms =
        servosight::fit::parse_terms("X.stator_temp_C, X.speed_rpm, ambient_C").expect("terms");
    let design =
        servosight::fit::Design::from_recording(&recording, "ref.X.motor_flange_temp_C", &terms)
            .expect("design");
    let direct = servosight::fit::ols(&design).expect("fit");
    assert_eq!(report.r2, direct.r2);
    assert_eq!(report.coefficients, direct.coefficients);
    assert_eq!(report.sensitivity[0].rank, 1);
    assert!(shows(h, "Sensitivity ranking"));
    assert!(shows(h, &format!("n = {}", report.n)));
}

#[test]
fn a_cancelled_fit_stops_while_reading() {
    use servosight::ui::jobs::{FitRequest, JobContext, JobStop, run_fit};
    use std::sync::{Arc, atomic::AtomicBool};
    let dir = tempfile::tempdir().expect("temp dir");
    let data = database(dir.path(), 3.0);
    let request = FitRequest {
        data,
        target: "ref.X.motor_flange_temp_C".into(),
        terms: "X.stator_temp_C".into(),
    };
    let (tx, rx) = std::sync::mpsc::sync_channel(1024);
    let cancelled = JobContext::new(tx.clone(), Arc::new(AtomicBool::new(true)));
    assert_eq!(
        run_fit(request.clone(), &cancelled).err(),
        Some(JobStop::Cancelled)
    );
    let running = JobContext::new(tx, Arc::new(AtomicBool::new(false)));
    let outcome = run_fit(request, &running).expect("the fit runs");
    assert_eq!(outcome.report.n, 10_801, "0 s to 10800 s inclusive");
    let stages: Vec<String> = rx
        .try_iter()
        .filter_map(|m| match m {
            servosight::ui::jobs::JobMessage::Progress(p) => Some(p.stage),
            _ => None,
        })
        .collect();
    assert!(
        stages.iter().any(|s| s.starts_with("reading")),
        "{stages:?}"
    );
    assert!(
        stages.iter().any(|s| s.starts_with("fitting")),
        "{stages:?}"
    );
}

#[test]
fn the_hmi_command_reports_a_bad_source_before_opening_a_window() {
    use crate::common::{servosight, stderr};
    let output = servosight(&["--replay", "/nonexistent/day.csv"]);
    assert!(!output.status.success());
    let message = stderr(&output);
    assert_eq!(message.lines().count(), 1, "{message}");
    assert!(message.contains("/nonexistent/day.csv"), "{message}");
    let both = servosight(&["--replay", "a.csv", "--port", "/dev/null"]);
    assert!(!both.status.success());
    assert!(
        stderr(&both).contains("cannot be used with"),
        "{}",
        stderr(&both)
    );
    let with_subcommand = servosight(&["--speed", "2", "inspect", "a.csv"]);
    assert!(!with_subcommand.status.success());
}

#[test]
fn layout_and_theme_persist_and_a_broken_file_gives_defaults() {
    use servosight::ui::Settings;
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("config").join("hmi.json");
    assert_eq!(Settings::load(&path), Settings::default(), "no file yet");
    let mut settings = Settings {
        tab: Tab::Warmup,
        dark: false,
        window_size: Some([1200.0, 700.0]),
        window_pos: Some([40.0, 60.0]),
        ..Settings::default()
    };
    settings.forms.checklist_operator = "otto".into();
    settings.forms.workpiece_diameter_mm = "62.5".into();
    settings.forms.lab_section = servosight::ui::panels::LabSection::Discrepancy;
    settings.forms.disc_sim = "/data/sim.csv".into();
    settings.forms.disc_real = "/data/real.csv".into();
    settings.forms.disc_target = "S.stator_temp_C".into();
    settings.trends.selected = vec!["X.load_pct".into()];
    settings.forms.operator = "otto".into();
    settings.forms.password = "never saved".into();
    settings.save(&path).expect("saved");
    let text = std::fs::read_to_string(&path).expect("written");
    assert!(!text.contains("never saved"), "passwords are not persisted");
    let back = Settings::load(&path);
    assert_eq!(back.tab, Tab::Warmup);
    assert_eq!(back.window_pos, Some([40.0, 60.0]));
    assert_eq!(back.forms.checklist_operator, "otto");
    assert_eq!(back.forms.workpiece_diameter_mm, "62.5");
    assert_eq!(
        back.forms.lab_section,
        servosight::ui::panels::LabSection::Discrepancy
    );
    assert_eq!(back.forms.disc_sim, "/data/sim.csv");
    assert_eq!(back.forms.disc_real, "/data/real.csv");
    assert_eq!(back.forms.disc_target, "S.stator_temp_C");
    assert!(!back.dark);
    assert_eq!(back.window_size, Some([1200.0, 700.0]));
    assert_eq!(back.trends.selected, vec!["X.load_pct".to_string()]);
    assert_eq!(back.forms.operator, "otto");
    // A file from before the newer form fields keeps what it has.
    std::fs::write(&path, r#"{"tab": "Trends", "forms": {"operator": "otto"}}"#).expect("written");
    let old = Settings::load(&path);
    assert_eq!(old.tab, Tab::Trends);
    assert_eq!(old.forms.operator, "otto");
    std::fs::write(&path, "{ not json").expect("written");
    assert_eq!(Settings::load(&path), Settings::default());
}

/// Everything the settings persist comes back as it was saved: the tab, the theme, the window,
/// the Trends layout (preset, chosen and legend-hidden series, folded picker groups, picker
/// width), the Events filter and the forms. What is not persisted (passwords, the approver, the
/// typed event filter, a zoom into a past session's time range) comes back as the default.
#[test]
fn every_persisted_setting_round_trips() {
    use servosight::ui::Settings;
    use servosight::ui::vm::trends::WindowPreset;
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("hmi.json");
    let mut settings = Settings {
        tab: Tab::Trends,
        dark: false,
        window_size: Some([1024.0, 700.0]),
        window_pos: Some([12.0, 34.0]),
        ..Settings::default()
    };
    let trends = &mut settings.trends;
    trends.preset = WindowPreset::Shift;
    trends.selected = vec!["X.stator_temp_C".into(), "est.X.nut_temp_C".into()];
    trends.hidden.insert("est.X.nut_temp_C".into());
    trends
        .groups_open
        .insert("X reference instruments".into(), true);
    trends.groups_open.insert("S axis".into(), false);
    trends.picker_width = Some(312.5);
    settings.events.problems_only = true;
    settings.events.hidden.insert("link".into());
    settings.forms.operator = "otto".into();
    settings.forms.fit_terms = "X.stator_temp_C, ambient_C".into();
    settings.forms.lab_section = servosight::ui::panels::LabSection::Discrepancy;
    settings.save(&path).expect("saved");
    assert_eq!(Settings::load(&path), settings);

    // Session-only state is left behind.
    let mut session = settings.clone();
    session.forms.password = "secret".into();
    session.forms.approver = "maria".into();
    session.forms.event_text = "timeout".into();
    session.trends.follow_live = false;
    session.trends.view = Some((100.0, 160.0));
    session.save(&path).expect("saved");
    assert_eq!(Settings::load(&path), settings);
}

/// The operator's shift start as a recording: the warm-up scenario's friction-fingerprint
/// moves (125 s at 100 Hz), then the backlash test (500 Hz), then the machine standing with
/// its last sample held (1 Hz for two hours, so the replay stays live while the test works).
/// Returns the file and the machine time at which the backlash test ends.
fn shift_start_recording(dir: &std::path::Path) -> (std::path::PathBuf, f64) {
    use servosight::signal::Recording;
    let mut warm = TwinConfig::new(ScenarioKind::Warmup, Some(125.0 / 3600.0), 5);
    warm.rate_hz = 100.0;
    let warm = servosight::sim::simulate(warm).expect("the twin runs");
    let lash = servosight::sim::simulate(TwinConfig::new(ScenarioKind::BacklashTest, None, 5))
        .expect("the twin runs");
    assert_eq!(warm.names(), lash.names(), "both come from the same twin");
    let mut out = Recording::new("shift start", warm.names().to_vec()).expect("names");
    let mut row = Vec::new();
    for i in 0..warm.len() {
        warm.row_into(i, &mut row);
        out.push_row(&row).expect("row");
    }
    let offset = warm.time()[warm.len() - 1] + 0.01;
    for i in 0..lash.len() {
        lash.row_into(i, &mut row);
        row[0] += offset;
        out.push_row(&row).expect("row");
    }
    let lash_end = row[0];
    for k in 1..=7200 {
        row[0] = lash_end + f64::from(k);
        out.push_row(&row).expect("row");
    }
    let path = dir.join("shift-start.csv");
    servosight::signal::write_recording(&path, &out).expect("written");
    (path, lash_end)
}

#[test]
fn the_warmup_checklist_is_driven_to_sign_off_and_saved() {
    use servosight::link::ReplayOptions;
    use servosight::ui::vm::warmup::{StepStatus, WarmupReport};

    let dir = tempfile::tempdir().expect("temp dir");
    let (recording, lash_end) = shift_start_recording(dir.path());
    let mut profile = twin_profile();
    // One minute of held samples after the test is enough to judge the rates here.
    profile.warmup.settle_window_min = 1.0;
    let source = SourceSpec::Replay {
        pieces: vec![recording],
        options: ReplayOptions {
            speed: ReplaySpeed::Factor(25.0),
            paused: false,
            // The held tail comes once a second of machine time; it is live all the same.
            stale_after: Duration::from_secs(3600),
        },
    };
    let data_dir = dir.path().join("data");
    let mut f = start_on(dir, source, profile, 192 << 20);
    let h = &mut f.harness;
    click(h, "Warm-up");
    assert!(shows(h, "1. Temperatures settled"));
    assert!(shows(h, "not analysed yet"));
    step_until_within(h, "the backlash test and a minute after it", 90, |app| {
        app.state
            .history
            .newest_time_s()
            .is_some_and(|t| t > lash_end + 65.0)
    });

    click(h, "Analyse warm-up moves");
    step_until_within(h, "the warm-up analysis", 180, |app| {
        app.state.warmup.analysis.is_some() || app.state.warmup.analysis_error.is_some()
    });
    settle(h);
    let state = &h.state().state;
    assert_eq!(state.warmup.analysis_error, None);
    let analysis = state.warmup.analysis.clone().expect("analysed");
    let fingerprint = analysis.fingerprint.as_ref().expect("fingerprint taken");
    assert!(fingerprint.coherence > 0.5, "{fingerprint:?}");
    let backlash = analysis.backlash.as_ref().expect("backlash measured");
    // The twin's X axis has 12 µm of backlash.
    assert!((backlash.backlash_um - 12.0).abs() < 2.0, "{backlash:?}");
    assert!(shows(h, "no baseline for X yet"));

    // A healthy machine: keep this fingerprint as the baseline; the step then passes.
    click(h, "Save as baseline");
    step_until(h, "the baseline", |app| {
        app.state.warmup.baselines.contains_key(&AxisId::X)
    });
    settle(h);
    let view = servosight::ui::vm::warmup::build(&h.state().state);
    assert_eq!(
        view.steps[1].status,
        StepStatus::Pass,
        "{:?}",
        view.steps[1]
    );
    assert!(data_dir.join("baselines/X-fingerprint.json").is_file());

    click(h, "Tool measured");
    step_until(h, "the tool calibration reset", |app| {
        matches!(
            app.state.elongation_origins.get(&AxisId::S),
            Some(Some(ElongationOrigin::ToolMeasured { .. }))
        )
    });

    // Signing off needs a name.
    click(h, "Sign off and save report");
    assert!(shows(h, "enter your name"));
    type_into(h, "Signed off by", "otto");
    click(h, "Sign off and save report");
    step_until(h, "the saved report", |app| {
        app.state.warmup.signed.is_some()
    });
    settle(h);
    assert!(shows(h, "Signed off by otto"));
    let saved = h.state().state.warmup.signed.clone().expect("saved");
    let report: WarmupReport =
        serde_json::from_str(&std::fs::read_to_string(&saved.json_path).expect("JSON report"))
            .expect("the report parses");
    assert_eq!(report.signed_off_by, "otto");
    assert_eq!(report.steps.len(), 5);
    assert!(report.steps.iter().all(|s| s.status != StepStatus::Pending));
    assert_eq!(report.steps[1].status, StepStatus::Pass);
    let backlash_step = &report.steps[2];
    assert!(
        backlash_step
            .values
            .iter()
            .any(|v| v.label == "backlash" && v.value == format!("{:.1}", backlash.backlash_um)),
        "{backlash_step:?}"
    );
    assert!(std::path::Path::new(&saved.json_path).starts_with(data_dir.join("warmup")));
    let text = std::fs::read_to_string(&saved.text_path).expect("text report");
    assert!(text.contains("Signed off by:  otto"), "{text}");
    assert!(text.contains("3. Backlash measured"), "{text}");
}

#[test]
fn an_estimate_proposal_goes_through_approval_and_is_written() {
    // The twin at 300× real time: the spindle's shift-start warm-up grows it within seconds.
    let mut twin = TwinConfig::new(ScenarioKind::Production, None, 7);
    twin.rate_hz = 2.0;
    let source = SourceSpec::Twin {
        config: Box::new(twin),
        speed: ReplaySpeed::Factor(300.0),
    };
    let mut f = start_on(
        tempfile::tempdir().expect("temp dir"),
        source,
        twin_profile(),
        16 << 20,
    );
    let h = &mut f.harness;
    step_until_within(h, "a spindle elongation worth compensating", 60, |app| {
        app.state.compensation.controller.is_some()
            && !app.state.compensation.users.is_empty()
            // The twin starts at rest: its elongation counts from a known tool length.
            && app
                .state
                .elongation_origin(AxisId::S)
                .is_some_and(|o| o.is_known())
            && app
                .state
                .latest
                .get("est.S.elongation_um")
                .is_some_and(|e| e.abs() >= 1.0)
    });
    click(h, "Compensation");
    assert!(shows(h, "Proposed from the estimates"));
    click(h, "Use thermal_offset.S");
    let id = CompensationId::ThermalOffset(AxisId::S);
    let proposed = h
        .state()
        .state
        .compensation
        .draft_changes
        .get(id)
        .expect("the proposal is in the draft");
    // The twin keeps running at 300× while the test clicks (on a loaded machine, minutes of
    // machine time pass), so the value taken is the live estimate at the click, not the one
    // waited for: it only has to be a real, nonzero proposal.
    // (For the same reason the row's "in the proposal" mark is not checked: it clears as soon as
    // the live estimate moves on from the value taken.)
    assert!(proposed.is_finite() && proposed != 0.0, "{proposed}");
    assert!(
        h.state()
            .settings
            .forms
            .evidence
            .contains("estimated S thermal elongation")
    );
    // Nothing is written yet: the request and the approver's credential come first.
    let written = |app: &HmiApp| {
        app.state
            .compensation
            .controller
            .as_ref()
            .and_then(|t| t.get(id))
    };
    assert_eq!(written(h.state()), Some(0.0));
    type_into(h, "Operator", "otto");
    click(h, "Request push");
    assert!(shows(h, "Approve compensation push"));
    type_into(h, "Approver", "maria");
    type_into(h, "Password", "maria-pw");
    click(h, "Approve and write");
    step_until(h, "the push", |app| {
        matches!(app.state.compensation.flow, PushFlow::Finished(_))
    });
    let PushFlow::Finished(result) = &h.state().state.compensation.flow else {
        unreachable!("checked above");
    };
    assert!(result.verified, "{result:?}");
    assert_eq!(result.values[0].read_back_um, Some(proposed));
}

/// A concealed-effect pair of `tests/discrepancy.rs` (the simulation omits copper loss),
/// written as CSV v1 files; returns the paths and the target.
fn discrepancy_files(dir: &std::path::Path) -> (std::path::PathBuf, std::path::PathBuf, String) {
    use crate::discrepancy::{Noise, case_for, make_pair};
    let case = case_for(servosight::sim::Effect::CopperLoss, 4, Noise::White, 3.0);
    let pair = make_pair(&case);
    let sim = dir.join("sim.csv");
    let real = dir.join("real.csv");
    servosight::signal::write_recording(&sim, &pair.sim).expect("sim written");
    servosight::signal::write_recording(&real, &pair.real).expect("real written");
    (sim, real, case.target)
}

/// Opens the Model lab's sim-vs-real section and types the two files' paths.
fn open_sim_vs_real(
    h: &mut Harness<'static, HmiApp>,
    sim: &std::path::Path,
    real: &std::path::Path,
) {
    click(h, "Model lab");
    click(h, "Sim vs real");
    type_into(h, "Simulation (CSV v1)", sim.to_str().expect("utf-8 path"));
    type_into(
        h,
        "Real recording (CSV v1)",
        real.to_str().expect("utf-8 path"),
    );
}

/// `real` cut at a third and two thirds of its time into the pieces a recorder would have
/// written in `dir`: `shift.csv`, `shift-0001.csv`, `shift-0002.csv`.
fn recorded_in_pieces(real: &std::path::Path, dir: &std::path::Path) -> Vec<std::path::PathBuf> {
    let time = servosight::signal::read_recording(real)
        .expect("real reads")
        .time()
        .to_vec();
    let end = time.last().copied().unwrap_or(0.0);
    let cuts = [f64::NEG_INFINITY, end / 3.0, 2.0 * end / 3.0, f64::INFINITY];
    std::fs::create_dir_all(dir).expect("pieces directory");
    (0..3u32)
        .map(|k| {
            let path = servosight::signal::piece_path(&dir.join("shift.csv"), k);
            crate::common::rows_between(real, &path, cuts[k as usize], cuts[k as usize + 1]);
            path
        })
        .collect()
}

/// A real recording the recorder cut into pieces is analysed in the Model lab as one: the
/// header job finds the pieces beside the chosen file and the panel says so; the analysis
/// reads them after it and reports what the whole file gives. "this file only" reads the
/// chosen file alone, and a piece with other columns is refused with its file named.
#[test]
fn the_model_lab_reads_a_real_recording_in_the_pieces_the_recorder_cut_it_into() {
    use servosight::ui::jobs::{JobContext, JobStop};
    use servosight::ui::sim_vs_real::{DiscrepancyRequest, read_shared_columns, run_discrepancy};
    use std::sync::{Arc, atomic::AtomicBool};
    let mut f = start();
    let (sim, real, target) = discrepancy_files(f._dir.path());
    let pieces = recorded_in_pieces(&real, &f._dir.path().join("recorded"));
    let h = &mut f.harness;
    open_sim_vs_real(h, &sim, &pieces[0]);
    let columns_read = |app: &HmiApp| {
        let d = &app.state.model_lab.discrepancy;
        d.columns.is_some() || d.columns_error.is_some()
    };
    step_until(h, "the shared columns", columns_read);
    settle(h);
    let said = format!(
        "read as one with the pieces the recorder continued it in: {} … {} (2 pieces)",
        pieces[1].display(),
        pieces[2].display()
    );
    let view = servosight::ui::vm::discrepancy::build(&h.state().state, 100);
    assert_eq!(view.real_pieces.as_deref(), Some(said.as_str()));
    assert!(view.shared_columns.contains(&target));
    assert!(shows(h, "read as one with the pieces"));
    click(h, "this file only");
    step_until(h, "the first piece's columns", |app| {
        app.state
            .model_lab
            .discrepancy
            .columns
            .as_ref()
            .is_some_and(|c| c.real_pieces.len() == 1)
    });
    settle(h);
    assert!(!shows(h, "read as one with the pieces"));

    let (tx, _rx) = std::sync::mpsc::sync_channel(1 << 16);
    let context = JobContext::new(tx, Arc::new(AtomicBool::new(false)));
    let analyse = |real: &std::path::Path, find_later_pieces: bool| {
        let request = DiscrepancyRequest {
            sim: sim.clone(),
            real: vec![real.to_path_buf()],
            find_later_pieces,
            target: target.clone(),
            average_s: None,
        };
        run_discrepancy(request, &context).expect("the analysis runs")
    };
    let whole = analyse(&real, false);
    let in_pieces = analyse(&pieces[0], true);
    assert_eq!(in_pieces.real_read, pieces);
    let json = |o: &servosight::ui::sim_vs_real::DiscrepancyOutcome| {
        serde_json::to_value(&o.report).expect("the report serialises")
    };
    assert_eq!(json(&in_pieces), json(&whole));
    let first_only = analyse(&pieces[0], false);
    assert_eq!(first_only.real_read, &pieces[..1]);
    assert!(
        first_only.report.rows * 2 < whole.report.rows,
        "{} rows of the first piece against {}",
        first_only.report.rows,
        whole.report.rows
    );

    let text = std::fs::read_to_string(&pieces[2])
        .expect("the last piece")
        .replacen("ambient_C", "room_C", 1);
    std::fs::write(&pieces[2], text).expect("the last piece rewritten");
    let (tx, _rx) = std::sync::mpsc::sync_channel(16);
    let context = JobContext::new(tx, Arc::new(AtomicBool::new(false)));
    match read_shared_columns(sim.clone(), pieces[0].clone(), true, &context) {
        Err(JobStop::Failed(message)) => assert!(
            message.contains(&format!(
                "{}: its columns are not those of {}",
                pieces[2].display(),
                pieces[0].display()
            )),
            "{message}"
        ),
        other => panic!("expected the piece refused, got {other:?}"),
    }
}

#[test]
fn the_model_lab_runs_sim_vs_real_off_the_ui_thread_and_shows_the_missing_physics() {
    let mut f = start();
    let (sim, real, target) = discrepancy_files(f._dir.path());
    let h = &mut f.harness;
    open_sim_vs_real(h, &sim, &real);
    // The headers are read on a job; the columns both files share are offered.
    step_until(h, "the shared columns", |app| {
        app.state.model_lab.discrepancy.columns.is_some()
            || app.state.model_lab.discrepancy.columns_error.is_some()
    });
    let offered = servosight::ui::vm::discrepancy::build(&h.state().state, 100).shared_columns;
    assert!(offered.contains(&target), "{offered:?}");
    assert!(!offered.iter().any(|c| c == "time_s"));
    type_into(h, "Compared column", &target);

    // A block length that is no length of time is refused before any job starts.
    type_into(h, "Average over (s)", "-5");
    click(h, "Analyse");
    let lab = &h.state().state.model_lab.discrepancy;
    assert!(lab.running.is_none());
    let error = lab.error.clone().unwrap_or_default();
    assert!(
        error.contains("`-5` is not a positive number of seconds"),
        "{error}"
    );
    assert!(shows(h, "not a positive number of seconds"));
    h.state_mut().settings.forms.disc_average_s.clear();

    // Cancel frees the panel at once (the analysis stops at its next stopping point).
    click(h, "Analyse");
    assert!(h.state().state.model_lab.discrepancy.running.is_some());
    click(h, "Cancel");
    let lab = &h.state().state.model_lab.discrepancy;
    assert!(lab.running.is_none());
    assert_eq!(lab.error.as_deref(), Some("cancelled"));
    assert!(shows(h, "Analyse"));

    click(h, "Analyse");
    step_until_within(h, "the analysis", 120, |app| {
        let d = &app.state.model_lab.discrepancy;
        d.result.is_some() || d.error.is_some()
    });
    settle(h);
    let lab = &h.state().state.model_lab.discrepancy;
    assert_eq!(lab.error, None);
    let report = &lab.result.as_ref().expect("a result").report;
    assert_eq!(report.findings[0].physics, "copper_loss");
    let view = servosight::ui::vm::discrepancy::build(&h.state().state, 1500);
    let result = view.result.expect("a result view");
    assert!(
        !result.plots.regions.is_empty(),
        "mismatch regions to shade"
    );
    assert_eq!(result.plots.regions.len(), report.mismatch_regions.len());
    assert!(shows(h, "copper_loss"));
    assert!(shows(h, "missing physics"));
    assert!(shows(h, "after: sim + corrections (held out)"));
    assert!(shows(h, "I²R"), "the finding's explanation is shown");

    // The result drawn into a PNG on a job, as `servosight discrepancy --plot` draws it.
    let png = f._dir.path().join("sim-vs-real.png");
    assert!(shows(h, "Figure (PNG)"));
    h.state_mut().settings.forms.disc_png_path = png.display().to_string();
    click(h, "Export PNG");
    step_until(h, "the PNG export", |app| {
        app.state
            .model_lab
            .discrepancy
            .png_note
            .as_deref()
            .is_some_and(|note| !note.contains("drawing") && !note.starts_with("PNG export: "))
    });
    settle(h);
    let note = h.state().state.model_lab.discrepancy.png_note.clone();
    assert!(
        note.as_deref()
            .is_some_and(|n| n.contains("PNG written to")),
        "{note:?}"
    );
    assert!(shows(h, "PNG written to"));
    let image = image::open(&png).expect("a PNG that decodes").to_rgba8();
    assert_eq!(image.width(), 1400);
    assert!(image.height() > 600, "{} px tall", image.height());

    // A report that cannot be written says where and why.
    assert!(shows(h, "Report (JSON)"));
    let nowhere = f._dir.path().join("no-such-dir").join("r.json");
    let note = save_discrepancy_report(h, &nowhere);
    assert!(note.starts_with("the report was not saved"), "{note}");
    assert!(shows(h, "no-such-dir"));

    // The report saved on a job is the command's: its JSON contract and its printed text.
    let json = f._dir.path().join("sim-vs-real.json");
    let text = f._dir.path().join("sim-vs-real.txt");
    let note = save_discrepancy_report(h, &json);
    assert_eq!(
        note,
        format!(
            "report written to {} and {}",
            json.display(),
            text.display()
        )
    );
    assert!(shows(h, "report written to"));
    // The command on the same files, its JSON to a file and its text to stdout.
    let cli_json = f._dir.path().join("cli.json");
    let cli = crate::common::servosight(&[
        "discrepancy",
        "--sim",
        sim.to_str().expect("utf-8 path"),
        "--real",
        real.to_str().expect("utf-8 path"),
        "--target",
        &target,
        "--json",
        cli_json.to_str().expect("utf-8 path"),
    ]);
    assert!(cli.status.success());
    let parsed = |path: &std::path::Path| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(path).expect("a JSON report"))
            .expect("JSON that parses")
    };
    assert_eq!(parsed(&json), parsed(&cli_json));
    assert_eq!(
        std::fs::read_to_string(&text).expect("saved text"),
        String::from_utf8_lossy(&cli.stdout)
    );
}

/// Saves the Model lab's sim-vs-real report to `json` with its button and returns the note
/// the save ends with.
fn save_discrepancy_report(h: &mut Harness<'static, HmiApp>, json: &std::path::Path) -> String {
    h.state_mut().settings.forms.disc_report_path = json.display().to_string();
    click(h, "Save report");
    step_until(h, "the report's save", |app| {
        app.state
            .model_lab
            .discrepancy
            .report_note
            .as_deref()
            .is_some_and(|note| note != "writing the report…")
    });
    settle(h);
    let lab = &h.state().state.model_lab.discrepancy;
    lab.report_note.clone().unwrap_or_default()
}

#[test]
fn a_missing_file_shows_the_error_in_the_model_lab() {
    let mut f = start();
    let missing = f._dir.path().join("no-such-sim.csv");
    let h = &mut f.harness;
    click(h, "Model lab");
    click(h, "Sim vs real");
    type_into(
        h,
        "Simulation (CSV v1)",
        missing.to_str().expect("utf-8 path"),
    );
    type_into(
        h,
        "Real recording (CSV v1)",
        missing.to_str().expect("utf-8 path"),
    );
    // The headers are read on a job; when it ends, its error line appears above the Analyse
    // button and shifts the button's id. A click sent in the frame before that lands on the old
    // id and is lost (this test then hung), so wait for the headers first.
    step_until(h, "the headers' error", |app| {
        app.state.model_lab.discrepancy.columns_error.is_some()
    });
    type_into(h, "Compared column", "S.stator_temp_C");
    click(h, "Analyse");
    step_until(h, "the error", |app| {
        app.state.model_lab.discrepancy.error.is_some()
    });
    settle(h);
    let error = h
        .state()
        .state
        .model_lab
        .discrepancy
        .error
        .clone()
        .expect("an error");
    assert!(error.contains("no-such-sim.csv"), "{error}");
    assert!(shows(h, "no-such-sim.csv"));
    assert!(shows(h, "Analyse"), "the panel is free again");
}

/// Bad input comes back as the library's own message: a target missing from a file and two
/// recordings that do not overlap in time.
#[test]
fn the_discrepancy_job_reports_the_librarys_errors() {
    use servosight::ui::jobs::{JobContext, JobStop};
    use servosight::ui::sim_vs_real::{DiscrepancyRequest, run_discrepancy};
    use std::sync::{Arc, atomic::AtomicBool};
    let dir = tempfile::tempdir().expect("temp dir");
    let (sim, real, target) = discrepancy_files(dir.path());
    let (tx, rx) = std::sync::mpsc::sync_channel(1024);
    let context = JobContext::new(tx, Arc::new(AtomicBool::new(false)));
    // The job's failure message for `sim` against `real` on `target`.
    let failure = |sim: &std::path::Path, real: &std::path::Path, target: &str| {
        let request = DiscrepancyRequest {
            sim: sim.to_path_buf(),
            real: vec![real.to_path_buf()],
            find_later_pieces: true,
            target: target.into(),
            average_s: None,
        };
        match run_discrepancy(request, &context).err() {
            Some(JobStop::Failed(message)) => message,
            other => panic!("expected a failure, got {other:?}"),
        }
    };
    let message = failure(&sim, &real, "ref.S.no_such_column_um");
    assert!(
        message.contains("ref.S.no_such_column_um") && message.contains("not a column"),
        "{message}"
    );
    // The same real recording shifted a day later: no overlap.
    let recording = servosight::signal::read_recording(&real).expect("real reads");
    let mut later = servosight::signal::Recording::with_schema("later", recording.schema().clone());
    let mut row = Vec::new();
    for i in 0..recording.len() {
        recording.row_into(i, &mut row);
        row[0] += 86_400.0;
        later.push_row(&row).expect("row");
    }
    let later_path = dir.path().join("later.csv");
    servosight::signal::write_recording(&later_path, &later).expect("written");
    let message = failure(&sim, &later_path, &target);
    assert!(message.contains("do not overlap in time"), "{message}");
    let stages: Vec<String> = rx
        .try_iter()
        .filter_map(|m| match m {
            servosight::ui::jobs::JobMessage::Progress(p) => Some(p.stage),
            _ => None,
        })
        .collect();
    for phase in [
        "reading the simulation",
        "reading the real recording",
        "analysing",
    ] {
        assert!(stages.iter().any(|s| s.starts_with(phase)), "{stages:?}");
    }
}

/// A recording longer than the analysis takes is refused while it is read, before it fills the
/// memory the HMI shares with the live machine's history, with the advice to average it; read
/// averaged over blocks of time (the panel's "Average over (s)"), the same file is analysed,
/// and the job says it averages while it reads and the report says it was read averaged.
#[test]
fn the_discrepancy_job_refuses_a_recording_too_long_or_reads_it_averaged() {
    use servosight::ui::jobs::{JobContext, JobMessage, JobStop};
    use servosight::ui::sim_vs_real::{DiscrepancyRequest, run_discrepancy};
    use std::sync::{Arc, atomic::AtomicBool};
    let dir = tempfile::tempdir().expect("temp dir");
    let limit = servosight::discrepancy::MAX_ROWS;
    let (long, real) = (dir.path().join("long.csv"), dir.path().join("real.csv"));
    // One row past the limit at 1 kHz, and the real stator at 1 Hz, a tenth of a kelvin off.
    crate::discrepancy::warming_stator_csv(&long, limit + 1, 0.001, 0.0);
    crate::discrepancy::warming_stator_csv(&real, limit / 1000 + 1, 1.0, 0.1);
    let (tx, rx) = std::sync::mpsc::sync_channel(1 << 16);
    let context = JobContext::new(tx, Arc::new(AtomicBool::new(false)));
    let request = |average_s| DiscrepancyRequest {
        sim: long.clone(),
        real: vec![real.clone()],
        find_later_pieces: false,
        target: "S.stator_temp_C".into(),
        average_s,
    };
    let stages = || -> Vec<String> {
        rx.try_iter()
            .filter_map(|m| match m {
                JobMessage::Progress(p) => Some(p.stage),
                _ => None,
            })
            .collect()
    };
    let message = match run_discrepancy(request(None), &context) {
        Err(JobStop::Failed(message)) => message,
        other => panic!("expected a failure, got {other:?}"),
    };
    // The job takes fewer rows than the fixed limit where the memory free now would not hold
    // the analysis (a machine with less than about 9 GB free): read the budget it stated.
    let budget = rows_refused_past(&message);
    assert!(budget <= limit, "{message}");
    assert!(
        message.contains(&format!(
            "long.csv: line {}: more than {budget} rows",
            budget + 2
        )) && message.contains("rows of each recording")
            && message.contains("Average over"),
        "{message}"
    );
    assert!(
        stages()
            .iter()
            .any(|s| s.starts_with("reading the simulation (")),
        "the read reports its rows"
    );
    // Blocks too short to bring it under the limit: refused, advised to lengthen them.
    let message = match run_discrepancy(request(Some(0.0005)), &context) {
        Err(JobStop::Failed(message)) => message,
        other => panic!("expected a failure, got {other:?}"),
    };
    let budget = rows_refused_past(&message);
    assert!(
        message.contains(&format!(
            "more than {budget} rows averaged over 0.0005 s blocks"
        )) && message.contains("longer blocks"),
        "{message}"
    );
    stages();
    let outcome = run_discrepancy(request(Some(1.0)), &context).expect("analysed averaged");
    let note = &outcome.report.alignment.note;
    assert!(
        note.starts_with(
            "read averaged (the simulation over 1 s blocks, the real recording over 1 s blocks)"
        ),
        "{note}"
    );
    assert_eq!(outcome.report.rows, limit / 1000, "{note}");
    let seen = stages();
    assert!(
        seen.iter().any(
            |s| s.starts_with("reading the simulation (") && s.ends_with("averaging over 1 s)")
        ),
        "{seen:?}"
    );
}

/// The row count in a refusal's "more than N rows".
fn rows_refused_past(message: &str) -> usize {
    message
        .split("more than ")
        .nth(1)
        .and_then(|rest| rest.split(' ').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no row count in {message}"))
}

/// The Model lab's job reports the analysis's own progress (between reading the files and
/// preparing the plots), and a cancel stops the analysis itself: the job ends `Cancelled`
/// without finishing it.
#[test]
fn cancelling_the_discrepancy_job_stops_the_analysis() {
    use servosight::ui::jobs::{JobContext, JobMessage, JobStop};
    use servosight::ui::sim_vs_real::{DiscrepancyRequest, run_discrepancy};
    use std::sync::atomic::{AtomicBool, Ordering};
    use std::sync::{Arc, mpsc};
    let dir = tempfile::tempdir().expect("temp dir");
    let (sim, real, target) = discrepancy_files(dir.path());
    let (tx, rx) = mpsc::sync_channel(4096);
    let cancel = Arc::new(AtomicBool::new(false));
    let context = JobContext::new(tx, Arc::clone(&cancel));
    // The operator presses Cancel once the selection has started.
    let operator = std::thread::spawn(move || {
        let mut seen = Vec::new();
        for message in rx {
            if let JobMessage::Progress(p) = message {
                if p.stage.starts_with("analysing: selection step 1") {
                    cancel.store(true, Ordering::Relaxed);
                }
                seen.push((p.stage, p.fraction));
            }
        }
        seen
    });
    let request = DiscrepancyRequest {
        sim,
        real: vec![real],
        find_later_pieces: false,
        target,
        average_s: None,
    };
    let outcome = run_discrepancy(request, &context);
    drop(context);
    let seen = operator.join().expect("the operator thread");
    assert!(
        matches!(outcome, Err(JobStop::Cancelled)),
        "{:?}",
        outcome.map(|o| o.report.summary())
    );
    let within: Vec<f32> = seen
        .iter()
        .filter(|(stage, _)| stage.starts_with("analysing: "))
        .filter_map(|(_, f)| *f)
        .collect();
    assert!(
        within.iter().any(|f| *f > 0.45) && within.iter().all(|f| (0.4..=0.95).contains(f)),
        "the bar moves within the analysis: {seen:?}"
    );
    assert!(
        !seen
            .iter()
            .any(|(stage, _)| stage.contains("refitting on all rows")
                || stage.starts_with("preparing the plots")),
        "the analysis did not run on: {seen:?}"
    );
}

/// A small recording of the twin (1 h at 1 Hz), and the same cut into the three pieces a
/// recorder would have written in `dir/shift`.
fn hour_in_pieces(dir: &std::path::Path) -> Vec<std::path::PathBuf> {
    let mut day = TwinConfig::new(ScenarioKind::Production, Some(1.0), 3);
    day.rate_hz = 1.0;
    let day = servosight::sim::simulate(day).expect("the twin runs");
    let whole = dir.join("day.csv");
    servosight::signal::write_recording(&whole, &day).expect("written");
    recorded_in_pieces(&whole, &dir.join("shift"))
}

fn recordings_in(dir: &std::path::Path) -> usize {
    std::fs::read_dir(dir).map_or(0, |entries| entries.count())
}

/// The Source window opens a recording in place of the running twin: a mistyped path is
/// refused with the file named while the twin runs on; a recording the recorder cut into
/// pieces is replayed as one, with the running profile's estimators, its own columns on the
/// Trends panel and the events saying what runs, and is not recorded again; paused it sends
/// nothing, and it runs at the speed set; the way back starts the twin again (recorded).
#[test]
fn the_source_window_opens_a_recording_and_goes_back_to_the_twin() {
    let mut f = start();
    let pieces = hour_in_pieces(f._dir.path());
    let h = &mut f.harness;
    step_until(h, "the twin's frames", |app| app.state.link.frames > 10);
    assert_eq!(recordings_in(&f.record_dir), 1, "the twin is recorded");
    let twin_source = h.state().state.link.source.clone();

    click(h, "Source…");
    let missing = f._dir.path().join("shfit.csv");
    type_into(h, "Recording (CSV)", missing.to_str().expect("utf-8 path"));
    click(h, "Open");
    step_until(h, "the refusal", |app| app.state.source.error.is_some());
    let error = h.state().state.source.error.clone().unwrap_or_default();
    assert!(error.contains("shfit.csv"), "{error}");
    assert!(shows(h, "shfit.csv"), "the window shows why");
    let frames = h.state().state.link.frames;
    step_until(h, "the twin running on", |app| {
        app.state.link.frames > frames + 5 && app.state.link.source == twin_source
    });

    let first = pieces[0].to_str().expect("utf-8 path").to_string();
    h.state_mut().settings.forms.open_recording = first;
    type_into(h, "Speed (× real time)", "600");
    click(h, "Open");
    step_until(h, "the recording's frames", |app| {
        app.state.source.start_source_label.is_some() && !app.state.latest.row.is_empty()
    });
    let app = h.state();
    assert_ne!(app.state.link.source, twin_source);
    let change = app.state.source.last_change.clone().unwrap_or_default();
    assert!(
        change.contains("(3 pieces)") && change.contains("600 × real time"),
        "{change}"
    );
    assert!(change.contains("the estimators of profile"), "{change}");
    assert!(change.contains("not recorded again"), "{change}");
    assert!(
        shows(h, "embedded twin is not running"),
        "the status bar says so"
    );
    assert!(
        app.state.events.iter().any(|e| e.message == change),
        "the events say what runs"
    );
    // The recording's time, not the twin's, and the estimates beside its columns.
    assert!(app.state.latest.names.iter().any(|n| n.starts_with("est.")));
    assert!(
        app.settings
            .trends
            .selected
            .iter()
            .any(|n| app.state.latest.names.contains(n)),
        "the Trends panel draws the recording's columns"
    );
    // Paused, the replay stops where it is; resumed at twice the speed it goes on.
    click(h, "Pause");
    std::thread::sleep(Duration::from_millis(300));
    settle(h);
    let held = h.state().state.latest.time_s();
    for _ in 0..10 {
        std::thread::sleep(Duration::from_millis(50));
        h.step();
    }
    assert_eq!(
        h.state().state.latest.time_s(),
        held,
        "a paused replay sends nothing"
    );
    assert!(shows(h, "600 × real time, paused"));
    // Slowed to 2 ×, a second of wall clock moves the machine time by seconds, not minutes.
    type_into(h, "Running speed (× real time)", "2");
    click(h, "Set speed");
    click(h, "Resume");
    assert!(shows(h, "now 2 × real time"));
    let before = h.state().state.latest.time_s().unwrap_or_default();
    for _ in 0..20 {
        std::thread::sleep(Duration::from_millis(50));
        h.step();
    }
    let moved = h.state().state.latest.time_s().unwrap_or_default() - before;
    assert!(
        moved < 30.0,
        "at 2 × the replay moved {moved} s in a second"
    );
    h.state_mut().settings.forms.running_speed = "1200".into();
    click(h, "Set speed");
    assert!(shows(h, "now 1200 × real time"));
    // The whole recording is replayed across its pieces (3600 s at 1200 ×: 3 s).
    step_until_within(h, "the last piece's rows", 40, |app| {
        app.state
            .latest
            .time_s()
            .is_some_and(|t| t > 2.0 * 3600.0 / 3.0 + 60.0)
    });
    assert_eq!(
        recordings_in(&f.record_dir),
        1,
        "a recording is not recorded again"
    );

    click(h, "Back to the start source (embedded twin)");
    step_until(h, "the twin again", |app| {
        app.state.source.start_source_label.is_none()
            && app.state.link.source == twin_source
            && !app.state.latest.row.is_empty()
    });
    assert!(
        h.state().state.latest.time_s().is_some_and(|t| t < 600.0),
        "the twin starts its program again"
    );
    assert!(!shows(h, "is not running"));
    step_until(h, "the twin's new recording", |_| {
        recordings_in(&f.record_dir) == 2
    });
}

/// A push waiting for its approver keeps the source it was requested on: opening a
/// recording is refused with why, and once the request is withdrawn it opens; a profile file
/// that cannot be read is refused with its name and the running source stays.
#[test]
fn a_push_waiting_for_its_approver_keeps_the_source() {
    use servosight::ui::panels::UiCommand;
    let mut f = start();
    let pieces = hour_in_pieces(f._dir.path());
    let h = &mut f.harness;
    request_a_push_of_backlash_x(h);
    let twin_source = h.state().state.link.source.clone();
    h.state_mut().settings.forms.open_recording = pieces[0].display().to_string();
    h.state_mut().execute(UiCommand::OpenRecording);
    let error = h.state().state.source.error.clone().unwrap_or_default();
    assert!(error.contains("waits for its approver"), "{error}");
    assert!(
        h.state().state.source.running.is_none(),
        "nothing was started"
    );

    click(h, "Cancel request");
    let missing = f._dir.path().join("no-such-profile.toml");
    h.state_mut().settings.forms.open_profile = missing.display().to_string();
    h.state_mut().execute(UiCommand::OpenRecording);
    step_until(h, "the profile's refusal", |app| {
        app.state.source.running.is_none() && app.state.source.error.is_some()
    });
    let error = h.state().state.source.error.clone().unwrap_or_default();
    assert!(error.contains("no-such-profile.toml"), "{error}");
    assert_eq!(h.state().state.link.source, twin_source);

    h.state_mut().settings.forms.open_profile.clear();
    h.state_mut().execute(UiCommand::OpenRecording);
    step_until(h, "the recording", |app| {
        app.state.source.start_source_label.is_some()
    });
    assert_ne!(h.state().state.link.source, twin_source);
}

/// The Source window connects to a controller: pymodbus on one end of a socat pty pair (the
/// peer of tests/modbus_peer.rs), the HMI's link on the other. Refused with the running twin
/// left as it is: a device that is not there (named), a blank profile (the twin's would judge
/// a machine by the twin), a line on which nothing answers. On the controller its frames
/// arrive, its table is read and it is recorded; its own line is refused for a second link;
/// leaving it, by a recording or by going back, takes the operator's tick.
#[test]
fn the_source_window_connects_to_a_controller_and_leaving_it_takes_a_tick() {
    use servosight::ui::panels::UiCommand;
    crate::modbus_peer::require_tools();
    let mut f = start();
    let dir = f._dir.path().to_path_buf();
    let pieces = hour_in_pieces(&dir);
    let pair = crate::modbus_peer::pty_pair(&dir, "line");
    let _peer = crate::modbus_peer::start_peer(&dir, &pair.b, &Default::default());
    let silent = crate::modbus_peer::pty_pair(&dir, "silent");
    let h = &mut f.harness;
    step_until(h, "the twin's frames", |app| app.state.link.frames > 10);
    let twin_source = h.state().state.link.source.clone();
    assert_eq!(recordings_in(&f.record_dir), 1, "the twin is recorded");
    let refused = |h: &mut Harness<'static, HmiApp>, what: &str| {
        step_until(h, what, |app| {
            app.state.source.running.is_none() && app.state.source.error.is_some()
        });
        assert_eq!(h.state().state.link.source, twin_source, "{what}");
        h.state().state.source.error.clone().unwrap_or_default()
    };

    click(h, "Source…");
    let missing = dir.join("no-such-tty");
    type_into(h, "Serial device", missing.to_str().expect("utf-8 path"));
    click(h, "Connect");
    let error = refused(h, "the missing device's refusal");
    assert!(error.contains("no-such-tty"), "{error}");

    h.state_mut().settings.forms.connect_device = pair.a.display().to_string();
    click(h, "Connect");
    let error = refused(h, "the blank profile's refusal");
    assert!(error.contains("give the machine profile"), "{error}");

    h.state_mut().settings.forms.open_profile = "none".into();
    h.state_mut().settings.forms.connect_device = silent.a.display().to_string();
    click(h, "Connect");
    let error = refused(h, "the silent line's refusal");
    assert!(error.contains("nothing answered"), "{error}");

    h.state_mut().settings.forms.connect_device = pair.a.display().to_string();
    click(h, "Connect");
    step_until(h, "the controller's frames and table", |app| {
        app.state.controller.is_some()
            && app.state.link.state == ConnectionState::Connected
            && app.state.compensation.controller.is_some()
    });
    let app = h.state();
    assert!(
        app.state.link.source.contains("line-a"),
        "{}",
        app.state.link.source
    );
    let change = app.state.source.last_change.clone().unwrap_or_default();
    assert!(
        change.contains("on Modbus RTU") && change.contains("recorded into"),
        "{change}"
    );
    assert!(
        app.state.pace.is_none(),
        "a controller runs at its own pace"
    );
    step_until(h, "the controller's recording", |_| {
        recordings_in(&f.record_dir) == 2
    });

    // Without the tick nothing leaves the controller: neither a recording nor the way back.
    h.state_mut().settings.forms.open_recording = pieces[0].display().to_string();
    h.state_mut().execute(UiCommand::OpenRecording);
    let error = h.state().state.source.error.clone().unwrap_or_default();
    assert!(error.contains("stop monitoring the controller"), "{error}");
    click(h, "Back to the start source (embedded twin)");
    let error = h.state().state.source.error.clone().unwrap_or_default();
    assert!(error.contains("stop monitoring the controller"), "{error}");
    assert!(
        h.state().state.source.running.is_none(),
        "nothing was started"
    );
    click(h, "stop monitoring the controller");
    // Its own line cannot take a second link.
    h.state_mut().execute(UiCommand::ConnectController);
    let error = h.state().state.source.error.clone().unwrap_or_default();
    assert!(error.contains("the running controller's line"), "{error}");
    click(h, "Back to the start source (embedded twin)");
    step_until(h, "the twin again", |app| {
        app.state.link.source == twin_source && app.state.controller.is_none()
    });
}

/// While a change runs (here a connect that waits for a line on which nothing answers), no
/// push is requested and no checklist signed off, and *Cancel* keeps the running twin and
/// leaves no recording of the attempt.
#[test]
fn while_the_source_changes_nothing_is_requested_and_cancel_keeps_the_twin() {
    use servosight::ui::panels::UiCommand;
    crate::modbus_peer::require_tools();
    let mut f = start();
    let dir = f._dir.path().to_path_buf();
    let silent = crate::modbus_peer::pty_pair(&dir, "silent");
    let h = &mut f.harness;
    draft_backlash_x(h);
    let twin_source = h.state().state.link.source.clone();
    let forms = &mut h.state_mut().settings.forms;
    forms.connect_device = silent.a.display().to_string();
    forms.open_profile = "none".into();
    forms.checklist_operator = "otto".into();
    h.state_mut().execute(UiCommand::ConnectController);
    assert!(h.state().state.source.running.is_some(), "the change runs");
    h.state_mut().execute(UiCommand::RequestPush);
    assert!(matches!(h.state().state.compensation.flow, PushFlow::Idle));
    let notice = h
        .state()
        .state
        .compensation
        .notice
        .clone()
        .unwrap_or_default();
    assert!(notice.contains("the source is changing"), "{notice}");
    h.state_mut().execute(UiCommand::SignOffWarmup);
    let notice = h.state().state.warmup.notice.clone().unwrap_or_default();
    assert!(notice.contains("the source is changing"), "{notice}");

    h.state_mut().execute(UiCommand::CancelSourceChange);
    let error = h.state().state.source.error.clone().unwrap_or_default();
    assert!(error.contains("cancelled"), "{error}");
    // Past the 3 s the line would have had: still the twin, and one recording (its own).
    let frames = h.state().state.link.frames;
    std::thread::sleep(Duration::from_secs(4));
    step_until(h, "the twin running on", |app| {
        app.state.link.frames > frames && app.state.link.source == twin_source
    });
    assert_eq!(recordings_in(&f.record_dir), 1);
}
