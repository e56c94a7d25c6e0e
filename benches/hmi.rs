//! HMI benchmarks (issue 7): the history pyramid with a 10-hour, 1 kHz, 5-axis history, the
//! CPU time of a whole UI frame on it, and the sample-to-screen latency at 1 kHz.
//!
//! `cargo bench --bench hmi`. Before criterion runs, the bench builds the 10-hour history
//! once and prints its ingest rate and memory, then measures latency on a live 1 kHz twin.

use std::hint::black_box;
use std::time::{Duration, Instant};

use criterion::{BatchSize, Criterion, Throughput};
use eframe::egui;
use servosight::compensation::CompensationLimits;
use servosight::link::{ConnectionState, ReplaySpeed};
use servosight::signal::channel::{AMBIENT, COOLANT, CUT_DEPTH, TIME};
use servosight::signal::{AxisId, Quantity, axis_column};
use servosight::sim::{ScenarioKind, TwinConfig};
use servosight::ui::history::{DEFAULT_HISTORY_BUDGET_BYTES, History, HistoryConfig};
use servosight::ui::panels::{self, Forms};
use servosight::ui::session::{SessionUpdate, SourceSpec};
use servosight::ui::state::{CompensationState, HmiState, LinkSnapshot};
use servosight::ui::vm::trends::{TrendsSettings, WindowPreset};
use servosight::ui::{Session, SessionConfig, vm};

const AXES: [AxisId; 5] = [AxisId::X, AxisId::Y, AxisId::Z, AxisId::S, AxisId::C];
const RATE_HZ: f64 = 1000.0;
const HOURS: f64 = 10.0;

fn names() -> Vec<String> {
    let mut names = vec![TIME.to_string()];
    for axis in AXES {
        for quantity in Quantity::ALL {
            names.push(axis_column(axis, quantity));
        }
    }
    names.extend([
        AMBIENT.to_string(),
        COOLANT.to_string(),
        CUT_DEPTH.to_string(),
    ]);
    names
}

/// A plausible 5-axis row at `t`: slow thermal drifts plus fast servo motion.
fn fill_row(t: f64, row: &mut [f64]) {
    for (c, value) in row.iter_mut().enumerate() {
        let phase = c as f64 * 0.37;
        *value = 40.0 + 10.0 * (t / 3600.0 + phase).sin() + (t * 3.1 + phase).sin();
    }
}

/// 4096 distinct rows of plausible values.
fn row_table(channels: usize) -> Vec<Vec<f64>> {
    (0..4096)
        .map(|i| {
            let mut row = vec![0.0; channels];
            fill_row(i as f64 * 0.87, &mut row);
            row
        })
        .collect()
}

fn resident_kib() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    status
        .lines()
        .find(|l| l.starts_with("VmRSS:"))?
        .split_whitespace()
        .nth(1)?
        .parse()
        .ok()
}

fn build_ten_hours() -> History {
    let names = names();
    let channels: Vec<String> = names[1..].to_vec();
    let config = HistoryConfig::for_budget(channels.len(), DEFAULT_HISTORY_BUDGET_BYTES);
    let mut history = History::new(channels.clone(), config);
    let samples = (HOURS * 3600.0 * RATE_HZ) as u64;
    // Rows are generated up front (an hour's worth of distinct slow drift, cycled) so the
    // timing is the pyramid's, not the sine function's.
    let table = row_table(channels.len());
    let rss_before = resident_kib();
    let started = Instant::now();
    for i in 0..samples {
        let t = i as f64 / RATE_HZ;
        history.push(t, &table[i as usize % table.len()]);
    }
    let elapsed = started.elapsed().as_secs_f64();
    eprintln!(
        "history: {samples} samples × {} channels ({HOURS} h at {RATE_HZ} Hz) ingested in {elapsed:.2} s \
         ({:.1} M samples/s, {:.0}× real time); pyramid {:.0} MiB (budget {} MiB); \
         resident memory {} → {} MiB",
        channels.len(),
        samples as f64 / elapsed / 1e6,
        HOURS * 3600.0 / elapsed,
        history.memory_bytes() as f64 / 1048576.0,
        DEFAULT_HISTORY_BUDGET_BYTES / 1048576,
        rss_before.map_or(0, |k| k / 1024),
        resident_kib().map_or(0, |k| k / 1024),
    );
    history
}

fn state_with(history: History) -> HmiState {
    let link = LinkSnapshot {
        state: ConnectionState::Connected,
        ..LinkSnapshot::starting("bench")
    };
    let compensation = CompensationState::new(
        "users.toml".into(),
        "audit.jsonl".into(),
        CompensationLimits::default(),
    );
    let mut state = HmiState::new(names(), link, 1 << 20, compensation);
    let newest = history.newest_time_s().unwrap_or(0.0);
    let mut row = vec![0.0; names().len()];
    row[0] = newest;
    fill_row(newest, &mut row[1..]);
    state.latest.row = row;
    state.history = history;
    state
}

fn settings(preset: WindowPreset) -> TrendsSettings {
    TrendsSettings {
        selected: AXES
            .iter()
            .flat_map(|a| {
                [
                    axis_column(*a, Quantity::StatorTemp),
                    axis_column(*a, Quantity::Load),
                ]
            })
            .collect(),
        preset,
        ..TrendsSettings::default()
    }
}

/// One whole UI frame of the Trends panel: view model, layout and drawing, tessellation.
fn trends_frame(ctx: &egui::Context, state: &HmiState, settings: &TrendsSettings) -> usize {
    let input = egui::RawInput {
        screen_rect: Some(egui::Rect::from_min_size(
            egui::Pos2::ZERO,
            egui::vec2(1600.0, 1000.0),
        )),
        ..Default::default()
    };
    let mut forms = Forms::default();
    let mut commands = Vec::new();
    let output = ctx.run_ui(input, |ui| {
        let view = vm::trends::build(state, settings, 1000);
        panels::trends::trends_ui(ui, &view, &mut forms, None, &mut commands);
    });
    let primitives = ctx.tessellate(output.shapes, output.pixels_per_point);
    primitives.len()
}

fn overview_frame(ctx: &egui::Context, state: &HmiState) -> usize {
    let input = egui::RawInput {
        screen_rect: Some(egui::Rect::from_min_size(
            egui::Pos2::ZERO,
            egui::vec2(1600.0, 1000.0),
        )),
        ..Default::default()
    };
    let output = ctx.run_ui(input, |ui| {
        let view = vm::overview::build(state);
        egui::CentralPanel::default().show(ui, |ui| panels::overview::overview_ui(ui, &view));
    });
    ctx.tessellate(output.shapes, output.pixels_per_point).len()
}

/// Runs the twin at 1 kHz through the real session for a few seconds with a UI loop at the
/// app's 33 ms cadence, and reports how old the oldest sample of each batch is when the frame
/// that shows it is finished.
fn latency_report() {
    let mut twin = TwinConfig::new(ScenarioKind::Production, None, 3);
    twin.rate_hz = RATE_HZ;
    let config = SessionConfig {
        source: SourceSpec::Twin {
            config: Box::new(twin),
            speed: ReplaySpeed::Factor(1.0),
        },
        record_dir: None,
        users_path: std::env::temp_dir().join("servosight-bench-users.toml"),
        audit_path: std::env::temp_dir().join("servosight-bench-audit.jsonl"),
        limits: CompensationLimits::default(),
        profile: None,
        data_dir: std::env::temp_dir().join("servosight-bench-data"),
    };
    let Ok(mut session) = Session::start(config) else {
        eprintln!("latency: the session did not start");
        return;
    };
    let mut state = state_with(History::new(
        names()[1..].to_vec(),
        HistoryConfig::for_budget(names().len() - 1, 64 << 20),
    ));
    state.history = History::new(
        session.schema().names()[1..].to_vec(),
        HistoryConfig::for_budget(session.schema().len(), 64 << 20),
    );
    state.latest.names = session.schema().names().to_vec();
    let ctx = egui::Context::default();
    let trend_settings = TrendsSettings {
        selected: vec![
            axis_column(AxisId::X, Quantity::StatorTemp),
            axis_column(AxisId::S, Quantity::Load),
        ],
        preset: WindowPreset::Minute,
        ..TrendsSettings::default()
    };
    let mut ages_ms = Vec::new();
    let mut frames_ms = Vec::new();
    let mut samples = 0usize;
    let end = Instant::now() + Duration::from_secs(6);
    while Instant::now() < end {
        let frame_start = Instant::now();
        let mut oldest: Option<Instant> = None;
        let budget = Instant::now() + Duration::from_millis(4);
        while Instant::now() < budget {
            match session.try_recv() {
                Some(SessionUpdate::Frames(batch)) => {
                    samples += batch.rows.len();
                    oldest = Some(oldest.map_or(batch.received_at, |o| o.min(batch.received_at)));
                    state.apply(SessionUpdate::Frames(batch));
                }
                Some(other) => state.apply(other),
                None => break,
            }
        }
        trends_frame(&ctx, &state, &trend_settings);
        if let Some(oldest) = oldest {
            ages_ms.push(oldest.elapsed().as_secs_f64() * 1e3);
        }
        frames_ms.push(frame_start.elapsed().as_secs_f64() * 1e3);
        std::thread::sleep(Duration::from_millis(33).saturating_sub(frame_start.elapsed()));
    }
    drop(session);
    // The first second is start-up (the runtime and the twin warming up).
    let skip = ages_ms.len() / 6;
    let mut steady: Vec<f64> = ages_ms[skip..].to_vec();
    steady.sort_by(f64::total_cmp);
    let percentile = |p: f64| steady[((steady.len() - 1) as f64 * p) as usize];
    frames_ms.sort_by(f64::total_cmp);
    if steady.is_empty() {
        eprintln!("latency: no frames arrived");
        return;
    }
    eprintln!(
        "latency at {RATE_HZ} Hz: {samples} samples in 6 s; oldest sample of each frame, \
         session receipt to finished frame: median {:.1} ms, p95 {:.1} ms, max {:.1} ms; \
         frame CPU median {:.2} ms",
        percentile(0.5),
        percentile(0.95),
        steady[steady.len() - 1],
        frames_ms[frames_ms.len() / 2],
    );
}

fn main() {
    latency_report();
    let history = build_ten_hours();
    let mut c = Criterion::default()
        .configure_from_args()
        .sample_size(20)
        .measurement_time(Duration::from_secs(5));

    let mut ingest = c.benchmark_group("history_ingest");
    let channels = names().len() - 1;
    let rows: u64 = 100_000;
    ingest.throughput(Throughput::Elements(rows));
    ingest.bench_function("push_100k_rows_38_channels", |b| {
        let table = row_table(channels);
        b.iter_batched(
            || {
                History::new(
                    names()[1..].to_vec(),
                    HistoryConfig::for_budget(channels, 256 << 20),
                )
            },
            |mut h| {
                for i in 0..rows {
                    h.push(i as f64 * 1e-3, &table[i as usize % table.len()]);
                }
                h
            },
            BatchSize::LargeInput,
        );
    });
    ingest.finish();

    let mut query = c.benchmark_group("history_window_10h");
    let newest = history.newest_time_s().unwrap_or(0.0);
    let selected: Vec<usize> = (0..10).map(|k| k * 3).collect();
    for (name, length) in [
        ("last_minute", 60.0),
        ("last_hour", 3600.0),
        ("all_10h", HOURS * 3600.0),
    ] {
        query.bench_function(format!("{name}_10_channels_1000_points"), |b| {
            b.iter(|| black_box(history.window(&selected, newest - length, newest, 1000)))
        });
    }
    query.finish();

    let state = state_with(history);
    let ctx = egui::Context::default();
    let mut frame = c.benchmark_group("frame_10h_history");
    for (name, preset) in [
        ("trends_10_series_last_minute", WindowPreset::Minute),
        ("trends_10_series_last_hour", WindowPreset::Hour),
        ("trends_10_series_all_10h", WindowPreset::All),
    ] {
        let settings = settings(preset);
        frame.bench_function(name, |b| {
            b.iter(|| black_box(trends_frame(&ctx, &state, &settings)))
        });
    }
    frame.bench_function("overview_5_axes", |b| {
        b.iter(|| black_box(overview_frame(&ctx, &state)))
    });
    frame.finish();
    c.final_summary();
}
