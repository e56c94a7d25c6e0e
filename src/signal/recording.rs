//! The columnar, in-memory recording and the schema that names its columns.

use std::collections::HashMap;
use std::sync::Arc;

use super::channel::{TIME, plausible_range_of};
use super::error::{Location, RecordingError, Separator};

/// The ordered column names of a recording or a frame stream, with a name → index map.
///
/// Cheap to clone (shared). Streaming consumers resolve the columns they need to indices once,
/// then read frames by index without hashing or allocating.
#[derive(Debug, Clone, PartialEq)]
pub struct Schema {
    inner: Arc<SchemaInner>,
}

#[derive(Debug, PartialEq)]
struct SchemaInner {
    names: Vec<String>,
    index: HashMap<String, usize>,
    ranges: Vec<Option<(f64, f64)>>,
}

impl Schema {
    /// Builds a schema; `names[0]` must be `time_s` and names must be unique and non-empty.
    /// `source` names the file or stream in errors.
    pub fn new(names: Vec<String>, source: &str) -> Result<Schema, RecordingError> {
        Self::with_header_line(names, source, 1)
    }

    pub(crate) fn with_header_line(
        names: Vec<String>,
        source: &str,
        line: u64,
    ) -> Result<Schema, RecordingError> {
        let at = |column: Option<(usize, String)>| Location {
            source: source.to_string(),
            line,
            column,
        };
        match names.first() {
            Some(first) if first == TIME => {}
            Some(first) => {
                // The csv reader split the header at commas; a header that starts `time_s`
                // and goes on after another separator was written with that one.
                let separator = match first
                    .strip_prefix(TIME)
                    .and_then(|rest| rest.chars().next())
                {
                    Some(';') => Some(Separator::Semicolon),
                    Some('\t') => Some(Separator::Tab),
                    _ => None,
                };
                if let Some(separator) = separator {
                    return Err(RecordingError::NotCommaSeparated {
                        at: at(None),
                        separator,
                    });
                }
                return Err(RecordingError::FirstColumnNotTime {
                    at: at(None),
                    found: first.clone(),
                });
            }
            None => {
                return Err(RecordingError::NoHeader {
                    source_name: source.to_string(),
                });
            }
        }
        let mut index = HashMap::with_capacity(names.len());
        for (i, name) in names.iter().enumerate() {
            if name.is_empty() {
                return Err(RecordingError::EmptyColumnName {
                    at: at(Some((i + 1, String::new()))),
                });
            }
            if let Some(first) = index.insert(name.clone(), i) {
                return Err(RecordingError::DuplicateColumn {
                    at: at(Some((i + 1, name.clone()))),
                    name: name.clone(),
                    first: first + 1,
                });
            }
        }
        let ranges = names.iter().map(|n| plausible_range_of(n)).collect();
        Ok(Schema {
            inner: Arc::new(SchemaInner {
                names,
                index,
                ranges,
            }),
        })
    }

    /// Column names in order; the first is `time_s`.
    pub fn names(&self) -> &[String] {
        &self.inner.names
    }

    /// Number of columns, `time_s` included.
    pub fn len(&self) -> usize {
        self.inner.names.len()
    }

    /// Never true: a schema always has `time_s`.
    pub fn is_empty(&self) -> bool {
        self.inner.names.is_empty()
    }

    /// The index of a column, if present.
    pub fn index_of(&self, name: &str) -> Option<usize> {
        self.inner.index.get(name).copied()
    }

    /// Checks one row against the schema: field count, finite values, plausible ranges, time
    /// order. `line` and `source` locate the row in errors.
    pub(crate) fn check_row(
        &self,
        row: &[f64],
        previous_time: Option<f64>,
        source: &str,
        line: u64,
    ) -> Result<(), RecordingError> {
        let at = |i: Option<usize>| Location {
            source: source.to_string(),
            line,
            column: i.map(|i| (i + 1, self.inner.names[i].clone())),
        };
        if row.len() != self.len() {
            return Err(RecordingError::FieldCount {
                at: at(None),
                expected: self.len(),
                found: row.len(),
            });
        }
        for (i, (&value, range)) in row.iter().zip(&self.inner.ranges).enumerate() {
            if !value.is_finite() {
                return Err(RecordingError::NonFinite {
                    at: at(Some(i)),
                    cell: value.to_string(),
                });
            }
            if let Some((low, high)) = *range
                && !(low..=high).contains(&value)
            {
                return Err(RecordingError::OutOfRange {
                    at: at(Some(i)),
                    value,
                    low,
                    high,
                });
            }
        }
        if let Some(previous_s) = previous_time
            && row[0] < previous_s
        {
            return Err(RecordingError::TimeBackwards {
                at: at(Some(0)),
                time_s: row[0],
                previous_s,
            });
        }
        Ok(())
    }

    /// The plausible range of column `i`, if the format defines one.
    pub(crate) fn range_of(&self, i: usize) -> Option<(f64, f64)> {
        self.inner.ranges[i]
    }
}

/// A whole recording in memory, stored column by column.
///
/// Invariants (kept by every constructor and mutator): column 0 is `time_s` and non-decreasing,
/// every value is finite, every column has the same length.
#[derive(Debug, Clone, PartialEq)]
pub struct Recording {
    source: String,
    metadata: Vec<(String, String)>,
    schema: Schema,
    columns: Vec<Vec<f64>>,
}

impl Recording {
    /// An empty recording with the given columns. `source` names it in errors (a file name, or
    /// something like `simulation`).
    pub fn new(source: impl Into<String>, names: Vec<String>) -> Result<Recording, RecordingError> {
        let source = source.into();
        let schema = Schema::new(names, &source)?;
        Ok(Self::with_schema(source, schema))
    }

    /// An empty recording with an existing schema.
    pub fn with_schema(source: impl Into<String>, schema: Schema) -> Recording {
        let columns = vec![Vec::new(); schema.len()];
        Recording {
            source: source.into(),
            metadata: Vec::new(),
            schema,
            columns,
        }
    }

    /// Its metadata and columns, in the schema's order, moved out (no copy).
    pub(crate) fn into_metadata_and_columns(self) -> (Vec<(String, String)>, Vec<Vec<f64>>) {
        (self.metadata, self.columns)
    }

    pub(crate) fn from_parts(
        source: String,
        metadata: Vec<(String, String)>,
        schema: Schema,
        columns: Vec<Vec<f64>>,
    ) -> Recording {
        Recording {
            source,
            metadata,
            schema,
            columns,
        }
    }

    /// The name used in errors (usually the file it was read from).
    pub fn source(&self) -> &str {
        &self.source
    }

    /// The `# key: value` metadata, in file order.
    pub fn metadata(&self) -> &[(String, String)] {
        &self.metadata
    }

    /// The value of a metadata key.
    pub fn metadata_value(&self, key: &str) -> Option<&str> {
        self.metadata
            .iter()
            .find(|(k, _)| k == key)
            .map(|(_, v)| v.as_str())
    }

    /// Sets (or replaces) a metadata entry. Keys must not contain `:` or line breaks, values
    /// must not contain line breaks; offending characters are replaced by spaces.
    pub fn set_metadata(&mut self, key: &str, value: &str) {
        let clean = |s: &str, also_colon: bool| {
            s.chars()
                .map(|c| {
                    if c == '\n' || c == '\r' || (also_colon && c == ':') {
                        ' '
                    } else {
                        c
                    }
                })
                .collect::<String>()
                .trim()
                .to_string()
        };
        let key = clean(key, true);
        let value = clean(value, false);
        match self.metadata.iter_mut().find(|(k, _)| *k == key) {
            Some(entry) => entry.1 = value,
            None => self.metadata.push((key, value)),
        }
    }

    /// The schema (column names).
    pub fn schema(&self) -> &Schema {
        &self.schema
    }

    /// Column names in order.
    pub fn names(&self) -> &[String] {
        self.schema.names()
    }

    /// Number of rows.
    pub fn len(&self) -> usize {
        self.columns[0].len()
    }

    /// True when there are no rows.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The `time_s` column.
    pub fn time(&self) -> &[f64] {
        &self.columns[0]
    }

    /// A column by name, or an error naming the recording and the missing column.
    pub fn column(&self, name: &str) -> Result<&[f64], RecordingError> {
        self.try_column(name)
            .ok_or_else(|| RecordingError::MissingColumn {
                source_name: self.source.clone(),
                name: name.to_string(),
                needed_for: None,
            })
    }

    /// A column by name, or an error that also says what needed it.
    pub fn column_for(&self, name: &str, needed_for: &str) -> Result<&[f64], RecordingError> {
        self.try_column(name)
            .ok_or_else(|| RecordingError::MissingColumn {
                source_name: self.source.clone(),
                name: name.to_string(),
                needed_for: Some(needed_for.to_string()),
            })
    }

    /// A column by name, `None` when absent.
    pub fn try_column(&self, name: &str) -> Option<&[f64]> {
        self.schema
            .index_of(name)
            .map(|i| self.columns[i].as_slice())
    }

    /// A column by index (0 is `time_s`).
    pub fn column_at(&self, index: usize) -> &[f64] {
        &self.columns[index]
    }

    /// Appends one row, checked like a row read from a file: right length, finite values inside
    /// their plausible ranges, time not going backwards. On error nothing is appended.
    pub fn push_row(&mut self, row: &[f64]) -> Result<(), RecordingError> {
        let line = self.len() as u64 + 2;
        self.schema
            .check_row(row, self.time().last().copied(), &self.source, line)?;
        for (column, &value) in self.columns.iter_mut().zip(row) {
            column.push(value);
        }
        Ok(())
    }

    /// Copies row `i` into `out` (cleared first), in schema order.
    pub fn row_into(&self, i: usize, out: &mut Vec<f64>) {
        out.clear();
        out.extend(self.columns.iter().map(|c| c[i]));
    }

    /// Adds a derived column (an estimate, say). Its values must be finite and as many as rows;
    /// a name that already exists is an error.
    pub fn add_column(&mut self, name: &str, values: Vec<f64>) -> Result<(), RecordingError> {
        if values.len() != self.len() {
            return Err(RecordingError::ColumnLength {
                source_name: self.source.clone(),
                name: name.to_string(),
                expected: self.len(),
                found: values.len(),
            });
        }
        if let Some(i) = values.iter().position(|v| !v.is_finite()) {
            return Err(RecordingError::NonFinite {
                at: Location {
                    source: self.source.clone(),
                    line: i as u64 + 2,
                    column: Some((self.schema.len() + 1, name.to_string())),
                },
                cell: values[i].to_string(),
            });
        }
        let mut names = self.schema.names().to_vec();
        names.push(name.to_string());
        self.schema = Schema::new(names, &self.source)?;
        self.columns.push(values);
        Ok(())
    }

    /// Seconds from the first to the last sample (0 for fewer than two rows).
    pub fn duration_s(&self) -> f64 {
        match (self.time().first(), self.time().last()) {
            (Some(first), Some(last)) => last - first,
            _ => 0.0,
        }
    }

    /// The typical sample interval: the median of the positive time steps. `None` when there are
    /// fewer than two distinct times.
    pub fn median_step_s(&self) -> Option<f64> {
        let mut steps: Vec<f64> = self
            .time()
            .windows(2)
            .map(|w| w[1] - w[0])
            .filter(|d| *d > 0.0)
            .collect();
        if steps.is_empty() {
            return None;
        }
        let mid = steps.len() / 2;
        let (_, median, _) = steps.select_nth_unstable_by(mid, f64::total_cmp);
        Some(*median)
    }

    /// The sample rate implied by [`Recording::median_step_s`].
    pub fn sample_rate_hz(&self) -> Option<f64> {
        self.median_step_s().map(|dt| 1.0 / dt)
    }

    /// Time gaps longer than `factor` × the median step: `(row before the gap, gap length s)`.
    pub fn gaps(&self, factor: f64) -> Vec<(usize, f64)> {
        let Some(step) = self.median_step_s() else {
            return Vec::new();
        };
        self.time()
            .windows(2)
            .enumerate()
            .filter_map(|(i, w)| {
                let d = w[1] - w[0];
                (d > factor * step).then_some((i, d))
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(list: &[&str]) -> Vec<String> {
        list.iter().map(|s| s.to_string()).collect()
    }

    #[test]
    fn push_row_rejects_backwards_time_and_keeps_earlier_rows() {
        let mut rec = Recording::new("test", names(&["time_s", "X.speed_rpm"])).unwrap();
        rec.push_row(&[0.0, 10.0]).unwrap();
        rec.push_row(&[1.0, 11.0]).unwrap();
        let err = rec.push_row(&[0.5, 12.0]).unwrap_err();
        assert!(matches!(err, RecordingError::TimeBackwards { .. }), "{err}");
        assert_eq!(rec.len(), 2);
        assert_eq!(rec.column("X.speed_rpm").unwrap(), &[10.0, 11.0]);
    }

    #[test]
    fn push_row_rejects_nan_and_implausible_values_naming_the_column() {
        let mut rec =
            Recording::new("live", names(&["time_s", "X.stator_temp_C", "mine"])).unwrap();
        let err = rec.push_row(&[0.0, f64::NAN, 1.0]).unwrap_err().to_string();
        assert!(
            err.contains("X.stator_temp_C") && err.contains("finite"),
            "{err}"
        );
        let err = rec.push_row(&[0.0, 900.0, 1.0]).unwrap_err().to_string();
        assert!(err.contains("plausible range"), "{err}");
        // Unknown columns have no range.
        rec.push_row(&[0.0, 30.0, 1.0e12]).unwrap();
    }

    #[test]
    fn schema_rejects_duplicates_and_wrong_first_column() {
        let err = Schema::new(names(&["time_s", "a", "a"]), "f.csv").unwrap_err();
        assert!(err.to_string().contains("duplicate column `a`"), "{err}");
        let err = Schema::new(names(&["t", "a"]), "f.csv").unwrap_err();
        assert!(err.to_string().contains("must be `time_s`"), "{err}");
    }

    #[test]
    fn missing_column_error_names_source_column_and_purpose() {
        let rec = Recording::new("day.csv", names(&["time_s"])).unwrap();
        let err = rec
            .column_for("S.speed_rpm", "spindle elongation")
            .unwrap_err();
        assert_eq!(
            err.to_string(),
            "day.csv: no column `S.speed_rpm` (needed for spindle elongation)"
        );
    }

    #[test]
    fn sample_rate_and_gaps() {
        let mut rec = Recording::new("t", names(&["time_s"])).unwrap();
        for t in [0.0, 0.5, 1.0, 1.5, 5.0, 5.5] {
            rec.push_row(&[t]).unwrap();
        }
        assert_eq!(rec.sample_rate_hz(), Some(2.0));
        assert_eq!(rec.gaps(3.0), vec![(3, 3.5)]);
    }
}
