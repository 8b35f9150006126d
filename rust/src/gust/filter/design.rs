//! The design of a forming filter: its continuous form normalised to unit stationary
//! covariance (Lyapunov), discretised exactly for the step (the matrix exponential, the noise
//! covariance by Van Loan's method and its factor), and the closed forms of the Dryden filters.

use super::super::spectra::Rational;
use super::{GustFilter, GustSpec};
use crate::config::{GustComponent, GustModel};
use nalgebra::{DMatrix, DVector, Matrix3, Vector3};

/// Steps longer than this many `L/V` are computed as this many: the transition
/// matrix is then zero to double precision for every filter here (the slowest
/// pole decays at rate >= 0.46 V/L, and exp(-4600) underflows), and the cap keeps
/// the matrix exponential and the closed forms away from overflow.
pub(super) const K_MAX: f64 = 1.0e4;

/// Continuous state-space form with unit stationary covariance, in
/// nondimensional time `V t / L`: `dx = A x dtau + B dW`, `y = c.x`,
/// `A + A^T + B B^T = 0`, `|c| = 1`.
#[derive(Clone, Debug)]
pub(super) struct Normalised {
    pub(super) a: DMatrix<f64>,
    pub(super) b: DVector<f64>,
    pub(super) c: DVector<f64>,
    /// Output variance of the *published* filter (gain included, intensity-pi
    /// noise) divided by sigma^2: 1 for Dryden, the approximant's own variance
    /// ratio for von Karman.
    pub(super) raw_variance_ratio: f64,
}

/// Solve `A P + P A^T + Q = 0` via the Kronecker form
/// `(I (x) A + A (x) I) vec P = -vec Q`.
pub(super) fn lyapunov(a: &DMatrix<f64>, q: &DMatrix<f64>) -> Option<DMatrix<f64>> {
    let n = a.nrows();
    let eye = DMatrix::<f64>::identity(n, n);
    let kron = eye.kronecker(a) + a.kronecker(&eye);
    let rhs = -DVector::from_column_slice(q.as_slice());
    let sol = kron.lu().solve(&rhs)?;
    let p = DMatrix::from_column_slice(n, n, sol.as_slice());
    Some((&p + p.transpose()) * 0.5)
}

/// The general method: controllable canonical form, continuous Lyapunov solve
/// for the stationary covariance P, then the change of state `x = L_P^{-1} x_raw`
/// (P = L_P L_P^T) that makes the stationary covariance the identity.
pub(super) fn normalise(r: &Rational) -> Result<Normalised, String> {
    let n = r.order;
    let lead = r.den[n];
    let mut a = DMatrix::<f64>::zeros(n, n);
    for i in 0..n - 1 {
        a[(i, i + 1)] = 1.0;
    }
    for j in 0..n {
        a[(n - 1, j)] = -r.den[j] / lead;
    }
    let mut b = DVector::<f64>::zeros(n);
    b[n - 1] = 1.0;
    let c = DVector::<f64>::from_fn(n, |j, _| r.num[j] / lead);
    let bbt = &b * b.transpose();
    let p = lyapunov(&a, &bbt).ok_or("gust: singular Lyapunov equation (internal error)")?;
    let lp = p
        .cholesky()
        .ok_or("gust: stationary covariance not positive definite (internal error)")?
        .l();
    let lp_inv = lp
        .solve_lower_triangular(&DMatrix::<f64>::identity(n, n))
        .ok_or("gust: singular covariance factor (internal error)")?;
    let a_n = &lp_inv * &a * &lp;
    let b_n = &lp_inv * &b;
    let c_n = lp.transpose() * &c;
    // Variance of the published filter with intensity-pi noise, over sigma^2:
    // gain2 * c^T P c (see docs/gust.md, "normalisation").
    let var = c_n.norm_squared();
    Ok(Normalised {
        a: a_n,
        b: b_n,
        c: c_n / var.sqrt(),
        raw_variance_ratio: r.gain2 * var,
    })
}

/// `Q = int_0^k e^{A s} B B^T e^{A^T s} ds` by Van Loan's block exponential.
/// Accurate *relative to Q* for small `k`, where `I - Phi Phi^T` cancels.
pub(super) fn van_loan_q(a: &DMatrix<f64>, bbt: &DMatrix<f64>, k: f64) -> DMatrix<f64> {
    let n = a.nrows();
    let mut m = DMatrix::<f64>::zeros(2 * n, 2 * n);
    m.view_mut((0, 0), (n, n)).copy_from(&(-a * k));
    m.view_mut((0, n), (n, n)).copy_from(&(bbt * k));
    m.view_mut((n, n), (n, n)).copy_from(&(a.transpose() * k));
    let f = m.exp();
    let f12 = f.view((0, n), (n, n)).into_owned();
    let phi = f.view((n, n), (n, n)).transpose();
    let q = phi * f12;
    (&q + q.transpose()) * 0.5
}

/// A square root `G` of the symmetric positive semidefinite `q` (`G G^T = q`):
/// the lower Cholesky factor whenever every pivot is positive; otherwise (q
/// numerically singular or with tiny negative eigenvalues from rounding) the
/// symmetric square root with negative eigenvalues clamped to zero. Never panics.
pub(super) fn noise_factor(q: &DMatrix<f64>) -> Result<DMatrix<f64>, String> {
    if !q.iter().all(|v| v.is_finite()) {
        return Err("gust: non-finite noise covariance (internal error)".into());
    }
    let n = q.nrows();
    let mut l = DMatrix::<f64>::zeros(n, n);
    let mut ok = true;
    'outer: for j in 0..n {
        let mut d = q[(j, j)];
        for k in 0..j {
            d -= l[(j, k)] * l[(j, k)];
        }
        if d.is_nan() || d <= 0.0 {
            ok = false;
            break 'outer;
        }
        let ljj = d.sqrt();
        l[(j, j)] = ljj;
        for i in j + 1..n {
            let mut s = q[(i, j)];
            for k in 0..j {
                s -= l[(i, k)] * l[(j, k)];
            }
            l[(i, j)] = s / ljj;
        }
    }
    if ok && l.iter().all(|v| v.is_finite()) {
        return Ok(l);
    }
    let eig = q.clone().symmetric_eigen();
    let mut g = eig.eigenvectors.clone();
    for (j, lam) in eig.eigenvalues.iter().enumerate() {
        let s = lam.max(0.0).sqrt();
        g.column_mut(j).scale_mut(s);
    }
    Ok(g)
}

/// The noise factor of the 2x2 `[[q11, q12], [q12, q22]]` (padded): `noise_factor`'s
/// Cholesky, operation for operation (so the same bits), without its heap matrices, since
/// scales that follow the vehicle rebuild it every step; `noise_factor` itself where a pivot
/// is not positive.
#[inline]
pub(super) fn chol2(q11: f64, q12: f64, q22: f64) -> [[f64; 3]; 3] {
    let l11 = q11.sqrt();
    let l21 = q12 / l11;
    let d = q22 - l21 * l21;
    let l22 = d.sqrt();
    if q11 > 0.0 && d > 0.0 && l21.is_finite() && l11.is_finite() && l22.is_finite() {
        return [[l11, 0.0, 0.0], [l21, l22, 0.0], [0.0; 3]];
    }
    let q = DMatrix::from_row_slice(2, 2, &[q11, q12, q12, q22]);
    // q is finite by construction, so noise_factor cannot fail.
    rows(&embed(
        &noise_factor(&q).unwrap_or_else(|_| DMatrix::zeros(2, 2)),
    ))
}

/// A padded matrix's rows.
pub(super) fn rows(m: &Matrix3<f64>) -> [[f64; 3]; 3] {
    std::array::from_fn(|i| std::array::from_fn(|j| m[(i, j)]))
}

/// The Dryden closed forms' `Phi` and `G` (padded) for the step `k` in scale lengths (capped at
/// `K_MAX`): what [`GustFilter::new`] and [`GustFilter::rescaled_coefficients`] both use, so
/// that the lane-set path and the per-realisation one fly the same bits.
#[inline]
pub(super) fn dryden_matrices(component: GustComponent, k: f64) -> ([[f64; 3]; 3], [[f64; 3]; 3]) {
    let k = k.min(K_MAX);
    let e = (-k).exp();
    let mut phi = [[0.0; 3]; 3];
    match component {
        GustComponent::Longitudinal => {
            phi[0][0] = e;
            let mut chol = [[0.0; 3]; 3];
            chol[0][0] = (-(-2.0 * k).exp_m1()).sqrt();
            (phi, chol)
        }
        GustComponent::Lateral | GustComponent::Vertical => {
            phi[0][0] = e * (1.0 + k);
            phi[0][1] = e * k;
            phi[1][0] = -e * k;
            phi[1][1] = e * (1.0 - k);
            // I - Phi Phi^T with x = 2k:
            //   Q11 = 1 - e^-x (1 + x + x^2/2) = e^-x S3(x)
            //   Q22 = 1 - e^-x (1 - x + x^2/2) = e^-x (2x + S3(x))
            //   Q12 = x^2/2 e^-x
            let x = 2.0 * k;
            let ex = (-x).exp();
            let (q11, q22) = if x <= 2.0 {
                let s3 = exp_tail3(x);
                (ex * s3, ex * (2.0 * x + s3))
            } else {
                (
                    1.0 - ex * (1.0 + x + 0.5 * x * x),
                    1.0 - ex * (1.0 - x + 0.5 * x * x),
                )
            };
            let q12 = 0.5 * x * x * ex;
            (phi, chol2(q11, q12, q22))
        }
    }
}
/// `S3(x) = sum_{n>=3} x^n / n! = e^x - 1 - x - x^2/2` without cancellation
/// (used for `x <= 2` only).
pub(super) fn exp_tail3(x: f64) -> f64 {
    let mut term = x * x * x / 6.0;
    let mut sum = 0.0;
    let mut n = 3.0;
    while n < 60.0 {
        sum += term;
        if term.abs() <= 1e-18 * sum.abs() {
            break;
        }
        n += 1.0;
        term *= x / n;
    }
    sum
}
pub(super) fn embed(m: &DMatrix<f64>) -> Matrix3<f64> {
    let mut out = Matrix3::zeros();
    for i in 0..m.nrows() {
        for j in 0..m.ncols() {
            out[(i, j)] = m[(i, j)];
        }
    }
    out
}

pub(super) fn embed_vec(v: &DVector<f64>) -> Vector3<f64> {
    let mut out = Vector3::zeros();
    for i in 0..v.len() {
        out[i] = v[i];
    }
    out
}

pub(super) fn check_finite(name: &str, v: f64) -> Result<(), String> {
    if v.is_finite() {
        Ok(())
    } else {
        Err(format!("{name} must be finite, got {v:?}"))
    }
}

pub(super) fn check_positive(name: &str, v: f64, why: &str) -> Result<(), String> {
    check_finite(name, v)?;
    if v > 0.0 {
        Ok(())
    } else {
        Err(format!("{name} must be > 0{why}, got {v:?}"))
    }
}

pub(super) fn check_non_negative(name: &str, v: f64) -> Result<(), String> {
    check_finite(name, v)?;
    if v >= 0.0 {
        Ok(())
    } else {
        Err(format!("{name} must be >= 0, got {v:?}"))
    }
}
impl GustFilter {
    pub(super) fn blank(order: usize) -> Self {
        GustFilter {
            spec: GustSpec {
                model: GustModel::Dryden,
                component: GustComponent::Vertical,
                sigma: 0.0,
                length_scale: 1.0,
                airspeed: 1.0,
                dt: 1.0,
            },
            k: 1.0,
            order,
            phi: Matrix3::zeros(),
            chol: Matrix3::zeros(),
            a: Matrix3::zeros(),
            b: Vector3::zeros(),
            c: Vector3::zeros(),
            out: Vector3::zeros(),
            num: [0.0; 4],
            den: [0.0; 4],
            gain2: 1.0,
            raw_variance_ratio: 1.0,
        }
    }

    /// The closed forms of docs/model.md section 4.
    pub(super) fn dryden_closed_form(component: GustComponent, k: f64) -> Self {
        let (phi, chol) = dryden_matrices(component, k);
        let (phi, chol) = (
            Matrix3::from_fn(|i, j| phi[i][j]),
            Matrix3::from_fn(|i, j| chol[i][j]),
        );
        match component {
            GustComponent::Longitudinal => {
                let mut f = Self::blank(1);
                f.phi = phi;
                f.chol = chol;
                f.a[(0, 0)] = -1.0;
                f.b[0] = 2.0_f64.sqrt();
                f.c[0] = 1.0;
                f
            }
            GustComponent::Lateral | GustComponent::Vertical => {
                let mut f = Self::blank(2);
                f.phi = phi;
                f.chol = chol;
                f.a[(0, 1)] = 1.0;
                f.a[(1, 0)] = -1.0;
                f.a[(1, 1)] = -2.0;
                f.b[1] = 2.0;
                f.c[0] = 0.5;
                f.c[1] = 0.5 * 3.0_f64.sqrt();
                f
            }
        }
    }

    /// The general method for any rational filter (used for von Karman; the
    /// tests show it reproduces the Dryden closed forms).
    pub(super) fn general(r: &Rational, k: f64) -> Result<Self, String> {
        let nz = normalise(r)?;
        let (phi, q) = discretise(&nz, k);
        let g = noise_factor(&q)?;
        let mut f = Self::blank(r.order);
        f.phi = embed(&phi);
        f.chol = embed(&g);
        f.a = embed(&nz.a);
        f.b = embed_vec(&nz.b);
        f.c = embed_vec(&nz.c);
        f.raw_variance_ratio = nz.raw_variance_ratio;
        Ok(f)
    }
}

/// `Phi = expm(A k)` and `Q = I - Phi Phi^T` (via Van Loan when `k |A|` is
/// small, where the subtraction would cancel).
pub(super) fn discretise(nz: &Normalised, k: f64) -> (DMatrix<f64>, DMatrix<f64>) {
    let n = nz.a.nrows();
    let k = k.min(K_MAX);
    let phi = (&nz.a * k).exp();
    let q = if k * nz.a.norm() <= 1.0 {
        let bbt = &nz.b * nz.b.transpose();
        van_loan_q(&nz.a, &bbt, k)
    } else {
        let q = DMatrix::<f64>::identity(n, n) - &phi * phi.transpose();
        (&q + q.transpose()) * 0.5
    };
    (phi, q)
}
