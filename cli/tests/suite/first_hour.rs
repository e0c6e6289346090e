//! A new user's first hour, with a model from outside the project: a glTF with no lights, no
//! camera and no normals (as most downloaded models are) bakes with the defaults in both modes
//! and relights to a lit picture; the mistakes a user makes get answers that say what to do
//! (`relight` on the glTF, mistyped flags, a clamped or unphysical edit, a replaced file).

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::OnceLock;

use crate::bad_input::{s, scenes};

const BAKE: &str = env!("CARGO_BIN_EXE_bake");
const RELIGHT: &str = env!("CARGO_BIN_EXE_relight");
const REFERENCE: &str = env!("CARGO_BIN_EXE_reference");

/// Writes `model.gltf` + `model.bin` into `dir`: a glossy red box (0.6 m, indexed, a dielectric
/// of roughness 0.4, so an editable ggx) standing on a rough gray slab (non-indexed), in one
/// node with no camera, no light and no normals. Unlike the project's scenes, it brings
/// nothing to see by.
fn outside_model(dir: &Path) -> PathBuf {
    let mut positions: Vec<[f32; 3]> = Vec::new();
    let corners = |c: [f32; 3], h: [f32; 3]| -> Vec<[f32; 3]> {
        (0..8)
            .map(|i| {
                let sign = |bit: usize| if i & bit == 0 { -1.0 } else { 1.0 };
                [
                    c[0] + sign(1) * h[0],
                    c[1] + sign(2) * h[1],
                    c[2] + sign(4) * h[2],
                ]
            })
            .collect()
    };
    // Counter-clockwise seen from outside.
    const QUADS: [[u32; 4]; 6] = [
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ];
    let quads_to_triangles = |q: &[u32; 4]| [q[0], q[1], q[2], q[0], q[2], q[3]];
    positions.extend(corners([0.0, 0.3, 0.0], [0.3, 0.3, 0.3]));
    let box_indices: Vec<u32> = QUADS.iter().flat_map(quads_to_triangles).collect();
    let slab = corners([0.0, -0.02, 0.0], [1.5, 0.02, 1.5]);
    let slab_start = positions.len();
    for q in &QUADS {
        for i in quads_to_triangles(q) {
            positions.push(slab[i as usize]);
        }
    }
    let slab_count = positions.len() - slab_start;

    let mut bin: Vec<u8> = positions
        .iter()
        .flatten()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    let positions_len = bin.len();
    bin.extend(box_indices.iter().flat_map(|i| i.to_le_bytes()));
    let bounds = |ps: &[[f32; 3]]| {
        ps.iter()
            .fold(([f32::MAX; 3], [f32::MIN; 3]), |(lo, hi), p| {
                (
                    std::array::from_fn::<f32, 3, _>(|k| lo[k].min(p[k])),
                    std::array::from_fn::<f32, 3, _>(|k| hi[k].max(p[k])),
                )
            })
    };
    let (box_lo, box_hi) = bounds(&positions[..slab_start]);
    let (slab_lo, slab_hi) = bounds(&positions[slab_start..]);
    let gltf = serde_json::json!({
        "asset": {"version": "2.0", "generator": "a new user's download"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "name": "model"}],
        "materials": [
            {"name": "paint", "pbrMetallicRoughness": {
                "baseColorFactor": [0.8, 0.15, 0.1, 1.0], "metallicFactor": 0.0,
                "roughnessFactor": 0.4}},
            {"name": "slab", "pbrMetallicRoughness": {
                "baseColorFactor": [0.6, 0.6, 0.6, 1.0], "metallicFactor": 0.0,
                "roughnessFactor": 1.0}}
        ],
        "meshes": [{"primitives": [
            {"attributes": {"POSITION": 0}, "indices": 1, "material": 0},
            {"attributes": {"POSITION": 2}, "material": 1}
        ]}],
        "buffers": [{"byteLength": bin.len(), "uri": "model.bin"}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": positions_len},
            {"buffer": 0, "byteOffset": positions_len, "byteLength": box_indices.len() * 4}
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 8, "type": "VEC3",
             "min": box_lo, "max": box_hi},
            {"bufferView": 1, "componentType": 5125, "count": box_indices.len(),
             "type": "SCALAR"},
            {"bufferView": 0, "byteOffset": slab_start * 12, "componentType": 5126,
             "count": slab_count, "type": "VEC3", "min": slab_lo, "max": slab_hi}
        ]
    });
    std::fs::write(dir.join("model.bin"), bin).expect("write model.bin");
    let path = dir.join("model.gltf");
    std::fs::write(&path, gltf.to_string()).expect("write model.gltf");
    path
}

fn run(bin: &str, args: &[&str]) -> Output {
    Command::new(bin).args(args).output().expect("spawn")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Runs a tool that must succeed; returns its stderr.
fn succeeds(bin: &str, args: &[&str]) -> String {
    let o = run(bin, args);
    assert!(o.status.success(), "{bin} {args:?}: {}", stderr(&o));
    stderr(&o)
}

/// The outside model's folder (under the target folder, emptied first) and its per-pixel bake
/// with the defaults (48 x 48, 8 spp), made once for the tests of this file.
fn pixel_bake() -> &'static (PathBuf, PathBuf, PathBuf) {
    static BAKED: OnceLock<(PathBuf, PathBuf, PathBuf)> = OnceLock::new();
    BAKED.get_or_init(|| {
        let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("cli-first-hour");
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("mkdir");
        let model = outside_model(&dir);
        let out = dir.join("pixel.prtbake");
        let err = succeeds(
            BAKE,
            &[
                s(&model),
                "--width",
                "48",
                "--height",
                "48",
                "--spp",
                "8",
                "--out",
                s(&out),
            ],
        );
        assert!(!err.contains("nothing lights"), "{err}");
        (dir, model, out)
    })
}

/// The share of pixels that differ by more than 0.01 in some channel, and the mean of `|a - b|`
/// (over the channels) on those pixels.
fn difference(a: &Path, b: &Path) -> (f64, f64) {
    let (w, h, pa) = prt_formats::read_exr_rgb(a).expect("read image");
    let (w2, h2, pb) = prt_formats::read_exr_rgb(b).expect("read image");
    assert_eq!((w, h), (w2, h2));
    let mut sum = 0.0f64;
    let mut differing = 0usize;
    for (x, y) in pa.iter().zip(&pb) {
        let d: Vec<f64> = (0..3).map(|c| f64::from((x[c] - y[c]).abs())).collect();
        if d.iter().any(|&d| d > 0.01) {
            sum += d.iter().sum::<f64>() / 3.0;
            differing += 1;
        }
    }
    (
        differing as f64 / pa.len() as f64,
        sum / differing.max(1) as f64,
    )
}

/// What the model's materials reflect in a relit image ([`difference`]): the image against one
/// relit with both materials black (the background, the environment seen directly, is in
/// both). A model that no light reaches reflects nothing and the two are equal.
fn model_reflects(bake: &Path, dir: &Path, extra: &[&str], name: &str) -> (f64, f64) {
    let lit = dir.join(format!("{name}-lit.exr"));
    let black = dir.join(format!("{name}-black.exr"));
    let mut args = vec![s(bake), "--out", s(&lit)];
    args.extend(extra);
    succeeds(RELIGHT, &args);
    let mut args = vec![
        s(bake),
        "--set",
        "paint.kd=0",
        "--set",
        "paint.ks=0",
        "--set",
        "slab.kd=0",
        "--out",
        s(&black),
    ];
    args.extend(extra);
    succeeds(RELIGHT, &args);
    difference(&lit, &black)
}

#[test]
fn an_outside_gltf_bakes_with_defaults_and_relights_lit_in_both_modes() {
    let (dir, model, pixel) = pixel_bake();
    // Per pixel: the model covers about a fifth of the image (the framing camera sees the
    // whole slab) and reflects the default light there (a white diffuse facing up would be
    // 0.9, the slab's 0.6 gray about 0.5).
    let (share, mean) = model_reflects(pixel, dir, &[], "pixel");
    assert!(
        share > 0.1 && mean > 0.2,
        "per pixel, the model reflects {mean:.4} on average over {:.0} % of the image",
        share * 100.0
    );
    // The reference tracer sees the same defaults and both materials lit.
    let reference = dir.join("reference.exr");
    let o = run(
        REFERENCE,
        &[
            s(model),
            "--width",
            "24",
            "--height",
            "24",
            "--spp",
            "4",
            "--json",
            "--out",
            s(&reference),
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).expect("reference --json");
    for m in ["paint", "slab"] {
        let rgb = &j["material_mean_radiance"][m]["mean_radiance"];
        let max = (0..3)
            .filter_map(|c| rgb[c].as_f64())
            .fold(0.0f64, f64::max);
        assert!(max > 0.05, "{m} is dark in the reference: {j}");
    }

    // Per vertex: the printed defaults with `mode = "vertex"`, saved beside the glTF (its
    // paths are relative to it); relit from the bake's camera.
    let printed = run(BAKE, &[s(model), "--print-config"]);
    assert!(printed.status.success(), "{}", stderr(&printed));
    let text = String::from_utf8(printed.stdout).expect("utf-8 config");
    let config = dir.join("bake.toml");
    std::fs::write(
        &config,
        text.replace("mode = \"pixel\"", "mode = \"vertex\""),
    )
    .expect("write config");
    let vertex = dir.join("vertex.prtbake");
    let err = succeeds(
        BAKE,
        &[s(&config), "--spp", "4", "--out", s(&vertex), "--quiet"],
    );
    assert!(!err.contains("nothing lights"), "{err}");
    let size = ["--width", "48", "--height", "48"];
    let (share, mean) = model_reflects(&vertex, dir, &size, "vertex");
    assert!(
        share > 0.1 && mean > 0.2,
        "per vertex, the model reflects {mean:.4} on average over {:.0} % of the image",
        share * 100.0
    );
}

/// `relight` on a scene, a config or an image: "not a PRT bake file" and what it looks like.
#[test]
fn relight_on_a_file_that_is_not_a_bake_says_what_it_is() {
    let (dir, model, _) = pixel_bake();
    let png = dir.join("never.png");
    let toml = dir.join("settings.toml");
    std::fs::write(&toml, "scene = \"model.gltf\"\nspp = 16\n").expect("write");
    for (file, what) in [
        (model.clone(), "a glTF JSON scene"),
        (
            scenes().join("furnace/furnace.glb"),
            "a binary glTF scene (.glb)",
        ),
        (toml, "a TOML text file"),
        (scenes().join("envmaps/sunset.exr"), "an OpenEXR image"),
    ] {
        crate::bad_input::fails(
            RELIGHT,
            &[s(&file), "--out", s(&png)],
            &[s(&file), "not a PRT bake file", what],
            &png,
        );
    }
}

/// Flags a user guesses get the flag they meant, and enumerations list their values.
#[test]
fn mistyped_flags_are_answered_with_the_right_one() {
    let tip = |bin: &str, args: &[&str], want: &str| {
        let o = run(bin, args);
        let e = stderr(&o);
        assert!(!o.status.success(), "{bin} {args:?} succeeded");
        assert!(
            e.contains(&format!("a similar argument exists: '{want}'")),
            "{bin} {args:?}: {e}"
        );
        assert!(!e.contains("-- --"), "a misleading tip: {e}");
    };
    tip(RELIGHT, &["x.prtbake", "--material", "paint.kd=1"], "--set");
    tip(BAKE, &["x.toml", "--sample", "16"], "--spp");
    tip(BAKE, &["x.toml", "--samples=16"], "--spp");
    tip(REFERENCE, &["x.toml", "--samples", "16"], "--spp");
    // Clap's own suggestions still work for flags spelt alike.
    tip(RELIGHT, &["x.prtbake", "--exposre", "2"], "--exposure");
    let o = run(BAKE, &["x.toml", "--precision", "f8"]);
    let e = stderr(&o);
    assert!(e.contains("[possible values: f32, f16]"), "{e}");
}

/// Values that are accepted but not what the user gets or wants say so: a lobe parameter
/// outside the basis' range names the material, the value and the range; an edit that
/// reflects more than it receives names the material and the values; `--list` names each
/// parameter; the summary gives its byte count a unit.
#[test]
fn quiet_wrong_values_are_named() {
    let (dir, _, bake) = pixel_bake();
    let png = dir.join("edit.png");
    let err = succeeds(
        RELIGHT,
        &[
            s(bake),
            "--set",
            "paint.alpha=0.001",
            "--set",
            "slab.kd=1.5",
            "--out",
            s(&png),
        ],
    );
    let warnings: Vec<&str> = err.lines().filter(|l| l.starts_with("warning:")).collect();
    assert_eq!(warnings.len(), 2, "{err}");
    assert!(
        warnings[0].contains("paint.alpha = 0.001") && warnings[0].contains("[0.02, 1]"),
        "{err}"
    );
    assert!(
        warnings[1].contains("`slab`")
            && warnings[1].contains("kd = 1.5")
            && warnings[1].contains("[0, 1]"),
        "{err}"
    );
    let summary = err.lines().last().unwrap_or_default();
    assert!(
        [" B read", " kB read", " MB read", " GB read"]
            .iter()
            .any(|unit| summary.contains(unit)),
        "{summary}"
    );
    // In range and physical: no warning.
    let err = succeeds(
        RELIGHT,
        &[s(bake), "--set", "paint.alpha=0.3", "--out", s(&png)],
    );
    assert!(!err.contains("warning"), "{err}");

    let o = run(RELIGHT, &[s(bake), "--list"]);
    let list = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!list.contains("param="), "{list}");
    let paint = list
        .lines()
        .find(|l| l.starts_with("paint"))
        .unwrap_or_else(|| panic!("{list}"));
    assert!(
        paint.contains("alpha=") && paint.contains("basis range [0.02, 1]"),
        "{paint}"
    );
    let slab = list.lines().find(|l| l.starts_with("slab")).unwrap_or("");
    assert!(
        slab.contains("kd=") && !slab.contains("ks=") && !slab.contains("alpha"),
        "a diffuse material has kd only: {slab}"
    );
}

/// A bake (and an image) written over an existing file says so, naming it.
#[test]
fn a_bake_that_replaces_a_file_says_so() {
    let (dir, model, _) = pixel_bake();
    let out = dir.join("again.prtbake");
    let args = [
        s(model),
        "--width",
        "8",
        "--height",
        "8",
        "--spp",
        "1",
        "--out",
        s(&out),
    ];
    let first = succeeds(BAKE, &args);
    assert!(!first.contains("replace"), "{first}");
    let second = succeeds(BAKE, &args);
    assert!(
        second.contains(&format!("{} exists; this bake replaces it", s(&out)))
            && second.contains("(replaced the previous file)"),
        "{second}"
    );
    let mut json_args = args.to_vec();
    json_args.push("--json");
    let o = run(BAKE, &json_args);
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).expect("--json");
    assert_eq!(j["replaced"], true, "{j}");

    let png = dir.join("again.png");
    let relit = succeeds(RELIGHT, &[s(&out), "--out", s(&png)]);
    assert!(!relit.contains("replaced"), "{relit}");
    let relit = succeeds(RELIGHT, &[s(&out), "--out", s(&png)]);
    assert!(relit.contains("(replaced the previous file)"), "{relit}");
}
