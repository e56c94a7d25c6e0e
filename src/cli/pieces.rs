//! Which files make up the one recording a command reads: the files given, or the first of
//! them and every piece the recorder continued it in (`--with-later-pieces`); and a warning
//! when pieces of it lie beside the first file that the command was not given.
//!
//! The recorder starts a new piece every hour (`shift.csv`, `shift-0001.csv`, …), so a shift
//! is several files. A command given `shift.csv` alone would report on its first hour without
//! a word, and a glob such as `shift-0*.csv` misses `shift-10000.csv`: both are said here.

use std::path::PathBuf;

use servosight::signal::{RecordingPieces, pieces_left_out, with_later_pieces};

/// `--with-later-pieces`, for a command that reads one recording.
#[derive(Debug, Clone, Default, clap::Args)]
pub struct LaterPieces {
    /// Read, after the one file given, every piece the recorder continued it in that lies
    /// beside it (<stem>-0001.<ext>, <stem>-0002.<ext>, … in the order of their numbers; a
    /// piece whose header says it belongs to another recording is not taken): the whole
    /// recording, however many pieces it has, without listing them.
    #[arg(long)]
    pub with_later_pieces: bool,
}

/// The files to read for the recording given as `given` (the command's `option`, named in
/// the refusal): `given` itself, or with `--with-later-pieces` its one file and the later pieces
/// found beside it, which stderr names. Where pieces of the recording lie beside its first
/// file and are not read, stderr warns and the warning is returned, for a report that keeps
/// its notes. The flag with more than one file given is refused: which pieces it should add
/// would be a guess.
pub fn recording_files(
    given: &[PathBuf],
    later: &LaterPieces,
    option: &str,
) -> anyhow::Result<(Vec<PathBuf>, Option<String>)> {
    if later.with_later_pieces {
        let [first] = given else {
            anyhow::bail!(
                "--with-later-pieces finds the pieces after the one file given, and {} were \
                 given to {option}: give the recording's first file alone, or every piece \
                 without --with-later-pieces",
                given.len()
            );
        };
        let files = with_later_pieces(first, true).map_err(anyhow::Error::msg)?;
        if let [_, later @ ..] = files.as_slice()
            && !later.is_empty()
        {
            eprintln!(
                "reading {} with the pieces the recorder continued it in: {}",
                first.display(),
                RecordingPieces::short_name(later)
            );
        }
        return Ok((files, None));
    }
    let warning = warn_of_pieces_left_out(
        given,
        "add --with-later-pieces (with the first file alone) to read the whole recording",
    );
    Ok((given.to_vec(), warning))
}

/// Warns on stderr, and returns the warning, where the recorder continued the recording
/// `given` starts in pieces beside its first file that `given` leaves out; `remedy` says how
/// to read them.
pub fn warn_of_pieces_left_out(given: &[PathBuf], remedy: &str) -> Option<String> {
    // A directory that cannot be listed leaves nothing to warn of: reading the files given
    // names any fault of theirs.
    let left_out = pieces_left_out(given).unwrap_or_default();
    let warning = given.first().filter(|_| !left_out.is_empty()).map(|first| {
        format!(
            "the recorder continued {} in {} beside it, which were not given and this command \
             leaves out: {remedy}",
            first.display(),
            RecordingPieces::short_name(&left_out)
        )
    });
    if let Some(warning) = &warning {
        eprintln!("warning: {warning}");
    }
    warning
}
