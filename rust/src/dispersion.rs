//! A batch's per-realisation values of the dispersed keys: row `j` of the table is what
//! realisation `first + j` flies. Each row patches the typed scenario directly (no text, no
//! JSON: every value arrives bit for bit) and is validated like any scenario.

use crate::config::keys::Seg;
use crate::scenario::{Config, ConfigError};

/// The values a batch's realisations fly: row `j` (realisation `first + j`) sets `keys` to
/// `values[j * keys.len()..][..keys.len()]` in the scenario.
pub struct Dispersion {
    /// The scenario without its `[dispersions]` table (each row is a fixed scenario).
    base: Config,
    keys: Vec<String>,
    paths: Vec<Vec<Seg>>,
    values: Vec<f64>,
}

/// Whether a key's value reaches the wind field (`WindField`): only `gust.*` and `wind.*` keys
/// do, so a batch that disperses none of them reuses the scenario's discretised filters.
pub fn touches_wind(key: &str) -> bool {
    key.starts_with("gust.") || key.starts_with("wind.")
}

impl Dispersion {
    /// Check the keys against the scenario and the table's shape against `rows`.
    pub fn new(
        cfg: &Config,
        keys: Vec<String>,
        values: Vec<f64>,
        rows: usize,
    ) -> Result<Self, ConfigError> {
        let paths = keys
            .iter()
            .map(|k| cfg.per_realisation_key(k))
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
        let mut base = cfg.clone();
        base.dispersions.clear();
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

    /// Whether any dispersed key reaches the gust field (see [`touches_wind`]).
    pub fn touches_wind(&self) -> bool {
        self.keys.iter().any(|k| touches_wind(k))
    }

    /// The scenario realisation `row` flies, validated; an invalid drawn value is an error
    /// naming the key, the realisation and the value.
    pub fn config(&self, row: usize, first: u64) -> Result<Config, ConfigError> {
        let cfg = self.patched(row, first)?;
        // The base scenario was validated whole; a row changes no fixed key.
        cfg.validate_realisation().map_err(|e| ConfigError {
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

    /// The scenario with row `row`'s values set, not validated: for a batch whose rows
    /// `config` has already checked (`montecarlo::Batch::check`), so that each realisation
    /// pays for its checks once.
    pub fn patched(&self, row: usize, first: u64) -> Result<Config, ConfigError> {
        let n = self.keys.len();
        let mut cfg = self.base.clone();
        for (j, (key, path)) in self.keys.iter().zip(&self.paths).enumerate() {
            let x = self.values[row * n + j];
            if !x.is_finite() {
                return Err(ConfigError {
                    key: key.clone(),
                    message: format!(
                        "dispersions: {key} drew {x:?} for realisation {}: not a finite number",
                        first + row as u64
                    ),
                });
            }
            let set = cfg.set_number(path, x);
            debug_assert!(set, "checked by Dispersion::new");
        }
        Ok(cfg)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::tests::paper;

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

    /// A drawn value arrives bit for bit, whatever its digits (no text on the way).
    #[test]
    fn drawn_values_arrive_exactly() {
        let cfg = paper();
        let xs: Vec<f64> = (0..2000)
            .map(|i| 0.1 + (i as f64 * 0.754_877_666_246_692_7).fract() * 0.3)
            .collect();
        let d = Dispersion::new(&cfg, vec!["payload.mass".into()], xs.clone(), xs.len()).unwrap();
        for (j, x) in xs.iter().enumerate() {
            assert_eq!(d.config(j, 0).unwrap().payload.mass.to_bits(), x.to_bits());
        }
    }
}
