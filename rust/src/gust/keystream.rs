//! The keystream of a realisation's `ChaCha8Rng`, eight blocks at a time in AVX2, written
//! straight into the caller's buffer: the same `u64`s `fill_bytes` gives, from the same
//! generator state, without rand_chacha's copy out of its own buffer (about 13 instructions
//! per word against 16 with the copy: docs/performance.md, "Third step").
//!
//! Hand-written because no maintained crate offers it: rand_chacha (through ppv-lite86) lays
//! four blocks out row-wise, two to a vector, which costs shuffles every round and a copy on
//! every `fill_bytes`. Here the layout is column-wise: one vector per state word, one lane per
//! block (eight consecutive blocks of one stream), so a round is only additions, xors and
//! rotations, and one transpose at the end puts the words in stream order. The arithmetic is
//! ChaCha's (RFC 8439 section 2.3, eight rounds) on rand_chacha's state: key = the seed's
//! eight little-endian words, words 12-13 the 64-bit block counter (wrapping), words 14-15 the
//! stream. `wide_matches_fill_bytes` holds it to rand_chacha.

use crate::lane::isa::Isa;
use rand::Rng;
use rand_chacha::ChaCha8Rng;

/// `u64`s one wide call writes: eight 64-byte blocks.
pub const WIDE: usize = 64;

/// `u32` words of one ChaCha block.
#[cfg(target_arch = "x86_64")]
const BLOCK_WORDS: u128 = 16;

/// Fill a prefix of `dst` with the next `u64`s of `rng`'s stream, advancing it past them, and
/// return the prefix's length. On AVX2 (`isa` not the baseline; AVX-512 CPUs have it too):
/// the words up to the next block boundary, then as many whole groups of [`WIDE`] as fit, so
/// only that head goes through rand_chacha's buffer; else all of `dst` through `fill_bytes`.
pub fn fill(rng: &mut ChaCha8Rng, dst: &mut [u64], isa: Isa) -> usize {
    #[cfg(target_arch = "x86_64")]
    if isa != Isa::Baseline {
        let at = rng.get_word_pos();
        let head = ((BLOCK_WORDS - at % BLOCK_WORDS) % BLOCK_WORDS / 2) as usize;
        let n = if at.is_multiple_of(2) && head + WIDE <= dst.len() {
            head + (dst.len() - head) / WIDE * WIDE
        } else {
            dst.len()
        };
        // SAFETY: AVX2 is available (`isa` is AVX2 or AVX-512).
        unsafe { fill_wide(rng, &mut dst[..n]) };
        return n;
    }
    let _ = isa;
    fill_from(rng, dst);
    dst.len()
}

/// Fill `dst` with the next `u64`s of `rng`'s stream and advance it past them, exactly as
/// `rng.fill_bytes` on `dst`'s bytes would: up to the next block boundary through `rng`, then
/// whole groups of eight blocks by the wide kernel, the rest through `rng` again.
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
pub unsafe fn fill_wide(rng: &mut ChaCha8Rng, dst: &mut [u64]) {
    let at = rng.get_word_pos();
    // A stream read a `u32` at a time can sit between two `u64`s of the block grid: then
    // it all goes through `rng` (StandardNormal never does that, so this never runs).
    if !at.is_multiple_of(2) {
        return fill_from(rng, dst);
    }
    let head = (((BLOCK_WORDS - at % BLOCK_WORDS) % BLOCK_WORDS) / 2) as usize;
    let head = head.min(dst.len());
    fill_from(rng, &mut dst[..head]);
    let groups = (dst.len() - head) / WIDE;
    if groups > 0 {
        let (key, stream) = (key_words(&rng.get_seed()), rng.get_stream());
        let start = at + 2 * head as u128;
        let first = (start / BLOCK_WORDS) as u64;
        for (g, out) in dst[head..head + groups * WIDE]
            .chunks_exact_mut(WIDE)
            .enumerate()
        {
            let out: &mut [u64; WIDE] = out.try_into().expect("WIDE words");
            // SAFETY: AVX2 is available (this function's contract).
            unsafe { blocks8(&key, stream, first.wrapping_add(8 * g as u64), out) };
        }
        rng.set_word_pos(start + (groups * WIDE) as u128 * 2);
    }
    fill_from(rng, &mut dst[head + groups * WIDE..]);
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

/// Blocks `block..block + 8` (wrapping) of the keystream `(key, stream)` as `u64`s in stream
/// order (each the little-endian pair of consecutive `u32` words).
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn blocks8(key: &[u32; 8], stream: u64, block: u64, out: &mut [u64; WIDE]) {
    use std::arch::x86_64::*;
    let splat = |w: u32| _mm256_set1_epi32(w as i32);
    let counter = |shift: u32| {
        let c: [u32; 8] = std::array::from_fn(|k| (block.wrapping_add(k as u64) >> shift) as u32);
        // SAFETY: `c` holds eight u32.
        unsafe { _mm256_loadu_si256(c.as_ptr().cast()) }
    };
    let init: [__m256i; 16] = [
        splat(0x6170_7865),
        splat(0x3320_646e),
        splat(0x7962_2d32),
        splat(0x6b20_6574),
        splat(key[0]),
        splat(key[1]),
        splat(key[2]),
        splat(key[3]),
        splat(key[4]),
        splat(key[5]),
        splat(key[6]),
        splat(key[7]),
        counter(0),
        counter(32),
        splat(stream as u32),
        splat((stream >> 32) as u32),
    ];
    // Byte shuffles that rotate every u32 left by 16 and by 8.
    let rot16 = _mm256_setr_epi8(
        2, 3, 0, 1, 6, 7, 4, 5, 10, 11, 8, 9, 14, 15, 12, 13, 2, 3, 0, 1, 6, 7, 4, 5, 10, 11, 8, 9,
        14, 15, 12, 13,
    );
    let rot8 = _mm256_setr_epi8(
        3, 0, 1, 2, 7, 4, 5, 6, 11, 8, 9, 10, 15, 12, 13, 14, 3, 0, 1, 2, 7, 4, 5, 6, 11, 8, 9, 10,
        15, 12, 13, 14,
    );
    let mut x = init;
    macro_rules! quarter {
        ($a:literal, $b:literal, $c:literal, $d:literal) => {
            x[$a] = _mm256_add_epi32(x[$a], x[$b]);
            x[$d] = _mm256_shuffle_epi8(_mm256_xor_si256(x[$d], x[$a]), rot16);
            x[$c] = _mm256_add_epi32(x[$c], x[$d]);
            let t = _mm256_xor_si256(x[$b], x[$c]);
            x[$b] = _mm256_or_si256(_mm256_slli_epi32::<12>(t), _mm256_srli_epi32::<20>(t));
            x[$a] = _mm256_add_epi32(x[$a], x[$b]);
            x[$d] = _mm256_shuffle_epi8(_mm256_xor_si256(x[$d], x[$a]), rot8);
            x[$c] = _mm256_add_epi32(x[$c], x[$d]);
            let t = _mm256_xor_si256(x[$b], x[$c]);
            x[$b] = _mm256_or_si256(_mm256_slli_epi32::<7>(t), _mm256_srli_epi32::<25>(t));
        };
    }
    // ChaCha8: four double rounds (columns, then diagonals).
    for _ in 0..4 {
        quarter!(0, 4, 8, 12);
        quarter!(1, 5, 9, 13);
        quarter!(2, 6, 10, 14);
        quarter!(3, 7, 11, 15);
        quarter!(0, 5, 10, 15);
        quarter!(1, 6, 11, 12);
        quarter!(2, 7, 8, 13);
        quarter!(3, 4, 9, 14);
    }
    for (x, i) in x.iter_mut().zip(init) {
        *x = _mm256_add_epi32(*x, i);
    }
    // Two 8 x 8 transposes (state words 0-7 and 8-15, one lane per block) to blocks in order.
    let dst = out.as_mut_ptr().cast::<__m256i>();
    for half in 0..2 {
        let r = &x[8 * half..8 * half + 8];
        let t: [__m256i; 8] = std::array::from_fn(|k| {
            let (a, b) = (r[2 * (k / 2)], r[2 * (k / 2) + 1]);
            if k % 2 == 0 {
                _mm256_unpacklo_epi32(a, b)
            } else {
                _mm256_unpackhi_epi32(a, b)
            }
        });
        // u[j]: words 4q..4q+4 of blocks j (low half) and j + 4 (high half), q = 0, 1.
        let u: [[__m256i; 2]; 4] = std::array::from_fn(|j| {
            std::array::from_fn(|q| {
                let (a, b) = (t[4 * q + j / 2], t[4 * q + 2 + j / 2]);
                if j % 2 == 0 {
                    _mm256_unpacklo_epi64(a, b)
                } else {
                    _mm256_unpackhi_epi64(a, b)
                }
            })
        });
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

#[cfg(all(test, target_arch = "x86_64"))]
mod tests {
    use super::*;
    use crate::gust::realisation_rng;
    use rand::SeedableRng;

    #[test]
    fn wide_matches_fill_bytes() {
        if !std::arch::is_x86_feature_detected!("avx2") {
            return;
        }
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
                for len in [0, 1, 7, 63, 64, 65, 128, 200, 300] {
                    let (mut a, mut b) = (start.clone(), start.clone());
                    for _ in 0..skip {
                        assert_eq!(a.next_u32(), b.next_u32());
                    }
                    let mut got = vec![0u64; len];
                    // SAFETY: AVX2 checked above.
                    unsafe { fill_wide(&mut a, &mut got) };
                    let mut bytes = vec![0u8; 8 * len];
                    b.fill_bytes(&mut bytes);
                    for (k, (g, w)) in got.iter().zip(bytes.chunks_exact(8)).enumerate() {
                        let w = u64::from_le_bytes(w.try_into().unwrap());
                        assert_eq!(*g, w, "skip {skip} len {len} word {k}");
                    }
                    assert_eq!(a.get_word_pos(), b.get_word_pos(), "skip {skip} len {len}");
                    assert_eq!(a.next_u64(), b.next_u64(), "left in step");
                }
            }
        }
    }
}
