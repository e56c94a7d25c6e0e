//! Time-blocked cross-validation by sufficient statistics.
//!
//! The rows are cut into contiguous time blocks; a fold holds out a run of blocks and trains on
//! the rest minus one gap block on each side (so autocorrelated noise does not leak from the
//! training rows into the held-out ones). Because a least-squares fit needs only ZᵀZ, Zᵀy and
//! yᵀy, everything is kept per block: the training statistics of a fold are the totals minus the
//! held-out and gap blocks, and the held-out squared error is yᵀy − 2βᵀZᵀy + βᵀZᵀZβ over the
//! held-out blocks. The y-independent part (ZᵀZ and its Cholesky factors per fold) is computed
//! once per model, so scoring the same model against many surrogate targets costs only the
//! Zᵀy products — which is what makes a surrogate null over a whole physics library affordable.

use std::ops::Range;

/// Blocks left out of training on each side of a held-out run (1/32 of the record each with the
/// default 8 folds × 4 blocks). Two were tried: they cost more detections than the leak they
/// stop (docs/discrepancy.md).
const GAP_BLOCKS: usize = 1;

/// How rows are cut into blocks and folds.
#[derive(Debug, Clone)]
pub struct Blocks {
    /// Row ranges of the blocks, in time order.
    pub ranges: Vec<Range<usize>>,
    /// The folds.
    pub folds: Vec<Fold>,
}

/// One fold of the cross-validation.
#[derive(Debug, Clone)]
pub struct Fold {
    /// Held-out blocks.
    pub test: Range<usize>,
    /// Blocks left out of training: the held-out ones plus the gap blocks on each side.
    pub excluded: Range<usize>,
}

impl Blocks {
    /// `n` rows in `folds` folds of `blocks_per_fold` blocks each; training leaves out one gap
    /// block on each side of the held-out run.
    pub fn new(n: usize, folds: usize, blocks_per_fold: usize) -> Blocks {
        let count = (folds * blocks_per_fold).clamp(1, n.max(1));
        let ranges = super::series::bin_ranges(n, count);
        let count = ranges.len();
        let folds = folds.clamp(1, count);
        let folds = (0..folds)
            .map(|f| {
                let start = f * count / folds;
                let end = (f + 1) * count / folds;
                Fold {
                    test: start..end,
                    excluded: start.saturating_sub(GAP_BLOCKS)..(end + GAP_BLOCKS).min(count),
                }
            })
            .collect();
        Blocks { ranges, folds }
    }

    /// Number of blocks.
    pub fn len(&self) -> usize {
        self.ranges.len()
    }

    /// True when there are no blocks.
    pub fn is_empty(&self) -> bool {
        self.ranges.is_empty()
    }

    /// Per-block dot products of two columns.
    pub fn dots(&self, a: &[f64], b: &[f64]) -> Vec<f64> {
        self.ranges
            .iter()
            .map(|r| super::series::dot(&a[r.clone()], &b[r.clone()]))
            .collect()
    }
}

/// Cholesky factor (lower, row-major p×p) of a symmetric matrix with a small ridge added for
/// near-collinear columns; `None` when the matrix is not usable at all.
pub(super) fn cholesky(matrix: &[f64], p: usize) -> Option<Vec<f64>> {
    if p == 0 {
        return Some(Vec::new());
    }
    let scale = (0..p).map(|i| matrix[i * p + i]).fold(0.0_f64, f64::max);
    if !(scale > 0.0 && scale.is_finite()) {
        return None;
    }
    let ridge = 1e-10 * scale;
    let mut l = vec![0.0; p * p];
    for i in 0..p {
        for j in 0..=i {
            let mut sum = matrix[i * p + j];
            if i == j {
                sum += ridge;
            }
            for k in 0..j {
                sum -= l[i * p + k] * l[j * p + k];
            }
            if i == j {
                if sum <= 0.0 {
                    return None;
                }
                l[i * p + i] = sum.sqrt();
            } else {
                l[i * p + j] = sum / l[j * p + j];
            }
        }
    }
    Some(l)
}

/// Solves L Lᵀ x = b.
pub(super) fn cholesky_solve(l: &[f64], p: usize, b: &[f64]) -> Vec<f64> {
    let mut z = b.to_vec();
    cholesky_solve_in_place(l, p, &mut z);
    z
}

/// [`cholesky_solve`] overwriting its right-hand side `z` with the solution: the held-out
/// error solves a small system per fold for every candidate and surrogate, hundreds of
/// thousands of them, where an allocation each costs as much as the solve.
fn cholesky_solve_in_place(l: &[f64], p: usize, z: &mut [f64]) {
    // L's rows and columns as slices, not indices: no bounds check in the inner loops, the
    // same operations in the same order.
    for i in 0..p {
        let mut zi = z[i];
        for (a, zk) in l[i * p..i * p + i].iter().zip(&z[..i]) {
            zi -= a * zk;
        }
        z[i] = zi / l[i * p + i];
    }
    for i in (0..p).rev() {
        let mut zi = z[i];
        let column_below = l[i * p + i..].iter().step_by(p).skip(1);
        for (a, zk) in column_below.zip(&z[i + 1..]) {
            zi -= a * zk;
        }
        z[i] = zi / l[i * p + i];
    }
}

/// Ordinary least squares of `y` on `columns` (include a column of ones for an intercept) by
/// the normal equations: coefficients and the residual sum of squares, `None` when degenerate.
/// Columns should be of similar scale (standardised) for the normal equations to be accurate.
pub fn least_squares(columns: &[&[f64]], y: &[f64]) -> Option<(Vec<f64>, f64)> {
    let p = columns.len();
    let mut g = vec![0.0; p * p];
    let mut h = vec![0.0; p];
    for i in 0..p {
        for j in 0..=i {
            let d: f64 = columns[i].iter().zip(columns[j]).map(|(a, b)| a * b).sum();
            g[i * p + j] = d;
            g[j * p + i] = d;
        }
        h[i] = columns[i].iter().zip(y).map(|(a, b)| a * b).sum();
    }
    let l = cholesky(&g, p)?;
    let beta = cholesky_solve(&l, p, &h);
    let sse = (0..y.len())
        .map(|r| {
            let fitted: f64 = columns.iter().zip(&beta).map(|(c, b)| c[r] * b).sum();
            (y[r] - fitted).powi(2)
        })
        .sum();
    Some((beta, sse))
}

/// The normal equations of fixed leading columns, kept so that many least-squares fits that
/// add a few columns to them compute only the new columns' products: refining a correction's
/// time constant fits every trial value beside the same other corrections.
pub struct NormalEquations<'a> {
    columns: Vec<&'a [f64]>,
    y: &'a [f64],
    /// ZᵀZ of the kept columns, row-major.
    gram: Vec<f64>,
    /// Zᵀy of the kept columns.
    cross: Vec<f64>,
    yty: f64,
}

impl<'a> NormalEquations<'a> {
    /// The normal equations of `y` on `columns` (include a column of ones for an intercept).
    pub fn new(columns: &[&'a [f64]], y: &'a [f64]) -> NormalEquations<'a> {
        let k = columns.len();
        let mut gram = vec![0.0; k * k];
        for i in 0..k {
            for j in 0..=i {
                let d = super::series::dot(columns[i], columns[j]);
                gram[i * k + j] = d;
                gram[j * k + i] = d;
            }
        }
        NormalEquations {
            cross: columns.iter().map(|c| super::series::dot(c, y)).collect(),
            columns: columns.to_vec(),
            y,
            gram,
            yty: super::series::dot(y, y),
        }
    }

    /// Ordinary least squares of `y` on the kept columns followed by `extra`: the coefficients
    /// and the residual sum of squares (yᵀy − 2βᵀZᵀy + βᵀZᵀZβ, which needs no pass over the
    /// residuals), `None` when degenerate. Columns should be of similar scale (standardised).
    pub fn fit_with(&self, extra: &[&[f64]]) -> Option<(Vec<f64>, f64)> {
        let k = self.columns.len();
        let p = k + extra.len();
        let mut g = embedded(&self.gram, k, p);
        let mut h = self.cross.clone();
        for (e, column) in extra.iter().enumerate() {
            let i = k + e;
            for j in 0..=i {
                let other = if j < k { self.columns[j] } else { extra[j - k] };
                let d = super::series::dot(column, other);
                g[i * p + j] = d;
                g[j * p + i] = d;
            }
            h.push(super::series::dot(column, self.y));
        }
        let l = cholesky(&g, p)?;
        let beta = cholesky_solve(&l, p, &h);
        let cross: f64 = beta.iter().zip(&h).map(|(b, h)| b * h).sum();
        let sse = self.yty - 2.0 * cross + quadratic(&g, p, &beta);
        Some((beta, sse.max(0.0)))
    }
}

/// A k×k matrix (row-major) as the top-left corner of a p×p one, the rest zero: the products
/// of the columns a model keeps, before a larger model's new ones are filled in.
fn embedded(matrix: &[f64], k: usize, p: usize) -> Vec<f64> {
    let mut g = vec![0.0; p * p];
    for i in 0..k {
        g[i * p..i * p + k].copy_from_slice(&matrix[i * k..(i + 1) * k]);
    }
    g
}

/// Per-block products of `columns[i]` with every earlier column and itself, for the rows
/// `i >= from` (the products among the first `from` columns are kept as they are), written
/// into both halves of each block's p×p matrix.
fn fill_products(per_block: &mut [Vec<f64>], columns: &[&[f64]], from: usize, blocks: &Blocks) {
    let p = columns.len();
    for i in from..p {
        for j in 0..=i {
            let dots = blocks.dots(columns[i], columns[j]);
            for (block, d) in per_block.iter_mut().zip(dots) {
                block[i * p + j] = d;
                block[j * p + i] = d;
            }
        }
    }
}

fn quadratic(g: &[f64], p: usize, beta: &[f64]) -> f64 {
    let mut total = 0.0;
    for i in 0..p {
        let row: f64 = (0..p).map(|j| g[i * p + j] * beta[j]).sum();
        total += beta[i] * row;
    }
    total
}

/// The y-independent statistics of one model (a set of columns) over the blocks.
#[derive(Debug, Clone)]
pub struct ModelGram {
    p: usize,
    total_factor: Option<Vec<f64>>,
    folds: Vec<FoldFactor>,
    per_block: Vec<Vec<f64>>,
}

#[derive(Debug, Clone)]
struct FoldFactor {
    training_factor: Option<Vec<f64>>,
    test_gram: Vec<f64>,
}

/// A target's cross products with every column of a model, per block, plus yᵀy per block.
#[derive(Debug, Clone)]
pub struct TargetStats<'a> {
    /// `zty[column][block]`.
    pub zty: Vec<&'a [f64]>,
    /// `yty[block]`.
    pub yty: &'a [f64],
}

/// A target's per-block cross products with a model's columns and with itself, owned: what a
/// [`TargetStats`] borrows.
#[derive(Debug, Clone)]
pub struct TargetProducts {
    /// `zty[column][block]`.
    pub zty: Vec<Vec<f64>>,
    /// `yty[block]`.
    pub yty: Vec<f64>,
}

impl TargetProducts {
    /// The products of `y` with every one of `columns` and with itself, per block.
    pub fn new(columns: &[&[f64]], y: &[f64], blocks: &Blocks) -> TargetProducts {
        TargetProducts {
            zty: columns.iter().map(|c| blocks.dots(c, y)).collect(),
            yty: blocks.dots(y, y),
        }
    }

    /// The products as [`TargetStats`].
    pub fn stats(&self) -> TargetStats<'_> {
        TargetStats {
            zty: self.zty.iter().map(|v| v.as_slice()).collect(),
            yty: &self.yty,
        }
    }
}

impl ModelGram {
    /// Builds the statistics of the model whose columns are `columns`.
    pub fn new(columns: &[&[f64]], blocks: &Blocks) -> ModelGram {
        let p = columns.len();
        let mut per_block = vec![vec![0.0; p * p]; blocks.len()];
        fill_products(&mut per_block, columns, 0, blocks);
        Self::from_per_block(p, per_block, blocks)
    }

    /// The statistics of this model (whose columns are `columns`) with `extra` columns added
    /// after its own. Only the new columns' products are computed: fitting many candidates
    /// beside the same corrections costs each candidate its own columns, not the whole model's
    /// again. The same figures as [`ModelGram::new`] on all the columns, to the bit.
    pub fn extended(&self, columns: &[&[f64]], extra: &[&[f64]], blocks: &Blocks) -> ModelGram {
        debug_assert_eq!(columns.len(), self.p, "the model's own columns");
        let k = self.p;
        let p = k + extra.len();
        let mut per_block: Vec<Vec<f64>> = self
            .per_block
            .iter()
            .map(|own| embedded(own, k, p))
            .collect();
        let all: Vec<&[f64]> = columns.iter().chain(extra).copied().collect();
        fill_products(&mut per_block, &all, k, blocks);
        Self::from_per_block(p, per_block, blocks)
    }

    /// Factors the training and held-out statistics of every fold from per-block products.
    fn from_per_block(p: usize, per_block: Vec<Vec<f64>>, blocks: &Blocks) -> ModelGram {
        let nb = blocks.len();
        let sum_blocks = |range: Range<usize>| {
            let mut g = vec![0.0; p * p];
            for block in &per_block[range] {
                for (a, b) in g.iter_mut().zip(block) {
                    *a += b;
                }
            }
            g
        };
        let total = sum_blocks(0..nb);
        let folds = blocks
            .folds
            .iter()
            .map(|fold| {
                let excluded = sum_blocks(fold.excluded.clone());
                let training: Vec<f64> = total.iter().zip(&excluded).map(|(t, e)| t - e).collect();
                FoldFactor {
                    training_factor: cholesky(&training, p),
                    test_gram: sum_blocks(fold.test.clone()),
                }
            })
            .collect();
        ModelGram {
            p,
            total_factor: cholesky(&total, p),
            folds,
            per_block,
        }
    }

    /// Number of columns.
    pub fn p(&self) -> usize {
        self.p
    }

    fn zty_sum(&self, stats: &TargetStats<'_>, range: Range<usize>) -> Vec<f64> {
        let mut sums = vec![0.0; stats.zty.len()];
        Self::zty_sum_into(stats, range, &mut sums);
        sums
    }

    /// [`ModelGram::zty_sum`] written into `sums` (see `cholesky_solve_in_place`).
    fn zty_sum_into(stats: &TargetStats<'_>, range: Range<usize>, sums: &mut [f64]) {
        for (sum, col) in sums.iter_mut().zip(&stats.zty) {
            *sum = col[range.clone()].iter().sum();
        }
    }

    /// Least-squares coefficients on all rows, `None` when the columns are degenerate.
    pub fn full_fit(&self, stats: &TargetStats<'_>, blocks: &Blocks) -> Option<Vec<f64>> {
        let factor = self.total_factor.as_ref()?;
        Some(cholesky_solve(
            factor,
            self.p,
            &self.zty_sum(stats, 0..blocks.len()),
        ))
    }

    /// Held-out sum of squared errors over all folds; `None` when a fold cannot be fitted.
    pub fn cv_sse(&self, stats: &TargetStats<'_>, blocks: &Blocks) -> Option<f64> {
        let nb = blocks.len();
        let total = self.zty_sum(stats, 0..nb);
        // The fold's coefficients and its test sums, reused fold after fold (see
        // `cholesky_solve_in_place`).
        let mut beta = vec![0.0; self.p];
        let mut test = vec![0.0; self.p];
        let mut sse = 0.0;
        for (fold, factor) in blocks.folds.iter().zip(&self.folds) {
            let l = factor.training_factor.as_ref()?;
            // The training sums: all blocks' less the excluded ones'.
            Self::zty_sum_into(stats, fold.excluded.clone(), &mut beta);
            for (b, t) in beta.iter_mut().zip(&total) {
                *b = t - *b;
            }
            cholesky_solve_in_place(l, self.p, &mut beta);
            Self::zty_sum_into(stats, fold.test.clone(), &mut test);
            let yty: f64 = stats.yty[fold.test.clone()].iter().sum();
            let cross: f64 = beta.iter().zip(&test).map(|(b, t)| b * t).sum();
            sse += yty - 2.0 * cross + quadratic(&factor.test_gram, self.p, &beta);
        }
        Some(sse.max(0.0))
    }

    /// Held-out squared error of every block (each predicted by its fold's training fit).
    pub fn cv_block_sse(&self, stats: &TargetStats<'_>, blocks: &Blocks) -> Option<Vec<f64>> {
        let nb = blocks.len();
        let total = self.zty_sum(stats, 0..nb);
        let mut out = vec![0.0; nb];
        for (fold, factor) in blocks.folds.iter().zip(&self.folds) {
            let l = factor.training_factor.as_ref()?;
            let excluded = self.zty_sum(stats, fold.excluded.clone());
            let training: Vec<f64> = total.iter().zip(&excluded).map(|(t, e)| t - e).collect();
            let beta = cholesky_solve(l, self.p, &training);
            for b in fold.test.clone() {
                let cross: f64 = beta
                    .iter()
                    .zip(&stats.zty)
                    .map(|(beta, col)| beta * col[b])
                    .sum();
                out[b] = (stats.yty[b] - 2.0 * cross
                    + quadratic(&self.per_block[b], self.p, &beta))
                .max(0.0);
            }
        }
        Some(out)
    }

    /// Out-of-fold predictions of every row for explicit column data (used once at the end on
    /// the full-rate data, where the predictions themselves are wanted).
    pub fn cv_predictions(
        &self,
        columns: &[&[f64]],
        stats: &TargetStats<'_>,
        blocks: &Blocks,
    ) -> Option<Vec<f64>> {
        let nb = blocks.len();
        let n = blocks.ranges.last().map_or(0, |r| r.end);
        let total = self.zty_sum(stats, 0..nb);
        let mut out = vec![0.0; n];
        for (fold, factor) in blocks.folds.iter().zip(&self.folds) {
            let l = factor.training_factor.as_ref()?;
            let excluded = self.zty_sum(stats, fold.excluded.clone());
            let training: Vec<f64> = total.iter().zip(&excluded).map(|(t, e)| t - e).collect();
            let beta = cholesky_solve(l, self.p, &training);
            for b in fold.test.clone() {
                for i in blocks.ranges[b].clone() {
                    out[i] = columns.iter().zip(&beta).map(|(c, b)| c[i] * b).sum();
                }
            }
        }
        Some(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A model extended by more columns has the statistics of the whole model built at once.
    #[test]
    fn an_extended_model_is_the_whole_model_to_the_bit() {
        let n = 300;
        let column = |k: usize| -> Vec<f64> {
            (0..n)
                .map(|i| ((i * (7 + 2 * k)) % (11 + k)) as f64 - 0.3 * k as f64)
                .collect()
        };
        let ones = vec![1.0; n];
        let (a, b, c) = (column(1), column(2), column(3));
        let y: Vec<f64> = (0..n)
            .map(|i| 0.5 * a[i] - 0.2 * c[i] + (i % 5) as f64)
            .collect();
        let blocks = Blocks::new(n, 4, 3);
        let base = ModelGram::new(&[&ones, &a], &blocks);
        let extended = base.extended(&[&ones, &a], &[&b, &c], &blocks);
        let whole = ModelGram::new(&[&ones, &a, &b, &c], &blocks);
        assert_eq!(extended.per_block, whole.per_block);
        let products = TargetProducts::new(&[&ones, &a, &b, &c], &y, &blocks);
        let stats = products.stats();
        assert_eq!(
            extended.cv_sse(&stats, &blocks),
            whole.cv_sse(&stats, &blocks)
        );
    }

    /// Fits that add columns to kept normal equations agree with a fit of all the columns,
    /// and their residual sum of squares with the residuals' own.
    #[test]
    fn kept_normal_equations_fit_as_the_whole_least_squares() {
        let n = 200;
        let ones = vec![1.0; n];
        let a: Vec<f64> = (0..n).map(|i| (i as f64 * 0.07).sin()).collect();
        let b: Vec<f64> = (0..n).map(|i| (i as f64 * 0.013).cos()).collect();
        let y: Vec<f64> = (0..n)
            .map(|i| 2.0 + 0.8 * a[i] - 1.3 * b[i] + 0.1 * ((i * 31 % 13) as f64 - 6.0))
            .collect();
        let kept = NormalEquations::new(&[&ones, &a], &y);
        let (beta, sse) = kept.fit_with(&[&b]).unwrap();
        let (whole_beta, whole_sse) = least_squares(&[&ones, &a, &b], &y).unwrap();
        for (x, w) in beta.iter().zip(&whole_beta) {
            assert!((x - w).abs() < 1e-10, "{beta:?} vs {whole_beta:?}");
        }
        assert!(
            (sse - whole_sse).abs() < 1e-9 * whole_sse,
            "{sse} vs {whole_sse}"
        );
        let (_, alone) = kept.fit_with(&[]).unwrap();
        let (_, whole_alone) = least_squares(&[&ones, &a], &y).unwrap();
        assert!((alone - whole_alone).abs() < 1e-9 * whole_alone);
    }

    /// The sufficient-statistics CV equals refitting each fold explicitly.
    #[test]
    fn blocked_cv_by_statistics_matches_explicit_refits() {
        let n = 240;
        let x: Vec<f64> = (0..n).map(|i| ((i * 37) % 17) as f64 - 8.0).collect();
        let ones = vec![1.0; n];
        let y: Vec<f64> = (0..n)
            .map(|i| 1.5 + 0.7 * x[i] + (((i * 13) % 7) as f64 - 3.0) * 0.3)
            .collect();
        let blocks = Blocks::new(n, 4, 3);
        let model = ModelGram::new(&[&ones, &x], &blocks);
        let products = TargetProducts::new(&[&ones, &x], &y, &blocks);
        let stats = products.stats();
        let sse = model.cv_sse(&stats, &blocks).unwrap();
        let mut explicit = 0.0;
        for fold in &blocks.folds {
            let excluded_rows =
                blocks.ranges[fold.excluded.start].start..blocks.ranges[fold.excluded.end - 1].end;
            let test_rows =
                blocks.ranges[fold.test.start].start..blocks.ranges[fold.test.end - 1].end;
            let train: Vec<usize> = (0..n).filter(|i| !excluded_rows.contains(i)).collect();
            let (mx, my) = (
                train.iter().map(|&i| x[i]).sum::<f64>() / train.len() as f64,
                train.iter().map(|&i| y[i]).sum::<f64>() / train.len() as f64,
            );
            let sxy: f64 = train.iter().map(|&i| (x[i] - mx) * (y[i] - my)).sum();
            let sxx: f64 = train.iter().map(|&i| (x[i] - mx) * (x[i] - mx)).sum();
            let slope = sxy / sxx;
            let intercept = my - slope * mx;
            explicit += test_rows
                .map(|i| (y[i] - intercept - slope * x[i]).powi(2))
                .sum::<f64>();
        }
        assert!(
            (sse - explicit).abs() < 1e-8 * explicit,
            "{sse} vs {explicit}"
        );
        let per_block: f64 = model.cv_block_sse(&stats, &blocks).unwrap().iter().sum();
        assert!((per_block - sse).abs() < 1e-8 * sse);
    }
}
