//! Alignment: both recordings on one time grid inside their overlap — the real recording's,
//! unless the simulation is clearly coarser — with the other interpolated onto it.

use super::DiscrepancyError;
use super::censor::Censoring;
use super::series;
use crate::fit::autocorrelation::white_noise_of_steps;
use crate::signal::Quantity;
use crate::signal::Recording;
use crate::signal::channel::{AMBIENT, Channel};

/// Fewest overlapping rows an analysis accepts.
pub const MIN_ROWS: usize = 60;

/// The simulation's grid is used when its typical step exceeds the real recording's by more
/// than this factor: between its samples a coarse simulation holds no information, and a
/// fast target interpolated across them (a current through a move shorter than a step) is
/// an error of the interpolation that the analysis would take for missing physics.
const COARSER_FACTOR: f64 = 1.5;

/// For each aligned row: the source row at or before it and the fraction towards the next
/// — or, for an instant placed on one side of a speed's step, the row that begins that
/// side's own interval and a fraction outside [0, 1] ([`placed_by_speeds`]).
pub type Index = Vec<(usize, f64)>;

/// A speed steps between two samples of the interpolated recording when it changes there by
/// more than this many times the two recordings' speed noise together (then the other
/// recording's speed at the instant says where in the step it falls to within a tenth).
const SPEED_STEP_NOISES: f64 = 10.0;

/// Most rows the real recording may have inside the overlap for the corrections to be built
/// at its own rate when the comparison runs at a coarser simulation's instants (see
/// [`Aligned::real_rate`]): ten times the rows the performance target allows an analysis.
pub const REAL_RATE_MAX_ROWS: usize = 1_000_000;

/// Which grid the rows are put on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Grid {
    /// The real recording's, unless the simulation's is clearly coarser.
    Auto,
    /// The real recording's.
    Real,
}

/// The real target read between two of its samples ([`Aligned::real_target_later`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Reading {
    /// The value read.
    pub value: f64,
    /// The share of one sample's white-noise variance that reading between two samples
    /// averages away: 2 f (1 − f) at a fraction f of the way.
    pub averaged: f64,
}

/// The two recordings joined on `time_s`.
#[derive(Debug)]
pub struct Aligned<'a> {
    real: &'a Recording,
    sim: &'a Recording,
    /// Where each aligned row lies in the real recording.
    real_index: Index,
    /// Where each aligned row lies in the simulation.
    sim_index: Index,
    /// True when the two recordings were not on one grid: the simulation interpolated onto the
    /// real recording's, or the real recording taken at the coarser simulation's instants.
    pub resampled: bool,
    /// True when the grid is the simulation's (it is clearly coarser than the real one).
    pub on_simulation_grid: bool,
    /// True when the simulation's values on these rows are read between its own samples
    /// (interpolated, or placed by the speeds): there a signal that flips, such as a torque at
    /// a reversal, has a sign the simulation never gave it.
    pub simulation_between_samples: bool,
    /// Rows placed by the speeds (see [`placed_by_speeds`]) instead of linearly in time.
    pub placed_by_speed: usize,
    /// Time of every aligned row, s.
    pub time: Vec<f64>,
    /// The real target.
    pub real_target: Vec<f64>,
    /// The simulated target on the aligned grid — as the real instrument would read it when
    /// the real recording is censored at a floor (see [`Censoring`]).
    pub sim_target: Vec<f64>,
    /// The real target's floor and the noise cut off there, when it has one.
    pub censoring: Option<Censoring>,
    /// How many of its own samples later the real target is read ([`Aligned::read_later`]);
    /// zero as recorded.
    pub target_read_later: f64,
    /// The real target as recorded on these rows, when it is read later.
    pub recorded_target: Option<Vec<f64>>,
}

impl<'a> Aligned<'a> {
    /// Joins `sim` and `real` on time for `target`.
    pub fn new(
        sim: &'a Recording,
        real: &'a Recording,
        target: &str,
    ) -> Result<Self, DiscrepancyError> {
        Self::join(sim, real, target, Grid::Auto, 0.0)
    }

    /// Joins `sim` and `real` on time for `target` with the real target read `samples` of the
    /// real recording's own samples later (earlier when negative; see
    /// [`Aligned::real_target_later`]), every other column as recorded: a measurement of the
    /// target that trails the simulation by that delay, compared with it where it was taken.
    /// Only the rows whose later samples the recording holds are kept.
    pub fn read_later(
        sim: &'a Recording,
        real: &'a Recording,
        target: &str,
        samples: f64,
    ) -> Result<Self, DiscrepancyError> {
        Self::join(sim, real, target, Grid::Auto, samples)
    }

    /// A column of the real recording on its own rows, as recorded.
    pub fn real_samples(&self, name: &str) -> Option<&'a [f64]> {
        self.real.try_column(name)
    }

    /// The real recording's median step, s.
    pub fn real_step_s(&self) -> Option<f64> {
        self.real.median_step_s()
    }

    /// The real target `samples` of its own samples later on each row ([`Aligned::read_later`]),
    /// `None` on a row whose later samples the recording does not hold. Whole samples later,
    /// each row is read with the weights it is read with at no delay; a fraction later, on the
    /// line between the two samples there, or, `placed`, where a step of a speed between them
    /// places the row ([`Aligned::place_later`]).
    pub fn real_target_later(
        &self,
        target: &str,
        samples: f64,
        placed: bool,
    ) -> Option<Vec<Option<Reading>>> {
        let column = self.real.try_column(target)?;
        let time = self.real.time();
        let step = self.real_step_s()?;
        let whole = samples.fract() == 0.0;
        // The instant a place (a sample and a fraction towards the next) stands for.
        let instant = |(j, f): (usize, f64)| {
            let next = time.get(j + 1).copied().unwrap_or(time[j]);
            time[j] + f.clamp(0.0, 1.0) * (next - time[j])
        };
        let at = |position: f64| -> Option<(usize, f64)> {
            let below = position.floor();
            let row = usize::try_from(below as i64).ok()?;
            (row + 1 < column.len()).then_some((row, position - below))
        };
        let mut moved: Vec<Option<(usize, f64)>> = self
            .real_index
            .iter()
            .map(|&(j, f)| {
                if whole {
                    let row = usize::try_from(j as i64 + samples as i64).ok()?;
                    (row < column.len()).then_some((row, f))
                } else {
                    at(j as f64 + f + samples)
                }
            })
            .collect();
        // Across a gap in the recording (or where its clock jitters by half a sample) a reading
        // so many samples later is not the delay later: not read.
        for (reading, &from) in moved.iter_mut().zip(&self.real_index) {
            if let Some(to) = *reading
                && (instant(to) - instant(from) - samples * step).abs() > 0.5 * step
            {
                *reading = None;
            }
        }
        if placed && !whole {
            self.place_later(&mut moved, samples);
        }
        let inside: Vec<(usize, f64)> = moved.iter().flatten().copied().collect();
        let mut values = interpolate(column, &inside).into_iter();
        Some(
            moved
                .iter()
                .map(|m| {
                    let (_, f) = (*m)?;
                    let value = values.next()?;
                    // Only a fraction between the samples averages their noise.
                    let f = if (0.0..=1.0).contains(&f) { f } else { 0.0 };
                    Some(Reading {
                        value,
                        averaged: 2.0 * f * (1.0 - f),
                    })
                })
                .collect(),
        )
    }

    /// Places each reading `samples` (a fraction of a sample) later whose two samples straddle
    /// a step of a speed by where the row's instant falls in that step, as the rows themselves
    /// are placed ([`placed_by_speeds`]): a sample of the target was taken `samples` after the
    /// machine was where it shows, so each sample's speed is the real speed read that much
    /// earlier, and the simulation's speed at the row says on which side of the step the row
    /// lies. On the line between two samples across a reversal the reading is neither side's
    /// torque; placed, it is the side the row is on (the sample on that side was taken after
    /// the reversal, or before it, whichever the row's own speed shows).
    fn place_later(&self, moved: &mut [Option<(usize, f64)>], samples: f64) {
        let guides: Vec<(Vec<f64>, Vec<f64>, f64, f64)> = self
            .real
            .names()
            .iter()
            .filter(|name| is_servo_speed(name))
            .filter_map(|name| {
                let own = self.real.try_column(name)?;
                let simulated = self.sim.try_column(name)?;
                let (lo, hi) = series::span(own);
                let range = hi - lo;
                if !(range.is_finite() && range > 0.0) {
                    return None;
                }
                let step = self.real_step_s()?;
                let earlier = series::shifted(self.real.time(), own, samples * step);
                // The real speed's own noise: the simulation's samples, a coarse export's,
                // differ from one to the next by what the speed did between them.
                let noise = noise_while_moving(own);
                Some((
                    earlier,
                    interpolate(simulated, &self.sim_index),
                    noise,
                    range,
                ))
            })
            .collect();
        // Agreement is judged on the rows with a reading alone.
        let read: Index = moved.iter().flatten().copied().collect();
        let agrees = |own: &[f64], at: &[f64], noise: f64, range: f64| {
            let at = at
                .iter()
                .zip(moved.iter())
                .filter(|(_, m)| m.is_some())
                .map(|(a, _)| *a)
                .collect();
            GuidingSpeed {
                own,
                at,
                noise,
                range,
            }
            .agrees(&read)
        };
        let speeds: Vec<GuidingSpeed<'_>> = guides
            .iter()
            .filter(|(own, at, noise, range)| agrees(own, at, *noise, *range))
            .map(|(own, at, noise, range)| GuidingSpeed {
                own,
                at: at.clone(),
                noise: *noise,
                range: *range,
            })
            .collect();
        if speeds.is_empty() {
            return;
        }
        for (row, reading) in moved.iter_mut().enumerate() {
            let Some((j, fraction)) = reading else {
                continue;
            };
            if *fraction <= COINCIDING || *fraction >= 1.0 - COINCIDING {
                continue;
            }
            if let Some((_, at)) = speeds
                .iter()
                .filter_map(|speed| speed.place(*j, row))
                .max_by(|a, b| a.0.total_cmp(&b.0))
            {
                *fraction = at;
            }
        }
    }

    /// When the rows are the coarser simulation's instants: the same pair on the real
    /// recording's own rows inside the same span, on which the corrections are built before
    /// they are read at those instants. A heat path integrates its driver between the
    /// simulation's samples (a current that rises for a few seconds of a cut), and a lag of
    /// the driver read only at those instants misses what happened between them. `None` when
    /// the rows already are the real recording's, or when it has more than
    /// [`REAL_RATE_MAX_ROWS`] rows in the span (then the corrections are built at the
    /// simulation's instants, as the note says).
    pub fn real_rate(&self, target: &str) -> Option<Aligned<'a>> {
        if !self.builds_at_real_rate() {
            return None;
        }
        Self::join(
            self.sim,
            self.real,
            target,
            Grid::Real,
            self.target_read_later,
        )
        .ok()
    }

    /// Where each aligned row lies among the real recording's rows from the one at
    /// `first_s` on (the rows of [`Aligned::real_rate`]): as placed here, so that what is
    /// built on those rows is read at an instant on the side of a step its real target is
    /// read on. A row before the first is read at the first.
    pub fn real_rows_from(&self, first_s: f64) -> Index {
        let offset = self.real.time().partition_point(|&t| t < first_s);
        self.real_index
            .iter()
            .map(|&(j, f)| j.checked_sub(offset).map_or((0, 0.0), |j| (j, f)))
            .collect()
    }

    /// Whether [`Aligned::real_rate`] gives the real recording's rows.
    fn builds_at_real_rate(&self) -> bool {
        self.on_simulation_grid && self.real_rows_in_span() <= REAL_RATE_MAX_ROWS
    }

    /// Rows of the real recording inside the aligned span.
    fn real_rows_in_span(&self) -> usize {
        let (Some(&start), Some(&end)) = (self.time.first(), self.time.last()) else {
            return 0;
        };
        let rt = self.real.time();
        rt.partition_point(|&t| t <= end) - rt.partition_point(|&t| t < start)
    }

    fn join(
        sim: &'a Recording,
        real: &'a Recording,
        target: &str,
        grid: Grid,
        read_later: f64,
    ) -> Result<Self, DiscrepancyError> {
        for (recording, role) in [(sim, "simulation"), (real, "real recording")] {
            if recording.try_column(target).is_none() {
                return Err(DiscrepancyError::MissingTarget {
                    role,
                    source_name: recording.source().to_string(),
                    target: target.to_string(),
                });
            }
        }
        let (st, rt) = (sim.time(), real.time());
        let (Some(&s0), Some(&s1), Some(&r0), Some(&r1)) =
            (st.first(), st.last(), rt.first(), rt.last())
        else {
            return Err(DiscrepancyError::NoOverlap {
                sim: describe_span(sim),
                real: describe_span(real),
            });
        };
        for (recording, role) in [(sim, "simulation"), (real, "real recording")] {
            if recording.len() > 1 && recording.median_step_s().is_none() {
                return Err(DiscrepancyError::TimeStalls {
                    role,
                    source_name: recording.source().to_string(),
                });
            }
        }
        let start = s0.max(r0);
        let end = s1.min(r1);
        // An overlap of one instant is no overlap for an analysis over time.
        if end <= start {
            return Err(DiscrepancyError::NoOverlap {
                sim: describe_span(sim),
                real: describe_span(real),
            });
        }
        let real_step = real.median_step_s().unwrap_or(1.0);
        let sim_step = sim.median_step_s().unwrap_or(real_step);
        let inside = |grid: &[f64]| -> Vec<f64> {
            grid[grid.partition_point(|&t| t < start)..]
                .iter()
                .copied()
                .take_while(|&t| t <= end)
                .collect()
        };
        // A simulation too sparse to give the fewest rows an analysis needs (a handful of FEA
        // time points) is still compared on the real grid, interpolated, as a slow target
        // allows.
        let coarse = (grid == Grid::Auto && sim_step > COARSER_FACTOR * real_step)
            .then(|| inside(st))
            .filter(|time| time.len() >= MIN_ROWS);
        let on_simulation_grid = coarse.is_some();
        let time = coarse.unwrap_or_else(|| inside(rt));
        if time.len() < MIN_ROWS {
            return Err(DiscrepancyError::TooShort {
                rows: time.len(),
                needed: MIN_ROWS,
            });
        }
        let (real_index, real_resampled) = index_onto(rt, &time, real_step);
        let (sim_index, sim_resampled) = index_onto(st, &time, real_step.min(sim_step));
        // The recording whose own rows these are guides the other one's interpolation.
        let (real_index, sim_index, placed_by_speed) = if on_simulation_grid {
            let (real_index, placed) =
                placed_by_speeds(real_index, real, sim, &sim_index, Sides::Held);
            (real_index, sim_index, placed)
        } else {
            let (sim_index, placed) =
                placed_by_speeds(sim_index, sim, real, &real_index, Sides::Extended);
            (real_index, sim_index, placed)
        };
        let mut aligned = Aligned {
            real,
            sim,
            real_index,
            sim_index,
            resampled: on_simulation_grid || real_resampled || sim_resampled,
            on_simulation_grid,
            simulation_between_samples: sim_resampled
                || (!on_simulation_grid && placed_by_speed > 0),
            placed_by_speed,
            time,
            real_target: Vec::new(),
            sim_target: Vec::new(),
            censoring: None,
            target_read_later: read_later,
            recorded_target: None,
        };
        if read_later != 0.0 {
            // Only the rows whose later reading the recording holds.
            let later = aligned
                .real_target_later(target, read_later, true)
                .unwrap_or_default();
            fn keep<T>(rows: &mut Vec<T>, later: &[Option<Reading>]) {
                let mut read = later.iter();
                rows.retain(|_| read.next().is_some_and(Option::is_some));
            }
            keep(&mut aligned.time, &later);
            keep(&mut aligned.real_index, &later);
            keep(&mut aligned.sim_index, &later);
            if aligned.time.len() < MIN_ROWS {
                return Err(DiscrepancyError::TooShort {
                    rows: aligned.time.len(),
                    needed: MIN_ROWS,
                });
            }
            aligned.recorded_target = aligned.real_column(target);
            aligned.real_target = later.into_iter().flatten().map(|r| r.value).collect();
        } else {
            aligned.real_target = aligned.real_column(target).unwrap_or_default();
        }
        aligned.sim_target = aligned.sim_column(target).unwrap_or_default();
        aligned.censoring = Censoring::detect(&aligned.real_target, &aligned.sim_target);
        if let Some(censoring) = aligned.censoring {
            aligned.sim_target =
                censoring.simulation_as_read(&aligned.real_target, &aligned.sim_target);
        }
        Ok(aligned)
    }

    /// Number of aligned rows.
    pub fn len(&self) -> usize {
        self.time.len()
    }

    /// True when no rows are aligned (never, after a successful [`Aligned::new`]).
    pub fn is_empty(&self) -> bool {
        self.time.is_empty()
    }

    /// A column of the real recording on the aligned rows (interpolated when the grid is the
    /// simulation's and the instants differ).
    pub fn real_column(&self, name: &str) -> Option<Vec<f64>> {
        Some(interpolate(self.real.try_column(name)?, &self.real_index))
    }

    /// A column of the simulation on the aligned rows (interpolated when the grids differ).
    pub fn sim_column(&self, name: &str) -> Option<Vec<f64>> {
        Some(interpolate(self.sim.try_column(name)?, &self.sim_index))
    }

    /// How far apart the simulated machine's temperatures are at the first aligned row, K:
    /// its windings (`<axis>.stator_temp_C`), its reference temperatures (`ref.*_C`) and its
    /// room (`ambient_C`), but `target`, each at the first row alone (a soaked machine starts
    /// warming at once: a nut sampled every 10 s had risen 0.5 K over its first five rows).
    /// A machine soaked in its room starts with them together; apart, the recording starts
    /// mid-run. The target is left out because it may carry the miscalibration the analysis
    /// is there to find (0.6 K + 1.04 × a soaked winding starts 1.4 K from its room). Only the
    /// simulation's own machine columns count: a simulation without a room may have assumed
    /// any (soaked at a nominal 20 °C in a shop at 23 °C), and a coolant supply or an
    /// estimate is no part of the machine's state. `None` when there are not two
    /// temperatures to compare.
    pub fn simulated_start_spread_k(&self, target: &str) -> Option<f64> {
        let of_the_machine = |name: &str| match Channel::parse(name) {
            Channel::Ambient => true,
            Channel::Servo { quantity, .. } => quantity == Quantity::StatorTemp,
            Channel::Reference { .. } => Channel::unit_of(name) == Some("°C"),
            _ => false,
        };
        let temperatures: Vec<f64> = self
            .sim
            .names()
            .iter()
            .filter(|name| *name != target && of_the_machine(name))
            .filter_map(|name| {
                let first = interpolate(self.sim.try_column(name)?, self.sim_index.get(..1)?);
                first.first().copied().filter(|t| t.is_finite())
            })
            .collect();
        let (lo, hi) = series::span(&temperatures);
        (temperatures.len() >= 2).then_some(hi - lo)
    }

    /// The simulation's own samples of `target`, for what reads the simulated target at
    /// instants other than the rows (a delay), when the simulation was interpolated onto the
    /// real grid at one offset: nearly every row ([`ONE_OFFSET_SHARE`]) lies the same share of
    /// the simulation's step after its sample before. An instant a delay moves onto one of
    /// those samples then reads the sample, which the rows' values, interpolated once
    /// already, would interpolate a second time: between two rows placed on either side of
    /// a torque's step, halfway. `None` on one grid, on the simulation's grid and without
    /// one offset (a jittered trace, a coarser export).
    pub fn simulated_samples(&self, target: &str) -> Option<SimulatedSamples> {
        if self.on_simulation_grid || !self.resampled {
            return None;
        }
        let time = self.sim.time();
        let step_s = self.sim.median_step_s()?;
        // A finer simulation has a sample near every instant: read between two, it loses
        // little, and the delays landing on its samples would be many.
        let real_step_s = self.real.median_step_s()?;
        if step_s < real_step_s * (1.0 - ONE_OFFSET_TOLERANCE) {
            return None;
        }
        let (index, _) = index_onto(time, &self.time, step_s);
        let shares: Vec<f64> = index.iter().map(|&(_, fraction)| fraction).collect();
        if shares.len() < MIN_ROWS {
            return None;
        }
        let offset_share = series::median(&shares);
        let at_offset = shares
            .iter()
            .filter(|s| (*s - offset_share).abs() <= ONE_OFFSET_TOLERANCE)
            .count();
        let between = (CLEARLY_BETWEEN..=1.0 - CLEARLY_BETWEEN).contains(&offset_share);
        (between && at_offset as f64 >= ONE_OFFSET_SHARE * shares.len() as f64).then(|| {
            SimulatedSamples {
                time: time.to_vec(),
                values: self
                    .sim
                    .try_column(target)
                    .map(<[f64]>::to_vec)
                    .unwrap_or_default(),
                on_rows: self.censoring.and_then(|_| self.sim_column(target)),
                offset_s: offset_share * step_s,
                step_s,
            }
        })
    }

    /// What the interpolation did where a speed steps between two samples, after `whose`
    /// speeds placed the instant; empty when it never did.
    fn placed_note(&self, whose: &str) -> String {
        match self.placed_by_speed {
            0 => String::new(),
            rows => format!(
                ", but for {rows} rows that fall inside a step of a speed: there the instant was placed where {whose} speeds put it, before the step, after it or that far through it, since a torque or a current steps with the speed and halfway in time is neither side"
            ),
        }
    }

    /// One sentence on how the two recordings were joined.
    pub fn note(&self) -> String {
        let span = format!(
            "{} rows from {:.1} s to {:.1} s",
            self.len(),
            self.time.first().copied().unwrap_or(0.0),
            self.time.last().copied().unwrap_or(0.0)
        );
        let joined = if self.on_simulation_grid {
            let built = if self.builds_at_real_rate() {
                "the corrections were built on the real recording's own rows and read at those instants"
            } else {
                "the corrections were built at those instants (the real recording has too many rows to build them on its own)"
            };
            format!(
                "the simulation's grid is coarser: the real recording ({} rows) was compared at the simulation's instants (linearly interpolated where they fall between its rows{}), since between its samples the simulation holds nothing to compare; {built}; {span}",
                self.real.len(),
                self.placed_note("the simulation's"),
            )
        } else if self.resampled {
            format!(
                "the time grids differ: the simulation ({} rows) was linearly interpolated onto the real recording's grid{}; {span}",
                self.sim.len(),
                self.placed_note("the real"),
            )
        } else {
            format!("both recordings share the time grid; {span}")
        };
        let averaged: Vec<String> = [("simulation", self.sim), ("real recording", self.real)]
            .iter()
            .filter_map(|(role, recording)| {
                let block = recording.metadata_value(crate::signal::AVERAGED_OVER_S)?;
                Some(format!("the {role} over {block} s blocks"))
            })
            .collect();
        let joined = if averaged.is_empty() {
            joined
        } else {
            format!("read averaged ({}); {joined}", averaged.join(", "))
        };
        let joined = match (self.target_read_later, self.real_step_s()) {
            (later, Some(step)) if later != 0.0 => format!(
                "{joined}; the real target was read {:.2} s later (a delay found on its own samples; the rows are those whose later readings the recording holds)",
                later * step
            ),
            _ => joined,
        };
        // An export of the target alone (as FEA tools write) does not say what room the
        // simulation assumed: the room's corrections then measure the real room from its mean,
        // and a temperature's excess from the real room, which the reader should know.
        let joined = if self.real.try_column(AMBIENT).is_some()
            && self.sim.try_column(AMBIENT).is_none()
        {
            format!(
                "{joined}; the simulation has no {AMBIENT} column, so the room it assumed is unknown: \
                 the room's difference is taken from the real room's mean, and a temperature's \
                 excess over the real room"
            )
        } else {
            joined
        };
        match self.censoring {
            Some(c) if c.standstill_spans == 0 => format!(
                "{joined}; the real target reads exactly {} in {:.1} % of the rows, where the simulation never sits (an instrument that cannot read below it, whose zero lies below the floor there), so those readings are taken as bounds (noise σ = {:.4}, from sample to sample above the floor)",
                c.floor,
                100.0 * c.share_at_floor,
                c.sigma,
            ),
            Some(c) => format!(
                "{joined}; the real target reads exactly {} in {:.1} % of the rows (an instrument that cannot read below it), so the simulation is compared as it would read: in each of the {} stretches where it sits at that floor it is raised by what the floor adds to the mean reading there, leaving the instrument's own level μ in the residual (noise σ = {:.4} about that level){}",
                c.floor,
                100.0 * c.share_at_floor,
                c.standstill_spans,
                c.sigma,
                match c.spans_levelled_beside {
                    0 => String::new(),
                    k => format!(
                        "; for {k} of them (too short, or nearly all at the floor, to show their own level) the readings at the floor are taken at their expected value below it given the level of the running rows beside them"
                    ),
                }
            ),
            None => joined,
        }
    }
}

/// Where each of `times` lies in the increasing `source` times: the row at or before it and
/// the fraction towards the next; and whether any falls between rows (by more than a
/// millionth of `step`).
pub fn index_onto(source: &[f64], times: &[f64], step: f64) -> (Index, bool) {
    let mut index = Vec::with_capacity(times.len());
    let mut j = 0usize;
    let mut resampled = false;
    for &t in times {
        while j + 1 < source.len() && source[j + 1] <= t {
            j += 1;
        }
        let fraction = if j + 1 < source.len() && source[j + 1] > source[j] {
            ((t - source[j]) / (source[j + 1] - source[j])).clamp(0.0, 1.0)
        } else {
            0.0
        };
        if (source[j] - t).abs() > 1e-6 * step.max(1e-9) {
            resampled = true;
        }
        index.push((j, fraction));
    }
    (index, resampled)
}

/// `index` (where each aligned row falls in `source`) with the rows that fall inside a step
/// of a speed placed by the speeds, and how many were. The speeds are the operating program,
/// which a simulation shares with the machine: where one steps between two samples of
/// `source` (a reversal, a move starting), a torque or a current steps with it, and the
/// linear interpolation's halfway value is neither side — on a simulation exported half a
/// sample off the real grid it left the X torque 5–8 × its noise from a machine with nothing
/// left out. There the instant is placed where `other`'s speed at it (its own row, read
/// through `other_index`) falls between the two samples' speeds: before the step, after it
/// (within three noises of either), or that far through a ramp. The speed that steps most
/// (for its range) decides; only speeds of one program guide ([`GuidingSpeed::agrees`]). Elsewhere,
/// and where an instant coincides with a sample but for rounding, the fraction in time
/// stands. How a side is read is `sides`.
fn placed_by_speeds(
    index: Index,
    source: &Recording,
    other: &Recording,
    other_index: &Index,
    sides: Sides,
) -> (Index, usize) {
    let between = |f: f64| f > COINCIDING && f < 1.0 - COINCIDING;
    if !index.iter().any(|&(_, f)| between(f)) {
        return (index, 0);
    }
    let speeds: Vec<GuidingSpeed<'_>> = source
        .names()
        .iter()
        .filter(|name| is_servo_speed(name))
        .filter_map(|name| {
            let own = source.try_column(name)?;
            let others = other.try_column(name)?;
            let (lo, hi) = series::span(own);
            let range = hi - lo;
            if !(range.is_finite() && range > 0.0) {
                return None;
            }
            let speed = GuidingSpeed {
                own,
                at: interpolate(others, other_index),
                noise: noise_while_moving(own).hypot(noise_while_moving(others)),
                range,
            };
            speed.agrees(&index).then_some(speed)
        })
        .collect();
    if speeds.is_empty() {
        return (index, 0);
    }
    let steps_within = |j: usize| speeds.iter().any(|speed| speed.steps_within(j));
    let time = source.time();
    // The fraction of row `from`'s interval at which `t` lies (outside [0, 1] when `t` lies
    // beyond it): the straight line through that interval, extended.
    let along = |from: usize, t: f64| {
        let span = time[from + 1] - time[from];
        (span > 0.0).then(|| (from, (t - time[from]) / span))
    };
    let mut placed = 0;
    let index = index
        .into_iter()
        .enumerate()
        .map(|(row, (j, fraction))| {
            if !between(fraction) || j + 1 >= time.len() {
                return (j, fraction);
            }
            let Some(at) = speeds
                .iter()
                .filter_map(|speed| speed.place(j, row))
                .max_by(|a, b| a.0.total_cmp(&b.0))
                .map(|(_, at)| at)
            else {
                return (j, fraction);
            };
            placed += 1;
            let t = time[j] + fraction * (time[j + 1] - time[j]);
            let extended = match sides {
                Sides::Extended if at == 0.0 && j >= 1 && !steps_within(j - 1) => along(j - 1, t),
                Sides::Extended if at == 1.0 && j + 2 < time.len() && !steps_within(j + 1) => {
                    along(j + 1, t)
                }
                _ => None,
            };
            extended.unwrap_or((j, at))
        })
        .collect();
    (index, placed)
}

/// Share of the rows that must lie at one offset from the simulation's samples for
/// [`Aligned::simulated_samples`]: a real recording's grid, not a jittered one.
const ONE_OFFSET_SHARE: f64 = 0.9;

/// How far (a share of the simulation's step) a row's offset may be from the others' to
/// count as the same, and an instant from a sample to read it: time stamps written to a
/// tenth of a millisecond on a 1 s grid.
const ONE_OFFSET_TOLERANCE: f64 = 1e-3;

/// How far (a share of the simulation's step) the one offset must be from a sample for
/// [`Aligned::simulated_samples`]: a hundredth of a step off, the rows' line loses nearly
/// nothing and the landing delays would nearly repeat the whole ones.
const CLEARLY_BETWEEN: f64 = 0.05;

/// The simulation's own samples of a target, for reading it at instants off the aligned rows
/// ([`Aligned::simulated_samples`]).
#[derive(Debug, Clone)]
pub struct SimulatedSamples {
    time: Vec<f64>,
    values: Vec<f64>,
    /// Where the simulation is compared as a censored instrument reads it
    /// ([`Censoring::simulation_as_read`]): its values on the aligned rows before that
    /// reading. `None` where the compared values are these.
    pub on_rows: Option<Vec<f64>>,
    /// How far each aligned row lies after the simulation's sample before it, s.
    pub offset_s: f64,
    /// The simulation's step, s.
    pub step_s: f64,
}

impl SimulatedSamples {
    /// Whether a delay of `delay_s` moves the rows onto the samples: it is the offset and a
    /// whole number of steps.
    pub fn lands_on_samples(&self, delay_s: f64) -> bool {
        let steps = (delay_s - self.offset_s) / self.step_s;
        (steps - steps.round()).abs() <= ONE_OFFSET_TOLERANCE
    }

    /// The simulated target at each of `instants` (increasing) that is one of its samples
    /// (within [`ONE_OFFSET_TOLERANCE`] of its step, the tolerance the offset was found
    /// with); `None` between them.
    pub fn at_each(&self, instants: impl Iterator<Item = f64>) -> Vec<Option<f64>> {
        let tolerance = ONE_OFFSET_TOLERANCE * self.step_s;
        let mut after = 0usize;
        instants
            .map(|instant| {
                while self.time.get(after).is_some_and(|&s| s < instant) {
                    after += 1;
                }
                [after.checked_sub(1), Some(after)]
                    .into_iter()
                    .flatten()
                    .find(|&j| {
                        self.time
                            .get(j)
                            .is_some_and(|s| (s - instant).abs() <= tolerance)
                    })
                    .and_then(|j| self.values.get(j).copied())
            })
            .collect()
    }

    /// The simulated target at `instant` when it is one of its samples ([`Self::at_each`]).
    #[cfg(test)]
    fn at(&self, instant: f64) -> Option<f64> {
        self.at_each(std::iter::once(instant)).pop().flatten()
    }
}

/// A fraction this close to 0 or 1 is an instant on a sample but for rounding (a grid of
/// 0.30000000000000004 s against one of 0.3 s): it stays where it is.
const COINCIDING: f64 = 1e-6;

/// An instant within this many noises of a step's side speed is on that side.
const SIDE_NOISES: f64 = 3.0;

/// Fewest moving rows on which two recordings' speeds must be compared to guide.
const MIN_MOVING_ROWS: usize = 30;

/// A speed of the interpolated recording that may place instants ([`placed_by_speeds`]).
struct GuidingSpeed<'a> {
    /// Its samples in the interpolated recording.
    own: &'a [f64],
    /// The other recording's speed at the aligned rows.
    at: Vec<f64>,
    /// The two recordings' speed noise together.
    noise: f64,
    /// Its range in the interpolated recording.
    range: f64,
}

impl GuidingSpeed<'_> {
    /// Whether it changes between samples `j` and `j + 1` beyond what its noise explains.
    fn steps_within(&self, j: usize) -> bool {
        matches!((self.own.get(j), self.own.get(j + 1)), (Some(a), Some(b)) if (b - a).abs() > SPEED_STEP_NOISES * self.noise)
    }

    /// Where aligned row `row` (between samples `j` and `j + 1`) falls in a step there: how
    /// much it steps for its range, and the fraction; `None` without a step.
    fn place(&self, j: usize, row: usize) -> Option<(f64, f64)> {
        let (before, after) = (*self.own.get(j)?, *self.own.get(j + 1)?);
        let there = *self.at.get(row)?;
        if !self.steps_within(j) {
            return None;
        }
        let side = SIDE_NOISES * self.noise;
        let at = if (there - before).abs() <= side {
            0.0
        } else if (there - after).abs() <= side {
            1.0
        } else {
            ((there - before) / (after - before)).clamp(0.0, 1.0)
        };
        Some(((after - before).abs() / self.range, at))
    }

    /// Whether the two recordings' speeds are one program: on at least [`SPEED_AGREEMENT`]
    /// of the aligned rows where this one moves and holds steady across its interval (and at
    /// least [`MIN_MOVING_ROWS`] of them) they read the same within ten noises or a hundredth
    /// of the range. Rows at rest say nothing (0 rpm is 0 rpm in any convention); a speed of
    /// the other sign or scale (another convention, a motor's speed against a spindle's) or
    /// of another program cannot say where an instant falls.
    fn agrees(&self, index: &Index) -> bool {
        let tolerance = (SPEED_STEP_NOISES * self.noise).max(0.01 * self.range);
        let (moving, agreeing) = index
            .iter()
            .zip(&self.at)
            .filter_map(|(&(j, _), &there)| {
                let before = *self.own.get(j)?;
                let steady = !self.steps_within(j);
                (steady && before.abs() > tolerance).then(|| (there - before).abs() <= tolerance)
            })
            .fold((0usize, 0usize), |(n, k), agrees| {
                (n + 1, k + usize::from(agrees))
            });
        moving >= MIN_MOVING_ROWS && agreeing as f64 >= SPEED_AGREEMENT * moving as f64
    }
}

/// Share of the steady moving rows on which two recordings' speeds must agree to place
/// instants ([`GuidingSpeed::agrees`]): a transport delay makes the real speed disagree for
/// its length after every change, which leaves most rows of a run agreeing.
const SPEED_AGREEMENT: f64 = 0.9;

/// How [`placed_by_speeds`] reads an instant it places before or after a step.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Sides {
    /// At that side's sample: a measured recording, whose noise a line through two of its
    /// samples, extended, would amplify.
    Held,
    /// On the line through that side's own interval, extended to the instant, where that
    /// interval has no step of a speed (and, column by column, the column moves steadily
    /// there: [`interpolate`]): a simulation's values are exact, and what moves steadily on
    /// each side (a preload's drag along the stroke at the end it reverses) is read at the
    /// instant instead of a sample away.
    Extended,
}

/// Whether a column is a servo axis's speed (one that may place instants).
fn is_servo_speed(name: &str) -> bool {
    matches!(
        Channel::parse(name),
        Channel::Servo {
            quantity: Quantity::Speed,
            ..
        }
    )
}

/// A speed's white noise (σ) from its sample-to-sample differences while it moves (both
/// samples off zero): a drive that reports exactly 0 at rest would otherwise, resting more
/// than half the time, read as noiseless. All differences where it hardly moves; 0 for a
/// speed held exactly between changes (a commanded speed, a noise-free simulation).
fn noise_while_moving(values: &[f64]) -> f64 {
    let moving: Vec<f64> = values
        .windows(2)
        .filter(|w| w[0] != 0.0 && w[1] != 0.0)
        .map(|w| w[1] - w[0])
        .collect();
    if moving.len() >= MIN_MOVING_ROWS {
        white_noise_of_steps(moving)
    } else {
        white_noise_of_steps(values.windows(2).map(|w| w[1] - w[0]).collect())
    }
}

/// `column` read at `index` by linear interpolation. A fraction outside [0, 1] (an instant
/// [`placed_by_speeds`] put on one side of a step, read on the line through that side's own
/// interval) is extended only where the column moves steadily on that side: its change
/// across that interval is at most twice its change across the next one out. Where it is
/// more (a load that steps in that interval, with no step of a speed to show it) the side's
/// sample is read.
pub fn interpolate(column: &[f64], index: &[(usize, f64)]) -> Vec<f64> {
    let steady = |change: f64, next_out: Option<f64>| {
        next_out.is_some_and(|out| change.abs() <= 2.0 * out.abs())
    };
    index
        .iter()
        .map(|&(j, f)| {
            let Some(&next) = column.get(j + 1) else {
                return column[j];
            };
            let change = next - column[j];
            let value = column[j] + f * change;
            if f > 1.0 {
                // The line through the side before the step, whose outer neighbour ends at j.
                let out = j
                    .checked_sub(1)
                    .and_then(|i| column.get(i))
                    .map(|b| column[j] - b);
                if steady(change, out) { value } else { next }
            } else if f < 0.0 {
                // The line through the side after the step, whose outer neighbour starts at j + 1.
                let out = column.get(j + 2).map(|after| after - next);
                if steady(change, out) {
                    value
                } else {
                    column[j]
                }
            } else {
                value
            }
        })
        .collect()
}

fn describe_span(recording: &Recording) -> String {
    match (recording.time().first(), recording.time().last()) {
        (Some(a), Some(b)) => format!("{} covers {a} s to {b} s", recording.source()),
        _ => format!("{} has no rows", recording.source()),
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A recording of `columns`, 100 rows a second apart, each column's value `value(name, t)`.
    fn recording(columns: &[&str], value: impl Fn(&str, f64) -> f64) -> Recording {
        let mut names = vec!["time_s".to_string()];
        names.extend(columns.iter().map(|c| c.to_string()));
        let mut recording = Recording::new("test", names).expect("a valid header");
        for i in 0..100 {
            let t = i as f64;
            let mut row = vec![t];
            row.extend(columns.iter().map(|c| value(c, t)));
            recording.push_row(&row).expect("a valid row");
        }
        recording
    }

    #[test]
    fn the_real_target_is_read_later_on_its_own_samples() {
        // A real torque (t²/4) every second, a simulation every five, over 400 s.
        let header = || vec!["time_s".to_string(), "X.torque_Nm".to_string()];
        let mut real = Recording::new("real", header()).expect("a valid header");
        for i in 0..400 {
            let t = i as f64;
            real.push_row(&[t, t * t / 4.0]).expect("a valid row");
        }
        let mut sim_long = Recording::new("sim", header()).expect("a valid header");
        for i in (0..400).step_by(5) {
            sim_long.push_row(&[i as f64, 0.0]).expect("a valid row");
        }
        let aligned = Aligned::new(&sim_long, &real, "X.torque_Nm").expect("aligned");
        assert!(aligned.on_simulation_grid);
        let later = aligned
            .real_target_later("X.torque_Nm", 3.0, true)
            .expect("the target");
        // Whole samples later: the sample itself, nothing averaged.
        assert_eq!(
            later[2],
            Some(Reading {
                value: 13.0 * 13.0 / 4.0,
                averaged: 0.0
            })
        );
        assert_eq!(later[79].map(|r| r.value), Some(398.0 * 398.0 / 4.0));
        // Past the recording's end there is nothing to read.
        let past = aligned
            .real_target_later("X.torque_Nm", 5.0, true)
            .expect("the target");
        assert_eq!(past[79], None);
        // A fraction later: on the line between the samples, half of a sample's white noise
        // averaged away at halfway.
        let between = aligned
            .real_target_later("X.torque_Nm", -1.5, false)
            .expect("the target");
        assert_eq!(between[0], None);
        assert_eq!(
            between[1],
            Some(Reading {
                value: (3.0 * 3.0 + 4.0 * 4.0) / 8.0,
                averaged: 0.5
            })
        );

        let read = Aligned::read_later(&sim_long, &real, "X.torque_Nm", 3.0).expect("aligned");
        // Only the rows whose later samples the recording holds.
        assert_eq!(read.time.first(), Some(&0.0));
        assert_eq!(read.time.last(), Some(&395.0));
        assert_eq!(read.len(), 80);
        let earlier = Aligned::read_later(&sim_long, &real, "X.torque_Nm", -7.5).expect("aligned");
        assert_eq!(earlier.time.first(), Some(&10.0));
        assert_eq!(earlier.real_target[0], (2.0 * 2.0 + 3.0 * 3.0) / 8.0);
        assert_eq!(earlier.recorded_target.as_ref().map(|r| r[0]), Some(25.0));
        // Across a gap in the recording, so many samples later is not so much later.
        let mut gapped = Recording::new("real", header()).expect("a valid header");
        for i in (0..400).filter(|i| !(200..210).contains(i)) {
            let t = i as f64;
            gapped.push_row(&[t, t * t / 4.0]).expect("a valid row");
        }
        let aligned = Aligned::new(&sim_long, &gapped, "X.torque_Nm").expect("aligned");
        let later = aligned
            .real_target_later("X.torque_Nm", 3.0, true)
            .expect("the target");
        let at = |t: f64| aligned.time.iter().position(|&r| r == t).expect("a row");
        assert_eq!(later[at(200.0)], None);
        assert_eq!(later[at(205.0)], None);
        assert_eq!(later[at(195.0)].map(|r| r.value), Some(198.0 * 198.0 / 4.0));
        assert_eq!(later[at(210.0)].map(|r| r.value), Some(213.0 * 213.0 / 4.0));
        assert_eq!(read.real_target[1], 8.0 * 8.0 / 4.0);
        assert_eq!(
            read.recorded_target.as_ref().map(|r| r[1]),
            Some(5.0 * 5.0 / 4.0)
        );
        assert!(
            Aligned::new(&sim_long, &real, "X.torque_Nm")
                .expect("aligned")
                .recorded_target
                .is_none()
        );
    }

    #[test]
    fn a_reading_between_two_samples_across_a_reversal_is_placed_on_the_rows_side() {
        // The axis reverses 0.3 s after every tenth second; its torque follows the direction
        // and is measured 2.5 s late, every second. The simulation: every five seconds.
        let speed = |t: f64| {
            if ((t - 0.3) / 10.0).floor() as i64 % 2 == 0 {
                100.0
            } else {
                -100.0
            }
        };
        let torque = |t: f64| speed(t) / 100.0;
        let header = || {
            ["time_s", "X.speed_rpm", "X.torque_Nm"]
                .map(String::from)
                .to_vec()
        };
        let mut real = Recording::new("real", header()).expect("a valid header");
        for i in 0..400 {
            let t = i as f64;
            real.push_row(&[t, speed(t), torque(t - 2.5)])
                .expect("a valid row");
        }
        let mut sim = Recording::new("sim", header()).expect("a valid header");
        for i in (0..400).step_by(5) {
            let t = i as f64;
            sim.push_row(&[t, speed(t), torque(t)])
                .expect("a valid row");
        }
        let aligned = Aligned::new(&sim, &real, "X.torque_Nm").expect("aligned");
        let read = |placed| {
            aligned
                .real_target_later("X.torque_Nm", 2.5, placed)
                .expect("the target")
        };
        let (plain, placed) = (read(false), read(true));
        let mut reversals = 0;
        for (row, &t) in aligned.time.iter().enumerate() {
            let Some(reading) = placed[row] else {
                continue;
            };
            // Placed, every row reads the torque the machine had at its instant.
            assert_eq!(reading.value, torque(t), "placed at {t} s");
            if t as i64 % 10 == 0 && t > 0.0 {
                // 0.3 s before a reversal: the two samples around 2.5 s later straddle it.
                reversals += 1;
                assert_eq!(plain[row].map(|r| r.value), Some(0.0), "plain at {t} s");
                assert_eq!(reading.averaged, 0.0);
            }
        }
        assert!(reversals >= 30, "{reversals}");
    }

    #[test]
    fn a_machine_soaked_in_its_room_starts_together_and_a_warm_one_apart() {
        let columns = ["ambient_C", "S.stator_temp_C", "ref.S.front_bearing_temp_C"];
        let soaked = recording(&columns, |c, t| match c {
            "S.stator_temp_C" => 20.0 + 0.01 * t,
            _ => 20.0,
        });
        let spread_on = |sim: &Recording, real: &Recording, target: &str| {
            let aligned = Aligned::new(sim, real, target).expect("aligned");
            aligned.simulated_start_spread_k(target)
        };
        let bearing = "ref.S.front_bearing_temp_C";
        let spread = spread_on(&soaked, &soaked, bearing).expect("three temperatures");
        assert!(spread < 0.05, "soaked: {spread} K");

        // An hour into a run: the winding 4 K and the bearing 2 K above the room.
        let warm = recording(&columns, |c, _| match c {
            "S.stator_temp_C" => 24.0,
            "ref.S.front_bearing_temp_C" => 22.0,
            _ => 20.0,
        });
        assert_eq!(spread_on(&warm, &warm, bearing), Some(4.0));
        // The target's own start says nothing: a miscalibrated winding is not a warm one.
        assert_eq!(spread_on(&warm, &warm, "S.stator_temp_C"), Some(2.0));
        let miscalibrated = recording(&columns, |c, _| match c {
            "S.stator_temp_C" => 18.6,
            _ => 20.0,
        });
        assert_eq!(
            spread_on(&miscalibrated, &soaked, "S.stator_temp_C"),
            Some(0.0)
        );

        // A simulation without a room may have assumed any: its own temperatures alone
        // count, not the real room.
        let without_room = recording(&["S.stator_temp_C", bearing], |_, _| 24.0);
        assert_eq!(spread_on(&without_room, &soaked, bearing), None);
        let apart = recording(&["S.stator_temp_C", "X.stator_temp_C", bearing], |c, _| {
            if c == "X.stator_temp_C" { 21.0 } else { 24.0 }
        });
        assert_eq!(spread_on(&apart, &apart, bearing), Some(3.0));
        // A coolant supply or an estimate is no part of the machine's state.
        let supply = recording(&["ambient_C", "coolant_supply_C", bearing], |c, _| {
            if c == "coolant_supply_C" { 14.0 } else { 20.0 }
        });
        assert_eq!(spread_on(&supply, &supply, bearing), None);
    }

    /// A feed axis's recording of `rows`: time (s), `X.speed_rpm`, `X.torque_Nm`.
    fn axis_recording(rows: impl IntoIterator<Item = [f64; 3]>) -> Recording {
        let names = ["time_s", "X.speed_rpm", "X.torque_Nm"]
            .map(String::from)
            .to_vec();
        let mut recording = Recording::new("axis", names).expect("a valid header");
        for row in rows {
            recording.push_row(&row).expect("a valid row");
        }
        recording
    }

    /// The direction (±1) at `t` of a feed axis that reverses every 7 s from 0 s on (and
    /// before it).
    pub(crate) fn direction_at(t: f64) -> f64 {
        if (t.floor() as i64).div_euclid(7) % 2 == 0 {
            1.0
        } else {
            -1.0
        }
    }

    /// A feed axis reversing every 7 s ([`direction_at`]), as a zero-order hold would record
    /// it at `times`: its speed ±300 rpm and its torque `torque(direction, t)`, which steps
    /// with the direction.
    pub(crate) fn reversing_axis(
        times: impl Iterator<Item = f64>,
        speed_noise: f64,
        torque: impl Fn(f64, f64) -> f64,
    ) -> Recording {
        axis_recording(times.enumerate().map(|(k, t)| {
            let direction = direction_at(t);
            // A deterministic ripple standing in for the speed's noise, half the reversals
            // reading inside the step.
            let ripple = speed_noise * [1.0, -1.0, -0.5, 0.5][k % 4];
            [t, 300.0 * direction + ripple, torque(direction, t)]
        }))
    }

    /// ±0.5 N·m, the same at every point of the stroke.
    fn plain(direction: f64, _: f64) -> f64 {
        0.5 * direction
    }

    #[test]
    fn a_simulation_half_a_sample_off_the_grid_is_taken_on_the_side_of_a_step_the_speed_shows() {
        let real = reversing_axis((0..200).map(f64::from), 2.0, plain);
        let sim = reversing_axis((0..200).map(|k| f64::from(k) + 0.5), 0.0, plain);
        let aligned = Aligned::new(&sim, &real, "X.torque_Nm").expect("aligned");
        assert!(aligned.resampled);
        // Every reversal falls between two of the simulation's samples.
        assert_eq!(aligned.placed_by_speed, 28);
        // As far through the step as the real speed, with its noise, shows: within a
        // hundredth of it.
        for (got, want) in aligned.sim_target.iter().zip(&aligned.real_target) {
            assert!((got - want).abs() < 0.01, "{got} against {want}");
        }
        assert!(
            aligned
                .note()
                .contains("28 rows that fall inside a step of a speed")
        );

        // Linearly in time, each reversal's row would read 0 N·m, neither side.
        let (index, _) = index_onto(sim.time(), &aligned.time, 1.0);
        let torque = sim.try_column("X.torque_Nm").expect("the torque");
        let linear = interpolate(torque, &index);
        assert_eq!(linear.iter().filter(|v| v.abs() < 1e-12).count(), 28);

        // What moves steadily on each side of a reversal (a drag that grows along the stroke)
        // is read at the instant, on the line through that side's own samples.
        let drag = |direction: f64, t: f64| direction * (0.5 + 0.01 * t);
        // The real speed's noise (±2 rpm) does not keep an instant off its side.
        let real = reversing_axis((0..200).map(f64::from), 2.0, drag);
        let sim = reversing_axis((0..200).map(|k| f64::from(k) + 0.5), 0.0, drag);
        let aligned = Aligned::new(&sim, &real, "X.torque_Nm").expect("aligned");
        assert_eq!(aligned.placed_by_speed, 28);
        for (got, want) in aligned.sim_target.iter().zip(&aligned.real_target) {
            assert!((got - want).abs() < 1e-9, "{got} against {want}");
        }
    }

    #[test]
    fn a_simulation_at_one_offset_from_the_real_grid_keeps_its_own_samples() {
        let real = reversing_axis((0..200).map(f64::from), 2.0, plain);
        let sim = reversing_axis((0..200).map(|k| f64::from(k) + 0.5), 0.0, plain);
        let aligned = Aligned::new(&sim, &real, "X.torque_Nm").expect("aligned");
        let samples = aligned
            .simulated_samples("X.torque_Nm")
            .expect("every row half a step after a sample");
        assert!((samples.offset_s - 0.5).abs() < 1e-9);
        assert_eq!(samples.step_s, 1.0);
        // 7.5 s is a sample (the reverse stroke's first), 7.3 s is not.
        assert_eq!(samples.at(7.5), Some(-0.5));
        assert_eq!(samples.at(7.5 + 1e-9), Some(-0.5));
        assert_eq!(samples.at(7.3), None);
        assert_eq!(samples.at(6.5), Some(0.5));

        let none_kept = |sim: &Recording| {
            let aligned = Aligned::new(sim, &real, "X.torque_Nm").expect("aligned");
            aligned.resampled && aligned.simulated_samples("X.torque_Nm").is_none()
        };
        // On one grid there is nothing between the samples to read.
        let aligned = Aligned::new(&real, &real, "X.torque_Nm").expect("aligned");
        assert!(aligned.simulated_samples("X.torque_Nm").is_none());
        // Nor under a trace whose samples were taken at no one offset (jittered by up to
        // ±0.1 s).
        let jittered = reversing_axis(
            (0..200).map(|k| f64::from(k) + 0.1 * [0.3, -0.7, 0.9, -0.2, 0.5][k as usize % 5]),
            2.0,
            plain,
        );
        let aligned = Aligned::new(&sim, &jittered, "X.torque_Nm").expect("aligned");
        assert!(aligned.simulated_samples("X.torque_Nm").is_none());
        // Nor from a finer simulation (every half second, a quarter off), which has a sample
        // near every instant, nor from one a hundredth of a step off, nor where the
        // simulation's coarser grid is the compared one.
        let finer = reversing_axis((0..400).map(|k| 0.5 * f64::from(k) + 0.25), 0.0, plain);
        assert!(none_kept(&finer));
        let nearly = reversing_axis((0..200).map(|k| f64::from(k) + 0.01), 0.0, plain);
        assert!(none_kept(&nearly));
        let coarse = reversing_axis((0..100).map(|k| 2.0 * f64::from(k) + 0.5), 0.0, plain);
        assert!(Aligned::new(&coarse, &real, "X.torque_Nm").is_ok_and(|a| a.on_simulation_grid));
        assert!(none_kept(&coarse));
    }

    #[test]
    fn a_speed_that_moves_within_its_noise_places_nothing() {
        // The real speed's noise (up to ±200 rpm, σ over 100 rpm from its differences) puts
        // ten noises beyond the steps (300 → −300): it cannot say where an instant falls,
        // and the interpolation stays linear.
        let real = reversing_axis((0..200).map(f64::from), 200.0, plain);
        let sim = reversing_axis((0..200).map(|k| f64::from(k) + 0.5), 0.0, plain);
        let aligned = Aligned::new(&sim, &real, "X.torque_Nm").expect("aligned");
        assert_eq!(aligned.placed_by_speed, 0);
        assert!(!aligned.note().contains("step of a speed"));
    }

    #[test]
    fn a_speed_of_another_sign_or_scale_places_nothing() {
        let sim = reversing_axis((0..200).map(|k| f64::from(k) + 0.5), 0.0, plain);
        let real = reversing_axis((0..200).map(f64::from), 0.0, plain);
        for factor in [-1.0, 3.0] {
            // The same run, its speed written in another convention (the other sign, or the
            // spindle's speed behind a 1 : 3 gear).
            let other = axis_recording((0..real.len()).map(|row| {
                let value = |name: &str| real.try_column(name).expect("a column")[row];
                [
                    value("time_s"),
                    factor * value("X.speed_rpm"),
                    value("X.torque_Nm"),
                ]
            }));
            let aligned = Aligned::new(&sim, &other, "X.torque_Nm").expect("aligned");
            assert_eq!(aligned.placed_by_speed, 0, "speed × {factor}");
        }

        // An axis at rest nine tenths of the time reads 0 rpm in any convention: its rows at
        // rest say nothing, and the moves, of the other sign, place nothing.
        let mostly_at_rest = |times: &mut dyn Iterator<Item = f64>, sign: f64| {
            axis_recording(times.map(|t| {
                let direction = match t.floor() as i64 % 40 {
                    0..=1 => 1.0,
                    2..=3 => -1.0,
                    _ => 0.0,
                };
                [t, sign * 300.0 * direction, 0.5 * direction]
            }))
        };
        let sim = mostly_at_rest(&mut (0..4000).map(|k| f64::from(k) + 0.5), 1.0);
        let real = mostly_at_rest(&mut (0..4000).map(f64::from), -1.0);
        let aligned = Aligned::new(&sim, &real, "X.torque_Nm").expect("aligned");
        assert_eq!(aligned.placed_by_speed, 0);
        // The same run in one convention places every move's start, reversal and stop (but
        // the first start, before the simulation's first sample).
        let real = mostly_at_rest(&mut (0..4000).map(f64::from), 1.0);
        let aligned = Aligned::new(&sim, &real, "X.torque_Nm").expect("aligned");
        assert_eq!(aligned.placed_by_speed, 299);
    }

    #[test]
    fn an_instant_on_a_sample_but_for_rounding_stays_there() {
        // Row k of either recording: the axis reverses every 25 rows.
        let direction = |k: usize| {
            if (k / 25).is_multiple_of(2) {
                1.0
            } else {
                -1.0
            }
        };
        let axis = |times: &[f64], speed_row: &dyn Fn(usize) -> usize| {
            axis_recording(
                times
                    .iter()
                    .enumerate()
                    .map(|(k, t)| [*t, 300.0 * direction(speed_row(k)), 0.5 * direction(k)]),
            )
        };
        // Times summed 0.3 s at a time drift off k · 0.3 by rounding alone.
        let exact: Vec<f64> = (0..200u32).map(|k| f64::from(k) * 0.3).collect();
        let summed: Vec<f64> = exact
            .iter()
            .scan(0.0, |t, _| {
                let now = *t;
                *t += 0.3;
                Some(now)
            })
            .collect();
        assert_ne!(summed, exact);
        let sim = axis(&summed, &|k| k);
        // The real speed reads a sample late: placed, every reversal would be read a sample
        // early.
        let real = axis(&exact, &|k| k.saturating_sub(1));
        let aligned = Aligned::new(&sim, &real, "X.torque_Nm").expect("aligned");
        assert_eq!(aligned.placed_by_speed, 0);
        for (got, want) in aligned.sim_target.iter().zip(&aligned.real_target) {
            assert!((got - want).abs() < 1e-9, "{got} against {want}");
        }
    }
}
