//! Scene input: the example scenes load with the expected content, malformed input (glTF,
//! GLB, buffers, images, configs) gives an error naming the problem instead of a panic, and
//! `bake INPUT` accepts a config, a scene folder or a bare glTF (`config::input`).
//!
//! Malformed files are written from small hand-made glTF documents into a fresh folder under
//! the system temp dir, removed again when the test ends.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use glam::{Vec2, Vec3};
use prt_bake::brdf::Family;
use prt_bake::config::input::{self, InputError, InputKind};
use prt_bake::config::{BakeConfig, ConfigError, EnvironmentConfig, MaterialConfig, Mode};
use prt_bake::scene::{load_with_warnings, Environment, PunctualLight, Scene, SceneError};
use serde_json::{json, Value};

mod configs;
mod gltf_input;
mod textures;

fn scenes_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes")
}

fn load_example(name: &str) -> (BakeConfig, Scene, Vec<String>) {
    let config = BakeConfig::from_file(scenes_dir().join(name).join("bake.toml"))
        .unwrap_or_else(|e| panic!("{e}"));
    let (scene, warnings) = load_with_warnings(&config).unwrap_or_else(|e| panic!("{e}"));
    (config, scene, warnings)
}

/// Checks the invariants every consumer relies on.
fn check_invariants(scene: &Scene) {
    let n = scene.positions.len();
    assert_eq!(scene.normals.len(), n);
    assert_eq!(scene.uvs.len(), n);
    assert_eq!(scene.triangle_material.len(), scene.triangles.len());
    assert!(scene.positions.iter().all(|p| p.is_finite()));
    assert!(scene.uvs.iter().all(|t| t.is_finite()));
    for nrm in &scene.normals {
        assert!(
            (nrm.length() - 1.0).abs() < 1e-4,
            "normal {nrm} is not unit"
        );
    }
    for (t, &m) in scene.triangles.iter().zip(&scene.triangle_material) {
        assert!((m as usize) < scene.materials.len());
        let [a, b, c] = t.map(|i| scene.positions[i as usize]);
        assert!((b - a).cross(c - a).length() > 0.0);
    }
}

/// Fraction of triangles whose geometric normal (p1 - p0) x (p2 - p0) agrees with the mean
/// shading normal of its vertices.
fn winding_agreement(scene: &Scene) -> f64 {
    let ok = scene
        .triangles
        .iter()
        .filter(|t| {
            let [a, b, c] = t.map(|i| scene.positions[i as usize]);
            let n: Vec3 = t.iter().map(|&i| scene.normals[i as usize]).sum();
            (b - a).cross(c - a).dot(n) > 0.0
        })
        .count();
    ok as f64 / scene.triangles.len() as f64
}

fn triangles_of(scene: &Scene, material: &str) -> Vec<[u32; 3]> {
    let m = scene.material_index(material).unwrap() as u32;
    scene
        .triangles
        .iter()
        .zip(&scene.triangle_material)
        .filter(|(_, &tm)| tm == m)
        .map(|(t, _)| *t)
        .collect()
}

#[test]
fn cornell_box_loads() {
    let (config, scene, warnings) = load_example("cornell");
    assert!(warnings.is_empty(), "{warnings:?}");
    check_invariants(&scene);
    assert_eq!((config.width, config.height), (256, 256));
    assert_eq!(config.reflections, 2);
    assert_eq!(config.mode, Mode::Pixel);

    let names: Vec<&str> = scene.materials.iter().map(|m| m.name.as_str()).collect();
    assert_eq!(
        names,
        ["white", "red", "green", "light", "bunny", "tall_box"]
    );
    // 3 white walls + 2 coloured ones at 16 x 16 quads, the lamp, the tall box (4 sides + top)
    // and the bunny (3674 triangles in the npm package).
    assert_eq!(triangles_of(&scene, "white").len(), 3 * 512);
    assert_eq!(triangles_of(&scene, "red").len(), 512);
    assert_eq!(triangles_of(&scene, "light").len(), 2);
    assert_eq!(triangles_of(&scene, "tall_box").len(), 10);
    assert_eq!(
        triangles_of(&scene, "bunny").len() + scene.skipped_triangles,
        3674
    );
    assert_eq!(scene.skipped_triangles, 0);
    assert!(
        winding_agreement(&scene) > 0.999,
        "{}",
        winding_agreement(&scene)
    );

    // Editable flags and BRDFs from the config.
    for m in &scene.materials {
        assert_eq!(
            m.editable,
            m.name == "bunny" || m.name == "tall_box",
            "{}",
            m.name
        );
    }
    let bunny = &scene.materials[scene.material_index("bunny").unwrap()];
    assert_eq!(bunny.brdf.family, Family::BlinnPhong);
    assert_eq!(bunny.brdf.param, 60.0);
    assert_eq!(bunny.brdf.ks, Vec3::splat(0.25));
    let tall = &scene.materials[scene.material_index("tall_box").unwrap()];
    assert_eq!(tall.brdf.family, Family::Ggx);
    assert_eq!(tall.brdf.param, 0.15);
    let red = &scene.materials[scene.material_index("red").unwrap()];
    assert_eq!(red.brdf.family, Family::Diffuse);
    assert!(red.brdf.kd.abs_diff_eq(Vec3::new(0.63, 0.065, 0.05), 1e-6));

    // The area light: emissive factor x strength, facing down.
    let light = &scene.materials[scene.material_index("light").unwrap()];
    assert!(light.emission.abs_diff_eq(Vec3::new(17.0, 12.0, 4.0), 1e-4));
    assert_eq!(
        scene.materials.iter().filter(|m| m.is_emissive()).count(),
        1
    );
    for t in triangles_of(&scene, "light") {
        let [a, b, c] = t.map(|i| scene.positions[i as usize]);
        assert!((b - a)
            .cross(c - a)
            .normalize()
            .abs_diff_eq(Vec3::NEG_Y, 1e-5));
    }
    assert!(scene.lights.is_empty());
    assert!(matches!(scene.environment, Environment::Constant(c) if c == Vec3::ZERO));

    // The bunny stands on the floor (node scale 0.02 applied), about 0.19 m tall.
    let (lo, hi) = bounds(&scene, "bunny");
    assert!(lo.y.abs() < 1e-3, "{lo}");
    assert!((hi.y - lo.y - 0.193).abs() < 0.005, "{lo} {hi}");
    assert!(lo.x > -0.2775 && hi.x < 0.2775 && lo.z > -0.5592 && hi.z < 0.0);

    // The tall box has no normals in the glTF: flat normals are generated, facing outward.
    let (blo, bhi) = bounds(&scene, "tall_box");
    let centre = (blo + bhi) * 0.5;
    for t in triangles_of(&scene, "tall_box") {
        let [a, b, c] = t.map(|i| scene.positions[i as usize]);
        let face = (b - a).cross(c - a).normalize();
        for &i in &t {
            assert!(scene.normals[i as usize].abs_diff_eq(face, 1e-5));
        }
        assert!(face.dot((a + b + c) / 3.0 - centre) > 0.0);
    }

    // The classic camera: 0.8 m in front of the opening, looking down -Z.
    let cam = scene.camera;
    assert!(cam.position.abs_diff_eq(Vec3::new(0.0, 0.2744, 0.8), 1e-5));
    assert!(cam.forward.abs_diff_eq(Vec3::NEG_Z, 1e-5));
    assert!(cam.up.abs_diff_eq(Vec3::Y, 1e-5));
    assert!(cam.right.abs_diff_eq(Vec3::X, 1e-5));
    assert!((cam.yfov.to_degrees() - 39.3).abs() < 1e-3);
}

fn bounds(scene: &Scene, material: &str) -> (Vec3, Vec3) {
    let mut lo = Vec3::splat(f32::INFINITY);
    let mut hi = Vec3::splat(f32::NEG_INFINITY);
    for t in triangles_of(scene, material) {
        for i in t {
            lo = lo.min(scene.positions[i as usize]);
            hi = hi.max(scene.positions[i as usize]);
        }
    }
    (lo, hi)
}

#[test]
fn ring_loads() {
    let (_, scene, warnings) = load_example("ring");
    assert!(warnings.is_empty(), "{warnings:?}");
    check_invariants(&scene);
    assert!(winding_agreement(&scene) > 0.999);
    assert_eq!(triangles_of(&scene, "floor").len(), 48 * 48 * 2);
    // Outer and inner walls (256 x 4 quads each) and two annular caps.
    assert_eq!(
        triangles_of(&scene, "ring").len(),
        2 * 256 * 4 * 2 + 2 * 256 * 2
    );
    let ring = &scene.materials[scene.material_index("ring").unwrap()];
    assert!(ring.editable);
    assert_eq!(ring.brdf.family, Family::BlinnPhong);
    assert_eq!(ring.brdf.param, 200.0);
    // Ks from the (fully metallic) glTF base colour; Kd from the config.
    assert!(ring.brdf.ks.abs_diff_eq(Vec3::new(0.95, 0.78, 0.4), 1e-6));
    assert_eq!(ring.brdf.kd, Vec3::splat(0.02));
    assert!(!scene.materials[scene.material_index("floor").unwrap()].editable);

    assert_eq!(scene.lights.len(), 1);
    match scene.lights[0] {
        PunctualLight::Point {
            position,
            intensity,
        } => {
            assert!(position.abs_diff_eq(Vec3::new(-0.8, 0.2, 0.05), 1e-6));
            assert!(intensity.abs_diff_eq(Vec3::new(6.0, 5.82, 5.4), 1e-5));
        }
        other => panic!("{other:?}"),
    }
    // Camera above, looking down at the ring at an angle.
    let cam = scene.camera;
    assert!(cam.position.y > 0.2);
    let to_origin = (Vec3::new(0.0, 0.0, -0.01) - cam.position).normalize();
    assert!(cam.forward.abs_diff_eq(to_origin, 1e-5));
    assert!(cam.up.y > 0.0 && cam.right.dot(cam.forward).abs() < 1e-5);
}

#[test]
fn furnace_loads_from_glb() {
    let (config, scene, warnings) = load_example("furnace");
    assert!(warnings.is_empty(), "{warnings:?}");
    check_invariants(&scene);
    assert_eq!(config.environment, EnvironmentConfig::Color(Vec3::ONE));
    assert!(matches!(scene.environment, Environment::Constant(c) if c == Vec3::ONE));
    assert_eq!(scene.triangles.len(), 20 * 4usize.pow(5));
    assert_eq!(scene.positions.len(), 10242);
    assert_eq!(scene.materials.len(), 1);
    let m = &scene.materials[0];
    assert!(m.editable);
    assert_eq!(m.brdf.family, Family::Diffuse);
    assert_eq!(m.brdf.kd, Vec3::splat(0.5));
    assert!(scene.lights.is_empty() && !m.is_emissive());
    // Smooth, exact sphere normals.
    for (p, n) in scene.positions.iter().zip(&scene.normals) {
        assert!((p.length() - 0.5).abs() < 1e-5);
        assert!(n.abs_diff_eq(p.normalize(), 1e-5));
    }
    assert!(winding_agreement(&scene) == 1.0);
}

// ---------------------------------------------------------------------------------------------
// Hand-made glTF files.

/// A fresh folder under the system temp dir, removed on drop.
struct TempDir(PathBuf);

impl TempDir {
    fn new(tag: &str) -> TempDir {
        static COUNTER: AtomicUsize = AtomicUsize::new(0);
        let dir = std::env::temp_dir().join(format!(
            "prt-bake-scene-test-{}-{}-{tag}",
            std::process::id(),
            COUNTER.fetch_add(1, Ordering::Relaxed)
        ));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        TempDir(dir)
    }

    fn write(&self, name: &str, bytes: impl AsRef<[u8]>) -> PathBuf {
        let p = self.0.join(name);
        std::fs::write(&p, bytes).unwrap();
        p
    }

    /// Writes `bake.toml` with `scene = "scene.gltf"` plus `extra`, and parses it.
    fn config(&self, extra: &str) -> BakeConfig {
        let p = self.write("bake.toml", format!("scene = \"scene.gltf\"\n{extra}"));
        BakeConfig::from_file(p).unwrap_or_else(|e| panic!("{e}"))
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn base64(bytes: &[u8]) -> String {
    const A: &[u8] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::new();
    for chunk in bytes.chunks(3) {
        let b = [
            chunk[0],
            *chunk.get(1).unwrap_or(&0),
            *chunk.get(2).unwrap_or(&0),
        ];
        let n = (b[0] as u32) << 16 | (b[1] as u32) << 8 | b[2] as u32;
        for k in 0..4 {
            if k <= chunk.len() {
                s.push(A[(n >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                s.push('=');
            }
        }
    }
    s
}

/// A glTF document under construction: one buffer, meshes, and a camera node.
struct Doc {
    json: Value,
    bin: Vec<u8>,
}

impl Doc {
    /// An empty scene with a perspective camera at +Z looking down -Z.
    fn new() -> Doc {
        Doc {
            json: json!({
                "asset": {"version": "2.0"},
                "scene": 0,
                "scenes": [{"nodes": [0]}],
                "nodes": [{"name": "cam", "camera": 0, "translation": [0.0, 0.0, 3.0]}],
                "cameras": [{"type": "perspective",
                             "perspective": {"yfov": 0.8, "znear": 0.01}}],
                "meshes": [],
                "accessors": [],
                "bufferViews": [],
                "buffers": [],
            }),
            bin: Vec::new(),
        }
    }

    fn push(&mut self, key: &str, v: Value) -> usize {
        let arr = self.json[key].as_array_mut().unwrap();
        arr.push(v);
        arr.len() - 1
    }

    fn view(&mut self, data: &[u8]) -> usize {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        let off = self.bin.len();
        self.bin.extend_from_slice(data);
        self.push(
            "bufferViews",
            json!({"buffer": 0, "byteOffset": off, "byteLength": data.len()}),
        )
    }

    fn floats(&mut self, v: &[f32], ty: &str) -> usize {
        let data: Vec<u8> = v.iter().flat_map(|x| x.to_le_bytes()).collect();
        let comps = match ty {
            "VEC2" => 2,
            _ => 3,
        };
        let view = self.view(&data);
        self.push(
            "accessors",
            json!({"bufferView": view, "componentType": 5126, "count": v.len() / comps,
                   "type": ty}),
        )
    }

    fn indices(&mut self, v: &[u32]) -> usize {
        let data: Vec<u8> = v.iter().flat_map(|x| x.to_le_bytes()).collect();
        let view = self.view(&data);
        self.push(
            "accessors",
            json!({"bufferView": view, "componentType": 5125, "count": v.len(),
                   "type": "SCALAR"}),
        )
    }

    /// Adds a mesh node with the given triangles (flattened xyz) and optional indices.
    fn mesh(
        &mut self,
        positions: &[f32],
        indices: Option<&[u32]>,
        material: Option<usize>,
    ) -> usize {
        let pos = self.floats(positions, "VEC3");
        let mut prim = json!({"attributes": {"POSITION": pos}});
        if let Some(idx) = indices {
            prim["indices"] = json!(self.indices(idx));
        }
        if let Some(m) = material {
            prim["material"] = json!(m);
        }
        let mesh = self.push("meshes", json!({"name": "thing", "primitives": [prim]}));
        let node = self.push("nodes", json!({"mesh": mesh}));
        self.json["scenes"][0]["nodes"]
            .as_array_mut()
            .unwrap()
            .push(json!(node));
        node
    }

    fn material(&mut self, m: Value) -> usize {
        if self.json.get("materials").is_none() {
            self.json["materials"] = json!([]);
        }
        self.push("materials", m)
    }

    /// Writes `scene.gltf` with the buffer embedded as a data URI.
    fn write_embedded(mut self, dir: &TempDir) -> PathBuf {
        self.json["buffers"] = json!([{
            "byteLength": self.bin.len(),
            "uri": format!("data:application/octet-stream;base64,{}", base64(&self.bin)),
        }]);
        dir.write(
            "scene.gltf",
            serde_json::to_string_pretty(&self.json).unwrap(),
        )
    }

    /// Writes `scene.gltf` + `scene.bin`.
    fn write_external(mut self, dir: &TempDir) -> PathBuf {
        self.json["buffers"] = json!([{"byteLength": self.bin.len(), "uri": "scene.bin"}]);
        dir.write("scene.bin", &self.bin);
        dir.write(
            "scene.gltf",
            serde_json::to_string_pretty(&self.json).unwrap(),
        )
    }

    /// The document as a GLB.
    fn glb(mut self) -> Vec<u8> {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        self.json["buffers"] = json!([{"byteLength": self.bin.len()}]);
        let mut js = serde_json::to_vec(&self.json).unwrap();
        while !js.len().is_multiple_of(4) {
            js.push(b' ');
        }
        let total = 12 + 8 + js.len() + 8 + self.bin.len();
        let mut out = Vec::new();
        out.extend_from_slice(b"glTF");
        out.extend_from_slice(&2u32.to_le_bytes());
        out.extend_from_slice(&(total as u32).to_le_bytes());
        out.extend_from_slice(&(js.len() as u32).to_le_bytes());
        out.extend_from_slice(b"JSON");
        out.extend_from_slice(&js);
        out.extend_from_slice(&(self.bin.len() as u32).to_le_bytes());
        out.extend_from_slice(b"BIN\0");
        out.extend_from_slice(&self.bin);
        out
    }
}

const TRI: [f32; 9] = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0];

fn load_err(config: &BakeConfig) -> String {
    match load_with_warnings(config) {
        Ok(_) => panic!("expected an error loading {}", config.scene_path.display()),
        Err(e) => e.to_string(),
    }
}
