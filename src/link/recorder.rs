//! The recorder: every frame the link delivers goes to a CSV v1 file.
//!
//! Durability: rows are buffered and pushed to the operating system at least every
//! `flush_every` (one second by default), so a crash of the process loses at most that much.
//! The buffer hands the operating system whole lines only (a row is appended to the buffer, or
//! the buffer is written out first), so a killed recorder leaves a file that ends at a line
//! boundary and reads back with [`crate::signal::read_recording`] and `servosight inspect`.
//! Files rotate by size and age; each part is a complete recording with its own header.
//!
//! Gaps: when the link carries the controller's sequence counter, two columns are added,
//! [`SEQUENCE_COLUMN`] and [`LOST_BEFORE_COLUMN`]; a row whose `link.lost_before` is non-zero
//! follows a gap of that many samples the controller published but the link never received.

use std::fs::File;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use super::Frame;
use crate::signal::pieces::{PART_KEY, RECORDING_KEY};
use crate::signal::{RecordingError, RecordingWriter, Schema};

/// Column holding the controller's sequence counter of each row.
pub const SEQUENCE_COLUMN: &str = "link.sequence";
/// Column holding the number of samples lost just before each row.
pub const LOST_BEFORE_COLUMN: &str = "link.lost_before";

/// Settings of a recorder.
#[derive(Debug, Clone, PartialEq)]
pub struct RecorderConfig {
    /// The first file; later parts are named `<stem>-0001.csv`, `<stem>-0002.csv`, ….
    pub path: PathBuf,
    /// Start a new part once a file holds this many bytes (checked on what has reached the
    /// file, so a part can run up to one 64 KiB write buffer past the limit).
    pub rotate_bytes: Option<u64>,
    /// Start a new part once a file is this old.
    pub rotate_after: Option<Duration>,
    /// Push buffered rows to the operating system at least this often.
    pub flush_every: Duration,
    /// Metadata written at the top of every part (`# key: value`).
    pub metadata: Vec<(String, String)>,
}

impl RecorderConfig {
    /// Defaults: rotate at 256 MiB or 1 h, flush every second.
    pub fn new(path: impl Into<PathBuf>) -> Self {
        RecorderConfig {
            path: path.into(),
            rotate_bytes: Some(256 * 1024 * 1024),
            rotate_after: Some(Duration::from_secs(3600)),
            flush_every: Duration::from_secs(1),
            metadata: Vec::new(),
        }
    }
}

/// What the recorder has done, for display.
#[derive(Debug, Clone, Default, PartialEq, Eq, serde::Serialize)]
pub struct RecorderStats {
    /// Rows written over all parts.
    pub rows: u64,
    /// Files written (parts).
    pub files: u64,
    /// Gaps marked (rows with `link.lost_before` > 0).
    pub gaps_marked: u64,
    /// Samples lost upstream, summed over the gaps marked.
    pub samples_lost_upstream: u64,
    /// Frames the recorder could not write (never silent: the caller gets the error too).
    pub frames_not_written: u64,
}

/// Errors of the recorder.
#[derive(Debug, thiserror::Error)]
pub enum RecorderError {
    /// Writing a row or a file failed.
    #[error(transparent)]
    Recording(#[from] RecordingError),
    /// The file to record into exists already: a recorder never writes over a recording.
    #[error("{0} exists already: a recorder never writes over a recording; choose another name")]
    Exists(String),
    /// The recorder's own columns clash with the link's.
    #[error("the link already has a column named `{0}`")]
    ColumnClash(String),
}

/// Counts bytes handed to the file, so the recorder knows when to rotate.
struct CountingFile {
    file: File,
    written: Arc<AtomicU64>,
}

impl Write for CountingFile {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let n = self.file.write(buf)?;
        self.written.fetch_add(n as u64, Ordering::Relaxed);
        Ok(n)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        self.file.flush()
    }
}

/// Writes frames to rotating CSV v1 files.
pub struct Recorder {
    config: RecorderConfig,
    schema: Schema,
    with_sequence: bool,
    writer: Option<RecordingWriter<CountingFile>>,
    written: Arc<AtomicU64>,
    part: u32,
    part_opened: Instant,
    last_flush: Instant,
    paths: Vec<PathBuf>,
    row: Vec<f64>,
    stats: RecorderStats,
}

impl Recorder {
    /// Creates the first file. `link_schema` is the link's; `with_sequence` adds the sequence
    /// and gap columns (pass [`super::ControllerLink::has_sequence`]).
    pub fn create(
        config: RecorderConfig,
        link_schema: &Schema,
        with_sequence: bool,
    ) -> Result<Recorder, RecorderError> {
        let mut names = link_schema.names().to_vec();
        if with_sequence {
            for extra in [SEQUENCE_COLUMN, LOST_BEFORE_COLUMN] {
                if link_schema.index_of(extra).is_some() {
                    return Err(RecorderError::ColumnClash(extra.to_string()));
                }
                names.push(extra.to_string());
            }
        }
        let schema = Schema::new(names, &config.path.display().to_string())?;
        let now = Instant::now();
        let mut recorder = Recorder {
            config,
            schema,
            with_sequence,
            writer: None,
            written: Arc::new(AtomicU64::new(0)),
            part: 0,
            part_opened: now,
            last_flush: now,
            paths: Vec::new(),
            row: Vec::new(),
            stats: RecorderStats::default(),
        };
        recorder.open_part()?;
        Ok(recorder)
    }

    /// The columns of the recorded files.
    pub fn schema(&self) -> &Schema {
        &self.schema
    }

    /// Every file written so far, in order.
    pub fn paths(&self) -> &[PathBuf] {
        &self.paths
    }

    /// Counters.
    pub fn stats(&self) -> &RecorderStats {
        &self.stats
    }

    fn part_path(&self, part: u32) -> PathBuf {
        crate::signal::piece_path(&self.config.path, part)
    }

    fn open_part(&mut self) -> Result<(), RecorderError> {
        if let Some(writer) = self.writer.take() {
            writer.finish()?;
        }
        let mut path = self.part_path(self.part);
        // A later part whose name an earlier run took moves on to the next free number; the
        // first file's name is the user's choice and is refused below instead.
        while self.part > 0 && path.exists() {
            self.part += 1;
            path = self.part_path(self.part);
        }
        let source = path.display().to_string();
        // `create_new`: a name that is taken (an earlier run's recording, or one of its later
        // parts) is refused rather than truncated, so nothing recorded is ever lost.
        let file = File::options()
            .write(true)
            .create_new(true)
            .open(&path)
            .map_err(|e| match e.kind() {
                std::io::ErrorKind::AlreadyExists => RecorderError::Exists(source.clone()),
                _ => RecordingError::Io {
                    source_name: source.clone(),
                    error: e,
                }
                .into(),
            })?;
        self.written = Arc::new(AtomicU64::new(0));
        let counting = CountingFile {
            file,
            written: Arc::clone(&self.written),
        };
        let mut metadata = self.config.metadata.clone();
        let first = self.config.path.file_name().unwrap_or_default();
        metadata.push((RECORDING_KEY.into(), first.to_string_lossy().into_owned()));
        metadata.push((PART_KEY.into(), self.part.to_string()));
        let mut writer = RecordingWriter::new(counting, &source, &metadata, &self.schema)?;
        // The header goes to disk at once: a recorder killed in its first second still leaves
        // a readable (empty) recording.
        writer.flush()?;
        self.writer = Some(writer);
        self.paths.push(path);
        self.part_opened = Instant::now();
        self.stats.files += 1;
        Ok(())
    }

    fn rotation_due(&self) -> bool {
        let by_size = self
            .config
            .rotate_bytes
            .is_some_and(|limit| self.written.load(Ordering::Relaxed) >= limit);
        let by_age = self
            .config
            .rotate_after
            .is_some_and(|limit| self.part_opened.elapsed() >= limit);
        by_size || by_age
    }

    /// Writes one frame (rotating first if a part is full, flushing if a flush is due).
    pub fn record(&mut self, frame: &Frame) -> Result<(), RecorderError> {
        if self.rotation_due() {
            self.part += 1;
            self.open_part()?;
        }
        self.row.clear();
        self.row.extend_from_slice(&frame.row);
        if self.with_sequence {
            self.row.push(frame.sequence.map_or(-1.0, f64::from));
            self.row.push(frame.lost_before as f64);
        }
        let Some(writer) = self.writer.as_mut() else {
            self.stats.frames_not_written += 1;
            return Err(RecorderError::Recording(RecordingError::Io {
                source_name: self.config.path.display().to_string(),
                error: std::io::Error::other("the recorder has been closed"),
            }));
        };
        if let Err(error) = writer.write_row(&self.row) {
            self.stats.frames_not_written += 1;
            return Err(error.into());
        }
        self.stats.rows += 1;
        if frame.lost_before > 0 {
            self.stats.gaps_marked += 1;
            self.stats.samples_lost_upstream += frame.lost_before;
        }
        self.flush_if_due()
    }

    /// Flushes when the last flush is `flush_every` old; call it on a timer too, so rows do not
    /// sit in the buffer while the link is quiet.
    pub fn flush_if_due(&mut self) -> Result<(), RecorderError> {
        if self.last_flush.elapsed() >= self.config.flush_every {
            self.flush()?;
        }
        Ok(())
    }

    /// Pushes every buffered row to the operating system now.
    pub fn flush(&mut self) -> Result<(), RecorderError> {
        if let Some(writer) = self.writer.as_mut() {
            writer.flush()?;
        }
        self.last_flush = Instant::now();
        Ok(())
    }

    /// Flushes and closes the current part.
    pub fn finish(mut self) -> Result<RecorderStats, RecorderError> {
        if let Some(writer) = self.writer.take() {
            writer.finish()?;
        }
        Ok(self.stats.clone())
    }
}

/// Reads a recording the recorder may not have finished, for recovery after a power loss: a
/// last line cut short (no line end, wrong field count or a broken number) is dropped and
/// reported; an error anywhere before the last line is an error as usual.
pub fn read_possibly_truncated(
    path: &Path,
) -> Result<(crate::signal::Recording, Option<RecordingError>), RecordingError> {
    let bytes = std::fs::read(path).map_err(|e| RecordingError::Io {
        source_name: path.display().to_string(),
        error: e,
    })?;
    let complete_len = match bytes.last() {
        Some(b'\n') | None => bytes.len(),
        Some(_) => bytes.iter().rposition(|b| *b == b'\n').map_or(0, |i| i + 1),
    };
    let source = path.display().to_string();
    let reader = crate::signal::RecordingReader::from_reader(&bytes[..complete_len], &source)?;
    let recording = reader.read_to_end()?;
    let dropped = (complete_len < bytes.len()).then(|| RecordingError::Malformed {
        at: crate::signal::Location {
            source: source.clone(),
            line: bytes[..complete_len]
                .iter()
                .filter(|b| **b == b'\n')
                .count() as u64
                + 1,
            column: None,
        },
        message: format!(
            "the last line is cut short ({} bytes without a line end) and was left out",
            bytes.len() - complete_len
        ),
    });
    Ok((recording, dropped))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::signal::read_recording;

    fn schema() -> Schema {
        Schema::new(vec!["time_s".into(), "X.speed_rpm".into()], "t").unwrap()
    }

    fn frame(t: f64, sequence: u32, lost_before: u64) -> Frame {
        Frame {
            row: vec![t, 100.0 + t],
            sequence: Some(sequence),
            lost_before,
        }
    }

    /// A recorder started on a name an earlier run took refuses it and leaves the earlier
    /// recording as it was; a later part whose name is taken moves on to a free number.
    #[test]
    fn never_writes_over_an_earlier_recording() {
        let dir = tempfile::tempdir().unwrap();
        let earlier = dir.path().join("run.csv");
        std::fs::write(&earlier, "time_s,X.speed_rpm\n0,1\n").unwrap();
        let error = Recorder::create(RecorderConfig::new(&earlier), &schema(), true)
            .err()
            .expect("an existing recording is refused");
        assert!(error.to_string().contains("exists already"), "{error}");
        assert_eq!(
            std::fs::read_to_string(&earlier).unwrap(),
            "time_s,X.speed_rpm\n0,1\n"
        );

        let taken_part = dir.path().join("new-0001.csv");
        std::fs::write(&taken_part, "kept").unwrap();
        let mut config = RecorderConfig::new(dir.path().join("new.csv"));
        config.rotate_bytes = Some(2000);
        let mut recorder = Recorder::create(config, &schema(), true).unwrap();
        for i in 0..20_000u32 {
            recorder
                .record(&frame(f64::from(i) * 0.01, i + 1, 0))
                .unwrap();
        }
        let paths = recorder.paths().to_vec();
        recorder.finish().unwrap();
        assert_eq!(std::fs::read_to_string(&taken_part).unwrap(), "kept");
        assert!(!paths.contains(&taken_part), "{paths:?}");
        assert_eq!(paths[1].file_name().unwrap(), "new-0002.csv");
    }

    #[test]
    fn rotates_by_size_and_marks_gaps() {
        let dir = tempfile::tempdir().unwrap();
        let mut config = RecorderConfig::new(dir.path().join("run.csv"));
        config.rotate_bytes = Some(2000);
        let mut recorder = Recorder::create(config, &schema(), true).unwrap();
        let mut sequence = 0;
        for i in 0..20_000 {
            let lost = u64::from(i % 5000 == 4999);
            sequence += 1 + lost as u32;
            recorder
                .record(&frame(i as f64 * 0.01, sequence, lost))
                .unwrap();
        }
        let paths = recorder.paths().to_vec();
        let stats = recorder.finish().unwrap();
        assert!(paths.len() > 2, "{paths:?}");
        assert_eq!(stats.rows, 20_000);
        assert_eq!(stats.gaps_marked, 4);
        assert_eq!(paths[1].file_name().unwrap(), "run-0001.csv");
        let mut rows = 0;
        let mut lost = 0.0;
        for path in &paths {
            let rec = read_recording(path).unwrap();
            rows += rec.len();
            lost += rec.column(LOST_BEFORE_COLUMN).unwrap().iter().sum::<f64>();
        }
        assert_eq!(rows, 20_000);
        assert_eq!(lost, 4.0);
        // The parts are found beside the first as its later pieces, and read back as one.
        assert_eq!(crate::signal::later_pieces(&paths[0]).unwrap(), paths[1..]);
        let whole = crate::signal::RecordingPieces::open(&paths)
            .unwrap()
            .read_observed(usize::MAX, None, &mut |_| true)
            .unwrap();
        assert_eq!(whole.len(), 20_000);
    }

    #[test]
    fn a_cut_last_line_is_dropped_and_reported() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("cut.csv");
        std::fs::write(&path, "time_s,X.speed_rpm\n0,1\n1,2\n2,3").unwrap();
        let (rec, dropped) = read_possibly_truncated(&path).unwrap();
        assert_eq!(rec.len(), 2);
        assert!(dropped.unwrap().to_string().contains("line 4"));
        std::fs::write(&path, "time_s,X.speed_rpm\n0,1\n1,x\n2,3\n").unwrap();
        assert!(read_possibly_truncated(&path).is_err());
    }
}
