//! Discrete gusts (`[[wind.gusts]]`, docs/model.md, "Wind over the whole flight"): 1-cosine
//! ramps and pulses in time, inertial, not turned by `wind.heading`. One source holds the
//! whole list and sums it in the list's order (from zero), so the scenario's gusts enter the
//! wind as one term.

use super::source::{Kinematics, Moment, WindSource};
use crate::config::keys::{Seg, Target};
use crate::config::params::{not_numbers, params, Field, Key, Params};
use crate::config::ConfigError;
use crate::gust::{Wind, WindContext};
use serde::{Deserialize, Serialize};

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

params! {
    /// One `[[wind.gusts]]` entry.
    #[derive(PartialEq)]
    pub struct DiscreteGust {
        /// s, when the gust begins.
        start: f64 => "s", "Discrete gust start", non_negative;
        /// s, D: the rise time of a ramp, the length of a pulse.
        duration: f64 => "s", "Discrete gust duration (rise or length)", positive;
        /// m/s, A: inertial x, y, z (not turned by `wind.heading`).
        amplitude: [f64; 3] => "m/s", "Discrete gust amplitude (x, y, z)", finite;
        #[serde(default)]
        shape: GustShape => "-", "Discrete gust shape (ramp or pulse)";
    }
}

not_numbers!(GustShape);

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

/// The `[[wind.gusts]]`, summed: not part of the mean air.
#[derive(Clone, Debug, PartialEq)]
pub struct Gusts(pub Vec<DiscreteGust>);

impl WindSource for Gusts {
    const MEAN_AIR: bool = false;
    fn keys() -> Vec<(String, Key)> {
        DiscreteGust::keys_under("gusts")
    }

    /// Blows where the scenario lists a gust.
    fn build(cfg: &WindContext) -> Option<Self> {
        let gusts = &cfg.wind.gusts;
        (!gusts.is_empty()).then(|| Gusts(gusts.clone()))
    }

    fn validate(wind: &Wind) -> Result<(), ConfigError> {
        for (i, g) in wind.gusts.iter().enumerate() {
            g.check_bounds(&format!("wind.gusts[{i}]"))?;
        }
        Ok(())
    }

    /// `wind.gusts[i].start`, `.duration`, `.amplitude[j]` are numbers; `.shape` is not (the
    /// entries' `params!` declaration).
    fn target<'w>(wind: &'w mut Wind, _field: &str, rest: &[Seg]) -> Target<'w> {
        Field::target(&mut wind.gusts, rest)
    }

    /// The sum of the gusts at `now.t`, from zero in the list's order.
    #[inline]
    fn at(&self, now: Moment, _kin: &Kinematics) -> [f64; 3] {
        let mut w = [0.0; 3];
        for g in &self.0 {
            for (w, x) in w.iter_mut().zip(discrete_gust(g, now.t)) {
                *w += x;
            }
        }
        w
    }

    #[inline]
    fn reads_vehicle(&self) -> bool {
        false
    }
}
