//! The append-only, hash-chained audit log of compensation pushes (JSON lines).
//!
//! Each line is one entry; its `hash` is SHA-256 over the entry serialised with an empty
//! `hash`, and that serialisation includes `prev_hash`, the hash of the line before (64 zeros
//! for the first). Changing, inserting, reordering or deleting a line breaks the chain at that
//! line; [`verify`] also requires every line to be exactly the canonical serialisation of its
//! entry, so even a change that leaves the meaning alone (spacing, key order) is detected.
//! Cutting lines off the end leaves a valid shorter chain: compare the count and head hash that
//! [`verify`] reports with a copy kept elsewhere to detect that.

use std::fs::{File, OpenOptions};
use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};

use sha2::{Digest, Sha256};

use super::CompensationValues;

/// The `prev_hash` of the first entry.
pub const GENESIS_HASH: &str = "0000000000000000000000000000000000000000000000000000000000000000";

/// What happened to a push (or one step of it).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Outcome {
    /// Written, read back and verified.
    Applied,
    /// Refused before anything was sent (approval, bounds, stale data).
    Refused,
    /// The write did not complete (timeout, exception, port error).
    WriteFailed,
    /// Written, but the read-back did not match: the controller did not apply it.
    VerifyFailed,
}

/// One line of the audit log.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AuditEntry {
    /// 0-based position in the log.
    pub index: u64,
    /// When, UTC, ISO 8601.
    pub time_utc: String,
    /// Identifies the request this entry belongs to (several steps share one).
    pub request_id: String,
    /// `adjust` or `rollback of <request id>`.
    pub action: String,
    /// Who requested.
    pub operator: String,
    /// Who approved, if anyone did.
    pub approver: Option<String>,
    /// Why (the proposal's reason).
    pub why: String,
    /// The evidence the proposal cites (a recording, an estimate, a report).
    pub evidence: String,
    /// Step number and count for a split push, e.g. `[2, 5]`.
    pub step: Option<(u32, u32)>,
    /// The controller, as the link names it.
    pub controller: String,
    /// The values before, for the ids this entry touches.
    pub old: CompensationValues,
    /// The values asked for in this entry.
    pub new: CompensationValues,
    /// What happened.
    pub outcome: Outcome,
    /// Details: the refusal reason, the failure, the read-back.
    pub detail: String,
    /// Hash of the previous line.
    pub prev_hash: String,
    /// Hash of this entry.
    pub hash: String,
}

/// Everything in an entry that the caller decides (the log fills in index, time and hashes).
#[derive(Debug, Clone, PartialEq)]
pub struct EntryContent {
    /// See [`AuditEntry::request_id`].
    pub request_id: String,
    /// See [`AuditEntry::action`].
    pub action: String,
    /// See [`AuditEntry::operator`].
    pub operator: String,
    /// See [`AuditEntry::approver`].
    pub approver: Option<String>,
    /// See [`AuditEntry::why`].
    pub why: String,
    /// See [`AuditEntry::evidence`].
    pub evidence: String,
    /// See [`AuditEntry::step`].
    pub step: Option<(u32, u32)>,
    /// See [`AuditEntry::controller`].
    pub controller: String,
    /// See [`AuditEntry::old`].
    pub old: CompensationValues,
    /// See [`AuditEntry::new`].
    pub new: CompensationValues,
    /// See [`AuditEntry::outcome`].
    pub outcome: Outcome,
    /// See [`AuditEntry::detail`].
    pub detail: String,
}

/// Errors of the audit log.
#[derive(Debug, thiserror::Error)]
pub enum AuditError {
    /// The file could not be read or written.
    // The operating system's error is part of the message and not also its `source`: the
    // command line prints an error's whole chain, which then said it twice.
    #[error("{path}: {error}")]
    Io {
        /// The file.
        path: String,
        /// The operating system's error.
        error: std::io::Error,
    },
    /// The chain is broken: the log was edited.
    #[error("{path}: line {line}: {reason}")]
    Broken {
        /// The file.
        path: String,
        /// 1-based line.
        line: u64,
        /// What is wrong there.
        reason: String,
    },
    /// The log no longer holds an entry it held before: its end was cut or it was replaced.
    #[error(
        "{path}: no entry has the head {head} read earlier (the log now holds {entries} \
         entries): entries were removed from its end, or the log was replaced"
    )]
    LostHead {
        /// The log.
        path: String,
        /// The head hash expected.
        head: String,
        /// Entries the log holds now.
        entries: u64,
    },
}

/// The result of a successful verification.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct VerifyReport {
    /// Entries in the log.
    pub entries: u64,
    /// Hash of the last entry (the genesis hash for an empty log).
    pub head_hash: String,
}

fn entry_hash(entry: &AuditEntry) -> String {
    let mut unhashed = entry.clone();
    unhashed.hash = String::new();
    // Serialising a plain struct of strings, numbers and maps cannot fail.
    let text = serde_json::to_string(&unhashed).unwrap_or_default();
    let digest = Sha256::digest(text.as_bytes());
    digest.iter().map(|b| format!("{b:02x}")).collect()
}

/// Checks every line of the log; the first broken one is the error.
pub fn verify(path: &Path) -> Result<VerifyReport, AuditError> {
    verify_holding(path, None)
}

/// [`verify`], and that the log still holds the entry whose hash is `head`: a head read
/// earlier (printed by `audit verify` at the end of a shift, say). A chain cannot show on its
/// own that entries were cut from its end, or that the whole log was emptied; an earlier head
/// it no longer holds does.
pub fn verify_holding(path: &Path, head: Option<&str>) -> Result<VerifyReport, AuditError> {
    let report = verify_chain(path, head)?;
    match head {
        Some(head) if !report.1 => Err(AuditError::LostHead {
            path: path.display().to_string(),
            head: head.to_string(),
            entries: report.0.entries,
        }),
        _ => Ok(report.0),
    }
}

/// The chain check; also whether an entry (or the empty log's genesis) has the hash `head`.
fn verify_chain(path: &Path, head: Option<&str>) -> Result<(VerifyReport, bool), AuditError> {
    let name = path.display().to_string();
    let file = File::open(path).map_err(|error| AuditError::Io {
        path: name.clone(),
        error,
    })?;
    let mut prev_hash = GENESIS_HASH.to_string();
    let mut entries = 0u64;
    let mut holds_head = head == Some(GENESIS_HASH);
    for (i, line) in BufReader::new(file).lines().enumerate() {
        let line_no = i as u64 + 1;
        let broken = |reason: String| AuditError::Broken {
            path: name.clone(),
            line: line_no,
            reason,
        };
        let line = line.map_err(|error| AuditError::Io {
            path: name.clone(),
            error,
        })?;
        let entry: AuditEntry =
            serde_json::from_str(&line).map_err(|e| broken(format!("not an audit entry: {e}")))?;
        if entry.index != entries {
            return Err(broken(format!(
                "entry index {} where {entries} was expected (a line was removed or inserted)",
                entry.index
            )));
        }
        if entry.prev_hash != prev_hash {
            return Err(broken(
                "prev_hash does not match the line before (a line was removed, inserted or changed)"
                    .into(),
            ));
        }
        if entry_hash(&entry) != entry.hash {
            return Err(broken(
                "the entry does not match its hash (it was edited)".into(),
            ));
        }
        let canonical = serde_json::to_string(&entry).unwrap_or_default();
        if canonical != line {
            return Err(broken(
                "the line is not in canonical form (it was edited)".into(),
            ));
        }
        holds_head |= head == Some(entry.hash.as_str());
        prev_hash = entry.hash;
        entries += 1;
    }
    Ok((
        VerifyReport {
            entries,
            head_hash: prev_hash,
        },
        holds_head,
    ))
}

/// An open audit log, verified on open, appended to with every entry synced to disk.
pub struct AuditLog {
    path: PathBuf,
    file: File,
    next_index: u64,
    head_hash: String,
}

impl AuditLog {
    /// Opens (or creates) a log. A log whose chain is broken is refused: appending to it would
    /// bury the evidence of the edit.
    pub fn open(path: &Path) -> Result<AuditLog, AuditError> {
        let report = if path.exists() {
            verify(path)?
        } else {
            VerifyReport {
                entries: 0,
                head_hash: GENESIS_HASH.to_string(),
            }
        };
        let file = OpenOptions::new()
            .create(true)
            .append(true)
            .open(path)
            .map_err(|error| AuditError::Io {
                path: path.display().to_string(),
                error,
            })?;
        Ok(AuditLog {
            path: path.to_path_buf(),
            file,
            next_index: report.entries,
            head_hash: report.head_hash,
        })
    }

    /// The file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Appends an entry and syncs it to disk before returning it.
    pub fn append(&mut self, content: EntryContent) -> Result<AuditEntry, AuditError> {
        let mut entry = AuditEntry {
            index: self.next_index,
            time_utc: utc_now(),
            request_id: content.request_id,
            action: content.action,
            operator: content.operator,
            approver: content.approver,
            why: content.why,
            evidence: content.evidence,
            step: content.step,
            controller: content.controller,
            old: content.old,
            new: content.new,
            outcome: content.outcome,
            detail: content.detail,
            prev_hash: self.head_hash.clone(),
            hash: String::new(),
        };
        entry.hash = entry_hash(&entry);
        let mut line = serde_json::to_string(&entry).unwrap_or_default();
        line.push('\n');
        let io = |error| AuditError::Io {
            path: self.path.display().to_string(),
            error,
        };
        self.file.write_all(line.as_bytes()).map_err(io)?;
        self.file.sync_data().map_err(io)?;
        self.next_index += 1;
        self.head_hash = entry.hash.clone();
        Ok(entry)
    }

    /// Every entry, read back from the file (verified).
    pub fn entries(&self) -> Result<Vec<AuditEntry>, AuditError> {
        verify(&self.path)?;
        let name = self.path.display().to_string();
        let text = std::fs::read_to_string(&self.path).map_err(|error| AuditError::Io {
            path: name.clone(),
            error,
        })?;
        text.lines()
            .enumerate()
            .map(|(i, line)| {
                serde_json::from_str(line).map_err(|e| AuditError::Broken {
                    path: name.clone(),
                    line: i as u64 + 1,
                    reason: e.to_string(),
                })
            })
            .collect()
    }
}

/// Now as `YYYY-MM-DDTHH:MM:SS.mmmZ`.
pub fn utc_now() -> String {
    let since_epoch = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap_or_default();
    format_utc(since_epoch.as_secs(), since_epoch.subsec_millis())
}

/// Formats seconds since the Unix epoch as ISO 8601 UTC (civil-from-days, proleptic Gregorian).
fn format_utc(seconds: u64, millis: u32) -> String {
    let days = (seconds / 86_400) as i64;
    let rem = seconds % 86_400;
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!(
        "{year:04}-{month:02}-{day:02}T{:02}:{:02}:{:02}.{millis:03}Z",
        rem / 3600,
        rem % 3600 / 60,
        rem % 60
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::compensation::CompensationId;
    use crate::signal::AxisId;

    fn content(outcome: Outcome) -> EntryContent {
        let id = CompensationId::Backlash(AxisId::X);
        EntryContent {
            request_id: "r1".into(),
            action: "adjust".into(),
            operator: "otto".into(),
            approver: Some("maria".into()),
            why: "backlash grew".into(),
            evidence: "run.csv".into(),
            step: Some((1, 1)),
            controller: "test".into(),
            old: [(id, 3.0)].into_iter().collect(),
            new: [(id, 4.5)].into_iter().collect(),
            outcome,
            detail: String::new(),
        }
    }

    #[test]
    fn utc_formatting_matches_known_dates() {
        assert_eq!(format_utc(0, 0), "1970-01-01T00:00:00.000Z");
        assert_eq!(format_utc(951_782_400, 5), "2000-02-29T00:00:00.005Z");
        assert_eq!(format_utc(1_700_000_000, 0), "2023-11-14T22:13:20.000Z");
    }

    /// Cutting entries from the end, or emptying the log, leaves a chain that is intact on
    /// its own; a head read before the cut is what shows it.
    #[test]
    fn a_cut_end_is_caught_by_an_earlier_head() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("audit.jsonl");
        let mut log = AuditLog::open(&path).unwrap();
        for outcome in [Outcome::Applied, Outcome::Refused, Outcome::Applied] {
            log.append(content(outcome)).unwrap();
        }
        drop(log);
        let full = verify(&path).unwrap();
        let original = std::fs::read_to_string(&path).unwrap();
        let lines: Vec<&str> = original.lines().collect();
        std::fs::write(
            &path,
            format!(
                "{}
{}
",
                lines[0], lines[1]
            ),
        )
        .unwrap();
        let cut = verify(&path).unwrap();
        assert_eq!(cut.entries, 2, "the cut chain is intact on its own");
        assert!(matches!(
            verify_holding(&path, Some(&full.head_hash)),
            Err(AuditError::LostHead { entries: 2, .. })
        ));
        // A head the log still holds (an earlier entry's) passes.
        assert_eq!(
            verify_holding(&path, Some(&cut.head_hash)).unwrap().entries,
            2
        );
        std::fs::write(&path, "").unwrap();
        assert_eq!(verify(&path).unwrap().entries, 0);
        assert!(matches!(
            verify_holding(&path, Some(&full.head_hash)),
            Err(AuditError::LostHead { entries: 0, .. })
        ));
    }

    #[test]
    fn any_edit_breaks_the_chain() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("audit.jsonl");
        let mut log = AuditLog::open(&path).unwrap();
        for outcome in [Outcome::Applied, Outcome::Refused, Outcome::VerifyFailed] {
            log.append(content(outcome)).unwrap();
        }
        drop(log);
        let report = verify(&path).unwrap();
        assert_eq!(report.entries, 3);
        let original = std::fs::read_to_string(&path).unwrap();
        let lines: Vec<&str> = original.lines().collect();
        let edits = [
            original.replacen("4.5", "5.5", 1),
            original.replacen("\"refused\"", "\"applied\"", 1),
            original.replacen("{\"index\":1,", "{\"index\":1, ", 1),
            format!("{}\n{}\n", lines[0], lines[2]),
            format!("{}\n{}\n{}\n", lines[1], lines[0], lines[2]),
        ];
        for (i, edited) in edits.iter().enumerate() {
            assert_ne!(edited, &original, "edit {i} changed nothing");
            std::fs::write(&path, edited).unwrap();
            assert!(
                matches!(verify(&path), Err(AuditError::Broken { .. })),
                "edit {i} went unnoticed"
            );
            assert!(
                AuditLog::open(&path).is_err(),
                "a broken log is not appended to"
            );
        }
    }
}
