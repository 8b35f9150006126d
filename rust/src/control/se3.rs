//! Geometric tracking on SE(3) (Lee, Leok & McClamroch 2010, as RotorPy's `SE3Control` flies it;
//! docs/model.md, "The geometric controller `se3`"): the thrust vector from the position errors
//! and the reference's acceleration, the desired attitude `R_d` built from its direction and the
//! reference's yaw, and the torque from the attitude error on SO(3),
//! `e_R = 1/2 vee(R_d^T R - R^T R_d)`, with no Euler angles in the law (the state's angles give
//! `R` once). Gains per axis, normalised by the controller's mass and inertia as RotorPy's are:
//! Lee's gain matrices are `m diag(kx)`, `m diag(kv)`, `J diag(kR)`, `J diag(kW)`.

use super::ControlContext;
use super::{position_errors, Control, Controller, Due, Shared, Sight, MIN_TILT_COS};
use crate::config::params::params;
use crate::lane::{gather, Lane, Masks, Param};
use crate::model::{Frame, Inputs, Tick};
use crate::trajectory::Reference;

params! {
    /// `[controller.se3]`: the geometric law's gains, every one >= 0, per axis and per unit of
    /// the controller's mass (position) or inertia (attitude).
    #[allow(non_snake_case)]
    pub struct Se3Gains {
        /// x, y, z position gains (Lee's k_x divided by the mass).
        kx: [f64; 3] => "1/s^2", "SE(3) position gains (x, y, z)", non_negative;
        /// x, y, z velocity gains (Lee's k_v divided by the mass).
        kv: [f64; 3] => "1/s", "SE(3) velocity gains (x, y, z)", non_negative;
        /// Attitude-error gains about the body axes (Lee's k_R divided by the inertia).
        kR: [f64; 3] => "1/s^2", "SE(3) attitude gains (body x, y, z)", non_negative;
        /// Body-rate gains (Lee's k_Omega divided by the inertia).
        kW: [f64; 3] => "1/s", "SE(3) body-rate gains (body x, y, z)", non_negative;
    }
}

/// The defaults, tuned for the paper's 2.2 kg vehicle with the delivery preset's slung load
/// and 30 ms rotors (docs/model.md, "The geometric controller `se3`": why these numbers).
pub const DEFAULTS: Se3Gains = Se3Gains {
    kx: [1.0, 1.0, 4.0],
    kv: [1.6, 1.6, 3.2],
    kR: [100.0, 100.0, 40.0],
    kW: [14.0, 14.0, 9.0],
};

/// Gains `P = f64` (one vehicle) or a lane type (one vehicle per lane, `Se3::gather`).
#[derive(Clone, Debug)]
pub struct Se3<P = f64> {
    shared: Shared<P>,
    kx: [P; 3],
    kv: [P; 3],
    k_r: [P; 3],
    k_w: [P; 3],
}

impl Controller for Se3 {
    const LABEL: &'static str = "SE(3)";
    type Params = Se3Gains;
    type At<L: Lane> = Se3<L>;

    fn defaults() -> Option<Se3Gains> {
        Some(DEFAULTS)
    }

    fn new(k: &Se3Gains, cfg: &ControlContext) -> Self {
        Self {
            shared: Shared::new(cfg),
            kx: k.kx,
            kv: k.kv,
            k_r: k.kR,
            k_w: k.kW,
        }
    }

    fn gather<L: Lane>(each: &[&Se3]) -> Se3<L> {
        gather!(|l| each[l] => Se3 { shared, kx, kv, k_r, k_w })
    }
}

#[inline(always)]
fn dot<L: Lane>(a: &[L; 3], b: &[L; 3]) -> L {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

#[inline(always)]
fn cross<L: Lane>(a: &[L; 3], b: &[L; 3]) -> [L; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

impl<P: Copy> Se3<P> {
    /// The desired body axes `[b1_d, b2_d, b3_d]` for the thrust vector `f` (N) and the yaw
    /// reference's sine and cosine: `b3_d` along `f`, tilted back to `controller.tilt_limit`
    /// from the vertical and never below the horizon; `b2_d = b3_d x c1 / |b3_d x c1|` with
    /// `c1 = (cos psi_d, sin psi_d, 0)`; `b1_d = b2_d x b3_d`.
    #[inline(always)]
    pub(crate) fn desired_axes<L: Lane>(&self, f: &[L; 3], spsi: L, cpsi: L) -> [[L; 3]; 3]
    where
        P: Param<L>,
    {
        let sh = &self.shared;
        let one = L::splat(1.0);
        let n = dot(f, f).sqrt().max(sh.thrust_floor.get());
        let (hx, hy) = (f[0] / n, f[1] / n);
        // sine of b3_d's angle from the vertical, limited to sin(tilt_limit)
        let sin_tilt: L = sh.sin_tilt.get();
        let k = sin_tilt / (hx * hx + hy * hy).sqrt().max(sin_tilt);
        let (bx, by) = (hx * k, hy * k);
        let bz = (one - bx * bx - by * by).max(L::splat(0.0)).sqrt();
        let b3 = [bx, by, bz];
        let c1 = [cpsi, spsi, L::splat(0.0)];
        let b2 = cross(&b3, &c1);
        let inv = one / dot(&b2, &b2).sqrt().max(L::splat(MIN_TILT_COS));
        let b2 = [b2[0] * inv, b2[1] * inv, b2[2] * inv];
        let b1 = cross(&b2, &b3);
        [b1, b2, b3]
    }
}

/// What the law holds between its loops' updates: the position loop's thrust and desired body
/// axes (b1_d, b2_d, b3_d), the attitude loop's torques.
const HELD_U1: usize = 0;
const HELD_AXES: usize = 1;
const HELD_TAU: usize = 10;
const HELD: usize = 13;

impl<P: Copy + Sync> Control<P> for Se3<P> {
    type Memory<L: Lane> = [L; HELD];

    #[inline(always)]
    fn memory<L: Masks>(&self, _seen: &Sight<L>) -> [L; HELD]
    where
        P: Param<L>,
    {
        [L::splat(0.0); HELD]
    }

    #[inline(always)]
    fn step<L: Masks>(
        &self,
        seen: &Sight<L>,
        r: &Reference,
        _at: Tick,
        due: Due,
        mem: &mut [L; HELD],
    ) -> Inputs<L>
    where
        P: Param<L>,
    {
        if due.position {
            let (u1, axes) = self.position(seen, r);
            mem[HELD_U1] = u1;
            for (j, b) in axes.iter().enumerate() {
                mem[HELD_AXES + 3 * j..HELD_AXES + 3 * j + 3].copy_from_slice(b);
            }
        }
        if due.attitude {
            let b = &mem[HELD_AXES..HELD_AXES + 9];
            let desired = [[b[0], b[1], b[2]], [b[3], b[4], b[5]], [b[6], b[7], b[8]]];
            let tau = self.attitude(seen, &desired, r);
            mem[HELD_TAU..HELD_TAU + 3].copy_from_slice(&tau);
        }
        Inputs {
            u1: mem[HELD_U1],
            tau: [mem[HELD_TAU], mem[HELD_TAU + 1], mem[HELD_TAU + 2]],
        }
    }
}

impl<P: Copy> Se3<P> {
    /// The position loop: the thrust along the body's z axis and the desired body axes.
    #[inline(always)]
    fn position<L: Lane>(&self, seen: &Sight<L>, r: &Reference) -> (L, [[L; 3]; 3])
    where
        P: Param<L>,
    {
        let sh = &self.shared;
        let (e, ed) = position_errors(seen.rigid, r);
        let (g, mt): (L, L) = (sh.g.get(), sh.mt.get());
        let [kx0, kx1, kx2] = self.kx;
        let [kv0, kv1, kv2] = self.kv;
        // F_d = m (kx e + kv e_dot + a_ref + g e3), e = reference - state (Lee's -e_x, -e_v).
        let f = [
            (e[0] * kx0.get() + ed[0] * kv0.get() + r.acc[0]) * mt,
            (e[1] * kx1.get() + ed[1] * kv1.get() + r.acc[1]) * mt,
            (e[2] * kx2.get() + ed[2] * kv2.get() + r.acc[2] + g) * mt,
        ];
        let [_, _, r3] = seen.trig.axes();
        let u1 = sh.limit_thrust(dot(&f, &r3));
        let (spsi_d, cpsi_d) = <f64 as Lane>::sin_cos(r.psi);
        (
            u1,
            self.desired_axes(&f, L::splat(spsi_d), L::splat(cpsi_d)),
        )
    }

    /// The attitude loop: the torques toward the desired body axes `[b1, b2, b3]`.
    #[inline(always)]
    fn attitude<L: Lane>(&self, seen: &Sight<L>, desired: &[[L; 3]; 3], r: &Reference) -> [L; 3]
    where
        P: Param<L>,
    {
        let sh = &self.shared;
        let [r1, r2, r3] = seen.trig.axes();
        let [b1, b2, b3] = desired;
        // e_R = 1/2 vee(R_d^T R - R^T R_d); (R_d^T R)_ij = b_i . r_j
        let half = L::splat(0.5);
        let e_r = [
            (dot(b3, &r2) - dot(b2, &r3)) * half,
            (dot(b1, &r3) - dot(b3, &r1)) * half,
            (dot(b2, &r1) - dot(b1, &r2)) * half,
        ];
        // e_W = W - W_d with RotorPy's W_d = (0, 0, psi_dot_ref) in body axes (its "this is
        // oversimplified": Lee's R^T R_d W_d would need the reference's jerk).
        let w = seen.rigid.rate;
        let r_err = w[2] - r.psi_dot;
        let [ixx, iyy, izz] = sh.inertia;
        let (ixx, iyy, izz): (L, L, L) = (ixx.get(), iyy.get(), izz.get());
        let [kr0, kr1, kr2] = self.k_r;
        let [kw0, kw1, kw2] = self.k_w;
        let (p, q, rr) = (w[0], w[1], w[2]);
        // M = J (-kR e_R - kW e_W) + W x J W
        [
            -(e_r[0] * kr0.get() + p * kw0.get()) * ixx + q * rr * (izz - iyy),
            -(e_r[1] * kr1.get() + q * kw1.get()) * iyy + rr * p * (ixx - izz),
            -(e_r[2] * kr2.get() + r_err * kw2.get()) * izz + p * q * (iyy - ixx),
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{Rigid, Trig};
    use crate::scenario::tests::paper;
    use crate::scenario::Config;

    fn law() -> (Se3, Config) {
        let cfg = paper();
        (Se3::new(&cfg.controller.se3, &cfg.control_context()), cfg)
    }

    fn state(pos: [f64; 3], att: [f64; 3], rate: [f64; 3]) -> Rigid<f64> {
        Rigid {
            pos,
            att,
            vel: [0.0; 3],
            rate,
        }
    }

    fn hover_ref(psi: f64) -> Reference {
        Reference {
            pos: [0.0, 0.0, 2.0],
            psi,
            ..Reference::default()
        }
    }

    /// R = Rz Ry Rx from independent rotation matrices.
    fn rotation(att: [f64; 3]) -> [[f64; 3]; 3] {
        let [phi, th, psi] = att;
        let rx = [
            [1.0, 0.0, 0.0],
            [0.0, phi.cos(), -phi.sin()],
            [0.0, phi.sin(), phi.cos()],
        ];
        let ry = [
            [th.cos(), 0.0, th.sin()],
            [0.0, 1.0, 0.0],
            [-th.sin(), 0.0, th.cos()],
        ];
        let rz = [
            [psi.cos(), -psi.sin(), 0.0],
            [psi.sin(), psi.cos(), 0.0],
            [0.0, 0.0, 1.0],
        ];
        let mul = |a: [[f64; 3]; 3], b: [[f64; 3]; 3]| {
            let mut c = [[0.0; 3]; 3];
            for i in 0..3 {
                for j in 0..3 {
                    c[i][j] = (0..3).map(|k| a[i][k] * b[k][j]).sum();
                }
            }
            c
        };
        mul(rz, mul(ry, rx))
    }

    /// The law reads the body axes as the paper body's frame gives them (`Frame::axes`): the
    /// columns of R = Rz Ry Rx.
    #[test]
    fn the_body_axes_the_law_reads_are_the_columns_of_the_rotation() {
        let att = [0.3, -0.7, 2.1];
        let axes = Trig::of_angles(att[0], att[1], att[2]).axes();
        let r = rotation(att);
        for j in 0..3 {
            for i in 0..3 {
                assert!((axes[j][i] - r[i][j]).abs() < 1e-15, "R[{i}][{j}]");
            }
        }
    }

    #[test]
    fn hover_holds_the_weight_with_no_torque() {
        let (c, cfg) = law();
        let w = (cfg.vehicle.mass + cfg.payload.mass) * cfg.environment.gravity;
        let u = c.control(
            &state([0.0, 0.0, 2.0], [0.0, 0.0, 0.3], [0.0; 3]),
            &hover_ref(0.3),
            Tick::START,
        );
        assert!((u.u1 - w).abs() < 1e-12, "U1 = {} vs weight {w}", u.u1);
        for t in u.tau {
            assert!(t.abs() < 1e-15, "{:?}", u.tau);
        }
    }

    /// For R = R_d exp(a hat(v)) the attitude error is sin(a) v (Lee et al., Prop. 1), so the
    /// torque at rest is -J kR sin(a) v: the sign convention of the PD's torques (positive
    /// torque raises the angle).
    #[test]
    fn attitude_error_is_the_sine_of_the_rotation_angle_about_its_axis() {
        let (c, cfg) = law();
        let [ixx, iyy, izz] = cfg.vehicle.inertia;
        let k = c.k_r;
        for (att, axis, a) in [
            ([0.2, 0.0, 0.0], [1.0, 0.0, 0.0], 0.2f64),
            ([0.0, -0.35, 0.0], [0.0, 1.0, 0.0], -0.35),
            ([0.0, 0.0, 0.6], [0.0, 0.0, 1.0], 0.6),
        ] {
            let u = c.control(
                &state([0.0, 0.0, 2.0], att, [0.0; 3]),
                &hover_ref(0.0),
                Tick::START,
            );
            let want = [
                -ixx * k[0] * a.sin() * axis[0],
                -iyy * k[1] * a.sin() * axis[1],
                -izz * k[2] * a.sin() * axis[2],
            ];
            for i in 0..3 {
                assert!(
                    (u.tau[i] - want[i]).abs() < 1e-13,
                    "{att:?}: {:?} vs {want:?}",
                    u.tau
                );
            }
        }
    }

    /// A vehicle 1 m behind its reference in x tilts nose down toward it: b3_d leans to +x,
    /// the pitch torque is positive (pitch raises R e3's x component).
    #[test]
    fn a_lateral_error_tilts_the_thrust_toward_the_reference() {
        let (c, cfg) = law();
        let mt = cfg.vehicle.mass + cfg.payload.mass;
        let g = cfg.environment.gravity;
        let s = state([-1.0, 0.0, 2.0], [0.0; 3], [0.0; 3]);
        let u = c.control(&s, &hover_ref(0.0), Tick::START);
        let f = [mt * DEFAULTS.kx[0], 0.0, mt * g];
        let b3x = f[0] / (f[0] * f[0] + f[2] * f[2]).sqrt();
        assert!((u.u1 - mt * g).abs() < 1e-12);
        // b1_d = (b3z, 0, -b3x): e_R,y = (b1_d . e3 - b3_d . e1) / 2 = -b3x
        let want = iyy_of(&cfg) * DEFAULTS.kR[1] * b3x;
        assert!((u.tau[1] - want).abs() < 1e-12, "{} vs {want}", u.tau[1]);
        assert!(u.tau[0].abs() < 1e-15 && u.tau[2].abs() < 1e-15);
    }

    fn iyy_of(cfg: &Config) -> f64 {
        cfg.vehicle.inertia[1]
    }

    /// The body rates are damped and the gyroscopic term cancelled: M = -J kW W + W x J W.
    #[test]
    fn rates_are_damped_and_the_gyroscopic_term_cancelled() {
        let (c, cfg) = law();
        let [ixx, iyy, izz] = cfg.vehicle.inertia;
        let w = [0.3, -0.2, 0.5];
        let u = c.control(
            &state([0.0, 0.0, 2.0], [0.0; 3], w),
            &hover_ref(0.0),
            Tick::START,
        );
        let jw = [ixx * w[0], iyy * w[1], izz * w[2]];
        let gyro = [
            w[1] * jw[2] - w[2] * jw[1],
            w[2] * jw[0] - w[0] * jw[2],
            w[0] * jw[1] - w[1] * jw[0],
        ];
        let kw = DEFAULTS.kW;
        for i in 0..3 {
            let want = -jw[i] * kw[i] + gyro[i];
            assert!(
                (u.tau[i] - want).abs() < 1e-14,
                "{i}: {} vs {want}",
                u.tau[i]
            );
        }
    }

    /// The desired axes are orthonormal and right-handed, b1_d lies in the plane of b3_d and
    /// the heading c1, and b3_d stays within `tilt_limit` of the vertical and above the
    /// horizon, even for a thrust vector pointing down.
    #[test]
    fn desired_axes_are_a_rotation_within_the_tilt_limit() {
        let mut cfg = paper();
        cfg.controller.tilt_limit = 0.4;
        let c = Se3::new(&cfg.controller.se3, &cfg.control_context());
        let (s, co) = 0.7f64.sin_cos();
        for f in [
            [0.5, -0.2, 20.0],
            [30.0, 10.0, 20.0],
            [3.0, -4.0, -20.0],
            [1e-3, 0.0, 2e-3],
        ] {
            let [b1, b2, b3] = c.desired_axes(&f, s, co);
            for (a, b, want) in [
                (b1, b1, 1.0),
                (b2, b2, 1.0),
                (b3, b3, 1.0),
                (b1, b2, 0.0),
                (b1, b3, 0.0),
                (b2, b3, 0.0),
            ] {
                assert!((dot(&a, &b) - want).abs() < 1e-14, "{f:?}");
            }
            let x = cross(&b1, &b2);
            assert!((0..3).all(|i| (x[i] - b3[i]).abs() < 1e-14), "{f:?}");
            assert!(b3[2] >= 0.4f64.cos() - 1e-14, "{f:?}: {b3:?}");
            // b2_d is across the heading c1: b1_d = c1 - (c1 . b3_d) b3_d, normalised
            assert!((b2[0] * co + b2[1] * s).abs() < 1e-14, "{f:?}");
            // within the limit b3_d is along f
            let n = dot(&f, &f).sqrt();
            if f[2] > 0.0 && (f[0] * f[0] + f[1] * f[1]).sqrt() / n < 0.4f64.sin() && n > 0.1 {
                assert!((0..3).all(|i| (b3[i] - f[i] / n).abs() < 1e-14), "{f:?}");
            }
        }
    }

    #[test]
    fn thrust_is_along_the_body_axis_and_limited() {
        let mut cfg = paper();
        cfg.controller.thrust_max = Some(20.0);
        let c = Se3::new(&cfg.controller.se3, &cfg.control_context());
        let s = state([0.0, 0.0, 1.0], [0.1, 0.0, 0.0], [0.0; 3]);
        let u = c.control(&s, &hover_ref(0.0), Tick::START);
        assert_eq!(u.u1, 20.0);
        cfg.controller.thrust_max = None;
        let c = Se3::new(&cfg.controller.se3, &cfg.control_context());
        let u = c.control(&s, &hover_ref(0.0), Tick::START);
        let mt = cfg.vehicle.mass + cfg.payload.mass;
        let fz = mt * (DEFAULTS.kx[2] * 1.0 + cfg.environment.gravity);
        // F_d = (0, 0, fz), R e3 = (0, -sin 0.1, cos 0.1)
        assert!((u.u1 - fz * 0.1f64.cos()).abs() < 1e-12);
    }

    #[test]
    fn lanes_fly_their_own_gains() {
        use crate::lane::F64x4;
        let (c, cfg) = law();
        let mut other = cfg.clone();
        other.controller.se3.kx = [2.0, 0.5, 3.0];
        other.controller.se3.kR = [50.0, 80.0, 10.0];
        let d = Se3::new(&other.controller.se3, &other.control_context());
        let laws = [&c, &d, &c, &d];
        let lanes: Se3<F64x4> = Se3::gather(&laws);
        let s1 = state([0.3, -0.4, 1.7], [0.1, -0.05, 0.2], [0.2, 0.1, -0.3]);
        let pack = |f: fn(&Rigid<f64>) -> [f64; 3]| [0, 1, 2].map(|i| F64x4::splat(f(&s1)[i]));
        let s4 = Rigid {
            pos: pack(|s| s.pos),
            att: pack(|s| s.att),
            vel: pack(|s| s.vel),
            rate: pack(|s| s.rate),
        };
        let r = hover_ref(0.1);
        let u4 = lanes.control(&s4, &r, Tick::START);
        for (l, law) in laws.iter().enumerate() {
            let u = law.control(&s1, &r, Tick::START);
            assert_eq!(u4.u1.lane(l).to_bits(), u.u1.to_bits());
            for i in 0..3 {
                assert_eq!(u4.tau[i].lane(l).to_bits(), u.tau[i].to_bits());
            }
        }
    }

    /// The closed loop's dual-number Jacobian (what `stability` and `linearize` use) against
    /// central differences of the same closed loop, off hover (every term of the law active:
    /// tilt, yaw error, rates, a moving reference with feed-forward), for the paper's vehicle
    /// and for the slung load on rotors.
    #[test]
    fn jacobian_matches_central_differences() {
        use crate::control::ControllerKind;
        use crate::stability::{closed_loop, closed_loop_jacobian};
        let mut slung = paper();
        slung.payload.model = crate::scenario::PayloadKind::Cable;
        slung.payload.cable.cable_length = Some(1.0);
        slung.payload.cable.attachment_offset = Some(0.05);
        slung.payload.natural_frequency = Some(10.0);
        slung.actuator.model = crate::scenario::ActuatorKind::Rotors;
        slung.validate().expect("a valid slung scenario on rotors");
        for cfg in [paper(), slung] {
            let r = Reference {
                pos: [0.5, -0.3, 2.0],
                vel: [0.4, 0.2, -0.1],
                acc: [0.3, -0.2, 0.1],
                psi: 0.2,
                ..Reference::default()
            };
            let cl = closed_loop(&cfg, ControllerKind::Se3, r);
            let mut s = cl.rest();
            for (i, x) in s.iter_mut().enumerate() {
                *x += 0.05 * (i as f64 + 1.0).sin();
            }
            let w = [1.0, -0.5, 0.3];
            let jac = closed_loop_jacobian(&*cl, &s, &w);
            let h = 1e-6;
            for j in 0..s.len() {
                let (mut up, mut down) = (s.clone(), s.clone());
                up[j] += h;
                down[j] -= h;
                let (fu, fd) = (cl.eval(&up, &w).0, cl.eval(&down, &w).0);
                for i in 0..s.len() {
                    let fdiff = (fu[i] - fd[i]) / (2.0 * h);
                    assert!(
                        (fdiff - jac[(i, j)]).abs() < 1e-6 * fdiff.abs().max(1.0),
                        "({i}, {j}): {fdiff} vs {}",
                        jac[(i, j)]
                    );
                }
            }
        }
    }
}
