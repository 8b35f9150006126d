//! The rigid quadrotor (docs/model.md section 1 and "Bodies"): mass, inertia, its own drag,
//! and the rotational equations; and the two ways its attitude is carried (`BodyKind`): the
//! paper's Euler angles whose rates stand for body rates (`Paper`), or a unit quaternion with
//! true body rates (`Rigid`). How it translates depends on how the payload pulls (`payload`).

use super::layout::{
    Layout, StateVar, RIGID_POSITIONS, RIGID_VELOCITIES, VEHICLE_POSITIONS, VEHICLE_VELOCITIES,
};
use super::{ix, State, Trig};
use crate::config::Context;
use crate::lane::{gather, KernelOps, Lane};

pub use crate::config::vehicle::{BodyModel, BODY_MODELS};

/// The quadrotor's parameters, resolved once from the scenario (plant inertia = nominal +
/// error). `L = f64` is one vehicle; a lane type carries one vehicle per lane (`gather`).
#[derive(Clone, Copy, Debug)]
pub struct Body<L = f64> {
    /// kg, the quadrotor alone.
    pub m: L,
    pub g: L,
    /// Plant inertia I + dI.
    pub inertia: [L; 3],
    /// 1/2 rho CdA of the quadrotor: vertical (`vehicle.drag_area`) and horizontal
    /// (`vehicle.lateral_drag_area`).
    pub drag_quad: L,
    pub drag_lateral: L,
    /// N/(m/s)^2, the rigid body's drag coefficients along its own axes
    /// (`vehicle.drag_coefficients`).
    pub drag_coefficients: [L; 3],
    /// Reciprocals, computed once: the derivative multiplies by them.
    pub inv_m: L,
    pub inv_inertia: [L; 3],
}

impl Body {
    /// The quadrotor of a validated scenario.
    pub fn new(cfg: &Context) -> Self {
        let half_rho = 0.5 * cfg.gust.air_density;
        let v = &cfg.vehicle;
        let inertia = [
            v.inertia[0] + v.inertia_error[0],
            v.inertia[1] + v.inertia_error[1],
            v.inertia[2] + v.inertia_error[2],
        ];
        Self {
            m: v.mass,
            g: cfg.environment.gravity,
            inertia,
            drag_quad: half_rho * v.drag_area,
            drag_lateral: half_rho * v.lateral_drag_area,
            drag_coefficients: v.drag_coefficients,
            inv_m: 1.0 / v.mass,
            inv_inertia: inertia.map(|i| 1.0 / i),
        }
    }

    /// One vehicle per lane: lane `l` of every parameter is `each[l]`'s.
    pub fn gather<L: Lane>(each: &[&Body]) -> Body<L> {
        gather!(|l| each[l] => Body {
            m, g, inertia, drag_quad, drag_lateral, drag_coefficients, inv_m, inv_inertia,
        })
    }
}

/// Drag force on a body of `k` = 1/2 rho CdA moving at `v` in wind `wind` (one axis).
#[inline(always)]
pub fn drag<L: Lane>(k: L, v: L, wind: L) -> L {
    let rel = v - wind;
    rel * rel.abs() * (-k)
}

impl<L: Lane> Body<L> {
    /// The vertical drag force on the quadrotor (N) at vertical speed `vz` in vertical wind
    /// `wind_z` (m/s): Fdz = -1/2 rho CdA (vz - wind_z) |vz - wind_z| (docs/model.md section 1),
    /// the very term the derivative uses (and the trace's `drag_z`).
    #[inline(always)]
    pub fn vertical_drag(&self, vz: L, wind_z: L) -> L {
        drag(self.drag_quad, vz, wind_z)
    }

    /// d(p, q, r)/dt: Euler's equations in the near-hover form, with the controller's torques
    /// `tau` and, if the payload applies one, its torque `extra` (body axes).
    #[inline(always)]
    pub fn rotation(&self, rate: &[L; 3], tau: &[L; 3], extra: &Option<[L; 3]>) -> [L; 3] {
        let [p, q, r] = *rate;
        let tau = match extra {
            Some(t) => [tau[0] + t[0], tau[1] + t[1], tau[2] + t[2]],
            None => *tau,
        };
        // Destructured, not `array::map`: everything here must inline into the flight loop.
        let [ixx, iyy, izz] = self.inertia;
        let [inv_ixx, inv_iyy, inv_izz] = self.inv_inertia;
        // Products-plus-sums as `mul_add`: the same bits as `a * b + c` except in the fused
        // mode (`Lane::mul_add`).
        [
            (q * r).mul_add(iyy - izz, tau[0]) * inv_ixx,
            (p * r).mul_add(izz - ixx, tau[1]) * inv_iyy,
            (p * q).mul_add(ixx - iyy, tau[2]) * inv_izz,
        ]
    }
}

/// The body's attitude at one state, as the payload and the drag read it: the paper's sines
/// and cosines of the Euler angles (`Trig`), or the rigid body's rotation matrix.
pub trait Frame<L: Lane>: Copy {
    /// How many states the attitude takes (3 Euler angles, 4 quaternion components).
    const ATT: usize;

    /// The body's x, y and z axes in inertial axes: the columns of R.
    fn axes(&self) -> [[L; 3]; 3];

    /// N, the quadrotor's own drag force in inertial axes at velocity `v` in wind `w` (m/s).
    fn drag(&self, body: &Body<L>, v: &[L; 3], w: &[L; 3]) -> [L; 3];

    /// Where each part's states sit with this attitude.
    fn layout(payload_dof: usize, actuator_states: usize) -> Layout {
        Layout::with_attitude(Self::ATT, payload_dof, actuator_states)
    }
}

impl<L: Lane> Frame<L> for Trig<L> {
    const ATT: usize = 3;

    /// R = Rz(psi) Ry(theta) Rx(phi).
    #[inline(always)]
    fn axes(&self) -> [[L; 3]; 3] {
        let Trig {
            sphi,
            cphi,
            sth,
            cth,
            spsi,
            cpsi,
        } = *self;
        let (ss, cs) = (sth * sphi, sth * cphi);
        [
            [cpsi * cth, spsi * cth, -sth],
            [
                cpsi.mul_add(ss, -(spsi * cphi)),
                spsi.mul_add(ss, cpsi * cphi),
                cth * sphi,
            ],
            [
                cs.mul_add(cpsi, spsi * sphi),
                cs.mul_add(spsi, -(sphi * cpsi)),
                cphi * cth,
            ],
        ]
    }

    /// The paper's: -1/2 rho CdA (v_i - w_i) |v_i - w_i| per inertial axis.
    #[inline(always)]
    fn drag(&self, body: &Body<L>, v: &[L; 3], w: &[L; 3]) -> [L; 3] {
        [
            drag(body.drag_lateral, v[0], w[0]),
            drag(body.drag_lateral, v[1], w[1]),
            body.vertical_drag(v[2], w[2]),
        ]
    }
}

/// A bound T on the roll and pitch, as `Rotation::surely_within` reads it: each lane's bound
/// narrowed by `MARGIN` of itself, T' = T (1 - MARGIN), and its sine and cosine. The margin
/// is far above the roundings of both sides (the matrix's products and square root, `euler`'s
/// `atan2` and `asin`, each within an ulp or two), so a lane found within T' is within T as
/// `euler` finds it.
#[derive(Clone, Copy, Debug)]
pub struct TiltBound<L> {
    sin_pitch: L,
    cos_roll: L,
}

impl<L: Lane> TiltBound<L> {
    /// The bound's relative narrowing.
    pub const MARGIN: f64 = 1e-6;

    /// The bound of each lane `max_tilt(lane)` (rad).
    pub fn new(max_tilt: impl Fn(usize) -> f64) -> Self {
        // Below 1e-4 rad the cosines of T and T' differ by under a hundred roundings, and a
        // bound that is no number is no bound to narrow: those lanes are left to `euler`.
        let narrowed = |l| {
            let t = max_tilt(l);
            (t > 1e-4).then(|| (t * (1.0 - Self::MARGIN)).min(std::f64::consts::PI))
        };
        Self {
            // Past pi/2 every pitch (`euler`'s, within +-pi/2) is within.
            sin_pitch: L::from_fn(|l| {
                narrowed(l).map_or(-1.0, |t| t.min(std::f64::consts::FRAC_PI_2).sin())
            }),
            // cos is decreasing on [0, pi]; 2 admits no lane.
            cos_roll: L::from_fn(|l| narrowed(l).map_or(2.0, f64::cos)),
        }
    }
}

/// The rigid body's attitude at one state: its rotation matrix.
#[derive(Clone, Copy, Debug)]
pub struct Rotation<L> {
    /// The body's x, y and z axes in inertial axes (the columns of R).
    pub axes: [[L; 3]; 3],
}

#[inline(always)]
fn dot<L: Lane>(a: &[L; 3], b: &[L; 3]) -> L {
    a[0].mul_add(b[0], a[1].mul_add(b[1], a[2] * b[2]))
}

impl<L: Lane> Rotation<L> {
    /// R of the quaternion (qw, qx, qy, qz), normalised on the way (as scipy's
    /// `Rotation.from_quat`, which RotorPy uses): exactly a rotation between the RK4 stages,
    /// where the quaternion is off unit length by O(dt^5).
    #[inline(always)]
    pub fn of_quaternion(q: [L; 4]) -> Self {
        let [w, x, y, z] = q;
        let s = L::splat(2.0) / (w * w + x * x + y * y + z * z);
        let (xx, yy, zz) = (x * x * s, y * y * s, z * z * s);
        let (xy, xz, yz) = (x * y * s, x * z * s, y * z * s);
        let (wx, wy, wz) = (w * x * s, w * y * s, w * z * s);
        let one = L::splat(1.0);
        Self {
            axes: [
                [one - (yy + zz), xy + wz, xz - wy],
                [xy - wz, one - (xx + zz), yz + wx],
                [xz + wy, yz - wx, one - (xx + yy)],
            ],
        }
    }

    /// The sines and cosines of `euler`'s angles from the matrix itself, without a
    /// trigonometric function: cos(pitch) = |(R21, R22)| (the pitch within +-90 deg, as
    /// `euler`'s), the roll's and yaw's its entries over it (at the pole, where neither angle is
    /// defined, both pairs 0).
    #[inline(always)]
    pub fn trig(&self) -> Trig<L> {
        let [ex, ey, ez] = self.axes;
        let one = L::splat(1.0);
        let cth = (ey[2] * ey[2] + ez[2] * ez[2]).sqrt();
        let inv = one / cth.max(L::splat(f64::MIN_POSITIVE));
        Trig {
            sphi: ey[2] * inv,
            cphi: ez[2] * inv,
            sth: (-ex[2]).max(-one).min(one),
            cth,
            spsi: ex[1] * inv,
            cpsi: ex[0] * inv,
        }
    }

    /// The ZYX Euler angles (roll, pitch, yaw) of R: yaw in (-pi, pi].
    #[inline(always)]
    pub fn euler(&self) -> [L; 3] {
        let [ex, ey, ez] = self.axes;
        let one = L::splat(1.0);
        [
            ey[2].atan2(ez[2]),
            (-ex[2]).max(-one).min(one).asin(),
            ex[1].atan2(ex[0]),
        ]
    }

    /// The lanes (a `Lane::le_mask`) whose roll and pitch (`euler`'s) are surely within
    /// `bound`, from the matrix's entries alone: a square root and three comparisons where
    /// `euler` takes two `atan2` and an `asin`. A lane left out may still be within: near the
    /// bound (a relative `TiltBound::MARGIN`), at the pole and where a value is not finite,
    /// only `euler` decides.
    #[inline(always)]
    pub fn surely_within(&self, bound: &TiltBound<L>) -> u32 {
        let [ex, ey, ez] = self.axes;
        // |roll| <= T' <=> cos(roll) = R33 / |(R32, R33)| >= cos T' (T' in [0, pi]);
        // |pitch| <= T' <=> |R31| <= sin T' (T' in [0, pi/2]; beyond it every pitch is).
        let cth = (ey[2] * ey[2] + ez[2] * ez[2]).sqrt();
        (bound.cos_roll * cth).le_mask(ez[2])
            & ex[2].abs().le_mask(bound.sin_pitch)
            & L::splat(f64::MIN_POSITIVE).le_mask(cth)
    }

    /// R^T a: inertial `a` in body axes.
    #[inline(always)]
    pub fn to_body(&self, a: &[L; 3]) -> [L; 3] {
        let [ex, ey, ez] = &self.axes;
        [dot(ex, a), dot(ey, a), dot(ez, a)]
    }

    /// R b: body-axis `b` in inertial axes.
    #[inline(always)]
    pub fn to_inertial(&self, b: &[L; 3]) -> [L; 3] {
        let [ex, ey, ez] = &self.axes;
        let at = |i: usize| ex[i].mul_add(b[0], ey[i].mul_add(b[1], ez[i] * b[2]));
        [at(0), at(1), at(2)]
    }
}

impl<L: Lane> Frame<L> for Rotation<L> {
    const ATT: usize = 4;

    #[inline(always)]
    fn axes(&self) -> [[L; 3]; 3] {
        self.axes
    }

    /// RotorPy's parasitic drag: D = -|v_b| diag(c) v_b in body axes, v_b = R^T (v - w),
    /// turned to inertial axes.
    #[inline(always)]
    fn drag(&self, body: &Body<L>, v: &[L; 3], w: &[L; 3]) -> [L; 3] {
        let vb = self.to_body(&[v[0] - w[0], v[1] - w[1], v[2] - w[2]]);
        let speed = dot(&vb, &vb).sqrt();
        let c = &body.drag_coefficients;
        let d = [
            -(speed * c[0] * vb[0]),
            -(speed * c[1] * vb[1]),
            -(speed * c[2] * vb[2]),
        ];
        self.to_inertial(&d)
    }
}

/// How a body carries its attitude (`vehicle.body`): its states, their kinematics, and what
/// the payload, the drag and the controller read of them (`Frame`).
pub trait BodyKind: Copy + Send + Sync + 'static {
    /// Its name in the scenario.
    const MODEL: BodyModel;
    /// The positions and attitude states, then the velocities and rates (the state names).
    const POSITIONS: &'static [StateVar];
    const VELOCITIES: &'static [StateVar];
    /// A state the linearisation leaves out, determined by the others through the attitude's
    /// constraint (the rigid body's qw = sqrt(1 - qx^2 - qy^2 - qz^2): the linear model's
    /// attitude is the quaternion's vector part, three parameters; `stability`).
    const DEPENDENT: Option<usize>;
    /// Trace columns derived from the states, after them (the rigid body's Euler angles).
    const DERIVED: &'static [&'static str];
    /// The attitude at one state.
    type Frame<L: Lane>: Frame<L>;

    /// Where each part's states sit.
    fn layout(payload_dof: usize, actuator_states: usize) -> Layout {
        <Self::Frame<f64> as Frame<f64>>::layout(payload_dof, actuator_states)
    }

    /// The attitude at `s`.
    fn frame<L: Lane, const N: usize>(s: &State<L, N>) -> Self::Frame<L>;

    /// The attitude at the RK4 stage state `at = s + h k`, from `f`, that at `s`.
    fn advanced<L: KernelOps, const N: usize>(
        f: &Self::Frame<L>,
        k: &State<L, N>,
        h: f64,
        at: &State<L, N>,
    ) -> Self::Frame<L>;

    /// The attitude states' derivative (`ds[att..]`) from the rates at `s`.
    fn attitude_rates<L: Lane, const N: usize>(s: &State<L, N>, lay: Layout, ds: &mut State<L, N>);

    /// Roll, pitch, yaw at `s` (rad), as the controllers read them.
    fn euler<L: Lane, const N: usize>(s: &State<L, N>, f: &Self::Frame<L>) -> [L; 3];

    /// The sines and cosines of `euler` (from `euler(s, f)`), as the controllers read them.
    fn trig<L: Lane>(f: &Self::Frame<L>, euler: &[L; 3]) -> Trig<L>;

    /// The dependent state (`DEPENDENT`) of `s` from the others.
    fn complete<L: Lane>(_s: &mut [L]) {}

    /// Put the attitude of roll, pitch, yaw `euler` (rad) into `s`.
    fn set_attitude(s: &mut [f64], euler: [f64; 3]);

    /// After each RK4 step: bring the attitude back onto its constraint (the quaternion to
    /// unit length).
    fn project<L: Lane, const N: usize>(s: &mut State<L, N>);
}

/// The paper's body: Euler angles whose rates are the body rates p, q, r.
#[derive(Clone, Copy, Debug)]
pub struct Paper;

impl BodyKind for Paper {
    const MODEL: BodyModel = BodyModel::Paper;
    const POSITIONS: &'static [StateVar] = &VEHICLE_POSITIONS;
    const VELOCITIES: &'static [StateVar] = &VEHICLE_VELOCITIES;
    const DERIVED: &'static [&'static str] = &[];
    const DEPENDENT: Option<usize> = None;
    type Frame<L: Lane> = Trig<L>;

    #[inline(always)]
    fn frame<L: Lane, const N: usize>(s: &State<L, N>) -> Trig<L> {
        Trig::of(s)
    }

    #[inline(always)]
    fn advanced<L: KernelOps, const N: usize>(
        f: &Trig<L>,
        k: &State<L, N>,
        h: f64,
        at: &State<L, N>,
    ) -> Trig<L> {
        f.advanced(k, h, at)
    }

    /// The angles move with the rates.
    #[inline(always)]
    fn attitude_rates<L: Lane, const N: usize>(s: &State<L, N>, lay: Layout, ds: &mut State<L, N>) {
        for i in 0..3 {
            ds[ix::PHI + i] = s[lay.rate() + i];
        }
    }

    #[inline(always)]
    fn euler<L: Lane, const N: usize>(s: &State<L, N>, _f: &Trig<L>) -> [L; 3] {
        [s[ix::PHI], s[ix::THETA], s[ix::PSI]]
    }

    #[inline(always)]
    fn trig<L: Lane>(f: &Trig<L>, _euler: &[L; 3]) -> Trig<L> {
        *f
    }

    fn set_attitude(s: &mut [f64], euler: [f64; 3]) {
        s[ix::PHI..ix::PHI + 3].copy_from_slice(&euler);
    }

    #[inline(always)]
    fn project<L: Lane, const N: usize>(_s: &mut State<L, N>) {}
}

/// The rigid body: a unit quaternion (qw, qx, qy, qz) and the body rates wx, wy, wz.
#[derive(Clone, Copy, Debug)]
pub struct Rigid;

/// Index of qw (then qx, qy, qz).
const QW: usize = ix::PHI;

impl Rigid {
    #[inline(always)]
    fn quaternion<L: Lane, const N: usize>(s: &State<L, N>) -> [L; 4] {
        [s[QW], s[QW + 1], s[QW + 2], s[QW + 3]]
    }

    /// The unit quaternion of roll, pitch, yaw (ZYX): q = qz(psi) qy(theta) qx(phi).
    pub fn quaternion_of_euler(euler: [f64; 3]) -> [f64; 4] {
        let (sr, cr) = (euler[0] * 0.5).sin_cos();
        let (sp, cp) = (euler[1] * 0.5).sin_cos();
        let (sy, cy) = (euler[2] * 0.5).sin_cos();
        [
            cr * cp * cy + sr * sp * sy,
            sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy,
        ]
    }
}

impl BodyKind for Rigid {
    const MODEL: BodyModel = BodyModel::Rigid;
    const POSITIONS: &'static [StateVar] = &RIGID_POSITIONS;
    const VELOCITIES: &'static [StateVar] = &RIGID_VELOCITIES;
    const DERIVED: &'static [&'static str] = &["phi", "theta", "psi"];
    const DEPENDENT: Option<usize> = Some(QW);
    type Frame<L: Lane> = Rotation<L>;

    #[inline(always)]
    fn frame<L: Lane, const N: usize>(s: &State<L, N>) -> Rotation<L> {
        Rotation::of_quaternion(Self::quaternion(s))
    }

    #[inline(always)]
    fn advanced<L: KernelOps, const N: usize>(
        _f: &Rotation<L>,
        _k: &State<L, N>,
        _h: f64,
        at: &State<L, N>,
    ) -> Rotation<L> {
        Self::frame(at)
    }

    /// dq/dt = 1/2 q (0, w) with w in body axes (RotorPy's `quat_dot`: no penalty term; the
    /// quaternion is renormalised after each step, `project`).
    #[inline(always)]
    fn attitude_rates<L: Lane, const N: usize>(s: &State<L, N>, lay: Layout, ds: &mut State<L, N>) {
        let [qw, qx, qy, qz] = Self::quaternion(s);
        let r = lay.rate();
        let (wx, wy, wz) = (s[r] * 0.5, s[r + 1] * 0.5, s[r + 2] * 0.5);
        ds[QW] = -(qx * wx + qy * wy + qz * wz);
        ds[QW + 1] = qw * wx - qz * wy + qy * wz;
        ds[QW + 2] = qz * wx + qw * wy - qx * wz;
        ds[QW + 3] = -(qy * wx) + qx * wy + qw * wz;
    }

    #[inline(always)]
    fn euler<L: Lane, const N: usize>(_s: &State<L, N>, f: &Rotation<L>) -> [L; 3] {
        f.euler()
    }

    #[inline(always)]
    fn trig<L: Lane>(_f: &Rotation<L>, euler: &[L; 3]) -> Trig<L> {
        Trig::of_angles(euler[0], euler[1], euler[2])
    }

    fn set_attitude(s: &mut [f64], euler: [f64; 3]) {
        s[QW..QW + 4].copy_from_slice(&Self::quaternion_of_euler(euler));
    }

    /// qw = sqrt(1 - qx^2 - qy^2 - qz^2): the quaternion near the identity (the linearisation
    /// is about hover).
    fn complete<L: Lane>(s: &mut [L]) {
        let v = s[QW + 1] * s[QW + 1] + s[QW + 2] * s[QW + 2] + s[QW + 3] * s[QW + 3];
        s[QW] = (L::splat(1.0) - v).sqrt();
    }

    /// q / |q| (RotorPy renormalises after each step too).
    #[inline(always)]
    fn project<L: Lane, const N: usize>(s: &mut State<L, N>) {
        let q = Self::quaternion(s);
        let inv = L::splat(1.0) / (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
        for (i, c) in q.iter().enumerate() {
            s[QW + i] = *c * inv;
        }
    }
}

#[cfg(test)]
#[path = "body_tests.rs"]
mod tests;
