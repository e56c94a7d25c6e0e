//! `servosight discrepancy`: where a simulation and a real recording disagree on a target, which
//! physics the simulation left out, the fitted correction, and the fit before and after.

use std::path::{Path, PathBuf};

use crate::servosight_cli::pieces::{LaterPieces, recording_files};
use crate::servosight_cli::{emit_report, out, refuse_overwriting_inputs};
use anyhow::Context;
use servosight::discrepancy::{Options, RowBudget, analyse};
use servosight::parallel::join_or_resume;
use servosight::signal::{Recording, RecordingError, RecordingPieces};
use servosight::ui::export_png::render_discrepancy;
use servosight::ui::sim_vs_real::{DiscrepancyOutcome, DiscrepancyRequest};
use servosight::ui::vm::discrepancy::result_view;

/// Width of `--plot`'s image, pixels.
const PLOT_WIDTH_PX: u32 = 1400;

/// Most points per line in `--plot`'s image (about one per pixel of the plots).
const PLOT_POINTS: usize = 1400;

/// Arguments of `servosight discrepancy`.
#[derive(Debug, clap::Args)]
#[command(
    after_help = "Example:\n  servosight simulate --scenario production --hours 6 --seed 3 --without copper_loss --noise 0 -o sim.csv\n  \
servosight simulate --scenario production --hours 6 --seed 3 -o real.csv\n  \
servosight discrepancy --sim sim.csv --real real.csv --target S.stator_temp_C --json report.json"
)]
pub struct Args {
    /// The simulation (CSV v1), e.g. a twin run or an imported FEA export.
    #[arg(long)]
    pub sim: PathBuf,
    /// The real recording (CSV v1); several files are the pieces of one recording, read as one
    /// in the order given (the recorder starts a new piece every hour: shift.csv,
    /// shift-0001.csv, …).
    #[arg(long, required = true, num_args = 1..)]
    pub real: Vec<PathBuf>,
    #[command(flatten)]
    pub pieces: LaterPieces,
    /// The column to compare (present in both files).
    #[arg(long)]
    pub target: String,
    /// Write the report as JSON to this file ("-" for stdout, which replaces the text report).
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Write the plot-ready series (time, real, sim, corrected, residual before/after, regions)
    /// as JSON to this file.
    #[arg(long)]
    pub plot_data: Option<PathBuf>,
    /// Draw the analysis as the HMI's Model lab shows it (verdict, fit before and after,
    /// findings, the residual with its mismatch regions, real vs sim vs corrected) into this
    /// PNG file, 1400 pixels wide and as tall as the report.
    #[arg(long, value_name = "FILE.png")]
    pub plot: Option<PathBuf>,
    /// Phase-randomised surrogates per selection step (the p-value resolution is 1/(N + 1)).
    #[arg(long, default_value_t = Options::default().surrogates)]
    pub surrogates: usize,
    /// Significance level of a finding.
    #[arg(long, default_value_t = Options::default().alpha)]
    pub alpha: f64,
    /// Time-blocked cross-validation folds.
    #[arg(long, default_value_t = Options::default().folds)]
    pub folds: usize,
    /// Seed of the surrogates (the same seed gives the same report).
    #[arg(long, default_value_t = Options::default().seed)]
    pub seed: u64,
    /// Average both recordings over blocks of this many seconds as they are read (one row
    /// per block, each column its mean there): for recordings longer than the analysis takes
    /// at their own rate (2,000,000 rows each, fewer where the memory free would not hold
    /// the analysis), e.g. 1 kHz servo data over hours.
    #[arg(long, value_name = "SECONDS")]
    pub average: Option<f64>,
}

/// Tells the C allocator to keep the memory the analysis frees for its next columns.
///
/// The analysis builds thousands of short-lived full-rate columns (800 kB each on 100,000 rows)
/// on several threads. By default glibc serves blocks that size with fresh mappings and hands
/// freed memory back to the system, so every column is faulted in and zeroed page by page
/// again: about 240,000 page faults and a tenth of the command's time on 100,000 rows
/// (docs/performance.md). Blocks up to 32 MiB now come from the allocator's heaps and freed
/// memory stays in the process until 256 MiB of it lies unused at the top of a heap. Both
/// must be set: raising the trim threshold alone turns off glibc's own adaptive threshold and
/// makes every column a fresh mapping (slower than the default).
fn keep_freed_memory_for_reuse() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: `mallopt` only changes two allocator parameters; it runs before this command
    // starts any thread (argument parsing spawns none), so no allocation is in flight in another
    // thread while glibc updates them.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, 32 << 20);
        libc::mallopt(libc::M_TRIM_THRESHOLD, 256 << 20);
    }
}

/// Reads a recording (or the pieces of one) for the analysis: whole, or averaged over
/// `average` seconds' blocks, and
/// never more rows than `budget` allows (at most [`servosight::discrepancy::MAX_ROWS`], fewer where
/// the memory free would not hold the analysis), so that a recording too long for it is
/// refused while it is read rather than after it filled the memory.
fn read_for_analysis(
    paths: &[PathBuf],
    average: Option<f64>,
    budget: RowBudget,
) -> anyhow::Result<Recording> {
    let read = RecordingPieces::open(paths)?.read_observed(budget.rows, average, &mut |_| true);
    let reason = budget.reason();
    read.map_err(|e| match e {
        RecordingError::TooManyRows { block_s: None, .. } => anyhow::anyhow!(
            "{e}: {reason}; average them over blocks of time as they are read with --average \
             SECONDS (--average 1 makes one row a second of a 1 kHz recording)"
        ),
        RecordingError::TooManyRows {
            block_s: Some(_), ..
        } => anyhow::anyhow!("{e}: {reason}; average them over longer blocks"),
        other => other.into(),
    })
}

/// Runs `servosight discrepancy`.
pub fn run(mut args: Args) -> anyhow::Result<()> {
    keep_freed_memory_for_reuse();
    args.real = recording_files(&args.real, &args.pieces, "--real")?.0;
    let inputs: Vec<&Path> = std::iter::once(args.sim.as_path())
        .chain(args.real.iter().map(PathBuf::as_path))
        .collect();
    refuse_overwriting_inputs(
        &inputs,
        &[
            args.json.as_deref(),
            args.plot_data.as_deref(),
            args.plot.as_deref(),
        ],
    )?;
    if let Some(block_s) = args.average
        && !(block_s.is_finite() && block_s > 0.0)
    {
        anyhow::bail!("--average must be a positive number of seconds, not {block_s}");
    }
    // The two files are read side by side: on a long recording reading is a quarter of the
    // command's time.
    let budget = RowBudget::now();
    let (sim, real) = std::thread::scope(|scope| {
        let sim = scope
            .spawn(|| read_for_analysis(std::slice::from_ref(&args.sim), args.average, budget));
        let real = read_for_analysis(&args.real, args.average, budget);
        (join_or_resume(sim), real)
    });
    let sim = sim.context("cannot read the simulation")?;
    let real = real.context("cannot read the real recording")?;
    if let Some(block_s) = args.average {
        eprintln!(
            "averaged over {block_s} s blocks: the simulation to {} rows, the real recording to {}",
            sim.len(),
            real.len()
        );
    }
    let options = Options {
        surrogates: args.surrogates,
        alpha: args.alpha,
        folds: args.folds,
        seed: args.seed,
        ..Options::default()
    };
    let report = analyse(&sim, &real, &args.target, &options)?;
    emit_report(args.json.as_deref(), &report, || {
        out!("{}", report.summary())
    })?;
    if let Some(path) = &args.plot_data {
        crate::servosight_cli::write_json(path, &report.plot)?;
    }
    // Last: a figure that cannot be written leaves the report and the data already written.
    if let Some(path) = &args.plot {
        let request = DiscrepancyRequest {
            sim: args.sim.clone(),
            real: args.real.clone(),
            find_later_pieces: false,
            target: args.target.clone(),
            average_s: args.average,
        };
        let outcome = DiscrepancyOutcome::new(request, args.real.clone(), report);
        let view = result_view(&outcome, PLOT_POINTS);
        let canvas = render_discrepancy(&view, false, PLOT_WIDTH_PX);
        canvas.save_png(path)?;
        eprintln!(
            "wrote {} ({} × {} px)",
            path.display(),
            canvas.width(),
            canvas.height()
        );
    }
    Ok(())
}
