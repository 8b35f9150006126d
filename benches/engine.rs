//! Criterion benches of the flight loop on the paper preset (350,000 RK4 steps per flight).
//!
//!     cargo bench --bench engine
//!
//! Throughput is reported in realisation-steps (one RK4 step of one realisation under one
//! controller): `elem/s` in criterion's output. Benches:
//! - `single_flight/scalar`: `Engine::fly::<f64>`, one realisation (the `simulate` path);
//! - `lane_set/<isa>`: `Engine::fly_set`, one lane-set at once (the Monte Carlo path: four
//!   realisations, eight on `avx512`), once per instruction set this CPU supports (`baseline` =
//!   SSE2, `avx2`, `avx512`) and, with `+fused`, in the opt-in fused mode where the path has
//!   FMA; the ones this CPU cannot run are named and skipped.
//!
//! - `turbulence/<case>`: `Engine::fly_set` on the widest path this CPU runs, 4 s flights with
//!   the gust on for the whole flight: `off` (gust disabled), `vertical` (the paper's
//!   component) and `three` (longitudinal, lateral and vertical), side by side in one run, so
//!   the turbulence's share of the loop reads off as a ratio of `elem/s`.
//!
//! Both controllers are flown in turn (PD then SMC), as a paired realisation is.

use _core::control::ControllerKind;
use _core::integrate::{Engine, FlightRequest};
use _core::lane::isa::Isa;
use _core::scenario::Config;
use criterion::measurement::WallTime;
use criterion::{
    criterion_group, criterion_main, BenchmarkGroup, BenchmarkId, Criterion, Throughput,
};
use rustfft::FftPlanner;
use std::hint::black_box;
use std::time::Duration;

fn paper() -> Config {
    let text = include_str!("../python/quadrs/presets/paper.toml");
    let value: serde_json::Value = toml::from_str(text).expect("paper.toml parses");
    Config::from_json(&value.to_string()).expect("paper preset is valid")
}

const KINDS: [ControllerKind; 2] = [ControllerKind::Pd, ControllerKind::Smc];

fn single_flight(c: &mut Criterion) {
    let engine = Engine::new(paper()).unwrap();
    let mut planner = FftPlanner::new();
    let mut g = c.benchmark_group("single_flight");
    g.sample_size(10).measurement_time(Duration::from_secs(4));
    g.throughput(Throughput::Elements((KINDS.len() * engine.steps) as u64));
    g.bench_function("scalar", |b| {
        b.iter(|| {
            for kind in KINDS {
                let idx = [black_box(0)];
                let req = FlightRequest {
                    want_spectra: true,
                    ..FlightRequest::new(kind, 1, &idx)
                };
                let r = engine.fly::<f64>(&req, None, &mut planner);
                black_box(r);
            }
        })
    });
    g.finish();
}

fn lane_set(c: &mut Criterion) {
    let mut engine = Engine::new(paper()).unwrap();
    let mut planner = FftPlanner::new();
    let mut g = c.benchmark_group("lane_set");
    g.sample_size(10).measurement_time(Duration::from_secs(4));
    let paths = Isa::ALL
        .into_iter()
        .flat_map(|isa| [(isa, false), (isa, true)]);
    for (isa, fused) in paths {
        let name = format!("{}{}", isa.name(), if fused { "+fused" } else { "" });
        if !isa.supported() || (fused && !isa.fused_supported()) {
            if !fused {
                eprintln!("lane_set/{name}: skipped, this CPU cannot run it");
            } else if isa.supported() {
                eprintln!("lane_set/{name}: skipped, no fused multiply-add on this path");
            }
            continue;
        }
        engine.isa = isa;
        engine.fused = fused;
        bench_set(&mut g, &name, &engine, &mut planner, true);
    }
    g.finish();
}

/// `Engine::fly_set` of one lane-set (realisations 0..), PD then SMC, as bench `name` of `g`.
fn bench_set(
    g: &mut BenchmarkGroup<WallTime>,
    name: &str,
    engine: &Engine,
    planner: &mut FftPlanner<f64>,
    want_spectra: bool,
) {
    let lanes = engine.lanes_per_set();
    g.throughput(Throughput::Elements(
        (KINDS.len() * lanes * engine.steps) as u64,
    ));
    let indices: Vec<u64> = (0..lanes as u64).collect();
    g.bench_with_input(BenchmarkId::from_parameter(name), &indices, |b, idx| {
        b.iter(|| {
            for kind in KINDS {
                let req = FlightRequest {
                    want_spectra,
                    ..FlightRequest::new(kind, 1, black_box(idx))
                };
                black_box(engine.fly_set(&req, planner));
            }
        })
    });
}

/// The paper preset cut to `seconds`, one phase, the gust on throughout with `components`
/// (none: the gust disabled).
fn whole_flight(seconds: f64, components: &[&str]) -> Config {
    let text = include_str!("../python/quadrs/presets/paper.toml");
    let mut v: serde_json::Value = toml::from_str(text).expect("paper.toml parses");
    v["integrator"]["duration"] = seconds.into();
    v["phases"] = serde_json::json!([{"name": "all", "start": 0.0, "end": seconds}]);
    let gust = &mut v["gust"];
    gust["start"] = 0.0.into();
    gust["end"] = seconds.into();
    gust["enabled"] = (!components.is_empty()).into();
    if !components.is_empty() {
        gust["components"] = serde_json::json!(components);
    }
    Config::from_json(&v.to_string()).expect("the cut preset is valid")
}

fn turbulence(c: &mut Criterion) {
    let mut planner = FftPlanner::new();
    let mut g = c.benchmark_group("turbulence");
    g.sample_size(10).measurement_time(Duration::from_secs(4));
    let cases: [(&str, &[&str]); 3] = [
        ("off", &[]),
        ("vertical", &["vertical"]),
        ("three", &["longitudinal", "lateral", "vertical"]),
    ];
    for (name, components) in cases {
        let engine = Engine::new(whole_flight(4.0, components)).unwrap();
        bench_set(&mut g, name, &engine, &mut planner, false);
    }
    g.finish();
}

criterion_group!(benches, single_flight, lane_set, turbulence);
criterion_main!(benches);
