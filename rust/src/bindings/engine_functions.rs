//! The module's engine functions: each is `Engine(config_json).<name>(*args, **kwargs)`, for a
//! caller with one call to make. The method is the one implementation: the function calls it,
//! and its signature is the method's, read from the method, with `config_json` first.

use super::engine::CompiledEngine;
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use pyo3::types::{PyCFunction, PyTuple};
use std::ffi::{CStr, CString};

/// The engine functions: each method's name and the summary its function's docstring gives
/// after the signature (pointing to the method).
const ENGINE_FUNCTIONS: [(&CStr, &str); 8] = [
    (c"simulate", "Engine(config_json).simulate(...): one flight, its trace, metrics and spectra."),
    (c"simulate_innovations", "Engine(config_json).simulate_innovations(...): one flight driven by given standard normals."),
    (c"run_batch", "Engine(config_json).run_batch(...): a Monte Carlo chunk."),
    (c"run_innovations", "Engine(config_json).run_innovations(...): one flight per row of standard normals."),
    (c"innovations", "Engine(config_json).innovations(...): the standard normals a seeded flight draws."),
    (c"innovations_dimension", "Engine(config_json).innovations_dimension(): standard normals per flight."),
    (c"stability", "Engine(config_json).stability(...): the closed-loop poles at hover."),
    (c"linearize", "Engine(config_json).linearize(...): the closed loop at hover as a state-space model."),
];

/// Add the engine functions to the module.
pub(super) fn add(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    let engine = py.get_type::<CompiledEngine>();
    for (name, summary) in ENGINE_FUNCTIONS {
        let method = name.to_str().expect("an ASCII name");
        // The method's `($self, a, b=1)` (or `($self)`): the function's is `(config_json, a, b=1)`.
        let signature: String = engine
            .getattr(method)?
            .getattr("__text_signature__")?
            .extract()?;
        let params = signature
            .strip_prefix("($self")
            .and_then(|s| s.strip_suffix(')'))
            .expect("a method's text signature");
        let doc = format!("{method}(config_json{params})\n--\n\n{summary}");
        // Built once, when the module is, and kept as long as the function (the process).
        let doc: &'static CStr = Box::leak(CString::new(doc)?.into_boxed_c_str());
        m.add_function(engine_function(py, name, doc)?)?;
    }
    Ok(())
}

/// One of `ENGINE_FUNCTIONS` as a Python function of `config_json` (first, or by keyword) and
/// the method's arguments.
fn engine_function<'py>(
    py: Python<'py>,
    name: &'static CStr,
    doc: &'static CStr,
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
                    .ok_or_else(|| PyTypeError::new_err(format!("{method}() needs config_json")))?;
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
