//! The flight loop: hold, step, check, accumulate, for every lane of a lane-set at once.

use super::engine::{Engine, FlightRequest, LaneResult, Realisation, MAX_LANES};
use super::entry::LoopEntry;
use super::rk4::rk4_advance;
use super::steps::{Attitude, Ends, Leg, Rates, Release, Runaway, TensionNoise, Winds};
use super::trace::{Trace, TraceRow, MAX_ACTUATOR_SIGNALS};
use crate::control::{Flying, Laws, Sight};
use crate::gust::WindField;
use crate::lane::KernelOps;
use crate::metrics::{LawLimits, PhaseAccumulator, Views};
use crate::model::payload::Cue;
use crate::model::{
    dispatch, state_from_fn, Actuator, ActuatorModel, AnyVehicle, BodyKind, Payload, Rigid, State,
    Tick, Vehicle, VehicleVisitor,
};
use crate::navigation::{Navigate, Navigation, NavigationParams};
use crate::start::LawStart;
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
            None => &own[..L::LANES],
        };
        /// The request, carried through the dispatch to `LoopEntry::enter`.
        struct Fly<'e, 'r, 't, L> {
            engine: &'e Engine,
            realisations: &'r [&'r Realisation],
            req: &'r FlightRequest<'r>,
            trace: Option<&'t mut Trace>,
            planner: &'t mut FftPlanner<f64>,
            kinds: PhantomData<L>,
        }
        impl<L: LoopEntry> VehicleVisitor for Fly<'_, '_, '_, L> {
            type Output = Option<Vec<LaneResult>>;
            fn visit<B: BodyKind, Pay: Payload, Act: Actuator, const N: usize>(
                self,
            ) -> Self::Output {
                L::enter::<B, Pay, Act, N>(
                    self.engine,
                    self.realisations,
                    self.req,
                    self.trace,
                    self.planner,
                )
            }
        }
        let fly = Fly {
            engine: self,
            realisations,
            req,
            trace,
            planner,
            kinds: PhantomData::<L>,
        };
        let cfg = &self.cfg;
        dispatch(cfg.vehicle.body, cfg.payload.model, cfg.actuator.model, fly)
    }

    /// Gather the lanes' realisations into lane-valued parameters and fly them: the body of
    /// every compiled loop (`LoopEntry::enter`), inlined there with everything it calls.
    #[inline(always)]
    pub(super) fn fly_vehicle<L, B, Pay, Act, const N: usize>(
        &self,
        realisations: &[&Realisation],
        req: &FlightRequest,
        trace: Option<&mut Trace>,
        planner: &mut FftPlanner<f64>,
    ) -> Option<Vec<LaneResult>>
    where
        L: Navigate,
        B: BodyKind,
        Pay: Payload,
        Act: Actuator,
    {
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
        assert_eq!(self.vars.len(), N, "the engine's layout is the vehicle's");
        // Each lane's start for this law: its closed-loop equilibrium (`crate::start`).
        let starts: Vec<&LawStart> = realisations.iter().map(|c| c.start(req.kind)).collect();
        let x0: State<L, N> = state_from_fn(|i| L::from_fn(|l| starts[l].state[i]));
        let mut s = x0;
        let fields: Vec<&WindField> = realisations.iter().map(|c| &c.wind).collect();
        let mut wind = Winds::<L>::new(realisations, req, &fields);
        let laws: Vec<&LawLimits> = realisations.iter().map(|c| &c.law_limits).collect();
        let mut acc =
            PhaseAccumulator::<L>::new(&self.phases, self.dt, self.decimation, self.steps, &laws);
        let mut ends = Ends::new(L::LANES);
        let runaway = Runaway::<L, N>::new::<B>(&self.vars, realisations);
        let mut leg = Leg::<L>::new();
        let mut extra = [L::splat(0.0); MAX_ACTUATOR_SIGNALS];
        let extra = &mut extra[..Act::SIGNALS.len()];
        // The law of the request, gathered one vehicle per lane, its memory at rest at the
        // start; its loops' schedule (`Rates`).
        let start = Attitude::<L, B>::of(&x0);
        let view0 = V::<L, Pay, Act, B>::rigid_with(&x0, start.euler);
        let trig0 = B::trig(&start.frame, &view0.att);
        let each: Vec<&Laws> = realisations.iter().map(|c| &c.laws).collect();
        let held: Vec<&[(usize, f64)]> = starts.iter().map(|c| c.held.as_slice()).collect();
        let mut law = Flying::<L>::new(req.kind, &each, &Sight::blind(&view0, &trig0), &held);
        let mut rates = Rates::new(self.cfg.controller.loop_steps(req.kind, self.dt));
        let mut release = Release::new();
        // The sensors and the filter, where the laws fly the estimate (every lane or none).
        let navs: Vec<&NavigationParams> = realisations
            .iter()
            .filter_map(|c| c.navigation.as_ref())
            .collect();
        let mut nav = (!navs.is_empty()).then(|| {
            assert_eq!(navs.len(), L::LANES, "every lane of a set navigates alike");
            let truths: Vec<Rigid<f64>> = (0..L::LANES)
                .map(|l| Rigid {
                    pos: view0.pos.map(|x| x.lane(l)),
                    att: view0.att.map(|x| x.lane(l)),
                    vel: view0.vel.map(|x| x.lane(l)),
                    rate: view0.rate.map(|x| x.lane(l)),
                })
                .collect();
            let g = vehicle.body.g;
            Navigation::<L>::new(&navs, req.seed, req.indices, &truths, g, trace.is_some())
        });
        let mut noise = TensionNoise::new(req, &self.cfg);

        let reads_payload = law.reads_payload();
        // The actuators' command, held between the inner loop's updates.
        let mut held = None;
        // The attitude the last runaway check derived for this state, if it did.
        let mut checked: Option<Attitude<L, B>> = None;
        for k in 0..=self.steps {
            let t = k as f64 * self.dt;
            leg.follow(&self.trajectory, t, realisations);
            let r = &leg.r;
            // A match, not `Option::unwrap_or_else`: nothing here may be left out of line.
            let attitude = match checked.take() {
                Some(a) => a,
                None => Attitude::of(&s),
            };
            let trig = attitude.frame;
            let tick = Tick { step: k, t };
            let view = V::<L, Pay, Act, B>::rigid_with(&s, attitude.euler);
            // What the law sees of the payload: only computed for a law that reads it.
            let payload = if reads_payload {
                Some(vehicle.payload.view(&s, &trig))
            } else {
                None
            };
            let law_trig = B::trig(&trig, &view.att);
            // What the laws read: the state, or the navigation's estimate of it.
            let seen = match nav.as_mut() {
                Some(n) => {
                    if n.due(k) {
                        L::sense(n, k, &view);
                    } else {
                        n.accumulate(&view);
                    }
                    Sight {
                        rigid: &n.estimate,
                        trig: &n.trig,
                        payload: payload.as_ref(),
                    }
                }
                None => Sight {
                    rigid: &view,
                    trig: &law_trig,
                    payload: payload.as_ref(),
                },
            };
            let due = rates.due(k);
            let u = law.step(&seen, r, tick, due);
            // The mixer runs with the inner loop (every loop is due at the first step).
            let cmd = match held {
                Some(c) if !due.rate => c,
                _ => vehicle.actuator.command(&u, tick),
            };
            held = Some(cmd);
            let w = wind.sample(k, k == self.steps && k > 0, &view, realisations);
            // The route's cue to the payload and its events, before the step (a hook that opens
            // now is open over the step).
            let cue = Cue {
                t,
                dt: self.dt,
                payout: leg.payout,
                // The height the vehicle knows: its estimate where it flies on its senses.
                height: match nav.as_ref() {
                    Some(n) => n.estimate.pos[2],
                    None => view.pos[2],
                },
                draw: noise.draw(),
            };
            let events = vehicle.payload.last_metres(&s, &trig, &cue);
            // The payload's record of the step and its RK4 step's first stage, together.
            let (k1, out) = vehicle.derivative_and_outputs(&s, &trig, &cmd, &w, u.u1);
            let axes = crate::model::Frame::axes(&trig);
            let zero = L::splat(0.0);
            let (nav_error, navigating) = match nav.as_mut() {
                Some(n) => {
                    let v = V::<L, Pay, Act, B>::LAYOUT.vel();
                    n.accelerometer(&[k1[v], k1[v + 1], k1[v + 2]], &axes);
                    let est = &n.estimate.pos;
                    let err = [0, 1, 2].map(|i| est[i] - view.pos[i]);
                    (err, L::splat(1.0))
                }
                None => ([zero; 3], zero),
            };
            // The position error, from the rigid view the law read (the same state).
            let e = [
                view.pos[0] * -1.0 + r.pos[0],
                view.pos[1] * -1.0 + r.pos[1],
                view.pos[2] * -1.0 + r.pos[2],
            ];
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
                    let lay = V::<L, Pay, Act, B>::LAYOUT;
                    vehicle.actuator.signals(&cmd, &s, lay.actuator(), extra);
                    let derived = &view.att[..B::DERIVED.len()];
                    let nav_columns = nav.as_ref().map(|n| n.columns());
                    let nav_row: &[f64] = match &nav_columns {
                        Some(c) => c,
                        None => &[],
                    };
                    tr.push(&TraceRow {
                        t,
                        s: &s,
                        derived,
                        r,
                        u: &u,
                        w: &w,
                        e_o: out.e_o,
                        accel_c: accel,
                        drag_z: crate::model::Frame::drag(&trig, &vehicle.body, &view.vel, &w)[2],
                        swing: out.swing,
                        tension: out.tension,
                        extra,
                        nav: nav_row,
                    });
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
                let tilt = attitude.map(|a| a.euler);
                #[rustfmt::skip]
                ends.retire(ok, t, self.dt, tilt, &mut s, &mut law, realisations, &self.vars);
                if ends.alive == 0 {
                    break;
                }
            }
            if k % CANCEL_CHECK_STEPS == 0 && req.cancel.is_some_and(|c| c.load(Ordering::Relaxed))
            {
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
