//! Accumulation of one pixel's paths into its dense transfer rows (T0, T1, T2 over all global
//! slots), one row per material the pixel's samples see first.

use glam::Vec3;
use prt_formats::pixel::row_len;

use crate::integrator::{PathSink, Slots, Surface};

use super::layout::SlotLayout;

/// Accumulates one pixel's tensors, one dense row per visible material, over all slots J.
pub(super) struct TensorSink<'a> {
    layout: &'a SlotLayout,
    inv_tint: Vec3,
    reflections: usize,
    /// (material, row) for the materials this pixel's samples saw first.
    pub(super) rows: Vec<(u32, Vec<f32>)>,
    pub(super) current: Option<usize>,
    pub(super) emission: Vec3,
}

impl<'a> TensorSink<'a> {
    pub(super) fn new(layout: &'a SlotLayout, reflections: usize) -> Self {
        TensorSink {
            layout,
            inv_tint: Vec3::ONE / layout.tint,
            reflections,
            rows: Vec::new(),
            current: None,
            emission: Vec3::ZERO,
        }
    }
}

impl PathSink for TensorSink<'_> {
    fn camera_emission(&mut self, radiance: Vec3) {
        if radiance.is_finite() {
            self.emission += radiance;
        }
    }

    fn first_hit(&mut self, s: &Surface) {
        let n0 = self.layout.materials[s.material as usize].slots.len();
        if n0 == 0 {
            self.current = None;
            return;
        }
        let idx = match self.rows.iter().position(|(m, _)| *m == s.material) {
            Some(i) => i,
            None => {
                let len = row_len(
                    n0,
                    self.layout.total_slots,
                    self.reflections,
                    self.layout.channels,
                );
                self.rows.push((s.material, vec![0.0; len]));
                self.rows.len() - 1
            }
        };
        self.current = Some(idx);
    }

    fn path(&mut self, prefix: &[Slots], last: &Slots, weight: Vec3) {
        let Some(row_idx) = self.current else {
            return;
        };
        let k = prefix.len();
        let c = self.layout.channels;
        let jn = self.layout.total_slots;
        let mats = &self.layout.materials;
        let row = &mut self.rows[row_idx].1;
        let v0 = if k == 0 { last } else { &prefix[0] };
        let n0 = v0.len;
        // Offset of the depth-k block.
        let mut off = 0usize;
        let mut pow = 1usize;
        for _ in 0..k {
            off += n0 * pow;
            pow *= jn;
        }
        // Vertices after the first, in path order.
        let mut chain: [&Slots; 4] = [last; 4];
        for (i, s) in prefix.iter().skip(1).enumerate() {
            chain[i] = s;
        }
        chain[k.saturating_sub(1)] = last;
        let chain = &chain[..k];
        if chain.iter().any(|v| v.len == 0) {
            // A vertex on a material without slots (black) reflects nothing.
            return;
        }
        // Enumerate every slot combination along the chain (j1 fastest).
        let mut choice = [0usize; 4];
        loop {
            let mut val = weight;
            let mut idx = 0usize;
            let mut mul = 1usize;
            for (d, v) in chain.iter().enumerate() {
                val *= v.values[choice[d]];
                idx += (mats[v.material as usize].slot_offset as usize + choice[d]) * mul;
                mul *= jn;
            }
            if val != Vec3::ZERO && val.is_finite() {
                for b0 in 0..n0 {
                    let x = val * v0.values[b0] * self.inv_tint;
                    let e = (off + b0 * pow + idx) * c;
                    if c == 1 {
                        row[e] += x.x;
                    } else {
                        row[e] += x.x;
                        row[e + 1] += x.y;
                        row[e + 2] += x.z;
                    }
                }
            }
            // Next combination.
            let mut d = 0;
            loop {
                if d == k {
                    return;
                }
                choice[d] += 1;
                if choice[d] < chain[d].len {
                    break;
                }
                choice[d] = 0;
                d += 1;
            }
        }
    }
}
