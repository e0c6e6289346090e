//! The inner loops of the per-pixel relight: a block of a group's pixels, contracted with
//! every stored element's weights.
//!
//! A group stores its values element-major (value e of pixel i at `e * pixels + i`), so a
//! block reads one short run of every column. Each kernel keeps a tile of pixels' three
//! channels in registers while all the columns are added, and writes the tile once. The
//! per-lane arithmetic is the same everywhere (a multiply, then an add, in term order, no
//! fused multiply-add), so the portable and the vector kernels give the same bits.

use half::f16;

/// One column of a group's stored values (pixel i's value at index i) and its weight per
/// output channel.
pub(crate) type Column<'a, T> = (&'a [T], [f32; 3]);

/// Pixels per tile of the portable kernel (its three accumulators stay in registers).
const TILE: usize = 8;
/// How many cache lines ahead of the current tile each column is prefetched.
const PREFETCH_LINES: usize = 8;

/// `acc[c][k] = init[c] + sum_cols w[c] * col[i0 + k]` for k < acc[0].len(), reading each
/// stored value once; `simd` allows the vector kernel. With `READS_ONLY`, the same values are
/// read in the same order but only summed, unweighted, into `acc[0]` (a measurement of what
/// the memory traffic alone costs, see `Relighter::time_reads`).
pub(crate) fn tiles_f32<const READS_ONLY: bool>(
    cols: &[Column<'_, f32>],
    i0: usize,
    init: [f32; 3],
    simd: bool,
    acc: &mut [Vec<f32>; 3],
) {
    #[cfg(target_arch = "x86_64")]
    if simd && std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU supports AVX2 (checked just above).
        unsafe { x86::tiles_f32::<READS_ONLY>(cols, i0, init, acc) };
        return;
    }
    let _ = simd;
    tiles_portable::<_, READS_ONLY>(cols, i0, 0, init, acc, |v| v);
}

/// [`tiles_f32`] over f16 values (converted as they are read).
pub(crate) fn tiles_f16<const READS_ONLY: bool>(
    cols: &[Column<'_, f16>],
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
        unsafe { x86::tiles_f16::<READS_ONLY>(cols, i0, init, acc) };
        return;
    }
    let _ = simd;
    tiles_portable::<_, READS_ONLY>(cols, i0, 0, init, acc, f16::to_f32);
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

/// The portable kernel from pixel `from` of the block on (the vector kernels leave it the
/// pixels past their last whole tile).
#[inline(always)]
fn tiles_portable<T: Copy, const READS_ONLY: bool>(
    cols: &[Column<'_, T>],
    i0: usize,
    from: usize,
    init: [f32; 3],
    acc: &mut [Vec<f32>; 3],
    one: impl Fn(T) -> f32,
) {
    let n = acc[0].len();
    let full = from + (n - from) / TILE * TILE;
    let mut k = from;
    while k < full {
        let mut r = [[init[0]; TILE], [init[1]; TILE], [init[2]; TILE]];
        for (col, w) in cols {
            for (l, &v) in col[i0 + k..i0 + k + TILE].iter().enumerate() {
                let x = one(v);
                if READS_ONLY {
                    r[0][l] += x;
                    continue;
                }
                r[0][l] += w[0] * x;
                r[1][l] += w[1] * x;
                r[2][l] += w[2] * x;
            }
        }
        for (c, rc) in r.iter().enumerate() {
            acc[c][k..k + TILE].copy_from_slice(rc);
        }
        k += TILE;
    }
    for k in full..n {
        let mut r = init;
        for (col, w) in cols {
            let x = one(col[i0 + k]);
            if READS_ONLY {
                r[0] += x;
                continue;
            }
            r[0] += w[0] * x;
            r[1] += w[1] * x;
            r[2] += w[2] * x;
        }
        for (a, v) in acc.iter_mut().zip(r) {
            a[k] = v;
        }
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

    use crate::contract::{add_run_portable, tiles_portable, Column, PREFETCH_LINES};

    /// Pixels per tile: two registers per channel, so six independent add chains hide the
    /// add latency.
    const TILE: usize = 16;
    /// Columns per pass over a block. A pass reads 8 columns' long runs (a block's pixels)
    /// and keeps the tile's running sums in the block's accumulators between passes (stored
    /// and reloaded as f32, so the sums are the same bits): 10-15 % faster per frame than
    /// all columns in one pass, whose ~100 interleaved streams the memory system served
    /// worse.
    const CHUNK: usize = 8;

    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn tiles_f32<const READS_ONLY: bool>(
        cols: &[Column<'_, f32>],
        i0: usize,
        init: [f32; 3],
        acc: &mut [Vec<f32>; 3],
    ) {
        // SAFETY (the closure): the slice holds TILE f32 values, two registers' worth.
        let from = tiles::<_, READS_ONLY>(cols, i0, init, acc, |s: &[f32]| unsafe {
            [
                _mm256_loadu_ps(s.as_ptr()),
                _mm256_loadu_ps(s.as_ptr().add(8)),
            ]
        });
        tiles_portable::<_, READS_ONLY>(cols, i0, from, init, acc, |v| v);
    }

    #[target_feature(enable = "avx2,f16c")]
    pub(super) unsafe fn tiles_f16<const READS_ONLY: bool>(
        cols: &[Column<'_, f16>],
        i0: usize,
        init: [f32; 3],
        acc: &mut [Vec<f32>; 3],
    ) {
        // SAFETY (the closure): the slice holds TILE f16 values (32 bytes); unaligned loads.
        let from = tiles::<_, READS_ONLY>(cols, i0, init, acc, |s: &[f16]| unsafe {
            let p = s.as_ptr() as *const __m128i;
            [
                _mm256_cvtph_ps(_mm_loadu_si128(p)),
                _mm256_cvtph_ps(_mm_loadu_si128(p.add(1))),
            ]
        });
        tiles_portable::<_, READS_ONLY>(cols, i0, from, init, acc, f16::to_f32);
    }

    /// [`crate::contract::stream_out`]: plain stores up to the first 32-byte boundary of
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

    /// [`crate::contract::add_run`] eight pixels at a time: the three channel vectors are
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

    /// The whole tiles of the block; returns where the portable tail starts.
    #[inline(always)]
    unsafe fn tiles<T, const READS_ONLY: bool>(
        cols: &[Column<'_, T>],
        i0: usize,
        init: [f32; 3],
        acc: &mut [Vec<f32>; 3],
        load: impl Fn(&[T]) -> [__m256; 2],
    ) -> usize {
        let n = acc[0].len();
        let full = n - n % TILE;
        // Values per 64-byte cache line. The columns lie far apart (one per stored element),
        // so each column's line PREFETCH_LINES ahead is asked for explicitly, once per line:
        // without it the loads waited on memory for 80 % of a frame (and still cost 1.4x
        // with the passes of CHUNK columns).
        let line = (64 / std::mem::size_of::<T>()).max(TILE);
        if cols.is_empty() {
            for (a, v) in acc.iter_mut().zip(init) {
                a[..full].fill(v);
            }
        }
        for (pass, chunk) in cols.chunks(CHUNK).enumerate() {
            let mut k = 0;
            while k < full {
                if k % line == 0 {
                    for (col, _) in chunk {
                        // A prefetch is only a hint and never faults, so an address past the
                        // column's end is harmless.
                        let p = col.as_ptr().wrapping_add(i0 + k + PREFETCH_LINES * line);
                        _mm_prefetch::<_MM_HINT_T0>(p as *const i8);
                    }
                }
                let mut r = if pass == 0 {
                    init.map(|v| [_mm256_set1_ps(v); 2])
                } else {
                    let mut r = [[_mm256_set1_ps(0.0); 2]; 3];
                    for (rc, a) in r.iter_mut().zip(acc.iter()) {
                        let src = &a[k..k + TILE];
                        *rc = [
                            _mm256_loadu_ps(src.as_ptr()),
                            _mm256_loadu_ps(src.as_ptr().add(8)),
                        ];
                    }
                    r
                };
                for (col, w) in chunk {
                    let x = load(&col[i0 + k..i0 + k + TILE]);
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
                for (a, rc) in acc.iter_mut().zip(&r) {
                    let out = &mut a[k..k + TILE];
                    _mm256_storeu_ps(out.as_mut_ptr(), rc[0]);
                    _mm256_storeu_ps(out.as_mut_ptr().add(8), rc[1]);
                }
                k += TILE;
            }
        }
        full
    }
}
