//! Sliding-mode cascade (paper eqs. 8-12): s = lambda e + edot, sat(s) = s / (|s| + gamma);
//! optionally (`integral`, off by default and in the paper) the integral sliding surface
//! s = lambda e + edot + k_i int e of the position channels, which holds the reference in a
//! steady disturbance (docs/model.md, "The SMC's integral sliding surface").

use super::ControlContext;
use super::{
    euler_control, euler_held, euler_step, position_errors, Control, Controller, ControllerKind,
    Due, EulerCascade, EulerHeld, Shared, Sight, HELD_OWN,
};
use crate::config::params::params;
use crate::lane::{gather, Lane, Masks, Param};
use crate::model::{Inputs, Rigid, Tick};
use crate::trajectory::Reference;

params! {
    /// `[controller.smc]`: the sliding-mode law's gains (x, y, z channels, then roll, pitch,
    /// yaw), every one >= 0, and its boundary layer.
    pub struct SmcGains {
        epsilon: [f64; 3] => "m/s^2 (x, y, z)", "SMC switching gains (x, y, z)", non_negative;
        lambda: [f64; 3] => "1/s", "SMC sliding-surface slopes (x, y, z)", non_negative;
        eta: [f64; 3] => "1/s", "SMC reaching gains (x, y, z)", non_negative;
        epsilon_attitude: [f64; 3] => "rad/s^2", "SMC switching gains (roll, pitch, yaw)", non_negative;
        lambda_attitude: [f64; 3] => "1/s", "SMC sliding-surface slopes (roll, pitch, yaw)", non_negative;
        eta_attitude: [f64; 3] => "1/s", "SMC reaching gains (roll, pitch, yaw)", non_negative;
        /// Boundary-layer width of sat(s) = s / (|s| + gamma), > 0.
        gamma: f64 => "m/s (x, y, z) or rad/s", "SMC boundary-layer width", positive;
        /// Integral sliding surface s = lambda e + edot + k_i int e (x, y, z; 0: none, the
        /// paper's law); k_i int e is limited to +/- g.
        #[serde(default)]
        integral: [f64; 3] => "1/s^2", "SMC integral sliding-surface gains (x, y, z)", non_negative;
    }
}

/// Gains `P = f64` (one vehicle) or a lane type (one vehicle per lane, `Smc::gather`).
#[derive(Clone, Debug)]
pub struct Smc<P = f64> {
    shared: Shared<P>,
    /// x, y, z channels, then roll, pitch, yaw.
    epsilon: [P; 3],
    lambda: [P; 3],
    eta: [P; 3],
    epsilon_attitude: [P; 3],
    lambda_attitude: [P; 3],
    eta_attitude: [P; 3],
    /// Boundary-layer width of sat(s) = s / (|s| + gamma).
    gamma: P,
    /// 1/s^2, the integral sliding surface's gains (x, y, z; 0: none).
    integral: [P; 3],
    /// s, the position loop's period (the integral's step).
    dt_position: P,
}

impl Controller for Smc {
    const LABEL: &'static str = "SMC";
    type Params = SmcGains;
    type At<L: Lane> = Smc<L>;

    fn new(k: &SmcGains, cfg: &ControlContext) -> Self {
        Self {
            shared: Shared::new(cfg),
            epsilon: k.epsilon,
            lambda: k.lambda,
            eta: k.eta,
            epsilon_attitude: k.epsilon_attitude,
            lambda_attitude: k.lambda_attitude,
            eta_attitude: k.eta_attitude,
            gamma: k.gamma,
            integral: k.integral,
            dt_position: cfg
                .controller
                .loop_periods(ControllerKind::Smc, cfg.integrator.dt)[0],
        }
    }

    fn gather<L: Lane>(each: &[&Smc]) -> Smc<L> {
        gather!(|l| each[l] => Smc {
            shared, epsilon, lambda, eta, epsilon_attitude, lambda_attitude, eta_attitude, gamma,
            integral, dt_position,
        })
    }

    fn integrators(&self) -> Vec<usize> {
        self.integral_channels().iter().map(|c| c.slot).collect()
    }
}

/// A position channel the integral sliding surface integrates the error of.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IntegralChannel {
    /// 0, 1, 2: x, y, z.
    pub axis: usize,
    /// The memory slot holding int e (m s).
    pub slot: usize,
    /// m s, the largest |int e| the surface uses: its term k_i int e is limited to +/- g.
    pub limit: f64,
}

impl Smc {
    /// The channels with an integral (k_i > 0), x to z. At an equilibrium each one's position
    /// error is zero (else its integral would move) and its integral within its limit.
    pub fn integral_channels(&self) -> Vec<IntegralChannel> {
        (0..3)
            .filter(|&i| self.integral[i] > 0.0)
            .map(|i| IntegralChannel {
                axis: i,
                slot: HELD_OWN + i,
                limit: self.shared.g / self.integral[i],
            })
            .collect()
    }
}

impl<P: Copy> Smc<P> {
    /// lambda edot + eta s + eps sat(s): the reaching law shared by every channel, on the
    /// surface s = lambda e + edot.
    #[inline(always)]
    fn reach<L: Lane>(&self, lambda: P, eta: P, eps: P, e: L, ed: L) -> L
    where
        P: Param<L>,
    {
        let l: L = lambda.get();
        self.reach_on(lambda, eta, eps, e * l + ed, ed)
    }

    /// The reaching law on the surface `s`.
    #[inline(always)]
    fn reach_on<L: Lane>(&self, lambda: P, eta: P, eps: P, s: L, ed: L) -> L
    where
        P: Param<L>,
    {
        let (lambda, eta, eps): (L, L, L) = (lambda.get(), eta.get(), eps.get());
        let sat = s / (s.abs() + self.gamma.get());
        ed * lambda + s * eta + sat * eps
    }

    /// A position channel's reaching law on the integral surface s = lambda e + edot + `held`.
    #[inline(always)]
    fn reach_integral<L: Lane>(&self, lambda: P, eta: P, eps: P, e: L, ed: L, held: L) -> L
    where
        P: Param<L>,
    {
        let l: L = lambda.get();
        self.reach_on(lambda, eta, eps, e * l + ed + held, ed)
    }

    /// The integral sliding surface's terms k_i int e (x, y, z), each limited to +/- g, from
    /// the integrals in `own`; then `own` advanced by e over the position loop's period, but
    /// not past the limit (no winding beyond what the term can use). With k_i = 0 the terms
    /// are zero and the paper's surface is unchanged.
    #[inline(always)]
    fn integral_terms<L: Masks>(&self, e: &[L; 3], own: &mut [L]) -> [L; 3]
    where
        P: Param<L>,
    {
        let (g, dt): (L, L) = (self.shared.g.get(), self.dt_position.get());
        let mut terms = [L::splat(0.0); 3];
        for i in 0..3 {
            let ki: L = self.integral[i].get();
            terms[i] = (own[i] * ki).clamp(-g, g);
            let next = own[i] + e[i] * dt;
            own[i] = L::select((next * ki).abs().cmp_le(g), next, own[i]);
        }
        terms
    }
}

euler_control!(Smc);

impl<P: Copy> EulerCascade<P> for Smc<P> {
    /// The position loop: the thrust and the commanded roll and pitch.
    #[inline(always)]
    fn position<L: Masks>(&self, seen: &Sight<L>, r: &Reference, own: &mut [L]) -> (L, L, L)
    where
        P: Param<L>,
    {
        let (s, trig) = (seen.rigid, seen.trig);
        let sh = &self.shared;
        let (cphi, cth, spsi, cpsi) = (trig.cphi, trig.cth, trig.spsi, trig.cpsi);
        let (e, ed) = position_errors(s, r);
        let ([lx, ly, lz], [hx, hy, hz], [ex, ey, ez]) = (self.lambda, self.eta, self.epsilon);
        let (g, mt): (L, L) = (sh.g.get(), sh.mt.get());
        let held = self.integral_terms(&e, own);

        let vz = self.reach_integral(lz, hz, ez, e[2], ed[2], held[2]);
        let u1 = (vz + r.acc[2] + g) * mt * sh.inv_tilt(cphi, cth);
        let u1 = sh.limit_thrust(u1);
        let m_u1 = sh.mass_over_thrust(u1);
        let ux = (self.reach_integral(lx, hx, ex, e[0], ed[0], held[0]) + r.acc[0]) * m_u1;
        let uy = (self.reach_integral(ly, hy, ey, e[1], ed[1], held[1]) + r.acc[1]) * m_u1;
        let (phi_d, theta_d) = sh.desired_attitude(ux, uy, spsi, cpsi);
        (u1, phi_d, theta_d)
    }

    /// The attitude loop: the torques toward the commanded roll and pitch and the reference's
    /// yaw.
    #[inline(always)]
    fn attitude<L: Lane>(&self, s: &Rigid<L>, phi_d: L, theta_d: L, r: &Reference) -> [L; 3]
    where
        P: Param<L>,
    {
        let sh = &self.shared;
        let [la0, la1, la2] = self.lambda_attitude;
        let [et0, et1, et2] = self.eta_attitude;
        let [ep0, ep1, ep2] = self.epsilon_attitude;
        let [ixx, iyy, izz] = sh.inertia;
        let (ixx, iyy, izz): (L, L, L) = (ixx.get(), iyy.get(), izz.get());
        let (p, q, rr) = (s.rate[0], s.rate[1], s.rate[2]);
        // Roll and pitch: desired rates and accelerations are zero (commanded by the outer loop).
        let v_phi = self.reach(la0, et0, ep0, phi_d - s.att[0], -p);
        let v_theta = self.reach(la1, et1, ep1, theta_d - s.att[1], -q);
        let v_psi = self.reach(
            la2,
            et2,
            ep2,
            L::splat(r.psi) - s.att[2],
            L::splat(r.psi_dot) - rr,
        ) + r.psi_ddot;
        [
            v_phi * ixx - q * rr * (iyy - izz),
            v_theta * iyy - p * rr * (izz - ixx),
            v_psi * izz - p * q * (ixx - iyy),
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::tests::paper;

    /// The paper's SMC with the integral gains `integral` 0.1 m below its reference at 2 m,
    /// climbing at 0.05 m/s, at rest otherwise; and the errors (e, edot) on z.
    fn below_its_reference(integral: [f64; 3]) -> (Smc, Rigid<f64>, Reference, f64) {
        let mut cfg = paper();
        cfg.controller.smc.integral = integral;
        let smc = Smc::new(&cfg.controller.smc, &cfg.control_context());
        let mut s = crate::control::tests::at_rest([0.0; 3], 0.0);
        s.pos[2] = 1.9;
        s.vel[2] = 0.05;
        let r = Reference {
            pos: [0.0, 0.0, 2.0],
            ..Reference::default()
        };
        (smc, s, r, cfg.vehicle.mass + cfg.payload.mass)
    }

    /// u1 = mt (v + g) of the z channel's reaching law on the surface s (e = 0.1, edot = -0.05).
    fn thrust_by_hand(surface: f64, mt: f64) -> f64 {
        let ed = -0.05;
        let v = 1.8 * surface / (surface.abs() + 0.2) + 0.4 * surface + 3.2 * ed;
        mt * (v + 9.81)
    }

    #[test]
    fn sliding_surface_law_by_hand() {
        let (smc, s, r, mt) = below_its_reference([0.0; 3]);
        let u = smc.control(&s, &r, Tick::START);
        assert!((u.u1 - thrust_by_hand(3.2 * 0.1 - 0.05, mt)).abs() < 1e-12);
    }

    /// The integral surface s = lambda e + edot + k_i int e by hand, the integral advanced by
    /// e over the position loop's period; with k_i = 0 the paper's surface.
    #[test]
    fn integral_surface_law_by_hand() {
        let (smc, s, r, mt) = below_its_reference([0.0, 0.0, 2.0]);
        let trig = crate::model::Trig::of_angles(0.0, 0.0, 0.0);
        let seen = Sight::blind(&s, &trig);
        let mut mem = smc.memory(&seen);
        mem[HELD_OWN + 2] = 0.25;
        let u = smc.step(&seen, &r, Tick::START, Due::ALL, &mut mem);
        let e = 0.1;
        assert!((u.u1 - thrust_by_hand(3.2 * e - 0.05 + 2.0 * 0.25, mt)).abs() < 1e-12);
        assert!((mem[HELD_OWN + 2] - (0.25 + e * smc.dt_position)).abs() < 1e-15);
        assert_eq!(smc.integrators(), vec![HELD_OWN + 2]);
        let channel = IntegralChannel {
            axis: 2,
            slot: HELD_OWN + 2,
            limit: 9.81 / 2.0,
        };
        assert_eq!(smc.integral_channels(), vec![channel]);
        // Its term stops winding at g.
        mem[HELD_OWN + 2] = 9.81 / 2.0;
        smc.step(&seen, &r, Tick::START, Due::ALL, &mut mem);
        assert_eq!(mem[HELD_OWN + 2], 9.81 / 2.0);
    }
}
