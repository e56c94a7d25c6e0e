//! `servosight compensate …`: propose, apply (request + approval + bounded, verified write) and
//! roll back compensation values, and manage the users who may approve.
//!
//! Passwords never appear on the command line (where `ps` would show them): they are read from
//! the first line of stdin, or from `SERVOSIGHT_APPROVER_PASSWORD`.

use std::io::BufRead;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{Context, bail};
use servosight::compensation::{
    self, AuditLog, CompensationId, CompensationLimits, CompensationValues, Credentials, Proposal,
    Request, Role,
};
use servosight::link::{ConnectionState, ControllerLink};

use super::serial_args::SerialArgs;
use crate::servosight_cli::{outln, refuse_overwriting_inputs};

/// Arguments of `servosight compensate`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(subcommand)]
    pub command: Command,
}

/// The compensation subcommands.
#[derive(Debug, clap::Subcommand)]
pub enum Command {
    /// Write a proposal file: new values and why.
    Propose(ProposeArgs),
    /// Read the values the controller applies now.
    Show(ShowArgs),
    /// An operator's request, approved by an approver, pushed within the limits and verified.
    Apply(ApplyArgs),
    /// Restore the values from before the last (or a given) applied push, through the same path.
    Rollback(RollbackArgs),
    /// Add a user or change their role and password (password from stdin).
    SetUser(SetUserArgs),
}

/// Arguments of `compensate propose`.
#[derive(Debug, clap::Args)]
pub struct ProposeArgs {
    /// A new value, `ID=MICROMETRES`, e.g. `backlash.X=12.5`, `straightness.Z#3=-2`.
    #[arg(long = "set", required = true)]
    pub set: Vec<String>,
    /// Why the change is needed.
    #[arg(long)]
    pub why: String,
    /// What supports it (a recording, an estimate report).
    #[arg(long)]
    pub evidence: String,
    /// The proposal file to write.
    #[arg(short = 'o', long = "output")]
    pub output: PathBuf,
}

/// Arguments of `compensate show`.
#[derive(Debug, clap::Args)]
pub struct ShowArgs {
    #[command(flatten)]
    pub serial: SerialArgs,
}

/// Who asks and who approves, and where the rules and the record live.
#[derive(Debug, clap::Args)]
pub struct PushArgs {
    #[command(flatten)]
    pub serial: SerialArgs,
    /// The operator requesting the push (a user in the users file).
    #[arg(long)]
    pub operator: String,
    /// The approver (a user with the approver role, not the operator); password from stdin or
    /// SERVOSIGHT_APPROVER_PASSWORD.
    #[arg(long)]
    pub approver: String,
    /// The users file (TOML with Argon2 hashes).
    #[arg(long)]
    pub users: PathBuf,
    /// The audit log (JSON lines, hash-chained).
    #[arg(long)]
    pub audit: PathBuf,
    /// A TOML file with a `[compensation_limits]` table (the machine profile); built-in
    /// conservative limits when absent.
    #[arg(long)]
    pub limits: Option<PathBuf>,
    /// Write the result as JSON here ("-" for stdout).
    #[arg(long)]
    pub json: Option<PathBuf>,
}

/// Arguments of `compensate apply`.
#[derive(Debug, clap::Args)]
pub struct ApplyArgs {
    /// The proposal file.
    #[arg(long)]
    pub proposal: PathBuf,
    #[command(flatten)]
    pub push: PushArgs,
}

/// Arguments of `compensate rollback`.
#[derive(Debug, clap::Args)]
pub struct RollbackArgs {
    /// The request to roll back (default: the last applied one in the audit log).
    #[arg(long)]
    pub request: Option<String>,
    #[command(flatten)]
    pub push: PushArgs,
}

/// Arguments of `compensate set-user`.
#[derive(Debug, clap::Args)]
pub struct SetUserArgs {
    /// The users file (created if missing).
    #[arg(long)]
    pub users: PathBuf,
    /// Login name.
    #[arg(long)]
    pub name: String,
    /// operator or approver.
    #[arg(long)]
    pub role: String,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    match args.command {
        Command::Propose(args) => propose(args),
        Command::Show(args) => show(args),
        Command::Apply(args) => {
            let text = std::fs::read_to_string(&args.proposal)
                .with_context(|| format!("cannot read {}", args.proposal.display()))?;
            let proposal: Proposal = serde_json::from_str(&text)
                .with_context(|| format!("{} is not a proposal", args.proposal.display()))?;
            push(proposal, &args.push, Some(&args.proposal))
        }
        Command::Rollback(args) => {
            let audit = AuditLog::open(&args.push.audit).context("the audit log")?;
            let entries = audit.entries()?;
            drop(audit);
            let proposal = compensation::rollback_proposal(&entries, args.request.as_deref())?;
            push(proposal, &args.push, None)
        }
        Command::SetUser(args) => set_user(args),
    }
}

fn propose(args: ProposeArgs) -> anyhow::Result<()> {
    // The evidence is often a file (a recording, a report): never write the proposal over it.
    refuse_overwriting_inputs(&[Path::new(&args.evidence)], &[Some(&args.output)])?;
    let mut changes = CompensationValues::new();
    for item in &args.set {
        let (id, value) = item
            .split_once('=')
            .with_context(|| format!("`{item}` is not ID=MICROMETRES"))?;
        let id: CompensationId = id.trim().parse().map_err(anyhow::Error::msg)?;
        let value: f64 = value
            .trim()
            .parse()
            .with_context(|| format!("`{value}` is not a number of micrometres"))?;
        if !value.is_finite() {
            bail!("`{value}` is not a finite number of micrometres");
        }
        if let Some(earlier) = changes.get(id)
            && earlier != value
        {
            bail!("{id} is set twice, to {earlier} and to {value} µm: give it once");
        }
        changes.set(id, value);
    }
    let proposal = Proposal {
        changes,
        why: args.why,
        evidence: args.evidence,
        action: "adjust".into(),
    };
    proposal.validate()?;
    crate::servosight_cli::write_json(&args.output, &proposal)
}

/// Starts the link and waits until fresh frames arrive (or gives up).
fn connect(serial: &SerialArgs) -> anyhow::Result<ControllerLink> {
    let mut link = ControllerLink::modbus(serial.config()).context("cannot start the link")?;
    let deadline = Instant::now() + Duration::from_secs(5);
    loop {
        // Frames are not needed here; draining keeps the channel from filling.
        while link.try_next_frame().is_some() {}
        let status = link.status();
        if status.state == ConnectionState::Connected {
            return Ok(link);
        }
        if Instant::now() >= deadline {
            bail!(
                "no live data from {} within 5 s ({:?}{})",
                serial.port,
                status.state,
                status
                    .last_error
                    .map(|e| format!(": {e}"))
                    .unwrap_or_default()
            );
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

fn show(args: ShowArgs) -> anyhow::Result<()> {
    let link = connect(&args.serial)?;
    let values = link.read_compensation().wait()?;
    for (id, value) in values.iter() {
        outln!("{id:<20} {value:>9.1} µm")?;
    }
    Ok(())
}

fn read_password() -> anyhow::Result<String> {
    if let Ok(password) = std::env::var("SERVOSIGHT_APPROVER_PASSWORD") {
        return Ok(password);
    }
    let mut line = String::new();
    std::io::stdin()
        .lock()
        .read_line(&mut line)
        .context("cannot read the password from stdin")?;
    let password = line.trim_end_matches(['\n', '\r']).to_string();
    if password.is_empty() {
        bail!("no password: give it on stdin or in SERVOSIGHT_APPROVER_PASSWORD");
    }
    Ok(password)
}

/// The `[compensation_limits]` table of a TOML file, or conservative built-in limits.
pub(crate) fn load_limits(path: Option<&Path>) -> anyhow::Result<CompensationLimits> {
    #[derive(serde::Deserialize)]
    struct Profile {
        compensation_limits: CompensationLimits,
    }
    match path {
        None => Ok(CompensationLimits::default()),
        Some(path) => {
            let text = std::fs::read_to_string(path)
                .with_context(|| format!("cannot read {}", path.display()))?;
            let profile: Profile = toml::from_str(&text)
                .with_context(|| format!("{}: no valid [compensation_limits]", path.display()))?;
            Ok(profile.compensation_limits)
        }
    }
}

fn push(proposal: Proposal, args: &PushArgs, proposal_path: Option<&Path>) -> anyhow::Result<()> {
    let mut inputs = vec![args.users.as_path(), args.audit.as_path()];
    inputs.extend(args.limits.as_deref());
    inputs.extend(proposal_path);
    refuse_overwriting_inputs(&inputs, &[args.json.as_deref()])?;
    let credentials = Credentials::load(&args.users)?;
    if !credentials.users.iter().any(|u| u.name == args.operator) {
        bail!(
            "`{}` is not a user in {}",
            args.operator,
            args.users.display()
        );
    }
    let limits = load_limits(args.limits.as_deref())?;
    let mut audit = AuditLog::open(&args.audit).context("the audit log")?;
    let request = Request::new(proposal, &args.operator)?;
    let password = read_password()?;
    let approved = match request.approve(&credentials, &args.approver, &password) {
        Ok(approved) => approved,
        Err(error) => {
            compensation::record_refusal(
                &mut audit,
                &request,
                Some(&args.approver),
                &args.serial.port,
                &error.to_string(),
            )?;
            return Err(error.into());
        }
    };
    let link = connect(&args.serial)?;
    let report = compensation::apply(&link, &limits, &mut audit, approved)?;
    if report.steps == 0 {
        eprintln!("nothing to do: the controller already applies these values");
    } else {
        eprintln!(
            "request {}: applied and verified in {} step(s)",
            report.request_id, report.steps
        );
        for (id, new) in report.new.iter() {
            let old = report.old.get(id).unwrap_or(f64::NAN);
            eprintln!("  {id:<20} {old:>9.1} → {new:>9.1} µm");
        }
    }
    if let Some(path) = &args.json {
        crate::servosight_cli::write_json(path, &report)?;
    }
    Ok(())
}

fn set_user(args: SetUserArgs) -> anyhow::Result<()> {
    let role = match args.role.as_str() {
        "operator" => Role::Operator,
        "approver" => Role::Approver,
        other => bail!("unknown role `{other}` (expected operator or approver)"),
    };
    let password = read_password()?;
    let mut credentials = Credentials::load_or_empty(&args.users)?;
    credentials.set_user(&args.name, role, &password)?;
    credentials.save(&args.users)?;
    Ok(())
}
