//! The flight loop's steps (`Engine::fly_loop`), each inlined into the loop: the reference
//! and its leg (`Leg`), the wind (`Winds`), the last metres (`Release`), the runaway bounds
//! (`Runaway`) and how each lane's flight ended (`Ends`).

use super::engine::{FlightRequest, Realisation, MAX_LANES};
use super::status::{classify, ExitStatus};
use crate::control::{Due, Flying};
use crate::gust::{Kinematics, LaneWind, WindField, WindState};
use crate::lane::{KernelOps, Lane};
use crate::metrics::LastSample;
use crate::model::payload::Release as Hook;
use crate::model::payload::{LastMetres, LOWER_RADIUS};
use crate::model::{
    ix, state_from_fn, BodyKind, Bound, Rigid, Rotation, State, StateVar, TiltBound,
};
use crate::scenario::Config;
use crate::trajectory::{Reference, Trajectory, TIME_SLACK};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

/// s, the window after the hook opens over which the vehicle's height change is taken
/// (`release_height_change`).
pub const RELEASE_WINDOW: f64 = 5.0;

/// The reference and the leg it is on, refreshed only when the trajectory changes
/// (`Trajectory::next_change`).
pub(super) struct Leg<L> {
    segment: usize,
    pub(super) r: Reference,
    changes: f64,
    /// The straight line of the current leg (a point, a unit direction): cross-track error.
    pub(super) line: ([L; 3], [L; 3]),
    line_of: usize,
    /// The last metres: a lowering's line to pay out and the point it lowers at (the last
    /// lowering's; before any, the reference's).
    pub(super) payout: Option<crate::legs::Lowering>,
    drop_at: Option<[f64; 2]>,
    /// The line a lowering due pays out (`Trajectory::lowering_due`: in the lowering and the
    /// hold after it), the winch's cue.
    pub(super) due: Option<crate::legs::Lowering>,
}

impl<L: Lane> Leg<L> {
    #[inline(always)]
    pub(super) fn new() -> Self {
        Self {
            segment: 0,
            r: Reference::default(),
            changes: f64::NEG_INFINITY,
            line: ([L::splat(0.0); 3], [L::splat(0.0); 3]),
            line_of: usize::MAX,
            payout: None,
            drop_at: None,
            due: None,
        }
    }

    /// The vehicle's horizontal distance squared from the lowering's point, as it knows its
    /// position (`known`), less `LOWER_RADIUS` squared (`Cue::off_drop`); 0 (over it) without a
    /// lowering due.
    #[inline(always)]
    pub(super) fn off_drop(&self, known: &[L; 3]) -> L {
        match (self.due, self.drop_at) {
            (Some(_), Some([x, y])) => {
                let (dx, dy) = (known[0] - L::splat(x), known[1] - L::splat(y));
                dx * dx + dy * dy - L::splat(LOWER_RADIUS * LOWER_RADIUS)
            }
            _ => L::splat(0.0),
        }
    }

    /// The reference at `t`, and the leg's line, payout and drop point where they change.
    #[inline(always)]
    pub(super) fn follow(
        &mut self,
        trajectory: &Trajectory,
        t: f64,
        realisations: &[&Realisation],
    ) {
        if t + TIME_SLACK >= self.changes {
            self.r = trajectory.at(t, &mut self.segment);
            self.changes = trajectory.next_change(self.segment);
            self.payout = trajectory.lowering(self.segment);
            self.due = trajectory.lowering_due(self.segment);
            self.drop_at = trajectory.drop_point(self.segment).or(self.drop_at);
            // Each lane's line (they differ before the first waypoint, which each lane's
            // own initial position leads to), once per segment: it depends on nothing else.
            if self.segment != self.line_of {
                self.line_of = self.segment;
                let mut lines = [([0.0; 3], [0.0; 3]); MAX_LANES];
                for (l, c) in realisations.iter().enumerate() {
                    lines[l] = trajectory.line(self.segment, [c.x0[0], c.x0[1], c.x0[2]]);
                }
                self.line = (
                    [0, 1, 2].map(|i| L::from_fn(|l| lines[l].0[i])),
                    [0, 1, 2].map(|i| L::from_fn(|l| lines[l].1[i])),
                );
            }
        }
    }
}

/// The wind the lanes fly, sampled at the start of each step and held over it.
pub(super) struct Winds<'f, 'a, L> {
    /// Each lane's wind state (its filters' states and their normals).
    states: Vec<WindState<'a>>,
    /// The wind of the whole lane-set at once where the lanes' fields allow it
    /// (`LaneWind::new`): the same numbers as the per-lane `sample_at`, drawn from the same
    /// sources. Else the per-lane path.
    set: Option<LaneWind<'f, 'a, L>>,
    lanes: [[f64; 3]; MAX_LANES],
    /// Steps inside any lane's gust window (lanes may differ in a dispersed batch).
    gust_from: u64,
    gust_to: u64,
    /// A deterministic wind source in any lane (a mean wind, a discrete gust, a table, a
    /// prescribed wind): the wind is sampled at every step.
    blows: bool,
    held: [L; 3],
    /// Integration steps per field step (`gust.rate`), and at a rate the field's winds the
    /// step interpolates between: the last update's and the next's.
    every: usize,
    from: [L; 3],
    to: [L; 3],
}

impl<'f, 'a, L: KernelOps> Winds<'f, 'a, L> {
    #[inline(always)]
    pub(super) fn new(
        realisations: &[&Realisation],
        req: &FlightRequest<'a>,
        fields: &[&'f WindField],
    ) -> Self {
        let states: Vec<WindState> = match req.innovations {
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
        let set = LaneWind::<L>::new(fields, states.iter().map(|w| w.source()).collect());
        let windy = || realisations.iter().filter(|c| c.wind.enabled());
        let gust_from = windy().map(|c| c.wind.start_step()).min();
        let gust_to = windy().map(|c| c.wind.end_step()).max();
        let (gust_from, gust_to) = (gust_from.unwrap_or(u64::MAX), gust_to.unwrap_or(0));
        let every = realisations[0].wind.every();
        assert!(
            realisations.iter().all(|c| c.wind.every() == every),
            "the lanes of a set share gust.rate (it cannot be dispersed)"
        );
        Self {
            states,
            set,
            lanes: [[0.0; 3]; MAX_LANES],
            gust_from,
            gust_to,
            blows: realisations.iter().any(|c| c.wind.blows()),
            held: [L::splat(0.0); 3],
            every: every as usize,
            from: [L::splat(0.0); 3],
            to: [L::splat(0.0); 3],
        }
    }

    /// The wind of step `k` with the quadrotor at `rigid` (its altitude and velocity). The row
    /// at t_k holds the wind of step k. The `last` row (t = duration) has no step after it: it
    /// holds the last step's wind (the hold runs to its end), so no metric sees a wind that no
    /// step flies, and no innovation is drawn for it.
    ///
    /// At a `gust.rate` (docs/model.md, "Loop rates") the field is evaluated at its own steps, every
    /// `every` integration steps, and the wind between two of them is interpolated linearly
    /// (a first-order hold): at an update the field's next value is drawn, with the vehicle
    /// where it is then, and the steps until the next update run from the current value to
    /// it.
    #[inline(always)]
    pub(super) fn sample(
        &mut self,
        k: usize,
        last: bool,
        rigid: &Rigid<L>,
        realisations: &[&Realisation],
    ) -> [L; 3] {
        let w = if last {
            self.held
        } else if self.every == 1 {
            self.field_at(k, rigid, realisations)
        } else {
            let (update, since) = (k / self.every, k % self.every);
            if since == 0 {
                self.from = if k == 0 {
                    self.field_at(0, rigid, realisations)
                } else {
                    self.to
                };
                self.to = self.field_at(update + 1, rigid, realisations);
                self.from
            } else {
                let f = L::splat(since as f64 / self.every as f64);
                let (a, b) = (self.from, self.to);
                [
                    a[0] + (b[0] - a[0]) * f,
                    a[1] + (b[1] - a[1]) * f,
                    a[2] + (b[2] - a[2]) * f,
                ]
            }
        };
        self.held = w;
        w
    }

    /// The field's wind at its step `k` (an integration step at every step, else a
    /// `gust.rate` step) with the quadrotor at `rigid`.
    #[inline(always)]
    fn field_at(&mut self, k: usize, rigid: &Rigid<L>, realisations: &[&Realisation]) -> [L; 3] {
        // Outside the gust window `sample_at` returns zeros without touching the state
        // unless a `[wind]` source blows, so the per-lane calls are skipped where no lane's
        // window is open and nothing else blows (most of a paper flight).
        {
            // The lane-set's wind when `set` flies it (else the per-lane values).
            let mut wind_set: Option<[L; 3]> = None;
            if let Some(g) = self.set.as_mut() {
                wind_set = Some(g.sample(
                    k as u64,
                    #[inline(always)]
                    || (rigid.pos[2], rigid.vel),
                ));
            } else if self.blows || (self.gust_from..self.gust_to).contains(&(k as u64)) {
                for (lane, ((ws, v), c)) in self
                    .states
                    .iter_mut()
                    .zip(self.lanes.iter_mut())
                    .zip(realisations)
                    .enumerate()
                {
                    // Read here, where the lane type's instruction set is enabled: in a
                    // closure `sample_at` calls, each lane operation would be a call.
                    let kin = Kinematics {
                        z: rigid.pos[2].lane(lane),
                        vel: [
                            rigid.vel[0].lane(lane),
                            rigid.vel[1].lane(lane),
                            rigid.vel[2].lane(lane),
                        ],
                    };
                    *v = c.wind.sample_at(ws, k as u64, || kin);
                }
            } else {
                self.lanes = [[0.0; 3]; MAX_LANES];
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
                    wind_of(&self.lanes, 0),
                    wind_of(&self.lanes, 1),
                    wind_of(&self.lanes, 2),
                ],
            }
        }
    }
}

/// Per lane, the height error at the hook's release and its time (the last metres).
pub(super) struct Release {
    err: [f64; MAX_LANES],
    t: [f64; MAX_LANES],
    /// The latest lane's release time (NaN before any): past its window, no lane has one open.
    latest: f64,
}

impl Release {
    #[inline(always)]
    pub(super) fn new() -> Self {
        Self {
            err: [f64::NAN; MAX_LANES],
            t: [f64::NAN; MAX_LANES],
            latest: f64::NAN,
        }
    }

    /// The last metres' sample of the step at `t` (none without the payload's `events`):
    /// the touchdown's speeds and miss from the drop point, the release and the height change
    /// over the window after it, the swing while lowering. `e`: the position error.
    #[inline(always)]
    pub(super) fn sample<L: Lane>(
        &mut self,
        events: Option<LastMetres<L>>,
        leg: &Leg<L>,
        e: &[L; 3],
        t: f64,
        swing: L,
    ) -> LastSample<L> {
        let (zero, one) = (L::splat(0.0), L::splat(1.0));
        match events {
            None => LastSample::none(),
            Some(ev) => {
                let drop = leg.drop_at.unwrap_or([leg.r.pos[0], leg.r.pos[1]]);
                // At the instant the parcel met the ground (located inside the step).
                let [vx, vy, vz] = ev.contact_vel;
                let (mx, my) = (ev.contact_pos[0] - drop[0], ev.contact_pos[1] - drop[1]);
                let mut after = [0.0; MAX_LANES];
                let mut change = [0.0; MAX_LANES];
                // Lane by lane only in a step that releases a hook or inside a release's window
                // (a few seconds of a flight): else every lane's is 0.
                let releases = ev.release.le_mask(zero) != L::ALL;
                if releases || t - self.latest <= RELEASE_WINDOW + TIME_SLACK {
                    for l in 0..L::LANES {
                        if ev.release.lane(l) > 0.0 {
                            self.t[l] = t;
                            self.err[l] = e[2].lane(l);
                            self.latest = t;
                        }
                        if t - self.t[l] <= RELEASE_WINDOW + TIME_SLACK {
                            after[l] = 1.0;
                            change[l] = (e[2].lane(l) - self.err[l]).abs();
                        }
                    }
                }
                LastSample {
                    touchdown: ev.touchdown,
                    touchdown_speed: vz.abs(),
                    touchdown_drift: vx.mul_add(vx, vy * vy).sqrt(),
                    touchdown_miss: mx.mul_add(mx, my * my).sqrt(),
                    contact: ev.contact,
                    attached: ev.hooked,
                    release: ev.release,
                    after_release: L::from_fn(|l| after[l]),
                    release_change: L::from_fn(|l| change[l]),
                    lowering_swing: if leg.payout.is_some() {
                        swing * (one - ev.grounded)
                    } else {
                        zero
                    },
                }
            }
        }
    }
}

/// The master seed's offset for the load cell's stream: its numbers are independent of the
/// turbulence's (`gust::realisation_rng`, the same seed and index).
const TENSION_STREAM: u64 = 0x6c6f_6164_6365_6c6c; // "loadcell"

/// The load cell's white noise on the measured tension (`payload.tension_noise`): a standard
/// normal per lane and step from each lane's own stream, keyed by (seed, realisation) as
/// the turbulence's, `ChaCha8Rng::seed_from_u64(seed ^ TENSION_STREAM)` with
/// `set_stream(index)`; none (zeros, nothing drawn) without a slack hook with noise.
pub(super) struct TensionNoise {
    streams: Vec<ChaCha8Rng>,
}

impl TensionNoise {
    #[inline(always)]
    pub(super) fn new(req: &FlightRequest, cfg: &Config) -> Self {
        let c = &cfg.payload.cable;
        let noisy = c.release == Some(Hook::Slack) && c.tension_noise.is_some_and(|x| x > 0.0);
        let streams = if noisy {
            req.indices
                .iter()
                .map(|&i| {
                    let mut rng = ChaCha8Rng::seed_from_u64(req.seed ^ TENSION_STREAM);
                    rng.set_stream(i);
                    rng
                })
                .collect()
        } else {
            Vec::new()
        };
        Self { streams }
    }

    /// This step's standard normals, one per lane (zeros without the noise).
    #[inline(always)]
    pub(super) fn draw<L: Lane>(&mut self) -> L {
        if self.streams.is_empty() {
            return L::splat(0.0);
        }
        let mut n = [0.0; MAX_LANES];
        for (x, rng) in n.iter_mut().zip(self.streams.iter_mut()) {
            *x = StandardNormal.sample(rng);
        }
        L::from_fn(|l| n[l])
    }
}

/// The bounds past which a lane's flight ends.
pub(super) struct Runaway<L, const N: usize> {
    limit: State<L, N>,
    floor: L,
    grounded: bool,
    derives_tilt: bool,
    max_tilt: L,
    /// `max_tilt` as the check's first, cheaper test reads it (`Rotation::surely_within`).
    tilt: TiltBound<L>,
}

impl<L: Lane, const N: usize> Runaway<L, N> {
    /// Each state's runaway bound per lane and the other bounds a flight ends at (the floor,
    /// the rigid body's tilt).
    #[inline(always)]
    pub(super) fn new<B: BodyKind>(vars: &[StateVar], realisations: &[&Realisation]) -> Self {
        Self {
            // Infinite where a state has no bound: then only a non-finite value ends the
            // flight. NaN compares false, so the masks also catch non-finite states.
            limit: state_from_fn(|i| {
                L::from_fn(|l| match vars[i].bound {
                    Some(b) => realisations[l].limits[b as usize],
                    None => f64::INFINITY,
                })
            }),
            floor: L::from_fn(|l| realisations[l].floor),
            grounded: realisations.iter().any(|c| c.floor > f64::NEG_INFINITY),
            // The rigid body's roll and pitch are no states: held to `divergence.max_tilt` here.
            derives_tilt: !B::DERIVED.is_empty(),
            max_tilt: L::from_fn(|l| realisations[l].limits[Bound::Tilt as usize]),
            tilt: TiltBound::new(|l| realisations[l].limits[Bound::Tilt as usize]),
        }
    }

    /// The mask of the lanes within every bound in state `s`, and for a body whose roll and
    /// pitch are no states (the rigid body's) the attitude it derived them from: `s`'s frame,
    /// and its Euler angles where the tilt's first test left a lane to them, which the next
    /// step reads unchanged (`Attitude`).
    #[inline(always)]
    #[allow(clippy::needless_range_loop)]
    pub(super) fn check<B: BodyKind>(&self, s: &State<L, N>) -> (u32, Option<Attitude<L, B>>) {
        let mut ok = L::ALL;
        for i in 0..N {
            ok &= s[i].abs().le_mask(self.limit[i]);
        }
        if self.grounded {
            ok &= self.floor.le_mask(s[ix::Z]);
        }
        let attitude = if self.derives_tilt {
            let mut at = Attitude::<L, B>::of(s);
            let r = Rotation {
                axes: crate::model::Frame::axes(&at.frame),
            };
            // The Euler angles only where a lane is not surely within (near the bound, past
            // it, not finite): the same decision, without two atan2 and an asin a step.
            if r.surely_within(&self.tilt) != L::ALL {
                let att = at.euler(s);
                ok &= att[0].abs().le_mask(self.max_tilt) & att[1].abs().le_mask(self.max_tilt);
            }
            Some(at)
        } else {
            None
        };
        (ok, attitude)
    }
}

/// A state's attitude as the step reads it: its frame (`BodyKind::frame`) and, once derived,
/// its Euler angles (`BodyKind::euler`): the runaway check after a step derives the frame and,
/// near the tilt bound, the angles; the next step starts from the same state and derives the
/// angles only where something reads them (`euler`).
pub(super) struct Attitude<L: Lane, B: BodyKind> {
    pub(super) frame: B::Frame<L>,
    derived: Option<[L; 3]>,
}

impl<L: Lane, B: BodyKind> Attitude<L, B> {
    /// The attitude at `s` (its frame; the Euler angles when asked).
    #[inline(always)]
    pub(super) fn of<const N: usize>(s: &State<L, N>) -> Self {
        Self {
            frame: B::frame(s),
            derived: None,
        }
    }

    /// The Euler angles of `s` (this attitude's state), derived on first use.
    #[inline(always)]
    pub(super) fn euler<const N: usize>(&mut self, s: &State<L, N>) -> [L; 3] {
        // A match, not `Option::get_or_insert_with`: nothing here may be left out of line.
        match self.derived {
            Some(e) => e,
            None => {
                let e = B::euler(s, &self.frame);
                self.derived = Some(e);
                e
            }
        }
    }

    /// The Euler angles of `s` where the runaway check derived its attitude (`checked`).
    #[inline(always)]
    pub(super) fn angles_of<const N: usize>(
        checked: Option<Self>,
        s: &State<L, N>,
    ) -> Option<[L; 3]> {
        // A match, not `Option::map`: nothing here may be left out of line.
        match checked {
            Some(mut a) => Some(a.euler(s)),
            None => None,
        }
    }

    /// The attitude the last runaway check derived for state `s` (`checked`), else `of(s)`.
    #[inline(always)]
    pub(super) fn checked_or_of<const N: usize>(checked: Option<Self>, s: &State<L, N>) -> Self {
        // A match, not `Option::unwrap_or_else`: nothing here may be left out of line.
        match checked {
            Some(a) => a,
            None => Self::of(s),
        }
    }
}

/// How each lane's flight ended: its divergence time (NaN while it flies) and status, and the
/// lanes still flying.
pub(super) struct Ends {
    pub(super) diverged_at: [f64; MAX_LANES],
    pub(super) status: [ExitStatus; MAX_LANES],
    pub(super) alive: usize,
}

impl Ends {
    /// `lanes` lanes, all flying.
    #[inline(always)]
    pub(super) fn new(lanes: usize) -> Self {
        Self {
            diverged_at: [f64::NAN; MAX_LANES],
            status: [ExitStatus::Ok; MAX_LANES],
            alive: lanes,
        }
    }

    /// End the flight of each lane still flying outside `ok` (a lane mask) after the step at
    /// `t` (of `dt`), and say why (`tilt`: the rigid body's Euler angles, where roll and pitch
    /// are no states); park the lane on its initial state and its law's memory.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    pub(super) fn retire<L: KernelOps, const N: usize>(
        &mut self,
        ok: u32,
        t: f64,
        dt: f64,
        tilt: Option<[L; 3]>,
        s: &mut State<L, N>,
        law: &mut Flying<L>,
        realisations: &[&Realisation],
        vars: &[StateVar],
    ) {
        for (lane, at) in self.diverged_at.iter_mut().enumerate().take(L::LANES) {
            if at.is_nan() && ok & (1 << lane) == 0 {
                *at = t + dt;
                self.alive -= 1;
                let values: Vec<f64> = s.iter().map(|x| x.lane(lane)).collect();
                let c = realisations[lane];
                let tilt = match tilt {
                    Some(tilt) => vec![tilt[0].lane(lane), tilt[1].lane(lane)],
                    None => Vec::new(),
                };
                self.status[lane] = classify(vars, &values, &tilt, &c.limits, c.floor);
                // Park the lane on a benign state so its neighbours' arithmetic stays clean.
                for (x, x0) in s.iter_mut().zip(realisations[lane].x0.iter()) {
                    x.set_lane(lane, *x0);
                }
                law.park(lane);
            }
        }
    }
}

/// When each of a law's loops updates (docs/model.md, "Loop rates"): every `steps[i]` steps from the
/// first, for the position, attitude and inner loops in turn (1: every step).
pub(super) struct Rates {
    steps: [usize; 3],
    next: [usize; 3],
}

impl Rates {
    #[inline(always)]
    pub(super) fn new(steps: [usize; 3]) -> Self {
        Self {
            steps,
            next: [0; 3],
        }
    }

    /// The loops due at step `k` (called once per step, in order).
    #[inline(always)]
    pub(super) fn due(&mut self, k: usize) -> Due {
        let mut due = [false; 3];
        for ((due, next), steps) in due.iter_mut().zip(&mut self.next).zip(self.steps) {
            if k == *next {
                *due = true;
                *next += steps;
            }
        }
        Due {
            position: due[0],
            attitude: due[1],
            rate: due[2],
        }
    }
}
