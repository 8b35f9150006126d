//! Routes (`trajectory.interpolation = "route"`, docs/model.md "Routes"): their checks, the
//! schedule of holds and legs a route's values give (`schedule`), and the phases of
//! `phases = "legs"` (`leg_phases`). The motion along a leg is `crate::legs`.

use crate::config::{rows_checked, ConfigError, Context, Interpolation, Phase};
use crate::legs::{length, Profile, Segment, SegmentKind, TIME_SLACK};

/// The whole-flight phase every result carries after the scenario's own phases.
pub const FLIGHT_PHASE: &str = "flight";

/// Fewest steps a hold or leg may last: its phase, with both ends moved to the step grid (by
/// up to half a step each), still spans the two steps a phase needs.
pub const MIN_STEPS: f64 = 4.0;

/// The keys of a route that can be checked without the step grid.
pub fn validate(cfg: &Context) -> Result<(), ConfigError> {
    let tr = &cfg.trajectory;
    if tr.interpolation != Interpolation::Route {
        for (key, set) in [
            ("trajectory.route", !tr.route.is_empty()),
            ("trajectory.speed", tr.speed.is_some()),
            ("trajectory.acceleration", tr.acceleration.is_some()),
            ("trajectory.hold", !tr.hold.is_empty()),
            ("trajectory.arrival_hold", !tr.arrival_hold.is_empty()),
            ("trajectory.lower", !tr.lower.is_empty()),
            ("trajectory.lower_speed", !tr.lower_speed.is_empty()),
            ("trajectory.retract", !tr.retract.is_empty()),
            ("trajectory.names", !tr.names.is_empty()),
        ] {
            if set {
                return Err(ConfigError::new(
                    key,
                    format!(
                        "{key} is only read by a route (trajectory.interpolation = \"route\"), \
                         got it with {:?}",
                        tr.interpolation
                    ),
                ));
            }
        }
        return Ok(());
    }
    if !tr.waypoints.is_empty() {
        return Err(ConfigError::new(
            "trajectory.waypoints",
            format!(
                "trajectory.waypoints must be absent for a route (trajectory.interpolation = \
                 \"route\" flies trajectory.route), got {} rows",
                tr.waypoints.len()
            ),
        ));
    }
    let r = &tr.route;
    rows_checked("trajectory.route", r, "points [x, y, z]", |i| {
        let p = r[i];
        if i > 0 && length(r[i - 1], p) == 0.0 {
            let key = format!("trajectory.route[{i}]");
            return Err(ConfigError::new(
                &key,
                format!("{key} repeats the previous point {p:?}: a leg needs two distinct points"),
            ));
        }
        Ok(())
    })?;
    for (key, x) in [
        ("trajectory.speed", tr.speed),
        ("trajectory.acceleration", tr.acceleration),
    ] {
        match x {
            None => {
                return Err(ConfigError::new(
                    key,
                    format!("{key} must be given for a route, got none"),
                ))
            }
            Some(x) if !(x.is_finite() && x > 0.0) => {
                return Err(ConfigError::new(
                    key,
                    format!("{key} must be > 0, got {x:?}"),
                ))
            }
            Some(_) => {}
        }
    }
    for (name, holds) in [
        ("trajectory.hold", &tr.hold),
        ("trajectory.arrival_hold", &tr.arrival_hold),
    ] {
        one_per_point(name, holds.len(), r.len())?;
        for (i, h) in holds.iter().enumerate() {
            if !(h.is_finite() && *h >= 0.0) {
                let key = format!("{name}[{i}]");
                return Err(ConfigError::new(
                    &key,
                    format!("{key} must be >= 0, got {h:?}"),
                ));
            }
        }
    }
    one_per_point("trajectory.lower", tr.lower.len(), r.len())?;
    for (i, x) in tr.lower.iter().enumerate() {
        if !(x.is_finite() && *x >= 0.0) {
            let key = format!("trajectory.lower[{i}]");
            return Err(ConfigError::new(
                &key,
                format!("{key} must be >= 0 (m of line to pay out), got {x:?}"),
            ));
        }
    }
    validate_lowering_speeds(cfg)?;
    one_per_point("trajectory.retract", tr.retract.len(), r.len())
}

/// A per-point key (`key`, `given` values) on a route of `points`: empty, or one per point.
fn one_per_point(key: &str, given: usize, points: usize) -> Result<(), ConfigError> {
    if given != 0 && given != points {
        return Err(ConfigError::new(
            key,
            format!("{key} needs one value per route point ({points}), got {given}"),
        ));
    }
    Ok(())
}

/// `trajectory.lower_speed`: one per point, each 0 (the winch's speed) or a pay-out speed in
/// (0, `payload.winch_speed`] (the winch's top speed).
fn validate_lowering_speeds(cfg: &Context) -> Result<(), ConfigError> {
    let tr = &cfg.trajectory;
    one_per_point(
        "trajectory.lower_speed",
        tr.lower_speed.len(),
        tr.route.len(),
    )?;
    let top = cfg.winch.speed.unwrap_or(f64::INFINITY);
    for (i, x) in tr.lower_speed.iter().enumerate() {
        if !(x.is_finite() && *x >= 0.0 && *x <= top) {
            let key = format!("trajectory.lower_speed[{i}]");
            return Err(ConfigError::new(
                &key,
                format!(
                    "{key} must be 0 (payload.winch_speed) or a pay-out speed in (0, \
                     payload.winch_speed = {top:?}] m/s, got {x:?}"
                ),
            ));
        }
    }
    Ok(())
}

/// m/s, the pay-out speed of point `i`'s lowering: its `trajectory.lower_speed`, or the
/// winch's top speed `top` (0 or none given).
pub fn lowering_speed(tr: &crate::config::Trajectory, i: usize, top: f64) -> f64 {
    match tr.lower_speed.get(i) {
        Some(&x) if x > 0.0 => x.min(top),
        _ => top,
    }
}

/// s, how long a lowering of `payout` m lasts (`trajectory.lower`): the pay-out at the winch's
/// speed `v` with a ramp `v / a` at each end (`model::payload::cable`'s winch reaches its
/// speed in about that, and settles within it). With a final approach (`approach`: its
/// height and speed) the line paid out once the parcel, `height` m above the ground at the
/// start, is below the approach's height goes at the approach's speed.
pub fn lowering_time(
    payout: f64,
    v: f64,
    a: f64,
    approach: Option<(f64, f64)>,
    height: f64,
) -> f64 {
    let ramps = 2.0 * v / a;
    match approach {
        None => payout / v + ramps,
        Some((h, slow)) => {
            let fast = (height - h).clamp(0.0, payout);
            fast / v + (payout - fast) / slow + ramps
        }
    }
}

/// The route's schedule over the flight: holds and legs in time order, from t = 0 to
/// `integrator.duration` (the time after the last arrival is a hold at the last point). Checks
/// what needs the step grid: a hold or leg shorter than MIN_STEPS steps, a route longer than the
/// flight, `trajectory.names`. Empty unless the scenario flies a route; `validate` first.
pub fn schedule(cfg: &Context) -> Result<Vec<Segment>, ConfigError> {
    let tr = &cfg.trajectory;
    if tr.interpolation != Interpolation::Route {
        return Ok(Vec::new());
    }
    let (speed, accel) = (
        tr.speed.unwrap_or(f64::NAN),
        tr.acceleration.unwrap_or(f64::NAN),
    );
    let dt = cfg.integrator.dt;
    let duration = cfg.integrator.duration;
    let n = tr.route.len();
    let mut out = Vec::with_capacity(2 * n);
    let mut t = 0.0;
    // m, the line out beyond the reeled-in length (a retract reels it in).
    let mut line_out = 0.0;
    for i in 0..n {
        // On arrival: the waypoint's own hold (PX4 holds before the point's items).
        let w = tr.arrival_hold.get(i).copied().unwrap_or(0.0);
        if w > 0.0 {
            out.push(hold_segment(ARRIVAL, i, t, w, dt)?);
            t += w;
        }
        let payout = tr.lower.get(i).copied().unwrap_or(0.0);
        let (top, a) = (
            cfg.winch.speed.unwrap_or(f64::NAN),
            cfg.winch.acceleration.unwrap_or(f64::NAN),
        );
        if payout > 0.0 {
            // The winch's keys are the cable's, checked with it (`Cable::validate`). At the
            // lowering's own speed r (the servo's ramps are the winch's, 2 v / a).
            let rate = lowering_speed(tr, i, top);
            let span = lowering_time(
                payout,
                rate,
                a,
                cfg.winch.approach.map(|(h, slow)| (h, slow.min(rate))),
                tr.route[i][2] - cfg.winch.hang - cfg.ground.altitude,
            ) + 2.0 * (top - rate) / a;
            let given = if rate < top { rate } else { f64::INFINITY };
            out.push(lowering_segment(
                format!("lower{}", i + 1),
                i,
                t,
                span,
                payout,
                given,
            ));
            t += span;
            line_out = payout;
        }
        if tr.retract.get(i).copied().unwrap_or(false) && line_out > 0.0 {
            // Reeled in at the winch's speed, the parcel still on the hook.
            let span = lowering_time(line_out, top, a, None, 0.0);
            let all = f64::INFINITY;
            out.push(lowering_segment(
                format!("retract{}", i + 1),
                i,
                t,
                span,
                0.0,
                all,
            ));
            t += span;
            line_out = 0.0;
        }
        let h = tr.hold.get(i).copied().unwrap_or(0.0);
        if h > 0.0 {
            out.push(hold_segment(AFTER, i, t, h, dt)?);
            t += h;
        }
        if i + 1 < n {
            let leg = leg_segment(tr, i, t, speed, accel, dt)?;
            t = leg.end;
            out.push(leg);
        }
    }
    if t > duration + TIME_SLACK {
        return Err(ConfigError::new(
            "integrator.duration",
            format!(
                "integrator.duration must cover the route's legs and holds ({t:.3} s at \
                 trajectory.speed = {speed:?}, trajectory.acceleration = {accel:?}), got \
                 {duration:?}: set it to at least {need} s",
                need = (t * 10.0).ceil() / 10.0
            ),
        ));
    }
    // What is left of the flight hovers at the last point: the last hold runs to the end, or
    // becomes one; a remainder shorter than MIN_STEPS steps closes the last leg instead.
    let last = out.last_mut().expect("a route has at least one leg");
    if last.kind.rests() || duration - t < MIN_STEPS * dt {
        last.end = duration;
    } else {
        out.push(Segment {
            name: format!("hold{n}"),
            kind: SegmentKind::Hold,
            start: t,
            arrival: t,
            end: duration,
            from: n - 1,
            to: n - 1,
            profile: Profile::default(),
            payout: 0.0,
            rate: 0.0,
        });
    }
    name_segments(&mut out, &tr.names)?;
    Ok(out)
}

/// A point's two holds: (key, the segment's default name), on arrival and after its items.
type HoldKind = (&'static str, &'static str);
const ARRIVAL: HoldKind = ("trajectory.arrival_hold", "arrive");
const AFTER: HoldKind = ("trajectory.hold", "hold");

/// The hold of `h` s at point `i` from `t` (at least MIN_STEPS steps of `dt`).
fn hold_segment(
    (name, label): HoldKind,
    i: usize,
    t: f64,
    h: f64,
    dt: f64,
) -> Result<Segment, ConfigError> {
    if h < MIN_STEPS * dt {
        let key = format!("{name}[{i}]");
        return Err(ConfigError::new(
            &key,
            format!(
                "{key} must be 0 or at least {MIN_STEPS} steps ({MIN_STEPS} integrator.dt = {:?} s), got {h:?}",
                MIN_STEPS * dt
            ),
        ));
    }
    Ok(Segment {
        name: format!("{label}{}", i + 1),
        kind: SegmentKind::Hold,
        start: t,
        arrival: t,
        end: t + h,
        from: i,
        to: i,
        profile: Profile::default(),
        payout: 0.0,
        rate: 0.0,
    })
}

/// The leg from point `i` to the next from `t`, by its profile at `speed` and `accel` (at
/// least MIN_STEPS steps of `dt`, and finite).
fn leg_segment(
    tr: &crate::config::Trajectory,
    i: usize,
    t: f64,
    speed: f64,
    accel: f64,
    dt: f64,
) -> Result<Segment, ConfigError> {
    let profile = Profile::new(length(tr.route[i], tr.route[i + 1]), speed, accel);
    let span = profile.duration();
    if !span.is_finite() {
        // A subnormal speed or acceleration: the leg would never end.
        let (key, x) = if speed <= accel {
            ("trajectory.speed", speed)
        } else {
            ("trajectory.acceleration", accel)
        };
        return Err(ConfigError::new(
            key,
            format!(
                "{key} is too small: the leg to trajectory.route[{}] would last {span:?} s, \
                 got {x:?}",
                i + 1
            ),
        ));
    }
    if span < MIN_STEPS * dt {
        let key = format!("trajectory.route[{}]", i + 1);
        return Err(ConfigError::new(
            &key,
            format!(
                "{key}: the leg to it lasts {span:?} s, less than {MIN_STEPS} steps \
                 ({MIN_STEPS} integrator.dt = {:?} s): move the point or lower trajectory.acceleration",
                MIN_STEPS * dt
            ),
        ));
    }
    Ok(Segment {
        name: format!("leg{}", i + 1),
        kind: SegmentKind::Leg,
        start: t,
        arrival: t + span,
        end: t + span,
        from: i,
        to: i + 1,
        profile,
        payout: 0.0,
        rate: 0.0,
    })
}

/// `trajectory.names` given to the segments `out` in order (one each, unique, not blank, not
/// the whole flight's phase name).
fn name_segments(out: &mut [Segment], names: &[String]) -> Result<(), ConfigError> {
    if names.is_empty() {
        return Ok(());
    }
    if names.len() != out.len() {
        let defaults: Vec<&str> = out.iter().map(|s| s.name.as_str()).collect();
        return Err(ConfigError::new(
            "trajectory.names",
            format!(
                "trajectory.names must name each of the route's {} segments in order ({}), got {}",
                out.len(),
                abridged(&defaults),
                names.len()
            ),
        ));
    }
    let mut seen = std::collections::HashSet::with_capacity(names.len());
    for (i, name) in names.iter().enumerate() {
        let key = format!("trajectory.names[{i}]");
        if name.trim().is_empty() {
            return Err(ConfigError::new(
                &key,
                format!("{key} must not be blank, got {name:?}"),
            ));
        }
        if name == FLIGHT_PHASE {
            return Err(ConfigError::new(
                &key,
                format!(
                    "{key} must be a name other than {FLIGHT_PHASE:?} (the whole flight's), got {name:?}"
                ),
            ));
        }
        if !seen.insert(name.as_str()) {
            return Err(ConfigError::new(
                &key,
                format!("{key} must be unique, got {name:?} twice"),
            ));
        }
    }
    for (s, name) in out.iter_mut().zip(names) {
        s.name = name.clone();
    }
    Ok(())
}

/// A lowering (`payout` m beyond the reeled-in length at `rate` m/s, infinity: the winch's
/// speed; 0 m: a retract) at point `i` from `t` for `span` s.
fn lowering_segment(name: String, i: usize, t: f64, span: f64, payout: f64, rate: f64) -> Segment {
    Segment {
        name,
        kind: SegmentKind::Lower,
        start: t,
        arrival: t,
        end: t + span,
        from: i,
        to: i,
        profile: Profile::default(),
        payout,
        rate,
    }
}

/// `a, b, c` for a few names; the first and last few around a count for many (a message
/// stays one short line whatever the route's length).
fn abridged(names: &[&str]) -> String {
    const FEW: usize = 8;
    if names.len() <= FEW {
        return names.join(", ");
    }
    format!(
        "{}, ... {} more ..., {}",
        names[..FEW - 2].join(", "),
        names.len() - FEW,
        names[names.len() - 2..].join(", ")
    )
}

/// `phases = "legs"`: one phase per segment of the schedule, covering the flight.
pub fn leg_phases(cfg: &Context) -> Result<Vec<Phase>, ConfigError> {
    if cfg.trajectory.interpolation != Interpolation::Route {
        return Err(ConfigError::new(
            "phases",
            format!(
                "phases = \"legs\" needs trajectory.interpolation = \"route\", got {:?}",
                cfg.trajectory.interpolation
            ),
        ));
    }
    // Interior boundaries on the step grid, so that consecutive phases share their boundary
    // sample (trapezoid sums then tile the flight); the flight's own ends stay exact.
    let dt = cfg.integrator.dt;
    let on_grid = |t: f64| (t / dt).round() * dt;
    let segments = schedule(cfg)?;
    let n = segments.len();
    Ok(segments
        .into_iter()
        .enumerate()
        .map(|(i, s)| Phase {
            name: s.name,
            start: if i == 0 { 0.0 } else { on_grid(s.start) },
            end: if i + 1 == n {
                cfg.integrator.duration
            } else {
                on_grid(s.end)
            },
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::tests::paper_value;
    use crate::scenario::Config;
    use crate::trajectory::{phase_steps, Reference, Trajectory};
    use serde_json::json;
    use std::f64::consts::PI;

    /// The paper scenario flying `route` under `phases = "legs"`, with `edit` applied.
    fn route_cfg(edit: impl Fn(&mut serde_json::Value)) -> Result<Config, ConfigError> {
        let mut v = paper_value();
        let tr = &mut v["trajectory"];
        tr["interpolation"] = json!("route");
        tr.as_object_mut().unwrap().remove("waypoints");
        tr["route"] = json!([[0, 0, 0], [0, 0, 10], [300, 40, 10], [300, 40, 0]]);
        tr["speed"] = json!(8.0);
        tr["acceleration"] = json!(1.5);
        tr["hold"] = json!([2.0, 0.0, 0.0, 5.0]);
        v["phases"] = json!("legs");
        v["integrator"]["duration"] = json!(80.0);
        v["integrator"]["dt"] = json!(1e-3);
        edit(&mut v);
        Config::from_json(&v.to_string())
    }

    fn norm(v: [f64; 3]) -> f64 {
        (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
    }

    #[test]
    fn profile_matches_the_closed_form_on_each_axis() {
        // A = 2 m/s^2, V = 5 m/s, L = 100 m: ramp T = 2V/A = 5 s, cruise L/V - T = 15 s.
        // Halfway up the ramp: a = A, v = V/2, s = A T^2 (1/16 - 1/(4 pi^2)).
        let (a, v, l, t) = (2.0, 5.0, 100.0, 5.0);
        let s_half = a * t * t * (1.0 / 16.0 - 1.0 / (4.0 * PI * PI));
        for axis in 0..3 {
            let mut to = [0.0; 3];
            to[axis] = l;
            let cfg = route_cfg(|c| {
                c["trajectory"]["route"] = json!([[0, 0, 0], to]);
                c["trajectory"]["speed"] = json!(v);
                c["trajectory"]["acceleration"] = json!(a);
                c["trajectory"]["hold"] = json!([]);
                c["integrator"]["duration"] = json!(30.0);
            })
            .unwrap();
            let seg = &schedule(&cfg.context()).unwrap()[0];
            assert_eq!((seg.profile.ramp, seg.profile.cruise), (t, 15.0));
            assert_eq!(seg.arrival, 25.0);
            let tr = Trajectory::new(&cfg.context());
            let r = tr.at(t / 2.0, &mut 0);
            assert!((r.pos[axis] - s_half).abs() < 1e-12, "{r:?}");
            assert!((r.vel[axis] - v / 2.0).abs() < 1e-12);
            assert!((r.acc[axis] - a).abs() < 1e-12);
            // Mid-cruise: s = V T / 2 + V (t - T); the other axes never move.
            let r = tr.at(12.5, &mut 0);
            assert!((r.pos[axis] - (12.5 + 5.0 * 7.5)).abs() < 1e-12);
            assert_eq!((r.vel[axis], r.acc[axis]), (v, 0.0));
            for other in (0..3).filter(|k| *k != axis) {
                assert_eq!((r.pos[other], r.vel[other], r.acc[other]), (0.0, 0.0, 0.0));
            }
            // Symmetric: a quarter of the way down the decel ramp mirrors the accel ramp.
            let r = tr.at(25.0 - t / 2.0, &mut 0);
            assert!((r.pos[axis] - (l - s_half)).abs() < 1e-12);
            assert!((r.acc[axis] + a).abs() < 1e-12);
        }
    }

    #[test]
    fn reference_rests_at_every_point_within_its_bounds_and_is_continuous() {
        let cfg = route_cfg(|_| {}).unwrap();
        let (speed, accel) = (8.0, 1.5);
        let segs = schedule(&cfg.context()).unwrap();
        let tr = Trajectory::new(&cfg.context());
        // At rest at each point on arrival, exactly.
        for s in &segs {
            let r = tr.at(s.arrival, &mut 0);
            assert_eq!(r.pos, cfg.trajectory.route[s.to], "{}", s.name);
            assert_eq!((r.vel, r.acc), ([0.0; 3], [0.0; 3]), "{}", s.name);
            if s.kind == SegmentKind::Leg {
                // ... and not before: the summary's arrival is the reference's.
                let r = tr.at(s.arrival - 0.05, &mut 0);
                assert!(norm(r.vel) > 0.0, "{}", s.name);
            }
        }
        // Dense sampling: |v| <= V and |a| <= A (to 1e-12 relative: rounding of the closed
        // form), and the steps between samples bounded as continuity demands: |dv| <= A h,
        // |da| <= max jerk * h (max jerk = pi A / T, T the shortest ramp).
        let h = 1e-4;
        let ramp = segs
            .iter()
            .filter(|s| s.kind == SegmentKind::Leg)
            .map(|s| s.profile.ramp)
            .fold(f64::INFINITY, f64::min);
        let jerk = PI * accel / ramp;
        let mut seg = 0;
        let mut prev: Option<Reference> = None;
        let steps = (80.0 / h) as usize;
        for k in 0..=steps {
            let r = tr.at(k as f64 * h, &mut seg);
            assert!(norm(r.vel) <= speed * (1.0 + 1e-12), "t {}", k as f64 * h);
            assert!(norm(r.acc) <= accel * (1.0 + 1e-12), "t {}", k as f64 * h);
            if let Some(p) = prev {
                let dv = norm([
                    r.vel[0] - p.vel[0],
                    r.vel[1] - p.vel[1],
                    r.vel[2] - p.vel[2],
                ]);
                let da = norm([
                    r.acc[0] - p.acc[0],
                    r.acc[1] - p.acc[1],
                    r.acc[2] - p.acc[2],
                ]);
                assert!(
                    dv <= accel * h * (1.0 + 1e-9),
                    "velocity jumps at t {}",
                    k as f64 * h
                );
                assert!(
                    da <= jerk * h * (1.0 + 1e-6),
                    "acceleration jumps at t {}",
                    k as f64 * h
                );
            }
            prev = Some(r);
        }
        // Derivatives agree with finite differences of the position.
        for t in [3.0, 9.7, 20.0, 44.4, 57.0] {
            let (a, b, c) = (
                tr.at(t - 1e-5, &mut 0),
                tr.at(t + 1e-5, &mut 0),
                tr.at(t, &mut 0),
            );
            for k in 0..3 {
                assert!(((b.pos[k] - a.pos[k]) / 2e-5 - c.vel[k]).abs() < 1e-6);
                assert!(((b.vel[k] - a.vel[k]) / 2e-5 - c.acc[k]).abs() < 1e-6);
            }
            assert_eq!((c.psi, c.psi_dot, c.psi_ddot), (0.0, 0.0, 0.0));
        }
    }

    #[test]
    fn leg_phases_cover_the_flight_without_gaps() {
        let cfg = route_cfg(|_| {}).unwrap();
        let names: Vec<&str> = cfg.phases.iter().map(|p| p.name.as_str()).collect();
        assert_eq!(names, ["hold1", "leg1", "leg2", "leg3", "hold4"]);
        assert_eq!(cfg.phases[0].start, 0.0);
        assert_eq!(cfg.phases.last().unwrap().end, cfg.integrator.duration);
        for w in cfg.phases.windows(2) {
            assert_eq!(w[0].end, w[1].start);
        }
        // On the step grid: consecutive phases share their boundary sample, the last ends on
        // the last step, and the whole-flight phase follows.
        let steps = phase_steps(&cfg.context());
        assert_eq!(steps.len(), cfg.phases.len() + 1);
        for w in steps[..cfg.phases.len()].windows(2) {
            assert_eq!(w[0].last, w[1].first);
        }
        assert_eq!(steps[cfg.phases.len() - 1].last, cfg.steps());
        assert_eq!(
            (steps.last().unwrap().first, steps.last().unwrap().last),
            (0, cfg.steps())
        );
        // A last hold of 0 s with time left over: the remainder is a hold at the last point;
        // names replace the defaults.
        let cfg = route_cfg(|c| {
            c["trajectory"]["hold"] = json!([0, 0, 0, 0]);
            c["trajectory"]["names"] = json!(["climb", "transit", "descent", "drop"]);
        })
        .unwrap();
        let names: Vec<&str> = cfg.phases.iter().map(|p| p.name.as_str()).collect();
        assert_eq!(names, ["climb", "transit", "descent", "drop"]);
        assert_eq!(cfg.phases[0].start, 0.0);
    }

    #[test]
    fn a_table_needs_two_finite_rows_checked_row_by_row() {
        let none = |_| Ok(());
        let e = rows_checked("t.rows", &[[0.0, 1.0]], "points", none).unwrap_err();
        assert_eq!(
            (e.key.as_str(), e.message.as_str()),
            ("t.rows", "t.rows needs at least two points, got 1")
        );
        let e = rows_checked("t.rows", &[[0.0, 1.0], [f64::NAN, 2.0]], "points", none).unwrap_err();
        assert_eq!(e.key, "t.rows[1][0]");
        assert_eq!(e.message, "t.rows[1][0] must be a finite number, got NaN");
        // Row 1's own check fails before row 2's numbers are read: the first problem found.
        let rows = [[0.0, 0.0], [0.0, 0.0], [f64::NAN, 0.0]];
        let repeated = |i| match i {
            1 => Err(ConfigError::new("t.rows[1]", "repeats")),
            _ => Ok(()),
        };
        assert_eq!(
            rows_checked("t.rows", &rows, "points", repeated)
                .unwrap_err()
                .key,
            "t.rows[1]"
        );
        let e = route_cfg(|c| c["trajectory"]["route"] = json!([[0, 0, 0]])).unwrap_err();
        assert_eq!(
            e.message,
            "trajectory.route needs at least two points [x, y, z], got 1"
        );
        let mut paper = crate::scenario::tests::paper();
        paper.trajectory.waypoints.truncate(1);
        assert_eq!(
            paper.validate().unwrap_err().message,
            "trajectory.waypoints needs at least two waypoints (t, x, y, z, psi), got 1"
        );
    }

    #[test]
    fn unflyable_routes_name_their_key() {
        let key = |edit: fn(&mut serde_json::Value)| route_cfg(edit).unwrap_err().key;
        assert_eq!(
            key(|c| c["trajectory"]["speed"] = json!(0.0)),
            "trajectory.speed"
        );
        assert_eq!(
            key(|c| c["trajectory"]["acceleration"] = json!(-1.0)),
            "trajectory.acceleration"
        );
        // Subnormal: positive, but the leg would never end.
        assert_eq!(
            key(|c| c["trajectory"]["speed"] = json!(5e-324)),
            "trajectory.speed"
        );
        // ... or ends after the flight: the message names what sets the route's time.
        let e = route_cfg(|c| c["trajectory"]["acceleration"] = json!(5e-324)).unwrap_err();
        assert!(
            e.message.contains("trajectory.acceleration = 5e-324"),
            "{e}"
        );
        let e = route_cfg(|c| {
            c["trajectory"].as_object_mut().unwrap().remove("speed");
        })
        .unwrap_err();
        assert_eq!(
            e.message,
            "trajectory.speed must be given for a route, got none"
        );
        let e = route_cfg(|c| {
            c["trajectory"]["route"] = json!([[0, 0, 0], [0, 0, 10], [0, 0, 10], [5, 0, 10]]);
        })
        .unwrap_err();
        assert_eq!(e.key, "trajectory.route[2]");
        assert!(e.message.contains("repeats the previous point"), "{e}");
        assert_eq!(
            key(|c| c["trajectory"]["route"] = json!([[0, 0, 0]])),
            "trajectory.route"
        );
        assert_eq!(
            key(|c| c["trajectory"]["hold"] = json!([1.0])),
            "trajectory.hold"
        );
        assert_eq!(
            key(|c| c["trajectory"]["hold"] = json!([1.0, -1.0, 0.0, 0.0])),
            "trajectory.hold[1]"
        );
        assert_eq!(
            key(|c| c["trajectory"]["hold"] = json!([1.0, 0.0005, 0.0, 0.0])),
            "trajectory.hold[1]"
        );
        let e = route_cfg(|c| c["integrator"]["duration"] = json!(40.0)).unwrap_err();
        assert_eq!(e.key, "integrator.duration");
        assert!(e.message.contains("must cover the route"), "{e}");
        assert_eq!(
            key(|c| c["trajectory"]["names"] = json!(["a"])),
            "trajectory.names"
        );
        assert_eq!(
            key(|c| c["trajectory"]["names"] = json!(["a", "b", "a", "c", "d"])),
            "trajectory.names[2]"
        );
        assert_eq!(
            key(|c| c["trajectory"]["waypoints"] = json!([[0, 0, 0, 2, 0], [1, 0, 0, 0, 0]])),
            "trajectory.waypoints"
        );
        // Route keys outside a route, and "legs" without one.
        let e = Config::from_json(&{
            let mut v = paper_value();
            v["trajectory"]["speed"] = json!(3.0);
            v.to_string()
        })
        .unwrap_err();
        assert_eq!(e.key, "trajectory.speed");
        let e = Config::from_json(&{
            let mut v = paper_value();
            v["phases"] = json!("legs");
            v.to_string()
        })
        .unwrap_err();
        assert_eq!(e.key, "phases");
        let e = Config::from_json(&{
            let mut v = paper_value();
            v["phases"][0]["name"] = json!("flight");
            v.to_string()
        })
        .unwrap_err();
        assert_eq!(e.key, "phases[0].name");
    }

    #[test]
    fn long_routes_validate_in_one_pass_with_short_messages() {
        let points = 20_000;
        let long = |names: usize| {
            route_cfg(move |c| {
                let route: Vec<[f64; 3]> = (0..points).map(|i| [i as f64, 0.0, 10.0]).collect();
                c["trajectory"]["route"] = json!(route);
                c["trajectory"]["hold"] = json!(Vec::<f64>::new());
                c["trajectory"]["speed"] = json!(20.0);
                c["trajectory"]["acceleration"] = json!(100.0);
                c["integrator"]["dt"] = json!(0.01);
                c["integrator"]["duration"] = json!(1e5);
                let names: Vec<String> = (0..names).map(|i| format!("n{i}")).collect();
                c["trajectory"]["names"] = json!(names);
            })
        };
        // One name per leg and the final hold: unique names checked in linear time.
        let cfg = long(points).expect("a long named route");
        assert_eq!(cfg.phases.len(), points);
        let e = long(points - 1).unwrap_err();
        assert_eq!(e.key, "trajectory.names");
        assert!(e.message.len() < 300, "{} characters", e.message.len());
        assert!(e.message.contains("more"), "{e}");
        let e =
            route_cfg(|c| c["trajectory"]["names"] = json!(["a", " ", "b", "c", "d"])).unwrap_err();
        assert_eq!(
            (e.key.as_str(), e.message.as_str()),
            (
                "trajectory.names[1]",
                "trajectory.names[1] must not be blank, got \" \""
            )
        );
    }
}
