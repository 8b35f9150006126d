//! The winch's speed servo against the integration step (docs/guarantees.md): a winch
//! acceleration the step cannot resolve is refused naming the key.

use super::{Cable, CableParams, WINCH_SPEED_GAIN};
use crate::config::ConfigError;
use crate::model::ModelContext;

impl Cable {
    /// The winch's speed servo (`winch`: L'' = kw (rate - L'), kw = 4 a / v, a pole at -kw)
    /// must be resolved by the step, as the rotors' lag is (`actuator.time_constant`): past
    /// kw dt = 1 RK4 with the servo's clamps overshoots, and beyond ~2.8 the line's speed
    /// grows without bound (its length goes negative) while the flight ends "ok".
    pub(super) fn validate_winch_step(
        c: &CableParams,
        cfg: &ModelContext,
    ) -> Result<(), ConfigError> {
        let (Some(v), Some(a)) = (c.winch_speed, c.winch_acceleration) else {
            return Ok(());
        };
        let dt = cfg.integrator.dt;
        let gain = WINCH_SPEED_GAIN * a / v;
        if gain * dt > 1.0 {
            return Err(ConfigError::new(
                "payload.winch_acceleration",
                format!(
                    "payload.winch_acceleration is more than integrator.dt ({dt:?} s) can \
                     resolve: the winch's speed servo (gain {WINCH_SPEED_GAIN} \
                     payload.winch_acceleration / payload.winch_speed = {gain:?} 1/s, \
                     payload.winch_speed = {v:?} m/s) needs gain x dt <= 1; use \
                     payload.winch_acceleration <= {:?} m/s^2 or a smaller integrator.dt, got {a:?}",
                    v / (WINCH_SPEED_GAIN * dt)
                ),
            ));
        }
        Ok(())
    }
}
