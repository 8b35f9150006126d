//! The flight's setting and its end: `[environment]` (gravity), `[initial]` (where the vehicle
//! starts), `[integrator]` (the step and the duration), `[metrics]` (the spectra's rate),
//! `[divergence]` (the bounds past which a flight has diverged) and `[ground]` (the plane a
//! flight ends at), with their checks.

use super::params::{not_numbers, params, Params};
use super::{non_negative, ConfigError};
use serde::{Deserialize, Serialize};

params! {
    pub struct Environment {
        gravity: f64 => "m/s^2", "Gravity", positive;
    }
}

impl Environment {
    /// Check every value; the first problem found is returned with its key.
    pub fn validate(&self) -> Result<(), ConfigError> {
        self.check_bounds("environment")
    }
}

params! {
    pub struct Initial {
        /// m, quadrotor x, y, z; the payload starts at its hover equilibrium below it.
        position: [f64; 3] => "m", "Start position (x, y, z)", finite;
        /// rad, roll, pitch, yaw.
        attitude: [f64; 3] => "rad", "Start attitude (roll, pitch, yaw)", finite;
        /// How the flight starts: trimmed in the start's steady wind, or at rest as in still
        /// air (docs/model.md, "The start: trimmed in the wind").
        #[serde(default)]
        trim: Trim => "-", "Start state: \"wind\" (trimmed in the steady wind) or \"rest\"";
    }
}

/// `initial.trim`: the state a flight starts from.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Trim {
    /// In equilibrium with the steady wind at the start (mean wind, wind table, the turbulence's
    /// mean): tilted into it, the payload at its steady line angle, the rotors at their steady
    /// speeds; `rest` when that wind is zero.
    #[default]
    Wind,
    /// At rest as in still air: level (`initial.attitude`), the payload straight below.
    Rest,
}

not_numbers!(Trim);

impl Initial {
    /// Check every value; the first problem found is returned with its key.
    pub fn validate(&self) -> Result<(), ConfigError> {
        self.check_bounds("initial")?;
        for i in 0..2 {
            let a = self.attitude[i];
            if a.abs() >= std::f64::consts::FRAC_PI_2 {
                let key = format!("initial.attitude[{i}]");
                return Err(ConfigError::new(
                    &key,
                    format!("{key} (roll/pitch) must be within (-pi/2, pi/2) rad, got {a:?}"),
                ));
            }
        }
        Ok(())
    }
}

/// Most integration steps one flight may take (guards against hangs from a tiny dt).
pub const MAX_STEPS: f64 = 2.0e9;

params! {
    pub struct Integrator {
        dt: f64 => "s", "Integration step", positive;
        duration: f64 => "s", "Flight duration", positive;
    }
}

impl Integrator {
    /// Check every value; the first problem found is returned with its key.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let it = self;
        it.check_bounds("integrator")?;
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
        Ok(())
    }
}

params! {
    pub struct Metrics {
        /// Hz, rate at which e_o is block-averaged for the amplitude spectra.
        spectrum_rate: f64 => "Hz", "Spectrum sample rate", positive;
    }
}

impl Metrics {
    /// Check every value; the first problem found is returned with its key.
    pub fn validate(&self) -> Result<(), ConfigError> {
        self.check_bounds("metrics")
    }
}

params! {
    pub struct Divergence {
        /// m, a realisation whose quadrotor or payload strays further than this from the origin diverged.
        max_distance: f64 => "m", "Largest distance from the origin before divergence", positive;
        /// rad, a realisation whose roll or pitch exceeds this diverged.
        max_tilt: f64 => "rad", "Largest roll or pitch before divergence", positive;
        /// m/s, a realisation whose quadrotor or payload moves faster than this along any axis
        /// diverged: catches a numerically unstable step (finite but absurd states) early.
        #[serde(default = "default_max_speed")]
        max_speed: f64 => "m/s", "Largest speed along an axis before divergence", positive;
        /// rad/s, a realisation whose body rate p, q or r exceeds this diverged.
        #[serde(default = "default_max_rate")]
        max_rate: f64 => "rad/s", "Largest body rate before divergence", positive;
    }
}

impl Divergence {
    /// Check every value; the first problem found is returned with its key.
    pub fn validate(&self) -> Result<(), ConfigError> {
        self.check_bounds("divergence")
    }
}

fn default_max_speed() -> f64 {
    100.0
}

fn default_max_rate() -> f64 {
    100.0
}

params! {
    /// A flight whose quadrotor goes below `altitude` (m, its z) ends there with status `ground`
    /// when `enabled`. The quadrotor has no contact dynamics (the flight simply stops); a cable
    /// payload's parcel does, when `stiffness` is given: Hunt and Crossley's contact (a spring
    /// whose damping grows with the depth) with friction at `altitude` (docs/model.md, "The
    /// last metres"; `model::payload::cable`).
    #[derive(Default)]
    pub struct Ground {
        #[serde(default)]
        enabled: bool => "-", "Ground plane on";
        #[serde(default)]
        altitude: f64 => "m", "Ground altitude", finite;
        /// N/m, the ground's contact stiffness under the parcel (none: the parcel never meets it).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        stiffness: Option<f64> => "N/m", "Ground contact stiffness", positive;
        /// s/m, Hunt and Crossley's dissipation alpha: the normal force is
        /// stiffness x depth x (1 + alpha x the depth's rate) (default 0: elastic).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        dissipation: Option<f64> => "s/m", "Ground contact dissipation (Hunt and Crossley)";
        /// -, the Coulomb friction coefficient between parcel and ground (default 0).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        friction: Option<f64> => "-", "Ground friction coefficient";
    }
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

    /// Check every value (the start against the ground when it is on); the first problem
    /// found is returned with its key.
    pub fn validate(&self, initial: &Initial) -> Result<(), ConfigError> {
        let g = self;
        g.check_bounds("ground")?;
        // Not bounds: a damping or friction without the stiffness is refused as such first.
        for (key, x) in [
            ("ground.dissipation", g.dissipation),
            ("ground.friction", g.friction),
        ] {
            if let Some(x) = x {
                if g.stiffness.is_none() {
                    return Err(ConfigError::new(
                        key,
                        format!("{key} needs ground.stiffness (the parcel's contact), got {x:?} without it"),
                    ));
                }
                non_negative(key, x)?;
            }
        }
        let z0 = initial.position[2];
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
}
