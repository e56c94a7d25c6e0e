//! CSV ingest throughput on a wide numeric recording (DESIGN target: ≥ 150 MB/s).

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use servosight::signal::{Recording, RecordingReader, write_recording_to};

/// A wide recording like a 5-axis controller export: 1 kHz, 64 numeric columns of servo-like
/// values with realistic digit counts.
fn wide_recording_bytes(rows: usize, columns: usize) -> Vec<u8> {
    let mut names = vec!["time_s".to_string()];
    names.extend((1..columns).map(|c| format!("ch{c}.value_u")));
    let mut rec = Recording::new("bench", names).expect("valid names");
    let mut row = vec![0.0; columns];
    for r in 0..rows {
        row[0] = r as f64 * 0.001;
        for (c, v) in row.iter_mut().enumerate().skip(1) {
            *v = ((r * 31 + c * 17) % 10_000) as f64 * 0.0137 - 40.0;
        }
        rec.push_row(&row).expect("finite, increasing time");
    }
    write_recording_to(Vec::new(), &rec).expect("in-memory write")
}

fn ingest(c: &mut Criterion) {
    let bytes = wide_recording_bytes(100_000, 64);
    let mut group = c.benchmark_group("csv_ingest");
    group.throughput(Throughput::Bytes(bytes.len() as u64));
    group.sample_size(10);
    group.bench_function("wide_64_columns_100k_rows", |b| {
        b.iter(|| {
            RecordingReader::from_reader(bytes.as_slice(), "bench")
                .and_then(|r| r.read_to_end())
                .expect("valid recording")
                .len()
        })
    });
    group.finish();
}

criterion_group!(benches, ingest);
criterion_main!(benches);
