//! Target `gltf`: the glTF loader, as `bake model.gltf` drives it: the defaults for a bare
//! glTF (`prt_bake::config::input::defaults_for_gltf`, which loads the scene once), the printed
//! config read back (`bake --print-config` output must parse to the same config), the scene
//! loaded with that config (`prt_bake::run::load_scene`), and the BVH and light set built from
//! it (the loader's output must be usable).
//!
//! An input is a `.glb` file, or a `.gltf` JSON with its one external buffer, packed as
//! [`BUNDLE_MAGIC`], the JSON's length (u32 LE), the JSON, then the buffer; it is written to a
//! scratch folder as `scene.gltf` + `scene.bin` (the buffer URI of the seeds is `scene.bin`).
//! Failing inputs are saved as such a folder, or as a `.glb`, which `bake` opens directly.
//!
//! Seeds: the example scenes (`cornell`, `ring`: .gltf + .bin; `furnace`: .glb), small scenes
//! made here that use what the examples do not (interleaved attributes, u8/u16/u32 indices,
//! data URIs, textures, emissive strength, punctual lights, node matrices and children,
//! orthographic cameras), and `fuzz/corpus/gltf` (`NAME.glb` files and `NAME/scene.gltf` +
//! `scene.bin` folders).
//!
//! Mutations: the JSON as a tree (accessor counts, byte offsets and strides, component types,
//! indices into every array, URIs), the JSON as text, and the binary buffer (values inside a
//! buffer view set to boundary integers, NaN or infinite floats); a `.glb` is split into its
//! chunks and reassembled with consistent lengths, or mutated raw.

use std::path::{Path, PathBuf};

use anyhow::Context as _;
use prt_bake::config::input::defaults_for_gltf;
use prt_bake::config::BakeConfig;
use prt_bake::progress::Silent;
use serde_json::{json, Value};

use crate::engine::{outcome, SaveFn, Target};
use crate::json_mut;
use crate::mutate::{byte_op, havoc, replace_number, Dice, U32S};

/// Marks a packed `.gltf` + `.bin` input.
const BUNDLE_MAGIC: &[u8; 8] = b"GLTF+BIN";
const MAX_LEN: usize = 4 << 20;

const DICT: &[&str] = &[
    "POSITION",
    "NORMAL",
    "TEXCOORD_0",
    "TEXCOORD_1",
    "COLOR_0",
    "TANGENT",
    "JOINTS_0",
    "SCALAR",
    "VEC2",
    "VEC3",
    "VEC4",
    "MAT4",
    "perspective",
    "orthographic",
    "point",
    "spot",
    "directional",
    "KHR_lights_punctual",
    "KHR_materials_emissive_strength",
    "KHR_texture_transform",
    "scene.bin",
    "data:application/octet-stream;base64,AAAA",
    "data:image/png;base64,iVBORw0KGgo=",
    "data:;base64,",
    "image/png",
    "image/jpeg",
    "file:///dev/null",
    "file:///dev/zero",
    "../scene.bin",
    "%zz",
    "http://x/y.bin",
    "accessors",
    "bufferViews",
    "buffers",
    "byteOffset",
    "byteLength",
    "byteStride",
    "count",
    "componentType",
    "normalized",
    "type",
    "min",
    "max",
    "sparse",
    "indices",
    "values",
    "nodes",
    "children",
    "mesh",
    "camera",
    "matrix",
    "translation",
    "rotation",
    "scale",
    "materials",
    "material",
    "emissiveFactor",
    "emissiveStrength",
    "emissiveTexture",
    "baseColorFactor",
    "metallicFactor",
    "roughnessFactor",
    "baseColorTexture",
    "pbrMetallicRoughness",
    "index",
    "texCoord",
    "images",
    "uri",
    "mimeType",
    "bufferView",
    "textures",
    "source",
    "sampler",
    "samplers",
    "extensionsUsed",
    "extensionsRequired",
    "extensions",
    "lights",
    "light",
    "color",
    "intensity",
    "range",
    "innerConeAngle",
    "outerConeAngle",
    "yfov",
    "aspectRatio",
    "xmag",
    "ymag",
    "znear",
    "zfar",
    "scenes",
    "scene",
    "mode",
    "primitives",
    "attributes",
    "targets",
    "skins",
    "skin",
    "joints",
    "name",
    "",
];

/// A glTF input: a `.glb`, or a `.gltf` JSON and its buffer.
enum Scene {
    Glb(Vec<u8>),
    Gltf { json: Vec<u8>, bin: Vec<u8> },
}

impl Scene {
    fn decode(input: &[u8]) -> Scene {
        let unpack = || {
            let rest = input.strip_prefix(BUNDLE_MAGIC)?;
            let n = u32::from_le_bytes(*rest.first_chunk::<4>()?) as usize;
            let json = rest.get(4..4usize.checked_add(n)?)?;
            Some(Scene::Gltf {
                json: json.to_vec(),
                bin: rest[4 + n..].to_vec(),
            })
        };
        unpack().unwrap_or_else(|| Scene::Glb(input.to_vec()))
    }

    fn encode(&self) -> Vec<u8> {
        match self {
            Scene::Glb(b) => b.clone(),
            Scene::Gltf { json, bin } => {
                let mut out = BUNDLE_MAGIC.to_vec();
                out.extend_from_slice(&(json.len() as u32).to_le_bytes());
                out.extend_from_slice(json);
                out.extend_from_slice(bin);
                out
            }
        }
    }
}

/// Writes an input as the files the loader reads; returns the path to load.
fn write_scene(input: &[u8], dir: &Path) -> std::io::Result<PathBuf> {
    std::fs::create_dir_all(dir)?;
    match Scene::decode(input) {
        Scene::Glb(b) => {
            let path = dir.join("scene.glb");
            std::fs::write(&path, b)?;
            Ok(path)
        }
        Scene::Gltf { json, bin } => {
            let path = dir.join("scene.gltf");
            std::fs::write(&path, json)?;
            std::fs::write(dir.join("scene.bin"), bin)?;
            Ok(path)
        }
    }
}

/// Saves a failing input as the files `bake` would open: `DIR/STEM/scene.gltf` (+ `.bin`) or
/// `DIR/STEM/scene.glb`.
fn save_scene(input: &[u8], dir: &Path, stem: &str) -> std::io::Result<PathBuf> {
    write_scene(input, &dir.join(stem))
}

/// A GLB's JSON and BIN chunks (`None` unless the layout is intact).
fn glb_chunks(b: &[u8]) -> Option<(Vec<u8>, Option<Vec<u8>>)> {
    let word = |at: usize| -> Option<usize> {
        Some(u32::from_le_bytes(*b.get(at..at + 4)?.first_chunk::<4>()?) as usize)
    };
    if b.get(..4)? != b"glTF" {
        return None;
    }
    let json_len = word(12)?;
    let json = b.get(20..20usize.checked_add(json_len)?)?.to_vec();
    let at = 20 + json_len;
    let bin = match word(at) {
        Some(n) => Some(b.get(at + 8..(at + 8).checked_add(n)?)?.to_vec()),
        None => None,
    };
    Some((json, bin))
}

/// A GLB with consistent lengths and 4-byte padding.
fn glb_assemble(json: &[u8], bin: Option<&[u8]>) -> Vec<u8> {
    let mut json = json.to_vec();
    json.resize(json.len().div_ceil(4) * 4, b' ');
    let bin = bin.map(|b| {
        let mut b = b.to_vec();
        b.resize(b.len().div_ceil(4) * 4, 0);
        b
    });
    let total = 12 + 8 + json.len() + bin.as_ref().map_or(0, |b| 8 + b.len());
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json);
    if let Some(b) = bin {
        out.extend_from_slice(&(b.len() as u32).to_le_bytes());
        out.extend_from_slice(b"BIN\0");
        out.extend_from_slice(&b);
    }
    out
}

/// Mutates a glTF's JSON text and binary buffer (a `.gltf`'s, or a `.glb`'s chunks).
fn mutate_parts(json: &mut Vec<u8>, bin: &mut Vec<u8>, other: &[u8], d: &mut Dice) {
    match d.below(20) {
        0..=9 => {
            let parsed: Option<Value> = serde_json::from_slice(json).ok();
            match parsed {
                Some(mut v) => {
                    for _ in 0..1 + d.below(3) {
                        json_mut::mutate(&mut v, d, DICT);
                    }
                    *json = v.to_string().into_bytes();
                }
                None => havoc(json, other, d, MAX_LEN),
            }
        }
        10..=13 => {
            // Values inside a buffer view: where accessors read indices and floats.
            let views: Vec<(usize, usize)> = serde_json::from_slice::<Value>(json)
                .ok()
                .and_then(|v| {
                    let views = v.get("bufferViews")?.as_array()?.clone();
                    Some(
                        views
                            .iter()
                            .filter_map(|bv| {
                                let off = bv.get("byteOffset").and_then(Value::as_u64).unwrap_or(0);
                                let len = bv.get("byteLength")?.as_u64()?;
                                Some((off as usize, len as usize))
                            })
                            .collect(),
                    )
                })
                .unwrap_or_default();
            let (off, len) = if views.is_empty() {
                (0, bin.len())
            } else {
                *d.pick(&views)
            };
            let end = off.saturating_add(len).min(bin.len());
            if off + 4 <= end {
                for _ in 0..1 + d.below(4) {
                    let i = off + 4 * d.below((end - off) / 4);
                    let v: u32 = if d.chance(0.5) {
                        *d.pick(&U32S)
                    } else {
                        // An index just past a typical vertex count, or a huge float.
                        *d.pick(&[3, 4, 100_000, 0x7149_F2CA, 0x0000_FFFF])
                    };
                    if d.chance(0.3) {
                        bin[i..i + 2].copy_from_slice(&(v as u16).to_le_bytes());
                    } else {
                        bin[i..i + 4].copy_from_slice(&v.to_le_bytes());
                    }
                }
            } else {
                byte_op(bin, other, d);
            }
        }
        14 | 15 => havoc(bin, other, d, MAX_LEN),
        16 | 17 => replace_number(json, d),
        _ => havoc(json, other, d, MAX_LEN),
    }
}

/// Standard base64 with padding (for data URIs in the seeds).
fn base64(bytes: &[u8]) -> String {
    const A: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::new();
    for c in bytes.chunks(3) {
        let n = (c[0] as u32) << 16
            | (*c.get(1).unwrap_or(&0) as u32) << 8
            | *c.get(2).unwrap_or(&0) as u32;
        for k in 0..4 {
            if k <= c.len() {
                out.push(A[(n >> (18 - 6 * k)) as usize & 63] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

fn f32s(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// Small scenes using what the examples do not: see the module doc.
fn made_seeds(scratch: &Path) -> anyhow::Result<Vec<Vec<u8>>> {
    let mut seeds = Vec::new();

    // One triangle: positions only (flat normals generated), not indexed, data URI buffer.
    let tri = f32s(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0]);
    let doc = json!({
        "asset": {"version": "2.0"},
        "scenes": [{"nodes": [0, 1]}],
        "nodes": [{"mesh": 0}, {"camera": 0, "translation": [0.3, 0.3, 2.0]}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3"}],
        "bufferViews": [{"buffer": 0, "byteLength": 36}],
        "buffers": [{"byteLength": 36,
                     "uri": format!("data:application/octet-stream;base64,{}", base64(&tri))}],
        "cameras": [{"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.1}}]
    });
    seeds.push(
        Scene::Gltf {
            json: doc.to_string().into_bytes(),
            bin: Vec::new(),
        }
        .encode(),
    );

    // A textured, interleaved quad (u16 indices) and an emissive triangle (u8 indices) under a
    // node hierarchy with a matrix, three punctual lights, and both camera types.
    let png_path = scratch.join("tex.png");
    prt_formats::write_png(
        &png_path,
        2,
        2,
        &[[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0; 3]],
        1.0,
    )?;
    let png = std::fs::read(&png_path)?;
    let mut bin = Vec::new();
    // Interleaved: position, normal, uv (32 bytes per vertex).
    for (x, y) in [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)] {
        bin.extend(f32s(&[x, y, 0.0, 0.0, 0.0, 1.0, x, y]));
    }
    let quad_idx = [0u16, 1, 2, 0, 2, 3];
    bin.extend(quad_idx.iter().flat_map(|i| i.to_le_bytes()));
    bin.extend([0u8; 4]); // align
    let tri_at = bin.len();
    bin.extend(f32s(&[0.0, 0.0, 1.0, 0.5, 0.0, 1.0, 0.0, 0.5, 1.0]));
    let tri_idx_at = bin.len();
    bin.extend([0u8, 1, 2, 0]);
    let png_at = bin.len();
    bin.extend(&png);
    while bin.len() % 4 != 0 {
        bin.push(0);
    }
    let quarter_turn = std::f64::consts::FRAC_1_SQRT_2;
    let doc = |buffer: Value, image: Value| {
        json!({
            "asset": {"version": "2.0"},
            "extensionsUsed": ["KHR_lights_punctual", "KHR_materials_emissive_strength"],
            "scene": 0,
            "scenes": [{"nodes": [0, 3]}],
            "nodes": [
                {"name": "root", "children": [1, 2],
                 "matrix": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0.1, 0, 0, 1]},
                {"name": "quad", "mesh": 0, "scale": [2, 2, -1]},
                {"name": "lamp", "mesh": 1, "rotation": [0, quarter_turn, 0, quarter_turn],
                 "extensions": {"KHR_lights_punctual": {"light": 0}}},
                {"name": "rig", "translation": [0.5, 0.5, 3], "children": [4, 5, 6]},
                {"camera": 0},
                {"camera": 1, "extensions": {"KHR_lights_punctual": {"light": 1}}},
                {"extensions": {"KHR_lights_punctual": {"light": 2}}}
            ],
            "meshes": [
                {"primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2},
                                 "indices": 3, "material": 0, "mode": 4}]},
                {"primitives": [{"attributes": {"POSITION": 4}, "indices": 5, "material": 1},
                                {"attributes": {"POSITION": 4}}]}
            ],
            "materials": [
                {"name": "tex", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0},
                 "metallicFactor": 0.2, "roughnessFactor": 0.4}},
                {"name": "glow", "emissiveFactor": [1, 0.5, 0.25],
                 "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 4}}}
            ],
            "textures": [{"source": 0, "sampler": 0}],
            "samplers": [{"magFilter": 9729, "wrapS": 33648}],
            "images": [image],
            "accessors": [
                {"bufferView": 0, "byteOffset": 0, "componentType": 5126, "count": 4,
                 "type": "VEC3"},
                {"bufferView": 0, "byteOffset": 12, "componentType": 5126, "count": 4,
                 "type": "VEC3"},
                {"bufferView": 0, "byteOffset": 24, "componentType": 5126, "count": 4,
                 "type": "VEC2"},
                {"bufferView": 1, "componentType": 5123, "count": 6, "type": "SCALAR"},
                {"bufferView": 2, "componentType": 5126, "count": 3, "type": "VEC3",
                 "min": [0, 0, 1], "max": [0.5, 0.5, 1]},
                {"bufferView": 3, "componentType": 5121, "count": 3, "type": "SCALAR"}
            ],
            "bufferViews": [
                {"buffer": 0, "byteOffset": 0, "byteLength": 128, "byteStride": 32},
                {"buffer": 0, "byteOffset": 128, "byteLength": 12},
                {"buffer": 0, "byteOffset": tri_at, "byteLength": 36},
                {"buffer": 0, "byteOffset": tri_idx_at, "byteLength": 3},
                {"buffer": 0, "byteOffset": png_at, "byteLength": png.len()}
            ],
            "buffers": [buffer],
            "cameras": [
                {"type": "perspective", "perspective": {"yfov": 0.9, "aspectRatio": 1.5,
                 "znear": 0.01, "zfar": 50}},
                {"type": "orthographic", "orthographic": {"xmag": 1, "ymag": 1, "znear": 0.1,
                 "zfar": 10}}
            ],
            "extensions": {"KHR_lights_punctual": {"lights": [
                {"type": "point", "color": [1, 0.9, 0.8], "intensity": 5, "range": 10},
                {"type": "spot", "intensity": 3,
                 "spot": {"innerConeAngle": 0.2, "outerConeAngle": 0.6}},
                {"type": "directional", "intensity": 2}
            ]}}
        })
    };
    let png_uri = json!({"uri": format!("data:image/png;base64,{}", base64(&png))});
    let gltf = doc(
        json!({"byteLength": bin.len(), "uri": "scene.bin"}),
        png_uri,
    );
    seeds.push(
        Scene::Gltf {
            json: gltf.to_string().into_bytes(),
            bin: bin.clone(),
        }
        .encode(),
    );
    // The same as a GLB, the image read from a buffer view; u32 quad indices.
    let mut glb_bin = bin.clone();
    let idx32: Vec<u8> = quad_idx
        .iter()
        .flat_map(|&i| (i as u32).to_le_bytes())
        .collect();
    let idx32_at = glb_bin.len();
    glb_bin.extend(&idx32);
    let mut glb_doc = doc(
        json!({"byteLength": glb_bin.len()}),
        json!({"bufferView": 4, "mimeType": "image/png"}),
    );
    glb_doc["bufferViews"]
        .as_array_mut()
        .context("bufferViews")?
        .push(json!({"buffer": 0, "byteOffset": idx32_at, "byteLength": 24}));
    glb_doc["accessors"][3] = json!({"bufferView": 5, "componentType": 5125, "count": 6,
                                     "type": "SCALAR"});
    seeds.push(glb_assemble(glb_doc.to_string().as_bytes(), Some(&glb_bin)));
    Ok(seeds)
}

/// An example scene's `.gltf` and its buffer, the buffer's URI renamed to `scene.bin`.
fn example_gltf(scenes: &Path, name: &str) -> anyhow::Result<Vec<u8>> {
    let dir = scenes.join(name);
    let mut doc: Value = serde_json::from_slice(&std::fs::read(dir.join(format!("{name}.gltf")))?)?;
    let buffer = &mut doc["buffers"][0];
    let uri = buffer["uri"]
        .as_str()
        .context("the example's buffer has a URI")?;
    let bin = std::fs::read(dir.join(uri))?;
    buffer["uri"] = Value::from("scene.bin");
    Ok(Scene::Gltf {
        json: doc.to_string().into_bytes(),
        bin,
    }
    .encode())
}

pub struct GltfTarget {
    scenes: PathBuf,
    extra: Vec<PathBuf>,
    dir: tempfile::TempDir,
}

impl GltfTarget {
    pub fn new(scenes: &Path, extra: Vec<PathBuf>) -> anyhow::Result<Self> {
        Ok(GltfTarget {
            scenes: scenes.to_path_buf(),
            extra,
            dir: tempfile::tempdir()?,
        })
    }
}

/// Reads corpus entries: `NAME.glb` files and folders holding `scene.gltf` (+ `scene.bin`).
fn read_corpus(dirs: &[PathBuf]) -> anyhow::Result<Vec<Vec<u8>>> {
    crate::targets::corpus_entries(dirs)?
        .iter()
        .filter(|p| p.is_file() || p.join("scene.gltf").is_file())
        .map(|p| read_corpus_entry(p))
        .collect()
}

/// One input: a folder holding `scene.gltf` (+ `scene.bin`), or a `.glb` file.
fn read_corpus_entry(p: &Path) -> anyhow::Result<Vec<u8>> {
    if p.is_dir() {
        let json = std::fs::read(p.join("scene.gltf"))
            .with_context(|| format!("{}: no scene.gltf", p.display()))?;
        let bin = std::fs::read(p.join("scene.bin")).unwrap_or_default();
        Ok(Scene::Gltf { json, bin }.encode())
    } else {
        Ok(std::fs::read(p)?)
    }
}

impl Target for GltfTarget {
    fn name(&self) -> &'static str {
        "gltf"
    }

    fn saver(&self) -> SaveFn {
        save_scene
    }

    fn load(&self, path: &Path) -> anyhow::Result<Vec<u8>> {
        let dir = if path.is_file() && path.extension().is_some_and(|e| e == "gltf") {
            path.parent().unwrap_or(Path::new("."))
        } else {
            path
        };
        read_corpus_entry(dir)
    }

    fn seeds(&mut self) -> anyhow::Result<Vec<Vec<u8>>> {
        let mut seeds = vec![
            example_gltf(&self.scenes, "cornell")?,
            example_gltf(&self.scenes, "ring")?,
            std::fs::read(self.scenes.join("furnace").join("furnace.glb"))?,
        ];
        seeds.extend(made_seeds(self.dir.path())?);
        seeds.extend(read_corpus(&self.extra)?);
        Ok(seeds)
    }

    fn mutate(&mut self, parent: &[u8], other: &[u8], d: &mut Dice) -> Vec<u8> {
        match Scene::decode(parent) {
            Scene::Gltf { mut json, mut bin } => {
                mutate_parts(&mut json, &mut bin, other, d);
                json.truncate(MAX_LEN);
                bin.truncate(MAX_LEN);
                Scene::Gltf { json, bin }.encode()
            }
            Scene::Glb(glb) => match glb_chunks(&glb) {
                Some((mut json, bin)) if d.chance(0.8) => {
                    let had_bin = bin.is_some();
                    let mut bin = bin.unwrap_or_default();
                    mutate_parts(&mut json, &mut bin, other, d);
                    glb_assemble(&json, (had_bin || !bin.is_empty()).then_some(&bin[..]))
                }
                _ => {
                    let mut b = glb;
                    havoc(&mut b, other, d, MAX_LEN);
                    b
                }
            },
        }
    }

    fn run(&mut self, input: &[u8]) -> Result<String, String> {
        let dir = self.dir.path().join("scene");
        let path = match write_scene(input, &dir) {
            Ok(p) => p,
            Err(e) => return Ok(outcome("write", &e.to_string(), &dir)),
        };
        let config = match defaults_for_gltf(&path) {
            Ok(c) => c,
            Err(e) => return Ok(outcome("defaults", &e.to_string(), &dir)),
        };
        // `bake model.glb --print-config` output must read back as the same config.
        let printed = config.to_toml();
        match BakeConfig::parse(&printed, &config.config_path) {
            Ok(back) if back == config => {}
            Ok(back) => {
                return Err(format!(
                    "the printed defaults do not round-trip: {config:?} printed as\n{printed}\n\
                     reads back as {back:?}"
                ))
            }
            Err(e) => {
                return Err(format!(
                    "the printed defaults do not parse ({e}):\n{printed}"
                ))
            }
        }
        let scene = match prt_bake::run::load_scene(&config, &Silent) {
            Ok(s) => s,
            Err(e) => return Ok(outcome("load", &e.to_string(), &dir)),
        };
        let accel = prt_bake::accel::Accel::build(&scene);
        let _lights = prt_bake::lights::LightSet::new(&scene);
        Ok(format!(
            "ok: loaded, {} materials, {} textures, {} lights, bvh {}",
            scene.materials.len().min(4),
            scene.textures.len().min(2),
            scene.lights.len().min(3),
            accel.triangle_count() > 0
        ))
    }
}
