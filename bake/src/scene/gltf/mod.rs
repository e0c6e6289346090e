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
//! - Degenerate (zero-area) and non-finite triangles are skipped, counted in
//!   [`Scene::skipped_triangles`] and reported once; out-of-range indices are an error.
//! - Missing TEXCOORD_0 reads as (0, 0); non-finite UVs are set to (0, 0).
//! - Punctual lights are taken radiometrically: 1 cd = 1 W/sr, 1 lux = 1 W/m^2.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use glam::{Mat3, Mat4, Vec2, Vec3};
use gltf::accessor::DataType;
use gltf::khr_lights_punctual::Kind as LightKind;
use gltf::mesh::Mode as PrimitiveMode;
use gltf::Semantic;

use super::gltf_io::{self, UriTarget};
use super::{envmap, Camera, Environment, Material, PunctualLight, Scene, Texture};
use crate::brdf::{BrdfParams, Family, ALPHA_RANGE, SHININESS_RANGE};
use crate::config::{BakeConfig, EnvironmentConfig, MaterialConfig};

/// Node hierarchies deeper than this are refused (they are certainly malformed, and deeper
/// recursion could be used to exhaust the stack).
const MAX_NODE_DEPTH: usize = 512;

/// Name given to the material of primitives that have none.
pub const DEFAULT_MATERIAL_NAME: &str = "default";

/// Ks used when the config switches a material to a specular family and neither it nor the
/// glTF gives one: glTF's dielectric F0.
pub const DEFAULT_KS: f32 = 0.04;

/// Why a scene could not be loaded. Every message names the file at fault and the problem.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    #[error("cannot read {}: {source}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// The glTF/GLB container or JSON is malformed or fails validation.
    #[error("{}: {message}", path.display())]
    Parse { path: PathBuf, message: String },
    /// A buffer could not be read or is shorter than declared.
    #[error("{}: buffer {index} ({source_label}): {message}", path.display())]
    Buffer {
        path: PathBuf,
        index: usize,
        source_label: String,
        message: String,
    },
    /// A texture image could not be read or decoded.
    #[error("{}: image {index} ({source_label}): {message}", path.display())]
    Image {
        path: PathBuf,
        index: usize,
        source_label: String,
        message: String,
    },
    /// A mesh primitive's data is malformed (bad accessor, out-of-range index, ...).
    #[error("{}: mesh \"{mesh}\" primitive {primitive}: {message}", path.display())]
    Mesh {
        path: PathBuf,
        mesh: String,
        primitive: usize,
        message: String,
    },
    /// A material's glTF data or its config overrides are unusable; `path` is the file at
    /// fault (the glTF or the bake config).
    #[error("{}: material \"{material}\": {message}", path.display())]
    Material {
        path: PathBuf,
        material: String,
        message: String,
    },
    /// The config names materials that the glTF does not have.
    #[error(
        "{}: [materials.{name}] names no material of {}; available: {}",
        config.display(),
        scene.display(),
        available.join(", ")
    )]
    UnknownMaterial {
        config: PathBuf,
        scene: PathBuf,
        name: String,
        available: Vec<String>,
    },
    /// Anything else wrong with the scene (nodes, lights, camera).
    #[error("{}: {message}", path.display())]
    Invalid { path: PathBuf, message: String },
    /// The environment map could not be used.
    #[error("environment map {}: {message}", path.display())]
    Environment { path: PathBuf, message: String },
}

/// Loads the scene named by `config`, printing warnings (skipped primitives, skipped
/// triangles, ...) to stderr. See [`load_with_warnings`] to get them instead.
pub fn load(config: &BakeConfig) -> Result<Scene, SceneError> {
    let (scene, warnings) = load_with_warnings(config)?;
    for w in &warnings {
        eprintln!("warning: {w}");
    }
    Ok(scene)
}

/// Like [`load`], but returns the warnings instead of printing them.
pub fn load_with_warnings(config: &BakeConfig) -> Result<(Scene, Vec<String>), SceneError> {
    let path = config.scene_path.as_path();
    let bytes = std::fs::read(path).map_err(|source| SceneError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let gltf = gltf_io::parse(&bytes).map_err(|message| SceneError::Parse {
        path: path.to_path_buf(),
        message,
    })?;
    drop(bytes);
    let mut loader = Loader {
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
    Ok((scene, loader.warnings))
}

struct Loader<'a> {
    config: &'a BakeConfig,
    path: &'a Path,
    folder: PathBuf,
    doc: &'a gltf::Document,
    buffers: Vec<Vec<u8>>,
    warnings: Vec<String>,
    textures: Vec<Texture>,
    texture_of_image: HashMap<usize, usize>,
}

/// A mesh instance found while walking the node tree.
struct MeshInstance<'a> {
    mesh: gltf::Mesh<'a>,
    world: Mat4,
}

/// Geometry accumulated over all primitives.
#[derive(Default)]
struct Geometry {
    positions: Vec<Vec3>,
    normals: Vec<Vec3>,
    uvs: Vec<Vec2>,
    triangles: Vec<[u32; 3]>,
    triangle_material: Vec<u32>,
    skipped: usize,
    repaired_normals: usize,
    repaired_uvs: usize,
    uses_default_material: bool,
}

impl<'a> Loader<'a> {
    fn invalid(&self, message: impl Into<String>) -> SceneError {
        SceneError::Invalid {
            path: self.path.to_path_buf(),
            message: message.into(),
        }
    }

    fn read_file(&self, file: &Path) -> Result<Vec<u8>, std::io::Error> {
        std::fs::read(file)
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
                                message: if index == 0 {
                                    "the buffer has no URI and the file has no GLB BIN chunk"
                                        .to_owned()
                                } else {
                                    "only buffer 0 may use the GLB BIN chunk; this one has no URI"
                                        .to_owned()
                                },
                            })
                        }
                    }
                }
                gltf::buffer::Source::Uri(uri) => {
                    let label = gltf_io::uri_label(uri);
                    let err = |message: String| SceneError::Buffer {
                        path: self.path.to_path_buf(),
                        index,
                        source_label: label.clone(),
                        message,
                    };
                    let data = match gltf_io::resolve_uri(uri, &self.folder).map_err(err)? {
                        UriTarget::Data(d) => d,
                        UriTarget::File(f) => self
                            .read_file(&f)
                            .map_err(|e| err(format!("cannot read {}: {e}", f.display())))?,
                    };
                    (label, data)
                }
            };
            if data.len() < buffer.length() {
                return Err(SceneError::Buffer {
                    path: self.path.to_path_buf(),
                    index,
                    source_label: label,
                    message: format!(
                        "holds {} bytes but the glTF declares byteLength {}",
                        data.len(),
                        buffer.length()
                    ),
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
                instances.push(MeshInstance { mesh, world });
            }
            if let Some(light) = node.light() {
                lights.push(self.light(&light, &node, world)?);
            }
            if let Some(cam) = node.camera() {
                match cam.projection() {
                    gltf::camera::Projection::Perspective(p) => {
                        if perspective_camera.is_none() {
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

        let camera = match (perspective_camera, orthographic_seen) {
            (Some(c), _) => c,
            (None, Some(o)) => {
                return Err(self.invalid(format!(
                    "the scene's only camera is orthographic ({o}); the baker needs a \
                     perspective camera"
                )))
            }
            (None, None) => {
                return Err(
                    self.invalid("the default scene has no camera; add a perspective camera node")
                )
            }
        };

        let n_gltf_materials = self.doc.materials().len();
        let mut geo = Geometry::default();
        for inst in &instances {
            self.add_mesh(inst, n_gltf_materials, &mut geo)?;
        }
        if geo.skipped > 0 {
            self.warnings.push(format!(
                "{}: skipped {} degenerate or non-finite triangle(s)",
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
        if geo.repaired_uvs > 0 {
            self.warnings.push(format!(
                "{}: set {} non-finite texture coordinate(s) to (0, 0)",
                self.path.display(),
                geo.repaired_uvs
            ));
        }

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
            skipped_triangles: geo.skipped,
        })
    }

    fn light(
        &mut self,
        light: &gltf::khr_lights_punctual::Light,
        node: &gltf::Node,
        world: Mat4,
    ) -> Result<PunctualLight, SceneError> {
        let name = light.name().unwrap_or("unnamed");
        let path = self.path;
        let err = |m: String| SceneError::Invalid {
            path: path.to_path_buf(),
            message: format!("light {} ({name}): {m}", light.index()),
        };
        let color = Vec3::from_array(light.color());
        let intensity = light.intensity();
        if !color.is_finite() || color.min_element() < 0.0 {
            return Err(err(format!("color {color:?} must be finite and >= 0")));
        }
        if !intensity.is_finite() || intensity < 0.0 {
            return Err(err(format!(
                "intensity {intensity} must be finite and >= 0"
            )));
        }
        if light.range().is_some() {
            // Physically based transport has no cut-off; say so rather than silently differ.
            self.warnings.push(format!(
                "{}: light {} ({name}): `range` is ignored; intensity falls off as 1/d^2 \
                 without cut-off",
                self.path.display(),
                light.index()
            ));
        }
        let power = color * intensity;
        let position = world.transform_point3(Vec3::ZERO);
        let direction = world.transform_vector3(Vec3::NEG_Z).normalize_or_zero();
        let need_direction = || {
            if direction == Vec3::ZERO || !direction.is_finite() {
                Err(err(format!(
                    "node {} has a degenerate transform, so the light has no direction",
                    node.index()
                )))
            } else {
                Ok(direction)
            }
        };
        Ok(match light.kind() {
            LightKind::Point => PunctualLight::Point {
                position,
                intensity: power,
            },
            LightKind::Spot {
                inner_cone_angle,
                outer_cone_angle,
            } => {
                let half_pi = std::f32::consts::FRAC_PI_2;
                if !(inner_cone_angle.is_finite()
                    && outer_cone_angle.is_finite()
                    && 0.0 <= inner_cone_angle
                    && inner_cone_angle <= outer_cone_angle
                    && outer_cone_angle <= half_pi + 1e-6)
                {
                    return Err(err(format!(
                        "spot cone angles inner {inner_cone_angle}, outer {outer_cone_angle} \
                         must satisfy 0 <= inner <= outer <= pi/2"
                    )));
                }
                PunctualLight::Spot {
                    position,
                    direction: need_direction()?,
                    intensity: power,
                    inner_cone: inner_cone_angle,
                    outer_cone: outer_cone_angle.min(half_pi),
                }
            }
            LightKind::Directional => PunctualLight::Directional {
                direction: need_direction()?,
                irradiance: power,
            },
        })
    }

    fn camera(&self, node: &gltf::Node, world: Mat4, yfov: f32) -> Result<Camera, SceneError> {
        let err = |m: &str| {
            self.invalid(format!(
                "camera on node {} ({}): {m}",
                node.index(),
                node.name().unwrap_or("unnamed")
            ))
        };
        if !(yfov.is_finite() && yfov > 0.0 && yfov < std::f32::consts::PI) {
            return Err(err(&format!("yfov {yfov} must be in (0, pi) radians")));
        }
        let position = world.transform_point3(Vec3::ZERO);
        let forward = world.transform_vector3(Vec3::NEG_Z).normalize_or_zero();
        let up0 = world.transform_vector3(Vec3::Y);
        let right = forward.cross(up0).normalize_or_zero();
        if forward == Vec3::ZERO || right == Vec3::ZERO || !right.is_finite() {
            return Err(err("degenerate transform (zero scale or collapsed axes)"));
        }
        // Re-orthogonalize: node scales/shears must not skew the image plane.
        let up = right.cross(forward);
        Ok(Camera {
            position,
            forward,
            up,
            right,
            yfov,
        })
    }

    fn add_mesh(
        &mut self,
        inst: &MeshInstance,
        n_gltf_materials: usize,
        geo: &mut Geometry,
    ) -> Result<(), SceneError> {
        let mesh = &inst.mesh;
        let world = inst.world;
        let linear = Mat3::from_mat4(world);
        let flip = linear.determinant() < 0.0;
        // Inverse transpose for normals; a singular matrix (zero scale) flattens the mesh, and
        // its triangles then fail the area test below anyway.
        let normal_matrix = if linear.determinant().abs() > 0.0 {
            linear.inverse().transpose()
        } else {
            linear
        };

        for prim in mesh.primitives() {
            let pi = prim.index();
            if prim.mode() != PrimitiveMode::Triangles {
                self.warnings.push(format!(
                    "{}: mesh \"{}\" primitive {pi}: mode {:?} is not supported (only \
                     TRIANGLES); skipped",
                    self.path.display(),
                    mesh_label(mesh),
                    prim.mode()
                ));
                continue;
            }
            let path = self.path;
            let perr = |message: String| SceneError::Mesh {
                path: path.to_path_buf(),
                mesh: mesh_label(mesh),
                primitive: pi,
                message,
            };
            let pos_acc = prim
                .get(&Semantic::Positions)
                .ok_or_else(|| perr("no POSITION attribute".to_owned()))?;
            let pos = gltf_io::read_f32(
                &pos_acc,
                &self.buffers,
                "POSITION",
                3,
                &[(DataType::F32, false)],
            )
            .map_err(perr)?;
            let n_verts = pos.len() / 3;
            let nor = match prim.get(&Semantic::Normals) {
                Some(acc) => {
                    let v = gltf_io::read_f32(
                        &acc,
                        &self.buffers,
                        "NORMAL",
                        3,
                        &[(DataType::F32, false)],
                    )
                    .map_err(perr)?;
                    if v.len() != pos.len() {
                        return Err(perr(format!(
                            "NORMAL has {} elements but POSITION has {n_verts}",
                            v.len() / 3
                        )));
                    }
                    Some(v)
                }
                None => None,
            };
            let uv = match prim.get(&Semantic::TexCoords(0)) {
                Some(acc) => {
                    let v = gltf_io::read_f32(
                        &acc,
                        &self.buffers,
                        "TEXCOORD_0",
                        2,
                        &[
                            (DataType::F32, false),
                            (DataType::U8, true),
                            (DataType::U16, true),
                        ],
                    )
                    .map_err(perr)?;
                    if v.len() / 2 != n_verts {
                        return Err(perr(format!(
                            "TEXCOORD_0 has {} elements but POSITION has {n_verts}",
                            v.len() / 2
                        )));
                    }
                    Some(v)
                }
                None => None,
            };
            let indices: Vec<u32> = match prim.indices() {
                Some(acc) => {
                    let idx = gltf_io::read_indices(&acc, &self.buffers).map_err(perr)?;
                    if let Some((k, &bad)) =
                        idx.iter().enumerate().find(|(_, &i)| i as usize >= n_verts)
                    {
                        return Err(perr(format!(
                            "index {bad} (entry {k} of accessor {}) is out of range: the \
                             primitive has {n_verts} vertices",
                            acc.index()
                        )));
                    }
                    idx
                }
                None => {
                    if n_verts > u32::MAX as usize {
                        return Err(perr(format!("{n_verts} vertices is too many")));
                    }
                    (0..n_verts as u32).collect()
                }
            };
            if !indices.len().is_multiple_of(3) {
                let what = if prim.indices().is_some() {
                    "indices"
                } else {
                    "vertices (non-indexed)"
                };
                return Err(perr(format!(
                    "{} {what} is not a multiple of 3 (mode TRIANGLES)",
                    indices.len()
                )));
            }

            let material = match prim.material().index() {
                Some(i) => i as u32,
                None => {
                    geo.uses_default_material = true;
                    n_gltf_materials as u32
                }
            };
            let textured = prim
                .material()
                .pbr_metallic_roughness()
                .base_color_texture()
                .is_some()
                || prim.material().emissive_texture().is_some();
            if textured && uv.is_none() {
                self.warnings.push(format!(
                    "{}: mesh \"{}\" primitive {pi}: its material has a texture but the \
                     primitive has no TEXCOORD_0; it samples texel (0, 0)",
                    self.path.display(),
                    mesh_label(mesh)
                ));
            }

            // World-space attributes.
            let wpos: Vec<Vec3> = pos
                .chunks_exact(3)
                .map(|c| world.transform_point3(Vec3::new(c[0], c[1], c[2])))
                .collect();
            let wnor: Option<Vec<Vec3>> = nor.map(|n| {
                n.chunks_exact(3)
                    .map(|c| (normal_matrix * Vec3::new(c[0], c[1], c[2])).normalize_or_zero())
                    .collect()
            });
            let get_uv = |v: usize, geo_repaired: &mut usize| -> Vec2 {
                match &uv {
                    Some(u) => {
                        let t = Vec2::new(u[2 * v], u[2 * v + 1]);
                        if t.is_finite() {
                            t
                        } else {
                            *geo_repaired += 1;
                            Vec2::ZERO
                        }
                    }
                    None => Vec2::ZERO,
                }
            };

            // Remap used vertices so the scene holds only vertices of kept triangles (a NaN
            // vertex used only by skipped triangles must not reach the BVH's bounds).
            let mut remap = vec![u32::MAX; if wnor.is_some() { n_verts } else { 0 }];
            // Area-weighted face normal sums for vertices whose supplied normal is unusable.
            let mut fix: HashMap<u32, Vec3> = HashMap::new();
            for tri in indices.chunks_exact(3) {
                let (a, mut b, mut c) = (tri[0] as usize, tri[1] as usize, tri[2] as usize);
                if flip {
                    std::mem::swap(&mut b, &mut c);
                }
                let (p0, p1, p2) = (wpos[a], wpos[b], wpos[c]);
                let cross = (p1 - p0).cross(p2 - p0);
                let ok = p0.is_finite()
                    && p1.is_finite()
                    && p2.is_finite()
                    && cross.is_finite()
                    && cross.length_squared() > 0.0
                    && cross.normalize_or_zero() != Vec3::ZERO;
                if !ok {
                    geo.skipped += 1;
                    continue;
                }
                if geo.positions.len() + 3 > u32::MAX as usize {
                    return Err(perr("the scene has more than 2^32 vertices".to_owned()));
                }
                let mut out = [0u32; 3];
                match &wnor {
                    None => {
                        // Flat normals (glTF spec 3.7.2.1): unshared vertices per triangle.
                        for (k, &v) in [a, b, c].iter().enumerate() {
                            out[k] = geo.positions.len() as u32;
                            geo.positions.push(wpos[v]);
                            geo.normals.push(cross.normalize());
                            let t = get_uv(v, &mut geo.repaired_uvs);
                            geo.uvs.push(t);
                        }
                    }
                    Some(wn) => {
                        for (k, &v) in [a, b, c].iter().enumerate() {
                            if remap[v] == u32::MAX {
                                remap[v] = geo.positions.len() as u32;
                                geo.positions.push(wpos[v]);
                                let n = wn[v];
                                geo.normals.push(n);
                                let t = get_uv(v, &mut geo.repaired_uvs);
                                geo.uvs.push(t);
                            }
                            out[k] = remap[v];
                            if wn[v] == Vec3::ZERO || !wn[v].is_finite() {
                                // |cross| = twice the area: area weighting for free.
                                *fix.entry(remap[v]).or_insert(Vec3::ZERO) += cross;
                            }
                        }
                    }
                }
                geo.triangles.push(out);
                geo.triangle_material.push(material);
            }
            for (v, sum) in fix {
                geo.normals[v as usize] = sum.normalize_or(Vec3::Y);
                geo.repaired_normals += 1;
            }
        }
        Ok(())
    }

    /// One [`Material`] per glTF material (plus `default` when a primitive has none), with the
    /// config's overrides applied.
    fn materials(&mut self, uses_default: bool) -> Result<Vec<Material>, SceneError> {
        let doc = self.doc;
        let mut names: Vec<String> = Vec::new();
        let mut seen: HashMap<String, usize> = HashMap::new();
        for m in doc.materials() {
            let i = m.index().unwrap_or(names.len());
            let mut name = m
                .name()
                .map(str::to_owned)
                .unwrap_or_else(|| format!("material{i}"));
            if seen.contains_key(&name) {
                // Config tables are keyed by name, so names must be unique.
                let unique = format!("{name}#{i}");
                self.warnings.push(format!(
                    "{}: material {i} is named \"{name}\" like material {}; it is called \
                     \"{unique}\" here",
                    self.path.display(),
                    seen[&name]
                ));
                name = unique;
            }
            seen.insert(name.clone(), i);
            names.push(name);
        }
        if uses_default {
            let mut name = DEFAULT_MATERIAL_NAME.to_owned();
            if seen.contains_key(&name) {
                name = format!("{DEFAULT_MATERIAL_NAME}#{}", names.len());
            }
            names.push(name);
        }

        // Every config table must name a material of the scene.
        for (name, _) in &self.config.materials {
            if !names.iter().any(|n| n == name) {
                return Err(SceneError::UnknownMaterial {
                    config: self.config.config_path.clone(),
                    scene: self.path.to_path_buf(),
                    name: name.clone(),
                    available: names.iter().map(|n| format!("\"{n}\"")).collect(),
                });
            }
        }

        let mut out = Vec::with_capacity(names.len());
        for (i, m) in doc.materials().enumerate() {
            let name = names[i].clone();
            let merr = |message: String| SceneError::Material {
                path: self.path.to_path_buf(),
                material: name.clone(),
                message,
            };
            let pbr = m.pbr_metallic_roughness();
            let bc = pbr.base_color_factor();
            let base = Vec3::new(bc[0], bc[1], bc[2]);
            if !base.is_finite() || base.min_element() < 0.0 {
                return Err(merr(format!(
                    "baseColorFactor {bc:?} must be finite and >= 0"
                )));
            }
            let (metallic, roughness) = (pbr.metallic_factor(), pbr.roughness_factor());
            if !metallic.is_finite() || !roughness.is_finite() {
                return Err(merr(
                    "metallicFactor/roughnessFactor must be finite".to_owned(),
                ));
            }
            if pbr.metallic_roughness_texture().is_some() {
                self.warnings.push(format!(
                    "{}: material \"{name}\": metallicRoughnessTexture is ignored (one BRDF per \
                     material); the factors are used",
                    self.path.display()
                ));
            }
            let strength = m.emissive_strength().unwrap_or(1.0);
            let emission = Vec3::from_array(m.emissive_factor()) * strength;
            if !emission.is_finite() || emission.min_element() < 0.0 {
                return Err(merr(format!(
                    "emission {emission:?} (emissiveFactor x emissiveStrength) must be finite and >= 0"
                )));
            }
            let base_color_texture = match pbr.base_color_texture() {
                Some(info) => Some(self.texture(&info, &name, "baseColorTexture")?),
                None => None,
            };
            let emissive_texture = match m.emissive_texture() {
                Some(info) => Some(self.texture(&info, &name, "emissiveTexture")?),
                None => None,
            };
            let gltf_pbr = GltfPbr {
                base,
                metallic,
                roughness,
            };
            let cfg = self.config.material(&name);
            let brdf =
                resolve_brdf(Some(gltf_pbr), cfg).map_err(|message| SceneError::Material {
                    path: self.config.config_path.clone(),
                    material: name.clone(),
                    message,
                })?;
            out.push(Material {
                name,
                brdf,
                base_color_texture,
                emission,
                emissive_texture,
                editable: cfg.is_some_and(|c| c.editable),
            });
        }
        if uses_default {
            let name = names[names.len() - 1].clone();
            let cfg = self.config.material(&name);
            let brdf = resolve_brdf(None, cfg).map_err(|message| SceneError::Material {
                path: self.config.config_path.clone(),
                material: name.clone(),
                message,
            })?;
            out.push(Material {
                name,
                brdf,
                base_color_texture: None,
                emission: Vec3::ZERO,
                emissive_texture: None,
                editable: cfg.is_some_and(|c| c.editable),
            });
        }
        Ok(out)
    }

    /// Loads (once per glTF image) the image behind a texture reference, sRGB-decoded.
    fn texture(
        &mut self,
        info: &gltf::texture::Info,
        material: &str,
        slot: &str,
    ) -> Result<usize, SceneError> {
        if info.tex_coord() != 0 {
            self.warnings.push(format!(
                "{}: material \"{material}\": {slot} uses TEXCOORD_{}; only TEXCOORD_0 is read",
                self.path.display(),
                info.tex_coord()
            ));
        }
        let image = info.texture().source();
        let index = image.index();
        if let Some(&t) = self.texture_of_image.get(&index) {
            return Ok(t);
        }
        let (label, bytes) = match image.source() {
            gltf::image::Source::View { view, .. } => {
                let label = format!("buffer view {}", view.index());
                let bytes = gltf_io::view_bytes(&view, &self.buffers)
                    .map_err(|message| SceneError::Image {
                        path: self.path.to_path_buf(),
                        index,
                        source_label: label.clone(),
                        message,
                    })?
                    .to_vec();
                (label, bytes)
            }
            gltf::image::Source::Uri { uri, .. } => {
                let label = gltf_io::uri_label(uri);
                let err = |message: String| SceneError::Image {
                    path: self.path.to_path_buf(),
                    index,
                    source_label: label.clone(),
                    message,
                };
                let bytes = match gltf_io::resolve_uri(uri, &self.folder).map_err(err)? {
                    UriTarget::Data(d) => d,
                    UriTarget::File(f) => self
                        .read_file(&f)
                        .map_err(|e| err(format!("cannot read {}: {e}", f.display())))?,
                };
                (label, bytes)
            }
        };
        let img = image::load_from_memory(&bytes).map_err(|e| SceneError::Image {
            path: self.path.to_path_buf(),
            index,
            source_label: label.clone(),
            message: format!("cannot decode: {e}"),
        })?;
        let rgb = img.to_rgb32f();
        let (width, height) = (rgb.width(), rgb.height());
        let texels = rgb
            .pixels()
            .map(|p| {
                Vec3::new(
                    srgb_to_linear(p.0[0]),
                    srgb_to_linear(p.0[1]),
                    srgb_to_linear(p.0[2]),
                )
            })
            .collect();
        let name = image
            .name()
            .map(str::to_owned)
            .unwrap_or_else(|| label.trim_matches('"').to_owned());
        self.textures.push(Texture {
            name,
            width,
            height,
            texels,
        });
        let t = self.textures.len() - 1;
        self.texture_of_image.insert(index, t);
        Ok(t)
    }

    fn environment(&mut self) -> Result<Environment, SceneError> {
        match &self.config.environment {
            EnvironmentConfig::Color(c) => Ok(Environment::Constant(*c)),
            EnvironmentConfig::Map { path, intensity } => {
                let (env, report) = envmap::load_latlong(path, *intensity).map_err(|message| {
                    SceneError::Environment {
                        path: path.clone(),
                        message,
                    }
                })?;
                if report.replaced_texels > 0 {
                    self.warnings.push(format!(
                        "environment map {}: {} NaN, infinite or negative texel(s) set to black",
                        path.display(),
                        report.replaced_texels
                    ));
                }
                Ok(env)
            }
        }
    }
}

fn mesh_label(mesh: &gltf::Mesh) -> String {
    match mesh.name() {
        Some(n) => n.to_owned(),
        None => format!("mesh{}", mesh.index()),
    }
}

/// The sRGB transfer function, inverted (IEC 61966-2-1).
pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// The metallic-roughness values of a glTF material.
#[derive(Clone, Copy, Debug)]
pub struct GltfPbr {
    pub base: Vec3,
    pub metallic: f32,
    pub roughness: f32,
}

/// Blinn-Phong exponent with the same lobe width as a GGX/Beckmann alpha (Walter et al. 2007,
/// "Microfacet models for refraction", eq. 29: s = 2 / alpha^2 - 2), clamped to the accepted
/// range.
pub fn alpha_to_shininess(alpha: f32) -> f32 {
    let a = alpha.max(ALPHA_RANGE.0);
    (2.0 / (a * a) - 2.0).clamp(SHININESS_RANGE.0, SHININESS_RANGE.1)
}

/// The BRDF of one material: the glTF mapping (`pbr`; `None` for the default material, white
/// diffuse) with the config's overrides. Rules (docs/conventions.md):
///
/// - `family` defaults to the glTF mapping's ([`BrdfParams::from_gltf_pbr`]).
/// - `kd` defaults to the glTF Kd = baseColor (1 - metallic).
/// - `ks` defaults to the glTF Ks = mix(0.04, baseColor, metallic) and the lobe parameter to the
///   glTF roughness (GGX alpha = roughness^2; Blinn-Phong s = 2 / alpha^2 - 2) — but only when
///   the glTF mapping itself is specular. A fully rough dielectric (mapped to `diffuse`) or the
///   default material supplies no specular lobe: for an *editable* material that is an error
///   (the user must say which lobe the bake starts from); otherwise the fallbacks are
///   Ks = 0.04 and the glTF roughness as above.
/// - A parameter the resolved family does not use is an error.
pub fn resolve_brdf(
    pbr: Option<GltfPbr>,
    cfg: Option<&MaterialConfig>,
) -> Result<BrdfParams, String> {
    let gltf = match pbr {
        Some(p) => BrdfParams::from_gltf_pbr(p.base, p.metallic, p.roughness),
        None => BrdfParams::diffuse(Vec3::ONE),
    };
    let Some(cfg) = cfg else {
        return Ok(gltf);
    };
    let family = cfg.family.unwrap_or(gltf.family);
    let from_gltf = if cfg.family.is_some() {
        "".to_owned()
    } else {
        format!(" (the glTF material maps to {})", family.name())
    };
    let stray = |key: &str| {
        Err(format!(
            "`{key}` does not apply to family \"{}\"{from_gltf}; set `family` to one that uses it",
            family.name()
        ))
    };
    match family {
        Family::Diffuse => {
            if cfg.ks.is_some() {
                return stray("ks");
            }
            if cfg.alpha.is_some() {
                return stray("alpha");
            }
            if cfg.shininess.is_some() {
                return stray("shininess");
            }
        }
        Family::BlinnPhong => {
            if cfg.alpha.is_some() {
                return stray("alpha");
            }
        }
        Family::Ggx => {
            if cfg.shininess.is_some() {
                return stray("shininess");
            }
        }
    }

    let kd = cfg.kd.unwrap_or(gltf.kd);
    if family == Family::Diffuse {
        return Ok(BrdfParams::diffuse(kd));
    }
    let gltf_specular = gltf.family != Family::Diffuse;
    let roughness = pbr.map_or(1.0, |p| p.roughness.clamp(0.0, 1.0));
    let fallback_alpha = (roughness * roughness).clamp(ALPHA_RANGE.0, ALPHA_RANGE.1);
    let fallback_ks = pbr.map_or(Vec3::splat(DEFAULT_KS), |p| {
        Vec3::splat(DEFAULT_KS).lerp(p.base, p.metallic.clamp(0.0, 1.0))
    });
    let (param_key, cfg_param) = match family {
        Family::BlinnPhong => ("shininess", cfg.shininess),
        _ => ("alpha", cfg.alpha),
    };
    if !gltf_specular && cfg.editable {
        let mut missing = Vec::new();
        if cfg.ks.is_none() {
            missing.push("`ks`");
        }
        if cfg_param.is_none() {
            missing.push(if param_key == "alpha" {
                "`alpha`"
            } else {
                "`shininess`"
            });
        }
        if !missing.is_empty() {
            let why = if pbr.is_some() {
                "the glTF material is a fully rough dielectric (it maps to diffuse)"
            } else {
                "the default material is plain diffuse"
            };
            return Err(format!(
                "editable family \"{}\" needs {} in the config: {why} and supplies no specular lobe",
                family.name(),
                missing.join(" and ")
            ));
        }
    }
    let ks = cfg
        .ks
        .unwrap_or(if gltf_specular { gltf.ks } else { fallback_ks });
    let gltf_alpha = if gltf_specular {
        gltf.param
    } else {
        fallback_alpha
    };
    let param = match family {
        Family::BlinnPhong => cfg
            .shininess
            .unwrap_or_else(|| alpha_to_shininess(gltf_alpha)),
        _ => cfg.alpha.unwrap_or(gltf_alpha),
    };
    Ok(BrdfParams {
        family,
        kd,
        ks,
        param,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cfg() -> MaterialConfig {
        MaterialConfig::default()
    }

    #[test]
    fn overrides_apply_individually() {
        let metal = GltfPbr {
            base: Vec3::new(0.9, 0.6, 0.2),
            metallic: 1.0,
            roughness: 0.5,
        };
        let g = resolve_brdf(Some(metal), None).unwrap();
        assert_eq!(g.family, Family::Ggx);
        let c = MaterialConfig {
            alpha: Some(0.1),
            ..cfg()
        };
        let b = resolve_brdf(Some(metal), Some(&c)).unwrap();
        assert_eq!((b.family, b.ks, b.param), (Family::Ggx, g.ks, 0.1));
        let c = MaterialConfig {
            family: Some(Family::BlinnPhong),
            ..cfg()
        };
        let b = resolve_brdf(Some(metal), Some(&c)).unwrap();
        assert_eq!(b.family, Family::BlinnPhong);
        assert!((b.param - alpha_to_shininess(0.25)).abs() < 1e-3);
        assert_eq!(b.ks, g.ks);
    }

    #[test]
    fn editable_specular_needs_params_when_gltf_is_diffuse() {
        let rough = GltfPbr {
            base: Vec3::splat(0.5),
            metallic: 0.0,
            roughness: 1.0,
        };
        let c = MaterialConfig {
            editable: true,
            family: Some(Family::BlinnPhong),
            ..cfg()
        };
        let e = resolve_brdf(Some(rough), Some(&c)).unwrap_err();
        assert!(e.contains("`ks`") && e.contains("`shininess`"), "{e}");
        let c = MaterialConfig {
            editable: false,
            ..c
        };
        let b = resolve_brdf(Some(rough), Some(&c)).unwrap();
        assert_eq!(b.ks, Vec3::splat(DEFAULT_KS));
        let c = MaterialConfig {
            alpha: Some(0.3),
            ..cfg()
        };
        assert!(resolve_brdf(Some(rough), Some(&c))
            .unwrap_err()
            .contains("alpha"));
    }

    #[test]
    fn srgb_endpoints() {
        assert_eq!(srgb_to_linear(0.0), 0.0);
        assert!((srgb_to_linear(1.0) - 1.0).abs() < 1e-6);
        assert!((srgb_to_linear(0.5) - 0.214).abs() < 1e-3);
    }
}
