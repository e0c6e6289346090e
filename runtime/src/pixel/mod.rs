//! The per-pixel relighter (docs/pixel.md, "Storage and relighting"): a bake whose camera
//! and light are frozen into the file, relit for any setting of its editable materials.
//!
//! Relighting contracts each group's per-pixel transfer rows with weights built from the
//! current slot coefficients ([`prt_formats::pixel::group_weights`]): uncompressed, one
//! multiply-add per stored value and channel; compressed (PCA over pixels), the K components
//! are contracted once per frame and each pixel costs K multiply-adds per channel. The inner
//! loops are in `contract.rs`, the in-memory tiled layout they read in `tiled.rs`.

mod contract;
mod tiled;

use std::path::Path;
use std::time::Instant;

use half::f16;
use prt_formats::overrides::OverrideValue;
use prt_formats::pixel::{group_weights, names, MaterialParams, PixelBakeMeta, Precision};
use prt_formats::vertex::BakeKind;
use prt_formats::{BakeFile, Dtype};
use rayon::prelude::*;

use crate::error::RuntimeError;
use crate::image::{check_len, Image, RenderStats};
use crate::materials::{MaterialInfo, Materials};
use contract::{add_run, stream_out, tiles_f16, tiles_f32, Column};
use tiled::Tiled;

/// Which representation to relight from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Variant {
    /// The stored transfer rows (`g<k>.t`: f32, or f16 with a per-group scale).
    Full,
    /// The low-rank (PCA over pixels) approximation (`g<k>.mean`, `.components`, `.weights`),
    /// present only when the bake was made with a compression rank.
    Compressed,
}

/// An opened per-pixel bake with the current material settings and variant.
pub struct PixelRelighter {
    file: BakeFile,
    meta: PixelBakeMeta,
    materials: Materials,
    variant: Variant,
    /// Whether the vector kernels may run (the hooks' `Kernel` switches them off).
    simd: bool,
    /// Per group, its pixel list as runs of consecutive image pixels, cut at band edges.
    runs: Vec<GroupRuns>,
    /// Per group, its stored values in the tiled layout the kernels read (`tiled.rs`).
    values: Vec<GroupValues>,
    /// The pixels whose stored emission is not +0 in every channel, as runs per band: a
    /// frame reads only these (the others start from zero), so a scene whose camera sees
    /// little emission does not read the whole emission image every frame.
    emitting: GroupRuns,
}

/// One group's values as a frame reads them (copied from the file into tiles at open).
struct GroupValues {
    /// The stored transfer rows.
    full: StoredValues,
    /// The low-rank weights (`g<k>.weights`, one column per component), when present.
    low_rank: Option<Tiled<f32>>,
}

/// A group's transfer rows in the precision they are stored in.
enum StoredValues {
    F32(Tiled<f32>),
    F16(Tiled<f16>),
}

impl PixelRelighter {
    /// Opens and validates a per-pixel bake file (checksums verified). A per-vertex bake is
    /// refused with [`RuntimeError::WrongKind`] ([`crate::open`] opens either kind).
    /// The transfer values (and low-rank weights) are copied into memory in the tiled layout
    /// the frames read, which takes about their size in the file.
    pub fn open(path: impl AsRef<Path>) -> Result<PixelRelighter, RuntimeError> {
        PixelRelighter::from_file(BakeFile::open(path)?)
    }

    /// Validates an opened bake file as a per-pixel bake (see [`PixelRelighter::open`]).
    /// The materials start at their baked parameters, the variant at [`Variant::Full`].
    pub fn from_file(file: BakeFile) -> Result<PixelRelighter, RuntimeError> {
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
                hint: "open it with prt_runtime::open or VertexRelighter (`relight` \
                       chooses the kind by itself and takes --env, --camera and \
                       --width/--height for it)",
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
        let emission = file.tensor(names::EMISSION)?;
        emission.require_shape(&[h, w, 3])?;
        // Bits, not values: a pixel starting from +0 instead of its stored emission must give
        // the same bits, which -0 would not.
        let emitting: Vec<u32> = emission
            .as_f32()?
            .chunks_exact(3)
            .zip(0u32..)
            .filter(|(e, _)| e.iter().any(|v| v.to_bits() != 0))
            .map(|(_, i)| i)
            .collect();
        let emitting = GroupRuns::new(&emitting, w, h);
        let mut runs = Vec::with_capacity(meta.groups.len());
        let mut values = Vec::with_capacity(meta.groups.len());
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
            // Rendering takes each band's pixels as one run of the list.
            if indices.windows(2).any(|ab| ab[0] >= ab[1]) {
                return Err(schema(format!(
                    "group {g}: pixel indices are not strictly ascending"
                )));
            }
            runs.push(GroupRuns::new(indices, w, h));
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
            let full = match stored {
                Dtype::F16 => StoredValues::F16(Tiled::from_element_major(t.as_f16()?, expect, p)),
                _ => StoredValues::F32(Tiled::from_element_major(t.as_f32()?, expect, p)),
            };
            let mut low_rank = None;
            if let Some(k) = gm.compressed_rank {
                let k = k as usize;
                file.tensor(&names::mean(g))?.require_shape(&[expect])?;
                file.tensor(&names::components(g))?
                    .require_shape(&[k, expect])?;
                let z = file.tensor(&names::weights(g))?;
                z.require_shape(&[k, p])?;
                low_rank = Some(Tiled::from_element_major(z.as_f32()?, k, p));
            }
            values.push(GroupValues { full, low_rank });
        }
        Ok(PixelRelighter {
            file,
            meta,
            materials,
            variant: Variant::Full,
            simd: true,
            runs,
            values,
            emitting,
        })
    }

    /// The bake's per-pixel metadata (camera, materials, slots, groups).
    pub fn meta(&self) -> &PixelBakeMeta {
        &self.meta
    }

    /// The image size `(width, height)` in pixels, fixed by the bake.
    pub fn size(&self) -> (u32, u32) {
        (self.meta.width, self.meta.height)
    }

    /// Every material with its family, current parameters and their ranges.
    pub fn materials(&self) -> Vec<MaterialInfo> {
        self.materials.info()
    }

    /// Current parameters of material `name`.
    pub fn params(&self, name: &str) -> Result<MaterialParams, RuntimeError> {
        self.materials.params(name)
    }

    /// Sets parameters of the editable material `name`, all or none (see
    /// [`crate::Relighter::set_params`]).
    pub fn set_params(&mut self, name: &str, values: &[OverrideValue]) -> Result<(), RuntimeError> {
        self.materials.set(name, values)
    }

    /// Whether [`Variant::Compressed`] can be rendered (every group has a low-rank variant).
    pub fn has_compressed(&self) -> bool {
        !self.meta.groups.is_empty() && self.meta.groups.iter().all(|g| g.compressed_rank.is_some())
    }

    /// The representation frames are relit from.
    pub fn variant(&self) -> Variant {
        self.variant
    }

    /// Chooses the representation frames are relit from; [`Variant::Compressed`] is refused
    /// with [`RuntimeError::NoCompressed`] when the bake has none.
    pub fn set_variant(&mut self, variant: Variant) -> Result<(), RuntimeError> {
        if variant == Variant::Compressed && !self.has_compressed() {
            return Err(RuntimeError::NoCompressed);
        }
        self.variant = variant;
        Ok(())
    }

    /// Relights the image for the current parameters into a new [`Image`].
    pub fn render(&self) -> Result<Image, RuntimeError> {
        let (width, height) = self.size();
        let mut image = Image::new(width, height);
        self.render_into(image.pixels.as_flattened_mut())?;
        Ok(image)
    }

    /// Relights the image for the current parameters into `out`: `3 * width * height` floats,
    /// linear RGB, row-major, top row first (anything else is refused with
    /// [`RuntimeError::BufferSize`]). Every float is written and none is read, so `out` needs
    /// no clearing, and rendering many frames into one buffer allocates nothing once the
    /// threads' working memory has settled.
    ///
    /// The image is cut into bands of rows processed in parallel; each band contracts, for
    /// every group, the rows of its own pixels (groups store pixels in ascending order) and
    /// adds them into its part of the image, so no thread writes another's pixels.
    pub fn render_into(&self, out: &mut [f32]) -> Result<RenderStats, RuntimeError> {
        let (seconds, bytes_read) = self.frame::<false>(out)?;
        Ok(RenderStats {
            seconds,
            bytes_read: Some(bytes_read),
            ..RenderStats::default()
        })
    }

    /// RGB coefficient of every global slot for the current parameters, and whether any
    /// parameter lay outside its basis' sampled range (and was clamped).
    #[cfg(any(feature = "hooks", feature = "gpu-surface"))]
    pub fn coefficients(&self) -> (Vec<[f32; 3]>, bool) {
        self.materials.coefficients()
    }

    /// The opened bake file (feature `gpu-surface`): a GPU backend uploads its stored tensors
    /// once and contracts them with weights from [`PixelRelighter::coefficients`] (docs/gpu.md).
    #[cfg(feature = "gpu-surface")]
    pub fn file(&self) -> &BakeFile {
        &self.file
    }

    /// Chooses the inner loops (default [`crate::hooks::Kernel::Auto`]); the frames are the
    /// same bit for bit, only the speed differs.
    #[cfg(feature = "hooks")]
    pub fn set_kernel(&mut self, kernel: crate::hooks::Kernel) {
        self.simd = kernel == crate::hooks::Kernel::Auto;
    }

    /// What a frame's memory traffic alone costs: reads every stored value that
    /// [`PixelRelighter::render_into`] reads, in the same order and with the same prefetches,
    /// copies the emission and adds into the image as it does, but sums the values unweighted
    /// instead of contracting them with the weights (one add per eight values instead of six
    /// multiplies and adds). `bench pixel` times it beside the frames, to tell what bounds a
    /// frame: the memory system serving this access pattern, or the arithmetic. `scratch` is
    /// reused between calls; what it holds afterwards is not an image of anything.
    #[cfg(feature = "hooks")]
    pub fn time_reads(
        &self,
        scratch: &mut Vec<f32>,
    ) -> Result<crate::hooks::ReadPass, RuntimeError> {
        let (width, height) = self.size();
        scratch.resize(3 * width as usize * height as usize, 0.0);
        let (seconds, bytes_read) = self.frame::<true>(scratch)?;
        Ok(crate::hooks::ReadPass {
            seconds,
            bytes_read,
        })
    }

    /// [`PixelRelighter::render_into`], or with `READS_ONLY` the traffic of one (the hooks'
    /// `time_reads`): the frame's seconds and bytes read.
    fn frame<const READS_ONLY: bool>(&self, out: &mut [f32]) -> Result<(f64, u64), RuntimeError> {
        let (width, height) = self.size();
        check_len("the output buffer", out, width, height)?;
        let variant = self.variant;
        let start = Instant::now();
        let (coeff, _) = self.materials.coefficients();
        let reflections = self.meta.reflections as usize;
        let channels = self.meta.channels as usize;
        let emission = self.file.tensor(names::EMISSION)?.as_f32()?;
        let mut bytes_read = (self.emitting.pixels() * 3 * 4) as u64;
        let mut groups = Vec::with_capacity(self.meta.groups.len());
        for (g, gm) in self.meta.groups.iter().enumerate() {
            let m = &self.meta.materials[gm.material as usize];
            let w = group_weights(gm, m, &coeff, reflections, channels, self.meta.tint);
            let len = gm.row_len as usize;
            // The pixel list itself is not read: its runs were found at open.
            let np = gm.pixels as usize;
            let stored = &self.values[g];
            let columns = match variant {
                Variant::Full => {
                    // Only the columns with a nonzero weight are read.
                    let (columns, read) = match &stored.full {
                        StoredValues::F16(values) => {
                            let cols = element_columns(&w, gm.scale);
                            let read = cols.len() * np * 2;
                            (Columns::F16(values, cols), read)
                        }
                        StoredValues::F32(values) => {
                            let cols = element_columns(&w, 1.0);
                            let read = cols.len() * np * 4;
                            (Columns::F32(values, cols, [0.0; 3]), read)
                        }
                    };
                    bytes_read += read as u64;
                    columns
                }
                Variant::Compressed => {
                    let (Some(z), Some(k)) = (&stored.low_rank, gm.compressed_rank) else {
                        return Err(RuntimeError::NoCompressed);
                    };
                    let k = k as usize;
                    let mean = self.file.tensor(&names::mean(g))?.as_f32()?;
                    let comps = self.file.tensor(&names::components(g))?.as_f32()?;
                    bytes_read += ((mean.len() + comps.len() + k * np) * 4) as u64;
                    // Contract the mean and the K components once per frame; each pixel's
                    // K weights are then its columns.
                    let base = dot3(mean, &w, len);
                    let cols = (0..k)
                        .map(|r| (r, dot3(&comps[r * len..(r + 1) * len], &w, len)))
                        .collect();
                    Columns::F32(z, cols, base)
                }
            };
            groups.push(columns);
        }
        let simd = self.simd;
        let band = band_pixels(width as usize);
        out.par_chunks_mut(3 * band)
            .enumerate()
            .for_each(|(b, out)| {
                let lo = b * band;
                let n = out.len() / 3;
                SCRATCH.with_borrow_mut(|Scratch { image, acc }| {
                    // The band is built in this thread's scratch (in cache from the band
                    // before) and then streamed to the frame, so the frame's old contents are
                    // never read: writing into the frame directly first fetched each of its
                    // lines from memory (2-9 % of a frame, measured).
                    // Each band starts from its own emission (in parallel, and while the band
                    // is in cache: a serial copy of the whole image took 8 % of a frame, and a
                    // parallel one before the bands 10-20 %), reading only the emitting pixels.
                    image.clear();
                    image.resize(3 * n, 0.0);
                    for run in self.emitting.band(b) {
                        let at = 3 * (run.pixel - lo);
                        image[at..at + 3 * run.len]
                            .copy_from_slice(&emission[3 * run.pixel..3 * (run.pixel + run.len)]);
                    }
                    let (img, _) = image.as_chunks_mut::<3>();
                    for (g, gr) in groups.iter().zip(&self.runs) {
                        let runs = gr.band(b);
                        let (first, last) = match (runs.first(), runs.last()) {
                            (Some(a), Some(z)) => (a.first, z.end()),
                            _ => continue,
                        };
                        let mut r = 0;
                        let mut i = first;
                        while i < last {
                            let end = (i + BLOCK).min(last);
                            g.contract_block::<READS_ONLY>(i, end, simd, acc);
                            // The block's pixels are a few runs of consecutive pixels (a
                            // group's span in each row): each run's part in the block is
                            // added as one stretch of the image, no index per pixel.
                            while let Some(run) = runs.get(r).filter(|run| run.first < end) {
                                let (from, to) = (run.first.max(i), run.end().min(end));
                                let at = run.pixel + (from - run.first) - lo;
                                add_run(&mut img[at..at + (to - from)], acc, from - i, simd);
                                if run.end() > end {
                                    break;
                                }
                                r += 1;
                            }
                            i = end;
                        }
                    }
                    stream_out(out, image, simd);
                });
            });
        Ok((start.elapsed().as_secs_f64(), bytes_read))
    }
}

/// A stretch of a pixel list (a group's, or the emitting pixels) whose image pixels are
/// consecutive.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Run {
    /// Index of its first pixel in the list.
    first: usize,
    /// Its first image pixel.
    pixel: usize,
    len: usize,
}

impl Run {
    fn end(&self) -> usize {
        self.first + self.len
    }
}

/// A pixel list (a group's, or the emitting pixels) cut into [`Run`]s once, when the file is
/// opened (finding a group's in every frame, by binary search over its list, took a tenth of a
/// frame: the searches' loads missed the cache).
#[derive(Debug)]
struct GroupRuns {
    runs: Vec<Run>,
    /// Where each band's runs start in `runs` (one entry per band, then `runs.len()`).
    band_starts: Vec<usize>,
}

impl GroupRuns {
    /// The runs of the strictly ascending pixel indices `indices` of a `width` x `height`
    /// image, cut at the bands' edges, so that no run crosses a band.
    fn new(indices: &[u32], width: usize, height: usize) -> GroupRuns {
        let band = band_pixels(width);
        let mut runs = Vec::new();
        let mut band_starts = Vec::with_capacity(height.div_ceil(BAND_ROWS) + 1);
        let mut k = 0;
        for b in 0..height.div_ceil(BAND_ROWS) {
            band_starts.push(runs.len());
            let end = k + indices[k..].partition_point(|&i| (i as usize) < (b + 1) * band);
            while k < end {
                let first = k;
                k += 1;
                while k < end && indices[k] == indices[k - 1] + 1 {
                    k += 1;
                }
                runs.push(Run {
                    first,
                    pixel: indices[first] as usize,
                    len: k - first,
                });
            }
        }
        band_starts.push(runs.len());
        GroupRuns { runs, band_starts }
    }

    /// How many pixels the runs hold.
    fn pixels(&self) -> usize {
        self.runs.iter().map(|r| r.len).sum()
    }

    /// The runs of band `b`.
    fn band(&self, b: usize) -> &[Run] {
        &self.runs[self.band_starts[b]..self.band_starts[b + 1]]
    }
}

/// A thread's working memory for [`PixelRelighter::render_into`], kept between bands and frames so
/// that a frame allocates and clears nothing once the sizes have settled.
#[derive(Default)]
struct Scratch {
    /// The band's image, channel-interleaved, while its groups are added.
    image: Vec<f32>,
    /// A block's per-channel sums.
    acc: [Vec<f32>; 3],
}

thread_local! {
    static SCRATCH: std::cell::RefCell<Scratch> = std::cell::RefCell::new(Scratch::default());
}

/// Image rows per parallel band.
const BAND_ROWS: usize = 8;

/// Pixels per band of an image `width` pixels wide (at least one, so an empty image still
/// cuts into bands); `render` and the band starts found at open must agree on it.
fn band_pixels(width: usize) -> usize {
    (width * BAND_ROWS).max(1)
}
/// Pixels contracted together: their three accumulators (12 KB) stay in L1 while the columns
/// stream, each in runs of a block's pixels.
const BLOCK: usize = 1024;

/// A group's values for a frame and its columns with a nonzero weight (stored elements, or
/// low-rank components), each with its weight per output channel.
enum Columns<'a> {
    /// f32 values and the radiance every pixel starts from (the low-rank mean's, else 0).
    F32(&'a Tiled<f32>, Vec<Column>, [f32; 3]),
    /// f16 values (the group's scale is folded into the weights).
    F16(&'a Tiled<f16>, Vec<Column>),
}

/// The stored elements whose weight is nonzero; `w` is 3 x len, channel-major, and `scale`
/// multiplies it.
fn element_columns(w: &[f32], scale: f32) -> Vec<Column> {
    let len = w.len() / 3;
    (0..len)
        .map(|e| {
            (
                e,
                [w[e] * scale, w[len + e] * scale, w[2 * len + e] * scale],
            )
        })
        .filter(|(_, we)| *we != [0.0; 3])
        .collect()
}

impl Columns<'_> {
    /// Radiance of the group's pixels `i0..i1` (at most [`BLOCK`]), per channel, into `acc`;
    /// `simd` allows the vector kernels.
    fn contract_block<const READS_ONLY: bool>(
        &self,
        i0: usize,
        i1: usize,
        simd: bool,
        acc: &mut [Vec<f32>; 3],
    ) {
        let n = i1 - i0;
        for a in acc.iter_mut() {
            // Every value is written by the kernel: no clearing needed.
            a.resize(n, 0.0);
        }
        match self {
            Columns::F32(values, cols, init) => {
                tiles_f32::<READS_ONLY>(values, cols, i0, *init, simd, acc)
            }
            Columns::F16(values, cols) => {
                tiles_f16::<READS_ONLY>(values, cols, i0, [0.0; 3], simd, acc)
            }
        }
    }
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
