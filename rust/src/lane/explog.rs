//! Branch-free `exp`, `expm1`, `ln` and `pow` over any lane type (`KernelOps`): every lane of
//! every path (`f64`, SSE2, AVX2, AVX-512, the portable array) runs the same IEEE-754
//! operations in the same order, so a lane's result has the same bits whatever the lane type,
//! the instruction set or the machine. Nothing here fuses, not even in the fused mode: the
//! kernels use the lane operators only (never `Lane::mul_add`), and the error-free products
//! inside `ln`/`pow` need their roundings where they are written. So the fused and the default
//! mode give these functions' bits alike too.
//!
//! The algorithms are FreeBSD msun's (fdlibm: `e_exp.c`, `s_expm1.c`, `e_log.c`), with their
//! branches turned into selects; `ln` and `pow` carry the logarithm in two doubles (the
//! quotient `s = f / (2 + f)` and the exponent's `k ln 2` with their rounding errors), so `ln`
//! is rounded once from about 2^-60 and `pow = exp(y ln x)` keeps `y ln x` to about 2^-60
//! relative. Measured errors against a correctly rounded reference (`benches/lane_math_error.py`,
//! docs/performance.md): all four within 1 ulp over the wind's arguments and beyond (`pow`
//! while |y ln x| < 64).
//!
//! Why our own: the crates that vectorise these (sleef-rs needs nightly `core::simd` and picks
//! FMA per target; `wide`'s are neither documented to 1 ulp nor available on our AVX-512 and
//! SSE2-pair types) cannot run through this crate's one lane template, which is what makes
//! every path give the same bits.
#![allow(clippy::excessive_precision)] // fdlibm's published digits, kept as published

use super::KernelOps;

/// 1.5 * 2^52: `x + ROUND - ROUND` rounds x (|x| < 2^51) to the nearest integer, ties to
/// even, and leaves it (two's complement, mod 2^51) in the low mantissa bits of `x + ROUND`.
const ROUND: f64 = 6_755_399_441_055_744.0;
/// 2^52, whose bit pattern plus an integer k < 2^52 is the double 2^52 + k.
const TWO52: f64 = 4_503_599_627_370_496.0;

/// 1 / ln 2 (the bits of fdlibm's `invln2`, 0x3ff71547652b82fe).
const INV_LN2: f64 = std::f64::consts::LOG2_E;
/// ln 2 in two parts; the high part has 32 significant bits, so `k * LN2_HI` is exact for
/// |k| < 2^21.
const LN2_HI: f64 = 6.931_471_803_691_238_164_90e-01;
const LN2_LO: f64 = 1.908_214_929_270_587_700_02e-10;

/// `e_exp.c`'s remez coefficients of `R(r^2) = r (e^r + 1) / (e^r - 1)`, |r| <= ln2 / 2.
const P1: f64 = 1.666_666_666_666_660_190_37e-01;
const P2: f64 = -2.777_777_777_701_559_338_42e-03;
const P3: f64 = 6.613_756_321_437_934_361_17e-05;
const P4: f64 = -1.653_390_220_546_525_153_90e-06;
const P5: f64 = 4.138_136_797_057_238_460_39e-08;

/// `s_expm1.c`'s coefficients (the scaled rational approximation of expm1 on |r| <= ln2/2).
const Q1: f64 = -3.333_333_333_333_313_164_28e-02;
const Q2: f64 = 1.587_301_587_254_814_601_65e-03;
const Q3: f64 = -7.936_507_578_674_879_424_73e-05;
const Q4: f64 = 4.008_217_827_329_362_395_52e-06;
const Q5: f64 = -2.010_992_181_836_243_713_26e-07;

/// `e_log.c`'s coefficients of `R(z)`, `2 atanh(s) = 2 s + s R(s^2)` for |s| <= 0.1716.
const LG1: f64 = 6.666_666_666_666_735_130e-01;
const LG2: f64 = 3.999_999_999_940_941_908e-01;
const LG3: f64 = 2.857_142_874_366_239_149e-01;
const LG4: f64 = 2.222_219_843_214_978_396e-01;
const LG5: f64 = 1.818_357_216_161_805_012e-01;
const LG6: f64 = 1.531_383_769_920_937_332e-01;
const LG7: f64 = 1.479_819_860_511_658_591e-01;

/// Arguments of `exp` beyond which the result is 0 or infinite anyway (clamping keeps the
/// exponent arithmetic in range).
const EXP_LO: f64 = -746.0;
const EXP_HI: f64 = 710.0;
/// Below this `expm1` is -1 to double precision.
const EXPM1_LO: f64 = -40.0;

#[inline(always)]
fn c<L: KernelOps>(x: f64) -> L {
    L::splat(x)
}

/// The integer nearest `x` (ties to even), for |x| < 2^51.
#[inline(always)]
fn round<L: KernelOps>(x: L) -> L {
    (x + ROUND) - ROUND
}

/// 2^n for an integer-valued n in [-1022, 1023].
#[inline(always)]
fn pow2<L: KernelOps>(n: L) -> L {
    ((n + 1023.0) + ROUND).shl52_bits()
}

/// `y * 2^n` for an integer-valued n in [-1100, 1100], rounded once: two exact-range factors
/// (2^n1 2^n2, n1 = round(n/2)), the first product exact for y near 1, the second rounding into
/// the subnormals or overflowing where the result does.
#[inline(always)]
fn scale<L: KernelOps>(y: L, n: L) -> L {
    let n1 = round(n * 0.5);
    let n2 = n - n1;
    y * pow2(n1) * pow2(n2)
}

/// Mask of `a == b` (false for NaN).
#[inline(always)]
fn eq<L: KernelOps>(a: L, b: f64) -> L {
    a.cmp_le(c(b)).and_bits(a.cmp_ge(c(b)))
}

/// Mask of `x` NaN.
#[inline(always)]
fn is_nan<L: KernelOps>(x: L) -> L {
    x.cmp_ne(x)
}

/// `x` where it is NaN, `r` elsewhere.
#[inline(always)]
fn keep_nan<L: KernelOps>(x: L, r: L) -> L {
    L::select(is_nan(x), x, r)
}

/// `e^(xh + xl)` (`xl` a small correction below `xh`'s last bit, 0 for `exp` itself), x
/// already clamped to [EXP_LO, EXP_HI]: `e_exp.c`'s reduction `x = n ln2 + hi - lo` and
/// `e^r = 1 + r + r c / (2 - c)`.
#[inline(always)]
fn exp_parts<L: KernelOps>(xh: L, xl: L) -> L {
    let n = round(xh * INV_LN2);
    let hi = xh - n * LN2_HI;
    let lo = n * LN2_LO - xl;
    let r = hi - lo;
    let t = r * r;
    let p = t * (c::<L>(P1) + t * (c::<L>(P2) + t * (c::<L>(P3) + t * (c::<L>(P4) + t * P5))));
    let cc = r - p;
    let y = c::<L>(1.0) - ((lo - (r * cc) / (c::<L>(2.0) - cc)) - hi);
    scale(y, n)
}

/// e^x: within 1 ulp (fdlibm `e_exp.c`); 0 below -745.2, infinite above 709.8, NaN for NaN.
#[inline(always)]
pub fn exp<L: KernelOps>(x: L) -> L {
    let xc = x.max(c(EXP_LO)).min(c(EXP_HI));
    keep_nan(x, exp_parts(xc, c(0.0)))
}

/// e^x - 1, accurate where it is near 0 (fdlibm `s_expm1.c`, every case evaluated and the
/// lane's selected): within 1 ulp; -1 below -40, infinite above 709.8, NaN for NaN.
#[inline(always)]
pub fn expm1<L: KernelOps>(x: L) -> L {
    let one = c::<L>(1.0);
    let x0 = x.max(c(EXPM1_LO)).min(c(EXP_HI));
    // x0 = k ln2 + hi - lo; r = hi - lo with its rounding error cr.
    let k = round(x0 * INV_LN2);
    let hi = x0 - k * LN2_HI;
    let lo = k * LN2_LO;
    let r = hi - lo;
    let cr = (hi - r) - lo;
    let hfx = r * 0.5;
    let hxs = r * hfx;
    let r1 = one
        + hxs
            * (c::<L>(Q1)
                + hxs * (c::<L>(Q2) + hxs * (c::<L>(Q3) + hxs * (c::<L>(Q4) + hxs * Q5))));
    let t = c::<L>(3.0) - r1 * hfx;
    let e = hxs * ((r1 - t) / (c::<L>(6.0) - r * t));
    // k = 0: no reduction (and cr = 0).
    let at0 = r - (r * e - hxs);
    let e = (r * (e - cr) - cr) - hxs;
    let at_m1 = (r - e) * 0.5 - 0.5;
    let at_1 = L::select(
        r.cmp_le(c(-0.25)).and_bits(r.cmp_ne(c(-0.25))),
        (e - (r + 0.5)) * -2.0,
        one + (r - e) * 2.0,
    );
    let far = scale(one - (e - r), k) - 1.0;
    // 2 <= k < 20 and 20 <= k <= 56 (2^-k is then a normal number).
    let twopk = pow2(k.min(c(1023.0)));
    let twomk = pow2(-(k.max(c(-1022.0)).min(c(1022.0))));
    let mid = ((one - twomk) - (e - r)) * twopk;
    let high = ((r - (e + twomk)) + 1.0) * twopk;
    let ge = |v: f64| k.cmp_ge(c(v));
    let le = |v: f64| k.cmp_le(c(v));
    let mut y = far;
    y = L::select(ge(20.0).and_bits(le(56.0)), high, y);
    y = L::select(ge(2.0).and_bits(le(19.0)), mid, y);
    y = L::select(eq(k, 1.0), at_1, y);
    y = L::select(eq(k, -1.0), at_m1, y);
    y = L::select(eq(k, 0.0), at0, y);
    keep_nan(x, y)
}

/// The largest |x| [`expm1_near0`] and [`tail3_near0`] take: their truncated Taylor series are
/// within 2^-61 (relative) of the functions there.
pub const NEAR0: f64 = 0.03125;

/// 1 / n! for n = 0..=12, rounded.
const INV_FACTORIAL: [f64; 13] = [
    1.0,
    1.0,
    0.5,
    0.16666666666666666,
    0.041666666666666664,
    0.008333333333333333,
    0.001388888888888889,
    0.0001984126984126984,
    2.48015873015873e-05,
    2.7557319223985893e-06,
    2.755731922398589e-07,
    2.505210838544172e-08,
    2.08767569878681e-09,
];

/// `sum_{j=0}^{N} x^j / (j + from)!` by Horner's rule (no division, no branch).
#[inline(always)]
fn taylor<L: KernelOps, const FROM: usize, const N: usize>(x: L) -> L {
    let mut p = c::<L>(INV_FACTORIAL[FROM + N]);
    for j in (0..N).rev() {
        p = p * x + INV_FACTORIAL[FROM + j];
    }
    p
}

/// e^x - 1 for |x| <= [`NEAR0`] (elsewhere: anything; the callers select [`expm1`] there),
/// within 1 ulp: `x + x^2 sum x^j / (j + 2)!` to x^9 (the rest below 2^-61 of the result), no
/// range reduction and no division. For the re-discretised turbulence filters, whose
/// `k = V dt / L` is of order 1e-3 (and which take e^-k as `1 + expm1(-k)`).
#[inline(always)]
pub fn expm1_near0<L: KernelOps>(x: L) -> L {
    x + x * x * taylor::<L, 2, 7>(x)
}

/// `e^x - 1 - x - x^2/2` (the tail of e^x from x^3) for |x| <= [`NEAR0`] (elsewhere:
/// anything): `x^3 sum x^j / (j + 3)!` to x^10 (the rest below 2^-62 of the result), within
/// 3 ulp (the products' roundings; the loop it replaces was no closer).
#[inline(always)]
pub fn tail3_near0<L: KernelOps>(x: L) -> L {
    x * x * x * taylor::<L, 3, 7>(x)
}

/// `a * b` exactly as `(p, e)`, `p = a * b` rounded (Dekker's product on Veltkamp's split: no
/// fused multiply-add needed, so the same bits on every path). For |a|, |b| < 2^995.
#[inline(always)]
fn two_prod<L: KernelOps>(a: L, b: L) -> (L, L) {
    let split = |v: L| {
        let t = v * 134_217_729.0; // 2^27 + 1
        let h = t - (t - v);
        (h, v - h)
    };
    let p = a * b;
    let (ah, al) = split(a);
    let (bh, bl) = split(b);
    let e = ((ah * bh - p) + ah * bl + al * bh) + al * bl;
    (p, e)
}

/// `a + b` exactly as `(s, e)`, `s = a + b` rounded (Knuth's two-sum).
#[inline(always)]
fn two_sum<L: KernelOps>(a: L, b: L) -> (L, L) {
    let s = a + b;
    let bb = s - a;
    let e = (a - (s - bb)) + (b - bb);
    (s, e)
}

/// ln x as `hi + lo` to about 2^-60 relative, for finite x > 0 (other x: anything; the callers
/// select). `e_log.c`'s reduction `x = 2^k (1 + f)`, sqrt(1/2) <= 1 + f < sqrt 2, and
/// `ln(1 + f) = 2 atanh(s) = 2 s + s R(s^2)`, `s = f / (2 + f)`, with `2 + f`, `s` and
/// `k ln 2` carried in two doubles each.
#[inline(always)]
fn ln_parts<L: KernelOps>(x: L) -> (L, L) {
    // Subnormals scaled into the normals first.
    let sub = x
        .cmp_le(c(f64::MIN_POSITIVE))
        .and_bits(x.cmp_ne(c(f64::MIN_POSITIVE)));
    let xs = L::select(sub, x * 18_014_398_509_481_984.0, x); // 2^54
    let k =
        (xs.shr52_bits().add_bits(c(TWO52)) - (TWO52 + 1023.0)) - L::select(sub, c(54.0), c(0.0));
    let m = xs
        .and_bits(c(f64::from_bits((1u64 << 52) - 1)))
        .add_bits(c(1.0));
    let big = m.cmp_ge(c(std::f64::consts::SQRT_2));
    let m = L::select(big, m * 0.5, m);
    let k = L::select(big, k + 1.0, k);
    let f = m - 1.0; // exact (Sterbenz)
    let (d, dl) = {
        let d = f + 2.0;
        (d, f - (d - 2.0)) // exact: |f| < 2
    };
    let s = f / d;
    // s's remainder: f - s (d + dl), exactly up to the last product's rounding.
    let (p, pe) = two_prod(s, d);
    let sl = (((f - p) - pe) - s * dl) / d;
    let z = s * s;
    let w = z * z;
    let t1 = w * (c::<L>(LG2) + w * (c::<L>(LG4) + w * LG6));
    let t2 = z * (c::<L>(LG1) + w * (c::<L>(LG3) + w * (c::<L>(LG5) + w * LG7)));
    let tail = s * (t2 + t1) + sl * 2.0;
    // k ln2_hi (exact) + 2 s (exact), then the small terms.
    let (h, hl) = two_sum(k * LN2_HI, s * 2.0);
    let lo = hl + (tail + k * LN2_LO);
    let hi = h + lo;
    (hi, lo - (hi - h))
}

/// ln x: within 1 ulp (rounded once from the two-double logarithm); -inf at 0, NaN below 0
/// and for NaN, inf at inf.
#[inline(always)]
pub fn ln<L: KernelOps>(x: L) -> L {
    let (hi, _) = ln_parts(x);
    special_ln(x, hi)
}

/// `ln`'s values at 0, below 0, at inf and NaN over `r`.
#[inline(always)]
fn special_ln<L: KernelOps>(x: L, r: L) -> L {
    let zero = eq(x, 0.0);
    let negative = x.cmp_le(c(0.0)).xor_bits(zero);
    let r = L::select(x.cmp_ge(c(f64::INFINITY)), x, r);
    let r = L::select(zero, c(f64::NEG_INFINITY), r);
    let r = L::select(negative, c(f64::NAN), r);
    keep_nan(x, r)
}

/// x^y = e^(y ln x) for x > 0 (`y ln x` carried in two doubles: within 1 ulp while |y ln x|
/// stays below about 64, as for the wind's scales, where |y ln x| < 2.1; the logarithm's
/// 2^-60 then grows to a few ulp of the result near the overflow threshold, |y ln x| ~ 700);
/// 0 and inf at x = 0 and inf as the limit of that formula says (x = 0, y > 0: 0; y < 0: inf),
/// NaN for x < 0 and wherever it is 0 * inf (y = 0 at x = 0 or inf); for |y| < 2^995.
#[inline(always)]
pub fn pow<L: KernelOps>(x: L, y: L) -> L {
    let (lh, ll) = ln_parts(x);
    let finite = x.cmp_le(c(f64::MAX)).and_bits(x.cmp_ge(c(0.0)));
    let lh = L::select(finite, lh, c(0.0));
    let ll = L::select(finite, ll, c(0.0));
    let (ph, pl) = two_prod(y, lh);
    let pl = pl + y * ll;
    let pc = ph.max(c(EXP_LO)).min(c(EXP_HI));
    let r = exp_parts(pc, pl);
    // Beyond x's finite positive range: e^(y * ln x) with ln x = -inf, inf or NaN, evaluated
    // only when a lane is there (each lane's value is the same either way).
    let inside = finite.and_bits(x.cmp_ne(c(0.0)));
    let r = if inside.le_mask(c(0.0)) == 0 {
        r
    } else {
        L::select(inside, r, exp(y * special_ln(x, c(0.0))))
    };
    L::select(is_nan(y), y, r)
}

/// The functions [`evaluate`] knows, by name.
pub const FUNCTIONS: [&str; 7] = [
    "exp",
    "expm1",
    "ln",
    "pow",
    "atan2",
    "expm1_near0",
    "tail3_near0",
];

/// `function` (one of [`FUNCTIONS`]; `pow` takes `y` as its exponent, `atan2` as its second
/// argument: atan2(x, y) is the angle of the point (y, x)) of every `x`, on the
/// lane path `path`: "scalar" (`f64`), "sse2" (`F64x4`), "avx2" (`F64x4Avx`), "avx512"
/// (`F64x8Avx512`): the measurement and cross-path check behind `benches/lane_math_error.py`.
/// An error names a function or path that does not exist or a path this CPU cannot run.
pub fn evaluate(function: &str, path: &str, x: &[f64], y: f64) -> Result<Vec<f64>, String> {
    let f = FUNCTIONS
        .iter()
        .position(|&f| f == function)
        .ok_or_else(|| format!("function must be one of {FUNCTIONS:?}, got {function:?}"))?;
    #[inline(always)]
    fn run<L: KernelOps>(f: usize, x: &[f64], y: f64) -> Vec<f64> {
        let mut out = Vec::with_capacity(x.len());
        for chunk in x.chunks(L::LANES) {
            let v = L::from_fn(|l| chunk.get(l).copied().unwrap_or(1.0));
            let r = match f {
                0 => exp(v),
                1 => expm1(v),
                2 => ln(v),
                3 => pow(v, L::splat(y)),
                4 => super::kernels::atan2(v, L::splat(y)),
                5 => expm1_near0(v),
                _ => tail3_near0(v),
            };
            out.extend((0..chunk.len()).map(|l| r.lane(l)));
        }
        out
    }
    /// `run::<L>` compiled for `L`'s instruction set (`Lane::within`), where this CPU has it
    /// (`isa`): a value of `L`, the proof `within` asks for, is made only then.
    #[cfg(target_arch = "x86_64")]
    fn on<L: KernelOps>(isa: Isa, f: usize, x: &[f64], y: f64) -> Option<Vec<f64>> {
        isa.supported().then(|| {
            L::splat(0.0).within(
                #[inline(always)]
                |_| run::<L>(f, x, y),
            )
        })
    }
    use super::isa::Isa;
    let unsupported =
        |isa: Isa| format!("path {path:?} needs {}, which this CPU lacks", isa.name());
    match path {
        "scalar" => Ok(run::<f64>(f, x, y)),
        "sse2" => Ok(run::<super::F64x4>(f, x, y)),
        #[cfg(target_arch = "x86_64")]
        "avx2" => on::<super::F64x4Avx>(Isa::Avx2, f, x, y).ok_or_else(|| unsupported(Isa::Avx2)),
        #[cfg(target_arch = "x86_64")]
        "avx512" => {
            on::<super::F64x8Avx512>(Isa::Avx512, f, x, y).ok_or_else(|| unsupported(Isa::Avx512))
        }
        _ => Err(format!(
            "path must be one of [\"scalar\", \"sse2\", \"avx2\", \"avx512\"], got {path:?}"
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// |a - b| in units of the spacing of doubles at b (b finite, nonzero).
    fn ulps(a: f64, b: f64) -> f64 {
        let spacing = f64::from_bits(b.abs().to_bits() + 1) - b.abs();
        (a - b).abs() / spacing
    }

    /// Uniform points of [lo, hi] from a fixed sequence (a Weyl sequence: no seed to manage).
    fn points(lo: f64, hi: f64, n: usize) -> impl Iterator<Item = f64> {
        let g = 0.618_033_988_749_894_9;
        (0..n).map(move |i| lo + (hi - lo) * ((i as f64 * g) % 1.0))
    }

    /// Worst distance from glibc's (itself within about 0.5 ulp of the truth) over `xs`.
    fn worst(
        xs: impl Iterator<Item = f64>,
        ours: impl Fn(f64) -> f64,
        libm: impl Fn(f64) -> f64,
    ) -> f64 {
        xs.map(|x| {
            let (a, b) = (ours(x), libm(x));
            assert!(a.is_finite() == b.is_finite(), "{x}: {a} vs {b}");
            if b == 0.0 || !b.is_finite() {
                assert_eq!(a, b, "{x}");
                0.0
            } else {
                ulps(a, b)
            }
        })
        .fold(0.0, f64::max)
    }

    #[test]
    fn exp_is_within_an_ulp_of_libm() {
        for (lo, hi) in [
            (-745.0, 709.7),
            (-1.0, 1.0),
            (-1e-6, 1e-6),
            (-0.05, 0.0),
            (-745.2, -700.0),
        ] {
            let w = worst(points(lo, hi, 200_000), exp::<f64>, f64::exp);
            assert!(w <= 1.0, "exp on [{lo}, {hi}]: {w} ulp");
        }
        assert_eq!(exp(0.0), 1.0);
        assert_eq!(exp(-800.0), 0.0);
        assert_eq!(exp(f64::NEG_INFINITY), 0.0);
        assert_eq!(exp(709.8), f64::INFINITY);
        assert_eq!(exp(f64::INFINITY), f64::INFINITY);
        assert!(exp(f64::NAN).is_nan());
        assert_eq!(exp(1e-300), 1.0);
    }

    #[test]
    fn the_near_zero_series_are_within_an_ulp_of_libm() {
        let r = NEAR0;
        for (lo, hi) in [(-r, r), (-1e-3, 1e-3), (-1e-9, 1e-9), (r - 1e-6, r)] {
            let xs = || points(lo, hi, 200_000);
            let w = worst(xs(), expm1_near0::<f64>, f64::exp_m1);
            assert!(w <= 1.0, "expm1_near0 on [{lo}, {hi}]: {w} ulp");
        }
        // The tail from x^3 against its series summed term by term, smallest first (libm has
        // no such function, and e^x - 1 - x - x^2/2 cancels). That sum is itself within about
        // 1.5 ulp, so this bounds the error loosely; against mpmath the worst is 2.8 ulp
        // (`benches/lane_math_error.py`).
        let reference = |x: f64| {
            let mut terms = vec![x * x * x / 6.0];
            for n in 4..30 {
                terms.push(terms[terms.len() - 1] * x / n as f64);
            }
            terms.iter().rev().sum::<f64>()
        };
        for (lo, hi) in [(1e-6, r), (-r, -1e-6)] {
            let w = worst(points(lo, hi, 200_000), tail3_near0::<f64>, reference);
            assert!(w <= 4.0, "tail3_near0 on [{lo}, {hi}]: {w} ulp");
        }
        assert_eq!(expm1_near0(0.0), 0.0);
        assert_eq!(tail3_near0(0.0), 0.0);
        assert!(expm1_near0(f64::NAN).is_nan() && tail3_near0(f64::NAN).is_nan());
    }

    #[test]
    fn expm1_is_within_an_ulp_of_libm() {
        for (lo, hi) in [
            (-40.0, 709.7),
            (-2.0, 2.0),
            (-0.35, 0.35),
            (-1e-9, 1e-9),
            (-0.1, 0.0),
            (-60.0, 60.0),
        ] {
            let w = worst(points(lo, hi, 200_000), expm1::<f64>, f64::exp_m1);
            assert!(w <= 1.0, "expm1 on [{lo}, {hi}]: {w} ulp");
        }
        for x in [
            0.0,
            -0.0,
            1e-300,
            -1e-310,
            0.5 * std::f64::consts::LN_2,
            -0.25,
        ] {
            assert!(
                ulps(expm1(x), x.exp_m1()) <= 1.0 || expm1(x) == x.exp_m1(),
                "{x}"
            );
        }
        assert_eq!(expm1(-50.0), -1.0);
        assert_eq!(expm1(f64::NEG_INFINITY), -1.0);
        assert_eq!(expm1(710.0), f64::INFINITY);
        assert!(expm1(f64::NAN).is_nan());
    }

    #[test]
    fn ln_is_within_an_ulp_of_libm() {
        for (lo, hi) in [
            (1e-300, 1e300),
            (0.5, 2.0),
            (0.99, 1.01),
            (1.0, 1e4),
            (1e-320, 1e-307),
        ] {
            let w = worst(points(lo, hi, 200_000), ln::<f64>, f64::ln);
            assert!(w <= 1.0, "ln on [{lo}, {hi}]: {w} ulp");
        }
        // Across the exponents, log-uniformly.
        let w = worst(
            points(-700.0, 700.0, 200_000).map(f64::exp),
            ln::<f64>,
            f64::ln,
        );
        assert!(w <= 1.0, "ln: {w} ulp");
        assert_eq!(ln(1.0).to_bits(), 0.0f64.to_bits());
        assert_eq!(ln(0.0), f64::NEG_INFINITY);
        assert!(ln(-1.0).is_nan() && ln(f64::NAN).is_nan() && ln(f64::NEG_INFINITY).is_nan());
        assert_eq!(ln(f64::INFINITY), f64::INFINITY);
        assert_eq!(ln(f64::MIN_POSITIVE / 4.0), (f64::MIN_POSITIVE / 4.0).ln());
    }

    #[test]
    fn pow_is_within_an_ulp_of_libm() {
        for y in [0.4, 1.2, -2.5, 3.7, 0.5, 2.0, -0.4, 11.3] {
            let w = worst(points(1e-3, 1e3, 100_000), |x| pow(x, y), |x| x.powf(y));
            assert!(w <= 1.0, "pow(x, {y}): {w} ulp");
        }
        // ln x is carried to about 2^-60 relative, so the error grows with |y ln x|: within
        // 1 ulp up to |y ln x| = 64 or so, a few ulp near the overflow threshold.
        let w = worst(
            points(-50.0, 50.0, 100_000),
            |y| pow(3.1, y),
            |y| 3.1f64.powf(y),
        );
        assert!(w <= 1.0, "pow(3.1, y): {w} ulp");
        let w = worst(
            points(-600.0, 600.0, 100_000),
            |y| pow(3.1, y),
            |y| 3.1f64.powf(y),
        );
        assert!(w <= 4.0, "pow(3.1, y): {w} ulp");
        assert_eq!(pow(1.0, 0.4), 1.0);
        assert_eq!(pow(4.0, 0.5), 2.0);
        assert_eq!(pow(0.0, 0.4), 0.0);
        assert_eq!(pow(0.0, -0.4), f64::INFINITY);
        assert_eq!(pow(f64::INFINITY, 0.4), f64::INFINITY);
        assert_eq!(pow(f64::INFINITY, -0.4), 0.0);
        assert!(
            pow(-1.0, 0.4).is_nan() && pow(f64::NAN, 0.4).is_nan() && pow(2.0, f64::NAN).is_nan()
        );
        assert_eq!(pow(2.0, 0.0), 1.0);
        assert_eq!(pow(10.0, 400.0), f64::INFINITY);
        assert_eq!(pow(10.0, -400.0), 0.0);
    }
}
