//! The `bake` command's jobs, as library functions: load a config's scene, build the bases
//! its editable materials need, bake, write. The binaries only parse arguments.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context, Result};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use prt_formats::basis::BrdfBasis;

use crate::basis::{BasisBuilder, BasisConfig};
use crate::brdf::Family;
use crate::config::BakeConfig;
use crate::pixel::{self, PixelBakeOptions, Precision, SlotLayout};
use crate::scene::Scene;

/// Default number of basis BRDFs of an editable glossy family. Blinn-Phong keeps the thesis'
/// 6 (mean 0.70 %, max 2.6 % relative L2 over s in [1, 200]). GGX gets 8: at 6 the truncated
/// PCA misses the reflectance (albedo) of sharp lobes by 37 % at alpha = 0.05, at 8 by at most
/// 2.4 % for alpha >= 0.05 (docs/brdf-basis.md).
pub fn default_basis_count(family: Family) -> usize {
    match family {
        Family::Ggx => 8,
        _ => 6,
    }
}

/// A progress bar on stderr over `len` steps (hidden when stderr is not a terminal).
pub fn progress_bar(len: u64, what: &str) -> ProgressBar {
    let bar = ProgressBar::with_draw_target(Some(len), ProgressDrawTarget::stderr());
    let style =
        ProgressStyle::with_template("{msg} [{bar:40}] {pos}/{len} rows, {elapsed} (eta {eta})")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> ");
    bar.set_style(style);
    bar.set_message(what.to_string());
    bar
}

/// Loads the config and its scene, with errors that name the file.
pub fn load(config_path: &Path) -> Result<(BakeConfig, Scene)> {
    let config = BakeConfig::from_file(config_path)?;
    let scene = crate::scene::load(&config)?;
    if scene.triangles.is_empty() {
        bail!(
            "{}: the scene has no valid triangles",
            config.scene_path.display()
        );
    }
    Ok((config, scene))
}

/// How many basis BRDFs each editable glossy family gets.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum BasisCount {
    Fixed(usize),
    /// The smallest N_b in 2..=12 whose max relative L2 reconstruction error over the family's
    /// sampled lobes (docs/brdf-basis.md) is at most this.
    ErrorTarget(f64),
    /// [`default_basis_count`] per family.
    Default,
}

/// Largest N_b the error-target selection considers.
const MAX_SELECTED_COUNT: usize = 12;

/// Picks N_b for `family` by error target (measured on the family's default sampling).
fn count_for_target(family: Family, target: f64, verbose: bool) -> Result<usize> {
    if target.is_nan() || target <= 0.0 {
        bail!("the basis error target must be a positive relative error, e.g. 0.01 (got {target})");
    }
    let cfg = BasisConfig::new(family, MAX_SELECTED_COUNT).map_err(anyhow::Error::msg)?;
    let counts: Vec<usize> = (2..=MAX_SELECTED_COUNT).collect();
    let (report, _) =
        crate::basis::select::family_report(&cfg, &counts, 2, 64).map_err(anyhow::Error::msg)?;
    let chosen = crate::basis::select::select_count(&report, target, false);
    let nb = chosen.unwrap_or(MAX_SELECTED_COUNT);
    if verbose {
        let err = report
            .rows
            .iter()
            .find(|r| r.num_bases == nb)
            .map_or(f64::NAN, |r| r.ours.max);
        match chosen {
            Some(_) => eprintln!(
                "basis {}: N_b = {nb} meets the error target {} (max relative L2 error {err:.4})",
                family.name(),
                target as f32
            ),
            None => eprintln!(
                "warning: basis {}: no N_b up to {MAX_SELECTED_COUNT} meets the error target {}; using {nb} (max error {err:.4})",
                family.name(),
                target as f32
            ),
        }
    }
    Ok(nb)
}

/// Builds one basis per family used by an editable glossy material.
pub fn build_bases(scene: &Scene, count: usize, verbose: bool) -> Result<Vec<BrdfBasis>> {
    build_bases_by(scene, BasisCount::Fixed(count), verbose)
}

/// Builds one basis per family used by an editable glossy material, sized by `count`.
pub fn build_bases_by(scene: &Scene, count: BasisCount, verbose: bool) -> Result<Vec<BrdfBasis>> {
    let mut families: Vec<Family> = Vec::new();
    for m in &scene.materials {
        if m.editable && m.brdf.family != Family::Diffuse && !families.contains(&m.brdf.family) {
            families.push(m.brdf.family);
        }
    }
    let mut out = Vec::new();
    for f in families {
        let start = Instant::now();
        let count = match count {
            BasisCount::Fixed(n) => n,
            BasisCount::ErrorTarget(t) => count_for_target(f, t, verbose)?,
            BasisCount::Default => default_basis_count(f),
        };
        let cfg = BasisConfig::new(f, count).map_err(anyhow::Error::msg)?;
        let built = BasisBuilder::new(cfg)
            .and_then(|b| b.build(count))
            .map_err(|e| anyhow::anyhow!("building the {} basis: {e}", f.name()))?;
        let basis = built.to_persisted();
        if verbose {
            eprintln!(
                "basis {}: {} BRDFs over {:?} built in {:.2} s",
                f.name(),
                basis.num_bases,
                basis.param_range,
                start.elapsed().as_secs_f64()
            );
        }
        out.push(basis);
    }
    Ok(out)
}

/// Command-line settings of a per-pixel bake on top of the config.
#[derive(Clone, Debug, Default)]
pub struct PixelRunSettings {
    pub spp: Option<u32>,
    pub width: Option<u32>,
    pub height: Option<u32>,
    pub output: Option<PathBuf>,
    pub precision: Option<Precision>,
    pub max_memory: Option<u64>,
    pub compress_rank: Option<usize>,
    pub basis_count: Option<usize>,
    pub quiet: bool,
}

/// What a bake did, for the CLI's summary and `--json`.
#[derive(Clone, Debug, serde::Serialize)]
pub struct PixelRunSummary {
    pub output: PathBuf,
    pub file_bytes: u64,
    pub estimated_bytes: u64,
    pub seconds: f64,
    pub basis_seconds: f64,
    pub stats: serde_json::Value,
}

/// Runs a per-pixel bake for a config.
pub fn run_pixel(
    config: &BakeConfig,
    scene: &Scene,
    s: &PixelRunSettings,
) -> Result<PixelRunSummary> {
    let start = Instant::now();
    // An explicit count wins; else the config's error target; else the default.
    let basis_cfg = config.basis.as_ref();
    let count = match (
        s.basis_count,
        basis_cfg.and_then(|b| b.count),
        basis_cfg.and_then(|b| b.error_target),
    ) {
        (Some(n), _, _) => BasisCount::Fixed(n),
        (None, Some(n), _) => BasisCount::Fixed(n as usize),
        (None, None, Some(t)) => BasisCount::ErrorTarget(t as f64),
        (None, None, None) => BasisCount::Default,
    };
    let bases = build_bases_by(scene, count, !s.quiet)?;
    let basis_seconds = start.elapsed().as_secs_f64();
    let layout = SlotLayout::new(scene, &bases).map_err(anyhow::Error::msg)?;
    let opts = PixelBakeOptions {
        width: s.width.unwrap_or(config.width),
        height: s.height.unwrap_or(config.height),
        spp: s.spp.unwrap_or(config.spp),
        reflections: config.reflections,
        seed: config.seed,
        precision: s.precision.unwrap_or(Precision::F32),
        max_memory: s.max_memory,
        compress_rank: s.compress_rank,
    };
    if opts.reflections as usize > crate::integrator::MAX_REFLECTIONS {
        bail!(
            "{}: reflections = {} but at most {} are supported",
            config.config_path.display(),
            opts.reflections,
            crate::integrator::MAX_REFLECTIONS
        );
    }
    let accel = crate::accel::Accel::build(scene);
    let lights = crate::lights::LightSet::new(scene);
    let integ = crate::integrator::Integrator::new(
        scene,
        &accel,
        &lights,
        opts.reflections as usize,
        opts.width,
        opts.height,
    );
    let est = pixel::estimate_memory(&integ, &layout, opts.reflections as usize);
    if !s.quiet {
        eprintln!("allocation ({} global slots):", layout.total_slots);
        for r in &layout.reasons {
            eprintln!("  {r}");
        }
        for (m, (&p, &v)) in layout
            .materials
            .iter()
            .zip(est.pixels_per_material.iter().zip(&est.values_per_pixel))
        {
            if p > 0 {
                eprintln!("  {}: ~{p} pixels x {v} values", m.name);
            }
        }
        eprintln!(
            "memory estimate: {} (dense accumulation; the file keeps only slots that carry light)",
            human_bytes(est.bytes)
        );
    }
    if let Some(max) = opts.max_memory {
        if est.bytes > max {
            bail!(
                "the bake needs about {} but --max-memory is {}: lower the resolution, the reflections or the basis count",
                human_bytes(est.bytes),
                human_bytes(max)
            );
        }
    }
    let bar = (!s.quiet).then(|| progress_bar(opts.height as u64, "baking"));
    let bake = pixel::bake(scene, &layout, &opts, bar.as_ref()).map_err(anyhow::Error::msg)?;
    if let Some(b) = bar {
        b.finish_and_clear();
    }
    let output = s.output.clone().unwrap_or_else(|| config.output.clone());
    let file_bytes = pixel::write_bake_file(&bake, &output, opts.precision)
        .map_err(anyhow::Error::msg)
        .with_context(|| format!("writing {}", output.display()))?;
    Ok(PixelRunSummary {
        output,
        file_bytes,
        estimated_bytes: est.bytes,
        seconds: start.elapsed().as_secs_f64(),
        basis_seconds,
        stats: bake.meta.stats.clone(),
    })
}

pub fn human_bytes(b: u64) -> String {
    let b = b as f64;
    if b >= 1e9 {
        format!("{:.2} GB", b / 1e9)
    } else if b >= 1e6 {
        format!("{:.1} MB", b / 1e6)
    } else if b >= 1e3 {
        format!("{:.1} kB", b / 1e3)
    } else {
        format!("{b} B")
    }
}

/// Parses sizes like `512M`, `4G` or `1000000` (bytes); suffixes are binary (`4G` = 4 GiB).
pub fn parse_size(s: &str) -> Result<u64, String> {
    let t = s.trim();
    let (num, mul) = match t.char_indices().last() {
        Some((i, c)) if c.is_ascii_alphabetic() => {
            let mul = match c.to_ascii_uppercase() {
                'K' => 1u64 << 10,
                'M' => 1 << 20,
                'G' => 1 << 30,
                'T' => 1 << 40,
                _ => {
                    return Err(format!(
                        "'{s}': unknown size suffix '{c}' (use K, M, G or T)"
                    ))
                }
            };
            (&t[..i], mul)
        }
        _ => (t, 1),
    };
    let v: f64 = num
        .trim()
        .parse()
        .map_err(|_| format!("'{s}' is not a size (e.g. 512M, 4G)"))?;
    if !(v.is_finite() && v > 0.0) {
        return Err(format!("'{s}': the size must be positive"));
    }
    Ok((v * mul as f64) as u64)
}

/// Applies a `--set MATERIAL.PARAM=VALUE` edit to the scene's true BRDFs (for the reference
/// tracer). Errors name the material and what is wrong.
pub fn apply_override(scene: &mut Scene, o: &prt_formats::MaterialOverride) -> Result<()> {
    use prt_formats::OverrideValue;
    let names: Vec<&str> = scene.materials.iter().map(|m| m.name.as_str()).collect();
    prt_formats::check_material(&o.material, &names)?;
    let Some(i) = scene.material_index(&o.material) else {
        bail!("unknown material '{}'", o.material);
    };
    let b = &mut scene.materials[i].brdf;
    let family = b.family;
    let wrong = |p: &str| {
        anyhow::anyhow!(
            "material '{}' is {}: it has no parameter '{p}'",
            o.material,
            family.name()
        )
    };
    match o.value {
        OverrideValue::Kd(c) => b.kd = glam::Vec3::from_array(c),
        OverrideValue::Ks(c) if family != Family::Diffuse => b.ks = glam::Vec3::from_array(c),
        OverrideValue::Shininess(v) if family == Family::BlinnPhong => b.param = v,
        OverrideValue::Alpha(v) if family == Family::Ggx => b.param = v,
        ref other => return Err(wrong(&other.param().to_string())),
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::parse_size;

    #[test]
    fn sizes_parse_with_binary_suffixes_and_reject_garbage() {
        assert_eq!(parse_size("1000"), Ok(1000));
        assert_eq!(parse_size("4G"), Ok(4 << 30));
        assert_eq!(parse_size("512m"), Ok(512 << 20));
        assert_eq!(parse_size(" 1.5K "), Ok(1536));
        for bad in ["", "G", "abc", "12Q", "-5M", "0", "nanG", "1e999"] {
            let e = parse_size(bad).expect_err(bad);
            assert!(e.contains(bad.trim()) || e.contains("size"), "{bad}: {e}");
        }
    }
}
