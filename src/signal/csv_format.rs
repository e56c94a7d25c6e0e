//! Recording format v1 on disk: a streaming reader and writer.
//!
//! ```text
//! # machine: IT-25
//! # scenario: production
//! time_s,S.speed_rpm,S.torque_Nm,ambient_C,ref.S.elongation_um
//! 0,0,0,21.3,0
//! 1,1500,12.5,21.3,0.4
//! ```
//!
//! UTF-8, comma separated, one header row, one row per sample. Lines that start with `#` before
//! the header are metadata (`# key: value`; a `#` line without a colon is kept as a comment).
//! Every cell is a finite number. Reading checks every row and stops at the first bad one with
//! an error naming file, line and column; the rows before it are not lost (see
//! [`RecordingReader::read_row`]).

use std::fs::File;
use std::io::{self, BufRead, BufReader, BufWriter, Read, Write};
use std::path::Path;

use super::error::{Location, RecordingError, quote_cell};
use super::recording::{Recording, Schema};

/// The bytes the csv parser reads: the header line, the rest of the file, and a line end
/// after its last line, so that every row ends in one (see [`RecordingReader::current_line`]).
type RowBytes<R> = io::Chain<io::Chain<io::Cursor<Vec<u8>>, BufReader<R>>, &'static [u8]>;

/// Reads a recording row by row.
pub struct RecordingReader<R: Read> {
    source: String,
    metadata: Vec<(String, String)>,
    schema: Schema,
    csv: csv::Reader<RowBytes<R>>,
    /// Lines before the header (metadata); csv positions count from the header line.
    lines_before_header: u64,
    record: csv::ByteRecord,
    previous_time: Option<f64>,
    rows_read: u64,
}

/// What a read took from a file, row by row as they stand in it (a read that averages keeps
/// fewer rows, at the blocks' mean times).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct RowsRead {
    /// The rows read.
    pub(super) rows: u64,
    /// The first row's time and the file line it is on (blank lines and metadata before it
    /// counted).
    pub(super) first: Option<(f64, u64)>,
    /// The last row's time (of a row read before, when this read found none).
    pub(super) last_time_s: Option<f64>,
}

impl RecordingReader<File> {
    /// Opens a recording file and reads its metadata and header.
    pub fn open(path: &Path) -> Result<Self, RecordingError> {
        let source = path.display().to_string();
        let file = File::open(path).map_err(|source_err| RecordingError::Io {
            source_name: source.clone(),
            error: source_err,
        })?;
        Self::from_reader(file, &source)
    }
}

/// Rows one after another, with their columns: a recording file, or the pieces of one.
pub trait RowSource {
    /// The columns.
    fn schema(&self) -> &Schema;
    /// Reads the next row into `out`; `Ok(false)` at the end.
    fn read_row(&mut self, out: &mut Vec<f64>) -> Result<bool, RecordingError>;
}

impl<R: Read> RowSource for RecordingReader<R> {
    fn schema(&self) -> &Schema {
        RecordingReader::schema(self)
    }

    fn read_row(&mut self, out: &mut Vec<f64>) -> Result<bool, RecordingError> {
        RecordingReader::read_row(self, out)
    }
}

impl<R: Read> RecordingReader<R> {
    /// Reads the metadata and header from any byte stream; `source` names it in errors.
    pub fn from_reader(reader: R, source: &str) -> Result<Self, RecordingError> {
        let mut buffered = BufReader::with_capacity(1 << 16, reader);
        let io_err = |e: io::Error| RecordingError::Io {
            source_name: source.to_string(),
            error: e,
        };
        let mut metadata = Vec::new();
        let mut line_no: u64 = 0;
        let mut line = Vec::new();
        let header_bytes = loop {
            line.clear();
            let n = buffered.read_until(b'\n', &mut line).map_err(io_err)?;
            if n == 0 {
                return Err(RecordingError::NoHeader {
                    source_name: source.to_string(),
                });
            }
            line_no += 1;
            if line_no == 1 && line.starts_with(b"\xEF\xBB\xBF") {
                // Spreadsheet exports start with a byte-order mark.
                line.drain(..3);
            }
            let text = trim_line_end(&line);
            if text.iter().all(u8::is_ascii_whitespace) {
                continue;
            }
            if let Some(rest) = text.strip_prefix(b"#") {
                let at = || Location {
                    source: source.to_string(),
                    line: line_no,
                    column: None,
                };
                let rest = std::str::from_utf8(rest).map_err(|_| RecordingError::Malformed {
                    at: at(),
                    message: "metadata line is not valid UTF-8".into(),
                })?;
                metadata.push(match rest.split_once(':') {
                    Some((k, v)) => (k.trim().to_string(), v.trim().to_string()),
                    None => (String::new(), rest.trim().to_string()),
                });
                continue;
            }
            break std::mem::take(&mut line);
        };
        let lines_before_header = line_no - 1;
        // Rows end at an LF alone (a CR before it stays in the row's last cell, which is
        // trimmed), so that the parser stands on the next line after every row it reads.
        let mut csv = csv::ReaderBuilder::new()
            .has_headers(true)
            .flexible(true)
            .terminator(csv::Terminator::Any(b'\n'))
            .from_reader(
                io::Cursor::new(header_bytes)
                    .chain(buffered)
                    .chain(&b"\n"[..]),
            );
        let header = csv
            .byte_headers()
            .map_err(|e| csv_error(e, source, line_no))?;
        let mut names = Vec::with_capacity(header.len());
        for (i, cell) in header.iter().enumerate() {
            let name = std::str::from_utf8(cell).map_err(|_| RecordingError::Malformed {
                at: Location {
                    source: source.to_string(),
                    line: line_no,
                    column: Some((i + 1, quote_cell(cell))),
                },
                message: "column name is not valid UTF-8".into(),
            })?;
            names.push(name.trim().to_string());
        }
        let schema = Schema::with_header_line(names, source, line_no)?;
        Ok(RecordingReader {
            source: source.to_string(),
            metadata,
            schema,
            csv,
            lines_before_header,
            record: csv::ByteRecord::new(),
            previous_time: None,
            rows_read: 0,
        })
    }

    /// The metadata read before the header.
    pub fn metadata(&self) -> &[(String, String)] {
        &self.metadata
    }

    /// The columns.
    pub fn schema(&self) -> &Schema {
        &self.schema
    }

    /// Rows read so far.
    pub fn rows_read(&self) -> u64 {
        self.rows_read
    }

    /// Reads the next row into `out` (cleared first). `Ok(false)` at the end of the file.
    ///
    /// On an error the reader has consumed the bad row; everything read before it is intact in
    /// the caller's hands, so a recorder or an importer can keep what was good and report where
    /// the file went wrong.
    pub fn read_row(&mut self, out: &mut Vec<f64>) -> Result<bool, RecordingError> {
        loop {
            let more = self
                .csv
                .read_byte_record(&mut self.record)
                .map_err(|e| csv_error(e, &self.source, self.lines_before_header))?;
            if !more {
                return Ok(false);
            }
            // A blank line (spaces, or the CR of a CR LF) is no row, as before the header.
            let blank =
                self.record.len() == 1 && self.record[0].iter().all(u8::is_ascii_whitespace);
            if !blank {
                break;
            }
        }
        let line = self.current_line();
        out.clear();
        let expected = self.schema.len();
        if self.record.len() != expected {
            return Err(RecordingError::FieldCount {
                at: self.location(line, None),
                expected,
                found: self.record.len(),
            });
        }
        // The row's text is checked once (UTF-8), not cell by cell; a row that is not text
        // is parsed cell by cell so that the error names the cell.
        let text = std::str::from_utf8(self.record.as_slice()).ok();
        // The last cell of a CR LF row ends in the CR: the parse trims it, and a message
        // leaves it out.
        for (i, cell) in self.record.iter().enumerate() {
            let parsed = match text.zip(self.record.range(i)).and_then(|(t, r)| t.get(r)) {
                Some(text_cell) => parse_text_cell(text_cell),
                None => parse_cell(cell),
            };
            let value = parsed.ok_or_else(|| RecordingError::NonNumeric {
                at: self.location(line, Some(i)),
                cell: quote_cell(trim_line_end(cell)),
            })?;
            if !value.is_finite() {
                return Err(RecordingError::NonFinite {
                    at: self.location(line, Some(i)),
                    cell: quote_cell(trim_line_end(cell)),
                });
            }
            if let Some((low, high)) = self.schema.range_of(i)
                && !(low..=high).contains(&value)
            {
                return Err(RecordingError::OutOfRange {
                    at: self.location(line, Some(i)),
                    value,
                    low,
                    high,
                });
            }
            out.push(value);
        }
        if let Some(previous_s) = self.previous_time
            && out[0] < previous_s
        {
            return Err(RecordingError::TimeBackwards {
                at: self.location(line, Some(0)),
                time_s: out[0],
                previous_s,
            });
        }
        self.previous_time = Some(out[0]);
        self.rows_read += 1;
        Ok(true)
    }

    /// Reads every remaining row into a columnar [`Recording`].
    pub fn read_to_end(self) -> Result<Recording, RecordingError> {
        self.read_observed(usize::MAX, None, &mut |_| true)
    }

    /// Like [`Self::read_to_end`], but stops with [`RecordingError::TooManyRows`] at the row past
    /// `limit`: a caller that must hold the whole recording in memory (many times over, as the
    /// discrepancy analysis does) refuses a file too long for it before it is read whole.
    pub fn read_at_most(self, limit: usize) -> Result<Recording, RecordingError> {
        self.read_observed(limit, None, &mut |_| true)
    }

    /// The rest of the file averaged over blocks of `block_s` seconds of its time (the
    /// recording says so in its metadata, [`AVERAGED_OVER_S`]): block `k`
    /// holds the rows with `k · block_s ≤ time_s < (k + 1) · block_s`, and each block that
    /// holds any row becomes one row whose every column, `time_s` included, is the mean of
    /// the block's values. A 0/1 column such as `coolant_on` becomes the share of the block it
    /// was on. The file is read in one pass holding only the blocks, so a recording at a rate
    /// far above what its physics needs (1 kHz servo data for temperatures that move over
    /// minutes) is read at a coarser one without first being held at its own. Blocks are
    /// anchored at time 0, so two recordings on one clock are averaged over the same blocks.
    /// More than `limit` blocks stop the read with [`RecordingError::TooManyRows`], a bad row
    /// with the row's own error as [`Self::read_row`] reports it, and a `block_s` that is not
    /// a positive number of seconds with [`RecordingError::InvalidBlock`].
    pub fn read_averaged(self, block_s: f64, limit: usize) -> Result<Recording, RecordingError> {
        self.read_observed(limit, Some(block_s), &mut |_| true)
    }

    /// How many rows [`Self::read_observed`] reads between two calls of its observer.
    pub const OBSERVED_EVERY: u64 = 8192;

    /// Reads every remaining row as [`Self::read_at_most`] does, or, given `block_s`, every
    /// block's mean row as [`Self::read_averaged`] does, at most `limit` of them, and calls
    /// `observe` with the number of rows read so far after every [`Self::OBSERVED_EVERY`]
    /// rows: the one reading loop behind the others, for a caller that shows how far a long
    /// read is or may stop it. `observe` returning `false` stops the read with
    /// [`RecordingError::Stopped`].
    pub fn read_observed(
        self,
        limit: usize,
        block_s: Option<f64>,
        observe: &mut dyn FnMut(u64) -> bool,
    ) -> Result<Recording, RecordingError> {
        self.read_observed_counting(limit, block_s, observe)
            .map(|(recording, _)| recording)
    }

    /// [`Self::read_observed`], with what was read as it stood in the file ([`RowsRead`]): the
    /// rows before any averaging, and where the first of them was.
    pub(super) fn read_observed_counting(
        mut self,
        limit: usize,
        block_s: Option<f64>,
        observe: &mut dyn FnMut(u64) -> bool,
    ) -> Result<(Recording, RowsRead), RecordingError> {
        if let Some(block_s) = block_s
            && !(block_s.is_finite() && block_s > 0.0)
        {
            return Err(RecordingError::InvalidBlock {
                source_name: self.source.clone(),
                block_s,
            });
        }
        let width = self.schema.len();
        let mut columns: Vec<Vec<f64>> = vec![Vec::new(); width];
        let mut row = Vec::with_capacity(width);
        // The block being summed: its index, the rows in it, the line it starts on; and the
        // rows' sums.
        let mut block: Option<(f64, usize, u64)> = None;
        let mut sums = vec![0.0; width];
        let mut means = Vec::with_capacity(width);
        let too_many = |reader: &Self, line: u64| RecordingError::TooManyRows {
            at: reader.location(line, None),
            limit,
            block_s,
        };
        // Appends a row unless `limit` rows are kept already.
        let keep = |columns: &mut Vec<Vec<f64>>, values: &[f64]| {
            let room = columns[0].len() < limit;
            if room {
                for (column, &value) in columns.iter_mut().zip(values) {
                    column.push(value);
                }
            }
            room
        };
        let mean_of = |means: &mut Vec<f64>, sums: &[f64], count: usize| {
            means.clear();
            means.extend(sums.iter().map(|s| s / count as f64));
        };
        let mut rows = 0u64;
        let mut first: Option<(f64, u64)> = None;
        while self.read_row(&mut row)? {
            let line = self.current_line();
            rows += 1;
            first.get_or_insert((row[0], line));
            if rows.is_multiple_of(Self::OBSERVED_EVERY) && !observe(rows) {
                return Err(RecordingError::Stopped {
                    at: self.location(line, None),
                });
            }
            let Some(block_s) = block_s else {
                if !keep(&mut columns, &row) {
                    return Err(too_many(&self, line));
                }
                continue;
            };
            let index = (row[0] / block_s).floor();
            match &mut block {
                Some((current, count, _)) if *current == index => *count += 1,
                Some((_, count, start)) => {
                    mean_of(&mut means, &sums, *count);
                    if !keep(&mut columns, &means) {
                        return Err(too_many(&self, *start));
                    }
                    sums.iter_mut().for_each(|s| *s = 0.0);
                    block = Some((index, 1, line));
                }
                None => block = Some((index, 1, line)),
            }
            for (sum, value) in sums.iter_mut().zip(&row) {
                *sum += value;
            }
        }
        if let Some((_, count, start)) = block {
            mean_of(&mut means, &sums, count);
            if !keep(&mut columns, &means) {
                return Err(too_many(&self, start));
            }
        }
        let mut recording = Recording::from_parts(self.source, self.metadata, self.schema, columns);
        if let Some(block_s) = block_s {
            recording.set_metadata(AVERAGED_OVER_S, &block_s.to_string());
        }
        let read = RowsRead {
            rows,
            first,
            last_time_s: self.previous_time,
        };
        Ok((recording, read))
    }

    /// The file line of the row read last.
    pub(super) fn current_line(&self) -> u64 {
        // Not the record's own position, which is where its read began, before the blank
        // lines it skipped: every row ends in an LF the parser has read, so it stands on the
        // line after the row's (after the last line of a row whose quoted cell spans lines).
        self.csv.position().line().saturating_sub(1) + self.lines_before_header
    }

    /// Like [`Self::read_to_end`], but on a bad row returns what was read before it together with
    /// the error instead of discarding it.
    pub fn read_until_error(mut self) -> (Recording, Option<RecordingError>) {
        let mut columns: Vec<Vec<f64>> = vec![Vec::new(); self.schema.len()];
        let mut row = Vec::with_capacity(self.schema.len());
        let error = loop {
            match self.read_row(&mut row) {
                Ok(true) => {
                    for (column, &value) in columns.iter_mut().zip(&row) {
                        column.push(value);
                    }
                }
                Ok(false) => break None,
                Err(e) => break Some(e),
            }
        };
        let recording = Recording::from_parts(self.source, self.metadata, self.schema, columns);
        (recording, error)
    }

    fn location(&self, line: u64, column: Option<usize>) -> Location {
        Location {
            source: self.source.clone(),
            line,
            column: column.map(|i| (i + 1, self.schema.names()[i].clone())),
        }
    }
}

/// The metadata key of a recording read averaged over blocks of time
/// ([`RecordingReader::read_averaged`]): the block, seconds.
pub const AVERAGED_OVER_S: &str = "averaged_over_s";

/// Reads a whole recording file.
pub fn read_recording(path: &Path) -> Result<Recording, RecordingError> {
    RecordingReader::open(path)?.read_to_end()
}

/// Parses one cell: a decimal or scientific number with optional surrounding spaces.
fn parse_cell(cell: &[u8]) -> Option<f64> {
    parse_text_cell(std::str::from_utf8(cell).ok()?)
}

/// [`parse_cell`] of a cell already known to be text.
fn parse_text_cell(cell: &str) -> Option<f64> {
    // Rust's float parser also takes "inf", "NaN" and "infinity"; those are reported as
    // non-finite, which is the more useful message, so they pass through here.
    cell.trim_ascii().parse::<f64>().ok()
}

fn trim_line_end(line: &[u8]) -> &[u8] {
    let line = line.strip_suffix(b"\n").unwrap_or(line);
    line.strip_suffix(b"\r").unwrap_or(line)
}

fn csv_error(error: csv::Error, source: &str, lines_before_header: u64) -> RecordingError {
    let line = error
        .position()
        .map_or(0, |p| p.line() + lines_before_header);
    match error.into_kind() {
        csv::ErrorKind::Io(e) => RecordingError::Io {
            source_name: source.to_string(),
            error: e,
        },
        other => RecordingError::Malformed {
            at: Location {
                source: source.to_string(),
                line,
                column: None,
            },
            message: format!("{other:?}"),
        },
    }
}

/// Writes a recording row by row. Every row is checked like a row that is read, so a writer
/// can never produce a file its reader rejects.
pub struct RecordingWriter<W: Write> {
    out: BufWriter<W>,
    source: String,
    schema: Schema,
    previous_time: Option<f64>,
    rows_written: u64,
    line: Vec<u8>,
}

impl RecordingWriter<File> {
    /// Creates (truncates) a file and writes the metadata and header.
    pub fn create(
        path: &Path,
        metadata: &[(String, String)],
        schema: &Schema,
    ) -> Result<Self, RecordingError> {
        let source = path.display().to_string();
        let file = File::create(path).map_err(|e| RecordingError::Io {
            source_name: source.clone(),
            error: e,
        })?;
        Self::new(file, &source, metadata, schema)
    }
}

impl<W: Write> RecordingWriter<W> {
    /// Writes the metadata and header to `writer`.
    pub fn new(
        writer: W,
        source: &str,
        metadata: &[(String, String)],
        schema: &Schema,
    ) -> Result<Self, RecordingError> {
        let mut out = BufWriter::with_capacity(1 << 16, writer);
        let mut head = Vec::new();
        for (key, value) in metadata {
            head.extend_from_slice(metadata_line(key, value).as_bytes());
        }
        let mut header = csv::Writer::from_writer(Vec::new());
        let header_io = |e: csv::Error| RecordingError::Io {
            source_name: source.to_string(),
            error: io::Error::other(e),
        };
        header.write_record(schema.names()).map_err(header_io)?;
        head.extend_from_slice(&header.into_inner().map_err(|e| RecordingError::Io {
            source_name: source.to_string(),
            error: e.into_error(),
        })?);
        out.write_all(&head).map_err(|e| RecordingError::Io {
            source_name: source.to_string(),
            error: e,
        })?;
        Ok(RecordingWriter {
            out,
            source: source.to_string(),
            schema: schema.clone(),
            previous_time: None,
            rows_written: 0,
            line: Vec::with_capacity(32 * schema.len()),
        })
    }

    /// Checks and writes one row.
    pub fn write_row(&mut self, row: &[f64]) -> Result<(), RecordingError> {
        let line_no = self.rows_written + 2;
        self.schema
            .check_row(row, self.previous_time, &self.source, line_no)?;
        self.line.clear();
        let mut buffer = ryu::Buffer::new();
        for (i, value) in row.iter().enumerate() {
            if i > 0 {
                self.line.push(b',');
            }
            self.line
                .extend_from_slice(buffer.format_finite(*value).as_bytes());
        }
        self.line.push(b'\n');
        self.out
            .write_all(&self.line)
            .map_err(|e| RecordingError::Io {
                source_name: self.source.clone(),
                error: e,
            })?;
        self.previous_time = Some(row[0]);
        self.rows_written += 1;
        Ok(())
    }

    /// Rows written so far.
    pub fn rows_written(&self) -> u64 {
        self.rows_written
    }

    /// Pushes buffered rows to the operating system (and, for files, to the disk cache).
    pub fn flush(&mut self) -> Result<(), RecordingError> {
        self.out.flush().map_err(|e| RecordingError::Io {
            source_name: self.source.clone(),
            error: e,
        })
    }

    /// Flushes and returns the underlying writer.
    pub fn finish(self) -> Result<W, RecordingError> {
        let source = self.source;
        self.out.into_inner().map_err(|e| RecordingError::Io {
            source_name: source,
            error: e.into_error(),
        })
    }
}

/// One metadata line, `# key: value\n` (or `# text\n` for a comment with an empty key).
fn metadata_line(key: &str, value: &str) -> String {
    let flat = |s: &str| s.replace(['\n', '\r'], " ");
    if key.is_empty() {
        format!("# {}\n", flat(value))
    } else {
        format!("# {}: {}\n", flat(key).replace(':', " "), flat(value))
    }
}

/// Writes a whole recording to a file.
pub fn write_recording(path: &Path, recording: &Recording) -> Result<(), RecordingError> {
    let mut writer = RecordingWriter::create(path, recording.metadata(), recording.schema())?;
    let mut row = Vec::with_capacity(recording.schema().len());
    for i in 0..recording.len() {
        recording.row_into(i, &mut row);
        writer.write_row(&row)?;
    }
    writer.finish()?;
    Ok(())
}

/// Writes a whole recording to any writer (a `Vec<u8>` in tests, stdout in the CLI).
pub fn write_recording_to<W: Write>(writer: W, recording: &Recording) -> Result<W, RecordingError> {
    let mut writer = RecordingWriter::new(
        writer,
        recording.source(),
        recording.metadata(),
        recording.schema(),
    )?;
    let mut row = Vec::with_capacity(recording.schema().len());
    for i in 0..recording.len() {
        recording.row_into(i, &mut row);
        writer.write_row(&row)?;
    }
    writer.finish()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read(text: &str) -> Result<Recording, RecordingError> {
        RecordingReader::from_reader(text.as_bytes(), "t.csv")?.read_to_end()
    }

    fn reader(text: &str) -> RecordingReader<&[u8]> {
        RecordingReader::from_reader(text.as_bytes(), "t.csv").expect("a header")
    }

    /// Each block of time becomes one row of the means of its rows, `time_s` included; a
    /// block without rows (a gap) gives no row, and blocks are anchored at time 0.
    #[test]
    fn rows_are_averaged_over_blocks_of_time() {
        let text = "# k: v\ntime_s,x,on\n0.0,1,0\n0.5,3,1\n1.0,10,1\n1.5,20,1\n1.75,30,0\n\
                    4.25,7,1\n";
        let rec = reader(text).read_averaged(1.0, 10).unwrap();
        assert_eq!(rec.metadata_value(AVERAGED_OVER_S), Some("1"));
        assert_eq!(rec.time(), &[0.25, 4.25 / 3.0, 4.25]);
        assert_eq!(rec.column("x").unwrap(), &[2.0, 20.0, 7.0]);
        assert_eq!(rec.column("on").unwrap(), &[0.5, 2.0 / 3.0, 1.0]);
        assert_eq!(rec.metadata_value("k"), Some("v"));
        // Blocks longer than the record: one row.
        let rec = reader(text).read_averaged(10.0, 10).unwrap();
        assert_eq!(rec.len(), 1);
        assert_eq!(rec.column("x").unwrap(), &[71.0 / 6.0]);
        // Blocks shorter than the steps: every row as it is.
        let rec = reader(text).read_averaged(0.1, 10).unwrap();
        assert_eq!(rec.column("x").unwrap(), &[1.0, 3.0, 10.0, 20.0, 30.0, 7.0]);
    }

    /// The observer hears how many rows are read every `OBSERVED_EVERY` rows, of an averaged
    /// read too, and stops the read where it returns `false`, with an error naming the line.
    #[test]
    fn an_observed_read_reports_its_rows_and_stops_when_told() {
        let every = RecordingReader::<&[u8]>::OBSERVED_EVERY;
        let rows = 3 * every + 5;
        let mut text = String::from("time_s,x\n");
        for i in 0..rows {
            text.push_str(&format!("{i},{}\n", 2 * i));
        }
        for block_s in [None, Some(100.0)] {
            let mut heard = Vec::new();
            let rec = reader(&text)
                .read_observed(usize::MAX, block_s, &mut |n| {
                    heard.push(n);
                    true
                })
                .unwrap();
            assert_eq!(heard, [every, 2 * every, 3 * every]);
            let expected = block_s.map_or(rows, |b| (rows as f64 / b).ceil() as u64);
            assert_eq!(rec.len() as u64, expected);
        }
        let err = reader(&text)
            .read_observed(usize::MAX, None, &mut |n| n < 2 * every)
            .unwrap_err();
        // Row 2·every is on line 2·every + 1 (the header is line 1).
        assert_eq!(
            err.to_string(),
            format!("t.csv: line {}: reading stopped here", 2 * every + 1)
        );
    }

    /// A bad cell is named on its own line, whatever blank lines come before it (the reader
    /// skips them) and whatever ends the lines (LF, CR LF, or both in one file), on the last
    /// line without its line end too, and under metadata; the CR is no part of the cell.
    #[test]
    fn a_bad_cell_after_blank_lines_is_named_on_its_own_line() {
        for (text, line) in [
            ("time_s,x\r\n2.5,1\n\n3.5,zz\n", 4),
            ("time_s,x\n2.5,1\r\n \r\n\r\n3.5,zz\r\n", 5),
            ("time_s,x\n2.5,1\n\n\n3.5,zz", 5),
            ("time_s,x\n\n2.5,zz", 3),
            ("time_s,x\n\n\n2.5,zz\n", 4),
            ("time_s,x\n2.5,1\n\n\n3.5,zz\n", 5),
            ("time_s,x\n2.5,1\n\n3.5,1\n4.5,zz", 5),
            ("# k: v\n\ntime_s,x\n2.5,1\n\n3.5,zz\n4.5,1\n", 6),
            ("time_s,x\r\n\r\n2.5,1\r\n3.5,zz\r\n", 4),
            ("time_s,x\r\n2.5,1\r\n\r\n\r\n3.5,zz\r\n", 5),
            ("time_s,x\r\n2.5,1\r\n3.5,zz", 3),
        ] {
            let error = read(text).unwrap_err().to_string();
            assert_eq!(
                error,
                format!("t.csv: line {line}, column 2 (`x`): `zz` is not a number"),
                "{text:?}"
            );
        }
        for text in [
            "time_s,x\r\n\r\n1,2\r\n  \r\n2,3\r\n",
            "time_s,x\n1,2\r\n\n2,3",
        ] {
            let recording = read(text).unwrap();
            assert_eq!(recording.time(), &[1.0, 2.0], "{text:?}");
            assert_eq!(recording.column("x").unwrap(), &[2.0, 3.0], "{text:?}");
        }
    }

    /// Past the limit the read stops with an error naming the file and the line where the row
    /// (or block) past it starts; a block that is no length of time is refused before reading.
    #[test]
    fn a_read_past_its_limit_or_over_no_length_of_time_is_refused() {
        let text = "time_s,x\n0,1\n1,2\n2,3\n3,4\n";
        assert_eq!(reader(text).read_at_most(4).unwrap().len(), 4);
        let err = reader(text).read_at_most(3).unwrap_err();
        assert!(
            matches!(
                err,
                RecordingError::TooManyRows {
                    limit: 3,
                    block_s: None,
                    ..
                }
            ),
            "{err:?}"
        );
        assert_eq!(err.to_string(), "t.csv: line 5: more than 3 rows");
        assert_eq!(reader(text).read_averaged(2.0, 2).unwrap().len(), 2);
        let err = reader(text).read_averaged(1.5, 2).unwrap_err();
        // Blocks [0, 1.5), [1.5, 3), [3, 4.5): the third starts on line 5.
        assert_eq!(
            err.to_string(),
            "t.csv: line 5: more than 2 rows averaged over 1.5 s blocks"
        );
        for block_s in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            let err = reader(text).read_averaged(block_s, 10).unwrap_err();
            assert!(
                matches!(err, RecordingError::InvalidBlock { .. }),
                "{err:?}"
            );
            assert!(
                err.to_string().starts_with("t.csv: cannot average"),
                "{err}"
            );
        }
    }

    /// A bad row stops an averaged read with the row's own error, where it is.
    #[test]
    fn a_bad_row_stops_an_averaged_read_where_it_is() {
        let err = reader("time_s,x\n0,1\n0.5,2\n0.2,3\n")
            .read_averaged(1.0, 10)
            .unwrap_err();
        assert!(
            matches!(err, RecordingError::TimeBackwards { .. }),
            "{err:?}"
        );
        assert!(err.to_string().starts_with("t.csv: line 4"), "{err}");
        let err = reader("time_s,x\n0,1\n0.5,oops\n")
            .read_averaged(1.0, 10)
            .unwrap_err();
        assert!(err.to_string().contains("line 3, column 2 (`x`)"), "{err}");
    }

    #[test]
    fn reads_metadata_header_and_rows() {
        let rec =
            read("# machine: IT-25\n# a comment\ntime_s,X.speed_rpm,note\n0,1,2\n1,3,4\n").unwrap();
        assert_eq!(rec.metadata_value("machine"), Some("IT-25"));
        assert_eq!(rec.metadata()[1], (String::new(), "a comment".to_string()));
        assert_eq!(rec.column("X.speed_rpm").unwrap(), &[1.0, 3.0]);
        assert_eq!(rec.column("note").unwrap(), &[2.0, 4.0]);
    }

    #[test]
    fn non_numeric_cell_names_file_line_and_column() {
        let text = "# k: v\ntime_s,X.speed_rpm\n0,1\n1,2\n2,abc\n";
        let err = read(text).unwrap_err().to_string();
        assert_eq!(
            err,
            "t.csv: line 5, column 2 (`X.speed_rpm`): `abc` is not a number"
        );
    }

    /// A row is checked as text once; a cell that is not text is still named, with the
    /// rows before it kept, and a quoted number in a text row reads as the number.
    #[test]
    fn a_cell_that_is_not_text_is_named_and_quoted_numbers_read() {
        let mut bytes = b"time_s,a,b\n0,\"1.5\",2\n1,2,".to_vec();
        bytes.extend([0xff, b'7', b'\n']);
        let (recording, error) = RecordingReader::from_reader(bytes.as_slice(), "t.csv")
            .expect("a header")
            .read_until_error();
        assert_eq!(recording.column("a").expect("a column"), &[1.5]);
        let error = error.expect("the bad row").to_string();
        assert!(
            error.starts_with("t.csv: line 3, column 3 (`b`): ") && error.contains("not a number"),
            "{error}"
        );
    }

    #[test]
    fn wrong_field_count_nan_and_backwards_time_are_located() {
        let err = read("time_s,a\n0,1\n1\n").unwrap_err().to_string();
        assert_eq!(err, "t.csv: line 3: 1 fields, but the header has 2");
        let err = read("time_s,a\n0,NaN\n").unwrap_err().to_string();
        assert_eq!(
            err,
            "t.csv: line 2, column 2 (`a`): `NaN` is not a finite number"
        );
        let err = read("time_s,a\n0,1\n2,1\n1,1\n").unwrap_err().to_string();
        assert_eq!(
            err,
            "t.csv: line 4, column 1 (`time_s`): time goes backwards: 1 s after 2 s"
        );
    }

    /// A spreadsheet's export with `;` between columns and a decimal comma, or a file with
    /// tabs between them, is named for what it is, not for a first column it lacks.
    #[test]
    fn a_file_separated_otherwise_than_by_commas_is_named_so() {
        let err = read("# k: v\ntime_s;X.speed_rpm\n0;1,5\n")
            .unwrap_err()
            .to_string();
        assert_eq!(
            err,
            "t.csv: line 2: the columns are separated by `;`, not by commas: CSV v1 separates \
             columns with `,` and writes numbers with a decimal point (a spreadsheet set to a \
             language with a decimal comma exports `;` and `1,5`): export it comma-separated \
             with decimal points"
        );
        let err = read("time_s\tX.speed_rpm\n0\t1.5\n")
            .unwrap_err()
            .to_string();
        assert_eq!(
            err,
            "t.csv: line 1: the columns are separated by tabs, not by commas: CSV v1 separates \
             columns with `,` and writes numbers with a decimal point: export it \
             comma-separated with decimal points"
        );
        let err = read("t,X.speed_rpm\n0,1\n").unwrap_err().to_string();
        assert_eq!(
            err,
            "t.csv: line 1: the first column must be `time_s`, found `t`"
        );
    }

    #[test]
    fn empty_file_and_metadata_only_have_no_header() {
        for text in ["", "# a: b\n", "\n\n"] {
            assert!(
                matches!(read(text), Err(RecordingError::NoHeader { .. })),
                "{text:?}"
            );
        }
    }

    #[test]
    fn read_until_error_keeps_the_good_rows() {
        let reader =
            RecordingReader::from_reader("time_s,a\n0,1\n1,2\n2,x\n3,4\n".as_bytes(), "t").unwrap();
        let (rec, err) = reader.read_until_error();
        assert_eq!(rec.len(), 2);
        assert!(err.unwrap().to_string().contains("line 4"));
    }

    #[test]
    fn crlf_bom_and_spaces_are_tolerated() {
        let rec = read("\u{feff}time_s, a \r\n0, 1.5 \r\n").unwrap();
        assert_eq!(rec.column("a").unwrap(), &[1.5]);
    }

    #[test]
    fn writer_output_reads_back_identically() {
        let mut rec = Recording::new(
            "mem",
            vec!["time_s".into(), "ref.X.straightness_h_um#3".into()],
        )
        .unwrap();
        rec.set_metadata("scenario", "warm\nup");
        rec.push_row(&[0.0, -1.0e-300]).unwrap();
        rec.push_row(&[0.1, 123456.789]).unwrap();
        let bytes = write_recording_to(Vec::new(), &rec).unwrap();
        let back = RecordingReader::from_reader(bytes.as_slice(), "mem")
            .unwrap()
            .read_to_end()
            .unwrap();
        assert_eq!(back, rec);
    }
}
