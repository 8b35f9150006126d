//! Dual numbers: forward-mode automatic differentiation through the same generic model code
//! the flight loop runs (`crate::stability` linearises with them).

use super::{Lane, Masks};
use std::ops::{Add, AddAssign, Div, Mul, Neg, Sub};

/// A number with a derivative along one direction (forward-mode automatic differentiation).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Dual {
    pub v: f64,
    pub d: f64,
}

impl Dual {
    pub fn constant(v: f64) -> Self {
        Self { v, d: 0.0 }
    }
}

impl Add for Dual {
    type Output = Self;
    fn add(self, o: Self) -> Self {
        Self {
            v: self.v + o.v,
            d: self.d + o.d,
        }
    }
}

impl Sub for Dual {
    type Output = Self;
    fn sub(self, o: Self) -> Self {
        Self {
            v: self.v - o.v,
            d: self.d - o.d,
        }
    }
}

impl Mul for Dual {
    type Output = Self;
    fn mul(self, o: Self) -> Self {
        Self {
            v: self.v * o.v,
            d: self.d * o.v + self.v * o.d,
        }
    }
}

impl Div for Dual {
    type Output = Self;
    fn div(self, o: Self) -> Self {
        Self {
            v: self.v / o.v,
            d: (self.d * o.v - self.v * o.d) / (o.v * o.v),
        }
    }
}

impl Neg for Dual {
    type Output = Self;
    fn neg(self) -> Self {
        Self {
            v: -self.v,
            d: -self.d,
        }
    }
}

impl AddAssign for Dual {
    fn add_assign(&mut self, o: Self) {
        *self = *self + o;
    }
}

impl Add<f64> for Dual {
    type Output = Self;
    fn add(self, o: f64) -> Self {
        Self {
            v: self.v + o,
            d: self.d,
        }
    }
}

impl Sub<f64> for Dual {
    type Output = Self;
    fn sub(self, o: f64) -> Self {
        Self {
            v: self.v - o,
            d: self.d,
        }
    }
}

impl Mul<f64> for Dual {
    type Output = Self;
    fn mul(self, o: f64) -> Self {
        Self {
            v: self.v * o,
            d: self.d * o,
        }
    }
}

impl Lane for Dual {
    const LANES: usize = 1;
    fn splat(x: f64) -> Self {
        Self::constant(x)
    }
    fn lane(self, _i: usize) -> f64 {
        self.v
    }
    fn set_lane(&mut self, _i: usize, x: f64) {
        *self = Self::constant(x);
    }
    fn sin_cos(self) -> (Self, Self) {
        let (s, c) = self.v.sin_cos();
        (
            Self {
                v: s,
                d: c * self.d,
            },
            Self {
                v: c,
                d: -s * self.d,
            },
        )
    }
    fn atan2(self, x: Self) -> Self {
        Self {
            v: Lane::atan2(self.v, x.v),
            d: (x.v * self.d - self.v * x.d) / (x.v * x.v + self.v * self.v),
        }
    }
    fn asin(self) -> Self {
        Self {
            v: self.v.asin(),
            d: self.d / (1.0 - self.v * self.v).sqrt(),
        }
    }
    /// The slope at 0 is taken as 0; the model only uses |x| multiplied by x (drag) or inside
    /// s / (|s| + gamma), where that choice drops out at x = 0.
    fn abs(self) -> Self {
        if self.v < 0.0 {
            -self
        } else if self.v > 0.0 {
            self
        } else {
            Self::constant(0.0)
        }
    }
    /// At 0 with a zero slope (the minimum of a sum of squares, e.g. a norm at the origin:
    /// sqrt(x^2) = |x|) the slope is taken as 0, as for `abs`, not 0 / 0.
    fn sqrt(self) -> Self {
        let r = self.v.sqrt();
        Self {
            v: r,
            d: if self.v == 0.0 && self.d == 0.0 {
                0.0
            } else {
                self.d / (2.0 * r)
            },
        }
    }
    fn max(self, other: Self) -> Self {
        if other.v > self.v {
            other
        } else {
            self
        }
    }
    fn min(self, other: Self) -> Self {
        if other.v < self.v {
            other
        } else {
            self
        }
    }
    fn if_negative(self, a: Self, b: Self) -> Self {
        if self.v < 0.0 {
            a
        } else {
            b
        }
    }
}

/// A mask is a constant whose value has every bit set (true) or none; `select` picks by the
/// value's mask and carries the chosen operand's derivative, as a branch would.
impl Masks for Dual {
    fn cmp_le(self, other: Self) -> Self {
        Self::constant(Masks::cmp_le(self.v, other.v))
    }
    fn cmp_ge(self, other: Self) -> Self {
        Self::constant(Masks::cmp_ge(self.v, other.v))
    }
    fn cmp_ne(self, other: Self) -> Self {
        Self::constant(Masks::cmp_ne(self.v, other.v))
    }
    fn select(mask: Self, a: Self, b: Self) -> Self {
        if mask.v.to_bits() == u64::MAX {
            a
        } else {
            b
        }
    }
}
