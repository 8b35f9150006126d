//! The number type of the hot loop: one realisation (`f64`) or four at once (`f64x4`).
//!
//! The model, the controllers and the integrator are written once, generic over `Lane`, so the
//! scalar path (single flights, traces) and the SIMD path (Monte Carlo batches) are the same
//! code. Parameters stay scalar `f64`; only states, inputs and wind differ per lane.

use std::ops::{Add, AddAssign, Div, Mul, Neg, Sub};
use wide::f64x4;

pub trait Lane:
    Copy
    + Send
    + Sync
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + AddAssign
    + Add<f64, Output = Self>
    + Sub<f64, Output = Self>
    + Mul<f64, Output = Self>
{
    /// How many realisations one value carries.
    const LANES: usize;
    fn splat(x: f64) -> Self;
    fn lane(self, i: usize) -> f64;
    fn set_lane(&mut self, i: usize, x: f64);
    fn sin_cos(self) -> (Self, Self);
    fn asin(self) -> Self;
    fn abs(self) -> Self;
    fn sqrt(self) -> Self;
    fn max(self, other: Self) -> Self;
    fn min(self, other: Self) -> Self;
    /// Lane-wise `self <= bound`; false for NaN, so it doubles as a finiteness check.
    fn within(self, bound: Self) -> [bool; 4];

    #[inline(always)]
    fn clamp(self, lo: Self, hi: Self) -> Self {
        self.max(lo).min(hi)
    }
}

impl Lane for f64 {
    const LANES: usize = 1;
    #[inline(always)]
    fn splat(x: f64) -> Self {
        x
    }
    #[inline(always)]
    fn lane(self, _i: usize) -> f64 {
        self
    }
    #[inline(always)]
    fn set_lane(&mut self, _i: usize, x: f64) {
        *self = x;
    }
    #[inline(always)]
    fn sin_cos(self) -> (Self, Self) {
        f64::sin_cos(self)
    }
    #[inline(always)]
    fn asin(self) -> Self {
        f64::asin(self)
    }
    #[inline(always)]
    fn abs(self) -> Self {
        f64::abs(self)
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        f64::sqrt(self)
    }
    #[inline(always)]
    fn max(self, other: Self) -> Self {
        f64::max(self, other)
    }
    #[inline(always)]
    fn min(self, other: Self) -> Self {
        f64::min(self, other)
    }
    #[inline(always)]
    fn within(self, bound: Self) -> [bool; 4] {
        [self <= bound, true, true, true]
    }
}

impl Lane for f64x4 {
    const LANES: usize = 4;
    #[inline(always)]
    fn splat(x: f64) -> Self {
        f64x4::splat(x)
    }
    #[inline(always)]
    fn lane(self, i: usize) -> f64 {
        self.as_array()[i]
    }
    #[inline(always)]
    fn set_lane(&mut self, i: usize, x: f64) {
        let mut a = self.to_array();
        a[i] = x;
        *self = f64x4::new(a);
    }
    #[inline(always)]
    fn sin_cos(self) -> (Self, Self) {
        f64x4::sin_cos(self)
    }
    #[inline(always)]
    fn asin(self) -> Self {
        f64x4::asin(self)
    }
    #[inline(always)]
    fn abs(self) -> Self {
        f64x4::abs(self)
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        f64x4::sqrt(self)
    }
    #[inline(always)]
    fn max(self, other: Self) -> Self {
        f64x4::max(self, other)
    }
    #[inline(always)]
    fn min(self, other: Self) -> Self {
        f64x4::min(self, other)
    }
    #[inline(always)]
    fn within(self, bound: Self) -> [bool; 4] {
        let m = self.simd_le(bound).to_bitmask();
        [m & 1 != 0, m & 2 != 0, m & 4 != 0, m & 8 != 0]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn simd_transcendentals_match_libm() {
        for &x in &[-1.2, -0.5, 0.0, 0.3, 0.9, 2.5] {
            let (s, c) = f64x4::splat(x).sin_cos();
            assert!((s.lane(2) - x.sin()).abs() < 1e-15);
            assert!((c.lane(3) - x.cos()).abs() < 1e-15);
        }
        for &x in &[-1.0, -0.7, 0.0, 0.2, 0.999, 1.0] {
            assert!((Lane::asin(f64x4::splat(x)).lane(1) - x.asin()).abs() < 1e-15);
        }
    }

    #[test]
    fn within_treats_nan_as_out_of_bounds() {
        let v = f64x4::new([0.5, f64::NAN, 2.0, -3.0]);
        assert_eq!(
            v.abs().within(f64x4::splat(1.0)),
            [true, false, false, false]
        );
        assert!(!f64::NAN.within(1.0)[0]);
    }
}
