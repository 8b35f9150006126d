//! Navigation (docs/model.md, "Navigation"): the vehicle's sensors (`sensors`) and the filter
//! that fuses them (`ekf`), one lane-set at a time, and what the laws read from them
//! (`Navigation::sense`): with `navigation.mode = "ekf"` every quantity a law reads comes from
//! the estimate (the body rates from the gyro less its estimated bias); the metrics stay on
//! the true state.
//!
//! The filter's work is compiled once per lane type (`Navigate`), not once per vehicle: it
//! reads the vehicle only through its rigid-body view.

pub mod ekf;
mod entry;
pub mod sensors;

pub use entry::Navigate;

use crate::config::navigation::{Navigation as NavigationKeys, Schedule, Sensors};
use crate::config::ConfigError;
use crate::lane::{each3, Lane};
use crate::model::{Rigid, RigidBody, Rotation, Trig};
use ekf::{Ekf, Tuning, BETA, E, P, STATES, TH, V};
use sensors::{initial_error, wrap, LaneSensors};

/// Trace columns with the navigation on: the estimate, then its standard deviations.
pub const NAVIGATION_COLUMNS: [&str; 18] = [
    "x_est",
    "y_est",
    "z_est",
    "vx_est",
    "vy_est",
    "vz_est",
    "phi_est",
    "theta_est",
    "psi_est",
    "x_std",
    "y_std",
    "z_std",
    "vx_std",
    "vy_std",
    "vz_std",
    "phi_std",
    "theta_std",
    "psi_std",
];

/// One realisation's navigation: its sensors and the filter's settings resolved (the filter's
/// keys that are unset take the sensors' values), and the schedule at the step.
#[derive(Clone, Debug)]
pub struct NavigationParams {
    pub sensors: Sensors,
    pub filter: NavigationKeys,
    pub schedule: Schedule,
    pub dt: f64,
}

impl NavigationParams {
    /// The navigation of a validated scenario, or `None` where the laws read the state.
    pub fn of(
        keys: &NavigationKeys,
        sensors: &Sensors,
        dt: f64,
    ) -> Result<Option<Self>, ConfigError> {
        if !keys.estimates() {
            return Ok(None);
        }
        let (i, g, b) = (&sensors.imu, &sensors.gnss, &sensors.baro);
        let mut f = keys.clone();
        // A key named as its sensor's value takes that value where unset (a matched filter).
        macro_rules! matched {
            ($sensor:ident: $($key:ident),+) => {$(
                f.$key.get_or_insert($sensor.$key);
            )+};
        }
        matched!(i: gyro_noise, accel_noise, gyro_bias_walk, accel_bias_walk, gyro_bias, accel_bias);
        matched!(g: position_noise, velocity_noise, drift, drift_time);
        f.baro_noise.get_or_insert(b.noise);
        f.baro_drift.get_or_insert(b.drift);
        f.baro_drift_time.get_or_insert(b.drift_time);
        f.heading_noise.get_or_insert(sensors.heading.noise);
        Ok(Some(Self {
            sensors: sensors.clone(),
            schedule: keys.schedule(sensors, dt),
            filter: f,
            dt,
        }))
    }

    /// The filter's initial standard deviations, in the error states' order.
    fn initial_sd(&self) -> [f64; STATES] {
        let f = &self.filter;
        let p = f.position_noise.expect("resolved");
        let v = f.velocity_noise.expect("resolved");
        let mut sd = [0.0; STATES];
        sd[P..P + 3].copy_from_slice(&p);
        sd[P + 2] = f.height_error.unwrap_or(p[2]);
        sd[V..V + 3].fill(v);
        sd[TH..TH + 3].copy_from_slice(&f.attitude_error);
        sd[ekf::BG..ekf::BG + 3].fill(f.gyro_bias.expect("resolved"));
        sd[ekf::BA..ekf::BA + 3].fill(f.accel_bias.expect("resolved"));
        sd[E..E + 3].fill(f.drift.expect("resolved"));
        sd[BETA] = f.baro_drift.expect("resolved");
        sd
    }

    /// The filter's tuning (one lane's).
    fn tuning(&self) -> Tuning<f64> {
        let f = &self.filter;
        let s = &self.schedule;
        let period = s.filter as f64 * self.dt;
        let sq = |x: Option<f64>| {
            let x = x.expect("resolved");
            x * x
        };
        let decay = |tau: Option<f64>| (-period / tau.expect("resolved")).exp();
        let (ge, be) = (decay(f.drift_time), decay(f.baro_drift_time));
        Tuning {
            gyro_noise2: sq(f.gyro_noise),
            accel_noise2: sq(f.accel_noise),
            gyro_walk2: sq(f.gyro_bias_walk),
            accel_walk2: sq(f.accel_bias_walk),
            drift_decay: ge,
            drift_gain: (1.0 - ge * ge) * sq(f.drift),
            baro_decay: be,
            baro_gain: (1.0 - be * be) * sq(f.baro_drift),
            position2: f.position_noise.expect("resolved").map(|x| x * x),
            velocity2: sq(f.velocity_noise),
            baro2: sq(f.baro_noise),
            heading2: sq(f.heading_noise),
        }
    }
}

/// What one flight's navigation recorded (lane 0 of a single flight with a trace): the
/// samples the filter read and its state at the end, so that a test can run its own filter
/// over the same samples.
#[derive(Clone, Debug, Default)]
pub struct NavigationRecord {
    /// Per IMU sample: t, gyro [3], accel [3].
    pub imu: Vec<[f64; 7]>,
    /// Per GNSS fix fused: t (when fused), position [3], velocity [3], received (0/1).
    pub gnss: Vec<[f64; 8]>,
    /// Per barometer sample: t, height.
    pub baro: Vec<[f64; 2]>,
    /// Per heading sample: t, yaw.
    pub heading: Vec<[f64; 2]>,
    /// The initial estimate: position [3], velocity [3], quaternion (w, x, y, z).
    pub initial: Vec<f64>,
    /// The final nominal state (p, v, q, bg, ba, e, beta: 20 numbers) and covariance (row-major).
    pub state: Vec<f64>,
    pub covariance: Vec<f64>,
    /// The sensors' true slow states at the start: gyro bias [3], accel bias [3], drift [3],
    /// baro bias.
    pub truth: Vec<f64>,
}

/// The navigation of a lane-set: each lane's sensors, the filter in lane values, the latest
/// IMU sample, and the estimate the laws read.
pub struct Navigation<L> {
    lanes: Vec<LaneSensors>,
    filter: Box<Ekf<L>>,
    tuning: Tuning<L>,
    schedule: Schedule,
    dt: f64,
    g: L,
    gyro: [L; 3],
    /// The sums of the true body rates and specific force (body axes) over the steps of the
    /// IMU's current period.
    rate_sum: [L; 3],
    force_sum: [L; 3],
    /// The filter's position and velocity after its last update, and the increments of its
    /// predictions since (the last `delay / filter` of them: the delayed fix's window).
    mark: [L; 6],
    increments: Vec<[L; 6]>,
    next: usize,
    /// The estimate as the laws read it, and its angles' sines and cosines.
    pub estimate: Rigid<L>,
    pub trig: Trig<L>,
    record: Option<NavigationRecord>,
}

impl<L: Lane> Navigation<L> {
    /// The navigation of the lanes' realisations `params` (one per lane, sharing a schedule)
    /// for realisations `indices` of `seed`, from the true initial rigid bodies `truth`
    /// (`f64`, one per lane); `g` is gravity, `record` whether to keep a record of lane 0.
    pub fn new(
        params: &[&NavigationParams],
        seed: u64,
        indices: &[u64],
        truth: &[Rigid<f64>],
        g: L,
        record: bool,
    ) -> Self {
        let schedule = params[0].schedule;
        let dt = params[0].dt;
        assert!(
            params.iter().all(|p| p.schedule == schedule),
            "the lanes of a set share the navigation's schedule (it cannot be dispersed)"
        );
        let isa = g.within(|isa| isa);
        let lanes: Vec<LaneSensors> = params
            .iter()
            .zip(indices)
            .map(|(p, &i)| LaneSensors::new(&p.sensors, &schedule, (dt, isa), seed, i))
            .collect();
        // Each lane's initial estimate: the truth less a draw of the initial covariance.
        let mut p0 = [[0.0; 3]; 8];
        let mut v0 = [[0.0; 3]; 8];
        let mut q0 = [[0.0; 4]; 8];
        let sds: Vec<[f64; STATES]> = params.iter().map(|p| p.initial_sd()).collect();
        for l in 0..L::LANES {
            let sd = &sds[l];
            let mut first = [0.0; 9];
            first.copy_from_slice(&sd[..9]);
            let d = initial_error(seed, indices[l], &first);
            let t = &truth[l];
            p0[l] = [0, 1, 2].map(|i| t.pos[i] - d[P + i]);
            v0[l] = [0, 1, 2].map(|i| t.vel[i] - d[V + i]);
            let q = RigidBody::quaternion_of_euler(t.att);
            let back = [1.0, -d[TH] * 0.5, -d[TH + 1] * 0.5, -d[TH + 2] * 0.5];
            q0[l] = ekf::normalised(ekf::product(&back, &q));
        }
        let lane3 = |x: &[[f64; 3]; 8], i: usize| L::from_fn(|l| x[l][i]);
        let var = std::array::from_fn(|i| L::from_fn(|l| sds[l][i] * sds[l][i]));
        let filter = Box::new(Ekf::new(
            [0, 1, 2].map(|i| lane3(&p0, i)),
            [0, 1, 2].map(|i| lane3(&v0, i)),
            [0, 1, 2, 3].map(|i| L::from_fn(|l| q0[l][i])),
            var,
        ));
        let tunings: Vec<Tuning<f64>> = params.iter().map(|p| p.tuning()).collect();
        let tl = |f: &dyn Fn(&Tuning<f64>) -> f64| L::from_fn(|l| f(&tunings[l]));
        let tuning = Tuning {
            gyro_noise2: tl(&|t| t.gyro_noise2),
            accel_noise2: tl(&|t| t.accel_noise2),
            gyro_walk2: tl(&|t| t.gyro_walk2),
            accel_walk2: tl(&|t| t.accel_walk2),
            drift_decay: tl(&|t| t.drift_decay),
            drift_gain: tl(&|t| t.drift_gain),
            baro_decay: tl(&|t| t.baro_decay),
            baro_gain: tl(&|t| t.baro_gain),
            position2: [0, 1, 2].map(|i| L::from_fn(|l| tunings[l].position2[i])),
            velocity2: tl(&|t| t.velocity2),
            baro2: tl(&|t| t.baro2),
            heading2: tl(&|t| t.heading2),
        };
        let window = schedule.delay / schedule.filter;
        let zero = L::splat(0.0);
        let record = record.then(|| {
            let s = &lanes[0];
            let mut truth0 = s.bg.to_vec();
            truth0.extend(s.ba);
            truth0.extend(s.e);
            truth0.push(s.beta);
            let mut initial = p0[0].to_vec();
            initial.extend(v0[0]);
            initial.extend(q0[0]);
            NavigationRecord {
                initial,
                truth: truth0,
                ..Default::default()
            }
        });
        let mut nav = Self {
            lanes,
            filter,
            tuning,
            schedule,
            dt,
            g,
            gyro: [zero; 3],
            rate_sum: [zero; 3],
            force_sum: [zero; 3],
            mark: [zero; 6],
            increments: vec![[zero; 6]; window],
            next: 0,
            estimate: Rigid {
                pos: [zero; 3],
                att: [zero; 3],
                vel: [zero; 3],
                rate: [zero; 3],
            },
            trig: Trig::of_angles(zero, zero, zero),
            record,
        };
        nav.mark_update();
        nav
    }

    /// Step `k`'s senses and estimate, with the vehicle truly at `truth`: on the IMU's steps
    /// its sample of the period just ended propagates the estimate to now; on the filter's the
    /// covariance is predicted and the measurements that arrive are fused. The estimate the
    /// laws read is then `estimate` and `trig`.
    #[inline(always)]
    pub fn sense(&mut self, k: usize, truth: &Rigid<L>) {
        let s = self.schedule;
        let imu_step = k.is_multiple_of(s.imu);
        let t = k as f64 * self.dt;
        if k > 0 && imu_step {
            self.sample_imu(t);
        } else if k == 0 {
            let mut gyro = [[0.0; 3]; 8];
            for (l, lane) in self.lanes.iter_mut().enumerate() {
                gyro[l] = lane.first_gyro(truth.rate.map(|x| x.lane(l)));
            }
            self.gyro = [0, 1, 2].map(|i| L::from_fn(|l| gyro[l][i]));
        }
        self.accumulate(truth);
        if k.is_multiple_of(s.filter) {
            if k > 0 {
                self.filter.predict(&self.tuning);
                self.push_increment();
            }
            self.measure_and_fuse(k, t, truth);
            self.mark_update();
        }
        if imu_step || k.is_multiple_of(s.filter) {
            self.refresh();
        }
    }

    /// `new` from the lanes' true initial rigid body `start` (lane values).
    pub fn starting_at(
        params: &[&NavigationParams],
        seed: u64,
        indices: &[u64],
        start: &Rigid<L>,
        g: L,
        record: bool,
    ) -> Self {
        assert_eq!(
            params.len(),
            L::LANES,
            "every lane of a set navigates alike"
        );
        let truths: Vec<Rigid<f64>> = (0..L::LANES)
            .map(|l| Rigid {
                pos: start.pos.map(|x| x.lane(l)),
                att: start.att.map(|x| x.lane(l)),
                vel: start.vel.map(|x| x.lane(l)),
                rate: start.rate.map(|x| x.lane(l)),
            })
            .collect();
        Self::new(params, seed, indices, &truths, g, record)
    }

    /// After a step's derivative (its acceleration `a`, world axes; the body's `axes`): the
    /// accelerometer's sum (`accelerometer`), and the estimate's position error against the
    /// true position `pos`.
    #[inline(always)]
    pub fn error_after(&mut self, a: &[L; 3], axes: &[[L; 3]; 3], pos: &[L; 3]) -> [L; 3] {
        self.accelerometer(a, axes);
        each3(
            #[inline(always)]
            |i| self.estimate.pos[i] - pos[i],
        )
    }

    /// Whether step `k` samples the IMU (and so may update the filter): else the step only adds
    /// to the IMU's sums (`accumulate`, `accelerometer`).
    #[inline(always)]
    pub fn due(&self, k: usize) -> bool {
        k.is_multiple_of(self.schedule.imu)
    }

    /// Whether step `k`'s senses read the true attitude (the heading's sample, `heading_due`,
    /// on a step that senses at all, `due`); else no sense reads the truth's Euler angles.
    #[inline(always)]
    pub fn reads_attitude(&self, k: usize) -> bool {
        self.due(k) && self.heading_due(k)
    }

    /// Whether a step that senses (`sense`) samples and fuses the heading: a filter step that
    /// is the heading's. The one rule `measure_and_fuse` and `reads_attitude` both follow.
    #[inline(always)]
    fn heading_due(&self, k: usize) -> bool {
        let s = self.schedule;
        k.is_multiple_of(s.filter) && k.is_multiple_of(s.heading)
    }

    /// The true body rates of the step into the IMU's period sum.
    #[inline(always)]
    pub fn accumulate(&mut self, truth: &Rigid<L>) {
        for (sum, w) in self.rate_sum.iter_mut().zip(truth.rate) {
            *sum += w;
        }
    }

    /// After a step's derivative: the specific force of the step's state (its acceleration
    /// `a`, world axes, with the body's `axes`), in body axes, into the IMU's period sum.
    #[inline(always)]
    pub fn accelerometer(&mut self, a: &[L; 3], axes: &[[L; 3]; 3]) {
        let f = [a[0], a[1], a[2] + self.g];
        let body = Rotation { axes: *axes }.to_body(&f);
        for (sum, f) in self.force_sum.iter_mut().zip(body) {
            *sum += f;
        }
    }

    /// The IMU's sample at `t` of the period just ended (the means of its sums), and the
    /// estimate propagated with it over that period.
    #[inline(always)]
    fn sample_imu(&mut self, t: f64) {
        let m = self.schedule.imu as f64;
        let (mut g, mut a) = ([[0.0; 3]; 8], [[0.0; 3]; 8]);
        for (l, lane) in self.lanes.iter_mut().enumerate() {
            let w = each3(
                #[inline(always)]
                |i| self.rate_sum[i].lane(l) / m,
            );
            let f = each3(
                #[inline(always)]
                |i| self.force_sum[i].lane(l) / m,
            );
            (g[l], a[l]) = lane.imu(w, f);
        }
        self.gyro = each3(
            #[inline(always)]
            |i| L::from_fn(|l| g[l][i]),
        );
        let accel = each3(
            #[inline(always)]
            |i| L::from_fn(|l| a[l][i]),
        );
        self.rate_sum = [L::splat(0.0); 3];
        self.force_sum = [L::splat(0.0); 3];
        let h = m * self.dt;
        self.filter.propagate(&self.gyro, &accel, h, self.g);
        if let Some(r) = self.record.as_mut() {
            let (g, a) = (g[0], a[0]);
            r.imu.push([t, g[0], g[1], g[2], a[0], a[1], a[2]]);
        }
    }

    /// The trace's navigation columns (`NAVIGATION_COLUMNS`), lane 0.
    pub fn columns(&self) -> [f64; 18] {
        let e = &self.estimate;
        let c = &self.filter.cov;
        let mut out = [0.0; 18];
        for i in 0..3 {
            out[i] = e.pos[i].lane(0);
            out[3 + i] = e.vel[i].lane(0);
            out[6 + i] = e.att[i].lane(0);
            out[9 + i] = c[P + i][P + i].lane(0).sqrt();
            out[12 + i] = c[V + i][V + i].lane(0).sqrt();
            out[15 + i] = c[TH + i][TH + i].lane(0).sqrt();
        }
        out
    }

    /// The record, with the filter's state at the end.
    pub fn finish(mut self) -> Option<NavigationRecord> {
        let f = &self.filter;
        let r = self.record.as_mut()?;
        let lane0 = |x: &[L]| x.iter().map(|v| v.lane(0)).collect::<Vec<_>>();
        let mut state = lane0(&f.p);
        for part in [
            &f.v[..],
            &f.q[..],
            &f.bg[..],
            &f.ba[..],
            &f.e[..],
            &[f.beta][..],
        ] {
            state.extend(lane0(part));
        }
        r.state = state;
        r.covariance = f.cov.iter().flat_map(|row| lane0(row)).collect();
        self.record
    }

    /// The estimate the laws read, from the filter's nominal state and the latest gyro sample.
    #[inline(always)]
    fn refresh(&mut self) {
        let f = &self.filter;
        let rot = f.rotation();
        let att = rot.euler();
        self.estimate = Rigid {
            pos: f.p,
            att,
            vel: f.v,
            rate: each3(
                #[inline(always)]
                |i| self.gyro[i] - f.bg[i],
            ),
        };
        // From the matrix: no sine or cosine to evaluate (3 % of the delivery's time).
        self.trig = rot.trig();
    }

    #[inline(always)]
    fn mark_update(&mut self) {
        let f = &self.filter;
        self.mark = [f.p[0], f.p[1], f.p[2], f.v[0], f.v[1], f.v[2]];
    }

    /// The increment of the filter's position and velocity over its last prediction.
    #[inline(always)]
    fn push_increment(&mut self) {
        if self.increments.is_empty() {
            return;
        }
        let f = &self.filter;
        let now = [f.p[0], f.p[1], f.p[2], f.v[0], f.v[1], f.v[2]];
        let mut increment = now;
        for i in 0..6 {
            increment[i] = now[i] - self.mark[i];
        }
        self.increments[self.next] = increment;
        self.next = (self.next + 1) % self.increments.len();
    }

    /// The measurements of step `k` (the vehicle at `truth`), taken and fused: a GNSS epoch's
    /// fix sent on its way, a fix that arrives, the barometer, the heading.
    #[inline(always)]
    fn measure_and_fuse(&mut self, k: usize, t: f64, truth: &Rigid<L>) {
        let s = self.schedule;
        if k.is_multiple_of(s.gnss) {
            for (l, lane) in self.lanes.iter_mut().enumerate() {
                let p = each3(
                    #[inline(always)]
                    |i| truth.pos[i].lane(l),
                );
                let v = each3(
                    #[inline(always)]
                    |i| truth.vel[i].lane(l),
                );
                lane.gnss_epoch(k, self.dt, p, v);
            }
        }
        if k >= s.delay && (k - s.delay).is_multiple_of(s.gnss) {
            self.fuse_gnss(k, t);
        }
        if k.is_multiple_of(s.baro) {
            let z = self.read(
                t,
                |r| &mut r.baro,
                |lane, l| lane.baro(truth.pos[2].lane(l)),
            );
            let f = &mut self.filter;
            let y = L::from_fn(|l| z[l]) - (f.p[2] + f.beta);
            f.fuse(
                &[(P + 2, L::splat(1.0)), (BETA, L::splat(1.0))],
                y,
                self.tuning.baro2,
                L::splat(1.0),
            );
        }
        if self.heading_due(k) {
            let z = self.read(
                t,
                |r| &mut r.heading,
                |lane, l| lane.heading(truth.att[2].lane(l)),
            );
            let f = &mut self.filter;
            let [c0, _, _] = f.rotation().axes;
            let n = c0[0] * c0[0] + c0[1] * c0[1];
            let psi = c0[1].atan2(c0[0]);
            let y = L::from_fn(|l| wrap(z[l] - psi.lane(l)));
            let h = [
                (TH, -(c0[0] * c0[2]) / n),
                (TH + 1, -(c0[1] * c0[2]) / n),
                (TH + 2, L::splat(1.0)),
            ];
            f.fuse(&h, y, self.tuning.heading2, L::splat(1.0));
        }
    }

    /// Each lane's reading of a scalar sensor (`sense`), lane 0's kept in its `log` at `t`.
    #[inline(always)]
    fn read(
        &mut self,
        t: f64,
        log: impl FnOnce(&mut NavigationRecord) -> &mut Vec<[f64; 2]>,
        sense: impl Fn(&mut LaneSensors, usize) -> f64,
    ) -> [f64; 8] {
        let mut z = [0.0; 8];
        for (l, lane) in self.lanes.iter_mut().enumerate() {
            z[l] = sense(lane, l);
        }
        if let Some(r) = self.record.as_mut() {
            log(r).push([t, z[0]]);
        }
        z
    }

    /// The GNSS fixes that arrive at step `k`, each lane's of the state `delay` steps ago:
    /// predicted from the filter's position less its predictions' increments since then (and
    /// its drift), position then velocity, one axis at a time. A lane whose fix fell in an
    /// outage fuses nothing.
    #[inline(always)]
    fn fuse_gnss(&mut self, k: usize, t: f64) {
        let mut z = [[0.0; 6]; 8];
        let mut on = [0.0; 8];
        for (l, lane) in self.lanes.iter_mut().enumerate() {
            let fix = lane
                .arrived(k)
                .expect("a fix is due at this step in every lane");
            z[l] = fix.z;
            on[l] = if fix.received { 1.0 } else { 0.0 };
        }
        if let Some(r) = self.record.as_mut() {
            let z0 = z[0];
            r.gnss
                .push([t, z0[0], z0[1], z0[2], z0[3], z0[4], z0[5], on[0]]);
        }
        let mut back = [L::splat(0.0); 6];
        for inc in &self.increments {
            for i in 0..6 {
                back[i] += inc[i];
            }
        }
        let on = L::from_fn(|l| on[l]);
        let tau = L::splat(self.schedule.delay as f64 * self.dt);
        let one = L::splat(1.0);
        let f = &mut self.filter;
        for i in 0..3 {
            let zi = L::from_fn(|l| z[l][i]);
            let y = (zi - (f.p[i] - back[i] + f.e[i])) * on;
            f.fuse(
                &[(P + i, one), (V + i, -tau), (E + i, one)],
                y,
                self.tuning.position2[i],
                on,
            );
        }
        for i in 0..3 {
            let zi = L::from_fn(|l| z[l][3 + i]);
            let y = (zi - (f.v[i] - back[3 + i])) * on;
            f.fuse(&[(V + i, one)], y, self.tuning.velocity2, on);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::navigation::NavigationMode;

    /// The flight loop derives the truth's Euler angles only where `reads_attitude` says a
    /// sense reads them (else it hands the navigation NaN): the steps it names must be exactly
    /// the steps whose heading sample is taken, at rates whose periods do not divide evenly.
    #[test]
    fn the_attitude_is_read_on_exactly_the_steps_that_sample_the_heading() {
        let dt = 1e-3;
        for (imu, filter, heading) in [(250.0, 50.0, 7.0), (0.0, 300.0, 45.0), (333.0, 90.0, 90.0)]
        {
            let mut sensors = Sensors::default();
            sensors.imu.rate = imu;
            sensors.heading.rate = heading;
            let keys = NavigationKeys {
                mode: NavigationMode::Ekf,
                rate: filter,
                ..Default::default()
            };
            let p = NavigationParams::of(&keys, &sensors, dt).unwrap().unwrap();
            let truth = Rigid {
                pos: [1.0, -2.0, 3.0],
                att: [0.1, -0.05, 0.7],
                vel: [0.0; 3],
                rate: [0.0; 3],
            };
            let mut nav = Navigation::<f64>::new(&[&p], 7, &[0], &[truth], 9.81, true);
            let mut read = vec![];
            for k in 0..3000 {
                if nav.reads_attitude(k) {
                    read.push(k as f64 * dt);
                }
                if nav.due(k) {
                    nav.sense(k, &truth);
                }
            }
            let sampled: Vec<f64> = nav.finish().unwrap().heading.iter().map(|r| r[0]).collect();
            assert!(sampled.len() >= 10, "{imu} {filter} {heading}: {sampled:?}");
            assert_eq!(
                read, sampled,
                "imu {imu} Hz, filter {filter} Hz, heading {heading} Hz"
            );
        }
    }
}
