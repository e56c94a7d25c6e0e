//! The pieces of one recording read as one: the files a recorder rotates a long recording into.

use std::fs::File;
use std::io::{self, Read};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

use super::csv_format::{RecordingReader, RowSource};
use super::error::{Location, PieceOrder, RecordingError};
use super::recording::{Recording, Schema};

/// The pieces of one recording read as one, in the order given: the files a recorder rotates
/// (every hour by default, each a whole recording with its own header). Every piece must have
/// the first one's columns, and none may start before the one before it ends; each piece's
/// rows are checked as [`RecordingReader`] checks them. Opened one at a time, so a shift of
/// 1 kHz pieces streams in constant memory.
pub struct RecordingPieces {
    paths: Vec<PathBuf>,
    /// The piece being read (its index in `paths`).
    at: usize,
    reader: RecordingReader<CountedFile>,
    /// How far the read is, in bytes of all the pieces.
    progress: ReadProgress,
    /// The last row's time and the piece it came from.
    last: Option<(f64, usize)>,
    /// The rows read in the current piece.
    rows_in_piece: u64,
}

impl RecordingPieces {
    /// Opens the first piece for reading. Every later piece's header is read now too, so a
    /// missing piece, or one with other columns, is refused before a row is read (an hour into
    /// a replay is too late to learn the third file was never copied); each is opened again
    /// when its turn comes. At least one path is needed.
    pub fn open(paths: &[PathBuf]) -> Result<Self, RecordingError> {
        let first = paths.first().ok_or_else(|| RecordingError::Io {
            source_name: "the recording".into(),
            error: io::Error::other("no recording file given"),
        })?;
        let progress = ReadProgress {
            read: Arc::default(),
            total: paths
                .iter()
                .map(|p| std::fs::metadata(p).map_or(0, |m| m.len()))
                .sum(),
        };
        let reader = CountedFile::open_recording(first, &progress.read)?;
        for later in &paths[1..] {
            Self::open_piece(later, first, reader.schema().names(), &Arc::default())?;
        }
        Ok(RecordingPieces {
            reader,
            progress,
            paths: paths.to_vec(),
            at: 0,
            last: None,
            rows_in_piece: 0,
        })
    }

    /// Opens the pieces for reading from the first row at or after `target_s` (`None` when no
    /// row is that late), which it returns: a replay's seek. A piece whose next piece starts
    /// at or before `target_s` holds nothing from there on and is not read, so a seek into the
    /// eighth hour reads one piece, not eight; the rows of the pieces skipped are not checked
    /// (their headers are, as [`Self::open`] checks them). Pieces whose first rows are out of
    /// order are read from the first, so that the read names the one that starts too early.
    pub fn open_at(
        paths: &[PathBuf],
        target_s: f64,
    ) -> Result<(Self, Option<Vec<f64>>), RecordingError> {
        let mut pieces = Self::open(paths)?;
        let mut row = Vec::new();
        // Each piece's first row's time, for the pieces that have one.
        let mut firsts = Vec::new();
        for (i, path) in paths.iter().enumerate() {
            if RecordingReader::open(path)?.read_row(&mut row)? {
                firsts.push((i, row[0]));
            }
        }
        let ordered = firsts.windows(2).all(|w| w[0].1 <= w[1].1);
        let start = firsts
            .iter()
            .rev()
            .find(|&&(_, time_s)| ordered && time_s <= target_s)
            .map_or(0, |&(i, _)| i);
        if start > 0 {
            let names = pieces.reader.schema().names();
            let read = &pieces.progress.read;
            pieces.reader = Self::open_piece(&paths[start], &paths[0], names, read)?;
            pieces.at = start;
        }
        while pieces.read_row(&mut row)? {
            if row[0] >= target_s {
                return Ok((pieces, Some(row)));
            }
        }
        Ok((pieces, None))
    }

    /// How far the read is: shared, so a job can show it while [`Self::read_observed`] has
    /// the pieces.
    pub fn progress(&self) -> ReadProgress {
        self.progress.clone()
    }

    /// The metadata of the piece being read (the first one's until its rows are read).
    pub fn metadata(&self) -> &[(String, String)] {
        self.reader.metadata()
    }

    /// The columns (the first piece's, which every piece has).
    pub fn schema(&self) -> &Schema {
        self.reader.schema()
    }

    /// The pieces' files as given, comma-separated: how the recording is named in messages.
    pub fn name(paths: &[PathBuf]) -> String {
        paths
            .iter()
            .map(|p| p.display().to_string())
            .collect::<Vec<_>>()
            .join(", ")
    }

    /// The pieces named in a line: the file, or the first and last piece and how many there
    /// are (a shift's eight pieces would not fit in a status bar).
    pub fn short_name(paths: &[PathBuf]) -> String {
        match paths {
            [first, .., last] => format!(
                "{} … {} ({} pieces)",
                first.display(),
                last.display(),
                paths.len()
            ),
            _ => Self::name(paths),
        }
    }

    /// Reads the next row, from the next piece once one ends. `Ok(false)` after the last.
    pub fn read_row(&mut self, out: &mut Vec<f64>) -> Result<bool, RecordingError> {
        loop {
            if self.reader.read_row(out)? {
                let time_s = out[0];
                if self.rows_in_piece == 0 {
                    let line = self.reader.current_line();
                    in_order(&self.paths, self.at, line, time_s, self.last)?;
                }
                self.rows_in_piece += 1;
                self.last = Some((time_s, self.at));
                return Ok(true);
            }
            let Some(next) = self.paths.get(self.at + 1) else {
                return Ok(false);
            };
            let names = self.reader.schema().names();
            self.reader = Self::open_piece(next, &self.paths[0], names, &self.progress.read)?;
            self.at += 1;
            self.rows_in_piece = 0;
        }
    }

    /// Every remaining piece into one columnar [`Recording`], each read as
    /// [`RecordingReader::read_observed`] reads a file (whole, or averaged over `block_s`
    /// blocks, which are anchored at time 0, so a block a piece boundary cuts becomes two rows),
    /// at most `limit` rows in all, with the same checks as [`Self::read_row`] between pieces.
    /// `observe` hears the rows read so far in all the pieces. For a reader that has read rows
    /// already, only the rest of the current piece and the pieces after it are kept.
    pub fn read_observed(
        self,
        limit: usize,
        block_s: Option<f64>,
        observe: &mut dyn FnMut(u64) -> bool,
    ) -> Result<Recording, RecordingError> {
        let RecordingPieces {
            paths,
            mut at,
            mut reader,
            mut last,
            progress,
            ..
        } = self;
        let schema = reader.schema().clone();
        let mut columns: Vec<Vec<f64>> = vec![Vec::new(); schema.len()];
        // The first piece's, with what its read adds (how it was averaged).
        let mut metadata: Option<Vec<(String, String)>> = None;
        // The rows read in the pieces before this one.
        let mut rows_before = 0;
        loop {
            let mut counted = |rows: u64| observe(rows_before + rows);
            let (part, read) =
                reader.read_observed_counting(limit - columns[0].len(), block_s, &mut counted)?;
            rows_before += read.rows;
            // The rows as they stand in the file, not the blocks' means: the order and the
            // line named are the file's.
            if let Some((time_s, line)) = read.first {
                in_order(&paths, at, line, time_s, last)?;
            }
            if let Some(time_s) = read.last_time_s {
                last = Some((time_s, at));
            }
            let (part_metadata, part_columns) = part.into_metadata_and_columns();
            if metadata.is_none() {
                // The first piece's columns are moved, not copied: one piece, one copy.
                metadata = Some(part_metadata);
                columns = part_columns;
            } else {
                for (column, part) in columns.iter_mut().zip(&part_columns) {
                    column.extend_from_slice(part);
                }
            }
            let Some(next) = paths.get(at + 1) else {
                break;
            };
            reader = Self::open_piece(next, &paths[0], schema.names(), &progress.read)?;
            at += 1;
        }
        Ok(Recording::from_parts(
            Self::name(&paths),
            metadata.unwrap_or_default(),
            schema,
            columns,
        ))
    }

    /// Opens the piece at `path`, which must have the first piece's columns, its bytes counted
    /// into `read`.
    fn open_piece(
        path: &Path,
        first: &Path,
        names: &[String],
        read: &Arc<AtomicU64>,
    ) -> Result<RecordingReader<CountedFile>, RecordingError> {
        let reader = CountedFile::open_recording(path, read)?;
        let now = reader.schema().names();
        if now != names {
            let missing: Vec<&String> = names.iter().filter(|c| !now.contains(c)).collect();
            let extra: Vec<&String> = now.iter().filter(|c| !names.contains(c)).collect();
            let difference = if missing.is_empty() && extra.is_empty() {
                "the same columns in another order".to_string()
            } else {
                format!("missing {missing:?}, not in the first {extra:?}")
            };
            return Err(RecordingError::PieceColumns {
                source_name: path.display().to_string(),
                first: first.display().to_string(),
                difference,
            });
        }
        Ok(reader)
    }
}

/// Checks that piece `at`'s first row, at `time_s` on `line`, does not start before `last`
/// (the previous row's time and piece).
fn in_order(
    paths: &[PathBuf],
    at: usize,
    line: u64,
    time_s: f64,
    last: Option<(f64, usize)>,
) -> Result<(), RecordingError> {
    match last {
        Some((previous_s, piece)) if time_s < previous_s => {
            Err(RecordingError::PieceOutOfOrder(Box::new(PieceOrder {
                at: Location {
                    source: paths[at].display().to_string(),
                    line,
                    column: None,
                },
                time_s,
                previous: paths[piece].display().to_string(),
                previous_s,
            })))
        }
        _ => Ok(()),
    }
}

/// Reads the pieces of one recording whole, in the order given, into one [`Recording`], as
/// [`crate::signal::read_recording`] reads a file (one path reads that file).
pub fn read_pieces(paths: &[PathBuf]) -> Result<Recording, RecordingError> {
    RecordingPieces::open(paths)?.read_observed(usize::MAX, None, &mut |_| true)
}

/// Metadata key naming, in every piece a recorder writes, the first piece's file (which
/// names the recording): pieces another run left beside it under the same names are not its.
pub const RECORDING_KEY: &str = "recording";

/// Metadata key holding a piece's number (0 for the first).
pub const PART_KEY: &str = "part";

/// The stem and extension a recorder names later pieces with: the first piece's, `recording`
/// and `csv` where it has none.
fn stem_and_extension(first: &Path) -> (String, String) {
    let stem = first
        .file_stem()
        .map_or_else(|| "recording".into(), |s| s.to_string_lossy().into_owned());
    let extension = first
        .extension()
        .map_or_else(|| "csv".into(), |e| e.to_string_lossy().into_owned());
    (stem, extension)
}

/// The name a recorder gives piece `part` of the recording it started at `first`: `first`
/// itself for part 0, then `<stem>-0001.<ext>`, `<stem>-0002.<ext>`, ….
pub fn piece_path(first: &Path, part: u32) -> PathBuf {
    if part == 0 {
        return first.to_path_buf();
    }
    let (stem, extension) = stem_and_extension(first);
    first.with_file_name(format!("{stem}-{part:04}.{extension}"))
}

/// The files to read for the recording `first`: itself, then (given `find_later`) the pieces
/// the recorder continued it in ([`later_pieces`]). The error says which directory could not
/// be looked in. Lists a directory, so call it off the UI thread.
pub fn with_later_pieces(first: &Path, find_later: bool) -> Result<Vec<PathBuf>, String> {
    let mut pieces = vec![first.to_path_buf()];
    if find_later {
        let later = later_pieces(first)
            .map_err(|e| format!("cannot look for the pieces beside {}: {e}", first.display()))?;
        pieces.extend(later);
    }
    Ok(pieces)
}

/// The pieces a recorder continued the recording `first` in, as [`piece_path`] names them,
/// that are in `first`'s directory, in the order of their numbers (a number may be missing: a
/// recorder skips a name an earlier run took). Where `first` says which recording it is
/// ([`RECORDING_KEY`], as the recorder writes), a piece that says it is another's, or another
/// part than its name, is left out: an earlier run's pieces under the same names are not this
/// one's. A piece whose header cannot be read is kept, so that reading it names the fault
/// instead of a piece going missing unsaid. Lists the directory and reads headers, so call it
/// off the UI thread.
pub fn later_pieces(first: &Path) -> io::Result<Vec<PathBuf>> {
    let (stem, extension) = stem_and_extension(first);
    let prefix = format!("{stem}-");
    let suffix = format!(".{extension}");
    let directory = match first.parent() {
        Some(parent) if !parent.as_os_str().is_empty() => parent,
        _ => Path::new("."),
    };
    let recording = piece_identity(first)
        .ok()
        .flatten()
        .map(|(recording, _)| recording);
    let mut numbered = Vec::new();
    for entry in std::fs::read_dir(directory)? {
        let file_name = entry?.file_name();
        let name = file_name.to_string_lossy();
        // Only the recorder's own spelling of a number: `-0001`, `-12345`, not `-00001`.
        let number = name
            .strip_prefix(&prefix)
            .and_then(|rest| rest.strip_suffix(&suffix))
            .and_then(|digits| {
                let n = digits.parse::<u32>().ok().filter(|&n| n > 0)?;
                (digits == format!("{n:04}")).then_some(n)
            });
        let Some(number) = number else {
            continue;
        };
        let path = first.with_file_name(&file_name);
        let ours = recording
            .as_ref()
            .is_none_or(|recording| match piece_identity(&path) {
                Ok(identity) => identity == Some((recording.clone(), u64::from(number))),
                Err(_) => true,
            });
        if ours {
            numbered.push((number, path));
        }
    }
    numbered.sort();
    Ok(numbered.into_iter().map(|(_, path)| path).collect())
}

/// The pieces the recorder continued the recording in that lie beside its first file
/// ([`later_pieces`]) and are not among `given` (its files as a user gave them, the first
/// first): what a command given `shift.csv` alone, or a glob that missed `shift-10000.csv`,
/// leaves out. A piece given under another spelling of its path (`./shift-0001.csv`, a link)
/// counts as given. Lists the directory, so call it off the UI thread.
pub fn pieces_left_out(given: &[PathBuf]) -> io::Result<Vec<PathBuf>> {
    let Some(first) = given.first() else {
        return Ok(Vec::new());
    };
    // A path that cannot be resolved (a piece given that does not exist) is compared as spelt;
    // reading it names the fault.
    let resolved = |path: &Path| std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf());
    let given: Vec<PathBuf> = given.iter().map(|p| resolved(p)).collect();
    Ok(later_pieces(first)?
        .into_iter()
        .filter(|piece| !given.contains(&resolved(piece)))
        .collect())
}

/// Which recording the file at `path` says it is a piece of, and which piece
/// ([`RECORDING_KEY`], [`PART_KEY`], as the recorder writes them); `None` for a file that does
/// not say both. Reads only the header.
fn piece_identity(path: &Path) -> Result<Option<(String, u64)>, RecordingError> {
    let reader = RecordingReader::open(path)?;
    let value = |key: &str| {
        reader
            .metadata()
            .iter()
            .find(|(k, _)| k == key)
            .map(|(_, v)| v.clone())
    };
    let part = value(PART_KEY).and_then(|p| p.parse::<u64>().ok());
    Ok(value(RECORDING_KEY).zip(part))
}

/// The recordings in a list of files: a file whose header says it is a later piece of the
/// recording the file before it belongs to (the same [`RECORDING_KEY`], a greater
/// [`PART_KEY`], as the recorder writes them) continues that recording; any other file is a
/// recording of its own. For a command that takes several recordings (calibration
/// experiments), so that an experiment the recorder cut into hourly pieces counts as one, its
/// heat accumulated across the cut instead of from rest again. Reads only headers.
pub fn group_pieces(paths: &[PathBuf]) -> Result<Vec<Vec<PathBuf>>, RecordingError> {
    let mut groups: Vec<Vec<PathBuf>> = Vec::new();
    let mut previous: Option<(String, u64)> = None;
    for path in paths {
        let this = piece_identity(path)?;
        let continues = matches!(
            (&previous, &this),
            (Some((recording, part)), Some((now, later))) if recording == now && later > part
        );
        match groups.last_mut() {
            Some(group) if continues => group.push(path.clone()),
            _ => groups.push(vec![path.clone()]),
        }
        previous = this;
    }
    Ok(groups)
}

/// How far a read of pieces is: the bytes read of all of them, against their size when they
/// were opened.
#[derive(Debug, Clone)]
pub struct ReadProgress {
    read: Arc<AtomicU64>,
    total: u64,
}

impl ReadProgress {
    /// The share read, 0 to 1 (a size that could not be learnt only leaves the bar at 1).
    pub fn fraction(&self) -> f32 {
        (self.read.load(Ordering::Relaxed) as f32 / self.total.max(1) as f32).min(1.0)
    }
}

/// A recording file that counts the bytes read from it into a shared total.
struct CountedFile {
    file: File,
    read: Arc<AtomicU64>,
}

impl CountedFile {
    /// Opens the recording at `path`, its bytes counted into `read`.
    fn open_recording(
        path: &Path,
        read: &Arc<AtomicU64>,
    ) -> Result<RecordingReader<CountedFile>, RecordingError> {
        let source = path.display().to_string();
        let file = File::open(path).map_err(|error| RecordingError::Io {
            source_name: source.clone(),
            error,
        })?;
        let counted = CountedFile {
            file,
            read: Arc::clone(read),
        };
        RecordingReader::from_reader(counted, &source)
    }
}

impl Read for CountedFile {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        let n = self.file.read(buf)?;
        self.read.fetch_add(n as u64, Ordering::Relaxed);
        Ok(n)
    }
}

impl RowSource for RecordingPieces {
    fn schema(&self) -> &Schema {
        RecordingPieces::schema(self)
    }

    fn read_row(&mut self, out: &mut Vec<f64>) -> Result<bool, RecordingError> {
        RecordingPieces::read_row(self, out)
    }
}

/// A recording cut into pieces anywhere (a piece may be empty) reads as the whole file does,
/// row by row and into one recording, and, cut on block boundaries, averaged as it does.
#[cfg(test)]
mod tests {
    use super::*;
    use crate::signal::AVERAGED_OVER_S;
    use proptest::prelude::*;

    /// Writes `rows` (time, x) cut before each index of `cuts` into files `name-k.csv` in
    /// `dir`.
    fn write_pieces(dir: &Path, name: &str, rows: &[(f64, f64)], cuts: &[usize]) -> Vec<PathBuf> {
        let mut bounds = vec![0];
        bounds.extend(cuts.iter().copied());
        bounds.push(rows.len());
        bounds
            .windows(2)
            .enumerate()
            .map(|(k, w)| {
                let path = dir.join(format!("{name}-{k}.csv"));
                let mut text = format!("# piece: {k}\ntime_s,x\n");
                for (t, x) in &rows[w[0]..w[1]] {
                    text.push_str(&format!("{t},{x}\n"));
                }
                std::fs::write(&path, text).unwrap();
                path
            })
            .collect()
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        #[test]
        fn pieces_read_as_the_whole(
            n in 1usize..200,
            cut_points in proptest::collection::vec(0.0f64..1.0, 0..5),
            seed in 0u64..1000,
        ) {
            let rows: Vec<(f64, f64)> = (0..n)
                .map(|i| (i as f64 * 0.5, ((i as u64 * 7919 + seed) % 101) as f64))
                .collect();
            let mut cuts: Vec<usize> =
                cut_points.iter().map(|c| (c * n as f64) as usize).collect();
            cuts.sort_unstable();
            let dir = tempfile::tempdir().unwrap();
            let paths = write_pieces(dir.path(), "piece", &rows, &cuts);
            let whole = write_pieces(dir.path(), "whole", &rows, &[]).remove(0);
            let mut pieces = RecordingPieces::open(&paths).unwrap();
            let mut row = Vec::new();
            let mut read = Vec::new();
            while pieces.read_row(&mut row).unwrap() {
                read.push((row[0], row[1]));
            }
            prop_assert_eq!(&read, &rows);
            let joined = RecordingPieces::open(&paths)
                .unwrap()
                .read_observed(usize::MAX, None, &mut |_| true)
                .unwrap();
            let alone = RecordingReader::open(&whole).unwrap().read_to_end().unwrap();
            prop_assert_eq!(joined.time(), alone.time());
            prop_assert_eq!(joined.column("x").unwrap(), alone.column("x").unwrap());
            // Cut on whole seconds, 1 s blocks see the same rows either way.
            let on_blocks: Vec<usize> = cuts.iter().map(|c| c - c % 2).collect();
            let paths = write_pieces(dir.path(), "on-blocks", &rows, &on_blocks);
            let averaged = RecordingPieces::open(&paths)
                .unwrap()
                .read_observed(usize::MAX, Some(1.0), &mut |_| true)
                .unwrap();
            let alone = RecordingReader::open(&whole).unwrap().read_averaged(1.0, usize::MAX).unwrap();
            prop_assert_eq!(averaged.time(), alone.time());
            prop_assert_eq!(averaged.column("x").unwrap(), alone.column("x").unwrap());
            prop_assert_eq!(averaged.metadata_value(AVERAGED_OVER_S), Some("1"));
        }
    }

    /// Pieces out of order are refused where they go wrong, a missing piece or one with
    /// other columns as the pieces are opened (and at its turn, if it changed since); a row
    /// budget counts the rows of every piece.
    #[test]
    fn pieces_out_of_order_or_with_other_columns_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let rows: Vec<(f64, f64)> = (0..10).map(|i| (i as f64, i as f64)).collect();
        let paths = write_pieces(dir.path(), "piece", &rows, &[5]);
        let reversed = [paths[1].clone(), paths[0].clone()];
        let error = RecordingPieces::open(&reversed)
            .unwrap()
            .read_observed(usize::MAX, None, &mut |_| true)
            .unwrap_err();
        assert_eq!(
            error.to_string(),
            format!(
                "{}: line 3: this piece starts at 0 s, before 9 s where {} ends: give the pieces in the order they were recorded",
                paths[0].display(),
                paths[1].display()
            )
        );
        // Blank lines after the header: the line named is the row's, read whole, averaged or
        // row by row.
        let spaced = dir.path().join("spaced.csv");
        std::fs::write(&spaced, "time_s,x\n\n\n2.5,1\n3.5,1\n").unwrap();
        let late = [paths[0].clone(), spaced.clone()];
        let expected = format!(
            "{}: line 4: this piece starts at 2.5 s, before 4 s where {} ends: give the pieces in the order they were recorded",
            spaced.display(),
            paths[0].display()
        );
        for block_s in [None, Some(2.0)] {
            let error = RecordingPieces::open(&late)
                .unwrap()
                .read_observed(usize::MAX, block_s, &mut |_| true)
                .unwrap_err();
            assert_eq!(error.to_string(), expected, "blocks of {block_s:?} s");
        }
        let mut row_by_row = RecordingPieces::open(&late).unwrap();
        let mut row = Vec::new();
        let error = loop {
            match row_by_row.read_row(&mut row) {
                Ok(true) => continue,
                Ok(false) => panic!("the piece out of order was read"),
                Err(error) => break error,
            }
        };
        assert_eq!(error.to_string(), expected);
        let other = dir.path().join("other.csv");
        std::fs::write(&other, "time_s,y\n20,1\n").unwrap();
        let mixed = [paths[0].clone(), other.clone()];
        let error = RecordingPieces::open(&mixed)
            .err()
            .expect("refused at open");
        assert!(
            error
                .to_string()
                .contains("missing [\"x\"], not in the first [\"y\"]"),
            "{error}"
        );
        let error = RecordingPieces::open(&paths)
            .unwrap()
            .read_observed(7, None, &mut |_| true)
            .unwrap_err();
        assert!(
            matches!(error, RecordingError::TooManyRows { .. }),
            "{error}"
        );
        // A piece that gets other columns after the open is refused at its turn.
        let mut pieces = RecordingPieces::open(&paths).unwrap();
        std::fs::copy(&other, &paths[1]).unwrap();
        let mut row = Vec::new();
        for _ in 0..5 {
            assert!(pieces.read_row(&mut row).unwrap());
        }
        let error = pieces.read_row(&mut row).unwrap_err();
        assert!(
            matches!(error, RecordingError::PieceColumns { .. }),
            "{error}"
        );
        let missing = [paths[0].clone(), dir.path().join("never-copied.csv")];
        let error = RecordingPieces::open(&missing)
            .err()
            .expect("refused at open");
        assert!(error.to_string().contains("never-copied.csv"), "{error}");
    }

    /// The recorder's names for a recording's pieces are found beside its first file in the
    /// order of their numbers, a number skipped; other files, another recording's pieces and
    /// names that only look alike are not taken. A first file without an extension has its
    /// pieces named `.csv`, as the recorder names them.
    #[test]
    fn the_pieces_a_recorder_continued_a_recording_in_are_found_in_order() {
        let dir = tempfile::tempdir().unwrap();
        let first = dir.path().join("shift.csv");
        assert_eq!(piece_path(&first, 0), first);
        assert_eq!(piece_path(&first, 2), dir.path().join("shift-0002.csv"));
        assert_eq!(
            piece_path(&first, 12345),
            dir.path().join("shift-12345.csv")
        );
        for name in [
            "shift.csv",
            "shift-0003.csv",
            "shift-0001.csv",
            "shift-0012.csv",
            "shift-12345.csv",
            "shift-00002.csv",
            "shift-0000.csv",
            "shift-01.csv",
            "shift-0002.csv.partial",
            "shift-00x1.csv",
            "shift-0001.txt",
            "other-0001.csv",
            "shift-2-0001.csv",
        ] {
            std::fs::write(dir.path().join(name), "time_s\n").unwrap();
        }
        let names = |found: Vec<PathBuf>| -> Vec<String> {
            assert!(found.iter().all(|p| p.parent() == Some(dir.path())));
            found
                .iter()
                .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
                .collect()
        };
        assert_eq!(
            names(later_pieces(&first).unwrap()),
            [
                "shift-0001.csv",
                "shift-0003.csv",
                "shift-0012.csv",
                "shift-12345.csv"
            ]
        );
        assert!(
            later_pieces(&dir.path().join("shift-0003.csv"))
                .unwrap()
                .is_empty()
        );
        assert!(later_pieces(&dir.path().join("missing").join("a.csv")).is_err());

        let bare = dir.path().join("run");
        std::fs::write(&bare, "time_s\n").unwrap();
        std::fs::write(dir.path().join("run-0001.csv"), "time_s\n").unwrap();
        assert_eq!(names(later_pieces(&bare).unwrap()), ["run-0001.csv"]);
    }

    /// What a list of files leaves out of the recording its first file starts: the later
    /// pieces beside it not in the list, a piece given under another spelling of its path
    /// counting as given; nothing for an empty list.
    #[test]
    fn the_pieces_left_out_are_the_later_ones_not_given_however_spelt() {
        let dir = tempfile::tempdir().unwrap();
        for name in ["day.csv", "day-0001.csv", "day-0002.csv", "day-0003.csv"] {
            std::fs::write(dir.path().join(name), "time_s\n").unwrap();
        }
        let first = dir.path().join("day.csv");
        let spelt_otherwise = dir.path().join(".").join("day-0002.csv");
        let left_out = pieces_left_out(&[first.clone(), spelt_otherwise]).unwrap();
        assert_eq!(
            left_out,
            [
                dir.path().join("day-0001.csv"),
                dir.path().join("day-0003.csv")
            ]
        );
        assert_eq!(pieces_left_out(&[first]).unwrap().len(), 3);
        assert!(pieces_left_out(&[]).unwrap().is_empty());
    }

    /// Where the first piece says which recording it is, as the recorder writes, only the
    /// pieces that say they are its, under their own number, are taken; one whose header
    /// cannot be read is kept, so that reading it names the fault.
    #[test]
    fn pieces_of_another_recording_under_the_same_names_are_not_taken() {
        let dir = tempfile::tempdir().unwrap();
        let piece = |name: &str, recording: &str, part: &str| {
            let text = format!("# {RECORDING_KEY}: {recording}\n# {PART_KEY}: {part}\ntime_s\n");
            std::fs::write(dir.path().join(name), text).unwrap();
        };
        piece("day.csv", "day.csv", "0");
        piece("day-0001.csv", "day.csv", "1");
        piece("day-0002.csv", "an-earlier-day.csv", "2");
        piece("day-0003.csv", "day.csv", "7");
        std::fs::write(dir.path().join("day-0004.csv"), "").unwrap();
        piece("day-0005.csv", "day.csv", "5");
        let found: Vec<String> = later_pieces(&dir.path().join("day.csv"))
            .unwrap()
            .iter()
            .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
            .collect();
        assert_eq!(found, ["day-0001.csv", "day-0004.csv", "day-0005.csv"]);
    }

    /// A read's progress counts the bytes of every piece against their size at open (read
    /// ahead by a buffer of 64 KiB, a tenth of these pieces), and its observer the rows of
    /// every piece.
    #[test]
    fn the_progress_of_a_read_counts_every_piece() {
        let dir = tempfile::tempdir().unwrap();
        let rows: Vec<(f64, f64)> = (0..60_000).map(|i| (i as f64, i as f64)).collect();
        let paths = write_pieces(dir.path(), "piece", &rows, &[20_000, 40_000]);
        let mut pieces = RecordingPieces::open(&paths).unwrap();
        let progress = pieces.progress();
        assert!(progress.fraction() < 0.15, "{}", progress.fraction());
        let mut row = Vec::new();
        for _ in 0..30_000 {
            assert!(pieces.read_row(&mut row).unwrap());
        }
        let halfway = progress.fraction();
        assert!((0.45..0.65).contains(&halfway), "{halfway}");
        let recording = pieces
            .read_observed(usize::MAX, None, &mut |_| true)
            .unwrap();
        assert_eq!(recording.len(), 30_000);
        assert_eq!(progress.fraction(), 1.0);
        // The rows the observer hears count on from piece to piece.
        let mut heard = Vec::new();
        RecordingPieces::open(&paths)
            .unwrap()
            .read_observed(usize::MAX, None, &mut |rows| {
                heard.push(rows);
                true
            })
            .unwrap();
        let every = RecordingReader::<File>::OBSERVED_EVERY;
        assert!(heard.windows(2).all(|w| w[0] < w[1]), "{heard:?}");
        assert_eq!(heard.last(), Some(&(40_000 + 2 * every)), "{heard:?}");
    }

    /// A seek opens the piece that holds its time and reads on from there through the later
    /// pieces; the pieces wholly before it are not read (a damaged row in one does not stop
    /// it), and pieces out of order are read from the first, which names the one too early.
    #[test]
    fn a_seek_starts_in_the_piece_that_holds_its_time() {
        let dir = tempfile::tempdir().unwrap();
        let rows: Vec<(f64, f64)> = (0..300).map(|i| (i as f64, i as f64)).collect();
        let paths = write_pieces(dir.path(), "piece", &rows, &[100, 200]);
        let rest = |(mut pieces, first): (RecordingPieces, Option<Vec<f64>>)| {
            let mut times: Vec<f64> = first.iter().map(|r| r[0]).collect();
            let mut row = Vec::new();
            while pieces.read_row(&mut row).unwrap() {
                times.push(row[0]);
            }
            times
        };
        for (target_s, from) in [(150.0, 150), (100.0, 100), (99.5, 100), (-5.0, 0)] {
            let times = rest(RecordingPieces::open_at(&paths, target_s).unwrap());
            let expected: Vec<f64> = (from..300).map(f64::from).collect();
            assert_eq!(times, expected, "seek to {target_s} s");
        }
        let (_, none) = RecordingPieces::open_at(&paths, 1000.0).unwrap();
        assert_eq!(none, None);

        let text = std::fs::read_to_string(&paths[0])
            .unwrap()
            .replace("\n50,", "\n50,x");
        std::fs::write(&paths[0], text).unwrap();
        assert_eq!(
            rest(RecordingPieces::open_at(&paths, 250.0).unwrap()).len(),
            50
        );
        let error = RecordingPieces::open_at(&paths, 70.0)
            .err()
            .expect("row 50 read");
        assert!(
            error.to_string().contains("piece-0.csv: line 53"),
            "{error}"
        );

        let shuffled = [paths[1].clone(), paths[0].clone(), paths[2].clone()];
        let error = RecordingPieces::open_at(&shuffled, 250.0)
            .err()
            .expect("out of order");
        assert!(
            error
                .to_string()
                .contains("give the pieces in the order they were recorded"),
            "{error}"
        );
    }

    /// In a list of recordings, a file that says it is the next piece of the recording the
    /// file before it belongs to continues it; anything else starts a recording of its own.
    #[test]
    fn consecutive_pieces_of_one_recording_are_grouped() {
        let dir = tempfile::tempdir().unwrap();
        let file = |name: &str, header: &str| {
            let path = dir.path().join(name);
            std::fs::write(&path, format!("{header}time_s\n")).unwrap();
            path
        };
        let key = |recording: &str, part: u32| {
            format!("# {RECORDING_KEY}: {recording}\n# {PART_KEY}: {part}\n")
        };
        let a = file("a.csv", &key("r.csv", 0));
        let b = file("b.csv", &key("r.csv", 1));
        let c = file("c.csv", "");
        let d = file("d.csv", &key("r.csv", 2));
        let e = file("e.csv", &key("s.csv", 0));
        let f = file("f.csv", &key("s.csv", 0));
        let g = file("g.csv", &key("s.csv", 3));
        let groups = group_pieces(&[
            a.clone(),
            b.clone(),
            c.clone(),
            d.clone(),
            e.clone(),
            f.clone(),
            g.clone(),
        ])
        .unwrap();
        assert_eq!(groups, [vec![a, b], vec![c], vec![d], vec![e], vec![f, g]]);
        let missing = group_pieces(&[dir.path().join("none.csv")]).unwrap_err();
        assert!(missing.to_string().contains("none.csv"), "{missing}");
    }
}
