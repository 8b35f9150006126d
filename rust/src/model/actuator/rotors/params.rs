//! The rotors' own keys in `[actuator]` (docs/model.md section 8, "Rotors"): their layout,
//! constants, limits, faults and battery sag, the defaults and the checks (the rotors fly in
//! `super`).

use super::allocation::{self, RotorLayout};
use crate::config::params::{self, params, Params};
use crate::config::{non_negative, ConfigError};
use crate::model::ModelContext;

params! {
    /// The rotors' keys in `[actuator]` (docs/model.md section 8 and "Rotors"): flown only when
    /// `model = "rotors"`, but checked always (one set of rules), so that a rotor scenario
    /// flies on the ideal actuators by `actuator.model` alone.
    pub struct RotorParams {
        #[serde(default)]
        layout: RotorLayout => "-", "Rotor layout";
        /// N s^2/rad^2, kf in T = kf w^2.
        #[serde(default = "default_thrust_coefficient")]
        thrust_coefficient: f64 => "N s^2/rad^2", "Rotor thrust coefficient", positive;
        /// m, cq: a rotor's yaw reaction torque per newton of its thrust.
        #[serde(default = "default_torque_ratio")]
        torque_ratio: f64 => "m", "Rotor yaw torque per thrust", positive;
        /// s, tau_m of the rotor speed lag dw/dt = (w_cmd - w) / tau_m.
        #[serde(default = "default_time_constant")]
        time_constant: f64 => "s", "Rotor speed time constant", positive;
        /// N per rotor, the commanded thrust's lower and upper clamps.
        #[serde(default)]
        thrust_min: f64 => "N", "Least rotor thrust", non_negative;
        #[serde(default = "default_rotor_thrust_max")]
        thrust_max: f64 => "N", "Largest rotor thrust", finite;
        /// Rotors that give a fraction of their commanded thrust from a time on (rotors only).
        #[serde(default, skip_serializing_if = "Vec::is_empty")]
        faults: Vec<RotorFault> => "-", "Rotor faults";
        /// The fraction of `thrust_max` lost by the end of the flight, linearly (rotors only).
        #[serde(default, skip_serializing_if = "is_zero")]
        battery_sag: f64 => "-", "Fraction of the rotor thrust limit lost by the end (battery sag)";
        /// The rotor's H-force -w diag(k_d, k_d, k_z) v_i (RotorPy's k_d, k_d, k_z; rigid body).
        #[serde(default, skip_serializing_if = "is_zero3")]
        rotor_drag: [f64; 3] => "N/(rad/s m/s)", "Rotor drag (H-force) coefficients (k_d, k_d, k_z)", non_negative;
        /// The blade-flapping moment -k_flap w (v_i x e3) (RotorPy's k_flap; rigid body).
        #[serde(default, skip_serializing_if = "is_zero")]
        flapping: f64 => "N m/(rad/s m/s)", "Rotor blade-flapping moment coefficient", non_negative;
        /// Translational lift k_h (v_ix^2 + v_iy^2) per rotor (RotorPy's k_h; rigid body).
        #[serde(default, skip_serializing_if = "is_zero")]
        translational_lift: f64 => "N/(m/s)^2", "Rotor translational lift coefficient", non_negative;
    }
}

params! {
    /// One `[[actuator.faults]]` entry: rotor `rotor` gives `thrust_fraction` of its commanded
    /// (clamped) thrust from `start` on (0: stuck off, or its propeller lost); flown by
    /// `model::actuator::rotors`. Declared here, with `[actuator]`, so that `config` names no
    /// `model` (the engine's modules form no cycle).
    pub struct RotorFault {
        /// Which rotor, 1 to 4 in the layout's order (docs/model.md "Rotors"); a key, not a
        /// number a dispersion draws.
        rotor: u32 => "-", "Failed rotor (1 to 4)";
        start: f64 => "s", "Rotor fault start";
        thrust_fraction: f64 => "-", "Thrust fraction the failed rotor gives";
    }
}

fn is_zero(x: &f64) -> bool {
    *x == 0.0
}

fn is_zero3(x: &[f64; 3]) -> bool {
    *x == [0.0; 3]
}

impl RotorParams {
    /// The rotors' keys under `prefix` (`"actuator"`) with a unit and a label (dotted, indices
    /// dropped), their faults' (`[[actuator.faults]]`) among them.
    pub fn keys(prefix: &str) -> Vec<(String, params::Key)> {
        let mut keys = Self::keys_under(prefix);
        keys.extend(RotorFault::keys_under(&format!("{prefix}.faults")));
        keys
    }
}

impl Default for RotorParams {
    fn default() -> Self {
        Self {
            layout: RotorLayout::default(),
            thrust_coefficient: default_thrust_coefficient(),
            torque_ratio: default_torque_ratio(),
            time_constant: default_time_constant(),
            thrust_min: 0.0,
            thrust_max: default_rotor_thrust_max(),
            faults: Vec::new(),
            battery_sag: 0.0,
            rotor_drag: [0.0; 3],
            flapping: 0.0,
            translational_lift: 0.0,
        }
    }
}

/// N s^2/rad^2: a 10-inch multirotor propeller (RotorS and PX4's x500 `motorConstant`;
/// docs/model.md "Rotors").
pub fn default_thrust_coefficient() -> f64 {
    8.54858e-6
}

/// m: RotorS and PX4's x500 `momentConstant` (docs/model.md "Rotors").
pub fn default_torque_ratio() -> f64 {
    0.016
}

/// s: a 2 kg class motor with a 10-inch propeller (docs/model.md "Rotors").
pub fn default_time_constant() -> f64 {
    0.03
}

/// N per rotor: thrust-to-weight about 2 for the paper's 2.42 kg loaded vehicle
/// (docs/model.md "Rotors").
pub fn default_rotor_thrust_max() -> f64 {
    12.0
}

impl RotorParams {
    /// The rotor aerodynamic coefficients (each >= 0: their declared bound) nonzero only on
    /// the rigid body (they need its body rates and body-axis airspeed: docs/model.md,
    /// "Bodies").
    fn validate_aero(&self, cfg: &ModelContext) -> Result<(), ConfigError> {
        let a = self;
        if cfg.vehicle.body == crate::model::BodyModel::Paper {
            let given = [
                ("actuator.rotor_drag", a.rotor_drag != [0.0; 3]),
                ("actuator.flapping", a.flapping != 0.0),
                ("actuator.translational_lift", a.translational_lift != 0.0),
            ];
            if let Some((key, _)) = given.into_iter().find(|(_, set)| *set) {
                return Err(ConfigError::new(
                    key,
                    format!(
                        "{key} applies to vehicle.body = \"rigid\" only (rotor aerodynamics need \
                         the true body rates and body-axis airspeed)"
                    ),
                ));
            }
        }
        Ok(())
    }

    /// Every rotor key in range always; whether the rotors can hold this vehicle in hover and
    /// the lag can be integrated at this step only when they fly (`flown`).
    pub fn validate(&self, flown: bool, cfg: &ModelContext) -> Result<(), ConfigError> {
        let a = self;
        a.check_bounds("actuator")?;
        if a.thrust_max <= a.thrust_min {
            return Err(ConfigError::new(
                "actuator.thrust_max",
                format!(
                    "actuator.thrust_max must exceed actuator.thrust_min ({:?} N), got {:?}",
                    a.thrust_min, a.thrust_max
                ),
            ));
        }
        self.validate_faults(flown, cfg)?;
        self.validate_aero(cfg)?;
        if !flown {
            return Ok(());
        }
        let l = cfg.vehicle.arm_length;
        if l <= 0.0 {
            return Err(ConfigError::new(
                "vehicle.arm_length",
                format!(
                    "vehicle.arm_length must be > 0 with actuator.model = \"rotors\" (the rotors' \
                     roll and pitch arms), got {l:?}"
                ),
            ));
        }
        // M^-1 must exist and be finite, and M M^-1 must be the identity: a huge arm or a
        // subnormal torque ratio overflows or underflows the inverse (NaN thrusts otherwise).
        let m = allocation::allocation(a.layout, l, a.torque_ratio);
        let inverse = allocation::allocation_inverse(&m)
            .filter(|inv| inv.iter().flatten().all(|x| x.is_finite()))
            .filter(|inv| {
                (0..4).all(|i| {
                    (0..4).all(|j| {
                        let mij: f64 = (0..4).map(|k| m[i][k] * inv[k][j]).sum();
                        (mij - if i == j { 1.0 } else { 0.0 }).abs() < 1e-9
                    })
                })
            });
        if inverse.is_none() {
            let (key, x) = if (1e-6..=1e3).contains(&l) {
                ("actuator.torque_ratio", a.torque_ratio)
            } else {
                ("vehicle.arm_length", l)
            };
            return Err(ConfigError::new(
                key,
                format!(
                    "{key} makes the rotors' allocation (vehicle.arm_length = {l:?} m, \
                     actuator.torque_ratio = {:?} m) impossible to invert in floating point, \
                     got {x:?}",
                    a.torque_ratio
                ),
            ));
        }
        let dt = cfg.integrator.dt;
        if a.time_constant < dt {
            return Err(ConfigError::new(
                "actuator.time_constant",
                format!(
                    "actuator.time_constant must be at least integrator.dt ({dt:?} s): RK4 on \
                     the rotor lag is unstable past dt / tau ~ 2.8; got {:?}",
                    a.time_constant
                ),
            ));
        }
        let weight = (cfg.vehicle.mass + cfg.payload.mass) * cfg.environment.gravity;
        if 4.0 * a.thrust_max < weight {
            return Err(ConfigError::new(
                "actuator.thrust_max",
                format!(
                    "actuator.thrust_max is too small to hover: 4 x {:?} N is below the weight \
                     (vehicle.mass + payload.mass) x environment.gravity = {weight:?} N",
                    a.thrust_max
                ),
            ));
        }
        if a.thrust_min > weight / 4.0 {
            return Err(ConfigError::new(
                "actuator.thrust_min",
                format!(
                    "actuator.thrust_min is too large to hover: {:?} N per rotor exceeds the \
                     hover thrust per rotor (vehicle.mass + payload.mass) x environment.gravity \
                     / 4 = {:?} N",
                    a.thrust_min,
                    weight / 4.0
                ),
            ));
        }
        self.validate_fault_hover(cfg, weight)
    }

    /// `actuator.faults` and `actuator.battery_sag`: each value in range, at most one fault a
    /// rotor, and none of them without rotors (the ideal actuators have no rotor to fail and
    /// no thrust limit to sag).
    fn validate_faults(&self, flown: bool, cfg: &ModelContext) -> Result<(), ConfigError> {
        let a = self;
        let sag = a.battery_sag;
        if !(sag.is_finite() && (0.0..1.0).contains(&sag)) {
            return Err(ConfigError::new(
                "actuator.battery_sag",
                format!(
                    "actuator.battery_sag must be in [0, 1) (the fraction of actuator.thrust_max \
                     lost by the end of the flight), got {sag:?}"
                ),
            ));
        }
        for (i, f) in a.faults.iter().enumerate() {
            let key = format!("actuator.faults[{i}]");
            if !(1..=4).contains(&f.rotor) {
                return Err(ConfigError::new(
                    format!("{key}.rotor"),
                    format!("{key}.rotor must be 1, 2, 3 or 4, got {}", f.rotor),
                ));
            }
            if let Some(j) = a.faults[..i].iter().position(|g| g.rotor == f.rotor) {
                return Err(ConfigError::new(
                    format!("{key}.rotor"),
                    format!(
                        "{key}.rotor: rotor {} already fails in actuator.faults[{j}] (one fault a \
                         rotor), got it twice",
                        f.rotor
                    ),
                ));
            }
            non_negative(format_args!("{key}.start"), f.start)?;
            let x = f.thrust_fraction;
            if !(x.is_finite() && (0.0..=1.0).contains(&x)) {
                return Err(ConfigError::new(
                    format!("{key}.thrust_fraction"),
                    format!(
                        "{key}.thrust_fraction must be in [0, 1] (the fraction of its commanded \
                         thrust the rotor still gives), got {x:?}"
                    ),
                ));
            }
        }
        if !flown {
            let (key, what) = if !a.faults.is_empty() {
                ("actuator.faults", format!("{} fault(s)", a.faults.len()))
            } else if sag != 0.0 {
                ("actuator.battery_sag", format!("{sag:?}"))
            } else {
                return Ok(());
            };
            return Err(ConfigError::new(
                key,
                format!(
                    "{key} needs actuator.model = \"rotors\" (the ideal actuators have no rotor \
                     to fail and no thrust limit to sag), got {what} with actuator.model = \"{}\"",
                    cfg.actuator.model.name()
                ),
            ));
        }
        Ok(())
    }

    /// With rotors: the thrust the rotors can still give at the end of the flight (the least
    /// over the flight: the battery only sags and a fault only starts) must hold the weight.
    /// Else the scenario is refused, naming the fault (or the sag) that takes the total below
    /// the weight and the numbers, rather than flown to a slow fall that could end `ok`.
    fn validate_fault_hover(&self, cfg: &ModelContext, weight: f64) -> Result<(), ConfigError> {
        let a = self;
        if a.faults.is_empty() && a.battery_sag == 0.0 {
            return Ok(());
        }
        let end = cfg.integrator.duration;
        let top = a.thrust_max * (1.0 - a.battery_sag);
        let total = |upto: f64| -> f64 {
            (1..=4u32)
                .map(|r| {
                    let f = a
                        .faults
                        .iter()
                        .find(|f| f.rotor == r && f.start <= upto)
                        .map_or(1.0, |f| f.thrust_fraction);
                    f * top
                })
                .sum()
        };
        let weighs = format!(
            "the weight (vehicle.mass + payload.mass) x environment.gravity = {weight:?} N"
        );
        if 4.0 * top < weight {
            return Err(ConfigError::new(
                "actuator.battery_sag",
                format!(
                    "actuator.battery_sag = {:?} leaves the rotors too little thrust to hover by \
                     the end of the flight: 4 x {top:?} N is below {weighs}",
                    a.battery_sag
                ),
            ));
        }
        let mut order: Vec<usize> = (0..a.faults.len()).collect();
        order.sort_by(|&i, &j| a.faults[i].start.total_cmp(&a.faults[j].start));
        for i in order {
            let f = &a.faults[i];
            if f.start > end {
                break;
            }
            let left = total(f.start);
            if left < weight {
                let key = format!("actuator.faults[{i}].thrust_fraction");
                return Err(ConfigError::new(
                    &key,
                    format!(
                        "{key} = {:?} (rotor {} from {:?} s) leaves the rotors too little thrust \
                         to hover: {left:?} N at the end of the flight (actuator.thrust_max = \
                         {:?} N, actuator.battery_sag = {:?}) is below {weighs}",
                        f.thrust_fraction, f.rotor, f.start, a.thrust_max, a.battery_sag
                    ),
                ));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::ActuatorKind;
    use crate::scenario::tests::{paper, with};
    use crate::scenario::Config;

    /// The paper's scenario on rotors, `edit`ed, validated.
    fn on_rotors(edit: impl FnOnce(&mut Config)) -> Result<(), ConfigError> {
        let mut c = paper();
        c.actuator.model = ActuatorKind::Rotors;
        edit(&mut c);
        c.validate()
    }

    #[test]
    fn faults_and_sag_are_checked_naming_their_key() {
        let rotors = |edit: &dyn Fn(&mut RotorParams)| on_rotors(|c| edit(&mut c.actuator.rotors));
        fn f(rotor: u32, start: f64, thrust_fraction: f64) -> RotorFault {
            RotorFault {
                rotor,
                start,
                thrust_fraction,
            }
        }
        rotors(&|a| {
            a.faults = vec![f(1, 10.0, 0.8), f(4, 0.0, 0.5)];
            a.battery_sag = 0.2;
        })
        .expect("weak motors and a sagging battery that still hover");
        for (edit, key, says) in [
            (
                (|a: &mut RotorParams| a.faults = vec![f(5, 1.0, 0.5)]) as fn(&mut _),
                "actuator.faults[0].rotor",
                "must be 1, 2, 3 or 4, got 5",
            ),
            (
                |a| a.faults = vec![f(2, 1.0, 0.5), f(2, 3.0, 0.5)],
                "actuator.faults[1].rotor",
                "rotor 2 already fails in actuator.faults[0]",
            ),
            (
                |a| a.faults = vec![f(2, -1.0, 0.5)],
                "actuator.faults[0].start",
                "got -1.0",
            ),
            (
                |a| a.faults = vec![f(2, 1.0, 1.5)],
                "actuator.faults[0].thrust_fraction",
                "must be in [0, 1]",
            ),
            (|a| a.battery_sag = 1.0, "actuator.battery_sag", "[0, 1)"),
            (|a| a.battery_sag = f64::NAN, "actuator.battery_sag", "NaN"),
        ] {
            let e = rotors(&|a| edit(a)).unwrap_err();
            assert_eq!(e.key, key, "{e}");
            assert!(e.message.contains(says) && !e.message.contains('\n'), "{e}");
        }
        // Too little thrust left to hold the weight (26.5 N; 4 x 12 N healthy): refused, with
        // the numbers, naming the fault that takes the total below it.
        let e = rotors(&|a| {
            a.faults = vec![f(1, 5.0, 0.5), f(2, 20.0, 0.1), f(3, 30.0, 0.1)];
        })
        .unwrap_err();
        assert_eq!(e.key, "actuator.faults[2].thrust_fraction", "{e}");
        assert!(e.message.contains("too little thrust to hover"), "{e}");
        assert!(
            e.message.contains("20.4") && e.message.contains("23.74"),
            "{e}"
        );
        // A fault after the end of the flight never happens.
        rotors(&|a| a.faults = vec![f(1, 99.0, 0.0), f(2, 99.0, 0.0), f(3, 99.0, 0.0)])
            .expect("faults after the flight");
        let e = rotors(&|a| a.battery_sag = 0.6).unwrap_err();
        assert_eq!(e.key, "actuator.battery_sag");
        assert!(
            e.message
                .contains("to hover by the end of the flight: 4 x 4.8"),
            "{e}"
        );
        // The ideal actuators have no rotors to fail.
        let mut c = paper();
        c.actuator.rotors.faults = vec![f(1, 1.0, 0.5)];
        let e = c.validate().unwrap_err();
        assert_eq!(e.key, "actuator.faults");
        assert!(
            e.message.contains("needs actuator.model = \"rotors\""),
            "{e}"
        );
        let mut c = paper();
        c.actuator.rotors.battery_sag = 0.1;
        assert_eq!(c.validate().unwrap_err().key, "actuator.battery_sag");
    }

    #[test]
    fn rotor_values_name_their_keys() {
        let bad = |edit: fn(&mut Config)| on_rotors(edit).unwrap_err();
        let mut c = paper();
        c.actuator.model = ActuatorKind::Rotors;
        c.validate()
            .expect("the paper vehicle on its default rotors");
        // 4 x 5 N = 20 N < (2.2 + 0.22) kg x 9.81 m/s^2 = 23.74 N.
        let e = bad(|c| c.actuator.rotors.thrust_max = 5.0);
        assert_eq!(e.key, "actuator.thrust_max");
        assert!(
            e.message.contains("too small to hover")
                && e.message.contains("vehicle.mass + payload.mass"),
            "{e}"
        );
        // Exactly the weight on four rotors still hovers; a heavier payload does not.
        c.actuator.rotors.thrust_max = (2.2 + 0.22) * 9.81 / 4.0;
        c.validate().expect("thrust_max = hover holds hover");
        let e = bad(|c| c.payload.mass = 3.0);
        assert_eq!(e.key, "actuator.thrust_max");
        let e = bad(|c| c.actuator.rotors.thrust_min = 6.0);
        assert_eq!(e.key, "actuator.thrust_min");
        assert!(e.message.contains("too large to hover"), "{e}");
        let e = bad(|c| c.actuator.rotors.time_constant = 1e-4);
        assert_eq!(e.key, "actuator.time_constant");
        assert!(e.message.contains("integrator.dt"), "{e}");
        let e = bad(|c| c.vehicle.arm_length = 0.0);
        assert_eq!(e.key, "vehicle.arm_length");
        for (edit, key) in [
            (
                (|c: &mut Config| c.actuator.rotors.thrust_coefficient = 0.0) as fn(&mut Config),
                "actuator.thrust_coefficient",
            ),
            (
                |c| c.actuator.rotors.torque_ratio = -0.01,
                "actuator.torque_ratio",
            ),
            (
                |c| c.actuator.rotors.time_constant = f64::NAN,
                "actuator.time_constant",
            ),
            (
                |c| c.actuator.rotors.thrust_min = -1.0,
                "actuator.thrust_min",
            ),
            (
                |c| c.actuator.rotors.thrust_max = 0.0,
                "actuator.thrust_max",
            ),
        ] {
            assert_eq!(bad(edit).key, key);
            // Checked with ideal actuators too: one set of rules.
            let mut c = paper();
            edit(&mut c);
            assert_eq!(c.validate().unwrap_err().key, key);
        }
        // What only rotors need is not asked of ideal actuators.
        let mut c = paper();
        c.actuator.rotors.thrust_max = 1.0;
        c.actuator.rotors.time_constant = 1e-6;
        c.vehicle.arm_length = 0.0;
        c.validate().expect("ideal actuators fly no rotors");
        let e = with(|v| v["actuator"]["layout"] = "y".into()).unwrap_err();
        assert_eq!(e.key, "actuator.layout");
        let e = with(|v| v["actuator"]["model"] = "jets".into()).unwrap_err();
        assert_eq!(e.key, "actuator.model");
    }

    #[test]
    fn rotor_geometry_the_allocation_cannot_invert_is_refused() {
        let rotors = |edit: fn(&mut Config)| on_rotors(edit);
        for (edit, key) in [
            (
                (|c: &mut Config| c.vehicle.arm_length = 1e155) as fn(&mut Config),
                "vehicle.arm_length",
            ),
            (
                |c| c.actuator.rotors.torque_ratio = 5e-324,
                "actuator.torque_ratio",
            ),
            (
                |c| c.actuator.rotors.torque_ratio = 1e-310,
                "actuator.torque_ratio",
            ),
        ] {
            let e = rotors(edit).unwrap_err();
            assert_eq!(e.key, key, "{e}");
            assert!(e.message.contains("impossible to invert"), "{e}");
        }
        rotors(|c| c.vehicle.arm_length = 2.0).expect("a large but invertible vehicle");
    }
}
