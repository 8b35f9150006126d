//! Which instruction set the hot loop runs on, chosen at run time.
//!
//! The flight loop (`Engine::fly`) is compiled once per path from the same source: for baseline
//! x86-64 (SSE2, what every wheel must run on), with AVX2 enabled and with AVX-512F/DQ enabled
//! (`#[target_feature]`), and the best one the CPU supports is used. In the default (exact)
//! mode FMA is deliberately not used: every lane operation stays a single IEEE-754 operation,
//! so all paths give bit-identical results (see `lane/mod.rs`), and a realisation's numbers do
//! not depend on the machine that flew it. The opt-in fused mode (`Engine::with_fused`) trades
//! that for speed.
//!
//! `QUADRS_SIMD=baseline|avx2|avx512` in the environment forces a path, for benchmarks and
//! checks (`auto` or unset: the best supported one). Forcing a path this CPU cannot run, or
//! naming none of these, is an error naming the variable, never a fallback and never SIGILL.

use std::sync::OnceLock;

/// The environment variable that forces a path.
pub const ENV: &str = "QUADRS_SIMD";

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Isa {
    /// Whatever the crate was compiled for (SSE2 on a default x86-64 build; other targets).
    Baseline,
    /// x86-64 with AVX2 (256-bit vectors, four realisations per lane-set).
    Avx2,
    /// x86-64 with AVX-512F and AVX-512DQ (512-bit vectors, eight realisations per lane-set).
    Avx512,
}

impl Isa {
    /// Every path, narrowest first.
    pub const ALL: [Isa; 3] = [Isa::Baseline, Isa::Avx2, Isa::Avx512];

    pub fn name(self) -> &'static str {
        match self {
            Isa::Baseline => "baseline",
            Isa::Avx2 => "avx2",
            Isa::Avx512 => "avx512",
        }
    }

    pub fn parse(name: &str) -> Option<Self> {
        match name.trim().to_ascii_lowercase().as_str() {
            "baseline" | "sse2" | "scalar" => Some(Isa::Baseline),
            "avx2" => Some(Isa::Avx2),
            "avx512" | "avx-512" => Some(Isa::Avx512),
            _ => None,
        }
    }

    /// Whether this CPU can run the path.
    pub fn supported(self) -> bool {
        match self {
            Isa::Baseline => true,
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2 => std::arch::is_x86_feature_detected!("avx2"),
            #[cfg(target_arch = "x86_64")]
            Isa::Avx512 => {
                std::arch::is_x86_feature_detected!("avx512f")
                    && std::arch::is_x86_feature_detected!("avx512dq")
            }
            #[cfg(not(target_arch = "x86_64"))]
            Isa::Avx2 | Isa::Avx512 => false,
        }
    }

    /// Whether this CPU can run the path's fused mode (fused multiply-add on its vectors):
    /// AVX2 needs the FMA extension beside it, AVX-512F has it; baseline has none.
    pub fn fused_supported(self) -> bool {
        match self {
            Isa::Baseline => false,
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2 => self.supported() && std::arch::is_x86_feature_detected!("fma"),
            #[cfg(target_arch = "x86_64")]
            Isa::Avx512 => self.supported(),
            #[cfg(not(target_arch = "x86_64"))]
            Isa::Avx2 | Isa::Avx512 => false,
        }
    }

    /// Realisations per lane-set of the batch path (`Engine::fly_set`).
    pub fn lane_count(self) -> usize {
        match self {
            Isa::Avx512 => 8,
            Isa::Baseline | Isa::Avx2 => 4,
        }
    }

    /// The best path this CPU supports.
    pub fn detect() -> Self {
        *Isa::ALL
            .iter()
            .rev()
            .find(|isa| isa.supported())
            .unwrap_or(&Isa::Baseline)
    }

    /// The path `QUADRS_SIMD` asks for (`None`: unset, empty or `auto`), or why it cannot be.
    pub fn from_env_value(value: Option<&str>) -> Result<Option<Self>, String> {
        let Some(v) = value.map(str::trim).filter(|v| !v.is_empty()) else {
            return Ok(None);
        };
        if v.eq_ignore_ascii_case("auto") {
            return Ok(None);
        }
        let usable = || -> Vec<&str> {
            let ok = Isa::ALL.iter().filter(|i| i.supported());
            ok.map(|i| i.name()).collect()
        };
        let isa = Isa::parse(v).ok_or_else(|| {
            format!("{ENV}={v:?} is not a path: use one of auto, baseline, avx2, avx512")
        })?;
        if !isa.supported() {
            return Err(format!(
                "{ENV}={v:?} forces the {} path, which this CPU cannot run; it supports: {} \
                 (or unset {ENV})",
                isa.name(),
                usable().join(", ")
            ));
        }
        Ok(Some(isa))
    }

    /// The path new engines use: `QUADRS_SIMD` if set, else `detect()`; an error if
    /// `QUADRS_SIMD` names no path or one this CPU cannot run. Read once per process.
    pub fn active() -> Result<Self, String> {
        static ACTIVE: OnceLock<Result<Isa, String>> = OnceLock::new();
        ACTIVE
            .get_or_init(|| {
                let value = std::env::var(ENV).ok();
                Ok(Isa::from_env_value(value.as_deref())?.unwrap_or_else(Isa::detect))
            })
            .clone()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_override_is_parsed_and_refused_clearly() {
        assert_eq!(Isa::from_env_value(None), Ok(None));
        assert_eq!(Isa::from_env_value(Some(" auto ")), Ok(None));
        assert_eq!(Isa::from_env_value(Some("")), Ok(None));
        assert_eq!(
            Isa::from_env_value(Some("Baseline")),
            Ok(Some(Isa::Baseline))
        );
        let e = Isa::from_env_value(Some("avx9")).unwrap_err();
        assert!(e.contains("QUADRS_SIMD") && e.contains("avx9"), "{e}");
        for isa in Isa::ALL {
            match Isa::from_env_value(Some(isa.name())) {
                Ok(got) => assert!(isa.supported() && got == Some(isa)),
                Err(e) => {
                    assert!(!isa.supported());
                    assert!(e.contains("cannot run") && e.contains(isa.name()), "{e}");
                }
            }
        }
        assert!(Isa::detect().supported());
        assert!(Isa::ALL
            .iter()
            .all(|i| i.lane_count() <= crate::integrate::MAX_LANES));
    }
}
