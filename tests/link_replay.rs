//! Replay of a CSV v1 recording through `ControllerLink`: pacing at 1× and N×, as fast as
//! possible, pause, seek, end of file, and no controller to write to.

use std::path::Path;
use std::time::{Duration, Instant};

use servosight::link::{
    ConnectionState, ControllerLink, Frame, LinkError, ReplayOptions, ReplaySpeed,
};
use servosight::signal::AxisId;

/// A recording of `rows` rows at 100 Hz.
fn write_recording(path: &Path, rows: usize) {
    let mut text = String::from("# machine: replay-test\ntime_s,X.speed_rpm\n");
    for i in 0..rows {
        text.push_str(&format!("{},{}\n", i as f64 / 100.0, i));
    }
    std::fs::write(path, text).unwrap();
}

fn collect(
    link: &mut ControllerLink,
    until: impl Fn(&[Frame]) -> bool,
    limit: Duration,
) -> Vec<Frame> {
    let deadline = Instant::now() + limit;
    let mut frames = Vec::new();
    while Instant::now() < deadline && !until(&frames) {
        while let Some(frame) = link.try_next_frame() {
            frames.push(frame);
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    frames
}

#[test]
fn as_fast_as_possible_delivers_every_row_in_order_then_ends() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("r.csv");
    write_recording(&path, 5000);
    let options = ReplayOptions {
        speed: ReplaySpeed::AsFastAsPossible,
        ..ReplayOptions::default()
    };
    let mut link = ControllerLink::replay(std::slice::from_ref(&path), options).unwrap();
    assert_eq!(link.schema().names(), ["time_s", "X.speed_rpm"]);
    let frames = collect(&mut link, |f| f.len() == 5000, Duration::from_secs(20));
    assert_eq!(frames.len(), 5000);
    assert!(frames.iter().enumerate().all(|(i, f)| f.row[1] == i as f64));
    std::thread::sleep(Duration::from_millis(50));
    let status = link.status();
    assert_eq!(status.state, ConnectionState::Disconnected);
    assert_eq!(status.last_error.as_deref(), Some("end of recording"));
    assert_eq!(status.stats.frames, 5000);
}

#[test]
fn real_time_and_faster_replays_keep_the_recorded_pace() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("r.csv");
    write_recording(&path, 101); // 1.00 s of recording
    for (factor, expected_s) in [(1.0, 1.0), (4.0, 0.25)] {
        let options = ReplayOptions {
            speed: ReplaySpeed::Factor(factor),
            ..ReplayOptions::default()
        };
        let started = Instant::now();
        let mut link = ControllerLink::replay(std::slice::from_ref(&path), options).unwrap();
        let frames = collect(&mut link, |f| f.len() == 101, Duration::from_secs(5));
        let took = started.elapsed().as_secs_f64();
        assert_eq!(frames.len(), 101);
        assert!(
            took >= expected_s * 0.95 && took < expected_s + 0.3,
            "{factor}×: {took:.3} s for {expected_s} s"
        );
    }
}

#[test]
fn pause_goes_stale_and_seek_jumps() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("r.csv");
    write_recording(&path, 1000); // 10 s
    let options = ReplayOptions {
        speed: ReplaySpeed::Factor(1.0),
        paused: false,
        stale_after: Duration::from_millis(200),
    };
    let mut link = ControllerLink::replay(std::slice::from_ref(&path), options).unwrap();
    let frames = collect(&mut link, |f| f.len() >= 10, Duration::from_secs(2));
    assert_eq!(link.status().state, ConnectionState::Connected);
    link.set_paused(true);
    std::thread::sleep(Duration::from_millis(50));
    let _ = collect(&mut link, |_| false, Duration::from_millis(20));
    let during_pause = collect(&mut link, |_| false, Duration::from_millis(400));
    assert!(
        during_pause.is_empty(),
        "{} frames while paused",
        during_pause.len()
    );
    assert_eq!(
        link.status().state,
        ConnectionState::Stale,
        "a paused replay is not live"
    );
    link.seek(7.5);
    link.set_paused(false);
    let after = collect(&mut link, |f| !f.is_empty(), Duration::from_secs(2));
    assert_eq!(after[0].row[0], 7.5, "first frame after the seek");
    assert!(frames[0].row[0] < 1.0);
    assert_eq!(link.status().state, ConnectionState::Connected);
}

#[test]
fn a_replay_has_no_controller_to_write_to() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("r.csv");
    write_recording(&path, 10);
    let link =
        ControllerLink::replay(std::slice::from_ref(&path), ReplayOptions::default()).unwrap();
    assert!(matches!(
        link.read_compensation().wait(),
        Err(LinkError::Unsupported(_))
    ));
    let missing = ControllerLink::replay(&[dir.path().join("nope.csv")], ReplayOptions::default());
    assert!(matches!(missing, Err(LinkError::Recording(_))));
}

#[test]
fn the_embedded_twin_streams_and_takes_compensation() {
    use servosight::compensation::{
        self, AuditLog, CompensationId, CompensationLimits, Credentials, Proposal, Request, Role,
    };
    let config =
        servosight::sim::TwinConfig::new(servosight::sim::ScenarioKind::Production, Some(1.0), 7);
    let mut link = ControllerLink::twin(
        config,
        ReplaySpeed::Factor(600.0),
        Duration::from_millis(500),
    )
    .unwrap();
    let frames = collect(&mut link, |f| f.len() >= 50, Duration::from_secs(5));
    assert!(frames.len() >= 50);
    assert!(link.schema().index_of("X.position_mm").is_some());
    let step = frames[1].row[0] - frames[0].row[0];
    assert!(
        (step - 1.0).abs() < 1e-9,
        "1 Hz twin, got a step of {step} s"
    );
    let mut users = Credentials::default();
    users.set_user("maria", Role::Approver, "pw").unwrap();
    let dir = tempfile::tempdir().unwrap();
    let mut audit = AuditLog::open(&dir.path().join("audit.jsonl")).unwrap();
    let backlash = CompensationId::Backlash(AxisId::X);
    let approved = Request::new(
        Proposal {
            changes: [(backlash, 7.0)].into_iter().collect(),
            why: "twin".into(),
            evidence: "test".into(),
            action: "adjust".into(),
        },
        "otto",
    )
    .unwrap()
    .approve(&users, "maria", "pw")
    .unwrap();
    let report =
        compensation::apply(&link, &CompensationLimits::default(), &mut audit, approved).unwrap();
    assert_eq!(report.steps, 2);
    assert_eq!(
        link.read_compensation().wait().unwrap().get(backlash),
        Some(7.0)
    );
}

/// The shipped profile of the embedded twin (it has abnormality models for X and S).
fn twin_profile() -> servosight::profile::MachineProfile {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/assets/it25-twin.toml");
    servosight::profile::MachineProfile::load(Path::new(path)).expect("twin profile")
}

/// The abnormality outputs a pipeline built on `schema` has, and its notes.
fn abnormality_columns(schema: &servosight::signal::Schema) -> (Vec<String>, Vec<String>) {
    let pipeline = servosight::estimators::EstimatorPipeline::new(&twin_profile(), schema)
        .expect("the twin profile fits the schema");
    let columns = pipeline
        .outputs()
        .into_iter()
        .map(|o| o.column)
        .filter(|c| c.ends_with(".abnormality_pct"))
        .collect();
    (columns, pipeline.notes().to_vec())
}

#[test]
fn every_link_schema_carries_the_depth_of_cut_so_abnormality_is_scored() {
    use servosight::link::register_map;
    use servosight::signal::channel::CUT_DEPTH;
    let expected = ["est.X.abnormality_pct", "est.S.abnormality_pct"];
    // A controller over Modbus (and the sim-controller serving the twin): the map's schema.
    let modbus = register_map::sample_schema();
    assert!(modbus.index_of(CUT_DEPTH).is_some());
    let (columns, notes) = abnormality_columns(&modbus);
    assert_eq!(columns, expected, "{notes:?}");
    assert!(
        !notes.iter().any(|n| n.contains("no abnormality score")),
        "{notes:?}"
    );
    // The embedded twin the HMI opens by default.
    let config =
        servosight::sim::TwinConfig::new(servosight::sim::ScenarioKind::Production, None, 7);
    let link =
        ControllerLink::twin(config, ReplaySpeed::Factor(1.0), Duration::from_secs(1)).unwrap();
    let (columns, notes) = abnormality_columns(link.schema());
    assert_eq!(columns, expected, "{notes:?}");
    assert!(notes.is_empty(), "{notes:?}");
    // A replayed recording without the column: nothing is invented, the pipeline says why.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("old.csv");
    write_recording_without_cut_depth(&path);
    let link =
        ControllerLink::replay(std::slice::from_ref(&path), ReplayOptions::default()).unwrap();
    assert!(link.schema().index_of(CUT_DEPTH).is_none());
    let (columns, notes) = abnormality_columns(link.schema());
    assert!(columns.is_empty(), "{columns:?}");
    assert_eq!(notes.len(), 2, "{notes:?}");
    assert!(
        notes
            .iter()
            .all(|n| n.contains("no abnormality score") && n.contains(CUT_DEPTH)),
        "{notes:?}"
    );
}

/// Five rows of the register map's columns without `cut_depth_mm` (an older recording).
fn write_recording_without_cut_depth(path: &Path) {
    use servosight::link::register_map;
    use servosight::signal::channel::CUT_DEPTH;
    let names: Vec<String> = register_map::sample_columns()
        .into_iter()
        .filter(|c| c != CUT_DEPTH)
        .collect();
    let rows: Vec<String> = (0..5)
        .map(|t| {
            let mut row = vec!["1".to_string(); names.len()];
            row[0] = t.to_string();
            row.join(",")
        })
        .collect();
    std::fs::write(path, format!("{}\n{}\n", names.join(","), rows.join("\n"))).unwrap();
}

/// The session's events, as debug text, until one contains `text` and `after` has passed
/// since (or 10 s have passed in all).
fn events_until(session: &mut servosight::ui::Session, text: &str, after: Duration) -> Vec<String> {
    use servosight::ui::session::SessionUpdate;
    let mut deadline = Instant::now() + Duration::from_secs(10);
    let mut seen = false;
    let mut events = Vec::new();
    while Instant::now() < deadline {
        while let Some(update) = session.try_recv() {
            if let SessionUpdate::Event(event) = update {
                events.push(format!("{event:?}"));
            }
        }
        if !seen && events.iter().any(|e| e.contains(text)) {
            seen = true;
            deadline = deadline.min(Instant::now() + after);
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    events
}

/// An HMI session on `source` with the shipped twin profile, its files in `dir`.
fn twin_profile_session(dir: &Path, source: servosight::ui::SourceSpec) -> servosight::ui::Session {
    servosight::ui::Session::start(servosight::ui::SessionConfig {
        source,
        record_dir: None,
        users_path: dir.join("users.toml"),
        audit_path: dir.join("audit.jsonl"),
        limits: servosight::compensation::CompensationLimits::default(),
        profile: Some(twin_profile()),
        data_dir: dir.join("data"),
    })
    .expect("session starts")
}

#[test]
fn the_hmi_session_on_the_embedded_twin_scores_abnormality() {
    use servosight::ui::SourceSpec;
    use servosight::ui::session::SessionUpdate;
    let dir = tempfile::tempdir().unwrap();
    // The HMI's default source: the production program, paced fast so the spindle's steady
    // shift-start warm-up (15 simulated minutes, no cutting) passes in about a second.
    let twin = servosight::sim::TwinConfig::new(servosight::sim::ScenarioKind::Production, None, 7);
    let mut session = twin_profile_session(
        dir.path(),
        SourceSpec::Twin {
            config: Box::new(twin),
            speed: ReplaySpeed::Factor(1000.0),
        },
    );
    let schema = session.schema().clone();
    let spindle = schema
        .index_of("est.S.abnormality_pct")
        .expect("the session has the spindle's abnormality score");
    assert!(schema.index_of("est.X.abnormality_pct").is_some());
    assert!(
        schema
            .index_of(servosight::signal::channel::CUT_DEPTH)
            .is_some()
    );
    // The score is reported once its standard error is small enough: it must become a number
    // on the healthy twin, and stay within the profile's normal band (the twin is healthy).
    let deadline = Instant::now() + Duration::from_secs(30);
    let mut scored = None;
    let mut warnings = Vec::new();
    while Instant::now() < deadline && scored.is_none() {
        while let Some(update) = session.try_recv() {
            match update {
                SessionUpdate::Frames(batch) => {
                    for row in &batch.rows {
                        if row[spindle].is_finite() {
                            scored = Some((row[0], row[spindle]));
                        }
                    }
                }
                SessionUpdate::Event(event) => warnings.push(format!("{event:?}")),
                _ => {}
            }
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    let (time_s, pct) = scored.unwrap_or_else(|| panic!("no spindle score; events: {warnings:?}"));
    let warning = twin_profile().axes[&AxisId::S].limits.abnormality.warning;
    assert!(
        pct.abs() < warning,
        "the healthy spindle scored {pct} % at {time_s} s (warning at {warning} %)"
    );
    assert!(
        !warnings.iter().any(|w| w.contains("estimators off")),
        "{warnings:?}"
    );
}

/// An HMI session on a recording without the depth of cut says in its events why there is no
/// abnormality score, instead of silently showing none.
#[test]
fn the_hmi_session_says_why_a_replay_has_no_abnormality_score() {
    use servosight::signal::channel::CUT_DEPTH;
    use servosight::ui::SourceSpec;
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("old.csv");
    write_recording_without_cut_depth(&path);
    let mut session = twin_profile_session(
        dir.path(),
        SourceSpec::Replay {
            pieces: vec![path.clone()],
            options: ReplayOptions::default(),
        },
    );
    let events = events_until(&mut session, CUT_DEPTH, Duration::ZERO);
    for axis in ["X", "S"] {
        assert!(
            events.iter().any(|e| e.contains(&format!(
                "estimators: {axis}: no abnormality score: the frames have no `{CUT_DEPTH}` column"
            ))),
            "{events:?}"
        );
    }
}

/// A replay of the controller's sample columns, one row a second for `seconds`, with the room
/// at 22 °C, `warm_column` at `warm_celsius` and every other value 1.
fn write_warm_replay(path: &Path, seconds: u32, warm_column: &str, warm_celsius: f64) {
    use servosight::link::register_map;
    use servosight::signal::channel::AMBIENT;
    let names = register_map::sample_columns();
    let rows: Vec<String> = (0..seconds)
        .map(|t| {
            let row: Vec<String> = names
                .iter()
                .enumerate()
                .map(|(i, name)| match name.as_str() {
                    _ if i == 0 => t.to_string(),
                    name if name == warm_column => warm_celsius.to_string(),
                    name if name == AMBIENT => "22".to_string(),
                    _ => "1".to_string(),
                })
                .collect();
            row.join(",")
        })
        .collect();
    std::fs::write(path, format!("{}\n{}\n", names.join(","), rows.join("\n"))).unwrap();
}

/// An HMI session that connects to a machine already warm (here a replay whose first frame
/// has the X stator 2 K above the room) says, once the first frame has arrived, that the
/// bearing and nut heat started from the profile's warm start: the estimates of the first
/// hour are a seed's, not the parts' own heat.
#[test]
fn the_hmi_session_says_when_it_started_on_a_warm_machine() {
    use servosight::ui::SourceSpec;
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("warm.csv");
    write_warm_replay(&path, 5, "X.stator_temp_C", 24.0);
    let mut session = twin_profile_session(
        dir.path(),
        SourceSpec::Replay {
            pieces: vec![path],
            options: ReplayOptions::default(),
        },
    );
    let said =
        "estimators: X: the machine was warm at the first frame (stator 2.0 K above the room)";
    // Kept listening while the rest of the replay arrives: said once, not once per batch.
    let events = events_until(&mut session, said, Duration::from_secs(2));
    let warm: Vec<&String> = events.iter().filter(|e| e.contains(said)).collect();
    assert_eq!(warm.len(), 1, "said once: {events:?}");
    assert!(warm[0].contains("the profile's warm start"), "{}", warm[0]);
}

/// An HMI session that starts on a warm spindle says its elongation does not count from a
/// known tool length (the thermal offset built on it is then withheld, tests/ui_view_models.rs),
/// and counts from the tool measurement once the operator says the tool was measured.
#[test]
fn the_hmi_session_says_where_the_spindle_elongation_counts_from() {
    use servosight::estimators::pipeline::ElongationOrigin;
    use servosight::ui::SourceSpec;
    use servosight::ui::session::{SessionCommand, SessionUpdate};
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("warm-spindle.csv");
    write_warm_replay(&path, 600, "S.stator_temp_C", 30.0);
    // Ten frames a second: the replay runs for a minute, long enough to measure the tool on a
    // loaded machine.
    let mut session = twin_profile_session(
        dir.path(),
        SourceSpec::Replay {
            pieces: vec![path],
            options: ReplayOptions {
                speed: ReplaySpeed::Factor(10.0),
                ..ReplayOptions::default()
            },
        },
    );
    let origin_until = |session: &mut servosight::ui::Session,
                        wanted: &dyn Fn(&ElongationOrigin) -> bool| {
        let deadline = Instant::now() + Duration::from_secs(10);
        let mut seen = Vec::new();
        while Instant::now() < deadline {
            while let Some(update) = session.try_recv() {
                if let SessionUpdate::ElongationOrigins(origins) = update {
                    if let Some(origin) = origins
                        .iter()
                        .find(|(axis, _)| *axis == AxisId::S)
                        .and_then(|(_, o)| *o)
                        .filter(|o| wanted(o))
                    {
                        return origin;
                    }
                    seen.push(format!("{origins:?}"));
                }
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        panic!("no such origin; the session said {seen:?}");
    };
    let started = origin_until(&mut session, &|o| {
        matches!(o, ElongationOrigin::FirstFrameWarm { .. })
    });
    let ElongationOrigin::FirstFrameWarm { time_s, excess_K } = started else {
        unreachable!("matched above")
    };
    assert_eq!(time_s, 0.0);
    assert!((excess_K - 8.0).abs() < 1e-9, "{started:?}");
    assert!(!started.is_known());
    session
        .send(SessionCommand::ResetToolCalibration)
        .expect("the session takes commands");
    let measured = origin_until(&mut session, &|o| {
        matches!(o, ElongationOrigin::ToolMeasured { .. })
    });
    assert!(measured.time_s() > 0.0, "{measured:?}");
    assert!(measured.is_known());
}

/// Rows `rows` of `recording` written as a CSV v1 file.
fn write_rows(
    path: &Path,
    recording: &servosight::signal::Recording,
    rows: impl IntoIterator<Item = usize>,
) {
    let mut writer = servosight::signal::csv_format::RecordingWriter::create(
        path,
        recording.metadata(),
        recording.schema(),
    )
    .unwrap();
    let mut row = Vec::new();
    for i in rows {
        recording.row_into(i, &mut row);
        writer.write_row(&row).unwrap();
    }
    writer.finish().unwrap();
}

/// The last frame a session forwards once its source has given `time_s`, with every event it
/// said until then.
fn run_until(session: &mut servosight::ui::Session, time_s: f64) -> (Vec<f64>, Vec<String>) {
    use servosight::ui::session::SessionUpdate;
    let deadline = Instant::now() + Duration::from_secs(30);
    let (mut last, mut events) = (Vec::new(), Vec::new());
    while Instant::now() < deadline {
        while let Some(update) = session.try_recv() {
            match update {
                SessionUpdate::Frames(batch) => {
                    if let Some(row) = batch.rows.last() {
                        last.clone_from(row);
                    }
                }
                SessionUpdate::Event(event) => events.push(format!("{event:?}")),
                _ => {}
            }
        }
        if last.first() == Some(&time_s) {
            return (last, events);
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    panic!("the session did not reach {time_s} s; it said {events:?}");
}

/// An HMI closed after an hour of a shift and opened again two minutes later carries its
/// estimators on from the state the first session saved as it closed: the estimates at the end
/// of the second hour are exactly those of estimators that ran through both hours with the
/// break (the break's inputs held at the first frame after it), the spindle's elongation still
/// counting from the first session's start at rest. The same state is not taken up by a
/// replay of the first hour again (its time is behind the state's), which says so.
#[test]
fn a_restarted_hmi_session_carries_its_estimators_on_from_where_the_last_one_left_them() {
    use servosight::estimators::EstimatorPipeline;
    use servosight::ui::SourceSpec;
    use servosight::ui::session::estimator_state_path;
    let dir = tempfile::tempdir().unwrap();
    let mut config =
        servosight::sim::TwinConfig::new(servosight::sim::ScenarioKind::Production, Some(2.0), 4);
    config.rate_hz = 1.0;
    let recording = servosight::sim::simulate(config).unwrap();
    let (closed_at, opened_at, end) = (3600, 3720, recording.len());
    let (first, second) = (dir.path().join("first.csv"), dir.path().join("second.csv"));
    write_rows(&first, &recording, 0..closed_at);
    write_rows(&second, &recording, opened_at..end);
    let replay = |path: &Path| SourceSpec::Replay {
        pieces: vec![path.to_path_buf()],
        options: ReplayOptions {
            speed: ReplaySpeed::AsFastAsPossible,
            ..ReplayOptions::default()
        },
    };
    let time = |i: usize| {
        let mut row = Vec::new();
        recording.row_into(i, &mut row);
        row[0]
    };

    let mut session = twin_profile_session(dir.path(), replay(&first));
    run_until(&mut session, time(closed_at - 1));
    drop(session);
    let (saved, _) = estimator_state_path(&dir.path().join("data"), &replay(&first))
        .expect("a replay's estimators carry on");
    let state = std::fs::read_to_string(&saved).expect("the closing session saved its state");

    let mut session = twin_profile_session(dir.path(), replay(&second));
    let (last, events) = run_until(&mut session, time(end - 1));
    let carried = "carried on from the state the last session saved, 121 s before";
    assert!(events.iter().any(|e| e.contains(carried)), "{events:?}");
    let mut through = EstimatorPipeline::new(&twin_profile(), recording.schema()).unwrap();
    let mut row = Vec::new();
    for i in (0..closed_at).chain(opened_at..end) {
        recording.row_into(i, &mut row);
        through.update(&row);
    }
    let mut expected = Vec::new();
    through.write_outputs(&mut expected);
    let estimates = &last[recording.schema().len()..];
    assert_eq!(estimates.len(), expected.len());
    for (got, want) in estimates.iter().zip(&expected) {
        assert!(
            got == want || (got.is_nan() && want.is_nan()),
            "{estimates:?} against {expected:?}"
        );
    }
    drop(session);

    // The first hour replayed again: a recording's time behind the state's is another
    // recording, or the same one opened again.
    std::fs::write(&saved, &state).unwrap();
    let mut session = twin_profile_session(dir.path(), replay(&first));
    let (_, events) = run_until(&mut session, time(closed_at - 1));
    assert!(
        events
            .iter()
            .any(|e| e.contains("started afresh") && e.contains("the same one opened again")),
        "{events:?}"
    );
}

/// A state file that is not a saved state (cut off, or written by hand) is not taken up: the
/// session says why, names the file, starts its estimators afresh and runs.
#[test]
fn a_damaged_estimator_state_file_is_named_and_the_estimators_start_afresh() {
    use servosight::ui::SourceSpec;
    use servosight::ui::session::estimator_state_path;
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("warm.csv");
    write_warm_replay(&path, 5, "X.stator_temp_C", 24.0);
    let source = SourceSpec::Replay {
        pieces: vec![path],
        options: ReplayOptions::default(),
    };
    let (state, _) = estimator_state_path(&dir.path().join("data"), &source).unwrap();
    std::fs::create_dir_all(state.parent().unwrap()).unwrap();
    std::fs::write(
        &state,
        "{\"format\": 1, \"profile\": \"it25-twin\", \"values\": [1.0,",
    )
    .unwrap();
    let mut session = twin_profile_session(dir.path(), source);
    let events = events_until(&mut session, "machine was warm", Duration::from_millis(200));
    let said = format!(
        "estimators: started afresh, not from the state in {}: it is not a saved state: EOF while parsing",
        state.display()
    );
    assert!(events.iter().any(|e| e.contains(&said)), "{events:?}");
    // The estimators ran (from the profile's warm start, as on any start).
    assert!(
        events
            .iter()
            .any(|e| e.contains("the machine was warm at the first frame")),
        "{events:?}"
    );
}

/// Rows `0..rows` of [`write_recording`]'s recording cut at `starts` into pieces named as the
/// recorder names them (`r.csv`, `r-0001.csv`, …), each a whole recording with its header.
fn write_pieces(dir: &Path, rows: usize, starts: &[usize]) -> Vec<std::path::PathBuf> {
    let ends = starts.iter().skip(1).copied().chain([rows]);
    starts
        .iter()
        .zip(ends)
        .enumerate()
        .map(|(k, (&start, end))| {
            let path = servosight::signal::piece_path(&dir.join("r.csv"), k as u32);
            let mut text = String::from("# machine: replay-test\ntime_s,X.speed_rpm\n");
            for i in start..end {
                text.push_str(&format!("{},{}\n", i as f64 / 100.0, i));
            }
            std::fs::write(&path, text).unwrap();
            path
        })
        .collect()
}

/// The pieces a recorder rotated a recording into replay as one: every row in order across
/// them, a seek into a later piece and back into the first, and pieces given out of order end
/// the replay with the piece named, after every row before it was delivered.
#[test]
fn the_pieces_of_a_recording_replay_as_one_and_a_seek_reaches_any_piece() {
    let dir = tempfile::tempdir().unwrap();
    let pieces = write_pieces(dir.path(), 5000, &[0, 1700, 3400]);
    let fast = ReplayOptions {
        speed: ReplaySpeed::AsFastAsPossible,
        ..ReplayOptions::default()
    };
    let mut link = ControllerLink::replay(&pieces, fast).unwrap();
    let frames = collect(&mut link, |f| f.len() == 5000, Duration::from_secs(20));
    assert_eq!(frames.len(), 5000);
    assert!(frames.iter().enumerate().all(|(i, f)| f.row[1] == i as f64));
    std::thread::sleep(Duration::from_millis(50));
    let status = link.status();
    assert_eq!(status.last_error.as_deref(), Some("end of recording"));
    let named = format!(
        "replay of {} … {} (3 pieces)",
        pieces[0].display(),
        pieces[2].display()
    );
    assert_eq!(status.source, named);

    let paused = ReplayOptions {
        speed: ReplaySpeed::Factor(1.0),
        paused: true,
        ..ReplayOptions::default()
    };
    let mut link = ControllerLink::replay(&pieces, paused).unwrap();
    for target_s in [41.0, 3.0] {
        link.set_paused(true);
        std::thread::sleep(Duration::from_millis(50));
        let _ = collect(&mut link, |_| false, Duration::from_millis(20));
        link.seek(target_s);
        link.set_paused(false);
        let after = collect(&mut link, |f| !f.is_empty(), Duration::from_secs(2));
        assert_eq!(after[0].row[0], target_s, "first frame after the seek");
    }

    let out_of_order = [pieces[0].clone(), pieces[2].clone(), pieces[1].clone()];
    let mut link = ControllerLink::replay(&out_of_order, fast).unwrap();
    let frames = collect(&mut link, |_| false, Duration::from_millis(500));
    assert_eq!(frames.len(), 1700 + 1600, "the first two pieces, every row");
    let status = link.status();
    assert_eq!(status.state, ConnectionState::Disconnected);
    let error = status.last_error.unwrap_or_default();
    assert!(
        error.contains("r-0001.csv")
            && error.contains("r-0002.csv")
            && error.contains("give the pieces in the order they were recorded"),
        "{error}"
    );
}

/// A replay whose frames stop for ten minutes (a link that was down, a piece missing) says so
/// once, and the spindle's elongation, which stepped over the gap, no longer counts from a
/// known tool length: its thermal offset waits for a tool measurement.
#[test]
fn an_hmi_session_says_when_its_frames_stopped_for_more_than_five_minutes() {
    use servosight::estimators::pipeline::ElongationOrigin;
    use servosight::ui::SourceSpec;
    use servosight::ui::session::SessionUpdate;
    let dir = tempfile::tempdir().unwrap();
    let mut config =
        servosight::sim::TwinConfig::new(servosight::sim::ScenarioKind::Production, Some(1.5), 4);
    config.rate_hz = 1.0;
    let recording = servosight::sim::simulate(config).unwrap();
    let gappy = dir.path().join("gappy.csv");
    write_rows(&gappy, &recording, (0..3600).chain(4200..recording.len()));
    let mut session = twin_profile_session(
        dir.path(),
        SourceSpec::Replay {
            pieces: vec![gappy],
            options: ReplayOptions {
                speed: ReplaySpeed::AsFastAsPossible,
                ..ReplayOptions::default()
            },
        },
    );
    let end_s = recording.time()[recording.len() - 1];
    let deadline = Instant::now() + Duration::from_secs(30);
    let (mut events, mut origin, mut last_s) = (Vec::new(), None, 0.0);
    while Instant::now() < deadline && last_s < end_s {
        while let Some(update) = session.try_recv() {
            match update {
                SessionUpdate::Frames(batch) => {
                    if let Some(row) = batch.rows.last() {
                        last_s = row[0];
                    }
                }
                SessionUpdate::Event(event) => events.push(format!("{event:?}")),
                SessionUpdate::ElongationOrigins(origins) => {
                    origin = origins
                        .iter()
                        .find(|(axis, _)| *axis == AxisId::S)
                        .and_then(|(_, o)| *o);
                }
                _ => {}
            }
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    assert_eq!(
        last_s, end_s,
        "the replay ran to its end; it said {events:?}"
    );
    let said = "estimators: a gap of 601 s in the frames before machine time 4200.0 s";
    let gaps: Vec<&String> = events.iter().filter(|e| e.contains(said)).collect();
    assert_eq!(gaps.len(), 1, "said once: {events:?}");
    assert!(gaps[0].contains("measure the tool"), "{}", gaps[0]);
    assert_eq!(
        origin,
        Some(ElongationOrigin::AcrossGap {
            time_s: 0.0,
            gap_end_s: 4200.0,
            gap_s: 601.0,
        })
    );
}

/// A replay of the first hour of a recording the recorder continued in later pieces says that
/// it leaves them out and how to replay the whole; a replay of every piece says nothing of it.
#[test]
fn an_hmi_replay_of_one_piece_says_which_later_pieces_it_leaves_out() {
    use servosight::ui::SourceSpec;
    let dir = tempfile::tempdir().unwrap();
    let pieces = write_pieces(dir.path(), 300, &[0, 100, 200]);
    let session = |given: &[std::path::PathBuf]| {
        servosight::ui::Session::start(servosight::ui::SessionConfig {
            source: SourceSpec::Replay {
                pieces: given.to_vec(),
                options: ReplayOptions {
                    speed: ReplaySpeed::AsFastAsPossible,
                    ..ReplayOptions::default()
                },
            },
            record_dir: None,
            users_path: dir.path().join("users.toml"),
            audit_path: dir.path().join("audit.jsonl"),
            limits: servosight::compensation::CompensationLimits::default(),
            profile: None,
            data_dir: dir.path().join("data"),
        })
        .expect("session starts")
    };
    let said = format!(
        "replay: the recorder continued {} in {} … {} (2 pieces) beside it that this replay leaves out",
        pieces[0].display(),
        pieces[1].display(),
        pieces[2].display()
    );
    let events = events_until(&mut session(&pieces[..1]), &said, Duration::ZERO);
    assert!(events.iter().any(|e| e.contains(&said)), "{events:?}");
    let events = events_until(&mut session(&pieces), "end of recording", Duration::ZERO);
    assert!(
        !events.iter().any(|e| e.contains("leaves out")),
        "{events:?}"
    );
}

/// A session ended at once, before anything it sent was read, still names the file its
/// recorder opened: a source change cancelled that early removes its attempt's empty
/// recording by that name (an HMI test once found the file left beside the twin's own when
/// the cancel came before the session's first recorder report). Without a recording
/// directory it names none.
#[test]
fn a_session_ended_before_it_reported_names_the_file_it_recorded_into() {
    use servosight::ui::SourceSpec;
    let dir = tempfile::tempdir().unwrap();
    let record_dir = dir.path().join("recordings");
    let twin = || SourceSpec::Twin {
        config: Box::new(servosight::sim::TwinConfig::new(
            servosight::sim::ScenarioKind::Production,
            None,
            7,
        )),
        speed: ReplaySpeed::Factor(1.0),
    };
    let session = servosight::ui::Session::start(servosight::ui::SessionConfig {
        source: twin(),
        record_dir: Some(record_dir.clone()),
        users_path: dir.path().join("users.toml"),
        audit_path: dir.path().join("audit.jsonl"),
        limits: servosight::compensation::CompensationLimits::default(),
        profile: Some(twin_profile()),
        data_dir: dir.path().join("data"),
    })
    .expect("session starts");
    let named = session.end().expect("the recorder opened a file");
    let on_disk: Vec<_> = std::fs::read_dir(&record_dir)
        .expect("the recording directory")
        .map(|e| e.expect("an entry").path())
        .collect();
    assert_eq!(on_disk, vec![named]);

    let unrecorded = twin_profile_session(dir.path(), twin());
    assert_eq!(unrecorded.end(), None);
}
