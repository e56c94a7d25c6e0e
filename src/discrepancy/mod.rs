//! Sim-vs-real discrepancy: locate where a simulation and a real recording disagree on a
//! target, say which physics the simulation left out, model it with fitted parameters, and show
//! the fit improve out of sample.
//!
//! The pipeline ([`analyse`]):
//! 1. [`align`]: join on `time_s` (interpolating the simulation when the grids differ);
//!    the residual is real − sim.
//! 2. [`library`]: every vocabulary id as a parametric correction built from the real
//!    recording's signals and the simulated target (first-order lags with fitted τ, estimated
//!    delays, friction signatures), plus a gain miscalibration that competes with them.
//! 3. [`select`]: stepwise, scored by time-blocked cross-validation ([`cv`]) and tested against
//!    phase-randomised surrogates of the residual (max gain over the whole library), so neither
//!    autocorrelated noise nor the size of the library produce false discoveries. The offset is
//!    always absorbed; a gain is reported as calibration, never as physics.
//! 4. Refit on all rows with refined parameters; before/after R² and RMSE, the after figures on
//!    held-out time blocks.
//! 5. [`localise`]: mismatch regions against a noise floor taken from the held-out residual,
//!    with the operating conditions there and where the simulation is right.
//!
//! [`analyse_observed`] runs the same analysis under an [`Observer`] that hears how far it has
//! got and can stop it (an HMI's progress bar and Cancel button); [`analyse`] runs it unwatched.
//!
//! ```no_run
//! use servosight::discrepancy::{Options, analyse};
//! use servosight::signal::read_recording;
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! let sim = read_recording("sim.csv".as_ref())?;
//! let real = read_recording("real.csv".as_ref())?;
//! let report = analyse(&sim, &real, "S.stator_temp_C", &Options::default())?;
//! println!("{}", report.summary());
//! # Ok(())
//! # }
//! ```

pub mod align;
pub mod budget;
pub mod censor;
pub mod cut_off_refit;
pub mod cv;
pub mod kept;
pub mod library;
pub mod localise;
pub mod real_delay;
pub mod report;
pub mod select;
pub mod series;

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};

pub use budget::{RowBudget, peak_memory_bytes};
pub use library::Physics;
pub use localise::Region;
pub use report::{
    Alignment, Alternative, Calibration, DiscrepancyReport, Finding, FitQuality,
    JUDGED_AFTER_REFIT, JUDGED_ON_BOUNDS, Method, NoiseFloor, NotTested, PlotData,
    ReadingsAsBounds, StepTrace, Verdict,
};

use crate::fit::autocorrelation::{white_noise_from_differences, white_noise_of_steps};
use crate::parallel::{join_or_resume, parallel_map};
use align::Aligned;
use cut_off_refit::{CUT_OFF_MIN_GAIN, CutOffReadings};
use cv::{Blocks, ModelGram, NormalEquations, TargetProducts, TargetStats, least_squares};
use library::{Context, Family, InheritedAlso, Kind, WindingCause, families};
use real_delay::RealDelay;
use select::{JointModel, Member, Problem, Step, Store, stepwise};
use series::{bin_means, bin_ranges, integrated_autocorrelation, mean};

/// Why an analysis could not run.
#[derive(Debug, thiserror::Error)]
pub enum DiscrepancyError {
    /// The target column is missing from one of the recordings.
    #[error("the target `{target}` is not a column of the {role} {source_name}")]
    MissingTarget {
        /// "simulation" or "real recording".
        role: &'static str,
        /// The file.
        source_name: String,
        /// The target.
        target: String,
    },
    /// The recordings do not overlap in time.
    #[error("the recordings do not overlap in time: {sim}; {real}")]
    NoOverlap {
        /// The simulation's span.
        sim: String,
        /// The real recording's span.
        real: String,
    },
    /// A recording whose rows all carry one time stamp: it has no time grid to analyse on.
    #[error("the {role} {source_name} does not advance in time: every row has the same time stamp")]
    TimeStalls {
        /// "simulation" or "real recording".
        role: &'static str,
        /// The recording's source.
        source_name: String,
    },
    /// Too few overlapping rows for a time-blocked analysis.
    #[error("only {rows} rows overlap in time; the analysis needs at least {needed}")]
    TooShort {
        /// Rows in the overlap.
        rows: usize,
        /// Rows needed.
        needed: usize,
    },
    /// A recording has more rows than the analysis takes ([`MAX_ROWS`]).
    #[error(
        "the {role} {source_name} has {rows} rows; the analysis takes at most {limit} of each \
         recording (it holds each of its candidate corrections at full rate, about 2 kB a row) \
         — average it over longer blocks of time first"
    )]
    TooManyRows {
        /// "simulation" or "real recording".
        role: &'static str,
        /// The file.
        source_name: String,
        /// Its rows.
        rows: usize,
        /// [`MAX_ROWS`].
        limit: usize,
    },
    /// An option is out of range.
    #[error("invalid option {name} = {value}: {requirement}")]
    InvalidOption {
        /// The option.
        name: &'static str,
        /// Its value.
        value: f64,
        /// What it must be.
        requirement: &'static str,
    },
    /// Too few surrogates for any finding to reach the significance level.
    #[error(
        "{surrogates} surrogates cannot reach alpha = {alpha}: the smallest p-value N \
         surrogates give is 1/(N + 1), so nothing could ever be significant; use at least \
         {needed}"
    )]
    TooFewSurrogates {
        /// Surrogates asked for.
        surrogates: usize,
        /// The significance level.
        alpha: f64,
        /// The fewest that can reach it.
        needed: usize,
    },
    /// The [`Observer`] stopped the analysis.
    #[error("the analysis was cancelled")]
    Cancelled,
}

/// Watches an analysis ([`analyse_observed`]): called with the share of the work done (0 to 1,
/// never falling) and what is being done, at the analysis's natural stopping points — between
/// its phases, every few candidate corrections built, and around each selection step's
/// surrogate test and joint refit. Returning `false` stops the analysis there with
/// [`DiscrepancyError::Cancelled`]. It is called from the analysis's worker threads too, hence
/// `Sync`; it should return quickly.
pub type Observer<'a> = dyn Fn(f32, &str) -> bool + Sync + 'a;

/// An analysis's [`Observer`] and whether it has said stop, so that work on other threads, and
/// code that cannot return an error, sees the stop too.
pub struct Watch<'a> {
    observer: Option<&'a Observer<'a>>,
    stopped: AtomicBool,
    /// The highest fraction reported so far. Held while the observer is called, so that
    /// reports from worker threads reach it one at a time and in rising order.
    fraction: Mutex<f32>,
}

impl<'a> Watch<'a> {
    /// A watch that reports to `observer` (`None`: nobody watches, nothing stops).
    pub fn new(observer: Option<&'a Observer<'a>>) -> Watch<'a> {
        Watch {
            observer,
            stopped: AtomicBool::new(false),
            fraction: Mutex::new(0.0),
        }
    }

    /// Reports `fraction` of the work done at `stage` (the stage is formatted only when
    /// someone watches); `Err(Cancelled)` when the observer says stop, now or before.
    pub fn report(
        &self,
        fraction: f32,
        stage: impl FnOnce() -> String,
    ) -> Result<(), DiscrepancyError> {
        if self.stopped() {
            return Err(DiscrepancyError::Cancelled);
        }
        let Some(observer) = self.observer else {
            return Ok(());
        };
        // An observer that panicked poisons the lock, but the fraction it guards is still sound.
        let mut highest = self.fraction.lock().unwrap_or_else(|e| e.into_inner());
        // Another thread may have been told stop while this one waited for the lock.
        if self.stopped() {
            return Err(DiscrepancyError::Cancelled);
        }
        *highest = highest.max(fraction.clamp(0.0, 1.0));
        if observer(*highest, &stage()) {
            Ok(())
        } else {
            self.stopped.store(true, Ordering::Relaxed);
            Err(DiscrepancyError::Cancelled)
        }
    }

    /// Asks the observer whether to go on without advancing the fraction (for long loops
    /// whose share of the work is not known in advance); true once it has said stop.
    pub fn should_stop(&self, stage: impl FnOnce() -> String) -> bool {
        // Zero never raises the fraction: the report repeats the highest one.
        self.report(0.0, stage).is_err()
    }

    /// True once the observer has said stop (without asking it again).
    pub fn stopped(&self) -> bool {
        self.stopped.load(Ordering::Relaxed)
    }
}

/// Settings of the analysis. The defaults are what the proof in `docs/discrepancy.md` ran.
#[derive(Debug, Clone)]
pub struct Options {
    /// Time-blocked cross-validation folds.
    pub folds: usize,
    /// Blocks per fold (one gap block on each side of a held-out run is left out of training).
    pub blocks_per_fold: usize,
    /// Phase-randomised surrogates per selection step.
    pub surrogates: usize,
    /// Significance level of a step (with 99 surrogates, 0.01 means: better than every one).
    pub alpha: f64,
    /// A finding must also lie beyond this upper-tail probability of a Gumbel law fitted to
    /// the surrogates' maxima (so that barely beating the largest surrogate is not enough)…
    pub tail_alpha: f64,
    /// …unless its held-out gain is at least this share of the error before the step.
    pub dominant_gain: f64,
    /// Smallest held-out gain worth reporting, as a share of the held-out error before the step.
    pub min_relative_gain: f64,
    /// Most selection steps (calibration and physics together).
    pub max_steps: usize,
    /// The selection runs on at most this many rows (bin means of the aligned rows; the model
    /// is linear in its coefficients, so bin means keep its form). The final refit and every
    /// reported figure use all rows.
    pub max_selection_rows: usize,
    /// A runner-up whose block-by-block held-out error is not worse than the winner's by at
    /// least this paired t statistic is reported as indistinguishable.
    pub distinguish_t: f64,
    /// Seed of the surrogates.
    pub seed: u64,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            folds: 8,
            blocks_per_fold: 4,
            surrogates: 99,
            alpha: 0.01,
            tail_alpha: 1e-4,
            dominant_gain: 0.8,
            min_relative_gain: 0.02,
            max_steps: 4,
            max_selection_rows: 8192,
            distinguish_t: 2.0,
            seed: 0x5EED_D15C,
        }
    }
}

/// A correction whose fitted contribution is smaller than this share of the sample noise, and
/// which adds nothing held out to the joint model on all rows, is empty and withdrawn.
const EMPTY_CORRECTION_NOISE_SHARE: f64 = 0.25;

/// Most cross-validation folds: each held-out run is a block of the recording, and beyond a
/// few dozen the blocks are shorter than the slow residuals they are meant to hold out whole.
const MAX_FOLDS: usize = 64;
/// [`MAX_FOLDS`] as the option's requirement says it.
const MAX_FOLDS_REQUIREMENT: &str = "between 2 and 64";

impl Options {
    fn validate(&self) -> Result<(), DiscrepancyError> {
        let checks: [(&'static str, f64, bool, &'static str); 5] = [
            (
                "folds",
                self.folds as f64,
                (2..=MAX_FOLDS).contains(&self.folds),
                MAX_FOLDS_REQUIREMENT,
            ),
            (
                "surrogates",
                self.surrogates as f64,
                self.surrogates >= 1,
                "at least 1",
            ),
            (
                "alpha",
                self.alpha,
                self.alpha > 0.0 && self.alpha < 1.0,
                "strictly between 0 and 1",
            ),
            (
                "max_selection_rows",
                self.max_selection_rows as f64,
                self.max_selection_rows >= 64,
                "at least 64",
            ),
            (
                "blocks_per_fold",
                self.blocks_per_fold as f64,
                self.blocks_per_fold >= 1,
                "at least 1",
            ),
        ];
        for (name, value, ok, requirement) in checks {
            if !ok {
                return Err(DiscrepancyError::InvalidOption {
                    name,
                    value,
                    requirement,
                });
            }
        }
        // The smallest p-value N surrogates can give is 1/(N + 1): with fewer than 1/α − 1 no
        // finding could ever be significant, and "consistent" would be a foregone conclusion.
        let needed = (1.0 / self.alpha - 1.0 - 1e-9).ceil().max(1.0) as usize;
        if self.surrogates < needed {
            return Err(DiscrepancyError::TooFewSurrogates {
                surrogates: self.surrogates,
                alpha: self.alpha,
                needed,
            });
        }
        Ok(())
    }
}

/// The joint model judged on every row, where the selection judged it on bin means.
struct AllRows<'a> {
    ctx: &'a Context,
    residual: &'a [f64],
    blocks: &'a Blocks,
    ss_total: f64,
}

impl AllRows<'_> {
    /// The accepted correction that is empty on all rows, if any (the weakest of them): its
    /// fitted contribution is smaller than [`EMPTY_CORRECTION_NOISE_SHARE`] of the sample
    /// noise, and the joint model predicts its held-out blocks no worse without it. Chosen on
    /// the selection's bin means, such a correction (a Coulomb step of 0.001 N·m, 0.04 σ,
    /// beside nothing at all) would name physics that the report's own figures say changes
    /// nothing. Both conditions: a true effect of a few tenths of the noise (a position
    /// profile under correlated noise) can show no held-out share on all rows and still be
    /// what the data hold.
    fn empty_correction(&self, joint: &Joint<'_>) -> Option<usize> {
        let sample_noise = match white_noise_from_differences(self.residual) {
            // A target read in coarse steps has differences of exactly zero; its spread is
            // then the only scale there is. So has a current whose readings sit at its floor
            // for most rows, and the spread is kept there too: measured between readings
            // above the floor instead, a Coulomb step that the floor made where a drifting
            // zero pushed the readings onto it (0.4 σ, adding nothing held out on bounds)
            // stayed named in two pair reports of the independent check.
            w if w > 0.0 => w,
            _ => series::std_dev(self.residual),
        };
        let state_ctx = joint.state_context();
        let active: Vec<usize> = (0..joint.accepted.len())
            .filter(|&k| joint.active[k])
            .collect();
        let columns: Vec<Vec<Vec<f64>>> = active
            .iter()
            .map(|&k| {
                let (family, theta) = &joint.accepted[k];
                let family = &joint.families[*family];
                build(
                    family,
                    if family.state { &state_ctx } else { self.ctx },
                    theta,
                )
            })
            .collect();
        let n = self.residual.len();
        let ones = vec![1.0; n];
        // The standardised design without one correction, and which correction owns each
        // column.
        let design_without = |left_out: Option<usize>| -> (Vec<Vec<f64>>, Vec<usize>) {
            let mut owners = Vec::new();
            let raw: Vec<Vec<f64>> = columns
                .iter()
                .enumerate()
                .filter(|(i, _)| Some(*i) != left_out)
                .flat_map(|(i, c)| {
                    owners.extend(std::iter::repeat_n(i, c.len()));
                    c.iter().cloned()
                })
                .collect();
            (standardised(&raw).0, owners)
        };
        fn with_intercept<'c>(ones: &'c [f64], standard: &'c [Vec<f64>]) -> Vec<&'c [f64]> {
            std::iter::once(ones)
                .chain(standard.iter().map(Vec::as_slice))
                .collect()
        }
        let held_out_r2 = |standard: &[Vec<f64>]| {
            held_out_quality(
                &with_intercept(&ones, standard),
                self.residual,
                self.blocks,
                self.ss_total,
            )
            .r2
        };
        let (standard, owners) = design_without(None);
        let all = held_out_r2(&standard);
        let beta = least_squares(&with_intercept(&ones, &standard), self.residual)?.0;
        // A correction's fitted contribution on all rows, as an RMS.
        let size = |i: usize| {
            let contribution: Vec<f64> = (0..n)
                .map(|row| {
                    owners
                        .iter()
                        .enumerate()
                        .filter(|(_, owner)| **owner == i)
                        .map(|(j, _)| beta[j + 1] * standard[j][row])
                        .sum()
                })
                .collect();
            series::std_dev(&contribution)
        };
        (0..active.len())
            .filter(|&i| {
                let (family, _) = &joint.accepted[active[i]];
                matches!(joint.families[*family].kind, Kind::Physics(_))
            })
            .filter(|&i| size(i) < EMPTY_CORRECTION_NOISE_SHARE * sample_noise)
            .map(|i| (i, all - held_out_r2(&design_without(Some(i)).0)))
            .filter(|(_, share)| *share <= 0.0)
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .map(|(i, _)| active[i])
    }
}

/// A censored target's last refused winner, accepted on its readings at the floor as bounds
/// ([`accepted_on_bounds`]).
struct OnBounds {
    /// The target's readings, the floor's as bounds.
    readings: CutOffReadings,
    /// Its columns on all rows.
    columns: Vec<Vec<f64>>,
    /// Held-out squared error on bounds of the corrections before it, summed over the blocks…
    before: f64,
    /// …and with it.
    after: f64,
    /// The held-out errors on bounds with it, row by row.
    errors_after: Vec<f64>,
    /// The sign-flip test of what it saves in each fold ([`fold_sign_flip_p`]).
    p_value: f64,
}

/// The selection scores its candidates on a censored target's readings as compared, each
/// reading at the floor taken as its value. A sensor whose zero falls through the floor puts
/// most readings there, whatever the simulation, and a line in time then explains little of
/// those values: on the twin's spindle current, 70 % at the floor after a zero falling
/// 0.05 A/h, the drift explained 0.19 of the held-out error, short of the surrogates, and the
/// report said `consistent` with 0.41 A left against 0.15 A of noise. So the step that ended
/// the selection is asked again on the readings as bounds ([`CutOffReadings`]): its winner,
/// of fixed shape and physics, enters where, beside the corrections already chosen, it
/// removes at least `dominant_gain` of their held-out error on bounds, and the folds say so
/// ([`fold_sign_flip_p`] at `alpha`: with 8 folds, every one of them better). The surrogates
/// cannot be asked there (a refit on bounds per fold and surrogate), hence the stricter
/// share, the one a step asked again after the refit meets.
#[allow(clippy::too_many_arguments)]
fn accepted_on_bounds(
    aligned: &Aligned,
    target: &str,
    ctx: &Context,
    families: &[Family],
    members: &[Member],
    steps: &[Step],
    selected_columns: &[Vec<Vec<f64>>],
    blocks: &Blocks,
    options: &Options,
) -> Option<OnBounds> {
    let censoring = aligned.censoring?;
    let step = steps.last().filter(|s| !s.accepted)?;
    let member = &members[step.member];
    let family = &families[member.family];
    if family.state || !matches!(family.kind, Kind::Physics(_)) {
        return None;
    }
    let sim = aligned.sim_column(target)?;
    let readings = CutOffReadings::new(&censoring, &aligned.real_target, &sim)?;
    let candidate = build(family, ctx, &member.theta);
    if candidate.is_empty() {
        return None;
    }
    let mut raw: Vec<Vec<f64>> = selected_columns.iter().flatten().cloned().collect();
    let without = block_sums(&held_out_on_bounds(&readings, &raw, blocks)?, blocks);
    raw.extend(candidate.iter().cloned());
    let errors_after = held_out_on_bounds(&readings, &raw, blocks)?;
    let with = block_sums(&errors_after, blocks);
    let before: f64 = without.iter().sum();
    let after: f64 = with.iter().sum();
    let by_fold: Vec<f64> = blocks
        .folds
        .iter()
        .map(|fold| fold.test.clone().map(|b| without[b] - with[b]).sum())
        .collect();
    let p_value = fold_sign_flip_p(&by_fold, options.seed);
    (before > 0.0 && 1.0 - after / before >= options.dominant_gain && p_value <= options.alpha)
        .then_some(OnBounds {
            readings,
            columns: candidate,
            before,
            after,
            errors_after,
            p_value,
        })
}

/// Held-out errors on bounds ([`CutOffReadings::held_out_errors`]) of the offset and the
/// `raw` columns standardised, as the report's final design is built; `None` where a fold
/// cannot be fitted.
fn held_out_on_bounds(
    readings: &CutOffReadings,
    raw: &[Vec<f64>],
    blocks: &Blocks,
) -> Option<Vec<f64>> {
    let ones = vec![1.0; readings.len()];
    let (standard, _) = standardised(raw);
    let mut design: Vec<&[f64]> = vec![&ones];
    design.extend(standard.iter().map(Vec::as_slice));
    readings.held_out_errors(&design, blocks)
}

/// Squared `errors` summed block by block.
fn block_sums(errors: &[f64], blocks: &Blocks) -> Vec<f64> {
    blocks
        .ranges
        .iter()
        .map(|r| errors[r.clone()].iter().map(|e| e * e).sum())
        .collect()
}

/// Of the corrections `columns` (but the one at `keep`), those `eligible` whose absence does
/// not raise the held-out error on bounds above `all` (theirs together), the one whose
/// absence lowers it most, with the held-out errors without it; `None` when each adds
/// something.
fn nothing_on_bounds(
    readings: &CutOffReadings,
    columns: &[Vec<Vec<f64>>],
    all: f64,
    keep: usize,
    eligible: impl Fn(usize) -> bool,
    blocks: &Blocks,
) -> Option<(usize, Vec<f64>)> {
    let errors_without = |left_out: usize| -> Option<Vec<f64>> {
        let raw: Vec<Vec<f64>> = columns
            .iter()
            .enumerate()
            .filter(|(k, _)| *k != left_out)
            .flat_map(|(_, c)| c.iter().cloned())
            .collect();
        held_out_on_bounds(readings, &raw, blocks)
    };
    let sse = |errors: &[f64]| errors.iter().map(|e| e * e).sum::<f64>();
    (0..columns.len())
        .filter(|&k| k != keep && eligible(k))
        .filter_map(|k| Some((k, errors_without(k)?)))
        .filter(|(_, without)| sse(without) <= all)
        .min_by(|a, b| sse(&a.1).total_cmp(&sse(&b.1)))
}

/// Folds beyond which [`fold_sign_flip_p`] draws its sign patterns instead of taking all.
const EXACT_SIGN_FLIP_FOLDS: usize = 16;
/// Sign patterns drawn beyond [`EXACT_SIGN_FLIP_FOLDS`].
const DRAWN_SIGN_FLIPS: usize = 1 << 16;

/// One-sided p-value that a correction lowers the held-out error, from what it saves in each
/// fold (`by_fold`: a fold's held-out blocks are one run of the recording, so folds far apart
/// in time are nearly independent even where its blocks are not): the share of the sign
/// patterns ±1 per fold whose signed total is at least the one observed. Exact over all
/// 2^folds patterns (1/256 at best with 8 folds, every fold better); beyond
/// [`EXACT_SIGN_FLIP_FOLDS`], [`DRAWN_SIGN_FLIPS`] patterns drawn with `seed`.
fn fold_sign_flip_p(by_fold: &[f64], seed: u64) -> f64 {
    let observed: f64 = by_fold.iter().sum();
    let signed = |pattern: &dyn Fn(usize) -> bool| -> f64 {
        by_fold
            .iter()
            .enumerate()
            .map(|(f, d)| if pattern(f) { d.abs() } else { -d.abs() })
            .sum()
    };
    // Sums of the same terms in another order may differ in the last bits.
    let at_least = |total: f64| total >= observed - 1e-12 * observed.abs();
    let (hits, count) = if by_fold.len() <= EXACT_SIGN_FLIP_FOLDS {
        let count = 1usize << by_fold.len();
        let hits = (0..count)
            .filter(|&bits| at_least(signed(&|f| bits >> f & 1 == 1)))
            .count();
        (hits, count)
    } else {
        use rand::{Rng, SeedableRng};
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let hits = (0..DRAWN_SIGN_FLIPS)
            .filter(|_| {
                let signs: Vec<bool> = (0..by_fold.len()).map(|_| rng.random()).collect();
                at_least(signed(&|f| signs[f]))
            })
            .count();
        // The pattern observed counts among the drawn ones.
        (hits + 1, DRAWN_SIGN_FLIPS + 1)
    };
    hits as f64 / count as f64
}

/// A selected correction at its refined parameters.
struct Selected {
    family: usize,
    theta: Vec<f64>,
    step: Step,
    /// Its step's place in the selection's trace.
    step_index: usize,
}

/// Builds a member's full-rate columns; empty when the family could not build them. When the
/// rows are a coarser simulation's instants, the columns are built on the real recording's
/// own rows and read at those instants.
fn build(family: &Family, ctx: &Context, theta: &[f64]) -> Vec<Vec<f64>> {
    match &ctx.real_rate {
        Some(real) => build_on_rows(family, &real.context, theta)
            .iter()
            .map(|c| real.read(c))
            .collect(),
        None => build_on_rows(family, ctx, theta),
    }
}

/// A member's columns on the context's own rows; empty when the family could not build them.
fn build_on_rows(family: &Family, ctx: &Context, theta: &[f64]) -> Vec<Vec<f64>> {
    let columns = (family.build)(ctx, theta);
    if columns
        .iter()
        .all(|c| c.len() == ctx.time.len() && c.iter().all(|v| v.is_finite()))
    {
        columns
    } else {
        Vec::new()
    }
}

/// Standardises columns for the normal equations; returns them with their (mean, sd).
fn standardised(columns: &[Vec<f64>]) -> (Vec<Vec<f64>>, Vec<(f64, f64)>) {
    columns
        .iter()
        .map(|c| {
            let m = mean(c);
            let s = series::std_dev(c);
            let s = if s > 0.0 { s } else { 1.0 };
            (c.iter().map(|v| (v - m) / s).collect(), (m, s))
        })
        .unzip()
}

/// Most rows of each recording the analysis takes. Its memory grows with the rows, about
/// 2 kB a row at the peak (2.1 GB and 18.6 s for 1,080,001 rows, docs/performance.md), since it
/// builds its candidate corrections at full rate before averaging them into the selection's
/// bins: two million rows stay near 4 GB. A longer recording (1 kHz servo data over hours) is
/// averaged over blocks of time first ([`crate::signal::RecordingReader::read_averaged`]; the
/// command's `--average`). What happens inside a block is then lost to the corrections built
/// from a signal's square or power (the heat of a block's mean current is not its mean heat:
/// 0.057 °C left of a 4.6 °C copper heat over 1 s blocks of 100 Hz data, 0.006 °C at full
/// rate, docs/discrepancy.md). The command and the HMI read fewer where the memory free would
/// not hold the analysis ([`RowBudget`]).
pub const MAX_ROWS: usize = 2_000_000;

/// Analyses `real` against `sim` for `target`.
pub fn analyse(
    sim: &crate::signal::Recording,
    real: &crate::signal::Recording,
    target: &str,
    options: &Options,
) -> Result<DiscrepancyReport, DiscrepancyError> {
    analyse_watched(sim, real, target, options, &Watch::new(None))
}

/// [`analyse`] under an [`Observer`] that hears how far the analysis has got and may stop it
/// ([`DiscrepancyError::Cancelled`]). Watching changes nothing in the result.
pub fn analyse_observed(
    sim: &crate::signal::Recording,
    real: &crate::signal::Recording,
    target: &str,
    options: &Options,
    observer: &Observer<'_>,
) -> Result<DiscrepancyReport, DiscrepancyError> {
    analyse_watched(sim, real, target, options, &Watch::new(Some(observer)))
}

/// Shares of the work (0 to 1) at which the phases start: building the candidates, the
/// selection, the final refit and figures, the localisation. Rough shares of the time on a
/// long recording.
const BUILD_AT: f32 = 0.05;
const SELECT_AT: f32 = 0.3;
const REFIT_AT: f32 = 0.9;
const LOCATE_AT: f32 = 0.97;

/// A part's residual this many times its sample-to-sample noise after what its analysis named
/// (or after calibration, with nothing named) is a gross mismatch: worth asking whether it is
/// the motor's winding's (`winding_cause`). On the independent check's bearings and growths
/// with nothing left out, or an effect that does not reach them, the ratio is 0.99–1.58 (AR(1)
/// noise beside the white, seeds 1–10); on the parts it names through the winding, 4–40.
const GROSS_MISMATCH_NOISE_RATIO: f64 = 4.0;

/// The level from which what the corrections leave is a gross mismatch rather than noise:
/// [`GROSS_MISMATCH_NOISE_RATIO`] × its sample-to-sample part.
fn gross_mismatch_level(floor: &NoiseFloor) -> f64 {
    GROSS_MISMATCH_NOISE_RATIO * floor.sample_noise_rms
}

/// The level from which a held-out error is a gross mismatch beside `sample_noise_rms` of
/// noise from sample to sample ([`GROSS_MISMATCH_NOISE_RATIO`] × it); infinite where that
/// noise reads zero because it cannot be told (most samples repeat the one before: a coarsely
/// quantised series), so that no error is gross there.
fn gross_mismatch_beside(sample_noise_rms: f64) -> f64 {
    if sample_noise_rms > 0.0 {
        GROSS_MISMATCH_NOISE_RATIO * sample_noise_rms
    } else {
        f64::INFINITY
    }
}

/// Whether what the corrections leave is a gross mismatch ([`gross_mismatch_level`]).
fn leaves_gross_mismatch(floor: &NoiseFloor) -> bool {
    floor.rms >= gross_mismatch_level(floor)
}

/// The localisation's spans between mismatch regions that are evidence the simulation is
/// right there. Its threshold stands on what the corrections leave; when that is itself a
/// gross mismatch, a span below it is no such evidence (a torque a coarse export aliases:
/// "right" at 1.33 N·m beside 0.07 N·m of sample noise), and only spans whose mismatch is
/// near the sample noise are kept. Nor is a span right where the simulation's instants do not
/// hold the target's course: its mismatch there looks like noise from one instant to the next
/// (1.25 N·m "from sample to sample" against a torque sensor's 0.02, test
/// `a_delay_behind_a_simulation_exported_too_coarsely_to_move_is_read_on_the_real_samples`).
fn spans_shown_right(agreement: Vec<Region>, floor: &NoiseFloor, ctx: &Context) -> Vec<Region> {
    if ctx.too_coarse.is_some() {
        return Vec::new();
    }
    if !leaves_gross_mismatch(floor) {
        return agreement;
    }
    let near_noise = gross_mismatch_level(floor);
    agreement
        .into_iter()
        .filter(|r| r.rms_residual < near_noise)
        .collect()
}

fn analyse_watched(
    sim: &crate::signal::Recording,
    real: &crate::signal::Recording,
    target: &str,
    options: &Options,
    watch: &Watch<'_>,
) -> Result<DiscrepancyReport, DiscrepancyError> {
    let report = analyse_with(sim, real, target, options, watch, None, None)?;
    let Some(cause) = winding_cause(sim, real, target, &report, options, watch)? else {
        return Ok(report);
    };
    let inherited = analyse_with(
        sim,
        real,
        target,
        options,
        watch,
        Some(Arc::new(cause)),
        None,
    )?;
    // The second analysis stands only if it names the winding's mismatch, and, where the
    // part named physics of its own, predicts the held-out blocks better (both are measured
    // on the same blocks of the same rows): with more candidates its surrogates' maxima
    // differ, and a small gain without the winding is no answer to the question asked. A
    // part with nothing named is no exception: on the independent check's seed-26 front
    // bearing (speed-dependent cooling left out, 2.6 σ) a second analysis that did not take
    // the winding's mismatch named copper heat (ΔR² 0.0004), which the first had refused.
    let names_winding = inherited
        .findings
        .iter()
        .any(|f| library::reads_winding_mismatch(&f.signals));
    let answers = names_winding
        && (report.findings.is_empty() || inherited.improved.rmse < report.improved.rmse);
    Ok(if !inherited.findings.is_empty() && answers {
        inherited
    } else {
        report
    })
}

/// When a part beside a motor is left with a gross mismatch, whether or not its analysis named
/// anything (what it named may be its own physics, or a lag standing in for the winding's),
/// what the motor's winding lacks: the physics an analysis of the winding (measured by the
/// drive in both runs) names first, if a part can inherit it, with the other heating physics
/// it names beside (said in the part's finding). The part's analysis is then run
/// again with the winding's mismatch on offer ([`library::WindingCause`]); the winding's own
/// forms of the physics, rebuilt from currents and speeds, may follow the winding less
/// faithfully than its measurement does, and through the housing the part follows the winding.
fn winding_cause(
    sim: &crate::signal::Recording,
    real: &crate::signal::Recording,
    target: &str,
    report: &DiscrepancyReport,
    options: &Options,
    watch: &Watch<'_>,
) -> Result<Option<WindingCause>, DiscrepancyError> {
    let gross = leaves_gross_mismatch(&report.noise_floor);
    let Some(winding) = WindingCause::winding_of(target) else {
        return Ok(None);
    };
    if !gross || sim.try_column(&winding).is_none() || real.try_column(&winding).is_none() {
        return Ok(None);
    }
    watch.report(LOCATE_AT, || {
        format!("a gross mismatch left: analysing the motor's winding ({winding})")
    })?;
    let winding_report = match analyse_with(sim, real, &winding, options, watch, None, None) {
        Ok(r) => r,
        Err(DiscrepancyError::Cancelled) => return Err(DiscrepancyError::Cancelled),
        // The winding cannot be analysed (too few rows where it reads): the part's report
        // stands as it is.
        Err(_) => return Ok(None),
    };
    let Some(first) = winding_report.findings.first() else {
        return Ok(None);
    };
    let Some(physics) = Physics::from_id(&first.physics).filter(|p| WindingCause::inheritable(*p))
    else {
        return Ok(None);
    };
    let mut also: Vec<InheritedAlso> = Vec::new();
    for finding in winding_report.findings.iter().skip(1) {
        let Some(other) = Physics::from_id(&finding.physics) else {
            continue;
        };
        if WindingCause::inheritable(other)
            && other != physics
            && also.iter().all(|named| named.physics != other)
        {
            also.push(InheritedAlso {
                physics: other,
                delta_r2: finding.delta_r2,
                explanation: finding.explanation.clone(),
            });
        }
    }
    Ok(Some(WindingCause {
        winding,
        physics,
        explanation: first.explanation.clone(),
        also,
    }))
}

/// One analysis of `target`; with `winding_cause`, the target may also inherit its motor's
/// winding's mismatch.
fn analyse_with(
    sim: &crate::signal::Recording,
    real: &crate::signal::Recording,
    target: &str,
    options: &Options,
    watch: &Watch<'_>,
    winding_cause: Option<Arc<WindingCause>>,
    read_later: Option<ReadLater>,
) -> Result<DiscrepancyReport, DiscrepancyError> {
    options.validate()?;
    for (role, recording) in [("simulation", sim), ("real recording", real)] {
        if recording.len() > MAX_ROWS {
            return Err(DiscrepancyError::TooManyRows {
                role,
                source_name: recording.source().to_string(),
                rows: recording.len(),
                limit: MAX_ROWS,
            });
        }
    }
    watch.report(0.0, || "aligning the recordings".into())?;
    let aligned = match read_later {
        Some(later) => Aligned::read_later(sim, real, target, later.delay.samples)?,
        None => Aligned::new(sim, real, target)?,
    };
    let n = aligned.len();
    let mut ctx = Context::new(&aligned, target);
    // A simulation exported too coarsely to be moved is compared with the real target read
    // later, when that predicts the held-out blocks better: the rest of the analysis then
    // works on what the delay leaves. Where the delay, so read, adds nothing to the refitted
    // model, or too few rows hold its later readings, the target is compared as recorded and
    // the report says why the delay is not named.
    let mut delay_refused = None;
    if let Some(later) = read_later {
        // The same export: the rows that hold later readings are no finer for it.
        ctx.too_coarse = ctx.too_coarse.or(Some(later.too_coarse));
    } else if let Some(too_coarse) = ctx.too_coarse {
        watch.report(0.0, || "reading the real recording later".into())?;
        if let Some(delay) = real_delay::search(&aligned, target, options) {
            let later = Some(ReadLater { delay, too_coarse });
            let cause = winding_cause.clone();
            delay_refused = Some(
                match analyse_with(sim, real, target, options, watch, cause, later) {
                    Ok(report) if reads_later_with_gain(&report) => return Ok(report),
                    Ok(_) => format!(
                        "the real {target} read {:.2} s later predicted the held-out blocks better alone, but added nothing to the corrections refitted beside it",
                        delay.delay_s
                    ),
                    Err(DiscrepancyError::TooShort { rows, .. }) => format!(
                        "the real {target} read {:.2} s later predicted the held-out blocks better, but only {rows} rows hold its later readings",
                        delay.delay_s
                    ),
                    Err(e) => return Err(e),
                },
            );
        }
    }
    if let Some(cause) = winding_cause {
        ctx = ctx.with_winding_cause(cause);
    }
    let residual: Vec<f64> = aligned
        .real_target
        .iter()
        .zip(&aligned.sim_target)
        .map(|(r, s)| r - s)
        .collect();
    // The real target as recorded, which the figures before any correction and the delay's
    // own share are measured on.
    let recorded_target = aligned
        .recorded_target
        .as_ref()
        .unwrap_or(&aligned.real_target);
    let recorded_residual: Vec<f64> = recorded_target
        .iter()
        .zip(&aligned.sim_target)
        .map(|(r, s)| r - s)
        .collect();
    // Measured where the instrument shows its noise: a current's readings at its floor hold
    // none, and taken with the rest they read it as 0, which made no error gross there.
    let residual_noise = sample_noise_of(&residual, &aligned, ctx.reading.is_some());
    let (families, untested) = families(&ctx);

    // The selection works on bin means (all rows when there are few enough).
    let bins = bin_ranges(n, options.max_selection_rows);
    let y_binned = bin_means(&residual, &bins);
    let mut store = Store::default();
    let mut members = Vec::new();
    let longest = library::SELECTION_LONGEST_LAG_SHARE * ctx.duration_s;
    let grid: Vec<(usize, &Vec<f64>)> = families
        .iter()
        .enumerate()
        .flat_map(|(index, family)| family.grid.iter().map(move |theta| (index, theta)))
        .filter(|(index, theta)| families[*index].selectable(theta, longest))
        .collect();
    watch.report(BUILD_AT, || {
        format!("building {} candidate corrections", grid.len())
    })?;
    // Counted under a lock that is held through the report, so that the counts the observer
    // hears rise as the fractions do.
    let done = Mutex::new(0_usize);
    let every = (grid.len() / 25).max(1);
    let built = parallel_map(&grid, |&(index, theta)| {
        if watch.stopped() {
            return BinnedMember::default();
        }
        // Standardised here, on the building threads, rather than as the store takes them.
        let binned = binned_with_scales(&families[index], &ctx, theta, &bins);
        let mut done = done.lock().unwrap_or_else(|e| e.into_inner());
        *done += 1;
        if done.is_multiple_of(every) {
            let done = *done;
            // A stop shows in `watch` and is returned after the loop.
            let _ = watch.report(
                BUILD_AT + (SELECT_AT - BUILD_AT) * done as f32 / grid.len() as f32,
                || format!("building candidate corrections ({done} of {})", grid.len()),
            );
        }
        binned
    });
    watch.report(SELECT_AT, || "preparing the selection".into())?;
    // The joint refit chooses each correction again from its whole family, and a refused step
    // asked again refits the model once for every rival kind: the members of fixed shape built
    // here are kept for it rather than built again there.
    let fixed = FixedMembers::default();
    for ((index, theta), binned) in grid.into_iter().zip(built) {
        if binned.is_empty() {
            continue;
        }
        if !families[index].state {
            fixed.keep(index, theta, &binned);
        }
        let columns = Arc::try_unwrap(binned).unwrap_or_else(|shared| (*shared).clone());
        let range = store.push_standardised(columns);
        members.push(Member {
            family: index,
            theta: theta.clone(),
            columns: range,
        });
    }
    let blocks = Blocks::new(y_binned.len(), options.folds, options.blocks_per_fold);
    let highpass_window = (y_binned.len() / 256).max(5);
    let mut views = parallel_map(&[false, true], |&high| {
        if high {
            select::View::highpassed(&store, highpass_window)
        } else {
            select::View::raw(&store)
        }
    });
    views.truncate(2);
    store.release_columns();
    // Every accepted correction at its current parameters, and the target's state correction
    // the state-dependent ones are rebuilt on; both are updated jointly after each acceptance.
    let mut joint = Joint {
        families: &families,
        members: &members,
        blocks: &blocks,
        highpass_window,
        ctx: &ctx,
        bins: &bins,
        y: &y_binned,
        accepted: Vec::new(),
        active: Vec::new(),
        min_relative_gain: options.min_relative_gain,
        state: None,
        watch,
        fixed,
        refinable: Vec::new(),
    };
    let mut steps = stepwise(
        &Problem {
            y: &y_binned,
            views: &views,
            blocks: &blocks,
            members: &members,
            families: &families,
            store: &store,
            gross_mismatch: gross_mismatch_beside(residual_noise),
        },
        options,
        &mut joint,
        watch,
        SELECT_AT..REFIT_AT,
    )?;
    // The named corrections may now take their refined forms: once, beside each other, after
    // every step is decided (a form refined at each step costs a refit of its whole family
    // there, and the names would not change).
    let mut refinable: Vec<usize> = joint
        .accepted
        .iter()
        .zip(&joint.active)
        .filter(|((family, _), active)| **active && families[*family].has_refit_only_refinements())
        .map(|((family, _), _)| *family)
        .collect();
    refinable.sort_unstable();
    refinable.dedup();
    if !refinable.is_empty() {
        watch.report(REFIT_AT, || "refining the corrections' forms".into())?;
        // The refit chooses every correction again, one at a time, and may settle where the
        // model as a whole predicts worse than before it, or where a correction breaks its
        // physics' limits (a time constant refined past them): the refined forms are kept
        // only within the limits and where the held-out blocks say the model is better.
        let before = joint.clone();
        let error = |j: &Joint<'_>| j.held_out_error(&j.state_context(), None, None);
        let baseline = error(&before);
        let refit_refining = |families: Vec<usize>| {
            let mut refined = before.clone();
            refined.refinable = families;
            refined.refit_jointly();
            let withdrawn = refined.keep_within_limits(refined.stateful());
            let refined_error = error(&refined);
            (!withdrawn && refined_error < baseline).then_some((refined, refined_error))
        };
        let mut kept = refit_refining(refinable.clone());
        if kept.is_none() && refinable.len() > 1 {
            // One correction's refined forms may lead the refit where the model predicts worse
            // while another's would help (the coolant's, held at its own temperature, beside
            // the room's faster lags): each alone, the best kept.
            kept = refinable
                .iter()
                .filter_map(|&family| refit_refining(vec![family]))
                .min_by(|a, b| a.1.total_cmp(&b.1));
        }
        if let Some((refined, _)) = kept {
            joint = refined;
        }
    }
    joint.simpler_where_nested(&mut steps, &members, options.distinguish_t);
    watch.report(REFIT_AT, || "refitting on all rows".into())?;
    let full_blocks = Blocks::new(n, options.folds, options.blocks_per_fold);
    let real_mean = mean(recorded_target);
    let ss_total: f64 = recorded_target
        .iter()
        .map(|v| (v - real_mean).powi(2))
        .sum::<f64>()
        .max(f64::MIN_POSITIVE);
    let all_rows = AllRows {
        ctx: &ctx,
        residual: &residual,
        blocks: &full_blocks,
        ss_total,
    };
    while let Some(k) = all_rows.empty_correction(&joint) {
        joint.active[k] = false;
        joint.refit_jointly();
    }
    let state_ctx = joint.state_context();
    let accepted = std::mem::take(&mut joint.accepted);
    let active = std::mem::take(&mut joint.active);
    // Which steps were withdrawn, in step order (for the trace).
    let mut withdrawn: Vec<bool> = {
        let mut flags = active.iter().map(|a| !a);
        steps
            .iter()
            .map(|s| s.accepted && flags.next().unwrap_or(false))
            .collect()
    };
    let mut selected: Vec<Selected> = steps
        .iter()
        .enumerate()
        .filter(|(_, s)| s.accepted)
        .zip(accepted.into_iter().zip(active))
        .filter(|(_, (_, active))| *active)
        .map(|((step_index, step), ((family, theta), _))| Selected {
            family,
            theta,
            step: step.clone(),
            step_index,
        })
        .collect();
    let ctx_of = |family: usize| {
        if families[family].state {
            &state_ctx
        } else {
            &ctx
        }
    };

    // Final model on all rows: offset + every selected correction.
    let mut selected_columns: Vec<Vec<Vec<f64>>> = selected
        .iter()
        .map(|s| build(&families[s.family], ctx_of(s.family), &s.theta))
        .collect();
    // A step that entered on bounds leaves the readings and the final model's held-out
    // errors on them, which the figures below take as they are.
    let mut entered_on_bounds: Option<(CutOffReadings, Vec<f64>)> = None;
    if read_later.is_none()
        && let Some(found) = accepted_on_bounds(
            &aligned,
            target,
            &ctx,
            &families,
            &members,
            &steps,
            &selected_columns,
            &full_blocks,
            options,
        )
        && let Some(step) = steps.last_mut()
    {
        step.accepted = true;
        step.on_bounds = true;
        step.gain = found.before - found.after;
        step.sse_before = found.before;
        step.p_value = found.p_value;
        step.tail_p = found.p_value;
        let member = &members[step.member];
        selected.push(Selected {
            family: member.family,
            theta: member.theta.clone(),
            step: step.clone(),
            step_index: steps.len() - 1,
        });
        selected_columns.push(found.columns);
        // The corrections chosen on the readings as values are asked again beside it, on the
        // readings as bounds: one that adds nothing held out there was fitted to the floor.
        let mut all = found.after;
        let mut errors = found.errors_after;
        loop {
            let physics: Vec<bool> = selected
                .iter()
                .map(|s| matches!(families[s.family].kind, Kind::Physics(_)))
                .collect();
            let Some((k, without)) = nothing_on_bounds(
                &found.readings,
                &selected_columns,
                all,
                selected.len() - 1,
                |k| physics[k],
                &full_blocks,
            ) else {
                break;
            };
            all = without.iter().map(|e| e * e).sum();
            errors = without;
            withdrawn[selected[k].step_index] = true;
            selected.remove(k);
            selected_columns.remove(k);
        }
        entered_on_bounds = Some((found.readings, errors));
    }
    let ones = vec![1.0; n];
    let raw: Vec<Vec<f64>> = selected_columns.iter().flatten().cloned().collect();
    let (standard, scales) = standardised(&raw);
    let mut design: Vec<&[f64]> = vec![&ones];
    design.extend(standard.iter().map(|c| c.as_slice()));
    let (beta, _) = least_squares(&design, &residual).unwrap_or_else(|| {
        let mut b = vec![0.0; design.len()];
        b[0] = mean(&residual);
        (b, 0.0)
    });
    // A censored target whose readings sit at the floor where the simulation compared as read
    // does not put them (its zero drifting down): the corrections refitted to those readings
    // as bounds, kept where they predict the held-out readings clearly better. Every held-out
    // figure below is then of that fit, so that the findings' shares compare like with like.
    // A step that entered on bounds was judged there, and its figures are those whatever the
    // comparison says.
    let entered = entered_on_bounds.is_some();
    let cut_off = aligned
        .censoring
        .filter(|_| read_later.is_none())
        .and_then(|censoring| {
            let (readings, errors) = match entered_on_bounds {
                Some(measured) => measured,
                None => {
                    let sim = aligned.sim_column(target)?;
                    let readings = CutOffReadings::new(&censoring, &aligned.real_target, &sim)?;
                    let errors = readings.held_out_errors(&design, &full_blocks)?;
                    (readings, errors)
                }
            };
            let as_bounds: f64 = errors.iter().map(|e| e * e).sum();
            let as_compared = held_out_sse(&design, &residual, &full_blocks);
            let rmse = |sse: f64| (sse / n.max(1) as f64).sqrt();
            (entered || as_bounds < (1.0 - CUT_OFF_MIN_GAIN) * as_compared).then(|| {
                let figures = ReadingsAsBounds {
                    held_out_rmse: rmse(as_bounds),
                    held_out_rmse_as_compared: rmse(as_compared),
                };
                (readings, (figures, errors))
            })
        });
    let (cut_off, kept) = cut_off.unzip();
    let (readings_as_bounds, mut final_errors) = kept.unzip();
    let beta = match &cut_off {
        Some(readings) => readings.fit(&design, &vec![true; n]).unwrap_or(beta),
        None => beta,
    };
    // Raw-unit coefficients and the offset.
    let raw_coefficients: Vec<f64> = beta[1..]
        .iter()
        .zip(&scales)
        .map(|(b, (_, s))| b / s)
        .collect();
    let offset = beta[0]
        - beta[1..]
            .iter()
            .zip(&scales)
            .map(|(b, (m, s))| b * m / s)
            .sum::<f64>();

    // Held-out figures after each accepted step, on all rows.
    let mut held_out = Vec::with_capacity(selected.len() + 1);
    let mut cv_residual = residual.clone();
    let mut offsets = vec![0usize];
    for c in &selected_columns {
        offsets.push(offsets.last().copied().unwrap_or(0) + c.len());
    }
    for k in 0..=selected.len() {
        let columns: Vec<&[f64]> = design[..1 + offsets[k]].to_vec();
        // The final model's errors on bounds are those the refit was kept for.
        let errors = match final_errors.take().filter(|_| k == selected.len()) {
            Some(errors) => errors,
            None => held_out_errors(&columns, &residual, &full_blocks, cut_off.as_ref()),
        };
        held_out.push(quality_of(&errors, ss_total));
        if k == selected.len() {
            cv_residual = errors;
        }
    }

    // Each correction's own share in the joint model: the held-out R² lost without it.
    let without: Vec<FitQuality> = (0..selected.len())
        .map(|k| {
            // Without the last, the model is the one after the step before it, measured above.
            if k + 1 == selected.len() {
                return held_out[k];
            }
            let mut columns: Vec<&[f64]> = vec![&ones];
            columns.extend(
                design[1..]
                    .iter()
                    .enumerate()
                    .filter(|(c, _)| !(offsets[k]..offsets[k + 1]).contains(c))
                    .map(|(_, c)| *c),
            );
            quality_of(
                &held_out_errors(&columns, &residual, &full_blocks, cut_off.as_ref()),
                ss_total,
            )
        })
        .collect();

    // Calibration and findings.
    let name_of = |member: usize| match families[members[member].family].kind {
        Kind::Physics(p) => p.id().to_string(),
        Kind::CalibrationGain => "calibration".to_string(),
    };
    let names_of = |step: &Step| -> Vec<String> {
        step.indistinguishable.iter().map(|&m| name_of(m)).collect()
    };
    let alternatives_of = |step: &Step| -> Vec<Alternative> {
        step.runners_up
            .iter()
            .take(3)
            .map(|&(m, g)| Alternative {
                physics: name_of(m),
                // Runners-up carry relative gains (shares of the error before the step), the
                // step its absolute gain: compare like with like.
                relative_gain: if step.gain > 0.0 && step.sse_before > 0.0 {
                    g * step.sse_before / step.gain
                } else {
                    0.0
                },
            })
            .collect()
    };
    let mut calibration_gain = None;
    let mut calibration_step = None;
    let mut findings = Vec::new();
    for (k, s) in selected.iter().enumerate() {
        let family = &families[s.family];
        let coefficients = &raw_coefficients[offsets[k]..offsets[k + 1]];
        match family.kind {
            Kind::CalibrationGain => {
                calibration_gain = Some((coefficients[0], held_out[k + 1].r2 - held_out[k].r2));
                calibration_step = Some(&s.step);
            }
            Kind::Physics(physics) => {
                let (mut parameters, explanation) = library::explain(
                    family,
                    &s.theta,
                    coefficients,
                    &selected_columns[k],
                    ctx_of(s.family),
                );
                if physics == Physics::SensorOffsetDrift {
                    parameters.insert("offset_at_start".into(), offset);
                }
                findings.push(Finding {
                    physics: physics.id().to_string(),
                    explanation,
                    parameters,
                    signals: family.member_signals(&s.theta),
                    delta_r2: held_out[selected.len()].r2 - without[k].r2,
                    p_value: s.step.p_value,
                    indistinguishable_from: names_of(&s.step),
                    masked_by: s.step.masked_by.map(name_of),
                    judged_after_refit: s.step.after_refit,
                    judged_on_bounds: s.step.on_bounds,
                    alternatives: alternatives_of(&s.step),
                });
            }
        }
    }
    if let Some(ReadLater { delay, .. }) = read_later {
        // Its share: the joint model refitted to the target as recorded loses it.
        let without_delay = held_out_quality(&design, &recorded_residual, &full_blocks, ss_total);
        findings.push(real_delay_finding(
            target,
            &delay,
            held_out.last().map_or(0.0, |q| q.r2) - without_delay.r2,
            aligned.real_step_s().unwrap_or(0.0),
        ));
    }
    // Strongest first: by what each finding adds to the joint model, not by when it entered
    // (a correction that entered first may have taken a share of a later one's effect).
    findings.sort_by(|a, b| b.delta_r2.total_cmp(&a.delta_r2));
    let gain = 1.0 + calibration_gain.map_or(0.0, |(g, _)| g);
    let unit = crate::signal::channel::Channel::unit_of(target).unwrap_or("");
    // A gain slip is the simpler claim where physics of its width predicts as well, and is
    // taken for it; the report says which physics that was rather than rule it out.
    let indistinguishable_from = calibration_step.map(names_of).unwrap_or_default();
    let calibration = Calibration {
        offset,
        gain,
        gain_absorbed: calibration_gain.is_some(),
        explanation: if calibration_gain.is_some() && indistinguishable_from.is_empty() {
            format!(
                "calibration absorbed first: real ≈ {offset:+.4} {unit} + {gain:.4} × sim (a gain miscalibration, not physics)"
            )
        } else if calibration_gain.is_some() {
            format!(
                "calibration absorbed first: real ≈ {offset:+.4} {unit} + {gain:.4} × sim (taken for a gain miscalibration, the simpler claim: the data cannot tell it from {})",
                indistinguishable_from.join(", ")
            )
        } else {
            format!(
                "calibration: an offset of {offset:+.4} {unit} at the start; no gain miscalibration was significant"
            )
        },
        alternatives: calibration_step.map(alternatives_of).unwrap_or_default(),
        indistinguishable_from,
    };
    // The calibrated-only held-out figure: offset, plus the gain when it was absorbed.
    let calibrated = {
        let mut columns: Vec<&[f64]> = vec![&ones];
        if calibration_gain.is_some() {
            columns.push(&aligned.sim_target);
        }
        let (standard_cal, _) =
            standardised(&columns[1..].iter().map(|c| c.to_vec()).collect::<Vec<_>>());
        let mut cols: Vec<&[f64]> = vec![&ones];
        cols.extend(standard_cal.iter().map(|c| c.as_slice()));
        quality_of(
            &held_out_errors(&cols, &recorded_residual, &full_blocks, cut_off.as_ref()),
            ss_total,
        )
    };

    // Mismatch: what the calibrated simulation does not explain (corrections + residual).
    let mut mismatch: Vec<f64> = recorded_residual.iter().map(|r| r - offset).collect();
    for (k, s) in selected.iter().enumerate() {
        if families[s.family].kind == Kind::CalibrationGain {
            let g = raw_coefficients[offsets[k]];
            for (m, sim) in mismatch.iter_mut().zip(&aligned.sim_target) {
                *m -= g * sim;
            }
        }
    }
    watch.report(LOCATE_AT, || "locating the mismatch".into())?;
    let conditions = localise::Conditions::new(&aligned);
    // The noise floor's correlation time (one long FFT) is found beside the localisation.
    let (located, correlation_samples) = std::thread::scope(|scope| {
        let correlation =
            scope.spawn(|| integrated_autocorrelation(&cv_residual, (n / 10).clamp(2, 20_000)));
        let located = localise::localise(&ctx.time, &mismatch, &cv_residual, &conditions);
        (located, join_or_resume(correlation))
    });
    let noise_floor = NoiseFloor {
        rms: series::rms(&cv_residual),
        correlation_time_s: correlation_samples * ctx.step_s,
        sample_noise_rms: sample_noise_of(&cv_residual, &aligned, ctx.reading.is_some()),
        window_s: located.window_s,
    };

    let fitted: Vec<f64> = (0..n)
        .map(|i| design.iter().zip(&beta).map(|(c, b)| c[i] * b).sum())
        .collect();
    let plot_bins = bin_ranges(n, 4000);
    // With a delay read from the real recording, the simulation moved that much later is
    // what the real recording holds then: the target as recorded less the later reading.
    let corrected: Vec<f64> = match &cut_off {
        Some(readings) => readings.corrected(&aligned.real_target, &fitted),
        None => aligned
            .sim_target
            .iter()
            .zip(&fitted)
            .zip(recorded_target.iter().zip(&aligned.real_target))
            .map(|((s, f), (recorded, later))| s + f + (recorded - later))
            .collect(),
    };
    let plot = PlotData {
        target: target.to_string(),
        time_s: bin_means(&ctx.time, &plot_bins),
        real: bin_means(recorded_target, &plot_bins),
        sim: bin_means(&aligned.sim_target, &plot_bins),
        corrected: bin_means(&corrected, &plot_bins),
        residual_before: bin_means(&recorded_residual, &plot_bins),
        residual_after: bin_means(&cv_residual, &plot_bins),
        regions: located.mismatch.clone(),
    };
    let baseline_sse: f64 = recorded_residual.iter().map(|r| r * r).sum();
    let mut not_tested: Vec<NotTested> = untested
        .into_iter()
        .map(|(p, reason)| NotTested {
            physics: p.id().to_string(),
            reason,
        })
        .collect();
    not_tested.extend(delay_refused.map(|reason| NotTested {
        physics: Physics::SignalDelay.id().to_string(),
        reason,
    }));
    not_tested.dedup();
    Ok(DiscrepancyReport {
        target: target.to_string(),
        rows: n,
        verdict: if findings.is_empty() {
            Verdict::Consistent
        } else {
            Verdict::MissingPhysics
        },
        baseline: FitQuality {
            r2: 1.0 - baseline_sse / ss_total,
            rmse: (baseline_sse / n as f64).sqrt(),
        },
        improved: held_out.last().copied().unwrap_or(calibrated),
        calibrated,
        mismatch_regions: located.mismatch,
        agreement_regions: spans_shown_right(located.agreement, &noise_floor, &ctx),
        findings,
        calibration,
        noise_floor,
        alignment: Alignment {
            resampled: aligned.resampled,
            on_simulation_grid: aligned.on_simulation_grid,
            placed_by_speed: aligned.placed_by_speed,
            note: match readings_as_bounds {
                Some(figures) => format!(
                    "{}; the corrections were then fitted to the readings at the floor as bounds (the instrument reads its floor where the simulation, compared as read and corrected, lies above it): the held-out readings are predicted to RMSE {:.4} {unit}, against {:.4} {unit} with each reading at the floor taken as its value",
                    aligned.note(),
                    figures.held_out_rmse,
                    figures.held_out_rmse_as_compared
                ),
                None => aligned.note(),
            },
            start_s: ctx.time.first().copied().unwrap_or(0.0),
            end_s: ctx.time.last().copied().unwrap_or(0.0),
            censoring: aligned.censoring,
            read_later_s: read_later.map(|later| later.delay.delay_s),
            readings_as_bounds,
        },
        not_tested,
        method: Method {
            folds: options.folds,
            surrogates: options.surrogates,
            alpha: options.alpha,
            selection_rows: y_binned.len(),
            candidates: members.len(),
            steps: read_later
                .iter()
                .map(|ReadLater { delay, .. }| report::StepTrace {
                    physics: Physics::SignalDelay.id().to_string(),
                    relative_gain: delay.relative_gain,
                    p_value: delay.p_value,
                    tail_p: delay.p_value,
                    accepted: true,
                    withdrawn: false,
                    after_refit: false,
                    on_bounds: false,
                })
                .chain(
                    steps
                        .iter()
                        .zip(withdrawn)
                        .map(|(s, withdrawn)| report::StepTrace {
                            physics: match families[members[s.member].family].kind {
                                Kind::Physics(p) => p.id().to_string(),
                                Kind::CalibrationGain => "calibration".to_string(),
                            },
                            relative_gain: if s.sse_before > 0.0 {
                                s.gain / s.sse_before
                            } else {
                                0.0
                            },
                            p_value: s.p_value,
                            tail_p: s.tail_p,
                            accepted: s.accepted,
                            withdrawn,
                            after_refit: s.after_refit,
                            on_bounds: s.on_bounds,
                        }),
                )
                .collect(),
        },
        plot,
    })
}

/// A delay found on the real recording's own samples, and the export that made it the way to
/// look for one.
#[derive(Debug, Clone, Copy)]
struct ReadLater {
    delay: RealDelay,
    too_coarse: library::TooCoarse,
}

/// Whether `report`, analysed with its real target read later, names that delay as adding to
/// the refitted model (held out).
fn reads_later_with_gain(report: &DiscrepancyReport) -> bool {
    report.alignment.read_later_s.is_some()
        && report.findings.iter().any(|f| {
            f.physics == Physics::SignalDelay.id()
                && f.parameters.contains_key(READ_LATER_RESOLUTION)
                && f.delta_r2 > 0.0
        })
}

/// The parameter that marks a delay read on the real recording's samples: their step, s.
const READ_LATER_RESOLUTION: &str = "resolution_s";

/// The finding of a delay read from the real recording's own samples ([`real_delay`]), with
/// `delta_r2` its share in the joint model and `real_step_s` the samples' step.
fn real_delay_finding(target: &str, delay: &RealDelay, delta_r2: f64, real_step_s: f64) -> Finding {
    let d = delay.delay_s;
    // The simulated value itself, not scaled: a share of one.
    let explanation = format!(
        "{}, read on the real recording's own samples every {real_step_s:.3} s (the simulation's export is too coarse to be moved)",
        library::delay_sentence(target, d, 1.0)
    );
    Finding {
        physics: Physics::SignalDelay.id().to_string(),
        explanation,
        parameters: BTreeMap::from([
            ("delay_s".to_string(), d),
            ("share".to_string(), 1.0),
            (READ_LATER_RESOLUTION.to_string(), real_step_s),
        ]),
        signals: vec![target.to_string()],
        delta_r2,
        p_value: delay.p_value,
        indistinguishable_from: Vec::new(),
        masked_by: None,
        judged_after_refit: false,
        judged_on_bounds: false,
        alternatives: Vec::new(),
    }
}

/// Held-out sum of squared errors of `y` on `columns` (the intercept first).
fn held_out_sse(columns: &[&[f64]], y: &[f64], blocks: &Blocks) -> f64 {
    let gram = ModelGram::new(columns, blocks);
    let products = TargetProducts::new(columns, y, blocks);
    gram.cv_sse(&products.stats(), blocks)
        .unwrap_or_else(|| y.iter().map(|v| v * v).sum())
}

/// Held-out errors of `residual` on `columns` (the intercept first), fold by fold; of the
/// readings taken as bounds where `cut_off` holds them ([`CutOffReadings`]).
fn held_out_errors(
    columns: &[&[f64]],
    residual: &[f64],
    blocks: &Blocks,
    cut_off: Option<&CutOffReadings>,
) -> Vec<f64> {
    if let Some(errors) = cut_off.and_then(|readings| readings.held_out_errors(columns, blocks)) {
        return errors;
    }
    let gram = ModelGram::new(columns, blocks);
    let products = TargetProducts::new(columns, residual, blocks);
    let predicted = gram
        .cv_predictions(columns, &products.stats(), blocks)
        .unwrap_or_else(|| vec![mean(residual); residual.len()]);
    residual
        .iter()
        .zip(&predicted)
        .map(|(r, p)| r - p)
        .collect()
}

/// The sample-to-sample noise of what the corrections leave (`errors`). A reading at the
/// real target's floor shows none of the instrument's noise (a current at 0 A through a
/// standstill, cut off there or from a drive switched off: `silent`), so where the target has
/// a floor its steps are taken only between two readings above it; otherwise more than half
/// of the steps may be nil and the noise read as 0.
fn sample_noise_of(errors: &[f64], aligned: &Aligned, silent: bool) -> f64 {
    let floor = match aligned.censoring {
        Some(censoring) => Some(censoring.floor),
        None if silent => censor::floor_of(&aligned.real_target),
        None => None,
    };
    let Some(floor) = floor else {
        return white_noise_from_differences(errors);
    };
    let above = |i: usize| aligned.real_target.get(i).is_some_and(|r| *r > floor);
    white_noise_of_steps(
        (1..errors.len())
            .filter(|&i| above(i) && above(i - 1))
            .map(|i| errors[i] - errors[i - 1])
            .collect(),
    )
}

/// Held-out R² and RMSE from held-out `errors`.
fn quality_of(errors: &[f64], ss_total: f64) -> FitQuality {
    let sse: f64 = errors.iter().map(|e| e * e).sum();
    FitQuality {
        r2: 1.0 - sse / ss_total,
        rmse: (sse / errors.len().max(1) as f64).sqrt(),
    }
}

/// Held-out R² and RMSE of `y` on `columns` (the intercept first).
fn held_out_quality(columns: &[&[f64]], y: &[f64], blocks: &Blocks, ss_total: f64) -> FitQuality {
    let sse = held_out_sse(columns, y, blocks);
    FitQuality {
        r2: 1.0 - sse / ss_total,
        rmse: (sse / y.len().max(1) as f64).sqrt(),
    }
}

/// A member's columns as bin means, standardised (what the selection works on), each with
/// its scale (`None` for a constant column). Empty when the family could not build them.
type BinnedMember = Arc<Vec<(Vec<f64>, Option<f64>)>>;

/// Builds a member's [`BinnedMember`] on `bins`, which cover every row of `ctx`.
fn binned_with_scales(
    family: &Family,
    ctx: &Context,
    theta: &[f64],
    bins: &[std::ops::Range<usize>],
) -> BinnedMember {
    let columns = match ctx.real_rate {
        Some(_) => build(family, ctx, theta),
        // On the context's own rows the columns are checked once binned, not row by row (a
        // pass over every full-rate column, of which the joint refit builds thousands): the
        // bins cover every row, and a bin holding a value that is not finite has a mean that
        // is not finite either.
        None => (family.build)(ctx, theta),
    };
    let rows = ctx.time.len();
    debug_assert!(
        bins.first().is_none_or(|b| b.start == 0)
            && bins.last().is_none_or(|b| b.end == rows)
            && bins.windows(2).all(|w| w[0].end == w[1].start)
    );
    if columns.iter().any(|c| c.len() != rows) {
        return Arc::new(Vec::new());
    }
    let binned: Vec<Vec<f64>> = columns.iter().map(|c| bin_means(c, bins)).collect();
    if binned.iter().flatten().any(|v| !v.is_finite()) {
        return Arc::new(Vec::new());
    }
    Arc::new(binned.iter().map(|b| select::standardise(b)).collect())
}

/// Most bin values [`FixedMembers`] keeps (128 MB): two thousand columns of 8,192 bins. The
/// selection's candidates take about half; the rest keeps the time constants the refit's
/// searches try round after round (half as much kept the candidates alone, and a 24 h case
/// built a fifth of its members of fixed shape again).
const FIXED_MEMBERS_BUDGET: usize = 16 << 20;

/// The binned columns of members whose shape does not depend on the target's state, kept once
/// built. The joint refit chooses every correction again from its whole family in each round,
/// and a refused step asked again refits the model once per rival kind, so the same members
/// are built over and over: room and copper heat concealed over 24 h built 3,162 such members,
/// 1,041 of them distinct. Shared by the copies of a joint model, which all stand on the same
/// context and bins; the kept columns are the very ones a build would give, so keeping them
/// changes no figure. The analysis starts it with the selection's candidates of fixed shape,
/// built the same way. Past [`FIXED_MEMBERS_BUDGET`] nothing more is kept.
#[derive(Clone)]
struct FixedMembers {
    /// By (family, the parameters' bits); sized in bin values.
    kept: Arc<kept::Kept<(usize, Vec<u64>), BinnedMember>>,
}

impl Default for FixedMembers {
    fn default() -> Self {
        FixedMembers {
            kept: Arc::new(kept::Kept::new(FIXED_MEMBERS_BUDGET)),
        }
    }
}

impl FixedMembers {
    fn key(family: usize, theta: &[f64]) -> (usize, Vec<u64>) {
        (family, theta.iter().map(|t| t.to_bits()).collect())
    }

    fn get(&self, family: usize, theta: &[f64]) -> Option<BinnedMember> {
        self.kept.get(&Self::key(family, theta))
    }

    fn keep(&self, family: usize, theta: &[f64], member: &BinnedMember) {
        let values: usize = member.iter().map(|(c, _)| c.len()).sum();
        self.kept.keep(Self::key(family, theta), member, values);
    }
}

/// Rounds of the joint refit after each acceptance (time constants member by member, then the
/// state correction to convergence).
const JOINT_ROUNDS: usize = 3;

/// How finely a member's parameter is refined, as a share of the span between its grid
/// neighbours (a coolant speed-up: of its log range): 0.07 % of τ on the doubling grid of
/// time constants, a thousandth of a sample on the delays' grid. A golden-section search took
/// 16 rebuilds of the member to get there; Brent's parabolas need fewer where the error is
/// smooth (docs/performance.md: refining took 24 % of a 24 h report's CPU instead of 36 %).
const REFINE_TOLERANCE: f64 = 5e-4;

/// Grid members refined before a correction's member is chosen again in the joint refit.
const RESELECT_REFINED: usize = 3;

/// Most fixed-point iterations of the state correction per round.
const STATE_ITERATIONS: usize = 12;

/// Most times the joint refit chooses a correction again to keep it within its gain limits
/// before withdrawing it ([`Joint::keep_within_limits`]).
const LIMIT_ROUNDS: usize = 2;

/// The columns a member is fitted beside in the joint model (the intercept first, then the
/// other corrections), with their block statistics computed once: choosing a correction's
/// member again fits every member of its family beside the same others.
struct Beside<'c> {
    columns: Vec<&'c [f64]>,
    gram: ModelGram,
    /// The target's products with them.
    products: TargetProducts,
}

impl<'c> Beside<'c> {
    fn new(others: &'c [Vec<f64>], blocks: &Blocks, y: &[f64]) -> Beside<'c> {
        let columns: Vec<&[f64]> = others.iter().map(|c| c.as_slice()).collect();
        Beside {
            gram: ModelGram::new(&columns, blocks),
            products: TargetProducts::new(&columns, y, blocks),
            columns,
        }
    }
}

/// The member [`Joint::reselect`] chose.
struct Reselected {
    theta: Vec<f64>,
    /// The member with its parameter refined beside the corrections it was chosen beside,
    /// when the choice already ran that search: the member is a refined contender, or a grid
    /// member that was refined as one. Refining it again would repeat the search on the same
    /// data.
    refined: Option<Vec<f64>>,
}

/// A member's fit in the joint model.
struct MemberFit {
    /// Held-out sum of squared errors over the selection's blocks.
    held_out_sse: f64,
    /// Whether its coefficients lie within its family's gain limits.
    within_limits: bool,
}

/// The accepted corrections, refitted jointly.
///
/// After a correction is accepted, every accepted correction's time constant (or delay) is
/// refined again with all the others in the model, one member at a time, and the
/// state-dependent ones ([`Family::state`]) are rebuilt on the corrected simulation until the
/// correction they produce reproduces itself (a fixed point: extra cooling acting on the
/// temperature the part really has). The next stepwise step then works on the residual of
/// this joint model, so a first correction that took a share of a second effect gives it back
/// once the second is in the model.
#[derive(Clone)]
struct Joint<'a> {
    families: &'a [Family],
    /// The selection's candidate members (what [`JointModel::accept`] is given).
    members: &'a [Member],
    /// The selection's blocks (on the binned rows), for choosing members by held-out error.
    blocks: &'a Blocks,
    /// Moving-average window of the selection's high-passed view, bins.
    highpass_window: usize,
    ctx: &'a Context,
    bins: &'a [std::ops::Range<usize>],
    y: &'a [f64],
    /// (family, parameters) in the order accepted.
    accepted: Vec<(usize, Vec<f64>)>,
    /// Whether each accepted correction is still in the model (a later one may make it
    /// redundant: see [`Joint::prune`]).
    active: Vec<bool>,
    /// Smallest held-out gain a correction must keep in the joint model, as a share of the
    /// held-out error without it.
    min_relative_gain: f64,
    /// Full-rate correction of the target's state (sum of the fitted physical corrections).
    state: Option<Vec<f64>>,
    /// The analysis's observer: the refit stops early once it says stop (the analysis then
    /// ends with `Cancelled` at the next report, so the unfinished refit is never used).
    watch: &'a Watch<'a>,
    /// Members of fixed shape already built on `ctx` and `bins`.
    fixed: FixedMembers,
    /// The families whose corrections may be chosen again among their refinements
    /// ([`Family::refinements`]): none while the selection runs, which names the physics with
    /// the members it was offered, only in the refit after it.
    refinable: Vec<usize>,
}

impl Joint<'_> {
    /// The context state-dependent families are built on.
    fn state_context(&self) -> Context {
        match &self.state {
            Some(state) => self.ctx.with_state(state),
            None => self.ctx.clone(),
        }
    }

    /// Binned, standardised columns of every accepted correction on `state_ctx`.
    fn columns(&self, state_ctx: &Context, skip: Option<usize>) -> Vec<Vec<f64>> {
        self.accepted
            .iter()
            .enumerate()
            .filter(|(k, _)| Some(*k) != skip && self.active[*k])
            .flat_map(|(_, (family, theta))| {
                let ctx = if self.families[*family].state {
                    state_ctx
                } else {
                    self.ctx
                };
                self.binned(*family, ctx, theta)
                    .iter()
                    .map(|(c, _)| c.clone())
                    .collect::<Vec<_>>()
            })
            .collect()
    }

    /// The member `theta` of `family` built on `ctx`, binned and standardised; members of
    /// fixed shape on the model's own context are built once ([`FixedMembers`]).
    fn binned(&self, family: usize, ctx: &Context, theta: &[f64]) -> BinnedMember {
        let f = &self.families[family];
        let fixed = !f.state && std::ptr::eq(ctx, self.ctx);
        if fixed && let Some(kept) = self.fixed.get(family, theta) {
            return kept;
        }
        let member = binned_with_scales(f, ctx, theta, self.bins);
        if fixed {
            self.fixed.keep(family, theta, &member);
        }
        member
    }

    /// Accepts a member refined on top of `base`, refits everything jointly and returns the
    /// new base columns (the intercept excluded) for the next step.
    fn accept(&mut self, family: usize, theta: &[f64], base: &[Vec<f64>]) -> Vec<Vec<f64>> {
        let state_ctx = self.state_context();
        let ctx = if self.families[family].state {
            &state_ctx
        } else {
            self.ctx
        };
        let theta = self.refine_member(family, theta, base, ctx);
        self.accepted.push((family, theta));
        self.active.push(true);
        self.refit_jointly();
        while self.prune() {
            self.refit_jointly();
        }
        self.columns(&self.state_context(), None)
    }

    /// Refits every active correction: time constants one member at a time, and the state
    /// correction to its fixed point.
    fn refit_jointly(&mut self) {
        let stateful = self.stateful();
        if !stateful {
            self.state = None;
        }
        for round in 0..JOINT_ROUNDS {
            if self
                .watch
                .should_stop(|| format!("refitting the corrections jointly (round {})", round + 1))
            {
                return;
            }
            // Time constants, one member at a time with all the others in the model. Even a
            // single correction is chosen again from its whole family: the selection offered
            // only lags the recording can identify (`SELECTION_LONGEST_LAG_SHARE`), and the
            // physics, once named, may need a slower one to fit.
            let state_ctx = self.state_context();
            for k in 0..self.accepted.len() {
                if !self.active[k] {
                    continue;
                }
                let others = self.others(&state_ctx, k);
                let (family, theta) = &self.accepted[k];
                let family_ref = &self.families[*family];
                let ctx = if family_ref.state {
                    &state_ctx
                } else {
                    self.ctx
                };
                let chosen = self.reselect(*family, theta, &others, ctx);
                // A member refined beside these very corrections is not refined again.
                self.accepted[k].1 = chosen
                    .refined
                    .unwrap_or_else(|| self.refine_member(*family, &chosen.theta, &others, ctx));
            }
            if !stateful {
                break;
            }
            self.settle_state();
        }
    }

    /// Whether an active correction is built on the target's own state.
    fn stateful(&self) -> bool {
        self.accepted
            .iter()
            .zip(&self.active)
            .any(|((f, _), a)| *a && self.families[*f].state)
    }

    /// Occam asked once more, beside every correction the selection named: a correction of a
    /// kind that nests a simpler one ([`library::nested_simpler`]) gives way to the simpler
    /// one when the model with it predicts the held-out blocks no significantly worse in
    /// either view (the paired test of the selection's own Occam rule, `distinguish_t`).
    /// At the step that named it the model lacked what came later: on the independent check's
    /// seed 2 a friction profile along the stroke took a Coulomb step on a current recorded
    /// 16 s late together with part of the delay's error at the reversals, and once the delay
    /// was in, its shape along the stroke added nothing. Both views, because under slow
    /// correlated noise the data as they are could not tell a concealed profile from its flat
    /// part where the high-passed data do (the twin's grid, position profile on the X torque:
    /// 0 / 5 named with the first view alone). The step then reports the simpler kind, the
    /// nesting one first among those the data cannot tell from it; its gain and p-value stay
    /// those of the step that named the nesting one.
    fn simpler_where_nested(&mut self, steps: &mut [Step], members: &[Member], distinguish_t: f64) {
        for k in 0..self.accepted.len() {
            if !self.active[k] || self.watch.stopped() {
                continue;
            }
            let nesting = &self.families[self.accepted[k].0];
            let Some((kind, theta)) = library::nested_simpler(nesting.kind) else {
                continue;
            };
            let in_model = self
                .accepted
                .iter()
                .zip(&self.active)
                .any(|((f, _), active)| *active && self.families[*f].kind == kind);
            let simpler = self
                .families
                .iter()
                .position(|f| f.kind == kind && f.axis == nesting.axis && !f.lagged);
            let Some((simpler, member)) = simpler.filter(|_| !in_model).and_then(|family| {
                let member = members
                    .iter()
                    .position(|m| m.family == family && m.theta == theta)?;
                Some((family, member))
            }) else {
                continue;
            };
            let Some(reference) = self.held_out_block_errors() else {
                continue;
            };
            let mut trial = self.clone();
            trial.accepted[k] = (simpler, theta.to_vec());
            trial.refit_jointly();
            if trial.keep_within_limits(trial.stateful()) {
                continue;
            }
            let Some(errors) = trial.held_out_block_errors() else {
                continue;
            };
            let worse_in = |view: usize| {
                select::significantly_worse(&errors[view], &reference[view], distinguish_t)
            };
            if worse_in(0) || worse_in(1) {
                continue;
            }
            *self = trial;
            if let Some(step) = steps.iter_mut().filter(|s| s.accepted).nth(k) {
                let relative = step.gain / step.sse_before.max(f64::MIN_POSITIVE);
                step.runners_up
                    .retain(|(m, _)| self.families[members[*m].family].kind != kind);
                step.runners_up.insert(0, (step.member, relative));
                step.indistinguishable.retain(|&m| m != member);
                step.indistinguishable.insert(0, step.member);
                step.member = member;
            }
        }
    }

    /// The held-out squared error of every block of the joint model in both views of the
    /// selection: the data as they are, and high-passed (where a fast correction that slow
    /// correlated noise hides in the data as they are still shows, as in [`Joint::prune`]).
    fn held_out_block_errors(&self) -> Option<[Vec<f64>; 2]> {
        let columns = self.columns(&self.state_context(), None);
        let block_errors = |y: &[f64], high: bool| {
            let mut all = vec![vec![1.0; self.y.len()]];
            all.extend(columns.iter().map(|c| {
                if high {
                    select::highpass(c, self.highpass_window)
                } else {
                    c.clone()
                }
            }));
            let refs: Vec<&[f64]> = all.iter().map(|c| c.as_slice()).collect();
            let gram = ModelGram::new(&refs, self.blocks);
            let products = TargetProducts::new(&refs, y, self.blocks);
            gram.cv_block_sse(&products.stats(), self.blocks)
        };
        let y_high = select::highpass(self.y, self.highpass_window);
        Some([block_errors(self.y, false)?, block_errors(&y_high, true)?])
    }

    /// Backward elimination in the joint model: with more than one correction in it, the one
    /// whose removal costs the least held-out error is withdrawn when that cost is below the
    /// smallest gain a step must bring (a later, better correction explains what it took).
    /// Returns whether one was withdrawn.
    fn prune(&mut self) -> bool {
        let active: Vec<usize> = (0..self.accepted.len())
            .filter(|k| self.active[*k])
            .collect();
        if active.len() < 2 {
            return false;
        }
        let state_ctx = self.state_context();
        // Judged in both views of the selection: a fast correction that slow correlated noise
        // hides in the data as they are still counts where the high-pass shows it.
        let y_high = select::highpass(self.y, self.highpass_window);
        let cv = |skip: Option<usize>, high: bool| -> f64 {
            self.held_out_error(&state_ctx, skip, high.then_some(y_high.as_slice()))
        };
        let cost_in = |k: usize, high: bool, all: f64| -> f64 {
            let without = cv(Some(k), high);
            if without > 0.0 {
                (without - all) / without
            } else {
                0.0
            }
        };
        let (all_raw, all_high) = (cv(None, false), cv(None, true));
        let weakest = active
            .iter()
            .map(|&k| {
                (
                    k,
                    cost_in(k, false, all_raw).max(cost_in(k, true, all_high)),
                )
            })
            .min_by(|a, b| a.1.total_cmp(&b.1));
        match weakest {
            Some((k, cost)) if cost < self.min_relative_gain => {
                self.active[k] = false;
                true
            }
            _ => false,
        }
    }

    /// The held-out squared error of the joint model on the binned rows: the intercept and
    /// every active correction but `skip`, in the data as they are or, given the high-passed
    /// target `y_high`, in the high-passed view.
    fn held_out_error(
        &self,
        state_ctx: &Context,
        skip: Option<usize>,
        y_high: Option<&[f64]>,
    ) -> f64 {
        let mut columns = vec![vec![1.0; self.y.len()]];
        columns.extend(self.columns(state_ctx, skip).into_iter().map(|c| {
            if y_high.is_some() {
                select::highpass(&c, self.highpass_window)
            } else {
                c
            }
        }));
        let refs: Vec<&[f64]> = columns.iter().map(|c| c.as_slice()).collect();
        held_out_sse(&refs, y_high.unwrap_or(self.y), self.blocks)
    }

    /// How the member `theta` of `family` fits beside `others` (the intercept first) in the
    /// model: its held-out error, and whether its coefficients lie within the family's gain
    /// limits. `None` when its columns cannot be built or the model cannot be fitted.
    fn member_fit(
        &self,
        family: usize,
        theta: &[f64],
        others: &Beside<'_>,
        ctx: &Context,
    ) -> Option<MemberFit> {
        let f = &self.families[family];
        let columns = self.binned(family, ctx, theta);
        if columns.is_empty() {
            return None;
        }
        let scales: Vec<f64> = columns.iter().map(|(_, s)| s.unwrap_or(0.0)).collect();
        let own: Vec<&[f64]> = columns.iter().map(|(c, _)| c.as_slice()).collect();
        let gram = others.gram.extended(&others.columns, &own, self.blocks);
        let own_zty: Vec<Vec<f64>> = own.iter().map(|c| self.blocks.dots(c, self.y)).collect();
        let stats = TargetStats {
            zty: others
                .products
                .zty
                .iter()
                .chain(&own_zty)
                .map(|v| v.as_slice())
                .collect(),
            yty: &others.products.yty,
        };
        let within_limits = f.limits.is_empty() || {
            let beta = gram.full_fit(&stats, self.blocks)?;
            let first = others.columns.len();
            let raw = |k: usize| (scales[k] > 0.0).then(|| beta[first + k] / scales[k]);
            f.within_limits(theta, columns.len(), raw)
        };
        Some(MemberFit {
            held_out_sse: gram.cv_sse(&stats, self.blocks)?,
            within_limits,
        })
    }

    /// Keeps every correction of the joint model within its physics' gain limits. The
    /// selection admitted each within them, but the joint refit moves every coefficient and,
    /// for a state-dependent correction, the state it acts on: a convective cooling fitted
    /// beside another correction could end up warming the part, and its explanation would then
    /// name physics the fit contradicts. A correction outside its limits is chosen again among
    /// the members they admit (the state settled again after), at most [`LIMIT_ROUNDS`]
    /// times; one still outside them is withdrawn. Returns whether one was withdrawn.
    fn keep_within_limits(&mut self, stateful: bool) -> bool {
        for _ in 0..LIMIT_ROUNDS {
            let outside = self.outside_limits();
            if outside.is_empty() || self.watch.stopped() {
                return false;
            }
            let state_ctx = self.state_context();
            for k in outside {
                let others = self.others(&state_ctx, k);
                let (family, theta) = self.accepted[k].clone();
                let ctx = if self.families[family].state {
                    &state_ctx
                } else {
                    self.ctx
                };
                self.accepted[k].1 = self.reselect(family, &theta, &others, ctx).theta;
            }
            if stateful {
                self.settle_state();
            }
        }
        let outside = self.outside_limits();
        for &k in &outside {
            self.active[k] = false;
        }
        !outside.is_empty()
    }

    /// The active corrections whose coefficients in the joint model break their family's
    /// gain limits.
    fn outside_limits(&self) -> Vec<usize> {
        let state_ctx = self.state_context();
        (0..self.accepted.len())
            .filter(|&k| self.active[k] && !self.families[self.accepted[k].0].limits.is_empty())
            .filter(|&k| {
                let others = self.others(&state_ctx, k);
                let (family, theta) = &self.accepted[k];
                let ctx = if self.families[*family].state {
                    &state_ctx
                } else {
                    self.ctx
                };
                let others = Beside::new(&others, self.blocks, self.y);
                self.member_fit(*family, theta, &others, ctx)
                    .is_some_and(|fit| !fit.within_limits)
            })
            .collect()
    }

    /// The intercept and every active correction but `skip`, as the joint model's columns.
    fn others(&self, state_ctx: &Context, skip: usize) -> Vec<Vec<f64>> {
        let mut others = vec![vec![1.0; self.y.len()]];
        others.extend(self.columns(state_ctx, Some(skip)));
        others
    }

    /// The member of `family` (its grid and the current parameters `current`) that predicts
    /// the held-out blocks best with `others` (the intercept first) in the model, among those
    /// the family's gain limits admit. The stepwise step chose the member before the other
    /// corrections and the corrected state were known; with them, another lag shape may fit.
    fn reselect(
        &self,
        family: usize,
        current: &[f64],
        others: &[Vec<f64>],
        ctx: &Context,
    ) -> Reselected {
        let f = &self.families[family];
        let mut grid: Vec<Vec<f64>> = f
            .grid
            .iter()
            .filter(|theta| {
                self.refinable.contains(&family) || !f.uses_refit_only_refinement(theta)
            })
            .cloned()
            .collect();
        grid.push(current.to_vec());
        let beside = Beside::new(others, self.blocks, self.y);
        let score = |theta: &Vec<f64>| -> f64 {
            match self.member_fit(family, theta, &beside, ctx) {
                Some(fit) if fit.within_limits => fit.held_out_sse,
                _ => f64::INFINITY,
            }
        };
        let scored = parallel_map(&grid, score);
        let mut ranked: Vec<(Vec<f64>, f64)> = grid
            .into_iter()
            .zip(scored)
            .filter(|(_, e)| e.is_finite())
            .collect();
        ranked.sort_by(|a, b| a.1.total_cmp(&b.1));
        // Grid members are compared at grid time constants while the current one is refined;
        // the best few are refined too before the choice, so a lag shape is not lost for
        // want of its τ being on the grid.
        let contenders: Vec<Vec<f64>> = ranked
            .iter()
            .take(RESELECT_REFINED)
            .map(|(theta, _)| theta.clone())
            .collect();
        let refined = parallel_map(&contenders, |theta| {
            let theta = self.refine_member(family, theta, others, ctx);
            let error = score(&theta);
            (theta, error)
        });
        let best = ranked
            .into_iter()
            .map(|(theta, e)| (theta, e, false))
            .chain(refined.iter().map(|(theta, e)| (theta.clone(), *e, true)))
            .filter(|(_, e, _)| e.is_finite())
            .min_by(|a, b| a.1.total_cmp(&b.1));
        match best {
            None => Reselected {
                theta: current.to_vec(),
                refined: None,
            },
            Some((theta, _, true)) => Reselected {
                refined: Some(theta.clone()),
                theta,
            },
            // A grid member chosen as it stands keeps the refinement it had as a contender.
            Some((theta, _, false)) => Reselected {
                refined: contenders
                    .iter()
                    .position(|c| *c == theta)
                    .map(|k| refined[k].0.clone()),
                theta,
            },
        }
    }

    /// Iterates the state correction to its fixed point: fit every accepted correction, take
    /// the physical ones' sum at full rate as the state, rebuild, repeat. Stops when the state
    /// moves by less than 0.1 % of the residual's spread, and keeps the last state that did
    /// not make the in-sample fit worse (a fixed point that runs away is not used).
    fn settle_state(&mut self) {
        let spread = series::std_dev(self.y).max(f64::MIN_POSITIVE);
        let ones = vec![1.0; self.y.len()];
        let mut previous_sse = f64::INFINITY;
        for _ in 0..STATE_ITERATIONS {
            if self.watch.stopped() {
                return;
            }
            let state_ctx = self.state_context();
            // Full-rate columns, their binned standardised form, and the joint fit.
            let full: Vec<(usize, Vec<Vec<f64>>)> = self
                .accepted
                .iter()
                .zip(&self.active)
                .filter(|(_, a)| **a)
                .map(|((family, theta), _)| {
                    let f = &self.families[*family];
                    let ctx = if f.state { &state_ctx } else { self.ctx };
                    (*family, build(f, ctx, theta))
                })
                .collect();
            let mut design: Vec<Vec<f64>> = vec![ones.clone()];
            let mut scales = Vec::new();
            for (_, columns) in &full {
                for c in columns {
                    let (standard, scale) = select::standardise(&bin_means(c, self.bins));
                    design.push(standard);
                    scales.push(scale.unwrap_or(0.0));
                }
            }
            let refs: Vec<&[f64]> = design.iter().map(|c| c.as_slice()).collect();
            let Some((beta, sse)) = least_squares(&refs, self.y) else {
                return;
            };
            if sse > previous_sse * (1.0 + 1e-9) {
                return;
            }
            previous_sse = sse;
            // The physical state: every correction but calibration and measurement effects.
            let n = self.ctx.time.len();
            let mut state = vec![0.0; n];
            let mut index = 0;
            for (family, columns) in &full {
                let physical = match self.families[*family].kind {
                    Kind::Physics(p) => {
                        !matches!(p, Physics::SignalDelay | Physics::SensorOffsetDrift)
                    }
                    Kind::CalibrationGain => false,
                };
                for c in columns {
                    let scale = scales[index];
                    let b = beta[1 + index];
                    index += 1;
                    if !physical || scale <= 0.0 {
                        continue;
                    }
                    // Uncentred: a correction is zero where its driver is (the part at rest
                    // at room temperature), and its mean level is part of the state.
                    let raw = b / scale;
                    for (s, v) in state.iter_mut().zip(c) {
                        *s += raw * v;
                    }
                }
            }
            if state.iter().any(|v| !v.is_finite()) {
                return;
            }
            let moved = match &self.state {
                Some(old) => old
                    .iter()
                    .zip(&state)
                    .fold(0.0_f64, |m, (a, b)| m.max((a - b).abs())),
                None => state.iter().fold(0.0_f64, |m, v| m.max(v.abs())),
            };
            self.state = Some(state);
            if moved < 1e-3 * spread {
                return;
            }
        }
    }

    /// Refines a member's first nonlinear parameter (τ on a log scale, a delay on a linear one)
    /// between its grid neighbours by a search (Brent's) of the in-sample error on top of
    /// `base`; the grid value stays when the search finds nothing better. Then, for a member
    /// chosen by its coolant speed-up ([`library::selectable_coolant_speedup_index`]), the
    /// speed-up over [`library::COOLANT_SPEEDUP_RANGE`], on a log scale.
    fn refine_member(
        &self,
        index: usize,
        theta: &[f64],
        base: &[Vec<f64>],
        ctx: &Context,
    ) -> Vec<f64> {
        let family = &self.families[index];
        let Some(refine) = family.refine else {
            return theta.to_vec();
        };
        let current = theta[0];
        // A nested member (τ = 0: no lag at all) has nothing to refine.
        if refine.log && current == 0.0 {
            return theta.to_vec();
        }
        // The search runs between the nearest grid values below and above the current one among
        // members that share the other parameters (the current value may lie between grid points
        // after an earlier refinement). A refined coolant speed-up lies between grid values
        // too: there, members that share it are those that use the coolant when this one does.
        let speedup = library::selectable_coolant_speedup_index(family);
        let shares_the_rest = |t: &[f64]| {
            (1..theta.len()).all(|i| {
                if Some(i) == speedup {
                    (t[i] > 0.0) == (theta[i] > 0.0)
                } else {
                    t[i] == theta[i]
                }
            })
        };
        let values: Vec<f64> = family
            .grid
            .iter()
            .filter(|t| shares_the_rest(t) && t[0].signum() == current.signum())
            .map(|t| t[0])
            .collect();
        let lower = values
            .iter()
            .copied()
            .filter(|v| *v < current)
            .max_by(f64::total_cmp)
            .unwrap_or(current);
        let upper = values
            .iter()
            .copied()
            .filter(|v| *v > current)
            .min_by(f64::total_cmp)
            .unwrap_or(current);
        // A member chosen by its coolant speed-up has that to refine even where τ has no
        // grid neighbours (a short recording's single τ).
        let refined_speedup = speedup.filter(|i| theta.get(*i).is_some_and(|g| *g > 0.0));
        if lower == upper && refined_speedup.is_none() {
            return theta.to_vec();
        }
        let base_columns: Vec<&[f64]> = base.iter().map(|c| c.as_slice()).collect();
        let base = NormalEquations::new(&base_columns, self.y);
        let mut out = theta.to_vec();
        if lower != upper {
            // Time constants are searched on a log scale, delays on a linear one.
            let to = |v: f64| if refine.log { v.abs().ln() } else { v };
            let sign = if refine.log { current.signum() } else { 1.0 };
            let from = |u: f64| if refine.log { sign * u.exp() } else { u };
            out = self.search_parameter(index, ctx, &base, out, 0, (to(lower), to(upper)), from);
        }
        if let Some(i) = refined_speedup {
            // How much faster a part sheds heat while the coolant flows is a property of the
            // part (its coolant's conductance over its other paths'), not a grid value: on the
            // independent check's nut (seed 10, true 0.83; a Python check with one lag), lags
            // switched by 0.5 or 1 left 0.14 and 0.13 °C where 0.83 left 0.076 °C.
            let (low, high) = library::COOLANT_SPEEDUP_RANGE;
            out = self.search_parameter(index, ctx, &base, out, i, (low.ln(), high.ln()), f64::exp);
        }
        out
    }

    /// `theta` with its parameter `at` replaced by the value that a search (Brent's) over
    /// `interval`, mapped to the parameter by `from`, finds of least in-sample error on top of
    /// `base`; unchanged when the search finds nothing better than its current value.
    #[allow(clippy::too_many_arguments)]
    fn search_parameter(
        &self,
        index: usize,
        ctx: &Context,
        base: &NormalEquations,
        theta: Vec<f64>,
        at: usize,
        interval: (f64, f64),
        from: impl Fn(f64) -> f64,
    ) -> Vec<f64> {
        let sse_at = |value: f64| -> f64 {
            let mut candidate = theta.clone();
            candidate[at] = value;
            let own = self.binned(index, ctx, &candidate);
            let own: Vec<&[f64]> = own.iter().map(|(c, _)| c.as_slice()).collect();
            base.fit_with(&own).map_or(f64::INFINITY, |(_, sse)| sse)
        };
        let (a, b) = interval;
        let found = crate::fit::minimise::minimise_on_interval(
            |u| sse_at(from(u)),
            a,
            b,
            REFINE_TOLERANCE * (b - a).abs(),
        );
        let best = from(found.at);
        let mut out = theta.clone();
        if found.value <= sse_at(theta[at]) {
            out[at] = best;
        }
        out
    }
}

impl JointModel for Joint<'_> {
    fn accept(&mut self, member: usize, base: &[Vec<f64>]) -> Vec<Vec<f64>> {
        let Member { family, theta, .. } = &self.members[member];
        Joint::accept(self, *family, theta, base)
    }

    /// Keeps every correction within its physics' gain limits
    /// ([`Joint::keep_within_limits`]), refitting jointly after each withdrawal. The selection
    /// asks for this when it would stop, not after each step: on the way, a first correction
    /// fitted alone may stand outside its limits until the effect it was taking a share of
    /// enters the model (copper heat beside the room on a stator: negative until the room was
    /// in, positive after).
    fn settle(&mut self) -> Option<Vec<Vec<f64>>> {
        if self.outside_limits().is_empty() {
            return None;
        }
        while self.keep_within_limits(self.stateful()) {
            self.refit_jointly();
            while self.prune() {
                self.refit_jointly();
            }
        }
        Some(self.columns(&self.state_context(), None))
    }
}

/// The parameters of a report's findings by physics id (a convenience for tests and the HMI).
pub fn parameters_by_physics(
    report: &DiscrepancyReport,
) -> BTreeMap<String, BTreeMap<String, f64>> {
    report
        .findings
        .iter()
        .map(|f| (f.physics.clone(), f.parameters.clone()))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Mutex;

    /// An error is gross from four times the noise from sample to sample; where that noise
    /// reads zero it cannot be told, and no error is gross.
    #[test]
    fn no_error_is_gross_beside_a_sample_noise_that_cannot_be_told() {
        assert!((gross_mismatch_beside(0.05) - 0.2).abs() < 1e-12);
        assert_eq!(gross_mismatch_beside(0.0), f64::INFINITY);
    }

    /// A member whose columns hold a value that is not finite is not offered: built for the
    /// selection it is checked once binned, and its bin's mean is not finite either.
    #[test]
    fn a_member_with_a_value_that_is_not_finite_is_dropped_once_binned() {
        let columns = ["time_s", "S.stator_temp_C"];
        let ctx = library::same_grid_context(&columns, "S.stator_temp_C", 1000, |i| {
            let t = f64::from(i);
            (vec![t, 20.0], vec![t, 20.0 + 1e-3 * t])
        });
        let bins = bin_ranges(ctx.time.len(), 64);
        let member_with = |bad: f64| {
            let family = Family {
                kind: Kind::Physics(library::Physics::SensorOffsetDrift),
                signals: Vec::new(),
                theta_names: Vec::new(),
                grid: vec![Vec::new()],
                refine: None,
                build: Box::new(move |ctx: &Context, _: &[f64]| {
                    let mut column = ctx.time.clone();
                    column[537] = bad;
                    vec![column]
                }),
                limits: Vec::new(),
                lagged: false,
                axis: None,
                state: false,
                refinements: Vec::new(),
                free_start: None,
            };
            binned_with_scales(&family, &ctx, &[], &bins)
        };
        assert_eq!(member_with(537.0).len(), 1);
        for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            assert!(member_with(bad).is_empty(), "{bad} was offered");
        }
    }

    /// The observer hears a fraction that never falls (a later phase may report less than an
    /// earlier estimate), and once it says stop every later report is `Cancelled` without
    /// asking it again; nobody watching never stops.
    #[test]
    fn a_watch_reports_rising_fractions_and_stays_stopped() {
        let heard = Mutex::new(Vec::new());
        let observer = |fraction: f32, stage: &str| {
            heard.lock().expect("not poisoned").push(fraction);
            stage != "stop here"
        };
        let watch = Watch::new(Some(&observer));
        assert!(watch.report(0.5, || "half".into()).is_ok());
        assert!(watch.report(0.3, || "less".into()).is_ok());
        assert!(!watch.should_stop(|| "still going".into()));
        assert!(watch.report(2.0, || "clamped".into()).is_ok());
        assert!(watch.should_stop(|| "stop here".into()));
        assert!(watch.stopped());
        assert!(matches!(
            watch.report(1.0, || "after".into()),
            Err(DiscrepancyError::Cancelled)
        ));
        assert_eq!(
            heard.into_inner().expect("not poisoned"),
            [0.5, 0.5, 0.5, 1.0, 1.0]
        );

        let unwatched = Watch::new(None);
        assert!(
            unwatched
                .report(0.5, || unreachable!("not formatted"))
                .is_ok()
        );
        assert!(!unwatched.should_stop(|| unreachable!("not formatted")));
    }

    /// Reports from several worker threads at once reach the observer in rising order: the
    /// candidates are built in parallel, and a progress bar that steps back looks broken.
    #[test]
    fn reports_from_many_threads_reach_the_observer_in_rising_order() {
        let heard = Mutex::new(Vec::new());
        let observer = |fraction: f32, _: &str| {
            heard.lock().expect("not poisoned").push(fraction);
            true
        };
        let watch = Watch::new(Some(&observer));
        let threads = 4;
        let per_thread = 20_000;
        std::thread::scope(|scope| {
            for thread in 0..threads {
                let watch = &watch;
                scope.spawn(move || {
                    for i in 0..per_thread {
                        let step = i * threads + thread;
                        let fraction = step as f32 / (threads * per_thread) as f32;
                        assert!(watch.report(fraction, String::new).is_ok());
                    }
                });
            }
        });
        let heard = heard.into_inner().expect("not poisoned");
        assert_eq!(heard.len(), threads * per_thread);
        let falls = heard.windows(2).filter(|w| w[1] < w[0]).count();
        assert_eq!(falls, 0, "the fraction fell {falls} times");

        // Once one thread's report is told stop, no other thread asks again.
        let asked = Mutex::new((0_usize, false));
        let stop_once_asked_enough = |_: f32, _: &str| {
            let mut asked = asked.lock().expect("not poisoned");
            assert!(!asked.1, "asked again after being told stop");
            asked.0 += 1;
            asked.1 = asked.0 == 100;
            // Long enough for the other threads to be waiting to report.
            std::thread::sleep(std::time::Duration::from_micros(200));
            !asked.1
        };
        let watch = Watch::new(Some(&stop_once_asked_enough));
        std::thread::scope(|scope| {
            for _ in 0..threads {
                let watch = &watch;
                scope.spawn(move || while watch.report(0.5, String::new).is_ok() {});
            }
        });
        assert_eq!(asked.into_inner().expect("not poisoned"), (100, true));
    }

    #[test]
    fn the_fold_sign_flip_test_counts_the_patterns_at_least_as_good() {
        // Every fold better: only the pattern observed reaches its total.
        let every = [1.0, 2.0, 0.5, 3.0, 1.0, 1.0, 2.0, 0.1];
        assert_eq!(fold_sign_flip_p(&every, 1), 1.0 / 256.0);
        // Every fold worse: every pattern is at least as good.
        let worse: Vec<f64> = every.iter().map(|d| -d).collect();
        assert_eq!(fold_sign_flip_p(&worse, 1), 1.0);
        // One small loss beside larger gains: the observed pattern and the one with that
        // fold's sign turned (every fold a gain) reach its total; turning any other does not.
        let one_loss = [1.0, 2.0, 0.5, 3.0, 1.0, 1.0, 2.0, -0.1];
        assert_eq!(fold_sign_flip_p(&one_loss, 1), 2.0 / 256.0);
        // Past the exact count the patterns are drawn: about one in 2^20 reaches all positive,
        // so the observed one alone counts.
        let many = [1.0; 20];
        let p = fold_sign_flip_p(&many, 7);
        assert!(p > 0.0 && p < 1e-4, "{p}");
    }
}
