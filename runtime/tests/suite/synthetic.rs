//! Synthetic per-pixel bake files written with the container writer alone (no baker), and an
//! independent f64 relighting of them: the runtime's kernels, bands, blocks, f16 scaling and
//! low-rank path are checked against a plain sum, and its validation against one corruption
//! at a time.

use half::f16;
use prt_formats::basis::{BrdfBasis, GridSpec, ParamWarp, BASIS_SCHEMA_VERSION};
use prt_formats::pixel::{
    group_weights, names, row_len, slot_coefficients, BakeStats, BasisMeta, CameraMeta, GroupMeta,
    MaterialMeta, MaterialParams, PixelBakeMeta, Precision, SlotKind, PIXEL_SCHEMA_VERSION,
};
use prt_formats::{BakeWriter, Family};

/// Image size of [`Synthetic::new`]: more pixels than one band of 8 rows, with a width that is
/// not a multiple of a tile (bands of more than one contraction block of 1024 pixels are
/// [`Synthetic::spans`]' job).
pub const W: u32 = 37;
pub const H: u32 = 23;
pub const REFLECTIONS: u32 = 2;

/// A small deterministic generator for test data (values only; the project's sampler is not
/// under test here).
pub struct Lcg(u64);

impl Lcg {
    pub fn new(seed: u64) -> Lcg {
        Lcg(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1)
    }
    /// Uniform in [lo, hi).
    pub fn uniform(&mut self, lo: f32, hi: f32) -> f32 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let u = (self.0 >> 40) as f32 / (1u64 << 24) as f32;
        lo + (hi - lo) * u
    }
}

/// One group's stored data.
#[derive(Clone)]
pub struct Group {
    pub meta: GroupMeta,
    pub pixels: Vec<u32>,
    /// Element-major `[row_len, pixels]`.
    pub transfer: Vec<f32>,
    /// `(mean [row_len], components [k, row_len], weights [k, pixels])`.
    pub compressed: Option<(Vec<f32>, Vec<f32>, Vec<f32>)>,
}

/// A synthetic bake: metadata and tensors, editable before writing.
#[derive(Clone)]
pub struct Synthetic {
    /// Width and height the data were made for (the metadata's may be corrupted by a test).
    pub size: (u32, u32),
    pub meta: PixelBakeMeta,
    pub emission: Vec<f32>,
    pub groups: Vec<Group>,
    /// The precision the metadata states, when it should contradict the stored tensors.
    pub stated_precision: Option<Precision>,
}

fn material(
    name: &str,
    editable: bool,
    family: Family,
    slots: Vec<SlotKind>,
    offset: u32,
    basis: Option<u32>,
    param: f32,
) -> MaterialMeta {
    MaterialMeta {
        name: name.to_string(),
        editable,
        family,
        kd: [0.5, 0.4, 0.3],
        ks: [0.3, 0.35, 0.4],
        param,
        textured: false,
        slots,
        slot_offset: offset,
        basis,
    }
}

/// A GGX basis of three functions sampled at three roughnesses (only its coefficient table
/// matters to relighting).
fn basis() -> BrdfBasis {
    let grid = GridSpec::DEFAULT;
    BrdfBasis {
        version: BASIS_SCHEMA_VERSION,
        family: Family::Ggx,
        method: "synthetic".to_string(),
        param_range: [0.05, 0.8],
        param_warp: ParamWarp::Linear,
        param_samples: vec![0.05, 0.3, 0.8],
        grid: grid.dims,
        grid_kind: grid.kind,
        num_bases: 3,
        tables: Vec::new(),
        coefficients: vec![
            1.0, 0.9, -0.3, //
            1.0, 0.5, 0.2, //
            1.0, 0.1, 0.6,
        ],
    }
}

impl Synthetic {
    /// Three materials (fixed Lambert, editable Lambert, editable GGX with a basis), five
    /// global slots, `channels` 1 or 3, one group per material over interleaved pixel sets
    /// (the GGX group spans every band; a pixel may be in no group), optionally low-rank.
    pub fn new(channels: u32, compressed_rank: Option<u32>, seed: u64) -> Synthetic {
        let npix = W * H;
        let sets = [
            (0..npix).filter(|p| p % 3 == 0).collect(),
            (0..npix).filter(|p| p % 3 == 1).collect(),
            (0..npix).filter(|p| p % 3 == 2 && p % 7 != 0).collect(),
        ];
        Synthetic::with_pixels(W, H, sets, channels, compressed_rank, seed)
    }

    /// A gray bake of `width` x `height` whose groups are long runs of consecutive pixels:
    /// the wall's spans of 140 pixels per row (more than a block of a band, when a band has
    /// more than 1024), the paint's row ends plus two whole rows (one run across a band's
    /// edge), and the metal on every seventh pixel, overlapping both.
    pub fn spans(width: u32, height: u32, seed: u64) -> Synthetic {
        let npix = width * height;
        let (x, row) = (|p: &u32| p % width, |p: &u32| p / width);
        let sets = [
            (0..npix)
                .filter(|p| x(p) < 140 && !matches!(row(p), 15 | 16))
                .collect(),
            (0..npix)
                .filter(|p| x(p) >= 140 || matches!(row(p), 15 | 16))
                .collect(),
            (0..npix).filter(|p| p % 7 == 0).collect(),
        ];
        Synthetic::with_pixels(width, height, sets, 1, None, seed)
    }

    /// The three materials of [`Synthetic::new`] with the given pixel sets (ascending), one
    /// group each.
    fn with_pixels(
        width: u32,
        height: u32,
        sets: [Vec<u32>; 3],
        channels: u32,
        compressed_rank: Option<u32>,
        seed: u64,
    ) -> Synthetic {
        let materials = vec![
            material(
                "wall",
                false,
                Family::Diffuse,
                vec![SlotKind::Kd],
                0,
                None,
                0.0,
            ),
            material(
                "paint",
                true,
                Family::Diffuse,
                vec![SlotKind::Kd],
                1,
                None,
                0.0,
            ),
            material(
                "metal",
                true,
                Family::Ggx,
                vec![SlotKind::Basis(0), SlotKind::Basis(1), SlotKind::Basis(2)],
                2,
                Some(0),
                0.3,
            ),
        ];
        let mut rng = Lcg::new(seed);
        let npix = (width * height) as usize;
        let emission: Vec<f32> = (0..npix * 3).map(|_| rng.uniform(0.0, 0.2)).collect();
        // Per material, its active global slots.
        let active: [Vec<u32>; 3] = [vec![0, 1, 2, 3, 4], vec![1, 3], vec![0, 2, 4]];
        let groups = sets
            .into_iter()
            .zip(active)
            .zip(0u32..)
            .map(|((pixels, active), m)| {
                let slots = materials[m as usize].slots.len();
                let len = row_len(slots, active.len(), REFLECTIONS as usize, channels as usize);
                let p = pixels.len();
                let transfer: Vec<f32> = (0..len * p).map(|_| rng.uniform(-0.2, 1.0)).collect();
                let compressed = compressed_rank.map(|k| {
                    let k = k as usize;
                    (
                        (0..len).map(|_| rng.uniform(0.0, 0.5)).collect(),
                        (0..k * len).map(|_| rng.uniform(-0.5, 0.5)).collect(),
                        (0..k * p).map(|_| rng.uniform(-1.0, 1.0)).collect(),
                    )
                });
                Group {
                    meta: GroupMeta {
                        material: m,
                        pixels: p as u32,
                        slots: slots as u32,
                        active,
                        row_len: len as u32,
                        compressed_rank,
                        scale: 1.0,
                    },
                    pixels,
                    transfer,
                    compressed,
                }
            })
            .collect();
        Synthetic {
            size: (width, height),
            meta: PixelBakeMeta {
                pixel_schema_version: PIXEL_SCHEMA_VERSION,
                width,
                height,
                spp: 1,
                emission_oversampling: Some(8),
                reflections: REFLECTIONS,
                seed,
                channels,
                tint: [1.0, 0.9, 0.8],
                precision: Precision::F32,
                materials,
                bases: vec![BasisMeta { basis: basis() }],
                groups: Vec::new(),
                camera: CameraMeta {
                    position: [0.0, 0.0, 1.0],
                    forward: [0.0, 0.0, -1.0],
                    up: [0.0, 1.0, 0.0],
                    yfov: 0.7,
                },
                stats: BakeStats {
                    rays: 0,
                    dense_values: 0,
                    stored_values: 0,
                    allocation: Vec::new(),
                    triangles: 0,
                },
            },
            emission,
            groups,
            stated_precision: None,
        }
    }

    /// Writes the bake to `path`, f32 or f16 (with a per-group scale, as the baker does).
    pub fn write(&self, path: &std::path::Path, precision: Precision) {
        let mut meta = self.meta.clone();
        meta.precision = precision;
        meta.groups = self.groups.iter().map(|g| g.meta.clone()).collect();
        let halves: Vec<(Vec<f16>, f32)> = self
            .groups
            .iter()
            .map(|g| {
                let max = g.transfer.iter().fold(0.0f32, |m, v| m.max(v.abs()));
                let scale = if max > 0.0 { max / 16384.0 } else { 1.0 };
                (
                    g.transfer
                        .iter()
                        .map(|v| f16::from_f32(v / scale))
                        .collect(),
                    scale,
                )
            })
            .collect();
        if precision == Precision::F16 {
            for (gm, (_, scale)) in meta.groups.iter_mut().zip(&halves) {
                gm.scale = *scale;
            }
        }
        let mut w = BakeWriter::new();
        // The emission's shape is its own (the size it was made for), whatever the metadata
        // says.
        w.add_f32(
            names::EMISSION,
            &[self.size.1 as usize, self.size.0 as usize, 3],
            &self.emission,
        )
        .expect("emission");
        for (i, g) in self.groups.iter().enumerate() {
            // Shapes from the data, so a corrupted `row_len` in the metadata stays corrupt.
            let p = g.pixels.len();
            let len = g.transfer.len() / p.max(1);
            w.add_u32(&names::pixels(i), &[p], &g.pixels)
                .expect("pixels");
            match precision {
                Precision::F32 => w.add_f32(&names::transfer(i), &[len, p], &g.transfer),
                Precision::F16 => w.add_f16(&names::transfer(i), &[len, p], &halves[i].0),
            }
            .expect("transfer");
            if let Some((mean, comps, z)) = &g.compressed {
                let k = z.len() / p.max(1);
                w.add_f32(&names::mean(i), &[len], mean).expect("mean");
                w.add_f32(&names::components(i), &[k, len], comps)
                    .expect("components");
                w.add_f32(&names::weights(i), &[k, p], z).expect("weights");
            }
        }
        if let Some(p) = self.stated_precision {
            meta.precision = p;
        }
        w.set_metadata(meta.to_json());
        w.write_atomic(path).expect("write synthetic bake");
    }

    /// Coefficients of every global slot for `params` (one per material), computed here from
    /// the basis table by linear interpolation in the parameter.
    pub fn coefficients(&self, params: &[MaterialParams]) -> Vec<[f32; 3]> {
        let b = &self.meta.bases[0].basis;
        let mut out = Vec::new();
        for (m, p) in self.meta.materials.iter().zip(params) {
            let lobe: Vec<f32> = match m.basis {
                Some(_) => {
                    let ps = &b.param_samples;
                    let x = p.param.clamp(ps[0], ps[ps.len() - 1]);
                    let j = (0..ps.len() - 1)
                        .find(|&j| x <= ps[j + 1])
                        .unwrap_or(ps.len() - 2);
                    let t = (x - ps[j]) / (ps[j + 1] - ps[j]);
                    (0..b.num_bases)
                        .map(|k| {
                            let a = b.coefficients[j * b.num_bases + k];
                            let c = b.coefficients[(j + 1) * b.num_bases + k];
                            a + t * (c - a)
                        })
                        .collect()
                }
                None => Vec::new(),
            };
            out.extend(slot_coefficients(m, p, &lobe));
        }
        out
    }

    /// A group's contraction weights (3 x row length, channel-major) for the slot
    /// coefficients `coeff`.
    pub fn weights(&self, g: &Group, coeff: &[[f32; 3]]) -> Vec<f32> {
        let m = &self.meta.materials[g.meta.material as usize];
        group_weights(
            &g.meta,
            m,
            coeff,
            self.meta.reflections as usize,
            self.meta.channels as usize,
            self.meta.tint,
        )
    }

    /// The relit image in f64: emission plus, per group and pixel, the sum over stored
    /// elements of value x weight (full) or of the low-rank reconstruction (compressed).
    /// `values` replaces the transfer values (e.g. by their f16 rounding).
    pub fn relight(
        &self,
        params: &[MaterialParams],
        compressed: bool,
        values: Option<&[Vec<f32>]>,
    ) -> Vec<[f64; 3]> {
        let coeff = self.coefficients(params);
        let mut img: Vec<[f64; 3]> = self
            .emission
            .chunks_exact(3)
            .map(|c| [c[0] as f64, c[1] as f64, c[2] as f64])
            .collect();
        for (gi, g) in self.groups.iter().enumerate() {
            let wts = self.weights(g, &coeff);
            let len = g.meta.row_len as usize;
            let p = g.pixels.len();
            let t = values.map_or(&g.transfer[..], |v| &v[gi][..]);
            for (i, &px) in g.pixels.iter().enumerate() {
                for (ch, out) in img[px as usize].iter_mut().enumerate() {
                    let w = &wts[ch * len..(ch + 1) * len];
                    *out += match (&g.compressed, compressed) {
                        (Some((mean, comps, z)), true) => {
                            let k = z.len() / p;
                            (0..len)
                                .map(|e| {
                                    let mut x = mean[e] as f64;
                                    for r in 0..k {
                                        x += z[r * p + i] as f64 * comps[r * len + e] as f64;
                                    }
                                    x * w[e] as f64
                                })
                                .sum::<f64>()
                        }
                        _ => (0..len)
                            .map(|e| t[e * p + i] as f64 * w[e] as f64)
                            .sum::<f64>(),
                    };
                }
            }
        }
        img
    }

    /// The transfer values as an f16 file stores them (value / scale rounded, times scale).
    pub fn f16_values(&self) -> Vec<Vec<f32>> {
        self.groups
            .iter()
            .map(|g| {
                let max = g.transfer.iter().fold(0.0f32, |m, v| m.max(v.abs()));
                let scale = if max > 0.0 { max / 16384.0 } else { 1.0 };
                g.transfer
                    .iter()
                    .map(|v| f16::from_f32(v / scale).to_f32() * scale)
                    .collect()
            })
            .collect()
    }

    /// The materials' baked parameters.
    pub fn params(&self) -> Vec<MaterialParams> {
        self.meta.materials.iter().map(|m| m.params()).collect()
    }
}
