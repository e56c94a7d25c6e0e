//! The controller link: where frames come from, and the only path compensation values take to
//! the controller.
//!
//! A [`ControllerLink`] runs its source on a named thread (`servosight-link`) with its own
//! single-threaded tokio runtime, so the UI thread never waits on I/O. Frames arrive through a
//! bounded channel; when the consumer falls behind, the source waits (backpressure) instead of
//! dropping, so a frame that was received is never lost between link and consumer. Samples the
//! source could not get from the controller are visible in the controller's sequence counter and
//! counted in [`LinkStats`].
//!
//! Sources: [`replay`] (a CSV v1 file at 1×, N× or as fast as possible, with pause and seek),
//! [`twin_source`] (the embedded physics twin) and [`modbus`] (a controller over Modbus RTU on
//! a serial line, map in [`register_map`]). [`controller_sim`] is the other end of that line.

pub mod controller_sim;
pub mod modbus;
pub mod recorder;
pub mod register_map;
pub mod replay;
pub mod twin_source;

use std::time::{Duration, Instant, SystemTime};

use tokio::sync::{mpsc, oneshot, watch};

use crate::compensation::CompensationValues;
use crate::signal::Schema;

pub use modbus::{ModbusConfig, Parity};
pub use recorder::{Recorder, RecorderConfig, RecorderStats};
pub use replay::{ReplayOptions, ReplaySpeed};

/// Frames buffered between the link thread and the consumer. At 1 kHz this is four seconds of
/// slack before the source has to wait for the consumer.
pub const FRAME_CHANNEL_CAPACITY: usize = 4096;

/// One sample from a source.
#[derive(Debug, Clone, PartialEq)]
pub struct Frame {
    /// Values in the order of [`ControllerLink::schema`], `time_s` first. For a live
    /// controller `time_s` is seconds since the link started, taken when the reply arrived.
    pub row: Vec<f64>,
    /// The controller's sequence counter, for sources that have one.
    pub sequence: Option<u32>,
    /// Samples the controller published that never reached the client, just before this one
    /// (a gap in the sequence counter). 0 when nothing was lost.
    pub lost_before: u64,
}

/// Whether what the link shows is live.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ConnectionState {
    /// Fresh samples are arriving.
    Connected,
    /// The line is open but no fresh sample arrived within the staleness limit: the last values
    /// are old and must not be shown or used as live.
    Stale,
    /// No line: the port cannot be opened, it failed, or the source has ended.
    Disconnected,
}

/// Counters of everything that went wrong (or right) on the link.
#[derive(Debug, Clone, Default, PartialEq, Eq, serde::Serialize)]
pub struct LinkStats {
    /// Requests sent (polls, reads and writes).
    pub requests: u64,
    /// Frames delivered to the consumer.
    pub frames: u64,
    /// Requests that got no (complete) reply in time.
    pub timeouts: u64,
    /// Replies whose bytes did not form a frame with a valid CRC; never decoded.
    pub crc_errors: u64,
    /// Modbus exception replies.
    pub exceptions: u64,
    /// Replies with a valid CRC but the wrong slave, function or content.
    pub protocol_errors: u64,
    /// Samples whose decoded values were implausible, refused.
    pub implausible_samples: u64,
    /// Serial port errors (open failures, read/write failures).
    pub io_errors: u64,
    /// Times the port was reopened after the line failed.
    pub reconnects: u64,
    /// Times the port was reopened to resynchronise after garbage on the line (the line
    /// itself stayed up).
    pub resyncs: u64,
    /// Samples lost according to the sequence counter.
    pub lost_samples: u64,
    /// Gaps (runs of lost samples) in the sequence counter.
    pub sequence_gaps: u64,
    /// Replies that repeated the previous sample (sequence unchanged); not delivered again.
    pub repeated_samples: u64,
}

/// What the link thread publishes after every event; [`LinkStatus`] is derived from it at the
/// moment it is asked for, so staleness is judged against the reader's clock, not the writer's.
#[derive(Debug, Clone)]
struct SharedState {
    source: String,
    line_open: bool,
    /// When the line last changed between open and not open.
    line_changed_at: (Instant, SystemTime),
    /// When the last fresh frame arrived.
    last_fresh: Option<Instant>,
    /// When the current run of fresh frames (without a stale pause) began.
    live_since: Option<(Instant, SystemTime)>,
    last_error: Option<String>,
    stats: LinkStats,
}

impl SharedState {
    fn new(source: String) -> Self {
        SharedState {
            source,
            line_open: false,
            line_changed_at: (Instant::now(), SystemTime::now()),
            last_fresh: None,
            live_since: None,
            last_error: None,
            stats: LinkStats::default(),
        }
    }

    fn set_line_open(&mut self, open: bool) {
        if self.line_open != open {
            self.line_open = open;
            self.line_changed_at = (Instant::now(), SystemTime::now());
            if !open {
                self.live_since = None;
            }
        }
    }

    fn fresh_frame(&mut self, stale_after: Duration) {
        let now = Instant::now();
        let was_live = self
            .last_fresh
            .is_some_and(|t| now.duration_since(t) <= stale_after);
        if !was_live || self.live_since.is_none() {
            self.live_since = Some((now, SystemTime::now()));
        }
        self.last_fresh = Some(now);
        self.stats.frames += 1;
    }
}

/// A snapshot of the link for display and for the compensation safety checks.
#[derive(Debug, Clone, serde::Serialize)]
pub struct LinkStatus {
    /// What the link reads from (a port, a file).
    pub source: String,
    /// Connected, stale or disconnected.
    pub state: ConnectionState,
    /// Since when the link has been in `state` (wall clock).
    #[serde(with = "system_time_seconds")]
    pub since: SystemTime,
    /// Seconds since the last fresh frame, if there was one.
    pub last_frame_age_s: Option<f64>,
    /// The most recent error, if any.
    pub last_error: Option<String>,
    /// Counters.
    pub stats: LinkStats,
}

mod system_time_seconds {
    use std::time::SystemTime;
    pub fn serialize<S: serde::Serializer>(t: &SystemTime, s: S) -> Result<S::Ok, S::Error> {
        let seconds = t
            .duration_since(SystemTime::UNIX_EPOCH)
            .map_or(0.0, |d| d.as_secs_f64());
        s.serialize_f64(seconds)
    }
}

fn derive_status(shared: &SharedState, stale_after: Duration) -> LinkStatus {
    let now = Instant::now();
    let wall_of = |instant: Instant| {
        // Map a monotonic instant to wall-clock time through the current pair.
        let now_wall = SystemTime::now();
        match now.checked_duration_since(instant) {
            Some(ago) => now_wall.checked_sub(ago).unwrap_or(now_wall),
            None => now_wall,
        }
    };
    let last_frame_age_s = shared
        .last_fresh
        .map(|t| now.duration_since(t).as_secs_f64());
    let (state, since) = if !shared.line_open {
        (ConnectionState::Disconnected, shared.line_changed_at.1)
    } else {
        match shared.last_fresh {
            Some(t) if now.duration_since(t) <= stale_after => (
                ConnectionState::Connected,
                shared.live_since.map_or(shared.line_changed_at.1, |l| l.1),
            ),
            Some(t) => (ConnectionState::Stale, wall_of(t + stale_after)),
            None => {
                let opened = shared.line_changed_at.0;
                (ConnectionState::Stale, wall_of(opened.min(now)))
            }
        }
    };
    LinkStatus {
        source: shared.source.clone(),
        state,
        since,
        last_frame_age_s,
        last_error: shared.last_error.clone(),
        stats: shared.stats.clone(),
    }
}

/// Errors of the link.
#[derive(Debug, thiserror::Error)]
pub enum LinkError {
    /// The serial port could not be opened or failed.
    #[error("serial port {port}: {message}")]
    Port {
        /// The port.
        port: String,
        /// What failed.
        message: String,
    },
    /// A recording could not be read for replay.
    #[error(transparent)]
    Recording(#[from] crate::signal::RecordingError),
    /// The source cannot do this (a replay has no controller to write to).
    #[error("{0}")]
    Unsupported(String),
    /// The link is not connected or its data is stale; nothing was sent.
    #[error("the link is {state:?}: {detail}")]
    NotLive {
        /// The state at the time of the request.
        state: ConnectionState,
        /// Why.
        detail: String,
    },
    /// A request to the controller failed (timeout, CRC error, exception, I/O).
    #[error("controller request failed: {0}")]
    Request(String),
    /// Register contents did not decode.
    #[error(transparent)]
    Map(#[from] register_map::MapError),
    /// The link thread is gone.
    #[error("the link has shut down")]
    Closed,
    /// The link thread could not be started.
    #[error("cannot start the link thread: {0}")]
    Thread(std::io::Error),
}

/// The controller's answer to a compensation write, read back after the commit.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct WriteOutcome {
    /// The table that was staged (the complete table, quantised to the register resolution).
    pub staged: CompensationValues,
    /// The commit token sent.
    pub token: u16,
    /// The token the controller says it last processed.
    pub echoed_token: u16,
    /// The controller's commit status.
    pub status: register_map::CommitStatus,
    /// The applied generation after the commit.
    pub generation: u32,
    /// The applied table read back after the commit.
    pub applied: CompensationValues,
}

impl WriteOutcome {
    /// True when the controller processed this commit, applied it and echoes exactly the staged
    /// table.
    pub fn verified(&self) -> bool {
        self.echoed_token == self.token
            && self.status == register_map::CommitStatus::Applied
            && self.applied == self.staged
    }
}

/// Requests from the handle to the link thread.
enum LinkCommand {
    ReadCompensation(oneshot::Sender<Result<CompensationValues, LinkError>>),
    WriteCompensation(
        CompensationValues,
        oneshot::Sender<Result<WriteOutcome, LinkError>>,
    ),
    Pause(bool),
    Seek(f64),
    Speed(ReplaySpeed),
}

/// A reply that will arrive from the link thread.
#[must_use = "a pending reply does nothing unless waited for"]
pub struct PendingReply<T> {
    receiver: oneshot::Receiver<Result<T, LinkError>>,
}

impl<T> PendingReply<T> {
    /// Blocks until the reply arrives. Call from a plain thread (the CLI, a worker), never from
    /// the UI thread or inside an async task.
    pub fn wait(self) -> Result<T, LinkError> {
        self.receiver
            .blocking_recv()
            .unwrap_or(Err(LinkError::Closed))
    }

    /// Waits for the reply in async code.
    pub async fn wait_async(self) -> Result<T, LinkError> {
        self.receiver.await.unwrap_or(Err(LinkError::Closed))
    }

    /// The reply if it has arrived, without waiting (for the UI's frame loop).
    pub fn try_take(&mut self) -> Option<Result<T, LinkError>> {
        match self.receiver.try_recv() {
            Ok(reply) => Some(reply),
            Err(oneshot::error::TryRecvError::Empty) => None,
            Err(oneshot::error::TryRecvError::Closed) => Some(Err(LinkError::Closed)),
        }
    }
}

/// The controller link: frames in, compensation values out.
pub struct ControllerLink {
    schema: Schema,
    has_sequence: bool,
    frames: mpsc::Receiver<Frame>,
    commands: mpsc::Sender<LinkCommand>,
    status: watch::Receiver<SharedState>,
    stale_after: Duration,
    thread: Option<std::thread::JoinHandle<()>>,
}

/// The next command for a paced source, or `None` once its pending frame is `due` (`Some(None)`:
/// the handle is gone; with no `due`, it waits for a command alone). A frame already due is
/// sent without waiting on the timer, whose millisecond tick held an as-fast-as-possible replay
/// to about a thousand frames a second.
async fn command_or_due(
    commands: &mut mpsc::Receiver<LinkCommand>,
    due: Option<tokio::time::Instant>,
) -> Option<Option<LinkCommand>> {
    match due {
        Some(at) if at <= tokio::time::Instant::now() => match commands.try_recv() {
            Ok(command) => Some(Some(command)),
            Err(mpsc::error::TryRecvError::Empty) => None,
            Err(mpsc::error::TryRecvError::Disconnected) => Some(None),
        },
        Some(at) => tokio::select! {
            biased;
            command = commands.recv() => Some(command),
            _ = tokio::time::sleep_until(at) => None,
        },
        None => Some(commands.recv().await),
    }
}

/// What a source task gets to talk to the handle.
struct SourceEnds {
    frames: mpsc::Sender<Frame>,
    commands: mpsc::Receiver<LinkCommand>,
    status: watch::Sender<SharedState>,
}

impl ControllerLink {
    /// Starts a source task on the link thread.
    fn start<F, Fut>(
        source: String,
        schema: Schema,
        has_sequence: bool,
        stale_after: Duration,
        task: F,
    ) -> Result<ControllerLink, LinkError>
    where
        F: FnOnce(SourceEnds) -> Fut + Send + 'static,
        Fut: std::future::Future<Output = ()>,
    {
        let (frame_tx, frame_rx) = mpsc::channel(FRAME_CHANNEL_CAPACITY);
        let (command_tx, command_rx) = mpsc::channel(16);
        let (status_tx, status_rx) = watch::channel(SharedState::new(source));
        let ends = SourceEnds {
            frames: frame_tx,
            commands: command_rx,
            status: status_tx,
        };
        let runtime = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .map_err(LinkError::Thread)?;
        let thread = std::thread::Builder::new()
            .name("servosight-link".into())
            .spawn(move || runtime.block_on(task(ends)))
            .map_err(LinkError::Thread)?;
        Ok(ControllerLink {
            schema,
            has_sequence,
            frames: frame_rx,
            commands: command_tx,
            status: status_rx,
            stale_after,
            thread: Some(thread),
        })
    }

    /// The columns of every frame, `time_s` first.
    pub fn schema(&self) -> &Schema {
        &self.schema
    }

    /// True when frames carry the controller's sequence counter.
    pub fn has_sequence(&self) -> bool {
        self.has_sequence
    }

    /// How long without a fresh frame before the data counts as stale.
    pub fn stale_after(&self) -> Duration {
        self.stale_after
    }

    /// The next frame if one is waiting; never blocks (for the UI's frame loop).
    pub fn try_next_frame(&mut self) -> Option<Frame> {
        self.frames.try_recv().ok()
    }

    /// Waits for the next frame; `None` once the source has ended.
    pub async fn next_frame(&mut self) -> Option<Frame> {
        self.frames.recv().await
    }

    /// The connection state, judged now.
    pub fn status(&self) -> LinkStatus {
        derive_status(&self.status.borrow(), self.stale_after)
    }

    fn send(&self, command: LinkCommand) {
        // A full or closed command queue answers through the dropped reply sender (`Closed`).
        let _ = self.commands.try_send(command);
    }

    /// Reads the compensation values the controller is applying now.
    pub fn read_compensation(&self) -> PendingReply<CompensationValues> {
        let (tx, rx) = oneshot::channel();
        self.send(LinkCommand::ReadCompensation(tx));
        PendingReply { receiver: rx }
    }

    /// Stages a complete compensation table, commits it and reads it back. Crate-private on
    /// purpose: the only way to reach it is [`crate::compensation`]'s approved, bounded path.
    pub(crate) fn write_compensation(
        &self,
        table: CompensationValues,
    ) -> PendingReply<WriteOutcome> {
        let (tx, rx) = oneshot::channel();
        self.send(LinkCommand::WriteCompensation(table, tx));
        PendingReply { receiver: rx }
    }

    /// Pauses or resumes a replay (no effect on a live controller).
    pub fn set_paused(&self, paused: bool) {
        self.send(LinkCommand::Pause(paused));
    }

    /// Moves a replay to the first row at or after `time_s`.
    pub fn seek(&self, time_s: f64) {
        self.send(LinkCommand::Seek(time_s));
    }

    /// Changes a replay's speed.
    pub fn set_speed(&self, speed: ReplaySpeed) {
        self.send(LinkCommand::Speed(speed));
    }
}

impl Drop for ControllerLink {
    fn drop(&mut self) {
        // Closing the frame receiver and the command sender ends the source task, which ends
        // the thread; joining keeps the serial port from outliving the handle.
        self.frames.close();
        let (closed_tx, _) = mpsc::channel(1);
        self.commands = closed_tx;
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}
