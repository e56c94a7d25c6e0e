//! The controller link against an independent Modbus RTU slave: pymodbus (tests/peers/
//! modbus_peer.py) on one end of a socat pty pair, servosight's RTU client on the other.
//!
//! Needs `socat`, `python3` and pymodbus 3 with pyserial; without them these tests FAIL with
//! the install line, they never pass silently. Nothing here is a test double: the peer is a
//! real Modbus implementation from another code base, the line is a real (pseudo) tty. The
//! corrupting/pacing relay is test equipment standing in for a noisy cable and a real baud rate,
//! which a pty does not have.

use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use servosight::compensation::{
    self, AuditLog, CompensationError, CompensationId, CompensationLimits, Credentials, Outcome,
    Proposal, Request, Role,
};
use servosight::link::recorder::{LOST_BEFORE_COLUMN, SEQUENCE_COLUMN};
use servosight::link::{
    ConnectionState, ControllerLink, Frame, ModbusConfig, Recorder, RecorderConfig, register_map,
};
use servosight::signal::channel::CUT_DEPTH;
use servosight::signal::{AxisId, Quantity, axis_column, read_recording};

const INSTALL: &str = "apt-get install -y socat && pip install 'pymodbus==3.*' pyserial";

/// Fails the test (never skips it) when the peer's tools are missing.
pub(crate) fn require_tools() {
    let socat = Command::new("socat").arg("-V").output();
    assert!(
        socat.is_ok_and(|o| o.status.success()),
        "socat is missing; install it: {INSTALL}"
    );
    let python = Command::new("python3")
        .args([
            "-c",
            "import pymodbus, serial; assert pymodbus.__version__.startswith('3.')",
        ])
        .output();
    assert!(
        python.is_ok_and(|o| o.status.success()),
        "python3 with pymodbus 3 and pyserial is missing; install them: {INSTALL}"
    );
}

/// A child process killed (by its own pid) when dropped.
pub(crate) struct Process(Child);

impl Process {
    fn kill(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

impl Drop for Process {
    fn drop(&mut self) {
        self.kill();
    }
}

/// `socat pty,link=A pty,link=B`: two tty ends joined, at stable paths.
pub(crate) struct PtyPair {
    _socat: Process,
    pub(crate) a: PathBuf,
    pub(crate) b: PathBuf,
}

pub(crate) fn pty_pair(dir: &Path, name: &str) -> PtyPair {
    let a = dir.join(format!("{name}-a"));
    let b = dir.join(format!("{name}-b"));
    let child = Command::new("socat")
        .arg("-d")
        .arg(format!("pty,raw,echo=0,link={}", a.display()))
        .arg(format!("pty,raw,echo=0,link={}", b.display()))
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap_or_else(|e| panic!("cannot start socat ({e}); install it: {INSTALL}"));
    let socat = Process(child);
    let deadline = Instant::now() + Duration::from_secs(5);
    while !(a.exists() && b.exists()) {
        assert!(
            Instant::now() < deadline,
            "socat did not create {}",
            a.display()
        );
        std::thread::sleep(Duration::from_millis(10));
    }
    PtyPair {
        _socat: socat,
        a,
        b,
    }
}

/// Options of the pymodbus peer.
#[derive(Default)]
pub(crate) struct PeerOptions {
    no_echo: bool,
    sequence_start: Option<u32>,
    /// A raw word for the depth-of-cut register instead of the peer's alternating cut.
    cut_depth_raw: Option<u16>,
    /// Serve this map instead of servosight's (a controller implementing another version).
    map: Option<serde_json::Value>,
}

/// The depth of cut the peer publishes while "cutting" (tests/peers/modbus_peer.py).
const PEER_CUT_DEPTH_MM: f64 = 2.345;

fn map_json(dir: &Path, map: Option<&serde_json::Value>) -> PathBuf {
    let path = dir.join("map.json");
    let json = match map {
        Some(map) => serde_json::to_string_pretty(map).unwrap(),
        None => serde_json::to_string_pretty(&register_map::describe()).unwrap(),
    };
    std::fs::write(&path, json).unwrap();
    path
}

pub(crate) fn start_peer(dir: &Path, port: &Path, options: &PeerOptions) -> Process {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/peers/modbus_peer.py");
    let mut command = Command::new("python3");
    command
        .arg(script)
        .arg("--port")
        .arg(port)
        .arg("--map")
        .arg(map_json(dir, options.map.as_ref()))
        .arg("--write-log")
        .arg(dir.join("peer-writes.jsonl"))
        .stdout(Stdio::null())
        .stderr(Stdio::from(
            std::fs::File::create(dir.join("peer.log")).unwrap(),
        ));
    if options.no_echo {
        command.arg("--no-echo");
    }
    if let Some(start) = options.sequence_start {
        command.arg("--sequence-start").arg(start.to_string());
    }
    if let Some(raw) = options.cut_depth_raw {
        command.arg("--cut-depth-raw").arg(raw.to_string());
    }
    let child = command
        .spawn()
        .unwrap_or_else(|e| panic!("cannot start python3 ({e}); install: {INSTALL}"));
    Process(child)
}

/// Write requests the peer received (one JSON line each).
fn peer_writes(dir: &Path) -> Vec<serde_json::Value> {
    match std::fs::read_to_string(dir.join("peer-writes.jsonl")) {
        Ok(text) => text
            .lines()
            .map(|l| serde_json::from_str(l).unwrap())
            .collect(),
        Err(_) => Vec::new(),
    }
}

fn config(port: &Path, poll_hz: f64) -> ModbusConfig {
    let mut config = ModbusConfig::new(port.display().to_string());
    config.poll_hz = poll_hz;
    config
}

/// Drains frames into `sink` until `until` says stop or `limit` passes.
fn pump(
    link: &mut ControllerLink,
    limit: Duration,
    sink: &mut dyn FnMut(Frame),
    mut until: impl FnMut(&ControllerLink) -> bool,
) {
    let deadline = Instant::now() + limit;
    while Instant::now() < deadline {
        while let Some(frame) = link.try_next_frame() {
            sink(frame);
        }
        if until(link) {
            return;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
}

fn wait_connected(link: &mut ControllerLink, frames: &mut Vec<Frame>) {
    pump(
        link,
        Duration::from_secs(10),
        &mut |f| frames.push(f),
        |l| l.status().state == ConnectionState::Connected,
    );
    let status = link.status();
    assert_eq!(
        status.state,
        ConnectionState::Connected,
        "no live data from the peer: {status:?}"
    );
}

/// Checks that a frame holds what the peer publishes, so a corrupted value cannot hide.
fn assert_plausible(schema: &servosight::signal::Schema, frame: &Frame) {
    let value = |name: &str| frame.row[schema.index_of(name).unwrap()];
    assert_eq!(value("ambient_C"), 21.5, "{frame:?}");
    assert_eq!(value("coolant_on"), 1.0, "{frame:?}");
    // Exactly the peer's depth (0.001 mm resolution) or 0 between cuts, nothing in between.
    let depth = value(CUT_DEPTH);
    assert!(
        depth == 0.0 || depth == PEER_CUT_DEPTH_MM,
        "cut depth {depth}: {frame:?}"
    );
    for axis in register_map::MAPPED_AXES {
        let temp = value(&axis_column(axis, Quantity::StatorTemp));
        assert!((24.99..=35.01).contains(&temp), "{axis} stator {temp}");
        let speed = value(&axis_column(axis, Quantity::Speed));
        assert!(speed.abs() <= 1500.01, "{axis} speed {speed}");
        // The peer publishes the same value as position and command.
        assert_eq!(
            value(&axis_column(axis, Quantity::Position)),
            value(&axis_column(axis, Quantity::Command)),
            "{axis}: {frame:?}"
        );
    }
}

fn users() -> Credentials {
    let mut credentials = Credentials::default();
    credentials
        .set_user("maria", Role::Approver, "pw-maria")
        .unwrap();
    credentials
        .set_user("otto", Role::Operator, "pw-otto")
        .unwrap();
    credentials
}

fn proposal(changes: &[(CompensationId, f64)]) -> Proposal {
    Proposal {
        changes: changes.iter().copied().collect(),
        why: "test".into(),
        evidence: "modbus_peer test".into(),
        action: "adjust".into(),
    }
}

#[test]
fn peer_streams_frames_and_an_approved_write_is_read_back() {
    require_tools();
    let dir = tempfile::tempdir().unwrap();
    let pair = pty_pair(dir.path(), "line");
    let _peer = start_peer(dir.path(), &pair.b, &PeerOptions::default());
    let mut link = ControllerLink::modbus(config(&pair.a, 100.0)).unwrap();
    let mut frames = Vec::new();
    wait_connected(&mut link, &mut frames);
    pump(
        &mut link,
        Duration::from_secs(2),
        &mut |f| frames.push(f),
        |_| false,
    );
    assert!(frames.len() > 100, "only {} frames in 2 s", frames.len());
    for pair in frames.windows(2) {
        assert_eq!(pair[1].sequence.unwrap(), pair[0].sequence.unwrap() + 1);
        assert_eq!(pair[1].lost_before, 0);
        assert!(pair[1].row[0] >= pair[0].row[0]);
    }
    for frame in &frames {
        assert_plausible(link.schema(), frame);
    }
    // The depth of cut crossed the line both ways: cutting and between cuts.
    let depth = link.schema().index_of(CUT_DEPTH).unwrap();
    assert!(frames.iter().any(|f| f.row[depth] == PEER_CUT_DEPTH_MM));
    assert!(frames.iter().any(|f| f.row[depth] == 0.0));

    let backlash = CompensationId::Backlash(AxisId::X);
    let tool = CompensationId::ThermalOffset(AxisId::S);
    let request = Request::new(proposal(&[(backlash, 12.0), (tool, -7.5)]), "otto").unwrap();
    let approved = request.approve(&users(), "maria", "pw-maria").unwrap();
    let mut audit = AuditLog::open(&dir.path().join("audit.jsonl")).unwrap();
    let report =
        compensation::apply(&link, &CompensationLimits::default(), &mut audit, approved).unwrap();
    assert_eq!(report.steps, 3, "12 µm of backlash at ≤ 5 µm per step");
    assert_eq!(report.new.get(backlash), Some(12.0));
    assert_eq!(report.new.get(tool), Some(-7.5));
    let read_back = link.read_compensation().wait().unwrap();
    assert_eq!(read_back.get(backlash), Some(12.0));
    assert_eq!(read_back.get(tool), Some(-7.5));
    // On the peer side: three staged tables and three commits, the last table holding the
    // targets in the documented registers (i32, high word first, 0.1 µm).
    let writes = peer_writes(dir.path());
    assert_eq!(writes.len(), 6, "{writes:?}");
    let last_table = &writes[4];
    assert_eq!(last_table["address"], 1010);
    assert_eq!(last_table["values"][0], 0);
    assert_eq!(last_table["values"][1], 120);
    let entries = audit.entries().unwrap();
    assert_eq!(entries.len(), 3);
    assert!(entries.iter().all(|e| e.outcome == Outcome::Applied));
    assert_eq!(entries[0].old.get(backlash), Some(0.0));
    assert_eq!(entries[2].new.get(backlash), Some(12.0));
    assert_eq!(
        compensation::audit::verify(audit.path()).unwrap().entries,
        3
    );

    // Rollback takes the same path and restores the values from before.
    let rollback = compensation::rollback_proposal(&entries, None).unwrap();
    let approved = Request::new(rollback, "otto")
        .unwrap()
        .approve(&users(), "maria", "pw-maria")
        .unwrap();
    compensation::apply(&link, &CompensationLimits::default(), &mut audit, approved).unwrap();
    let restored = link.read_compensation().wait().unwrap();
    assert_eq!(restored.get(backlash), Some(0.0));
    assert_eq!(restored.get(tool), Some(0.0));
    assert!(
        audit.entries().unwrap()[3]
            .action
            .starts_with("rollback of ")
    );
}

/// Polls a peer whose every sample must be refused: no frame may arrive, and the refusals are
/// counted with `expected` in the link's last error.
fn assert_every_sample_refused(options: PeerOptions, expected: &str) {
    require_tools();
    let dir = tempfile::tempdir().unwrap();
    let pair = pty_pair(dir.path(), "line");
    let _peer = start_peer(dir.path(), &pair.b, &options);
    let mut link = ControllerLink::modbus(config(&pair.a, 100.0)).unwrap();
    let mut frames = Vec::new();
    pump(
        &mut link,
        Duration::from_secs(10),
        &mut |f| frames.push(f),
        |l| l.status().stats.implausible_samples >= 20,
    );
    let status = link.status();
    assert!(
        status.stats.implausible_samples >= 20,
        "the peer's samples were not refused: {status:?}"
    );
    assert!(frames.is_empty(), "{} frames got through", frames.len());
    assert_ne!(status.state, ConnectionState::Connected, "{status:?}");
    let error = status.last_error.unwrap_or_default();
    assert!(error.contains(expected), "{error}");
}

#[test]
fn peer_with_an_implausible_depth_of_cut_is_refused_naming_the_register() {
    // 0xFFFF reads as 65.535 mm: beyond any cut, a garbled or "no value" word.
    assert_every_sample_refused(
        PeerOptions {
            cut_depth_raw: Some(0xFFFF),
            ..PeerOptions::default()
        },
        "register 7 (cut_depth_mm): 65.535 is outside its plausible range 0 to 50",
    );
}

#[test]
fn peer_speaking_map_version_1_without_the_depth_of_cut_is_refused() {
    // The map as a version-1 controller implements it: no depth of cut (register 7 reads 0,
    // which would pass for "never cutting"), version 1.
    let mut map = serde_json::to_value(register_map::describe()).unwrap();
    map["version"] = 1.into();
    map["machine"]
        .as_array_mut()
        .unwrap()
        .retain(|f| f["name"] != CUT_DEPTH);
    assert_every_sample_refused(
        PeerOptions {
            map: Some(map),
            ..PeerOptions::default()
        },
        "the controller reports register map version 1, servosight speaks 2",
    );
}

#[test]
fn peer_killed_mid_stream_reconnects_and_the_recording_marks_the_gap() {
    require_tools();
    let dir = tempfile::tempdir().unwrap();
    let mut pair = pty_pair(dir.path(), "line");
    let mut peer = start_peer(dir.path(), &pair.b, &PeerOptions::default());
    let mut config = config(&pair.a, 100.0);
    config.request_timeout = Duration::from_millis(100);
    let mut link = ControllerLink::modbus(config).unwrap();
    let path = dir.path().join("run.csv");
    let mut recorder = Recorder::create(RecorderConfig::new(&path), link.schema(), true).unwrap();
    let last_sequence = std::cell::Cell::new(0u32);
    let mut record = |frame: Frame| {
        last_sequence.set(frame.sequence.unwrap());
        recorder.record(&frame).unwrap();
    };
    let mut before = Vec::new();
    wait_connected(&mut link, &mut before);
    before.iter().cloned().for_each(&mut record);
    pump(&mut link, Duration::from_secs(1), &mut record, |_| false);

    // Unplug: the peer and the line (socat) go away; the port disappears.
    peer.kill();
    drop(pair);
    let mut states = Vec::new();
    pump(&mut link, Duration::from_millis(1500), &mut record, |l| {
        states.push(l.status().state);
        false
    });
    let status = link.status();
    assert_eq!(status.state, ConnectionState::Disconnected, "{status:?}");
    assert!(
        states[states.len() / 2..]
            .iter()
            .all(|s| *s != ConnectionState::Connected),
        "the link claimed to be live while the line was down"
    );

    // Plug back in: a controller whose counter went on while the line was down.
    pair = pty_pair(dir.path(), "line");
    let resume_at = last_sequence.get() + 40;
    let _peer = start_peer(
        dir.path(),
        &pair.b,
        &PeerOptions {
            sequence_start: Some(resume_at),
            ..PeerOptions::default()
        },
    );
    pump(&mut link, Duration::from_secs(10), &mut record, |l| {
        l.status().state == ConnectionState::Connected
    });
    pump(&mut link, Duration::from_secs(1), &mut record, |_| false);
    let status = link.status();
    assert_eq!(status.state, ConnectionState::Connected, "{status:?}");
    assert!(status.stats.reconnects >= 1, "{status:?}");
    assert_eq!(status.stats.lost_samples, 39, "{status:?}");
    assert_eq!(status.stats.sequence_gaps, 1, "{status:?}");
    let stats = recorder.finish().unwrap();
    assert_eq!(stats.gaps_marked, 1);

    // One file, readable, continuing across the outage, with the gap marked where it was.
    let recording = read_recording(&path).unwrap();
    let sequence = recording.column(SEQUENCE_COLUMN).unwrap();
    let lost = recording.column(LOST_BEFORE_COLUMN).unwrap();
    let gap_row = lost.iter().position(|v| *v > 0.0).unwrap();
    assert_eq!(lost[gap_row], 39.0);
    assert_eq!(sequence[gap_row], f64::from(resume_at));
    assert_eq!(sequence[gap_row - 1], f64::from(resume_at - 40));
    let time = recording.time();
    assert!(
        time[gap_row] - time[gap_row - 1] > 1.0,
        "the outage shows in time_s"
    );
    assert!(
        recording.len() - gap_row > 50,
        "recording continued after the reconnect"
    );
}

/// Copies bytes between two pty ends, optionally pacing them at a baud rate (10 bits per byte)
/// and flipping one bit in every `corrupt_every`-th chunk from the peer to the client.
struct Relay {
    stop: Arc<AtomicBool>,
    corrupted: Arc<AtomicU64>,
    threads: Vec<std::thread::JoinHandle<()>>,
}

fn relay(
    client_side: &Path,
    peer_side: &Path,
    baud: Option<u32>,
    corrupt_every: Option<u64>,
) -> Relay {
    let stop = Arc::new(AtomicBool::new(false));
    let corrupted = Arc::new(AtomicU64::new(0));
    let open = |p: &Path| {
        std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .open(p)
            .unwrap()
    };
    let client = open(client_side);
    let peer = open(peer_side);
    let mut threads = Vec::new();
    for (mut from, mut to, corrupt) in [
        (client.try_clone().unwrap(), peer.try_clone().unwrap(), None),
        (peer, client, corrupt_every),
    ] {
        let stop = Arc::clone(&stop);
        let corrupted = Arc::clone(&corrupted);
        threads.push(
            std::thread::Builder::new()
                .name("test-relay".into())
                .spawn(move || {
                    let mut buffer = [0u8; 512];
                    let mut chunks = 0u64;
                    while !stop.load(Ordering::Relaxed) {
                        let n = match from.read(&mut buffer) {
                            Ok(0) | Err(_) => return,
                            Ok(n) => n,
                        };
                        chunks += 1;
                        if let Some(every) = corrupt
                            && chunks.is_multiple_of(every)
                        {
                            buffer[n / 2] ^= 0x10;
                            corrupted.fetch_add(1, Ordering::Relaxed);
                        }
                        if let Some(baud) = baud {
                            std::thread::sleep(Duration::from_secs_f64(
                                n as f64 * 10.0 / f64::from(baud),
                            ));
                        }
                        if to.write_all(&buffer[..n]).is_err() {
                            return;
                        }
                    }
                })
                .unwrap(),
        );
    }
    Relay {
        stop,
        corrupted,
        threads,
    }
}

impl Relay {
    /// Stops the threads; they leave once their pty ends go away (socat killed).
    fn stop(self) {
        self.stop.store(true, Ordering::Relaxed);
        drop(self.threads);
    }
}

#[test]
fn corrupted_bytes_are_counted_and_never_accepted() {
    require_tools();
    let dir = tempfile::tempdir().unwrap();
    let client_line = pty_pair(dir.path(), "client");
    let peer_line = pty_pair(dir.path(), "peer");
    let _peer = start_peer(dir.path(), &peer_line.b, &PeerOptions::default());
    let relay = relay(&client_line.b, &peer_line.a, None, Some(7));
    let mut config = config(&client_line.a, 200.0);
    config.request_timeout = Duration::from_millis(100);
    config.reconnect_after_failures = 50;
    let mut link = ControllerLink::modbus(config).unwrap();
    let mut frames = Vec::new();
    wait_connected(&mut link, &mut frames);
    pump(
        &mut link,
        Duration::from_secs(4),
        &mut |f| frames.push(f),
        |_| false,
    );
    let status = link.status();
    // A frame whose gap the link has counted may still be on its way to the test: take what
    // arrives shortly after, and compare with the counts before and after it.
    pump(
        &mut link,
        Duration::from_millis(300),
        &mut |f| frames.push(f),
        |_| false,
    );
    let later = link.status();
    let corrupted = relay.corrupted.load(Ordering::Relaxed);
    eprintln!(
        "{corrupted} chunks corrupted; {} frames; {:?}",
        frames.len(),
        status.stats
    );
    assert!(
        corrupted >= 5,
        "the relay corrupted only {corrupted} chunks"
    );
    assert!(
        status.stats.crc_errors >= corrupted / 2,
        "{corrupted} corrupted replies but {status:?}"
    );
    // Corruption is not a line failure: the link stayed up.
    assert_eq!(status.stats.io_errors, 0, "{status:?}");
    assert_eq!(status.stats.reconnects, 0, "{status:?}");
    assert!(
        status.stats.lost_samples <= status.stats.crc_errors + status.stats.timeouts,
        "{status:?}"
    );
    assert!(frames.len() > 100, "{} frames", frames.len());
    for frame in &frames {
        assert_plausible(link.schema(), frame);
    }
    // Every reply lost to corruption is a sample the peer published: the gaps say so.
    let lost: u64 = frames.iter().map(|f| f.lost_before).sum();
    assert!(
        status.stats.lost_samples <= lost && lost <= later.stats.lost_samples,
        "frames carry {lost} lost samples; the link counted {} then {}",
        status.stats.lost_samples,
        later.stats.lost_samples
    );
    assert!(lost >= 1);
    drop(link);
    relay.stop();
}

#[test]
fn a_write_the_peer_does_not_echo_fails_and_the_audit_says_so() {
    require_tools();
    let dir = tempfile::tempdir().unwrap();
    let pair = pty_pair(dir.path(), "line");
    let _peer = start_peer(
        dir.path(),
        &pair.b,
        &PeerOptions {
            no_echo: true,
            ..PeerOptions::default()
        },
    );
    let mut link = ControllerLink::modbus(config(&pair.a, 50.0)).unwrap();
    wait_connected(&mut link, &mut Vec::new());
    let backlash = CompensationId::Backlash(AxisId::Z);
    let approved = Request::new(proposal(&[(backlash, 3.0)]), "otto")
        .unwrap()
        .approve(&users(), "maria", "pw-maria")
        .unwrap();
    let mut audit = AuditLog::open(&dir.path().join("audit.jsonl")).unwrap();
    let result = compensation::apply(&link, &CompensationLimits::default(), &mut audit, approved);
    assert!(
        matches!(result, Err(CompensationError::VerifyFailed(_))),
        "{result:?}"
    );
    let entries = audit.entries().unwrap();
    assert_eq!(entries.len(), 1);
    assert_eq!(entries[0].outcome, Outcome::VerifyFailed);
    assert!(
        entries[0].detail.contains("\"backlash.Z\":0.0"),
        "{}",
        entries[0].detail
    );
    assert_eq!(
        link.read_compensation().wait().unwrap().get(backlash),
        Some(0.0)
    );
    // The write did go out (it is the peer that ignored it).
    assert_eq!(peer_writes(dir.path()).len(), 2);
}

#[test]
fn out_of_bounds_unapproved_or_stale_writes_send_nothing() {
    require_tools();
    let dir = tempfile::tempdir().unwrap();
    let pair = pty_pair(dir.path(), "line");
    let mut peer = start_peer(dir.path(), &pair.b, &PeerOptions::default());
    let mut link = ControllerLink::modbus(config(&pair.a, 50.0)).unwrap();
    wait_connected(&mut link, &mut Vec::new());
    let mut audit = AuditLog::open(&dir.path().join("audit.jsonl")).unwrap();
    let limits = CompensationLimits::default();
    let backlash = CompensationId::Backlash(AxisId::X);

    // Not approved: a wrong password, an operator approving, the requester approving.
    let request = Request::new(proposal(&[(backlash, 2.0)]), "otto").unwrap();
    for (who, password) in [("maria", "guess"), ("otto", "pw-otto")] {
        let error = request.approve(&users(), who, password).unwrap_err();
        assert!(
            matches!(error, CompensationError::NotApproved(_)),
            "{error}"
        );
        compensation::record_refusal(&mut audit, &request, Some(who), "test", &error.to_string())
            .unwrap();
    }
    let own = Request::new(proposal(&[(backlash, 2.0)]), "maria").unwrap();
    assert!(own.approve(&users(), "maria", "pw-maria").is_err());

    // Approved but beyond the absolute limit.
    let approved = Request::new(proposal(&[(backlash, 80.0)]), "otto")
        .unwrap()
        .approve(&users(), "maria", "pw-maria")
        .unwrap();
    let result = compensation::apply(&link, &limits, &mut audit, approved);
    assert!(
        matches!(result, Err(CompensationError::OutOfBounds(_))),
        "{result:?}"
    );

    // Approved, within bounds, but the data is stale: the peer has stopped answering.
    peer.kill();
    pump(&mut link, Duration::from_secs(5), &mut |_| {}, |l| {
        l.status().state != ConnectionState::Connected
    });
    let approved = Request::new(proposal(&[(backlash, 2.0)]), "otto")
        .unwrap()
        .approve(&users(), "maria", "pw-maria")
        .unwrap();
    let result = compensation::apply(&link, &limits, &mut audit, approved);
    assert!(
        matches!(result, Err(CompensationError::NotLive(_))),
        "{result:?}"
    );

    // Verified on the peer side: no write request ever arrived.
    assert_eq!(peer_writes(dir.path()), Vec::<serde_json::Value>::new());
    let entries = audit.entries().unwrap();
    assert_eq!(entries.len(), 4);
    assert!(entries.iter().all(|e| e.outcome == Outcome::Refused));
    assert!(
        entries[2].detail.contains("absolute limit"),
        "{}",
        entries[2].detail
    );
}

/// Polls as fast as the line allows for `duration` and checks that no sample was lost between
/// the peer and the recording, and that memory stays flat. Returns polls per second.
///
/// The memory check reads the process's RSS: run it from a test that
/// [runs in its own process](crate::common::in_own_process).
fn soak(duration: Duration, baud: Option<u32>) -> f64 {
    require_tools();
    let dir = tempfile::tempdir().unwrap();
    let client_line = pty_pair(dir.path(), "client");
    let peer_line;
    let _relay;
    let _peer;
    let port = match baud {
        None => {
            _peer = start_peer(dir.path(), &client_line.b, &PeerOptions::default());
            client_line.a.clone()
        }
        Some(baud) => {
            peer_line = pty_pair(dir.path(), "peer");
            _peer = start_peer(dir.path(), &peer_line.b, &PeerOptions::default());
            _relay = relay(&client_line.b, &peer_line.a, Some(baud), None);
            client_line.a.clone()
        }
    };
    let mut config = config(&port, 10_000.0);
    if let Some(baud) = baud {
        config.baud = baud;
        // 64 registers at 10 bits per byte plus the peer's turnaround.
        config.request_timeout = Duration::from_secs_f64(200.0 * 10.0 / f64::from(baud) + 0.2);
    }
    let mut link = ControllerLink::modbus(config).unwrap();
    let path = dir.path().join("soak.csv");
    let mut recorder_config = RecorderConfig::new(&path);
    recorder_config.rotate_bytes = Some(8 * 1024 * 1024);
    let mut recorder = Recorder::create(recorder_config, link.schema(), true).unwrap();
    wait_connected(&mut link, &mut Vec::new());
    let rss_kib = || {
        std::fs::read_to_string("/proc/self/status")
            .ok()
            .and_then(|s| {
                s.lines()
                    .find(|l| l.starts_with("VmRSS:"))
                    .and_then(|l| l.split_whitespace().nth(1)?.parse::<u64>().ok())
            })
            .unwrap_or(0)
    };
    let started = Instant::now();
    let frames_before = link.status().stats.frames;
    let mut rss_after_warmup = None;
    let mut record = |frame: Frame| recorder.record(&frame).unwrap();
    pump(&mut link, duration, &mut record, |_| {
        if rss_after_warmup.is_none() && started.elapsed() > duration / 5 {
            rss_after_warmup = Some(rss_kib());
        }
        false
    });
    let elapsed = started.elapsed().as_secs_f64();
    let status = link.status();
    let rate = (status.stats.frames - frames_before) as f64 / elapsed;
    let paths = recorder.paths().to_vec();
    let stats = recorder.finish().unwrap();
    let rss_end = rss_kib();
    eprintln!(
        "soak {:?} baud {:?}: {:.1} polls/s, {} rows in {} files, rss {:?} → {} KiB, {:?}",
        duration,
        baud,
        rate,
        stats.rows,
        paths.len(),
        rss_after_warmup,
        rss_end,
        status.stats
    );
    assert_eq!(status.stats.lost_samples, 0, "{status:?}");
    assert_eq!(stats.samples_lost_upstream, 0);
    // No frame lost between peer and recording: the recorded sequence is gapless.
    let mut expected: Option<f64> = None;
    let mut rows = 0u64;
    for path in &paths {
        let recording = read_recording(path).unwrap();
        for &sequence in recording.column(SEQUENCE_COLUMN).unwrap() {
            if let Some(e) = expected {
                assert_eq!(sequence, e, "{}", path.display());
            }
            expected = Some(sequence + 1.0);
            rows += 1;
        }
    }
    assert_eq!(rows, stats.rows);
    if let Some(warm) = rss_after_warmup {
        assert!(
            rss_end < warm + 16 * 1024,
            "memory grew from {warm} KiB to {rss_end} KiB"
        );
    }
    rate
}

#[test]
fn soak_short_no_sample_lost_memory_flat() {
    if !crate::common::in_own_process("modbus_peer::soak_short_no_sample_lost_memory_flat") {
        return;
    }
    let rate = soak(Duration::from_secs(20), None);
    assert!(rate > 50.0, "{rate} polls/s");
}

#[test]
#[ignore = "10 minutes; run by hand: cargo test --test tests soak_ten_minutes -- --ignored --nocapture"]
fn soak_ten_minutes() {
    if !crate::common::in_own_process("modbus_peer::soak_ten_minutes") {
        return;
    }
    soak(Duration::from_secs(600), None);
}

#[test]
#[ignore = "measures the sustained poll rate per baud rate for docs/performance.md (~1 min)"]
fn poll_rate_per_baud() {
    if !crate::common::in_own_process("modbus_peer::poll_rate_per_baud") {
        return;
    }
    for baud in [9600, 19_200, 38_400, 57_600, 115_200] {
        let rate = soak(Duration::from_secs(10), Some(baud));
        println!("baud {baud}: {rate:.1} polls/s");
    }
    let rate = soak(Duration::from_secs(10), None);
    println!("pty without pacing: {rate:.1} polls/s");
}

fn servosight() -> Command {
    Command::new(env!("CARGO_BIN_EXE_servosight"))
}

#[test]
fn record_cli_killed_hard_leaves_a_file_inspect_reads() {
    require_tools();
    let dir = tempfile::tempdir().unwrap();
    let pair = pty_pair(dir.path(), "line");
    let _peer = start_peer(dir.path(), &pair.b, &PeerOptions::default());
    let output = dir.path().join("rec.csv");
    let mut recorder = Process(
        servosight()
            .args([
                "record",
                "--poll-hz",
                "100",
                "--status-every-s",
                "0",
                "--port",
            ])
            .arg(&pair.a)
            .arg("-o")
            .arg(&output)
            .stderr(Stdio::null())
            .spawn()
            .unwrap(),
    );
    // Until 300 rows have reached the file (3 s at 100 Hz), however long a loaded machine
    // takes to start the recorder; a fixed wait left 148 rows under load.
    let written = || {
        std::fs::read_to_string(&output)
            .map(|text| {
                text.lines()
                    .filter(|l| !l.starts_with('#'))
                    .count()
                    .saturating_sub(1)
            })
            .unwrap_or(0)
    };
    let deadline = std::time::Instant::now() + Duration::from_secs(60);
    while written() < 300 && std::time::Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(100));
    }
    let started = written();
    assert!(
        started >= 300,
        "the recorder wrote {started} rows in a minute"
    );
    // The recorder flushes every second: 1.5 s later more rows have reached the file.
    std::thread::sleep(Duration::from_millis(1500));
    let seen = written();
    assert!(
        seen > started,
        "no row reached the file in 1.5 s ({started} rows): the recorder does not flush every second"
    );
    // SIGKILL: no chance to flush; what had reached the file must survive it whole.
    recorder.kill();
    let inspect = servosight()
        .arg("inspect")
        .arg(&output)
        .args(["--json", "-"])
        .output()
        .unwrap();
    assert!(
        inspect.status.success(),
        "inspect failed on the killed recorder's file: {}",
        String::from_utf8_lossy(&inspect.stderr)
    );
    let summary: serde_json::Value = serde_json::from_slice(&inspect.stdout).unwrap();
    let rows = summary["rows"].as_u64().unwrap();
    assert!(rows as usize >= seen, "only {rows} of {seen} rows survived");
    assert_eq!(
        summary["last_line_cut_short"], false,
        "the recorder writes whole lines"
    );
    let recording = read_recording(&output).unwrap();
    let lost: f64 = recording.column(LOST_BEFORE_COLUMN).unwrap().iter().sum();
    assert_eq!(lost, 0.0);
}

#[test]
fn compensate_cli_applies_with_an_approver_and_audit_verify_catches_an_edit() {
    require_tools();
    let dir = tempfile::tempdir().unwrap();
    let pair = pty_pair(dir.path(), "line");
    let _peer = start_peer(dir.path(), &pair.b, &PeerOptions::default());
    let users = dir.path().join("users.toml");
    let audit = dir.path().join("audit.jsonl");
    let proposal = dir.path().join("proposal.json");
    let run = |args: &[&str], stdin: &str| {
        let mut child = servosight()
            .args(args)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        child
            .stdin
            .take()
            .unwrap()
            .write_all(stdin.as_bytes())
            .unwrap();
        child.wait_with_output().unwrap()
    };
    let path = |p: &Path| p.display().to_string();
    let port = path(&pair.a);
    for (name, role, password) in [
        ("maria", "approver", "pw-maria"),
        ("otto", "operator", "pw-otto"),
    ] {
        let out = run(
            &[
                "compensate",
                "set-user",
                "--users",
                &path(&users),
                "--name",
                name,
                "--role",
                role,
            ],
            &format!("{password}\n"),
        );
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    assert!(
        !std::fs::read_to_string(&users)
            .unwrap()
            .contains("pw-maria")
    );
    let out = run(
        &[
            "compensate",
            "propose",
            "--set",
            "straightness.Z#3=-2.5",
            "--why",
            "bent",
            "--evidence",
            "est.json",
            "-o",
            &path(&proposal),
        ],
        "",
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let apply = |password: &str| {
        run(
            &[
                "compensate",
                "apply",
                "--port",
                &port,
                "--proposal",
                &path(&proposal),
                "--operator",
                "otto",
                "--approver",
                "maria",
                "--users",
                &path(&users),
                "--audit",
                &path(&audit),
            ],
            &format!("{password}\n"),
        )
    };
    let refused = apply("not-the-password");
    assert!(!refused.status.success());
    assert!(
        String::from_utf8_lossy(&refused.stderr).contains("not approved"),
        "{}",
        String::from_utf8_lossy(&refused.stderr)
    );
    assert!(
        peer_writes(dir.path()).is_empty(),
        "a refused push sent something"
    );
    let applied = apply("pw-maria");
    assert!(
        applied.status.success(),
        "{}",
        String::from_utf8_lossy(&applied.stderr)
    );
    assert_eq!(peer_writes(dir.path()).len(), 2);
    let verify = run(&["audit", "verify", &path(&audit), "--json", "-"], "");
    assert!(verify.status.success());
    let report: serde_json::Value = serde_json::from_slice(&verify.stdout).unwrap();
    assert_eq!(report["entries"], 2, "one refusal, one applied step");
    // The head read now (given in capitals) holds while the log holds its entry; a copy cut
    // back to its first entry is a chain intact on its own, and no longer holds it.
    let head = report["head_hash"].as_str().unwrap().to_string();
    let upper = head.to_ascii_uppercase();
    let held = run(
        &["audit", "verify", &path(&audit), "--expect-head", &upper],
        "",
    );
    assert!(
        held.status.success(),
        "{}",
        String::from_utf8_lossy(&held.stderr)
    );
    let text = std::fs::read_to_string(&audit).unwrap();
    let cut_copy = dir.path().join("cut.jsonl");
    std::fs::write(&cut_copy, format!("{}\n", text.lines().next().unwrap())).unwrap();
    assert!(
        run(&["audit", "verify", &path(&cut_copy)], "")
            .status
            .success()
    );
    let cut = run(
        &["audit", "verify", &path(&cut_copy), "--expect-head", &head],
        "",
    );
    assert!(!cut.status.success());
    assert!(
        String::from_utf8_lossy(&cut.stderr).contains("no entry has the head"),
        "{}",
        String::from_utf8_lossy(&cut.stderr)
    );
    // Make the refusal look approved: the chain breaks at that line.
    let text = std::fs::read_to_string(&audit).unwrap();
    std::fs::write(&audit, text.replacen("\"refused\"", "\"applied\"", 1)).unwrap();
    let verify = run(&["audit", "verify", &path(&audit)], "");
    assert!(!verify.status.success());
    assert!(
        String::from_utf8_lossy(&verify.stderr).contains("line 1"),
        "{}",
        String::from_utf8_lossy(&verify.stderr)
    );
}

#[test]
fn sim_controller_serves_a_recording_and_takes_an_approved_write() {
    require_tools();
    let dir = tempfile::tempdir().unwrap();
    // A recording with every column of the map: stator temperatures ramp 20 → 40 °C, and the
    // tool cuts 1.25 mm deep for a quarter second every half second.
    let columns = register_map::sample_columns();
    let mut text = columns.join(",") + "\n";
    for i in 0..=200 {
        let row: Vec<String> = columns
            .iter()
            .map(|name| match name.as_str() {
                "time_s" => format!("{}", i as f64 * 0.05),
                n if n.ends_with("stator_temp_C") => format!("{}", 20.0 + i as f64 * 0.1),
                "coolant_on" => "1".into(),
                CUT_DEPTH if i % 10 >= 5 => "1.25".into(),
                _ => "0".into(),
            })
            .collect();
        text.push_str(&(row.join(",") + "\n"));
    }
    let source = dir.path().join("source.csv");
    std::fs::write(&source, text).unwrap();
    let pair = pty_pair(dir.path(), "line");
    let _controller = Process(
        servosight()
            .arg("sim-controller")
            .arg("--port")
            .arg(&pair.b)
            .arg("--replay")
            .arg(&source)
            .stderr(Stdio::null())
            .spawn()
            .unwrap(),
    );
    let mut link = ControllerLink::modbus(config(&pair.a, 100.0)).unwrap();
    let mut frames = Vec::new();
    wait_connected(&mut link, &mut frames);
    pump(
        &mut link,
        Duration::from_secs(2),
        &mut |f| frames.push(f),
        |_| false,
    );
    let temp = link
        .schema()
        .index_of(&axis_column(AxisId::X, Quantity::StatorTemp))
        .unwrap();
    let temps: Vec<f64> = frames.iter().map(|f| f.row[temp]).collect();
    assert!(temps.len() > 100);
    assert!(temps.iter().all(|t| (20.0..=40.0).contains(t)), "{temps:?}");
    assert!(
        temps.last().unwrap() > temps.first().unwrap(),
        "the replay advances"
    );
    assert_eq!(link.status().stats.lost_samples, 0);
    let depth = link.schema().index_of(CUT_DEPTH).unwrap();
    let depths: Vec<f64> = frames.iter().map(|f| f.row[depth]).collect();
    assert!(
        depths.contains(&1.25) && depths.contains(&0.0),
        "{depths:?}"
    );
    assert!(depths.iter().all(|d| *d == 0.0 || *d == 1.25), "{depths:?}");

    let offset = CompensationId::ThermalOffset(AxisId::Z);
    let approved = Request::new(proposal(&[(offset, -15.0)]), "otto")
        .unwrap()
        .approve(&users(), "maria", "pw-maria")
        .unwrap();
    let mut audit = AuditLog::open(&dir.path().join("audit.jsonl")).unwrap();
    let report =
        compensation::apply(&link, &CompensationLimits::default(), &mut audit, approved).unwrap();
    assert_eq!(report.steps, 1);
    assert_eq!(
        link.read_compensation().wait().unwrap().get(offset),
        Some(-15.0)
    );
}

#[test]
fn sim_controller_refuses_a_recording_without_the_depth_of_cut() {
    // Serving it would put 0 ("not cutting") on the line for every cut in the file.
    let dir = tempfile::tempdir().unwrap();
    let columns: Vec<String> = register_map::sample_columns()
        .into_iter()
        .filter(|c| c != CUT_DEPTH)
        .collect();
    let row = vec!["1"; columns.len()].join(",");
    let source = dir.path().join("old.csv");
    std::fs::write(&source, format!("{}\n{row}\n", columns.join(","))).unwrap();
    let output = servosight()
        .arg("sim-controller")
        .arg("--port")
        .arg(dir.path().join("no-such-port"))
        .arg("--replay")
        .arg(&source)
        .output()
        .unwrap();
    assert!(!output.status.success());
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(stderr.contains("no column `cut_depth_mm`"), "{stderr}");
    assert!(stderr.contains("servosight --replay"), "{stderr}");
}

#[test]
fn sim_controller_serves_the_twin_with_z_at_rest() {
    require_tools();
    let dir = tempfile::tempdir().unwrap();
    let pair = pty_pair(dir.path(), "line");
    let _controller = Process(
        servosight()
            .args([
                "sim-controller",
                "--scenario",
                "production",
                "--speed",
                "600",
            ])
            .arg("--port")
            .arg(&pair.b)
            .stderr(Stdio::null())
            .spawn()
            .unwrap(),
    );
    let mut link = ControllerLink::modbus(config(&pair.a, 50.0)).unwrap();
    let mut frames = Vec::new();
    wait_connected(&mut link, &mut frames);
    // 600×: the shift's 15-minute spindle warm-up (no cutting) is over after 1.5 s, and the
    // first part's roughing follows.
    pump(
        &mut link,
        Duration::from_secs(4),
        &mut |f| frames.push(f),
        |_| false,
    );
    let schema = link.schema().clone();
    let column = |axis, quantity| {
        let i = schema.index_of(&axis_column(axis, quantity)).unwrap();
        frames.iter().map(move |f| f.row[i]).collect::<Vec<f64>>()
    };
    let ambient_index = schema.index_of("ambient_C").unwrap();
    // The twin's X and S move; Z is published at rest, its stator at room temperature.
    let x_position = column(AxisId::X, Quantity::Position);
    assert!(
        x_position.iter().any(|p| (p - x_position[0]).abs() > 1e-3),
        "X never moved in 40 simulated minutes"
    );
    // The twin's depth of cut reaches the client: 0 out of the cut, the programmed depth
    // (0.2 to 4 mm on this twin) in it.
    let depth_index = schema.index_of(CUT_DEPTH).unwrap();
    let depths: Vec<f64> = frames.iter().map(|f| f.row[depth_index]).collect();
    assert!(depths.contains(&0.0), "never out of the cut");
    assert!(
        depths.iter().any(|d| (0.2..=4.0).contains(d)),
        "the twin never cut in 40 simulated minutes"
    );
    assert!(depths.iter().all(|d| *d == 0.0 || (0.2..=4.0).contains(d)));
    assert!(
        column(AxisId::S, Quantity::StatorTemp)
            .iter()
            .all(|t| (0.0..150.0).contains(t))
    );
    assert!(column(AxisId::Z, Quantity::Speed).iter().all(|v| *v == 0.0));
    for frame in &frames {
        let z_temp = frame.row[schema
            .index_of(&axis_column(AxisId::Z, Quantity::StatorTemp))
            .unwrap()];
        assert!(
            (z_temp - frame.row[ambient_index]).abs() < 0.006,
            "{z_temp}"
        );
    }
    let backlash = CompensationId::Backlash(AxisId::X);
    let approved = Request::new(proposal(&[(backlash, 4.0)]), "otto")
        .unwrap()
        .approve(&users(), "maria", "pw-maria")
        .unwrap();
    let mut audit = AuditLog::open(&dir.path().join("audit.jsonl")).unwrap();
    compensation::apply(&link, &CompensationLimits::default(), &mut audit, approved).unwrap();
    assert_eq!(
        link.read_compensation().wait().unwrap().get(backlash),
        Some(4.0)
    );
}
