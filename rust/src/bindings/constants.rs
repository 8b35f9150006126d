//! The module's constants: the metrics, scenario keys, controllers, models, state and trace
//! names, and exit statuses, each read from its one definition in the engine.

use crate::control::ControllerKind;
use crate::integrate::{trace_columns, ExitStatus};
use crate::metrics::{METRICS, METRIC_NAMES};
use crate::model::{state_vars, ActuatorKind, PayloadKind};
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// Add the constants to the module.
pub(super) fn add(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("METRIC_NAMES", METRIC_NAMES.to_vec())?;
    // The metrics of an event (NaN in a phase or flight without it), in METRIC_NAMES' order.
    let events: Vec<&str> = METRICS.iter().filter(|x| x.event).map(|x| x.name).collect();
    m.add("EVENT_METRICS", events)?;
    // Each metric's unit (SI, as stored) and plain-English label, from its one definition.
    let metrics = METRICS
        .iter()
        .map(|x| (x.name.to_string(), x.unit, x.label));
    add_units_and_labels(m, "METRIC", metrics)?;
    // The unit and label of every scenario key (dotted, indices dropped), from the
    // declaration beside its section's struct or in its kind's file (`config::params!`).
    let keys = crate::scenario::Config::keys()
        .into_iter()
        .map(|(key, k)| (key, k.unit, k.label));
    add_units_and_labels(m, "KEY", keys)?;
    // The pairs of keys that give one thing two ways: setting one replaces the other.
    m.add(
        "ONE_OF_KEYS",
        crate::scenario::Config::ONE_OF
            .iter()
            .map(|pair| (pair.keys[0], pair.keys[1]))
            .collect::<Vec<_>>(),
    )?;
    // Each controller kind's default table (JSON text), where it has one.
    let defaults = PyDict::new(m.py());
    for (name, table) in crate::scenario::ControllerConfig::default_tables() {
        if let Some(json) = table {
            defaults.set_item(name, json)?;
        }
    }
    m.add("CONTROLLER_DEFAULTS", defaults)?;
    // Hz, each law's own loop rates (position, attitude, inner; 0: every step) where the
    // scenario sets none (`Controller::RATES`).
    let rates = PyDict::new(m.py());
    for kind in ControllerKind::ALL {
        rates.set_item(kind.name(), kind.rates().to_vec())?;
    }
    m.add("CONTROLLER_RATES", rates)?;
    m.add("MAX_PERIOD_STEPS", crate::stability::MAX_PERIOD_STEPS)?;
    add_names(
        m,
        "CONTROLLER_LABELS",
        ControllerKind::ALL.iter().map(|k| k.label()),
    )?;
    add_names(
        m,
        "CONTROLLER_NAMES",
        ControllerKind::ALL.iter().map(|k| k.name()),
    )?;
    // The payload and actuator models (`payload.model`, `actuator.model`), registered once
    // (`model::kinds!`).
    add_names(
        m,
        "PAYLOAD_MODELS",
        crate::model::PAYLOAD_KINDS.iter().map(|k| k.name()),
    )?;
    add_names(
        m,
        "ACTUATOR_MODELS",
        crate::model::ACTUATOR_KINDS.iter().map(|k| k.name()),
    )?;
    // The bodies (`vehicle.body`).
    add_names(
        m,
        "BODY_MODELS",
        crate::model::BODY_MODELS.iter().map(|k| k.name()),
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
    Ok(())
}

/// `{prefix}_UNITS` and `{prefix}_LABELS`: dicts from each name to its unit and its label.
fn add_units_and_labels<'a, K: AsRef<str>>(
    m: &Bound<'_, PyModule>,
    prefix: &str,
    entries: impl Iterator<Item = (K, &'a str, &'a str)>,
) -> PyResult<()> {
    let units = PyDict::new(m.py());
    let labels = PyDict::new(m.py());
    for (name, unit, label) in entries {
        units.set_item(name.as_ref(), unit)?;
        labels.set_item(name.as_ref(), label)?;
    }
    m.add(format!("{prefix}_UNITS").as_str(), units)?;
    m.add(format!("{prefix}_LABELS").as_str(), labels)
}

/// A list of a registry's names (or labels) under `name`.
fn add_names<'a>(
    m: &Bound<'_, PyModule>,
    name: &str,
    names: impl Iterator<Item = &'a str>,
) -> PyResult<()> {
    m.add(name, names.collect::<Vec<_>>())
}
