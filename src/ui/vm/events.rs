//! Events: link events, condition changes, writes, recorder and job events, filterable.

use std::collections::BTreeSet;

use serde::{Deserialize, Serialize};

use crate::ui::state::{EventKind, HmiState, Severity};

/// The Events panel's filter (persisted with the layout).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct EventFilter {
    /// Kinds hidden.
    pub hidden: BTreeSet<String>,
    /// Show only warnings and faults.
    pub problems_only: bool,
    /// Text the message must contain (case-insensitive).
    #[serde(skip)]
    pub text: String,
}

/// One row.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EventRow {
    /// When, UTC.
    pub time_utc: String,
    /// What it is about.
    pub kind: EventKind,
    /// How bad.
    pub severity: Severity,
    /// What happened.
    pub message: String,
}

/// A kind in the filter.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct KindChoice {
    /// The kind.
    pub kind: EventKind,
    /// Its label.
    pub label: String,
    /// Shown.
    pub shown: bool,
    /// Events of this kind.
    pub count: usize,
}

/// The Events panel.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EventsView {
    /// The kind filter.
    pub kinds: Vec<KindChoice>,
    /// Only warnings and faults.
    pub problems_only: bool,
    /// Rows that pass the filter, newest first.
    pub rows: Vec<EventRow>,
    /// "12 of 40 events shown".
    pub summary: String,
}

/// Builds the Events panel, at most `limit` rows.
pub fn build(state: &HmiState, filter: &EventFilter, limit: usize) -> EventsView {
    let needle = filter.text.to_lowercase();
    let passes = |e: &crate::ui::state::Event| {
        !filter.hidden.contains(e.kind.label())
            && (!filter.problems_only || e.severity != Severity::Normal)
            && (needle.is_empty() || e.message.to_lowercase().contains(&needle))
    };
    let total = state.events.len();
    let matching = state.events.iter().filter(|e| passes(e)).count();
    let rows: Vec<EventRow> = state
        .events
        .iter()
        .rev()
        .filter(|e| passes(e))
        .take(limit)
        .map(|e| EventRow {
            time_utc: e.time_utc.clone(),
            kind: e.kind,
            severity: e.severity,
            message: e.message.clone(),
        })
        .collect();
    let kinds = EventKind::ALL
        .into_iter()
        .map(|kind| KindChoice {
            kind,
            label: kind.label().to_string(),
            shown: !filter.hidden.contains(kind.label()),
            count: state.events.iter().filter(|e| e.kind == kind).count(),
        })
        .collect();
    let mut summary = format!("{matching} of {total} events shown");
    if rows.len() < matching {
        summary.push_str(&format!(" (newest {} listed)", rows.len()));
    }
    if state.events.forgotten() > 0 {
        summary.push_str(&format!(
            "; {} older events dropped from memory",
            state.events.forgotten()
        ));
    }
    EventsView {
        kinds,
        problems_only: filter.problems_only,
        rows,
        summary,
    }
}
