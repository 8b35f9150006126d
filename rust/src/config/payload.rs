//! `[payload]`: which payload model flies, its parameters and their checks (the models
//! themselves are `model::payload`).

use super::params::{not_numbers, params};
use super::{non_negative, positive, ConfigError};
use serde::{Deserialize, Serialize};

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

not_numbers!(PayloadModelName);

params! {
    pub struct Payload {
        /// The payload model (default "spring").
        #[serde(default)]
        model: PayloadModelName => "-", "Payload model";
        mass: f64 => "kg", "Payload mass";
        /// Hz, fn with kc = mc (2 pi fn)^2. Exactly one of this and `stiffness`.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        natural_frequency: Option<f64> => "Hz", "Attachment natural frequency";
        /// N/m.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        stiffness: Option<f64> => "N/m", "Attachment stiffness";
        damping: f64 => "N s/m", "Attachment damping";
        /// m^2, Cd times projected area for vertical drag (the cable's payload: in every direction).
        drag_area: f64 => "m^2", "Payload drag area";
        /// m, the cable's unstretched length L0 (`model = "cable"` only; required there).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        cable_length: Option<f64> => "m", "Cable length, unstretched";
        /// m, the hook's distance below the centre of gravity along the body z axis
        /// (`model = "cable"` only; default 0).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        attachment_offset: Option<f64> => "m", "Hook below the centre of gravity";
    }
}

impl Payload {
    /// m, the cable's hook below the centre of gravity (0 unless given).
    pub fn attachment_offset(&self) -> f64 {
        self.attachment_offset.unwrap_or(0.0)
    }

    /// Check every value; the first problem found is returned with its key.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let p = self;
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
        Ok(())
    }
}
