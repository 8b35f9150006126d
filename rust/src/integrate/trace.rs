//! The trace: its columns (the layout's states, the common signals, the actuator's own) and
//! its rows, lane 0 of a flight every `every` steps.

use crate::lane::Lane;
use crate::model::{
    dispatch, Actuator, ActuatorKind, ActuatorModel, BodyKind, BodyModel, Inputs, Payload,
    PayloadKind, State, VehicleVisitor,
};
use crate::trajectory::Reference;

/// Trace columns after the states (whose names come from the layout), in order; the actuator's
/// own (`ActuatorModel::SIGNALS`) follow.
pub const SIGNAL_COLUMNS: [&str; 16] = [
    "x_ref",
    "y_ref",
    "z_ref",
    "psi_ref",
    "U1",
    "tau_phi",
    "tau_theta",
    "tau_psi",
    "wind_x",
    "wind_y",
    "wind_z",
    "e_o",
    "accel_c",
    "drag_z",
    "swing",
    "tension",
];

/// Most extra trace columns an actuator kind may have.
pub(super) const MAX_ACTUATOR_SIGNALS: usize = 8;

/// Every trace column after `t` of a vehicle with these kinds: its states, the body's derived
/// columns (`BodyKind::DERIVED`), `SIGNAL_COLUMNS`, then the actuator's own.
pub fn trace_columns(
    body: BodyModel,
    payload: PayloadKind,
    actuator: ActuatorKind,
) -> Vec<&'static str> {
    struct Columns;
    impl VehicleVisitor for Columns {
        type Output = Vec<&'static str>;
        fn visit<B: BodyKind, Pay: Payload, Act: Actuator, const N: usize>(self) -> Self::Output {
            let extra = <Act::At<f64> as ActuatorModel<f64>>::SIGNALS;
            assert!(extra.len() <= MAX_ACTUATOR_SIGNALS);
            let vars = crate::model::state_vars_of::<B, Pay, Act>();
            vars.iter()
                .map(|v| v.name)
                .chain(B::DERIVED.iter().copied())
                .chain(SIGNAL_COLUMNS)
                .chain(extra.iter().copied())
                .collect()
        }
    }
    dispatch(body, payload, actuator, Columns)
}

/// Rows of (t, trace columns...) every `every` steps, for lane 0 of a flight.
pub struct Trace {
    pub every: usize,
    /// Values per row (t included).
    pub width: usize,
    pub data: Vec<f64>,
    /// The navigation's record of the flight (with `navigation.mode = "ekf"`).
    pub navigation: Option<crate::navigation::NavigationRecord>,
}

impl Trace {
    /// A trace of a flight of `steps` steps with `columns` columns after `t`.
    pub fn new(every: usize, steps: usize, columns: usize) -> Self {
        let every = every.max(1);
        let width = 1 + columns;
        Self {
            every,
            width,
            data: Vec::with_capacity((steps / every + 1) * width),
            navigation: None,
        }
    }

    pub(super) fn push<L: Lane, const N: usize>(&mut self, row: &TraceRow<L, N>) {
        debug_assert_eq!(
            self.width,
            1 + N + row.derived.len() + SIGNAL_COLUMNS.len() + row.extra.len() + row.nav.len()
        );
        self.data.push(row.t);
        self.data.extend(row.s.iter().map(|x| x.lane(0)));
        self.data.extend(row.derived.iter().map(|x| x.lane(0)));
        let r = row.r;
        self.data
            .extend_from_slice(&[r.pos[0], r.pos[1], r.pos[2], r.psi, row.u.u1.lane(0)]);
        self.data
            .extend(row.u.tau.iter().chain(row.w.iter()).map(|x| x.lane(0)));
        for x in [row.e_o, row.accel_c, row.drag_z, row.swing, row.tension] {
            self.data.push(x.lane(0));
        }
        self.data.extend(row.extra.iter().map(|x| x.lane(0)));
        self.data.extend_from_slice(row.nav);
    }
}

/// One trace row: lane 0 of the flight at time `t` (columns as `trace_columns`).
pub(super) struct TraceRow<'a, L, const N: usize> {
    pub(super) t: f64,
    pub(super) s: &'a State<L, N>,
    /// The body's derived columns (`BodyKind::DERIVED`).
    pub(super) derived: &'a [L],
    pub(super) r: &'a Reference,
    /// The controller's command held over the step starting at `t`.
    pub(super) u: &'a Inputs<L>,
    /// The wind held over the step starting at `t`.
    pub(super) w: &'a [L; 3],
    pub(super) e_o: L,
    /// m/s^2, the magnitude of the payload's inertial acceleration.
    pub(super) accel_c: L,
    /// N, the vertical drag on the quadrotor the derivative uses at `s` in `w`.
    pub(super) drag_z: L,
    pub(super) swing: L,
    pub(super) tension: L,
    /// The actuator's own columns.
    pub(super) extra: &'a [L],
    /// The navigation's columns (`NAVIGATION_COLUMNS`; empty when the laws read the state).
    pub(super) nav: &'a [f64],
}
