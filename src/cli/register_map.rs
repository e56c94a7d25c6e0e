//! `servosight register-map`: the Modbus register map as JSON (for tools and test peers) or as
//! the Markdown tables of `docs/register-map.md`.

use std::path::PathBuf;

use crate::servosight_cli::out;
use servosight::link::register_map;

/// Arguments of `servosight register-map`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Print the Markdown tables instead of JSON.
    #[arg(long)]
    pub markdown: bool,
    /// Write the JSON here instead of stdout.
    #[arg(long)]
    pub json: Option<PathBuf>,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    if args.markdown {
        out!("{}", register_map::markdown_tables())?;
        return Ok(());
    }
    let path = args.json.unwrap_or_else(|| PathBuf::from("-"));
    crate::servosight_cli::write_json(&path, &register_map::describe())
}
