//! The `[wind]` table (docs/model.md, "Wind over the whole flight"): the keys of the wind
//! sources (`source`: the mean wind with its shear, the discrete gusts, a measured table), each
//! kind's checks and keys in its own file.

use super::gusts::DiscreteGust;
use super::steady::{Shear, DEFAULT_ROUGHNESS};
use super::table::WindTable;
use crate::config::{ConfigError, Context};
use serde::{Deserialize, Serialize};

/// The `[wind]` table: each source's keys (`source`), its checks and keys in the source's file.
/// Absent: no wind outside the section-4 gust window (the paper's flight).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Wind {
    /// m/s, W20: the mean wind at 20 ft (6.096 m).
    #[serde(default)]
    pub speed: f64,
    /// deg, the direction the wind blows toward, counter-clockwise from +x.
    #[serde(default)]
    pub heading: f64,
    #[serde(default)]
    pub shear: Shear,
    /// m, z0 of the log profile.
    #[serde(default = "default_roughness")]
    pub roughness: f64,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub gusts: Vec<DiscreteGust>,
    /// A measured wind added to the others (`[wind.table]`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub table: Option<WindTable>,
}

fn default_roughness() -> f64 {
    DEFAULT_ROUGHNESS
}

impl Default for Wind {
    /// Every key at its serde default (no source blows): the defaults are the fields' own, so
    /// a source's table is one field here.
    fn default() -> Self {
        serde_json::from_str("{}").expect("every `[wind]` key has a default")
    }
}

impl Wind {
    /// No mean wind and no discrete gust (then the table is left out of the JSON form).
    pub fn is_default(&self) -> bool {
        *self == Self::default()
    }

    /// Check every value; the first problem found is returned with its key (each source's
    /// checks, in registration order: `gust::AnySource::validate`).
    pub fn validate(&self) -> Result<(), ConfigError> {
        super::AnySource::validate(self)
    }
}

/// What the wind sources and the wind field are built from: the sections below the kinds
/// (`config::Context`, read through it as `cfg.gust`, `cfg.integrator`) and the `[wind]` table.
#[derive(Debug, Clone, Copy)]
pub struct WindContext<'a> {
    pub sections: Context<'a>,
    pub wind: &'a Wind,
}

crate::config::reads_through!(WindContext => sections: Context);
