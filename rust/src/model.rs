//! The plant: quadrotor plus a payload on a vertical spring (docs/model.md section 1).
//!
//! State `s = [x, y, z, phi, theta, psi, zc, vx, vy, vz, p, q, r, vzc]`, z up; `p, q, r` are
//! the Euler-angle rates (the paper's near-hover form).

use crate::config::Config;
use crate::lane::{KernelOps, Lane, Param};

pub const NX: usize = 14;
pub type State<L> = [L; NX];

/// `[f(0), f(1), ..., f(NX - 1)]`, always inlined. (`std::array::from_fn` is not guaranteed to
/// be, and an out-of-line copy would be compiled without the flight loop's target features:
/// see `lane.rs`.)
#[inline(always)]
pub fn state_from_fn<L>(mut f: impl FnMut(usize) -> L) -> State<L> {
    [
        f(0),
        f(1),
        f(2),
        f(3),
        f(4),
        f(5),
        f(6),
        f(7),
        f(8),
        f(9),
        f(10),
        f(11),
        f(12),
        f(13),
    ]
}

/// Indices into the state, so the physics reads like the equations.
pub mod ix {
    pub const X: usize = 0;
    pub const Y: usize = 1;
    pub const Z: usize = 2;
    pub const PHI: usize = 3;
    pub const THETA: usize = 4;
    pub const PSI: usize = 5;
    pub const ZC: usize = 6;
    pub const VX: usize = 7;
    pub const VY: usize = 8;
    pub const VZ: usize = 9;
    pub const P: usize = 10;
    pub const Q: usize = 11;
    pub const R: usize = 12;
    pub const VZC: usize = 13;
}

pub const STATE_NAMES: [&str; NX] = [
    "x", "y", "z", "phi", "theta", "psi", "zc", "vx", "vy", "vz", "p", "q", "r", "vzc",
];

/// Total thrust and body torques, held over one step.
#[derive(Clone, Copy, Debug)]
pub struct Inputs<L> {
    pub u1: L,
    pub tau: [L; 3],
}

/// Plant parameters, resolved once from the scenario (plant inertia = nominal + error).
/// `P = f64` is one vehicle; `P` a lane type carries one vehicle per lane (`Plant::gather`).
#[derive(Clone, Debug)]
pub struct Plant<P = f64> {
    pub m: P,
    pub mc: P,
    pub g: P,
    pub kc: P,
    pub cc: P,
    /// Plant inertia I + dI.
    pub inertia: [P; 3],
    /// 1/2 rho CdA for the quadrotor (vertical), payload (vertical) and the pair (horizontal).
    pub drag_quad: P,
    pub drag_payload: P,
    pub drag_lateral: P,
    /// Reciprocals, computed once: the derivative multiplies by them.
    inv_m_lateral: P,
    inv_m: P,
    inv_mc: P,
    inv_inertia: [P; 3],
}

/// Sines and cosines of the Euler angles of one state: computed once per RK4 stage and shared
/// by the controller and the first stage of the step.
#[derive(Clone, Copy, Debug)]
pub struct Trig<L> {
    pub sphi: L,
    pub cphi: L,
    pub sth: L,
    pub cth: L,
    pub spsi: L,
    pub cpsi: L,
}

impl<L: Lane> Trig<L> {
    #[inline(always)]
    pub fn of(s: &State<L>) -> Self {
        let (sphi, cphi) = s[ix::PHI].sin_cos();
        let (sth, cth) = s[ix::THETA].sin_cos();
        let (spsi, cpsi) = s[ix::PSI].sin_cos();
        Self {
            sphi,
            cphi,
            sth,
            cth,
            spsi,
            cpsi,
        }
    }
}

/// Turns of at most this (rad) within one RK4 stage take the angle-addition path of
/// `Trig::advanced`; its series are then exact to well below an ulp (the first omitted terms
/// are d^9/9! and d^10/10!, under 2e-18 relative at 0.03 rad).
pub const SMALL_TURN: f64 = 0.03;

/// (sin d, cos d) for |d| <= SMALL_TURN: Taylor series to d^7 and d^8.
#[inline(always)]
fn sin_cos_small<L: Lane>(d: L) -> (L, L) {
    let d2 = d * d;
    let s = d + d * d2 * ((d2 * (-1.0 / 5040.0) + 1.0 / 120.0) * d2 + (-1.0 / 6.0));
    let c = (((d2 * (1.0 / 40320.0) + (-1.0 / 720.0)) * d2 + 1.0 / 24.0) * d2 + (-0.5)) * d2 + 1.0;
    (s, c)
}

impl<L: KernelOps> Trig<L> {
    /// The sines and cosines at the angles `angle + k[angle] h` (an RK4 stage state `at`),
    /// from those at `angle` (`self`) by the angle-addition formulas: a few multiplications
    /// instead of three full sin/cos. A lane whose turn |k h| exceeds `SMALL_TURN` (never in
    /// the paper preset: that is 150 rad/s at dt = 2e-4 s) gets the full kernels at `at`
    /// instead; the choice is per lane, so a lane's numbers never depend on its neighbours.
    #[inline(always)]
    pub fn advanced(&self, k: &State<L>, h: f64, at: &State<L>) -> Self {
        let small = L::splat(SMALL_TURN);
        #[inline(always)]
        fn turn<L: KernelOps>(s0: L, c0: L, d: L) -> (L, L) {
            let (sd, cd) = sin_cos_small(d);
            (s0 * cd + c0 * sd, c0 * cd - s0 * sd)
        }
        let (dphi, dth, dpsi) = (k[ix::PHI] * h, k[ix::THETA] * h, k[ix::PSI] * h);
        let (sphi, cphi) = turn(self.sphi, self.cphi, dphi);
        let (sth, cth) = turn(self.sth, self.cth, dth);
        let (spsi, cpsi) = turn(self.spsi, self.cpsi, dpsi);
        let t = Self {
            sphi,
            cphi,
            sth,
            cth,
            spsi,
            cpsi,
        };
        let ok = dphi.abs().le_mask(small) & dth.abs().le_mask(small) & dpsi.abs().le_mask(small);
        if ok == L::ALL {
            return t;
        }
        let full = Self::of(at);
        let pick = |d: L, a: L, b: L| L::select(d.abs().cmp_le(small), a, b);
        Self {
            sphi: pick(dphi, t.sphi, full.sphi),
            cphi: pick(dphi, t.cphi, full.cphi),
            sth: pick(dth, t.sth, full.sth),
            cth: pick(dth, t.cth, full.cth),
            spsi: pick(dpsi, t.spsi, full.spsi),
            cpsi: pick(dpsi, t.cpsi, full.cpsi),
        }
    }
}

impl Plant {
    pub fn new(cfg: &Config) -> Self {
        let half_rho = 0.5 * cfg.gust.air_density;
        let v = &cfg.vehicle;
        let inertia = [
            v.inertia[0] + v.inertia_error[0],
            v.inertia[1] + v.inertia_error[1],
            v.inertia[2] + v.inertia_error[2],
        ];
        Self {
            m: v.mass,
            mc: cfg.payload.mass,
            g: cfg.environment.gravity,
            kc: cfg.stiffness(),
            cc: cfg.payload.damping,
            inertia,
            drag_quad: half_rho * v.drag_area,
            drag_payload: half_rho * cfg.payload.drag_area,
            drag_lateral: half_rho * v.lateral_drag_area,
            inv_m_lateral: 1.0 / (v.mass + cfg.payload.mass),
            inv_m: 1.0 / v.mass,
            inv_mc: 1.0 / cfg.payload.mass,
            inv_inertia: inertia.map(|i| 1.0 / i),
        }
    }

    /// Static stretch of the spring at hover: the payload hangs d0 = mc g / kc below.
    pub fn hover_offset(&self) -> f64 {
        self.mc * self.g / self.kc
    }

    /// One vehicle per lane: lane `l` of every parameter is `each[l]`'s (built once per flight,
    /// outside the loop).
    pub fn gather<L: Lane>(each: &[&Plant]) -> Plant<L> {
        let at = |f: fn(&Plant) -> f64| L::from_fn(|l| f(each[l]));
        let at3 = |f: fn(&Plant) -> [f64; 3]| -> [L; 3] {
            [0, 1, 2].map(|i| L::from_fn(|l| f(each[l])[i]))
        };
        Plant {
            m: at(|p| p.m),
            mc: at(|p| p.mc),
            g: at(|p| p.g),
            kc: at(|p| p.kc),
            cc: at(|p| p.cc),
            inertia: at3(|p| p.inertia),
            drag_quad: at(|p| p.drag_quad),
            drag_payload: at(|p| p.drag_payload),
            drag_lateral: at(|p| p.drag_lateral),
            inv_m_lateral: at(|p| p.inv_m_lateral),
            inv_m: at(|p| p.inv_m),
            inv_mc: at(|p| p.inv_mc),
            inv_inertia: at3(|p| p.inv_inertia),
        }
    }

    /// Relative oscillation e_o = (zc - z) + d0: the payload's displacement from its hover
    /// equilibrium relative to the quadrotor.
    #[inline(always)]
    pub fn relative_oscillation<L: Lane>(&self, s: &State<L>) -> L {
        s[ix::ZC] - s[ix::Z] + self.hover_offset()
    }

    /// A state at rest at `position` and `attitude`, payload at its hover equilibrium.
    pub fn rest_state(&self, position: [f64; 3], attitude: [f64; 3]) -> State<f64> {
        let mut s = [0.0; NX];
        s[ix::X] = position[0];
        s[ix::Y] = position[1];
        s[ix::Z] = position[2];
        s[ix::PHI] = attitude[0];
        s[ix::THETA] = attitude[1];
        s[ix::PSI] = attitude[2];
        s[ix::ZC] = position[2] - self.hover_offset();
        s
    }
}

/// Drag force on a body of `k` = 1/2 rho CdA moving at `v` in wind `wind` (one axis).
#[inline(always)]
fn drag<L: Lane>(k: L, v: L, wind: L) -> L {
    let rel = v - wind;
    rel * rel.abs() * (-k)
}

impl<P: Copy> Plant<P> {
    /// Spring and damper force Fs = kc (z - zc) + cc (vz - vzc) (N, pulls the payload up).
    #[inline(always)]
    fn spring_force<L: Lane>(&self, s: &State<L>) -> L
    where
        P: Param<L>,
    {
        (s[ix::Z] - s[ix::ZC]).mul_add(self.kc.get(), (s[ix::VZ] - s[ix::VZC]) * self.cc.get())
    }

    /// The payload's vertical inertial acceleration d2zc/dt2 (m/s^2) at state `s` with vertical
    /// wind `wind_z` (m/s): its equation of motion, mc azc = -mc g + Fs + Fdzc (docs/model.md
    /// section 1), the very expression the derivative uses; zero at hover.
    #[inline(always)]
    pub fn payload_acceleration<L: Lane>(&self, s: &State<L>, wind_z: L) -> L
    where
        P: Param<L>,
    {
        self.payload_acceleration_with(s, self.spring_force(s), wind_z)
    }

    #[inline(always)]
    fn payload_acceleration_with<L: Lane>(&self, s: &State<L>, spring: L, wind_z: L) -> L
    where
        P: Param<L>,
    {
        let fdzc = drag(self.drag_payload.get(), s[ix::VZC], wind_z);
        (spring + fdzc) * self.inv_mc.get() - self.g.get()
    }

    /// The vertical drag force on the quadrotor (N) at state `s` in vertical wind `wind_z`
    /// (m/s): Fdz = -1/2 rho CdA (vz - wind_z) |vz - wind_z| (docs/model.md section 1), the
    /// very term the derivative uses (and the trace's `drag_z`).
    #[inline(always)]
    pub fn vertical_drag<L: Lane>(&self, s: &State<L>, wind_z: L) -> L
    where
        P: Param<L>,
    {
        drag(self.drag_quad.get(), s[ix::VZ], wind_z)
    }

    /// ds/dt for inputs `u` and wind `w` (m/s, inertial), both held over the step.
    #[inline(always)]
    pub fn derivative<L: Lane>(&self, s: &State<L>, u: &Inputs<L>, w: &[L; 3]) -> State<L>
    where
        P: Param<L>,
    {
        self.derivative_with(s, &Trig::of(s), u, w)
    }

    /// `derivative` with the sines and cosines of `s`'s angles already at hand.
    #[inline(always)]
    pub fn derivative_with<L: Lane>(
        &self,
        s: &State<L>,
        trig: &Trig<L>,
        u: &Inputs<L>,
        w: &[L; 3],
    ) -> State<L>
    where
        P: Param<L>,
    {
        use ix::*;
        let Trig {
            sphi,
            cphi,
            sth,
            cth,
            spsi,
            cpsi,
        } = *trig;

        let drag_lateral: L = self.drag_lateral.get();
        let fdx = drag(drag_lateral, s[VX], w[0]);
        let fdy = drag(drag_lateral, s[VY], w[1]);
        let fdz = self.vertical_drag(s, w[2]);
        let spring = self.spring_force(s);

        let (inv_m_lateral, g): (L, L) = (self.inv_m_lateral.get(), self.g.get());
        // Products-plus-sums as `mul_add`: the same bits as `a * b + c` except in the fused
        // mode (`Lane::mul_add`); `a - b c` is `(-b) c + a`, exactly.
        let cs = cphi * sth;
        let ax = cs.mul_add(cpsi, spsi * sphi).mul_add(u.u1, fdx) * inv_m_lateral;
        let ay = cs.mul_add(spsi, -(sphi * cpsi)).mul_add(u.u1, fdy) * inv_m_lateral;
        let az = (cphi * cth).mul_add(u.u1, -spring) + fdz;
        let az = az * self.inv_m.get() - g;
        let azc = self.payload_acceleration_with(s, spring, w[2]);

        // Destructured, not `array::map`: everything here must inline into the flight loop.
        let [ixx, iyy, izz] = self.inertia;
        let (ixx, iyy, izz): (L, L, L) = (ixx.get(), iyy.get(), izz.get());
        let [inv_ixx, inv_iyy, inv_izz] = self.inv_inertia;
        let (inv_ixx, inv_iyy, inv_izz): (L, L, L) = (inv_ixx.get(), inv_iyy.get(), inv_izz.get());
        let pdot = (s[Q] * s[R]).mul_add(iyy - izz, u.tau[0]) * inv_ixx;
        let qdot = (s[P] * s[R]).mul_add(izz - ixx, u.tau[1]) * inv_iyy;
        let rdot = (s[P] * s[Q]).mul_add(ixx - iyy, u.tau[2]) * inv_izz;

        [
            s[VX], s[VY], s[VZ], s[P], s[Q], s[R], s[VZC], ax, ay, az, pdot, qdot, rdot, azc,
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::tests::paper;

    #[test]
    fn hover_is_an_equilibrium_of_the_plant() {
        let plant = Plant::new(&paper());
        let s = plant.rest_state([1.0, -2.0, 2.0], [0.0, 0.0, 0.5]);
        let u = Inputs {
            u1: (plant.m + plant.mc) * plant.g,
            tau: [0.0; 3],
        };
        let ds = plant.derivative(&s, &u, &[0.0; 3]);
        for (i, d) in ds.iter().enumerate() {
            assert!(d.abs() < 1e-12, "d{}/dt = {d}", STATE_NAMES[i]);
        }
    }

    #[test]
    fn payload_acceleration_is_the_derivative_of_vzc() {
        let plant = Plant::new(&paper());
        let mut s = plant.rest_state([0.0, 0.0, 2.0], [0.0; 3]);
        let u = Inputs {
            u1: (plant.m + plant.mc) * plant.g,
            tau: [0.0; 3],
        };
        assert!(
            plant.payload_acceleration(&s, 0.0).abs() < 1e-12,
            "zero at hover"
        );
        s[ix::ZC] -= 0.03;
        s[ix::VZ] = 0.4;
        s[ix::VZC] = -0.7;
        for wz in [0.0, 1.3, -2.0] {
            let ds = plant.derivative(&s, &u, &[0.0, 0.0, wz]);
            let a = plant.payload_acceleration(&s, wz);
            assert_eq!(a.to_bits(), ds[ix::VZC].to_bits(), "wind {wz}");
        }
    }

    #[test]
    fn drag_opposes_relative_velocity() {
        let plant = Plant::new(&paper());
        let s = plant.rest_state([0.0; 3], [0.0; 3]);
        let u = Inputs {
            u1: (plant.m + plant.mc) * plant.g,
            tau: [0.0; 3],
        };
        // An updraft of 1 m/s pushes both bodies up by 1/2 rho CdA (1 m/s)^2.
        let ds = plant.derivative(&s, &u, &[0.0, 0.0, 1.0]);
        assert!((ds[ix::VZ] - plant.drag_quad / plant.m).abs() < 1e-12);
        assert!((ds[ix::VZC] - plant.drag_payload / plant.mc).abs() < 1e-12);
        let ds = plant.derivative(&s, &u, &[2.0, 0.0, 0.0]);
        assert!((ds[ix::VX] - 4.0 * plant.drag_lateral / (plant.m + plant.mc)).abs() < 1e-12);
    }

    /// Trig at a stage state by angle addition agrees with direct sin/cos to about an ulp, for
    /// small turns and at the series' limit; larger turns fall back to the kernels, per lane.
    #[test]
    fn advanced_trig_matches_direct_evaluation() {
        use crate::lane::F64x4;
        let angles = [0.0, 0.3, -1.2, 2.9, 1.0e3, -7.0];
        let turns = [
            0.0,
            1e-9,
            -2e-5,
            0.01,
            -SMALL_TURN,
            SMALL_TURN * 0.999,
            0.2,
            -3.0,
        ];
        let h = 1e-3;
        for &a in &angles {
            for &d in &turns {
                let mut s = [0.0; NX];
                let mut k = [0.0; NX];
                for (i, ang) in [ix::PHI, ix::THETA, ix::PSI].into_iter().enumerate() {
                    s[ang] = a + 0.1 * i as f64;
                    k[ang] = d / h * (1.0 + 0.5 * i as f64);
                }
                let at: State<f64> = state_from_fn(|i| s[i] + k[i] * h);
                let got = Trig::of(&s).advanced(&k, h, &at);
                let want = Trig::of(&at);
                let err = [
                    got.sphi - want.sphi,
                    got.cphi - want.cphi,
                    got.sth - want.sth,
                    got.cth - want.cth,
                    got.spsi - want.spsi,
                    got.cpsi - want.cpsi,
                ];
                // Angle addition evaluates at s + k h exactly, `want` at its rounded value:
                // they differ by rounding, up to a few ulp of the angle for |a| = 1000.
                let tol = 4.0 * f64::EPSILON * (1.0 + a.abs());
                assert!(err.iter().all(|e| e.abs() <= tol), "a {a} d {d}: {err:?}");
            }
        }
        // Per lane: a lane that turns too far takes the kernels; its neighbours keep the series.
        let s: State<F64x4> = state_from_fn(|_| F64x4::splat(0.4));
        let mut k: State<F64x4> = state_from_fn(|_| F64x4::splat(1e-3 / h));
        k[ix::PSI] = F64x4::from_fn(|i| if i == 2 { 0.5 / h } else { 1e-3 / h });
        let at = state_from_fn(|i| s[i] + k[i] * h);
        let got = Trig::of(&s).advanced(&k, h, &at);
        let alone = Trig::of(&s.map(|x| x.lane(0))).advanced(
            &k.map(|x| x.lane(0)),
            h,
            &at.map(|x| x.lane(0)),
        );
        assert_eq!(got.spsi.lane(0).to_bits(), alone.spsi.to_bits());
        assert_eq!(
            got.spsi.lane(2).to_bits(),
            Trig::of(&at).spsi.lane(2).to_bits()
        );
    }
}
