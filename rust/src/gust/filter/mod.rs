//! One gust component's forming filter, discretised exactly for the integration step. This
//! file holds the filter (`GustFilter`) and what it answers: its coefficients, rescaled for
//! scales that follow the vehicle, its spectra and autocorrelation. `design` builds it
//! (normalisation to unit stationary covariance by Lyapunov, the transition matrix and the
//! noise covariance by Van Loan, the closed forms of the Dryden filters); `kernels` steps it
//! (the per-step state update and the lane-valued Dryden coefficients).

mod design;
mod kernels;

use super::spectra::{poly_abs2, rational, von_karman_psd_exact};
use crate::config::{GustComponent, GustModel};
use design::{check_non_negative, check_positive, rows, K_MAX};
pub use kernels::Normals;
pub(super) use kernels::{dryden_lanes, step_fixed, DrydenLanes};
use nalgebra::{Matrix3, Vector3};

/// The numbers one step of a filter applies, row-major and padded to order 3: `x' = phi x +
/// g n`, `w = out . x` (`out = sigma c`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Coefficients {
    pub phi: [[f64; 3]; 3],
    pub g: [[f64; 3]; 3],
    pub out: [f64; 3],
}

impl Coefficients {
    /// Every number NaN: what a step whose scales no filter can take flies
    /// ([`GustFilter::poisoned`]'s).
    pub const NAN: Self = Self {
        phi: [[f64::NAN; 3]; 3],
        g: [[f64::NAN; 3]; 3],
        out: [f64::NAN; 3],
    };

    fn of(phi: &Matrix3<f64>, g: &Matrix3<f64>, out: [f64; 3]) -> Self {
        Self {
            phi: rows(phi),
            g: rows(g),
            out,
        }
    }
}
/// What a forming filter is built from: its model and component, the output's standard
/// deviation `sigma` (m/s), the scale length (m), the airspeed (m/s) and the step `dt` (s).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GustSpec {
    pub model: GustModel,
    pub component: GustComponent,
    pub sigma: f64,
    pub length_scale: f64,
    pub airspeed: f64,
    pub dt: f64,
}

/// One gust component's forming filter, exactly discretised for a step `dt`,
/// with its state normalised to unit stationary covariance:
/// `x' = Phi x + G n`, `w = sigma c.x` (`|c| = 1`, `G G^T = I - Phi Phi^T`).
///
/// Orders: Dryden longitudinal 1, Dryden lateral/vertical 2, von Karman
/// longitudinal 2, von Karman lateral/vertical 3. Matrices are padded with zeros
/// to 3x3. Fixed-size storage, no heap, `Copy`.
///
/// Dryden uses the closed forms of docs/model.md section 4 (`k = V dt / L`, `E = exp(-k)`):
/// longitudinal `Phi = E`, `G = sqrt(1 - E^2)`, `c = 1`; lateral/vertical
/// `Phi = E [[1+k, k], [-k, 1-k]]`, `G = chol(I - Phi Phi^T)` (entries of
/// `I - Phi Phi^T` evaluated without cancellation), `c = (1/2, sqrt3/2)`.
/// Von Karman uses the general method (controllable canonical form, Lyapunov
/// solve, normalisation, `Phi = expm(A k)`, `Q` by Van Loan's method for
/// `k |A| <= 1`); its output is scaled so that the variance is exactly sigma^2
/// (the published approximants' own variance differs: see
/// [`GustFilter::approximant_variance_ratio`] and docs/gust.md).
#[derive(Clone, Copy, Debug)]
pub struct GustFilter {
    spec: GustSpec,
    /// V dt / L.
    k: f64,
    order: usize,
    phi: Matrix3<f64>,
    chol: Matrix3<f64>,
    /// Normalised continuous A in nondimensional time V t / L (padded).
    a: Matrix3<f64>,
    /// Normalised continuous B in nondimensional time (padded).
    b: Vector3<f64>,
    /// Unit output row (padded).
    c: Vector3<f64>,
    /// sigma * c, the row applied to the state.
    out: Vector3<f64>,
    num: [f64; 4],
    den: [f64; 4],
    gain2: f64,
    raw_variance_ratio: f64,
}

impl GustFilter {
    /// Build and discretise one component's filter.
    ///
    /// `sigma` (m/s) >= 0, `length_scale` (m) > 0, `airspeed` (m/s) > 0, `dt`
    /// (s) > 0, all finite; otherwise `Err` with a message naming the
    /// parameter and the value (e.g. `airspeed must be > 0 (the Dryden filters
    /// are singular at zero airspeed), got 0.0`).
    pub fn new(spec: GustSpec) -> Result<Self, String> {
        let k = Self::check(
            spec.model,
            spec.sigma,
            spec.length_scale,
            spec.airspeed,
            spec.dt,
        )?;
        let r = rational(spec.model, spec.component);
        let mut f = match spec.model {
            GustModel::Dryden => Self::dryden_closed_form(spec.component, k),
            GustModel::VonKarman => Self::general(&r, k)?,
        };
        f.spec = spec;
        f.k = k;
        f.out = f.c * spec.sigma;
        f.num = r.num;
        f.den = r.den;
        f.gain2 = r.gain2;
        Ok(f)
    }

    /// What `new` requires of its numbers, checked without building the filter (scenario
    /// validation runs it for every component): the step in scale lengths, `airspeed * dt /
    /// length_scale`, finite and positive.
    pub fn check(
        model: GustModel,
        sigma: f64,
        length_scale: f64,
        airspeed: f64,
        dt: f64,
    ) -> Result<f64, String> {
        check_non_negative("sigma", sigma)?;
        check_positive("length_scale", length_scale, "")?;
        if !(airspeed.is_finite() && airspeed > 0.0) {
            // The message is built only on failure: scales that follow the vehicle rebuild
            // the filter every step.
            let why = format!(
                " (the {} filters are singular at zero airspeed)",
                model.name()
            );
            check_positive("airspeed", airspeed, &why)?;
        }
        check_positive("dt", dt, "")?;
        let k = airspeed * dt / length_scale;
        if !(k.is_finite() && k > 0.0) {
            return Err(format!(
                "airspeed * dt / length_scale must be finite and > 0, got {k:?} \
                 (airspeed {airspeed:?}, dt {dt:?}, length_scale {length_scale:?})"
            ));
        }
        Ok(k)
    }

    /// This filter re-discretised for new scales (same model, component and step): for
    /// turbulence whose altitude or airspeed follows the vehicle. The normalised state keeps
    /// unit stationary covariance whatever the scales, so changing them never makes the
    /// variance jump. Dryden: the closed forms, no allocation.
    #[inline]
    pub fn rescaled(&self, sigma: f64, length_scale: f64, airspeed: f64) -> Result<Self, String> {
        Self::new(GustSpec {
            sigma,
            length_scale,
            airspeed,
            ..self.spec
        })
    }

    /// The `Phi`, `G` and `sigma c` of this filter re-discretised for new scales, or
    /// [`Coefficients::NAN`] where [`rescaled`](Self::rescaled) errs (what
    /// [`poisoned`](Self::poisoned) flies): the numbers of turbulence that follows the vehicle,
    /// computed every step. Dryden: [`dryden_lanes`] on `f64` (the lane-valued `exp` and
    /// `expm1`, so the lane-set path gives each lane these bits; within a few ulp of
    /// `rescaled`'s libm closed forms), without building a filter or allocating. Von Karman:
    /// `rescaled`'s, bit for bit.
    #[inline]
    pub fn rescaled_coefficients(
        &self,
        sigma: f64,
        length_scale: f64,
        airspeed: f64,
    ) -> Coefficients {
        match self.spec.model {
            GustModel::Dryden => {
                // `check`'s conditions, inline (`dt` was checked when `self` was built): the
                // same `k`, and an error exactly where `check` errs.
                let ok = |x: f64| x.is_finite() && x > 0.0;
                let k = airspeed * self.spec.dt / length_scale;
                let valid = sigma.is_finite() && sigma >= 0.0;
                if !(valid && ok(length_scale) && ok(airspeed) && ok(self.spec.dt) && ok(k)) {
                    return Coefficients::NAN;
                }
                let mut out = Coefficients {
                    phi: [[0.0; 3]; 3],
                    g: [[0.0; 3]; 3],
                    out: [self.c[0] * sigma, self.c[1] * sigma, self.c[2] * sigma],
                };
                dryden_lanes(
                    self.spec.component,
                    sigma,
                    length_scale,
                    airspeed,
                    self.spec.dt,
                    [self.c[0], self.c[1]],
                    DrydenLanes {
                        phi: &mut out.phi,
                        g: &mut out.g,
                        out: &mut out.out,
                    },
                );
                out
            }
            GustModel::VonKarman => match self.rescaled(sigma, length_scale, airspeed) {
                Ok(f) => f.coefficients(),
                Err(_) => Coefficients::NAN,
            },
        }
    }

    /// This filter re-discretised for new scales as turbulence that follows the vehicle flies
    /// it every step: [`rescaled_coefficients`](Self::rescaled_coefficients)' numbers (so the
    /// per-realisation path and the lane-set path fly the same bits), or
    /// [`poisoned`](Self::poisoned) where the scales are rejected.
    #[inline]
    pub fn rescaled_following(&self, sigma: f64, length_scale: f64, airspeed: f64) -> Self {
        if self.spec.model == GustModel::VonKarman {
            return self
                .rescaled(sigma, length_scale, airspeed)
                .unwrap_or_else(|_| self.poisoned());
        }
        let c = self.rescaled_coefficients(sigma, length_scale, airspeed);
        let mut f = *self;
        f.phi = Matrix3::from_fn(|i, j| c.phi[i][j]);
        f.chol = Matrix3::from_fn(|i, j| c.g[i][j]);
        f.out = Vector3::from(c.out);
        f.spec = GustSpec {
            sigma,
            length_scale,
            airspeed,
            ..self.spec
        };
        f.k = airspeed * self.spec.dt / length_scale;
        f
    }

    /// This filter's `Phi`, `G` and `sigma c`.
    pub fn coefficients(&self) -> Coefficients {
        Coefficients::of(
            &self.phi,
            &self.chol,
            [self.out[0], self.out[1], self.out[2]],
        )
    }

    /// This filter with NaN transition, noise and output: what a step whose scales no filter
    /// can take (a runaway state) flies, so that the flight ends as non-finite.
    pub(super) fn poisoned(&self) -> Self {
        let nan = f64::NAN;
        Self {
            phi: Matrix3::from_element(nan),
            chol: Matrix3::from_element(nan),
            out: Vector3::from_element(nan),
            ..*self
        }
    }

    /// The unit output row `c` (padded): `output_row` is `sigma c`.
    pub(super) fn unit_output(&self) -> [f64; 3] {
        [self.c[0], self.c[1], self.c[2]]
    }

    /// Filter order (state dimension), 1 to 3.
    pub fn order(&self) -> usize {
        self.order
    }

    pub fn model(&self) -> GustModel {
        self.spec.model
    }

    pub fn component(&self) -> GustComponent {
        self.spec.component
    }

    /// Output standard deviation, m/s.
    pub fn sigma(&self) -> f64 {
        self.spec.sigma
    }

    /// Scale length, m.
    pub fn length_scale(&self) -> f64 {
        self.spec.length_scale
    }

    /// Airspeed, m/s.
    pub fn airspeed(&self) -> f64 {
        self.spec.airspeed
    }

    /// Step, s.
    pub fn dt(&self) -> f64 {
        self.spec.dt
    }

    /// `k = V dt / L`, the step in scale lengths.
    pub fn step_in_scale_lengths(&self) -> f64 {
        self.k
    }

    /// Variance of the published forming filter (with its published gain and
    /// intensity-pi noise) over sigma^2. Exactly 1 for Dryden; for von Karman
    /// the approximant's own variance ratio (the output here is rescaled so
    /// the variance is exactly sigma^2).
    pub fn approximant_variance_ratio(&self) -> f64 {
        self.raw_variance_ratio
    }
    /// Transition matrix `Phi = expm(A dt)` of the normalised state (padded).
    pub fn transition(&self) -> Matrix3<f64> {
        self.phi
    }

    /// Noise factor `G` with `G G^T = I - Phi Phi^T` (padded): the lower
    /// Cholesky factor; only if `I - Phi Phi^T` were numerically singular
    /// would it be the clamped symmetric square root instead (not triangular).
    pub fn noise_chol(&self) -> Matrix3<f64> {
        self.chol
    }

    /// Continuous `A` of the normalised state, in 1/s (`Phi = expm(A dt)`).
    pub fn continuous_a(&self) -> Matrix3<f64> {
        self.a * (self.spec.airspeed / self.spec.length_scale)
    }

    /// Continuous `B` of the normalised state for unit-intensity white noise,
    /// in 1/sqrt(s): `A + A^T + B B^T = 0` (stationary covariance I).
    pub fn continuous_b(&self) -> Vector3<f64> {
        self.b * (self.spec.airspeed / self.spec.length_scale).sqrt()
    }

    /// Output row `sigma c` (m/s per unit state), padded.
    pub fn output_row(&self) -> Vector3<f64> {
        self.out
    }

    /// One-sided PSD of the generated gust, m^2/s^2 per Hz, at `f_hz`:
    /// `2 pi |H(j 2 pi f)|^2`, i.e. Dryden longitudinal `4 sigma^2 T/(1+x^2)`,
    /// lateral/vertical `2 sigma^2 T (1+3x^2)/(1+x^2)^2` (`T = L/V`,
    /// `x = 2 pi f T`); von Karman: the approximant's, rescaled by
    /// `1/approximant_variance_ratio()` like the output. Integrates to sigma^2.
    pub fn psd(&self, f_hz: f64) -> f64 {
        let t = self.spec.length_scale / self.spec.airspeed;
        let x = 2.0 * std::f64::consts::PI * f_hz.abs() * t;
        2.0 * self.spec.sigma * self.spec.sigma * t * self.gain2 / self.raw_variance_ratio
            * poly_abs2(&self.num, x)
            / poly_abs2(&self.den, x)
    }

    /// The spectrum this filter is meant to realise: equal to [`Self::psd`] for
    /// Dryden, the exact von Karman PSD ([`von_karman_psd_exact`]) for von Karman.
    pub fn target_psd(&self, f_hz: f64) -> f64 {
        match self.spec.model {
            GustModel::Dryden => self.psd(f_hz),
            GustModel::VonKarman => von_karman_psd_exact(
                self.spec.component,
                self.spec.sigma,
                self.spec.length_scale,
                self.spec.airspeed,
                f_hz,
            ),
        }
    }

    /// Autocorrelation (m^2/s^2) of the generated gust at lag `tau` (s).
    /// Dryden, exactly: `sigma^2 e^-u` (longitudinal), `sigma^2 e^-u (1 - u/2)`
    /// (lateral/vertical), `u = V |tau| / L`. Von Karman: the approximant's,
    /// `sigma^2 c expm(A u) c^T` from the normalised state-space form.
    pub fn autocorrelation(&self, tau: f64) -> f64 {
        let u = self.spec.airspeed * tau.abs() / self.spec.length_scale;
        let s2 = self.spec.sigma * self.spec.sigma;
        match (self.spec.model, self.spec.component) {
            (GustModel::Dryden, GustComponent::Longitudinal) => s2 * (-u).exp(),
            (GustModel::Dryden, _) => s2 * (-u).exp() * (1.0 - 0.5 * u),
            (GustModel::VonKarman, _) => {
                if u.is_nan() {
                    return f64::NAN;
                }
                if u > K_MAX {
                    return 0.0;
                }
                let m = (self.a * u).exp();
                s2 * (self.c.transpose() * m * self.c)[(0, 0)]
            }
        }
    }
}
#[cfg(test)]
pub(super) mod tests;
