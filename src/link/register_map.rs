//! The Modbus register map servosight speaks: the one definition that the RTU client, the
//! `sim-controller` and (through [`describe`] as JSON) the independent test peer all use.
//!
//! `docs/register-map.md` shows the same tables; a test checks that the document contains
//! exactly what [`markdown_tables`] prints, so the document cannot drift from this module.
//!
//! Conventions: register addresses are 0-based protocol addresses (the number on the wire).
//! Signed values are two's complement. A 32-bit value occupies two consecutive registers with
//! the **high word first** (big-endian word order, "ABCD"): `value = (reg[a] << 16) | reg[a+1]`.
//! A physical value is `raw × scale`.

use crate::compensation::{CompensationId, CompensationValues};
use crate::signal::channel::{AMBIENT, COOLANT, CUT_DEPTH, TIME, plausible_range_of};
use crate::signal::{AxisId, Channel, Quantity, Schema, axis_column};

/// Version of this map; the controller reports it at [`MAP_VERSION_REGISTER`] and the client
/// refuses to read samples from a controller that reports another.
///
/// Version 2 added the depth of cut ([`CUT_DEPTH_REGISTER`]). That is a breaking change, not
/// an optional extra: a version-1 controller leaves register 7 reserved at 0, which reads as
/// "not cutting", and the motor abnormality score (which only judges steady non-cutting
/// running) would then score every cut's torque as excess friction: false alarms with no hint
/// of why. Accepting version 1 with the column left out is not possible either, because the
/// link's schema is fixed before the first reply arrives. So a version-1 controller is refused,
/// with a message naming both versions, rather than read with a silently wrong depth.
pub const MAP_VERSION: u16 = 2;

/// The axes the map publishes, in block order.
pub const MAPPED_AXES: [AxisId; 3] = [AxisId::X, AxisId::Z, AxisId::S];
/// The linear axes that carry backlash and straightness compensation.
pub const COMPENSATED_LINEAR_AXES: [AxisId; 2] = [AxisId::X, AxisId::Z];
/// Nodes of each straightness table, evenly spaced over the travel.
pub const STRAIGHTNESS_NODES: usize = 8;

// ---- input registers (function code 04) -------------------------------------------------

/// The sample block starts here; one read of the whole block is one sample.
pub const SAMPLE_BLOCK_START: u16 = 0;
/// Sequence counter, u32 (two registers). It counts published samples: the controller
/// increments it once per sample it publishes, so a step larger than one means samples were
/// lost between controller and client, and a step of zero means the client read the same
/// sample twice.
pub const SEQUENCE_REGISTER: u16 = 0;
/// Controller clock at the sample, u32 milliseconds (wraps after 49.7 days).
pub const CLOCK_MS_REGISTER: u16 = 2;
/// Room temperature, i16, 0.01 °C.
pub const AMBIENT_REGISTER: u16 = 4;
/// Coolant state, u16, 0 = off, 1 = on.
pub const COOLANT_REGISTER: u16 = 5;
/// Version of the register map the controller implements, u16, must equal [`MAP_VERSION`].
pub const MAP_VERSION_REGISTER: u16 = 6;
/// Depth of cut of the active NC block, u16, 0.001 mm; 0 outside cutting blocks (rapid moves,
/// idle, dwell, tool change). The controller knows it from the program, not from a sensor.
/// Registers 8..=15 are reserved and read as 0.
pub const CUT_DEPTH_REGISTER: u16 = 7;
/// First register of the first axis block.
pub const AXIS_BLOCKS_START: u16 = 16;
/// Registers per axis block (the tail of each block is reserved and reads as 0).
pub const AXIS_BLOCK_LEN: u16 = 16;
/// Registers in the whole sample block.
pub const SAMPLE_BLOCK_LEN: u16 = AXIS_BLOCKS_START + AXIS_BLOCK_LEN * MAPPED_AXES.len() as u16;

/// Counts per °C of the ambient temperature register.
pub const AMBIENT_COUNTS_PER_UNIT: f64 = 100.0;
/// Counts per mm of the depth-of-cut register. 1 µm resolution is finer than any programmed
/// depth; a u16 then spans 0 to 65.535 mm, well beyond the plausible range
/// ([`crate::signal::channel::CUT_DEPTH_PLAUSIBLE_RANGE_MM`], 0 to 50 mm), so the top of the register (0xFFFF, the
/// usual "no value" or a garbled word) is refused on decode rather than read as a cut.
pub const CUT_DEPTH_COUNTS_PER_MM: f64 = 1000.0;

/// How one value is stored in registers.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum RegisterType {
    /// One register, signed.
    I16,
    /// One register, unsigned.
    U16,
    /// Two registers, signed, high word first.
    I32,
    /// Two registers, unsigned, high word first.
    U32,
}

impl RegisterType {
    /// Registers the value occupies.
    pub fn words(self) -> u16 {
        match self {
            RegisterType::I16 | RegisterType::U16 => 1,
            RegisterType::I32 | RegisterType::U32 => 2,
        }
    }

    /// Reads the raw integer at `registers[0..words]`.
    fn read(self, registers: &[u16]) -> i64 {
        match self {
            RegisterType::I16 => i64::from(registers[0] as i16),
            RegisterType::U16 => i64::from(registers[0]),
            RegisterType::I32 => i64::from(join_words(registers[0], registers[1]) as i32),
            RegisterType::U32 => i64::from(join_words(registers[0], registers[1])),
        }
    }

    /// The raw integer range.
    fn raw_range(self) -> (i64, i64) {
        match self {
            RegisterType::I16 => (i64::from(i16::MIN), i64::from(i16::MAX)),
            RegisterType::U16 => (0, i64::from(u16::MAX)),
            RegisterType::I32 => (i64::from(i32::MIN), i64::from(i32::MAX)),
            RegisterType::U32 => (0, i64::from(u32::MAX)),
        }
    }

    /// Writes `raw` (already range-checked) to `out[0..words]`.
    fn write(self, raw: i64, out: &mut [u16]) {
        match self {
            RegisterType::I16 | RegisterType::U16 => out[0] = raw as u16,
            RegisterType::I32 | RegisterType::U32 => {
                let (high, low) = split_words(raw as u32);
                out[0] = high;
                out[1] = low;
            }
        }
    }
}

/// One servo quantity inside an axis block.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AxisField {
    /// The quantity.
    pub quantity: Quantity,
    /// Register offset inside the axis block.
    pub offset: u16,
    /// Storage type.
    pub register_type: RegisterType,
    /// Counts per physical unit (a power of ten): `value = raw / counts_per_unit`. Dividing by
    /// an exact integer gives the double nearest the decimal value (multiplying by 0.1 would
    /// not), so decoded values print as short as they were meant.
    pub counts_per_unit: f64,
}

/// The layout of every axis block.
pub const AXIS_FIELDS: [AxisField; 7] = [
    AxisField {
        quantity: Quantity::Position,
        offset: 0,
        register_type: RegisterType::I32,
        counts_per_unit: 1e4,
    },
    AxisField {
        quantity: Quantity::Command,
        offset: 2,
        register_type: RegisterType::I32,
        counts_per_unit: 1e4,
    },
    AxisField {
        quantity: Quantity::Speed,
        offset: 4,
        register_type: RegisterType::I32,
        counts_per_unit: 100.0,
    },
    AxisField {
        quantity: Quantity::Torque,
        offset: 6,
        register_type: RegisterType::I32,
        counts_per_unit: 1000.0,
    },
    AxisField {
        quantity: Quantity::Current,
        offset: 8,
        register_type: RegisterType::I32,
        counts_per_unit: 1000.0,
    },
    AxisField {
        quantity: Quantity::Load,
        offset: 10,
        register_type: RegisterType::I16,
        counts_per_unit: 10.0,
    },
    AxisField {
        quantity: Quantity::StatorTemp,
        offset: 11,
        register_type: RegisterType::I16,
        counts_per_unit: 100.0,
    },
];

/// First register of `axis`'s block, `None` when the map does not publish that axis.
pub fn axis_block_start(axis: AxisId) -> Option<u16> {
    MAPPED_AXES
        .iter()
        .position(|a| *a == axis)
        .map(|i| AXIS_BLOCKS_START + AXIS_BLOCK_LEN * i as u16)
}

/// One machine-level value of the sample block (not an axis quantity).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MachineField {
    /// The recording column it decodes to.
    pub column: &'static str,
    /// Its register.
    pub register: u16,
    /// Storage type.
    pub register_type: RegisterType,
    /// Counts per physical unit, as in [`AxisField::counts_per_unit`].
    pub counts_per_unit: f64,
}

/// The machine-level values of the sample block, in [`sample_columns`] order (after the axes).
pub const MACHINE_FIELDS: [MachineField; 3] = [
    MachineField {
        column: AMBIENT,
        register: AMBIENT_REGISTER,
        register_type: RegisterType::I16,
        counts_per_unit: AMBIENT_COUNTS_PER_UNIT,
    },
    MachineField {
        column: COOLANT,
        register: COOLANT_REGISTER,
        register_type: RegisterType::U16,
        counts_per_unit: 1.0,
    },
    MachineField {
        column: CUT_DEPTH,
        register: CUT_DEPTH_REGISTER,
        register_type: RegisterType::U16,
        counts_per_unit: CUT_DEPTH_COUNTS_PER_MM,
    },
];

// ---- holding registers (function codes 03 read, 16 write) -------------------------------

/// Commit status, u16, written by the controller: see [`CommitStatus`].
pub const COMMIT_STATUS_REGISTER: u16 = 1000;
/// Applied generation, u32, incremented by the controller on every successful commit.
pub const APPLIED_GENERATION_REGISTER: u16 = 1001;
/// The commit token of the last commit the controller processed (applied or rejected).
pub const LAST_COMMIT_TOKEN_REGISTER: u16 = 1003;
/// CRC-16/MODBUS of the staged value registers, written by the client together with the token.
pub const STAGED_CHECKSUM_REGISTER: u16 = 1004;
/// Commit token, written by the client right after the checksum in one write of two
/// registers; the write is the commit request. Any non-zero value different from the last one.
pub const COMMIT_TOKEN_REGISTER: u16 = 1005;
/// Registers of the handshake block that the client reads back: 1000..=1005.
pub const HANDSHAKE_LEN: u16 = 6;
/// First staged value register; the client writes the whole table here.
pub const STAGED_VALUES_START: u16 = 1010;
/// First applied value register: the controller's echo of what it is using now.
pub const APPLIED_VALUES_START: u16 = 1110;
/// Storage of every compensation value: i32, high word first.
pub const COMPENSATION_REGISTER_TYPE: RegisterType = RegisterType::I32;
/// Counts per micrometre of every compensation value (0.1 µm resolution).
pub const COMPENSATION_COUNTS_PER_UM: f64 = 10.0;

/// What the controller reports in [`COMMIT_STATUS_REGISTER`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum CommitStatus {
    /// No commit since power-up.
    Idle,
    /// The staged table was copied to the applied table.
    Applied,
    /// The staged registers did not match the checksum: nothing applied.
    RejectedChecksum,
    /// A staged value is outside the controller's own hard limits: nothing applied.
    RejectedLimits,
    /// A code this map does not define.
    Unknown(u16),
}

impl CommitStatus {
    /// The register value.
    pub fn code(self) -> u16 {
        match self {
            CommitStatus::Idle => 0,
            CommitStatus::Applied => 1,
            CommitStatus::RejectedChecksum => 2,
            CommitStatus::RejectedLimits => 3,
            CommitStatus::Unknown(code) => code,
        }
    }

    /// Decodes the register value.
    pub fn from_code(code: u16) -> CommitStatus {
        match code {
            0 => CommitStatus::Idle,
            1 => CommitStatus::Applied,
            2 => CommitStatus::RejectedChecksum,
            3 => CommitStatus::RejectedLimits,
            other => CommitStatus::Unknown(other),
        }
    }
}

/// Every compensation value in table order: value `i` is at `STAGED_VALUES_START + 2 i` and
/// echoed at `APPLIED_VALUES_START + 2 i`.
pub fn compensation_ids() -> Vec<CompensationId> {
    let mut ids = Vec::new();
    ids.extend(
        COMPENSATED_LINEAR_AXES
            .iter()
            .map(|a| CompensationId::Backlash(*a)),
    );
    ids.extend(
        MAPPED_AXES
            .iter()
            .map(|a| CompensationId::ThermalOffset(*a)),
    );
    for axis in COMPENSATED_LINEAR_AXES {
        ids.extend((0..STRAIGHTNESS_NODES).map(|node| CompensationId::Straightness { axis, node }));
    }
    ids
}

/// Registers of the whole compensation table (staged or applied).
pub fn compensation_table_len() -> u16 {
    compensation_ids().len() as u16 * COMPENSATION_REGISTER_TYPE.words()
}

/// Errors of encoding and decoding register contents.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MapError {
    /// Fewer registers than the block needs.
    #[error("expected {expected} registers, got {found}")]
    WrongLength {
        /// Registers the block has.
        expected: usize,
        /// Registers supplied.
        found: usize,
    },
    /// The controller implements another version of the map.
    #[error("the controller reports register map version {found}, servosight speaks {MAP_VERSION}")]
    VersionMismatch {
        /// The version the controller reported.
        found: u16,
    },
    /// A decoded value lies outside its channel's plausible range: a garbled register.
    #[error(
        "register {register} ({column}): {value} is outside its plausible range {low} to {high}"
    )]
    Implausible {
        /// The first register of the value.
        register: u16,
        /// The column it decodes to.
        column: String,
        /// The decoded value.
        value: f64,
        /// Lower end of the plausible range.
        low: f64,
        /// Upper end of the plausible range.
        high: f64,
    },
    /// A value does not fit its registers.
    #[error("{name} = {value} does not fit in {register_type:?} registers at scale {scale}")]
    OutOfRegisterRange {
        /// What was being encoded.
        name: String,
        /// Its value.
        value: f64,
        /// The storage type.
        register_type: RegisterType,
        /// The scale.
        scale: f64,
    },
    /// A compensation value the table does not hold, or a missing one.
    #[error("compensation table: {0}")]
    Table(String),
}

/// Joins a high and a low word.
pub fn join_words(high: u16, low: u16) -> u32 {
    (u32::from(high) << 16) | u32::from(low)
}

/// Splits a 32-bit value into (high, low) words.
pub fn split_words(value: u32) -> (u16, u16) {
    ((value >> 16) as u16, value as u16)
}

/// Converts a physical value to its raw integer, refusing values that do not fit.
fn to_raw(
    name: &str,
    value: f64,
    register_type: RegisterType,
    counts_per_unit: f64,
) -> Result<i64, MapError> {
    let raw = (value * counts_per_unit).round();
    let (low, high) = register_type.raw_range();
    if !raw.is_finite() || raw < low as f64 || raw > high as f64 {
        return Err(MapError::OutOfRegisterRange {
            name: name.to_string(),
            value,
            register_type,
            scale: 1.0 / counts_per_unit,
        });
    }
    Ok(raw as i64)
}

/// The columns a sample decodes to, `time_s` first: every quantity of every mapped axis, then
/// the machine-level values ([`MACHINE_FIELDS`]: ambient, coolant, depth of cut). `time_s` is
/// the client's receive time (see [`super::Frame`]).
pub fn sample_columns() -> Vec<String> {
    let mut names = vec![TIME.to_string()];
    for axis in MAPPED_AXES {
        names.extend(AXIS_FIELDS.iter().map(|f| axis_column(axis, f.quantity)));
    }
    names.extend(MACHINE_FIELDS.iter().map(|f| f.column.to_string()));
    names
}

/// The schema of [`sample_columns`].
pub fn sample_schema() -> Schema {
    // The names come from the channel module and are unique by construction, so building the
    // schema cannot fail; a failure would be a bug in this module, caught by its tests.
    Schema::new(sample_columns(), "register map").expect("register map columns form a schema")
}

/// One sample as read from the sample block.
#[derive(Debug, Clone, PartialEq)]
pub struct DecodedSample {
    /// The controller's sequence counter.
    pub sequence: u32,
    /// The controller's clock, ms.
    pub clock_ms: u32,
    /// The values of [`sample_columns`] without `time_s` (in the same order).
    pub values: Vec<f64>,
}

/// Decodes the sample block (`SAMPLE_BLOCK_LEN` registers from `SAMPLE_BLOCK_START`).
///
/// Every value is checked against its channel's plausible range: a value outside it is a
/// garbled register, and the whole sample is refused rather than recorded.
pub fn decode_sample(registers: &[u16]) -> Result<DecodedSample, MapError> {
    if registers.len() != usize::from(SAMPLE_BLOCK_LEN) {
        return Err(MapError::WrongLength {
            expected: usize::from(SAMPLE_BLOCK_LEN),
            found: registers.len(),
        });
    }
    let at = |register: u16| &registers[usize::from(register - SAMPLE_BLOCK_START)..];
    let version = registers[usize::from(MAP_VERSION_REGISTER)];
    if version != MAP_VERSION {
        return Err(MapError::VersionMismatch { found: version });
    }
    let sequence = RegisterType::U32.read(at(SEQUENCE_REGISTER)) as u32;
    let clock_ms = RegisterType::U32.read(at(CLOCK_MS_REGISTER)) as u32;
    let mut values =
        Vec::with_capacity(MAPPED_AXES.len() * AXIS_FIELDS.len() + MACHINE_FIELDS.len());
    let columns = sample_columns();
    let check = |register: u16, value: f64, index: usize| -> Result<f64, MapError> {
        let column = &columns[index + 1];
        match plausible_range_of(column) {
            Some((low, high)) if !(low..=high).contains(&value) => Err(MapError::Implausible {
                register,
                column: column.clone(),
                value,
                low,
                high,
            }),
            _ => Ok(value),
        }
    };
    for axis in MAPPED_AXES {
        let base = axis_block_start(axis).unwrap_or(AXIS_BLOCKS_START);
        for field in AXIS_FIELDS {
            let register = base + field.offset;
            let value = field.register_type.read(at(register)) as f64 / field.counts_per_unit;
            let value = check(register, value, values.len())?;
            values.push(value);
        }
    }
    for field in MACHINE_FIELDS {
        let value = field.register_type.read(at(field.register)) as f64 / field.counts_per_unit;
        let value = check(field.register, value, values.len())?;
        values.push(value);
    }
    Ok(DecodedSample {
        sequence,
        clock_ms,
        values,
    })
}

/// Encodes a sample into the sample block: the controller side (the `sim-controller`).
/// `values` are in [`sample_columns`] order without `time_s`.
pub fn encode_sample(sample: &DecodedSample) -> Result<Vec<u16>, MapError> {
    let columns = sample_columns();
    let expected = columns.len() - 1;
    if sample.values.len() != expected {
        return Err(MapError::WrongLength {
            expected,
            found: sample.values.len(),
        });
    }
    let mut registers = vec![0u16; usize::from(SAMPLE_BLOCK_LEN)];
    RegisterType::U32.write(
        i64::from(sample.sequence),
        &mut registers[usize::from(SEQUENCE_REGISTER)..],
    );
    RegisterType::U32.write(
        i64::from(sample.clock_ms),
        &mut registers[usize::from(CLOCK_MS_REGISTER)..],
    );
    registers[usize::from(MAP_VERSION_REGISTER)] = MAP_VERSION;
    let mut next = sample.values.iter().zip(&columns[1..]);
    for axis in MAPPED_AXES {
        let base = axis_block_start(axis).unwrap_or(AXIS_BLOCKS_START);
        for field in AXIS_FIELDS {
            let Some((value, name)) = next.next() else {
                break;
            };
            let raw = to_raw(name, *value, field.register_type, field.counts_per_unit)?;
            field
                .register_type
                .write(raw, &mut registers[usize::from(base + field.offset)..]);
        }
    }
    for field in MACHINE_FIELDS {
        let Some((value, name)) = next.next() else {
            break;
        };
        let raw = to_raw(name, *value, field.register_type, field.counts_per_unit)?;
        field
            .register_type
            .write(raw, &mut registers[usize::from(field.register)..]);
    }
    Ok(registers)
}

/// Rounds a compensation value to what the registers can hold (0.1 µm), so what is written
/// and what is read back compare exactly.
pub fn quantise_um(micrometres: f64) -> f64 {
    (micrometres * COMPENSATION_COUNTS_PER_UM).round() / COMPENSATION_COUNTS_PER_UM
}

/// Encodes a complete compensation table (every id of [`compensation_ids`]).
pub fn encode_compensation(values: &CompensationValues) -> Result<Vec<u16>, MapError> {
    let ids = compensation_ids();
    if let Some((extra, _)) = values.iter().find(|(id, _)| !ids.contains(id)) {
        return Err(MapError::Table(format!(
            "the controller has no register for {extra}"
        )));
    }
    let words = usize::from(COMPENSATION_REGISTER_TYPE.words());
    let mut registers = vec![0u16; ids.len() * words];
    for (i, id) in ids.iter().enumerate() {
        let value = values
            .get(*id)
            .ok_or_else(|| MapError::Table(format!("no value for {id}")))?;
        let raw = to_raw(
            &id.to_string(),
            value,
            COMPENSATION_REGISTER_TYPE,
            COMPENSATION_COUNTS_PER_UM,
        )?;
        COMPENSATION_REGISTER_TYPE.write(raw, &mut registers[i * words..]);
    }
    Ok(registers)
}

/// Decodes a compensation table (staged or applied).
pub fn decode_compensation(registers: &[u16]) -> Result<CompensationValues, MapError> {
    let ids = compensation_ids();
    let words = usize::from(COMPENSATION_REGISTER_TYPE.words());
    if registers.len() != ids.len() * words {
        return Err(MapError::WrongLength {
            expected: ids.len() * words,
            found: registers.len(),
        });
    }
    Ok(ids
        .iter()
        .enumerate()
        .map(|(i, id)| {
            let raw = COMPENSATION_REGISTER_TYPE.read(&registers[i * words..]);
            (*id, raw as f64 / COMPENSATION_COUNTS_PER_UM)
        })
        .collect())
}

/// CRC-16/MODBUS (poly 0xA001 reflected, init 0xFFFF) over the registers as big-endian bytes:
/// the checksum the client writes to [`STAGED_CHECKSUM_REGISTER`].
pub fn staging_checksum(registers: &[u16]) -> u16 {
    let bytes: Vec<u8> = registers.iter().flat_map(|r| r.to_be_bytes()).collect();
    super::modbus::crc16_modbus(&bytes)
}

/// The map as data, for the JSON that test peers and outside tools read.
#[derive(Debug, Clone, serde::Serialize)]
pub struct MapDescription {
    /// [`MAP_VERSION`].
    pub version: u16,
    /// Word order of 32-bit values.
    pub word_order: &'static str,
    /// The sample block (input registers).
    pub sample_block: BlockDescription,
    /// Machine-level input registers.
    pub machine: Vec<FieldDescription>,
    /// Axis blocks.
    pub axes: Vec<AxisDescription>,
    /// The compensation handshake (holding registers).
    pub handshake: HandshakeDescription,
    /// The compensation table in register order.
    pub compensation: Vec<CompensationDescription>,
}

/// A contiguous block.
#[derive(Debug, Clone, serde::Serialize)]
pub struct BlockDescription {
    /// First register.
    pub start: u16,
    /// Registers.
    pub len: u16,
}

/// One value.
#[derive(Debug, Clone, serde::Serialize)]
pub struct FieldDescription {
    /// What it is (a recording column, or a register role).
    pub name: String,
    /// First register.
    pub address: u16,
    /// Storage type.
    #[serde(rename = "type")]
    pub register_type: RegisterType,
    /// Units per count.
    pub scale: f64,
    /// Unit of the scaled value.
    pub unit: &'static str,
}

/// One axis block.
#[derive(Debug, Clone, serde::Serialize)]
pub struct AxisDescription {
    /// The axis id.
    pub axis: AxisId,
    /// First register of the block.
    pub start: u16,
    /// Its fields with absolute addresses.
    pub fields: Vec<FieldDescription>,
}

/// The handshake registers.
#[derive(Debug, Clone, serde::Serialize)]
pub struct HandshakeDescription {
    /// [`COMMIT_STATUS_REGISTER`].
    pub status: u16,
    /// Status codes by name.
    pub status_codes: Vec<(&'static str, u16)>,
    /// [`APPLIED_GENERATION_REGISTER`].
    pub applied_generation: u16,
    /// [`LAST_COMMIT_TOKEN_REGISTER`].
    pub last_commit_token: u16,
    /// [`STAGED_CHECKSUM_REGISTER`].
    pub staged_checksum: u16,
    /// [`COMMIT_TOKEN_REGISTER`].
    pub commit_token: u16,
    /// [`STAGED_VALUES_START`].
    pub staged_values_start: u16,
    /// [`APPLIED_VALUES_START`].
    pub applied_values_start: u16,
    /// Registers of either table.
    pub table_len: u16,
}

/// One compensation value.
#[derive(Debug, Clone, serde::Serialize)]
pub struct CompensationDescription {
    /// Its id, e.g. `backlash.X`.
    pub id: String,
    /// Staged register (first of two).
    pub staged: u16,
    /// Applied echo register (first of two).
    pub applied: u16,
    /// Storage type.
    #[serde(rename = "type")]
    pub register_type: RegisterType,
    /// µm per count.
    pub scale: f64,
}

/// The whole map as data.
pub fn describe() -> MapDescription {
    let unit = |name: &str| Channel::unit_of(name).unwrap_or("");
    let mut machine = vec![
        FieldDescription {
            name: "sequence".into(),
            address: SEQUENCE_REGISTER,
            register_type: RegisterType::U32,
            scale: 1.0,
            unit: "count",
        },
        FieldDescription {
            name: "clock_ms".into(),
            address: CLOCK_MS_REGISTER,
            register_type: RegisterType::U32,
            scale: 1.0,
            unit: "ms",
        },
        FieldDescription {
            name: "map_version".into(),
            address: MAP_VERSION_REGISTER,
            register_type: RegisterType::U16,
            scale: 1.0,
            unit: "",
        },
    ];
    machine.extend(MACHINE_FIELDS.iter().map(|f| FieldDescription {
        name: f.column.into(),
        address: f.register,
        register_type: f.register_type,
        scale: 1.0 / f.counts_per_unit,
        unit: unit(f.column),
    }));
    // In address order, as a reader of the table expects.
    machine.sort_by_key(|f| f.address);
    let axes = MAPPED_AXES
        .iter()
        .map(|&axis| {
            let start = axis_block_start(axis).unwrap_or(AXIS_BLOCKS_START);
            AxisDescription {
                axis,
                start,
                fields: AXIS_FIELDS
                    .iter()
                    .map(|f| {
                        let name = axis_column(axis, f.quantity);
                        FieldDescription {
                            unit: unit(&name),
                            name,
                            address: start + f.offset,
                            register_type: f.register_type,
                            scale: 1.0 / f.counts_per_unit,
                        }
                    })
                    .collect(),
            }
        })
        .collect();
    let words = COMPENSATION_REGISTER_TYPE.words();
    let compensation = compensation_ids()
        .iter()
        .enumerate()
        .map(|(i, id)| CompensationDescription {
            id: id.to_string(),
            staged: STAGED_VALUES_START + words * i as u16,
            applied: APPLIED_VALUES_START + words * i as u16,
            register_type: COMPENSATION_REGISTER_TYPE,
            scale: 1.0 / COMPENSATION_COUNTS_PER_UM,
        })
        .collect();
    MapDescription {
        version: MAP_VERSION,
        word_order: "high word first",
        sample_block: BlockDescription {
            start: SAMPLE_BLOCK_START,
            len: SAMPLE_BLOCK_LEN,
        },
        machine,
        axes,
        handshake: HandshakeDescription {
            status: COMMIT_STATUS_REGISTER,
            status_codes: [
                CommitStatus::Idle,
                CommitStatus::Applied,
                CommitStatus::RejectedChecksum,
                CommitStatus::RejectedLimits,
            ]
            .iter()
            .map(|s| (status_name(*s), s.code()))
            .collect(),
            applied_generation: APPLIED_GENERATION_REGISTER,
            last_commit_token: LAST_COMMIT_TOKEN_REGISTER,
            staged_checksum: STAGED_CHECKSUM_REGISTER,
            commit_token: COMMIT_TOKEN_REGISTER,
            staged_values_start: STAGED_VALUES_START,
            applied_values_start: APPLIED_VALUES_START,
            table_len: compensation_table_len(),
        },
        compensation,
    }
}

fn status_name(status: CommitStatus) -> &'static str {
    match status {
        CommitStatus::Idle => "idle",
        CommitStatus::Applied => "applied",
        CommitStatus::RejectedChecksum => "rejected_checksum",
        CommitStatus::RejectedLimits => "rejected_limits",
        CommitStatus::Unknown(_) => "unknown",
    }
}

fn type_name(register_type: RegisterType) -> &'static str {
    match register_type {
        RegisterType::I16 => "i16",
        RegisterType::U16 => "u16",
        RegisterType::I32 => "i32 (2 regs)",
        RegisterType::U32 => "u32 (2 regs)",
    }
}

/// The register tables as Markdown, exactly as `docs/register-map.md` shows them.
pub fn markdown_tables() -> String {
    let map = describe();
    let mut out = String::new();
    out.push_str("### Input registers (function code 04): the sample block\n\n");
    out.push_str(&format!(
        "One read of registers {}..{} (inclusive, {} registers) is one sample.\n\n",
        map.sample_block.start,
        map.sample_block.start + map.sample_block.len - 1,
        map.sample_block.len
    ));
    out.push_str("| address | name | type | scale | unit |\n|---|---|---|---|---|\n");
    let row = |out: &mut String, f: &FieldDescription| {
        out.push_str(&format!(
            "| {} | `{}` | {} | {} | {} |\n",
            f.address,
            f.name,
            type_name(f.register_type),
            f.scale,
            f.unit
        ));
    };
    for field in &map.machine {
        row(&mut out, field);
    }
    for axis in &map.axes {
        for field in &axis.fields {
            row(&mut out, field);
        }
    }
    out.push_str("\n### Holding registers (function codes 03 read, 16 write): compensation\n\n");
    out.push_str("| address | name | written by | type |\n|---|---|---|---|\n");
    let h = &map.handshake;
    for (address, name, by, register_type) in [
        (h.status, "commit_status", "controller", RegisterType::U16),
        (
            h.applied_generation,
            "applied_generation",
            "controller",
            RegisterType::U32,
        ),
        (
            h.last_commit_token,
            "last_commit_token",
            "controller",
            RegisterType::U16,
        ),
        (
            h.staged_checksum,
            "staged_checksum",
            "client",
            RegisterType::U16,
        ),
        (h.commit_token, "commit_token", "client", RegisterType::U16),
    ] {
        out.push_str(&format!(
            "| {address} | `{name}` | {by} | {} |\n",
            type_name(register_type)
        ));
    }
    out.push_str("\nCommit status codes: ");
    let codes: Vec<String> = h
        .status_codes
        .iter()
        .map(|(name, code)| format!("{code} = `{name}`"))
        .collect();
    out.push_str(&codes.join(", "));
    out.push_str(".\n\n### Compensation table (µm, i32, 2 registers each, high word first)\n\n");
    out.push_str(&format!(
        "Scale {} µm per count. Staged table {}..{} (written by the client), applied echo {}..{} \
         (written by the controller).\n\n",
        1.0 / COMPENSATION_COUNTS_PER_UM,
        h.staged_values_start,
        h.staged_values_start + h.table_len - 1,
        h.applied_values_start,
        h.applied_values_start + h.table_len - 1
    ));
    out.push_str("| value | staged | applied echo |\n|---|---|---|\n");
    for c in &map.compensation {
        out.push_str(&format!("| `{}` | {} | {} |\n", c.id, c.staged, c.applied));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::signal::channel::CUT_DEPTH_PLAUSIBLE_RANGE_MM;

    fn sample_values() -> Vec<f64> {
        let columns = sample_columns();
        columns[1..]
            .iter()
            .enumerate()
            .map(|(i, name)| match Channel::parse(name) {
                Channel::Unknown if name == CUT_DEPTH => 2.345,
                Channel::Coolant => 1.0,
                Channel::Ambient => 21.37,
                Channel::Servo { quantity, .. } => match quantity {
                    Quantity::Position | Quantity::Command => -123.4567 + i as f64,
                    Quantity::Speed => 2999.5,
                    Quantity::Torque => -12.345,
                    Quantity::Current => 4.321,
                    Quantity::Load => 55.5,
                    Quantity::StatorTemp => 41.23,
                },
                _ => 0.0,
            })
            .collect()
    }

    #[test]
    fn sample_block_round_trips_and_fits_one_read() {
        const { assert!(SAMPLE_BLOCK_LEN <= 125, "one FC04 read holds at most 125") };
        let sample = DecodedSample {
            sequence: 0x0001_0002,
            clock_ms: 123_456_789,
            values: sample_values(),
        };
        let registers = encode_sample(&sample).unwrap();
        assert_eq!(registers[0], 0x0001, "high word first");
        assert_eq!(registers[1], 0x0002);
        let back = decode_sample(&registers).unwrap();
        assert_eq!(back.sequence, sample.sequence);
        assert_eq!(back.clock_ms, sample.clock_ms);
        for ((a, b), name) in back
            .values
            .iter()
            .zip(&sample.values)
            .zip(&sample_columns()[1..])
        {
            assert!((a - b).abs() < 1e-9, "{name}: {a} vs {b}");
        }
    }

    #[test]
    fn garbled_or_foreign_samples_are_refused() {
        let sample = DecodedSample {
            sequence: 1,
            clock_ms: 0,
            values: sample_values(),
        };
        let mut registers = encode_sample(&sample).unwrap();
        registers[usize::from(MAP_VERSION_REGISTER)] = MAP_VERSION + 1;
        assert_eq!(
            decode_sample(&registers),
            Err(MapError::VersionMismatch {
                found: MAP_VERSION + 1
            })
        );
        registers[usize::from(MAP_VERSION_REGISTER)] = MAP_VERSION;
        // Stator temperature of X at 327 °C: beyond any working winding.
        let x_temp = AXIS_BLOCKS_START + 11;
        registers[usize::from(x_temp)] = 32_700;
        let err = decode_sample(&registers).unwrap_err();
        assert!(
            matches!(&err, MapError::Implausible { column, .. } if column == "X.stator_temp_C"),
            "{err}"
        );
        assert!(decode_sample(&registers[..10]).is_err());
    }

    #[test]
    fn the_depth_of_cut_sits_in_the_machine_header_at_one_micrometre() {
        let columns = sample_columns();
        let depth_index = columns.iter().position(|c| c == CUT_DEPTH).unwrap() - 1;
        let mut sample = DecodedSample {
            sequence: 1,
            clock_ms: 0,
            values: sample_values(),
        };
        let registers = encode_sample(&sample).unwrap();
        assert_eq!(registers[usize::from(CUT_DEPTH_REGISTER)], 2345);
        assert_eq!(
            decode_sample(&registers).unwrap().values[depth_index],
            2.345
        );
        // Outside cutting blocks the register reads 0, and 0 round-trips as "not cutting".
        sample.values[depth_index] = 0.0;
        let registers = encode_sample(&sample).unwrap();
        assert_eq!(registers[usize::from(CUT_DEPTH_REGISTER)], 0);
        assert_eq!(decode_sample(&registers).unwrap().values[depth_index], 0.0);
        // The top of the plausible range still fits the register, with margin.
        sample.values[depth_index] = CUT_DEPTH_PLAUSIBLE_RANGE_MM.1;
        let registers = encode_sample(&sample).unwrap();
        assert_eq!(
            decode_sample(&registers).unwrap().values[depth_index],
            CUT_DEPTH_PLAUSIBLE_RANGE_MM.1
        );
        // A negative depth has no register value: refused, not wrapped.
        sample.values[depth_index] = -0.5;
        assert!(matches!(
            encode_sample(&sample),
            Err(MapError::OutOfRegisterRange { name, .. }) if name == CUT_DEPTH
        ));
    }

    #[test]
    fn an_implausible_depth_of_cut_is_refused_naming_its_register() {
        let sample = DecodedSample {
            sequence: 1,
            clock_ms: 0,
            values: sample_values(),
        };
        let mut registers = encode_sample(&sample).unwrap();
        // 0xFFFF: a "no value" word or a garbled register, 65.535 mm if taken at face value.
        registers[usize::from(CUT_DEPTH_REGISTER)] = 0xFFFF;
        let err = decode_sample(&registers).unwrap_err();
        assert_eq!(
            err,
            MapError::Implausible {
                register: CUT_DEPTH_REGISTER,
                column: CUT_DEPTH.into(),
                value: 65.535,
                low: 0.0,
                high: 50.0,
            }
        );
        assert_eq!(
            err.to_string(),
            "register 7 (cut_depth_mm): 65.535 is outside its plausible range 0 to 50"
        );
        // Just past the range is refused too; just inside is not.
        registers[usize::from(CUT_DEPTH_REGISTER)] = 50_001;
        assert!(decode_sample(&registers).is_err());
        registers[usize::from(CUT_DEPTH_REGISTER)] = 50_000;
        assert!(decode_sample(&registers).is_ok());
    }

    #[test]
    fn a_version_1_controller_without_the_depth_of_cut_is_refused() {
        let sample = DecodedSample {
            sequence: 1,
            clock_ms: 0,
            values: sample_values(),
        };
        let mut registers = encode_sample(&sample).unwrap();
        // What a version-1 controller sends: register 7 reserved (0, which would read as
        // "not cutting") and version 1.
        registers[usize::from(CUT_DEPTH_REGISTER)] = 0;
        registers[usize::from(MAP_VERSION_REGISTER)] = 1;
        let err = decode_sample(&registers).unwrap_err();
        assert_eq!(err, MapError::VersionMismatch { found: 1 });
        assert_eq!(
            err.to_string(),
            "the controller reports register map version 1, servosight speaks 2"
        );
    }

    #[test]
    fn sample_fields_do_not_overlap_and_stay_in_the_block() {
        let map = describe();
        let mut used = vec![None::<String>; usize::from(SAMPLE_BLOCK_LEN)];
        let fields = map
            .machine
            .iter()
            .chain(map.axes.iter().flat_map(|a| a.fields.iter()));
        for field in fields {
            for word in 0..field.register_type.words() {
                let address = usize::from(field.address + word);
                assert!(address < used.len(), "{} outside the block", field.name);
                if let Some(other) = &used[address] {
                    panic!("{} and {other} share register {address}", field.name);
                }
                used[address] = Some(field.name.clone());
            }
        }
        // The machine header ends before the first axis block.
        assert!(
            map.machine
                .iter()
                .all(|f| f.address + f.register_type.words() <= AXIS_BLOCKS_START)
        );
        let depth = map.machine.iter().find(|f| f.name == CUT_DEPTH).unwrap();
        assert_eq!(
            (depth.address, depth.register_type, depth.scale, depth.unit),
            (CUT_DEPTH_REGISTER, RegisterType::U16, 0.001, "mm")
        );
        // Every column a sample decodes to is described, and nothing else.
        let mut described: Vec<&str> = map
            .machine
            .iter()
            .map(|f| f.name.as_str())
            .filter(|n| !["sequence", "clock_ms", "map_version"].contains(n))
            .chain(
                map.axes
                    .iter()
                    .flat_map(|a| a.fields.iter().map(|f| f.name.as_str())),
            )
            .collect();
        let columns = sample_columns();
        let mut expected: Vec<&str> = columns[1..].iter().map(String::as_str).collect();
        described.sort_unstable();
        expected.sort_unstable();
        assert_eq!(described, expected);
    }

    #[test]
    fn compensation_table_round_trips_and_checksums() {
        let ids = compensation_ids();
        assert_eq!(ids.len(), 2 + 3 + 2 * STRAIGHTNESS_NODES);
        assert!(
            compensation_table_len() <= 123,
            "one FC16 write holds at most 123"
        );
        assert!(STAGED_VALUES_START + compensation_table_len() <= APPLIED_VALUES_START);
        let values: CompensationValues = ids
            .iter()
            .enumerate()
            .map(|(i, id)| (*id, quantise_um(i as f64 * 1.37 - 9.0)))
            .collect();
        let registers = encode_compensation(&values).unwrap();
        assert_eq!(decode_compensation(&registers).unwrap(), values);
        // Registers 0x3132 0x3334 are the bytes "1234" on the wire.
        assert_eq!(
            staging_checksum(&[0x3132, 0x3334]),
            super::super::modbus::crc16_modbus(b"1234")
        );
        let mut incomplete = values.clone();
        incomplete = incomplete.restricted_to(&ids[1..]);
        assert!(encode_compensation(&incomplete).is_err());
    }

    #[test]
    fn out_of_range_values_are_refused_not_wrapped() {
        let mut values: CompensationValues =
            compensation_ids().iter().map(|id| (*id, 0.0)).collect();
        values.set(CompensationId::Backlash(AxisId::X), 1e12);
        assert!(matches!(
            encode_compensation(&values),
            Err(MapError::OutOfRegisterRange { .. })
        ));
    }
}

#[cfg(test)]
mod document_tests {
    #[test]
    fn the_document_shows_exactly_this_map() {
        let document = include_str!("../../docs/register-map.md");
        assert!(
            document.contains(&super::markdown_tables()),
            "docs/register-map.md is out of date: regenerate its tables with \
             `servosight register-map --markdown`"
        );
    }
}
