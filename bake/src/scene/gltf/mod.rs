//! glTF 2.0 loading: the default scene's meshes, materials, punctual lights and camera, plus the
//! environment from the bake config, flattened into a world-space [`Scene`].
//!
//! Conventions are in docs/conventions.md; the short version:
//! - Node transforms are applied to positions; normals get the inverse transpose and are
//!   re-normalized. A node whose matrix has a negative determinant flips the triangle winding
//!   (as the glTF spec requires) so that `(p1 - p0) x (p2 - p0)` always faces the front side.
//! - Missing normals are generated *flat* (one normal per triangle, vertices unshared), which is
//!   what the glTF spec mandates. Supplied normals that are zero or non-finite are replaced by
//!   the area-weighted average of the adjacent triangles' normals.
//! - Degenerate (zero-area) and non-finite triangles, and triangles with a coordinate beyond
//!   +-1e15 m, are skipped, counted in [`Scene::skipped_triangles`] and reported once;
//!   out-of-range indices are an error.
//! - Missing TEXCOORD_0 reads as (0, 0); non-finite UVs are set to (0, 0).
//! - Punctual lights are taken radiometrically: 1 cd = 1 W/sr, 1 lux = 1 W/m^2.

//!
//! The loader is split by concern: [`source`] (container parsing, URIs), [`accessors`]
//! (reading accessors), `mesh` (geometry and instances), [`material`] (glTF PBR to BRDF and the
//! config's overrides), `texture`, `lights` and [`camera`].

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use glam::Mat4;

use super::error::ResourceError;
use super::{envmap, Camera, Environment, Scene, SceneError, Texture};
use crate::config::{BakeConfig, EnvironmentConfig};
use source::UriTarget;

pub mod accessors;
pub mod camera;
mod facets;
mod lights;
pub mod material;
mod mesh;
pub mod source;
pub mod texture;

/// Node hierarchies deeper than this are refused (they are certainly malformed, and deeper
/// recursion could be used to exhaust the stack).
const MAX_NODE_DEPTH: usize = 512;

/// Loads the scene named by `config`, dropping the loader's warnings (for tests and tools that
/// build their own scenes). Tools that face users take them with [`load_with_warnings`] (or
/// `run::load_scene`, which passes them to a progress reporter).
pub fn load(config: &BakeConfig) -> Result<Scene, SceneError> {
    load_with_warnings(config).map(|(scene, _)| scene)
}

/// Like [`load`], but returns the warnings instead of printing them.
pub fn load_with_warnings(config: &BakeConfig) -> Result<(Scene, Vec<String>), SceneError> {
    let (scene, warnings, _) = load_impl(config, false)?;
    Ok((scene, warnings))
}

/// Loads a scene for choosing default settings: like [`load_with_warnings`], but a scene
/// without a perspective camera (and without a config `[camera]`) is no error; it gets
/// [`camera::framing_camera`] instead. The flag says whether the camera came from the glTF.
pub(crate) fn load_for_defaults(
    config: &BakeConfig,
) -> Result<(Scene, Vec<String>, bool), SceneError> {
    load_impl(config, true)
}

fn load_impl(
    config: &BakeConfig,
    frame_missing_camera: bool,
) -> Result<(Scene, Vec<String>, bool), SceneError> {
    let path = config.scene_path.as_path();
    let bytes = std::fs::read(path).map_err(|source| SceneError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let gltf = source::parse(&bytes).map_err(|source| SceneError::Parse {
        path: path.to_path_buf(),
        source,
    })?;
    drop(bytes);
    let mut loader = Loader {
        frame_missing_camera,
        has_gltf_camera: false,
        config,
        path,
        folder: path.parent().unwrap_or(Path::new("")).to_path_buf(),
        doc: &gltf.document,
        buffers: Vec::new(),
        warnings: Vec::new(),
        textures: Vec::new(),
        texture_of_image: HashMap::new(),
    };
    loader.buffers = loader.load_buffers(gltf.blob.as_deref())?;
    let scene = loader.build()?;
    Ok((scene, loader.warnings, loader.has_gltf_camera))
}

/// The state of one load: the document, its buffers, and what has been gathered so far.
struct Loader<'a> {
    /// Frame the scene instead of failing when it has no camera ([`load_for_defaults`]).
    frame_missing_camera: bool,
    /// Whether the camera used came from the glTF (set by `build`).
    has_gltf_camera: bool,
    config: &'a BakeConfig,
    path: &'a Path,
    folder: PathBuf,
    doc: &'a gltf::Document,
    buffers: Vec<Vec<u8>>,
    warnings: Vec<String>,
    textures: Vec<Texture>,
    /// Loaded textures by (glTF image, [`texture::Encoding`] key).
    texture_of_image: HashMap<(usize, u32), usize>,
}

impl Loader<'_> {
    fn invalid(&self, message: impl Into<String>) -> SceneError {
        SceneError::Invalid {
            path: self.path.to_path_buf(),
            message: message.into(),
        }
    }

    /// The bytes a buffer or image URI names (a `data:` URI or a file).
    fn read_uri(&self, uri: &str) -> Result<Vec<u8>, ResourceError> {
        Ok(match source::resolve_uri(uri, &self.folder)? {
            UriTarget::Data(d) => d,
            UriTarget::File(file) => {
                // Only regular files: a device or pipe could be read forever (found by fuzzing:
                // `file:///dev/zero` filled the memory). A missing file fails in the read.
                if std::fs::metadata(&file).is_ok_and(|m| !m.is_file()) {
                    return Err(ResourceError::NotAFile { file });
                }
                std::fs::read(&file).map_err(|source| ResourceError::Read { file, source })?
            }
        })
    }

    fn load_buffers(&self, blob: Option<&[u8]>) -> Result<Vec<Vec<u8>>, SceneError> {
        let mut out = Vec::new();
        for buffer in self.doc.buffers() {
            let index = buffer.index();
            let (label, data) = match buffer.source() {
                gltf::buffer::Source::Bin => {
                    let label = "GLB BIN chunk".to_owned();
                    match blob {
                        Some(b) if index == 0 => (label, b.to_vec()),
                        _ => {
                            return Err(SceneError::Buffer {
                                path: self.path.to_path_buf(),
                                index,
                                source_label: label,
                                source: Box::new(if index == 0 {
                                    ResourceError::NoBinChunk
                                } else {
                                    ResourceError::BinChunkNotFirst
                                }),
                            })
                        }
                    }
                }
                gltf::buffer::Source::Uri(uri) => {
                    let label = source::uri_label(uri);
                    let data = self.read_uri(uri).map_err(|source| SceneError::Buffer {
                        path: self.path.to_path_buf(),
                        index,
                        source_label: label.clone(),
                        source: Box::new(source),
                    })?;
                    (label, data)
                }
            };
            if data.len() < buffer.length() {
                return Err(SceneError::Buffer {
                    path: self.path.to_path_buf(),
                    index,
                    source_label: label,
                    source: Box::new(ResourceError::Short {
                        len: data.len(),
                        declared: buffer.length(),
                    }),
                });
            }
            out.push(data);
        }
        Ok(out)
    }

    fn build(&mut self) -> Result<Scene, SceneError> {
        let gscene = match self
            .doc
            .default_scene()
            .or_else(|| self.doc.scenes().next())
        {
            Some(s) => s,
            None => return Err(self.invalid("the file has no scene")),
        };

        // glTF node hierarchies are strict trees. The crate's validation does not check that,
        // and a node shared by several parents, level after level, would multiply the
        // instances exponentially; refuse it up front.
        let mut parent_of: Vec<Option<usize>> = vec![None; self.doc.nodes().len()];
        for node in self.doc.nodes() {
            for child in node.children() {
                if let Some(first) = parent_of[child.index()].replace(node.index()) {
                    return Err(self.invalid(format!(
                        "node {} has two parents (nodes {first} and {}); glTF node hierarchies \
                         must be trees",
                        child.index(),
                        node.index()
                    )));
                }
            }
        }

        // Walk the node tree (iteratively, with cycle and depth guards: validation does not
        // rule out a node being its own ancestor).
        let mut instances = Vec::new();
        let mut lights = Vec::new();
        let mut perspective_camera: Option<Camera> = None;
        let mut orthographic_seen: Option<String> = None;
        let mut on_path = vec![false; self.doc.nodes().len()];
        // (node, parent world matrix, depth); `None` node marks "leave the node on top".
        let mut stack: Vec<(Option<gltf::Node>, Mat4, usize)> = Vec::new();
        for root in gscene.nodes().collect::<Vec<_>>().into_iter().rev() {
            stack.push((Some(root), Mat4::IDENTITY, 0));
        }
        let mut path_nodes: Vec<usize> = Vec::new();
        while let Some((node, parent, depth)) = stack.pop() {
            let Some(node) = node else {
                if let Some(n) = path_nodes.pop() {
                    on_path[n] = false;
                }
                continue;
            };
            let ni = node.index();
            if on_path[ni] {
                return Err(self.invalid(format!(
                    "node {} ({}) is its own ancestor (cyclic node hierarchy)",
                    ni,
                    node.name().unwrap_or("unnamed")
                )));
            }
            if depth > MAX_NODE_DEPTH {
                return Err(self.invalid(format!(
                    "node hierarchy deeper than {MAX_NODE_DEPTH} levels"
                )));
            }
            let local = Mat4::from_cols_array_2d(&node.transform().matrix());
            let world = parent * local;
            if !world.is_finite() {
                return Err(self.invalid(format!(
                    "node {} ({}) has a non-finite transform",
                    ni,
                    node.name().unwrap_or("unnamed")
                )));
            }
            if let Some(mesh) = node.mesh() {
                if node.skin().is_some() {
                    self.warnings.push(format!(
                        "node {ni}: skinning is ignored; mesh \"{}\" is placed by the node's \
                         transform as if unskinned",
                        mesh.name().unwrap_or("unnamed")
                    ));
                }
                instances.push(mesh::MeshInstance { mesh, world });
            }
            if let Some(light) = node.light() {
                lights.push(self.light(&light, &node, world)?);
            }
            if let Some(cam) = node.camera() {
                match cam.projection() {
                    gltf::camera::Projection::Perspective(p) => {
                        if perspective_camera.is_none() && self.config.camera.is_none() {
                            perspective_camera = Some(self.camera(&node, world, p.yfov())?);
                        }
                    }
                    gltf::camera::Projection::Orthographic(_) => {
                        if orthographic_seen.is_none() {
                            orthographic_seen = Some(format!(
                                "camera {} on node {ni} ({})",
                                cam.index(),
                                node.name().unwrap_or("unnamed")
                            ));
                        }
                    }
                }
            }
            on_path[ni] = true;
            path_nodes.push(ni);
            stack.push((None, Mat4::IDENTITY, depth));
            for child in node.children().collect::<Vec<_>>().into_iter().rev() {
                stack.push((Some(child), world, depth + 1));
            }
        }

        // The config's camera wins; else the glTF's first perspective camera; else (only when
        // choosing defaults) a camera framing the geometry, made once the geometry is known.
        self.has_gltf_camera = perspective_camera.is_some();
        let camera = match (&self.config.camera, perspective_camera, orthographic_seen) {
            (Some(c), _, _) => {
                Some(camera::from_config(c).map_err(|e| self.invalid(format!("[camera]: {e}")))?)
            }
            (None, Some(c), _) => Some(c),
            (None, None, _) if self.frame_missing_camera => None,
            (None, None, Some(o)) => {
                return Err(self.invalid(format!(
                    "the scene's only camera is orthographic ({o}); the baker needs a \
                     perspective camera"
                )))
            }
            (None, None, None) => {
                return Err(self.invalid(format!(
                    "the default scene has no camera: add a perspective camera node to the \
                     glTF, or a `[camera]` table (position, target, fov in degrees) to the bake \
                     config {} (docs/config.md); `bake` on the bare glTF frames the scene by \
                     itself",
                    self.config.config_path.display()
                )))
            }
        };

        let n_gltf_materials = self.doc.materials().len();
        let mut geo = mesh::Geometry::default();
        for inst in &instances {
            self.add_mesh(inst, n_gltf_materials, &mut geo)?;
        }
        if geo.skipped > 0 {
            self.warnings.push(format!(
                "{}: skipped {} degenerate, non-finite or out-of-range triangle(s)",
                self.path.display(),
                geo.skipped
            ));
        }
        if geo.repaired_normals > 0 {
            self.warnings.push(format!(
                "{}: replaced {} zero or non-finite vertex normal(s) by the adjacent faces' normal",
                self.path.display(),
                geo.repaired_normals
            ));
        }
        for (mesh, f) in &geo.faceted {
            let mut line = format!(
                "{}: mesh \"{mesh}\" has no normals and is baked faceted (the glTF rule: flat \
                 normals): {} vertices per vertex bake, where smooth normals would need {}",
                self.path.display(),
                f.faceted_vertices,
                f.smooth_vertices
            );
            if f.looks_smooth() {
                line.push_str(&format!(
                    "; its faces meet at a median {:.1} degrees, so it is probably meant to be \
                     smooth: set missing_normals = \"smooth\" in the config to compute smooth \
                     normals",
                    f.median_crease_degrees.unwrap_or(0.0)
                ));
            }
            self.warnings.push(line);
        }
        if geo.repaired_uvs > 0 {
            self.warnings.push(format!(
                "{}: set {} non-finite texture coordinate(s) to (0, 0)",
                self.path.display(),
                geo.repaired_uvs
            ));
        }

        let camera = match camera {
            Some(c) => c,
            None => {
                let aspect = self.config.width as f32 / self.config.height as f32;
                camera::from_config(&camera::framing_camera(&geo.positions, aspect))
                    .map_err(|e| self.invalid(format!("the camera framing the scene: {e}")))?
            }
        };
        let materials = self.materials(geo.uses_default_material)?;
        let environment = self.environment()?;

        Ok(Scene {
            positions: geo.positions,
            normals: geo.normals,
            uvs: geo.uvs,
            triangles: geo.triangles,
            triangle_material: geo.triangle_material,
            materials,
            textures: std::mem::take(&mut self.textures),
            lights,
            camera,
            environment,
            environment_rotation: match &self.config.environment {
                EnvironmentConfig::Map { rotation, .. } => *rotation,
                EnvironmentConfig::Color(_) => 0.0,
            },
            skipped_triangles: geo.skipped,
        })
    }

    fn environment(&mut self) -> Result<Environment, SceneError> {
        match &self.config.environment {
            EnvironmentConfig::Color(c) => Ok(Environment::Constant(*c)),
            EnvironmentConfig::Map {
                path, intensity, ..
            } => {
                let (env, report) = envmap::load_latlong(path, *intensity).map_err(|source| {
                    SceneError::Environment {
                        path: path.clone(),
                        source: Box::new(source),
                    }
                })?;
                if report.clamped_texels > 0 {
                    self.warnings.push(format!(
                        "environment map {}: {} texel(s) with negative channels (lossy \
                         compression rings around bright spots) clamped to 0",
                        path.display(),
                        report.clamped_texels
                    ));
                }
                Ok(env)
            }
        }
    }
}

/// The warning for a scene nothing lights ([`Scene::has_light`]), whose every image would be
/// black, or `None`: it names the scene and says how to light it. Baking such a scene is not an
/// error (a per-vertex bake can be relit under another environment), but it is rarely meant:
/// most glTF models bring no lights, and a config without `[environment]` has a black one.
pub fn unlit_warning(config: &BakeConfig, scene: &Scene) -> Option<String> {
    if scene.has_light() {
        return None;
    }
    let relight = match config.mode {
        crate::config::Mode::Vertex => {
            " (or relight this per-vertex bake under a map with `relight --env FILE`)"
        }
        crate::config::Mode::Pixel => "",
    };
    Some(format!(
        "{}: nothing lights the scene (no emissive material, no punctual light, and the \
         environment is black), so its images will be black; give the bake config {} an \
         `[environment]`, e.g. `map = {:?}`, the neutral studio light a bare glTF gets \
         (docs/config.md){relight}",
        config.scene_path.display(),
        config.config_path.display(),
        crate::config::default_environment_map()
            .display()
            .to_string(),
    ))
}
