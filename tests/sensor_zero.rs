//! A current sensor whose zero falls through the drive's floor, made from a recording, and the
//! column mapping it is made with: shared by the integration tests and the discrepancy bench
//! (`#[path]`), which cannot reach each other.

use servosight::signal::Recording;

/// `recording` with `column` read by a sensor whose zero falls `per_hour` from the first row,
/// cut off at 0 as a drive reports a magnitude.
pub fn with_zero_falling(recording: &Recording, column: &str, per_hour: f64) -> Recording {
    with_column_mapped(recording, column, |time_s, value| {
        (value - per_hour * time_s / 3600.0).max(0.0)
    })
}

/// `recording` with `column` replaced by `f(time, value)` row by row.
pub fn with_column_mapped(
    recording: &Recording,
    column: &str,
    f: impl Fn(f64, f64) -> f64,
) -> Recording {
    let index = recording
        .schema()
        .index_of(column)
        .expect("the column is recorded");
    let mut read =
        Recording::with_schema(recording.source().to_string(), recording.schema().clone());
    let mut row = Vec::new();
    for i in 0..recording.len() {
        recording.row_into(i, &mut row);
        row[index] = f(recording.time()[i], row[index]);
        read.push_row(&row).expect("mapped values stay valid");
    }
    read
}
