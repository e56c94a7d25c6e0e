//! Compensation pushes that cannot hurt a machine.
//!
//! The path, in order, each stage a type that only the previous stage can produce:
//! a [`Proposal`] (from the estimators, or typed by an engineer) → an operator's [`Request`] →
//! an [`ApprovedRequest`] (a user with the approver role, not the requester, password checked
//! against an Argon2 hash) → [`apply`]: refusal on stale or disconnected data, bounds check
//! against [`CompensationLimits`] (absolute and per-step; large changes split into steps), write,
//! read back and verify, and an entry in the hash-chained [`audit`] log for every step and every
//! refusal. [`rollback_proposal`] turns the audit log's record of a push into a proposal that
//! restores the values before it, which then takes the same path.

pub mod audit;
pub mod credentials;
pub mod values;

use sha2::{Digest, Sha256};

pub use audit::{AuditEntry, AuditError, AuditLog, EntryContent, Outcome};
pub use credentials::{CredentialError, Credentials, Role};
pub use values::{CompensationId, CompensationKind, CompensationValues};

use crate::link::register_map::quantise_um;
use crate::link::{ConnectionState, ControllerLink, LinkError};

/// Limits of one kind of value, µm.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct KindLimits {
    /// No value of this kind may exceed this magnitude.
    pub absolute_um: f64,
    /// No single write may change a value of this kind by more than this.
    pub step_um: f64,
}

/// The safety limits of compensation writes; the machine profile embeds this table as
/// `[compensation_limits]`.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CompensationLimits {
    /// Backlash per axis.
    pub backlash: KindLimits,
    /// Thermal offset per axis / tool length.
    pub thermal_offset: KindLimits,
    /// Straightness table nodes.
    pub straightness: KindLimits,
    /// Refuse to write when the newest frame is older than this, s.
    pub max_data_age_s: f64,
    /// Refuse a change that needs more steps than this.
    pub max_steps: u32,
}

impl Default for CompensationLimits {
    /// Conservative limits for a small lathe; a machine profile should state its own.
    fn default() -> Self {
        CompensationLimits {
            backlash: KindLimits {
                absolute_um: 50.0,
                step_um: 5.0,
            },
            thermal_offset: KindLimits {
                absolute_um: 200.0,
                step_um: 20.0,
            },
            straightness: KindLimits {
                absolute_um: 30.0,
                step_um: 5.0,
            },
            max_data_age_s: 1.0,
            max_steps: 20,
        }
    }
}

impl CompensationLimits {
    /// The limits of one kind.
    pub fn of(&self, kind: CompensationKind) -> KindLimits {
        match kind {
            CompensationKind::Backlash => self.backlash,
            CompensationKind::ThermalOffset => self.thermal_offset,
            CompensationKind::Straightness => self.straightness,
        }
    }
}

/// Proposed new values and why.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Proposal {
    /// The new values, µm (only the ones to change).
    pub changes: CompensationValues,
    /// Why (shown to the approver, kept in the audit log).
    pub why: String,
    /// What supports it: a recording, an estimate, a report.
    pub evidence: String,
    /// `adjust`, or `rollback of <request id>`.
    #[serde(default = "default_action")]
    pub action: String,
}

fn default_action() -> String {
    "adjust".into()
}

impl Proposal {
    /// What every proposal must be before anybody is asked to approve it (checked when it is
    /// written and again when it is requested): it changes something, every value is a finite
    /// number of micrometres, no backlash compensation is negative, and it says why.
    pub fn validate(&self) -> Result<(), CompensationError> {
        if self.changes.is_empty() {
            return Err(CompensationError::Invalid(
                "the proposal changes nothing".into(),
            ));
        }
        if let Some((id, value)) = self.changes.iter().find(|(_, v)| !v.is_finite()) {
            return Err(CompensationError::Invalid(format!(
                "{id} = {value} is not a number"
            )));
        }
        // Backlash compensation adds lost motion back at a reversal; a negative amount would
        // make the axis overshoot by it at every reversal.
        if let Some((id, value)) = self
            .changes
            .iter()
            .find(|(id, v)| matches!(id, CompensationId::Backlash(_)) && *v < 0.0)
        {
            return Err(CompensationError::Invalid(format!(
                "{id} = {value} µm: a backlash compensation is never negative"
            )));
        }
        if self.why.trim().is_empty() {
            return Err(CompensationError::Invalid(
                "the proposal does not say why it is needed (the approver reads it)".into(),
            ));
        }
        Ok(())
    }
}

/// A proposal an operator asked to push.
#[derive(Debug, Clone, PartialEq)]
pub struct Request {
    proposal: Proposal,
    operator: String,
    id: String,
}

impl Request {
    /// An operator requests a proposal. The request id is derived from the proposal, the
    /// operator and the time, and ties the audit entries of all its steps together.
    pub fn new(proposal: Proposal, operator: &str) -> Result<Request, CompensationError> {
        if operator.trim().is_empty() {
            return Err(CompensationError::Invalid(
                "the operator has no name".into(),
            ));
        }
        proposal.validate()?;
        let mut hasher = Sha256::new();
        hasher.update(serde_json::to_string(&proposal).unwrap_or_default());
        hasher.update(operator.as_bytes());
        hasher.update(audit::utc_now().as_bytes());
        let id: String = hasher.finalize()[..6]
            .iter()
            .map(|b| format!("{b:02x}"))
            .collect();
        Ok(Request {
            proposal,
            operator: operator.to_string(),
            id,
        })
    }

    /// The proposal.
    pub fn proposal(&self) -> &Proposal {
        &self.proposal
    }

    /// Who asked.
    pub fn operator(&self) -> &str {
        &self.operator
    }

    /// The request id.
    pub fn id(&self) -> &str {
        &self.id
    }

    /// An approver approves. The approver must be a different person from the requester, hold
    /// the approver role and give the right password.
    pub fn approve(
        &self,
        credentials: &Credentials,
        approver: &str,
        password: &str,
    ) -> Result<ApprovedRequest, CompensationError> {
        if approver == self.operator {
            return Err(CompensationError::NotApproved(format!(
                "`{approver}` requested this push and cannot also approve it"
            )));
        }
        credentials
            .authenticate_approver(approver, password)
            .map_err(|e| CompensationError::NotApproved(e.to_string()))?;
        Ok(ApprovedRequest {
            request: self.clone(),
            approver: approver.to_string(),
        })
    }
}

/// A request an approver approved: the only thing [`apply`] accepts.
#[derive(Debug, Clone, PartialEq)]
pub struct ApprovedRequest {
    request: Request,
    approver: String,
}

impl ApprovedRequest {
    /// The request.
    pub fn request(&self) -> &Request {
        &self.request
    }

    /// Who approved.
    pub fn approver(&self) -> &str {
        &self.approver
    }
}

/// Errors of the compensation path. Every one of them means the push did not (completely)
/// happen; the audit log says how far it got.
#[derive(Debug, thiserror::Error)]
pub enum CompensationError {
    /// The request is malformed.
    #[error("invalid request: {0}")]
    Invalid(String),
    /// Approval failed.
    #[error("not approved: {0}")]
    NotApproved(String),
    /// A value is beyond its absolute limit, or the change needs too many steps.
    #[error("out of bounds: {0}")]
    OutOfBounds(String),
    /// The link is not live.
    #[error("refused: {0}")]
    NotLive(String),
    /// Talking to the controller failed.
    #[error(transparent)]
    Link(#[from] LinkError),
    /// The controller did not apply what was written.
    #[error("verification failed: {0}")]
    VerifyFailed(String),
    /// The audit log failed: the push is stopped, since it could not be recorded.
    #[error(transparent)]
    Audit(#[from] AuditError),
}

/// Splits the change from `current` (the complete table) to `changes` into complete tables,
/// each within the per-step limits of the previous, the last one holding the targets.
pub fn plan_steps(
    current: &CompensationValues,
    changes: &CompensationValues,
    limits: &CompensationLimits,
) -> Result<Vec<CompensationValues>, CompensationError> {
    let mut targets = Vec::new();
    for (id, value) in changes.iter() {
        let Some(now) = current.get(id) else {
            return Err(CompensationError::Invalid(format!(
                "the controller has no value {id}"
            )));
        };
        let limit = limits.of(id.kind());
        let target = quantise_um(value);
        if target.abs() > limit.absolute_um {
            return Err(CompensationError::OutOfBounds(format!(
                "{id} = {target} µm exceeds the absolute limit ±{} µm",
                limit.absolute_um
            )));
        }
        if limit.step_um.is_nan() || limit.step_um <= 0.0 {
            return Err(CompensationError::OutOfBounds(format!(
                "the per-step limit of {id} is {} µm: no change allowed",
                limit.step_um
            )));
        }
        if target != now {
            targets.push((id, now, target, limit.step_um));
        }
    }
    if targets.is_empty() {
        return Ok(Vec::new());
    }
    let needed = targets
        .iter()
        .map(|(_, now, target, step)| ((target - now).abs() / step).ceil() as u32)
        .max()
        .unwrap_or(1)
        .max(1);
    // Rounding each intermediate value to the register resolution can push a step a hair over
    // its limit; one more step then fixes it.
    for steps in needed..=needed + 2 {
        if steps > limits.max_steps {
            return Err(CompensationError::OutOfBounds(format!(
                "the change needs {steps} steps, more than the {} allowed",
                limits.max_steps
            )));
        }
        let mut plan = Vec::with_capacity(steps as usize);
        let mut previous = current.clone();
        let mut within = true;
        for k in 1..=steps {
            let mut table = previous.clone();
            for (id, now, target, step) in &targets {
                let value = if k == steps {
                    *target
                } else {
                    quantise_um(now + (target - now) * f64::from(k) / f64::from(steps))
                };
                let before = previous.get(*id).unwrap_or(*now);
                if (value - before).abs() > step + 1e-9 {
                    within = false;
                }
                table.set(*id, value);
            }
            plan.push(table.clone());
            previous = table;
        }
        if within {
            return Ok(plan);
        }
    }
    Err(CompensationError::OutOfBounds(
        "cannot split the change into steps within the limits".into(),
    ))
}

/// What [`apply`] did.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ApplyReport {
    /// The request id.
    pub request_id: String,
    /// The values before, for the ids changed.
    pub old: CompensationValues,
    /// The values after, for the ids changed.
    pub new: CompensationValues,
    /// Steps written.
    pub steps: u32,
    /// Audit entries written.
    pub audit_entries: Vec<u64>,
}

fn check_live(link: &ControllerLink, limits: &CompensationLimits) -> Result<(), String> {
    let status = link.status();
    match (status.state, status.last_frame_age_s) {
        (ConnectionState::Connected, Some(age)) if age <= limits.max_data_age_s => Ok(()),
        (ConnectionState::Connected, age) => Err(format!(
            "the newest frame is {} old, the limit is {} s",
            age.map_or_else(|| "missing".into(), |a| format!("{a:.3} s")),
            limits.max_data_age_s
        )),
        (state, _) => Err(format!(
            "the link is {state:?}{}",
            status
                .last_error
                .map(|e| format!(" ({e})"))
                .unwrap_or_default()
        )),
    }
}

/// Records a request that was refused before anything was sent (approval failed, for
/// example). Callers of [`Request::approve`] use this so that refusals are audited too.
pub fn record_refusal(
    audit: &mut AuditLog,
    request: &Request,
    approver: Option<&str>,
    controller: &str,
    reason: &str,
) -> Result<AuditEntry, AuditError> {
    audit.append(EntryContent {
        request_id: request.id.clone(),
        action: request.proposal.action.clone(),
        operator: request.operator.clone(),
        approver: approver.map(str::to_string),
        why: request.proposal.why.clone(),
        evidence: request.proposal.evidence.clone(),
        step: None,
        controller: controller.to_string(),
        old: CompensationValues::new(),
        new: request.proposal.changes.clone(),
        outcome: Outcome::Refused,
        detail: reason.to_string(),
    })
}

/// Pushes an approved request: freshness check, bounds and steps, then for each step write,
/// read back, verify and audit. Stops at the first step that does not verify.
pub fn apply(
    link: &ControllerLink,
    limits: &CompensationLimits,
    audit: &mut AuditLog,
    approved: ApprovedRequest,
) -> Result<ApplyReport, CompensationError> {
    let request = &approved.request;
    let controller = link.status().source;
    let changed_ids: Vec<CompensationId> =
        request.proposal.changes.iter().map(|(id, _)| id).collect();
    let entry = |step: Option<(u32, u32)>,
                 old: CompensationValues,
                 new: CompensationValues,
                 outcome: Outcome,
                 detail: String| EntryContent {
        request_id: request.id.clone(),
        action: request.proposal.action.clone(),
        operator: request.operator.clone(),
        approver: Some(approved.approver.clone()),
        why: request.proposal.why.clone(),
        evidence: request.proposal.evidence.clone(),
        step,
        controller: controller.clone(),
        old,
        new,
        outcome,
        detail,
    };
    let refuse = |audit: &mut AuditLog,
                  old: CompensationValues,
                  error: CompensationError|
     -> CompensationError {
        match audit.append(entry(
            None,
            old,
            request.proposal.changes.clone(),
            Outcome::Refused,
            error.to_string(),
        )) {
            Ok(_) => error,
            Err(audit_error) => audit_error.into(),
        }
    };
    if let Err(reason) = check_live(link, limits) {
        return Err(refuse(
            audit,
            CompensationValues::new(),
            CompensationError::NotLive(reason),
        ));
    }
    let current = match link.read_compensation().wait() {
        Ok(values) => values,
        Err(error) => {
            return Err(refuse(audit, CompensationValues::new(), error.into()));
        }
    };
    let old = current.restricted_to(&changed_ids);
    let plan = match plan_steps(&current, &request.proposal.changes, limits) {
        Ok(plan) => plan,
        Err(error) => return Err(refuse(audit, old, error)),
    };
    let steps = plan.len() as u32;
    let mut audit_entries = Vec::new();
    let mut before = current;
    for (k, table) in plan.into_iter().enumerate() {
        let step = Some((k as u32 + 1, steps));
        let step_old = before.restricted_to(&changed_ids);
        let step_new = table.restricted_to(&changed_ids);
        if let Err(reason) = check_live(link, limits) {
            let error = CompensationError::NotLive(reason);
            audit.append(entry(
                step,
                step_old,
                step_new,
                Outcome::Refused,
                error.to_string(),
            ))?;
            return Err(error);
        }
        match link.write_compensation(table.clone()).wait() {
            Err(error) => {
                // The write may or may not have reached the controller: read back what it
                // applies now, so the audit says where the machine stands.
                let readback = match link.read_compensation().wait() {
                    Ok(values) => format!(
                        "read-back after the failure: {}",
                        serde_json::to_string(&values.restricted_to(&changed_ids))
                            .unwrap_or_default()
                    ),
                    Err(e) => format!("read-back after the failure also failed: {e}"),
                };
                audit.append(entry(
                    step,
                    step_old,
                    step_new,
                    Outcome::WriteFailed,
                    format!("{error}; {readback}"),
                ))?;
                return Err(error.into());
            }
            Ok(outcome) if !outcome.verified() => {
                let detail = format!(
                    "controller status {:?}, token sent {} echoed {}, applied values read back {}",
                    outcome.status,
                    outcome.token,
                    outcome.echoed_token,
                    serde_json::to_string(&outcome.applied.restricted_to(&changed_ids))
                        .unwrap_or_default()
                );
                audit.append(entry(
                    step,
                    step_old,
                    step_new,
                    Outcome::VerifyFailed,
                    detail.clone(),
                ))?;
                return Err(CompensationError::VerifyFailed(detail));
            }
            Ok(outcome) => {
                let written = audit.append(entry(
                    step,
                    step_old,
                    step_new,
                    Outcome::Applied,
                    format!(
                        "read back and verified, controller generation {}",
                        outcome.generation
                    ),
                ))?;
                audit_entries.push(written.index);
                before = outcome.applied;
            }
        }
    }
    Ok(ApplyReport {
        request_id: request.id.clone(),
        old,
        new: before.restricted_to(&changed_ids),
        steps,
        audit_entries,
    })
}

/// A proposal that restores the values from before the last applied push in the log (or the
/// push `request_id`). A push that was applied only partly (some steps) is rolled back to the
/// values before its first step too.
pub fn rollback_proposal(
    entries: &[AuditEntry],
    request_id: Option<&str>,
) -> Result<Proposal, CompensationError> {
    let target = match request_id {
        Some(id) => id.to_string(),
        None => entries
            .iter()
            .rev()
            .find(|e| e.outcome == Outcome::Applied)
            .map(|e| e.request_id.clone())
            .ok_or_else(|| {
                CompensationError::Invalid("the audit log holds no applied push".into())
            })?,
    };
    let first = entries
        .iter()
        .find(|e| e.request_id == target && e.outcome == Outcome::Applied)
        .ok_or_else(|| {
            CompensationError::Invalid(format!("no applied push with request id {target}"))
        })?;
    Ok(Proposal {
        changes: first.old.clone(),
        why: format!("rollback of request {target} ({})", first.why),
        evidence: format!("audit log entry {}", first.index),
        action: format!("rollback of {target}"),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::link::register_map::compensation_ids;
    use crate::signal::AxisId;

    fn zero_table() -> CompensationValues {
        compensation_ids().iter().map(|id| (*id, 0.0)).collect()
    }

    #[test]
    fn large_changes_are_split_within_the_step_limit() {
        let limits = CompensationLimits::default();
        let id = CompensationId::ThermalOffset(AxisId::S);
        let other = CompensationId::Backlash(AxisId::X);
        let changes: CompensationValues = [(id, 73.3), (other, 4.0)].into_iter().collect();
        let plan = plan_steps(&zero_table(), &changes, &limits).unwrap();
        assert_eq!(plan.len(), 4, "73.3 µm at ≤ 20 µm per step");
        let mut previous = zero_table();
        for table in &plan {
            for (k, v) in table.iter() {
                let step = limits.of(k.kind()).step_um;
                assert!((v - previous.get(k).unwrap()).abs() <= step + 1e-9, "{k}");
            }
            previous = table.clone();
        }
        assert_eq!(plan.last().unwrap().get(id), Some(73.3));
        assert_eq!(plan.last().unwrap().get(other), Some(4.0));
        // Untouched values stay as they were.
        assert_eq!(plan[0].get(CompensationId::Backlash(AxisId::Z)), Some(0.0));
    }

    #[test]
    fn absolute_limits_unknown_ids_and_step_counts_are_refused() {
        let limits = CompensationLimits::default();
        let too_big: CompensationValues = [(CompensationId::Backlash(AxisId::X), 50.1)]
            .into_iter()
            .collect();
        assert!(matches!(
            plan_steps(&zero_table(), &too_big, &limits),
            Err(CompensationError::OutOfBounds(_))
        ));
        let unknown: CompensationValues = [(CompensationId::Backlash(AxisId::S), 1.0)]
            .into_iter()
            .collect();
        assert!(matches!(
            plan_steps(&zero_table(), &unknown, &limits),
            Err(CompensationError::Invalid(_))
        ));
        let tight = CompensationLimits {
            max_steps: 2,
            ..limits
        };
        let far: CompensationValues = [(CompensationId::ThermalOffset(AxisId::X), 100.0)]
            .into_iter()
            .collect();
        assert!(matches!(
            plan_steps(&zero_table(), &far, &tight),
            Err(CompensationError::OutOfBounds(_))
        ));
        let same: CompensationValues = [(CompensationId::ThermalOffset(AxisId::X), 0.0)]
            .into_iter()
            .collect();
        assert!(
            plan_steps(&zero_table(), &same, &limits)
                .unwrap()
                .is_empty()
        );
    }

    #[test]
    fn requests_need_an_approver_who_is_not_the_requester() {
        let mut credentials = Credentials::default();
        credentials
            .set_user("maria", Role::Approver, "pw-maria")
            .unwrap();
        credentials
            .set_user("otto", Role::Operator, "pw-otto")
            .unwrap();
        let proposal = Proposal {
            changes: [(CompensationId::Backlash(AxisId::X), 2.0)]
                .into_iter()
                .collect(),
            why: "test".into(),
            evidence: "none".into(),
            action: "adjust".into(),
        };
        let request = Request::new(proposal.clone(), "otto").unwrap();
        assert!(request.approve(&credentials, "maria", "pw-maria").is_ok());
        assert!(request.approve(&credentials, "maria", "nope").is_err());
        assert!(request.approve(&credentials, "otto", "pw-otto").is_err());
        let own = Request::new(proposal, "maria").unwrap();
        assert!(matches!(
            own.approve(&credentials, "maria", "pw-maria"),
            Err(CompensationError::NotApproved(_))
        ));
    }
}
