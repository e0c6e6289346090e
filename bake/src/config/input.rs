//! What `bake INPUT` accepts, resolved to a [`BakeConfig`] (docs/config.md, "What `bake`
//! accepts"):
//!
//! * a **folder**: its `bake.toml`;
//! * a **`.toml` file**: a bake config;
//! * a **`.gltf`/`.glb` file**: the scene baked with defaults ([`defaults_for_gltf`]).

use std::path::{Path, PathBuf};

use super::{default_environment_map, BakeConfig, ConfigError, EnvironmentConfig, MaterialConfig};
use crate::scene::{Scene, SceneError};

/// The file a scene folder must hold.
pub const FOLDER_CONFIG: &str = "bake.toml";

/// Which of the accepted forms an input was.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum InputKind {
    /// A bake config file (`.toml`).
    Config,
    /// A folder holding `bake.toml`.
    SceneFolder,
    /// A bare glTF scene (`.gltf`/`.glb`), baked with defaults.
    Gltf,
}

/// A user's input resolved to a config.
#[derive(Clone, Debug)]
pub struct ResolvedInput {
    pub kind: InputKind,
    pub config: BakeConfig,
    /// Warnings about the config (deprecated keys, with what to write instead), for the tool
    /// to show.
    pub warnings: Vec<String>,
}

/// Why an input is none of the accepted forms.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WrongForm {
    /// Nothing exists at the path.
    Missing,
    /// A folder without `bake.toml`.
    FolderWithoutConfig,
    /// A file whose extension is none of `.toml`, `.gltf`, `.glb`.
    UnknownExtension,
}

impl std::fmt::Display for WrongForm {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            WrongForm::Missing => "no such file or folder",
            WrongForm::FolderWithoutConfig => "the folder holds no bake.toml",
            WrongForm::UnknownExtension => "unknown file type",
        })
    }
}

/// Why an input could not be turned into a config.
#[derive(Debug, thiserror::Error)]
pub enum InputError {
    /// The path is none of the three accepted forms.
    #[error(
        "{}: {reason}; expected a bake config (.toml), a scene folder holding bake.toml, or a \
         glTF scene (.gltf/.glb)",
        path.display()
    )]
    WrongForm { path: PathBuf, reason: WrongForm },
    /// The config (named, or the folder's `bake.toml`) is unreadable or invalid.
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// The scene could not be loaded (to choose a bare glTF's defaults).
    #[error(transparent)]
    Scene(#[from] SceneError),
}

/// Resolves what the user named to a config: a folder means its `bake.toml`, a `.toml` is read
/// as a config, a `.gltf`/`.glb` gets [`defaults_for_gltf`]. Extensions are matched without
/// regard to case.
pub fn resolve(path: &Path) -> Result<ResolvedInput, InputError> {
    let wrong = |reason| InputError::WrongForm {
        path: path.to_path_buf(),
        reason,
    };
    if path.is_dir() {
        let config = path.join(FOLDER_CONFIG);
        if !config.is_file() {
            return Err(wrong(WrongForm::FolderWithoutConfig));
        }
        let (config, warnings) = BakeConfig::from_file_with_warnings(config)?;
        return Ok(ResolvedInput {
            kind: InputKind::SceneFolder,
            config,
            warnings,
        });
    }
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase());
    match ext.as_deref() {
        // A missing .toml is reported by the config reader (it names the config).
        Some("toml") => {
            let (config, warnings) = BakeConfig::from_file_with_warnings(path)?;
            Ok(ResolvedInput {
                kind: InputKind::Config,
                config,
                warnings,
            })
        }
        _ if !path.exists() => Err(wrong(WrongForm::Missing)),
        Some("gltf" | "glb") => Ok(ResolvedInput {
            kind: InputKind::Gltf,
            config: defaults_for_gltf(path)?,
            warnings: Vec::new(),
        }),
        _ => Err(wrong(WrongForm::UnknownExtension)),
    }
}

/// The config `bake` uses for a bare glTF: as if a `bake.toml` beside it said only
/// `scene = "<file>"` ([`BakeConfig::with_defaults`]: pixel mode, 256 x 256, 64 spp, two
/// reflections, seed 0), plus:
///
/// * `output` = `out/<glTF file stem>.prtbake` beside the glTF;
/// * `[environment]`: [`default_environment_map`] (most glTF models bring no light of their
///   own; under the black default they would bake to a black image);
/// * `[camera]`: none when the glTF has a perspective camera (it is used), else
///   [`crate::scene::framing_camera`] (the scene's bounding box, seen from +Z and a little
///   above);
/// * `[materials.NAME]`: every non-emissive material (the `default` one included when used) is
///   editable, in the family its glTF values map to (`diffuse` for a fully rough dielectric,
///   else `ggx`), with no other override.
///
/// The scene is loaded once to learn its materials and bounds.
pub fn defaults_for_gltf(path: &Path) -> Result<BakeConfig, SceneError> {
    let mut config = BakeConfig::with_defaults(path);
    let stem = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "scene".to_owned());
    config.output = config.folder().join("out").join(format!("{stem}.prtbake"));
    let (scene, _warnings, has_gltf_camera) = crate::scene::gltf::load_for_defaults(&config)?;
    if !has_gltf_camera {
        let aspect = config.width as f32 / config.height as f32;
        config.camera = Some(crate::scene::framing_camera(&scene.positions, aspect));
    }
    config.materials = editable_defaults(&scene);
    config.environment = EnvironmentConfig::Map {
        path: default_environment_map(),
        intensity: 1.0,
        rotation: 0.0,
    };
    Ok(config)
}

fn editable_defaults(scene: &Scene) -> Vec<(String, MaterialConfig)> {
    scene
        .materials
        .iter()
        .filter(|m| !m.is_emissive())
        .map(|m| {
            (
                m.name.clone(),
                MaterialConfig {
                    editable: true,
                    family: Some(m.brdf.family),
                    ..MaterialConfig::default()
                },
            )
        })
        .collect()
}
