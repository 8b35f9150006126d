//! PX4's control allocator for the `px4` law (docs/model.md, "The PX4 cascade", "Allocation"):
//! the normalised pseudo-inverse of the rotors' effectiveness (PX4's
//! `ActuatorEffectivenessRotors`, `ControlAllocationPseudoInverse`) and the sequential
//! desaturation with airmode off (`ControlAllocationSequentialDesaturation::mixAirmodeDisabled`,
//! PX4's default `MC_AIRMODE = 0`): normalised thrust and torques in, motor outputs in [0, 1]
//! out, with the torque the motors could not give (`control_allocator_status`).
//!
//! Axes are the model's body axes (x forward, y left, z up) for the torques, PX4's sign for the
//! thrust (`THRUST_Z`, along body z down: a lift is negative), as the desaturation's "reduce
//! thrust only" test reads that sign. The normalisation is the same in either frame.

use crate::lane::{each3, each4, Lane};
use crate::model::actuator::rotors::{allocation, RotorLayout};
use nalgebra::DMatrix;

/// Axes of the allocation's control vector (PX4's `ControlAxis` without `THRUST_X/Y`, whose
/// rotor effectiveness is zero).
pub const ROLL: usize = 0;
pub const PITCH: usize = 1;
pub const YAW: usize = 2;
pub const THRUST_Z: usize = 3;

/// PX4's motor range (`ControlAllocator::update_effectiveness_matrix_if_needed`: 0 to 1 for a
/// motor that does not reverse).
const MOTOR_MIN: f64 = 0.0;
const MOTOR_MAX: f64 = 1.0;
/// `mixYaw` lets yaw use 15 % of the range above the top (`_actuator_max += (max - min) 0.15`).
const YAW_HEADROOM: f64 = MOTOR_MAX + (MOTOR_MAX - MOTOR_MIN) * 0.15;
/// `computeDesaturationGain` skips motors whose entry in the desaturation vector is weaker.
const WEAK_ENTRY: f64 = 0.2;
/// `normalizeControlAllocationMatrix` zeroes smaller entries of the mix; a torque column's
/// entries above it count as the axis's effective motors (`updateControlAllocationMatrixScale`).
const SMALL_ENTRY: f64 = 1e-3;

/// The allocation of one vehicle, from its rotor geometry (f64, computed once).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Mixer {
    /// `mix[i][axis]`: motor i's output per unit of normalised control on `axis`.
    pub mix: [[f64; 4]; 4],
    /// `1 / mix[i][axis]` where the desaturation may use it, else 0.
    pub inv: [[f64; 4]; 4],
    /// `effect[axis][i]`: the normalised control motor i gives per unit output (PX4's
    /// effectiveness times its allocation scale: `getAllocatedControl`).
    pub effect: [[f64; 4]; 4],
}

impl Mixer {
    /// PX4's normalised allocation of a quadrotor with rotors at `arm` (m) in `layout` and
    /// reaction torque `km` (m) per unit thrust. The effectiveness's thrust coefficient
    /// (`CA_ROTORn_CT`) drops out of the normalisation: it is 1 here.
    pub fn new(layout: RotorLayout, arm: f64, km: f64) -> Self {
        // Effectiveness: torques as the rotors' geometry gives them (rows 1-3 of M), thrust
        // along body z down.
        let m = allocation(layout, arm, km);
        let e: [[f64; 4]; 4] = [m[1], m[2], m[3], [-1.0; 4]];
        let a = pseudo_inverse(&e);
        // updateControlAllocationMatrixScale: roll and pitch share the larger of
        // sqrt(|column|^2 / (n / 2)), n the motors with a non-negligible entry; yaw the
        // column's largest entry; thrust the mean norm of the motors' thrust entries.
        let torque_scale = |axis: usize| {
            let n = (0..4).filter(|&i| a[i][axis].abs() > SMALL_ENTRY).count();
            if n == 0 {
                1.0
            } else {
                let sq: f64 = (0..4).map(|i| a[i][axis] * a[i][axis]).sum();
                (sq / (n as f64 / 2.0)).sqrt()
            }
        };
        let rp = torque_scale(ROLL).max(torque_scale(PITCH));
        let yaw = (0..4).map(|i| a[i][YAW]).fold(f64::NEG_INFINITY, f64::max);
        let thrusting: Vec<f64> = (0..4)
            .map(|i| a[i][THRUST_Z].abs())
            .filter(|n| *n > f32::EPSILON as f64)
            .collect();
        let thrust = if thrusting.is_empty() {
            1.0
        } else {
            thrusting.iter().sum::<f64>() / thrusting.len() as f64
        };
        let mut scale = [rp, rp, yaw, thrust];
        // normalizeControlAllocationMatrix divides only by scales above FLT_EPSILON.
        for s in &mut scale {
            if s.is_nan() || *s <= f32::EPSILON as f64 {
                *s = 1.0;
            }
        }
        let mix: [[f64; 4]; 4] = std::array::from_fn(|i| {
            std::array::from_fn(|j| {
                let x = a[i][j] / scale[j];
                if x.abs() < SMALL_ENTRY {
                    0.0
                } else {
                    x
                }
            })
        });
        let inv = mix.map(|row| row.map(|x| if x.abs() < WEAK_ENTRY { 0.0 } else { 1.0 / x }));
        let effect = std::array::from_fn(|j| std::array::from_fn(|i| e[j][i] * scale[j]));
        Self { mix, inv, effect }
    }
}

/// PX4's `matrix::geninv`: the pseudo-inverse (a singular geometry, e.g. a zero arm, leaves
/// its axis without motors rather than failing). NaN if the decomposition does not converge.
/// Column `axis` of a 4 x 4 matrix of lane values.
#[inline(always)]
fn column<L: Copy>(m: &[[L; 4]; 4], axis: usize) -> [L; 4] {
    [m[0][axis], m[1][axis], m[2][axis], m[3][axis]]
}

fn pseudo_inverse(e: &[[f64; 4]; 4]) -> [[f64; 4]; 4] {
    let m = DMatrix::from_fn(4, 4, |i, j| e[i][j]);
    let inv = crate::svd::bounded(m, true, true, f64::EPSILON, 1000)
        .and_then(|svd| svd.pseudo_inverse(1e-12).ok());
    match inv {
        Some(p) => std::array::from_fn(|i| std::array::from_fn(|j| p[(i, j)])),
        None => [[f64::NAN; 4]; 4],
    }
}

/// What the allocation gave: the motor outputs in [0, 1] and the control it could not give.
pub struct Allocated<L> {
    pub motors: [L; 4],
    /// Normalised roll, pitch and yaw torque asked for less the torque the outputs give
    /// (`control_allocator_status.unallocated_torque`).
    pub unallocated: [L; 3],
}

/// `computeDesaturationGain`: the gain along `d` (its usable inverse entries `inv`) that
/// removes the worst violations of [lo, hi] (below and above at once: their sum). A motor
/// within the range gives 0, as one PX4 skips does.
#[inline(always)]
fn gain<L: Lane>(inv: &[L; 4], u: &[L; 4], lo: f64, hi: f64) -> L {
    let zero = L::splat(0.0);
    let (mut k_min, mut k_max) = (zero, zero);
    for i in 0..4 {
        let over = (L::splat(lo) - u[i]).max(zero) + (L::splat(hi) - u[i]).min(zero);
        let k = over * inv[i];
        k_min = k_min.min(k);
        k_max = k_max.max(k);
    }
    k_min + k_max
}

/// `desaturateActuators`: move `u` along `d` by the gain, then by half the gain that remains;
/// `reduce_only` (PX4's `increase_only`, for the thrust: a positive gain along the negative
/// thrust column lowers the thrust) leaves `u` untouched when the first gain is negative.
#[inline(always)]
fn desaturate<L: Lane>(u: &mut [L; 4], d: &[L; 4], inv: &[L; 4], hi: f64, reduce_only: bool) {
    let first = gain(inv, u, MOTOR_MIN, hi);
    // Each move along `d`: none at all where `reduce_only` and the first gain is negative.
    // (A function inlined always, not a closure: see `lane::each3`.)
    #[inline(always)]
    fn nudge<L: Lane>(u: &mut [L; 4], d: &[L; 4], g: L, held: Option<L>) {
        let g = match held {
            Some(first) => first.if_negative(L::splat(0.0), g),
            None => g,
        };
        for i in 0..4 {
            u[i] += g * d[i];
        }
    }
    let held = reduce_only.then_some(first);
    nudge(u, d, first, held);
    let second = gain(inv, u, MOTOR_MIN, hi) * 0.5;
    nudge(u, d, second, held);
}

/// `mixAirmodeDisabled` then `clipActuatorSetpoint`: `c` the normalised control (roll, pitch,
/// yaw torques; thrust along body z down), `mix`, `inv`, `effect` a `Mixer`'s as lanes.
#[inline(always)]
pub fn allocate<L: Lane>(
    c: &[L; 4],
    mix: &[[L; 4]; 4],
    inv: &[[L; 4]; 4],
    effect: &[[L; 4]; 4],
) -> Allocated<L> {
    // (No closures or array `map` here: see `lane::each3`.)
    // Without yaw; thrust only reduced, then roll, then pitch given up where they must be.
    let mut u = each4(
        #[inline(always)]
        |i| mix[i][ROLL] * c[ROLL] + mix[i][PITCH] * c[PITCH] + mix[i][THRUST_Z] * c[THRUST_Z],
    );
    let (thrust, thrust_inv) = (column(mix, THRUST_Z), column(inv, THRUST_Z));
    desaturate(&mut u, &thrust, &thrust_inv, MOTOR_MAX, true);
    for axis in [ROLL, PITCH] {
        desaturate(
            &mut u,
            &column(mix, axis),
            &column(inv, axis),
            MOTOR_MAX,
            false,
        );
    }
    // mixYaw: yaw added and given up first (15 % headroom at the top), then thrust reduced.
    let yaw = column(mix, YAW);
    for i in 0..4 {
        u[i] += yaw[i] * c[YAW];
    }
    desaturate(&mut u, &yaw, &column(inv, YAW), YAW_HEADROOM, false);
    desaturate(&mut u, &thrust, &thrust_inv, MOTOR_MAX, true);
    let motors = each4(
        #[inline(always)]
        |i| u[i].clamp(L::splat(MOTOR_MIN), L::splat(MOTOR_MAX)),
    );
    let axes = [ROLL, PITCH, YAW];
    let unallocated = each3(
        #[inline(always)]
        |k| {
            let j = axes[k];
            let given = effect[j][0] * motors[0]
                + effect[j][1] * motors[1]
                + effect[j][2] * motors[2]
                + effect[j][3] * motors[3];
            c[j] - given
        },
    );
    Allocated {
        motors,
        unallocated,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A quad X: roll and pitch move each motor by 1/sqrt 2 per unit, yaw by 1, thrust by 1
    /// (PX4's documented normalisation); a plus quad: 1/sqrt 2 on the two motors of an axis.
    #[test]
    fn the_normalised_mix_is_px4s() {
        let h = std::f64::consts::FRAC_1_SQRT_2;
        let x = Mixer::new(RotorLayout::X, 0.1725, 0.016);
        for i in 0..4 {
            assert!((x.mix[i][ROLL].abs() - h).abs() < 1e-12, "{:?}", x.mix);
            assert!((x.mix[i][PITCH].abs() - h).abs() < 1e-12, "{:?}", x.mix);
            assert!((x.mix[i][YAW].abs() - 1.0).abs() < 1e-12, "{:?}", x.mix);
            assert!((x.mix[i][THRUST_Z] + 1.0).abs() < 1e-12, "{:?}", x.mix);
        }
        let p = Mixer::new(RotorLayout::Plus, 0.3, 0.05);
        assert!(
            (p.mix[1][ROLL] - h).abs() < 1e-12 && p.mix[0][ROLL] == 0.0,
            "{:?}",
            p.mix
        );
        assert_eq!(p.inv[0][ROLL], 0.0);
        // effect * mix is the identity (the allocated control of an unsaturated output).
        for m in [x, p] {
            for j in 0..4 {
                for k in 0..4 {
                    let s: f64 = (0..4).map(|i| m.effect[j][i] * m.mix[i][k]).sum();
                    let id = if j == k { 1.0 } else { 0.0 };
                    assert!((s - id).abs() < 1e-12, "{j} {k}: {s}");
                }
            }
        }
    }

    /// Inside the range the outputs are the mix and nothing is unallocated; a yaw that does not
    /// fit is given up before roll; a thrust above the top is reduced, never raised.
    #[test]
    fn desaturation_gives_up_yaw_first_and_only_reduces_thrust() {
        let m = Mixer::new(RotorLayout::X, 0.1725, 0.016);
        let (mix, inv, eff) = (m.mix, m.inv, m.effect);
        let c = [0.1, -0.05, 0.02, -0.5];
        let a = allocate(&c, &mix, &inv, &eff);
        for (row, got) in mix.iter().zip(a.motors) {
            let want: f64 = (0..4).map(|j| row[j] * c[j]).sum();
            assert!((got - want).abs() < 1e-15);
        }
        assert!(a.unallocated.iter().all(|x| x.abs() < 1e-15));
        // Roll 0.5 at hover thrust 0.5 fits (0.5 +/- 0.354); yaw 0.5 on top does not: roll
        // kept whole, yaw cut.
        let a = allocate(&[0.5, 0.0, 0.5, -0.5], &mix, &inv, &eff);
        assert!(a.unallocated[ROLL].abs() < 1e-12, "{:?}", a.unallocated);
        assert!(a.unallocated[YAW] > 0.1, "{:?}", a.unallocated);
        // Full thrust with a roll: thrust reduced so that the roll fits.
        let a = allocate(&[0.4, 0.0, 0.0, -1.0], &mix, &inv, &eff);
        assert!(a.unallocated[ROLL].abs() < 1e-12, "{:?}", a.unallocated);
        let total: f64 = a.motors.iter().sum();
        assert!(total < 4.0 - 0.5, "{:?}", a.motors);
        // Idle thrust with a roll: not raised (airmode off), the roll is cut instead.
        let a = allocate(&[0.4, 0.0, 0.0, -0.05], &mix, &inv, &eff);
        assert!(a.unallocated[ROLL] > 0.0, "{:?}", a.unallocated);
        let total: f64 = a.motors.iter().sum();
        assert!(total <= 4.0 * 0.05 + 1e-12, "{:?}", a.motors);
    }
}
