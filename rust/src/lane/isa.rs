//! Which instruction set the hot loop runs on, chosen at run time.
//!
//! The flight loop (`Engine::fly`) is compiled twice from the same source: for baseline x86-64
//! (SSE2, what every wheel must run on) and with AVX2 enabled (`#[target_feature]`), and the
//! best one the CPU supports is used. FMA is deliberately not used: every lane operation stays a
//! single IEEE-754 operation, so both builds give bit-identical results (see `lane/mod.rs`), and a
//! realisation's numbers do not depend on the machine that flew it.
//!
//! `QUADRS_SIMD=baseline` (or `avx2`) in the environment forces a path, for benchmarks and
//! checks; a path the CPU lacks falls back to baseline.

use std::sync::OnceLock;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Isa {
    /// Whatever the crate was compiled for (SSE2 on a default x86-64 build; other targets).
    Baseline,
    /// x86-64 with AVX2 (256-bit vectors), checked at run time.
    Avx2,
}

impl Isa {
    pub fn name(self) -> &'static str {
        match self {
            Isa::Baseline => "baseline",
            Isa::Avx2 => "avx2",
        }
    }

    pub fn parse(name: &str) -> Option<Self> {
        match name.trim().to_ascii_lowercase().as_str() {
            "baseline" | "sse2" | "scalar" => Some(Isa::Baseline),
            "avx2" => Some(Isa::Avx2),
            _ => None,
        }
    }

    /// Whether this CPU can run the path.
    pub fn supported(self) -> bool {
        match self {
            Isa::Baseline => true,
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2 => std::arch::is_x86_feature_detected!("avx2"),
            #[cfg(not(target_arch = "x86_64"))]
            Isa::Avx2 => false,
        }
    }

    /// The best path this CPU supports.
    pub fn detect() -> Self {
        if Isa::Avx2.supported() {
            Isa::Avx2
        } else {
            Isa::Baseline
        }
    }

    /// The path new engines use: `QUADRS_SIMD` if set and supported, else `detect()`.
    /// Read once per process.
    pub fn active() -> Self {
        static ACTIVE: OnceLock<Isa> = OnceLock::new();
        *ACTIVE.get_or_init(|| {
            match std::env::var("QUADRS_SIMD")
                .ok()
                .as_deref()
                .and_then(Isa::parse)
            {
                Some(isa) if isa.supported() => isa,
                Some(_) => Isa::Baseline,
                None => Isa::detect(),
            }
        })
    }
}
