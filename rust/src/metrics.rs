//! Per-phase indices of the relative oscillation e_o, accumulated online (docs/model.md section 5),
//! and the whole vehicle's (section 11): the magnitude of the payload's inertial acceleration
//! (`max_accel`, `rms_accel`), the specific force an accelerometer on the payload reads
//! (`max_specific_force`, |a - g|: how fragility is specified; docs/risk.md), the 3-D tracking error,
//! the attachment's swing and tension, slack and actuator saturation times.
//!
//! A metric is one entry of `metrics!` below: its name, unit and label, the signal it derives
//! from what the flight loop hands over at each step (`Views`), how the signal folds into the
//! phase's running sum (`fold`) and its value from that sum. Integrals use the trapezoidal rule
//! on the step grid. The amplitude spectrum needs the signal, so e_o is also kept
//! block-averaged at `metrics.spectrum_rate` (a few thousand numbers per flight, allocated once
//! per flight, never per step).

use crate::control::ControllerConfig;
use crate::lane::{KernelOps, Lane};
use crate::model::{PayloadOutputs, Rigid};
use crate::trajectory::{PhaseSteps, Reference};
use rustfft::{num_complex::Complex, FftPlanner};

/// One metric: its column name, its unit (SI, as the engine stores it; "-" for none), a
/// plain-English label (no unit: figures and tables add theirs) and its value from one
/// phase's running sums. The column order of every metrics array, `_core.METRIC_NAMES`,
/// `_core.METRIC_UNITS` and `_core.METRIC_LABELS` come from `METRICS`, which `metrics!` writes.
pub struct Metric {
    pub name: &'static str,
    pub unit: &'static str,
    pub label: &'static str,
    /// An event's value (a touchdown, a release): NaN in a phase or flight without the event,
    /// where every other metric is finite.
    pub event: bool,
    value: fn(&Totals) -> f64,
}

/// What the flight loop hands the metrics at one step (lane values): each metric derives its
/// signal from these views (`metrics!`).
#[derive(Clone, Copy)]
pub struct Views<'a, L> {
    /// s, the step's time.
    pub t: f64,
    /// The vehicle's rigid-body state.
    pub rigid: &'a Rigid<L>,
    /// The body's x, y and z axes in inertial axes (the columns of R).
    pub axes: [[L; 3]; 3],
    /// m/s^2, gravity.
    pub g: L,
    /// The payload's outputs (e_o, acceleration, tension, swing).
    pub out: &'a PayloadOutputs<L>,
    /// The reference.
    pub r: &'a Reference,
    /// m, the position error p_ref - p.
    pub e: &'a [L; 3],
    /// The straight line of the current leg (a point, a unit direction; `Trajectory::line`).
    pub line: &'a ([L; 3], [L; 3]),
    /// 1 where an actuator command was clamped over this step, else 0.
    pub saturated: L,
    /// The last metres (`LastSample::none()` for a payload without them).
    pub last: &'a LastSample<L>,
    /// m, the navigation's position error (estimate less truth; 0 where the laws read the
    /// state), and 1 where the laws fly the estimate, else 0.
    pub nav_error: [L; 3],
    pub navigating: L,
}

/// The laws' limits a metric may compare against (`given` in `metrics!`), one realisation's,
/// read from `[controller]`.
#[derive(Clone, Debug)]
pub struct LawLimits {
    /// rad, the bound on the commanded roll and pitch (`controller.tilt_limit`).
    pub tilt_limit: f64,
}

impl LawLimits {
    pub fn of(c: &ControllerConfig) -> Self {
        Self {
            tilt_limit: c.tilt_limit,
        }
    }
}

/// One lane's running sums over one phase, and what a value needs besides them.
pub struct Totals {
    /// Each metric's running sum, and its event's count (0 for a metric without one).
    s: PerMetric<f64>,
    n: PerMetric<f64>,
    /// s, the phase's length.
    span: f64,
    /// s, the step.
    dt: f64,
    /// Hz and m: the largest bin of e_o's amplitude spectrum (NaN when there is none).
    peak: (f64, f64),
}

impl Totals {
    /// sqrt(integral / span): the RMS of a signal whose squared integral is `sq`.
    fn rms(&self, sq: f64) -> f64 {
        (sq / self.span).sqrt()
    }
}

/// How a signal `x` folds into its running sum `s` at a step of trapezoid weight `w` (s) and
/// time `t`: `sum` adds it, `integral` its trapezoid area, `time_integral` its area times t,
/// `max` and `min` keep the extreme (from the initial value given, 0 by default).
macro_rules! fold {
    (sum, $s:expr, $x:expr, $w:expr, $t:expr) => {
        $s += $x
    };
    (integral, $s:expr, $x:expr, $w:expr, $t:expr) => {
        $s += $x * $w
    };
    (time_integral, $s:expr, $x:expr, $w:expr, $t:expr) => {
        $s += $x * ($w * $t)
    };
    (max, $s:expr, $x:expr, $w:expr, $t:expr) => {
        $s = $s.max($x)
    };
    (min, $s:expr, $x:expr, $w:expr, $t:expr) => {
        $s = $s.min($x)
    };
}

/// An event's value (`count`: how often it counted in the phase), NaN where it never did; a
/// metric without an event (`None`), its value.
fn gated(count: Option<f64>, value: f64) -> f64 {
    match count {
        Some(n) if n > 0.0 => value,
        Some(_) => f64::NAN,
        None => value,
    }
}

/// The first of its arguments, else the default (`$d`).
macro_rules! or {
    ($d:expr;) => {
        $d
    };
    ($d:expr; $x:expr) => {
        $x
    };
}

/// The metrics, in column order: per entry its name, `unit`, `label`, and
/// - `event: |v| flag`: an event's (1 at the steps it counts, else 0); the value is NaN in a
///   phase where it never counts;
/// - `given: |laws| value`: a number per realisation from the laws' limits (`LawLimits`), taken
///   once per flight and handed to the signal as its second argument;
/// - `signal: |v| x` or `|v, given| x`: the step's signal from the views `v` (a lane value), once
///   per step; an earlier entry's signal is the local of its name (shared, not recomputed);
/// - `fold`: how the signal folds into the phase's running sum (`fold!`; `max(init)`);
/// - `value: |totals, sum| x`: the phase's value from its running sum.
///
/// It writes `METRICS`, `N_METRICS`, `PerMetric` (a lane value per metric: the running sums,
/// the event counts, the given values and the signals of a step) and `PhaseAccumulator`'s fold.
macro_rules! metrics {
    ($(
        $(#[$doc:meta])*
        $name:ident {
            unit: $unit:literal,
            label: $label:literal,
            $(event: |$ev:pat_param| $event:expr,)?
            $(given: |$law:pat_param| $given:expr,)?
            $(
                signal: |$v:pat_param $(, $c:pat_param)?| $signal:expr,
                fold: $fold:ident $(($init:expr))?,
            )?
            value: |$t:pat_param, $x:pat_param| $value:expr,
        }
    )+) => {
        pub const N_METRICS: usize = [$(stringify!($name)),+].len();

        /// Every metric, in column order.
        pub const METRICS: [Metric; N_METRICS] = [$(
            Metric {
                name: stringify!($name),
                unit: $unit,
                label: $label,
                event: or!(false; $({ let _ = stringify!($event); true })?),
                value: |totals| {
                    let ($t, $x) = (totals, totals.s.$name);
                    let count = or!(None; $({
                        let _ = stringify!($event);
                        Some(totals.n.$name)
                    })?);
                    gated(count, $value)
                },
            },
        )+];

        /// One lane value per metric: its signal at a step, its running sum over a phase (from
        /// its fold's initial value), its event's count, its given value.
        #[derive(Clone, Copy, Debug)]
        pub struct PerMetric<L> {
            $($(#[$doc])* pub $name: L,)+
        }

        impl<L: Lane> PerMetric<L> {
            /// Each metric's initial running sum.
            fn start() -> Self {
                Self { $($name: L::splat(or!(0.0; $($($init)?)?)),)+ }
            }

            /// Zero for every metric.
            fn zero() -> Self {
                Self { $($name: L::splat(0.0),)+ }
            }

            fn lane(&self, lane: usize) -> PerMetric<f64> {
                PerMetric { $($name: self.$name.lane(lane),)+ }
            }

            /// Each metric's given value (0 without one) of the laws' limits, one per lane.
            fn given(laws: &[&LawLimits]) -> Self {
                Self {
                    $($name: L::from_fn(|_lane| {
                        or!(0.0; $({
                            let $law = laws[_lane];
                            $given
                        })?)
                    }),)+
                }
            }
        }

        impl<L: KernelOps> PhaseAccumulator<L> {
            /// The signals of the step whose views are `views`, folded into the running sums of
            /// every phase holding step `k` (k = 0, 1, 2, ... in turn). Returns the signals.
            #[inline(always)]
            pub fn sample(&mut self, k: usize, views: &Views<L>) -> PerMetric<L> {
                let t = views.t;
                $(
                    let $name: L = or!(L::splat(0.0); $({
                        let $v = views;
                        $(let $c = self.given.$name;)?
                        $signal
                    })?);
                )+
                let signals = PerMetric { $($name,)+ };
                let events = PerMetric {
                    $($name: or!(L::splat(0.0); $({
                        let $ev = views;
                        $event
                    })?),)+
                };
                for (ph, run) in self.phases.iter().zip(self.sums.iter_mut()) {
                    if ph.contains(k) {
                        let w = if k == ph.first || k == ph.last {
                            0.5 * self.dt
                        } else {
                            self.dt
                        };
                        $($(fold!($fold, run.s.$name, signals.$name, w, t);)?)+
                        $($(
                            let _ = stringify!($event);
                            run.n.$name += events.$name;
                        )?)+
                    }
                }
                self.block(views.out.e_o);
                signals
            }
        }
    };
}

metrics! {
    /// m s, the trapezoid integral of |e_o|.
    iae {
        unit: "m s",
        label: "Integrated absolute displacement, IAE",
        signal: |v| v.out.e_o.abs(),
        fold: integral,
        value: |_, x| x,
    }
    itae {
        unit: "m s^2",
        label: "Time-weighted IAE, ITAE",
        signal: |_| iae,
        fold: time_integral,
        value: |_, x| x,
    }
    max_abs {
        unit: "m",
        label: "Peak |payload relative displacement|",
        signal: |_| iae,
        fold: max,
        value: |_, x| x,
    }
    rms {
        unit: "m",
        label: "RMS payload relative displacement",
        signal: |v| v.out.e_o * v.out.e_o,
        fold: integral,
        value: |t, x| t.rms(x),
    }
    /// m^2, the squared 3-D position error |p_ref - p|^2.
    tracking_rms {
        unit: "m",
        label: "RMS 3-D tracking error",
        signal: |v| v.e[0] * v.e[0] + v.e[1] * v.e[1] + v.e[2] * v.e[2],
        fold: integral,
        value: |t, x| t.rms(x),
    }
    // The spectrum's peak: from the block-averaged e_o (`finish`), no signal of its own.
    peak_frequency {
        unit: "Hz",
        label: "Frequency of the displacement's spectral peak",
        value: |t, _| t.peak.0,
    }
    peak_amplitude {
        unit: "m",
        label: "Amplitude of the displacement's spectral peak",
        value: |t, _| t.peak.1,
    }
    /// m/s^2, the magnitude of the payload's inertial acceleration.
    /// The parcel's, while it hangs from the vehicle (0 once released: its fall and impact are
    /// the touchdown's metrics).
    max_accel {
        unit: "m/s^2",
        label: "Payload acceleration peak",
        signal: |v| {
            let [ax, ay, az] = v.out.accel;
            (ax * ax + ay * ay + az * az).sqrt() * v.last.attached
        },
        fold: max,
        value: |_, x| x,
    }
    rms_accel {
        unit: "m/s^2",
        label: "Payload acceleration RMS",
        signal: |_| max_accel * max_accel,
        fold: integral,
        value: |t, x| t.rms(x),
    }
    /// rad, the attachment's angle from the vertical.
    max_swing {
        unit: "rad",
        label: "Peak swing angle of the line",
        signal: |v| v.out.swing,
        fold: max,
        value: |_, x| x,
    }
    rms_swing {
        unit: "rad",
        label: "RMS swing angle of the line",
        signal: |_| max_swing * max_swing,
        fold: integral,
        value: |t, x| t.rms(x),
    }
    /// N, the force the attachment carries.
    max_tension {
        unit: "N",
        label: "Peak line tension",
        signal: |v| v.out.tension,
        fold: max(f64::NEG_INFINITY),
        value: |_, x| x,
    }
    min_tension {
        unit: "N",
        label: "Lowest line tension",
        signal: |_| max_tension,
        fold: min(f64::INFINITY),
        value: |_, x| x,
    }
    /// 1 where the attachment is slack (tension <= 0) while the parcel hangs, else 0.
    slack_time {
        unit: "s",
        label: "Time with the line slack",
        signal: |v| L::select(v.out.tension.cmp_le(L::splat(0.0)), v.last.attached, L::splat(0.0)),
        fold: sum,
        value: |t, x| x * t.dt,
    }
    saturated_time {
        unit: "s",
        label: "Time with a rotor at its limit",
        signal: |v| v.saturated,
        fold: sum,
        value: |t, x| x * t.dt,
    }
    max_tracking {
        unit: "m",
        label: "Peak 3-D tracking error",
        signal: |_| tracking_rms,
        fold: max,
        value: |_, x| x.sqrt(),
    }
    /// m^2, the squared distance from the current leg's straight line (cross-track error).
    rms_cross_track {
        unit: "m",
        label: "RMS cross-track error",
        signal: |v| cross_track_sq(&v.rigid.pos, v.line),
        fold: integral,
        value: |t, x| t.rms(x),
    }
    max_cross_track {
        unit: "m",
        label: "Peak cross-track error",
        signal: |_| rms_cross_track,
        fold: max,
        value: |_, x| x.sqrt(),
    }
    /// m^2/s^4, the squared specific force |a - g| (g pointing down): what an accelerometer on
    /// the payload reads (g at rest, 0 in free fall). Its largest square's root is the largest
    /// |a - g| bit for bit (a correctly rounded square root is monotone): one square root per
    /// flight, not per step. While the parcel hangs (0 once released).
    max_specific_force {
        unit: "m/s^2",
        label: "Peak specific force on the payload, |a - g|",
        signal: |v| specific_force_sq(&v.out.accel, v.g) * v.last.attached,
        fold: max,
        value: |_, x| x.sqrt(),
    }
    /// 1 where the tilt is past 90 % of the law's limit: cos(phi) cos(theta), the body's z
    /// axis' vertical component, at most cos(0.9 `tilt_limit`) (given once per flight).
    near_tilt_time {
        unit: "s",
        label: "Time with the tilt above 90 % of the law's limit",
        given: |laws| (0.9 * laws.tilt_limit).cos(),
        signal: |v, near| L::select(v.axes[2][2].cmp_le(near), L::splat(1.0), L::splat(0.0)),
        fold: sum,
        value: |t, x| x * t.dt,
    }
    // The last metres (docs/model.md): each event's value in the phase it falls in, NaN in
    // the others (and in a flight without it).
    touchdown_speed {
        unit: "m/s",
        label: "Parcel's vertical speed at touchdown",
        event: |v| v.last.touchdown,
        signal: |v| v.last.touchdown * v.last.touchdown_speed,
        fold: sum,
        value: |_, x| x,
    }
    touchdown_drift {
        unit: "m/s",
        label: "Parcel's horizontal speed at touchdown",
        event: |v| v.last.touchdown,
        signal: |v| v.last.touchdown * v.last.touchdown_drift,
        fold: sum,
        value: |_, x| x,
    }
    touchdown_miss {
        unit: "m",
        label: "Touchdown's distance from the drop point",
        event: |v| v.last.touchdown,
        signal: |v| v.last.touchdown * v.last.touchdown_miss,
        fold: sum,
        value: |_, x| x,
    }
    /// m, the height a free fall meets the ground at the touchdown's vertical speed from,
    /// v^2 / (2 g): the figure a parcel's drop test is rated by.
    touchdown_drop_height {
        unit: "m",
        label: "Touchdown's equivalent drop height",
        event: |v| v.last.touchdown,
        signal: |v| {
            let speed = v.last.touchdown_speed;
            v.last.touchdown * (speed * speed) / (v.g * 2.0)
        },
        fold: sum,
        value: |_, x| x,
    }
    /// m^2/s^4, the squared specific force |a - g| while the parcel touches the ground (its
    /// largest square's root: `max_specific_force`'s, over the contact alone).
    touchdown_peak_force {
        unit: "m/s^2",
        label: "Peak specific force on the parcel in contact with the ground",
        event: |v| v.last.contact,
        signal: |v| v.last.contact * specific_force_sq(&v.out.accel, v.g),
        fold: max,
        value: |_, x| x.sqrt(),
    }
    release_time {
        unit: "s",
        label: "Time the hook opens",
        event: |v| v.last.release,
        signal: |v| v.last.release * v.t,
        fold: sum,
        value: |_, x| x,
    }
    /// The largest height change within the window after the release.
    release_height_change {
        unit: "m",
        label: "Vehicle's largest height change in the 5 s after the release",
        event: |v| v.last.after_release,
        signal: |v| v.last.release_change,
        fold: max,
        value: |_, x| x,
    }
    lowering_swing {
        unit: "rad",
        label: "Peak swing angle of the line while lowering",
        signal: |v| v.last.lowering_swing,
        fold: max,
        value: |_, x| x,
    }
    // Containment (docs/risk.md): the margins to the operational volume the reference carries
    // (`Reference::corridor`, `[volume]`), about the current leg's line; NaN without a volume.
    /// m, the smallest margin to the flight geography: its half-width less the horizontal
    /// offset from the leg's line, or its half-height less the vertical offset.
    geography_margin {
        unit: "m",
        label: "Smallest margin to the flight geography",
        event: |v| in_volume(v),
        signal: |v| {
            let (across, up) = leg_offsets(&v.rigid.pos, v.line);
            let [w, h, _] = v.r.corridor.map(L::splat);
            (w - across).min(h - up)
        },
        fold: min(f64::INFINITY),
        value: |_, x| finite_or_nan(x),
    }
    /// m, the same margin to the operational volume (the geography and its contingency
    /// buffer): the geography's margin plus the buffer, step by step.
    volume_margin {
        unit: "m",
        label: "Smallest margin to the operational volume",
        event: |v| in_volume(v),
        signal: |v| geography_margin + L::splat(v.r.corridor[2]),
        fold: min(f64::INFINITY),
        value: |_, x| finite_or_nan(x),
    }
    /// 1 if the flight was outside the flight geography at any step of the phase, else 0.
    left_geography {
        unit: "-",
        label: "Left the flight geography",
        event: |v| in_volume(v),
        signal: |_| geography_margin,
        fold: min(f64::INFINITY),
        value: |_, x| outside(x),
    }
    /// 1 if the flight was outside the operational volume at any step of the phase (a
    /// containment loss), else 0.
    left_volume {
        unit: "-",
        label: "Left the operational volume",
        event: |v| in_volume(v),
        signal: |_| volume_margin,
        fold: min(f64::INFINITY),
        value: |_, x| outside(x),
    }
    // Navigation (docs/model.md, "Navigation"): the estimate the laws fly against the truth,
    // NaN where the laws read the state.
    /// m, the largest horizontal distance between the estimated and the true position.
    nav_error_max {
        unit: "m",
        label: "Peak horizontal navigation error",
        event: |v| v.navigating,
        signal: |v| {
            let [dx, dy, _] = v.nav_error;
            (dx * dx + dy * dy).sqrt()
        },
        fold: max,
        value: |_, x| x,
    }
    /// m, the RMS of that distance over the phase.
    nav_error_rms {
        unit: "m",
        label: "RMS horizontal navigation error",
        event: |v| v.navigating,
        signal: |_| nav_error_max * nav_error_max,
        fold: integral,
        value: |t, x| t.rms(x),
    }
    /// m, the largest vertical distance between the estimated and the true position.
    nav_error_vertical_max {
        unit: "m",
        label: "Peak vertical navigation error",
        event: |v| v.navigating,
        signal: |v| v.nav_error[2].abs(),
        fold: max,
        value: |_, x| x,
    }
}

/// A margin's value: NaN where no volume bounds it (the corridor is infinite).
/// 1 where the flight has an operational volume (`[volume]`), else 0: the volume's metrics are
/// NaN without one, as an event's are in a phase without the event.
#[inline(always)]
fn in_volume<L: Lane>(v: &Views<L>) -> L {
    L::splat(if v.r.corridor[0].is_finite() {
        1.0
    } else {
        0.0
    })
}

fn finite_or_nan(margin: f64) -> f64 {
    if margin.is_finite() {
        margin
    } else {
        f64::NAN
    }
}

/// 1 where the smallest margin is negative (outside), 0 inside, NaN without a volume.
fn outside(margin: f64) -> f64 {
    match finite_or_nan(margin) {
        m if m < 0.0 => 1.0,
        m if m >= 0.0 => 0.0,
        _ => f64::NAN,
    }
}

/// m, the offset of `p` from the line through `line.0` along the unit vector `line.1` (from
/// the point itself where the direction is zero), split into its horizontal length (across
/// the leg) and its vertical one (above or below it).
#[inline(always)]
fn leg_offsets<L: Lane>(p: &[L; 3], line: &([L; 3], [L; 3])) -> (L, L) {
    let q = line_offset(p, line);
    ((q[0] * q[0] + q[1] * q[1]).sqrt(), q[2].abs())
}

/// Column order of every metrics array the engine returns (`METRICS`' names).
pub const METRIC_NAMES: [&str; N_METRICS] = {
    let mut names = [""; N_METRICS];
    let mut i = 0;
    while i < N_METRICS {
        names[i] = METRICS[i].name;
        i += 1;
    }
    names
};

/// Squared distance from `p` to the line through `line.0` along the unit vector `line.1` (to
/// the point itself where the direction is zero): the squared cross-track error.
#[inline(always)]
fn cross_track_sq<L: Lane>(p: &[L; 3], line: &([L; 3], [L; 3])) -> L {
    let q = line_offset(p, line);
    q[0] * q[0] + q[1] * q[1] + q[2] * q[2]
}

/// The offset of `p` from the line through `line.0` along the unit vector `line.1`: the
/// component of `p - line.0` across the direction.
/// m^2/s^4, the squared specific force |a - g| of an acceleration `a` (g pointing down).
#[inline(always)]
fn specific_force_sq<L: Lane>(a: &[L; 3], g: L) -> L {
    let [ax, ay, az] = *a;
    let fz = az + g;
    ax * ax + ay * ay + fz * fz
}

#[inline(always)]
fn line_offset<L: Lane>(p: &[L; 3], line: &([L; 3], [L; 3])) -> [L; 3] {
    let (a, u) = line;
    let d = [p[0] - a[0], p[1] - a[1], p[2] - a[2]];
    let along = d[0] * u[0] + d[1] * u[1] + d[2] * u[2];
    [
        d[0] - along * u[0],
        d[1] - along * u[1],
        d[2] - along * u[2],
    ]
}

/// The last metres at one step (docs/model.md, "The last metres").
#[derive(Clone, Copy, Debug)]
pub struct LastSample<L> {
    /// 1 at the step of the parcel's first touchdown, else 0; its vertical speed (m/s,
    /// downward positive), horizontal speed (m/s) and distance from the drop point (m) there.
    pub touchdown: L,
    pub touchdown_speed: L,
    pub touchdown_drift: L,
    pub touchdown_miss: L,
    /// 1 while the parcel is in contact with the ground, else 0.
    pub contact: L,
    /// 1 while the parcel hangs from the vehicle (and for a payload that never leaves it),
    /// 0 once released: the parcel's metrics stop there.
    pub attached: L,
    /// 1 at the step the hook opens, else 0.
    pub release: L,
    /// 1 within the window after the release, else 0; m, |the vehicle's height error less its
    /// value at the release| there (0 elsewhere).
    pub after_release: L,
    pub release_change: L,
    /// rad, the line's swing while lowering (0 elsewhere).
    pub lowering_swing: L,
}

impl<L: Lane> LastSample<L> {
    /// Nothing of the last metres at this step.
    pub fn none() -> Self {
        let z = L::splat(0.0);
        Self {
            touchdown: z,
            touchdown_speed: z,
            touchdown_drift: z,
            touchdown_miss: z,
            contact: z,
            attached: L::splat(1.0),
            release: z,
            after_release: z,
            release_change: z,
            lowering_swing: z,
        }
    }
}

/// A phase's running sums and event counts (`PerMetric`).
#[derive(Clone, Copy)]
struct Running<L> {
    s: PerMetric<L>,
    n: PerMetric<L>,
}

/// Online accumulator for one lane-set over all phases.
pub struct PhaseAccumulator<L: Lane> {
    phases: Vec<PhaseSteps>,
    sums: Vec<Running<L>>,
    /// Each metric's given value (`metrics!`), per lane.
    given: PerMetric<L>,
    dt: f64,
    decimation: usize,
    /// Samples still to add before the current block is complete (avoids a `%` per step).
    block_left: usize,
    block_sum: L,
    blocks: Vec<L>,
}

impl<L: Lane> PhaseAccumulator<L> {
    /// `decimation`: steps per spectrum sample; `steps`: steps of the flight; `laws`: each
    /// lane's laws' limits.
    pub fn new(
        phases: &[PhaseSteps],
        dt: f64,
        decimation: usize,
        steps: usize,
        laws: &[&LawLimits],
    ) -> Self {
        let zero = L::splat(0.0);
        let run = Running {
            s: PerMetric::start(),
            n: PerMetric::zero(),
        };
        Self {
            phases: phases.to_vec(),
            sums: vec![run; phases.len()],
            given: PerMetric::given(laws),
            dt,
            decimation: decimation.max(1),
            block_left: decimation.max(1),
            block_sum: zero,
            blocks: Vec::with_capacity(steps / decimation.max(1) + 1),
        }
    }

    /// Add e_o's sample to the spectrum's current block.
    #[inline(always)]
    fn block(&mut self, e_o: L) {
        self.block_sum += e_o;
        self.block_left -= 1;
        if self.block_left == 0 {
            self.blocks
                .push(self.block_sum * (1.0 / self.decimation as f64));
            self.block_sum = L::splat(0.0);
            self.block_left = self.decimation;
        }
    }

    /// The indices of lane `lane`, one row per phase, columns as `METRICS`.
    /// `spectra` receives each phase's amplitude spectrum when given (see `spectrum_grid`).
    pub fn finish(
        &self,
        lane: usize,
        planner: &mut FftPlanner<f64>,
        mut spectra: Option<&mut [Vec<f64>]>,
    ) -> Vec<[f64; N_METRICS]> {
        let mut rows = Vec::with_capacity(self.phases.len());
        for (p, (ph, run)) in self.phases.iter().zip(&self.sums).enumerate() {
            let span = (ph.last - ph.first) as f64 * self.dt;
            let (lo, hi) = block_range(ph, self.decimation, self.blocks.len());
            let signal: Vec<f64> = self.blocks[lo..hi].iter().map(|b| b.lane(lane)).collect();
            let amp = amplitude_spectrum(&signal, planner);
            let df = 1.0 / (signal.len().max(1) as f64 * self.decimation as f64 * self.dt);
            let (peak_f, peak_a) =
                amp.iter()
                    .enumerate()
                    .skip(1)
                    .fold((f64::NAN, f64::NAN), |best, (i, &a)| {
                        if best.1.is_nan() || a > best.1 {
                            (i as f64 * df, a)
                        } else {
                            best
                        }
                    });
            if let Some(out) = spectra.as_deref_mut() {
                out[p] = amp;
            }
            let totals = Totals {
                s: run.s.lane(lane),
                n: run.n.lane(lane),
                span,
                dt: self.dt,
                peak: (peak_f, peak_a),
            };
            rows.push(METRICS.map(|m| (m.value)(&totals)));
        }
        rows
    }
}

/// Blocks lying wholly inside a phase: block j covers samples [j d, (j + 1) d).
fn block_range(ph: &PhaseSteps, d: usize, n_blocks: usize) -> (usize, usize) {
    let hi = ((ph.last + 1) / d).min(n_blocks);
    (ph.first.div_ceil(d).min(hi), hi)
}

/// Frequencies (Hz) of each phase's spectrum bins for a flight of `steps` steps.
pub fn spectrum_grid(
    phases: &[PhaseSteps],
    dt: f64,
    decimation: usize,
    steps: usize,
) -> Vec<Vec<f64>> {
    let n_blocks = (steps + 1) / decimation;
    phases
        .iter()
        .map(|ph| {
            let (lo, hi) = block_range(ph, decimation, n_blocks);
            let n = hi - lo;
            let df = 1.0 / (n.max(1) as f64 * decimation as f64 * dt);
            (0..n / 2 + 1).map(|i| i as f64 * df).collect()
        })
        .collect()
}

/// Single-sided amplitude spectrum of a real signal with its mean removed: a sinusoid of
/// amplitude A shows as a bin of height A (rectangular window, bins 0..=n/2).
pub fn amplitude_spectrum(signal: &[f64], planner: &mut FftPlanner<f64>) -> Vec<f64> {
    let n = signal.len();
    if n < 2 {
        return vec![0.0; n / 2 + 1];
    }
    let mean = signal.iter().sum::<f64>() / n as f64;
    let mut buf: Vec<Complex<f64>> = signal
        .iter()
        .map(|&x| Complex::new(x - mean, 0.0))
        .collect();
    planner.plan_fft_forward(n).process(&mut buf);
    buf.iter()
        .take(n / 2 + 1)
        .enumerate()
        .map(|(i, c)| {
            let one_sided = if i == 0 || (n.is_multiple_of(2) && i == n / 2) {
                1.0
            } else {
                2.0
            };
            one_sided * c.norm() / n as f64
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// What one test step hands the accumulator (one lane).
    struct Step {
        e_o: f64,
        e: [f64; 3],
        accel: [f64; 3],
        g: f64,
        swing: f64,
        tension: f64,
        saturated: f64,
        /// The body's z axis' vertical component, cos(phi) cos(theta).
        tilt_cos: f64,
        last: LastSample<f64>,
    }

    impl Step {
        fn quiet() -> Self {
            Self {
                e_o: 0.0,
                e: [0.0; 3],
                accel: [0.0; 3],
                g: 0.0,
                swing: 0.0,
                tension: 0.0,
                saturated: 0.0,
                tilt_cos: 1.0,
                last: LastSample::none(),
            }
        }

        /// Hand this step to `acc` at step `k`, time `t`.
        fn sample(&self, acc: &mut PhaseAccumulator<f64>, k: usize, t: f64) -> PerMetric<f64> {
            let rigid = Rigid {
                pos: [0.0; 3],
                att: [0.0; 3],
                vel: [0.0; 3],
                rate: [0.0; 3],
            };
            let out = PayloadOutputs {
                e_o: self.e_o,
                accel: self.accel,
                tension: self.tension,
                swing: self.swing,
            };
            let mut axes = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
            axes[2][2] = self.tilt_cos;
            acc.sample(
                k,
                &Views {
                    t,
                    rigid: &rigid,
                    axes,
                    g: self.g,
                    out: &out,
                    r: &Reference::default(),
                    e: &self.e,
                    line: &([0.0; 3], [1.0, 0.0, 0.0]),
                    saturated: self.saturated,
                    last: &self.last,
                    nav_error: [0.0; 3],
                    navigating: 0.0,
                },
            )
        }
    }

    /// A tilt limit of 0.5 rad: 90 % of it, 0.45 rad, has cos 0.9004.
    const LAWS: LawLimits = LawLimits { tilt_limit: 0.5 };

    #[test]
    fn amplitude_spectrum_finds_a_sinusoid() {
        let (n, fs) = (2000, 100.0);
        let sig: Vec<f64> = (0..n)
            .map(|i| 0.3 + 0.7 * (2.0 * std::f64::consts::PI * 2.5 * i as f64 / fs).sin())
            .collect();
        let amp = amplitude_spectrum(&sig, &mut FftPlanner::new());
        let (k, a) = amp
            .iter()
            .enumerate()
            .fold((0, 0.0), |b, (i, &a)| if a > b.1 { (i, a) } else { b });
        assert_eq!(k as f64 * fs / n as f64, 2.5);
        assert!((a - 0.7).abs() < 1e-9);
        assert!(amp[0].abs() < 1e-12, "mean removed");
    }

    #[test]
    fn trapezoid_integrals_of_a_known_signal() {
        // e(t) = t on [0, 1] with dt = 0.01: IAE = 1/2, ITAE = 1/3 (+dt^2/6 trapezoid error),
        // RMS = sqrt(1/3), max 1.
        let dt = 0.01;
        let ph = [PhaseSteps {
            first: 0,
            last: 100,
        }];
        let mut acc = PhaseAccumulator::<f64>::new(&ph, dt, 5, 100, &[&LAWS]);
        for k in 0..=100 {
            let t = k as f64 * dt;
            let flag = if k < 30 { 1.0 } else { 0.0 };
            let step = Step {
                e_o: t,
                e: [0.6 * t, 0.0, -0.8 * t],
                accel: [0.0, 0.0, -2.0 * t],
                g: 9.81,
                swing: 0.1 * t,
                tension: 5.0 - 10.0 * t,
                saturated: flag,
                tilt_cos: if k < 30 { 1.0 } else { 0.5 },
                last: LastSample {
                    touchdown: if k == 40 { 1.0 } else { 0.0 },
                    touchdown_speed: 0.7,
                    touchdown_drift: 0.2,
                    touchdown_miss: 0.3,
                    contact: if (40..=45).contains(&k) { 1.0 } else { 0.0 },
                    attached: 1.0,
                    release: if k == 60 { 1.0 } else { 0.0 },
                    after_release: if k >= 60 { 1.0 } else { 0.0 },
                    release_change: if k >= 60 { 0.01 * (k - 60) as f64 } else { 0.0 },
                    lowering_swing: if k < 40 { 0.1 * t } else { 0.0 },
                },
            };
            let signals = step.sample(&mut acc, k, t);
            // A signal shared by two metrics is one local: |a| (the trace's) for both.
            assert_eq!(signals.rms_accel, signals.max_accel * signals.max_accel);
        }
        let row = acc.finish(0, &mut FftPlanner::new(), None)[0];
        let at = |name: &str| row[METRIC_NAMES.iter().position(|n| *n == name).unwrap()];
        let rms_t = (1.0f64 / 3.0 + dt * dt / 6.0).sqrt();
        assert!((at("iae") - 0.5).abs() < 1e-12);
        assert!((at("itae") - (1.0 / 3.0 + dt * dt / 6.0)).abs() < 1e-12);
        assert!((at("max_abs") - 1.0).abs() < 1e-12);
        assert!((at("rms") - rms_t).abs() < 1e-12);
        // |e| = t: the same RMS and peak 1.
        assert!((at("tracking_rms") - rms_t).abs() < 1e-12);
        assert!((at("max_tracking") - 1.0).abs() < 1e-12);
        // accel = 2 t: peak 2, RMS 2 sqrt(1/3 + dt^2/6).
        assert!((at("max_accel") - 2.0).abs() < 1e-12);
        assert!((at("rms_accel") - 2.0 * rms_t).abs() < 1e-12);
        // swing = 0.1 t; tension 5 - 10 t from 5 down to -5, slack (<= 0) over the 51 steps
        // from t = 0.5 s; 30 saturated steps.
        assert!((at("max_swing") - 0.1).abs() < 1e-12);
        assert!((at("rms_swing") - 0.1 * rms_t).abs() < 1e-12);
        assert_eq!((at("max_tension"), at("min_tension")), (5.0, -5.0));
        assert!((at("slack_time") - 51.0 * dt).abs() < 1e-12);
        assert!((at("saturated_time") - 30.0 * dt).abs() < 1e-12);
        // The position on the leg's line: no cross-track error.
        assert_eq!((at("rms_cross_track"), at("max_cross_track")), (0.0, 0.0));
        // specific force 9.81 - 2 t: its peak at t = 0.
        assert_eq!(at("max_specific_force"), 9.81);
        // 71 steps near the tilt limit (cos 0.5 below cos 0.45); the touchdown's values
        // (0.7, 0.2, 0.3) at k = 40, the release at t = 0.6 s, the height change 0.4 m at its
        // window's end, the swing while lowering 0.1 t up to t = 0.39 s.
        assert!((at("near_tilt_time") - 71.0 * dt).abs() < 1e-12);
        assert_eq!(
            (
                at("touchdown_speed"),
                at("touchdown_drift"),
                at("touchdown_miss")
            ),
            (0.7, 0.2, 0.3)
        );
        // The drop height v^2 / 2g of 0.7 m/s; the peak specific force in contact (k = 40 to
        // 45), 9.81 - 2 t at its first step.
        assert_eq!(at("touchdown_drop_height"), 0.7 * 0.7 / (9.81 * 2.0));
        assert!((at("touchdown_peak_force") - (9.81 - 0.8)).abs() < 1e-12);
        assert_eq!(at("release_time"), 60.0 * dt);
        assert!((at("release_height_change") - 0.4).abs() < 1e-12);
        assert!((at("lowering_swing") - 0.039).abs() < 1e-12);
        // A phase without the events: NaN for them, 0 for the durations and peaks.
        let ph = [PhaseSteps { first: 0, last: 10 }];
        let mut acc = PhaseAccumulator::<f64>::new(&ph, dt, 5, 10, &[&LAWS]);
        for k in 0..=10 {
            Step::quiet().sample(&mut acc, k, k as f64 * dt);
        }
        let row = acc.finish(0, &mut FftPlanner::new(), None)[0];
        let at = |name: &str| row[METRIC_NAMES.iter().position(|n| *n == name).unwrap()];
        for name in [
            "touchdown_speed",
            "touchdown_drift",
            "touchdown_miss",
            "release_time",
            "release_height_change",
        ] {
            assert!(at(name).is_nan(), "{name}");
        }
        for m in METRICS.iter().filter(|m| m.event) {
            assert!(at(m.name).is_nan(), "{} is an event", m.name);
        }
        assert_eq!((at("near_tilt_time"), at("lowering_swing")), (0.0, 0.0));
    }

    /// The given value is taken per lane from that lane's laws' limits: a lane whose limit is
    /// wide is never near it where the other is.
    #[test]
    fn each_lane_compares_with_its_own_tilt_limit() {
        let wide = LawLimits { tilt_limit: 1.4 };
        let acc = PhaseAccumulator::<crate::lane::F64x4>::new(
            &[PhaseSteps { first: 0, last: 1 }],
            0.01,
            1,
            1,
            &[&LAWS, &wide, &LAWS, &wide],
        );
        assert_eq!(acc.given.near_tilt_time.lane(0), 0.45f64.cos());
        assert_eq!(acc.given.near_tilt_time.lane(1), (0.9 * 1.4f64).cos());
        assert_eq!(acc.given.iae.lane(2), 0.0);
    }

    /// The peak specific force taken as the square root of the peak square is the peak of the
    /// per-step square roots (what the flight loop took before), bit for bit.
    #[test]
    fn the_peak_of_square_roots_is_the_square_root_of_the_peak_square() {
        let ph = [PhaseSteps {
            first: 0,
            last: 999,
        }];
        let mut acc = PhaseAccumulator::<f64>::new(&ph, 0.01, 5, 999, &[&LAWS]);
        let mut peak = 0.0f64;
        let mut x = 0.123_456_789f64;
        for k in 0..=999 {
            // A scrambled sequence of specific forces around g (g = 0 here: a = a - g).
            x = (x * 3.987_654_321 + 0.314_159).fract();
            let [ax, ay, fz] = [x - 0.5, 0.25 - x * x, 9.81 * (1.0 + x)];
            let sq = ax * ax + ay * ay + fz * fz;
            peak = peak.max(sq.sqrt());
            let step = Step {
                accel: [ax, ay, fz],
                ..Step::quiet()
            };
            step.sample(&mut acc, k, k as f64 * 0.01);
        }
        let row = acc.finish(0, &mut FftPlanner::new(), None)[0];
        assert!(peak > 9.81);
        assert_eq!(row[18].to_bits(), peak.to_bits());
        // Monotone, so exhaustively near a peak: sqrt(max(a, b)) == max(sqrt(a), sqrt(b)).
        let mut a = 96.0f64;
        for _ in 0..100_000 {
            let b = f64::from_bits(a.to_bits() + 1);
            assert_eq!(a.max(b).sqrt().to_bits(), a.sqrt().max(b.sqrt()).to_bits());
            a = b;
        }
    }

    /// Every metric names its unit and its label, and no two share a name: a new metric
    /// cannot reach the tables and figures without them.
    #[test]
    fn every_metric_has_a_unit_and_a_label() {
        for (i, m) in METRICS.iter().enumerate() {
            assert!(!m.unit.trim().is_empty(), "{} has no unit", m.name);
            assert!(!m.label.trim().is_empty(), "{} has no label", m.name);
            assert!(
                !m.label.contains('('),
                "{}: the label carries no unit",
                m.name
            );
            assert_eq!(METRIC_NAMES[i], m.name);
            assert!(!METRIC_NAMES[..i].contains(&m.name), "{} twice", m.name);
        }
    }

    /// The column order Python and the results files read: unchanged by how the table is
    /// written.
    #[test]
    fn the_columns_keep_their_order() {
        assert_eq!(
            METRIC_NAMES,
            [
                "iae",
                "itae",
                "max_abs",
                "rms",
                "tracking_rms",
                "peak_frequency",
                "peak_amplitude",
                "max_accel",
                "rms_accel",
                "max_swing",
                "rms_swing",
                "max_tension",
                "min_tension",
                "slack_time",
                "saturated_time",
                "max_tracking",
                "rms_cross_track",
                "max_cross_track",
                "max_specific_force",
                "near_tilt_time",
                "touchdown_speed",
                "touchdown_drift",
                "touchdown_miss",
                "touchdown_drop_height",
                "touchdown_peak_force",
                "release_time",
                "release_height_change",
                "lowering_swing",
                "geography_margin",
                "volume_margin",
                "left_geography",
                "left_volume",
                "nav_error_max",
                "nav_error_rms",
                "nav_error_vertical_max",
            ]
        );
        let events: Vec<&str> = METRICS.iter().filter(|m| m.event).map(|m| m.name).collect();
        assert_eq!(
            events,
            [
                "touchdown_speed",
                "touchdown_drift",
                "touchdown_miss",
                "touchdown_drop_height",
                "touchdown_peak_force",
                "release_time",
                "release_height_change",
                "geography_margin",
                "volume_margin",
                "left_geography",
                "left_volume",
                "nav_error_max",
                "nav_error_rms",
                "nav_error_vertical_max",
            ]
        );
    }
}
