//! The report's bake settings: the `[vertex]` keys each one changes, and the bakes. The main
//! scene's settings differ only in compression keys, so it is traced once and every setting
//! is compressed from the kept checkpoint (`bake --keep-checkpoint` / `--resume`); the
//! detail scene's settings (kept Haar terms, samples) change the trace, so each is baked whole.

use std::path::{Path, PathBuf};

use anyhow::{Context as _, Result};
use prt_bake::config::{BakeConfig, VertexConfig};
use prt_bake::progress::Silent;
use prt_bake::run::{run_vertex, CheckpointMode, VertexRunSettings};
use prt_bake::scene::Scene;
use prt_formats::pixel::Precision;

use crate::util::{peak_resident_bytes, reset_peak_resident};

/// One bake: a label, the knob it moves (for the plots), and the keys it sets.
#[derive(Clone, Debug)]
pub(crate) struct Setting {
    pub label: String,
    /// The knob's name ("" for the defaults and the dense bake).
    pub knob: &'static str,
    /// The knob's value (its plot's x).
    pub value: f64,
    pub compress: bool,
    pub cluster_vertices: Option<u32>,
    pub compress_error: Option<f32>,
    pub vertex_rank: Option<u32>,
    pub light_rank: Option<u32>,
    pub t0_terms: Option<u32>,
    pub spp: Option<u32>,
    /// Added to the config's seed (the noise floor's second dense bake).
    pub seed_offset: u64,
}

impl Setting {
    pub(crate) fn defaults() -> Setting {
        Setting {
            label: "defaults".into(),
            knob: "",
            value: f64::NAN,
            compress: true,
            cluster_vertices: None,
            compress_error: None,
            vertex_rank: None,
            light_rank: None,
            t0_terms: None,
            spp: None,
            seed_offset: 0,
        }
    }

    /// A dense bake with another seed: its distance from the dense bake is the Monte Carlo
    /// noise of the dense tensors, the floor under any "against the dense relight" error.
    pub(crate) fn noise_floor() -> Setting {
        Setting {
            label: "dense, seed + 1 (noise floor)".into(),
            compress: false,
            seed_offset: 1,
            ..Setting::defaults()
        }
    }

    /// The config with this setting's keys.
    fn apply(&self, config: &BakeConfig) -> BakeConfig {
        let mut c = config.clone();
        let v = c.vertex.get_or_insert_with(VertexConfig::default);
        v.compress = Some(self.compress);
        v.cluster_vertices = self.cluster_vertices.or(v.cluster_vertices);
        v.compress_error = self.compress_error.or(v.compress_error);
        v.vertex_rank = self.vertex_rank.or(v.vertex_rank);
        v.light_rank = self.light_rank.or(v.light_rank);
        v.t0_terms = self.t0_terms.or(v.t0_terms);
        if let Some(spp) = self.spp {
            c.spp = spp;
        }
        c.seed += self.seed_offset;
        c
    }
}

/// A knob's settings, `label` formatted with the value.
fn knob(
    name: &'static str,
    values: &[f64],
    set: impl Fn(&mut Setting, f64),
    label: impl Fn(f64) -> String,
) -> Vec<Setting> {
    values
        .iter()
        .map(|&x| {
            let mut s = Setting::defaults();
            s.knob = name;
            s.value = x;
            s.label = label(x);
            set(&mut s, x);
            s
        })
        .collect()
}

/// The main scene's settings: the defaults first (they trace), the compression knobs, and the
/// dense bake last (it removes the checkpoint).
pub(crate) fn compression_settings(quick: bool) -> Vec<Setting> {
    let mut out = vec![Setting::defaults()];
    if !quick {
        out.extend(knob(
            "vertices per cluster",
            &[64.0, 128.0, 256.0, 512.0],
            |s, x| s.cluster_vertices = Some(x as u32),
            |x| format!("{x} vertices per cluster"),
        ));
        out.extend(knob(
            "vertex rank (eigenvectors)",
            &[8.0, 16.0],
            |s, x| s.vertex_rank = Some(x as u32),
            |x| format!("vertex rank {x}"),
        ));
        out.extend(knob(
            "light rank (light dimension)",
            &[16.0, 32.0],
            |s, x| s.light_rank = Some(x as u32),
            |x| format!("light rank {x}"),
        ));
        out.extend(knob(
            "error target",
            &[0.05, 0.2],
            |s, x| s.compress_error = Some(x as f32),
            |x| format!("error target {} %", x * 100.0),
        ));
    }
    out.push(Setting {
        label: "dense".into(),
        compress: false,
        ..Setting::defaults()
    });
    out
}

/// The detail scene's settings: the defaults, then kept Haar terms and samples (each retraces).
pub(crate) fn trace_settings(quick: bool) -> Vec<Setting> {
    let mut out = vec![Setting::defaults()];
    let (terms, spps): (&[f64], &[f64]) = if quick {
        (&[24.0], &[])
    } else {
        (&[24.0, 48.0, 192.0], &[16.0, 32.0, 128.0])
    };
    out.extend(knob(
        "kept Haar terms",
        terms,
        |s, x| s.t0_terms = Some(x as u32),
        |x| format!("{x} Haar terms"),
    ));
    out.extend(knob(
        "samples (spp)",
        spps,
        |s, x| s.spp = Some(x as u32),
        |x| format!("{x} spp"),
    ));
    out
}

/// A finished bake of a setting.
#[derive(Clone, Debug)]
pub(crate) struct Baked {
    pub path: PathBuf,
    pub file_bytes: u64,
    /// The whole run (pre-pass, bases, trace or checkpoint read, compression, write).
    pub seconds: f64,
    pub trace_seconds: f64,
    pub compress_seconds: f64,
    pub vertices_per_second: f64,
    /// Measured peak resident memory of the run (this process's, reset before it).
    pub peak_bytes: Option<u64>,
    pub estimated_bytes: u64,
}

fn bake_one(
    config: &BakeConfig,
    scene: &Scene,
    output: &Path,
    checkpoint: CheckpointMode,
    keep_checkpoint: bool,
    quick: bool,
) -> Result<Baked> {
    let run = VertexRunSettings {
        output: Some(output.to_path_buf()),
        precision: Some(Precision::F16),
        spp: quick.then_some(8),
        checkpoint,
        keep_traced: keep_checkpoint,
        ..Default::default()
    };
    let measured = reset_peak_resident();
    let summary = run_vertex(config, scene, &run, &Silent)
        .with_context(|| format!("baking {}", config.config_path.display()))?;
    Ok(Baked {
        path: output.to_path_buf(),
        file_bytes: summary.file_bytes,
        seconds: summary.seconds,
        trace_seconds: summary.timings.trace_seconds,
        compress_seconds: summary.timings.compress_seconds,
        vertices_per_second: summary.timings.vertices_per_second,
        peak_bytes: peak_resident_bytes().filter(|_| measured),
        estimated_bytes: summary.estimate.bytes,
    })
}

/// Bakes the compression settings of one scene from one trace: the first setting saves and
/// keeps a checkpoint, the others resume from it (no ray traced), the last removes it.
pub(crate) fn bake_from_one_trace(
    config: &BakeConfig,
    scene: &Scene,
    settings: &[Setting],
    dir: &Path,
    stem: &str,
    quick: bool,
) -> Result<Vec<Baked>> {
    let traced = dir.join(format!("{stem}.prtbake"));
    let checkpoint = prt_bake::shard::checkpoint_folder(&traced);
    if checkpoint.exists() {
        // A previous report run that stopped part-way: its checkpoint is this run's only if
        // its inputs match, which `Resume` checks; start clean instead of reasoning about it.
        std::fs::remove_dir_all(&checkpoint)
            .with_context(|| format!("removing {}", checkpoint.display()))?;
    }
    let mut out = Vec::new();
    for (i, s) in settings.iter().enumerate() {
        eprintln!(
            "{stem}: baking {} ({} of {})",
            s.label,
            i + 1,
            settings.len()
        );
        let mode = if i == 0 {
            CheckpointMode::Save
        } else {
            CheckpointMode::Resume
        };
        let last = i + 1 == settings.len();
        let mut b = bake_one(&s.apply(config), scene, &traced, mode, !last, quick)?;
        let kept = dir.join(format!("{stem}-{i}.prtbake"));
        std::fs::rename(&traced, &kept).with_context(|| format!("moving {}", kept.display()))?;
        b.path = kept;
        out.push(b);
    }
    Ok(out)
}

/// Bakes every setting from the start (no checkpoint).
pub(crate) fn bake_each(
    config: &BakeConfig,
    scene: &Scene,
    settings: &[Setting],
    dir: &Path,
    stem: &str,
    quick: bool,
) -> Result<Vec<Baked>> {
    let mut out = Vec::new();
    for (i, s) in settings.iter().enumerate() {
        eprintln!(
            "{stem}: baking {} ({} of {})",
            s.label,
            i + 1,
            settings.len()
        );
        let path = dir.join(format!("{stem}-{i}.prtbake"));
        out.push(bake_one(
            &s.apply(config),
            scene,
            &path,
            CheckpointMode::Off,
            false,
            quick,
        )?);
    }
    Ok(out)
}
