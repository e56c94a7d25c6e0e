//! Channel names of recording format v1 and what they mean.
//!
//! A column name says which axis it belongs to, what it measures and in which unit:
//! `X.torque_Nm`, `S.stator_temp_C`, `ambient_C`, `ref.X.straightness_h_um#3`. Code never spells
//! these strings by hand; it asks this module (`axis_column(AxisId::X, Quantity::Torque)`), so a
//! name is defined in exactly one place.

use std::fmt;
use std::str::FromStr;

/// The first column of every recording: seconds, non-decreasing.
pub const TIME: &str = "time_s";
/// Room temperature next to the machine, °C.
pub const AMBIENT: &str = "ambient_C";
/// Coolant (or oil chiller) state, 0 = off, 1 = on.
pub const COOLANT: &str = "coolant_on";
/// The programmed depth of cut while the tool is cutting, mm (0 otherwise). Not a servo signal:
/// the controller knows it from the NC program; depth-of-cut recommendations need it.
pub const CUT_DEPTH: &str = "cut_depth_mm";
/// The plausible range of [`CUT_DEPTH`], mm. The twin cuts 0.2 to 4 mm, heavy roughing on a
/// big lathe takes a few tens of mm at most; a depth outside this range is a garbled value,
/// not a cut. (The format keeps `cut_depth_mm` as a plain column, so
/// [`Channel::plausible_range`] does not know it; [`plausible_range_of`] does.)
pub const CUT_DEPTH_PLAUSIBLE_RANGE_MM: (f64, f64) = (0.0, 50.0);
/// Prefix of reference-instrument columns, used for calibration and validation only.
pub const REFERENCE_PREFIX: &str = "ref.";

/// An axis of the machine.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize, serde::Deserialize,
)]
pub enum AxisId {
    /// Linear feed axis X.
    X,
    /// Linear feed axis Y.
    Y,
    /// Linear feed axis Z.
    Z,
    /// The spindle.
    S,
    /// Rotary axis A.
    A,
    /// Rotary axis B.
    B,
    /// Rotary axis C.
    C,
}

impl AxisId {
    /// Every axis id in the order the format lists them.
    pub const ALL: [AxisId; 7] = [
        AxisId::X,
        AxisId::Y,
        AxisId::Z,
        AxisId::S,
        AxisId::A,
        AxisId::B,
        AxisId::C,
    ];

    /// Linear axes measure position in mm; the spindle and rotary axes in degrees.
    pub fn is_linear(self) -> bool {
        matches!(self, AxisId::X | AxisId::Y | AxisId::Z)
    }

    /// The one-letter id used in column names.
    pub fn as_str(self) -> &'static str {
        match self {
            AxisId::X => "X",
            AxisId::Y => "Y",
            AxisId::Z => "Z",
            AxisId::S => "S",
            AxisId::A => "A",
            AxisId::B => "B",
            AxisId::C => "C",
        }
    }
}

impl fmt::Display for AxisId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

impl FromStr for AxisId {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        AxisId::ALL
            .into_iter()
            .find(|a| a.as_str().eq_ignore_ascii_case(s))
            .ok_or_else(|| format!("unknown axis `{s}` (expected one of X, Y, Z, S, A, B, C)"))
    }
}

/// A servo quantity every axis reports.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub enum Quantity {
    /// Motor-encoder position: mm on linear axes, degrees on rotary ones.
    Position,
    /// Commanded position, same unit as `Position`.
    Command,
    /// Motor speed, rpm.
    Speed,
    /// Motor torque, N·m.
    Torque,
    /// Motor current, A.
    Current,
    /// Load as a percentage of the rated torque.
    Load,
    /// Stator winding temperature, °C.
    StatorTemp,
}

impl Quantity {
    /// Every servo quantity.
    pub const ALL: [Quantity; 7] = [
        Quantity::Position,
        Quantity::Command,
        Quantity::Speed,
        Quantity::Torque,
        Quantity::Current,
        Quantity::Load,
        Quantity::StatorTemp,
    ];

    /// The `<quantity>_<unit>` part of the column name on `axis`.
    pub fn column_suffix(self, axis: AxisId) -> &'static str {
        match (self, axis.is_linear()) {
            (Quantity::Position, true) => "position_mm",
            (Quantity::Position, false) => "position_deg",
            (Quantity::Command, true) => "command_mm",
            (Quantity::Command, false) => "command_deg",
            (Quantity::Speed, _) => "speed_rpm",
            (Quantity::Torque, _) => "torque_Nm",
            (Quantity::Current, _) => "current_A",
            (Quantity::Load, _) => "load_pct",
            (Quantity::StatorTemp, _) => "stator_temp_C",
        }
    }

    /// The physically plausible range of this quantity. A value outside it is a corrupt sample
    /// (a wrong scaling, a garbled register), not a machine state, and is rejected on read.
    pub fn plausible_range(self) -> (f64, f64) {
        match self {
            // Positions: ±100 m or ±10⁶ turns covers every machine; beyond is garbage.
            Quantity::Position | Quantity::Command => (-1.0e5, 1.0e5),
            Quantity::Speed => (-1.0e5, 1.0e5),
            Quantity::Torque => (-1.0e5, 1.0e5),
            Quantity::Current => (-1.0e4, 1.0e4),
            Quantity::Load => (-1000.0, 1000.0),
            // Below −50 °C or above 250 °C a winding sensor is broken or disconnected.
            Quantity::StatorTemp => (-50.0, 250.0),
        }
    }
}

/// The column holding `quantity` on `axis`, e.g. `X.torque_Nm`.
pub fn axis_column(axis: AxisId, quantity: Quantity) -> String {
    format!("{axis}.{}", quantity.column_suffix(axis))
}

/// A reference-instrument column, e.g. `reference_column(AxisId::X, "nut_temp_C", None)` is
/// `ref.X.nut_temp_C` and `reference_column(AxisId::X, "straightness_h_um", Some(3))` is
/// `ref.X.straightness_h_um#3`.
pub fn reference_column(axis: AxisId, quantity_with_unit: &str, node: Option<usize>) -> String {
    match node {
        Some(k) => format!("{REFERENCE_PREFIX}{axis}.{quantity_with_unit}#{k}"),
        None => format!("{REFERENCE_PREFIX}{axis}.{quantity_with_unit}"),
    }
}

/// What a column name means, as far as the format defines it.
#[derive(Debug, Clone, PartialEq)]
pub enum Channel {
    /// `time_s`.
    Time,
    /// A servo quantity of an axis.
    Servo {
        /// The axis.
        axis: AxisId,
        /// The quantity.
        quantity: Quantity,
    },
    /// `ambient_C`.
    Ambient,
    /// `coolant_on`.
    Coolant,
    /// A reference-instrument column `ref.<AXIS>.<quantity>_<unit>[#k]`.
    Reference {
        /// The axis.
        axis: AxisId,
        /// `<quantity>_<unit>`, e.g. `straightness_h_um`.
        quantity: String,
        /// The node index for per-node values.
        node: Option<usize>,
    },
    /// Any other column: kept as it is, meaning unknown to the format.
    Unknown,
}

impl Channel {
    /// Classifies a column name.
    pub fn parse(name: &str) -> Channel {
        match name {
            TIME => return Channel::Time,
            AMBIENT => return Channel::Ambient,
            COOLANT => return Channel::Coolant,
            _ => {}
        }
        if let Some(rest) = name.strip_prefix(REFERENCE_PREFIX) {
            let Some((axis, quantity)) = rest.split_once('.') else {
                return Channel::Unknown;
            };
            let Ok(axis) = axis.parse::<AxisId>() else {
                return Channel::Unknown;
            };
            let (quantity, node) = match quantity.split_once('#') {
                Some((q, k)) => match k.parse::<usize>() {
                    Ok(k) => (q, Some(k)),
                    Err(_) => return Channel::Unknown,
                },
                None => (quantity, None),
            };
            if quantity.is_empty() {
                return Channel::Unknown;
            }
            return Channel::Reference {
                axis,
                quantity: quantity.to_string(),
                node,
            };
        }
        let Some((axis, suffix)) = name.split_once('.') else {
            return Channel::Unknown;
        };
        // Axis ids are upper case in the format; `x.speed_rpm` is somebody else's column.
        let Some(axis) = AxisId::ALL.into_iter().find(|a| a.as_str() == axis) else {
            return Channel::Unknown;
        };
        Quantity::ALL
            .into_iter()
            .find(|q| q.column_suffix(axis) == suffix)
            .map_or(Channel::Unknown, |quantity| Channel::Servo {
                axis,
                quantity,
            })
    }

    /// The unit of the column, taken from its name (`°C` for `_C`, `µm` for `_um`, …).
    pub fn unit_of(name: &str) -> Option<&'static str> {
        let base = name.split('#').next().unwrap_or(name);
        let (_, unit) = base.rsplit_once('_')?;
        Some(match unit {
            "s" => "s",
            "mm" => "mm",
            "um" => "µm",
            "deg" => "°",
            "rpm" => "rpm",
            "Nm" => "N·m",
            "A" => "A",
            "pct" => "%",
            "C" => "°C",
            "W" => "W",
            "N" => "N",
            "on" => "0/1",
            _ => return None,
        })
    }

    /// The plausible value range of a column the format knows, `None` for columns it does not.
    pub fn plausible_range(&self) -> Option<(f64, f64)> {
        match self {
            // Seconds: a run's clock or a Unix time; beyond ±300 years it is garbage.
            Channel::Time => Some((-1.0e10, 1.0e10)),
            Channel::Servo { quantity, .. } => Some(quantity.plausible_range()),
            Channel::Ambient => Some((-50.0, 80.0)),
            Channel::Coolant => Some((0.0, 1.0)),
            // A reference instrument measures a temperature of the machine (the range of a
            // winding sensor) or a displacement (straightness, growth, backlash: ±100 m, as
            // for positions).
            Channel::Reference { quantity, .. } => match Channel::unit_of(quantity) {
                Some("°C") => Some(Quantity::StatorTemp.plausible_range()),
                Some("µm") => Some((-1.0e8, 1.0e8)),
                Some("mm") => Some((-1.0e5, 1.0e5)),
                _ => None,
            },
            Channel::Unknown => None,
        }
    }
}

/// The plausible range of a column: the format's range for the channels it knows
/// ([`Channel::plausible_range`]), and for the depth of cut (a column the format keeps as a
/// plain number) [`CUT_DEPTH_PLAUSIBLE_RANGE_MM`]. A value outside it is refused on read.
pub fn plausible_range_of(column: &str) -> Option<(f64, f64)> {
    Channel::parse(column)
        .plausible_range()
        .or_else(|| (column == CUT_DEPTH).then_some(CUT_DEPTH_PLAUSIBLE_RANGE_MM))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn standard_names_round_trip_through_parse() {
        for axis in AxisId::ALL {
            for quantity in Quantity::ALL {
                let name = axis_column(axis, quantity);
                assert_eq!(
                    Channel::parse(&name),
                    Channel::Servo { axis, quantity },
                    "{name}"
                );
            }
        }
        assert_eq!(axis_column(AxisId::S, Quantity::Position), "S.position_deg");
        assert_eq!(axis_column(AxisId::X, Quantity::Position), "X.position_mm");
    }

    #[test]
    fn reference_columns_carry_axis_quantity_and_node() {
        let name = reference_column(AxisId::X, "straightness_h_um", Some(3));
        assert_eq!(name, "ref.X.straightness_h_um#3");
        assert_eq!(
            Channel::parse(&name),
            Channel::Reference {
                axis: AxisId::X,
                quantity: "straightness_h_um".into(),
                node: Some(3)
            }
        );
        assert_eq!(Channel::unit_of(&name), Some("µm"));
        assert_eq!(Channel::parse("ref.Q.thing_um"), Channel::Unknown);
        assert_eq!(Channel::parse("ref.X.thing_um#x"), Channel::Unknown);
    }

    #[test]
    fn unknown_columns_stay_unknown() {
        for name in [
            "spindle_override",
            "x.speed_rpm",
            "X.speed",
            "X.",
            "ref.",
            "S.torque_kNm",
        ] {
            assert_eq!(Channel::parse(name), Channel::Unknown, "{name}");
        }
    }
}
