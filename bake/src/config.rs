//! The bake config (TOML, beside the glTF). Every key is documented in docs/config.md.

use std::path::{Path, PathBuf};

use glam::Vec3;
use serde::Deserialize;

use crate::brdf::Family;

#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Mode {
    Pixel,
    Vertex,
}

/// Environment lighting as written in the config.
#[derive(Clone, Debug, PartialEq)]
pub enum EnvironmentConfig {
    /// Constant radiance (linear RGB).
    Color(Vec3),
    /// An EXR or Radiance HDR lat-long map (path resolved against the config's folder), scaled.
    Map { path: PathBuf, intensity: f32 },
}

/// Per-material settings from the config's `[materials.NAME]` tables.
#[derive(Clone, Debug, PartialEq)]
pub struct MaterialConfig {
    pub editable: bool,
    /// When given, overrides the BRDF mapped from the glTF material.
    pub family: Option<Family>,
    pub kd: Option<Vec3>,
    pub ks: Option<Vec3>,
    /// Blinn-Phong shininess.
    pub shininess: Option<f32>,
    /// GGX alpha.
    pub alpha: Option<f32>,
}

#[derive(Clone, Debug)]
pub struct BakeConfig {
    /// The config file itself (relative paths inside it resolve against its folder).
    pub config_path: PathBuf,
    /// The glTF/GLB scene, resolved.
    pub scene_path: PathBuf,
    /// The bake output file, resolved.
    pub output: PathBuf,
    pub mode: Mode,
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    /// Number of reflections along a path: 1 = direct only, 2 = direct + one bounce, ...
    pub reflections: u32,
    pub seed: u64,
    pub environment: EnvironmentConfig,
    /// Keyed by glTF material name, in file order.
    pub materials: Vec<(String, MaterialConfig)>,
}

impl BakeConfig {
    pub fn folder(&self) -> &Path {
        self.config_path.parent().unwrap_or(Path::new("."))
    }
}
