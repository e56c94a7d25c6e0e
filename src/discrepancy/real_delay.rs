//! A signal delay found by reading the real recording later, where the simulation is exported
//! too coarsely to be moved.
//!
//! A delay is otherwise a correction like any other: the simulated target moved later, its
//! share fitted ([`super::library`]). A simulation exported every few seconds of a torque that
//! reverses every few seconds cannot be moved: read between its instants it is a line across
//! the very changes a delay would move ([`super::library::TooCoarse`]). The real recording is
//! finer, and it can: a measurement that trails by `d` reads at `t + d` what the simulation
//! holds at `t`. So each delay is tried by comparing the real target `d` later with the
//! simulation at its own instants. The comparison's coefficient is fixed at one (the later
//! reading is the simulated value, nothing scaled): a fitted coefficient on the real target's
//! own changes would let its noise fit itself, a fixed one cannot gain from noise, and where
//! the simulation's changes are the target's own and on time, reading the target later only
//! moves them to the wrong instants. What it is not weighed against is another physics that
//! also makes the measurement trail (a sensor's first-order filter of a second or more would
//! read as a transport delay of about that length); a delay of less than one sample of the
//! real recording is not looked for.

use super::Options;
use super::align::Aligned;
use super::cv::Blocks;
use crate::fit::autocorrelation::{mean_above_zero, white_noise_from_differences};
use crate::parallel::parallel_map;

/// The longest delay tried: a tenth of the recording, at most this, s (as the simulation's
/// own delays).
const LONGEST_DELAY_S: f64 = 600.0;

/// Steps of a sample in which the best whole delay is refined: twentieths.
const STEPS_PER_SAMPLE: i64 = 20;

/// A delay of the real target behind the simulation, found on the real recording's samples.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RealDelay {
    /// How many of the real recording's samples later the real target matches the
    /// simulation (negative: earlier), to a twentieth of a sample.
    pub samples: f64,
    /// The same in seconds (the real recording's median step times `samples`).
    pub delay_s: f64,
    /// The held-out gain (each fold's delay chosen on the other folds) over the held-out
    /// error at no delay.
    pub relative_gain: f64,
    /// One-sided p-value of the paired comparison of the held-out blocks' errors with and
    /// without the delay (over the blocks' effective number, as neighbouring blocks share
    /// correlated noise).
    pub p_value: f64,
}

/// Per block: rows compared, and the sum and sum of squares of the later real target less the
/// simulation on them. Each square carries back the white noise that reading between two
/// samples averages away, so that a delay between samples is not preferred for that alone.
#[derive(Debug, Clone)]
struct BlockSums {
    count: Vec<f64>,
    sum: Vec<f64>,
    squares: Vec<f64>,
}

impl BlockSums {
    fn of(
        aligned: &Aligned<'_>,
        target: &str,
        blocks: &Blocks,
        noise_variance: f64,
        steps: i64,
    ) -> BlockSums {
        let samples = steps as f64 / STEPS_PER_SAMPLE as f64;
        // On the plain line between two samples: across a reversal that reading depends on
        // how far between them the delay falls, which a placed one hardly does
        // (`Aligned::place_later`); the analysis then reads the delay found, placed.
        let later = aligned
            .real_target_later(target, samples, false)
            .unwrap_or_default();
        let mut sums = BlockSums {
            count: vec![0.0; blocks.len()],
            sum: vec![0.0; blocks.len()],
            squares: vec![0.0; blocks.len()],
        };
        for (b, range) in blocks.ranges.iter().enumerate() {
            for row in range.clone() {
                let Some(Some(real)) = later.get(row) else {
                    continue;
                };
                let r = real.value - aligned.sim_target[row];
                if r.is_finite() {
                    sums.count[b] += 1.0;
                    sums.sum[b] += r;
                    sums.squares[b] += r * r + real.averaged * noise_variance;
                }
            }
        }
        sums
    }

    /// Mean and mean square over the blocks `take` admits.
    fn moments(&self, take: impl Fn(usize) -> bool) -> Option<(f64, f64)> {
        let (mut n, mut s, mut q) = (0.0, 0.0, 0.0);
        for b in (0..self.count.len()).filter(|&b| take(b)) {
            n += self.count[b];
            s += self.sum[b];
            q += self.squares[b];
        }
        (n > 0.0).then(|| (s / n, q / n))
    }

    /// Mean squared error about its own mean over the blocks `take` admits.
    fn spread(&self, take: impl Fn(usize) -> bool) -> Option<f64> {
        self.moments(take).map(|(m, q)| (q - m * m).max(0.0))
    }

    /// Block `b`'s mean squared error about `offset`.
    fn block_error(&self, b: usize, offset: f64) -> Option<f64> {
        let n = self.count[b];
        (n > 0.0).then(|| (self.squares[b] - 2.0 * offset * self.sum[b]) / n + offset * offset)
    }
}

/// Block sums by delay (in [`STEPS_PER_SAMPLE`]ths of a sample), built as they are asked for.
struct Tried<'a> {
    aligned: &'a Aligned<'a>,
    target: &'a str,
    blocks: &'a Blocks,
    noise_variance: f64,
    sums: Vec<(i64, BlockSums)>,
}

impl Tried<'_> {
    fn get(&mut self, steps: i64) -> &BlockSums {
        let at = match self.sums.iter().position(|(s, _)| *s == steps) {
            Some(at) => at,
            None => {
                let sums = BlockSums::of(
                    self.aligned,
                    self.target,
                    self.blocks,
                    self.noise_variance,
                    steps,
                );
                self.sums.push((steps, sums));
                self.sums.len() - 1
            }
        };
        &self.sums[at].1
    }

    /// The least error over the blocks `take` admits among `candidates` (in steps), and
    /// where.
    fn least(
        &mut self,
        candidates: impl Iterator<Item = i64>,
        take: &impl Fn(usize) -> bool,
    ) -> Option<(i64, f64)> {
        let mut best: Option<(i64, f64)> = None;
        for steps in candidates {
            if let Some(e) = self.get(steps).spread(take)
                && best.is_none_or(|(_, b)| e < b)
            {
                best = Some((steps, e));
            }
        }
        best
    }

    /// The delay whose error over the blocks `take` admits is least: among `grid` (whole
    /// samples), then every whole sample between its neighbours there, then, when that is
    /// not zero, every step within a sample of it. Whether there is a delay at all is decided
    /// on whole samples, read as the rows are read at no delay: between two samples the rows
    /// where a speed steps are read on the plain line ([`Aligned::real_target_later`]), and
    /// a fraction of a sample fitted those rows better than their reading as recorded (a torque
    /// with its Coulomb friction left out, 0.1 s "late").
    fn best(&mut self, grid: &[isize], take: &impl Fn(usize) -> bool) -> i64 {
        let per = STEPS_PER_SAMPLE;
        let whole = |s: isize| s as i64 * per;
        let Some((at, _)) = self.least(grid.iter().map(|&s| whole(s)), take) else {
            return 0;
        };
        let k = grid.partition_point(|&s| whole(s) < at);
        let low = if k > 0 { grid[k - 1] + 1 } else { grid[k] };
        let high = grid.get(k + 1).map_or(grid[k], |&next| next - 1);
        let at = self
            .least((low..=high).map(whole), take)
            .map_or(at, |(s, _)| s);
        if at == 0 {
            return 0;
        }
        self.least(at - per + 1..at + per, take)
            .map_or(at, |(s, _)| s)
    }
}

/// The delays tried, in order: [`super::series::delay_samples`] up to `reach` samples, each
/// way, and none.
fn delay_grid(reach: isize) -> Vec<isize> {
    let ahead: Vec<isize> = super::series::delay_samples()
        .map(|s| s as isize)
        .take_while(|&s| s <= reach)
        .collect();
    let mut grid: Vec<isize> = ahead.iter().rev().map(|s| -s).collect();
    grid.push(0);
    grid.extend(ahead);
    grid
}

/// The real target's delay behind the simulation, read on the real recording's own samples,
/// when one predicts the held-out blocks materially (at least the options' smallest relative
/// gain) and significantly (the options' alpha) better than none. Each fold's delay is chosen
/// on the other folds; the delay returned is the one all rows choose.
pub fn search(aligned: &Aligned<'_>, target: &str, options: &Options) -> Option<RealDelay> {
    let step = aligned.real_step_s().filter(|s| *s > 0.0)?;
    let (first, last) = (aligned.time.first()?, aligned.time.last()?);
    let longest = (0.1 * (last - first)).min(LONGEST_DELAY_S);
    let reach = (longest / step).floor() as isize;
    if reach < 1 {
        return None;
    }
    let blocks = Blocks::new(aligned.len(), options.folds, options.blocks_per_fold);
    let noise_variance = white_noise_from_differences(aligned.real_samples(target)?).powi(2);
    let grid = delay_grid(reach);
    let built = parallel_map(&grid, |&s| {
        let steps = s as i64 * STEPS_PER_SAMPLE;
        (
            steps,
            BlockSums::of(aligned, target, &blocks, noise_variance, steps),
        )
    });
    let mut tried = Tried {
        aligned,
        target,
        blocks: &blocks,
        noise_variance,
        sums: built,
    };
    let everywhere = tried.best(&grid, &|_| true);
    if everywhere == 0 {
        return None;
    }
    let mut with = Vec::new();
    let mut without = Vec::new();
    for fold in &blocks.folds {
        let training = |b: usize| !fold.excluded.contains(&b);
        let chosen = tried.best(&grid, &training);
        let offset_of =
            |tried: &mut Tried<'_>, s: i64| tried.get(s).moments(training).map_or(0.0, |(m, _)| m);
        let (chosen_offset, none_offset) =
            (offset_of(&mut tried, chosen), offset_of(&mut tried, 0));
        for b in fold.test.clone() {
            let later = tried.get(chosen).block_error(b, chosen_offset);
            let recorded = tried.get(0).block_error(b, none_offset);
            if let (Some(later), Some(recorded)) = (later, recorded) {
                // Both weighed by the rows the later reading compares.
                let rows = tried.get(chosen).count[b];
                with.push(later * rows);
                without.push(recorded * rows);
            }
        }
    }
    let before: f64 = without.iter().sum();
    let gain = before - with.iter().sum::<f64>();
    let relative_gain = if before > 0.0 { gain / before } else { 0.0 };
    let p_value = one_sided_paired_p(&without, &with);
    let samples = everywhere as f64 / STEPS_PER_SAMPLE as f64;
    (relative_gain >= options.min_relative_gain && p_value <= options.alpha).then_some(RealDelay {
        samples,
        delay_s: samples * step,
        relative_gain,
        p_value,
    })
}

/// One-sided p-value that `before` exceeds `after`, paired: Student's t of the differences
/// over their effective number ([`mean_above_zero`]); 0 for differences all equal and
/// positive, 1 where there are too few to tell.
fn one_sided_paired_p(before: &[f64], after: &[f64]) -> f64 {
    let d: Vec<f64> = before.iter().zip(after).map(|(b, a)| b - a).collect();
    if d.len() < 2 {
        return 1.0;
    }
    if d.windows(2).all(|w| w[0] == w[1]) {
        return if d[0] > 0.0 { 0.0 } else { 1.0 };
    }
    let p = mean_above_zero(&d).p_value;
    if p.is_finite() { p } else { 1.0 }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::signal::Recording;
    use proptest::prelude::*;
    use rand::{Rng, SeedableRng, rngs::StdRng};
    use rand_distr::{Distribution, Normal};

    /// An hour of a feed axis on a 0.5 s grid: reversals every 3–8 s at 100–400 rpm, a cut's
    /// load changing every 30–120 s; the torque is Coulomb + viscous + load. The simulation
    /// (noise-free) every 5 s; the real recording every second, its torque `shift` grid steps
    /// late (early when negative) with 0.02 N·m of white noise and, `correlated`, as much
    /// again correlated over five minutes.
    fn axis_pair(seed: u64, shift: i64, correlated: bool) -> (Recording, Recording) {
        let mut rng = StdRng::seed_from_u64(seed);
        let noise = Normal::new(0.0, 0.02).expect("a positive σ");
        let steps = 7200;
        let (mut speed, mut torque) = (Vec::new(), Vec::new());
        let (mut direction, mut left, mut rpm) = (1.0, 0, 0.0);
        let (mut load, mut load_left) = (0.0, 0);
        for _ in 0..steps {
            if left == 0 {
                direction = -direction;
                left = rng.random_range(6..16);
                rpm = rng.random_range(100.0..400.0);
            }
            if load_left == 0 {
                load = rng.random_range(0.0..0.5);
                load_left = rng.random_range(60..240);
            }
            left -= 1;
            load_left -= 1;
            let v: f64 = direction * rpm;
            speed.push(v);
            torque.push(0.2 * v.signum() + 0.001 * v + load * v.signum());
        }
        let header = || {
            ["time_s", "X.speed_rpm", "X.torque_Nm"]
                .map(String::from)
                .to_vec()
        };
        let mut sim = Recording::new("sim", header()).expect("a valid header");
        let mut real = Recording::new("real", header()).expect("a valid header");
        let keep = (-1.0_f64 / 300.0).exp();
        let mut slow = 0.0;
        for k in 0..steps {
            let t = k as f64 * 0.5;
            if k % 10 == 0 {
                sim.push_row(&[t, speed[k], torque[k]])
                    .expect("a valid row");
            }
            if k % 2 == 0 {
                if correlated {
                    slow = keep * slow + (1.0 - keep * keep).sqrt() * noise.sample(&mut rng);
                }
                let at = (k as i64 - shift).clamp(0, steps as i64 - 1) as usize;
                let late = torque[at] + slow;
                real.push_row(&[t, speed[k], late + noise.sample(&mut rng)])
                    .expect("a valid row");
            }
        }
        (sim, real)
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        /// On a torque the simulation's 5 s export cannot hold, a delay of one real sample or
        /// more, whole or not (1–20 s, the measurement late or early), is found within half a
        /// sample, and none is found where there is none, under white noise or correlated. (Less than a sample is not looked for: whether there is a delay is
        /// decided on whole samples.)
        #[test]
        fn a_delay_is_found_where_there_is_one_and_only_there(
            seed in 0_u64..1_000_000,
            shift in prop::sample::select(vec![0_i64, 0, 0, 0, 2, 3, 7, 15, 40, -2, -9, -30]),
            correlated in any::<bool>(),
        ) {
            let (sim, real) = axis_pair(seed, shift, correlated);
            let aligned = Aligned::new(&sim, &real, "X.torque_Nm").expect("aligned");
            prop_assert!(aligned.on_simulation_grid);
            let found = search(&aligned, "X.torque_Nm", &Options::default());
            if shift == 0 {
                prop_assert!(found.is_none(), "{found:?}");
            } else {
                let found = found.expect("a delay");
                let truth = shift as f64 * 0.5;
                prop_assert!((found.delay_s - truth).abs() <= 0.5, "{found:?} against {truth} s");
                prop_assert!(found.relative_gain > 0.5, "{found:?}");
            }
        }
    }

    #[test]
    fn the_grid_takes_every_sample_then_grows_by_a_tenth_both_ways() {
        let grid = delay_grid(80);
        assert_eq!(grid.len(), 2 * (60 + 3) + 1, "{grid:?}");
        assert_eq!(&grid[grid.len() - 4..], &[60, 66, 73, 80]);
        assert_eq!(grid[0], -80);
        assert!(grid.windows(2).all(|w| w[0] < w[1]));
        assert_eq!(delay_grid(0), vec![0]);
    }

    #[test]
    fn the_paired_test_is_one_sided() {
        let before = [5.0, 6.0, 5.5, 6.2, 5.9, 6.1];
        let after = [1.0, 1.1, 0.9, 1.2, 1.0, 1.05];
        assert!(one_sided_paired_p(&before, &after) < 1e-4);
        assert!(one_sided_paired_p(&after, &before) > 0.999);
        assert_eq!(one_sided_paired_p(&[1.0], &[0.0]), 1.0);
        assert_eq!(one_sided_paired_p(&[1.0, 1.0], &[1.0, 1.0]), 1.0);
    }
}
