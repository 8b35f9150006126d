//! The last metres' two readings of a step (docs/model.md, "The last metres"): where and how
//! fast the parcel met the ground, located inside the step that crossed it, and the winch's
//! pay-out speed of the final approach.

use super::{where_positive, Cable, Cue, Ix};
use crate::lane::Lane;
use crate::model::body::Frame;
use crate::model::State;

/// m/s, the least descent speed the contact instant divides by (a parcel that reached the
/// ground at rest met it at the previous step's instant).
const LEAST_DESCENT: f64 = 1e-9;

impl<L: Lane> Cable<L> {
    /// The parcel's position and velocity at the instant it met the ground, from its state at
    /// the previous step (`last_pos`, `approach`, above the ground) and its velocity a step
    /// before (`before`): the free flight's acceleration a = (approach - before) / dt held
    /// over the fraction tau of the step, z(tau) = z + vz tau + az tau^2 / 2 = ground solved
    /// by two fixed-point passes from tau = h / -vz (the contact's own force, which acts from
    /// that instant on, never enters). Its error is the jerk's, O(dt^2): the touchdown's
    /// speed converges in the step however stiff the contact.
    #[inline(always)]
    pub(super) fn contact_instant(
        &self,
        last_pos: &[L; 3],
        approach: &[L; 3],
        before: &[L; 3],
        dt: f64,
    ) -> ([L; 3], [L; 3]) {
        let zero = L::splat(0.0);
        let inv_dt = 1.0 / dt;
        let a = [0, 1, 2].map(
            #[inline(always)]
            |i| (approach[i] - before[i]) * inv_dt,
        );
        let height = zero.max(last_pos[2] - self.ground);
        let descent = |tau: L| L::splat(LEAST_DESCENT).max(-(a[2] * 0.5).mul_add(tau, approach[2]));
        let mut tau = zero;
        for _ in 0..3 {
            tau = (height / descent(tau)).min(L::splat(dt));
        }
        let pos = [0, 1, 2].map(
            #[inline(always)]
            |i| (a[i] * 0.5 * tau).mul_add(tau, approach[i].mul_add(tau, last_pos[i])),
        );
        let vel = [0, 1, 2].map(
            #[inline(always)]
            |i| a[i].mul_add(tau, approach[i]),
        );
        (pos, vel)
    }

    /// m, the parcel's height above the ground as the vehicle knows it at `s`: the vehicle's
    /// height as it knows it (`height`) less the hook's offset and the line paid out.
    #[inline(always)]
    pub(super) fn known_height<F: Frame<L>, const N: usize>(
        &self,
        s: &State<L, N>,
        height: L,
    ) -> L {
        let line = Ix::of::<L, F>().line;
        height - self.offset - s[line] - self.ground
    }

    /// m/s, the winch's pay-out speed (docs/model.md, "The final approach"): `winch_speed`
    /// while the parcel's height above the ground as the vehicle knows it (`known`) exceeds
    /// `approach_height`, else `approach_speed` (exactly `winch_speed` without an approach).
    #[inline(always)]
    pub(super) fn final_approach(&self, known: L) -> L {
        let slow = where_positive(self.approach_height - known, L::splat(1.0));
        slow.mul_add(self.approach_speed - self.winch_speed, self.winch_speed)
    }

    /// 1 where the slack hook opens at this step (`payload.release = "slack"`), else 0: the
    /// measured tension T + sigma n (`cue.draw`, a standard normal per lane and step) below
    /// `slack_tension` at every step for `release_delay` s since the first of them. Computed
    /// only where some lane releases on slack.
    #[inline(always)]
    pub(super) fn slack_hook<F: Frame<L>, const N: usize>(
        &mut self,
        s: &State<L, N>,
        frame: &F,
        cue: &Cue<L>,
    ) -> L {
        let zero = L::splat(0.0);
        if !self.slack_release {
            return zero;
        }
        let one = L::splat(1.0);
        let measured = self
            .tension_noise
            .mul_add(cue.draw, self.line(s, frame).tension);
        let slack = where_positive(self.slack_tension - measured, one);
        // The time since the first step below the threshold of an unbroken run.
        self.slack_for = (self.slack_for + self.was_slack * cue.dt) * slack;
        self.was_slack = slack;
        let due = where_positive(self.slack_for - self.release_delay + cue.dt * 0.5, one);
        self.release_on_slack * due
    }

    /// 1 where the drop's hook opens at this step (`payload.release = { height = h }`), else
    /// 0: the parcel's known height (`known`) at most h, once it has been above it (a parcel
    /// that starts below h, on a low pad, is dropped on the way down, not at the start).
    #[inline(always)]
    pub(super) fn drop_hook(&mut self, known: L) -> L {
        let one = L::splat(1.0);
        self.drop_armed = self
            .drop_armed
            .max(where_positive(known - self.release_height, one));
        self.drop_armed * where_positive(self.release_height - known, one)
    }
}
