//! "Is this gain set stable?" (docs/model.md section 8): closed-loop poles at hover.
//!
//! The closed loop ds/dt = f(s, u(s, r)) is linearised at a hover equilibrium: reference at the
//! first waypoint's position with psi_ref = 0 and zero velocity and acceleration, state at rest
//! there with psi = 0, zero wind. What is neglected, and why it does not matter:
//! - The zero-order hold of the digital controller: it adds a delay of dt/2 (1e-4 s in the paper
//!   preset), far faster than any pole, so the analysis is continuous-time.
//! - Drag: it is quadratic in the relative velocity, so its slope at zero relative velocity is
//!   zero; it leaves the linearisation unchanged (the model's drag is kept in f anyway).
//! - Yaw: at psi = 0 the x channel is driven by pitch alone and y by roll alone. With equal
//!   roll and pitch gains the lateral poles are the same at any yaw; with unequal ones, other
//!   yaws mix the two channels and shift the poles somewhat.
//!
//! The Jacobian is exact (to rounding): `Vehicle::derivative` composed with `Control::control` is
//! evaluated on forward-mode dual numbers, the same code the flights run (both are generic over
//! `Lane`), one column per seeded state. Unlike finite differences this needs no step size,
//! which matters at the kinks of sat(s) and v|v| (smooth at the origin, but their second
//! derivatives jump there, so central differences lose an order).
//!
//! At this point the plant decouples into lateral x/pitch, lateral y/roll, vertical + payload
//! and yaw. The blocks are found from the Jacobian's sparsity (not assumed), and each is
//! decomposed on its own: the eigenvalues of identical x and y loops then never mix their
//! eigenvectors, and each pole keeps an unambiguous mode label.

mod closed_loop;

pub use closed_loop::{closed_loop, ClosedLoop};

use crate::control::ControllerKind;
use crate::lane::dual::Dual;
use crate::model::{ix, Axis, Part, StateVar};
use crate::scenario::{Config, GustComponent};
use crate::trajectory::Reference;
use nalgebra::{Complex, DMatrix, DVector, Schur};

/// Real parts within this (1/s) of zero are "marginal", e.g. a position with no feedback. Not
/// smaller: a position with neither gain is a double integrator, a defective zero eigenvalue
/// that any eigensolver returns only to ~sqrt(machine eps) (about +/-3e-8 here). An e-folding
/// time of 1e6 s is no instability for a flight.
pub const TOLERANCE: f64 = 1e-6;

/// d f / d s, one row and column per state of the scenario's layout.
pub type Jacobian = DMatrix<f64>;

/// Mode labels, by the group of states that carries most of a pole's eigenvector.
pub const MODE_LATERAL_X: &str = "lateral x/pitch";
pub const MODE_LATERAL_Y: &str = "lateral y/roll";
pub const MODE_VERTICAL: &str = "vertical";
pub const MODE_PAYLOAD: &str = "payload";
/// A slung payload swinging below the vehicle (the pendulum modes of a cable).
pub const MODE_SWING_X: &str = "swing x";
pub const MODE_SWING_Y: &str = "swing y";
pub const MODE_YAW: &str = "yaw";
pub const MODE_ACTUATOR: &str = "actuator";

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Verdict {
    Stable,
    Marginal,
    Unstable,
}

impl Verdict {
    /// A NaN pole (the linearisation broke down) is never called stable.
    pub fn of(re: f64) -> Self {
        if re.is_nan() || re > TOLERANCE {
            Self::Unstable
        } else if re >= -TOLERANCE {
            Self::Marginal
        } else {
            Self::Stable
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Self::Stable => "stable",
            Self::Marginal => "marginal",
            Self::Unstable => "unstable",
        }
    }
}

#[derive(Clone, Debug)]
pub struct Pole {
    pub re: f64,
    pub im: f64,
    /// One of the `MODE_*` labels.
    pub mode: &'static str,
    /// The state with the largest eigenvector component.
    pub dominant: &'static str,
    /// Fraction of the eigenvector's squared norm in lateral states (x, y, phi, theta, rates).
    pub lateral_share: f64,
    /// Whether the scenario drives this mode at all (see [`lateral_sources`]).
    pub excited: bool,
    pub verdict: Verdict,
}

#[derive(Clone, Debug)]
pub struct Analysis {
    pub controller: ControllerKind,
    /// The closed-loop hover equilibrium the model was linearised at.
    pub equilibrium: Vec<f64>,
    /// |f(equilibrium)|: zero unless the closed loop has no hover equilibrium (e.g. no
    /// altitude gain without mass compensation), in which case the reference point is used.
    pub residual: f64,
    pub jacobian: Jacobian,
    /// Least stable first.
    pub poles: Vec<Pole>,
    pub verdict: Verdict,
    /// Why lateral modes are excited; empty if x and y stay exactly zero in this scenario.
    pub lateral_sources: Vec<&'static str>,
    /// s, where the law's loops run at rates: the period of the discrete-time model the poles
    /// are of (`ClosedLoop::sampled`); None: the continuous model's.
    pub period: Option<f64>,
    /// s, the loops' common period where it is longer than `MAX_PERIOD_STEPS` steps: too long
    /// to fly for the discrete-time model, so the poles are the continuous model's (the loops
    /// taken as updating every instant). None where the poles model the loops as flown.
    pub unmodelled_period: Option<f64>,
}

/// Steps of the longest period the discrete-time model of a sampled law is made over: its
/// matrix flies that many steps twice per state (60 times for the delivery vehicle), about a
/// second at this bound. Past it (a position loop at a fraction of a hertz; rates whose steps
/// share no factor, whose common period is their product) the analysis would take minutes to
/// forever, and the continuous model is analysed instead, saying so.
pub const MAX_PERIOD_STEPS: usize = 20_000;

/// Inputs of the linear model: the wind components (m/s, inertial, z up).
pub const NU: usize = 3;
pub const INPUT_NAMES: [&str; NU] = ["wind_x", "wind_y", "wind_z"];

/// Outputs of the linear model after the states: e_o (m), the controls (N, N m) and the
/// payload's vertical inertial acceleration `azc` (m/s^2; the only output the wind drives
/// directly, through the payload's drag).
pub const SIGNAL_OUTPUTS: [&str; 6] = ["e_o", "U1", "tau_phi", "tau_theta", "tau_psi", "azc"];

/// Every output of the linear model: the states of `vars`, then `SIGNAL_OUTPUTS`.
pub fn output_names(vars: &[StateVar]) -> Vec<&'static str> {
    vars.iter().map(|v| v.name).chain(SIGNAL_OUTPUTS).collect()
}

/// The hover reference: the first waypoint's (or route point's) position, psi_ref = 0, no
/// motion.
fn hover_reference(cfg: &Config) -> Reference {
    Reference {
        pos: cfg.trajectory.points()[0],
        ..Reference::default()
    }
}

/// Closed-loop poles of `kind` at hover for the scenario `cfg`.
pub fn analyse(cfg: &Config, kind: ControllerKind) -> Analysis {
    // The same linearisation `linearise` returns, in still air: A is the Jacobian.
    let cl = closed_loop(cfg, kind, hover_reference(cfg));
    let Linearisation {
        equilibrium,
        residual,
        a: jacobian,
        ..
    } = linearise_loop(&*cl, [0.0; 3]);
    let sources = lateral_sources(cfg);
    let vars = cl.vars();
    // A sampled law: the poles of the discrete-time model over one period T of its schedule
    // (the monodromy matrix's eigenvalues z, as s = ln(z) / T); else the continuous model's.
    let sampled = cl.sampled();
    let (matrix, period) = match sampled {
        Some((steps, dt)) if steps <= MAX_PERIOD_STEPS => {
            (period_map(&*cl, &equilibrium), Some(steps as f64 * dt))
        }
        _ => (jacobian.clone(), None),
    };
    let unmodelled_period = sampled
        .filter(|&(steps, _)| steps > MAX_PERIOD_STEPS)
        .map(|(steps, dt)| steps as f64 * dt);
    let mut poles = Vec::with_capacity(vars.len());
    for block in blocks(&matrix) {
        let has_actuator = block.iter().any(|&i| vars[i].part == Part::Actuator);
        for (lambda, v) in eigen(&matrix, &block) {
            let actuator = if has_actuator {
                actuator_participation(vars, &matrix, &block, lambda, &v)
            } else {
                0.0
            };
            let pole = match period {
                // A multiplier of zero (a state the period's holds wipe out) is no mode.
                Some(_) if lambda.norm() < 1e-12 => continue,
                Some(t) => lambda.ln() / t,
                None => lambda,
            };
            poles.push(describe(
                vars,
                pole,
                &block,
                &v,
                actuator,
                !sources.is_empty(),
            ));
        }
    }
    poles.sort_by(|a, b| b.re.total_cmp(&a.re).then(b.im.total_cmp(&a.im)));
    name_both_axes(&mut poles);
    let verdict = poles.first().map_or(Verdict::Stable, |p| p.verdict);
    Analysis {
        controller: kind,
        equilibrium,
        residual,
        jacobian,
        poles,
        verdict,
        lateral_sources: sources,
        period,
        unmodelled_period,
    }
}

/// The sampled closed loop's map over one period (`ClosedLoop::fly_period`) linearised at `s`
/// by central differences (the flight loop's own steps on plain numbers: the holds and the
/// schedule have no derivative to carry).
fn period_map(cl: &dyn ClosedLoop, s: &[f64]) -> Jacobian {
    crate::differences::central(s, |s| DVector::from_vec(cl.fly_period(s)))
}

/// The closed loop linearised at hover in a steady wind: deviations from the equilibrium obey
/// ds/dt = A ds + B dw, dy = C ds + D dw, with dw the wind's deviation from `wind`.
#[derive(Clone, Debug)]
pub struct Linearisation {
    pub wind: [f64; 3],
    pub equilibrium: Vec<f64>,
    /// |f(equilibrium)| (see [`Analysis::residual`]).
    pub residual: f64,
    pub a: Jacobian,
    pub b: DMatrix<f64>,
    pub c: DMatrix<f64>,
    pub d: DMatrix<f64>,
    /// Names of the rows of C and D (`output_names`).
    pub outputs: Vec<&'static str>,
    /// Names of the states.
    pub states: Vec<&'static str>,
}

/// The closed loop of `kind` linearised at hover in the steady wind `wind` (m/s): A, B, C, D,
/// exact (dual numbers). In still air A is [`Analysis::jacobian`] and B = 0: drag is quadratic
/// in the relative velocity, so a small wind change acts only at second order there.
pub fn linearise(cfg: &Config, kind: ControllerKind, wind: [f64; 3]) -> Linearisation {
    linearise_loop(&*closed_loop(cfg, kind, hover_reference(cfg)), wind)
}

fn linearise_loop(cl: &dyn ClosedLoop, wind: [f64; 3]) -> Linearisation {
    let nx = cl.vars().len();
    let (equilibrium, residual) = equilibrium(cl, &wind);
    let ny = cl.eval(&equilibrium, &wind).1.len();
    let mut lin = Linearisation {
        wind,
        equilibrium,
        residual,
        a: DMatrix::zeros(nx, nx),
        b: DMatrix::zeros(nx, NU),
        c: DMatrix::zeros(ny, nx),
        d: DMatrix::zeros(ny, NU),
        outputs: output_names(cl.vars()),
        states: cl.vars().iter().map(|v| v.name).collect(),
    };
    // One dual-number pass per column: seeded on state j, then on wind component j.
    for j in 0..nx + NU {
        let mut s: Vec<Dual> = lin.equilibrium.iter().map(|&x| Dual::constant(x)).collect();
        let mut w: [Dual; NU] = wind.map(Dual::constant);
        if j < nx {
            s[j].d = 1.0;
        } else {
            w[j - nx].d = 1.0;
        }
        let (f, y) = cl.eval_dual(&s, &w);
        for (i, fi) in f.iter().enumerate() {
            if j < nx {
                lin.a[(i, j)] = fi.d;
            } else {
                lin.b[(i, j - nx)] = fi.d;
            }
        }
        for (i, yi) in y.iter().enumerate() {
            if j < nx {
                lin.c[(i, j)] = yi.d;
            } else {
                lin.d[(i, j - nx)] = yi.d;
            }
        }
    }
    lin
}

/// d f / d s at `s` in the steady wind `w`, exact: column j carries the derivative seeded on
/// state j.
pub fn closed_loop_jacobian(cl: &dyn ClosedLoop, s: &[f64], w: &[f64; 3]) -> Jacobian {
    let n = s.len();
    let mut jac = Jacobian::zeros(n, n);
    let w = w.map(Dual::constant);
    for j in 0..n {
        let mut sd: Vec<Dual> = s.iter().map(|&x| Dual::constant(x)).collect();
        sd[j].d = 1.0;
        let (f, _) = cl.eval_dual(&sd, &w);
        for i in 0..n {
            jac[(i, j)] = f[i].d;
        }
    }
    jac
}

/// Newton's method from rest at the reference: exact there with mass compensation, a few
/// millimetres of altitude droop without. The pseudo-inverse lets it step past the directions
/// with no feedback (a position with zero gains), where any point is an equilibrium.
/// In a steady wind `w` the drag moves the equilibrium a little (no integral action).
fn equilibrium(cl: &dyn ClosedLoop, w: &[f64; 3]) -> (Vec<f64>, f64) {
    let start = cl.rest();
    let norm = |f: &[f64]| f.iter().map(|x| x * x).sum::<f64>().sqrt();
    let f_at = |s: &[f64]| cl.eval(s, w).0;
    let mut s = start.clone();
    let mut res = norm(&f_at(&s));
    for _ in 0..50 {
        if res < 1e-13 {
            break;
        }
        let f = DVector::from_vec(f_at(&s));
        let jac = closed_loop_jacobian(cl, &s, w);
        // Bounded SVD: the plain one never returns on a non-finite Jacobian.
        let svd = crate::svd::bounded(jac, true, true, f64::EPSILON, MAX_ITERATIONS);
        let Some(Ok(step)) = svd.map(|svd| svd.solve(&f, 1e-12)) else {
            break;
        };
        let mut next = s.clone();
        for (x, d) in next.iter_mut().zip(step.iter()) {
            *x -= d;
        }
        let next_res = norm(&f_at(&next));
        // Stop when Newton no longer helps (or produced NaN).
        if next_res.is_nan() || next_res >= res {
            break;
        }
        (s, res) = (next, next_res);
    }
    if res < 1e-9 {
        (s, res)
    } else {
        // No hover equilibrium (e.g. a steady climb or sink): report at the reference point.
        let r = norm(&f_at(&start));
        (start, r)
    }
}

/// Groups of states that the Jacobian couples (connected components of its sparsity graph).
fn blocks(jac: &Jacobian) -> Vec<Vec<usize>> {
    let n = jac.nrows();
    let scale = jac.amax().max(1.0);
    let mut group: Vec<usize> = (0..n).collect();
    // Label propagation: each state takes the smallest label it is coupled to, until stable.
    let mut changed = true;
    while changed {
        changed = false;
        for i in 0..n {
            for j in 0..n {
                let coupled =
                    jac[(i, j)].abs() > 1e-12 * scale || jac[(j, i)].abs() > 1e-12 * scale;
                if coupled && group[j] < group[i] {
                    group[i] = group[j];
                    changed = true;
                }
            }
        }
    }
    let mut out: Vec<Vec<usize>> = Vec::new();
    for label in 0..n {
        let members: Vec<usize> = (0..n).filter(|&i| group[i] == label).collect();
        if !members.is_empty() {
            out.push(members);
        }
    }
    out
}

/// Eigenvalues of the block's sub-matrix, each with a unit eigenvector over the block's states.
/// Iterations allowed to the Schur and SVD solvers (they converge in tens on a 14x14).
const MAX_ITERATIONS: usize = 10_000;

fn eigen(jac: &Jacobian, block: &[usize]) -> Vec<(Complex<f64>, Vec<Complex<f64>>)> {
    let n = block.len();
    let sub = DMatrix::from_fn(n, n, |i, j| jac[(block[i], block[j])]);
    // nalgebra's plain `complex_eigenvalues`/`svd` iterate without bound, which never ends on
    // a non-finite matrix (an absurd but legal scenario): bound them and report NaN instead.
    let nan = Complex::new(f64::NAN, f64::NAN);
    let values: Vec<Complex<f64>> = if n == 1 {
        vec![Complex::new(sub[(0, 0)], 0.0)]
    } else if !sub.iter().all(|x| x.is_finite()) {
        vec![nan; n]
    } else {
        match Schur::try_new(sub.clone(), f64::EPSILON, MAX_ITERATIONS) {
            Some(schur) => schur.complex_eigenvalues().iter().copied().collect(),
            None => vec![nan; n],
        }
    };
    let csub = sub.map(|x| Complex::new(x, 0.0));
    values
        .into_iter()
        .map(|lambda| (lambda, null_vector(&csub, lambda)))
        .collect()
}

/// A unit eigenvector of `a` for `lambda`: the right singular vector of (A - lambda I) with
/// the least singular value (NaN if the solver gives up).
fn null_vector(a: &DMatrix<Complex<f64>>, lambda: Complex<f64>) -> Vec<Complex<f64>> {
    let n = a.nrows();
    let shifted = a - DMatrix::from_diagonal_element(n, n, lambda);
    let svd = lambda
        .is_finite()
        .then(|| crate::svd::bounded(shifted, false, true, f64::EPSILON, MAX_ITERATIONS))
        .flatten();
    match svd {
        Some(svd) => {
            let k = svd.singular_values.argmin().0;
            let v_t = svd.v_t.expect("asked for V");
            v_t.row(k).iter().map(|c| c.conj()).collect()
        }
        None => vec![Complex::new(f64::NAN, f64::NAN); n],
    }
}

/// The actuator states' share of a pole: the sum of their participation factors |v_i w_i| /
/// sum_j |v_j w_j| (v right, w left eigenvector over the block). Unlike eigenvector shares it
/// does not depend on the states' units: a rotor speed (hundreds of rad/s) follows every slow
/// mode with large components, yet takes little part in it.
fn actuator_participation(
    vars: &[StateVar],
    jac: &Jacobian,
    block: &[usize],
    lambda: Complex<f64>,
    v: &[Complex<f64>],
) -> f64 {
    let n = block.len();
    let sub_t = DMatrix::from_fn(n, n, |i, j| Complex::new(jac[(block[j], block[i])], 0.0));
    let w = null_vector(&sub_t, lambda);
    let p: Vec<f64> = v.iter().zip(&w).map(|(a, b)| (a * b).norm()).collect();
    let total: f64 = p.iter().sum();
    let actuator: f64 = block
        .iter()
        .zip(&p)
        .filter(|(&i, _)| vars[i].part == Part::Actuator)
        .map(|(_, x)| x)
        .sum();
    actuator / total.max(f64::MIN_POSITIVE)
}

/// A vehicle symmetric in x and y (equal inertias and gains) has each lateral and swing mode
/// twice at one eigenvalue; the eigensolver then returns any basis of that plane, often two
/// vectors leaning to the same axis, and both would be named after it. Name such a pair once
/// per axis: one mode in x and one in y is what the repeated eigenvalue means.
fn name_both_axes(poles: &mut [Pole]) {
    const PAIRS: [(&str, &str); 2] = [
        (MODE_LATERAL_X, MODE_LATERAL_Y),
        (MODE_SWING_X, MODE_SWING_Y),
    ];
    let same = |a: &Pole, b: &Pole| {
        let scale = a.re.hypot(a.im).max(1.0);
        (a.re - b.re).abs() <= 1e-9 * scale && (a.im - b.im).abs() <= 1e-9 * scale
    };
    for i in 0..poles.len() {
        for j in i + 1..poles.len() {
            let Some(&(x, y)) = PAIRS
                .iter()
                .find(|(x, y)| [*x, *y].contains(&poles[i].mode))
            else {
                break;
            };
            if poles[j].mode == poles[i].mode && same(&poles[i], &poles[j]) {
                let other = if poles[i].mode == x { y } else { x };
                // Neither is named after the other axis yet at this eigenvalue.
                if !poles.iter().any(|p| p.mode == other && same(p, &poles[i])) {
                    poles[j].mode = other;
                }
            }
        }
    }
}

/// Indices of the states of `vars` that satisfy `keep`, in order.
fn states_where(vars: &[StateVar], keep: impl Fn(&StateVar) -> bool) -> Vec<usize> {
    (0..vars.len()).filter(|&i| keep(&vars[i])).collect()
}

/// A pole's description from its right eigenvector `v` over `block`. `actuator` is the
/// actuator states' participation (`actuator_participation`): above one half the pole is an
/// actuator mode; otherwise it is named, and its shares and dominant state taken, over the
/// airframe and payload states only (the actuator states' components are in their own units).
fn describe(
    vars: &[StateVar],
    lambda: Complex<f64>,
    block: &[usize],
    v: &[Complex<f64>],
    actuator: f64,
    lateral_source: bool,
) -> Pole {
    let mut full = vec![Complex::new(0.0, 0.0); vars.len()];
    for (&i, c) in block.iter().zip(v) {
        full[i] = *c;
    }
    let is_actuator_mode = actuator > 0.5;
    let counted = |s: &StateVar| is_actuator_mode || s.part != Part::Actuator;
    let mag: Vec<f64> = full
        .iter()
        .zip(vars)
        .map(|(c, s)| if counted(s) { c.norm() } else { 0.0 })
        .collect();
    let total = mag
        .iter()
        .map(|a| a * a)
        .sum::<f64>()
        .max(f64::MIN_POSITIVE);
    let share = |states: &[usize]| states.iter().map(|&i| mag[i] * mag[i]).sum::<f64>() / total;
    let on = |axes: &[Axis]| states_where(vars, |s| axes.contains(&s.axis));
    let lateral_share = share(&states_where(vars, |s| s.axis.lateral()));
    let groups = [
        (MODE_LATERAL_X, share(&on(&[Axis::X, Axis::Pitch]))),
        (MODE_LATERAL_Y, share(&on(&[Axis::Y, Axis::Roll]))),
        (MODE_VERTICAL, share(&on(&[Axis::Z]))),
        (MODE_YAW, share(&on(&[Axis::Yaw]))),
    ];
    let mut mode = if is_actuator_mode {
        MODE_ACTUATOR
    } else {
        groups
            .iter()
            .max_by(|a, b| a.1.total_cmp(&b.1))
            .expect("four groups")
            .0
    };
    // The payload mode moves the payload against the quadrotor; the vertical modes carry both
    // together (the attachment barely stretches).
    let payload_z = states_where(vars, |s| s.part == Part::Payload && s.axis == Axis::Z);
    if mode == MODE_VERTICAL {
        if let Some(&zc) = payload_z.first() {
            if (full[zc] - full[ix::Z]).norm() > full[ix::Z].norm() {
                mode = MODE_PAYLOAD;
            }
        }
    }
    // A swing mode moves the payload sideways more than the quadrotor, and against it (the
    // lateral modes of the controller carry the payload along, or barely move it).
    for (lateral, swing, axis, own) in [
        (MODE_LATERAL_X, MODE_SWING_X, Axis::X, ix::X),
        (MODE_LATERAL_Y, MODE_SWING_Y, Axis::Y, ix::Y),
    ] {
        let payload = states_where(vars, |s| s.part == Part::Payload && s.axis == axis);
        if let (true, Some(&c)) = (mode == lateral, payload.first()) {
            let (load, vehicle) = (full[c], full[own]);
            if load.norm() > vehicle.norm() && (load - vehicle).norm() > vehicle.norm() {
                mode = swing;
            }
        }
    }
    let dominant = (0..vars.len())
        .max_by(|&a, &b| mag[a].total_cmp(&mag[b]))
        .map_or("", |i| vars[i].name);
    Pole {
        re: lambda.re,
        im: lambda.im,
        mode,
        dominant,
        lateral_share,
        // Vertical and yaw modes are driven by every flight (take-off, gravity, initial yaw).
        excited: lateral_share < 1e-3 || lateral_source,
        verdict: Verdict::of(lambda.re),
    }
}

/// What moves a flight sideways. The lateral states start at zero and, with no lateral force,
/// stay exactly zero (the paper flies vertically: x = y = 0 throughout), so an unstable lateral
/// mode is harmless unless one of these sets it off. Yaw alone does not: it rotates a zero
/// lateral command.
pub fn lateral_sources(cfg: &Config) -> Vec<&'static str> {
    let mut out = Vec::new();
    let w = cfg.trajectory.points();
    let [x0, y0, _] = cfg.initial.position;
    if w.iter().any(|p| p[0] != w[0][0] || p[1] != w[0][1]) {
        out.push("waypoints move in x/y");
    }
    if x0 != w[0][0] || y0 != w[0][1] {
        out.push("initial x/y off the first waypoint");
    }
    if cfg.initial.attitude[0] != 0.0 || cfg.initial.attitude[1] != 0.0 {
        out.push("initial roll/pitch");
    }
    let g = &cfg.gust;
    let blowing = g.enabled && g.end > g.start && g.start < cfg.integrator.duration;
    let horizontal = [GustComponent::Longitudinal, GustComponent::Lateral];
    if blowing && cfg.turbulence_w20() > 0.0 && g.components.iter().any(|c| horizontal.contains(c))
    {
        out.push("horizontal gust components");
    }
    if blowing && (g.mean_wind[0] != 0.0 || g.mean_wind[1] != 0.0) {
        out.push("horizontal mean wind");
    }
    if cfg.wind.speed != 0.0 {
        out.push("wind.speed (a horizontal mean wind over the whole flight)");
    }
    if cfg
        .wind
        .gusts
        .iter()
        .any(|d| d.amplitude[0] != 0.0 || d.amplitude[1] != 0.0)
    {
        out.push("horizontal discrete gusts");
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::actuator::Ideal;
    use crate::model::paper_ix::{self as ix, NX};
    use crate::model::payload::Spring;
    use crate::model::AnyVehicle;
    use crate::scenario::tests::paper;

    /// Rows of C and D (the paper layout).
    const NY: usize = NX + SIGNAL_OUTPUTS.len();

    fn paper_vehicle(cfg: &Config) -> crate::model::PaperVehicle {
        AnyVehicle::new(&cfg.model_context()).vehicle::<Spring, Ideal>()
    }

    fn poles_of(a: &Analysis, mode: &str) -> Vec<Complex<f64>> {
        a.poles
            .iter()
            .filter(|p| p.mode == mode)
            .map(|p| Complex::new(p.re, p.im))
            .collect()
    }

    /// Coefficients (highest power first, monic) of prod (s - r).
    fn poly_from_roots(roots: &[Complex<f64>]) -> Vec<Complex<f64>> {
        let mut c = vec![Complex::new(1.0, 0.0)];
        for r in roots {
            let mut next = vec![Complex::new(0.0, 0.0); c.len() + 1];
            for (k, ck) in c.iter().enumerate() {
                next[k] += ck;
                next[k + 1] -= ck * r;
            }
            c = next;
        }
        c
    }

    /// The poles of `mode` are exactly the roots of `coeffs` (highest power first).
    fn assert_roots(a: &Analysis, mode: &str, coeffs: &[f64]) {
        let roots = poles_of(a, mode);
        assert_eq!(roots.len(), coeffs.len() - 1, "{mode}: {roots:?}");
        let got = poly_from_roots(&roots);
        for (k, (g, want)) in got.iter().zip(coeffs).enumerate() {
            let want = want / coeffs[0];
            assert!(
                (g.re - want).abs() <= 1e-8 * want.abs().max(1.0) && g.im.abs() < 1e-8,
                "{mode}: coefficient {k}: {g} vs {want} (poles {roots:?})"
            );
        }
    }

    /// A sampled law whose loops' common period is past `MAX_PERIOD_STEPS` (a position loop
    /// at 1e-300 Hz, its steps past usize; two loops whose 9973 and 9967 steps share no factor,
    /// a common period of 99.4 M steps) is analysed by the continuous model, saying so, where
    /// flying the period for the discrete-time model never ended; the longest it flies gives
    /// the discrete-time model.
    #[test]
    fn a_period_too_long_to_fly_is_the_continuous_models() {
        let dt = paper().integrator.dt;
        let continuous = analyse(&paper(), ControllerKind::Pd);
        let cases = [
            (1e-300, 0.0, f64::MAX),
            (
                1.0 / (9973.0 * dt),
                1.0 / (9967.0 * dt),
                9973.0 * 9967.0 * dt,
            ),
        ];
        for (position, attitude, period) in cases {
            let mut cfg = paper();
            cfg.controller.position_rate = Some(position);
            cfg.controller.attitude_rate = Some(attitude);
            let a = analyse(&cfg, ControllerKind::Pd);
            assert_eq!(a.period, None);
            let unmodelled = a.unmodelled_period.expect("said");
            assert!(unmodelled >= period.min(usize::MAX as f64 * dt) * (1.0 - 1e-12));
            assert_eq!(a.jacobian, continuous.jacobian);
            assert_eq!(a.verdict, continuous.verdict);
        }
        let mut cfg = paper();
        cfg.controller.position_rate = Some(1.0 / (MAX_PERIOD_STEPS as f64 * dt));
        let a = analyse(&cfg, ControllerKind::Pd);
        let longest = MAX_PERIOD_STEPS as f64 * dt;
        assert!((a.period.expect("sampled") - longest).abs() < 1e-9 * longest);
        assert_eq!(a.unmodelled_period, None);
    }

    #[test]
    fn paper_pd_is_stable() {
        let a = analyse(&paper(), ControllerKind::Pd);
        assert_eq!(a.verdict, Verdict::Stable, "{:?}", a.poles);
        assert_eq!(a.poles.len(), NX);
        assert!(a.residual < 1e-12);
    }

    #[test]
    fn paper_smc_is_laterally_unstable_near_1_3_pm_3_9j() {
        let a = analyse(&paper(), ControllerKind::Smc);
        assert_eq!(a.verdict, Verdict::Unstable);
        let top = &a.poles[0];
        assert!(top.mode.starts_with("lateral"), "{top:?}");
        assert!(
            (top.re - 1.3).abs() < 0.2 && (top.im.abs() - 3.9).abs() < 0.2,
            "{top:?}"
        );
        for p in &a.poles {
            if p.verdict != Verdict::Stable {
                assert!(
                    p.mode.starts_with("lateral") && p.lateral_share > 0.999,
                    "{p:?}"
                );
                // The paper flies vertically: nothing pushes it sideways.
                assert!(!p.excited, "{p:?}");
            }
        }
        let mut cfg = paper();
        cfg.gust.components.push(GustComponent::Lateral);
        let a = analyse(&cfg, ControllerKind::Smc);
        assert!(a
            .poles
            .iter()
            .filter(|p| p.verdict == Verdict::Unstable)
            .all(|p| p.excited));
        assert_eq!(a.lateral_sources, ["horizontal gust components"]);
        // ... unless the gust blows only after the flight has ended
        cfg.gust.start = cfg.integrator.duration + 1.0;
        cfg.gust.end = cfg.gust.start + 1.0;
        assert!(lateral_sources(&cfg).is_empty());
        // each other source on its own
        type Change = fn(&mut Config);
        let cases: [(Change, &str); 4] = [
            (
                |c| c.trajectory.waypoints[1][1] = 1.0,
                "waypoints move in x/y",
            ),
            (
                |c| c.initial.position[1] = 0.1,
                "initial x/y off the first waypoint",
            ),
            (|c| c.initial.attitude[0] = 0.01, "initial roll/pitch"),
            (|c| c.gust.mean_wind[0] = 2.0, "horizontal mean wind"),
        ];
        for (change, source) in cases {
            let mut cfg = paper();
            change(&mut cfg);
            let a = analyse(&cfg, ControllerKind::Smc);
            assert_eq!(a.lateral_sources, [source]);
            assert!(a
                .poles
                .iter()
                .filter(|p| p.verdict == Verdict::Unstable)
                .all(|p| p.excited));
        }
    }

    /// Linearised SMC channel: v = K lambda e + (lambda + K) edot with K = eta + eps / gamma
    /// (sat'(0) = 1 / gamma).
    fn smc_k(eta: f64, eps: f64, gamma: f64) -> f64 {
        eta + eps / gamma
    }

    #[test]
    fn yaw_poles_match_the_hand_derived_loops() {
        let cfg = paper();
        // PD: Izz psi'' = kp (0 - psi) + kd (0 - r).
        let pd = analyse(&cfg, ControllerKind::Pd);
        let k = &cfg.controller.pd;
        assert_roots(
            &pd,
            MODE_YAW,
            &[cfg.vehicle.inertia[2], k.kd_attitude[2], k.kp_attitude[2]],
        );
        // SMC (feedback-linearised with the nominal Izz = plant Izz): psi'' = v_psi, so
        // s^2 + (lambda + K) s + K lambda = (s + lambda)(s + K).
        let smc = analyse(&cfg, ControllerKind::Smc);
        let g = &cfg.controller.smc;
        let (l, kk) = (
            g.lambda_attitude[2],
            smc_k(g.eta_attitude[2], g.epsilon_attitude[2], g.gamma),
        );
        assert_roots(&smc, MODE_YAW, &[1.0, l + kk, kk * l]);
        let mut re: Vec<f64> = poles_of(&smc, MODE_YAW).iter().map(|p| p.re).collect();
        re.sort_by(f64::total_cmp);
        assert!(
            (re[0] + 5.54).abs() < 1e-9 && (re[1] + 1.5).abs() < 1e-9,
            "{re:?}"
        );
    }

    /// Vertical with payload: with k(s) = kc + cc s and the altitude law's linear part
    /// mt (a + b s), (m s^2 + mt (b s + a) + k)(mc s^2 + k) - k^2 = 0.
    fn vertical_poly(cfg: &Config, a: f64, b: f64) -> Vec<f64> {
        let (m, mc, kc, cc) = (
            cfg.vehicle.mass,
            cfg.payload.mass,
            cfg.stiffness(),
            cfg.payload.damping,
        );
        let mt = m + mc;
        // (m s^2 + (mt b + cc) s + (mt a + kc)) (mc s^2 + cc s + kc) - (cc s + kc)^2
        let p = [m, mt * b + cc, mt * a + kc];
        let q = [mc, cc, kc];
        let mut c = vec![0.0; 5];
        for (i, pi) in p.iter().enumerate() {
            for (j, qj) in q.iter().enumerate() {
                c[i + j] += pi * qj;
            }
        }
        c[2] -= cc * cc;
        c[3] -= 2.0 * cc * kc;
        c[4] -= kc * kc;
        c
    }

    #[test]
    fn vertical_and_payload_poles_match_the_fourth_order_loop() {
        let mut cfg = paper();
        cfg.payload.damping = 0.3; // exercise the damper term too
        let pd = analyse(&cfg, ControllerKind::Pd);
        let k = &cfg.controller.pd;
        let mut both = poles_of(&pd, MODE_VERTICAL);
        both.extend(poles_of(&pd, MODE_PAYLOAD));
        let want = vertical_poly(&cfg, k.kp[2], k.kd[2]);
        let got = poly_from_roots(&both);
        for (g, w) in got.iter().zip(&want) {
            assert!(
                (g.re - w / want[0]).abs() < 1e-8 * (w / want[0]).abs().max(1.0),
                "{got:?} {want:?}"
            );
        }
        // SMC: a = K lambda, b = lambda + K.
        let smc = analyse(&cfg, ControllerKind::Smc);
        let g = &cfg.controller.smc;
        let (l, kk) = (g.lambda[2], smc_k(g.eta[2], g.epsilon[2], g.gamma));
        let mut both = poles_of(&smc, MODE_VERTICAL);
        both.extend(poles_of(&smc, MODE_PAYLOAD));
        let want = vertical_poly(&cfg, kk * l, l + kk);
        let got = poly_from_roots(&both);
        for (g, w) in got.iter().zip(&want) {
            assert!(
                (g.re - w / want[0]).abs() < 1e-8 * (w / want[0]).abs().max(1.0),
                "{got:?} {want:?}"
            );
        }
        // The payload pair sits near the two-body spring frequency fn sqrt((m + mc) / m).
        let payload = poles_of(&smc, MODE_PAYLOAD);
        assert_eq!(payload.len(), 2, "{:?}", smc.poles);
        let f = payload[0].norm() / (2.0 * std::f64::consts::PI);
        assert!((f - 2.0 * (2.42f64 / 2.2).sqrt()).abs() < 0.2, "{f} Hz");
    }

    #[test]
    fn lateral_poles_match_the_cascade_polynomial() {
        // x'' = g theta, theta_des = Ux = v_x / g (mt = m + mc, U1 = (m + mc) g): the inner loop
        // s^2 + (la + Ka) s + la Ka closed around the outer lambda_x, K_x gives
        // s^2 (s^2 + (la + Ka) s + la Ka) + la Ka ((lx + Kx) s + lx Kx).
        let cfg = paper();
        let smc = analyse(&cfg, ControllerKind::Smc);
        let g = &cfg.controller.smc;
        let (lx, kx) = (g.lambda[0], smc_k(g.eta[0], g.epsilon[0], g.gamma));
        let (la, ka) = (
            g.lambda_attitude[1],
            smc_k(g.eta_attitude[1], g.epsilon_attitude[1], g.gamma),
        );
        assert_roots(
            &smc,
            MODE_LATERAL_X,
            &[
                1.0,
                la + ka,
                la * ka,
                la * ka * (lx + kx),
                la * ka * lx * kx,
            ],
        );
        // PD: s^2 (Iyy s^2 + kd s + kp) + kp (kdx s + kpx).
        let pd = analyse(&cfg, ControllerKind::Pd);
        let k = &cfg.controller.pd;
        let (kp, kd) = (k.kp_attitude[1], k.kd_attitude[1]);
        assert_roots(
            &pd,
            MODE_LATERAL_X,
            &[cfg.vehicle.inertia[1], kd, kp, kp * k.kd[0], kp * k.kp[0]],
        );
    }

    #[test]
    fn jacobian_matches_analytic_entries_and_finite_differences() {
        let cfg = paper();
        let plant = paper_vehicle(&cfg);
        let r = Reference {
            pos: [0.0, 0.0, 2.0],
            ..Reference::default()
        };
        let cl = closed_loop(&cfg, ControllerKind::Smc, r);
        let s0 = cl.rest();
        let jac = closed_loop_jacobian(&*cl, &s0, &[0.0; 3]);
        // d(ax)/d(theta) = U1 / (m + mc) = g at hover; d(ay)/d(phi) = -g.
        assert!((jac[(ix::VX, ix::THETA)] - 9.81).abs() < 1e-12);
        assert!((jac[(ix::VY, ix::PHI)] + 9.81).abs() < 1e-12);
        // d(azc)/d(z) = kc / mc; d(az)/d(zc) = kc / m.
        let (kc, m, mc) = (plant.payload.kc, plant.body.m, plant.payload.mc);
        assert!((jac[(ix::VZC, ix::Z)] - kc / mc).abs() < 1e-9);
        assert!((jac[(ix::VZ, ix::ZC)] - kc / m).abs() < 1e-9);
        // Off hover (every channel away from its kinks), central differences agree.
        let mut s = s0;
        for (i, x) in s.iter_mut().enumerate() {
            *x += 0.01 * (i as f64 + 1.0).sin();
        }
        let jac = closed_loop_jacobian(&*cl, &s, &[0.0; 3]);
        let h = 1e-6;
        for j in 0..NX {
            let (mut up, mut down) = (s.clone(), s.clone());
            up[j] += h;
            down[j] -= h;
            let (fu, fd) = (cl.eval(&up, &[0.0; 3]).0, cl.eval(&down, &[0.0; 3]).0);
            for i in 0..NX {
                let fdiff = (fu[i] - fd[i]) / (2.0 * h);
                assert!(
                    (fdiff - jac[(i, j)]).abs() < 1e-5 * fdiff.abs().max(1.0),
                    "({i}, {j}): {fdiff} vs {}",
                    jac[(i, j)]
                );
            }
        }
    }

    #[test]
    fn linearisation_in_still_air_is_the_stability_jacobian_and_wind_enters_at_second_order() {
        for kind in [ControllerKind::Pd, ControllerKind::Smc] {
            let cfg = paper();
            let a = analyse(&cfg, kind);
            let l = linearise(&cfg, kind, [0.0; 3]);
            assert_eq!(a.jacobian, l.a);
            assert_eq!(l.b, DMatrix::<f64>::zeros(NX, NU));
            assert_eq!(l.d, DMatrix::<f64>::zeros(NY, NU));
            assert_eq!(l.c.nrows(), NY);
            // Outputs: the states themselves, then e_o = zc - z + d0.
            for i in 0..NX {
                for j in 0..NX {
                    assert_eq!(l.c[(i, j)], if i == j { 1.0 } else { 0.0 });
                }
            }
            assert_eq!(l.c[(NX, ix::ZC)], 1.0);
            assert_eq!(l.c[(NX, ix::Z)], -1.0);
            // azc is the payload's row of A.
            for j in 0..NX {
                assert_eq!(l.c[(NY - 1, j)], l.a[(ix::VZC, j)]);
            }
        }
    }

    #[test]
    fn wind_jacobian_is_the_drag_slope_and_matches_finite_differences() {
        let mut cfg = paper();
        cfg.payload.damping = 0.5;
        let w0 = [0.7, -0.4, 1.5];
        let l = linearise(&cfg, ControllerKind::Smc, w0);
        assert!(l.residual < 1e-10, "{}", l.residual);
        let plant = paper_vehicle(&cfg);
        let (m, mc) = (plant.body.m, plant.payload.mc);
        // At the equilibrium the bodies are at rest, so the relative speed is |w0|:
        // d/dw of -k (v - w)|v - w| is 2 k |w0|, with k = rho CdA / 2.
        let bz = 2.0 * plant.body.drag_quad * w0[2].abs() / m;
        assert!((l.b[(ix::VZ, 2)] - bz).abs() < 1e-12 * bz);
        let bzc = 2.0 * plant.payload.drag_payload * w0[2].abs() / mc;
        assert!((l.b[(ix::VZC, 2)] - bzc).abs() < 1e-12 * bzc);
        assert!((l.d[(NY - 1, 2)] - bzc).abs() < 1e-12 * bzc);
        let bx = 2.0 * plant.body.drag_lateral * w0[0].abs() / (m + mc);
        assert!((l.b[(ix::VX, 0)] - bx).abs() < 1e-12 * bx);
        // B and D by central differences of the same closed loop.
        let cl = closed_loop(&cfg, ControllerKind::Smc, hover_reference(&cfg));
        let h = 1e-6;
        for j in 0..NU {
            let (mut up, mut down) = (w0, w0);
            up[j] += h;
            down[j] -= h;
            let (fu, yu) = cl.eval(&l.equilibrium, &up);
            let (fd, yd) = cl.eval(&l.equilibrium, &down);
            for i in 0..NX {
                let fdiff = (fu[i] - fd[i]) / (2.0 * h);
                assert!((fdiff - l.b[(i, j)]).abs() < 1e-6 * fdiff.abs().max(1.0));
            }
            for i in 0..NY {
                let fdiff = (yu[i] - yd[i]) / (2.0 * h);
                assert!((fdiff - l.d[(i, j)]).abs() < 1e-6 * fdiff.abs().max(1.0));
            }
        }
        // The drag also damps: A gains -2 k |w0| / m on vz (PD: its own slope does not depend
        // on the operating point, unlike the SMC's sat(s), whose s moves off zero in a wind).
        let up = linearise(&cfg, ControllerKind::Pd, [0.0, 0.0, w0[2]]);
        let still = linearise(&cfg, ControllerKind::Pd, [0.0; 3]);
        let damp = up.a[(ix::VZ, ix::VZ)] - still.a[(ix::VZ, ix::VZ)];
        assert!((damp + bz).abs() < 1e-12, "{damp} vs {bz}");
        let damp = up.a[(ix::VZC, ix::VZC)] - still.a[(ix::VZC, ix::VZC)];
        assert!((damp + bzc).abs() < 1e-12, "{damp} vs {bzc}");
    }

    #[test]
    fn no_mass_compensation_linearises_at_the_drooped_equilibrium() {
        let mut cfg = paper();
        cfg.controller.mass_compensation = false;
        let a = analyse(&cfg, ControllerKind::Pd);
        // PD without compensation holds kp ez = mc g / m below the reference (test_flight too).
        let droop = 2.0 - a.equilibrium[ix::Z];
        assert!((droop - 0.22 * 9.81 / (2.2 * 1.5)).abs() < 1e-9, "{droop}");
        assert!(a.residual < 1e-9);
        assert_eq!(a.verdict, Verdict::Stable);
    }

    #[test]
    fn a_position_without_feedback_is_marginal() {
        let mut cfg = paper();
        cfg.controller.pd.kp[0] = 0.0;
        let a = analyse(&cfg, ControllerKind::Pd);
        assert_eq!(a.verdict, Verdict::Marginal, "{:?}", a.poles);
        let top = &a.poles[0];
        assert_eq!((top.re, top.mode), (0.0, MODE_LATERAL_X));
        // Neither altitude gain: a double integrator (defective zero eigenvalue, computed only
        // to ~1e-8) and the undamped spring: marginal, not unstable.
        let mut cfg = paper();
        cfg.controller.pd.kp[2] = 0.0;
        cfg.controller.pd.kd[2] = 0.0;
        let a = analyse(&cfg, ControllerKind::Pd);
        assert_eq!(a.verdict, Verdict::Marginal, "{:?}", a.poles);
        let marginal: Vec<_> = a
            .poles
            .iter()
            .filter(|p| p.verdict == Verdict::Marginal)
            .collect();
        assert_eq!(marginal.len(), 4, "{marginal:?}");
    }
}
