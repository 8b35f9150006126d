//! The closed loop at hover (rust/src/stability.rs) as Python dicts: its poles and verdict,
//! and its linearisation.

use super::errors::guarded;
use crate::control::ControllerKind;
use crate::integrate::Engine;
use numpy::ndarray::{Array1, Array2};
use numpy::IntoPyArray;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// `Engine.stability`: the poles of `controller`'s closed loop at hover and the verdict.
pub(super) fn stability<'py>(
    py: Python<'py>,
    engine: &Engine,
    controller: &str,
) -> PyResult<Bound<'py, PyDict>> {
    let kind = ControllerKind::parse(controller).map_err(PyValueError::new_err)?;
    let cfg = &engine.cfg;
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
    // s: the period of the discrete-time model of a law at rates; None: continuous.
    d.set_item("period", a.period)?;
    // s: the loops' common period where too long to model sampled (the poles continuous).
    d.set_item("unmodelled_period", a.unmodelled_period)?;
    Ok(d)
}

/// `Engine.linearize`: `controller`'s closed loop linearised at hover in the steady `wind`.
pub(super) fn linearize<'py>(
    py: Python<'py>,
    engine: &Engine,
    controller: &str,
    wind: [f64; 3],
) -> PyResult<Bound<'py, PyDict>> {
    let kind = ControllerKind::parse(controller).map_err(PyValueError::new_err)?;
    let cfg = &engine.cfg;
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
