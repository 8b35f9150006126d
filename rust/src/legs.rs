//! The motion along a route (docs/model.md "Routes"): straight legs between 3-D points, each
//! flown rest to rest, with optional hovers (holds) at the points. Pure kinematics: the
//! schedule a scenario's route gives, and its checks, are `config::route`.
//!
//! Along a leg of length L the reference moves by s(t) with a sin^2 acceleration pulse,
//! a(t) = A sin^2(pi t / T) over the ramp T = 2 v_p / A, then cruises at v_p, then mirrors the
//! ramp to rest. The pulse is the simplest closed form whose acceleration *and* jerk are
//! continuous (zero at both ends, so it joins rest and cruise smoothly) and whose peak is
//! exactly the bound A; the ramp covers v_p T / 2. v_p = min(V, sqrt(A L / 2)): a leg too short
//! to reach the cruise speed V ramps up and straight down. A leg lasts T + L / v_p.

use std::f64::consts::PI;

/// Times are compared with this slack so that a waypoint at t = 60 s is reached at the step
/// whose nominal time k dt rounds to 60 s, whatever the floating-point noise in k dt.
pub const TIME_SLACK: f64 = 1e-9;

/// The motion along one leg: s, ds/dt, d2s/dt2 as functions of the time since it began.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Profile {
    /// m.
    pub length: f64,
    /// m/s^2, the acceleration bound (the pulse's peak).
    pub accel: f64,
    /// m/s, the speed reached: the cruise speed, or less on a short leg.
    pub peak_speed: f64,
    /// s, each of the two ramps.
    pub ramp: f64,
    /// s, at peak speed between the ramps (0 on a short leg).
    pub cruise: f64,
}

impl Profile {
    pub fn new(length: f64, speed: f64, accel: f64) -> Self {
        let peak_speed = speed.min((accel * length / 2.0).sqrt());
        let ramp = 2.0 * peak_speed / accel;
        Self {
            length,
            accel,
            peak_speed,
            ramp,
            cruise: (length / peak_speed - ramp).max(0.0),
        }
    }

    /// s, rest to rest.
    pub fn duration(&self) -> f64 {
        2.0 * self.ramp + self.cruise
    }

    /// (s, v, a) during the first ramp, `tau` in [0, ramp].
    fn ramp_at(&self, tau: f64) -> (f64, f64, f64) {
        let (t, a) = (self.ramp, self.accel);
        let w = 2.0 * PI / t;
        let s = 0.5 * a * (0.5 * tau * tau + ((w * tau).cos() - 1.0) / (w * w));
        let v = 0.5 * a * (tau - (w * tau).sin() / w);
        let sin = (PI * tau / t).sin();
        (s, v, a * sin * sin)
    }

    /// (s, v, a) at `tau` s after the leg began: at rest at 0 before, at `length` after.
    pub fn at(&self, tau: f64) -> (f64, f64, f64) {
        let total = self.duration();
        if tau <= 0.0 {
            (0.0, 0.0, 0.0)
        } else if tau >= total {
            (self.length, 0.0, 0.0)
        } else if tau <= self.ramp {
            self.ramp_at(tau)
        } else if tau <= self.ramp + self.cruise {
            let s = 0.5 * self.peak_speed * self.ramp + self.peak_speed * (tau - self.ramp);
            (s, self.peak_speed, 0.0)
        } else {
            let (s, v, a) = self.ramp_at(total - tau);
            (self.length - s, v, -a)
        }
    }
}

/// A hover at a point, a leg between two, or a hover at a point while the winch lowers the
/// parcel (`trajectory.lower`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SegmentKind {
    Hold,
    Leg,
    Lower,
}

impl SegmentKind {
    pub fn name(self) -> &'static str {
        match self {
            SegmentKind::Hold => "hold",
            SegmentKind::Leg => "leg",
            SegmentKind::Lower => "lower",
        }
    }

    /// The reference rests at a point (a hold or a lowering).
    pub fn rests(self) -> bool {
        self != SegmentKind::Leg
    }
}

/// One segment of the route's schedule (one phase under `phases = "legs"`).
#[derive(Clone, Debug, PartialEq)]
pub struct Segment {
    pub name: String,
    pub kind: SegmentKind,
    /// s, when the segment begins (a leg leaves its first point at rest).
    pub start: f64,
    /// s, when the reference is at rest at `to` (a hold: `start`).
    pub arrival: f64,
    /// s, when the next segment begins (the flight's end for the last one).
    pub end: f64,
    /// Indices into `trajectory.route` (equal for a hold).
    pub from: usize,
    pub to: usize,
    /// The motion along a leg (all zero for a hold or a lowering).
    pub profile: Profile,
    /// m, the line a lowering pays out beyond `payload.length_min` (0 for a hold or a leg,
    /// and for a retract, which reels it in) and m/s, its pay-out speed (infinity: the winch's;
    /// 0 for a hold or a leg).
    pub payout: f64,
    pub rate: f64,
}

/// A lowering in progress (`Trajectory::lowering`): m of line beyond `payload.length_min`
/// (0: a retract, reeling it in) and m/s, its own pay-out speed (infinity: the winch's).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lowering {
    pub payout: f64,
    pub speed: f64,
}

/// m, from `a` to `b`.
pub fn length(a: [f64; 3], b: [f64; 3]) -> f64 {
    let d = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn short_leg_peaks_below_the_cruise_speed() {
        // L = 4 m, A = 2: v_p = sqrt(A L / 2) = 2 m/s < V = 8; lasts sqrt(8 L / A) = 4 s.
        let p = Profile::new(4.0, 8.0, 2.0);
        assert_eq!(p.peak_speed, 2.0);
        assert_eq!((p.cruise, p.duration()), (0.0, 4.0));
        let (s, v, a) = p.at(2.0);
        assert!((s - 2.0).abs() < 1e-12 && (v - 2.0).abs() < 1e-12 && a.abs() < 1e-12);
    }
}
