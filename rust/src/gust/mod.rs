//! The wind a flight meets (docs/model.md section 4, docs/gust.md): continuous turbulence
//! composed with the deterministic sources (the mean wind with its shear, discrete gusts, a
//! measured table, a prescribed wind). The turbulence: MIL-F-8785C low-altitude Dryden
//! forming filters (and the usual rational von Karman approximants), discretised
//! *exactly* for the integration step, with a filter state normalised to unit
//! stationary covariance.
//!
//! Conventions (derivations in `docs/gust.md`):
//!
//! * Everything here is SI: metres, seconds, m/s. The standard's low-altitude
//!   scale formulas take the altitude in feet; [`low_altitude_scales`] converts.
//! * A filter of order `n` (1 to 3) is held as `x' = Phi x + G n`, `w = sigma c.x`,
//!   with `n` a vector of `n` independent standard normals, `Phi = expm(A dt)`,
//!   `G G^T = I - Phi Phi^T` and `|c| = 1`. The state's stationary covariance is
//!   the identity, so the output variance is exactly `sigma^2` at any step size,
//!   and a stationary state is just `n` standard normals.
//! * Normals are drawn with `rand_distr::StandardNormal` in a fixed order: per
//!   step, components longitudinal, lateral, vertical, each `order()` normals
//!   (state index order).
//! * Realisation `i` under master seed `s` draws from
//!   `ChaCha8Rng::seed_from_u64(s)` with `set_stream(i)` ([`realisation_rng`]).
//!
//! Layout: [`spectra`] (the scales and spectra), [`filter`] (the exactly discretised
//! forming filter), [`wind`] (the wind field a flight samples and stationary series),
//! [`lanes`] (the same turbulence for a whole lane-set at once, what the flight loop flies),
//! [`source`] (the seam of the deterministic wind sources, one file each, registered below),
//! [`section`] (the `[wind]` table they read, and `WindContext`, what they are built from).

pub mod filter;
pub mod lanes;
pub mod section;
pub mod source;
pub mod spectra;
pub mod wind;

// The deterministic wind sources, one file each (`gust/<name>.rs`), in the summation order
// (docs/architecture.md, "Wind"): a new kind is its file and one line here.
source::wind_sources! {
    steady => Steady,
    gusts => Gusts,
    table => Table,
    prescribed => Prescribed,
}

pub use filter::{Coefficients, GustFilter, GustSpec};
pub use lanes::{LaneGust, LaneWind};
pub use section::{Wind, WindContext};
pub use source::Kinematics;
pub use spectra::{low_altitude_scales, von_karman_psd_exact, METRES_PER_FOOT};
pub use wind::{
    fill_series, realisation_rng, Source, WindField, WindState, VEHICLE_ALTITUDE_RANGE,
};
