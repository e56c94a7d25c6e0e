//! The corrections refitted to a censored instrument's readings taken as bounds.
//!
//! [`super::censor`] compares the simulation as the instrument would read it, each standstill
//! with one latent level of its own, so that the residual can be fitted like any other. That
//! holds while the instrument's zero stays where the simulation's does. A current sensor whose
//! zero drifts down reads the floor through whole standstills, where one level per span cannot
//! follow the drift, and then on running rows too, where nothing lifts the simulation: a
//! reading of 0 A then says only that the current plus the sensor's offset is at or below 0 A,
//! and fitted as the value 0 it holds the drift's line up (0.093 A left held out beside 0.03 A
//! of noise, independent seed 1).
//!
//! Here every reading at the floor is taken for what it is, an upper bound on the residual,
//! and the corrections are fitted by maximum likelihood (a censored regression with the
//! instrument's scatter σ known): the readings above the floor by their squared errors, those
//! at it by the probability that the reading falls at or below it. The model's prediction of
//! a held-out reading is what the instrument would show for it, E[max(floor, value + e)]. The
//! analysis keeps this fit only where it predicts the held-out readings clearly better than
//! the fit of the readings as compared ([`CUT_OFF_MIN_GAIN`]).

use super::censor::{Censoring, NORMAL_TAIL_FROM, inverse_mills_ratio_given};
use super::cv::{Blocks, cholesky, cholesky_solve};
use crate::fit::distributions::{standard_normal_cdf, standard_normal_pdf};

/// Share of the held-out squared error of the readings, as compared, that the fit to the
/// readings as bounds must remove to be kept. Where the instrument's zero stays put, the
/// simulation compared as read already holds what the bounds say, and the fit as compared, on
/// which the selection ran, is kept.
pub const CUT_OFF_MIN_GAIN: f64 = 0.2;
/// Newton steps of one fit at most (it converges in a handful: the likelihood is concave).
const MAX_STEPS: usize = 60;
/// Halvings of a Newton step that does not raise the likelihood.
const MAX_HALVINGS: usize = 40;

/// A censored target's readings beside the simulation as it was exported.
#[derive(Debug, Clone)]
pub struct CutOffReadings {
    /// Reading less the simulation, per row; at a reading at the floor, the bound the residual
    /// lies at or below.
    residual: Vec<f64>,
    /// The floor less the simulation, per row: the least residual the instrument can show.
    bound: Vec<f64>,
    /// Rows whose reading sits at the floor.
    at_floor: Vec<bool>,
    /// The instrument's scatter about its level, target unit.
    sigma: f64,
}

impl CutOffReadings {
    /// The readings of `real` censored as `censoring` found, beside `sim` (the simulation as
    /// exported, not as read). `None` when the scatter is not positive or no reading sits at
    /// the floor.
    pub fn new(censoring: &Censoring, real: &[f64], sim: &[f64]) -> Option<CutOffReadings> {
        CutOffReadings::at_floor(censoring.floor, censoring.sigma, real, sim)
    }

    /// The readings of `real` at and above `floor`, scattered by `sigma` about their level,
    /// beside `sim`; `None` as [`CutOffReadings::new`].
    pub fn at_floor(floor: f64, sigma: f64, real: &[f64], sim: &[f64]) -> Option<CutOffReadings> {
        let n = real.len().min(sim.len());
        if !(sigma > 0.0 && sigma.is_finite()) {
            return None;
        }
        let at_floor: Vec<bool> = real[..n].iter().map(|r| *r <= floor).collect();
        if !at_floor.contains(&true) {
            return None;
        }
        let residual = real[..n]
            .iter()
            .zip(&sim[..n])
            .map(|(r, s)| r - s)
            .collect();
        let bound = sim[..n].iter().map(|s| floor - s).collect();
        Some(CutOffReadings {
            residual,
            bound,
            at_floor,
            sigma,
        })
    }

    /// Number of rows.
    pub fn len(&self) -> usize {
        self.residual.len()
    }

    /// True when there are no rows.
    pub fn is_empty(&self) -> bool {
        self.residual.is_empty()
    }

    /// The residual the instrument would show at `row` for a model value `value` (relative to
    /// the simulation): E[max(bound, value + e)], the bound being where the floor lies.
    pub fn reading(&self, row: usize, value: f64) -> f64 {
        let bound = self.bound[row];
        let s = value - bound;
        let u = s / self.sigma;
        bound + s * standard_normal_cdf(u) + self.sigma * standard_normal_pdf(u)
    }

    /// The simulation with the model's `fitted` values (relative to it), row by row, as the
    /// instrument would read it; `real` is the recording these readings came from.
    pub fn corrected(&self, real: &[f64], fitted: &[f64]) -> Vec<f64> {
        (0..self.residual.len().min(fitted.len()))
            .map(|i| real[i] - self.residual[i] + self.reading(i, fitted[i]))
            .collect()
    }

    /// Squared errors of the readings, summed, against what the instrument would show for the
    /// model `beta` of `columns`.
    pub fn sse(&self, columns: &[&[f64]], beta: &[f64]) -> f64 {
        (0..self.residual.len())
            .map(|i| {
                let m: f64 = columns.iter().zip(beta).map(|(c, b)| c[i] * b).sum();
                (self.residual[i] - self.reading(i, m)).powi(2)
            })
            .sum()
    }

    /// Coefficients of `columns` fitted to the readings of the rows `training` keeps, by
    /// maximum likelihood with the readings at the floor as bounds; `None` when the columns
    /// are degenerate on those rows.
    pub fn fit(&self, columns: &[&[f64]], training: &[bool]) -> Option<Vec<f64>> {
        self.fit_from(columns, training, None)
    }

    /// [`CutOffReadings::fit`] from the coefficients `start` (of the same columns) where
    /// given, rather than from the fit that takes every reading as its value. The
    /// likelihood is concave, so the start changes only how many Newton steps it takes: a
    /// fold's fit started from the one before it, which left out other blocks, is a step or
    /// two from its own.
    fn fit_from(
        &self,
        columns: &[&[f64]],
        training: &[bool],
        start: Option<&[f64]>,
    ) -> Option<Vec<f64>> {
        let p = columns.len();
        let sigma = self.sigma;
        let rows = || (0..self.residual.len()).filter(|&i| training[i]);
        // The readings above the floor: fixed Gram and products.
        let mut gram_above = vec![0.0; p * p];
        let mut products_above = vec![0.0; p];
        let mut squares_above = 0.0;
        let mut x = vec![0.0; p];
        let mut floor_rows = Vec::new();
        for i in rows() {
            if self.at_floor[i] {
                floor_rows.push(i);
                continue;
            }
            row_into(columns, i, &mut x);
            let y = self.residual[i];
            squares_above += y * y;
            for a in 0..p {
                products_above[a] += x[a] * y;
                for b in 0..=a {
                    gram_above[a * p + b] += x[a] * x[b];
                }
            }
        }
        symmetrise(&mut gram_above, p);
        let mut beta = match start.filter(|start| start.len() == p) {
            Some(start) => start.to_vec(),
            None => {
                // The start: every reading taken as its value.
                let mut gram_all = gram_above.clone();
                let mut products_all = products_above.clone();
                for &i in &floor_rows {
                    row_into(columns, i, &mut x);
                    let y = self.residual[i];
                    for a in 0..p {
                        products_all[a] += x[a] * y;
                        for b in 0..=a {
                            gram_all[a * p + b] += x[a] * x[b];
                        }
                    }
                }
                symmetrise(&mut gram_all, p);
                cholesky_solve(&cholesky(&gram_all, p)?, p, &products_all)
            }
        };
        // σ² × the log-likelihood (up to a constant): −½ Σ (y − m)² above the floor, σ² Σ ln Φ
        // at it. Each reading at the floor's z and Φ(z) are kept in `at` for the Newton step
        // that follows an accepted one, which needs them again.
        let objective = |beta: &[f64], x: &mut [f64], at: &mut Vec<(f64, f64)>| -> f64 {
            let quadratic: f64 = (0..p)
                .map(|a| beta[a] * (0..p).map(|b| gram_above[a * p + b] * beta[b]).sum::<f64>())
                .sum();
            let cross: f64 = beta.iter().zip(&products_above).map(|(b, r)| b * r).sum();
            let above = -0.5 * (squares_above - 2.0 * cross + quadratic);
            at.clear();
            let at_floor: f64 = floor_rows
                .iter()
                .map(|&i| {
                    row_into(columns, i, x);
                    let m: f64 = x.iter().zip(beta).map(|(x, b)| x * b).sum();
                    let z = (self.residual[i] - m) / sigma;
                    let cdf = standard_normal_cdf(z);
                    at.push((z, cdf));
                    ln_standard_normal_cdf_given(z, cdf)
                })
                .sum();
            above + sigma * sigma * at_floor
        };
        let mut at = Vec::with_capacity(floor_rows.len());
        let mut trial_at = Vec::with_capacity(floor_rows.len());
        let mut current = objective(&beta, &mut x, &mut at);
        for _ in 0..MAX_STEPS {
            // Gradient and (negated) Hessian, both × σ².
            let mut gradient: Vec<f64> = (0..p)
                .map(|a| {
                    products_above[a] - (0..p).map(|b| gram_above[a * p + b] * beta[b]).sum::<f64>()
                })
                .collect();
            let mut curvature = gram_above.clone();
            for (&i, &(z, cdf)) in floor_rows.iter().zip(&at) {
                row_into(columns, i, &mut x);
                let lambda = inverse_mills_ratio_given(z, cdf);
                let weight = (lambda * (lambda + z)).clamp(0.0, 1.0);
                for a in 0..p {
                    gradient[a] -= sigma * lambda * x[a];
                    for b in 0..=a {
                        curvature[a * p + b] += weight * x[a] * x[b];
                    }
                }
            }
            symmetrise(&mut curvature, p);
            let step = cholesky_solve(&cholesky(&curvature, p)?, p, &gradient);
            let mut t = 1.0;
            let mut accepted = None;
            for _ in 0..MAX_HALVINGS {
                let trial: Vec<f64> = beta.iter().zip(&step).map(|(b, s)| b + t * s).collect();
                let value = objective(&trial, &mut x, &mut trial_at);
                if value >= current {
                    accepted = Some((trial, value));
                    break;
                }
                t *= 0.5;
            }
            let Some((trial, value)) = accepted else {
                break;
            };
            let moved = beta
                .iter()
                .zip(&trial)
                .all(|(b, t)| (t - b).abs() <= 1e-10 * (1.0 + b.abs()));
            beta = trial;
            current = value;
            std::mem::swap(&mut at, &mut trial_at);
            if moved {
                break;
            }
        }
        Some(beta)
    }

    /// Held-out errors of the readings, fold by fold: each held-out row's reading less what
    /// the instrument would show for the model fitted to the readings of the fold's training
    /// blocks. `None` when a fold cannot be fitted.
    pub fn held_out_errors(&self, columns: &[&[f64]], blocks: &Blocks) -> Option<Vec<f64>> {
        let n = self.residual.len();
        let mut errors = vec![0.0; n];
        let mut previous: Option<Vec<f64>> = None;
        for fold in &blocks.folds {
            let mut training = vec![true; n];
            for b in fold.excluded.clone() {
                for i in blocks.ranges[b].clone() {
                    training[i] = false;
                }
            }
            let beta = self.fit_from(columns, &training, previous.as_deref())?;
            for b in fold.test.clone() {
                for i in blocks.ranges[b].clone() {
                    let m: f64 = columns.iter().zip(&beta).map(|(c, b)| c[i] * b).sum();
                    errors[i] = self.residual[i] - self.reading(i, m);
                }
            }
            previous = Some(beta);
        }
        Some(errors)
    }
}

/// Row `i` of `columns` into `x`.
fn row_into(columns: &[&[f64]], i: usize, x: &mut [f64]) {
    for (x, c) in x.iter_mut().zip(columns) {
        *x = c[i];
    }
}

/// Copies the lower triangle of a p×p row-major matrix to its upper one.
fn symmetrise(matrix: &mut [f64], p: usize) {
    for a in 0..p {
        for b in 0..a {
            matrix[b * p + a] = matrix[a * p + b];
        }
    }
}

/// ln Φ(z) where Φ(z) is already known (`cdf`), kept finite far in the lower tail where Φ
/// underflows.
fn ln_standard_normal_cdf_given(z: f64, cdf: f64) -> f64 {
    if z > NORMAL_TAIL_FROM {
        cdf.ln()
    } else {
        let w = 1.0 / (z * z);
        -0.5 * z * z - (-z).ln() - 0.5 * (2.0 * std::f64::consts::PI).ln()
            + (1.0 - w + 3.0 * w * w).ln()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{SeedableRng, rngs::StdRng};
    use rand_distr::{Distribution, Normal};

    /// A reading whose zero falls through its floor, with the offset and the line in time it
    /// is fitted on and its residual taken as values.
    struct FallingZero {
        ones: Vec<f64>,
        hours: Vec<f64>,
        as_values: Vec<f64>,
        readings: CutOffReadings,
    }

    impl FallingZero {
        fn columns(&self) -> Vec<&[f64]> {
            vec![&self.ones, &self.hours]
        }
    }

    /// A current of 1 A running and 0 A standing in turns of ten minutes, read with an offset
    /// falling from +0.2 A by 0.4 A/h over 6 h and 0.03 A of noise, cut off at 0 A.
    fn falling_zero() -> FallingZero {
        let n = 6 * 3600;
        let mut rng = StdRng::seed_from_u64(7);
        let noise = Normal::new(0.0, 0.03).expect("a positive σ");
        let hours: Vec<f64> = (0..n).map(|i| i as f64 / 3600.0).collect();
        // The axis runs (1 A) and stands (0 A) in turns of ten minutes.
        let sim: Vec<f64> = (0..n)
            .map(|i| if (i / 600) % 2 == 0 { 1.0 } else { 0.0 })
            .collect();
        let real: Vec<f64> = sim
            .iter()
            .zip(&hours)
            .map(|(s, h)| (s + 0.2 - 0.4 * h + noise.sample(&mut rng)).max(0.0))
            .collect();
        let censoring = Censoring {
            floor: 0.0,
            share_at_floor: real.iter().filter(|r| **r == 0.0).count() as f64 / n as f64,
            sigma: 0.03,
            standstill_spans: 18,
            spans_levelled_beside: 0,
            sigma_overall: 0.03,
            standstill_lag_rows: 0,
        };
        FallingZero {
            ones: vec![1.0; n],
            as_values: real.iter().zip(&sim).map(|(r, s)| r - s).collect(),
            readings: CutOffReadings::new(&censoring, &real, &sim).expect("readings at 0 A"),
            hours,
        }
    }

    #[test]
    fn a_zero_falling_through_the_floor_is_fitted_from_the_readings_as_bounds() {
        let zero = falling_zero();
        let columns = zero.columns();
        let beta = zero
            .readings
            .fit(&columns, &vec![true; zero.ones.len()])
            .expect("a fit");
        assert!((beta[0] - 0.2).abs() < 0.01, "offset {}", beta[0]);
        assert!((beta[1] + 0.4).abs() < 0.005, "drift {} A/h", beta[1]);
        // Each reading at the floor taken as its value holds the line up.
        let (as_values, _) = crate::discrepancy::cv::least_squares(&columns, &zero.as_values)
            .expect("a least-squares fit");
        assert!(as_values[1] > -0.3, "drift as values {} A/h", as_values[1]);
    }

    #[test]
    fn the_held_out_readings_are_predicted_as_the_instrument_shows_them() {
        let zero = falling_zero();
        let columns = zero.columns();
        let blocks = Blocks::new(zero.ones.len(), 8, 4);
        let errors = zero
            .readings
            .held_out_errors(&columns, &blocks)
            .expect("every fold fitted");
        let rmse = (errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64).sqrt();
        // No more than the noise (less where the floor cuts it off).
        assert!(rmse < 0.03, "held-out RMSE {rmse} A");
        let gram = crate::discrepancy::cv::ModelGram::new(&columns, &blocks);
        let products =
            crate::discrepancy::cv::TargetProducts::new(&columns, &zero.as_values, &blocks);
        let as_values = gram
            .cv_sse(&products.stats(), &blocks)
            .expect("folds fitted");
        let as_values_rmse = (as_values / errors.len() as f64).sqrt();
        assert!(as_values_rmse > 3.0 * rmse, "as values {as_values_rmse} A");
    }

    #[test]
    fn a_fit_started_elsewhere_reaches_the_same_coefficients() {
        let zero = falling_zero();
        let columns = zero.columns();
        // The first half hour left out, as a fold leaves out its blocks.
        let training: Vec<bool> = (0..zero.ones.len()).map(|i| i >= 1800).collect();
        let from_values = zero.readings.fit(&columns, &training).expect("a fit");
        // Far from the optimum, on the wrong side of the floor: a drift upwards.
        let from_far = zero
            .readings
            .fit_from(&columns, &training, Some(&[-1.0, 0.5]))
            .expect("a fit");
        for (a, b) in from_values.iter().zip(&from_far) {
            assert!((a - b).abs() < 1e-8, "{from_values:?} against {from_far:?}");
        }
        assert!(
            (from_far[1] + 0.4).abs() < 0.005,
            "drift {} A/h",
            from_far[1]
        );
    }

    #[test]
    fn ln_phi_joins_its_tail_form() {
        for z in [-29.999, -30.0, -30.001] {
            let exact = (0.5 * statrs::function::erf::erfc(-z / std::f64::consts::SQRT_2)).ln();
            assert!(
                (ln_standard_normal_cdf_given(z, standard_normal_cdf(z)) - exact).abs()
                    < 1e-6 * exact.abs(),
                "{z}"
            );
        }
    }
}
