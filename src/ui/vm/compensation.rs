//! Compensation: the controller's values, the proposal being put together, the request →
//! approval → write → read-back flow, and the audit history with rollback.

use serde::Serialize;

use super::number;
use crate::compensation::{CompensationId, Outcome, Role};
use crate::estimators::pipeline::ElongationOrigin;
use crate::link::ConnectionState;
use crate::signal::AxisId;
use crate::ui::state::{HmiState, PushFlow, PushResult};

/// One row of the controller table.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ValueRow {
    /// `backlash.X`.
    pub id: String,
    /// What the controller applies now, µm.
    pub current_um: String,
    /// The proposal's new value, µm, when the draft changes it.
    pub proposed_um: Option<String>,
    /// Limits of this kind: "±50.0 µm, ≤ 5.0 µm per step".
    pub limits: String,
}

/// The request awaiting approval (what the approver sees before giving their credential).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RequestView {
    /// The request id.
    pub request_id: String,
    /// `adjust` or `rollback of …`.
    pub action: String,
    /// Who asked.
    pub operator: String,
    /// "backlash.X: 0.0 -> 12.5 µm" per value.
    pub changes: Vec<String>,
    /// Why.
    pub why: String,
    /// What supports it.
    pub evidence: String,
}

/// Where the push stands.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "stage", rename_all = "snake_case")]
pub enum FlowView {
    /// No request pending.
    Idle,
    /// The approver dialog is open.
    AwaitingApproval {
        /// The request.
        request: RequestView,
        /// Approvers in the users file (not the requester).
        approvers: Vec<String>,
        /// Why the last attempt was refused.
        refusal: Option<String>,
    },
    /// Checking the credential, writing, reading back.
    Writing {
        /// The request.
        request: RequestView,
        /// Who approved.
        approver: String,
    },
    /// Finished: the read-back result.
    Finished(PushResult),
}

/// One audit log entry.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AuditRow {
    /// Position in the log.
    pub index: u64,
    /// When, UTC.
    pub time_utc: String,
    /// The request.
    pub request_id: String,
    /// `adjust` / `rollback of …`.
    pub action: String,
    /// "otto, approver maria" (requester, then who gave their credential).
    pub who: String,
    /// "2/3" for a split push.
    pub step: String,
    /// applied, refused, write_failed, verify_failed.
    pub outcome: String,
    /// "backlash.X 0.0 -> 2.0 µm".
    pub changes: String,
    /// Details.
    pub detail: String,
    /// Whether this row's push can be rolled back (an applied adjust, its first step).
    pub can_roll_back: bool,
}

/// A compensation value computed from the live estimates or the warm-up analysis.
#[derive(Debug, Clone, PartialEq)]
pub struct EstimateProposal {
    /// The value.
    pub id: CompensationId,
    /// The proposed value, µm (rounded to 0.1 µm, the table's resolution on screen).
    pub value_um: f64,
    /// What it is computed from, in words (goes into the request's evidence).
    pub basis: String,
    /// Why it must not be used although it can be computed (the estimate does not count from
    /// a known tool length).
    pub withheld: Option<String>,
}

/// Where a spindle's elongation estimate counts from, in words: `Ok` when the estimate is the
/// growth since a known tool length, `Err` with what to do when it is not. The thermal offset
/// corrects the tool length measured at that moment, so a spindle that was already warm when
/// the estimates started has grown by an amount nobody estimated, and a correction built on the
/// estimate would leave that growth uncorrected.
pub fn elongation_counted_from(state: &HmiState, axis: AxisId) -> Result<String, String> {
    let measure = "measure the tool and press Tool measured on the Warm-up panel";
    let origin = state.elongation_origin(axis);
    // The origin and the frames travel separately: an origin newer than the newest frame
    // belongs to estimates not shown yet.
    if let Some(o) = origin
        && state.latest.time_s().is_none_or(|t| t < o.time_s())
    {
        return Err(format!(
            "the newest estimates are from before the count that starts at machine time {:.1} s",
            o.time_s()
        ));
    }
    match origin {
        Some(ElongationOrigin::ToolMeasured {
            time_s,
            started_warm_K,
        }) => Ok(format!(
            "counted from the tool measurement at {}{}",
            machine_time(time_s),
            started_warm_K.map_or_else(String::new, |k| format!(
                "; the spindle was {k:.1} K above the room when the estimates started, so for \
                 the first hours the model's heat may read growth a spindle in balance does not \
                 show"
            ))
        )),
        Some(ElongationOrigin::FirstFrameAtRest { time_s }) => Ok(format!(
            "counted from the estimates' start at {}, the spindle at rest then (no tool \
             measured since)",
            machine_time(time_s)
        )),
        Some(ElongationOrigin::FirstFrameWarm { time_s, excess_K }) => Err(format!(
            "the spindle was {excess_K:.1} K above the room when the estimates started at \
             {}, so its growth before then is unknown: {measure}",
            machine_time(time_s)
        )),
        Some(ElongationOrigin::AcrossGap {
            time_s,
            gap_end_s,
            gap_s,
        }) => Err(format!(
            "counted from {}, but the frames stopped for {} before {}, and how far the spindle \
             grew or shrank then is unknown: {measure}",
            machine_time(time_s),
            crate::ui::vm::duration(gap_s),
            machine_time(gap_end_s)
        )),
        Some(ElongationOrigin::FirstFrameUnread { time_s }) => Err(format!(
            "no room or spindle stator reading at the estimates' start ({}) says whether the \
             spindle was at rest: {measure}",
            machine_time(time_s)
        )),
        None => Err(
            "the estimators have not yet counted a frame since they started or the tool was \
             measured"
                .into(),
        ),
    }
}

/// A machine time in words; one before zero is before this session's clock started (the
/// estimators carried on from the last session's state, whose times moved onto this clock).
fn machine_time(time_s: f64) -> String {
    if time_s < 0.0 {
        format!(
            "machine time {time_s:.1} s (before this session's clock started: carried over from \
             the last session)"
        )
    } else {
        format!("machine time {time_s:.1} s")
    }
}

/// Compensation values the estimates call for: the spindle's thermal offset from its
/// estimated elongation, a feed axis's backlash from the warm-up backlash test. Only values
/// the controller's table has are proposed. (Straightness tables are not proposed: the
/// controller's node positions along the stroke are not known to the HMI.) A thermal offset
/// whose elongation does not count from a known tool length is listed, withheld, with why.
pub fn estimate_proposals(state: &HmiState) -> Vec<EstimateProposal> {
    let Some(table) = &state.compensation.controller else {
        return Vec::new();
    };
    let mut out = Vec::new();
    let round = |v: f64| (v * 10.0).round() / 10.0;
    for axis in state.latest.axes() {
        let column = format!("{}{axis}.elongation_um", super::ESTIMATE_PREFIX);
        let id = CompensationId::ThermalOffset(axis);
        if let Some(e) = state.latest.get(&column).filter(|v| v.is_finite())
            && table.get(id).is_some()
        {
            let counted_from = elongation_counted_from(state, axis);
            out.push(EstimateProposal {
                id,
                value_um: round(e),
                basis: format!(
                    "estimated {axis} thermal elongation {e:.1} µm at machine time {} s ({})",
                    number(state.latest.time_s(), 1),
                    counted_from
                        .as_deref()
                        .unwrap_or("not counted from a known tool length")
                ),
                withheld: counted_from.err(),
            });
        }
    }
    if let Some(analysis) = &state.warmup.analysis
        && let Ok(report) = &analysis.backlash
    {
        let id = CompensationId::Backlash(analysis.axis);
        let min_confidence = state
            .profile
            .as_ref()
            .map_or(0.1, |p| p.warmup.min_backlash_confidence);
        if table.get(id).is_some() && report.confidence >= min_confidence {
            let (low, high) = report
                .by_speed
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), b| {
                    (l.min(b.ci_low_um), h.max(b.ci_high_um))
                });
            out.push(EstimateProposal {
                id,
                value_um: round(report.backlash_um),
                basis: format!(
                    "warm-up backlash test: {:.1} µm (per-feed 95 % intervals {low:.1}–{high:.1} µm, confidence {:.2})",
                    report.backlash_um, report.confidence
                ),
                withheld: None,
            });
        }
    }
    out
}

/// A proposal as the panel shows it, beside the controller's value.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ProposalRow {
    /// `thermal_offset.S`.
    pub id: String,
    /// What the controller applies now, µm.
    pub current_um: String,
    /// The proposed value, µm.
    pub proposed_um: String,
    /// Proposed minus current, µm.
    pub change_um: String,
    /// What it is computed from.
    pub basis: String,
    /// Why it cannot be used (withheld, or beyond the absolute limit).
    pub blocked: Option<String>,
    /// Already in the draft at this value.
    pub in_draft: bool,
}

/// The Compensation panel.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CompensationView {
    /// Values computed from the estimates, beside the controller's; using one puts it into
    /// the draft (it is written only after a request and the approver's credential).
    pub proposals: Vec<ProposalRow>,
    /// The controller's table with the proposal beside it.
    pub values: Vec<ValueRow>,
    /// Why the table is not shown (a replay has no controller, the line is down, …).
    pub controller_note: Option<String>,
    /// The ids a proposal may change.
    pub ids: Vec<String>,
    /// The proposal's changes: `backlash.X = 12.5 µm`.
    pub draft: Vec<String>,
    /// Why a request cannot be made now, when it cannot.
    pub request_blocked: Option<String>,
    /// Where the push stands.
    pub flow: FlowView,
    /// The users file and who may approve.
    pub users_note: String,
    /// The audit log, newest first.
    pub audit: Vec<AuditRow>,
    /// Why the audit log cannot be shown.
    pub audit_note: Option<String>,
    /// A problem with the operator's last action.
    pub notice: Option<String>,
}

fn request_view(state: &HmiState, request: &crate::compensation::Request) -> RequestView {
    let proposal = request.proposal();
    let controller = state.compensation.controller.as_ref();
    RequestView {
        request_id: request.id().to_string(),
        action: proposal.action.clone(),
        operator: request.operator().to_string(),
        changes: proposal
            .changes
            .iter()
            .map(|(id, new)| {
                format!(
                    "{id}: {} -> {new:.1} µm",
                    number(controller.and_then(|c| c.get(id)), 1)
                )
            })
            .collect(),
        why: proposal.why.clone(),
        evidence: proposal.evidence.clone(),
    }
}

/// Approvers in the users file other than `operator`.
fn approvers(state: &HmiState, operator: Option<&str>) -> Vec<String> {
    state
        .compensation
        .users
        .iter()
        .filter(|(name, role)| *role == Role::Approver && Some(name.as_str()) != operator)
        .map(|(name, _)| name.clone())
        .collect()
}

/// Builds the Compensation panel.
pub fn build(state: &HmiState) -> CompensationView {
    let c = &state.compensation;
    let ids: Vec<CompensationId> = match &c.controller {
        Some(table) => table.iter().map(|(id, _)| id).collect(),
        None => Vec::new(),
    };
    let values = ids
        .iter()
        .map(|id| {
            let limits = c.limits.of(id.kind());
            ValueRow {
                id: id.to_string(),
                current_um: number(c.controller.as_ref().and_then(|t| t.get(*id)), 1),
                proposed_um: c.draft_changes.get(*id).map(|v| format!("{v:.1}")),
                limits: format!(
                    "±{:.1} µm, ≤ {:.1} µm per step",
                    limits.absolute_um, limits.step_um
                ),
            }
        })
        .collect();
    let controller_note = match (&c.controller, &c.controller_error) {
        (_, Some(error)) => Some(format!("controller values not available: {error}")),
        (None, None) => Some("waiting for the controller's values".into()),
        (Some(_), None) => None,
    };
    let request_blocked = if c.controller.is_none() {
        Some("no controller values: nothing can be written to this source".to_string())
    } else if c.audit_error.is_some() {
        Some("the audit log is not usable, so nothing may be written".to_string())
    } else if state.link.state != ConnectionState::Connected {
        Some(format!(
            "the link is {:?}: writes are refused on data that is not live",
            state.link.state
        ))
    } else if c.draft_changes.is_empty() {
        Some("add at least one change to the proposal".to_string())
    } else if !matches!(c.flow, PushFlow::Idle | PushFlow::Finished(_)) {
        Some("a request is already in progress".to_string())
    } else {
        None
    };
    let flow = match &c.flow {
        PushFlow::Idle => FlowView::Idle,
        PushFlow::AwaitingApproval { request, refusal } => FlowView::AwaitingApproval {
            request: request_view(state, request),
            approvers: approvers(state, Some(request.operator())),
            refusal: refusal.clone(),
        },
        PushFlow::Writing { request, approver } => FlowView::Writing {
            request: request_view(state, request),
            approver: approver.clone(),
        },
        PushFlow::Finished(result) => FlowView::Finished(result.clone()),
    };
    let users_note = match &c.users_error {
        Some(error) => format!(
            "users file {} not readable ({error}); add an approver with \
             `servosight compensate set-user --users {} --name NAME --role approver`",
            c.users_path, c.users_path
        ),
        None => {
            let names = approvers(state, None);
            if names.is_empty() {
                format!(
                    "no approver in {}; add one with \
                     `servosight compensate set-user --users {} --name NAME --role approver`",
                    c.users_path, c.users_path
                )
            } else {
                format!("approvers in {}: {}", c.users_path, names.join(", "))
            }
        }
    };
    let first_applied: std::collections::BTreeMap<&str, u64> = c
        .audit
        .iter()
        .filter(|e| e.outcome == Outcome::Applied)
        .fold(Default::default(), |mut m, e| {
            m.entry(e.request_id.as_str()).or_insert(e.index);
            m
        });
    let audit = c
        .audit
        .iter()
        .rev()
        .map(|e| AuditRow {
            index: e.index,
            time_utc: e.time_utc.clone(),
            request_id: e.request_id.clone(),
            action: e.action.clone(),
            who: match &e.approver {
                Some(a) => format!("{}, approver {a}", e.operator),
                None => e.operator.clone(),
            },
            step: e.step.map(|(k, n)| format!("{k}/{n}")).unwrap_or_default(),
            outcome: match e.outcome {
                Outcome::Applied => "applied",
                Outcome::Refused => "refused",
                Outcome::WriteFailed => "write failed",
                Outcome::VerifyFailed => "verify failed",
            }
            .to_string(),
            changes: e
                .new
                .iter()
                .map(|(id, new)| format!("{id} {} -> {new:.1} µm", number(e.old.get(id), 1)))
                .collect::<Vec<_>>()
                .join(", "),
            detail: e.detail.clone(),
            can_roll_back: first_applied.get(e.request_id.as_str()) == Some(&e.index),
        })
        .collect();
    let proposals = estimate_proposals(state)
        .into_iter()
        .map(|p| {
            let current = c.controller.as_ref().and_then(|t| t.get(p.id));
            let limit = c.limits.of(p.id.kind()).absolute_um;
            ProposalRow {
                id: p.id.to_string(),
                current_um: number(current, 1),
                proposed_um: format!("{:.1}", p.value_um),
                change_um: number(current.map(|v| p.value_um - v), 1),
                basis: p.basis,
                blocked: p.withheld.or_else(|| {
                    (p.value_um.abs() > limit).then(|| {
                        format!("beyond the absolute limit ±{limit:.1} µm: check the machine first")
                    })
                }),
                in_draft: c.draft_changes.get(p.id) == Some(p.value_um),
            }
        })
        .collect();
    CompensationView {
        proposals,
        values,
        controller_note,
        ids: ids.iter().map(|id| id.to_string()).collect(),
        draft: c
            .draft_changes
            .iter()
            .map(|(id, v)| format!("{id} = {v:.1} µm"))
            .collect(),
        request_blocked,
        flow,
        users_note,
        audit,
        audit_note: c
            .audit_error
            .as_ref()
            .map(|e| format!("audit log not readable: {e}")),
        notice: c.notice.clone(),
    }
}
