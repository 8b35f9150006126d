//! Reference trajectory from waypoints, and the flight's named phases (docs/model.md section 3).

use crate::config::route::FLIGHT_PHASE;
use crate::config::{Context, Interpolation};
use crate::legs::{Segment, SegmentKind};

/// Desired position (x, y, z), yaw and their first two derivatives at one instant, and the
/// corridor the flight is to stay in about the current leg.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Reference {
    pub pos: [f64; 3],
    pub vel: [f64; 3],
    pub acc: [f64; 3],
    pub psi: f64,
    pub psi_dot: f64,
    pub psi_ddot: f64,
    /// m, the operational volume about the leg (`[volume]`, `Volume::sizes`): the flight
    /// geography's half-width and half-height, the contingency buffer; infinite without one.
    /// Read by the containment metrics only (`metrics::geography_margin`), never by a law.
    pub corridor: [f64; 3],
}

impl Default for Reference {
    /// At the origin, at rest, in no volume (an infinite corridor).
    fn default() -> Self {
        Self {
            pos: [0.0; 3],
            vel: [0.0; 3],
            acc: [0.0; 3],
            psi: 0.0,
            psi_dot: 0.0,
            psi_ddot: 0.0,
            corridor: [f64::INFINITY; 3],
        }
    }
}

pub(crate) use crate::legs::TIME_SLACK;

#[derive(Clone, Debug, PartialEq)]
pub struct Trajectory {
    waypoints: Vec<[f64; 5]>,
    interpolation: Interpolation,
    /// Min-jerk only: where the reference starts, (t0, x, y, z, psi) of the initial state.
    start: [f64; 5],
    /// Min-jerk only: s, the duration of each move (shortened to the gap to the next waypoint).
    transition: f64,
    /// Route only: the points and the schedule of holds and legs over them.
    route: Vec<[f64; 3]>,
    segments: Vec<Segment>,
    /// m, the operational volume every reference carries (`Reference::corridor`).
    corridor: [f64; 3],
}

impl Trajectory {
    pub fn new(cfg: &Context) -> Self {
        let w = &cfg.trajectory.waypoints;
        let [x, y, z] = cfg.initial.position;
        Self {
            waypoints: w.clone(),
            interpolation: cfg.trajectory.interpolation,
            start: [
                w.first().map_or(0.0, |r| r[0]),
                x,
                y,
                z,
                cfg.initial.attitude[2],
            ],
            transition: cfg.trajectory.transition,
            route: cfg.trajectory.route.clone(),
            // A validated scenario's schedule cannot fail (`Config::validate` built it).
            segments: crate::config::route::schedule(cfg).unwrap_or_default(),
            corridor: cfg.volume.sizes(),
        }
    }

    /// The time from which `at` may give a different reference than it gave with `segment`:
    /// the next waypoint's time for step references (constant in between), -inf for min-jerk
    /// (changes every step). The flight loop recomputes the reference once `t + TIME_SLACK`
    /// reaches it, the same test `at` makes.
    #[inline]
    pub fn next_change(&self, segment: usize) -> f64 {
        match self.interpolation {
            Interpolation::Step => self
                .waypoints
                .get(segment + 1)
                .map_or(f64::INFINITY, |w| w[0]),
            Interpolation::MinJerk | Interpolation::Route => f64::NEG_INFINITY,
        }
    }

    /// The reference at time `t`. `segment` caches the waypoint index reached so far: times are
    /// asked for in increasing order, so the lookup is O(1) per step.
    ///
    /// Step: the reference jumps to waypoint i's values at its time t_i. Min-jerk: at t_i the
    /// reference *starts* a quintic move from the previous waypoint (from the initial state for
    /// the first one) to waypoint i, lasting `transition` seconds or the gap to the next
    /// waypoint if shorter, then holds it. A waypoint's time is thus when its move begins in
    /// both modes, and min-jerk tends to step as the transition tends to zero.
    #[inline]
    pub fn at(&self, t: f64, segment: &mut usize) -> Reference {
        Reference {
            corridor: self.corridor,
            ..self.motion_at(t, segment)
        }
    }

    /// `at` without the corridor (the default's).
    #[inline]
    fn motion_at(&self, t: f64, segment: &mut usize) -> Reference {
        if self.interpolation == Interpolation::Route {
            return self.route_at(t, segment);
        }
        let w = &self.waypoints;
        while *segment + 1 < w.len() && t + TIME_SLACK >= w[*segment + 1][0] {
            *segment += 1;
        }
        let i = *segment;
        match self.interpolation {
            Interpolation::Step => hold(&w[i]),
            Interpolation::MinJerk => {
                if t + TIME_SLACK < w[0][0] {
                    return hold(&self.start);
                }
                let from = if i == 0 { &self.start } else { &w[i - 1] };
                let span = match w.get(i + 1) {
                    Some(next) => self.transition.min(next[0] - w[i][0]),
                    None => self.transition,
                };
                if span <= 0.0 || t >= w[i][0] + span {
                    return hold(&w[i]);
                }
                min_jerk(from, &w[i], w[i][0], span, t)
            }
            Interpolation::Route => unreachable!("handled above"),
        }
    }

    /// The straight line the reference follows in `segment` (as left by `at`): a point on it
    /// and its unit direction, from the previous point (waypoint, route point, or the initial
    /// position before the first waypoint) to the current one. The direction is zero where
    /// the two coincide (a route's hold, a waypoint repeating the previous position): the
    /// line is then that point. The cross-track error is the distance from this line.
    /// `start` is the flight's own initial position (a dispersed batch's lanes differ in it).
    pub fn line(&self, segment: usize, start: [f64; 3]) -> ([f64; 3], [f64; 3]) {
        let (a, b) = match self.interpolation {
            Interpolation::Route => match self.segments.get(segment) {
                Some(s) => (self.route[s.from], self.route[s.to]),
                None => ([0.0; 3], [0.0; 3]),
            },
            Interpolation::Step | Interpolation::MinJerk => {
                let w = &self.waypoints;
                let from = match segment {
                    0 => start,
                    _ => [w[segment - 1][1], w[segment - 1][2], w[segment - 1][3]],
                };
                let to = &w[segment];
                (from, [to[1], to[2], to[3]])
            }
        };
        let d = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
        let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        if n == 0.0 {
            (b, [0.0; 3])
        } else {
            (a, [d[0] / n, d[1] / n, d[2] / n])
        }
    }

    /// The line segment `segment` of a route pays out beyond `payload.length_min` and its
    /// speed when it is a lowering (`trajectory.lower`, `.lower_speed`, `.retract`), else None.
    pub fn lowering(&self, segment: usize) -> Option<crate::legs::Lowering> {
        self.segments
            .get(segment)
            .filter(|s| s.kind == SegmentKind::Lower)
            .map(|s| crate::legs::Lowering {
                payout: s.payout,
                speed: s.rate,
            })
    }

    /// The lowering due at segment `segment` (its line and speed, `lowering`): in a lowering,
    /// and in the hold at its point after it (a lowering that could not start on time, the
    /// vehicle not yet over the point, may start there).
    pub fn lowering_due(&self, segment: usize) -> Option<crate::legs::Lowering> {
        let s = self.segments.get(segment)?;
        match s.kind {
            SegmentKind::Lower => self.lowering(segment),
            SegmentKind::Hold => {
                let before = segment.checked_sub(1)?;
                let b = self.segments.get(before)?;
                if b.kind == SegmentKind::Lower && b.from == s.from {
                    self.lowering(before)
                } else {
                    None
                }
            }
            _ => None,
        }
    }

    /// The horizontal point (m) segment `segment` of a route lowers at, if it is a lowering.
    pub fn drop_point(&self, segment: usize) -> Option<[f64; 2]> {
        self.lowering(segment)?;
        let p = self.route[self.segments[segment].from];
        Some([p[0], p[1]])
    }

    /// Route: `segment` indexes the schedule. A hold (and any time after the schedule) rests
    /// at its point; a leg moves along the straight line by its profile. psi_des = 0.
    #[inline]
    fn route_at(&self, t: f64, segment: &mut usize) -> Reference {
        let s = &self.segments;
        while *segment + 1 < s.len() && t + TIME_SLACK >= s[*segment + 1].start {
            *segment += 1;
        }
        let Some(seg) = s.get(*segment) else {
            return Reference::default();
        };
        let (a, b) = (self.route[seg.from], self.route[seg.to]);
        if seg.kind.rests() {
            return Reference {
                pos: a,
                ..Reference::default()
            };
        }
        let p = &seg.profile;
        let (dist, speed, accel) = p.at(t - seg.start);
        let mut r = Reference::default();
        for k in 0..3 {
            let u = (b[k] - a[k]) / p.length;
            // At arrival the position is the point itself, not a + L u (rounding).
            r.pos[k] = if dist >= p.length {
                b[k]
            } else {
                a[k] + dist * u
            };
            r.vel[k] = speed * u;
            r.acc[k] = accel * u;
        }
        r
    }
}

fn hold(row: &[f64; 5]) -> Reference {
    Reference {
        pos: [row[1], row[2], row[3]],
        psi: row[4],
        ..Reference::default()
    }
}

/// Quintic from `a` to `b` (columns 1..5 of each) over [t0, t0 + span], with zero velocity and
/// acceleration at both ends.
fn min_jerk(a: &[f64; 5], b: &[f64; 5], t0: f64, span: f64, t: f64) -> Reference {
    let tau = ((t - t0) / span).clamp(0.0, 1.0);
    let (t2, t3) = (tau * tau, tau * tau * tau);
    let shape = t3 * (10.0 - 15.0 * tau + 6.0 * t2);
    let dshape = 30.0 * t2 * (1.0 - 2.0 * tau + t2) / span;
    let ddshape = 60.0 * tau * (1.0 - 3.0 * tau + 2.0 * t2) / (span * span);
    let mut r = Reference::default();
    for k in 0..3 {
        let d = b[k + 1] - a[k + 1];
        r.pos[k] = a[k + 1] + d * shape;
        r.vel[k] = d * dshape;
        r.acc[k] = d * ddshape;
    }
    let d = b[4] - a[4];
    r.psi = a[4] + d * shape;
    r.psi_dot = d * dshape;
    r.psi_ddot = d * ddshape;
    r
}

/// A phase as a closed range of sample indices k (time k dt) on the step grid.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PhaseSteps {
    pub first: usize,
    pub last: usize,
}

impl PhaseSteps {
    #[inline(always)]
    pub fn contains(&self, k: usize) -> bool {
        k >= self.first && k <= self.last
    }
}

/// Each phase of the scenario on the step grid: the samples whose time lies in [start, end].
/// After them, the whole flight (`FLIGHT_PHASE`): every sample, 0 to the last step.
pub fn phase_steps(cfg: &Context) -> Vec<PhaseSteps> {
    let dt = cfg.integrator.dt;
    let steps = cfg.steps();
    cfg.phases
        .iter()
        .map(|p| {
            let first = ((p.start / dt) - TIME_SLACK).ceil().max(0.0) as usize;
            let last = (((p.end / dt) + TIME_SLACK).floor() as usize).min(steps);
            PhaseSteps {
                first: first.min(last),
                last,
            }
        })
        .chain(std::iter::once(PhaseSteps {
            first: 0,
            last: steps,
        }))
        .collect()
}

/// The names of `phase_steps`' phases: the scenario's, then `FLIGHT_PHASE`.
pub fn phase_names(cfg: &Context) -> Vec<String> {
    cfg.phases
        .iter()
        .map(|p| p.name.clone())
        .chain(std::iter::once(FLIGHT_PHASE.to_string()))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::tests::paper;

    #[test]
    fn step_reference_jumps_at_waypoints() {
        let cfg = paper();
        let tr = Trajectory::new(&cfg.context());
        let mut seg = 0;
        assert_eq!(tr.at(0.0, &mut seg).pos, [0.0, 0.0, 2.0]);
        assert_eq!(tr.at(59.9998, &mut seg).pos[2], 2.0);
        let r = tr.at(300_000.0 * 2e-4, &mut seg);
        assert_eq!(r.pos[2], 0.0);
        assert_eq!(r.vel, [0.0; 3]);
    }

    #[test]
    fn min_jerk_is_smooth_and_consistent() {
        let mut cfg = paper();
        cfg.trajectory.interpolation = Interpolation::MinJerk;
        cfg.trajectory.transition = 4.0;
        cfg.initial.position = [0.0; 3];
        cfg.initial.attitude = [0.0; 3];
        cfg.trajectory.waypoints = vec![[0.0, 1.0, -2.0, 3.0, 0.4], [10.0, 1.0, -2.0, 0.0, 0.0]];
        let tr = Trajectory::new(&cfg.context());
        let mut seg = 0;
        let mid = tr.at(2.0, &mut seg);
        assert!((mid.pos[2] - 1.5).abs() < 1e-12, "symmetric halfway");
        assert!(
            (mid.vel[2] - 3.0 * 1.875 / 4.0).abs() < 1e-12,
            "peak speed 1.875 d/T"
        );
        // derivatives agree with finite differences of position
        let h = 1e-5;
        for t in [1.3, 11.7] {
            let (mut s1, mut s2) = (0, 0);
            let (a, b) = (tr.at(t - h, &mut s1), tr.at(t + h, &mut s2));
            let c = tr.at(t, &mut 0);
            for k in 0..3 {
                assert!(((b.pos[k] - a.pos[k]) / (2.0 * h) - c.vel[k]).abs() < 1e-7);
                assert!(((b.vel[k] - a.vel[k]) / (2.0 * h) - c.acc[k]).abs() < 1e-6);
            }
            assert!(((b.psi - a.psi) / (2.0 * h) - c.psi_dot).abs() < 1e-7);
        }
        // holds the first waypoint from the end of its move to the next waypoint's time
        for t in [4.0, 7.0, 9.999] {
            let r = tr.at(t, &mut seg);
            assert_eq!(r.pos, [1.0, -2.0, 3.0]);
            assert_eq!((r.vel, r.acc, r.psi), ([0.0; 3], [0.0; 3], 0.4));
        }
        // the landing move starts at the last waypoint's time and lasts the transition
        let land = tr.at(12.0, &mut seg);
        assert!((land.pos[2] - 1.5).abs() < 1e-12 && land.vel[2] < 0.0);
        let end = tr.at(14.0, &mut seg);
        assert_eq!(end.pos, [1.0, -2.0, 0.0]);
        assert_eq!(end.vel, [0.0; 3]);
    }

    #[test]
    fn min_jerk_tends_to_step_and_never_overruns_the_next_waypoint() {
        let mut cfg = paper();
        let step = Trajectory::new(&cfg.context());
        cfg.trajectory.interpolation = Interpolation::MinJerk;
        cfg.trajectory.transition = 0.0;
        let zero = Trajectory::new(&cfg.context());
        for t in [0.0, 1.0, 59.9, 60.0, 65.0] {
            assert_eq!(zero.at(t, &mut 0), step.at(t, &mut 0), "t = {t}");
        }
        // a transition longer than the gap ends at the next waypoint's time
        cfg.trajectory.transition = 100.0;
        let long = Trajectory::new(&cfg.context());
        let r = long.at(60.0 - 1e-6, &mut 0);
        assert!(
            (r.pos[2] - 2.0).abs() < 1e-9 && r.vel[2].abs() < 1e-6,
            "{r:?}"
        );
    }

    #[test]
    fn paper_phases_on_the_grid() {
        let cfg = paper();
        let ph = phase_steps(&cfg.context());
        assert_eq!(
            ph[0],
            PhaseSteps {
                first: 0,
                last: 100_000
            }
        );
        assert_eq!(
            ph[1],
            PhaseSteps {
                first: 100_000,
                last: 250_000
            }
        );
        assert_eq!(
            ph[2],
            PhaseSteps {
                first: 250_000,
                last: 350_000
            }
        );
    }
}
