//! A table's own parameters (a controller kind's gains, a section of the scenario such as
//! `[vehicle]`): one `params!` declaration in the table's file gives the serde struct (unknown
//! keys refused, so a misspelt key is named), its dotted keys with their units and labels
//! (`Params::KEYS`, which reach Python through `_core.KEY_UNITS` and `_core.KEY_LABELS`), and
//! the typed targets a dispersion, a sweep or an optimisation sets (`Params::target`: a key's
//! path, `Seg`s, to what it names, a `Target`) and the simple bounds its keys declare
//! (`Params::check_bounds`). `keys` reads whole dotted keys with these; this file names no other
//! of `config`'s modules but `ConfigError` and its three checks.

use super::ConfigError;
use serde::{Deserialize, Serialize};
use std::fmt;

/// One step of a dotted key: a table field or an array index.
#[derive(Debug, Clone, PartialEq)]
pub enum Seg {
    Field(String),
    Index(usize),
}

/// What a parsed key names in a scenario.
pub enum Target<'c> {
    /// A number (an optional one that is set counts; one that is unset does not exist).
    Number(&'c mut f64),
    /// A key that exists but holds no number (a flag, a name, a list of names).
    NotNumber,
    /// No such key in this scenario.
    Missing,
}

/// A key a kind owns: its name inside the kind's table, its unit (SI; "-" for none) and a
/// plain-English label (no unit).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Key {
    pub name: &'static str,
    pub unit: &'static str,
    pub label: &'static str,
}

/// A value a key may hold, as a typed target (`Config::target`).
pub trait Field {
    fn target(&mut self, rest: &[Seg]) -> Target<'_>;
}

impl Field for f64 {
    fn target(&mut self, rest: &[Seg]) -> Target<'_> {
        if rest.is_empty() {
            Target::Number(self)
        } else {
            Target::Missing
        }
    }
}

/// A fixed-length row of numbers (`[x, y, z]`, a waypoint's five): each element a number.
impl<const N: usize> Field for [f64; N] {
    fn target(&mut self, rest: &[Seg]) -> Target<'_> {
        match rest {
            [Seg::Index(i)] if *i < N => Target::Number(&mut self[*i]),
            [] => Target::NotNumber,
            _ => Target::Missing,
        }
    }
}

/// An optional value exists as a key only when it is set.
impl<T: Field> Field for Option<T> {
    fn target(&mut self, rest: &[Seg]) -> Target<'_> {
        match self {
            Some(x) => x.target(rest),
            None => Target::Missing,
        }
    }
}

/// A list (of rows, names or tables): the list itself holds no number; an entry is a key while
/// its index is in the list.
impl<T: Field> Field for Vec<T> {
    fn target(&mut self, rest: &[Seg]) -> Target<'_> {
        match rest {
            [] => Target::NotNumber,
            [Seg::Index(i), tail @ ..] if *i < self.len() => self[*i].target(tail),
            _ => Target::Missing,
        }
    }
}

/// The target of a key that holds no number (then `rest` must be empty).
pub fn not_number(rest: &[Seg]) -> Target<'static> {
    if rest.is_empty() {
        Target::NotNumber
    } else {
        Target::Missing
    }
}

/// Values that are keys but not numbers a dispersion can draw: a flag, a name, a whole number
/// (a rotor's index), one word of a vocabulary (`payload.model`).
macro_rules! not_numbers {
    ($($ty:ty),+ $(,)?) => {$(
        impl $crate::config::params::Field for $ty {
            fn target(
                &mut self,
                rest: &[$crate::config::params::Seg],
            ) -> $crate::config::params::Target<'_> {
                $crate::config::params::not_number(rest)
            }
        }
    )+};
}
pub(crate) use not_numbers;

not_numbers!(u32, bool, String);

/// A check of one number under its dotted key (`config::finite`, `positive`, `non_negative`).
pub type Check<'a> = &'a dyn Fn(&dyn fmt::Display, f64) -> Result<(), ConfigError>;

/// A value a key's bound applies to: each of its numbers is checked under its own dotted key.
pub trait Bounded {
    fn check_each(&self, key: &dyn fmt::Display, check: Check) -> Result<(), ConfigError>;
}

impl Bounded for f64 {
    fn check_each(&self, key: &dyn fmt::Display, check: Check) -> Result<(), ConfigError> {
        check(key, *self)
    }
}

/// Entry `i` is checked as `{key}[{i}]`, in order: a row's numbers, a list's entries.
fn check_entries<'a, T: Bounded + 'a>(
    entries: impl IntoIterator<Item = &'a T>,
    key: &dyn fmt::Display,
    check: Check,
) -> Result<(), ConfigError> {
    for (i, x) in entries.into_iter().enumerate() {
        x.check_each(&format_args!("{key}[{i}]"), check)?;
    }
    Ok(())
}

impl<T: Bounded, const N: usize> Bounded for [T; N] {
    fn check_each(&self, key: &dyn fmt::Display, check: Check) -> Result<(), ConfigError> {
        check_entries(self, key, check)
    }
}

/// A list (a wind table's rows).
impl<T: Bounded> Bounded for Vec<T> {
    fn check_each(&self, key: &dyn fmt::Display, check: Check) -> Result<(), ConfigError> {
        check_entries(self, key, check)
    }
}

/// An optional value is checked only when it is set.
impl<T: Bounded> Bounded for Option<T> {
    fn check_each(&self, key: &dyn fmt::Display, check: Check) -> Result<(), ConfigError> {
        match self {
            Some(x) => x.check_each(key, check),
            None => Ok(()),
        }
    }
}

/// Parameters declared with `params!`.
pub trait Params {
    /// Every key, in declaration order.
    const KEYS: &'static [Key];
    /// The target of `field` (then `rest`) in these parameters.
    fn target(&mut self, field: &str, rest: &[Seg]) -> Target<'_>;
    /// The value of key `name` read from `map` as its field's type (so a mistyped value's
    /// error carries its dotted key), as JSON; `None` (nothing read) if `name` is not a key
    /// of these parameters. For a table whose keys several `Params` share (`model::section`).
    fn read_value<'de, A: serde::de::MapAccess<'de>>(
        name: &str,
        map: &mut A,
    ) -> Result<Option<serde_json::Value>, A::Error>;
    /// Check the simple bounds the keys declare (`non_negative`, `positive`, `finite`), in declaration
    /// order, each number under its dotted key `{prefix}.{name}` (`[i]` after it for an
    /// element): the first that fails is the error. The rules across keys are the table's own.
    fn check_bounds(&self, prefix: &str) -> Result<(), ConfigError>;

    /// Every key as a dotted key under `prefix` (`"vehicle"` -> `"vehicle.mass"`).
    fn keys_under(prefix: &str) -> Vec<(String, Key)> {
        Self::KEYS
            .iter()
            .map(|k| (format!("{prefix}.{}", k.name), *k))
            .collect()
    }
}

/// A table of parameters (a kind's, or a section of the scenario): `name: type => "unit",
/// "label";` per key, with its doc comment and serde attributes above it, and optionally a
/// simple bound after the label, the name of the check in `config` that words its message:
/// `name: f64 => "m", "Arm length", non_negative;` (>= 0; also `positive`, > 0, and `finite`),
/// on a number, each number of a row (`name[i]`), or an optional number when it is set.
/// Generates the struct (`deny_unknown_fields`), its `Params` (with `check_bounds`: the
/// declared bounds in declaration order) and its `Field` (so a list of such tables, like
/// `[[actuator.faults]]`, is a key with the entries' keys under it).
macro_rules! params {
    (
        $(#[$meta:meta])*
        pub struct $Name:ident {
            $(
                $(#[$fmeta:meta])*
                $field:ident: $ty:ty => $unit:literal, $label:literal $(, $check:ident)?;
            )*
        }
    ) => {
        $(#[$meta])*
        #[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
        #[serde(deny_unknown_fields)]
        pub struct $Name {
            $($(#[$fmeta])* pub $field: $ty,)*
        }

        impl $crate::config::params::Params for $Name {
            const KEYS: &'static [$crate::config::params::Key] = &[$(
                $crate::config::params::Key {
                    name: stringify!($field),
                    unit: $unit,
                    label: $label,
                },
            )*];

            #[allow(unused_variables)] // a table without bounds
            fn check_bounds(&self, prefix: &str) -> Result<(), $crate::config::ConfigError> {
                $($(
                    $crate::config::params::Bounded::check_each(
                        &self.$field,
                        &format_args!(concat!("{}.", stringify!($field)), prefix),
                        &|key: &dyn std::fmt::Display, x: f64| $crate::config::$check(key, x),
                    )?;
                )?)*
                Ok(())
            }

            #[allow(unused_variables)] // a table without keys
            fn target(
                &mut self,
                field: &str,
                rest: &[$crate::config::params::Seg],
            ) -> $crate::config::params::Target<'_> {
                match field {
                    $(stringify!($field) => $crate::config::params::Field::target(&mut self.$field, rest),)*
                    _ => $crate::config::params::Target::Missing,
                }
            }

            #[allow(unused_variables)] // a table without keys
            fn read_value<'de, A: serde::de::MapAccess<'de>>(
                name: &str,
                map: &mut A,
            ) -> Result<Option<serde_json::Value>, A::Error> {
                match name {
                    $(stringify!($field) => {
                        let value: $ty = map.next_value()?;
                        serde_json::to_value(value).map(Some).map_err(serde::de::Error::custom)
                    })*
                    _ => Ok(None),
                }
            }
        }

        impl $crate::config::params::Field for $Name {
            fn target(
                &mut self,
                rest: &[$crate::config::params::Seg],
            ) -> $crate::config::params::Target<'_> {
                match rest {
                    [] => $crate::config::params::Target::NotNumber,
                    [$crate::config::params::Seg::Field(f), sub @ ..] => {
                        $crate::config::params::Params::target(self, f, sub)
                    }
                    _ => $crate::config::params::Target::Missing,
                }
            }
        }
    };
}
pub(crate) use params;

/// A kind's table that a scenario may leave out when the kind has defaults (filled in once,
/// when the scenario is read: see `ControllerConfig::fill_defaults`). Reads as the parameters
/// themselves; reading an absent table is a bug (validation refuses one without defaults).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(transparent)]
pub struct Table<P>(pub Option<P>);

impl<P> Default for Table<P> {
    fn default() -> Self {
        Self(None)
    }
}

impl<P> Table<P> {
    pub fn is_absent(&self) -> bool {
        self.0.is_none()
    }
}

impl<P> std::ops::Deref for Table<P> {
    type Target = P;
    fn deref(&self) -> &P {
        self.0
            .as_ref()
            .expect("a validated scenario has every controller's table")
    }
}

impl<P> std::ops::DerefMut for Table<P> {
    fn deref_mut(&mut self) -> &mut P {
        self.0
            .as_mut()
            .expect("a validated scenario has every controller's table")
    }
}
