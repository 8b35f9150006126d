//! Sliding-mode cascade (paper eqs. 8-12): s = lambda e + edot, sat(s) = s / (|s| + gamma).

use super::ControlContext;
use super::{
    euler_control, euler_held, euler_step, position_errors, Control, Controller, Due, EulerCascade,
    EulerHeld, Shared, Sight,
};
use crate::config::params::{params, Params};
use crate::config::ConfigError;
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
}

impl Controller for Smc {
    const LABEL: &'static str = "SMC";
    type Params = SmcGains;
    type At<L: Lane> = Smc<L>;

    fn validate(k: &SmcGains, key: &str, _cfg: &ControlContext) -> Result<(), ConfigError> {
        k.check_bounds(key)
    }

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
        }
    }

    fn gather<L: Lane>(each: &[&Smc]) -> Smc<L> {
        gather!(|l| each[l] => Smc {
            shared, epsilon, lambda, eta, epsilon_attitude, lambda_attitude, eta_attitude, gamma,
        })
    }
}

impl<P: Copy> Smc<P> {
    /// lambda edot + eta s + eps sat(s): the reaching law shared by every channel.
    #[inline(always)]
    fn reach<L: Lane>(&self, lambda: P, eta: P, eps: P, e: L, ed: L) -> L
    where
        P: Param<L>,
    {
        let (lambda, eta, eps): (L, L, L) = (lambda.get(), eta.get(), eps.get());
        let s = e * lambda + ed;
        let sat = s / (s.abs() + self.gamma.get());
        ed * lambda + s * eta + sat * eps
    }
}

euler_control!(Smc);

impl<P: Copy> EulerCascade<P> for Smc<P> {
    /// The position loop: the thrust and the commanded roll and pitch.
    #[inline(always)]
    fn position<L: Lane>(&self, seen: &Sight<L>, r: &Reference) -> (L, L, L)
    where
        P: Param<L>,
    {
        let (s, trig) = (seen.rigid, seen.trig);
        let sh = &self.shared;
        let (cphi, cth, spsi, cpsi) = (trig.cphi, trig.cth, trig.spsi, trig.cpsi);
        let (e, ed) = position_errors(s, r);
        let ([lx, ly, lz], [hx, hy, hz], [ex, ey, ez]) = (self.lambda, self.eta, self.epsilon);
        let (g, mt): (L, L) = (sh.g.get(), sh.mt.get());

        let vz = self.reach(lz, hz, ez, e[2], ed[2]);
        let u1 = (vz + r.acc[2] + g) * mt * sh.inv_tilt(cphi, cth);
        let u1 = sh.limit_thrust(u1);
        let m_u1 = sh.mass_over_thrust(u1);
        let ux = (self.reach(lx, hx, ex, e[0], ed[0]) + r.acc[0]) * m_u1;
        let uy = (self.reach(ly, hy, ey, e[1], ed[1]) + r.acc[1]) * m_u1;
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

    #[test]
    fn sliding_surface_law_by_hand() {
        let cfg = paper();
        let smc = Smc::new(&cfg.controller.smc, &cfg.control_context());
        let mut s = crate::control::tests::at_rest([0.0; 3], 0.0);
        s.pos[2] = 1.9;
        s.vel[2] = 0.05;
        let r = Reference {
            pos: [0.0, 0.0, 2.0],
            ..Reference::default()
        };
        let u = smc.control(&s, &r, Tick::START);
        let (e, ed) = (0.1, -0.05);
        let sz = 3.2 * e + ed;
        let v = 1.8 * sz / (sz.abs() + 0.2) + 0.4 * sz + 3.2 * ed;
        let mt = cfg.vehicle.mass + cfg.payload.mass;
        assert!((u.u1 - mt * (v + 9.81)).abs() < 1e-12);
    }
}
