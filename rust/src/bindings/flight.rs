//! One flight (`simulate`, `simulate_innovations`): its trace, metrics and spectra; and the
//! scenario values a flight driven by given standard normals flies.

use super::checks::{check_innovations, flight_memory};
use super::errors::{guarded, scenario_error, ScenarioError};
use super::progress::Progress;
use crate::control::ControllerKind;
use crate::dispersion::Dispersion;
use crate::integrate::{Engine, FlightRequest, Realisation};
use crate::memory;
use crate::metrics::N_METRICS;
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray2, PyReadonlyArray1, PyReadonlyArray2};
use pyo3::exceptions::{PyKeyboardInterrupt, PyMemoryError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rustfft::FftPlanner;
use std::borrow::Cow;

/// What `simulate` flies, besides the scenario: the law, the stream and the record, and the
/// inputs that replace the scenario's own (`simulate`'s `wind`, `xi` and dispersion values).
pub(super) struct Flight<'a, 'py> {
    pub(super) controller: &'a str,
    pub(super) seed: u64,
    pub(super) realisation: u64,
    pub(super) record_every: usize,
    pub(super) wind: Option<PyReadonlyArray2<'py, f64>>,
    pub(super) progress: Option<&'a Bound<'py, Progress>>,
    pub(super) xi: Option<PyReadonlyArray1<'py, f64>>,
    pub(super) dispersion_keys: Vec<String>,
    pub(super) dispersion_values: Option<PyReadonlyArray1<'py, f64>>,
}

pub(super) fn simulate_on<'py>(
    py: Python<'py>,
    mut e: Cow<'_, Engine>,
    f: Flight<'_, 'py>,
) -> PyResult<Bound<'py, PyDict>> {
    let kind = ControllerKind::parse(f.controller).map_err(PyValueError::new_err)?;
    if f.record_every == 0 {
        return Err(PyValueError::new_err("record_every must be >= 1, got 0"));
    }
    if f.xi.is_some() {
        let values = f.dispersion_values.map(|v| {
            let v: Vec<f64> = v.as_array().iter().copied().collect();
            Array2::from_shape_vec((1, v.len()), v).expect("one row")
        });
        if let Some(d) = innovations_dispersion(&e, f.dispersion_keys, values.as_ref(), 1)? {
            // The fixed scenario of the row: exactly what an override of the keys flies.
            let cfg = d.config(0, 0).map_err(scenario_error)?;
            e = Cow::Owned(Engine::of_valid(cfg).map_err(scenario_error)?);
        }
    } else if !f.dispersion_keys.is_empty() || f.dispersion_values.is_some() {
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
    if let Some(w) = f.wind {
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
    e.check_start(kind).map_err(scenario_error)?;
    let rows = (e.steps / f.record_every + 1) as u128;
    let width = 1 + e.trace_columns().len();
    memory::check(
        "trace (integrator.duration / integrator.dt / record_every rows)",
        rows * width as u128,
        8,
    )
    .and_then(|()| flight_memory(&e, 1, 1))
    .map_err(PyMemoryError::new_err)?;
    let cancel = f.progress.map(|p| p.get().cancel.clone());
    let xi: Option<Vec<f64>> = f.xi.map(|x| x.as_array().iter().copied().collect());
    if let Some(x) = &xi {
        check_innovations(&e, x.len())?;
    }
    let flown = py.detach(|| {
        guarded("simulate", || {
            let mut trace = e.trace(f.record_every);
            let indices = [f.realisation];
            let rows: Option<[&[f64]; 1]> = xi.as_deref().map(|x| [x]);
            let req = FlightRequest {
                want_spectra: true,
                cancel: cancel.as_deref(),
                innovations: rows.as_ref().map(|r| &r[..]),
                ..FlightRequest::new(kind, f.seed, &indices)
            };
            let res = e.fly::<f64>(&req, Some(&mut trace), &mut FftPlanner::new())?;
            Some((trace, res.into_iter().next().expect("one lane")))
        })
    })?;
    let Some((trace, res)) = flown else {
        return Err(PyKeyboardInterrupt::new_err("simulate was cancelled"));
    };
    let rows = trace.data.len() / width;
    let navigation = trace
        .navigation
        .map(|r| navigation_record(py, r))
        .transpose()?;
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
    d.set_item("navigation", navigation)?;
    Ok(d)
}

/// The navigation's record as arrays (`NavigationRecord`): what a test's own filter reads.
fn navigation_record<'py>(
    py: Python<'py>,
    r: crate::navigation::NavigationRecord,
) -> PyResult<Bound<'py, PyDict>> {
    fn rows<const W: usize>(py: Python<'_>, x: Vec<[f64; W]>) -> Bound<'_, PyArray2<f64>> {
        let n = x.len();
        Array2::from_shape_vec((n, W), x.concat())
            .expect("rows of W")
            .into_pyarray(py)
    }
    let d = PyDict::new(py);
    d.set_item("imu", rows(py, r.imu))?;
    d.set_item("gnss", rows(py, r.gnss))?;
    d.set_item("baro", rows(py, r.baro))?;
    d.set_item("heading", rows(py, r.heading))?;
    d.set_item("initial", r.initial.into_pyarray(py))?;
    d.set_item("state", r.state.into_pyarray(py))?;
    d.set_item("covariance", r.covariance.into_pyarray(py))?;
    d.set_item("truth", r.truth.into_pyarray(py))?;
    Ok(d)
}

/// The per-row values of a dispersed scenario's keys for a flight driven by innovations
/// (None for a fixed scenario). The engine draws no parameter values, so it refuses a
/// dispersed scenario without them, keys other than exactly its dispersed ones, a table
/// not of shape (rows, keys), a value the scenario refuses, and gust values that change
/// the count of innovations (the standard-normal space must be the same for every row).
pub(super) fn innovations_dispersion(
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
            // (no law's start: only the wind's innovations are compared)
            let got = Realisation::for_laws(&cfg, None, &[])
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
