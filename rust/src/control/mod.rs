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
mod smc;

pub use pd::Pd;
pub use smc::Smc;

use crate::config::Config;
use crate::lane::{Lane, Param};
use crate::model::{Inputs, Rigid, Tick, Trig};
use crate::trajectory::Reference;

/// A control law: inputs for the state `s` and reference `r` at the step `at`, computed once
/// per step. Its gains are of type `P`: `f64` (one vehicle) or a lane type (one vehicle per
/// lane).
pub trait Control<P = f64>: Sync {
    /// `control` with the sines and cosines of `s`'s angles (`Trig::of(s)`) at hand: the
    /// flight loop computes them once and shares them with the plant's first RK4 stage.
    fn control_with<L: Lane>(
        &self,
        s: &Rigid<L>,
        trig: &Trig<L>,
        r: &Reference,
        at: Tick,
    ) -> Inputs<L>
    where
        P: Param<L>;

    #[inline(always)]
    fn control<L: Lane>(&self, s: &Rigid<L>, r: &Reference, at: Tick) -> Inputs<L>
    where
        P: Param<L>,
    {
        self.control_with(s, &Trig::of_angles(s.att[0], s.att[1], s.att[2]), r, at)
    }
}

/// A controller kind: its parameters for one vehicle, resolved once from a validated scenario
/// (`new`), and the same law with one vehicle per lane (`gather`). `Self` is the law on `f64`
/// gains, which the linearisation flies on plain and dual numbers.
pub trait Controller: Control + Clone + std::fmt::Debug + Send + Sized + 'static {
    /// The public name (`controller="pd"`, `_core.CONTROLLER_NAMES`, `--controller`).
    const NAME: &'static str;
    /// The law with gains of lane type `L`, one vehicle per lane.
    type At<L: Lane>: Control<L>;

    fn new(cfg: &Config) -> Self;
    /// One vehicle per lane: lane `l` of every gain is `each[l]`'s.
    fn gather<L: Lane>(each: &[&Self]) -> Self::At<L>;
}

/// Work to do with a controller whose kind is known at compile time (the flight loop, the
/// closed loop of the linearisation).
pub trait ControllerVisitor {
    type Output;
    fn visit<C: Controller>(self) -> Self::Output;
}

/// The registration of every controller kind: `Variant(Type)`, in the order the Python layer
/// lists them. One line per kind; everything else about a kind lives in its own file.
macro_rules! controllers {
    ($($Variant:ident($Ty:ty)),+ $(,)?) => {
        /// Which law to fly; `name` is the kind's public name (`Controller::NAME`).
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
        pub enum ControllerKind {
            $($Variant),+
        }

        impl ControllerKind {
            /// Every controller, in the order the Python layer lists them.
            pub const ALL: &'static [Self] = &[$(Self::$Variant),+];

            pub fn name(self) -> &'static str {
                match self {
                    $(Self::$Variant => <$Ty as Controller>::NAME),+
                }
            }
        }

        /// One controller kind's parameters for one vehicle.
        #[derive(Clone, Debug)]
        pub enum AnyController {
            $($Variant($Ty)),+
        }

        impl AnyController {
            /// The law `kind` of a validated scenario.
            pub fn new(kind: ControllerKind, cfg: &Config) -> Self {
                match kind {
                    $(ControllerKind::$Variant => Self::$Variant(<$Ty as Controller>::new(cfg))),+
                }
            }

            pub fn kind(&self) -> ControllerKind {
                match self {
                    $(Self::$Variant(_) => ControllerKind::$Variant),+
                }
            }

            /// The parameters as kind `C` (`dispatch` matched the kind: anything else is a bug).
            pub fn get<C: Controller>(&self) -> &C {
                let any: &dyn std::any::Any = match self {
                    $(Self::$Variant(c) => c),+
                };
                any.downcast_ref::<C>().unwrap_or_else(|| {
                    panic!("controller {} asked for as {}", self.kind().name(), C::NAME)
                })
            }
        }

        /// The one dispatch point from a controller's name to the code compiled for it. Always
        /// inlined, like `model::dispatch`: the flight loop must be compiled inside the
        /// caller's instruction-set function.
        #[inline(always)]
        pub fn dispatch<V: ControllerVisitor>(kind: ControllerKind, v: V) -> V::Output {
            match kind {
                $(ControllerKind::$Variant => v.visit::<$Ty>()),+
            }
        }
    };
}

controllers! {
    Pd(Pd),
    Smc(Smc),
}

impl ControllerKind {
    /// The kind named `name` (its `Controller::NAME`).
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

/// Every kind's law for one vehicle, in the order of `ControllerKind::ALL`: a craft carries
/// them all, so that one batch flies every law through the same gusts.
#[derive(Clone, Debug)]
pub struct Laws(Vec<AnyController>);

impl Laws {
    pub fn new(cfg: &Config) -> Self {
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
    pub fn new(cfg: &Config) -> Self {
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

    /// One vehicle per lane (see `Parts::gather`).
    pub fn gather<L: Lane>(each: &[&Shared]) -> Shared<L> {
        let at = |f: fn(&Shared) -> f64| L::from_fn(|l| f(each[l]));
        Shared {
            mt: at(|s| s.mt),
            g: at(|s| s.g),
            inertia: [
                at(|s| s.inertia[0]),
                at(|s| s.inertia[1]),
                at(|s| s.inertia[2]),
            ],
            thrust_min: at(|s| s.thrust_min),
            thrust_max: at(|s| s.thrust_max),
            thrust_floor: at(|s| s.thrust_floor),
            sin_tilt: at(|s| s.sin_tilt),
        }
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
    use crate::config::tests::paper;

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
        for u in [hover_inputs(&Pd::new(&cfg)), hover_inputs(&Smc::new(&cfg))] {
            assert!((u.u1 - w).abs() < 1e-12, "U1 = {} vs weight {w}", u.u1);
            assert_eq!(u.tau, [0.0; 3]);
        }
    }

    #[test]
    fn attitude_inversion_reproduces_the_virtual_inputs() {
        let sh = Shared::new(&paper());
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
        let sh = Shared::new(&cfg);
        let (phi, th): (f64, f64) = sh.desired_attitude(5.0, -5.0, 0.0, 1.0);
        assert!((phi.abs() - 0.2).abs() < 1e-12 && (th.abs() - 0.2).abs() < 1e-12);
    }
}
