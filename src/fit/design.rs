//! The design matrix: the intercept and every term as columns, the target beside it.

use faer::Mat;

use super::error::FitError;
use super::terms::{INTERCEPT, Term};
use crate::signal::Recording;

/// A regression problem ready to fit: `y ≈ X β` with the intercept `const` as column 0.
///
/// Columns are stored column-major (one contiguous slice per term), which is what both the QR
/// factorisation and per-term statistics want. Rows are in time order, which time-blocked
/// cross-validation relies on.
#[derive(Debug, Clone)]
pub struct Design {
    target: String,
    terms: Vec<String>,
    x: Mat<f64>,
    y: Vec<f64>,
    time_s: Vec<f64>,
    rows_dropped: usize,
}

impl Design {
    /// Builds the design for `target` from the columns of `recording`.
    ///
    /// Every missing column is reported by name with the term that needed it. Rows where a
    /// `lag` term has no value (its lag reaches back before the first sample) are left out and
    /// counted in [`Design::rows_dropped`]. A term that overflows is an error naming it.
    pub fn from_recording(
        recording: &Recording,
        target: &str,
        terms: &[Term],
    ) -> Result<Design, FitError> {
        let y_all = recording.column_for(target, "the fit target")?;
        let mut columns = Vec::with_capacity(terms.len());
        for term in terms {
            if term.name() == target {
                return Err(FitError::TargetAsTerm {
                    target: target.to_string(),
                });
            }
            columns.push(term.evaluate(recording)?);
        }
        // A row is usable when every term has a value there; only lags leave holes, and
        // anything else that is not finite is an overflow worth naming.
        let time = recording.time();
        let mut usable = vec![true; recording.len()];
        for (term, values) in terms.iter().zip(&columns) {
            for (row, value) in values.iter().enumerate() {
                if value.is_nan() {
                    usable[row] = false;
                } else if !value.is_finite() {
                    return Err(FitError::NonFinite {
                        term: term.name().to_string(),
                        row,
                        time_s: time[row],
                    });
                }
            }
        }
        refuse_too_large(target, y_all)?;
        for (term, values) in terms.iter().zip(&columns) {
            refuse_too_large(term.name(), values)?;
        }
        let kept: Vec<usize> = (0..recording.len()).filter(|&i| usable[i]).collect();
        let n = kept.len();
        let p = terms.len() + 1;
        let mut x = Mat::<f64>::zeros(n, p);
        x.col_as_slice_mut(0).fill(1.0);
        for (j, values) in columns.iter().enumerate() {
            let out = x.col_as_slice_mut(j + 1);
            for (slot, &row) in out.iter_mut().zip(&kept) {
                *slot = values[row];
            }
        }
        let mut names = vec![INTERCEPT.to_string()];
        names.extend(terms.iter().map(|t| t.name().to_string()));
        Ok(Design {
            target: target.to_string(),
            terms: names,
            x,
            y: kept.iter().map(|&i| y_all[i]).collect(),
            time_s: kept.iter().map(|&i| time[i]).collect(),
            rows_dropped: recording.len() - n,
        })
    }

    /// Builds a design from named columns already computed (the intercept is added as column
    /// 0). Rows are taken to be in time order with unit spacing. Names must be unique and must
    /// not be `const`; every column must have as many values as `y`, all finite.
    pub fn from_columns(
        target: &str,
        y: Vec<f64>,
        columns: Vec<(String, Vec<f64>)>,
    ) -> Result<Design, FitError> {
        let n = y.len();
        let p = columns.len() + 1;
        let mut names = vec![INTERCEPT.to_string()];
        let mut x = Mat::<f64>::zeros(n, p);
        x.col_as_slice_mut(0).fill(1.0);
        if let Some(row) = y.iter().position(|v| !v.is_finite()) {
            return Err(FitError::NonFinite {
                term: target.to_string(),
                row,
                time_s: row as f64,
            });
        }
        refuse_too_large(target, &y)?;
        for (j, (name, values)) in columns.into_iter().enumerate() {
            if names.contains(&name) {
                return Err(FitError::RepeatedTerm { term: name });
            }
            if values.len() != n {
                return Err(FitError::Dimension {
                    what: "a design column",
                    expected: n,
                    found: values.len(),
                });
            }
            if let Some(row) = values.iter().position(|v| !v.is_finite()) {
                return Err(FitError::NonFinite {
                    term: name,
                    row,
                    time_s: row as f64,
                });
            }
            refuse_too_large(&name, &values)?;
            x.col_as_slice_mut(j + 1).copy_from_slice(&values);
            names.push(name);
        }
        Ok(Design {
            target: target.to_string(),
            terms: names,
            x,
            y,
            time_s: (0..n).map(|i| i as f64).collect(),
            rows_dropped: 0,
        })
    }

    /// The target's name.
    pub fn target(&self) -> &str {
        &self.target
    }

    /// Term names; `terms()[0]` is `const`.
    pub fn terms(&self) -> &[String] {
        &self.terms
    }

    /// The index of a term's column.
    pub fn term_index(&self, name: &str) -> Option<usize> {
        self.terms.iter().position(|t| t == name)
    }

    /// Number of rows (observations).
    pub fn n_rows(&self) -> usize {
        self.y.len()
    }

    /// Number of columns (coefficients), the intercept included.
    pub fn n_coefficients(&self) -> usize {
        self.terms.len()
    }

    /// The design matrix `X` (rows × coefficients).
    pub fn x(&self) -> faer::MatRef<'_, f64> {
        self.x.as_ref()
    }

    /// One column of `X`.
    pub fn column(&self, j: usize) -> &[f64] {
        self.x.col_as_slice(j)
    }

    /// The target values.
    pub fn y(&self) -> &[f64] {
        &self.y
    }

    /// The time of each row, seconds.
    pub fn time_s(&self) -> &[f64] {
        &self.time_s
    }

    /// Rows of the recording left out because a lag had no value there.
    pub fn rows_dropped(&self) -> usize {
        self.rows_dropped
    }

    /// Copies row `i` of `X` into `out` (cleared first): the regressor vector an online
    /// estimator or [`super::RecursiveLeastSquares`] takes.
    pub fn row_into(&self, i: usize, out: &mut Vec<f64>) {
        out.clear();
        out.extend((0..self.terms.len()).map(|j| self.x[(i, j)]));
    }

    /// The design with only the intercept and the given term columns (indices into
    /// [`Design::terms`]; 0, the intercept, is always kept and need not be listed).
    pub fn with_terms(&self, columns: &[usize]) -> Design {
        let mut chosen = vec![0usize];
        chosen.extend(columns.iter().copied().filter(|&j| j != 0));
        let n = self.n_rows();
        let mut x = Mat::<f64>::zeros(n, chosen.len());
        for (k, &j) in chosen.iter().enumerate() {
            x.col_as_slice_mut(k).copy_from_slice(self.column(j));
        }
        Design {
            target: self.target.clone(),
            terms: chosen.iter().map(|&j| self.terms[j].clone()).collect(),
            x,
            y: self.y.clone(),
            time_s: self.time_s.clone(),
            rows_dropped: self.rows_dropped,
        }
    }

    /// The whitened design of a weighted fit: every row of `X` and `y` multiplied by √wᵢ.
    /// `weights` must have one entry per row (checked by the caller, [`super::wls`]).
    pub(crate) fn with_row_scales(&self, weights: &[f64]) -> Design {
        let scales: Vec<f64> = weights.iter().map(|w| w.sqrt()).collect();
        let mut x = self.x.clone();
        for j in 0..self.n_coefficients() {
            for (v, s) in x.col_as_slice_mut(j).iter_mut().zip(&scales) {
                *v *= s;
            }
        }
        Design {
            target: self.target.clone(),
            terms: self.terms.clone(),
            x,
            y: self.y.iter().zip(&scales).map(|(y, s)| y * s).collect(),
            time_s: self.time_s.clone(),
            rows_dropped: self.rows_dropped,
        }
    }

    /// The design restricted to the rows for which `keep(row)` is true (order kept).
    pub fn with_rows(&self, keep: impl Fn(usize) -> bool) -> Design {
        let rows: Vec<usize> = (0..self.n_rows()).filter(|&i| keep(i)).collect();
        let p = self.n_coefficients();
        let mut x = Mat::<f64>::zeros(rows.len(), p);
        for j in 0..p {
            let source = self.column(j);
            for (slot, &i) in x.col_as_slice_mut(j).iter_mut().zip(&rows) {
                *slot = source[i];
            }
        }
        Design {
            target: self.target.clone(),
            terms: self.terms.clone(),
            x,
            y: rows.iter().map(|&i| self.y[i]).collect(),
            time_s: rows.iter().map(|&i| self.time_s[i]).collect(),
            rows_dropped: self.rows_dropped,
        }
    }
}

/// Largest magnitude a fitted value may have: squared and summed over a billion rows it stays
/// finite (1e100² × 1e9 = 1e209), so every sum of squares behind R², F and the standard errors
/// does too.
const MAX_MAGNITUDE: f64 = 1e100;

/// Refuses a column holding a value beyond [`MAX_MAGNITUDE`] (NaN, a lag's hole, is left to
/// the caller).
fn refuse_too_large(column: &str, values: &[f64]) -> Result<(), FitError> {
    match values.iter().position(|v| v.abs() > MAX_MAGNITUDE) {
        Some(row) => Err(FitError::TooLarge {
            column: column.to_string(),
            row,
            value: values[row],
        }),
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::terms::parse_terms;

    fn recording() -> Recording {
        let mut rec = Recording::new(
            "db.csv",
            ["time_s", "X.speed_rpm", "ref.X.nut_temp_C"]
                .map(String::from)
                .to_vec(),
        )
        .unwrap();
        for i in 0..6 {
            let t = i as f64;
            rec.push_row(&[t, 100.0 * t, 20.0 + t]).unwrap();
        }
        rec
    }

    #[test]
    fn builds_columns_and_drops_rows_a_lag_cannot_fill() {
        let terms = parse_terms("X.speed_rpm^2,lag(X.speed_rpm,2)").unwrap();
        let design = Design::from_recording(&recording(), "ref.X.nut_temp_C", &terms).unwrap();
        assert_eq!(
            design.terms(),
            ["const", "X.speed_rpm^2", "lag(X.speed_rpm,2)"]
        );
        assert_eq!(design.rows_dropped(), 2);
        assert_eq!(design.n_rows(), 4);
        assert_eq!(design.column(0), [1.0; 4]);
        assert_eq!(design.column(1), [40000.0, 90000.0, 160000.0, 250000.0]);
        assert_eq!(design.column(2), [0.0, 100.0, 200.0, 300.0]);
        assert_eq!(design.y(), [22.0, 23.0, 24.0, 25.0]);
        assert_eq!(design.time_s(), [2.0, 3.0, 4.0, 5.0]);
    }

    #[test]
    fn missing_columns_are_named_with_the_term_that_needs_them() {
        let terms = parse_terms("X.speed_rpm,lowpass(X.torque_Nm,60)").unwrap();
        let err = Design::from_recording(&recording(), "ref.X.nut_temp_C", &terms).unwrap_err();
        assert_eq!(
            err.to_string(),
            "db.csv: no column `X.torque_Nm` (needed for term `lowpass(X.torque_Nm,60)`)"
        );
        let err = Design::from_recording(&recording(), "ref.X.flange_C", &terms).unwrap_err();
        assert_eq!(
            err.to_string(),
            "db.csv: no column `ref.X.flange_C` (needed for the fit target)"
        );
    }

    #[test]
    fn overflowing_terms_are_named() {
        let mut rec =
            Recording::new("big.csv", ["time_s", "a", "y"].map(String::from).to_vec()).unwrap();
        rec.push_row(&[0.0, 1e200, 1.0]).unwrap();
        let terms = parse_terms("a^2").unwrap();
        let err = Design::from_recording(&rec, "y", &terms).unwrap_err();
        assert!(
            err.to_string()
                .contains("term `a^2` is not a finite number at row 0"),
            "{err}"
        );
    }

    #[test]
    fn subsets_keep_the_intercept_and_order() {
        let terms = parse_terms("X.speed_rpm,X.speed_rpm^2").unwrap();
        let design = Design::from_recording(&recording(), "ref.X.nut_temp_C", &terms).unwrap();
        let only_square = design.with_terms(&[2]);
        assert_eq!(only_square.terms(), ["const", "X.speed_rpm^2"]);
        let late = design.with_rows(|i| i >= 4);
        assert_eq!(late.y(), [24.0, 25.0]);
        assert_eq!(late.column(1), [400.0, 500.0]);
        let mut row = Vec::new();
        design.row_into(3, &mut row);
        assert_eq!(row, [1.0, 300.0, 90000.0]);
    }
}
