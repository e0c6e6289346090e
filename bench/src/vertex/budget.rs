//! The per-vertex error budget (`bench budget`; "Error budget" in docs/report-vertex.md): a
//! scene's relit image against converged ground truth, split by region (what each pixel's
//! camera ray meets first: every material, and the background) and by part of the method,
//! each part measured by moving one approximation to (or towards) its exact limit while the
//! rest is held.
//!
//! Ground truth is the mean of `--references` reference renders with independent seeds, and
//! its own noise is measured, not assumed: the two half-means (odd and even seeds) differ by
//! `2 x` the mean's standard error in expectation (each half has twice the mean's variance),
//! so half their relative L2 is the truth's noise, reported beside every figure.
//!
//! The parts:
//! - **compression**: the default (compressed) bake against the dense bake of the same trace;
//! - **bake noise**: the dense bake against a dense bake with another seed, over sqrt 2 (the
//!   Monte Carlo noise of one bake's tensors at the config's N1);
//! - **T0's Haar truncation**: the dense bake against a dense bake keeping `--t0-terms` Haar
//!   terms per row instead of the config's;
//! - **the rest** (the last reflection's Tucker shading and specular split, the 6x16x16
//!   visibility, I1's order-4 SH, per-vertex interpolation, the rasterizer's pixel centres):
//!   the dense bake with the most terms against the truth; what the parts above do not
//!   explain. It is split three ways, each against the full truth's magnitude so that the
//!   parts' squares add up to the rest's (where they do not correlate):
//!   - **direct light**: that bake relit with I1 and I2 off
//!     (`VertexRelighter::set_direct_light_only`) against a second ground truth traced with
//!     one reflection (the light seen directly, reflected once: I0 exactly);
//!     It is split again: the **shading basis** (the Tucker residual, the specular split's
//!     Gaussians and where they are read) by the same image with the true lobe at the last
//!     reflection (`VertexRelighter::set_true_lobe`, the baker's lobes, 4096 stratified draws
//!     of the lobe and as many of the map per pixel; its noise measured with a quarter of the
//!     draws) against the same incident light; what is left of I0 (the 6x16x16
//!     visibility, per-vertex interpolation, pixel centres) by that image against the truth;
//!   - **reflected light**: the relit image less its direct part against the truth less its
//!     one-reflection part (I1 and I2 against the light after two or more reflections);
//!   - **antialiasing**: the relit image (its silhouettes and creases sampled 16 times per
//!     pixel, `VertexRelighter::set_antialias`) against the same with every pixel shaded at
//!     its centre alone: what the antialiasing changes;
//!   - **pixel centres left**: the relit image against the same relighter rendered 2 x 2 per
//!     pixel and averaged, as the reference's jittered rays average silhouettes and textures:
//!     what the antialiasing leaves.
//!
//! A part's figure is the relative L2 (and mean ratio) of the image it changes, per region;
//! a mean ratio away from 1 by more than the noise is a bias.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use std::sync::Arc;

use anyhow::{bail, Context as _, Result};
use glam::{Vec2, Vec3};
use prt_bake::brdf::{Family, Lobe as _};
use prt_bake::config::BakeConfig;
use prt_bake::metrics::{region_error, relative_l2, RegionError};
use prt_bake::progress::Silent;
use prt_bake::run::load;
use prt_bake::scene::Scene;
use prt_runtime::hooks::TrueLobe;

use super::measure::{lit, map_intensity, reference, render, Light, Pixels, LIGHTS};
use super::sweep::{self, Setting};
use crate::util::{cpu_model, git_head, load_average, utc_now};

/// Where a scene's section starts and ends in the report (one section per config, named by
/// its folder: `<!-- bench budget gallery: begin -->`).
fn markers(config: &Path) -> (String, String) {
    let name = config
        .parent()
        .and_then(|p| p.file_name())
        .map_or_else(|| "scene".to_string(), |n| n.to_string_lossy().into_owned());
    (
        format!("<!-- bench budget {name}: begin -->"),
        format!("<!-- bench budget {name}: end -->"),
    )
}

/// Arguments of `bench budget`.
#[derive(clap::Args, Debug)]
pub struct BudgetArgs {
    /// The scene (a per-vertex config).
    #[arg(long, default_value = "scenes/gallery/bake.toml")]
    pub config: PathBuf,
    /// Image side (square images from the config's camera).
    #[arg(long, default_value_t = 128)]
    pub size: u32,
    /// Reference renders with independent seeds averaged into the ground truth (at least 2:
    /// their halves measure its noise).
    #[arg(long, default_value_t = 8)]
    pub references: u32,
    /// Samples per pixel of each reference render.
    #[arg(long, default_value_t = 1024)]
    pub reference_spp: u32,
    /// Haar terms per T0 row of the bake that measures T0's truncation (24 576 keeps every
    /// term: exact, and about 100 KB per row per vertex).
    #[arg(long, default_value_t = 1536)]
    pub t0_terms: u32,
    /// The report whose budget section is replaced (appended when it has none); `-` prints
    /// the section only.
    #[arg(long, default_value = "docs/report-vertex.md")]
    pub out: PathBuf,
    /// Scratch folder for the bake files (removed after use).
    #[arg(long, default_value = "target/report/budget")]
    pub work_dir: PathBuf,
}

/// The regions of an image: every material the camera sees, then the background.
struct Regions {
    names: Vec<String>,
    /// Per region, per pixel: inside.
    masks: Vec<Vec<bool>>,
}

impl Regions {
    fn of(scene: &Scene, size: u32) -> Regions {
        let first = prt_bake::view::first_hit_materials(scene, size, size);
        let mut names = Vec::new();
        let mut masks = Vec::new();
        for (m, mat) in scene.materials.iter().enumerate() {
            let mask: Vec<bool> = first.iter().map(|f| *f == Some(m as u32)).collect();
            if mask.iter().any(|&x| x) {
                names.push(mat.name.clone());
                masks.push(mask);
            }
        }
        let background: Vec<bool> = first.iter().map(Option::is_none).collect();
        if background.iter().any(|&x| x) {
            names.push("background".into());
            masks.push(background);
        }
        Regions { names, masks }
    }

    /// The L2 norm of `image` over the whole image, then over each region.
    fn norms(&self, image: &[[f32; 3]]) -> Vec<f64> {
        let all = vec![true; image.len()];
        std::iter::once(&all)
            .chain(&self.masks)
            .map(|m| {
                image
                    .iter()
                    .zip(m)
                    .filter(|(_, &inside)| inside)
                    .map(|(p, _)| p.iter().map(|&c| f64::from(c).powi(2)).sum::<f64>())
                    .sum::<f64>()
                    .sqrt()
            })
            .collect()
    }

    /// The whole image, then each region.
    fn errors(&self, a: &[[f32; 3]], b: &[[f32; 3]]) -> Vec<RegionError> {
        let all = vec![true; a.len()];
        std::iter::once(&all)
            .chain(&self.masks)
            .map(|m| region_error(a, b, m))
            .collect()
    }
}

/// Ground truth under one light: the mean of the renders, and its noise per region (the
/// whole image first).
struct Truth {
    mean: Pixels,
    noise: Vec<RegionError>,
}

fn mean_of(images: &[Pixels]) -> Pixels {
    let n = images.len().max(1) as f32;
    (0..images[0].len())
        .map(|i| {
            let mut s = [0.0f32; 3];
            for img in images {
                for c in 0..3 {
                    s[c] += img[i][c];
                }
            }
            s.map(|v| v / n)
        })
        .collect()
}

/// The ground truth under `light` traced with `reflections` reflections (the config's, or 1:
/// the direct light alone).
fn truth(
    args: &BudgetArgs,
    config: &BakeConfig,
    scene: &Scene,
    light: &Light,
    regions: &Regions,
    reflections: u32,
) -> Result<Truth> {
    let k = args.references.max(2);
    let config = &BakeConfig {
        reflections,
        ..config.clone()
    };
    let mut renders = Vec::new();
    for i in 0..k {
        eprintln!(
            "budget: reference {} of {k} under {} ({} spp, {reflections} reflection(s))",
            i + 1,
            light.name,
            args.reference_spp
        );
        // Seeds away from the bake's, so no stream is shared with it.
        let seed = config.seed.wrapping_add(1_000_003 * (u64::from(i) + 1));
        renders.push(reference(
            config,
            scene,
            light,
            args.size,
            args.reference_spp,
            seed,
        )?);
    }
    let (odd, even): (Vec<_>, Vec<_>) = renders
        .iter()
        .cloned()
        .enumerate()
        .partition(|(i, _)| i % 2 == 1);
    let odd: Vec<Pixels> = odd.into_iter().map(|(_, p)| p).collect();
    let even: Vec<Pixels> = even.into_iter().map(|(_, p)| p).collect();
    let mean = mean_of(&renders);
    let noise = regions
        .errors(&mean_of(&odd), &mean_of(&even))
        .into_iter()
        .map(|mut e| {
            // Half the halves' difference: the mean's standard error (see the module
            // documentation); the ratio's distance from 1 likewise.
            e.relative_l2 *= 0.5;
            e.mean_ratio = 1.0 + 0.5 * (e.mean_ratio - 1.0).abs();
            e.squared_share *= 0.25;
            e
        })
        .collect();
    Ok(Truth { mean, noise })
}

/// The bakes, in order: defaults (compressed), dense (the same trace), dense with another
/// seed, dense with more T0 terms.
fn settings(args: &BudgetArgs) -> Vec<Setting> {
    let defaults = Setting::defaults();
    let dense = Setting {
        label: "dense".into(),
        compress: false,
        ..Setting::defaults()
    };
    let noise = Setting::noise_floor();
    let t0 = Setting {
        label: format!("dense, {} T0 terms", args.t0_terms),
        compress: false,
        t0_terms: Some(args.t0_terms),
        ..Setting::defaults()
    };
    vec![defaults, dense, noise, t0]
}

/// Runs the measurements and writes the section; returns it.
pub fn run(args: &BudgetArgs) -> Result<String> {
    if args.size == 0 {
        bail!("--size must be at least 1");
    }
    let (config, scene) = load(&args.config, &Silent)?;
    std::fs::create_dir_all(&args.work_dir)
        .with_context(|| format!("creating {}", args.work_dir.display()))?;
    let regions = Regions::of(&scene, args.size);
    let truths = LIGHTS
        .iter()
        .map(|l| truth(args, &config, &scene, l, &regions, config.reflections))
        .collect::<Result<Vec<_>>>()?;
    let direct_truths = LIGHTS
        .iter()
        .map(|l| truth(args, &config, &scene, l, &regions, 1))
        .collect::<Result<Vec<_>>>()?;

    let settings = settings(args);
    let mut baked = sweep::bake_from_one_trace(
        &config,
        &scene,
        &settings[..2],
        &args.work_dir,
        "budget",
        false,
    )?;
    baked.extend(sweep::bake_each(
        &config,
        &scene,
        &settings[2..],
        &args.work_dir,
        "budget-more",
        false,
    )?);
    let intensity = map_intensity(&config);
    // images[bake][light]; the last bake (the most T0 terms) also with the direct light
    // alone and 2 x 2 per pixel: split[light].
    let mut images: Vec<Vec<Pixels>> = Vec::new();
    let mut split = Vec::new();
    for (i, b) in baked.iter().enumerate() {
        let mut per_light = Vec::new();
        for light in &LIGHTS {
            let mut r = lit(&b.path, light, intensity)?;
            per_light.push(render(&mut r, args.size)?.0);
            if i + 1 == baked.len() {
                let supersampled = box_down(&render(&mut r, 2 * args.size)?.0, 2 * args.size);
                r.set_antialias(false);
                let centres = render(&mut r, args.size)?.0;
                r.set_antialias(true);
                r.set_direct_light_only(true);
                let direct = render(&mut r, args.size)?.0;
                r.set_true_lobe(Some((Arc::new(BakerLobe), TRUE_LOBE_SIDE)));
                let direct_true_lobe = render(&mut r, args.size)?.0;
                r.set_true_lobe(Some((Arc::new(BakerLobe), TRUE_LOBE_SIDE / 2)));
                let direct_true_lobe_quarter = render(&mut r, args.size)?.0;
                split.push(Split {
                    direct,
                    direct_true_lobe,
                    direct_true_lobe_quarter,
                    supersampled,
                    centres,
                });
            }
        }
        images.push(per_light);
        let _ = std::fs::remove_file(&b.path);
    }

    let section = section(
        args,
        &regions,
        &settings,
        &Measured {
            truths,
            direct_truths,
            images,
            split,
        },
    );
    if args.out.as_os_str() != "-" {
        let (begin, end) = markers(&args.config);
        crate::util::write_section(&args.out, &section, &begin, &end)?;
    }
    Ok(section)
}

/// The relit images that split "the rest" under one light.
struct Split {
    /// I1 and I2 off.
    direct: Pixels,
    /// I1 and I2 off, the true lobe at the last reflection.
    direct_true_lobe: Pixels,
    /// The same with a quarter of the draws (its difference measures the noise).
    direct_true_lobe_quarter: Pixels,
    /// 2 x 2 per pixel, averaged.
    supersampled: Pixels,
    /// Antialiasing off: every pixel shaded at its centre alone.
    centres: Pixels,
}

/// Draws per side of the true lobe's stratified grids per pixel (`set_true_lobe`): 4096 of
/// the lobe and 4096 of the map. The noise of that image is measured beside it: the same
/// with a quarter of the draws differs from it by `sqrt(4 + 1)` times its own noise.
const TRUE_LOBE_SIDE: u32 = 64;

/// The baker's lobes (its sampler and evaluation) for the runtime's true-lobe switch.
struct BakerLobe;

impl TrueLobe for BakerLobe {
    fn sample(&self, family: Family, param: f32, wo: [f32; 3], u: [f32; 2]) -> Option<[f32; 3]> {
        let wo = Vec3::from(wo);
        let h = family.sample_half(param, Vec2::from(u))?;
        let wi = 2.0 * wo.dot(h) * h - wo;
        (wi.z > 0.0).then(|| wi.to_array())
    }

    fn eval(&self, family: Family, param: f32, wo: [f32; 3], wi: [f32; 3]) -> (f32, f32) {
        let (wo, wi) = (Vec3::from(wo), Vec3::from(wi));
        (
            family.specular_lobe(param, wo, wi) * wi.z.max(0.0),
            family.lobe_pdf(param, wo, wi),
        )
    }
}

/// Everything a section reports: per light, the truths and the relit images.
struct Measured {
    truths: Vec<Truth>,
    /// Traced with one reflection.
    direct_truths: Vec<Truth>,
    /// `[bake][light]`.
    images: Vec<Vec<Pixels>>,
    /// `[light]`, of the last bake.
    split: Vec<Split>,
}

/// The mean of each 2 x 2 block of a `side` x `side` image (rows first): the image at half
/// the side, each pixel the average over its area.
fn box_down(image: &[[f32; 3]], side: u32) -> Pixels {
    let (side, half) = (side as usize, side as usize / 2);
    let mut out = vec![[0.0f32; 3]; half * half];
    for (i, o) in out.iter_mut().enumerate() {
        let (x, y) = (2 * (i % half), 2 * (i / half));
        for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
            let p = image[(y + dy) * side + x + dx];
            for c in 0..3 {
                o[c] += 0.25 * p[c];
            }
        }
    }
    out
}

/// `a - b`, pixel by pixel.
fn difference(a: &[[f32; 3]], b: &[[f32; 3]]) -> Pixels {
    a.iter()
        .zip(b)
        .map(|(x, y)| [x[0] - y[0], x[1] - y[1], x[2] - y[2]])
        .collect()
}

/// `a` against `b` per region (the whole image first), the relative L2 taken over the
/// `truth`'s magnitude instead of `b`'s: the part's contribution to the image's error. The
/// mean ratio stays `a`'s over `b`'s.
fn contribution(
    regions: &Regions,
    a: &[[f32; 3]],
    b: &[[f32; 3]],
    truth: &[[f32; 3]],
) -> Vec<RegionError> {
    over_truth(regions, regions.errors(a, b), b, truth)
}

/// `errors`, relative L2s taken over `of`'s magnitude per region, retaken over `truth`'s.
fn over_truth(
    regions: &Regions,
    errors: Vec<RegionError>,
    of: &[[f32; 3]],
    truth: &[[f32; 3]],
) -> Vec<RegionError> {
    let (of_own, of_truth) = (regions.norms(of), regions.norms(truth));
    errors
        .into_iter()
        .zip(of_own.iter().zip(&of_truth))
        .map(|(mut e, (no, nt))| {
            e.relative_l2 *= no / nt;
            e
        })
        .collect()
}

fn pct(x: f64) -> String {
    if x.is_nan() {
        "-".into()
    } else {
        format!("{:.1} %", 100.0 * x)
    }
}

fn ratio(x: f64) -> String {
    if x.is_nan() {
        "-".into()
    } else {
        format!("{x:.3}")
    }
}

fn section(args: &BudgetArgs, regions: &Regions, settings: &[Setting], m: &Measured) -> String {
    let (truths, images) = (&m.truths, &m.images);
    let (begin, end) = markers(&args.config);
    let mut s = String::new();
    let _ = writeln!(s, "{begin}");
    let name = begin
        .trim_start_matches("<!-- bench budget ")
        .trim_end_matches(": begin -->")
        .to_string();
    let _ = writeln!(s, "### {name}\n");
    let _ = writeln!(
        s,
        "Generated by `cargo run --release -p prt-bench -- budget --config {} --size {} --references {} --reference-spp {}` on {} ({}, \
         load {}, commit {}). {}x{} images from the config's camera. Ground truth: the mean of \
         {} reference renders of {} spp with independent seeds ({} spp in all); its noise \
         (\"truth noise\") is half the distance between the means of the odd and the even \
         renders, measured the same way per region. Regions are what each pixel's camera ray \
         meets first. Each row's figures are relative L2 over the region (whole image first) \
         and, in brackets, the region's mean over the truth's: a ratio away from 1 by more \
         than the noise's is a bias. The background compares the runtime's average of the map \
         over each pixel (`k x k` lookups, docs/vertex.md) with the reference's (its jittered \
         camera rays). The indented rows split \"the rest\", each over the truth's magnitude \
         so that their squares add up to the rest's where they do not correlate: the direct \
         light (the relit image with I1 and I2 off) against a second truth traced with one \
         reflection, the same number of renders and samples, itself split into the shading \
         basis (the direct light against the same with the true BRDF at the last reflection, \
         4096 stratified draws of the lobe and as many of the map per pixel, combined by the \
         balance heuristic, against the same incident light; its own noise measured beside it) and what is \
         left of it (that image against the truth: visibility, interpolation, pixel centres); \
         the reflected light (each image less its direct part); antialiasing (the relit \
         image, whose silhouettes and creases are sampled 16 times per pixel, against the same \
         with every pixel shaded at its centre alone: what the antialiasing changes); the pixel \
         centres left (the relit image against the same relighter rendered 2 x 2 per pixel and \
         averaged, as the reference's jittered rays average silhouettes and textures: what \
         the antialiasing leaves). Method: `bench/src/vertex/budget.rs`.\n",
        args.config.display(),
        args.size,
        args.references.max(2),
        args.reference_spp,
        utc_now(),
        cpu_model(),
        load_average(),
        git_head().unwrap_or_else(|| "unknown".into()),
        args.size,
        args.size,
        args.references.max(2),
        args.reference_spp,
        args.references.max(2) as u64 * u64::from(args.reference_spp),
    );
    let header = |s: &mut String, first: &str| {
        let _ = write!(s, "| {first} | whole image |");
        for n in &regions.names {
            let _ = write!(s, " {n} |");
        }
        let _ = writeln!(s);
        let _ = write!(s, "| --- | ---: |");
        for _ in &regions.names {
            let _ = write!(s, " ---: |");
        }
        let _ = writeln!(s);
    };
    let row = |s: &mut String, label: &str, errs: &[RegionError], with_ratio: bool| {
        let _ = write!(s, "| {label} |");
        for e in errs {
            if with_ratio {
                let _ = write!(s, " {} ({}) |", pct(e.relative_l2), ratio(e.mean_ratio));
            } else {
                let _ = write!(s, " {} |", pct(e.relative_l2));
            }
        }
        let _ = writeln!(s);
    };
    let _ = writeln!(
        s,
        "Pixels per region: {}.\n",
        regions
            .names
            .iter()
            .zip(&regions.masks)
            .map(|(n, m)| format!("{n} {}", m.iter().filter(|&&x| x).count()))
            .collect::<Vec<_>>()
            .join(", ")
    );
    let (defaults, dense, seed, t0) = (0, 1, 2, 3);
    for (li, light) in LIGHTS.iter().enumerate() {
        let truth = &truths[li];
        let _ = writeln!(s, "#### {name}, {}\n", light.name);
        header(&mut s, "against the truth");
        row(&mut s, "truth noise", &truth.noise, true);
        for (b, setting) in settings.iter().enumerate() {
            row(
                &mut s,
                &setting.label,
                &regions.errors(&images[b][li], &truth.mean),
                true,
            );
        }
        let _ = writeln!(s);
        header(&mut s, "part (the image it changes)");
        let part = |a: usize, b: usize| regions.errors(&images[a][li], &images[b][li]);
        row(
            &mut s,
            "compression (defaults vs dense)",
            &part(defaults, dense),
            true,
        );
        let mut noise = part(seed, dense);
        for e in &mut noise {
            e.relative_l2 /= std::f64::consts::SQRT_2;
        }
        row(
            &mut s,
            "bake noise (dense vs seed + 1, / sqrt 2)",
            &noise,
            false,
        );
        row(
            &mut s,
            &format!("T0 truncation (dense vs {} terms)", args.t0_terms),
            &part(dense, t0),
            true,
        );
        row(
            &mut s,
            &format!("the rest ({} T0 terms vs truth)", args.t0_terms),
            &regions.errors(&images[t0][li], &truth.mean),
            true,
        );
        let (split, one) = (&m.split[li], &m.direct_truths[li]);
        // The one-reflection truth's noise over the full truth's magnitude.
        let one_noise = over_truth(regions, one.noise.clone(), &one.mean, &truth.mean);
        let reflected_truth = difference(&truth.mean, &one.mean);
        let mut share = regions.errors(&reflected_truth, &truth.mean);
        for e in &mut share {
            e.relative_l2 = e.mean_ratio;
        }
        row(
            &mut s,
            "&nbsp; reflected light's share of the truth's mean",
            &share,
            false,
        );
        row(
            &mut s,
            "&nbsp; noise of the truth of one reflection",
            &one_noise,
            false,
        );
        row(
            &mut s,
            "&nbsp; direct light (I0 alone vs the truth of one reflection)",
            &contribution(regions, &split.direct, &one.mean, &truth.mean),
            true,
        );
        let mut lobe_noise = contribution(
            regions,
            &split.direct_true_lobe_quarter,
            &split.direct_true_lobe,
            &truth.mean,
        );
        for e in &mut lobe_noise {
            e.relative_l2 /= 5f64.sqrt();
        }
        row(
            &mut s,
            "&nbsp; &nbsp; noise of I0 with the true BRDF (its draws' Monte Carlo error)",
            &lobe_noise,
            false,
        );
        row(
            &mut s,
            "&nbsp; &nbsp; shading basis (I0 vs I0 with the true BRDF at the last reflection)",
            &contribution(regions, &split.direct, &split.direct_true_lobe, &truth.mean),
            true,
        );
        row(
            &mut s,
            "&nbsp; &nbsp; the rest of I0 (I0 with the true BRDF vs the truth of one reflection)",
            &contribution(regions, &split.direct_true_lobe, &one.mean, &truth.mean),
            true,
        );
        row(
            &mut s,
            "&nbsp; reflected light (the rest less I0 vs the truth less one reflection's)",
            &contribution(
                regions,
                &difference(&images[t0][li], &split.direct),
                &reflected_truth,
                &truth.mean,
            ),
            true,
        );
        row(
            &mut s,
            "&nbsp; antialiasing (the same with every pixel shaded at its centre alone)",
            &contribution(regions, &images[t0][li], &split.centres, &truth.mean),
            true,
        );
        row(
            &mut s,
            "&nbsp; pixel centres left (vs the same 2 x 2 per pixel, averaged)",
            &contribution(regions, &images[t0][li], &split.supersampled, &truth.mean),
            true,
        );
        row(
            &mut s,
            "the rest at 2 x 2 per pixel (vs truth)",
            &regions.errors(&split.supersampled, &truth.mean),
            true,
        );
        let whole = relative_l2(&images[defaults][li], &truth.mean);
        let _ = writeln!(
            s,
            "\nThe defaults' whole-image error: {} against truth noise {}.\n",
            pct(whole),
            pct(truth.noise[0].relative_l2)
        );
    }
    let _ = writeln!(s, "{end}");
    s
}
