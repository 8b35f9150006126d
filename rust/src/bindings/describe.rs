//! A scenario's derived quantities, without building an engine.

use super::checks::isa;
use super::errors::scenario_error;
use crate::gust;
use crate::integrate::trace_columns;
use crate::model::state_vars;
use crate::scenario::Config;
use numpy::{IntoPyArray, PyArray1};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

/// Validate a scenario; return the quantities derived from it. Cheap: builds no engine (no
/// gust filters).
#[pyfunction]
pub(super) fn describe<'py>(py: Python<'py>, config_json: &str) -> PyResult<Bound<'py, PyDict>> {
    isa()?;
    let cfg = Config::from_json(config_json).map_err(scenario_error)?;
    gust::WindField::check(&cfg.wind_context()).map_err(scenario_error)?;
    let d = PyDict::new(py);
    d.set_item("stiffness", cfg.stiffness())?;
    d.set_item(
        "hover_offset",
        crate::model::hover_drop(&cfg.model_context()),
    )?;
    d.set_item("steps", cfg.steps())?;
    d.set_item("turbulence_w20", cfg.turbulence_w20())?;
    d.set_item("phases", crate::trajectory::phase_names(&cfg.context()))?;
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
    for s in crate::config::route::schedule(&cfg.context()).map_err(scenario_error)? {
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
        &crate::trajectory::phase_steps(&cfg.context()),
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
