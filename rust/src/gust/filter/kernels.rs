//! The per-step kernels of a forming filter: the state update `x' = Phi x + G n` with fresh
//! normals, and the Dryden coefficients of every lane of a lane-set at once (for scales that
//! follow the vehicle, rebuilt every step).

use super::design::{noise_factor, K_MAX};
use super::GustFilter;
use crate::config::GustComponent;
use crate::lane::{explog, KernelOps};
use nalgebra::DMatrix;
use rand_chacha::ChaCha8Rng;

/// Lanes where `mask` (all bits set: true) is false in every lane.
#[inline(always)]
fn none<L: KernelOps>(mask: L) -> bool {
    // A true lane is all ones (a NaN, so never <= 0), a false one +0.
    mask.le_mask(L::splat(0.0)) == L::ALL
}

/// The least positive double (a subnormal): `x > 0` is `x >= TINY`.
const TINY: f64 = f64::from_bits(1);

/// Mask (all bits set where true) of `x > 0`, false for NaN: one comparison.
#[inline(always)]
fn positive<L: KernelOps>(x: L) -> L {
    x.cmp_ge(L::splat(TINY))
}

/// Mask of `x > 0` and finite. (A function, not a closure: a closure the optimiser leaves out
/// of line is compiled without the lane type's instruction set, every lane operation in it a
/// call.)
#[inline(always)]
fn finite_positive<L: KernelOps>(x: L) -> L {
    positive(x).and_bits(x.cmp_le(L::splat(f64::MAX)))
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
pub(in crate::gust) fn exp_tail3_lanes<L: KernelOps>(x: L, mut active: L) -> L {
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
pub(in crate::gust) struct DrydenLanes<'a, L> {
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
pub(in crate::gust) fn dryden_lanes<L: KernelOps>(
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
    let valid = finite(sigma)
        .and_bits(sigma.cmp_ge(zero))
        .and_bits(finite_positive(length))
        .and_bits(finite_positive(airspeed))
        .and_bits(finite_positive(dt))
        .and_bits(finite_positive(k));
    // `dryden_matrices`' cap.
    let kc = k.min(L::splat(K_MAX));
    // Where `2 k` is near 0 (k of order 1e-3 in flight), every exponential below is a short
    // Taylor series; the lanes beyond it (rare) take the general functions, evaluated only
    // when a lane needs them. Each lane's numbers depend on its own k only, so every lane
    // path gives the same bits.
    let near = kc.cmp_le(L::splat(0.5 * explog::NEAR0));
    let far = valid.xor_bits(valid.and_bits(near));
    let any_far = !none(far);
    // (A macro, not a closure: see `finite_positive`.)
    macro_rules! near_or {
        ($fast:expr, $general:expr) => {
            if any_far {
                L::select(near, $fast, $general)
            } else {
                $fast
            }
        };
    }
    // Near 0 one series serves every axis: e^-k = 1 + expm1(-k) (exact to rounding: the sum
    // is near 1), e^-2k = (e^-k)^2 and expm1(-2k) = expm1(-k) (2 + expm1(-k)), within 1.5 ulp.
    let em1 = explog::expm1_near0(-kc);
    let e = near_or!(L::splat(1.0) + em1, explog::exp(-kc));
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
            let m2k = L::splat(-2.0) * kc;
            let m = near_or!(em1 * (L::splat(2.0) + em1), explog::expm1(m2k));
            d.phi[0][0] = e;
            d.g[0][0] = (-m).sqrt();
        }
        GustComponent::Lateral | GustComponent::Vertical => {
            d.phi[0][0] = e * (L::splat(1.0) + kc);
            d.phi[0][1] = e * kc;
            d.phi[1][0] = -e * kc;
            d.phi[1][1] = e * (L::splat(1.0) - kc);
            let x = L::splat(2.0) * kc;
            let ex = near_or!(e * e, explog::exp(-x));
            let series = x.cmp_le(L::splat(2.0));
            let s3 = near_or!(
                explog::tail3_near0(x),
                exp_tail3_lanes(x, series.and_bits(far))
            );
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
        rare_lanes(d, n, q, rejected, fallback);
    }
}

/// [`dryden_lanes`]' lanes whose scales `rescaled_coefficients` rejects (bits of `rejected`:
/// NaN) and those whose Cholesky pivot is not positive (bits of `fallback`: `chol2`'s fallback,
/// `noise_factor`'s eigen-factor of the lane's `I - Phi Phi^T`, `q` = its q11, q12, q22). Out
/// of line: no flight's lanes take it.
#[cold]
fn rare_lanes<L: KernelOps>(
    d: DrydenLanes<'_, L>,
    n: usize,
    q: [L; 3],
    rejected: u32,
    fallback: u32,
) {
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
pub(in crate::gust) fn step_fixed<const N: usize>(
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
impl GustFilter {
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
    pub(in crate::gust) fn fixed<const N: usize>(
        &self,
    ) -> ([[f64; N]; N], [[f64; N]; N], [f64; N]) {
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
}
