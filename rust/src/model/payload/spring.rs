//! The paper's payload (docs/model.md section 1): a point mass on a vertical spring and damper
//! of zero rest length. It moves only vertically; laterally it travels with the quadrotor, so
//! the lateral mass is m + mc. One degree of freedom: `zc`, `vzc`.

use super::{AtState, Payload, PayloadModel, PayloadOutputs, PayloadView};
use crate::config::params::params;
use crate::lane::{gather, Lane};
use crate::model::body::{drag, Body, Frame};
use crate::model::layout::{Axis, Bound, Part, StateVar};
use crate::model::section::OwnsKeys;
use crate::model::ModelContext;
use crate::model::{ix, Layout, State};

params! {
    /// The spring's own keys in `[payload]`: none beyond the point mass's
    /// (`model::payload::Shared`).
    pub struct SpringParams {}
}

/// Spring payload parameters: `L = f64` for one vehicle, a lane type for one per lane.
#[derive(Clone, Copy, Debug)]
pub struct Spring<L = f64> {
    /// kg.
    pub mc: L,
    /// N/m and N s/m.
    pub kc: L,
    pub cc: L,
    /// 1/2 rho CdA of the payload (vertical).
    pub drag_payload: L,
    /// m, the static stretch at hover d0 = mc g / kc.
    pub hover_offset: L,
    /// 1 / (m + mc) and 1 / mc, computed once.
    inv_m_lateral: L,
    inv_mc: L,
}

const LAYOUT: Layout = Layout::new(1, 0);
const ZC: usize = ix::PAYLOAD;
const VX: usize = LAYOUT.vel();
const VY: usize = VX + 1;
const VZ: usize = VX + 2;
const VZC: usize = LAYOUT.payload_vel();

impl OwnsKeys for Spring {
    type Params = SpringParams;
}

impl Payload for Spring {
    type At<L: Lane> = Spring<L>;
    const POSITIONS: &'static [StateVar] = &[StateVar::new(
        "zc",
        Axis::Z,
        Some(Bound::Distance),
        Part::Payload,
    )];
    const VELOCITIES: &'static [StateVar] = &[StateVar::new(
        "vzc",
        Axis::Z,
        Some(Bound::Speed),
        Part::Payload,
    )];

    fn new(_: &SpringParams, cfg: &ModelContext) -> Self {
        let (m, mc) = (cfg.vehicle.mass, cfg.payload.mass);
        let kc = cfg.stiffness();
        Self {
            mc,
            kc,
            cc: cfg.payload.damping,
            drag_payload: 0.5 * cfg.gust.air_density * cfg.payload.drag_area,
            hover_offset: mc * cfg.environment.gravity / kc,
            inv_m_lateral: 1.0 / (m + mc),
            inv_mc: 1.0 / mc,
        }
    }

    fn hover_drop(&self) -> f64 {
        self.hover_offset
    }

    fn gather<L: Lane>(each: &[&Self]) -> Spring<L> {
        gather!(|l| each[l] => Spring {
            mc, kc, cc, drag_payload, hover_offset, inv_m_lateral, inv_mc,
        })
    }
}

impl<L: Lane> Spring<L> {
    /// Spring and damper force Fs = kc (z - zc) + cc (vz - vzc) (N, pulls the payload up).
    #[inline(always)]
    fn force<const N: usize>(&self, s: &State<L, N>) -> L {
        (s[ix::Z] - s[ZC]).mul_add(self.kc, (s[VZ] - s[VZC]) * self.cc)
    }

    /// The lateral accelerations of quadrotor and payload together (mass m + mc).
    #[inline(always)]
    fn lateral<F: Frame<L>, const N: usize>(&self, at: &AtState<'_, L, F, N>) -> [L; 2] {
        const { assert!(F::ATT == 3, "the spring flies on the paper's body only") };
        let AtState {
            body,
            s,
            frame,
            u1,
            w,
        } = *at;
        let fdx = drag(body.drag_lateral, s[VX], w[0]);
        let fdy = drag(body.drag_lateral, s[VY], w[1]);
        // Products-plus-sums as `mul_add`: the same bits as `a * b + c` except in the fused
        // mode (`Lane::mul_add`); `a - b c` is `(-b) c + a`, exactly. The thrust's direction
        // R e3 (`Frame::axes`).
        let thrust = frame.axes()[2];
        [
            thrust[0].mul_add(u1, fdx) * self.inv_m_lateral,
            thrust[1].mul_add(u1, fdy) * self.inv_m_lateral,
        ]
    }

    /// mc azc = -mc g + Fs + Fdzc: the payload's vertical inertial acceleration.
    #[inline(always)]
    fn acceleration<const N: usize>(&self, body: &Body<L>, s: &State<L, N>, spring: L, wz: L) -> L {
        let fdzc = drag(self.drag_payload, s[VZC], wz);
        (spring + fdzc) * self.inv_mc - body.g
    }
}

impl<L: Lane> PayloadModel<L> for Spring<L> {
    const DOF: usize = 1;

    #[inline(always)]
    fn accelerations<F: Frame<L>, const N: usize>(
        &self,
        at: &AtState<'_, L, F, N>,
        ds: &mut State<L, N>,
    ) -> Option<[L; 3]> {
        let AtState {
            body,
            s,
            frame,
            u1,
            w,
        } = *at;
        let fdz = body.vertical_drag(s[VZ], w[2]);
        let spring = self.force(s);
        [ds[VX], ds[VY]] = self.lateral(at);
        let az = frame.axes()[2][2].mul_add(u1, -spring) + fdz;
        ds[VZ] = az * body.inv_m - body.g;
        ds[VZC] = self.acceleration(body, s, spring, w[2]);
        None
    }

    #[inline(always)]
    fn outputs<F: Frame<L>, const N: usize>(&self, at: &AtState<'_, L, F, N>) -> PayloadOutputs<L> {
        let AtState { body, s, w, .. } = *at;
        let spring = self.force(s);
        // The payload moves laterally with the quadrotor (docs/model.md section 12).
        let [ax, ay] = self.lateral(at);
        PayloadOutputs {
            e_o: s[ZC] - s[ix::Z] + self.hover_offset,
            accel: [ax, ay, self.acceleration(body, s, spring, w[2])],
            tension: spring,
            swing: L::splat(0.0),
        }
    }

    /// The parcel below the centre of gravity, where the spring hangs from: vertical only.
    #[inline(always)]
    fn view<F: Frame<L>, const N: usize>(&self, s: &State<L, N>, _frame: &F) -> PayloadView<L> {
        const { assert!(F::ATT == 3, "the spring flies on the paper's body only") };
        let zero = L::splat(0.0);
        PayloadView {
            pos: [zero, zero, s[ZC] - s[ix::Z]],
            vel: [zero, zero, s[VZC] - s[VZ]],
        }
    }

    fn rest<F: Frame<L>, const N: usize>(&self, _body: &Body<L>, _frame: &F, s: &mut State<L, N>) {
        s[ZC] = s[ix::Z] - self.hover_offset;
    }
}
