//! `[vehicle]`: the quadrotor's airframe (mass, inertia, arm, drag, which body flies:
//! `BodyModel`) and its checks.

use super::params::{params, Params};
use super::ConfigError;

params! {
    pub struct Vehicle {
        /// kg, the quadrotor alone.
        mass: f64 => "kg", "Quadrotor mass", positive;
        /// kg m^2, nominal (what the controller believes): Ixx, Iyy, Izz.
        inertia: [f64; 3] => "kg m^2", "Quadrotor inertia, nominal (Ixx, Iyy, Izz)", positive;
        /// kg m^2, plant inertia minus nominal (the paper's Delta I).
        inertia_error: [f64; 3] => "kg m^2", "Inertia error, plant minus nominal (Ixx, Iyy, Izz)", finite;
        /// m, arm length (Table 1; the model applies torques directly, so it is informational).
        arm_length: f64 => "m", "Arm length", non_negative;
        /// m^2, Cd times projected area for vertical drag.
        drag_area: f64 => "m^2", "Quadrotor drag area", non_negative;
        /// m^2, Cd times projected area for horizontal drag of vehicle plus payload.
        lateral_drag_area: f64 => "m^2", "Lateral drag area of quadrotor and payload", non_negative;
        /// Which body flies: "paper" (Euler angles, drag per inertial axis; the default) or
        /// "rigid" (unit quaternion, true body rates, body-axis drag).
        #[serde(default, skip_serializing_if = "BodyModel::is_paper")]
        body: BodyModel => "-", "Body model";
        /// N/(m/s)^2, the rigid body's drag -|v_b| diag(c) v_b along its own axes (c_x, c_y,
        /// c_z); the paper's body uses the drag areas instead.
        #[serde(default, skip_serializing_if = "is_zero3")]
        drag_coefficients: [f64; 3] => "N/(m/s)^2", "Body-axis drag coefficients (x, y, z)", non_negative;
        /// The rotors' wake on a dropped parcel (docs/model.md, "The rotors' downwash"): a
        /// column of momentum theory's far wake below the vehicle (default on).
        #[serde(default = "downwash_on", skip_serializing_if = "is_on")]
        downwash: bool => "-", "Rotors' downwash on a dropped parcel";
        /// m, each of the four rotors' radius: their disk area for the downwash (default
        /// ROTOR_RADIUS, a 10-inch propeller's).
        #[serde(default = "default_rotor_radius", skip_serializing_if = "is_default_radius")]
        rotor_radius: f64 => "m", "Rotor radius (downwash)", positive;
    }
}

/// m, the rotor radius without `vehicle.rotor_radius`: a 10-inch (254 mm) propeller, the
/// x500's (PX4's `motorConstant`, the rotors' default thrust coefficient, is measured on it).
pub const ROTOR_RADIUS: f64 = 0.127;

fn downwash_on() -> bool {
    true
}

fn is_on(x: &bool) -> bool {
    *x
}

fn default_rotor_radius() -> f64 {
    ROTOR_RADIUS
}

fn is_default_radius(r: &f64) -> bool {
    *r == ROTOR_RADIUS
}

fn is_zero3(c: &[f64; 3]) -> bool {
    *c == [0.0; 3]
}

impl Vehicle {
    /// Check every value; the first problem found is returned with its key.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let v = self;
        v.check_bounds("vehicle")?;
        for (i, x) in v.inertia_error.iter().enumerate() {
            if v.inertia[i] + x <= 0.0 {
                let key = format!("vehicle.inertia_error[{i}]");
                return Err(ConfigError::new(
                    &key,
                    format!(
                        "{key} must leave a positive plant inertia (vehicle.inertia[{i}] + error > 0), got {x:?}"
                    ),
                ));
            }
        }
        if v.body == BodyModel::Paper && v.drag_coefficients != [0.0; 3] {
            return Err(ConfigError::new(
                "vehicle.drag_coefficients",
                format!(
                    "vehicle.drag_coefficients applies to vehicle.body = \"rigid\" only (the \
                     paper's body takes vehicle.drag_area and vehicle.lateral_drag_area), got {:?}",
                    v.drag_coefficients
                ),
            ));
        }
        Ok(())
    }
}

/// Which body flies (`vehicle.body`): the paper's (default) or the rigid body.
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "snake_case")]
pub enum BodyModel {
    /// Euler angles whose rates are used as body rates; drag per inertial axis (the paper's).
    #[default]
    Paper,
    /// A unit quaternion, true body rates, Euler's equations; drag in body axes.
    Rigid,
}

/// Every body, in the order the Python layer lists them (`_core.BODY_MODELS`).
pub const BODY_MODELS: &[BodyModel] = &[BodyModel::Paper, BodyModel::Rigid];

impl BodyModel {
    /// The public name.
    pub fn name(self) -> &'static str {
        match self {
            Self::Paper => "paper",
            Self::Rigid => "rigid",
        }
    }

    /// The default: skipped when a scenario is written out, so the paper's read as before.
    pub fn is_paper(&self) -> bool {
        *self == Self::Paper
    }
}

super::params::not_numbers!(BodyModel);
