//! The batch: realisations in parallel, one SIMD lane-set at a time (four realisations, eight
//! on AVX-512: `Engine::lanes_per_set`), every controller flown through the same gust (common
//! random numbers). Only per-phase metrics and running spectrum sums are kept, so memory does
//! not grow with the number of realisations beyond the result table. `run_innovations` flies
//! given standard normals instead of seeded realisations (rare events), the same way.

use crate::config::ConfigError;
use crate::control::ControllerKind;
use crate::dispersion::Dispersion;
use crate::integrate::{Engine, ExitStatus, FlightRequest, Realisation};
use crate::metrics::N_METRICS;
use rayon::prelude::*;
use rustfft::FftPlanner;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, OnceLock};

/// Ensemble sums of amplitude spectra: per controller, per phase, per bin.
#[derive(Clone, Debug, Default)]
pub struct SpectrumSums {
    pub sum: Vec<Vec<Vec<f64>>>,
    pub sum_sq: Vec<Vec<Vec<f64>>>,
    /// Non-diverged realisations that contributed, per controller.
    pub count: Vec<u64>,
}

impl SpectrumSums {
    fn zeros(n_ctrl: usize, grid: &[Vec<f64>]) -> Self {
        let per_ctrl: Vec<Vec<f64>> = grid.iter().map(|g| vec![0.0; g.len()]).collect();
        Self {
            sum: vec![per_ctrl.clone(); n_ctrl],
            sum_sq: vec![per_ctrl; n_ctrl],
            count: vec![0; n_ctrl],
        }
    }

    fn add(&mut self, ctrl: usize, spectra: &[Vec<f64>]) {
        for (p, amp) in spectra.iter().enumerate() {
            for (i, a) in amp.iter().enumerate() {
                self.sum[ctrl][p][i] += a;
                self.sum_sq[ctrl][p][i] += a * a;
            }
        }
        self.count[ctrl] += 1;
    }

    fn merge(mut self, other: Self) -> Self {
        for c in 0..self.sum.len() {
            for p in 0..self.sum[c].len() {
                for i in 0..self.sum[c][p].len() {
                    self.sum[c][p][i] += other.sum[c][p][i];
                    self.sum_sq[c][p][i] += other.sum_sq[c][p][i];
                }
            }
            self.count[c] += other.count[c];
        }
        self
    }
}

/// Results of realisations first..first+count.
#[derive(Clone, Debug)]
pub struct BatchOutput {
    /// Row-major (count, n_ctrl, n_phase, N_METRICS); NaN where diverged or not done.
    pub metrics: Vec<f64>,
    /// (count, n_ctrl): time of divergence, NaN if none.
    pub diverged_at: Vec<f64>,
    /// (count, n_ctrl): why each flight ended (`ExitStatus as u8`; `Ok` if not done).
    pub status: Vec<u8>,
    /// (count,): the realisation finished (false only after a cancel).
    pub done: Vec<bool>,
    pub spectra: SpectrumSums,
    /// A dispersed realisation a law cannot start at its reference (`Refusal`): the batch
    /// stopped there, and its results are not to be read.
    pub refused: Option<ConfigError>,
}

/// The first dispersed realisation whose law has no equilibrium at its reference
/// (`LawStart::refused`: the SMC's integral limit cannot hold that realisation's drag). The
/// scenario's own vehicle is refused before a batch starts (`Engine::check_start`); a
/// realisation's is known only once its start is solved, in the batch, which then stops and is
/// refused naming it, as a drawn value the scenario refuses is (`Dispersion::config`). The one
/// named is the lowest refused, whatever the threads' order: a lane-set is skipped only when
/// its rows all come after a realisation already refused (`passed`).
struct Refusal {
    lowest: AtomicU64,
    kept: Mutex<Option<ConfigError>>,
}

impl Refusal {
    fn new() -> Self {
        Self {
            lowest: AtomicU64::new(u64::MAX),
            kept: Mutex::new(None),
        }
    }

    /// Whether realisation `index` comes after one already refused.
    fn passed(&self, index: u64) -> bool {
        index > self.lowest.load(Ordering::Relaxed)
    }

    /// Whether a law in `kinds` of the lanes' `realisations` (realisation `index[l]`) is
    /// refused (`refuse`).
    fn check(
        &self,
        realisations: &[Realisation],
        index: impl Iterator<Item = u64>,
        kinds: &[ControllerKind],
        cancel: &AtomicBool,
    ) -> bool {
        let found = realisations.iter().zip(index).find_map(|(r, index)| {
            kinds
                .iter()
                .find_map(|&k| r.start(k).refused.as_ref().map(|e| (index, k, e)))
        });
        found.is_some_and(|(index, kind, e)| {
            self.refuse(index, kind, e, cancel);
            true
        })
    }

    /// Realisation `index`'s law `kind` refused (`e`): kept if the lowest so far; `cancel`
    /// stops the batch.
    fn refuse(&self, index: u64, kind: ControllerKind, e: &ConfigError, cancel: &AtomicBool) {
        let mut kept = self.kept.lock().unwrap_or_else(|p| p.into_inner());
        if index < self.lowest.load(Ordering::Relaxed) {
            self.lowest.store(index, Ordering::Relaxed);
            *kept = Some(ConfigError {
                key: e.key.clone(),
                message: format!(
                    "dispersions: realisation {index} drew values the {} law has no start at \
                     its reference for: {} (narrow or truncate the distribution)",
                    kind.name(),
                    e.message
                ),
            });
        }
        cancel.store(true, Ordering::Relaxed);
    }

    fn into_error(self) -> Option<ConfigError> {
        self.kept.into_inner().unwrap_or_else(|p| p.into_inner())
    }
}

/// Thread pools kept alive between calls (most recently used last).
pub const POOLS_KEPT: usize = 2;

/// Each worker thread's stack (see `pool`).
const WORKER_STACK: usize = 16 << 20;

/// A rayon pool of `workers` threads, reused across calls. Only the `POOLS_KEPT` most recently
/// used sizes are kept: a pool evicted while a batch still runs on it lives until that batch
/// ends (the batch holds an `Arc`), then its threads exit. So calling with many different
/// `workers` values never accumulates threads.
pub fn pool(workers: usize) -> Arc<rayon::ThreadPool> {
    type Pools = Vec<(usize, Arc<rayon::ThreadPool>)>;
    static POOLS: OnceLock<Mutex<Pools>> = OnceLock::new();
    let workers = workers.max(1);
    let mut pools = POOLS
        .get_or_init(Default::default)
        .lock()
        .unwrap_or_else(|e| e.into_inner());
    if let Some(i) = pools.iter().position(|(n, _)| *n == workers) {
        let entry = pools.remove(i);
        pools.push(entry);
    } else {
        let built = rayon::ThreadPoolBuilder::new()
            .num_threads(workers)
            .thread_name(|i| format!("quadrs-worker-{i}"))
            // A flight's frames hold whole lane-sets of states (eight lanes of every state on
            // AVX-512): an unoptimised build needs between 2 and 4 MiB, past the 2 MiB a
            // thread gets by default. Reserved, not touched: address space, not memory.
            .stack_size(WORKER_STACK)
            .build()
            .expect("thread pool");
        pools.push((workers, Arc::new(built)));
        if pools.len() > POOLS_KEPT {
            pools.remove(0);
        }
    }
    pools.last().expect("just pushed").1.clone()
}

/// A batch: realisations `first..first + count` under every controller in `kinds`.
#[derive(Clone, Copy)]
pub struct Batch<'a> {
    pub kinds: &'a [ControllerKind],
    pub seed: u64,
    pub first: u64,
    pub count: usize,
    pub want_spectra: bool,
    /// Per realisation, the values of the dispersed keys (row j: realisation first + j).
    pub dispersion: Option<&'a Dispersion>,
    /// Per realisation, the gust stream it flies (default: its own index, first + j). A
    /// sensitivity design sets it to reuse one gust across rows that differ in parameters.
    pub streams: Option<&'a [u64]>,
}

impl<'a> Batch<'a> {
    pub fn new(kinds: &'a [ControllerKind], seed: u64, first: u64, count: usize) -> Self {
        Self {
            kinds,
            seed,
            first,
            count,
            want_spectra: false,
            dispersion: None,
            streams: None,
        }
    }

    /// Check the per-realisation inputs before anything flies: every drawn scenario valid.
    pub fn check(&self) -> Result<(), ConfigError> {
        if let Some(s) = self.streams {
            if s.len() != self.count {
                return Err(ConfigError {
                    key: "streams".into(),
                    message: format!("{} gust streams for {} realisations", s.len(), self.count),
                });
            }
        }
        if let Some(d) = self.dispersion {
            if d.rows() != self.count {
                return Err(ConfigError {
                    key: "dispersions".into(),
                    message: format!(
                        "dispersions: {} rows of values for {} realisations",
                        d.rows(),
                        self.count
                    ),
                });
            }
            (0..self.count)
                .into_par_iter()
                .try_for_each(|j| d.config(j, self.first).map(|_| ()))?;
        }
        Ok(())
    }
}

/// One flight of `kind` per row of `rows` (each a flight's standard normals,
/// `Engine::innovations` of them), in lane-sets on `workers` threads: metrics row-major
/// (rows, phases, N_METRICS), NaN after a divergence. With `dispersion`, row j flies the
/// scenario with its row j of values (checked by the caller: `Dispersion::config` accepts
/// every row; a row whose law has no start at its reference is refused by name, `Refusal`).
/// `done` counts finished rows; None if `cancel` was set.
pub fn run_innovations(
    engine: &Engine,
    kind: ControllerKind,
    rows: &[&[f64]],
    dispersion: Option<&Dispersion>,
    workers: usize,
    done: &AtomicU64,
    cancel: &AtomicBool,
) -> Result<Option<Vec<f64>>, ConfigError> {
    let e = engine;
    let refusal = Refusal::new();
    let n = rows.len();
    let row = e.phase_count() * N_METRICS;
    let mut metrics = vec![f64::NAN; n * row];
    let lanes = e.lanes_per_set();
    let finished = pool(workers).install(|| {
        metrics
            .par_chunks_mut(lanes * row)
            .enumerate()
            .map_init(FftPlanner::new, |planner, (set, out)| {
                if refusal.passed((set * lanes) as u64) {
                    return false;
                }
                // Pad the last lane-set by repeating its final row.
                let set_rows: Vec<usize> =
                    (0..lanes).map(|l| (set * lanes + l).min(n - 1)).collect();
                let mine: Vec<&[f64]> = set_rows.iter().map(|&j| rows[j]).collect();
                let indices: Vec<u64> = (0..lanes as u64).collect();
                let realisations = match dispersion {
                    Some(d) => match dispersed_set(e, d, &set_rows, 0, &[kind], (&refusal, cancel))
                    {
                        Some(r) => Some(r),
                        None => return false,
                    },
                    None => None,
                };
                let lane_realisations: Option<Vec<&Realisation>> =
                    realisations.as_ref().map(|c| c.iter().collect());
                let req = FlightRequest {
                    cancel: Some(cancel),
                    realisations: lane_realisations.as_deref(),
                    innovations: Some(&mine),
                    ..FlightRequest::new(kind, 0, &indices)
                };
                let Some(res) = e.fly_set(&req, planner) else {
                    return false;
                };
                for (l, r) in res.iter().take(out.len() / row).enumerate() {
                    for (p, m) in r.metrics.iter().enumerate() {
                        let at = l * row + p * N_METRICS;
                        out[at..at + N_METRICS].copy_from_slice(m);
                    }
                }
                done.fetch_add((out.len() / row) as u64, Ordering::Relaxed);
                true
            })
            // Every set is visited (`all` would stop at the first false, and a set below the
            // realisation refused first could go unchecked): the lowest refused is named.
            .reduce(|| true, |a, b| a && b)
    });
    match refusal.into_error() {
        Some(e) => Err(e),
        None => Ok(finished.then_some(metrics)),
    }
}

/// Lane-set `set` of `batch` (`engine.lanes_per_set()` a set): each lane's stream index, and in
/// a dispersed batch each lane's realisation (its own vehicle), built once per set, reusing the
/// scenario's gust filters unless a gust key is dispersed. The last set is padded by repeating
/// the final realisation; padded lanes are dropped. `None` where a realisation's law has no
/// start at its reference, or the set comes after one that had none (`Refusal`).
fn lane_set(
    engine: &Engine,
    batch: &Batch,
    set: usize,
    (refusal, cancel): (&Refusal, &AtomicBool),
) -> Option<(Vec<u64>, Option<Vec<Realisation>>)> {
    let (first, count, lanes) = (batch.first, batch.count, engine.lanes_per_set());
    if refusal.passed(first + (set * lanes) as u64) {
        return None;
    }
    let rows: Vec<usize> = (0..lanes)
        .map(|l| (set * lanes + l).min(count - 1))
        .collect();
    let indices: Vec<u64> = rows
        .iter()
        .map(|&j| match batch.streams {
            Some(s) => s[j],
            None => first + j as u64,
        })
        .collect();
    let realisations = match batch.dispersion {
        Some(d) => Some(dispersed_set(
            engine,
            d,
            &rows,
            first,
            batch.kinds,
            (refusal, cancel),
        )?),
        None => None,
    };
    Some((indices, realisations))
}

/// Each lane's realisation of rows `rows` of the dispersion `d` (realisations `first + j`):
/// its own vehicle, with the scenario's gust filters unless a gust key is dispersed, and the
/// starts of the laws `kinds`. `None` where a lane's law has no start at its reference
/// (`Refusal` keeps the lowest such realisation to name).
fn dispersed_set(
    engine: &Engine,
    d: &Dispersion,
    rows: &[usize],
    first: u64,
    kinds: &[ControllerKind],
    (refusal, cancel): (&Refusal, &AtomicBool),
) -> Option<Vec<Realisation>> {
    let wind = (!d.touches_wind()).then_some(&engine.realisation);
    let set: Vec<Realisation> = rows
        .iter()
        .map(|&j| {
            let cfg = d
                .patched(j, first)
                .expect("every row is checked before the batch");
            Realisation::for_laws(&cfg, wind, kinds).expect("every row is checked before the batch")
        })
        .collect();
    let index = rows.iter().map(|&j| first + j as u64);
    (!refusal.check(&set, index, kinds, cancel)).then_some(set)
}

/// Fly `batch` (checked with `Batch::check`). `progress` counts finished realisations; setting
/// `cancel` stops work promptly and leaves `done` false for whatever had not finished.
pub fn run_batch(
    engine: &Engine,
    batch: &Batch,
    progress: &AtomicU64,
    cancel: &AtomicBool,
) -> BatchOutput {
    let Batch {
        kinds,
        seed,
        count,
        want_spectra,
        ..
    } = *batch;
    let n_ctrl = kinds.len();
    let n_phase = engine.phase_count();
    let row = n_ctrl * n_phase * N_METRICS;
    let grid = engine.spectrum_grid();
    let mut metrics = vec![f64::NAN; count * row];
    let mut diverged_at = vec![f64::NAN; count * n_ctrl];
    let mut status = vec![ExitStatus::Ok as u8; count * n_ctrl];
    let mut done = vec![false; count];
    let lanes_per_set = engine.lanes_per_set();
    let refusal = Refusal::new();

    // Each lane-set writes its rows straight into the output (disjoint chunks): nothing per set
    // is kept on the heap, so memory is the output arrays plus a few buffers per thread.
    let spectra = metrics
        .par_chunks_mut(lanes_per_set * row)
        .zip(diverged_at.par_chunks_mut(lanes_per_set * n_ctrl))
        .zip(
            status
                .par_chunks_mut(lanes_per_set * n_ctrl)
                .zip(done.par_chunks_mut(lanes_per_set)),
        )
        .enumerate()
        .fold(
            || {
                // Per thread: spectrum sums, FFT plans and the rows and spectra of the set in
                // flight.
                let buffers = (
                    vec![f64::NAN; lanes_per_set * row],
                    vec![(f64::NAN, ExitStatus::Ok as u8); lanes_per_set * n_ctrl],
                    Vec::new(),
                );
                (
                    SpectrumSums::zeros(n_ctrl, &grid),
                    FftPlanner::new(),
                    buffers,
                )
            },
            |(mut spectra, mut planner, (mut set_metrics, mut set_diverged, mut set_spectra)),
             (set, ((out_metrics, out_diverged), (out_status, out_done)))| {
                set_spectra.clear();
                let refused = (&refusal, cancel);
                let Some((indices, realisations)) = lane_set(engine, batch, set, refused) else {
                    return (spectra, planner, (set_metrics, set_diverged, set_spectra));
                };
                let lane_realisations: Option<Vec<&Realisation>> =
                    realisations.as_ref().map(|c| c.iter().collect());
                let lanes = out_done.len();
                for (c, &kind) in kinds.iter().enumerate() {
                    if cancel.load(Ordering::Relaxed) {
                        return (spectra, planner, (set_metrics, set_diverged, set_spectra));
                    }
                    let req = FlightRequest {
                        want_spectra,
                        cancel: Some(cancel),
                        realisations: lane_realisations.as_deref(),
                        ..FlightRequest::new(kind, seed, &indices)
                    };
                    let Some(res) = engine.fly_set(&req, &mut planner) else {
                        return (spectra, planner, (set_metrics, set_diverged, set_spectra));
                    };
                    for (l, r) in res.into_iter().take(lanes).enumerate() {
                        set_diverged[l * n_ctrl + c] = (r.diverged_at, r.status as u8);
                        for (p, m) in r.metrics.iter().enumerate() {
                            let at = l * row + (c * n_phase + p) * N_METRICS;
                            set_metrics[at..at + N_METRICS].copy_from_slice(m);
                        }
                        if want_spectra && r.diverged_at.is_nan() {
                            set_spectra.push((c, r.spectra));
                        }
                    }
                }
                // Only a finished set is published (a cancelled one stays NaN, not done).
                out_metrics.copy_from_slice(&set_metrics[..lanes * row]);
                for ((d, s), &(at, why)) in out_diverged
                    .iter_mut()
                    .zip(out_status.iter_mut())
                    .zip(&set_diverged[..lanes * n_ctrl])
                {
                    (*d, *s) = (at, why);
                }
                out_done.fill(true);
                // ... and only then are its spectra counted, so the spectrum counts always
                // equal the finished, non-diverged realisations (a cancel mid-set adds none).
                for (c, amp) in &set_spectra {
                    spectra.add(*c, amp);
                }
                progress.fetch_add(lanes as u64, Ordering::Relaxed);
                (spectra, planner, (set_metrics, set_diverged, set_spectra))
            },
        )
        .map(|(spectra, _, _)| spectra)
        .reduce(|| SpectrumSums::zeros(n_ctrl, &grid), SpectrumSums::merge);

    BatchOutput {
        metrics,
        diverged_at,
        status,
        done,
        spectra,
        refused: refusal.into_error(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::tests::paper_cut;
    use crate::scenario::Config;

    fn short() -> Config {
        let mut cfg = paper_cut(6.0, 2e-3, 2);
        cfg.gust.start = 1.0;
        cfg.gust.end = 5.0;
        cfg.phases[0].end = 3.0;
        cfg.phases[1].start = 3.0;
        cfg
    }

    fn batch(engine: &Engine, first: u64, count: usize, workers: usize) -> BatchOutput {
        let (p, c) = (AtomicU64::new(0), AtomicBool::new(false));
        let kinds = [ControllerKind::Pd, ControllerKind::Smc];
        let b = Batch {
            want_spectra: true,
            ..Batch::new(&kinds, 3, first, count)
        };
        pool(workers).install(|| run_batch(engine, &b, &p, &c))
    }

    #[test]
    fn results_depend_only_on_seed_and_index() {
        let engine = Engine::new(short()).unwrap();
        let a = batch(&engine, 0, 10, 1);
        let b = batch(&engine, 0, 10, 2);
        assert_eq!(a.metrics.len(), 10 * 2 * 3 * N_METRICS); // 2 phases and the whole flight
        assert!(a.done.iter().all(|d| *d));
        assert_eq!(
            a.metrics.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
            b.metrics.iter().map(|x| x.to_bits()).collect::<Vec<_>>()
        );
        // Realisations 3..9 alone equal the same rows inside 0..10 (different lane packing).
        let c = batch(&engine, 3, 6, 2);
        let row = 2 * engine.phase_count() * N_METRICS;
        assert_eq!(
            c.metrics.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
            a.metrics[3 * row..9 * row]
                .iter()
                .map(|x| x.to_bits())
                .collect::<Vec<_>>()
        );
    }

    /// Flying the innovations seeded realisations draw gives those realisations' metrics, bit
    /// for bit, however the rows fall into lane-sets and threads; a cancel flag set beforehand
    /// returns None.
    #[test]
    fn innovations_fly_the_seeded_realisations() {
        let engine = Engine::new(short()).unwrap();
        let n = 5;
        let seeded = batch(&engine, 0, n, 1);
        let xi: Vec<Vec<f64>> = (0..n as u64).map(|i| engine.innovations_of(3, i)).collect();
        let rows: Vec<&[f64]> = xi.iter().map(|r| r.as_slice()).collect();
        let (done, cancel) = (AtomicU64::new(0), AtomicBool::new(false));
        for kind in [ControllerKind::Pd, ControllerKind::Smc] {
            for workers in [1, 2] {
                let got = run_innovations(&engine, kind, &rows, None, workers, &done, &cancel)
                    .expect("not dispersed")
                    .expect("not cancelled");
                let per = engine.phase_count() * N_METRICS;
                let c = kind as usize;
                for j in 0..n {
                    let want = &seeded.metrics[(j * 2 + c) * per..(j * 2 + c + 1) * per];
                    let bits = |x: &[f64]| x.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
                    assert_eq!(bits(&got[j * per..(j + 1) * per]), bits(want), "row {j}");
                }
            }
        }
        assert_eq!(done.load(Ordering::Relaxed), 4 * n as u64);
        cancel.store(true, Ordering::Relaxed);
        let kind = ControllerKind::Pd;
        let got = run_innovations(&engine, kind, &rows, None, 1, &done, &cancel);
        assert!(got.expect("not dispersed").is_none());
    }

    /// The spectrum counts equal the finished, non-diverged realisations per controller, even
    /// when a cancel lands between the controllers of a lane-set.
    #[test]
    fn spectra_count_only_published_sets() {
        let engine = Engine::new(short()).unwrap();
        let kinds = [ControllerKind::Pd, ControllerKind::Smc];
        for _ in 0..3 {
            let (p, c) = (AtomicU64::new(0), AtomicBool::new(false));
            let out = std::thread::scope(|scope| {
                // Cancel as soon as the first set is published: the second set is then (almost
                // always) inside its PD flight, so its SMC flight never starts.
                scope.spawn(|| {
                    while p.load(Ordering::Relaxed) < engine.lanes_per_set() as u64 {
                        std::hint::spin_loop();
                    }
                    c.store(true, Ordering::Relaxed);
                });
                {
                    let b = Batch {
                        want_spectra: true,
                        ..Batch::new(&kinds, 3, 0, 3 * engine.lanes_per_set())
                    };
                    pool(1).install(|| run_batch(&engine, &b, &p, &c))
                }
            });
            for k in 0..kinds.len() {
                let finished = (0..3 * engine.lanes_per_set())
                    .filter(|&i| out.done[i] && out.diverged_at[i * kinds.len() + k].is_nan())
                    .count() as u64;
                assert_eq!(out.spectra.count[k], finished, "controller {k}: {out:?}");
            }
        }
    }

    #[test]
    fn pools_are_bounded() {
        let first = pool(3);
        for w in 4..10 {
            pool(w);
        }
        // Evicted from the cache: only our handle keeps the first pool alive.
        assert_eq!(Arc::strong_count(&first), 1);
    }

    #[test]
    fn cancel_stops_and_reports_nothing_false() {
        let engine = Engine::new(short()).unwrap();
        let (p, c) = (AtomicU64::new(0), AtomicBool::new(true));
        let out = run_batch(&engine, &Batch::new(&[ControllerKind::Pd], 0, 0, 8), &p, &c);
        assert!(out.done.iter().all(|d| !d));
        assert!(out.metrics.iter().all(|x| x.is_nan()));
    }

    /// A batch refused by several realisations, found in any order, names the lowest, and
    /// skips only the lane-sets past one already refused (so it always finds the lowest).
    /// (A dispersed batch refused end to end: tests/engine/test_dispersed_starts.py.)
    #[test]
    fn a_refused_batch_names_its_lowest_refused_realisation() {
        let r = Refusal::new();
        let cancel = AtomicBool::new(false);
        assert!(!r.passed(u64::MAX - 1) && !cancel.load(Ordering::Relaxed));
        let e = |key: &str| ConfigError {
            key: key.into(),
            message: format!("{key} cannot hold it"),
        };
        r.refuse(10, ControllerKind::Smc, &e("a"), &cancel);
        assert!(cancel.load(Ordering::Relaxed));
        r.refuse(3, ControllerKind::Smc, &e("b"), &cancel);
        r.refuse(7, ControllerKind::Pd, &e("c"), &cancel);
        assert!(r.passed(4) && !r.passed(3) && !r.passed(0));
        let got = r.into_error().expect("refused");
        assert_eq!(got.key, "b");
        assert_eq!(
            got.message,
            "dispersions: realisation 3 drew values the smc law has no start at its reference \
             for: b cannot hold it (narrow or truncate the distribution)"
        );
        assert_eq!(Refusal::new().into_error(), None);
    }

    #[test]
    fn a_dispersed_row_equals_the_single_flight_of_its_drawn_scenario() {
        use crate::lane::isa::Isa;
        let cfg = short();
        let keys: Vec<String> = [
            "payload.mass",
            "payload.natural_frequency",
            "vehicle.inertia[2]",
            "controller.smc.lambda[2]",
            "gust.w20",
            "initial.position[0]",
        ]
        .map(String::from)
        .to_vec();
        let count = 6;
        let values: Vec<f64> = (0..count)
            .flat_map(|j| {
                let f = j as f64;
                [
                    0.1 + 0.05 * f,
                    1.5 + 0.2 * f,
                    0.05 + 0.002 * f,
                    3.0 + 0.1 * f,
                    5.0 + f,
                    0.01 * f,
                ]
            })
            .collect();
        let d = Dispersion::new(&cfg, keys, values, count).unwrap();
        let kinds = [ControllerKind::Pd, ControllerKind::Smc];
        let b = Batch {
            dispersion: Some(&d),
            ..Batch::new(&kinds, 5, 20, count)
        };
        b.check().unwrap();
        let mut engine = Engine::new(cfg).unwrap();
        let mut planner = FftPlanner::new();
        for isa in Isa::ALL {
            if !isa.supported() {
                eprintln!("skipped the {} path: this CPU cannot run it", isa.name());
                continue;
            }
            engine.isa = isa;
            let (p, c) = (AtomicU64::new(0), AtomicBool::new(false));
            let out = pool(2).install(|| run_batch(&engine, &b, &p, &c));
            let row = kinds.len() * engine.phase_count() * N_METRICS;
            for j in 0..count {
                let alone = Engine::new(d.config(j, 20).unwrap()).unwrap();
                for (ci, &kind) in kinds.iter().enumerate() {
                    let idx = [20 + j as u64];
                    let r = alone
                        .fly::<f64>(&FlightRequest::new(kind, 5, &idx), None, &mut planner)
                        .unwrap();
                    let want: Vec<u64> =
                        r[0].metrics.concat().iter().map(|x| x.to_bits()).collect();
                    let at = j * row + ci * engine.phase_count() * N_METRICS;
                    let got: Vec<u64> = out.metrics[at..at + engine.phase_count() * N_METRICS]
                        .iter()
                        .map(|x| x.to_bits())
                        .collect();
                    assert_eq!(got, want, "{isa:?} {kind:?} row {j}");
                }
            }
            // The rows differ: the dispersion reached the flights.
            assert_ne!(out.metrics[0].to_bits(), out.metrics[row].to_bits());
        }
        // A drawn value the scenario refuses is reported before anything flies.
        let bad =
            Dispersion::new(&engine.cfg, vec!["payload.mass".into()], vec![0.2, -1.0], 2).unwrap();
        let e = Batch {
            dispersion: Some(&bad),
            ..Batch::new(&kinds, 5, 0, 2)
        }
        .check()
        .unwrap_err();
        assert!(
            e.message.contains("realisation 1") && e.message.contains("payload.mass"),
            "{e:?}"
        );
    }
}
