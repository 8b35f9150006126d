//! The sensors of one lane (docs/model.md, "Navigation"): the IMU, the GNSS receiver, the
//! barometer and the heading source, each drawing from its own seeded stream, keyed by the
//! flight's seed, its realisation and the sensor, so that no sensor's numbers depend on
//! another's, on the law, on the gust or on the workers.

use crate::config::navigation::{Schedule, Sensors};
use crate::lane::isa::Isa;
use crate::lane::random::normal::{standard_normal, Ahead, CHUNK};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::collections::VecDeque;

/// The streams, by name (the second word of their key).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stream {
    Imu,
    Gnss,
    Baro,
    Heading,
    /// The filter's initial estimate error.
    Filter,
}

impl Stream {
    fn tag(self) -> &'static [u8; 8] {
        match self {
            Stream::Imu => b"imu\0\0\0\0\0",
            Stream::Gnss => b"gnss\0\0\0\0",
            Stream::Baro => b"baro\0\0\0\0",
            Stream::Heading => b"heading\0",
            Stream::Filter => b"filter\0\0",
        }
    }
}

/// The stream of `sensor` for realisation `index` under `seed`: ChaCha8 keyed by the seed's
/// eight bytes and the sensor's tag (the gust's key is the seed expanded by `seed_from_u64`,
/// which never has this form), on stream `index`.
pub fn sensor_rng(seed: u64, index: u64, sensor: Stream) -> ChaCha8Rng {
    let mut key = [0u8; 32];
    key[..8].copy_from_slice(&seed.to_le_bytes());
    key[8..16].copy_from_slice(sensor.tag());
    key[16..24].copy_from_slice(b"quadrs\0\0");
    let mut rng = ChaCha8Rng::from_seed(key);
    rng.set_stream(index);
    rng
}

/// n standard normals of `rng`.
#[inline(always)]
fn normals<const N: usize>(rng: &mut ChaCha8Rng) -> [f64; N] {
    std::array::from_fn(|_| standard_normal(rng))
}

/// The IMU's normals drawn at once: `IMU_DRAWS` a sample, for this many samples.
const IMU_SAMPLES: usize = 32;
/// Normals an IMU sample draws.
const IMU_DRAWS: usize = 12;
/// The buffer's normals (`Ahead::normals` may write up to `CHUNK - 1` past the last).
const IMU_BUFFER: usize = IMU_SAMPLES * IMU_DRAWS + CHUNK;

/// The IMU stream's next normals, drawn in bulk (`Ahead`): the same numbers, in the same
/// order, as `standard_normal` drawing them one at a time, which cost the filter's step 4 %
/// of the delivery's time (a ChaCha8 word and the ziggurat's branch per normal).
struct ImuNormals {
    ahead: Ahead,
    buffer: Box<[f64; IMU_BUFFER]>,
    /// `next..filled` are the stream's next normals.
    next: usize,
    filled: usize,
    /// The instruction set the keystream and the ziggurat's candidates are made with.
    isa: Isa,
}

impl ImuNormals {
    fn new(isa: Isa) -> Self {
        Self {
            ahead: Ahead::new(),
            buffer: Box::new([0.0; IMU_BUFFER]),
            next: 0,
            filled: 0,
            isa,
        }
    }

    /// The stream's next `N` normals.
    #[inline(always)]
    fn take<const N: usize>(&mut self, rng: &mut ChaCha8Rng) -> [f64; N] {
        if self.filled - self.next < N {
            self.refill(rng);
        }
        let mut out = [0.0; N];
        out.copy_from_slice(&self.buffer[self.next..self.next + N]);
        self.next += N;
        out
    }

    /// The normals held moved to the front, and the buffer filled up after them.
    #[inline(never)]
    fn refill(&mut self, rng: &mut ChaCha8Rng) {
        let held = self.filled - self.next;
        self.buffer.copy_within(self.next..self.filled, 0);
        let n = IMU_SAMPLES * IMU_DRAWS - held;
        let buffer = &mut self.buffer;
        self.ahead.normals(rng, n, self.isa, |r, xs| {
            buffer[held + r..held + r + xs.len()].copy_from_slice(xs);
        });
        (self.next, self.filled) = (0, held + n);
    }
}

/// A GNSS fix: position and velocity, and whether it was received (not in an outage).
#[derive(Clone, Copy, Debug)]
pub struct Fix {
    pub due: usize,
    pub z: [f64; 6],
    pub received: bool,
}

/// One lane's sensors: their streams, their slow states (biases, drifts) and the GNSS fixes on
/// their way.
pub struct LaneSensors {
    imu: ChaCha8Rng,
    imu_normals: ImuNormals,
    gnss: ChaCha8Rng,
    baro: ChaCha8Rng,
    heading: ChaCha8Rng,
    /// The IMU's biases now.
    pub bg: [f64; 3],
    pub ba: [f64; 3],
    /// The GNSS receiver's drift and the barometer's bias now.
    pub e: [f64; 3],
    pub beta: f64,
    fixes: VecDeque<Fix>,
    // Per sample: the noises' sigmas and the slow states' steps.
    gyro_sd: f64,
    accel_sd: f64,
    gyro_walk_sd: f64,
    accel_walk_sd: f64,
    drift_decay: f64,
    drift_sd: f64,
    position_sd: [f64; 3],
    velocity_sd: f64,
    baro_decay: f64,
    baro_step_sd: f64,
    baro_sd: f64,
    heading_sd: f64,
    outages: Vec<(f64, f64)>,
    delay: usize,
}

impl LaneSensors {
    /// The sensors of realisation `index` under `seed` at the step `dt`: their initial biases
    /// and drifts drawn (the IMU's biases from N(0, sigma^2), the drifts stationary). `isa`:
    /// the instruction set the caller runs on (`Lane::within`), for the IMU's bulk draws.
    pub fn new(
        s: &Sensors,
        schedule: &Schedule,
        (dt, isa): (f64, Isa),
        seed: u64,
        index: u64,
    ) -> Self {
        let mut imu = sensor_rng(seed, index, Stream::Imu);
        let mut gnss = sensor_rng(seed, index, Stream::Gnss);
        let mut baro = sensor_rng(seed, index, Stream::Baro);
        let heading = sensor_rng(seed, index, Stream::Heading);
        let h = schedule.imu as f64 * dt;
        let b0: [f64; 6] = normals(&mut imu);
        let e0: [f64; 3] = normals(&mut gnss);
        let beta0 = standard_normal(&mut baro);
        let (i, g, b) = (&s.imu, &s.gnss, &s.baro);
        let drift_decay = (-(schedule.gnss as f64 * dt) / g.drift_time).exp();
        let baro_decay = (-(schedule.baro as f64 * dt) / b.drift_time).exp();
        Self {
            imu,
            imu_normals: ImuNormals::new(isa),
            gnss,
            baro,
            heading,
            bg: [0, 1, 2].map(|k| b0[k] * i.gyro_bias),
            ba: [0, 1, 2].map(|k| b0[3 + k] * i.accel_bias),
            e: e0.map(|x| x * g.drift),
            beta: beta0 * b.drift,
            fixes: VecDeque::with_capacity(schedule.delay / schedule.gnss + 2),
            gyro_sd: i.gyro_noise / h.sqrt(),
            accel_sd: i.accel_noise / h.sqrt(),
            gyro_walk_sd: i.gyro_bias_walk * h.sqrt(),
            accel_walk_sd: i.accel_bias_walk * h.sqrt(),
            drift_decay,
            drift_sd: (1.0 - drift_decay * drift_decay).sqrt() * g.drift,
            position_sd: g.position_noise,
            velocity_sd: g.velocity_noise,
            baro_decay,
            baro_step_sd: (1.0 - baro_decay * baro_decay).sqrt() * b.drift,
            baro_sd: b.noise,
            heading_sd: s.heading.noise,
            outages: g.outages.iter().map(|o| (o.start, o.duration)).collect(),
            delay: schedule.delay,
        }
    }

    /// One IMU sample: the gyro's (rad/s) of the body rates `w` and the accelerometer's
    /// (m/s^2) of the specific force `f` (body axes), both their means over the sample's
    /// period (what an IMU's delta angle and delta velocity give), each with its bias and
    /// white noise; then the biases' random walk over the period. Draws, in order: gyro noise,
    /// accelerometer noise, gyro bias step, accelerometer bias step (3 each).
    #[inline(always)]
    pub fn imu(&mut self, w: [f64; 3], f: [f64; 3]) -> ([f64; 3], [f64; 3]) {
        let n: [f64; IMU_DRAWS] = self.imu_normals.take(&mut self.imu);
        let gyro = [0, 1, 2].map(|k| w[k] + self.bg[k] + n[k] * self.gyro_sd);
        let accel = [0, 1, 2].map(|k| f[k] + self.ba[k] + n[3 + k] * self.accel_sd);
        for k in 0..3 {
            self.bg[k] += n[6 + k] * self.gyro_walk_sd;
            self.ba[k] += n[9 + k] * self.accel_walk_sd;
        }
        (gyro, accel)
    }

    /// rad/s, the gyro's reading at the start, before any sample: the body rates `w` with the
    /// bias and one white-noise draw (3 draws).
    #[inline(always)]
    pub fn first_gyro(&mut self, w: [f64; 3]) -> [f64; 3] {
        let n: [f64; 3] = self.imu_normals.take(&mut self.imu);
        [0, 1, 2].map(|k| w[k] + self.bg[k] + n[k] * self.gyro_sd)
    }

    /// A GNSS epoch at step `k`: the fix of the state now (position `p`, velocity `v`), on
    /// its way until step `k + delay`; the drift then steps to the next epoch.
    #[inline(always)]
    pub fn gnss_epoch(&mut self, k: usize, dt: f64, p: [f64; 3], v: [f64; 3]) {
        let n: [f64; 9] = normals(&mut self.gnss);
        let t = k as f64 * dt;
        let received = !self
            .outages
            .iter()
            .any(|&(start, length)| t >= start && t < start + length);
        let mut z = [0.0; 6];
        for i in 0..3 {
            z[i] = p[i] + self.e[i] + n[i] * self.position_sd[i];
            z[3 + i] = v[i] + n[3 + i] * self.velocity_sd;
            self.e[i] = self.drift_decay * self.e[i] + self.drift_sd * n[6 + i];
        }
        self.fixes.push_back(Fix {
            due: k + self.delay,
            z,
            received,
        });
    }

    /// The fix due at step `k`, if one is.
    #[inline(always)]
    pub fn arrived(&mut self, k: usize) -> Option<Fix> {
        match self.fixes.front() {
            Some(f) if f.due == k => self.fixes.pop_front(),
            _ => None,
        }
    }

    /// m, the barometer's height for the height `z` (z up); its bias then steps.
    #[inline(always)]
    pub fn baro(&mut self, z: f64) -> f64 {
        let [n, xi]: [f64; 2] = normals(&mut self.baro);
        let m = z + self.beta + n * self.baro_sd;
        self.beta = self.baro_decay * self.beta + self.baro_step_sd * xi;
        m
    }

    /// rad, the heading source's yaw for the yaw `psi`, in (-pi, pi].
    #[inline(always)]
    pub fn heading(&mut self, psi: f64) -> f64 {
        wrap(psi + standard_normal(&mut self.heading) * self.heading_sd)
    }
}

/// The filter's initial estimate error of realisation `index` under `seed`: position,
/// velocity and attitude (world axes), each a standard normal times its sigma.
pub fn initial_error(seed: u64, index: u64, sd: &[f64; 9]) -> [f64; 9] {
    let mut rng = sensor_rng(seed, index, Stream::Filter);
    let n: [f64; 9] = normals(&mut rng);
    std::array::from_fn(|i| n[i] * sd[i])
}

/// An angle in (-pi, pi].
#[inline(always)]
pub fn wrap(a: f64) -> f64 {
    use std::f64::consts::{PI, TAU};
    let w = a - TAU * (a / TAU).round();
    if w <= -PI {
        w + TAU
    } else if w > PI {
        w - TAU
    } else {
        w
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_sensor_has_its_own_stream() {
        let a = normals::<4>(&mut sensor_rng(7, 3, Stream::Imu));
        let b = normals::<4>(&mut sensor_rng(7, 3, Stream::Gnss));
        let c = normals::<4>(&mut sensor_rng(7, 4, Stream::Imu));
        let again = normals::<4>(&mut sensor_rng(7, 3, Stream::Imu));
        assert_eq!(a, again);
        assert_ne!(a, b);
        assert_ne!(a, c);
        let gust = normals::<4>(&mut crate::gust::realisation_rng(7, 3));
        assert_ne!(a, gust);
    }

    /// The IMU's normals drawn in bulk are the stream's normals one at a time, in order, across
    /// refills and on each instruction set this machine has (the first gyro's 3, then 12 a
    /// sample).
    #[test]
    fn the_imus_bulk_normals_are_its_streams_one_at_a_time() {
        let isas = [Isa::Baseline, Isa::Avx2, Isa::Avx512];
        for isa in isas.into_iter().filter(|isa| isa.supported()) {
            let mut one = sensor_rng(5, 2, Stream::Imu);
            let want: Vec<f64> = (0..3 + 12 * 100)
                .map(|_| standard_normal(&mut one))
                .collect();
            let mut rng = sensor_rng(5, 2, Stream::Imu);
            let mut bulk = ImuNormals::new(isa);
            let mut got = bulk.take::<3>(&mut rng).to_vec();
            for _ in 0..100 {
                got.extend(bulk.take::<IMU_DRAWS>(&mut rng));
            }
            assert_eq!(got, want, "{isa:?}");
        }
    }

    fn sensors(change: impl Fn(&mut Sensors)) -> (Sensors, Schedule) {
        let mut s = Sensors::default();
        change(&mut s);
        let schedule = Schedule {
            imu: 5,
            filter: 10,
            gnss: 200,
            delay: 110,
            baro: 20,
            heading: 100,
        };
        (s, schedule)
    }

    /// The overlapping Allan deviation of `x` (samples every `h` s) at `m` samples.
    fn allan(x: &[f64], m: usize) -> f64 {
        let mut c = vec![0.0; x.len() + 1];
        for (i, v) in x.iter().enumerate() {
            c[i + 1] = c[i] + v;
        }
        let n = x.len() - 2 * m + 1;
        let mut s = 0.0;
        for i in 0..n {
            let a = (c[i + m] - c[i]) / m as f64;
            let b = (c[i + 2 * m] - c[i + m]) / m as f64;
            s += (b - a) * (b - a);
        }
        (s / (2.0 * n as f64)).sqrt()
    }

    /// The gyro's Allan deviation is N / sqrt(tau) where the white noise dominates and
    /// K sqrt(tau / 3) where the bias walk does (IEEE Std 952), each to 10 %.
    #[test]
    fn the_gyros_allan_deviation_shows_its_density_and_its_bias_walk() {
        let (noise, walk) = (1e-3, 1e-2);
        let (s, sch) = sensors(|s| {
            s.imu.gyro_noise = noise;
            s.imu.gyro_bias_walk = walk;
        });
        let dt = 1e-3;
        let h = sch.imu as f64 * dt;
        let mut lane = LaneSensors::new(&s, &sch, (dt, Isa::Baseline), 9, 0);
        let x: Vec<f64> = (0..400_000)
            .map(|_| lane.imu([0.0; 3], [0.0; 3]).0[0])
            .collect();
        let white = allan(&x, 1);
        let want = noise / h.sqrt();
        assert!((white / want - 1.0).abs() < 0.1, "{white} vs {want}");
        let m = 400; // tau = 2 s: the walk's K sqrt(tau / 3) is 11x the white part
        let tau = m as f64 * h;
        let got = allan(&x, m);
        let want = (noise * noise / tau + walk * walk * tau / 3.0).sqrt();
        assert!((got / want - 1.0).abs() < 0.1, "{got} vs {want}");
    }

    /// The GNSS drift's autocorrelation at a lag of its time constant is exp(-1), and its
    /// sigma is the stated one.
    #[test]
    fn the_gnss_drift_has_its_time_constant_and_its_sigma() {
        let (s, sch) = sensors(|s| {
            s.gnss.drift = 2.0;
            s.gnss.drift_time = 10.0;
            s.gnss.position_noise = [0.0; 3];
        });
        let dt = 1e-3;
        let epoch = sch.gnss as f64 * dt;
        let mut lane = LaneSensors::new(&s, &sch, (dt, Isa::Baseline), 4, 1);
        let n = 400_000;
        let mut e = Vec::with_capacity(n);
        for j in 0..n {
            lane.gnss_epoch(j * sch.gnss, dt, [0.0; 3], [0.0; 3]);
            e.push(lane.fixes.pop_front().expect("a fix").z[0]);
        }
        let var = e.iter().map(|x| x * x).sum::<f64>() / n as f64;
        assert!(
            (var.sqrt() / 2.0 - 1.0).abs() < 0.05,
            "sigma {}",
            var.sqrt()
        );
        let lag = (10.0 / epoch).round() as usize;
        let cov = (0..n - lag).map(|i| e[i] * e[i + lag]).sum::<f64>() / (n - lag) as f64;
        let rho = cov / var;
        assert!((rho - (-1f64).exp()).abs() < 0.05, "rho {rho}");
    }

    #[test]
    fn angles_wrap_into_the_half_open_circle() {
        use std::f64::consts::PI;
        assert_eq!(wrap(PI), PI);
        assert_eq!(wrap(-PI), PI);
        assert!((wrap(3.0 * PI / 2.0) + PI / 2.0).abs() < 1e-15);
        assert_eq!(wrap(0.25), 0.25);
    }
}
