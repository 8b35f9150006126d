//! Dotted scenario keys (`"vehicle.inertia[2]"`) read as typed fields of `Config`: the numbers
//! a dispersion, a sweep or an optimisation may set, without going through text or JSON.

use super::{Config, ConfigError, GustAirspeed, GustAltitude, Interpolation};

/// One step of a dotted key: a table field or an array index.
#[derive(Debug, Clone, PartialEq)]
pub enum Seg {
    Field(String),
    Index(usize),
}

/// `"vehicle.inertia[2]"` -> [Field vehicle, Field inertia, Index 2].
pub fn parse_key(key: &str) -> Option<Vec<Seg>> {
    let mut out = Vec::new();
    for part in key.split('.') {
        let (name, mut rest) = part.split_at(part.find('[').unwrap_or(part.len()));
        let valid_name = name
            .chars()
            .next()
            .is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
            && name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_');
        if !valid_name {
            return None;
        }
        out.push(Seg::Field(name.to_string()));
        while !rest.is_empty() {
            let close = rest.find(']')?;
            if !rest.starts_with('[') {
                return None;
            }
            out.push(Seg::Index(rest[1..close].parse().ok()?));
            rest = &rest[close + 1..];
        }
    }
    Some(out)
}

/// What a parsed key names in a scenario.
pub enum Target<'c> {
    /// A number (an optional one that is set counts; one that is unset does not exist).
    Number(&'c mut f64),
    /// A key that exists but holds no number (a flag, a name, a list of names).
    NotNumber,
    /// No such key in this scenario.
    Missing,
}

/// Key prefixes that cannot carry a per-realisation value: they change the step grid, the
/// phases, the reference every lane shares or the spectrum grid, or they are the table itself.
pub const FIXED_PREFIXES: [&str; 5] = [
    "integrator",
    "phases",
    "trajectory",
    "metrics",
    "dispersions",
];

pub(crate) fn at3<'c>(a: &'c mut [f64; 3], rest: &[Seg]) -> Target<'c> {
    match rest {
        [Seg::Index(i)] if *i < 3 => Target::Number(&mut a[*i]),
        [] => Target::NotNumber,
        _ => Target::Missing,
    }
}

pub(crate) fn one<'c>(x: &'c mut f64, rest: &[Seg]) -> Target<'c> {
    if rest.is_empty() {
        Target::Number(x)
    } else {
        Target::Missing
    }
}

fn optional<'c>(x: &'c mut Option<f64>, rest: &[Seg]) -> Target<'c> {
    match x {
        Some(x) => one(x, rest),
        None => Target::Missing,
    }
}

pub(crate) fn flag(rest: &[Seg]) -> Target<'static> {
    if rest.is_empty() {
        Target::NotNumber
    } else {
        Target::Missing
    }
}

impl Config {
    /// The field a parsed key names (see [`Target`]). Keys under `FIXED_PREFIXES` are found
    /// like any other; callers refuse them where a key must be per realisation.
    pub fn target(&mut self, path: &[Seg]) -> Target<'_> {
        let field = |i: usize| match path.get(i) {
            Some(Seg::Field(f)) => f.as_str(),
            _ => "",
        };
        let rest = path.get(2..).unwrap_or(&[]);
        match (field(0), field(1)) {
            ("vehicle", f) => {
                let v = &mut self.vehicle;
                match f {
                    "mass" => one(&mut v.mass, rest),
                    "inertia" => at3(&mut v.inertia, rest),
                    "inertia_error" => at3(&mut v.inertia_error, rest),
                    "arm_length" => one(&mut v.arm_length, rest),
                    "drag_area" => one(&mut v.drag_area, rest),
                    "lateral_drag_area" => one(&mut v.lateral_drag_area, rest),
                    _ => Target::Missing,
                }
            }
            ("payload", f) => {
                let p = &mut self.payload;
                match f {
                    "model" => flag(rest),
                    "mass" => one(&mut p.mass, rest),
                    "natural_frequency" => optional(&mut p.natural_frequency, rest),
                    "stiffness" => optional(&mut p.stiffness, rest),
                    "damping" => one(&mut p.damping, rest),
                    "drag_area" => one(&mut p.drag_area, rest),
                    "cable_length" => optional(&mut p.cable_length, rest),
                    "attachment_offset" => optional(&mut p.attachment_offset, rest),
                    _ => Target::Missing,
                }
            }
            ("environment", "gravity") => one(&mut self.environment.gravity, rest),
            ("initial", "position") => at3(&mut self.initial.position, rest),
            ("initial", "attitude") => at3(&mut self.initial.attitude, rest),
            ("controller", _) => self.controller.target(&path[1..]),
            ("actuator", f) => {
                let a = &mut self.actuator;
                match f {
                    "model" | "layout" => flag(rest),
                    "thrust_coefficient" => one(&mut a.thrust_coefficient, rest),
                    "torque_ratio" => one(&mut a.torque_ratio, rest),
                    "time_constant" => one(&mut a.time_constant, rest),
                    "thrust_min" => one(&mut a.thrust_min, rest),
                    "thrust_max" => one(&mut a.thrust_max, rest),
                    "battery_sag" => one(&mut a.battery_sag, rest),
                    "faults" => match rest {
                        [] => Target::NotNumber,
                        [Seg::Index(i), tail @ ..] if *i < a.faults.len() => match tail {
                            [] => Target::NotNumber,
                            [Seg::Field(f), sub @ ..] => {
                                crate::config::params::Params::target(&mut a.faults[*i], f, sub)
                            }
                            _ => Target::Missing,
                        },
                        _ => Target::Missing,
                    },
                    _ => Target::Missing,
                }
            }
            ("gust", f) => {
                let g = &mut self.gust;
                match f {
                    "enabled" | "model" => flag(rest),
                    "components" => match rest {
                        [] => Target::NotNumber,
                        [Seg::Index(i)] if *i < g.components.len() => Target::NotNumber,
                        _ => Target::Missing,
                    },
                    "start" => one(&mut g.start, rest),
                    "end" => one(&mut g.end, rest),
                    "altitude" => match &mut g.altitude {
                        GustAltitude::Fixed(h) => one(h, rest),
                        GustAltitude::Vehicle => flag(rest),
                    },
                    "w20" => optional(&mut g.w20, rest),
                    "intensity" if g.intensity.is_some() => flag(rest),
                    "airspeed" => match &mut g.airspeed {
                        GustAirspeed::Fixed(v) => one(v, rest),
                        GustAirspeed::Relative => flag(rest),
                    },
                    "min_airspeed" => one(&mut g.min_airspeed, rest),
                    "air_density" => one(&mut g.air_density, rest),
                    "mean_wind" => at3(&mut g.mean_wind, rest),
                    _ => Target::Missing,
                }
            }
            // Each wind source reads its own keys (`WindSource::target`).
            ("wind", f) => crate::gust::AnySource::target(&mut self.wind, f, rest),
            ("divergence", f) => {
                let d = &mut self.divergence;
                match f {
                    "max_distance" => one(&mut d.max_distance, rest),
                    "max_tilt" => one(&mut d.max_tilt, rest),
                    "max_speed" => one(&mut d.max_speed, rest),
                    "max_rate" => one(&mut d.max_rate, rest),
                    _ => Target::Missing,
                }
            }
            ("ground", "altitude") => one(&mut self.ground.altitude, rest),
            ("ground", "enabled") => Target::NotNumber,
            _ => Target::Missing,
        }
    }

    /// The parsed path of `key` if it names a number that may differ between the realisations
    /// of a batch, or an error under `dispersions.<key>` saying why not.
    pub fn per_realisation_key(&self, key: &str) -> Result<Vec<Seg>, ConfigError> {
        let err = |why: &str| ConfigError {
            key: format!("dispersions.{key}"),
            message: format!("dispersions: {key:?} {why}"),
        };
        let path = parse_key(key).ok_or_else(|| err("is not a dotted scenario key"))?;
        if let Some(Seg::Field(first)) = path.first() {
            if FIXED_PREFIXES.contains(&first.as_str()) {
                return Err(err(&format!(
                    "cannot be dispersed: {first}.* fixes the step grid, phases, reference or \
                     spectrum grid that every realisation of a batch shares"
                )));
            }
        }
        // A min-jerk reference starts from the initial state, and a batch's lanes share one
        // reference: a drawn start would fly the nominal start's reference.
        if self.trajectory.interpolation == Interpolation::MinJerk
            && matches!(path.first(), Some(Seg::Field(f)) if f == "initial")
        {
            return Err(err(
                "cannot be dispersed with trajectory.interpolation = \"min_jerk\": the \
                 reference starts from the initial state, which every realisation of a batch \
                 shares (disperse it with \"step\" or \"route\")",
            ));
        }
        match self.clone().target(&path) {
            Target::Number(_) => Ok(path),
            Target::NotNumber => Err(err("is not a number (only numeric keys can be dispersed)")),
            Target::Missing => Err(err("is not a key of this scenario")),
        }
    }

    /// Set the number at `path` (a path `per_realisation_key` accepted).
    pub fn set_number(&mut self, path: &[Seg], value: f64) -> bool {
        match self.target(path) {
            Target::Number(x) => {
                *x = value;
                true
            }
            _ => false,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::tests::paper;

    #[test]
    fn keys_parse_with_indices() {
        assert_eq!(
            parse_key("vehicle.inertia[2]"),
            Some(vec![
                Seg::Field("vehicle".into()),
                Seg::Field("inertia".into()),
                Seg::Index(2)
            ])
        );
        for bad in ["", "a..b", "a[", "a[x]", "a]b", "1a", "a[1]b"] {
            assert_eq!(parse_key(bad), None, "{bad:?}");
        }
    }

    /// Every number of the paper preset's JSON form is a typed target, and nothing else is:
    /// the typed keys and the serialised scenario agree key for key.
    #[test]
    fn every_number_in_the_scenario_is_a_typed_key() {
        fn leaves(v: &serde_json::Value, path: String, out: &mut Vec<(String, bool)>) {
            match v {
                serde_json::Value::Object(m) => {
                    for (k, x) in m {
                        let p = if path.is_empty() {
                            k.clone()
                        } else {
                            format!("{path}.{k}")
                        };
                        leaves(x, p, out);
                    }
                }
                serde_json::Value::Array(a) if a.iter().all(|x| x.is_number()) && a.len() == 3 => {
                    for (i, x) in a.iter().enumerate() {
                        leaves(x, format!("{path}[{i}]"), out);
                    }
                }
                other => out.push((path, other.is_number())),
            }
        }
        let cfg = paper();
        let mut out = Vec::new();
        leaves(
            &serde_json::to_value(&cfg).unwrap(),
            String::new(),
            &mut out,
        );
        let mut numbers = 0;
        for (key, is_number) in out {
            let path = parse_key(&key).unwrap_or_default();
            let fixed = FIXED_PREFIXES.iter().any(|p| key.starts_with(p));
            if fixed || path.is_empty() {
                continue;
            }
            let mut c = cfg.clone();
            match (c.target(&path), is_number) {
                (Target::Number(_), true) => numbers += 1,
                (Target::NotNumber, false) => {}
                (_, n) => panic!("{key}: typed target disagrees with the JSON (number: {n})"),
            }
        }
        assert!(numbers > 50, "{numbers}");
    }

    #[test]
    fn only_numeric_keys_off_the_grid_are_per_realisation() {
        let cfg = paper();
        assert!(cfg.per_realisation_key("payload.mass").is_ok());
        assert!(cfg.per_realisation_key("vehicle.inertia[2]").is_ok());
        for (key, says) in [
            ("integrator.dt", "cannot be dispersed"),
            ("phases[1].end", "cannot be dispersed"),
            ("trajectory.waypoints[1][0]", "cannot be dispersed"),
            ("payload.massive", "not a key"),
            ("vehicle.inertia[3]", "not a key"),
            ("gust.enabled", "not a number"),
            ("payload.stiffness", "not a key"),
            ("controller.thrust_max", "not a key"),
        ] {
            let e = cfg.per_realisation_key(key).unwrap_err();
            assert!(e.message.contains(says) && e.message.contains(key), "{e:?}");
        }
    }

    #[test]
    fn fault_keys_are_per_realisation_numbers() {
        use crate::config::{ActuatorModelName, RotorFault};
        let mut cfg = paper();
        cfg.actuator.model = ActuatorModelName::Rotors;
        cfg.actuator.faults = vec![RotorFault {
            rotor: 2,
            start: 1.0,
            thrust_fraction: 0.8,
        }];
        for key in [
            "actuator.faults[0].start",
            "actuator.faults[0].thrust_fraction",
            "actuator.battery_sag",
        ] {
            let path = cfg.per_realisation_key(key).unwrap();
            let mut c = cfg.clone();
            assert!(c.set_number(&path, 0.25), "{key}");
            assert_ne!(c.to_json(), cfg.to_json(), "{key}");
        }
        for (key, says) in [
            ("actuator.faults[0].rotor", "not a number"),
            ("actuator.faults", "not a number"),
            ("actuator.faults[0]", "not a number"),
            ("actuator.faults[1].start", "not a key"),
            ("actuator.faults[0].stop", "not a key"),
        ] {
            let e = cfg.per_realisation_key(key).unwrap_err();
            assert!(e.message.contains(says), "{key}: {e:?}");
        }
    }

    #[test]
    fn wind_keys_are_per_realisation_numbers() {
        use crate::config::{DiscreteGust, GustAltitude, GustShape, Intensity};
        let mut cfg = paper();
        cfg.wind.speed = 3.0;
        cfg.wind.gusts = vec![DiscreteGust {
            start: 1.0,
            duration: 2.0,
            amplitude: [0.0, 0.0, 1.0],
            shape: GustShape::Pulse,
        }];
        for key in [
            "wind.speed",
            "wind.heading",
            "wind.roughness",
            "wind.gusts[0].start",
            "wind.gusts[0].duration",
            "wind.gusts[0].amplitude[2]",
            "gust.min_airspeed",
            "gust.altitude",
            "gust.w20",
        ] {
            let path = cfg.per_realisation_key(key).unwrap();
            let mut c = cfg.clone();
            assert!(c.set_number(&path, 0.25), "{key}");
            assert_ne!(c.to_json(), cfg.to_json(), "{key}");
        }
        cfg.gust.altitude = GustAltitude::Vehicle;
        cfg.gust.w20 = None;
        cfg.gust.intensity = Some(Intensity::Light);
        for (key, says) in [
            ("wind.shear", "not a number"),
            ("wind.gusts[0].shape", "not a number"),
            ("wind.gusts", "not a number"),
            ("wind.gusts[1].start", "not a key"),
            ("wind.gusts[0].colour", "not a key"),
            ("gust.altitude", "not a number"),
            ("gust.intensity", "not a number"),
            ("gust.w20", "not a key"),
        ] {
            let e = cfg.per_realisation_key(key).unwrap_err();
            assert!(e.message.contains(says), "{key}: {e:?}");
        }
    }
}
