//! The PX4 multicopter cascade (docs/model.md, "The PX4 cascade"): position P -> velocity PID
//! -> acceleration to thrust vector and attitude setpoint -> quaternion attitude P with reduced
//! yaw priority (Brescianini, Hehn & D'Andrea 2013) -> body-rate PID -> PX4's control
//! allocator (`px4_allocator`), as PX4's `PositionControl`, `AttitudeControl`, `RateControl`
//! and `ControlAllocator` compute it, in PX4's normalised units mapped to this model's SI. A
//! discrete law with memory (`Control::step`) in three loops at their own rates (PX4's own by
//! default, `Px4::RATES`): the position and velocity loop with its integrator and filtered
//! derivative, the attitude loop, the body-rate loop with its integrator and filtered
//! derivative and the allocator, each updating its memory when it runs.

use super::px4_allocator::{allocate, Mixer};
use super::ControlContext;
use super::{Control, Controller, ControllerKind, Due, Shared, Sight};
use crate::config::params::{params, Params};
use crate::config::ConfigError;
use crate::lane::{each3, gather, Lane, Masks, Param};
use crate::model::actuator::rotors::{allocation, RotorLayout};
use crate::model::{ActuatorKind, Inputs, Rigid, Tick, Trig};
use crate::trajectory::Reference;

params! {
    /// `[controller.px4]`: PX4's parameters under their own names and in their own units
    /// (degrees, deg/s, normalised thrust and torque), PX4's defaults where they fit.
    #[allow(non_snake_case)]
    pub struct Px4Params {
        MPC_XY_P: f64 => "1/s", "PX4 horizontal position gain", non_negative;
        MPC_Z_P: f64 => "1/s", "PX4 vertical position gain", non_negative;
        MPC_XY_VEL_P_ACC: f64 => "1/s", "PX4 horizontal velocity P gain", non_negative;
        MPC_XY_VEL_I_ACC: f64 => "1/s^2", "PX4 horizontal velocity I gain", non_negative;
        MPC_XY_VEL_D_ACC: f64 => "-", "PX4 horizontal velocity D gain", non_negative;
        MPC_Z_VEL_P_ACC: f64 => "1/s", "PX4 vertical velocity P gain", non_negative;
        MPC_Z_VEL_I_ACC: f64 => "1/s^2", "PX4 vertical velocity I gain", non_negative;
        MPC_Z_VEL_D_ACC: f64 => "-", "PX4 vertical velocity D gain", non_negative;
        MPC_VELD_LP: f64 => "Hz", "PX4 velocity-derivative low-pass cutoff", positive;
        MPC_XY_VEL_MAX: f64 => "m/s", "PX4 largest horizontal velocity setpoint", positive;
        MPC_Z_VEL_MAX_UP: f64 => "m/s", "PX4 largest ascent velocity setpoint", positive;
        MPC_Z_VEL_MAX_DN: f64 => "m/s", "PX4 largest descent velocity setpoint", positive;
        MPC_TILTMAX_AIR: f64 => "deg", "PX4 largest tilt of the thrust setpoint";
        /// The position loop's hover thrust feed-forward (PX4's `_hover_thrust`), normalised
        /// by the vehicle's full thrust (`full_thrust`); 0: the vehicle's own, mt g / full
        /// thrust, as PX4's hover-thrust estimator (`MPC_USE_HTE`, on by default) learns it.
        MPC_THR_HOVER: f64 => "-", "PX4 hover thrust (normalised; 0: the vehicle's own)", non_negative;
        MPC_THR_MIN: f64 => "-", "PX4 least collective thrust (normalised)", non_negative;
        MPC_THR_MAX: f64 => "-", "PX4 largest collective thrust (normalised)", positive;
        MPC_THR_XY_MARG: f64 => "-", "PX4 horizontal thrust margin (normalised)", non_negative;
        MC_ROLL_P: f64 => "1/s", "PX4 roll attitude gain", non_negative;
        MC_PITCH_P: f64 => "1/s", "PX4 pitch attitude gain", non_negative;
        MC_YAW_P: f64 => "1/s", "PX4 yaw attitude gain", non_negative;
        MC_YAW_WEIGHT: f64 => "-", "PX4 yaw weight of the attitude error", non_negative;
        MC_ROLLRATE_MAX: f64 => "deg/s", "PX4 largest roll-rate setpoint", positive;
        MC_PITCHRATE_MAX: f64 => "deg/s", "PX4 largest pitch-rate setpoint", positive;
        MC_YAWRATE_MAX: f64 => "deg/s", "PX4 largest yaw-rate setpoint", positive;
        MC_ROLLRATE_P: f64 => "s/rad", "PX4 roll-rate P gain (normalised torque)", non_negative;
        MC_ROLLRATE_I: f64 => "1/rad", "PX4 roll-rate I gain (normalised torque)", non_negative;
        MC_ROLLRATE_D: f64 => "s^2/rad", "PX4 roll-rate D gain (normalised torque)", non_negative;
        MC_PITCHRATE_P: f64 => "s/rad", "PX4 pitch-rate P gain (normalised torque)", non_negative;
        MC_PITCHRATE_I: f64 => "1/rad", "PX4 pitch-rate I gain (normalised torque)", non_negative;
        MC_PITCHRATE_D: f64 => "s^2/rad", "PX4 pitch-rate D gain (normalised torque)", non_negative;
        MC_YAWRATE_P: f64 => "s/rad", "PX4 yaw-rate P gain (normalised torque)", non_negative;
        MC_YAWRATE_I: f64 => "1/rad", "PX4 yaw-rate I gain (normalised torque)", non_negative;
        MC_YAWRATE_D: f64 => "s^2/rad", "PX4 yaw-rate D gain (normalised torque)", non_negative;
        MC_RR_INT_LIM: f64 => "-", "PX4 roll-rate integrator limit (normalised torque)", non_negative;
        MC_PR_INT_LIM: f64 => "-", "PX4 pitch-rate integrator limit (normalised torque)", non_negative;
        MC_YR_INT_LIM: f64 => "-", "PX4 yaw-rate integrator limit (normalised torque)", non_negative;
        IMU_DGYRO_CUTOFF: f64 => "Hz", "PX4 rate-derivative low-pass cutoff", positive;
        /// PX4's `CA_ROTORn_KM`: the rotors' yaw torque per unit thrust as the allocator
        /// believes it. The normalised allocation does not depend on it; it sets the yaw
        /// torque of the ideal actuator (the rotors' own `torque_ratio` sets it on rotors).
        yaw_torque_ratio: f64 => "m", "Yaw torque per rotor thrust (PX4 CA_ROTOR_KM)", positive;
    }
}

impl Default for Px4Params {
    /// PX4's defaults (mc_pos_control, mc_att_control, mc_rate_control parameters).
    fn default() -> Self {
        Self {
            MPC_XY_P: 0.95,
            MPC_Z_P: 1.0,
            MPC_XY_VEL_P_ACC: 1.8,
            MPC_XY_VEL_I_ACC: 0.4,
            MPC_XY_VEL_D_ACC: 0.2,
            MPC_Z_VEL_P_ACC: 4.0,
            MPC_Z_VEL_I_ACC: 2.0,
            MPC_Z_VEL_D_ACC: 0.0,
            MPC_VELD_LP: 5.0,
            MPC_XY_VEL_MAX: 12.0,
            MPC_Z_VEL_MAX_UP: 3.0,
            MPC_Z_VEL_MAX_DN: 1.5,
            MPC_TILTMAX_AIR: 45.0,
            MPC_THR_HOVER: 0.0,
            MPC_THR_MIN: 0.12,
            MPC_THR_MAX: 1.0,
            MPC_THR_XY_MARG: 0.3,
            MC_ROLL_P: 6.5,
            MC_PITCH_P: 6.5,
            MC_YAW_P: 2.8,
            MC_YAW_WEIGHT: 0.4,
            MC_ROLLRATE_MAX: 220.0,
            MC_PITCHRATE_MAX: 220.0,
            MC_YAWRATE_MAX: 200.0,
            MC_ROLLRATE_P: 0.15,
            MC_ROLLRATE_I: 0.2,
            MC_ROLLRATE_D: 0.003,
            MC_PITCHRATE_P: 0.15,
            MC_PITCHRATE_I: 0.2,
            MC_PITCHRATE_D: 0.003,
            MC_YAWRATE_P: 0.2,
            MC_YAWRATE_I: 0.1,
            MC_YAWRATE_D: 0.0,
            MC_RR_INT_LIM: 0.3,
            MC_PR_INT_LIM: 0.3,
            MC_YR_INT_LIM: 0.3,
            IMU_DGYRO_CUTOFF: 30.0,
            yaw_torque_ratio: 0.016,
        }
    }
}

/// Memory slots (`Control::Memory`): velocity integrator (m/s^2), last velocity, filtered
/// velocity derivative, rate integrator (normalised torque), last rate, filtered rate
/// derivative; x, y, z or roll, pitch, yaw each. Then the allocator's last published saturation
/// per torque axis (+1: a positive torque was not achieved, -1: a negative one, 0: none) and
/// the rate loop's updates since that publication. Then what the loops hold between their
/// updates: the position loop's normalised collective thrust, desired body z axis and desired
/// attitude (a quaternion), the attitude loop's rate setpoint, the rate loop's thrust and
/// torques (N, N m).
const VEL_INT: usize = 0;
const VEL_PREV: usize = 3;
const VEL_DOT: usize = 6;
const RATE_INT: usize = 9;
const RATE_PREV: usize = 12;
const RATE_DOT: usize = 15;
const SATURATION: usize = 18;
const STATUS_AGE: usize = 21;
const HELD_THRUST: usize = 22;
const HELD_B3: usize = 23;
const HELD_QD: usize = 26;
const HELD_RATE_SP: usize = 30;
const HELD_U1: usize = 33;
const HELD_TAU: usize = 34;

/// PX4's PID with the derivative on the measurement, per axis: the error `sp - x` and
/// `(sp - x) kp + integral - derivative kd`, the integrator and the filtered derivative as
/// `mem` holds them (`slots`: their first indices). The velocity and the rate loops' rule.
#[inline(always)]
fn pid_on_measurement<L: Lane, P: Param<L>>(
    sp: &[L; 3],
    x: &[L; 3],
    (kp, kd): (&[P; 3], &[P; 3]),
    mem: &Memory<L>,
    (int, dot): (usize, usize),
) -> ([L; 3], [L; 3]) {
    let err = each3(
        #[inline(always)]
        |i| sp[i] - x[i],
    );
    let out = each3(
        #[inline(always)]
        |i| err[i] * kp[i].get() + mem[int + i] - mem[dot + i] * kd[i].get(),
    );
    (err, out)
}

/// PX4's filtered derivative of a measurement `x` (x, y, z or roll, pitch, yaw): its change
/// since the last one (`mem[prev..]`) over the loop's period `dt`, low-passed by `alpha` into
/// `mem[dot..]`; `x` then becomes the last one.
#[inline(always)]
#[allow(clippy::manual_memcpy)] // each slot read before it is written, as PX4 does
fn filter_derivative<L: Lane>(
    x: &[L; 3],
    mem: &mut Memory<L>,
    prev: usize,
    dot: usize,
    dt: L,
    alpha: L,
) {
    for i in 0..3 {
        let raw = (x[i] - mem[prev + i]) / dt;
        mem[dot + i] += (raw - mem[dot + i]) * alpha;
        mem[prev + i] = x[i];
    }
}
/// Slots the law uses.
const PX4_MEMORY: usize = 37;

/// The law's memory.
type Memory<L> = [L; PX4_MEMORY];

/// Hz, PX4's loop rates (the multicopter control architecture: mc_pos_control's position and
/// velocity loops at 50 Hz, mc_att_control at 250 Hz, mc_rate_control and the control
/// allocator at the gyro's 1 kHz; docs/model.md, "Loop rates").
const PX4_RATES: [f64; 3] = [50.0, 250.0, 1000.0];

/// Norms are never divided by less than this (a zero vector keeps its direction undefined
/// and its scale factor 1).
const TINY: f64 = 1e-12;
/// PX4's I-term attenuation: the rate error at which the I gain falls to zero (400 deg/s).
const I_FACTOR_RATE: f64 = 400.0 * std::f64::consts::PI / 180.0;
/// `ControlAllocator::Run` publishes its status (the saturation the rate controller's
/// anti-windup reads) at most every 5 ms.
const STATUS_PERIOD: f64 = 0.005;
/// `torque_setpoint_achieved`: the unallocated torque's squared norm below this.
const ACHIEVED: f64 = 1e-6;
/// A torque axis counts as saturated past this unallocated torque (`FLT_EPSILON`).
const SATURATED: f64 = f32::EPSILON as f64;
/// The status age of a memory at rest: the first control step publishes.
const NEVER: f64 = 1e9;

/// Gains `P = f64` (one vehicle) or a lane type (one vehicle per lane, `Px4::gather`), in SI.
#[derive(Clone, Debug)]
pub struct Px4<P = f64> {
    shared: Shared<P>,
    /// 1/s: x, y, z position gains.
    pos_p: [P; 3],
    vel_p: [P; 3],
    vel_i: [P; 3],
    vel_d: [P; 3],
    vel_max_xy: P,
    vel_max_up: P,
    vel_max_dn: P,
    /// g tan(MPC_TILTMAX_AIR): the largest horizontal acceleration setpoint, m/s^2.
    acc_max_xy: P,
    /// Normalised thrusts.
    thr_hover: P,
    thr_min: P,
    thr_max: P,
    thr_xy_marg: P,
    /// Attitude gains (yaw already divided by the yaw weight, as PX4 does).
    att_p: [P; 3],
    yaw_w: P,
    /// rad/s.
    rate_max: [P; 3],
    rate_p: [P; 3],
    rate_i: [P; 3],
    rate_d: [P; 3],
    rate_int_lim: [P; 3],
    /// N per unit normalised thrust: the vehicle's full thrust (`full_thrust`).
    thrust_full: P,
    /// m/s^2, the vertical velocity integrator of a vehicle hovering for ever: what takes up
    /// the difference between the hover feed-forward and the weight (0 with the vehicle's own).
    vel_int_hover: P,
    /// PX4's allocation (`px4_allocator::Mixer`): motor i's output per normalised control,
    /// its usable inverse, and the control per output.
    mix: [[P; 4]; 4],
    mix_inv: [[P; 4]; 4],
    effect: [[P; 4]; 4],
    /// (U1, tau) in N and N m per unit output of each motor: the actuator's allocation matrix
    /// (the rotors' own on rotors, so that they are told exactly PX4's outputs) times a
    /// motor's full thrust T_full / 4.
    out: [[P; 4]; 4],
    /// Rate-loop updates between two publications of the allocator's status.
    status_every: P,
    /// s, the position loop's and the rate loop's periods.
    dt_vel: P,
    dt_rate: P,
    /// First-order low-pass weights dt / (dt + 1 / (2 pi fc)) of the derivatives, each at its
    /// loop's period.
    alpha_vel: P,
    alpha_rate: P,
}

fn lowpass_weight(dt: f64, fc: f64) -> f64 {
    dt / (dt + 1.0 / (2.0 * std::f64::consts::PI * fc))
}

impl Controller for Px4 {
    const LABEL: &'static str = "PX4";
    type Params = Px4Params;
    type At<L: Lane> = Px4<L>;
    const RATES: [f64; 3] = PX4_RATES;

    fn defaults() -> Option<Px4Params> {
        Some(Px4Params::default())
    }

    fn validate(k: &Px4Params, key: &str, cfg: &ControlContext) -> Result<(), ConfigError> {
        k.check_bounds(key)?;
        let range = |name: &str, x: f64, lo: f64, hi: f64, what: &str| {
            if x > lo && x < hi {
                Ok(())
            } else {
                Err(ConfigError::new(
                    format!("{key}.{name}"),
                    format!("{key}.{name} must be {what}, got {x:?}"),
                ))
            }
        };
        range(
            "MPC_TILTMAX_AIR",
            k.MPC_TILTMAX_AIR,
            0.0,
            90.0,
            "between 0 and 90 deg (exclusive)",
        )?;
        range(
            "MPC_THR_MAX",
            k.MPC_THR_MAX,
            k.MPC_THR_MIN.max(k.MPC_THR_XY_MARG),
            f64::INFINITY,
            "above MPC_THR_MIN and MPC_THR_XY_MARG",
        )?;
        if k.MPC_THR_HOVER != 0.0 {
            range(
                "MPC_THR_HOVER",
                k.MPC_THR_HOVER,
                0.0,
                k.MPC_THR_MAX,
                "0 (the vehicle's own) or between 0 and MPC_THR_MAX (exclusive)",
            )?;
        }
        // At a least thrust at or above hover the vehicle cannot descend: it climbs away. The
        // hover thrust set, or the vehicle's own (0: its weight over its full thrust) where the
        // least thrust is set away from PX4's default: a vehicle too strong for the default
        // least thrust is refused only for px4's own keys, not for every law (a thrust too
        // small to hover is the actuators' and `thrust_max`'s checks, named by their keys).
        let hover = hover_thrust(k, cfg);
        let judged = k.MPC_THR_HOVER > 0.0 || k.MPC_THR_MIN != Px4Params::default().MPC_THR_MIN;
        if judged && k.MPC_THR_MIN >= hover {
            return Err(ConfigError::new(
                format!("{key}.MPC_THR_MIN"),
                format!(
                    "{key}.MPC_THR_MIN must be below MPC_THR_HOVER ({:?}): at a least thrust at or above hover the vehicle cannot descend, got {:?}",
                    hover, k.MPC_THR_MIN
                ),
            ));
        }
        range(
            "MC_YAW_WEIGHT",
            k.MC_YAW_WEIGHT,
            0.0,
            1.0 + f64::EPSILON,
            "in (0, 1]",
        )?;
        if k.MPC_XY_VEL_I_ACC > 0.0 && k.MPC_XY_VEL_P_ACC <= 0.0 {
            return Err(ConfigError::new(
                format!("{key}.MPC_XY_VEL_P_ACC"),
                format!(
                    "{key}.MPC_XY_VEL_P_ACC must be > 0 with an integral gain (its anti-windup divides by it), got {:?}",
                    k.MPC_XY_VEL_P_ACC
                ),
            ));
        }
        Ok(())
    }

    fn new(k: &Px4Params, cfg: &ControlContext) -> Self {
        let shared = Shared::new(cfg);
        let g = cfg.environment.gravity;
        let [dt_vel, _, dt_rate] = cfg
            .controller
            .loop_periods(ControllerKind::Px4, cfg.integrator.dt);
        let thrust_full = full_thrust(cfg);
        let arm = cfg.vehicle.arm_length;
        let (layout, torque_ratio) = px4_geometry(k, cfg);
        let mixer = Mixer::new(layout, arm, k.yaw_torque_ratio);
        let m = allocation(layout, arm, torque_ratio);
        let motor_full = thrust_full / 4.0;
        let out = m.map(|row| row.map(|x| x * motor_full));
        Self {
            shared,
            pos_p: [k.MPC_XY_P, k.MPC_XY_P, k.MPC_Z_P],
            vel_p: [k.MPC_XY_VEL_P_ACC, k.MPC_XY_VEL_P_ACC, k.MPC_Z_VEL_P_ACC],
            vel_i: [k.MPC_XY_VEL_I_ACC, k.MPC_XY_VEL_I_ACC, k.MPC_Z_VEL_I_ACC],
            vel_d: [k.MPC_XY_VEL_D_ACC, k.MPC_XY_VEL_D_ACC, k.MPC_Z_VEL_D_ACC],
            vel_max_xy: k.MPC_XY_VEL_MAX,
            vel_max_up: k.MPC_Z_VEL_MAX_UP,
            vel_max_dn: k.MPC_Z_VEL_MAX_DN,
            acc_max_xy: g * k.MPC_TILTMAX_AIR.to_radians().tan(),
            thr_hover: hover_thrust(k, cfg),
            vel_int_hover: hover_integrator(k, cfg),
            thr_min: k.MPC_THR_MIN,
            thr_max: k.MPC_THR_MAX,
            thr_xy_marg: k.MPC_THR_XY_MARG,
            att_p: [k.MC_ROLL_P, k.MC_PITCH_P, k.MC_YAW_P / k.MC_YAW_WEIGHT],
            yaw_w: k.MC_YAW_WEIGHT,
            rate_max: [
                k.MC_ROLLRATE_MAX.to_radians(),
                k.MC_PITCHRATE_MAX.to_radians(),
                k.MC_YAWRATE_MAX.to_radians(),
            ],
            rate_p: [k.MC_ROLLRATE_P, k.MC_PITCHRATE_P, k.MC_YAWRATE_P],
            rate_i: [k.MC_ROLLRATE_I, k.MC_PITCHRATE_I, k.MC_YAWRATE_I],
            rate_d: [k.MC_ROLLRATE_D, k.MC_PITCHRATE_D, k.MC_YAWRATE_D],
            rate_int_lim: [k.MC_RR_INT_LIM, k.MC_PR_INT_LIM, k.MC_YR_INT_LIM],
            thrust_full,
            mix: mixer.mix,
            mix_inv: mixer.inv,
            effect: mixer.effect,
            out,
            status_every: (STATUS_PERIOD / dt_rate - 1e-9).ceil().max(1.0),
            dt_vel,
            dt_rate,
            alpha_vel: lowpass_weight(dt_vel, k.MPC_VELD_LP),
            alpha_rate: lowpass_weight(dt_rate, k.IMU_DGYRO_CUTOFF),
        }
    }

    fn gather<L: Lane>(each: &[&Px4]) -> Px4<L> {
        gather!(|l| each[l] => Px4 {
            shared, pos_p, vel_p, vel_i, vel_d, vel_max_xy, vel_max_up, vel_max_dn, acc_max_xy,
            thr_hover, thr_min, thr_max, thr_xy_marg, att_p, yaw_w, rate_max, rate_p, rate_i,
            rate_d, rate_int_lim, thrust_full, vel_int_hover, mix, mix_inv, effect, out, status_every, dt_vel,
            dt_rate, alpha_vel, alpha_rate,
        })
    }

    /// The velocity integrator (x, y, z) and the rate integrator (roll, pitch, yaw), each whose
    /// gain is not zero.
    fn integrators(&self) -> Vec<usize> {
        let velocity = (0..3).filter(|&i| self.vel_i[i] > 0.0).map(|i| VEL_INT + i);
        let rate = (0..3)
            .filter(|&i| self.rate_i[i] > 0.0)
            .map(|i| RATE_INT + i);
        velocity.chain(rate).collect()
    }
}

/// N, the vehicle's full collective thrust, PX4's normalised thrust 1 (every motor's output
/// at 1): what the rotors give (4 `actuator.thrust_max`, before any battery sag or fault, which
/// PX4 does not know of); with the ideal actuator, which has no limit, `controller.thrust_max`
/// if given, else twice the weight the law believes (an airframe hovering at half thrust,
/// PX4's default `MPC_THR_HOVER`).
pub fn full_thrust(cfg: &ControlContext) -> f64 {
    match cfg.actuator.model {
        ActuatorKind::Rotors => 4.0 * cfg.actuator.rotors.thrust_max,
        _ => cfg
            .controller
            .thrust_max
            .unwrap_or_else(|| Shared::new(cfg).mt * cfg.environment.gravity / 0.5),
    }
}

/// The hover thrust the position loop feeds forward (normalised): `MPC_THR_HOVER`, or where it
/// is 0 the vehicle's own, mt g / `full_thrust`. Only the feed-forward: the thrust's scale,
/// and so every gain in N and N m, is the vehicle's full thrust whatever it is.
pub fn hover_thrust(k: &Px4Params, cfg: &ControlContext) -> f64 {
    if k.MPC_THR_HOVER > 0.0 {
        k.MPC_THR_HOVER
    } else {
        Shared::new(cfg).mt * cfg.environment.gravity / full_thrust(cfg)
    }
}

/// m/s^2, the vertical velocity integrator at steady hover: the acceleration setpoint a with
/// `MPC_THR_HOVER (a + g) / g` full thrust = mt g, within the integrator's limit g; exactly 0
/// with the vehicle's own hover thrust.
fn hover_integrator(k: &Px4Params, cfg: &ControlContext) -> f64 {
    if k.MPC_THR_HOVER > 0.0 {
        let g = cfg.environment.gravity;
        let weight = Shared::new(cfg).mt * g;
        (g * (weight / (k.MPC_THR_HOVER * full_thrust(cfg)) - 1.0)).clamp(-g, g)
    } else {
        0.0
    }
}

/// The rotor geometry PX4's allocator is configured for (its `CA_ROTORn_P*` follow the
/// airframe: the rotors' `layout`, quad X by default) and the reaction torque per thrust of the
/// rotors its outputs drive: the rotors' own `torque_ratio` when the actuator is the rotors,
/// else PX4's belief `yaw_torque_ratio`.
fn px4_geometry(k: &Px4Params, cfg: &ControlContext) -> (RotorLayout, f64) {
    let rotors = &cfg.actuator.rotors;
    match cfg.actuator.model {
        ActuatorKind::Rotors => (rotors.layout, rotors.torque_ratio),
        _ => (rotors.layout, k.yaw_torque_ratio),
    }
}

/// A weight in [0, 1] that is 1 where `excess` <= 0 and falls to 0 just above: the reference's
/// feed-forward where its velocity is within the limits. (Functions, not closures, in the law:
/// see `lane::each3`.)
#[inline(always)]
fn feed_forward_weight<L: Lane>(excess: L) -> L {
    let (zero, one) = (L::splat(0.0), L::splat(1.0));
    (excess * L::splat(-1e9) + one).max(zero).min(one)
}

/// One output row's weighted sum of the motor outputs: thrust or a torque in N or N m.
#[inline(always)]
fn motor_sum<L: Lane, P: Param<L>>(row: &[P; 4], m: &[L; 4]) -> L {
    let w: [L; 4] = [row[0].get(), row[1].get(), row[2].get(), row[3].get()];
    w[0] * m[0] + w[1] * m[1] + w[2] * m[2] + w[3] * m[3]
}

/// A 4 x 4 parameter matrix as lane values.
#[inline(always)]
fn lanes44<L: Lane, P: Param<L>>(m: &[[P; 4]; 4]) -> [[L; 4]; 4] {
    m.map(|row| row.map(|x| x.get()))
}

/// A quaternion (w, x, y, z), Hamilton product.
type Quat<L> = [L; 4];

#[inline(always)]
fn qmul<L: Lane>(a: &Quat<L>, b: &Quat<L>) -> Quat<L> {
    [
        a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
        a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
        a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
        a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0],
    ]
}

#[inline(always)]
fn conj<L: Lane>(q: &Quat<L>) -> Quat<L> {
    [q[0], -q[1], -q[2], -q[3]]
}

/// x / |x| (+/-1; 0 at 0): PX4's `canonical()` sign.
#[inline(always)]
fn sign<L: Lane>(x: L) -> L {
    x / x.abs().max(L::splat(TINY))
}

/// (cos, sin) of half an angle in (-pi/2, pi/2] given its cosine (>= 0) and sine.
#[inline(always)]
fn half<L: Lane>(c: L, s: L) -> (L, L) {
    let ch = ((c + 1.0) * 0.5).sqrt();
    (ch, s / (ch * 2.0))
}

/// min(1, limit / |v|): the factor that scales a vector of norm `n` down to at most `limit`.
#[inline(always)]
fn shrink<L: Lane>(n: L, limit: L) -> L {
    (limit / n.max(L::splat(TINY))).min(L::splat(1.0))
}

/// What the position loop computed that its integrator update needs.
struct VelocityLoop<L> {
    vel_err: [L; 3],
    /// The acceleration setpoint with its feed-forward, before the tilt limit (m/s^2).
    acc_sp: [L; 3],
    /// Vertical normalised thrust out of the acceleration-to-thrust step (before saturation).
    thr_z_acc: L,
    /// Horizontal normalised thrust after saturation.
    thr_xy: [L; 2],
}

impl<P: Copy + Sync> Px4<P> {
    /// The position and velocity loop (PX4's `PositionControl`): its filtered derivative takes
    /// the new measurement, the setpoints follow with the integrator as held, then the
    /// integrator advances by the loop's period with its anti-windup
    /// (`PositionControl::_velocityControl`). Holds the collective thrust, the desired body z
    /// axis and the desired attitude.
    #[inline(always)]
    fn position_loop<L: Masks>(&self, s: &Rigid<L>, r: &Reference, mem: &mut Memory<L>)
    where
        P: Param<L>,
    {
        let (dt, alpha) = (self.dt_vel.get(), self.alpha_vel.get());
        filter_derivative(&s.vel, mem, VEL_PREV, VEL_DOT, dt, alpha);
        let (thrust, b3, qd, p) = self.setpoints(s, r, mem);
        mem[HELD_THRUST] = thrust;
        mem[HELD_B3..HELD_B3 + 3].copy_from_slice(&b3);
        mem[HELD_QD..HELD_QD + 4].copy_from_slice(&qd);
        let zero = L::splat(0.0);
        let g: L = self.shared.g.get();

        // Velocity integrator. Vertical: no further winding into a saturated thrust.
        let mut e = p.vel_err;
        let low = p.thr_z_acc.cmp_le(self.thr_min.get());
        let high = p.thr_z_acc.cmp_ge(self.thr_max.get());
        e[2] = L::select(low, e[2].max(zero), e[2]);
        e[2] = L::select(high, e[2].min(zero), e[2]);
        // Horizontal: tracking anti-windup towards the acceleration the thrust produces.
        let to_acc = g / self.thr_hover.get();
        let prod = [p.thr_xy[0] * to_acc, p.thr_xy[1] * to_acc];
        let a = [p.acc_sp[0], p.acc_sp[1]];
        let fits = (a[0] * a[0] + a[1] * a[1]).cmp_le(prod[0] * prod[0] + prod[1] * prod[1]);
        let arw: L = L::splat(2.0) / self.vel_p[0].get();
        for i in 0..2 {
            let limited = L::select(fits, a[i], prod[i]);
            e[i] = e[i] - (a[i] - limited) * arw;
        }
        for (i, e) in e.iter().enumerate() {
            mem[VEL_INT + i] += *e * self.vel_i[i].get() * dt;
        }
        mem[VEL_INT + 2] = mem[VEL_INT + 2].clamp(-g, g);
    }

    /// The position loop's setpoints at state `s` with the integrator and filtered derivative
    /// in `mem`: the collective thrust (normalised), the desired body z axis, the desired
    /// attitude, and what the integrator update needs.
    #[inline(always)]
    #[allow(clippy::type_complexity)]
    fn setpoints<L: Masks>(
        &self,
        s: &Rigid<L>,
        r: &Reference,
        mem: &Memory<L>,
    ) -> (L, [L; 3], Quat<L>, VelocityLoop<L>)
    where
        P: Param<L>,
    {
        let g: L = self.shared.g.get();
        // Position P, plus the reference velocity as feed-forward, then the velocity limits.
        let mut v_sp = each3(
            #[inline(always)]
            |i| (L::splat(r.pos[i]) - s.pos[i]) * self.pos_p[i].get() + L::splat(r.vel[i]),
        );
        let k = shrink(
            (v_sp[0] * v_sp[0] + v_sp[1] * v_sp[1]).sqrt(),
            self.vel_max_xy.get(),
        );
        v_sp[0] = v_sp[0] * k;
        v_sp[1] = v_sp[1] * k;
        let vmax_dn: L = self.vel_max_dn.get();
        v_sp[2] = v_sp[2].clamp(-vmax_dn, self.vel_max_up.get());
        // Velocity PID (derivative on the measurement), plus the reference acceleration where
        // the reference's velocity is within the limits: a route that asks for more is not a
        // trajectory PX4's own generator would give, and its acceleration fed forward past a
        // clamped velocity setpoint would push the vehicle past the limit.
        let ff_xy = feed_forward_weight(L::splat(r.vel[0].hypot(r.vel[1])) - self.vel_max_xy.get());
        let ff_z = feed_forward_weight(L::splat(r.vel[2]) - self.vel_max_up.get())
            * feed_forward_weight(L::splat(-r.vel[2]) - vmax_dn);
        let ff = [ff_xy, ff_xy, ff_z];
        let gains = (&self.vel_p, &self.vel_d);
        let (vel_err, pid) = pid_on_measurement(&v_sp, &s.vel, gains, mem, (VEL_INT, VEL_DOT));
        let acc_sp = each3(
            #[inline(always)]
            |i| pid[i] + ff[i] * r.acc[i],
        );
        // Acceleration to thrust: tilt limit on the horizontal acceleration (the thrust
        // direction assumes g vertically), collective thrust from the hover thrust.
        let k = shrink(
            (acc_sp[0] * acc_sp[0] + acc_sp[1] * acc_sp[1]).sqrt(),
            self.acc_max_xy.get(),
        );
        let (ax, ay) = (acc_sp[0] * k, acc_sp[1] * k);
        let nz = (ax * ax + ay * ay + g * g).sqrt();
        let hover: L = self.thr_hover.get();
        let thr_z_raw = hover * (acc_sp[2] + g) / g;
        let collective = (thr_z_raw * nz / g).max(self.thr_min.get());
        let (mut tx, mut ty, mut tz) = (
            collective * ax / nz,
            collective * ay / nz,
            collective * g / nz,
        );
        let thr_z_acc = tz;
        // Vertical thrust first, keeping a horizontal margin; the horizontal thrust gets what
        // is left of MPC_THR_MAX.
        let thr_max: L = self.thr_max.get();
        let txy = (tx * tx + ty * ty).sqrt();
        let alloc = txy.min(self.thr_xy_marg.get());
        tz = tz.min((thr_max * thr_max - alloc * alloc).sqrt());
        let txy_max = (thr_max * thr_max - tz * tz).max(L::splat(0.0)).sqrt();
        let k = shrink(txy, txy_max);
        tx = tx * k;
        ty = ty * k;
        let thrust = (tx * tx + ty * ty + tz * tz).sqrt();

        // Attitude setpoint: body z along the thrust, heading psi_ref (PX4's bodyzToAttitude,
        // which is the ZYX Euler attitude (phi_d, theta_d, psi_ref) with that z axis).
        let b3 = [tx / thrust, ty / thrust, tz / thrust];
        let (spd, cpd) = r.psi.sin_cos();
        let (spd, cpd) = (L::splat(spd), L::splat(cpd));
        let a = cpd * b3[0] + spd * b3[1];
        let b = cpd * b3[1] - spd * b3[0];
        let c = b3[2];
        let cphi_d = (a * a + c * c).sqrt();
        let (cp2, sp2) = half(cphi_d, -b);
        let (ct2, st2) = half(c / cphi_d, a / cphi_d);
        let (sy2, cy2) = (r.psi * 0.5).sin_cos();
        let z = L::splat(0.0);
        let qd = qmul(
            &qmul(&[L::splat(cy2), z, z, L::splat(sy2)], &[ct2, z, st2, z]),
            &[cp2, sp2, z, z],
        );
        (
            thrust,
            b3,
            qd,
            VelocityLoop {
                vel_err,
                acc_sp,
                thr_z_acc,
                thr_xy: [tx, ty],
            },
        )
    }

    /// The attitude loop (PX4's `AttitudeControl`): the rate setpoint toward the held desired
    /// attitude, from the attitude the vehicle has now.
    #[inline(always)]
    fn attitude_loop<L: Masks>(
        &self,
        s: &Rigid<L>,
        trig: &Trig<L>,
        r: &Reference,
        mem: &mut Memory<L>,
    ) where
        P: Param<L>,
    {
        let one = L::splat(1.0);
        let z = L::splat(0.0);
        let b3 = [mem[HELD_B3], mem[HELD_B3 + 1], mem[HELD_B3 + 2]];
        let qd = [
            mem[HELD_QD],
            mem[HELD_QD + 1],
            mem[HELD_QD + 2],
            mem[HELD_QD + 3],
        ];
        // The vehicle's attitude.
        let (sh_phi, ch_phi) = (s.att[0] * 0.5).sin_cos();
        let (sh_th, ch_th) = (s.att[1] * 0.5).sin_cos();
        let (sh_psi, ch_psi) = (s.att[2] * 0.5).sin_cos();
        let q = qmul(
            &qmul(&[ch_psi, z, z, sh_psi], &[ch_th, z, sh_th, z]),
            &[ch_phi, sh_phi, z, z],
        );
        // Reduced attitude: the shortest rotation of the body z axis onto the desired one
        // (roll and pitch first), then the yaw part of the rest, weighted by MC_YAW_WEIGHT.
        let (sphi, cphi, sth, cth, spsi, cpsi) = (
            trig.sphi, trig.cphi, trig.sth, trig.cth, trig.spsi, trig.cpsi,
        );
        let ez = [
            cphi * sth * cpsi + sphi * spsi,
            cphi * sth * spsi - sphi * cpsi,
            cphi * cth,
        ];
        let dot = ez[0] * b3[0] + ez[1] * b3[1] + ez[2] * b3[2];
        let cr = [
            ez[1] * b3[2] - ez[2] * b3[1],
            ez[2] * b3[0] - ez[0] * b3[2],
            ez[0] * b3[1] - ez[1] * b3[0],
        ];
        let w0 = dot + 1.0;
        let n = (w0 * w0 + cr[0] * cr[0] + cr[1] * cr[1] + cr[2] * cr[2]).sqrt();
        let q_red = [w0 / n, cr[0] / n, cr[1] / n, cr[2] / n];
        let qd_red = qmul(&q_red, &q);
        let q_mix = qmul(&conj(&qd_red), &qd);
        let half_yaw = (sign(q_mix[0]) * q_mix[3]).clamp(-one, one).asin();
        let (sw, cw) = (half_yaw * self.yaw_w.get()).sin_cos();
        let qd = qmul(&qd_red, &[cw, z, z, sw]);
        let qe = qmul(&conj(&q), &qd);
        let sgn = sign(qe[0]) * 2.0;
        // Rate setpoint: P on the error, the yaw-rate reference about the world z axis (in
        // body axes: the third row of R), then the rate limits.
        let world_z = [-sth, sphi * cth, cphi * cth];
        let rate_sp = each3(
            #[inline(always)]
            |i| {
                let max: L = self.rate_max[i].get();
                (qe[i + 1] * sgn * self.att_p[i].get() + world_z[i] * r.psi_dot).clamp(-max, max)
            },
        );
        mem[HELD_RATE_SP..HELD_RATE_SP + 3].copy_from_slice(&rate_sp);
    }

    /// The body-rate loop and the allocator (PX4's `RateControl`, `ControlAllocator`): the
    /// filtered rate derivative takes the new measurement, the torques follow from the held
    /// rate setpoint with the integrator as held, the allocator gives the motors the held
    /// thrust and those torques, then the integrator advances by the loop's period
    /// (`RateControl::updateIntegral`) and the allocator's status is published on its period.
    /// Holds the thrust and torques the motors give.
    #[inline(always)]
    fn rate_loop<L: Masks>(&self, s: &Rigid<L>, mem: &mut Memory<L>)
    where
        P: Param<L>,
    {
        let (dt, alpha) = (self.dt_rate.get(), self.alpha_rate.get());
        filter_derivative(&s.rate, mem, RATE_PREV, RATE_DOT, dt, alpha);
        let rate_sp = [
            mem[HELD_RATE_SP],
            mem[HELD_RATE_SP + 1],
            mem[HELD_RATE_SP + 2],
        ];
        let thrust = mem[HELD_THRUST];
        // Rate PID (derivative on the measurement), normalised torque, then N m.
        let gains = (&self.rate_p, &self.rate_d);
        let (rate_err, torque) =
            pid_on_measurement(&rate_sp, &s.rate, gains, mem, (RATE_INT, RATE_DOT));
        // PX4's allocator: normalised torques and thrust (along body z down) to motor outputs
        // in [0, 1]; each motor's thrust is its output times T_full / 4.
        let c = [torque[0], torque[1], torque[2], -thrust];
        let a = allocate(
            &c,
            &lanes44(&self.mix),
            &lanes44(&self.mix_inv),
            &lanes44(&self.effect),
        );
        let m = &a.motors;
        let u1 = self.shared.limit_thrust(motor_sum(&self.out[0], m));
        let tau = [
            motor_sum(&self.out[1], m),
            motor_sum(&self.out[2], m),
            motor_sum(&self.out[3], m),
        ];
        mem[HELD_U1] = u1;
        mem[HELD_TAU..HELD_TAU + 3].copy_from_slice(&tau);
        let unallocated = a.unallocated;
        let zero = L::splat(0.0);

        // Rate integrator (RateControl::updateIntegral): not further into a torque the
        // allocator last reported unachieved, attenuated at large errors, limited.
        let one = L::splat(1.0);
        for i in 0..3 {
            let mut e = rate_err[i];
            let sat = mem[SATURATION + i];
            e = L::select(sat.cmp_ge(one), e.min(zero), e);
            e = L::select(sat.cmp_le(-one), e.max(zero), e);
            let f = e * (1.0 / I_FACTOR_RATE);
            let i_factor = (one - f * f).max(zero);
            let lim: L = self.rate_int_lim[i].get();
            mem[RATE_INT + i] =
                (mem[RATE_INT + i] + i_factor * self.rate_i[i].get() * e * dt).clamp(-lim, lim);
        }

        // The allocator's status, published every `status_every` steps, read by the rate
        // controller from the next step on (MulticopterRateControl: a direction is saturated
        // where the torque was not achieved and its unallocated part exceeds FLT_EPSILON).
        let un = &unallocated;
        let norm2 = un[0] * un[0] + un[1] * un[1] + un[2] * un[2];
        let missed = norm2.cmp_ge(L::splat(ACHIEVED));
        let due = mem[STATUS_AGE].cmp_ge(self.status_every.get());
        for i in 0..3 {
            let pos = L::select(L::splat(SATURATED).cmp_ge(un[i]), zero, one);
            let neg = L::select(un[i].cmp_ge(L::splat(-SATURATED)), zero, -one);
            let flag = L::select(missed, pos + neg, zero);
            mem[SATURATION + i] = L::select(due, flag, mem[SATURATION + i]);
        }
        mem[STATUS_AGE] = L::select(due, zero, mem[STATUS_AGE]) + one;
    }

    /// The memory of a vehicle that has been at `s` for ever: no integral, no derivative.
    #[inline(always)]
    #[allow(clippy::manual_memcpy)] // the slots are named one by one, as the loop below reads them
    fn at_rest<L: Lane>(s: &Rigid<L>) -> Memory<L> {
        let mut m = [L::splat(0.0); PX4_MEMORY];
        for i in 0..3 {
            m[VEL_PREV + i] = s.vel[i];
            m[RATE_PREV + i] = s.rate[i];
        }
        m[STATUS_AGE] = L::splat(NEVER);
        m
    }
}

impl<P: Copy + Sync> Control<P> for Px4<P> {
    type Memory<L: Lane> = Memory<L>;

    /// Integrators at their hover value (the vertical one taking up the difference between
    /// the hover feed-forward and the weight, `hover_integrator`; the others zero), derivative
    /// terms zero: at rest, the law is what the linearisation differentiates (docs/model.md,
    /// "The PX4 cascade").
    #[inline(always)]
    fn memory<L: Masks>(&self, seen: &Sight<L>) -> Memory<L>
    where
        P: Param<L>,
    {
        let mut m = Self::at_rest(seen.rigid);
        m[VEL_INT + 2] = self.vel_int_hover.get();
        m
    }

    /// One step of PX4's loops: each that is due runs (position, attitude, rate and allocator,
    /// in that order, each reading what the one above holds).
    #[inline(always)]
    fn step<L: Masks>(
        &self,
        seen: &Sight<L>,
        r: &Reference,
        _at: Tick,
        due: Due,
        mem: &mut Memory<L>,
    ) -> Inputs<L>
    where
        P: Param<L>,
    {
        let s = seen.rigid;
        if due.position {
            self.position_loop(s, r, mem);
        }
        if due.attitude {
            self.attitude_loop(s, seen.trig, r, mem);
        }
        if due.rate {
            self.rate_loop(s, mem);
        }
        Inputs {
            u1: mem[HELD_U1],
            tau: [mem[HELD_TAU], mem[HELD_TAU + 1], mem[HELD_TAU + 2]],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::control::tests::at_rest;
    use crate::scenario::tests::paper;
    use crate::scenario::Config;

    fn px4(cfg: &Config) -> Px4 {
        Px4::new(&Px4Params::default(), &cfg.control_context())
    }

    /// The paper's scenario, PX4's default parameters and the law they make.
    fn paper_px4() -> (Config, Px4Params, Px4) {
        let cfg = paper();
        let c = px4(&cfg);
        (cfg, Px4Params::default(), c)
    }

    /// The vehicle at rest and level 2 m up, and a reference holding it there.
    fn held_at_two_metres() -> (Rigid<f64>, Reference) {
        let r = Reference {
            pos: [0.0, 0.0, 2.0],
            ..Reference::default()
        };
        (at_rest(r.pos, 0.0), r)
    }

    #[test]
    fn hover_is_the_weight_and_no_torque() {
        let cfg = paper();
        let c = px4(&cfg);
        let s = at_rest([1.0, -2.0, 3.0], 0.4);
        let r = Reference {
            pos: [1.0, -2.0, 3.0],
            psi: 0.4,
            ..Reference::default()
        };
        let u = c.control(&s, &r, Tick::START);
        let w = (cfg.vehicle.mass + cfg.payload.mass) * cfg.environment.gravity;
        assert!((u.u1 - w).abs() < 1e-12, "{} vs {w}", u.u1);
        for t in u.tau {
            assert!(t.abs() < 1e-12, "{:?}", u.tau);
        }
    }

    /// The mapping: at a level attitude, a roll-rate error e gives MC_ROLLRATE_P e full-scale
    /// torques; a height error gives the cascade's P-P vertical thrust.
    #[test]
    fn gains_map_to_si_as_documented() {
        let (cfg, k, c) = paper_px4();
        let (mut s, r) = held_at_two_metres();
        s.rate[0] = -0.1;
        s.pos[2] = 1.9;
        let u = c.control(&s, &r, Tick::START);
        let full = full_thrust(&cfg.control_context());
        // The paper's ideal actuators: twice the weight, the vehicle's own hover thrust 0.5.
        let mt = cfg.vehicle.mass + cfg.payload.mass;
        assert_eq!(full, mt * 9.81 * 2.0);
        let hover = hover_thrust(&k, &cfg.control_context());
        assert_eq!(hover, 0.5);
        // PX4's normalisation of a quad X: one unit of roll moves each motor by 1/sqrt 2 of
        // its full thrust full / 4, at arm / sqrt 2 from the axis: arm full / 2 in all.
        let roll_full = cfg.vehicle.arm_length * full / 2.0;
        assert!((u.tau[0] - k.MC_ROLLRATE_P * 0.1 * roll_full).abs() < 1e-12);
        let acc = k.MPC_Z_VEL_P_ACC * k.MPC_Z_P * 0.1;
        let want = hover * (acc + 9.81) / 9.81 * full;
        assert!((u.u1 - want).abs() < 1e-9, "{} vs {want}", u.u1);
    }

    /// A far target and a fast reference: the thrust direction stays within MPC_TILTMAX_AIR.
    #[test]
    fn thrust_setpoint_respects_the_tilt_limit() {
        let cfg = paper();
        let c = px4(&cfg);
        let s = at_rest([0.0, 0.0, 2.0], 0.0);
        let r = Reference {
            pos: [500.0, 300.0, 2.0],
            vel: [20.0, 0.0, 0.0],
            acc: [30.0, 0.0, 0.0],
            ..Reference::default()
        };
        let (_, _, _, k) = c.setpoints(&s, &r, &Px4::<f64>::at_rest(&s));
        let txy = (k.thr_xy[0].powi(2) + k.thr_xy[1].powi(2)).sqrt();
        // thr_z_acc is before the vertical saturation, which only lowers it when MPC_THR_MAX
        // binds; here it does not.
        let tilt = txy.atan2(k.thr_z_acc);
        assert!(tilt <= 45f64.to_radians() + 1e-12, "{tilt}");
        assert!(tilt > 44f64.to_radians(), "{tilt}");
    }

    /// The integrators: a held velocity error winds the vertical integrator by
    /// MPC_Z_VEL_I_ACC e dt per update of its loop (dt its period); a held rate error the rate
    /// integrator likewise.
    #[test]
    fn integrators_advance_once_per_update() {
        let (cfg, k, c) = paper_px4();
        let (mut s, r) = held_at_two_metres();
        s.vel[2] = -0.2;
        s.rate[0] = 0.05;
        let trig = Trig::of_angles(0.0, 0.0, 0.0);
        let seen = Sight::blind(&s, &trig);
        let mut mem = c.memory(&seen);
        // Each update advances an integrator by its own loop's period.
        let [dt_vel, _, dt_rate] = cfg
            .controller
            .loop_periods(ControllerKind::Px4, cfg.integrator.dt);
        for step in 0..3 {
            c.step(&seen, &r, Tick { step, t: 0.0 }, Due::ALL, &mut mem);
        }
        let want = 3.0 * k.MPC_Z_VEL_I_ACC * 0.2 * dt_vel;
        assert!(
            (mem[VEL_INT + 2] - want).abs() < 1e-15,
            "{}",
            mem[VEL_INT + 2]
        );
        let e = -0.05;
        let f = 1.0 - (e / I_FACTOR_RATE).powi(2);
        let want = 3.0 * f * k.MC_ROLLRATE_I * e * dt_rate;
        assert!((mem[RATE_INT] - want).abs() < 1e-15, "{}", mem[RATE_INT]);
        // A held state: the derivative filters stay at zero.
        assert_eq!(mem[VEL_DOT + 2], 0.0);
    }

    #[test]
    fn a_bad_value_is_named() {
        let mut v = crate::scenario::tests::paper_value();
        v["controller"]["px4"] = serde_json::to_value(Px4Params::default()).unwrap();
        v["controller"]["px4"]["MPC_TILTMAX_AIR"] = serde_json::json!(95.0);
        let e = crate::scenario::Config::from_json(&v.to_string()).unwrap_err();
        assert_eq!(e.key, "controller.px4.MPC_TILTMAX_AIR");
        assert!(e.message.contains("between 0 and 90 deg"), "{e}");
    }

    #[test]
    fn a_least_thrust_at_or_above_hover_is_refused() {
        for min in [0.5, 0.6] {
            let mut v = crate::scenario::tests::paper_value();
            v["controller"]["px4"] = serde_json::to_value(Px4Params::default()).unwrap();
            v["controller"]["px4"]["MPC_THR_MIN"] = serde_json::json!(min);
            let e = crate::scenario::Config::from_json(&v.to_string()).unwrap_err();
            assert_eq!(e.key, "controller.px4.MPC_THR_MIN");
            assert!(e.message.contains("below MPC_THR_HOVER"), "{e}");
        }
    }

    /// The delivery vehicle's full thrust is its rotors' (4 x 12 N), whatever `MPC_THR_HOVER`
    /// says: the hover thrust is only the position loop's feed-forward. At rest on its
    /// reference the vertical integrator takes up the difference between it and the weight
    /// (the collective is the weight); a height error's thrust scales with it, as PX4's
    /// acceleration-to-thrust does; the torque per unit (the rate gains in N m) does not move.
    #[test]
    fn the_hover_thrust_is_a_feed_forward_not_the_thrust_scale() {
        let cfg = delivery();
        let ctx = cfg.control_context();
        assert_eq!(full_thrust(&ctx), 48.0);
        let g = cfg.environment.gravity;
        let weight = (cfg.vehicle.mass + cfg.payload.mass) * g;
        let start = cfg.trajectory.points()[0];
        let r = Reference {
            pos: start,
            ..Reference::default()
        };
        let own = px4(&cfg);
        let set = Px4::new(
            &Px4Params {
                MPC_THR_HOVER: 0.42,
                ..Px4Params::default()
            },
            &ctx,
        );
        assert_eq!((own.thrust_full, set.thrust_full), (48.0, 48.0));
        assert_eq!(own.out, set.out);
        assert_eq!(own.vel_int_hover, 0.0);
        let want = g * (weight / (0.42 * 48.0) - 1.0);
        assert!(
            (set.vel_int_hover - want).abs() < 1e-12,
            "{}",
            set.vel_int_hover
        );
        let k = Px4Params::default();
        for (law, hover) in [(&own, weight / 48.0), (&set, 0.42)] {
            let s = at_rest(start, 0.0);
            let u = law.control(&s, &r, Tick::START);
            assert!((u.u1 - weight).abs() < 1e-9, "{} vs {weight}", u.u1);
            // 0.1 m low: the P-P vertical acceleration through this hover thrust.
            let low = at_rest([start[0], start[1], start[2] - 0.1], 0.0);
            let u = law.control(&low, &r, Tick::START);
            let extra = hover * k.MPC_Z_VEL_P_ACC * k.MPC_Z_P * 0.1 / g * 48.0;
            assert!(
                (u.u1 - weight - extra).abs() < 1e-9,
                "{} vs {}",
                u.u1,
                weight + extra
            );
        }
    }

    fn delivery() -> Config {
        let v = crate::scenario::tests::delivery_value();
        Config::from_json(&v.to_string()).expect("the delivery preset is valid")
    }

    /// The linearisation's Jacobian (dual numbers) against central differences of the same
    /// closed loop, at hover and off it (tilted, moving, yawed), on the paper's vehicle and on
    /// the delivery vehicle (cable and rotor lag); and the delivery hover is stable.
    #[test]
    fn linearisation_matches_finite_differences() {
        use crate::control::ControllerKind;
        use crate::stability::{analyse, closed_loop, closed_loop_jacobian, linearise, Verdict};
        for cfg in [paper(), delivery()] {
            let r = Reference {
                pos: cfg.trajectory.points()[0],
                ..Reference::default()
            };
            let cl = closed_loop(&cfg, ControllerKind::Px4, r);
            let lin = linearise(&cfg, ControllerKind::Px4, [0.0; 3]);
            assert!(lin.residual < 1e-9, "{}", lin.residual);
            let mut off = lin.equilibrium.clone();
            for (i, x) in off.iter_mut().enumerate() {
                *x += 0.01 * ((i as f64) * 0.7).sin();
            }
            for (at, exact) in [
                (lin.equilibrium.clone(), lin.a.clone()),
                (off.clone(), closed_loop_jacobian(&*cl, &off, &[0.0; 3])),
            ] {
                let n = at.len();
                let h = 1e-6;
                for j in 0..n {
                    let (mut up, mut down) = (at.clone(), at.clone());
                    up[j] += h;
                    down[j] -= h;
                    let (fu, _) = cl.eval(&up, &[0.0; 3]);
                    let (fd, _) = cl.eval(&down, &[0.0; 3]);
                    for i in 0..n {
                        let diff = (fu[i] - fd[i]) / (2.0 * h);
                        let tol = 1e-5 * diff.abs().max(1.0);
                        assert!(
                            (diff - exact[(i, j)]).abs() < tol,
                            "d f{i} / d s{j}: {diff} vs {}",
                            exact[(i, j)]
                        );
                    }
                }
            }
        }
        let a = analyse(&delivery(), ControllerKind::Px4);
        assert_eq!(a.verdict, Verdict::Stable, "{:?}", a.poles);
        let a = analyse(&paper(), ControllerKind::Px4);
        assert_eq!(a.verdict, Verdict::Stable, "{:?}", a.poles);
    }
}
