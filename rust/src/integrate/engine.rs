//! The compiled scenario (`Engine`): what may differ between realisations (`Realisation`), a request
//! to the flight loop (`FlightRequest`) and what it gives back (`LaneResult`), and the engine's
//! public methods.

use super::status::ExitStatus;
use super::trace::{trace_columns, Trace};
use crate::control::{ControllerKind, Laws};
use crate::gust::{Kinematics, WindField};
use crate::lane::isa::Isa;
use crate::metrics::{LawLimits, N_METRICS};
use crate::model::{
    dispatch, state_vars, Actuator, AnyVehicle, BodyKind, Payload, StateVar, VehicleVisitor,
};
use crate::navigation::{NavigationParams, NAVIGATION_COLUMNS};
use crate::scenario::{Config, ConfigError, Trim};
use crate::start::{law_start, LawStart};
use crate::trajectory::{phase_steps, PhaseSteps, Trajectory};
use std::sync::atomic::AtomicBool;
use std::sync::OnceLock;

/// What may differ between realisations: one vehicle's physical parameters, controllers,
/// wind field, initial state and runaway bounds, built from one validated `Config`. A fixed
/// scenario has one (`Engine::realisation`); a dispersed batch builds one per realisation and the
/// flight loop carries them one per lane.
#[derive(Clone)]
pub struct Realisation {
    pub vehicle: AnyVehicle,
    /// Every controller kind's law (`Laws::get`): a batch flies each through the same gusts.
    pub laws: Laws,
    pub(super) wind: WindField,
    /// The initial state (the layout's order): the plant's trim (or rest), the cross-track
    /// line's start and where a retired lane is parked.
    pub x0: Vec<f64>,
    /// Whether `x0` balances the start's steady wind: false where `initial.trim = "wind"`
    /// finds no trim (the vehicle cannot hover in that wind) and it starts at rest instead.
    pub balanced: bool,
    /// Each law's start (`ControllerKind::ALL`'s order): its closed-loop equilibrium in the
    /// start's steady wind (`crate::start`), solved when the realisation is built for the laws
    /// it flies (`Realisation::for_laws`), or for the engine's own on first use
    /// (`Engine::own_start`); unset for a law no one asked for.
    starts: Vec<OnceLock<LawStart>>,
    /// `divergence.max_distance`, `max_tilt`, `max_speed`, `max_rate` (m, rad, m/s, rad/s), in
    /// the order of `Bound`.
    pub(super) limits: [f64; 4],
    /// m, the flight ends below this z (`ground.*`; minus infinity when off).
    pub(super) floor: f64,
    /// The laws' limits the metrics may compare against (`metrics::LawLimits`).
    pub(super) law_limits: LawLimits,
    /// The sensors and the filter the laws read (`None`: the laws read the state).
    pub(super) navigation: Option<NavigationParams>,
    /// The reference and the route's schedule: a realisation's own (a dispersed winch's
    /// lowering lasts its own time, and every segment after it moves), so that a batch row
    /// flies what `simulate(realisation=i)` flies.
    pub(super) trajectory: Trajectory,
}

impl Realisation {
    /// The realisation of a validated config (`Config::validate` has run).
    pub fn new(cfg: &Config) -> Result<Self, ConfigError> {
        Self::with_wind_of(cfg, None)
    }

    /// The realisation of `cfg`, with `other`'s gust field if given (the same `gust.*` values and
    /// step: its discretised filters are reused rather than rebuilt).
    pub fn with_wind_of(cfg: &Config, other: Option<&Realisation>) -> Result<Self, ConfigError> {
        Self::for_laws(cfg, other, ControllerKind::ALL)
    }

    /// `with_wind_of`, with the starts of the laws in `kinds` alone (a batch's realisation:
    /// each start is a Newton solve on the closed loop, most of a dispersed flight's set-up).
    pub fn for_laws(
        cfg: &Config,
        other: Option<&Realisation>,
        kinds: &[ControllerKind],
    ) -> Result<Self, ConfigError> {
        let vehicle = AnyVehicle::new(&cfg.model_context());
        let wind = match other {
            Some(c) => c.wind.clone(),
            None => WindField::new(&cfg.wind_context())?,
        };
        let (x0, balanced) = initial_state(&vehicle, cfg, &wind)?;
        let d = &cfg.divergence;
        let realisation = Self {
            vehicle,
            starts: ControllerKind::ALL
                .iter()
                .map(|_| OnceLock::new())
                .collect(),
            laws: Laws::new(&cfg.control_context()),
            wind,
            x0,
            balanced,
            limits: [d.max_distance, d.max_tilt, d.max_speed, d.max_rate],
            floor: cfg.ground.floor(),
            law_limits: LawLimits::of(&cfg.controller),
            navigation: NavigationParams::of(&cfg.navigation, &cfg.sensors, cfg.integrator.dt)?,
            trajectory: Trajectory::new(&cfg.context()),
        };
        for &kind in kinds {
            realisation.start_of(cfg, kind);
        }
        Ok(realisation)
    }

    /// Law `kind`'s start in this realisation of `cfg` (the config it was built from), solved
    /// on first use. Where the vehicle cannot hover in the start's wind (no plant trim: it
    /// starts level at rest) there is no balance for any law to start near: each starts there,
    /// flown and flagged as the plant's start is, none refused for its own want of one.
    fn start_of(&self, cfg: &Config, kind: ControllerKind) -> &LawStart {
        self.starts[kind as usize].get_or_init(|| {
            if !self.balanced {
                return LawStart::plant(&self.x0);
            }
            law_start(cfg, kind, &self.x0, &|z| trim_wind(cfg, &self.wind, z))
        })
    }
}

impl Realisation {
    /// The gust field.
    pub fn wind(&self) -> &WindField {
        &self.wind
    }

    /// Where law `kind` starts (`crate::start`).
    pub fn start(&self, kind: ControllerKind) -> &LawStart {
        self.starts[kind as usize]
            .get()
            .expect("a realisation is built with the start of each law it flies")
    }
}

/// The state a flight of `cfg` starts from, at `initial.*`: with `initial.trim = "wind"`
/// trimmed in the steady wind `wind` blows at the start (`start_wind`), with `"rest"` (or in
/// still air) at rest, payload and actuators at hover. A vehicle that cannot hover in the
/// start's wind (no trim exists: too much drag, too little thrust) starts at rest too, and its
/// flight shows what the wind does to it (it is flown and flagged, as any other). Returns the
/// state and whether it balances the start's wind (false only for that vehicle:
/// `Realisation::balanced`).
pub fn initial_state(
    parts: &AnyVehicle,
    cfg: &Config,
    wind: &WindField,
) -> Result<(Vec<f64>, bool), ConfigError> {
    struct Start<'a>(&'a AnyVehicle, &'a Config, [f64; 3]);
    impl VehicleVisitor for Start<'_> {
        type Output = (Vec<f64>, bool);
        fn visit<B: BodyKind, Pay: Payload, Act: Actuator, const N: usize>(self) -> Self::Output {
            let Start(parts, cfg, w) = self;
            let i = &cfg.initial;
            let v = parts.vehicle_on::<B, Pay, Act>();
            match v.trim_state::<N>(i.position, i.attitude, w) {
                Ok(s) => (s.to_vec(), true),
                Err(_) => (v.rest_state::<N>(i.position, i.attitude).to_vec(), false),
            }
        }
    }
    let w = trim_wind(cfg, wind, cfg.initial.position[2]);
    Ok(dispatch(
        cfg.vehicle.body,
        cfg.payload.model,
        cfg.actuator.model,
        Start(parts, cfg, w),
    ))
}

/// m/s, the wind a start of `cfg` at altitude `z` is trimmed in: `start_wind` with
/// `initial.trim = "wind"`, none with `"rest"`. The one rule for the state at the start, each
/// law's closed-loop start and what the engine reports.
pub fn trim_wind(cfg: &Config, wind: &WindField, z: f64) -> [f64; 3] {
    match cfg.initial.trim {
        Trim::Wind => start_wind(wind, z),
        Trim::Rest => [0.0; 3],
    }
}

/// m/s, the steady wind at the start, at altitude `z0`: every deterministic source at step 0
/// and, if the turbulence's window is open then, its mean (not its random part).
pub fn start_wind(wind: &WindField, z0: f64) -> [f64; 3] {
    let kin = Kinematics {
        z: z0,
        vel: [0.0; 3],
    };
    let mut w = wind.deterministic(0, &kin);
    if wind.is_active(0) {
        let m = wind.mean_wind();
        for i in 0..3 {
            w[i] += m[i];
        }
    }
    w
}

/// One request to the flight loop: which law, and for a dispersed batch the realisations, one
/// per lane (`None`: the engine's own, in every lane).
#[derive(Clone, Copy)]
pub struct FlightRequest<'a> {
    pub kind: ControllerKind,
    pub seed: u64,
    pub indices: &'a [u64],
    pub realisations: Option<&'a [&'a Realisation]>,
    pub want_spectra: bool,
    pub cancel: Option<&'a AtomicBool>,
    /// Per lane, the turbulence's innovations to fly instead of the seeded stream of
    /// (`seed`, index): a flight as a function of its standard normals (rare events).
    pub innovations: Option<&'a [&'a [f64]]>,
}

impl<'a> FlightRequest<'a> {
    /// The engine's own realisation in every lane, no spectra, no cancel flag.
    pub fn new(kind: ControllerKind, seed: u64, indices: &'a [u64]) -> Self {
        Self {
            kind,
            seed,
            indices,
            realisations: None,
            want_spectra: false,
            cancel: None,
            innovations: None,
        }
    }
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

/// A validated scenario turned into everything the loop needs, built once and shared read-only.
#[derive(Clone)]
pub struct Engine {
    pub cfg: Config,
    /// The scenario's own vehicle (every realisation's, unless dispersed).
    pub realisation: Realisation,
    /// The states, in order (names, axes, runaway bounds).
    pub vars: Vec<StateVar>,
    pub(super) phases: Vec<PhaseSteps>,
    pub steps: usize,
    pub dt: f64,
    pub(super) decimation: usize,
    /// The instruction set the flight loop runs on (`Isa::active()` unless set otherwise).
    pub isa: Isa,
    /// The opt-in fused mode (`with_fused`): the batch path fuses multiply-adds. Off by
    /// default; its numbers are not bit-identical to the default mode's, nor across
    /// instruction sets. Single flights (`fly::<f64>`) never fuse.
    pub fused: bool,
}

/// Most lanes a `Lane` type may carry (sizes the per-step wind buffer; the widest lane-set).
pub const MAX_LANES: usize = crate::gust::lanes::MAX_LANES;

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
            // Each law's start solved when a flight first asks for it (`own_start`): a Newton
            // solve on the closed loop each, most of a compile where the wind blows.
            realisation: Realisation::for_laws(&cfg, None, &[])?,
            vars: state_vars(cfg.vehicle.body, cfg.payload.model, cfg.actuator.model),
            phases: phase_steps(&cfg.context()),
            steps,
            dt,
            decimation,
            cfg,
            isa,
            fused: false,
        })
    }

    /// Whether law `kind` may fly the scenario: an error naming the keys where its start has
    /// no equilibrium at its reference (`LawStart::refused`).
    pub fn check_start(&self, kind: ControllerKind) -> Result<(), ConfigError> {
        match &self.own_start(kind).refused {
            Some(e) => Err(e.clone()),
            None => Ok(()),
        }
    }

    /// Law `kind`'s start in the engine's own realisation, solved on first use.
    pub fn own_start(&self, kind: ControllerKind) -> &LawStart {
        self.realisation.start_of(&self.cfg, kind)
    }

    /// Unit normals one flight's turbulence draws (see `WindField::innovations`).
    pub fn innovations(&self) -> usize {
        let wind = self.realisation.wind();
        wind.innovations(wind.field_steps(self.steps))
    }

    /// The innovations realisation `index` of `seed` draws.
    pub fn innovations_of(&self, seed: u64, index: u64) -> Vec<f64> {
        let wind = self.realisation.wind();
        wind.innovations_of(seed, index, wind.field_steps(self.steps))
    }

    /// Trace columns after `t`.
    pub fn trace_columns(&self) -> Vec<&'static str> {
        let mut columns = trace_columns(
            self.cfg.vehicle.body,
            self.cfg.payload.model,
            self.cfg.actuator.model,
        );
        if self.realisation.navigation.is_some() {
            columns.extend(NAVIGATION_COLUMNS);
        }
        columns
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
        // The laws' starts are the scenario's, in its own steady wind: solved before it goes.
        for &kind in ControllerKind::ALL {
            self.own_start(kind);
        }
        // A wind source of the realisation's field (`gust/prescribed.rs`), the turbulence off.
        self.realisation.wind = self.realisation.wind.clone().prescribed(wind);
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
    pub fn lanes_per_set(&self) -> usize {
        self.isa.lane_count()
    }
}
