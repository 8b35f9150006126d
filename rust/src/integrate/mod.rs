//! The flight loop: classical RK4 with controls and wind sampled at the start of each step and
//! held over its four stages (a digital controller at 1/dt Hz), metrics taken online. The loop
//! knows no model's details: the vehicle (`model::Vehicle`) gives the derivative and the
//! payload's outputs, the layout gives the state names and runaway bounds.
//!
//! `rk4` is the step; `flight` the loop over a lane-set (`fly_kinds` dispatches on the vehicle
//! and controller kinds, `fly_law` gathers the lanes' parameters, `fly_loop` flies them);
//! `steps` the loop's named steps (the reference's leg, the wind, the last metres, the runaway
//! checks), inlined into it (the metrics take their signals from the loop's `metrics::Views`);
//! `entry` the way in, one function per (lane type, vehicle, law) compiled for the lane type's
//! instruction set (`LoopEntry`, `Engine::fly`, `Engine::fly_set`); `engine` the compiled
//! scenario (`Engine`, `Realisation`, `FlightRequest`, `LaneResult`); `trace` the trace's columns and rows;
//! `status` why a flight ended (`ExitStatus`).

mod engine;
mod entry;
mod flight;
mod rk4;
mod status;
mod steps;
mod trace;

pub use engine::{initial_state, Engine, FlightRequest, LaneResult, Realisation, MAX_LANES};
pub use entry::LoopEntry;
pub use rk4::{rk4_advance, rk4_step};
pub use status::ExitStatus;
pub use trace::{trace_columns, Trace, SIGNAL_COLUMNS};

#[cfg(test)]
mod tests;
