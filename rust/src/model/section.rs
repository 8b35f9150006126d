//! A section of the scenario that a family of kinds shares (`[payload]`, `[actuator]`): one flat
//! table holding the keys every kind of the family has (`model`, the payload's `mass`, ...,
//! declared as `Shared` in `payload::shared` and `actuator::shared`) and the keys each kind owns
//! (the cable's `cable_length`, the rotors' `thrust_max`), declared in the kind's own file
//! (`payload::cable`, `actuator::rotors`). `model::kinds!` assembles the section's struct from
//! the registration; this file holds what its reading needs, and `ModelContext`, what a kind is
//! built and checked from.
//!
//! The table is read key by key, each value as its owner's field type where it stands, so that
//! serde_path_to_error names the dotted key of a mistyped value (`payload.cable_length`) and an
//! unknown key is refused with the section's every key, as `deny_unknown_fields` words it. Each
//! owner's keys are then read into its struct, which fills its defaults.

use super::{ActuatorConfig, PayloadConfig};
use crate::config::params::{Key, Params};
use crate::config::{ConfigError, Context};
use serde::de::{self, DeserializeOwned, DeserializeSeed, Visitor};
use std::fmt;

/// A kind that owns keys of its family's flat section (a payload kind's of `[payload]`, an
/// actuator kind's of `[actuator]`): declared in the kind's file, checked there.
pub trait OwnsKeys {
    /// The kind's own keys, beside the family's shared ones; every one optional or defaulted,
    /// since the table of a scenario flying another kind of the family leaves them out.
    type Params: Params + Clone + fmt::Debug + serde::Serialize + DeserializeOwned;

    /// Check the kind's keys (`flown`: this kind is the section's `model`); messages name each
    /// key dotted under the section (`payload.cable_length`).
    fn validate(_p: &Self::Params, _flown: bool, _cfg: &ModelContext) -> Result<(), ConfigError> {
        Ok(())
    }

    /// The kind's dotted keys with their units and labels, under `prefix` (the section's name).
    fn keys(prefix: &str) -> Vec<(String, Key)> {
        Self::Params::keys_under(prefix)
    }
}

/// A key of a section: one of its owners' keys (each owner's `Params::KEYS`), refused otherwise.
pub struct KnownKey<'a>(pub &'a [&'static [Key]]);

impl KnownKey<'_> {
    fn names(&self) -> impl Iterator<Item = &'static str> + '_ {
        self.0.iter().flat_map(|keys| keys.iter().map(|k| k.name))
    }
}

impl<'de> DeserializeSeed<'de> for KnownKey<'_> {
    type Value = String;

    fn deserialize<D: de::Deserializer<'de>>(self, d: D) -> Result<String, D::Error> {
        d.deserialize_str(self)
    }
}

impl<'de> Visitor<'de> for KnownKey<'_> {
    type Value = String;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("a key")
    }

    fn visit_str<E: de::Error>(self, key: &str) -> Result<String, E> {
        if self.names().any(|name| name == key) {
            return Ok(key.to_string());
        }
        // serde's own words for an unknown field, so a message reads the same in every table.
        let names: Vec<String> = self.names().map(|name| format!("`{name}`")).collect();
        let expected = match names.as_slice() {
            [] => "there are no fields".to_string(),
            [one] => format!("expected {one}"),
            [a, b] => format!("expected {a} or {b}"),
            _ => format!("expected one of {}", names.join(", ")),
        };
        Err(E::custom(format_args!("unknown field `{key}`, {expected}")))
    }
}

/// One owner's keys, read into its struct (its defaults filled, a missing key named).
pub fn part<T: DeserializeOwned, E: de::Error>(
    keys: serde_json::Map<String, serde_json::Value>,
) -> Result<T, E> {
    serde_json::from_value(serde_json::Value::Object(keys)).map_err(E::custom)
}

/// The first key two owners of a section both declare (a flat table cannot tell them apart).
pub fn shared_key(owners: &[&'static [Key]]) -> Option<&'static str> {
    let mut seen = std::collections::BTreeSet::new();
    owners
        .iter()
        .flat_map(|keys| keys.iter())
        .find(|k| !seen.insert(k.name))
        .map(|k| k.name)
}

/// What a payload or actuator kind is built and checked from: the sections below the kinds
/// (`config::Context`, read through it as `cfg.vehicle`, `cfg.integrator`) and the two
/// families' own sections. The controllers build on it (`control::ControlContext`).
#[derive(Debug, Clone, Copy)]
pub struct ModelContext<'a> {
    pub sections: Context<'a>,
    pub payload: &'a PayloadConfig,
    pub actuator: &'a ActuatorConfig,
}

crate::config::reads_through!(ModelContext => sections: Context);

impl ModelContext<'_> {
    /// kc in N/m, from whichever of stiffness / natural frequency was given.
    pub fn stiffness(&self) -> f64 {
        match (self.payload.stiffness, self.payload.natural_frequency) {
            (Some(k), _) => k,
            (None, Some(fn_hz)) => self.payload.mass * (2.0 * std::f64::consts::PI * fn_hz).powi(2),
            (None, None) => f64::NAN, // rejected by validate()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::shared_key;
    use crate::model::{ActuatorConfig, ActuatorKind, PayloadConfig, PayloadKind};
    use crate::model::{ACTUATOR_KINDS, PAYLOAD_KINDS};
    use crate::scenario::tests::{paper, with};
    use serde_json::json;

    #[test]
    fn no_two_owners_of_a_section_declare_the_same_key() {
        assert_eq!(shared_key(PayloadConfig::OWNERS), None);
        assert_eq!(shared_key(ActuatorConfig::OWNERS), None);
        assert_eq!(shared_key(&[&[], &[]]), None);
        // It finds one: the keys of one owner declared twice.
        let shared = <crate::model::payload::Shared as crate::config::params::Params>::KEYS;
        assert_eq!(shared_key(&[shared, &[], shared]), Some("model"));
    }

    #[test]
    fn a_section_is_every_owners_keys_in_one_flat_table() {
        let keys: Vec<String> = PayloadConfig::keys().into_iter().map(|(k, _)| k).collect();
        assert_eq!(
            keys,
            [
                "payload.model",
                "payload.mass",
                "payload.natural_frequency",
                "payload.stiffness",
                "payload.damping",
                "payload.drag_area",
                "payload.cable_length",
                "payload.attachment_offset",
                "payload.winch_speed",
                "payload.winch_acceleration",
                "payload.length_min",
                "payload.release",
                "payload.release_delay",
                "payload.approach_height",
                "payload.approach_speed",
                "payload.slack_tension",
                "payload.tension_noise",
                "payload.release_after",
            ]
        );
        let keys: Vec<String> = ActuatorConfig::keys().into_iter().map(|(k, _)| k).collect();
        assert!(keys.starts_with(&["actuator.model".into(), "actuator.layout".into()]));
        assert!(
            keys.contains(&"actuator.faults.thrust_fraction".into()),
            "{keys:?}"
        );
        // Written back as one flat table, the kinds' keys beside the shared ones.
        let mut c = paper();
        c.payload.model = PayloadKind::Cable;
        c.payload.cable.cable_length = Some(1.5);
        let v = serde_json::to_value(&c).unwrap();
        assert_eq!(v["payload"]["cable_length"], json!(1.5));
        assert_eq!(v["payload"]["model"], json!("cable"));
        assert_eq!(v["actuator"]["thrust_max"], json!(12.0));
        let again: crate::scenario::Config = serde_json::from_value(v.clone()).unwrap();
        assert_eq!(serde_json::to_value(&again).unwrap(), v);
    }

    #[test]
    fn every_kind_reads_from_a_table_that_names_only_it() {
        let actuator = ActuatorConfig::from_empty().expect("every actuator key has a default");
        assert_eq!(actuator.model, ActuatorKind::Ideal);
        for kind in ACTUATOR_KINDS {
            assert_eq!(serde_json::to_value(kind).unwrap(), json!(kind.name()));
            let a: ActuatorConfig = serde_json::from_value(json!({"model": kind.name()})).unwrap();
            assert_eq!(a.model, *kind);
        }
        for kind in PAYLOAD_KINDS {
            assert_eq!(serde_json::to_value(kind).unwrap(), json!(kind.name()));
            let p: PayloadConfig = serde_json::from_value(json!({
                "model": kind.name(), "mass": 0.2, "stiffness": 30.0, "damping": 0.1,
                "drag_area": 0.0,
            }))
            .unwrap();
            assert_eq!(p.model, *kind);
        }
    }

    #[test]
    fn a_kinds_key_is_read_and_checked_where_it_stands() {
        // Mistyped: named by its dotted key, as serde_path_to_error gives it.
        let e = with(|v| v["payload"]["cable_length"] = "long".into()).unwrap_err();
        assert_eq!(e.key, "payload.cable_length");
        assert_eq!(
            e.message,
            "payload.cable_length: invalid type: string \"long\", expected f64"
        );
        let e =
            with(|v| v["actuator"] = json!({"faults": [{"rotor": 1, "start": "x"}]})).unwrap_err();
        assert_eq!(e.key, "actuator.faults[0].start");
        // Unknown: refused with every key of the section, in serde's words.
        let e = with(|v| v["payload"]["colour"] = "red".into()).unwrap_err();
        assert_eq!(e.key, "payload.colour");
        assert!(
            e.message.ends_with(
                "unknown field `colour`, expected one of `model`, `mass`, `natural_frequency`, \
                 `stiffness`, `damping`, `drag_area`, `cable_length`, `attachment_offset`, \
                 `winch_speed`, `winch_acceleration`, `length_min`, `release`, `release_delay`, \
                 `approach_height`, `approach_speed`, `slack_tension`, `tension_noise`, \
                 `release_after`"
            ),
            "{e}"
        );
        // A shared key left out is named at the table.
        let e = with(|v| {
            v["payload"].as_object_mut().unwrap().remove("mass");
        })
        .unwrap_err();
        assert_eq!(
            (e.key.as_str(), e.message.as_str()),
            ("payload", "payload: missing field `mass`")
        );
        // A kind's keys with another kind flying: the cable's refused, the rotors' checked.
        let e = with(|v| v["payload"]["cable_length"] = 1.0.into()).unwrap_err();
        assert_eq!(e.key, "payload.cable_length");
        assert!(e.message.contains("with payload.model = \"spring\""), "{e}");
        with(|v| v["actuator"] = json!({"model": "ideal", "thrust_max": 30.0}))
            .expect("the rotors' keys with the ideal actuators");
        let e =
            with(|v| v["actuator"] = json!({"model": "ideal", "thrust_max": -1.0})).unwrap_err();
        assert_eq!(e.key, "actuator.thrust_max");
        let e = with(|v| v["actuator"] = json!({"model": "jets"})).unwrap_err();
        assert_eq!(e.key, "actuator.model");
        assert!(e.message.contains("expected `ideal` or `rotors`"), "{e}");
    }
}
