//! `servosight record --port DEV -o FILE.csv`: records every frame a controller sends.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::Context;
use servosight::link::{ControllerLink, Recorder, RecorderConfig};

use super::serial_args::SerialArgs;

/// Arguments of `servosight record`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    pub serial: SerialArgs,
    /// The recording (CSV v1); later parts are FILE-0001.csv, FILE-0002.csv, ….
    #[arg(short = 'o', long = "output")]
    pub output: PathBuf,
    /// Start a new part after this many MiB.
    #[arg(long, default_value_t = 256)]
    pub rotate_mib: u64,
    /// Start a new part after this many minutes.
    #[arg(long, default_value_t = 60)]
    pub rotate_min: u64,
    /// Stop after this many seconds (default: record until killed; at most the last second is
    /// lost then).
    #[arg(long)]
    pub duration_s: Option<f64>,
    /// Print the link state to stderr this often, s (0: never).
    #[arg(long, default_value_t = 5.0)]
    pub status_every_s: f64,
    /// Write a JSON summary (link and recorder counters) here at the end ("-" for stdout).
    #[arg(long)]
    pub json: Option<PathBuf>,
}

#[derive(Debug, serde::Serialize)]
struct Summary {
    files: Vec<String>,
    recorder: servosight::link::RecorderStats,
    link: servosight::link::LinkStatus,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    if let Some(seconds) = args.duration_s {
        anyhow::ensure!(
            seconds.is_finite() && seconds > 0.0,
            "--duration-s must be a positive number of seconds, not {seconds}"
        );
    }
    anyhow::ensure!(
        args.status_every_s.is_finite() && args.status_every_s >= 0.0,
        "--status-every-s must be 0 (never) or a positive number of seconds, not {}",
        args.status_every_s
    );
    // The recording does not exist yet (the recorder refuses a name that does), so the JSON
    // summary is compared with it by name.
    if let Some(json) = &args.json
        && std::path::absolute(json).ok() == std::path::absolute(&args.output).ok()
    {
        anyhow::bail!(
            "--json {} would write the summary over the recording: choose another path",
            json.display()
        );
    }
    let config = args.serial.config();
    let link = ControllerLink::modbus(config).context("cannot start the controller link")?;
    let mut recorder_config = RecorderConfig::new(&args.output);
    recorder_config.rotate_bytes = Some(args.rotate_mib.max(1) * 1024 * 1024);
    recorder_config.rotate_after = Some(Duration::from_secs(args.rotate_min.max(1) * 60));
    recorder_config.metadata = vec![
        ("source".into(), link.status().source),
        (
            "recorded_by".into(),
            format!("servosight {}", env!("CARGO_PKG_VERSION")),
        ),
        (
            "started_utc".into(),
            servosight::compensation::audit::utc_now(),
        ),
    ];
    let recorder = Recorder::create(recorder_config, link.schema(), link.has_sequence())
        .context("cannot create the recording")?;
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_time()
        .build()
        .context("cannot start the recorder's runtime")?;
    let (link, recorder) = runtime.block_on(record_loop(link, recorder, &args))?;
    let summary = Summary {
        files: recorder
            .paths()
            .iter()
            .map(|p| p.display().to_string())
            .collect(),
        link: link.status(),
        recorder: recorder.finish().context("cannot close the recording")?,
    };
    eprintln!(
        "recorded {} rows in {} file(s); {} samples lost upstream in {} gap(s)",
        summary.recorder.rows,
        summary.files.len(),
        summary.recorder.samples_lost_upstream,
        summary.recorder.gaps_marked
    );
    if let Some(path) = &args.json {
        let parts: Vec<&std::path::Path> = summary.files.iter().map(std::path::Path::new).collect();
        crate::servosight_cli::refuse_overwriting_inputs(&parts, &[Some(path)])?;
        crate::servosight_cli::write_json(path, &summary)?;
    }
    Ok(())
}

async fn record_loop(
    mut link: ControllerLink,
    mut recorder: Recorder,
    args: &Args,
) -> anyhow::Result<(ControllerLink, Recorder)> {
    let started = Instant::now();
    let deadline = args
        .duration_s
        .map(|s| started + Duration::from_secs_f64(s.max(0.0)));
    let mut tick = tokio::time::interval(Duration::from_millis(200));
    let mut last_status = Instant::now();
    loop {
        tokio::select! {
            frame = link.next_frame() => match frame {
                Some(frame) => recorder.record(&frame).context("cannot write the recording")?,
                None => break,
            },
            _ = tick.tick() => {
                recorder.flush_if_due().context("cannot flush the recording")?;
                if deadline.is_some_and(|d| Instant::now() >= d) {
                    // Frames already received are recorded before stopping.
                    while let Some(frame) = link.try_next_frame() {
                        recorder.record(&frame).context("cannot write the recording")?;
                    }
                    break;
                }
                if args.status_every_s > 0.0
                    && last_status.elapsed().as_secs_f64() >= args.status_every_s
                {
                    last_status = Instant::now();
                    let status = link.status();
                    let s = &status.stats;
                    eprintln!(
                        "{:?}: {} rows, {} lost in {} gaps, {} timeouts, {} CRC errors, {} exceptions, {} reconnects",
                        status.state,
                        recorder.stats().rows,
                        s.lost_samples,
                        s.sequence_gaps,
                        s.timeouts,
                        s.crc_errors,
                        s.exceptions,
                        s.reconnects
                    );
                }
            }
        }
    }
    Ok((link, recorder))
}
