//! The scenario as the engine receives it: one plain struct, deserialised once from the
//! JSON the Python layer sends, then validated here so that every entry point of the engine
//! guards itself. Field names mirror the TOML keys, so an error names the user's key.

pub mod allocation;
pub mod dispersions;
pub mod keys;
pub mod params;
pub mod route;
pub mod wind;

pub use crate::control::ControllerConfig;
pub use dispersions::{Dispersions, Distribution};
use serde::{Deserialize, Serialize};
use std::fmt;
pub use wind::{
    DiscreteGust, GustAirspeed, GustAltitude, GustShape, Intensity, Shear, TableBy, Wind, WindTable,
};

/// A bad scenario value: `key` is the dotted TOML path, `message` the whole sentence.
#[derive(Debug, Clone, PartialEq)]
pub struct ConfigError {
    pub key: String,
    pub message: String,
}

impl fmt::Display for ConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.message)
    }
}

impl std::error::Error for ConfigError {}

impl ConfigError {
    pub(crate) fn new(key: impl Into<String>, message: impl Into<String>) -> Self {
        Self {
            key: key.into(),
            message: message.into(),
        }
    }
}

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Config {
    pub vehicle: Vehicle,
    pub payload: Payload,
    pub environment: Environment,
    pub initial: Initial,
    pub controller: ControllerConfig,
    /// How the controller's thrust and torques reach the airframe (docs/model.md section 8).
    #[serde(default)]
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
    /// Uncertain parameters: dotted key -> distribution (`crate::dispersion`).
    #[serde(default, skip_serializing_if = "Dispersions::is_empty")]
    pub dispersions: Dispersions,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Vehicle {
    /// kg, the quadrotor alone.
    pub mass: f64,
    /// kg m^2, nominal (what the controller believes): Ixx, Iyy, Izz.
    pub inertia: [f64; 3],
    /// kg m^2, plant inertia minus nominal (the paper's Delta I).
    pub inertia_error: [f64; 3],
    /// m, arm length (Table 1; the model applies torques directly, so it is informational).
    pub arm_length: f64,
    /// m^2, Cd times projected area for vertical drag.
    pub drag_area: f64,
    /// m^2, Cd times projected area for horizontal drag of vehicle plus payload.
    pub lateral_drag_area: f64,
}

/// Which payload model flies (`payload.model`, docs/model.md sections 1 and 7).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PayloadModelName {
    /// A point mass on a vertical spring (the paper's).
    #[default]
    Spring,
    /// A point mass on an elastic cable that swings in 3-D and can go slack (section 7).
    Cable,
}

/// Which actuator model flies (`actuator.model`, docs/model.md section 8).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ActuatorModelName {
    /// The controller's thrust and torques act at once, without limit (the paper's).
    #[default]
    Ideal,
    /// Four rotors with first-order speed dynamics and per-rotor thrust limits.
    Rotors,
}

/// Where the four rotors sit (`actuator.layout`): rotor i at arm angle a_i from body x.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RotorLayout {
    /// a = 45, 135, 225, 315 degrees.
    #[default]
    X,
    /// a = 0, 90, 180, 270 degrees.
    Plus,
}

impl RotorLayout {
    /// The arm angles a_1..a_4 (rad).
    pub fn angles(self) -> [f64; 4] {
        let first = match self {
            RotorLayout::X => 45.0,
            RotorLayout::Plus => 0.0,
        };
        [0.0, 90.0, 180.0, 270.0].map(|a: f64| (first + a).to_radians())
    }
}

/// `[actuator]` (docs/model.md section 8 and "Rotors"). The rotor keys are read only when
/// `model = "rotors"`, but checked always (one set of rules).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ActuatorConfig {
    #[serde(default)]
    pub model: ActuatorModelName,
    #[serde(default)]
    pub layout: RotorLayout,
    /// N s^2/rad^2, kf in T = kf w^2.
    #[serde(default = "default_thrust_coefficient")]
    pub thrust_coefficient: f64,
    /// m, cq: a rotor's yaw reaction torque per newton of its thrust.
    #[serde(default = "default_torque_ratio")]
    pub torque_ratio: f64,
    /// s, tau_m of the rotor speed lag dw/dt = (w_cmd - w) / tau_m.
    #[serde(default = "default_time_constant")]
    pub time_constant: f64,
    /// N per rotor, the commanded thrust's lower and upper clamps.
    #[serde(default)]
    pub thrust_min: f64,
    #[serde(default = "default_rotor_thrust_max")]
    pub thrust_max: f64,
    /// Rotors that give a fraction of their commanded thrust from a time on (rotors only).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub faults: Vec<RotorFault>,
    /// The fraction of `thrust_max` lost by the end of the flight, linearly (rotors only).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub battery_sag: f64,
}

params::params! {
    /// One `[[actuator.faults]]` entry: rotor `rotor` gives `thrust_fraction` of its commanded
    /// (clamped) thrust from `start` on (0: stuck off, or its propeller lost); flown by
    /// `model::actuator::rotors`. Declared here, with `[actuator]`, so that `config` names no
    /// `model` (the engine's modules form no cycle).
    pub struct RotorFault {
        /// Which rotor, 1 to 4 in the layout's order (docs/model.md "Rotors"); a key, not a
        /// number a dispersion draws.
        rotor: u32 => "-", "Failed rotor (1 to 4)";
        start: f64 => "s", "Rotor fault start";
        thrust_fraction: f64 => "-", "Thrust fraction the failed rotor gives";
    }
}

/// `actuator.battery_sag`: the fraction of `thrust_max` lost by the end of the flight.
pub const BATTERY_SAG: params::Key = params::Key {
    name: "battery_sag",
    unit: "-",
    label: "Fraction of the rotor thrust limit lost by the end (battery sag)",
};

fn is_zero(x: &f64) -> bool {
    *x == 0.0
}

impl ActuatorConfig {
    /// The keys `[actuator]` owns with a unit and a label (dotted, indices dropped): the
    /// rotors' faults and the battery's sag (`model::actuator::rotors`).
    pub fn keys() -> Vec<(String, params::Key)> {
        use params::Params;
        let faults = RotorFault::KEYS
            .iter()
            .map(|k| (format!("actuator.faults.{}", k.name), *k));
        faults
            .chain([(format!("actuator.{}", BATTERY_SAG.name), BATTERY_SAG)])
            .collect()
    }
}

impl Default for ActuatorConfig {
    fn default() -> Self {
        Self {
            model: ActuatorModelName::default(),
            layout: RotorLayout::default(),
            thrust_coefficient: default_thrust_coefficient(),
            torque_ratio: default_torque_ratio(),
            time_constant: default_time_constant(),
            thrust_min: 0.0,
            thrust_max: default_rotor_thrust_max(),
            faults: Vec::new(),
            battery_sag: 0.0,
        }
    }
}

/// N s^2/rad^2: a 10-inch multirotor propeller (RotorS and PX4's x500 `motorConstant`;
/// docs/model.md "Rotors").
pub fn default_thrust_coefficient() -> f64 {
    8.54858e-6
}

/// m: RotorS and PX4's x500 `momentConstant` (docs/model.md "Rotors").
pub fn default_torque_ratio() -> f64 {
    0.016
}

/// s: a 2 kg class motor with a 10-inch propeller (docs/model.md "Rotors").
pub fn default_time_constant() -> f64 {
    0.03
}

/// N per rotor: thrust-to-weight about 2 for the paper's 2.42 kg loaded vehicle
/// (docs/model.md "Rotors").
pub fn default_rotor_thrust_max() -> f64 {
    12.0
}

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Payload {
    /// The payload model (default "spring").
    #[serde(default)]
    pub model: PayloadModelName,
    /// kg.
    pub mass: f64,
    /// Hz, fn with kc = mc (2 pi fn)^2. Exactly one of this and `stiffness`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub natural_frequency: Option<f64>,
    /// N/m.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stiffness: Option<f64>,
    /// N s/m.
    pub damping: f64,
    /// m^2, Cd times projected area for vertical drag (the cable's payload: in every direction).
    pub drag_area: f64,
    /// m, the cable's unstretched length L0 (`model = "cable"` only; required there).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cable_length: Option<f64>,
    /// m, the hook's distance below the centre of gravity along the body z axis
    /// (`model = "cable"` only; default 0).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub attachment_offset: Option<f64>,
}

impl Payload {
    /// m, the cable's hook below the centre of gravity (0 unless given).
    pub fn attachment_offset(&self) -> f64 {
        self.attachment_offset.unwrap_or(0.0)
    }
}

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Environment {
    /// m/s^2.
    pub gravity: f64,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Initial {
    /// m, quadrotor x, y, z; the payload starts at its hover equilibrium below it.
    pub position: [f64; 3],
    /// rad, roll, pitch, yaw.
    pub attitude: [f64; 3],
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Interpolation {
    Step,
    MinJerk,
    /// Straight legs between `trajectory.route` points, rest to rest (docs/model.md, "Routes").
    Route,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Trajectory {
    pub interpolation: Interpolation,
    /// Rows of (t s, x m, y m, z m, psi rad), times strictly increasing (step and min-jerk;
    /// absent for a route).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub waypoints: Vec<[f64; 5]>,
    /// s, min-jerk only: each move toward a waypoint starts at its time and lasts this long
    /// (or up to the next waypoint's time if that comes sooner).
    #[serde(default = "default_transition")]
    pub transition: f64,
    /// Route only: the points [x, y, z] (m) flown in straight legs, in order.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub route: Vec<[f64; 3]>,
    /// Route only: m/s, the cruise speed of every leg long enough to reach it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub speed: Option<f64>,
    /// Route only: m/s^2, the bound on the reference's acceleration along a leg.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub acceleration: Option<f64>,
    /// Route only: s, the hover at each point (one per point; empty: no holds).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub hold: Vec<f64>,
    /// Route only: the names of the route's segments (holds and legs, in time order) in place
    /// of leg1, hold2, ...; empty: those defaults.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub names: Vec<String>,
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

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Phase {
    pub name: String,
    /// s, inclusive.
    pub start: f64,
    /// s, inclusive.
    pub end: f64,
}

/// Which spectrum the gust's forming filters realise (`gust.model`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum GustModel {
    /// MIL-F-8785C Dryden (rational, exact).
    Dryden,
    /// von Karman, through the published 2nd/3rd-order rational approximants
    /// (MIL-HDBK-1797; MATLAB "Von Karman Wind Turbulence Model (Continuous)").
    VonKarman,
}

impl GustModel {
    pub const ALL: [GustModel; 2] = [GustModel::Dryden, GustModel::VonKarman];

    /// Human-readable name used in messages.
    pub fn name(self) -> &'static str {
        match self {
            GustModel::Dryden => "Dryden",
            GustModel::VonKarman => "von Karman",
        }
    }

    /// The scenario's spelling (what serde reads and writes).
    pub fn key(self) -> &'static str {
        match self {
            GustModel::Dryden => "dryden",
            GustModel::VonKarman => "von_karman",
        }
    }
}

/// Gust velocity component, along the inertial axes: x (longitudinal), y (lateral),
/// z (vertical, z up) (`gust.components`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum GustComponent {
    Longitudinal,
    Lateral,
    Vertical,
}

impl GustComponent {
    /// All components in the fixed draw order.
    pub const ALL: [GustComponent; 3] = [
        GustComponent::Longitudinal,
        GustComponent::Lateral,
        GustComponent::Vertical,
    ];

    /// Axis index: 0 (x), 1 (y), 2 (z).
    pub fn index(self) -> usize {
        match self {
            GustComponent::Longitudinal => 0,
            GustComponent::Lateral => 1,
            GustComponent::Vertical => 2,
        }
    }

    /// Lower-case name used in messages; also the scenario's spelling.
    pub fn name(self) -> &'static str {
        match self {
            GustComponent::Longitudinal => "longitudinal",
            GustComponent::Lateral => "lateral",
            GustComponent::Vertical => "vertical",
        }
    }
}

/// `'a', 'b' or 'c'`.
fn one_of(keys: &[&str]) -> String {
    let quoted: Vec<String> = keys.iter().map(|k| format!("'{k}'")).collect();
    match quoted.split_last() {
        Some((last, [])) => last.clone(),
        Some((last, rest)) => format!("{} or {last}", rest.join(", ")),
        None => String::new(),
    }
}

impl std::str::FromStr for GustModel {
    type Err = String;

    /// From the scenario's spelling (`"dryden"`, `"von_karman"`).
    fn from_str(s: &str) -> Result<Self, String> {
        Self::ALL.into_iter().find(|m| m.key() == s).ok_or_else(|| {
            let keys: Vec<&str> = Self::ALL.iter().map(|m| m.key()).collect();
            format!("model must be {}, got {s:?}", one_of(&keys))
        })
    }
}

impl std::str::FromStr for GustComponent {
    type Err = String;

    /// From the scenario's spelling (`"longitudinal"`, `"lateral"`, `"vertical"`).
    fn from_str(s: &str) -> Result<Self, String> {
        Self::ALL
            .into_iter()
            .find(|c| c.name() == s)
            .ok_or_else(|| {
                let keys: Vec<&str> = Self::ALL.iter().map(|c| c.name()).collect();
                format!("component must be {}, got {s:?}", one_of(&keys))
            })
    }
}

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Gust {
    pub enabled: bool,
    pub model: GustModel,
    pub components: Vec<GustComponent>,
    /// s, the gust window [start, end).
    pub start: f64,
    pub end: f64,
    /// m above ground (converted to feet for the MIL-F-8785C scale formulas), or `"vehicle"`:
    /// the quadrotor's z at each step, clamped to [10 ft, 1000 ft].
    pub altitude: GustAltitude,
    /// m/s, wind speed at 20 ft for the turbulence. Exactly one of this and `intensity`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub w20: Option<f64>,
    /// The standard's named level (W20 = 15, 30, 45 kt), instead of `w20`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub intensity: Option<Intensity>,
    /// m/s, the speed at which the frozen turbulence is convected past the vehicle, or
    /// `"relative"`: max(|v - mean(h)|, `min_airspeed`) at each step.
    pub airspeed: GustAirspeed,
    /// m/s, the floor of the relative airspeed.
    #[serde(default = "wind::default_min_airspeed")]
    pub min_airspeed: f64,
    /// kg/m^3.
    pub air_density: f64,
    /// m/s, inertial x, y, z, added to the gust inside the window.
    pub mean_wind: [f64; 3],
}

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Integrator {
    /// s.
    pub dt: f64,
    /// s.
    pub duration: f64,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Metrics {
    /// Hz, rate at which e_o is block-averaged for the amplitude spectra.
    pub spectrum_rate: f64,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Divergence {
    /// m, a realisation whose quadrotor or payload strays further than this from the origin diverged.
    pub max_distance: f64,
    /// rad, a realisation whose roll or pitch exceeds this diverged.
    pub max_tilt: f64,
    /// m/s, a realisation whose quadrotor or payload moves faster than this along any axis
    /// diverged: catches a numerically unstable step (finite but absurd states) early.
    #[serde(default = "default_max_speed")]
    pub max_speed: f64,
    /// rad/s, a realisation whose body rate p, q or r exceeds this diverged.
    #[serde(default = "default_max_rate")]
    pub max_rate: f64,
}

/// A flight whose quadrotor goes below `altitude` (m, its z) ends there with status `ground`
/// when `enabled`. No contact dynamics: the flight simply stops.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Ground {
    #[serde(default)]
    pub enabled: bool,
    /// m.
    #[serde(default)]
    pub altitude: f64,
}

impl Ground {
    /// The altitude below which a flight ends (minus infinity when the ground is off).
    pub fn floor(&self) -> f64 {
        if self.enabled {
            self.altitude
        } else {
            f64::NEG_INFINITY
        }
    }
}

fn default_max_speed() -> f64 {
    100.0
}

fn default_max_rate() -> f64 {
    100.0
}

/// `phases = "legs"`: one phase per leg and hold of the route (docs/model.md, "Routes").
pub const LEGS: &str = "legs";

/// Most integration steps one flight may take (guards against hangs from a tiny dt).
pub const MAX_STEPS: f64 = 2.0e9;

impl Config {
    /// Parse and validate the engine's JSON form of a scenario.
    pub fn from_json(text: &str) -> Result<Self, ConfigError> {
        let (mut cfg, legs) = Self::parse(text)?;
        cfg.validate()?;
        // `phases = "legs"`: the route's schedule gives the phases, once the rest is valid
        // (`parse` left a placeholder phase covering the flight).
        if legs {
            cfg.phases = route::leg_phases(&cfg)?;
            cfg.validate_phases()?;
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

    pub fn to_json(&self) -> String {
        serde_json::to_string(self).expect("a Config always serialises")
    }

    /// kc in N/m, from whichever of stiffness / natural frequency was given.
    pub fn stiffness(&self) -> f64 {
        match (self.payload.stiffness, self.payload.natural_frequency) {
            (Some(k), _) => k,
            (None, Some(fn_hz)) => self.payload.mass * (2.0 * std::f64::consts::PI * fn_hz).powi(2),
            (None, None) => f64::NAN, // rejected by validate()
        }
    }

    /// m/s, W20 of the turbulence: `gust.w20`, or the level `gust.intensity` names.
    pub fn turbulence_w20(&self) -> f64 {
        match (self.gust.w20, self.gust.intensity) {
            (Some(w), _) => w,
            (None, Some(i)) => i.w20(),
            (None, None) => f64::NAN, // rejected by validate()
        }
    }

    /// Number of RK4 steps of a flight: the duration rounded to the nearest whole step.
    pub fn steps(&self) -> usize {
        (self.integrator.duration / self.integrator.dt).round() as usize
    }

    /// Integration steps per spectrum sample (`metrics.spectrum_rate`).
    pub fn decimation(&self) -> usize {
        ((1.0 / (self.metrics.spectrum_rate * self.integrator.dt)).round() as usize).max(1)
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
        let v = &self.vehicle;
        positive("vehicle.mass", v.mass)?;
        for (i, x) in v.inertia.iter().enumerate() {
            positive(format_args!("vehicle.inertia[{i}]"), *x)?;
        }
        for (i, x) in v.inertia_error.iter().enumerate() {
            let key = format!("vehicle.inertia_error[{i}]");
            finite(&key, *x)?;
            if v.inertia[i] + x <= 0.0 {
                return Err(ConfigError::new(
                    &key,
                    format!(
                        "{key} must leave a positive plant inertia (vehicle.inertia[{i}] + error > 0), got {x:?}"
                    ),
                ));
            }
        }
        non_negative("vehicle.arm_length", v.arm_length)?;
        non_negative("vehicle.drag_area", v.drag_area)?;
        non_negative("vehicle.lateral_drag_area", v.lateral_drag_area)?;

        let p = &self.payload;
        positive("payload.mass", p.mass)?;
        match (p.stiffness, p.natural_frequency) {
            (Some(_), Some(_)) => {
                return Err(ConfigError::new(
                    "payload.stiffness",
                    "give exactly one of payload.stiffness and payload.natural_frequency, got both",
                ))
            }
            (None, None) => return Err(ConfigError::new(
                "payload.natural_frequency",
                "give exactly one of payload.stiffness and payload.natural_frequency, got neither",
            )),
            (Some(k), None) => positive("payload.stiffness", k)?,
            (None, Some(f)) => positive("payload.natural_frequency", f)?,
        }
        non_negative("payload.damping", p.damping)?;
        non_negative("payload.drag_area", p.drag_area)?;
        match p.model {
            PayloadModelName::Cable => {
                let Some(l0) = p.cable_length else {
                    return Err(ConfigError::new(
                        "payload.cable_length",
                        "payload.cable_length must be given for payload.model = \"cable\"",
                    ));
                };
                positive("payload.cable_length", l0)?;
                if let Some(h) = p.attachment_offset {
                    non_negative("payload.attachment_offset", h)?;
                }
            }
            PayloadModelName::Spring => {
                for (key, value) in [
                    ("payload.cable_length", p.cable_length),
                    ("payload.attachment_offset", p.attachment_offset),
                ] {
                    if let Some(x) = value {
                        return Err(ConfigError::new(
                            key,
                            format!(
                                "{key} applies to payload.model = \"cable\" only, got {x:?} \
                                 with payload.model = \"spring\""
                            ),
                        ));
                    }
                }
            }
        }

        positive("environment.gravity", self.environment.gravity)?;

        for (i, x) in self.initial.position.iter().enumerate() {
            finite(format_args!("initial.position[{i}]"), *x)?;
        }
        for (i, x) in self.initial.attitude.iter().enumerate() {
            finite(format_args!("initial.attitude[{i}]"), *x)?;
        }
        for i in 0..2 {
            let a = self.initial.attitude[i];
            if a.abs() >= std::f64::consts::FRAC_PI_2 {
                let key = format!("initial.attitude[{i}]");
                return Err(ConfigError::new(
                    &key,
                    format!("{key} (roll/pitch) must be within (-pi/2, pi/2) rad, got {a:?}"),
                ));
            }
        }

        self.controller.validate(self)?;
        if fixed {
            self.validate_trajectory()?;
        }
        self.validate_gust()?;
        self.wind.validate()?;
        self.validate_shear()?;

        let it = &self.integrator;
        positive("integrator.dt", it.dt)?;
        positive("integrator.duration", it.duration)?;
        if it.dt > it.duration {
            return Err(ConfigError::new(
                "integrator.dt",
                format!(
                    "integrator.dt must not exceed integrator.duration ({:?} s), got {:?}",
                    it.duration, it.dt
                ),
            ));
        }
        if it.duration / it.dt > MAX_STEPS {
            return Err(ConfigError::new(
                "integrator.dt",
                format!(
                    "integrator.dt is too small: duration / dt must be at most {MAX_STEPS:e} steps, got {:?}",
                    it.dt
                ),
            ));
        }
        if fixed {
            route::schedule(self)?;
            self.validate_phases()?;
        }
        self.validate_actuator()?;

        positive("metrics.spectrum_rate", self.metrics.spectrum_rate)?;
        positive("divergence.max_distance", self.divergence.max_distance)?;
        positive("divergence.max_tilt", self.divergence.max_tilt)?;
        positive("divergence.max_speed", self.divergence.max_speed)?;
        positive("divergence.max_rate", self.divergence.max_rate)?;
        self.validate_ground()?;
        dispersions::validate(self)
    }

    /// `wind.roughness` gives a finite shear factor at every height a flight can reach (up to
    /// `divergence.max_distance`): a subnormal z0 passes the bounds but makes ln(h / z0)
    /// infinite. Checked whatever `wind.shear` says (one set of rules).
    fn validate_shear(&self) -> Result<(), ConfigError> {
        let z0 = self.wind.roughness;
        let top = self.divergence.max_distance.max(wind::REFERENCE_HEIGHT);
        let reference = wind::shear_factor(Shear::Log, wind::REFERENCE_HEIGHT, z0);
        let highest = wind::shear_factor(Shear::Log, top, z0);
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

    fn validate_ground(&self) -> Result<(), ConfigError> {
        let g = &self.ground;
        finite("ground.altitude", g.altitude)?;
        let z0 = self.initial.position[2];
        if g.enabled && z0 < g.altitude {
            return Err(ConfigError::new(
                "ground.altitude",
                format!(
                    "ground.altitude must be at or below the start (initial.position[2] = {z0:?}) \
                     when ground.enabled, got {:?}",
                    g.altitude
                ),
            ));
        }
        Ok(())
    }

    /// `[actuator]`: every rotor key in range always; whether the rotors can hold this
    /// vehicle in hover and the lag can be integrated at this step only when they fly.
    fn validate_actuator(&self) -> Result<(), ConfigError> {
        let a = &self.actuator;
        positive("actuator.thrust_coefficient", a.thrust_coefficient)?;
        positive("actuator.torque_ratio", a.torque_ratio)?;
        positive("actuator.time_constant", a.time_constant)?;
        non_negative("actuator.thrust_min", a.thrust_min)?;
        finite("actuator.thrust_max", a.thrust_max)?;
        if a.thrust_max <= a.thrust_min {
            return Err(ConfigError::new(
                "actuator.thrust_max",
                format!(
                    "actuator.thrust_max must exceed actuator.thrust_min ({:?} N), got {:?}",
                    a.thrust_min, a.thrust_max
                ),
            ));
        }
        self.validate_faults()?;
        if a.model != ActuatorModelName::Rotors {
            return Ok(());
        }
        let l = self.vehicle.arm_length;
        if l <= 0.0 {
            return Err(ConfigError::new(
                "vehicle.arm_length",
                format!(
                    "vehicle.arm_length must be > 0 with actuator.model = \"rotors\" (the rotors' \
                     roll and pitch arms), got {l:?}"
                ),
            ));
        }
        // M^-1 must exist and be finite, and M M^-1 must be the identity: a huge arm or a
        // subnormal torque ratio overflows or underflows the inverse (NaN thrusts otherwise).
        let m = allocation::allocation(a.layout, l, a.torque_ratio);
        let inverse = allocation::allocation_inverse(&m)
            .filter(|inv| inv.iter().flatten().all(|x| x.is_finite()))
            .filter(|inv| {
                (0..4).all(|i| {
                    (0..4).all(|j| {
                        let mij: f64 = (0..4).map(|k| m[i][k] * inv[k][j]).sum();
                        (mij - if i == j { 1.0 } else { 0.0 }).abs() < 1e-9
                    })
                })
            });
        if inverse.is_none() {
            let (key, x) = if (1e-6..=1e3).contains(&l) {
                ("actuator.torque_ratio", a.torque_ratio)
            } else {
                ("vehicle.arm_length", l)
            };
            return Err(ConfigError::new(
                key,
                format!(
                    "{key} makes the rotors' allocation (vehicle.arm_length = {l:?} m, \
                     actuator.torque_ratio = {:?} m) impossible to invert in floating point, \
                     got {x:?}",
                    a.torque_ratio
                ),
            ));
        }
        let dt = self.integrator.dt;
        if a.time_constant < dt {
            return Err(ConfigError::new(
                "actuator.time_constant",
                format!(
                    "actuator.time_constant must be at least integrator.dt ({dt:?} s): RK4 on \
                     the rotor lag is unstable past dt / tau ~ 2.8; got {:?}",
                    a.time_constant
                ),
            ));
        }
        let weight = (self.vehicle.mass + self.payload.mass) * self.environment.gravity;
        if 4.0 * a.thrust_max < weight {
            return Err(ConfigError::new(
                "actuator.thrust_max",
                format!(
                    "actuator.thrust_max is too small to hover: 4 x {:?} N is below the weight \
                     (vehicle.mass + payload.mass) x environment.gravity = {weight:?} N",
                    a.thrust_max
                ),
            ));
        }
        if a.thrust_min > weight / 4.0 {
            return Err(ConfigError::new(
                "actuator.thrust_min",
                format!(
                    "actuator.thrust_min is too large to hover: {:?} N per rotor exceeds the \
                     hover thrust per rotor (vehicle.mass + payload.mass) x environment.gravity \
                     / 4 = {:?} N",
                    a.thrust_min,
                    weight / 4.0
                ),
            ));
        }
        self.validate_fault_hover(weight)
    }

    /// `actuator.faults` and `actuator.battery_sag`: each value in range, at most one fault a
    /// rotor, and none of them without rotors (the ideal actuators have no rotor to fail and
    /// no thrust limit to sag).
    fn validate_faults(&self) -> Result<(), ConfigError> {
        let a = &self.actuator;
        let sag = a.battery_sag;
        if !(sag.is_finite() && (0.0..1.0).contains(&sag)) {
            return Err(ConfigError::new(
                "actuator.battery_sag",
                format!(
                    "actuator.battery_sag must be in [0, 1) (the fraction of actuator.thrust_max \
                     lost by the end of the flight), got {sag:?}"
                ),
            ));
        }
        for (i, f) in a.faults.iter().enumerate() {
            let key = format!("actuator.faults[{i}]");
            if !(1..=4).contains(&f.rotor) {
                return Err(ConfigError::new(
                    format!("{key}.rotor"),
                    format!("{key}.rotor must be 1, 2, 3 or 4, got {}", f.rotor),
                ));
            }
            if let Some(j) = a.faults[..i].iter().position(|g| g.rotor == f.rotor) {
                return Err(ConfigError::new(
                    format!("{key}.rotor"),
                    format!(
                        "{key}.rotor: rotor {} already fails in actuator.faults[{j}] (one fault a \
                         rotor), got it twice",
                        f.rotor
                    ),
                ));
            }
            non_negative(format_args!("{key}.start"), f.start)?;
            let x = f.thrust_fraction;
            if !(x.is_finite() && (0.0..=1.0).contains(&x)) {
                return Err(ConfigError::new(
                    format!("{key}.thrust_fraction"),
                    format!(
                        "{key}.thrust_fraction must be in [0, 1] (the fraction of its commanded \
                         thrust the rotor still gives), got {x:?}"
                    ),
                ));
            }
        }
        if a.model != ActuatorModelName::Rotors {
            let (key, what) = if !a.faults.is_empty() {
                ("actuator.faults", format!("{} fault(s)", a.faults.len()))
            } else if sag != 0.0 {
                ("actuator.battery_sag", format!("{sag:?}"))
            } else {
                return Ok(());
            };
            return Err(ConfigError::new(
                key,
                format!(
                    "{key} needs actuator.model = \"rotors\" (the ideal actuators have no rotor \
                     to fail and no thrust limit to sag), got {what} with actuator.model = \"ideal\""
                ),
            ));
        }
        Ok(())
    }

    /// With rotors: the thrust the rotors can still give at the end of the flight (the least
    /// over the flight: the battery only sags and a fault only starts) must hold the weight.
    /// Else the scenario is refused, naming the fault (or the sag) that takes the total below
    /// the weight and the numbers, rather than flown to a slow fall that could end `ok`.
    fn validate_fault_hover(&self, weight: f64) -> Result<(), ConfigError> {
        let a = &self.actuator;
        if a.faults.is_empty() && a.battery_sag == 0.0 {
            return Ok(());
        }
        let end = self.integrator.duration;
        let top = a.thrust_max * (1.0 - a.battery_sag);
        let total = |upto: f64| -> f64 {
            (1..=4u32)
                .map(|r| {
                    let f = a
                        .faults
                        .iter()
                        .find(|f| f.rotor == r && f.start <= upto)
                        .map_or(1.0, |f| f.thrust_fraction);
                    f * top
                })
                .sum()
        };
        let weighs = format!(
            "the weight (vehicle.mass + payload.mass) x environment.gravity = {weight:?} N"
        );
        if 4.0 * top < weight {
            return Err(ConfigError::new(
                "actuator.battery_sag",
                format!(
                    "actuator.battery_sag = {:?} leaves the rotors too little thrust to hover by \
                     the end of the flight: 4 x {top:?} N is below {weighs}",
                    a.battery_sag
                ),
            ));
        }
        let mut order: Vec<usize> = (0..a.faults.len()).collect();
        order.sort_by(|&i, &j| a.faults[i].start.total_cmp(&a.faults[j].start));
        for i in order {
            let f = &a.faults[i];
            if f.start > end {
                break;
            }
            let left = total(f.start);
            if left < weight {
                let key = format!("actuator.faults[{i}].thrust_fraction");
                return Err(ConfigError::new(
                    &key,
                    format!(
                        "{key} = {:?} (rotor {} from {:?} s) leaves the rotors too little thrust \
                         to hover: {left:?} N at the end of the flight (actuator.thrust_max = \
                         {:?} N, actuator.battery_sag = {:?}) is below {weighs}",
                        f.thrust_fraction, f.rotor, f.start, a.thrust_max, a.battery_sag
                    ),
                ));
            }
        }
        Ok(())
    }

    fn validate_trajectory(&self) -> Result<(), ConfigError> {
        route::validate(self)?;
        let tr = self.trajectory.transition;
        if !(tr.is_finite() && tr >= 0.0) {
            return Err(ConfigError::new(
                "trajectory.transition",
                format!("trajectory.transition must be a finite number >= 0 (s), got {tr:?}"),
            ));
        }
        if self.trajectory.interpolation == Interpolation::Route {
            return Ok(());
        }
        let w = &self.trajectory.waypoints;
        if w.len() < 2 {
            return Err(ConfigError::new(
                "trajectory.waypoints",
                format!(
                    "trajectory.waypoints needs at least two waypoints (t, x, y, z, psi), got {}",
                    w.len()
                ),
            ));
        }
        for (i, row) in w.iter().enumerate() {
            for (j, x) in row.iter().enumerate() {
                finite(format_args!("trajectory.waypoints[{i}][{j}]"), *x)?;
            }
            if i > 0 && row[0] <= w[i - 1][0] {
                let key = format!("trajectory.waypoints[{i}][0]");
                return Err(ConfigError::new(
                    &key,
                    format!(
                        "{key} (time) must be later than the previous waypoint's ({:?} s), got {:?}",
                        w[i - 1][0], row[0]
                    ),
                ));
            }
        }
        Ok(())
    }

    fn validate_phases(&self) -> Result<(), ConfigError> {
        let dur = self.integrator.duration;
        if self.phases.is_empty() {
            return Err(ConfigError::new(
                "phases",
                "phases must name at least one time window, got none",
            ));
        }
        let mut seen = std::collections::HashSet::with_capacity(self.phases.len());
        for (i, ph) in self.phases.iter().enumerate() {
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
            if ph.end - ph.start < 2.0 * self.integrator.dt {
                return Err(ConfigError::new(
                    &k_end,
                    format!(
                        "{k_end} must be later than {k_start} by at least two steps (2 integrator.dt = {:?} s), got {:?} (start {:?})",
                        2.0 * self.integrator.dt, ph.end, ph.start
                    ),
                ));
            }
        }
        Ok(())
    }

    fn validate_gust(&self) -> Result<(), ConfigError> {
        let g = &self.gust;
        non_negative("gust.start", g.start)?;
        finite("gust.end", g.end)?;
        if g.end < g.start {
            return Err(ConfigError::new(
                "gust.end",
                format!(
                    "gust.end must not be before gust.start ({:?} s), got {:?}",
                    g.start, g.end
                ),
            ));
        }
        if let GustAltitude::Fixed(h) = g.altitude {
            positive("gust.altitude", h)?;
        }
        match (g.w20, g.intensity) {
            (Some(_), Some(_)) => {
                return Err(ConfigError::new(
                    "gust.intensity",
                    "give exactly one of gust.w20 and gust.intensity, got both",
                ))
            }
            (None, None) => {
                return Err(ConfigError::new(
                    "gust.w20",
                    "give exactly one of gust.w20 and gust.intensity, got neither",
                ))
            }
            (Some(w), None) => non_negative("gust.w20", w)?,
            (None, Some(_)) => {}
        }
        if let GustAirspeed::Fixed(v) = g.airspeed {
            if !(v.is_finite() && v > 0.0) {
                return Err(ConfigError::new(
                    "gust.airspeed",
                    format!(
                        "gust.airspeed must be > 0 (the {} filters are singular at zero airspeed), got {:?}",
                        g.model.name(),
                        v
                    ),
                ));
            }
        }
        if !(g.min_airspeed.is_finite() && g.min_airspeed > 0.0) {
            return Err(ConfigError::new(
                "gust.min_airspeed",
                format!(
                    "gust.min_airspeed must be > 0 (the {} filters are singular at zero airspeed), got {:?}",
                    g.model.name(),
                    g.min_airspeed
                ),
            ));
        }
        non_negative("gust.air_density", g.air_density)?;
        for (i, x) in g.mean_wind.iter().enumerate() {
            finite(format_args!("gust.mean_wind[{i}]"), *x)?;
        }
        for (i, c) in g.components.iter().enumerate() {
            if g.components[..i].contains(c) {
                return Err(ConfigError::new(
                    "gust.components",
                    format!("gust.components lists {c:?} twice"),
                ));
            }
        }
        Ok(())
    }
}

/// (`key` is formatted only on failure: the checks run once per dispersed realisation.)
/// The value at a dotted key (`trajectory.route[1]`, as serde_path_to_error prints it).
fn at_path<'v>(value: &'v serde_json::Value, key: &str) -> Option<&'v serde_json::Value> {
    let mut node = value;
    for seg in keys::parse_key(key)? {
        node = match seg {
            keys::Seg::Field(f) => node.get(f.as_str())?,
            keys::Seg::Index(i) => node.get(i)?,
        };
    }
    Some(node)
}

/// The scenario's tables, by dotted key (`phases[i]`, `wind.gusts[i]` and each
/// `dispersions` entry are tables too).
const TABLES: [&str; 16] = [
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

pub(crate) fn finite(key: impl fmt::Display, x: f64) -> Result<(), ConfigError> {
    if x.is_finite() {
        Ok(())
    } else {
        Err(ConfigError::new(
            key.to_string(),
            format!("{key} must be a finite number, got {x:?}"),
        ))
    }
}

/// (`key` is formatted only on failure: the checks run once per dispersed realisation.)
pub(crate) fn positive(key: impl fmt::Display, x: f64) -> Result<(), ConfigError> {
    if x.is_finite() && x > 0.0 {
        Ok(())
    } else {
        Err(ConfigError::new(
            key.to_string(),
            format!("{key} must be > 0, got {x:?}"),
        ))
    }
}

/// (`key` is formatted only on failure: the checks run once per dispersed realisation.)
pub(crate) fn non_negative(key: impl fmt::Display, x: f64) -> Result<(), ConfigError> {
    if x.is_finite() && x >= 0.0 {
        Ok(())
    } else {
        Err(ConfigError::new(
            key.to_string(),
            format!("{key} must be >= 0, got {x:?}"),
        ))
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

    #[test]
    fn paper_preset_parses_and_round_trips() {
        let c = paper();
        let again = Config::from_json(&c.to_json()).unwrap();
        assert_eq!(c.to_json(), again.to_json());
        assert_eq!(c.steps(), 350_000);
        let kc = c.stiffness();
        assert!((kc - 0.22 * (4.0 * std::f64::consts::PI).powi(2)).abs() < 1e-12);
    }

    fn with(edit: impl Fn(&mut serde_json::Value)) -> Result<Config, ConfigError> {
        let mut v = paper_value();
        edit(&mut v);
        Config::from_json(&v.to_string())
    }

    #[test]
    fn faults_and_sag_are_checked_naming_their_key() {
        let rotors = |edit: &dyn Fn(&mut ActuatorConfig)| {
            let mut c = paper();
            c.actuator.model = ActuatorModelName::Rotors;
            edit(&mut c.actuator);
            c.validate()
        };
        fn f(rotor: u32, start: f64, thrust_fraction: f64) -> RotorFault {
            RotorFault {
                rotor,
                start,
                thrust_fraction,
            }
        }
        rotors(&|a| {
            a.faults = vec![f(1, 10.0, 0.8), f(4, 0.0, 0.5)];
            a.battery_sag = 0.2;
        })
        .expect("weak motors and a sagging battery that still hover");
        for (edit, key, says) in [
            (
                (|a: &mut ActuatorConfig| a.faults = vec![f(5, 1.0, 0.5)]) as fn(&mut _),
                "actuator.faults[0].rotor",
                "must be 1, 2, 3 or 4, got 5",
            ),
            (
                |a| a.faults = vec![f(2, 1.0, 0.5), f(2, 3.0, 0.5)],
                "actuator.faults[1].rotor",
                "rotor 2 already fails in actuator.faults[0]",
            ),
            (
                |a| a.faults = vec![f(2, -1.0, 0.5)],
                "actuator.faults[0].start",
                "got -1.0",
            ),
            (
                |a| a.faults = vec![f(2, 1.0, 1.5)],
                "actuator.faults[0].thrust_fraction",
                "must be in [0, 1]",
            ),
            (|a| a.battery_sag = 1.0, "actuator.battery_sag", "[0, 1)"),
            (|a| a.battery_sag = f64::NAN, "actuator.battery_sag", "NaN"),
        ] {
            let e = rotors(&|a| edit(a)).unwrap_err();
            assert_eq!(e.key, key, "{e}");
            assert!(e.message.contains(says) && !e.message.contains('\n'), "{e}");
        }
        // Too little thrust left to hold the weight (26.5 N; 4 x 12 N healthy): refused, with
        // the numbers, naming the fault that takes the total below it.
        let e = rotors(&|a| {
            a.faults = vec![f(1, 5.0, 0.5), f(2, 20.0, 0.1), f(3, 30.0, 0.1)];
        })
        .unwrap_err();
        assert_eq!(e.key, "actuator.faults[2].thrust_fraction", "{e}");
        assert!(e.message.contains("too little thrust to hover"), "{e}");
        assert!(
            e.message.contains("20.4") && e.message.contains("23.74"),
            "{e}"
        );
        // A fault after the end of the flight never happens.
        rotors(&|a| a.faults = vec![f(1, 99.0, 0.0), f(2, 99.0, 0.0), f(3, 99.0, 0.0)])
            .expect("faults after the flight");
        let e = rotors(&|a| a.battery_sag = 0.6).unwrap_err();
        assert_eq!(e.key, "actuator.battery_sag");
        assert!(
            e.message
                .contains("to hover by the end of the flight: 4 x 4.8"),
            "{e}"
        );
        // The ideal actuators have no rotors to fail.
        let mut c = paper();
        c.actuator.faults = vec![f(1, 1.0, 0.5)];
        let e = c.validate().unwrap_err();
        assert_eq!(e.key, "actuator.faults");
        assert!(
            e.message.contains("needs actuator.model = \"rotors\""),
            "{e}"
        );
        let mut c = paper();
        c.actuator.battery_sag = 0.1;
        assert_eq!(c.validate().unwrap_err().key, "actuator.battery_sag");
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
    fn rotor_values_name_their_keys() {
        let bad = |edit: fn(&mut Config)| {
            let mut c = paper();
            c.actuator.model = ActuatorModelName::Rotors;
            edit(&mut c);
            c.validate().unwrap_err()
        };
        let mut c = paper();
        c.actuator.model = ActuatorModelName::Rotors;
        c.validate()
            .expect("the paper vehicle on its default rotors");
        // 4 x 5 N = 20 N < (2.2 + 0.22) kg x 9.81 m/s^2 = 23.74 N.
        let e = bad(|c| c.actuator.thrust_max = 5.0);
        assert_eq!(e.key, "actuator.thrust_max");
        assert!(
            e.message.contains("too small to hover")
                && e.message.contains("vehicle.mass + payload.mass"),
            "{e}"
        );
        // Exactly the weight on four rotors still hovers; a heavier payload does not.
        c.actuator.thrust_max = (2.2 + 0.22) * 9.81 / 4.0;
        c.validate().expect("thrust_max = hover holds hover");
        let e = bad(|c| c.payload.mass = 3.0);
        assert_eq!(e.key, "actuator.thrust_max");
        let e = bad(|c| c.actuator.thrust_min = 6.0);
        assert_eq!(e.key, "actuator.thrust_min");
        assert!(e.message.contains("too large to hover"), "{e}");
        let e = bad(|c| c.actuator.time_constant = 1e-4);
        assert_eq!(e.key, "actuator.time_constant");
        assert!(e.message.contains("integrator.dt"), "{e}");
        let e = bad(|c| c.vehicle.arm_length = 0.0);
        assert_eq!(e.key, "vehicle.arm_length");
        for (edit, key) in [
            (
                (|c: &mut Config| c.actuator.thrust_coefficient = 0.0) as fn(&mut Config),
                "actuator.thrust_coefficient",
            ),
            (|c| c.actuator.torque_ratio = -0.01, "actuator.torque_ratio"),
            (
                |c| c.actuator.time_constant = f64::NAN,
                "actuator.time_constant",
            ),
            (|c| c.actuator.thrust_min = -1.0, "actuator.thrust_min"),
            (|c| c.actuator.thrust_max = 0.0, "actuator.thrust_max"),
        ] {
            assert_eq!(bad(edit).key, key);
            // Checked with ideal actuators too: one set of rules.
            let mut c = paper();
            edit(&mut c);
            assert_eq!(c.validate().unwrap_err().key, key);
        }
        // What only rotors need is not asked of ideal actuators.
        let mut c = paper();
        c.actuator.thrust_max = 1.0;
        c.actuator.time_constant = 1e-6;
        c.vehicle.arm_length = 0.0;
        c.validate().expect("ideal actuators fly no rotors");
        let e = with(|v| v["actuator"]["layout"] = "y".into()).unwrap_err();
        assert_eq!(e.key, "actuator.layout");
        let e = with(|v| v["actuator"]["model"] = "jets".into()).unwrap_err();
        assert_eq!(e.key, "actuator.model");
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
    fn rotor_geometry_the_allocation_cannot_invert_is_refused() {
        let rotors = |edit: fn(&mut Config)| {
            let mut c = paper();
            c.actuator.model = ActuatorModelName::Rotors;
            edit(&mut c);
            c.validate()
        };
        for (edit, key) in [
            (
                (|c: &mut Config| c.vehicle.arm_length = 1e155) as fn(&mut Config),
                "vehicle.arm_length",
            ),
            (
                |c| c.actuator.torque_ratio = 5e-324,
                "actuator.torque_ratio",
            ),
            (
                |c| c.actuator.torque_ratio = 1e-310,
                "actuator.torque_ratio",
            ),
        ] {
            let e = rotors(edit).unwrap_err();
            assert_eq!(e.key, key, "{e}");
            assert!(e.message.contains("impossible to invert"), "{e}");
        }
        rotors(|c| c.vehicle.arm_length = 2.0).expect("a large but invertible vehicle");
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

    #[test]
    fn gust_words_are_one_vocabulary() {
        // serde's spelling, `key`/`name` and `FromStr` agree, so the scenario, the messages
        // and `gust_series` all read the same words.
        for m in GustModel::ALL {
            assert_eq!(serde_json::to_value(m).unwrap(), m.key());
            assert_eq!(m.key().parse::<GustModel>(), Ok(m));
        }
        for c in GustComponent::ALL {
            assert_eq!(serde_json::to_value(c).unwrap(), c.name());
            assert_eq!(c.name().parse::<GustComponent>(), Ok(c));
            assert_eq!(GustComponent::ALL[c.index()], c);
        }
        assert_eq!(
            "karman".parse::<GustModel>().unwrap_err(),
            "model must be 'dryden' or 'von_karman', got \"karman\""
        );
        assert_eq!(
            "up".parse::<GustComponent>().unwrap_err(),
            "component must be 'longitudinal', 'lateral' or 'vertical', got \"up\""
        );
        let e = with(|v| v["gust"]["model"] = "karman".into()).unwrap_err();
        assert_eq!(e.key, "gust.model");
    }

    #[test]
    fn gust_values_name_their_key() {
        let bad = |edit: fn(&mut Config)| {
            let mut c = paper();
            edit(&mut c);
            c.validate().unwrap_err()
        };
        let e = bad(|c| c.gust.airspeed = GustAirspeed::Fixed(0.0));
        assert_eq!(e.key, "gust.airspeed");
        assert_eq!(
            e.message,
            "gust.airspeed must be > 0 (the Dryden filters are singular at zero airspeed), got 0.0"
        );
        let e = bad(|c| {
            c.gust.model = GustModel::VonKarman;
            c.gust.airspeed = GustAirspeed::Fixed(0.0);
        });
        assert!(e.message.contains("von Karman filters are singular"), "{e}");
        let e = bad(|c| c.gust.altitude = GustAltitude::Fixed(-1.0));
        assert_eq!(
            (e.key.as_str(), e.message.as_str()),
            ("gust.altitude", "gust.altitude must be > 0, got -1.0")
        );
        let e = bad(|c| c.gust.w20 = Some(-3.0));
        assert_eq!(e.message, "gust.w20 must be >= 0, got -3.0");
        let e = bad(|c| c.gust.end = 10.0);
        assert_eq!(e.key, "gust.end");
        assert!(e
            .message
            .starts_with("gust.end must not be before gust.start"));
        let e = bad(|c| c.gust.mean_wind[1] = f64::NAN);
        assert_eq!(e.key, "gust.mean_wind[1]");
        let e = bad(|c| c.gust.components = vec![GustComponent::Lateral; 2]);
        assert_eq!(e.message, "gust.components lists Lateral twice");
        // A disabled gust is still checked: the scenario is one set of rules.
        let e = bad(|c| {
            c.gust.enabled = false;
            c.gust.w20 = Some(-3.0);
        });
        assert_eq!(e.key, "gust.w20");
    }
}
