//! The wind of a whole lane-set at once ([`LaneWind`]): the turbulence ([`LaneGust`]) with each
//! lane's normals drawn in bulk from its own source (the realisation's seeded stream or its
//! given innovations, exactly as [`WindField::sample_at`] would draw them) and the forming
//! filters advanced as lane values; where the scales follow the vehicle, every lane's scales
//! and filter numbers for the step in lane values (the lane-valued `pow`, `exp` and `expm1` of
//! `lane::explog`, which the per-realisation path runs on `f64`, so the same bits); the
//! `[wind]` mean wind in lane values too (the log shear's `ln` on the lane type) where it is
//! each lane's only mean air, else the mean air per lane; the discrete gusts once per lane-set
//! where the lanes share them.
//!
//! Per lane the arithmetic is operation for operation that of the per-realisation path
//! (`WindField::sample_at`: `step_fixed`, `GustFilter::output`, the axes' turn), with the lane
//! operators that never fuse, so a lane's gust is bitwise the scalar one whatever the lane
//! type, the packing of realisations into lanes or the engine's fused mode. What changes is
//! only where the time goes: the normals of many steps are drawn in one tight loop per lane
//! (no per-normal dispatch on the source, no per-step match on the filters' orders), and the
//! filters of all lanes advance in one pass of vector arithmetic.

use super::filter::{dryden_lanes, Coefficients, DrydenLanes, Normals};
use super::source::Kinematics;
use super::spectra::low_altitude_scales_lanes;
use super::steady::SteadyLanes;
use super::wind::{turned, FollowLanes, Source, WindField};
use super::AnySource;
use crate::config::{GustComponent, GustModel};
use crate::lane::isa::Isa;
use crate::lane::random::normal::{Ahead, CHUNK};
use crate::lane::{KernelOps, Lane};

/// Most lanes a lane-set carries (the widest lane type).
pub const MAX_LANES: usize = 8;

/// Normals the buffer holds per lane. A refill draws as many whole steps' worth
/// (`ROWS / per_step` steps) as fit.
const ROWS: usize = 256;

/// The normals buffer, lane by lane (`rows[l][r]`: lane `l`'s `r`-th buffered normal, so a
/// lane's draw is one contiguous copy): `ROWS` per lane and the `CHUNK - 1` spare ones
/// `Ahead::normals` may write past the last.
type Rows = [[f64; ROWS + CHUNK - 1]; MAX_LANES];

/// One axis's filter as lane values (padded to order 3 like `GustFilter`).
#[derive(Clone, Copy)]
struct Component<L> {
    /// 0: none on this axis.
    order: usize,
    /// First row of this component's normals within a step's rows.
    offset: usize,
    phi: [[L; 3]; 3],
    g: [[L; 3]; 3],
    out: [L; 3],
    x: [L; 3],
}

/// The turbulence of one lane-set: built by [`LaneGust::new`] where every lane's field allows
/// it (see there), sampled once per step inside the window by [`LaneGust::sample`], at the
/// scales its fields were built for unless [`LaneWind`] writes a step's into its components.
pub struct LaneGust<'a, L> {
    /// Per axis (longitudinal, lateral, vertical); order 0 where the axis has no turbulence.
    components: [Component<L>; 3],
    /// Normals one step draws per lane (the active components' orders summed).
    per_step: usize,
    /// `gust.mean_wind` added to the filters' sum (zero when the axes are turned).
    base: [L; 3],
    mean: [L; 3],
    /// (cos chi, sin chi) per lane, when the axes are turned.
    axes: Option<(L, L)>,
    start: u64,
    /// First step after the window.
    end: u64,
    started: bool,
    /// The step the filter states belong to (valid once started).
    at: u64,
    sources: Vec<Source<'a>>,
    /// Each seeded lane's words drawn ahead (unused for given innovations).
    ahead: Vec<Ahead>,
    /// `rows[l][r]`: lane `l`'s `r`-th buffered normal.
    rows: Box<Rows>,
    /// Next unread row, and the rows filled (a whole number of steps).
    next: usize,
    filled: usize,
}

impl<'a, L: Lane> LaneGust<'a, L> {
    /// The lane-set's turbulence, lane `l` drawing from `sources[l]`, with `fields[l]` its
    /// wind field (its filters as built: where the scales follow the vehicle, [`LaneWind`]
    /// sets each step's); `None` where the per-realisation path must fly it instead: where a
    /// field has no turbulence, or where the lanes differ in window, components, orders or
    /// whether the axes are turned. The other sources ([`LaneWind`]) are not its business.
    pub fn new(fields: &[&WindField], sources: Vec<Source<'a>>) -> Option<Self> {
        assert!(L::LANES <= MAX_LANES && fields.len() == L::LANES);
        assert_eq!(sources.len(), L::LANES, "one source per lane");
        let first = fields[0];
        let usable = |f: &WindField| f.enabled();
        let alike = |f: &WindField| {
            f.start_step() == first.start_step()
                && f.end_step() == first.end_step()
                && f.axes().is_some() == first.axes().is_some()
                && (0..3).all(|i| {
                    f.filters()[i].map(|g| g.order()) == first.filters()[i].map(|g| g.order())
                })
        };
        if !fields.iter().all(|f| usable(f) && alike(f)) {
            return None;
        }
        let lanes = |get: &dyn Fn(&WindField) -> f64| L::from_fn(|l| get(fields[l]));
        let unused = Component {
            order: 0,
            offset: 0,
            phi: [[L::splat(0.0); 3]; 3],
            g: [[L::splat(0.0); 3]; 3],
            out: [L::splat(0.0); 3],
            x: [L::splat(0.0); 3],
        };
        let mut components = [unused; 3];
        let mut per_step = 0;
        for (axis, slot) in components.iter_mut().enumerate() {
            let Some(f0) = first.filters()[axis] else {
                continue;
            };
            let filter = |l: usize| fields[l].filters()[axis].expect("orders checked alike");
            let phi = std::array::from_fn(|i| {
                std::array::from_fn(|j| L::from_fn(|l| filter(l).transition()[(i, j)]))
            });
            let g = std::array::from_fn(|i| {
                std::array::from_fn(|j| L::from_fn(|l| filter(l).noise_chol()[(i, j)]))
            });
            let out = std::array::from_fn(|i| L::from_fn(|l| filter(l).output_row()[i]));
            *slot = Component {
                order: f0.order(),
                offset: per_step,
                phi,
                g,
                out,
                x: [L::splat(0.0); 3],
            };
            per_step += f0.order();
        }
        let mean: [L; 3] = std::array::from_fn(|i| lanes(&|f| f.mean_wind()[i]));
        let axes = first.axes().map(|_| {
            (
                lanes(&|f| f.axes().map_or(1.0, |a| a.0)),
                lanes(&|f| f.axes().map_or(0.0, |a| a.1)),
            )
        });
        Some(LaneGust {
            components,
            per_step,
            base: if axes.is_some() {
                [L::splat(0.0); 3]
            } else {
                mean
            },
            mean,
            axes,
            start: first.start_step(),
            end: first.end_step(),
            started: false,
            at: 0,
            ahead: (0..L::LANES).map(|_| Ahead::new()).collect(),
            sources,
            rows: Box::new([[0.0; ROWS + CHUNK - 1]; MAX_LANES]),
            next: 0,
            filled: 0,
        })
    }

    /// The turbulence (m/s, inertial, `gust.mean_wind` included) of every lane over the step
    /// `step` inside the window: `WindField::sample_at`'s, lane by lane. Call in increasing
    /// step order; as there, the states are drawn stationary at the first call (as of the
    /// window's first step), advanced once per step up to `step`, and a repeated step draws
    /// nothing. No allocation.
    #[inline(always)]
    pub fn sample(&mut self, step: u64) -> [L; 3] {
        let mut w = self.base;
        if self.started && self.at + 1 == step {
            // The flight loop's case, one step on: each filter advanced and read in one pass.
            let row = self.take_step();
            let LaneGust {
                components, rows, ..
            } = self;
            // Three iterations, unrolled: `w` stays in registers.
            for (w, c) in w.iter_mut().zip(components.iter_mut()) {
                if c.order > 0 {
                    *w += c.advance(rows, row);
                }
            }
            self.at = step;
        } else {
            self.advance_to(step);
            for (w, c) in w.iter_mut().zip(self.components.iter()) {
                if c.order > 0 {
                    *w += c.output();
                }
            }
        }
        turned(w, self.axes, &self.mean)
    }

    /// Whether step `step` is inside the window.
    #[inline(always)]
    fn active(&self, step: u64) -> bool {
        self.start <= step && step < self.end
    }

    /// Start the filters (stationary states, at the window's first step) if not yet, and
    /// advance them once per step up to `step`. Out of the hot loop's line, so compiled for
    /// the lane type's instruction set through `Lane::within` (else each lane operation in it
    /// would be a call).
    #[inline(never)]
    fn advance_to(&mut self, step: u64) {
        let lane = self.base[0];
        lane.within(
            #[inline(always)]
            |_| self.advance_within(step),
        );
    }

    /// `advance_to`'s body, inlined into the instruction set's frame.
    #[inline(always)]
    fn advance_within(&mut self, step: u64) {
        if !self.started {
            let row = self.take_step();
            let LaneGust {
                components, rows, ..
            } = self;
            for c in components.iter_mut() {
                for j in 0..c.order {
                    c.x[j] = row_lanes(rows, row + c.offset + j);
                }
            }
            self.started = true;
            self.at = self.start;
        }
        while self.at < step {
            let row = self.take_step();
            let LaneGust {
                components, rows, ..
            } = self;
            for c in components.iter_mut().filter(|c| c.order > 0) {
                c.advance(rows, row);
            }
            self.at += 1;
        }
    }

    /// The first row of the next step's normals, refilling the buffer when it is spent.
    #[inline(always)]
    fn take_step(&mut self) -> usize {
        if self.next + self.per_step > self.filled {
            self.refill();
        }
        let row = self.next;
        self.next += self.per_step;
        row
    }

    /// Draw the next `ROWS / per_step` steps' normals of every lane, each lane from its own
    /// source in its stream's order (one match on the source per lane, not per normal), a
    /// seeded lane's in bulk through its `Ahead`. Compiled for the lane type's instruction set
    /// (`Lane::within`): the same numbers on every path, integer operations, one product and
    /// one comparison per normal.
    #[inline(never)]
    fn refill(&mut self) {
        let n = (ROWS / self.per_step) * self.per_step;
        let lane = self.base[0];
        lane.within(
            #[inline(always)]
            |isa| self.draw(n, isa),
        );
        self.next = 0;
        self.filled = n;
    }

    /// `refill`'s draws: rows `0..n` of every lane, on the instruction set `isa`.
    #[inline(always)]
    fn draw(&mut self, n: usize, isa: Isa) {
        let LaneGust {
            sources,
            ahead,
            rows,
            ..
        } = self;
        for (l, (src, ahead)) in sources.iter_mut().zip(ahead.iter_mut()).enumerate() {
            match src {
                Source::Seeded(rng) => ahead.normals(
                    rng,
                    n,
                    isa,
                    #[inline(always)]
                    |r, xs| {
                        // Whole chunks (`xs` is), so no call to memcpy.
                        let to = rows[l][r..r + xs.len()].chunks_exact_mut(CHUNK);
                        for (to, xs) in to.zip(xs.chunks_exact(CHUNK)) {
                            to.copy_from_slice(xs);
                        }
                    },
                ),
                Source::Given { xi, next } => {
                    let mut given = super::wind::Given::new(xi, *next);
                    for x in rows[l][..n].iter_mut() {
                        *x = given.normal();
                    }
                    *next = given.next();
                }
            }
        }
    }
}

/// How a lane-set's other sources (after the mean air's: the discrete gusts, a prescribed
/// wind) are evaluated.
enum Others {
    None,
    /// Every lane's the same (the same sources, the same step, none reading the quadrotor):
    /// evaluated once, as lane 0's.
    Shared,
    /// Lane by lane.
    PerLane,
}

/// The wind of one lane-set: [`WindField::sample_at`]'s, lane by lane and bit for bit (the
/// turbulence with its scales following each lane's quadrotor where they do, the `[wind]`
/// mean air at each lane's altitude, the other sources, each through `WindSource`), built by
/// [`LaneWind::new`] where
/// the lanes' fields are alike enough (see there) and sampled at every step by
/// [`LaneWind::sample`].
pub struct LaneWind<'f, 'a, L> {
    fields: Vec<&'f WindField>,
    gust: Option<LaneGust<'a, L>>,
    /// The turbulence's scales follow the vehicle (every lane's).
    follow: bool,
    /// A mean air blows (a `[wind]` mean wind or a `[wind.table]`, in every lane).
    steady: bool,
    /// The mean air in lane values, where every lane's is exactly one `[wind]` mean wind of
    /// the same shear kind (else it is summed lane by lane, `WindField::at_vehicle`).
    mean: Option<SteadyLanes<L>>,
    /// What the turbulence's scales follow, in lane values (with `mean`, the scales' inputs
    /// are computed for every lane at once).
    follow_lanes: Option<FollowLanes<L>>,
    others: Others,
    /// How many other sources each lane has (the same kinds in every lane).
    other_count: usize,
    /// Some lane's other source reads the quadrotor.
    others_read: bool,
    /// Some lane's source reads the quadrotor's altitude or velocity.
    reads_vehicle: bool,
    /// How each axis's filter numbers follow the vehicle.
    rescale: [Rescale<L>; 3],
    /// Each lane's filter numbers for the step where an axis takes them lane by lane
    /// (`Rescale::PerLane`).
    coefficients: Box<[[Coefficients; 3]; MAX_LANES]>,
}

/// How one axis's filter numbers are computed each step where the scales follow the vehicle.
#[derive(Clone, Copy)]
enum Rescale<L> {
    /// No turbulence on this axis (or scales that do not follow).
    None,
    /// Dryden in every lane: [`dryden_lanes`], every lane at once, with each lane's filter's
    /// `dt` and unit output row.
    Dryden {
        component: GustComponent,
        dt: L,
        c: [L; 2],
    },
    /// Lane by lane (`GustFilter::rescaled_coefficients`): von Karman.
    PerLane,
}

impl<'f, 'a, L: KernelOps> LaneWind<'f, 'a, L> {
    /// The lane-set's wind, lane `l` with the field `fields[l]` drawing from `sources[l]`;
    /// `None` where the per-realisation path must fly it: where the lanes differ in whether
    /// the turbulence is on and follows the vehicle, whether a mean air blows, in the kinds of
    /// their other sources (in order), or in what [`LaneGust::new`] needs alike.
    pub fn new(fields: &[&'f WindField], sources: Vec<Source<'a>>) -> Option<Self> {
        assert!(L::LANES <= MAX_LANES && fields.len() == L::LANES);
        let first = fields[0];
        let alike = |f: &&WindField| {
            f.enabled() == first.enabled()
                && f.turbulence_follows() == first.turbulence_follows()
                && f.has_steady() == first.has_steady()
                && f.others()
                    .iter()
                    .map(AnySource::name)
                    .eq(first.others().iter().map(AnySource::name))
        };
        if !fields.iter().all(alike) {
            return None;
        }
        let gust = match first.enabled() {
            true => Some(LaneGust::new(fields, sources)?),
            false => None,
        };
        let others_read = fields
            .iter()
            .any(|f| f.others().iter().any(AnySource::reads_vehicle));
        let shared = !others_read
            && fields
                .iter()
                .all(|f| f.others() == first.others() && f.dt().to_bits() == first.dt().to_bits());
        let others = match (first.others().is_empty(), shared) {
            (true, _) => Others::None,
            (false, true) => Others::Shared,
            (false, false) => Others::PerLane,
        };
        let follow = first.enabled() && first.turbulence_follows();
        let steadies: Option<Vec<_>> = fields
            .iter()
            .map(|f| match f.mean_sources() {
                [AnySource::Steady(s)] => Some(s),
                _ => None,
            })
            .collect();
        let mean = steadies.and_then(|s| SteadyLanes::new(&s));
        let rescale = std::array::from_fn(|axis| {
            let Some(f0) = first.filters()[axis].filter(|_| follow) else {
                return Rescale::None;
            };
            let filter = |l: usize| fields[l].filters()[axis].expect("orders checked alike");
            let dryden = (0..L::LANES).all(|l| {
                filter(l).model() == GustModel::Dryden && filter(l).component() == f0.component()
            });
            if !dryden {
                return Rescale::PerLane;
            }
            Rescale::Dryden {
                component: f0.component(),
                dt: L::from_fn(|l| filter(l).dt()),
                c: [0, 1].map(|i| L::from_fn(|l| filter(l).unit_output()[i])),
            }
        });
        Some(LaneWind {
            fields: fields.to_vec(),
            gust,
            follow,
            steady: first.has_steady(),
            mean,
            follow_lanes: WindField::follow_lanes(fields).filter(|_| follow),
            others,
            other_count: first.others().len(),
            others_read,
            reads_vehicle: fields.iter().any(|f| f.follows_vehicle()),
            rescale,
            coefficients: Box::new([[Coefficients::NAN; 3]; MAX_LANES]),
        })
    }

    /// The wind (m/s, inertial) of every lane over the step `step`, the quadrotors where `at`
    /// says (their altitudes and velocities, asked only if a source follows them): each
    /// lane's `WindField::sample_at`, bit for bit. Call once per step in increasing step
    /// order (as there). No allocation.
    #[inline(always)]
    pub fn sample(&mut self, step: u64, at: impl FnOnce() -> (L, [L; 3])) -> [L; 3] {
        let zero = L::splat(0.0);
        let turbulent = self.gust.as_ref().is_some_and(|g| g.active(step));
        let blows = self.steady || !matches!(self.others, Others::None);
        if !turbulent && !blows {
            return [zero; 3];
        }
        let mut steady = [zero; 3];
        let rescale = turbulent && self.follow;
        let mut kin = [Kinematics::AT_REST; MAX_LANES];
        // Every lane's altitude (at rest where none is asked: then no lane's mean air reads
        // it).
        let mut height = L::splat(Kinematics::AT_REST.z);
        let mut velocity = [zero; 3];
        if (self.steady || rescale || self.others_read) && self.reads_vehicle {
            let (z, vel) = at();
            height = z;
            velocity = vel;
            for (l, k) in kin.iter_mut().enumerate().take(L::LANES) {
                *k = Kinematics {
                    z: z.lane(l),
                    vel: [vel[0].lane(l), vel[1].lane(l), vel[2].lane(l)],
                };
            }
        }
        if self.steady || rescale {
            let components = match self.gust.as_mut() {
                Some(g) if rescale => Some(&mut g.components),
                _ => None,
            };
            let at = AtVehicles {
                step,
                fields: &self.fields,
                kin: &kin,
                mean: self.mean.as_ref().map(|m| (m, height)),
                follow: self.follow_lanes.as_ref().map(|f| (f, velocity)),
                rescale: components.map(|c| (c, &self.rescale, &mut *self.coefficients)),
            };
            at_vehicles(at, &mut steady);
        }
        let mut w = match self.gust.as_mut() {
            Some(g) if turbulent => g.sample(step),
            _ => [zero; 3],
        };
        if self.steady {
            for (w, m) in w.iter_mut().zip(steady) {
                *w += m;
            }
        }
        // Each other source added in turn, as `WindField::sample_at` adds them.
        for j in 0..self.other_count {
            match self.others {
                Others::None => {}
                Others::Shared => {
                    let g = self.fields[0].other_at(j, step, &Kinematics::AT_REST);
                    for (w, g) in w.iter_mut().zip(g) {
                        *w += L::splat(g);
                    }
                }
                Others::PerLane => {
                    let mut g = [[0.0; 3]; MAX_LANES];
                    for (l, (g, f)) in g.iter_mut().zip(&self.fields).enumerate() {
                        *g = f.other_at(j, step, &kin[l]);
                    }
                    for (i, w) in w.iter_mut().enumerate() {
                        *w += L::from_fn(
                            #[inline(always)]
                            |l| g[l][i],
                        );
                    }
                }
            }
        }
        w
    }
}

/// The filters' numbers of a lane-set's step where the scales follow the vehicle: the
/// components they go to, how each axis computes them, and the per-lane axes' scratch.
type Rescaling<'r, L> = (
    &'r mut [Component<L>; 3],
    &'r [Rescale<L>; 3],
    &'r mut [[Coefficients; 3]; MAX_LANES],
);

/// Each lane's `WindField::at_vehicle` (the mean air, the `[wind]` mean wind and a table's
/// wind, into `steady` as lane values; with `mean`, the lane-set's `[wind]` mean wind at the
/// lanes' altitudes, every lane at once, and with `follow` the scales' inputs from it, every
/// lane at once too) and, with `rescale`, the step's filter numbers of every lane written into
/// the components (`GustFilter::rescaled_coefficients`'s, bit for bit): the scales and the
/// Dryden axes' numbers by [`dryden_lanes`] for all lanes at once, the others lane by lane.
/// Kept out of the flight loop's line so that the loop saves its vector registers once per
/// step around it, not around every per-lane call it makes (the mean air's sources; every
/// vector register is the caller's to save); compiled for the lane type's instruction set
/// (`Lane::within`).
#[inline(never)]
fn at_vehicles<L: KernelOps>(at: AtVehicles<'_, L>, steady: &mut [L; 3]) {
    L::splat(0.0).within(
        #[inline(always)]
        |_| at_vehicles_within(at, steady),
    )
}

/// What `at_vehicles` reads: the step, the lanes' fields and vehicles, and the lane-set's
/// mean wind, scales' inputs and filters to rescale where it has them.
struct AtVehicles<'a, L: KernelOps> {
    step: u64,
    fields: &'a [&'a WindField],
    kin: &'a [Kinematics; MAX_LANES],
    mean: Option<(&'a SteadyLanes<L>, L)>,
    follow: Option<(&'a FollowLanes<L>, [L; 3])>,
    rescale: Option<Rescaling<'a, L>>,
}

/// `at_vehicles`' work, inlined into its instruction set's function.
#[inline(always)]
fn at_vehicles_within<L: KernelOps>(at: AtVehicles<'_, L>, steady: &mut [L; 3]) {
    let AtVehicles {
        step,
        fields,
        kin,
        mean,
        follow,
        rescale,
    } = at;
    let lanes = |a: &[f64; MAX_LANES]| {
        L::from_fn(
            #[inline(always)]
            |l| a[l],
        )
    };
    // Each lane's altitude, W20 and V, from which the scales come.
    let mut altitude = [1.0; MAX_LANES];
    let mut w20 = [0.0; MAX_LANES];
    let mut airspeed = [0.0; MAX_LANES];
    let mut put = |l: usize, inputs: Option<(f64, f64, f64)>| {
        if let Some((h, w, v)) = inputs {
            altitude[l] = h;
            w20[l] = w;
            airspeed[l] = v;
        }
    };
    // The scales' inputs where they are computed for every lane at once.
    let mut inputs = None;
    if let Some((m, z)) = mean {
        *steady = m.at(z);
        if let (Some(_), Some((f, vel))) = (&rescale, follow) {
            inputs = Some(f.inputs(z, vel, *steady));
        } else if rescale.is_some() {
            for (l, f) in fields.iter().enumerate() {
                let m = [steady[0].lane(l), steady[1].lane(l), steady[2].lane(l)];
                put(l, f.follow_at(&kin[l], m));
            }
        }
    } else {
        let mut per_lane = [[0.0; 3]; MAX_LANES];
        for (l, f) in fields.iter().enumerate() {
            let (m, inputs) = f.at_vehicle(step, &kin[l], rescale.is_some());
            if let Some(m) = m {
                per_lane[l] = m;
            }
            put(l, inputs);
        }
        *steady = std::array::from_fn(|i| {
            L::from_fn(
                #[inline(always)]
                |l| per_lane[l][i],
            )
        });
    }
    let Some((components, plan, coefficients)) = rescale else {
        return;
    };
    let (h, w20, v) = match inputs {
        Some(lanes) => lanes,
        None => (lanes(&altitude), lanes(&w20), lanes(&airspeed)),
    };
    // `WindField::follow_scales`' scales, every lane at once.
    let (sigma, length) = low_altitude_scales_lanes(h, w20);
    for (axis, (c, how)) in components.iter_mut().zip(plan).enumerate() {
        match how {
            Rescale::None => {}
            Rescale::Dryden {
                component,
                dt,
                c: unit,
            } => {
                dryden_lanes(
                    *component,
                    sigma[axis],
                    length[axis],
                    v,
                    *dt,
                    *unit,
                    DrydenLanes {
                        phi: &mut c.phi,
                        g: &mut c.g,
                        out: &mut c.out,
                    },
                );
            }
            Rescale::PerLane => {
                for (l, out) in coefficients.iter_mut().enumerate().take(L::LANES) {
                    let base = fields[l].filters()[axis].expect("orders checked alike");
                    out[axis] = base.rescaled_coefficients(
                        sigma[axis].lane(l),
                        length[axis].lane(l),
                        v.lane(l),
                    );
                }
                match c.order {
                    1 => c.set::<1>(coefficients, axis),
                    2 => c.set::<2>(coefficients, axis),
                    _ => c.set::<3>(coefficients, axis),
                }
            }
        }
    }
}

impl<L: Lane> Component<L> {
    /// Advance one step, the normals from the step's rows starting at `row` (this
    /// component's at `row + offset`), and return the new output. Order 1 to 3.
    #[inline(always)]
    fn advance(&mut self, rows: &Rows, row: usize) -> L {
        let r = row + self.offset;
        match self.order {
            1 => advance::<L, 1>(self, rows, r),
            2 => advance::<L, 2>(self, rows, r),
            _ => advance::<L, 3>(self, rows, r),
        }
    }

    /// The order-`N` block of lane `l`'s numbers, `per_lane[l][axis]`, for every lane.
    #[inline(always)]
    fn set<const N: usize>(&mut self, per_lane: &[[Coefficients; 3]; MAX_LANES], axis: usize) {
        for i in 0..N {
            for j in 0..N {
                self.phi[i][j] = L::from_fn(
                    #[inline(always)]
                    |l| per_lane[l][axis].phi[i][j],
                );
                self.g[i][j] = L::from_fn(
                    #[inline(always)]
                    |l| per_lane[l][axis].g[i][j],
                );
            }
            self.out[i] = L::from_fn(
                #[inline(always)]
                |l| per_lane[l][axis].out[i],
            );
        }
    }

    /// `GustFilter::output` on lane values. Order 1 to 3.
    #[inline(always)]
    fn output(&self) -> L {
        match self.order {
            1 => self.output_of::<1>(),
            2 => self.output_of::<2>(),
            _ => self.output_of::<3>(),
        }
    }

    /// `GustFilter::output` for `N = order`: the `N` states, summed as there.
    #[inline(always)]
    fn output_of<const N: usize>(&self) -> L {
        let mut y = self.out[0] * self.x[0];
        for j in 1..N {
            y += self.out[j] * self.x[j];
        }
        y
    }
}

/// The `r`-th buffered normal of every lane, as a lane value.
#[inline(always)]
fn row_lanes<L: Lane>(rows: &Rows, r: usize) -> L {
    assert!(r < ROWS + CHUNK - 1);
    L::from_fn(
        #[inline(always)]
        |l| rows[l][r],
    )
}

/// `step_fixed::<N>` on lane values, the normals from rows `r..r + N`: `x' = Phi x + G n`,
/// summed in the same order; returns the new output.
#[inline(always)]
// Element by element, not `copy_from_slice`: lane values stay in registers (no memcpy).
#[allow(clippy::needless_range_loop, clippy::manual_memcpy)]
fn advance<L: Lane, const N: usize>(c: &mut Component<L>, rows: &Rows, r: usize) -> L {
    let mut n = [L::splat(0.0); N];
    for (j, n) in n.iter_mut().enumerate() {
        *n = row_lanes(rows, r + j);
    }
    let mut y = [L::splat(0.0); N];
    for i in 0..N {
        let mut acc = c.phi[i][0] * c.x[0] + c.g[i][0] * n[0];
        for j in 1..N {
            acc += c.phi[i][j] * c.x[j] + c.g[i][j] * n[j];
        }
        y[i] = acc;
    }
    for i in 0..N {
        c.x[i] = y[i];
    }
    c.output_of::<N>()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lane::F64x4;
    use crate::scenario::{Config, GustAltitude, GustComponent, GustModel};
    use rand::Rng;

    /// The paper preset's gust with `edit` applied, for the step `dt` (window [0.5, 3) s).
    fn field(dt: f64, edit: impl Fn(&mut Config)) -> WindField {
        let mut cfg = crate::scenario::tests::paper();
        cfg.gust.enabled = true;
        cfg.gust.start = 0.5;
        cfg.gust.end = 3.0;
        cfg.integrator.dt = dt;
        edit(&mut cfg);
        cfg.validate().unwrap();
        WindField::new(&cfg.wind_context()).unwrap()
    }

    /// Every lane of `LaneGust` against `WindField::sample` of the same realisation, bit for
    /// bit, over the window and a little past it (the flight loop samples inside only).
    fn lanes_match<L: Lane>(fields: &[&WindField], seed: u64, indices: &[u64]) {
        let sources = indices
            .iter()
            .zip(fields)
            .map(|(&i, f)| f.realisation(seed, i).source())
            .collect();
        let mut set = LaneGust::<L>::new(fields, sources).expect("a plain gust flies as a set");
        let mut one: Vec<_> = indices
            .iter()
            .zip(fields)
            .map(|(&i, f)| f.realisation(seed, i))
            .collect();
        let (from, to) = (fields[0].start_step(), fields[0].end_step());
        for step in from..to {
            let w = set.sample(step);
            for (l, (st, f)) in one.iter_mut().zip(fields).enumerate() {
                let want = f.sample(st, step);
                for i in 0..3 {
                    assert_eq!(
                        w[i].lane(l).to_bits(),
                        want[i].to_bits(),
                        "step {step} lane {l} axis {i}"
                    );
                }
            }
        }
        // The normals drawn ahead and not used yet are each stream's next ones, and the stream
        // goes on in step after them: no word lost or used twice across the refills.
        for (l, st) in one.iter().enumerate() {
            let Source::Seeded(mut rng) = st.source() else {
                continue;
            };
            let Source::Seeded(lane_rng) = &mut set.sources[l] else {
                unreachable!("seeded on both paths");
            };
            for r in set.next..set.filled {
                let want = crate::lane::random::normal::standard_normal(&mut rng);
                assert_eq!(set.rows[l][r].to_bits(), want.to_bits(), "lane {l} row {r}");
            }
            for k in 0..300 {
                let word = set.ahead[l].next_u64(lane_rng);
                assert_eq!(word, rng.next_u64(), "lane {l} word {k}");
            }
        }
    }

    /// The lane types of the AVX2 and AVX-512 paths, where this CPU has them (their draws go
    /// through the wide keystream and candidate kernels, `keystream` and `normal::mark`).
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn the_wide_paths_draw_the_same_gust() {
        use crate::lane::{F64x4Avx, F64x8Avx512};
        use GustComponent::*;
        for comps in [&[Vertical][..], &[Longitudinal, Lateral, Vertical]] {
            let f = field(2e-3, |c| c.gust.components = comps.to_vec());
            if Isa::Avx2.supported() {
                lanes_match::<F64x4Avx>(&[&f; 4], 8, &[1, 0, 5, u64::MAX]);
            }
            if Isa::Avx512.supported() {
                lanes_match::<F64x8Avx512>(&[&f; 8], 8, &[1, 0, 5, 9, 2, 3, 4, 6]);
            }
        }
    }

    #[test]
    fn a_lane_set_draws_each_realisations_gust_bit_for_bit() {
        use GustComponent::*;
        let sets: [&[GustComponent]; 4] = [
            &[Vertical],
            &[Longitudinal, Lateral, Vertical],
            &[Longitudinal],
            &[Lateral, Vertical],
        ];
        for model in [GustModel::Dryden, GustModel::VonKarman] {
            for comps in sets {
                for heading in [0.0, 30.0] {
                    let f = field(0.01, |c| {
                        c.gust.model = model;
                        c.gust.components = comps.to_vec();
                        c.gust.mean_wind = [0.25, -0.5, 0.125];
                        c.wind.heading = heading;
                    });
                    lanes_match::<f64>(&[&f], 11, &[7]);
                    lanes_match::<F64x4>(&[&f; 4], 11, &[3, 0, 9, u64::MAX]);
                }
            }
        }
    }

    #[test]
    fn lanes_may_differ_in_intensity_and_scale() {
        // A dispersed batch: per-lane sigma (w20) and length scale (altitude).
        let fs: Vec<WindField> = (0..4)
            .map(|l| {
                field(2e-3, |c| {
                    c.gust.components = GustComponent::ALL.to_vec();
                    c.gust.w20 = Some(5.0 + l as f64);
                    c.gust.altitude = GustAltitude::Fixed(2.0 + 10.0 * l as f64);
                })
            })
            .collect();
        let refs: Vec<&WindField> = fs.iter().collect();
        lanes_match::<F64x4>(&refs, 5, &[0, 1, 2, 3]);
    }

    #[test]
    fn given_innovations_fly_the_seeded_lanes() {
        let f = field(0.01, |c| c.gust.components = GustComponent::ALL.to_vec());
        let steps = 400;
        let xi: Vec<Vec<f64>> = (0..4).map(|i| f.innovations_of(3, i, steps)).collect();
        let fields = [&f; 4];
        let given = xi.iter().map(|x| f.given(x).source()).collect();
        let seeded = (0..4).map(|i| f.realisation(3, i).source()).collect();
        // Given and seeded lanes in one set, too.
        let mixed = (0..4)
            .map(|i| match i % 2 {
                0 => f.given(&xi[i]).source(),
                _ => f.realisation(3, i as u64).source(),
            })
            .collect();
        let mut a = LaneGust::<F64x4>::new(&fields, given).unwrap();
        let mut b = LaneGust::<F64x4>::new(&fields, seeded).unwrap();
        let mut c = LaneGust::<F64x4>::new(&fields, mixed).unwrap();
        for step in f.start_step()..=(steps as u64).min(f.end_step() - 1) {
            let (x, y, z) = (a.sample(step), b.sample(step), c.sample(step));
            for i in 0..3 {
                for l in 0..4 {
                    assert_eq!(x[i].lane(l).to_bits(), y[i].lane(l).to_bits());
                    assert_eq!(z[i].lane(l).to_bits(), y[i].lane(l).to_bits());
                }
            }
        }
        // Past the innovations given: NaN, as on the per-realisation path.
        let short = &xi[0][..xi[0].len() - 5];
        let mut c = LaneGust::<f64>::new(&[&f], vec![f.given(short).source()]).unwrap();
        let last = (steps as u64).min(f.end_step() - 1);
        assert!(c.sample(last - 1).iter().all(|w| w.is_finite()));
        assert!(c.sample(last).iter().all(|w| w.is_nan()));
    }

    #[test]
    fn what_the_set_cannot_fly_is_left_to_the_per_lane_path() {
        let src = |f: &WindField| vec![f.realisation(0, 0).source()];
        let plain = field(0.01, |_| {});
        assert!(LaneGust::<f64>::new(&[&plain], src(&plain)).is_some());
        let off = field(0.01, |c| c.gust.enabled = false);
        assert!(LaneGust::<f64>::new(&[&off], src(&off)).is_none());
        // Scales that follow the vehicle and other sources: the turbulence is the set's, the
        // rest `LaneWind`'s.
        let vehicle = field(0.01, |c| c.gust.altitude = GustAltitude::Vehicle);
        let blows = field(0.01, |c| c.wind.speed = 2.0);
        for f in [&off, &vehicle, &blows, &plain] {
            assert!(LaneWind::<f64>::new(&[f], src(f)).is_some());
        }
        // Lanes that differ in their window or components.
        let later = field(0.01, |c| c.gust.start = 1.0);
        let three = field(0.01, |c| c.gust.components = GustComponent::ALL.to_vec());
        // ... or in whether the turbulence is on or follows, or a mean wind or a gust blows.
        let gusty = field(0.01, |c| c.wind.gusts = vec![ramp(0.2)]);
        for other in [&later, &three, &off, &vehicle, &blows, &gusty] {
            let fields = [&plain, &plain, other, &plain];
            let sources = fields
                .iter()
                .map(|f| f.realisation(0, 0).source())
                .collect();
            assert!(LaneWind::<F64x4>::new(&fields, sources).is_none());
        }
    }

    // ---- The whole wind of a lane-set --------------------------------------------------

    use crate::scenario::{DiscreteGust, GustAirspeed, GustShape, Shear, TableBy, WindTable};

    fn ramp(start: f64) -> DiscreteGust {
        DiscreteGust {
            start,
            duration: 0.3,
            amplitude: [1.0, -0.5, 0.25],
            shape: GustShape::Ramp,
        }
    }

    /// Lane `l` at step `n`: climbing from below 10 ft through the clamp, moving.
    fn kin(n: u64, l: usize) -> Kinematics {
        let t = n as f64;
        Kinematics {
            z: -0.5 + 0.05 * t + 0.7 * l as f64,
            vel: [
                3.0 + 0.1 * l as f64 - 0.01 * t,
                -1.0 + 0.02 * t,
                0.5 - 0.3 * l as f64,
            ],
        }
    }

    /// Every lane of `LaneWind` against `WindField::sample_at` of the same realisation, bit
    /// for bit (NaN against NaN), over `steps` steps with the lanes at `kin`.
    fn wind_matches<L: KernelOps>(
        fields: &[&WindField],
        sources: Vec<Source<'_>>,
        mut one: Vec<super::super::wind::WindState<'_>>,
        steps: u64,
        kin: impl Fn(u64, usize) -> Kinematics,
    ) {
        let mut set = LaneWind::<L>::new(fields, sources).expect("alike lanes fly as a set");
        for step in 0..steps {
            let k: Vec<Kinematics> = (0..L::LANES).map(|l| kin(step, l)).collect();
            let z = L::from_fn(|l| k[l].z);
            let vel = [0, 1, 2].map(|i| L::from_fn(|l| k[l].vel[i]));
            let w = set.sample(step, || (z, vel));
            for (l, (st, f)) in one.iter_mut().zip(fields).enumerate() {
                let want = f.sample_at(st, step, || k[l]);
                for i in 0..3 {
                    let got = w[i].lane(l);
                    assert!(
                        got.to_bits() == want[i].to_bits() || (got.is_nan() && want[i].is_nan()),
                        "step {step} lane {l} axis {i}: {got} vs {}",
                        want[i]
                    );
                }
            }
        }
    }

    fn seeded<'a>(
        fields: &[&WindField],
        seed: u64,
    ) -> (Vec<Source<'a>>, Vec<super::super::wind::WindState<'a>>) {
        let one: Vec<_> = (0..fields.len())
            .map(|l| fields[l].realisation(seed, l as u64 * 3 + 1))
            .collect();
        (one.iter().map(|w| w.source()).collect(), one)
    }

    /// The delivery preset's wind and its variants: turbulence that follows the vehicle in
    /// altitude, in airspeed or both, a sheared mean wind, discrete gusts, turned axes.
    fn whole_flight_fields() -> Vec<WindField> {
        let by_time = WindTable {
            by: TableBy::Time,
            points: vec![
                [0.5, 1.0, 0.0, 0.0],
                [1.5, 2.0, -1.0, 0.5],
                [2.0, 0.0, 0.0, 0.0],
            ],
        };
        let by_altitude = WindTable {
            by: TableBy::Altitude,
            points: vec![
                [0.0, 0.0, 0.0, 0.0],
                [5.0, 3.0, 1.0, 0.0],
                [10.0, 6.0, -2.0, 0.5],
            ],
        };
        let edits: [&dyn Fn(&mut Config); 9] = [
            &|c| {
                c.gust.altitude = GustAltitude::Vehicle;
                c.gust.airspeed = GustAirspeed::Relative;
                c.wind.speed = 5.0;
                c.wind.heading = 90.0;
                c.wind.shear = Shear::Log;
            },
            &|c| c.gust.altitude = GustAltitude::Vehicle,
            &|c| {
                c.gust.airspeed = GustAirspeed::Relative;
                c.gust.min_airspeed = 3.2;
            },
            &|c| {
                c.gust.model = GustModel::VonKarman;
                c.gust.altitude = GustAltitude::Vehicle;
                c.gust.airspeed = GustAirspeed::Relative;
                c.wind.speed = 3.0;
            },
            &|c| {
                c.gust.enabled = false;
                c.wind.speed = 4.0;
                c.wind.shear = Shear::Log;
                c.wind.gusts = vec![ramp(0.1), ramp(0.4)];
            },
            &|c| {
                c.gust.altitude = GustAltitude::Vehicle;
                c.gust.mean_wind = [0.25, -0.5, 0.125];
                c.wind.heading = 30.0;
                c.wind.gusts = vec![ramp(0.05)];
            },
            &|c| c.wind.gusts = vec![ramp(0.6)],
            // A measured wind by time with turbulence through the air it moves, and one by
            // altitude over a sheared mean wind with a gust.
            &|c| {
                c.gust.airspeed = GustAirspeed::Relative;
                c.wind.table = Some(by_time.clone());
            },
            &|c| {
                c.gust.altitude = GustAltitude::Vehicle;
                c.gust.airspeed = GustAirspeed::Relative;
                c.wind.speed = 2.0;
                c.wind.shear = Shear::Log;
                c.wind.gusts = vec![ramp(0.2)];
                c.wind.table = Some(by_altitude.clone());
            },
        ];
        let mut fields = edited_fields(&edits, &|c| {
            c.gust.start = 0.3;
            c.gust.end = 2.0;
        });
        // A prescribed wind (a source, added last) over a sheared mean wind, a table by
        // altitude and a gust, the turbulence off.
        let sheared = field(0.01, |c| {
            c.gust.components = GustComponent::ALL.to_vec();
            c.wind.speed = 3.0;
            c.wind.heading = 120.0;
            c.wind.shear = Shear::Log;
            c.wind.gusts = vec![ramp(0.2)];
            c.wind.table = Some(by_altitude.clone());
        });
        fields.push(sheared.prescribed(prescribed_rows(0.0)));
        fields
    }

    /// One field (at 0.01 s) per edit, each over the same `base`, all three components blowing.
    fn edited_fields(edits: &[&dyn Fn(&mut Config)], base: &dyn Fn(&mut Config)) -> Vec<WindField> {
        edits
            .iter()
            .map(|edit| {
                field(0.01, |c| {
                    c.gust.components = GustComponent::ALL.to_vec();
                    base(c);
                    edit(c);
                })
            })
            .collect()
    }

    /// A prescribed wind's rows, one per step of the tests' flights (and one past them).
    fn prescribed_rows(phase: f64) -> Vec<[f64; 3]> {
        (0..=260)
            .map(|k| {
                let t = k as f64 * 0.01 + phase;
                [(5.0 * t).sin(), -0.5 * (2.0 * t).cos(), 0.0]
            })
            .collect()
    }

    #[test]
    fn a_lane_set_flies_each_realisations_whole_flight_wind_bit_for_bit() {
        for f in &whole_flight_fields() {
            let (sources, one) = seeded(&[f], 4);
            wind_matches::<f64>(&[f], sources, one, 260, kin);
            let (sources, one) = seeded(&[f; 4], 4);
            wind_matches::<F64x4>(&[f; 4], sources, one, 260, kin);
        }
    }

    /// Lanes whose scales follow the vehicle in different ways, over one sheared mean wind
    /// kind (the scales' inputs then computed for every lane at once, `FollowLanes`): each
    /// lane's own wind, bit for bit, on every lane type this CPU runs.
    #[test]
    fn lanes_following_in_their_own_ways_fly_each_lanes_wind_bit_for_bit() {
        let edits: [&dyn Fn(&mut Config); 4] = [
            &|c| {
                c.gust.altitude = GustAltitude::Vehicle;
                c.gust.airspeed = GustAirspeed::Relative;
            },
            &|c| {
                c.gust.altitude = GustAltitude::Fixed(40.0);
                c.gust.airspeed = GustAirspeed::Relative;
                c.gust.min_airspeed = 2.5;
            },
            &|c| {
                c.gust.altitude = GustAltitude::Vehicle;
                c.gust.airspeed = GustAirspeed::Fixed(7.0);
                c.gust.w20 = Some(9.0);
            },
            &|c| {
                c.gust.altitude = GustAltitude::Vehicle;
                c.gust.airspeed = GustAirspeed::Relative;
                c.gust.min_airspeed = 4.0;
                c.wind.roughness = 0.3;
            },
        ];
        let fields = edited_fields(&edits, &|c| {
            c.gust.start = 0.0;
            c.gust.end = 2.0;
            c.wind.speed = 4.0;
            c.wind.heading = 60.0;
            c.wind.shear = Shear::Log;
        });
        let four: Vec<&WindField> = fields.iter().collect();
        let (sources, one) = seeded(&four, 5);
        wind_matches::<F64x4>(&four, sources, one, 200, kin);
        #[cfg(target_arch = "x86_64")]
        {
            use crate::lane::{F64x4Avx, F64x8Avx512};
            if Isa::Avx2.supported() {
                let (sources, one) = seeded(&four, 5);
                wind_matches::<F64x4Avx>(&four, sources, one, 200, kin);
            }
            if Isa::Avx512.supported() {
                let eight: Vec<&WindField> = fields.iter().chain(&fields).collect();
                let (sources, one) = seeded(&eight, 5);
                wind_matches::<F64x8Avx512>(&eight, sources, one, 200, kin);
            }
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn the_wide_paths_fly_the_same_whole_flight_wind() {
        use crate::lane::{F64x4Avx, F64x8Avx512};
        for f in &whole_flight_fields() {
            if Isa::Avx2.supported() {
                let (sources, one) = seeded(&[f; 4], 6);
                wind_matches::<F64x4Avx>(&[f; 4], sources, one, 260, kin);
            }
            if Isa::Avx512.supported() {
                let (sources, one) = seeded(&[f; 8], 6);
                wind_matches::<F64x8Avx512>(&[f; 8], sources, one, 260, kin);
            }
        }
    }

    /// `SteadyLanes::at` on the lane type `L` against each lane's `Steady::at`, bit for bit
    /// (the same NaN too), for lanes with their own W20, heading and roughness, at heights
    /// below, at and above z0, at 20 ft, far up, NaN and infinite.
    fn mean_wind_matches<L: KernelOps>(shear: Shear) {
        use super::super::source::{Moment, WindSource};
        use super::super::steady::{Steady, SteadyLanes, REFERENCE_HEIGHT};
        let z0 = |l: usize| [0.0457, 0.01, 0.3, 1.7, 0.08, 0.002, 0.5, 6.0][l];
        let steadies: Vec<Steady> = (0..L::LANES)
            .map(|l| {
                let mut cfg = crate::scenario::tests::paper();
                cfg.wind.speed = 1.5 + 0.7 * l as f64;
                cfg.wind.heading = -40.0 + 37.0 * l as f64;
                cfg.wind.shear = shear;
                cfg.wind.roughness = z0(l);
                cfg.validate().unwrap();
                Steady::build(&cfg.wind_context()).expect("a wind blows")
            })
            .collect();
        let refs: Vec<&Steady> = steadies.iter().collect();
        let set = SteadyLanes::<L>::new(&refs).expect("one shear kind");
        let now = Moment { step: 3, t: 0.03 };
        let heights: [&dyn Fn(usize) -> f64; 12] = [
            &|l| z0(l) * 0.5,
            &z0,
            &|l| z0(l) * (1.0 + f64::EPSILON),
            &|_| REFERENCE_HEIGHT,
            &|l| 0.2 + 1.3 * l as f64,
            &|l| 12.0 + 40.0 * l as f64,
            &|_| 1e6,
            &|_| 0.0,
            &|_| -3.0,
            &|l| if l % 2 == 0 { f64::NAN } else { 7.0 },
            &|_| f64::INFINITY,
            &|l| {
                if l % 2 == 1 {
                    f64::NEG_INFINITY
                } else {
                    1e-300
                }
            },
        ];
        for h in heights {
            let w = set.at(L::from_fn(h));
            for (l, s) in steadies.iter().enumerate() {
                let kin = Kinematics {
                    z: h(l),
                    vel: [0.0; 3],
                };
                let want = s.at(now, &kin);
                for i in 0..3 {
                    assert_eq!(
                        w[i].lane(l).to_bits(),
                        want[i].to_bits(),
                        "{shear:?} lane {l} at {} axis {i}",
                        h(l)
                    );
                }
            }
        }
    }

    #[test]
    fn the_lane_valued_mean_wind_is_each_lanes_bit_for_bit() {
        use super::super::source::WindSource;
        use super::super::steady::{Steady, SteadyLanes};
        for shear in [Shear::Log, Shear::None] {
            mean_wind_matches::<f64>(shear);
            mean_wind_matches::<F64x4>(shear);
            #[cfg(target_arch = "x86_64")]
            {
                use crate::lane::{F64x4Avx, F64x8Avx512};
                if Isa::Avx2.supported() {
                    mean_wind_matches::<F64x4Avx>(shear);
                }
                if Isa::Avx512.supported() {
                    mean_wind_matches::<F64x8Avx512>(shear);
                }
            }
        }
        // Lanes of different shear kinds are left to the per-lane path.
        let built: Vec<Steady> = [Shear::Log, Shear::None]
            .iter()
            .map(|&shear| {
                let mut cfg = crate::scenario::tests::paper();
                cfg.wind.speed = 3.0;
                cfg.wind.shear = shear;
                Steady::build(&cfg.wind_context()).unwrap()
            })
            .collect();
        assert!(SteadyLanes::<F64x4>::new(&[&built[0], &built[1], &built[0], &built[0]]).is_none());
    }

    #[test]
    fn lanes_may_differ_in_their_wind_and_a_runaway_lane_flies_nan() {
        // A dispersed batch: per-lane W20, mean wind, roughness and gust lists.
        let fs: Vec<WindField> = (0..4)
            .map(|l| {
                field(0.01, |c| {
                    c.gust.components = GustComponent::ALL.to_vec();
                    c.gust.altitude = GustAltitude::Vehicle;
                    c.gust.airspeed = GustAirspeed::Relative;
                    c.gust.w20 = Some(4.0 + l as f64);
                    c.wind.speed = 2.0 + l as f64;
                    c.wind.shear = Shear::Log;
                    c.wind.roughness = 0.03 * (l + 1) as f64;
                    c.wind.gusts = vec![ramp(0.1 * l as f64)];
                })
            })
            .collect();
        let refs: Vec<&WindField> = fs.iter().collect();
        let (sources, one) = seeded(&refs, 2);
        wind_matches::<F64x4>(&refs, sources, one, 200, kin);
        // Lane 2's state runs away (NaN) from step 120: NaN there on both paths, the other
        // lanes untouched.
        let runaway = |n: u64, l: usize| {
            let mut k = kin(n, l);
            if l == 2 && n >= 120 {
                k.z = f64::NAN;
            }
            k
        };
        let (sources, one) = seeded(&refs, 2);
        wind_matches::<F64x4>(&refs, sources, one, 200, runaway);
        // Given innovations fly the seeded lanes.
        let xi: Vec<Vec<f64>> = (0..4)
            .map(|l| fs[l].innovations_of(2, l as u64 * 3 + 1, 200))
            .collect();
        let given: Vec<_> = (0..4).map(|l| fs[l].given(&xi[l])).collect();
        let sources = given.iter().map(|w| w.source()).collect();
        let (_, one) = seeded(&refs, 2);
        wind_matches::<F64x4>(&refs, sources, one, 200, kin);
        // Each lane its own prescribed wind: the other sources lane by lane.
        let fs: Vec<WindField> = (0..4)
            .map(|l| {
                let f = field(0.01, |c| {
                    c.wind.speed = 2.0 + l as f64;
                    c.wind.gusts = vec![ramp(0.1 * l as f64)];
                });
                f.prescribed(prescribed_rows(0.3 * l as f64))
            })
            .collect();
        let refs: Vec<&WindField> = fs.iter().collect();
        let (sources, one) = seeded(&refs, 2);
        wind_matches::<F64x4>(&refs, sources, one, 200, kin);
    }
}
