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
    /// Weibull: P(X > x) = exp(-(x / scale)^shape), x >= 0 (a site's wind speed).
    Weibull { shape: f64, scale: f64 },
    /// One of `values`, value i with probability weights[i] / sum(weights).
    Choice { values: Vec<f64>, weights: Vec<f64> },
}

/// A discrete law's values and weights: as many of each (at least one), every value finite,
/// every weight finite and >= 0, their sum > 0. The message names the entry (`values[i]`).
fn check_choice(values: &[f64], weights: &[f64]) -> Result<(), String> {
    if values.is_empty() {
        return Err("values must list at least one number, got none".into());
    }
    if weights.len() != values.len() {
        return Err(format!(
            "weights must have one entry per value ({}), got {}",
            values.len(),
            weights.len()
        ));
    }
    if let Some((i, x)) = values.iter().enumerate().find(|(_, x)| !x.is_finite()) {
        return Err(format!("values[{i}] must be a finite number, got {x:?}"));
    }
    if let Some((i, w)) = weights
        .iter()
        .enumerate()
        .find(|(_, w)| !(w.is_finite() && **w >= 0.0))
    {
        return Err(format!(
            "weights[{i}] must be a finite number >= 0, got {w:?}"
        ));
    }
    let total: f64 = weights.iter().sum();
    if !(total > 0.0 && total.is_finite()) {
        return Err(format!(
            "weights must sum to a finite number > 0, got {total:?}"
        ));
    }
    Ok(())
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
        Distribution::Weibull { shape, scale } => {
            positive("shape", shape)?;
            positive("scale", scale)
        }
        Distribution::Choice {
            ref values,
            ref weights,
        } => check_choice(values, weights).map_err(err),
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
