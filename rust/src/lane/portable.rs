//! Four lanes as a plain array, operation by operation (LLVM vectorises what it can): the lane
//! type off x86-64. Also compiled, and tested, on x86-64 test builds.

use super::{KernelOps, Lane, Masks, Param};
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

/// Methods of trait `$Trait` that are `f64`'s own, lane by lane (`o`: a second operand).
macro_rules! lanewise {
    ($Trait:ident: $($name:ident($($o:ident)?);)+) => {$(
        #[inline(always)]
        fn $name(self $(, $o: Self)?) -> Self {
            each!(|x $(, $o)?| <f64 as $Trait>::$name(x $(, $o)?), self $(, $o)?)
        }
    )+};
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
    kernel_trig!();
    lanewise!(Lane: abs(); sqrt(); max(o); min(o););
    #[inline(always)]
    fn le_mask(self, bound: Self) -> u32 {
        let (a, b) = (self.0, bound.0);
        (a[0] <= b[0]) as u32
            | ((a[1] <= b[1]) as u32) << 1
            | ((a[2] <= b[2]) as u32) << 2
            | ((a[3] <= b[3]) as u32) << 3
    }
}

impl Masks for F64x4 {
    lanewise!(Masks: cmp_le(o); cmp_ge(o); cmp_ne(o););
    #[inline(always)]
    fn select(m: Self, a: Self, b: Self) -> Self {
        let (m, a, b) = (m.0, a.0, b.0);
        let f = <f64 as Masks>::select;
        Self([
            f(m[0], a[0], b[0]),
            f(m[1], a[1], b[1]),
            f(m[2], a[2], b[2]),
            f(m[3], a[3], b[3]),
        ])
    }
}

impl KernelOps for F64x4 {
    lanewise!(KernelOps: and_bits(o); xor_bits(o); add_bits(o); shl62_bits(); shl52_bits(); shr52_bits(););
}
