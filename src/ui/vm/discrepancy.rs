//! Model lab, sim vs real: the discrepancy analysis of a simulation against a real recording —
//! verdict, findings in words, before/after figures, the residual with its mismatch regions and
//! the before/after overlay, drawn from a decimated window of the report's plot series.

use serde::Serialize;

use super::{channel_label, duration, probability, statistic, unit};
use crate::discrepancy::{Region, Verdict};
use crate::signal::RecordingPieces;
use crate::ui::sim_vs_real::{DiscrepancyOutcome, PLOT_CHANNELS};
use crate::ui::state::{HmiState, JobProgress};

/// One line of a plot: `[time_s, value]` points.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PlotLine {
    /// The legend.
    pub label: String,
    /// Points, time ascending.
    pub points: Vec<[f64; 2]>,
}

/// A mismatch region: where to shade and what to say.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RegionView {
    /// Start, s.
    pub start_s: f64,
    /// End, s.
    pub end_s: f64,
    /// "0 s – 1 h 05 min: mean +0.412 °C, RMS 0.520 °C; S speed 1200 …".
    pub text: String,
}

/// One parameter of a finding with its unit.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ParameterView {
    /// The library's name (`tau_min`).
    pub name: String,
    /// "41.23 min".
    pub value: String,
}

/// A missing physics, in words.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FindingView {
    /// 1 for the strongest.
    pub rank: usize,
    /// The vocabulary id (`copper_loss`).
    pub physics: String,
    /// The library's sentence with the fitted parameters.
    pub explanation: String,
    /// Fitted parameters with units.
    pub parameters: Vec<ParameterView>,
    /// The signals the correction is built from.
    pub signals: String,
    /// Held-out R² this correction adds.
    pub delta_r2: String,
    /// Surrogate p-value.
    pub p_value: String,
    /// "the data cannot tell this apart from …", when so.
    pub indistinguishable: Option<String>,
    /// "admitted together with …", when it was found as one of two effects that mask each
    /// other.
    pub masked_by: Option<String>,
    /// "found with the corrections before it refitted beside it …", when it was accepted
    /// only after that refit.
    pub judged_after_refit: Option<String>,
    /// "found on the readings at the instrument's floor taken as bounds …", when it was
    /// accepted only on those.
    pub judged_on_bounds: Option<String>,
}

/// R² and RMSE of one stage.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct QualityRow {
    /// "before: the simulation as it is", …
    pub stage: String,
    /// R².
    pub r2: String,
    /// RMSE with the target's unit.
    pub rmse: String,
}

/// The drawing data.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DiscrepancyPlots {
    /// The target's unit (empty when its name has none).
    pub unit: String,
    /// real − sim over time.
    pub residual: PlotLine,
    /// What is left after the corrections, each point predicted from other time blocks.
    pub residual_after: PlotLine,
    /// Where the simulation misses (shaded on the residual plot).
    pub regions: Vec<RegionView>,
    /// Real, sim, and sim + corrections.
    pub overlay: Vec<PlotLine>,
    /// "1 point = up to 8 bins (mean)" or "every point".
    pub decimation: String,
}

/// A finished analysis.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DiscrepancyResultView {
    /// The simulation file.
    pub sim: String,
    /// The real recording.
    pub real: String,
    /// The compared column and its label.
    pub target: String,
    /// True when physics is missing.
    pub missing_physics: bool,
    /// The verdict in words.
    pub verdict: String,
    /// Rows analysed, how they were aligned.
    pub alignment: String,
    /// How the simulation was calibrated before any physics.
    pub calibration: String,
    /// Before, calibrated and after (held out).
    pub quality: Vec<QualityRow>,
    /// What is left.
    pub noise_floor: String,
    /// Findings, strongest first.
    pub findings: Vec<FindingView>,
    /// Physics the data could not test, and other caveats.
    pub notes: Vec<String>,
    /// What to draw.
    pub plots: DiscrepancyPlots,
}

/// The sim-vs-real part of the Model lab.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DiscrepancyView {
    /// Columns both chosen files share (the target choices).
    pub shared_columns: Vec<String>,
    /// Why the headers could not be read.
    pub columns_error: Option<String>,
    /// The later pieces found beside the real recording, which the analysis reads after it as
    /// one recording; `None` when there are none or only the chosen file is read.
    pub real_pieces: Option<String>,
    /// The running analysis's progress.
    pub running: Option<JobProgress>,
    /// The last analysis.
    pub result: Option<DiscrepancyResultView>,
    /// Why the last analysis failed or stopped (the library's message).
    pub error: Option<String>,
    /// How the last PNG export of the result went (or how far it is).
    pub png_note: Option<String>,
    /// How the last save of the result's report went (or that it is being written).
    pub report_note: Option<String>,
}

/// Builds the view, drawing at most `max_points` points per line.
pub fn build(state: &HmiState, max_points: usize) -> DiscrepancyView {
    let d = &state.model_lab.discrepancy;
    DiscrepancyView {
        shared_columns: d
            .columns
            .as_ref()
            .map(|c| c.columns.clone())
            .unwrap_or_default(),
        columns_error: d.columns_error.clone(),
        real_pieces: d
            .columns
            .as_ref()
            .and_then(|c| c.real_pieces.get(1..).filter(|later| !later.is_empty()))
            .map(|later| {
                format!(
                    "read as one with the pieces the recorder continued it in: {}",
                    RecordingPieces::short_name(later)
                )
            }),
        running: d.running.clone(),
        result: d.result.as_ref().map(|o| result_view(o, max_points)),
        error: d.error.clone(),
        png_note: d.png_note.clone(),
        report_note: d.report_note.clone(),
    }
}

/// The view of a finished analysis, its plots decimated to at most `max_points` points.
pub fn result_view(outcome: &DiscrepancyOutcome, max_points: usize) -> DiscrepancyResultView {
    let r = &outcome.report;
    let u = unit(&r.target);
    let with_unit = |text: String| {
        if u.is_empty() {
            text
        } else {
            format!("{text} {u}")
        }
    };
    let quality = |stage: &str, q: crate::discrepancy::FitQuality| QualityRow {
        stage: stage.to_string(),
        r2: statistic(q.r2),
        rmse: with_unit(statistic(q.rmse)),
    };
    let mut notes: Vec<String> = r
        .not_tested
        .iter()
        .map(|t| format!("not tested: {} ({})", t.physics, t.reason))
        .collect();
    if let Some(unnamed) = r.strongest_unnamed() {
        notes.insert(0, unnamed);
    }
    if r.findings.is_empty() {
        notes.insert(
            0,
            "no physics in the library improved the held-out fit beyond what noise alone does"
                .into(),
        );
    }
    DiscrepancyResultView {
        sim: outcome.request.sim.display().to_string(),
        real: RecordingPieces::short_name(&outcome.real_read),
        target: format!("{} ({})", r.target, channel_label(&r.target)),
        missing_physics: r.verdict == Verdict::MissingPhysics,
        verdict: match r.verdict {
            Verdict::MissingPhysics => format!(
                "missing physics: the simulation leaves out {}",
                r.findings
                    .iter()
                    .map(|f| f.physics.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
            Verdict::Consistent => {
                "consistent: no missing physics beyond calibration, within the noise".into()
            }
        },
        alignment: format!("{} rows; {}", r.rows, r.alignment.note),
        calibration: r.calibration.explanation.clone(),
        quality: vec![
            quality("before: the simulation as it is", r.baseline),
            quality("calibrated (held out)", r.calibrated),
            quality("after: sim + corrections (held out)", r.improved),
        ],
        noise_floor: format!(
            "noise floor: RMS {}, correlation time {}; {} from sample to sample, {} slow{}",
            with_unit(statistic(r.noise_floor.rms)),
            duration(r.noise_floor.correlation_time_s),
            with_unit(statistic(r.noise_floor.sample_noise_rms)),
            with_unit(statistic(r.noise_floor.slow_rms())),
            r.noise_floor
                .slow_reading()
                .map_or(String::new(), |reading| format!(" ({reading})"))
        ),
        findings: r
            .findings
            .iter()
            .enumerate()
            .map(|(i, f)| FindingView {
                rank: i + 1,
                physics: f.physics.clone(),
                explanation: f.explanation.clone(),
                parameters: f
                    .parameters
                    .iter()
                    .map(|(name, value)| ParameterView {
                        name: name.clone(),
                        value: parameter_value(name, *value, &u),
                    })
                    .collect(),
                signals: f.signals.join(", "),
                delta_r2: format!("{:+.4}", f.delta_r2),
                p_value: probability(f.p_value),
                indistinguishable: (!f.indistinguishable_from.is_empty()).then(|| {
                    format!(
                        "the data cannot tell this apart from: {}",
                        f.indistinguishable_from.join(", ")
                    )
                }),
                masked_by: f.masked_by.as_ref().map(|partner| {
                    format!(
                        "admitted together with {partner}: each explains most of the held-out error the other leaves"
                    )
                }),
                judged_after_refit: f
                    .judged_after_refit
                    .then(|| crate::discrepancy::JUDGED_AFTER_REFIT.to_string()),
                judged_on_bounds: f
                    .judged_on_bounds
                    .then(|| crate::discrepancy::JUDGED_ON_BOUNDS.to_string()),
            })
            .collect(),
        notes,
        plots: plots(outcome, &u, max_points),
    }
}

/// A parameter's value with the unit its name implies (the library's names carry them:
/// `tau_min`, `delay_s`, `gain_per_K`, …; effect sizes are in the target's unit).
fn parameter_value(name: &str, value: f64, target_unit: &str) -> String {
    let per = |suffix: &str| {
        if target_unit.is_empty() {
            format!("1{suffix}")
        } else {
            format!("{target_unit}{suffix}")
        }
    };
    let unit = match name {
        n if n.ends_with("_min") => "min".to_string(),
        n if n.ends_with("_s") => "s".to_string(),
        // A lubricant's temperature coefficient is the drag's fall per K at 1000 rpm, in the
        // target's unit (not a share).
        "gain_per_K" | "temperature_coefficient_per_K" => per("/K"),
        "per_A2" => per("/A²"),
        "drift_per_hour" => per("/h"),
        "per_krpm" => per("/krpm"),
        "per_krpm2" => per("/krpm²"),
        "lowest_at" | "highest_at" => "mm".into(),
        "top_running_rpm" | "simulated_at_rpm" => "rpm".into(),
        "effect_range"
        | "mean_effect"
        | "largest_effect"
        | "difference_on_vs_off"
        | "at_rms_current"
        | "at_top_running_speed"
        | "friction_change"
        | "friction_step"
        | "stribeck_excess"
        | "variation"
        | "offset_at_start"
        | "already_at_start" => target_unit.to_string(),
        // share, gain, exponent, relative_change_at_1000rpm: ratios.
        _ => String::new(),
    };
    let number = statistic(value);
    if unit.is_empty() {
        number
    } else {
        format!("{number} {unit}")
    }
}

/// One operating condition of a region as a person reads it, with its unit: speeds and loads
/// are mean magnitudes, `…:moving_share` and `coolant_on` are shares of the region's time.
fn condition_text(name: &str, value: f64) -> String {
    if let Some(speed) = name.strip_suffix(":moving_share") {
        let axis = speed.split('.').next().unwrap_or(speed);
        return format!("{axis} moving {:.0} % of the time", 100.0 * value);
    }
    if name == crate::signal::channel::COOLANT {
        return format!("coolant on {:.0} % of the time", 100.0 * value);
    }
    let u = unit(name);
    let label = channel_label(name);
    if u.is_empty() {
        format!("{label} {}", super::number(Some(value), 2))
    } else {
        format!("{label} {} {u}", super::number(Some(value), 2))
    }
}

fn region_view(region: &Region, target_unit: &str) -> RegionView {
    let conditions: Vec<String> = region
        .conditions
        .iter()
        .map(|(name, v)| condition_text(name, *v))
        .collect();
    let space = if target_unit.is_empty() { "" } else { " " };
    RegionView {
        start_s: region.start_s,
        end_s: region.end_s,
        text: format!(
            "{} – {}: mean {:+.4}{space}{target_unit}, RMS {}{space}{target_unit}; {}",
            duration(region.start_s),
            duration(region.end_s),
            region.mean_residual,
            statistic(region.rms_residual),
            conditions.join(", ")
        ),
    }
}

fn plots(outcome: &DiscrepancyOutcome, target_unit: &str, max_points: usize) -> DiscrepancyPlots {
    let history = &outcome.plot;
    let channels: Vec<usize> = (0..PLOT_CHANNELS.len()).collect();
    let (t0, t1) = match (history.oldest_time_s(), history.newest_time_s()) {
        (Some(t0), Some(t1)) => (t0, t1),
        _ => (0.0, 0.0),
    };
    let window = history.window(&channels, t0, t1, max_points);
    let line = |channel: usize, label: &str| PlotLine {
        label: label.to_string(),
        points: window
            .time_s
            .iter()
            .zip(&window.series[channel].mean)
            .filter(|(_, v)| v.is_finite())
            .map(|(t, v)| [*t, f64::from(*v)])
            .collect(),
    };
    let per_point = window.samples_per_point.iter().copied().max().unwrap_or(1);
    DiscrepancyPlots {
        unit: target_unit.to_string(),
        residual: line(3, "real − sim"),
        residual_after: line(4, "real − (sim + corrections), held out"),
        regions: outcome
            .report
            .plot
            .regions
            .iter()
            .map(|r| region_view(r, target_unit))
            .collect(),
        overlay: vec![
            line(0, "real"),
            line(1, "sim"),
            line(2, "sim + corrections"),
        ],
        decimation: if per_point > 1 {
            format!("1 point = up to {per_point} of the report's bins (mean)")
        } else {
            "every point of the report".into()
        },
    }
}

#[cfg(test)]
mod tests {
    use super::{condition_text, parameter_value};

    #[test]
    fn parameters_and_conditions_carry_their_units() {
        assert_eq!(parameter_value("tau_min", 41.25, "°C"), "41.2500 min");
        assert_eq!(parameter_value("delay_s", 12.0, "N·m"), "12.0000 s");
        assert_eq!(parameter_value("gain_per_K", 3.8, "µm"), "3.8000 µm/K");
        assert_eq!(parameter_value("per_A2", 0.5, "°C"), "0.5000 °C/A²");
        assert_eq!(parameter_value("effect_range", 2.0, "°C"), "2.0000 °C");
        assert_eq!(parameter_value("already_at_start", 6.6, "°C"), "6.6000 °C");
        assert_eq!(parameter_value("share", 0.5, "°C"), "0.5000");
        assert_eq!(parameter_value("gain_per_K", 3.8, ""), "3.8000 1/K");
        assert_eq!(
            parameter_value("temperature_coefficient_per_K", -0.0012, "N·m"),
            "-0.0012 N·m/K"
        );
        assert_eq!(
            parameter_value("top_running_rpm", 376.0, "°C"),
            "376.0000 rpm"
        );
        assert_eq!(
            parameter_value("at_top_running_speed", 2.3, "°C"),
            "2.3000 °C"
        );
        assert_eq!(
            condition_text("S.speed_rpm:moving_share", 0.615),
            "S moving 62 % of the time"
        );
        assert_eq!(
            condition_text("coolant_on", 0.25),
            "coolant on 25 % of the time"
        );
        assert_eq!(condition_text("X.load_pct", 10.687), "X load 10.69 %");
    }
}
