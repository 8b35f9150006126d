//! The navigation filter (docs/model.md, "Navigation"): an error-state extended Kalman filter
//! in lane values. The nominal state (position, velocity, attitude quaternion, gyro and
//! accelerometer biases, the GNSS receiver's drift and the barometer's bias) is propagated with
//! every IMU sample; the covariance of its error, 19 states, at the filter's rate from the
//! samples' sums since its last update; measurements are fused one scalar at a time at the
//! filter's updates, each injected into the nominal state at once.
//!
//! Error states: position, velocity, attitude (world axes: R = Exp(dtheta) R_hat), gyro bias,
//! accelerometer bias, GNSS drift, baro bias, in the order of the `P`, `V`, ... indices.

// The equations are written index by index, as docs/model.md states them (and a lane value has
// no `-=`/`*=`).
#![allow(clippy::assign_op_pattern, clippy::needless_range_loop)]

use crate::lane::{each3, each4, Lane};
use crate::model::Rotation;

/// Error states.
pub const STATES: usize = 19;
pub const P: usize = 0;
pub const V: usize = 3;
pub const TH: usize = 6;
pub const BG: usize = 9;
pub const BA: usize = 12;
pub const E: usize = 15;
pub const BETA: usize = 18;

/// The filter's own settings, one value per lane: process noises and the measurements'
/// variances (`[navigation]`'s keys, defaulting to the sensors').
#[derive(Clone, Copy)]
pub struct Tuning<L> {
    /// (rad/s)^2/Hz, (m/s^2)^2/Hz: white noise densities squared.
    pub gyro_noise2: L,
    pub accel_noise2: L,
    /// Bias random walks' densities squared.
    pub gyro_walk2: L,
    pub accel_walk2: L,
    /// GNSS drift: its decay over one filter period and the variance it gains.
    pub drift_decay: L,
    pub drift_gain: L,
    pub baro_decay: L,
    pub baro_gain: L,
    /// m^2, (m/s)^2, m^2, rad^2: the measurements' variances.
    pub position2: [L; 3],
    pub velocity2: L,
    pub baro2: L,
    pub heading2: L,
}

/// The filter of a lane-set: nominal state, error covariance, and the sums of the IMU samples
/// since its last covariance update.
#[derive(Clone)]
pub struct Ekf<L> {
    pub p: [L; 3],
    pub v: [L; 3],
    /// (w, x, y, z), body to world.
    pub q: [L; 4],
    pub bg: [L; 3],
    pub ba: [L; 3],
    pub e: [L; 3],
    pub beta: L,
    pub cov: [[L; STATES]; STATES],
    /// Sum of R_hat h over the samples since the last covariance update (s).
    sum_r: [[L; 3]; 3],
    /// Sum of R_hat (f - ba_hat) h (m/s): the specific force's velocity increment, world axes.
    sum_dv: [L; 3],
    /// s, the time those samples cover.
    span: f64,
}

#[inline(always)]
fn dot3<L: Lane>(a: &[L; 3], b: &[L; 3]) -> L {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

impl<L: Lane> Ekf<L> {
    /// The filter at its initial estimate with the diagonal covariance `var`.
    pub fn new(p: [L; 3], v: [L; 3], q: [L; 4], var: [L; STATES]) -> Self {
        let zero = L::splat(0.0);
        let mut cov = [[zero; STATES]; STATES];
        for (i, row) in cov.iter_mut().enumerate() {
            row[i] = var[i];
        }
        Self {
            p,
            v,
            q,
            bg: [zero; 3],
            ba: [zero; 3],
            e: [zero; 3],
            beta: zero,
            cov,
            sum_r: [[zero; 3]; 3],
            sum_dv: [zero; 3],
            span: 0.0,
        }
    }

    /// The attitude (rotation body to world).
    #[inline(always)]
    pub fn rotation(&self) -> Rotation<L> {
        Rotation::of_quaternion(self.q)
    }

    /// Propagate the nominal state over `h` seconds with one IMU sample (`gyro` rad/s, `accel`
    /// m/s^2, both raw, body axes) taken at the interval's start; gravity `g` along -z.
    #[inline(always)]
    pub fn propagate(&mut self, gyro: &[L; 3], accel: &[L; 3], h: f64, g: L) {
        let rot = self.rotation();
        let f = each3(
            #[inline(always)]
            |i| accel[i] - self.ba[i],
        );
        let w = each3(
            #[inline(always)]
            |i| (gyro[i] - self.bg[i]) * h,
        );
        let fw = rot.to_inertial(&f);
        let a = [fw[0], fw[1], fw[2] - g];
        for i in 0..3 {
            self.p[i] = self.p[i] + self.v[i] * h + a[i] * (0.5 * h * h);
            self.v[i] = self.v[i] + a[i] * h;
            self.sum_dv[i] = self.sum_dv[i] + fw[i] * h;
            for j in 0..3 {
                // R_ij = axes[j][i].
                self.sum_r[i][j] = self.sum_r[i][j] + rot.axes[j][i] * h;
            }
        }
        // q <- q Exp(w): the exponential to third order (error O(|w|^5) after normalising).
        let n2 = dot3(&w, &w);
        let c = L::splat(1.0) - n2 * 0.125;
        let s = (L::splat(1.0) - n2 * (1.0 / 24.0)) * 0.5;
        let d = [c, w[0] * s, w[1] * s, w[2] * s];
        self.q = normalised(product(&self.q, &d));
        self.span += h;
    }

    /// Propagate the error covariance over the samples since the last update (their sums),
    /// with the process noises of `t`; the drift and bias states decay.
    ///
    /// P' = F P F^T + Q is symmetric, so only its upper triangle is computed and then copied
    /// to the lower (as PX4's EKF2 predicts its covariance): the rows (F P) only on the columns
    /// the upper triangle's column operations read, the columns ((F P) F^T) only from each
    /// row's own block on. F is the identity but for its blocks P-V (dt), V-TH (-[dv]x), V-BA
    /// (-M), TH-BG (-M) and the decays of E and BETA.
    #[inline(always)]
    pub fn predict(&mut self, t: &Tuning<L>) {
        let dt = self.span;
        if dt == 0.0 {
            return;
        }
        let m = self.sum_r;
        let dv = self.sum_dv;
        // [dv]x: the attitude error's effect on the velocity error is -[dv]x dtheta.
        let zero = L::splat(0.0);
        let skew = [
            [zero, -dv[2], dv[1]],
            [dv[2], zero, -dv[0]],
            [-dv[1], dv[0], zero],
        ];
        let c = &mut self.cov;
        // Rows (F P), in place: position first (reads the old velocity rows), then velocity
        // (the old attitude rows), then attitude (the bias rows, unchanged). A row of block b
        // is needed on the columns from b's first on (the upper triangle's column operations
        // on rows of block b read no column left of it); the rest of it is left stale, below
        // the diagonal, and overwritten by the copy.
        for i in 0..3 {
            for k in 0..STATES {
                c[P + i][k] = c[P + i][k] + c[V + i][k] * dt;
            }
        }
        for i in 0..3 {
            for k in V..STATES {
                let mut x = c[V + i][k];
                for j in 0..3 {
                    x = x - skew[i][j] * c[TH + j][k] - m[i][j] * c[BA + j][k];
                }
                c[V + i][k] = x;
            }
        }
        for i in 0..3 {
            for k in TH..STATES {
                let mut x = c[TH + i][k];
                for j in 0..3 {
                    x = x - m[i][j] * c[BG + j][k];
                }
                c[TH + i][k] = x;
            }
        }
        for i in 0..3 {
            for k in E..STATES {
                c[E + i][k] = c[E + i][k] * t.drift_decay;
            }
        }
        c[BETA][BETA] = c[BETA][BETA] * t.baro_decay;
        // Columns ((F P) F^T) on each row from its block's first column on.
        for (r, row) in c.iter_mut().enumerate() {
            if r < V {
                for i in 0..3 {
                    row[P + i] = row[P + i] + row[V + i] * dt;
                }
            }
            if r < TH {
                for i in 0..3 {
                    let mut x = row[V + i];
                    for j in 0..3 {
                        x = x - skew[i][j] * row[TH + j] - m[i][j] * row[BA + j];
                    }
                    row[V + i] = x;
                }
            }
            if r < BG {
                for i in 0..3 {
                    let mut x = row[TH + i];
                    for j in 0..3 {
                        x = x - m[i][j] * row[BG + j];
                    }
                    row[TH + i] = x;
                }
            }
            for i in 0..3 {
                row[E + i] = row[E + i] * t.drift_decay;
            }
            row[BETA] = row[BETA] * t.baro_decay;
        }
        mirror(c);
        for i in 0..3 {
            c[V + i][V + i] = c[V + i][V + i] + t.accel_noise2 * dt;
            c[TH + i][TH + i] = c[TH + i][TH + i] + t.gyro_noise2 * dt;
            c[BG + i][BG + i] = c[BG + i][BG + i] + t.gyro_walk2 * dt;
            c[BA + i][BA + i] = c[BA + i][BA + i] + t.accel_walk2 * dt;
            c[E + i][E + i] = c[E + i][E + i] + t.drift_gain;
            self.e[i] = self.e[i] * t.drift_decay;
        }
        c[BETA][BETA] = c[BETA][BETA] + t.baro_gain;
        self.beta = self.beta * t.baro_decay;
        self.sum_r = [[zero; 3]; 3];
        self.sum_dv = [zero; 3];
        self.span = 0.0;
    }

    /// Fuse one scalar measurement: innovation `y` (measured less predicted), variance `r`,
    /// and the row `h` of its Jacobian in the error states, given by its non-zero entries.
    /// Lanes where `on` is 0 are left as they are (a lane without this measurement now).
    #[inline(always)]
    pub fn fuse<const K: usize>(&mut self, h: &[(usize, L); K], y: L, r: L, on: L) {
        let c = &mut self.cov;
        let mut ph = [L::splat(0.0); STATES];
        for (i, row) in c.iter().enumerate() {
            let mut x = L::splat(0.0);
            for &(j, hj) in h {
                x = x + row[j] * hj;
            }
            ph[i] = x;
        }
        let mut s = r;
        for &(j, hj) in h {
            s = s + hj * ph[j];
        }
        // `on` is 0 or 1: the gain vanishes where the lane has no measurement.
        let gain = on / s;
        let mut k = [L::splat(0.0); STATES];
        for i in 0..STATES {
            k[i] = ph[i] * gain;
        }
        // The upper triangle, copied to the lower: the update stays symmetric to the bit.
        for i in 0..STATES {
            for j in i..STATES {
                let x = c[i][j] - k[i] * ph[j];
                c[i][j] = x;
                c[j][i] = x;
            }
        }
        let mut dx = k;
        for d in dx.iter_mut() {
            *d = *d * y;
        }
        self.inject(&dx);
    }

    /// The error estimate `dx` moved into the nominal state (the error reset to zero).
    #[inline(always)]
    fn inject(&mut self, dx: &[L; STATES]) {
        for i in 0..3 {
            self.p[i] = self.p[i] + dx[P + i];
            self.v[i] = self.v[i] + dx[V + i];
            self.bg[i] = self.bg[i] + dx[BG + i];
            self.ba[i] = self.ba[i] + dx[BA + i];
            self.e[i] = self.e[i] + dx[E + i];
        }
        self.beta = self.beta + dx[BETA];
        let d = [
            L::splat(1.0),
            dx[TH] * 0.5,
            dx[TH + 1] * 0.5,
            dx[TH + 2] * 0.5,
        ];
        self.q = normalised(product(&d, &self.q));
    }
}

/// The upper triangle of `c` copied to the lower.
#[inline(always)]
fn mirror<L: Lane>(c: &mut [[L; STATES]; STATES]) {
    for i in 0..STATES {
        for j in i + 1..STATES {
            c[j][i] = c[i][j];
        }
    }
}

/// The Hamilton product a b (w first).
#[inline(always)]
pub fn product<L: Lane>(a: &[L; 4], b: &[L; 4]) -> [L; 4] {
    let [aw, ax, ay, az] = *a;
    let [bw, bx, by, bz] = *b;
    [
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    ]
}

#[inline(always)]
pub fn normalised<L: Lane>(q: [L; 4]) -> [L; 4] {
    let inv = L::splat(1.0) / (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
    each4(
        #[inline(always)]
        |i| q[i] * inv,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tuning() -> Tuning<f64> {
        Tuning {
            gyro_noise2: 1e-6,
            accel_noise2: 1e-3,
            gyro_walk2: 1e-8,
            accel_walk2: 1e-7,
            drift_decay: 0.99,
            drift_gain: 0.01,
            baro_decay: 0.999,
            baro_gain: 0.002,
            position2: [0.25; 3],
            velocity2: 0.09,
            baro2: 1.0,
            heading2: 0.09,
        }
    }

    #[test]
    fn a_level_filter_at_rest_stays_at_rest_and_its_covariance_is_symmetric() {
        let mut f = Ekf::new([0.0; 3], [0.0; 3], [1.0, 0.0, 0.0, 0.0], [0.1; STATES]);
        for _ in 0..20 {
            f.propagate(&[0.0; 3], &[0.0, 0.0, 9.81], 0.005, 9.81);
            f.propagate(&[0.0; 3], &[0.0, 0.0, 9.81], 0.005, 9.81);
            f.predict(&tuning());
            f.fuse(&[(P, 1.0), (V, -0.11), (E, 1.0)], 0.3, 0.25, 1.0);
            f.fuse(&[(P + 2, 1.0), (BETA, 1.0)], -0.2, 1.0, 1.0);
        }
        for i in 0..STATES {
            assert!(f.cov[i][i] > 0.0, "variance {i} stays positive");
            for j in 0..STATES {
                let (a, b) = (f.cov[i][j], f.cov[j][i]);
                assert_eq!(a.to_bits(), b.to_bits(), "{i} {j}: {a} {b}");
            }
        }
        // Fusing a lane that has no measurement (`on` = 0) changes nothing.
        let before = f.clone();
        f.fuse(&[(P, 1.0)], 5.0, 0.25, 0.0);
        assert_eq!(before.p, f.p);
        assert_eq!(before.cov, f.cov);
    }

    /// A symmetric positive definite matrix with entries of every sign and size (a seeded
    /// Gram matrix), and the dense F of `predict` for the sums `m`, `dv` over `dt`.
    type Matrix = [[f64; STATES]; STATES];

    fn dense_case() -> (Matrix, [[f64; 3]; 3], [f64; 3], f64) {
        let mut s = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let a: Vec<[f64; STATES]> = (0..STATES)
            .map(|_| std::array::from_fn(|_| next()))
            .collect();
        let mut p = [[0.0; STATES]; STATES];
        for i in 0..STATES {
            for j in 0..STATES {
                p[i][j] = (0..STATES).map(|k| a[i][k] * a[j][k]).sum::<f64>();
            }
        }
        let m = std::array::from_fn(|_| std::array::from_fn(|_| next() * 0.01));
        let dv = std::array::from_fn(|_| next() * 0.2);
        (p, m, dv, 0.01)
    }

    /// `predict` (the upper triangle, copied) equals F P F^T + Q multiplied out densely, and is
    /// symmetric to the bit; `fuse` (the upper triangle, copied) equals P - P h^T h P / s.
    #[test]
    fn the_covariance_is_f_p_f_transposed_plus_q_and_symmetric() {
        let (p, m, dv, dt) = dense_case();
        let t = tuning();
        let mut f = Ekf::new([0.0; 3], [0.0; 3], [1.0, 0.0, 0.0, 0.0], [0.0; STATES]);
        f.cov = p;
        (f.sum_r, f.sum_dv, f.span) = (m, dv, dt);
        f.predict(&t);
        let mut fm = [[0.0; STATES]; STATES];
        for i in 0..STATES {
            fm[i][i] = 1.0;
        }
        let skew = [
            [0.0, -dv[2], dv[1]],
            [dv[2], 0.0, -dv[0]],
            [-dv[1], dv[0], 0.0],
        ];
        for i in 0..3 {
            fm[P + i][V + i] = dt;
            for j in 0..3 {
                fm[V + i][TH + j] = -skew[i][j];
                fm[V + i][BA + j] = -m[i][j];
                fm[TH + i][BG + j] = -m[i][j];
            }
            fm[E + i][E + i] = t.drift_decay;
        }
        fm[BETA][BETA] = t.baro_decay;
        let mut want = [[0.0; STATES]; STATES];
        for i in 0..STATES {
            for j in 0..STATES {
                want[i][j] = (0..STATES)
                    .flat_map(|k| (0..STATES).map(move |l| (k, l)))
                    .map(|(k, l)| fm[i][k] * p[k][l] * fm[j][l])
                    .sum::<f64>();
            }
        }
        for i in 0..3 {
            want[V + i][V + i] += t.accel_noise2 * dt;
            want[TH + i][TH + i] += t.gyro_noise2 * dt;
            want[BG + i][BG + i] += t.gyro_walk2 * dt;
            want[BA + i][BA + i] += t.accel_walk2 * dt;
            want[E + i][E + i] += t.drift_gain;
        }
        want[BETA][BETA] += t.baro_gain;
        for i in 0..STATES {
            for j in 0..STATES {
                let scale = (want[i][i] * want[j][j]).sqrt();
                assert!(
                    (f.cov[i][j] - want[i][j]).abs() <= 1e-13 * scale,
                    "{i} {j}: {} against {}",
                    f.cov[i][j],
                    want[i][j]
                );
                assert_eq!(f.cov[i][j].to_bits(), f.cov[j][i].to_bits(), "{i} {j}");
            }
        }
        // A scalar fusion of h = (1 at P + 1, -0.3 at V + 1, 1 at E + 1).
        let before = f.cov;
        let h = [(P + 1, 1.0), (V + 1, -0.3), (E + 1, 1.0)];
        f.fuse(&h, 0.0, 0.4, 1.0);
        let ph: Vec<f64> = (0..STATES)
            .map(|i| h.iter().map(|&(j, hj)| before[i][j] * hj).sum())
            .collect();
        let s = 0.4 + h.iter().map(|&(j, hj)| hj * ph[j]).sum::<f64>();
        for i in 0..STATES {
            for j in 0..STATES {
                let want = before[i][j] - ph[i] * ph[j] / s;
                let scale = (before[i][i] * before[j][j]).sqrt();
                assert!((f.cov[i][j] - want).abs() <= 1e-13 * scale, "{i} {j}");
                assert_eq!(f.cov[i][j].to_bits(), f.cov[j][i].to_bits(), "{i} {j}");
            }
        }
    }

    #[test]
    fn a_constant_rate_turns_the_attitude_by_its_angle() {
        let mut f = Ekf::new([0.0; 3], [0.0; 3], [1.0, 0.0, 0.0, 0.0], [0.1; STATES]);
        for _ in 0..1000 {
            f.propagate(&[0.0, 0.0, 0.5], &[0.0, 0.0, 9.81], 0.002, 9.81);
        }
        // 1 rad of yaw in 2 s: q = (cos 0.5, 0, 0, sin 0.5).
        assert!((f.q[0] - 0.5f64.cos()).abs() < 1e-12, "{:?}", f.q);
        assert!((f.q[3] - 0.5f64.sin()).abs() < 1e-12, "{:?}", f.q);
    }
}
