//! `servosight fit`: multiple regression of one column on terms of others, with the paper's
//! F-test and R², statsmodels' per-coefficient inference, sensitivity and optional selection.

use std::path::PathBuf;

use crate::servosight_cli::{emit_report, out, refuse_overwriting_inputs};
use anyhow::Context;
use servosight::fit::{
    Criterion, Design, Direction, FitReport, SelectionOptions, ols, parse_terms, select,
    sensitivity,
};
use servosight::signal::read_recording;

/// How `--select` chooses terms.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum SelectMethod {
    /// Forward/backward stepwise by partial F-test (--p-enter / --p-remove).
    Stepwise,
    /// Forward/backward by the Bayesian information criterion.
    Bic,
}

/// Arguments of `servosight fit`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The database or recording (CSV v1).
    #[arg(long)]
    pub data: PathBuf,
    /// The column to explain.
    #[arg(long)]
    pub target: String,
    /// Comma-separated terms: a, a^2, a*b, lag(a,SECONDS), lowpass(a,TAU_SECONDS), delta(a);
    /// the intercept `const` is always included.
    #[arg(long)]
    pub terms: String,
    /// Choose among the terms instead of fitting them all.
    #[arg(long, value_enum)]
    pub select: Option<SelectMethod>,
    /// Stepwise: a term enters below this p-value.
    #[arg(long, default_value_t = 0.05)]
    pub p_enter: f64,
    /// Stepwise: a term leaves above this p-value.
    #[arg(long, default_value_t = 0.10)]
    pub p_remove: f64,
    /// Number of contiguous time blocks for cross-validating a selection.
    #[arg(long, default_value_t = 5)]
    pub cv_folds: usize,
    /// Rows left out of training on each side of a held-out block.
    #[arg(long, default_value_t = 0)]
    pub cv_gap_rows: usize,
    /// Write the report as JSON to this file ("-" for stdout, which replaces the table).
    #[arg(long)]
    pub json: Option<PathBuf>,
}

/// Runs `servosight fit`.
pub fn run(args: Args) -> anyhow::Result<()> {
    refuse_overwriting_inputs(&[&args.data], &[args.json.as_deref()])?;
    let terms = parse_terms(&args.terms)?;
    if terms.is_empty() {
        anyhow::bail!("--terms lists only `const`: give at least one term to fit");
    }
    let recording = read_recording(&args.data).context("cannot read the data")?;
    let design = Design::from_recording(&recording, &args.target, &terms)?;
    let (design, selection) = match args.select {
        None => (design, None),
        Some(method) => {
            let options = SelectionOptions {
                criterion: match method {
                    SelectMethod::Stepwise => Criterion::FTest {
                        p_enter: args.p_enter,
                        p_remove: args.p_remove,
                    },
                    SelectMethod::Bic => Criterion::Bic,
                },
                direction: Direction::Both,
                cv_folds: args.cv_folds,
                cv_gap_rows: args.cv_gap_rows,
            };
            let selection = select(&design, &options).context("selecting terms")?;
            let chosen: Vec<usize> = selection
                .chosen
                .iter()
                .filter_map(|term| design.term_index(term))
                .collect();
            (design.with_terms(&chosen), Some(selection))
        }
    };
    let fit = ols(&design)?;
    let mut report = FitReport::new(&fit, sensitivity(&fit, &design));
    if let Some(selection) = selection {
        report = report.with_selection(selection);
    }
    emit_report(args.json.as_deref(), &report, || {
        out!("{}", report.summary_table())
    })
}
