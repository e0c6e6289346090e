//! A minimal glTF 2.0 writer for generated test and benchmark scenes: indexed triangle
//! meshes (positions, optional normals and UVs), metallic-roughness materials and one
//! perspective camera, written as `.gltf` + `.bin`. Scenes written here go through the same
//! loader as a user's files, so a generated scene exercises what a user's does (the flat
//! normals of a mesh without a NORMAL attribute included).
//!
//! Written by hand rather than with a glTF crate: the `gltf` crate reads only, and the JSON
//! needed for these scenes is a few dozen lines.

use std::io;
use std::path::{Path, PathBuf};

use serde_json::{json, Value};

/// A glTF metallic-roughness material.
#[derive(Clone, Debug)]
pub struct GltfMaterial {
    pub name: String,
    /// Linear base colour.
    pub base_color: [f32; 3],
    pub metallic: f32,
    pub roughness: f32,
}

/// One indexed triangle mesh with its material.
#[derive(Clone, Debug, Default)]
pub struct GltfMesh {
    pub name: String,
    pub positions: Vec<[f32; 3]>,
    /// Per vertex, or empty to leave the NORMAL attribute out (the loader then gives the mesh
    /// flat normals, per the glTF specification).
    pub normals: Vec<[f32; 3]>,
    /// Per vertex, or empty.
    pub uvs: Vec<[f32; 2]>,
    /// Counter-clockwise seen from the front.
    pub triangles: Vec<[u32; 3]>,
    /// Index into the writer's materials.
    pub material: usize,
}

/// A glTF document under construction.
#[derive(Default)]
pub struct GltfWriter {
    materials: Vec<GltfMaterial>,
    meshes: Vec<GltfMesh>,
    camera: Option<([f32; 3], [f32; 3], f32)>,
}

impl GltfWriter {
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds a material; returns its index.
    pub fn material(&mut self, m: GltfMaterial) -> usize {
        self.materials.push(m);
        self.materials.len() - 1
    }

    pub fn mesh(&mut self, m: GltfMesh) {
        self.meshes.push(m);
    }

    /// A perspective camera at `eye` looking at `target` (+Y up), vertical field of view in
    /// degrees.
    pub fn camera(&mut self, eye: [f32; 3], target: [f32; 3], yfov_degrees: f32) {
        self.camera = Some((eye, target, yfov_degrees));
    }

    /// Vertices over every mesh.
    pub fn vertices(&self) -> usize {
        self.meshes.iter().map(|m| m.positions.len()).sum()
    }

    /// Writes `<dir>/<stem>.gltf` and `<dir>/<stem>.bin`; returns the `.gltf` path.
    pub fn write(&self, dir: &Path, stem: &str) -> io::Result<PathBuf> {
        std::fs::create_dir_all(dir)?;
        let mut bin: Vec<u8> = Vec::new();
        let mut views: Vec<Value> = Vec::new();
        let mut accessors: Vec<Value> = Vec::new();
        let mut push = |bytes: Vec<u8>, accessor: Value, target: u32| -> usize {
            while !bin.len().is_multiple_of(4) {
                bin.push(0);
            }
            views.push(json!({"buffer": 0, "byteOffset": bin.len(),
                              "byteLength": bytes.len(), "target": target}));
            bin.extend_from_slice(&bytes);
            let mut a = accessor;
            a["bufferView"] = json!(views.len() - 1);
            accessors.push(a);
            accessors.len() - 1
        };
        let mut meshes = Vec::new();
        let mut nodes = Vec::new();
        for m in &self.meshes {
            let (lo, hi) = bounds(&m.positions);
            let pos = push(
                floats(m.positions.iter().flatten()),
                json!({"componentType": 5126, "count": m.positions.len(), "type": "VEC3",
                       "min": lo, "max": hi}),
                34962,
            );
            let mut attributes = json!({"POSITION": pos});
            if !m.normals.is_empty() {
                attributes["NORMAL"] = json!(push(
                    floats(m.normals.iter().flatten()),
                    json!({"componentType": 5126, "count": m.normals.len(), "type": "VEC3"}),
                    34962,
                ));
            }
            if !m.uvs.is_empty() {
                attributes["TEXCOORD_0"] = json!(push(
                    floats(m.uvs.iter().flatten()),
                    json!({"componentType": 5126, "count": m.uvs.len(), "type": "VEC2"}),
                    34962,
                ));
            }
            let indices = push(
                m.triangles
                    .iter()
                    .flatten()
                    .flat_map(|i| i.to_le_bytes())
                    .collect(),
                json!({"componentType": 5125, "count": 3 * m.triangles.len(),
                       "type": "SCALAR"}),
                34963,
            );
            meshes.push(json!({"name": m.name, "primitives": [{
                "attributes": attributes, "indices": indices, "material": m.material}]}));
            nodes.push(json!({"name": m.name, "mesh": meshes.len() - 1}));
        }
        let mut cameras = Vec::new();
        if let Some((eye, target, yfov)) = self.camera {
            cameras.push(json!({"type": "perspective",
                "perspective": {"yfov": yfov.to_radians(), "znear": 0.01}}));
            nodes.push(json!({"name": "camera", "camera": 0, "translation": eye,
                              "rotation": look_at_quaternion(eye, target)}));
        }
        let materials: Vec<Value> = self
            .materials
            .iter()
            .map(|m| {
                json!({"name": m.name, "pbrMetallicRoughness": {
                    "baseColorFactor": [m.base_color[0], m.base_color[1], m.base_color[2], 1.0],
                    "metallicFactor": m.metallic, "roughnessFactor": m.roughness}})
            })
            .collect();
        let bin_name = format!("{stem}.bin");
        let mut doc = json!({
            "asset": {"version": "2.0", "generator": "prt-bake testing"},
            "scene": 0,
            "scenes": [{"nodes": (0..nodes.len()).collect::<Vec<_>>()}],
            "nodes": nodes,
            "meshes": meshes,
            "materials": materials,
            "accessors": accessors,
            "bufferViews": views,
            "buffers": [{"byteLength": bin.len(), "uri": bin_name}],
        });
        if !cameras.is_empty() {
            doc["cameras"] = json!(cameras);
        }
        std::fs::write(dir.join(&bin_name), &bin)?;
        let path = dir.join(format!("{stem}.gltf"));
        std::fs::write(&path, serde_json::to_string_pretty(&doc)?)?;
        Ok(path)
    }
}

fn floats<'a>(v: impl Iterator<Item = &'a f32>) -> Vec<u8> {
    v.flat_map(|x| x.to_le_bytes()).collect()
}

fn bounds(p: &[[f32; 3]]) -> ([f32; 3], [f32; 3]) {
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for v in p {
        for i in 0..3 {
            lo[i] = lo[i].min(v[i]);
            hi[i] = hi[i].max(v[i]);
        }
    }
    if p.is_empty() {
        return ([0.0; 3], [0.0; 3]);
    }
    (lo, hi)
}

/// The rotation (x, y, z, w) that turns a glTF camera (looking down -Z, +Y up) to look from
/// `eye` at `target`.
fn look_at_quaternion(eye: [f32; 3], target: [f32; 3]) -> [f32; 4] {
    let f = glam::Vec3::from(target) - glam::Vec3::from(eye);
    let f = f.normalize_or(glam::Vec3::NEG_Z);
    let r = f.cross(glam::Vec3::Y).normalize_or(glam::Vec3::X);
    let u = r.cross(f);
    let m = glam::Mat3::from_cols(r, u, -f);
    glam::Quat::from_mat3(&m).to_array()
}
