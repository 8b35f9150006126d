//! PD cascade (paper eqs. 4-7).

use super::{non_negative3, position_errors, Control, Controller, Shared};
use crate::config::params::params;
use crate::config::{Config, ConfigError};
use crate::lane::{gather3, Lane, Param};
use crate::model::{Inputs, Rigid, Tick, Trig};
use crate::trajectory::Reference;

params! {
    /// `[controller.pd]`: the PD law's gains, every one >= 0.
    pub struct PdGains {
        /// x, y, z position gains.
        kp: [f64; 3] => "1/s^2", "PD position gains (x, y, z)";
        kd: [f64; 3] => "1/s", "PD velocity gains (x, y, z)";
        /// roll, pitch, yaw gains (torque per rad, per rad/s).
        kp_attitude: [f64; 3] => "N m/rad", "PD attitude gains (roll, pitch, yaw)";
        kd_attitude: [f64; 3] => "N m s/rad", "PD body-rate gains (roll, pitch, yaw)";
    }
}

/// Gains `P = f64` (one vehicle) or a lane type (one vehicle per lane, `Pd::gather`).
#[derive(Clone, Debug)]
pub struct Pd<P = f64> {
    shared: Shared<P>,
    /// x, y, z position gains; roll, pitch, yaw attitude gains.
    kp: [P; 3],
    kd: [P; 3],
    kp_attitude: [P; 3],
    kd_attitude: [P; 3],
}

impl Controller for Pd {
    type Params = PdGains;
    type At<L: Lane> = Pd<L>;

    fn validate(k: &PdGains, key: &str, _cfg: &Config) -> Result<(), ConfigError> {
        non_negative3(key, "kp", &k.kp)?;
        non_negative3(key, "kd", &k.kd)?;
        non_negative3(key, "kp_attitude", &k.kp_attitude)?;
        non_negative3(key, "kd_attitude", &k.kd_attitude)
    }

    fn new(k: &PdGains, cfg: &Config) -> Self {
        Self {
            shared: Shared::new(cfg),
            kp: k.kp,
            kd: k.kd,
            kp_attitude: k.kp_attitude,
            kd_attitude: k.kd_attitude,
        }
    }

    fn gather<L: Lane>(each: &[&Pd]) -> Pd<L> {
        let at3 = |f: fn(&Pd) -> [f64; 3]| -> [L; 3] { gather3(each, f) };
        let shared: Vec<&Shared> = each.iter().map(|p| &p.shared).collect();
        Pd {
            shared: Shared::gather(&shared),
            kp: at3(|p| p.kp),
            kd: at3(|p| p.kd),
            kp_attitude: at3(|p| p.kp_attitude),
            kd_attitude: at3(|p| p.kd_attitude),
        }
    }
}

impl<P: Copy + Sync> Control<P> for Pd<P> {
    #[inline(always)]
    fn control_with<L: Lane>(
        &self,
        s: &Rigid<L>,
        trig: &Trig<L>,
        r: &Reference,
        _at: Tick,
    ) -> Inputs<L>
    where
        P: Param<L>,
    {
        let sh = &self.shared;
        let (cphi, cth, spsi, cpsi) = (trig.cphi, trig.cth, trig.spsi, trig.cpsi);
        let (e, ed) = position_errors(s, r);
        let [kpx, kpy, kpz] = self.kp;
        let [kdx, kdy, kdz] = self.kd;
        let (g, mt): (L, L) = (sh.g.get(), sh.mt.get());

        let u1 = (e[2] * kpz.get() + ed[2] * kdz.get() + g) * mt * sh.inv_tilt(cphi, cth);
        let u1 = sh.limit_thrust(u1);
        let m_u1 = sh.mass_over_thrust(u1);
        let ux = (e[0] * kpx.get() + ed[0] * kdx.get()) * m_u1;
        let uy = (e[1] * kpy.get() + ed[1] * kdy.get()) * m_u1;
        let (phi_d, theta_d) = sh.desired_attitude(ux, uy, spsi, cpsi);

        let [kp0, kp1, kp2] = self.kp_attitude;
        let [kd0, kd1, kd2] = self.kd_attitude;
        let (kp0, kp1, kp2): (L, L, L) = (kp0.get(), kp1.get(), kp2.get());
        let (kd0, kd1, kd2): (L, L, L) = (kd0.get(), kd1.get(), kd2.get());
        let tau = [
            (phi_d - s.att[0]) * kp0 - s.rate[0] * kd0,
            (theta_d - s.att[1]) * kp1 - s.rate[1] * kd1,
            (L::splat(r.psi) - s.att[2]) * kp2 + (L::splat(r.psi_dot) - s.rate[2]) * kd2,
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
        let pd = Pd::new(&cfg.controller.pd, &cfg);
        let mut s = crate::control::tests::at_rest([0.0; 3], 0.0);
        s.pos[2] = 1.9;
        let r = Reference {
            pos: [0.0, 0.0, 2.0],
            ..Reference::default()
        };
        let u = pd.control(&s, &r, Tick::START);
        let mt = cfg.vehicle.mass + cfg.payload.mass;
        assert!((u.u1 - mt * (9.81 + 1.5 * 0.1)).abs() < 1e-12);
    }
}
