//! The flight loop: hold, step, check, accumulate, for every lane of a lane-set at once.

use super::*;

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

/// How often (in steps) a flight looks at the cancel flag.
const CANCEL_CHECK_STEPS: usize = 4096;

/// s, the window after the hook opens over which the vehicle's height change is taken
/// (`release_height_change`).
pub const RELEASE_WINDOW: f64 = 5.0;

impl Engine {
    /// Fly on the vehicle kinds (`model::dispatch`) and law (`control::dispatch`) of the
    /// request: dispatch to the loop compiled for them and lane type `L` (`LoopEntry::enter`).
    /// Each (lane type, vehicle, law) is its own function, so the compiler builds them apart
    /// (in parallel, each the size of one loop, not one function holding all sixteen). Only
    /// `f64` values pass here: lane values exist only inside `enter`.
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
        /// The request, carried through both dispatches to `LoopEntry::enter`.
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
                let kind = self.req.kind;
                let law = Law::<L, B, Pay, Act, N> {
                    fly: self,
                    kinds: PhantomData,
                };
                crate::control::dispatch(kind, law)
            }
        }
        struct Law<'e, 'r, 't, L, B, Pay, Act, const N: usize> {
            fly: Fly<'e, 'r, 't, L>,
            kinds: PhantomData<(B, Pay, Act)>,
        }
        impl<L: LoopEntry, B: BodyKind, Pay: Payload, Act: Actuator, const N: usize>
            ControllerVisitor for Law<'_, '_, '_, L, B, Pay, Act, N>
        {
            type Output = Option<Vec<LaneResult>>;
            fn visit<C: Controller>(self) -> Self::Output {
                let f = self.fly;
                L::enter::<B, Pay, Act, C, N>(f.engine, f.realisations, f.req, f.trace, f.planner)
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

    /// Gather the lanes' realisations into lane-valued parameters and fly law `C`: the body of
    /// every compiled loop (`LoopEntry::enter`), inlined there with everything it calls.
    #[inline(always)]
    pub(super) fn fly_law<L, B, Pay, Act, C, const N: usize>(
        &self,
        realisations: &[&Realisation],
        req: &FlightRequest,
        trace: Option<&mut Trace>,
        planner: &mut FftPlanner<f64>,
    ) -> Option<Vec<LaneResult>>
    where
        L: KernelOps,
        B: BodyKind,
        Pay: Payload,
        Act: Actuator,
        C: Controller,
    {
        let each: Vec<&AnyVehicle> = realisations.iter().map(|c| &c.vehicle).collect();
        // Mutable: a payload's winch target and hook change along the flight (`last_metres`).
        let mut vehicle = AnyVehicle::gather_on::<L, B, Pay, Act>(&each);
        let kind = req.kind;
        let laws: Vec<&C> = realisations
            .iter()
            .map(|c| c.laws.get(kind).get::<C>())
            .collect();
        let ctrl = C::gather::<L>(&laws);
        self.fly_loop::<L, B, Pay::At<L>, Act::At<L>, C::At<L>, N>(
            &mut vehicle,
            &ctrl,
            realisations,
            req,
            trace,
            planner,
        )
    }

    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn fly_loop<L, B, Pay, Act, C, const N: usize>(
        &self,
        vehicle: &mut Vehicle<L, Pay, Act, B>,
        ctrl: &C,
        realisations: &[&Realisation],
        req: &FlightRequest,
        mut trace: Option<&mut Trace>,
        planner: &mut FftPlanner<f64>,
    ) -> Option<Vec<LaneResult>>
    where
        L: KernelOps,
        B: BodyKind,
        Pay: crate::model::PayloadModel<L>,
        Act: ActuatorModel<L>,
        C: Control<L>,
    {
        type V<L, Pay, Act, B> = Vehicle<L, Pay, Act, B>;
        assert_eq!(self.vars.len(), N, "the engine's layout is the vehicle's");
        let x0: State<L, N> = state_from_fn(|i| L::from_fn(|l| realisations[l].x0[i]));
        let mut s = x0;
        let mut winds: Vec<WindState> = match req.innovations {
            Some(xi) => {
                assert_eq!(xi.len(), L::LANES, "one row of innovations per lane");
                xi.iter()
                    .zip(realisations)
                    .map(|(x, c)| c.wind.given(x))
                    .collect()
            }
            None => req
                .indices
                .iter()
                .zip(realisations)
                .map(|(&i, c)| c.wind.realisation(req.seed, i))
                .collect(),
        };
        // The wind of the whole lane-set at once where the lanes' fields allow it
        // (`LaneWind::new`): the same numbers as the per-lane `sample_at`, drawn from the same
        // sources. Else the per-lane path below.
        let fields: Vec<&WindField> = realisations.iter().map(|c| &c.wind).collect();
        let mut lane_wind = LaneWind::<L>::new(&fields, winds.iter().map(|w| w.source()).collect());
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
                Some(b) => realisations[l].limits[b as usize],
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
        let windy = || realisations.iter().filter(|c| c.wind.enabled());
        let gust_from = windy().map(|c| c.wind.start_step()).min();
        let gust_to = windy().map(|c| c.wind.end_step()).max();
        let (gust_from, gust_to) = (gust_from.unwrap_or(u64::MAX), gust_to.unwrap_or(0));
        let floor = L::from_fn(|l| realisations[l].floor);
        // The rigid body's roll and pitch are no states: held to `divergence.max_tilt` here.
        let derives_tilt = !B::DERIVED.is_empty();
        let max_tilt = L::from_fn(|l| realisations[l].limits[Bound::Tilt as usize]);
        let grounded = realisations.iter().any(|c| c.floor > f64::NEG_INFINITY);
        let (zero, one) = (L::splat(0.0), L::splat(1.0));
        let mut extra = [zero; MAX_ACTUATOR_SIGNALS];
        let extra = &mut extra[..Act::SIGNALS.len()];
        // A deterministic wind source in any lane (a mean wind, a discrete gust, a table, a
        // prescribed wind): the wind is sampled at every step.
        let blows = realisations.iter().any(|c| c.wind.blows());
        let mut held = [zero; 3];
        // The law's discrete memory (none for a static law), and each lane's at its start.
        let mem0 = ctrl.memory(&V::<L, Pay, Act, B>::rigid(&x0));
        let mut mem = mem0;
        // The tilt past 90 % of the law's limit (`near_tilt_time`): cos(phi) cos(theta) below.
        let near_tilt_cos = L::from_fn(|l| realisations[l].near_tilt_cos);
        // The last metres: a lowering's line to pay out and the point it lowers at (the last
        // lowering's; before any, the reference's), per lane the height error at the release
        // and its time.
        let mut payout: Option<f64> = None;
        let mut drop_at: Option<[f64; 2]> = None;
        let mut release_err = [f64::NAN; MAX_LANES];
        let mut release_t = [f64::NAN; MAX_LANES];

        for k in 0..=self.steps {
            let t = k as f64 * self.dt;
            if t + TIME_SLACK >= ref_changes {
                r = self.trajectory.at(t, &mut segment);
                ref_changes = self.trajectory.next_change(segment);
                payout = self.trajectory.lowering(segment);
                drop_at = self.trajectory.drop_point(segment).or(drop_at);
                // Each lane's line (they differ before the first waypoint, which each lane's
                // own initial position leads to), once per segment: it depends on nothing else.
                if segment != line_of {
                    line_of = segment;
                    let mut lines = [([0.0; 3], [0.0; 3]); MAX_LANES];
                    for (l, c) in realisations.iter().enumerate() {
                        lines[l] = self.trajectory.line(segment, [c.x0[0], c.x0[1], c.x0[2]]);
                    }
                    line = (
                        [0, 1, 2].map(|i| L::from_fn(|l| lines[l].0[i])),
                        [0, 1, 2].map(|i| L::from_fn(|l| lines[l].1[i])),
                    );
                }
            }
            let trig = B::frame(&s);
            let tick = Tick { step: k, t };
            let view = V::<L, Pay, Act, B>::rigid_at(&s, &trig);
            let u = ctrl.step_with(&view, &B::trig(&trig, &view.att), &r, tick, &mut mem);
            let cmd = vehicle.actuator.command(&u, tick);
            // Outside the gust window `sample_at` returns zeros without touching the state
            // unless a `[wind]` source blows, so the per-lane calls are skipped where no lane's
            // window is open and nothing else blows (most of a paper flight).
            let at = |lane: usize| {
                let rigid = V::<L, Pay, Act, B>::rigid(&s);
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
                // The lane-set's wind when `lane_wind` flies it (else the per-lane values).
                let mut wind_set: Option<[L; 3]> = None;
                if let Some(g) = lane_wind.as_mut() {
                    wind_set = Some(g.sample(
                        k as u64,
                        #[inline(always)]
                        || {
                            let rigid = V::<L, Pay, Act, B>::rigid(&s);
                            (rigid.pos[2], rigid.vel)
                        },
                    ));
                } else if blows || (gust_from..gust_to).contains(&(k as u64)) {
                    for (lane, ((ws, v), c)) in winds
                        .iter_mut()
                        .zip(wind_lanes.iter_mut())
                        .zip(realisations)
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
            // The route's cue to the payload and its events, before the step (a hook that opens
            // now is open over the step).
            let cue = Cue {
                t,
                dt: self.dt,
                payout,
            };
            let events = vehicle.payload.last_metres(&s, &trig, &cue);
            // The payload's record of the step and its RK4 step's first stage, together.
            let (k1, out) = vehicle.derivative_and_outputs(&s, &trig, &cmd, &w, u.u1);
            let rigid = V::<L, Pay, Act, B>::rigid(&s);
            let e = [
                rigid.pos[0] * -1.0 + r.pos[0],
                rigid.pos[1] * -1.0 + r.pos[1],
                rigid.pos[2] * -1.0 + r.pos[2],
            ];
            let last = match events {
                None => LastSample::none(),
                Some(ev) => {
                    let drop = drop_at.unwrap_or([r.pos[0], r.pos[1]]);
                    let [vx, vy, vz] = ev.approach;
                    let (mx, my) = (ev.pos[0] - drop[0], ev.pos[1] - drop[1]);
                    let mut after = [0.0; MAX_LANES];
                    let mut change = [0.0; MAX_LANES];
                    for l in 0..L::LANES {
                        if ev.release.lane(l) > 0.0 {
                            release_t[l] = t;
                            release_err[l] = e[2].lane(l);
                        }
                        if t - release_t[l] <= RELEASE_WINDOW + TIME_SLACK {
                            after[l] = 1.0;
                            change[l] = (e[2].lane(l) - release_err[l]).abs();
                        }
                    }
                    LastSample {
                        touchdown: ev.touchdown,
                        touchdown_speed: vz.abs(),
                        touchdown_drift: vx.mul_add(vx, vy * vy).sqrt(),
                        touchdown_miss: mx.mul_add(mx, my * my).sqrt(),
                        release: ev.release,
                        after_release: L::from_fn(|l| after[l]),
                        release_change: L::from_fn(|l| change[l]),
                        lowering_swing: if payout.is_some() {
                            out.swing * (one - ev.grounded)
                        } else {
                            zero
                        },
                    }
                }
            };
            let [ax, ay, az] = out.accel;
            // |a| without the square root's rounding where the acceleration is vertical only.
            let accel = (ax * ax + ay * ay + az * az).sqrt();
            // The specific force a - g (g = (0, 0, -g)): what an accelerometer on the payload reads.
            let fz = az + vehicle.body.g;
            // Its square: the metric is its peak, whose square root is taken at the end.
            let specific_force_sq = ax * ax + ay * ay + fz * fz;
            acc.sample(
                k,
                t,
                &Sample {
                    e_o: out.e_o,
                    tracking_sq: e[0] * e[0] + e[1] * e[1] + e[2] * e[2],
                    cross_sq: cross_track_sq(&rigid.pos, &line),
                    accel,
                    specific_force_sq,
                    swing: out.swing,
                    tension: out.tension,
                    slack: L::select(out.tension.cmp_le(zero), one, zero),
                    saturated: vehicle.actuator.saturated(&cmd),
                    near_tilt: L::select(
                        crate::model::Frame::axes(&trig)[2][2].cmp_le(near_tilt_cos),
                        one,
                        zero,
                    ),
                    last,
                },
            );
            if let Some(tr) = trace.as_deref_mut() {
                // The trace ends where its lane diverged: nothing after `diverged_at` is recorded.
                if k % tr.every == 0 && diverged_at[0].is_nan() {
                    let lay = V::<L, Pay, Act, B>::LAYOUT;
                    vehicle.actuator.signals(&cmd, &s, lay.actuator(), extra);
                    let derived = &view.att[..B::DERIVED.len()];
                    tr.push(&TraceRow {
                        t,
                        s: &s,
                        derived,
                        r: &r,
                        u: &u,
                        w: &w,
                        e_o: out.e_o,
                        accel_c: accel,
                        drag_z: crate::model::Frame::drag(&trig, &vehicle.body, &rigid.vel, &w)[2],
                        swing: out.swing,
                        tension: out.tension,
                        extra,
                    });
                }
            }
            if k == self.steps {
                break;
            }
            rk4_advance(vehicle, &mut s, &trig, &k1, &cmd, &w, self.dt);

            let mut ok = L::ALL;
            for i in 0..N {
                ok &= s[i].abs().le_mask(limit[i]);
            }
            if grounded {
                ok &= floor.le_mask(s[ix::Z]);
            }
            let tilt = if derives_tilt {
                let att = B::euler(&s, &B::frame(&s));
                ok &= att[0].abs().le_mask(max_tilt) & att[1].abs().le_mask(max_tilt);
                [att[0], att[1]]
            } else {
                [zero; 2]
            };
            if ok != L::ALL {
                for (lane, at) in diverged_at.iter_mut().enumerate().take(L::LANES) {
                    if at.is_nan() && ok & (1 << lane) == 0 {
                        *at = t + self.dt;
                        alive -= 1;
                        let values: Vec<f64> = s.iter().map(|x| x.lane(lane)).collect();
                        let c = realisations[lane];
                        let tilt = if derives_tilt {
                            vec![tilt[0].lane(lane), tilt[1].lane(lane)]
                        } else {
                            Vec::new()
                        };
                        status[lane] = classify(&self.vars, &values, &tilt, &c.limits, c.floor);
                        // Park the lane on a benign state so its neighbours' arithmetic stays clean.
                        for (x, x0) in s.iter_mut().zip(realisations[lane].x0.iter()) {
                            x.set_lane(lane, *x0);
                        }
                        for (m, m0) in mem.iter_mut().zip(mem0.iter()) {
                            m.set_lane(lane, m0.lane(lane));
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
