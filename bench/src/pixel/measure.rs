//! The timed steps: bakes, reference renders, PCA over pixels, relights.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use prt_bake::config::BakeConfig;
use prt_bake::metrics::relative_l2;
use prt_bake::pixel::{self, Compressed, PixelBake, PixelBakeOptions, Precision, SlotLayout};
use prt_bake::scene::Scene;
use prt_formats::basis::BrdfBasis;
use prt_runtime::{Image, OverrideValue, PixelRelighter, RenderStats, Variant};

use super::scenes::{SceneCtx, Setting};
use super::stream::StreamBench;
use crate::util::median;

pub(crate) struct BakeRun {
    pub(crate) bake: PixelBake,
    pub(crate) seconds: f64,
    pub(crate) rays: u64,
    pub(crate) slots: usize,
}

pub(crate) fn bake_once(
    ctx: &SceneCtx,
    bases: &[BrdfBasis],
    w: u32,
    h: u32,
    spp: u32,
) -> Result<BakeRun> {
    let layout = SlotLayout::new(&ctx.scene, bases).map_err(anyhow::Error::msg)?;
    let opts = PixelBakeOptions {
        width: w,
        height: h,
        spp,
        emission_oversampling: ctx.config.emission_oversampling,
        reflections: ctx.config.reflections,
        seed: ctx.config.seed,
        precision: Precision::F16,
        max_memory: None,
        compress_rank: None,
    };
    let t = Instant::now();
    let bake = pixel::bake(&ctx.scene, &layout, &opts, None).map_err(anyhow::Error::msg)?;
    let seconds = t.elapsed().as_secs_f64();
    let rays = bake.meta.stats.rays;
    Ok(BakeRun {
        bake,
        seconds,
        rays,
        slots: layout.total_slots,
    })
}

pub(crate) struct RefRun {
    pub(crate) pixels: Vec<[f32; 3]>,
    pub(crate) seconds: f64,
    pub(crate) rays: u64,
}

/// True-BRDF render of `scene` with `config`'s reflections and emission oversampling (timed
/// from the acceleration structure build on, as the bake).
pub(crate) fn reference(
    scene: &Scene,
    config: &BakeConfig,
    w: u32,
    h: u32,
    spp: u32,
    seed: u64,
) -> RefRun {
    let t = Instant::now();
    let r = prt_bake::reference::render_true(
        scene,
        config.reflections as usize,
        w,
        h,
        spp,
        config.emission_oversampling,
        seed,
        None,
    );
    RefRun {
        pixels: r.pixels.iter().map(|p| p.to_array()).collect(),
        seconds: t.elapsed().as_secs_f64(),
        rays: r.rays,
    }
}

/// Full-rank PCA of every group (computed once), truncated to any rank afterwards.
pub(crate) struct Pca {
    pub(crate) per_group: Vec<Compressed>,
    pub(crate) seconds: f64,
}

impl Pca {
    pub(crate) fn new(bake: &PixelBake, max_rank: usize) -> Pca {
        let t = Instant::now();
        let per_group = bake
            .groups
            .iter()
            .zip(&bake.meta.groups)
            .map(|(g, gm)| {
                prt_bake::pixel::pca_rows(&g.rows, g.pixels.len(), gm.row_len as usize, max_rank)
            })
            .collect();
        Pca {
            per_group,
            seconds: t.elapsed().as_secs_f64(),
        }
    }

    /// Stores the rank-`k` truncation as the bake's compressed variant.
    pub(crate) fn apply(&self, bake: &mut PixelBake, k: usize) {
        for ((g, gm), full) in bake
            .groups
            .iter_mut()
            .zip(bake.meta.groups.iter_mut())
            .zip(&self.per_group)
        {
            let r = k.min(full.rank);
            let len = gm.row_len as usize;
            let weights = full
                .weights
                .chunks_exact(full.rank.max(1))
                .flat_map(|w| w[..r].iter().copied())
                .collect::<Vec<_>>();
            let weights = if full.rank == 0 { Vec::new() } else { weights };
            g.compressed = Some(Compressed {
                mean: full.mean.clone(),
                components: full.components[..r * len].to_vec(),
                weights,
                rank: r,
            });
            gm.compressed_rank = Some(r as u32);
        }
    }
}

/// A relighter of one variant whose state can be set to any setting: `reset` restores every
/// editable material's starting parameters before the setting's edits are applied.
pub(crate) struct Relit {
    pub(crate) r: PixelRelighter,
    reset: Vec<(String, Vec<OverrideValue>)>,
    /// The last frame, whose memory the next one renders into (as an interactive viewer
    /// would).
    image: Image,
}

impl Relit {
    pub(crate) fn open(path: &Path, variant: Variant) -> Result<Relit> {
        let mut r =
            PixelRelighter::open(path).with_context(|| format!("opening {}", path.display()))?;
        r.set_variant(variant)?;
        let reset = r
            .materials()
            .into_iter()
            .filter(|m| m.editable)
            .map(|m| (m.name, m.params.iter().map(|p| p.value).collect()))
            .collect();
        let (width, height) = r.size();
        Ok(Relit {
            r,
            reset,
            image: Image::new(width, height),
        })
    }

    pub(crate) fn set(&mut self, s: &Setting) -> Result<()> {
        for (name, values) in &self.reset {
            self.r.set_params(name, values)?;
        }
        for e in &s.edits {
            self.r
                .set_params(&e.material, &[e.value])
                .with_context(|| format!("setting '{}': {e}", s.label))?;
        }
        Ok(())
    }

    /// The frame of setting `s`, and what it cost.
    pub(crate) fn frame(&mut self, s: &Setting) -> Result<(&Image, RenderStats)> {
        self.set(s)?;
        let stats = self.r.render_into(self.image.pixels.as_flattened_mut())?;
        Ok((&self.image, stats))
    }

    pub(crate) fn image(&mut self, s: &Setting) -> Result<Vec<[f32; 3]>> {
        Ok(self.frame(s)?.0.pixels.clone())
    }
}

/// One relight variant under test.
pub(crate) struct VariantRun {
    pub(crate) label: String,
    pub(crate) rank: Option<usize>,
    pub(crate) variant: Variant,
    pub(crate) path: PathBuf,
    pub(crate) file_bytes: u64,
}

#[derive(Clone, Debug)]
pub(crate) struct RelightTiming {
    pub(crate) label: String,
    pub(crate) rank: Option<usize>,
    pub(crate) file_bytes: u64,
    pub(crate) bytes_read: u64,
    pub(crate) median_s: f64,
    pub(crate) min_s: f64,
    pub(crate) max_s: f64,
    /// Uncompressed variants: the median time of the frame's reads alone
    /// (`PixelRelighter::time_reads`), timed right after each of its frames.
    pub(crate) reads_median_s: Option<f64>,
    /// Largest relative L2 difference to the uncompressed relight over the settings.
    pub(crate) added_error: Option<f64>,
}

/// Times every variant, interleaved frame by frame (so a burst of load on the shared machine
/// hits all variants alike): two warm-up rounds, then `frames` rounds, the settings cycling
/// between rounds (each frame restores the starting values and applies a setting's edits).
/// Added error: largest relative L2 difference of each variant to the first one over the
/// settings.
pub(crate) fn time_variants(
    runs: &[VariantRun],
    settings: &[Setting],
    frames: usize,
    stream: &mut StreamBench,
    stream_every: usize,
) -> Result<(Vec<RelightTiming>, Vec<f64>, Vec<f64>)> {
    let mut rls = runs
        .iter()
        .map(|v| Relit::open(&v.path, v.variant))
        .collect::<Result<Vec<_>>>()?;
    let mut times = vec![Vec::with_capacity(frames); runs.len()];
    let mut reads = vec![Vec::with_capacity(frames); runs.len()];
    let mut scratch = Vec::new();
    let mut bytes = vec![0u64; runs.len()];
    let mut rates = Vec::new();
    let mut write_rates = Vec::new();
    for f in 0..frames + 2 {
        if f >= 2 && (f - 2) % stream_every.max(1) == 0 {
            rates.push(stream.run());
            write_rates.push(stream.run_write());
        }
        let s = &settings[f % settings.len()];
        for (i, (r, v)) in rls.iter_mut().zip(runs).enumerate() {
            let (_, stats) = r.frame(s)?;
            bytes[i] = stats.bytes_read.unwrap_or(0);
            if f >= 2 {
                times[i].push(stats.seconds);
            }
            if v.variant == Variant::Full {
                let pass = r.r.time_reads(&mut scratch)?;
                if f >= 2 {
                    reads[i].push(pass.seconds);
                }
            }
        }
    }
    let mut added = vec![0.0f64; runs.len()];
    for s in settings {
        let base = rls[0].image(s)?;
        for (i, r) in rls.iter_mut().enumerate().skip(1) {
            added[i] = added[i].max(relative_l2(&r.image(s)?, &base));
        }
    }
    let rows = runs
        .iter()
        .enumerate()
        .map(|(i, v)| RelightTiming {
            label: v.label.clone(),
            rank: v.rank,
            file_bytes: v.file_bytes,
            bytes_read: bytes[i],
            median_s: median(&times[i]),
            min_s: times[i].iter().copied().fold(f64::INFINITY, f64::min),
            max_s: times[i].iter().copied().fold(0.0, f64::max),
            reads_median_s: (!reads[i].is_empty()).then(|| median(&reads[i])),
            added_error: (i > 0 && v.variant == Variant::Compressed).then_some(added[i]),
        })
        .collect();
    Ok((rows, rates, write_rates))
}

/// Relit images of every setting from one bake file.
pub(crate) fn relight_all(
    path: &Path,
    settings: &[Setting],
    v: Variant,
) -> Result<Vec<Vec<[f32; 3]>>> {
    let mut r = Relit::open(path, v)?;
    settings.iter().map(|s| r.image(s)).collect()
}

pub(crate) fn write_bake(bake: &PixelBake, path: &Path) -> Result<u64> {
    pixel::write_bake_file(bake, path, Precision::F16)
        .map_err(anyhow::Error::msg)
        .with_context(|| format!("writing {}", path.display()))
}

pub(crate) fn remove(path: &Path) {
    let _ = std::fs::remove_file(path);
}

pub(crate) fn err_norm_diff(a: &[[f32; 3]], b: &[[f32; 3]]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (0..3).map(|c| ((x[c] - y[c]) as f64).powi(2)).sum::<f64>())
        .sum::<f64>()
        .sqrt()
}

pub(crate) fn err_norm(a: &[[f32; 3]]) -> f64 {
    a.iter()
        .map(|p| p.iter().map(|&v| (v as f64).powi(2)).sum::<f64>())
        .sum::<f64>()
        .sqrt()
}
