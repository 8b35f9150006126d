//! `payload.release`: when the cable's hook opens (docs/model.md, "The last metres").

use crate::config::params::{not_number, Field, Seg, Target};

/// `payload.release`: "touchdown" (the parcel rests on the ground with the line slack),
/// "slack" (the measured tension below `payload.slack_tension`), a time (s, dispersible), or
/// `{ height = h }` (m: the parcel's height above the ground as the vehicle knows it, a drop).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Release {
    Touchdown,
    Slack,
    At(f64),
    Height(f64),
}

/// The words `payload.release` takes, and the key of its table.
pub const TOUCHDOWN: &str = "touchdown";
pub const SLACK: &str = "slack";
const HEIGHT: &str = "height";

impl Release {
    /// The value as a scenario gives it (for messages).
    pub fn shown(&self) -> String {
        match self {
            Release::Touchdown => format!("\"{TOUCHDOWN}\""),
            Release::Slack => format!("\"{SLACK}\""),
            Release::At(t) => format!("{t:?}"),
            Release::Height(h) => format!("{{ {HEIGHT} = {h:?} }}"),
        }
    }
}

impl serde::Serialize for Release {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap;
        match self {
            Release::Touchdown => s.serialize_str(TOUCHDOWN),
            Release::Slack => s.serialize_str(SLACK),
            Release::At(t) => s.serialize_f64(*t),
            Release::Height(h) => {
                let mut m = s.serialize_map(Some(1))?;
                m.serialize_entry(HEIGHT, h)?;
                m.end()
            }
        }
    }
}

impl<'de> serde::Deserialize<'de> for Release {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> serde::de::Visitor<'de> for V {
            type Value = Release;
            fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                write!(
                    f,
                    "\"{TOUCHDOWN}\", \"{SLACK}\", a time in s or {{ {HEIGHT} = h }} in m"
                )
            }
            fn visit_str<E: serde::de::Error>(self, v: &str) -> Result<Release, E> {
                match v {
                    TOUCHDOWN => Ok(Release::Touchdown),
                    SLACK => Ok(Release::Slack),
                    _ => Err(E::custom(format_args!(
                        "must be \"{TOUCHDOWN}\", \"{SLACK}\", a time in s or {{ {HEIGHT} = h }} \
                         in m, got {v:?}"
                    ))),
                }
            }
            fn visit_f64<E: serde::de::Error>(self, v: f64) -> Result<Release, E> {
                Ok(Release::At(v))
            }
            fn visit_i64<E: serde::de::Error>(self, v: i64) -> Result<Release, E> {
                Ok(Release::At(v as f64))
            }
            fn visit_u64<E: serde::de::Error>(self, v: u64) -> Result<Release, E> {
                Ok(Release::At(v as f64))
            }
            fn visit_map<M: serde::de::MapAccess<'de>>(
                self,
                mut m: M,
            ) -> Result<Release, M::Error> {
                use serde::de::Error;
                let mut height = None;
                while let Some(key) = m.next_key::<String>()? {
                    if key != HEIGHT || height.is_some() {
                        return Err(M::Error::custom(format_args!(
                            "a release table has one key, {HEIGHT} (m), got {key:?}"
                        )));
                    }
                    height = Some(m.next_value::<f64>()?);
                }
                height.map(Release::Height).ok_or_else(|| {
                    M::Error::custom(format_args!("a release table needs {HEIGHT} (m)"))
                })
            }
        }
        d.deserialize_any(V)
    }
}

/// A release time is a number a dispersion can draw; the words and the drop's height are not.
impl Field for Release {
    fn target(&mut self, rest: &[Seg]) -> Target<'_> {
        match self {
            Release::At(t) => t.target(rest),
            Release::Touchdown | Release::Slack | Release::Height(_) => not_number(rest),
        }
    }
}
