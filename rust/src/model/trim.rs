//! The trim (`initial.trim = "wind"`, docs/model.md "The start: trimmed in the wind"): the
//! state a vehicle holds still in a steady wind, found by Newton's method on the plant's own
//! derivative, so it holds for any body, payload and actuator kind whose derivative the plant
//! evaluates. Unknowns: roll and pitch (yaw kept), the total thrust (no torque), the payload's
//! positions and the actuator's states; equations: no translational acceleration of the
//! quadrotor, none of the payload, no change of the actuator's states. The rotational
//! accelerations are left to the controller (a hook below the centre of gravity leaves a small
//! pitching moment that the attitude loop holds).

use super::{ActuatorModel, BodyKind, Inputs, PayloadModel, State, Tick, Vehicle};
use nalgebra::DVector;

/// Newton steps at most; a trim converges in 3 to 5 (the balance is nearly linear in the
/// unknowns).
const MAX_ITERATIONS: usize = 30;
/// Largest residual (m/s^2 and state units per s) accepted as balanced.
const TOLERANCE: f64 = 1e-10;
/// Largest trimmed roll or pitch (rad): beyond it there is no hover to speak of.
const MAX_TILT: f64 = 1.2;

impl<Pay: PayloadModel<f64>, Act: ActuatorModel<f64>, B: BodyKind> Vehicle<f64, Pay, Act, B> {
    /// A state at rest at `position` (velocities zero) in the steady wind `wind` (m/s,
    /// inertial): tilted into the wind, the payload hanging back at its steady line angle, the
    /// actuators at their steady states, with yaw `attitude[2]`. `rest_state` exactly when the
    /// wind is zero; an error (a sentence) when Newton's method finds no balance.
    pub fn trim_state<const N: usize>(
        &self,
        position: [f64; 3],
        attitude: [f64; 3],
        wind: [f64; 3],
    ) -> Result<State<f64, N>, String> {
        let rest: State<f64, N> = self.rest_state(position, attitude);
        if wind == [0.0; 3] {
            return Ok(rest);
        }
        let lay = Self::LAYOUT;
        let (pay, dof) = (lay.payload(), lay.payload_dof);
        let (act, states) = (lay.actuator(), lay.actuator_states);
        let n = 3 + dof + states;
        // The unknowns: roll, pitch, thrust, payload positions, actuator states.
        let state_of = |x: &DVector<f64>| -> (State<f64, N>, Inputs<f64>) {
            let mut s: State<f64, N> = self.rest_state(position, [x[0], x[1], attitude[2]]);
            for i in 0..dof {
                s[pay + i] = x[3 + i];
            }
            for i in 0..states {
                s[act + i] = x[3 + dof + i];
            }
            let u = Inputs {
                u1: x[2],
                tau: [0.0; 3],
            };
            (s, u)
        };
        let residual = |x: &DVector<f64>| -> DVector<f64> {
            let (s, u) = state_of(x);
            let cmd = self.actuator.command(&u, Tick::START);
            let ds = self.derivative(&s, &B::frame(&s), &cmd, &wind);
            let (v, pv) = (lay.vel(), lay.payload_vel());
            DVector::from_fn(n, |i, _| match i {
                0..=2 => ds[v + i],
                _ if i < 3 + dof => ds[pv + i - 3],
                _ => ds[act + i - 3 - dof],
            })
        };
        let mut x = DVector::from_fn(n, |i, _| match i {
            0 | 1 => attitude[i],
            2 => self.body.m * self.body.g,
            _ if i < 3 + dof => rest[pay + i - 3],
            _ => rest[act + i - 3 - dof],
        });
        for _ in 0..MAX_ITERATIONS {
            let r = residual(&x);
            if !r.iter().all(|v| v.is_finite()) {
                break;
            }
            if r.amax() < TOLERANCE {
                let (s, _) = state_of(&x);
                return Ok(s);
            }
            let jac = crate::differences::central(x.as_slice(), |x| {
                residual(&DVector::from_column_slice(x))
            });
            let Some(step) = jac.lu().solve(&r) else {
                break;
            };
            x -= step;
            if x[0].abs() > MAX_TILT || x[1].abs() > MAX_TILT {
                break;
            }
        }
        Err(format!(
            "no steady hover found in the start's wind ({:.3}, {:.3}, {:.3}) m/s",
            wind[0], wind[1], wind[2]
        ))
    }
}

#[cfg(test)]
mod tests {
    use crate::model::actuator::{ActuatorModel, Rotors};
    use crate::model::payload::Cable;
    use crate::model::{AnyVehicle, Inputs, State, Tick, Trig, Vehicle};
    use crate::scenario::Config;

    const NX: usize = 24;

    /// The delivery preset on the paper's body.
    fn delivery() -> Config {
        let mut v = crate::scenario::tests::delivery_value();
        // On the paper's body (the checks below write its drag law): the rigid body's drag
        // and the rotors' aerodynamics out.
        v["vehicle"]["body"] = "paper".into();
        let vehicle = v["vehicle"].as_object_mut().expect("[vehicle]");
        vehicle.remove("drag_coefficients");
        let actuator = v["actuator"].as_object_mut().expect("[actuator]");
        for key in ["rotor_drag", "flapping", "translational_lift"] {
            actuator.remove(key);
        }
        Config::from_json(&v.to_string()).expect("the delivery preset is valid")
    }

    /// In an 8 m/s crosswind the trim is a fixed point of the whole plant (rates and all but
    /// the hook's small moment), and its line angle is the parcel's own balance, drag on
    /// weight, computed here from the drag law alone; the quadrotor leans into the wind by
    /// the balance of the whole vehicle's drag on its weight.
    #[test]
    fn the_trim_balances_the_parcels_drag_on_its_weight() {
        let cfg = delivery();
        let v: Vehicle<f64, Cable, Rotors> =
            AnyVehicle::new(&cfg.model_context()).vehicle::<Cable, Rotors>();
        let wind = [0.0, 8.0, 0.0];
        let s: State<f64, NX> = v
            .trim_state([0.0, 0.0, 2.0], [0.0, 0.0, 0.3], wind)
            .unwrap();
        let lay = Vehicle::<f64, Cable, Rotors>::LAYOUT;
        let (pay, act) = (lay.payload(), lay.actuator());
        // The line from the hook (offset below the centre, tilted with the body) to the parcel.
        let (sphi, cphi) = s[3].sin_cos();
        let (sth, cth) = s[4].sin_cos();
        let (sps, cps) = s[5].sin_cos();
        // Body z axis in inertial axes (ZYX Euler angles).
        let ez = [
            cps * sth * cphi + sps * sphi,
            sps * sth * cphi - cps * sphi,
            cth * cphi,
        ];
        let h = cfg.payload.cable.attachment_offset.unwrap();
        let hook: Vec<f64> = (0..3).map(|i| s[i] - h * ez[i]).collect();
        let line: Vec<f64> = (0..3).map(|i| s[pay + i] - hook[i]).collect();
        let swing = (line[0].hypot(line[1])).atan2(-line[2]);
        let rho = cfg.gust.air_density;
        let drag = 0.5 * rho * cfg.payload.drag_area * 8.0 * 8.0;
        let weight = cfg.payload.mass * cfg.environment.gravity;
        assert!(
            (swing - (drag / weight).atan()).abs() < 1e-9,
            "swing {swing}"
        );
        // Downwind: the parcel trails toward +y; the thrust leans into the wind, by the whole
        // vehicle's drag (the quadrotor's and the parcel's) on its weight.
        assert!(line[1] > 0.0 && ez[1] < 0.0, "line {line:?}, ez {ez:?}");
        let quad_drag = 0.5 * rho * cfg.vehicle.lateral_drag_area * 8.0 * 8.0;
        let lean = (-ez[1] / ez[2]).atan();
        let total = (quad_drag + drag) / (weight + cfg.vehicle.mass * cfg.environment.gravity);
        assert!((lean - total.atan()).abs() < 1e-9, "lean {lean}");
        // The rotors spin at the speed their command holds: the thrust they give, commanded
        // back, leaves nothing to settle.
        let zero = Inputs {
            u1: 0.0,
            tau: [0.0; 3],
        };
        let felt = v
            .actuator
            .inputs(&v.actuator.command(&zero, Tick::START), &s, act);
        let u = Inputs {
            u1: felt.u1,
            tau: [0.0; 3],
        };
        let ds = v.derivative(
            &s,
            &Trig::of(&s),
            &v.actuator.command(&u, Tick::START),
            &wind,
        );
        for (i, d) in ds.iter().enumerate() {
            // Positions and angles stay (velocities zero); rates: the hook's moment only.
            if i != lay.vel() + 3 && i != lay.vel() + 4 {
                assert!(d.abs() < 1e-8, "d s[{i}]/dt = {d}");
            }
        }
    }

    #[test]
    fn no_wind_is_the_rest_state_bit_for_bit() {
        let cfg = delivery();
        let v: Vehicle<f64, Cable, Rotors> =
            AnyVehicle::new(&cfg.model_context()).vehicle::<Cable, Rotors>();
        let a: State<f64, NX> = v
            .trim_state([1.0, 2.0, 3.0], [0.1, 0.0, 0.3], [0.0; 3])
            .unwrap();
        let b: State<f64, NX> = v.rest_state([1.0, 2.0, 3.0], [0.1, 0.0, 0.3]);
        assert_eq!(a.map(f64::to_bits), b.map(f64::to_bits));
    }

    /// A flight whose vehicle cannot hover in the start's wind starts at rest (and is flown
    /// and flagged like any other); one that can starts trimmed.
    #[test]
    fn a_start_with_no_trim_is_the_rest_state() {
        use crate::gust::WindField;
        use crate::integrate::initial_state;
        let mut cfg = delivery();
        let parts = AnyVehicle::new(&cfg.model_context());
        let i = cfg.initial.clone();
        let rest: State<f64, NX> = parts
            .vehicle::<Cable, Rotors>()
            .rest_state(i.position, i.attitude);
        let (trimmed, balanced) =
            initial_state(&parts, &cfg, &WindField::new(&cfg.wind_context()).unwrap()).unwrap();
        assert_ne!(trimmed, rest.to_vec()); // the preset's 5 m/s breeze tilts it
        assert!(balanced);
        cfg.vehicle.lateral_drag_area = 1e155;
        let parts = AnyVehicle::new(&cfg.model_context());
        let (start, balanced) =
            initial_state(&parts, &cfg, &WindField::new(&cfg.wind_context()).unwrap()).unwrap();
        assert_eq!(start, rest.to_vec());
        assert!(!balanced);
    }

    #[test]
    fn a_wind_no_tilt_can_hold_is_refused() {
        let cfg = delivery();
        let v: Vehicle<f64, Cable, Rotors> =
            AnyVehicle::new(&cfg.model_context()).vehicle::<Cable, Rotors>();
        let e = v
            .trim_state::<NX>([0.0; 3], [0.0; 3], [0.0, 400.0, 0.0])
            .unwrap_err();
        assert!(e.contains("no steady hover"), "{e}");
    }
}
