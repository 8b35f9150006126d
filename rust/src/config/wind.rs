//! Wind over the whole flight (docs/model.md, "Wind over the whole flight"): the `[wind]` table
//! (mean wind with its shear profile, discrete gusts) and the `gust.*` values that may follow
//! the vehicle (`gust.altitude = "vehicle"`, `gust.airspeed = "relative"`, `gust.intensity`).

//!
//! The `[wind]` table itself (`gust::Wind`) and its sources' own types (their tables, checks,
//! keys and physics) live in their files in `gust/` (`gust::source`, docs/architecture.md
//! "Wind").

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

pub(super) fn default_min_airspeed() -> f64 {
    DEFAULT_MIN_AIRSPEED
}
