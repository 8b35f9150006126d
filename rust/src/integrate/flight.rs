//! The flight loop: hold, step, check, accumulate, for every lane of a lane-set at once.

use super::engine::{Engine, FlightRequest, LaneResult, Realisation, MAX_LANES};
use super::entry::{LoopEntry, Sortie};
use super::steps::{Attitude, Ends, Leg, Rates, Release, Runaway, TensionNoise, Winds};
use super::trace::{Trace, TraceRow, MAX_ACTUATOR_SIGNALS};
use crate::control::{Flying, Laws, Sight};
use crate::gust::WindField;
use crate::lane::KernelOps;
use crate::metrics::{LawLimits, PhaseAccumulator, Views};
use crate::model::payload::Cue;
use crate::model::{
    dispatch, state_from_fn, Actuator, ActuatorModel, AnyVehicle, BodyKind, Inputs, Payload,
    PayloadView, Rigid, State, Tick, Trig, Vehicle, VehicleVisitor,
};
use crate::navigation::{Navigate, Navigation, NavigationParams};
use crate::rk4::rk4_advance;
use crate::start::LawStart;
use crate::trajectory::Reference;
use rustfft::FftPlanner;
use std::marker::PhantomData;
use std::sync::atomic::Ordering;

/// How often (in steps) a flight looks at the cancel flag.
const CANCEL_CHECK_STEPS: usize = 4096;

impl Engine {
    /// Fly on the vehicle kinds of the request (`model::dispatch`): dispatch to the loop
    /// compiled for them and lane type `L` (`LoopEntry::enter`). Each (lane type, vehicle) is
    /// its own function, so the compiler builds them apart (in parallel, each the size of one
    /// loop); the law is chosen inside it, once per step (`control::Flying`). Only `f64` values
    /// pass here: lane values exist only inside `enter`.
    pub(super) fn fly_kinds<L: LoopEntry>(
        &self,
        req: &FlightRequest,
        trace: Option<&mut Trace>,
        planner: &mut FftPlanner<f64>,
    ) -> Option<Vec<LaneResult>> {
        let own = [&self.realisation; MAX_LANES];
        let realisations: &[&Realisation] = match req.realisations {
            Some(c) => {
                assert_eq!(c.len(), L::LANES, "one realisation per lane");
                c
            }
            None => {
                self.own_start(req.kind); // solved here if no flight of the law came first
                &own[..L::LANES]
            }
        };
        let lead = &realisations[0].trajectory;
        if realisations.iter().any(|c| c.trajectory != *lead) {
            return self.fly_by_schedule::<L>(realisations, req, trace, planner);
        }
        /// The request, carried through the dispatch to `LoopEntry::enter`.
        struct Fly<'e, 'r, L> {
            engine: &'e Engine,
            sortie: Sortie<'r>,
            kinds: PhantomData<L>,
        }
        impl<L: LoopEntry> VehicleVisitor for Fly<'_, '_, L> {
            type Output = Option<Vec<LaneResult>>;
            fn visit<B: BodyKind, Pay: Payload, Act: Actuator, const N: usize>(
                self,
            ) -> Self::Output {
                L::enter::<B, Pay, Act, N>(self.engine, self.sortie)
            }
        }
        let fly = Fly {
            engine: self,
            sortie: Sortie {
                realisations,
                req,
                trace,
                planner,
            },
            kinds: PhantomData::<L>,
        };
        let cfg = &self.cfg;
        dispatch(cfg.vehicle.body, cfg.payload.model, cfg.actuator.model, fly)
    }

    /// A lane-set whose realisations fly different schedules (a dispersed winch's lowering
    /// lasts its own time; the loop gives the whole set one reference): flown once per
    /// schedule, the set filled with the lanes of that schedule and the rest padded with the
    /// first of them, each lane's result taken from its own schedule's flight. Lanes never mix,
    /// so each is bit for bit its flight alone; a batch that disperses the schedule pays up to
    /// one flight of the set per lane.
    fn fly_by_schedule<L: LoopEntry>(
        &self,
        realisations: &[&Realisation],
        req: &FlightRequest,
        trace: Option<&mut Trace>,
        planner: &mut FftPlanner<f64>,
    ) -> Option<Vec<LaneResult>> {
        assert!(trace.is_none(), "a trace is of one flight: one schedule");
        let mut out: Vec<Option<LaneResult>> = (0..L::LANES).map(|_| None).collect();
        for first in 0..L::LANES {
            if out[first].is_some() {
                continue;
            }
            let schedule = &realisations[first].trajectory;
            let lanes: Vec<usize> = (0..L::LANES)
                .map(|l| {
                    if realisations[l].trajectory == *schedule {
                        l
                    } else {
                        first
                    }
                })
                .collect();
            let set: Vec<&Realisation> = lanes.iter().map(|&l| realisations[l]).collect();
            let indices: Vec<u64> = lanes.iter().map(|&l| req.indices[l]).collect();
            let innovations: Option<Vec<&[f64]>> = req
                .innovations
                .map(|lane| lanes.iter().map(|&l| lane[l]).collect());
            let sub = FlightRequest {
                indices: &indices,
                realisations: Some(&set),
                innovations: innovations.as_deref(),
                ..*req
            };
            let results = self.fly_kinds::<L>(&sub, None, planner)?;
            for (l, r) in results.into_iter().enumerate() {
                if lanes[l] == l && out[l].is_none() {
                    out[l] = Some(r);
                }
            }
        }
        Some(
            out.into_iter()
                .map(|r| r.expect("every lane flown"))
                .collect(),
        )
    }

    /// Gather the lanes' realisations into lane-valued parameters and fly them: the body of
    /// every compiled loop (`LoopEntry::enter`), inlined there with everything it calls.
    #[inline(always)]
    pub(super) fn fly_vehicle<L, B, Pay, Act, const N: usize>(
        &self,
        sortie: Sortie<'_>,
    ) -> Option<Vec<LaneResult>>
    where
        L: Navigate,
        B: BodyKind,
        Pay: Payload,
        Act: Actuator,
    {
        let Sortie {
            realisations,
            req,
            trace,
            planner,
        } = sortie;
        let each: Vec<&AnyVehicle> = realisations.iter().map(|c| &c.vehicle).collect();
        // Mutable: a payload's winch target and hook change along the flight (`last_metres`).
        let mut vehicle = AnyVehicle::gather_on::<L, B, Pay, Act>(&each);
        self.fly_loop::<L, B, Pay::At<L>, Act::At<L>, N>(
            &mut vehicle,
            realisations,
            req,
            trace,
            planner,
        )
    }

    /// The flight loop's state at the start (`Start`): the lanes' initial states, their winds
    /// and metrics, the law of the request gathered one vehicle per lane (its memory at rest at
    /// the start) with its loops' schedule, and the sensors and filter where the laws fly the
    /// estimate (every lane or none; `record`: keep lane 0's record).
    #[inline(always)]
    fn start<'f, 'a, L, B, Pay, Act, const N: usize>(
        &self,
        vehicle: &Vehicle<L, Pay, Act, B>,
        realisations: &[&'f Realisation],
        req: &FlightRequest<'a>,
        record: bool,
    ) -> Start<'f, 'a, L, N>
    where
        L: Navigate,
        B: BodyKind,
        Pay: crate::model::PayloadModel<L>,
        Act: ActuatorModel<L>,
    {
        assert_eq!(self.vars.len(), N, "the engine's layout is the vehicle's");
        // Each lane's start for this law: its closed-loop equilibrium (`crate::start`).
        let starts: Vec<&LawStart> = realisations.iter().map(|c| c.start(req.kind)).collect();
        let x0: State<L, N> = state_from_fn(|i| L::from_fn(|l| starts[l].state[i]));
        let fields: Vec<&WindField> = realisations.iter().map(|c| &c.wind).collect();
        let laws: Vec<&LawLimits> = realisations.iter().map(|c| &c.law_limits).collect();
        let mut start = Attitude::<L, B>::of(&x0);
        let view0 = Vehicle::<L, Pay, Act, B>::rigid_with(&x0, start.euler(&x0));
        let trig0 = B::trig(&start.frame, &view0.att);
        let each: Vec<&Laws> = realisations.iter().map(|c| &c.laws).collect();
        let held: Vec<&[(usize, f64)]> = starts.iter().map(|c| c.held.as_slice()).collect();
        let navs: Vec<&NavigationParams> = realisations
            .iter()
            .filter_map(|c| c.navigation.as_ref())
            .collect();
        let g = vehicle.body.g;
        Start {
            s: x0,
            wind: Winds::<L>::new(realisations, req, &fields),
            acc: PhaseAccumulator::new(&self.phases, self.dt, self.decimation, self.steps, &laws),
            ends: Ends::new(L::LANES),
            runaway: Runaway::<L, N>::new::<B>(&self.vars, realisations),
            law: Flying::<L>::new(req.kind, &each, &Sight::blind(&view0, &trig0), &held),
            rates: Rates::new(self.cfg.controller.loop_steps(req.kind, self.dt)),
            nav: (!navs.is_empty()).then(|| {
                Navigation::<L>::starting_at(&navs, req.seed, req.indices, &view0, g, record)
            }),
        }
    }

    /// Fly the lane-set: step by step, the reference, the law, the wind, the payload's last
    /// metres, the metrics and the trace, then the RK4 step and the runaway checks; at the end
    /// each lane's result.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn fly_loop<L, B, Pay, Act, const N: usize>(
        &self,
        vehicle: &mut Vehicle<L, Pay, Act, B>,
        realisations: &[&Realisation],
        req: &FlightRequest,
        mut trace: Option<&mut Trace>,
        planner: &mut FftPlanner<f64>,
    ) -> Option<Vec<LaneResult>>
    where
        L: Navigate,
        B: BodyKind,
        Pay: crate::model::PayloadModel<L>,
        Act: ActuatorModel<L>,
    {
        type V<L, Pay, Act, B> = Vehicle<L, Pay, Act, B>;
        let Start {
            mut s,
            mut wind,
            mut acc,
            mut ends,
            runaway,
            mut law,
            mut rates,
            mut nav,
        } = self.start::<L, B, Pay, Act, N>(vehicle, realisations, req, trace.is_some());
        // One reference for the set: its lanes share a schedule (`fly_kinds`).
        let trajectory = &realisations[0].trajectory;
        let mut leg = Leg::<L>::new();
        let mut extra = [L::splat(0.0); MAX_ACTUATOR_SIGNALS];
        let extra = &mut extra[..Act::SIGNALS.len()];
        let mut release = Release::new();
        let mut noise = TensionNoise::new(req, &self.cfg);

        let reads_payload = law.reads_payload();
        // The actuators' command, held between the inner loop's updates.
        let mut held = None;
        let mut checked: Option<Attitude<L, B>> = None; // the runaway check's, of `s`
        for k in 0..=self.steps {
            let t = k as f64 * self.dt;
            leg.follow(trajectory, t, realisations);
            let r = &leg.r;
            let mut attitude = Attitude::checked_or_of(checked.take(), &s);
            let trig = attitude.frame;
            let tick = Tick { step: k, t };
            let att = euler_read(nav.as_ref(), k, trace.is_some(), &mut attitude, &s);
            let view = V::<L, Pay, Act, B>::rigid_with(&s, att);
            // What the law sees of the payload: only computed for a law that reads it.
            let payload = vehicle.payload_view_if(reads_payload, &s, &trig);
            let law_trig = truth_trig::<L, B>(nav.is_none(), &trig, &view.att);
            let seen = sight(nav.as_mut(), k, &view, law_trig.as_ref(), payload.as_ref());
            let due = rates.due(k);
            let u = law.step(&seen, r, tick, due);
            let cmd = mixer(&mut held, due.rate, &vehicle.actuator, &u, tick);
            let w = wind.sample(k, k == self.steps && k > 0, &view, realisations);
            let cue = cue(t, self.dt, &leg, nav.as_ref(), &view, &mut noise);
            let events = vehicle.payload.last_metres(&s, &trig, &cue);
            // The payload's record of the step and its RK4 step's first stage, together.
            let (k1, out) = vehicle.derivative_and_outputs(&s, &trig, &cmd, &w, u.u1);
            let axes = crate::model::Frame::axes(&trig);
            let vel = V::<L, Pay, Act, B>::LAYOUT.vel();
            let a = [k1[vel], k1[vel + 1], k1[vel + 2]];
            let (nav_error, navigating) = navigation_error(nav.as_mut(), &a, &axes, &view.pos);
            // The position error, from the rigid view the law read (the same state).
            let e = position_error(r, &view.pos);
            let last = release.sample(events, &leg, &e, t, out.swing);
            // What the metrics derive their signals from (`metrics!`); |a| for the trace.
            let views = Views {
                t,
                rigid: &view,
                axes,
                g: vehicle.body.g,
                out: &out,
                r,
                e: &e,
                line: &leg.line,
                saturated: vehicle.actuator.saturated(&cmd),
                last: &last,
                nav_error,
                navigating,
            };
            let accel = acc.sample(k, &views).max_accel;
            if let Some(tr) = trace.as_deref_mut() {
                // The trace ends where its lane diverged: nothing after `diverged_at` is recorded.
                if k % tr.every == 0 && ends.diverged_at[0].is_nan() {
                    let held = Held {
                        cmd: &cmd,
                        u: &u,
                        w: &w,
                        trig: &trig,
                        accel,
                    };
                    record(tr, vehicle, &s, &views, &held, nav.as_ref(), extra);
                }
            }
            if k == self.steps {
                break;
            }
            rk4_advance(vehicle, &mut s, &trig, &k1, &cmd, &w, self.dt);

            let (ok, attitude) = runaway.check::<B>(&s);
            if ok == L::ALL {
                checked = attitude;
            } else {
                // Retired lanes are parked on their initial state: the next step derives its own.
                let tilt = Attitude::angles_of(attitude, &s);
                #[rustfmt::skip]
                ends.retire(ok, t, self.dt, tilt, &mut s, &mut law, realisations, &self.vars);
                if ends.alive == 0 {
                    break;
                }
            }
            if cancelled(req, k) {
                return None;
            }
        }
        if let (Some(tr), Some(n)) = (trace, nav) {
            tr.navigation = n.finish();
        }
        Some(self.lane_results(&acc, &ends, planner, req.want_spectra))
    }

    /// Each lane's metrics and spectra, NaN over the phases its divergence cut short.
    #[inline(always)]
    fn lane_results<L: KernelOps>(
        &self,
        acc: &PhaseAccumulator<L>,
        ends: &Ends,
        planner: &mut FftPlanner<f64>,
        want_spectra: bool,
    ) -> Vec<LaneResult> {
        let n_phase = self.phases.len();
        (0..L::LANES)
            .map(|lane| {
                let mut spectra = vec![Vec::new(); if want_spectra { n_phase } else { 0 }];
                let mut metrics = acc.finish(
                    lane,
                    planner,
                    want_spectra.then_some(spectra.as_mut_slice()),
                );
                if !ends.diverged_at[lane].is_nan() {
                    // Phases that ended before the first bad step are real; NaN the rest
                    // (over the whole bin grid: the flight may have stopped early).
                    let bad = (ends.diverged_at[lane] / self.dt).round() as usize;
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
                    diverged_at: ends.diverged_at[lane],
                    status: ends.status[lane],
                    spectra,
                }
            })
            .collect()
    }
}

/// The state's sines and cosines as the laws read them (`frame`, the angles `att`), made only
/// where they read the state (`reads_state`: on the estimate, the navigation's own), through
/// `within`: compiled for the loop's instruction set even where it is left out of the loop's
/// line (a bare closure left out of line was compiled without it, and made the flights on
/// their state 1.5x slower), and kept out of the line of the flights on their estimate, a few
/// per cent faster so (docs/performance.md, "The filter's step made cheaper").
#[inline(always)]
fn truth_trig<L: Navigate, B: BodyKind>(
    reads_state: bool,
    frame: &B::Frame<L>,
    att: &[L; 3],
) -> Option<Trig<L>> {
    if reads_state {
        Some(att[0].within(
            #[inline(always)]
            |_| B::trig(frame, att),
        ))
    } else {
        None
    }
}

/// The true Euler angles at step `k` where something reads them (the laws where they read the
/// state, the navigation's heading sample, the trace; and the paper's body, whose angles are
/// states, free to read), else NaN: a reader this step did not foresee would make the
/// flight's numbers NaN, never silently wrong.
#[inline(always)]
fn euler_read<L: Navigate, B: BodyKind, const N: usize>(
    nav: Option<&Navigation<L>>,
    k: usize,
    tracing: bool,
    attitude: &mut Attitude<L, B>,
    s: &State<L, N>,
) -> [L; 3] {
    let reads = B::DERIVED.is_empty()
        || tracing
        || match nav {
            Some(n) => n.reads_attitude(k),
            None => true,
        };
    if reads {
        attitude.euler(s)
    } else {
        [L::splat(f64::NAN); 3]
    }
}

/// What the laws read at step `k`: the navigation's estimate where it flies (the IMU sampled
/// on its steps, its sums added to between them), else the state itself (`view`, and its
/// sines and cosines `trig`, made only then).
#[inline(always)]
fn sight<'a, L: Navigate>(
    nav: Option<&'a mut Navigation<L>>,
    k: usize,
    view: &'a Rigid<L>,
    trig: Option<&'a Trig<L>>,
    payload: Option<&'a PayloadView<L>>,
) -> Sight<'a, L> {
    match nav {
        Some(n) => {
            if n.due(k) {
                L::sense(n, k, view);
            } else {
                n.accumulate(view);
            }
            let n: &'a Navigation<L> = n;
            Sight {
                rigid: &n.estimate,
                trig: &n.trig,
                payload,
            }
        }
        None => Sight {
            rigid: view,
            trig: trig.expect("made where the laws read the state"),
            payload,
        },
    }
}

/// What a trace row reads of the step beside its `Views`: the actuators' command `cmd` and
/// the law's `u` held over it, the wind `w`, the body's frame, the payload's |a|.
struct Held<'a, L, C, F> {
    cmd: &'a C,
    u: &'a Inputs<L>,
    w: &'a [L; 3],
    trig: &'a F,
    accel: L,
}

/// The trace's row of the step `views` describes (state `s`): the actuator's own columns
/// (into `extra`) and the navigation's, gathered here.
#[inline(always)]
fn record<L, B, Pay, Act, const N: usize>(
    tr: &mut Trace,
    vehicle: &Vehicle<L, Pay, Act, B>,
    s: &State<L, N>,
    views: &Views<L>,
    held: &Held<L, Act::Command, B::Frame<L>>,
    nav: Option<&Navigation<L>>,
    extra: &mut [L],
) where
    L: Navigate,
    B: BodyKind,
    Pay: crate::model::PayloadModel<L>,
    Act: ActuatorModel<L>,
{
    let lay = Vehicle::<L, Pay, Act, B>::LAYOUT;
    vehicle.actuator.signals(held.cmd, s, lay.actuator(), extra);
    let nav_columns = nav.map(|n| n.columns());
    let nav_row: &[f64] = match &nav_columns {
        Some(c) => c,
        None => &[],
    };
    let (view, w) = (views.rigid, held.w);
    tr.push(&TraceRow {
        t: views.t,
        s,
        derived: &view.att[..B::DERIVED.len()],
        r: views.r,
        u: held.u,
        w,
        e_o: views.out.e_o,
        accel_c: held.accel,
        drag_z: crate::model::Frame::drag(held.trig, &vehicle.body, &view.vel, w)[2],
        swing: views.out.swing,
        tension: views.out.tension,
        extra,
        nav: nav_row,
    });
}

/// The flight loop's state at its first step (`Engine::start`).
struct Start<'f, 'a, L: Navigate, const N: usize> {
    s: State<L, N>,
    wind: Winds<'f, 'a, L>,
    acc: PhaseAccumulator<L>,
    ends: Ends,
    runaway: Runaway<L, N>,
    law: Flying<L>,
    rates: Rates,
    nav: Option<Navigation<L>>,
}

/// The route's cue to the payload at `t`, before the step (a hook that opens now is open
/// over the step): the lowering due, where the vehicle knows it is (its estimate where it flies
/// on its senses, else the state's `view`): its height and its distance from the lowering's
/// point, the load cell's normal.
#[inline(always)]
fn cue<L: Navigate>(
    t: f64,
    dt: f64,
    leg: &Leg<L>,
    nav: Option<&Navigation<L>>,
    view: &Rigid<L>,
    noise: &mut TensionNoise,
) -> Cue<L> {
    let known = match nav {
        Some(n) => &n.estimate.pos,
        None => &view.pos,
    };
    Cue {
        t,
        dt,
        payout: leg.due,
        off_drop: leg.off_drop(known),
        height: known[2],
        draw: noise.draw(),
    }
}

/// The navigation's position error (estimate less the true `pos`) after the step's
/// acceleration `a` (world axes; the body's `axes`) went into its accelerometer, and 1 where
/// the laws fly the estimate; zeros where they read the state.
#[inline(always)]
fn navigation_error<L: Navigate>(
    nav: Option<&mut Navigation<L>>,
    a: &[L; 3],
    axes: &[[L; 3]; 3],
    pos: &[L; 3],
) -> ([L; 3], L) {
    let zero = L::splat(0.0);
    match nav {
        Some(n) => (n.error_after(a, axes, pos), L::splat(1.0)),
        None => ([zero; 3], zero),
    }
}

/// m, the position error p_ref - p of the reference `r` at the true position `pos`.
#[inline(always)]
fn position_error<L: Navigate>(r: &Reference, pos: &[L; 3]) -> [L; 3] {
    [
        pos[0] * -1.0 + r.pos[0],
        pos[1] * -1.0 + r.pos[1],
        pos[2] * -1.0 + r.pos[2],
    ]
}

/// Whether the request was cancelled, looked at every `CANCEL_CHECK_STEPS` steps.
#[inline(always)]
fn cancelled(req: &FlightRequest, k: usize) -> bool {
    k.is_multiple_of(CANCEL_CHECK_STEPS) && req.cancel.is_some_and(|c| c.load(Ordering::Relaxed))
}

/// The actuators' command over the step: the mixer runs with the inner loop (`rate` due;
/// every loop is due at the first step), its command `held` between the loop's updates.
#[inline(always)]
fn mixer<L: Navigate, Act: ActuatorModel<L>>(
    held: &mut Option<Act::Command>,
    rate: bool,
    actuator: &Act,
    u: &Inputs<L>,
    tick: Tick,
) -> Act::Command {
    let cmd = match *held {
        Some(c) if !rate => c,
        _ => actuator.command(u, tick),
    };
    *held = Some(cmd);
    cmd
}
