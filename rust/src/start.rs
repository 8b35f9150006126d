//! The trimmed start as an equilibrium of the closed loop (docs/model.md, "The start: trimmed in
//! the wind"). The plant's trim (`Vehicle::trim_state`) balances the vehicle in the start's
//! steady wind with the thrust and tilt it needs; a law flown from it does not necessarily ask
//! for that tilt: a law without integral action (the PD, the geometric law, the SMC without its
//! integral surface) holds a steady offset downwind of its reference to lean into the wind, and
//! a law with integrators (PX4's velocity and rate integrators, the SMC's integral surface)
//! holds the reference only with its integrators at the values that balance the drag. From the
//! plant's trim with the integrators empty, the law first levels the vehicle and the parcel
//! swings out (issue 72: 0.14 -> 0.03 -> 0.35 rad in 2 s at 8 m/s).
//!
//! So each law starts at its own closed-loop equilibrium: the state and the law's integrators
//! at which the law, every loop updating, gives the inputs that hold the plant still (no
//! acceleration of any state) and no integrator changes. Newton's method on the closed loop
//! (`stability::ClosedLoop::eval_held`) from the plant's trim finds it in a few steps. A sampled
//! law at a constant state gives constant outputs, so the equilibrium is its too.

use crate::control::ControllerKind;
use crate::scenario::Config;
use crate::stability::{closed_loop, ClosedLoop};
use crate::trajectory::Trajectory;
use nalgebra::{DMatrix, DVector, SVD};

/// Newton steps at most.
const MAX_ITERATIONS: usize = 60;
/// Singular values below this fraction of the largest are directions the loop does not hold.
const SINGULAR: f64 = 1e-10;
/// Steps in which the wind is raised to its value (`settle`).
const CONTINUATION: usize = 10;
/// The smallest fraction of a Newton step tried before it is taken anyway.
const MIN_SCALE: f64 = 1e-3;
/// Largest residual (state units per s, integrator units per update) accepted as balanced.
const TOLERANCE: f64 = 1e-10;
/// The SVD's own iteration bound (the plain SVD never returns on a non-finite matrix).
const SVD_ITERATIONS: usize = 1000;

/// Where a flight by one law starts: the vehicle's state (the layout's order) and the law's
/// memory slots that differ from its memory at rest there (slot, value: its integrators).
#[derive(Clone, Debug, PartialEq)]
pub struct LawStart {
    pub state: Vec<f64>,
    pub held: Vec<(usize, f64)>,
}

impl LawStart {
    /// At the plant's own start `x0` (the rest state, or the plant's trim), the law's memory at
    /// rest.
    pub fn plant(x0: &[f64]) -> Self {
        Self {
            state: x0.to_vec(),
            held: Vec::new(),
        }
    }
}

/// The steady wind (m/s) at an altitude (m): the start's wind where the law holds the vehicle
/// (a law without integral action settles a little off `initial.position`'s altitude, into
/// another wind where the wind is sheared).
pub type WindAt<'a> = &'a dyn Fn(f64) -> [f64; 3];

/// Each law's start (in the order of `ControllerKind::ALL`) for the plant's start `x0` in the
/// steady wind `wind_at`: in still air the plant's start itself (bit for bit: the laws hold
/// hover there at rest), else each law's closed-loop equilibrium near it, or the plant's start
/// where the law has none (then the flight shows what the law does from there).
pub fn law_starts(cfg: &Config, x0: &[f64], wind_at: WindAt) -> Vec<LawStart> {
    let still = wind_at(x0[2]) == [0.0; 3];
    ControllerKind::ALL
        .iter()
        .map(|&kind| {
            if still {
                return LawStart::plant(x0);
            }
            closed_loop_start(cfg, kind, x0, wind_at).unwrap_or_else(|| LawStart::plant(x0))
        })
        .collect()
}

/// Law `kind`'s closed-loop equilibrium in the steady wind `wind_at`, from the plant's trim
/// `x0` (`settle`); `None` if Newton's method finds none.
pub fn closed_loop_start(
    cfg: &Config,
    kind: ControllerKind,
    x0: &[f64],
    wind_at: WindAt,
) -> Option<LawStart> {
    let r = Trajectory::new(&cfg.context()).at(0.0, &mut 0);
    let cl = closed_loop(cfg, kind, r);
    let b = Balance {
        cl: cl.as_ref(),
        n: cl.reduced(x0).len(),
        wind_at,
    };
    let z = settle(&b, cl.reduced(x0))?;
    let n = b.n;
    let held = cl.integrators().iter().copied().zip(z[n..].iter().copied());
    Some(LawStart {
        state: cl.expanded(&z[..n]),
        held: held.collect(),
    })
}

/// The equilibrium in two steps: the states with the integrators held empty (the law's
/// offset equilibrium, as a law without integral action holds it), the wind raised to its
/// value in `CONTINUATION` steps from rest, each solved from the last (a soft law's offset is metres,
/// beyond where Newton's method from the plant's trim converges); then from there the states
/// and the integrators together at the full wind: the integrators take over what the position
/// error held, and Newton's method goes straight to the equilibrium at the reference (from the
/// plant's trim it can settle where an integrator's anti-windup holds it at its limit, metres
/// off). A law whose offset equilibrium is not found is solved from the plant's trim.
fn settle(b: &Balance, x0: Vec<f64>) -> Option<Vec<f64>> {
    // From rest at the reference: in a tenth of the wind the law is near its linear range.
    let mut states = Some(b.cl.rest());
    for step in 1..=CONTINUATION {
        let f = step as f64 / CONTINUATION as f64;
        let at = |h: f64| (b.wind_at)(h).map(|w| w * f);
        let scaled = Balance {
            cl: b.cl,
            n: b.n,
            wind_at: &at,
        };
        states = states.and_then(|z| newton(&scaled, z));
    }
    let k = b.cl.integrators().len();
    if k == 0 {
        return states;
    }
    let mut z = states.unwrap_or(x0);
    z.extend(std::iter::repeat_n(0.0, k));
    newton(b, z)
}

/// What is balanced: the closed loop's rates of change (`ClosedLoop::eval_held`) at the
/// unknowns z, the loop's `n` states and, if z goes on, the law's integrators (else they are
/// held empty and their rows left out), in the wind at z's altitude.
struct Balance<'a> {
    cl: &'a dyn ClosedLoop,
    n: usize,
    wind_at: WindAt<'a>,
}

impl Balance<'_> {
    fn residual(&self, z: &[f64]) -> DVector<f64> {
        // The loop's states begin with the position (x, y, z), as the vehicle's do.
        let wind = (self.wind_at)(z[2]);
        let empty = vec![0.0; self.cl.integrators().len()];
        let held = if z.len() > self.n {
            &z[self.n..]
        } else {
            &empty
        };
        let mut f = self.cl.eval_held(&z[..self.n], held, &wind);
        f.truncate(z.len());
        DVector::from_vec(f)
    }

    /// Central-difference slopes of the residual at z.
    fn jacobian(&self, z: &[f64]) -> DMatrix<f64> {
        crate::differences::central(z, |z| self.residual(z))
    }
}

/// Newton's method with central-difference slopes and a pseudo-inverse (relative to the
/// largest singular value: a line length the winch keeps wherever it is, or any other
/// direction the loop does not hold, is left where it is), each step halved until the
/// residual falls (a soft law's offset is far from the plant's trim).
fn newton(b: &Balance, mut z: Vec<f64>) -> Option<Vec<f64>> {
    let mut r = b.residual(&z);
    for _ in 0..MAX_ITERATIONS {
        if !r.iter().all(|x| x.is_finite()) {
            return None;
        }
        if r.amax() < TOLERANCE {
            return Some(z);
        }
        let svd = SVD::try_new(b.jacobian(&z), true, true, f64::EPSILON, SVD_ITERATIONS)?;
        let cut = svd.singular_values.max() * SINGULAR;
        let step = svd.solve(&r, cut).ok()?;
        let mut scale = 1.0;
        loop {
            let next: Vec<f64> = z
                .iter()
                .zip(step.iter())
                .map(|(x, d)| x - scale * d)
                .collect();
            let rn = b.residual(&next);
            if rn.norm() < r.norm() || scale < MIN_SCALE {
                (z, r) = (next, rn);
                break;
            }
            scale *= 0.5;
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::tests::delivery_value;

    /// The delivery preset in a steady 8 m/s crosswind at the start (no turbulence), the laws
    /// reading the state.
    fn windy() -> (Config, crate::gust::WindField) {
        let mut v = delivery_value();
        v["gust"]["enabled"] = false.into();
        v["navigation"]["mode"] = "truth".into();
        v["wind"]["speed"] = 8.0.into();
        let cfg = Config::from_json(&v.to_string()).expect("valid");
        let field = crate::gust::WindField::new(&cfg.wind_context()).unwrap();
        (cfg, field)
    }

    /// Each law's start is a fixed point of its closed loop (no state accelerates, no
    /// integrator moves); a law with integral action starts at its reference, one without
    /// downwind of it, leaning into the wind.
    #[test]
    fn each_law_starts_at_its_closed_loop_equilibrium() {
        let (cfg, field) = windy();
        let wind_at = |z: f64| crate::integrate::start_wind(&field, z);
        assert!(wind_at(2.0)[1] > 6.0, "{:?}", wind_at(2.0));
        let engine_start = crate::integrate::Realisation::new(&cfg).unwrap();
        let x0 = &engine_start.x0;
        for &kind in ControllerKind::ALL {
            let start = closed_loop_start(&cfg, kind, x0, &wind_at);
            let start = start.unwrap_or_else(|| panic!("{}: no equilibrium", kind.name()));
            let wind = wind_at(start.state[2]);
            assert_eq!(&start, engine_start.start(kind), "{}", kind.name());
            let r = Trajectory::new(&cfg.context()).at(0.0, &mut 0);
            let cl = closed_loop(&cfg, kind, r);
            let held: Vec<f64> = start.held.iter().map(|h| h.1).collect();
            let f = cl.eval_held(&cl.reduced(&start.state), &held, &wind);
            let worst = f.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
            assert!(worst < 1e-9, "{}: residual {worst}", kind.name());
            let downwind = start.state[1] - cfg.initial.position[1];
            let integral = matches!(kind, ControllerKind::Px4 | ControllerKind::Smc);
            assert_eq!(start.held.is_empty(), !integral, "{}", kind.name());
            match kind {
                // PX4's integrators hold it at its reference (within its anti-windup's
                // centimetre); the SMC's integral is found at its limit (issue 72: left open).
                ControllerKind::Px4 => assert!(downwind.abs() < 0.05, "px4: {downwind}"),
                ControllerKind::Smc => {}
                _ => assert!(downwind > 0.1, "{}: {downwind}", kind.name()),
            }
        }
    }

    /// In still air every law starts at the plant's start, bit for bit (the paper's presets).
    #[test]
    fn still_air_starts_at_the_plant_start() {
        let (cfg, _) = windy();
        let x0 = vec![0.25; 3];
        let starts = law_starts(&cfg, &x0, &|_| [0.0; 3]);
        assert!(starts.iter().all(|s| *s == LawStart::plant(&x0)));
    }
}
