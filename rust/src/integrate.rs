//! The flight loop: classical RK4 with controls and wind sampled at the start of each step and
//! held over its four stages (a digital controller at 1/dt Hz), metrics taken online. The loop
//! knows no model's details: the vehicle (`model::Vehicle`) gives the derivative and the
//! payload's outputs, the layout gives the state names and runaway bounds.

use crate::config::{Config, ConfigError};
use crate::control::{Control, ControllerKind, Pd, Smc};
use crate::gust::{Kinematics, LaneWind, WindField, WindState};
use crate::lane::isa::Isa;
use crate::lane::{F64x4, KernelOps, Lane};
#[cfg(target_arch = "x86_64")]
use crate::lane::{F64x4Avx, F64x4Fma, F64x8Avx512, F64x8Fma512};
use crate::metrics::{PhaseAccumulator, Sample, N_METRICS};
use crate::model::{
    dispatch, ix, state_from_fn, state_vars, Actuator, ActuatorKind, ActuatorModel, Bound, Inputs,
    Parts, Payload, PayloadKind, State, StateVar, Trig, Vehicle, VehicleVisitor,
};
use crate::trajectory::{phase_steps, PhaseSteps, Reference, Trajectory, TIME_SLACK};
use rustfft::FftPlanner;
use std::marker::PhantomData;
use std::sync::atomic::{AtomicBool, Ordering};

/// One RK4 step of the vehicle with the actuator command and wind held; `trig` are the sines
/// and cosines of `s`'s angles (the controller needed them too). The later stages get theirs
/// from these by angle addition (`Trig::advanced`).
#[inline(always)]
pub fn rk4_step<L: KernelOps, Pay, Act, const N: usize>(
    vehicle: &Vehicle<L, Pay, Act>,
    s: &State<L, N>,
    trig: &Trig<L>,
    cmd: &Act::Command,
    w: &[L; 3],
    dt: f64,
) -> State<L, N>
where
    Pay: crate::model::PayloadModel<L>,
    Act: ActuatorModel<L>,
{
    #[inline(always)]
    fn stage<L: Lane, const N: usize>(base: &State<L, N>, k: &State<L, N>, h: f64) -> State<L, N> {
        state_from_fn(
            #[inline(always)]
            |i| k[i].mul_add(L::splat(h), base[i]),
        )
    }
    let k1 = vehicle.derivative(s, trig, cmd, w);
    let s2 = stage(s, &k1, 0.5 * dt);
    let k2 = vehicle.derivative(&s2, &trig.advanced(&k1, 0.5 * dt, &s2), cmd, w);
    let s3 = stage(s, &k2, 0.5 * dt);
    let k3 = vehicle.derivative(&s3, &trig.advanced(&k2, 0.5 * dt, &s3), cmd, w);
    let s4 = stage(s, &k3, dt);
    let k4 = vehicle.derivative(&s4, &trig.advanced(&k3, dt, &s4), cmd, w);
    let h6 = dt / 6.0;
    state_from_fn(
        #[inline(always)]
        |i| (k1[i] + (k2[i] + k3[i]) * 2.0 + k4[i]).mul_add(L::splat(h6), s[i]),
    )
}

/// Trace columns after the states (whose names come from the layout), in order; the actuator's
/// own (`ActuatorModel::SIGNALS`) follow.
pub const SIGNAL_COLUMNS: [&str; 16] = [
    "x_ref",
    "y_ref",
    "z_ref",
    "psi_ref",
    "U1",
    "tau_phi",
    "tau_theta",
    "tau_psi",
    "wind_x",
    "wind_y",
    "wind_z",
    "e_o",
    "accel_c",
    "drag_z",
    "swing",
    "tension",
];

/// Most extra trace columns an actuator kind may have.
const MAX_ACTUATOR_SIGNALS: usize = 8;

/// Every trace column after `t` of a vehicle with these kinds: its states, `SIGNAL_COLUMNS`,
/// then the actuator's own.
pub fn trace_columns(payload: PayloadKind, actuator: ActuatorKind) -> Vec<&'static str> {
    struct Columns;
    impl VehicleVisitor for Columns {
        type Output = Vec<&'static str>;
        fn visit<Pay: Payload, Act: Actuator, const N: usize>(self) -> Self::Output {
            let extra = <Act::At<f64> as ActuatorModel<f64>>::SIGNALS;
            assert!(extra.len() <= MAX_ACTUATOR_SIGNALS);
            let vars = crate::model::state_vars_of::<Pay, Act>();
            vars.iter()
                .map(|v| v.name)
                .chain(SIGNAL_COLUMNS)
                .chain(extra.iter().copied())
                .collect()
        }
    }
    dispatch(payload, actuator, Columns)
}

/// Rows of (t, trace columns...) every `every` steps, for lane 0 of a flight.
pub struct Trace {
    pub every: usize,
    /// Values per row (t included).
    pub width: usize,
    pub data: Vec<f64>,
}

impl Trace {
    /// A trace of a flight of `steps` steps with `columns` columns after `t`.
    pub fn new(every: usize, steps: usize, columns: usize) -> Self {
        let every = every.max(1);
        let width = 1 + columns;
        Self {
            every,
            width,
            data: Vec::with_capacity((steps / every + 1) * width),
        }
    }

    fn push<L: Lane, const N: usize>(&mut self, row: &TraceRow<L, N>) {
        debug_assert_eq!(self.width, 1 + N + SIGNAL_COLUMNS.len() + row.extra.len());
        self.data.push(row.t);
        self.data.extend(row.s.iter().map(|x| x.lane(0)));
        let r = row.r;
        self.data
            .extend_from_slice(&[r.pos[0], r.pos[1], r.pos[2], r.psi, row.u.u1.lane(0)]);
        self.data
            .extend(row.u.tau.iter().chain(row.w.iter()).map(|x| x.lane(0)));
        for x in [row.e_o, row.accel_c, row.drag_z, row.swing, row.tension] {
            self.data.push(x.lane(0));
        }
        self.data.extend(row.extra.iter().map(|x| x.lane(0)));
    }
}

/// One trace row: lane 0 of the flight at time `t` (columns as `trace_columns`).
struct TraceRow<'a, L, const N: usize> {
    t: f64,
    s: &'a State<L, N>,
    r: &'a Reference,
    /// The controller's command held over the step starting at `t`.
    u: &'a Inputs<L>,
    /// The wind held over the step starting at `t`.
    w: &'a [L; 3],
    e_o: L,
    /// m/s^2, the magnitude of the payload's inertial acceleration.
    accel_c: L,
    /// N, the vertical drag on the quadrotor the derivative uses at `s` in `w`.
    drag_z: L,
    swing: L,
    tension: L,
    /// The actuator's own columns.
    extra: &'a [L],
}

/// Why a flight ended (docs/model.md section 11): it ran to the end, or a state went
/// non-finite or past its runaway bound (`divergence.*`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum ExitStatus {
    Ok = 0,
    NonFinite = 1,
    Distance = 2,
    Tilt = 3,
    Speed = 4,
    Rate = 5,
    Ground = 6,
}

impl ExitStatus {
    pub const ALL: [Self; 7] = [
        Self::Ok,
        Self::NonFinite,
        Self::Distance,
        Self::Tilt,
        Self::Speed,
        Self::Rate,
        Self::Ground,
    ];

    /// The public name (`mc.runs["status"]`).
    pub fn name(self) -> &'static str {
        match self {
            Self::Ok => "ok",
            Self::NonFinite => "non_finite",
            Self::Distance => "distance",
            Self::Tilt => "tilt",
            Self::Speed => "speed",
            Self::Rate => "rate",
            Self::Ground => "ground",
        }
    }

    /// What happened, in a sentence.
    pub fn message(self) -> &'static str {
        match self {
            Self::Ok => "the flight ran to the end",
            Self::NonFinite => "a state became infinite or NaN",
            Self::Distance => "a position went past divergence.max_distance",
            Self::Tilt => "roll or pitch went past divergence.max_tilt",
            Self::Speed => "a velocity went past divergence.max_speed",
            Self::Rate => "a body rate went past divergence.max_rate",
            Self::Ground => "the quadrotor went below ground.altitude",
        }
    }

    fn of(bound: Bound) -> Self {
        match bound {
            Bound::Distance => Self::Distance,
            Bound::Tilt => Self::Tilt,
            Bound::Speed => Self::Speed,
            Bound::Rate => Self::Rate,
        }
    }
}

/// Why the state `s` (one lane's values) failed its checks: non-finite first, then the ground
/// (`floor`, the quadrotor's z), then the first bound exceeded in the order of `Bound`.
fn classify(vars: &[StateVar], s: &[f64], limits: &[f64; 4], floor: f64) -> ExitStatus {
    if s.iter().any(|x| !x.is_finite()) {
        return ExitStatus::NonFinite;
    }
    if s[ix::Z] < floor {
        return ExitStatus::Ground;
    }
    [Bound::Distance, Bound::Tilt, Bound::Speed, Bound::Rate]
        .into_iter()
        .find(|&b| {
            vars.iter()
                .zip(s)
                .any(|(v, x)| v.bound == Some(b) && x.abs() > limits[b as usize])
        })
        .map_or(ExitStatus::NonFinite, ExitStatus::of)
}

/// What one realisation of one controller produced.
#[derive(Clone, Debug)]
pub struct LaneResult {
    /// One row per phase, columns as `metrics::METRIC_NAMES`; NaN when diverged.
    pub metrics: Vec<[f64; N_METRICS]>,
    /// Time (s) at which the state went non-finite or ran away; NaN if it never did.
    pub diverged_at: f64,
    /// Why the flight ended.
    pub status: ExitStatus,
    /// Amplitude spectrum of e_o per phase (empty unless asked for).
    pub spectra: Vec<Vec<f64>>,
}

/// What may differ between realisations: one vehicle's physical parameters, controllers,
/// wind field, initial state and runaway bounds, built from one validated `Config`. A fixed
/// scenario has one (`Engine::craft`); a dispersed batch builds one per realisation and the
/// flight loop carries them one per lane.
#[derive(Clone)]
pub struct Craft {
    pub parts: Parts,
    pd: Pd,
    smc: Smc,
    wind: WindField,
    /// The initial state (the layout's order).
    pub x0: Vec<f64>,
    /// `divergence.max_distance`, `max_tilt`, `max_speed`, `max_rate` (m, rad, m/s, rad/s), in
    /// the order of `Bound`.
    limits: [f64; 4],
    /// m, the flight ends below this z (`ground.*`; minus infinity when off).
    floor: f64,
}

impl Craft {
    /// The craft of a validated config (`Config::validate` has run).
    pub fn new(cfg: &Config) -> Result<Self, ConfigError> {
        Self::with_wind_of(cfg, None)
    }

    /// The craft of `cfg`, with `other`'s gust field if given (the same `gust.*` values and
    /// step: its discretised filters are reused rather than rebuilt).
    pub fn with_wind_of(cfg: &Config, other: Option<&Craft>) -> Result<Self, ConfigError> {
        let parts = Parts::new(cfg);
        let wind = match other {
            Some(c) => c.wind.clone(),
            None => WindField::new(cfg)?,
        };
        let x0 = initial_state(&parts, cfg);
        let d = &cfg.divergence;
        Ok(Self {
            parts,
            pd: Pd::new(cfg),
            smc: Smc::new(cfg),
            wind,
            x0,
            limits: [d.max_distance, d.max_tilt, d.max_speed, d.max_rate],
            floor: cfg.ground.floor(),
        })
    }
}

impl Craft {
    /// The gust field.
    pub fn wind(&self) -> &WindField {
        &self.wind
    }
}

/// The state a flight of `cfg` starts from: at rest at `initial.*`, payload and actuators at
/// hover.
pub fn initial_state(parts: &Parts, cfg: &Config) -> Vec<f64> {
    struct Rest<'a>(&'a Parts, &'a Config);
    impl VehicleVisitor for Rest<'_> {
        type Output = Vec<f64>;
        fn visit<Pay: Payload, Act: Actuator, const N: usize>(self) -> Vec<f64> {
            let Rest(parts, cfg) = self;
            let s: State<f64, N> = parts
                .vehicle::<Pay, Act>()
                .rest_state(cfg.initial.position, cfg.initial.attitude);
            s.to_vec()
        }
    }
    dispatch(cfg.payload.model, cfg.actuator.model, Rest(parts, cfg))
}

/// One request to the flight loop: which law, which realisations (one per lane) and, for a
/// dispersed batch, each realisation's craft (`None`: the engine's own, in every lane).
#[derive(Clone, Copy)]
pub struct FlightRequest<'a> {
    pub kind: ControllerKind,
    pub seed: u64,
    pub indices: &'a [u64],
    pub crafts: Option<&'a [&'a Craft]>,
    pub want_spectra: bool,
    pub cancel: Option<&'a AtomicBool>,
    /// Per lane, the turbulence's innovations to fly instead of the seeded stream of
    /// (`seed`, index): a flight as a function of its standard normals (rare events).
    pub innovations: Option<&'a [&'a [f64]]>,
}

impl<'a> FlightRequest<'a> {
    /// The engine's own craft in every lane, no spectra, no cancel flag.
    pub fn new(kind: ControllerKind, seed: u64, indices: &'a [u64]) -> Self {
        Self {
            kind,
            seed,
            indices,
            crafts: None,
            want_spectra: false,
            cancel: None,
            innovations: None,
        }
    }
}

/// A validated scenario turned into everything the loop needs, built once and shared read-only.
#[derive(Clone)]
pub struct Engine {
    pub cfg: Config,
    /// The scenario's own vehicle (every realisation's, unless dispersed).
    pub craft: Craft,
    /// The states, in order (names, axes, runaway bounds).
    pub vars: Vec<StateVar>,
    trajectory: Trajectory,
    phases: Vec<PhaseSteps>,
    pub steps: usize,
    pub dt: f64,
    decimation: usize,
    /// The instruction set the flight loop runs on (`Isa::active()` unless set otherwise).
    pub isa: Isa,
    /// The opt-in fused mode (`with_fused`): the batch path fuses multiply-adds. Off by
    /// default; its numbers are not bit-identical to the default mode's, nor across
    /// instruction sets. Single flights (`fly::<f64>`) never fuse.
    pub fused: bool,
    /// A wind prescribed step by step (`with_wind`), flown instead of the gust model.
    prescribed_wind: Option<Vec<[f64; 3]>>,
}

/// Most lanes a `Lane` type may carry (sizes the per-step wind buffer; the widest lane-set).
pub const MAX_LANES: usize = crate::gust::lanes::MAX_LANES;

/// `fly_any` compiled with target features: one `unsafe fn $name` per (name, features).
/// Safety of each: the CPU must support the features.
macro_rules! flight_loop_for {
    ($($(#[$doc:meta])* $name:ident, $features:literal;)+) => {$(
        $(#[$doc])*
        ///
        /// # Safety
        #[doc = concat!("The CPU must support ", $features, ".")]
        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = $features)]
        unsafe fn $name<L: KernelOps>(
            &self,
            req: &FlightRequest,
            trace: Option<&mut Trace>,
            planner: &mut FftPlanner<f64>,
        ) -> Option<Vec<LaneResult>> {
            self.fly_any::<L>(req, trace, planner)
        }
    )+};
}

/// Squared distance from `p` to the line through `line.0` along the unit vector `line.1` (to
/// the point itself where the direction is zero): the squared cross-track error.
#[inline(always)]
fn cross_track_sq<L: Lane>(p: &[L; 3], line: &([L; 3], [L; 3])) -> L {
    let (a, u) = line;
    let d = [p[0] - a[0], p[1] - a[1], p[2] - a[2]];
    let along = d[0] * u[0] + d[1] * u[1] + d[2] * u[2];
    let q = [
        d[0] - along * u[0],
        d[1] - along * u[1],
        d[2] - along * u[2],
    ];
    q[0] * q[0] + q[1] * q[1] + q[2] * q[2]
}

/// A lane type's way into the flight loop: the one function compiled for the instruction set
/// its operations need, and no other. Each (lane type, instruction set) pair the loop is
/// compiled for costs a copy of the whole inlined model, controller and integrator per vehicle
/// and law, so only the pairs that can run are built: the intrinsic lane types in their own
/// instruction set, the portable ones (`f64` for single flights, `F64x4`) in the baseline
/// one. The arithmetic never contracts or reorders, so the same lanes give the same bits in
/// any of them.
pub trait LoopEntry: KernelOps {
    fn enter(
        engine: &Engine,
        req: &FlightRequest,
        trace: Option<&mut Trace>,
        planner: &mut FftPlanner<f64>,
    ) -> Option<Vec<LaneResult>>;
}

macro_rules! portable_entry {
    ($($ty:ty),+) => {$(
        impl LoopEntry for $ty {
            fn enter(
                engine: &Engine,
                req: &FlightRequest,
                trace: Option<&mut Trace>,
                planner: &mut FftPlanner<f64>,
            ) -> Option<Vec<LaneResult>> {
                engine.fly_any::<Self>(req, trace, planner)
            }
        }
    )+};
}
portable_entry!(f64, F64x4);

/// An intrinsic lane type enters only the loop compiled for its instruction set (and only on
/// a CPU that has it: asserted, because the type's operations would be illegal otherwise).
macro_rules! intrinsic_entry {
    ($($ty:ty => $isa:expr, $fused:expr, $name:ident;)+) => {$(
        #[cfg(target_arch = "x86_64")]
        impl LoopEntry for $ty {
            fn enter(
                engine: &Engine,
                req: &FlightRequest,
                trace: Option<&mut Trace>,
                planner: &mut FftPlanner<f64>,
            ) -> Option<Vec<LaneResult>> {
                let isa: Isa = $isa;
                assert!(
                    isa.supported() && (!$fused || isa.fused_supported()),
                    "the {} path{} does not run on this CPU",
                    isa.name(),
                    if $fused { " (fused)" } else { "" }
                );
                // SAFETY: the CPU supports the instruction set (asserted just above).
                unsafe { engine.$name::<Self>(req, trace, planner) }
            }
        }
    )+};
}
intrinsic_entry! {
    F64x4Avx => Isa::Avx2, false, fly_avx2;
    F64x4Fma => Isa::Avx2, true, fly_avx2_fma;
    F64x8Avx512 => Isa::Avx512, false, fly_avx512;
    F64x8Fma512 => Isa::Avx512, true, fly_avx512;
}

/// How often (in steps) a flight looks at the cancel flag.
const CANCEL_CHECK_STEPS: usize = 4096;

impl Engine {
    /// The engine of a scenario, on the instruction set `Isa::active()` picks (an error
    /// under key `QUADRS_SIMD` if that variable forces a path this CPU cannot run).
    pub fn new(cfg: Config) -> Result<Self, ConfigError> {
        cfg.validate()?;
        Self::of_valid(cfg)
    }

    /// `new` for a scenario already validated (`Config::from_json`, `Dispersion::config`):
    /// the checks are not run a second time.
    pub fn of_valid(cfg: Config) -> Result<Self, ConfigError> {
        let isa = Isa::active().map_err(|message| ConfigError {
            key: crate::lane::isa::ENV.into(),
            message,
        })?;
        let dt = cfg.integrator.dt;
        let steps = cfg.steps();
        let decimation = cfg.decimation();
        Ok(Self {
            craft: Craft::new(&cfg)?,
            vars: state_vars(cfg.payload.model, cfg.actuator.model),
            trajectory: Trajectory::new(&cfg),
            phases: phase_steps(&cfg),
            steps,
            dt,
            decimation,
            cfg,
            isa,
            fused: false,
            prescribed_wind: None,
        })
    }

    /// Unit normals one flight's turbulence draws (see `WindField::innovations`).
    pub fn innovations(&self) -> usize {
        self.craft.wind().innovations(self.steps)
    }

    /// The innovations realisation `index` of `seed` draws.
    pub fn innovations_of(&self, seed: u64, index: u64) -> Vec<f64> {
        self.craft.wind().innovations_of(seed, index, self.steps)
    }

    /// Trace columns after `t`.
    pub fn trace_columns(&self) -> Vec<&'static str> {
        trace_columns(self.cfg.payload.model, self.cfg.actuator.model)
    }

    /// An empty trace for one flight, a row every `every` steps.
    pub fn trace(&self, every: usize) -> Trace {
        Trace::new(every, self.steps, self.trace_columns().len())
    }

    /// Fly the wind `wind` (m/s, inertial [x, y, z]; row k held over step k, one row per step
    /// and one for the final time: `steps + 1` rows) instead of the scenario's gust model: the
    /// `gust` block is then ignored. For deterministic inputs such as a sinusoid.
    pub fn with_wind(mut self, wind: Vec<[f64; 3]>) -> Result<Self, String> {
        if wind.len() != self.steps + 1 {
            return Err(format!(
                "wind must have steps + 1 = {} rows (one per step of the trace), got {}",
                self.steps + 1,
                wind.len()
            ));
        }
        if let Some(k) = wind.iter().position(|w| !w.iter().all(|x| x.is_finite())) {
            return Err(format!("wind must be finite, got {:?} in row {k}", wind[k]));
        }
        self.prescribed_wind = Some(wind);
        Ok(self)
    }

    /// The fused mode on or off (see `fused`): an error if this engine's instruction set has
    /// no fused multiply-add on this CPU (the baseline path never has).
    pub fn with_fused(mut self, fused: bool) -> Result<Self, String> {
        if fused && !self.isa.fused_supported() {
            return Err(format!(
                "fused=True needs fused multiply-add on vectors (AVX2 with FMA, or AVX-512), as \
                 --fused needs on the command line: \
                 the {} path on this CPU has none",
                self.isa.name()
            ));
        }
        self.fused = fused;
        Ok(self)
    }

    /// Integration steps per spectrum sample.
    pub fn decimation(&self) -> usize {
        self.decimation
    }

    pub fn phase_count(&self) -> usize {
        self.phases.len()
    }

    /// Frequencies (Hz) of each phase's spectrum bins.
    pub fn spectrum_grid(&self) -> Vec<Vec<f64>> {
        crate::metrics::spectrum_grid(&self.phases, self.dt, self.decimation, self.steps)
    }

    /// Realisations per lane-set of the batch path (`fly_set`): the widest vector of
    /// `self.isa` (8 with AVX-512, else 4).
    pub fn set_lanes(&self) -> usize {
        self.isa.set_lanes()
    }

    /// Fly `req.indices` (one per lane of `L`) on lane type `L`, with a trace of lane 0 if
    /// asked. Returns None if cancelled.
    pub fn fly<L: LoopEntry>(
        &self,
        req: &FlightRequest,
        trace: Option<&mut Trace>,
        planner: &mut FftPlanner<f64>,
    ) -> Option<Vec<LaneResult>> {
        self.fly_on::<L>(req, trace, planner)
    }

    /// Fly `set_lanes()` realisations at once on the widest SIMD lane type of this engine's
    /// instruction set (`self.isa`): the batch path. Every path gives bit-identical numbers.
    pub fn fly_set(
        &self,
        req: &FlightRequest,
        planner: &mut FftPlanner<f64>,
    ) -> Option<Vec<LaneResult>> {
        assert_eq!(
            req.indices.len(),
            self.set_lanes(),
            "one realisation index per lane"
        );
        // Each lane type below enters the loop compiled for its own instruction set
        // (`LoopEntry`), checked to run on this CPU.
        match (self.isa, self.fused) {
            (Isa::Baseline, _) => self.fly_on::<F64x4>(req, None, planner),
            #[cfg(target_arch = "x86_64")]
            (Isa::Avx2, false) => self.fly_on::<F64x4Avx>(req, None, planner),
            #[cfg(target_arch = "x86_64")]
            (Isa::Avx2, true) => self.fly_on::<F64x4Fma>(req, None, planner),
            #[cfg(target_arch = "x86_64")]
            (Isa::Avx512, false) => self.fly_on::<F64x8Avx512>(req, None, planner),
            #[cfg(target_arch = "x86_64")]
            (Isa::Avx512, true) => self.fly_on::<F64x8Fma512>(req, None, planner),
            #[cfg(not(target_arch = "x86_64"))]
            (Isa::Avx2 | Isa::Avx512, _) => unreachable!("{:?} off x86-64", self.isa),
        }
    }

    /// Enter the flight loop for lane type `L` (`LoopEntry`). Refuses, rather than risks an
    /// illegal instruction, a path the CPU cannot run.
    fn fly_on<L: LoopEntry>(
        &self,
        req: &FlightRequest,
        trace: Option<&mut Trace>,
        planner: &mut FftPlanner<f64>,
    ) -> Option<Vec<LaneResult>> {
        assert_eq!(
            req.indices.len(),
            L::LANES,
            "one realisation index per lane"
        );
        assert!(L::LANES <= MAX_LANES);
        L::enter(self, req, trace, planner)
    }

    flight_loop_for! {
        /// `fly_any` compiled with AVX2 enabled. No FMA: see `lane/isa.rs`.
        fly_avx2, "avx2";
        /// `fly_any` compiled with AVX2 and FMA enabled: the fused mode's AVX2 loop (only
        /// `Lane::mul_add` of `F64x4Fma` fuses; Rust never contracts the other operations).
        fly_avx2_fma, "avx2,fma";
        /// `fly_any` compiled with AVX-512F and DQ enabled (this enables AVX2 too). No FMA in
        /// the default mode: the lane operations never fuse, whatever the enabled features.
        fly_avx512, "avx512f,avx512dq";
    }

    /// Fly on the vehicle kinds of the scenario (`model::dispatch`).
    #[inline(always)]
    fn fly_any<L: KernelOps>(
        &self,
        req: &FlightRequest,
        trace: Option<&mut Trace>,
        planner: &mut FftPlanner<f64>,
    ) -> Option<Vec<LaneResult>> {
        struct Fly<'e, 'r, 't, L> {
            engine: &'e Engine,
            req: &'r FlightRequest<'r>,
            trace: Option<&'t mut Trace>,
            planner: &'t mut FftPlanner<f64>,
            lanes: PhantomData<L>,
        }
        impl<L: KernelOps> VehicleVisitor for Fly<'_, '_, '_, L> {
            type Output = Option<Vec<LaneResult>>;
            #[inline(always)]
            fn visit<Pay: Payload, Act: Actuator, const N: usize>(self) -> Self::Output {
                self.engine
                    .fly_vehicle::<L, Pay, Act, N>(self.req, self.trace, self.planner)
            }
        }
        let cfg = &self.cfg;
        let fly = Fly {
            engine: self,
            req,
            trace,
            planner,
            lanes: PhantomData::<L>,
        };
        dispatch(cfg.payload.model, cfg.actuator.model, fly)
    }

    /// Gather the lanes' crafts into lane-valued parameters and fly the chosen law.
    #[inline(always)]
    fn fly_vehicle<L: KernelOps, Pay: Payload, Act: Actuator, const N: usize>(
        &self,
        req: &FlightRequest,
        trace: Option<&mut Trace>,
        planner: &mut FftPlanner<f64>,
    ) -> Option<Vec<LaneResult>> {
        let own = [&self.craft; MAX_LANES];
        let crafts: &[&Craft] = match req.crafts {
            Some(c) => {
                assert_eq!(c.len(), L::LANES, "one craft per lane");
                c
            }
            None => &own[..L::LANES],
        };
        let parts: Vec<&Parts> = crafts.iter().map(|c| &c.parts).collect();
        let vehicle = Parts::gather::<L, Pay, Act>(&parts);
        match req.kind {
            ControllerKind::Pd => {
                let each: Vec<&Pd> = crafts.iter().map(|c| &c.pd).collect();
                let ctrl = Pd::gather::<L>(&each);
                self.fly_loop::<L, _, _, _, N>(&vehicle, &ctrl, crafts, req, trace, planner)
            }
            ControllerKind::Smc => {
                let each: Vec<&Smc> = crafts.iter().map(|c| &c.smc).collect();
                let ctrl = Smc::gather::<L>(&each);
                self.fly_loop::<L, _, _, _, N>(&vehicle, &ctrl, crafts, req, trace, planner)
            }
        }
    }

    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn fly_loop<L, Pay, Act, C, const N: usize>(
        &self,
        vehicle: &Vehicle<L, Pay, Act>,
        ctrl: &C,
        crafts: &[&Craft],
        req: &FlightRequest,
        mut trace: Option<&mut Trace>,
        planner: &mut FftPlanner<f64>,
    ) -> Option<Vec<LaneResult>>
    where
        L: KernelOps,
        Pay: crate::model::PayloadModel<L>,
        Act: ActuatorModel<L>,
        C: Control<L>,
    {
        assert_eq!(self.vars.len(), N, "the engine's layout is the vehicle's");
        let x0: State<L, N> = state_from_fn(|i| L::from_fn(|l| crafts[l].x0[i]));
        let mut s = x0;
        let mut winds: Vec<WindState> = match req.innovations {
            Some(xi) => {
                assert_eq!(xi.len(), L::LANES, "one row of innovations per lane");
                xi.iter()
                    .zip(crafts)
                    .map(|(x, c)| c.wind.given(x))
                    .collect()
            }
            None => req
                .indices
                .iter()
                .zip(crafts)
                .map(|(&i, c)| c.wind.realisation(req.seed, i))
                .collect(),
        };
        // The wind of the whole lane-set at once where the lanes' fields allow it
        // (`LaneWind::new`): the same numbers as the per-lane `sample_at`, drawn from the same
        // sources. Else (and for a prescribed wind) the per-lane path below.
        let mut lane_wind = if self.prescribed_wind.is_none() {
            let fields: Vec<&WindField> = crafts.iter().map(|c| &c.wind).collect();
            LaneWind::<L>::new(&fields, winds.iter().map(|w| w.source()).collect())
        } else {
            None
        };
        let mut acc =
            PhaseAccumulator::<L>::new(&self.phases, self.dt, self.decimation, self.steps);
        let mut diverged_at = [f64::NAN; MAX_LANES];
        let mut status = [ExitStatus::Ok; MAX_LANES];
        let mut alive = L::LANES;
        // Each state's runaway bound per lane (infinite where it has none: then only a
        // non-finite value ends the flight). NaN compares false, so the masks also catch
        // non-finite states.
        let limit: State<L, N> = state_from_fn(|i| {
            L::from_fn(|l| match self.vars[i].bound {
                Some(b) => crafts[l].limits[b as usize],
                None => f64::INFINITY,
            })
        });
        let mut segment = 0;
        let mut r = Reference::default();
        let mut ref_changes = f64::NEG_INFINITY;
        // The straight line of the current leg (a point, a unit direction): cross-track error.
        let mut line = ([L::splat(0.0); 3], [L::splat(0.0); 3]);
        let mut line_of = usize::MAX;
        let mut wind_lanes = [[0.0; 3]; MAX_LANES];
        // Steps inside any lane's gust window (lanes may differ in a dispersed batch).
        let windy = || crafts.iter().filter(|c| c.wind.enabled());
        let gust_from = windy().map(|c| c.wind.start_step()).min();
        let gust_to = windy().map(|c| c.wind.end_step()).max();
        let (gust_from, gust_to) = (gust_from.unwrap_or(u64::MAX), gust_to.unwrap_or(0));
        let floor = L::from_fn(|l| crafts[l].floor);
        let grounded = crafts.iter().any(|c| c.floor > f64::NEG_INFINITY);
        let (zero, one) = (L::splat(0.0), L::splat(1.0));
        let mut extra = [zero; MAX_ACTUATOR_SIGNALS];
        let extra = &mut extra[..Act::SIGNALS.len()];
        // A mean wind or a discrete gust in any lane: the wind is sampled at every step.
        let blows = crafts.iter().any(|c| c.wind.blows());
        let mut held = [zero; 3];

        for k in 0..=self.steps {
            let t = k as f64 * self.dt;
            if t + TIME_SLACK >= ref_changes {
                r = self.trajectory.at(t, &mut segment);
                ref_changes = self.trajectory.next_change(segment);
                // Each lane's line (they differ before the first waypoint, which each lane's
                // own initial position leads to), once per segment: it depends on nothing else.
                if segment != line_of {
                    line_of = segment;
                    let mut lines = [([0.0; 3], [0.0; 3]); MAX_LANES];
                    for (l, c) in crafts.iter().enumerate() {
                        lines[l] = self.trajectory.line(segment, [c.x0[0], c.x0[1], c.x0[2]]);
                    }
                    line = (
                        [0, 1, 2].map(|i| L::from_fn(|l| lines[l].0[i])),
                        [0, 1, 2].map(|i| L::from_fn(|l| lines[l].1[i])),
                    );
                }
            }
            let trig = Trig::of(&s);
            let u = ctrl.control_with(&Vehicle::<L, Pay, Act>::rigid(&s), &trig, &r);
            let cmd = vehicle.actuator.command(&u);
            // Outside the gust window `sample_at` returns zeros without touching the state
            // unless a `[wind]` source blows, so the per-lane calls are skipped where no lane's
            // window is open and nothing else blows (most of a paper flight).
            let at = |lane: usize| {
                let rigid = Vehicle::<L, Pay, Act>::rigid(&s);
                move || Kinematics {
                    z: rigid.pos[2].lane(lane),
                    vel: [0, 1, 2].map(|i| rigid.vel[i].lane(lane)),
                }
            };
            // The row at t_k holds the wind of step k. The last row (t = duration) has no step
            // after it: it holds the last step's wind (the hold runs to its end), so no metric
            // sees a wind that no step flies, and no innovation is drawn for it.
            let w: [L; 3] = if k == self.steps && k > 0 {
                held
            } else {
                // The lane-set's turbulence when `lane_gust` flies it (else the per-lane values).
                let mut wind_set: Option<[L; 3]> = None;
                if let Some(prescribed) = &self.prescribed_wind {
                    wind_lanes = [prescribed[k]; MAX_LANES];
                    if blows {
                        for (lane, (v, c)) in wind_lanes.iter_mut().zip(crafts).enumerate() {
                            let d = c.wind.deterministic(k as u64, &at(lane)());
                            *v = [0, 1, 2].map(|i| v[i] + d[i]);
                        }
                    }
                } else if let Some(g) = lane_wind.as_mut() {
                    wind_set = Some(g.sample(
                        k as u64,
                        #[inline(always)]
                        || {
                            let rigid = Vehicle::<L, Pay, Act>::rigid(&s);
                            (rigid.pos[2], rigid.vel)
                        },
                    ));
                } else if blows || (gust_from..gust_to).contains(&(k as u64)) {
                    for (lane, ((ws, v), c)) in winds
                        .iter_mut()
                        .zip(wind_lanes.iter_mut())
                        .zip(crafts)
                        .enumerate()
                    {
                        *v = c.wind.sample_at(ws, k as u64, at(lane));
                    }
                } else {
                    wind_lanes = [[0.0; 3]; MAX_LANES];
                }
                #[inline(always)]
                fn wind_of<L: Lane>(lanes: &[[f64; 3]; MAX_LANES], c: usize) -> L {
                    L::from_fn(
                        #[inline(always)]
                        |lane| lanes[lane][c],
                    )
                }
                match wind_set {
                    Some(w) => w,
                    None => [
                        wind_of(&wind_lanes, 0),
                        wind_of(&wind_lanes, 1),
                        wind_of(&wind_lanes, 2),
                    ],
                }
            };
            held = w;
            let out = vehicle.payload_outputs(&s, &trig, u.u1, &w);
            let rigid = Vehicle::<L, Pay, Act>::rigid(&s);
            let e = [
                rigid.pos[0] * -1.0 + r.pos[0],
                rigid.pos[1] * -1.0 + r.pos[1],
                rigid.pos[2] * -1.0 + r.pos[2],
            ];
            let [ax, ay, az] = out.accel;
            // |a| without the square root's rounding where the acceleration is vertical only.
            let accel = (ax * ax + ay * ay + az * az).sqrt();
            // The specific force a - g (g = (0, 0, -g)): what an accelerometer on the payload reads.
            let fz = az + vehicle.body.g;
            let specific_force = (ax * ax + ay * ay + fz * fz).sqrt();
            acc.sample(
                k,
                t,
                &Sample {
                    e_o: out.e_o,
                    tracking_sq: e[0] * e[0] + e[1] * e[1] + e[2] * e[2],
                    cross_sq: cross_track_sq(&rigid.pos, &line),
                    accel,
                    specific_force,
                    swing: out.swing,
                    tension: out.tension,
                    slack: L::select(out.tension.cmp_le(zero), one, zero),
                    saturated: vehicle.actuator.saturated(&cmd),
                },
            );
            if let Some(tr) = trace.as_deref_mut() {
                // The trace ends where its lane diverged: nothing after `diverged_at` is recorded.
                if k % tr.every == 0 && diverged_at[0].is_nan() {
                    let lay = Vehicle::<L, Pay, Act>::LAYOUT;
                    vehicle.actuator.signals(&cmd, &s, lay.actuator(), extra);
                    tr.push(&TraceRow {
                        t,
                        s: &s,
                        r: &r,
                        u: &u,
                        w: &w,
                        e_o: out.e_o,
                        accel_c: accel,
                        drag_z: vehicle.body.vertical_drag(rigid.vel[2], w[2]),
                        swing: out.swing,
                        tension: out.tension,
                        extra,
                    });
                }
            }
            if k == self.steps {
                break;
            }
            s = rk4_step(vehicle, &s, &trig, &cmd, &w, self.dt);

            let mut ok = L::ALL;
            for i in 0..N {
                ok &= s[i].abs().le_mask(limit[i]);
            }
            if grounded {
                ok &= floor.le_mask(s[ix::Z]);
            }
            if ok != L::ALL {
                for (lane, at) in diverged_at.iter_mut().enumerate().take(L::LANES) {
                    if at.is_nan() && ok & (1 << lane) == 0 {
                        *at = t + self.dt;
                        alive -= 1;
                        let values: Vec<f64> = s.iter().map(|x| x.lane(lane)).collect();
                        let c = crafts[lane];
                        status[lane] = classify(&self.vars, &values, &c.limits, c.floor);
                        // Park the lane on a benign state so its neighbours' arithmetic stays clean.
                        for (x, x0) in s.iter_mut().zip(crafts[lane].x0.iter()) {
                            x.set_lane(lane, *x0);
                        }
                    }
                }
                if alive == 0 {
                    break;
                }
            }
            if k % CANCEL_CHECK_STEPS == 0 && req.cancel.is_some_and(|c| c.load(Ordering::Relaxed))
            {
                return None;
            }
        }

        let n_phase = self.phases.len();
        let want_spectra = req.want_spectra;
        Some(
            (0..L::LANES)
                .map(|lane| {
                    let mut spectra = vec![Vec::new(); if want_spectra { n_phase } else { 0 }];
                    let mut metrics = acc.finish(
                        lane,
                        planner,
                        want_spectra.then_some(spectra.as_mut_slice()),
                    );
                    if !diverged_at[lane].is_nan() {
                        // Phases that ended before the first bad step are real; NaN the rest
                        // (over the whole bin grid: the flight may have stopped early).
                        let bad = (diverged_at[lane] / self.dt).round() as usize;
                        let grid = if want_spectra {
                            self.spectrum_grid()
                        } else {
                            Vec::new()
                        };
                        for (i, ph) in self.phases.iter().enumerate() {
                            if ph.last >= bad {
                                metrics[i].fill(f64::NAN);
                                if let Some(amp) = spectra.get_mut(i) {
                                    *amp = vec![f64::NAN; grid[i].len()];
                                }
                            }
                        }
                    }
                    LaneResult {
                        metrics,
                        diverged_at: diverged_at[lane],
                        status: status[lane],
                        spectra,
                    }
                })
                .collect(),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::tests::paper;
    use crate::model::actuator::Ideal;
    use crate::model::paper_ix::{self as ix, NX};
    use crate::model::payload::Spring;
    use crate::model::PaperVehicle;

    fn paper_vehicle(cfg: &Config) -> PaperVehicle {
        Parts::new(cfg).vehicle::<Spring, Ideal>()
    }

    fn step(v: &PaperVehicle, s: &State<f64, NX>, u: &Inputs<f64>, dt: f64) -> State<f64, NX> {
        rk4_step(v, s, &Trig::of(s), u, &[0.0; 3], dt)
    }

    /// Free two-body oscillation: thrust = total weight, no control, payload displaced by a.
    fn free_oscillation_error(dt: f64, t_end: f64) -> f64 {
        let mut cfg = paper();
        cfg.gust.air_density = 0.0; // no drag: the analytic solution is undamped
        let plant = paper_vehicle(&cfg);
        let a = 0.05;
        let mut s: State<f64, NX> = plant.rest_state([0.0, 0.0, 2.0], [0.0; 3]);
        s[ix::ZC] -= a;
        let u = Inputs {
            u1: (plant.body.m + plant.payload.mc) * plant.body.g,
            tau: [0.0; 3],
        };
        let omega = (plant.payload.kc * (plant.body.m + plant.payload.mc)
            / (plant.body.m * plant.payload.mc))
            .sqrt();
        let n = (t_end / dt).round() as usize;
        for _ in 0..n {
            s = step(&plant, &s, &u, dt);
        }
        // Relative coordinate r = z - zc oscillates about d0 with amplitude a.
        let exact = plant.payload.hover_offset + a * (omega * n as f64 * dt).cos();
        (s[ix::Z] - s[ix::ZC] - exact).abs()
    }

    #[test]
    fn rk4_converges_at_fourth_order() {
        let (e1, e2, e3) = (
            free_oscillation_error(0.02, 2.0),
            free_oscillation_error(0.01, 2.0),
            free_oscillation_error(0.005, 2.0),
        );
        for (coarse, fine) in [(e1, e2), (e2, e3)] {
            let ratio = coarse / fine;
            assert!(
                (14.0..18.0).contains(&ratio),
                "error ratio {ratio} (errors {e1} {e2} {e3})"
            );
        }
    }

    #[test]
    fn free_oscillation_frequency_is_the_two_body_one() {
        // Count zero crossings of r - d0 over 10 s at fine dt, drag off.
        let mut cfg = paper();
        cfg.gust.air_density = 0.0;
        let plant = paper_vehicle(&cfg);
        let mut s: State<f64, NX> = plant.rest_state([0.0; 3], [0.0; 3]);
        s[ix::ZC] -= 0.01;
        let u = Inputs {
            u1: (plant.body.m + plant.payload.mc) * plant.body.g,
            tau: [0.0; 3],
        };
        let dt = 1e-4;
        let d0 = plant.payload.hover_offset;
        let (mut crossings, mut first, mut last) = (0usize, f64::NAN, f64::NAN);
        let mut prev = s[ix::Z] - s[ix::ZC] - d0;
        for k in 1..=100_000 {
            s = step(&plant, &s, &u, dt);
            let cur = s[ix::Z] - s[ix::ZC] - d0;
            if prev.signum() != cur.signum() {
                let tc = (k as f64 - cur / (cur - prev)) * dt;
                if first.is_nan() {
                    first = tc;
                }
                last = tc;
                crossings += 1;
            }
            prev = cur;
        }
        let measured = 0.5 * (crossings - 1) as f64 / (last - first);
        let fn_payload = 2.0;
        let expected = fn_payload * ((cfg.vehicle.mass + 0.22) / cfg.vehicle.mass).sqrt();
        assert!(
            (measured - expected).abs() < 1e-4,
            "{measured} Hz vs {expected} Hz"
        );
    }

    #[test]
    fn a_flight_diverging_in_p2_keeps_p1_metrics() {
        // The paper's SMC is laterally unstable: a lateral gust from 25 s sets it off in P2.
        let mut cfg = paper();
        cfg.integrator.dt = 1e-3;
        cfg.gust
            .components
            .push(crate::config::GustComponent::Lateral);
        let engine = Engine::new(cfg).unwrap();
        let mut planner = FftPlanner::new();
        let mut fly = |e: &Engine| {
            let req = FlightRequest {
                want_spectra: true,
                ..FlightRequest::new(ControllerKind::Smc, 3, &[0])
            };
            e.fly::<f64>(&req, None, &mut planner).unwrap().remove(0)
        };
        let r = fly(&engine);
        assert!(
            r.diverged_at > 25.0 && r.diverged_at < 50.0,
            "{}",
            r.diverged_at
        );
        // Before the gust the lateral component changes nothing: P1 equals the vertical-only
        // flight's, exactly; the phases still open at the divergence are NaN.
        let mut vertical = paper();
        vertical.integrator.dt = 1e-3;
        let v = fly(&Engine::new(vertical).unwrap());
        assert!(v.diverged_at.is_nan());
        assert_eq!(r.metrics[0], v.metrics[0]);
        assert_eq!(r.spectra[0], v.spectra[0]);
        assert!(r.metrics[0].iter().all(|x| x.is_finite()));
        for i in 1..3 {
            assert!(
                r.metrics[i].iter().all(|x| x.is_nan()),
                "{:?}",
                r.metrics[i]
            );
            assert!(r.spectra[i].iter().all(|x| x.is_nan()));
        }
    }

    /// Each runaway bound, broken alone, ends the flight with its own status; a state that
    /// overflows is `non_finite`; a flight within every bound is `ok`.
    #[test]
    fn exit_status_names_what_ended_the_flight() {
        let fly = |edit: &dyn Fn(&mut Config)| {
            let mut cfg = paper();
            cfg.integrator.dt = 1e-3;
            cfg.integrator.duration = 10.0;
            cfg.phases.truncate(1);
            cfg.phases[0].end = 10.0;
            cfg.gust.enabled = false;
            cfg.initial.attitude = [0.02, -0.01, 0.5];
            edit(&mut cfg);
            let engine = Engine::new(cfg).unwrap();
            let req = FlightRequest::new(ControllerKind::Pd, 0, &[0]);
            let r = engine
                .fly::<f64>(&req, None, &mut FftPlanner::new())
                .unwrap()
                .remove(0);
            (r.status, r.diverged_at)
        };
        assert_eq!(fly(&|_| {}).0, ExitStatus::Ok);
        assert!(fly(&|_| {}).1.is_nan());
        for (status, edit) in [
            (
                ExitStatus::Distance,
                &(|c: &mut Config| c.divergence.max_distance = 0.5) as &dyn Fn(&mut Config),
            ),
            (ExitStatus::Tilt, &|c: &mut Config| {
                c.divergence.max_tilt = 0.015
            }),
            (ExitStatus::Speed, &|c: &mut Config| {
                c.divergence.max_speed = 0.05
            }),
            (ExitStatus::Rate, &|c: &mut Config| {
                c.divergence.max_rate = 0.01
            }),
            (ExitStatus::NonFinite, &|c: &mut Config| {
                c.controller.pd.kp[2] = 1e308
            }),
        ] {
            let (got, at) = fly(edit);
            assert_eq!(got, status, "diverged at {at}");
            assert!(at > 0.0 && at <= 10.0, "{status:?} at {at}");
        }
        // The classification itself: non-finite first, then the bounds in order.
        let vars = crate::model::state_vars(Default::default(), Default::default());
        let limits = [1.0, 1.0, 1.0, 1.0];
        let mut s = vec![0.0; vars.len()];
        s[ix::ZC] = -2.0;
        assert_eq!(
            classify(&vars, &s, &limits, f64::NEG_INFINITY),
            ExitStatus::Distance
        );
        s[ix::ZC] = 0.0;
        s[ix::VZ] = 2.0;
        s[ix::P] = 2.0;
        assert_eq!(
            classify(&vars, &s, &limits, f64::NEG_INFINITY),
            ExitStatus::Speed
        );
        s[ix::PSI] = f64::NAN;
        assert_eq!(
            classify(&vars, &s, &limits, f64::NEG_INFINITY),
            ExitStatus::NonFinite
        );
    }

    fn hover_cfg() -> Config {
        let mut cfg = paper();
        cfg.gust.enabled = false;
        cfg.initial.position = [0.0, 0.0, 2.0];
        cfg.initial.attitude = [0.0, 0.0, 0.0];
        cfg.trajectory.waypoints = vec![[0.0, 0.0, 0.0, 2.0, 0.0], [5.0, 0.0, 0.0, 2.0, 0.0]];
        cfg.integrator.duration = 10.0;
        cfg.phases.truncate(1);
        cfg.phases[0].end = 10.0;
        cfg
    }

    #[test]
    fn hover_equilibrium_holds_for_both_laws() {
        let engine = Engine::new(hover_cfg()).unwrap();
        for kind in [ControllerKind::Pd, ControllerKind::Smc] {
            let mut tr = engine.trace(1000);
            engine
                .fly::<f64>(
                    &FlightRequest::new(kind, 0, &[0]),
                    Some(&mut tr),
                    &mut FftPlanner::new(),
                )
                .unwrap();
            let x0 = &engine.craft.x0;
            for row in tr.data.chunks(tr.width) {
                for i in 0..NX {
                    assert!(
                        (row[1 + i] - x0[i]).abs() < 1e-9,
                        "{kind:?} state {i} drifted: {row:?}"
                    );
                }
            }
        }
    }

    #[test]
    fn simd_lanes_match_scalar_flights() {
        let mut cfg = paper();
        cfg.integrator.duration = 30.0;
        cfg.integrator.dt = 1e-3;
        cfg.gust.end = 29.0;
        cfg.phases.truncate(2);
        cfg.phases[1].end = 30.0;
        // Lateral motion too, so that every kernel (asin included) sees non-trivial inputs.
        cfg.initial.position = [0.3, -0.2, 0.0];
        cfg.initial.attitude = [0.05, -0.03, 0.5];
        let mut engine = Engine::new(cfg).unwrap();
        let mut planner = FftPlanner::new();
        let bits = |r: &[LaneResult]| -> Vec<Vec<u64>> {
            r.iter()
                .map(|l| {
                    let m = l.metrics.iter().flatten().map(|x| x.to_bits());
                    m.chain([l.diverged_at.to_bits()]).collect()
                })
                .collect()
        };
        for kind in [ControllerKind::Pd, ControllerKind::Smc] {
            let mut runs = Vec::new();
            // Realisations 3..11: two lane-sets of four, or one of eight (AVX-512).
            let indices: Vec<u64> = (3..3 + MAX_LANES as u64).collect();
            for isa in Isa::ALL {
                if !isa.supported() {
                    eprintln!("skipped the {} path: this CPU cannot run it", isa.name());
                    continue;
                }
                engine.isa = isa;
                let flown = |f: &mut dyn FnMut(&FlightRequest) -> Vec<LaneResult>, n| {
                    let sets = indices.chunks(n);
                    sets.flat_map(|set| f(&FlightRequest::new(kind, 7, set)))
                        .collect::<Vec<_>>()
                };
                let set_lanes = engine.set_lanes();
                runs.push(flown(
                    &mut |req| engine.fly_set(req, &mut planner).unwrap(),
                    set_lanes,
                ));
                runs.push(flown(
                    &mut |req| engine.fly::<F64x4>(req, None, &mut planner).unwrap(),
                    4,
                ));
                runs.push(flown(
                    &mut |req| engine.fly::<f64>(req, None, &mut planner).unwrap(),
                    1,
                ));
            }
            // Bit-identical across lane types, packings and instruction sets (no FMA anywhere).
            for r in &runs[1..] {
                assert_eq!(bits(r), bits(&runs[0]), "{kind:?}");
            }
            // ... and the flights went somewhere. (The paper's SMC gains are unstable
            // laterally, so its flights diverge here: equally on every path.)
            if kind == ControllerKind::Pd {
                assert!(runs[0]
                    .iter()
                    .all(|l| l.diverged_at.is_nan() && l.metrics[0][0] > 0.0));
            }
        }
    }

    /// Column `name` of a trace row (`row[0]` is t).
    fn col(row: &[f64], name: &str) -> f64 {
        let columns = trace_columns(Default::default(), Default::default());
        row[1 + columns.iter().position(|c| *c == name).unwrap()]
    }

    #[test]
    fn drag_z_is_the_drag_the_dynamics_feel() {
        // A gusty stretch of the paper flight: vz and wind_z both move.
        let mut cfg = paper();
        cfg.integrator.dt = 1e-3;
        cfg.integrator.duration = 28.0;
        cfg.phases.truncate(1);
        let engine = Engine::new(cfg.clone()).unwrap();
        let mut tr = engine.trace(7);
        let req = FlightRequest::new(ControllerKind::Pd, 5, &[0]);
        engine
            .fly::<f64>(&req, Some(&mut tr), &mut FftPlanner::new())
            .unwrap();
        let plant = paper_vehicle(&cfg);
        let mut no_drag = paper_vehicle(&cfg);
        no_drag.body.drag_quad = 0.0;
        let (mut gusty, mut worst) = (0, 0.0_f64);
        for row in tr.data.chunks(tr.width) {
            let s: State<f64, NX> = state_from_fn(|i| row[1 + i]);
            let u = Inputs {
                u1: col(row, "U1"),
                tau: [
                    col(row, "tau_phi"),
                    col(row, "tau_theta"),
                    col(row, "tau_psi"),
                ],
            };
            let w = [col(row, "wind_x"), col(row, "wind_y"), col(row, "wind_z")];
            let drag_z = col(row, "drag_z");
            // The force the derivative adds to m az, recovered from two derivatives.
            let trig = Trig::of(&s);
            let felt = (plant.derivative(&s, &trig, &u, &w)[ix::VZ]
                - no_drag.derivative(&s, &trig, &u, &w)[ix::VZ])
                * plant.body.m;
            worst = worst.max((felt - drag_z).abs());
            // ... and the formula by hand, from the trace's own columns.
            let rel = col(row, "vz") - w[2];
            let k = 0.5 * cfg.gust.air_density * cfg.vehicle.drag_area;
            assert_eq!(drag_z, rel * rel.abs() * -k, "t = {}", row[0]);
            gusty += usize::from(w[2] != 0.0 && drag_z.abs() > 1e-3);
        }
        assert!(worst < 1e-12, "{worst:e}");
        assert!(gusty > 100, "the gust must load the drag: {gusty} rows");
    }

    #[test]
    fn drag_z_vanishes_at_hover_without_wind() {
        let engine = Engine::new(hover_cfg()).unwrap();
        let mut tr = engine.trace(100);
        let req = FlightRequest::new(ControllerKind::Pd, 0, &[0]);
        engine
            .fly::<f64>(&req, Some(&mut tr), &mut FftPlanner::new())
            .unwrap();
        for row in tr.data.chunks(tr.width) {
            assert_eq!(col(row, "wind_z"), 0.0);
            assert!(col(row, "drag_z").abs() < 1e-15, "{row:?}");
        }
    }

    /// The fused mode: refused where the path has no FMA; elsewhere close to the default
    /// mode (last digits), yet not identical (the fusing happened).
    #[test]
    fn fused_mode_is_close_to_the_default_and_refused_without_fma() {
        let mut cfg = paper();
        cfg.integrator.duration = 10.0;
        cfg.integrator.dt = 1e-3;
        cfg.gust.start = 1.0;
        cfg.gust.end = 9.0;
        cfg.phases.truncate(1);
        cfg.phases[0].end = 10.0;
        let mut planner = FftPlanner::new();
        for isa in Isa::ALL {
            let mut engine = Engine::new(cfg.clone()).unwrap();
            engine.isa = isa;
            if !isa.fused_supported() {
                let e = engine.with_fused(true).err().expect("refused");
                assert!(e.contains("fused") && e.contains(isa.name()), "{e}");
                eprintln!(
                    "skipped the fused {} path: this CPU cannot run it",
                    isa.name()
                );
                continue;
            }
            let indices: Vec<u64> = (0..engine.set_lanes() as u64).collect();
            let req = FlightRequest::new(ControllerKind::Pd, 1, &indices);
            let exact = engine.fly_set(&req, &mut planner).unwrap();
            let engine = engine.with_fused(true).unwrap();
            let fused = engine.fly_set(&req, &mut planner).unwrap();
            let (mut worst, mut differ) = (0.0f64, false);
            for (a, b) in exact.iter().zip(&fused) {
                for (x, y) in a.metrics[0].iter().zip(&b.metrics[0]) {
                    worst = worst.max((x - y).abs() / x.abs().max(1e-300));
                    differ |= x.to_bits() != y.to_bits();
                }
            }
            assert!(
                worst < 1e-8 && differ,
                "{isa:?}: worst relative difference {worst}"
            );
        }
    }

    /// A short paper flight in the whole-flight wind: a sheared mean wind at 30 deg, turbulence
    /// on all axes following the vehicle's altitude and airspeed, a ramp and a pulse.
    fn windy_cfg() -> Config {
        use crate::config::{
            DiscreteGust, GustAirspeed, GustAltitude, GustComponent, GustShape, Shear,
        };
        let mut cfg = paper();
        cfg.integrator.dt = 1e-3;
        cfg.integrator.duration = 24.0;
        cfg.phases.truncate(2);
        cfg.phases[1].end = 24.0;
        cfg.trajectory.interpolation = crate::config::Interpolation::MinJerk;
        cfg.trajectory.waypoints = vec![[0.0, 0.0, 0.0, 0.0, 0.0], [2.0, 0.0, 0.0, 20.0, 0.0]];
        cfg.trajectory.transition = 15.0;
        cfg.gust.components = GustComponent::ALL.to_vec();
        cfg.gust.start = 3.0;
        cfg.gust.end = 20.0;
        cfg.gust.altitude = GustAltitude::Vehicle;
        cfg.gust.airspeed = GustAirspeed::Relative;
        cfg.wind.speed = 2.0;
        cfg.wind.heading = 30.0;
        cfg.wind.shear = Shear::Log;
        cfg.wind.gusts = vec![
            DiscreteGust {
                start: 5.0,
                duration: 2.0,
                amplitude: [1.0, -0.5, 0.3],
                shape: GustShape::Ramp,
            },
            DiscreteGust {
                start: 12.0,
                duration: 1.5,
                amplitude: [0.0, 1.0, -0.8],
                shape: GustShape::Pulse,
            },
        ];
        cfg.validate().unwrap();
        cfg
    }

    #[test]
    fn given_innovations_fly_the_seeded_flight_in_a_wind_that_follows_the_vehicle() {
        let engine = Engine::new(windy_cfg()).unwrap();
        let mut planner = FftPlanner::new();
        let bits = |r: &[LaneResult]| -> Vec<u64> {
            r.iter()
                .flat_map(|l| l.metrics.iter().flatten().map(|x| x.to_bits()))
                .collect()
        };
        let indices: Vec<u64> = (3..7).collect();
        let req = FlightRequest::new(ControllerKind::Pd, 11, &indices);
        let seeded = engine.fly::<F64x4>(&req, None, &mut planner).unwrap();
        assert!(seeded.iter().all(|l| l.status == ExitStatus::Ok));
        let xi: Vec<Vec<f64>> = indices
            .iter()
            .map(|&i| engine.innovations_of(11, i))
            .collect();
        assert!(xi[0].len() > 1000);
        let rows: Vec<&[f64]> = xi.iter().map(|x| x.as_slice()).collect();
        let given = FlightRequest {
            innovations: Some(&rows),
            ..req
        };
        let flown = engine.fly::<F64x4>(&given, None, &mut planner).unwrap();
        assert_eq!(bits(&seeded), bits(&flown));
        // One lane alone flies the same as in its lane-set.
        let one = engine
            .fly::<f64>(
                &FlightRequest::new(ControllerKind::Pd, 11, &indices[1..2]),
                None,
                &mut planner,
            )
            .unwrap();
        assert_eq!(bits(&one), bits(&seeded[1..2]));
    }

    #[test]
    fn the_wind_blows_outside_the_window_and_the_prescribed_wind_adds_to_it() {
        let mut cfg = windy_cfg();
        cfg.gust.enabled = false;
        let engine = Engine::new(cfg).unwrap();
        let every = 1;
        let mut tr = engine.trace(every);
        let req = FlightRequest::new(ControllerKind::Pd, 0, &[0]);
        engine
            .fly::<f64>(&req, Some(&mut tr), &mut FftPlanner::new())
            .unwrap();
        let wind = engine.craft.wind();
        let mut max_x = 0.0_f64;
        let rows: Vec<&[f64]> = tr.data.chunks(tr.width).collect();
        let (last, flown) = rows.split_last().unwrap();
        // The closing row holds the last step's wind: no step follows it.
        for c in ["wind_x", "wind_y", "wind_z"] {
            assert_eq!(col(last, c), col(flown[flown.len() - 1], c));
        }
        for (k, row) in flown.iter().enumerate() {
            let z = col(row, "z");
            let m = wind.mean_at(z);
            let g = wind.discrete_gusts(k as u64);
            let w = [col(row, "wind_x"), col(row, "wind_y"), col(row, "wind_z")];
            assert_eq!(w, [m[0] + g[0], m[1] + g[1], m[2] + g[2]], "t = {}", row[0]);
            max_x = max_x.max(w[0]);
        }
        assert!(max_x > 2.0, "{max_x}");
        // A prescribed wind (zero here) adds to the mean wind and the discrete gusts.
        let steps = engine.steps;
        let engine = Engine::new(engine.cfg.clone())
            .unwrap()
            .with_wind(vec![[0.0; 3]; steps + 1])
            .unwrap();
        let mut tr2 = engine.trace(every);
        engine
            .fly::<f64>(&req, Some(&mut tr2), &mut FftPlanner::new())
            .unwrap();
        assert_eq!(tr.data, tr2.data);
    }
}
