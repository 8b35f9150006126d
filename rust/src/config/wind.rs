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

/// A key that takes a number or one word: the enum `$Ty` with `Fixed(f64)` and the word's
/// variant, read and written through `NumberOrWord` (one rule for both keys below).
macro_rules! number_or_word {
    ($(#[$doc:meta])* $Ty:ident, $Word:ident = $word:literal, $what:literal) => {
        $(#[$doc])*
        #[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
        #[serde(try_from = "NumberOrWord", into = "NumberOrWord")]
        pub enum $Ty {
            Fixed(f64),
            $Word,
        }

        impl TryFrom<NumberOrWord> for $Ty {
            type Error = String;
            fn try_from(v: NumberOrWord) -> Result<Self, String> {
                match v {
                    NumberOrWord::Number(x) => Ok(Self::Fixed(x)),
                    NumberOrWord::Word(w) if w == $word => Ok(Self::$Word),
                    NumberOrWord::Word(w) => Err(format!(
                        concat!("must be ", $what, " or \"", $word, "\", got {:?}"),
                        w
                    )),
                }
            }
        }

        impl From<$Ty> for NumberOrWord {
            fn from(v: $Ty) -> Self {
                match v {
                    $Ty::Fixed(x) => Self::Number(x),
                    $Ty::$Word => Self::Word($word.into()),
                }
            }
        }
    };
}

number_or_word!(
    /// `gust.altitude`: a fixed altitude (m) or `"vehicle"` (the quadrotor's z at each step).
    GustAltitude,
    Vehicle = "vehicle",
    "an altitude in m"
);

number_or_word!(
    /// `gust.airspeed`: a fixed airspeed (m/s) or `"relative"` (the speed through the mean air).
    GustAirspeed,
    Relative = "relative",
    "an airspeed in m/s"
);

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
