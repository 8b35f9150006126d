//! The scenario as the engine receives it: one plain struct, deserialised once from the
//! JSON the Python layer sends, then validated here so that every entry point of the engine
//! guards itself. Field names mirror the TOML keys, so an error names the user's key.
//!
//! The assembled scenario sits above the kinds: the sections below them are `config`'s (each
//! its own file), the kinds own their keys in their own files (the controllers' tables are
//! `control`'s; `[payload]` and `[actuator]` are one flat table each, assembled by
//! `model::kinds!` and read by `model::section`; `[wind]` is `gust::Wind`). A kind is built
//! and checked from a narrow view (`config::Context`, `gust::WindContext`,
//! `model::ModelContext`, `control::ControlContext`) that `Config` hands it, so that no kind
//! names this module. This file holds `Config`, the reading of the JSON and the order the
//! sections are checked in; `keys`, the typed targets of dotted keys.

pub mod keys;

use crate::config::keys::Seg;
pub use crate::config::navigation::{Navigation, NavigationMode, Sensors};
use crate::config::{dispersions, params, route, trajectory};
pub use crate::config::{
    BodyModel, ConfigError, Context, Dispersions, Distribution, Divergence, Environment, Ground,
    Gust, GustAirspeed, GustAltitude, GustComponent, GustModel, Initial, Integrator, Intensity,
    Interpolation, Metrics, Phase, Trajectory, Trim, Vehicle, Volume, Winch, LEGS, MAX_STEPS,
};
pub use crate::control::{ControlContext, ControllerConfig};
pub use crate::gust::gusts::{DiscreteGust, GustShape};
pub use crate::gust::steady::Shear;
pub use crate::gust::table::{TableBy, WindTable};
pub use crate::gust::{Wind, WindContext};
pub use crate::model::actuator::rotors::{RotorFault, RotorLayout, RotorParams};
pub use crate::model::{ActuatorConfig, ActuatorKind, ModelContext, PayloadConfig, PayloadKind};
use serde::{Deserialize, Serialize};

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Config {
    pub vehicle: Vehicle,
    pub payload: PayloadConfig,
    pub environment: Environment,
    pub initial: Initial,
    pub controller: ControllerConfig,
    /// How the controller's thrust and torques reach the airframe (docs/model.md section 8).
    #[serde(default = "crate::model::actuator::shared::absent")]
    pub actuator: ActuatorConfig,
    pub trajectory: Trajectory,
    pub phases: Vec<Phase>,
    pub gust: Gust,
    /// Wind over the whole flight: mean wind with shear, discrete gusts (docs/model.md).
    #[serde(default, skip_serializing_if = "Wind::is_default")]
    pub wind: Wind,
    pub integrator: Integrator,
    pub metrics: Metrics,
    pub divergence: Divergence,
    /// The ground plane a flight ends at (docs/model.md section 11); off by default.
    #[serde(default)]
    pub ground: Ground,
    /// The route's operational volume (docs/risk.md, "Containment"); none by default.
    #[serde(default, skip_serializing_if = "Volume::is_default")]
    pub volume: Volume,
    /// What the laws read: the state, or the estimate of the navigation filter
    /// (docs/model.md, "Navigation"); the state by default.
    #[serde(default, skip_serializing_if = "Navigation::is_default")]
    pub navigation: Navigation,
    /// The vehicle's sensors (read with `navigation.mode = "ekf"`).
    #[serde(default, skip_serializing_if = "Sensors::is_default")]
    pub sensors: Sensors,
    /// Uncertain parameters: dotted key -> distribution (`crate::dispersion`).
    #[serde(default, skip_serializing_if = "Dispersions::is_empty")]
    pub dispersions: Dispersions,
}

impl Config {
    /// Parse and validate the engine's JSON form of a scenario.
    pub fn from_json(text: &str) -> Result<Self, ConfigError> {
        let (mut cfg, legs) = Self::parse(text)?;
        cfg.validate()?;
        // `phases = "legs"`: the route's schedule gives the phases, once the rest is valid
        // (`parse` left a placeholder phase covering the flight).
        if legs {
            cfg.phases = route::leg_phases(&cfg.context())?;
            trajectory::validate_phases(&cfg.phases, &cfg.integrator)?;
        }
        Ok(cfg)
    }

    /// The JSON form read into a `Config`, not validated: every table given as a table (an
    /// array where a table is expected is refused, never read by position) and every
    /// fixed-length array of its length. `phases = "legs"` becomes one placeholder phase named
    /// `LEGS` over the whole flight (then the flag is true).
    fn parse(text: &str) -> Result<(Self, bool), ConfigError> {
        let mut value: serde_json::Value = serde_json::from_str(text).map_err(|e| {
            let inner = e.to_string();
            let inner = inner
                .split(" at line ")
                .next()
                .unwrap_or(&inner)
                .to_string();
            ConfigError::new("", format!("scenario: {inner}"))
        })?;
        let legs = value.get("phases").and_then(|p| p.as_str()) == Some(LEGS);
        if legs {
            let whole = value
                .pointer("/integrator/duration")
                .cloned()
                .unwrap_or(serde_json::Value::Null);
            value["phases"] = serde_json::json!([{"name": LEGS, "start": 0.0, "end": whole}]);
        }
        if let Some(key) = static_array_for_table(&value) {
            return Err(ConfigError::new(
                key.clone(),
                format!("{key} must be a table, got an array"),
            ));
        }
        let mut cfg: Config = serde_path_to_error::deserialize(&value).map_err(|e| {
            let key = e.path().to_string();
            let inner = e.inner().to_string();
            if key == "." || key.is_empty() {
                return ConfigError::new("", format!("scenario: {inner}"));
            }
            let given = at_path(&value, &key);
            let message = match given {
                // serde reads a struct from an array by position: never accept that.
                Some(serde_json::Value::Array(a)) if inner.contains("expected struct") => {
                    format!("{key} must be a table, got an array of {}", a.len())
                }
                // A fixed-length array ([x, y, z], a waypoint's 5 numbers) of another length.
                Some(serde_json::Value::Array(a)) if inner.starts_with("invalid length") => {
                    let wanted = inner
                        .rsplit("array of length ")
                        .next()
                        .and_then(|n| n.parse::<usize>().ok())
                        .unwrap_or(if key.starts_with("trajectory.waypoints") {
                            5
                        } else {
                            3
                        });
                    format!("{key} must have {wanted} numbers, got {}", a.len())
                }
                _ => format!("{key}: {inner}"),
            };
            ConfigError::new(key, message)
        })?;
        cfg.controller.fill_defaults();
        // serde also reads a table from an array silently where the fields have defaults
        // (`wind = [5.0, 2.0]`, `ground = []`): every table of the scenario must be one.
        let shape = serde_json::to_value(&cfg).expect("a Config always serialises");
        if let Some(key) = array_for_table(&value, &shape, String::new()) {
            return Err(ConfigError::new(
                key.clone(),
                format!("{key} must be a table, got an array"),
            ));
        }
        Ok((cfg, legs))
    }

    /// Every key the engine reads, with its unit and plain-English label (dotted, indices
    /// dropped: `phases.end`, `controller.pd.kp`), each declared beside its section's struct or
    /// in its kind's file: `_core.KEY_UNITS` and `_core.KEY_LABELS` (Python adds only the keys
    /// it alone reads, `quadrs.scenario.units`).
    pub fn keys() -> Vec<(String, params::Key)> {
        use params::Params;
        let mut keys = Vehicle::keys_under("vehicle");
        keys.extend(PayloadConfig::keys());
        keys.extend(Environment::keys_under("environment"));
        keys.extend(Initial::keys_under("initial"));
        keys.extend(ControllerConfig::keys());
        keys.extend(ActuatorConfig::keys());
        keys.extend(Trajectory::keys_under("trajectory"));
        keys.extend(Phase::keys());
        keys.extend(Gust::keys_under("gust"));
        keys.extend(crate::gust::AnySource::keys());
        keys.extend(Integrator::keys_under("integrator"));
        keys.extend(Metrics::keys_under("metrics"));
        keys.extend(Divergence::keys_under("divergence"));
        keys.extend(Ground::keys_under("ground"));
        keys.extend(Volume::keys_under("volume"));
        keys.extend(Navigation::keys_under("navigation"));
        keys.extend(Sensors::keys());
        keys
    }

    /// The pairs of keys that give one thing two ways (exactly one of each given), each
    /// declared beside its owner: `_core.ONE_OF_KEYS`.
    pub const ONE_OF: [crate::config::OneOf; 2] = [
        crate::model::payload::ATTACHMENT,
        crate::config::gust::TURBULENCE_LEVEL,
    ];

    pub fn to_json(&self) -> String {
        serde_json::to_string(self).expect("a Config always serialises")
    }

    /// The sections below the kinds, by reference: what every kind is built from.
    pub fn context(&self) -> Context<'_> {
        Context {
            vehicle: &self.vehicle,
            environment: &self.environment,
            initial: &self.initial,
            trajectory: &self.trajectory,
            phases: &self.phases,
            gust: &self.gust,
            integrator: &self.integrator,
            metrics: &self.metrics,
            divergence: &self.divergence,
            ground: &self.ground,
            volume: &self.volume,
            winch: Winch {
                speed: self.payload.cable.winch_speed,
                acceleration: self.payload.cable.winch_acceleration,
                approach: self
                    .payload
                    .cable
                    .approach_height
                    .zip(self.payload.cable.approach_speed),
                hang: self.payload.cable.attachment_offset.unwrap_or(0.0)
                    + self
                        .payload
                        .cable
                        .length_min
                        .or(self.payload.cable.cable_length)
                        .unwrap_or(0.0),
            },
        }
    }

    /// What the wind sources and the wind field are built from.
    pub fn wind_context(&self) -> WindContext<'_> {
        WindContext {
            sections: self.context(),
            wind: &self.wind,
        }
    }

    /// What the payload and actuator kinds are built and checked from.
    pub fn model_context(&self) -> ModelContext<'_> {
        ModelContext {
            sections: self.context(),
            payload: &self.payload,
            actuator: &self.actuator,
        }
    }

    /// What the control laws are built and checked from.
    pub fn control_context(&self) -> ControlContext<'_> {
        ControlContext {
            model: self.model_context(),
            controller: &self.controller,
        }
    }

    /// kc in N/m, from whichever of stiffness / natural frequency was given.
    pub fn stiffness(&self) -> f64 {
        self.model_context().stiffness()
    }

    /// m/s, W20 of the turbulence: `gust.w20`, or the level `gust.intensity` names.
    pub fn turbulence_w20(&self) -> f64 {
        self.context().turbulence_w20()
    }

    /// Number of RK4 steps of a flight: the duration rounded to the nearest whole step.
    pub fn steps(&self) -> usize {
        self.context().steps()
    }

    /// Integration steps per spectrum sample (`metrics.spectrum_rate`).
    pub fn decimation(&self) -> usize {
        self.context().decimation()
    }

    /// Check every value; the first problem found is returned with its key.
    pub fn validate(&self) -> Result<(), ConfigError> {
        self.validate_values(true)
    }

    /// `validate` without the keys no realisation of a batch may change (`keys::FIXED_PREFIXES`:
    /// the trajectory, its route and schedule, the phases): for a dispersed realisation of a
    /// scenario `validate` has accepted, so that a long route is checked once, not per
    /// realisation.
    pub fn validate_realisation(&self) -> Result<(), ConfigError> {
        self.validate_values(false)
    }

    fn validate_values(&self, fixed: bool) -> Result<(), ConfigError> {
        self.vehicle.validate()?;
        self.payload.validate(&self.model_context())?;
        if self.vehicle.body == crate::model::BodyModel::Rigid
            && !crate::model::RIGID_PAYLOADS.contains(&self.payload.model)
        {
            return Err(ConfigError::new(
                "vehicle.body",
                format!(
                    "vehicle.body = \"rigid\" flies payload.model = {} only, got payload.model = \"{}\"",
                    crate::model::RIGID_PAYLOADS
                        .iter()
                        .map(|p| format!("\"{}\"", p.name()))
                        .collect::<Vec<_>>()
                        .join(", "),
                    self.payload.model.name()
                ),
            ));
        }
        self.environment.validate()?;
        self.initial.validate()?;
        self.controller.validate(&self.control_context())?;
        if fixed {
            self.trajectory.validate(&self.context())?;
        }
        self.gust.validate()?;
        self.wind.validate()?;
        self.validate_shear()?;
        self.integrator.validate()?;
        if let Err(why) = crate::config::steps_per_update(self.gust.rate, self.integrator.dt) {
            return Err(ConfigError::new("gust.rate", format!("gust.rate: {why}")));
        }
        if fixed {
            route::schedule(&self.context())?;
            trajectory::validate_phases(&self.phases, &self.integrator)?;
        } else if self.trajectory.lower.iter().any(|&p| p > 0.0) {
            // A realisation's winch times its own lowering (`Realisation::trajectory`): its
            // schedule must still fit the flight.
            route::schedule(&self.context())?;
        }
        self.actuator.validate(&self.model_context())?;
        self.metrics.validate()?;
        self.divergence.validate()?;
        self.ground.validate(&self.initial)?;
        self.volume.validate()?;
        self.navigation
            .validate(&self.sensors, self.integrator.duration)?;
        self.validate_dispersions()
    }

    /// The `[dispersions]` table: every key a per-realisation number (`per_realisation_key`),
    /// every distribution sound.
    fn validate_dispersions(&self) -> Result<(), ConfigError> {
        for (key, dist) in &self.dispersions {
            self.per_realisation_key(key)?;
            dispersions::check_distribution(key, dist)?;
        }
        Ok(())
    }

    /// `wind.roughness` gives a finite shear factor at every height a flight can reach (up to
    /// `divergence.max_distance`): a subnormal z0 passes the bounds but makes ln(h / z0)
    /// infinite. Checked whatever `wind.shear` says (one set of rules).
    fn validate_shear(&self) -> Result<(), ConfigError> {
        use crate::gust::steady;
        let z0 = self.wind.roughness;
        let top = self.divergence.max_distance.max(steady::REFERENCE_HEIGHT);
        let reference = steady::shear_factor(Shear::Log, steady::REFERENCE_HEIGHT, z0);
        let highest = steady::shear_factor(Shear::Log, top, z0);
        if !(reference.is_finite() && reference > 0.0 && highest.is_finite() && highest > 0.0) {
            return Err(ConfigError::new(
                "wind.roughness",
                format!(
                    "wind.roughness gives no finite log shear factor up to {top:?} m \
                     (divergence.max_distance): too small, got {z0:?}"
                ),
            ));
        }
        Ok(())
    }
}

/// (`key` is formatted only on failure: the checks run once per dispersed realisation.)
/// The value at a dotted key (`trajectory.route[1]`, as serde_path_to_error prints it).
fn at_path<'v>(value: &'v serde_json::Value, key: &str) -> Option<&'v serde_json::Value> {
    let mut node = value;
    for seg in crate::config::keys::parse_key(key)? {
        node = match seg {
            Seg::Field(f) => node.get(f.as_str())?,
            Seg::Index(i) => node.get(i)?,
        };
    }
    Some(node)
}

/// The scenario's tables, by dotted key (`phases[i]`, `wind.gusts[i]` and each
/// `dispersions` entry are tables too).
const TABLES: [&str; 23] = [
    "vehicle",
    "payload",
    "environment",
    "initial",
    "controller",
    "controller.pd",
    "controller.smc",
    "actuator",
    "trajectory",
    "gust",
    "wind",
    "integrator",
    "metrics",
    "divergence",
    "ground",
    "volume",
    "navigation",
    "sensors",
    "sensors.imu",
    "sensors.gnss",
    "sensors.baro",
    "sensors.heading",
    "dispersions",
];

/// The first table of the scenario given as an array (checked before serde, which would read
/// a struct from an array by position).
fn static_array_for_table(value: &serde_json::Value) -> Option<String> {
    if let Some(key) = TABLES
        .iter()
        .find(|k| at_path(value, k).is_some_and(|v| v.is_array()))
    {
        return Some(key.to_string());
    }
    let rows = |key: &str| -> Option<String> {
        let rows = at_path(value, key)?.as_array()?;
        let i = rows.iter().position(|r| r.is_array())?;
        Some(format!("{key}[{i}]"))
    };
    if let Some(key) = rows("phases").or_else(|| rows("wind.gusts")) {
        return Some(key);
    }
    let table = value.get("dispersions")?.as_object()?;
    let (key, _) = table.iter().find(|(_, v)| v.is_array())?;
    Some(format!("dispersions.{key}"))
}

/// The first key where `shape` (the parsed scenario, serialised) holds a table and `given`
/// (what was sent) an array.
fn array_for_table(
    given: &serde_json::Value,
    shape: &serde_json::Value,
    key: String,
) -> Option<String> {
    use serde_json::Value;
    let join = |k: &str| {
        if key.is_empty() {
            k.to_string()
        } else {
            format!("{key}.{k}")
        }
    };
    match (given, shape) {
        (Value::Array(_), Value::Object(_)) => Some(key),
        (Value::Object(g), Value::Object(s)) => s
            .iter()
            .find_map(|(k, v)| array_for_table(g.get(k)?, v, join(k))),
        (Value::Array(g), Value::Array(s)) if s.first().is_some_and(Value::is_object) => g
            .iter()
            .zip(s)
            .enumerate()
            .find_map(|(i, (g, s))| array_for_table(g, s, format!("{key}[{i}]"))),
        _ => None,
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// The paper preset exactly as the Python package ships it.
    pub(crate) const PAPER_TOML: &str = include_str!("../../../python/quadrs/presets/paper.toml");

    pub(crate) fn paper_value() -> serde_json::Value {
        toml::from_str(PAPER_TOML).expect("paper.toml parses")
    }

    pub(crate) fn paper() -> Config {
        Config::from_json(&paper_value().to_string()).expect("paper preset is valid")
    }

    /// The paper's scenario cut to `duration` s at step `dt`: its first `phases` phases, the
    /// last ending with the flight.
    pub(crate) fn paper_cut(duration: f64, dt: f64, phases: usize) -> Config {
        let mut cfg = paper();
        cfg.integrator.duration = duration;
        cfg.integrator.dt = dt;
        cfg.phases.truncate(phases);
        cfg.phases[phases - 1].end = duration;
        cfg
    }

    /// Each of `keys` is a per-realisation number, and setting it changes the scenario.
    pub(crate) fn assert_settable(cfg: &Config, keys: &[&str]) {
        for key in keys {
            let path = cfg.per_realisation_key(key).unwrap();
            let mut c = cfg.clone();
            assert!(c.set_number(&path, 0.25), "{key}");
            assert_ne!(c.to_json(), cfg.to_json(), "{key}");
        }
    }

    /// Each key of `refused` is no per-realisation number, the message saying why.
    pub(crate) fn assert_refused(cfg: &Config, refused: &[(&str, &str)]) {
        for (key, says) in refused {
            let e = cfg.per_realisation_key(key).unwrap_err();
            assert!(e.message.contains(says), "{key}: {e:?}");
        }
    }

    /// The delivery preset as the Python package reads it: a controller table it gives in part
    /// (`[controller.px4]`, the keys it changes) completed from the kind's defaults, as
    /// `quadrs.scenario.tables` completes it.
    pub(crate) fn delivery_value() -> serde_json::Value {
        let text = include_str!("../../../python/quadrs/presets/delivery.toml");
        let mut v: serde_json::Value = toml::from_str(text).expect("delivery.toml parses");
        for (name, table) in crate::control::ControllerConfig::default_tables() {
            let given = v["controller"]
                .get_mut(name)
                .and_then(|t| t.as_object_mut());
            if let (Some(json), Some(given)) = (table, given) {
                let defaults: serde_json::Map<String, serde_json::Value> =
                    serde_json::from_str(&json).expect("a kind's defaults parse");
                for (key, x) in defaults {
                    given.entry(key).or_insert(x);
                }
            }
        }
        v
    }

    #[test]
    fn paper_preset_parses_and_round_trips() {
        let c = paper();
        let again = Config::from_json(&c.to_json()).unwrap();
        assert_eq!(c.to_json(), again.to_json());
        assert_eq!(c.steps(), 350_000);
        let kc = c.stiffness();
        assert!((kc - 0.22 * (4.0 * std::f64::consts::PI).powi(2)).abs() < 1e-12);
    }

    pub(crate) fn with(edit: impl Fn(&mut serde_json::Value)) -> Result<Config, ConfigError> {
        let mut v = paper_value();
        edit(&mut v);
        Config::from_json(&v.to_string())
    }

    #[test]
    fn bad_values_name_their_key() {
        let e = with(|v| v["payload"]["mass"] = (-1.0).into()).unwrap_err();
        assert_eq!(e.key, "payload.mass");
        assert_eq!(e.message, "payload.mass must be > 0, got -1.0");
        let e = with(|v| v["integrator"]["dt"] = 0.0.into()).unwrap_err();
        assert_eq!(e.key, "integrator.dt");
        let e = with(|v| v["integrator"]["dt"] = 100.0.into()).unwrap_err();
        assert!(
            e.message.contains("must not exceed integrator.duration"),
            "{e}"
        );
        let e = with(|v| v["phases"][2]["end"] = 80.0.into()).unwrap_err();
        assert_eq!(e.key, "phases[2].end");
        let e = with(|v| {
            v["trajectory"]["waypoints"] = serde_json::json!([[0, 0, 0, 2, 0]]);
        })
        .unwrap_err();
        assert_eq!(e.key, "trajectory.waypoints");
        let e = with(|v| v["gust"]["airspeed"] = 0.0.into()).unwrap_err();
        assert!(e.message.contains("singular"), "{e}");
    }

    #[test]
    fn unknown_and_mistyped_keys_are_named() {
        let e = with(|v| v["payload"]["colour"] = "red".into()).unwrap_err();
        assert!(
            e.message.contains("payload") && e.message.contains("colour"),
            "{e}"
        );
        let e = with(|v| v["vehicle"]["mass"] = "heavy".into()).unwrap_err();
        assert_eq!(e.key, "vehicle.mass");
        let e = with(|v| v["payload"]["stiffness"] = 30.0.into()).unwrap_err();
        assert!(e.message.contains("exactly one"), "{e}");
    }

    #[test]
    fn each_pair_of_keys_for_one_thing_takes_exactly_one() {
        let keys: Vec<String> = Config::keys().into_iter().map(|(k, _)| k).collect();
        for pair in Config::ONE_OF {
            assert!(
                pair.keys.iter().all(|k| keys.iter().any(|x| x == k)),
                "{pair:?}"
            );
        }
        // The paper gives the attachment's natural frequency: its stiffness too is both.
        let e = with(|v| v["payload"]["stiffness"] = 30.0.into()).unwrap_err();
        assert_eq!(e.key, "payload.stiffness");
        assert_eq!(
            e.message,
            "give exactly one of payload.stiffness and payload.natural_frequency, got both"
        );
        let e = with(|v| {
            v["payload"]
                .as_object_mut()
                .unwrap()
                .remove("natural_frequency");
        })
        .unwrap_err();
        assert_eq!(e.key, "payload.natural_frequency");
        assert!(e.message.ends_with("got neither"), "{e}");
        // Either one alone is checked as a number.
        let e = with(|v| {
            v["payload"]
                .as_object_mut()
                .unwrap()
                .remove("natural_frequency");
            v["payload"]["stiffness"] = (-1.0).into();
        })
        .unwrap_err();
        assert_eq!(e.message, "payload.stiffness must be > 0, got -1.0");
        let e = with(|v| v["gust"]["intensity"] = "light".into()).unwrap_err();
        assert_eq!(
            (e.key.as_str(), e.message.as_str()),
            (
                "gust.intensity",
                "give exactly one of gust.w20 and gust.intensity, got both"
            )
        );
        let e = with(|v| {
            v["gust"].as_object_mut().unwrap().remove("w20");
        })
        .unwrap_err();
        assert_eq!(e.key, "gust.w20");
        assert!(e.message.ends_with("got neither"), "{e}");
    }

    #[test]
    fn a_table_given_as_an_array_is_refused_by_name() {
        use serde_json::json;
        for (key, value) in [
            ("wind", json!([5.0, 2.0])),
            ("wind", json!([])),
            ("actuator", json!([])),
            ("ground", json!([])),
            ("environment", json!([3.71])),
        ] {
            let e = with(|v| v[key] = value.clone()).unwrap_err();
            assert_eq!(e.key, key, "{e}");
            assert_eq!(e.message, format!("{key} must be a table, got an array"));
        }
        let e = with(|v| v["phases"][1] = json!(["P2", 25.0, 40.0])).unwrap_err();
        assert_eq!(e.key, "phases[1]", "{e}");
        let e = with(|v| v["controller"]["pd"] = json!([[1, 1, 1]])).unwrap_err();
        assert!(
            e.message.starts_with("controller.pd must be a table"),
            "{e}"
        );
        let e = with(|v| v["initial"]["position"] = json!([0, 0, 0, 1])).unwrap_err();
        assert_eq!(
            (e.key.as_str(), e.message.as_str()),
            (
                "initial.position",
                "initial.position must have 3 numbers, got 4"
            )
        );
        let e = with(|v| v["trajectory"]["waypoints"][1] = json!([1, 0, 0])).unwrap_err();
        assert_eq!(
            e.message,
            "trajectory.waypoints[1] must have 5 numbers, got 3"
        );
    }

    #[test]
    fn a_roughness_without_a_finite_shear_factor_is_refused() {
        for z0 in [5e-324, 1e-310] {
            let mut c = paper();
            c.wind.roughness = z0;
            let e = c.validate().unwrap_err();
            assert_eq!(e.key, "wind.roughness", "{e}");
        }
        let mut c = paper();
        c.wind.roughness = 1e-6;
        c.validate().expect("a smooth surface");
    }
}
