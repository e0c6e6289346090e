//! The bake config (TOML, beside the glTF). Every key is documented in docs/config.md.
//!
//! Parsing happens in two steps: serde reads the file into private `Raw*` structs with
//! `deny_unknown_fields` (`raw.rs`; a misspelt key is an error, reported by `toml` with its
//! line and column), then [`BakeConfig::parse`] validates every value and resolves relative
//! paths against the config's folder (`validate.rs`). Checks that need the glTF (material names, family parameters the glTF
//! must supply) happen later, in [`crate::scene::load`].
//!
//! [`input`] turns what a user names on the command line (a config, a scene folder, or a bare
//! glTF) into a config; [`BakeConfig::to_toml`] writes a config back as TOML. The `[vertex]`
//! table ([`VertexConfig`]) has its keys, defaults and checks in `vertex.rs`.

use std::path::{Path, PathBuf};

use glam::Vec3;
use serde::Deserialize;

use crate::brdf::{Family, ALPHA_RANGE, SHININESS_RANGE};
use crate::film_emission::DEFAULT_EMISSION_OVERSAMPLING;

pub mod input;
mod raw;
mod validate;
mod vertex;
mod write;

/// Largest accepted image side in pixels; anything larger is almost certainly a typo.
pub const MAX_IMAGE_SIDE: u32 = 16384;
/// Largest accepted samples per pixel (or per vertex).
pub use crate::sampling::MAX_SPP;
/// Largest accepted number of reflections per path: what the integrator supports (one limit,
/// so a config can never ask for more than is rendered).
pub const MAX_REFLECTIONS: u32 = crate::sampling::MAX_REFLECTIONS as u32;
/// Largest accepted `emission_oversampling`.
pub const MAX_EMISSION_OVERSAMPLING: u32 = 64;
/// Largest accepted `[basis] count`.
pub const MAX_BASIS_COUNT: u32 = 1024;

#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Mode {
    Pixel,
    Vertex,
}

/// What a mesh without NORMAL attributes is baked with (`missing_normals`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum MissingNormals {
    /// Flat normals, one vertex per triangle corner: the glTF rule (spec 3.7.2.1), faceted.
    #[default]
    Flat,
    /// Smooth normals: the area-weighted mean of the faces around each shared vertex.
    Smooth,
}

/// Environment lighting as written in the config.
#[derive(Clone, Debug, PartialEq)]
pub enum EnvironmentConfig {
    /// Constant radiance (linear RGB), already multiplied by `intensity`.
    Color(Vec3),
    /// An EXR or Radiance HDR lat-long map (path resolved against the config's folder),
    /// scaled, and turned `rotation` degrees about +Y (right-hand rule; docs/conventions.md).
    Map {
        path: PathBuf,
        intensity: f32,
        rotation: f32,
    },
}

/// Per-material settings from the config's `[materials.NAME]` tables.
#[derive(Clone, Debug, PartialEq, Default)]
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

/// The `[basis]` table: how the editable BRDFs are projected (docs/brdf-basis.md). Every key
/// is optional; the baker picks defaults.
#[derive(Clone, Debug, PartialEq, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BasisConfig {
    /// Number of basis BRDFs per editable family (N_b), diffuse lobe included.
    pub count: Option<u32>,
    /// Target relative L2 projection error; the baker grows the basis until it is met.
    pub error_target: Option<f32>,
}

pub use vertex::{VertexConfig, DEFAULT_SECONDARY, MAX_SECONDARY};

/// The `[camera]` table: a pinhole camera replacing the glTF's (docs/config.md). It is the
/// camera `--camera "eye=.. target=.. fov=.."` gives ([`CameraConfig::spec`]), in the same
/// unit: every angle a user types is in degrees (docs/conventions.md, "Space and units").
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraConfig {
    /// The eye, world space.
    pub position: Vec3,
    /// The point looked at; the image's up is as close to +Y as the view allows.
    pub target: Vec3,
    /// Vertical field of view, degrees, in (0, 180).
    pub fov: f32,
}

impl CameraConfig {
    /// The same camera as a `--camera` argument, whose frame
    /// ([`prt_formats::view::CameraSpec::frame`]) is the camera the baker renders through.
    pub fn spec(&self) -> prt_formats::view::CameraSpec {
        prt_formats::view::CameraSpec {
            eye: self.position.to_array(),
            target: self.target.to_array(),
            fov_deg: self.fov,
        }
    }
}

/// `[camera]`'s default `fov`: 45 degrees.
pub const DEFAULT_FOV: f32 = 45.0;

#[derive(Clone, Debug, PartialEq)]
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
    /// Camera samples per path sample for what the camera sees directly (emitters, the
    /// environment): per-pixel mode only
    /// ([`crate::film_emission::DEFAULT_EMISSION_OVERSAMPLING`] says why).
    pub emission_oversampling: u32,
    /// Number of reflections along a path: 1 = direct only, 2 = direct + one bounce, ...
    pub reflections: u32,
    pub seed: u64,
    /// Normals for meshes without NORMAL attributes ([`MissingNormals`]; default flat).
    pub missing_normals: MissingNormals,
    pub environment: EnvironmentConfig,
    /// Keyed by glTF material name, in file order.
    pub materials: Vec<(String, MaterialConfig)>,
    /// The optional `[basis]` table.
    pub basis: Option<BasisConfig>,
    /// The optional `[camera]` table; without it the glTF's first perspective camera is used.
    pub camera: Option<CameraConfig>,
    /// The optional `[vertex]` table (only with `mode = "vertex"`).
    pub vertex: Option<VertexConfig>,
}

/// Why a config could not be read. Every message names the config file, and the key where one
/// is at fault.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    #[error("cannot read bake config {}: {source}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// TOML syntax errors, unknown keys and values of the wrong type (with line and column).
    #[error("bake config {}: {source}", path.display())]
    Parse {
        path: PathBuf,
        #[source]
        source: toml::de::Error,
    },
    /// A value of the right type that is out of range or inconsistent.
    #[error("bake config {}: `{key}`: {message}", path.display())]
    Invalid {
        path: PathBuf,
        key: String,
        message: String,
    },
}

pub const DEFAULT_WIDTH: u32 = 256;
pub const DEFAULT_HEIGHT: u32 = 256;
pub use crate::sampling::DEFAULT_SPP;
pub const DEFAULT_REFLECTIONS: u32 = 2;

impl BakeConfig {
    pub fn folder(&self) -> &Path {
        self.config_path.parent().unwrap_or(Path::new("."))
    }

    /// Reads and validates a bake config file.
    pub fn from_file(path: impl AsRef<Path>) -> Result<BakeConfig, ConfigError> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::parse(&text, path)
    }

    /// Like [`BakeConfig::from_file`], with the warnings about keys that are accepted but
    /// deprecated (each names the key to write instead and its value), for tools to show.
    pub fn from_file_with_warnings(
        path: impl AsRef<Path>,
    ) -> Result<(BakeConfig, Vec<String>), ConfigError> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::parse_with_warnings(&text, path)
    }

    /// Parses and validates config text as if it had been read from `config_path` (which need
    /// not exist; it names the config in errors and anchors relative paths). Warnings about
    /// deprecated keys are dropped ([`BakeConfig::parse_with_warnings`] returns them).
    pub fn parse(text: &str, config_path: impl AsRef<Path>) -> Result<BakeConfig, ConfigError> {
        Self::parse_with_warnings(text, config_path).map(|(config, _)| config)
    }

    /// A config with every default, for `scene_path`, as if a file `bake.toml` beside the scene
    /// said only `scene = "<file name>"`. Handy for tools and tests that have no config file.
    pub fn with_defaults(scene_path: impl Into<PathBuf>) -> BakeConfig {
        let scene_path = scene_path.into();
        let folder = scene_path.parent().unwrap_or(Path::new("")).to_path_buf();
        let config_path = folder.join("bake.toml");
        BakeConfig {
            output: default_output(&config_path),
            config_path,
            scene_path,
            mode: Mode::Pixel,
            width: DEFAULT_WIDTH,
            height: DEFAULT_HEIGHT,
            spp: DEFAULT_SPP,
            emission_oversampling: DEFAULT_EMISSION_OVERSAMPLING,
            reflections: DEFAULT_REFLECTIONS,
            seed: 0,
            missing_normals: MissingNormals::Flat,
            environment: EnvironmentConfig::Color(Vec3::ZERO),
            materials: Vec::new(),
            basis: None,
            camera: None,
            vertex: None,
        }
    }

    /// The config's settings for the glTF material `name`, if it has a `[materials.NAME]` table.
    pub fn material(&self, name: &str) -> Option<&MaterialConfig> {
        self.materials
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, m)| m)
    }
}

/// The environment a bare glTF is baked under: `scenes/envmaps/neutral.hdr` of the source tree
/// this program was built from, a soft, colourless studio light (a bright sky dome, a large
/// soft key light high in front on the left, a dark gray floor; made by
/// `scenes/envmaps/neutral.py`, described in docs/config.md). `--print-config` writes its
/// absolute path.
pub fn default_environment_map() -> PathBuf {
    let manifest = Path::new(env!("CARGO_MANIFEST_DIR"));
    manifest
        .parent()
        .unwrap_or(manifest)
        .join("scenes/envmaps/neutral.hdr")
}

/// `out/<name>.prtbake` in the config's folder, where name is the config's stem, or the
/// folder's name for a config called `bake.toml` (so `scenes/cornell/bake.toml` bakes to
/// `scenes/cornell/out/cornell.prtbake`).
fn default_output(config_path: &Path) -> PathBuf {
    let stem = config_path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "bake".to_owned());
    let name = if stem == "bake" {
        config_path
            .parent()
            .and_then(|p| p.file_name())
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or(stem)
    } else {
        stem
    };
    resolve(config_path, &format!("out/{name}.prtbake"))
}

/// Resolves a path written in the config against the config's folder (absolute paths stay).
fn resolve(config_path: &Path, written: &str) -> PathBuf {
    let p = Path::new(written);
    if p.is_absolute() {
        p.to_path_buf()
    } else {
        config_path.parent().unwrap_or(Path::new("")).join(p)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<BakeConfig, ConfigError> {
        BakeConfig::parse(text, "/scenes/x/bake.toml")
    }

    /// The message of the error `text` must give.
    fn error(text: &str) -> String {
        parse(text).unwrap_err().to_string()
    }

    #[test]
    fn defaults_and_paths() {
        let c = parse("scene = \"x.gltf\"").unwrap();
        assert_eq!(c.scene_path, PathBuf::from("/scenes/x/x.gltf"));
        assert_eq!(c.output, PathBuf::from("/scenes/x/out/x.prtbake"));
        assert_eq!(
            (c.width, c.height, c.spp, c.reflections, c.seed),
            (256, 256, 64, 2, 0)
        );
        assert_eq!(c.mode, Mode::Pixel);
        assert_eq!(c.emission_oversampling, DEFAULT_EMISSION_OVERSAMPLING);
        assert_eq!(c.environment, EnvironmentConfig::Color(Vec3::ZERO));
        assert!(c.basis.is_none());
    }

    #[test]
    fn emission_oversampling_is_checked_and_per_pixel_only() {
        let c = parse("scene = \"x.gltf\"\nemission_oversampling = 1").expect("1 turns it off");
        assert_eq!(c.emission_oversampling, 1);
        for bad in [0, MAX_EMISSION_OVERSAMPLING + 1] {
            let e = error(&format!(
                "scene = \"x.gltf\"\nemission_oversampling = {bad}"
            ));
            assert!(
                e.contains("`emission_oversampling`") && e.contains("outside"),
                "{e}"
            );
        }
        // Values of the wrong type: TOML's error, quoting the line with the key.
        for garbage in ["\"many\"", "-3", "2.5", "[2]"] {
            let e = error(&format!(
                "scene = \"x.gltf\"\nemission_oversampling = {garbage}"
            ));
            assert!(e.contains("emission_oversampling"), "{garbage}: {e}");
        }
        let e = error("scene = \"x.gltf\"\nmode = \"vertex\"\nemission_oversampling = 2");
        assert!(
            e.contains("`emission_oversampling`") && e.contains("per-vertex"),
            "{e}"
        );
    }

    #[test]
    fn materials_keep_file_order_and_gray_shorthand() {
        let c = parse(
            "scene = \"x.gltf\"\n[materials.zeta]\nkd = 0.5\n[materials.alpha]\neditable = true\n\
             family = \"blinn-phong\"\nks = [0.1, 0.2, 0.3]\nshininess = 40\n",
        )
        .unwrap();
        assert_eq!(c.materials[0].0, "zeta");
        assert_eq!(c.materials[0].1.kd, Some(Vec3::splat(0.5)));
        assert_eq!(c.materials[1].0, "alpha");
        let m = c.material("alpha").unwrap();
        assert!(m.editable);
        assert_eq!(m.family, Some(Family::BlinnPhong));
        assert_eq!(m.ks, Some(Vec3::new(0.1, 0.2, 0.3)));
        assert_eq!(m.shininess, Some(40.0));
    }

    #[test]
    fn errors_name_the_key() {
        let e = error("scene = \"x.gltf\"\nwidht = 3");
        assert!(e.contains("widht"), "{e}");
        let e = error("scene = \"x.gltf\"\nwidth = 0");
        assert!(e.contains("`width`"), "{e}");
        let e = error("scene = \"x.gltf\"\n[materials.m]\nkd = [1, nan, 0]");
        assert!(e.contains("materials.m.kd"), "{e}");
        let e = error("scene = \"x.gltf\"\n[materials.m]\nkd = [1, 0]");
        assert!(e.contains("kd"), "{e}");
        let e = error("scene = \"x.gltf\"\n[materials.m]\nfamily = \"ggx\"\nshininess = 3");
        assert!(e.contains("materials.m.shininess"), "{e}");
        let e = error("scene = \"x.gltf\"\n[environment]\ncolor = 1\nmap = \"a.exr\"");
        assert!(e.contains("not both"), "{e}");
        let e = error("scene = \"x.gltf\"\n[environment]\ncolor = 1\nrotation = 30");
        assert!(
            e.contains("environment.rotation") && e.contains("only a `map`"),
            "{e}"
        );
        let e = error("scene = \"x.gltf\"\n[environment]\nmap = \"a.exr\"\nrotation = 400");
        assert!(
            e.contains("environment.rotation") && e.contains("400"),
            "{e}"
        );
        let c = parse("scene = \"x.gltf\"\n[environment]\nmap = \"a.exr\"\nrotation = -45")
            .expect("a rotated map");
        assert!(
            matches!(c.environment, EnvironmentConfig::Map { rotation, .. } if rotation == -45.0)
        );
    }
}
