//! Dotted scenario keys (`"vehicle.inertia[2]"`) read as typed fields of `Config`: the numbers
//! a dispersion, a sweep or an optimisation may set, without going through text or JSON (the
//! keys' parsing is `config::keys`; each section and kind finds its own fields).

use super::Config;
use crate::config::keys::{parse_key, Seg, Target, FIXED_PREFIXES, SCHEDULE_KEYS};
use crate::config::params::{self, Params};
use crate::config::{ConfigError, Interpolation};

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
            ("vehicle", f) => self.vehicle.target(f, rest),
            ("payload", f) => self.payload.target(f, rest),
            ("environment", f) => self.environment.target(f, rest),
            ("initial", f) => self.initial.target(f, rest),
            ("controller", _) => self.controller.target(&path[1..]),
            ("actuator", f) => self.actuator.target(f, rest),
            ("trajectory", f) => self.trajectory.target(f, rest),
            ("phases", _) => params::Field::target(&mut self.phases, &path[1..]),
            ("gust", f) => self.gust.target(f, rest),
            // Each wind source reads its own keys (`WindSource::target`).
            ("wind", f) => crate::gust::AnySource::target(&mut self.wind, f, rest),
            ("integrator", f) => self.integrator.target(f, rest),
            ("metrics", f) => self.metrics.target(f, rest),
            ("divergence", f) => self.divergence.target(f, rest),
            ("ground", f) => self.ground.target(f, rest),
            ("volume", f) => self.volume.target(f, rest),
            ("navigation", f) => self.navigation.target(f, rest),
            ("sensors", f) => self.sensors.target(f, rest),
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
        if SCHEDULE_KEYS.contains(&key) {
            return Err(err(
                "cannot be dispersed: the loops' rates fix the steps at which every realisation \
                 of a batch updates its laws and its wind",
            ));
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
    use crate::scenario::tests::{assert_refused, assert_settable, paper};

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

    /// The paper and delivery presets, as the engine reads them.
    fn presets() -> Vec<Config> {
        let delivery = crate::scenario::tests::delivery_value();
        let delivery = Config::from_json(&delivery.to_string()).expect("delivery is valid");
        vec![paper(), delivery]
    }

    /// `leaves` of the scenario `cfg`'s JSON form.
    fn config_leaves(cfg: &Config) -> Vec<(String, bool)> {
        let mut out = Vec::new();
        leaves(&serde_json::to_value(cfg).unwrap(), String::new(), &mut out);
        out
    }

    /// Every leaf of a scenario's JSON form as a dotted key, with whether it is a number.
    fn leaves(v: &serde_json::Value, path: String, out: &mut Vec<(String, bool)>) {
        use serde_json::Value;
        match v {
            Value::Object(m) => {
                for (k, x) in m {
                    let p = if path.is_empty() {
                        k.clone()
                    } else {
                        format!("{path}.{k}")
                    };
                    leaves(x, p, out);
                }
            }
            Value::Array(a) if !a.is_empty() && a.iter().all(|x| !x.is_string()) => {
                for (i, x) in a.iter().enumerate() {
                    leaves(x, format!("{path}[{i}]"), out);
                }
            }
            other => out.push((path, other.is_number())),
        }
    }

    /// Every number of the presets' JSON form is a typed target, and nothing else is: the typed
    /// keys and the serialised scenario agree key for key (the fixed keys too, which only a
    /// dispersion refuses).
    #[test]
    fn every_number_in_the_scenario_is_a_typed_key() {
        for cfg in presets() {
            let out = config_leaves(&cfg);
            let mut numbers = 0;
            for (key, is_number) in out {
                let path = parse_key(&key).unwrap();
                let mut c = cfg.clone();
                match (c.target(&path), is_number) {
                    (Target::Number(_), true) => numbers += 1,
                    (Target::NotNumber, false) => {}
                    (_, n) => panic!("{key}: typed target disagrees with the JSON (number: {n})"),
                }
            }
            assert!(numbers > 50, "{numbers}");
        }
    }

    /// Every key of the presets' JSON form (indices dropped) is declared with a unit and a label
    /// (`Config::keys`, `_core.KEY_UNITS`), the wind sources' included.
    #[test]
    fn every_key_in_the_scenario_is_declared() {
        let declared: std::collections::HashMap<String, crate::config::params::Key> =
            Config::keys().into_iter().collect();
        assert_eq!(declared.len(), Config::keys().len(), "a key declared twice");
        let mut found = 0;
        for cfg in presets() {
            let out = config_leaves(&cfg);
            for (key, _) in out {
                let mut bare = String::new();
                for seg in parse_key(&key).unwrap() {
                    if let Seg::Field(f) = seg {
                        if !bare.is_empty() {
                            bare.push('.');
                        }
                        bare.push_str(&f);
                    }
                }
                let k = declared
                    .get(&bare)
                    .unwrap_or_else(|| panic!("{bare} is not declared"));
                assert!(!k.unit.is_empty() && !k.label.is_empty(), "{bare}");
                found += 1;
            }
        }
        assert!(found > 100, "{found}");
        for (key, k) in &declared {
            assert!(
                !k.unit.trim().is_empty() && !k.label.trim().is_empty(),
                "{key}"
            );
        }
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
        use crate::scenario::{ActuatorKind, RotorFault};
        let mut cfg = paper();
        cfg.actuator.model = ActuatorKind::Rotors;
        cfg.actuator.rotors.faults = vec![RotorFault {
            rotor: 2,
            start: 1.0,
            thrust_fraction: 0.8,
        }];
        assert_settable(
            &cfg,
            &[
                "actuator.faults[0].start",
                "actuator.faults[0].thrust_fraction",
                "actuator.battery_sag",
            ],
        );
        assert_refused(
            &cfg,
            &[
                ("actuator.faults[0].rotor", "not a number"),
                ("actuator.faults", "not a number"),
                ("actuator.faults[0]", "not a number"),
                ("actuator.faults[1].start", "not a key"),
                ("actuator.faults[0].stop", "not a key"),
            ],
        );
    }

    #[test]
    fn wind_keys_are_per_realisation_numbers() {
        use crate::gust::table::{TableBy, WindTable};
        use crate::scenario::{DiscreteGust, GustAltitude, GustShape, Intensity};
        let mut cfg = paper();
        cfg.wind.table = Some(WindTable {
            by: TableBy::Time,
            points: vec![[0.0, 1.0, 0.0, 0.0], [5.0, 2.0, 0.0, 0.0]],
        });
        cfg.wind.speed = 3.0;
        cfg.wind.gusts = vec![DiscreteGust {
            start: 1.0,
            duration: 2.0,
            amplitude: [0.0, 0.0, 1.0],
            shape: GustShape::Pulse,
        }];
        assert_settable(
            &cfg,
            &[
                "wind.speed",
                "wind.heading",
                "wind.roughness",
                "wind.gusts[0].start",
                "wind.gusts[0].duration",
                "wind.gusts[0].amplitude[2]",
                "wind.table.points[1][3]",
                "gust.min_airspeed",
                "gust.altitude",
                "gust.w20",
            ],
        );
        cfg.gust.altitude = GustAltitude::Vehicle;
        cfg.gust.w20 = None;
        cfg.gust.intensity = Some(Intensity::Light);
        assert_refused(
            &cfg,
            &[
                ("wind.shear", "not a number"),
                ("wind.gusts[0].shape", "not a number"),
                ("wind.gusts", "not a number"),
                ("wind.gusts[1].start", "not a key"),
                ("wind.gusts[0].colour", "not a key"),
                ("wind.gusts[0].amplitude[3]", "not a key"),
                ("wind.table", "not a number"),
                ("wind.table.by", "not a number"),
                ("wind.table.points", "not a number"),
                ("wind.table.points[1]", "not a number"),
                ("wind.table.points[2][0]", "not a key"),
                ("wind.table.points[0][4]", "not a key"),
                ("wind.table.rows", "not a key"),
                ("gust.altitude", "not a number"),
                ("gust.intensity", "not a number"),
                ("gust.w20", "not a key"),
            ],
        );
    }
}
