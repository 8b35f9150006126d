use super::design::*;
use super::kernels::*;
use super::*;
use crate::lane::KernelOps;
use nalgebra::DMatrix;
use rand_chacha::ChaCha8Rng;

pub(in crate::gust) const KS: [f64; 4] = [0.01, 0.5, 2.0, 10.0];
pub(in crate::gust) const MODELS: [GustModel; 2] = [GustModel::Dryden, GustModel::VonKarman];

/// A filter with V dt / L = k (L = 2 m, V = 10 m/s).
pub(in crate::gust) fn filt(model: GustModel, c: GustComponent, sigma: f64, k: f64) -> GustFilter {
    let (l, v) = (2.0, 10.0);
    built(model, c, [sigma, l, v, k * l / v]).unwrap()
}

/// `GustFilter::new` of these numbers: sigma, length_scale, airspeed, dt.
fn built(
    model: GustModel,
    component: GustComponent,
    [sigma, length_scale, airspeed, dt]: [f64; 4],
) -> Result<GustFilter, String> {
    GustFilter::new(GustSpec {
        model,
        component,
        sigma,
        length_scale,
        airspeed,
        dt,
    })
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
fn each_filters_order_is_its_denominators_degree() {
    use GustComponent::{Lateral, Longitudinal, Vertical};
    for (model, orders) in [
        (GustModel::Dryden, [1, 2, 2]),
        (GustModel::VonKarman, [2, 3, 3]),
    ] {
        for (c, order) in [Longitudinal, Lateral, Vertical].into_iter().zip(orders) {
            let r = rational(model, c);
            let gain2 = if c == Longitudinal { 2.0 } else { 1.0 };
            assert_eq!((r.order, r.gain2), (order, gain2), "{model:?} {c:?}");
            assert_eq!(filt(model, c, 1.0, 0.5).order(), order);
        }
    }
}

#[test]
fn bad_input_is_rejected_with_the_parameter_named() {
    let d = GustModel::Dryden;
    let v = GustComponent::Vertical;
    let e = built(d, v, [1.0, 2.0, 0.0, 0.01]).unwrap_err();
    assert_eq!(
        e,
        "airspeed must be > 0 (the Dryden filters are singular at zero airspeed), got 0.0"
    );
    let e = built(d, v, [-1.0, 2.0, 10.0, 0.01]).unwrap_err();
    assert_eq!(e, "sigma must be >= 0, got -1.0");
    let e = built(d, v, [1.0, 0.0, 10.0, 0.01]).unwrap_err();
    assert_eq!(e, "length_scale must be > 0, got 0.0");
    let e = built(d, v, [1.0, 2.0, 10.0, -0.01]).unwrap_err();
    assert_eq!(e, "dt must be > 0, got -0.01");
    let e = built(d, v, [f64::NAN, 2.0, 10.0, 0.01]).unwrap_err();
    assert_eq!(e, "sigma must be finite, got NaN");
    let e = built(d, v, [1.0, 2.0, f64::INFINITY, 0.01]).unwrap_err();
    assert_eq!(e, "airspeed must be finite, got inf");
    let e = built(d, v, [1.0, 1e300, 1e-300, 1e-300]).unwrap_err();
    assert!(e.starts_with("airspeed * dt / length_scale"), "{e}");
    assert!(built(d, v, [0.0, 2.0, 10.0, 0.01]).is_ok());
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
                .map(|s| built(GustModel::Dryden, c, [1.0, 2.0, 10.0, s.3]).unwrap())
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
                            assert_eq!(bits(d.phi[i][j].lane(l)), bits(want.phi[i][j]), "phi {at}");
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
