//! Branch-free sin/cos and asin over any `Lane`. The algorithms and constants are those of
//! `wide` 1.7 (after Agner Fog's vector class library, from Cephes), evaluated in the same
//! order without FMA, so batches give exactly what they gave with `wide::f64x4` before. Their
//! products-plus-sums are `Lane::mul_add`: fused in the fused mode only.
#![allow(clippy::excessive_precision)] // the published Cephes digits, kept as published

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
/// Below pi/4 (by a margin far beyond rounding): |x| * 2/pi + ROUND then rounds to quadrant 0.
const QUARTER_PI_BELOW: f64 = 0.785;

/// `a * b + c` as `Lane::mul_add` (fused only in the fused mode).
#[inline(always)]
fn madd<L: KernelOps>(a: L, b: f64, c: f64) -> L {
    a.mul_add(L::splat(b), L::splat(c))
}

/// `c0 + c1 x + ... + c5 x^5`, in wide's `polynomial_5!` order.
#[inline(always)]
fn poly5<L: KernelOps>(x: L, c: [f64; 6]) -> L {
    let x2 = x * x;
    let x4 = x2 * x2;
    madd(x, c[3], c[2]).mul_add(x2, madd(x, c[5], c[4]).mul_add(x4, madd(x, c[1], c[0])))
}

/// (sin x, cos x), within about 1 ulp for |x| <= SIN_COS_LIMIT; NaN beyond, and for
/// non-finite x.
#[inline(always)]
pub fn sin_cos<L: KernelOps>(x: L) -> (L, L) {
    let xa = x.abs();
    // The fused mode's shortcut: where every lane has |x| < pi/4 (the quadrant is 0), the
    // reduction, quadrant swap and cosine sign below do nothing; skip them. The numbers are
    // those of the full kernel (in the same mode), only cheaper.
    if L::FUSED && xa.le_mask(L::splat(QUARTER_PI_BELOW)) == L::ALL {
        let r2 = xa * xa;
        let s = poly5(r2, [P0SIN, P1SIN, P2SIN, P3SIN, P4SIN, P5SIN]);
        let c = poly5(r2, [P0COS, P1COS, P2COS, P3COS, P4COS, P5COS]);
        let s = (xa * r2).mul_add(s, xa);
        let c = (r2 * r2).mul_add(c, L::splat(1.0) - r2 * 0.5);
        return (s.xor_bits(x.and_bits(L::splat(SIGN))), c);
    }
    let t = madd(xa, 2.0 / std::f64::consts::PI, ROUND);
    let y = t - ROUND;
    // xa - y DP1 - y DP2 - y DP3 (negation is exact: a - b y is b (-y) + a)
    let ny = -y;
    let r = ny.mul_add(
        L::splat(DP3),
        ny.mul_add(L::splat(DP2), ny.mul_add(L::splat(DP1), xa)),
    );

    let r2 = r * r;
    let s = poly5(r2, [P0SIN, P1SIN, P2SIN, P3SIN, P4SIN, P5SIN]);
    let c = poly5(r2, [P0COS, P1COS, P2COS, P3COS, P4COS, P5COS]);
    let s = (r * r2).mul_add(s, r);
    let c = (r2 * r2).mul_add(c, L::splat(1.0) - r2 * 0.5);

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

/// Below the 0.625 at which `asin` switches approximations (`le_mask` is `<=`).
const ASIN_SPLIT_BELOW: f64 = f64::from_bits(0.625f64.to_bits() - 1);
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
    // Where every lane has |x| < 0.625 only the second rational approximation is selected
    // below; evaluate just that one: the same operations on the same values, so the same
    // numbers in every mode, without the first approximation and its square root (a
    // controller's attitude commands and a swing angle stay below 0.625 in steady flight).
    if xa.le_mask(L::splat(ASIN_SPLIT_BELOW)) == L::ALL {
        let c = L::splat;
        let x1 = xa * xa;
        let x2 = x1 * x1;
        let x3 = x2 * x1;
        let x4 = x2 * x2;
        let x5 = x4 * x1;
        let px = (madd(x3, P3ASIN, P0ASIN) + x4.mul_add(c(P4ASIN), x1 * P1ASIN))
            + x5.mul_add(c(P5ASIN), x2 * P2ASIN);
        let qx = (x4.mul_add(c(Q4ASIN), x5) + x3.mul_add(c(Q3ASIN), x1 * Q1ASIN))
            + madd(x2, Q2ASIN, Q0ASIN);
        let y1 = px / qx * x1;
        return xa.mul_add(y1, xa).xor_bits(x.and_bits(L::splat(SIGN)));
    }
    let big = xa.cmp_ge(L::splat(0.625));
    let x1 = L::select(big, L::splat(1.0) - xa, xa * xa);
    let x2 = x1 * x1;
    let x3 = x2 * x1;
    let x4 = x2 * x2;
    let x5 = x4 * x1;

    let rx = (x3 * R3ASIN + x2 * R2ASIN) + (x4 * R4ASIN + (x1 * R1ASIN + R0ASIN));
    let sx = (x3 * S3ASIN + x4) + (x2 * S2ASIN + (x1 * S1ASIN + S0ASIN));
    let px = ((x3 * P3ASIN + P0ASIN) + (x4 * P4ASIN + x1 * P1ASIN)) + (x5 * P5ASIN + x2 * P2ASIN);
    let qx = ((x4 * Q4ASIN + x5) + (x3 * Q3ASIN + x1 * Q1ASIN)) + (x2 * Q2ASIN + Q0ASIN);
    let vx = L::select(big, rx, px);
    let wx = L::select(big, sx, qx);
    let y1 = vx / wx * x1;

    let xb = (x1 + x1).sqrt();
    let z1 = xb.mul_add(y1, xb);
    let z2 = xa.mul_add(y1, xa);
    let a = L::select(big, L::splat(std::f64::consts::FRAC_PI_2) - z1, z2);
    a.xor_bits(x.and_bits(L::splat(SIGN)))
}

/// Cephes' atan rational approximation (`atan.c`), valid for |z| <= 0.66: P from the highest
/// power down, Q monic.
const P4ATAN: f64 = -8.750_608_600_031_904_122_785E-1;
const P3ATAN: f64 = -1.615_753_718_733_365_076_637E1;
const P2ATAN: f64 = -7.500_855_792_314_704_667_340E1;
const P1ATAN: f64 = -1.228_866_684_490_136_173_410E2;
const P0ATAN: f64 = -6.485_021_904_942_025_371_773E1;
const Q4ATAN: f64 = 2.485_846_490_142_306_297_962E1;
const Q3ATAN: f64 = 1.650_270_098_316_988_542_046E2;
const Q2ATAN: f64 = 4.328_810_604_912_902_668_951E2;
const Q1ATAN: f64 = 4.853_903_996_359_136_964_868E2;
const Q0ATAN: f64 = 1.945_506_571_482_613_964_425E2;
/// Cephes' switch to `(t - 1) / (t + 1)` about pi/4.
const ATAN_MEDIUM: f64 = 0.66;
/// k pi/4 for k = 1..4: the nearest double (HI) and the rest (LO, from the exact value), so
/// that the final sum `(r + lo) + hi` rounds once at the scale of the result.
const QUARTER_PI_HI: [f64; 4] = [
    std::f64::consts::FRAC_PI_4,
    std::f64::consts::FRAC_PI_2,
    2.356_194_490_192_345, // 3 pi/4
    std::f64::consts::PI,
];
const QUARTER_PI_LO: [f64; 4] = [
    3.061_616_997_868_383E-17,
    6.123_233_995_736_766E-17,
    9.184_850_993_605_148E-17,
    1.224_646_799_147_353_2E-16,
];

/// The angle of (x, y) in (-pi, pi], as the standard library's `y.atan2(x)` within 1 ulp
/// (`benches/lane_math_error.py` measures it), branch-free and without FMA, so that every lane
/// path gives the same bits. The point is folded into the first octant (t = min/max of |x|,
/// |y|), atan t taken from Cephes' rational approximation (about pi/4 on (t - 1) / (t + 1),
/// formed from |x| and |y| directly, whose difference is exact), and the fold undone in one
/// sum `(+-r + lo) + hi` with k pi/4 in two parts. Signed zeros as the standard library's
/// (atan2(+-0, -0) = +-pi); both infinite: an odd multiple of pi/4; NaN in, NaN out.
#[inline(always)]
pub fn atan2<L: KernelOps>(y: L, x: L) -> L {
    let c = L::splat;
    let (xa, ya) = (x.abs(), y.abs());
    // |y| > |x| (false for NaN and for equal magnitudes, zeros included).
    let swap = ya.cmp_ge(xa).and_bits(ya.cmp_ne(xa));
    let num = L::select(swap, xa, ya);
    let den = L::select(swap, ya, xa);
    let medium = num.cmp_ge(den * ATAN_MEDIUM).and_bits(den.cmp_ne(c(0.0)));
    let z = L::select(medium, num - den, num) / L::select(medium, num + den, den);
    // num = den (zeros, infinities, or on the diagonal): atan 0 about the base.
    let z = L::select(num.cmp_ne(den), z, c(0.0));
    let zz = z * z;
    let px = zz.mul_add(c(P4ATAN), c(P3ATAN));
    let px = px.mul_add(zz, c(P2ATAN));
    let px = px.mul_add(zz, c(P1ATAN));
    let px = px.mul_add(zz, c(P0ATAN));
    let qx = zz + c(Q4ATAN);
    let qx = qx.mul_add(zz, c(Q3ATAN));
    let qx = qx.mul_add(zz, c(Q2ATAN));
    let qx = qx.mul_add(zz, c(Q1ATAN));
    let qx = qx.mul_add(zz, c(Q0ATAN));
    let r = (px / qx).mul_add(z * zz, z);
    // Unfold: the angle of (|x|, |y|) is q pi/4 + sigma r, q in 0..=4 and sigma = -1 where
    // the point was swapped or x is negative (not both). x's sign by its bit (-0 counts).
    let sign_x = c(1.0).xor_bits(x.and_bits(c(SIGN)));
    let negative = sign_x.cmp_le(c(0.0));
    let sigma = L::select(swap, -sign_x, sign_x);
    let q = L::select(swap, c(2.0), L::select(negative, c(4.0), c(0.0)))
        + L::select(medium, sigma, c(0.0));
    // Written out, no closure or array `map`: a closure the optimiser leaves out of line is
    // compiled without the lane type's instruction set, every lane operation in it a call.
    let at_least = [
        q.cmp_ge(c(0.5)),
        q.cmp_ge(c(1.5)),
        q.cmp_ge(c(2.5)),
        q.cmp_ge(c(3.5)),
    ];
    let angle = (r * sigma + quarter_pi_multiple(&at_least, QUARTER_PI_LO))
        + quarter_pi_multiple(&at_least, QUARTER_PI_HI);
    angle.xor_bits(y.and_bits(c(SIGN)))
}

/// `t[k]` for the largest `k` with `at_least[k]` (0 where none): `q pi/4`'s part `t` for q in
/// 1..=4, selected in increasing `k`.
#[inline(always)]
#[allow(clippy::needless_range_loop)] // the selects in increasing k, one per index
fn quarter_pi_multiple<L: KernelOps>(at_least: &[L; 4], t: [f64; 4]) -> L {
    let mut v = L::splat(0.0);
    for k in 0..4 {
        v = L::select(at_least[k], L::splat(t[k]), v);
    }
    v
}
