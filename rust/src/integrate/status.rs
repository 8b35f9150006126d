//! Why a flight ended (`ExitStatus`) and how a failed state is classified.

use crate::model::{ix, Bound, StateVar};

/// Why a flight ended (docs/model.md section 11): it ran to the end, or a state went
/// non-finite or past its runaway bound (`divergence.*`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum ExitStatus {
    Ok = 0,
    NonFinite = 1,
    Distance = 2,
    Tilt = 3,
    Speed = 4,
    Rate = 5,
    Ground = 6,
}

impl ExitStatus {
    pub const ALL: [Self; 7] = [
        Self::Ok,
        Self::NonFinite,
        Self::Distance,
        Self::Tilt,
        Self::Speed,
        Self::Rate,
        Self::Ground,
    ];

    /// The public name (`mc.runs["status"]`).
    pub fn name(self) -> &'static str {
        match self {
            Self::Ok => "ok",
            Self::NonFinite => "non_finite",
            Self::Distance => "distance",
            Self::Tilt => "tilt",
            Self::Speed => "speed",
            Self::Rate => "rate",
            Self::Ground => "ground",
        }
    }

    /// What happened, in a sentence.
    pub fn message(self) -> &'static str {
        match self {
            Self::Ok => "the flight ran to the end",
            Self::NonFinite => "a state became infinite or NaN",
            Self::Distance => "a position went past divergence.max_distance",
            Self::Tilt => "roll or pitch went past divergence.max_tilt",
            Self::Speed => "a velocity went past divergence.max_speed",
            Self::Rate => "a body rate went past divergence.max_rate",
            Self::Ground => "the quadrotor went below ground.altitude",
        }
    }

    fn of(bound: Bound) -> Self {
        match bound {
            Bound::Distance => Self::Distance,
            Bound::Tilt => Self::Tilt,
            Bound::Speed => Self::Speed,
            Bound::Rate => Self::Rate,
        }
    }
}

/// Why the state `s` (one lane's values) failed its checks: non-finite first, then the ground
/// (`floor`, the quadrotor's z), then the first bound exceeded in the order of `Bound`.
/// `tilt` are roll and pitch where they are no states (the rigid body's, derived), else empty.
pub(super) fn classify(
    vars: &[StateVar],
    s: &[f64],
    tilt: &[f64],
    limits: &[f64; 4],
    floor: f64,
) -> ExitStatus {
    if s.iter().any(|x| !x.is_finite()) {
        return ExitStatus::NonFinite;
    }
    if s[ix::Z] < floor {
        return ExitStatus::Ground;
    }
    [Bound::Distance, Bound::Tilt, Bound::Speed, Bound::Rate]
        .into_iter()
        .find(|&b| {
            let limit = limits[b as usize];
            (b == Bound::Tilt && tilt.iter().any(|x| x.abs() > limit))
                || vars
                    .iter()
                    .zip(s)
                    .any(|(v, x)| v.bound == Some(b) && x.abs() > limit)
        })
        .map_or(ExitStatus::NonFinite, ExitStatus::of)
}
