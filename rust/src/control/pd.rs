//! PD cascade (paper eqs. 4-7), with optional feedback of the parcel's swing (docs/model.md,
//! "The swing-damping PD").

use super::ControlContext;
use super::{
    euler_control, euler_held, euler_step, position_errors, Control, Controller, Due, EulerCascade,
    EulerHeld, Shared, Sight,
};
use crate::config::params::params;
use crate::lane::{gather, Lane, Masks, Param};
use crate::model::{Inputs, PayloadView, Rigid, Tick};
use crate::trajectory::Reference;

params! {
    /// `[controller.pd]`: the PD law's gains, every one >= 0.
    pub struct PdGains {
        /// x, y, z position gains.
        kp: [f64; 3] => "1/s^2", "PD position gains (x, y, z)", non_negative;
        kd: [f64; 3] => "1/s", "PD velocity gains (x, y, z)", non_negative;
        /// roll, pitch, yaw gains (torque per rad, per rad/s).
        kp_attitude: [f64; 3] => "N m/rad", "PD attitude gains (roll, pitch, yaw)", non_negative;
        kd_attitude: [f64; 3] => "N m s/rad", "PD body-rate gains (roll, pitch, yaw)", non_negative;
        /// Horizontal acceleration commanded per unit of the line's horizontal lean (the
        /// parcel's offset from below its attachment over the line's length: the swing angle's
        /// sine), toward the parcel; 0 (the default): off.
        #[serde(default)]
        swing_gain: f64 => "m/s^2", "PD swing-angle feedback", non_negative;
        /// Horizontal acceleration commanded per unit of the lean's rate (rad/s at small
        /// angles), toward where the parcel swings: damps the swing; 0 (the default): off.
        #[serde(default)]
        swing_damping: f64 => "m/s", "PD swing-rate feedback", non_negative;
    }
}

/// m, the least line length the swing feedback divides by (a parcel at its attachment, or off
/// the hook, leans nowhere).
const MIN_SWING_LENGTH: f64 = 1e-6;

/// Gains `P = f64` (one vehicle) or a lane type (one vehicle per lane, `Pd::gather`).
#[derive(Clone, Debug)]
pub struct Pd<P = f64> {
    shared: Shared<P>,
    /// x, y, z position gains; roll, pitch, yaw attitude gains.
    kp: [P; 3],
    kd: [P; 3],
    kp_attitude: [P; 3],
    kd_attitude: [P; 3],
    /// The swing feedback (`swing_gain`, `swing_damping`), and whether any lane flies it: if
    /// none, the law is the paper's, bit for bit.
    swing_gain: P,
    swing_damping: P,
    swing: bool,
}

impl Controller for Pd {
    const LABEL: &'static str = "PD";
    type Params = PdGains;
    type At<L: Lane> = Pd<L>;

    fn new(k: &PdGains, cfg: &ControlContext) -> Self {
        Self {
            shared: Shared::new(cfg),
            kp: k.kp,
            kd: k.kd,
            kp_attitude: k.kp_attitude,
            kd_attitude: k.kd_attitude,
            swing_gain: k.swing_gain,
            swing_damping: k.swing_damping,
            swing: k.swing_gain != 0.0 || k.swing_damping != 0.0,
        }
    }

    fn gather<L: Lane>(each: &[&Pd]) -> Pd<L> {
        gather!(|l| each[l] => Pd {
            shared, kp, kd, kp_attitude, kd_attitude, swing_gain, swing_damping;
            swing: each.iter().any(|p| p.swing),
        })
    }
}

euler_control!(Pd, sees: |law| law.swing);

impl<P: Copy> EulerCascade<P> for Pd<P> {
    /// The position loop: the thrust and the commanded roll and pitch, with the swing feedback
    /// where it is on and the payload is seen.
    #[inline(always)]
    fn position<L: Masks>(&self, seen: &Sight<L>, r: &Reference, _own: &mut [L]) -> (L, L, L)
    where
        P: Param<L>,
    {
        let (s, trig) = (seen.rigid, seen.trig);
        let sh = &self.shared;
        let (cphi, cth, spsi, cpsi) = (trig.cphi, trig.cth, trig.spsi, trig.cpsi);
        let (e, ed) = position_errors(s, r);
        let [kpx, kpy, kpz] = self.kp;
        let [kdx, kdy, kdz] = self.kd;
        let (g, mt): (L, L) = (sh.g.get(), sh.mt.get());

        let u1 = (e[2] * kpz.get() + ed[2] * kdz.get() + g) * mt * sh.inv_tilt(cphi, cth);
        let u1 = sh.limit_thrust(u1);
        let m_u1 = sh.mass_over_thrust(u1);
        // The commanded horizontal accelerations, and the swing's where it is fed back.
        let mut ax = e[0] * kpx.get() + ed[0] * kdx.get();
        let mut ay = e[1] * kpy.get() + ed[1] * kdy.get();
        if let (true, Some(payload)) = (self.swing, seen.payload) {
            let [sx, sy] = self.swing_acceleration(payload);
            ax += sx;
            ay += sy;
        }
        let ux = ax * m_u1;
        let uy = ay * m_u1;
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
        let [kp0, kp1, kp2] = self.kp_attitude;
        let [kd0, kd1, kd2] = self.kd_attitude;
        let (kp0, kp1, kp2): (L, L, L) = (kp0.get(), kp1.get(), kp2.get());
        let (kd0, kd1, kd2): (L, L, L) = (kd0.get(), kd1.get(), kd2.get());
        [
            (phi_d - s.att[0]) * kp0 - s.rate[0] * kd0,
            (theta_d - s.att[1]) * kp1 - s.rate[1] * kd1,
            (L::splat(r.psi) - s.att[2]) * kp2 + (L::splat(r.psi_dot) - s.rate[2]) * kd2,
        ]
    }
}

impl<P: Copy> Pd<P> {
    /// m/s^2, the horizontal acceleration the swing feedback adds: with u the line's unit
    /// vector from the attachment to the parcel and u' its rate, `swing_gain` u_h +
    /// `swing_damping` u'_h (x, y): the vehicle moves under the parcel, and with it as it
    /// swings, which damps the pendulum.
    #[inline(always)]
    fn swing_acceleration<L: Lane>(&self, seen: &PayloadView<L>) -> [L; 2]
    where
        P: Param<L>,
    {
        let [dx, dy, dz] = seen.pos;
        let [vx, vy, vz] = seen.vel;
        let length = (dx * dx + dy * dy + dz * dz)
            .sqrt()
            .max(L::splat(MIN_SWING_LENGTH));
        let inv = L::splat(1.0) / length;
        let (ux, uy, uz) = (dx * inv, dy * inv, dz * inv);
        // u' = (v - u (u . v)) / l: the relative velocity across the line, over its length.
        let along = ux * vx + uy * vy + uz * vz;
        let rate_x = (vx - ux * along) * inv;
        let rate_y = (vy - uy * along) * inv;
        let (k, c): (L, L) = (self.swing_gain.get(), self.swing_damping.get());
        [ux * k + rate_x * c, uy * k + rate_y * c]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::Trig;
    use crate::scenario::tests::paper;

    #[test]
    fn altitude_error_raises_thrust_by_kp() {
        let cfg = paper();
        let pd = Pd::new(&cfg.controller.pd, &cfg.control_context());
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

    /// A parcel 0.1 m forward of below its hook on a 1 m line, swinging forward at 0.3 m/s.
    fn swinging() -> PayloadView<f64> {
        PayloadView {
            pos: [0.1, 0.0, -0.995],
            vel: [0.3, 0.0, 0.03],
        }
    }

    fn seeing(pd: &Pd, seen: &PayloadView<f64>) -> Inputs<f64> {
        let mut s = crate::control::tests::at_rest([0.0, 0.0, 2.0], 0.0);
        s.vel[0] = 0.2;
        let r = Reference {
            pos: [0.5, -0.2, 2.0],
            ..Reference::default()
        };
        let trig = Trig::of_angles(0.0, 0.0, 0.0);
        let seen = Sight {
            rigid: &s,
            trig: &trig,
            payload: Some(seen),
        };
        pd.at_rest(&seen, &r, Tick::START)
    }

    #[test]
    fn without_swing_gains_the_payload_is_not_seen() {
        let cfg = paper();
        let pd = Pd::new(&cfg.controller.pd, &cfg.control_context());
        let blind = seeing(&pd, &PayloadView::none());
        let u = seeing(&pd, &swinging());
        assert_eq!(u.u1.to_bits(), blind.u1.to_bits());
        assert_eq!(u.tau.map(f64::to_bits), blind.tau.map(f64::to_bits));
    }

    #[test]
    fn swing_damping_pitches_toward_the_swing() {
        let cfg = paper();
        let mut gains = cfg.controller.pd.clone();
        gains.swing_damping = 2.0;
        let pd = Pd::new(&gains, &cfg.control_context());
        let still = seeing(&pd, &PayloadView::none());
        let u = seeing(&pd, &swinging());
        // Forward: a larger pitch command (theta > 0 accelerates toward +x at psi = 0); the
        // thrust and the roll are the same.
        assert!(u.tau[1] > still.tau[1] + 1e-3, "{u:?} vs {still:?}");
        assert_eq!(u.u1.to_bits(), still.u1.to_bits());
        assert_eq!(u.tau[0].to_bits(), still.tau[0].to_bits());
        let mut bad = gains.clone();
        bad.swing_damping = -1.0;
        let e = Pd::validate(&bad, "controller.pd", &cfg.control_context()).unwrap_err();
        assert_eq!(e.key, "controller.pd.swing_damping");
        bad.swing_damping = 0.0;
        bad.swing_gain = f64::NAN;
        let e = Pd::validate(&bad, "controller.pd", &cfg.control_context()).unwrap_err();
        assert_eq!(e.key, "controller.pd.swing_gain");
    }
}
