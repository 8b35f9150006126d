//! The Python module `quadrs._core`: the engine's entry points for Python.
//!
//! Every entry point takes the scenario as JSON (validated here again, so the engine guards
//! itself), runs with the GIL released, and hands results to numpy without copying. This file
//! registers the module (its functions, classes and constants); the rest is split by concern:
//! `engine` the compiled scenario (`Engine`), `flight` one flight (`simulate`), `batch` many
//! (`run_batch`, `run_innovations`), `stability` the closed loop at hover, `engine_functions`
//! the module-level functions that build an `Engine` and call its method, `describe` a
//! scenario's derived quantities, `constants` the module's names and units, `wind` the gust
//! filters and the mean wind, `lane_math` the instruction set and lane functions, `progress` a
//! batch's progress, `errors` the exceptions, `checks` the argument checks.

mod batch;
mod checks;
mod constants;
mod describe;
mod engine;
mod engine_functions;
mod errors;
mod flight;
mod lane_math;
mod progress;
mod stability;
mod wind;

pub use errors::{EngineError, ScenarioError};
use pyo3::prelude::*;

#[pymodule]
mod _core {
    #[pymodule_export]
    use super::describe::describe;
    #[pymodule_export]
    use super::engine::CompiledEngine;
    #[pymodule_export]
    use super::errors::_panic_for_tests;
    #[pymodule_export]
    use super::lane_math::{lane_math, lanes_per_set, simd_path};
    #[pymodule_export]
    use super::progress::Progress;
    #[pymodule_export]
    use super::wind::{gust_psd, gust_series, low_altitude_scales, mean_wind};
    use pyo3::prelude::*;

    #[pymodule_init]
    fn init(m: &Bound<'_, PyModule>) -> PyResult<()> {
        super::errors::add(m)?;
        super::constants::add(m)?;
        super::engine_functions::add(m)?;
        m.add("__version__", env!("CARGO_PKG_VERSION"))
    }
}
