//! The keystream of a realisation's `ChaCha8Rng`, eight blocks at a time in AVX2 and sixteen
//! in AVX-512, written straight into the caller's buffer: the same `u64`s `fill_bytes` gives,
//! from the same generator state, without rand_chacha's copy out of its own buffer (the
//! kernels take 10.5 and 4.2 instructions per word: docs/performance.md, "Third step" and
//! "Fourth step").
//!
//! Hand-written because no maintained crate offers it: rand_chacha (through ppv-lite86) lays
//! four blocks out row-wise, two to a vector, which costs shuffles every round and a copy on
//! every `fill_bytes`. Here the layout is column-wise: one vector per state word, one lane per
//! block (consecutive blocks of one stream), so a round is only additions, xors and
//! rotations, and one transpose at the end puts the words in stream order. The arithmetic is
//! ChaCha's (RFC 8439 section 2.3, eight rounds) on rand_chacha's state: key = the seed's
//! eight little-endian words, words 12-13 the 64-bit block counter (wrapping), words 14-15 the
//! stream. `wide_matches_fill_bytes` holds each kernel the CPU has to rand_chacha;
//! `scripts/emulated_kernels.py` runs both in an emulated AVX-512 CPU against RFC 8439.

use crate::lane::isa::Isa;
use rand::Rng;
use rand_chacha::ChaCha8Rng;

/// `u64`s one group of the wide keystream holds at most (sixteen 64-byte blocks, AVX-512);
/// AVX2 groups are half as long.
pub const WIDE: usize = 128;

/// `u32` words of one ChaCha block.
#[cfg(target_arch = "x86_64")]
const BLOCK_WORDS: u128 = 16;

/// Fill a prefix of `dst` with the next `u64`s of `rng`'s stream, advancing it past them, and
/// return the prefix's length. On AVX2 and AVX-512 (`isa` not the baseline): the words up to
/// the next block boundary, then as many whole groups of the wide keystream as fit (eight
/// blocks on AVX2, sixteen on AVX-512), so only that head goes through rand_chacha's buffer;
/// else all of `dst` through `fill_bytes`.
pub fn fill(rng: &mut ChaCha8Rng, dst: &mut [u64], isa: Isa) -> usize {
    #[cfg(target_arch = "x86_64")]
    if let Some(kernel) = Kernel::of(isa) {
        let group = kernel.words();
        let at = rng.get_word_pos();
        let head = ((BLOCK_WORDS - at % BLOCK_WORDS) % BLOCK_WORDS / 2) as usize;
        let n = if at.is_multiple_of(2) && head + group <= dst.len() {
            head + (dst.len() - head) / group * group
        } else {
            dst.len()
        };
        // SAFETY: the CPU has the kernel's instruction set (`isa` is the caller's, supported).
        unsafe { fill_wide(rng, &mut dst[..n], kernel) };
        return n;
    }
    let _ = isa;
    fill_from(rng, dst);
    dst.len()
}

/// A wide keystream kernel: ChaCha8 blocks column-wise, one vector lane per block.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kernel {
    /// Eight blocks per call in 256-bit vectors (`blocks8`).
    Avx2,
    /// Sixteen blocks per call in 512-bit vectors with one-instruction rotations (`blocks16`).
    Avx512,
}

#[cfg(target_arch = "x86_64")]
impl Kernel {
    /// The kernel of the instruction set `isa` (none on the baseline).
    pub fn of(isa: Isa) -> Option<Kernel> {
        match isa {
            Isa::Baseline => None,
            Isa::Avx2 => Some(Kernel::Avx2),
            Isa::Avx512 => Some(Kernel::Avx512),
        }
    }

    /// `u64`s one call writes.
    pub fn words(self) -> usize {
        match self {
            Kernel::Avx2 => WIDE / 2,
            Kernel::Avx512 => WIDE,
        }
    }
}

/// Fill `dst` with the next `u64`s of `rng`'s stream and advance it past them, exactly as
/// `rng.fill_bytes` on `dst`'s bytes would: up to the next block boundary through `rng`, then
/// whole groups of blocks by `kernel`, the rest through `rng` again.
///
/// # Safety
/// The CPU must support AVX2, and AVX-512F for `Kernel::Avx512`.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
pub unsafe fn fill_wide(rng: &mut ChaCha8Rng, dst: &mut [u64], kernel: Kernel) {
    let at = rng.get_word_pos();
    // A stream read a `u32` at a time can sit between two `u64`s of the block grid: then
    // it all goes through `rng` (StandardNormal never does that, so this never runs).
    if !at.is_multiple_of(2) {
        return fill_from(rng, dst);
    }
    let head = (((BLOCK_WORDS - at % BLOCK_WORDS) % BLOCK_WORDS) / 2) as usize;
    let head = head.min(dst.len());
    fill_from(rng, &mut dst[..head]);
    let group = kernel.words();
    let groups = (dst.len() - head) / group;
    if groups > 0 {
        let (key, stream) = (key_words(&rng.get_seed()), rng.get_stream());
        let start = at + 2 * head as u128;
        let first = (start / BLOCK_WORDS) as u64;
        let blocks = group as u64 / 8;
        for (g, out) in dst[head..head + groups * group]
            .chunks_exact_mut(group)
            .enumerate()
        {
            let block = first.wrapping_add(blocks * g as u64);
            // SAFETY: the CPU has the kernel's instruction set (this function's contract);
            // `out` holds the kernel's words.
            unsafe {
                match kernel {
                    Kernel::Avx2 => blocks8(&key, stream, block, out.as_mut_ptr().cast()),
                    Kernel::Avx512 => blocks16(&key, stream, block, out.as_mut_ptr().cast()),
                }
            }
        }
        rng.set_word_pos(start + (groups * group) as u128 * 2);
    }
    fill_from(rng, &mut dst[head + groups * group..]);
}

/// `dst`'s `u64`s through `rng.fill_bytes` (the little-endian bytes of `next_u64`'s words).
fn fill_from(rng: &mut ChaCha8Rng, dst: &mut [u64]) {
    if dst.is_empty() {
        return;
    }
    let mut bytes = [0u8; 8 * WIDE];
    for part in dst.chunks_mut(WIDE) {
        let b = &mut bytes[..8 * part.len()];
        rng.fill_bytes(b);
        for (w, b) in part.iter_mut().zip(b.chunks_exact(8)) {
            *w = u64::from_le_bytes(b.try_into().expect("8 bytes"));
        }
    }
}

/// The seed as ChaCha's eight key words.
#[cfg(target_arch = "x86_64")]
fn key_words(seed: &[u8; 32]) -> [u32; 8] {
    std::array::from_fn(|i| u32::from_le_bytes(seed[4 * i..4 * i + 4].try_into().expect("4")))
}

/// One ChaCha quarter round on state words `a, b, c, d` of `$x` (literals, so the state stays
/// in registers), with the operations of `chacha8_columns!`.
#[cfg(target_arch = "x86_64")]
macro_rules! quarter {
    ($x:ident, $add:path, $xor:path, $rotate:ident; $a:literal, $b:literal, $c:literal, $d:literal) => {
        $x[$a] = $add($x[$a], $x[$b]);
        $x[$d] = $rotate!($xor($x[$d], $x[$a]), 16);
        $x[$c] = $add($x[$c], $x[$d]);
        $x[$b] = $rotate!($xor($x[$b], $x[$c]), 12);
        $x[$a] = $add($x[$a], $x[$b]);
        $x[$d] = $rotate!($xor($x[$d], $x[$a]), 8);
        $x[$c] = $add($x[$c], $x[$d]);
        $x[$b] = $rotate!($xor($x[$b], $x[$c]), 7);
    };
}

/// The keystream state of blocks `block..block + $lanes` column-wise (one vector per state
/// word, one lane per block) after ChaCha8's four double rounds and the feed-forward, in the
/// vector type of the operations given: `$splat`, `$load` (unaligned), `$add` (u32 lanes),
/// `$xor`, and `$rotate!(v, n)` (every u32 left by `n`). A macro, not a generic function,
/// because each kernel must be compiled whole for its own instruction set.
#[cfg(target_arch = "x86_64")]
macro_rules! chacha8_columns {
    ($lanes:literal, $key:expr, $stream:expr, $block:expr; $zero:path, $splat:path,
     $load:path, $add:path, $xor:path, $rotate:ident) => {{
        // No closures: they would not be inlined into the kernel.
        let mut init = [$zero(); 16];
        for (v, w) in init.iter_mut().zip(state_words($key, $stream)) {
            *v = $splat(w as i32);
        }
        let [lo, hi] = counters::<$lanes>($block);
        // SAFETY: `lo` and `hi` hold one u32 per lane.
        (init[12], init[13]) = unsafe { ($load(lo.as_ptr().cast()), $load(hi.as_ptr().cast())) };
        let mut x = init;
        // Four double rounds: columns, then diagonals.
        for _ in 0..4 {
            quarter!(x, $add, $xor, $rotate; 0, 4, 8, 12);
            quarter!(x, $add, $xor, $rotate; 1, 5, 9, 13);
            quarter!(x, $add, $xor, $rotate; 2, 6, 10, 14);
            quarter!(x, $add, $xor, $rotate; 3, 7, 11, 15);
            quarter!(x, $add, $xor, $rotate; 0, 5, 10, 15);
            quarter!(x, $add, $xor, $rotate; 1, 6, 11, 12);
            quarter!(x, $add, $xor, $rotate; 2, 7, 8, 13);
            quarter!(x, $add, $xor, $rotate; 3, 4, 9, 14);
        }
        for (x, i) in x.iter_mut().zip(init) {
            *x = $add(*x, i);
        }
        x
    }};
}

/// Words `w0..w0 + 4 * $groups` of a column-wise state `$x`, interleaved within each 128-bit
/// lane (blocks 4g..4g + 4 of lane g): `u[j][q]` holds, in lane g, words w0 + 4q..w0 + 4q + 4
/// of block 4g + j. Two rounds of unpacking: word pairs, then pairs of pairs.
#[cfg(target_arch = "x86_64")]
macro_rules! interleave {
    ($x:expr, $groups:literal; $zero:path, $lo32:path, $hi32:path, $lo64:path, $hi64:path) => {{
        let x = $x;
        let mut t = [$zero(); 2 * $groups * 2];
        for (k, t) in t.iter_mut().enumerate() {
            let (a, b) = (x[2 * (k / 2)], x[2 * (k / 2) + 1]);
            *t = if k % 2 == 0 { $lo32(a, b) } else { $hi32(a, b) };
        }
        let mut u = [[$zero(); $groups]; 4];
        for (j, u) in u.iter_mut().enumerate() {
            for (q, u) in u.iter_mut().enumerate() {
                let (a, b) = (t[4 * q + j / 2], t[4 * q + 2 + j / 2]);
                *u = if j % 2 == 0 { $lo64(a, b) } else { $hi64(a, b) };
            }
        }
        u
    }};
}

/// `vpshufb` for the byte rotations, shifts and an or for the others.
#[cfg(target_arch = "x86_64")]
macro_rules! rotate_avx2 {
    ($v:expr, 16) => {
        rotate_bytes($v, &ROTATE_16)
    };
    ($v:expr, 8) => {
        rotate_bytes($v, &ROTATE_8)
    };
    ($v:expr, $n:literal) => {{
        let v = $v;
        _mm256_or_si256(
            _mm256_slli_epi32::<$n>(v),
            _mm256_srli_epi32::<{ 32 - $n }>(v),
        )
    }};
}

/// `vprold`.
#[cfg(target_arch = "x86_64")]
macro_rules! rotate_avx512 {
    ($v:expr, $n:literal) => {
        _mm512_rol_epi32::<$n>($v)
    };
}

/// Blocks `block..block + 8` (wrapping) of the keystream `(key, stream)` as `u64`s in stream
/// order (each the little-endian pair of consecutive `u32` words). A C-ABI leaf (no calls),
/// so `scripts/emulated_kernels.py` can run it in an emulated CPU beside `blocks16`.
///
/// # Safety
/// The CPU must support AVX2; `out` must be valid for 64 `u64` writes.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline(never)]
unsafe extern "C" fn blocks8(key: &[u32; 8], stream: u64, block: u64, out: *mut [u64; 64]) {
    use std::arch::x86_64::*;
    let x = chacha8_columns!(8, key, stream, block; _mm256_setzero_si256, _mm256_set1_epi32,
        _mm256_loadu_si256, _mm256_add_epi32, _mm256_xor_si256, rotate_avx2);
    // State words 0-7, then 8-15 (fewer vectors live at once).
    let dst = out.cast::<__m256i>();
    for half in 0..2 {
        let u = interleave!(&x[8 * half..8 * half + 8], 2; _mm256_setzero_si256,
            _mm256_unpacklo_epi32, _mm256_unpackhi_epi32, _mm256_unpacklo_epi64,
            _mm256_unpackhi_epi64);
        // u[j]: this half's words of blocks j (low 128 bits) and j + 4 (high).
        for (j, [lo, hi]) in u.into_iter().enumerate() {
            // SAFETY: block `j` (and `j + 4`) spans vectors 2j, 2j + 1 (2j + 8, 2j + 9) of
            // `out`'s sixteen; this half is the first (second) of them.
            unsafe {
                _mm256_storeu_si256(
                    dst.add(2 * j + half),
                    _mm256_permute2x128_si256::<0x20>(lo, hi),
                );
                _mm256_storeu_si256(
                    dst.add(2 * (j + 4) + half),
                    _mm256_permute2x128_si256::<0x31>(lo, hi),
                );
            }
        }
    }
}

/// Blocks `block..block + 16` (wrapping) of the keystream `(key, stream)` as `u64`s in stream
/// order: `blocks8`'s arithmetic in 512-bit vectors, where a rotation is one instruction
/// (`vprold`) and the sixteen state vectors leave room for the temporaries (no spills). A
/// C-ABI leaf like `blocks8`: `scripts/emulated_kernels.py` holds it to `blocks8` and to
/// RFC 8439 in an emulated AVX-512 CPU where this one has none.
///
/// # Safety
/// The CPU must support AVX-512F; `out` must be valid for 128 `u64` writes.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
#[inline(never)]
unsafe extern "C" fn blocks16(key: &[u32; 8], stream: u64, block: u64, out: *mut [u64; 128]) {
    use std::arch::x86_64::*;
    let x = chacha8_columns!(16, key, stream, block; _mm512_setzero_si512, _mm512_set1_epi32,
        _mm512_loadu_si512, _mm512_add_epi32, _mm512_xor_si512, rotate_avx512);
    let u = interleave!(&x, 4; _mm512_setzero_si512, _mm512_unpacklo_epi32,
        _mm512_unpackhi_epi32, _mm512_unpacklo_epi64, _mm512_unpackhi_epi64);
    // Then, for each j, the 4 x 4 transpose of 128-bit lanes across u[j]: block 4g + j is
    // lane g of u[j][0], u[j][1], u[j][2], u[j][3].
    let dst = out.cast::<__m512i>();
    for (j, [u0, u1, u2, u3]) in u.into_iter().enumerate() {
        // Lanes (0, 2) and (1, 3) of each pair.
        let a = _mm512_shuffle_i32x4::<0x88>(u0, u1);
        let b = _mm512_shuffle_i32x4::<0xdd>(u0, u1);
        let c = _mm512_shuffle_i32x4::<0x88>(u2, u3);
        let d = _mm512_shuffle_i32x4::<0xdd>(u2, u3);
        let blocks = [
            _mm512_shuffle_i32x4::<0x88>(a, c),
            _mm512_shuffle_i32x4::<0x88>(b, d),
            _mm512_shuffle_i32x4::<0xdd>(a, c),
            _mm512_shuffle_i32x4::<0xdd>(b, d),
        ];
        for (g, v) in blocks.into_iter().enumerate() {
            // SAFETY: block 4g + j is vector 4g + j of `out`'s sixteen.
            unsafe { _mm512_storeu_si512(dst.add(4 * g + j), v) };
        }
    }
}

/// The block counter's low and high words for blocks `block..block + N` (wrapping).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn counters<const N: usize>(block: u64) -> [[u32; N]; 2] {
    let (mut lo, mut hi) = ([0u32; N], [0u32; N]);
    for (k, (lo, hi)) in lo.iter_mut().zip(hi.iter_mut()).enumerate() {
        let b = block.wrapping_add(k as u64);
        (*lo, *hi) = (b as u32, (b >> 32) as u32);
    }
    [lo, hi]
}

/// ChaCha's sixteen state words for `(key, stream)` with the block counter (words 12, 13)
/// zero: the constant "expand 32-byte k", the key, the counter, the stream.
#[cfg(target_arch = "x86_64")]
fn state_words(key: &[u32; 8], stream: u64) -> [u32; 16] {
    let mut w = [0u32; 16];
    w[..4].copy_from_slice(&[0x6170_7865, 0x3320_646e, 0x7962_2d32, 0x6b20_6574]);
    w[4..12].copy_from_slice(key);
    w[14] = stream as u32;
    w[15] = (stream >> 32) as u32;
    w
}

/// Byte shuffles that rotate every `u32` left by 16 and by 8.
#[cfg(target_arch = "x86_64")]
static ROTATE_16: Shuffle = Shuffle([
    2, 3, 0, 1, 6, 7, 4, 5, 10, 11, 8, 9, 14, 15, 12, 13, 2, 3, 0, 1, 6, 7, 4, 5, 10, 11, 8, 9, 14,
    15, 12, 13,
]);
#[cfg(target_arch = "x86_64")]
static ROTATE_8: Shuffle = Shuffle([
    3, 0, 1, 2, 7, 4, 5, 6, 11, 8, 9, 10, 15, 12, 13, 14, 3, 0, 1, 2, 7, 4, 5, 6, 11, 8, 9, 10, 15,
    12, 13, 14,
]);

/// A `vpshufb` control, aligned for a memory operand.
#[cfg(target_arch = "x86_64")]
#[repr(C, align(32))]
struct Shuffle([u8; 32]);

/// `_mm256_shuffle_epi8(x, by)` as exactly one `vpshufb` with `by` read from memory. Written
/// out because LLVM otherwise moves the shuffle through the xor before it (two shuffles for
/// one), splits the rotation by 16 into two word shuffles, and keeps both controls in
/// registers the sixteen state vectors need (docs/performance.md, "Fourth step").
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn rotate_bytes(x: std::arch::x86_64::__m256i, by: &Shuffle) -> std::arch::x86_64::__m256i {
    let out;
    // SAFETY: AVX2 is available (this function's contract); `by` is 32 readable bytes.
    unsafe {
        std::arch::asm!(
            "vpshufb {out}, {x}, ymmword ptr [{by}]",
            out = lateout(ymm_reg) out,
            x = in(ymm_reg) x,
            by = in(reg) by.0.as_ptr(),
            options(pure, readonly, nostack, preserves_flags),
        );
    }
    out
}

#[cfg(all(test, target_arch = "x86_64"))]
mod tests {
    use super::*;
    use crate::gust::realisation_rng;
    use rand::SeedableRng;

    #[test]
    fn wide_matches_fill_bytes() {
        // Each kernel this CPU can run (`scripts/emulated_kernels.py` runs both where it
        // cannot).
        let kernels = Isa::ALL
            .into_iter()
            .filter(|i| i.supported())
            .filter_map(Kernel::of);
        for kernel in kernels {
            wide_kernel_matches_fill_bytes(kernel);
        }
    }

    fn wide_kernel_matches_fill_bytes(kernel: Kernel) {
        // Several seeds and streams, every offset within a block (even and odd u32
        // positions), lengths around the group size, and a block counter that wraps.
        let mut starts: Vec<ChaCha8Rng> = Vec::new();
        for (seed, stream) in [(0, 0), (9, 1), (4, u64::MAX), (123_456, 77)] {
            starts.push(realisation_rng(seed, stream));
        }
        let mut near_wrap = ChaCha8Rng::seed_from_u64(5);
        near_wrap.set_stream(3);
        near_wrap.set_word_pos(u128::from(u64::MAX - 20) * BLOCK_WORDS);
        starts.push(near_wrap);
        for start in starts {
            for skip in 0..40u32 {
                for len in [0, 1, 7, 63, 64, 65, 127, 128, 129, 200, 300] {
                    let (mut a, mut b) = (start.clone(), start.clone());
                    for _ in 0..skip {
                        assert_eq!(a.next_u32(), b.next_u32());
                    }
                    let mut got = vec![0u64; len];
                    // SAFETY: the kernel's instruction set is supported (checked by the caller).
                    unsafe { fill_wide(&mut a, &mut got, kernel) };
                    let mut bytes = vec![0u8; 8 * len];
                    b.fill_bytes(&mut bytes);
                    for (k, (g, w)) in got.iter().zip(bytes.chunks_exact(8)).enumerate() {
                        let w = u64::from_le_bytes(w.try_into().unwrap());
                        assert_eq!(*g, w, "{kernel:?} skip {skip} len {len} word {k}");
                    }
                    assert_eq!(a.get_word_pos(), b.get_word_pos(), "skip {skip} len {len}");
                    assert_eq!(a.next_u64(), b.next_u64(), "left in step");
                }
            }
        }
    }
}
