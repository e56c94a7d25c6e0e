//! `servosight fingerprint`: the friction fingerprint of an axis, trended against a baseline,
//! with the preload diagnosis.

use std::path::PathBuf;

use crate::servosight_cli::pieces::{LaterPieces, recording_files};
use crate::servosight_cli::{outln, refuse_overwriting_inputs, text_report_wanted};
use anyhow::Context;
use servosight::estimators::fingerprint::{
    FrictionFingerprint, diagnose_preload, drift, fingerprint,
};
use servosight::profile::MachineProfile;
use servosight::signal::{AxisId, read_pieces};

/// Arguments of `servosight fingerprint`.
#[derive(Debug, clap::Args)]
#[command(
    after_help = "Example (a baseline on the healthy machine, then a shift's warm-up):\n  \
servosight fingerprint --recording warmup-day1.csv --axis X --save-baseline x-baseline.json\n  \
servosight fingerprint --recording warmup-today.csv --axis X --baseline x-baseline.json"
)]
pub struct Args {
    /// A recording with the warm-up moves (both directions, several speeds); several files
    /// are the pieces of one recording, read as one in the order given (moves the recorder's
    /// hourly new piece cut in two: warmup.csv warmup-0001.csv).
    #[arg(long, required = true, num_args = 1..)]
    pub recording: Vec<PathBuf>,
    #[command(flatten)]
    pub pieces: LaterPieces,
    /// The axis.
    #[arg(long, value_parser = parse_axis)]
    pub axis: AxisId,
    /// A baseline fingerprint (JSON) to trend against and to diagnose preload from.
    #[arg(long, conflicts_with = "save_baseline")]
    pub baseline: Option<PathBuf>,
    /// Save this fingerprint as the axis's baseline (JSON).
    #[arg(long)]
    pub save_baseline: Option<PathBuf>,
    /// Machine profile (drift limits, preloads); default: the twin's machine.
    #[arg(long)]
    pub profile: Option<PathBuf>,
    /// Write the result as JSON ("-" for stdout).
    #[arg(long)]
    pub json: Option<PathBuf>,
}

fn parse_axis(s: &str) -> Result<AxisId, String> {
    s.parse()
}

#[derive(Debug, serde::Serialize)]
struct Report {
    fingerprint: FrictionFingerprint,
    drift: Vec<servosight::estimators::fingerprint::FingerprintDrift>,
    preload: Option<servosight::estimators::fingerprint::PreloadDiagnosis>,
}

pub fn run(mut args: Args) -> anyhow::Result<()> {
    args.recording = recording_files(&args.recording, &args.pieces, "--recording")?.0;
    let mut inputs: Vec<&std::path::Path> = args.recording.iter().map(PathBuf::as_path).collect();
    inputs.extend(args.profile.as_deref());
    // Saving the new baseline over the one compared with is how a baseline is renewed; the
    // JSON report over it would lose it.
    refuse_overwriting_inputs(&inputs, &[args.save_baseline.as_deref()])?;
    inputs.extend(args.baseline.as_deref());
    refuse_overwriting_inputs(&inputs, &[args.json.as_deref()])?;
    let text = text_report_wanted(args.json.as_deref());
    let profile = match &args.profile {
        Some(path) => MachineProfile::load(path)?,
        None => MachineProfile::twin_default(),
    };
    let axis_profile = profile
        .axis(args.axis)
        .with_context(|| format!("the profile has no axis {}", args.axis))?;
    let recording = read_pieces(&args.recording).context("cannot read recording")?;
    let current = fingerprint(&recording, args.axis)?;
    if text {
        outln!(
            "{} axis friction fingerprint ({} samples, coherence R² {:.3})",
            current.axis,
            current.samples,
            current.coherence
        )?;
        outln!(
            "  Coulomb {:.4} N·m (+ {:.4} / − {:.4}), viscous {:.4} N·m/krpm, inertia {:.2e} kg·m², offset {:.4} N·m",
            current.coulomb_Nm,
            current.coulomb_positive_Nm,
            current.coulomb_negative_Nm,
            current.viscous_Nm_per_krpm,
            current.inertia_kgm2,
            current.offset_Nm
        )?;
    }
    let mut report = Report {
        fingerprint: current.clone(),
        drift: Vec::new(),
        preload: None,
    };
    if let Some(path) = &args.baseline {
        let stored = std::fs::read_to_string(path)
            .with_context(|| format!("cannot read baseline {}", path.display()))?;
        let baseline: FrictionFingerprint = serde_json::from_str(&stored)
            .with_context(|| format!("{} is not a fingerprint baseline", path.display()))?;
        baseline
            .validate()
            .map_err(|why| anyhow::anyhow!("the baseline {}: {why}", path.display()))?;
        anyhow::ensure!(
            baseline.axis == args.axis,
            "the baseline {} is of axis {}, not {}",
            path.display(),
            baseline.axis,
            args.axis
        );
        report.drift = drift(
            &current,
            &baseline,
            axis_profile.limits.fingerprint_drift_fraction,
        );
        for d in report.drift.iter().filter(|_| text) {
            outln!(
                "  {:<22} baseline {:>9.4}  now {:>9.4}  {:>+7.1} %{}",
                d.figure,
                d.baseline,
                d.current,
                100.0 * d.change,
                if d.warning {
                    "  ← beyond the drift limit"
                } else {
                    ""
                }
            )?;
        }
        report.preload = diagnose_preload(&current, &baseline, axis_profile);
        if let Some(p) = report.preload.as_ref().filter(|_| text) {
            outln!("  preload: {:?} — {}", p.state, p.evidence)?;
        }
    }
    if let Some(path) = &args.save_baseline {
        std::fs::write(path, serde_json::to_string_pretty(&current)? + "\n")
            .with_context(|| format!("cannot write {}", path.display()))?;
        if text {
            outln!("  saved as the baseline {}", path.display())?;
        }
    }
    if let Some(path) = &args.json {
        crate::servosight_cli::write_json(path, &report)?;
    }
    Ok(())
}
