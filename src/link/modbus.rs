//! A controller over Modbus RTU on a serial line (tokio-modbus's RTU client on tokio-serial).
//!
//! One task owns the port and serialises everything on it: polls of the sample block at the
//! configured rate and, between polls, compensation reads and writes. Every request has a
//! timeout; failures are classified (timeout, CRC error, exception, protocol, I/O), counted in
//! [`LinkStats`](super::LinkStats), and retried with exponential backoff; after a run of
//! failures or any port error the port is closed and reopened, so an unplugged line comes back
//! by itself.
//!
//! tokio-modbus resynchronises silently on a bad CRC (it drops bytes and waits for a valid
//! frame), so to count CRC errors the port is wrapped in a `WireTap` that keeps the bytes of
//! the current reply; a failed request whose reply bytes contain no frame with a valid CRC is a
//! CRC error, one with no reply bytes at all is a timeout.

use std::pin::Pin;
use std::sync::{Arc, Mutex};
use std::task::{Context, Poll};
use std::time::Duration;

use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio::time::Instant;
use tokio_modbus::client::{Context as ModbusContext, Reader, Writer};
use tokio_modbus::prelude::rtu;
use tokio_modbus::{ExceptionCode, Slave};
use tokio_serial::{SerialPort, SerialPortBuilderExt, SerialStream};

use super::register_map::{self as map, CommitStatus};
use super::{ControllerLink, Frame, LinkCommand, LinkError, SourceEnds, WriteOutcome};
use crate::compensation::CompensationValues;

/// Parity of the serial line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Parity {
    /// No parity bit (Modbus then asks for two stop bits, but most devices run 8N1).
    None,
    /// Even parity (the Modbus default).
    Even,
    /// Odd parity.
    Odd,
}

impl std::str::FromStr for Parity {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.to_ascii_lowercase().as_str() {
            "none" | "n" => Ok(Parity::None),
            "even" | "e" => Ok(Parity::Even),
            "odd" | "o" => Ok(Parity::Odd),
            _ => Err(format!("unknown parity `{s}` (expected none, even or odd)")),
        }
    }
}

/// Settings of a Modbus RTU controller link.
#[derive(Debug, Clone, PartialEq)]
pub struct ModbusConfig {
    /// The serial device, e.g. `/dev/ttyUSB0`.
    pub port: String,
    /// Baud rate.
    pub baud: u32,
    /// Parity.
    pub parity: Parity,
    /// Stop bits: 1 or 2.
    pub stop_bits: u8,
    /// The controller's slave id (1..=247).
    pub slave: u8,
    /// Polls of the sample block per second (the link polls slower if the line cannot keep up).
    pub poll_hz: f64,
    /// How long to wait for a reply.
    pub request_timeout: Duration,
    /// First retry delay after a failure; doubled per consecutive failure up to `max_backoff`.
    pub min_backoff: Duration,
    /// Longest retry delay.
    pub max_backoff: Duration,
    /// Consecutive failed requests after which the port is closed and reopened.
    pub reconnect_after_failures: u32,
    /// No fresh sample for this long and the data counts as stale.
    pub stale_after: Duration,
}

impl ModbusConfig {
    /// Defaults for `port`: 115200 baud, 8N1, slave 1, 50 Hz polling, 200 ms timeout.
    pub fn new(port: impl Into<String>) -> Self {
        ModbusConfig {
            port: port.into(),
            baud: 115_200,
            parity: Parity::None,
            stop_bits: 1,
            slave: 1,
            poll_hz: 50.0,
            request_timeout: Duration::from_millis(200),
            min_backoff: Duration::from_millis(20),
            max_backoff: Duration::from_secs(1),
            reconnect_after_failures: 5,
            stale_after: Duration::from_millis(500),
        }
    }

    fn poll_period(&self) -> Duration {
        Duration::from_secs_f64(1.0 / self.poll_hz.clamp(0.01, 10_000.0))
    }
}

impl ControllerLink {
    /// Connects to a controller over Modbus RTU. Returns at once; the port is opened (and
    /// reopened) on the link thread, and [`ControllerLink::status`] tells how that goes.
    pub fn modbus(config: ModbusConfig) -> Result<ControllerLink, LinkError> {
        if !(1..=247).contains(&config.slave) {
            return Err(LinkError::Port {
                port: config.port.clone(),
                message: format!("slave id {} is outside 1..=247", config.slave),
            });
        }
        let source = format!(
            "Modbus RTU {} @ {} baud, slave {}",
            config.port, config.baud, config.slave
        );
        let stale_after = config.stale_after;
        ControllerLink::start(
            source,
            map::sample_schema(),
            true,
            stale_after,
            move |ends| run_modbus(config, ends),
        )
    }
}

/// The bytes of the reply to the request in flight.
#[derive(Debug, Default)]
struct TapState {
    reply: Vec<u8>,
    /// Discard whatever is waiting in the port's input before the next request: after a failed
    /// request, late bytes of its reply must not be taken for the next one's.
    clear_before_next_request: bool,
}

/// The serial port with a tap on its receive side.
struct WireTap {
    port: SerialStream,
    state: Arc<Mutex<TapState>>,
    request_started: bool,
}

impl AsyncRead for WireTap {
    fn poll_read(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &mut ReadBuf<'_>,
    ) -> Poll<std::io::Result<()>> {
        let before = buf.filled().len();
        let result = Pin::new(&mut self.port).poll_read(cx, buf);
        if let Poll::Ready(Ok(())) = result {
            self.request_started = false;
            if let Ok(mut state) = self.state.lock() {
                state.reply.extend_from_slice(&buf.filled()[before..]);
            }
        }
        result
    }
}

impl AsyncWrite for WireTap {
    fn poll_write(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        data: &[u8],
    ) -> Poll<std::io::Result<usize>> {
        if !self.request_started {
            // The first write of a request: a new reply begins.
            self.request_started = true;
            let clear = match self.state.lock() {
                Ok(mut state) => {
                    state.reply.clear();
                    std::mem::take(&mut state.clear_before_next_request)
                }
                Err(_) => false,
            };
            if clear {
                let _ = self.port.clear(tokio_serial::ClearBuffer::Input);
            }
        }
        Pin::new(&mut self.port).poll_write(cx, data)
    }

    fn poll_flush(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<std::io::Result<()>> {
        Pin::new(&mut self.port).poll_flush(cx)
    }

    fn poll_shutdown(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<std::io::Result<()>> {
        Pin::new(&mut self.port).poll_shutdown(cx)
    }
}

/// Why a request failed.
#[derive(Debug, Clone, PartialEq)]
enum Failure {
    Timeout,
    Crc,
    /// Garbage the RTU decoder could not resynchronise on: it has shut its stream, and the
    /// port has to be reopened before the next request.
    CrcDecoderGaveUp,
    Exception(ExceptionCode),
    Protocol(String),
    Io(String),
}

impl std::fmt::Display for Failure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Failure::Timeout => write!(f, "no reply within the timeout"),
            Failure::Crc => write!(f, "reply with a bad CRC (discarded)"),
            Failure::CrcDecoderGaveUp => {
                write!(
                    f,
                    "reply with a bad CRC (discarded; reopening the port to resynchronise)"
                )
            }
            Failure::Exception(code) => write!(f, "Modbus exception {code:?}"),
            Failure::Protocol(message) => write!(f, "protocol error: {message}"),
            Failure::Io(message) => write!(f, "port error: {message}"),
        }
    }
}

/// CRC-16/MODBUS of a byte string.
pub fn crc16_modbus(bytes: &[u8]) -> u16 {
    let mut crc: u16 = 0xFFFF;
    for byte in bytes {
        crc ^= u16::from(*byte);
        for _ in 0..8 {
            crc = if crc & 1 != 0 {
                (crc >> 1) ^ 0xA001
            } else {
                crc >> 1
            };
        }
    }
    crc
}

/// True when some prefix of `bytes` (slave, function, data, CRC low, CRC high) is an RTU frame
/// with a valid CRC.
fn contains_valid_frame(bytes: &[u8]) -> bool {
    (4..=bytes.len()).any(|end| {
        let (body, crc) = bytes[..end].split_at(end - 2);
        crc16_modbus(body) == u16::from_le_bytes([crc[0], crc[1]])
    })
}

/// Names the failure of a request from its outcome and the reply bytes seen.
fn classify(error: Option<tokio_modbus::Error>, reply: &[u8]) -> Failure {
    let bad_bytes = !reply.is_empty() && !contains_valid_frame(reply);
    match error {
        Some(tokio_modbus::Error::Protocol(protocol)) => Failure::Protocol(protocol.to_string()),
        Some(tokio_modbus::Error::Transport(io)) => {
            if io.kind() == std::io::ErrorKind::InvalidData {
                // The decoder gave up resynchronising: garbage on the line.
                Failure::CrcDecoderGaveUp
            } else {
                Failure::Io(io.to_string())
            }
        }
        None if bad_bytes => Failure::Crc,
        None => Failure::Timeout,
    }
}

/// The connection to the controller: the modbus context and the tap on its port.
struct Connection {
    modbus: ModbusContext,
    tap: Arc<Mutex<TapState>>,
}

fn open(config: &ModbusConfig) -> Result<Connection, String> {
    let parity = match config.parity {
        Parity::None => tokio_serial::Parity::None,
        Parity::Even => tokio_serial::Parity::Even,
        Parity::Odd => tokio_serial::Parity::Odd,
    };
    let stop_bits = if config.stop_bits == 2 {
        tokio_serial::StopBits::Two
    } else {
        tokio_serial::StopBits::One
    };
    let port = tokio_serial::new(&config.port, config.baud)
        .parity(parity)
        .stop_bits(stop_bits)
        .data_bits(tokio_serial::DataBits::Eight)
        .flow_control(tokio_serial::FlowControl::None)
        .open_native_async()
        .map_err(|e| e.to_string())?;
    let tap = Arc::new(Mutex::new(TapState::default()));
    let transport = WireTap {
        port,
        state: Arc::clone(&tap),
        request_started: false,
    };
    Ok(Connection {
        modbus: rtu::attach_slave(transport, Slave(config.slave)),
        tap,
    })
}

impl Connection {
    /// Runs one request with a timeout and classifies its failure.
    async fn request<T, F>(
        &mut self,
        timeout: Duration,
        call: F,
        ends: &SourceEnds,
    ) -> Result<T, Failure>
    where
        F: for<'a> FnOnce(
            &'a mut ModbusContext,
        ) -> Pin<
            Box<dyn std::future::Future<Output = tokio_modbus::Result<T>> + Send + 'a>,
        >,
    {
        ends.status.send_modify(|s| s.stats.requests += 1);
        let outcome = tokio::time::timeout(timeout, call(&mut self.modbus)).await;
        let reply = match self.tap.lock() {
            Ok(state) => state.reply.clone(),
            Err(_) => Vec::new(),
        };
        let failure = match outcome {
            Ok(Ok(Ok(value))) => return Ok(value),
            Ok(Ok(Err(exception))) => Failure::Exception(exception),
            Ok(Err(error)) => classify(Some(error), &reply),
            Err(_elapsed) => classify(None, &reply),
        };
        if let Ok(mut state) = self.tap.lock() {
            state.clear_before_next_request = true;
        }
        ends.status.send_modify(|s| {
            match &failure {
                Failure::Timeout => s.stats.timeouts += 1,
                Failure::Crc | Failure::CrcDecoderGaveUp => s.stats.crc_errors += 1,
                Failure::Exception(_) => s.stats.exceptions += 1,
                Failure::Protocol(_) => s.stats.protocol_errors += 1,
                Failure::Io(_) => s.stats.io_errors += 1,
            }
            s.last_error = Some(failure.to_string());
        });
        Err(failure)
    }

    async fn read_input(
        &mut self,
        timeout: Duration,
        start: u16,
        count: u16,
        ends: &SourceEnds,
    ) -> Result<Vec<u16>, Failure> {
        self.request(
            timeout,
            |m| Box::pin(m.read_input_registers(start, count)),
            ends,
        )
        .await
    }

    async fn read_holding(
        &mut self,
        timeout: Duration,
        start: u16,
        count: u16,
        ends: &SourceEnds,
    ) -> Result<Vec<u16>, Failure> {
        self.request(
            timeout,
            |m| Box::pin(m.read_holding_registers(start, count)),
            ends,
        )
        .await
    }

    async fn write_holding(
        &mut self,
        timeout: Duration,
        start: u16,
        words: Vec<u16>,
        ends: &SourceEnds,
    ) -> Result<(), Failure> {
        self.request(
            timeout,
            move |m| Box::pin(async move { m.write_multiple_registers(start, &words).await }),
            ends,
        )
        .await
    }
}

/// Link-side bookkeeping of the sequence counter.
#[derive(Debug, Default)]
struct SequenceTracker {
    last: Option<u32>,
}

enum SequenceStep {
    Fresh { lost_before: u64 },
    Repeat,
}

impl SequenceTracker {
    fn step(&mut self, sequence: u32) -> SequenceStep {
        let step = match self.last {
            None => SequenceStep::Fresh { lost_before: 0 },
            Some(last) => match sequence.wrapping_sub(last) {
                0 => SequenceStep::Repeat,
                // A jump "backwards" (a huge wrapping difference) is a restarted controller:
                // its counter began again, and how much was lost in between is unknown.
                delta if delta > u32::MAX / 2 => SequenceStep::Fresh { lost_before: 0 },
                delta => SequenceStep::Fresh {
                    lost_before: u64::from(delta - 1),
                },
            },
        };
        self.last = Some(sequence);
        step
    }
}

/// Waits out `delay` while still answering commands; `false` when the handle is gone.
async fn pause_answering(delay: Duration, ends: &mut SourceEnds, why: &str) -> bool {
    let until = Instant::now() + delay;
    loop {
        tokio::select! {
            _ = tokio::time::sleep_until(until) => return true,
            command = ends.commands.recv() => match command {
                None => return false,
                Some(command) => refuse(command, why),
            },
        }
    }
}

/// Answers a command the link cannot carry out now.
fn refuse(command: LinkCommand, why: &str) {
    let error = || LinkError::NotLive {
        state: super::ConnectionState::Disconnected,
        detail: why.to_string(),
    };
    match command {
        LinkCommand::ReadCompensation(reply) => {
            let _ = reply.send(Err(error()));
        }
        LinkCommand::WriteCompensation(_, reply) => {
            let _ = reply.send(Err(error()));
        }
        LinkCommand::Pause(_) | LinkCommand::Seek(_) | LinkCommand::Speed(_) => {}
    }
}

fn backoff(config: &ModbusConfig, failures: u32) -> Duration {
    let factor = 1u32 << failures.saturating_sub(1).min(16);
    (config.min_backoff * factor).min(config.max_backoff)
}

async fn run_modbus(config: ModbusConfig, mut ends: SourceEnds) {
    let started = Instant::now();
    let mut sequence = SequenceTracker::default();
    let mut opened_before = false;
    let mut open_failures: u32 = 0;
    let mut resyncing = false;
    loop {
        let mut connection = match open(&config) {
            Ok(connection) => connection,
            Err(message) => {
                open_failures += 1;
                ends.status.send_modify(|s| {
                    s.stats.io_errors += 1;
                    s.last_error = Some(format!("cannot open {}: {message}", config.port));
                    s.set_line_open(false);
                });
                let delay = backoff(&config, open_failures);
                if !pause_answering(delay, &mut ends, "the serial port is not open").await {
                    return;
                }
                continue;
            }
        };
        open_failures = 0;
        ends.status.send_modify(|s| {
            if resyncing {
                s.stats.resyncs += 1;
            } else if opened_before {
                s.stats.reconnects += 1;
            }
            s.set_line_open(true);
        });
        opened_before = true;
        let reopen = serve(&config, &mut connection, &mut ends, &mut sequence, started).await;
        // Dropping the connection closes the port before it is opened again.
        drop(connection);
        resyncing = reopen == Reopen::Resync;
        match reopen {
            Reopen::Stop => return,
            // The line itself is fine: the state stays as it is while the port is reopened.
            Reopen::Resync => {}
            Reopen::Reconnect => {
                ends.status.send_modify(|s| s.set_line_open(false));
                if !pause_answering(config.min_backoff, &mut ends, "reconnecting").await {
                    return;
                }
            }
        }
    }
}

/// Why [`serve`] returned.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Reopen {
    /// The handle is gone: stop.
    Stop,
    /// The line failed: close, mark disconnected, reopen with backoff.
    Reconnect,
    /// The line is fine but the RTU decoder shut down on garbage: reopen at once.
    Resync,
}

/// Polls and answers commands on an open port until the port must be reopened or the handle
/// is gone.
async fn serve(
    config: &ModbusConfig,
    connection: &mut Connection,
    ends: &mut SourceEnds,
    sequence: &mut SequenceTracker,
    started: Instant,
) -> Reopen {
    let period = config.poll_period();
    let mut next_poll = Instant::now();
    let mut failures: u32 = 0;
    loop {
        tokio::select! {
            biased;
            command = ends.commands.recv() => {
                let Some(command) = command else { return Reopen::Stop };
                match command {
                    LinkCommand::ReadCompensation(reply) => {
                        let result = read_applied(config, connection, ends).await;
                        let _ = reply.send(result);
                    }
                    LinkCommand::WriteCompensation(table, reply) => {
                        let result = write_table(config, connection, ends, table).await;
                        let _ = reply.send(result);
                    }
                    LinkCommand::Pause(_) | LinkCommand::Seek(_) | LinkCommand::Speed(_) => {}
                }
            }
            _ = tokio::time::sleep_until(next_poll) => {
                let poll_started = Instant::now();
                let result = connection
                    .read_input(
                        config.request_timeout,
                        map::SAMPLE_BLOCK_START,
                        map::SAMPLE_BLOCK_LEN,
                        ends,
                    )
                    .await;
                let received_s = started.elapsed().as_secs_f64();
                match result {
                    Ok(registers) => {
                        failures = 0;
                        match map::decode_sample(&registers) {
                            Ok(sample) => {
                                if let SequenceStep::Fresh { lost_before } = sequence.step(sample.sequence) {
                                    let mut row = Vec::with_capacity(sample.values.len() + 1);
                                    row.push(received_s);
                                    row.extend_from_slice(&sample.values);
                                    let frame = Frame { row, sequence: Some(sample.sequence), lost_before };
                                    if ends.frames.send(frame).await.is_err() {
                                        return Reopen::Stop;
                                    }
                                    ends.status.send_modify(|s| {
                                        if lost_before > 0 {
                                            s.stats.lost_samples += lost_before;
                                            s.stats.sequence_gaps += 1;
                                        }
                                        s.fresh_frame(config.stale_after);
                                    });
                                } else {
                                    ends.status.send_modify(|s| s.stats.repeated_samples += 1);
                                }
                            }
                            Err(error) => {
                                ends.status.send_modify(|s| {
                                    s.stats.implausible_samples += 1;
                                    s.last_error = Some(error.to_string());
                                });
                            }
                        }
                        next_poll = (poll_started + period).max(Instant::now());
                    }
                    Err(failure) => {
                        failures += 1;
                        if failure == Failure::CrcDecoderGaveUp {
                            return Reopen::Resync;
                        }
                        if matches!(failure, Failure::Io(_)) || failures >= config.reconnect_after_failures {
                            return Reopen::Reconnect;
                        }
                        next_poll = Instant::now() + backoff(config, failures);
                    }
                }
            }
        }
    }
}

fn request_error(failure: Failure) -> LinkError {
    LinkError::Request(failure.to_string())
}

async fn read_applied(
    config: &ModbusConfig,
    connection: &mut Connection,
    ends: &SourceEnds,
) -> Result<CompensationValues, LinkError> {
    let registers = connection
        .read_holding(
            config.request_timeout,
            map::APPLIED_VALUES_START,
            map::compensation_table_len(),
            ends,
        )
        .await
        .map_err(request_error)?;
    Ok(map::decode_compensation(&registers)?)
}

/// Stage, commit, read back. The link refuses to send anything while its data is not live.
async fn write_table(
    config: &ModbusConfig,
    connection: &mut Connection,
    ends: &SourceEnds,
    table: CompensationValues,
) -> Result<WriteOutcome, LinkError> {
    let status = super::derive_status(&ends.status.borrow(), config.stale_after);
    if status.state != super::ConnectionState::Connected {
        return Err(LinkError::NotLive {
            state: status.state,
            detail: "no compensation is written on stale or disconnected data".into(),
        });
    }
    let staged_registers = map::encode_compensation(&table)?;
    let staged = map::decode_compensation(&staged_registers)?;
    let timeout = config.request_timeout;
    let handshake = connection
        .read_holding(
            timeout,
            map::COMMIT_STATUS_REGISTER,
            map::HANDSHAKE_LEN,
            ends,
        )
        .await
        .map_err(request_error)?;
    let last_token =
        handshake[usize::from(map::LAST_COMMIT_TOKEN_REGISTER - map::COMMIT_STATUS_REGISTER)];
    let token = match last_token.wrapping_add(1) {
        0 => 1,
        t => t,
    };
    let checksum = map::staging_checksum(&staged_registers);
    connection
        .write_holding(timeout, map::STAGED_VALUES_START, staged_registers, ends)
        .await
        .map_err(request_error)?;
    connection
        .write_holding(
            timeout,
            map::STAGED_CHECKSUM_REGISTER,
            vec![checksum, token],
            ends,
        )
        .await
        .map_err(request_error)?;
    let handshake = connection
        .read_holding(
            timeout,
            map::COMMIT_STATUS_REGISTER,
            map::HANDSHAKE_LEN,
            ends,
        )
        .await
        .map_err(request_error)?;
    let at = |register: u16| handshake[usize::from(register - map::COMMIT_STATUS_REGISTER)];
    let applied = read_applied(config, connection, ends).await?;
    Ok(WriteOutcome {
        staged,
        token,
        echoed_token: at(map::LAST_COMMIT_TOKEN_REGISTER),
        status: CommitStatus::from_code(at(map::COMMIT_STATUS_REGISTER)),
        generation: map::join_words(
            at(map::APPLIED_GENERATION_REGISTER),
            at(map::APPLIED_GENERATION_REGISTER + 1),
        ),
        applied,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crc_matches_the_modbus_reference() {
        assert_eq!(crc16_modbus(b"123456789"), 0x4B37);
        // Read 2 input registers at 0 from slave 1: 01 04 00 00 00 02 71 CB.
        let frame = [0x01, 0x04, 0x00, 0x00, 0x00, 0x02, 0x71, 0xCB];
        assert!(contains_valid_frame(&frame));
        let mut flipped = frame;
        flipped[3] ^= 0x10;
        assert!(!contains_valid_frame(&flipped));
    }

    #[test]
    fn failures_are_classified_from_the_reply_bytes() {
        assert_eq!(classify(None, &[]), Failure::Timeout);
        assert_eq!(
            classify(None, &[0x01, 0x04, 0x02, 0x00, 0x00, 0xAA, 0xBB]),
            Failure::Crc
        );
        let io = std::io::Error::new(std::io::ErrorKind::InvalidData, "Too many retries");
        assert_eq!(
            classify(Some(io.into()), &[1, 2, 3]),
            Failure::CrcDecoderGaveUp
        );
    }

    #[test]
    fn sequence_gaps_repeats_and_restarts() {
        let mut tracker = SequenceTracker::default();
        assert!(matches!(
            tracker.step(10),
            SequenceStep::Fresh { lost_before: 0 }
        ));
        assert!(matches!(
            tracker.step(11),
            SequenceStep::Fresh { lost_before: 0 }
        ));
        assert!(matches!(tracker.step(11), SequenceStep::Repeat));
        assert!(matches!(
            tracker.step(15),
            SequenceStep::Fresh { lost_before: 3 }
        ));
        assert!(matches!(
            tracker.step(u32::MAX),
            SequenceStep::Fresh { lost_before: 0 }
        ));
        assert!(matches!(
            tracker.step(1),
            SequenceStep::Fresh { lost_before: 1 }
        ));
        assert!(matches!(
            tracker.step(0),
            SequenceStep::Fresh { lost_before: 0 }
        ));
    }
}
