//! The last metres' checks on the cable (docs/model.md, "The last metres"): the energy balance
//! with the winch's work, the hook's release, the ground's hold on a resting parcel.

use super::tests::{hover_thrust, vehicle, Slung};
use super::*;
use crate::model::actuator::Ideal;
use crate::model::{state_from_fn, AnyVehicle, Inputs, Trig};
use crate::scenario::tests::paper;
use crate::scenario::Config;
use crate::scenario::PayloadKind;

const NX: usize = 20;
const LAYOUT: Layout = Layout::new(4, 0);
const XC: usize = LAYOUT.payload();
const LINE: usize = XC + 3;
const VX: usize = LAYOUT.vel();
const VXC: usize = LAYOUT.payload_vel();
const VLINE: usize = VXC + 3;
const ZC: usize = XC + 2;
const VZ: usize = VX + 2;

/// The paper's vehicle with a winch on a cable of `l0` m reeled in to `min` m, a ground at 0.
fn winch_config(l0: f64, min: f64) -> Config {
    let mut cfg = paper();
    cfg.payload.model = PayloadKind::Cable;
    let c = &mut cfg.payload.cable;
    c.cable_length = Some(l0);
    c.attachment_offset = Some(0.1);
    c.winch_speed = Some(0.5);
    c.winch_acceleration = Some(0.5);
    c.length_min = Some(min);
    cfg.payload.natural_frequency = Some(3.0);
    cfg.ground.stiffness = Some(2.0e4);
    cfg.ground.dissipation = Some(1.0);
    cfg.ground.friction = Some(0.5);
    cfg.initial.position = [0.0, 0.0, 10.0];
    cfg.validate().expect("a valid winch scenario");
    cfg
}

fn derivative(v: &Slung, s: &State<f64, NX>) -> State<f64, NX> {
    v.derivative(s, &Trig::of(s), &hover_thrust(v), &[0.0; 3])
}

/// The cue of 1 ms step `k` at 10 m over the drop point, no lowering due, no noise drawn.
fn cue_at<L: Lane>(k: usize) -> Cue<L> {
    Cue {
        t: k as f64 * 1e-3,
        dt: 1e-3,
        payout: None,
        off_drop: L::splat(0.0),
        height: L::splat(10.0),
        draw: L::splat(0.0),
    }
}

/// With the hook fixed, no damping and no drag, the parcel's energy (kinetic, gravitational,
/// elastic about the present length L) changes only by the winch's work: dE/dt = -T L'. The
/// work is integrated with the state (one more equation of the same RK4), so E - W is an
/// invariant whose error is RK4's: it falls 16 times (fourth order) or more when dt halves.
#[test]
fn energy_changes_by_the_winchs_work_to_rk4_order() {
    let mut cfg = winch_config(6.0, 1.0);
    cfg.gust.air_density = 0.0;
    cfg.payload.damping = 0.0;
    let mut v = vehicle(&cfg);
    // Paying out toward 5 m, faster and faster (L'' = kw (v - L') > 0, within the bounds).
    v.payload.target = 5.0;
    let (mc, g, k) = (v.payload.mc, v.body.g, v.payload.k);
    let energy = |s: &State<f64, NX>| {
        let line = v.payload.line(s, &Trig::of(s));
        let stretch = (line.length - s[LINE]).max(0.0);
        let speed2: f64 = (0..3).map(|i| s[VXC + i] * s[VXC + i]).sum();
        0.5 * mc * speed2 + mc * g * s[ZC] + 0.5 * k * stretch * stretch
    };
    let start = {
        let mut s: State<f64, NX> = v.rest_state([0.0, 0.0, 10.0], [0.0; 3]);
        // Swung 0.3 rad in x-z, moving sideways; the line already paying out at 0.98 v.
        let l = v.payload.hover_length;
        s[XC] = l * 0.3f64.sin();
        s[ZC] = 10.0 - 0.1 - l * 0.3f64.cos();
        s[VXC + 1] = 0.6;
        s[VLINE] = 0.49;
        s
    };
    // d(s, W)/dt: the vehicle held still (its derivatives zeroed), W' = -T L'.
    let f = |s: &State<f64, NX>, _w: f64| {
        let mut ds = derivative(&v, s);
        for i in (0..6).chain(VX..VX + 6) {
            ds[i] = 0.0;
        }
        let t = v.payload.line(s, &Trig::of(s)).tension;
        (ds, -t * s[VLINE])
    };
    let drift = |dt: f64| {
        let (mut s, mut w) = (start, 0.0);
        let e0 = energy(&s);
        let mut worst: f64 = 0.0;
        let add = |a: &State<f64, NX>, k: &State<f64, NX>, h: f64| -> State<f64, NX> {
            state_from_fn(|i| a[i] + h * k[i])
        };
        for _ in 0..(4.0 / dt).round() as usize {
            let (k1, w1) = f(&s, w);
            let (k2, w2) = f(&add(&s, &k1, 0.5 * dt), w);
            let (k3, w3) = f(&add(&s, &k2, 0.5 * dt), w);
            let (k4, w4) = f(&add(&s, &k3, dt), w);
            s = state_from_fn(|i| s[i] + dt / 6.0 * (k1[i] + 2.0 * (k2[i] + k3[i]) + k4[i]));
            w += dt / 6.0 * (w1 + 2.0 * (w2 + w3) + w4);
            worst = worst.max((energy(&s) - w - e0).abs());
        }
        // The line stayed taut and paid out over a metre: the work is not a small term.
        assert!(s[LINE] > 2.5, "{}", s[LINE]);
        assert!(w.abs() > 2.0, "winch work {w} J");
        worst / (mc * g * v.payload.hover_length)
    };
    let (coarse, fine) = (drift(4e-3), drift(2e-3));
    assert!(fine < 1e-7, "relative energy error {fine:e}");
    crate::testing::assert_halving_ratio(coarse, fine, 14.0..40.0);
}

/// At hover the vehicle's thrust carries the parcel too; the instant the hook opens it
/// accelerates up by the released weight over its own mass, and from then on no payload state
/// reaches the vehicle's equations.
#[test]
fn the_release_leaves_the_released_weight_over_the_mass_and_nothing_of_the_payload() {
    let mut cfg = winch_config(3.0, 1.0);
    // The parcel in still air: without the rotors' wake it falls at g exactly.
    cfg.vehicle.downwash = false;
    let mut v = vehicle(&cfg);
    let s: State<f64, NX> = v.rest_state([0.3, -0.2, 10.0], [0.0; 3]);
    assert!(derivative(&v, &s)[VZ].abs() < 1e-12);
    v.payload.release_at = 2.0;
    let cue = |t: f64| Cue {
        t,
        dt: 1e-3,
        payout: None,
        off_drop: 0.0,
        height: 10.0,
        draw: 0.0,
    };
    let trig = Trig::of(&s);
    let before = v.payload.last_metres(&s, &trig, &cue(1.998)).unwrap();
    assert_eq!((before.release, before.hooked), (0.0, 1.0));
    let at = v.payload.last_metres(&s, &trig, &cue(1.9996)).unwrap();
    assert_eq!((at.release, at.hooked), (1.0, 0.0));
    let ds = derivative(&v, &s);
    let expected = v.payload.mc * v.body.g / v.body.m;
    assert!(
        (ds[VZ] - expected).abs() < 1e-9,
        "{} vs mc g / m = {expected}",
        ds[VZ]
    );
    // The parcel falls freely (no line), the line is reeled in, the outputs say nothing.
    assert!((ds[VXC + 2] + v.body.g).abs() < 1e-12, "{}", ds[VXC + 2]);
    assert_eq!(v.payload.target, 1.0);
    let out = v.payload_outputs(&s, &trig, 0.0, &[0.0; 3]);
    assert_eq!((out.e_o, out.tension, out.swing), (0.0, 0.0, 0.0));
    // Any payload state: the vehicle's derivative is the same, bit for bit.
    let vehicle_rows = |ds: &State<f64, NX>| [&ds[..6], &ds[VX..VX + 6]].concat();
    let base = vehicle_rows(&ds);
    for (i, x) in [(XC, 0.7), (XC + 1, -1.3), (ZC, -4.0), (LINE, 2.2)]
        .into_iter()
        .chain([(VXC, 3.0), (VXC + 1, -0.5), (VXC + 2, -6.0), (VLINE, 0.5)])
    {
        let mut moved = s;
        moved[i] += x;
        assert_eq!(vehicle_rows(&derivative(&v, &moved)), base, "state {i}");
    }
    // And it stays open.
    let later = v.payload.last_metres(&s, &trig, &cue(5.0)).unwrap();
    assert_eq!((later.release, later.hooked), (0.0, 0.0));
}

/// A parcel resting on the ground with the line slack sinks in by its weight over the
/// stiffness and stays there; sliding, friction slows it at mu g; the hook opens after
/// `release_delay` at rest.
#[test]
fn the_ground_holds_a_resting_parcel_and_friction_slows_a_sliding_one() {
    let mut cfg = winch_config(12.0, 1.0);
    cfg.gust.air_density = 0.0;
    cfg.payload.cable.release = Some(Release::Touchdown);
    cfg.payload.cable.release_delay = Some(0.5);
    cfg.validate().unwrap();
    let mut v = vehicle(&cfg);
    let mut s: State<f64, NX> = v.rest_state([0.0, 0.0, 10.0], [0.0; 3]);
    let (mc, g, kg) = (v.payload.mc, v.body.g, v.payload.ground_k);
    // On the ground at its static depth, the line paid out beyond the distance: slack.
    s[ZC] = -mc * g / kg;
    s[LINE] = 11.0;
    let ds = derivative(&v, &s);
    assert!(ds[VXC + 2].abs() < 1e-12, "{}", ds[VXC + 2]);
    assert_eq!(v.payload.line(&s, &Trig::of(&s)).tension, 0.0);
    // Sliding at 1 m/s (far above the regularisation speed): decelerated at mu g.
    let mut sliding = s;
    sliding[VXC] = 1.0;
    let a = derivative(&v, &sliding)[VXC];
    let mu = v.payload.friction;
    assert!(
        (a + mu * g / (1.0 + (FRICTION_SPEED * FRICTION_SPEED)).sqrt()).abs() < 1e-12,
        "{a}"
    );
    // Touchdown at the first step in contact, then the hook opens 0.5 s later.
    let trig = Trig::of(&s);
    let mut opened = None;
    for k in 0..1000 {
        let cue = cue_at::<f64>(k);
        let ev = v.payload.last_metres(&s, &trig, &cue).unwrap();
        assert_eq!(ev.touchdown, if k == 0 { 1.0 } else { 0.0 });
        if ev.release == 1.0 {
            opened = Some(cue.t);
        }
    }
    let t = opened.expect("the hook opens");
    assert!((t - 0.5).abs() < 1.5e-3, "{t}");
}

/// Hunt and Crossley's contact: kg d (1 + alpha d'), d' = -vzc, never pulling; no force at
/// the first instant of contact whatever the speed (the linear damper pushed c v0 at once).
#[test]
fn the_ground_pushes_kg_d_one_plus_alpha_rate_and_nothing_at_first_contact() {
    let mut cfg = winch_config(12.0, 1.0);
    cfg.gust.air_density = 0.0;
    let v = vehicle(&cfg);
    let mut s: State<f64, NX> = v.rest_state([0.0, 0.0, 10.0], [0.0; 3]);
    s[LINE] = 11.0; // slack
    let (g, kg, alpha, mc) = (
        v.body.g,
        v.payload.ground_k,
        v.payload.ground_alpha,
        v.payload.mc,
    );
    assert_eq!(alpha, 1.0);
    // At first contact, at speed; in it, sinking and rising; rising fast (it would pull).
    for (depth, vz) in [(1e-15, -5.0), (1e-3, -1.0), (2e-3, 0.5), (1e-3, 1.5)] {
        s[ZC] = -depth;
        s[VXC + 2] = vz;
        let a = derivative(&v, &s)[VXC + 2];
        let normal = (kg * depth * (1.0 - alpha * vz)).max(0.0);
        assert!(
            (a - (normal / mc - g)).abs() < 1e-9,
            "depth {depth} vz {vz}: {a} vs {}",
            normal / mc - g
        );
    }
}

/// The ground's force and the resting clock are computed only when some lane's parcel
/// touches: in a lane-set where one lane's parcel rests on the ground and the others' hang in
/// the air (or all hang), each lane's derivative and events are its own vehicle's, bit for
/// bit, step after step.
#[test]
fn lanes_on_and_off_the_ground_fly_their_own_parcels() {
    use crate::lane::F64x4;
    let mut cfg = winch_config(12.0, 1.0);
    cfg.payload.cable.release = Some(Release::Touchdown);
    cfg.payload.cable.release_delay = Some(0.005);
    // The derivatives compared are taken hooked and released: without the rotors' wake on the
    // released parcel they agree (the line is slack either way).
    cfg.vehicle.downwash = false;
    cfg.validate().unwrap();
    let one = vehicle(&cfg);
    let base: State<f64, NX> = one.rest_state([0.0, 0.0, 10.0], [0.0; 3]);
    let (mc, g, kg) = (one.payload.mc, one.body.g, one.payload.ground_k);
    // Lane 0 rests on the ground with the line slack; the others hang, lane 3 just above it.
    let mut states = [base; 4];
    states[0][ZC] = -mc * g / kg;
    states[0][LINE] = 11.0;
    states[1][VXC] = -0.3;
    states[2][VXC + 1] = 0.2;
    states[3][ZC] = 1e-3;
    states[3][VXC] = -0.1;
    for touching in [true, false] {
        let lanes = if touching { [0, 1, 2, 3] } else { [1, 2, 3, 3] };
        let part = AnyVehicle::new(&cfg.model_context());
        let mut set = AnyVehicle::gather::<F64x4, Cable, Ideal>(&[&part; 4]);
        let mut each = [(); 4].map(|_| vehicle(&cfg));
        let s: State<F64x4, NX> = state_from_fn(|i| F64x4::from_fn(|l| states[lanes[l]][i]));
        let u = Inputs {
            u1: F64x4::splat(hover_thrust(&one).u1),
            tau: [F64x4::splat(0.0); 3],
        };
        let w = [F64x4::splat(0.0); 3];
        let got = set.derivative(&s, &Trig::of(&s), &u, &w);
        for k in 0..20 {
            let (cue, lanes_cue) = (cue_at::<f64>(k), cue_at::<F64x4>(k));
            let ev = set
                .payload
                .last_metres(&s, &Trig::of(&s), &lanes_cue)
                .unwrap();
            for (l, v) in each.iter_mut().enumerate() {
                let sl = &states[lanes[l]];
                let e = v.payload.last_metres(sl, &Trig::of(sl), &cue).unwrap();
                for (a, b) in [(ev.touchdown, e.touchdown), (ev.release, e.release)] {
                    assert_eq!(a.lane(l).to_bits(), b.to_bits(), "lane {l} step {k}");
                }
            }
        }
        for (l, v) in each.iter().enumerate() {
            let want = derivative(v, &states[lanes[l]]);
            for i in 0..NX {
                assert_eq!(
                    got[i].lane(l).to_bits(),
                    want[i].to_bits(),
                    "lane {l} state {i}"
                );
            }
        }
        // The ground holds the resting lane's parcel; the resting lane's hook opens after the
        // delay.
        if touching {
            assert!(got[VXC + 2].lane(0).abs() < 1e-9, "{:?}", got[VXC + 2]);
        }
        let rested = set.payload.hooked.lane(0);
        assert_eq!(rested, if touching { 0.0 } else { 1.0 });
    }
}

/// The winch's servo gain is a constant: any acceleration is resolved (before, a gain of
/// 4 a / v made a large one unstable and it was refused); a step too coarse for the servo
/// (kw dt > 1) is refused naming `integrator.dt`, at the bound it is accepted.
#[test]
fn a_step_too_coarse_for_the_winch_is_refused_and_any_acceleration_resolves() {
    let mut cfg = winch_config(8.0, 1.0);
    cfg.payload.cable.winch_acceleration = Some(1.0e6);
    cfg.validate().expect("any acceleration is resolved");
    // The servo's own check (the paper's other keys are not all for so coarse a step).
    let check = |cfg: &Config| Cable::validate_winch_step(&cfg.payload.cable, &cfg.model_context());
    cfg.integrator.dt = 1.0 / WINCH_SPEED_GAIN;
    check(&cfg).expect("gain x dt = 1 is resolved");
    cfg.integrator.dt = 1.01 / WINCH_SPEED_GAIN;
    let e = check(&cfg).unwrap_err();
    assert_eq!(e.key, "integrator.dt");
    assert!(e.message.contains("winch's speed servo"), "{e}");
}

/// The line's rate from rest toward a far target: it rises at the acceleration limit and
/// reaches the winch's speed at v / a (within the servo's lag, a / kw in speed), for a slow
/// winch and a fast one alike, and stops at its target without overshoot; on a lowering
/// shorter than 1.5 v^2 / a (accelerating at a, stopping at a / 2) the peak is sqrt(2 a P / 3),
/// so a faster winch never pays out slower (before: kp = a / v gave 5 m/s a 0.88 m/s peak).
#[test]
fn the_line_reaches_its_speed_when_the_acceleration_limit_says() {
    let line_alone = |v: f64, a: f64, payout: f64| {
        let mut cfg = winch_config(12.0, 1.0);
        cfg.payload.cable.winch_speed = Some(v);
        cfg.payload.cable.winch_acceleration = Some(a);
        let mut veh = vehicle(&cfg);
        veh.payload.target = 1.0 + payout;
        let mut s: State<f64, NX> = veh.rest_state([0.0, 0.0, 10.0], [0.0; 3]);
        let dt = 1e-4;
        let mut rates = Vec::new();
        let mut longest: f64 = 0.0;
        // Only the line moves (semi-implicit Euler on L, L'): the servo's own law.
        for _ in 0..((payout / v + 2.0 * v / a + 1.0) / dt) as usize {
            let ds = derivative(&veh, &s);
            s[VLINE] += dt * ds[VLINE];
            s[LINE] += dt * s[VLINE];
            rates.push(s[VLINE]);
            longest = longest.max(s[LINE]);
        }
        assert!(longest <= 1.0 + payout + 1e-9, "overshoot: {longest}");
        (rates, s[LINE], dt)
    };
    for (v, a) in [(1.0, 1.0), (5.0, 2.0)] {
        let (rates, end, dt) = line_alone(v, a, 30.0);
        let at = |t: f64| rates[(t / dt) as usize];
        // Half-way up the ramp: a t (the acceleration limit holds).
        assert!(
            (at(0.5 * v / a) - 0.5 * v).abs() < 1e-3 * v,
            "{}",
            at(0.5 * v / a)
        );
        // At v / a within the lag a / kw, and settled 5 / kw later.
        let lag = a / WINCH_SPEED_GAIN;
        assert!((at(v / a) - v).abs() <= 1.01 * lag, "{} vs {v}", at(v / a));
        assert!((at(v / a + 5.0 / WINCH_SPEED_GAIN) - v).abs() < 0.01 * lag);
        assert!((end - 31.0).abs() < 1e-3, "{end}");
    }
    let peaks: Vec<f64> = [0.5, 1.0, 2.0, 3.0, 4.0, 5.0]
        .iter()
        .map(|&v| {
            let (rates, end, _) = line_alone(v, 1.0, 4.0);
            assert!((end - 5.0).abs() < 1e-3, "{v}: {end}");
            rates.iter().cloned().fold(0.0, f64::max)
        })
        .collect();
    for w in peaks.windows(2) {
        assert!(w[1] >= w[0] - 1e-9, "{peaks:?}");
    }
    // The fastest: the profile's sqrt(2 a P / 3) = 1.63 m/s on 4 m, less the servo's lag.
    assert!(peaks[5] > 1.55, "{peaks:?}");
}

/// A release at touchdown given with another payload is named as the word it is, not NaN.
#[test]
fn a_touchdown_release_on_another_payload_is_shown_as_given() {
    let mut cfg = paper();
    cfg.payload.cable.release = Some(Release::Touchdown);
    let e = cfg.validate().unwrap_err();
    assert_eq!(e.key, "payload.release");
    assert!(e.message.contains("got \"touchdown\""), "{e}");
    assert!(!e.message.contains("NaN"), "{e}");
}
