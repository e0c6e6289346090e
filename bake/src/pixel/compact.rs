//! Compaction of a group's dense rows (over every global slot J) to the slots that actually
//! carry light into the group ("active" slots): what the file stores.

use prt_formats::pixel::row_len;

/// Global slots j that appear with a nonzero value anywhere in the group's T1/T2 blocks.
pub(super) fn active_slots(
    rows: &[Vec<f32>],
    n0: usize,
    jn: usize,
    reflections: usize,
    c: usize,
) -> Vec<usize> {
    let mut used = vec![false; jn];
    for row in rows {
        let mut off = n0 * c; // skip T0
        let mut pow = jn;
        for depth in 1..reflections {
            let block = &row[off..off + n0 * pow * c];
            for (i, v) in block.iter().enumerate() {
                if *v != 0.0 {
                    // Decompose the element into its active indices.
                    let mut idx = (i / c) % pow;
                    for _ in 0..depth {
                        used[idx % jn] = true;
                        idx /= jn;
                    }
                }
            }
            off += n0 * pow * c;
            pow *= jn;
        }
    }
    (0..jn).filter(|&j| used[j]).collect()
}

/// Rewrites dense rows over all J slots into rows over the active slots only.
pub(super) fn compact_rows(
    rows: &[Vec<f32>],
    n0: usize,
    jn: usize,
    active: &[usize],
    reflections: usize,
    c: usize,
) -> (usize, Vec<f32>) {
    let ja = active.len();
    let len = row_len(n0, ja, reflections, c);
    let mut out = Vec::with_capacity(rows.len() * len);
    for row in rows {
        let mut src_off = 0usize;
        let mut src_pow = 1usize;
        let mut dst_pow = 1usize;
        for depth in 0..reflections {
            for b0 in 0..n0 {
                for idx in 0..dst_pow {
                    // Map the compact multi-index to the dense one.
                    let mut rest = idx;
                    let mut dense = 0usize;
                    let mut mul = 1usize;
                    for _ in 0..depth {
                        dense += active[rest % ja] * mul;
                        rest /= ja;
                        mul *= jn;
                    }
                    let e = (src_off + b0 * src_pow + dense) * c;
                    out.extend_from_slice(&row[e..e + c]);
                }
            }
            src_off += n0 * src_pow;
            src_pow *= jn;
            dst_pow *= ja;
        }
    }
    (len, out)
}
