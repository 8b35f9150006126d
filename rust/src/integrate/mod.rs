//! The flight loop: classical RK4 with controls and wind sampled at the start of each step and
//! held over its four stages (a digital controller at 1/dt Hz), metrics taken online. The loop
//! knows no model's details: the vehicle (`model::Vehicle`) gives the derivative and the
//! payload's outputs, the layout gives the state names and runaway bounds.
//!
//! `rk4` is the step; `flight` the loop over a lane-set (`fly_kinds` dispatches on the vehicle
//! and controller kinds, `fly_law` gathers the lanes' parameters, `fly_loop` flies them);
//! `entry` the way in, one function per (lane type, vehicle, law) compiled for the lane type's
//! instruction set (`LoopEntry`, `Engine::fly`, `Engine::fly_set`); `engine` the compiled
//! scenario (`Engine`, `Realisation`, `FlightRequest`); `trace` the trace's columns and rows;
//! `status` why a flight ended (`ExitStatus`).

use crate::config::{Config, ConfigError};
use crate::control::{Control, Controller, ControllerKind, ControllerVisitor, Laws};
use crate::gust::{Kinematics, LaneWind, WindField, WindState};
use crate::lane::isa::Isa;
use crate::lane::{F64x4, KernelOps, Lane};
#[cfg(target_arch = "x86_64")]
use crate::lane::{F64x4Avx, F64x4Fma, F64x8Avx512, F64x8Fma512};
use crate::metrics::{LastSample, PhaseAccumulator, Sample, N_METRICS};
use crate::model::payload::Cue;
use crate::model::{
    dispatch, ix, state_from_fn, state_vars, Actuator, ActuatorKind, ActuatorModel, AnyVehicle,
    BodyKind, BodyModel, Bound, Inputs, Payload, PayloadKind, State, StateVar, Tick, Vehicle,
    VehicleVisitor,
};
use crate::trajectory::{phase_steps, PhaseSteps, Reference, Trajectory, TIME_SLACK};
use rustfft::FftPlanner;
use std::marker::PhantomData;
use std::sync::atomic::{AtomicBool, Ordering};

mod engine;
mod entry;
mod flight;
mod rk4;
mod status;
mod trace;

pub use engine::{initial_state, Engine, FlightRequest, Realisation, MAX_LANES};
pub use entry::LoopEntry;
pub use flight::LaneResult;
pub use rk4::{rk4_advance, rk4_step};
use status::classify;
pub use status::ExitStatus;
pub use trace::{trace_columns, Trace, SIGNAL_COLUMNS};
use trace::{TraceRow, MAX_ACTUATOR_SIGNALS};

#[cfg(test)]
mod tests;
