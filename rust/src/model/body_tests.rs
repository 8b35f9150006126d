//! The rigid body's checks: torque-free rotation conserves the angular momentum (inertial) and
//! the kinetic energy (Euler's equations with w x J w), the quaternion stays unit; the
//! quaternion's Euler angles and rotation matrix agree with the paper's; the body-axis drag.

use super::*;
use crate::model::actuator::Ideal;
use crate::model::payload::Cable;
use crate::model::{AnyVehicle, Inputs, State, Vehicle};
use crate::rk4::rk4_step;
use crate::scenario::tests::paper;
use crate::scenario::{Config, PayloadKind};

type Spinning = Vehicle<f64, Cable, Ideal, Rigid>;
const NX: usize = 21;

/// A rigid body with an asymmetric inertia and a cable hooked at its centre of gravity (so the
/// line applies no torque), no drag.
fn rigid_config() -> Config {
    let mut cfg = paper();
    cfg.vehicle.body = BodyModel::Rigid;
    cfg.vehicle.inertia = [0.02, 0.035, 0.05];
    cfg.vehicle.inertia_error = [0.0; 3];
    cfg.vehicle.drag_area = 0.0;
    cfg.vehicle.lateral_drag_area = 0.0;
    cfg.payload.model = PayloadKind::Cable;
    cfg.payload.cable.cable_length = Some(1.0);
    cfg.payload.natural_frequency = Some(2.0);
    cfg.validate().expect("a valid rigid scenario");
    cfg
}

/// Inertial angular momentum R J w and kinetic energy w . J w / 2.
fn momentum_energy(v: &Spinning, s: &State<f64, NX>) -> ([f64; 3], f64) {
    let r = Rigid::frame(s);
    let lay = Spinning::LAYOUT;
    let w = [s[lay.rate()], s[lay.rate() + 1], s[lay.rate() + 2]];
    let jw = [0, 1, 2].map(|i| v.body.inertia[i] * w[i]);
    let energy = 0.5 * (0..3).map(|i| w[i] * jw[i]).sum::<f64>();
    (r.to_inertial(&jw), energy)
}

#[test]
fn torque_free_rotation_conserves_momentum_and_energy() {
    let cfg = rigid_config();
    let v: Spinning = AnyVehicle::new(&cfg.model_context()).vehicle_on::<Rigid, Cable, Ideal>();
    let mut s: State<f64, NX> = v.rest_state([0.0; 3], [0.1, -0.2, 0.3]);
    let r = Spinning::LAYOUT.rate();
    // Near the intermediate axis: the tumbling is strong, w x J w large.
    s[r..r + 3].copy_from_slice(&[0.3, 4.0, -0.5]);
    let (h0, e0) = momentum_energy(&v, &s);
    let zero = Inputs {
        u1: 0.0,
        tau: [0.0; 3],
    };
    let dt = 1e-4;
    let mut worst: f64 = 0.0;
    for _ in 0..30_000 {
        s = rk4_step(&v, &s, &Rigid::frame(&s), &zero, &[0.0; 3], dt);
        let q = [s[3], s[4], s[5], s[6]];
        let norm = q.iter().map(|x| x * x).sum::<f64>().sqrt();
        assert!((norm - 1.0).abs() < 1e-15, "|q| = {norm}");
        worst = worst.max((norm - 1.0).abs());
    }
    let (h, e) = momentum_energy(&v, &s);
    for i in 0..3 {
        assert!(
            (h[i] - h0[i]).abs() < 1e-10,
            "H[{i}]: {} vs {}",
            h[i],
            h0[i]
        );
    }
    assert!((e - e0).abs() < 1e-10 * e0, "energy {e} vs {e0}");
    // The body did tumble: its rates changed by much more than the tolerance.
    assert!(
        (s[r + 1] - 4.0).abs() > 0.1,
        "no tumbling: {:?}",
        &s[r..r + 3]
    );
}

/// Without w x J w (the torque-free equations as if J were spherical) the momentum would not be
/// conserved: the check above can fail.
#[test]
fn dropping_the_gyroscopic_term_breaks_the_momentum() {
    let cfg = rigid_config();
    let v: Spinning = AnyVehicle::new(&cfg.model_context()).vehicle_on::<Rigid, Cable, Ideal>();
    let w = [0.3, 4.0, -0.5];
    let wdot = v.body.rotation(&w, &[0.0; 3], &None);
    // J dw/dt = -w x J w, not 0.
    let j = v.body.inertia;
    let jw = [j[0] * w[0], j[1] * w[1], j[2] * w[2]];
    let cross = [
        w[1] * jw[2] - w[2] * jw[1],
        w[2] * jw[0] - w[0] * jw[2],
        w[0] * jw[1] - w[1] * jw[0],
    ];
    for i in 0..3 {
        assert!((j[i] * wdot[i] + cross[i]).abs() < 1e-15);
    }
    assert!(cross.iter().any(|c| c.abs() > 1e-3));
}

#[test]
#[allow(clippy::needless_range_loop)]
fn quaternion_euler_and_rotation_agree_with_the_papers_angles() {
    for euler in [[0.1, -0.2, 0.3], [-0.7, 0.4, -2.9], [1.2, -1.1, 3.0]] {
        let q = Rigid::quaternion_of_euler(euler);
        let rot = Rotation::of_quaternion(q);
        let paper = Trig::of_angles(euler[0], euler[1], euler[2]).axes();
        for j in 0..3 {
            for i in 0..3 {
                assert!((rot.axes[j][i] - paper[j][i]).abs() < 1e-15);
            }
        }
        let back = rot.euler();
        for i in 0..3 {
            assert!((back[i] - euler[i]).abs() < 1e-14, "{back:?} vs {euler:?}");
        }
        // The angles' sines and cosines from the matrix, without a trigonometric function.
        let (got, want) = (rot.trig(), Trig::of_angles(euler[0], euler[1], euler[2]));
        for (g, w) in [
            (got.sphi, want.sphi),
            (got.cphi, want.cphi),
            (got.sth, want.sth),
            (got.cth, want.cth),
            (got.spsi, want.spsi),
            (got.cpsi, want.cpsi),
        ] {
            assert!((g - w).abs() < 1e-14, "{euler:?}: {g} vs {w}");
        }
        // A quaternion off unit length gives the same rotation (normalised on the way).
        let scaled = Rotation::of_quaternion(q.map(|x| 1.001 * x));
        for j in 0..3 {
            for i in 0..3 {
                assert!((scaled.axes[j][i] - rot.axes[j][i]).abs() < 1e-15);
            }
        }
    }
}

#[test]
fn body_drag_is_quadratic_in_body_axes() {
    let mut cfg = rigid_config();
    cfg.vehicle.drag_coefficients = [0.5, 0.7, 1.1];
    let v: Spinning = AnyVehicle::new(&cfg.model_context()).vehicle_on::<Rigid, Cable, Ideal>();
    let euler = [0.2, -0.3, 0.9];
    let rot = Rotation::of_quaternion(Rigid::quaternion_of_euler(euler));
    let (vel, wind) = ([3.0, -1.0, 0.5], [1.0, 2.0, -0.5]);
    let f = rot.drag(&v.body, &vel, &wind);
    // In body axes: -|v_b| c_i v_b,i with v_b = R^T (v - w).
    let vb = rot.to_body(&[2.0, -3.0, 1.0]);
    let speed = (vb[0] * vb[0] + vb[1] * vb[1] + vb[2] * vb[2]).sqrt();
    let fb = rot.to_body(&f);
    for i in 0..3 {
        let want = -speed * cfg.vehicle.drag_coefficients[i] * vb[i];
        assert!((fb[i] - want).abs() < 1e-13, "{i}: {} vs {want}", fb[i]);
    }
}

#[test]
fn the_rigid_body_refuses_the_spring_and_the_paper_body_the_coefficients() {
    let mut cfg = paper();
    cfg.vehicle.body = BodyModel::Rigid;
    let e = cfg.validate().expect_err("the spring on the rigid body");
    assert_eq!(e.key, "vehicle.body");
    let mut cfg = paper();
    cfg.vehicle.drag_coefficients = [0.1, 0.0, 0.0];
    let e = cfg
        .validate()
        .expect_err("drag coefficients on the paper's body");
    assert_eq!(e.key, "vehicle.drag_coefficients");
}

#[test]
fn a_lane_surely_within_the_tilt_bound_is_within_it_as_euler_finds() {
    use rand::{RngExt, SeedableRng};
    use std::f64::consts::{FRAC_PI_2, PI};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    let bounds = [
        1e-5,
        2e-4,
        0.05,
        0.3,
        PI / 4.0,
        1.0,
        FRAC_PI_2,
        2.0,
        3.1,
        PI,
        4.0,
    ];
    let mut surely = 0;
    for t in bounds.into_iter().chain([f64::INFINITY, f64::NAN]) {
        let bound = TiltBound::<f64>::new(|_| t);
        let edge = t.min(PI);
        for i in 0..20_000 {
            // Angles anywhere, and on the bound to within a relative 1e-3 .. 1e-16 either side.
            let d = 10f64.powf(rng.random_range(-16.0..-3.0)) * rng.random_range(-1.0..1.0);
            let near = edge * (1.0 + d) * if rng.random_bool(0.5) { 1.0 } else { -1.0 };
            let (any_roll, any_pitch) = (
                rng.random_range(-PI..PI),
                rng.random_range(-FRAC_PI_2..FRAC_PI_2),
            );
            let (roll, pitch) = match i % 3 {
                0 => (near, any_pitch),
                1 => (any_roll, near.clamp(-FRAC_PI_2, FRAC_PI_2)),
                _ => (any_roll, any_pitch),
            };
            let yaw = rng.random_range(-PI..PI);
            let rot = Rotation::of_quaternion(Rigid::quaternion_of_euler([roll, pitch, yaw]));
            let e = rot.euler();
            let within = e[0].abs() <= t && e[1].abs() <= t;
            let sure = rot.surely_within(&bound) == 1;
            assert!(
                within || !sure,
                "t {t}: {e:?} is past the bound, found surely within"
            );
            // Well inside a bound the test can resolve, the angles are never needed (but at
            // the pole, where the roll is rounding's, and |R31| may round past 1).
            let off_pole = e[1].cos() > 1e-6;
            if t >= 1e-3 && off_pole && e[0].abs() <= 0.99 * t && e[1].abs() <= 0.99 * t {
                assert!(sure, "t {t}: {e:?} is well within, not found so");
            }
            surely += sure as usize;
        }
        if t.is_nan() || t <= 1e-4 {
            let any = Rotation::of_quaternion([1.0, 0.0, 0.0, 0.0]).surely_within(&bound);
            assert_eq!(
                any, 0,
                "t {t}: no lane is surely within a bound too small to narrow"
            );
        }
    }
    assert!(surely > 50_000, "{surely}");
}
