//! A small driver for profiling the hot loop (callgrind, perf) and for before/after checks.
//!
//!     cargo run --release --example hotloop -- MODE DURATION_S [CTRL] [RUNS]
//!
//! MODE: `scalar` (Engine::fly::<f64>), `simd` (one lane-set of the active path), `batch` (run_batch on
//! the global pool), `metrics` (print full-precision metrics of a few realisations, scalar and
//! SIMD, to compare physics before and after a change; `metrics-lateral` the same off the
//! vertical line, with all gust components). CTRL: pd | smc (default pd).

use _core::control::ControllerKind;
use _core::integrate::{Engine, FlightRequest};
use _core::montecarlo::{pool, run_batch, Batch};
use _core::scenario::Config;
use rustfft::FftPlanner;
use std::sync::atomic::{AtomicBool, AtomicU64};
use std::time::Instant;

fn paper(duration: f64) -> Config {
    let text = include_str!("../python/quadrs/presets/paper.toml");
    let v: serde_json::Value = toml::from_str(text).expect("paper.toml");
    let mut cfg = Config::from_json(&v.to_string()).expect("valid");
    if duration < cfg.integrator.duration {
        cfg.integrator.duration = duration;
        cfg.phases
            .retain(|p| p.start + 2.0 * cfg.integrator.dt < duration);
        if let Some(last) = cfg.phases.last_mut() {
            last.end = last.end.min(duration);
        }
    }
    cfg
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let mode = args.get(1).map_or("scalar", |s| s.as_str());
    let duration: f64 = args.get(2).map_or(70.0, |s| s.parse().expect("duration"));
    let kind = ControllerKind::parse(args.get(3).map_or("pd", |s| s.as_str())).expect("ctrl");
    let runs: usize = args.get(4).map_or(4, |s| s.parse().expect("runs"));
    // One lane-set of the engine's path (QUADRS_SIMD): four realisations, eight on AVX-512.
    let set: Vec<u64> = (0.._core::lane::isa::Isa::active()
        .expect("QUADRS_SIMD")
        .lane_count() as u64)
        .collect();
    let mut cfg = paper(duration);
    if mode == "metrics-lateral" {
        // Off the paper's vertical line: lateral offsets, all three gust components, and the
        // SMC's lateral gains of the paper_stable_lateral preset (the paper's are unstable).
        use _core::config::GustComponent::*;
        cfg.initial.position = [0.3, -0.2, 0.0];
        cfg.initial.attitude = [0.05, -0.03, 0.5];
        cfg.gust.components = vec![Longitudinal, Lateral, Vertical];
        let smc = &mut cfg.controller.smc;
        smc.epsilon = [0.16, 0.16, 1.8];
        smc.lambda = [1.2, 1.2, 3.2];
        smc.epsilon_attitude = [1.432, 1.432, 1.1];
        smc.lambda_attitude = [7.2, 7.2, 1.5];
    }
    let engine = Engine::new(cfg).expect("engine");
    let mut planner = FftPlanner::new();
    let t0 = Instant::now();
    let real_steps = match mode {
        "scalar" => {
            let r = engine
                .fly::<f64>(&FlightRequest::new(kind, 1, &[0]), None, &mut planner)
                .unwrap();
            println!(
                "iae {:?}",
                r[0].metrics.iter().map(|m| m[0]).collect::<Vec<_>>()
            );
            engine.steps
        }
        "simd" => {
            let r = engine
                .fly_set(&FlightRequest::new(kind, 1, &set), &mut planner)
                .unwrap();
            println!(
                "iae {:?}",
                r[0].metrics.iter().map(|m| m[0]).collect::<Vec<_>>()
            );
            set.len() * engine.steps
        }
        "batch" => {
            let (p, c) = (AtomicU64::new(0), AtomicBool::new(false));
            let workers = std::thread::available_parallelism().map_or(1, |n| n.get());
            let workers = args.get(5).map_or(workers, |s| s.parse().expect("workers"));
            let out = pool(workers).install(|| {
                let kinds = [ControllerKind::Pd, ControllerKind::Smc];
                let b = Batch {
                    want_spectra: true,
                    ..Batch::new(&kinds, 1, 0, runs)
                };
                run_batch(&engine, &b, &p, &c)
            });
            println!("first iae {}", out.metrics[0]);
            2 * runs * engine.steps
        }
        "metrics" | "metrics-lateral" => {
            for kind in [ControllerKind::Pd, ControllerKind::Smc] {
                let simd = engine
                    .fly_set(
                        &FlightRequest {
                            want_spectra: true,
                            ..FlightRequest::new(kind, 11, &set)
                        },
                        &mut planner,
                    )
                    .unwrap();
                for (lane, r) in simd.iter().enumerate() {
                    let s = engine
                        .fly::<f64>(
                            &FlightRequest {
                                want_spectra: true,
                                ..FlightRequest::new(kind, 11, &[lane as u64])
                            },
                            None,
                            &mut planner,
                        )
                        .unwrap();
                    for (p, (a, b)) in r.metrics.iter().zip(&s[0].metrics).enumerate() {
                        println!("{} r{lane} P{} simd {:?}", kind.name(), p + 1, a);
                        println!("{} r{lane} P{} scal {:?}", kind.name(), p + 1, b);
                    }
                }
            }
            return;
        }
        other => panic!("unknown mode {other}"),
    };
    let secs = t0.elapsed().as_secs_f64();
    println!(
        "{mode}: {real_steps} realisation-steps in {secs:.3} s = {:.3} M/s",
        real_steps as f64 / secs / 1e6
    );
}
