//! quadrs engine: the crate root. The physics lives in the modules below; `bindings` is the
//! Python module `quadrs._core` built on them.

// Every `unsafe` block says why it is sound (they live in `lane/`, its random-number kernels
// and the flight loop's instruction-set entry).
#![deny(clippy::undocumented_unsafe_blocks)]

mod bindings;
pub mod config;
pub mod control;
pub mod differences;
pub mod dispersion;
pub mod gust;
pub mod integrate;
pub mod lane;
pub mod legs;
pub mod memory;
pub mod metrics;
pub mod model;
pub mod montecarlo;
pub mod navigation;
pub mod rk4;
pub mod scenario;
pub mod stability;
pub mod start;
pub mod svd;
#[cfg(test)]
mod testing;
pub mod trajectory;

pub use bindings::{EngineError, ScenarioError};
