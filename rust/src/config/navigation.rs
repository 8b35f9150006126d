//! `[navigation]` and `[sensors]`: what the laws read (the state, or the estimate of a filter
//! fed by the vehicle's sensors) and the sensors' models (docs/model.md, "Navigation"). The
//! defaults are real parts': a current MEMS IMU's densities with in-flight vibration, PX4's
//! EKF2 defaults for the GNSS receiver and the barometer, the Gazebo GPS plugin's drift time.

use super::params::{not_numbers, params, Params};
use super::ConfigError;
use serde::{Deserialize, Serialize};

/// What the laws read (`navigation.mode`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum NavigationMode {
    /// The state itself (every paper preset).
    #[default]
    Truth,
    /// The estimate of the extended Kalman filter (`navigation::Ekf`).
    Ekf,
}

not_numbers!(NavigationMode);

macro_rules! defaults {
    ($($name:ident = $value:expr;)+) => {$(
        fn $name() -> f64 {
            $value
        }
    )+};
}

defaults! {
    imu_rate = 200.0;
    gyro_noise = 1.5e-3;
    accel_noise = 3.5e-2;
    gyro_bias_walk = 1.0e-4;
    accel_bias_walk = 3.0e-4;
    gyro_bias = 5.0e-3;
    accel_bias = 5.0e-2;
    gnss_rate = 5.0;
    gnss_delay = 0.11;
    velocity_noise = 0.3;
    gnss_drift = 0.5;
    gnss_drift_time = 60.0;
    baro_rate = 50.0;
    baro_noise = 3.5;
    baro_drift = 1.0;
    baro_drift_time = 300.0;
    heading_rate = 10.0;
    heading_noise = 0.3;
    navigation_rate = 100.0;
}

fn position_noise() -> [f64; 3] {
    [0.5, 0.5, 0.75]
}

fn attitude_error() -> [f64; 3] {
    [0.01, 0.01, 0.05]
}

params! {
    /// The IMU: a gyro and an accelerometer at the centre of mass, in body axes.
    #[derive(PartialEq)]
    pub struct Imu {
        /// Hz, the IMU's sample rate (0: every step).
        #[serde(default = "imu_rate")]
        rate: f64 => "Hz", "IMU sample rate", non_negative;
        #[serde(default = "gyro_noise")]
        gyro_noise: f64 => "rad/s/sqrt(Hz)", "Gyro noise density", non_negative;
        #[serde(default = "accel_noise")]
        accel_noise: f64 => "m/s^2/sqrt(Hz)", "Accelerometer noise density", non_negative;
        #[serde(default = "gyro_bias_walk")]
        gyro_bias_walk: f64 => "rad/s^2/sqrt(Hz)", "Gyro bias random walk", non_negative;
        #[serde(default = "accel_bias_walk")]
        accel_bias_walk: f64 => "m/s^3/sqrt(Hz)", "Accelerometer bias random walk", non_negative;
        /// rad/s, sigma of each axis's initial gyro bias.
        #[serde(default = "gyro_bias")]
        gyro_bias: f64 => "rad/s", "Gyro initial bias sigma", non_negative;
        /// m/s^2, sigma of each axis's initial accelerometer bias.
        #[serde(default = "accel_bias")]
        accel_bias: f64 => "m/s^2", "Accelerometer initial bias sigma", non_negative;
    }
}

params! {
    /// A window without a GNSS fix (`[[sensors.gnss.outages]]`).
    #[derive(PartialEq)]
    pub struct Outage {
        start: f64 => "s", "GNSS outage start", non_negative;
        duration: f64 => "s", "GNSS outage duration", non_negative;
    }
}

params! {
    /// The GNSS receiver: position and velocity at its rate, late by `delay`.
    #[derive(PartialEq)]
    pub struct Gnss {
        #[serde(default = "gnss_rate")]
        rate: f64 => "Hz", "GNSS rate", positive;
        #[serde(default = "gnss_delay")]
        delay: f64 => "s", "GNSS delay", non_negative;
        /// m, the white noise's sigma per axis [x, y, z].
        #[serde(default = "position_noise")]
        position_noise: [f64; 3] => "m", "GNSS position noise", non_negative;
        #[serde(default = "velocity_noise")]
        velocity_noise: f64 => "m/s", "GNSS velocity noise", non_negative;
        /// m, the stationary sigma of the Gauss-Markov position error (each axis).
        #[serde(default = "gnss_drift")]
        drift: f64 => "m", "GNSS drift sigma", non_negative;
        #[serde(default = "gnss_drift_time")]
        drift_time: f64 => "s", "GNSS drift time constant", positive;
        #[serde(default, skip_serializing_if = "Vec::is_empty")]
        outages: Vec<Outage> => "-", "GNSS outages";
    }
}

params! {
    /// The barometer: the height (z up) plus a slow Gauss-Markov bias and white noise.
    #[derive(PartialEq)]
    pub struct Baro {
        #[serde(default = "baro_rate")]
        rate: f64 => "Hz", "Barometer rate", positive;
        #[serde(default = "baro_noise")]
        noise: f64 => "m", "Barometer noise", non_negative;
        #[serde(default = "baro_drift")]
        drift: f64 => "m", "Barometer drift sigma", non_negative;
        #[serde(default = "baro_drift_time")]
        drift_time: f64 => "s", "Barometer drift time constant", positive;
    }
}

params! {
    /// A heading source (a compass): the yaw plus white noise.
    #[derive(PartialEq)]
    pub struct Heading {
        #[serde(default = "heading_rate")]
        rate: f64 => "Hz", "Heading rate", positive;
        #[serde(default = "heading_noise")]
        noise: f64 => "rad", "Heading noise", non_negative;
    }
}

/// `[sensors]`: the vehicle's senses (read only with `navigation.mode = "ekf"`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Sensors {
    #[serde(default = "default_of")]
    pub imu: Imu,
    #[serde(default = "default_of")]
    pub gnss: Gnss,
    #[serde(default = "default_of")]
    pub baro: Baro,
    #[serde(default = "default_of")]
    pub heading: Heading,
}

/// A table with every key at its default (serde reads `{}`).
fn default_of<T: serde::de::DeserializeOwned>() -> T {
    serde_json::from_str("{}").expect("every key of the table has a default")
}

impl Default for Sensors {
    fn default() -> Self {
        default_of()
    }
}

impl Sensors {
    /// Every key, dotted (`sensors.imu.rate`).
    pub fn keys() -> Vec<(String, super::params::Key)> {
        let mut keys = Imu::keys_under("sensors.imu");
        keys.extend(Gnss::keys_under("sensors.gnss"));
        keys.extend(Outage::keys_under("sensors.gnss.outages"));
        keys.extend(Baro::keys_under("sensors.baro"));
        keys.extend(Heading::keys_under("sensors.heading"));
        keys
    }

    /// The number a dotted key under `[sensors]` names (`field` the table, then `rest`).
    pub fn target(
        &mut self,
        field: &str,
        rest: &[super::params::Seg],
    ) -> super::params::Target<'_> {
        use super::params::{Field, Target};
        match field {
            "imu" => Field::target(&mut self.imu, rest),
            "gnss" => Field::target(&mut self.gnss, rest),
            "baro" => Field::target(&mut self.baro, rest),
            "heading" => Field::target(&mut self.heading, rest),
            _ => Target::Missing,
        }
    }

    pub fn is_default(&self) -> bool {
        *self == Self::default()
    }
}

params! {
    /// `[navigation]`: what the laws read, and the filter's own settings. The filter's noise
    /// keys default to the sensors' (a matched filter); set one to mistune it.
    #[derive(PartialEq)]
    pub struct Navigation {
        #[serde(default)]
        mode: NavigationMode => "-", "What the laws read";
        /// Hz, the filter's covariance prediction and fusion rate.
        #[serde(default = "navigation_rate")]
        rate: f64 => "Hz", "Navigation filter rate", positive;
        /// rad, sigma of the filter's initial attitude error about [x, y, z] (world axes).
        #[serde(default = "attitude_error")]
        attitude_error: [f64; 3] => "rad", "Initial attitude error sigma", non_negative;
        /// m, sigma of the filter's initial height error: a filter aligned on the pad knows its
        /// height above it (PX4's EKF2 sets its height origin where it initialises, and a
        /// mission's altitudes are above home); absent, the GNSS's vertical position noise (a
        /// filter started on a GNSS fix alone).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        height_error: Option<f64> => "m", "Initial height error sigma", non_negative;
        #[serde(default, skip_serializing_if = "Option::is_none")]
        gyro_noise: Option<f64> => "rad/s/sqrt(Hz)", "Filter gyro noise density", non_negative;
        #[serde(default, skip_serializing_if = "Option::is_none")]
        accel_noise: Option<f64> => "m/s^2/sqrt(Hz)", "Filter accelerometer noise density", non_negative;
        #[serde(default, skip_serializing_if = "Option::is_none")]
        gyro_bias_walk: Option<f64> => "rad/s^2/sqrt(Hz)", "Filter gyro bias walk", non_negative;
        #[serde(default, skip_serializing_if = "Option::is_none")]
        accel_bias_walk: Option<f64> => "m/s^3/sqrt(Hz)", "Filter accelerometer bias walk", non_negative;
        #[serde(default, skip_serializing_if = "Option::is_none")]
        gyro_bias: Option<f64> => "rad/s", "Filter initial gyro bias sigma", non_negative;
        #[serde(default, skip_serializing_if = "Option::is_none")]
        accel_bias: Option<f64> => "m/s^2", "Filter initial accelerometer bias sigma", non_negative;
        #[serde(default, skip_serializing_if = "Option::is_none")]
        position_noise: Option<[f64; 3]> => "m", "Filter GNSS position noise", positive;
        #[serde(default, skip_serializing_if = "Option::is_none")]
        velocity_noise: Option<f64> => "m/s", "Filter GNSS velocity noise", positive;
        #[serde(default, skip_serializing_if = "Option::is_none")]
        drift: Option<f64> => "m", "Filter GNSS drift sigma", non_negative;
        #[serde(default, skip_serializing_if = "Option::is_none")]
        drift_time: Option<f64> => "s", "Filter GNSS drift time constant", positive;
        #[serde(default, skip_serializing_if = "Option::is_none")]
        baro_noise: Option<f64> => "m", "Filter barometer noise", positive;
        #[serde(default, skip_serializing_if = "Option::is_none")]
        baro_drift: Option<f64> => "m", "Filter barometer drift sigma", non_negative;
        #[serde(default, skip_serializing_if = "Option::is_none")]
        baro_drift_time: Option<f64> => "s", "Filter barometer drift time constant", positive;
        #[serde(default, skip_serializing_if = "Option::is_none")]
        heading_noise: Option<f64> => "rad", "Filter heading noise", positive;
    }
}

impl Default for Navigation {
    fn default() -> Self {
        default_of()
    }
}

impl Navigation {
    pub fn is_default(&self) -> bool {
        *self == Self::default()
    }

    /// Whether the laws fly the filter's estimate.
    pub fn estimates(&self) -> bool {
        self.mode == NavigationMode::Ekf
    }

    /// Steps between updates of the filter (`rate`), of each sensor and the GNSS delay in
    /// steps, at the step `dt`, as flown: a sensor samples, and the filter updates, only at
    /// steps, so each period is rounded to whole steps (at least one: the IMU at 200 Hz on a
    /// 2 ms step samples every 3 steps, at 167 Hz), the filter's to whole IMU periods, each
    /// measurement's period and the GNSS delay to whole filter periods (a measurement is fused
    /// at the filter update it arrives at). docs/model.md, "Navigation".
    pub fn schedule(&self, sensors: &Sensors, dt: f64) -> Schedule {
        // Whole multiples of `unit` steps nearest `period` s, at least `least`.
        // (Saturating: a period longer than any flight, say a rate of 1e-300 Hz, never comes.)
        let whole = |period: f64, unit: usize, least: usize| -> usize {
            let n = (period / (unit as f64 * dt)).round();
            let n = if n.is_finite() {
                n.min(1e15) as usize
            } else {
                0
            };
            n.max(least).saturating_mul(unit)
        };
        let imu = if sensors.imu.rate == 0.0 {
            1
        } else {
            whole(1.0 / sensors.imu.rate, 1, 1)
        };
        let filter = whole(1.0 / self.rate, imu, 1);
        let gnss = whole(1.0 / sensors.gnss.rate, filter, 1);
        let baro = whole(1.0 / sensors.baro.rate, filter, 1);
        let heading = whole(1.0 / sensors.heading.rate, filter, 1);
        let delay = whole(sensors.gnss.delay, filter, 0);
        Schedule {
            imu,
            filter,
            gnss,
            delay,
            baro,
            heading,
        }
    }

    /// Check every value (any step flies the schedule: `schedule` rounds it to whole steps).
    /// The GNSS's delay is at most the flight's `duration` (s): the filter keeps its
    /// predictions over the delay to fuse a late fix, and a fix later than the flight never
    /// arrives.
    pub fn validate(&self, sensors: &Sensors, duration: f64) -> Result<(), ConfigError> {
        self.check_bounds("navigation")?;
        sensors.imu.check_bounds("sensors.imu")?;
        sensors.gnss.check_bounds("sensors.gnss")?;
        if self.estimates() && sensors.gnss.delay > duration {
            return Err(ConfigError {
                key: "sensors.gnss.delay".into(),
                message: format!(
                    "sensors.gnss.delay = {} s is longer than the flight (integrator.duration \
                     = {duration} s): no fix would arrive",
                    sensors.gnss.delay
                ),
            });
        }
        for (i, o) in sensors.gnss.outages.iter().enumerate() {
            o.check_bounds(&format!("sensors.gnss.outages[{i}]"))?;
        }
        sensors.baro.check_bounds("sensors.baro")?;
        sensors.heading.check_bounds("sensors.heading")
    }
}

/// Steps between the updates of the IMU, the filter, each measurement, and the GNSS delay in
/// steps (`Navigation::schedule`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Schedule {
    pub imu: usize,
    pub filter: usize,
    pub gnss: usize,
    pub delay: usize,
    pub baro: usize,
    pub heading: usize,
}
