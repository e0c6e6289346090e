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

#[test]
fn minimal_scene_embedded_external_and_glb() {
    for variant in 0..3 {
        let dir = TempDir::new("minimal");
        let mut doc = Doc::new();
        doc.mesh(&TRI, Some(&[0, 1, 2]), None);
        let config = match variant {
            0 => {
                doc.write_embedded(&dir);
                dir.config("")
            }
            1 => {
                doc.write_external(&dir);
                dir.config("")
            }
            _ => {
                dir.write("scene.glb", doc.glb());
                let p = dir.write("bake.toml", "scene = \"scene.glb\"");
                BakeConfig::from_file(p).unwrap()
            }
        };
        let (scene, warnings) = load_with_warnings(&config).unwrap_or_else(|e| panic!("{e}"));
        assert!(warnings.is_empty(), "{warnings:?}");
        check_invariants(&scene);
        assert_eq!(scene.triangles.len(), 1);
        // No material: the white diffuse `default`.
        assert_eq!(scene.materials.len(), 1);
        assert_eq!(scene.materials[0].name, "default");
        assert_eq!(scene.materials[0].brdf.kd, Vec3::ONE);
        // No normals: flat, counter-clockwise front (+Z); no UVs: zero.
        assert!(scene.normals.iter().all(|n| *n == Vec3::Z));
        assert!(scene.uvs.iter().all(|t| *t == Vec2::ZERO));
        assert!(scene
            .camera
            .position
            .abs_diff_eq(Vec3::new(0.0, 0.0, 3.0), 1e-6));
        assert!(scene.camera.forward.abs_diff_eq(Vec3::NEG_Z, 1e-6));
    }
}

#[test]
fn truncated_glb_is_an_error() {
    let glb = std::fs::read(scenes_dir().join("furnace/furnace.glb")).unwrap();
    let dir = TempDir::new("trunc-glb");
    let p = dir.write("bake.toml", "scene = \"scene.glb\"");
    let config = BakeConfig::from_file(p).unwrap();
    let mut lengths: Vec<usize> = vec![
        0,
        3,
        4,
        11,
        12,
        19,
        20,
        27,
        100,
        glb.len() / 2,
        glb.len() - 1,
    ];
    lengths.extend((0..40).map(|k| k * glb.len() / 40));
    for len in lengths {
        dir.write("scene.glb", &glb[..len]);
        let e = load_err(&config);
        assert!(e.contains("scene.glb"), "{e}");
    }
    // A plausible-looking header whose length field is too small must not underflow.
    let mut bad = glb.clone();
    bad[8..12].copy_from_slice(&5u32.to_le_bytes());
    dir.write("scene.glb", &bad);
    assert!(load_err(&config).contains("GLB"));
}

#[test]
fn truncated_gltf_json_is_an_error() {
    let text = std::fs::read_to_string(scenes_dir().join("cornell/cornell.gltf")).unwrap();
    let bin = std::fs::read(scenes_dir().join("cornell/cornell.bin")).unwrap();
    let dir = TempDir::new("trunc-json");
    dir.write("cornell.bin", &bin);
    let p = dir.write("bake.toml", "scene = \"cornell.gltf\"");
    let config = BakeConfig::from_file(p).unwrap();
    for k in 0..30 {
        let cut = k * text.len() / 30;
        dir.write("cornell.gltf", &text[..cut]);
        let e = load_err(&config);
        assert!(e.contains("cornell.gltf"), "{e}");
    }
    dir.write("cornell.gltf", &text[..text.len() / 2]);
    assert!(load_err(&config).contains("malformed glTF JSON"));
}

/// Truncated buffers and flipped bytes anywhere in a GLB: always Ok or Err, never a panic.
#[test]
fn corrupted_bytes_never_panic() {
    let mut doc = Doc::new();
    doc.mesh(&TRI, Some(&[0, 1, 2]), None);
    let glb = doc.glb();
    let dir = TempDir::new("corrupt");
    let p = dir.write("bake.toml", "scene = \"scene.glb\"");
    let config = BakeConfig::from_file(p).unwrap();
    let mut state = 0x9E3779B97F4A7C15u64;
    for _ in 0..300 {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let pos = (state >> 33) as usize % glb.len();
        let mut bytes = glb.clone();
        bytes[pos] ^= 1 << ((state >> 20) % 8);
        dir.write("scene.glb", &bytes);
        let _ = load_with_warnings(&config);
    }
}

#[test]
fn missing_bin_is_an_error_naming_the_file() {
    let dir = TempDir::new("missing-bin");
    let mut doc = Doc::new();
    doc.mesh(&TRI, None, None);
    doc.write_external(&dir);
    std::fs::remove_file(dir.0.join("scene.bin")).unwrap();
    let e = load_err(&dir.config(""));
    assert!(e.contains("scene.bin") && e.contains("buffer 0"), "{e}");
}

#[test]
fn short_bin_is_an_error() {
    let dir = TempDir::new("short-bin");
    let mut doc = Doc::new();
    doc.mesh(&TRI, None, None);
    doc.write_external(&dir);
    dir.write("scene.bin", [0u8; 20]);
    let e = load_err(&dir.config(""));
    assert!(e.contains("byteLength"), "{e}");
}

#[test]
fn accessor_past_the_end_of_its_view_is_an_error() {
    let dir = TempDir::new("accessor-range");
    let mut doc = Doc::new();
    doc.mesh(&TRI, None, None);
    doc.json["accessors"][0]["count"] = json!(1000);
    doc.write_embedded(&dir);
    let e = load_err(&dir.config(""));
    assert!(
        e.contains("mesh \"thing\"") && e.contains("POSITION"),
        "{e}"
    );
    // A zero-element accessor is merely empty.
    let dir = TempDir::new("accessor-zero");
    let mut doc = Doc::new();
    doc.mesh(&TRI, None, None);
    doc.json["accessors"][0]["count"] = json!(0);
    doc.write_embedded(&dir);
    let (scene, _) = load_with_warnings(&dir.config("")).unwrap();
    assert!(scene.triangles.is_empty());
}

#[test]
fn wrong_accessor_type_is_an_error() {
    let dir = TempDir::new("accessor-type");
    let mut doc = Doc::new();
    doc.mesh(&TRI, None, None);
    doc.json["accessors"][0]["type"] = json!("VEC2");
    doc.json["accessors"][0]["count"] = json!(4);
    doc.write_embedded(&dir);
    let e = load_err(&dir.config(""));
    assert!(e.contains("VEC2"), "{e}");
}

#[test]
fn out_of_range_indices_are_an_error_naming_the_mesh() {
    let dir = TempDir::new("bad-indices");
    let mut doc = Doc::new();
    doc.mesh(&TRI, Some(&[0, 1, 7]), None);
    doc.write_embedded(&dir);
    let e = load_err(&dir.config(""));
    assert!(
        e.contains("mesh \"thing\"") && e.contains("index 7") && e.contains("out of range"),
        "{e}"
    );
    let dir = TempDir::new("bad-index-count");
    let mut doc = Doc::new();
    doc.mesh(&TRI, Some(&[0, 1]), None);
    doc.write_embedded(&dir);
    assert!(load_err(&dir.config("")).contains("multiple of 3"));
}

#[test]
fn nan_and_degenerate_triangles_are_skipped_and_counted() {
    let dir = TempDir::new("nan");
    let mut doc = Doc::new();
    let nan = f32::NAN;
    #[rustfmt::skip]
    let pos = [
        0.0, 0.0, 0.0,  1.0, 0.0, 0.0,  0.0, 1.0, 0.0,   // good
        nan, 0.0, 0.0,  1.0, 0.0, 0.0,  0.0, 1.0, 0.0,   // NaN vertex
        0.0, 0.0, 0.0,  1.0, 0.0, 0.0,  2.0, 0.0, 0.0,   // collinear: zero area
    ];
    doc.mesh(&pos, Some(&[0, 1, 2, 3, 4, 5, 6, 7, 8, 0, 0, 1]), None);
    doc.write_embedded(&dir);
    let (scene, warnings) = load_with_warnings(&dir.config("")).unwrap();
    check_invariants(&scene);
    assert_eq!(scene.triangles.len(), 1);
    assert_eq!(scene.skipped_triangles, 3);
    // The NaN vertex is not kept.
    assert_eq!(scene.positions.len(), 3);
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    assert!(warnings[0].contains("skipped 3"), "{warnings:?}");
}

/// Found by fuzzing (`prt-fuzz gltf`): one finite vertex near f32::MAX among a thousand
/// triangles made the BVH builder (obvhs) panic. The loader drops such triangles like
/// non-finite ones, so every scene it returns can be traced.
#[test]
fn triangles_beyond_the_coordinate_limit_are_skipped() {
    let dir = TempDir::new("huge");
    let mut doc = Doc::new();
    let mut pos = Vec::new();
    for i in 0..1000 {
        let (x, y) = ((i % 32) as f32 * 0.1, (i / 32) as f32 * 0.1);
        pos.extend([x, y, 0.0, x + 0.1, y, 0.0, x, y + 0.1, 0.0]);
    }
    pos[4] = 2e38;
    pos[12] = 1.1e15;
    doc.mesh(&pos, None, None);
    doc.write_embedded(&dir);
    let (scene, warnings) = load_with_warnings(&dir.config("")).unwrap();
    check_invariants(&scene);
    assert_eq!(scene.skipped_triangles, 2);
    assert_eq!(scene.triangles.len(), 998);
    assert!(warnings[0].contains("skipped 2"), "{warnings:?}");
    let accel = prt_bake::accel::Accel::build(&scene);
    assert_eq!(accel.triangle_count(), 998);
}

/// Found by fuzzing (`prt-fuzz gltf`): a buffer URI naming a device was read until memory ran
/// out. URIs must name regular files.
#[test]
fn uris_naming_devices_or_folders_are_errors() {
    for uri in ["file:///dev/zero", "."] {
        let dir = TempDir::new("device");
        let mut doc = Doc::new();
        doc.mesh(&TRI, None, None);
        doc.json["buffers"] = json!([{"byteLength": 36, "uri": uri}]);
        dir.write("scene.gltf", doc.json.to_string());
        let e = load_err(&dir.config(""));
        assert!(e.contains("is not a regular file"), "{uri}: {e}");
    }
}

/// Found by fuzzing (`prt-fuzz gltf`): the glTF crate's validation does not check that a
/// camera has the projection its `type` names, or that an image has a source (and a MIME
/// type with a buffer view), and its accessors then panic. The loader refuses such files.
#[test]
fn cameras_and_images_must_have_what_their_accessors_unwrap() {
    let cases = [
        (
            "camera",
            json!({"cameras": [{"type": "orthographic", "perspective": {"yfov": 0.8, "znear": 0.1}}]}),
            "cameras[0].orthographic",
        ),
        (
            "image-view",
            json!({"images": [{"bufferView": 0}], "textures": [{"source": 0}]}),
            "images[0].mimeType",
        ),
        (
            "image-none",
            json!({"images": [{"name": "nothing"}], "textures": [{"source": 0}]}),
            "images[0].uri",
        ),
    ];
    for (tag, patch, expected) in cases {
        let dir = TempDir::new(tag);
        let mut doc = Doc::new();
        let m = doc.material(json!({"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}));
        doc.mesh(&TRI, None, Some(m));
        for (k, v) in patch.as_object().unwrap() {
            doc.json[k] = v.clone();
        }
        doc.write_embedded(&dir);
        let e = load_err(&dir.config(""));
        assert!(e.contains(expected), "{tag}: {e}");
    }
}

#[test]
fn supplied_normals_are_transformed_and_bad_ones_repaired() {
    let dir = TempDir::new("normals");
    let mut doc = Doc::new();
    doc.mesh(&TRI, None, None);
    // Normals: +Z, zero, NaN; the node scales x by 2 and mirrors z (determinant < 0).
    let nor = doc.floats(&[0.0, 0.0, 1.0, 0.0, 0.0, 0.0, f32::NAN, 0.0, 0.0], "VEC3");
    doc.json["meshes"][0]["primitives"][0]["attributes"]["NORMAL"] = json!(nor);
    doc.json["nodes"][1]["scale"] = json!([2.0, 1.0, -1.0]);
    doc.write_embedded(&dir);
    let (scene, warnings) = load_with_warnings(&dir.config("")).unwrap();
    check_invariants(&scene);
    assert!(
        warnings.iter().any(|w| w.contains("2 zero or non-finite")),
        "{warnings:?}"
    );
    // The mirrored triangle faces -Z; all its normals (transformed or repaired) agree, and
    // the winding was flipped so the geometric normal does too.
    assert!(scene
        .normals
        .iter()
        .all(|n| n.abs_diff_eq(Vec3::NEG_Z, 1e-6)));
    assert_eq!(winding_agreement(&scene), 1.0);
}

#[test]
fn node_hierarchy_transforms_compose() {
    let dir = TempDir::new("hierarchy");
    let mut doc = Doc::new();
    let child = doc.mesh(&TRI, None, None);
    // Move the mesh node under a parent: parent translates by +10 x, child by +1 y.
    doc.json["scenes"][0]["nodes"] = json!([0, child + 1]);
    doc.json["nodes"][child]["translation"] = json!([0.0, 1.0, 0.0]);
    doc.push(
        "nodes",
        json!({"name": "parent", "children": [child], "translation": [10.0, 0.0, 0.0]}),
    );
    doc.write_embedded(&dir);
    let (scene, _) = load_with_warnings(&dir.config("")).unwrap();
    let min = scene
        .positions
        .iter()
        .fold(Vec3::INFINITY, |a, &b| a.min(b));
    assert_eq!(min, Vec3::new(10.0, 1.0, 0.0));
}

#[test]
fn cyclic_nodes_are_an_error() {
    let dir = TempDir::new("cycle");
    let mut doc = Doc::new();
    doc.mesh(&TRI, None, None);
    doc.json["nodes"][1]["children"] = json!([2]);
    doc.push("nodes", json!({"children": [1]}));
    doc.write_embedded(&dir);
    // Either the glTF validator or the loader must refuse it.
    let e = load_err(&dir.config(""));
    assert!(e.contains("scene.gltf"), "{e}");
}

#[test]
fn cameras_perspective_required() {
    let dir = TempDir::new("ortho");
    let mut doc = Doc::new();
    doc.mesh(&TRI, None, None);
    doc.json["cameras"] = json!([{"type": "orthographic",
        "orthographic": {"xmag": 1.0, "ymag": 1.0, "znear": 0.01, "zfar": 10.0}}]);
    doc.write_embedded(&dir);
    let e = load_err(&dir.config(""));
    assert!(e.contains("orthographic"), "{e}");

    let dir = TempDir::new("nocam");
    let mut doc = Doc::new();
    doc.mesh(&TRI, None, None);
    doc.json["nodes"][0] = json!({"name": "empty"});
    doc.json.as_object_mut().unwrap().remove("cameras");
    doc.write_embedded(&dir);
    let e = load_err(&dir.config(""));
    assert!(e.contains("no camera"), "{e}");

    // A rotated camera: 90 degrees about +Y turns -Z into -X.
    let dir = TempDir::new("camrot");
    let mut doc = Doc::new();
    doc.mesh(&TRI, None, None);
    let h = std::f32::consts::FRAC_PI_4;
    doc.json["nodes"][0]["rotation"] = json!([0.0, h.sin(), 0.0, h.cos()]);
    doc.write_embedded(&dir);
    let (scene, _) = load_with_warnings(&dir.config("")).unwrap();
    assert!(scene.camera.forward.abs_diff_eq(Vec3::NEG_X, 1e-6));
    assert!(scene.camera.right.abs_diff_eq(Vec3::NEG_Z, 1e-6));
    assert!(scene.camera.up.abs_diff_eq(Vec3::Y, 1e-6));
}

#[test]
fn punctual_lights_and_emission() {
    let dir = TempDir::new("lights");
    let mut doc = Doc::new();
    let m = doc.material(json!({
        "name": "glow",
        "emissiveFactor": [1.0, 0.5, 0.25],
        "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 4.0}}
    }));
    doc.mesh(&TRI, None, Some(m));
    doc.json["extensionsUsed"] = json!(["KHR_lights_punctual", "KHR_materials_emissive_strength"]);
    doc.json["extensions"] = json!({"KHR_lights_punctual": {"lights": [
        {"type": "point", "color": [1.0, 0.5, 0.5], "intensity": 10.0},
        {"type": "spot", "intensity": 2.0,
         "spot": {"innerConeAngle": 0.2, "outerConeAngle": 0.5}},
        {"type": "directional", "color": [0.5, 0.5, 1.0], "intensity": 3.0}
    ]}});
    let h = std::f32::consts::FRAC_PI_4;
    for (k, rot) in [
        [0.0, 0.0, 0.0, 1.0],
        [h.sin(), 0.0, 0.0, h.cos()],
        [0.0, 0.0, 0.0, 1.0],
    ]
    .iter()
    .enumerate()
    {
        let n = doc.push(
            "nodes",
            json!({"translation": [1.0, 2.0, 3.0], "rotation": rot,
                   "extensions": {"KHR_lights_punctual": {"light": k}}}),
        );
        doc.json["scenes"][0]["nodes"]
            .as_array_mut()
            .unwrap()
            .push(json!(n));
    }
    doc.write_embedded(&dir);
    let (scene, _) = load_with_warnings(&dir.config("")).unwrap();
    assert!(scene.materials[0]
        .emission
        .abs_diff_eq(Vec3::new(4.0, 2.0, 1.0), 1e-6));
    assert_eq!(scene.lights.len(), 3);
    assert_eq!(
        scene.lights[0],
        PunctualLight::Point {
            position: Vec3::new(1.0, 2.0, 3.0),
            intensity: Vec3::new(10.0, 5.0, 5.0)
        }
    );
    match scene.lights[1] {
        PunctualLight::Spot {
            position,
            direction,
            intensity,
            inner_cone,
            outer_cone,
        } => {
            assert_eq!(position, Vec3::new(1.0, 2.0, 3.0));
            // 90 degrees about +X turns -Z into +Y.
            assert!(direction.abs_diff_eq(Vec3::Y, 1e-6), "{direction}");
            assert_eq!(intensity, Vec3::splat(2.0));
            assert_eq!((inner_cone, outer_cone), (0.2, 0.5));
        }
        ref other => panic!("{other:?}"),
    }
    assert_eq!(
        scene.lights[2],
        PunctualLight::Directional {
            direction: Vec3::NEG_Z,
            irradiance: Vec3::new(1.5, 1.5, 3.0)
        }
    );
}

#[test]
fn config_material_names_must_exist() {
    let dir = TempDir::new("unknown-material");
    let mut doc = Doc::new();
    let m = doc.material(json!({"name": "paint"}));
    doc.mesh(&TRI, None, Some(m));
    doc.material(json!({}));
    doc.write_embedded(&dir);
    let e = load_err(&dir.config("[materials.pain]\neditable = true\n"));
    assert!(
        e.contains("pain") && e.contains("\"paint\"") && e.contains("\"material1\""),
        "{e}"
    );
    assert!(e.contains("bake.toml"), "{e}");
    // And a correct one applies.
    let (scene, _) =
        load_with_warnings(&dir.config("[materials.paint]\neditable = true\nkd = 0.25\n")).unwrap();
    assert!(scene.materials[0].editable);
    assert_eq!(scene.materials[0].brdf.kd, Vec3::splat(0.25));
    assert_eq!(scene.materials[1].name, "material1");
}

#[test]
fn editable_specular_family_without_parameters_is_an_error() {
    let dir = TempDir::new("family-params");
    let mut doc = Doc::new();
    let m = doc.material(json!({"name": "matte"}));
    doc.mesh(&TRI, None, Some(m));
    doc.write_embedded(&dir);
    // The default glTF material (metallic 1, roughness 1) is specular: it supplies Ks/alpha.
    // Make it a fully rough dielectric, which maps to diffuse and supplies nothing.
    let dir2 = TempDir::new("family-params2");
    let mut doc = Doc::new();
    let m = doc.material(json!({"name": "matte",
        "pbrMetallicRoughness": {"metallicFactor": 0.0}}));
    doc.mesh(&TRI, None, Some(m));
    doc.write_embedded(&dir2);
    let e =
        load_err(&dir2.config("[materials.matte]\neditable = true\nfamily = \"blinn-phong\"\n"));
    assert!(
        e.contains("matte") && e.contains("`ks`") && e.contains("`shininess`"),
        "{e}"
    );
    let (scene, _) = load_with_warnings(&dir2.config(
        "[materials.matte]\neditable = true\nfamily = \"blinn-phong\"\nks = 0.1\nshininess = 20\n",
    ))
    .unwrap();
    assert_eq!(scene.materials[0].brdf.family, Family::BlinnPhong);
    let e = load_err(&dir2.config("[materials.matte]\nalpha = 0.5\n"));
    assert!(e.contains("`alpha`") && e.contains("diffuse"), "{e}");
    drop(dir);
}

#[test]
fn environment_maps_exr_and_hdr() {
    let dir = TempDir::new("envmap");
    let mut doc = Doc::new();
    doc.mesh(&TRI, None, None);
    doc.write_embedded(&dir);
    // 4x2 maps whose texel (x, y) holds (x, y, 1).
    let (w, h) = (4usize, 2usize);
    exr::prelude::write_rgb_file(dir.0.join("sky.exr"), w, h, |x, y| {
        (x as f32, y as f32, 1.0f32)
    })
    .unwrap();
    let pixels: Vec<image::Rgb<f32>> = (0..h)
        .flat_map(|y| (0..w).map(move |x| image::Rgb([x as f32, y as f32, 1.0])))
        .collect();
    let mut hdr = Vec::new();
    image::codecs::hdr::HdrEncoder::new(&mut hdr)
        .encode(&pixels, w, h)
        .unwrap();
    dir.write("sky.hdr", &hdr);
    for file in ["sky.exr", "sky.hdr"] {
        let config = dir.config(&format!(
            "[environment]\nmap = \"{file}\"\nintensity = 2.0\n"
        ));
        let (scene, _) = load_with_warnings(&config).unwrap_or_else(|e| panic!("{e}"));
        match &scene.environment {
            Environment::LatLong {
                width,
                height,
                texels,
            } => {
                assert_eq!((*width, *height), (4, 2));
                // Row 0 first (the top, +Y), intensity applied.
                assert!(
                    texels[1].abs_diff_eq(Vec3::new(2.0, 0.0, 2.0), 0.05),
                    "{file} {texels:?}"
                );
                assert!(
                    texels[4 + 3].abs_diff_eq(Vec3::new(6.0, 2.0, 2.0), 0.05),
                    "{file}"
                );
            }
            other => panic!("{other:?}"),
        }
    }
    let e = load_err(&dir.config("[environment]\nmap = \"nothere.exr\"\n"));
    assert!(e.contains("nothere.exr"), "{e}");
    dir.write("broken.hdr", b"#?RADIANCE\ngarbage");
    let e = load_err(&dir.config("[environment]\nmap = \"broken.hdr\"\n"));
    assert!(e.contains("broken.hdr"), "{e}");
    // A NaN or infinite texel is refused, naming the file and the texel; negative channels
    // (lossy compression's ringing) are clamped to 0 with a warning.
    exr::prelude::write_rgb_file(dir.0.join("nan.exr"), w, h, |x, y| {
        let r = if (x, y) == (2, 1) { f32::NAN } else { 1.0 };
        (r, 1.0f32, 1.0f32)
    })
    .unwrap();
    let e = load_err(&dir.config("[environment]\nmap = \"nan.exr\"\n"));
    assert!(
        e.contains("nan.exr") && e.contains("NaN or infinite") && e.contains("column 2, row 1"),
        "{e}"
    );
    exr::prelude::write_rgb_file(dir.0.join("negative.exr"), w, h, |x, y| {
        let g = if (x, y) == (1, 0) { -0.25 } else { 0.5 };
        (1.0f32, g, 1.0f32)
    })
    .unwrap();
    let (scene, warnings) =
        load_with_warnings(&dir.config("[environment]\nmap = \"negative.exr\"\n"))
            .unwrap_or_else(|e| panic!("{e}"));
    let Environment::LatLong { texels, .. } = &scene.environment else {
        panic!("{:?}", scene.environment)
    };
    assert_eq!(texels[1], Vec3::new(1.0, 0.0, 1.0));
    assert_eq!(texels[0], Vec3::new(1.0, 0.5, 1.0));
    assert!(
        warnings
            .iter()
            .any(|w| w.contains("negative.exr") && w.contains("1 texel(s)")),
        "{warnings:?}"
    );
}

// ---------------------------------------------------------------------------------------------
// Configs.

fn config_err(text: &str) -> String {
    match BakeConfig::parse(text, "/somewhere/bake.toml") {
        Ok(_) => panic!("expected an error for:\n{text}"),
        Err(e) => {
            let s = e.to_string();
            assert!(s.contains("/somewhere/bake.toml"), "{s}");
            s
        }
    }
}

#[test]
fn config_unknown_keys_are_errors() {
    let e = config_err("scene = \"a.gltf\"\nsamples = 3\n");
    assert!(e.contains("unknown field `samples`"), "{e}");
    let e = config_err("scene = \"a.gltf\"\n[materials.m]\neditible = true\n");
    assert!(e.contains("editible"), "{e}");
    let e = config_err("scene = \"a.gltf\"\n[environment]\ncolour = 1\n");
    assert!(e.contains("colour"), "{e}");
    let e = config_err("scene = \"a.gltf\"\n[basis]\ncont = 3\n");
    assert!(e.contains("cont"), "{e}");
    let e = config_err("scene = \"a.gltf\"\n[bake]\nx = 3\n");
    assert!(e.contains("bake"), "{e}");
    let e = config_err("width = 3\n");
    assert!(e.contains("scene"), "{e}");
    let e = config_err("scene = \"a.gltf\"\nwidth = \n");
    assert!(e.contains("line 2"), "{e}");
}

#[test]
fn config_bad_values_name_the_key() {
    let cases: &[(&str, &str)] = &[
        ("width = 0", "`width`"),
        ("height = 20000", "`height`"),
        ("width = -3", "width"),
        ("spp = 0", "`spp`"),
        ("spp = 100000000", "`spp`"),
        ("reflections = 0", "`reflections`"),
        // One limit for the config and the integrator: more would be silently clamped.
        ("reflections = 5", "`reflections`"),
        ("mode = \"voxel\"", "voxel"),
        ("seed = -1", "seed"),
        ("[environment]\ncolor = [1, -1, 0]", "`environment.color`"),
        ("[environment]\ncolor = [1, nan, 0]", "`environment.color`"),
        ("[environment]\ncolor = [1, 1]", "color"),
        ("[environment]\ncolor = \"white\"", "color"),
        ("[environment]\nmap = \"sky.png\"", "`environment.map`"),
        (
            "[environment]\nmap = \"sky.exr\"\nintensity = -2",
            "`environment.intensity`",
        ),
        ("[environment]\nintensity = 2", "`environment`"),
        ("[materials.m]\nkd = [0.5, -0.1, 0]", "`materials.m.kd`"),
        ("[materials.m]\nks = inf", "`materials.m.ks`"),
        (
            "[materials.m]\nfamily = \"cook-torrance\"",
            "`materials.m.family`",
        ),
        (
            "[materials.m]\nfamily = \"blinn-phong\"\nshininess = -1",
            "`materials.m.shininess`",
        ),
        (
            "[materials.m]\nfamily = \"blinn-phong\"\nshininess = 2e6",
            "`materials.m.shininess`",
        ),
        (
            "[materials.m]\nfamily = \"ggx\"\nalpha = 0",
            "`materials.m.alpha`",
        ),
        (
            "[materials.m]\nfamily = \"ggx\"\nalpha = 1.5",
            "`materials.m.alpha`",
        ),
        (
            "[materials.m]\nfamily = \"diffuse\"\nks = 0.5",
            "`materials.m.ks`",
        ),
        ("[materials.m]\nshininess = 10", "`materials.m.shininess`"),
        ("[materials.m]\neditable = \"yes\"", "editable"),
        ("[basis]\ncount = 0", "`basis.count`"),
        ("[basis]\nerror_target = -0.1", "`basis.error_target`"),
        ("output = \"\"", "`output`"),
    ];
    for (body, key) in cases {
        let e = config_err(&format!("scene = \"a.gltf\"\n{body}\n"));
        assert!(e.contains(key), "{body:?}: expected {key:?} in: {e}");
    }
}

#[test]
fn config_full_example_parses() {
    let c = BakeConfig::parse(
        r#"
scene = "models/room.glb"
output = "/tmp/room.prtbake"
mode = "vertex"
width = 320
height = 200
spp = 16
reflections = 3
seed = 42

[environment]
map = "sky.hdr"
intensity = 0.5

[materials.floor]
kd = [0.2, 0.3, 0.4]

[materials.vase]
editable = true
family = "ggx"
ks = 0.04
alpha = 0.3

[basis]
count = 6
error_target = 0.01
"#,
        "/project/bake.toml",
    )
    .unwrap();
    assert_eq!(c.scene_path, PathBuf::from("/project/models/room.glb"));
    assert_eq!(c.output, PathBuf::from("/tmp/room.prtbake"));
    assert_eq!(c.mode, Mode::Vertex);
    assert_eq!(
        (c.width, c.height, c.spp, c.reflections, c.seed),
        (320, 200, 16, 3, 42)
    );
    assert_eq!(
        c.environment,
        EnvironmentConfig::Map {
            path: PathBuf::from("/project/sky.hdr"),
            intensity: 0.5,
            rotation: 0.0,
        }
    );
    assert_eq!(c.materials.len(), 2);
    let vase = c.material("vase").unwrap();
    assert!(vase.editable && vase.family == Some(Family::Ggx) && vase.alpha == Some(0.3));
    let basis = c.basis.as_ref().unwrap();
    assert_eq!((basis.count, basis.error_target), (Some(6), Some(0.01)));
    assert_eq!(c.folder(), Path::new("/project"));
}

#[test]
fn config_default_output_and_missing_file() {
    let c = BakeConfig::from_file(scenes_dir().join("ring/bake.toml")).unwrap();
    assert_eq!(c.output, scenes_dir().join("ring/out/ring.prtbake"));
    match BakeConfig::from_file(scenes_dir().join("nope/bake.toml")) {
        Err(ConfigError::Io { path, .. }) => assert!(path.ends_with("nope/bake.toml")),
        other => panic!("{other:?}"),
    }
    let c = BakeConfig::with_defaults("/x/y/scene.glb");
    assert_eq!(c.output, PathBuf::from("/x/y/out/y.prtbake"));
    assert_eq!(c.scene_path, PathBuf::from("/x/y/scene.glb"));
}

#[test]
fn missing_scene_file_is_an_io_error() {
    let c = BakeConfig::with_defaults("/definitely/not/here.gltf");
    match load_with_warnings(&c) {
        Err(e @ SceneError::Io { .. }) => assert!(e.to_string().contains("here.gltf")),
        other => panic!("{:?}", other.map(|_| ())),
    }
}

#[test]
fn interleaved_and_sparse_accessors() {
    let dir = TempDir::new("interleaved");
    let mut doc = Doc::new();
    // Positions and normals interleaved in one view (stride 24), and a sparse accessor that
    // moves vertex 2 of the positions from (0, 1, 0) to (0, 2, 0).
    let mut inter = Vec::new();
    for k in 0..3 {
        for v in [TRI[3 * k], TRI[3 * k + 1], TRI[3 * k + 2], 0.0, 0.0, 1.0] {
            inter.extend_from_slice(&f32::to_le_bytes(v));
        }
    }
    let view = doc.view(&inter);
    doc.json["bufferViews"][view]["byteStride"] = json!(24);
    let sparse_idx = doc.view(&[2u8]);
    let sparse_val = doc.view(&[0.0f32, 2.0, 0.0].map(f32::to_le_bytes).concat());
    let pos = doc.push(
        "accessors",
        json!({"bufferView": view, "componentType": 5126, "count": 3, "type": "VEC3",
               "sparse": {"count": 1,
                          "indices": {"bufferView": sparse_idx, "componentType": 5121},
                          "values": {"bufferView": sparse_val}}}),
    );
    let nor = doc.push(
        "accessors",
        json!({"bufferView": view, "byteOffset": 12, "componentType": 5126, "count": 3,
               "type": "VEC3"}),
    );
    let mesh = doc.push(
        "meshes",
        json!({"primitives": [{"attributes": {"POSITION": pos, "NORMAL": nor}}]}),
    );
    let node = doc.push("nodes", json!({"mesh": mesh}));
    doc.json["scenes"][0]["nodes"] = json!([0, node]);
    doc.write_embedded(&dir);
    let (scene, warnings) = load_with_warnings(&dir.config("")).unwrap_or_else(|e| panic!("{e}"));
    assert!(warnings.is_empty(), "{warnings:?}");
    assert_eq!(
        scene.positions,
        [Vec3::ZERO, Vec3::X, Vec3::new(0.0, 2.0, 0.0)]
    );
    assert!(scene.normals.iter().all(|n| *n == Vec3::Z));
}

/// The example in docs/config.md must stay a valid config.
#[test]
fn documented_example_config_parses() {
    let doc =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("../docs/config.md"))
            .unwrap();
    let start = doc.find("```toml\n").expect("a toml block") + "```toml\n".len();
    let end = start + doc[start..].find("```").unwrap();
    let c = BakeConfig::parse(&doc[start..end], scenes_dir().join("cornell/bake.toml"))
        .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(c.materials.len(), 2);
    // And it fits the scene it claims to be for.
    load_with_warnings(&c).unwrap_or_else(|e| panic!("{e}"));
}

#[test]
fn shared_child_nodes_are_an_error() {
    // Node 2 is a child of both node 1 and node 3: a DAG, not a tree.
    let dir = TempDir::new("dag");
    let mut doc = Doc::new();
    let m = doc.mesh(&TRI, None, None);
    let a = doc.push("nodes", json!({"children": [m]}));
    let b = doc.push("nodes", json!({"children": [m]}));
    doc.json["scenes"][0]["nodes"] = json!([0, a, b]);
    doc.write_embedded(&dir);
    let e = load_err(&dir.config(""));
    assert!(e.contains("two parents"), "{e}");
}

#[test]
fn glb_embedded_image_via_buffer_view() {
    let dir = TempDir::new("glb-image");
    let mut png = Vec::new();
    image::RgbImage::from_raw(1, 1, vec![0, 255, 0])
        .unwrap()
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .unwrap();
    let mut doc = Doc::new();
    let m = doc.material(json!({"name": "glowing",
        "emissiveFactor": [1.0, 1.0, 1.0], "emissiveTexture": {"index": 0}}));
    doc.mesh(&TRI, None, Some(m));
    let view = doc.view(&png);
    doc.json["textures"] = json!([{"source": 0}]);
    doc.json["images"] = json!([{"bufferView": view, "mimeType": "image/png"}]);
    dir.write("scene.glb", doc.glb());
    let p = dir.write("bake.toml", "scene = \"scene.glb\"");
    let (scene, _) =
        load_with_warnings(&BakeConfig::from_file(p).unwrap()).unwrap_or_else(|e| panic!("{e}"));
    let t = scene.materials[0].emissive_texture.unwrap();
    assert_eq!(scene.textures[t].texels, [Vec3::Y]);
    assert!(scene.materials[0].is_emissive());
}

// ---------------------------------------------------------------------------------------------
// What `bake INPUT` accepts (config::input) and configs written back as TOML.

/// The config's TOML parses back (from the same config path) to the same config, and writing
/// that again gives the same text.
fn assert_roundtrip(c: &BakeConfig) {
    let text = c.to_toml();
    let back = BakeConfig::parse(&text, &c.config_path).unwrap_or_else(|e| panic!("{e}\n{text}"));
    assert_eq!(&back, c, "{text}");
    assert_eq!(back.to_toml(), text);
}

/// Found by fuzzing (`prt-fuzz config`): a path naming the config's own folder was written
/// back as `""`, which the parser refuses.
#[test]
fn roundtrip_keeps_a_path_naming_the_config_folder() {
    let c = BakeConfig::parse("scene = \".\"\noutput = \"./\"", "/scenes/x/bake.toml").unwrap();
    assert_eq!(c.scene_path, PathBuf::from("/scenes/x"));
    assert_roundtrip(&c);
}

#[test]
fn input_folder_means_its_bake_toml() {
    let r = input::resolve(&scenes_dir().join("cornell")).unwrap();
    assert_eq!(r.kind, InputKind::SceneFolder);
    let direct = BakeConfig::from_file(scenes_dir().join("cornell/bake.toml")).unwrap();
    assert_eq!(r.config, direct);
    let r = input::resolve(&scenes_dir().join("cornell/bake.toml")).unwrap();
    assert_eq!(r.kind, InputKind::Config);
    assert_eq!(r.config, direct);
    // The example configs survive a round trip through TOML too.
    for name in ["cornell", "ring", "furnace"] {
        assert_roundtrip(&load_example(name).0);
    }
}

#[test]
fn input_glb_bakes_with_defaults() {
    let path = scenes_dir().join("furnace/furnace.glb");
    let r = input::resolve(&path).unwrap();
    assert_eq!(r.kind, InputKind::Gltf);
    let c = &r.config;
    assert_eq!(c.scene_path, path);
    assert_eq!(c.mode, Mode::Pixel);
    assert_eq!((c.width, c.height, c.spp, c.reflections), (256, 256, 64, 2));
    assert_eq!(c.output, scenes_dir().join("furnace/out/furnace.prtbake"));
    // Under the neutral studio map shipped with the project (a bare glTF rarely brings lights).
    assert_eq!(
        c.environment,
        EnvironmentConfig::Map {
            path: prt_bake::config::default_environment_map(),
            intensity: 1.0,
            rotation: 0.0
        }
    );
    assert!(prt_bake::config::default_environment_map().is_file());
    // The GLB has a camera, so the config names none and the glTF's is used.
    assert!(c.camera.is_none());
    let editable_diffuse = MaterialConfig {
        editable: true,
        family: Some(Family::Diffuse),
        ..MaterialConfig::default()
    };
    assert_eq!(c.materials, vec![("sphere".to_owned(), editable_diffuse)]);
    let scene = prt_bake::run::load_scene(c, &prt_bake::progress::Silent).unwrap();
    let (_, example, _) = load_example("furnace");
    assert_eq!(scene.camera, example.camera);
    assert!(scene.materials[0].editable);
    assert_roundtrip(c);
}

#[test]
fn input_gltf_leaves_emissive_materials_alone() {
    let r = input::resolve(&scenes_dir().join("cornell/cornell.gltf")).unwrap();
    let names: Vec<&str> = r.config.materials.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(names, ["white", "red", "green", "bunny", "tall_box"]);
    let family = |n: &str| r.config.material(n).unwrap().family;
    // The bunny is glossy in the glTF (ggx); the walls and the tall box are fully rough.
    assert_eq!(family("bunny"), Some(Family::Ggx));
    assert_eq!(family("white"), Some(Family::Diffuse));
    assert_eq!(family("tall_box"), Some(Family::Diffuse));
    assert!(r.config.materials.iter().all(|(_, m)| m.editable));
    let scene = prt_bake::run::load_scene(&r.config, &prt_bake::progress::Silent).unwrap();
    assert!(!scene.materials[scene.material_index("light").unwrap()].editable);
    assert_roundtrip(&r.config);
}

#[test]
fn input_gltf_without_camera_gets_a_framing_camera() {
    let dir = TempDir::new("frame");
    let mut doc = Doc::new();
    doc.mesh(
        &[
            2.0, 1.0, -3.0, 4.0, 1.0, -3.0, 2.0, 3.0, -4.0, 5.0, -1.0, -6.0, 6.0, 0.0, -6.0, 5.0,
            0.5, -5.0,
        ],
        None,
        None,
    );
    doc.json["nodes"][0] = json!({"name": "empty"});
    doc.json.as_object_mut().unwrap().remove("cameras");
    let path = doc.write_embedded(&dir);
    // Loading it with a plain config is still an error: only the defaults frame the scene.
    assert!(load_err(&BakeConfig::with_defaults(&path)).contains("no camera"));

    let r = input::resolve(&path).unwrap();
    assert_eq!(r.kind, InputKind::Gltf);
    let framing = r.config.camera.expect("a framing camera");
    assert!(framing.position.is_finite() && framing.target.is_finite());
    let scene = prt_bake::run::load_scene(&r.config, &prt_bake::progress::Silent).unwrap();
    let cam = scene.camera;
    assert!(cam.position.is_finite() && cam.forward.is_finite() && cam.up.is_finite());
    let tan = (0.5 * cam.yfov).tan();
    let aspect = r.config.width as f32 / r.config.height as f32;
    for p in &scene.positions {
        let d = *p - cam.position;
        let z = d.dot(cam.forward);
        assert!(z > 0.0, "{p} is behind the camera");
        assert!(
            d.dot(cam.up).abs() / z < tan,
            "{p} is above or below the view"
        );
        assert!(
            d.dot(cam.right).abs() / z < tan * aspect,
            "{p} is left or right of the view"
        );
    }
    // Primitives without a material share `default`: editable diffuse.
    assert_eq!(r.config.materials.len(), 1);
    assert_eq!(r.config.materials[0].0, "default");
    assert_eq!(r.config.materials[0].1.family, Some(Family::Diffuse));
    assert_roundtrip(&r.config);

    // The printed config, saved beside the glTF, gives the same config and the same scene.
    dir.write("bake.toml", r.config.to_toml());
    let again = input::resolve(&dir.0).unwrap();
    assert_eq!(again.kind, InputKind::SceneFolder);
    assert_eq!(again.config, r.config);
    let scene2 = prt_bake::run::load_scene(&again.config, &prt_bake::progress::Silent).unwrap();
    assert_eq!(scene2.camera, scene.camera);
    assert_eq!(scene2.positions, scene.positions);
}

#[test]
fn input_of_the_wrong_form_says_what_was_expected() {
    const EXPECTED: &str = "expected a bake config (.toml), a scene folder holding bake.toml, \
                            or a glTF scene (.gltf/.glb)";
    let dir = TempDir::new("forms");
    dir.write("notes.txt", "hello");
    for (path, reason) in [
        (dir.0.join("missing"), "no such file or folder"),
        (dir.0.join("missing.glb"), "no such file or folder"),
        (dir.0.clone(), "the folder holds no bake.toml"),
        (dir.0.join("notes.txt"), "unknown file type"),
    ] {
        let e = input::resolve(&path).unwrap_err();
        assert!(matches!(e, InputError::WrongForm { .. }), "{e:?}");
        let e = e.to_string();
        assert!(e.starts_with(&path.display().to_string()), "{e}");
        assert!(e.contains(reason) && e.contains(EXPECTED), "{e}");
    }
    // The right form with bad content: the config's or the scene's own error, naming the file.
    dir.write("bad.toml", "scene = ");
    let e = input::resolve(&dir.0.join("bad.toml")).unwrap_err();
    assert!(matches!(e, InputError::Config(_)), "{e:?}");
    assert!(e.to_string().contains("bad.toml"), "{e}");
    let e = input::resolve(&dir.0.join("absent.toml")).unwrap_err();
    assert!(
        matches!(e, InputError::Config(ConfigError::Io { .. })),
        "{e:?}"
    );
    dir.write("bad.glb", "not a glb");
    let e = input::resolve(&dir.0.join("bad.glb")).unwrap_err();
    assert!(
        matches!(e, InputError::Scene(SceneError::Parse { .. })),
        "{e:?}"
    );
    assert!(e.to_string().contains("bad.glb"), "{e}");
}

#[test]
fn config_camera_table() {
    let c = BakeConfig::parse(
        "scene = \"x.gltf\"\n[camera]\nposition = [0, 1, 5]\ntarget = [0, 1, 0]\n",
        "/somewhere/bake.toml",
    )
    .unwrap();
    let cam = c.camera.unwrap();
    assert_eq!(cam.position, Vec3::new(0.0, 1.0, 5.0));
    assert_eq!(cam.fov, prt_bake::config::DEFAULT_FOV);
    assert_roundtrip(&c);
    for (body, key) in [
        ("position = [0, 0, 0]\ntarget = [0, 0, 0]", "camera.target"),
        ("position = [0, 0, 0]\ntarget = [0, 5, 0]", "camera.target"),
        (
            "position = [0, 0, 1]\ntarget = [0, 0, 0]\nyfov = 4",
            "camera.yfov",
        ),
        ("position = [0, 0, 1]", "target"),
        (
            "position = [0, 0, 1]\ntarget = [0, 0, 0]\nfov = 180",
            "camera.fov",
        ),
        (
            "position = [0, 0, 1]\ntarget = [0, 0, 0]\nfov = 0",
            "camera.fov",
        ),
        (
            "position = [0, 0, 1]\ntarget = [0, 0, 0]\nfov = 40\nyfov = 0.7",
            "camera.yfov",
        ),
        (
            "position = [0, 0, 1]\ntarget = [0, 0, 0]\nfovy = 40",
            "fovy",
        ),
    ] {
        let e = config_err(&format!("scene = \"x.gltf\"\n[camera]\n{body}\n"));
        assert!(e.contains(key), "{body:?}: {e}");
    }
}
