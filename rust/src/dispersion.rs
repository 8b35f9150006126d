//! Uncertain parameters: the scenario's `[dispersions]` table (a distribution per dotted key)
//! and, for a batch, the values each realisation flies.
//!
//! The engine validates the table (one set of rules, like every other field) and builds one
//! `Craft` per realisation from the scenario with that realisation's values set. Sampling the
//! values (random, Latin hypercube, Sobol) is the Python layer's job (scipy.stats/qmc); the
//! engine only checks them, so every realisation it flies is a scenario it would accept alone.

use crate::config::{Config, ConfigError};
use crate::integrate::Craft;
use serde::{Deserialize, Serialize};
use serde_json::Value;
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

/// Key prefixes that cannot carry a distribution: they change the step grid, the phases, the
/// reference every lane shares or the spectrum grid, or they are the table itself.
const FIXED_PREFIXES: [&str; 5] = [
    "integrator",
    "phases",
    "trajectory",
    "metrics",
    "dispersions",
];

/// One step of a dotted key: a table field or an array index.
#[derive(Debug, Clone, PartialEq)]
enum Seg {
    Field(String),
    Index(usize),
}

/// `"vehicle.inertia[2]"` -> [Field vehicle, Field inertia, Index 2].
fn parse_key(key: &str) -> Option<Vec<Seg>> {
    let mut out = Vec::new();
    for part in key.split('.') {
        let (name, mut rest) = part.split_at(part.find('[').unwrap_or(part.len()));
        let valid_name = name
            .chars()
            .next()
            .is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
            && name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_');
        if !valid_name {
            return None;
        }
        out.push(Seg::Field(name.to_string()));
        while !rest.is_empty() {
            let close = rest.find(']')?;
            if !rest.starts_with('[') {
                return None;
            }
            out.push(Seg::Index(rest[1..close].parse().ok()?));
            rest = &rest[close + 1..];
        }
    }
    Some(out)
}

fn lookup_mut<'v>(value: &'v mut Value, path: &[Seg]) -> Option<&'v mut Value> {
    path.iter().try_fold(value, |v, seg| match seg {
        Seg::Field(f) => v.as_object_mut()?.get_mut(f),
        Seg::Index(i) => v.as_array_mut()?.get_mut(*i),
    })
}

/// The parsed path of a key that may be dispersed in `base` (the scenario's JSON form), or an
/// error naming it.
fn dispersible(base: &mut Value, key: &str) -> Result<Vec<Seg>, ConfigError> {
    let err = |why: &str| ConfigError {
        key: format!("dispersions.{key}"),
        message: format!("dispersions: {key:?} {why}"),
    };
    let path = parse_key(key).ok_or_else(|| err("is not a dotted scenario key"))?;
    if let Some(Seg::Field(first)) = path.first() {
        if FIXED_PREFIXES.contains(&first.as_str()) {
            return Err(err(&format!(
                "cannot be dispersed: {first}.* fixes the step grid, phases, reference or \
                 spectrum grid that every realisation of a batch shares"
            )));
        }
    }
    match lookup_mut(base, &path) {
        None => Err(err("is not a key of this scenario")),
        Some(v) if v.is_number() => Ok(path),
        Some(_) => Err(err("is not a number (only numeric keys can be dispersed)")),
    }
}

fn check_distribution(key: &str, d: &Distribution) -> Result<(), ConfigError> {
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

/// Check a scenario's `[dispersions]` table: every key dispersible, every distribution sound.
pub fn validate(cfg: &Config) -> Result<(), ConfigError> {
    if cfg.dispersions.is_empty() {
        return Ok(());
    }
    let mut base = fixed_value(cfg);
    for (key, dist) in &cfg.dispersions {
        dispersible(&mut base, key)?;
        check_distribution(key, dist)?;
    }
    Ok(())
}

/// The scenario's JSON form without its `[dispersions]` table.
fn fixed_value(cfg: &Config) -> Value {
    let mut v = serde_json::to_value(cfg).expect("a Config always serialises");
    if let Some(obj) = v.as_object_mut() {
        obj.remove("dispersions");
    }
    v
}

/// The values a batch's realisations fly: row `j` (realisation `first + j`) sets `keys` to
/// `values[j * keys.len()..][..keys.len()]` in the scenario.
pub struct Dispersion {
    base: Value,
    keys: Vec<String>,
    paths: Vec<Vec<Seg>>,
    values: Vec<f64>,
}

impl Dispersion {
    /// Check the keys against the scenario and the table's shape against `rows`.
    pub fn new(
        cfg: &Config,
        keys: Vec<String>,
        values: Vec<f64>,
        rows: usize,
    ) -> Result<Self, ConfigError> {
        let mut base = fixed_value(cfg);
        let paths = keys
            .iter()
            .map(|k| dispersible(&mut base, k))
            .collect::<Result<Vec<_>, _>>()?;
        if values.len() != rows * keys.len() {
            return Err(ConfigError {
                key: "dispersions".into(),
                message: format!(
                    "dispersions: {} values for {rows} realisations of {} keys, expected {}",
                    values.len(),
                    keys.len(),
                    rows * keys.len()
                ),
            });
        }
        Ok(Self {
            base,
            keys,
            paths,
            values,
        })
    }

    pub fn rows(&self) -> usize {
        self.values.len().checked_div(self.keys.len()).unwrap_or(0)
    }

    /// The scenario realisation `row` flies, validated; an invalid drawn value is an error
    /// naming the key, the realisation and the value.
    pub fn config(&self, row: usize, first: u64) -> Result<Config, ConfigError> {
        let n = self.keys.len();
        let mut v = self.base.clone();
        for (j, (key, path)) in self.keys.iter().zip(&self.paths).enumerate() {
            let x = self.values[row * n + j];
            let number = serde_json::Number::from_f64(x).ok_or_else(|| ConfigError {
                key: key.clone(),
                message: format!(
                    "dispersions: {key} drew {x:?} for realisation {}: not a finite number",
                    first + row as u64
                ),
            })?;
            *lookup_mut(&mut v, path).expect("checked by Dispersion::new") = Value::Number(number);
        }
        let cfg: Config = serde_json::from_value(v).map_err(|e| ConfigError {
            key: "dispersions".into(),
            message: format!("dispersions: a drawn scenario does not parse: {e}"),
        })?;
        cfg.validate().map_err(|e| ConfigError {
            message: format!(
                "dispersions: realisation {} drew a value the scenario refuses: {} \
                 (narrow or truncate the distribution)",
                first + row as u64,
                e.message
            ),
            key: e.key,
        })?;
        Ok(cfg)
    }

    /// The craft realisation `row` flies.
    pub fn craft(&self, row: usize, first: u64) -> Result<Craft, ConfigError> {
        Craft::new(&self.config(row, first)?)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::tests::paper;

    #[test]
    fn keys_parse_with_indices() {
        assert_eq!(
            parse_key("vehicle.inertia[2]"),
            Some(vec![
                Seg::Field("vehicle".into()),
                Seg::Field("inertia".into()),
                Seg::Index(2)
            ])
        );
        for bad in ["", "a..b", "a[", "a[x]", "a]b", "1a", "a[1]b"] {
            assert_eq!(parse_key(bad), None, "{bad:?}");
        }
    }

    #[test]
    fn only_numeric_keys_off_the_grid_are_dispersible() {
        let mut v = fixed_value(&paper());
        assert!(dispersible(&mut v, "payload.mass").is_ok());
        assert!(dispersible(&mut v, "vehicle.inertia[2]").is_ok());
        for (key, says) in [
            ("integrator.dt", "cannot be dispersed"),
            ("phases[1].end", "cannot be dispersed"),
            ("trajectory.waypoints[1][0]", "cannot be dispersed"),
            ("payload.massive", "not a key"),
            ("vehicle.inertia[3]", "not a key"),
            ("gust.enabled", "not a number"),
        ] {
            let e = dispersible(&mut v, key).unwrap_err();
            assert!(e.message.contains(says) && e.message.contains(key), "{e:?}");
        }
    }

    #[test]
    fn rows_set_their_keys_and_bad_draws_name_key_and_realisation() {
        let cfg = paper();
        let keys = vec!["payload.mass".to_string(), "vehicle.inertia[2]".to_string()];
        let d = Dispersion::new(&cfg, keys, vec![0.3, 0.05, -0.1, 0.05], 2).unwrap();
        let c = d.config(0, 10).unwrap();
        assert_eq!(c.payload.mass, 0.3);
        assert_eq!(c.vehicle.inertia[2], 0.05);
        let e = d.config(1, 10).unwrap_err();
        assert!(e.message.contains("realisation 11") && e.message.contains("payload.mass"));
        assert!(Dispersion::new(&cfg, vec!["payload.mass".into()], vec![0.1], 2).is_err());
    }
}
