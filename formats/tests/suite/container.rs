//! Bake-file container: round trips, zero-copy access, atomic writes, and clear errors (never
//! panics) on corrupt, truncated or foreign files.

use std::collections::BTreeMap;
use std::fs;
use std::path::{Path, PathBuf};

use half::f16;
use prt_formats::container::{keys, write_file_atomic, MAX_HEADER_LEN};
use prt_formats::{BakeFile, BakeWriter, Dtype, FormatError, SCHEMA_VERSION, TENSOR_ALIGN};
use serde_json::json;

/// A fresh, empty scratch folder per test (tests run in parallel).
fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("prt-formats-{}-{name}", std::process::id()));
    let _ = fs::remove_dir_all(&dir);
    fs::create_dir_all(&dir).unwrap();
    dir
}

struct Sample {
    f32s: Vec<f32>,
    f16s: Vec<f16>,
    u32s: Vec<u32>,
    u16s: Vec<u16>,
    u8s: Vec<u8>,
    i32s: Vec<i32>,
}

fn sample() -> Sample {
    Sample {
        f32s: (0..24).map(|i| i as f32 * 0.25 - 3.0).collect(),
        f16s: (0..5).map(|i| f16::from_f32(i as f32 * 1.5)).collect(),
        u32s: vec![0, 1, u32::MAX],
        u16s: (0..7).map(|i| i * 1000).collect(),
        u8s: (0..13).collect(),
        i32s: vec![i32::MIN, -1, 0, i32::MAX],
    }
}

fn sample_writer(s: &Sample) -> BakeWriter<'_> {
    let mut w = BakeWriter::new();
    // Sizes chosen so that most tensors need padding after them (13 u8, 7 u16, 5 f16, 3 u32).
    w.add_u8("mask", &[13], &s.u8s).unwrap();
    w.add_f32("t0", &[2, 3, 4], &s.f32s).unwrap();
    w.add_f16("half", &[5], &s.f16s).unwrap();
    w.add_u32("ids", &[3, 1], &s.u32s).unwrap();
    w.add_u16("small", &[7], &s.u16s).unwrap();
    w.add_i32("signed", &[2, 2], &s.i32s).unwrap();
    w.add_f32("scalar", &[], &s.f32s[..1]).unwrap();
    w.add_f32("empty", &[0, 3], &[]).unwrap();
    w.set_metadata(json!({
        "materials": [{"name": "bunny", "family": "blinn-phong"}, {"name": "wall.left"}],
        "camera": {"fov": 45.0, "res": [64, 48]},
        "note": "quotes \" and unicode \u{e9} survive",
    }));
    w
}

#[test]
fn round_trip_every_dtype() {
    let dir = scratch("roundtrip");
    let path = dir.join("a.prtbake");
    let s = sample();
    let w = sample_writer(&s);
    w.write_atomic(&path).unwrap();

    let f = BakeFile::open(&path).unwrap();
    assert_eq!(f.schema_version(), SCHEMA_VERSION);
    assert_eq!(f.path(), path.as_path());
    assert_eq!(
        f.tensor_names().collect::<Vec<_>>(),
        ["mask", "t0", "half", "ids", "small", "signed", "scalar", "empty"],
        "file order = insertion order, padding hidden"
    );
    assert_eq!(f.metadata()["camera"]["res"], json!([64, 48]));
    assert_eq!(f.metadata()["materials"][1]["name"], "wall.left");
    assert_eq!(f.metadata()["note"], "quotes \" and unicode \u{e9} survive");

    assert_eq!(f.tensor("mask").unwrap().as_u8().unwrap(), &s.u8s[..]);
    let t0 = f.tensor("t0").unwrap();
    assert_eq!(t0.dtype(), Dtype::F32);
    assert_eq!(t0.shape(), &[2, 3, 4]);
    assert_eq!(t0.num_elements(), 24);
    assert_eq!(t0.as_f32().unwrap(), &s.f32s[..]);
    assert_eq!(t0.to_f32_vec().unwrap(), s.f32s);
    assert_eq!(f.tensor("half").unwrap().as_f16().unwrap(), &s.f16s[..]);
    assert_eq!(
        f.tensor("half").unwrap().to_f32_vec().unwrap(),
        s.f16s.iter().map(|h| h.to_f32()).collect::<Vec<_>>()
    );
    assert_eq!(f.tensor("ids").unwrap().as_u32().unwrap(), &s.u32s[..]);
    assert_eq!(f.tensor("small").unwrap().as_u16().unwrap(), &s.u16s[..]);
    assert_eq!(f.tensor("signed").unwrap().as_i32().unwrap(), &s.i32s[..]);
    let scalar = f.tensor("scalar").unwrap();
    assert_eq!(scalar.shape(), &[] as &[usize]);
    assert_eq!(scalar.as_f32().unwrap(), &[-3.0]);
    let empty = f.tensor("empty").unwrap();
    assert_eq!(empty.shape(), &[0, 3]);
    assert!(empty.as_f32().unwrap().is_empty());

    // The same bytes come out of to_bytes (the writer is deterministic).
    assert_eq!(fs::read(&path).unwrap(), w.to_bytes().unwrap());
    assert_eq!(w.to_bytes().unwrap(), sample_writer(&s).to_bytes().unwrap());
    assert_eq!(w.file_len().unwrap(), fs::metadata(&path).unwrap().len());
    fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn typed_access_is_zero_copy_and_aligned() {
    let dir = scratch("zerocopy");
    let path = dir.join("a.prtbake");
    let s = sample();
    sample_writer(&s).write_atomic(&path).unwrap();
    let f = BakeFile::open(&path).unwrap();
    let file = f.file_bytes().as_ptr_range();
    let names: Vec<String> = f.tensor_names().map(String::from).collect();
    for name in names {
        let t = f.tensor(&name).unwrap();
        assert_eq!(t.file_offset() % TENSOR_ALIGN, 0, "{name} offset");
        assert_eq!(
            t.bytes().as_ptr() as usize % TENSOR_ALIGN,
            0,
            "{name} pointer"
        );
        assert!(file.contains(&t.bytes().as_ptr()) || t.bytes().is_empty());
        // The bytes are the file's bytes at the stated offset: a view, not a copy.
        assert_eq!(
            t.bytes().as_ptr(),
            f.file_bytes()[t.file_offset()..].as_ptr(),
            "{name}"
        );
    }
    let t0 = f.tensor("t0").unwrap();
    assert_eq!(
        t0.as_f32().unwrap().as_ptr().cast::<u8>(),
        t0.bytes().as_ptr()
    );

    // The data section starts aligned and the header is padded with spaces.
    let bytes = f.file_bytes();
    let n = u64::from_le_bytes(bytes[..8].try_into().unwrap()) as usize;
    assert_eq!((8 + n) % TENSOR_ALIGN, 0);
    let header = std::str::from_utf8(&bytes[8..8 + n]).unwrap();
    assert!(header.starts_with('{'));
    assert!(header.trim_end().ends_with('}'));
    fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn header_metadata_keys_are_as_documented() {
    let s = sample();
    let bytes = sample_writer(&s).to_bytes().unwrap();
    let n = u64::from_le_bytes(bytes[..8].try_into().unwrap()) as usize;
    let header: serde_json::Value = serde_json::from_slice(&bytes[8..8 + n]).unwrap();
    let meta = header["__metadata__"].as_object().unwrap();
    assert_eq!(meta[keys::FORMAT], "prt-bake");
    assert_eq!(meta[keys::SCHEMA_VERSION], SCHEMA_VERSION.to_string());
    let crcs: BTreeMap<String, String> =
        serde_json::from_str(meta[keys::CRC32].as_str().unwrap()).unwrap();
    // One checksum per tensor, none for padding; each is the CRC-32 of the tensor's bytes.
    assert_eq!(crcs.len(), 8);
    let data = &bytes[8 + n..];
    for (name, crc) in &crcs {
        let offs = &header[name]["data_offsets"];
        let (b, e) = (
            offs[0].as_u64().unwrap() as usize,
            offs[1].as_u64().unwrap() as usize,
        );
        assert_eq!(*crc, format!("{:08x}", crc32fast::hash(&data[b..e])));
    }
    // The documented header digest reproduces header_crc32.
    assert_eq!(
        meta[keys::HEADER_CRC32].as_str().unwrap(),
        format!("{:08x}", documented_digest(&header))
    );
    // Padding tensors are U8, 1-D, shorter than the alignment.
    let pads: Vec<_> = header
        .as_object()
        .unwrap()
        .iter()
        .filter(|(k, _)| k.starts_with("__pad"))
        .collect();
    assert!(!pads.is_empty());
    for (_, p) in pads {
        assert_eq!(p["dtype"], "U8");
        assert!(p["shape"][0].as_u64().unwrap() < TENSOR_ALIGN as u64);
    }
}

/// The header digest exactly as `docs/format.md` specifies it (independent of the crate code).
fn documented_digest(header: &serde_json::Value) -> u32 {
    let mut buf = b"prt-bake header digest v1\0".to_vec();
    let put_u64 = |b: &mut Vec<u8>, v: u64| b.extend_from_slice(&v.to_le_bytes());
    let put_str = |b: &mut Vec<u8>, s: &str| {
        b.extend_from_slice(&(s.len() as u64).to_le_bytes());
        b.extend_from_slice(s.as_bytes());
    };
    let obj = header.as_object().unwrap();
    let meta: BTreeMap<&String, &str> = obj["__metadata__"]
        .as_object()
        .unwrap()
        .iter()
        .filter(|(k, _)| *k != "header_crc32")
        .map(|(k, v)| (k, v.as_str().unwrap()))
        .collect();
    put_u64(&mut buf, meta.len() as u64);
    for (k, v) in meta {
        put_str(&mut buf, k);
        put_str(&mut buf, v);
    }
    let tensors: BTreeMap<&String, &serde_json::Value> =
        obj.iter().filter(|(k, _)| *k != "__metadata__").collect();
    put_u64(&mut buf, tensors.len() as u64);
    for (name, t) in tensors {
        put_str(&mut buf, name);
        put_str(&mut buf, t["dtype"].as_str().unwrap());
        let shape = t["shape"].as_array().unwrap();
        put_u64(&mut buf, shape.len() as u64);
        for d in shape {
            put_u64(&mut buf, d.as_u64().unwrap());
        }
        put_u64(&mut buf, t["data_offsets"][0].as_u64().unwrap());
        put_u64(&mut buf, t["data_offsets"][1].as_u64().unwrap());
    }
    crc32fast::hash(&buf)
}

/// A raw safetensors file from a header and data section (no padding, no checks).
fn raw_file(header: &serde_json::Value, data: &[u8]) -> Vec<u8> {
    let h = header.to_string();
    let mut out = (h.len() as u64).to_le_bytes().to_vec();
    out.extend_from_slice(h.as_bytes());
    out.extend_from_slice(data);
    out
}

/// A complete, valid PRT header for hand-made layouts (checksums filled in).
fn valid_raw_file(tensors: &[(&str, &str, Vec<u64>, u64, u64)], data: &[u8]) -> Vec<u8> {
    let mut header = serde_json::Map::new();
    let mut crcs = BTreeMap::new();
    for (name, dtype, shape, b, e) in tensors {
        header.insert(
            name.to_string(),
            json!({"dtype": dtype, "shape": shape, "data_offsets": [b, e]}),
        );
        crcs.insert(
            name.to_string(),
            format!("{:08x}", crc32fast::hash(&data[*b as usize..*e as usize])),
        );
    }
    header.insert(
        "__metadata__".into(),
        json!({
            "format": "prt-bake",
            "schema_version": SCHEMA_VERSION.to_string(),
            "metadata": "{}",
            "crc32": serde_json::to_string(&crcs).unwrap(),
        }),
    );
    let mut header = serde_json::Value::Object(header);
    let digest = documented_digest(&header);
    header["__metadata__"]["header_crc32"] = json!(format!("{digest:08x}"));
    raw_file(&header, data)
}

fn open_bytes(dir: &Path, bytes: &[u8]) -> Result<BakeFile, FormatError> {
    let path = dir.join("x.prtbake");
    fs::write(&path, bytes).unwrap();
    BakeFile::open(&path)
}

fn open_err(dir: &Path, bytes: &[u8]) -> String {
    let e = open_bytes(dir, bytes).expect_err("expected an error");
    let msg = e.to_string();
    assert!(
        msg.contains(&dir.join("x.prtbake").display().to_string()),
        "error does not name the file: {msg}"
    );
    msg
}

/// A scene, a config, an image or junk opened as a bake file (`relight scene.gltf`): the error
/// says the file is not a bake file and what it looks like, rather than "truncated" with a
/// header length read from the file's text. The project's own files, as a user would name them.
#[test]
fn files_that_are_not_bakes_say_what_they_look_like() {
    let scenes = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes");
    let dir = scratch("foreign");
    let png = dir.join("image.png");
    prt_formats::write_png(&png, 2, 1, &[[0.5; 3], [1.0; 3]], 1.0).unwrap();
    let junk = dir.join("junk.bin");
    fs::write(&junk, [0xa5u8; 64]).unwrap();
    for (file, what) in [
        (
            scenes.join("cornell/cornell.gltf"),
            "a glTF JSON scene (.gltf)",
        ),
        (
            scenes.join("furnace/furnace.glb"),
            "a binary glTF scene (.glb)",
        ),
        (scenes.join("cornell/bake.toml"), "a TOML text file"),
        (scenes.join("envmaps/sky.exr"), "an OpenEXR image"),
        (scenes.join("README.md"), "a text file"),
        (png, "a PNG image"),
        (junk, "unrecognised binary data (first bytes a5 a5"),
    ] {
        let e = BakeFile::open(&file).expect_err("not a bake");
        assert!(
            matches!(e, FormatError::NotABakeFile { .. }),
            "{}: {e:?}",
            file.display()
        );
        let msg = e.to_string();
        let name = file.display().to_string();
        assert!(
            msg.contains(&name) && msg.contains("not a PRT bake file") && msg.contains(what),
            "{name}: {msg}"
        );
        assert!(!msg.contains("truncated"), "{msg}");
    }
    fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn files_from_other_writers_with_misaligned_tensors_are_read_safely() {
    let dir = scratch("misaligned");
    // A U8 tensor of 3 bytes followed by an F32 at data offset 3: valid safetensors, but not
    // a layout our writer produces.
    let mut data = vec![1u8, 2, 3];
    data.extend_from_slice(&1.5f32.to_le_bytes());
    let bytes = valid_raw_file(
        &[("a", "U8", vec![3], 0, 3), ("b", "F32", vec![1], 3, 7)],
        &data,
    );
    let f = open_bytes(&dir, &bytes).unwrap();
    let b = f.tensor("b").unwrap();
    let msg = b.as_f32().unwrap_err().to_string();
    assert!(msg.contains("'b'") && msg.contains("aligned"), "{msg}");
    // The copying accessor still works.
    assert_eq!(b.to_f32_vec().unwrap(), vec![1.5]);
    assert_eq!(f.tensor("a").unwrap().as_u8().unwrap(), &[1, 2, 3]);
    fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn clear_errors_for_foreign_truncated_and_wrong_files() {
    let dir = scratch("errors");
    let p = dir.join("x.prtbake");
    let pname = p.display().to_string();

    // Missing file, folder.
    let e = BakeFile::open(dir.join("nope.prtbake"))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("nope.prtbake") && e.contains("cannot open"),
        "{e}"
    );
    let e = BakeFile::open(&dir).unwrap_err().to_string();
    assert!(e.contains("not a regular file"), "{e}");

    // Too short.
    for len in [0usize, 1, 7] {
        let e = open_err(&dir, &vec![0u8; len]);
        assert!(e.contains("too short"), "{e}");
    }
    // Header length beyond the file.
    let mut b = 1000u64.to_le_bytes().to_vec();
    b.extend_from_slice(b"{}");
    let e = open_err(&dir, &b);
    assert!(e.contains("truncated") && e.contains("1000"), "{e}");
    let b = u64::MAX.to_le_bytes();
    assert!(open_err(&dir, &b).contains("truncated"));

    // Bad JSON, non-UTF-8.
    let e = open_err(&dir, &raw_bytes(b"{\"a\": [1, 2", &[]));
    assert!(e.contains("bad JSON"), "{e}");
    let e = open_err(&dir, &raw_bytes(b"{\"a\xff\": 1}", &[]));
    assert!(e.contains("UTF-8"), "{e}");
    let e = open_err(&dir, &raw_bytes(b"[1, 2]", &[]));
    assert!(e.contains("bad JSON"), "{e}");

    // A plain safetensors file, another format, another version.
    let plain = raw_file(
        &json!({"w": {"dtype": "F32", "shape": [1], "data_offsets": [0, 4]}}),
        &[0; 4],
    );
    let e = open_err(&dir, &plain);
    assert!(
        e.contains("not a PRT bake file") && e.contains("missing"),
        "{e}"
    );
    let other = raw_file(&json!({"__metadata__": {"format": "pt"}}), &[]);
    let e = open_err(&dir, &other);
    assert!(e.contains("'pt'") && e.contains("prt-bake"), "{e}");
    let v2 = raw_file(
        &json!({"__metadata__": {"format": "prt-bake", "schema_version": "2"}}),
        &[],
    );
    let e = open_err(&dir, &v2);
    assert!(
        e.contains("schema version 2") && e.contains(&format!("version {SCHEMA_VERSION}")),
        "{e}"
    );
    let vx = raw_file(
        &json!({"__metadata__": {"format": "prt-bake", "schema_version": "one"}}),
        &[],
    );
    assert!(open_err(&dir, &vx).contains("'one'"));

    // A tensor whose range runs past the end of the file (truncated data).
    let meta = json!({"format": "prt-bake", "schema_version": SCHEMA_VERSION.to_string()});
    let trunc = raw_file(
        &json!({"__metadata__": meta, "t1": {"dtype": "F32", "shape": [4], "data_offsets": [0, 16]}}),
        &[0; 10],
    );
    let e = open_err(&dir, &trunc);
    assert!(
        e.contains("'t1'") && e.contains("0..16") && e.contains("10 bytes"),
        "{e}"
    );
    // dtype/shape inconsistent with the byte range; unsupported dtype; bad shape.
    let bad = raw_file(
        &json!({"__metadata__": meta, "t": {"dtype": "F32", "shape": [3], "data_offsets": [0, 16]}}),
        &[0; 16],
    );
    let e = open_err(&dir, &bad);
    assert!(e.contains("'t'") && e.contains("12 bytes"), "{e}");
    let bad = raw_file(
        &json!({"__metadata__": meta, "t": {"dtype": "F64", "shape": [2], "data_offsets": [0, 16]}}),
        &[0; 16],
    );
    assert!(open_err(&dir, &bad).contains("F64"));
    let bad = raw_file(
        &json!({"__metadata__": meta, "t": {"dtype": "U8", "shape": [-2], "data_offsets": [0, 2]}}),
        &[0; 2],
    );
    assert!(open_err(&dir, &bad).contains("non-negative"));
    let bad = raw_file(
        &json!({"__metadata__": meta,
                "t": {"dtype": "U8", "shape": [u64::MAX, u64::MAX, 4], "data_offsets": [0, 2]}}),
        &[0; 2],
    );
    assert!(open_err(&dir, &bad).contains("'t'"));
    // Gaps and trailing bytes.
    let gap = raw_file(
        &json!({"__metadata__": meta,
                "a": {"dtype": "U8", "shape": [2], "data_offsets": [0, 2]},
                "b": {"dtype": "U8", "shape": [2], "data_offsets": [4, 6]}}),
        &[0; 6],
    );
    assert!(open_err(&dir, &gap).contains("gap of 2 bytes before tensor 'b'"));
    let trailing = raw_file(
        &json!({"__metadata__": meta, "a": {"dtype": "U8", "shape": [2], "data_offsets": [0, 2]}}),
        &[0; 5],
    );
    assert!(open_err(&dir, &trailing).contains("3 bytes after the last tensor"));
    // Structurally fine but without checksums.
    let nocrc = raw_file(
        &json!({"__metadata__": meta, "a": {"dtype": "U8", "shape": [2], "data_offsets": [0, 2]}}),
        &[0; 2],
    );
    assert!(open_err(&dir, &nocrc).contains("crc32"));

    // Checksum mismatch in a tensor names the tensor; open_unchecked defers it.
    let s = sample();
    let good = sample_writer(&s).to_bytes().unwrap();
    let f = open_bytes(&dir, &good).unwrap();
    let off = f.tensor("t0").unwrap().file_offset();
    drop(f);
    let mut bad = good.clone();
    bad[off + 5] ^= 0x10;
    let e = open_err(&dir, &bad);
    assert!(e.contains("checksum mismatch in tensor 't0'"), "{e}");
    let f = BakeFile::open_unchecked(&p).unwrap();
    assert!(f.verify_tensor("mask").is_ok());
    assert!(f.verify_tensor("t0").is_err());
    assert!(f.verify_checksums().is_err());
    drop(f);

    // Corrupt metadata (still valid JSON, same length): caught by the header checksum.
    let needle = b"blinn-phong";
    let at = good
        .windows(needle.len())
        .position(|w| w == needle)
        .unwrap();
    let mut bad = good.clone();
    bad[at] = b'B';
    let e = open_err(&dir, &bad);
    assert!(e.contains("header checksum mismatch"), "{e}");

    // Missing tensor and wrong dtype name the tensor and the file.
    let f = open_bytes(&dir, &good).unwrap();
    let e = f.tensor("T0").unwrap_err().to_string();
    assert!(
        e.contains(&pname) && e.contains("no tensor named 'T0'") && e.contains("'t0'"),
        "{e}"
    );
    let e = f.tensor("t0").unwrap().as_u32().unwrap_err().to_string();
    assert!(
        e.contains(&pname) && e.contains("'t0'") && e.contains("F32") && e.contains("U32"),
        "{e}"
    );
    let e = f
        .tensor("ids")
        .unwrap()
        .to_f32_vec()
        .unwrap_err()
        .to_string();
    assert!(e.contains("F32 or F16"), "{e}");
    let e = f
        .tensor("t0")
        .unwrap()
        .require_shape(&[2, 3])
        .unwrap_err()
        .to_string();
    assert!(e.contains("[2, 3, 4]") && e.contains("[2, 3]"), "{e}");
    assert!(f.tensor("t0").unwrap().require_shape(&[2, 3, 4]).is_ok());
    drop(f);
    fs::remove_dir_all(&dir).unwrap();
}

fn raw_bytes(header: &[u8], data: &[u8]) -> Vec<u8> {
    let mut out = (header.len() as u64).to_le_bytes().to_vec();
    out.extend_from_slice(header);
    out.extend_from_slice(data);
    out
}

#[test]
fn every_truncation_and_byte_flip_is_an_error_never_a_panic() {
    let dir = scratch("fuzz");
    let data: Vec<f32> = (0..7).map(|i| i as f32).collect();
    let ids: Vec<u16> = vec![1, 2, 3];
    let mut w = BakeWriter::new();
    w.add_u16("ids", &[3], &ids).unwrap();
    w.add_f32("x.y", &[7], &data).unwrap();
    w.set_metadata(json!({"m": ["a", 1.5], "s": "esc\"aped"}));
    let good = w.to_bytes().unwrap();
    assert!(open_bytes(&dir, &good).is_ok());

    for len in 0..good.len() {
        assert!(
            open_bytes(&dir, &good[..len]).is_err(),
            "truncation to {len} bytes was accepted"
        );
    }
    // Appended garbage is also rejected.
    let mut longer = good.clone();
    longer.push(0);
    assert!(open_bytes(&dir, &longer).is_err());

    for i in 0..good.len() {
        for mask in [0x01u8, 0x20, 0x80, 0xff] {
            let mut bad = good.clone();
            bad[i] ^= mask;
            assert!(
                open_bytes(&dir, &bad).is_err(),
                "flip {mask:#04x} at byte {i} was accepted"
            );
        }
    }

    // Random garbage, and garbage after a plausible length prefix (deterministic LCG).
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut next = || {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (state >> 33) as u32
    };
    for _ in 0..300 {
        let len = (next() % 400) as usize;
        let mut bytes: Vec<u8> = (0..len).map(|_| next() as u8).collect();
        if len >= 8 && next() % 2 == 0 {
            let n = (next() as usize) % (len - 7);
            bytes[..8].copy_from_slice(&(n as u64).to_le_bytes());
        }
        let _ = open_bytes(&dir, &bytes);
    }
    fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn writer_rejects_bad_tensors() {
    let v = [1.0f32; 6];
    let mut w = BakeWriter::new();
    w.add_f32("a", &[2, 3], &v).unwrap();
    let e = w.add_f32("a", &[6], &v).unwrap_err().to_string();
    assert!(e.contains("'a'") && e.contains("twice"), "{e}");
    let e = w.add_f32("b", &[2, 2], &v).unwrap_err().to_string();
    assert!(
        e.contains("'b'") && e.contains("16 bytes") && e.contains("24"),
        "{e}"
    );
    let e = w
        .add_f32("c", &[usize::MAX, usize::MAX, usize::MAX], &v)
        .unwrap_err();
    assert!(matches!(e, FormatError::DataSize { .. }));
    assert!(w.add_f32("", &[6], &v).is_err());
    let e = w.add_f32("__pad0", &[6], &v).unwrap_err().to_string();
    assert!(e.contains("reserved"), "{e}");
    assert!(w.add_f32("bad\nname", &[6], &v).is_err());
    assert!(w.add_tensor("raw", Dtype::U16, &[3], vec![0u8; 5]).is_err());
    w.add_tensor("raw", Dtype::U16, &[3], vec![0u8; 6]).unwrap();
    assert_eq!(w.len(), 2);
}

#[test]
fn header_size_limit_matches_safetensors() {
    let mut w = BakeWriter::new();
    w.set_metadata(json!("x".repeat(MAX_HEADER_LEN)));
    let e = w.to_bytes().unwrap_err().to_string();
    assert!(e.contains("limit"), "{e}");
}

#[test]
fn atomic_write_replaces_whole_files_and_cleans_up() {
    let dir = scratch("atomic");
    let path = dir.join("sub/folder/a.prtbake");
    let v1 = vec![1.0f32; 100];
    let v2 = vec![2.0f32; 50];

    let mut w = BakeWriter::new();
    w.add_f32("x", &[100], &v1).unwrap();
    w.write_atomic(&path).unwrap(); // creates the missing parent folders
    let old = BakeFile::open(&path).unwrap();

    let mut w2 = BakeWriter::new();
    w2.add_f32("x", &[50], &v2).unwrap();
    w2.write_atomic(&path).unwrap();
    let new = BakeFile::open(&path).unwrap();
    assert_eq!(new.tensor("x").unwrap().as_f32().unwrap(), &v2[..]);
    // A reader that opened the old file keeps seeing the old, complete data: the writer
    // replaced the directory entry, never the mapped bytes.
    assert_eq!(old.tensor("x").unwrap().as_f32().unwrap(), &v1[..]);
    old.verify_checksums().unwrap();

    // A failing write (here: the target is a non-empty folder, so the final rename fails after
    // the whole temporary file was written) leaves no temporary file behind.
    let blocker = dir.join("blocker");
    fs::create_dir_all(blocker.join("inside")).unwrap();
    let e = w2.write_atomic(&blocker).unwrap_err().to_string();
    assert!(e.contains("blocker") && e.contains("renaming"), "{e}");
    assert!(blocker.join("inside").is_dir());

    // A failing write over an existing file leaves it untouched.
    let before = fs::read(&path).unwrap();
    let r = write_file_atomic(&path, |out| {
        use std::io::Write;
        out.write_all(b"partial")?;
        Err(std::io::Error::other("disk on fire"))
    });
    assert!(r.unwrap_err().to_string().contains("disk on fire"));
    assert_eq!(fs::read(&path).unwrap(), before);

    let leftovers: Vec<_> = walk(&dir)
        .into_iter()
        .filter(|p| p.to_string_lossy().ends_with(".tmp"))
        .collect();
    assert!(leftovers.is_empty(), "temporary files left: {leftovers:?}");
    drop((old, new));
    fs::remove_dir_all(&dir).unwrap();
}

fn walk(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for e in fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            out.extend(walk(&p));
        }
        out.push(p);
    }
    out
}

#[test]
fn empty_bake_is_valid() {
    let dir = scratch("empty");
    let path = dir.join("e.prtbake");
    BakeWriter::new().write_atomic(&path).unwrap();
    let f = BakeFile::open(&path).unwrap();
    assert_eq!(f.tensor_names().len(), 0);
    assert_eq!(f.metadata(), &json!({}));
    let e = f.tensor("x").unwrap_err().to_string();
    assert!(e.contains("no tensors"), "{e}");
    fs::remove_dir_all(&dir).unwrap();
}

/// A streamed tensor from pieces: a 4-byte counter run, written in chunks of `chunk`.
struct Counter {
    values: u32,
    chunk: usize,
    /// Extra bytes written at the end (a source that breaks its promise).
    extra: usize,
}

impl prt_formats::container::TensorSource for Counter {
    fn write_to(&self, out: &mut dyn std::io::Write) -> std::io::Result<()> {
        let bytes: Vec<u8> = (0..self.values).flat_map(|v| v.to_le_bytes()).collect();
        for c in bytes.chunks(self.chunk) {
            out.write_all(c)?;
        }
        out.write_all(&vec![7u8; self.extra])
    }
}

#[test]
fn streamed_tensors_give_the_same_file_as_tensors_in_memory() {
    let dir = scratch("streamed");
    let values: Vec<u32> = (0..1000).collect();
    let pad = vec![1.5f32; 3];
    let mut a = BakeWriter::new();
    a.add_f32("pad", &[3], &pad).unwrap();
    a.add_u32("counter", &[10, 100], &values).unwrap();
    a.set_metadata(json!({"k": 1}));
    let mut b = BakeWriter::new();
    b.add_f32("pad", &[3], &pad).unwrap();
    let counter = Counter {
        values: 1000,
        chunk: 37,
        extra: 0,
    };
    b.add_streamed("counter", Dtype::U32, &[10, 100], 4000, &counter)
        .unwrap();
    b.set_metadata(json!({"k": 1}));
    assert_eq!(a.to_bytes().unwrap(), b.to_bytes().unwrap());
    let path = dir.join("s.prtbake");
    b.write_atomic(&path).unwrap();
    assert_eq!(fs::read(&path).unwrap(), a.to_bytes().unwrap());
    let f = BakeFile::open(&path).unwrap();
    assert_eq!(f.tensor("counter").unwrap().as_u32().unwrap(), &values[..]);

    // A declared length that does not match the shape, and a source that writes more than
    // it declared, are refused naming the tensor; nothing is written.
    let bad = Counter {
        values: 1000,
        chunk: 64,
        extra: 0,
    };
    let liar = Counter {
        values: 1000,
        chunk: 64,
        extra: 4,
    };
    let mut c = BakeWriter::new();
    assert!(c
        .add_streamed("counter", Dtype::U32, &[999], 4000, &bad)
        .is_err());
    c.add_streamed("counter", Dtype::U32, &[1000], 4000, &liar)
        .unwrap();
    let e = c
        .write_atomic(dir.join("liar.prtbake"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("counter") && e.contains("4004"), "{e}");
    assert!(!dir.join("liar.prtbake").exists());
}
