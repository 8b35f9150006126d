//! Sliding-mode cascade (paper eqs. 8-12): s = lambda e + edot, sat(s) = s / (|s| + gamma).

use super::{position_errors, Control, Shared};
use crate::config::{Config, SmcGains};
use crate::lane::Lane;
use crate::model::{ix, Inputs, State, Trig};
use crate::trajectory::Reference;

#[derive(Clone, Debug)]
pub struct Smc {
    shared: Shared,
    gains: SmcGains,
}

impl Smc {
    pub fn new(cfg: &Config) -> Self {
        Self {
            shared: Shared::new(cfg),
            gains: cfg.controller.smc.clone(),
        }
    }

    /// lambda edot + eta s + eps sat(s): the reaching law shared by every channel.
    #[inline(always)]
    fn reach<L: Lane>(&self, lambda: f64, eta: f64, eps: f64, e: L, ed: L) -> L {
        let s = e * lambda + ed;
        let sat = s / (s.abs() + self.gains.gamma);
        ed * lambda + s * eta + sat * eps
    }
}

impl Control for Smc {
    #[inline(always)]
    fn control_with<L: Lane>(&self, s: &State<L>, trig: &Trig<L>, r: &Reference) -> Inputs<L> {
        let (sh, k) = (&self.shared, &self.gains);
        let (cphi, cth, spsi, cpsi) = (trig.cphi, trig.cth, trig.spsi, trig.cpsi);
        let (e, ed) = position_errors(s, r);

        let vz = self.reach(k.lambda[2], k.eta[2], k.epsilon[2], e[2], ed[2]);
        let u1 = (vz + r.acc[2] + sh.g) * sh.mt * sh.inv_tilt(cphi, cth);
        let u1 = sh.limit_thrust(u1);
        let m_u1 = sh.mass_over_thrust(u1);
        let ux = (self.reach(k.lambda[0], k.eta[0], k.epsilon[0], e[0], ed[0]) + r.acc[0]) * m_u1;
        let uy = (self.reach(k.lambda[1], k.eta[1], k.epsilon[1], e[1], ed[1]) + r.acc[1]) * m_u1;
        let (phi_d, theta_d) = sh.desired_attitude(ux, uy, spsi, cpsi);

        let (la, et, ep) = (k.lambda_attitude, k.eta_attitude, k.epsilon_attitude);
        let [ixx, iyy, izz] = sh.inertia;
        let (p, q, rr) = (s[ix::P], s[ix::Q], s[ix::R]);
        // Roll and pitch: desired rates and accelerations are zero (commanded by the outer loop).
        let v_phi = self.reach(la[0], et[0], ep[0], phi_d - s[ix::PHI], -p);
        let v_theta = self.reach(la[1], et[1], ep[1], theta_d - s[ix::THETA], -q);
        let v_psi = self.reach(
            la[2],
            et[2],
            ep[2],
            L::splat(r.psi) - s[ix::PSI],
            L::splat(r.psi_dot) - rr,
        ) + r.psi_ddot;
        let tau = [
            v_phi * ixx - q * rr * (iyy - izz),
            v_theta * iyy - p * rr * (izz - ixx),
            v_psi * izz - p * q * (ixx - iyy),
        ];
        Inputs { u1, tau }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::tests::paper;

    #[test]
    fn sliding_surface_law_by_hand() {
        let cfg = paper();
        let smc = Smc::new(&cfg);
        let mut s = [0.0; crate::model::NX];
        s[ix::Z] = 1.9;
        s[ix::VZ] = 0.05;
        let r = Reference {
            pos: [0.0, 0.0, 2.0],
            ..Reference::default()
        };
        let u = smc.control(&s, &r);
        let (e, ed) = (0.1, -0.05);
        let sz = 3.2 * e + ed;
        let v = 1.8 * sz / (sz.abs() + 0.2) + 0.4 * sz + 3.2 * ed;
        let mt = cfg.vehicle.mass + cfg.payload.mass;
        assert!((u.u1 - mt * (v + 9.81)).abs() < 1e-12);
    }
}
