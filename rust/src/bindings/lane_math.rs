//! The instruction set the engine runs on, and its lane-valued functions for measurement.

use super::checks::isa;
use numpy::{IntoPyArray, PyArray1, PyReadonlyArray1};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

/// The instruction set the engine's hot loop uses on this machine ("avx512", "avx2" or
/// "baseline"), chosen at run time; QUADRS_SIMD=baseline|avx2|avx512 forces one (an error
/// if this CPU cannot run it). Every path gives bit-identical results in the default mode.
#[pyfunction]
pub(super) fn simd_path() -> PyResult<&'static str> {
    isa().map(|i| i.name())
}

/// Realisations the batch path flies at once per worker on `simd_path()` (8 on AVX-512, else
/// 4): a calibration that is to time the machine flies at least one such set per worker.
#[pyfunction]
pub(super) fn lanes_per_set() -> PyResult<usize> {
    isa().map(|i| i.lane_count())
}

/// The engine's lane-valued `function` ("exp", "expm1", "ln", "pow": x^y, "atan2": the angle
/// of the point (y, x), as `math.atan2(x, y)`; "expm1_near0" and "tail3_near0", e^x - 1 - x -
/// x^2/2: the short series for |x| <= 1/32 the turbulence filters use) of every `x`, on
/// the lane path `path` ("scalar", "sse2", "avx2", "avx512"): for measuring their error
/// and checking that every path gives the same bits (`benches/lane_math_error.py`).
#[pyfunction]
#[pyo3(signature = (function, x, path = "scalar", y = 0.0))]
pub(super) fn lane_math<'py>(
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
