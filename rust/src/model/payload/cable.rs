//! The cable-slung payload (docs/model.md, "Cable-slung payload"): a point mass on a massless
//! elastic cable that swings freely in 3-D and goes slack, hooked `h` below the centre of
//! gravity. Three degrees of freedom: `xc, yc, zc` and `vxc, vyc, vzc`.
//!
//! ```text
//! hook          a  = p + R hb,   hb = (0, 0, -h)
//! hook velocity va = v + R (w x hb),   w = (p, q, r), the body's rates
//! cable         d = pc - a,  l = |d|,  u = d / l,  ldot = u . (vc - va)
//! tension       T = max(0, k (l - L0) + c ldot)   if l > L0,   else T = 0
//! payload       mc dvc/dt = -T u - mc g e3 + Fdc
//! quadrotor     m  dv/dt  =  U1 R e3 + T u - m g e3 + Fd
//! torque        tau += hb x (R^T (T u))
//! payload drag  Fdc = -1/2 rho CdA_c |vc - vw| (vc - vw)
//! ```
//!
//! The quadrotor's own drag Fd acts on its mass m alone: the payload is its own body. R and Fd
//! are the body's (`Frame`: the paper's Euler angles and inertial-axis drag, or the rigid
//! body's quaternion and body-axis drag); the state indices follow its layout.

use super::{Payload, PayloadModel, PayloadOutputs};
use crate::config::params::params;
use crate::config::section::OwnsKeys;
use crate::config::{non_negative, positive, Config, ConfigError};
use crate::lane::Lane;
use crate::model::body::{Body, Frame};
use crate::model::layout::{Axis, Bound, Part, StateVar};
use crate::model::{ix, Layout, State};

params! {
    /// The cable's own keys in `[payload]` (beside the point mass's, `config::payload::Shared`).
    /// Optional in the table, so that another kind's scenario reads without them; required
    /// when the cable flies (`validate`).
    pub struct CableParams {
        /// m, the cable's unstretched length L0 (required).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        cable_length: Option<f64> => "m", "Cable length, unstretched";
        /// m, the hook's distance below the centre of gravity along the body z axis (default 0).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        attachment_offset: Option<f64> => "m", "Hook below the centre of gravity";
    }
}

/// Cable payload parameters: `L = f64` for one vehicle, a lane type for one per lane.
#[derive(Clone, Copy, Debug)]
pub struct Cable<L = f64> {
    /// kg.
    pub mc: L,
    /// N/m (axial stiffness k) and N s/m (axial damping c).
    pub k: L,
    pub c: L,
    /// m, the unstretched length L0.
    pub rest_length: L,
    /// m, the hook's distance h below the centre of gravity (body z axis).
    pub offset: L,
    /// 1/2 rho CdA of the payload (in every direction).
    pub drag_payload: L,
    /// m, the length at hover l_eq = L0 + mc g / k.
    pub hover_length: L,
    /// 1 / mc, computed once.
    inv_mc: L,
}

/// The cable's states and the quadrotor's it reads, on the body of attitude `F` (the actuator's
/// states come after all of them).
struct Ix {
    xc: usize,
    vx: usize,
    p: usize,
    vxc: usize,
}

impl Ix {
    #[inline(always)]
    fn of<L: Lane, F: Frame<L>>() -> Self {
        let lay: Layout = F::layout(3, 0);
        Self {
            xc: lay.payload(),
            vx: lay.vel(),
            p: lay.rate(),
            vxc: lay.payload_vel(),
        }
    }
}

const fn payload(name: &'static str, axis: Axis, bound: Bound) -> StateVar {
    StateVar::new(name, axis, Some(bound), Part::Payload)
}

impl OwnsKeys for Cable {
    type Params = CableParams;

    /// The cable's keys: the length is required and positive, the hook's offset at least 0;
    /// neither may be given when another payload flies.
    fn validate(c: &CableParams, flown: bool, cfg: &Config) -> Result<(), ConfigError> {
        if !flown {
            for (key, value) in [
                ("payload.cable_length", c.cable_length),
                ("payload.attachment_offset", c.attachment_offset),
            ] {
                if let Some(x) = value {
                    return Err(ConfigError::new(
                        key,
                        format!(
                            "{key} applies to payload.model = \"cable\" only, got {x:?} with \
                             payload.model = \"{}\"",
                            cfg.payload.model.name()
                        ),
                    ));
                }
            }
            return Ok(());
        }
        let Some(l0) = c.cable_length else {
            return Err(ConfigError::new(
                "payload.cable_length",
                "payload.cable_length must be given for payload.model = \"cable\"",
            ));
        };
        positive("payload.cable_length", l0)?;
        match c.attachment_offset {
            Some(h) => non_negative("payload.attachment_offset", h),
            None => Ok(()),
        }
    }
}

impl Payload for Cable {
    type At<L: Lane> = Cable<L>;
    const POSITIONS: &'static [StateVar] = &[
        payload("xc", Axis::X, Bound::Distance),
        payload("yc", Axis::Y, Bound::Distance),
        payload("zc", Axis::Z, Bound::Distance),
    ];
    const VELOCITIES: &'static [StateVar] = &[
        payload("vxc", Axis::X, Bound::Speed),
        payload("vyc", Axis::Y, Bound::Speed),
        payload("vzc", Axis::Z, Bound::Speed),
    ];

    fn new(c: &CableParams, cfg: &Config) -> Self {
        let p = &cfg.payload;
        let k = cfg.stiffness();
        let rest_length = c.cable_length.unwrap_or(f64::NAN); // required: `validate`
        Self {
            mc: p.mass,
            k,
            c: p.damping,
            rest_length,
            offset: c.attachment_offset.unwrap_or(0.0),
            drag_payload: 0.5 * cfg.gust.air_density * p.drag_area,
            hover_length: rest_length + p.mass * cfg.environment.gravity / k,
            inv_mc: 1.0 / p.mass,
        }
    }

    /// The stretched line below the hook, the hook below the centre of gravity.
    fn hover_drop(&self) -> f64 {
        self.hover_length + self.offset
    }

    fn gather<L: Lane>(each: &[&Self]) -> Cable<L> {
        let at = |f: fn(&Cable) -> f64| L::from_fn(|l| f(each[l]));
        Cable {
            mc: at(|p| p.mc),
            k: at(|p| p.k),
            c: at(|p| p.c),
            rest_length: at(|p| p.rest_length),
            offset: at(|p| p.offset),
            drag_payload: at(|p| p.drag_payload),
            hover_length: at(|p| p.hover_length),
            inv_mc: at(|p| p.inv_mc),
        }
    }
}

/// `[f(0), f(1), f(2)]`, always inlined (`array::map` is not guaranteed to be: see
/// `model::state_from_fn`).
#[inline(always)]
fn vec3<L: Copy>(f: impl Fn(usize) -> L) -> [L; 3] {
    [f(0), f(1), f(2)]
}

#[inline(always)]
fn dot<L: Lane>(a: &[L; 3], b: &[L; 3]) -> L {
    a[0].mul_add(b[0], a[1].mul_add(b[1], a[2] * b[2]))
}

/// `value` where `gate > 0`, else 0, for `value >= 0`, without a branch (the model is generic
/// over lane types that have no select). `max(gate, 0) * MAX * MAX` is 0 where `gate <= 0`
/// and at least 1.6e293 (or infinite) where `gate > 0`, even at the least subnormal, so the
/// `min` returns `value` exactly there; NaN propagates.
#[inline(always)]
fn where_positive<L: Lane>(gate: L, value: L) -> L {
    value.min(L::splat(0.0).max(gate) * f64::MAX * f64::MAX)
}

/// The cable at one state: what both the dynamics and the outputs read.
#[derive(Clone, Copy, Debug)]
pub struct Line<L> {
    /// The hook's inertial position a (m).
    pub hook: [L; 3],
    /// pc - a (m) and its length l (m).
    pub d: [L; 3],
    pub length: L,
    /// The unit vector u from the hook to the payload.
    pub u: [L; 3],
    /// N, the tension T (never negative; exactly 0 while slack).
    pub tension: L,
}

impl<L: Lane> Cable<L> {
    /// The hook, the cable's direction and its tension at `s` (whose attitude is `frame`).
    #[inline(always)]
    pub fn line<F: Frame<L>, const N: usize>(&self, s: &State<L, N>, frame: &F) -> Line<L> {
        let Ix { xc, vx, p, vxc } = Ix::of::<L, F>();
        let [ex, ey, ez] = &frame.axes();
        let h = self.offset;
        // a = p + R (0, 0, -h);  va = v + R (w x hb) with w x hb = (-h q, h p, 0).
        let hook: [L; 3] = vec3(
            #[inline(always)]
            |i| (-h).mul_add(ez[i], s[ix::X + i]),
        );
        let (hq, hp) = (h * s[p + 1], h * s[p]);
        let va: [L; 3] = vec3(
            #[inline(always)]
            |i| hp.mul_add(ey[i], (-hq).mul_add(ex[i], s[vx + i])),
        );
        let d: [L; 3] = vec3(
            #[inline(always)]
            |i| s[xc + i] - hook[i],
        );
        let length = dot(&d, &d).sqrt();
        let inv = L::splat(1.0) / length;
        let u = vec3(
            #[inline(always)]
            |i| d[i] * inv,
        );
        let rel = vec3(
            #[inline(always)]
            |i| s[vxc + i] - va[i],
        );
        let ldot = dot(&u, &rel);
        let stretch = length - self.rest_length;
        let pull = L::splat(0.0).max(stretch.mul_add(self.k, self.c * ldot));
        Line {
            hook,
            d,
            length,
            u,
            tension: where_positive(stretch, pull),
        }
    }

    /// mc dvc/dt = -T u - mc g e3 + Fdc: the payload's inertial acceleration.
    #[inline(always)]
    fn acceleration<F: Frame<L>, const N: usize>(
        &self,
        body: &Body<L>,
        s: &State<L, N>,
        line: &Line<L>,
        w: &[L; 3],
    ) -> [L; 3] {
        let vxc = Ix::of::<L, F>().vxc;
        let rel = vec3(
            #[inline(always)]
            |i| s[vxc + i] - w[i],
        );
        let k = dot(&rel, &rel).sqrt() * (-self.drag_payload);
        let mut a = vec3(
            #[inline(always)]
            |i| rel[i].mul_add(k, -(line.tension * line.u[i])) * self.inv_mc,
        );
        a[2] = a[2] - body.g;
        a
    }

    /// rad, the cable's angle from hanging straight down, acos(-u_z), as 2 asin(|u + e3| / 2):
    /// accurate at small angles (acos loses half the digits near 1), clamped against rounding.
    #[inline(always)]
    fn swing(line: &Line<L>) -> L {
        let [dx, dy, dz] = line.d;
        let up = dz + line.length;
        let chord = dx.mul_add(dx, dy.mul_add(dy, up * up)).sqrt();
        let half = chord / (line.length * 2.0);
        L::splat(1.0).min(half).asin() * 2.0
    }
}

impl<L: Lane> PayloadModel<L> for Cable<L> {
    const DOF: usize = 3;

    #[inline(always)]
    fn accelerations<F: Frame<L>, const N: usize>(
        &self,
        body: &Body<L>,
        s: &State<L, N>,
        frame: &F,
        u1: L,
        w: &[L; 3],
        ds: &mut State<L, N>,
    ) -> Option<[L; 3]> {
        self.accelerations_of(body, s, frame, &self.line(s, frame), u1, w, ds)
    }

    #[inline(always)]
    fn outputs<F: Frame<L>, const N: usize>(
        &self,
        body: &Body<L>,
        s: &State<L, N>,
        frame: &F,
        _u1: L,
        w: &[L; 3],
    ) -> PayloadOutputs<L> {
        let line = self.line(s, frame);
        let accel = self.acceleration::<F, N>(body, s, &line, w);
        self.outputs_of::<F, N>(s, &line, accel)
    }

    /// The line and the payload's acceleration once for both (the same bits as apart).
    #[inline(always)]
    fn accelerations_and_outputs<F: Frame<L>, const N: usize>(
        &self,
        body: &Body<L>,
        s: &State<L, N>,
        frame: &F,
        u1: L,
        _u1_out: L,
        w: &[L; 3],
        ds: &mut State<L, N>,
    ) -> (Option<[L; 3]>, PayloadOutputs<L>) {
        let line = self.line(s, frame);
        let torque = self.accelerations_of(body, s, frame, &line, u1, w, ds);
        // `accelerations_of` stored the payload's acceleration in `ds`.
        let vxc = Ix::of::<L, F>().vxc;
        let accel = [ds[vxc], ds[vxc + 1], ds[vxc + 2]];
        (torque, self.outputs_of::<F, N>(s, &line, accel))
    }

    fn rest<F: Frame<L>, const N: usize>(&self, _body: &Body<L>, frame: &F, s: &mut State<L, N>) {
        // pc = a - l_eq e3, vc = v: hanging straight below the hook, moving with it.
        let Ix { xc, vx, vxc, .. } = Ix::of::<L, F>();
        let ez = frame.axes()[2];
        for i in 0..3 {
            s[xc + i] = (-self.offset).mul_add(ez[i], s[ix::X + i]);
            s[vxc + i] = s[vx + i];
        }
        s[xc + 2] = s[xc + 2] - self.hover_length;
    }
}

impl<L: Lane> Cable<L> {
    /// `PayloadModel::accelerations` with the line at `s` given.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn accelerations_of<F: Frame<L>, const N: usize>(
        &self,
        body: &Body<L>,
        s: &State<L, N>,
        frame: &F,
        line: &Line<L>,
        u1: L,
        w: &[L; 3],
        ds: &mut State<L, N>,
    ) -> Option<[L; 3]> {
        let pull = vec3(
            #[inline(always)]
            |i| line.tension * line.u[i],
        );
        let Ix { vx, vxc, .. } = Ix::of::<L, F>();
        let axes = &frame.axes();
        let fd = frame.drag(body, &[s[vx], s[vx + 1], s[vx + 2]], w);
        let thrust = &axes[2];
        for i in 0..3 {
            ds[vx + i] = thrust[i].mul_add(u1, pull[i] + fd[i]) * body.inv_m;
        }
        ds[vx + 2] = ds[vx + 2] - body.g;
        let ac = self.acceleration::<F, N>(body, s, line, w);
        ds[vxc..vxc + 3].copy_from_slice(&ac);
        // hb x f with hb = (0, 0, -h) and f = R^T (T u) = (ex . Tu, ey . Tu, ez . Tu).
        let h = self.offset;
        let (fx, fy) = (dot(&axes[0], &pull), dot(&axes[1], &pull));
        Some([h * fy, -(h * fx), L::splat(0.0)])
    }

    /// `PayloadModel::outputs` with the line at `s` and the payload's acceleration given.
    #[inline(always)]
    fn outputs_of<F: Frame<L>, const N: usize>(
        &self,
        s: &State<L, N>,
        line: &Line<L>,
        accel: [L; 3],
    ) -> PayloadOutputs<L> {
        let xc = Ix::of::<L, F>().xc;
        PayloadOutputs {
            e_o: (s[xc + 2] - line.hook[2]) + self.hover_length,
            accel,
            tension: line.tension,
            swing: Self::swing(line),
        }
    }
}

#[cfg(test)]
#[path = "cable_tests.rs"]
mod tests;
