//! The terms language: regressors written as text and computed from recording columns.
//!
//! A terms string is a comma-separated list, e.g.
//! `"X.stator_temp_C, X.torque_Nm^3, X.speed_rpm*X.torque_Nm, lowpass(X.torque_Nm*X.speed_rpm,600)"`.
//!
//! | form | meaning |
//! |---|---|
//! | `a` | the column `a` (any name without `, * ^ ( )`: dots, `#`, `_` are fine) |
//! | `a^N` | `a` to the power `N`, an integer from 1 to 9 (the paper uses 2 and 3) |
//! | `a*b`, `a*b*c` | elementwise products (interactions) |
//! | `lag(a,SECONDS)` | `a` as it was `SECONDS` earlier, linearly interpolated in `time_s`; rows whose lag reaches back before the first sample have no value and are left out of the fit |
//! | `lowpass(a,TAU)` | first-order exponential accumulation with time constant `TAU` seconds (Eq. 10) |
//! | `delta(a)` | `a` minus its value in the first row (Eq. 15's ΔT) |
//! | `const` | the intercept: always in the model, may be listed, never twice |
//! | `( … )` | grouping, e.g. `(a*b)^2` |
//!
//! Functions take any expression, so the paper's bearing heat (Eqs. 10–11, heat input ∝
//! torque × speed, accumulated) is `lowpass(X.torque_Nm*X.speed_rpm,600)`.
//!
//! Each term has a canonical name (spaces removed, numbers printed shortest), used in every
//! report: `lag( X.speed_rpm , 30.0 )` is reported as `lag(X.speed_rpm,30)`.

use std::fmt;

use super::error::{FitError, TermError};
use crate::signal::Recording;

/// The name of the intercept term.
pub const INTERCEPT: &str = "const";

/// Highest power `a^N` accepts. The paper needs cubes; higher powers of uncentred temperatures
/// are numerically hopeless and physically meaningless.
pub const MAX_POWER: u32 = 9;

/// A regressor expression over recording columns.
#[derive(Debug, Clone, PartialEq)]
pub enum Expr {
    /// A recording column by name.
    Column(String),
    /// `base^exponent`.
    Power {
        /// The expression raised to the power.
        base: Box<Expr>,
        /// The integer exponent, 1 to [`MAX_POWER`].
        exponent: u32,
    },
    /// The elementwise product of two or more factors (never nested: `(a*b)*c` is flattened).
    Product(Vec<Expr>),
    /// The expression `seconds` earlier, interpolated in time.
    Lag {
        /// The lagged expression.
        of: Box<Expr>,
        /// How far back, in seconds (≥ 0).
        seconds: f64,
    },
    /// First-order exponential accumulation (a first-order lowpass) with time constant `tau_s`.
    Lowpass {
        /// The accumulated expression.
        of: Box<Expr>,
        /// The time constant in seconds (> 0).
        tau_s: f64,
    },
    /// The expression minus its first value.
    Delta(Box<Expr>),
}

impl fmt::Display for Expr {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Expr::Column(name) => f.write_str(name),
            Expr::Power { base, exponent } => match **base {
                Expr::Product(_) | Expr::Power { .. } => write!(f, "({base})^{exponent}"),
                _ => write!(f, "{base}^{exponent}"),
            },
            Expr::Product(factors) => {
                for (i, factor) in factors.iter().enumerate() {
                    if i > 0 {
                        f.write_str("*")?;
                    }
                    write!(f, "{factor}")?;
                }
                Ok(())
            }
            Expr::Lag { of, seconds } => write!(f, "lag({of},{seconds})"),
            Expr::Lowpass { of, tau_s } => write!(f, "lowpass({of},{tau_s})"),
            Expr::Delta(of) => write!(f, "delta({of})"),
        }
    }
}

impl Expr {
    /// The recording columns this expression reads, in first-use order, without repeats.
    pub fn columns(&self) -> Vec<&str> {
        let mut out = Vec::new();
        self.collect_columns(&mut out);
        out
    }

    fn collect_columns<'a>(&'a self, out: &mut Vec<&'a str>) {
        match self {
            Expr::Column(name) => {
                if !out.contains(&name.as_str()) {
                    out.push(name);
                }
            }
            Expr::Power { base, .. } => base.collect_columns(out),
            Expr::Product(factors) => factors.iter().for_each(|f| f.collect_columns(out)),
            Expr::Lag { of, .. } | Expr::Lowpass { of, .. } | Expr::Delta(of) => {
                of.collect_columns(out)
            }
        }
    }

    /// A key equal for expressions that compute the same thing up to the order of product
    /// factors (`a*b` and `b*a`), used to refuse a term listed twice in another spelling.
    pub fn identity_key(&self) -> String {
        match self {
            Expr::Product(factors) => {
                let mut keys: Vec<String> = factors.iter().map(Expr::identity_key).collect();
                keys.sort_unstable();
                format!("({})", keys.join("*"))
            }
            Expr::Power { base, exponent } => format!("({})^{exponent}", base.identity_key()),
            Expr::Lag { of, seconds } => format!("lag({},{seconds})", of.identity_key()),
            Expr::Lowpass { of, tau_s } => format!("lowpass({},{tau_s})", of.identity_key()),
            Expr::Delta(of) => format!("delta({})", of.identity_key()),
            Expr::Column(name) => format!("[{name}]"),
        }
    }

    /// Computes the expression for every row of `recording`. Rows where a lag reaches back
    /// before the first sample are NaN. `term` names the whole term in missing-column errors.
    pub fn evaluate(&self, recording: &Recording, term: &str) -> Result<Vec<f64>, FitError> {
        Ok(match self {
            Expr::Column(name) => recording
                .column_for(name, &format!("term `{term}`"))?
                .to_vec(),
            Expr::Power { base, exponent } => {
                let mut values = base.evaluate(recording, term)?;
                let exponent = *exponent as i32;
                values.iter_mut().for_each(|v| *v = v.powi(exponent));
                values
            }
            Expr::Product(factors) => {
                let mut factors = factors.iter();
                let mut values = match factors.next() {
                    Some(first) => first.evaluate(recording, term)?,
                    None => vec![1.0; recording.len()],
                };
                for factor in factors {
                    let other = factor.evaluate(recording, term)?;
                    values.iter_mut().zip(&other).for_each(|(v, o)| *v *= o);
                }
                values
            }
            Expr::Lag { of, seconds } => {
                lag_series(recording.time(), &of.evaluate(recording, term)?, *seconds)
            }
            Expr::Lowpass { of, tau_s } => {
                lowpass_series(recording.time(), &of.evaluate(recording, term)?, *tau_s)
            }
            Expr::Delta(of) => delta_series(&of.evaluate(recording, term)?),
        })
    }
}

/// One regressor: its expression and canonical name.
#[derive(Debug, Clone, PartialEq)]
pub struct Term {
    name: String,
    expr: Expr,
}

impl Term {
    /// A term from an expression; the name is the expression's canonical text.
    pub fn new(expr: Expr) -> Term {
        Term {
            name: expr.to_string(),
            expr,
        }
    }

    /// A term that is just a column.
    pub fn column(name: &str) -> Term {
        Term::new(Expr::Column(name.to_string()))
    }

    /// Parses a single term (no commas at the top level; `const` is not a term here).
    pub fn parse(text: &str) -> Result<Term, TermError> {
        let mut terms = parse_terms(text)?;
        match (terms.len(), terms.pop()) {
            (1, Some(term)) => Ok(term),
            _ => Err(TermError {
                term: text.trim().to_string(),
                position: 1,
                message: "expected exactly one term other than `const`".to_string(),
            }),
        }
    }

    /// The canonical name, as reported.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The expression.
    pub fn expr(&self) -> &Expr {
        &self.expr
    }

    /// Computes the term for every row of `recording` (NaN where a lag has no value).
    pub fn evaluate(&self, recording: &Recording) -> Result<Vec<f64>, FitError> {
        self.expr.evaluate(recording, &self.name)
    }
}

impl fmt::Display for Term {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.name)
    }
}

/// Parses a comma-separated terms string. `const` may appear (once); it is not returned because
/// the intercept is always part of the model. An empty list, an empty item, a term listed twice
/// or any malformed term is an error naming the term and the character position.
pub fn parse_terms(text: &str) -> Result<Vec<Term>, TermError> {
    if text.trim().is_empty() {
        return Err(TermError {
            term: String::new(),
            position: 1,
            message: "no terms: list at least one, e.g. `a,b,a^2,a*b`".to_string(),
        });
    }
    let mut parser = Parser {
        chars: text.chars().collect(),
        pos: 0,
    };
    let mut terms: Vec<Term> = Vec::new();
    let mut saw_intercept = false;
    loop {
        parser.skip_spaces();
        let start = parser.pos;
        let item = parser.item().map_err(|e| parser.error_in_item(start, e))?;
        parser.skip_spaces();
        match item {
            None if saw_intercept => {
                return Err(parser.error_in_item(start, located(start, "`const` is listed twice")));
            }
            None => saw_intercept = true,
            Some(expr) => {
                let term = Term::new(expr);
                let key = term.expr.identity_key();
                if let Some(earlier) = terms.iter().find(|t| t.expr.identity_key() == key) {
                    let message = if earlier.name == term.name {
                        format!("`{}` is listed twice", term.name)
                    } else {
                        format!(
                            "`{}` is listed twice (also as `{}`)",
                            term.name, earlier.name
                        )
                    };
                    return Err(parser.error_in_item(start, located(start, &message)));
                }
                terms.push(term);
            }
        }
        match parser.peek() {
            None => break,
            Some(',') => parser.pos += 1,
            Some(c) => {
                let at = parser.pos;
                return Err(parser.error_in_item(
                    start,
                    located(at, &format!("unexpected `{c}`: expected `,`, `*` or `^`")),
                ));
            }
        }
    }
    Ok(terms)
}

/// A parse problem before it is attached to its term: 0-based character index and message.
struct Located {
    at: usize,
    message: String,
}

fn located(at: usize, message: &str) -> Located {
    Located {
        at,
        message: message.to_string(),
    }
}

/// Characters that end a column name.
fn is_delimiter(c: char) -> bool {
    matches!(c, ',' | '*' | '^' | '(' | ')')
}

struct Parser {
    chars: Vec<char>,
    pos: usize,
}

impl Parser {
    fn peek(&self) -> Option<char> {
        self.chars.get(self.pos).copied()
    }

    fn skip_spaces(&mut self) {
        while self.peek().is_some_and(char::is_whitespace) {
            self.pos += 1;
        }
    }

    /// The text of the top-level item that starts at `start`, for error messages.
    fn item_text(&self, start: usize) -> String {
        let mut depth = 0usize;
        let mut end = start;
        while let Some(&c) = self.chars.get(end) {
            match c {
                '(' => depth += 1,
                ')' => depth = depth.saturating_sub(1),
                ',' if depth == 0 => break,
                _ => {}
            }
            end += 1;
        }
        self.chars[start.min(end)..end]
            .iter()
            .collect::<String>()
            .trim()
            .to_string()
    }

    fn error_in_item(&self, start: usize, problem: Located) -> TermError {
        TermError {
            term: self.item_text(start),
            position: problem.at + 1,
            message: problem.message,
        }
    }

    /// One list item: `None` for `const`, else the expression.
    fn item(&mut self) -> Result<Option<Expr>, Located> {
        let save = self.pos;
        let word = self.name();
        self.skip_spaces();
        if word == INTERCEPT && matches!(self.peek(), None | Some(',')) {
            return Ok(None);
        }
        self.pos = save;
        self.product().map(Some)
    }

    /// A run of non-delimiter characters, trimmed.
    fn name(&mut self) -> String {
        let start = self.pos;
        while self.peek().is_some_and(|c| !is_delimiter(c)) {
            self.pos += 1;
        }
        self.chars[start..self.pos]
            .iter()
            .collect::<String>()
            .trim()
            .to_string()
    }

    fn product(&mut self) -> Result<Expr, Located> {
        let mut factors = Vec::new();
        loop {
            match self.factor()? {
                Expr::Product(inner) => factors.extend(inner),
                other => factors.push(other),
            }
            self.skip_spaces();
            if self.peek() == Some('*') {
                self.pos += 1;
            } else {
                break;
            }
        }
        Ok(if factors.len() == 1 {
            factors.remove(0)
        } else {
            Expr::Product(factors)
        })
    }

    fn factor(&mut self) -> Result<Expr, Located> {
        let base = self.primary()?;
        self.skip_spaces();
        if self.peek() != Some('^') {
            return Ok(base);
        }
        self.pos += 1;
        self.skip_spaces();
        let start = self.pos;
        while self.peek().is_some_and(|c| c.is_ascii_digit()) {
            self.pos += 1;
        }
        let digits: String = self.chars[start..self.pos].iter().collect();
        match digits.parse::<u32>() {
            Ok(exponent) if (1..=MAX_POWER).contains(&exponent) => Ok(Expr::Power {
                base: Box::new(base),
                exponent,
            }),
            _ => Err(located(
                start,
                &format!("expected a whole power from 1 to {MAX_POWER} after `^`"),
            )),
        }
    }

    fn primary(&mut self) -> Result<Expr, Located> {
        self.skip_spaces();
        let start = self.pos;
        if self.peek() == Some('(') {
            self.pos += 1;
            let inner = self.product()?;
            self.expect(')', "to close the group")?;
            return Ok(inner);
        }
        let word = self.name();
        if word.is_empty() {
            return Err(located(
                start,
                match self.peek() {
                    None => "expected a column name, found the end of the terms",
                    Some(',') => "expected a column name, found `,` (an empty term)",
                    Some(_) => "expected a column name",
                },
            ));
        }
        self.skip_spaces();
        if self.peek() == Some('(') {
            self.pos += 1;
            return self.call(&word, start);
        }
        if word == INTERCEPT {
            return Err(located(
                start,
                "`const` is the intercept and must stand alone as a term",
            ));
        }
        Ok(Expr::Column(word))
    }

    fn expect(&mut self, wanted: char, purpose: &str) -> Result<(), Located> {
        self.skip_spaces();
        if self.peek() == Some(wanted) {
            self.pos += 1;
            Ok(())
        } else {
            let found = match self.peek() {
                Some(c) => format!("`{c}`"),
                None => "the end of the terms".to_string(),
            };
            Err(located(
                self.pos,
                &format!("expected `{wanted}` {purpose}, found {found}"),
            ))
        }
    }

    /// `lag(expr,SECONDS)`, `lowpass(expr,TAU)`, `delta(expr)`; the `(` is consumed.
    fn call(&mut self, function: &str, start: usize) -> Result<Expr, Located> {
        match function {
            "lag" => {
                let of = Box::new(self.product()?);
                self.expect(',', "and then the lag in seconds")?;
                let seconds = self.number("the lag in seconds", |s| s >= 0.0, "≥ 0")?;
                self.expect(')', "to close `lag(`")?;
                Ok(Expr::Lag { of, seconds })
            }
            "lowpass" => {
                let of = Box::new(self.product()?);
                self.expect(',', "and then the time constant in seconds")?;
                let tau_s = self.number("the time constant in seconds", |s| s > 0.0, "> 0")?;
                self.expect(')', "to close `lowpass(`")?;
                Ok(Expr::Lowpass { of, tau_s })
            }
            "delta" => {
                let of = Box::new(self.product()?);
                self.expect(')', "to close `delta(` (it takes one argument)")?;
                Ok(Expr::Delta(of))
            }
            other => Err(located(
                start,
                &format!("unknown function `{other}`: expected `lag`, `lowpass` or `delta`"),
            )),
        }
    }

    fn number(
        &mut self,
        what: &str,
        valid: impl Fn(f64) -> bool,
        requirement: &str,
    ) -> Result<f64, Located> {
        self.skip_spaces();
        let start = self.pos;
        while self.peek().is_some_and(|c| c != ')' && c != ',') {
            self.pos += 1;
        }
        let text: String = self.chars[start..self.pos].iter().collect();
        let text = text.trim();
        match text.parse::<f64>() {
            Ok(value) if value.is_finite() && valid(value) => Ok(value),
            Ok(_) => Err(located(
                start,
                &format!("{what} must be a finite number {requirement}, found `{text}`"),
            )),
            Err(_) => Err(located(
                start,
                &format!("expected {what} (a number), found `{text}`"),
            )),
        }
    }
}

/// `values` as they were `seconds` earlier: at row `i`, the value at time `time[i] - seconds`,
/// linearly interpolated between the two samples around it, so the lag means the same at any
/// sample rate. Rows whose lagged time falls before `time[0]` are NaN (no value exists).
/// `time` must be non-decreasing (a [`Recording`] guarantees it).
pub fn lag_series(time: &[f64], values: &[f64], seconds: f64) -> Vec<f64> {
    let mut out = vec![f64::NAN; values.len()];
    let Some(&first_time) = time.first() else {
        return out;
    };
    // `j` is the last sample with time ≤ the lagged time; it only moves forward.
    let mut j = 0usize;
    for (i, slot) in out.iter_mut().enumerate() {
        let wanted = time[i] - seconds;
        if wanted < first_time {
            continue;
        }
        while j + 1 < time.len() && time[j + 1] <= wanted {
            j += 1;
        }
        *slot = if time[j] == wanted || j + 1 == time.len() {
            values[j]
        } else {
            let fraction = (wanted - time[j]) / (time[j + 1] - time[j]);
            values[j] + fraction * (values[j + 1] - values[j])
        };
    }
    out
}

/// First-order exponential accumulation of `values` with time constant `tau_s` (the paper's
/// Eq. 10, `H ← H(1 − C) + C·H′`), discretised exactly for the actual time step of each row:
/// `C = 1 − exp(−Δt/τ)`. This is the paper's "C_BH adjusted by the ratio of sampling
/// frequencies", done per sample, so irregular or different sample rates give the same heat.
///
/// The state starts at the first value (the system is assumed in equilibrium when the
/// recording starts); leading NaNs (from a lag inside) stay NaN and the state starts at the
/// first number.
pub fn lowpass_series(time: &[f64], values: &[f64], tau_s: f64) -> Vec<f64> {
    let mut out = Vec::with_capacity(values.len());
    let mut state: Option<(f64, f64)> = None; // (time, accumulated value)
    for (&t, &u) in time.iter().zip(values) {
        let next = match state {
            _ if u.is_nan() => None,
            None => Some((t, u)),
            Some((t_previous, h)) => {
                let gain = -(-(t - t_previous) / tau_s).exp_m1();
                Some((t, h + gain * (u - h)))
            }
        };
        match next {
            Some((_, h)) => {
                out.push(h);
                state = next;
            }
            None => out.push(f64::NAN),
        }
    }
    out
}

/// `values` minus the first value that is a number (Eq. 15's ΔT: change since calibration).
pub fn delta_series(values: &[f64]) -> Vec<f64> {
    let reference = values.iter().copied().find(|v| !v.is_nan());
    match reference {
        Some(first) => values.iter().map(|v| v - first).collect(),
        None => values.to_vec(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(text: &str) -> Vec<String> {
        parse_terms(text)
            .unwrap()
            .iter()
            .map(|t| t.name().to_string())
            .collect()
    }

    #[test]
    fn parses_every_form_and_normalises_names() {
        assert_eq!(
            names(
                " a , b ,a^2, a * b*c ,lag( X.speed_rpm , 30.0 ),lowpass(S.stator_temp_C,600),delta(S.stator_temp_C)"
            ),
            [
                "a",
                "b",
                "a^2",
                "a*b*c",
                "lag(X.speed_rpm,30)",
                "lowpass(S.stator_temp_C,600)",
                "delta(S.stator_temp_C)"
            ]
        );
    }

    #[test]
    fn column_names_keep_dots_hashes_and_underscores() {
        let terms =
            parse_terms("ref.X.straightness_h_um#3^3, X.torque_Nm*ref.X.nut_temp_C").unwrap();
        assert_eq!(
            terms[0].expr(),
            &Expr::Power {
                base: Box::new(Expr::Column("ref.X.straightness_h_um#3".into())),
                exponent: 3
            }
        );
        assert_eq!(
            terms[1].expr().columns(),
            ["X.torque_Nm", "ref.X.nut_temp_C"]
        );
    }

    #[test]
    fn intercept_may_be_listed_once_and_is_not_returned() {
        assert_eq!(names("const,a"), ["a"]);
        assert_eq!(names("a, const"), ["a"]);
        let err = parse_terms("const,a,const").unwrap_err();
        assert_eq!(err.position, 9, "{err}");
        let err = parse_terms("a*const").unwrap_err();
        assert!(err.message.contains("stand alone"), "{err}");
    }

    #[test]
    fn nested_and_grouped_expressions() {
        assert_eq!(
            names("lowpass(X.torque_Nm*X.speed_rpm,600),(a*b)^2,lag(delta(a),0.5),(a)"),
            [
                "lowpass(X.torque_Nm*X.speed_rpm,600)",
                "(a*b)^2",
                "lag(delta(a),0.5)",
                "a"
            ]
        );
    }

    #[test]
    fn malformed_terms_name_the_term_and_position() {
        let cases = [
            ("a,,b", "", 3, "empty term"),
            ("a,lag(b,)", "lag(b,)", 9, "lag in seconds"),
            ("a,lag(b,-3)", "lag(b,-3)", 9, "≥ 0"),
            ("a,lowpass(b,0)", "lowpass(b,0)", 13, "> 0"),
            ("a^4x", "a^4x", 4, "unexpected `x`"),
            ("a^0", "a^0", 3, "whole power"),
            ("a^", "a^", 3, "whole power"),
            ("a*", "a*", 3, "end of the terms"),
            ("foo(a)", "foo(a)", 1, "unknown function `foo`"),
            ("lag(a,3", "lag(a,3", 8, "close `lag(`"),
            ("delta(a,3)", "delta(a,3)", 8, "one argument"),
            ("b,a,b", "b", 5, "listed twice"),
            ("a,b*a, a*b", "a*b", 8, "listed twice"),
            ("(a*b", "(a*b", 5, "close the group"),
            ("a)", "a)", 2, "unexpected `)`"),
            ("", "", 1, "no terms"),
        ];
        for (text, term, position, needle) in cases {
            let err = parse_terms(text).unwrap_err();
            assert_eq!(
                (err.term.as_str(), err.position),
                (term, position),
                "{text}: {err}"
            );
            assert!(err.to_string().contains(needle), "{text}: {err}");
        }
    }

    #[test]
    fn lag_interpolates_in_time_and_is_undefined_before_the_start() {
        let time = [0.0, 1.0, 2.0, 4.0, 5.0];
        let values = [0.0, 10.0, 20.0, 40.0, 50.0];
        let lagged = lag_series(&time, &values, 1.5);
        assert!(lagged[0].is_nan() && lagged[1].is_nan());
        assert_eq!(&lagged[2..], &[5.0, 25.0, 35.0]);
        assert_eq!(lag_series(&time, &values, 0.0), values);
    }

    #[test]
    fn lowpass_is_independent_of_the_sample_rate() {
        // A unit step at t = 0 through τ = 10 s: after 10 s the state is 1 − e⁻¹, whatever dt.
        for dt in [0.01f64, 0.1, 1.0, 2.5] {
            let n = (10.0 / dt).round() as usize + 1;
            let time: Vec<f64> = (0..n).map(|i| i as f64 * dt).collect();
            let mut input = vec![1.0; n];
            input[0] = 0.0;
            let out = lowpass_series(&time, &input, 10.0);
            // The step arrives in the sample after t = 0 and is held for that whole step.
            let expected = 1.0 - (-(10.0 - 0.0) / 10.0f64).exp();
            assert!(
                (out[n - 1] - expected).abs() < 1e-10,
                "dt {dt}: {}",
                out[n - 1]
            );
        }
    }

    #[test]
    fn lowpass_skips_leading_nans_and_delta_subtracts_the_first_number() {
        let out = lowpass_series(&[0.0, 1.0, 2.0], &[f64::NAN, 4.0, 4.0], 5.0);
        assert!(out[0].is_nan());
        assert_eq!(&out[1..], &[4.0, 4.0]);
        assert_eq!(delta_series(&[f64::NAN, 3.0, 5.0])[1..], [0.0, 2.0]);
    }

    proptest::proptest! {
        /// Whatever is typed: no panic, an error position inside the text (or just after it),
        /// and any accepted list reparses from its canonical names to the same terms.
        #[test]
        fn parser_is_total_and_canonical_names_round_trip(
            text in "[abc.#_, *^()0-9]{0,12}|(lag|lowpass|delta)\\([abc*^0-9,. ]{0,10}\\)"
        ) {
            match parse_terms(&text) {
                Ok(terms) => {
                    let canonical: Vec<&str> = terms.iter().map(Term::name).collect();
                    if !canonical.is_empty() {
                        let again = parse_terms(&canonical.join(",")).unwrap();
                        proptest::prop_assert_eq!(again, terms);
                    }
                }
                Err(error) => {
                    proptest::prop_assert!(error.position >= 1);
                    proptest::prop_assert!(error.position <= text.chars().count() + 1);
                }
            }
        }
    }
}
