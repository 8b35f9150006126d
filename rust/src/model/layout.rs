//! The state vector's layout, defined once: which state sits where, its name, the axis it moves
//! along (stability's mode labels) and the runaway bound that ends a flight when it is exceeded
//! (the divergence checks). Trace columns, stability outputs, `linearize`'s names and the
//! divergence checks are all derived from `Layout::vars`.

use super::ix;

/// The runaway bound a state is held to (`divergence.*`): a flight whose state exceeds it ends
/// with the matching `ExitStatus`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Bound {
    /// |position| <= `divergence.max_distance`.
    Distance,
    /// |roll|, |pitch| <= `divergence.max_tilt`.
    Tilt,
    /// |velocity| <= `divergence.max_speed`.
    Speed,
    /// |body rate| <= `divergence.max_rate`.
    Rate,
}

/// The direction a state moves the vehicle in, for naming a linear mode by the states that
/// carry it (`stability::describe`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Axis {
    X,
    Y,
    Z,
    Roll,
    Pitch,
    Yaw,
    /// Not a motion of the airframe or the load (e.g. a rotor speed).
    Other,
}

impl Axis {
    /// Lateral motion: what a horizontal disturbance drives.
    pub fn lateral(self) -> bool {
        matches!(self, Axis::X | Axis::Y | Axis::Roll | Axis::Pitch)
    }
}

/// Which body a state belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Part {
    Vehicle,
    Payload,
    Actuator,
}

/// One state: its name (the trace column), what it measures, and its runaway bound.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StateVar {
    pub name: &'static str,
    pub axis: Axis,
    pub bound: Option<Bound>,
    pub part: Part,
}

impl StateVar {
    pub const fn new(name: &'static str, axis: Axis, bound: Option<Bound>, part: Part) -> Self {
        Self {
            name,
            axis,
            bound,
            part,
        }
    }
}

const fn vehicle(name: &'static str, axis: Axis, bound: Option<Bound>) -> StateVar {
    StateVar::new(name, axis, bound, Part::Vehicle)
}

/// The quadrotor's positions and angles.
pub const VEHICLE_POSITIONS: [StateVar; 6] = [
    vehicle("x", Axis::X, Some(Bound::Distance)),
    vehicle("y", Axis::Y, Some(Bound::Distance)),
    vehicle("z", Axis::Z, Some(Bound::Distance)),
    vehicle("phi", Axis::Roll, Some(Bound::Tilt)),
    vehicle("theta", Axis::Pitch, Some(Bound::Tilt)),
    // Yaw is free: a turn is no runaway.
    vehicle("psi", Axis::Yaw, None),
];

/// The quadrotor's velocities and Euler-angle rates.
pub const VEHICLE_VELOCITIES: [StateVar; 6] = velocities(["p", "q", "r"]);

/// The rigid body's positions and attitude quaternion (`model::body::Rigid`).
pub const RIGID_POSITIONS: [StateVar; 7] = [
    vehicle("x", Axis::X, Some(Bound::Distance)),
    vehicle("y", Axis::Y, Some(Bound::Distance)),
    vehicle("z", Axis::Z, Some(Bound::Distance)),
    // The quaternion's components are bounded by 1: the tilt is checked on the derived roll
    // and pitch (`BodyKind::tilt`).
    vehicle("qw", Axis::Other, None),
    vehicle("qx", Axis::Roll, None),
    vehicle("qy", Axis::Pitch, None),
    vehicle("qz", Axis::Yaw, None),
];

/// The rigid body's velocities and true body rates.
pub const RIGID_VELOCITIES: [StateVar; 6] = velocities(["wx", "wy", "wz"]);

/// The vehicle's velocities (bounded by the speed), then its roll, pitch and yaw rates named
/// `rates` (bounded by the rate): every body's, whatever its attitude.
const fn velocities(rates: [&'static str; 3]) -> [StateVar; 6] {
    [
        vehicle("vx", Axis::X, Some(Bound::Speed)),
        vehicle("vy", Axis::Y, Some(Bound::Speed)),
        vehicle("vz", Axis::Z, Some(Bound::Speed)),
        vehicle(rates[0], Axis::Roll, Some(Bound::Rate)),
        vehicle(rates[1], Axis::Pitch, Some(Bound::Rate)),
        vehicle(rates[2], Axis::Yaw, Some(Bound::Rate)),
    ]
}

/// Where each part's states sit: `[vehicle positions and attitude (3 + attitude), payload
/// positions (dof), vehicle velocities and rates (6), payload velocities (dof), actuator
/// states]`. The paper's body has 3 attitude states (Euler angles), the rigid body 4 (a
/// quaternion).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Layout {
    /// The attitude's states (3 Euler angles, or 4 quaternion components).
    pub attitude: usize,
    /// The payload's degrees of freedom (1 for the vertical spring, 3 for the cable).
    pub payload_dof: usize,
    /// The actuator's states (0 ideal, 4 rotors).
    pub actuator_states: usize,
}

impl Layout {
    /// The paper's body's layout (Euler angles).
    pub const fn new(payload_dof: usize, actuator_states: usize) -> Self {
        Self::with_attitude(3, payload_dof, actuator_states)
    }

    /// A body whose attitude takes `attitude` states.
    pub const fn with_attitude(
        attitude: usize,
        payload_dof: usize,
        actuator_states: usize,
    ) -> Self {
        Self {
            attitude,
            payload_dof,
            actuator_states,
        }
    }

    /// The vehicle's positions and attitude states.
    const fn poses(self) -> usize {
        3 + self.attitude
    }

    /// Number of states.
    pub const fn len(self) -> usize {
        self.poses() + 6 + 2 * self.payload_dof + self.actuator_states
    }

    pub const fn is_empty(self) -> bool {
        false
    }

    /// Index of the attitude's first state (phi, or qw).
    pub const fn att(self) -> usize {
        ix::PHI
    }

    /// Index of the payload's first position.
    pub const fn payload(self) -> usize {
        self.poses()
    }

    /// Index of vx (then vy, vz, and the three rates).
    pub const fn vel(self) -> usize {
        self.poses() + self.payload_dof
    }

    /// Index of the first rate (p or wx).
    pub const fn rate(self) -> usize {
        self.vel() + 3
    }

    /// Index of the payload's first velocity.
    pub const fn payload_vel(self) -> usize {
        self.poses() + 6 + self.payload_dof
    }

    /// Index of the actuator's first state.
    pub const fn actuator(self) -> usize {
        self.poses() + 6 + 2 * self.payload_dof
    }

    /// Every state in order, from the body's, the payload's and the actuator's own lists.
    pub fn vars(
        self,
        body: (&[StateVar], &[StateVar]),
        payload_positions: &[StateVar],
        payload_velocities: &[StateVar],
        actuator: &[StateVar],
    ) -> Vec<StateVar> {
        assert_eq!(body.0.len(), self.poses());
        assert_eq!(body.1.len(), 6);
        assert_eq!(payload_positions.len(), self.payload_dof);
        assert_eq!(payload_velocities.len(), self.payload_dof);
        assert_eq!(actuator.len(), self.actuator_states);
        let mut out = Vec::with_capacity(self.len());
        out.extend_from_slice(body.0);
        out.extend_from_slice(payload_positions);
        out.extend_from_slice(body.1);
        out.extend_from_slice(payload_velocities);
        out.extend_from_slice(actuator);
        out
    }
}
