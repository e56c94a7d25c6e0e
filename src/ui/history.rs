//! The in-memory history behind the Trends panel: every channel at full rate for the recent
//! past, then a decimation pyramid of min / max / mean buckets, so hours of 1 kHz data fit in a
//! fixed memory budget and any time window can be drawn from a few thousand points.
//!
//! The full-rate record is the recorder's file on disk; this is only what the screen needs.
//!
//! Level 0 holds raw samples. Level k ≥ 1 holds buckets of `factor` entries of level k − 1
//! (so `factorᵏ` raw samples each). Every level but the last is a ring of fixed capacity that
//! forgets its oldest entries; the last level keeps everything (with the default sizing one
//! bucket per 32768 samples: about 60 kB per hour of 1 kHz data for 40 channels). Capacities
//! come from a memory budget ([`HistoryConfig::for_budget`]), so [`History::memory_bytes`] stays under it.

/// How a [`History`] is sized.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct HistoryConfig {
    /// Raw samples kept at full rate.
    pub raw_capacity: usize,
    /// Entries of one level that make one bucket of the next.
    pub factor: usize,
    /// Buckets kept on each intermediate level, finest first (levels 1 ..); the level after
    /// the last of these is the unbounded top level.
    pub level_capacities: Vec<usize>,
}

impl HistoryConfig {
    /// Sizes the rings so that raw samples and intermediate buckets of `channels` channels fit
    /// in `budget_bytes`, with a factor of 8 between levels: a quarter of the budget each to
    /// raw samples and to levels 1 (8 samples per bucket) and 2 (64), an eighth to level 3
    /// (512), a sixteenth to level 4 (4096); the top level (32768 samples per bucket, about
    /// 15 kB per hour at 1 kHz) keeps everything.
    pub fn for_budget(channels: usize, budget_bytes: usize) -> HistoryConfig {
        let raw_entry = RAW_ENTRY_FIXED_BYTES + channels * RAW_VALUE_BYTES;
        let bucket_entry = BUCKET_ENTRY_FIXED_BYTES + channels * BUCKET_VALUE_BYTES;
        let share = |divisor: usize, entry: usize| (budget_bytes / divisor / entry).max(16);
        HistoryConfig {
            raw_capacity: share(4, raw_entry),
            factor: 8,
            level_capacities: vec![
                share(4, bucket_entry),
                share(4, bucket_entry),
                share(8, bucket_entry),
                share(16, bucket_entry),
            ],
        }
    }
}

/// The default memory budget of the HMI's history: 768 MiB, leaving room under the 1 GB
/// target for the rest of the application.
pub const DEFAULT_HISTORY_BUDGET_BYTES: usize = 768 * 1024 * 1024;

const RAW_ENTRY_FIXED_BYTES: usize = std::mem::size_of::<f64>();
const RAW_VALUE_BYTES: usize = std::mem::size_of::<f32>();
const BUCKET_ENTRY_FIXED_BYTES: usize = 2 * std::mem::size_of::<f64>() + std::mem::size_of::<u32>();
const BUCKET_VALUE_BYTES: usize = 3 * std::mem::size_of::<f32>();

/// A ring buffer that grows up to `limit` entries and then overwrites its oldest.
///
/// Growth is exact (`reserve_exact`) so that the allocation never exceeds the limit; that is
/// what makes the memory budget hold.
#[derive(Debug, Clone)]
struct Ring<T> {
    items: Vec<T>,
    head: usize,
    limit: usize,
}

impl<T: Copy> Ring<T> {
    fn new(limit: usize) -> Self {
        Ring {
            items: Vec::new(),
            head: 0,
            limit: limit.max(1),
        }
    }

    fn len(&self) -> usize {
        self.items.len()
    }

    fn push(&mut self, value: T) {
        if self.items.len() < self.limit {
            if self.items.len() == self.items.capacity() {
                let grow = self.items.len().max(64).min(self.limit - self.items.len());
                self.items.reserve_exact(grow);
            }
            self.items.push(value);
        } else {
            self.items[self.head] = value;
            self.head = (self.head + 1) % self.limit;
        }
    }

    /// The `i`-th oldest entry.
    fn get(&self, i: usize) -> T {
        let n = self.items.len();
        self.items[(self.head + i) % n]
    }

    fn bytes(&self) -> usize {
        self.items.capacity() * std::mem::size_of::<T>()
    }
}

/// One level: entry times, sample counts and per-channel statistics, column by column.
#[derive(Debug, Clone)]
struct Level {
    /// Time of the first raw sample of each entry.
    t_first: Ring<f64>,
    /// Time of the last raw sample of each entry (absent on the raw level, where it equals
    /// `t_first`).
    t_last: Option<Ring<f64>>,
    /// Raw samples per entry (absent on the raw level).
    count: Option<Ring<u32>>,
    /// Per channel: the raw value (raw level) or the bucket mean.
    mean: Vec<Ring<f32>>,
    /// Per channel bucket minimum and maximum (absent on the raw level).
    min: Vec<Ring<f32>>,
    max: Vec<Ring<f32>>,
}

impl Level {
    fn new(raw: bool, channels: usize, limit: usize) -> Level {
        Level {
            t_first: Ring::new(limit),
            t_last: (!raw).then(|| Ring::new(limit)),
            count: (!raw).then(|| Ring::new(limit)),
            mean: (0..channels).map(|_| Ring::new(limit)).collect(),
            min: if raw {
                Vec::new()
            } else {
                (0..channels).map(|_| Ring::new(limit)).collect()
            },
            max: if raw {
                Vec::new()
            } else {
                (0..channels).map(|_| Ring::new(limit)).collect()
            },
        }
    }

    fn len(&self) -> usize {
        self.t_first.len()
    }

    fn is_raw(&self) -> bool {
        self.t_last.is_none()
    }

    fn t_last(&self, i: usize) -> f64 {
        self.t_last
            .as_ref()
            .map_or_else(|| self.t_first.get(i), |t| t.get(i))
    }

    fn count(&self, i: usize) -> u32 {
        self.count.as_ref().map_or(1, |c| c.get(i))
    }

    /// Mean, min and max of channel `c` in entry `i`.
    fn stats(&self, c: usize, i: usize) -> (f32, f32, f32) {
        let mean = self.mean[c].get(i);
        if self.is_raw() {
            (mean, mean, mean)
        } else {
            (mean, self.min[c].get(i), self.max[c].get(i))
        }
    }

    /// Index of the first entry whose last sample is at or after `t`.
    fn first_ending_at_or_after(&self, t: f64) -> usize {
        let (mut lo, mut hi) = (0, self.len());
        while lo < hi {
            let mid = (lo + hi) / 2;
            if self.t_last(mid) < t {
                lo = mid + 1;
            } else {
                hi = mid;
            }
        }
        lo
    }

    /// Index one past the last entry whose first sample is at or before `t`.
    fn end_starting_at_or_before(&self, t: f64) -> usize {
        let (mut lo, mut hi) = (0, self.len());
        while lo < hi {
            let mid = (lo + hi) / 2;
            if self.t_first.get(mid) <= t {
                lo = mid + 1;
            } else {
                hi = mid;
            }
        }
        lo
    }

    fn bytes(&self) -> usize {
        self.t_first.bytes()
            + self.t_last.as_ref().map_or(0, Ring::bytes)
            + self.count.as_ref().map_or(0, Ring::bytes)
            + self.mean.iter().map(Ring::bytes).sum::<usize>()
            + self.min.iter().map(Ring::bytes).sum::<usize>()
            + self.max.iter().map(Ring::bytes).sum::<usize>()
    }
}

/// A bucket being filled from the level below.
#[derive(Debug, Clone)]
struct Partial {
    children: usize,
    samples: u32,
    t_first: f64,
    t_last: f64,
    sum: Vec<f64>,
    weight: Vec<f64>,
    min: Vec<f32>,
    max: Vec<f32>,
}

impl Partial {
    fn new(channels: usize) -> Partial {
        Partial {
            children: 0,
            samples: 0,
            t_first: f64::NAN,
            t_last: f64::NAN,
            sum: vec![0.0; channels],
            weight: vec![0.0; channels],
            min: vec![f32::INFINITY; channels],
            max: vec![f32::NEG_INFINITY; channels],
        }
    }

    fn clear(&mut self) {
        self.children = 0;
        self.samples = 0;
        self.t_first = f64::NAN;
        self.t_last = f64::NAN;
        self.sum.fill(0.0);
        self.weight.fill(0.0);
        self.min.fill(f32::INFINITY);
        self.max.fill(f32::NEG_INFINITY);
    }

    fn mean(&self, c: usize) -> f32 {
        if self.weight[c] > 0.0 {
            (self.sum[c] / self.weight[c]) as f32
        } else {
            f32::NAN
        }
    }

    fn min(&self, c: usize) -> f32 {
        if self.min[c].is_finite() {
            self.min[c]
        } else {
            f32::NAN
        }
    }

    fn max(&self, c: usize) -> f32 {
        if self.max[c].is_finite() {
            self.max[c]
        } else {
            f32::NAN
        }
    }
}

/// One channel of a [`Window`]: a point per bucket.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct WindowSeries {
    /// Bucket means (the raw value at full rate).
    pub mean: Vec<f32>,
    /// Bucket minima.
    pub min: Vec<f32>,
    /// Bucket maxima.
    pub max: Vec<f32>,
}

/// What [`History::window`] returns: shared times and one series per requested channel.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Window {
    /// Midpoint time of each point, s.
    pub time_s: Vec<f64>,
    /// Raw samples behind each point (1 at full rate).
    pub samples_per_point: Vec<u32>,
    /// One series per requested channel, in request order.
    pub series: Vec<WindowSeries>,
    /// The pyramid level the points came from (0 = full rate).
    pub level: usize,
}

impl Window {
    /// Points in the window.
    pub fn len(&self) -> usize {
        self.time_s.len()
    }

    /// True when the window holds no point.
    pub fn is_empty(&self) -> bool {
        self.time_s.is_empty()
    }
}

/// The history of every channel of a link (time excluded: it is the axis).
#[derive(Debug, Clone)]
pub struct History {
    config: HistoryConfig,
    channels: Vec<String>,
    levels: Vec<Level>,
    /// `partials[k]` fills the next bucket of level `k + 1`.
    partials: Vec<Partial>,
    samples: u64,
    newest_t: f64,
}

impl History {
    /// An empty history of `channels` (names as in the link's schema, without `time_s`).
    pub fn new(channels: Vec<String>, config: HistoryConfig) -> History {
        let n = channels.len();
        let levels_count = config.level_capacities.len() + 2;
        let levels = (0..levels_count)
            .map(|k| {
                let limit = if k == 0 {
                    config.raw_capacity
                } else {
                    config
                        .level_capacities
                        .get(k - 1)
                        .copied()
                        .unwrap_or(usize::MAX)
                };
                Level::new(k == 0, n, limit)
            })
            .collect();
        let partials = (1..levels_count).map(|_| Partial::new(n)).collect();
        History {
            config,
            channels,
            levels,
            partials,
            samples: 0,
            newest_t: f64::NAN,
        }
    }

    /// The channels, in storage order.
    pub fn channels(&self) -> &[String] {
        &self.channels
    }

    /// Index of a channel by name.
    pub fn channel_index(&self, name: &str) -> Option<usize> {
        self.channels.iter().position(|c| c == name)
    }

    /// Samples pushed so far.
    pub fn samples(&self) -> u64 {
        self.samples
    }

    /// Time of the newest sample, if any.
    pub fn newest_time_s(&self) -> Option<f64> {
        (self.samples > 0).then_some(self.newest_t)
    }

    /// Time of the oldest sample still represented, if any.
    pub fn oldest_time_s(&self) -> Option<f64> {
        self.levels
            .iter()
            .filter(|l| l.len() > 0)
            .map(|l| l.t_first.get(0))
            .reduce(f64::min)
    }

    /// The configuration.
    pub fn config(&self) -> &HistoryConfig {
        &self.config
    }

    /// Bytes allocated for samples and buckets.
    pub fn memory_bytes(&self) -> usize {
        self.levels.iter().map(Level::bytes).sum::<usize>()
            + self.partials.len() * self.channels.len() * 24
    }

    /// Appends one sample: `values` in channel order (extra values are ignored, missing ones
    /// count as not available). Samples must come in time order; an earlier time is clamped to
    /// the newest so the pyramid's binary searches stay valid.
    pub fn push(&mut self, time_s: f64, values: &[f64]) {
        // A NaN time compares as neither, and is clamped too.
        let in_order = time_s
            .partial_cmp(&self.newest_t)
            .is_some_and(|o| o.is_ge());
        let t = if self.samples > 0 && !in_order {
            self.newest_t
        } else {
            time_s
        };
        self.samples += 1;
        self.newest_t = t;
        let raw = &mut self.levels[0];
        raw.t_first.push(t);
        for (c, ring) in raw.mean.iter_mut().enumerate() {
            ring.push(values.get(c).map_or(f32::NAN, |v| *v as f32));
        }
        // Feed the raw sample into the first partial bucket, then carry completed buckets up.
        let partial = &mut self.partials[0];
        if partial.children == 0 {
            partial.t_first = t;
        }
        partial.t_last = t;
        partial.children += 1;
        partial.samples += 1;
        for c in 0..self.channels.len() {
            let v = values.get(c).copied().unwrap_or(f64::NAN);
            if v.is_finite() {
                partial.sum[c] += v;
                partial.weight[c] += 1.0;
                let v = v as f32;
                partial.min[c] = partial.min[c].min(v);
                partial.max[c] = partial.max[c].max(v);
            }
        }
        let mut k = 0;
        while k < self.partials.len() && self.partials[k].children >= self.config.factor {
            self.complete_partial(k);
            k += 1;
        }
    }

    /// Moves partial bucket `k` into level `k + 1` and feeds it to partial `k + 1`.
    fn complete_partial(&mut self, k: usize) {
        let (lower, upper) = self.partials.split_at_mut(k + 1);
        let done = &mut lower[k];
        let level = &mut self.levels[k + 1];
        level.t_first.push(done.t_first);
        if let Some(t) = level.t_last.as_mut() {
            t.push(done.t_last);
        }
        if let Some(c) = level.count.as_mut() {
            c.push(done.samples);
        }
        for c in 0..self.channels.len() {
            level.mean[c].push(done.mean(c));
            level.min[c].push(done.min(c));
            level.max[c].push(done.max(c));
        }
        if let Some(next) = upper.first_mut() {
            if next.children == 0 {
                next.t_first = done.t_first;
            }
            next.t_last = done.t_last;
            next.children += 1;
            next.samples += done.samples;
            for c in 0..self.channels.len() {
                if done.weight[c] > 0.0 {
                    next.sum[c] += done.sum[c];
                    next.weight[c] += done.weight[c];
                    next.min[c] = next.min[c].min(done.min[c]);
                    next.max[c] = next.max[c].max(done.max[c]);
                }
            }
        }
        done.clear();
    }

    /// Points of `channels` (indices) between `t0` and `t1`, at most `max_points` of them.
    ///
    /// Takes the finest level that still holds `t0` and has at most eight times `max_points`
    /// entries in the window, then merges neighbouring entries down to `max_points`. On a
    /// coarse level the bucket still being filled is added at the end, so the live edge is
    /// never missing.
    pub fn window(&self, channels: &[usize], t0: f64, t1: f64, max_points: usize) -> Window {
        let max_points = max_points.max(2);
        if self.samples == 0 || t1.partial_cmp(&t0).is_none_or(|o| o.is_lt()) {
            return Window {
                series: vec![WindowSeries::default(); channels.len()],
                ..Window::default()
            };
        }
        let mut chosen = self.levels.len() - 1;
        for (k, level) in self.levels.iter().enumerate() {
            if level.len() == 0 {
                continue;
            }
            let holds_start = level.t_first.get(0) <= t0 || k + 1 == self.levels.len() || {
                // A coarser level that reaches further back exists: only take this one if no
                // coarser level has older data either.
                let oldest_here = level.t_first.get(0);
                self.levels[k + 1..]
                    .iter()
                    .all(|l| l.len() == 0 || l.t_first.get(0) >= oldest_here)
            };
            let count = level
                .end_starting_at_or_before(t1)
                .saturating_sub(level.first_ending_at_or_after(t0));
            if holds_start && count <= max_points * 8 {
                chosen = k;
                break;
            }
        }
        self.window_from_level(chosen, channels, t0, t1, max_points)
    }

    fn window_from_level(
        &self,
        k: usize,
        channels: &[usize],
        t0: f64,
        t1: f64,
        max_points: usize,
    ) -> Window {
        let level = &self.levels[k];
        let start = level.first_ending_at_or_after(t0);
        let end = level.end_starting_at_or_before(t1);
        // The live edge: on a coarse level, the partial bucket below it holds the newest
        // samples not yet in any of its buckets (and the partials below that, newer still).
        let live_edge = k > 0 && self.partial_overlaps(k, t0, t1);
        let count = end.saturating_sub(start) + usize::from(live_edge);
        let group = count.div_ceil(max_points).max(1);
        let points = count.div_ceil(group);
        let mut out = Window {
            time_s: Vec::with_capacity(points),
            samples_per_point: Vec::with_capacity(points),
            series: channels
                .iter()
                .map(|_| WindowSeries {
                    mean: Vec::with_capacity(points),
                    min: Vec::with_capacity(points),
                    max: Vec::with_capacity(points),
                })
                .collect(),
            level: k,
        };
        let mut i = start;
        while i < end {
            let j = (i + group).min(end);
            let t_first = level.t_first.get(i);
            let t_last = level.t_last(j - 1);
            let mut samples = 0u32;
            for e in i..j {
                samples = samples.saturating_add(level.count(e));
            }
            out.time_s.push(0.5 * (t_first + t_last));
            out.samples_per_point.push(samples);
            for (s, &c) in channels.iter().enumerate() {
                let (mut sum, mut weight) = (0.0f64, 0.0f64);
                let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
                for e in i..j {
                    let (mean, min, max) = level.stats(c, e);
                    if mean.is_finite() {
                        let w = f64::from(level.count(e));
                        sum += f64::from(mean) * w;
                        weight += w;
                        lo = lo.min(min);
                        hi = hi.max(max);
                    }
                }
                let series = &mut out.series[s];
                if weight > 0.0 {
                    series.mean.push((sum / weight) as f32);
                    series.min.push(lo);
                    series.max.push(hi);
                } else {
                    series.mean.push(f32::NAN);
                    series.min.push(f32::NAN);
                    series.max.push(f32::NAN);
                }
            }
            i = j;
        }
        if live_edge {
            self.push_live_edge(k, channels, &mut out);
        }
        out
    }

    /// True when samples newer than level `k`'s last bucket fall inside `[t0, t1]`.
    fn partial_overlaps(&self, k: usize, t0: f64, t1: f64) -> bool {
        let first = (0..k)
            .rev()
            .map(|p| &self.partials[p])
            .filter(|p| p.children > 0)
            .map(|p| p.t_first)
            .reduce(f64::min);
        first.is_some_and(|t_first| t_first <= t1 && self.newest_t >= t0)
    }

    /// Merges the partial buckets below level `k` (everything newer than its last bucket)
    /// into one point at the end of `out`.
    fn push_live_edge(&self, k: usize, channels: &[usize], out: &mut Window) {
        let partials: Vec<&Partial> = (0..k)
            .map(|p| &self.partials[p])
            .filter(|p| p.children > 0)
            .collect();
        let t_first = partials
            .iter()
            .map(|p| p.t_first)
            .fold(f64::INFINITY, f64::min);
        let samples: u32 = partials.iter().map(|p| p.samples).sum();
        out.time_s.push(0.5 * (t_first + self.newest_t));
        out.samples_per_point.push(samples);
        for (s, &c) in channels.iter().enumerate() {
            let sum: f64 = partials.iter().map(|p| p.sum[c]).sum();
            let weight: f64 = partials.iter().map(|p| p.weight[c]).sum();
            let series = &mut out.series[s];
            if weight > 0.0 {
                series.mean.push((sum / weight) as f32);
                series.min.push(
                    partials
                        .iter()
                        .map(|p| p.min[c])
                        .fold(f32::INFINITY, f32::min),
                );
                series.max.push(
                    partials
                        .iter()
                        .map(|p| p.max[c])
                        .fold(f32::NEG_INFINITY, f32::max),
                );
            } else {
                series.mean.push(f32::NAN);
                series.min.push(f32::NAN);
                series.max.push(f32::NAN);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn small() -> HistoryConfig {
        HistoryConfig {
            raw_capacity: 100,
            factor: 4,
            level_capacities: vec![50, 50],
        }
    }

    #[test]
    fn recent_windows_are_full_rate_and_exact() {
        let mut h = History::new(vec!["a".into(), "b".into()], small());
        for i in 0..1000 {
            h.push(i as f64, &[i as f64, -(i as f64)]);
        }
        let w = h.window(&[0, 1], 950.0, 999.0, 100);
        assert_eq!(w.level, 0);
        assert_eq!(w.len(), 50);
        assert_eq!(w.time_s[0], 950.0);
        assert_eq!(w.series[0].mean[0], 950.0);
        assert_eq!(w.series[1].mean[49], -999.0);
    }

    #[test]
    fn old_windows_come_from_buckets_with_true_extremes() {
        let mut h = History::new(vec!["a".into()], small());
        for i in 0..10_000 {
            // A spike the decimation must not hide.
            let v = if i == 37 { 1000.0 } else { (i % 10) as f64 };
            h.push(i as f64, &[v]);
        }
        let w = h.window(&[0], 0.0, 9_999.0, 100);
        assert!(w.level >= 2, "level {}", w.level);
        assert!(w.len() <= 100 && w.len() >= 40, "{} points", w.len());
        let max = w.series[0].max.iter().copied().fold(f32::MIN, f32::max);
        assert_eq!(max, 1000.0, "the spike survives as a maximum");
        let total: u64 = w.samples_per_point.iter().map(|n| u64::from(*n)).sum();
        assert_eq!(total, 10_000, "every sample is behind exactly one point");
        let mean_of_means: f64 = w.series[0]
            .mean
            .iter()
            .zip(&w.samples_per_point)
            .map(|(m, n)| f64::from(*m) * f64::from(*n))
            .sum::<f64>()
            / 10_000.0;
        let exact = (0..10_000)
            .map(|i| if i == 37 { 1000.0 } else { (i % 10) as f64 })
            .sum::<f64>()
            / 10_000.0;
        assert!(
            (mean_of_means - exact).abs() < 1e-3,
            "{mean_of_means} vs {exact}"
        );
    }

    #[test]
    fn missing_values_do_not_poison_buckets() {
        let mut h = History::new(vec!["a".into()], small());
        for i in 0..64 {
            let v = if i % 2 == 0 { f64::NAN } else { 2.0 };
            h.push(i as f64, &[v]);
        }
        let w = h.window(&[0], 0.0, 63.0, 4);
        assert!(
            w.series[0].mean.iter().all(|m| *m == 2.0),
            "{:?}",
            w.series[0]
        );
    }

    #[test]
    fn memory_stays_within_the_budget() {
        let channels = 10;
        let budget = 4 * 1024 * 1024;
        let config = HistoryConfig::for_budget(channels, budget);
        let raw = config.raw_capacity;
        let mut h = History::new((0..channels).map(|c| format!("c{c}")).collect(), config);
        let row = vec![1.0; channels];
        for i in 0..(raw * 3) {
            h.push(i as f64 * 0.001, &row);
        }
        assert!(
            h.memory_bytes() <= budget,
            "{} > {budget}",
            h.memory_bytes()
        );
        assert_eq!(
            h.oldest_time_s(),
            Some(0.0),
            "the top level keeps the start"
        );
    }

    #[test]
    fn the_live_edge_is_drawn_from_coarse_levels() {
        let mut h = History::new(vec!["a".into()], small());
        for i in 0..1003 {
            h.push(i as f64, &[i as f64]);
        }
        let w = h.window(&[0], 0.0, 1002.0, 20);
        assert!(w.level > 0);
        let total: u64 = w.samples_per_point.iter().map(|n| u64::from(*n)).sum();
        assert_eq!(total, 1003, "the newest samples are part of the last point");
    }
}
