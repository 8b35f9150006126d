//! Checks of the arguments Python passes, before the engine runs.

use super::errors::scenario_error;
use crate::control::ControllerKind;
use crate::integrate::Engine;
use crate::memory;
use crate::scenario::Config;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

/// The spectrum samples every flight keeps (one per `1 / metrics.spectrum_rate`), for
/// `lanes` realisations on each of `threads` threads: must fit in memory.
pub(super) fn flight_memory(e: &Engine, lanes: usize, threads: usize) -> Result<(), String> {
    let samples = (e.steps / e.decimation() + 1) as u128;
    memory::check(
        "spectrum samples per flight (integrator.duration * metrics.spectrum_rate)",
        samples * (lanes * threads) as u128,
        8,
    )
}

/// The instruction set new engines use: an error (ValueError: a bad setting, so the CLI's
/// exit 2) if QUADRS_SIMD forces one this CPU cannot run or names none.
pub(super) fn isa() -> PyResult<crate::lane::isa::Isa> {
    crate::lane::isa::Isa::active().map_err(PyValueError::new_err)
}

/// Most worker threads a call may ask for (quadrs.guard.MAX_WORKERS): a pool of a million
/// threads would swamp the machine, not speed anything up.
const MAX_WORKERS: usize = 4096;

/// `workers` in [1, MAX_WORKERS], or a ValueError naming it.
pub(super) fn check_workers(workers: usize) -> PyResult<()> {
    if (1..=MAX_WORKERS).contains(&workers) {
        Ok(())
    } else {
        Err(PyValueError::new_err(format!(
            "workers must be between 1 and {MAX_WORKERS}, got {workers}"
        )))
    }
}

pub(super) fn engine(config_json: &str) -> PyResult<Engine> {
    isa()?;
    let cfg = Config::from_json(config_json).map_err(scenario_error)?;
    Engine::of_valid(cfg).map_err(scenario_error)
}

pub(super) fn controllers(names: &[String]) -> PyResult<Vec<ControllerKind>> {
    if names.is_empty() {
        let names: Vec<String> = ControllerKind::ALL
            .iter()
            .map(|k| format!("'{}'", k.name()))
            .collect();
        return Err(PyValueError::new_err(format!(
            "controllers must name at least one of {}",
            names.join(", ")
        )));
    }
    names
        .iter()
        .map(|n| ControllerKind::parse(n).map_err(PyValueError::new_err))
        .collect()
}

/// xi must hold exactly the engine's innovations per flight.
pub(super) fn check_innovations(e: &Engine, len: usize) -> PyResult<()> {
    let want = e.innovations();
    if len != want {
        return Err(PyValueError::new_err(format!(
            "xi must hold {want} standard normals per flight (innovations_dimension), got {len}"
        )));
    }
    Ok(())
}
