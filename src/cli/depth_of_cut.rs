//! `servosight depth-of-cut`: the maximum rough-cut depth from the loads measured during cuts.

use std::path::PathBuf;

use crate::servosight_cli::pieces::{LaterPieces, recording_files};
use crate::servosight_cli::{emit_report, outln, refuse_overwriting_inputs};
use anyhow::Context;
use servosight::estimators::depth_of_cut::recommend_depth_of_cut;
use servosight::profile::MachineProfile;
use servosight::signal::read_pieces;

/// Arguments of `servosight depth-of-cut`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// A recording with some cuts at different depths (needs `cut_depth_mm`); several files
    /// are the pieces of one recording, read as one in the order given (the recorder starts a
    /// new piece every hour: day.csv, day-0001.csv, …).
    #[arg(long, required = true, num_args = 1..)]
    pub recording: Vec<PathBuf>,
    #[command(flatten)]
    pub pieces: LaterPieces,
    /// Machine profile (ratings, margin); default: the twin's machine.
    #[arg(long)]
    pub profile: Option<PathBuf>,
    /// Diameter being turned, mm (the cutting force acts on its radius).
    #[arg(long, default_value_t = 80.0)]
    pub workpiece_diameter_mm: f64,
    /// Write the recommendation as JSON ("-" for stdout).
    #[arg(long)]
    pub json: Option<PathBuf>,
}

pub fn run(mut args: Args) -> anyhow::Result<()> {
    args.recording = recording_files(&args.recording, &args.pieces, "--recording")?.0;
    let mut inputs: Vec<&std::path::Path> = args.recording.iter().map(PathBuf::as_path).collect();
    inputs.extend(args.profile.as_deref());
    refuse_overwriting_inputs(&inputs, &[args.json.as_deref()])?;
    let profile = match &args.profile {
        Some(path) => MachineProfile::load(path)?,
        None => MachineProfile::twin_default(),
    };
    let recording = read_pieces(&args.recording).context("cannot read recording")?;
    let r = recommend_depth_of_cut(&profile, &recording, args.workpiece_diameter_mm)?;
    emit_report(args.json.as_deref(), &r, || {
        outln!(
            "Maximum rough-cut depth: {:.1} mm at f = {:.2} mm/rev, {:.0} rpm — limited by {}",
            r.recommended_depth_mm,
            r.feed_per_rev_mm,
            r.spindle_rpm,
            r.limiting_component
        )?;
        outln!("  {}", r.reason)?;
        outln!(
            "  {:<22} {:>10} {:>12} {:>12} {:>10} {:>6}",
            "component",
            "idle",
            "per mm",
            "limit",
            "max depth",
            "R²"
        )?;
        for c in &r.components {
            outln!(
                "  {:<22} {:>10.2} {:>12.2} {:>12.1} {:>7.2} mm {:>6.3}  {} ({})",
                c.component,
                c.idle_load,
                c.load_per_mm,
                c.limit,
                c.max_depth_mm,
                c.r2,
                c.unit,
                c.why
            )?;
        }
        Ok(())
    })
}
