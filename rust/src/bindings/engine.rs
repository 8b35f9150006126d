//! `Engine`: a scenario compiled once and flown many times. Its methods are the Python surface;
//! the work is `flight`'s, `batch`'s and `stability`'s.

use super::checks::engine;
use super::flight::{simulate_on, Flight};
use super::progress::Progress;
use crate::control::ControllerKind;
use crate::integrate::Engine;
use crate::memory;
use numpy::{IntoPyArray, PyArray1, PyReadonlyArray1, PyReadonlyArray2};
use pyo3::exceptions::{PyMemoryError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::borrow::Cow;

/// A scenario compiled once (validated; its vehicle, reference and gust filters built) and
/// then flown many times without reading the scenario again, as a schema validator is
/// built once and called many times. `quadrs.Scenario.engine` holds one. Its methods are
/// the module's functions without `config_json`, and give the same numbers bit for bit.
#[pyclass(frozen, name = "Engine", module = "quadrs._core")]
pub(super) struct CompiledEngine {
    engine: Engine,
}

#[pymethods]
impl CompiledEngine {
    #[new]
    pub(super) fn new(config_json: &str) -> PyResult<Self> {
        Ok(Self {
            engine: engine(config_json)?,
        })
    }

    /// Integration steps of one flight.
    #[getter]
    fn steps(&self) -> usize {
        self.engine.steps
    }

    /// Whether the start balances its steady wind (`initial.trim = "wind"`): false where the
    /// vehicle cannot hover in that wind and starts level at rest instead (docs/model.md,
    /// "The start").
    #[getter]
    fn start_balanced(&self) -> bool {
        self.engine.realisation.balanced
    }

    /// m/s, the steady wind at the start (world axes) that the start is trimmed in: zeros
    /// with `initial.trim = "rest"`.
    #[getter]
    fn start_wind(&self) -> [f64; 3] {
        let e = &self.engine;
        crate::integrate::trim_wind(&e.cfg, e.realisation.wind(), e.cfg.initial.position[2])
    }

    /// Integration steps between the updates of `controller`'s position, attitude and inner
    /// loops (1: every step; docs/model.md, "Loop rates").
    fn loop_steps(&self, controller: &str) -> PyResult<[usize; 3]> {
        let kind = ControllerKind::parse(controller).map_err(PyValueError::new_err)?;
        Ok(self.engine.cfg.controller.loop_steps(kind, self.engine.dt))
    }

    /// Whether `controller`'s position, attitude and inner loops each run at every step
    /// whatever the step (no rate of their own: a coarser step holds them longer).
    fn every_step(&self, controller: &str) -> PyResult<[bool; 3]> {
        let kind = ControllerKind::parse(controller).map_err(PyValueError::new_err)?;
        Ok(self.engine.cfg.controller.every_step(kind))
    }

    /// Standard normals one flight's turbulence draws: its onset's stationary state and every
    /// later update of the gust window, per active component (docs/rare-events.md).
    fn innovations_dimension(&self) -> usize {
        self.engine.innovations()
    }

    /// The innovations realisation `realisation` of `seed` draws: `simulate(..., xi=these)`
    /// flies the seeded flight, bit for bit.
    fn innovations<'py>(
        &self,
        py: Python<'py>,
        seed: u64,
        realisation: u64,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let e = &self.engine;
        memory::check("innovations", e.innovations() as u128, 8).map_err(PyMemoryError::new_err)?;
        Ok(e.innovations_of(seed, realisation).into_pyarray(py))
    }

    /// Closed-loop poles at hover (rust/src/stability.rs), least stable first: per pole its
    /// mode, dominant state, status and whether the scenario excites it; and the verdict.
    fn stability<'py>(&self, py: Python<'py>, controller: &str) -> PyResult<Bound<'py, PyDict>> {
        super::stability::stability(py, &self.engine, controller)
    }

    /// The closed loop linearised at hover in the steady wind `wind` (rust/src/stability.rs):
    /// A, B, C, D (exact, dual numbers), the equilibrium and the signal names.
    fn linearize<'py>(
        &self,
        py: Python<'py>,
        controller: &str,
        wind: [f64; 3],
    ) -> PyResult<Bound<'py, PyDict>> {
        super::stability::linearize(py, &self.engine, controller, wind)
    }

    /// One flight: trace every `record_every` steps, per-phase metrics, divergence time. With
    /// `wind` ((steps + 1, 3), m/s) that wind is flown instead of the gust model; with `xi`
    /// (`innovations_dimension` values) the turbulence is driven by those standard normals
    /// instead of the seeded stream; a dispersed scenario's flight then needs
    /// `dispersion_keys` (its dispersed keys) and `dispersion_values` (one value each): the
    /// flight of the fixed scenario with those values set, bit for bit. A seeded flight flies
    /// a fixed scenario only (the engine draws no parameter values). With `progress`, the
    /// flight polls its cancel flag (`Progress.cancel()`) and raises KeyboardInterrupt when
    /// cancelled.
    #[pyo3(signature = (controller, seed, realisation=0, record_every=1, wind=None, progress=None, xi=None, dispersion_keys=Vec::new(), dispersion_values=None))]
    #[allow(clippy::too_many_arguments)]
    fn simulate<'py>(
        &self,
        py: Python<'py>,
        controller: &str,
        seed: u64,
        realisation: u64,
        record_every: usize,
        wind: Option<PyReadonlyArray2<'py, f64>>,
        progress: Option<&Bound<'py, Progress>>,
        xi: Option<PyReadonlyArray1<'py, f64>>,
        dispersion_keys: Vec<String>,
        dispersion_values: Option<PyReadonlyArray1<'py, f64>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let flight = Flight {
            controller,
            seed,
            realisation,
            record_every,
            wind,
            progress,
            xi,
            dispersion_keys,
            dispersion_values,
        };
        simulate_on(py, Cow::Borrowed(&self.engine), flight)
    }

    /// `simulate` driven by the innovations `xi_row` (see `simulate`'s `xi`, and its
    /// `dispersion_keys`/`dispersion_values` for a dispersed scenario).
    #[pyo3(signature = (controller, xi_row, record_every=1, progress=None, dispersion_keys=Vec::new(), dispersion_values=None))]
    #[allow(clippy::too_many_arguments)]
    fn simulate_innovations<'py>(
        &self,
        py: Python<'py>,
        controller: &str,
        xi_row: PyReadonlyArray1<'py, f64>,
        record_every: usize,
        progress: Option<&Bound<'py, Progress>>,
        dispersion_keys: Vec<String>,
        dispersion_values: Option<PyReadonlyArray1<'py, f64>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let flight = Flight {
            controller,
            seed: 0,
            realisation: 0,
            record_every,
            wind: None,
            progress,
            xi: Some(xi_row),
            dispersion_keys,
            dispersion_values,
        };
        simulate_on(py, Cow::Borrowed(&self.engine), flight)
    }

    /// Realisations first..first+count of every controller, on `workers` threads. With
    /// `dispersion_keys`, row j of `dispersion_values` (count, keys) holds the values
    /// realisation first + j flies; `streams` (count,) overrides each one's gust stream.
    /// `fused`: the opt-in fused mode (fused multiply-adds; not bit-identical to the default).
    #[pyo3(signature = (controllers, seed, first, count, workers, spectra=true, progress=None, dispersion_keys=Vec::new(), dispersion_values=None, streams=None, fused=false))]
    #[allow(clippy::too_many_arguments)]
    fn run_batch<'py>(
        &self,
        py: Python<'py>,
        controllers: Vec<String>,
        seed: u64,
        first: u64,
        count: usize,
        workers: usize,
        spectra: bool,
        progress: Option<&Bound<'py, Progress>>,
        dispersion_keys: Vec<String>,
        dispersion_values: Option<PyReadonlyArray2<'py, f64>>,
        streams: Option<PyReadonlyArray1<'py, u64>>,
        fused: bool,
    ) -> PyResult<Bound<'py, PyDict>> {
        let args = super::batch::BatchArgs {
            controllers,
            seed,
            first,
            count,
            workers,
            spectra,
            progress,
            dispersion_keys,
            dispersion_values,
            streams,
            fused,
        };
        super::batch::run_batch(py, &self.engine, args)
    }

    /// Fly one row of `xi` ((N, innovations_dimension)) per flight with `controller`, in
    /// lane-sets on `workers` threads: metrics (N, phases, metrics), NaN after a divergence.
    /// A dispersed scenario needs `dispersion_keys` (its dispersed keys) and
    /// `dispersion_values` (N, keys): row j flies the fixed scenario with row j's values set.
    #[pyo3(signature = (controller, xi, progress=None, workers=None, dispersion_keys=Vec::new(), dispersion_values=None))]
    #[allow(clippy::too_many_arguments)]
    fn run_innovations<'py>(
        &self,
        py: Python<'py>,
        controller: &str,
        xi: PyReadonlyArray2<'py, f64>,
        progress: Option<&Bound<'py, Progress>>,
        workers: Option<usize>,
        dispersion_keys: Vec<String>,
        dispersion_values: Option<PyReadonlyArray2<'py, f64>>,
    ) -> PyResult<Bound<'py, numpy::PyArray3<f64>>> {
        let args = super::batch::InnovationsArgs {
            controller,
            xi,
            progress,
            workers,
            dispersion_keys,
            dispersion_values,
        };
        super::batch::run_innovations(py, &self.engine, args)
    }
}
