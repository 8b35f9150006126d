//! The random-number kernels of the turbulence: ChaCha8's keystream many blocks at a time
//! ([`keystream`], hand-written AVX2 and AVX-512) and the ziggurat's standard normals in bulk
//! ([`normal`]). Beside the lane types because, like them, they are where the crate's `unsafe`
//! lives (every block with its `// SAFETY:` reason: `clippy::undocumented_unsafe_blocks` is
//! denied crate-wide); `gust/` draws through them and holds no `unsafe` of its own.

pub mod keystream;
pub mod normal;
