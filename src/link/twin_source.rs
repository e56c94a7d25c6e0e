//! The embedded twin as a live source: the HMI's simulated machine, no hardware needed.
//!
//! Rows come from [`crate::sim::Twin`] paced like a replay (1×, N×, as fast as possible,
//! pause). Compensation writes go to an in-process table with the same full-table, read-back
//! semantics as a controller; an applied X backlash compensation changes what the twin
//! simulates.

use std::time::Duration;

use tokio::time::Instant;

use super::{
    ControllerLink, Frame, LinkCommand, LinkError, ReplaySpeed, SourceEnds, WriteOutcome,
    command_or_due,
};
use crate::compensation::{CompensationId, CompensationValues};
use crate::link::register_map::{self as map, CommitStatus};
use crate::signal::AxisId;
use crate::sim::{Twin, TwinConfig};

impl ControllerLink {
    /// Runs the twin as a source at `speed`. `stale_after` as for a replay.
    ///
    /// Frames carry every column the twin produces, in the twin's own schema: the servo
    /// signals, ambient, coolant, the depth of cut of the active block (`cut_depth_mm`, which
    /// the motor abnormality score needs to leave cuts out) and the twin's `ref.*` truth.
    /// Unlike a controller it is not squeezed through the register map, so it needs no map
    /// version; `tests/link_replay.rs` checks that both schemas carry the depth of cut.
    pub fn twin(
        config: TwinConfig,
        speed: ReplaySpeed,
        stale_after: Duration,
    ) -> Result<ControllerLink, LinkError> {
        let twin = Twin::new(config).map_err(|e| LinkError::Unsupported(e.to_string()))?;
        let schema = twin.schema().clone();
        let source = "embedded twin".to_string();
        ControllerLink::start(source, schema, false, stale_after, move |ends| {
            run_twin(twin, speed, stale_after, ends)
        })
    }
}

async fn run_twin(
    mut twin: Twin,
    mut speed: ReplaySpeed,
    stale_after: Duration,
    mut ends: SourceEnds,
) {
    ends.status.send_modify(|s| s.set_line_open(true));
    let mut table: CompensationValues = map::compensation_ids()
        .iter()
        .map(|id| (*id, 0.0))
        .collect();
    let mut generation: u32 = 0;
    let mut token: u16 = 0;
    let mut paused = false;
    let mut origin: Option<(f64, Instant)> = None;
    let mut row = Vec::new();
    let mut pending: Option<Vec<f64>> = None;
    loop {
        if pending.is_none() && !paused {
            if !twin.next_row(&mut row) {
                ends.status.send_modify(|s| {
                    s.last_error = Some("the twin's program has ended".into());
                    s.set_line_open(false);
                });
                return;
            }
            pending = Some(row.clone());
        }
        let due = match (&pending, speed, paused) {
            (_, _, true) | (None, _, _) => None,
            (Some(_), ReplaySpeed::AsFastAsPossible, false) => Some(Instant::now()),
            (Some(values), ReplaySpeed::Factor(factor), false) => {
                let (t0, wall0) = *origin.get_or_insert((values[0], Instant::now()));
                let offset = ((values[0] - t0) / factor.max(1e-6)).max(0.0);
                Some(wall0 + Duration::from_secs_f64(offset))
            }
        };
        let command = command_or_due(&mut ends.commands, due).await;
        match command {
            Some(None) => return,
            Some(Some(LinkCommand::Pause(p))) => {
                paused = p;
                origin = None;
            }
            Some(Some(LinkCommand::Speed(s))) => {
                speed = s;
                origin = None;
            }
            Some(Some(LinkCommand::Seek(_))) => {
                ends.status.send_modify(|s| {
                    s.last_error = Some("the twin cannot seek: it simulates forward only".into());
                });
            }
            Some(Some(LinkCommand::ReadCompensation(reply))) => {
                let _ = reply.send(Ok(table.clone()));
            }
            Some(Some(LinkCommand::WriteCompensation(new_table, reply))) => {
                // The same checks a controller makes: a complete table that fits its registers.
                let result = map::encode_compensation(&new_table)
                    .and_then(|registers| map::decode_compensation(&registers))
                    .map_err(LinkError::from)
                    .map(|staged| {
                        table = staged.clone();
                        generation += 1;
                        token = token.wrapping_add(1).max(1);
                        if let Some(backlash) = table.get(CompensationId::Backlash(AxisId::X)) {
                            twin.set_backlash_compensation_um(backlash);
                        }
                        WriteOutcome {
                            staged,
                            token,
                            echoed_token: token,
                            status: CommitStatus::Applied,
                            generation,
                            applied: table.clone(),
                        }
                    });
                let _ = reply.send(result);
            }
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
