//! `[volume]`: the route's operational volume (docs/risk.md, "Containment"): the flight
//! geography, a corridor about the route's legs (a half-width across the leg and a
//! half-height about it), and the contingency buffer beyond it. The metrics measure each
//! flight's margin to both boundaries (`metrics::geography_margin`, `volume_margin`) from the
//! reference, which carries the corridor (`trajectory::Corridor`).

use super::params::{params, Params};
use super::ConfigError;

params! {
    /// Absent (every key unset): no volume, the margins are NaN and no flight leaves it.
    #[derive(Default, PartialEq)]
    pub struct Volume {
        /// m, the flight geography's half-width across the current leg (horizontal).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        flight_geography: Option<f64> => "m", "Flight geography half-width", positive;
        /// m, the flight geography's half-height about the current leg (vertical).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        flight_height_band: Option<f64> => "m", "Flight geography half-height", positive;
        /// m, the contingency buffer beyond the flight geography, across and up and down
        /// (default 0: the operational volume is the flight geography).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        contingency: Option<f64> => "m", "Contingency buffer", non_negative;
    }
}

impl Volume {
    /// No key given (the table is then left out of the JSON form).
    pub fn is_default(&self) -> bool {
        *self == Self::default()
    }

    /// The bounds, then the two sizes of the flight geography given together (a corridor
    /// needs both; the buffer alone is no volume).
    pub fn validate(&self) -> Result<(), ConfigError> {
        self.check_bounds("volume")?;
        if self.is_default() {
            return Ok(());
        }
        for (key, x) in [
            ("volume.flight_geography", self.flight_geography),
            ("volume.flight_height_band", self.flight_height_band),
        ] {
            if x.is_none() {
                return Err(ConfigError::new(
                    key,
                    format!(
                        "{key} is required in [volume] (the flight geography's half-width and \
                         half-height, m), got none"
                    ),
                ));
            }
        }
        Ok(())
    }

    /// m, the flight geography's (half-width, half-height) and the buffer: infinite without
    /// a volume (no margin is ever negative).
    pub fn sizes(&self) -> [f64; 3] {
        match (self.flight_geography, self.flight_height_band) {
            (Some(w), Some(h)) => [w, h, self.contingency.unwrap_or(0.0)],
            _ => [f64::INFINITY; 3],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn volume(w: Option<f64>, h: Option<f64>, c: Option<f64>) -> Volume {
        Volume {
            flight_geography: w,
            flight_height_band: h,
            contingency: c,
        }
    }

    #[test]
    fn a_volume_needs_both_sizes_and_names_the_key() {
        assert!(Volume::default().validate().is_ok());
        assert_eq!(Volume::default().sizes(), [f64::INFINITY; 3]);
        let v = volume(Some(10.0), Some(5.0), None);
        assert!(v.validate().is_ok());
        assert_eq!(v.sizes(), [10.0, 5.0, 0.0]);
        let e = volume(Some(10.0), None, Some(2.0)).validate().unwrap_err();
        assert_eq!(e.key, "volume.flight_height_band");
        let e = volume(None, None, Some(2.0)).validate().unwrap_err();
        assert_eq!(e.key, "volume.flight_geography");
        let e = volume(Some(-1.0), Some(5.0), None).validate().unwrap_err();
        assert_eq!(
            (e.key.as_str(), e.message.as_str()),
            (
                "volume.flight_geography",
                "volume.flight_geography must be > 0, got -1.0"
            )
        );
        let e = volume(Some(1.0), Some(5.0), Some(-2.0))
            .validate()
            .unwrap_err();
        assert_eq!(e.key, "volume.contingency");
    }
}
