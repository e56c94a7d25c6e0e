//! One-dimensional minimisation on an interval (Brent's method).
//!
//! The analyses here refine one nonlinear parameter at a time — a time constant, a delay, a
//! servo lag — where every evaluation of the error is costly (a correction rebuilt over a whole
//! recording). Brent's method fits a parabola through its last three points where the error is
//! smooth and falls back on golden-section steps where it is not, so it reaches a tolerance in
//! far fewer evaluations than a golden-section search on a smooth minimum (a parabola on
//! [−3, 5] to 10⁻⁴ in at most 8, against 25) and still converges on a rough one (R. P. Brent,
//! *Algorithms for Minimization without Derivatives*, 1973, ch. 5).

/// Where a search ended.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Minimum {
    /// The best argument evaluated.
    pub at: f64,
    /// The function's value there.
    pub value: f64,
    /// How many times the function was evaluated.
    pub evaluations: usize,
}

/// The squared conjugate of the golden ratio, (3 − √5) / 2: the share of an interval a
/// golden-section step moves into its larger part.
const GOLDEN_STEP: f64 = 0.381_966_011_250_105_1;

/// Enough for any tolerance above 10⁻¹⁵ of the interval: golden-section steps alone shrink it
/// by 0.618 per step.
const MAX_EVALUATIONS: usize = 100;

/// Finds a minimum of `f` between `low` and `high` (in either order) to within `tolerance`
/// (absolute, in the argument's units), evaluating `f` only inside the interval.
///
/// The result is a local minimum; it is the minimum on the interval when `f` has one there
/// (unimodal). A value that is not a number counts as worse than every number, so an
/// evaluation that fails (returns NaN or +∞) steers the search away rather than ending it.
/// An empty interval (`low == high`) or a tolerance that is not positive evaluates `f` once,
/// at `low`.
pub fn minimise_on_interval(
    mut f: impl FnMut(f64) -> f64,
    low: f64,
    high: f64,
    tolerance: f64,
) -> Minimum {
    let value_of = |v: f64| if v.is_nan() { f64::INFINITY } else { v };
    let (mut a, mut b) = (low.min(high), low.max(high));
    let searchable = tolerance > 0.0 && a < b && a.is_finite() && b.is_finite();
    if !searchable {
        return Minimum {
            at: low,
            value: value_of(f(low)),
            evaluations: 1,
        };
    }
    // x: the best point so far; w: the second best; v: the previous w.
    let mut x = a + GOLDEN_STEP * (b - a);
    let mut fx = value_of(f(x));
    let mut evaluations = 1;
    let (mut w, mut fw, mut v, mut fv) = (x, fx, x, fx);
    // d: the last step; e: the step before it (a parabolic step must be smaller than half of
    // it, or the search is not converging and takes a golden-section step instead).
    let (mut d, mut e) = (0.0_f64, 0.0_f64);
    while evaluations < MAX_EVALUATIONS {
        let middle = 0.5 * (a + b);
        let tol1 = tolerance + 1e-12 * x.abs();
        let tol2 = 2.0 * tol1;
        if (x - middle).abs() <= tol2 - 0.5 * (b - a) {
            break;
        }
        let mut golden = true;
        if e.abs() > tol1 && fx.is_finite() && fw.is_finite() && fv.is_finite() {
            let r = (x - w) * (fx - fv);
            let mut q = (x - v) * (fx - fw);
            let mut p = (x - v) * q - (x - w) * r;
            q = 2.0 * (q - r);
            if q > 0.0 {
                p = -p;
            }
            q = q.abs();
            let before = e;
            if p.abs() < (0.5 * q * before).abs() && p > q * (a - x) && p < q * (b - x) {
                e = d;
                d = p / q;
                let u = x + d;
                if u - a < tol2 || b - u < tol2 {
                    d = tol1.copysign(middle - x);
                }
                golden = false;
            }
        }
        if golden {
            e = if x >= middle { a - x } else { b - x };
            d = GOLDEN_STEP * e;
        }
        let u = if d.abs() >= tol1 {
            x + d
        } else {
            x + tol1.copysign(d)
        };
        let fu = value_of(f(u));
        evaluations += 1;
        if fu <= fx {
            if u >= x {
                a = x;
            } else {
                b = x;
            }
            (v, fv, w, fw, x, fx) = (w, fw, x, fx, u, fu);
        } else {
            if u < x {
                a = u;
            } else {
                b = u;
            }
            if fu <= fw || w == x {
                (v, fv, w, fw) = (w, fw, u, fu);
            } else if fu <= fv || v == x || v == w {
                (v, fv) = (u, fu);
            }
        }
    }
    Minimum {
        at: x,
        value: fx,
        evaluations,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// A parabola's minimum is found to the tolerance, in a handful of evaluations (its
    /// parabolic steps are exact): far fewer than the 25 a golden-section search needs to
    /// narrow [−3, 5] to 10⁻⁴.
    #[test]
    fn a_parabola_is_solved_in_a_few_evaluations() {
        let found = minimise_on_interval(|x| (x - 1.234).powi(2) + 7.0, -3.0, 5.0, 1e-4);
        assert!((found.at - 1.234).abs() < 2e-4, "{found:?}");
        assert!((found.value - 7.0).abs() < 1e-7, "{found:?}");
        assert!(found.evaluations <= 8, "{found:?}");
    }

    /// The closed forms of smooth, asymmetric minima: x·ln x at 1/e, and eˣ − 2x at ln 2.
    #[test]
    fn smooth_asymmetric_minima_match_their_closed_forms() {
        let found = minimise_on_interval(|x| x * x.ln(), 0.05, 3.0, 1e-6);
        assert!((found.at - (-1.0_f64).exp()).abs() < 3e-6, "{found:?}");
        let found = minimise_on_interval(|x| x.exp() - 2.0 * x, -2.0, 4.0, 1e-6);
        assert!((found.at - 2.0_f64.ln()).abs() < 3e-6, "{found:?}");
        assert!(found.evaluations < 20, "{found:?}");
    }

    /// A kink (|x − c|) defeats the parabolas; the golden-section fallback still converges.
    #[test]
    fn a_kinked_minimum_is_found_by_the_golden_section_fallback() {
        let found = minimise_on_interval(|x| (x - 0.3).abs(), -1.0, 1.0, 1e-5);
        assert!((found.at - 0.3).abs() < 3e-5, "{found:?}");
        assert!(found.evaluations < MAX_EVALUATIONS, "{found:?}");
    }

    /// A minimum at the interval's end is approached from inside; the function is never
    /// evaluated outside the interval, given in either order.
    #[test]
    fn a_falling_function_ends_at_the_upper_bound_without_leaving_the_interval() {
        let found = minimise_on_interval(
            |x| {
                assert!((2.0..=3.0).contains(&x), "evaluated outside at {x}");
                -x
            },
            3.0,
            2.0,
            1e-6,
        );
        assert!((found.at - 3.0).abs() < 1e-5, "{found:?}");
    }

    /// Failed evaluations (NaN, +∞) count as worse than any number.
    #[test]
    fn failed_evaluations_steer_the_search_away() {
        let found = minimise_on_interval(
            |x| if x > 0.8 { f64::NAN } else { (x - 0.5).powi(2) },
            0.0,
            1.0,
            1e-6,
        );
        assert!((found.at - 0.5).abs() < 1e-5, "{found:?}");
        let found = minimise_on_interval(
            |x| {
                if x < 0.2 {
                    f64::INFINITY
                } else {
                    (x - 0.6).powi(2)
                }
            },
            0.0,
            1.0,
            1e-6,
        );
        assert!((found.at - 0.6).abs() < 1e-5, "{found:?}");
    }

    /// An empty interval or a tolerance that is not positive evaluates once, at `low`.
    #[test]
    fn degenerate_requests_evaluate_once_at_the_lower_argument() {
        for (low, high, tolerance) in [(2.0, 2.0, 1e-3), (0.0, 1.0, 0.0), (0.0, 1.0, f64::NAN)] {
            let found = minimise_on_interval(|x| x * x, low, high, tolerance);
            assert_eq!(found.evaluations, 1);
            assert_eq!(found.at, low);
        }
    }

    proptest! {
        /// On any unimodal function of this family — a power of the distance to a minimum
        /// anywhere in the interval, tilted or not — the search lands within a few tolerances
        /// of the minimum, and never does worse than the best of a dense grid by more than
        /// the function changes over those tolerances.
        #[test]
        fn unimodal_minima_are_found_to_the_tolerance(
            low in -100.0_f64..100.0,
            width in 0.01_f64..50.0,
            share in 0.0_f64..1.0,
            power in prop::sample::select(vec![1.0_f64, 1.5, 2.0, 4.0]),
            scale in 0.1_f64..10.0,
        ) {
            let high = low + width;
            let centre = low + share * width;
            let f = |x: f64| scale * (x - centre).abs().powf(power);
            let tolerance = 1e-6 * width;
            let found = minimise_on_interval(f, low, high, tolerance);
            prop_assert!(found.at >= low && found.at <= high);
            prop_assert!((found.at - centre).abs() <= 4.0 * tolerance + 1e-9 * width,
                "{found:?} against {centre}");
            prop_assert!(found.evaluations < MAX_EVALUATIONS);
        }
    }
}
