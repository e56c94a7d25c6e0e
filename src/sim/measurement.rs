//! What instruments add to the true state: noise (white plus optional AR(1)-correlated), a
//! transport delay, and an offset with a slow drift of the reference instruments.

use std::collections::VecDeque;

use rand::SeedableRng;
use rand::rngs::StdRng;
use rand_distr::{Distribution, StandardNormal};

/// How one output column is measured.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ColumnMeasurement {
    /// Noise level (1σ) in the column's unit; 0 for exact values (time, commands).
    pub noise_sigma: f64,
    /// Subject to the transport delay.
    pub delayed: bool,
    /// Subject to the reference instruments' offset and drift.
    pub drifts: bool,
    /// Never below zero (magnitudes such as an rms current).
    pub non_negative: bool,
}

impl ColumnMeasurement {
    /// An exact, undelayed column (time, commands, program state).
    pub const EXACT: ColumnMeasurement = ColumnMeasurement {
        noise_sigma: 0.0,
        delayed: false,
        drifts: false,
        non_negative: false,
    };

    /// A measured signal with noise `sigma`.
    pub fn measured(sigma: f64) -> Self {
        ColumnMeasurement {
            noise_sigma: sigma,
            delayed: true,
            drifts: false,
            non_negative: false,
        }
    }
}

/// Settings of the measurement chain.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeasurementSettings {
    /// Sample interval, s.
    pub dt_s: f64,
    /// Multiplies every column's noise.
    pub noise_scale: f64,
    /// Share of the noise variance that is AR(1)-correlated.
    pub correlated_fraction: f64,
    /// Correlation time of that part, s.
    pub correlation_time_s: f64,
    /// Transport delay, s (0 = none).
    pub delay_s: f64,
    /// Offset of drifting columns.
    pub offset: f64,
    /// Drift of drifting columns per hour.
    pub drift_per_hour: f64,
}

/// Applies noise, delay and drift to rows of true values.
#[derive(Debug)]
pub struct MeasurementChain {
    columns: Vec<ColumnMeasurement>,
    settings: MeasurementSettings,
    delay_rows: usize,
    history: VecDeque<Vec<f64>>,
    correlated_state: Vec<f64>,
    phi: f64,
    rng: StdRng,
}

impl MeasurementChain {
    /// A chain for `columns`, drawing noise from `seed`.
    pub fn new(columns: Vec<ColumnMeasurement>, settings: MeasurementSettings, seed: u64) -> Self {
        let delay_rows = (settings.delay_s / settings.dt_s).round() as usize;
        let phi = (-settings.dt_s / settings.correlation_time_s).exp();
        let mut rng = StdRng::seed_from_u64(seed ^ 0x0001_5E0F_5EED);
        // Start the correlated part in its stationary distribution.
        let correlated_state = columns
            .iter()
            .map(|_| StandardNormal.sample(&mut rng))
            .collect();
        MeasurementChain {
            delay_rows,
            history: VecDeque::with_capacity(delay_rows + 1),
            correlated_state,
            phi,
            rng,
            columns,
            settings,
        }
    }

    /// Turns the true row at time `t_s` into the measured row `out`.
    pub fn measure(&mut self, t_s: f64, truth: &[f64], out: &mut Vec<f64>) {
        out.clear();
        out.extend_from_slice(truth);
        if self.delay_rows > 0 {
            if self.history.len() == self.delay_rows + 1 {
                let mut recycled = self.history.pop_front().unwrap_or_default();
                recycled.clear();
                recycled.extend_from_slice(truth);
                self.history.push_back(recycled);
            } else {
                self.history.push_back(truth.to_vec());
            }
            // Until the delay line has filled, instruments show the first value they saw.
            let delayed = &self.history[0];
            for (i, column) in self.columns.iter().enumerate() {
                if column.delayed {
                    out[i] = delayed[i];
                }
            }
        }
        let s = &self.settings;
        let white_share = (1.0 - s.correlated_fraction).sqrt();
        let correlated_share = s.correlated_fraction.sqrt();
        let innovation = (1.0 - self.phi * self.phi).sqrt();
        for (i, column) in self.columns.iter().enumerate() {
            if column.drifts {
                out[i] += s.offset + s.drift_per_hour * t_s / 3600.0;
            }
            let sigma = column.noise_sigma * s.noise_scale;
            if sigma > 0.0 {
                let white: f64 = StandardNormal.sample(&mut self.rng);
                let shock: f64 = StandardNormal.sample(&mut self.rng);
                let state = self.phi * self.correlated_state[i] + innovation * shock;
                self.correlated_state[i] = state;
                out[i] += sigma * (white_share * white + correlated_share * state);
            }
            if column.non_negative && out[i] < 0.0 {
                out[i] = 0.0;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn settings() -> MeasurementSettings {
        MeasurementSettings {
            dt_s: 1.0,
            noise_scale: 1.0,
            correlated_fraction: 0.0,
            correlation_time_s: 50.0,
            delay_s: 0.0,
            offset: 0.0,
            drift_per_hour: 0.0,
        }
    }

    #[test]
    fn delay_shifts_measured_columns_only() {
        let columns = vec![ColumnMeasurement::EXACT, ColumnMeasurement::measured(0.0)];
        let mut chain = MeasurementChain::new(
            columns,
            MeasurementSettings {
                delay_s: 3.0,
                ..settings()
            },
            1,
        );
        let mut out = Vec::new();
        let mut seen = Vec::new();
        for k in 0..8 {
            chain.measure(k as f64, &[k as f64, 10.0 * k as f64], &mut out);
            seen.push(out.clone());
        }
        assert_eq!(seen[7], vec![7.0, 40.0]);
        assert_eq!(seen[1], vec![1.0, 0.0]);
    }

    #[test]
    fn noise_has_the_configured_spread_and_correlation() {
        for fraction in [0.0, 0.9] {
            let columns = vec![ColumnMeasurement::measured(2.0)];
            let mut chain = MeasurementChain::new(
                columns,
                MeasurementSettings {
                    correlated_fraction: fraction,
                    ..settings()
                },
                7,
            );
            let mut out = Vec::new();
            let values: Vec<f64> = (0..40_000)
                .map(|k| {
                    chain.measure(k as f64, &[0.0], &mut out);
                    out[0]
                })
                .collect();
            let n = values.len() as f64;
            let mean = values.iter().sum::<f64>() / n;
            let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n;
            let lag1 = values
                .windows(2)
                .map(|w| (w[0] - mean) * (w[1] - mean))
                .sum::<f64>()
                / n
                / var;
            assert!((var.sqrt() - 2.0).abs() < 0.15, "σ {}", var.sqrt());
            let expected = fraction * (-1.0_f64 / 50.0).exp();
            assert!((lag1 - expected).abs() < 0.05, "lag-1 {lag1} vs {expected}");
        }
    }

    #[test]
    fn drift_grows_linearly_with_time() {
        let columns = vec![ColumnMeasurement {
            drifts: true,
            ..ColumnMeasurement::EXACT
        }];
        let mut chain = MeasurementChain::new(
            columns,
            MeasurementSettings {
                offset: 1.0,
                drift_per_hour: 2.0,
                ..settings()
            },
            1,
        );
        let mut out = Vec::new();
        chain.measure(7200.0, &[5.0], &mut out);
        assert_eq!(out[0], 10.0);
    }
}
