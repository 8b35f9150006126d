//! One gust component's forming filter, discretised exactly for the integration step:
//! normalisation to unit stationary covariance (Lyapunov), the transition matrix and the
//! noise covariance (Van Loan), and the closed forms of the Dryden filters.

use super::spectra::{poly_abs2, rational, von_karman_psd_exact, Rational};
use crate::config::{GustComponent, GustModel};
use crate::lane::{explog, KernelOps};
use nalgebra::{DMatrix, DVector, Matrix3, Vector3};
use rand_chacha::ChaCha8Rng;

/// Steps longer than this many `L/V` are computed as this many: the transition
/// matrix is then zero to double precision for every filter here (the slowest
/// pole decays at rate >= 0.46 V/L, and exp(-4600) underflows), and the cap keeps
/// the matrix exponential and the closed forms away from overflow.
const K_MAX: f64 = 1.0e4;

/// Continuous state-space form with unit stationary covariance, in
/// nondimensional time `V t / L`: `dx = A x dtau + B dW`, `y = c.x`,
/// `A + A^T + B B^T = 0`, `|c| = 1`.
#[derive(Clone, Debug)]
struct Normalised {
    a: DMatrix<f64>,
    b: DVector<f64>,
    c: DVector<f64>,
    /// Output variance of the *published* filter (gain included, intensity-pi
    /// noise) divided by sigma^2: 1 for Dryden, the approximant's own variance
    /// ratio for von Karman.
    raw_variance_ratio: f64,
}

/// Solve `A P + P A^T + Q = 0` via the Kronecker form
/// `(I (x) A + A (x) I) vec P = -vec Q`.
fn lyapunov(a: &DMatrix<f64>, q: &DMatrix<f64>) -> Option<DMatrix<f64>> {
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
fn normalise(r: &Rational) -> Result<Normalised, String> {
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
fn van_loan_q(a: &DMatrix<f64>, bbt: &DMatrix<f64>, k: f64) -> DMatrix<f64> {
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
fn noise_factor(q: &DMatrix<f64>) -> Result<DMatrix<f64>, String> {
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
fn chol2(q11: f64, q12: f64, q22: f64) -> [[f64; 3]; 3] {
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
fn rows(m: &Matrix3<f64>) -> [[f64; 3]; 3] {
    std::array::from_fn(|i| std::array::from_fn(|j| m[(i, j)]))
}

/// The Dryden closed forms' `Phi` and `G` (padded) for the step `k` in scale lengths (capped at
/// `K_MAX`): what [`GustFilter::new`] and [`GustFilter::rescaled_coefficients`] both use, so
/// that the lane-set path and the per-realisation one fly the same bits.
#[inline]
fn dryden_matrices(component: GustComponent, k: f64) -> ([[f64; 3]; 3], [[f64; 3]; 3]) {
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

/// The numbers one step of a filter applies, row-major and padded to order 3: `x' = phi x +
/// g n`, `w = out . x` (`out = sigma c`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Coefficients {
    pub phi: [[f64; 3]; 3],
    pub g: [[f64; 3]; 3],
    pub out: [f64; 3],
}

impl Coefficients {
    /// Every number NaN: what a step whose scales no filter can take flies
    /// ([`GustFilter::poisoned`]'s).
    pub const NAN: Self = Self {
        phi: [[f64::NAN; 3]; 3],
        g: [[f64::NAN; 3]; 3],
        out: [f64::NAN; 3],
    };

    fn of(phi: &Matrix3<f64>, g: &Matrix3<f64>, out: [f64; 3]) -> Self {
        Self {
            phi: rows(phi),
            g: rows(g),
            out,
        }
    }
}

/// `S3(x) = sum_{n>=3} x^n / n! = e^x - 1 - x - x^2/2` without cancellation
/// (used for `x <= 2` only).
fn exp_tail3(x: f64) -> f64 {
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

/// Lanes where `mask` (all bits set: true) is false in every lane.
#[inline(always)]
fn none<L: KernelOps>(mask: L) -> bool {
    // A true lane is all ones (a NaN, so never <= 0), a false one +0.
    mask.le_mask(L::splat(0.0)) == L::ALL
}

/// Mask (all bits set where true) of `x > 0`, false for NaN.
#[inline(always)]
fn positive<L: KernelOps>(x: L) -> L {
    let zero = L::splat(0.0);
    x.cmp_ge(zero).and_bits(x.cmp_ne(zero))
}

/// Mask of `x.is_finite()`.
#[inline(always)]
fn finite<L: KernelOps>(x: L) -> L {
    x.abs().cmp_le(L::splat(f64::MAX))
}

/// [`exp_tail3`] of every lane where `active` (a mask, as from `cmp_le`) at once, 0 where not:
/// the same operations in the same order per lane (so the same bits), each lane's sum kept from
/// the term at which its own series stops; the loop runs while some lane's has not.
#[inline(always)]
pub(super) fn exp_tail3_lanes<L: KernelOps>(x: L, mut active: L) -> L {
    let mut term = x * x * x / L::splat(6.0);
    let mut sum = L::splat(0.0);
    let mut n = 3.0;
    while n < 60.0 {
        sum = L::select(active, sum + term, sum);
        let stop = term.abs().cmp_le(L::splat(1e-18) * sum.abs());
        active = active.xor_bits(active.and_bits(stop));
        if none(active) {
            break;
        }
        n += 1.0;
        term = term * (x / L::splat(n));
    }
    sum
}

/// Where [`dryden_lanes`] writes one axis's numbers for every lane of a lane-set (the
/// lane-set's filter itself, in place): the order-`N` block of `Phi`, `G` and `sigma c`
/// (order 1: the `[0][0]` and `[0]` entries only; the rest is left as it is).
pub(super) struct DrydenLanes<'a, L> {
    pub phi: &'a mut [[L; 3]; 3],
    pub g: &'a mut [[L; 3]; 3],
    pub out: &'a mut [L; 3],
}

/// [`GustFilter::rescaled_coefficients`] of a Dryden filter of `component` for every lane at
/// once (that function is this one on `f64`), `sigma`, `length`, `airspeed`, `dt` and `c` (the
/// unit output row) per lane: the closed forms of [`dryden_matrices`] in lane values, with the
/// lane-valued `exp` and `expm1` ([`crate::lane::explog`], within 1 ulp of the true values)
/// instead of libm's, and the same operations in the same order on every lane type (no
/// operation fused), so each lane has the bits of the `f64` evaluation. Lanes whose scales
/// `rescaled_coefficients` rejects get NaN; a lane whose Cholesky pivot is not positive takes
/// `noise_factor`'s eigen-factor of its `I - Phi Phi^T`. Written into `d`.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub(super) fn dryden_lanes<L: KernelOps>(
    component: GustComponent,
    sigma: L,
    length: L,
    airspeed: L,
    dt: L,
    c: [L; 2],
    d: DrydenLanes<'_, L>,
) {
    let zero = L::splat(0.0);
    // `rescaled_coefficients`' checks: `sigma >= 0` finite, `L`, `V`, `dt` and `k` > 0 finite.
    let k = airspeed * dt / length;
    let ok = |x: L| finite(x).and_bits(positive(x));
    let valid = finite(sigma)
        .and_bits(sigma.cmp_ge(zero))
        .and_bits(ok(length))
        .and_bits(ok(airspeed))
        .and_bits(ok(dt))
        .and_bits(ok(k));
    // `dryden_matrices`' cap.
    let kc = k.min(L::splat(K_MAX));
    let e = explog::exp(-kc);
    let n = match component {
        GustComponent::Longitudinal => 1,
        GustComponent::Lateral | GustComponent::Vertical => 2,
    };
    d.out[0] = c[0] * sigma;
    if n == 2 {
        d.out[1] = c[1] * sigma;
    }
    let mut scalar = zero;
    let mut q = [zero; 3];
    match component {
        GustComponent::Longitudinal => {
            let m = explog::expm1(L::splat(-2.0) * kc);
            d.phi[0][0] = e;
            d.g[0][0] = (-m).sqrt();
        }
        GustComponent::Lateral | GustComponent::Vertical => {
            d.phi[0][0] = e * (L::splat(1.0) + kc);
            d.phi[0][1] = e * kc;
            d.phi[1][0] = -e * kc;
            d.phi[1][1] = e * (L::splat(1.0) - kc);
            let x = L::splat(2.0) * kc;
            let ex = explog::exp(-x);
            let series = x.cmp_le(L::splat(2.0));
            let s3 = exp_tail3_lanes(x, series.and_bits(valid));
            let (mut q11, mut q22) = (ex * s3, ex * (L::splat(2.0) * x + s3));
            if !none(valid.xor_bits(valid.and_bits(series))) {
                let half_x2 = L::splat(0.5) * x * x;
                let one = L::splat(1.0);
                q11 = L::select(series, q11, one - ex * (one + x + half_x2));
                q22 = L::select(series, q22, one - ex * (one - x + half_x2));
            }
            let q12 = L::splat(0.5) * x * x * ex;
            // `chol2`.
            let l11 = q11.sqrt();
            let l21 = q12 / l11;
            let dd = q22 - l21 * l21;
            let l22 = dd.sqrt();
            let pivots = positive(q11)
                .and_bits(positive(dd))
                .and_bits(finite(l21))
                .and_bits(finite(l11))
                .and_bits(finite(l22));
            d.g[0][0] = l11;
            d.g[0][1] = zero;
            d.g[1][0] = l21;
            d.g[1][1] = l22;
            scalar = valid.xor_bits(valid.and_bits(pivots));
            q = [q11, q12, q22];
        }
    }
    // The rare lanes: NaN where the scales are rejected, scalar where a pivot is not positive.
    // (`le_mask(0)` of a mask: the lanes where it is false.)
    let rejected = valid.le_mask(zero);
    let fallback = !scalar.le_mask(zero) & L::ALL;
    if rejected | fallback != 0 {
        for l in 0..L::LANES {
            let bit = 1 << l;
            if rejected & bit != 0 {
                d.out[..n].iter_mut().for_each(|v| v.set_lane(l, f64::NAN));
                for i in 0..n {
                    for j in 0..n {
                        d.phi[i][j].set_lane(l, f64::NAN);
                        d.g[i][j].set_lane(l, f64::NAN);
                    }
                }
            } else if fallback & bit != 0 {
                // `chol2`'s fallback on this lane's I - Phi Phi^T (finite: the scales are).
                let q = DMatrix::from_row_slice(
                    2,
                    2,
                    &[q[0].lane(l), q[1].lane(l), q[1].lane(l), q[2].lane(l)],
                );
                let g = noise_factor(&q).unwrap_or_else(|_| DMatrix::zeros(2, 2));
                for i in 0..2 {
                    for j in 0..2 {
                        d.g[i][j].set_lane(l, g[(i, j)]);
                    }
                }
            }
        }
    }
}

fn embed(m: &DMatrix<f64>) -> Matrix3<f64> {
    let mut out = Matrix3::zeros();
    for i in 0..m.nrows() {
        for j in 0..m.ncols() {
            out[(i, j)] = m[(i, j)];
        }
    }
    out
}

fn embed_vec(v: &DVector<f64>) -> Vector3<f64> {
    let mut out = Vector3::zeros();
    for i in 0..v.len() {
        out[i] = v[i];
    }
    out
}

fn check_finite(name: &str, v: f64) -> Result<(), String> {
    if v.is_finite() {
        Ok(())
    } else {
        Err(format!("{name} must be finite, got {v:?}"))
    }
}

fn check_positive(name: &str, v: f64, why: &str) -> Result<(), String> {
    check_finite(name, v)?;
    if v > 0.0 {
        Ok(())
    } else {
        Err(format!("{name} must be > 0{why}, got {v:?}"))
    }
}

fn check_non_negative(name: &str, v: f64) -> Result<(), String> {
    check_finite(name, v)?;
    if v >= 0.0 {
        Ok(())
    } else {
        Err(format!("{name} must be >= 0, got {v:?}"))
    }
}

/// One gust component's forming filter, exactly discretised for a step `dt`,
/// with its state normalised to unit stationary covariance:
/// `x' = Phi x + G n`, `w = sigma c.x` (`|c| = 1`, `G G^T = I - Phi Phi^T`).
///
/// Orders: Dryden longitudinal 1, Dryden lateral/vertical 2, von Karman
/// longitudinal 2, von Karman lateral/vertical 3. Matrices are padded with zeros
/// to 3x3. Fixed-size storage, no heap, `Copy`.
///
/// Dryden uses the closed forms of docs/model.md section 4 (`k = V dt / L`, `E = exp(-k)`):
/// longitudinal `Phi = E`, `G = sqrt(1 - E^2)`, `c = 1`; lateral/vertical
/// `Phi = E [[1+k, k], [-k, 1-k]]`, `G = chol(I - Phi Phi^T)` (entries of
/// `I - Phi Phi^T` evaluated without cancellation), `c = (1/2, sqrt3/2)`.
/// Von Karman uses the general method (controllable canonical form, Lyapunov
/// solve, normalisation, `Phi = expm(A k)`, `Q` by Van Loan's method for
/// `k |A| <= 1`); its output is scaled so that the variance is exactly sigma^2
/// (the published approximants' own variance differs: see
/// [`GustFilter::approximant_variance_ratio`] and docs/gust.md).
#[derive(Clone, Copy, Debug)]
pub struct GustFilter {
    model: GustModel,
    component: GustComponent,
    sigma: f64,
    length_scale: f64,
    airspeed: f64,
    dt: f64,
    /// V dt / L.
    k: f64,
    order: usize,
    phi: Matrix3<f64>,
    chol: Matrix3<f64>,
    /// Normalised continuous A in nondimensional time V t / L (padded).
    a: Matrix3<f64>,
    /// Normalised continuous B in nondimensional time (padded).
    b: Vector3<f64>,
    /// Unit output row (padded).
    c: Vector3<f64>,
    /// sigma * c, the row applied to the state.
    out: Vector3<f64>,
    num: [f64; 4],
    den: [f64; 4],
    gain2: f64,
    raw_variance_ratio: f64,
}

impl GustFilter {
    /// Build and discretise one component's filter.
    ///
    /// `sigma` (m/s) >= 0, `length_scale` (m) > 0, `airspeed` (m/s) > 0, `dt`
    /// (s) > 0, all finite; otherwise `Err` with a message naming the
    /// parameter and the value (e.g. `airspeed must be > 0 (the Dryden filters
    /// are singular at zero airspeed), got 0.0`).
    pub fn new(
        model: GustModel,
        component: GustComponent,
        sigma: f64,
        length_scale: f64,
        airspeed: f64,
        dt: f64,
    ) -> Result<Self, String> {
        let k = Self::check(model, sigma, length_scale, airspeed, dt)?;
        let r = rational(model, component);
        let mut f = match model {
            GustModel::Dryden => Self::dryden_closed_form(component, k),
            GustModel::VonKarman => Self::general(&r, k)?,
        };
        f.model = model;
        f.component = component;
        f.sigma = sigma;
        f.length_scale = length_scale;
        f.airspeed = airspeed;
        f.dt = dt;
        f.k = k;
        f.out = f.c * sigma;
        f.num = r.num;
        f.den = r.den;
        f.gain2 = r.gain2;
        Ok(f)
    }

    /// What `new` requires of its numbers, checked without building the filter (scenario
    /// validation runs it for every component): the step in scale lengths, `airspeed * dt /
    /// length_scale`, finite and positive.
    pub fn check(
        model: GustModel,
        sigma: f64,
        length_scale: f64,
        airspeed: f64,
        dt: f64,
    ) -> Result<f64, String> {
        check_non_negative("sigma", sigma)?;
        check_positive("length_scale", length_scale, "")?;
        if !(airspeed.is_finite() && airspeed > 0.0) {
            // The message is built only on failure: scales that follow the vehicle rebuild
            // the filter every step.
            let why = format!(
                " (the {} filters are singular at zero airspeed)",
                model.name()
            );
            check_positive("airspeed", airspeed, &why)?;
        }
        check_positive("dt", dt, "")?;
        let k = airspeed * dt / length_scale;
        if !(k.is_finite() && k > 0.0) {
            return Err(format!(
                "airspeed * dt / length_scale must be finite and > 0, got {k:?} \
                 (airspeed {airspeed:?}, dt {dt:?}, length_scale {length_scale:?})"
            ));
        }
        Ok(k)
    }

    fn blank(order: usize) -> Self {
        GustFilter {
            model: GustModel::Dryden,
            component: GustComponent::Vertical,
            sigma: 0.0,
            length_scale: 1.0,
            airspeed: 1.0,
            dt: 1.0,
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
    fn dryden_closed_form(component: GustComponent, k: f64) -> Self {
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
    fn general(r: &Rational, k: f64) -> Result<Self, String> {
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

    /// This filter re-discretised for new scales (same model, component and step): for
    /// turbulence whose altitude or airspeed follows the vehicle. The normalised state keeps
    /// unit stationary covariance whatever the scales, so changing them never makes the
    /// variance jump. Dryden: the closed forms, no allocation.
    #[inline]
    pub fn rescaled(&self, sigma: f64, length_scale: f64, airspeed: f64) -> Result<Self, String> {
        Self::new(
            self.model,
            self.component,
            sigma,
            length_scale,
            airspeed,
            self.dt,
        )
    }

    /// The `Phi`, `G` and `sigma c` of this filter re-discretised for new scales, or
    /// [`Coefficients::NAN`] where [`rescaled`](Self::rescaled) errs (what
    /// [`poisoned`](Self::poisoned) flies): the numbers of turbulence that follows the vehicle,
    /// computed every step. Dryden: [`dryden_lanes`] on `f64` (the lane-valued `exp` and
    /// `expm1`, so the lane-set path gives each lane these bits; within a few ulp of
    /// `rescaled`'s libm closed forms), without building a filter or allocating. Von Karman:
    /// `rescaled`'s, bit for bit.
    #[inline]
    pub fn rescaled_coefficients(
        &self,
        sigma: f64,
        length_scale: f64,
        airspeed: f64,
    ) -> Coefficients {
        match self.model {
            GustModel::Dryden => {
                // `check`'s conditions, inline (`dt` was checked when `self` was built): the
                // same `k`, and an error exactly where `check` errs.
                let ok = |x: f64| x.is_finite() && x > 0.0;
                let k = airspeed * self.dt / length_scale;
                let valid = sigma.is_finite() && sigma >= 0.0;
                if !(valid && ok(length_scale) && ok(airspeed) && ok(self.dt) && ok(k)) {
                    return Coefficients::NAN;
                }
                let mut out = Coefficients {
                    phi: [[0.0; 3]; 3],
                    g: [[0.0; 3]; 3],
                    out: [self.c[0] * sigma, self.c[1] * sigma, self.c[2] * sigma],
                };
                dryden_lanes(
                    self.component,
                    sigma,
                    length_scale,
                    airspeed,
                    self.dt,
                    [self.c[0], self.c[1]],
                    DrydenLanes {
                        phi: &mut out.phi,
                        g: &mut out.g,
                        out: &mut out.out,
                    },
                );
                out
            }
            GustModel::VonKarman => match self.rescaled(sigma, length_scale, airspeed) {
                Ok(f) => f.coefficients(),
                Err(_) => Coefficients::NAN,
            },
        }
    }

    /// This filter re-discretised for new scales as turbulence that follows the vehicle flies
    /// it every step: [`rescaled_coefficients`](Self::rescaled_coefficients)' numbers (so the
    /// per-realisation path and the lane-set path fly the same bits), or
    /// [`poisoned`](Self::poisoned) where the scales are rejected.
    #[inline]
    pub fn rescaled_following(&self, sigma: f64, length_scale: f64, airspeed: f64) -> Self {
        if self.model == GustModel::VonKarman {
            return self
                .rescaled(sigma, length_scale, airspeed)
                .unwrap_or_else(|_| self.poisoned());
        }
        let c = self.rescaled_coefficients(sigma, length_scale, airspeed);
        let mut f = *self;
        f.phi = Matrix3::from_fn(|i, j| c.phi[i][j]);
        f.chol = Matrix3::from_fn(|i, j| c.g[i][j]);
        f.out = Vector3::from(c.out);
        f.sigma = sigma;
        f.length_scale = length_scale;
        f.airspeed = airspeed;
        f.k = airspeed * self.dt / length_scale;
        f
    }

    /// This filter's `Phi`, `G` and `sigma c`.
    pub fn coefficients(&self) -> Coefficients {
        Coefficients::of(
            &self.phi,
            &self.chol,
            [self.out[0], self.out[1], self.out[2]],
        )
    }

    /// This filter with NaN transition, noise and output: what a step whose scales no filter
    /// can take (a runaway state) flies, so that the flight ends as non-finite.
    pub(super) fn poisoned(&self) -> Self {
        let nan = f64::NAN;
        Self {
            phi: Matrix3::from_element(nan),
            chol: Matrix3::from_element(nan),
            out: Vector3::from_element(nan),
            ..*self
        }
    }

    /// The unit output row `c` (padded): `output_row` is `sigma c`.
    pub(super) fn unit_output(&self) -> [f64; 3] {
        [self.c[0], self.c[1], self.c[2]]
    }

    /// Filter order (state dimension), 1 to 3.
    pub fn order(&self) -> usize {
        self.order
    }

    pub fn model(&self) -> GustModel {
        self.model
    }

    pub fn component(&self) -> GustComponent {
        self.component
    }

    /// Output standard deviation, m/s.
    pub fn sigma(&self) -> f64 {
        self.sigma
    }

    /// Scale length, m.
    pub fn length_scale(&self) -> f64 {
        self.length_scale
    }

    /// Airspeed, m/s.
    pub fn airspeed(&self) -> f64 {
        self.airspeed
    }

    /// Step, s.
    pub fn dt(&self) -> f64 {
        self.dt
    }

    /// `k = V dt / L`, the step in scale lengths.
    pub fn step_in_scale_lengths(&self) -> f64 {
        self.k
    }

    /// Variance of the published forming filter (with its published gain and
    /// intensity-pi noise) over sigma^2. Exactly 1 for Dryden; for von Karman
    /// the approximant's own variance ratio (the output here is rescaled so
    /// the variance is exactly sigma^2).
    pub fn approximant_variance_ratio(&self) -> f64 {
        self.raw_variance_ratio
    }

    /// Draw a state from the stationary distribution (unit covariance, so just
    /// `order()` standard normals; the rest zero).
    pub fn stationary_state(&self, rng: &mut impl Normals) -> [f64; 3] {
        let mut x = [0.0; 3];
        for v in x.iter_mut().take(self.order) {
            *v = rng.normal();
        }
        x
    }

    /// Gust velocity (m/s) for a state: `sigma c.x`, summed over the filter's `order()`
    /// states in index order (the padding beyond them is zero).
    #[inline]
    pub fn output(&self, state: &[f64; 3]) -> f64 {
        let terms = self.out.iter().zip(state).take(self.order);
        terms
            .skip(1)
            .fold(self.out[0] * state[0], |y, (c, x)| y + c * x)
    }

    /// Advance the state one step with `order()` fresh normals from `rng`.
    #[inline]
    pub fn advance(&self, state: &mut [f64; 3], rng: &mut impl Normals) {
        match self.order {
            1 => {
                let (phi, g, _) = self.fixed::<1>();
                step_fixed::<1>(&phi, &g, state, rng);
            }
            2 => {
                let (phi, g, _) = self.fixed::<2>();
                step_fixed::<2>(&phi, &g, state, rng);
            }
            _ => {
                let (phi, g, _) = self.fixed::<3>();
                step_fixed::<3>(&phi, &g, state, rng);
            }
        }
    }

    /// Row-major copies of Phi, G and sigma c, for hot loops.
    #[inline(always)]
    pub(super) fn fixed<const N: usize>(&self) -> ([[f64; N]; N], [[f64; N]; N], [f64; N]) {
        let mut phi = [[0.0; N]; N];
        let mut g = [[0.0; N]; N];
        let mut c = [0.0; N];
        for i in 0..N {
            for j in 0..N {
                phi[i][j] = self.phi[(i, j)];
                g[i][j] = self.chol[(i, j)];
            }
            c[i] = self.out[i];
        }
        (phi, g, c)
    }

    /// Transition matrix `Phi = expm(A dt)` of the normalised state (padded).
    pub fn transition(&self) -> Matrix3<f64> {
        self.phi
    }

    /// Noise factor `G` with `G G^T = I - Phi Phi^T` (padded): the lower
    /// Cholesky factor; only if `I - Phi Phi^T` were numerically singular
    /// would it be the clamped symmetric square root instead (not triangular).
    pub fn noise_chol(&self) -> Matrix3<f64> {
        self.chol
    }

    /// Continuous `A` of the normalised state, in 1/s (`Phi = expm(A dt)`).
    pub fn continuous_a(&self) -> Matrix3<f64> {
        self.a * (self.airspeed / self.length_scale)
    }

    /// Continuous `B` of the normalised state for unit-intensity white noise,
    /// in 1/sqrt(s): `A + A^T + B B^T = 0` (stationary covariance I).
    pub fn continuous_b(&self) -> Vector3<f64> {
        self.b * (self.airspeed / self.length_scale).sqrt()
    }

    /// Output row `sigma c` (m/s per unit state), padded.
    pub fn output_row(&self) -> Vector3<f64> {
        self.out
    }

    /// One-sided PSD of the generated gust, m^2/s^2 per Hz, at `f_hz`:
    /// `2 pi |H(j 2 pi f)|^2`, i.e. Dryden longitudinal `4 sigma^2 T/(1+x^2)`,
    /// lateral/vertical `2 sigma^2 T (1+3x^2)/(1+x^2)^2` (`T = L/V`,
    /// `x = 2 pi f T`); von Karman: the approximant's, rescaled by
    /// `1/approximant_variance_ratio()` like the output. Integrates to sigma^2.
    pub fn psd(&self, f_hz: f64) -> f64 {
        let t = self.length_scale / self.airspeed;
        let x = 2.0 * std::f64::consts::PI * f_hz.abs() * t;
        2.0 * self.sigma * self.sigma * t * self.gain2 / self.raw_variance_ratio
            * poly_abs2(&self.num, x)
            / poly_abs2(&self.den, x)
    }

    /// The spectrum this filter is meant to realise: equal to [`Self::psd`] for
    /// Dryden, the exact von Karman PSD ([`von_karman_psd_exact`]) for von Karman.
    pub fn target_psd(&self, f_hz: f64) -> f64 {
        match self.model {
            GustModel::Dryden => self.psd(f_hz),
            GustModel::VonKarman => von_karman_psd_exact(
                self.component,
                self.sigma,
                self.length_scale,
                self.airspeed,
                f_hz,
            ),
        }
    }

    /// Autocorrelation (m^2/s^2) of the generated gust at lag `tau` (s).
    /// Dryden, exactly: `sigma^2 e^-u` (longitudinal), `sigma^2 e^-u (1 - u/2)`
    /// (lateral/vertical), `u = V |tau| / L`. Von Karman: the approximant's,
    /// `sigma^2 c expm(A u) c^T` from the normalised state-space form.
    pub fn autocorrelation(&self, tau: f64) -> f64 {
        let u = self.airspeed * tau.abs() / self.length_scale;
        let s2 = self.sigma * self.sigma;
        match (self.model, self.component) {
            (GustModel::Dryden, GustComponent::Longitudinal) => s2 * (-u).exp(),
            (GustModel::Dryden, _) => s2 * (-u).exp() * (1.0 - 0.5 * u),
            (GustModel::VonKarman, _) => {
                if u.is_nan() {
                    return f64::NAN;
                }
                if u > K_MAX {
                    return 0.0;
                }
                let m = (self.a * u).exp();
                s2 * (self.c.transpose() * m * self.c)[(0, 0)]
            }
        }
    }
}

/// `Phi = expm(A k)` and `Q = I - Phi Phi^T` (via Van Loan when `k |A|` is
/// small, where the subtraction would cancel).
fn discretise(nz: &Normalised, k: f64) -> (DMatrix<f64>, DMatrix<f64>) {
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

/// Where the forming filters' unit normals come from: a realisation's seeded stream, or
/// innovations given explicitly (`WindState`). Both hand them out in the same order.
pub trait Normals {
    fn normal(&mut self) -> f64;
}

impl Normals for ChaCha8Rng {
    /// `StandardNormal`'s draw, its fast path inlined (`normal::standard_normal`).
    #[inline(always)]
    fn normal(&mut self) -> f64 {
        crate::lane::random::normal::standard_normal(self)
    }
}

#[inline(always)]
#[allow(clippy::needless_range_loop)]
pub(super) fn step_fixed<const N: usize>(
    phi: &[[f64; N]; N],
    g: &[[f64; N]; N],
    x: &mut [f64; 3],
    rng: &mut impl Normals,
) {
    let mut n = [0.0; N];
    for v in n.iter_mut() {
        *v = rng.normal();
    }
    let mut y = [0.0; N];
    for i in 0..N {
        let mut acc = phi[i][0] * x[0] + g[i][0] * n[0];
        for j in 1..N {
            acc += phi[i][j] * x[j] + g[i][j] * n[j];
        }
        y[i] = acc;
    }
    x[..N].copy_from_slice(&y);
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;

    pub(in crate::gust) const KS: [f64; 4] = [0.01, 0.5, 2.0, 10.0];
    pub(in crate::gust) const MODELS: [GustModel; 2] = [GustModel::Dryden, GustModel::VonKarman];

    /// A filter with V dt / L = k (L = 2 m, V = 10 m/s).
    pub(in crate::gust) fn filt(
        model: GustModel,
        c: GustComponent,
        sigma: f64,
        k: f64,
    ) -> GustFilter {
        let (l, v) = (2.0, 10.0);
        GustFilter::new(model, c, sigma, l, v, k * l / v).unwrap()
    }

    fn max_abs(m: &Matrix3<f64>) -> f64 {
        m.iter().fold(0.0_f64, |a, v| a.max(v.abs()))
    }

    /// Independent matrix exponential: Taylor series with scaling and squaring.
    fn expm_taylor(a: &Matrix3<f64>) -> Matrix3<f64> {
        let norm = max_abs(a) * 3.0;
        let mut s = 0;
        while norm / f64::from(1u32 << s) > 0.25 {
            s += 1;
        }
        let b = a / f64::from(1u32 << s);
        let mut term = Matrix3::identity();
        let mut sum = Matrix3::identity();
        for n in 1..30 {
            term = term * b / f64::from(n);
            sum += term;
        }
        for _ in 0..s {
            sum = sum * sum;
        }
        sum
    }

    #[test]
    fn dryden_phi_is_expm_of_the_normalised_model() {
        // Derived in docs/gust.md: in nondimensional time V t / L,
        // longitudinal A = -1, B = sqrt2, c = 1;
        // lateral/vertical A = [[0, 1], [-1, -2]], B = (0, 2), c = (1/2, sqrt3/2).
        let mut a_v = Matrix3::zeros();
        a_v[(0, 1)] = 1.0;
        a_v[(1, 0)] = -1.0;
        a_v[(1, 1)] = -2.0;
        let mut a_l = Matrix3::zeros();
        a_l[(0, 0)] = -1.0;
        for k in KS {
            for c in GustComponent::ALL {
                let f = filt(GustModel::Dryden, c, 1.0, k);
                let a = if c == GustComponent::Longitudinal {
                    a_l
                } else {
                    a_v
                };
                let mut expm = (a * k).exp();
                // Padding: the unused diagonal of expm is 1, of Phi 0.
                for i in f.order()..3 {
                    expm[(i, i)] = 0.0;
                }
                assert!(max_abs(&(f.transition() - expm)) < 1e-12, "{c:?} k={k}");
                // docs/model.md's closed form, literally.
                let e = (-k).exp();
                let phi = f.transition();
                if c == GustComponent::Longitudinal {
                    assert!((phi[(0, 0)] - e).abs() < 1e-15);
                    assert!((f.noise_chol()[(0, 0)] - (1.0 - e * e).sqrt()).abs() < 1e-12);
                } else {
                    let want = Matrix3::new(
                        e * (1.0 + k),
                        e * k,
                        0.0,
                        -e * k,
                        e * (1.0 - k),
                        0.0,
                        0.0,
                        0.0,
                        0.0,
                    );
                    assert!(max_abs(&(phi - want)) < 1e-15);
                    let out = f.output_row();
                    assert!((out[0] - 0.5).abs() < 1e-15);
                    assert!((out[1] - 0.75_f64.sqrt()).abs() < 1e-15);
                }
                // A dt with A in 1/s.
                let a_t = f.continuous_a() * f.dt();
                let mut expm_t = (a_t).exp();
                for i in f.order()..3 {
                    expm_t[(i, i)] = 0.0;
                }
                assert!(max_abs(&(f.transition() - expm_t)) < 1e-12);
            }
        }
    }

    #[test]
    fn general_method_reproduces_dryden_closed_form() {
        for c in [GustComponent::Longitudinal, GustComponent::Vertical] {
            let r = rational(GustModel::Dryden, c);
            let nz = normalise(&r).unwrap();
            assert!((nz.raw_variance_ratio - 1.0).abs() < 1e-12);
            for k in KS.iter().copied().chain([1e-4, 1e-6, 50.0]) {
                let g = GustFilter::general(&r, k).unwrap();
                let f = GustFilter::dryden_closed_form(c, k);
                assert!(max_abs(&(g.a - f.a)) < 1e-12, "{c:?} A");
                assert!((g.b - f.b).amax() < 1e-12, "{c:?} B");
                assert!((g.c - f.c).amax() < 1e-12, "{c:?} c");
                assert!(max_abs(&(g.phi - f.phi)) < 1e-12, "{c:?} k={k} Phi");
                let qg = g.chol * g.chol.transpose();
                let qf = f.chol * f.chol.transpose();
                assert!(max_abs(&(qg - qf)) < 1e-12, "{c:?} k={k} Q");
                assert!(max_abs(&(g.chol - f.chol)) < 1e-9, "{c:?} k={k} G");
            }
        }
    }

    #[test]
    fn von_karman_phi_matches_independent_expm() {
        for c in GustComponent::ALL {
            for k in KS {
                let f = filt(GustModel::VonKarman, c, 1.0, k);
                let mut want = expm_taylor(&(f.a * k));
                for i in f.order()..3 {
                    want[(i, i)] = 0.0;
                }
                let err = max_abs(&(f.transition() - want));
                assert!(err < 1e-12, "{c:?} k={k} err {err:e}");
                // Semigroup: Phi(k)^2 = Phi(2k).
                let f2 = filt(GustModel::VonKarman, c, 1.0, 2.0 * k);
                let sq = f.transition() * f.transition();
                assert!(max_abs(&(sq - f2.transition())) < 1e-12);
            }
        }
    }

    #[test]
    fn stationary_covariance_is_identity() {
        for model in MODELS {
            for c in GustComponent::ALL {
                for k in KS {
                    let f = filt(model, c, 1.0, k);
                    let n = f.order();
                    let phi = f.transition();
                    let g = f.noise_chol();
                    let mut eye = Matrix3::zeros();
                    for i in 0..n {
                        eye[(i, i)] = 1.0;
                    }
                    // P = Phi P Phi^T + Q with P = I.
                    let p = phi * eye * phi.transpose() + g * g.transpose();
                    let err = max_abs(&(p - eye));
                    assert!(err < 1e-12, "{model:?} {c:?} k={k} err {err:e}");
                    // G lower triangular.
                    for i in 0..3 {
                        for j in i + 1..3 {
                            assert_eq!(g[(i, j)], 0.0);
                        }
                    }
                    // Continuous Lyapunov with P = I: A + A^T + B B^T = 0.
                    let a = f.continuous_a();
                    let b = f.continuous_b();
                    let lyap = a + a.transpose() + b * b.transpose();
                    assert!(max_abs(&lyap) < 1e-12 * f.airspeed() / f.length_scale());
                    // Output variance sigma^2.
                    assert!((f.output_row().norm_squared() - 1.0).abs() < 1e-14);
                    assert!((f.autocorrelation(0.0) - 1.0).abs() < 1e-13);
                }
            }
        }
    }

    #[test]
    fn discrete_autocorrelation_matches_formula() {
        let sigma = 1.7;
        for c in GustComponent::ALL {
            // (k, n) with n k = V tau / L in {0.5, 1, 2, 3, 5}.
            for (k, ns) in [
                (0.5, [1usize, 2, 4, 6, 10]),
                (0.25, [2, 4, 8, 12, 20]),
                (0.1, [5, 10, 20, 30, 50]),
            ] {
                let f = filt(GustModel::Dryden, c, sigma, k);
                for n in ns {
                    let u = n as f64 * k;
                    let mut m = Matrix3::identity();
                    for _ in 0..n {
                        m = f.transition() * m;
                    }
                    let row = f.output_row();
                    let disc = (row.transpose() * m * row)[(0, 0)];
                    let want = if c == GustComponent::Longitudinal {
                        sigma * sigma * (-u).exp()
                    } else {
                        sigma * sigma * (-u).exp() * (1.0 - u / 2.0)
                    };
                    assert!((disc - want).abs() < 1e-12, "{c:?} k={k} n={n}");
                    let tau = n as f64 * f.dt();
                    assert!((f.autocorrelation(tau) - want).abs() < 1e-12);
                    assert!((f.autocorrelation(-tau) - want).abs() < 1e-12);
                }
                // Von Karman: the discrete model against the continuous one.
                let f = filt(GustModel::VonKarman, c, sigma, k);
                for n in ns {
                    let mut m = Matrix3::identity();
                    for _ in 0..n {
                        m = f.transition() * m;
                    }
                    let row = f.output_row();
                    let disc = (row.transpose() * m * row)[(0, 0)];
                    let cont = f.autocorrelation(n as f64 * f.dt());
                    assert!((disc - cont).abs() < 1e-12, "vK {c:?} k={k} n={n}");
                }
            }
        }
    }

    /// Simpson in log-frequency: f = (V/L) e^y, y in [-40, 40].
    fn psd_integral(f: &GustFilter, target: bool) -> f64 {
        let scale = f.airspeed() / f.length_scale();
        let (lo, hi, m) = (-40.0, 40.0, 400_000);
        let h = (hi - lo) / m as f64;
        let g = |y: f64| {
            let fr = scale * f64::exp(y);
            let s = if target { f.target_psd(fr) } else { f.psd(fr) };
            s * fr
        };
        let mut sum = g(lo) + g(hi);
        for i in 1..m {
            let w = if i % 2 == 1 { 4.0 } else { 2.0 };
            sum += w * g(lo + i as f64 * h);
        }
        sum * h / 3.0
    }

    #[test]
    fn psd_closed_forms_and_integral() {
        let sigma = 1.3;
        let pi = std::f64::consts::PI;
        for c in GustComponent::ALL {
            let f = filt(GustModel::Dryden, c, sigma, 0.3);
            let t = f.length_scale() / f.airspeed();
            for fr in [0.0, 0.01, 0.3, 1.0, 7.0, 100.0] {
                let x = 2.0 * pi * fr * t;
                let want = if c == GustComponent::Longitudinal {
                    4.0 * sigma * sigma * t / (1.0 + x * x)
                } else {
                    2.0 * sigma * sigma * t * (1.0 + 3.0 * x * x) / (1.0 + x * x).powi(2)
                };
                assert!((f.psd(fr) - want).abs() <= 1e-14 * want);
            }
            for model in MODELS {
                let f = filt(model, c, sigma, 0.3);
                let v = psd_integral(&f, false);
                assert!(
                    (v / (sigma * sigma) - 1.0).abs() < 1e-9,
                    "{model:?} {c:?}: {v}"
                );
            }
        }
        // Exact von Karman integrates to sigma^2 too, up to the rounding of
        // 1.339 (= Gamma(1/3) / (sqrt(pi) Gamma(5/6)) = 1.338985...): the
        // longitudinal variance is sigma^2 * 1.338985 / 1.339 = 0.999989 sigma^2.
        for c in [GustComponent::Longitudinal, GustComponent::Vertical] {
            let f = filt(GustModel::VonKarman, c, sigma, 0.3);
            let v = psd_integral(&f, true) / (sigma * sigma);
            assert!((v - 0.999_989).abs() < 1e-5, "{c:?} exact: {v}");
        }
    }

    /// Worst relative error of the published approximant |H|^2 (as published,
    /// no renormalisation) and of the generated PSD (renormalised to variance
    /// sigma^2) against the exact von Karman PSD, for omega L/V in [0.01, x_max].
    fn von_karman_errors(c: GustComponent, x_max: f64) -> (f64, f64) {
        let f = filt(GustModel::VonKarman, c, 1.0, 0.1);
        let t = f.length_scale() / f.airspeed();
        let mut worst_raw = 0.0_f64;
        let mut worst_norm = 0.0_f64;
        let n = 4001;
        let decades = (x_max / 0.01).log10();
        for i in 0..n {
            let x = 0.01 * 10f64.powf(decades * i as f64 / (n - 1) as f64);
            let fr = x / (2.0 * std::f64::consts::PI * t);
            let exact = f.target_psd(fr);
            let gen = f.psd(fr);
            let raw = gen * f.approximant_variance_ratio();
            worst_raw = worst_raw.max((raw / exact - 1.0).abs());
            worst_norm = worst_norm.max((gen / exact - 1.0).abs());
        }
        (worst_raw, worst_norm)
    }

    #[test]
    fn von_karman_approximant_accuracy() {
        // The numbers quoted in docs/gust.md.
        let lon = filt(GustModel::VonKarman, GustComponent::Longitudinal, 1.0, 0.1);
        let ver = filt(GustModel::VonKarman, GustComponent::Vertical, 1.0, 0.1);
        let (rl, rv) = (
            lon.approximant_variance_ratio(),
            ver.approximant_variance_ratio(),
        );
        println!("variance ratio: longitudinal {rl:.6}, vertical {rv:.6}");
        assert!((rl - 0.968_714).abs() < 1e-6, "{rl}");
        assert!((rv - 0.962_336).abs() < 1e-6, "{rv}");
        for (c, band10, band100) in [
            (GustComponent::Longitudinal, (0.034, 0.062), (0.447, 0.429)),
            (GustComponent::Vertical, (0.046, 0.06), (0.364, 0.339)),
        ] {
            let e10 = von_karman_errors(c, 10.0);
            let e100 = von_karman_errors(c, 100.0);
            println!("{c:?}: worst (raw, renormalised) to 10: {e10:.4?}, to 100: {e100:.4?}");
            assert!(e10.0 < band10.0 && e10.1 < band10.1, "{c:?} {e10:?}");
            assert!(e100.0 < band100.0 && e100.1 < band100.1, "{c:?} {e100:?}");
        }
    }

    #[test]
    fn noise_factor_is_robust_for_extreme_steps() {
        for model in MODELS {
            for c in GustComponent::ALL {
                for k in [1e-12, 1e-9, 1e-6, 1e-3, 1e3, 1e5, 1e12, 1e300] {
                    let f = filt(model, c, 1.0, k);
                    let phi = f.transition();
                    let g = f.noise_chol();
                    assert!(phi.iter().chain(g.iter()).all(|v| v.is_finite()));
                    let n = f.order();
                    let mut q = -phi * phi.transpose();
                    for i in 0..n {
                        q[(i, i)] += 1.0;
                    }
                    let err = max_abs(&(g * g.transpose() - q));
                    assert!(err < 1e-12, "{model:?} {c:?} k={k:e} err {err:e}");
                    assert!(f.autocorrelation(1e300).is_finite());
                }
            }
        }
        // Tiny k, vertical Dryden: the cancellation-free Q keeps G exact:
        // G11^2 = Q11 = e^-2k S3(2k) ~ (2k)^3 / 6.
        let k = 1e-7;
        let f = filt(GustModel::Dryden, GustComponent::Vertical, 1.0, k);
        let g11 = f.noise_chol()[(0, 0)];
        let x = 2.0 * k;
        assert!((g11 * g11 / (x * x * x / 6.0) - 1.0).abs() < 1e-6);
    }

    #[test]
    fn rescaled_coefficients_are_the_rescaled_filters_bit_for_bit() {
        let bits = |c: &Coefficients| {
            let mut v: Vec<u64> = c
                .phi
                .iter()
                .chain(&c.g)
                .flatten()
                .map(|x| x.to_bits())
                .collect();
            v.extend(c.out.iter().map(|x| x.to_bits()));
            v
        };
        let nan = f64::NAN;
        // Ordinary scales, steps long and short in scale lengths (both branches of Q), and
        // scales no filter takes (a runaway state): NaN numbers, as `poisoned` flies.
        let scales = [
            (1.3, 30.0, 10.0),
            (0.4, 3.048, 1.0),
            (2.0, 0.01, 500.0),
            (1.0, 1e4, 1e-3),
            (0.0, 5.0, 2.0),
            (nan, 5.0, 2.0),
            (1.0, nan, 2.0),
            (1.0, 5.0, nan),
            (1.0, 5.0, 0.0),
            (-1.0, 5.0, 2.0),
        ];
        for model in MODELS {
            for c in GustComponent::ALL {
                let base = filt(model, c, 1.0, 0.2);
                for (sigma, l, v) in scales {
                    let got = base.rescaled_coefficients(sigma, l, v);
                    let following = base.rescaled_following(sigma, l, v).coefficients();
                    assert_eq!(bits(&got), bits(&following), "{model:?} {c:?}");
                    match base.rescaled(sigma, l, v) {
                        // Von Karman: rescaled's; Dryden: the lane-valued exp and expm1 in
                        // place of libm's, so within a few ulp of the built filter.
                        Ok(f) if model == GustModel::VonKarman => {
                            assert_eq!(bits(&got), bits(&f.coefficients()), "{model:?} {c:?}")
                        }
                        Ok(f) => {
                            let want = f.coefficients();
                            let close = |a: f64, b: f64| {
                                (a - b).abs() <= 8.0 * f64::EPSILON * b.abs().max(1e-300)
                            };
                            for i in 0..3 {
                                assert!(close(got.out[i], want.out[i]), "out {c:?} {sigma}");
                                for j in 0..3 {
                                    assert!(close(got.phi[i][j], want.phi[i][j]), "phi {c:?}");
                                    assert!(
                                        close(got.g[i][j], want.g[i][j]),
                                        "g {c:?} {l} {v}: {} vs {}",
                                        got.g[i][j],
                                        want.g[i][j]
                                    );
                                }
                            }
                        }
                        Err(_) => assert_eq!(bits(&got), bits(&Coefficients::NAN)),
                    }
                }
            }
        }
    }

    #[test]
    fn noise_factor_fallback_on_singular_matrices() {
        let singular = DMatrix::from_row_slice(2, 2, &[1.0, 1.0, 1.0, 1.0]);
        let g = noise_factor(&singular).unwrap();
        assert!(((&g * g.transpose()) - &singular).amax() < 1e-12);
        let indefinite = DMatrix::from_row_slice(2, 2, &[1.0, 0.0, 0.0, -1e-17]);
        let g = noise_factor(&indefinite).unwrap();
        assert!(g.iter().all(|v| v.is_finite()));
        assert!(((&g * g.transpose()) - &indefinite).amax() < 1e-15);
        let zero = DMatrix::<f64>::zeros(3, 3);
        assert_eq!(noise_factor(&zero).unwrap().amax(), 0.0);
        let nan = DMatrix::from_row_slice(1, 1, &[f64::NAN]);
        assert!(noise_factor(&nan).is_err());
    }

    #[test]
    fn bad_input_is_rejected_with_the_parameter_named() {
        let d = GustModel::Dryden;
        let v = GustComponent::Vertical;
        let e = GustFilter::new(d, v, 1.0, 2.0, 0.0, 0.01).unwrap_err();
        assert_eq!(
            e,
            "airspeed must be > 0 (the Dryden filters are singular at zero airspeed), got 0.0"
        );
        let e = GustFilter::new(d, v, -1.0, 2.0, 10.0, 0.01).unwrap_err();
        assert_eq!(e, "sigma must be >= 0, got -1.0");
        let e = GustFilter::new(d, v, 1.0, 0.0, 10.0, 0.01).unwrap_err();
        assert_eq!(e, "length_scale must be > 0, got 0.0");
        let e = GustFilter::new(d, v, 1.0, 2.0, 10.0, -0.01).unwrap_err();
        assert_eq!(e, "dt must be > 0, got -0.01");
        let e = GustFilter::new(d, v, f64::NAN, 2.0, 10.0, 0.01).unwrap_err();
        assert_eq!(e, "sigma must be finite, got NaN");
        let e = GustFilter::new(d, v, 1.0, 2.0, f64::INFINITY, 0.01).unwrap_err();
        assert_eq!(e, "airspeed must be finite, got inf");
        let e = GustFilter::new(d, v, 1.0, 1e300, 1e-300, 1e-300).unwrap_err();
        assert!(e.starts_with("airspeed * dt / length_scale"), "{e}");
        assert!(GustFilter::new(d, v, 0.0, 2.0, 10.0, 0.01).is_ok());
    }

    // ---- The lane-set's Dryden numbers ------------------------------------------------

    /// Values from `pick` in groups of `L::LANES`, each group as lane values (the last group
    /// padded with the first values).
    fn groups<L: KernelOps, T: Copy>(all: &[T], mut each: impl FnMut(&[T])) {
        let n = L::LANES;
        let padded: Vec<T> = all
            .iter()
            .chain(all.iter())
            .copied()
            .take(all.len().div_ceil(n) * n)
            .collect();
        for g in padded.chunks(n) {
            each(g);
        }
    }

    /// Edge cases of `exp_tail3`'s series (nothing, underflow, a single term, every length up
    /// to the cap, the branch's edge at 2) and a random spread, including lanes it must leave.
    fn tail_inputs() -> Vec<f64> {
        use rand::{RngExt, SeedableRng};
        let mut xs = vec![
            0.0,
            -0.0,
            f64::MIN_POSITIVE,
            5e-324,
            1e-300,
            1e-100,
            1e-20,
            1e-10,
            6e-4,
            2e-3,
            0.1,
            0.5,
            1.0,
            1.5,
            1.999_999_999_999_999_8,
            2.0,
            2.000_000_000_000_000_4,
            3.0,
            -0.5,
            -2.0,
            f64::NAN,
            f64::INFINITY,
        ];
        let mut rng = ChaCha8Rng::seed_from_u64(36);
        for _ in 0..400 {
            let e: f64 = rng.random_range(-30.0..0.5);
            xs.push(2.0 * 10f64.powf(e).min(1.0) * rng.random_range(0.5..1.0));
        }
        xs
    }

    fn exp_tail3_lanes_match<L: KernelOps>() {
        let xs = tail_inputs();
        // In input order and in a shuffled order, so lanes of every length share a set.
        let mut shuffled = xs.clone();
        shuffled.reverse();
        shuffled.rotate_left(7);
        for all in [&xs, &shuffled] {
            groups::<L, f64>(all, |g| {
                let x = L::from_fn(|l| g[l]);
                let got = exp_tail3_lanes(x, x.cmp_le(L::splat(2.0)));
                for (l, &x) in g.iter().enumerate() {
                    let want = if x <= 2.0 { exp_tail3(x) } else { 0.0 };
                    assert_eq!(got.lane(l).to_bits(), want.to_bits(), "x = {x:e}");
                }
            });
        }
    }

    /// Run `check::<L>()` on every lane type: the portable ones always, the AVX2 and AVX-512
    /// ones where this CPU has them.
    macro_rules! on_every_lane_type {
        ($check:ident) => {{
            $check::<f64>();
            $check::<crate::lane::F64x4>();
            #[cfg(target_arch = "x86_64")]
            {
                use crate::lane::isa::Isa;
                if Isa::Avx2.supported() {
                    $check::<crate::lane::F64x4Avx>();
                }
                if Isa::Avx512.supported() {
                    $check::<crate::lane::F64x8Avx512>();
                }
            }
        }};
    }

    #[test]
    fn exp_tail3_lanes_is_exp_tail3_bit_for_bit() {
        on_every_lane_type!(exp_tail3_lanes_match);
    }

    type Scales = (f64, f64, f64, f64);

    /// Scales (sigma, L, V, dt) of every kind: the delivery's (k ~ 1e-4), both branches of `Q`
    /// and the edge between them (k = 1: x = 2), the cap, and scales no filter takes.
    fn scale_inputs() -> Vec<Scales> {
        use rand::{RngExt, SeedableRng};
        let nan = f64::NAN;
        let mut s = vec![
            (1.3, 30.0, 10.0, 1e-3),
            (0.4, 3.048, 1.0, 1e-3),
            (2.0, 0.01, 500.0, 1e-3),
            (1.0, 1e4, 1e-3, 1e-3),
            (0.0, 5.0, 2.0, 1e-3),
            (1.0, 1.0, 1.0, 1.0),
            (1.0, 1.0, 1.0, 0.999_999_999_999_999_9),
            (1.0, 1.0, 1.0, 1.000_000_000_000_000_2),
            (1.0, 2.0, 10.0, 0.2),
            (1.0, 1e-3, 1e4, 1e3),
            (1.0, 1e-300, 1e300, 1.0),
            (1.0, 1e300, 1e-300, 1e-300),
            (nan, 5.0, 2.0, 1e-3),
            (1.0, nan, 2.0, 1e-3),
            (1.0, 5.0, nan, 1e-3),
            (1.0, 5.0, 0.0, 1e-3),
            (1.0, 0.0, 2.0, 1e-3),
            (1.0, -5.0, 2.0, 1e-3),
            (-1.0, 5.0, 2.0, 1e-3),
            (f64::INFINITY, 5.0, 2.0, 1e-3),
            (1.0, f64::INFINITY, 2.0, 1e-3),
            (1.0, 5.0, f64::INFINITY, 1e-3),
        ];
        let mut rng = ChaCha8Rng::seed_from_u64(37);
        for _ in 0..300 {
            let l = 10f64.powf(rng.random_range(-1.0..3.0));
            let v = 10f64.powf(rng.random_range(-1.0..2.0));
            let dt = [1e-3, 2e-3, 1e-2, 0.1][rng.random_range(0..4)];
            s.push((rng.random_range(0.0..3.0), l, v, dt));
        }
        s
    }

    fn dryden_lanes_match<L: KernelOps>() {
        let scales = scale_inputs();
        let bits = |x: f64| x.to_bits();
        for c in GustComponent::ALL {
            let n = if c == GustComponent::Longitudinal {
                1
            } else {
                2
            };
            groups::<L, Scales>(&scales, |g| {
                let lanes = |f: &dyn Fn(&Scales) -> f64| L::from_fn(|l| f(&g[l]));
                let base: Vec<GustFilter> = g
                    .iter()
                    .map(|s| GustFilter::new(GustModel::Dryden, c, 1.0, 2.0, 10.0, s.3).unwrap())
                    .collect();
                let unit = [0, 1].map(|i| L::from_fn(|l| base[l].unit_output()[i]));
                {
                    let seven = L::splat(7.0);
                    let (mut phi, mut g3, mut out) = ([[seven; 3]; 3], [[seven; 3]; 3], [seven; 3]);
                    dryden_lanes(
                        c,
                        lanes(&|s| s.0),
                        lanes(&|s| s.1),
                        lanes(&|s| s.2),
                        lanes(&|s| s.3),
                        unit,
                        DrydenLanes {
                            phi: &mut phi,
                            g: &mut g3,
                            out: &mut out,
                        },
                    );
                    let d = DrydenLanes {
                        phi: &mut phi,
                        g: &mut g3,
                        out: &mut out,
                    };
                    for (l, s) in g.iter().enumerate() {
                        let want = base[l].rescaled_coefficients(s.0, s.1, s.2);
                        let at = format!("{c:?} {s:?}");
                        for i in 0..n {
                            assert_eq!(bits(d.out[i].lane(l)), bits(want.out[i]), "out {at}");
                            for j in 0..n {
                                assert_eq!(
                                    bits(d.phi[i][j].lane(l)),
                                    bits(want.phi[i][j]),
                                    "phi {at}"
                                );
                                assert_eq!(bits(d.g[i][j].lane(l)), bits(want.g[i][j]), "g {at}");
                            }
                        }
                    }
                }
            });
        }
    }

    #[test]
    fn dryden_lanes_are_rescaled_coefficients_bit_for_bit() {
        on_every_lane_type!(dryden_lanes_match);
    }
}
