//! `servosight sim-controller --port DEV`: a Modbus RTU slave speaking the register map,
//! publishing the physics twin in real time (or the rows of a recording with `--replay`) and
//! accepting compensation commits; an applied X backlash compensation changes what the twin
//! simulates.

use std::path::PathBuf;

use anyhow::Context;
use servosight::link::controller_sim::{self, RecordingSource, SampleSource, TwinSource};
use servosight::sim::{ScenarioKind, Twin, TwinConfig};

/// Arguments of `servosight sim-controller`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Serial device to serve on (e.g. one end of a socat pty pair).
    #[arg(long)]
    pub port: String,
    /// Baud rate.
    #[arg(long, default_value_t = 115_200)]
    pub baud: u32,
    /// Slave id to answer to.
    #[arg(long, default_value_t = 1)]
    pub slave: u8,
    /// Publish the rows of this recording (CSV v1 with every column of the register map,
    /// `cut_depth_mm` included), looping at the end, instead of the twin.
    #[arg(long)]
    pub replay: Option<PathBuf>,
    /// Twin program: warmup, production, backlash-test or doe (the twin publishes Z at rest:
    /// it models only the spindle and X).
    #[arg(long, default_value = "production")]
    pub scenario: ScenarioKind,
    /// Twin sample rate, Hz (default: the scenario's usual rate).
    #[arg(long)]
    pub rate_hz: Option<f64>,
    /// Seed of the twin's program and noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Speed: simulated (or recorded) seconds per wall-clock second.
    #[arg(long, default_value_t = 1.0)]
    pub speed: f64,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let (source, what): (Box<dyn SampleSource>, String) = match &args.replay {
        Some(path) => {
            let recording = servosight::signal::read_recording(path)
                .with_context(|| format!("cannot read {}", path.display()))?;
            let source = RecordingSource::new(recording, args.speed)?;
            (Box::new(source), path.display().to_string())
        }
        None => {
            let mut config = TwinConfig::new(args.scenario, None, args.seed);
            if let Some(rate) = args.rate_hz {
                config.rate_hz = rate;
            }
            let twin = Twin::new(config).context("cannot start the twin")?;
            let source = TwinSource::new(twin, args.speed)?;
            (
                Box::new(source),
                format!("the twin ({})", args.scenario.name()),
            )
        }
    };
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .context("cannot start the runtime")?;
    eprintln!("serving {what} as slave {} on {}", args.slave, args.port);
    runtime.block_on(controller_sim::serve(
        &args.port, args.baud, args.slave, source,
    ))?;
    Ok(())
}
