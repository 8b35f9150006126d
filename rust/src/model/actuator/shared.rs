//! `[actuator]`: the key every actuator kind shares (which kind flies). Each kind's own keys
//! are declared and checked in its file (`model::actuator::rotors::params`), the section
//! assembled from the registration `model::kinds!` (`ActuatorConfig`, read by
//! `model::section`).

use super::{ActuatorConfig, ActuatorKind};
use crate::config::params::params;
use crate::config::ConfigError;
use crate::model::ModelContext;

params! {
    /// The keys of `[actuator]` every kind has.
    pub struct Shared {
        /// The actuator model (default "ideal").
        #[serde(default)]
        model: ActuatorKind => "-", "Actuator model";
    }
}

impl Shared {
    /// Nothing to check beyond the model's name (serde read it).
    pub fn validate(&self, _cfg: &ModelContext) -> Result<(), ConfigError> {
        Ok(())
    }
}

/// `[actuator]` left out: the ideal actuators, every kind's keys at their defaults.
pub fn absent() -> ActuatorConfig {
    ActuatorConfig::from_empty().expect("every actuator kind's key has a default")
}
