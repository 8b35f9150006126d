//! One classical RK4 step of the vehicle, its command and wind held over the four stages.

use crate::lane::{KernelOps, Lane};
use crate::model::{state_from_fn, ActuatorModel, BodyKind, State, Vehicle};

/// One RK4 step of the vehicle with the actuator command and wind held; `trig` is `s`'s
/// attitude (`BodyKind::frame`; the controller needed it too). The later stages get theirs
/// from it (`BodyKind::advanced`: on the paper's body by angle addition, `Trig::advanced`).
/// The step ends with `BodyKind::project` (the rigid body's quaternion renormalised).
#[inline(always)]
pub fn rk4_step<L: KernelOps, Pay, Act, B: BodyKind, const N: usize>(
    vehicle: &Vehicle<L, Pay, Act, B>,
    s: &State<L, N>,
    trig: &B::Frame<L>,
    cmd: &Act::Command,
    w: &[L; 3],
    dt: f64,
) -> State<L, N>
where
    Pay: crate::model::PayloadModel<L>,
    Act: ActuatorModel<L>,
{
    let k1 = vehicle.derivative(s, trig, cmd, w);
    let mut next = *s;
    rk4_advance(vehicle, &mut next, trig, &k1, cmd, w, dt);
    next
}

/// `rk4_step` in place, with its first stage's derivative `k1 = vehicle.derivative(s, trig,
/// cmd, w)` given (the flight loop has it from `Vehicle::derivative_and_outputs`): `s`
/// becomes the step's end, each element from its own old value as in `rk4_step` (the same
/// bits), without a copy of the whole state per step.
#[inline(always)]
pub fn rk4_advance<L: KernelOps, Pay, Act, B: BodyKind, const N: usize>(
    vehicle: &Vehicle<L, Pay, Act, B>,
    s: &mut State<L, N>,
    trig: &B::Frame<L>,
    k1: &State<L, N>,
    cmd: &Act::Command,
    w: &[L; 3],
    dt: f64,
) where
    Pay: crate::model::PayloadModel<L>,
    Act: ActuatorModel<L>,
{
    #[inline(always)]
    fn stage<L: Lane, const N: usize>(base: &State<L, N>, k: &State<L, N>, h: f64) -> State<L, N> {
        state_from_fn(
            #[inline(always)]
            |i| k[i].mul_add(L::splat(h), base[i]),
        )
    }
    let s2 = stage(s, k1, 0.5 * dt);
    let k2 = vehicle.derivative(&s2, &B::advanced(trig, k1, 0.5 * dt, &s2), cmd, w);
    let s3 = stage(s, &k2, 0.5 * dt);
    let k3 = vehicle.derivative(&s3, &B::advanced(trig, &k2, 0.5 * dt, &s3), cmd, w);
    let s4 = stage(s, &k3, dt);
    let k4 = vehicle.derivative(&s4, &B::advanced(trig, &k3, dt, &s4), cmd, w);
    let h6 = dt / 6.0;
    for i in 0..N {
        s[i] = (k1[i] + (k2[i] + k3[i]) * 2.0 + k4[i]).mul_add(L::splat(h6), s[i]);
    }
    // The rigid body's quaternion back to unit length (nothing on the paper's body).
    B::project(s);
}
