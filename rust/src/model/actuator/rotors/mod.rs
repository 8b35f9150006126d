//! Four rotors with first-order speed dynamics and per-rotor thrust limits (docs/model.md
//! section 8, "Rotors").
//!
//! Rotor i sits at l (cos a_i, sin a_i, 0) in body axes and pushes T_i = kf w_i^2 along body z,
//! with a yaw reaction s_i cq T_i. The allocation (U1, tau) = M T has rows (1, 1, 1, 1),
//! (l sin a_i), (-l cos a_i), (cq s_i). Held over a step: the controller's (U1, tau) through
//! M^-1, each rotor's thrust clamped to [thrust_min, thrust_max], and the speed that gives it,
//! w_cmd = sqrt(T / kf). The speeds are states, dw/dt = (w_cmd - w) / tau_m, and the airframe
//! feels M (kf w^2) at every RK4 stage.
//!
//! Faults and the battery (docs/model.md, "Rotor faults and battery sag"): the upper clamp
//! falls linearly over the flight, thrust_max (1 - battery_sag t / duration), and a failed
//! rotor i gives f_i of its clamped command from its fault's start on (its speed command is
//! sqrt(f_i T_i / kf)), the command held over the step as always.

mod aero;
mod allocation;
mod params;

use super::{Actuator, ActuatorModel};
use crate::config::ConfigError;
use crate::lane::{gather, Lane};
use crate::model::layout::{Axis, Part, StateVar};
use crate::model::section::OwnsKeys;
use crate::model::ModelContext;
use crate::model::{state_from_fn, Inputs, State, Tick};

use aero::{Coefficients, HubSums};
pub use allocation::{allocation, allocation_inverse, arm_directions, RotorLayout, SPIN};
pub use params::{RotorFault, RotorParams};

/// The rotors' parameters: `L = f64` for one vehicle, a lane type for one per lane.
#[derive(Clone, Copy, Debug)]
pub struct Rotors<L = f64> {
    /// M (see [`allocation`]).
    pub allocation: [[L; 4]; 4],
    /// M^-1 (see [`allocation_inverse`]).
    pub inverse: [[L; 4]; 4],
    /// N s^2/rad^2, kf.
    pub kf: L,
    /// N per rotor, the command's clamps.
    pub thrust_min: L,
    pub thrust_max: L,
    /// rad/s, the speed at which the four rotors hold the vehicle and its payload.
    pub hover_speed: L,
    /// 1 / kf and 1 / tau_m, computed once.
    inv_kf: L,
    inv_tau: L,
    /// N/s, thrust_max battery_sag / duration: how fast the upper clamp falls.
    sag_rate: L,
    /// s, when each rotor's fault starts (infinite: none), and the fraction it then gives.
    fault_start: [L; 4],
    fault_fraction: [L; 4],
    /// Whether any lane's battery sags, whether any lane has a fault (else the command is
    /// computed exactly as without them).
    sags: bool,
    faulty: bool,
    /// m, rotor i's hub (x, y) in body axes: l (cos a_i, sin a_i); and the hubs' sums the
    /// aerodynamic wrench reads (`aero::HubSums`).
    hubs: [[L; 2]; 4],
    hub_sums: HubSums<L>,
    /// Rotor aerodynamics (`aero::Coefficients`), and whether any lane has a term of them
    /// (else `aero` is None: no arithmetic).
    aero: Coefficients<L>,
    aerodynamic: bool,
}

/// What the rotors are told at the start of a step and hold over its four RK4 stages.
#[derive(Clone, Copy, Debug)]
pub struct RotorCommand<L> {
    /// N, each rotor's thrust from M^-1 (U1, tau), before the clamp.
    pub wanted: [L; 4],
    /// N, the same clamped to [thrust_min, limit], times a failed rotor's fraction.
    pub thrust: [L; 4],
    /// rad/s, w_cmd = sqrt(thrust / kf).
    pub speed: [L; 4],
    /// N, the step's upper clamp: thrust_max less the battery's sag so far.
    pub limit: L,
}

/// The rotor speed states.
pub const ROTOR_VARS: [StateVar; 4] = [
    StateVar::new("omega_1", Axis::Other, None, Part::Actuator),
    StateVar::new("omega_2", Axis::Other, None, Part::Actuator),
    StateVar::new("omega_3", Axis::Other, None, Part::Actuator),
    StateVar::new("omega_4", Axis::Other, None, Part::Actuator),
];

impl OwnsKeys for Rotors {
    type Params = RotorParams;

    fn validate(p: &RotorParams, flown: bool, cfg: &ModelContext) -> Result<(), ConfigError> {
        p.validate(flown, cfg)
    }

    fn keys(prefix: &str) -> Vec<(String, crate::config::params::Key)> {
        RotorParams::keys(prefix)
    }
}

impl Actuator for Rotors {
    type At<L: Lane> = Rotors<L>;
    const VARS: &'static [StateVar] = &ROTOR_VARS;

    fn new(a: &RotorParams, cfg: &ModelContext) -> Self {
        let m = allocation(a.layout, cfg.vehicle.arm_length, a.torque_ratio);
        // `Config::validate` refuses l = 0 or cq = 0 with rotors; were M singular anyway, the
        // flight would end non-finite at once rather than panic.
        let inverse = allocation_inverse(&m).unwrap_or([[f64::NAN; 4]; 4]);
        let weight = (cfg.vehicle.mass + cfg.payload.mass) * cfg.environment.gravity;
        let arm = cfg.vehicle.arm_length;
        let hubs = arm_directions(a.layout).map(|[c, s]| [arm * c, arm * s]);
        let aero = Coefficients::new(a.rotor_drag, a.flapping, a.translational_lift);
        let mut fault_start = [f64::INFINITY; 4];
        let mut fault_fraction = [1.0; 4];
        for f in &a.faults {
            // Validated: rotors 1 to 4, one fault each.
            let i = f.rotor as usize - 1;
            fault_start[i] = f.start;
            fault_fraction[i] = f.thrust_fraction;
        }
        Self {
            allocation: m,
            inverse,
            kf: a.thrust_coefficient,
            thrust_min: a.thrust_min,
            thrust_max: a.thrust_max,
            hover_speed: (weight / (4.0 * a.thrust_coefficient)).sqrt(),
            inv_kf: 1.0 / a.thrust_coefficient,
            inv_tau: 1.0 / a.time_constant,
            sag_rate: a.thrust_max * a.battery_sag / cfg.integrator.duration,
            fault_start,
            fault_fraction,
            sags: a.battery_sag != 0.0,
            faulty: !a.faults.is_empty(),
            hubs,
            hub_sums: HubSums::of(&hubs),
            aero,
            aerodynamic: aero.any(),
        }
    }

    fn gather<L: Lane>(each: &[&Self]) -> Rotors<L> {
        gather!(|l| each[l] => Rotors {
            allocation, inverse, kf, thrust_min, thrust_max, hover_speed, inv_kf, inv_tau,
            sag_rate, fault_start, fault_fraction, hubs, hub_sums, aero;
            sags: each.iter().any(|r| r.sags),
            faulty: each.iter().any(|r| r.faulty),
            aerodynamic: each.iter().any(|r| r.aerodynamic),
        })
    }
}

impl<L: Lane> Rotors<L> {
    /// N, each rotor's thrust kf w_i^2 at the speeds `s[at..at + 4]`.
    #[inline(always)]
    pub fn thrusts<const N: usize>(&self, s: &State<L, N>, at: usize) -> [L; 4] {
        state_from_fn(
            #[inline(always)]
            |i| s[at + i] * s[at + i] * self.kf,
        )
    }

    /// M t: the total thrust and torques of rotor thrusts `t`.
    #[inline(always)]
    pub fn allocate(&self, t: &[L; 4]) -> Inputs<L> {
        let m = &self.allocation;
        #[inline(always)]
        fn dot<L: Lane>(row: &[L; 4], t: &[L; 4]) -> L {
            row[0] * t[0] + row[1] * t[1] + row[2] * t[2] + row[3] * t[3]
        }
        Inputs {
            u1: dot(&m[0], t),
            tau: [dot(&m[1], t), dot(&m[2], t), dot(&m[3], t)],
        }
    }
}

impl<L: Lane> Rotors<L> {
    /// Each failed rotor's thrust at time `t` (s): times its fraction in the lanes where its
    /// fault has started.
    #[inline(always)]
    fn fail(&self, thrust: &mut [L; 4], t: f64) {
        let now = L::splat(t);
        for (i, thrust) in thrust.iter_mut().enumerate() {
            let started = self.fault_start[i].le_mask(now);
            if started == L::ALL {
                *thrust = *thrust * self.fault_fraction[i];
            } else if started != 0 {
                let f = self.fault_fraction[i];
                *thrust = *thrust
                    * L::from_fn(|l| {
                        if started & (1 << l) != 0 {
                            f.lane(l)
                        } else {
                            1.0
                        }
                    });
            }
        }
    }
}

impl<L: Lane> ActuatorModel<L> for Rotors<L> {
    const STATES: usize = 4;
    type Command = RotorCommand<L>;
    /// The actual thrusts kf w_i^2 (N), and whether the step's command was clamped (0 or 1).
    const SIGNALS: &'static [&'static str] =
        &["thrust_1", "thrust_2", "thrust_3", "thrust_4", "saturated"];

    /// RotorPy's rotor aerodynamics (`aero::wrench`: the H-force, translational lift and
    /// blade flapping of each rotor in its local air, summed in closed form).
    #[inline(always)]
    fn aero<const N: usize>(
        &self,
        s: &State<L, N>,
        at: usize,
        air: &[L; 3],
        axes: &[[L; 3]; 3],
        rates: &[L; 3],
    ) -> Option<([L; 3], [L; 3])> {
        if !self.aerodynamic {
            return None;
        }
        // v_b = R^T air as the body's drag forms it (`Rotation::to_body`): the same operations
        // on the same values, which the compiler may then compute once for both.
        let dot = |a: &[L; 3]| a[0].mul_add(air[0], a[1].mul_add(air[1], a[2] * air[2]));
        let vb = [dot(&axes[0]), dot(&axes[1]), dot(&axes[2])];
        let w = [s[at], s[at + 1], s[at + 2], s[at + 3]];
        Some(aero::wrench(
            &self.aero,
            &w,
            &self.hubs,
            &self.hub_sums,
            &vb,
            rates,
        ))
    }

    #[inline(always)]
    fn command(&self, u: &Inputs<L>, at: Tick) -> RotorCommand<L> {
        let inv = &self.inverse;
        let wanted: [L; 4] = state_from_fn(
            #[inline(always)]
            |i| {
                inv[i][0] * u.u1
                    + inv[i][1] * u.tau[0]
                    + inv[i][2] * u.tau[1]
                    + inv[i][3] * u.tau[2]
            },
        );
        let limit = if self.sags {
            self.thrust_max - self.sag_rate * at.t
        } else {
            self.thrust_max
        };
        let mut thrust: [L; 4] = state_from_fn(
            #[inline(always)]
            |i| wanted[i].clamp(self.thrust_min, limit),
        );
        if self.faulty {
            self.fail(&mut thrust, at.t);
        }
        let speed = state_from_fn(
            #[inline(always)]
            |i| (thrust[i] * self.inv_kf).sqrt(),
        );
        RotorCommand {
            wanted,
            thrust,
            speed,
            limit,
        }
    }

    #[inline(always)]
    fn inputs<const N: usize>(
        &self,
        _cmd: &RotorCommand<L>,
        s: &State<L, N>,
        at: usize,
    ) -> Inputs<L> {
        self.allocate(&self.thrusts(s, at))
    }

    #[inline(always)]
    fn derivative<const N: usize>(
        &self,
        cmd: &RotorCommand<L>,
        s: &State<L, N>,
        at: usize,
        ds: &mut State<L, N>,
    ) {
        for i in 0..4 {
            ds[at + i] = (cmd.speed[i] - s[at + i]) * self.inv_tau;
        }
    }

    fn rest<const N: usize>(&self, s: &mut State<L, N>, at: usize) {
        for i in 0..4 {
            s[at + i] = self.hover_speed;
        }
    }

    #[inline(always)]
    fn signals<const N: usize>(
        &self,
        cmd: &RotorCommand<L>,
        s: &State<L, N>,
        at: usize,
        out: &mut [L],
    ) {
        out[..4].copy_from_slice(&self.thrusts(s, at));
        out[4] = self.saturated(cmd);
    }

    /// 1 where any rotor's wanted thrust lay outside [thrust_min, the step's limit] (or was
    /// NaN).
    #[inline(always)]
    fn saturated(&self, cmd: &RotorCommand<L>) -> L {
        let mut inside = L::ALL;
        for i in 0..4 {
            inside &= cmd.wanted[i].le_mask(cmd.limit) & self.thrust_min.le_mask(cmd.wanted[i]);
        }
        if inside == L::ALL {
            return L::splat(0.0);
        }
        L::from_fn(|l| if inside & (1 << l) != 0 { 0.0 } else { 1.0 })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::payload::Spring;
    use crate::model::ActuatorKind;
    use crate::model::{AnyVehicle, Trig, Vehicle};
    use crate::scenario::tests::paper;
    use crate::scenario::Config;

    const NX: usize = 18;
    const OMEGA: usize = 14;

    fn rotor_config() -> Config {
        let mut cfg = paper();
        cfg.actuator.model = ActuatorKind::Rotors;
        cfg.validate()
            .expect("the paper vehicle on its default rotors");
        cfg
    }

    fn vehicle(cfg: &Config) -> Vehicle<f64, Spring, Rotors> {
        AnyVehicle::new(&cfg.model_context()).vehicle::<Spring, Rotors>()
    }

    fn weight(cfg: &Config) -> f64 {
        (cfg.vehicle.mass + cfg.payload.mass) * cfg.environment.gravity
    }

    #[test]
    fn the_rotor_states_follow_the_payloads_velocities() {
        let names: Vec<&str> = crate::model::state_vars(
            Default::default(),
            crate::model::PayloadKind::Spring,
            crate::model::ActuatorKind::Rotors,
        )
        .iter()
        .map(|v| v.name)
        .collect();
        assert_eq!(names.len(), NX);
        assert_eq!(names[OMEGA..], ["omega_1", "omega_2", "omega_3", "omega_4"]);
    }

    #[test]
    fn hover_is_an_equilibrium_with_rotors() {
        let cfg = rotor_config();
        let v = vehicle(&cfg);
        let s: State<f64, NX> = v.rest_state([1.0, -2.0, 2.0], [0.0, 0.0, 0.5]);
        let w0 = (weight(&cfg) / (4.0 * cfg.actuator.rotors.thrust_coefficient)).sqrt();
        for i in 0..4 {
            assert!((s[OMEGA + i] - w0).abs() < 1e-12 * w0);
        }
        let cmd = v.actuator.command(
            &Inputs {
                u1: weight(&cfg),
                tau: [0.0; 3],
            },
            Tick::START,
        );
        let ds = v.derivative(&s, &Trig::of(&s), &cmd, &[0.0; 3]);
        for (i, d) in ds.iter().enumerate() {
            assert!(d.abs() < 1e-9, "state {i}: {d}");
        }
    }

    /// At the commanded speeds (no clamp binding) the airframe feels exactly what the
    /// controller asked for, and the speeds stay put.
    #[test]
    fn rotors_at_their_commanded_speeds_deliver_the_controllers_inputs() {
        for layout in [RotorLayout::X, RotorLayout::Plus] {
            let mut cfg = rotor_config();
            cfg.actuator.rotors.layout = layout;
            let v = vehicle(&cfg);
            let u = Inputs {
                u1: 26.0,
                tau: [0.06, -0.04, 0.02],
            };
            let cmd = v.actuator.command(&u, Tick::START);
            assert_eq!(cmd.thrust.map(f64::to_bits), cmd.wanted.map(f64::to_bits));
            let mut s: State<f64, NX> = v.rest_state([0.0, 0.0, 2.0], [0.0; 3]);
            s[OMEGA..].copy_from_slice(&cmd.speed);
            let felt = v.actuator.inputs(&cmd, &s, OMEGA);
            assert!((felt.u1 - u.u1).abs() < 1e-13 * u.u1, "{layout:?}");
            for k in 0..3 {
                assert!(
                    (felt.tau[k] - u.tau[k]).abs() < 1e-14,
                    "{layout:?} tau[{k}]"
                );
            }
            let mut ds = [0.0; NX];
            v.actuator.derivative(&cmd, &s, OMEGA, &mut ds);
            assert!(ds[OMEGA..].iter().all(|d| *d == 0.0));
        }
    }

    #[test]
    fn a_command_past_the_limits_is_clamped_and_the_lag_is_first_order() {
        let mut cfg = rotor_config();
        cfg.actuator.rotors.thrust_min = 1.0;
        let v = vehicle(&cfg);
        let a = &cfg.actuator.rotors;
        // A hard roll: rotors 1, 2 (y > 0) asked for more than thrust_max, 3, 4 for less
        // than thrust_min.
        let cmd = v.actuator.command(
            &Inputs {
                u1: 30.0,
                tau: [4.0, 0.0, 0.0],
            },
            Tick::START,
        );
        let wanted = cmd.wanted;
        assert!(
            wanted[0] > a.thrust_max && wanted[1] > a.thrust_max,
            "{wanted:?}"
        );
        assert!(
            wanted[2] < a.thrust_min && wanted[3] < a.thrust_min,
            "{wanted:?}"
        );
        assert_eq!(
            cmd.thrust,
            [a.thrust_max, a.thrust_max, a.thrust_min, a.thrust_min]
        );
        for i in 0..4 {
            let want = (cmd.thrust[i] / a.thrust_coefficient).sqrt();
            assert!((cmd.speed[i] - want).abs() < 1e-12 * want);
        }
        assert_eq!(v.actuator.saturated(&cmd), 1.0);
        let hover = v.actuator.command(
            &Inputs {
                u1: weight(&cfg),
                tau: [0.0; 3],
            },
            Tick::START,
        );
        assert_eq!(v.actuator.saturated(&hover), 0.0);
        let mut s: State<f64, NX> = v.rest_state([0.0, 0.0, 2.0], [0.0; 3]);
        s[OMEGA..].copy_from_slice(&[500.0, 900.0, 1300.0, 700.0]);
        let mut out = [0.0; 5];
        v.actuator.signals(&cmd, &s, OMEGA, &mut out);
        assert_eq!(out[4], 1.0);
        for i in 0..4 {
            assert_eq!(out[i], a.thrust_coefficient * s[OMEGA + i] * s[OMEGA + i]);
        }
        let mut ds = [0.0; NX];
        v.actuator.derivative(&cmd, &s, OMEGA, &mut ds);
        for i in 0..4 {
            let want = (cmd.speed[i] - s[OMEGA + i]) / a.time_constant;
            assert!((ds[OMEGA + i] - want).abs() < 1e-12 * want.abs());
        }
    }

    fn fault(rotor: u32, start: f64, thrust_fraction: f64) -> RotorFault {
        RotorFault {
            rotor,
            start,
            thrust_fraction,
        }
    }

    /// Before its start a fault changes nothing (bit for bit); from it on the failed rotor is
    /// told its fraction of the clamped command, the others what they were told.
    #[test]
    fn a_failed_rotor_gives_its_fraction_of_the_command_from_its_start() {
        let healthy = rotor_config();
        let mut cfg = rotor_config();
        cfg.actuator.rotors.faults = vec![fault(3, 2.0, 0.8)];
        cfg.validate().expect("a weak motor can still hover");
        let (v0, v) = (vehicle(&healthy), vehicle(&cfg));
        let u = Inputs {
            u1: 30.0,
            tau: [0.3, -0.2, 0.01],
        };
        for (t, failed) in [(0.0, false), (1.999, false), (2.0, true), (9.0, true)] {
            let tick = Tick { step: 0, t };
            let (a, b) = (v0.actuator.command(&u, tick), v.actuator.command(&u, tick));
            assert_eq!(a.wanted.map(f64::to_bits), b.wanted.map(f64::to_bits));
            for i in 0..4 {
                let want = if failed && i == 2 {
                    a.thrust[i] * 0.8
                } else {
                    a.thrust[i]
                };
                assert_eq!(b.thrust[i].to_bits(), want.to_bits(), "t {t} rotor {i}");
                let speed = (want / cfg.actuator.rotors.thrust_coefficient).sqrt();
                assert!((b.speed[i] - speed).abs() <= 1e-12 * speed);
            }
        }
        // Stuck off: no thrust, no speed.
        cfg.actuator.rotors.faults = vec![fault(1, 0.0, 0.0)];
        let cmd = vehicle(&cfg).actuator.command(&u, Tick::START);
        assert_eq!((cmd.thrust[0], cmd.speed[0]), (0.0, 0.0));
    }

    /// Lanes with and without the fault (a dispersed start) agree lane by lane with the scalar
    /// vehicles.
    #[test]
    fn faults_per_lane_are_the_scalar_faults() {
        use crate::lane::F64x4;
        let mut cfgs = Vec::new();
        for start in [0.0, 1.0, 5.0, f64::INFINITY] {
            let mut c = rotor_config();
            if start.is_finite() {
                c.actuator.rotors.faults = vec![fault(2, start, 0.5)];
            }
            cfgs.push(c);
        }
        let parts: Vec<AnyVehicle> = cfgs
            .iter()
            .map(|c| AnyVehicle::new(&c.model_context()))
            .collect();
        let each: Vec<&Rotors> = parts.iter().map(|p| Rotors::of(&p.actuator)).collect();
        let lanes: Rotors<F64x4> = Rotors::gather(&each);
        let u = Inputs {
            u1: F64x4::splat(28.0),
            tau: [F64x4::splat(0.1), F64x4::splat(0.05), F64x4::splat(-0.01)],
        };
        for t in [0.0, 0.5, 1.0, 4.0, 6.0] {
            let tick = Tick { step: 0, t };
            let got = lanes.command(&u, tick);
            for (l, r) in each.iter().enumerate() {
                let one = Inputs {
                    u1: 28.0,
                    tau: [0.1, 0.05, -0.01],
                };
                let want = r.command(&one, tick);
                for i in 0..4 {
                    assert_eq!(got.thrust[i].lane(l).to_bits(), want.thrust[i].to_bits());
                }
            }
        }
    }

    /// The battery's sag lowers the upper clamp linearly to (1 - sag) thrust_max at the end of
    /// the flight; a command above it is clamped there and counts as saturated.
    #[test]
    fn the_battery_sag_lowers_the_clamp_linearly() {
        let mut cfg = rotor_config();
        cfg.actuator.rotors.battery_sag = 0.25;
        cfg.validate().expect("a 25 % sag still hovers");
        let v = vehicle(&cfg);
        let (top, end) = (cfg.actuator.rotors.thrust_max, cfg.integrator.duration);
        let hard = Inputs {
            u1: 4.0 * top,
            tau: [0.0; 3],
        };
        for t in [0.0, 0.3 * end, end] {
            let cmd = v.actuator.command(&hard, Tick { step: 0, t });
            let limit = top * (1.0 - 0.25 * t / end);
            assert!((cmd.limit - limit).abs() < 1e-12 * top, "t {t}");
            for i in 0..4 {
                assert_eq!(cmd.thrust[i], cmd.limit);
            }
            let cap = cmd.limit;
            let just_under = v.actuator.command(
                &Inputs {
                    u1: 3.99 * cap,
                    tau: [0.0; 3],
                },
                Tick { step: 0, t },
            );
            assert_eq!(v.actuator.saturated(&just_under), 0.0, "t {t}");
            assert_eq!(v.actuator.saturated(&cmd), if t == 0.0 { 0.0 } else { 1.0 });
        }
    }

    /// The linearisation sees the rotor states: the lag's diagonal is -1 / tau, the four
    /// extra poles are labelled "actuator", and as tau -> 0 the other poles tend to the
    /// ideal actuator's.
    #[test]
    fn stability_sees_the_rotor_states() {
        use crate::control::ControllerKind;
        use crate::stability::{analyse, MODE_ACTUATOR};
        let ideal = analyse(&paper(), ControllerKind::Pd);
        let mut far = f64::NAN;
        for (tau, tol) in [(0.03, f64::INFINITY), (1e-3, 0.05), (1e-4, 0.005)] {
            let mut cfg = rotor_config();
            cfg.actuator.rotors.time_constant = tau;
            cfg.integrator.dt = tau.min(cfg.integrator.dt);
            let a = analyse(&cfg, ControllerKind::Pd);
            assert!(a.residual < 1e-9, "hover is an equilibrium: {}", a.residual);
            assert_eq!(a.poles.len(), NX);
            for i in OMEGA..NX {
                let d = a.jacobian[(i, i)];
                assert!((d + 1.0 / tau).abs() < 1e-9 / tau, "d omega'/d omega = {d}");
            }
            let fast: Vec<_> = a.poles.iter().filter(|p| p.mode == MODE_ACTUATOR).collect();
            assert_eq!(fast.len(), 4, "{:?}", a.poles);
            assert!(fast.iter().all(|p| p.re < -0.5 / tau), "{fast:?}");
            // Each of the ideal vehicle's poles has a rotor pole next to it.
            let slow: Vec<_> = a.poles.iter().filter(|p| p.mode != MODE_ACTUATOR).collect();
            let mut worst: f64 = 0.0;
            for p in &ideal.poles {
                let nearest = slow
                    .iter()
                    .map(|q| (q.re - p.re).hypot(q.im - p.im))
                    .fold(f64::INFINITY, f64::min);
                worst = worst.max(nearest);
            }
            assert!(worst < tol, "tau {tau}: a pole moved by {worst}");
            if tau == 0.03 {
                far = worst;
            } else {
                assert!(worst < far, "closer to ideal as tau shrinks");
            }
        }
    }

    #[test]
    fn the_allocation_inverse_is_the_inverse_for_both_layouts() {
        for layout in [RotorLayout::Plus, RotorLayout::X] {
            for (l, cq) in [(0.1725, 0.016), (0.3, 0.05), (0.05, 0.002)] {
                let m = allocation(layout, l, cq);
                let inv = allocation_inverse(&m).expect("M is invertible");
                for i in 0..4 {
                    for j in 0..4 {
                        let mi: f64 = (0..4).map(|k| m[i][k] * inv[k][j]).sum();
                        let im: f64 = (0..4).map(|k| inv[i][k] * m[k][j]).sum();
                        let id = if i == j { 1.0 } else { 0.0 };
                        assert!(
                            (mi - id).abs() < 1e-14,
                            "{layout:?} M M^-1 [{i}][{j}] = {mi}"
                        );
                        assert!(
                            (im - id).abs() < 1e-14,
                            "{layout:?} M^-1 M [{i}][{j}] = {im}"
                        );
                    }
                }
            }
        }
    }

    /// The rows from the rotor positions and spins, written out for each layout.
    #[test]
    fn the_allocation_is_the_rotor_geometry() {
        let (l, cq) = (0.2, 0.01);
        let m = allocation(RotorLayout::Plus, l, cq);
        assert_eq!(m[1], [0.0, l, 0.0, -l]);
        assert_eq!(m[2], [-l, 0.0, l, 0.0]);
        assert_eq!(m[3], [cq, -cq, cq, -cq]);
        let m = allocation(RotorLayout::X, l, cq);
        let h = l * 0.5f64.sqrt();
        for (got, want) in m[1].iter().zip([h, h, -h, -h]) {
            assert!((got - want).abs() < 1e-16);
        }
        for (got, want) in m[2].iter().zip([-h, h, h, -h]) {
            assert!((got - want).abs() < 1e-16);
        }
        // A rotor's roll and pitch arms are r x (0, 0, T): (y T, -x T).
        for layout in [RotorLayout::Plus, RotorLayout::X] {
            let m = allocation(layout, l, cq);
            let d = arm_directions(layout);
            for i in 0..4 {
                let angle = d[i][1].atan2(d[i][0]).to_degrees().rem_euclid(360.0);
                let first = if layout == RotorLayout::X { 45.0 } else { 0.0 };
                assert!((angle - (first + 90.0 * i as f64)).abs() < 1e-12);
                assert_eq!(m[1][i], l * d[i][1]);
                assert_eq!(m[2][i], -l * d[i][0]);
            }
        }
    }
}
