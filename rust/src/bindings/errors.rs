//! The module's exceptions, and how an engine failure reaches Python.

use crate::config::ConfigError;
use crate::montecarlo::pool;
use pyo3::prelude::*;
use std::panic::{catch_unwind, AssertUnwindSafe};

pyo3::create_exception!(
    _core,
    ScenarioError,
    pyo3::exceptions::PyValueError,
    "A scenario value is invalid; the message names the key and the value."
);
pyo3::create_exception!(
    _core,
    EngineError,
    pyo3::exceptions::PyRuntimeError,
    "The engine failed internally (a bug): the message says where."
);

/// Add the exceptions to the module.
pub(super) fn add(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let scenario_error = m.py().get_type::<ScenarioError>();
    // `key`: the dotted scenario key at fault (None unless the raiser names one).
    scenario_error.setattr("key", m.py().None())?;
    m.add("ScenarioError", scenario_error)?;
    m.add("EngineError", m.py().get_type::<EngineError>())?;
    Ok(())
}

/// ScenarioError with the message, and the offending dotted key as its `key` attribute.
pub(super) fn scenario_error(e: ConfigError) -> PyErr {
    Python::attach(|py| {
        let err = ScenarioError::new_err(e.message);
        match err.value(py).setattr("key", e.key) {
            Ok(()) => err,
            Err(failed) => failed,
        }
    })
}

/// Run `f`, turning a Rust panic into EngineError with its message (the process survives).
pub(super) fn guarded<T>(what: &str, f: impl FnOnce() -> T) -> PyResult<T> {
    catch_unwind(AssertUnwindSafe(f)).map_err(|p| {
        let msg = p
            .downcast_ref::<String>()
            .cloned()
            .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
            .unwrap_or_else(|| "unknown panic".into());
        EngineError::new_err(format!("{what} failed inside the engine: {msg}"))
    })
}

/// Panic inside the engine (on a worker thread of the pool when `in_pool`): lets the tests
/// prove that a Rust panic surfaces as EngineError and the process survives. Not public API.
#[pyfunction]
pub(super) fn _panic_for_tests(py: Python<'_>, message: &str, in_pool: bool) -> PyResult<()> {
    py.detach(|| {
        guarded("_panic_for_tests", || {
            if in_pool {
                pool(2).install(|| rayon::join(|| panic!("{message}"), || ()));
            } else {
                panic!("{message}");
            }
        })
    })
}
