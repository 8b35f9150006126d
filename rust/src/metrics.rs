//! Per-phase indices of the relative oscillation e_o, accumulated online (docs/model.md section 5),
//! and the whole vehicle's (section 11): the magnitude of the payload's inertial acceleration
//! (`max_accel`, `rms_accel`), the specific force an accelerometer on the payload reads
//! (`max_specific_force`, |a - g|: how fragility is specified; docs/risk.md), the 3-D tracking error,
//! the attachment's swing and tension, slack and actuator saturation times.
//!
//! Integrals use the trapezoidal rule on the step grid. The amplitude spectrum needs the signal,
//! so e_o is also kept block-averaged at `metrics.spectrum_rate` (a few thousand numbers per
//! flight, allocated once per flight, never per step).

use crate::lane::Lane;
use crate::trajectory::PhaseSteps;
use rustfft::{num_complex::Complex, FftPlanner};

/// One metric: its column name, its unit (SI, as the engine stores it; "-" for none), a
/// plain-English label (no unit: figures and tables add theirs) and its value from one
/// phase's running sums. The one place a metric is defined: the column order of every metrics
/// array, `_core.METRIC_NAMES`, `_core.METRIC_UNITS` and `_core.METRIC_LABELS` come from
/// `METRICS`.
pub struct Metric {
    pub name: &'static str,
    pub unit: &'static str,
    pub label: &'static str,
    /// An event's value (a touchdown, a release): NaN in a phase or flight without the event,
    /// where every other metric is finite.
    pub event: bool,
    value: fn(&Totals) -> f64,
}

/// One lane's running sums over one phase, and what a value needs besides them.
pub struct Totals {
    s: Sums<f64>,
    /// s, the phase's length.
    span: f64,
    /// s, the step.
    dt: f64,
    /// Hz and m: the largest bin of e_o's amplitude spectrum (NaN when there is none).
    peak: (f64, f64),
}

impl Totals {
    /// A value recorded at the phase's touchdown; NaN where the phase has none.
    fn once(&self, value: f64) -> f64 {
        if self.s.touchdowns > 0.0 {
            value
        } else {
            f64::NAN
        }
    }

    /// sqrt(integral / span): the RMS of a signal whose squared integral is `sq`.
    fn rms(&self, sq: f64) -> f64 {
        (sq / self.span).sqrt()
    }
}

/// Every metric, in column order.
pub const METRICS: [Metric; 26] = [
    Metric {
        name: "iae",
        unit: "m s",
        label: "Integrated absolute displacement, IAE",
        event: false,
        value: |t| t.s.iae,
    },
    Metric {
        name: "itae",
        unit: "m s^2",
        label: "Time-weighted IAE, ITAE",
        event: false,
        value: |t| t.s.itae,
    },
    Metric {
        name: "max_abs",
        unit: "m",
        label: "Peak |payload relative displacement|",
        event: false,
        value: |t| t.s.max_abs,
    },
    Metric {
        name: "rms",
        unit: "m",
        label: "RMS payload relative displacement",
        event: false,
        value: |t| t.rms(t.s.sq),
    },
    Metric {
        name: "tracking_rms",
        unit: "m",
        label: "RMS 3-D tracking error",
        event: false,
        value: |t| t.rms(t.s.tracking_sq),
    },
    Metric {
        name: "peak_frequency",
        unit: "Hz",
        label: "Frequency of the displacement's spectral peak",
        event: false,
        value: |t| t.peak.0,
    },
    Metric {
        name: "peak_amplitude",
        unit: "m",
        label: "Amplitude of the displacement's spectral peak",
        event: false,
        value: |t| t.peak.1,
    },
    Metric {
        name: "max_accel",
        unit: "m/s^2",
        label: "Payload acceleration peak",
        event: false,
        value: |t| t.s.max_accel,
    },
    Metric {
        name: "rms_accel",
        unit: "m/s^2",
        label: "Payload acceleration RMS",
        event: false,
        value: |t| t.rms(t.s.accel_sq),
    },
    Metric {
        name: "max_swing",
        unit: "rad",
        label: "Peak swing angle of the line",
        event: false,
        value: |t| t.s.max_swing,
    },
    Metric {
        name: "rms_swing",
        unit: "rad",
        label: "RMS swing angle of the line",
        event: false,
        value: |t| t.rms(t.s.swing_sq),
    },
    Metric {
        name: "max_tension",
        unit: "N",
        label: "Peak line tension",
        event: false,
        value: |t| t.s.max_tension,
    },
    Metric {
        name: "min_tension",
        unit: "N",
        label: "Lowest line tension",
        event: false,
        value: |t| t.s.min_tension,
    },
    Metric {
        name: "slack_time",
        unit: "s",
        label: "Time with the line slack",
        event: false,
        value: |t| t.s.slack_steps * t.dt,
    },
    Metric {
        name: "saturated_time",
        unit: "s",
        label: "Time with a rotor at its limit",
        event: false,
        value: |t| t.s.saturated_steps * t.dt,
    },
    Metric {
        name: "max_tracking",
        unit: "m",
        label: "Peak 3-D tracking error",
        event: false,
        value: |t| t.s.max_tracking_sq.sqrt(),
    },
    Metric {
        name: "rms_cross_track",
        unit: "m",
        label: "RMS cross-track error",
        event: false,
        value: |t| t.rms(t.s.cross_sq),
    },
    Metric {
        name: "max_cross_track",
        unit: "m",
        label: "Peak cross-track error",
        event: false,
        value: |t| t.s.max_cross_sq.sqrt(),
    },
    Metric {
        name: "max_specific_force",
        unit: "m/s^2",
        label: "Peak specific force on the payload, |a - g|",
        event: false,
        value: |t| t.s.max_specific_force_sq.sqrt(),
    },
    Metric {
        name: "near_tilt_time",
        unit: "s",
        label: "Time with the tilt above 90 % of the law's limit",
        event: false,
        value: |t| t.s.near_tilt_steps * t.dt,
    },
    // The last metres (docs/model.md): each event's value in the phase it falls in, NaN in
    // the others (and in a flight without it).
    Metric {
        name: "touchdown_speed",
        unit: "m/s",
        label: "Parcel's vertical speed at touchdown",
        event: true,
        value: |t| t.once(t.s.touchdown_speed),
    },
    Metric {
        name: "touchdown_drift",
        unit: "m/s",
        label: "Parcel's horizontal speed at touchdown",
        event: true,
        value: |t| t.once(t.s.touchdown_drift),
    },
    Metric {
        name: "touchdown_miss",
        unit: "m",
        label: "Touchdown's distance from the drop point",
        event: true,
        value: |t| t.once(t.s.touchdown_miss),
    },
    Metric {
        name: "release_time",
        unit: "s",
        label: "Time the hook opens",
        event: true,
        value: |t| {
            if t.s.releases > 0.0 {
                t.s.release_time
            } else {
                f64::NAN
            }
        },
    },
    Metric {
        name: "release_height_change",
        unit: "m",
        label: "Vehicle's largest height change in the 5 s after the release",
        event: true,
        value: |t| {
            if t.s.release_seen > 0.0 {
                t.s.max_release_change
            } else {
                f64::NAN
            }
        },
    },
    Metric {
        name: "lowering_swing",
        unit: "rad",
        label: "Peak swing angle of the line while lowering",
        event: false,
        value: |t| t.s.max_lowering_swing,
    },
];
pub const N_METRICS: usize = METRICS.len();

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

/// The running sums of one phase, each starting at its initial value: a struct of lane values
/// (`Sums<L>`), and one lane's values of them (`Sums<f64>`, `lane`).
macro_rules! sums {
    ($($(#[$doc:meta])* $field:ident: $init:expr,)+) => {
        #[derive(Clone, Copy)]
        struct Sums<L> {
            $($(#[$doc])* $field: L,)+
        }

        impl<L: Lane> Sums<L> {
            fn new() -> Self {
                Self { $($field: L::splat($init),)+ }
            }

            fn lane(&self, lane: usize) -> Sums<f64> {
                Sums { $($field: self.$field.lane(lane),)+ }
            }
        }
    };
}

sums! {
    iae: 0.0,
    itae: 0.0,
    sq: 0.0,
    tracking_sq: 0.0,
    max_abs: 0.0,
    accel_sq: 0.0,
    max_accel: 0.0,
    swing_sq: 0.0,
    max_swing: 0.0,
    max_tension: f64::NEG_INFINITY,
    min_tension: f64::INFINITY,
    /// Steps (at t_k) with the attachment slack, and with an actuator command clamped.
    slack_steps: 0.0,
    saturated_steps: 0.0,
    max_tracking_sq: 0.0,
    cross_sq: 0.0,
    max_cross_sq: 0.0,
    /// The largest |a - g|^2: its square root at the end is the largest |a - g| bit for bit
    /// (a correctly rounded square root is monotone), one square root per flight, not per step.
    max_specific_force_sq: 0.0,
    near_tilt_steps: 0.0,
    /// The first touchdown (at most one per flight) and the hook's opening: how many in the
    /// phase (0 or 1) and their values (the sum of the one).
    touchdowns: 0.0,
    touchdown_speed: 0.0,
    touchdown_drift: 0.0,
    touchdown_miss: 0.0,
    releases: 0.0,
    release_time: 0.0,
    /// Steps within the window after the release, and the largest height change there.
    release_seen: 0.0,
    max_release_change: 0.0,
    max_lowering_swing: 0.0,
}

/// What the flight loop hands the accumulator at one step (lane values).
#[derive(Clone, Copy, Debug)]
pub struct Sample<L> {
    /// m, the relative oscillation.
    pub e_o: L,
    /// m^2, the squared 3-D position error |p_ref - p|^2.
    pub tracking_sq: L,
    /// m^2, the squared distance from the current leg's straight line (cross-track error;
    /// `Trajectory::line`).
    pub cross_sq: L,
    /// m/s^2, the magnitude of the payload's inertial acceleration.
    pub accel: L,
    /// m^2/s^4, the squared magnitude of the payload's specific force |a - g| (g pointing
    /// down): what an accelerometer on the payload reads (g at rest, 0 in free fall).
    pub specific_force_sq: L,
    /// rad, the attachment's angle from the vertical.
    pub swing: L,
    /// N, the force the attachment carries.
    pub tension: L,
    /// 1 where the attachment is slack (tension <= 0), else 0.
    pub slack: L,
    /// 1 where an actuator command was clamped over this step, else 0.
    pub saturated: L,
    /// 1 where the tilt exceeds 90 % of the law's limit, else 0.
    pub near_tilt: L,
    /// The last metres (`LastMetres` below; all zero for a payload without them).
    pub last: LastSample<L>,
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
            release: z,
            after_release: z,
            release_change: z,
            lowering_swing: z,
        }
    }
}

/// Online accumulator for one lane-set over all phases.
pub struct PhaseAccumulator<L: Lane> {
    phases: Vec<PhaseSteps>,
    sums: Vec<Sums<L>>,
    dt: f64,
    decimation: usize,
    /// Samples still to add before the current block is complete (avoids a `%` per step).
    block_left: usize,
    block_sum: L,
    blocks: Vec<L>,
}

impl<L: Lane> PhaseAccumulator<L> {
    /// `decimation`: steps per spectrum sample; `steps`: steps of the flight.
    pub fn new(phases: &[PhaseSteps], dt: f64, decimation: usize, steps: usize) -> Self {
        let zero = L::splat(0.0);
        Self {
            phases: phases.to_vec(),
            sums: vec![Sums::new(); phases.len()],
            dt,
            decimation: decimation.max(1),
            block_left: decimation.max(1),
            block_sum: zero,
            blocks: Vec::with_capacity(steps / decimation.max(1) + 1),
        }
    }

    /// Take sample k (time t); k = 0, 1, 2, ... in turn.
    #[inline(always)]
    pub fn sample(&mut self, k: usize, t: f64, x: &Sample<L>) {
        let e_o = x.e_o;
        let a = e_o.abs();
        for (ph, sums) in self.phases.iter().zip(self.sums.iter_mut()) {
            if ph.contains(k) {
                let w = if k == ph.first || k == ph.last {
                    0.5 * self.dt
                } else {
                    self.dt
                };
                sums.iae += a * w;
                sums.itae += a * (w * t);
                sums.sq += e_o * e_o * w;
                sums.tracking_sq += x.tracking_sq * w;
                sums.max_abs = sums.max_abs.max(a);
                sums.accel_sq += x.accel * x.accel * w;
                sums.max_accel = sums.max_accel.max(x.accel);
                sums.swing_sq += x.swing * x.swing * w;
                sums.max_swing = sums.max_swing.max(x.swing);
                sums.max_tension = sums.max_tension.max(x.tension);
                sums.min_tension = sums.min_tension.min(x.tension);
                sums.slack_steps += x.slack;
                sums.saturated_steps += x.saturated;
                sums.max_tracking_sq = sums.max_tracking_sq.max(x.tracking_sq);
                sums.cross_sq += x.cross_sq * w;
                sums.max_cross_sq = sums.max_cross_sq.max(x.cross_sq);
                sums.max_specific_force_sq = sums.max_specific_force_sq.max(x.specific_force_sq);
                sums.near_tilt_steps += x.near_tilt;
                let e = &x.last;
                sums.touchdowns += e.touchdown;
                sums.touchdown_speed += e.touchdown * e.touchdown_speed;
                sums.touchdown_drift += e.touchdown * e.touchdown_drift;
                sums.touchdown_miss += e.touchdown * e.touchdown_miss;
                sums.releases += e.release;
                sums.release_time += e.release * t;
                sums.release_seen += e.after_release;
                sums.max_release_change = sums.max_release_change.max(e.release_change);
                sums.max_lowering_swing = sums.max_lowering_swing.max(e.lowering_swing);
            }
        }
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
        for (p, (ph, s)) in self.phases.iter().zip(&self.sums).enumerate() {
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
                s: s.lane(lane),
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
        let mut acc = PhaseAccumulator::<f64>::new(&ph, dt, 5, 100);
        for k in 0..=100 {
            let t = k as f64 * dt;
            let flag = if k < 30 { 1.0 } else { 0.0 };
            acc.sample(
                k,
                t,
                &Sample {
                    e_o: t,
                    tracking_sq: 0.0,
                    cross_sq: 0.0,
                    accel: 2.0 * t,
                    specific_force_sq: (9.81 - t) * (9.81 - t),
                    swing: 0.1 * t,
                    tension: 5.0 - 10.0 * t,
                    slack: 1.0 - flag,
                    saturated: flag,
                    near_tilt: 1.0 - flag,
                    last: LastSample {
                        touchdown: if k == 40 { 1.0 } else { 0.0 },
                        touchdown_speed: 0.7,
                        touchdown_drift: 0.2,
                        touchdown_miss: 0.3,
                        release: if k == 60 { 1.0 } else { 0.0 },
                        after_release: if k >= 60 { 1.0 } else { 0.0 },
                        release_change: if k >= 60 { 0.01 * (k - 60) as f64 } else { 0.0 },
                        lowering_swing: if k < 40 { 0.1 * t } else { 0.0 },
                    },
                },
            );
        }
        let row = acc.finish(0, &mut FftPlanner::new(), None)[0];
        assert!((row[0] - 0.5).abs() < 1e-12);
        assert!((row[1] - (1.0 / 3.0 + dt * dt / 6.0)).abs() < 1e-12);
        assert!((row[2] - 1.0).abs() < 1e-12);
        assert!((row[3] - (1.0f64 / 3.0 + dt * dt / 6.0).sqrt()).abs() < 1e-12);
        // accel = 2 t: peak 2, RMS 2 sqrt(1/3 + dt^2/6).
        assert!((row[7] - 2.0).abs() < 1e-12);
        assert!((row[8] - 2.0 * (1.0f64 / 3.0 + dt * dt / 6.0).sqrt()).abs() < 1e-12);
        // swing = 0.1 t; tension 5 - 10 t from 5 down to -5; 71 slack and 30 saturated steps.
        assert!((row[9] - 0.1).abs() < 1e-12);
        assert!((row[10] - 0.1 * (1.0f64 / 3.0 + dt * dt / 6.0).sqrt()).abs() < 1e-12);
        assert_eq!((row[11], row[12]), (5.0, -5.0));
        assert!((row[13] - 71.0 * dt).abs() < 1e-12);
        assert!((row[14] - 30.0 * dt).abs() < 1e-12);
        // specific force 9.81 - t: its peak at t = 0.
        assert_eq!(row[18], 9.81);
        // 71 steps near the tilt limit; the touchdown's values (0.7, 0.2, 0.3) at k = 40, the
        // release at t = 0.6 s, the height change 0.4 m at its window's end, the swing while
        // lowering 0.1 t up to t = 0.39 s.
        let at = |name: &str| row[METRIC_NAMES.iter().position(|n| *n == name).unwrap()];
        assert!((at("near_tilt_time") - 71.0 * dt).abs() < 1e-12);
        assert_eq!(
            (
                at("touchdown_speed"),
                at("touchdown_drift"),
                at("touchdown_miss")
            ),
            (0.7, 0.2, 0.3)
        );
        assert_eq!(at("release_time"), 60.0 * dt);
        assert!((at("release_height_change") - 0.4).abs() < 1e-12);
        assert!((at("lowering_swing") - 0.039).abs() < 1e-12);
        // A phase without the events: NaN for them, 0 for the durations and peaks.
        let ph = [PhaseSteps { first: 0, last: 10 }];
        let mut acc = PhaseAccumulator::<f64>::new(&ph, dt, 5, 10);
        for k in 0..=10 {
            acc.sample(
                k,
                k as f64 * dt,
                &Sample {
                    e_o: 0.0,
                    tracking_sq: 0.0,
                    cross_sq: 0.0,
                    accel: 0.0,
                    specific_force_sq: 0.0,
                    swing: 0.0,
                    tension: 0.0,
                    slack: 0.0,
                    saturated: 0.0,
                    near_tilt: 0.0,
                    last: LastSample::none(),
                },
            );
        }
        let row = acc.finish(0, &mut FftPlanner::new(), None)[0];
        let at = |name: &str| row[METRIC_NAMES.iter().position(|n| *n == name).unwrap()];
        for name in [
            "touchdown_speed",
            "touchdown_drift",
            "touchdown_miss",
            "release_time",
        ] {
            assert!(at(name).is_nan(), "{name}");
        }
        assert!(at("release_height_change").is_nan());
        assert_eq!((at("near_tilt_time"), at("lowering_swing")), (0.0, 0.0));
    }

    /// The peak specific force taken as the square root of the peak square is the peak of the
    /// per-step square roots (what the flight loop took before), bit for bit.
    #[test]
    fn the_peak_of_square_roots_is_the_square_root_of_the_peak_square() {
        let ph = [PhaseSteps {
            first: 0,
            last: 999,
        }];
        let mut acc = PhaseAccumulator::<f64>::new(&ph, 0.01, 5, 999);
        let mut peak = 0.0f64;
        let mut x = 0.123_456_789f64;
        for k in 0..=999 {
            // A scrambled sequence of squares of magnitudes around g.
            x = (x * 3.987_654_321 + 0.314_159).fract();
            let [ax, ay, fz] = [x - 0.5, 0.25 - x * x, 9.81 * (1.0 + x)];
            let sq = ax * ax + ay * ay + fz * fz;
            peak = peak.max(sq.sqrt());
            acc.sample(
                k,
                k as f64 * 0.01,
                &Sample {
                    e_o: 0.0,
                    tracking_sq: 0.0,
                    cross_sq: 0.0,
                    accel: 0.0,
                    specific_force_sq: sq,
                    swing: 0.0,
                    tension: 0.0,
                    slack: 0.0,
                    saturated: 0.0,
                    near_tilt: 0.0,
                    last: LastSample::none(),
                },
            );
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
}
