//! The closed loop at hover as functions of the state and a steady wind (`ClosedLoop`), on
//! plain and on dual numbers: what `stability` linearises and `crate::start` balances. Its law
//! is held as a value (`Law`), so the loop, the plant with it, is compiled once per vehicle
//! (docs/architecture.md, "What the library weighs").

use crate::control::{
    dispatch as dispatch_law, AnyController, Controller, ControllerKind, ControllerVisitor, Due,
    Kept, Sight,
};
use crate::lane::{dual::Dual, Lane, Masks, Param};
use crate::model::{
    dispatch, Actuator, ActuatorModel, AnyVehicle, BodyKind, Inputs, Payload, PayloadModel,
    PayloadView, Rigid, State, StateVar, Tick, Trig, Vehicle, VehicleVisitor,
};
use crate::rk4::rk4_step;
use crate::scenario::Config;
use crate::trajectory::Reference;

/// The closed loop ds/dt = f(s, u(s, r), w) and its outputs y, as functions of the state and
/// a steady wind, on plain numbers and on dual numbers (for exact derivatives). Built for one
/// scenario's vehicle kinds and one controller (`closed_loop`).
pub trait ClosedLoop {
    /// The states, in order.
    fn vars(&self) -> &[StateVar];
    /// (f, y) at `s` in wind `w`.
    fn eval(&self, s: &[f64], w: &[f64; 3]) -> (Vec<f64>, Vec<f64>);
    fn eval_dual(&self, s: &[Dual], w: &[Dual; 3]) -> (Vec<Dual>, Vec<Dual>);
    /// At rest at the reference position (zero angles), payload and actuators at hover.
    fn rest(&self) -> Vec<f64>;
    /// Where the law's loops run at rates (docs/model.md, "Loop rates"): the period of the slowest
    /// schedule (steps, every loop updating at its first) and the step, s. None where every
    /// loop runs every step (the continuous model is the law's).
    fn sampled(&self) -> Option<(usize, f64)>;
    /// The sampled closed loop flown for one such period from `s` in still air, the law's
    /// memory at rest at `s` (as the continuous model's law is), every loop updating on its
    /// schedule and holding between, the plant integrated as the flight loop integrates it:
    /// the state it ends in.
    fn fly_period(&self, s: &[f64]) -> Vec<f64>;
    /// The law's integrator slots (`Controller::integrators`).
    fn integrators(&self) -> &[usize];
    /// The closed loop at `s` in the steady wind `w` with the law's integrators at `held` (one
    /// per `integrators`), every loop updating: ds/dt, then each integrator's change over the
    /// update. Zero at a closed-loop equilibrium (`crate::start`).
    fn eval_held(&self, s: &[f64], held: &[f64], w: &[f64; 3]) -> Vec<f64>;
    /// The loop's states of a vehicle's full state (the dependent one left out), and back.
    fn reduced(&self, full: &[f64]) -> Vec<f64>;
    fn expanded(&self, s: &[f64]) -> Vec<f64>;
}

/// The closed loop's law, its kind chosen at run time: each call a `match` on the kind
/// (`control::dispatch`) whose arm is the law's own code, as the flight loop's `Flying` is. So
/// the closed loop (the plant on plain and on dual numbers, the period's integration) is
/// compiled once per vehicle, not once per vehicle and law. Its memory travels as its slots
/// (`Kept::slots`: a law's memory is a fixed array of them, nothing else).
struct Law {
    any: AnyController,
    /// `Control::SEES_PAYLOAD`: the loop works out the payload's view for the law.
    sees_payload: bool,
    /// The law's integrator slots (`Controller::integrators`).
    integrators: Vec<usize>,
}

impl Law {
    /// Law `kind` of the scenario `cfg`.
    fn new(cfg: &Config, kind: ControllerKind) -> Self {
        struct Build(AnyController);
        impl ControllerVisitor for Build {
            type Output = Law;
            fn visit<C: Controller>(self) -> Law {
                let integrators = self.0.get::<C>().integrators();
                Law {
                    any: self.0,
                    sees_payload: C::SEES_PAYLOAD,
                    integrators,
                }
            }
        }
        let any = AnyController::new(kind, &cfg.control_context());
        dispatch_law(kind, Build(any))
    }

    /// The law at rest at `seen` at the flight's start (`Control::at_rest`).
    fn at_rest<L: Masks>(&self, seen: &Sight<L>, r: &Reference) -> Inputs<L>
    where
        f64: Param<L>,
    {
        struct AtRest<'a, 'b, L>(&'a AnyController, &'a Sight<'b, L>, &'a Reference);
        impl<L: Masks> ControllerVisitor for AtRest<'_, '_, L>
        where
            f64: Param<L>,
        {
            type Output = Inputs<L>;
            fn visit<C: Controller>(self) -> Inputs<L> {
                let AtRest(any, seen, r) = self;
                any.get::<C>().at_rest(seen, r, Tick::START)
            }
        }
        dispatch_law(self.any.kind(), AtRest(&self.any, seen, r))
    }

    /// The slots of the memory at rest at `seen` (`Control::memory`).
    fn memory(&self, seen: &Sight<f64>) -> Vec<f64> {
        struct Memory<'a, 'b>(&'a AnyController, &'a Sight<'b, f64>);
        impl ControllerVisitor for Memory<'_, '_> {
            type Output = Vec<f64>;
            fn visit<C: Controller>(self) -> Vec<f64> {
                self.0.get::<C>().memory(self.1).slots().to_vec()
            }
        }
        dispatch_law(self.any.kind(), Memory(&self.any, seen))
    }

    /// One control step (`Control::step`) from the memory whose slots are `mem`, advanced in
    /// place.
    fn step(
        &self,
        seen: &Sight<f64>,
        r: &Reference,
        at: Tick,
        due: Due,
        mem: &mut [f64],
    ) -> Inputs<f64> {
        struct Step<'a, 'b> {
            any: &'a AnyController,
            seen: &'a Sight<'b, f64>,
            r: &'a Reference,
            at: Tick,
            due: Due,
            mem: &'a mut [f64],
        }
        impl ControllerVisitor for Step<'_, '_> {
            type Output = Inputs<f64>;
            fn visit<C: Controller>(self) -> Inputs<f64> {
                let law = self.any.get::<C>();
                // A memory of the law's type, every slot then set: `mem` is all of it.
                let mut m = law.memory(self.seen);
                m.slots_mut().copy_from_slice(self.mem);
                let u = law.step(self.seen, self.r, self.at, self.due, &mut m);
                self.mem.copy_from_slice(m.slots());
                u
            }
        }
        let step = Step {
            any: &self.any,
            seen,
            r,
            at,
            due,
            mem,
        };
        dispatch_law(self.any.kind(), step)
    }
}

/// The closed loop of one vehicle and law (the law chosen at run time, `Law`). The states are
/// the vehicle's less the body's dependent one (`BodyKind::DEPENDENT`: the rigid body's qw, so
/// that the linear model's attitude has three parameters, the quaternion's vector part, and no
/// spurious zero mode).
struct Loop<B: BodyKind, Pay: Payload, Act: Actuator, const N: usize> {
    vars: Vec<StateVar>,
    plain: Vehicle<f64, Pay::At<f64>, Act::At<f64>, B>,
    dual: Vehicle<Dual, Pay::At<Dual>, Act::At<Dual>, B>,
    ctrl: Law,
    r: Reference,
    /// Steps between the updates of the position, attitude and inner loops, and the step (s).
    steps: [usize; 3],
    dt: f64,
}

impl<B: BodyKind, Pay: Payload, Act: Actuator, const N: usize> Loop<B, Pay, Act, N> {
    /// The vehicle's full state from the loop's (the dependent state put back).
    fn full<L: Lane>(s: &[L]) -> State<L, N> {
        let mut full = [L::splat(0.0); N];
        match B::DEPENDENT {
            Some(k) => {
                full[..k].copy_from_slice(&s[..k]);
                full[k + 1..].copy_from_slice(&s[k..]);
                B::complete(&mut full);
            }
            None => full.copy_from_slice(s),
        }
        full
    }

    /// What the law sees at `s` (frame `frame`): the rigid body, its angles' sines and cosines
    /// and, for a law that sees it (`sees_payload`: `Control::SEES_PAYLOAD`), the payload.
    #[allow(clippy::type_complexity)]
    fn seen<L: Lane>(
        v: &Vehicle<L, Pay::At<L>, Act::At<L>, B>,
        s: &State<L, N>,
        frame: &B::Frame<L>,
        sees_payload: bool,
    ) -> (Rigid<L>, Trig<L>, Option<PayloadView<L>>) {
        let view = Vehicle::<L, Pay::At<L>, Act::At<L>, B>::rigid_at(s, frame);
        let trig = Trig::of_angles(view.att[0], view.att[1], view.att[2]);
        let payload = sees_payload.then(|| v.payload.view(s, frame));
        (view, trig, payload)
    }

    /// The loop's states of a full vector (the dependent one left out).
    fn reduce<L: Copy>(full: &[L]) -> Vec<L> {
        let mut v = full.to_vec();
        if let Some(k) = B::DEPENDENT {
            v.remove(k);
        }
        v
    }

    fn signals<L: Masks>(
        v: &Vehicle<L, Pay::At<L>, Act::At<L>, B>,
        ctrl: &Law,
        r: &Reference,
        s: &[L],
        w: &[L; 3],
    ) -> (Vec<L>, Vec<L>)
    where
        f64: Param<L>,
    {
        let s = Self::full(s);
        // Hover is time-invariant: the law and the actuators are asked at the flight's start;
        // the law at rest, every loop updating: the linear model is the continuous law's (a
        // sampled law's holds are the discrete model's business: `sampled`).
        let frame = B::frame(&s);
        let (view, trig, payload) = Self::seen(v, &s, &frame, ctrl.sees_payload);
        let u = ctrl.at_rest(&Sight::of(&view, &trig, &payload), r);
        let cmd = v.actuator.command(&u, Tick::START);
        let f = v.derivative(&s, &frame, &cmd, w);
        let out = v.payload_outputs(&s, &frame, u.u1, w);
        let mut y = Self::reduce(&s);
        y.extend([out.e_o, u.u1, u.tau[0], u.tau[1], u.tau[2], out.accel[2]]);
        (Self::reduce(&f), y)
    }
}

impl<B: BodyKind, Pay: Payload, Act: Actuator, const N: usize> ClosedLoop for Loop<B, Pay, Act, N> {
    fn vars(&self) -> &[StateVar] {
        &self.vars
    }
    fn eval(&self, s: &[f64], w: &[f64; 3]) -> (Vec<f64>, Vec<f64>) {
        Self::signals(&self.plain, &self.ctrl, &self.r, s, w)
    }
    fn eval_dual(&self, s: &[Dual], w: &[Dual; 3]) -> (Vec<Dual>, Vec<Dual>) {
        Self::signals(&self.dual, &self.ctrl, &self.r, s, w)
    }
    fn rest(&self) -> Vec<f64> {
        let s: State<f64, N> = self.plain.rest_state(self.r.pos, [0.0; 3]);
        Self::reduce(&s)
    }
    fn sampled(&self) -> Option<(usize, f64)> {
        // (a period past usize, of rates whose steps share no factor, is as good as endless)
        let period = (self.steps.iter()).fold(1, |p, &n| lcm(p, n).unwrap_or(usize::MAX));
        (period > 1).then_some((period, self.dt))
    }
    fn fly_period(&self, s: &[f64]) -> Vec<f64> {
        let v = &self.plain;
        let mut s = Self::full(s);
        let (period, _) = self.sampled().unwrap_or((1, self.dt));
        let mut mem = None;
        let mut cmd = None;
        for step in 0..period {
            let frame = B::frame(&s);
            let (view, trig, payload) = Self::seen(v, &s, &frame, self.ctrl.sees_payload);
            let seen = Sight::of(&view, &trig, &payload);
            let due = Due {
                position: step % self.steps[0] == 0,
                attitude: step % self.steps[1] == 0,
                rate: step % self.steps[2] == 0,
            };
            let m = mem.get_or_insert_with(|| self.ctrl.memory(&seen));
            let tick = Tick {
                step,
                t: step as f64 * self.dt,
            };
            let u = self.ctrl.step(&seen, &self.r, tick, due, m);
            let c = match cmd {
                Some(c) if !due.rate => c,
                _ => v.actuator.command(&u, tick),
            };
            cmd = Some(c);
            s = rk4_step(v, &s, &frame, &c, &[0.0; 3], self.dt);
        }
        Self::reduce(&s)
    }
    fn integrators(&self) -> &[usize] {
        &self.ctrl.integrators
    }
    fn eval_held(&self, s: &[f64], held: &[f64], w: &[f64; 3]) -> Vec<f64> {
        let (v, s) = (&self.plain, Self::full(s));
        let frame = B::frame(&s);
        let (view, trig, payload) = Self::seen(v, &s, &frame, self.ctrl.sees_payload);
        let seen = Sight::of(&view, &trig, &payload);
        let mut mem = self.ctrl.memory(&seen);
        (self.ctrl.integrators.iter().zip(held)).for_each(|(&i, &x)| mem[i] = x);
        let before = mem.clone();
        let u = self
            .ctrl
            .step(&seen, &self.r, Tick::START, Due::ALL, &mut mem);
        let f = v.derivative(&s, &frame, &v.actuator.command(&u, Tick::START), w);
        let change = self.ctrl.integrators.iter().map(|&i| mem[i] - before[i]);
        Self::reduce(&f).into_iter().chain(change).collect()
    }
    fn reduced(&self, full: &[f64]) -> Vec<f64> {
        Self::reduce(full)
    }
    fn expanded(&self, s: &[f64]) -> Vec<f64> {
        Self::full(s).to_vec()
    }
}

/// The least common multiple of two step counts, None past `usize`.
fn lcm(a: usize, b: usize) -> Option<usize> {
    fn gcd(a: usize, b: usize) -> usize {
        if b == 0 {
            a
        } else {
            gcd(b, a % b)
        }
    }
    (a / gcd(a, b)).checked_mul(b)
}

/// The closed loop of `kind` for the scenario `cfg`, about the reference `r`.
pub fn closed_loop(cfg: &Config, kind: ControllerKind, r: Reference) -> Box<dyn ClosedLoop> {
    struct Build<'a>(&'a Config, ControllerKind, Reference);
    impl VehicleVisitor for Build<'_> {
        type Output = Box<dyn ClosedLoop>;
        fn visit<B: BodyKind, Pay: Payload, Act: Actuator, const N: usize>(
            self,
        ) -> Box<dyn ClosedLoop> {
            let Build(cfg, kind, r) = self;
            let parts = AnyVehicle::new(&cfg.model_context());
            let mut vars = crate::model::state_vars_of::<B, Pay, Act>();
            if let Some(k) = B::DEPENDENT {
                vars.remove(k);
            }
            Box::new(Loop::<B, Pay, Act, N> {
                vars,
                plain: parts.vehicle_on::<B, Pay, Act>(),
                dual: AnyVehicle::gather_on::<Dual, B, Pay, Act>(&[&parts]),
                ctrl: Law::new(cfg, kind),
                r,
                steps: cfg.controller.loop_steps(kind, cfg.integrator.dt),
                dt: cfg.integrator.dt,
            })
        }
    }
    dispatch(
        cfg.vehicle.body,
        cfg.payload.model,
        cfg.actuator.model,
        Build(cfg, kind, r),
    )
}
