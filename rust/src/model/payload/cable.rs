//! The cable-slung payload (docs/model.md, "Cable-slung payload" and "The last metres"): a
//! point mass on a massless elastic cable that swings freely in 3-D and goes slack, hooked `h`
//! below the centre of gravity, its unstretched length L paid out and reeled in by a winch.
//! Four degrees of freedom: `xc, yc, zc, line` and `vxc, vyc, vzc, line_rate`.
//!
//! ```text
//! hook          a  = p + R hb,   hb = (0, 0, -h)
//! hook velocity va = v + R (w x hb),   w = (p, q, r), the body's rates
//! cable         d = pc - a,  l = |d|,  u = d / l,  ldot = u . (vc - va)
//! tension       T = H max(0, k (l - L) + c (ldot - L'))   if l > L,   else T = 0
//! payload       mc dvc/dt = -T u - mc g e3 + Fdc + Fg
//! quadrotor     m  dv/dt  =  U1 R e3 + T u - m g e3 + Fd
//! torque        tau += hb x (R^T (T u))
//! payload drag  Fdc = -1/2 rho CdA_c |vc - vw| (vc - vw)
//! winch         L'' = clamp(kw (r - L'), -aw, aw),   e = L* - L   (L* the route's target)
//!               r = clamp(clamp(kp e, -sqrt(aw |e|), sqrt(aw |e|)), -vw, vw),
//!               kw = 20 1/s,  kp = kw / 4
//! ground        n = zg - zc,  N = max(0, kg n - cg vzc) if n > 0, else 0
//!               Fg = (-mu N vxc / s, -mu N vyc / s, N),  s = sqrt(vxc^2 + vyc^2 + eps^2)
//! ```
//!
//! The quadrotor's own drag Fd acts on its mass m alone: the payload is its own body. R and Fd
//! are the body's (`Frame`: the paper's Euler angles and inertial-axis drag, or the rigid
//! body's quaternion and body-axis drag); the state indices follow its layout.
//! The line is massless, so the tension the winch holds while paying out is the tension of the elastic
//! line, and the winch's work on the system is -T L' (`cable_tests.rs` checks the balance). The
//! winch is a speed servo stiff enough that the tension never slows it (a rated drum). H is the
//! hook: 1 while the parcel hangs, 0 from the step it opens (`payload.release`) on, when the
//! parcel leaves the vehicle's equations: its states still move (a free body on the ground),
//! but nothing of them reaches the quadrotor.

pub use super::release::Release;
use super::{AtState, Cue, LastMetres, Payload, PayloadModel, PayloadOutputs, PayloadView};
use crate::config::{non_negative, params::params, positive, ConfigError};
use crate::lane::{gather, Lane};
use crate::model::body::{Body, Frame};
use crate::model::{ix, Axis, Bound, Layout, ModelContext, OwnsKeys, Part, State, StateVar};

params! {
    /// The cable's own keys in `[payload]` (beside the point mass's, `model::payload::Shared`).
    /// Optional in the table, so that another kind's scenario reads without them; required
    /// when the cable flies (`validate`).
    pub struct CableParams {
        /// m, the cable's unstretched length L0 (required).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        cable_length: Option<f64> => "m", "Cable length, unstretched";
        /// m, the hook's distance below the centre of gravity along the body z axis (default 0).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        attachment_offset: Option<f64> => "m", "Hook below the centre of gravity";
        /// m/s, the winch's largest pay-out and reel-in speed (none: no winch, the line stays
        /// at `cable_length`).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        winch_speed: Option<f64> => "m/s", "Winch pay-out and reel-in speed";
        /// m/s^2, the winch's largest acceleration of the line.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        winch_acceleration: Option<f64> => "m/s^2", "Winch acceleration";
        /// m, the line reeled in (the start, and after the release; default `cable_length`).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        length_min: Option<f64> => "m", "Line length reeled in";
        /// When the hook opens: "touchdown" (the parcel rests on the ground with the line
        /// slack for `release_delay`) or a time in s; none: never.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        release: Option<Release> => "s", "Hook release, \"touchdown\", \"slack\", a time or a height";
        /// s, how long the parcel rests with the line slack before the hook opens (default 1).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        release_delay: Option<f64> => "s", "Rest before the hook opens";
        /// m, the parcel's height above the ground, as the vehicle knows it, below which the
        /// winch pays out at `approach_speed` (none: at `winch_speed` to the end).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        approach_height: Option<f64> => "m", "Final approach: height the winch slows at";
        /// m/s, the winch's pay-out speed below `approach_height`.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        approach_speed: Option<f64> => "m/s", "Final approach: pay-out speed";
        /// N, the measured tension below which the line is slack (`release = "slack"`).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        slack_tension: Option<f64> => "N", "Tension the hook reads as slack";
        /// N, the standard deviation of the load cell's white noise on the measured tension
        /// (default 0).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        tension_noise: Option<f64> => "N", "Load cell noise on the tension";
        /// s, the hook's condition ("touchdown", "slack", a height) is read from this time on
        /// (a `.plan`'s release item: not before the mission reaches it; default: always).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        release_after: Option<f64> => "s", "Hook's condition read from this time on";
    }
}

/// m/s, the friction's regularisation speed: below it the Coulomb force grows linearly with
/// the sliding speed (a resting parcel is held, not chattering between signs).
pub const FRICTION_SPEED: f64 = 0.01;
/// m/s, a parcel on the ground slower than this rests (`payload.release = "touchdown"`).
pub const REST_SPEED: f64 = 0.1;
/// s, the release delay without `payload.release_delay`.
pub const RELEASE_DELAY: f64 = 1.0;
/// s, how long a released parcel rests on the ground (slower than REST_SPEED) before it is
/// still: from then on nothing of it is integrated (its states held) and its metrics stop.
/// Many contact periods (2 pi sqrt(m / kg), 31 ms for 0.5 kg on 20 kN/m): a bounce's turning
/// point is not a rest.
pub const SETTLE_TIME: f64 = 0.5;
/// The downwash's edge: the wake's speed falls from full to 0 over r_w (1 -+ WAKE_EDGE), a
/// cubic smoothstep (C1; the band symmetric about r_w keeps the column's area).
const WAKE_EDGE: f64 = 0.1;
/// 1/s, the winch's speed loop gain kw: the line's rate follows its command with a 50 ms lag
/// (a drum's motor), within the acceleration limit. A constant: neither the speed nor the
/// acceleration limit slows the servo (before the sixth round's fix kw was 4 a / v, so a
/// faster winch paid out slower on a short lowering).
pub const WINCH_SPEED_GAIN: f64 = 20.0;
/// 1/s, the position loop's gain kp near the target, kw / 4: the pair critically damped (both
/// poles at -kw / 2), so the line stops at its length without overshoot.
const WINCH_POSITION_GAIN: f64 = WINCH_SPEED_GAIN / 4.0;

/// Cable payload parameters: `L = f64` for one vehicle, a lane type for one per lane.
#[derive(Clone, Copy, Debug)]
pub struct Cable<L = f64> {
    /// kg.
    pub mc: L,
    /// N/m (axial stiffness k) and N s/m (axial damping c).
    pub k: L,
    pub c: L,
    /// m, the unstretched length L0.
    pub rest_length: L,
    /// m, the hook's distance h below the centre of gravity (body z axis).
    pub offset: L,
    /// 1/2 rho CdA of the payload (in every direction).
    pub drag_payload: L,
    /// m, the length at hover l_eq = L0 + mc g / k.
    pub hover_length: L,
    /// 1 / mc, computed once.
    inv_mc: L,
    /// The winch: m/s and m/s^2 (its bounds), m (the reeled-in length and the full line).
    pub winch_speed: L,
    pub winch_acceleration: L,
    pub length_min: L,
    pub length_max: L,
    /// m, the length the winch drives the line to (set by the route: `last_metres`).
    pub target: L,
    /// The ground under the parcel: m (its height), N/m, N s/m, - (friction).
    pub ground: L,
    pub ground_k: L,
    /// s/m, Hunt and Crossley's dissipation alpha: N = kg d (1 + alpha d').
    pub ground_alpha: L,
    pub friction: L,
    /// Any lane's parcel can meet the ground (else the contact is not computed at all).
    pub contact: bool,
    /// The hook: s (a release time, or infinity), 1 or 0 (opens on touchdown), s (the delay).
    pub release_at: L,
    pub release_on_touchdown: L,
    pub release_delay: L,
    /// The slack hook (`release = "slack"`, any lane): 1 or 0 per lane, N (the threshold and
    /// the noise's sigma), s (how long the measured tension has been below it), 1 or 0 (below
    /// it at the last step). A drop: m (the parcel's known height the hook opens at, once it
    /// has been above it; minus infinity: never), 1 once it has been above it.
    pub slack_release: bool,
    pub release_on_slack: L,
    pub slack_tension: L,
    pub tension_noise: L,
    slack_for: L,
    was_slack: L,
    pub release_height: L,
    drop_armed: L,
    /// Events: 1 while hooked, 1 once touched down, s resting with the line slack.
    pub hooked: L,
    touched: L,
    resting: L,
    /// The final approach: m (the parcel's known height the winch slows below; minus
    /// infinity: never), m/s (the pay-out speed there; `winch_speed` without one), m/s (the
    /// pay-out speed of this step).
    pub approach_height: L,
    pub approach_speed: L,
    payout_speed: L,
    /// The lowering's own pay-out speed (m/s; infinity: the winch's), and s, the time the
    /// hook's condition is read from (`release_after`).
    lowering_speed: L,
    pub release_from: L,
    /// 1 once the released parcel is still on the ground (SETTLE_TIME at rest): its states
    /// are held from then on.
    still: L,
    /// The rotors' downwash on the released parcel (`vehicle.downwash`, any lane; 1 or 0 per
    /// lane), 1 / sqrt(2 rho A) times 2 (the far wake's speed per sqrt(N) of thrust) and m,
    /// the far wake's radius (the disk area A halved, as one column).
    pub downwash: bool,
    pub wake_on: L,
    pub wake_gain: L,
    pub wake_radius: L,
    /// The parcel's velocity at the previous step and the one before, and its position at
    /// the previous step: the contact instant is located from them (`touchdown.rs`).
    approach: [L; 3],
    before: [L; 3],
    last_pos: [L; 3],
}

/// The cable's states and the quadrotor's it reads, on the body of attitude `F` (the actuator's
/// states come after all of them).
struct Ix {
    xc: usize,
    line: usize,
    vx: usize,
    p: usize,
    vxc: usize,
    vline: usize,
}

impl Ix {
    #[inline(always)]
    fn of<L: Lane, F: Frame<L>>() -> Self {
        let lay: Layout = F::layout(4, 0);
        Self {
            xc: lay.payload(),
            line: lay.payload() + 3,
            vx: lay.vel(),
            p: lay.rate(),
            vxc: lay.payload_vel(),
            vline: lay.payload_vel() + 3,
        }
    }
}

const fn payload(name: &'static str, axis: Axis, bound: Bound) -> StateVar {
    StateVar::new(name, axis, Some(bound), Part::Payload)
}

impl OwnsKeys for Cable {
    type Params = CableParams;

    /// The cable's keys: the length is required and positive, the hook's offset at least 0;
    /// neither may be given when another payload flies.
    fn validate(c: &CableParams, flown: bool, cfg: &ModelContext) -> Result<(), ConfigError> {
        if !flown {
            // Each value as the scenario gives it: a release at touchdown is a word.
            let shown = |x: Option<f64>| x.map(|x| format!("{x:?}"));
            let release = c.release.map(|r| r.shown());
            for (key, value) in [
                ("payload.cable_length", shown(c.cable_length)),
                ("payload.attachment_offset", shown(c.attachment_offset)),
                ("payload.winch_speed", shown(c.winch_speed)),
                ("payload.winch_acceleration", shown(c.winch_acceleration)),
                ("payload.length_min", shown(c.length_min)),
                ("payload.release", release),
                ("payload.release_delay", shown(c.release_delay)),
                ("payload.approach_height", shown(c.approach_height)),
                ("payload.approach_speed", shown(c.approach_speed)),
                ("payload.slack_tension", shown(c.slack_tension)),
                ("payload.tension_noise", shown(c.tension_noise)),
                ("payload.release_after", shown(c.release_after)),
                ("ground.stiffness", shown(cfg.ground.stiffness)),
                (
                    "trajectory.lower",
                    shown(cfg.trajectory.lower.iter().copied().find(|x| *x != 0.0)),
                ),
            ] {
                if let Some(x) = value {
                    return Err(ConfigError::new(
                        key,
                        format!(
                            "{key} applies to payload.model = \"cable\" only, got {x} with \
                             payload.model = \"{}\"",
                            cfg.payload.model.name()
                        ),
                    ));
                }
            }
            return Ok(());
        }
        let Some(l0) = c.cable_length else {
            return Err(ConfigError::new(
                "payload.cable_length",
                "payload.cable_length must be given for payload.model = \"cable\"",
            ));
        };
        positive("payload.cable_length", l0)?;
        if let Some(h) = c.attachment_offset {
            non_negative("payload.attachment_offset", h)?;
        }
        Self::validate_last_metres(c, l0, cfg)
    }
}

impl Payload for Cable {
    type At<L: Lane> = Cable<L>;
    const POSITIONS: &'static [StateVar] = &[
        payload("xc", Axis::X, Bound::Distance),
        payload("yc", Axis::Y, Bound::Distance),
        payload("zc", Axis::Z, Bound::Distance),
        // The winch's line: no motion of the load by itself (stability names it apart).
        payload("line", Axis::Other, Bound::Distance),
    ];
    const VELOCITIES: &'static [StateVar] = &[
        payload("vxc", Axis::X, Bound::Speed),
        payload("vyc", Axis::Y, Bound::Speed),
        payload("vzc", Axis::Z, Bound::Speed),
        payload("line_rate", Axis::Other, Bound::Speed),
    ];

    fn new(c: &CableParams, cfg: &ModelContext) -> Self {
        let p = &cfg.payload;
        let k = cfg.stiffness();
        let length_max = c.cable_length.unwrap_or(f64::NAN); // required: `validate`
        let rest_length = c.length_min.unwrap_or(length_max);
        // Without a winch the line is held at its length by the same servo (its own modes,
        // at -kw / 2 = -10 1/s, stay apart from the vehicle's: nothing drives them).
        let (v, a) = (
            c.winch_speed.unwrap_or(1.0),
            c.winch_acceleration.unwrap_or(1.0),
        );
        let g = &cfg.ground;
        let (release_at, on_touchdown) = match c.release {
            Some(Release::At(t)) => (t, 0.0),
            Some(Release::Touchdown) => (f64::INFINITY, 1.0),
            _ => (f64::INFINITY, 0.0),
        };
        let on_slack = c.release == Some(Release::Slack);
        let release_height = match c.release {
            Some(Release::Height(h)) => h,
            _ => f64::NEG_INFINITY,
        };
        Self {
            mc: p.mass,
            k,
            c: p.damping,
            rest_length,
            offset: c.attachment_offset.unwrap_or(0.0),
            drag_payload: 0.5 * cfg.gust.air_density * p.drag_area,
            hover_length: rest_length + p.mass * cfg.environment.gravity / k,
            inv_mc: 1.0 / p.mass,
            winch_speed: v,
            winch_acceleration: a,
            length_min: rest_length,
            length_max,
            target: rest_length,
            ground: g.altitude,
            ground_k: g.stiffness.unwrap_or(0.0),
            ground_alpha: g.dissipation.unwrap_or(0.0),
            friction: g.friction.unwrap_or(0.0),
            contact: g.stiffness.is_some(),
            release_at,
            release_on_touchdown: on_touchdown,
            release_delay: c.release_delay.unwrap_or(RELEASE_DELAY),
            slack_release: on_slack,
            release_on_slack: if on_slack { 1.0 } else { 0.0 },
            slack_tension: c.slack_tension.unwrap_or(0.0),
            tension_noise: c.tension_noise.unwrap_or(0.0),
            slack_for: 0.0,
            was_slack: 0.0,
            release_height,
            drop_armed: 0.0,
            hooked: 1.0,
            touched: 0.0,
            resting: 0.0,
            approach_height: c
                .approach_height
                .filter(|_| c.approach_speed.is_some())
                .unwrap_or(f64::NEG_INFINITY),
            approach_speed: c.approach_speed.unwrap_or(v),
            payout_speed: v,
            lowering_speed: f64::INFINITY,
            release_from: c.release_after.unwrap_or(f64::NEG_INFINITY),
            still: 0.0,
            downwash: cfg.vehicle.downwash,
            wake_on: if cfg.vehicle.downwash { 1.0 } else { 0.0 },
            wake_gain: wake_gain(cfg.vehicle.rotor_radius, cfg.gust.air_density),
            wake_radius: wake_radius(cfg.vehicle.rotor_radius),
            approach: [0.0; 3],
            before: [0.0; 3],
            last_pos: [0.0; 3],
        }
    }

    /// The stretched line below the hook, the hook below the centre of gravity.
    fn hover_drop(&self) -> f64 {
        self.hover_length + self.offset
    }

    fn gather<L: Lane>(each: &[&Self]) -> Cable<L> {
        gather!(|l| each[l] => Cable {
            mc, k, c, rest_length, offset, drag_payload, hover_length, inv_mc, winch_speed,
            winch_acceleration, length_min, length_max, target, ground,
            ground_k, ground_alpha, friction, release_at, release_on_touchdown, release_delay,
            hooked, touched, resting, approach_height, approach_speed, payout_speed, approach,
            before, last_pos, release_on_slack, slack_tension, tension_noise, slack_for,
            was_slack, release_height, drop_armed, lowering_speed, release_from, still, wake_on,
            wake_gain, wake_radius;
            downwash: each.iter().any(|p| p.downwash),
            contact: each.iter().any(|p| p.contact),
            slack_release: each.iter().any(|p| p.slack_release)
        })
    }
}

/// Rotors in the wake's disk area: a quadrotor's four.
const ROTORS: f64 = 4.0;

/// 2 / sqrt(2 rho A), A = 4 pi R^2: the far wake's speed 2 v_i = 2 sqrt(T / (2 rho A)) per
/// sqrt(N) of the thrust T (momentum theory in hover; docs/model.md, "The rotors' downwash").
pub fn wake_gain(radius: f64, rho: f64) -> f64 {
    2.0 / (2.0 * rho * ROTORS * std::f64::consts::PI * radius * radius).sqrt()
}

/// m, the far wake's radius: one column of the disk area halved, sqrt(A / (2 pi)) = R sqrt(2).
pub fn wake_radius(radius: f64) -> f64 {
    (ROTORS * radius * radius / 2.0).sqrt()
}

/// `[f(0), f(1), f(2)]`, always inlined (`array::map` is not guaranteed to be: see
/// `model::state_from_fn`).
#[inline(always)]
fn vec3<L: Copy>(f: impl Fn(usize) -> L) -> [L; 3] {
    [f(0), f(1), f(2)]
}

#[inline(always)]
fn dot<L: Lane>(a: &[L; 3], b: &[L; 3]) -> L {
    a[0].mul_add(b[0], a[1].mul_add(b[1], a[2] * b[2]))
}

/// `value` where `gate > 0`, else 0, for `value >= 0`, without a branch (the model is generic
/// over lane types that have no select). `max(gate, 0) * MAX * MAX` is 0 where `gate <= 0`
/// and at least 1.6e293 (or infinite) where `gate > 0`, even at the least subnormal, so the
/// `min` returns `value` exactly there; NaN propagates.
#[inline(always)]
fn where_positive<L: Lane>(gate: L, value: L) -> L {
    value.min(L::splat(0.0).max(gate) * f64::MAX * f64::MAX)
}

/// The cable at one state: what both the dynamics and the outputs read.
#[derive(Clone, Copy, Debug)]
pub struct Line<L> {
    /// The hook's inertial position a (m).
    pub hook: [L; 3],
    /// pc - a (m) and its length l (m).
    pub d: [L; 3],
    pub length: L,
    /// The unit vector u from the hook to the payload.
    pub u: [L; 3],
    /// N, the tension T (never negative; exactly 0 while slack).
    pub tension: L,
}

impl<L: Lane> Cable<L> {
    /// The hook, the cable's direction and its tension at `s` (whose attitude is `frame`).
    #[inline(always)]
    pub fn line<F: Frame<L>, const N: usize>(&self, s: &State<L, N>, frame: &F) -> Line<L> {
        let Ix {
            xc,
            line: ln,
            vxc,
            vline,
            ..
        } = Ix::of::<L, F>();
        let (hook, va) = self.hook::<F, N>(s, frame);
        let d: [L; 3] = vec3(
            #[inline(always)]
            |i| s[xc + i] - hook[i],
        );
        let length = dot(&d, &d).sqrt();
        let inv = L::splat(1.0) / length;
        let u = vec3(
            #[inline(always)]
            |i| d[i] * inv,
        );
        let rel = vec3(
            #[inline(always)]
            |i| s[vxc + i] - va[i],
        );
        // The strain's rate is that of the distance less the pay-out: ldot - L'.
        let ldot = dot(&u, &rel) - s[vline];
        let stretch = length - s[ln];
        let pull = L::splat(0.0).max(stretch.mul_add(self.k, self.c * ldot));
        Line {
            hook,
            d,
            length,
            u,
            // The hook open: nothing of the line reaches either body.
            tension: where_positive(self.hooked, where_positive(stretch, pull)),
        }
    }

    /// The hook's inertial position a and velocity va at `s` (whose attitude is `frame`).
    #[inline(always)]
    fn hook<F: Frame<L>, const N: usize>(&self, s: &State<L, N>, frame: &F) -> ([L; 3], [L; 3]) {
        let Ix { vx, p, .. } = Ix::of::<L, F>();
        let [ex, ey, ez] = &frame.axes();
        let h = self.offset;
        // a = p + R (0, 0, -h);  va = v + R (w x hb) with w x hb = (-h q, h p, 0).
        let hook: [L; 3] = vec3(
            #[inline(always)]
            |i| (-h).mul_add(ez[i], s[ix::X + i]),
        );
        let (hq, hp) = (h * s[p + 1], h * s[p]);
        let va: [L; 3] = vec3(
            #[inline(always)]
            |i| hp.mul_add(ey[i], (-hq).mul_add(ex[i], s[vx + i])),
        );
        (hook, va)
    }

    /// Some lane's parcel below the ground's height at `s` (or not finite): else the ground's
    /// force is zero in every lane and is not computed (adding it would add zeros).
    #[inline(always)]
    fn touches<F: Frame<L>, const N: usize>(&self, s: &State<L, N>) -> bool {
        let xc = Ix::of::<L, F>().xc;
        self.contact && (self.ground - s[xc + 2]).le_mask(L::splat(0.0)) != L::ALL
    }

    /// N, the ground's force on the parcel at `s` (zero where it does not touch; only called
    /// when a lane touches, `touches`).
    #[inline(always)]
    fn ground_force<F: Frame<L>, const N: usize>(&self, s: &State<L, N>) -> [L; 3] {
        let Ix { xc, vxc, .. } = Ix::of::<L, F>();
        let depth = self.ground - s[xc + 2];
        let (vx, vy, vz) = (s[vxc], s[vxc + 1], s[vxc + 2]);
        // Hunt and Crossley: kg d (1 + alpha d'), d' = -vzc: no force at d = 0 whatever the
        // speed (no jump at the first contact), the damping growing with the depth.
        let spring = depth * self.ground_k;
        let normal = where_positive(
            depth,
            L::splat(0.0).max(spring * (-self.ground_alpha).mul_add(vz, L::splat(1.0))),
        );
        let slide = vx.mul_add(
            vx,
            vy.mul_add(vy, L::splat(FRICTION_SPEED * FRICTION_SPEED)),
        );
        let k = -(self.friction * normal) / slide.sqrt();
        [vx * k, vy * k, normal]
    }

    /// L'', the winch's speed servo driving the line toward `target` within its bounds: the
    /// rate command is the speed limit, or the speed from which half the acceleration limit
    /// stops the line at its target (sqrt(a |e|): the other half is the speed loop's to follow
    /// the profile, so the line never overshoots), or near the target kp e, whichever is least
    /// (a trapezoidal profile: the line reaches its speed v / a after it starts).
    #[inline(always)]
    fn winch<F: Frame<L>, const N: usize>(&self, s: &State<L, N>) -> L {
        let Ix {
            line: ln, vline, ..
        } = Ix::of::<L, F>();
        let v = self.winch_speed;
        let a = self.winch_acceleration;
        let e = self.target - s[ln];
        let stop = (a * e.abs()).sqrt();
        // Paying out no faster than this step's speed (the final approach's, below its height).
        let rate = (e * WINCH_POSITION_GAIN)
            .clamp(-stop, stop)
            .clamp(-v, self.payout_speed);
        ((rate - s[vline]) * WINCH_SPEED_GAIN).clamp(-a, a)
    }

    /// m/s, the rotors' downwash at the released parcel (downward; docs/model.md, "The
    /// rotors' downwash"): the far wake 2 v_i of the thrust `u1` within the column of radius
    /// r_w below the vehicle's centre, its edge smoothed over r_w (1 -+ WAKE_EDGE), 0 above the
    /// vehicle, on the hook and without `vehicle.downwash`.
    #[inline(always)]
    fn wake<F: Frame<L>, const N: usize>(&self, s: &State<L, N>, u1: L) -> L {
        let xc = Ix::of::<L, F>().xc;
        let one = L::splat(1.0);
        let (dx, dy) = (s[xc] - s[ix::X], s[xc + 1] - s[ix::Y]);
        let r = dx.mul_add(dx, dy * dy).sqrt();
        let band = self.wake_radius * (2.0 * WAKE_EDGE);
        let x = ((self.wake_radius * (1.0 + WAKE_EDGE) - r) / band).clamp(L::splat(0.0), one);
        let edge = x * x * (x * -2.0 + 3.0);
        let below = where_positive(s[ix::Z] - s[xc + 2], one);
        let speed = self.wake_gain * L::splat(0.0).max(u1).sqrt();
        speed * edge * below * self.wake_on * (one - self.hooked)
    }

    /// Some lane's parcel is released where the downwash blows (else it is not computed).
    #[inline(always)]
    fn blown(&self) -> bool {
        self.downwash && self.hooked.le_mask(L::splat(0.5)) != 0
    }

    /// mc dvc/dt = -T u - mc g e3 + Fdc: the payload's inertial acceleration (0 once the
    /// released parcel is still); the air it moves through is the wind `w` and, released,
    /// the rotors' downwash of the thrust `u1`.
    #[inline(always)]
    fn acceleration<F: Frame<L>, const N: usize>(
        &self,
        body: &Body<L>,
        s: &State<L, N>,
        line: &Line<L>,
        w: &[L; 3],
        u1: L,
    ) -> [L; 3] {
        let vxc = Ix::of::<L, F>().vxc;
        let mut air = *w;
        if self.blown() {
            air[2] = air[2] - self.wake::<F, N>(s, u1);
        }
        let rel = vec3(
            #[inline(always)]
            |i| s[vxc + i] - air[i],
        );
        let k = dot(&rel, &rel).sqrt() * (-self.drag_payload);
        let mut a = vec3(
            #[inline(always)]
            |i| rel[i].mul_add(k, -(line.tension * line.u[i])) * self.inv_mc,
        );
        if self.touches::<F, N>(s) {
            let f = self.ground_force::<F, N>(s);
            for i in 0..3 {
                a[i] = f[i].mul_add(self.inv_mc, a[i]);
            }
        }
        a[2] = a[2] - body.g;
        if self.any_still() {
            let moving = L::splat(1.0) - self.still;
            for x in a.iter_mut() {
                *x = *x * moving;
            }
        }
        a
    }

    /// Some lane's released parcel is still (its states held).
    #[inline(always)]
    fn any_still(&self) -> bool {
        self.still.le_mask(L::splat(0.0)) != L::ALL
    }

    /// rad, the cable's angle from hanging straight down, acos(-u_z), as 2 asin(|u + e3| / 2):
    /// accurate at small angles (acos loses half the digits near 1), clamped against rounding.
    #[inline(always)]
    fn swing(line: &Line<L>) -> L {
        let [dx, dy, dz] = line.d;
        let up = dz + line.length;
        let chord = dx.mul_add(dx, dy.mul_add(dy, up * up)).sqrt();
        let half = chord / (line.length * 2.0);
        L::splat(1.0).min(half).asin() * 2.0
    }
}

impl<L: Lane> PayloadModel<L> for Cable<L> {
    const DOF: usize = 4;

    #[inline(always)]
    fn accelerations<F: Frame<L>, const N: usize>(
        &self,
        at: &AtState<'_, L, F, N>,
        ds: &mut State<L, N>,
    ) -> Option<[L; 3]> {
        self.accelerations_of(at, &self.line(at.s, at.frame), ds)
    }

    #[inline(always)]
    fn outputs<F: Frame<L>, const N: usize>(&self, at: &AtState<'_, L, F, N>) -> PayloadOutputs<L> {
        let AtState {
            body,
            s,
            frame,
            u1,
            w,
        } = *at;
        let line = self.line(s, frame);
        let accel = self.acceleration::<F, N>(body, s, &line, w, u1);
        self.outputs_of::<F, N>(s, &line, accel)
    }

    /// The line and the payload's acceleration once for both (the same bits as apart).
    #[inline(always)]
    fn accelerations_and_outputs<F: Frame<L>, const N: usize>(
        &self,
        at: &AtState<'_, L, F, N>,
        _u1_out: L,
        ds: &mut State<L, N>,
    ) -> (Option<[L; 3]>, PayloadOutputs<L>) {
        let s = at.s;
        let line = self.line(s, at.frame);
        let torque = self.accelerations_of(at, &line, ds);
        // `accelerations_of` stored the payload's acceleration in `ds`.
        let vxc = Ix::of::<L, F>().vxc;
        let accel = [ds[vxc], ds[vxc + 1], ds[vxc + 2]];
        (torque, self.outputs_of::<F, N>(s, &line, accel))
    }

    /// The parcel relative to the hook (nothing once the hook is open).
    #[inline(always)]
    fn view<F: Frame<L>, const N: usize>(&self, s: &State<L, N>, frame: &F) -> PayloadView<L> {
        let Ix { xc, vxc, .. } = Ix::of::<L, F>();
        let (hook, va) = self.hook::<F, N>(s, frame);
        PayloadView {
            pos: vec3(
                #[inline(always)]
                |i| (s[xc + i] - hook[i]) * self.hooked,
            ),
            vel: vec3(
                #[inline(always)]
                |i| (s[vxc + i] - va[i]) * self.hooked,
            ),
        }
    }

    fn rest<F: Frame<L>, const N: usize>(&self, _body: &Body<L>, frame: &F, s: &mut State<L, N>) {
        // pc = a - l_eq e3, vc = v: hanging straight below the hook, moving with it.
        let Ix {
            xc,
            line,
            vx,
            vxc,
            vline,
            ..
        } = Ix::of::<L, F>();
        let ez = frame.axes()[2];
        for i in 0..3 {
            s[xc + i] = (-self.offset).mul_add(ez[i], s[ix::X + i]);
            s[vxc + i] = s[vx + i];
        }
        s[xc + 2] = s[xc + 2] - self.hover_length;
        s[line] = self.rest_length;
        s[vline] = L::splat(0.0);
    }

    /// The winch's target from the route, then the events of this step: first touchdown
    /// (the parcel below the ground's height), rest (on the ground, slower than REST_SPEED,
    /// the line slack) and the hook opening (at `release_at`, or after resting
    /// `release_delay`); released lanes reel the line in. Inlined into the flight loop: an
    /// out-of-line function is compiled for the baseline instruction set, so each lane
    /// operation in it would be a call.
    #[inline(always)]
    fn last_metres<F: Frame<L>, const N: usize>(
        &mut self,
        s: &State<L, N>,
        frame: &F,
        cue: &Cue<L>,
    ) -> Option<LastMetres<L>> {
        let Ix { xc, vxc, .. } = Ix::of::<L, F>();
        let (zero, one) = (L::splat(0.0), L::splat(1.0));
        let on = |gate: L| where_positive(gate, one);
        let vel = [s[vxc], s[vxc + 1], s[vxc + 2]];
        let pos = [s[xc], s[xc + 1], s[xc + 2]];
        let approach = std::mem::replace(&mut self.approach, vel);
        let before = std::mem::replace(&mut self.before, approach);
        let last_pos = std::mem::replace(&mut self.last_pos, pos);
        let (mut touchdown, mut contact) = (zero, zero);
        if self.contact {
            contact = on(self.ground - s[xc + 2]) * on(self.ground_k);
            touchdown = contact * (one - self.touched);
            self.touched = self.touched.max(contact);
            // Only a lane in contact rests: the line's tension is read only if one is.
            self.resting = if contact.le_mask(zero) == L::ALL {
                zero
            } else {
                let speed = dot(&vel, &vel).sqrt();
                let slack = one - on(self.line(s, frame).tension);
                let rests = contact * on(L::splat(REST_SPEED) - speed) * slack;
                (self.resting + cue.dt) * rests
            };
        }
        // Where and how fast the parcel met the ground: located inside the step that crossed
        // it (only in a step where some lane touches down).
        let (contact_pos, contact_vel) = if touchdown.le_mask(zero) == L::ALL {
            (pos, vel)
        } else {
            self.contact_instant(&last_pos, &approach, &before, cue.dt)
        };
        let half = cue.dt * 0.5;
        let known = self.known_height::<F, N>(s, cue.height);
        // The hook's conditions, read once the mission reaches the release (`release_after`).
        let armed = on(L::splat(cue.t + half) - self.release_from);
        let condition = (self.release_on_touchdown
            * on(self.resting - self.release_delay + half)
            * self.touched)
            .max(self.slack_hook::<F, N>(s, frame, cue))
            .max(self.drop_hook(known));
        let due = on(L::splat(cue.t + half) - self.release_at).max(condition * armed);
        let release = self.hooked * due;
        self.hooked = self.hooked - release;
        if let Some(lowering) = cue.payout {
            // Started over the point only (then kept: the target stays where it was set).
            let over = one - on(cue.off_drop);
            let target = self.length_min + L::splat(lowering.payout);
            self.target = target * over + self.target * (one - over);
            self.lowering_speed = L::splat(lowering.speed);
        }
        self.payout_speed = self.final_approach(known).min(self.lowering_speed);
        // Released: the winch reels the line in.
        self.target = self.target * self.hooked + self.length_min * (one - self.hooked);
        // Released and at rest for SETTLE_TIME: still from now on, its metrics stopped.
        self.still = self
            .still
            .max((one - self.hooked) * on(self.resting - SETTLE_TIME + half));
        let contact = contact * (one - self.still);
        Some(LastMetres {
            touchdown,
            contact,
            release,
            hooked: self.hooked,
            grounded: self.touched,
            pos,
            vel,
            contact_pos,
            contact_vel,
        })
    }
}

impl<L: Lane> Cable<L> {
    /// `PayloadModel::accelerations` with the line at `s` given.
    #[inline(always)]
    fn accelerations_of<F: Frame<L>, const N: usize>(
        &self,
        at: &AtState<'_, L, F, N>,
        line: &Line<L>,
        ds: &mut State<L, N>,
    ) -> Option<[L; 3]> {
        let AtState {
            body,
            s,
            frame,
            u1,
            w,
        } = *at;
        let pull = vec3(
            #[inline(always)]
            |i| line.tension * line.u[i],
        );
        let Ix { vx, vxc, .. } = Ix::of::<L, F>();
        let axes = &frame.axes();
        let fd = frame.drag(body, &[s[vx], s[vx + 1], s[vx + 2]], w);
        let thrust = &axes[2];
        for i in 0..3 {
            ds[vx + i] = thrust[i].mul_add(u1, pull[i] + fd[i]) * body.inv_m;
        }
        ds[vx + 2] = ds[vx + 2] - body.g;
        let ac = self.acceleration::<F, N>(body, s, line, w, u1);
        ds[vxc..vxc + 3].copy_from_slice(&ac);
        if self.any_still() {
            // A still parcel's position is held too (its velocity's derivative is 0 above).
            let xc = Ix::of::<L, F>().xc;
            let moving = L::splat(1.0) - self.still;
            for i in 0..3 {
                ds[xc + i] = ds[xc + i] * moving;
            }
        }
        ds[Ix::of::<L, F>().vline] = self.winch::<F, N>(s);
        // hb x f with hb = (0, 0, -h) and f = R^T (T u) = (ex . Tu, ey . Tu, ez . Tu).
        let h = self.offset;
        let (fx, fy) = (dot(&axes[0], &pull), dot(&axes[1], &pull));
        Some([h * fy, -(h * fx), L::splat(0.0)])
    }

    /// `PayloadModel::outputs` with the line at `s` and the payload's acceleration given.
    #[inline(always)]
    fn outputs_of<F: Frame<L>, const N: usize>(
        &self,
        s: &State<L, N>,
        line: &Line<L>,
        accel: [L; 3],
    ) -> PayloadOutputs<L> {
        let Ix { xc, line: ln, .. } = Ix::of::<L, F>();
        // Relative to the line's present length (the same bits while it is not paid out);
        // nothing once the hook is open.
        let e_o = ((s[xc + 2] - line.hook[2]) + self.hover_length) + (s[ln] - self.rest_length);
        PayloadOutputs {
            e_o: e_o * self.hooked,
            accel,
            tension: line.tension,
            swing: Self::swing(line) * self.hooked,
        }
    }
}

#[cfg(test)]
#[path = "cable_tests.rs"]
mod tests;

// The contact instant and the final approach (`Cable::contact_instant`, `final_approach`).
#[path = "touchdown.rs"]
mod touchdown;

// The last metres' keys (`Cable::validate_last_metres`).
#[path = "last_metres_checks.rs"]
mod last_metres_checks;

// The winch's servo against the step (`Cable::validate_winch_step`).
#[path = "winch_step.rs"]
mod winch_step;

#[cfg(test)]
#[path = "winch_tests.rs"]
mod winch_tests;
