//! The estimators' state, saved and taken up again: an HMI restarted in the middle of a shift
//! carries on from the heat its accumulators had built up, the lags, the tool measurement the
//! spindle's elongation counts from and the abnormality averages, instead of starting from a
//! guess (the profile's warm start) and withholding the spindle's thermal offset until the tool
//! is measured again.
//!
//! Every stateful estimator walks its state with one [`StateWalk`] in a fixed order: the same
//! walk saves and restores, so the two cannot drift apart when a field is added. What is saved
//! ([`SavedState`]) is JSON, with what it was saved from (the calibration's fingerprint, the
//! estimates' columns) and what the machine read then (each stator and the room), so that a
//! state is taken up only by the same models and only on a machine that is where it was left
//! ([`SavedState::check_resume`]).

#![allow(non_snake_case)] // unit suffixes (`_K`) are part of the names

use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use crate::estimators::models::Calibration;
use crate::estimators::pipeline::ElongationOrigin;
use crate::signal::{AxisId, Schema};

/// The version of [`SavedState`]'s layout; a file of another version is not taken up. 2: the
/// spindles' own room lags after a gap in the frames.
pub const STATE_FORMAT: u32 = 2;

/// The longest break between the last frame saved and the first frame of the next session
/// (machine time, or wall-clock time where the clock started again) over which the state is
/// taken up: a restart of the HMI or of its computer. Over the break the estimators hold the
/// first new frame's inputs (the heat accumulators are exact for an input that did not change),
/// which is right for a machine that stood or ran steadily and errs for one whose program
/// changed meanwhile. On the twin's production program (docs/accuracy.md, *An HMI restarted
/// mid-shift*) the carried state follows every estimate more closely than a fresh start (with
/// the profile's warm start) over breaks of up to three minutes; over four the nut, over five
/// the nut and the front bearing, read a fresh start's seed a little better (nut 0.15–0.16 K
/// off on average against 0.13–0.14 K), while the elongation still counts from its tool
/// measurement (0.3–0.5 µm off against 20 µm: a fresh start must have the tool measured again
/// before its thermal offset is used).
pub const MAX_RESUME_GAP_S: f64 = 300.0;

/// How far a stator or the room may read from where it read when the state was saved, K,
/// with no time passed: beyond a reading's noise and the fraction of a minute a restart takes.
pub const RESUME_READING_TOLERANCE_K: f64 = 1.0;

/// How fast a stator may move while the HMI is closed, K per minute, added to
/// [`RESUME_READING_TOLERANCE_K`] for the time passed: a spindle's stator moves fastest (on the
/// twin's production program, three 8 h shifts, at most 1.3 K in a minute and 7 K in ten), so
/// a machine that went on cutting or stood cooling still counts as where it was left, while one
/// whose stators read what they cannot have reached in the time (a controller or twin started
/// again from cold, another machine) does not.
pub const RESUME_READING_RATE_K_PER_MIN: f64 = 1.5;

/// How far a reading may have moved in `gap_s` for the machine to count as where it was left.
pub fn resume_tolerance_K(gap_s: f64) -> f64 {
    RESUME_READING_TOLERANCE_K + RESUME_READING_RATE_K_PER_MIN * gap_s / 60.0
}

/// The wall clock now, s since 1970 (UTC); `None` on a clock set before 1970.
pub fn unix_now_s() -> Option<f64> {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .ok()
        .map(|d| d.as_secs_f64())
}

/// Why a saved state is not taken up.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum StateError {
    /// It was saved in another layout.
    #[error("it was saved in format {found}, this version reads format {STATE_FORMAT}")]
    Format {
        /// The file's format.
        found: u32,
    },
    /// The models it was saved from are not these.
    #[error(
        "it was saved with another calibration of the profile (`{saved}`), whose estimators keep other state"
    )]
    Calibration {
        /// The profile it was saved with.
        saved: String,
    },
    /// The estimates are not the same set (another profile, or a link without a column some
    /// estimator needs).
    #[error("it holds the estimates {saved:?}, this session makes {now:?}")]
    Outputs {
        /// The estimates it holds.
        saved: Vec<String>,
        /// The estimates this session makes.
        now: Vec<String>,
    },
    /// It holds more or fewer values than the estimators keep.
    #[error("it holds {saved} state values, the estimators keep {expected}")]
    Length {
        /// Values in the file.
        saved: usize,
        /// Values the estimators keep.
        expected: usize,
    },
    /// The file is not a saved state (cut off, or not JSON of this layout).
    #[error("it is not a saved state: {0}")]
    Damaged(String),
    /// The first frame has no time.
    #[error("the first frame has no time")]
    NoTime,
    /// The recording's clock is behind the state's.
    #[error(
        "the recording's time reads {now_s:.1} s, before the {saved_s:.1} s the state was saved at: another recording, or the same one opened again"
    )]
    ClockBehind {
        /// Time of the first frame now, s.
        now_s: f64,
        /// Machine time of the state, s.
        saved_s: f64,
    },
    /// The wall clock reads earlier than when the state was saved.
    #[error("the computer's clock reads earlier than when the state was saved")]
    WallClockBehind,
    /// The state does not say when it was saved, and the frames' clock started again.
    #[error(
        "it does not say when its last frame was received, and the link's clock has started again"
    )]
    NoWallClock,
    /// Too long has passed for the state to stand for the machine.
    #[error(
        "{gap_s:.0} s passed since its last frame, longer than the {MAX_RESUME_GAP_S:.0} s over which it is taken up"
    )]
    TooLong {
        /// Time passed since the state's last frame, s.
        gap_s: f64,
    },
    /// A stator or the room reads far from where it read when the state was saved.
    #[error(
        "`{column}` reads {now:.2} now and read {saved:.2} then, {gap_s:.0} s before, more than the {allowed_K:.1} K it can move in that time: the machine is not where the state left it"
    )]
    Moved {
        /// The column.
        column: String,
        /// What it reads now.
        now: f64,
        /// What it read when the state was saved.
        saved: f64,
        /// The time passed, s.
        gap_s: f64,
        /// How far it may have moved in that time, K ([`resume_tolerance_K`]).
        allowed_K: f64,
    },
    /// A column the state is checked by was not read when it was saved.
    #[error(
        "`{column}` was not read when it was saved, so whether the machine is where the state left it cannot be told"
    )]
    UnreadThen {
        /// The column.
        column: String,
    },
    /// A column the state is checked by is missing now, or unread.
    #[error(
        "`{column}` is not read now, so whether the machine is where the state left it cannot be told"
    )]
    Unread {
        /// The column.
        column: String,
    },
}

/// One pass over estimators' state in a fixed order, saving it or restoring it.
#[derive(Debug)]
pub struct StateWalk<'a> {
    mode: Mode<'a>,
}

#[derive(Debug)]
enum Mode<'a> {
    Save(Vec<f64>),
    Restore { values: &'a [f64], next: usize },
}

impl StateWalk<'static> {
    /// A walk that saves every value it is shown.
    pub fn saving() -> Self {
        StateWalk {
            mode: Mode::Save(Vec::new()),
        }
    }
}

impl<'a> StateWalk<'a> {
    /// A walk that writes `values`, in order, into every value it is shown.
    pub fn restoring(values: &'a [f64]) -> Self {
        StateWalk {
            mode: Mode::Restore { values, next: 0 },
        }
    }

    /// Saves or restores one number. Restoring past the end leaves it and is counted
    /// ([`Self::finish`] says so).
    pub fn value(&mut self, x: &mut f64) {
        match &mut self.mode {
            Mode::Save(out) => out.push(*x),
            Mode::Restore { values, next } => {
                if let Some(v) = values.get(*next) {
                    *x = *v;
                }
                *next += 1;
            }
        }
    }

    /// Saves or restores a flag (as 0 or 1).
    pub fn flag(&mut self, b: &mut bool) {
        let mut x = f64::from(u8::from(*b));
        self.value(&mut x);
        *b = x == 1.0;
    }

    /// Saves or restores a count (exact up to 2⁵³).
    pub fn count(&mut self, n: &mut u64) {
        let mut x = *n as f64;
        self.value(&mut x);
        *n = if x.is_finite() && x > 0.0 {
            x as u64
        } else {
            0
        };
    }

    /// Saves or restores a count held as a `usize`.
    pub fn count_usize(&mut self, n: &mut usize) {
        let mut wide = *n as u64;
        self.count(&mut wide);
        *n = usize::try_from(wide).unwrap_or(usize::MAX);
    }

    /// Saves or restores an optional number (a flag, then the number or NaN).
    pub fn optional(&mut self, x: &mut Option<f64>) {
        let mut present = x.is_some();
        let mut v = x.unwrap_or(f64::NAN);
        self.flag(&mut present);
        self.value(&mut v);
        *x = present.then_some(v);
    }

    /// Saves or restores an optional part (a flag, then the part, a default one when absent).
    pub fn optional_state<T: WalkState + Default>(&mut self, x: &mut Option<T>) {
        let mut present = x.is_some();
        self.flag(&mut present);
        let mut inner = x.take().unwrap_or_default();
        inner.walk_state(self);
        *x = present.then_some(inner);
    }

    /// Saves or restores every number of an array.
    pub fn values(&mut self, xs: &mut [f64]) {
        for x in xs {
            self.value(x);
        }
    }

    /// The values saved (empty for a restoring walk).
    pub fn into_saved(self) -> Vec<f64> {
        match self.mode {
            Mode::Save(out) => out,
            Mode::Restore { .. } => Vec::new(),
        }
    }

    /// Checks that a restoring walk used every value and asked for no more.
    pub fn finish(self) -> Result<(), StateError> {
        match self.mode {
            Mode::Restore { values, next } if next != values.len() => Err(StateError::Length {
                saved: values.len(),
                expected: next,
            }),
            _ => Ok(()),
        }
    }
}

/// An estimator whose state carries over from one session to the next.
pub trait WalkState {
    /// Shows every value of the state to `walk`, always in the same order.
    fn walk_state(&mut self, walk: &mut StateWalk<'_>);
}

impl<T: WalkState> WalkState for Option<T> {
    fn walk_state(&mut self, walk: &mut StateWalk<'_>) {
        if let Some(inner) = self {
            inner.walk_state(walk);
        }
    }
}

impl<T: WalkState, const N: usize> WalkState for [T; N] {
    fn walk_state(&mut self, walk: &mut StateWalk<'_>) {
        for inner in self {
            inner.walk_state(walk);
        }
    }
}

/// What a reading was when the state was saved.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SavedReading {
    /// The column.
    pub column: String,
    /// Its value at the last frame (`null` when it was not a number).
    pub value: Option<f64>,
}

/// Where a spindle's elongation counted from when the state was saved.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SavedSpindle {
    /// The spindle.
    pub axis: AxisId,
    /// Where its elongation counts from (`null` before its first estimate).
    pub origin: Option<ElongationOrigin>,
    /// What the spindle was at its first estimate (a later tool measurement carries it).
    pub start: Option<ElongationOrigin>,
    /// The operator had measured the tool and the elongation had not counted from it yet.
    pub tool_measured_pending: bool,
}

/// The estimators' state after one frame, as a later session takes it up (JSON).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SavedState {
    /// [`STATE_FORMAT`].
    pub format: u32,
    /// The profile's name (for messages).
    pub profile: String,
    /// SHA-256 of the profile's calibration ([`calibration_fingerprint`]).
    pub calibration_sha256: String,
    /// The estimates' output columns, in order.
    pub outputs: Vec<String>,
    /// Machine time of the last frame, s.
    pub time_s: f64,
    /// Wall-clock time the last frame was received, s since 1970 (UTC), where the saver knew
    /// it: how long ago it was when the machine's clock has started again.
    #[serde(default)]
    pub frame_unix_s: Option<f64>,
    /// Each stator and the room at the last frame: the machine must read near them for the
    /// state to be taken up.
    pub readings: Vec<SavedReading>,
    /// The estimators' values in their walk's order (`null` for a value that was not a number,
    /// which JSON cannot hold).
    pub values: Vec<Option<f64>>,
    /// Where each spindle's elongation counted from.
    pub spindles: Vec<SavedSpindle>,
}

impl SavedState {
    /// The values as the walk restores them (`null` back to NaN).
    pub fn walk_values(&self) -> Vec<f64> {
        self.values.iter().map(|v| v.unwrap_or(f64::NAN)).collect()
    }

    /// Whether the state may be taken up on a machine whose first frame of the new session is
    /// `frame` (laid out as `schema`), its time on `clock`: at most [`MAX_RESUME_GAP_S`] has
    /// passed since the state's last frame, and every stator and the room read within what they
    /// can have moved in that time ([`resume_tolerance_K`]) of where they read then.
    pub fn check_resume(
        &self,
        schema: &Schema,
        frame: &[f64],
        clock: Clock,
    ) -> Result<Resume, StateError> {
        let now_s = frame.first().copied().unwrap_or(f64::NAN);
        if !now_s.is_finite() {
            return Err(StateError::NoTime);
        }
        let gap_s = match clock {
            Clock::Continued if now_s >= self.time_s => now_s - self.time_s,
            Clock::Continued => {
                return Err(StateError::ClockBehind {
                    now_s,
                    saved_s: self.time_s,
                });
            }
            Clock::Restarted { now_unix_s } => match self.frame_unix_s {
                Some(then) if now_unix_s >= then => now_unix_s - then,
                Some(_) => return Err(StateError::WallClockBehind),
                None => return Err(StateError::NoWallClock),
            },
        };
        if gap_s.is_nan() || gap_s > MAX_RESUME_GAP_S {
            return Err(StateError::TooLong { gap_s });
        }
        for reading in &self.readings {
            let saved = reading.value.ok_or_else(|| StateError::UnreadThen {
                column: reading.column.clone(),
            })?;
            let now = schema
                .index_of(&reading.column)
                .and_then(|i| frame.get(i))
                .copied()
                .filter(|v| v.is_finite())
                .ok_or_else(|| StateError::Unread {
                    column: reading.column.clone(),
                })?;
            let allowed_K = resume_tolerance_K(gap_s);
            if (now - saved).abs() > allowed_K {
                return Err(StateError::Moved {
                    column: reading.column.clone(),
                    now,
                    saved,
                    gap_s,
                    allowed_K,
                });
            }
        }
        Ok(Resume {
            gap_s,
            time_shift_s: (now_s - gap_s) - self.time_s,
            clock,
        })
    }

    /// Reads a saved state from its JSON, its layout's version first: a file of another version
    /// is [`StateError::Format`], not whatever field that version lacks.
    pub fn from_json(text: &str) -> Result<SavedState, StateError> {
        #[derive(Deserialize)]
        struct Version {
            format: u32,
        }
        let damaged = |e: serde_json::Error| StateError::Damaged(e.to_string());
        let version: Version = serde_json::from_str(text).map_err(damaged)?;
        if version.format != STATE_FORMAT {
            return Err(StateError::Format {
                found: version.format,
            });
        }
        serde_json::from_str(text).map_err(damaged)
    }
}

/// The clock the frames of the new session are on.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Clock {
    /// Their time goes on from the state's (a replay of the recording's continuation): the
    /// time passed is the machine time between the two frames, and a time behind the state's
    /// is another recording, or the same one opened again.
    Continued,
    /// Their time started again (a live link's time counts from the link's start): the time
    /// passed is the wall-clock time between the two frames.
    Restarted {
        /// When the first frame now was received, s since 1970 (UTC).
        now_unix_s: f64,
    },
}

/// How a saved state is taken up.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Resume {
    /// Time passed between the state's last frame and the first frame now, s.
    pub gap_s: f64,
    /// What to add to the state's machine times to put them on the clock of the frames now, s
    /// (0 where the clock went on).
    pub time_shift_s: f64,
    /// The clock the frames now are on.
    pub clock: Clock,
}

/// SHA-256 (hex) of a calibration as JSON: a state saved with one calibration is taken up only
/// by the same models (other time constants or terms keep other state). `None` for one that
/// cannot be written as JSON, whose state is then neither saved nor taken up.
pub fn calibration_fingerprint(calibration: &Calibration) -> Option<String> {
    // The calibration's maps are ordered (BTreeMap), so the same calibration gives the same
    // text.
    let text = serde_json::to_string(calibration).ok()?;
    Some(
        Sha256::digest(text.as_bytes())
            .iter()
            .map(|b| format!("{b:02x}"))
            .collect(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, Default, PartialEq)]
    struct Part {
        heat: f64,
        started: bool,
        blocks: u64,
        at_calibration: Option<f64>,
        lags: [f64; 3],
    }

    impl WalkState for Part {
        fn walk_state(&mut self, walk: &mut StateWalk<'_>) {
            walk.value(&mut self.heat);
            walk.flag(&mut self.started);
            walk.count(&mut self.blocks);
            walk.optional(&mut self.at_calibration);
            walk.values(&mut self.lags);
        }
    }

    #[test]
    fn the_same_walk_saves_and_restores() {
        let mut parts = [
            Part {
                heat: 1.5,
                started: true,
                blocks: 17,
                at_calibration: Some(-2.25),
                lags: [20.0, 21.0, f64::NAN],
            },
            Part::default(),
        ];
        let mut saving = StateWalk::saving();
        parts.walk_state(&mut saving);
        let saved = saving.into_saved();
        assert_eq!(saved.len(), 2 * 8);
        let mut restored = [Part::default(), Part::default()];
        let mut walk = StateWalk::restoring(&saved);
        restored.walk_state(&mut walk);
        walk.finish().expect("every value used");
        assert_eq!(restored[0].heat, 1.5);
        assert!(restored[0].started);
        assert_eq!(restored[0].blocks, 17);
        assert_eq!(restored[0].at_calibration, Some(-2.25));
        assert_eq!(&restored[0].lags[..2], &[20.0, 21.0]);
        assert!(restored[0].lags[2].is_nan());
        assert_eq!(restored[1], Part::default());
    }

    #[test]
    fn a_walk_over_values_of_another_layout_is_refused() {
        let mut part = Part::default();
        let short = [1.0; 5];
        let mut walk = StateWalk::restoring(&short);
        part.walk_state(&mut walk);
        assert_eq!(
            walk.finish(),
            Err(StateError::Length {
                saved: 5,
                expected: 8
            })
        );
        let long = [1.0; 9];
        let mut walk = StateWalk::restoring(&long);
        part.walk_state(&mut walk);
        assert_eq!(
            walk.finish(),
            Err(StateError::Length {
                saved: 9,
                expected: 8
            })
        );
    }
}
