//! The turbulence of a whole lane-set at once: each lane's normals drawn in bulk from its own
//! source (the realisation's seeded stream or its given innovations, exactly as
//! [`WindField::sample_at`] would draw them), the forming filters advanced as lane values.
//!
//! Per lane the arithmetic is operation for operation that of the per-realisation path
//! (`WindField::sample_at`: `step_fixed`, `GustFilter::output`, the axes' turn), with the lane
//! operators that never fuse, so a lane's gust is bitwise the scalar one whatever the lane
//! type, the packing of realisations into lanes or the engine's fused mode. What changes is
//! only where the time goes: the normals of many steps are drawn in one tight loop per lane
//! (no per-normal dispatch on the source, no per-step match on the filters' orders), and the
//! filters of all lanes advance in one pass of vector arithmetic.

use super::filter::Normals;
use super::normal::{Ahead, CHUNK};
use super::wind::{Source, WindField};
use crate::lane::isa::Isa;
use crate::lane::Lane;

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
/// it (see there), sampled once per step inside the window by [`LaneGust::sample`].
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
    /// wind field; `None` where the per-realisation path must fly it instead: where a field
    /// has no turbulence, where its turbulence follows the vehicle (`gust.altitude =
    /// "vehicle"`, `gust.airspeed = "relative"`) or another source blows (a `[wind]` mean
    /// wind, a discrete gust), or where the lanes differ in window, components, orders or
    /// whether the axes are turned.
    pub fn new(fields: &[&WindField], sources: Vec<Source<'a>>) -> Option<Self> {
        assert!(L::LANES <= MAX_LANES && fields.len() == L::LANES);
        assert_eq!(sources.len(), L::LANES, "one source per lane");
        let first = fields[0];
        let usable = |f: &WindField| f.enabled() && !f.follows_vehicle() && !f.blows();
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
        match self.axes {
            None => w,
            Some((cos, sin)) => [
                w[0] * cos - w[1] * sin + self.mean[0],
                w[0] * sin + w[1] * cos + self.mean[1],
                w[2] + self.mean[2],
            ],
        }
    }

    /// Start the filters (stationary states, at the window's first step) if not yet, and
    /// advance them once per step up to `step`.
    #[inline(never)]
    fn advance_to(&mut self, step: u64) {
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
    use crate::config::{Config, GustAltitude, GustComponent, GustModel};
    use crate::lane::F64x4;
    use rand::Rng;

    /// The paper preset's gust with `edit` applied, for the step `dt` (window [0.5, 3) s).
    fn field(dt: f64, edit: impl Fn(&mut Config)) -> WindField {
        let mut cfg = crate::config::tests::paper();
        cfg.gust.enabled = true;
        cfg.gust.start = 0.5;
        cfg.gust.end = 3.0;
        cfg.integrator.dt = dt;
        edit(&mut cfg);
        cfg.validate().unwrap();
        WindField::new(&cfg).unwrap()
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
                let want = super::super::normal::standard_normal(&mut rng);
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
        let vehicle = field(0.01, |c| c.gust.altitude = GustAltitude::Vehicle);
        let blows = field(0.01, |c| c.wind.speed = 2.0);
        for f in [&off, &vehicle, &blows] {
            assert!(LaneGust::<f64>::new(&[f], src(f)).is_none());
        }
        // Lanes that differ in their window or components.
        let later = field(0.01, |c| c.gust.start = 1.0);
        let three = field(0.01, |c| c.gust.components = GustComponent::ALL.to_vec());
        for other in [&later, &three] {
            let fields = [&plain, &plain, other, &plain];
            let sources = fields
                .iter()
                .map(|f| f.realisation(0, 0).source())
                .collect();
            assert!(LaneGust::<F64x4>::new(&fields, sources).is_none());
        }
    }
}
