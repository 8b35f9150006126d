//! The wind a flight sees (`WindField`: the scenario's components inside the gust window, one
//! random stream per realisation) and stationary series of one component (`fill_series`).

use super::filter::{step_fixed, GustFilter, Normals};
use super::spectra::low_altitude_scales;
use crate::config::{Config, ConfigError, GustComponent};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

/// The random stream of realisation `index` under master `seed`:
/// `ChaCha8Rng::seed_from_u64(seed)` then `set_stream(index)`. A realisation's
/// numbers depend on `(seed, index)` only.
pub fn realisation_rng(seed: u64, index: u64) -> ChaCha8Rng {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(index);
    rng
}

#[allow(clippy::needless_range_loop)]
fn fill_row<const N: usize>(filter: &GustFilter, rng: &mut ChaCha8Rng, row: &mut [f64]) {
    let (phi, g, c) = filter.fixed::<N>();
    let mut x = filter.stationary_state(rng);
    let mut it = row.iter_mut();
    if let Some(first) = it.next() {
        *first = filter.output(&x);
    }
    for v in it {
        step_fixed::<N>(&phi, &g, &mut x, rng);
        let mut w = 0.0;
        for i in 0..N {
            w += c[i] * x[i];
        }
        *v = w;
    }
}

/// Fill `out` (row-major; row `r` is realisation `first_index + r`, `steps`
/// samples long) with a stationary series of one component: row `r` draws from
/// `realisation_rng(seed, first_index + r)`, starts from a stationary state
/// (sample 0 is its output) and advances once per sample. Parallel over rows
/// with rayon in the caller's pool; each row's content is independent of the
/// thread count and of how rows are split between calls.
///
/// A row is bitwise the gust series a single-component [`WindField`] with the
/// same filter produces from the onset step of realisation `first_index + r`.
///
/// # Panics
/// If `steps > 0` and `out.len()` is not a multiple of `steps`.
pub fn fill_series(
    filter: &GustFilter,
    seed: u64,
    first_index: u64,
    steps: usize,
    out: &mut [f64],
) {
    if steps == 0 || out.is_empty() {
        return;
    }
    assert!(
        out.len().is_multiple_of(steps),
        "fill_series: out.len() = {} is not a multiple of steps = {}",
        out.len(),
        steps
    );
    out.par_chunks_mut(steps).enumerate().for_each(|(r, row)| {
        let mut rng = realisation_rng(seed, first_index.wrapping_add(r as u64));
        match filter.order() {
            1 => fill_row::<1>(filter, &mut rng, row),
            2 => fill_row::<2>(filter, &mut rng, row),
            _ => fill_row::<3>(filter, &mut rng, row),
        }
    });
}

/// The discretised wind field of a scenario: built once per batch, shared
/// read-only by all threads. Per-realisation state lives in [`WindState`].
#[derive(Clone, Debug)]
pub struct WindField {
    enabled: bool,
    filters: [Option<GustFilter>; 3],
    mean: [f64; 3],
    start_step: u64,
    end_step: u64,
    dt: f64,
}

/// The unit normals of one flight's turbulence: its seeded stream, or innovations given
/// explicitly (`xi`, consumed in the order the stream would have been: the onset's
/// stationary draws, then each step's, components in the fixed order). Past the end of `xi`
/// (a flight longer than `WindField::innovations` promised) the draws are NaN, which ends
/// the flight as non-finite rather than inventing numbers.
// The seeded stream is the common case and lives on the stack, with the filter states (no
// heap per flight): the size difference is the point.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug)]
pub enum Source<'a> {
    Seeded(ChaCha8Rng),
    Given { xi: &'a [f64], next: usize },
}

/// A cursor over given innovations.
struct Given<'a> {
    xi: &'a [f64],
    next: usize,
}

impl Normals for Given<'_> {
    #[inline(always)]
    fn normal(&mut self) -> f64 {
        let x = self.xi.get(self.next).copied().unwrap_or(f64::NAN);
        self.next += 1;
        x
    }
}

/// Per-realisation wind state: the realisation's normals, the filter states, and whether the
/// gust has started. Fixed size, no heap.
#[derive(Clone, Debug)]
pub struct WindState<'a> {
    rng: Source<'a>,
    x: [[f64; 3]; 3],
    started: bool,
    /// The step the filter states belong to (valid once started).
    step: u64,
}

/// First step `n` with `n dt >= t`, times within 1e-9 of a step treated as on it.
fn step_at_or_after(t: f64, dt: f64) -> u64 {
    if t == f64::INFINITY {
        return u64::MAX;
    }
    let s = (t / dt - 1e-9).ceil();
    if s <= 0.0 {
        0
    } else {
        s as u64 // saturating
    }
}

impl WindField {
    /// Compute the scales ([`low_altitude_scales`]) of a validated scenario's gust
    /// (`Config::validate` has checked every `gust` value, once for the whole engine) and
    /// discretise the active components for the step `integrator.dt`.
    ///
    /// Step `n` (time `n dt`) is inside the window iff `start <= n dt < end`,
    /// times within 1e-9 steps of a grid point counting as on it (so a window
    /// [25, 40) s with dt = 2e-4 s is exactly steps 125000..200000).
    /// When `gust.enabled` is false the field is zero. Errs (key `gust`) only if a filter
    /// cannot be discretised for this step (e.g. `airspeed * dt / length_scale` overflows).
    pub fn new(cfg: &Config) -> Result<Self, ConfigError> {
        let (g, dt) = (&cfg.gust, cfg.integrator.dt);
        if !g.enabled {
            return Ok(WindField {
                enabled: false,
                filters: [None; 3],
                mean: [0.0; 3],
                start_step: 0,
                end_step: 0,
                dt,
            });
        }
        let (sigma, length) = low_altitude_scales(g.altitude, g.w20);
        let mut filters = [None; 3];
        for c in GustComponent::ALL {
            let i = c.index();
            if g.components.contains(&c) {
                let f = GustFilter::new(g.model, c, sigma[i], length[i], g.airspeed, dt).map_err(
                    |e| ConfigError::new("gust", format!("gust ({} component): {e}", c.name())),
                )?;
                filters[i] = Some(f);
            }
        }
        Ok(WindField {
            enabled: true,
            filters,
            mean: g.mean_wind,
            start_step: step_at_or_after(g.start, dt),
            end_step: step_at_or_after(g.end, dt),
            dt,
        })
    }

    /// Fresh per-realisation state: `rng = realisation_rng(seed, index)`; the
    /// filter states are drawn from their stationary distributions lazily at
    /// gust onset, so they do not depend on the length of the pre-gust flight.
    pub fn realisation(&self, seed: u64, index: u64) -> WindState<'static> {
        WindState {
            rng: Source::Seeded(realisation_rng(seed, index)),
            x: [[0.0; 3]; 3],
            started: false,
            step: 0,
        }
    }

    /// Wind (m/s, inertial x, y, z) held over the step starting at `t = step dt`:
    /// zero outside the window and when disabled; `mean + gust` inside.
    ///
    /// Call once per integration step in increasing step order. At the first
    /// call inside the window the filter states are drawn from their stationary
    /// distributions (as of the window's first step; components in order
    /// longitudinal, lateral, vertical, each `order()` normals), then advanced
    /// once per step (same component order). If steps are skipped the filters
    /// are advanced through them, so the value at a step does not depend on
    /// which earlier steps were sampled; a repeated step returns the same value
    /// without drawing, and a step earlier than the last one inside the window
    /// is not rewound (it returns the current value). No allocation, and no
    /// random draws outside the window.
    #[inline]
    pub fn sample(&self, state: &mut WindState<'_>, step: u64) -> [f64; 3] {
        if !self.enabled || step < self.start_step || step >= self.end_step {
            return [0.0; 3];
        }
        // One match per sample, not per normal: the draws below run on the concrete source.
        let WindState {
            rng,
            x,
            started,
            step: at,
        } = state;
        match rng {
            Source::Seeded(rng) => self.advance_to(x, started, at, step, rng),
            Source::Given { xi, next } => {
                let mut given = Given { xi, next: *next };
                let w = self.advance_to(x, started, at, step, &mut given);
                *next = given.next;
                w
            }
        }
    }

    /// `sample`'s work on a concrete source of normals.
    #[inline(always)]
    fn advance_to(
        &self,
        x: &mut [[f64; 3]; 3],
        started: &mut bool,
        at: &mut u64,
        step: u64,
        normals: &mut impl Normals,
    ) -> [f64; 3] {
        if !*started {
            for (i, f) in self.filters.iter().enumerate() {
                if let Some(f) = f {
                    x[i] = f.stationary_state(normals);
                }
            }
            *started = true;
            *at = self.start_step;
        }
        while *at < step {
            for (i, f) in self.filters.iter().enumerate() {
                if let Some(f) = f {
                    f.advance(&mut x[i], normals);
                }
            }
            *at += 1;
        }
        let mut w = self.mean;
        for (i, f) in self.filters.iter().enumerate() {
            if let Some(f) = f {
                w[i] += f.output(&x[i]);
            }
        }
        w
    }

    /// A realisation driven by the innovations `xi` instead of a seeded stream: the same
    /// flight as `realisation(seed, index)` when `xi` is `innovations_of(seed, index, ..)`.
    pub fn given<'a>(&self, xi: &'a [f64]) -> WindState<'a> {
        WindState {
            rng: Source::Given { xi, next: 0 },
            x: [[0.0; 3]; 3],
            started: false,
            step: 0,
        }
    }

    /// How many unit normals a flight of `steps` steps draws (its innovations): the active
    /// components' orders, at the onset and at every later step of the window up to the last
    /// step of the flight. Zero when the gust is off.
    pub fn innovations(&self, steps: usize) -> usize {
        if !self.enabled {
            return 0;
        }
        let per_step: usize = self.filters.iter().flatten().map(|f| f.order()).sum();
        let last = (steps as u64).min(self.end_step.saturating_sub(1));
        let sampled = (last + 1).saturating_sub(self.start_step) as usize;
        per_step * sampled
    }

    /// The innovations realisation `index` of `seed` draws in a flight of `steps` steps:
    /// `given` with them flies exactly the seeded flight.
    pub fn innovations_of(&self, seed: u64, index: u64, steps: usize) -> Vec<f64> {
        let mut rng = realisation_rng(seed, index);
        (0..self.innovations(steps)).map(|_| rng.normal()).collect()
    }

    /// Whether the wind is on at all.
    pub fn enabled(&self) -> bool {
        self.enabled
    }

    /// First step inside the window.
    pub fn start_step(&self) -> u64 {
        self.start_step
    }

    /// First step after the window (exclusive end).
    pub fn end_step(&self) -> u64 {
        self.end_step
    }

    /// Whether step `step` is inside the (enabled) window.
    pub fn is_active(&self, step: u64) -> bool {
        self.enabled && step >= self.start_step && step < self.end_step
    }

    /// The filter of a component, if active.
    pub fn filter(&self, component: GustComponent) -> Option<&GustFilter> {
        self.filters[component.index()].as_ref()
    }

    /// Mean wind added inside the window (zero when disabled).
    pub fn mean_wind(&self) -> [f64; 3] {
        self.mean
    }

    /// The integration step the field was discretised for, s.
    pub fn dt(&self) -> f64 {
        self.dt
    }
}

#[cfg(test)]
mod tests {
    use super::super::filter::tests::{filt, KS, MODELS};
    use super::*;
    use crate::config::GustModel;

    fn serial_row(f: &GustFilter, seed: u64, index: u64, steps: usize) -> Vec<f64> {
        let mut rng = realisation_rng(seed, index);
        let mut x = f.stationary_state(&mut rng);
        let mut out = vec![f.output(&x)];
        for _ in 1..steps {
            f.advance(&mut x, &mut rng);
            out.push(f.output(&x));
        }
        out
    }

    #[test]
    fn streams_are_deterministic_per_seed_and_index() {
        for model in MODELS {
            let f = filt(model, GustComponent::Vertical, 1.0, 0.2);
            let a = serial_row(&f, 7, 3, 500);
            let b = serial_row(&f, 7, 3, 500);
            assert!(a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()));
            let c = serial_row(&f, 7, 4, 500);
            let d = serial_row(&f, 8, 3, 500);
            assert!(a.iter().zip(&c).all(|(x, y)| x != y));
            assert!(a.iter().zip(&d).all(|(x, y)| x != y));
        }
    }

    #[test]
    fn fill_series_is_independent_of_threads_and_splitting() {
        for (model, c) in [
            (GustModel::Dryden, GustComponent::Longitudinal),
            (GustModel::Dryden, GustComponent::Vertical),
            (GustModel::VonKarman, GustComponent::Longitudinal),
            (GustModel::VonKarman, GustComponent::Vertical),
        ] {
            let f = filt(model, c, 1.2, 0.05);
            let (rows, steps, seed) = (13, 257, 42);
            let run = |threads: usize, first: u64, n: usize| {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap();
                let mut out = vec![0.0; n * steps];
                pool.install(|| fill_series(&f, seed, first, steps, &mut out));
                out
            };
            let one = run(1, 0, rows);
            let two = run(2, 0, rows);
            assert!(one
                .iter()
                .zip(&two)
                .all(|(x, y)| x.to_bits() == y.to_bits()));
            // Rows 5.. computed as a separate call.
            let tail = run(2, 5, rows - 5);
            assert!(one[5 * steps..]
                .iter()
                .zip(&tail)
                .all(|(x, y)| x.to_bits() == y.to_bits()));
            for r in [0, 6, 12] {
                let s = serial_row(&f, seed, r as u64, steps);
                let row = &one[r * steps..(r + 1) * steps];
                assert!(row.iter().zip(&s).all(|(x, y)| x.to_bits() == y.to_bits()));
            }
        }
    }

    /// Per-row estimates of E[w_t w_{t+lag}]: their mean, and its standard error.
    fn lag_moment(series: &[f64], rows: usize, steps: usize, lag: usize) -> (f64, f64) {
        let est: Vec<f64> = (0..rows)
            .map(|r| {
                let row = &series[r * steps..(r + 1) * steps];
                let n = steps - lag;
                (0..n).map(|t| row[t] * row[t + lag]).sum::<f64>() / n as f64
            })
            .collect();
        let mean = est.iter().sum::<f64>() / rows as f64;
        let var = est.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / (rows - 1) as f64;
        (mean, (var / rows as f64).sqrt())
    }

    #[test]
    fn sample_variance_and_autocorrelation() {
        let (rows, steps) = (200, 2000);
        let sigma = 1.3;
        let mut cases = Vec::new();
        for k in KS {
            cases.push((GustModel::Dryden, GustComponent::Longitudinal, k));
            cases.push((GustModel::Dryden, GustComponent::Vertical, k));
        }
        for k in [0.5, 2.0] {
            cases.push((GustModel::VonKarman, GustComponent::Longitudinal, k));
            cases.push((GustModel::VonKarman, GustComponent::Vertical, k));
        }
        for (i, (model, c, k)) in cases.into_iter().enumerate() {
            let f = filt(model, c, sigma, k);
            let mut out = vec![0.0; rows * steps];
            fill_series(&f, 1000 + i as u64, 0, steps, &mut out);
            for lag in [0usize, 1, 2, 4] {
                let (m, se) = lag_moment(&out, rows, steps, lag);
                let want = f.autocorrelation(lag as f64 * f.dt());
                assert!(
                    (m - want).abs() < 4.5 * se,
                    "{model:?} {c:?} k={k} lag {lag}: {m} vs {want} (se {se})"
                );
                if lag == 0 {
                    // The test must be able to see a few-percent error.
                    assert!(se < 0.03 * sigma * sigma, "{model:?} {c:?} k={k}: se {se}");
                }
            }
        }
    }

    /// The paper preset's gust with a short window: vertical Dryden, h = 2 m, W20 = 10 m/s,
    /// V = 10 m/s, [1, 2) s.
    fn spec() -> Config {
        let mut cfg = crate::config::tests::paper();
        cfg.gust.enabled = true;
        cfg.gust.model = GustModel::Dryden;
        cfg.gust.components = vec![GustComponent::Vertical];
        cfg.gust.altitude = 2.0;
        cfg.gust.w20 = 10.0;
        cfg.gust.airspeed = 10.0;
        cfg.gust.mean_wind = [0.0; 3];
        cfg.gust.start = 1.0;
        cfg.gust.end = 2.0;
        cfg
    }

    /// `s`'s wind field for the step `dt`.
    fn field(s: &Config, dt: f64) -> WindField {
        let mut cfg = s.clone();
        cfg.integrator.dt = dt;
        WindField::new(&cfg).unwrap()
    }

    #[test]
    fn wind_field_window_mean_and_disable() {
        use GustComponent::*;
        let dt = 0.01;
        let mut s = spec();
        s.gust.components = vec![Longitudinal, Vertical];
        s.gust.mean_wind = [1.0, -2.0, 0.5];
        let wf = field(&s, dt);
        assert_eq!((wf.start_step(), wf.end_step()), (100, 200));
        let mut st = wf.realisation(3, 9);
        let mut inside = Vec::new();
        for step in 0..300u64 {
            let w = wf.sample(&mut st, step);
            if (100..200).contains(&step) {
                assert!(wf.is_active(step));
                assert_ne!(w[0], s.gust.mean_wind[0]);
                assert_eq!(w[1], s.gust.mean_wind[1]); // lateral off: mean only
                assert_ne!(w[2], s.gust.mean_wind[2]);
                inside.push(w);
            } else {
                assert_eq!(w, [0.0; 3], "step {step}");
                assert!(!wf.is_active(step));
            }
        }
        // Gust inside = mean + the filters' outputs, and the vertical has sigma_z = 1.
        let fz = wf.filter(Vertical).unwrap();
        assert!((fz.sigma() - 1.0).abs() < 1e-15 && fz.length_scale() == 2.0);
        assert!(wf.filter(Lateral).is_none());
        // Disabled: zero throughout, no matter the rest.
        s.gust.enabled = false;
        s.gust.airspeed = 0.0;
        let wf = field(&s, dt);
        let mut st = wf.realisation(3, 9);
        for step in 0..300u64 {
            assert_eq!(wf.sample(&mut st, step), [0.0; 3]);
        }
    }

    #[test]
    fn window_boundaries_snap_to_the_step_grid() {
        let mut s = spec();
        s.gust.start = 25.0;
        s.gust.end = 40.0;
        let wf = field(&s, 2e-4);
        assert_eq!((wf.start_step(), wf.end_step()), (125_000, 200_000));
        s.gust.start = 0.1;
        s.gust.end = 0.3;
        let wf = field(&s, 0.1);
        assert_eq!((wf.start_step(), wf.end_step()), (1, 3));
        s.gust.start = 0.15;
        let wf = field(&s, 0.1);
        assert_eq!(wf.start_step(), 2);
        s.gust.start = 0.0;
        s.gust.end = f64::INFINITY;
        let wf = field(&s, 0.1);
        assert_eq!((wf.start_step(), wf.end_step()), (0, u64::MAX));
    }

    #[test]
    fn gust_does_not_depend_on_pre_gust_duration() {
        let dt = 0.01;
        for model in MODELS {
            let mut s = spec();
            s.gust.model = model;
            s.gust.components = GustComponent::ALL.to_vec();
            s.gust.mean_wind = [0.3, 0.0, -0.1];
            let a = field(&s, dt);
            s.gust.start += 37.0 * dt;
            s.gust.end += 37.0 * dt;
            let b = field(&s, dt);
            assert_eq!(b.start_step(), a.start_step() + 37);
            let mut sa = a.realisation(11, 2);
            let mut sb = b.realisation(11, 2);
            let wa: Vec<[f64; 3]> = (0..a.end_step()).map(|n| a.sample(&mut sa, n)).collect();
            let wb: Vec<[f64; 3]> = (0..b.end_step()).map(|n| b.sample(&mut sb, n)).collect();
            let ia = &wa[a.start_step() as usize..];
            let ib = &wb[b.start_step() as usize..];
            assert_eq!(ia.len(), 100);
            assert_eq!(ia, ib);
        }
    }

    #[test]
    fn single_component_field_equals_fill_series_row() {
        let wf = field(&spec(), 0.01);
        let f = *wf.filter(GustComponent::Vertical).unwrap();
        let steps = (wf.end_step() - wf.start_step()) as usize;
        let mut rows = vec![0.0; 4 * steps];
        fill_series(&f, 5, 0, steps, &mut rows);
        let mut st = wf.realisation(5, 3);
        let z: Vec<f64> = (0..wf.end_step())
            .map(|n| wf.sample(&mut st, n)[2])
            .skip(wf.start_step() as usize)
            .collect();
        assert!(z
            .iter()
            .zip(&rows[3 * steps..])
            .all(|(x, y)| x.to_bits() == y.to_bits()));
    }

    #[test]
    fn skipped_and_repeated_steps_are_consistent() {
        let mut s = spec();
        s.gust.components = GustComponent::ALL.to_vec();
        let wf = field(&s, 0.01);
        let mut every = wf.realisation(1, 1);
        let all: Vec<[f64; 3]> = (0..200).map(|n| wf.sample(&mut every, n)).collect();
        let mut sparse = wf.realisation(1, 1);
        for n in [0u64, 50, 103, 103, 150, 151, 199] {
            assert_eq!(wf.sample(&mut sparse, n), all[n as usize], "step {n}");
        }
    }

    #[test]
    fn a_scale_no_value_check_can_see_names_the_gust() {
        // The scenario's gust values are checked once, by `Config::validate` (config.rs
        // tests); what no value check can see (a step too small for the scale) names `gust`.
        let mut s = spec();
        s.gust.altitude = 1e300;
        s.gust.airspeed = 1e-300;
        assert!(s.validate().is_ok());
        let e = WindField::new(&s).unwrap_err();
        assert_eq!(e.key, "gust");
        assert!(
            e.message
                .starts_with("gust (vertical component): airspeed * dt / length_scale"),
            "{e}"
        );
    }
}
