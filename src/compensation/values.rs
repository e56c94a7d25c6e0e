//! Compensation values: what can be written to the controller, named and in micrometres.

use std::collections::BTreeMap;
use std::fmt;
use std::str::FromStr;

use crate::signal::AxisId;

/// One compensation value the controller accepts.
///
/// Written as text `backlash.X`, `thermal_offset.S`, `straightness.Z#3`: the same form in the
/// proposal files, the audit log and the CLI, so an operator reads one vocabulary everywhere.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum CompensationId {
    /// Backlash (lost motion at reversal) of a linear feed axis, µm.
    Backlash(AxisId),
    /// Thermal offset of an axis, µm; on the spindle `S` this is the tool-length correction for
    /// spindle thermal elongation.
    ThermalOffset(AxisId),
    /// Straightness correction of a linear axis at one node of its table, µm.
    Straightness {
        /// The axis whose travel the table runs along.
        axis: AxisId,
        /// The node index, 0 at the negative end of travel.
        node: usize,
    },
}

impl CompensationId {
    /// The kind of value, which selects its limits: `backlash`, `thermal_offset`, `straightness`.
    pub fn kind(self) -> CompensationKind {
        match self {
            CompensationId::Backlash(_) => CompensationKind::Backlash,
            CompensationId::ThermalOffset(_) => CompensationKind::ThermalOffset,
            CompensationId::Straightness { .. } => CompensationKind::Straightness,
        }
    }
}

/// The three kinds of compensation value, each with its own limits.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum CompensationKind {
    /// Backlash per axis.
    Backlash,
    /// Thermal offset per axis / tool length.
    ThermalOffset,
    /// Straightness table nodes.
    Straightness,
}

impl fmt::Display for CompensationId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        // `pad` so that width and alignment work in tables (`{id:<20}`).
        let text = match self {
            CompensationId::Backlash(axis) => format!("backlash.{axis}"),
            CompensationId::ThermalOffset(axis) => format!("thermal_offset.{axis}"),
            CompensationId::Straightness { axis, node } => format!("straightness.{axis}#{node}"),
        };
        f.pad(&text)
    }
}

impl FromStr for CompensationId {
    type Err = String;
    fn from_str(text: &str) -> Result<Self, Self::Err> {
        let bad = || {
            format!(
                "`{text}` is not a compensation value \
                 (expected backlash.<AXIS>, thermal_offset.<AXIS> or straightness.<AXIS>#<node>)"
            )
        };
        let (kind, rest) = text.split_once('.').ok_or_else(bad)?;
        match kind {
            "backlash" => Ok(CompensationId::Backlash(rest.parse().map_err(|_| bad())?)),
            "thermal_offset" => Ok(CompensationId::ThermalOffset(
                rest.parse().map_err(|_| bad())?,
            )),
            "straightness" => {
                let (axis, node) = rest.split_once('#').ok_or_else(bad)?;
                Ok(CompensationId::Straightness {
                    axis: axis.parse().map_err(|_| bad())?,
                    node: node.parse().map_err(|_| bad())?,
                })
            }
            _ => Err(bad()),
        }
    }
}

impl serde::Serialize for CompensationId {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.collect_str(self)
    }
}

impl<'de> serde::Deserialize<'de> for CompensationId {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        let text = String::deserialize(deserializer)?;
        text.parse().map_err(serde::de::Error::custom)
    }
}

/// A set of compensation values in µm, ordered by id (so JSON and hashes are deterministic).
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(transparent)]
pub struct CompensationValues {
    values: BTreeMap<CompensationId, f64>,
}

impl CompensationValues {
    /// An empty set.
    pub fn new() -> Self {
        Self::default()
    }

    /// Sets one value, µm.
    pub fn set(&mut self, id: CompensationId, micrometres: f64) {
        self.values.insert(id, micrometres);
    }

    /// Takes one value out, returning it if it was there.
    pub fn remove(&mut self, id: CompensationId) -> Option<f64> {
        self.values.remove(&id)
    }

    /// One value, µm, if present.
    pub fn get(&self, id: CompensationId) -> Option<f64> {
        self.values.get(&id).copied()
    }

    /// Every value in id order.
    pub fn iter(&self) -> impl Iterator<Item = (CompensationId, f64)> + '_ {
        self.values.iter().map(|(id, v)| (*id, *v))
    }

    /// Number of values.
    pub fn len(&self) -> usize {
        self.values.len()
    }

    /// True when there are no values.
    pub fn is_empty(&self) -> bool {
        self.values.is_empty()
    }

    /// `self` with every value of `changes` put over it.
    pub fn overlaid_with(&self, changes: &CompensationValues) -> CompensationValues {
        let mut merged = self.clone();
        for (id, value) in changes.iter() {
            merged.set(id, value);
        }
        merged
    }

    /// Only the values whose ids appear in `ids`.
    pub fn restricted_to<'a>(
        &self,
        ids: impl IntoIterator<Item = &'a CompensationId>,
    ) -> CompensationValues {
        let mut out = CompensationValues::new();
        for id in ids {
            if let Some(value) = self.get(*id) {
                out.set(*id, value);
            }
        }
        out
    }
}

impl FromIterator<(CompensationId, f64)> for CompensationValues {
    fn from_iter<I: IntoIterator<Item = (CompensationId, f64)>>(iter: I) -> Self {
        CompensationValues {
            values: iter.into_iter().collect(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ids_round_trip_through_text() {
        for id in [
            CompensationId::Backlash(AxisId::X),
            CompensationId::ThermalOffset(AxisId::S),
            CompensationId::Straightness {
                axis: AxisId::Z,
                node: 7,
            },
        ] {
            assert_eq!(id.to_string().parse::<CompensationId>(), Ok(id));
        }
        assert!("backlash".parse::<CompensationId>().is_err());
        assert!("straightness.X".parse::<CompensationId>().is_err());
        assert!("wear.X".parse::<CompensationId>().is_err());
    }

    #[test]
    fn values_serialise_as_an_ordered_map() {
        let values: CompensationValues = [
            (CompensationId::ThermalOffset(AxisId::S), 12.5),
            (CompensationId::Backlash(AxisId::X), 3.0),
        ]
        .into_iter()
        .collect();
        let json = serde_json::to_string(&values).unwrap();
        assert_eq!(json, r#"{"backlash.X":3.0,"thermal_offset.S":12.5}"#);
        let back: CompensationValues = serde_json::from_str(&json).unwrap();
        assert_eq!(back, values);
    }
}
