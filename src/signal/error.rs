//! Errors of the recording format: each names the file, the line and, where there is one, the
//! column, so an operator can open the file and find the bad cell.

use std::fmt;

/// Where in a recording a problem is: `file:line` plus the column when one is at fault.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Location {
    /// The file (or stream) name as the user gave it.
    pub source: String,
    /// 1-based line number in the file, counting metadata lines.
    pub line: u64,
    /// 1-based column number and the column's name, when one column is at fault.
    pub column: Option<(usize, String)>,
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: line {}", self.source, self.line)?;
        if let Some((index, name)) = &self.column {
            write!(f, ", column {index} (`{name}`)")?;
        }
        Ok(())
    }
}

/// Where a piece of a recording starts before the one before it ends
/// ([`RecordingError::PieceOutOfOrder`]).
#[derive(Debug, Clone, PartialEq)]
pub struct PieceOrder {
    /// The piece's first row.
    pub at: Location,
    /// Its time, s.
    pub time_s: f64,
    /// The piece before it.
    pub previous: String,
    /// That piece's last time, s.
    pub previous_s: f64,
}

/// A separator other than a comma that a header was written with
/// ([`RecordingError::NotCommaSeparated`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Separator {
    /// `;`: a spreadsheet's export in a language that writes a decimal comma.
    Semicolon,
    /// A tab.
    Tab,
}

impl Separator {
    /// The separator in words.
    pub fn name(self) -> &'static str {
        match self {
            Separator::Semicolon => "`;`",
            Separator::Tab => "tabs",
        }
    }

    /// Where a file separated so usually comes from, as a clause (empty where nothing is
    /// known).
    pub fn likely_source(self) -> &'static str {
        match self {
            Separator::Semicolon => {
                " (a spreadsheet set to a language with a decimal comma exports `;` and `1,5`)"
            }
            Separator::Tab => "",
        }
    }
}

/// Everything that can be wrong with a recording, read or built.
#[derive(Debug, thiserror::Error)]
pub enum RecordingError {
    /// The file could not be opened, read or written.
    // The operating system's error is part of the message and not also its `source`: the
    // command line prints an error's whole chain, which then said it twice.
    #[error("{source_name}: {error}")]
    Io {
        /// The file name.
        source_name: String,
        /// The operating system's error.
        error: std::io::Error,
    },
    /// The file has no header row.
    #[error("{source_name}: no header row (the file is empty or holds only metadata)")]
    NoHeader {
        /// The file name.
        source_name: String,
    },
    /// The first column is not `time_s`.
    #[error("{at}: the first column must be `time_s`, found `{found}`")]
    FirstColumnNotTime {
        /// The header line.
        at: Location,
        /// What the header has instead.
        found: String,
    },
    /// The header's columns are separated by something else than a comma: a spreadsheet's
    /// export in a language that writes a decimal comma (`;`), or a tab-separated file.
    #[error(
        "{at}: the columns are separated by {}, not by commas: CSV v1 separates columns with \
         `,` and writes numbers with a decimal point{}: export it comma-separated with decimal \
         points",
        separator.name(),
        separator.likely_source()
    )]
    NotCommaSeparated {
        /// The header line.
        at: Location,
        /// The separator found.
        separator: Separator,
    },
    /// A header names the same column twice.
    #[error("{at}: duplicate column `{name}` (also column {first})")]
    DuplicateColumn {
        /// The header line and the second occurrence.
        at: Location,
        /// The column name.
        name: String,
        /// 1-based index of the first occurrence.
        first: usize,
    },
    /// A header cell is empty.
    #[error("{at}: empty column name")]
    EmptyColumnName {
        /// The header line and column.
        at: Location,
    },
    /// A metadata line is not `# key: value`.
    #[error("{at}: metadata line is not `# key: value`: `{text}`")]
    MalformedMetadata {
        /// The metadata line.
        at: Location,
        /// The line as read.
        text: String,
    },
    /// The file is not valid UTF-8 or not valid CSV.
    #[error("{at}: {message}")]
    Malformed {
        /// Where the parser stopped.
        at: Location,
        /// What it found.
        message: String,
    },
    /// A row has a different number of fields than the header.
    #[error("{at}: {found} fields, but the header has {expected}")]
    FieldCount {
        /// The row.
        at: Location,
        /// Fields in the header.
        expected: usize,
        /// Fields in this row.
        found: usize,
    },
    /// A cell is not a number.
    #[error("{at}: `{cell}` is not a number")]
    NonNumeric {
        /// The cell.
        at: Location,
        /// Its text (shortened if long).
        cell: String,
    },
    /// A cell is NaN or infinite.
    #[error("{at}: `{cell}` is not a finite number")]
    NonFinite {
        /// The cell.
        at: Location,
        /// Its text.
        cell: String,
    },
    /// A value lies outside the physically plausible range of its channel.
    #[error("{at}: {value} is outside the plausible range {low} to {high} of this channel")]
    OutOfRange {
        /// The cell.
        at: Location,
        /// The value read.
        value: f64,
        /// Lowest plausible value.
        low: f64,
        /// Highest plausible value.
        high: f64,
    },
    /// `time_s` decreases.
    #[error("{at}: time goes backwards: {time_s} s after {previous_s} s")]
    TimeBackwards {
        /// The row.
        at: Location,
        /// This row's time.
        time_s: f64,
        /// The previous row's time.
        previous_s: f64,
    },
    /// A piece of a recording read as one ([`crate::signal::RecordingPieces`]) has other
    /// columns than the first piece.
    #[error(
        "{source_name}: its columns are not those of {first} (the pieces of one recording must share them): {difference}"
    )]
    PieceColumns {
        /// The piece.
        source_name: String,
        /// The first piece.
        first: String,
        /// What differs.
        difference: String,
    },
    /// A piece of a recording read as one starts before the piece before it ends: the pieces
    /// are out of order, or not of one recording.
    #[error(
        "{}: this piece starts at {} s, before {} s where {} ends: give the pieces in the order they were recorded",
        .0.at, .0.time_s, .0.previous_s, .0.previous
    )]
    PieceOutOfOrder(Box<PieceOrder>),
    /// The file holds more rows than the reader was asked to keep: a recording too long to
    /// hold in memory at its own rate (see [`crate::signal::RecordingReader::read_averaged`]).
    #[error(
        "{at}: more than {limit} rows{}",
        .block_s.map(|s| format!(" averaged over {s} s blocks")).unwrap_or_default()
    )]
    TooManyRows {
        /// Where the row past the limit starts.
        at: Location,
        /// Most rows kept.
        limit: usize,
        /// The blocks the rows were averaged over, when they were.
        block_s: Option<f64>,
    },
    /// The caller stopped the read (see [`crate::signal::RecordingReader::read_observed`]);
    /// nothing read is kept.
    #[error("{at}: reading stopped here")]
    Stopped {
        /// The row the read stopped at.
        at: Location,
    },
    /// Rows were to be averaged over blocks that are not a positive length of time.
    #[error(
        "{source_name}: cannot average over blocks of {block_s} s (a block is a positive number of seconds)"
    )]
    InvalidBlock {
        /// The file name.
        source_name: String,
        /// The block asked for.
        block_s: f64,
    },
    /// A column a computation needs is not in the recording.
    #[error("{source_name}: no column `{name}`{}", purpose_suffix(.needed_for))]
    MissingColumn {
        /// The file name.
        source_name: String,
        /// The column that was asked for.
        name: String,
        /// What needed it, when the caller said.
        needed_for: Option<String>,
    },
    /// A column added to a recording has the wrong length.
    #[error("{source_name}: column `{name}` has {found} values, the recording has {expected} rows")]
    ColumnLength {
        /// The recording's name.
        source_name: String,
        /// The column.
        name: String,
        /// Rows in the recording.
        expected: usize,
        /// Values offered.
        found: usize,
    },
}

fn purpose_suffix(purpose: &Option<String>) -> String {
    purpose
        .as_ref()
        .map(|p| format!(" (needed for {p})"))
        .unwrap_or_default()
}

/// Shortens a cell's text for an error message: a 10 MB garbage cell must not become a 10 MB
/// error line.
pub(crate) fn quote_cell(bytes: &[u8]) -> String {
    const MAX: usize = 40;
    let text = String::from_utf8_lossy(bytes);
    if text.chars().count() <= MAX {
        text.into_owned()
    } else {
        let head: String = text.chars().take(MAX).collect();
        format!("{head}…")
    }
}
