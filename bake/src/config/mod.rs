//! The bake config (TOML, beside the glTF). Every key is documented in docs/config.md.
//!
//! Parsing happens in two steps: serde reads the file into private `Raw*` structs with
//! `deny_unknown_fields` (so a misspelt key is an error, reported by `toml` with its line and
//! column), then [`BakeConfig::parse`] validates every value and resolves relative paths against
//! the config's folder. Checks that need the glTF (material names, family parameters the glTF
//! must supply) happen later, in [`crate::scene::load`].
//!
//! [`input`] turns what a user names on the command line (a config, a scene folder, or a bare
//! glTF) into a config; [`BakeConfig::to_toml`] writes a config back as TOML. The `[vertex]`
//! table ([`VertexConfig`]) has its keys, defaults and checks in `vertex.rs`.

use std::fmt;
use std::path::{Path, PathBuf};

use glam::Vec3;
use serde::de::{self, Deserializer, MapAccess, SeqAccess, Visitor};
use serde::Deserialize;

use crate::brdf::{Family, ALPHA_RANGE, SHININESS_RANGE};
use crate::film_emission::DEFAULT_EMISSION_OVERSAMPLING;

pub mod input;
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

    /// Like [`BakeConfig::parse`], with the warnings about deprecated keys (e.g. `[camera]
    /// yfov` in radians, now `fov` in degrees): each names the config, the key to write
    /// instead and the converted value.
    pub fn parse_with_warnings(
        text: &str,
        config_path: impl AsRef<Path>,
    ) -> Result<(BakeConfig, Vec<String>), ConfigError> {
        let config_path = config_path.as_ref().to_path_buf();
        let raw: RawConfig = toml::from_str(text).map_err(|source| ConfigError::Parse {
            path: config_path.clone(),
            source,
        })?;
        raw.validate(config_path)
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

// ---------------------------------------------------------------------------------------------
// Raw (as written) structures.

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawConfig {
    scene: String,
    output: Option<String>,
    mode: Option<Mode>,
    width: Option<u32>,
    height: Option<u32>,
    spp: Option<u32>,
    emission_oversampling: Option<u32>,
    reflections: Option<u32>,
    seed: Option<u64>,
    missing_normals: Option<MissingNormals>,
    environment: Option<RawEnvironment>,
    #[serde(default)]
    materials: OrderedTables<RawMaterial>,
    basis: Option<BasisConfig>,
    camera: Option<RawCamera>,
    vertex: Option<VertexConfig>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawCamera {
    position: [f32; 3],
    target: [f32; 3],
    fov: Option<f32>,
    /// Deprecated: the field of view in radians (accepted with a warning naming `fov`).
    yfov: Option<f32>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawEnvironment {
    color: Option<Rgb>,
    map: Option<String>,
    intensity: Option<f32>,
    rotation: Option<f32>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawMaterial {
    #[serde(default)]
    editable: bool,
    family: Option<String>,
    kd: Option<Rgb>,
    ks: Option<Rgb>,
    shininess: Option<f32>,
    alpha: Option<f32>,
}

/// A colour written either as `[r, g, b]` or as one number meaning gray.
struct Rgb(Vec3);

impl<'de> Deserialize<'de> for Rgb {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = Rgb;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a number (gray) or an array of 3 numbers [r, g, b]")
            }
            fn visit_f64<E: de::Error>(self, v: f64) -> Result<Rgb, E> {
                Ok(Rgb(Vec3::splat(v as f32)))
            }
            fn visit_i64<E: de::Error>(self, v: i64) -> Result<Rgb, E> {
                Ok(Rgb(Vec3::splat(v as f32)))
            }
            fn visit_u64<E: de::Error>(self, v: u64) -> Result<Rgb, E> {
                Ok(Rgb(Vec3::splat(v as f32)))
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Rgb, A::Error> {
                let mut c = [0.0f32; 3];
                for (i, slot) in c.iter_mut().enumerate() {
                    *slot = seq
                        .next_element::<f32>()?
                        .ok_or_else(|| de::Error::invalid_length(i, &self))?;
                }
                if seq.next_element::<de::IgnoredAny>()?.is_some() {
                    return Err(de::Error::invalid_length(4, &self));
                }
                Ok(Rgb(Vec3::from_array(c)))
            }
        }
        d.deserialize_any(V)
    }
}

/// A TOML table of tables kept in file order (a `BTreeMap` would sort the names).
struct OrderedTables<T>(Vec<(String, T)>);

impl<T> Default for OrderedTables<T> {
    fn default() -> Self {
        OrderedTables(Vec::new())
    }
}

impl<'de, T: Deserialize<'de>> Deserialize<'de> for OrderedTables<T> {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V<T>(std::marker::PhantomData<T>);
        impl<'de, T: Deserialize<'de>> Visitor<'de> for V<T> {
            type Value = OrderedTables<T>;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a table of [materials.NAME] tables")
            }
            fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Self::Value, A::Error> {
                let mut out = Vec::new();
                while let Some((k, v)) = map.next_entry::<String, T>()? {
                    out.push((k, v));
                }
                Ok(OrderedTables(out))
            }
        }
        d.deserialize_map(V(std::marker::PhantomData))
    }
}

// ---------------------------------------------------------------------------------------------
// Validation.

struct Checker<'a> {
    path: &'a Path,
    /// Deprecation warnings, each naming the config.
    warnings: std::cell::RefCell<Vec<String>>,
}

impl Checker<'_> {
    fn warn(&self, key: &str, message: impl std::fmt::Display) {
        self.warnings.borrow_mut().push(format!(
            "bake config {}: `{key}`: {message}",
            self.path.display()
        ));
    }

    fn err(&self, key: &str, message: impl Into<String>) -> ConfigError {
        ConfigError::Invalid {
            path: self.path.to_path_buf(),
            key: key.to_owned(),
            message: message.into(),
        }
    }

    fn range_u32(&self, key: &str, v: u32, lo: u32, hi: u32) -> Result<u32, ConfigError> {
        if v < lo || v > hi {
            return Err(self.err(
                key,
                format!("{v} is outside the accepted range [{lo}, {hi}]"),
            ));
        }
        Ok(v)
    }

    fn range_f32(&self, key: &str, v: f32, lo: f32, hi: f32) -> Result<f32, ConfigError> {
        if !v.is_finite() {
            return Err(self.err(key, format!("{v} is not a finite number")));
        }
        if v < lo || v > hi {
            return Err(self.err(
                key,
                format!("{v} is outside the accepted range [{lo}, {hi}]"),
            ));
        }
        Ok(v)
    }

    /// A radiance or reflectance: every channel finite and >= 0.
    fn color(&self, key: &str, c: Vec3) -> Result<Vec3, ConfigError> {
        if !c.is_finite() {
            return Err(self.err(key, format!("{c:?} has a non-finite channel")));
        }
        if c.min_element() < 0.0 {
            return Err(self.err(key, format!("{c:?} has a negative channel")));
        }
        Ok(c)
    }

    fn file_path(&self, key: &str, written: &str) -> Result<PathBuf, ConfigError> {
        if written.trim().is_empty() {
            return Err(self.err(key, "the path is empty"));
        }
        Ok(resolve(self.path, written))
    }
}

impl RawConfig {
    fn validate(self, config_path: PathBuf) -> Result<(BakeConfig, Vec<String>), ConfigError> {
        let c = Checker {
            path: &config_path,
            warnings: Default::default(),
        };
        let scene_path = c.file_path("scene", &self.scene)?;
        let output = match &self.output {
            Some(o) => c.file_path("output", o)?,
            None => default_output(&config_path),
        };
        let width = c.range_u32(
            "width",
            self.width.unwrap_or(DEFAULT_WIDTH),
            1,
            MAX_IMAGE_SIDE,
        )?;
        let height = c.range_u32(
            "height",
            self.height.unwrap_or(DEFAULT_HEIGHT),
            1,
            MAX_IMAGE_SIDE,
        )?;
        let spp = c.range_u32("spp", self.spp.unwrap_or(DEFAULT_SPP), 1, MAX_SPP)?;
        let reflections = c.range_u32(
            "reflections",
            self.reflections.unwrap_or(DEFAULT_REFLECTIONS),
            1,
            MAX_REFLECTIONS,
        )?;

        let environment = match self.environment {
            None => EnvironmentConfig::Color(Vec3::ZERO),
            Some(env) => {
                let intensity = match env.intensity {
                    Some(i) => c.range_f32("environment.intensity", i, 0.0, f32::MAX)?,
                    None => 1.0,
                };
                match (env.color, env.map) {
                    (Some(_), Some(_)) => {
                        return Err(c.err("environment", "give either `color` or `map`, not both"))
                    }
                    (None, None) => {
                        return Err(c.err(
                            "environment",
                            "the table needs `color = [r, g, b]` or `map = \"file.exr\"`",
                        ))
                    }
                    (Some(Rgb(col)), None) => {
                        if env.rotation.is_some() {
                            return Err(c.err(
                                "environment.rotation",
                                "only a `map` can be rotated (a constant colour is the same \
                                 from every direction)",
                            ));
                        }
                        let col = c.color("environment.color", col)?;
                        let scaled = c.color("environment.color", col * intensity)?;
                        EnvironmentConfig::Color(scaled)
                    }
                    (None, Some(map)) => {
                        let path = c.file_path("environment.map", &map)?;
                        let ext = path
                            .extension()
                            .map(|e| e.to_string_lossy().to_ascii_lowercase())
                            .unwrap_or_default();
                        if ext != "exr" && ext != "hdr" {
                            return Err(c.err(
                                "environment.map",
                                format!(
                                    "{} is neither an OpenEXR (.exr) nor a Radiance (.hdr) file",
                                    path.display()
                                ),
                            ));
                        }
                        let rotation = match env.rotation {
                            Some(r) => c.range_f32("environment.rotation", r, -360.0, 360.0)?,
                            None => 0.0,
                        };
                        EnvironmentConfig::Map {
                            path,
                            intensity,
                            rotation,
                        }
                    }
                }
            }
        };

        let mut materials = Vec::with_capacity(self.materials.0.len());
        for (name, m) in self.materials.0 {
            materials.push((name.clone(), validate_material(&c, &name, m)?));
        }

        if let Some(b) = &self.basis {
            if let Some(n) = b.count {
                c.range_u32("basis.count", n, 1, MAX_BASIS_COUNT)?;
            }
            if let Some(e) = b.error_target {
                if !(e.is_finite() && e > 0.0) {
                    return Err(c.err(
                        "basis.error_target",
                        format!("{e} must be a finite number > 0 (a relative error, e.g. 0.01)"),
                    ));
                }
            }
        }

        let camera = self
            .camera
            .map(|cam| validate_camera(&c, cam))
            .transpose()?;

        let mode = self.mode.unwrap_or(Mode::Pixel);
        let emission_oversampling = match self.emission_oversampling {
            Some(_) if mode == Mode::Vertex => {
                return Err(c.err(
                    "emission_oversampling",
                    "per-pixel only: remove this key for mode = \"vertex\" (it sets the \
                     camera's samples of a per-pixel bake; a per-vertex bake has none)",
                ))
            }
            Some(k) => c.range_u32("emission_oversampling", k, 1, MAX_EMISSION_OVERSAMPLING)?,
            None => DEFAULT_EMISSION_OVERSAMPLING,
        };
        if let Some(v) = &self.vertex {
            v.validate(&c, mode)?;
        }

        let config = BakeConfig {
            config_path: config_path.clone(),
            scene_path,
            output,
            mode,
            width,
            height,
            spp,
            emission_oversampling,
            reflections,
            seed: self.seed.unwrap_or(0),
            missing_normals: self.missing_normals.unwrap_or_default(),
            environment,
            materials,
            basis: self.basis,
            camera,
            vertex: self.vertex,
        };
        Ok((config, c.warnings.take()))
    }
}

fn validate_camera(c: &Checker, cam: RawCamera) -> Result<CameraConfig, ConfigError> {
    let position = Vec3::from_array(cam.position);
    let target = Vec3::from_array(cam.target);
    if !position.is_finite() {
        return Err(c.err("camera.position", format!("{position:?} is not finite")));
    }
    if !target.is_finite() {
        return Err(c.err("camera.target", format!("{target:?} is not finite")));
    }
    if target == position {
        return Err(c.err("camera.target", "must differ from `camera.position`"));
    }
    let fov = match (cam.fov, cam.yfov) {
        (Some(_), Some(_)) => {
            return Err(c.err(
                "camera.yfov",
                "give `fov` (degrees) only: `yfov` is its deprecated form in radians",
            ))
        }
        (Some(fov), None) => {
            if !(fov.is_finite() && fov > 0.0 && fov < 180.0) {
                return Err(c.err(
                    "camera.fov",
                    format!("{fov} must be in (0, 180) degrees (the vertical field of view)"),
                ));
            }
            fov
        }
        (None, Some(yfov)) => {
            if !(yfov.is_finite() && yfov > 0.0 && yfov < std::f32::consts::PI) {
                return Err(c.err(
                    "camera.yfov",
                    format!(
                        "{yfov} radians is not in (0, pi); `yfov` is deprecated: write the \
                         vertical field of view in degrees as `fov` (e.g. `fov = {yfov}` for \
                         {yfov} degrees)"
                    ),
                ));
            }
            // To 1e-4 degree, so that 40 degrees written in radians reads back as 40 (and
            // `--print-config` writes `fov = 40.0`), not 39.999996; unrounded where rounding
            // would reach 0 or 180.
            let degrees = yfov.to_degrees();
            let rounded = (degrees * 1e4).round() / 1e4;
            let fov = if rounded > 0.0 && rounded < 180.0 {
                rounded
            } else {
                degrees
            };
            c.warn(
                "camera.yfov",
                format!(
                    "deprecated (radians): write `fov = {fov}` (degrees) instead of \
                     `yfov = {yfov}`"
                ),
            );
            fov
        }
        (None, None) => DEFAULT_FOV,
    };
    let camera = CameraConfig {
        position,
        target,
        fov,
    };
    // The frame `--camera` would give this view: refused for the same views (straight up or
    // down), so a config and a command line accept the same cameras and render the same one.
    if let Err(e) = camera.spec().frame() {
        let reason = match e {
            prt_formats::view::CameraSpecError::Invalid { reason, .. } => reason,
            other => other.to_string(),
        };
        return Err(c.err("camera.target", reason));
    }
    Ok(camera)
}

fn validate_material(
    c: &Checker,
    name: &str,
    m: RawMaterial,
) -> Result<MaterialConfig, ConfigError> {
    let key = |k: &str| format!("materials.{name}.{k}");
    let family = match &m.family {
        None => None,
        Some(f) => Some(Family::parse(f).ok_or_else(|| {
            c.err(
                &key("family"),
                format!(
                    "unknown family \"{f}\" (expected \"diffuse\", \"blinn-phong\" or \"ggx\")"
                ),
            )
        })?),
    };
    let kd = m.kd.map(|Rgb(v)| c.color(&key("kd"), v)).transpose()?;
    let ks = m.ks.map(|Rgb(v)| c.color(&key("ks"), v)).transpose()?;
    let shininess = m
        .shininess
        .map(|s| c.range_f32(&key("shininess"), s, SHININESS_RANGE.0, SHININESS_RANGE.1))
        .transpose()?;
    let alpha = m
        .alpha
        .map(|a| c.range_f32(&key("alpha"), a, ALPHA_RANGE.0, ALPHA_RANGE.1))
        .transpose()?;

    // Parameters that the named family has no use for are almost always a mistake (e.g. a
    // `shininess` left behind after switching to ggx); say so instead of ignoring them.
    // Without `family`, the family comes from the glTF (diffuse or ggx), checked on load.
    if let Some(f) = family {
        let stray = |k: &str| {
            c.err(
                &key(k),
                format!("family \"{}\" has no `{k}` parameter", f.name()),
            )
        };
        match f {
            Family::Diffuse => {
                if ks.is_some() {
                    return Err(stray("ks"));
                }
                if shininess.is_some() {
                    return Err(stray("shininess"));
                }
                if alpha.is_some() {
                    return Err(stray("alpha"));
                }
            }
            Family::BlinnPhong => {
                if alpha.is_some() {
                    return Err(stray("alpha"));
                }
            }
            Family::Ggx => {
                if shininess.is_some() {
                    return Err(stray("shininess"));
                }
            }
        }
    } else if shininess.is_some() {
        // glTF materials never map to Blinn-Phong, so a shininess needs an explicit family.
        return Err(c.err(
            &key("shininess"),
            "`shininess` needs `family = \"blinn-phong\"` (glTF materials map to diffuse or ggx)",
        ));
    }

    Ok(MaterialConfig {
        editable: m.editable,
        family,
        kd,
        ks,
        shininess,
        alpha,
    })
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
