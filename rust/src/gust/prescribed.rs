//! A wind prescribed step by step (`Engine::with_wind`, `quadrs.simulate(..., wind=...)`): row
//! k held over step k, flown instead of the turbulence and added to the scenario's other
//! sources, last. Not from the scenario: it has no keys.

use super::source::{Kinematics, Moment, WindSource};
use crate::config::keys::{Seg, Target};
use crate::config::params::Key;
use crate::config::ConfigError;
use crate::gust::{Wind, WindContext};
use std::sync::Arc;

/// The rows of a prescribed wind (m/s, inertial), one per step; NaN past the last row (a
/// flight longer than the rows ends as non-finite rather than inventing numbers).
#[derive(Clone, Debug, PartialEq)]
pub struct Prescribed(pub Arc<[[f64; 3]]>);

impl WindSource for Prescribed {
    const MEAN_AIR: bool = false;
    /// Never in the scenario: no key.
    fn keys() -> Vec<(String, Key)> {
        Vec::new()
    }

    /// Never from the scenario (`WindField::prescribed` adds it).
    fn build(_cfg: &WindContext) -> Option<Self> {
        None
    }

    fn validate(_wind: &Wind) -> Result<(), ConfigError> {
        Ok(())
    }

    fn target<'w>(_wind: &'w mut Wind, _field: &str, _rest: &[Seg]) -> Target<'w> {
        Target::Missing
    }

    #[inline]
    fn at(&self, now: Moment, _kin: &Kinematics) -> [f64; 3] {
        usize::try_from(now.step)
            .ok()
            .and_then(|k| self.0.get(k).copied())
            .unwrap_or([f64::NAN; 3])
    }

    #[inline]
    fn reads_vehicle(&self) -> bool {
        false
    }
}
