//! `[trajectory]` and `phases`: the reference the vehicle flies (waypoints, a min-jerk move or
//! a route, whose schedule is `route`) and the time windows the metrics are taken over, with
//! their checks (the reference itself is `crate::trajectory`).

use super::params::{not_numbers, params, Key, Params};
use super::{finite, non_negative, route, rows_checked, ConfigError, Context, Integrator};
use serde::{Deserialize, Serialize};

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Interpolation {
    Step,
    MinJerk,
    /// Straight legs between `trajectory.route` points, rest to rest (docs/model.md, "Routes").
    Route,
}

not_numbers!(Interpolation);

params! {
    pub struct Trajectory {
        interpolation: Interpolation => "-", "Reference interpolation";
        /// Rows of (t s, x m, y m, z m, psi rad), times strictly increasing (step and min-jerk;
        /// absent for a route).
        #[serde(default, skip_serializing_if = "Vec::is_empty")]
        waypoints: Vec<[f64; 5]> => "[s, m, m, m, rad]", "Waypoints (t, x, y, z, yaw)";
        /// s, min-jerk only: each move toward a waypoint starts at its time and lasts this long
        /// (or up to the next waypoint's time if that comes sooner).
        #[serde(default = "default_transition")]
        transition: f64 => "s", "Min-jerk move duration";
        /// Route only: the points [x, y, z] (m) flown in straight legs, in order.
        #[serde(default, skip_serializing_if = "Vec::is_empty")]
        route: Vec<[f64; 3]> => "[m, m, m]", "Route points (x, y, z)";
        /// Route only: m/s, the cruise speed of every leg long enough to reach it.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        speed: Option<f64> => "m/s", "Route cruise speed";
        /// Route only: m/s^2, the bound on the reference's acceleration along a leg.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        acceleration: Option<f64> => "m/s^2", "Route acceleration bound";
        /// Route only: s, the hover at each point after its lowering and retract (one per point;
        /// empty: no holds).
        #[serde(default, skip_serializing_if = "Vec::is_empty")]
        hold: Vec<f64> => "s", "Hover at each route point";
        /// Route only: s, the hover on arrival at each point before its lowering, retract and
        /// `hold` (one per point; empty: none): a `.plan` waypoint's hold, which PX4 flies
        /// before the waypoint's items.
        #[serde(default, skip_serializing_if = "Vec::is_empty")]
        arrival_hold: Vec<f64> => "s", "Hover on arrival at each route point, before its lowering";
        /// Route only: m, the line the winch pays out at each point (one per point; 0 or empty:
        /// none): on arrival the vehicle hovers while the parcel is lowered, then holds.
        #[serde(default, skip_serializing_if = "Vec::is_empty")]
        lower: Vec<f64> => "m", "Line lowered at each route point";
        /// Route only: m/s, each point's lowering's own pay-out speed (a `.plan`'s DO_WINCH
        /// rate; one per point; 0 or empty: `payload.winch_speed`).
        #[serde(default, skip_serializing_if = "Vec::is_empty")]
        lower_speed: Vec<f64> => "m/s", "Pay-out speed of each point's lowering";
        /// Route only: after each point's lowering (true), the winch reels the line in with
        /// the parcel still on the hook (a `.plan`'s DO_WINCH retract before its release).
        #[serde(default, skip_serializing_if = "Vec::is_empty")]
        retract: Vec<bool> => "-", "Line reeled in at each route point";
        /// Route only: the names of the route's segments (holds and legs, in time order) in place
        /// of leg1, hold2, ...; empty: those defaults.
        #[serde(default, skip_serializing_if = "Vec::is_empty")]
        names: Vec<String> => "-", "Names of the route's segments";
    }
}

impl Trajectory {
    /// The reference's points (m): the waypoints' positions, or the route.
    pub fn points(&self) -> Vec<[f64; 3]> {
        if self.interpolation == Interpolation::Route {
            self.route.clone()
        } else {
            self.waypoints.iter().map(|w| [w[1], w[2], w[3]]).collect()
        }
    }
}

/// s, the default min-jerk move duration: a 2 m climb peaks at 0.75 m/s and 0.46 m/s^2.
pub fn default_transition() -> f64 {
    5.0
}

params! {
    pub struct Phase {
        name: String => "-", "Phase name";
        /// s, inclusive.
        start: f64 => "s", "Phase start";
        /// s, inclusive.
        end: f64 => "s", "Phase end";
    }
}

/// `phases = "legs"`: one phase per leg and hold of the route (docs/model.md, "Routes").
pub const LEGS: &str = "legs";

/// `phases` itself: a list of `[[phases]]` tables, or `"legs"`.
const PHASES: Key = Key {
    name: "phases",
    unit: "-",
    label: "Metric windows, or \"legs\": one per leg and hold of the route",
};

impl Phase {
    /// `phases` and its entries' keys with their units and labels (dotted, indices dropped).
    pub fn keys() -> Vec<(String, Key)> {
        let mut keys = vec![(PHASES.name.to_string(), PHASES)];
        keys.extend(Self::keys_under(PHASES.name));
        keys
    }
}

impl Trajectory {
    /// Check every value (the route's through `route::validate`); the first problem found is
    /// returned with its key.
    pub fn validate(&self, cfg: &Context) -> Result<(), ConfigError> {
        route::validate(cfg)?;
        let tr = self.transition;
        if !(tr.is_finite() && tr >= 0.0) {
            return Err(ConfigError::new(
                "trajectory.transition",
                format!("trajectory.transition must be a finite number >= 0 (s), got {tr:?}"),
            ));
        }
        if self.interpolation == Interpolation::Route {
            return Ok(());
        }
        let w = &self.waypoints;
        // Each waypoint's time after the previous one's.
        let later = |i: usize| {
            if i > 0 && w[i][0] <= w[i - 1][0] {
                let key = format!("trajectory.waypoints[{i}][0]");
                return Err(ConfigError::new(
                    &key,
                    format!(
                        "{key} (time) must be later than the previous waypoint's ({:?} s), got {:?}",
                        w[i - 1][0], w[i][0]
                    ),
                ));
            }
            Ok(())
        };
        rows_checked(
            "trajectory.waypoints",
            w,
            "waypoints (t, x, y, z, psi)",
            later,
        )
    }
}

/// `phases`: at least one, each named (uniquely, and not the whole flight's name), inside the
/// flight and at least two steps long.
pub fn validate_phases(phases: &[Phase], integrator: &Integrator) -> Result<(), ConfigError> {
    let dur = integrator.duration;
    if phases.is_empty() {
        return Err(ConfigError::new(
            "phases",
            "phases must name at least one time window, got none",
        ));
    }
    let mut seen = std::collections::HashSet::with_capacity(phases.len());
    for (i, ph) in phases.iter().enumerate() {
        if ph.name.trim().is_empty() {
            return Err(ConfigError::new(
                format!("phases[{i}].name"),
                format!("phases[{i}].name must not be empty, got {:?}", ph.name),
            ));
        }
        if ph.name == route::FLIGHT_PHASE {
            return Err(ConfigError::new(
                format!("phases[{i}].name"),
                format!(
                    "phases[{i}].name {:?} is the whole-flight phase every result has: choose another name",
                    ph.name
                ),
            ));
        }
        if !seen.insert(ph.name.as_str()) {
            return Err(ConfigError::new(
                format!("phases[{i}].name"),
                format!("phases[{i}].name must be unique, got {:?} twice", ph.name),
            ));
        }
        let k_start = format!("phases[{i}].start");
        let k_end = format!("phases[{i}].end");
        non_negative(&k_start, ph.start)?;
        finite(&k_end, ph.end)?;
        if ph.end > dur * (1.0 + 1e-12) {
            return Err(ConfigError::new(
                &k_end,
                format!(
                    "{k_end} must be within the flight (<= integrator.duration = {dur:?} s), got {:?}",
                    ph.end
                ),
            ));
        }
        if ph.end - ph.start < 2.0 * integrator.dt {
            return Err(ConfigError::new(
                &k_end,
                format!(
                    "{k_end} must be later than {k_start} by at least two steps (2 integrator.dt = {:?} s), got {:?} (start {:?})",
                    2.0 * integrator.dt, ph.end, ph.start
                ),
            ));
        }
    }
    Ok(())
}
