//! PRT runtime: opens a bake file and produces images for any setting of the editable
//! materials, without tracing a ray. It depends only on `prt-formats`, never on the baker.
//!
//! - [`Relighter`]: a per-pixel bake (docs/pixel.md, "Storage and relighting"): camera and
//!   light frozen into the file, materials edited.
//! - [`vertex::VertexRelighter`]: a per-vertex bake (docs/vertex.md): environment, camera and
//!   materials all edited.
//!
//! Both take material edits by the same rules (`materials.rs`).
//!
//! Relighting contracts each group's per-pixel transfer rows with weights built from the
//! current slot coefficients ([`prt_formats::pixel::group_weights`]): uncompressed, one
//! multiply-add per stored value and channel; compressed (PCA over pixels), the K components
//! are contracted once per frame and each pixel costs K multiply-adds per channel.
//!
//! The per-vertex mode is built on [`light`] (an environment's light coefficients: cube map,
//! Haar, coarse cubes, prefiltered cubes) and [`raster`] (the visibility buffer: triangle,
//! perspective-correct barycentrics, distance per pixel centre).

#![warn(missing_docs)]

mod error;
pub mod light;
mod materials;
pub mod raster;
pub mod vertex;

pub use error::RuntimeError;

use std::path::Path;
use std::time::Instant;

use half::f16;
use prt_formats::overrides::MaterialOverride;
use prt_formats::pixel::{group_weights, names, MaterialParams, PixelBakeMeta, Precision};
use prt_formats::vertex::BakeKind;
use prt_formats::{BakeFile, Dtype};
use rayon::prelude::*;

use materials::Materials;

/// Which representation to relight from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Variant {
    /// The stored transfer rows (`g<k>.t`: f32, or f16 with a per-group scale).
    Full,
    /// The low-rank (PCA over pixels) approximation (`g<k>.mean`, `.components`, `.weights`),
    /// present only when the bake was made with a compression rank.
    Compressed,
}

/// Which inner loops [`Relighter::render`] runs. Both give bit-identical frames (the per-lane
/// arithmetic is the same); the switch exists so tests and measurements can run the portable
/// path on a CPU that has the vector instructions.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Kernel {
    /// The fastest the CPU supports: AVX2 (and F16C for f16 bakes) on x86-64, else portable.
    #[default]
    Auto,
    /// The portable scalar code, whatever the CPU.
    Scalar,
}

/// A relit image and what it cost.
#[derive(Clone, Debug)]
pub struct Frame {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Row-major, top row first, linear RGB (`width * height` pixels).
    pub pixels: Vec<[f32; 3]>,
    /// Wall-clock time of [`Relighter::render`], in seconds.
    pub seconds: f64,
    /// Bytes of bake data read to make the frame.
    pub bytes_read: u64,
}

/// An opened bake file with the current material settings.
pub struct Relighter {
    file: BakeFile,
    meta: PixelBakeMeta,
    materials: Materials,
    kernel: Kernel,
}

impl Relighter {
    /// Opens and validates a per-pixel bake file (checksums verified). A per-vertex bake is
    /// refused with [`RuntimeError::WrongKind`] (open it with [`vertex::VertexRelighter`]).
    pub fn open(path: impl AsRef<Path>) -> Result<Relighter, RuntimeError> {
        Relighter::from_file(BakeFile::open(path)?)
    }

    /// Validates an opened bake file as a per-pixel bake (see [`Relighter::open`]).
    pub fn from_file(file: BakeFile) -> Result<Relighter, RuntimeError> {
        let path = file.path().to_path_buf();
        let schema = |reason: String| RuntimeError::Schema {
            path: path.display().to_string(),
            reason,
        };
        if BakeKind::of_metadata(file.metadata()) == Some(BakeKind::Vertex) {
            return Err(RuntimeError::WrongKind {
                path: path.display().to_string(),
                kind: BakeKind::Vertex.describe(),
                expected: BakeKind::Pixel.describe(),
                hint: "relight it with the per-vertex runtime (prt_runtime::vertex::\
                       VertexRelighter; `relight` chooses it by itself and takes --env, \
                       --camera and --width/--height)",
            });
        }
        let meta: PixelBakeMeta = serde_json::from_value(file.metadata().clone())
            .map_err(|e| schema(format!("metadata does not match the per-pixel schema: {e}")))?;
        if meta.pixel_schema_version != prt_formats::pixel::PIXEL_SCHEMA_VERSION {
            return Err(schema(format!(
                "per-pixel schema version {} (this runtime reads {})",
                meta.pixel_schema_version,
                prt_formats::pixel::PIXEL_SCHEMA_VERSION
            )));
        }
        // The contraction weights are laid out for gray (1) or RGB (3) values only.
        if !matches!(meta.channels, 1 | 3) {
            return Err(schema(format!(
                "{} channels per value (1 or 3 expected)",
                meta.channels
            )));
        }
        let materials = Materials::new(&meta.materials, &meta.bases).map_err(schema)?;
        let nslots: usize = meta.materials.iter().map(|m| m.slots.len()).sum();
        let (w, h) = (meta.width as usize, meta.height as usize);
        file.tensor(names::EMISSION)?.require_shape(&[h, w, 3])?;
        for (g, gm) in meta.groups.iter().enumerate() {
            let Some(m) = meta.materials.get(gm.material as usize) else {
                return Err(schema(format!(
                    "group {g} names material {} which does not exist",
                    gm.material
                )));
            };
            if gm.active.iter().any(|&j| j as usize >= nslots) {
                return Err(schema(format!(
                    "group {g} names a slot beyond the {nslots} slots"
                )));
            }
            let expect = prt_formats::pixel::row_len(
                m.slots.len(),
                gm.active.len(),
                meta.reflections as usize,
                meta.channels as usize,
            );
            if expect != gm.row_len as usize {
                return Err(schema(format!(
                    "group {g}: row length {} but the layout gives {expect}",
                    gm.row_len
                )));
            }
            let p = gm.pixels as usize;
            if p == 0 {
                // The baker writes groups of visible materials only. An empty group would hold
                // no data however long its row, while rendering allocates and walks the row.
                return Err(schema(format!("group {g} has no pixels")));
            }
            let pix = file.tensor(&names::pixels(g))?;
            pix.require_shape(&[p])?;
            let indices = pix.as_u32()?;
            if indices.iter().any(|&i| i as usize >= w * h) {
                return Err(schema(format!(
                    "group {g} has a pixel index outside the image"
                )));
            }
            // Rendering finds each band's pixels by binary search.
            if indices.windows(2).any(|ab| ab[0] >= ab[1]) {
                return Err(schema(format!(
                    "group {g}: pixel indices are not strictly ascending"
                )));
            }
            let t = file.tensor(&names::transfer(g))?;
            t.require_shape(&[expect, p])?;
            let stored = match meta.precision {
                Precision::F32 => Dtype::F32,
                Precision::F16 => Dtype::F16,
            };
            if t.dtype() != stored {
                return Err(schema(format!(
                    "group {g}: transfer tensor is {} but the metadata says {}",
                    t.dtype(),
                    meta.precision.name()
                )));
            }
            if let Some(k) = gm.compressed_rank {
                let k = k as usize;
                file.tensor(&names::mean(g))?.require_shape(&[expect])?;
                file.tensor(&names::components(g))?
                    .require_shape(&[k, expect])?;
                file.tensor(&names::weights(g))?.require_shape(&[k, p])?;
            }
        }
        Ok(Relighter {
            file,
            meta,
            materials,
            kernel: Kernel::Auto,
        })
    }

    /// Chooses the inner loops of [`Relighter::render`] (default [`Kernel::Auto`]); the frames
    /// are the same bit for bit, only the speed differs.
    pub fn set_kernel(&mut self, kernel: Kernel) {
        self.kernel = kernel;
    }

    /// The bake's per-pixel metadata (camera, materials, slots, groups).
    pub fn meta(&self) -> &PixelBakeMeta {
        &self.meta
    }

    /// Image width in pixels.
    pub fn width(&self) -> u32 {
        self.meta.width
    }

    /// Image height in pixels.
    pub fn height(&self) -> u32 {
        self.meta.height
    }

    /// Whether [`Variant::Compressed`] can be rendered (every group has a low-rank variant).
    pub fn has_compressed(&self) -> bool {
        !self.meta.groups.is_empty() && self.meta.groups.iter().all(|g| g.compressed_rank.is_some())
    }

    /// Current parameters of material `name`.
    pub fn params(&self, name: &str) -> Result<MaterialParams, RuntimeError> {
        self.materials.params(name)
    }

    /// Applies one `--set MATERIAL.PARAM=VALUE` edit (values already range-checked by the
    /// parser; shininess/alpha outside the basis' sampled range are clamped by it).
    pub fn apply(&mut self, o: &MaterialOverride) -> Result<(), RuntimeError> {
        self.materials.apply(o)
    }

    /// RGB coefficient of every global slot for the current parameters, and whether any
    /// parameter lay outside its basis' sampled range (and was clamped).
    pub fn coefficients(&self) -> (Vec<[f32; 3]>, bool) {
        self.materials.coefficients()
    }

    /// Relights the image for the current parameters.
    ///
    /// The image is cut into bands of rows processed in parallel; each band contracts, for
    /// every group, the rows of its own pixels (groups store pixels in ascending order) and
    /// adds them into its part of the image, so no thread writes another's pixels.
    pub fn render(&self, variant: Variant) -> Result<Frame, RuntimeError> {
        if variant == Variant::Compressed && !self.has_compressed() {
            return Err(RuntimeError::NoCompressed);
        }
        let start = Instant::now();
        let (coeff, _) = self.coefficients();
        let reflections = self.meta.reflections as usize;
        let channels = self.meta.channels as usize;
        let emission = self.file.tensor(names::EMISSION)?.as_f32()?;
        let mut bytes_read = (emission.len() * 4) as u64;
        let mut groups = Vec::with_capacity(self.meta.groups.len());
        for (g, gm) in self.meta.groups.iter().enumerate() {
            let m = &self.meta.materials[gm.material as usize];
            let w = group_weights(gm, m, &coeff, reflections, channels, self.meta.tint);
            let len = gm.row_len as usize;
            let pixels = self.file.tensor(&names::pixels(g))?.as_u32()?;
            bytes_read += (pixels.len() * 4) as u64;
            let data = match variant {
                Variant::Full => {
                    let t = self.file.tensor(&names::transfer(g))?;
                    bytes_read += t.bytes().len() as u64;
                    match t.dtype() {
                        Dtype::F16 => Rows::F16(t.as_f16()?, gm.scale),
                        _ => Rows::F32(t.as_f32()?),
                    }
                }
                Variant::Compressed => {
                    let k = gm.compressed_rank.unwrap_or(0) as usize;
                    let mean = self.file.tensor(&names::mean(g))?.as_f32()?;
                    let comps = self.file.tensor(&names::components(g))?.as_f32()?;
                    let z = self.file.tensor(&names::weights(g))?.as_f32()?;
                    bytes_read += ((mean.len() + comps.len() + z.len()) * 4) as u64;
                    // Contract the mean and the K components once per frame.
                    let base = dot3(mean, &w, len);
                    let s: Vec<[f32; 3]> = (0..k)
                        .map(|r| dot3(&comps[r * len..(r + 1) * len], &w, len))
                        .collect();
                    Rows::Compressed { base, s, z }
                }
            };
            groups.push(GroupFrame {
                pixels,
                len,
                w,
                data,
            });
        }
        let (width, height) = (self.meta.width as usize, self.meta.height as usize);
        // Zeroed pages from the allocator; each band copies its own emission in (in parallel
        // and while the band is in cache: a serial copy of the whole image took 8 % of a
        // frame).
        let mut pixels = vec![[0.0f32; 3]; width * height];
        let simd = self.kernel == Kernel::Auto;
        let band = (width * BAND_ROWS).max(1);
        pixels
            .par_chunks_mut(band)
            .enumerate()
            .for_each(|(b, out)| {
                let lo = (b * band) as u32;
                let hi = lo + out.len() as u32;
                if let Some(e) = emission.get(3 * lo as usize..3 * hi as usize) {
                    for (o, e) in out.iter_mut().zip(e.chunks_exact(3)) {
                        *o = [e[0], e[1], e[2]];
                    }
                }
                let mut scratch = Scratch::default();
                for g in &groups {
                    let first = g.pixels.partition_point(|&p| p < lo);
                    let last = g.pixels.partition_point(|&p| p < hi);
                    let mut i = first;
                    while i < last {
                        let end = (i + BLOCK).min(last);
                        let acc = g.contract_block(i, end, simd, &mut scratch);
                        let ids = &g.pixels[i..end];
                        let start = (ids[0] - lo) as usize;
                        if (ids[ids.len() - 1] - ids[0]) as usize == ids.len() - 1 {
                            // Consecutive pixels (most of a group's blocks): no index per
                            // pixel, and the compiler vectorises the additions.
                            let run = &mut out[start..start + ids.len()];
                            for (k, o) in run.iter_mut().enumerate() {
                                add_pixel(o, acc, k);
                            }
                        } else {
                            for (k, p) in ids.iter().enumerate() {
                                add_pixel(&mut out[(p - lo) as usize], acc, k);
                            }
                        }
                        i = end;
                    }
                }
            });
        debug_assert_eq!(pixels.len(), width * height);
        Ok(Frame {
            width: self.meta.width,
            height: self.meta.height,
            pixels,
            seconds: start.elapsed().as_secs_f64(),
            bytes_read,
        })
    }
}

/// Adds pixel `k` of a block's channel-major accumulators to an image pixel.
#[inline(always)]
fn add_pixel(o: &mut [f32; 3], acc: &[Vec<f32>; 3], k: usize) {
    o[0] += acc[0][k];
    o[1] += acc[1][k];
    o[2] += acc[2][k];
}

/// Image rows per parallel band.
const BAND_ROWS: usize = 8;
/// Pixels contracted together: their three accumulators stay in L1 while the columns stream.
const BLOCK: usize = 256;

/// One group's data for a frame.
struct GroupFrame<'a> {
    pixels: &'a [u32],
    len: usize,
    /// Contraction weights, 3 x len (channel-major).
    w: Vec<f32>,
    data: Rows<'a>,
}

/// A group's values, stored element-major: value e of pixel i at `e * pixels + i`.
enum Rows<'a> {
    F32(&'a [f32]),
    F16(&'a [f16], f32),
    /// Low rank: radiance = base + sum_r z[r, i] s[r].
    Compressed {
        base: [f32; 3],
        s: Vec<[f32; 3]>,
        z: &'a [f32],
    },
}

/// Per-band working memory.
#[derive(Default)]
struct Scratch {
    acc: [Vec<f32>; 3],
    terms: Vec<Term>,
}

/// One stored element (or low-rank component) with a nonzero weight: where its column
/// starts and its weight per output channel.
#[derive(Clone, Copy)]
struct Term {
    offset: usize,
    w: [f32; 3],
}

impl GroupFrame<'_> {
    /// The elements with nonzero weight and their column offsets.
    fn terms(&self, out: &mut Vec<Term>) -> [f32; 3] {
        out.clear();
        let np = self.pixels.len();
        let len = self.len;
        let w = &self.w;
        match &self.data {
            Rows::F32(_) | Rows::F16(..) => {
                let scale = if let Rows::F16(_, s) = &self.data {
                    *s
                } else {
                    1.0
                };
                for e in 0..len {
                    let we = [w[e] * scale, w[len + e] * scale, w[2 * len + e] * scale];
                    if we != [0.0; 3] {
                        out.push(Term {
                            offset: e * np,
                            w: we,
                        });
                    }
                }
                [0.0; 3]
            }
            Rows::Compressed { base, s, .. } => {
                for (r, sr) in s.iter().enumerate() {
                    out.push(Term {
                        offset: r * np,
                        w: *sr,
                    });
                }
                *base
            }
        }
    }

    /// Radiance of the group's pixels `i0..i1` (at most [`BLOCK`]), per channel; `simd` allows
    /// the vector kernels.
    fn contract_block<'s>(
        &self,
        i0: usize,
        i1: usize,
        simd: bool,
        sc: &'s mut Scratch,
    ) -> &'s [Vec<f32>; 3] {
        let n = i1 - i0;
        for a in sc.acc.iter_mut() {
            a.clear();
            a.resize(n, 0.0);
        }
        let mut terms = std::mem::take(&mut sc.terms);
        let init = self.terms(&mut terms);
        match &self.data {
            Rows::F32(t) => tiles_f32(t, &terms, i0, init, simd, &mut sc.acc),
            Rows::F16(t, _) => tiles_f16(t, &terms, i0, init, simd, &mut sc.acc),
            Rows::Compressed { z, .. } => tiles_f32(z, &terms, i0, init, simd, &mut sc.acc),
        }
        sc.terms = terms;
        &sc.acc
    }
}

/// Pixels whose three accumulators stay in registers while every term is added.
const TILE: usize = 8;

/// `acc[c][k] = init[c] + sum_terms w[c] * col[i0 + k]` for k < acc[0].len(), reading each
/// stored value once; the per-lane arithmetic (multiply, then add, in term order) is the same
/// in every instruction set, so results are bit-identical whatever the CPU.
#[inline(always)]
fn tiles_impl<T: Copy>(
    t: &[T],
    terms: &[Term],
    i0: usize,
    init: [f32; 3],
    acc: &mut [Vec<f32>; 3],
    load: impl Fn(&[T]) -> [f32; TILE],
    one: impl Fn(T) -> f32,
) {
    let n = acc[0].len();
    let full = n - n % TILE;
    let mut k = 0;
    while k < full {
        let mut r = [[init[0]; TILE], [init[1]; TILE], [init[2]; TILE]];
        for term in terms {
            let start = term.offset + i0 + k;
            let Some(src) = t.get(start..start + TILE) else {
                continue;
            };
            let x = load(src);
            for l in 0..TILE {
                r[0][l] += term.w[0] * x[l];
                r[1][l] += term.w[1] * x[l];
                r[2][l] += term.w[2] * x[l];
            }
        }
        for (c, rc) in r.iter().enumerate() {
            acc[c][k..k + TILE].copy_from_slice(rc);
        }
        k += TILE;
    }
    for k in full..n {
        let mut r = init;
        for term in terms {
            if let Some(&v) = t.get(term.offset + i0 + k) {
                let x = one(v);
                r[0] += term.w[0] * x;
                r[1] += term.w[1] * x;
                r[2] += term.w[2] * x;
            }
        }
        for (a, v) in acc.iter_mut().zip(r) {
            a[k] = v;
        }
    }
}

#[inline(always)]
fn load_f32(src: &[f32]) -> [f32; TILE] {
    let mut x = [0.0; TILE];
    x.copy_from_slice(&src[..TILE]);
    x
}

fn tiles_f32(
    t: &[f32],
    terms: &[Term],
    i0: usize,
    init: [f32; 3],
    simd: bool,
    acc: &mut [Vec<f32>; 3],
) {
    #[cfg(target_arch = "x86_64")]
    if simd && std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU supports AVX2 (checked just above).
        unsafe { tiles_f32_avx2(t, terms, i0, init, acc) };
        return;
    }
    tiles_impl(t, terms, i0, init, acc, load_f32, |v| v);
}

/// The same kernel compiled for AVX2 (8-wide registers for the tile).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn tiles_f32_avx2(
    t: &[f32],
    terms: &[Term],
    i0: usize,
    init: [f32; 3],
    acc: &mut [Vec<f32>; 3],
) {
    tiles_impl(t, terms, i0, init, acc, load_f32, |v| v);
}

fn tiles_f16(
    t: &[f16],
    terms: &[Term],
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
        unsafe { tiles_f16_avx2(t, terms, i0, init, acc) };
        return;
    }
    tiles_impl(
        t,
        terms,
        i0,
        init,
        acc,
        |src| {
            let mut x = [0.0; TILE];
            for (o, v) in x.iter_mut().zip(src) {
                *o = v.to_f32();
            }
            x
        },
        f16::to_f32,
    );
}

/// The f16 kernel with inline hardware conversion (F16C) and AVX2 registers.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,f16c")]
unsafe fn tiles_f16_avx2(
    t: &[f16],
    terms: &[Term],
    i0: usize,
    init: [f32; 3],
    acc: &mut [Vec<f32>; 3],
) {
    use std::arch::x86_64::{__m128i, _mm256_cvtph_ps, _mm256_storeu_ps, _mm_loadu_si128};
    tiles_impl(
        t,
        terms,
        i0,
        init,
        acc,
        |src| {
            let mut x = [0.0f32; TILE];
            // SAFETY: `src` holds at least TILE (8) f16 values = 16 bytes (callers slice it
            // to TILE); unaligned load and store; F16C is enabled for this function.
            unsafe {
                let h = _mm_loadu_si128(src.as_ptr() as *const __m128i);
                _mm256_storeu_ps(x.as_mut_ptr(), _mm256_cvtph_ps(h));
            }
            x
        },
        f16::to_f32,
    );
}

/// `sum_e W[c][e] x[e]` for the three output channels (`w` is 3 x len, channel-major), used
/// once per frame to contract the low-rank mean and components.
fn dot3(x: &[f32], w: &[f32], len: usize) -> [f32; 3] {
    let mut out = [0.0f32; 3];
    for e in 0..len {
        out[0] += w[e] * x[e];
        out[1] += w[len + e] * x[e];
        out[2] += w[2 * len + e] * x[e];
    }
    out
}
