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
/// stored value once; `simd` allows the vector kernel.
pub(crate) fn tiles_f32(
    cols: &[Column<'_, f32>],
    i0: usize,
    init: [f32; 3],
    simd: bool,
    acc: &mut [Vec<f32>; 3],
) {
    #[cfg(target_arch = "x86_64")]
    if simd && std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU supports AVX2 (checked just above).
        unsafe { x86::tiles_f32(cols, i0, init, acc) };
        return;
    }
    let _ = simd;
    tiles_portable(cols, i0, 0, init, acc, |v| v);
}

/// [`tiles_f32`] over f16 values (converted as they are read).
pub(crate) fn tiles_f16(
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
        unsafe { x86::tiles_f16(cols, i0, init, acc) };
        return;
    }
    let _ = simd;
    tiles_portable(cols, i0, 0, init, acc, f16::to_f32);
}

/// The portable kernel from pixel `from` of the block on (the vector kernels leave it the
/// pixels past their last whole tile).
#[inline(always)]
fn tiles_portable<T: Copy>(
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
        _mm256_set1_ps, _mm256_storeu_ps, _mm_loadu_si128, _mm_prefetch, _MM_HINT_T0,
    };

    use half::f16;

    use crate::contract::{tiles_portable, Column, PREFETCH_LINES};

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
    pub(super) unsafe fn tiles_f32(
        cols: &[Column<'_, f32>],
        i0: usize,
        init: [f32; 3],
        acc: &mut [Vec<f32>; 3],
    ) {
        // SAFETY (the closure): the slice holds TILE f32 values, two registers' worth.
        let from = tiles(cols, i0, init, acc, |s: &[f32]| unsafe {
            [
                _mm256_loadu_ps(s.as_ptr()),
                _mm256_loadu_ps(s.as_ptr().add(8)),
            ]
        });
        tiles_portable(cols, i0, from, init, acc, |v| v);
    }

    #[target_feature(enable = "avx2,f16c")]
    pub(super) unsafe fn tiles_f16(
        cols: &[Column<'_, f16>],
        i0: usize,
        init: [f32; 3],
        acc: &mut [Vec<f32>; 3],
    ) {
        // SAFETY (the closure): the slice holds TILE f16 values (32 bytes); unaligned loads.
        let from = tiles(cols, i0, init, acc, |s: &[f16]| unsafe {
            let p = s.as_ptr() as *const __m128i;
            [
                _mm256_cvtph_ps(_mm_loadu_si128(p)),
                _mm256_cvtph_ps(_mm_loadu_si128(p.add(1))),
            ]
        });
        tiles_portable(cols, i0, from, init, acc, f16::to_f32);
    }

    /// The whole tiles of the block; returns where the portable tail starts.
    #[inline(always)]
    unsafe fn tiles<T>(
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
