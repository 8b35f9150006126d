//! The cable's last-metres keys checked together (`Cable::validate`): the winch, the hook,
//! the lowerings of the route, the final approach and the parcel's start above the ground.

use super::{Cable, CableParams, Release};
use crate::config::{non_negative, positive, ConfigError};
use crate::model::ModelContext;

impl Cable {
    /// The winch, the hook and the lowerings of the route (`flown`, `cable_length` = `l0`).
    pub(super) fn validate_last_metres(
        c: &CableParams,
        l0: f64,
        cfg: &ModelContext,
    ) -> Result<(), ConfigError> {
        let winch = c.winch_speed.is_some() || c.winch_acceleration.is_some();
        if winch {
            for (key, x) in [
                ("payload.winch_speed", c.winch_speed),
                ("payload.winch_acceleration", c.winch_acceleration),
            ] {
                match x {
                    Some(x) => positive(key, x)?,
                    None => {
                        return Err(ConfigError::new(
                            key,
                            format!(
                                "{key} must be given with the winch's other key \
                                 (payload.winch_speed and payload.winch_acceleration)"
                            ),
                        ))
                    }
                }
            }
            Self::validate_winch_step(c, cfg)?;
        }
        let min = c.length_min.unwrap_or(l0);
        positive("payload.length_min", min)?;
        if min > l0 {
            return Err(ConfigError::new(
                "payload.length_min",
                format!(
                    "payload.length_min must be at most payload.cable_length ({l0:?} m), got {min:?}"
                ),
            ));
        }
        if c.length_min.is_some() && !winch {
            return Err(ConfigError::new(
                "payload.length_min",
                "payload.length_min needs a winch (payload.winch_speed and \
                 payload.winch_acceleration)",
            ));
        }
        for (i, x) in cfg.trajectory.lower.iter().enumerate() {
            let key = format!("trajectory.lower[{i}]");
            if *x > 0.0 && !winch {
                return Err(ConfigError::new(
                    &key,
                    format!(
                        "{key} lowers the parcel: it needs a winch (payload.winch_speed and \
                         payload.winch_acceleration), got {x:?} m without one"
                    ),
                ));
            }
            if min + x > l0 {
                return Err(ConfigError::new(
                    &key,
                    format!(
                        "{key} must be at most payload.cable_length - payload.length_min \
                         ({:?} m of line to pay out), got {x:?}",
                        l0 - min
                    ),
                ));
            }
        }
        Self::validate_final_approach(c, winch)?;
        if let Some(d) = c.release_delay {
            non_negative("payload.release_delay", d)?;
        }
        if let Some(t) = c.release_after {
            non_negative("payload.release_after", t)?;
        }
        Self::validate_slack_hook(c)?;
        Self::validate_release(c, cfg)?;
        Self::validate_hanging_clear(c, cfg, min)
    }

    /// `payload.release`: a time or a height at least 0; a drop or a release on touchdown
    /// needs a ground the parcel meets.
    fn validate_release(c: &CableParams, cfg: &ModelContext) -> Result<(), ConfigError> {
        match c.release {
            Some(Release::At(t)) => non_negative("payload.release", t)?,
            Some(Release::Height(h)) => {
                non_negative("payload.release", h)?;
                if cfg.ground.stiffness.is_none() {
                    return Err(ConfigError::new(
                        "payload.release",
                        format!(
                            "payload.release = {{ height = {h:?} }} drops the parcel: it needs \
                             a ground it lands on (ground.stiffness)"
                        ),
                    ));
                }
            }
            Some(Release::Touchdown) if cfg.ground.stiffness.is_none() => {
                return Err(ConfigError::new(
                    "payload.release",
                    "payload.release = \"touchdown\" needs a ground the parcel meets \
                     (ground.stiffness)",
                ))
            }
            _ => {}
        }
        Ok(())
    }

    /// With a ground, the parcel starts hanging clear of it (the line's starting length
    /// `min`, its stretch under the parcel's weight and the hook's offset below the vehicle).
    fn validate_hanging_clear(
        c: &CableParams,
        cfg: &ModelContext,
        min: f64,
    ) -> Result<(), ConfigError> {
        if cfg.ground.stiffness.is_some() {
            // The parcel starts hanging clear of the ground.
            let p = &cfg.payload;
            let stretch = p.mass * cfg.environment.gravity / cfg.stiffness();
            if !stretch.is_finite() {
                // A spring too soft to hold the parcel: name the key that set it.
                let key = if p.stiffness.is_some() {
                    "payload.stiffness"
                } else {
                    "payload.natural_frequency"
                };
                let value = p.stiffness.or(p.natural_frequency).unwrap_or(f64::NAN);
                return Err(ConfigError::new(
                    key,
                    format!(
                        "{key} is too small to hold the parcel above the ground (its weight \
                         stretches the line {stretch:?} m), got {value:?}"
                    ),
                ));
            }
            let hang = c.attachment_offset.unwrap_or(0.0) + min + stretch;
            let z = cfg.initial.position[2] - hang;
            if z <= cfg.ground.altitude {
                return Err(ConfigError::new(
                    "initial.position[2]",
                    format!(
                        "initial.position[2] must hang the parcel above the ground \
                         (ground.altitude = {:?} m; the parcel hangs {hang:?} m below the \
                         vehicle: payload.attachment_offset, the line's starting length \
                         payload.length_min and its stretch under the parcel's weight, \
                         payload.mass x environment.gravity over the line's stiffness, \
                         payload.stiffness or from payload.natural_frequency), got {:?}",
                        cfg.ground.altitude, cfg.initial.position[2]
                    ),
                ));
            }
        }
        Ok(())
    }

    /// `payload.approach_height` and `approach_speed` come together, with a winch; the
    /// approach's speed is positive and at most the winch's.
    fn validate_final_approach(c: &CableParams, winch: bool) -> Result<(), ConfigError> {
        let (h, v) = (c.approach_height, c.approach_speed);
        if h.is_none() && v.is_none() {
            return Ok(());
        }
        for (key, x) in [
            ("payload.approach_height", h),
            ("payload.approach_speed", v),
        ] {
            let Some(x) = x else {
                return Err(ConfigError::new(
                    key,
                    format!(
                        "{key} must be given with the final approach's other key \
                         (payload.approach_height and payload.approach_speed)"
                    ),
                ));
            };
            if !winch {
                return Err(ConfigError::new(
                    key,
                    format!(
                        "{key} is the winch's final approach: it needs a winch \
                         (payload.winch_speed and payload.winch_acceleration), got {x:?}"
                    ),
                ));
            }
        }
        non_negative("payload.approach_height", h.unwrap_or(0.0))?;
        let (v, top) = (v.unwrap_or(f64::NAN), c.winch_speed.unwrap_or(f64::NAN));
        positive("payload.approach_speed", v)?;
        if v > top {
            return Err(ConfigError::new(
                "payload.approach_speed",
                format!(
                    "payload.approach_speed must be at most payload.winch_speed ({top:?} m/s): \
                     the winch slows for the last metres, got {v:?}"
                ),
            ));
        }
        Ok(())
    }

    /// `payload.release = "slack"` needs `payload.slack_tension` (> 0); the slack hook's keys
    /// apply to it only; the load cell's noise is at least 0.
    fn validate_slack_hook(c: &CableParams) -> Result<(), ConfigError> {
        let slack = c.release == Some(Release::Slack);
        for (key, x) in [
            ("payload.slack_tension", c.slack_tension),
            ("payload.tension_noise", c.tension_noise),
        ] {
            if let (Some(x), false) = (x, slack) {
                return Err(ConfigError::new(
                    key,
                    format!(
                        "{key} applies to payload.release = \"slack\" only, got {x:?} with \
                         payload.release = {}",
                        c.release.map_or("none".to_string(), |r| r.shown())
                    ),
                ));
            }
        }
        if !slack {
            return Ok(());
        }
        let Some(t) = c.slack_tension else {
            return Err(ConfigError::new(
                "payload.slack_tension",
                "payload.release = \"slack\" needs payload.slack_tension (N, the measured \
                 tension below which the line is slack)",
            ));
        };
        positive("payload.slack_tension", t)?;
        non_negative("payload.tension_noise", c.tension_noise.unwrap_or(0.0))
    }
}
