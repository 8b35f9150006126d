//! `[payload]`: the keys every payload kind shares (which kind flies, and the point mass on its
//! attachment) and their checks. Each kind's own keys are declared and checked in its file
//! (`model::payload::cable`), the section assembled from the registration `model::kinds!`
//! (`PayloadConfig`, read by `model::section`).

use super::PayloadKind;
use crate::config::params::{params, Params};
use crate::config::{ConfigError, OneOf};
use crate::model::ModelContext;

params! {
    /// The keys of `[payload]` every kind has.
    pub struct Shared {
        /// The payload model (default "spring").
        #[serde(default)]
        model: PayloadKind => "-", "Payload model";
        mass: f64 => "kg", "Payload mass", positive;
        /// Hz, fn with kc = mc (2 pi fn)^2. Exactly one of this and `stiffness`.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        natural_frequency: Option<f64> => "Hz", "Attachment natural frequency", positive;
        /// N/m.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        stiffness: Option<f64> => "N/m", "Attachment stiffness", positive;
        damping: f64 => "N s/m", "Attachment damping", non_negative;
        /// m^2, Cd times projected area for vertical drag (the cable's payload: in every direction).
        drag_area: f64 => "m^2", "Payload drag area", non_negative;
    }
}

/// The attachment's stiffness, given directly or as the natural frequency it has with the
/// payload's mass: exactly one of the two.
pub const ATTACHMENT: OneOf = OneOf {
    keys: ["payload.stiffness", "payload.natural_frequency"],
    named_if_both: 0,
};

impl Shared {
    /// Check every shared value; the first problem found is returned with its key.
    pub fn validate(&self, _cfg: &ModelContext) -> Result<(), ConfigError> {
        self.check_bounds("payload")?;
        ATTACHMENT.check([self.stiffness.is_some(), self.natural_frequency.is_some()])
    }
}
