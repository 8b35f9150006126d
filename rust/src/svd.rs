//! nalgebra's singular value decomposition, made total for the engine's solvers: its plain
//! form iterates without bound on a non-finite matrix, and its bounded form (`try_new`) panics
//! where a singular value comes out NaN (as one did in the closed loop of a scenario with a
//! gravity of 2e111 m/s^2: legal, absurd, and no reason to abort). Here each of those, and a
//! singular value past f64, is `None`, for the caller to treat as no answer.

use nalgebra::{ComplexField, DMatrix, Dyn, SVD};

/// The SVD of `m` (singular values in descending order), with the left (`u`) and right (`v`)
/// singular vectors as asked, in at most `max_iterations`; `None` where `m` is not finite,
/// the iterations run out or a singular value is not finite.
pub fn bounded<T: ComplexField>(
    m: DMatrix<T>,
    u: bool,
    v: bool,
    eps: T::RealField,
    max_iterations: usize,
) -> Option<SVD<T, Dyn, Dyn>> {
    if !m.iter().all(|x| x.is_finite()) {
        return None;
    }
    let mut svd = SVD::try_new_unordered(m, u, v, eps, max_iterations)?;
    if !svd.singular_values.iter().all(|s| s.is_finite()) {
        return None;
    }
    svd.sort_by_singular_values();
    Some(svd)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A matrix with an entry not finite, or a singular value past f64 (1e308 entries), is no
    /// answer; a plain one is decomposed as nalgebra does it, its singular values descending.
    /// (The NaN singular value nalgebra panicked on came from the closed loop of a gravity of
    /// 2e111 m/s^2: tests/guarantees/test_hostile_input.py flies it.)
    #[test]
    fn a_matrix_not_finite_or_past_f64_is_no_answer_and_a_plain_one_is_nalgebras() {
        let nan = DMatrix::from_row_slice(2, 2, &[1.0, f64::NAN, 0.0, 1.0]);
        assert!(bounded(nan, true, true, f64::EPSILON, 1000).is_none());
        let inf = DMatrix::from_row_slice(2, 2, &[1.0, f64::INFINITY, 0.0, 1.0]);
        assert!(bounded(inf, true, true, f64::EPSILON, 1000).is_none());
        let huge = DMatrix::from_row_slice(2, 2, &[1e308, 1e308, 1e308, 1e308]);
        assert!(bounded(huge, true, true, f64::EPSILON, 1000).is_none());
        let m = DMatrix::from_row_slice(3, 2, &[3.0, 1.0, 1.0, 3.0, 0.5, -0.5]);
        let ours = bounded(m.clone(), true, true, f64::EPSILON, 1000).expect("decomposed");
        let theirs = SVD::try_new(m, true, true, f64::EPSILON, 1000).expect("decomposed");
        assert_eq!(ours.singular_values, theirs.singular_values);
        assert!(ours.singular_values[0] >= ours.singular_values[1]);
    }
}
