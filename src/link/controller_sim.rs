//! The controller side of the register map: a Modbus RTU slave that publishes samples from a
//! [`SampleSource`] and accepts compensation through the stage-then-commit handshake, exactly
//! as `docs/register-map.md` describes. `servosight sim-controller` serves a source with it so
//! the whole stack runs end to end without hardware.
//!
//! Every read of the sample block publishes one new sample (the sequence counter increments
//! per read), so a reply lost on the line shows up as a gap on the client side.

use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use tokio_modbus::server::Service;
use tokio_modbus::{ExceptionCode, Request, Response, SlaveRequest};
use tokio_serial::SerialPortBuilderExt;

use super::register_map::{self as map, CommitStatus, DecodedSample};
use crate::compensation::CompensationValues;

/// Where the served samples come from.
pub trait SampleSource: Send {
    /// The next sample's values in [`map::sample_columns`] order, without `time_s`, at
    /// `elapsed` since serving began. `None` when the source has nothing (more) to give; the
    /// controller then answers reads with a "slave device failure" exception.
    fn sample(&mut self, elapsed: Duration) -> Option<Vec<f64>>;

    /// The controller applied a new compensation table (a twin lets it change what it
    /// simulates; a replay ignores it).
    fn compensation_applied(&mut self, _table: &CompensationValues) {}
}

/// Hard limits the controller itself enforces on a commit, µm (independent of servosight's
/// own, stricter, per-profile limits: the last line of defence).
pub const CONTROLLER_HARD_LIMIT_UM: f64 = 500.0;

/// The controller's registers and its sample source.
struct ControllerState {
    source: Box<dyn SampleSource>,
    started: Instant,
    sequence: u32,
    /// Holding registers from [`map::COMMIT_STATUS_REGISTER`] to the end of the applied echo.
    holding: Vec<u16>,
    commits: u64,
}

fn holding_len() -> usize {
    usize::from(
        map::APPLIED_VALUES_START + map::compensation_table_len() - map::COMMIT_STATUS_REGISTER,
    )
}

impl ControllerState {
    fn holding_index(address: u16) -> usize {
        usize::from(address - map::COMMIT_STATUS_REGISTER)
    }

    fn read_samples(&mut self, address: u16, count: u16) -> Result<Vec<u16>, ExceptionCode> {
        let end = u32::from(address) + u32::from(count);
        if address != map::SAMPLE_BLOCK_START
            || end > u32::from(map::SAMPLE_BLOCK_START + map::SAMPLE_BLOCK_LEN)
        {
            // A sample is only consistent as a whole block: partial reads are refused.
            return Err(ExceptionCode::IllegalDataAddress);
        }
        let values = self
            .source
            .sample(self.started.elapsed())
            .ok_or(ExceptionCode::ServerDeviceFailure)?;
        self.sequence = self.sequence.wrapping_add(1);
        let sample = DecodedSample {
            sequence: self.sequence,
            clock_ms: self.started.elapsed().as_millis() as u32,
            values,
        };
        let registers =
            map::encode_sample(&sample).map_err(|_| ExceptionCode::ServerDeviceFailure)?;
        Ok(registers[..usize::from(count)].to_vec())
    }

    fn read_holding(&self, address: u16, count: u16) -> Result<Vec<u16>, ExceptionCode> {
        let start = address
            .checked_sub(map::COMMIT_STATUS_REGISTER)
            .ok_or(ExceptionCode::IllegalDataAddress)?;
        let end = usize::from(start) + usize::from(count);
        if end > self.holding.len() {
            return Err(ExceptionCode::IllegalDataAddress);
        }
        Ok(self.holding[usize::from(start)..end].to_vec())
    }

    fn write_holding(&mut self, address: u16, words: &[u16]) -> Result<(), ExceptionCode> {
        let table_len = map::compensation_table_len();
        let end = u32::from(address) + words.len() as u32;
        let in_staging = address >= map::STAGED_VALUES_START
            && end <= u32::from(map::STAGED_VALUES_START + table_len);
        let is_commit = address == map::STAGED_CHECKSUM_REGISTER && words.len() == 2;
        if in_staging {
            let at = Self::holding_index(address);
            self.holding[at..at + words.len()].copy_from_slice(words);
            return Ok(());
        }
        if !is_commit {
            return Err(ExceptionCode::IllegalDataAddress);
        }
        let (checksum, token) = (words[0], words[1]);
        let staged_at = Self::holding_index(map::STAGED_VALUES_START);
        let staged = self.holding[staged_at..staged_at + usize::from(table_len)].to_vec();
        let status = if map::staging_checksum(&staged) != checksum {
            CommitStatus::RejectedChecksum
        } else {
            match map::decode_compensation(&staged) {
                Ok(table)
                    if table
                        .iter()
                        .all(|(_, v)| v.abs() <= CONTROLLER_HARD_LIMIT_UM) =>
                {
                    let applied_at = Self::holding_index(map::APPLIED_VALUES_START);
                    self.holding[applied_at..applied_at + staged.len()].copy_from_slice(&staged);
                    self.commits += 1;
                    let (high, low) = map::split_words(self.commits as u32);
                    let generation_at = Self::holding_index(map::APPLIED_GENERATION_REGISTER);
                    self.holding[generation_at] = high;
                    self.holding[generation_at + 1] = low;
                    self.source.compensation_applied(&table);
                    CommitStatus::Applied
                }
                _ => CommitStatus::RejectedLimits,
            }
        };
        self.holding[Self::holding_index(map::COMMIT_STATUS_REGISTER)] = status.code();
        self.holding[Self::holding_index(map::LAST_COMMIT_TOKEN_REGISTER)] = token;
        self.holding[Self::holding_index(map::STAGED_CHECKSUM_REGISTER)] = checksum;
        self.holding[Self::holding_index(map::COMMIT_TOKEN_REGISTER)] = token;
        Ok(())
    }
}

/// A Modbus service answering one slave id.
struct SlaveService {
    slave: u8,
    state: Arc<Mutex<ControllerState>>,
}

impl Service for SlaveService {
    type Request = SlaveRequest<'static>;
    type Response = Option<Response>;
    type Exception = ExceptionCode;
    type Future = std::future::Ready<Result<Self::Response, Self::Exception>>;

    fn call(&self, request: Self::Request) -> Self::Future {
        if request.slave != self.slave {
            // Another device on the bus is addressed: stay silent, as RTU slaves do.
            return std::future::ready(Ok(None));
        }
        let Ok(mut state) = self.state.lock() else {
            return std::future::ready(Err(ExceptionCode::ServerDeviceFailure));
        };
        let result = match request.request {
            Request::ReadInputRegisters(address, count) => state
                .read_samples(address, count)
                .map(|r| Some(Response::ReadInputRegisters(r))),
            Request::ReadHoldingRegisters(address, count) => state
                .read_holding(address, count)
                .map(|r| Some(Response::ReadHoldingRegisters(r))),
            Request::WriteMultipleRegisters(address, words) => {
                state.write_holding(address, &words).map(|()| {
                    Some(Response::WriteMultipleRegisters(
                        address,
                        words.len() as u16,
                    ))
                })
            }
            Request::WriteSingleRegister(address, word) => state
                .write_holding(address, &[word])
                .map(|()| Some(Response::WriteSingleRegister(address, word))),
            _ => Err(ExceptionCode::IllegalFunction),
        };
        std::future::ready(result)
    }
}

/// Errors of the simulated controller.
#[derive(Debug, thiserror::Error)]
pub enum ControllerSimError {
    /// The serial port could not be opened.
    #[error("serial port {port}: {message}")]
    Port {
        /// The port.
        port: String,
        /// What failed.
        message: String,
    },
}

/// Serves `source` as slave `slave` on `port` until the process ends. Garbage on the line makes
/// the RTU decoder give up; the port is then reopened and serving goes on.
pub async fn serve(
    port: &str,
    baud: u32,
    slave: u8,
    source: Box<dyn SampleSource>,
) -> Result<(), ControllerSimError> {
    let mut holding = vec![0u16; holding_len()];
    holding[ControllerState::holding_index(map::COMMIT_STATUS_REGISTER)] =
        CommitStatus::Idle.code();
    let state = Arc::new(Mutex::new(ControllerState {
        source,
        started: Instant::now(),
        sequence: 0,
        holding,
        commits: 0,
    }));
    loop {
        let serial = tokio_serial::new(port, baud)
            .open_native_async()
            .map_err(|e| ControllerSimError::Port {
                port: port.to_string(),
                message: e.to_string(),
            })?;
        let server = tokio_modbus::server::rtu::Server::new(serial);
        let service = SlaveService {
            slave,
            state: Arc::clone(&state),
        };
        // An error here is a garbled request or a port failure: reopen and serve on.
        let _ = server.serve_forever(service).await;
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
}

/// Serves the rows of a recording as samples: the row at the elapsed time (looping at the end),
/// columns matched by name.
pub struct RecordingSource {
    recording: crate::signal::Recording,
    columns: Vec<usize>,
    speed: f64,
}

impl RecordingSource {
    /// Maps the recording's columns onto the sample block; every mapped column must be present.
    ///
    /// That includes the depth of cut: a recording without `cut_depth_mm` is refused rather
    /// than served with 0 in its register, because 0 means "not cutting" on the line and the
    /// client would score every cut in the file as motor friction. (The map has no "unknown"
    /// code for it, on purpose: a controller always knows its program.) Such a file can still
    /// be replayed directly (`servosight --replay`), where the missing column stays missing
    /// and the estimators say what they cannot compute.
    pub fn new(
        recording: crate::signal::Recording,
        speed: f64,
    ) -> Result<RecordingSource, crate::signal::RecordingError> {
        let mut columns = Vec::new();
        for name in &map::sample_columns()[1..] {
            let index = recording.schema().index_of(name).ok_or_else(|| {
                let needed_for = if name == crate::signal::channel::CUT_DEPTH {
                    "serving the register map: without it every cut would be published as \
                     \"not cutting\" (0); replay the file with `servosight --replay` instead"
                } else {
                    "serving the register map"
                };
                crate::signal::RecordingError::MissingColumn {
                    source_name: recording.source().to_string(),
                    name: name.clone(),
                    needed_for: Some(needed_for.into()),
                }
            })?;
            columns.push(index);
        }
        if recording.is_empty() {
            return Err(crate::signal::RecordingError::NoHeader {
                source_name: recording.source().to_string(),
            });
        }
        Ok(RecordingSource {
            recording,
            columns,
            speed: speed.max(1e-6),
        })
    }
}

impl SampleSource for RecordingSource {
    fn sample(&mut self, elapsed: Duration) -> Option<Vec<f64>> {
        let time = self.recording.time();
        let first = *time.first()?;
        let span = self.recording.duration_s();
        let offset = elapsed.as_secs_f64() * self.speed;
        let target = if span > 0.0 {
            first + offset % span
        } else {
            first
        };
        let row = time.partition_point(|t| *t <= target).saturating_sub(1);
        Some(
            self.columns
                .iter()
                .map(|&c| self.recording.column_at(c)[row])
                .collect(),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::compensation::CompensationId;
    use crate::signal::AxisId;

    struct Constant;
    impl SampleSource for Constant {
        fn sample(&mut self, _: Duration) -> Option<Vec<f64>> {
            Some(vec![1.0; map::sample_columns().len() - 1])
        }
    }

    fn state() -> ControllerState {
        ControllerState {
            source: Box::new(Constant),
            started: Instant::now(),
            sequence: 0,
            holding: vec![0; holding_len()],
            commits: 0,
        }
    }

    fn table(backlash_x: f64) -> Vec<u16> {
        let mut values: CompensationValues = map::compensation_ids()
            .iter()
            .map(|id| (*id, 0.0))
            .collect();
        values.set(CompensationId::Backlash(AxisId::X), backlash_x);
        map::encode_compensation(&values).unwrap()
    }

    #[test]
    fn stage_then_commit_applies_only_a_matching_checksum_within_hard_limits() {
        let mut s = state();
        let staged = table(12.5);
        s.write_holding(map::STAGED_VALUES_START, &staged).unwrap();
        // Wrong checksum: nothing applied.
        s.write_holding(map::STAGED_CHECKSUM_REGISTER, &[0x1234, 1])
            .unwrap();
        let handshake = s
            .read_holding(map::COMMIT_STATUS_REGISTER, map::HANDSHAKE_LEN)
            .unwrap();
        assert_eq!(handshake[0], CommitStatus::RejectedChecksum.code());
        assert_eq!(handshake[3], 1);
        let applied = s
            .read_holding(map::APPLIED_VALUES_START, map::compensation_table_len())
            .unwrap();
        assert!(applied.iter().all(|r| *r == 0));
        // Right checksum: applied and echoed.
        s.write_holding(
            map::STAGED_CHECKSUM_REGISTER,
            &[map::staging_checksum(&staged), 2],
        )
        .unwrap();
        let handshake = s
            .read_holding(map::COMMIT_STATUS_REGISTER, map::HANDSHAKE_LEN)
            .unwrap();
        assert_eq!(handshake[0], CommitStatus::Applied.code());
        assert_eq!(map::join_words(handshake[1], handshake[2]), 1);
        let applied = s
            .read_holding(map::APPLIED_VALUES_START, map::compensation_table_len())
            .unwrap();
        assert_eq!(applied, staged);
        // Beyond the controller's hard limit: rejected.
        let wild = table(CONTROLLER_HARD_LIMIT_UM + 1.0);
        s.write_holding(map::STAGED_VALUES_START, &wild).unwrap();
        s.write_holding(
            map::STAGED_CHECKSUM_REGISTER,
            &[map::staging_checksum(&wild), 3],
        )
        .unwrap();
        assert_eq!(
            s.read_holding(map::COMMIT_STATUS_REGISTER, 1).unwrap()[0],
            CommitStatus::RejectedLimits.code()
        );
    }

    #[test]
    fn only_staging_and_commit_registers_take_writes_and_samples_are_read_whole() {
        let mut s = state();
        for address in [
            map::COMMIT_STATUS_REGISTER,
            map::APPLIED_VALUES_START,
            999,
            2000,
        ] {
            assert_eq!(
                s.write_holding(address, &[1]),
                Err(ExceptionCode::IllegalDataAddress),
                "{address}"
            );
        }
        assert!(s.read_samples(1, 10).is_err());
        let first = s.read_samples(0, map::SAMPLE_BLOCK_LEN).unwrap();
        let second = s.read_samples(0, map::SAMPLE_BLOCK_LEN).unwrap();
        assert_eq!(map::decode_sample(&first).unwrap().sequence, 1);
        assert_eq!(map::decode_sample(&second).unwrap().sequence, 2);
    }

    fn recording_with(columns: &[String]) -> crate::signal::Recording {
        let mut recording = crate::signal::Recording::new("source.csv", columns.to_vec()).unwrap();
        for i in 0..10 {
            let row: Vec<f64> = columns
                .iter()
                .map(|name| match name.as_str() {
                    "time_s" => f64::from(i),
                    "coolant_on" => 1.0,
                    crate::signal::channel::CUT_DEPTH => {
                        if i >= 5 {
                            1.5
                        } else {
                            0.0
                        }
                    }
                    _ => 20.0,
                })
                .collect();
            recording.push_row(&row).unwrap();
        }
        recording
    }

    #[test]
    fn a_recording_is_served_with_its_depth_of_cut_and_refused_without_one() {
        use crate::signal::channel::CUT_DEPTH;
        let columns = map::sample_columns();
        let depth = columns.iter().position(|c| c == CUT_DEPTH).unwrap() - 1;
        let mut source = RecordingSource::new(recording_with(&columns), 1.0).unwrap();
        assert_eq!(source.sample(Duration::from_secs(1)).unwrap()[depth], 0.0);
        assert_eq!(source.sample(Duration::from_secs(6)).unwrap()[depth], 1.5);

        // Without the column nothing is invented: serving is refused, and the message says
        // why and what to do instead.
        let without: Vec<String> = columns.into_iter().filter(|c| c != CUT_DEPTH).collect();
        let Err(err) = RecordingSource::new(recording_with(&without), 1.0) else {
            panic!("a recording without {CUT_DEPTH} was served");
        };
        let message = err.to_string();
        assert!(message.contains("no column `cut_depth_mm`"), "{message}");
        assert!(message.contains("servosight --replay"), "{message}");
    }

    #[test]
    fn the_twin_source_publishes_the_twins_depth_of_cut() {
        use crate::signal::channel::CUT_DEPTH;
        let config = crate::sim::TwinConfig::new(crate::sim::ScenarioKind::Production, None, 3);
        let twin = crate::sim::Twin::new(config).unwrap();
        let mut source = TwinSource::new(twin, 1.0).unwrap();
        let depth = map::sample_columns()
            .iter()
            .position(|c| c == CUT_DEPTH)
            .unwrap()
            - 1;
        // One simulated hour in 10 s steps: the production program cuts (roughing and
        // finishing, 0.2 to 4 mm) and also runs without cutting.
        let depths: Vec<f64> = (1..=360)
            .map(|k| source.sample(Duration::from_secs(10 * k)).unwrap()[depth])
            .collect();
        assert!(depths.contains(&0.0), "never out of the cut");
        assert!(
            depths.iter().any(|d| (0.2..=4.0).contains(d)),
            "never cutting: {depths:?}"
        );
        assert!(depths.iter().all(|d| *d == 0.0 || (0.2..=4.0).contains(d)));
        // And every sample fits the map: encodes and decodes to the same depth (1 µm).
        let values = source.sample(Duration::from_secs(3600)).unwrap();
        let registers = map::encode_sample(&DecodedSample {
            sequence: 1,
            clock_ms: 0,
            values: values.clone(),
        })
        .unwrap();
        let back = map::decode_sample(&registers).unwrap();
        assert!((back.values[depth] - values[depth]).abs() <= 0.0005);
    }
}

/// Serves the physics twin in real time (or faster): the sample at the elapsed time, with the
/// X backlash compensation the controller applied fed back into the twin.
///
/// The twin models the spindle `S` and the feed axis `X`. The map also publishes `Z`; this
/// source reports it as an axis at rest (no motion, no torque or current, stator at room
/// temperature) and says so in [`TwinSource::AT_REST_AXES`], rather than inventing a model of
/// an axis the twin does not have. The spindle runs in speed control and has no position
/// command; its `S.command_deg` is published equal to `S.position_deg` (no following error).
/// The depth of cut is the twin's own `cut_depth_mm`: the programmed depth while the tool is
/// in the cut, 0 otherwise, exactly what a controller knows from its NC program.
pub struct TwinSource {
    twin: crate::sim::Twin,
    /// For each map column (without `time_s`): where the twin has it, or how to stand in.
    columns: Vec<TwinColumn>,
    speed: f64,
    row: Vec<f64>,
    last: Option<Vec<f64>>,
}

#[derive(Debug, Clone, Copy)]
enum TwinColumn {
    Twin(usize),
    /// A command the twin does not produce: the position it would command.
    CommandFollows(usize),
    AtRest,
    AtRoomTemperature,
}

impl TwinSource {
    /// Axes of the map the twin does not model, published at rest.
    pub const AT_REST_AXES: [crate::signal::AxisId; 1] = [crate::signal::AxisId::Z];

    /// Wraps a twin; `speed` is simulated seconds per wall-clock second.
    pub fn new(
        twin: crate::sim::Twin,
        speed: f64,
    ) -> Result<TwinSource, crate::signal::RecordingError> {
        use crate::signal::{Channel, Quantity};
        let schema = twin.schema().clone();
        let mut columns = Vec::new();
        for name in &map::sample_columns()[1..] {
            let missing = || crate::signal::RecordingError::MissingColumn {
                source_name: "twin".into(),
                name: name.clone(),
                needed_for: Some("serving the register map".into()),
            };
            let column = match (schema.index_of(name), Channel::parse(name)) {
                (Some(index), _) => TwinColumn::Twin(index),
                (None, Channel::Servo { axis, quantity }) if Self::AT_REST_AXES.contains(&axis) => {
                    if quantity == Quantity::StatorTemp {
                        TwinColumn::AtRoomTemperature
                    } else {
                        TwinColumn::AtRest
                    }
                }
                (
                    None,
                    Channel::Servo {
                        axis,
                        quantity: Quantity::Command,
                    },
                ) => schema
                    .index_of(&crate::signal::axis_column(axis, Quantity::Position))
                    .map(TwinColumn::CommandFollows)
                    .ok_or_else(missing)?,
                (None, _) => return Err(missing()),
            };
            columns.push(column);
        }
        if schema.index_of(crate::signal::channel::AMBIENT).is_none() {
            return Err(crate::signal::RecordingError::MissingColumn {
                source_name: "twin".into(),
                name: crate::signal::channel::AMBIENT.into(),
                needed_for: Some("the stator temperature of an axis at rest".into()),
            });
        }
        Ok(TwinSource {
            twin,
            columns,
            speed: speed.max(1e-6),
            row: Vec::new(),
            last: None,
        })
    }
}

impl SampleSource for TwinSource {
    fn sample(&mut self, elapsed: Duration) -> Option<Vec<f64>> {
        let target_s = elapsed.as_secs_f64() * self.speed;
        while self.last.is_none() || self.twin.time_s() <= target_s {
            if !self.twin.next_row(&mut self.row) {
                break;
            }
            self.last = Some(self.row.clone());
        }
        let row = self.last.as_ref()?;
        let ambient = row[self
            .twin
            .schema()
            .index_of(crate::signal::channel::AMBIENT)?];
        Some(
            self.columns
                .iter()
                .map(|column| match column {
                    TwinColumn::Twin(index) | TwinColumn::CommandFollows(index) => row[*index],
                    TwinColumn::AtRest => 0.0,
                    TwinColumn::AtRoomTemperature => ambient,
                })
                .collect(),
        )
    }

    fn compensation_applied(&mut self, table: &CompensationValues) {
        use crate::compensation::CompensationId;
        if let Some(backlash) = table.get(CompensationId::Backlash(crate::signal::AxisId::X)) {
            self.twin.set_backlash_compensation_um(backlash);
        }
    }
}
