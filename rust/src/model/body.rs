//! The rigid quadrotor (docs/model.md section 1): mass, inertia, its own drag, and the rotational
//! equations. How it translates depends on how the payload pulls (`payload`).

use crate::config::Config;
use crate::lane::{gather3, Lane};

/// The quadrotor's parameters, resolved once from the scenario (plant inertia = nominal +
/// error). `L = f64` is one vehicle; a lane type carries one vehicle per lane (`gather`).
#[derive(Clone, Copy, Debug)]
pub struct Body<L = f64> {
    /// kg, the quadrotor alone.
    pub m: L,
    pub g: L,
    /// Plant inertia I + dI.
    pub inertia: [L; 3],
    /// 1/2 rho CdA of the quadrotor: vertical (`vehicle.drag_area`) and horizontal
    /// (`vehicle.lateral_drag_area`).
    pub drag_quad: L,
    pub drag_lateral: L,
    /// Reciprocals, computed once: the derivative multiplies by them.
    pub inv_m: L,
    pub inv_inertia: [L; 3],
}

impl Body {
    /// The quadrotor of a validated scenario.
    pub fn new(cfg: &Config) -> Self {
        let half_rho = 0.5 * cfg.gust.air_density;
        let v = &cfg.vehicle;
        let inertia = [
            v.inertia[0] + v.inertia_error[0],
            v.inertia[1] + v.inertia_error[1],
            v.inertia[2] + v.inertia_error[2],
        ];
        Self {
            m: v.mass,
            g: cfg.environment.gravity,
            inertia,
            drag_quad: half_rho * v.drag_area,
            drag_lateral: half_rho * v.lateral_drag_area,
            inv_m: 1.0 / v.mass,
            inv_inertia: inertia.map(|i| 1.0 / i),
        }
    }

    /// One vehicle per lane: lane `l` of every parameter is `each[l]`'s.
    pub fn gather<L: Lane>(each: &[&Body]) -> Body<L> {
        let at = |f: fn(&Body) -> f64| L::from_fn(|l| f(each[l]));
        let at3 = |f: fn(&Body) -> [f64; 3]| -> [L; 3] { gather3(each, f) };
        Body {
            m: at(|b| b.m),
            g: at(|b| b.g),
            inertia: at3(|b| b.inertia),
            drag_quad: at(|b| b.drag_quad),
            drag_lateral: at(|b| b.drag_lateral),
            inv_m: at(|b| b.inv_m),
            inv_inertia: at3(|b| b.inv_inertia),
        }
    }
}

/// Drag force on a body of `k` = 1/2 rho CdA moving at `v` in wind `wind` (one axis).
#[inline(always)]
pub fn drag<L: Lane>(k: L, v: L, wind: L) -> L {
    let rel = v - wind;
    rel * rel.abs() * (-k)
}

impl<L: Lane> Body<L> {
    /// The vertical drag force on the quadrotor (N) at vertical speed `vz` in vertical wind
    /// `wind_z` (m/s): Fdz = -1/2 rho CdA (vz - wind_z) |vz - wind_z| (docs/model.md section 1),
    /// the very term the derivative uses (and the trace's `drag_z`).
    #[inline(always)]
    pub fn vertical_drag(&self, vz: L, wind_z: L) -> L {
        drag(self.drag_quad, vz, wind_z)
    }

    /// d(p, q, r)/dt: Euler's equations in the near-hover form, with the controller's torques
    /// `tau` and, if the payload applies one, its torque `extra` (body axes).
    #[inline(always)]
    pub fn rotation(&self, rate: &[L; 3], tau: &[L; 3], extra: &Option<[L; 3]>) -> [L; 3] {
        let [p, q, r] = *rate;
        let tau = match extra {
            Some(t) => [tau[0] + t[0], tau[1] + t[1], tau[2] + t[2]],
            None => *tau,
        };
        // Destructured, not `array::map`: everything here must inline into the flight loop.
        let [ixx, iyy, izz] = self.inertia;
        let [inv_ixx, inv_iyy, inv_izz] = self.inv_inertia;
        // Products-plus-sums as `mul_add`: the same bits as `a * b + c` except in the fused
        // mode (`Lane::mul_add`).
        [
            (q * r).mul_add(iyy - izz, tau[0]) * inv_ixx,
            (p * r).mul_add(izz - ixx, tau[1]) * inv_iyy,
            (p * q).mul_add(ixx - iyy, tau[2]) * inv_izz,
        ]
    }
}
