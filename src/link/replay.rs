//! Replay of a CSV v1 recording as if it were a live source: one file, or the pieces a recorder
//! rotated it into, read as one.

use std::path::PathBuf;
use std::time::Duration;

use tokio::time::Instant;

use super::{ControllerLink, Frame, LinkCommand, LinkError, SourceEnds, command_or_due};
use crate::signal::RecordingPieces;

/// How fast a replay runs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ReplaySpeed {
    /// `factor` seconds of recording per second of wall clock (1.0 is real time).
    Factor(f64),
    /// As fast as the consumer takes frames.
    AsFastAsPossible,
}

/// Options of a replay.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReplayOptions {
    /// Playback speed.
    pub speed: ReplaySpeed,
    /// Start paused.
    pub paused: bool,
    /// How long without a frame before the replay counts as stale (a paused replay goes stale:
    /// its values are not live).
    pub stale_after: Duration,
}

impl Default for ReplayOptions {
    fn default() -> Self {
        ReplayOptions {
            speed: ReplaySpeed::Factor(1.0),
            paused: false,
            stale_after: Duration::from_secs(1),
        }
    }
}

impl ControllerLink {
    /// Replays a recording: one file, or the pieces of one recording in the order they were
    /// recorded (the recorder starts a new file every hour, `shift.csv`, `shift-0001.csv`, …),
    /// read as one ([`RecordingPieces`]). Every piece's header is read now, so a missing or
    /// broken file, or a piece with other columns, is reported here; a bad row later, or a
    /// piece that starts before the piece before it ends, ends the replay with the error, which
    /// names the file, in the status, after every row before it was delivered. A seek may go
    /// to any piece.
    ///
    /// The frames have exactly the file's columns. A recording without `cut_depth_mm` (older
    /// files, or ones from a controller that does not publish it) stays without it: no depth
    /// is made up, because a 0 would claim "not cutting" and cuts would be scored as motor
    /// friction. The estimators then say which score they cannot compute
    /// ([`crate::estimators::EstimatorPipeline::notes`]).
    pub fn replay(pieces: &[PathBuf], options: ReplayOptions) -> Result<ControllerLink, LinkError> {
        let reader = RecordingPieces::open(pieces)?;
        let schema = reader.schema().clone();
        let pieces = pieces.to_vec();
        let source = format!("replay of {}", RecordingPieces::short_name(&pieces));
        ControllerLink::start(source, schema, false, options.stale_after, move |ends| {
            run_replay(pieces, reader, options, ends)
        })
    }
}

/// The replay position: the file's time and the wall-clock moment that maps to it.
struct Clock {
    file_origin_s: f64,
    wall_origin: Instant,
}

async fn run_replay(
    pieces: Vec<PathBuf>,
    mut reader: RecordingPieces,
    options: ReplayOptions,
    mut ends: SourceEnds,
) {
    ends.status.send_modify(|s| s.set_line_open(true));
    let stale_after = options.stale_after;
    let mut speed = options.speed;
    let mut paused = options.paused;
    let mut clock: Option<Clock> = None;
    let mut row = Vec::new();
    let mut pending: Option<Vec<f64>> = None;
    loop {
        if pending.is_none() && !paused {
            match reader.read_row(&mut row) {
                Ok(true) => pending = Some(row.clone()),
                Ok(false) => {
                    ends.status.send_modify(|s| {
                        s.last_error = Some("end of recording".into());
                        s.set_line_open(false);
                    });
                    return;
                }
                Err(error) => {
                    ends.status.send_modify(|s| {
                        s.last_error = Some(error.to_string());
                        s.set_line_open(false);
                    });
                    return;
                }
            }
        }
        let due = match (&pending, speed, paused) {
            (_, _, true) | (None, _, _) => None,
            (Some(_), ReplaySpeed::AsFastAsPossible, false) => Some(Instant::now()),
            (Some(values), ReplaySpeed::Factor(factor), false) => {
                let clock = clock.get_or_insert(Clock {
                    file_origin_s: values[0],
                    wall_origin: Instant::now(),
                });
                let offset_s = ((values[0] - clock.file_origin_s) / factor.max(1e-6)).max(0.0);
                Some(clock.wall_origin + Duration::from_secs_f64(offset_s))
            }
        };
        let command = command_or_due(&mut ends.commands, due).await;
        match command {
            // The handle is gone.
            Some(None) => return,
            Some(Some(command)) => match command {
                LinkCommand::Pause(p) => {
                    paused = p;
                    clock = None;
                }
                LinkCommand::Speed(s) => {
                    speed = s;
                    clock = None;
                }
                LinkCommand::Seek(target_s) => match seek(&pieces, target_s) {
                    Ok((new_reader, first)) => {
                        reader = new_reader;
                        pending = first;
                        clock = None;
                    }
                    Err(error) => {
                        ends.status
                            .send_modify(|s| s.last_error = Some(error.to_string()));
                    }
                },
                LinkCommand::ReadCompensation(reply) => {
                    let _ = reply.send(Err(LinkError::Unsupported(
                        "a replay has no controller to read compensation from".into(),
                    )));
                }
                LinkCommand::WriteCompensation(_, reply) => {
                    let _ = reply.send(Err(LinkError::Unsupported(
                        "a replay has no controller to write compensation to".into(),
                    )));
                }
            },
            None => {
                if let Some(values) = pending.take() {
                    let frame = Frame {
                        row: values,
                        sequence: None,
                        lost_before: 0,
                    };
                    if ends.frames.send(frame).await.is_err() {
                        return;
                    }
                    ends.status.send_modify(|s| s.fresh_frame(stale_after));
                }
            }
        }
    }
}

/// Reopens the recording at the first row at or after `target_s`
/// ([`RecordingPieces::open_at`]: the pieces wholly before it are not read).
fn seek(
    pieces: &[PathBuf],
    target_s: f64,
) -> Result<(RecordingPieces, Option<Vec<f64>>), LinkError> {
    Ok(RecordingPieces::open_at(pieces, target_s)?)
}
