//! The plant (docs/model.md sections 1, 7, 8): a rigid quadrotor (`body`), a payload model
//! (`payload`: how the load hangs and pulls) and an actuator model (`actuator`: how the
//! controller's thrust and torques reach the airframe). Each family is one trait with one
//! dispatch point (`PayloadKind`, `ActuatorKind`); each kind is one file.
//!
//! The state vector is laid out once, here (`Layout`): the quadrotor's positions and angles,
//! the payload's positions, the quadrotor's velocities and rates, the payload's velocities,
//! then the actuator's states. For the vertical spring this is the paper's
//! `[x, y, z, phi, theta, psi, zc, vx, vy, vz, p, q, r, vzc]`. State names, trace columns,
//! stability outputs and divergence checks all derive from `Layout::vars`.

pub mod actuator;
pub mod body;
mod kinds;
pub mod layout;
pub mod payload;
pub mod section;
mod trim;

pub use actuator::{Actuator, ActuatorModel};
pub use body::{
    Body, BodyKind, BodyModel, Frame, Paper, Rigid as RigidBody, Rotation, TiltBound, BODY_MODELS,
};
pub use kinds::{
    dispatch, ActuatorConfig, ActuatorKind, AnyActuator, AnyPayload, PayloadConfig, PayloadKind,
    ACTUATOR_KINDS, PAYLOAD_KINDS, RIGID_PAYLOADS,
};
pub use layout::{Axis, Bound, Layout, Part, StateVar};
pub use payload::{AtState, Payload, PayloadModel, PayloadOutputs, PayloadView};
pub use section::{ModelContext, OwnsKeys};

use crate::lane::{KernelOps, Lane};

/// The quadrotor's own states, first in every layout: positions and angles (6), and after the
/// payload's positions, velocities and rates (6).
pub mod ix {
    pub const X: usize = 0;
    pub const Y: usize = 1;
    pub const Z: usize = 2;
    pub const PHI: usize = 3;
    pub const THETA: usize = 4;
    pub const PSI: usize = 5;
    /// The payload's positions start here.
    pub const PAYLOAD: usize = 6;
}

/// Indices of the paper's layout (vertical spring, ideal actuators), for tests and examples,
/// derived from its `Layout`; the engine itself reads indices from `Layout`.
pub mod paper_ix {
    pub use super::ix::*;
    use super::Layout;
    const LAYOUT: Layout = Layout::new(1, 0);
    pub const ZC: usize = PAYLOAD;
    pub const VX: usize = LAYOUT.vel();
    pub const VY: usize = VX + 1;
    pub const VZ: usize = VX + 2;
    pub const P: usize = VX + 3;
    pub const Q: usize = VX + 4;
    pub const R: usize = VX + 5;
    pub const VZC: usize = LAYOUT.payload_vel();
    /// Number of states.
    pub const NX: usize = LAYOUT.len();
}

/// The paper's vehicle (vertical spring, ideal actuators) with `f64` parameters.
pub type PaperVehicle = Vehicle<f64, payload::Spring, actuator::Ideal>;

/// A state vector of `N` values (N from the models' `Layout`).
pub type State<L, const N: usize> = [L; N];

/// `[f(0), f(1), ..., f(N - 1)]`, always inlined (`std::array::from_fn` is not guaranteed to
/// be, and an out-of-line copy would be compiled without the flight loop's target features:
/// see `lane/isa.rs`).
#[inline(always)]
pub fn state_from_fn<L: Copy, const N: usize>(mut f: impl FnMut(usize) -> L) -> [L; N] {
    let first = f(0);
    let mut out = [first; N];
    let mut i = 1;
    while i < N {
        out[i] = f(i);
        i += 1;
    }
    out
}

/// Where a flight is: step `step` of the flight loop, at time `t = step dt` (s). The controller
/// and the actuator receive it once per step, so a gain schedule or a scheduled fault is a
/// function of it inside one kind's file. The linearisation (`stability`) asks at `Tick::START`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Tick {
    pub step: usize,
    /// s.
    pub t: f64,
}

impl Tick {
    /// The start of a flight.
    pub const START: Tick = Tick { step: 0, t: 0.0 };
}

/// Total thrust and body torques, as the controller commands them or as the plant feels them.
#[derive(Clone, Copy, Debug)]
pub struct Inputs<L> {
    pub u1: L,
    pub tau: [L; 3],
}

/// The quadrotor's rigid-body state, as the controllers read it (a view of the state vector).
#[derive(Clone, Copy, Debug)]
pub struct Rigid<L> {
    pub pos: [L; 3],
    /// Roll, pitch, yaw (the rigid body's derived from its quaternion, yaw in (-pi, pi]).
    pub att: [L; 3],
    pub vel: [L; 3],
    /// The paper's body: Euler-angle rates p, q, r used as body rates; the rigid body: the
    /// true body rates wx, wy, wz.
    pub rate: [L; 3],
}

/// Sines and cosines of the Euler angles of one state: computed once per RK4 stage and shared
/// by the controller and the first stage of the step.
#[derive(Clone, Copy, Debug)]
pub struct Trig<L> {
    pub sphi: L,
    pub cphi: L,
    pub sth: L,
    pub cth: L,
    pub spsi: L,
    pub cpsi: L,
}

impl<L: Lane> Trig<L> {
    #[inline(always)]
    pub fn of<const N: usize>(s: &State<L, N>) -> Self {
        Self::of_angles(s[ix::PHI], s[ix::THETA], s[ix::PSI])
    }

    #[inline(always)]
    pub fn of_angles(phi: L, theta: L, psi: L) -> Self {
        Self::of_pairs(phi.sin_cos(), theta.sin_cos(), psi.sin_cos())
    }

    /// From the (sine, cosine) pairs of phi, theta and psi.
    #[inline(always)]
    fn of_pairs(phi: (L, L), theta: (L, L), psi: (L, L)) -> Self {
        Self {
            sphi: phi.0,
            cphi: phi.1,
            sth: theta.0,
            cth: theta.1,
            spsi: psi.0,
            cpsi: psi.1,
        }
    }
}

/// Turns of at most this (rad) within one RK4 stage take the angle-addition path of
/// `Trig::advanced`; its series are then exact to well below an ulp (the first omitted terms
/// are d^9/9! and d^10/10!, under 2e-18 relative at 0.03 rad).
pub const SMALL_TURN: f64 = 0.03;

/// (sin d, cos d) for |d| <= SMALL_TURN: Taylor series to d^7 and d^8.
#[inline(always)]
fn sin_cos_small<L: Lane>(d: L) -> (L, L) {
    let d2 = d * d;
    let s = d + d * d2 * ((d2 * (-1.0 / 5040.0) + 1.0 / 120.0) * d2 + (-1.0 / 6.0));
    let c = (((d2 * (1.0 / 40320.0) + (-1.0 / 720.0)) * d2 + 1.0 / 24.0) * d2 + (-0.5)) * d2 + 1.0;
    (s, c)
}

impl<L: KernelOps> Trig<L> {
    /// The sines and cosines at the angles `angle + k[angle] h` (an RK4 stage state `at`),
    /// from those at `angle` (`self`) by the angle-addition formulas: a few multiplications
    /// instead of three full sin/cos. A lane whose turn |k h| exceeds `SMALL_TURN` (never in
    /// the paper preset: that is 150 rad/s at dt = 2e-4 s) gets the full kernels at `at`
    /// instead; the choice is per lane, so a lane's numbers never depend on its neighbours.
    #[inline(always)]
    pub fn advanced<const N: usize>(&self, k: &State<L, N>, h: f64, at: &State<L, N>) -> Self {
        let small = L::splat(SMALL_TURN);
        #[inline(always)]
        fn turn<L: KernelOps>(s0: L, c0: L, d: L) -> (L, L) {
            let (sd, cd) = sin_cos_small(d);
            (s0 * cd + c0 * sd, c0 * cd - s0 * sd)
        }
        let (dphi, dth, dpsi) = (k[ix::PHI] * h, k[ix::THETA] * h, k[ix::PSI] * h);
        let t = Self::of_pairs(
            turn(self.sphi, self.cphi, dphi),
            turn(self.sth, self.cth, dth),
            turn(self.spsi, self.cpsi, dpsi),
        );
        let ok = dphi.abs().le_mask(small) & dth.abs().le_mask(small) & dpsi.abs().le_mask(small);
        if ok == L::ALL {
            return t;
        }
        let full = Self::of(at);
        let pick = |d: L, a: L, b: L| L::select(d.abs().cmp_le(small), a, b);
        Self {
            sphi: pick(dphi, t.sphi, full.sphi),
            cphi: pick(dphi, t.cphi, full.cphi),
            sth: pick(dth, t.sth, full.sth),
            cth: pick(dth, t.cth, full.cth),
            spsi: pick(dpsi, t.spsi, full.spsi),
            cpsi: pick(dpsi, t.cpsi, full.cpsi),
        }
    }
}

/// One vehicle: the quadrotor of body kind `B`, its payload and its actuators, with
/// parameters of type `L` (an `f64` for one vehicle, a lane type for one vehicle per lane,
/// dual numbers for the linearisation). `N` states in the order of `Vehicle::LAYOUT`.
#[derive(Clone, Debug)]
pub struct Vehicle<L, Pay, Act, B = Paper> {
    pub body: Body<L>,
    pub payload: Pay,
    pub actuator: Act,
    pub kind: std::marker::PhantomData<B>,
}

impl<L: Lane, Pay: PayloadModel<L>, Act: ActuatorModel<L>, B: BodyKind> Vehicle<L, Pay, Act, B> {
    /// Where each part's states sit in the state vector.
    pub const LAYOUT: Layout =
        Layout::with_attitude(<B::Frame<f64> as Frame<f64>>::ATT, Pay::DOF, Act::STATES);

    /// The quadrotor's rigid-body state within `s`.
    #[inline(always)]
    pub fn rigid<const N: usize>(s: &State<L, N>) -> Rigid<L> {
        Self::rigid_at(s, &B::frame(s))
    }

    /// The quadrotor's rigid-body state within `s`, whose attitude is `f`.
    #[inline(always)]
    pub fn rigid_at<const N: usize>(s: &State<L, N>, f: &B::Frame<L>) -> Rigid<L> {
        Self::rigid_with(s, B::euler(s, f))
    }

    /// The quadrotor's rigid-body state within `s`, whose Euler angles are `att`
    /// (`BodyKind::euler`, derived already).
    #[inline(always)]
    pub fn rigid_with<const N: usize>(s: &State<L, N>, att: [L; 3]) -> Rigid<L> {
        let v = Self::LAYOUT.vel();
        Rigid {
            pos: [s[ix::X], s[ix::Y], s[ix::Z]],
            att,
            vel: [s[v], s[v + 1], s[v + 2]],
            rate: [s[v + 3], s[v + 4], s[v + 5]],
        }
    }

    /// ds/dt with the actuator's command `cmd` and the wind `w` (m/s, inertial) held over the
    /// step; `trig` is `s`'s attitude (`BodyKind::frame`).
    #[inline(always)]
    pub fn derivative<const N: usize>(
        &self,
        s: &State<L, N>,
        trig: &B::Frame<L>,
        cmd: &Act::Command,
        w: &[L; 3],
    ) -> State<L, N> {
        self.derivative_with(
            s,
            trig,
            cmd,
            w,
            #[inline(always)]
            |p, at, ds| (p.accelerations(at, ds), ()),
        )
        .0
    }

    /// `derivative(s, trig, cmd, w)` and `payload_outputs(s, trig, u1, w)` together, bit for
    /// bit, sharing what the payload computes for both (`PayloadModel::accelerations_and_outputs`):
    /// the flight loop's record of a step and its RK4 step's first stage.
    #[inline(always)]
    pub fn derivative_and_outputs<const N: usize>(
        &self,
        s: &State<L, N>,
        trig: &B::Frame<L>,
        cmd: &Act::Command,
        w: &[L; 3],
        u1: L,
    ) -> (State<L, N>, PayloadOutputs<L>) {
        self.derivative_with(
            s,
            trig,
            cmd,
            w,
            #[inline(always)]
            |p, at, ds| p.accelerations_and_outputs(at, u1, ds),
        )
    }

    /// ds/dt, the payload's part by `payload` (the torque it applies, and anything else it
    /// returns), given the felt thrust; the actuator's aerodynamic wrench (`ActuatorModel::aero`,
    /// the rotors' on the rigid body) added to the quadrotor's.
    #[inline(always)]
    fn derivative_with<const N: usize, R>(
        &self,
        s: &State<L, N>,
        frame: &B::Frame<L>,
        cmd: &Act::Command,
        w: &[L; 3],
        payload: impl FnOnce(
            &Pay,
            &AtState<'_, L, B::Frame<L>, N>,
            &mut State<L, N>,
        ) -> (Option<[L; 3]>, R),
    ) -> (State<L, N>, R) {
        const { assert!(N == Self::LAYOUT.len()) };
        let lay = Self::LAYOUT;
        let u = self.actuator.inputs(cmd, s, lay.actuator());
        let mut ds = [s[0]; N];
        // Kinematics: positions move with the velocities, the attitude with the rates.
        let (v, pv, pp) = (lay.vel(), lay.payload_vel(), lay.payload());
        ds[..3].copy_from_slice(&s[v..v + 3]);
        B::attitude_rates(s, lay, &mut ds);
        ds[pp..pp + Pay::DOF].copy_from_slice(&s[pv..pv + Pay::DOF]);
        let (torque, out) = payload(&self.payload, &self.payload_at(s, frame, u.u1, w), &mut ds);
        let rates = [s[v + 3], s[v + 4], s[v + 5]];
        let mut tau = u.tau;
        let air = [s[v] - w[0], s[v + 1] - w[1], s[v + 2] - w[2]];
        let axes = frame.axes();
        if let Some((f, m)) = self.actuator.aero(s, lay.actuator(), &air, &axes, &rates) {
            for i in 0..3 {
                let fi = axes[0][i] * f[0] + axes[1][i] * f[1] + axes[2][i] * f[2];
                ds[v + i] += fi * self.body.inv_m;
                tau[i] += m[i];
            }
        }
        let rdot = self.body.rotation(&rates, &tau, &torque);
        ds[v + 3..v + 6].copy_from_slice(&rdot);
        self.actuator.derivative(cmd, s, lay.actuator(), &mut ds);
        (ds, out)
    }

    /// What a law sees of the payload at state `s` (`PayloadModel::view`), where it reads it
    /// (`reads`); None, and nothing computed, where it does not.
    #[inline(always)]
    pub fn payload_view_if<const N: usize>(
        &self,
        reads: bool,
        s: &State<L, N>,
        trig: &B::Frame<L>,
    ) -> Option<PayloadView<L>> {
        // A match, not `bool::then`: nothing here may be left out of line.
        match reads {
            true => Some(self.payload.view(s, trig)),
            false => None,
        }
    }

    /// What the payload's dynamics read (`AtState`): this vehicle's body at `s`, whose attitude
    /// is `frame`, under the total thrust `u1` in the wind `w`.
    #[inline(always)]
    fn payload_at<'a, const N: usize>(
        &'a self,
        s: &'a State<L, N>,
        frame: &'a B::Frame<L>,
        u1: L,
        w: &'a [L; 3],
    ) -> AtState<'a, L, B::Frame<L>, N> {
        AtState {
            body: &self.body,
            s,
            frame,
            u1,
            w,
        }
    }

    /// Everything the flight loop records about the payload at `s` in wind `w`.
    #[inline(always)]
    pub fn payload_outputs<const N: usize>(
        &self,
        s: &State<L, N>,
        trig: &B::Frame<L>,
        u1: L,
        w: &[L; 3],
    ) -> PayloadOutputs<L> {
        self.payload.outputs(&self.payload_at(s, trig, u1, w))
    }
}

impl<Pay: PayloadModel<f64>, Act: ActuatorModel<f64>, B: BodyKind> Vehicle<f64, Pay, Act, B> {
    /// A state at rest at `position` and `attitude` (roll, pitch, yaw), payload and actuators
    /// at their hover equilibria.
    pub fn rest_state<const N: usize>(
        &self,
        position: [f64; 3],
        attitude: [f64; 3],
    ) -> State<f64, N> {
        let mut s = [0.0; N];
        s[..3].copy_from_slice(&position);
        B::set_attitude(&mut s, attitude);
        let lay = Self::LAYOUT;
        self.payload.rest(&self.body, &B::frame(&s), &mut s);
        self.actuator.rest(&mut s, lay.actuator());
        s
    }
}

/// Work to do on a vehicle whose body, payload and actuator kinds are known at compile time:
/// the flight loop, the linearisation, the state names. `N` is the number of states.
pub trait VehicleVisitor {
    type Output;
    fn visit<B: BodyKind, Pay: Payload, Act: Actuator, const N: usize>(self) -> Self::Output;
}

/// The number of states of a vehicle with kinds `B`, `Pay`, `Act` (`Layout::len`).
pub const fn state_count<B: BodyKind, Pay: Payload, Act: Actuator>() -> usize {
    Layout::with_attitude(
        <B::Frame<f64> as Frame<f64>>::ATT,
        Pay::POSITIONS.len(),
        Act::VARS.len(),
    )
    .len()
}

/// m, how far a validated scenario's payload hangs below the centre of gravity at hover.
pub fn hover_drop(cfg: &ModelContext) -> f64 {
    struct Drop<'a>(&'a AnyPayload);
    impl VehicleVisitor for Drop<'_> {
        type Output = f64;
        fn visit<B: BodyKind, Pay: Payload, Act: Actuator, const N: usize>(self) -> f64 {
            Pay::of(self.0).hover_drop()
        }
    }
    dispatch(
        cfg.vehicle.body,
        cfg.payload.model,
        cfg.actuator.model,
        Drop(&AnyPayload::new(cfg)),
    )
}

/// Every state of a vehicle with these kinds, in order.
pub fn state_vars(body: BodyModel, payload: PayloadKind, actuator: ActuatorKind) -> Vec<StateVar> {
    struct Vars;
    impl VehicleVisitor for Vars {
        type Output = Vec<StateVar>;
        fn visit<B: BodyKind, Pay: Payload, Act: Actuator, const N: usize>(self) -> Vec<StateVar> {
            let vars = state_vars_of::<B, Pay, Act>();
            assert_eq!(vars.len(), N, "model::dispatch gives the wrong state count");
            vars
        }
    }
    dispatch(body, payload, actuator, Vars)
}

/// Every state of a vehicle with kinds `B`, `Pay`, `Act`, in order.
pub fn state_vars_of<B: BodyKind, Pay: Payload, Act: Actuator>() -> Vec<StateVar> {
    let lay = B::layout(Pay::POSITIONS.len(), Act::VARS.len());
    lay.vars(
        (B::POSITIONS, B::VELOCITIES),
        Pay::POSITIONS,
        Pay::VELOCITIES,
        Act::VARS,
    )
}

/// One vehicle's parameters, all kinds, resolved once from a validated scenario: what may
/// differ between the realisations of a dispersed batch.
#[derive(Clone, Debug)]
pub struct AnyVehicle {
    pub body: Body,
    pub payload: AnyPayload,
    pub actuator: AnyActuator,
}

impl AnyVehicle {
    pub fn new(cfg: &ModelContext) -> Self {
        Self {
            body: Body::new(cfg),
            payload: AnyPayload::new(cfg),
            actuator: AnyActuator::new(cfg),
        }
    }

    /// The vehicle with kinds `B`, `Pay`, `Act`, one per lane of `L` (`each[l]` in lane `l`).
    pub fn gather_on<L: Lane, B: BodyKind, Pay: Payload, Act: Actuator>(
        each: &[&AnyVehicle],
    ) -> Vehicle<L, Pay::At<L>, Act::At<L>, B> {
        let bodies: Vec<&Body> = each.iter().map(|p| &p.body).collect();
        let payloads: Vec<&Pay> = each.iter().map(|p| Pay::of(&p.payload)).collect();
        let actuators: Vec<&Act> = each.iter().map(|p| Act::of(&p.actuator)).collect();
        Vehicle {
            body: Body::gather(&bodies),
            payload: Pay::gather(&payloads),
            actuator: Act::gather(&actuators),
            kind: std::marker::PhantomData,
        }
    }

    /// The paper's body with kinds `Pay`, `Act`, one per lane of `L`.
    pub fn gather<L: Lane, Pay: Payload, Act: Actuator>(
        each: &[&AnyVehicle],
    ) -> Vehicle<L, Pay::At<L>, Act::At<L>> {
        Self::gather_on::<L, Paper, Pay, Act>(each)
    }

    /// This one vehicle on body `B` (`f64` parameters).
    pub fn vehicle_on<B: BodyKind, Pay: Payload, Act: Actuator>(
        &self,
    ) -> Vehicle<f64, Pay::At<f64>, Act::At<f64>, B> {
        Self::gather_on::<f64, B, Pay, Act>(&[self])
    }

    /// This one vehicle on the paper's body (`f64` parameters).
    pub fn vehicle<Pay: Payload, Act: Actuator>(&self) -> Vehicle<f64, Pay::At<f64>, Act::At<f64>> {
        self.vehicle_on::<Paper, Pay, Act>()
    }
}

#[cfg(test)]
pub(crate) mod tests;
