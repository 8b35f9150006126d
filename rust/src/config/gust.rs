//! `[gust]`: the section-4 turbulence (which spectrum, which components, its window, altitude,
//! intensity and airspeed) and its checks (the wind itself is `crate::gust`).

use super::params::{not_number, not_numbers, params, Field, Params, Seg, Target};
use super::wind::{self, GustAirspeed, GustAltitude, Intensity};
use super::{non_negative, positive, ConfigError, OneOf};
use serde::{Deserialize, Serialize};

/// Which spectrum the gust's forming filters realise (`gust.model`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum GustModel {
    /// MIL-F-8785C Dryden (rational, exact).
    Dryden,
    /// von Karman, through the published 2nd/3rd-order rational approximants
    /// (MIL-HDBK-1797; MATLAB "Von Karman Wind Turbulence Model (Continuous)").
    VonKarman,
}

impl GustModel {
    pub const ALL: [GustModel; 2] = [GustModel::Dryden, GustModel::VonKarman];

    /// Human-readable name used in messages.
    pub fn name(self) -> &'static str {
        match self {
            GustModel::Dryden => "Dryden",
            GustModel::VonKarman => "von Karman",
        }
    }

    /// The scenario's spelling (what serde reads and writes).
    pub fn key(self) -> &'static str {
        match self {
            GustModel::Dryden => "dryden",
            GustModel::VonKarman => "von_karman",
        }
    }
}

/// Gust velocity component, along the inertial axes: x (longitudinal), y (lateral),
/// z (vertical, z up) (`gust.components`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum GustComponent {
    Longitudinal,
    Lateral,
    Vertical,
}

impl GustComponent {
    /// All components in the fixed draw order.
    pub const ALL: [GustComponent; 3] = [
        GustComponent::Longitudinal,
        GustComponent::Lateral,
        GustComponent::Vertical,
    ];

    /// Axis index: 0 (x), 1 (y), 2 (z).
    pub fn index(self) -> usize {
        match self {
            GustComponent::Longitudinal => 0,
            GustComponent::Lateral => 1,
            GustComponent::Vertical => 2,
        }
    }

    /// Lower-case name used in messages; also the scenario's spelling.
    pub fn name(self) -> &'static str {
        match self {
            GustComponent::Longitudinal => "longitudinal",
            GustComponent::Lateral => "lateral",
            GustComponent::Vertical => "vertical",
        }
    }
}

/// `'a', 'b' or 'c'`.
fn one_of(keys: &[&str]) -> String {
    let quoted: Vec<String> = keys.iter().map(|k| format!("'{k}'")).collect();
    match quoted.split_last() {
        Some((last, [])) => last.clone(),
        Some((last, rest)) => format!("{} or {last}", rest.join(", ")),
        None => String::new(),
    }
}

not_numbers!(GustModel, GustComponent, Intensity);

/// A fixed altitude is a number; `"vehicle"` is a word.
impl Field for GustAltitude {
    fn target(&mut self, rest: &[Seg]) -> Target<'_> {
        match self {
            GustAltitude::Fixed(h) => h.target(rest),
            GustAltitude::Vehicle => not_number(rest),
        }
    }
}

/// A fixed airspeed is a number; `"relative"` is a word.
impl Field for GustAirspeed {
    fn target(&mut self, rest: &[Seg]) -> Target<'_> {
        match self {
            GustAirspeed::Fixed(v) => v.target(rest),
            GustAirspeed::Relative => not_number(rest),
        }
    }
}

impl std::str::FromStr for GustModel {
    type Err = String;

    /// From the scenario's spelling (`"dryden"`, `"von_karman"`).
    fn from_str(s: &str) -> Result<Self, String> {
        Self::ALL.into_iter().find(|m| m.key() == s).ok_or_else(|| {
            let keys: Vec<&str> = Self::ALL.iter().map(|m| m.key()).collect();
            format!("model must be {}, got {s:?}", one_of(&keys))
        })
    }
}

impl std::str::FromStr for GustComponent {
    type Err = String;

    /// From the scenario's spelling (`"longitudinal"`, `"lateral"`, `"vertical"`).
    fn from_str(s: &str) -> Result<Self, String> {
        Self::ALL
            .into_iter()
            .find(|c| c.name() == s)
            .ok_or_else(|| {
                let keys: Vec<&str> = Self::ALL.iter().map(|c| c.name()).collect();
                format!("component must be {}, got {s:?}", one_of(&keys))
            })
    }
}

params! {
    pub struct Gust {
        enabled: bool => "-", "Turbulence on";
        model: GustModel => "-", "Turbulence spectrum";
        components: Vec<GustComponent> => "-", "Turbulence components";
        /// s, the gust window [start, end).
        start: f64 => "s", "Turbulence start", non_negative;
        end: f64 => "s", "Turbulence end", finite;
        /// m above ground (converted to feet for the MIL-F-8785C scale formulas), or `"vehicle"`:
        /// the quadrotor's z at each step, clamped to [10 ft, 1000 ft].
        altitude: GustAltitude => "m", "Altitude of the gust model";
        /// m/s, wind speed at 20 ft for the turbulence. Exactly one of this and `intensity`.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        w20: Option<f64> => "m/s", "Wind at 20 ft";
        /// The standard's named level (W20 = 15, 30, 45 kt), instead of `w20`.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        intensity: Option<Intensity> => "-", "Turbulence intensity level";
        /// m/s, the speed at which the frozen turbulence is convected past the vehicle, or
        /// `"relative"`: max(|v - mean(h)|, `min_airspeed`) at each step.
        airspeed: GustAirspeed => "m/s", "Airspeed";
        /// m/s, the floor of the relative airspeed.
        #[serde(default = "wind::default_min_airspeed")]
        min_airspeed: f64 => "m/s", "Least relative airspeed";
        /// kg/m^3.
        air_density: f64 => "kg/m^3", "Air density", non_negative;
        /// m/s, inertial x, y, z, added to the gust inside the window.
        mean_wind: [f64; 3] => "m/s", "Mean wind in the gust window (x, y, z)", finite;
        /// Hz, the rate the wind is evaluated at (docs/model.md, "Loop rates"): the turbulence filters
        /// discretised at its period, the wind linearly interpolated between its updates; 0
        /// (the default): every step.
        #[serde(default, skip_serializing_if = "is_zero")]
        rate: f64 => "Hz", "Wind update rate (0: every step)", non_negative;
    }
}

fn is_zero(x: &f64) -> bool {
    *x == 0.0
}

/// The turbulence's level, as W20 or as the standard's named level: exactly one of the two.
pub const TURBULENCE_LEVEL: OneOf = OneOf {
    keys: ["gust.w20", "gust.intensity"],
    named_if_both: 1,
};

impl Gust {
    /// Check every value; the first problem found is returned with its key.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let g = self;
        g.check_bounds("gust")?;
        if g.end < g.start {
            return Err(ConfigError::new(
                "gust.end",
                format!(
                    "gust.end must not be before gust.start ({:?} s), got {:?}",
                    g.start, g.end
                ),
            ));
        }
        if let GustAltitude::Fixed(h) = g.altitude {
            positive("gust.altitude", h)?;
        }
        TURBULENCE_LEVEL.check([g.w20.is_some(), g.intensity.is_some()])?;
        if let Some(w) = g.w20 {
            non_negative("gust.w20", w)?;
        }
        if let GustAirspeed::Fixed(v) = g.airspeed {
            if !(v.is_finite() && v > 0.0) {
                return Err(ConfigError::new(
                    "gust.airspeed",
                    format!(
                        "gust.airspeed must be > 0 (the {} filters are singular at zero airspeed), got {:?}",
                        g.model.name(),
                        v
                    ),
                ));
            }
        }
        if !(g.min_airspeed.is_finite() && g.min_airspeed > 0.0) {
            return Err(ConfigError::new(
                "gust.min_airspeed",
                format!(
                    "gust.min_airspeed must be > 0 (the {} filters are singular at zero airspeed), got {:?}",
                    g.model.name(),
                    g.min_airspeed
                ),
            ));
        }
        for (i, c) in g.components.iter().enumerate() {
            if g.components[..i].contains(c) {
                return Err(ConfigError::new(
                    "gust.components",
                    format!("gust.components lists {c:?} twice"),
                ));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::tests::{paper, with};
    use crate::scenario::Config;

    #[test]
    fn gust_words_are_one_vocabulary() {
        // serde's spelling, `key`/`name` and `FromStr` agree, so the scenario, the messages
        // and `gust_series` all read the same words.
        for m in GustModel::ALL {
            assert_eq!(serde_json::to_value(m).unwrap(), m.key());
            assert_eq!(m.key().parse::<GustModel>(), Ok(m));
        }
        for c in GustComponent::ALL {
            assert_eq!(serde_json::to_value(c).unwrap(), c.name());
            assert_eq!(c.name().parse::<GustComponent>(), Ok(c));
            assert_eq!(GustComponent::ALL[c.index()], c);
        }
        assert_eq!(
            "karman".parse::<GustModel>().unwrap_err(),
            "model must be 'dryden' or 'von_karman', got \"karman\""
        );
        assert_eq!(
            "up".parse::<GustComponent>().unwrap_err(),
            "component must be 'longitudinal', 'lateral' or 'vertical', got \"up\""
        );
        let e = with(|v| v["gust"]["model"] = "karman".into()).unwrap_err();
        assert_eq!(e.key, "gust.model");
    }

    #[test]
    fn gust_values_name_their_key() {
        let bad = |edit: fn(&mut Config)| {
            let mut c = paper();
            edit(&mut c);
            c.validate().unwrap_err()
        };
        let e = bad(|c| c.gust.airspeed = GustAirspeed::Fixed(0.0));
        assert_eq!(e.key, "gust.airspeed");
        assert_eq!(
            e.message,
            "gust.airspeed must be > 0 (the Dryden filters are singular at zero airspeed), got 0.0"
        );
        let e = bad(|c| {
            c.gust.model = GustModel::VonKarman;
            c.gust.airspeed = GustAirspeed::Fixed(0.0);
        });
        assert!(e.message.contains("von Karman filters are singular"), "{e}");
        let e = bad(|c| c.gust.altitude = GustAltitude::Fixed(-1.0));
        assert_eq!(
            (e.key.as_str(), e.message.as_str()),
            ("gust.altitude", "gust.altitude must be > 0, got -1.0")
        );
        let e = bad(|c| c.gust.w20 = Some(-3.0));
        assert_eq!(e.message, "gust.w20 must be >= 0, got -3.0");
        let e = bad(|c| c.gust.end = 10.0);
        assert_eq!(e.key, "gust.end");
        assert!(e
            .message
            .starts_with("gust.end must not be before gust.start"));
        let e = bad(|c| c.gust.mean_wind[1] = f64::NAN);
        assert_eq!(e.key, "gust.mean_wind[1]");
        let e = bad(|c| c.gust.components = vec![GustComponent::Lateral; 2]);
        assert_eq!(e.message, "gust.components lists Lateral twice");
        // A disabled gust is still checked: the scenario is one set of rules.
        let e = bad(|c| {
            c.gust.enabled = false;
            c.gust.w20 = Some(-3.0);
        });
        assert_eq!(e.key, "gust.w20");
    }
}
