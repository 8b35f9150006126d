//! TEMPORARY stand-in with gust.rs's interface (zero wind) while gust.rs is written.
#![allow(dead_code, unused_variables)]
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TurbulenceModel { Dryden, VonKarman }
#[derive(Clone, Debug)]
pub struct GustSpec { pub enabled: bool, pub model: TurbulenceModel, pub components: [bool; 3],
    pub altitude: f64, pub w20: f64, pub airspeed: f64, pub mean_wind: [f64; 3], pub start: f64, pub end: f64 }
#[derive(Clone, Debug)]
pub struct WindField;
pub struct WindState(ChaCha8Rng);
impl WindField {
    pub fn new(spec: &GustSpec, dt: f64) -> Result<Self, String> { Ok(WindField) }
    pub fn realisation(&self, seed: u64, index: u64) -> WindState { WindState(ChaCha8Rng::seed_from_u64(seed)) }
    pub fn sample(&self, state: &mut WindState, step: u64) -> [f64; 3] { [0.0; 3] }
}
