//! The number type of the hot loop: one realisation (`f64`) or four at once (`F64x4`).
//!
//! The model, the controllers and the integrator are written once, generic over `Lane`, so the
//! scalar path (single flights, traces) and the SIMD path (Monte Carlo batches) are the same
//! code. Parameters are either scalar `f64` (the same vehicle in every lane) or lane values
//! (a different vehicle per lane: dispersed parameters); `Param` reads either as a lane value.
//!
//! Lane types:
//! - `f64`: one realisation.
//! - `F64x4`: four realisations in two SSE2 registers (baseline x86-64, every CPU a wheel runs
//!   on; a plain array elsewhere).
//! - `F64x4Avx` (x86-64, crate-private): the same four lanes in one AVX register. Its
//!   operations are only valid on a CPU with AVX2, so the engine alone creates it, inside the
//!   flight loop compiled with `#[target_feature(enable = "avx2")]` and entered only after a
//!   run-time check (`crate::simd`).
//!
//! Speed: the flight loop is written so that everything it does to lane values is inlined into
//! it (every lane method here is `#[inline(always)]`; closures in the loop are marked so; no
//! `std::array::from_fn` or iterator adaptors on lane values in the loop). An operation left
//! out of line would be compiled without the loop's target features: correct, but an order of
//! magnitude slower for `F64x4Avx`.
//!
//! Reproducibility: every lane operation is a single IEEE-754 operation (add, sub, mul, div,
//! sqrt, compare, select, bit operations) and nothing is fused (Rust never contracts
//! `a * b + c` into an FMA and this crate never calls `mul_add`), so a lane's result is
//! bit-for-bit the same whatever the lane type, the packing of realisations into lanes, the
//! instruction set chosen at run time or the machine. The transcendental functions are our
//! own branch-free kernels (`kernels::sin_cos`, `kernels::asin`) written once over these
//! operations and used by the scalar path too, so scalar and SIMD flights agree exactly. (RK4
//! stages 2-4 get their sines and cosines from stage 1's by angle addition, per lane:
//! `model::Trig::advanced`.) Measurements and the reasons behind these choices:
//! `docs/performance.md`.

use std::ops::{Add, AddAssign, Div, Mul, Neg, Sub};

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
    /// How many realisations one value carries (at most 32).
    const LANES: usize;
    /// `le_mask` of a value whose lanes all pass.
    const ALL: u32 = if Self::LANES >= 32 {
        u32::MAX
    } else {
        (1u32 << Self::LANES) - 1
    };
    fn splat(x: f64) -> Self;
    fn lane(self, i: usize) -> f64;
    fn set_lane(&mut self, i: usize, x: f64);
    fn sin_cos(self) -> (Self, Self);
    fn asin(self) -> Self;
    fn abs(self) -> Self;
    fn sqrt(self) -> Self;
    /// Lane-wise `if self > other { self } else { other }` (x86 `maxpd` semantics).
    fn max(self, other: Self) -> Self;
    /// Lane-wise `if self < other { self } else { other }` (x86 `minpd` semantics).
    fn min(self, other: Self) -> Self;

    /// Lane `i` is `f(i)`.
    #[inline(always)]
    fn from_fn(mut f: impl FnMut(usize) -> f64) -> Self {
        let mut v = Self::splat(0.0);
        for i in 0..Self::LANES {
            v.set_lane(i, f(i));
        }
        v
    }
    /// Bit `i` set where lane `i` has `self <= bound`; clear for NaN, so it doubles as a
    /// finiteness check.
    #[inline(always)]
    fn le_mask(self, bound: Self) -> u32 {
        (0..Self::LANES).fold(0, |m, i| m | ((self.lane(i) <= bound.lane(i)) as u32) << i)
    }
    #[inline(always)]
    fn clamp(self, lo: Self, hi: Self) -> Self {
        self.max(lo).min(hi)
    }
}

/// A model or controller parameter read as a lane value: an `f64` is the same in every lane
/// (`splat`), a lane value differs per lane (a dispersed parameter). Both give the same bits
/// in the arithmetic: `x * splat(p)` is what `x * p` always computed.
pub trait Param<L>: Copy + Send + Sync {
    fn get(self) -> L;
}

impl<L: Lane> Param<L> for f64 {
    #[inline(always)]
    fn get(self) -> L {
        L::splat(self)
    }
}

/// What the branch-free kernels (`kernels::sin_cos`, `kernels::asin`) are built from. A mask is
/// a value whose lanes have all bits set (true) or clear (false); the `_bits` operations act on
/// the lanes' IEEE-754 bit patterns.
pub trait KernelOps: Lane + Param<Self> {
    /// Mask of `self <= other` (false for NaN).
    fn cmp_le(self, other: Self) -> Self;
    /// Mask of `self >= other` (false for NaN).
    fn cmp_ge(self, other: Self) -> Self;
    /// Mask of `self != other` (true for NaN).
    fn cmp_ne(self, other: Self) -> Self;
    /// Lane-wise `if mask { a } else { b }`.
    fn select(mask: Self, a: Self, b: Self) -> Self;
    fn and_bits(self, other: Self) -> Self;
    fn xor_bits(self, other: Self) -> Self;
    /// 64-bit integer sum of the bit patterns.
    fn add_bits(self, other: Self) -> Self;
    /// Bit patterns shifted left by 62.
    fn shl62_bits(self) -> Self;
}

#[inline(always)]
fn mask_f64(b: bool) -> f64 {
    f64::from_bits(if b { u64::MAX } else { 0 })
}

impl Lane for f64 {
    const LANES: usize = 1;
    #[inline(always)]
    fn splat(x: f64) -> Self {
        x
    }
    #[inline(always)]
    fn from_fn(mut f: impl FnMut(usize) -> f64) -> Self {
        f(0)
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
    fn abs(self) -> Self {
        f64::abs(self)
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        f64::sqrt(self)
    }
    #[inline(always)]
    fn max(self, other: Self) -> Self {
        if self > other {
            self
        } else {
            other
        }
    }
    #[inline(always)]
    fn min(self, other: Self) -> Self {
        if self < other {
            self
        } else {
            other
        }
    }
    #[inline(always)]
    fn le_mask(self, bound: Self) -> u32 {
        (self <= bound) as u32
    }
    #[inline(always)]
    fn sin_cos(self) -> (Self, Self) {
        kernels::sin_cos(self)
    }
    #[inline(always)]
    fn asin(self) -> Self {
        kernels::asin(self)
    }
}

impl KernelOps for f64 {
    #[inline(always)]
    fn cmp_le(self, other: Self) -> Self {
        mask_f64(self <= other)
    }
    #[inline(always)]
    fn cmp_ge(self, other: Self) -> Self {
        mask_f64(self >= other)
    }
    #[inline(always)]
    fn cmp_ne(self, other: Self) -> Self {
        mask_f64(self != other)
    }
    #[inline(always)]
    fn select(mask: Self, a: Self, b: Self) -> Self {
        let m = mask.to_bits();
        f64::from_bits((m & a.to_bits()) | (!m & b.to_bits()))
    }
    #[inline(always)]
    fn and_bits(self, other: Self) -> Self {
        f64::from_bits(self.to_bits() & other.to_bits())
    }
    #[inline(always)]
    fn xor_bits(self, other: Self) -> Self {
        f64::from_bits(self.to_bits() ^ other.to_bits())
    }
    #[inline(always)]
    fn add_bits(self, other: Self) -> Self {
        f64::from_bits(self.to_bits().wrapping_add(other.to_bits()))
    }
    #[inline(always)]
    fn shl62_bits(self) -> Self {
        f64::from_bits(self.to_bits() << 62)
    }
}

/// Operators of a lane type from its inherent `add_`, `sub_`, `mul_`, `div_` and `Lane` methods.
macro_rules! lane_ops {
    ($ty:ident) => {
        impl Param<$ty> for $ty {
            #[inline(always)]
            fn get(self) -> Self {
                self
            }
        }
        impl Add for $ty {
            type Output = Self;
            #[inline(always)]
            fn add(self, o: Self) -> Self {
                self.add_(o)
            }
        }
        impl Sub for $ty {
            type Output = Self;
            #[inline(always)]
            fn sub(self, o: Self) -> Self {
                self.sub_(o)
            }
        }
        impl Mul for $ty {
            type Output = Self;
            #[inline(always)]
            fn mul(self, o: Self) -> Self {
                self.mul_(o)
            }
        }
        impl Div for $ty {
            type Output = Self;
            #[inline(always)]
            fn div(self, o: Self) -> Self {
                self.div_(o)
            }
        }
        impl Neg for $ty {
            type Output = Self;
            #[inline(always)]
            fn neg(self) -> Self {
                self.xor_bits(<$ty as Lane>::splat(-0.0))
            }
        }
        impl AddAssign for $ty {
            #[inline(always)]
            fn add_assign(&mut self, o: Self) {
                *self = self.add_(o);
            }
        }
        impl Add<f64> for $ty {
            type Output = Self;
            #[inline(always)]
            fn add(self, o: f64) -> Self {
                self.add_(<$ty as Lane>::splat(o))
            }
        }
        impl Sub<f64> for $ty {
            type Output = Self;
            #[inline(always)]
            fn sub(self, o: f64) -> Self {
                self.sub_(<$ty as Lane>::splat(o))
            }
        }
        impl Mul<f64> for $ty {
            type Output = Self;
            #[inline(always)]
            fn mul(self, o: f64) -> Self {
                self.mul_(<$ty as Lane>::splat(o))
            }
        }
    };
}

#[cfg(target_arch = "x86_64")]
pub use x86::F64x4;
#[cfg(target_arch = "x86_64")]
pub(crate) use x86::F64x4Avx;

#[cfg(target_arch = "x86_64")]
mod x86 {
    use super::{kernels, KernelOps, Lane, Param};
    use std::arch::x86_64::*;
    use std::ops::{Add, AddAssign, Div, Mul, Neg, Sub};

    /// Four realisations in two SSE2 registers (SSE2 is part of every x86-64 CPU).
    #[derive(Clone, Copy, Debug)]
    #[repr(C, align(32))]
    pub struct F64x4(__m128d, __m128d);

    /// An SSE2 intrinsic applied to both halves.
    macro_rules! halves {
        ($f:ident($a:expr)) => {{
            let a = $a;
            // SAFETY: SSE2 is part of x86-64.
            #[allow(unused_unsafe)]
            let r = unsafe { F64x4($f(a.0), $f(a.1)) };
            r
        }};
        ($f:ident($a:expr, $b:expr)) => {{
            let (a, b) = ($a, $b);
            // SAFETY: SSE2 is part of x86-64.
            #[allow(unused_unsafe)]
            let r = unsafe { F64x4($f(a.0, b.0), $f(a.1, b.1)) };
            r
        }};
    }

    #[inline(always)]
    fn add_epi64(a: __m128d, b: __m128d) -> __m128d {
        // SAFETY: SSE2 is part of x86-64.
        unsafe { _mm_castsi128_pd(_mm_add_epi64(_mm_castpd_si128(a), _mm_castpd_si128(b))) }
    }
    #[inline(always)]
    fn shl62(a: __m128d) -> __m128d {
        // SAFETY: SSE2 is part of x86-64.
        unsafe { _mm_castsi128_pd(_mm_slli_epi64::<62>(_mm_castpd_si128(a))) }
    }
    #[inline(always)]
    fn select(m: __m128d, a: __m128d, b: __m128d) -> __m128d {
        // SAFETY: SSE2 is part of x86-64.
        unsafe { _mm_or_pd(_mm_and_pd(m, a), _mm_andnot_pd(m, b)) }
    }
    #[inline(always)]
    fn abs(a: __m128d) -> __m128d {
        // SAFETY: SSE2 is part of x86-64.
        unsafe { _mm_andnot_pd(_mm_set1_pd(-0.0), a) }
    }

    impl F64x4 {
        #[inline(always)]
        pub fn to_array(self) -> [f64; 4] {
            let mut a = [0.0; 4];
            // SAFETY: SSE2; a has room for two f64 at 0 and two at 2.
            unsafe {
                _mm_storeu_pd(a.as_mut_ptr(), self.0);
                _mm_storeu_pd(a.as_mut_ptr().add(2), self.1);
            }
            a
        }
        #[inline(always)]
        pub fn from_array(a: [f64; 4]) -> Self {
            // SAFETY: SSE2; a holds four f64.
            unsafe { Self(_mm_loadu_pd(a.as_ptr()), _mm_loadu_pd(a.as_ptr().add(2))) }
        }
        #[inline(always)]
        fn add_(self, o: Self) -> Self {
            halves!(_mm_add_pd(self, o))
        }
        #[inline(always)]
        fn sub_(self, o: Self) -> Self {
            halves!(_mm_sub_pd(self, o))
        }
        #[inline(always)]
        fn mul_(self, o: Self) -> Self {
            halves!(_mm_mul_pd(self, o))
        }
        #[inline(always)]
        fn div_(self, o: Self) -> Self {
            halves!(_mm_div_pd(self, o))
        }
    }

    lane_ops!(F64x4);

    impl Lane for F64x4 {
        const LANES: usize = 4;
        #[inline(always)]
        fn splat(x: f64) -> Self {
            // SAFETY: SSE2 is part of x86-64.
            let v = unsafe { _mm_set1_pd(x) };
            Self(v, v)
        }
        #[inline(always)]
        fn from_fn(mut f: impl FnMut(usize) -> f64) -> Self {
            Self::from_array([f(0), f(1), f(2), f(3)])
        }
        #[inline(always)]
        fn lane(self, i: usize) -> f64 {
            self.to_array()[i]
        }
        #[inline(always)]
        fn set_lane(&mut self, i: usize, x: f64) {
            let mut a = self.to_array();
            a[i] = x;
            *self = Self::from_array(a);
        }
        #[inline(always)]
        fn sin_cos(self) -> (Self, Self) {
            kernels::sin_cos(self)
        }
        #[inline(always)]
        fn asin(self) -> Self {
            kernels::asin(self)
        }
        #[inline(always)]
        fn abs(self) -> Self {
            halves!(abs(self))
        }
        #[inline(always)]
        fn sqrt(self) -> Self {
            halves!(_mm_sqrt_pd(self))
        }
        #[inline(always)]
        fn max(self, o: Self) -> Self {
            halves!(_mm_max_pd(self, o))
        }
        #[inline(always)]
        fn min(self, o: Self) -> Self {
            halves!(_mm_min_pd(self, o))
        }
        #[inline(always)]
        fn le_mask(self, bound: Self) -> u32 {
            let m = self.cmp_le(bound);
            // SAFETY: SSE2 is part of x86-64.
            unsafe { (_mm_movemask_pd(m.0) | (_mm_movemask_pd(m.1) << 2)) as u32 }
        }
    }

    impl KernelOps for F64x4 {
        #[inline(always)]
        fn cmp_le(self, o: Self) -> Self {
            halves!(_mm_cmple_pd(self, o))
        }
        #[inline(always)]
        fn cmp_ge(self, o: Self) -> Self {
            halves!(_mm_cmpge_pd(self, o))
        }
        #[inline(always)]
        fn cmp_ne(self, o: Self) -> Self {
            halves!(_mm_cmpneq_pd(self, o))
        }
        #[inline(always)]
        fn select(m: Self, a: Self, b: Self) -> Self {
            Self(select(m.0, a.0, b.0), select(m.1, a.1, b.1))
        }
        #[inline(always)]
        fn and_bits(self, o: Self) -> Self {
            halves!(_mm_and_pd(self, o))
        }
        #[inline(always)]
        fn xor_bits(self, o: Self) -> Self {
            halves!(_mm_xor_pd(self, o))
        }
        #[inline(always)]
        fn add_bits(self, o: Self) -> Self {
            halves!(add_epi64(self, o))
        }
        #[inline(always)]
        fn shl62_bits(self) -> Self {
            halves!(shl62(self))
        }
    }

    /// Four realisations in one AVX register.
    ///
    /// Every operation executes AVX/AVX2 instructions: only create values of this type on a
    /// CPU that has AVX2 (the engine does so inside `Engine::fly_avx2`, after checking). All
    /// `unsafe` blocks below rely on that invariant. For speed, every method is
    /// `#[inline(always)]` so that it lands in the AVX2-compiled flight loop; an operation
    /// left out of line there would still be correct, only slow.
    #[derive(Clone, Copy, Debug)]
    #[repr(transparent)]
    pub(crate) struct F64x4Avx(__m256d);

    /// An AVX intrinsic applied to the register(s).
    macro_rules! avx {
        ($f:ident($($a:expr),+)) => {
            // SAFETY: AVX2 is available (type invariant).
            F64x4Avx(unsafe { $f($($a.0),+) })
        };
    }

    impl F64x4Avx {
        #[inline(always)]
        fn to_array(self) -> [f64; 4] {
            let mut a = [0.0; 4];
            // SAFETY: AVX is available (type invariant); a holds four f64.
            unsafe { _mm256_storeu_pd(a.as_mut_ptr(), self.0) };
            a
        }
        #[inline(always)]
        fn from_array(a: [f64; 4]) -> Self {
            // SAFETY: AVX is available (type invariant); a holds four f64.
            Self(unsafe { _mm256_loadu_pd(a.as_ptr()) })
        }
        #[inline(always)]
        fn add_(self, o: Self) -> Self {
            avx!(_mm256_add_pd(self, o))
        }
        #[inline(always)]
        fn sub_(self, o: Self) -> Self {
            avx!(_mm256_sub_pd(self, o))
        }
        #[inline(always)]
        fn mul_(self, o: Self) -> Self {
            avx!(_mm256_mul_pd(self, o))
        }
        #[inline(always)]
        fn div_(self, o: Self) -> Self {
            avx!(_mm256_div_pd(self, o))
        }
    }

    lane_ops!(F64x4Avx);

    impl Lane for F64x4Avx {
        const LANES: usize = 4;
        #[inline(always)]
        fn splat(x: f64) -> Self {
            // SAFETY: AVX is available (type invariant).
            Self(unsafe { _mm256_set1_pd(x) })
        }
        #[inline(always)]
        fn from_fn(mut f: impl FnMut(usize) -> f64) -> Self {
            Self::from_array([f(0), f(1), f(2), f(3)])
        }
        #[inline(always)]
        fn lane(self, i: usize) -> f64 {
            self.to_array()[i]
        }
        #[inline(always)]
        fn set_lane(&mut self, i: usize, x: f64) {
            let mut a = self.to_array();
            a[i] = x;
            *self = Self::from_array(a);
        }
        #[inline(always)]
        fn sin_cos(self) -> (Self, Self) {
            kernels::sin_cos(self)
        }
        #[inline(always)]
        fn asin(self) -> Self {
            kernels::asin(self)
        }
        #[inline(always)]
        fn abs(self) -> Self {
            self.and_bits(Self::splat(f64::from_bits(!(1u64 << 63))))
        }
        #[inline(always)]
        fn sqrt(self) -> Self {
            avx!(_mm256_sqrt_pd(self))
        }
        #[inline(always)]
        fn max(self, o: Self) -> Self {
            avx!(_mm256_max_pd(self, o))
        }
        #[inline(always)]
        fn min(self, o: Self) -> Self {
            avx!(_mm256_min_pd(self, o))
        }
        #[inline(always)]
        fn le_mask(self, bound: Self) -> u32 {
            // SAFETY: AVX is available (type invariant).
            unsafe { _mm256_movemask_pd(self.cmp_le(bound).0) as u32 }
        }
    }

    impl KernelOps for F64x4Avx {
        #[inline(always)]
        fn cmp_le(self, o: Self) -> Self {
            // SAFETY: AVX is available (type invariant).
            Self(unsafe { _mm256_cmp_pd::<_CMP_LE_OQ>(self.0, o.0) })
        }
        #[inline(always)]
        fn cmp_ge(self, o: Self) -> Self {
            // SAFETY: AVX is available (type invariant).
            Self(unsafe { _mm256_cmp_pd::<_CMP_GE_OQ>(self.0, o.0) })
        }
        #[inline(always)]
        fn cmp_ne(self, o: Self) -> Self {
            // SAFETY: AVX is available (type invariant).
            Self(unsafe { _mm256_cmp_pd::<_CMP_NEQ_UQ>(self.0, o.0) })
        }
        #[inline(always)]
        fn select(m: Self, a: Self, b: Self) -> Self {
            avx!(_mm256_blendv_pd(b, a, m))
        }
        #[inline(always)]
        fn and_bits(self, o: Self) -> Self {
            avx!(_mm256_and_pd(self, o))
        }
        #[inline(always)]
        fn xor_bits(self, o: Self) -> Self {
            avx!(_mm256_xor_pd(self, o))
        }
        #[inline(always)]
        fn add_bits(self, o: Self) -> Self {
            // SAFETY: AVX2 is available (type invariant).
            Self(unsafe {
                _mm256_castsi256_pd(_mm256_add_epi64(
                    _mm256_castpd_si256(self.0),
                    _mm256_castpd_si256(o.0),
                ))
            })
        }
        #[inline(always)]
        fn shl62_bits(self) -> Self {
            // SAFETY: AVX2 is available (type invariant).
            Self(unsafe {
                _mm256_castsi256_pd(_mm256_slli_epi64::<62>(_mm256_castpd_si256(self.0)))
            })
        }
    }
}

#[cfg(not(target_arch = "x86_64"))]
pub use portable::F64x4;

/// Elsewhere: four lanes as a plain array, operation by operation (LLVM vectorises what it can).
/// Also compiled, and tested, on x86-64 test builds.
#[cfg(any(not(target_arch = "x86_64"), test))]
#[cfg_attr(test, allow(dead_code))]
mod portable {
    use super::{kernels, KernelOps, Lane, Param};
    use std::ops::{Add, AddAssign, Div, Mul, Neg, Sub};

    #[derive(Clone, Copy, Debug)]
    #[repr(C, align(32))]
    pub struct F64x4(pub [f64; 4]);

    macro_rules! each {
        (|$x:ident| $e:expr, $a:expr) => {{
            let a = $a.0;
            let f = |$x: f64| $e;
            F64x4([f(a[0]), f(a[1]), f(a[2]), f(a[3])])
        }};
        (|$x:ident, $y:ident| $e:expr, $a:expr, $b:expr) => {{
            let (a, b) = ($a.0, $b.0);
            let f = |$x: f64, $y: f64| $e;
            F64x4([f(a[0], b[0]), f(a[1], b[1]), f(a[2], b[2]), f(a[3], b[3])])
        }};
    }

    impl F64x4 {
        #[inline(always)]
        pub fn to_array(self) -> [f64; 4] {
            self.0
        }
        #[inline(always)]
        pub fn from_array(a: [f64; 4]) -> Self {
            Self(a)
        }
        #[inline(always)]
        fn add_(self, o: Self) -> Self {
            each!(|x, y| x + y, self, o)
        }
        #[inline(always)]
        fn sub_(self, o: Self) -> Self {
            each!(|x, y| x - y, self, o)
        }
        #[inline(always)]
        fn mul_(self, o: Self) -> Self {
            each!(|x, y| x * y, self, o)
        }
        #[inline(always)]
        fn div_(self, o: Self) -> Self {
            each!(|x, y| x / y, self, o)
        }
    }

    lane_ops!(F64x4);

    impl Lane for F64x4 {
        const LANES: usize = 4;
        #[inline(always)]
        fn splat(x: f64) -> Self {
            Self([x; 4])
        }
        #[inline(always)]
        fn from_fn(mut f: impl FnMut(usize) -> f64) -> Self {
            Self([f(0), f(1), f(2), f(3)])
        }
        #[inline(always)]
        fn lane(self, i: usize) -> f64 {
            self.0[i]
        }
        #[inline(always)]
        fn set_lane(&mut self, i: usize, x: f64) {
            self.0[i] = x;
        }
        #[inline(always)]
        fn sin_cos(self) -> (Self, Self) {
            kernels::sin_cos(self)
        }
        #[inline(always)]
        fn asin(self) -> Self {
            kernels::asin(self)
        }
        #[inline(always)]
        fn abs(self) -> Self {
            each!(|x| x.abs(), self)
        }
        #[inline(always)]
        fn sqrt(self) -> Self {
            each!(|x| x.sqrt(), self)
        }
        #[inline(always)]
        fn max(self, o: Self) -> Self {
            each!(|x, y| Lane::max(x, y), self, o)
        }
        #[inline(always)]
        fn min(self, o: Self) -> Self {
            each!(|x, y| Lane::min(x, y), self, o)
        }
        #[inline(always)]
        fn le_mask(self, bound: Self) -> u32 {
            let (a, b) = (self.0, bound.0);
            (a[0] <= b[0]) as u32
                | ((a[1] <= b[1]) as u32) << 1
                | ((a[2] <= b[2]) as u32) << 2
                | ((a[3] <= b[3]) as u32) << 3
        }
    }

    impl KernelOps for F64x4 {
        #[inline(always)]
        fn cmp_le(self, o: Self) -> Self {
            each!(|x, y| KernelOps::cmp_le(x, y), self, o)
        }
        #[inline(always)]
        fn cmp_ge(self, o: Self) -> Self {
            each!(|x, y| KernelOps::cmp_ge(x, y), self, o)
        }
        #[inline(always)]
        fn cmp_ne(self, o: Self) -> Self {
            each!(|x, y| KernelOps::cmp_ne(x, y), self, o)
        }
        #[inline(always)]
        fn select(m: Self, a: Self, b: Self) -> Self {
            let (m, a, b) = (m.0, a.0, b.0);
            let f = <f64 as KernelOps>::select;
            Self([
                f(m[0], a[0], b[0]),
                f(m[1], a[1], b[1]),
                f(m[2], a[2], b[2]),
                f(m[3], a[3], b[3]),
            ])
        }
        #[inline(always)]
        fn and_bits(self, o: Self) -> Self {
            each!(|x, y| x.and_bits(y), self, o)
        }
        #[inline(always)]
        fn xor_bits(self, o: Self) -> Self {
            each!(|x, y| x.xor_bits(y), self, o)
        }
        #[inline(always)]
        fn add_bits(self, o: Self) -> Self {
            each!(|x, y| x.add_bits(y), self, o)
        }
        #[inline(always)]
        fn shl62_bits(self) -> Self {
            each!(|x| x.shl62_bits(), self)
        }
    }
}

/// Branch-free sin/cos and asin over any `Lane`. The algorithms and constants are those of
/// `wide` 1.7 (after Agner Fog's vector class library, from Cephes), evaluated in the same
/// order without FMA, so batches give exactly what they gave with `wide::f64x4` before.
#[allow(clippy::excessive_precision)] // the published Cephes digits, kept as published
pub mod kernels {
    use super::KernelOps;

    const P0SIN: f64 = -1.666_666_666_666_663_072_95E-1;
    const P1SIN: f64 = 8.333_333_333_322_118_588_78E-3;
    const P2SIN: f64 = -1.984_126_982_958_953_859_96E-4;
    const P3SIN: f64 = 2.755_731_362_138_572_452_13E-6;
    const P4SIN: f64 = -2.505_074_776_285_780_728_66E-8;
    const P5SIN: f64 = 1.589_623_015_765_465_680_60E-10;

    const P0COS: f64 = 4.166_666_666_666_659_292_18E-2;
    const P1COS: f64 = -1.388_888_888_887_305_641_16E-3;
    const P2COS: f64 = 2.480_158_728_885_170_453_48E-5;
    const P3COS: f64 = -2.755_731_417_929_673_881_12E-7;
    const P4COS: f64 = 2.087_570_084_197_473_167_78E-9;
    const P5COS: f64 = -1.135_853_652_138_768_173_00E-11;

    /// pi/2 in three parts (Cody-Waite); DP1 has 25 significant bits, so y * DP1 is exact for
    /// y < 2^28.
    const DP1: f64 = 7.853_981_554_508_209_228_515_625E-1 * 2.0;
    const DP2: f64 = 7.946_627_356_147_928_367_14E-9 * 2.0;
    const DP3: f64 = 3.061_616_997_868_382_943_07E-17 * 2.0;

    /// 1.5 * 2^52: `x + ROUND - ROUND` rounds x (0 <= x < 2^51) to the nearest integer, ties
    /// to even, and leaves that integer in the low mantissa bits of `x + ROUND`.
    const ROUND: f64 = 6_755_399_441_055_744.0;
    /// Beyond this |x| (rad) the reduction loses accuracy: sin and cos return NaN, which the
    /// flight's divergence check then flags (no real flight turns a billion radians).
    pub const SIN_COS_LIMIT: f64 = 1.0e9;
    const SIGN: f64 = -0.0;

    /// `c0 + c1 x + ... + c5 x^5`, in wide's `polynomial_5!` order.
    #[inline(always)]
    fn poly5<L: KernelOps>(x: L, c: [f64; 6]) -> L {
        let x2 = x * x;
        let x4 = x2 * x2;
        (x * c[3] + c[2]) * x2 + ((x * c[5] + c[4]) * x4 + (x * c[1] + c[0]))
    }

    /// (sin x, cos x), within about 1 ulp for |x| <= SIN_COS_LIMIT; NaN beyond, and for
    /// non-finite x.
    #[inline(always)]
    pub fn sin_cos<L: KernelOps>(x: L) -> (L, L) {
        let xa = x.abs();
        let t = xa * (2.0 / std::f64::consts::PI) + ROUND;
        let y = t - ROUND;
        let r = ((xa - y * DP1) - y * DP2) - y * DP3;

        let r2 = r * r;
        let s = poly5(r2, [P0SIN, P1SIN, P2SIN, P3SIN, P4SIN, P5SIN]);
        let c = poly5(r2, [P0COS, P1COS, P2COS, P3COS, P4COS, P5COS]);
        let s = (r * r2) * s + r;
        let c = (r2 * r2) * c + (L::splat(1.0) - r2 * 0.5);

        // Quadrant y: odd swaps sin and cos (y / 2 is then not an integer).
        let half = y * 0.5;
        let odd = ((half + ROUND) - ROUND).cmp_ne(half);
        let sin = L::select(odd, c, s);
        let cos = L::select(odd, s, c);
        // Signs from the quadrant's low two bits, held in the low bits of t.
        let sign = L::splat(SIGN);
        let sin = sin.xor_bits(t.shl62_bits().xor_bits(x).and_bits(sign));
        let one = L::splat(f64::from_bits(1));
        let two = L::splat(f64::from_bits(2));
        let cos = cos.xor_bits(t.add_bits(one).and_bits(two).shl62_bits());

        let ok = xa.cmp_le(L::splat(SIN_COS_LIMIT));
        let nan = L::splat(f64::NAN);
        (L::select(ok, sin, nan), L::select(ok, cos, nan))
    }

    const R4ASIN: f64 = 2.967_721_961_301_243_206_100E-3;
    const R3ASIN: f64 = -5.634_242_780_008_963_776_856E-1;
    const R2ASIN: f64 = 6.968_710_824_104_713_396_794E0;
    const R1ASIN: f64 = -2.556_901_049_652_824_852_289E1;
    const R0ASIN: f64 = 2.853_665_548_261_061_424_989E1;

    const S3ASIN: f64 = -2.194_779_531_642_920_639_778E1;
    const S2ASIN: f64 = 1.470_656_354_026_814_941_758E2;
    const S1ASIN: f64 = -3.838_770_957_603_691_357_202E2;
    const S0ASIN: f64 = 3.424_398_657_913_078_477_438E2;

    const P5ASIN: f64 = 4.253_011_369_004_428_248_960E-3;
    const P4ASIN: f64 = -6.019_598_008_014_123_785_661E-1;
    const P3ASIN: f64 = 5.444_622_390_564_711_410_273E0;
    const P2ASIN: f64 = -1.626_247_967_210_700_244_449E1;
    const P1ASIN: f64 = 1.956_261_983_317_594_739_197E1;
    const P0ASIN: f64 = -8.198_089_802_484_824_371_615E0;

    const Q4ASIN: f64 = -1.474_091_372_988_853_791_896E1;
    const Q3ASIN: f64 = 7.049_610_280_856_842_141_659E1;
    const Q2ASIN: f64 = -1.471_791_292_232_726_029_859E2;
    const Q1ASIN: f64 = 1.395_105_614_657_485_689_735E2;
    const Q0ASIN: f64 = -4.918_853_881_490_881_290_097E1;

    /// asin x for x in [-1, 1] (NaN outside): two rational approximations joined at
    /// |x| = 0.625, both evaluated and one selected (no branch).
    #[inline(always)]
    pub fn asin<L: KernelOps>(x: L) -> L {
        let xa = x.abs();
        let big = xa.cmp_ge(L::splat(0.625));
        let x1 = L::select(big, L::splat(1.0) - xa, xa * xa);
        let x2 = x1 * x1;
        let x3 = x2 * x1;
        let x4 = x2 * x2;
        let x5 = x4 * x1;

        let rx = (x3 * R3ASIN + x2 * R2ASIN) + (x4 * R4ASIN + (x1 * R1ASIN + R0ASIN));
        let sx = (x3 * S3ASIN + x4) + (x2 * S2ASIN + (x1 * S1ASIN + S0ASIN));
        let px =
            ((x3 * P3ASIN + P0ASIN) + (x4 * P4ASIN + x1 * P1ASIN)) + (x5 * P5ASIN + x2 * P2ASIN);
        let qx = ((x4 * Q4ASIN + x5) + (x3 * Q3ASIN + x1 * Q1ASIN)) + (x2 * Q2ASIN + Q0ASIN);
        let vx = L::select(big, rx, px);
        let wx = L::select(big, sx, qx);
        let y1 = vx / wx * x1;

        let xb = (x1 + x1).sqrt();
        let z1 = xb * y1 + xb;
        let z2 = xa * y1 + xa;
        let a = L::select(big, L::splat(std::f64::consts::FRAC_PI_2) - z1, z2);
        a.xor_bits(x.and_bits(L::splat(SIGN)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ulps(a: f64, b: f64) -> f64 {
        (a - b).abs() / (b.abs().max(f64::MIN_POSITIVE) * f64::EPSILON)
    }

    #[test]
    fn sin_cos_kernel_matches_libm() {
        let mut worst: f64 = 0.0;
        let mut x = -50.0;
        while x < 50.0 {
            let (s, c) = kernels::sin_cos(x);
            // absolute error in units of eps: near zeros of sin/cos, relative error is moot
            worst = worst.max((s - x.sin()).abs().max((c - x.cos()).abs()) / f64::EPSILON);
            x += 0.000_731;
        }
        assert!(worst <= 1.0, "worst |error| = {worst} eps");
        for &x in &[0.0, 1e-300, 0.3, 0.5, -1.2, 3.0, 1.0e6, -1.0e8] {
            let (s, c) = kernels::sin_cos(x);
            assert!(
                ulps(s, x.sin()) <= 2.0 || (s - x.sin()).abs() < 1e-16,
                "sin {x}: {s}"
            );
            assert!(
                ulps(c, x.cos()) <= 2.0 || (c - x.cos()).abs() < 1e-16,
                "cos {x}: {c}"
            );
        }
        assert_eq!(kernels::sin_cos(-0.0).0.to_bits(), (-0.0f64).to_bits());
        for x in [f64::NAN, f64::INFINITY, -f64::INFINITY, 2.0e9] {
            let (s, c) = kernels::sin_cos(x);
            assert!(s.is_nan() && c.is_nan(), "{x}");
        }
    }

    #[test]
    fn asin_kernel_matches_libm() {
        let mut x = -1.0;
        while x <= 1.0 {
            let a = kernels::asin(x);
            assert!(ulps(a, x.asin()) <= 2.0, "asin {x}: {a} vs {}", x.asin());
            x += 0.000_37;
        }
        for x in [-1.0, 1.0, 0.625, -0.625, 0.0, 1e-200] {
            assert!(ulps(kernels::asin(x), x.asin()) <= 2.0, "asin {x}");
        }
        assert!(kernels::asin(1.5).is_nan() && kernels::asin(f64::NAN).is_nan());
    }

    /// Every lane of a pack computes exactly what the scalar path computes.
    fn pack_agrees_bitwise<L: KernelOps>() {
        let xs = [-1.2, -0.5, 0.37, 2.5, 1e10, f64::NAN, -0.0, 7.0];
        for chunk in xs.chunks(4) {
            let v = L::from_fn(|i| chunk[i]);
            let (s, c) = v.sin_cos();
            let a = (v * 0.3).asin();
            let m = v.max(L::splat(0.1)).min(L::splat(2.0));
            for (i, &x) in chunk.iter().enumerate() {
                let (ss, cc) = Lane::sin_cos(x);
                assert_eq!(s.lane(i).to_bits(), ss.to_bits(), "sin {x}");
                assert_eq!(c.lane(i).to_bits(), cc.to_bits(), "cos {x}");
                assert_eq!(
                    a.lane(i).to_bits(),
                    Lane::asin(x * 0.3).to_bits(),
                    "asin {x}"
                );
                assert_eq!(
                    m.lane(i).to_bits(),
                    Lane::min(Lane::max(x, 0.1), 2.0).to_bits()
                );
            }
        }
    }

    #[test]
    fn packs_agree_bitwise_with_scalars() {
        pack_agrees_bitwise::<F64x4>();
        pack_agrees_bitwise::<portable::F64x4>();
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: AVX2 is available (checked above).
            #[target_feature(enable = "avx2")]
            unsafe fn avx() {
                pack_agrees_bitwise::<F64x4Avx>();
            }
            unsafe { avx() };
        }
    }

    #[test]
    fn le_mask_treats_nan_as_out_of_bounds() {
        let v = F64x4::from_fn(|i| [0.5, f64::NAN, 2.0, -3.0][i]);
        assert_eq!(v.abs().le_mask(F64x4::splat(1.0)), 0b0001);
        assert_eq!(f64::NAN.le_mask(1.0), 0);
        assert_eq!(<F64x4 as Lane>::ALL, 0b1111);
        assert_eq!(<f64 as Lane>::ALL, 1);
    }
}
