//! The report's scenes, material settings and cached bases.

use std::path::Path;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use prt_bake::basis::{BasisBuilder, BasisConfig};
use prt_bake::brdf::Family;
use prt_bake::config::BakeConfig;
use prt_bake::run::{apply_override, load};
use prt_bake::scene::Scene;
use prt_formats::basis::{AngularGrid, BrdfBasis};
use prt_formats::MaterialOverride;

use super::options::DEFAULT_SETTINGS;

/// A named set of material edits.
#[derive(Clone, Debug)]
pub(crate) struct Setting {
    pub(crate) label: String,
    pub(crate) edits: Vec<MaterialOverride>,
}

impl Setting {
    pub(crate) fn slug(&self) -> String {
        let s: String = self
            .label
            .chars()
            .map(|c| {
                if c.is_ascii_alphanumeric() {
                    c.to_ascii_lowercase()
                } else {
                    '-'
                }
            })
            .collect();
        s.split('-')
            .filter(|p| !p.is_empty())
            .collect::<Vec<_>>()
            .join("-")
    }

    pub(crate) fn describe(&self) -> String {
        if self.edits.is_empty() {
            "starting values".into()
        } else {
            self.edits
                .iter()
                .map(|e| format!("`{e}`"))
                .collect::<Vec<_>>()
                .join(" ")
        }
    }
}

pub(crate) struct SceneCtx {
    pub(crate) name: String,
    pub(crate) config: BakeConfig,
    pub(crate) scene: Scene,
    pub(crate) settings: Vec<Setting>,
}

impl SceneCtx {
    pub(crate) fn new(path: &Path, verbose: bool) -> Result<SceneCtx> {
        let (config, scene) = load(path, &prt_bake::progress::Silent)?;
        if config.mode != prt_bake::config::Mode::Pixel {
            bail!(
                "{}: the pixel report needs mode = \"pixel\"",
                path.display()
            );
        }
        let name = config
            .folder()
            .file_name()
            .map_or_else(|| "scene".to_string(), |s| s.to_string_lossy().into_owned());
        let mut settings = vec![Setting {
            label: "start".into(),
            edits: Vec::new(),
        }];
        for (label, edits) in DEFAULT_SETTINGS {
            let edits = edits
                .iter()
                .map(|e| {
                    prt_formats::overrides::parse_override(e)
                        .with_context(|| format!("built-in setting '{label}'"))
                })
                .collect::<Result<Vec<_>>>()?;
            let mut probe = scene.clone();
            let applies = edits.iter().all(|e| {
                apply_override(&mut probe, e).is_ok()
                    && probe
                        .materials
                        .iter()
                        .any(|m| m.name == e.material && m.editable)
            });
            if applies {
                settings.push(Setting {
                    label: label.to_string(),
                    edits,
                });
            } else if verbose {
                eprintln!("report: {name}: setting '{label}' does not apply, skipped");
            }
        }
        if settings.len() == 1 {
            if let Some(m) = scene.materials.iter().find(|m| m.editable) {
                settings.push(Setting {
                    label: format!("{} red", m.name),
                    edits: vec![prt_formats::overrides::parse_override(&format!(
                        "{}.kd=0.8,0.2,0.2",
                        m.name
                    ))?],
                });
            }
        }
        if !scene.materials.iter().any(|m| m.editable) {
            bail!(
                "{}: the scene has no editable material, nothing to relight",
                path.display()
            );
        }
        Ok(SceneCtx {
            name,
            config,
            scene,
            settings,
        })
    }

    pub(crate) fn scene_with(&self, s: &Setting) -> Result<Scene> {
        let mut sc = self.scene.clone();
        for e in &s.edits {
            apply_override(&mut sc, e)?;
        }
        Ok(sc)
    }

    pub(crate) fn families(&self) -> Vec<Family> {
        let mut out = Vec::new();
        for m in &self.scene.materials {
            if m.editable && m.brdf.family != Family::Diffuse && !out.contains(&m.brdf.family) {
                out.push(m.brdf.family);
            }
        }
        out
    }
}

/// Tabulates each family's lobes once and builds bases of any size from that.
pub(crate) struct BasisCache {
    pub(crate) grid: Option<AngularGrid>,
    pub(crate) param_samples: Option<usize>,
    /// The grid and parameter samples actually used, for the report.
    pub(crate) used: Option<(AngularGrid, usize)>,
    pub(crate) builders: Vec<(Family, BasisBuilder, f64)>,
    pub(crate) built: Vec<(Family, usize, BrdfBasis, f64)>,
}

impl BasisCache {
    pub(crate) fn new(grid: Option<AngularGrid>, param_samples: Option<usize>) -> Self {
        BasisCache {
            grid,
            param_samples,
            used: None,
            builders: Vec::new(),
            built: Vec::new(),
        }
    }

    /// The bases for `families` with `count` BRDFs each, and the time building them from
    /// scratch takes (tabulation + PCA, summed over families).
    pub(crate) fn get(
        &mut self,
        families: &[Family],
        count: usize,
    ) -> Result<(Vec<BrdfBasis>, f64)> {
        let mut out = Vec::new();
        let mut seconds = 0.0;
        for &f in families {
            if let Some((_, _, b, s)) = self
                .built
                .iter()
                .find(|(g, n, _, _)| *g == f && *n == count)
            {
                out.push(b.clone());
                seconds += s;
                continue;
            }
            if !self.builders.iter().any(|(g, _, _)| *g == f) {
                let t = Instant::now();
                let mut cfg = BasisConfig::new(f, count).map_err(anyhow::Error::msg)?;
                if let Some(g) = self.grid {
                    cfg.grid = g;
                }
                if let Some(n) = self.param_samples {
                    cfg.param_samples = n;
                }
                self.used = Some((cfg.grid, cfg.param_samples));
                let b = BasisBuilder::new(cfg)
                    .map_err(|e| anyhow::anyhow!("tabulating the {} basis: {e}", f.name()))?;
                self.builders.push((f, b, t.elapsed().as_secs_f64()));
            }
            let Some((_, builder, tab)) = self.builders.iter().find(|(g, _, _)| *g == f) else {
                bail!("internal: no basis builder for {}", f.name());
            };
            let t = Instant::now();
            let b = builder
                .build(count)
                .map_err(|e| {
                    anyhow::anyhow!("building the {} basis with {count} BRDFs: {e}", f.name())
                })?
                .to_persisted();
            let s = tab + t.elapsed().as_secs_f64();
            self.built.push((f, count, b.clone(), s));
            out.push(b);
            seconds += s;
        }
        Ok((out, seconds))
    }
}
