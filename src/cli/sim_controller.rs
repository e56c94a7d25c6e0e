//! `servosight sim-controller --port DEV --replay FILE.csv`: a Modbus RTU slave speaking the
//! register map, publishing the rows of a recording and accepting compensation commits.
//!
//! Serving the physics twin instead of a recording waits for the twin's streaming API.

use std::path::PathBuf;

use anyhow::Context;
use servosight::link::controller_sim::{self, RecordingSource};

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
    /// Publish the rows of this recording (CSV v1 with every column of the register map),
    /// looping at the end.
    #[arg(long)]
    pub replay: PathBuf,
    /// Replay speed (recording seconds per wall-clock second).
    #[arg(long, default_value_t = 1.0)]
    pub speed: f64,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let recording = servosight::signal::read_recording(&args.replay)
        .with_context(|| format!("cannot read {}", args.replay.display()))?;
    let source = RecordingSource::new(recording, args.speed)?;
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .context("cannot start the runtime")?;
    eprintln!(
        "serving {} as slave {} on {}",
        args.replay.display(),
        args.slave,
        args.port
    );
    runtime.block_on(controller_sim::serve(
        &args.port,
        args.baud,
        args.slave,
        Box::new(source),
    ))?;
    Ok(())
}
