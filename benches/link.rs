//! The controller link's replay (issue 6): how fast a recording replayed as fast as possible
//! reaches the link's consumer.
//!
//! `cargo bench --bench link`.

use std::time::Duration;

use criterion::{Criterion, Throughput};
use servosight::link::{ControllerLink, ReplayOptions, ReplaySpeed};

const ROWS: usize = 20_000;

/// A 1 kHz recording of `ROWS` rows of an axis's speed and torque.
fn write_recording(path: &std::path::Path) {
    let mut text = String::from("# machine: bench\ntime_s,X.speed_rpm,X.torque_Nm\n");
    for i in 0..ROWS {
        let t = i as f64 / 1000.0;
        text.push_str(&format!(
            "{t},{},{}\n",
            1000.0 * (t * 0.3).sin(),
            (t * 2.0).cos()
        ));
    }
    std::fs::write(path, text).expect("the bench writes its recording");
}

fn replay(c: &mut Criterion) {
    let dir = std::env::temp_dir().join(format!("servosight-bench-link-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("a temporary directory");
    let path = dir.join("replay.csv");
    write_recording(&path);
    let mut group = c.benchmark_group("link");
    group.throughput(Throughput::Elements(ROWS as u64));
    group.sample_size(10);
    group.measurement_time(Duration::from_secs(10));
    group.bench_function("replay_as_fast_as_possible_20k_rows", |b| {
        b.iter(|| {
            let options = ReplayOptions {
                speed: ReplaySpeed::AsFastAsPossible,
                ..ReplayOptions::default()
            };
            let mut link = ControllerLink::replay(std::slice::from_ref(&path), options)
                .expect("the replay opens");
            let mut received = 0;
            while received < ROWS {
                match link.try_next_frame() {
                    Some(_) => received += 1,
                    None => std::thread::yield_now(),
                }
            }
        })
    });
    group.finish();
    let _ = std::fs::remove_dir_all(&dir);
}

fn main() {
    let mut criterion = Criterion::default().configure_from_args();
    replay(&mut criterion);
    criterion.final_summary();
}
