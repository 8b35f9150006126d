//! Actuator models (`actuator.model`, docs/model.md sections 2 and 8): how the controller's
//! total thrust and torques reach the airframe. Each kind is one file implementing `Actuator`
//! (its parameters, built once from the scenario and gathered one vehicle per lane) and
//! `ActuatorModel` (its command, held over a step, its states' dynamics and the thrust and
//! torques the plant feels). Its own keys in `[actuator]` are declared in its file
//! (`OwnsKeys::Params`, with `config::params!`) and checked there (`OwnsKeys::validate`). To
//! add a kind: a file beside `ideal.rs`, its `mod` line here and its line in the registration
//! `model::kinds!` (which generates its name in `ActuatorKind`, its table in
//! `ActuatorConfig`, `AnyActuator` and every `model::dispatch` line).

mod ideal;
pub mod rotors;
pub mod shared;

pub use ideal::{Ideal, IdealParams};
pub use rotors::{RotorParams, Rotors};
pub use shared::Shared;

use super::layout::StateVar;
use super::{Inputs, State, Tick};
use crate::model::section::OwnsKeys;
use crate::model::ModelContext;

pub use super::{ActuatorConfig, ActuatorKind, AnyActuator};
use crate::lane::Lane;

/// An actuator's dynamics, with parameters of lane type `L`.
pub trait ActuatorModel<L: Lane>: Sync {
    /// The actuator's own states (after the payload's velocities).
    const STATES: usize;
    /// What the actuator is told at the start of a step and holds over its four RK4 stages.
    type Command: Copy;
    /// The kind's extra trace columns, after the common ones (`signals` writes them).
    const SIGNALS: &'static [&'static str] = &[];

    /// The held command for the controller's thrust and torques `u` at the step `at` (a
    /// scheduled fault reads its time here).
    fn command(&self, u: &Inputs<L>, at: Tick) -> Self::Command;

    /// The thrust and torques the airframe feels at state `s` (actuator states from `at`).
    fn inputs<const N: usize>(&self, cmd: &Self::Command, s: &State<L, N>, at: usize) -> Inputs<L>;

    /// Write the actuator states' derivatives (`ds[at..at + STATES]`).
    fn derivative<const N: usize>(
        &self,
        cmd: &Self::Command,
        s: &State<L, N>,
        at: usize,
        ds: &mut State<L, N>,
    );

    /// Put the actuator states at hover (`s[at..at + STATES]`).
    fn rest<const N: usize>(&self, s: &mut State<L, N>, at: usize);

    /// The actuator's aerodynamic wrench on the airframe at `s` (its states from `at`), in body
    /// axes (force N, moment N m), for the air's velocity relative to the vehicle `air` (m/s,
    /// inertial: v - wind), the body's axes `axes` (the columns of R) and its body rates `rates`
    /// (rad/s); None (the default) where it has none. Flown on the rigid body only (the paper's
    /// body refuses the keys that make one).
    #[inline(always)]
    fn aero<const N: usize>(
        &self,
        _s: &State<L, N>,
        _at: usize,
        _air: &[L; 3],
        _axes: &[[L; 3]; 3],
        _rates: &[L; 3],
    ) -> Option<([L; 3], [L; 3])> {
        None
    }

    /// The kind's extra trace columns (`SIGNALS`, in order) at `s` with `cmd` held.
    #[inline(always)]
    fn signals<const N: usize>(
        &self,
        _cmd: &Self::Command,
        _s: &State<L, N>,
        _at: usize,
        _out: &mut [L],
    ) {
    }

    /// 1 in a lane where the held command `cmd` was clamped to a limit, else 0.
    #[inline(always)]
    fn saturated(&self, _cmd: &Self::Command) -> L {
        L::splat(0.0)
    }
}

/// An actuator kind's parameters for one vehicle, resolved once from the scenario.
pub trait Actuator: OwnsKeys + Clone + Sync + Send + Sized + 'static {
    type At<L: Lane>: ActuatorModel<L>;
    /// The kind's states (`STATES` of them).
    const VARS: &'static [StateVar];
    /// The parameters of a validated scenario (`p`: the kind's keys).
    fn new(p: &<Self as OwnsKeys>::Params, cfg: &ModelContext) -> Self;
    fn gather<L: Lane>(each: &[&Self]) -> Self::At<L>;
    /// This kind's parameters inside the combined enum (`model::dispatch` matched the kind).
    fn of(any: &AnyActuator) -> &Self {
        any.get::<Self>()
    }
}
