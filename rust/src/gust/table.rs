//! A measured wind (`[wind.table]`, docs/model.md, "A measured wind"): (t or z, wind_x,
//! wind_y, wind_z) rows interpolated linearly and held at the end rows' values outside them, a
//! source of the mean air. The Python layer reads the rows from the CSV file the scenario
//! names (`file`), so the engine receives the numbers, not the path.

use super::source::{Kinematics, Moment, WindSource};
use crate::config::keys::{Seg, Target};
use crate::config::params::{not_numbers, params, Field, Key, Params};
use crate::config::ConfigError;
use crate::gust::{Wind, WindContext};
use serde::{Deserialize, Serialize};

/// `wind.table.by`: what a wind table's first column is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TableBy {
    /// s, the time since the start of the flight.
    Time,
    /// m, the quadrotor's altitude z.
    Altitude,
}

params! {
    /// `[wind.table]`: the rows of a measured wind, by time or by altitude.
    #[derive(PartialEq)]
    pub struct WindTable {
        by: TableBy => "-", "Wind table by time or altitude";
        /// Rows of (t s or z m, wind_x, wind_y, wind_z m/s inertial), the first column strictly
        /// increasing.
        points: Vec<[f64; 4]> => "[s or m, m/s, m/s, m/s]", "Wind table rows (t or z, wind x, y, z)", finite;
    }
}

not_numbers!(TableBy);

impl WindTable {
    /// `[wind.table]`'s keys with their units and labels (dotted, indices dropped); its `file`
    /// is read in Python and never reaches the engine.
    pub fn keys() -> Vec<(String, Key)> {
        super::source::keys_of::<Table>()
    }

    fn validate(&self) -> Result<(), ConfigError> {
        if self.points.is_empty() {
            return Err(ConfigError::new(
                "wind.table.points",
                "wind.table.points needs at least one row (t or z, wind_x, wind_y, wind_z), got none",
            ));
        }
        self.check_bounds("wind.table")?;
        for (i, row) in self.points.iter().enumerate() {
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

/// The `[wind.table]` as a wind source: part of the mean air.
#[derive(Clone, Debug, PartialEq)]
pub struct Table(pub WindTable);

impl WindSource for Table {
    const MEAN_AIR: bool = true;
    fn keys() -> Vec<(String, Key)> {
        WindTable::keys_under("table")
    }

    /// Blows where the scenario has a `[wind.table]`.
    fn build(cfg: &WindContext) -> Option<Self> {
        cfg.wind.table.clone().map(Table)
    }

    fn validate(wind: &Wind) -> Result<(), ConfigError> {
        wind.table.as_ref().map_or(Ok(()), WindTable::validate)
    }

    /// `wind.table.points[i][j]` are numbers; `wind.table.by` is not (the table's `params!`
    /// declaration).
    fn target<'w>(wind: &'w mut Wind, _field: &str, rest: &[Seg]) -> Target<'w> {
        Field::target(&mut wind.table, rest)
    }

    #[inline]
    fn at(&self, now: Moment, kin: &Kinematics) -> [f64; 3] {
        let x = match self.0.by {
            TableBy::Time => now.t,
            TableBy::Altitude => kin.z,
        };
        table_wind(&self.0.points, x)
    }

    #[inline]
    fn reads_vehicle(&self) -> bool {
        self.0.by == TableBy::Altitude
    }
}
