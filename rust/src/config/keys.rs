//! Dotted scenario keys (`"vehicle.inertia[2]"`): their parsing and the prefixes no realisation
//! may change. The assembled scenario reads them as typed fields (`scenario::Config::target`).

pub use super::params::{Seg, Target};

/// `"vehicle.inertia[2]"` -> [Field vehicle, Field inertia, Index 2].
pub fn parse_key(key: &str) -> Option<Vec<Seg>> {
    let mut out = Vec::new();
    for part in key.split('.') {
        let (name, mut rest) = part.split_at(part.find('[').unwrap_or(part.len()));
        let valid_name = name
            .chars()
            .next()
            .is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
            && name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_');
        if !valid_name {
            return None;
        }
        out.push(Seg::Field(name.to_string()));
        while !rest.is_empty() {
            let close = rest.find(']')?;
            if !rest.starts_with('[') {
                return None;
            }
            out.push(Seg::Index(rest[1..close].parse().ok()?));
            rest = &rest[close + 1..];
        }
    }
    Some(out)
}

/// The loops' rates (docs/model.md, "Loop rates"), the sensors' and the navigation filter's:
/// every lane of a set updates its law, its wind, its senses and its estimate at the same steps,
/// so no realisation of a batch may change them.
pub const SCHEDULE_KEYS: [&str; 11] = [
    "gust.rate",
    "controller.position_rate",
    "controller.attitude_rate",
    "controller.inner_rate",
    "navigation.mode",
    "navigation.rate",
    "sensors.imu.rate",
    "sensors.gnss.rate",
    "sensors.gnss.delay",
    "sensors.baro.rate",
    "sensors.heading.rate",
];

/// Key prefixes that cannot carry a per-realisation value: they change the step grid, the
/// phases, the reference every lane shares (and the volume it carries) or the spectrum grid,
/// or they are the table itself.
pub const FIXED_PREFIXES: [&str; 6] = [
    "integrator",
    "phases",
    "trajectory",
    "volume",
    "metrics",
    "dispersions",
];
