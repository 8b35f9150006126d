//! Ideal actuators (docs/model.md section 2): the controller's thrust and torques act on the
//! airframe at once and without limit. No states.

use super::{Actuator, ActuatorModel};
use crate::config::params::params;
use crate::lane::Lane;
use crate::model::layout::StateVar;
use crate::model::section::OwnsKeys;
use crate::model::ModelContext;
use crate::model::{Inputs, State, Tick};

params! {
    /// The ideal actuators' own keys in `[actuator]`: none.
    pub struct IdealParams {}
}

#[derive(Clone, Copy, Debug, Default)]
pub struct Ideal;

impl OwnsKeys for Ideal {
    type Params = IdealParams;
}

impl Actuator for Ideal {
    type At<L: Lane> = Ideal;
    const VARS: &'static [StateVar] = &[];

    fn new(_: &IdealParams, _cfg: &ModelContext) -> Self {
        Ideal
    }

    fn gather<L: Lane>(_each: &[&Self]) -> Ideal {
        Ideal
    }
}

impl<L: Lane> ActuatorModel<L> for Ideal {
    const STATES: usize = 0;
    type Command = Inputs<L>;

    #[inline(always)]
    fn command(&self, u: &Inputs<L>, _at: Tick) -> Inputs<L> {
        *u
    }

    #[inline(always)]
    fn inputs<const N: usize>(&self, cmd: &Inputs<L>, _s: &State<L, N>, _at: usize) -> Inputs<L> {
        *cmd
    }

    #[inline(always)]
    fn derivative<const N: usize>(
        &self,
        _cmd: &Inputs<L>,
        _s: &State<L, N>,
        _at: usize,
        _ds: &mut State<L, N>,
    ) {
    }

    fn rest<const N: usize>(&self, _s: &mut State<L, N>, _at: usize) {}
}
