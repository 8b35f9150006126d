//! The wind and the gust filters on their own: the mean wind, the MIL-F-8785C scales, and a
//! forming filter's spectra and series.

use super::checks::check_workers;
use super::errors::{guarded, scenario_error};
use crate::gust;
use crate::memory;
use crate::montecarlo::pool;
use crate::scenario::Config;
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray1, PyArray2, PyReadonlyArray1};
use pyo3::exceptions::{PyMemoryError, PyValueError};
use pyo3::prelude::*;

/// The scenario's `[wind]` mean wind (m/s, inertial x, y, z) at each altitude in
/// `altitudes` (m): W20 f(h) (cos chi, sin chi, 0), shape (n, 3).
#[pyfunction]
pub(super) fn mean_wind<'py>(
    py: Python<'py>,
    config_json: &str,
    altitudes: PyReadonlyArray1<'py, f64>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let cfg = Config::from_json(config_json).map_err(scenario_error)?;
    let field = gust::WindField::new(&cfg.wind_context()).map_err(scenario_error)?;
    let h = altitudes.as_slice()?;
    let out = Array2::from_shape_fn((h.len(), 3), |(i, j)| field.mean_at(h[i])[j]);
    Ok(out.into_pyarray(py))
}

/// Low-altitude MIL-F-8785C intensities (m/s) and scale lengths (m) for
/// [longitudinal, lateral, vertical], from altitude (m) and the wind at 20 ft (m/s).
#[pyfunction]
pub(super) fn low_altitude_scales(altitude: f64, w20: f64) -> PyResult<([f64; 3], [f64; 3])> {
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

type Array<'py> = Bound<'py, PyArray1<f64>>;

/// A forming filter's numbers as `gust_psd` and `gust_series` take them, in one tuple:
/// (model, component, sigma, length_scale, airspeed, dt), the model and component in the
/// scenario's words (`GustModel`, `GustComponent`).
#[derive(FromPyObject)]
pub(super) struct FilterArgs(String, String, f64, f64, f64, f64);

impl FilterArgs {
    /// The filter these numbers build.
    fn build(self) -> PyResult<gust::GustFilter> {
        let FilterArgs(model, component, sigma, length_scale, airspeed, dt) = self;
        gust::GustFilter::new(gust::GustSpec {
            model: model.parse().map_err(PyValueError::new_err)?,
            component: component.parse().map_err(PyValueError::new_err)?,
            sigma,
            length_scale,
            airspeed,
            dt,
        })
        .map_err(PyValueError::new_err)
    }
}

/// One-sided spectra ((m/s)^2/Hz) of one gust component at `frequency` (Hz): the spectrum
/// the discretised forming filter realises (`filter`) and the formula it is built for
/// (`target`: the Dryden PSD, or the exact von Karman PSD of MIL-F-8785C).
#[pyfunction]
pub(super) fn gust_psd<'py>(
    py: Python<'py>,
    spec: FilterArgs,
    frequency: PyReadonlyArray1<'py, f64>,
) -> PyResult<(Array<'py>, Array<'py>)> {
    let filter = spec.build()?;
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
pub(super) fn gust_series<'py>(
    py: Python<'py>,
    spec: FilterArgs,
    steps: usize,
    realisations: usize,
    seed: u64,
    first: u64,
    workers: usize,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let filter = spec.build()?;
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
