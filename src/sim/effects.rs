//! The physical effects of the twin, each of which can be switched off by name.
//!
//! Sim-vs-real work depends on this: the "real" run has every effect, the "simulation" omits one,
//! and the discrepancy analysis must find which. The ids match DESIGN.md's physics vocabulary
//! where one exists.

use std::fmt;
use std::str::FromStr;

/// One switchable effect.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Effect {
    /// The structure follows room-temperature changes (through its own thermal lag). Off: the
    /// twin assumes a constant room at the profile's base temperature.
    AmbientTemperature,
    /// The heat capacity of the structure (headstock, bed, screw). Off: the structure is treated
    /// as massless, so it responds without lag.
    ThermalInertia,
    /// Convective heat transfer grows with rotational speed. Off: still-air convection at every
    /// speed.
    SpeedDependentCooling,
    /// Lubricant viscosity falls as it warms, and bearing friction torque and heat with it. Off:
    /// viscosity fixed at its 40 °C value.
    LubricantViscosity,
    /// Motor copper loss I²R (with the winding resistance rising with temperature). Off: no
    /// copper loss heat.
    CopperLoss,
    /// Motor iron loss (hysteresis ∝ speed, eddy currents ∝ speed²). Off: none.
    IronLoss,
    /// Coolant / oil-chiller cooling while `coolant_on` is 1. Off: coolant has no thermal effect.
    Coolant,
    /// Coulomb friction of guideways and seals that flips with the direction of motion, with a
    /// Stribeck rise near zero speed. Off: no direction-dependent friction of the table.
    CoulombReversal,
    /// Effects varying along the stroke: ball-screw preload drag torque changes along the screw
    /// and the nut's heat enters the bed where the nut is. Off: uniform along the stroke.
    PositionDependent,
    /// Lost motion between the nut and the table (a dead zone). Off: rigid connection.
    Backlash,
    /// A time delay of every measured signal (the controller's or logger's transport delay).
    /// Its size is the measurement setting `delay_s`. Off: no delay.
    SignalDelay,
    /// A constant offset and a slow linear drift of the reference instruments. Its size is the
    /// measurement settings `offset` and `drift_per_hour`. Off: none.
    SensorOffsetDrift,
}

impl Effect {
    /// Every effect, in documentation order.
    pub const ALL: [Effect; 12] = [
        Effect::AmbientTemperature,
        Effect::ThermalInertia,
        Effect::SpeedDependentCooling,
        Effect::LubricantViscosity,
        Effect::CopperLoss,
        Effect::IronLoss,
        Effect::Coolant,
        Effect::CoulombReversal,
        Effect::PositionDependent,
        Effect::Backlash,
        Effect::SignalDelay,
        Effect::SensorOffsetDrift,
    ];

    /// The id used on the command line and in reports.
    pub fn id(self) -> &'static str {
        match self {
            Effect::AmbientTemperature => "ambient_temperature",
            Effect::ThermalInertia => "thermal_inertia",
            Effect::SpeedDependentCooling => "speed_dependent_cooling",
            Effect::LubricantViscosity => "lubricant_viscosity",
            Effect::CopperLoss => "copper_loss",
            Effect::IronLoss => "iron_loss",
            Effect::Coolant => "coolant",
            Effect::CoulombReversal => "coulomb_reversal",
            Effect::PositionDependent => "position_dependent",
            Effect::Backlash => "backlash",
            Effect::SignalDelay => "signal_delay",
            Effect::SensorOffsetDrift => "sensor_offset_drift",
        }
    }

    fn bit(self) -> u32 {
        1 << (self as u32)
    }
}

impl fmt::Display for Effect {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.id())
    }
}

impl FromStr for Effect {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Effect::ALL
            .into_iter()
            .find(|e| e.id() == s.trim())
            .ok_or_else(|| {
                let known: Vec<&str> = Effect::ALL.iter().map(|e| e.id()).collect();
                format!("unknown effect `{s}` (known: {})", known.join(", "))
            })
    }
}

/// The set of effects a twin simulates.
#[derive(Clone, Copy, PartialEq, Eq)]
pub struct EffectSet(u32);

impl EffectSet {
    /// Every effect on: the "real machine".
    pub fn all() -> Self {
        EffectSet(Effect::ALL.iter().fold(0, |bits, e| bits | e.bit()))
    }

    /// No effect on.
    pub fn none() -> Self {
        EffectSet(0)
    }

    /// This set without `effect`.
    pub fn without(self, effect: Effect) -> Self {
        EffectSet(self.0 & !effect.bit())
    }

    /// This set with `effect`.
    pub fn with(self, effect: Effect) -> Self {
        EffectSet(self.0 | effect.bit())
    }

    /// Is `effect` simulated?
    pub fn has(self, effect: Effect) -> bool {
        self.0 & effect.bit() != 0
    }

    /// The effects that are off, in documentation order.
    pub fn missing(self) -> Vec<Effect> {
        Effect::ALL.into_iter().filter(|e| !self.has(*e)).collect()
    }
}

impl Default for EffectSet {
    fn default() -> Self {
        EffectSet::all()
    }
}

impl fmt::Debug for EffectSet {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_set()
            .entries(Effect::ALL.iter().filter(|e| self.has(**e)).map(|e| e.id()))
            .finish()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ids_round_trip_and_unknown_ids_list_the_known_ones() {
        for effect in Effect::ALL {
            assert_eq!(effect.id().parse::<Effect>(), Ok(effect));
        }
        let err = "friction".parse::<Effect>().unwrap_err();
        assert!(err.contains("coulomb_reversal"), "{err}");
    }

    #[test]
    fn without_removes_exactly_one_effect() {
        let set = EffectSet::all().without(Effect::Coolant);
        assert!(!set.has(Effect::Coolant));
        assert_eq!(set.missing(), vec![Effect::Coolant]);
        assert!(
            Effect::ALL
                .iter()
                .filter(|e| **e != Effect::Coolant)
                .all(|e| set.has(*e))
        );
    }
}
