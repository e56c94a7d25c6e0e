//! Backlash from servo signals (paper Sect. 3.3).
//!
//! The test moves the axis back and forth with growing amplitude, starting from the minimum
//! increment. After a reversal the motor first crosses the lost motion without the table:
//! only the motor, screw and nut turn, and the current stays low. Once the lash is taken up
//! the table is driven and the current rises by the table's friction. The paper reads the
//! backlash off the amplitude at which that rise appears.
//!
//! This module fits that physics directly instead of eyeballing a knee. For a candidate
//! backlash `b`, a dead zone of width `b` run along the axis's commanded trajectory says at
//! every sample whether the table is driven; the current during moves is then
//! `c_move + ΔI·driven_b(t)`. The `b` that minimises the squared error is the backlash, fitted
//! separately per feed, and the profile-likelihood interval of `b` gives its confidence. Any
//! reciprocating program works, not only this crate's own test plan.

use crate::signal::{AxisId, Quantity, Recording, axis_column};

/// Backlash at one feed.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct BacklashAtSpeed {
    /// Motor speed of the test moves at this feed, rpm.
    pub speed_rpm: f64,
    /// Programmed feed, mm/min.
    pub feed_mm_per_min: f64,
    /// Fitted backlash, µm.
    pub backlash_um: f64,
    /// 95 % profile-likelihood interval, µm.
    pub ci_low_um: f64,
    /// Upper end of the interval, µm.
    pub ci_high_um: f64,
    /// Current rise when the table is driven, A.
    #[serde(rename = "current_rise_A")]
    pub current_rise_a: f64,
    /// t statistic of that rise (a real lash shows a clear rise).
    pub rise_t: f64,
    /// Samples used.
    pub samples: usize,
}

/// The backlash analysis of one axis (DESIGN.md's JSON contract plus detail).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct BacklashReport {
    /// The axis.
    pub axis: AxisId,
    /// The backlash, µm: the precision-weighted mean over feeds.
    pub backlash_um: f64,
    /// Per feed.
    pub by_speed: Vec<BacklashAtSpeed>,
    /// Feeds whose moves showed no rise of the current at all (mm/min): no knee, so no
    /// backlash at that feed; they count against the confidence.
    pub feeds_without_a_rise: Vec<f64>,
    /// 0–1: 1 when every feed found a clear current rise and a narrow interval that agree.
    pub confidence: f64,
    /// Machine time of the test in the recording, s.
    pub test_duration_s: f64,
}

/// Why a backlash analysis failed.
#[derive(Debug, thiserror::Error)]
pub enum BacklashError {
    /// A needed column is missing.
    #[error(transparent)]
    Recording(#[from] crate::signal::RecordingError),
    /// The recording holds no reciprocating moves.
    #[error(
        "{0}: no reciprocating moves of the {1} axis found (is this a backlash-test recording?)"
    )]
    NoMoves(String, AxisId),
    /// The moves were found, but at no feed did the current rise once the table was driven.
    #[error(
        "{0}: the {1} axis's moves were found, but at no feed ({2}) did the current rise once \
         the table was driven: no knee, so no backlash can be read (is the current recorded?)"
    )]
    NoRise(String, AxisId, String),
    /// Every row has the same time stamp: no moves can be timed.
    #[error("{0}: every row has the same time stamp, so no move can be timed")]
    TimeStalls(String),
    /// The lead is needed to turn feeds into motor speeds.
    #[error("screw lead must be positive, is {0} mm")]
    InvalidLead(f64),
}

/// Candidate backlash grid step, µm.
const GRID_STEP_UM: f64 = 0.1;
/// Largest backlash considered, as a multiple of the largest move (a lash larger than every
/// move cannot be seen).
const MAX_FRACTION_OF_LARGEST_MOVE: f64 = 0.95;

/// Finds the backlash of `axis` in a backlash-test recording.
pub fn analyse_backlash(
    recording: &Recording,
    axis: AxisId,
    lead_mm: f64,
) -> Result<BacklashReport, BacklashError> {
    if lead_mm.is_nan() || lead_mm <= 0.0 {
        return Err(BacklashError::InvalidLead(lead_mm));
    }
    let time = recording.time();
    let command =
        recording.column_for(&axis_column(axis, Quantity::Command), "the backlash test")?;
    let position =
        recording.column_for(&axis_column(axis, Quantity::Position), "the backlash test")?;
    let current =
        recording.column_for(&axis_column(axis, Quantity::Current), "the backlash test")?;
    let n = time.len();
    if n < 10 {
        return Err(BacklashError::NoMoves(recording.source().to_string(), axis));
    }
    if recording.median_step_s().is_none() {
        return Err(BacklashError::TimeStalls(recording.source().to_string()));
    }
    // The motor follows the command with the servo lag; find it by aligning motor and command
    // positions, then use the (noise-free) command shifted by that lag as the motor trajectory.
    let lag = servo_lag_samples(command, position);
    let motor: Vec<f64> = (0..n).map(|i| delayed(command, i, lag)).collect();
    let mut moves = find_moves(time, &motor);
    assign_feeds(&mut moves);
    if moves.len() < 4 {
        return Err(BacklashError::NoMoves(recording.source().to_string(), axis));
    }
    // Group moves by feed (programmed feeds differ by clear factors).
    let mut groups: Vec<(f64, Vec<&Move>)> = Vec::new();
    for m in &moves {
        match groups
            .iter_mut()
            .find(|(f, _)| (m.feed_mm_per_min / f - 1.0).abs() < 0.25)
        {
            Some((_, list)) => list.push(m),
            None => groups.push((m.feed_mm_per_min, vec![m])),
        }
    }
    groups.retain(|(_, list)| list.len() >= 6);
    if groups.is_empty() {
        return Err(BacklashError::NoMoves(recording.source().to_string(), axis));
    }
    groups.sort_by(|a, b| a.0.total_cmp(&b.0));
    let largest_um = moves.iter().map(|m| m.amplitude_um).fold(0.0, f64::max);
    let mut by_speed = Vec::new();
    let mut feeds_without_a_rise = Vec::new();
    for (feed, list) in &groups {
        // Samples inside this group's moves (plus the lag, while the motor is still moving).
        // Only samples at constant velocity: during acceleration the inertia torque
        // (J·α, amperes) swamps the table friction (a tenth of an ampere) the test looks for.
        let mut in_group = vec![false; n];
        for m in list {
            let last = m.end.min(n - 1);
            for (i, flag) in in_group.iter_mut().enumerate().take(last).skip(m.start + 1) {
                *flag = cruising(&motor, i);
            }
        }
        let fit = fit_group(
            &motor,
            current,
            &in_group,
            largest_um * MAX_FRACTION_OF_LARGEST_MOVE,
        );
        let Some(fit) = fit else { continue };
        // The current falling where the table should be driven is no knee: the best split of
        // a flat or noisy current lands anywhere, so its "backlash" would mean nothing.
        if fit.rise <= 0.0 {
            feeds_without_a_rise.push(*feed);
            continue;
        }
        by_speed.push(BacklashAtSpeed {
            speed_rpm: feed / lead_mm,
            feed_mm_per_min: *feed,
            backlash_um: fit.backlash_um,
            ci_low_um: fit.ci.0,
            ci_high_um: fit.ci.1,
            current_rise_a: fit.rise,
            rise_t: fit.rise_t,
            samples: fit.samples,
        });
    }
    if by_speed.is_empty() && !feeds_without_a_rise.is_empty() {
        let feeds: Vec<String> = feeds_without_a_rise
            .iter()
            .map(|f| format!("{f:.0} mm/min"))
            .collect();
        return Err(BacklashError::NoRise(
            recording.source().to_string(),
            axis,
            feeds.join(", "),
        ));
    }
    if by_speed.is_empty() {
        return Err(BacklashError::NoMoves(recording.source().to_string(), axis));
    }
    // Precision-weighted mean of the feeds that found a clear rise.
    let clear: Vec<&BacklashAtSpeed> = by_speed.iter().filter(|b| b.rise_t > 5.0).collect();
    let used = if clear.is_empty() {
        by_speed.iter().collect()
    } else {
        clear
    };
    let weight =
        |b: &BacklashAtSpeed| 1.0 / ((b.ci_high_um - b.ci_low_um).max(GRID_STEP_UM)).powi(2);
    let total: f64 = used.iter().map(|b| weight(b)).sum();
    let backlash_um = used.iter().map(|b| weight(b) * b.backlash_um).sum::<f64>() / total;
    // Confidence: share of feeds with a clear rise × how narrow and consistent the intervals are.
    let clear_share = by_speed.iter().filter(|b| b.rise_t > 5.0).count() as f64
        / (by_speed.len() + feeds_without_a_rise.len()) as f64;
    let width = used
        .iter()
        .map(|b| b.ci_high_um - b.ci_low_um)
        .fold(0.0, f64::max);
    let spread = used
        .iter()
        .map(|b| (b.backlash_um - backlash_um).abs())
        .fold(0.0, f64::max);
    let scale = backlash_um.max(2.0);
    let precision = (1.0 - (0.5 * width + spread) / scale).clamp(0.0, 1.0);
    Ok(BacklashReport {
        axis,
        backlash_um,
        by_speed,
        feeds_without_a_rise,
        confidence: clear_share * precision,
        test_duration_s: recording.duration_s(),
    })
}

/// One programmed move: samples `start..=end` (command moving), its amplitude and feed.
#[derive(Debug, Clone, PartialEq)]
struct Move {
    start: usize,
    end: usize,
    amplitude_um: f64,
    feed_mm_per_min: f64,
}

/// Short moves never reach their programmed feed (and a few samples cannot show it), so a
/// move shorter than `MIN_SAMPLES_FOR_FEED` takes the feed of the nearest long move in the
/// sequence: a test program runs one feed at a time.
fn assign_feeds(moves: &mut [Move]) {
    const MIN_SAMPLES_FOR_FEED: usize = 8;
    let measured: Vec<Option<f64>> = moves
        .iter()
        .map(|m| (m.end - m.start >= MIN_SAMPLES_FOR_FEED).then_some(m.feed_mm_per_min))
        .collect();
    for i in 0..moves.len() {
        if measured[i].is_some() {
            continue;
        }
        let before = (0..i).rev().find_map(|j| measured[j].map(|f| (i - j, f)));
        let after = (i + 1..moves.len()).find_map(|j| measured[j].map(|f| (j - i, f)));
        let nearest = match (before, after) {
            (Some(b), Some(a)) => Some(if b.0 <= a.0 { b.1 } else { a.1 }),
            (Some(b), None) => Some(b.1),
            (None, Some(a)) => Some(a.1),
            (None, None) => None,
        };
        if let Some(feed) = nearest {
            moves[i].feed_mm_per_min = feed;
        }
    }
}

/// Splits a trajectory into moves separated by standstill.
fn find_moves(time: &[f64], trajectory: &[f64]) -> Vec<Move> {
    let n = trajectory.len();
    let mut moves = Vec::new();
    let mut i = 1;
    while i < n {
        if (trajectory[i] - trajectory[i - 1]).abs() > 1e-9 {
            let start = i - 1;
            let mut end = i;
            let mut peak_speed = 0.0_f64;
            while end + 1 < n && (trajectory[end + 1] - trajectory[end]).abs() > 1e-9 {
                let dt = (time[end + 1] - time[end]).max(1e-12);
                peak_speed = peak_speed.max((trajectory[end + 1] - trajectory[end]).abs() / dt);
                end += 1;
            }
            let dt = (time[i] - time[i - 1]).max(1e-12);
            peak_speed = peak_speed.max((trajectory[i] - trajectory[i - 1]).abs() / dt);
            moves.push(Move {
                start,
                end,
                amplitude_um: (trajectory[end] - trajectory[start]).abs() * 1000.0,
                feed_mm_per_min: peak_speed * 60.0,
            });
            i = end + 1;
        } else {
            i += 1;
        }
    }
    moves
}

/// True when the trajectory moves at the same speed into and out of sample `i`.
fn cruising(trajectory: &[f64], i: usize) -> bool {
    if i == 0 || i + 1 >= trajectory.len() {
        return false;
    }
    let before = trajectory[i] - trajectory[i - 1];
    let after = trajectory[i + 1] - trajectory[i];
    before.abs() > 1e-12 && (after - before).abs() <= 1e-6 * before.abs().max(1e-9)
}

/// The delay (samples, fractional) between command and encoder position, by least squares:
/// the best whole number of samples over 0..=200, then refined between its neighbours. A servo
/// lag is rarely a whole number of samples, and half a sample (1 ms at 500 Hz) at 200 mm/min
/// is 3 µm of motor travel, three times what the test may be off by.
fn servo_lag_samples(command: &[f64], position: &[f64]) -> f64 {
    let n = command.len();
    let sse = |lag: f64| -> f64 {
        let first = lag.ceil() as usize;
        (first..n)
            .map(|i| (position[i] - delayed(command, i, lag)).powi(2))
            .sum::<f64>()
            / (n - first).max(1) as f64
    };
    let whole = (0..=200.min(n / 4))
        .map(|k| k as f64)
        .min_by(|a, b| sse(*a).total_cmp(&sse(*b)))
        .unwrap_or(0.0);
    // The squared error is smooth and single-minimum within a sample of the best whole lag.
    crate::fit::minimise::minimise_on_interval(sse, (whole - 1.0).max(0.0), whole + 1.0, 5e-4).at
}

/// `trajectory` delayed by `lag` samples at sample `i`, linearly interpolated (held at its
/// first value before the start). In samples, not seconds like `discrepancy::series::shifted`:
/// the lag is fitted in samples, and a live recording's time stamps are not an even grid (a lag
/// found in samples and applied in seconds put the HMI warm-up test's backlash at 8.3 µm).
fn delayed(trajectory: &[f64], i: usize, lag: f64) -> f64 {
    let at = i as f64 - lag;
    if at <= 0.0 {
        return trajectory[0];
    }
    let j = at.floor() as usize;
    let fraction = at - j as f64;
    let next = trajectory[(j + 1).min(trajectory.len() - 1)];
    trajectory[j] + fraction * (next - trajectory[j])
}

struct GroupFit {
    backlash_um: f64,
    ci: (f64, f64),
    rise: f64,
    rise_t: f64,
    samples: usize,
}

/// Fits `current = c + ΔI·driven_b` over the selected samples for every candidate `b`.
fn fit_group(motor: &[f64], current: &[f64], selected: &[bool], max_um: f64) -> Option<GroupFit> {
    let samples = selected.iter().filter(|s| **s).count();
    if samples < 10 {
        return None;
    }
    let steps = (max_um / GRID_STEP_UM).floor() as usize;
    let mut profile = Vec::with_capacity(steps + 1);
    let mut driven = vec![false; motor.len()];
    for k in 0..=steps {
        let b_um = k as f64 * GRID_STEP_UM;
        driven_samples(motor, b_um / 1000.0, &mut driven);
        let fit = two_level_fit(current, selected, &driven);
        profile.push((b_um, fit));
    }
    let (best_index, _) = profile
        .iter()
        .enumerate()
        .filter(|(_, (_, f))| f.is_some())
        .min_by(|(_, (_, a)), (_, (_, b))| {
            let (a, b) = (
                a.as_ref().map_or(f64::INFINITY, |f| f.sse),
                b.as_ref().map_or(f64::INFINITY, |f| f.sse),
            );
            a.total_cmp(&b)
        })?;
    let (_, best) = &profile[best_index];
    let best = best.as_ref()?;
    // Samples see the lash only at discrete motor positions, so SSE(b) is flat between them;
    // the middle of the flat minimum is the unbiased estimate (its lowest edge is biased low).
    let plateau: Vec<f64> = profile
        .iter()
        .filter(|(_, f)| {
            f.as_ref()
                .is_some_and(|f| f.sse <= best.sse * (1.0 + 1e-9) + 1e-15)
        })
        .map(|(b, _)| *b)
        .collect();
    let b_best = plateau.iter().sum::<f64>() / plateau.len().max(1) as f64;
    // Profile-likelihood 95 % interval: SSE(b) ≤ SSE_min (1 + F₀.₉₅(1, n − 3) / (n − 3)).
    let dof = (samples as f64 - 3.0).max(1.0);
    let limit = best.sse * (1.0 + 3.84 / dof);
    let inside: Vec<f64> = profile
        .iter()
        .filter(|(_, f)| f.as_ref().is_some_and(|f| f.sse <= limit))
        .map(|(b, _)| *b)
        .collect();
    let ci = (
        inside.iter().cloned().fold(f64::INFINITY, f64::min),
        inside.iter().cloned().fold(f64::NEG_INFINITY, f64::max),
    );
    Some(GroupFit {
        backlash_um: b_best,
        ci,
        rise: best.rise,
        rise_t: best.rise_t,
        samples,
    })
}

/// Marks the samples at which a dead zone of total width `gap_mm` drives the table, for a
/// motor trajectory that starts with the lash taken up against the direction of its first move.
fn driven_samples(motor: &[f64], gap_mm: f64, driven: &mut [bool]) {
    let half = 0.5 * gap_mm;
    let first_direction = motor
        .windows(2)
        .map(|w| w[1] - w[0])
        .find(|d| d.abs() > 1e-12)
        .map_or(1.0, f64::signum);
    let mut table = motor[0] - first_direction * half;
    driven[0] = false;
    for i in 1..motor.len() {
        let gap = motor[i] - table;
        let before = table;
        if gap > half {
            table = motor[i] - half;
        } else if gap < -half {
            table = motor[i] + half;
        }
        driven[i] = (table - before).abs() > 1e-12;
    }
}

struct TwoLevel {
    sse: f64,
    rise: f64,
    rise_t: f64,
}

/// Least squares of `current` on an intercept and the driven flag over the selected samples.
fn two_level_fit(current: &[f64], selected: &[bool], driven: &[bool]) -> Option<TwoLevel> {
    let (mut n0, mut n1, mut s0, mut s1, mut q0, mut q1) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    for i in 0..current.len() {
        if !selected[i] {
            continue;
        }
        let c = current[i];
        if driven[i] {
            n1 += 1.0;
            s1 += c;
            q1 += c * c;
        } else {
            n0 += 1.0;
            s0 += c;
            q0 += c * c;
        }
    }
    if n0 < 3.0 || n1 < 3.0 {
        return None;
    }
    let (m0, m1) = (s0 / n0, s1 / n1);
    let sse = (q0 - n0 * m0 * m0) + (q1 - n1 * m1 * m1);
    let sigma2 = sse / (n0 + n1 - 2.0);
    let rise = m1 - m0;
    let se = (sigma2 * (1.0 / n0 + 1.0 / n1)).sqrt();
    Some(TwoLevel {
        sse,
        rise,
        rise_t: if se > 0.0 { rise / se } else { 0.0 },
    })
}

/// The NC program of a backlash test (ISO/Fanuc dialect, radius programming): the moves of
/// `plan`, with comments stating the axis, the expected machine time and what to record.
pub fn nc_program(
    plan: &crate::sim::BacklashTestPlan,
    axis: AxisId,
    acceleration_mm_per_s2: f64,
) -> String {
    use std::fmt::Write;
    let mut out = String::new();
    let minutes = plan.duration_s(acceleration_mm_per_s2) / 60.0;
    let _ = writeln!(out, "%");
    let _ = writeln!(out, "O9100 (SERVOSIGHT BACKLASH TEST {axis})");
    let _ = writeln!(
        out,
        "(RECIPROCATING MOVES FROM {:.3} TO {:.3} UM AT {} MM/MIN, ABOUT {:.1} MIN)",
        plan.min_increment_um,
        plan.max_amplitude_um,
        plan.feeds_mm_per_min
            .iter()
            .map(|f| format!("{f:.0}"))
            .collect::<Vec<_>>()
            .join("/"),
        minutes
    );
    let _ = writeln!(
        out,
        "(RECORD {axis} COMMAND, POSITION AND CURRENT AT 500 HZ OR FASTER)"
    );
    let _ = writeln!(out, "G90 G94 G40");
    for m in plan.moves() {
        let _ = writeln!(
            out,
            "G01 {axis}{:.4} F{:.1}",
            m.target_mm, m.feed_mm_per_min
        );
        if m.dwell_s > 0.0 {
            let _ = writeln!(out, "G04 X{:.3}", m.dwell_s);
        }
    }
    let _ = writeln!(out, "M30");
    let _ = writeln!(out, "%");
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dead_zone_drives_the_table_only_beyond_the_lash() {
        // 10 µm lash taken up for a + move: +30 µm drives the table; back 5 µm and 4 µm more
        // stay inside the lash (9 < 10 µm); 6 µm more drives it again.
        let motor: Vec<f64> = [0.0, 0.010, 0.020, 0.030, 0.025, 0.021, 0.015]
            .iter()
            .map(|x| x + 100.0)
            .collect();
        let mut driven = vec![false; motor.len()];
        driven_samples(&motor, 0.010, &mut driven);
        assert_eq!(driven, vec![false, true, true, true, false, false, true]);
    }

    #[test]
    fn servo_lag_is_found_to_a_fraction_of_a_sample() {
        // A reciprocating command and the encoder following it 16.4 samples late.
        let path =
            |k: f64| 100.0 + 0.05 * (k / 40.0).sin() + 0.002 * (k.rem_euclid(97.0) - 48.5).abs();
        let command: Vec<f64> = (0..4000).map(|i| path(i as f64)).collect();
        let position: Vec<f64> = (0..4000).map(|i| path(i as f64 - 16.4)).collect();
        let lag = servo_lag_samples(&command, &position);
        assert!((lag - 16.4).abs() < 0.02, "lag {lag} samples");
        assert!((delayed(&command, 100, 16.4) - path(83.6)).abs() < 1e-4);
    }

    #[test]
    fn nc_program_ends_and_states_its_duration() {
        let plan = crate::sim::BacklashTestPlan::default();
        let program = nc_program(&plan, AxisId::X, 2000.0);
        assert!(program.contains("O9100") && program.trim_end().ends_with('%'));
        assert!(program.lines().filter(|l| l.starts_with("G01 X")).count() > 200);
    }
}
