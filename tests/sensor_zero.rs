//! A current sensor whose zero falls through the drive's floor, made from a recording: shared by
//! the integration tests and the discrepancy bench (`#[path]`), which cannot reach each other.

use servosight::signal::Recording;

/// `recording` with `column` read by a sensor whose zero falls `per_hour` from the first row,
/// cut off at 0 as a drive reports a magnitude.
pub fn with_zero_falling(recording: &Recording, column: &str, per_hour: f64) -> Recording {
    let index = recording
        .schema()
        .index_of(column)
        .expect("the column is recorded");
    let mut read =
        Recording::with_schema(recording.source().to_string(), recording.schema().clone());
    let mut row = Vec::new();
    for i in 0..recording.len() {
        recording.row_into(i, &mut row);
        row[index] = (row[index] - per_hour * recording.time()[i] / 3600.0).max(0.0);
        read.push_row(&row).expect("rows of a valid recording");
    }
    read
}
