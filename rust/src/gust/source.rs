//! The wind-source seam: a deterministic wind source (no state, no random numbers) is one file
//! implementing [`WindSource`] (its parameters read from the scenario, their checks, their
//! dotted keys with units and labels, its wind at a step) and one line of `wind_sources!` in
//! `gust/mod.rs`, which gives it its `AnySource` variant, its place in the list a
//! [`super::WindField`] holds and in the summation order, its checks in `Wind::validate` and
//! its keys in `_core.KEY_UNITS`. The turbulence stays apart (it has state and draws random
//! numbers): `WindField` composes it with the list.
//!
//! The order of the sum is fixed (the bits of a seeded flight depend on it): the sources of
//! the mean air ([`WindSource::MEAN_AIR`], the air the turbulence rides on and its relative
//! airspeed is measured against) are summed first, in registration order; the turbulence is
//! added to that; then the other sources, each in registration order.

use crate::config::keys::{Seg, Target};
use crate::config::params::Key;
use crate::config::ConfigError;
use crate::gust::{Wind, WindContext};

/// When a source is asked for its wind: the step, held over `[t, t + dt)`, and its time
/// `t = step dt` (s), computed once per step for every source.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Moment {
    pub step: u64,
    /// s.
    pub t: f64,
}

/// Where the quadrotor is at the start of a step: what the wind sources that follow it read.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Kinematics {
    /// m, the quadrotor's altitude z.
    pub z: f64,
    /// m/s, its inertial velocity.
    pub vel: [f64; 3],
}

impl Kinematics {
    /// At rest at z = 0.
    pub const AT_REST: Self = Self {
        z: 0.0,
        vel: [0.0; 3],
    };
}

/// A deterministic wind source: its wind is a function of the step and of where the
/// quadrotor is (built once per batch, shared read-only by all threads).
pub trait WindSource: Sized {
    /// Part of the mean air (summed before the turbulence, which rides on it).
    const MEAN_AIR: bool;
    /// Its keys, named below `wind.` (`speed`, `gusts.start`, `table.by`), with units and
    /// labels; an indexed key drops its indices. A source with a table of its own declares
    /// it with `params!` and gives `Table::keys_under("name")`.
    fn keys() -> Vec<(String, Key)>;
    /// The source of a validated scenario; `None` where it does not blow.
    fn build(cfg: &WindContext) -> Option<Self>;
    /// Check its values in the `[wind]` table; the first problem found, naming its key.
    fn validate(wind: &Wind) -> Result<(), ConfigError>;
    /// What the dotted key `wind.<field><rest>` names, for a `field` this kind owns (the first
    /// part of one of its `keys`): the typed targets of dispersions, sweeps and optimisations
    /// (`config::keys`).
    fn target<'w>(wind: &'w mut Wind, field: &str, rest: &[Seg]) -> Target<'w>;
    /// Its wind (m/s, inertial x, y, z) held over the step `now`, the quadrotor at `kin`
    /// (at rest at z = 0 unless some source of the field reads the vehicle).
    fn at(&self, now: Moment, kin: &Kinematics) -> [f64; 3];
    /// Whether `at` reads `kin` (the quadrotor's altitude or velocity).
    fn reads_vehicle(&self) -> bool;
}

/// Whether `field` (a part of `wind.`) is the first part of one of the kind's keys.
pub fn owns<S: WindSource>(field: &str) -> bool {
    S::keys()
        .iter()
        .any(|(name, _)| name.split('.').next() == Some(field))
}

/// A kind's keys, dotted from `wind.`.
pub fn keys_of<S: WindSource>() -> Vec<(String, Key)> {
    S::keys()
        .into_iter()
        .map(|(name, k)| (format!("wind.{name}"), k))
        .collect()
}

/// Register the wind-source kinds, in the summation order: `name => Kind,` declares the module
/// `gust/name.rs` and generates `AnySource` (one variant per kind, dispatched by `match`, no
/// `dyn`), `sources` (the scenario's sources in this order), `validate` and `keys`.
macro_rules! wind_sources {
    ($($name:ident => $kind:ident),+ $(,)?) => {
        $(pub mod $name;)+
        $(pub use $name::$kind;)+

        /// One wind source of any registered kind.
        #[derive(Clone, Debug, PartialEq)]
        pub enum AnySource {
            $($kind($kind),)+
        }

        impl AnySource {
            /// The kinds' names, in the summation order.
            pub const NAMES: &'static [&'static str] = &[$(stringify!($name)),+];

            /// Its wind held over the step `now` (`WindSource::at`).
            #[inline(always)]
            pub fn at(&self, now: source::Moment, kin: &Kinematics) -> [f64; 3] {
                match self {
                    $(Self::$kind(s) => source::WindSource::at(s, now, kin),)+
                }
            }

            /// Whether it reads the quadrotor (`WindSource::reads_vehicle`).
            #[inline]
            pub fn reads_vehicle(&self) -> bool {
                match self {
                    $(Self::$kind(s) => source::WindSource::reads_vehicle(s),)+
                }
            }

            /// Whether it is part of the mean air (`WindSource::MEAN_AIR`).
            #[inline(always)]
            pub fn is_mean_air(&self) -> bool {
                match self {
                    $(Self::$kind(_) => <$kind as source::WindSource>::MEAN_AIR,)+
                }
            }

            /// Its kind's name.
            pub fn name(&self) -> &'static str {
                match self {
                    $(Self::$kind(_) => stringify!($name),)+
                }
            }

            /// The scenario's sources that blow, in the summation order: the mean air's first,
            /// then the others, each in registration order.
            pub fn of(cfg: &crate::gust::WindContext<'_>) -> Vec<AnySource> {
                let mut all = Vec::new();
                $(
                    if let Some(s) = <$kind as source::WindSource>::build(cfg) {
                        all.push(AnySource::$kind(s));
                    }
                )+
                all.sort_by_key(|s| !s.is_mean_air()); // stable: registration order kept
                all
            }

            /// Every kind's checks of the `[wind]` table, in registration order.
            pub fn validate(
                wind: &crate::gust::Wind,
            ) -> Result<(), crate::config::ConfigError> {
                $(<$kind as source::WindSource>::validate(wind)?;)+
                Ok(())
            }

            /// What `wind.<field><rest>` names: the target of the kind that owns `field`.
            pub fn target<'w>(
                wind: &'w mut crate::gust::Wind,
                field: &str,
                rest: &[crate::config::keys::Seg],
            ) -> crate::config::keys::Target<'w> {
                $(
                    if source::owns::<$kind>(field) {
                        return <$kind as source::WindSource>::target(wind, field, rest);
                    }
                )+
                crate::config::keys::Target::Missing
            }

            /// Every kind's keys, dotted (`wind.speed`), with units and labels.
            pub fn keys() -> Vec<(String, crate::config::params::Key)> {
                let mut all = Vec::new();
                $(all.extend(source::keys_of::<$kind>());)+
                all
            }
        }
    };
}
pub(super) use wind_sources;

#[cfg(test)]
mod tests {
    use super::super::gusts::{discrete_gust, DiscreteGust, GustShape};
    use super::super::steady::{shear_factor, Shear};
    use super::super::table::{table_wind, TableBy, WindTable};
    use super::super::{AnySource, Kinematics, WindField};
    use crate::scenario::Config;

    fn windy() -> Config {
        let mut cfg = crate::scenario::tests::paper();
        cfg.gust.enabled = false;
        cfg.wind.speed = 4.0;
        cfg.wind.heading = 150.0;
        cfg.wind.shear = Shear::Log;
        cfg.wind.roughness = 0.08;
        cfg.wind.gusts = vec![
            DiscreteGust {
                start: 0.02,
                duration: 0.05,
                amplitude: [1.0, -0.5, 0.25],
                shape: GustShape::Ramp,
            },
            DiscreteGust {
                start: 0.04,
                duration: 0.03,
                amplitude: [-0.3, 0.7, 0.1],
                shape: GustShape::Pulse,
            },
        ];
        cfg.wind.table = Some(WindTable {
            by: TableBy::Altitude,
            points: vec![
                [0.0, 0.0, 0.0, 0.0],
                [3.0, 1.5, -1.0, 0.2],
                [8.0, -2.0, 0.5, 0.0],
            ],
        });
        cfg.validate().unwrap();
        cfg
    }

    fn add(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
        [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
    }

    #[test]
    fn the_list_is_the_registration_in_the_summation_order() {
        assert_eq!(AnySource::NAMES, ["steady", "gusts", "table", "prescribed"]);
        let cfg = windy();
        let field = WindField::new(&cfg.wind_context()).unwrap();
        let names: Vec<_> = field.sources().iter().map(AnySource::name).collect();
        // The mean air's first (steady, table), then the others in registration order.
        assert_eq!(names, ["steady", "table", "gusts"]);
        let rows = vec![[0.5, -0.25, 0.125]; 4];
        let names: Vec<_> = field
            .prescribed(rows)
            .sources()
            .iter()
            .map(AnySource::name)
            .collect();
        assert_eq!(names, ["steady", "table", "gusts", "prescribed"]);
        // Every kind's keys, dotted below `wind.`, with a unit and a label.
        let keys = AnySource::keys();
        for key in [
            "wind.speed",
            "wind.roughness",
            "wind.gusts.shape",
            "wind.table.points",
        ] {
            let k = keys.iter().find(|(k, _)| k == key).expect(key).1;
            assert!(!k.unit.is_empty() && !k.label.is_empty(), "{key}");
        }
    }

    /// The field's sum is the sources' own values, computed here from their formulas (not
    /// through the list), summed in the documented order: the mean air's (steady, then the
    /// table), then the gusts (from zero, in their order), then the prescribed wind.
    #[test]
    fn the_lists_sum_is_the_sources_values_in_order() {
        let cfg = windy();
        let dt = cfg.integrator.dt;
        let rows: Vec<[f64; 3]> = (0..400)
            .map(|k| {
                let t = k as f64 * dt;
                [(7.0 * t).sin(), -0.5 * (3.0 * t).cos(), 0.1 * t]
            })
            .collect();
        let plain = WindField::new(&cfg.wind_context()).unwrap();
        let given = plain.clone().prescribed(rows.clone());
        assert!(plain.follows_vehicle() && given.blows() && !given.enabled());
        let chi = cfg.wind.heading.to_radians();
        let points = &cfg.wind.table.as_ref().unwrap().points;
        let mut s1 = plain.realisation(3, 1);
        let mut s2 = given.realisation(3, 1);
        for step in 0..400_u64 {
            let kin = Kinematics {
                z: -1.0 + 0.03 * step as f64,
                vel: [1.0, 0.0, -0.5],
            };
            let t = step as f64 * dt;
            let s = cfg.wind.speed * shear_factor(Shear::Log, kin.z, cfg.wind.roughness);
            let steady = [s * chi.cos(), s * chi.sin(), 0.0];
            let mean = add(steady, table_wind(points, kin.z));
            let mut gusts = [0.0; 3];
            for g in &cfg.wind.gusts {
                gusts = add(gusts, discrete_gust(g, t));
            }
            let want = add(mean, gusts);
            let bits = |w: [f64; 3]| w.map(f64::to_bits);
            assert_eq!(bits(plain.deterministic(step, &kin)), bits(want), "{step}");
            // Without turbulence the held wind is the sum from zero.
            let sampled = plain.sample_at(&mut s1, step, || kin);
            assert_eq!(bits(sampled), bits(add(add([0.0; 3], mean), gusts)));
            // A prescribed wind is added last.
            let p = rows[step as usize];
            assert_eq!(bits(given.deterministic(step, &kin)), bits(add(want, p)));
            let sampled = given.sample_at(&mut s2, step, || kin);
            assert_eq!(bits(sampled), bits(add(add(add([0.0; 3], mean), gusts), p)));
            // Each source alone, through the trait, is its formula.
            let now = super::Moment { step, t };
            let each: Vec<[f64; 3]> = given.sources().iter().map(|s| s.at(now, &kin)).collect();
            assert_eq!(
                each.iter().copied().map(bits).collect::<Vec<_>>(),
                [steady, table_wind(points, kin.z), gusts, p].map(bits)
            );
        }
        // Past the rows, a prescribed wind is NaN (the flight ends as non-finite).
        let past = given.deterministic(400, &Kinematics::AT_REST);
        assert!(past.iter().all(|w| w.is_nan()));
    }
}
