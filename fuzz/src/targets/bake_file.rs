//! Target `bake-file`: the bake-file reader (`prt_formats::BakeFile`: open, tensor views,
//! checksum verification) and the runtime on top of it (`prt_runtime::open`: open either
//! kind, edit, render), on a file written for every input.
//!
//! Seeds: tiny bakes of the example scenes made in-process by the baker (f32 and f16, with
//! and without the compressed variant, with Blinn-Phong and GGX bases), container files made
//! with `BakeWriter` (every dtype, scalars, empty tensors, padding), and `fuzz/corpus/bake-file`.
//!
//! Mutations: raw bytes; the container header as JSON (names, dtypes, shapes, offsets, the
//! `__metadata__` entries); the bake schema's metadata JSON (materials, bases, groups); the
//! bytes of one tensor; reshaping or retyping a tensor; and resizing one (the file laid out
//! again by the writer). After a structured mutation the
//! checksums are usually recomputed ([`fix_checksums`]), so the input gets past the CRC checks
//! to the layout, schema and runtime checks behind them.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::Context as _;
use prt_bake::basis::{BasisBuilder, BasisConfig};
use prt_bake::pixel::{write_bake_file, PixelBakeOptions, SlotLayout};
use prt_bake::progress::Silent;
use prt_bake::run::load_scene;
use prt_formats::basis::AngularGrid;
use prt_formats::overrides::OverrideValue;
use prt_formats::pixel::Precision;
use prt_formats::{BakeFile, BakeWriter, Dtype, Family};
use prt_runtime::hooks::Kernel;
use prt_runtime::{PixelRelighter, Relighter, Variant, VertexRelighter};
use serde_json::{Map, Value};

use crate::engine::{outcome, Target};
use crate::json_mut;
use crate::mutate::{byte_op, havoc, Dice, U32S};

/// Largest input kept (the seeds are a few hundred kB at most).
const MAX_LEN: usize = 2 << 20;

/// Strings worth trying in the container header and the schema metadata.
const DICT: &[&str] = &[
    "emission",
    "g0.pixels",
    "g0.t",
    "g0.mean",
    "g0.components",
    "g0.weights",
    "g1.pixels",
    "g1.t",
    "basis.0.tables",
    "__pad0",
    "__metadata__",
    "__x",
    "format",
    "schema_version",
    "metadata",
    "crc32",
    "header_crc32",
    "prt-bake",
    "1",
    "2",
    "F32",
    "F16",
    "U32",
    "U16",
    "U8",
    "I32",
    "F64",
    "BOOL",
    "dtype",
    "shape",
    "data_offsets",
    "kd",
    "basis",
    "lobe",
    "own",
    "kind",
    "index",
    "diffuse",
    "blinn-phong",
    "ggx",
    "f32",
    "f16",
    "log",
    "linear",
    "half-diff",
    "angles",
    "materials",
    "bases",
    "groups",
    "active",
    "pixels",
    "slots",
    "row_len",
    "compressed_rank",
    "scale",
    "channels",
    "reflections",
    "width",
    "height",
    "param_samples",
    "coefficients",
    "num_bases",
    "param_warp",
    "param_range",
    "grid",
    "slot_offset",
    "offset",
    "",
];

pub struct BakeFileTarget {
    scenes: PathBuf,
    extra: Vec<PathBuf>,
    dir: tempfile::TempDir,
    path: PathBuf,
}

impl BakeFileTarget {
    /// `scenes`: the example scenes folder; `extra`: corpus folders (every file is a seed).
    pub fn new(scenes: &Path, extra: Vec<PathBuf>) -> anyhow::Result<Self> {
        let dir = tempfile::tempdir()?;
        let path = dir.path().join("input.prtbake");
        Ok(BakeFileTarget {
            scenes: scenes.to_path_buf(),
            extra,
            dir,
            path,
        })
    }
}

/// Bakes `scene` (a folder of `scenes/`) tiny and returns the file's bytes. The editable
/// glossy materials get small bases (a coarse grid, few parameter samples): the baker's
/// defaults take seconds to build, and the reader treats every basis alike.
/// A per-vertex bake of a small diffuse scene (a floor and a ball under a constant sky), T1
/// stored compressed or dense, as file bytes.
fn tiny_vertex_bake(out: &Path, compressed: bool) -> anyhow::Result<Vec<u8>> {
    use glam::Vec3;
    use prt_bake::brdf::BrdfParams;
    use prt_bake::scene::Environment;
    use prt_bake::vertex::{bake_vertex, VertexBakeOptions};
    let mut b = prt_bake::testing::SceneBuilder::new();
    let floor = b.material(
        "floor",
        BrdfParams::diffuse(Vec3::splat(0.6)),
        Vec3::ZERO,
        true,
    );
    let ball = b.material(
        "ball",
        BrdfParams::diffuse(Vec3::new(0.8, 0.2, 0.1)),
        Vec3::ZERO,
        false,
    );
    b.quad(
        [
            Vec3::new(-1.0, 0.0, -1.0),
            Vec3::new(-1.0, 0.0, 1.0),
            Vec3::new(1.0, 0.0, 1.0),
            Vec3::new(1.0, 0.0, -1.0),
        ],
        floor,
    );
    b.sphere(Vec3::new(0.0, 0.4, 0.0), 0.35, 0, ball);
    b.environment(Environment::Constant(Vec3::ONE));
    let scene = b.build();
    let opts = VertexBakeOptions {
        samples: 4,
        secondary: 1,
        t0_terms: 8,
        compression: compressed.then_some(prt_formats::clustered::CompressionSettings {
            error_target: 0.1,
            cluster_vertices: Some(4),
            max_light_rank: 8,
            max_element_rank: 8,
            max_vertex_rank: 3,
        }),
        ..Default::default()
    };
    let path = out.join(format!("vertex-{compressed}.prtbake"));
    bake_vertex(&scene, &[], &[], &opts, &path, None)?;
    Ok(std::fs::read(&path)?)
}

fn tiny_bake(
    scenes: &Path,
    out: &Path,
    scene: &str,
    (width, height): (u32, u32),
    precision: Precision,
    compress_rank: Option<usize>,
) -> anyhow::Result<Vec<u8>> {
    let config_path = scenes.join(scene).join("bake.toml");
    let config = prt_bake::config::BakeConfig::from_file(&config_path)?;
    let scene_data = load_scene(&config, &Silent)?;
    let mut families: Vec<Family> = Vec::new();
    for m in &scene_data.materials {
        if m.editable && m.brdf.family != Family::Diffuse && !families.contains(&m.brdf.family) {
            families.push(m.brdf.family);
        }
    }
    let mut bases = Vec::new();
    for f in families {
        let mut cfg = BasisConfig::new(f, 3)?;
        cfg.grid = AngularGrid {
            n_theta_i: 6,
            n_theta_o: 5,
            n_phi: 3,
        };
        cfg.param_samples = 8;
        bases.push(BasisBuilder::new(cfg)?.build(3)?.to_persisted());
    }
    let layout = SlotLayout::new(&scene_data, &bases)?;
    let opts = PixelBakeOptions {
        width,
        height,
        spp: 2,
        emission_oversampling: config.emission_oversampling,
        reflections: config.reflections,
        seed: 7,
        precision,
        max_memory: None,
        compress_rank,
    };
    let baked = prt_bake::pixel::bake(&scene_data, &layout, &opts, None)
        .with_context(|| format!("baking {}", config_path.display()))?;
    let output = out.join(format!("{scene}-{width}x{height}.prtbake"));
    write_bake_file(&baked, &output, precision)?;
    Ok(std::fs::read(&output)?)
}

/// Container files that exercise the reader beyond what the baker writes.
fn writer_seeds() -> anyhow::Result<Vec<Vec<u8>>> {
    let mut out = Vec::new();
    out.push(BakeWriter::new().to_bytes()?);
    let f32s = [0.25f32, -3.0, 1e30, 0.0, 7.5];
    let u32s = [0u32, 1, 4_000_000_000];
    let u16s = [1u16, 65535, 3];
    let i32s = [-1i32, 2, i32::MIN];
    let u8s = [1u8, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13];
    // 1.0, -2.0 and 0.5 as little-endian f16 bit patterns.
    let f16s = [0x00u8, 0x3C, 0x00, 0xC0, 0x00, 0x38];
    // Declared after the data it borrows: a writer may hold streamed sources, which borrow too.
    let mut w = BakeWriter::new();
    w.set_metadata(serde_json::json!({"camera": {"fov": 45.0}, "list": [1, 2, 3]}));
    w.add_u8("mask", &[13], &u8s)?;
    w.add_f32("t0", &[5], &f32s)?;
    w.add_u32("idx", &[3], &u32s)?;
    w.add_u16("u16", &[1, 3], &u16s)?;
    w.add_i32("i32", &[3, 1], &i32s)?;
    w.add_tensor("f16", Dtype::F16, &[3], &f16s[..])?;
    w.add_f32("scalar", &[], &f32s[..1])?;
    w.add_f32("empty", &[0], &[])?;
    w.add_f32("empty2", &[2, 0, 3], &[])?;
    out.push(w.to_bytes()?);
    Ok(out)
}

/// A bake file split into its JSON header and data section.
struct Parts {
    header: Map<String, Value>,
    data: Vec<u8>,
}

fn split(bytes: &[u8]) -> Option<Parts> {
    let n = u64::from_le_bytes(*bytes.first_chunk::<8>()?);
    let end = 8usize.checked_add(usize::try_from(n).ok()?)?;
    let header = std::str::from_utf8(bytes.get(8..end)?).ok()?;
    let header = serde_json::from_str(header).ok()?;
    Some(Parts {
        header,
        data: bytes[end..].to_vec(),
    })
}

/// The file for a header and data section; `align` pads the header with spaces so the data
/// starts on a 16-byte boundary, as the writer does.
fn assemble(header: &Map<String, Value>, data: &[u8], align: bool) -> Vec<u8> {
    let mut h = Value::Object(header.clone()).to_string().into_bytes();
    if align {
        let pad = (16 - (8 + h.len()) % 16) % 16;
        h.resize(h.len() + pad, b' ');
    }
    let mut out = Vec::with_capacity(8 + h.len() + data.len());
    out.extend_from_slice(&(h.len() as u64).to_le_bytes());
    out.extend_from_slice(&h);
    out.extend_from_slice(data);
    out
}

/// A tensor entry's `(begin, end)` when both are integers inside the data section.
fn range_of(entry: &Value, data_len: usize) -> Option<(usize, usize)> {
    let o = entry.get("data_offsets")?.as_array()?;
    let (b, e) = (o.first()?.as_u64()?, o.get(1)?.as_u64()?);
    let (b, e) = (usize::try_from(b).ok()?, usize::try_from(e).ok()?);
    (b <= e && e <= data_len).then_some((b, e))
}

/// Recomputes the tensor checksums (`__metadata__.crc32`) and the header checksum
/// (`__metadata__.header_crc32`) after a mutation, as the writer would, so that the reader's
/// checks behind the CRCs see the input. The header digest is re-implemented from its
/// specification (docs/format.md, section 3) rather than taken from `prt-formats`, where it is
/// private; [`check_fixup`] confirms at startup that both agree on every seed.
fn fix_checksums(header: &mut Map<String, Value>, data: &[u8]) {
    let mut crcs: BTreeMap<String, String> = BTreeMap::new();
    for (name, entry) in header.iter() {
        if name == "__metadata__" || name.starts_with("__pad") {
            continue;
        }
        if let Some((b, e)) = range_of(entry, data.len()) {
            crcs.insert(
                name.clone(),
                format!("{:08x}", crc32fast::hash(&data[b..e])),
            );
        }
    }
    let Some(Value::Object(meta)) = header.get_mut("__metadata__") else {
        return;
    };
    if let Ok(text) = serde_json::to_string(&crcs) {
        meta.insert("crc32".into(), Value::String(text));
    }
    if let Some(crc) = header_digest(header) {
        if let Some(Value::Object(meta)) = header.get_mut("__metadata__") {
            meta.insert("header_crc32".into(), Value::String(format!("{crc:08x}")));
        }
    }
}

/// CRC-32 of the canonical header digest (docs/format.md, section 3), or `None` when the
/// header is too broken for the reader to get that far anyway.
fn header_digest(header: &Map<String, Value>) -> Option<u32> {
    fn put_u64(h: &mut crc32fast::Hasher, v: u64) {
        h.update(&v.to_le_bytes());
    }
    fn put_str(h: &mut crc32fast::Hasher, s: &str) {
        put_u64(h, s.len() as u64);
        h.update(s.as_bytes());
    }
    let mut h = crc32fast::Hasher::new();
    h.update(b"prt-bake header digest v1\0");
    let meta = header.get("__metadata__")?.as_object()?;
    let mut entries: Vec<(&str, &str)> = Vec::new();
    for (k, v) in meta {
        if k != "header_crc32" {
            entries.push((k, v.as_str()?));
        }
    }
    entries.sort_unstable();
    put_u64(&mut h, entries.len() as u64);
    for (k, v) in entries {
        put_str(&mut h, k);
        put_str(&mut h, v);
    }
    let mut tensors: Vec<(&str, &Value)> = header
        .iter()
        .filter(|(k, _)| *k != "__metadata__")
        .map(|(k, v)| (k.as_str(), v))
        .collect();
    tensors.sort_unstable_by(|a, b| a.0.cmp(b.0));
    put_u64(&mut h, tensors.len() as u64);
    for (name, t) in tensors {
        put_str(&mut h, name);
        put_str(&mut h, t.get("dtype")?.as_str()?);
        let shape = t.get("shape")?.as_array()?;
        put_u64(&mut h, shape.len() as u64);
        for d in shape {
            put_u64(&mut h, d.as_u64()?);
        }
        let offsets = t.get("data_offsets")?.as_array()?;
        put_u64(&mut h, offsets.first()?.as_u64()?);
        put_u64(&mut h, offsets.get(1)?.as_u64()?);
    }
    Some(h.finalize())
}

/// Confirms that [`fix_checksums`] leaves a valid file's checksums as they are (so it computes
/// what the reader checks).
fn check_fixup(seed: &[u8]) -> anyhow::Result<()> {
    let parts = split(seed).context("a seed does not split into header and data")?;
    let mut fixed = parts.header.clone();
    fix_checksums(&mut fixed, &parts.data);
    for key in ["crc32", "header_crc32"] {
        let a = parts.header.get("__metadata__").and_then(|m| m.get(key));
        let b = fixed.get("__metadata__").and_then(|m| m.get(key));
        anyhow::ensure!(
            a == b,
            "the fuzzer's checksum fix-up disagrees with prt-formats on `{key}` ({a:?} vs \
             {b:?}): docs/format.md section 3 and this harness have drifted apart"
        );
    }
    Ok(())
}

/// The file laid out again by the writer after one tensor is resized (a dimension changed,
/// its data cut, or extended by repeating it): so a shape can change together with its data,
/// the offsets of the tensors after it and every checksum, and the reader's schema checks see
/// a consistent file with, say, a group of one more pixel or a row of another length.
fn resize_tensor(header: &Map<String, Value>, data: &[u8], d: &mut Dice) -> Option<Vec<u8>> {
    let meta_text = header.get("__metadata__")?.get("metadata")?.as_str()?;
    let metadata: Value = serde_json::from_str(meta_text).ok()?;
    // (data offset, name, dtype, shape, bytes)
    type Tensor<'a> = (usize, &'a str, Dtype, Vec<usize>, &'a [u8]);
    let mut tensors: Vec<Tensor> = Vec::new();
    for (name, entry) in header {
        if name.starts_with("__") {
            continue;
        }
        let dtype = Dtype::from_name(entry.get("dtype")?.as_str()?)?;
        let shape = entry
            .get("shape")?
            .as_array()?
            .iter()
            .map(|v| v.as_u64().and_then(|v| usize::try_from(v).ok()))
            .collect::<Option<Vec<usize>>>()?;
        let (b, e) = range_of(entry, data.len())?;
        tensors.push((b, name, dtype, shape, &data[b..e]));
    }
    if tensors.is_empty() {
        return None;
    }
    tensors.sort_by_key(|t| t.0);
    let i = d.below(tensors.len());
    let (_, _, dtype, shape, bytes) = &mut tensors[i];
    if shape.is_empty() {
        shape.push(1);
    }
    let k = d.below(shape.len());
    let s = shape[k];
    shape[k] = *d.pick(&[s + 1, s.saturating_sub(1), s * 2, s / 2, 0, 1]);
    let len = shape
        .iter()
        .try_fold(dtype.size(), |acc, &x| acc.checked_mul(x))
        .filter(|&n| n <= MAX_LEN)?;
    let resized: Vec<u8> = if bytes.is_empty() {
        vec![0; len]
    } else {
        bytes.iter().copied().cycle().take(len).collect()
    };
    let mut w = BakeWriter::new();
    w.set_metadata(metadata);
    for (j, (_, name, dtype, shape, bytes)) in tensors.iter().enumerate() {
        let data = if j == i { &resized[..] } else { bytes };
        w.add_tensor(name, *dtype, shape, data).ok()?;
    }
    w.to_bytes().ok()
}

impl BakeFileTarget {
    fn structured(&self, parent: &[u8], other: &[u8], d: &mut Dice) -> Option<Vec<u8>> {
        let Parts {
            mut header,
            mut data,
        } = split(parent)?;
        match d.below(10) {
            // The container header.
            0..=2 => {
                let mut v = Value::Object(header);
                for _ in 0..1 + d.below(2) {
                    json_mut::mutate(&mut v, d, DICT);
                }
                header = match v {
                    Value::Object(m) => m,
                    other => return Some(other.to_string().into_bytes()),
                };
            }
            // The bake schema's metadata (a JSON text inside `__metadata__.metadata`).
            3..=5 => {
                let meta = header.get_mut("__metadata__")?.as_object_mut()?;
                let text = meta.get("metadata")?.as_str()?;
                let mut v: Value = serde_json::from_str(text).ok()?;
                for _ in 0..1 + d.below(3) {
                    json_mut::mutate(&mut v, d, DICT);
                }
                meta.insert("metadata".into(), Value::String(v.to_string()));
            }
            // A tensor resized, the file laid out again by the writer.
            6 => return resize_tensor(&header, &data, d),
            // One tensor's bytes.
            7 | 8 => {
                let ranges: Vec<(usize, usize)> = header
                    .iter()
                    .filter(|(k, _)| *k != "__metadata__")
                    .filter_map(|(_, e)| range_of(e, data.len()))
                    .filter(|(b, e)| e > b)
                    .collect();
                if ranges.is_empty() {
                    return None;
                }
                let (b, e) = *d.pick(&ranges);
                let slice = &mut data[b..e];
                for _ in 0..1 + d.below(4) {
                    if slice.len() >= 4 && d.chance(0.6) {
                        let i = 4 * d.below(slice.len() / 4);
                        slice[i..i + 4].copy_from_slice(&d.pick(&U32S).to_le_bytes());
                    } else {
                        let mut bytes = slice.to_vec();
                        byte_op(&mut bytes, other, d);
                        let n = bytes.len().min(slice.len());
                        slice[..n].copy_from_slice(&bytes[..n]);
                    }
                }
            }
            // Reshape or retype a tensor, keeping its byte length.
            _ => {
                let names: Vec<String> = header
                    .keys()
                    .filter(|k| *k != "__metadata__")
                    .cloned()
                    .collect();
                if names.is_empty() {
                    return None;
                }
                let name = d.pick(&names).clone();
                let entry = header.get_mut(&name)?.as_object_mut()?;
                let bytes =
                    range_of(&Value::Object(entry.clone()), data.len()).map_or(0, |(b, e)| e - b);
                let dtype = *d.pick(&["F32", "F16", "U32", "U16", "U8", "I32"]);
                let size = Dtype::from_name(dtype).map_or(1, Dtype::size);
                let n = bytes / size;
                let shape: Vec<u64> = match d.below(4) {
                    0 => vec![n as u64],
                    1 => vec![1, n as u64],
                    2 if n > 1 => vec![2, (n / 2) as u64],
                    _ => vec![n as u64, 1],
                };
                entry.insert("dtype".into(), Value::from(dtype));
                entry.insert("shape".into(), Value::from(shape));
            }
        }
        if d.chance(0.9) {
            fix_checksums(&mut header, &data);
        }
        Some(assemble(&header, &data, d.chance(0.9)))
    }
}

impl Target for BakeFileTarget {
    fn name(&self) -> &'static str {
        "bake-file"
    }

    fn seeds(&mut self) -> anyhow::Result<Vec<Vec<u8>>> {
        let out = self.dir.path().join("seeds");
        std::fs::create_dir_all(&out)?;
        let s = &self.scenes;
        let mut seeds = vec![
            tiny_bake(s, &out, "furnace", (6, 5), Precision::F32, None)?,
            tiny_bake(s, &out, "furnace", (4, 4), Precision::F16, Some(2))?,
            tiny_bake(s, &out, "cornell", (5, 4), Precision::F32, Some(1))?,
            tiny_bake(s, &out, "ring", (4, 3), Precision::F16, None)?,
            // Tall enough for several of the runtime's bands of rows.
            tiny_bake(s, &out, "cornell", (3, 20), Precision::F32, None)?,
            // Per vertex, T1 compressed (clustered Tucker) and dense.
            tiny_vertex_bake(&out, true)?,
            tiny_vertex_bake(&out, false)?,
        ];
        seeds.extend(writer_seeds()?);
        for seed in &seeds {
            check_fixup(seed)?;
        }
        seeds.extend(crate::targets::read_corpus_files(&self.extra)?);
        Ok(seeds)
    }

    fn mutate(&mut self, parent: &[u8], other: &[u8], d: &mut Dice) -> Vec<u8> {
        if d.chance(0.75) {
            if let Some(child) = self.structured(parent, other, d) {
                if child.len() <= MAX_LEN {
                    return child;
                }
            }
        }
        let mut child = parent.to_vec();
        havoc(&mut child, other, d, MAX_LEN);
        child
    }

    fn run(&mut self, input: &[u8]) -> Result<String, String> {
        let dir = self.dir.path();
        let path = &self.path;
        if let Err(e) = std::fs::write(path, input) {
            return Ok(outcome("write", &e.to_string(), dir));
        }
        // The container reader alone: every accessor on every tensor.
        let file = match BakeFile::open_unchecked(path) {
            Ok(f) => f,
            Err(e) => return Ok(outcome("container", &e.to_string(), dir)),
        };
        let names: Vec<String> = file.tensor_names().map(str::to_string).collect();
        for name in &names {
            if let Ok(t) = file.tensor(name) {
                let _ = (
                    t.shape(),
                    t.num_elements(),
                    t.file_offset(),
                    t.bytes().len(),
                );
                let _ = t.as_f32().map(<[f32]>::len);
                let _ = t.as_f16().map(<[_]>::len);
                let _ = t.as_u32().map(<[u32]>::len);
                let _ = t.as_u16().map(<[u16]>::len);
                let _ = t.as_u8().map(<[u8]>::len);
                let _ = t.as_i32().map(<[i32]>::len);
                let _ = t.to_f32_vec().map(|v| v.len());
                let _ = t.require_shape(&[1, 2]);
            }
        }
        let _ = file.tensor("no such tensor").map(|t| t.num_elements());
        let _ = (
            file.metadata(),
            file.schema_version(),
            file.file_bytes().len(),
        );
        if let Err(e) = file.verify_checksums() {
            return Ok(outcome("verify", &e.to_string(), dir));
        }
        drop(file);

        // The runtime: open the kind the file names, render, edit every editable material,
        // render again.
        let r = match prt_runtime::open(path) {
            Ok(Relighter::Pixel(r)) => r,
            Ok(Relighter::Vertex(r)) => return Ok(relight_vertex(r, dir)),
            Err(e) => return Ok(outcome("relighter", &e.to_string(), dir)),
        };
        Ok(relight_pixel(r, dir))
    }
}

/// The per-pixel runtime on a (mutated) file: render both variants, edit every editable
/// material with values at the ends of their ranges, render again on the portable kernel.
fn relight_pixel(mut r: PixelRelighter, dir: &Path) -> String {
    let render = |r: &mut PixelRelighter| -> Result<(), String> {
        r.set_variant(Variant::Full).map_err(|e| e.to_string())?;
        r.render().map_err(|e| e.to_string())?;
        if r.has_compressed() {
            r.set_variant(Variant::Compressed)
                .map_err(|e| e.to_string())?;
            r.render().map_err(|e| e.to_string())?;
        }
        Ok(())
    };
    if let Err(e) = render(&mut r) {
        return outcome("render", &e, dir);
    }
    let materials = r.materials();
    let mut edits = 0;
    for m in &materials {
        let _ = r.params(&m.name);
        let mut values = vec![OverrideValue::Kd([0.9, 0.1, 0.0])];
        match m.family {
            Family::BlinnPhong => values.push(OverrideValue::Shininess(1e6)),
            Family::Ggx => values.push(OverrideValue::Alpha(1e-4)),
            Family::Diffuse => {}
        }
        if m.family != Family::Diffuse {
            values.push(OverrideValue::Ks([2.0, 0.0, 0.5]));
        }
        for value in values {
            if r.set_params(&m.name, &[value]).is_ok() {
                edits += 1;
            }
        }
    }
    let _ = r.coefficients();
    r.set_kernel(Kernel::Scalar);
    if let Err(e) = render(&mut r) {
        return outcome("render after edits", &e, dir);
    }
    format!(
        "ok: relit, {} materials, {} groups, compressed {}, {} edits",
        materials.len().min(4),
        r.meta().groups.len().min(4),
        r.has_compressed(),
        edits.min(4)
    )
}

/// The per-vertex runtime on a (mutated) file: render from the baked camera, turn the light,
/// edit every editable material, render again.
fn relight_vertex(mut r: VertexRelighter, dir: &Path) -> String {
    let mut image = vec![0.0f32; 3 * 6 * 5];
    let first = r.set_size(6, 5).and_then(|()| r.render_into(&mut image));
    if let Err(e) = first {
        return outcome("vertex render", &e.to_string(), dir);
    }
    let _ = r.set_environment_rotation(40.0);
    for m in r.materials() {
        let _ = r.set_params(&m.name, &[OverrideValue::Kd([0.9, 0.1, 0.0])]);
    }
    let _ = r.vertex_incident(0);
    if let Err(e) = r.render_into(&mut image) {
        return outcome("vertex render after edits", &e.to_string(), dir);
    }
    format!(
        "ok: vertex relit, {} groups, compressed {}",
        r.meta().groups.len().min(4),
        r.meta().groups.iter().any(|g| g.compression.is_some())
    )
}
