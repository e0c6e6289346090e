//! Mesh geometry: reading a mesh instance's TRIANGLES primitives into world-space vertex and
//! triangle arrays (transforms, winding, flat or repaired normals, skipped triangles).

use std::collections::HashMap;

use glam::{Mat3, Mat4, Vec2, Vec3};
use gltf::accessor::DataType;
use gltf::mesh::Mode as PrimitiveMode;
use gltf::Semantic;

use super::accessors;
use super::facets::{analyse, Facets};
use super::Loader;
use crate::config::MissingNormals;
use crate::scene::error::MeshError;
use crate::scene::SceneError;

/// Largest accepted vertex coordinate magnitude, in metres (far beyond any real scene). Sums
/// and products of coordinates (bounding boxes, areas, ray-triangle determinants) must stay
/// finite in f32: a vertex near f32::MAX made the BVH builder panic (found by fuzzing).
const MAX_COORDINATE: f32 = 1e15;

/// Whether a world-space vertex is finite and within [`MAX_COORDINATE`].
fn in_range(p: Vec3) -> bool {
    p.is_finite() && p.abs().max_element() <= MAX_COORDINATE
}

/// A mesh instance found while walking the node tree.
pub(super) struct MeshInstance<'a> {
    pub mesh: gltf::Mesh<'a>,
    pub world: Mat4,
}

/// Geometry accumulated over all primitives.
#[derive(Default)]
pub(super) struct Geometry {
    pub positions: Vec<Vec3>,
    pub normals: Vec<Vec3>,
    pub uvs: Vec<Vec2>,
    pub triangles: Vec<[u32; 3]>,
    pub triangle_material: Vec<u32>,
    pub skipped: usize,
    pub repaired_normals: usize,
    /// Primitives without normals baked faceted: mesh name and what it costs.
    pub faceted: Vec<(String, Facets)>,
    pub repaired_uvs: usize,
    pub uses_default_material: bool,
}

impl Loader<'_> {
    pub(super) fn add_mesh(
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
            let perr = |source: MeshError| SceneError::Mesh {
                path: path.to_path_buf(),
                mesh: mesh_label(mesh),
                primitive: pi,
                source: Box::new(source),
            };
            let aerr = |e: crate::scene::error::AccessorError| perr(MeshError::Accessor(e));
            let pos_acc = prim
                .get(&Semantic::Positions)
                .ok_or_else(|| perr(MeshError::NoPosition))?;
            let pos = accessors::read_f32(
                &pos_acc,
                &self.buffers,
                "POSITION",
                3,
                &[(DataType::F32, false)],
            )
            .map_err(aerr)?;
            let n_verts = pos.len() / 3;
            let nor = match prim.get(&Semantic::Normals) {
                Some(acc) => {
                    let v = accessors::read_f32(
                        &acc,
                        &self.buffers,
                        "NORMAL",
                        3,
                        &[(DataType::F32, false)],
                    )
                    .map_err(aerr)?;
                    if v.len() != pos.len() {
                        return Err(perr(MeshError::CountMismatch {
                            attribute: "NORMAL",
                            found: v.len() / 3,
                            positions: n_verts,
                        }));
                    }
                    Some(v)
                }
                None => None,
            };
            let uv = match prim.get(&Semantic::TexCoords(0)) {
                Some(acc) => {
                    let v = accessors::read_f32(
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
                    .map_err(aerr)?;
                    if v.len() / 2 != n_verts {
                        return Err(perr(MeshError::CountMismatch {
                            attribute: "TEXCOORD_0",
                            found: v.len() / 2,
                            positions: n_verts,
                        }));
                    }
                    Some(v)
                }
                None => None,
            };
            let indices: Vec<u32> = match prim.indices() {
                Some(acc) => {
                    let idx = accessors::read_indices(&acc, &self.buffers).map_err(aerr)?;
                    if let Some((k, &bad)) =
                        idx.iter().enumerate().find(|(_, &i)| i as usize >= n_verts)
                    {
                        return Err(perr(MeshError::IndexOutOfRange {
                            index: bad,
                            entry: k,
                            accessor: acc.index(),
                            vertices: n_verts,
                        }));
                    }
                    idx
                }
                None => {
                    if n_verts > u32::MAX as usize {
                        return Err(perr(MeshError::TooManyVertices(n_verts)));
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
                return Err(perr(MeshError::NotTriangles {
                    count: indices.len(),
                    what,
                }));
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
            if prim.material().normal_texture().is_some() && uv.is_none() {
                self.warnings.push(format!(
                    "{}: mesh \"{}\" primitive {pi}: its material has a normalTexture but the \
                     primitive has no TEXCOORD_0 to orient it by; the map is not applied there",
                    self.path.display(),
                    mesh_label(mesh)
                ));
            }
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
            // Without normals and asked for smooth ones: zero normals, which the repair below
            // replaces by the area-weighted normal of the faces around each vertex.
            let smoothing = nor.is_none() && self.config.missing_normals == MissingNormals::Smooth;
            let wnor: Option<Vec<Vec3>> = match nor {
                Some(n) => Some(
                    n.chunks_exact(3)
                        .map(|c| (normal_matrix * Vec3::new(c[0], c[1], c[2])).normalize_or_zero())
                        .collect(),
                ),
                None if smoothing => Some(vec![Vec3::ZERO; n_verts]),
                None => None,
            };
            let mut flat_faces: Vec<([u32; 3], Vec3)> = Vec::new();
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
                let ok = in_range(p0)
                    && in_range(p1)
                    && in_range(p2)
                    && cross.is_finite()
                    && cross.length_squared() > 0.0
                    && cross.normalize_or_zero() != Vec3::ZERO;
                if !ok {
                    geo.skipped += 1;
                    continue;
                }
                if geo.positions.len() + 3 > u32::MAX as usize {
                    return Err(perr(MeshError::SceneTooLarge));
                }
                let mut out = [0u32; 3];
                match &wnor {
                    None => {
                        // Flat normals (glTF spec 3.7.2.1): unshared vertices per triangle.
                        flat_faces.push(([a as u32, b as u32, c as u32], cross.normalize()));
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
                // Asked-for smooth normals are no repair to report.
                if !smoothing {
                    geo.repaired_normals += 1;
                }
            }
            if !flat_faces.is_empty() {
                let facets = analyse(&flat_faces);
                if facets.creased() {
                    geo.faceted.push((mesh_label(mesh), facets));
                }
            }
        }
        Ok(())
    }
}

fn mesh_label(mesh: &gltf::Mesh) -> String {
    match mesh.name() {
        Some(n) => n.to_owned(),
        None => format!("mesh{}", mesh.index()),
    }
}
