//! The scenario's sections that sit below the kinds: each its own file (its struct, defaults
//! and checks): `vehicle`, `trajectory` (with `phases` and the route's `route`), `gust`, `wind`
//! (the values of `[gust]` that may follow the vehicle), `flight` (`[environment]`,
//! `[initial]`, `[integrator]`, `[metrics]`, `[divergence]`, `[ground]`), `volume`, `dispersions`; the
//! `params!` declarations and the dotted keys (`params`, `keys`); `ConfigError`. The kinds are
//! built from a narrow view of these sections (`Context`), never from the assembled scenario:
//! that one (`crate::scenario::Config`, with the kinds' own tables) sits above the kinds.

pub mod dispersions;
pub mod flight;
pub mod gust;
pub mod keys;
pub mod navigation;
pub mod params;
pub mod route;
pub mod trajectory;
pub mod vehicle;
pub mod volume;
pub mod wind;

pub use dispersions::{Dispersions, Distribution};
pub use flight::{Divergence, Environment, Ground, Initial, Integrator, Metrics, Trim, MAX_STEPS};
pub use gust::{Gust, GustComponent, GustModel};
use std::fmt;
pub use trajectory::{Interpolation, Phase, Trajectory, LEGS};
pub use vehicle::{BodyModel, Vehicle, BODY_MODELS};
pub use volume::Volume;
pub use wind::{GustAirspeed, GustAltitude, Intensity};

/// A context built on a lower one held in its `$field`, read through it (`Deref`): a law's
/// `cfg.vehicle` is its model context's, whose is the sections'. One rule for every layer's
/// context (model, control, wind).
macro_rules! reads_through {
    ($Ctx:ident => $field:ident: $Lower:ident) => {
        impl<'a> std::ops::Deref for $Ctx<'a> {
            type Target = $Lower<'a>;
            fn deref(&self) -> &$Lower<'a> {
                &self.$field
            }
        }
    };
}
pub(crate) use reads_through;

/// A bad scenario value: `key` is the dotted TOML path, `message` the whole sentence.
#[derive(Debug, Clone, PartialEq)]
pub struct ConfigError {
    pub key: String,
    pub message: String,
}

impl fmt::Display for ConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.message)
    }
}

impl std::error::Error for ConfigError {}

impl ConfigError {
    pub(crate) fn new(key: impl Into<String>, message: impl Into<String>) -> Self {
        Self {
            key: key.into(),
            message: message.into(),
        }
    }
}

/// Two keys that give one thing two ways (the attachment's stiffness or natural frequency, the
/// turbulence's W20 or named level): exactly one of them is given. Declared beside the keys'
/// owner and checked there; Python reads every pair (`_core.ONE_OF_KEYS`, from
/// `scenario::Config::ONE_OF`) so that setting one key replaces the other.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct OneOf {
    pub keys: [&'static str; 2],
    /// The key an error names when both are given (the other one when neither is).
    pub named_if_both: usize,
}

impl OneOf {
    /// Refuses both or neither (`given`: whether each key is set), naming a key.
    pub(crate) fn check(&self, given: [bool; 2]) -> Result<(), ConfigError> {
        let [a, b] = self.keys;
        let (named, got) = match given {
            [true, true] => (self.keys[self.named_if_both], "both"),
            [false, false] => (self.keys[1 - self.named_if_both], "neither"),
            _ => return Ok(()),
        };
        Err(ConfigError::new(
            named,
            format!("give exactly one of {a} and {b}, got {got}"),
        ))
    }
}

/// The winch's keys a route's lowering needs (`payload.winch_speed`,
/// `payload.winch_acceleration`, the cable's: checked with it), passed down as plain values.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Winch {
    pub speed: Option<f64>,
    pub acceleration: Option<f64>,
    /// The final approach (`payload.approach_height`, `approach_speed`; both or none) and m,
    /// how far the parcel hangs below the vehicle reeled in (`payload.attachment_offset` plus
    /// `length_min`): a lowering's time.
    pub approach: Option<(f64, f64)>,
    pub hang: f64,
}

/// What a kind is built and checked from: the scenario's sections below the kinds, by
/// reference (the assembled scenario gives it, `scenario::Config::context`). Each family adds
/// its own tables on top (`gust::WindContext`, `model::ModelContext`,
/// `control::ControlContext`), so that a kind never names the assembled scenario.
#[derive(Debug, Clone, Copy)]
pub struct Context<'a> {
    pub vehicle: &'a Vehicle,
    pub environment: &'a Environment,
    pub initial: &'a Initial,
    pub trajectory: &'a Trajectory,
    pub phases: &'a [Phase],
    pub gust: &'a Gust,
    pub integrator: &'a Integrator,
    pub metrics: &'a Metrics,
    pub divergence: &'a Divergence,
    pub ground: &'a Ground,
    /// The route's operational volume (`[volume]`).
    pub volume: &'a Volume,
    pub winch: Winch,
}

impl Context<'_> {
    /// m/s, W20 of the turbulence: `gust.w20`, or the level `gust.intensity` names.
    pub fn turbulence_w20(&self) -> f64 {
        match (self.gust.w20, self.gust.intensity) {
            (Some(w), _) => w,
            (None, Some(i)) => i.w20(),
            (None, None) => f64::NAN, // rejected by validate()
        }
    }

    /// Number of RK4 steps of a flight: the duration rounded to the nearest whole step.
    pub fn steps(&self) -> usize {
        (self.integrator.duration / self.integrator.dt).round() as usize
    }

    /// Integration steps per update of the wind (`gust.rate`; 1: every step). `validate` has
    /// checked that the period is whole.
    pub fn gust_every(&self) -> usize {
        steps_per_update(self.gust.rate, self.integrator.dt).unwrap_or(1)
    }

    /// Integration steps per spectrum sample (`metrics.spectrum_rate`).
    pub fn decimation(&self) -> usize {
        ((1.0 / (self.metrics.spectrum_rate * self.integrator.dt)).round() as usize).max(1)
    }
}

/// Steps between a loop's updates at `rate` Hz with the step `dt` (0 Hz: 1, every step), or
/// why not: the period must be a whole number of steps.
pub fn steps_per_update(rate: f64, dt: f64) -> Result<usize, String> {
    if rate == 0.0 {
        return Ok(1);
    }
    let n = 1.0 / (rate * dt);
    let whole = n.round();
    if whole < 1.0 || (n - whole).abs() > 1e-9 * n.max(1.0) {
        return Err(format!(
            "{rate:?} Hz ({:.6} s) is not a whole number of integrator.dt = {dt:?} s steps \
             (0: every step)",
            1.0 / rate
        ));
    }
    Ok(whole as usize)
}

pub(crate) fn finite(key: impl fmt::Display, x: f64) -> Result<(), ConfigError> {
    if x.is_finite() {
        Ok(())
    } else {
        Err(ConfigError::new(
            key.to_string(),
            format!("{key} must be a finite number, got {x:?}"),
        ))
    }
}

/// A table of rows (`trajectory.waypoints`, `trajectory.route`): at least two rows (`what`
/// names them), and row by row every number finite, then `each(i)`'s check of row i.
pub(crate) fn rows_checked<const W: usize>(
    key: &str,
    rows: &[[f64; W]],
    what: &str,
    mut each: impl FnMut(usize) -> Result<(), ConfigError>,
) -> Result<(), ConfigError> {
    if rows.len() < 2 {
        let n = rows.len();
        return Err(ConfigError::new(
            key,
            format!("{key} needs at least two {what}, got {n}"),
        ));
    }
    for (i, row) in rows.iter().enumerate() {
        for (j, x) in row.iter().enumerate() {
            finite(format_args!("{key}[{i}][{j}]"), *x)?;
        }
        each(i)?;
    }
    Ok(())
}

/// (`key` is formatted only on failure: the checks run once per dispersed realisation.)
pub(crate) fn positive(key: impl fmt::Display, x: f64) -> Result<(), ConfigError> {
    if x.is_finite() && x > 0.0 {
        Ok(())
    } else {
        Err(ConfigError::new(
            key.to_string(),
            format!("{key} must be > 0, got {x:?}"),
        ))
    }
}

/// (`key` is formatted only on failure: the checks run once per dispersed realisation.)
pub(crate) fn non_negative(key: impl fmt::Display, x: f64) -> Result<(), ConfigError> {
    if x.is_finite() && x >= 0.0 {
        Ok(())
    } else {
        Err(ConfigError::new(
            key.to_string(),
            format!("{key} must be >= 0, got {x:?}"),
        ))
    }
}
