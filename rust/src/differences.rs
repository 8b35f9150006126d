//! Central-difference slopes, shared by the solvers that balance a function on plain numbers:
//! the plant's trim (`model::trim`), each law's closed-loop start (`start`) and the sampled
//! loop's map over one period (`stability`).

use nalgebra::{DMatrix, DVector};

/// d f / d x at `x` by central differences, each column's step 1e-6 of its unknown (at least
/// 1e-6): column j is (f(x + h e_j) - f(x - h e_j)) / 2h.
pub fn central(x: &[f64], f: impl Fn(&[f64]) -> DVector<f64>) -> DMatrix<f64> {
    let mut jac: Option<DMatrix<f64>> = None;
    for j in 0..x.len() {
        let h = 1e-6 * x[j].abs().max(1.0);
        let (mut up, mut down) = (x.to_vec(), x.to_vec());
        up[j] += h;
        down[j] -= h;
        let column = (f(&up) - f(&down)) / (2.0 * h);
        jac.get_or_insert_with(|| DMatrix::zeros(column.len(), x.len()))
            .set_column(j, &column);
    }
    jac.unwrap_or_else(|| DMatrix::zeros(0, 0))
}
