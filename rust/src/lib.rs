//! quadrs engine. This file holds the Python bindings only; the physics lives in the modules.
//!
//! Every entry point takes the scenario as JSON (validated here again, so the engine guards
//! itself), runs with the GIL released, and hands results to numpy without copying.

// Every `unsafe` block says why it is sound (they live in `lane/`, its random-number kernels
// and the flight loop's instruction-set entry).
#![deny(clippy::undocumented_unsafe_blocks)]

pub mod config;
pub mod control;
pub mod dispersion;
pub mod gust;
pub mod integrate;
pub mod lane;
pub mod legs;
pub mod memory;
pub mod metrics;
pub mod model;
pub mod montecarlo;
pub mod stability;
pub mod trajectory;

use pyo3::prelude::*;

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

#[pymodule]
mod _core {
    use super::{EngineError, ScenarioError};
    use crate::config::{Config, ConfigError, GustComponent, GustModel};
    use crate::control::ControllerKind;
    use crate::dispersion::Dispersion;
    use crate::gust;
    use crate::integrate::{trace_columns, Engine, ExitStatus, FlightRequest, Realisation};
    use crate::memory;
    use crate::metrics::{METRICS, METRIC_NAMES, N_METRICS};
    use crate::model::{state_vars, ActuatorKind, PayloadKind};
    use crate::montecarlo::{
        pool, run_batch as batch, run_innovations as innovations_batch, Batch,
    };
    use numpy::ndarray::{Array1, Array2, Array4};
    use numpy::{IntoPyArray, PyArray1, PyArray2, PyReadonlyArray1, PyReadonlyArray2};
    use pyo3::exceptions::{PyKeyboardInterrupt, PyMemoryError, PyTypeError, PyValueError};
    use pyo3::prelude::*;
    use pyo3::types::{PyCFunction, PyDict, PyList, PyTuple};
    use rustfft::FftPlanner;
    use std::borrow::Cow;
    use std::ffi::CStr;
    use std::panic::{catch_unwind, AssertUnwindSafe};
    use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
    use std::sync::Arc;

    #[pymodule_init]
    fn init(m: &Bound<'_, PyModule>) -> PyResult<()> {
        let scenario_error = m.py().get_type::<ScenarioError>();
        // `key`: the dotted scenario key at fault (None unless the raiser names one).
        scenario_error.setattr("key", m.py().None())?;
        m.add("ScenarioError", scenario_error)?;
        m.add("EngineError", m.py().get_type::<EngineError>())?;
        m.add("METRIC_NAMES", METRIC_NAMES.to_vec())?;
        // The metrics of an event (NaN in a phase or flight without it), in METRIC_NAMES' order.
        let events: Vec<&str> = METRICS.iter().filter(|x| x.event).map(|x| x.name).collect();
        m.add("EVENT_METRICS", events)?;
        // Each metric's unit (SI, as stored) and plain-English label, from its one definition.
        let units = PyDict::new(m.py());
        let labels = PyDict::new(m.py());
        for metric in &METRICS {
            units.set_item(metric.name, metric.unit)?;
            labels.set_item(metric.name, metric.label)?;
        }
        m.add("METRIC_UNITS", units)?;
        m.add("METRIC_LABELS", labels)?;
        // The unit and label of every scenario key (dotted, indices dropped), from the
        // declaration beside its section's struct or in its kind's file (`config::params!`).
        let units = PyDict::new(m.py());
        let labels = PyDict::new(m.py());
        for (key, k) in crate::config::Config::keys() {
            units.set_item(&key, k.unit)?;
            labels.set_item(&key, k.label)?;
        }
        m.add("KEY_UNITS", units)?;
        m.add("KEY_LABELS", labels)?;
        // Each controller kind's default table (JSON text), where it has one.
        let defaults = PyDict::new(m.py());
        for (name, table) in crate::config::ControllerConfig::default_tables() {
            if let Some(json) = table {
                defaults.set_item(name, json)?;
            }
        }
        m.add("CONTROLLER_DEFAULTS", defaults)?;
        m.add(
            "CONTROLLER_NAMES",
            ControllerKind::ALL
                .iter()
                .map(|k| k.name())
                .collect::<Vec<_>>(),
        )?;
        // The payload and actuator models (`payload.model`, `actuator.model`), registered once
        // (`model::kinds!`).
        m.add(
            "PAYLOAD_MODELS",
            crate::model::PAYLOAD_KINDS
                .iter()
                .map(|k| k.name())
                .collect::<Vec<_>>(),
        )?;
        m.add(
            "ACTUATOR_MODELS",
            crate::model::ACTUATOR_KINDS
                .iter()
                .map(|k| k.name())
                .collect::<Vec<_>>(),
        )?;
        // The bodies (`vehicle.body`).
        m.add(
            "BODY_MODELS",
            crate::model::BODY_MODELS
                .iter()
                .map(|k| k.name())
                .collect::<Vec<_>>(),
        )?;
        // The paper's layout (vertical spring, ideal actuators); a scenario's own come with its
        // description (`describe`) and its flights.
        let vars = state_vars(
            Default::default(),
            PayloadKind::default(),
            ActuatorKind::default(),
        );
        m.add(
            "TRACE_COLUMNS",
            trace_columns(
                Default::default(),
                PayloadKind::default(),
                ActuatorKind::default(),
            ),
        )?;
        m.add(
            "STATE_NAMES",
            vars.iter().map(|v| v.name).collect::<Vec<_>>(),
        )?;
        m.add(
            "EXIT_STATUSES",
            ExitStatus::ALL.map(ExitStatus::name).to_vec(),
        )?;
        m.add(
            "EXIT_MESSAGES",
            ExitStatus::ALL.map(ExitStatus::message).to_vec(),
        )?;
        for f in ENGINE_FUNCTIONS {
            m.add_function(engine_function(m.py(), f)?)?;
        }
        m.add("__version__", env!("CARGO_PKG_VERSION"))
    }

    /// The spectrum samples every flight keeps (one per `1 / metrics.spectrum_rate`), for
    /// `lanes` realisations on each of `threads` threads: must fit in memory.
    fn flight_memory(e: &Engine, lanes: usize, threads: usize) -> Result<(), String> {
        let samples = (e.steps / e.decimation() + 1) as u128;
        memory::check(
            "spectrum samples per flight (integrator.duration * metrics.spectrum_rate)",
            samples * (lanes * threads) as u128,
            8,
        )
    }

    /// ScenarioError with the message, and the offending dotted key as its `key` attribute.
    fn scenario_error(e: ConfigError) -> PyErr {
        Python::attach(|py| {
            let err = ScenarioError::new_err(e.message);
            match err.value(py).setattr("key", e.key) {
                Ok(()) => err,
                Err(failed) => failed,
            }
        })
    }

    /// The instruction set new engines use: an error (ValueError: a bad setting, so the CLI's
    /// exit 2) if QUADRS_SIMD forces one this CPU cannot run or names none.
    fn isa() -> PyResult<crate::lane::isa::Isa> {
        crate::lane::isa::Isa::active().map_err(PyValueError::new_err)
    }

    /// Most worker threads a call may ask for (quadrs.guard.MAX_WORKERS): a pool of a million
    /// threads would swamp the machine, not speed anything up.
    const MAX_WORKERS: usize = 4096;

    /// `workers` in [1, MAX_WORKERS], or a ValueError naming it.
    fn check_workers(workers: usize) -> PyResult<()> {
        if (1..=MAX_WORKERS).contains(&workers) {
            Ok(())
        } else {
            Err(PyValueError::new_err(format!(
                "workers must be between 1 and {MAX_WORKERS}, got {workers}"
            )))
        }
    }

    fn engine(config_json: &str) -> PyResult<Engine> {
        isa()?;
        let cfg = Config::from_json(config_json).map_err(scenario_error)?;
        Engine::of_valid(cfg).map_err(scenario_error)
    }

    fn controllers(names: &[String]) -> PyResult<Vec<ControllerKind>> {
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

    /// Run `f`, turning a Rust panic into EngineError with its message (the process survives).
    fn guarded<T>(what: &str, f: impl FnOnce() -> T) -> PyResult<T> {
        catch_unwind(AssertUnwindSafe(f)).map_err(|p| {
            let msg = p
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_else(|| "unknown panic".into());
            EngineError::new_err(format!("{what} failed inside the engine: {msg}"))
        })
    }

    /// The instruction set the engine's hot loop uses on this machine ("avx512", "avx2" or
    /// "baseline"), chosen at run time; QUADRS_SIMD=baseline|avx2|avx512 forces one (an error
    /// if this CPU cannot run it). Every path gives bit-identical results in the default mode.
    #[pyfunction]
    fn simd_path() -> PyResult<&'static str> {
        isa().map(|i| i.name())
    }

    /// Validate a scenario; return the quantities derived from it. Cheap: builds no engine (no
    /// gust filters).
    #[pyfunction]
    fn describe<'py>(py: Python<'py>, config_json: &str) -> PyResult<Bound<'py, PyDict>> {
        isa()?;
        let cfg = Config::from_json(config_json).map_err(scenario_error)?;
        gust::WindField::check(&cfg).map_err(scenario_error)?;
        let d = PyDict::new(py);
        d.set_item("stiffness", cfg.stiffness())?;
        d.set_item("hover_offset", crate::model::hover_drop(&cfg))?;
        d.set_item("steps", cfg.steps())?;
        d.set_item("turbulence_w20", cfg.turbulence_w20())?;
        d.set_item("phases", crate::trajectory::phase_names(&cfg))?;
        let windows: Vec<(String, f64, f64)> = cfg
            .phases
            .iter()
            .map(|p| (p.name.clone(), p.start, p.end))
            .chain(std::iter::once((
                crate::config::route::FLIGHT_PHASE.to_string(),
                0.0,
                cfg.integrator.duration,
            )))
            .collect();
        d.set_item("phase_windows", windows)?;
        let route = PyList::empty(py);
        for s in crate::config::route::schedule(&cfg).map_err(scenario_error)? {
            let seg = PyDict::new(py);
            seg.set_item("name", &s.name)?;
            seg.set_item("kind", s.kind.name())?;
            seg.set_item("start", s.start)?;
            seg.set_item("arrival", s.arrival)?;
            seg.set_item("end", s.end)?;
            seg.set_item("origin", cfg.trajectory.route[s.from])?;
            seg.set_item("target", cfg.trajectory.route[s.to])?;
            seg.set_item("length", s.profile.length)?;
            seg.set_item("peak_speed", s.profile.peak_speed)?;
            seg.set_item("ramp", s.profile.ramp)?;
            seg.set_item("cruise", s.profile.cruise)?;
            seg.set_item("payout", s.payout)?;
            route.append(seg)?;
        }
        d.set_item("route", route)?;
        let vars = state_vars(cfg.vehicle.body, cfg.payload.model, cfg.actuator.model);
        d.set_item(
            "state_names",
            vars.iter().map(|v| v.name).collect::<Vec<_>>(),
        )?;
        d.set_item(
            "trace_columns",
            trace_columns(cfg.vehicle.body, cfg.payload.model, cfg.actuator.model),
        )?;
        let grids: Vec<Bound<'py, PyArray1<f64>>> = crate::metrics::spectrum_grid(
            &crate::trajectory::phase_steps(&cfg),
            cfg.integrator.dt,
            cfg.decimation(),
            cfg.steps(),
        )
        .into_iter()
        .map(|g| g.into_pyarray(py))
        .collect();
        d.set_item("spectrum_frequencies", grids)?;
        Ok(d)
    }

    /// The module's engine functions: each is `Engine(config_json).<name>(*args, **kwargs)`,
    /// for a caller with one call to make (the docstring holds the signature and points to
    /// the method, the one implementation).
    const ENGINE_FUNCTIONS: [(&CStr, &CStr); 8] = [
        (c"simulate", c"simulate(config_json, controller, seed, realisation=0, record_every=1, wind=None, progress=None, xi=None, dispersion_keys=..., dispersion_values=None)\n--\n\nEngine(config_json).simulate(...): one flight, its trace, metrics and spectra."),
        (c"simulate_innovations", c"simulate_innovations(config_json, controller, xi_row, record_every=1, progress=None, dispersion_keys=..., dispersion_values=None)\n--\n\nEngine(config_json).simulate_innovations(...): one flight driven by given standard normals."),
        (c"run_batch", c"run_batch(config_json, controllers, seed, first, count, workers, spectra=True, progress=None, dispersion_keys=..., dispersion_values=None, streams=None, fused=False)\n--\n\nEngine(config_json).run_batch(...): a Monte Carlo chunk."),
        (c"run_innovations", c"run_innovations(config_json, controller, xi, progress=None, workers=None, dispersion_keys=..., dispersion_values=None)\n--\n\nEngine(config_json).run_innovations(...): one flight per row of standard normals."),
        (c"innovations", c"innovations(config_json, seed, realisation)\n--\n\nEngine(config_json).innovations(...): the standard normals a seeded flight draws."),
        (c"innovations_dimension", c"innovations_dimension(config_json)\n--\n\nEngine(config_json).innovations_dimension(): standard normals per flight."),
        (c"stability", c"stability(config_json, controller)\n--\n\nEngine(config_json).stability(...): the closed-loop poles at hover."),
        (c"linearize", c"linearize(config_json, controller, wind)\n--\n\nEngine(config_json).linearize(...): the closed loop at hover as a state-space model."),
    ];

    /// One of `ENGINE_FUNCTIONS` as a Python function of `config_json` (first, or by
    /// keyword) and the method's arguments.
    fn engine_function<'py>(
        py: Python<'py>,
        (name, doc): (&'static CStr, &'static CStr),
    ) -> PyResult<Bound<'py, PyCFunction>> {
        let method = name.to_str().expect("an ASCII name");
        PyCFunction::new_closure(py, Some(name), Some(doc), move |args, kwargs| {
            let py = args.py();
            let kwargs = kwargs.map(|k| k.copy()).transpose()?;
            let (json, rest) = match args.len() {
                0 => {
                    let json = kwargs
                        .as_ref()
                        .and_then(|k| k.get_item("config_json").transpose())
                        .transpose()?
                        .ok_or_else(|| {
                            PyTypeError::new_err(format!("{method}() needs config_json"))
                        })?;
                    if let Some(k) = &kwargs {
                        k.del_item("config_json")?;
                    }
                    (json, PyTuple::empty(py))
                }
                n => (args.get_item(0)?, args.get_slice(1, n)),
            };
            let engine = Bound::new(py, CompiledEngine::new(&json.extract::<String>()?)?)?;
            engine
                .call_method(method, rest, kwargs.as_ref())
                .map(Bound::unbind)
        })
    }

    /// A scenario compiled once (validated; its vehicle, reference and gust filters built) and
    /// then flown many times without reading the scenario again, as a schema validator is
    /// built once and called many times. `quadrs.Scenario.engine` holds one. Its methods are
    /// the module's functions without `config_json`, and give the same numbers bit for bit.
    #[pyclass(frozen, name = "Engine", module = "quadrs._core")]
    struct CompiledEngine {
        engine: Engine,
    }

    #[pymethods]
    impl CompiledEngine {
        #[new]
        fn new(config_json: &str) -> PyResult<Self> {
            Ok(Self {
                engine: engine(config_json)?,
            })
        }

        /// Integration steps of one flight.
        #[getter]
        fn steps(&self) -> usize {
            self.engine.steps
        }

        /// Standard normals one flight's turbulence draws: its onset's stationary state and every
        /// later step of the gust window, per active component (docs/rare-events.md).
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
            memory::check("innovations", e.innovations() as u128, 8)
                .map_err(PyMemoryError::new_err)?;
            Ok(e.innovations_of(seed, realisation).into_pyarray(py))
        }

        /// Closed-loop poles at hover (rust/src/stability.rs), least stable first: per pole its
        /// mode, dominant state, status and whether the scenario excites it; and the verdict.
        fn stability<'py>(
            &self,
            py: Python<'py>,
            controller: &str,
        ) -> PyResult<Bound<'py, PyDict>> {
            let kind = ControllerKind::parse(controller).map_err(PyValueError::new_err)?;
            let cfg = &self.engine.cfg;
            use crate::stability::{analyse, Pole, Verdict, TOLERANCE};
            let a = py.detach(|| guarded("stability", || analyse(cfg, kind)))?;
            let numbers = |f: fn(&Pole) -> f64| Array1::from_iter(a.poles.iter().map(f));
            let names = |f: fn(&Pole) -> &'static str| a.poles.iter().map(f).collect::<Vec<_>>();
            let excited = Array1::from_iter(a.poles.iter().map(|p| p.excited));
            let n = a.jacobian.nrows();
            let jac = Array2::from_shape_fn((n, n), |(i, j)| a.jacobian[(i, j)]);
            let d = PyDict::new(py);
            d.set_item("real", numbers(|p| p.re).into_pyarray(py))?;
            d.set_item("imag", numbers(|p| p.im).into_pyarray(py))?;
            d.set_item("mode", names(|p| p.mode))?;
            d.set_item("dominant", names(|p| p.dominant))?;
            d.set_item("status", names(|p| p.verdict.name()))?;
            d.set_item("excited", excited.into_pyarray(py))?;
            d.set_item("verdict", a.verdict.name())?;
            d.set_item("stable", a.verdict == Verdict::Stable)?;
            d.set_item("lateral_sources", a.lateral_sources)?;
            d.set_item("equilibrium", a.equilibrium.to_vec().into_pyarray(py))?;
            d.set_item("residual", a.residual)?;
            d.set_item("jacobian", jac.into_pyarray(py))?;
            d.set_item("tolerance", TOLERANCE)?;
            Ok(d)
        }

        /// The closed loop linearised at hover in the steady wind `wind` (rust/src/stability.rs):
        /// A, B, C, D (exact, dual numbers), the equilibrium and the signal names.
        fn linearize<'py>(
            &self,
            py: Python<'py>,
            controller: &str,
            wind: [f64; 3],
        ) -> PyResult<Bound<'py, PyDict>> {
            let kind = ControllerKind::parse(controller).map_err(PyValueError::new_err)?;
            let cfg = &self.engine.cfg;
            use crate::stability::{linearise, INPUT_NAMES};
            if let Some(w) = wind.iter().find(|w| !w.is_finite()) {
                return Err(PyValueError::new_err(format!(
                    "wind must be finite, got {w}"
                )));
            }
            let l = py.detach(|| guarded("linearize", || linearise(cfg, kind, wind)))?;
            let d = PyDict::new(py);
            let dense = |rows: usize, cols: usize, f: &dyn Fn(usize, usize) -> f64| {
                Array2::from_shape_fn((rows, cols), |(i, j)| f(i, j))
            };
            let (nx, nu, ny) = (l.b.nrows(), l.b.ncols(), l.c.nrows());
            d.set_item("A", dense(nx, nx, &|i, j| l.a[(i, j)]).into_pyarray(py))?;
            d.set_item("B", dense(nx, nu, &|i, j| l.b[(i, j)]).into_pyarray(py))?;
            d.set_item("C", dense(ny, nx, &|i, j| l.c[(i, j)]).into_pyarray(py))?;
            d.set_item("D", dense(ny, nu, &|i, j| l.d[(i, j)]).into_pyarray(py))?;
            d.set_item("state_names", l.states.clone())?;
            d.set_item("input_names", INPUT_NAMES.to_vec())?;
            d.set_item("output_names", l.outputs.clone())?;
            d.set_item("equilibrium", l.equilibrium.clone().into_pyarray(py))?;
            d.set_item("residual", l.residual)?;
            Ok(d)
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
            };
            #[rustfmt::skip]
            let out = simulate_on(py, Cow::Borrowed(&self.engine), flight, wind, progress, xi, dispersion_keys, dispersion_values);
            out
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
            };
            #[rustfmt::skip]
            let out = simulate_on(py, Cow::Borrowed(&self.engine), flight, None, progress, Some(xi_row), dispersion_keys, dispersion_values);
            out
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
            let e = Cow::Borrowed(&self.engine);
            let kinds = self::controllers(&controllers)?;
            if count == 0 {
                return Err(PyValueError::new_err("runs must be >= 1, got 0"));
            }
            check_workers(workers)?;
            let e = match fused {
                false => e,
                true => Cow::Owned(
                    e.into_owned()
                        .with_fused(true)
                        .map_err(PyValueError::new_err)?,
                ),
            };
            let row = kinds.len() * e.phase_count() * N_METRICS;
            memory::check(
                "batch results (runs * controllers * phases * metrics)",
                count as u128 * (row + kinds.len() + 1) as u128,
                8,
            )
            .and_then(|()| flight_memory(&e, e.lanes_per_set(), workers))
            .map_err(PyMemoryError::new_err)?;
            let dispersion = match (dispersion_keys.is_empty(), dispersion_values) {
                (true, None) => None,
                (false, Some(v)) => {
                    let v = v.as_array();
                    let shape = v.shape();
                    if shape != [count, dispersion_keys.len()] {
                        return Err(PyValueError::new_err(format!(
                            "dispersion_values must have shape ({count}, {}), got {shape:?}",
                            dispersion_keys.len()
                        )));
                    }
                    let values = v.iter().copied().collect();
                    Some(
                        Dispersion::new(&e.cfg, dispersion_keys, values, count)
                            .map_err(scenario_error)?,
                    )
                }
                _ => {
                    return Err(PyValueError::new_err(
                        "dispersion_keys and dispersion_values go together",
                    ))
                }
            };
            let streams: Option<Vec<u64>> = streams.map(|s| s.as_array().iter().copied().collect());
            let b = Batch {
                want_spectra: spectra,
                dispersion: dispersion.as_ref(),
                streams: streams.as_deref(),
                ..Batch::new(&kinds, seed, first, count)
            };
            let (done, cancel) = match progress {
                Some(p) => (p.get().done.clone(), p.get().cancel.clone()),
                None => (
                    Arc::new(AtomicU64::new(0)),
                    Arc::new(AtomicBool::new(false)),
                ),
            };
            let out = py.detach(|| {
                guarded("run_batch", || {
                    pool(workers).install(|| {
                        b.check()?;
                        Ok(batch(&e, &b, &done, &cancel))
                    })
                })
            })?;
            let out = out.map_err(scenario_error)?;
            let n_ctrl = kinds.len();
            let n_phase = e.phase_count();
            let d = PyDict::new(py);
            let metrics = Array4::from_shape_vec((count, n_ctrl, n_phase, N_METRICS), out.metrics)
                .expect("metrics shape");
            d.set_item("metrics", metrics.into_pyarray(py))?;
            let diverged = Array2::from_shape_vec((count, n_ctrl), out.diverged_at).expect("shape");
            d.set_item("diverged_at", diverged.into_pyarray(py))?;
            let status = Array2::from_shape_vec((count, n_ctrl), out.status).expect("shape");
            d.set_item("status", status.into_pyarray(py))?;
            d.set_item("done", Array1::from_vec(out.done).into_pyarray(py))?;
            if spectra {
                // Per phase: (n_ctrl, bins) arrays of the ensemble sum and sum of squares.
                let per_phase =
                    |src: &Vec<Vec<Vec<f64>>>| -> Vec<Bound<'py, numpy::PyArray2<f64>>> {
                        (0..n_phase)
                            .map(|p| {
                                let bins = src.first().map_or(0, |c| c[p].len());
                                let flat: Vec<f64> =
                                    src.iter().flat_map(|c| c[p].iter().copied()).collect();
                                Array2::from_shape_vec((n_ctrl, bins), flat)
                                    .expect("shape")
                                    .into_pyarray(py)
                            })
                            .collect()
                    };
                d.set_item("spectrum_sum", per_phase(&out.spectra.sum))?;
                d.set_item("spectrum_sum_sq", per_phase(&out.spectra.sum_sq))?;
                d.set_item("spectrum_count", out.spectra.count)?;
            }
            Ok(d)
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
            let e = &self.engine;
            use numpy::ndarray::Array3;
            let kind = ControllerKind::parse(controller).map_err(PyValueError::new_err)?;
            let xi = xi.as_array();
            let (n, dim) = (xi.nrows(), xi.ncols());
            check_innovations(e, dim)?;
            let values = dispersion_values.map(|v| v.as_array().to_owned());
            let dispersion = innovations_dispersion(e, dispersion_keys, values.as_ref(), n)?;
            let workers = workers
                .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
            check_workers(workers)?;
            let rows: Vec<&[f64]> = match xi.as_slice() {
                Some(flat) if dim > 0 => flat.chunks(dim).collect(),
                Some(_) => vec![&[][..]; n],
                None => return Err(PyValueError::new_err("xi must be C-contiguous")),
            };
            let n_phase = e.phase_count();
            let (done, cancel) = match progress {
                Some(p) => (p.get().done.clone(), p.get().cancel.clone()),
                None => (
                    Arc::new(AtomicU64::new(0)),
                    Arc::new(AtomicBool::new(false)),
                ),
            };
            let flown = py.detach(|| {
                guarded("run_innovations", || {
                    innovations_batch(e, kind, &rows, dispersion.as_ref(), workers, &done, &cancel)
                })
            })?;
            let Some(metrics) = flown else {
                return Err(PyKeyboardInterrupt::new_err(
                    "run_innovations was cancelled",
                ));
            };
            Ok(Array3::from_shape_vec((n, n_phase, N_METRICS), metrics)
                .expect("shape")
                .into_pyarray(py))
        }
    }

    /// What `simulate` flies, besides the scenario and its inputs.
    struct Flight<'a> {
        controller: &'a str,
        seed: u64,
        realisation: u64,
        record_every: usize,
    }

    #[allow(clippy::too_many_arguments)]
    fn simulate_on<'py>(
        py: Python<'py>,
        mut e: Cow<'_, Engine>,
        flight: Flight<'_>,
        wind: Option<PyReadonlyArray2<'py, f64>>,
        progress: Option<&Bound<'py, Progress>>,
        xi: Option<PyReadonlyArray1<'py, f64>>,
        dispersion_keys: Vec<String>,
        dispersion_values: Option<PyReadonlyArray1<'py, f64>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let Flight {
            controller,
            seed,
            realisation,
            record_every,
        } = flight;
        let kind = ControllerKind::parse(controller).map_err(PyValueError::new_err)?;
        if record_every == 0 {
            return Err(PyValueError::new_err("record_every must be >= 1, got 0"));
        }
        if xi.is_some() {
            let values = dispersion_values.map(|v| {
                let v: Vec<f64> = v.as_array().iter().copied().collect();
                Array2::from_shape_vec((1, v.len()), v).expect("one row")
            });
            if let Some(d) = innovations_dispersion(&e, dispersion_keys, values.as_ref(), 1)? {
                // The fixed scenario of the row: exactly what an override of the keys flies.
                let cfg = d.config(0, 0).map_err(scenario_error)?;
                e = Cow::Owned(Engine::of_valid(cfg).map_err(scenario_error)?);
            }
        } else if !dispersion_keys.is_empty() || dispersion_values.is_some() {
            return Err(PyValueError::new_err(
                "dispersion_keys and dispersion_values go with xi (a flight driven by innovations)",
            ));
        } else if !e.cfg.dispersions.is_empty() {
            return Err(ScenarioError::new_err(format!(
                "simulate flies a fixed scenario, and this one disperses {:?}: the engine draws \
                 no parameter values; fly the fixed scenario of a realisation \
                 (Scenario.realisation, as quadrs.simulate does)",
                e.cfg.dispersions.keys().collect::<Vec<_>>()
            )));
        }
        if let Some(w) = wind {
            let w = w.as_array();
            if w.ncols() != 3 {
                return Err(PyValueError::new_err(format!(
                    "wind must have 3 columns (x, y, z), got shape {:?}",
                    w.shape()
                )));
            }
            let rows = w.rows().into_iter().map(|r| [r[0], r[1], r[2]]).collect();
            e = Cow::Owned(
                e.into_owned()
                    .with_wind(rows)
                    .map_err(PyValueError::new_err)?,
            );
        }
        let rows = (e.steps / record_every + 1) as u128;
        let width = 1 + e.trace_columns().len();
        memory::check(
            "trace (integrator.duration / integrator.dt / record_every rows)",
            rows * width as u128,
            8,
        )
        .and_then(|()| flight_memory(&e, 1, 1))
        .map_err(PyMemoryError::new_err)?;
        let cancel = progress.map(|p| p.get().cancel.clone());
        let xi: Option<Vec<f64>> = xi.map(|x| x.as_array().iter().copied().collect());
        if let Some(x) = &xi {
            check_innovations(&e, x.len())?;
        }
        let flown = py.detach(|| {
            guarded("simulate", || {
                let mut trace = e.trace(record_every);
                let indices = [realisation];
                let rows: Option<[&[f64]; 1]> = xi.as_deref().map(|x| [x]);
                let req = FlightRequest {
                    want_spectra: true,
                    cancel: cancel.as_deref(),
                    innovations: rows.as_ref().map(|r| &r[..]),
                    ..FlightRequest::new(kind, seed, &indices)
                };
                let res = e.fly::<f64>(&req, Some(&mut trace), &mut FftPlanner::new())?;
                Some((trace, res.into_iter().next().expect("one lane")))
            })
        })?;
        let Some((trace, res)) = flown else {
            return Err(PyKeyboardInterrupt::new_err("simulate was cancelled"));
        };
        let rows = trace.data.len() / width;
        let trace = Array2::from_shape_vec((rows, width), trace.data).expect("trace shape");
        let n_phase = res.metrics.len();
        let metrics =
            Array2::from_shape_vec((n_phase, N_METRICS), res.metrics.concat()).expect("shape");
        let d = PyDict::new(py);
        d.set_item("trace", trace.into_pyarray(py))?;
        d.set_item("metrics", metrics.into_pyarray(py))?;
        d.set_item("diverged_at", res.diverged_at)?;
        d.set_item("status", res.status.name())?;
        d.set_item("trace_columns", e.trace_columns())?;
        let spectra: Vec<_> = res
            .spectra
            .into_iter()
            .map(|s| s.into_pyarray(py))
            .collect();
        d.set_item("spectra", spectra)?;
        Ok(d)
    }

    /// xi must hold exactly the engine's innovations per flight.
    fn check_innovations(e: &Engine, len: usize) -> PyResult<()> {
        let want = e.innovations();
        if len != want {
            return Err(PyValueError::new_err(format!(
                "xi must hold {want} standard normals per flight (innovations_dimension), got {len}"
            )));
        }
        Ok(())
    }

    /// The per-row values of a dispersed scenario's keys for a flight driven by innovations
    /// (None for a fixed scenario). The engine draws no parameter values, so it refuses a
    /// dispersed scenario without them, keys other than exactly its dispersed ones, a table
    /// not of shape (rows, keys), a value the scenario refuses, and gust values that change
    /// the count of innovations (the standard-normal space must be the same for every row).
    fn innovations_dispersion(
        e: &Engine,
        keys: Vec<String>,
        values: Option<&Array2<f64>>,
        rows: usize,
    ) -> PyResult<Option<Dispersion>> {
        let dispersed: Vec<&String> = e.cfg.dispersions.keys().collect();
        let values = match (values, keys.is_empty()) {
            (None, true) if dispersed.is_empty() => return Ok(None),
            (None, true) => {
                return Err(ScenarioError::new_err(format!(
                    "the scenario disperses {dispersed:?}: a flight driven by innovations flies \
                     the values given for them (dispersion_keys, dispersion_values) and none \
                     were given; the engine draws no parameter values"
                )))
            }
            (Some(v), false) => v,
            _ => {
                return Err(PyValueError::new_err(
                    "dispersion_keys and dispersion_values go together",
                ))
            }
        };
        let mut sorted = keys.clone();
        sorted.sort();
        sorted.dedup();
        if sorted.len() != keys.len() || !sorted.iter().eq(dispersed.iter().copied()) {
            return Err(ScenarioError::new_err(format!(
                "dispersion_keys must be the scenario's dispersed keys {dispersed:?}, each once, \
                 got {keys:?}"
            )));
        }
        if values.shape() != [rows, keys.len()] {
            return Err(PyValueError::new_err(format!(
                "dispersion_values must have shape ({rows}, {}), got {:?}",
                keys.len(),
                values.shape()
            )));
        }
        let flat = values.iter().copied().collect();
        let d = Dispersion::new(&e.cfg, keys, flat, rows).map_err(scenario_error)?;
        let want = e.innovations();
        for j in 0..rows {
            let cfg = d.config(j, 0).map_err(scenario_error)?;
            if d.touches_wind() {
                let got = Realisation::new(&cfg)
                    .map_err(scenario_error)?
                    .wind()
                    .innovations(e.steps);
                if got != want {
                    return Err(ScenarioError::new_err(format!(
                        "dispersions: row {j}'s gust values change the flight's innovations \
                         from {want} to {got}; every row must be driven by the same standard \
                         normals (disperse only gust keys that keep the gust window and its \
                         filters)"
                    )));
                }
            }
        }
        Ok(Some(d))
    }

    /// The scenario's `[wind]` mean wind (m/s, inertial x, y, z) at each altitude in
    /// `altitudes` (m): W20 f(h) (cos chi, sin chi, 0), shape (n, 3).
    #[pyfunction]
    fn mean_wind<'py>(
        py: Python<'py>,
        config_json: &str,
        altitudes: PyReadonlyArray1<'py, f64>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let cfg = Config::from_json(config_json).map_err(scenario_error)?;
        let field = gust::WindField::new(&cfg).map_err(scenario_error)?;
        let h = altitudes.as_slice()?;
        let out = Array2::from_shape_fn((h.len(), 3), |(i, j)| field.mean_at(h[i])[j]);
        Ok(out.into_pyarray(py))
    }

    /// Low-altitude MIL-F-8785C intensities (m/s) and scale lengths (m) for
    /// [longitudinal, lateral, vertical], from altitude (m) and the wind at 20 ft (m/s).
    #[pyfunction]
    fn low_altitude_scales(altitude: f64, w20: f64) -> PyResult<([f64; 3], [f64; 3])> {
        if !(altitude.is_finite() && altitude > 0.0) {
            return Err(PyValueError::new_err(format!(
                "altitude must be > 0, got {altitude:?}"
            )));
        }
        if !(w20.is_finite() && w20 >= 0.0) {
            return Err(PyValueError::new_err(format!(
                "w20 must be >= 0, got {w20:?}"
            )));
        }
        Ok(gust::low_altitude_scales(altitude, w20))
    }

    /// The engine's lane-valued `function` ("exp", "expm1", "ln", "pow": x^y) of every `x`, on
    /// the lane path `path` ("scalar", "sse2", "avx2", "avx512"): for measuring their error
    /// and checking that every path gives the same bits (`benches/lane_math_error.py`).
    #[pyfunction]
    #[pyo3(signature = (function, x, path = "scalar", y = 0.0))]
    fn lane_math<'py>(
        py: Python<'py>,
        function: &str,
        x: PyReadonlyArray1<'py, f64>,
        path: &str,
        y: f64,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let out = crate::lane::explog::evaluate(function, path, x.as_slice()?, y)
            .map_err(PyValueError::new_err)?;
        Ok(out.into_pyarray(py))
    }

    type Array<'py> = Bound<'py, PyArray1<f64>>;

    /// The forming filter `gust_psd` and `gust_series` use, its model and component read
    /// through the scenario's own words (`GustModel`, `GustComponent`).
    fn gust_filter(
        model: &str,
        component: &str,
        sigma: f64,
        length_scale: f64,
        airspeed: f64,
        dt: f64,
    ) -> PyResult<gust::GustFilter> {
        let model: GustModel = model.parse().map_err(PyValueError::new_err)?;
        let component: GustComponent = component.parse().map_err(PyValueError::new_err)?;
        gust::GustFilter::new(model, component, sigma, length_scale, airspeed, dt)
            .map_err(PyValueError::new_err)
    }

    /// One-sided spectra ((m/s)^2/Hz) of one gust component at `frequency` (Hz): the spectrum
    /// the discretised forming filter realises (`filter`) and the formula it is built for
    /// (`target`: the Dryden PSD, or the exact von Karman PSD of MIL-F-8785C).
    #[pyfunction]
    #[allow(clippy::too_many_arguments)]
    fn gust_psd<'py>(
        py: Python<'py>,
        model: &str,
        component: &str,
        sigma: f64,
        length_scale: f64,
        airspeed: f64,
        dt: f64,
        frequency: PyReadonlyArray1<'py, f64>,
    ) -> PyResult<(Array<'py>, Array<'py>)> {
        let filter = gust_filter(model, component, sigma, length_scale, airspeed, dt)?;
        let f = frequency.as_array();
        if let Some(bad) = f.iter().find(|x| !(x.is_finite() && **x >= 0.0)) {
            return Err(PyValueError::new_err(format!(
                "frequency must be finite and >= 0 Hz, got {bad:?}"
            )));
        }
        let realised: Vec<f64> = f.iter().map(|&x| filter.psd(x)).collect();
        let target: Vec<f64> = f.iter().map(|&x| filter.target_psd(x)).collect();
        Ok((realised.into_pyarray(py), target.into_pyarray(py)))
    }

    /// `realisations` stationary series of one gust component, `steps` samples each, row r from
    /// the random stream (seed, first + r).
    #[pyfunction]
    #[allow(clippy::too_many_arguments)]
    fn gust_series<'py>(
        py: Python<'py>,
        model: &str,
        component: &str,
        sigma: f64,
        length_scale: f64,
        airspeed: f64,
        dt: f64,
        steps: usize,
        realisations: usize,
        seed: u64,
        first: u64,
        workers: usize,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let filter = gust_filter(model, component, sigma, length_scale, airspeed, dt)?;
        check_workers(workers)?;
        let len = (realisations as u128) * (steps as u128);
        let mut buf = usize::try_from(len)
            .map_err(|_| format!("gust samples (steps * realisations): {len} values"))
            .and_then(|len| memory::zeroed_vec("gust samples (steps * realisations)", len, 0.0))
            .map_err(PyMemoryError::new_err)?;
        py.detach(|| {
            guarded("gust_series", || {
                pool(workers).install(|| gust::fill_series(&filter, seed, first, steps, &mut buf))
            })
        })?;
        let out = Array2::from_shape_vec((realisations, steps), buf).expect("shape");
        Ok(out.into_pyarray(py))
    }

    /// Panic inside the engine (on a worker thread of the pool when `in_pool`): lets the tests
    /// prove that a Rust panic surfaces as EngineError and the process survives. Not public API.
    #[pyfunction]
    fn _panic_for_tests(py: Python<'_>, message: &str, in_pool: bool) -> PyResult<()> {
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

    /// Progress of a batch, shared between the polling Python thread and the workers.
    #[pyclass(frozen)]
    struct Progress {
        done: Arc<AtomicU64>,
        cancel: Arc<AtomicBool>,
    }

    #[pymethods]
    impl Progress {
        #[new]
        fn new() -> Self {
            Self {
                done: Arc::new(AtomicU64::new(0)),
                cancel: Arc::new(AtomicBool::new(false)),
            }
        }
        /// Realisations finished so far.
        fn done(&self) -> u64 {
            self.done.load(Ordering::Relaxed)
        }
        /// Ask the workers to stop; finished realisations are kept.
        fn cancel(&self) {
            self.cancel.store(true, Ordering::Relaxed)
        }
        fn cancelled(&self) -> bool {
            self.cancel.load(Ordering::Relaxed)
        }
    }
}
