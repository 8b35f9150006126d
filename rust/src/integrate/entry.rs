//! The way into the flight loop: one function per lane type, compiled for the instruction set
//! its operations need (`LoopEntry`), and the engine's `fly`, `fly_set`.

use super::engine::{Engine, FlightRequest, LaneResult, Realisation, MAX_LANES};
use super::trace::Trace;
use crate::lane::isa::Isa;
use crate::lane::F64x4;
#[cfg(target_arch = "x86_64")]
use crate::lane::{F64x4Avx, F64x4Fma, F64x8Avx512, F64x8Fma512};
use crate::model::{Actuator, BodyKind, Payload};
use crate::navigation::Navigate;
use rustfft::FftPlanner;

/// `fly_vehicle` compiled with target features: one generic `unsafe fn $name` per (name,
/// features), instantiated per (lane type, vehicle).
/// Safety of each: the CPU must support the features.
macro_rules! flight_loop_for {
    ($($(#[$doc:meta])* $name:ident, $features:literal;)+) => {$(
        $(#[$doc])*
        ///
        /// # Safety
        #[doc = concat!("The CPU must support ", $features, ".")]
        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = $features)]
        unsafe fn $name<L, B, Pay, Act, const N: usize>(
            &self,
            sortie: Sortie<'_>,
        ) -> Option<Vec<LaneResult>>
        where
            L: Navigate,
            B: BodyKind,
            Pay: Payload,
            Act: Actuator,
        {
            self.fly_vehicle::<L, B, Pay, Act, N>(sortie)
        }
    )+};
}

/// A lane type's way into the flight loop: the loop of one vehicle compiled for the instruction
/// set its operations need, and no other. Each (lane type, instruction set) pair the loop is
/// compiled for costs a copy of the whole inlined model, laws and integrator per vehicle, so
/// only the pairs that can run are built: the intrinsic lane types in
/// their own instruction set, the portable ones (`f64` for single flights, `F64x4`) in the
/// baseline one. The arithmetic never contracts or reorders, so the same lanes give the same
/// bits in any of them.
pub trait LoopEntry: Navigate {
    /// Fly the request's law on the vehicle of kinds `B`, `Pay`, `Act` (`N` states), one
    /// realisation per lane.
    fn enter<B: BodyKind, Pay: Payload, Act: Actuator, const N: usize>(
        engine: &Engine,
        sortie: Sortie<'_>,
    ) -> Option<Vec<LaneResult>>;
}

/// What one entry into the flight loop flies: the lanes' realisations, the request, a trace
/// of lane 0 if asked, and the planner the turbulence's spectra are drawn with.
pub struct Sortie<'a> {
    pub realisations: &'a [&'a Realisation],
    pub req: &'a FlightRequest<'a>,
    pub trace: Option<&'a mut Trace>,
    pub planner: &'a mut FftPlanner<f64>,
}

macro_rules! portable_entry {
    ($($ty:ty),+) => {$(
        impl LoopEntry for $ty {
            fn enter<B: BodyKind, Pay: Payload, Act: Actuator, const N: usize>(
                engine: &Engine,
                sortie: Sortie<'_>,
            ) -> Option<Vec<LaneResult>> {
                engine.fly_vehicle::<Self, B, Pay, Act, N>(sortie)
            }
        }
    )+};
}
portable_entry!(f64, F64x4);

/// An intrinsic lane type enters only the loop compiled for its instruction set (and only on
/// a CPU that has it: asserted, because the type's operations would be illegal otherwise).
macro_rules! intrinsic_entry {
    ($($ty:ty => $isa:expr, $fused:expr, $name:ident;)+) => {$(
        #[cfg(target_arch = "x86_64")]
        impl LoopEntry for $ty {
            fn enter<B: BodyKind, Pay: Payload, Act: Actuator, const N: usize>(
                engine: &Engine,
                sortie: Sortie<'_>,
            ) -> Option<Vec<LaneResult>> {
                let isa: Isa = $isa;
                assert!(
                    isa.supported() && (!$fused || isa.fused_supported()),
                    "the {} path{} does not run on this CPU",
                    isa.name(),
                    if $fused { " (fused)" } else { "" }
                );
                // SAFETY: the CPU supports the instruction set (asserted just above).
                unsafe { engine.$name::<Self, B, Pay, Act, N>(sortie) }
            }
        }
    )+};
}
intrinsic_entry! {
    F64x4Avx => Isa::Avx2, false, fly_avx2;
    F64x4Fma => Isa::Avx2, true, fly_avx2_fma;
    F64x8Avx512 => Isa::Avx512, false, fly_avx512;
    F64x8Fma512 => Isa::Avx512, true, fly_avx512;
}

impl Engine {
    /// Fly `req.indices` (one per lane of `L`) on lane type `L`, with a trace of lane 0 if
    /// asked. Returns None if cancelled.
    pub fn fly<L: LoopEntry>(
        &self,
        req: &FlightRequest,
        trace: Option<&mut Trace>,
        planner: &mut FftPlanner<f64>,
    ) -> Option<Vec<LaneResult>> {
        self.fly_on::<L>(req, trace, planner)
    }

    /// Fly `lanes_per_set()` realisations at once on the widest SIMD lane type of this engine's
    /// instruction set (`self.isa`): the batch path. Every path gives bit-identical numbers.
    pub fn fly_set(
        &self,
        req: &FlightRequest,
        planner: &mut FftPlanner<f64>,
    ) -> Option<Vec<LaneResult>> {
        assert_eq!(
            req.indices.len(),
            self.lanes_per_set(),
            "one realisation index per lane"
        );
        // Each lane type below enters the loop compiled for its own instruction set
        // (`LoopEntry`), checked to run on this CPU.
        match (self.isa, self.fused) {
            (Isa::Baseline, _) => self.fly_on::<F64x4>(req, None, planner),
            #[cfg(target_arch = "x86_64")]
            (Isa::Avx2, false) => self.fly_on::<F64x4Avx>(req, None, planner),
            #[cfg(target_arch = "x86_64")]
            (Isa::Avx2, true) => self.fly_on::<F64x4Fma>(req, None, planner),
            #[cfg(target_arch = "x86_64")]
            (Isa::Avx512, false) => self.fly_on::<F64x8Avx512>(req, None, planner),
            #[cfg(target_arch = "x86_64")]
            (Isa::Avx512, true) => self.fly_on::<F64x8Fma512>(req, None, planner),
            #[cfg(not(target_arch = "x86_64"))]
            (Isa::Avx2 | Isa::Avx512, _) => unreachable!("{:?} off x86-64", self.isa),
        }
    }

    /// Enter the flight loop for lane type `L` (`LoopEntry`). Refuses, rather than risks an
    /// illegal instruction, a path the CPU cannot run.
    fn fly_on<L: LoopEntry>(
        &self,
        req: &FlightRequest,
        trace: Option<&mut Trace>,
        planner: &mut FftPlanner<f64>,
    ) -> Option<Vec<LaneResult>> {
        assert_eq!(
            req.indices.len(),
            L::LANES,
            "one realisation index per lane"
        );
        assert!(L::LANES <= MAX_LANES);
        self.fly_kinds::<L>(req, trace, planner)
    }

    flight_loop_for! {
        /// `fly_vehicle` compiled with AVX2 enabled. No FMA: see `lane/isa.rs`.
        fly_avx2, "avx2";
        /// `fly_vehicle` compiled with AVX2 and FMA enabled: the fused mode's AVX2 loop (only
        /// `Lane::mul_add` of `F64x4Fma` fuses; Rust never contracts the other operations).
        fly_avx2_fma, "avx2,fma";
        /// `fly_vehicle` compiled with AVX-512F and DQ enabled (this enables AVX2 too). No FMA in
        /// the default mode: the lane operations never fuse, whatever the enabled features.
        fly_avx512, "avx512f,avx512dq";
    }
}
