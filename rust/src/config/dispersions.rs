//! The scenario's `[dispersions]` table: a distribution per dotted key (docs/dispersions.md).
//! Checked here with every other field; sampling the values (random, Latin hypercube, Sobol)
//! is the Python layer's job (scipy.stats/qmc), and flying them `crate::dispersion`'s.

use super::ConfigError;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// A distribution with scipy.stats semantics (docs/dispersions.md).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "dist", rename_all = "snake_case", deny_unknown_fields)]
pub enum Distribution {
    /// U(low, high).
    Uniform { low: f64, high: f64 },
    /// N(mean, std^2).
    Normal { mean: f64, std: f64 },
    /// N(mean, std^2) truncated to [low, high].
    Truncnorm {
        mean: f64,
        std: f64,
        low: f64,
        high: f64,
    },
    /// exp(N(mu, sigma^2)): mu and sigma of the logarithm.
    Lognormal { mu: f64, sigma: f64 },
    /// Triangular on [low, high] with its peak at mode.
    Triangular { low: f64, mode: f64, high: f64 },
}

/// The `[dispersions]` table: dotted key -> distribution (sorted by key: the order of the
/// design's dimensions and of the result columns).
pub type Dispersions = BTreeMap<String, Distribution>;

/// One distribution of `[dispersions]` sound (its key's checks are the assembled scenario's,
/// `scenario::Config::per_realisation_key`).
pub fn check_distribution(key: &str, d: &Distribution) -> Result<(), ConfigError> {
    let err = |msg: String| ConfigError {
        key: format!("dispersions.{key}"),
        message: format!("dispersions: {key:?}: {msg}"),
    };
    let finite = |name: &str, x: f64| {
        if x.is_finite() {
            Ok(())
        } else {
            Err(err(format!("{name} must be a finite number, got {x:?}")))
        }
    };
    let positive = |name: &str, x: f64| {
        finite(name, x)?;
        if x > 0.0 {
            Ok(())
        } else {
            Err(err(format!("{name} must be > 0, got {x:?}")))
        }
    };
    let ordered = |low: f64, high: f64| {
        finite("low", low)?;
        finite("high", high)?;
        if low < high {
            Ok(())
        } else {
            Err(err(format!(
                "low must be < high, got low = {low:?}, high = {high:?}"
            )))
        }
    };
    match *d {
        Distribution::Uniform { low, high } => ordered(low, high),
        Distribution::Normal { mean, std } => {
            finite("mean", mean)?;
            positive("std", std)
        }
        Distribution::Truncnorm {
            mean,
            std,
            low,
            high,
        } => {
            finite("mean", mean)?;
            positive("std", std)?;
            ordered(low, high)
        }
        Distribution::Lognormal { mu, sigma } => {
            finite("mu", mu)?;
            positive("sigma", sigma)
        }
        Distribution::Triangular { low, mode, high } => {
            ordered(low, high)?;
            finite("mode", mode)?;
            if (low..=high).contains(&mode) {
                Ok(())
            } else {
                Err(err(format!(
                    "mode must lie in [low, high] = [{low:?}, {high:?}], got {mode:?}"
                )))
            }
        }
    }
}
