//! Operating programs: what the machine is told to do, block by block.
//!
//! A [`Block`] holds the spindle speed, the cut, the coolant and the X-axis activity for a span
//! of time. A scenario is a generator of blocks, so an endless program (the HMI's live machine)
//! costs no more memory than a short one. Programs are drawn from their own random stream, so
//! switching an effect off or changing the noise never changes what the machine does.

use std::collections::VecDeque;
use std::fmt;
use std::str::FromStr;

use rand::Rng;
use rand::SeedableRng;
use rand::rngs::StdRng;

use super::machine::MachineParams;

/// The scenarios the twin knows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ScenarioKind {
    /// Shift-start warm-up: friction-fingerprint moves, then spindle speed steps with the X
    /// axis traversing, no cutting.
    Warmup,
    /// A production day: roughing and finishing cuts, tool changes, short stops and a lunch
    /// break (the paper's Table 1/2 conditions).
    Production,
    /// Backlash test: reciprocating X moves growing from the minimum increment, at several feeds.
    BacklashTest,
    /// Design of experiments: a randomised sweep of speeds, cuts, feeds and coolant — the "big
    /// data database" the estimators are calibrated on.
    Doe,
}

impl ScenarioKind {
    /// Every scenario.
    pub const ALL: [ScenarioKind; 4] = [
        ScenarioKind::Warmup,
        ScenarioKind::Production,
        ScenarioKind::BacklashTest,
        ScenarioKind::Doe,
    ];

    /// The name used on the command line.
    pub fn name(self) -> &'static str {
        match self {
            ScenarioKind::Warmup => "warmup",
            ScenarioKind::Production => "production",
            ScenarioKind::BacklashTest => "backlash-test",
            ScenarioKind::Doe => "doe",
        }
    }

    /// The sample rate a scenario is usually recorded at, Hz: thermal scenarios at 1 Hz, the
    /// backlash test fast enough to resolve moves of a few micrometres.
    pub fn default_rate_hz(self) -> f64 {
        match self {
            ScenarioKind::BacklashTest => 500.0,
            _ => 1.0,
        }
    }
}

impl fmt::Display for ScenarioKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for ScenarioKind {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        ScenarioKind::ALL
            .into_iter()
            .find(|k| k.name() == s)
            .ok_or_else(|| {
                format!("unknown scenario `{s}` (known: warmup, production, backlash-test, doe)")
            })
    }
}

/// One programmed X move: go to `target_mm` at `feed_mm_per_min`, then wait `dwell_s`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Move {
    /// Target position, mm.
    pub target_mm: f64,
    /// Programmed feed, mm/min (capped at rapid).
    pub feed_mm_per_min: f64,
    /// Pause after arriving, s.
    pub dwell_s: f64,
    /// The tool is cutting during this move (feed force acts on the axis).
    pub cutting: bool,
}

/// What the X axis does during a block.
#[derive(Debug, Clone, PartialEq)]
pub enum XActivity {
    /// Stand at a position (holding any cutting force).
    Hold {
        /// Position, mm.
        at_mm: f64,
    },
    /// Traverse back and forth between two positions at a feed, pausing at each end.
    Traverse {
        /// One end, mm.
        from_mm: f64,
        /// The other end, mm.
        to_mm: f64,
        /// Feed, mm/min.
        feed_mm_per_min: f64,
        /// Pause at each end, s.
        dwell_s: f64,
    },
    /// Facing passes: feed from `from_mm` to `to_mm` while cutting, rapid back, repeat.
    Facing {
        /// Start of the cut, mm.
        from_mm: f64,
        /// End of the cut, mm.
        to_mm: f64,
    },
    /// An explicit list of moves, played once (the backlash test, fingerprint moves).
    Moves(Vec<Move>),
}

/// A span of the program.
#[derive(Debug, Clone, PartialEq)]
pub struct Block {
    /// How long the block lasts, s.
    pub duration_s: f64,
    /// Spindle speed command, rpm (0 = stopped).
    pub spindle_rpm: f64,
    /// Depth of cut, mm (0 = not cutting).
    pub depth_of_cut_mm: f64,
    /// Feed per revolution, mm.
    pub feed_per_rev_mm: f64,
    /// Coolant flowing.
    pub coolant: bool,
    /// The X axis.
    pub x: XActivity,
    /// What the block is, for metadata and event logs ("roughing", "lunch break", …).
    pub label: &'static str,
}

impl Block {
    fn idle(duration_s: f64, at_mm: f64, label: &'static str) -> Block {
        Block {
            duration_s,
            spindle_rpm: 0.0,
            depth_of_cut_mm: 0.0,
            feed_per_rev_mm: 0.0,
            coolant: false,
            x: XActivity::Hold { at_mm },
            label,
        }
    }
}

/// The backlash test program: reciprocating moves of growing amplitude from the minimum
/// increment, at several feeds. The same plan drives the twin and the NC program the operator
/// runs on a real machine, so both measure the same thing.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct BacklashTestPlan {
    /// Where the test runs, mm.
    pub centre_mm: f64,
    /// The controller's minimum increment, µm (the first amplitude).
    pub min_increment_um: f64,
    /// Largest amplitude, µm.
    pub max_amplitude_um: f64,
    /// Amplitude step up to `fine_until_um`, µm (then twice that).
    pub step_um: f64,
    /// Amplitude below which the fine step is used, µm.
    pub fine_until_um: f64,
    /// Feeds to test, mm/min.
    pub feeds_mm_per_min: Vec<f64>,
    /// Back-and-forth cycles per amplitude.
    pub cycles: usize,
    /// Pause after every move, s.
    pub dwell_s: f64,
}

impl Default for BacklashTestPlan {
    fn default() -> Self {
        BacklashTestPlan {
            centre_mm: 200.0,
            min_increment_um: 1.0,
            max_amplitude_um: 100.0,
            step_um: 1.0,
            fine_until_um: 30.0,
            feeds_mm_per_min: vec![20.0, 60.0, 200.0],
            cycles: 2,
            dwell_s: 0.15,
        }
    }
}

impl BacklashTestPlan {
    /// The amplitudes tested, µm, smallest first.
    pub fn amplitudes_um(&self) -> Vec<f64> {
        let mut amplitudes = Vec::new();
        let mut a = self.min_increment_um;
        while a <= self.max_amplitude_um + 1e-9 {
            amplitudes.push(a);
            a += if a < self.fine_until_um {
                self.step_um
            } else {
                2.0 * self.step_um
            };
        }
        amplitudes
    }

    /// The moves, in order. A move first takes up the lash in the positive direction (so every
    /// test starts from a known contact side), then for each feed and amplitude goes +A and −A
    /// `cycles` times.
    pub fn moves(&self) -> Vec<Move> {
        let mut moves = vec![
            Move {
                target_mm: self.centre_mm - 0.5,
                feed_mm_per_min: 1000.0,
                dwell_s: 0.3,
                cutting: false,
            },
            Move {
                target_mm: self.centre_mm,
                feed_mm_per_min: 200.0,
                dwell_s: 0.5,
                cutting: false,
            },
        ];
        for &feed in &self.feeds_mm_per_min {
            for amplitude in self.amplitudes_um() {
                for _ in 0..self.cycles {
                    for target in [self.centre_mm + amplitude / 1000.0, self.centre_mm] {
                        moves.push(Move {
                            target_mm: target,
                            feed_mm_per_min: feed,
                            dwell_s: self.dwell_s,
                            cutting: false,
                        });
                    }
                }
            }
        }
        moves
    }

    /// Machine time of the whole test, s, for a given acceleration (mm/s²).
    pub fn duration_s(&self, acceleration_mm_per_s2: f64) -> f64 {
        let mut position = self.centre_mm;
        self.moves()
            .iter()
            .map(|m| {
                let d = (m.target_mm - position).abs();
                position = m.target_mm;
                TrapezoidMove::new(0.0, d, m.feed_mm_per_min / 60.0, acceleration_mm_per_s2)
                    .duration_s()
                    + m.dwell_s
            })
            .sum()
    }
}

/// A trapezoidal (or triangular) velocity profile over a distance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrapezoidMove {
    start_mm: f64,
    direction: f64,
    peak_mm_per_s: f64,
    acceleration: f64,
    ramp_s: f64,
    cruise_s: f64,
}

impl TrapezoidMove {
    /// A move from `start_mm` by `distance_mm` (signed) at up to `speed_mm_per_s`.
    pub fn new(start_mm: f64, distance_mm: f64, speed_mm_per_s: f64, acceleration: f64) -> Self {
        let d = distance_mm.abs();
        let v = speed_mm_per_s.max(1e-9);
        let (peak, ramp_s, cruise_s) = if d * acceleration < v * v {
            let ramp = (d / acceleration).sqrt();
            (acceleration * ramp, ramp, 0.0)
        } else {
            (v, v / acceleration, (d - v * v / acceleration) / v)
        };
        TrapezoidMove {
            start_mm,
            direction: if distance_mm < 0.0 { -1.0 } else { 1.0 },
            peak_mm_per_s: peak,
            acceleration,
            ramp_s,
            cruise_s,
        }
    }

    /// Time from start to arrival, s.
    pub fn duration_s(&self) -> f64 {
        2.0 * self.ramp_s + self.cruise_s
    }

    /// Position (mm), velocity (mm/s) and acceleration (mm/s²) `t` seconds after the start.
    pub fn at(&self, t: f64) -> (f64, f64, f64) {
        let (a, v, ramp, cruise) = (
            self.acceleration,
            self.peak_mm_per_s,
            self.ramp_s,
            self.cruise_s,
        );
        let (s, ds, dds) = if t <= 0.0 {
            (0.0, 0.0, 0.0)
        } else if t < ramp {
            (0.5 * a * t * t, a * t, a)
        } else if t < ramp + cruise {
            (0.5 * a * ramp * ramp + v * (t - ramp), v, 0.0)
        } else if t < 2.0 * ramp + cruise {
            let td = t - ramp - cruise;
            (
                0.5 * a * ramp * ramp + v * cruise + v * td - 0.5 * a * td * td,
                v - a * td,
                -a,
            )
        } else {
            (a * ramp * ramp + v * cruise, 0.0, 0.0)
        };
        (
            self.start_mm + self.direction * s,
            self.direction * ds,
            self.direction * dds,
        )
    }
}

/// Generates the blocks of a scenario.
#[derive(Debug)]
pub struct ScenarioGenerator {
    kind: ScenarioKind,
    rng: StdRng,
    /// Program time already generated, s.
    generated_s: f64,
    /// Stop after this much program time; `None` = endless.
    limit_s: Option<f64>,
    queue: VecDeque<Block>,
    stroke_mm: f64,
    rapid_mm_per_min: f64,
    max_rpm: f64,
    day: u32,
}

impl ScenarioGenerator {
    /// A generator for `kind`, drawing from `seed`, for `hours` of program time (or endless).
    pub fn new(kind: ScenarioKind, machine: &MachineParams, seed: u64, hours: Option<f64>) -> Self {
        ScenarioGenerator {
            kind,
            // A fixed offset keeps the program stream apart from the noise streams.
            rng: StdRng::seed_from_u64(seed ^ 0x005E_ED0F_9206_7A11),
            generated_s: 0.0,
            limit_s: hours.map(|h| h * 3600.0),
            queue: VecDeque::new(),
            stroke_mm: machine.x_axis.stroke_mm,
            rapid_mm_per_min: machine.x_axis.rapid_mm_per_min,
            max_rpm: machine.spindle.motor.max_speed_rpm,
            day: 0,
        }
    }

    /// The next block, or `None` when the program is over.
    pub fn next_block(&mut self) -> Option<Block> {
        if let Some(limit) = self.limit_s
            && self.generated_s >= limit - 1e-9
        {
            return None;
        }
        if self.queue.is_empty() {
            self.refill();
        }
        let mut block = self.queue.pop_front()?;
        if let Some(limit) = self.limit_s {
            block.duration_s = block.duration_s.min(limit - self.generated_s);
        }
        self.generated_s += block.duration_s;
        Some(block)
    }

    fn refill(&mut self) {
        let blocks = match self.kind {
            ScenarioKind::Warmup => self.warmup(),
            ScenarioKind::Production => self.production_day(),
            // The backlash test is played once.
            ScenarioKind::BacklashTest if self.day > 0 => Vec::new(),
            ScenarioKind::BacklashTest => self.backlash_test(),
            ScenarioKind::Doe => self.doe_blocks(),
        };
        self.day += 1;
        self.queue.extend(blocks);
    }

    /// The friction-fingerprint moves: full-stroke constant-speed passes at several feeds in
    /// both directions, so Coulomb and viscous friction and inertia can be separated.
    pub fn fingerprint_moves(stroke_mm: f64) -> Vec<Move> {
        let (low, high) = (0.1 * stroke_mm, 0.9 * stroke_mm);
        let mut moves = vec![Move {
            target_mm: low,
            feed_mm_per_min: 5000.0,
            dwell_s: 1.0,
            cutting: false,
        }];
        for feed in [500.0, 1000.0, 2000.0, 5000.0, 10_000.0, 15_000.0] {
            for target in [high, low] {
                moves.push(Move {
                    target_mm: target,
                    feed_mm_per_min: feed,
                    dwell_s: 1.0,
                    cutting: false,
                });
            }
        }
        moves
    }

    fn warmup(&mut self) -> Vec<Block> {
        let stroke = self.stroke_mm;
        let mut blocks = vec![Block {
            duration_s: 120.0,
            x: XActivity::Moves(Self::fingerprint_moves(stroke)),
            ..Block::idle(120.0, 0.1 * stroke, "friction fingerprint")
        }];
        let steps = [0.15, 0.3, 0.5, 0.7, 0.9];
        for (i, fraction) in steps.iter().enumerate() {
            blocks.push(Block {
                duration_s: 480.0,
                spindle_rpm: (fraction * self.max_rpm).round(),
                depth_of_cut_mm: 0.0,
                feed_per_rev_mm: 0.0,
                coolant: false,
                x: XActivity::Traverse {
                    from_mm: 0.05 * stroke,
                    to_mm: 0.95 * stroke,
                    feed_mm_per_min: 3000.0 + 2000.0 * i as f64,
                    dwell_s: 1.0,
                },
                label: "warm-up step",
            });
        }
        blocks
    }

    fn production_day(&mut self) -> Vec<Block> {
        let stroke = self.stroke_mm;
        let rng = &mut self.rng;
        let mut blocks = Vec::new();
        if self.day > 0 {
            // Overnight: the machine stands until the next shift, 07:00.
            blocks.push(Block::idle(14.0 * 3600.0, 0.5 * stroke, "overnight"));
        }
        // Short spindle warm-up at shift start.
        blocks.push(Block {
            duration_s: 900.0,
            spindle_rpm: 1500.0,
            depth_of_cut_mm: 0.0,
            feed_per_rev_mm: 0.0,
            coolant: false,
            x: XActivity::Traverse {
                from_mm: 0.1 * stroke,
                to_mm: 0.9 * stroke,
                feed_mm_per_min: 5000.0,
                dwell_s: 1.0,
            },
            label: "warm-up",
        });
        // 07:15–12:00, 13:00–17:00 with a short stop every one to two hours.
        for (start_h, end_h) in [(7.25, 12.0), (13.0, 17.0)] {
            let mut t = start_h * 3600.0;
            let mut next_stop = t + rng.random_range(3600.0..7200.0);
            while t < end_h * 3600.0 {
                if t >= next_stop {
                    let stop = rng.random_range(300.0..900.0);
                    blocks.push(Block::idle(stop, 0.5 * stroke, "short stop"));
                    t += stop;
                    next_stop = t + rng.random_range(3600.0..7200.0);
                    continue;
                }
                for block in Self::part_cycle(rng, stroke, self.max_rpm) {
                    t += block.duration_s;
                    blocks.push(block);
                }
            }
            if start_h < 12.0 {
                let overrun = t - end_h * 3600.0;
                blocks.push(Block::idle(
                    3600.0 - overrun.max(0.0),
                    0.5 * stroke,
                    "lunch break",
                ));
            }
        }
        blocks
    }

    /// One part: load, roughing passes, a tool change, finishing, unload.
    fn part_cycle(rng: &mut StdRng, stroke: f64, max_rpm: f64) -> Vec<Block> {
        let x0 = rng.random_range(0.2 * stroke..0.7 * stroke);
        let face = rng.random_range(25.0..60.0);
        let rough_rpm = rng.random_range(1100.0..2000.0_f64).round();
        let finish_rpm = rng.random_range(2400.0..0.92 * max_rpm).round();
        let rough_depth = (rng.random_range(1.0..4.0_f64) * 10.0).round() / 10.0;
        vec![
            Block::idle(rng.random_range(40.0..90.0), x0, "part change"),
            Block {
                duration_s: rng.random_range(180.0..420.0),
                spindle_rpm: rough_rpm,
                depth_of_cut_mm: rough_depth,
                feed_per_rev_mm: rng.random_range(0.2..0.35),
                coolant: true,
                x: XActivity::Facing {
                    from_mm: x0 + face,
                    to_mm: x0,
                },
                label: "roughing",
            },
            Block {
                duration_s: rng.random_range(10.0..25.0),
                // The turret indexes at the home position, far from the chuck.
                x: XActivity::Hold {
                    at_mm: 0.95 * stroke,
                },
                ..Block::idle(0.0, 0.0, "tool change")
            },
            // Turn-mill: the spindle indexes (C axis) while X contours a milled feature.
            Block {
                duration_s: rng.random_range(120.0..360.0),
                x: XActivity::Traverse {
                    from_mm: x0,
                    to_mm: (x0 + rng.random_range(60.0..160.0)).min(stroke),
                    feed_mm_per_min: rng.random_range(3000.0..12000.0),
                    dwell_s: 0.2,
                },
                ..Block::idle(0.0, 0.0, "milling")
            },
            Block {
                duration_s: rng.random_range(120.0..300.0),
                spindle_rpm: finish_rpm,
                depth_of_cut_mm: rng.random_range(0.2..0.6),
                feed_per_rev_mm: rng.random_range(0.08..0.15),
                coolant: true,
                x: XActivity::Facing {
                    from_mm: x0 + face,
                    to_mm: x0,
                },
                label: "finishing",
            },
        ]
    }

    fn backlash_test(&mut self) -> Vec<Block> {
        let plan = BacklashTestPlan {
            centre_mm: 0.5 * self.stroke_mm,
            ..BacklashTestPlan::default()
        };
        // The duration is set by the moves; the block ends when they have been played.
        vec![Block {
            duration_s: f64::INFINITY,
            x: XActivity::Moves(plan.moves()),
            ..Block::idle(0.0, plan.centre_mm, "backlash test")
        }]
    }

    fn doe_blocks(&mut self) -> Vec<Block> {
        let stroke = self.stroke_mm;
        let rapid = self.rapid_mm_per_min;
        let max_rpm = self.max_rpm;
        let rng = &mut self.rng;
        (0..24)
            .map(|_| {
                // Log-uniform from 10 minutes to 2 hours, so the database holds both quick
                // changes and slow structural heating and cooling.
                let duration_s = 600.0 * rng.random_range(0.0..(12.0_f64).ln()).exp();
                // A quarter of the blocks rest, so cooling curves are in the database too.
                if rng.random_bool(0.25) {
                    return Block::idle(duration_s, rng.random_range(0.0..stroke), "rest");
                }
                let spindle_rpm = (rng.random_range(0.0..1.0_f64).sqrt() * max_rpm).round();
                let cutting = spindle_rpm > 300.0 && rng.random_bool(0.5);
                let from = rng.random_range(0.0..0.5 * stroke);
                let to = rng.random_range(from + 20.0..stroke);
                let x = if cutting {
                    XActivity::Facing {
                        from_mm: to.min(from + 80.0),
                        to_mm: from,
                    }
                } else {
                    XActivity::Traverse {
                        from_mm: from,
                        to_mm: to,
                        feed_mm_per_min: rng.random_range(200.0..rapid),
                        dwell_s: rng.random_range(0.2..5.0),
                    }
                };
                Block {
                    duration_s,
                    spindle_rpm,
                    depth_of_cut_mm: if cutting {
                        rng.random_range(0.5..4.0)
                    } else {
                        0.0
                    },
                    feed_per_rev_mm: if cutting {
                        rng.random_range(0.1..0.35)
                    } else {
                        0.0
                    },
                    coolant: rng.random_bool(0.5),
                    x,
                    label: if cutting { "doe cut" } else { "doe run" },
                }
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trapezoid_reaches_its_target_with_zero_speed() {
        for (d, v) in [(100.0, 50.0), (-0.001, 50.0), (0.05, 0.33)] {
            let m = TrapezoidMove::new(10.0, d, v, 2000.0);
            let (p, vel, _) = m.at(m.duration_s() + 1e-9);
            assert!((p - (10.0 + d)).abs() < 1e-9, "{d}: {p}");
            assert_eq!(vel, 0.0);
            let (_, vmid, _) = m.at(m.duration_s() / 2.0);
            assert!(vmid.abs() <= v + 1e-9 && vmid * d > 0.0);
        }
    }

    #[test]
    fn backlash_test_takes_under_ten_minutes_of_machine_time() {
        let plan = BacklashTestPlan::default();
        let seconds = plan.duration_s(MachineParams::default().x_axis.acceleration_mm_per_s2);
        assert!(seconds < 600.0, "{seconds} s");
        let amplitudes = plan.amplitudes_um();
        assert_eq!(amplitudes[0], 1.0);
        assert!(*amplitudes.last().unwrap() <= 100.0);
    }

    #[test]
    fn production_day_has_a_lunch_break_and_respects_the_hour_limit() {
        let machine = MachineParams::default();
        let mut generator =
            ScenarioGenerator::new(ScenarioKind::Production, &machine, 3, Some(10.0));
        let mut total = 0.0;
        let mut labels = Vec::new();
        while let Some(block) = generator.next_block() {
            total += block.duration_s;
            labels.push(block.label);
        }
        assert!((total - 36_000.0).abs() < 1e-6, "{total}");
        assert!(labels.contains(&"lunch break") && labels.contains(&"roughing"));
    }

    #[test]
    fn same_seed_same_program() {
        let machine = MachineParams::default();
        let blocks = |seed| {
            let mut g = ScenarioGenerator::new(ScenarioKind::Doe, &machine, seed, Some(5.0));
            std::iter::from_fn(move || g.next_block()).collect::<Vec<_>>()
        };
        assert_eq!(blocks(1), blocks(1));
        assert_ne!(blocks(1), blocks(2));
    }
}
