//! A kind's own parameters (a controller's gains today): one `params!` declaration in the
//! kind's file gives the serde struct (unknown keys refused, so a misspelt key is named), its
//! dotted keys with their units and labels (`Params::KEYS`, which reach Python through
//! `_core.KEY_UNITS` and `_core.KEY_LABELS`), and the typed targets a dispersion, a sweep or an
//! optimisation sets (`Params::target`).

use super::keys::{Seg, Target};
use serde::{Deserialize, Serialize};

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

impl Field for [f64; 3] {
    fn target(&mut self, rest: &[Seg]) -> Target<'_> {
        match rest {
            [Seg::Index(i)] if *i < 3 => Target::Number(&mut self[*i]),
            [] => Target::NotNumber,
            _ => Target::Missing,
        }
    }
}

/// An optional number exists as a key only when it is set.
impl Field for Option<f64> {
    fn target(&mut self, rest: &[Seg]) -> Target<'_> {
        match self {
            Some(x) => x.target(rest),
            None => Target::Missing,
        }
    }
}

/// A whole number (a rotor's index): a key, but not one a dispersion can draw.
impl Field for u32 {
    fn target(&mut self, rest: &[Seg]) -> Target<'_> {
        if rest.is_empty() {
            Target::NotNumber
        } else {
            Target::Missing
        }
    }
}

impl Field for bool {
    fn target(&mut self, rest: &[Seg]) -> Target<'_> {
        if rest.is_empty() {
            Target::NotNumber
        } else {
            Target::Missing
        }
    }
}

/// Parameters declared with `params!`.
pub trait Params {
    /// Every key, in declaration order.
    const KEYS: &'static [Key];
    /// The target of `field` (then `rest`) in these parameters.
    fn target(&mut self, field: &str, rest: &[Seg]) -> Target<'_>;
}

/// A kind's parameter table: `name: type => "unit", "label";` per key, with its doc comment and
/// serde attributes above it. Generates the struct (`deny_unknown_fields`) and its `Params`.
macro_rules! params {
    (
        $(#[$meta:meta])*
        pub struct $Name:ident {
            $(
                $(#[$fmeta:meta])*
                $field:ident: $ty:ty => $unit:literal, $label:literal;
            )+
        }
    ) => {
        $(#[$meta])*
        #[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
        #[serde(deny_unknown_fields)]
        pub struct $Name {
            $($(#[$fmeta])* pub $field: $ty,)+
        }

        impl $crate::config::params::Params for $Name {
            const KEYS: &'static [$crate::config::params::Key] = &[$(
                $crate::config::params::Key {
                    name: stringify!($field),
                    unit: $unit,
                    label: $label,
                },
            )+];

            fn target(
                &mut self,
                field: &str,
                rest: &[$crate::config::keys::Seg],
            ) -> $crate::config::keys::Target<'_> {
                match field {
                    $(stringify!($field) => $crate::config::params::Field::target(&mut self.$field, rest),)+
                    _ => $crate::config::keys::Target::Missing,
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
