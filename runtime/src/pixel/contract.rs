//! The inner loops of the per-pixel relight: a block of a group's pixels, contracted with
//! every stored element's weights.
//!
//! A group's values are tiled in memory (`tiled.rs`: 16 pixels' values, column after column),
//! so a block reads its group front to back. Each kernel keeps a tile of pixels' three
//! channels in registers while all the columns are added, and writes the tile once. The
//! per-lane arithmetic is the same everywhere (a multiply, then an add, in term order, no
//! fused multiply-add), so the portable and the vector kernels give the same bits.

use half::f16;

use super::tiled::Tiled;

/// A column (stored element, or low-rank component) of a group with a nonzero weight: its
/// index and its weight per output channel.
pub(crate) type Column = (usize, [f32; 3]);

/// Pixels per tile of the portable kernel (its three accumulators stay in registers).
const TILE: usize = 8;

/// `acc[c][k] = init[c] + sum_cols w[c] * value(col, i0 + k)` for k < acc[0].len(), reading
/// each stored value once; `simd` allows the vector kernel. With `READS_ONLY`, the same values
/// are read in the same order but only summed, unweighted, into `acc[0]` (a measurement of
/// what the memory traffic alone costs, see `PixelRelighter::time_reads`).
pub(crate) fn tiles_f32<const READS_ONLY: bool>(
    values: &Tiled<f32>,
    cols: &[Column],
    i0: usize,
    init: [f32; 3],
    simd: bool,
    acc: &mut [Vec<f32>; 3],
) {
    #[cfg(target_arch = "x86_64")]
    if simd && std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU supports AVX2 (checked just above).
        unsafe { x86::tiles_f32::<READS_ONLY>(values, cols, i0, init, acc) };
        return;
    }
    let _ = simd;
    let n = acc[0].len();
    tiles_portable::<_, READS_ONLY>(values, cols, i0, 0..n, init, acc, |v| v);
}

/// [`tiles_f32`] over f16 values (converted as they are read).
pub(crate) fn tiles_f16<const READS_ONLY: bool>(
    values: &Tiled<f16>,
    cols: &[Column],
    i0: usize,
    init: [f32; 3],
    simd: bool,
    acc: &mut [Vec<f32>; 3],
) {
    #[cfg(target_arch = "x86_64")]
    if simd
        && std::arch::is_x86_feature_detected!("avx2")
        && std::arch::is_x86_feature_detected!("f16c")
    {
        // SAFETY: the CPU supports AVX2 and F16C (checked just above).
        unsafe { x86::tiles_f16::<READS_ONLY>(values, cols, i0, init, acc) };
        return;
    }
    let _ = simd;
    let n = acc[0].len();
    tiles_portable::<_, READS_ONLY>(values, cols, i0, 0..n, init, acc, f16::to_f32);
}

/// Adds pixels `k..k + out.len()` of a block's channel-major sums `acc` to a stretch of
/// consecutive image pixels; `simd` allows the vector code (the same additions).
pub(crate) fn add_run(out: &mut [[f32; 3]], acc: &[Vec<f32>; 3], k: usize, simd: bool) {
    let n = out.len();
    let [a0, a1, a2] = acc.each_ref().map(|a| &a[k..k + n]);
    #[cfg(target_arch = "x86_64")]
    if simd && std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU supports AVX2 (checked just above).
        unsafe { x86::add_run(out, a0, a1, a2) };
        return;
    }
    let _ = simd;
    add_run_portable(out, a0, a1, a2);
}

/// Copies a finished band to the frame (`dst.len() == src.len()`). With `simd`, with
/// non-temporal stores: the frame's lines are written without first being read from memory
/// and without displacing the cache (the same values, so the same bits).
pub(crate) fn stream_out(dst: &mut [f32], src: &[f32], simd: bool) {
    #[cfg(target_arch = "x86_64")]
    if simd && std::arch::is_x86_feature_detected!("avx") {
        // SAFETY: the CPU supports AVX (checked just above).
        unsafe { x86::stream_out(dst, src) };
        return;
    }
    let _ = simd;
    dst.copy_from_slice(src);
}

fn add_run_portable(out: &mut [[f32; 3]], a0: &[f32], a1: &[f32], a2: &[f32]) {
    for (o, ((r, g), b)) in out.iter_mut().zip(a0.iter().zip(a1).zip(a2)) {
        *o = [o[0] + r, o[1] + g, o[2] + b];
    }
}

/// The portable kernel over the block's pixels `range` (block-relative).
#[inline(always)]
fn tiles_portable<T: Copy + Default + Send + Sync, const READS_ONLY: bool>(
    values: &Tiled<T>,
    cols: &[Column],
    i0: usize,
    range: std::ops::Range<usize>,
    init: [f32; 3],
    acc: &mut [Vec<f32>; 3],
    one: impl Fn(T) -> f32,
) {
    let mut k = range.start;
    while k < range.end {
        let n = TILE.min(range.end - k);
        let [mut r0, mut r1, mut r2] = init.map(|v| [v; TILE]);
        for &(e, w) in cols {
            for (l, ((a0, a1), a2)) in r0.iter_mut().zip(&mut r1).zip(&mut r2).take(n).enumerate() {
                let x = one(values.get(e, i0 + k + l));
                if READS_ONLY {
                    *a0 += x;
                    continue;
                }
                *a0 += w[0] * x;
                *a1 += w[1] * x;
                *a2 += w[2] * x;
            }
        }
        let r = [r0, r1, r2];
        for (c, rc) in r.iter().enumerate() {
            acc[c][k..k + n].copy_from_slice(&rc[..n]);
        }
        k += n;
    }
}

/// The AVX2 kernels: a tile of 16 pixels is six 8-lane accumulators, written as intrinsics
/// because the compiler spilled the same loop written over arrays to the stack.
#[cfg(target_arch = "x86_64")]
mod x86 {
    use std::arch::x86_64::{
        __m128i, __m256, _mm256_add_ps, _mm256_cvtph_ps, _mm256_loadu_ps, _mm256_mul_ps,
        _mm256_permute2f128_ps, _mm256_set1_ps, _mm256_shuffle_ps, _mm256_storeu_ps,
        _mm256_stream_ps, _mm_loadu_si128, _mm_prefetch, _mm_sfence, _MM_HINT_T0,
    };

    use half::f16;

    use crate::pixel::contract::{add_run_portable, Column};
    use crate::pixel::tiled::{Tiled, TILE_PIXELS};

    /// Pixels per tile: two registers per channel, so six independent add chains hide the
    /// add latency.
    const TILE: usize = 16;
    const _: () = assert!(TILE == TILE_PIXELS, "a vector tile is a stored tile");
    /// How far ahead of each load its line is prefetched: the hardware's prefetchers alone
    /// left the loads waiting on memory for most of a frame.
    const PREFETCH_BYTES: usize = 8192;

    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn tiles_f32<const READS_ONLY: bool>(
        values: &Tiled<f32>,
        cols: &[Column],
        i0: usize,
        init: [f32; 3],
        acc: &mut [Vec<f32>; 3],
    ) {
        // SAFETY (the closure): the pointer starts TILE f32 values inside the tiled copy.
        tiles::<_, READS_ONLY>(values, cols, i0, init, acc, |p: *const f32| unsafe {
            [_mm256_loadu_ps(p), _mm256_loadu_ps(p.add(8))]
        });
    }

    #[target_feature(enable = "avx2,f16c")]
    pub(super) unsafe fn tiles_f16<const READS_ONLY: bool>(
        values: &Tiled<f16>,
        cols: &[Column],
        i0: usize,
        init: [f32; 3],
        acc: &mut [Vec<f32>; 3],
    ) {
        // SAFETY (the closure): the pointer starts TILE f16 values (32 bytes) inside the
        // tiled copy; unaligned loads.
        tiles::<_, READS_ONLY>(values, cols, i0, init, acc, |p: *const f16| unsafe {
            let p = p as *const __m128i;
            [
                _mm256_cvtph_ps(_mm_loadu_si128(p)),
                _mm256_cvtph_ps(_mm_loadu_si128(p.add(1))),
            ]
        });
    }

    /// Every stored tile the block's pixels `i0..i0 + acc[0].len()` touch. A tile only
    /// partly in the block (a group's pixels in a band start and end anywhere in a tile) is
    /// computed whole, its lanes outside the block dropped: handing those pixels to the
    /// portable kernel instead made cornell's frames 9 % (1024 x 1024) to 27 % (512 x 512)
    /// slower.
    #[inline(always)]
    unsafe fn tiles<T: Copy + Default + Send + Sync, const READS_ONLY: bool>(
        values: &Tiled<T>,
        cols: &[Column],
        i0: usize,
        init: [f32; 3],
        acc: &mut [Vec<f32>; 3],
        load: impl Fn(*const T) -> [__m256; 2],
    ) {
        let i1 = i0 + acc[0].len();
        let stride = values.stride();
        let base = values.values.as_ptr();
        for t in i0 / TILE..i1.div_ceil(TILE) {
            // SAFETY: tile t holds pixel i1 - 1 or an earlier one of the group, so it exists
            // and its stride values lie inside `values`.
            let tile = base.add(t * stride);
            let mut r = init.map(|v| [_mm256_set1_ps(v); 2]);
            for &(e, w) in cols {
                let p = tile.add(e * TILE);
                // A prefetch is only a hint and never faults, so an address past the end is
                // harmless.
                _mm_prefetch::<_MM_HINT_T0>(p.wrapping_byte_add(PREFETCH_BYTES) as *const i8);
                let x = load(p);
                if READS_ONLY {
                    r[0][0] = _mm256_add_ps(r[0][0], x[0]);
                    r[0][1] = _mm256_add_ps(r[0][1], x[1]);
                    continue;
                }
                for (c, rc) in r.iter_mut().enumerate() {
                    let wc = _mm256_set1_ps(w[c]);
                    rc[0] = _mm256_add_ps(rc[0], _mm256_mul_ps(wc, x[0]));
                    rc[1] = _mm256_add_ps(rc[1], _mm256_mul_ps(wc, x[1]));
                }
            }
            // The tile's pixels inside the block, as lanes of the tile.
            let (from, to) = ((t * TILE).max(i0), (t * TILE + TILE).min(i1));
            let lanes = from - t * TILE..to - t * TILE;
            let k = from - i0;
            for (a, rc) in acc.iter_mut().zip(&r) {
                if lanes.len() == TILE {
                    let out = &mut a[k..k + TILE];
                    _mm256_storeu_ps(out.as_mut_ptr(), rc[0]);
                    _mm256_storeu_ps(out.as_mut_ptr().add(8), rc[1]);
                } else {
                    let mut lane = [0.0f32; TILE];
                    _mm256_storeu_ps(lane.as_mut_ptr(), rc[0]);
                    _mm256_storeu_ps(lane.as_mut_ptr().add(8), rc[1]);
                    a[k..k + lanes.len()].copy_from_slice(&lane[lanes.clone()]);
                }
            }
        }
    }

    /// [`super::stream_out`]: plain stores up to the first 32-byte boundary of
    /// `dst`, then aligned non-temporal stores of eight values, then the tail; a fence at the
    /// end, so the frame is complete in memory order before the band's task returns.
    #[target_feature(enable = "avx")]
    pub(super) unsafe fn stream_out(dst: &mut [f32], src: &[f32]) {
        assert_eq!(dst.len(), src.len(), "a band and its copy");
        let head = dst.as_ptr().align_offset(32).min(dst.len());
        dst[..head].copy_from_slice(&src[..head]);
        let body = (dst.len() - head) / 8 * 8;
        for k in (head..head + body).step_by(8) {
            // SAFETY: k + 8 <= dst.len() (body is whole groups of eight after head), and
            // dst + k is 32-byte aligned (head aligns it, and k - head is a multiple of 8).
            _mm256_stream_ps(
                dst.as_mut_ptr().add(k),
                _mm256_loadu_ps(src.as_ptr().add(k)),
            );
        }
        dst[head + body..].copy_from_slice(&src[head + body..]);
        _mm_sfence();
    }

    /// [`super::add_run`] eight pixels at a time: the three channel vectors are
    /// interleaved into the image's layout (r g b r g b ...) by shuffles, then added to it.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn add_run(out: &mut [[f32; 3]], a0: &[f32], a1: &[f32], a2: &[f32]) {
        let full = out.len() / 8 * 8;
        for (k, o) in out[..full].chunks_exact_mut(8).enumerate() {
            let (x, y, z) = (
                _mm256_loadu_ps(a0[8 * k..8 * k + 8].as_ptr()),
                _mm256_loadu_ps(a1[8 * k..8 * k + 8].as_ptr()),
                _mm256_loadu_ps(a2[8 * k..8 * k + 8].as_ptr()),
            );
            // Per 128-bit half (pixels 0-3 and 4-7), then the halves recombined.
            let xy = _mm256_shuffle_ps::<0b10_00_10_00>(x, y); // x0 x2 y0 y2
            let yz = _mm256_shuffle_ps::<0b11_01_11_01>(y, z); // y1 y3 z1 z3
            let zx = _mm256_shuffle_ps::<0b11_01_10_00>(z, x); // z0 z2 x1 x3
            let r03 = _mm256_shuffle_ps::<0b10_00_10_00>(xy, zx); // x0 y0 z0 x1
            let r14 = _mm256_shuffle_ps::<0b11_01_10_00>(yz, xy); // y1 z1 x2 y2
            let r25 = _mm256_shuffle_ps::<0b11_01_11_01>(zx, yz); // z2 x3 y3 z3
            let m = [
                _mm256_permute2f128_ps::<0x20>(r03, r14),
                _mm256_permute2f128_ps::<0x30>(r25, r03),
                _mm256_permute2f128_ps::<0x31>(r14, r25),
            ];
            let flat = o.as_flattened_mut();
            for (j, mj) in m.into_iter().enumerate() {
                let dst = &mut flat[8 * j..8 * j + 8];
                let sum = _mm256_add_ps(_mm256_loadu_ps(dst.as_ptr()), mj);
                _mm256_storeu_ps(dst.as_mut_ptr(), sum);
            }
        }
        add_run_portable(&mut out[full..], &a0[full..], &a1[full..], &a2[full..]);
    }
}
