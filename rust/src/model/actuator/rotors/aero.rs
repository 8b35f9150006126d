//! The rotors' aerodynamic wrench (RotorPy's `Multirotor.compute_body_wrench`), summed over
//! the four rotors in closed form.
//!
//! Rotor i at hub (rx_i, ry_i) in body axes spins at w_i in the local air
//! v_i = v_b + W x r_i = (v_x - W_z ry_i, v_y + W_z rx_i, v_z + W_x ry_i - W_y rx_i), v_b the
//! body's airspeed in body axes, W its rates. It feels the H-force -w_i diag(k_d, k_d, k_z) v_i
//! and the translational lift k_h (v_ix^2 + v_iy^2) along body z, both at its hub (moment
//! r_i x f_i), and the flapping moment -k_flap w_i (v_iy, -v_ix, 0). Every term is linear in
//! w_i or free of it, and v_i is linear in the hub: the sums over the rotors are sums of the
//! speeds weighted by the hubs' coordinates (`Moments`, per stage) and of the hubs'
//! own coordinates (`HubSums`, fixed). About half the operations of the rotor-by-rotor sum, for
//! the same wrench up to rounding (`tests::the_closed_form_is_the_sum_over_the_rotors`).

use crate::lane::{gather, Gathered, Lane};

/// Sums over the rotors of a weight c_i times the hubs' coordinates: sum c_i, c_i rx_i,
/// c_i ry_i, c_i rx_i^2, c_i ry_i^2, c_i rx_i ry_i (the speeds' with c_i = w_i; the hubs'
/// own with c_i = 1).
#[derive(Clone, Copy, Debug)]
pub struct Moments<L = f64> {
    n: L,
    x: L,
    y: L,
    xx: L,
    yy: L,
    xy: L,
}

impl<L: Lane> Moments<L> {
    /// The sums of weights `c` on hubs `hubs` (m, each rotor's (x, y) in body axes).
    #[inline(always)]
    pub fn of(c: &[L; 4], hubs: &[[L; 2]; 4]) -> Self {
        let zero = L::splat(0.0);
        let mut s = Self {
            n: zero,
            x: zero,
            y: zero,
            xx: zero,
            yy: zero,
            xy: zero,
        };
        for (c, [rx, ry]) in c.iter().zip(hubs) {
            let (cx, cy) = (*c * *rx, *c * *ry);
            s.n += *c;
            s.x += cx;
            s.y += cy;
            s.xx += cx * *rx;
            s.yy += cy * *ry;
            s.xy += cx * *ry;
        }
        s
    }
}

/// The hubs' own sums (m^k): their `Moments`, and sum rx^2 + ry^2, rx (rx^2 + ry^2),
/// ry (rx^2 + ry^2). The odd ones are zero for the symmetric layouts; kept general.
#[derive(Clone, Copy, Debug)]
pub struct HubSums<L = f64> {
    moments: Moments<L>,
    rr: L,
    xrr: L,
    yrr: L,
}

impl HubSums {
    /// The sums of `hubs` (m, each rotor's (x, y) in body axes).
    pub fn of(hubs: &[[f64; 2]; 4]) -> Self {
        let sum = |f: &dyn Fn(f64, f64) -> f64| hubs.iter().map(|&[x, y]| f(x, y)).sum();
        Self {
            moments: Moments::of(&[1.0; 4], hubs),
            rr: sum(&|x, y| x * x + y * y),
            xrr: sum(&|x, y| x * (x * x + y * y)),
            yrr: sum(&|x, y| y * (x * x + y * y)),
        }
    }
}

impl<L: Lane> Gathered for Moments<L> {
    type From = Moments;
    fn gather_from<'a>(lane: impl Fn(usize) -> &'a Moments + Copy) -> Self {
        gather!(|l| lane(l) => Moments { n, x, y, xx, yy, xy })
    }
}

impl<L: Lane> Gathered for HubSums<L> {
    type From = HubSums;
    fn gather_from<'a>(lane: impl Fn(usize) -> &'a HubSums + Copy) -> Self {
        gather!(|l| lane(l) => HubSums { moments, rr, xrr, yrr })
    }
}

/// The rotors' aerodynamic coefficients (RotorPy's `Multirotor.compute_body_wrench`): the
/// H-force's (k_d, k_d, k_z) (N per rad/s m/s), the flapping moment's k_flap (N m per rad/s
/// m/s; `flaps`: whether any lane's is nonzero, else the moment is not added), the
/// translational lift's k_h (N per (m/s)^2).
#[derive(Clone, Copy, Debug)]
pub struct Coefficients<L = f64> {
    pub drag: [L; 3],
    pub flapping: L,
    pub flaps: bool,
    pub lift: L,
}

impl Coefficients {
    /// `actuator.rotor_drag`, `actuator.flapping` and `actuator.translational_lift`.
    pub fn new(drag: [f64; 3], flapping: f64, lift: f64) -> Self {
        Self {
            drag,
            flapping,
            flaps: flapping != 0.0,
            lift,
        }
    }

    /// Whether any term is nonzero (else the wrench is zero and not computed).
    pub fn any(&self) -> bool {
        self.drag != [0.0; 3] || self.flapping != 0.0 || self.lift != 0.0
    }
}

impl<L: Lane> Gathered for Coefficients<L> {
    type From = Coefficients;
    fn gather_from<'a>(lane: impl Fn(usize) -> &'a Coefficients + Copy) -> Self {
        gather!(|l| lane(l) => Coefficients {
            drag, flapping, lift;
            flaps: (0..L::LANES).any(|l| lane(l).flaps)
        })
    }
}

/// The force and moment (body axes, N and N m) of rotors spinning at `w` (rad/s) on hubs
/// `hubs` (sums `sums`) with the body's airspeed `vb` (m/s) and rates `rates` (rad/s), both
/// in body axes.
#[inline(always)]
pub fn wrench<L: Lane>(
    c: &Coefficients<L>,
    w: &[L; 4],
    hubs: &[[L; 2]; 4],
    sums: &HubSums<L>,
    vb: &[L; 3],
    rates: &[L; 3],
) -> ([L; 3], [L; 3]) {
    let [v0, v1, v2] = *vb;
    let [wx, wy, wz] = *rates;
    let [kd, kd_y, kz] = c.drag;
    let s = Moments::of(w, hubs);
    let (h, hm) = (sums, &sums.moments);
    // Sum w_i v_i, and sum w_i v_iz weighted by rx_i and by ry_i (the moments' arms).
    let wv = [
        v0 * s.n - wz * s.y,
        v1 * s.n + wz * s.x,
        v2 * s.n + wx * s.y - wy * s.x,
    ];
    let wvz_x = v2 * s.x + wx * s.xy - wy * s.xx;
    let wvz_y = v2 * s.y + wx * s.yy - wy * s.xy;
    // Sum of v_ix^2 + v_iy^2, and the same weighted by rx_i and by ry_i, times k_h.
    let (speed2, wz2, wz_twice) = (v0 * v0 + v1 * v1, wz * wz, wz + wz);
    let lift_all = c.lift * (hm.n * speed2 + wz_twice * (v1 * hm.x - v0 * hm.y) + wz2 * h.rr);
    let lift_x = c.lift * (hm.x * speed2 + wz_twice * (v1 * hm.xx - v0 * hm.xy) + wz2 * h.xrr);
    let lift_y = c.lift * (hm.y * speed2 + wz_twice * (v1 * hm.xy - v0 * hm.yy) + wz2 * h.yrr);
    let f = [-(kd * wv[0]), -(kd_y * wv[1]), lift_all - kz * wv[2]];
    // Sum r_i x f_i = (sum ry_i f_iz, -sum rx_i f_iz, sum rx_i f_iy - ry_i f_ix).
    let mut m = [
        lift_y - kz * wvz_y,
        kz * wvz_x - lift_x,
        kd * (v0 * s.y - wz * s.yy) - kd_y * (v1 * s.x + wz * s.xx),
    ];
    if c.flaps {
        m[0] = m[0] - c.flapping * wv[1];
        m[1] += c.flapping * wv[0];
    }
    (f, m)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::actuator::rotors::{arm_directions, RotorLayout};

    /// RotorPy's loop, rotor by rotor (`Multirotor.compute_body_wrench`).
    fn rotor_by_rotor(
        c: &Coefficients<f64>,
        w: &[f64; 4],
        hubs: &[[f64; 2]; 4],
        vb: &[f64; 3],
        rates: &[f64; 3],
    ) -> ([f64; 3], [f64; 3]) {
        let (mut f, mut m) = ([0.0; 3], [0.0; 3]);
        for (w, [rx, ry]) in w.iter().zip(hubs) {
            let v = [
                vb[0] - rates[2] * ry,
                vb[1] + rates[2] * rx,
                vb[2] + rates[0] * ry - rates[1] * rx,
            ];
            let h = [
                -w * c.drag[0] * v[0],
                -w * c.drag[1] * v[1],
                -w * c.drag[2] * v[2] + c.lift * (v[0] * v[0] + v[1] * v[1]),
            ];
            for i in 0..3 {
                f[i] += h[i];
            }
            m[0] += ry * h[2] - c.flapping * w * v[1];
            m[1] += c.flapping * w * v[0] - rx * h[2];
            m[2] += rx * h[1] - ry * h[0];
        }
        (f, m)
    }

    /// Over both layouts, an asymmetric set of hubs (where the odd sums are not zero), speeds,
    /// airspeeds and rates of flight, with and without flapping: the closed form is the
    /// rotor-by-rotor sum to rounding (each term's scale times a few ulp).
    #[test]
    fn the_closed_form_is_the_sum_over_the_rotors() {
        let arm = 0.1725;
        let mut layouts: Vec<[[f64; 2]; 4]> = [RotorLayout::X, RotorLayout::Plus]
            .iter()
            .map(|&l| arm_directions(l).map(|[c, s]| [arm * c, arm * s]))
            .collect();
        layouts.push([[0.2, 0.1], [-0.15, 0.18], [-0.1, -0.22], [0.25, -0.05]]);
        let mut x = 0.123_f64;
        let mut next = move || {
            x = (x * 9301.0 + 0.49297).fract();
            x - 0.5
        };
        for hubs in &layouts {
            for flapping in [0.0, 2e-4] {
                let c = Coefficients {
                    drag: [1.44e-4, 1.6e-4, 2.8e-4],
                    flapping,
                    flaps: flapping != 0.0,
                    lift: 5.5e-3,
                };
                for _ in 0..200 {
                    let w = [0; 4].map(|_| 700.0 + 600.0 * next());
                    let vb = [0; 3].map(|_| 30.0 * next());
                    let rates = [0; 3].map(|_| 8.0 * next());
                    let (f, m) = wrench(&c, &w, hubs, &HubSums::of(hubs), &vb, &rates);
                    let (fr, mr) = rotor_by_rotor(&c, &w, hubs, &vb, &rates);
                    // The largest single term of the sums sets the rounding's scale.
                    let scale = 4.0 * 1e3 * 30.0 * 3e-4 + 5.5e-3 * 4.0 * 900.0;
                    for (a, b) in f.iter().zip(&fr).chain(m.iter().zip(&mr)) {
                        assert!((a - b).abs() <= 1e-14 * scale, "{a} {b}");
                    }
                }
            }
        }
    }
}
