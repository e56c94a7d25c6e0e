//! `servosight calibrate`: fit every estimator from a simulation database and a few experiments.

use std::path::PathBuf;

use crate::servosight_cli::pieces::warn_of_pieces_left_out;
use crate::servosight_cli::{emit_report, outln, refuse_overwriting_inputs, repeated};
use anyhow::Context;
use servosight::estimators::calibration::{
    CalibrationReport, CorrectionForm, ElongationExperiment, calibrate, warm_at_first_row,
    warm_experiment_for_elongation,
};
use servosight::estimators::models::{AMBIENT_LAG_FEATURES, AMBIENT_LAG_TAUS_S};
use servosight::profile::MachineProfile;
use servosight::signal::{Recording, group_pieces, read_pieces};

/// Arguments of `servosight calibrate`.
#[derive(Debug, clap::Args)]
#[command(
    after_help = "Example:\n  servosight simulate --scenario doe --hours 48 --seed 1 -o db.csv\n  \
servosight simulate --scenario production --hours 4 --seed 2 -o exp.csv\n  \
servosight calibrate --database db.csv --experiments exp.csv -o profile.toml --json report.json"
)]
pub struct Args {
    /// Simulation database recordings (CSV v1 with reference columns), repeatable; the pieces
    /// a recorder cut one recording into (consecutive, their `# recording:` the same) are one.
    #[arg(long = "database", required = true, num_args = 1..)]
    pub database: Vec<PathBuf>,
    /// Experiment recordings that correct the database, repeatable; the pieces a recorder cut
    /// one experiment into (consecutive, their `# recording:` the same) are one experiment.
    #[arg(long = "experiments", num_args = 1..)]
    pub experiments: Vec<PathBuf>,
    /// Machine profile to start from (geometry, ratings, limits); default: the twin's machine.
    #[arg(long)]
    pub profile: Option<PathBuf>,
    /// Where to write the calibrated profile (TOML).
    #[arg(short = 'o', long = "output")]
    pub output: PathBuf,
    /// Write the calibration report as JSON to this file ("-" for stdout).
    #[arg(long)]
    pub json: Option<PathBuf>,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let recordings: Vec<&std::path::Path> = args
        .database
        .iter()
        .chain(&args.experiments)
        .map(PathBuf::as_path)
        .collect();
    refuse_overwriting_inputs(&recordings, &[Some(&args.output), args.json.as_deref()])?;
    // The calibrated profile written over the one it started from renews it (that one is read
    // first); the report written over it would lose it.
    let mut with_profile = recordings.clone();
    with_profile.extend(args.profile.as_deref());
    refuse_overwriting_inputs(&with_profile, &[args.json.as_deref()])?;
    refuse_a_recording_given_twice(&args.database, &args.experiments)?;
    let mut profile = match &args.profile {
        Some(path) => MachineProfile::load(path)?,
        None => MachineProfile::twin_default(),
    };
    // The pieces a recorder cut one recording into (its `# recording:` and `# part:`) are read
    // as that one recording.
    let recordings_given: Vec<PathBuf> = args
        .database
        .iter()
        .chain(&args.experiments)
        .cloned()
        .collect();
    let read_all = |paths: &[PathBuf]| {
        group_pieces(paths)
            .context("cannot read recording")?
            .iter()
            .map(|group| {
                // An experiment's second hour left out would fit other models without a word.
                // A piece given as a recording of its own (no header to join it by) is given.
                let named: Vec<PathBuf> = group.iter().chain(&recordings_given).cloned().collect();
                warn_of_pieces_left_out(
                    &named,
                    "list them after it, in the order recorded, to take the recording as one",
                );
                read_pieces(group).context("cannot read recording")
            })
            .collect::<anyhow::Result<Vec<_>>>()
    };
    let database = read_all(&args.database)?;
    let experiments = read_all(&args.experiments)?;
    let (calibration, report) =
        calibrate(&profile, &database, &experiments).context("calibration failed")?;
    profile.calibration = Some(calibration);
    profile.validate("the calibrated profile")?;
    profile.save(&args.output)?;
    warn_of_weak_models(&report, &database);
    warn_of_warm_starts(&database, &experiments);
    emit_report(args.json.as_deref(), &report, || {
        outln!(
            "{:<34} {:>8} {:>8} {:>8} {:>12}  equation",
            "model",
            "n",
            "R²",
            "CV R²",
            "F"
        )?;
        for m in &report.models {
            outln!(
                "{:<34} {:>8} {:>8.4} {:>8.4} {:>12.4e}  {}",
                m.estimate,
                m.n,
                m.r2,
                m.cv_r2,
                m.f_statistic,
                m.equation
            )?;
            if let Some(c) = &m.experiment_correction {
                let verdict = match c.form {
                    CorrectionForm::None => "none applied".to_string(),
                    CorrectionForm::Offset => format!("applied: {:+.4}", c.offset),
                    CorrectionForm::Gain => format!("applied: {:.4}·predicted", c.gain),
                    CorrectionForm::GainOffset => {
                        format!("applied: {:+.4} + {:.4}·predicted", c.offset, c.gain)
                    }
                };
                let warm = if c.warm_start_taken_out {
                    " (experiments that begin warm, their start taken out)"
                } else {
                    ""
                };
                outln!(
                    "{:<34} experiments{warm}: n = {}, held-out RMSE none {:.4} / offset {:.4} / gain {:.4} / gain+offset {:.4} (p = {:.3}); {}; RMSE {:.4} → {:.4}",
                    "",
                    c.n,
                    c.cv_rmse_none,
                    c.cv_rmse_offset,
                    c.cv_rmse_gain,
                    c.cv_rmse_gain_offset,
                    c.improvement_p_value,
                    verdict,
                    c.rmse_before,
                    c.rmse_after,
                )?;
            }
        }
        outln!("calibrated profile written to {}", args.output.display())
    })
}

/// The profile is written whatever these say, since it is the best the data allow; what may
/// make its estimates unreliable is said on stderr.
fn warn_of_weak_models(report: &CalibrationReport, database: &[Recording]) {
    // Over a database shorter than a lag, that lag is nearly a constant: half an hour of DOE
    // fitted straightness intercepts of −2e4 µm from the room's slowest lag.
    let database_s: f64 = database.iter().map(|r| r.duration_s()).sum();
    let slowest_read = AMBIENT_LAG_TAUS_S
        .iter()
        .zip(AMBIENT_LAG_FEATURES)
        .filter(|(tau, _)| **tau > database_s)
        .filter(|(_, feature)| report.models.iter().any(|m| m.equation.contains(feature)))
        .map(|(tau, _)| *tau)
        .reduce(f64::max);
    if let Some(tau) = slowest_read {
        eprintln!(
            "warning: the database spans {:.1} h, less than the slowest lag the models read \
             ({:.1} h, the room through the machine's mass): over so short a span such a lag \
             is nearly a constant and its coefficients extrapolate; a DOE of a day or more \
             (simulate --scenario doe runs 24 h) pins them down",
            database_s / 3600.0,
            tau / 3600.0
        );
    }
    for m in report.models.iter().filter(|m| m.cv_r2 < WEAK_CV_R2) {
        let why = m
            .coverage
            .as_deref()
            .unwrap_or("the database may be too short or too uniform for it");
        eprintln!(
            "warning: {} predicts its held-out blocks poorly (CV R² {:.3}): {why}; check its \
             estimates before trusting them",
            m.estimate, m.cv_r2
        );
    }
}

/// A recording that starts on a warm machine: said on stderr, naming the recording and the
/// axes. A database recording biases every heat model (they are accumulated from rest at its
/// first row); an experiment's start is fitted free for the heat models, and the spindle
/// elongation uses it as [`warm_experiment_for_elongation`] says.
fn warn_of_warm_starts(database: &[Recording], experiments: &[Recording]) {
    let tagged = database.iter().map(|r| (r, true));
    for (recording, in_database) in tagged.chain(experiments.iter().map(|r| (r, false))) {
        let warm = warm_at_first_row(recording);
        if warm.is_empty() {
            continue;
        }
        let axes: Vec<String> = warm
            .iter()
            .map(|(axis, excess)| format!("{axis} stator {excess:.1} K above the room"))
            .collect();
        let consequence = if in_database {
            "calibration accumulates the heat of every model from rest at a database \
             recording's first row, so the heat models are fitted to heat this recording does \
             not show; calibrate on recordings that start after a long stop"
                .to_string()
        } else {
            let elongation = match warm_experiment_for_elongation(recording, experiments) {
                ElongationExperiment::LeftOut => {
                    "; the spindle elongation, counted from the tool measurement, cannot tell that \
                     heat from its own slow heat and is calibrated without this recording, on the \
                     experiments from rest"
                }
                ElongationExperiment::ScoresAndGain => {
                    "; the spindle elongation, counted from the tool measurement, cannot tell that \
                     heat from its own slow heat: it is fitted on the database alone, and this \
                     recording, its start fitted free, only chooses among those fits and weighs a \
                     correction of their gain; for it, give an experiment that starts after a long \
                     stop"
                }
                ElongationExperiment::NoReference | ElongationExperiment::FromRest => "",
            };
            format!(
                "the heat it held then is fitted as a free start (decays that are no term of \
                 the models) for the flange, bearing and nut models, and the straightness reads \
                 the estimators' temperatures, which start warm as in service{elongation}"
            )
        };
        eprintln!(
            "warning: {} starts on a warm machine ({}): {consequence}",
            recording.source(),
            axes.join(", ")
        );
    }
}

/// Below this held-out R² a calibrated model is flagged: it predicts its held-out blocks worse
/// than their mean would. (A threshold any higher would flag sound models whose target is
/// noisy by nature: the twin's torque ratios hold out at 0.39–0.53.)
const WEAK_CV_R2: f64 = 0.0;

/// A recording listed twice (twice as a database, or as a database and an experiment) would
/// count its rows twice and make every model's statistics claim more evidence than there is.
fn refuse_a_recording_given_twice(
    database: &[PathBuf],
    experiments: &[PathBuf],
) -> anyhow::Result<()> {
    let all: Vec<&std::path::Path> = database
        .iter()
        .chain(experiments)
        .map(PathBuf::as_path)
        .collect();
    match repeated(&all) {
        Some((again, first)) => {
            let alias = if again == first {
                String::new()
            } else {
                format!(" (also as {})", first.display())
            };
            anyhow::bail!(
                "{} is given twice{alias}: each recording may be used once",
                again.display()
            )
        }
        None => Ok(()),
    }
}
