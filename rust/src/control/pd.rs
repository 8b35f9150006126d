//! PD cascade (paper eqs. 4-7).

use super::{position_errors, Control, Shared};
use crate::config::{Config, PdGains};
use crate::lane::Lane;
use crate::model::{ix, Inputs, State, Trig};
use crate::trajectory::Reference;

#[derive(Clone, Debug)]
pub struct Pd {
    shared: Shared,
    gains: PdGains,
}

impl Pd {
    pub fn new(cfg: &Config) -> Self {
        Self {
            shared: Shared::new(cfg),
            gains: cfg.controller.pd.clone(),
        }
    }
}

impl Control for Pd {
    #[inline(always)]
    fn control_with<L: Lane>(&self, s: &State<L>, trig: &Trig<L>, r: &Reference) -> Inputs<L> {
        let (sh, k) = (&self.shared, &self.gains);
        let (cphi, cth, spsi, cpsi) = (trig.cphi, trig.cth, trig.spsi, trig.cpsi);
        let (e, ed) = position_errors(s, r);

        let u1 = (e[2] * k.kp[2] + ed[2] * k.kd[2] + sh.g) * sh.mt * sh.inv_tilt(cphi, cth);
        let u1 = sh.limit_thrust(u1);
        let m_u1 = sh.mass_over_thrust(u1);
        let ux = (e[0] * k.kp[0] + ed[0] * k.kd[0]) * m_u1;
        let uy = (e[1] * k.kp[1] + ed[1] * k.kd[1]) * m_u1;
        let (phi_d, theta_d) = sh.desired_attitude(ux, uy, spsi, cpsi);

        let kp = k.kp_attitude;
        let kd = k.kd_attitude;
        let tau = [
            (phi_d - s[ix::PHI]) * kp[0] - s[ix::P] * kd[0],
            (theta_d - s[ix::THETA]) * kp[1] - s[ix::Q] * kd[1],
            (L::splat(r.psi) - s[ix::PSI]) * kp[2] + (L::splat(r.psi_dot) - s[ix::R]) * kd[2],
        ];
        Inputs { u1, tau }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::tests::paper;

    #[test]
    fn altitude_error_raises_thrust_by_kp() {
        let cfg = paper();
        let pd = Pd::new(&cfg);
        let mut s = [0.0; crate::model::NX];
        s[ix::Z] = 1.9;
        let r = Reference {
            pos: [0.0, 0.0, 2.0],
            ..Reference::default()
        };
        let u = pd.control(&s, &r);
        let mt = cfg.vehicle.mass + cfg.payload.mass;
        assert!((u.u1 - mt * (9.81 + 1.5 * 0.1)).abs() < 1e-12);
    }
}
