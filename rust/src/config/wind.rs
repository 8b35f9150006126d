//! Wind over the whole flight (docs/model.md, "Wind over the whole flight"): the `[wind]` table
//! (mean wind with its shear profile, discrete gusts) and the `gust.*` values that may follow
//! the vehicle (`gust.altitude = "vehicle"`, `gust.airspeed = "relative"`, `gust.intensity`).

//!
//! The wind sources' own types (their tables, checks, keys and physics) live in their files in
//! `gust/` (`gust::source`, docs/architecture.md "Wind"); they are named here for the `[wind]`
//! table that holds them.

use super::ConfigError;
pub use crate::gust::gusts::{discrete_gust, DiscreteGust, GustShape};
pub use crate::gust::steady::{
    shear_factor, shear_factor_with, shear_log_reference, Shear, DEFAULT_ROUGHNESS,
    REFERENCE_HEIGHT,
};
pub use crate::gust::table::{table_wind, TableBy, WindTable};
use serde::{Deserialize, Serialize};

/// m/s, default `gust.min_airspeed`: the floor of the relative airspeed convecting the
/// turbulence (the forming filters are singular at zero airspeed).
pub const DEFAULT_MIN_AIRSPEED: f64 = 1.0;

/// m/s per knot (1852 m / 3600 s).
pub const METRES_PER_SECOND_PER_KNOT: f64 = 1852.0 / 3600.0;

/// A number, or one word (the serde form of the keys below that take either).
#[derive(Serialize, Deserialize)]
#[serde(untagged)]
enum NumberOrWord {
    Number(f64),
    Word(String),
}

/// `gust.altitude`: a fixed altitude (m) or `"vehicle"` (the quadrotor's z at each step).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "NumberOrWord", into = "NumberOrWord")]
pub enum GustAltitude {
    Fixed(f64),
    Vehicle,
}

/// `gust.airspeed`: a fixed airspeed (m/s) or `"relative"` (the speed through the mean air).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "NumberOrWord", into = "NumberOrWord")]
pub enum GustAirspeed {
    Fixed(f64),
    Relative,
}

impl TryFrom<NumberOrWord> for GustAltitude {
    type Error = String;
    fn try_from(v: NumberOrWord) -> Result<Self, String> {
        match v {
            NumberOrWord::Number(x) => Ok(Self::Fixed(x)),
            NumberOrWord::Word(w) if w == "vehicle" => Ok(Self::Vehicle),
            NumberOrWord::Word(w) => Err(format!(
                "must be an altitude in m or \"vehicle\", got {w:?}"
            )),
        }
    }
}

impl From<GustAltitude> for NumberOrWord {
    fn from(v: GustAltitude) -> Self {
        match v {
            GustAltitude::Fixed(x) => Self::Number(x),
            GustAltitude::Vehicle => Self::Word("vehicle".into()),
        }
    }
}

impl TryFrom<NumberOrWord> for GustAirspeed {
    type Error = String;
    fn try_from(v: NumberOrWord) -> Result<Self, String> {
        match v {
            NumberOrWord::Number(x) => Ok(Self::Fixed(x)),
            NumberOrWord::Word(w) if w == "relative" => Ok(Self::Relative),
            NumberOrWord::Word(w) => Err(format!(
                "must be an airspeed in m/s or \"relative\", got {w:?}"
            )),
        }
    }
}

impl From<GustAirspeed> for NumberOrWord {
    fn from(v: GustAirspeed) -> Self {
        match v {
            GustAirspeed::Fixed(x) => Self::Number(x),
            GustAirspeed::Relative => Self::Word("relative".into()),
        }
    }
}

/// `gust.intensity`: the standard's named turbulence levels, W20 = 15, 30, 45 knots.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Intensity {
    Light,
    Moderate,
    Severe,
}

impl Intensity {
    /// W20 (m/s) of the level: 15, 30 or 45 knots (7.717, 15.433, 23.150 m/s).
    pub fn w20(self) -> f64 {
        let knots = match self {
            Self::Light => 15.0,
            Self::Moderate => 30.0,
            Self::Severe => 45.0,
        };
        knots * METRES_PER_SECOND_PER_KNOT
    }
}

/// The `[wind]` table: the keys of the wind sources (`gust/source.rs`: the mean wind with its
/// shear, the discrete gusts, a measured table), each kind's checks and keys in its own file.
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

pub(super) fn default_min_airspeed() -> f64 {
    DEFAULT_MIN_AIRSPEED
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
        crate::gust::AnySource::validate(self)
    }
}
