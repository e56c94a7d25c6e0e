//! Trends: time series of the chosen channels over a time window, one plot per unit, drawn
//! from the history's decimation pyramid (bucket means with their min / max band).

use std::collections::{BTreeMap, BTreeSet};
use std::io::Write;
use std::path::Path;

use serde::{Deserialize, Serialize};

use super::{channel_label, unit};
use crate::signal::{AxisId, Channel};
use crate::ui::state::HmiState;

/// The time window presets.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum WindowPreset {
    /// The last minute.
    Minute,
    /// The last ten minutes.
    TenMinutes,
    /// The last hour.
    Hour,
    /// The last eight hours (a shift).
    Shift,
    /// Everything since the start.
    All,
}

impl WindowPreset {
    /// Every preset, in the order of the buttons.
    pub const ALL: [WindowPreset; 5] = [
        WindowPreset::Minute,
        WindowPreset::TenMinutes,
        WindowPreset::Hour,
        WindowPreset::Shift,
        WindowPreset::All,
    ];

    /// The button's label.
    pub fn label(self) -> &'static str {
        match self {
            WindowPreset::Minute => "1 min",
            WindowPreset::TenMinutes => "10 min",
            WindowPreset::Hour => "1 h",
            WindowPreset::Shift => "8 h",
            WindowPreset::All => "all",
        }
    }

    /// The window length, s (`None` for everything).
    pub fn seconds(self) -> Option<f64> {
        match self {
            WindowPreset::Minute => Some(60.0),
            WindowPreset::TenMinutes => Some(600.0),
            WindowPreset::Hour => Some(3600.0),
            WindowPreset::Shift => Some(8.0 * 3600.0),
            WindowPreset::All => None,
        }
    }
}

/// Default width of the channel picker, points.
pub const PICKER_WIDTH: f32 = 230.0;

/// What the operator chose on the Trends panel (persisted with the layout). Fields missing
/// from a settings file written by an older version take their defaults.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct TrendsSettings {
    /// Channels drawn, by column name.
    pub selected: Vec<String>,
    /// The window preset.
    pub preset: WindowPreset,
    /// Follow the newest sample (off once the operator zooms or pans). Not persisted, like the
    /// zoom itself: a past session's time range means nothing after a restart, so the plots
    /// start out following.
    #[serde(skip)]
    pub follow_live: bool,
    /// The time range the operator zoomed or panned to, s (used when not following).
    #[serde(skip)]
    pub view: Option<(f64, f64)>,
    /// Series the operator switched off in a plot's legend (still chosen, not drawn), by
    /// column name.
    pub hidden: BTreeSet<String>,
    /// Picker groups the operator opened or closed, by title; the others keep their default
    /// (reference instruments closed, the rest open).
    pub groups_open: BTreeMap<String, bool>,
    /// Width of the channel picker, points (`None`: [`PICKER_WIDTH`]).
    pub picker_width: Option<f32>,
}

impl Default for TrendsSettings {
    fn default() -> Self {
        TrendsSettings {
            selected: Vec::new(),
            preset: WindowPreset::TenMinutes,
            follow_live: true,
            view: None,
            hidden: BTreeSet::new(),
            groups_open: BTreeMap::new(),
            picker_width: None,
        }
    }
}

/// A channel in the picker.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ChannelChoice {
    /// Column name.
    pub name: String,
    /// "X stator temperature [°C]".
    pub label: String,
    /// Drawn now.
    pub selected: bool,
}

/// A group of the picker (one axis, the machine, reference instruments).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ChannelGroup {
    /// "X axis".
    pub title: String,
    /// Unfolded in the picker.
    pub open: bool,
    /// Its channels.
    pub channels: Vec<ChannelChoice>,
}

/// `[time_s, value]` points of one line.
pub type Points = Vec<[f64; 2]>;

/// One drawn series.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SeriesView {
    /// Column name.
    pub channel: String,
    /// Legend text.
    pub label: String,
    /// `[time_s, mean]` per point (the raw value at full rate).
    pub points: Points,
    /// `[time_s, min]` and `[time_s, max]` per point, when points are buckets of several
    /// samples.
    pub band: Option<(Points, Points)>,
    /// Switched off in the plot's legend: listed there, not drawn.
    pub hidden: bool,
}

/// One plot: the chosen series that share a unit.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PlotView {
    /// The y axis unit.
    pub unit: String,
    /// The series.
    pub series: Vec<SeriesView>,
}

/// The straightness of a feed axis along its stroke, in one direction, from the newest
/// estimates.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StraightnessView {
    /// "X".
    pub axis: String,
    /// "horizontal (H)" or "vertical (V)".
    pub direction: String,
    /// `[position along the stroke mm, deviation µm]` per node.
    pub points: Points,
    /// The ISO 1101 straightness (minimum zone) over the nodes, with unit.
    pub zone: String,
}

/// The Trends panel.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TrendsView {
    /// The picker.
    pub groups: Vec<ChannelGroup>,
    /// The picker's width, points.
    pub picker_width: f32,
    /// The window preset.
    pub preset: WindowPreset,
    /// Following the newest sample.
    pub follow_live: bool,
    /// The window, s.
    pub t0: f64,
    /// The window end, s.
    pub t1: f64,
    /// "full rate" or "1 point = 512 samples (min/max band shown)".
    pub resolution: String,
    /// The plots.
    pub plots: Vec<PlotView>,
    /// The estimated straightness profile along the stroke per feed axis and direction.
    pub straightness: Vec<StraightnessView>,
}

/// The newest straightness profiles: for every feed axis of the profile whose per-node
/// estimates the link carries, the deviation at each node against its position along the
/// stroke, and the ISO 1101 minimum-zone value over them.
pub fn straightness_profiles(state: &HmiState) -> Vec<StraightnessView> {
    let Some(profile) = &state.profile else {
        return Vec::new();
    };
    let mut out = Vec::new();
    for (axis, a) in &profile.axes {
        let Some(screw) = &a.screw else { continue };
        for (hv, direction) in [("h", "horizontal (H)"), ("v", "vertical (V)")] {
            let points: Points = screw
                .node_positions_mm
                .iter()
                .enumerate()
                .filter_map(|(k, x)| {
                    let name = format!(
                        "{}{axis}.straightness_{hv}_um#{}",
                        super::ESTIMATE_PREFIX,
                        k + 1
                    );
                    let d = state.latest.get(&name)?;
                    d.is_finite().then_some([*x, d])
                })
                .collect();
            if points.len() < 2 {
                continue;
            }
            let xs: Vec<f64> = points.iter().map(|p| p[0]).collect();
            let ds: Vec<f64> = points.iter().map(|p| p[1]).collect();
            let zone = crate::estimators::streaming::minimum_zone_straightness(&xs, &ds);
            out.push(StraightnessView {
                axis: axis.to_string(),
                direction: direction.to_string(),
                points,
                zone: format!("{} µm", super::number(Some(zone), 2)),
            });
        }
    }
    out
}

/// The axis of an estimator output column (`est.X.nut_temp_C` → X).
fn estimate_axis(name: &str) -> Option<AxisId> {
    let rest = name.strip_prefix(super::ESTIMATE_PREFIX)?;
    rest.split_once('.')?.0.parse().ok()
}

fn group_title(name: &str) -> String {
    if let Some(axis) = estimate_axis(name) {
        return format!("{axis} estimates");
    }
    match Channel::parse(name) {
        Channel::Servo { axis, .. } => format!("{axis} axis"),
        Channel::Reference { axis, .. } => format!("{axis} reference instruments"),
        _ => "machine".into(),
    }
}

fn group_order(name: &str) -> (u8, Option<AxisId>) {
    if let Some(axis) = estimate_axis(name) {
        return (1, Some(axis));
    }
    match Channel::parse(name) {
        Channel::Servo { axis, .. } => (0, Some(axis)),
        Channel::Reference { axis, .. } => (3, Some(axis)),
        _ => (2, None),
    }
}

/// Builds the Trends view with at most `max_points` points per series.
pub fn build(state: &HmiState, settings: &TrendsSettings, max_points: usize) -> TrendsView {
    let history = &state.history;
    let mut names: Vec<&String> = history.channels().iter().collect();
    names.sort_by_key(|n| group_order(n));
    let mut groups: Vec<ChannelGroup> = Vec::new();
    for name in names {
        let title = group_title(name);
        let choice = ChannelChoice {
            name: name.clone(),
            label: labelled(name),
            selected: settings.selected.contains(name),
        };
        match groups.iter_mut().find(|g| g.title == title) {
            Some(group) => group.channels.push(choice),
            None => groups.push(ChannelGroup {
                // Reference instruments are for calibration, not for watching the machine:
                // folded away unless the operator opened them.
                open: settings
                    .groups_open
                    .get(&title)
                    .copied()
                    .unwrap_or(!title.contains("reference")),
                title,
                channels: vec![choice],
            }),
        }
    }
    let newest = history.newest_time_s().unwrap_or(0.0);
    let oldest = history.oldest_time_s().unwrap_or(0.0);
    let (t0, t1) = match (settings.follow_live, settings.view) {
        (false, Some((a, b))) if b > a => (a, b),
        _ => match settings.preset.seconds() {
            Some(length) => (newest - length, newest),
            None => (oldest, newest),
        },
    };
    let indices: Vec<usize> = settings
        .selected
        .iter()
        .filter_map(|n| history.channel_index(n))
        .collect();
    let window = history.window(&indices, t0, t1, max_points);
    let per_point = window.samples_per_point.iter().copied().max().unwrap_or(1);
    let resolution = if per_point <= 1 {
        "full rate".to_string()
    } else {
        format!("1 point = up to {per_point} samples (mean, with the min/max band)")
    };
    let mut plots: Vec<PlotView> = Vec::new();
    for (k, &c) in indices.iter().enumerate() {
        let name = &history.channels()[c];
        let series = &window.series[k];
        let points = window
            .time_s
            .iter()
            .zip(&series.mean)
            .filter(|(_, v)| v.is_finite())
            .map(|(t, v)| [*t, f64::from(*v)])
            .collect();
        let band = (per_point > 1).then(|| {
            let pick = |values: &[f32]| {
                window
                    .time_s
                    .iter()
                    .zip(values)
                    .filter(|(_, v)| v.is_finite())
                    .map(|(t, v)| [*t, f64::from(*v)])
                    .collect::<Vec<_>>()
            };
            (pick(&series.min), pick(&series.max))
        });
        let view = SeriesView {
            channel: name.clone(),
            label: labelled(name),
            points,
            band,
            hidden: settings.hidden.contains(name),
        };
        let u = unit(name);
        match plots.iter_mut().find(|p| p.unit == u) {
            Some(plot) => plot.series.push(view),
            None => plots.push(PlotView {
                unit: u,
                series: vec![view],
            }),
        }
    }
    TrendsView {
        groups,
        // A width saved on a larger screen (or a broken file) must not hide the plots.
        picker_width: settings
            .picker_width
            .filter(|w| w.is_finite())
            .map_or(PICKER_WIDTH, |w| w.clamp(120.0, 800.0)),
        preset: settings.preset,
        follow_live: settings.follow_live,
        t0,
        t1,
        resolution,
        plots,
        straightness: straightness_profiles(state),
    }
}

fn labelled(name: &str) -> String {
    let u = unit(name);
    if u.is_empty() {
        channel_label(name)
    } else {
        format!("{} [{u}]", channel_label(name))
    }
}

/// Why an export failed.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    /// Nothing is drawn.
    #[error("nothing to export: choose at least one channel with data in the window")]
    Empty,
    /// The file could not be written.
    // The operating system's error is part of the message and not also its `source`: the
    // command line prints an error's whole chain, which then said it twice.
    #[error("{path}: {error}")]
    Io {
        /// The file.
        path: String,
        /// The operating system's error.
        error: std::io::Error,
    },
}

/// Writes what the Trends panel shows as CSV: `time_s`, then for each series its mean and,
/// for decimated windows, its min and max (`<column>`, `<column>.min`, `<column>.max`). Points
/// of the different series share their times (they come from one window query). Returns the
/// rows written.
pub fn export_csv(view: &TrendsView, path: &Path) -> Result<usize, ExportError> {
    let series: Vec<&SeriesView> = view.plots.iter().flat_map(|p| &p.series).collect();
    let Some(first) = series.first() else {
        return Err(ExportError::Empty);
    };
    let io = |error| ExportError::Io {
        path: path.display().to_string(),
        error,
    };
    let mut out = std::io::BufWriter::new(std::fs::File::create(path).map_err(io)?);
    let decimated = first.band.is_some();
    writeln!(out, "# exported: servosight Trends panel").map_err(io)?;
    writeln!(out, "# window_s: {} .. {}", view.t0, view.t1).map_err(io)?;
    writeln!(out, "# resolution: {}", view.resolution).map_err(io)?;
    let mut header = vec!["time_s".to_string()];
    for s in &series {
        header.push(s.channel.clone());
        if decimated {
            header.push(format!("{}.min", s.channel));
            header.push(format!("{}.max", s.channel));
        }
    }
    writeln!(out, "{}", header.join(",")).map_err(io)?;
    // Rows by time: a series that had no value at a time leaves its cell empty.
    let mut times: Vec<f64> = series
        .iter()
        .flat_map(|s| s.points.iter().map(|p| p[0]))
        .collect();
    times.sort_by(f64::total_cmp);
    times.dedup();
    let lookup = |points: &[[f64; 2]], t: f64| -> String {
        points
            .binary_search_by(|p| p[0].total_cmp(&t))
            .map(|i| points[i][1].to_string())
            .unwrap_or_default()
    };
    for &t in &times {
        let mut cells = vec![t.to_string()];
        for s in &series {
            cells.push(lookup(&s.points, t));
            if let Some((min, max)) = &s.band {
                cells.push(lookup(min, t));
                cells.push(lookup(max, t));
            } else if decimated {
                cells.push(String::new());
                cells.push(String::new());
            }
        }
        writeln!(out, "{}", cells.join(",")).map_err(io)?;
    }
    out.flush().map_err(io)?;
    Ok(times.len())
}
