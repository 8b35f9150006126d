//! Controllers (docs/model.md section 2): a kind family like the payloads and actuators. Each
//! law is one file implementing `Controller` (its parameters for one vehicle, built once from
//! the scenario and gathered one vehicle per lane) and `Control` (the law itself, on the
//! rigid-body view), and one line of `controllers!` below registers it: that line gives it its
//! `ControllerKind` variant, its public name (`Controller::NAME`), its `AnyController` variant
//! and its arm of `dispatch`, which the flight loop and the linearisation both go through.
//!
//! The PD and SMC laws are cascades: an outer loop gives the thrust U1 and virtual inputs
//! Ux, Uy, inverted into commanded roll and pitch for the inner attitude loop (`Shared`).

mod pd;
mod px4;
mod px4_allocator;
mod se3;
mod smc;

pub use pd::Pd;
pub use px4::Px4;
pub use se3::Se3;
pub use smc::{IntegralChannel, Smc};

use crate::config::keys::{Seg, Target};
use crate::config::params::{params, Key, Params, Table};
use crate::config::{steps_per_update, ConfigError};
use crate::lane::{gather, Gathered, KernelOps, Lane, Masks, Param};
use crate::model::section::{part, KnownKey};
use crate::model::{Inputs, ModelContext, PayloadView, Rigid, Tick, Trig};
use crate::trajectory::Reference;
use serde::{de::DeserializeOwned, Deserialize, Serialize};

/// What a law is built and checked from: the payload and actuator kinds' view of the scenario
/// (`model::ModelContext`, read through it as `cfg.vehicle`, `cfg.payload.mass`,
/// `cfg.actuator.rotors`) and the controllers' own section. The model sits below the laws: a
/// law reads the vehicle's kinds, never the reverse.
#[derive(Debug, Clone, Copy)]
pub struct ControlContext<'a> {
    pub model: ModelContext<'a>,
    pub controller: &'a ControllerConfig,
}

crate::config::reads_through!(ControlContext => model: ModelContext);

/// What a law sees at a step: the rigid body (`Rigid`), the sines and cosines of its angles
/// (`Trig`: the flight loop computes them once and shares them with the plant's first RK4
/// stage) and the payload as the law may see it (`PayloadView`; `None` for a law that does not
/// read it, whose view is then never computed).
#[derive(Clone, Copy)]
pub struct Sight<'a, L> {
    pub rigid: &'a Rigid<L>,
    pub trig: &'a Trig<L>,
    pub payload: Option<&'a PayloadView<L>>,
}

impl<'a, L: Lane> Sight<'a, L> {
    /// The rigid body, its angles' sines and cosines, and the payload if in view.
    #[inline(always)]
    pub fn of(rigid: &'a Rigid<L>, trig: &'a Trig<L>, payload: &'a Option<PayloadView<L>>) -> Self {
        Self {
            rigid,
            trig,
            payload: payload.as_ref(),
        }
    }

    /// The rigid body alone (no payload in view).
    #[inline(always)]
    pub fn blind(rigid: &'a Rigid<L>, trig: &'a Trig<L>) -> Self {
        Self {
            rigid,
            trig,
            payload: None,
        }
    }
}

/// Which of a law's loops update at a step (docs/model.md, "Loop rates"): the position loop, the
/// attitude loop and the body-rate loop with the mixer. A loop samples what it reads when it
/// updates and holds its output until its next update; at `Due::ALL` every loop updates (a law
/// without rates, the linearisation, the flight's first step).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Due {
    pub position: bool,
    pub attitude: bool,
    pub rate: bool,
}

impl Due {
    pub const ALL: Self = Self {
        position: true,
        attitude: true,
        rate: true,
    };
}

/// What a law keeps from one step to the next, one value per lane: the outputs its loops hold
/// between their updates and its own discrete state (integrators, filtered derivatives). A
/// law's `Memory` is a fixed array of named slots.
pub trait Kept<L: Lane>: Copy {
    /// Lane `lane` set to `from`'s (a retired lane parked on the memory it started with).
    fn park(&mut self, lane: usize, from: &Self);
    /// The slots, in order (`Controller::integrators` names some by index).
    fn slots(&self) -> &[L];
    fn slots_mut(&mut self) -> &mut [L];
}

impl<L: Lane, const K: usize> Kept<L> for [L; K] {
    #[inline(always)]
    fn park(&mut self, lane: usize, from: &Self) {
        for (m, m0) in self.iter_mut().zip(from.iter()) {
            m.set_lane(lane, m0.lane(lane));
        }
    }
    fn slots(&self) -> &[L] {
        self
    }
    fn slots_mut(&mut self) -> &mut [L] {
        self
    }
}

/// A control law: the inputs for what it sees (`Sight`) and the reference `r` at the step
/// `at`, one `step` per control step. Its gains are of type `P`: `f64` (one vehicle) or a lane
/// type (one vehicle per lane).
///
/// `Memory` is what the law keeps between steps (`Kept`); `memory` its value for a vehicle that
/// has been at the seen state for ever (no integral, no derivative, every held output about to
/// be refreshed), `step` one control step: the loops that are `due` update from what they see
/// and the held outputs of the loop above, the others hold, and the memory advances. The law
/// at rest (`control`: `step` from `memory`, every loop due) is what the linearisation
/// differentiates (docs/architecture.md, "A law with memory").
///
/// A law sees the rigid body only, unless it sets `SEES_PAYLOAD`: then the flight loop and the
/// linearisation also give it what it may see of the payload (`Sight::payload`). A law that
/// does not set it costs nothing: the view is never computed.
pub trait Control<P = f64>: Sync {
    /// The law reads the payload's view (`Sight::payload`).
    const SEES_PAYLOAD: bool = false;

    /// Whether this law, as built, reads the view: `SEES_PAYLOAD` by default; a law whose
    /// payload feedback is off in every lane says no, and the flight loop skips the view.
    #[inline(always)]
    fn reads_payload(&self) -> bool {
        Self::SEES_PAYLOAD
    }

    /// What the law keeps between steps.
    type Memory<L: Lane>: Kept<L>;

    /// The memory of a vehicle that has been where `seen` shows it for ever.
    fn memory<L: Masks>(&self, seen: &Sight<L>) -> Self::Memory<L>
    where
        P: Param<L>;

    /// One control step: the inputs held over step `at`, the loops that are `due` updated and
    /// `mem` advanced to the next step.
    fn step<L: Masks>(
        &self,
        seen: &Sight<L>,
        r: &Reference,
        at: Tick,
        due: Due,
        mem: &mut Self::Memory<L>,
    ) -> Inputs<L>
    where
        P: Param<L>;

    /// The law at rest at `seen`: `step` from `memory`, every loop due.
    #[inline(always)]
    fn at_rest<L: Masks>(&self, seen: &Sight<L>, r: &Reference, at: Tick) -> Inputs<L>
    where
        P: Param<L>,
    {
        let mut mem = self.memory(seen);
        self.step(seen, r, at, Due::ALL, &mut mem)
    }

    /// The law at rest for the rigid state `s` alone (its angles' sines and cosines worked
    /// out here, no payload in view).
    #[inline(always)]
    fn control<L: Masks>(&self, s: &Rigid<L>, r: &Reference, at: Tick) -> Inputs<L>
    where
        P: Param<L>,
    {
        let trig = Trig::of_angles(s.att[0], s.att[1], s.att[2]);
        self.at_rest(&Sight::blind(s, &trig), r, at)
    }
}

/// A controller kind: its parameters (`Params`, its own table `[controller.<name>]`, declared
/// with `config::params!`), their checks (`validate`), the law for one vehicle resolved once
/// from a validated scenario (`new`), and the same law with one vehicle per lane (`gather`).
/// `Self` is the law on `f64` gains, which the linearisation flies on plain and dual numbers.
pub trait Controller: Control + Clone + std::fmt::Debug + Send + Sized + 'static {
    /// The kind's table: its keys, units and labels (`Params::KEYS`).
    type Params: Params + Clone + std::fmt::Debug + Serialize + DeserializeOwned;
    /// The law with gains of lane type `L`, one vehicle per lane.
    type At<L: Lane>: Control<L>;

    /// The law's name as a person reads it (tables, legends): "PD", "SE(3)".
    const LABEL: &'static str;

    /// Hz, the rates of the law's position, attitude and inner loops where the scenario sets
    /// none (`[controller]` `position_rate`, `attitude_rate`, `inner_rate`); 0: every step.
    const RATES: [f64; 3] = [0.0; 3];

    /// The parameters a scenario that gives no table for this kind flies (None: it must give
    /// one).
    fn defaults() -> Option<Self::Params> {
        None
    }
    /// Check every parameter; `key` is the table's dotted key (`"controller.pd"`), which every
    /// message names as `{key}.{name}`. By default each key within its declared bounds (a law
    /// whose keys bound one another says so).
    fn validate(p: &Self::Params, key: &str, _cfg: &ControlContext) -> Result<(), ConfigError> {
        p.check_bounds(key)
    }
    fn new(p: &Self::Params, cfg: &ControlContext) -> Self;
    /// One vehicle per lane: lane `l` of every gain is `each[l]`'s.
    fn gather<L: Lane>(each: &[&Self]) -> Self::At<L>;

    /// The memory slots (`Kept::slots`) that integrate an error, those whose gain is not zero:
    /// at a closed-loop equilibrium each holds what balances a steady disturbance, and the
    /// trimmed start (`crate::start`) solves for them. None for a law without integral action.
    fn integrators(&self) -> Vec<usize> {
        Vec::new()
    }
}

/// Work to do with a controller whose kind is known at compile time (the flight loop, the
/// closed loop of the linearisation).
pub trait ControllerVisitor {
    type Output;
    fn visit<C: Controller>(self) -> Self::Output;
}

/// The registration of every controller kind, `name => Type`, in the order the Python layer
/// lists them: `name` is its public name (`controller="pd"`, `_core.CONTROLLER_NAMES`,
/// `--controller`) and its table's (`[controller.pd]`); `Type` implements `Controller`. One line
/// per kind generates its `ControllerKind` variant, its table in `ControllerConfig` (checked,
/// defaulted, its keys typed and listed with their units), its `AnyController` variant and its
/// arm of `dispatch`; everything else about a kind lives in its own file.
macro_rules! controllers {
    ($($name:ident => $Ty:ident),+ $(,)?) => {
        /// Which law to fly.
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
        pub enum ControllerKind {
            $($Ty),+
        }

        impl ControllerKind {
            /// Every controller, in the order the Python layer lists them.
            pub const ALL: &'static [Self] = &[$(Self::$Ty),+];

            /// The public name.
            pub fn name(self) -> &'static str {
                match self {
                    $(Self::$Ty => stringify!($name)),+
                }
            }

            /// The kind's label (`Controller::LABEL`).
            pub fn label(self) -> &'static str {
                match self {
                    $(Self::$Ty => <$Ty as Controller>::LABEL),+
                }
            }

            /// Hz, the kind's own loop rates (`Controller::RATES`).
            pub fn rates(self) -> [f64; 3] {
                match self {
                    $(Self::$Ty => <$Ty as Controller>::RATES),+
                }
            }

            /// The keys of the kind's table (`Params::KEYS`).
            pub fn keys(self) -> &'static [Key] {
                match self {
                    $(Self::$Ty => <<$Ty as Controller>::Params as Params>::KEYS),+
                }
            }
        }

        /// `[controller]`: what every law shares (`SharedParams`, its keys directly under
        /// `[controller]`, read through `Deref`), then one table per kind.
        #[derive(Debug, Clone, Serialize)]
        pub struct ControllerConfig {
            #[serde(flatten)]
            pub shared: SharedParams,
            $(
                #[serde(skip_serializing_if = "Table::is_absent")]
                pub $name: Table<<$Ty as Controller>::Params>,
            )+
        }

        /// Read key by key, as `[payload]` is (`model::section`; serde's `flatten` would let an
        /// unknown key through): a shared key as its field's type (so a mistyped value names its
        /// dotted key), a kind's table as the table, any other key refused with every key of
        /// `[controller]` named, as `deny_unknown_fields` words it.
        impl<'de> Deserialize<'de> for ControllerConfig {
            fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
                struct Visit;
                impl<'de> serde::de::Visitor<'de> for Visit {
                    type Value = ControllerConfig;

                    fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                        f.write_str("the [controller] table")
                    }

                    fn visit_map<M: serde::de::MapAccess<'de>>(
                        self,
                        mut map: M,
                    ) -> Result<ControllerConfig, M::Error> {
                        let mut shared = serde_json::Map::new();
                        $(let mut $name = Table::default();)+
                        while let Some(key) = map.next_key_seed(KnownKey(ControllerConfig::OWNERS))? {
                            if let Some(v) = SharedParams::read_value(&key, &mut map)? {
                                shared.insert(key, v);
                                continue;
                            }
                            match key.as_str() {
                                $(stringify!($name) => $name = map.next_value()?,)+
                                _ => return Err(serde::de::Error::custom(format_args!("no owner for `{key}`"))),
                            }
                        }
                        Ok(ControllerConfig {
                            shared: part(shared)?,
                            $($name,)+
                        })
                    }
                }
                d.deserialize_map(Visit)
            }
        }

        impl ControllerConfig {
            /// The keys of `[controller]`: the shared ones, then the kinds' tables (for the
            /// message that refuses another).
            const OWNERS: &'static [&'static [Key]] = &[
                SharedParams::KEYS,
                &[$(Key {
                    name: stringify!($name),
                    unit: "-",
                    label: concat!("The ", stringify!($name), " law's parameters"),
                }),+],
            ];

            /// Each kind's default table as JSON text (`None` for a kind without defaults):
            /// what a scenario that leaves the table out flies, for Python to show and to
            /// start from when one key of it is set.
            pub fn default_tables() -> Vec<(&'static str, Option<String>)> {
                vec![$(
                    (
                        stringify!($name),
                        <$Ty as Controller>::defaults().map(|p| {
                            serde_json::to_string(&p).expect("a kind's defaults serialise")
                        }),
                    )
                ),+]
            }

            /// Give every kind whose table the scenario left out its defaults, if it has them.
            pub fn fill_defaults(&mut self) {
                $(
                    if self.$name.is_absent() {
                        self.$name = Table(<$Ty as Controller>::defaults());
                    }
                )+
            }

            /// Every kind's table is there and its values in range.
            fn validate_kinds(&self, cfg: &ControlContext) -> Result<(), ConfigError> {
                $(
                    let key = concat!("controller.", stringify!($name));
                    match &self.$name.0 {
                        Some(p) => <$Ty as Controller>::validate(p, key, cfg)?,
                        None => return Err(ConfigError::new(
                            key,
                            format!("{key} must be given (the {} law's parameters)", stringify!($name)),
                        )),
                    }
                )+
                Ok(())
            }

            /// The typed target of `field` (then `rest`) of a kind's table.
            fn kind_target(&mut self, name: &str, field: &str, rest: &[Seg]) -> Target<'_> {
                match name {
                    $(stringify!($name) => match &mut self.$name.0 {
                        Some(p) => Params::target(p, field, rest),
                        None => Target::Missing,
                    },)+
                    _ => Target::Missing,
                }
            }
        }

        /// One controller kind's parameters for one vehicle (built once per realisation: the
        /// variants' sizes differ, nothing is gained by boxing them).
        #[derive(Clone, Debug)]
        #[allow(clippy::large_enum_variant)]
        pub enum AnyController {
            $($Ty($Ty)),+
        }

        impl AnyController {
            /// The law `kind` of a validated scenario.
            pub fn new(kind: ControllerKind, cfg: &ControlContext) -> Self {
                match kind {
                    $(ControllerKind::$Ty => {
                        Self::$Ty(<$Ty as Controller>::new(&cfg.controller.$name, cfg))
                    })+
                }
            }

            pub fn kind(&self) -> ControllerKind {
                match self {
                    $(Self::$Ty(_) => ControllerKind::$Ty),+
                }
            }

            /// The parameters as kind `C` (`dispatch` matched the kind: anything else is a bug).
            pub fn get<C: Controller>(&self) -> &C {
                let any: &dyn std::any::Any = match self {
                    $(Self::$Ty(c) => c),+
                };
                any.downcast_ref::<C>().unwrap_or_else(|| {
                    panic!(
                        "controller {} asked for as {}",
                        self.kind().name(),
                        std::any::type_name::<C>()
                    )
                })
            }
        }

        /// The law a lane-set flies, its kind chosen at run time: a `match` per step, whose
        /// branch every step of a flight takes alike (every lane of a set flies the same law),
        /// each arm its law inlined. So the flight loop is compiled once per lane type and
        /// vehicle, not once per law as well.
        #[allow(clippy::large_enum_variant)]
        pub enum Flying<L: KernelOps> {
            $($Ty(InFlight<<$Ty as Controller>::At<L>, L>)),+
        }

        impl<L: KernelOps> Flying<L> {
            /// Law `kind` of each lane's realisation (`each[l]`), gathered one vehicle per lane,
            /// its memory at rest at `seen` but for the slots each lane's trimmed start sets
            /// (`held[l]`: slot and value, `crate::start`).
            pub fn new(
                kind: ControllerKind,
                each: &[&Laws],
                seen: &Sight<L>,
                held: &[&[(usize, f64)]],
            ) -> Self {
                match kind {
                    $(ControllerKind::$Ty => {
                        let laws: Vec<&$Ty> = each.iter().map(|l| l.get(kind).get::<$Ty>()).collect();
                        Self::$Ty(InFlight::new(<$Ty as Controller>::gather::<L>(&laws), seen, held))
                    })+
                }
            }

            /// Whether the law reads the payload's view (`Control::reads_payload`).
            #[inline(always)]
            pub fn reads_payload(&self) -> bool {
                match self {
                    $(Self::$Ty(f) => f.law.reads_payload()),+
                }
            }

            /// One control step (`Control::step`) with the law's own memory.
            #[inline(always)]
            pub fn step(&mut self, seen: &Sight<L>, r: &Reference, at: Tick, due: Due) -> Inputs<L> {
                match self {
                    $(Self::$Ty(f) => f.law.step(seen, r, at, due, &mut f.mem)),+
                }
            }

            /// Lane `lane`'s memory set back to the flight's start (a retired lane).
            #[inline(always)]
            pub fn park(&mut self, lane: usize) {
                match self {
                    $(Self::$Ty(f) => f.mem.park(lane, &f.start)),+
                }
            }
        }

        /// The one dispatch point from a controller's name to the code compiled for it (for the
        /// flight loop, through `integrate::LoopEntry::enter`, like `model::dispatch`).
        pub fn dispatch<V: ControllerVisitor>(kind: ControllerKind, v: V) -> V::Output {
            match kind {
                $(ControllerKind::$Ty => v.visit::<$Ty>()),+
            }
        }
    };
}

controllers! {
    pd => Pd,
    smc => Smc,
    px4 => Px4,
    se3 => Se3,
}

params! {
    /// The keys of `[controller]` every law shares (`ControllerConfig::shared`).
    pub struct SharedParams {
        /// Use m + mc in the control laws (the paper's proposal) instead of m.
        mass_compensation: bool => "-", "Payload mass in the control laws";
        /// rad, bound on the commanded roll and pitch.
        tilt_limit: f64 => "rad", "Largest commanded roll and pitch", positive;
        /// N, the thrust is never divided by less than this (guards Ux, Uy).
        thrust_floor: f64 => "N", "Least thrust the laws divide by", positive;
        /// N, optional saturation of the total thrust.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        thrust_min: Option<f64> => "N", "Least total thrust", non_negative;
        #[serde(default, skip_serializing_if = "Option::is_none")]
        thrust_max: Option<f64> => "N", "Largest total thrust", positive;
        /// Hz, the loops' rates (docs/model.md, "Loop rates"; 0: every step; unset: the law's own,
        /// `Controller::RATES`).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        position_rate: Option<f64> => "Hz", "Position loop rate (0: every step)", non_negative;
        #[serde(default, skip_serializing_if = "Option::is_none")]
        attitude_rate: Option<f64> => "Hz", "Attitude loop rate (0: every step)", non_negative;
        #[serde(default, skip_serializing_if = "Option::is_none")]
        inner_rate: Option<f64> => "Hz", "Body-rate loop and mixer rate (0: every step)", non_negative;
    }
}

/// The keys of the loops' rates, in the order of `ControllerConfig::rates`.
pub const RATE_KEYS: [&str; 3] = [
    "controller.position_rate",
    "controller.attitude_rate",
    "controller.inner_rate",
];

impl std::ops::Deref for ControllerConfig {
    type Target = SharedParams;
    fn deref(&self) -> &SharedParams {
        &self.shared
    }
}

impl std::ops::DerefMut for ControllerConfig {
    fn deref_mut(&mut self) -> &mut SharedParams {
        &mut self.shared
    }
}

impl ControllerConfig {
    /// Every key of `[controller]` with its unit and label, as dotted keys (indices dropped):
    /// the shared ones, then each kind's.
    pub fn keys() -> Vec<(String, Key)> {
        let shared = SharedParams::keys_under("controller");
        let kinds = ControllerKind::ALL.iter().flat_map(|kind| {
            kind.keys()
                .iter()
                .map(move |k| (format!("controller.{}.{}", kind.name(), k.name), *k))
        });
        shared.into_iter().chain(kinds).collect()
    }

    /// The typed target of the key `controller.<path>` (`path` after `controller`).
    pub fn target(&mut self, path: &[Seg]) -> Target<'_> {
        let field = |i: usize| match path.get(i) {
            Some(Seg::Field(f)) => f.as_str(),
            _ => "",
        };
        let rest = path.get(1..).unwrap_or(&[]);
        if SharedParams::KEYS.iter().any(|k| k.name == field(0)) {
            return self.shared.target(field(0), rest);
        }
        self.kind_target(field(0), field(1), path.get(2..).unwrap_or(&[]))
    }

    /// Steps between the updates of law `kind`'s position, attitude and inner loops at the
    /// step `dt`: a key's rate exactly (`validate` has checked that its period is whole steps),
    /// a law's own rate (`Controller::RATES`, where the key is unset) to the nearest whole
    /// number of steps, at least one (PX4's 1 kHz rate loop on a 2 ms step runs every step).
    pub fn loop_steps(&self, kind: ControllerKind, dt: f64) -> [usize; 3] {
        let own = kind.rates();
        let set = [self.position_rate, self.attitude_rate, self.inner_rate];
        [0, 1, 2].map(|i| match set[i] {
            Some(rate) => steps_per_update(rate, dt).unwrap_or(1),
            None if own[i] == 0.0 => 1,
            None => ((1.0 / (own[i] * dt)).round() as usize).max(1),
        })
    }

    /// Which of law `kind`'s position, attitude and inner loops run at every step whatever
    /// the step (the key 0, or unset where the law has no rate of its own): their hold is the
    /// step's, so a coarser step lags them more; a loop at a rate holds its own period at any
    /// step that divides it.
    pub fn every_step(&self, kind: ControllerKind) -> [bool; 3] {
        let own = kind.rates();
        let set = [self.position_rate, self.attitude_rate, self.inner_rate];
        [0, 1, 2].map(|i| set[i].unwrap_or(own[i]) == 0.0)
    }

    /// s, law `kind`'s loops' periods at the step `dt` (`loop_steps` steps each).
    pub fn loop_periods(&self, kind: ControllerKind, dt: f64) -> [f64; 3] {
        self.loop_steps(kind, dt).map(|n| n as f64 * dt)
    }

    /// The rates the keys set are whole numbers of steps.
    fn validate_rates(&self, dt: f64) -> Result<(), ConfigError> {
        let set = [self.position_rate, self.attitude_rate, self.inner_rate];
        for (key, rate) in RATE_KEYS.iter().zip(set) {
            if let Some(Err(why)) = rate.map(|r| steps_per_update(r, dt)) {
                return Err(ConfigError::new(*key, format!("{key}: {why}")));
            }
        }
        Ok(())
    }

    /// Check every value: the shared keys (their bounds, then the rules across them), then
    /// each kind's table.
    pub fn validate(&self, cfg: &ControlContext) -> Result<(), ConfigError> {
        self.shared.check_bounds("controller")?;
        self.validate_rates(cfg.integrator.dt)?;
        let tl = self.tilt_limit;
        if tl > std::f64::consts::FRAC_PI_2 {
            return Err(ConfigError::new(
                "controller.tilt_limit",
                format!("controller.tilt_limit must be at most pi/2 rad, got {tl:?}"),
            ));
        }
        if let Some(x) = self.thrust_max {
            if x <= self.thrust_min.unwrap_or(0.0) {
                return Err(ConfigError::new(
                    "controller.thrust_max",
                    format!("controller.thrust_max must exceed controller.thrust_min, got {x:?}"),
                ));
            }
        }
        self.validate_kinds(cfg)
    }
}

impl ControllerKind {
    /// The kind named `name`.
    pub fn parse(name: &str) -> Result<Self, String> {
        Self::ALL
            .iter()
            .copied()
            .find(|k| k.name() == name)
            .ok_or_else(|| {
                let names: Vec<String> = Self::ALL
                    .iter()
                    .map(|k| format!("'{}'", k.name()))
                    .collect();
                format!(
                    "controller must be one of {}, got {name:?}",
                    names.join(", ")
                )
            })
    }
}

/// Every kind's law for one vehicle, in the order of `ControllerKind::ALL`: a realisation carries
/// them all, so that one batch flies every law through the same gusts.
#[derive(Clone, Debug)]
pub struct Laws(Vec<AnyController>);

impl Laws {
    pub fn new(cfg: &ControlContext) -> Self {
        Self(
            ControllerKind::ALL
                .iter()
                .map(|&k| AnyController::new(k, cfg))
                .collect(),
        )
    }

    /// The law of kind `kind`.
    pub fn get(&self, kind: ControllerKind) -> &AnyController {
        &self.0[kind as usize]
    }
}

/// A law in flight (`Flying`): its gains one vehicle per lane, its memory, and the memory it
/// started with.
pub struct InFlight<C: Control<L>, L: KernelOps> {
    law: C,
    mem: C::Memory<L>,
    start: C::Memory<L>,
}

impl<C: Control<L>, L: KernelOps> InFlight<C, L> {
    fn new(law: C, seen: &Sight<L>, held: &[&[(usize, f64)]]) -> Self {
        let mut mem = law.memory(seen);
        for (lane, slots) in held.iter().enumerate() {
            for &(i, x) in slots.iter() {
                mem.slots_mut()[i].set_lane(lane, x);
            }
        }
        Self {
            law,
            mem,
            start: mem,
        }
    }
}

/// What both laws share: the mass they compensate, the thrust guards and the attitude inversion.
#[derive(Clone, Debug)]
pub struct Shared<P = f64> {
    /// m~: m + mc with mass compensation, m without.
    pub mt: P,
    pub g: P,
    /// Nominal inertia (the controller's belief).
    pub inertia: [P; 3],
    thrust_min: P,
    thrust_max: P,
    thrust_floor: P,
    /// sin of the tilt limit: asin is monotone, so clamping its argument clamps the angle.
    sin_tilt: P,
}

/// Smallest cos(phi) cos(theta) the laws divide by. Only reached by a vehicle tipped on its
/// side, which the divergence check flags anyway; it keeps the arithmetic finite until then.
const MIN_TILT_COS: f64 = 1e-6;

impl Shared {
    pub fn new(cfg: &ControlContext) -> Self {
        let c = &cfg.controller;
        let mt = if c.mass_compensation {
            cfg.vehicle.mass + cfg.payload.mass
        } else {
            cfg.vehicle.mass
        };
        Self {
            mt,
            g: cfg.environment.gravity,
            inertia: cfg.vehicle.inertia,
            thrust_min: c.thrust_min.unwrap_or(f64::NEG_INFINITY),
            thrust_max: c.thrust_max.unwrap_or(f64::INFINITY),
            thrust_floor: c.thrust_floor,
            sin_tilt: c.tilt_limit.sin(),
        }
    }
}

/// One vehicle per lane (see `AnyVehicle::gather`): a law's `gather` gathers its `shared`.
impl<L: Lane> Gathered for Shared<L> {
    type From = Shared;
    fn gather_from<'a>(lane: impl Fn(usize) -> &'a Shared + Copy) -> Self {
        gather!(|l| lane(l) => Shared { mt, g, inertia, thrust_min, thrust_max, thrust_floor, sin_tilt })
    }
}

impl<P: Copy> Shared<P> {
    /// 1 / (cos(phi) cos(theta)), guarded.
    #[inline(always)]
    fn inv_tilt<L: Lane>(&self, cphi: L, cth: L) -> L {
        L::splat(1.0) / (cphi * cth).max(L::splat(MIN_TILT_COS))
    }

    /// Thrust after the optional limits.
    #[inline(always)]
    fn limit_thrust<L: Lane>(&self, u1: L) -> L
    where
        P: Param<L>,
    {
        u1.clamp(self.thrust_min.get(), self.thrust_max.get())
    }

    /// mt / U1 with U1 kept away from zero (the virtual inputs divide by it).
    #[inline(always)]
    fn mass_over_thrust<L: Lane>(&self, u1: L) -> L
    where
        P: Param<L>,
    {
        self.mt.get() / u1.max(self.thrust_floor.get())
    }

    /// Exact inversion of the x/y equations: commanded (phi, theta) for virtual inputs Ux, Uy
    /// at the current yaw.
    #[inline(always)]
    fn desired_attitude<L: Lane>(&self, ux: L, uy: L, spsi: L, cpsi: L) -> (L, L)
    where
        P: Param<L>,
    {
        let lim: L = self.sin_tilt.get();
        let sphi = (spsi * ux - cpsi * uy).clamp(-lim, lim);
        let cphi = (L::splat(1.0) - sphi * sphi)
            .sqrt()
            .max(L::splat(MIN_TILT_COS));
        let sth = ((cpsi * ux + spsi * uy) / cphi).clamp(-lim, lim);
        (sphi.asin(), sth.asin())
    }
}

/// What an Euler-angle cascade (PD, SMC) holds between its loops' updates: the position loop's
/// thrust and commanded roll and pitch, the attitude loop's torques; then the position loop's
/// own state (the SMC's integral of the position error, x, y, z; unused by the PD).
pub type EulerHeld<L> = [L; 9];
const HELD_U1: usize = 0;
const HELD_PHI: usize = 1;
const HELD_THETA: usize = 2;
const HELD_TAU: usize = 3;
/// The first of the position loop's own slots (`EulerCascade::position`'s `own`).
pub(crate) const HELD_OWN: usize = 6;

/// The held outputs of an Euler-angle cascade at the flight's start (every loop updates at its
/// first step, so none is read before it is written).
#[inline(always)]
fn euler_held<L: Lane>() -> EulerHeld<L> {
    [L::splat(0.0); 9]
}

/// An Euler-angle cascade (PD, SMC): a position loop giving the thrust and the commanded roll
/// and pitch, and an attitude loop giving the torques toward them.
trait EulerCascade<P> {
    /// The thrust and the commanded roll and pitch; `own` is the position loop's own state
    /// (`EulerHeld`'s last three slots), which it advances by one update.
    fn position<L: Masks>(&self, seen: &Sight<L>, r: &Reference, own: &mut [L]) -> (L, L, L)
    where
        P: Param<L>;
    fn attitude<L: Lane>(&self, s: &Rigid<L>, phi_d: L, theta_d: L, r: &Reference) -> [L; 3]
    where
        P: Param<L>;
}

/// `Control` for an Euler-angle cascade (`EulerCascade`): its memory the held outputs
/// (`EulerHeld`), its step `euler_step`. `sees: |law| reads` for a law that sees the payload,
/// `reads` whether it reads the view as built.
macro_rules! euler_control {
    ($Ty:ident $(, sees: |$law:ident| $reads:expr)?) => {
        impl<P: Copy + Sync> Control<P> for $Ty<P> {
            $(
                const SEES_PAYLOAD: bool = true;

                #[inline(always)]
                fn reads_payload(&self) -> bool {
                    let $law = self;
                    $reads
                }
            )?

            type Memory<L: Lane> = EulerHeld<L>;

            #[inline(always)]
            fn memory<L: Masks>(&self, _seen: &Sight<L>) -> EulerHeld<L>
            where
                P: Param<L>,
            {
                euler_held()
            }

            #[inline(always)]
            fn step<L: Masks>(
                &self,
                seen: &Sight<L>,
                r: &Reference,
                _at: Tick,
                due: Due,
                mem: &mut EulerHeld<L>,
            ) -> Inputs<L>
            where
                P: Param<L>,
            {
                euler_step(self, seen, r, due, mem)
            }
        }
    };
}
use euler_control;

/// An Euler-angle cascade's step: each loop that is due updates its held outputs in `mem` (the
/// attitude loop from the position loop's held setpoint), and the inputs are the held ones.
#[inline(always)]
fn euler_step<P, C: EulerCascade<P>, L: Masks>(
    law: &C,
    seen: &Sight<L>,
    r: &Reference,
    due: Due,
    mem: &mut EulerHeld<L>,
) -> Inputs<L>
where
    P: Param<L>,
{
    if due.position {
        let (u1, phi_d, theta_d) = law.position(seen, r, &mut mem[HELD_OWN..]);
        mem[HELD_U1] = u1;
        mem[HELD_PHI] = phi_d;
        mem[HELD_THETA] = theta_d;
    }
    if due.attitude {
        let tau = law.attitude(seen.rigid, mem[HELD_PHI], mem[HELD_THETA], r);
        mem[HELD_TAU..HELD_TAU + 3].copy_from_slice(&tau);
    }
    Inputs {
        u1: mem[HELD_U1],
        tau: [mem[HELD_TAU], mem[HELD_TAU + 1], mem[HELD_TAU + 2]],
    }
}

/// Position errors e = desired - actual and their rates, as the laws use them.
#[inline(always)]
fn position_errors<L: Lane>(s: &Rigid<L>, r: &Reference) -> ([L; 3], [L; 3]) {
    let e = [
        L::splat(r.pos[0]) - s.pos[0],
        L::splat(r.pos[1]) - s.pos[1],
        L::splat(r.pos[2]) - s.pos[2],
    ];
    let ed = [
        L::splat(r.vel[0]) - s.vel[0],
        L::splat(r.vel[1]) - s.vel[1],
        L::splat(r.vel[2]) - s.vel[2],
    ];
    (e, ed)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::tests::paper;

    /// At rest at `pos` with yaw `psi`.
    pub(crate) fn at_rest(pos: [f64; 3], psi: f64) -> Rigid<f64> {
        Rigid {
            pos,
            att: [0.0, 0.0, psi],
            vel: [0.0; 3],
            rate: [0.0; 3],
        }
    }

    fn hover_inputs<C: Control>(c: &C) -> Inputs<f64> {
        let s = at_rest([0.0, 0.0, 2.0], 0.3);
        let r = Reference {
            pos: [0.0, 0.0, 2.0],
            psi: 0.3,
            ..Reference::default()
        };
        c.control(&s, &r, Tick::START)
    }

    #[test]
    fn both_laws_hold_hover_with_total_weight() {
        let cfg = paper();
        let w = (cfg.vehicle.mass + cfg.payload.mass) * cfg.environment.gravity;
        for u in [
            hover_inputs(&Pd::new(&cfg.controller.pd, &cfg.control_context())),
            hover_inputs(&Smc::new(&cfg.controller.smc, &cfg.control_context())),
        ] {
            assert!((u.u1 - w).abs() < 1e-12, "U1 = {} vs weight {w}", u.u1);
            assert_eq!(u.tau, [0.0; 3]);
        }
    }

    /// Every key of `[controller]` has a unit and a label, names a field of the scenario
    /// (a typed target of the paper preset) and is listed once; every field of every kind's
    /// table is a listed key: the registration, the tables and the units cannot drift apart.
    #[test]
    fn every_controller_key_has_a_unit_a_label_and_a_target() {
        use crate::config::keys::parse_key;
        let cfg = paper();
        let keys = ControllerConfig::keys();
        for (i, (key, k)) in keys.iter().enumerate() {
            assert!(!k.unit.trim().is_empty(), "{key} has no unit");
            assert!(!k.label.trim().is_empty(), "{key} has no label");
            assert!(
                !keys[..i].iter().any(|(other, _)| other == key),
                "{key} twice"
            );
            let mut c = cfg.clone();
            let path = parse_key(key).unwrap();
            let found = !matches!(c.target(&path), Target::Missing);
            // An unset optional number is no key of this scenario.
            let optional = key == "controller.thrust_min"
                || key == "controller.thrust_max"
                || RATE_KEYS.contains(&key.as_str());
            assert!(found || optional, "{key} is no key of the paper scenario");
        }
        let json = serde_json::to_value(&cfg.controller).unwrap();
        for kind in ControllerKind::ALL {
            let table = json[kind.name()].as_object().expect("a table per kind");
            let listed: Vec<&str> = kind.keys().iter().map(|k| k.name).collect();
            let fields: Vec<&str> = table.keys().map(|k| k.as_str()).collect();
            let mut sorted = listed.clone();
            sorted.sort_unstable();
            assert_eq!(sorted, fields, "{}", kind.name());
        }
    }

    #[test]
    fn a_missing_controller_table_is_named() {
        let mut v = crate::scenario::tests::paper_value();
        v["controller"].as_object_mut().unwrap().remove("smc");
        let e = crate::scenario::Config::from_json(&v.to_string()).unwrap_err();
        assert_eq!(e.key, "controller.smc");
        assert_eq!(
            e.message,
            "controller.smc must be given (the smc law's parameters)"
        );
        let mut v = crate::scenario::tests::paper_value();
        v["controller"]["pd"]["kq"] = serde_json::json!([1, 2, 3]);
        let e = crate::scenario::Config::from_json(&v.to_string()).unwrap_err();
        assert_eq!(e.key, "controller.pd.kq");
        assert!(e.message.contains("unknown field `kq`"), "{e}");
        let mut v = crate::scenario::tests::paper_value();
        v["controller"]["smc"]["eta"][1] = serde_json::json!(-1.0);
        let e = crate::scenario::Config::from_json(&v.to_string()).unwrap_err();
        assert_eq!(e.key, "controller.smc.eta[1]");
        assert_eq!(e.message, "controller.smc.eta[1] must be >= 0, got -1.0");
    }

    #[test]
    fn a_kind_is_named_once() {
        for &kind in ControllerKind::ALL {
            assert_eq!(ControllerKind::parse(kind.name()), Ok(kind));
            let cfg = paper();
            assert_eq!(
                AnyController::new(kind, &cfg.control_context()).kind(),
                kind
            );
            assert_eq!(Laws::new(&cfg.control_context()).get(kind).kind(), kind);
        }
        let e = ControllerKind::parse("lqr").unwrap_err();
        assert!(
            e.starts_with("controller must be one of 'pd', 'smc'"),
            "{e}"
        );
        assert!(e.ends_with(", got \"lqr\""), "{e}");
    }

    #[test]
    fn attitude_inversion_reproduces_the_virtual_inputs() {
        let sh = Shared::new(&paper().control_context());
        for &(ux, uy, psi) in &[(0.1, -0.2, 0.5), (-0.3, 0.05, -2.0), (0.0, 0.4, 3.0)] {
            let (spsi, cpsi) = f64::sin_cos(psi);
            let (phi, th): (f64, f64) = sh.desired_attitude(ux, uy, spsi, cpsi);
            let (sphi, cphi) = phi.sin_cos();
            let sth = th.sin();
            assert!((cphi * sth * cpsi + spsi * sphi - ux).abs() < 1e-12);
            assert!((cphi * sth * spsi - sphi * cpsi - uy).abs() < 1e-12);
        }
    }

    #[test]
    fn tilt_limit_bounds_the_commanded_angles() {
        let mut cfg = paper();
        cfg.controller.tilt_limit = 0.2;
        let sh = Shared::new(&cfg.control_context());
        let (phi, th): (f64, f64) = sh.desired_attitude(5.0, -5.0, 0.0, 1.0);
        assert!((phi.abs() - 0.2).abs() < 1e-12 && (th.abs() - 0.2).abs() < 1e-12);
    }
}
