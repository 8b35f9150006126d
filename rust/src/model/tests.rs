use super::*;
use crate::lane::F64x4;
use crate::scenario::tests::paper;
use crate::scenario::Config;

type Paper = Vehicle<f64, payload::Spring, actuator::Ideal>;
const NX: usize = 14;

fn paper_vehicle(cfg: &Config) -> Paper {
    AnyVehicle::new(&cfg.model_context()).vehicle::<payload::Spring, actuator::Ideal>()
}

fn hover(v: &Paper) -> Inputs<f64> {
    Inputs {
        u1: (v.body.m + v.payload.mc) * v.body.g,
        tau: [0.0; 3],
    }
}

/// ds/dt of a vehicle on the ideal actuators at `s`, its attitude worked out from `s`.
pub(crate) fn derivative<Pay: PayloadModel<f64>, const N: usize>(
    v: &Vehicle<f64, Pay, actuator::Ideal>,
    s: &State<f64, N>,
    u: &Inputs<f64>,
    w: &[f64; 3],
) -> State<f64, N> {
    v.derivative(s, &Trig::of(s), u, w)
}

/// The gathered-lanes checks' case: each config's vehicle (`parts`) and their lane-set
/// (`lanes`), a state splatted to every lane (`sl`), a command `u` and a wind `w`, each also
/// splatted (`ul`, `wl`).
pub(crate) struct LaneCase<Pay: Payload, Act: Actuator, const N: usize> {
    pub parts: Vec<AnyVehicle>,
    pub lanes: Vehicle<F64x4, Pay::At<F64x4>, Act::At<F64x4>>,
    pub sl: State<F64x4, N>,
    pub u: Inputs<f64>,
    pub ul: Inputs<F64x4>,
    pub w: [f64; 3],
    pub wl: [F64x4; 3],
}

impl<Pay: Payload, Act: Actuator, const N: usize> LaneCase<Pay, Act, N> {
    pub(crate) fn new(cfgs: &[Config], s: State<f64, N>) -> Self {
        let parts: Vec<AnyVehicle> = cfgs
            .iter()
            .map(|c| AnyVehicle::new(&c.model_context()))
            .collect();
        let refs: Vec<&AnyVehicle> = parts.iter().collect();
        let lanes = AnyVehicle::gather::<F64x4, Pay, Act>(&refs);
        let u = Inputs {
            u1: 25.0,
            tau: [0.01, -0.02, 0.003],
        };
        let w = [0.3, -0.1, 1.2];
        Self {
            sl: state_from_fn(|i| F64x4::splat(s[i])),
            ul: Inputs {
                u1: F64x4::splat(u.u1),
                tau: u.tau.map(F64x4::splat),
            },
            wl: w.map(F64x4::splat),
            parts,
            lanes,
            u,
            w,
        }
    }
}

/// Lane `l` of `got` is `want`, bit for bit, in every state.
pub(crate) fn assert_lane_bits<const N: usize>(
    got: &State<F64x4, N>,
    want: &State<f64, N>,
    l: usize,
) {
    for i in 0..N {
        assert_eq!(
            got[i].lane(l).to_bits(),
            want[i].to_bits(),
            "lane {l} state {i}"
        );
    }
}

#[test]
fn the_paper_layout_is_the_papers_state_vector() {
    let names: Vec<&str> = state_vars(Default::default(), PayloadKind::Spring, ActuatorKind::Ideal)
        .iter()
        .map(|v| v.name)
        .collect();
    assert_eq!(
        names,
        ["x", "y", "z", "phi", "theta", "psi", "zc", "vx", "vy", "vz", "p", "q", "r", "vzc"]
    );
    assert_eq!(Paper::LAYOUT.len(), NX);
    // Every state but yaw has a runaway bound; positions, angles, speeds and rates each theirs.
    let vars = state_vars(Default::default(), PayloadKind::Spring, ActuatorKind::Ideal);
    let bounded: Vec<_> = vars
        .iter()
        .filter(|v| v.bound.is_none())
        .map(|v| v.name)
        .collect();
    assert_eq!(bounded, ["psi"]);
    assert_eq!(vars[6].bound, Some(Bound::Distance));
    assert_eq!(vars[13].bound, Some(Bound::Speed));
}

#[test]
fn hover_is_an_equilibrium_of_the_plant() {
    let v = paper_vehicle(&paper());
    let s: State<f64, NX> = v.rest_state([1.0, -2.0, 2.0], [0.0, 0.0, 0.5]);
    let ds = derivative(&v, &s, &hover(&v), &[0.0; 3]);
    let vars = state_vars(Default::default(), PayloadKind::Spring, ActuatorKind::Ideal);
    for (i, d) in ds.iter().enumerate() {
        assert!(d.abs() < 1e-12, "d{}/dt = {d}", vars[i].name);
    }
}

#[test]
fn payload_acceleration_is_the_derivative_of_vzc() {
    let v = paper_vehicle(&paper());
    let mut s: State<f64, NX> = v.rest_state([0.0, 0.0, 2.0], [0.0; 3]);
    let u = hover(&v);
    let trig = Trig::of(&s);
    assert!(
        v.payload_outputs(&s, &trig, u.u1, &[0.0; 3]).accel[2].abs() < 1e-12,
        "zero at hover"
    );
    s[6] -= 0.03;
    s[9] = 0.4;
    s[13] = -0.7;
    for wz in [0.0, 1.3, -2.0] {
        let ds = derivative(&v, &s, &u, &[0.0, 0.0, wz]);
        let a = v.payload_outputs(&s, &trig, u.u1, &[0.0, 0.0, wz]).accel[2];
        assert_eq!(a.to_bits(), ds[13].to_bits(), "wind {wz}");
    }
}

#[test]
fn drag_opposes_relative_velocity() {
    let v = paper_vehicle(&paper());
    let s: State<f64, NX> = v.rest_state([0.0; 3], [0.0; 3]);
    let u = hover(&v);
    // An updraft of 1 m/s pushes both bodies up by 1/2 rho CdA (1 m/s)^2.
    let ds = derivative(&v, &s, &u, &[0.0, 0.0, 1.0]);
    assert!((ds[9] - v.body.drag_quad / v.body.m).abs() < 1e-12);
    assert!((ds[13] - v.payload.drag_payload / v.payload.mc).abs() < 1e-12);
    let ds = derivative(&v, &s, &u, &[2.0, 0.0, 0.0]);
    let lateral = 4.0 * v.body.drag_lateral / (v.body.m + v.payload.mc);
    assert!((ds[7] - lateral).abs() < 1e-12);
}

/// The lane-set vehicle is one vehicle per lane: gathering differing parts gives each lane
/// its own derivative, bit for bit.
#[test]
fn gathered_lanes_fly_their_own_vehicle() {
    let mut cfgs = [paper(), paper(), paper(), paper()];
    cfgs[1].payload.mass = 0.4;
    cfgs[2].vehicle.inertia[0] = 0.03;
    cfgs[3].gust.air_density = 0.9;
    let mut s: State<f64, NX> =
        paper_vehicle(&cfgs[0]).rest_state([0.0, 0.0, 1.0], [0.1, -0.2, 0.3]);
    s[13] = 0.2;
    s[10] = 0.4;
    let c = LaneCase::<payload::Spring, actuator::Ideal, NX>::new(&cfgs, s);
    let got = c.lanes.derivative(&c.sl, &Trig::of(&c.sl), &c.ul, &c.wl);
    for (l, p) in c.parts.iter().enumerate() {
        let one = p.vehicle::<payload::Spring, actuator::Ideal>();
        assert_lane_bits(&got, &derivative(&one, &s, &c.u, &c.w), l);
    }
}

/// Trig at a stage state by angle addition agrees with direct sin/cos to about an ulp, for
/// small turns and at the series' limit; larger turns fall back to the kernels, per lane.
#[test]
fn advanced_trig_matches_direct_evaluation() {
    use crate::lane::F64x4;
    let angles = [0.0, 0.3, -1.2, 2.9, 1.0e3, -7.0];
    let turns = [
        0.0,
        1e-9,
        -2e-5,
        0.01,
        -SMALL_TURN,
        SMALL_TURN * 0.999,
        0.2,
        -3.0,
    ];
    let h = 1e-3;
    for &a in &angles {
        for &d in &turns {
            let mut s = [0.0; NX];
            let mut k = [0.0; NX];
            for (i, ang) in [ix::PHI, ix::THETA, ix::PSI].into_iter().enumerate() {
                s[ang] = a + 0.1 * i as f64;
                k[ang] = d / h * (1.0 + 0.5 * i as f64);
            }
            let at: State<f64, NX> = state_from_fn(|i| s[i] + k[i] * h);
            let got = Trig::of(&s).advanced(&k, h, &at);
            let want = Trig::of(&at);
            let err = [
                got.sphi - want.sphi,
                got.cphi - want.cphi,
                got.sth - want.sth,
                got.cth - want.cth,
                got.spsi - want.spsi,
                got.cpsi - want.cpsi,
            ];
            // Angle addition evaluates at s + k h exactly, `want` at its rounded value:
            // they differ by rounding, up to a few ulp of the angle for |a| = 1000.
            let tol = 4.0 * f64::EPSILON * (1.0 + a.abs());
            assert!(err.iter().all(|e| e.abs() <= tol), "a {a} d {d}: {err:?}");
        }
    }
    // Per lane: a lane that turns too far takes the kernels; its neighbours keep the series.
    let s: State<F64x4, NX> = state_from_fn(|_| F64x4::splat(0.4));
    let mut k: State<F64x4, NX> = state_from_fn(|_| F64x4::splat(1e-3 / h));
    k[ix::PSI] = F64x4::from_fn(|i| if i == 2 { 0.5 / h } else { 1e-3 / h });
    let at: State<F64x4, NX> = state_from_fn(|i| s[i] + k[i] * h);
    let got = Trig::of(&s).advanced(&k, h, &at);
    let alone =
        Trig::of(&s.map(|x| x.lane(0))).advanced(&k.map(|x| x.lane(0)), h, &at.map(|x| x.lane(0)));
    assert_eq!(got.spsi.lane(0).to_bits(), alone.spsi.to_bits());
    assert_eq!(
        got.spsi.lane(2).to_bits(),
        Trig::of(&at).spsi.lane(2).to_bits()
    );
}

#[test]
fn every_registered_pair_flies_with_its_layouts_state_count() {
    // `state_vars` goes through `dispatch` and asserts the `N` that `kinds!` computed for the
    // pair against the kinds' own `Layout`; each kind is built from a scenario that names it
    // and reports that name back.
    for &p in PAYLOAD_KINDS {
        for &a in ACTUATOR_KINDS {
            // The quadrotor's 12 states come first, whatever the kinds.
            let vars = state_vars(Default::default(), p, a);
            let own = vars.iter().filter(|v| v.part == Part::Vehicle).count();
            assert_eq!(own, 12, "{p:?} {a:?}");
            let mut cfg = paper();
            cfg.payload.model = p;
            cfg.payload.cable.cable_length = Some(1.0);
            cfg.actuator.model = a;
            assert_eq!(AnyPayload::new(&cfg.model_context()).name(), p);
            assert_eq!(AnyActuator::new(&cfg.model_context()).name(), a);
        }
    }
    let names = |k: &[String]| k.iter().collect::<std::collections::HashSet<_>>().len();
    let payloads: Vec<String> = PAYLOAD_KINDS
        .iter()
        .map(|k| serde_json::to_string(k).unwrap())
        .collect();
    let actuators: Vec<String> = ACTUATOR_KINDS
        .iter()
        .map(|k| serde_json::to_string(k).unwrap())
        .collect();
    assert_eq!(names(&payloads), PAYLOAD_KINDS.len(), "{payloads:?}");
    assert_eq!(names(&actuators), ACTUATOR_KINDS.len(), "{actuators:?}");
}
