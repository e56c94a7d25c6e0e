//! Alignment: the real recording's time grid inside the overlap of both recordings, with the
//! simulation interpolated onto it when the grids differ.

use super::DiscrepancyError;
use super::censor::Censoring;
use crate::signal::Recording;

/// Fewest overlapping rows an analysis accepts.
pub const MIN_ROWS: usize = 60;

/// The two recordings joined on `time_s`.
#[derive(Debug)]
pub struct Aligned<'a> {
    real: &'a Recording,
    sim: &'a Recording,
    /// First and one-past-last real row inside the overlap.
    rows: std::ops::Range<usize>,
    /// For each aligned row: the sim row at or before it and the fraction towards the next.
    sim_index: Vec<(usize, f64)>,
    /// True when the simulation had to be interpolated onto the real grid.
    pub resampled: bool,
    /// Time of every aligned row, s.
    pub time: Vec<f64>,
    /// The real target.
    pub real_target: Vec<f64>,
    /// The simulated target on the real grid — as the real instrument would read it when the
    /// real recording is censored at a floor (see [`Censoring`]).
    pub sim_target: Vec<f64>,
    /// The real target's floor and the noise cut off there, when it has one.
    pub censoring: Option<Censoring>,
}

impl<'a> Aligned<'a> {
    /// Joins `sim` and `real` on time for `target`.
    pub fn new(
        sim: &'a Recording,
        real: &'a Recording,
        target: &str,
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
        let start = s0.max(r0);
        let end = s1.min(r1);
        if end < start {
            return Err(DiscrepancyError::NoOverlap {
                sim: describe_span(sim),
                real: describe_span(real),
            });
        }
        let first = rt.partition_point(|&t| t < start);
        let last = rt.partition_point(|&t| t <= end);
        let rows = first..last;
        if rows.len() < MIN_ROWS {
            return Err(DiscrepancyError::TooShort {
                rows: rows.len(),
                needed: MIN_ROWS,
            });
        }
        let time: Vec<f64> = rt[rows.clone()].to_vec();
        let step = real.median_step_s().unwrap_or(1.0);
        let mut sim_index = Vec::with_capacity(time.len());
        let mut j = 0usize;
        let mut resampled = false;
        for &t in &time {
            while j + 1 < st.len() && st[j + 1] <= t {
                j += 1;
            }
            let fraction = if j + 1 < st.len() && st[j + 1] > st[j] {
                ((t - st[j]) / (st[j + 1] - st[j])).clamp(0.0, 1.0)
            } else {
                0.0
            };
            if (st[j] - t).abs() > 1e-6 * step.max(1e-9) {
                resampled = true;
            }
            sim_index.push((j, fraction));
        }
        let mut aligned = Aligned {
            real,
            sim,
            rows,
            sim_index,
            resampled,
            time,
            real_target: Vec::new(),
            sim_target: Vec::new(),
            censoring: None,
        };
        aligned.real_target = aligned.real_column(target).unwrap_or_default();
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

    /// A column of the real recording on the aligned rows.
    pub fn real_column(&self, name: &str) -> Option<Vec<f64>> {
        self.real
            .try_column(name)
            .map(|c| c[self.rows.clone()].to_vec())
    }

    /// A column of the simulation on the aligned rows (interpolated when the grids differ).
    pub fn sim_column(&self, name: &str) -> Option<Vec<f64>> {
        let column = self.sim.try_column(name)?;
        Some(
            self.sim_index
                .iter()
                .map(|&(j, f)| {
                    if f > 0.0 && j + 1 < column.len() {
                        column[j] + f * (column[j + 1] - column[j])
                    } else {
                        column[j]
                    }
                })
                .collect(),
        )
    }

    /// One sentence on how the two recordings were joined.
    pub fn note(&self) -> String {
        let span = format!(
            "{} rows from {:.1} s to {:.1} s",
            self.len(),
            self.time.first().copied().unwrap_or(0.0),
            self.time.last().copied().unwrap_or(0.0)
        );
        let joined = if self.resampled {
            format!(
                "the time grids differ: the simulation ({} rows) was linearly interpolated onto the real recording's grid; {span}",
                self.sim.len()
            )
        } else {
            format!("both recordings share the time grid; {span}")
        };
        match self.censoring {
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

fn describe_span(recording: &Recording) -> String {
    match (recording.time().first(), recording.time().last()) {
        (Some(a), Some(b)) => format!("{} covers {a} s to {b} s", recording.source()),
        _ => format!("{} has no rows", recording.source()),
    }
}
