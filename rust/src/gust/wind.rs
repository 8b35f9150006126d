//! The wind a flight sees (`WindField`: the scenario's components inside the gust window, one
//! random stream per realisation) and stationary series of one component (`fill_series`).

use super::filter::{step_fixed, GustFilter, GustSpec, Normals};
use super::source::{Kinematics, Moment};
use super::spectra::METRES_PER_FOOT;
use super::spectra::{low_altitude_scales, low_altitude_scales_lanes};
use super::{AnySource, Prescribed};
use crate::config::{ConfigError, GustAirspeed, GustAltitude, GustComponent};
use crate::gust::WindContext;
use crate::lane::{KernelOps, Lane};
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

/// Lowest and highest altitude (m) of `gust.altitude = "vehicle"`: MIL-F-8785C's
/// low-altitude model holds for 10 ft to 1000 ft; the vehicle's altitude is clamped to it.
pub const VEHICLE_ALTITUDE_RANGE: (f64, f64) = (10.0 * METRES_PER_FOOT, 1000.0 * METRES_PER_FOOT);

/// The `Follow` of every lane of a lane-set ([`WindField::follow_lanes`]): masks (all bits set
/// where true) of the lanes whose altitude and airspeed follow the vehicle, the others' fixed
/// values, and each lane's minimum airspeed and W20.
#[derive(Clone, Copy)]
pub(super) struct FollowLanes<L> {
    vehicle_altitude: L,
    fixed_altitude: L,
    relative_airspeed: L,
    fixed_airspeed: L,
    min_airspeed: L,
    w20: L,
}

impl<L: KernelOps> FollowLanes<L> {
    /// [`WindField::follow_inputs`] of every lane at once, bit for bit: the altitude, W20 and
    /// V of the quadrotors at altitudes `z` moving at `vel` through the mean air `mean`.
    #[inline(always)]
    pub(super) fn inputs(&self, z: L, vel: [L; 3], mean: [L; 3]) -> (L, L, L) {
        let (lo, hi) = VEHICLE_ALTITUDE_RANGE;
        // `f64::clamp`, which keeps a NaN (a lane's `max` gives its bound).
        let clamped = L::select(z.cmp_ne(z), z, z.max(L::splat(lo)).min(L::splat(hi)));
        let h = L::select(self.vehicle_altitude, clamped, self.fixed_altitude);
        let r: [L; 3] = std::array::from_fn(|i| vel[i] - mean[i]);
        let speed = (r[0] * r[0] + r[1] * r[1] + r[2] * r[2])
            .sqrt()
            .max(self.min_airspeed);
        let v = L::select(self.relative_airspeed, speed, self.fixed_airspeed);
        (h, self.w20, v)
    }
}

/// Turbulence scales that follow the vehicle: sigma and L from its altitude, V from its speed
/// through the mean air, re-discretised every step.
#[derive(Clone, Copy, Debug)]
struct Follow {
    altitude: GustAltitude,
    airspeed: GustAirspeed,
    w20: f64,
    min_airspeed: f64,
}

/// The wind of a scenario, built once per batch and shared read-only by all threads
/// (per-realisation state lives in [`WindState`]): the held wind of a step is
/// `mean air + turbulence + the other sources`, composed behind one vector.
///
/// * turbulence (docs/model.md section 4): inside [gust.start, gust.end) when `gust.enabled`,
///   plus `gust.mean_wind` there; its axes turned by `wind.heading` (u along it, v to its
///   left, w up); with `gust.altitude = "vehicle"` or `gust.airspeed = "relative"` its
///   filters are re-discretised every step for that step's scales;
/// * the deterministic sources ([`super::source`]: the `[wind]` mean wind with its shear
///   profile, `[[wind.gusts]]`, `[wind.table]`, a prescribed wind), a list in the summation
///   order, at all times: the mean air's (summed first, the turbulence then added to them),
///   then the others one by one.
#[derive(Clone, Debug)]
pub struct WindField {
    enabled: bool,
    filters: [Option<GustFilter>; 3],
    mean: [f64; 3],
    start_step: u64,
    end_step: u64,
    /// s, the field's own step: the wind is evaluated every `every` integration steps of
    /// `step_dt` (`gust.rate`), and its steps (the window's, the filters') are of `dt`.
    dt: f64,
    step_dt: f64,
    every: u64,
    /// Scales that follow the vehicle, if any (else the filters above are the step's).
    follow: Option<Follow>,
    /// (cos chi, sin chi) of the turbulence axes; None when chi = 0 (no rotation at all).
    axes: Option<(f64, f64)>,
    /// The deterministic sources that blow, the mean air's first (`AnySource::of`).
    sources: Vec<AnySource>,
    /// How many of `sources` (the first) are the mean air's.
    mean_len: usize,
}

/// The filters' sum `w` (u, v, w) in the turned axes (cos chi, sin chi) turned to inertial
/// and `gust.mean_wind` added; unturned, `w` as it is (its sum began from the mean): the one
/// rule of the scalar field and of the lanes (`LaneGust::sample`).
#[inline(always)]
pub(super) fn turned<L: Lane>(w: [L; 3], axes: Option<(L, L)>, mean: &[L; 3]) -> [L; 3] {
    match axes {
        None => w,
        Some((c, s)) => [
            w[0] * c - w[1] * s + mean[0],
            w[0] * s + w[1] * c + mean[1],
            w[2] + mean[2],
        ],
    }
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
pub(super) struct Given<'a> {
    xi: &'a [f64],
    next: usize,
}

impl<'a> Given<'a> {
    /// The cursor at `next` in `xi`.
    pub(super) fn new(xi: &'a [f64], next: usize) -> Self {
        Given { xi, next }
    }

    /// Where the next draw will read.
    pub(super) fn next(&self) -> usize {
        self.next
    }
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

impl<'a> WindState<'a> {
    /// A copy of the realisation's source of normals as it stands (a fresh state's: the
    /// stream from its start, or the innovations from the first).
    pub fn source(&self) -> Source<'a> {
        self.rng.clone()
    }
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

/// A component's filter cannot be built for this scenario: the error names `gust`.
fn component_error(c: GustComponent, e: String) -> ConfigError {
    ConfigError::new("gust", format!("gust ({} component): {e}", c.name()))
}

impl WindField {
    /// Intensities and scale lengths ([`low_altitude_scales`], per component) and the
    /// airspeed the kept filters are built for: the fixed values, or where the scales follow
    /// the vehicle the lowest altitude (10 ft) and `gust.min_airspeed`.
    fn scales(cfg: &WindContext) -> ([f64; 3], [f64; 3], f64) {
        let g = &cfg.gust;
        let altitude = match g.altitude {
            GustAltitude::Fixed(h) => h,
            GustAltitude::Vehicle => VEHICLE_ALTITUDE_RANGE.0,
        };
        let airspeed = match g.airspeed {
            GustAirspeed::Fixed(v) => v,
            GustAirspeed::Relative => g.min_airspeed,
        };
        let (sigma, length) = low_altitude_scales(altitude, cfg.turbulence_w20());
        (sigma, length, airspeed)
    }

    /// Whether [`WindField::new`] can discretise every active component for this step, checked
    /// without building the filters (what validating a scenario runs: e.g. a `gust.altitude`
    /// so small that `airspeed * dt / length_scale` overflows is refused there, naming `gust`).
    pub fn check(cfg: &WindContext) -> Result<(), ConfigError> {
        let g = &cfg.gust;
        if !g.enabled {
            return Ok(());
        }
        let (sigma, length, airspeed) = Self::scales(cfg);
        let dt = cfg.integrator.dt * cfg.gust_every() as f64;
        for &c in &g.components {
            let i = c.index();
            GustFilter::check(g.model, sigma[i], length[i], airspeed, dt)
                .map_err(|e| component_error(c, e))?;
        }
        Ok(())
    }

    /// Compute the scales ([`low_altitude_scales`]) of a validated scenario's gust
    /// (`Config::validate` has checked every `gust` and `wind` value, once for the whole
    /// engine) and discretise the active components for the step `integrator.dt`.
    ///
    /// Step `n` (time `n dt`) is inside the window iff `start <= n dt < end`,
    /// times within 1e-9 steps of a grid point counting as on it (so a window
    /// [25, 40) s with dt = 2e-4 s is exactly steps 125000..200000).
    /// When `gust.enabled` is false there is no turbulence (the `[wind]` sources still
    /// blow). Errs (key `gust`) only if a filter cannot be discretised for this step (e.g.
    /// `airspeed * dt / length_scale` overflows). Where the scales follow the vehicle the
    /// filters kept here are those of the lowest altitude (10 ft) and airspeed
    /// `gust.min_airspeed` (or the fixed values): they fix the orders, the draws and the
    /// innovations; each step uses its own.
    pub fn new(cfg: &WindContext) -> Result<Self, ConfigError> {
        let (g, step_dt, wind) = (&cfg.gust, cfg.integrator.dt, &cfg.wind);
        let every = cfg.gust_every() as u64;
        let dt = step_dt * every as f64;
        let chi = wind.heading.to_radians();
        let sources = AnySource::of(cfg);
        let mean_len = sources.iter().take_while(|s| s.is_mean_air()).count();
        let mut field = WindField {
            enabled: false,
            filters: [None; 3],
            mean: [0.0; 3],
            start_step: 0,
            end_step: 0,
            dt,
            step_dt,
            every,
            follow: None,
            axes: None,
            sources,
            mean_len,
        };
        if !g.enabled {
            return Ok(field);
        }
        let w20 = cfg.turbulence_w20();
        let follows = g.altitude == GustAltitude::Vehicle || g.airspeed == GustAirspeed::Relative;
        let (sigma, length, airspeed) = Self::scales(cfg);
        for c in GustComponent::ALL {
            let i = c.index();
            if g.components.contains(&c) {
                let spec = GustSpec {
                    model: g.model,
                    component: c,
                    sigma: sigma[i],
                    length_scale: length[i],
                    airspeed,
                    dt,
                };
                let f = GustFilter::new(spec).map_err(|e| component_error(c, e))?;
                field.filters[i] = Some(f);
            }
        }
        field.enabled = true;
        field.mean = g.mean_wind;
        field.start_step = step_at_or_after(g.start, dt);
        field.end_step = step_at_or_after(g.end, dt);
        field.follow = follows.then_some(Follow {
            altitude: g.altitude,
            airspeed: g.airspeed,
            w20,
            min_airspeed: g.min_airspeed,
        });
        field.axes = (chi != 0.0).then_some((chi.cos(), chi.sin()));
        Ok(field)
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

    /// Turbulence only (m/s, inertial x, y, z) held over the step starting at `t = step dt`,
    /// for a vehicle at rest at z = 0: [`sample_at`](Self::sample_at) without the vehicle.
    #[inline]
    pub fn sample(&self, state: &mut WindState<'_>, step: u64) -> [f64; 3] {
        self.sample_at(state, step, || Kinematics::AT_REST)
    }

    /// The wind (m/s, inertial x, y, z) held over the step starting at `t = step dt`, the
    /// quadrotor being where `at` says (asked only if a source follows it): zero outside the
    /// gust window, when disabled, and when nothing else blows; inside, `gust.mean_wind`
    /// plus the turbulence; plus, at all times, the `[wind]` mean wind at the quadrotor's
    /// altitude and the discrete gusts at `t`.
    ///
    /// Call once per integration step in increasing step order. At the first
    /// call inside the window the filter states are drawn from their stationary
    /// distributions (as of the window's first step; components in order
    /// longitudinal, lateral, vertical, each `order()` normals), then advanced
    /// once per step (same component order). If steps are skipped the filters
    /// are advanced through them (with the scales of the step asked for, where they
    /// follow the vehicle), so with fixed scales the value at a step does not depend on
    /// which earlier steps were sampled; a repeated step returns the same value
    /// without drawing, and a step earlier than the last one inside the window
    /// is not rewound (it returns the current value). No allocation, and no
    /// random draws outside the window.
    #[inline]
    pub fn sample_at(
        &self,
        state: &mut WindState<'_>,
        step: u64,
        at: impl FnOnce() -> Kinematics,
    ) -> [f64; 3] {
        let turbulent = self.is_active(step);
        if !turbulent && !self.blows() {
            return [0.0; 3];
        }
        let kin = if self.follows_vehicle() {
            at()
        } else {
            Kinematics::AT_REST
        };
        let now = self.moment(step);
        let steady = self.mean_air(now, &kin);
        let mut w = if turbulent {
            self.turbulence(state, step, &kin, steady)
        } else {
            [0.0; 3]
        };
        if let Some(m) = steady {
            for (w, m) in w.iter_mut().zip(m) {
                *w += m;
            }
        }
        self.add_others(now, &kin, &mut w);
        w
    }

    /// The step `step` and its time `step dt`, as the sources are asked for it.
    #[inline(always)]
    fn moment(&self, step: u64) -> Moment {
        Moment {
            step,
            t: step as f64 * self.dt,
        }
    }

    /// The sources that need no random numbers (all but the turbulence) at `step`, the
    /// quadrotor at `kin`: the mean air's sum, then each other source added.
    #[inline]
    pub fn deterministic(&self, step: u64, kin: &Kinematics) -> [f64; 3] {
        let now = self.moment(step);
        let mut w = self.mean_air(now, kin).unwrap_or([0.0; 3]);
        self.add_others(now, kin, &mut w);
        w
    }

    /// The sources, in the summation order (the mean air's first).
    pub fn sources(&self) -> &[AnySource] {
        &self.sources
    }

    /// The wind of the first source of kind `name` at `step`, the quadrotor at `kin`.
    fn source_at(&self, name: &str, step: u64, kin: &Kinematics) -> Option<[f64; 3]> {
        let s = self.sources.iter().find(|s| s.name() == name)?;
        Some(s.at(self.moment(step), kin))
    }

    /// The `[wind]` mean wind (m/s, inertial) at altitude `h` (m): W20 f(h) (cos chi, sin chi,
    /// 0); zero when `wind.speed` is 0.
    pub fn mean_at(&self, h: f64) -> [f64; 3] {
        let kin = Kinematics {
            z: h,
            vel: [0.0; 3],
        };
        self.source_at("steady", 0, &kin).unwrap_or([0.0; 3])
    }

    /// The sum of the discrete gusts (m/s, inertial) at the step starting at `step dt`.
    pub fn discrete_gusts(&self, step: u64) -> [f64; 3] {
        self.source_at("gusts", step, &Kinematics::AT_REST)
            .unwrap_or([0.0; 3])
    }

    /// The mean air the turbulence rides on at the step `now` with the quadrotor at `kin`: the
    /// mean air's sources summed in order (the `[wind]` mean wind plus the `[wind.table]`'s
    /// wind; None where none blows).
    #[inline]
    fn mean_air(&self, now: Moment, kin: &Kinematics) -> Option<[f64; 3]> {
        let mut sum: Option<[f64; 3]> = None;
        for s in &self.sources[..self.mean_len] {
            let w = s.at(now, kin);
            sum = Some(match sum {
                None => w,
                Some(m) => [m[0] + w[0], m[1] + w[1], m[2] + w[2]],
            });
        }
        sum
    }

    /// The sources after the mean air's (the discrete gusts, a prescribed wind), each added to
    /// `w` in order.
    #[inline]
    fn add_others(&self, now: Moment, kin: &Kinematics, w: &mut [f64; 3]) {
        for s in &self.sources[self.mean_len..] {
            let g = s.at(now, kin);
            for (w, g) in w.iter_mut().zip(g) {
                *w += g;
            }
        }
    }

    /// The other source `j` (after the mean air's: `others()[j]`) at `step`, the quadrotor at
    /// `kin` if a source of the field reads it (else at rest): its term of `sample_at`.
    #[inline]
    pub(super) fn other_at(&self, j: usize, step: u64, kin: &Kinematics) -> [f64; 3] {
        let kin = if self.follows_vehicle() {
            *kin
        } else {
            Kinematics::AT_REST
        };
        self.sources[self.mean_len + j].at(self.moment(step), &kin)
    }

    /// The `[wind.table]`'s wind (m/s, inertial) at the step `step` with the quadrotor at
    /// altitude `z`, if the scenario has a table.
    pub fn table_at(&self, step: u64, z: f64) -> Option<[f64; 3]> {
        let kin = Kinematics { z, vel: [0.0; 3] };
        self.source_at("table", step, &kin)
    }

    /// Whether something blows outside the gust window (a deterministic source: a mean wind,
    /// a discrete gust, a wind table, a prescribed wind): then the wind is sampled at every
    /// step.
    #[inline]
    pub fn blows(&self) -> bool {
        !self.sources.is_empty()
    }

    /// Whether a source reads the quadrotor's altitude or velocity.
    #[inline]
    pub fn follows_vehicle(&self) -> bool {
        self.follow.is_some() || self.sources.iter().any(AnySource::reads_vehicle)
    }

    /// This field with the wind `rows` (m/s, inertial; row k held over step k) prescribed
    /// instead of the turbulence, added last to the other sources (`Engine::with_wind`).
    pub fn prescribed(mut self, rows: Vec<[f64; 3]>) -> Self {
        self.enabled = false;
        self.follow = None;
        // A row per integration step: the field is evaluated at every step.
        self.dt = self.step_dt;
        self.every = 1;
        self.sources
            .push(AnySource::Prescribed(Prescribed(rows.into())));
        self
    }

    /// The turbulence of a step inside the window, `gust.mean_wind` included, inertial.
    #[inline(always)]
    fn turbulence(
        &self,
        state: &mut WindState<'_>,
        step: u64,
        kin: &Kinematics,
        steady: Option<[f64; 3]>,
    ) -> [f64; 3] {
        let rescaled;
        let filters = match &self.follow {
            None => &self.filters,
            Some(f) => {
                rescaled = self.rescale(f, kin, steady.unwrap_or([0.0; 3]));
                &rescaled
            }
        };
        // With the axes turned, the filters' (u, v, w) are summed from zero and turned, then
        // gust.mean_wind (inertial) is added; unturned, exactly the section-4 sum.
        let base = if self.axes.is_some() {
            [0.0; 3]
        } else {
            self.mean
        };
        // One match per sample, not per normal: the draws below run on the concrete source.
        let WindState {
            rng,
            x,
            started,
            step: at,
        } = state;
        let w = match rng {
            Source::Seeded(rng) => self.advance_to(filters, base, x, started, at, step, rng),
            Source::Given { xi, next } => {
                let mut given = Given { xi, next: *next };
                let w = self.advance_to(filters, base, x, started, at, step, &mut given);
                *next = given.next;
                w
            }
        };
        turned(w, self.axes, &self.mean)
    }

    /// The step's filters where the scales follow the vehicle: sigma and L from its altitude
    /// (clamped to [10 ft, 1000 ft]) or the fixed one, V = max(|v - mean(h)|, min_airspeed)
    /// or the fixed one. A scale no filter can take (a runaway state) gives NaN filters, so
    /// the wind is NaN and the flight ends as non-finite.
    #[inline]
    fn rescale(&self, f: &Follow, kin: &Kinematics, mean: [f64; 3]) -> [Option<GustFilter>; 3] {
        let (sigma, length, v) = Self::follow_scales(f, kin, mean);
        let mut out = self.filters;
        for (i, slot) in out.iter_mut().enumerate() {
            if let Some(base) = slot {
                *slot = Some(base.rescaled_following(sigma[i], length[i], v));
            }
        }
        out
    }

    /// `rescale`'s scales: (sigma, L) per component ([`low_altitude_scales_lanes`] of
    /// `follow_inputs`' altitude) and V.
    #[inline]
    fn follow_scales(f: &Follow, kin: &Kinematics, mean: [f64; 3]) -> ([f64; 3], [f64; 3], f64) {
        let (h, w20, v) = Self::follow_inputs(f, kin, mean);
        let (sigma, length) = low_altitude_scales_lanes(h, w20);
        (sigma, length, v)
    }

    /// What the step's scales are computed from: the altitude, W20 and the airspeed V.
    #[inline(always)]
    fn follow_inputs(f: &Follow, kin: &Kinematics, mean: [f64; 3]) -> (f64, f64, f64) {
        let (lo, hi) = VEHICLE_ALTITUDE_RANGE;
        let h = match f.altitude {
            GustAltitude::Fixed(h) => h,
            GustAltitude::Vehicle => kin.z.clamp(lo, hi),
        };
        let v = match f.airspeed {
            GustAirspeed::Fixed(v) => v,
            GustAirspeed::Relative => {
                let r: [f64; 3] = std::array::from_fn(|i| kin.vel[i] - mean[i]);
                (r[0] * r[0] + r[1] * r[1] + r[2] * r[2])
                    .sqrt()
                    .max(f.min_airspeed)
            }
        };
        (h, f.w20, v)
    }

    /// [`follow_inputs`](Self::follow_inputs) of every lane at once, the lanes' `Follow`s in
    /// lane values; `None` where a lane's turbulence does not follow the vehicle.
    pub(super) fn follow_lanes<L: KernelOps>(fields: &[&WindField]) -> Option<FollowLanes<L>> {
        let follows: Option<Vec<&Follow>> = fields.iter().map(|f| f.follow.as_ref()).collect();
        let f = follows?;
        let mask = |yes: &dyn Fn(&Follow) -> bool| {
            L::from_fn(|l| if yes(f[l]) { f64::from_bits(!0) } else { 0.0 })
        };
        let fixed_altitude = |f: &Follow| match f.altitude {
            GustAltitude::Fixed(h) => h,
            GustAltitude::Vehicle => 0.0,
        };
        let fixed_airspeed = |f: &Follow| match f.airspeed {
            GustAirspeed::Fixed(v) => v,
            GustAirspeed::Relative => 0.0,
        };
        Some(FollowLanes {
            vehicle_altitude: mask(&|f| f.altitude == GustAltitude::Vehicle),
            fixed_altitude: L::from_fn(|l| fixed_altitude(f[l])),
            relative_airspeed: mask(&|f| f.airspeed == GustAirspeed::Relative),
            fixed_airspeed: L::from_fn(|l| fixed_airspeed(f[l])),
            min_airspeed: L::from_fn(|l| f[l].min_airspeed),
            w20: L::from_fn(|l| f[l].w20),
        })
    }

    /// [`sample_at`](Self::sample_at)'s work that reads the quadrotor, for the lane-set path
    /// ([`super::lanes::LaneWind`]) to do per lane: the `[wind]` mean wind at the quadrotor
    /// (`None` where it does not blow) and, when `scales` is asked and the turbulence follows
    /// the vehicle, what the step's scales come from (`follow_inputs`: altitude, W20, V), from
    /// which the lane-set computes the scales and the filters' numbers (`rescale`'s, bit for
    /// bit).
    #[inline(always)]
    #[allow(clippy::type_complexity)]
    pub(super) fn at_vehicle(
        &self,
        step: u64,
        kin: &Kinematics,
        scales: bool,
    ) -> (Option<[f64; 3]>, Option<(f64, f64, f64)>) {
        let kin = if self.follows_vehicle() {
            *kin
        } else {
            Kinematics::AT_REST
        };
        let steady = self.mean_air(self.moment(step), &kin);
        let scales = match (scales, &self.follow) {
            (true, Some(f)) => Some(Self::follow_inputs(f, &kin, steady.unwrap_or([0.0; 3]))),
            _ => None,
        };
        (steady, scales)
    }

    /// [`at_vehicle`](Self::at_vehicle)'s scales' inputs with the mean air given (`mean`, the
    /// lane-set's lane-valued `[wind]` mean wind): `follow_inputs` at the quadrotor where the
    /// field follows it (else at rest); `None` where the turbulence's scales do not follow.
    #[inline(always)]
    pub(super) fn follow_at(&self, kin: &Kinematics, mean: [f64; 3]) -> Option<(f64, f64, f64)> {
        let kin = if self.follows_vehicle() {
            *kin
        } else {
            Kinematics::AT_REST
        };
        let f = self.follow.as_ref()?;
        Some(Self::follow_inputs(f, &kin, mean))
    }

    /// The mean air's sources (the `[wind]` mean wind, a `[wind.table]`), in summation order.
    pub(super) fn mean_sources(&self) -> &[AnySource] {
        &self.sources[..self.mean_len]
    }

    /// Whether the turbulence's scales follow the vehicle (`gust.altitude = "vehicle"` or
    /// `gust.airspeed = "relative"`).
    pub(super) fn turbulence_follows(&self) -> bool {
        self.follow.is_some()
    }

    /// Whether a mean air blows (the `[wind]` mean wind or a `[wind.table]`).
    pub(super) fn has_steady(&self) -> bool {
        self.mean_len > 0
    }

    /// The sources after the mean air's (the discrete gusts, a prescribed wind).
    pub(super) fn others(&self) -> &[AnySource] {
        &self.sources[self.mean_len..]
    }

    /// `sample`'s work on a concrete source of normals.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn advance_to(
        &self,
        filters: &[Option<GustFilter>; 3],
        base: [f64; 3],
        x: &mut [[f64; 3]; 3],
        started: &mut bool,
        at: &mut u64,
        step: u64,
        normals: &mut impl Normals,
    ) -> [f64; 3] {
        if !*started {
            for (i, f) in filters.iter().enumerate() {
                if let Some(f) = f {
                    x[i] = f.stationary_state(normals);
                }
            }
            *started = true;
            *at = self.start_step;
        }
        while *at < step {
            for (i, f) in filters.iter().enumerate() {
                if let Some(f) = f {
                    f.advance(&mut x[i], normals);
                }
            }
            *at += 1;
        }
        let mut w = base;
        for (i, f) in filters.iter().enumerate() {
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
    /// step flown (step `steps - 1`: the closing row holds that step's wind and draws nothing).
    /// Zero when the gust is off.
    pub fn innovations(&self, steps: usize) -> usize {
        if !self.enabled {
            return 0;
        }
        let per_step: usize = self.filters.iter().flatten().map(|f| f.order()).sum();
        let last_flown = (steps as u64).max(1) - 1;
        let last = last_flown.min(self.end_step.saturating_sub(1));
        let sampled = (last + 1).saturating_sub(self.start_step) as usize;
        per_step * sampled
    }

    /// The innovations realisation `index` of `seed` draws in a flight of `steps` steps:
    /// `given` with them flies exactly the seeded flight.
    pub fn innovations_of(&self, seed: u64, index: u64, steps: usize) -> Vec<f64> {
        let mut rng = realisation_rng(seed, index);
        (0..self.innovations(steps)).map(|_| rng.normal()).collect()
    }

    /// Whether the turbulence is on at all.
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

    /// The filters of (longitudinal, lateral, vertical), the active ones only.
    pub(super) fn filters(&self) -> &[Option<GustFilter>; 3] {
        &self.filters
    }

    /// (cos chi, sin chi) of the turbulence axes; None when they are not turned.
    pub(super) fn axes(&self) -> Option<(f64, f64)> {
        self.axes
    }

    /// The filter of a component, if active.
    pub fn filter(&self, component: GustComponent) -> Option<&GustFilter> {
        self.filters[component.index()].as_ref()
    }

    /// Mean wind added inside the window (zero when disabled).
    pub fn mean_wind(&self) -> [f64; 3] {
        self.mean
    }

    /// s, the field's step: the period its filters were discretised for (`gust.rate`'s, or
    /// the integration step).
    pub fn dt(&self) -> f64 {
        self.dt
    }

    /// Integration steps per field step (`gust.rate`; 1: every step).
    pub fn every(&self) -> u64 {
        self.every
    }

    /// The field steps a flight of `steps` integration steps samples: every one at every
    /// step; at a rate, each update's and, for the linear interpolation, the next (the
    /// update after the last step flown).
    pub fn field_steps(&self, steps: usize) -> usize {
        match self.every {
            1 => steps,
            n => (steps.max(1) - 1) / n as usize + 2,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::filter::tests::{filt, KS, MODELS};
    use super::*;
    use crate::config::GustModel;
    use crate::scenario::Config;

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
    fn check_refuses_what_new_cannot_build_and_builds_nothing() {
        let mut cfg = crate::scenario::tests::paper();
        cfg.gust.enabled = true;
        cfg.validate().unwrap();
        assert!(
            WindField::check(&cfg.wind_context()).is_ok()
                && WindField::new(&cfg.wind_context()).is_ok()
        );
        // An altitude so small that the step in scale lengths overflows: refused by both,
        // with the same key and message.
        cfg.gust.altitude = crate::config::GustAltitude::Fixed(5e-324);
        cfg.validate().unwrap();
        let checked = WindField::check(&cfg.wind_context()).unwrap_err();
        let Err(built) = WindField::new(&cfg.wind_context()) else {
            panic!("new built a filter check refuses");
        };
        assert_eq!(
            (checked.key.as_str(), &checked.message),
            ("gust", &built.message)
        );
        assert!(
            checked.message.contains("airspeed * dt / length_scale"),
            "{checked:?}"
        );
        // Turbulence off: nothing to discretise.
        cfg.gust.enabled = false;
        assert!(WindField::check(&cfg.wind_context()).is_ok());
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
        let mut cfg = crate::scenario::tests::paper();
        cfg.gust.enabled = true;
        cfg.gust.model = GustModel::Dryden;
        cfg.gust.components = vec![GustComponent::Vertical];
        cfg.gust.altitude = GustAltitude::Fixed(2.0);
        cfg.gust.w20 = Some(10.0);
        cfg.gust.airspeed = GustAirspeed::Fixed(10.0);
        cfg.gust.mean_wind = [0.0; 3];
        cfg.gust.start = 1.0;
        cfg.gust.end = 2.0;
        cfg
    }

    /// `s`'s wind field for the step `dt`.
    fn field(s: &Config, dt: f64) -> WindField {
        let mut cfg = s.clone();
        cfg.integrator.dt = dt;
        WindField::new(&cfg.wind_context()).unwrap()
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
        s.gust.airspeed = GustAirspeed::Fixed(0.0);
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
        s.gust.altitude = GustAltitude::Fixed(1e300);
        s.gust.airspeed = GustAirspeed::Fixed(1e-300);
        assert!(s.validate().is_ok());
        let e = WindField::new(&s.wind_context()).unwrap_err();
        assert_eq!(e.key, "gust");
        assert!(
            e.message
                .starts_with("gust (vertical component): airspeed * dt / length_scale"),
            "{e}"
        );
    }

    // ---- Wind over the whole flight ----------------------------------------------------

    use crate::scenario::{Intensity, Shear};

    /// A field of `spec()` with all three components, the window open from step 0 on, and
    /// `edit` applied.
    fn whole(dt: f64, edit: impl Fn(&mut Config)) -> WindField {
        let mut s = spec();
        s.gust.components = GustComponent::ALL.to_vec();
        s.gust.start = 0.0;
        s.gust.end = 1e6;
        edit(&mut s);
        s.validate().unwrap();
        field(&s, dt)
    }

    fn at(z: f64, vel: [f64; 3]) -> impl Fn() -> Kinematics {
        move || Kinematics { z, vel }
    }

    /// The same wind to rounding: a filter re-discretised every step (the lane-valued
    /// functions) and one built once for the same scales (libm's) differ in the last bits of
    /// their numbers, so their outputs by about 1e-15 m/s.
    fn assert_same_wind(a: [f64; 3], b: [f64; 3], what: &str) {
        for i in 0..3 {
            let tol = 1e-13 * b[i].abs().max(1.0);
            assert!((a[i] - b[i]).abs() <= tol, "{what}: {a:?} vs {b:?}");
        }
    }

    #[test]
    fn log_shear_gives_w20_at_20_ft_and_nothing_at_or_below_z0() {
        for z0 in [0.0457, 0.61, 2.0] {
            let f = whole(0.01, |c| {
                c.gust.enabled = false;
                c.wind.speed = 7.5;
                c.wind.shear = Shear::Log;
                c.wind.roughness = z0;
            });
            assert_eq!(f.mean_at(6.096), [7.5, 0.0, 0.0], "z0 = {z0}");
            assert_eq!(f.mean_at(z0), [0.0; 3]);
            assert_eq!(f.mean_at(0.5 * z0), [0.0; 3]);
            assert_eq!(f.mean_at(-3.0), [0.0; 3]);
            // Between: the formula, by hand; above 20 ft it keeps growing.
            let h = 2.5;
            let want = 7.5 * (h / z0).ln() / (6.096 / z0).ln();
            assert!((f.mean_at(h)[0] - want).abs() < 1e-14);
            assert!(f.mean_at(60.0)[0] > 7.5);
        }
        // No shear: W20 at every height.
        let f = whole(0.01, |c| c.wind.speed = 3.0);
        for h in [-1.0, 0.0, 1.0, 100.0] {
            assert_eq!(f.mean_at(h), [3.0, 0.0, 0.0]);
        }
    }

    #[test]
    fn heading_turns_the_mean_wind_and_the_turbulence_axes() {
        let dt = 0.01;
        let chi = 120.0_f64;
        let (c, s) = (chi.to_radians().cos(), chi.to_radians().sin());
        let mean = whole(dt, |g| {
            g.gust.enabled = false;
            g.wind.speed = 4.0;
            g.wind.heading = chi;
        });
        let m = mean.mean_at(1.0);
        assert_eq!(m, [4.0 * c, 4.0 * s, 0.0]);
        assert!((m[0] + 2.0).abs() < 1e-12 && (m[1] - 12f64.sqrt()).abs() < 1e-12);
        // Turbulence: the heading-0 field's (u, v, w), turned; gust.mean_wind not turned.
        let edit = |g: &mut Config| g.gust.mean_wind = [0.3, -0.2, 0.1];
        let plain = whole(dt, edit);
        let turned = whole(dt, |g| {
            edit(g);
            g.wind.heading = chi;
        });
        let (mut a, mut b) = (plain.realisation(4, 1), turned.realisation(4, 1));
        for n in 0..300 {
            let u = plain.sample(&mut a, n);
            let w = turned.sample(&mut b, n);
            let (du, dv) = (u[0] - 0.3, u[1] + 0.2);
            let want = [du * c - dv * s + 0.3, du * s + dv * c - 0.2, u[2]];
            for i in 0..3 {
                assert!(
                    (w[i] - want[i]).abs() < 1e-14,
                    "step {n}: {w:?} vs {want:?}"
                );
            }
        }
        // Heading 0 is section 4 exactly.
        let zero = whole(dt, |g| {
            edit(g);
            g.wind.heading = 0.0;
        });
        let (mut a, mut b) = (plain.realisation(4, 1), zero.realisation(4, 1));
        for n in 0..50 {
            assert_eq!(plain.sample(&mut a, n), zero.sample(&mut b, n));
        }
    }

    /// A table is interpolated linearly between its rows and held at its end rows' values
    /// outside them; a constant table blows exactly the `[wind]` mean wind it copies, through
    /// the turbulence too (the relative airspeed is through the same mean air).
    #[test]
    fn a_wind_table_interpolates_holds_and_adds_like_a_mean_wind() {
        use crate::gust::table::table_wind;
        use crate::scenario::{TableBy, WindTable};
        let points = [
            [0.0, 1.0, 0.0, -1.0],
            [10.0, 3.0, 2.0, 1.0],
            [20.0, 3.0, -2.0, 0.0],
        ];
        assert_eq!(table_wind(&points, -5.0), [1.0, 0.0, -1.0]);
        assert_eq!(table_wind(&points, 0.0), [1.0, 0.0, -1.0]);
        assert_eq!(table_wind(&points, 2.5), [1.5, 0.5, -0.5]);
        assert_eq!(table_wind(&points, 10.0), [3.0, 2.0, 1.0]);
        assert_eq!(table_wind(&points, 15.0), [3.0, 0.0, 0.5]);
        assert_eq!(table_wind(&points, 25.0), [3.0, -2.0, 0.0]);
        assert!(table_wind(&points, f64::NAN).iter().all(|w| w.is_nan()));
        assert_eq!(table_wind(&points[..1], 7.0), [1.0, 0.0, -1.0]);

        let windy = |c: &mut Config| {
            c.gust.components = GustComponent::ALL.to_vec();
            c.gust.altitude = GustAltitude::Vehicle;
            c.gust.airspeed = GustAirspeed::Relative;
        };
        let mean = whole(0.01, |c| {
            windy(c);
            c.wind.speed = 4.0;
            c.wind.heading = 30.0;
        });
        let m = mean.mean_at(0.0);
        for by in [TableBy::Time, TableBy::Altitude] {
            let table = whole(0.01, |c| {
                windy(c);
                c.wind.heading = 30.0;
                c.wind.table = Some(WindTable {
                    by,
                    points: vec![[3.0, m[0], m[1], m[2]], [9.0, m[0], m[1], m[2]]],
                });
            });
            assert!(table.blows() && table.follows_vehicle());
            let (mut a, mut b) = (mean.realisation(1, 2), table.realisation(1, 2));
            for step in 0..400 {
                let kin = at(0.02 * step as f64, [2.0, -1.0, 0.3]);
                let (x, y) = (
                    mean.sample_at(&mut a, step, &kin),
                    table.sample_at(&mut b, step, &kin),
                );
                assert_eq!(
                    x.map(f64::to_bits),
                    y.map(f64::to_bits),
                    "{by:?} step {step}"
                );
                let d = table.deterministic(step, &kin());
                assert_eq!(d.map(f64::to_bits), m.map(f64::to_bits));
            }
        }
        // By altitude, at the quadrotor's height; by time, at the step's time; added to the
        // `[wind]` mean wind.
        let both = whole(0.5, |c| {
            c.gust.enabled = false;
            c.wind.speed = 2.0;
            c.wind.table = Some(WindTable {
                by: TableBy::Altitude,
                points: points.to_vec(),
            });
        });
        let mut st = both.realisation(0, 0);
        let w = both.sample_at(&mut st, 3, at(15.0, [0.0; 3]));
        assert_eq!(w, [5.0, 0.0, 0.5]);
        let timed = whole(0.5, |c| {
            c.gust.enabled = false;
            c.wind.table = Some(WindTable {
                by: TableBy::Time,
                points: points.to_vec(),
            });
        });
        assert!(!timed.follows_vehicle());
        let mut st = timed.realisation(0, 0);
        assert_eq!(
            timed.sample_at(&mut st, 5, at(99.0, [0.0; 3])),
            [1.5, 0.5, -0.5]
        );
    }

    #[test]
    fn wind_table_rows_are_checked_naming_the_row() {
        use crate::scenario::{TableBy, WindTable};
        let mut c = crate::scenario::tests::paper();
        c.wind.table = Some(WindTable {
            by: TableBy::Time,
            points: vec![[0.0, 1.0, 0.0, 0.0], [0.0, 2.0, 0.0, 0.0]],
        });
        let e = c.validate().unwrap_err();
        assert_eq!(e.key, "wind.table.points[1][0]");
        assert!(e.message.contains("increasing time"), "{e}");
        c.wind.table = Some(WindTable {
            by: TableBy::Altitude,
            points: vec![[0.0, f64::NAN, 0.0, 0.0]],
        });
        assert_eq!(c.validate().unwrap_err().key, "wind.table.points[0][1]");
        c.wind.table = Some(WindTable {
            by: TableBy::Altitude,
            points: vec![],
        });
        assert_eq!(c.validate().unwrap_err().key, "wind.table.points");
        c.wind.table = Some(WindTable {
            by: TableBy::Altitude,
            points: vec![[0.0, 1.0, 0.0, 0.0], [10.0, 2.0, 0.0, 0.0]],
        });
        c.validate().expect("a table by altitude");
        let path = c.per_realisation_key("wind.table.points[1][2]").unwrap();
        assert!(c.set_number(&path, 0.5));
        crate::scenario::tests::assert_refused(
            &c,
            &[
                ("wind.table.by", "not a number"),
                ("wind.table.points[1]", "not a number"),
                ("wind.table.points[2][0]", "not a key"),
                ("wind.table.points[1][4]", "not a key"),
            ],
        );
    }

    #[test]
    fn discrete_gust_shapes_reach_a_and_return_to_zero() {
        use crate::gust::gusts::discrete_gust;
        use crate::scenario::{DiscreteGust, GustShape};
        let a = [1.5, -2.0, 0.75];
        for (start, d) in [(2.0, 3.0), (0.0, 0.7), (1.1, 1e-3)] {
            let ramp = DiscreteGust {
                start,
                duration: d,
                amplitude: a,
                shape: GustShape::Ramp,
            };
            let pulse = DiscreteGust {
                shape: GustShape::Pulse,
                ..ramp.clone()
            };
            for g in [&ramp, &pulse] {
                assert_eq!(discrete_gust(g, start - 1e-9), [0.0; 3]);
                assert_eq!(discrete_gust(g, start), [0.0; 3]);
            }
            assert_eq!(discrete_gust(&ramp, start + d), a);
            assert_eq!(discrete_gust(&ramp, start + 10.0 * d), a);
            assert_eq!(discrete_gust(&pulse, start + d), [0.0; 3]);
            assert_eq!(discrete_gust(&pulse, start + 10.0 * d), [0.0; 3]);
            let half_ramp = discrete_gust(&ramp, start + 0.5 * d);
            let peak = discrete_gust(&pulse, start + 0.5 * d);
            for i in 0..3 {
                assert!((half_ramp[i] - 0.5 * a[i]).abs() < 1e-12);
                assert!((peak[i] - a[i]).abs() < 1e-12);
            }
        }
        // In the field: inertial (not turned by the heading), at every step, whatever
        // gust.enabled; t = step dt.
        let f = whole(0.1, |c| {
            c.gust.enabled = false;
            c.wind.heading = 45.0;
            c.wind.gusts = vec![
                DiscreteGust {
                    start: 1.0,
                    duration: 2.0,
                    amplitude: a,
                    shape: GustShape::Ramp,
                },
                DiscreteGust {
                    start: 0.5,
                    duration: 1.0,
                    amplitude: [0.0, 0.0, 3.0],
                    shape: GustShape::Pulse,
                },
            ];
        });
        assert!(f.blows() && !f.enabled());
        let mut st = f.realisation(0, 0);
        assert_eq!(f.sample(&mut st, 0), [0.0; 3]);
        assert_eq!(f.sample(&mut st, 30), a);
        let mid = f.sample(&mut st, 10);
        assert!((mid[2] - 3.0).abs() < 1e-15 && mid[0] == 0.0);
    }

    /// Per-row estimates of E[w_i(t) w_i(t + lag)] / their standard error, for a component of
    /// `rows` realisations of `steps` steps flown at the altitude `z` held.
    fn held_moments(
        f: &WindField,
        z: f64,
        rows: usize,
        steps: usize,
        lag: usize,
    ) -> [(f64, f64); 3] {
        let mut series: [Vec<f64>; 3] = std::array::from_fn(|_| Vec::with_capacity(rows * steps));
        for r in 0..rows {
            let mut st = f.realisation(77, r as u64);
            for n in 0..steps as u64 {
                let w = f.sample_at(&mut st, n, at(z, [0.0; 3]));
                for i in 0..3 {
                    series[i].push(w[i]);
                }
            }
        }
        std::array::from_fn(|i| lag_moment(&series[i], rows, steps, lag))
    }

    #[test]
    fn turbulence_follows_the_vehicle_altitude() {
        // The formulas, written here from MIL-F-8785C (h in feet), not through the engine.
        let sigmas = |h_m: f64, w20: f64| {
            let h = h_m / 0.3048;
            let sw = 0.1 * w20;
            let su = sw / (0.177 + 0.000823 * h).powf(0.4);
            let lu = h / (0.177 + 0.000823 * h).powf(1.2) * 0.3048;
            ([su, su, sw], [lu, lu, h_m])
        };
        // A long step (the discretisation is exact at any step): many scale lengths per row.
        let (dt, v) = (0.5, 12.0);
        let f = whole(dt, |c| {
            c.gust.altitude = GustAltitude::Vehicle;
            c.gust.airspeed = GustAirspeed::Fixed(v);
            c.gust.w20 = None;
            c.gust.intensity = Some(Intensity::Moderate);
        });
        let w20 = 30.0 * 1852.0 / 3600.0;
        for h in [15.0, 150.0] {
            let (sigma, length) = sigmas(h, w20);
            let var = held_moments(&f, h, 300, 1000, 0);
            let lag = 2;
            let cov = held_moments(&f, h, 300, 1000, lag);
            for i in 0..3 {
                let (m, se) = var[i];
                let want = sigma[i] * sigma[i];
                assert!(
                    (m - want).abs() < 4.5 * se,
                    "h {h} component {i}: {m} vs {want} ({se})"
                );
                assert!(
                    se < 0.03 * want,
                    "h {h} component {i}: se {se} too large to see"
                );
                // The autocorrelation of that altitude's L.
                let u = v * lag as f64 * dt / length[i];
                let rho = if i == 0 {
                    (-u).exp()
                } else {
                    (-u).exp() * (1.0 - u / 2.0)
                };
                let (m, se) = cov[i];
                assert!(
                    (m - want * rho).abs() < 4.5 * se,
                    "h {h} component {i} lag {lag}: {m} vs {} ({se})",
                    want * rho
                );
            }
        }
        // Below 10 ft and above 1000 ft the altitude is clamped: the same numbers as there.
        for (z, clamp) in [(0.5, 10.0 * 0.3048), (-4.0, 10.0 * 0.3048), (900.0, 304.8)] {
            let fixed = whole(dt, |c| {
                c.gust.altitude = GustAltitude::Fixed(clamp);
                c.gust.airspeed = GustAirspeed::Fixed(v);
                c.gust.w20 = Some(w20);
            });
            let (mut a, mut b) = (f.realisation(2, 3), fixed.realisation(2, 3));
            for n in 0..200 {
                assert_same_wind(
                    f.sample_at(&mut a, n, at(z, [0.0; 3])),
                    fixed.sample(&mut b, n),
                    &format!("h {z} step {n}"),
                );
            }
        }
    }

    #[test]
    fn an_altitude_held_flies_the_fixed_altitude() {
        for model in MODELS {
            let vehicle = whole(0.01, |c| {
                c.gust.model = model;
                c.gust.altitude = GustAltitude::Vehicle;
            });
            let fixed = whole(0.01, |c| {
                c.gust.model = model;
                c.gust.altitude = GustAltitude::Fixed(37.0);
            });
            let (mut a, mut b) = (vehicle.realisation(9, 9), fixed.realisation(9, 9));
            for n in 0..300 {
                let w = vehicle.sample_at(&mut a, n, at(37.0, [1.0, 2.0, 3.0]));
                let what = format!("{model:?} step {n}");
                assert_same_wind(w, fixed.sample(&mut b, n), &what);
            }
        }
    }

    #[test]
    fn a_climb_changes_the_variance_only_as_sigma_does() {
        // An ensemble climbing from 5 m to 250 m, with a jump of the altitude at step 60: at
        // every step the ensemble variance is that step's sigma^2, before, at and after the
        // jump (the normalised state keeps unit covariance).
        let (dt, rows, steps) = (0.02, 4000, 120);
        let f = whole(dt, |c| c.gust.altitude = GustAltitude::Vehicle);
        let z = |n: u64| {
            if n < 60 {
                5.0 + 0.2 * n as f64
            } else {
                250.0 - 0.5 * (n - 60) as f64
            }
        };
        let mut w = vec![[0.0; 3]; rows * steps];
        for r in 0..rows {
            let mut st = f.realisation(5, r as u64);
            for n in 0..steps {
                w[r * steps + n] = f.sample_at(&mut st, n as u64, at(z(n as u64), [0.0; 3]));
            }
        }
        for n in [0usize, 30, 59, 60, 61, 62, 90, 119] {
            let (sigma, _) = low_altitude_scales(z(n as u64), 10.0);
            for i in 0..3 {
                // Normalised by that step's sigma: unit variance, standard error sqrt(2/rows).
                let x: Vec<f64> = (0..rows).map(|r| w[r * steps + n][i] / sigma[i]).collect();
                let var = x.iter().map(|v| v * v).sum::<f64>() / rows as f64;
                let se = (2.0 / rows as f64).sqrt();
                assert!(
                    (var - 1.0).abs() < 4.5 * se,
                    "step {n} component {i}: {var}"
                );
            }
        }
    }

    #[test]
    fn relative_airspeed_is_the_speed_through_the_mean_air() {
        let edit = |c: &mut Config| {
            c.wind.speed = 5.0;
            c.wind.heading = 90.0;
        };
        let relative = whole(0.01, |c| {
            edit(c);
            c.gust.airspeed = GustAirspeed::Relative;
            c.gust.min_airspeed = 0.5;
        });
        // mean = (5 cos 90deg, 5, 0): v - mean = (3, 4, 12) up to cos 90deg's rounding.
        let mean = relative.mean_at(2.0);
        let vel = [3.0 + mean[0], 4.0 + mean[1], 12.0];
        let v = {
            let r = [vel[0] - mean[0], vel[1] - mean[1], vel[2]];
            (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]).sqrt()
        };
        assert!((v - 13.0).abs() < 1e-14);
        for (vel, airspeed) in [(vel, v), (mean, 0.5)] {
            let fixed = whole(0.01, |c| {
                edit(c);
                c.gust.airspeed = GustAirspeed::Fixed(airspeed);
            });
            let (mut a, mut b) = (relative.realisation(3, 0), fixed.realisation(3, 0));
            for n in 0..200 {
                assert_same_wind(
                    relative.sample_at(&mut a, n, at(2.0, vel)),
                    fixed.sample(&mut b, n),
                    &format!("V {airspeed} step {n}"),
                );
            }
        }
    }

    #[test]
    fn innovations_drive_the_vehicle_following_field_like_its_seed() {
        let f = whole(0.01, |c| {
            c.gust.altitude = GustAltitude::Vehicle;
            c.gust.airspeed = GustAirspeed::Relative;
            c.wind.speed = 3.0;
            c.wind.shear = Shear::Log;
        });
        let steps = 400;
        let xi = f.innovations_of(8, 2, steps);
        let (mut a, mut b) = (f.realisation(8, 2), f.given(&xi));
        // Steps 0..steps are flown; the closing row draws nothing (`innovations`).
        for n in 0..steps as u64 {
            let z = 1.0 + 0.1 * n as f64;
            let k = at(z, [0.3, -0.1, 0.5]);
            assert_eq!(f.sample_at(&mut a, n, &k), f.sample_at(&mut b, n, &k));
        }
    }
}
