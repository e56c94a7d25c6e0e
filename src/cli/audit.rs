//! `servosight audit verify LOG`: checks the compensation audit log's hash chain.

use std::path::PathBuf;

use crate::servosight_cli::outln;
use servosight::compensation::audit;

/// Arguments of `servosight audit`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(subcommand)]
    pub command: Command,
}

/// The audit subcommands.
#[derive(Debug, clap::Subcommand)]
pub enum Command {
    /// Verify every entry and the chain; fails naming the first edited line.
    Verify {
        /// The audit log (JSON lines).
        log: PathBuf,
        /// Write `{entries, head_hash}` as JSON here ("-" for stdout).
        #[arg(long)]
        json: Option<PathBuf>,
        /// A head hash printed by an earlier verify: fails unless the log still holds that
        /// entry (the chain alone cannot show entries cut from its end, or an emptied log).
        #[arg(long, value_name = "HASH")]
        expect_head: Option<String>,
    },
}

pub fn run(args: Args) -> anyhow::Result<()> {
    match args.command {
        Command::Verify {
            log,
            json,
            expect_head,
        } => {
            crate::servosight_cli::refuse_overwriting_inputs(&[&log], &[json.as_deref()])?;
            let expect_head = expect_head
                .map(|head| {
                    let head = head.trim().to_ascii_lowercase();
                    anyhow::ensure!(
                        head.len() == 64 && head.chars().all(|c| c.is_ascii_hexdigit()),
                        "--expect-head must be a head hash as `audit verify` prints it (64 hex \
                         digits), not `{head}`"
                    );
                    Ok(head)
                })
                .transpose()?;
            let report = audit::verify_holding(&log, expect_head.as_deref())?;
            match json {
                Some(path) => crate::servosight_cli::write_json(&path, &report)?,
                None => outln!(
                    "{}: {} entries, chain intact, head {}",
                    log.display(),
                    report.entries,
                    report.head_hash
                )?,
            }
            Ok(())
        }
    }
}
