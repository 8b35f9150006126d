//! The `[wind]` mean wind with its shear profile (docs/model.md, "Wind over the whole flight"):
//! W20 f(h) (cos chi, sin chi, 0) at the quadrotor's altitude h, a wind source of the mean air
//! (the turbulence's relative airspeed is measured against it). Its keys are `[wind]`'s own:
//! `wind.speed`, `wind.heading` (which also turns the turbulence's axes), `wind.shear`,
//! `wind.roughness`.

use super::source::{Kinematics, Moment, WindSource};
use crate::lane::{explog, KernelOps};
use crate::config::keys::{Seg, Target};
use crate::config::params::{not_number, Field, Key};
use crate::config::{finite, non_negative, ConfigError};
use crate::gust::{Wind, WindContext};
use serde::{Deserialize, Serialize};

/// m, the MIL-F-8785C reference height of the mean wind (20 ft).
pub const REFERENCE_HEIGHT: f64 = 6.096;

/// m, default `wind.roughness`: MIL-F-8785C's 0.15 ft for terminal flight phases (take-off,
/// approach, landing), the closest to a small vehicle flying near the ground.
pub const DEFAULT_ROUGHNESS: f64 = 0.0457;

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

/// The shear factor f(h) of `wind.shear` at height `h` (m) with roughness `z0` (m): 1 for
/// `none`; `ln(h / z0) / ln(6.096 / z0)` for `log` when h > z0, else 0 (so exactly 1 at
/// 6.096 m, and a NaN height gives NaN). `ln` is the engine's lane-valued one
/// (`lane::explog::ln`, within 1 ulp), evaluated on `f64` here and per lane on the lane-set
/// path alike.
#[inline]
pub fn shear_factor(shear: Shear, h: f64, z0: f64) -> f64 {
    shear_factor_with(shear, h, z0, shear_log_reference(z0))
}

/// ln(20 ft / z0): the log profile's denominator, for [`shear_factor_with`].
#[inline]
pub fn shear_log_reference(z0: f64) -> f64 {
    explog::ln(REFERENCE_HEIGHT / z0)
}

/// [`shear_factor`] with its denominator computed once (`log_reference =
/// shear_log_reference(z0)`): the same bits, one logarithm per call instead of two.
#[inline]
pub fn shear_factor_with(shear: Shear, h: f64, z0: f64, log_reference: f64) -> f64 {
    match shear {
        Shear::None => 1.0,
        Shear::Log if h > z0 => explog::ln(h / z0) / log_reference,
        Shear::Log if h.is_nan() => f64::NAN,
        Shear::Log => 0.0,
    }
}

/// The `[wind]` mean wind: W20 f(h) (cos chi, sin chi, 0).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Steady {
    w20: f64,
    shear: Shear,
    roughness: f64,
    /// ln(20 ft / z0), f(h)'s denominator, computed once (`shear_log_reference`).
    log_reference: f64,
    cos: f64,
    sin: f64,
}

/// `[wind]`'s keys of the mean wind.
const KEYS: [Key; 4] = [
    Key {
        name: "speed",
        unit: "m/s",
        label: "Mean wind at 20 ft (W20)",
    },
    Key {
        name: "heading",
        unit: "deg",
        label: "Wind heading (toward, from +x)",
    },
    Key {
        name: "shear",
        unit: "-",
        label: "Mean wind shear profile",
    },
    Key {
        name: "roughness",
        unit: "m",
        label: "Surface roughness z0",
    },
];

impl WindSource for Steady {
    const MEAN_AIR: bool = true;
    /// Fields of `[wind]` itself (`gust::Wind`), not a table of its own.
    fn keys() -> Vec<(String, Key)> {
        KEYS.iter().map(|k| (k.name.to_string(), *k)).collect()
    }

    /// Blows where `wind.speed` is not 0.
    fn build(cfg: &WindContext) -> Option<Self> {
        let wind = &cfg.wind;
        let chi = wind.heading.to_radians();
        (wind.speed != 0.0).then_some(Steady {
            w20: wind.speed,
            shear: wind.shear,
            roughness: wind.roughness,
            log_reference: shear_log_reference(wind.roughness),
            cos: chi.cos(),
            sin: chi.sin(),
        })
    }

    fn validate(wind: &Wind) -> Result<(), ConfigError> {
        non_negative("wind.speed", wind.speed)?;
        finite("wind.heading", wind.heading)?;
        let z0 = wind.roughness;
        if !(z0.is_finite() && z0 > 0.0 && z0 < REFERENCE_HEIGHT) {
            return Err(ConfigError::new(
                "wind.roughness",
                format!(
                    "wind.roughness must be > 0 and below the 20 ft reference height \
                     ({REFERENCE_HEIGHT} m), got {z0:?}"
                ),
            ));
        }
        Ok(())
    }

    fn target<'w>(wind: &'w mut Wind, field: &str, rest: &[Seg]) -> Target<'w> {
        match field {
            "speed" => Field::target(&mut wind.speed, rest),
            "heading" => Field::target(&mut wind.heading, rest),
            "roughness" => Field::target(&mut wind.roughness, rest),
            _ => not_number(rest), // shear
        }
    }

    #[inline]
    fn at(&self, _now: Moment, kin: &Kinematics) -> [f64; 3] {
        let f = shear_factor_with(self.shear, kin.z, self.roughness, self.log_reference);
        let s = self.w20 * f;
        [s * self.cos, s * self.sin, 0.0]
    }

    #[inline]
    fn reads_vehicle(&self) -> bool {
        self.shear != Shear::None
    }
}

/// The `[wind]` mean wind of a whole lane-set in lane values, each lane with its own
/// realisation's W20, heading and roughness (gathered once, when the lane-set is built): the
/// same operations in the same order as [`Steady::at`] (`shear_factor_with`'s, the log
/// profile's `ln` on the lane type), so each lane's wind is bitwise its scalar one. Only for
/// lanes alike in their shear kind.
#[derive(Clone, Copy)]
pub(super) struct SteadyLanes<L> {
    shear: Shear,
    w20: L,
    roughness: L,
    log_reference: L,
    cos: L,
    sin: L,
}

impl<L: KernelOps> SteadyLanes<L> {
    /// Lane `l` flying `lanes[l]`; `None` where the lanes' shear kinds differ.
    pub(super) fn new(lanes: &[&Steady]) -> Option<Self> {
        assert_eq!(lanes.len(), L::LANES, "one mean wind per lane");
        let shear = lanes[0].shear;
        if lanes.iter().any(|s| s.shear != shear) {
            return None;
        }
        let get = |f: fn(&Steady) -> f64| L::from_fn(|l| f(lanes[l]));
        Some(SteadyLanes {
            shear,
            w20: get(|s| s.w20),
            roughness: get(|s| s.roughness),
            log_reference: get(|s| s.log_reference),
            cos: get(|s| s.cos),
            sin: get(|s| s.sin),
        })
    }

    /// Every lane's [`Steady::at`] at altitudes `h` (m), bit for bit: f(h) as
    /// `shear_factor_with` computes it (its branches as selects, the canonical NaN for a NaN
    /// height), then `W20 f (cos chi, sin chi, 0)`.
    #[inline(always)]
    pub(super) fn at(&self, h: L) -> [L; 3] {
        let f = match self.shear {
            Shear::None => L::splat(1.0),
            Shear::Log => {
                let log = explog::ln(h / self.roughness) / self.log_reference;
                let f = L::select(h.cmp_le(self.roughness), L::splat(0.0), log);
                L::select(h.cmp_ne(h), L::splat(f64::NAN), f)
            }
        };
        let s = self.w20 * f;
        [s * self.cos, s * self.sin, L::splat(0.0)]
    }
}
