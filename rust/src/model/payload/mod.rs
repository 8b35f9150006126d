//! Payload models (`payload.model`, docs/model.md sections 1 and 7): how the load hangs below
//! the quadrotor, moves and pulls on it. Each kind is one file implementing two traits:
//! `Payload` (its parameters, built once from the scenario and gathered one vehicle per lane)
//! and `PayloadModel` (its dynamics and outputs, with parameters of any lane type). Its own
//! keys in `[payload]` are declared in its file (`OwnsKeys::Params`, with `config::params!`) and
//! checked there (`OwnsKeys::validate`). To add a kind: a file beside `spring.rs`, its `mod`
//! line here and its line in the registration `model::kinds!` (which generates its name in
//! `PayloadKind`, its table in `PayloadConfig`, `AnyPayload` and every `model::dispatch`
//! line; docs/architecture.md).

mod cable;
mod release;
pub mod shared;
mod spring;

pub use cable::{Cable, CableParams, Line, Release};
pub use shared::{Shared, ATTACHMENT};
pub use spring::{Spring, SpringParams};

use super::body::{Body, Frame};
use super::layout::StateVar;
use super::State;
use crate::model::section::OwnsKeys;
use crate::model::ModelContext;

pub use super::{AnyPayload, PayloadConfig, PayloadKind};
use crate::lane::Lane;

/// What the flight loop records about the payload at one instant.
#[derive(Clone, Copy, Debug)]
pub struct PayloadOutputs<L> {
    /// m, the vertical relative oscillation: the payload's height relative to its attachment,
    /// minus that at hover (0 at hover; the paper's e_o).
    pub e_o: L,
    /// m/s^2, the payload's inertial acceleration (x, y, z; 0 at hover).
    pub accel: [L; 3],
    /// N, the force the attachment carries (the spring force Fs, or the cable tension).
    pub tension: L,
    /// rad, the attachment's angle from the vertical (0 for the vertical spring).
    pub swing: L,
}

/// What a control law may see of the payload at one instant (`PayloadModel::view`,
/// `control::Control::step_seeing`): the parcel relative to where it hangs from the vehicle
/// (its attachment: the cable's hook, the spring's end at the centre of gravity), in inertial
/// axes. Zero for a payload that moves with the vehicle, and once the parcel has left it.
#[derive(Clone, Copy, Debug)]
pub struct PayloadView<L> {
    /// m, the parcel's position minus its attachment's.
    pub pos: [L; 3],
    /// m/s, the parcel's velocity minus its attachment's.
    pub vel: [L; 3],
}

impl<L: Lane> PayloadView<L> {
    /// Nothing to see: the parcel at its attachment, moving with it.
    #[inline(always)]
    pub fn none() -> Self {
        let zero = L::splat(0.0);
        Self {
            pos: [zero; 3],
            vel: [zero; 3],
        }
    }
}

/// m, how close (horizontally) the vehicle must be to a lowering's point, as it knows its
/// position, for the winch to start paying out: PX4's acceptance radius `NAV_ACC_RAD` (its
/// default), within which a mission's waypoint is reached and its winch item runs. A late
/// vehicle lowers at the point, not on the way to it; one held off it by a steady wind (the
/// delivery preset's PD, about 2.5 m downwind) still lowers.
pub const LOWER_RADIUS: f64 = 10.0;

/// What the route and the vehicle tell the payload at one step (`PayloadModel::last_metres`).
#[derive(Clone, Copy, Debug)]
pub struct Cue<L> {
    /// s, the step's time, and the step.
    pub t: f64,
    pub dt: f64,
    /// The lowering due (`trajectory.lower`: from the lowering's scheduled start to the end of
    /// its point's hold): the line it pays out beyond the reeled-in length and its speed, else
    /// None (the winch keeps its target).
    pub payout: Option<crate::legs::Lowering>,
    /// m^2, the vehicle's horizontal distance from the lowering's point, as it knows its
    /// position, squared, less LOWER_RADIUS squared: the winch starts a lowering due only
    /// where it is at most 0 (over the point), never on the time alone.
    pub off_drop: L,
    /// m, the vehicle's height as it knows it (its estimate; the state's under
    /// `navigation.mode = "truth"`): the winch's final approach reads it.
    pub height: L,
    /// A standard normal per lane for the load cell's noise on the measured tension (its own
    /// seeded stream: `integrate::steps::TensionNoise`; 0 without the noise).
    pub draw: L,
}

/// The last metres at one step (lane values: 1 or 0 for the events), for the metrics.
#[derive(Clone, Copy, Debug)]
pub struct LastMetres<L> {
    /// 1 at the step of the parcel's first contact with the ground, else 0; 1 while it is in
    /// contact, else 0.
    pub touchdown: L,
    pub contact: L,
    /// 1 at the step the hook opens, else 0.
    pub release: L,
    /// 1 while the parcel hangs on the hook, 0 once released; 1 once it has touched down.
    pub hooked: L,
    pub grounded: L,
    /// m and m/s, the parcel's inertial position and velocity.
    pub pos: [L; 3],
    pub vel: [L; 3],
    /// m and m/s, its position and velocity at the instant it met the ground, located inside
    /// the step that crossed it (at the touchdown's step; elsewhere `pos` and `vel`).
    pub contact_pos: [L; 3],
    pub contact_vel: [L; 3],
}

/// Where a payload's dynamics are evaluated: the quadrotor's `body`, the state `s` and its
/// attitude `frame` (its axes, its own drag, and where the states sit: `Frame::layout`), the
/// total thrust `u1` and the wind `w` (m/s, inertial). What every payload model reads, passed
/// as one.
pub struct AtState<'a, L, F, const N: usize> {
    pub body: &'a Body<L>,
    pub s: &'a State<L, N>,
    pub frame: &'a F,
    pub u1: L,
    pub w: &'a [L; 3],
}

// By hand: a derive would ask `F: Copy`, and only the references are copied.
impl<L: Copy, F, const N: usize> Clone for AtState<'_, L, F, N> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<L: Copy, F, const N: usize> Copy for AtState<'_, L, F, N> {}

/// A payload's dynamics, with parameters of lane type `L`.
pub trait PayloadModel<L: Lane>: Sync {
    /// Degrees of freedom: the payload has this many positions (after the quadrotor's angles)
    /// and as many velocities (after the quadrotor's rates).
    const DOF: usize;

    /// Write the quadrotor's translational accelerations (`ds[vx..vx + 3]`) and the payload's
    /// (`ds[payload_vel..]`) at `at` (`AtState`: the state, its attitude, the total thrust and
    /// the wind); return the torque the payload applies to the quadrotor (body axes), if it
    /// applies one.
    fn accelerations<F: Frame<L>, const N: usize>(
        &self,
        at: &AtState<'_, L, F, N>,
        ds: &mut State<L, N>,
    ) -> Option<[L; 3]>;

    /// What the loop records (`PayloadOutputs`) at `at`.
    fn outputs<F: Frame<L>, const N: usize>(&self, at: &AtState<'_, L, F, N>) -> PayloadOutputs<L>;

    /// `accelerations(at, ds)` and `outputs` at `at` with the thrust `u1_out`, together, bit
    /// for bit: a model whose outputs repeat work of its accelerations at the same state (the
    /// cable's line) computes it once. The flight loop records the outputs at the state its
    /// RK4 step starts from, so the first stage's derivative shares them.
    #[inline(always)]
    fn accelerations_and_outputs<F: Frame<L>, const N: usize>(
        &self,
        at: &AtState<'_, L, F, N>,
        u1_out: L,
        ds: &mut State<L, N>,
    ) -> (Option<[L; 3]>, PayloadOutputs<L>) {
        let torque = self.accelerations(at, ds);
        (torque, self.outputs(&AtState { u1: u1_out, ..*at }))
    }

    /// What a control law sees of the payload at `s` (`frame` its attitude): `PayloadView`.
    /// Computed only for a law that asks for it (`Control::SEES_PAYLOAD`); by default,
    /// nothing (a payload that moves with the vehicle).
    #[inline(always)]
    fn view<F: Frame<L>, const N: usize>(&self, _s: &State<L, N>, _frame: &F) -> PayloadView<L> {
        PayloadView::none()
    }

    /// Put the payload at its hover equilibrium below the quadrotor of `s` (at rest), whose
    /// attitude is `frame`.
    fn rest<F: Frame<L>, const N: usize>(&self, body: &Body<L>, frame: &F, s: &mut State<L, N>);

    /// The last metres (docs/model.md): once per step, before it, at `s` (`frame` its attitude),
    /// the payload takes the route's `cue` (a winch's target), updates its events (first
    /// touchdown, the hook opening) and returns them; None for a payload that never meets
    /// the ground nor leaves the hook (then the flight loop records none).
    #[inline(always)]
    fn last_metres<F: Frame<L>, const N: usize>(
        &mut self,
        _s: &State<L, N>,
        _frame: &F,
        _cue: &Cue<L>,
    ) -> Option<LastMetres<L>> {
        None
    }
}

/// A payload kind's parameters for one vehicle, resolved once from the scenario.
pub trait Payload: OwnsKeys + Clone + Sync + Send + Sized + 'static {
    /// The same parameters, one vehicle per lane of `L`.
    type At<L: Lane>: PayloadModel<L>;
    /// The kind's states: positions, then velocities (`DOF` each).
    const POSITIONS: &'static [StateVar];
    const VELOCITIES: &'static [StateVar];
    /// The parameters of a validated scenario (`p`: the kind's keys).
    fn new(p: &<Self as OwnsKeys>::Params, cfg: &ModelContext) -> Self;
    /// One vehicle per lane: lane `l` of every parameter is `each[l]`'s.
    fn gather<L: Lane>(each: &[&Self]) -> Self::At<L>;
    /// This kind's parameters inside the combined enum (`model::dispatch` matched the kind).
    fn of(any: &AnyPayload) -> &Self {
        any.get::<Self>()
    }
    /// m, how far the payload hangs below the centre of gravity at hover.
    fn hover_drop(&self) -> f64;
}
