//! The runtime's in-memory layout of a group's stored values: tiles of [`TILE_PIXELS`]
//! consecutive pixels of the group, each tile holding all its values, column after column.
//!
//! The file stores a group element-major (`[E, P]`, pixels fastest), which a frame would read
//! as one short run of every column per block of pixels: up to ~100 interleaved streams,
//! served by the memory system at about two thirds of the rate of one stream on an idle
//! machine (`bench pixel`, "reads alone"). Tiled, a frame reads each group front to back.
//! The copy is made once, when the file is opened; it costs the transfer tensors' size in
//! memory beside the mapped file (whose pages the system may drop).

use rayon::prelude::*;

/// Pixels per tile: one 64-byte cache line of f32 values per column.
pub(crate) const TILE_PIXELS: usize = 16;

/// One group's values, tiled: value e of the group's pixel i at
/// `(i / TILE_PIXELS) * stride + e * TILE_PIXELS + i % TILE_PIXELS`, with
/// `stride = columns * TILE_PIXELS`; the last tile is padded with zeros.
pub(crate) struct Tiled<T> {
    pub(crate) values: Vec<T>,
    pub(crate) columns: usize,
}

impl<T: Copy + Default + Send + Sync> Tiled<T> {
    /// The tiled copy of element-major values (`t[e * pixels + i]`, `columns` x `pixels`).
    pub(crate) fn from_element_major(t: &[T], columns: usize, pixels: usize) -> Tiled<T> {
        debug_assert_eq!(t.len(), columns * pixels);
        let stride = columns * TILE_PIXELS;
        let tiles = pixels.div_ceil(TILE_PIXELS);
        let mut values = vec![T::default(); tiles * stride];
        if stride > 0 {
            values
                .par_chunks_mut(stride)
                .enumerate()
                .for_each(|(k, tile)| {
                    let i0 = k * TILE_PIXELS;
                    let n = TILE_PIXELS.min(pixels - i0);
                    for (e, dst) in tile.chunks_exact_mut(TILE_PIXELS).enumerate() {
                        dst[..n].copy_from_slice(&t[e * pixels + i0..e * pixels + i0 + n]);
                    }
                });
        }
        Tiled { values, columns }
    }

    /// Values between one tile's start and the next's.
    pub(crate) fn stride(&self) -> usize {
        self.columns * TILE_PIXELS
    }

    /// Value `e` of the group's pixel `i`.
    #[inline(always)]
    pub(crate) fn get(&self, e: usize, i: usize) -> T {
        self.values[(i / TILE_PIXELS) * self.stride() + e * TILE_PIXELS + i % TILE_PIXELS]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tiling_keeps_every_value_at_its_place_and_pads_with_zeros() {
        let (columns, pixels) = (5, 37);
        let t: Vec<f32> = (0..columns * pixels).map(|v| v as f32 + 1.0).collect();
        let tiled = Tiled::from_element_major(&t, columns, pixels);
        assert_eq!(tiled.values.len(), 3 * columns * TILE_PIXELS);
        for e in 0..columns {
            for i in 0..pixels {
                assert_eq!(tiled.get(e, i), t[e * pixels + i], "value {e} of pixel {i}");
            }
        }
        let stored: f32 = tiled.values.iter().sum();
        assert_eq!(stored, t.iter().sum::<f32>(), "padding holds zeros only");
    }
}
