//! MIL-F-8785C low-altitude scales and the spectra the forming filters stand for: the
//! scale formulas, the exact von Karman PSD, and each filter's rational form.

use crate::config::{GustComponent, GustModel};
use crate::lane::{explog, KernelOps};

/// Metres in one foot (the MIL-F-8785C low-altitude formulas take feet).
pub const METRES_PER_FOOT: f64 = 0.3048;

/// Low-altitude MIL-F-8785C turbulence intensities and scale lengths.
///
/// SI in and out: `altitude_m` in metres above ground, `w20` (wind speed at
/// 20 ft) in m/s. Returns `(sigma, L)` for `[longitudinal, lateral, vertical]`,
/// sigma in m/s and L in metres:
///
/// ```text
/// h_ft = altitude_m / 0.3048
/// L_z = h,  sigma_z = 0.1 W20
/// L_x = L_y = h_ft / (0.177 + 0.000823 h_ft)^1.2  [ft]   (returned in metres)
/// sigma_x = sigma_y = sigma_z / (0.177 + 0.000823 h_ft)^0.4
/// ```
///
/// The standard defines this form for 10 ft < h < 1000 ft. It is **not
/// clamped** to that band: below 10 ft the formulas are used as they stand (the
/// paper's preset flies at h = 2 m = 6.56 ft, with `L_z = h = 2 m`), and above
/// 1000 ft there is no blending into the medium/high-altitude model. Callers who
/// want the standard's band can clamp the altitude themselves before calling.
/// The formulas need `altitude_m > 0` and `w20 >= 0`; they are not checked here
/// (`Config::validate` checks the scenario's `gust.altitude` and `gust.w20`).
pub fn low_altitude_scales(altitude_m: f64, w20: f64) -> ([f64; 3], [f64; 3]) {
    let h_ft = altitude_m / METRES_PER_FOOT;
    let d = 0.177 + 0.000823 * h_ft;
    let sigma_z = 0.1 * w20;
    let sigma_xy = sigma_z / d.powf(0.4);
    let l_xy = h_ft / d.powf(1.2) * METRES_PER_FOOT;
    ([sigma_xy, sigma_xy, sigma_z], [l_xy, l_xy, altitude_m])
}

/// [`low_altitude_scales`] for every lane at once with the lane-valued `pow`
/// ([`crate::lane::explog::pow`], within 1 ulp, the same bits on every lane path; `d^-1.2` as
/// the cube of `d^-0.4`, so within a few ulp of libm's formula): the scales
/// of turbulence that follows the vehicle, computed every step (the per-realisation path
/// takes it with `L = f64`, so both fly the same bits). The fixed scales a filter is built
/// for keep libm's [`low_altitude_scales`] (the paper's numbers).
#[inline(always)]
pub fn low_altitude_scales_lanes<L: KernelOps>(altitude_m: L, w20: L) -> ([L; 3], [L; 3]) {
    let h_ft = altitude_m / L::splat(METRES_PER_FOOT);
    let d = L::splat(0.177) + h_ft * 0.000823;
    let sigma_z = L::splat(0.1) * w20;
    // d^-0.4 once (within 1 ulp), and d^-1.2 as its cube (within 3 ulp): one `pow` and no
    // division per step where the turbulence follows the vehicle.
    let p = explog::pow(d, L::splat(-0.4));
    let sigma_xy = sigma_z * p;
    let l_xy = h_ft * (p * p * p) * METRES_PER_FOOT;
    ([sigma_xy, sigma_xy, sigma_z], [l_xy, l_xy, altitude_m])
}

/// Exact one-sided von Karman PSD (m^2/s^2 per Hz) of MIL-F-8785C at frequency
/// `f_hz`, for the scale-length convention used throughout (L_z = h at low
/// altitude): longitudinal `4 sigma^2 T / (1 + (1.339 x)^2)^(5/6)`, lateral and
/// vertical `2 sigma^2 T (1 + 8/3 (1.339 x)^2) / (1 + (1.339 x)^2)^(11/6)`, with
/// `T = L/V` and `x = 2 pi f T`. This is the target the von Karman approximants
/// of [`GustFilter`](super::GustFilter) are measured against.
pub fn von_karman_psd_exact(
    component: GustComponent,
    sigma: f64,
    length_scale: f64,
    airspeed: f64,
    f_hz: f64,
) -> f64 {
    let t = length_scale / airspeed;
    let x = 2.0 * std::f64::consts::PI * f_hz.abs() * t;
    let y = (1.339 * x).powi(2);
    match component {
        GustComponent::Longitudinal => 4.0 * sigma * sigma * t / (1.0 + y).powf(5.0 / 6.0),
        GustComponent::Lateral | GustComponent::Vertical => {
            2.0 * sigma * sigma * t * (1.0 + 8.0 / 3.0 * y) / (1.0 + y).powf(11.0 / 6.0)
        }
    }
}

/// A forming filter `H(s) = sigma sqrt(gain2 L / (pi V)) N(T s) / D(T s)` in the
/// nondimensional Laplace variable `T s` (`T = L/V`); coefficients ascending.
#[derive(Clone, Copy, Debug)]
pub(super) struct Rational {
    pub(super) num: [f64; 4],
    pub(super) den: [f64; 4],
    pub(super) order: usize,
    pub(super) gain2: f64,
}

/// Each filter's `N` and `D`: its order is the degree of `D`, and `gain2` is 2 for the
/// longitudinal component (its PSD's `2 L / (pi V)`) and 1 for the lateral and vertical ones.
pub(super) fn rational(model: GustModel, component: GustComponent) -> Rational {
    use GustModel::{Dryden, VonKarman};
    let longitudinal = component == GustComponent::Longitudinal;
    let sqrt3 = 3.0_f64.sqrt();
    let (num, den) = match (model, longitudinal) {
        (Dryden, true) => ([1.0, 0.0, 0.0, 0.0], [1.0, 1.0, 0.0, 0.0]),
        (Dryden, false) => ([1.0, sqrt3, 0.0, 0.0], [1.0, 2.0, 1.0, 0.0]),
        (VonKarman, true) => ([1.0, 0.25, 0.0, 0.0], [1.0, 1.357, 0.1987, 0.0]),
        (VonKarman, false) => ([1.0, 2.7478, 0.3398, 0.0], [1.0, 2.9958, 1.9754, 0.1539]),
    };
    Rational {
        num,
        den,
        order: den.iter().rposition(|&d| d != 0.0).expect("D(0) = 1"),
        gain2: if longitudinal { 2.0 } else { 1.0 },
    }
}

/// |P(j x)|^2 for a real polynomial with ascending coefficients.
pub(super) fn poly_abs2(c: &[f64; 4], x: f64) -> f64 {
    // (j x)^i = x^i * (1, j, -1, -j)[i % 4]
    let mut re = 0.0;
    let mut im = 0.0;
    let mut p = 1.0;
    for (i, &ci) in c.iter().enumerate() {
        match i % 4 {
            0 => re += ci * p,
            1 => im += ci * p,
            2 => re -= ci * p,
            _ => im -= ci * p,
        }
        p *= x;
    }
    re * re + im * im
}
#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scales_paper_preset_and_hand_calculation() {
        let (s, l) = low_altitude_scales(2.0, 10.0);
        assert!((s[2] - 1.0).abs() < 1e-15, "sigma_z {}", s[2]);
        assert_eq!(l[2], 2.0);
        // By hand, in feet: h = 2 / 0.3048 = 6.561679790026 ft,
        // d = 0.177 + 0.000823 h = 0.182400262467,
        // Lx = h / d^1.2 = 50.5573709860 ft = 15.4098866765 m,
        // sigma_x = 1 / d^0.4 = 1.97510330823 m/s.
        assert!((l[0] - 15.409_886_676_534).abs() < 1e-9, "Lx {}", l[0]);
        assert_eq!(l[0], l[1]);
        assert!((s[0] - 1.975_103_308_233).abs() < 1e-9, "sigma_x {}", s[0]);
        assert_eq!(s[0], s[1]);
        // 100 m = 328.08 ft: Lx = 262.794137 m, sigma_x/sigma_z = 1.379977.
        let (s, l) = low_altitude_scales(100.0, 10.0);
        assert!((l[0] - 262.794_137_166).abs() < 1e-6, "Lx {}", l[0]);
        assert!((s[0] - 1.379_977_135_317).abs() < 1e-9);
        assert_eq!(l[2], 100.0);
        // Not clamped below 10 ft: Lz stays h.
        let (_, l) = low_altitude_scales(1.0, 10.0);
        assert_eq!(l[2], 1.0);
    }
}
