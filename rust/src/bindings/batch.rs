//! Many flights at once: a Monte Carlo chunk (`run_batch`) and one flight per row of given
//! standard normals (`run_innovations`), on a pool of worker threads.

use super::checks::{
    check_innovations, check_workers, controllers as controller_kinds, flight_memory,
};
use super::errors::{guarded, scenario_error};
use super::flight::innovations_dispersion;
use super::progress::{counters, Progress};
use crate::control::ControllerKind;
use crate::dispersion::Dispersion;
use crate::integrate::Engine;
use crate::memory;
use crate::metrics::N_METRICS;
use crate::montecarlo::{pool, run_batch as batch, run_innovations as innovations_batch, Batch};
use numpy::ndarray::{Array1, Array2, Array4};
use numpy::{IntoPyArray, PyArray3, PyReadonlyArray1, PyReadonlyArray2};
use pyo3::exceptions::{PyKeyboardInterrupt, PyMemoryError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::borrow::Cow;

/// `Engine.run_batch`'s arguments as Python gives them (the method says what each is).
pub(super) struct BatchArgs<'a, 'py> {
    pub controllers: Vec<String>,
    pub seed: u64,
    pub first: u64,
    pub count: usize,
    pub workers: usize,
    pub spectra: bool,
    pub progress: Option<&'a Bound<'py, Progress>>,
    pub dispersion_keys: Vec<String>,
    pub dispersion_values: Option<PyReadonlyArray2<'py, f64>>,
    pub streams: Option<PyReadonlyArray1<'py, u64>>,
    pub fused: bool,
}

/// `Engine.run_batch`: realisations first..first+count of every controller.
pub(super) fn run_batch<'py>(
    py: Python<'py>,
    engine: &Engine,
    args: BatchArgs<'_, 'py>,
) -> PyResult<Bound<'py, PyDict>> {
    let e = Cow::Borrowed(engine);
    let kinds = controller_kinds(&args.controllers)?;
    for &kind in &kinds {
        e.check_start(kind).map_err(scenario_error)?;
    }
    if args.count == 0 {
        return Err(PyValueError::new_err("runs must be >= 1, got 0"));
    }
    check_workers(args.workers)?;
    let e = match args.fused {
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
        args.count as u128 * (row + kinds.len() + 1) as u128,
        8,
    )
    .and_then(|()| flight_memory(&e, e.lanes_per_set(), args.workers))
    .map_err(PyMemoryError::new_err)?;
    let dispersion = match (args.dispersion_keys.is_empty(), args.dispersion_values) {
        (true, None) => None,
        (false, Some(v)) => {
            let v = v.as_array();
            let shape = v.shape();
            if shape != [args.count, args.dispersion_keys.len()] {
                return Err(PyValueError::new_err(format!(
                    "dispersion_values must have shape ({}, {}), got {shape:?}",
                    args.count,
                    args.dispersion_keys.len()
                )));
            }
            let values = v.iter().copied().collect();
            Some(
                Dispersion::new(&e.cfg, args.dispersion_keys, values, args.count)
                    .map_err(scenario_error)?,
            )
        }
        _ => {
            return Err(PyValueError::new_err(
                "dispersion_keys and dispersion_values go together",
            ))
        }
    };
    let streams: Option<Vec<u64>> = args.streams.map(|s| s.as_array().iter().copied().collect());
    let b = Batch {
        want_spectra: args.spectra,
        dispersion: dispersion.as_ref(),
        streams: streams.as_deref(),
        ..Batch::new(&kinds, args.seed, args.first, args.count)
    };
    let (done, cancel) = counters(args.progress);
    let out = py.detach(|| {
        guarded("run_batch", || {
            pool(args.workers).install(|| {
                b.check()?;
                Ok(batch(&e, &b, &done, &cancel))
            })
        })
    })?;
    let out = out.map_err(scenario_error)?;
    if let Some(e) = out.refused {
        return Err(scenario_error(e));
    }
    let n_ctrl = kinds.len();
    let n_phase = e.phase_count();
    let d = PyDict::new(py);
    let metrics = Array4::from_shape_vec((args.count, n_ctrl, n_phase, N_METRICS), out.metrics)
        .expect("metrics shape");
    d.set_item("metrics", metrics.into_pyarray(py))?;
    let diverged = Array2::from_shape_vec((args.count, n_ctrl), out.diverged_at).expect("shape");
    d.set_item("diverged_at", diverged.into_pyarray(py))?;
    let status = Array2::from_shape_vec((args.count, n_ctrl), out.status).expect("shape");
    d.set_item("status", status.into_pyarray(py))?;
    d.set_item("done", Array1::from_vec(out.done).into_pyarray(py))?;
    if args.spectra {
        // Per phase: (n_ctrl, bins) arrays of the ensemble sum and sum of squares.
        let per_phase = |src: &Vec<Vec<Vec<f64>>>| -> Vec<Bound<'py, numpy::PyArray2<f64>>> {
            (0..n_phase)
                .map(|p| {
                    let bins = src.first().map_or(0, |c| c[p].len());
                    let flat: Vec<f64> = src.iter().flat_map(|c| c[p].iter().copied()).collect();
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

/// `Engine.run_innovations`' arguments as Python gives them (the method says what each is).
pub(super) struct InnovationsArgs<'a, 'py> {
    pub controller: &'a str,
    pub xi: PyReadonlyArray2<'py, f64>,
    pub progress: Option<&'a Bound<'py, Progress>>,
    pub workers: Option<usize>,
    pub dispersion_keys: Vec<String>,
    pub dispersion_values: Option<PyReadonlyArray2<'py, f64>>,
}

/// `Engine.run_innovations`: one flight of `controller` per row of `xi`.
pub(super) fn run_innovations<'py>(
    py: Python<'py>,
    engine: &Engine,
    args: InnovationsArgs<'_, 'py>,
) -> PyResult<Bound<'py, PyArray3<f64>>> {
    let e = engine;
    use numpy::ndarray::Array3;
    let kind = ControllerKind::parse(args.controller).map_err(PyValueError::new_err)?;
    e.check_start(kind).map_err(scenario_error)?;
    let xi = args.xi.as_array();
    let (n, dim) = (xi.nrows(), xi.ncols());
    check_innovations(e, dim)?;
    let values = args.dispersion_values.map(|v| v.as_array().to_owned());
    let dispersion = innovations_dispersion(e, args.dispersion_keys, values.as_ref(), n)?;
    let workers = args
        .workers
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    check_workers(workers)?;
    let rows: Vec<&[f64]> = match xi.as_slice() {
        Some(flat) if dim > 0 => flat.chunks(dim).collect(),
        Some(_) => vec![&[][..]; n],
        None => return Err(PyValueError::new_err("xi must be C-contiguous")),
    };
    let n_phase = e.phase_count();
    let (done, cancel) = counters(args.progress);
    let flown = py
        .detach(|| {
            guarded("run_innovations", || {
                innovations_batch(e, kind, &rows, dispersion.as_ref(), workers, &done, &cancel)
            })
        })?
        .map_err(scenario_error)?;
    let Some(metrics) = flown else {
        return Err(PyKeyboardInterrupt::new_err(
            "run_innovations was cancelled",
        ));
    };
    Ok(Array3::from_shape_vec((n, n_phase, N_METRICS), metrics)
        .expect("shape")
        .into_pyarray(py))
}
