use super::engine::LaneResult;
use super::engine::{Engine, FlightRequest, MAX_LANES};
use super::status::{classify, ExitStatus};
use super::trace::trace_columns;
use crate::control::ControllerKind;
use crate::lane::isa::Isa;
use crate::lane::F64x4;
use crate::model::actuator::Ideal;
use crate::model::paper_ix::{self as ix, NX};
use crate::model::payload::Spring;
use crate::model::{state_from_fn, AnyVehicle, Inputs, PaperVehicle, State, Trig};
use crate::rk4::rk4_step;
use crate::scenario::tests::{paper, paper_cut};
use crate::scenario::Config;
use rustfft::FftPlanner;

fn paper_vehicle(cfg: &Config) -> PaperVehicle {
    AnyVehicle::new(&cfg.model_context()).vehicle::<Spring, Ideal>()
}

fn step(v: &PaperVehicle, s: &State<f64, NX>, u: &Inputs<f64>, dt: f64) -> State<f64, NX> {
    rk4_step(v, s, &Trig::of(s), u, &[0.0; 3], dt)
}

/// Free two-body oscillation: thrust = total weight, no control, payload displaced by a.
fn free_oscillation_error(dt: f64, t_end: f64) -> f64 {
    let mut cfg = paper();
    cfg.gust.air_density = 0.0; // no drag: the analytic solution is undamped
    let plant = paper_vehicle(&cfg);
    let a = 0.05;
    let mut s: State<f64, NX> = plant.rest_state([0.0, 0.0, 2.0], [0.0; 3]);
    s[ix::ZC] -= a;
    let u = Inputs {
        u1: (plant.body.m + plant.payload.mc) * plant.body.g,
        tau: [0.0; 3],
    };
    let omega = (plant.payload.kc * (plant.body.m + plant.payload.mc)
        / (plant.body.m * plant.payload.mc))
        .sqrt();
    let n = (t_end / dt).round() as usize;
    for _ in 0..n {
        s = step(&plant, &s, &u, dt);
    }
    // Relative coordinate r = z - zc oscillates about d0 with amplitude a.
    let exact = plant.payload.hover_offset + a * (omega * n as f64 * dt).cos();
    (s[ix::Z] - s[ix::ZC] - exact).abs()
}

#[test]
fn rk4_converges_at_fourth_order() {
    let (e1, e2, e3) = (
        free_oscillation_error(0.02, 2.0),
        free_oscillation_error(0.01, 2.0),
        free_oscillation_error(0.005, 2.0),
    );
    for (coarse, fine) in [(e1, e2), (e2, e3)] {
        crate::testing::assert_halving_ratio(coarse, fine, 14.0..18.0);
    }
}

#[test]
fn free_oscillation_frequency_is_the_two_body_one() {
    // Count zero crossings of r - d0 over 10 s at fine dt, drag off.
    let mut cfg = paper();
    cfg.gust.air_density = 0.0;
    let plant = paper_vehicle(&cfg);
    let mut s: State<f64, NX> = plant.rest_state([0.0; 3], [0.0; 3]);
    s[ix::ZC] -= 0.01;
    let u = Inputs {
        u1: (plant.body.m + plant.payload.mc) * plant.body.g,
        tau: [0.0; 3],
    };
    let dt = 1e-4;
    let d0 = plant.payload.hover_offset;
    let start = s[ix::Z] - s[ix::ZC] - d0;
    let (_, measured) = crate::testing::crossing_frequency(start, 100_000, dt, || {
        s = step(&plant, &s, &u, dt);
        s[ix::Z] - s[ix::ZC] - d0
    });
    let fn_payload = 2.0;
    let expected = fn_payload * ((cfg.vehicle.mass + 0.22) / cfg.vehicle.mass).sqrt();
    assert!(
        (measured - expected).abs() < 1e-4,
        "{measured} Hz vs {expected} Hz"
    );
}

#[test]
fn a_flight_diverging_in_p2_keeps_p1_metrics() {
    // The paper's SMC is laterally unstable: a lateral gust from 25 s sets it off in P2.
    let mut cfg = paper();
    cfg.integrator.dt = 1e-3;
    cfg.gust
        .components
        .push(crate::config::GustComponent::Lateral);
    let engine = Engine::new(cfg).unwrap();
    let mut planner = FftPlanner::new();
    let mut fly = |e: &Engine| {
        let req = FlightRequest {
            want_spectra: true,
            ..FlightRequest::new(ControllerKind::Smc, 3, &[0])
        };
        e.fly::<f64>(&req, None, &mut planner).unwrap().remove(0)
    };
    let r = fly(&engine);
    assert!(
        r.diverged_at > 25.0 && r.diverged_at < 50.0,
        "{}",
        r.diverged_at
    );
    // Before the gust the lateral component changes nothing: P1 equals the vertical-only
    // flight's, exactly; the phases still open at the divergence are NaN.
    let mut vertical = paper();
    vertical.integrator.dt = 1e-3;
    let v = fly(&Engine::new(vertical).unwrap());
    assert!(v.diverged_at.is_nan());
    // Bits, so that the last metres' NaN (no touchdown, no release) compare equal.
    let bits = |row: &[f64]| row.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&r.metrics[0]), bits(&v.metrics[0]));
    assert_eq!(r.spectra[0], v.spectra[0]);
    // Events are NaN in a phase without them (the paper has no touchdown, no volume, no
    // navigation); every other metric is finite.
    let events: Vec<&str> = crate::metrics::METRICS
        .iter()
        .filter(|m| m.event)
        .map(|m| m.name)
        .collect();
    for (x, name) in r.metrics[0].iter().zip(crate::metrics::METRIC_NAMES) {
        assert!(
            x.is_finite() || (events.contains(&name) && x.is_nan()),
            "{name}: {x}"
        );
    }
    for i in 1..3 {
        assert!(
            r.metrics[i].iter().all(|x| x.is_nan()),
            "{:?}",
            r.metrics[i]
        );
        assert!(r.spectra[i].iter().all(|x| x.is_nan()));
    }
}

/// Each runaway bound, broken alone, ends the flight with its own status; a state that
/// overflows is `non_finite`; a flight within every bound is `ok`.
#[test]
fn exit_status_names_what_ended_the_flight() {
    let fly = |edit: &dyn Fn(&mut Config)| {
        let mut cfg = paper_cut(10.0, 1e-3, 1);
        cfg.gust.enabled = false;
        cfg.initial.attitude = [0.02, -0.01, 0.5];
        edit(&mut cfg);
        let engine = Engine::new(cfg).unwrap();
        let req = FlightRequest::new(ControllerKind::Pd, 0, &[0]);
        let r = engine
            .fly::<f64>(&req, None, &mut FftPlanner::new())
            .unwrap()
            .remove(0);
        (r.status, r.diverged_at)
    };
    assert_eq!(fly(&|_| {}).0, ExitStatus::Ok);
    assert!(fly(&|_| {}).1.is_nan());
    for (status, edit) in [
        (
            ExitStatus::Distance,
            &(|c: &mut Config| c.divergence.max_distance = 0.5) as &dyn Fn(&mut Config),
        ),
        (ExitStatus::Tilt, &|c: &mut Config| {
            c.divergence.max_tilt = 0.015
        }),
        (ExitStatus::Speed, &|c: &mut Config| {
            c.divergence.max_speed = 0.05
        }),
        (ExitStatus::Rate, &|c: &mut Config| {
            c.divergence.max_rate = 0.01
        }),
        (ExitStatus::NonFinite, &|c: &mut Config| {
            c.controller.pd.kp[2] = 1e308
        }),
    ] {
        let (got, at) = fly(edit);
        assert_eq!(got, status, "diverged at {at}");
        assert!(at > 0.0 && at <= 10.0, "{status:?} at {at}");
    }
    // The classification itself: non-finite first, then the bounds in order.
    let vars = crate::model::state_vars(Default::default(), Default::default(), Default::default());
    let limits = [1.0, 1.0, 1.0, 1.0];
    let mut s = vec![0.0; vars.len()];
    s[ix::ZC] = -2.0;
    assert_eq!(
        classify(&vars, &s, &[], &limits, f64::NEG_INFINITY),
        ExitStatus::Distance
    );
    s[ix::ZC] = 0.0;
    s[ix::VZ] = 2.0;
    s[ix::P] = 2.0;
    assert_eq!(
        classify(&vars, &s, &[], &limits, f64::NEG_INFINITY),
        ExitStatus::Speed
    );
    s[ix::PSI] = f64::NAN;
    assert_eq!(
        classify(&vars, &s, &[], &limits, f64::NEG_INFINITY),
        ExitStatus::NonFinite
    );
}

fn hover_cfg() -> Config {
    let mut cfg = paper();
    cfg.gust.enabled = false;
    cfg.initial.position = [0.0, 0.0, 2.0];
    cfg.initial.attitude = [0.0, 0.0, 0.0];
    cfg.trajectory.waypoints = vec![[0.0, 0.0, 0.0, 2.0, 0.0], [5.0, 0.0, 0.0, 2.0, 0.0]];
    cfg.integrator.duration = 10.0;
    cfg.phases.truncate(1);
    cfg.phases[0].end = 10.0;
    cfg
}

#[test]
fn hover_equilibrium_holds_for_both_laws() {
    let engine = Engine::new(hover_cfg()).unwrap();
    for kind in [ControllerKind::Pd, ControllerKind::Smc] {
        let mut tr = engine.trace(1000);
        engine
            .fly::<f64>(
                &FlightRequest::new(kind, 0, &[0]),
                Some(&mut tr),
                &mut FftPlanner::new(),
            )
            .unwrap();
        let x0 = &engine.realisation.x0;
        for row in tr.data.chunks(tr.width) {
            for i in 0..NX {
                assert!(
                    (row[1 + i] - x0[i]).abs() < 1e-9,
                    "{kind:?} state {i} drifted: {row:?}"
                );
            }
        }
    }
}

#[test]
fn simd_lanes_match_scalar_flights() {
    let mut cfg = paper_cut(30.0, 1e-3, 2);
    cfg.gust.end = 29.0;
    // Lateral motion too, so that every kernel (asin included) sees non-trivial inputs.
    cfg.initial.position = [0.3, -0.2, 0.0];
    cfg.initial.attitude = [0.05, -0.03, 0.5];
    let mut engine = Engine::new(cfg).unwrap();
    let mut planner = FftPlanner::new();
    let bits = |r: &[LaneResult]| -> Vec<Vec<u64>> {
        r.iter()
            .map(|l| {
                let m = l.metrics.iter().flatten().map(|x| x.to_bits());
                m.chain([l.diverged_at.to_bits()]).collect()
            })
            .collect()
    };
    for kind in [ControllerKind::Pd, ControllerKind::Smc] {
        let mut runs = Vec::new();
        // Realisations 3..11: two lane-sets of four, or one of eight (AVX-512).
        let indices: Vec<u64> = (3..3 + MAX_LANES as u64).collect();
        for isa in Isa::ALL {
            if !isa.supported() {
                eprintln!("skipped the {} path: this CPU cannot run it", isa.name());
                continue;
            }
            engine.isa = isa;
            let flown = |f: &mut dyn FnMut(&FlightRequest) -> Vec<LaneResult>, n| {
                let sets = indices.chunks(n);
                sets.flat_map(|set| f(&FlightRequest::new(kind, 7, set)))
                    .collect::<Vec<_>>()
            };
            let lanes_per_set = engine.lanes_per_set();
            runs.push(flown(
                &mut |req| engine.fly_set(req, &mut planner).unwrap(),
                lanes_per_set,
            ));
            runs.push(flown(
                &mut |req| engine.fly::<F64x4>(req, None, &mut planner).unwrap(),
                4,
            ));
            runs.push(flown(
                &mut |req| engine.fly::<f64>(req, None, &mut planner).unwrap(),
                1,
            ));
        }
        // Bit-identical across lane types, packings and instruction sets (no FMA anywhere).
        for r in &runs[1..] {
            assert_eq!(bits(r), bits(&runs[0]), "{kind:?}");
        }
        // ... and the flights went somewhere. (The paper's SMC gains are unstable
        // laterally, so its flights diverge here: equally on every path.)
        if kind == ControllerKind::Pd {
            assert!(runs[0]
                .iter()
                .all(|l| l.diverged_at.is_nan() && l.metrics[0][0] > 0.0));
        }
    }
}

/// Column `name` of a trace row (`row[0]` is t).
fn col(row: &[f64], name: &str) -> f64 {
    let columns = trace_columns(Default::default(), Default::default(), Default::default());
    row[1 + columns.iter().position(|c| *c == name).unwrap()]
}

#[test]
fn drag_z_is_the_drag_the_dynamics_feel() {
    // A gusty stretch of the paper flight: vz and wind_z both move.
    let mut cfg = paper();
    cfg.integrator.dt = 1e-3;
    cfg.integrator.duration = 28.0;
    cfg.phases.truncate(1);
    let engine = Engine::new(cfg.clone()).unwrap();
    let mut tr = engine.trace(7);
    let req = FlightRequest::new(ControllerKind::Pd, 5, &[0]);
    engine
        .fly::<f64>(&req, Some(&mut tr), &mut FftPlanner::new())
        .unwrap();
    let plant = paper_vehicle(&cfg);
    let mut no_drag = paper_vehicle(&cfg);
    no_drag.body.drag_quad = 0.0;
    let (mut gusty, mut worst) = (0, 0.0_f64);
    for row in tr.data.chunks(tr.width) {
        let s: State<f64, NX> = state_from_fn(|i| row[1 + i]);
        let u = Inputs {
            u1: col(row, "U1"),
            tau: [
                col(row, "tau_phi"),
                col(row, "tau_theta"),
                col(row, "tau_psi"),
            ],
        };
        let w = [col(row, "wind_x"), col(row, "wind_y"), col(row, "wind_z")];
        let drag_z = col(row, "drag_z");
        // The force the derivative adds to m az, recovered from two derivatives.
        let trig = Trig::of(&s);
        let felt = (plant.derivative(&s, &trig, &u, &w)[ix::VZ]
            - no_drag.derivative(&s, &trig, &u, &w)[ix::VZ])
            * plant.body.m;
        worst = worst.max((felt - drag_z).abs());
        // ... and the formula by hand, from the trace's own columns.
        let rel = col(row, "vz") - w[2];
        let k = 0.5 * cfg.gust.air_density * cfg.vehicle.drag_area;
        assert_eq!(drag_z, rel * rel.abs() * -k, "t = {}", row[0]);
        gusty += usize::from(w[2] != 0.0 && drag_z.abs() > 1e-3);
    }
    assert!(worst < 1e-12, "{worst:e}");
    assert!(gusty > 100, "the gust must load the drag: {gusty} rows");
}

#[test]
fn drag_z_vanishes_at_hover_without_wind() {
    let engine = Engine::new(hover_cfg()).unwrap();
    let mut tr = engine.trace(100);
    let req = FlightRequest::new(ControllerKind::Pd, 0, &[0]);
    engine
        .fly::<f64>(&req, Some(&mut tr), &mut FftPlanner::new())
        .unwrap();
    for row in tr.data.chunks(tr.width) {
        assert_eq!(col(row, "wind_z"), 0.0);
        assert!(col(row, "drag_z").abs() < 1e-15, "{row:?}");
    }
}

/// The fused mode: refused where the path has no FMA; elsewhere close to the default
/// mode (last digits), yet not identical (the fusing happened).
#[test]
fn fused_mode_is_close_to_the_default_and_refused_without_fma() {
    let mut cfg = paper_cut(10.0, 1e-3, 1);
    cfg.gust.start = 1.0;
    cfg.gust.end = 9.0;
    let mut planner = FftPlanner::new();
    for isa in Isa::ALL {
        let mut engine = Engine::new(cfg.clone()).unwrap();
        engine.isa = isa;
        if !isa.fused_supported() {
            let e = engine.with_fused(true).err().expect("refused");
            assert!(e.contains("fused") && e.contains(isa.name()), "{e}");
            eprintln!(
                "skipped the fused {} path: this CPU cannot run it",
                isa.name()
            );
            continue;
        }
        let indices: Vec<u64> = (0..engine.lanes_per_set() as u64).collect();
        let req = FlightRequest::new(ControllerKind::Pd, 1, &indices);
        let exact = engine.fly_set(&req, &mut planner).unwrap();
        let engine = engine.with_fused(true).unwrap();
        let fused = engine.fly_set(&req, &mut planner).unwrap();
        let (mut worst, mut differ) = (0.0f64, false);
        for (a, b) in exact.iter().zip(&fused) {
            for (x, y) in a.metrics[0].iter().zip(&b.metrics[0]) {
                worst = worst.max((x - y).abs() / x.abs().max(1e-300));
                differ |= x.to_bits() != y.to_bits();
            }
        }
        assert!(
            worst < 1e-8 && differ,
            "{isa:?}: worst relative difference {worst}"
        );
    }
}

/// A short paper flight in the whole-flight wind: a sheared mean wind at 30 deg, turbulence
/// on all axes following the vehicle's altitude and airspeed, a ramp and a pulse.
fn windy_cfg() -> Config {
    use crate::scenario::{
        DiscreteGust, GustAirspeed, GustAltitude, GustComponent, GustShape, Shear,
    };
    let mut cfg = paper_cut(24.0, 1e-3, 2);
    cfg.trajectory.interpolation = crate::config::Interpolation::MinJerk;
    cfg.trajectory.waypoints = vec![[0.0, 0.0, 0.0, 0.0, 0.0], [2.0, 0.0, 0.0, 20.0, 0.0]];
    cfg.trajectory.transition = 15.0;
    cfg.gust.components = GustComponent::ALL.to_vec();
    cfg.gust.start = 3.0;
    cfg.gust.end = 20.0;
    cfg.gust.altitude = GustAltitude::Vehicle;
    cfg.gust.airspeed = GustAirspeed::Relative;
    cfg.wind.speed = 2.0;
    cfg.wind.heading = 30.0;
    cfg.wind.shear = Shear::Log;
    cfg.wind.gusts = vec![
        DiscreteGust {
            start: 5.0,
            duration: 2.0,
            amplitude: [1.0, -0.5, 0.3],
            shape: GustShape::Ramp,
        },
        DiscreteGust {
            start: 12.0,
            duration: 1.5,
            amplitude: [0.0, 1.0, -0.8],
            shape: GustShape::Pulse,
        },
    ];
    cfg.validate().unwrap();
    cfg
}

#[test]
fn given_innovations_fly_the_seeded_flight_in_a_wind_that_follows_the_vehicle() {
    let engine = Engine::new(windy_cfg()).unwrap();
    let mut planner = FftPlanner::new();
    let bits = |r: &[LaneResult]| -> Vec<u64> {
        r.iter()
            .flat_map(|l| l.metrics.iter().flatten().map(|x| x.to_bits()))
            .collect()
    };
    let indices: Vec<u64> = (3..7).collect();
    let req = FlightRequest::new(ControllerKind::Pd, 11, &indices);
    let seeded = engine.fly::<F64x4>(&req, None, &mut planner).unwrap();
    assert!(seeded.iter().all(|l| l.status == ExitStatus::Ok));
    let xi: Vec<Vec<f64>> = indices
        .iter()
        .map(|&i| engine.innovations_of(11, i))
        .collect();
    assert!(xi[0].len() > 1000);
    let rows: Vec<&[f64]> = xi.iter().map(|x| x.as_slice()).collect();
    let given = FlightRequest {
        innovations: Some(&rows),
        ..req
    };
    let flown = engine.fly::<F64x4>(&given, None, &mut planner).unwrap();
    assert_eq!(bits(&seeded), bits(&flown));
    // One lane alone flies the same as in its lane-set.
    let one = engine
        .fly::<f64>(
            &FlightRequest::new(ControllerKind::Pd, 11, &indices[1..2]),
            None,
            &mut planner,
        )
        .unwrap();
    assert_eq!(bits(&one), bits(&seeded[1..2]));
}

#[test]
fn the_wind_blows_outside_the_window_and_the_prescribed_wind_adds_to_it() {
    let mut cfg = windy_cfg();
    cfg.gust.enabled = false;
    let engine = Engine::new(cfg).unwrap();
    let every = 1;
    let mut tr = engine.trace(every);
    let req = FlightRequest::new(ControllerKind::Pd, 0, &[0]);
    engine
        .fly::<f64>(&req, Some(&mut tr), &mut FftPlanner::new())
        .unwrap();
    let wind = engine.realisation.wind();
    let mut max_x = 0.0_f64;
    let rows: Vec<&[f64]> = tr.data.chunks(tr.width).collect();
    let (last, flown) = rows.split_last().unwrap();
    // The closing row holds the last step's wind: no step follows it.
    for c in ["wind_x", "wind_y", "wind_z"] {
        assert_eq!(col(last, c), col(flown[flown.len() - 1], c));
    }
    for (k, row) in flown.iter().enumerate() {
        let z = col(row, "z");
        let m = wind.mean_at(z);
        let g = wind.discrete_gusts(k as u64);
        let w = [col(row, "wind_x"), col(row, "wind_y"), col(row, "wind_z")];
        assert_eq!(w, [m[0] + g[0], m[1] + g[1], m[2] + g[2]], "t = {}", row[0]);
        max_x = max_x.max(w[0]);
    }
    assert!(max_x > 2.0, "{max_x}");
    // A prescribed wind (zero here) adds to the mean wind and the discrete gusts.
    let steps = engine.steps;
    let engine = Engine::new(engine.cfg.clone())
        .unwrap()
        .with_wind(vec![[0.0; 3]; steps + 1])
        .unwrap();
    let mut tr2 = engine.trace(every);
    engine
        .fly::<f64>(&req, Some(&mut tr2), &mut FftPlanner::new())
        .unwrap();
    assert_eq!(tr.data, tr2.data);
}

/// The paper's vehicle moving sideways and up (every loop of every law has work to do), its
/// laws at 50, 250 and 500 Hz on the 1 ms step.
fn sampled_cfg() -> Config {
    let mut cfg = hover_cfg();
    cfg.trajectory.waypoints = vec![[0.0, 0.5, -0.3, 2.4, 0.0], [5.0, 0.5, -0.3, 2.4, 0.0]];
    cfg.integrator.dt = 1e-3;
    cfg.integrator.duration = 0.3;
    cfg.phases[0].end = 0.3;
    cfg.controller.position_rate = Some(50.0);
    cfg.controller.attitude_rate = Some(250.0);
    cfg.controller.inner_rate = Some(500.0);
    cfg
}

/// A law at its rates is the law evaluated by hand at its update instants and held between
/// them (docs/model.md, "Loop rates"), for every law: the trace's inputs at each step are what the
/// law gives with its loops updated on the steps k with k % (steps per update) == 0 from the
/// state recorded then, each loop's output unchanged between its updates, and where every
/// loop updates (each 20 ms), a static law's inputs are the law at rest at that state.
#[test]
fn a_law_at_its_rates_is_the_law_sampled_and_held() {
    use crate::control::Pd;
    use crate::control::{AnyController, Control, Controller, Due, Px4, Se3, Sight, Smc};
    use crate::model::{Rigid, Tick};
    let cfg = sampled_cfg();
    let engine = Engine::new(cfg.clone()).unwrap();
    let dt = cfg.integrator.dt;
    let columns = trace_columns(Default::default(), Default::default(), Default::default());
    let at = |name: &str| 1 + columns.iter().position(|c| *c == name).unwrap();
    fn by_hand<C: Control>(
        law: &C,
        rows: &[&[f64]],
        at: &dyn Fn(&str) -> usize,
        steps: [usize; 3],
        dt: f64,
        is_static: bool,
    ) {
        let rigid = |row: &[f64]| Rigid {
            pos: [row[at("x")], row[at("y")], row[at("z")]],
            att: [row[at("phi")], row[at("theta")], row[at("psi")]],
            vel: [row[at("vx")], row[at("vy")], row[at("vz")]],
            rate: [row[at("p")], row[at("q")], row[at("r")]],
        };
        let reference = |row: &[f64]| crate::trajectory::Reference {
            pos: [row[at("x_ref")], row[at("y_ref")], row[at("z_ref")]],
            psi: row[at("psi_ref")],
            ..Default::default()
        };
        let s0 = rigid(rows[0]);
        let trig0 = Trig::of_angles(s0.att[0], s0.att[1], s0.att[2]);
        let mut mem = law.memory(&Sight::blind(&s0, &trig0));
        let mut changes = [0usize; 2];
        for (k, row) in rows.iter().enumerate() {
            let s = rigid(row);
            let trig = Trig::of_angles(s.att[0], s.att[1], s.att[2]);
            let due = Due {
                position: k % steps[0] == 0,
                attitude: k % steps[1] == 0,
                rate: k % steps[2] == 0,
            };
            let r = reference(row);
            let tick = Tick {
                step: k,
                t: k as f64 * dt,
            };
            let u = law.step(&Sight::blind(&s, &trig), &r, tick, due, &mut mem);
            let got = [
                row[at("U1")],
                row[at("tau_phi")],
                row[at("tau_theta")],
                row[at("tau_psi")],
            ];
            let want = [u.u1, u.tau[0], u.tau[1], u.tau[2]];
            assert_eq!(got.map(f64::to_bits), want.map(f64::to_bits), "step {k}");
            if k > 0 {
                let prev = rows[k - 1];
                let moved = |name: &str| row[at(name)] != prev[at(name)];
                // The torques move only where the loop that gives them updates.
                let torque_loop = if is_static { due.attitude } else { due.rate };
                if moved("tau_phi") || moved("tau_theta") {
                    assert!(
                        torque_loop,
                        "the torques moved at step {k}, between updates"
                    );
                    changes[1] += 1;
                }
                if is_static && moved("U1") {
                    assert!(
                        due.position,
                        "the thrust moved at step {k}, between updates"
                    );
                    changes[0] += 1;
                }
            }
            if is_static && due.position {
                let rest = law.at_rest(&Sight::blind(&s, &trig), &r, tick);
                assert_eq!(rest.u1.to_bits(), u.u1.to_bits(), "step {k}");
                assert_eq!(
                    rest.tau.map(f64::to_bits),
                    u.tau.map(f64::to_bits),
                    "step {k}"
                );
            }
        }
        // The holds held something that moves: the law was exercised.
        assert!(changes[1] > 10, "{changes:?}");
        if is_static {
            assert!(
                changes[0] > 5 && changes[0] <= rows.len() / steps[0],
                "{changes:?}"
            );
        }
    }
    for kind in ControllerKind::ALL.iter().copied() {
        let mut tr = engine.trace(1);
        let req = FlightRequest::new(kind, 0, &[0]);
        engine
            .fly::<f64>(&req, Some(&mut tr), &mut FftPlanner::new())
            .unwrap();
        let rows: Vec<&[f64]> = tr.data.chunks(tr.width).collect();
        // The closing row holds the last step's inputs: no step follows it.
        let rows = &rows[..rows.len() - 1];
        let steps = cfg.controller.loop_steps(kind, dt);
        assert_eq!(steps, [20, 4, 2]);
        let law = AnyController::new(kind, &cfg.control_context());
        match kind {
            ControllerKind::Pd => by_hand(law.get::<Pd>(), rows, &at, steps, dt, true),
            ControllerKind::Smc => by_hand(law.get::<Smc>(), rows, &at, steps, dt, true),
            ControllerKind::Se3 => by_hand(law.get::<Se3>(), rows, &at, steps, dt, true),
            ControllerKind::Px4 => by_hand(law.get::<Px4>(), rows, &at, steps, dt, false),
        }
        let _ = <Pd as Controller>::RATES;
    }
}

/// A position loop slow enough to destabilise the hover: the sampled model's poles say so, and
/// the flight diverges; at PX4's own 50 Hz both are stable.
#[test]
fn a_slow_position_loop_is_unstable_in_the_model_and_in_flight() {
    use crate::stability::{analyse, Verdict};
    let mut cfg = hover_cfg();
    cfg.integrator.duration = 30.0;
    cfg.phases[0].end = 30.0;
    // Released 0.3 m below the hover point: the vertical loop has work to do; a flight that
    // leaves a 20 m ball has run away.
    cfg.initial.position = [0.0, 0.0, 1.7];
    cfg.integrator.dt = 1e-3;
    cfg.divergence.max_distance = 20.0;
    for (rate, verdict) in [(50.0, Verdict::Stable), (0.5, Verdict::Unstable)] {
        cfg.controller.position_rate = Some(rate);
        let a = analyse(&cfg, ControllerKind::Pd);
        assert_eq!(a.period, Some(1.0 / rate), "{rate} Hz");
        assert_eq!(a.verdict, verdict, "{rate} Hz: {:?}", a.poles.first());
        let engine = Engine::new(cfg.clone()).unwrap();
        let out = engine
            .fly::<f64>(
                &FlightRequest::new(ControllerKind::Pd, 0, &[0]),
                None,
                &mut FftPlanner::new(),
            )
            .unwrap();
        let diverged = !out[0].diverged_at.is_nan();
        assert_eq!(diverged, verdict == Verdict::Unstable, "{rate} Hz");
    }
}
