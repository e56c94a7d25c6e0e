//! The report: DESIGN.md's JSON contract (`target, rows, verdict, baseline, improved,
//! mismatch_regions, findings`) plus calibration, agreement regions, noise floor, alignment and
//! method, a readable text rendering, and the plot-ready series the HMI draws.

use std::collections::BTreeMap;
use std::fmt::Write as _;

use super::localise::Region;

/// The overall answer.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Verdict {
    /// At least one missing physics was found.
    MissingPhysics,
    /// Nothing significant beyond calibration: the simulation agrees with the real recording
    /// within its noise.
    Consistent,
}

/// R² and RMSE of a prediction of the real target.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct FitQuality {
    /// Coefficient of determination against the real target's own variance.
    pub r2: f64,
    /// Root-mean-square error, target unit.
    pub rmse: f64,
}

/// What the report says of a finding accepted after the refit
/// ([`Finding::judged_after_refit`]), in the text summary and the Model lab alike.
pub const JUDGED_AFTER_REFIT: &str = "found with the corrections before it refitted beside it: as they stood, it did not clear the surrogates";

/// What the report says of a finding accepted on a censored target's readings at the floor
/// taken as bounds ([`Finding::judged_on_bounds`]).
pub const JUDGED_ON_BOUNDS: &str = "found on the readings at the instrument's floor taken as bounds: with them taken as values it did not clear the surrogates; its p-value is a sign-flip test of what it saves in each fold";

/// A missing physics found, with its fitted correction.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Finding {
    /// The vocabulary id.
    pub physics: String,
    /// A sentence with the fitted parameters in physical units.
    pub explanation: String,
    /// The fitted parameters (names carry their units: `tau_min`, `delay_s`, `gain_per_K`…).
    pub parameters: BTreeMap<String, f64>,
    /// The signals the correction is built from.
    pub signals: Vec<String>,
    /// Out-of-sample (time-blocked) R² gained by adding this correction.
    pub delta_r2: f64,
    /// Surrogate p-value: the share of phase-randomised residuals for which the best
    /// correction of the whole library did at least as well (resolution 1/(surrogates + 1)).
    /// A delay read on the real recording's own samples (a simulation exported too coarsely
    /// to be moved; its `resolution_s` parameter says so) has no fitted coefficient for a
    /// surrogate to fit: its p-value is the one-sided paired t-test of the held-out blocks'
    /// errors with and without it, each fold's delay chosen on the other folds.
    pub p_value: f64,
    /// Other physics that fit these data about as well (the data cannot tell them apart).
    pub indistinguishable_from: Vec<String>,
    /// Admitted together with this other physics: the two mask each other (each explains
    /// most of the held-out error the other leaves), so `p_value`, this correction's test
    /// alone, is not the evidence.
    pub masked_by: Option<String>,
    /// Accepted only once the corrections found before it were refitted beside it (as they
    /// stood, it did not clear the surrogates): `p_value` is that of the refitted gain.
    pub judged_after_refit: bool,
    /// Accepted only on a censored target's readings at the floor taken as bounds: with them
    /// taken as values it did not clear the surrogates. `p_value` is then the one-sided
    /// sign-flip test of the held-out error on bounds it saves in each fold.
    pub judged_on_bounds: bool,
    /// The next best other physics at this step, with their gains relative to this one's.
    pub alternatives: Vec<Alternative>,
}

/// A competing explanation at a step.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Alternative {
    /// Its id (`calibration` for a gain miscalibration).
    pub physics: String,
    /// Its held-out gain as a fraction of the winner's.
    pub relative_gain: f64,
}

/// How the simulation had to be calibrated before any physics (never reported as physics).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Calibration {
    /// real ≈ offset + gain × sim (+ corrections); the offset is at the recording's start.
    pub offset: f64,
    /// The gain (1 when no gain miscalibration was significant).
    pub gain: f64,
    /// Whether a gain miscalibration was significant and absorbed.
    pub gain_absorbed: bool,
    /// A sentence.
    pub explanation: String,
    /// Physics of no more columns that predicts the held-out blocks as well as the absorbed
    /// gain: the gain is the simpler claim and was taken, but the data cannot rule these out.
    pub indistinguishable_from: Vec<String>,
    /// The next best physics where the gain was absorbed, with their gains relative to its.
    pub alternatives: Vec<Alternative>,
}

/// The noise left once every correction is in, measured on held-out blocks.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct NoiseFloor {
    /// RMS, target unit.
    pub rms: f64,
    /// Integrated autocorrelation time, s (white noise: one sample interval).
    pub correlation_time_s: f64,
    /// The part that changes from one sample to the next (white-noise σ from the successive
    /// differences), target unit. What is left beyond it is slow: correlated noise, or an
    /// effect that is too weak to name or that the corrections do not follow exactly, which
    /// the residual alone cannot tell apart.
    pub sample_noise_rms: f64,
    /// Window of the localisation's power estimates, s.
    pub window_s: f64,
}

impl NoiseFloor {
    /// The RMS of the slow part: what is left beyond the sample-to-sample noise.
    pub fn slow_rms(&self) -> f64 {
        (self.rms * self.rms - self.sample_noise_rms * self.sample_noise_rms)
            .max(0.0)
            .sqrt()
    }

    /// What the slow part may be, when it holds a fifth of the floor's power or more (slow
    /// at half the sample-to-sample RMS or above): a reader should not take it for the
    /// instrument's noise alone.
    pub fn slow_reading(&self) -> Option<&'static str> {
        (self.slow_rms() >= 0.5 * self.sample_noise_rms)
            .then_some("slow noise, or physics the corrections have not captured")
    }

    /// One line: the floor, its correlation time, and how much of it is slow.
    pub fn describe(&self, unit: &str) -> String {
        let reading = self
            .slow_reading()
            .map_or(String::new(), |r| format!(" ({r})"));
        format!(
            "noise floor: RMS {:.4} {unit}, correlation time {:.0} s; {:.4} {unit} from sample to sample, {:.4} {unit} slow{reading}",
            self.rms,
            self.correlation_time_s,
            self.sample_noise_rms,
            self.slow_rms()
        )
    }
}

/// How the recordings were joined.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Alignment {
    /// True when the recordings were not on one grid (see `on_simulation_grid`).
    pub resampled: bool,
    /// True when the comparison runs on the simulation's grid, which is clearly coarser than
    /// the real recording's (the real one taken at the simulation's instants); otherwise on
    /// the real recording's grid, with the simulation interpolated onto it when they differ.
    pub on_simulation_grid: bool,
    /// Rows where a speed steps between two samples of the interpolated recording, placed
    /// where the other recording's speed shows the instant (before the step, after it or that
    /// far through it) instead of linearly in time; the note says so.
    pub placed_by_speed: usize,
    /// A sentence.
    pub note: String,
    /// First aligned time, s.
    pub start_s: f64,
    /// Last aligned time, s.
    pub end_s: f64,
    /// The real target's floor (a magnitude that cannot read below zero) and the noise cut off
    /// there; when present the simulation was compared as the instrument would read it.
    pub censoring: Option<super::censor::Censoring>,
    /// When a delay was found on the real recording's own samples (a simulation exported too
    /// coarsely to be moved): how much later the real target was read, s. The rows are then
    /// those whose later readings the recording holds.
    pub read_later_s: Option<f64>,
    /// When the real target is censored and its readings at the floor were taken as bounds in
    /// the corrections' fit (`discrepancy::cut_off_refit`): the held-out figures of both fits.
    pub readings_as_bounds: Option<ReadingsAsBounds>,
}

/// The corrections of a censored target refitted to its readings at the floor as bounds, and
/// why that fit was kept.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct ReadingsAsBounds {
    /// Held-out RMSE of the readings with the corrections fitted to them as bounds, target
    /// unit (the report's `improved` figure).
    pub held_out_rmse: f64,
    /// Held-out RMSE of the same corrections fitted to the readings as compared (each reading
    /// at the floor taken as its value), target unit.
    pub held_out_rmse_as_compared: f64,
}

/// A physics that could not be tried, and why.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct NotTested {
    /// The id.
    pub physics: String,
    /// Why not.
    pub reason: String,
}

/// How the analysis was run.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Method {
    /// Time-blocked cross-validation folds.
    pub folds: usize,
    /// Surrogates per selection step.
    pub surrogates: usize,
    /// Significance level.
    pub alpha: f64,
    /// Rows the selection ran on (bin means of the aligned rows when there are more).
    pub selection_rows: usize,
    /// Candidate corrections (family members) in the library for this target.
    pub candidates: usize,
    /// Every selection step: the best candidate, its held-out gain and surrogate p-value.
    pub steps: Vec<StepTrace>,
}

/// One step of the stepwise selection, accepted or not.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct StepTrace {
    /// The best candidate's id (`calibration` for a gain).
    pub physics: String,
    /// Its held-out gain as a share of the held-out error before the step.
    pub relative_gain: f64,
    /// Its surrogate p-value.
    pub p_value: f64,
    /// Its upper-tail probability under a Gumbel law fitted to the surrogates' maxima (for a
    /// delay read on the real recording's samples, which has no surrogates, its `p_value`).
    pub tail_p: f64,
    /// Whether it entered the model.
    pub accepted: bool,
    /// Whether it was withdrawn again: when a later correction, refitted jointly with it,
    /// explained what it had taken (backward elimination), when on all rows it proved empty
    /// (smaller than a quarter of the sample noise and adding nothing held out), or when,
    /// beside a step that entered on a censored target's readings as bounds, it added nothing
    /// held out there.
    pub withdrawn: bool,
    /// Whether it was accepted on what it explains with every correction refitted beside it,
    /// having not been significant beside them as they stood; its gain and p-values are then
    /// the refitted model's.
    pub after_refit: bool,
    /// Whether it was accepted on a censored target's readings at the floor taken as bounds,
    /// having been refused on them taken as values; its gain and p-value are then those.
    pub on_bounds: bool,
}

/// The whole analysis.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct DiscrepancyReport {
    /// The target column.
    pub target: String,
    /// Aligned rows analysed.
    pub rows: usize,
    /// `missing_physics` or `consistent`.
    pub verdict: Verdict,
    /// The simulation as it is against the real target.
    pub baseline: FitQuality,
    /// Calibrated simulation plus every correction, measured on held-out time blocks.
    pub improved: FitQuality,
    /// Calibrated simulation only (offset, and gain when absorbed), held-out.
    pub calibrated: FitQuality,
    /// Where the simulation misses.
    pub mismatch_regions: Vec<Region>,
    /// Where the simulation is right.
    pub agreement_regions: Vec<Region>,
    /// Missing physics, strongest first.
    pub findings: Vec<Finding>,
    /// Calibration absorbed before physics.
    pub calibration: Calibration,
    /// What is left.
    pub noise_floor: NoiseFloor,
    /// How the recordings were joined.
    pub alignment: Alignment,
    /// Physics the data could not test.
    pub not_tested: Vec<NotTested>,
    /// How the analysis was run.
    pub method: Method,
    /// Plot-ready series (written separately, see [`PlotData`]).
    #[serde(skip)]
    pub plot: PlotData,
}

/// Series for the model-lab panel: everything on one (decimated) time axis.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct PlotData {
    /// The target.
    pub target: String,
    /// Time, s.
    pub time_s: Vec<f64>,
    /// The real target.
    pub real: Vec<f64>,
    /// The simulated target.
    pub sim: Vec<f64>,
    /// Calibrated simulation plus the corrections (fitted on all rows).
    pub corrected: Vec<f64>,
    /// real − sim.
    pub residual_before: Vec<f64>,
    /// real − corrected, each row predicted from the other time blocks.
    pub residual_after: Vec<f64>,
    /// The mismatch regions.
    pub regions: Vec<Region>,
}

impl DiscrepancyReport {
    /// The strongest candidate the selection weighed last and did not name, as a sentence:
    /// how close the analysis came to naming more (or anything, when it says `consistent`).
    /// `None` when its last step named its candidate.
    pub fn strongest_unnamed(&self) -> Option<String> {
        let last = self.method.steps.last().filter(|s| !s.accepted)?;
        Some(format!(
            "strongest candidate not named: {}, explains {:.1} % of the held-out error left (p = {:.3}, tail probability {:.1e}): not enough to name it",
            last.physics,
            100.0 * last.relative_gain,
            last.p_value,
            last.tail_p
        ))
    }

    /// The report as a person reads it.
    pub fn summary(&self) -> String {
        let mut s = String::new();
        let unit = crate::signal::channel::Channel::unit_of(&self.target).unwrap_or("");
        let _ = writeln!(
            s,
            "Discrepancy of {} ({} rows): {}",
            self.target,
            self.rows,
            match self.verdict {
                Verdict::MissingPhysics => "the simulation is missing physics",
                Verdict::Consistent => "consistent — no missing physics beyond calibration",
            }
        );
        let _ = writeln!(s, "  {}", self.alignment.note);
        let _ = writeln!(
            s,
            "  before: R² {:.4}, RMSE {:.4} {unit}   calibrated: R² {:.4}, RMSE {:.4}   after (held-out): R² {:.4}, RMSE {:.4} {unit}",
            self.baseline.r2,
            self.baseline.rmse,
            self.calibrated.r2,
            self.calibrated.rmse,
            self.improved.r2,
            self.improved.rmse
        );
        let _ = writeln!(s, "  {}", self.calibration.explanation);
        let _ = writeln!(s, "  {}", self.noise_floor.describe(unit));
        if self.findings.is_empty() {
            let _ = writeln!(s, "\nNo missing physics found.");
        } else {
            let _ = writeln!(s, "\nFindings, strongest first:");
        }
        for (i, f) in self.findings.iter().enumerate() {
            let _ = writeln!(
                s,
                "  {}. {} (ΔR² {:+.4}, p = {:.3})\n     {}",
                i + 1,
                f.physics,
                f.delta_r2,
                f.p_value,
                f.explanation
            );
            let _ = writeln!(s, "     signals: {}", f.signals.join(", "));
            if let Some(partner) = &f.masked_by {
                let _ = writeln!(
                    s,
                    "     admitted together with {partner}: each explains most of the held-out error the other leaves, so the p-value of its test alone is not the evidence"
                );
            }
            if f.judged_after_refit {
                let _ = writeln!(s, "     {JUDGED_AFTER_REFIT}");
            }
            if f.judged_on_bounds {
                let _ = writeln!(s, "     {JUDGED_ON_BOUNDS}");
            }
            if !f.indistinguishable_from.is_empty() {
                let _ = writeln!(
                    s,
                    "     the data cannot tell this apart from: {}",
                    f.indistinguishable_from.join(", ")
                );
            }
        }
        if let Some(unnamed) = self.strongest_unnamed() {
            let _ = writeln!(s, "  {unnamed}");
        }
        let describe = |r: &Region| {
            let conditions: Vec<String> = r
                .conditions
                .iter()
                .map(|(k, v)| format!("{k} {v:.2}"))
                .collect();
            format!(
                "{:>9.0}–{:<9.0} s  mean {:+.4}  rms {:.4}   {}",
                r.start_s,
                r.end_s,
                r.mean_residual,
                r.rms_residual,
                conditions.join(", ")
            )
        };
        if !self.mismatch_regions.is_empty() {
            let _ = writeln!(s, "\nWhere the simulation misses:");
            for r in &self.mismatch_regions {
                let _ = writeln!(s, "  {}", describe(r));
            }
        } else if self.verdict == Verdict::MissingPhysics && self.agreement_regions.is_empty() {
            let _ = writeln!(
                s,
                "\nWhere the simulation misses: throughout; no span stands out above the rest"
            );
        }
        if !self.agreement_regions.is_empty() {
            let _ = writeln!(s, "\nWhere the simulation is right:");
            for r in self.agreement_regions.iter().take(10) {
                let _ = writeln!(s, "  {}", describe(r));
            }
            if self.agreement_regions.len() > 10 {
                let _ = writeln!(s, "  … and {} more", self.agreement_regions.len() - 10);
            }
        }
        for t in &self.not_tested {
            let _ = writeln!(s, "  not tested: {} ({})", t.physics, t.reason);
        }
        s
    }
}
