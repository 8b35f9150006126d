//! The flight loop: classical RK4 with controls and wind sampled at the start of each step and
//! held over its four stages, metrics taken online. A law's loops update at their own rates
//! (docs/model.md, "Loop rates": every step by default, a digital controller at 1/dt Hz), each holding
//! its output between its updates, and the wind at `gust.rate`, interpolated between. The loop
//! knows no model's details: the vehicle (`model::Vehicle`) gives the derivative and the
//! payload's outputs, the layout gives the state names and runaway bounds, the law
//! (`control::Flying`) its inputs.
//!
//! `crate::rk4` is the step; `flight` the loop over a lane-set (`fly_kinds` dispatches on the vehicle
//! kinds, `fly_vehicle` gathers the lanes' parameters, `fly_loop` flies them, choosing the
//! request's law once per step); `steps` the loop's named steps (the reference's leg, the
//! wind, the loops' schedule, the last metres, the runaway checks), inlined into it (the
//! metrics take their signals from the loop's `metrics::Views`); `entry` the way in, one
//! function per (lane type, vehicle) compiled for the lane type's instruction set
//! (`LoopEntry`, `Engine::fly`, `Engine::fly_set`); `engine` the compiled scenario (`Engine`,
//! `Realisation`, `FlightRequest`, `LaneResult`); `trace` the trace's columns and rows;
//! `status` why a flight ended (`ExitStatus`).

mod engine;
mod entry;
mod flight;
mod status;
mod steps;
mod trace;

pub use crate::rk4::{rk4_advance, rk4_step};
pub use engine::{
    initial_state, start_wind, trim_wind, Engine, FlightRequest, LaneResult, Realisation, MAX_LANES,
};
pub use entry::LoopEntry;
pub use status::ExitStatus;
pub use trace::{trace_columns, Trace, SIGNAL_COLUMNS};

#[cfg(test)]
mod tests;
