//! The winch's speed servo against the integration step (docs/guarantees.md): a step too
//! coarse for it is refused naming `integrator.dt`.

use super::{Cable, CableParams, WINCH_SPEED_GAIN};
use crate::config::ConfigError;
use crate::model::ModelContext;

impl Cable {
    /// The winch's speed servo (`winch`: L'' = kw (r - L') within the acceleration limit, a
    /// pole at -kw, kw = WINCH_SPEED_GAIN whatever the winch's speed and acceleration) must be
    /// resolved by the step, as the rotors' lag is (`actuator.time_constant`): past kw dt = 1
    /// RK4 with the servo's clamps overshoots, and beyond ~2.8 the line's speed grows without
    /// bound (its length goes negative) while the flight ends "ok". Any acceleration resolves:
    /// its limit only ever slows the line.
    pub(super) fn validate_winch_step(
        c: &CableParams,
        cfg: &ModelContext,
    ) -> Result<(), ConfigError> {
        if c.winch_speed.is_none() && c.winch_acceleration.is_none() {
            return Ok(());
        }
        let dt = cfg.integrator.dt;
        if WINCH_SPEED_GAIN * dt > 1.0 {
            return Err(ConfigError::new(
                "integrator.dt",
                format!(
                    "integrator.dt is too coarse for the winch's speed servo (gain \
                     {WINCH_SPEED_GAIN:?} 1/s: it needs gain x dt <= 1, integrator.dt <= {:?} s \
                     with a winch, payload.winch_speed), got {dt:?}",
                    1.0 / WINCH_SPEED_GAIN
                ),
            ));
        }
        Ok(())
    }
}
