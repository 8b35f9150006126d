//! Where the rotors sit (`RotorLayout`), their allocation matrix and its inverse (docs/model.md
//! section 8): geometry only, for the rotors' checks (`params`: the inverse must exist) and
//! their flight.

use crate::config::params::not_numbers;
use nalgebra::Matrix4;
use serde::{Deserialize, Serialize};

/// Where the four rotors sit (`actuator.layout`): rotor i at arm angle a_i from body x.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RotorLayout {
    /// a = 45, 135, 225, 315 degrees.
    #[default]
    X,
    /// a = 0, 90, 180, 270 degrees.
    Plus,
}

impl RotorLayout {
    /// The arm angles a_1..a_4 (rad).
    pub fn angles(self) -> [f64; 4] {
        let first = match self {
            RotorLayout::X => 45.0,
            RotorLayout::Plus => 0.0,
        };
        [0.0, 90.0, 180.0, 270.0].map(|a: f64| (first + a).to_radians())
    }
}

not_numbers!(RotorLayout);

/// Spin directions s_i: rotor i's yaw reaction torque is s_i cq T_i.
pub const SPIN: [f64; 4] = [1.0, -1.0, 1.0, -1.0];

/// (cos a_i, sin a_i) of the four arms, exact (no rounding of 90-degree multiples).
pub fn arm_directions(layout: RotorLayout) -> [[f64; 2]; 4] {
    match layout {
        RotorLayout::Plus => [[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]],
        RotorLayout::X => {
            let h = std::f64::consts::FRAC_1_SQRT_2;
            [[h, h], [-h, h], [-h, -h], [h, -h]]
        }
    }
}

/// The allocation matrix M: row 0 is U1, rows 1-3 the torques about body x, y, z; column i is
/// rotor i. `arm` is l (m), `torque_ratio` cq (m).
pub fn allocation(layout: RotorLayout, arm: f64, torque_ratio: f64) -> [[f64; 4]; 4] {
    let d = arm_directions(layout);
    [
        [1.0; 4],
        [0, 1, 2, 3].map(|i| arm * d[i][1]),
        [0, 1, 2, 3].map(|i| -arm * d[i][0]),
        SPIN.map(|s| torque_ratio * s),
    ]
}

/// M^-1 (row i: rotor i's thrust per unit of U1, tau_phi, tau_theta, tau_psi), or None if M is
/// singular (l or cq zero: refused by `Config::validate`).
pub fn allocation_inverse(m: &[[f64; 4]; 4]) -> Option<[[f64; 4]; 4]> {
    let inv = Matrix4::from_fn(|i, j| m[i][j]).try_inverse()?;
    Some(std::array::from_fn(|i| {
        std::array::from_fn(|j| inv[(i, j)])
    }))
}
