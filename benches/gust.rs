//! Criterion bench of the gust field alone, through the interface the flight loop uses
//! (`WindField::new`, `realisation`, `sample`, once per lane per step).
//!
//!     cargo bench --bench gust
//!
//! Paper preset gust (vertical Dryden, h = 2 m, W20 = 10 m/s, V = 10 m/s, dt = 2e-4 s,
//! window [25, 40) s). `in_window`: the 75,000 steps of the window for one realisation (two
//! normals per step); `outside`: 75,000 steps before the window (zeros). Throughput is in
//! samples (`elem/s`).

use _core::gust::WindField;
use _core::scenario::Config;
use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use std::hint::black_box;
use std::time::Duration;

const DT: f64 = 2e-4;

/// The paper preset, whose gust and step the numbers above describe.
fn paper() -> Config {
    let text = include_str!("../python/quadrs/presets/paper.toml");
    let value: serde_json::Value = toml::from_str(text).expect("paper.toml parses");
    let cfg = Config::from_json(&value.to_string()).expect("paper preset is valid");
    assert_eq!(cfg.integrator.dt, DT);
    assert_eq!((cfg.gust.start, cfg.gust.end), (25.0, 40.0));
    cfg
}

fn gust(c: &mut Criterion) {
    let field = WindField::new(&paper().wind_context()).unwrap();
    let first = (25.0 / DT).round() as u64;
    let n = ((40.0 - 25.0) / DT).round() as u64;
    let mut g = c.benchmark_group("gust");
    g.sample_size(20).measurement_time(Duration::from_secs(3));
    g.throughput(Throughput::Elements(n));
    let mut index = 0;
    g.bench_function("in_window", |b| {
        b.iter(|| {
            index += 1;
            let mut state = field.realisation(7, index);
            let mut sum = 0.0;
            for step in first..first + n {
                sum += field.sample(&mut state, black_box(step))[2];
            }
            sum
        })
    });
    g.bench_function("outside", |b| {
        b.iter(|| {
            let mut state = field.realisation(7, 0);
            let mut sum = 0.0;
            for step in 0..n {
                sum += field.sample(&mut state, black_box(step))[2];
            }
            sum
        })
    });
    g.finish();
}

criterion_group!(benches, gust);
criterion_main!(benches);
