//! Wind over the whole flight (docs/model.md, "Wind over the whole flight"): the `[wind]` table
//! (mean wind with its shear profile, discrete gusts) and the `gust.*` values that may follow
//! the vehicle (`gust.altitude = "vehicle"`, `gust.airspeed = "relative"`, `gust.intensity`).

use super::params::Key;
use super::{finite, non_negative, positive, ConfigError};
use serde::{Deserialize, Serialize};

/// m, the MIL-F-8785C reference height of the mean wind (20 ft).
pub const REFERENCE_HEIGHT: f64 = 6.096;

/// m, default `wind.roughness`: MIL-F-8785C's 0.15 ft for terminal flight phases (take-off,
/// approach, landing), the closest to a small vehicle flying near the ground.
pub const DEFAULT_ROUGHNESS: f64 = 0.0457;

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

/// `wind.shear`: the mean wind's profile with height.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Shear {
    /// f(h) = 1: the same wind at every height.
    #[default]
    None,
    /// MIL-F-8785C: f(h) = ln(h / z0) / ln(6.096 / z0) for h > z0, else 0.
    Log,
}

/// `wind.gusts[i].shape`: the 1-cosine discrete gust.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum GustShape {
    /// A/2 (1 - cos(pi tau / D)) for 0 <= tau <= D, then A (MIL-F-8785C).
    #[default]
    Ramp,
    /// A/2 (1 - cos(2 pi tau / D)) for 0 <= tau <= D, then 0.
    Pulse,
}

/// One `[[wind.gusts]]` entry.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DiscreteGust {
    /// s, when the gust begins.
    pub start: f64,
    /// s, D: the rise time of a ramp, the length of a pulse.
    pub duration: f64,
    /// m/s, A: inertial x, y, z (not turned by `wind.heading`).
    pub amplitude: [f64; 3],
    #[serde(default)]
    pub shape: GustShape,
}

/// `wind.table.by`: what a wind table's first column is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TableBy {
    /// s, the time since the start of the flight.
    Time,
    /// m, the quadrotor's altitude z.
    Altitude,
}

/// `[wind.table]`: a measured wind, (t or z, wind_x, wind_y, wind_z) rows interpolated
/// linearly and held at the end rows' values outside them (docs/model.md, "A measured wind").
/// The Python layer reads the rows from the CSV file the scenario names (`file`), so the
/// engine receives the numbers, not the path.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WindTable {
    pub by: TableBy,
    /// Rows of (t s or z m, wind_x, wind_y, wind_z m/s inertial), the first column strictly
    /// increasing.
    pub points: Vec<[f64; 4]>,
}

impl WindTable {
    /// `[wind.table]`'s keys with their units and labels (dotted, indices dropped); its `file`
    /// is read in Python and never reaches the engine.
    pub fn keys() -> Vec<(String, Key)> {
        const KEYS: [Key; 2] = [
            Key {
                name: "by",
                unit: "-",
                label: "Wind table by time or altitude",
            },
            Key {
                name: "points",
                unit: "[s or m, m/s, m/s, m/s]",
                label: "Wind table rows (t or z, wind x, y, z)",
            },
        ];
        KEYS.iter()
            .map(|k| (format!("wind.table.{}", k.name), *k))
            .collect()
    }

    fn validate(&self) -> Result<(), ConfigError> {
        if self.points.is_empty() {
            return Err(ConfigError::new(
                "wind.table.points",
                "wind.table.points needs at least one row (t or z, wind_x, wind_y, wind_z), got none",
            ));
        }
        for (i, row) in self.points.iter().enumerate() {
            for (j, x) in row.iter().enumerate() {
                finite(format_args!("wind.table.points[{i}][{j}]"), *x)?;
            }
            if i > 0 && row[0] <= self.points[i - 1][0] {
                let key = format!("wind.table.points[{i}][0]");
                let what = match self.by {
                    TableBy::Time => "time",
                    TableBy::Altitude => "altitude",
                };
                return Err(ConfigError::new(
                    &key,
                    format!(
                        "{key} ({what}) must be greater than the row before's ({:?}): the rows \
                         in increasing {what}, got {:?}",
                        self.points[i - 1][0],
                        row[0]
                    ),
                ));
            }
        }
        Ok(())
    }
}

/// The wind (m/s, inertial) of a table's `points` at `x` (s or m): linear between the rows,
/// the first row's below them and the last's above (held); NaN at a NaN `x`.
#[inline]
pub fn table_wind(points: &[[f64; 4]], x: f64) -> [f64; 3] {
    let (first, last) = (points[0], points[points.len() - 1]);
    if x.is_nan() {
        return [f64::NAN; 3];
    }
    if x <= first[0] {
        return [first[1], first[2], first[3]];
    }
    if x >= last[0] {
        return [last[1], last[2], last[3]];
    }
    // The first row past x: 1..len-1, as x lies strictly inside.
    let i = points.partition_point(|p| p[0] <= x);
    let (a, b) = (points[i - 1], points[i]);
    let f = (x - a[0]) / (b[0] - a[0]);
    [1, 2, 3].map(|j| a[j] + (b[j] - a[j]) * f)
}

/// The `[wind]` table: a mean wind over the whole flight and discrete gusts. Absent: no wind
/// outside the section-4 gust window (the paper's flight).
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
    fn default() -> Self {
        Self {
            speed: 0.0,
            heading: 0.0,
            shear: Shear::None,
            roughness: DEFAULT_ROUGHNESS,
            gusts: Vec::new(),
            table: None,
        }
    }
}

impl Wind {
    /// No mean wind and no discrete gust (then the table is left out of the JSON form).
    pub fn is_default(&self) -> bool {
        *self == Self::default()
    }

    /// Whether anything blows outside the gust window: a mean wind, a discrete gust or a table.
    pub fn blows(&self) -> bool {
        self.speed != 0.0 || !self.gusts.is_empty() || self.table.is_some()
    }

    /// Check every value; the first problem found is returned with its key.
    pub fn validate(&self) -> Result<(), ConfigError> {
        non_negative("wind.speed", self.speed)?;
        finite("wind.heading", self.heading)?;
        let z0 = self.roughness;
        if !(z0.is_finite() && z0 > 0.0 && z0 < REFERENCE_HEIGHT) {
            return Err(ConfigError::new(
                "wind.roughness",
                format!(
                    "wind.roughness must be > 0 and below the 20 ft reference height \
                     ({REFERENCE_HEIGHT} m), got {z0:?}"
                ),
            ));
        }
        for (i, g) in self.gusts.iter().enumerate() {
            non_negative(format_args!("wind.gusts[{i}].start"), g.start)?;
            positive(format_args!("wind.gusts[{i}].duration"), g.duration)?;
            for (j, a) in g.amplitude.iter().enumerate() {
                finite(format_args!("wind.gusts[{i}].amplitude[{j}]"), *a)?;
            }
        }
        if let Some(t) = &self.table {
            t.validate()?;
        }
        Ok(())
    }
}

/// The shear factor f(h) of `wind.shear` at height `h` (m) with roughness `z0` (m): 1 for
/// `none`; `ln(h / z0) / ln(6.096 / z0)` for `log` when h > z0, else 0 (so exactly 1 at
/// 6.096 m, and a NaN height gives NaN).
#[inline]
pub fn shear_factor(shear: Shear, h: f64, z0: f64) -> f64 {
    shear_factor_with(shear, h, z0, shear_log_reference(z0))
}

/// ln(20 ft / z0): the log profile's denominator, for [`shear_factor_with`].
#[inline]
pub fn shear_log_reference(z0: f64) -> f64 {
    (REFERENCE_HEIGHT / z0).ln()
}

/// [`shear_factor`] with its denominator computed once (`log_reference =
/// shear_log_reference(z0)`): the same bits, one logarithm per call instead of two.
#[inline]
pub fn shear_factor_with(shear: Shear, h: f64, z0: f64, log_reference: f64) -> f64 {
    match shear {
        Shear::None => 1.0,
        Shear::Log if h > z0 => (h / z0).ln() / log_reference,
        Shear::Log if h.is_nan() => f64::NAN,
        Shear::Log => 0.0,
    }
}

/// The velocity (m/s, inertial) of one discrete gust at time `t` (s).
#[inline]
pub fn discrete_gust(g: &DiscreteGust, t: f64) -> [f64; 3] {
    let tau = t - g.start;
    if tau.is_nan() || tau < 0.0 {
        return [0.0; 3];
    }
    let pi = std::f64::consts::PI;
    let f = match g.shape {
        GustShape::Ramp if tau <= g.duration => 0.5 * (1.0 - (pi * (tau / g.duration)).cos()),
        GustShape::Ramp => 1.0,
        GustShape::Pulse if tau <= g.duration => {
            0.5 * (1.0 - (2.0 * pi * (tau / g.duration)).cos())
        }
        GustShape::Pulse => 0.0,
    };
    g.amplitude.map(|a| a * f)
}
