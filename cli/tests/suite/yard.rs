//! A scene unlike the project's own, as a new user's first per-vertex bake: the yard
//! (`prt_bake::testing::Yard`, small): a ground grid, an editable GGX sphere at 8 basis BRDFs,
//! an editable Blinn-Phong torus and an editable diffuse box, under the sunset map with the sun
//! in it, three reflections, compressed at the defaults. Its full-size version stopped a bake
//! in compression (`NoConvergence`); with and without NORMAL attributes it must bake and
//! compress, weld what a mesh without normals splits, and say what faceting costs.

use std::path::Path;
use std::process::Command;

use prt_bake::testing::Yard;
use serde_json::Value;

use crate::bad_input::{s, scenes};

const BAKE: &str = env!("CARGO_BIN_EXE_bake");

/// Bakes the yard written to `dir` (with `extra` appended to its config) at N1 = 4; returns the
/// `--json` summary and stderr.
fn bake_yard(yard: &Yard, dir: &Path, extra: &str) -> (Value, String) {
    std::fs::create_dir_all(dir).expect("dir");
    let config = yard
        .write(dir, &scenes().join("envmaps/sunset.exr"))
        .expect("write the yard");
    if !extra.is_empty() {
        let text = std::fs::read_to_string(&config).expect("config");
        // Top-level keys go before the first table.
        std::fs::write(&config, format!("{extra}\n{text}")).expect("config");
    }
    let out = dir.join("yard.prtbake");
    let o = Command::new(BAKE)
        .args([s(&config), "--spp", "4", "--json", "--out", s(&out)])
        .output()
        .expect("spawn bake");
    let stderr = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(o.status.success(), "the yard did not bake: {stderr}");
    let j: Value = serde_json::from_slice(&o.stdout).expect("bake --json");
    assert!(
        std::fs::metadata(&out).is_ok_and(|m| m.len() > 0),
        "no file"
    );
    (j, stderr)
}

fn count(j: &Value, key: &str) -> u64 {
    j[key].as_u64().unwrap_or_else(|| panic!("no {key} in {j}"))
}

/// The vertex count the loader's warning gives for the faceted mesh `mesh`.
fn faceted(stderr: &str, mesh: &str) -> u64 {
    let line = stderr
        .lines()
        .find(|l| l.contains(&format!("mesh \"{mesh}\" has no normals")))
        .unwrap_or_else(|| panic!("no faceting warning for {mesh}: {stderr}"));
    let figure = line
        .split("faceted (the glTF rule: flat normals): ")
        .nth(1)
        .and_then(|r| r.split(' ').next())
        .unwrap_or_else(|| panic!("no vertex count in {line}"));
    figure.parse().expect("a count")
}

#[test]
fn the_yard_bakes_and_compresses_with_and_without_normals_welding_the_flat_ones() {
    let dir = tempfile::tempdir().expect("temp dir");
    let yard = Yard::small();
    let glb_vertices = yard.gltf_vertices() as u64;

    // With normals: every vertex is its own (the box's faces have their own vertices).
    let (j, stderr) = bake_yard(&yard, &dir.path().join("normals"), "");
    assert_eq!(count(&j, "vertices"), glb_vertices, "{j}");
    assert!(!stderr.contains("has no normals"), "{stderr}");
    assert!(
        j["timings"]["compress_seconds"].as_f64() > Some(0.0),
        "not compressed: {j}"
    );

    // Without: the loader splits every triangle's corners; the bake welds those that share
    // position and normal. The flat ground and the box's flat faces weld back to one vertex per
    // grid point; the sphere and torus stay faceted, with the vertex count the loader's
    // warning gives, and the sphere is named as probably meant to be smooth.
    let flat = Yard {
        normals: false,
        ..yard.clone()
    };
    let (j, stderr) = bake_yard(&flat, &dir.path().join("flat"), "");
    let ground = (yard.ground_quads as u64 + 1).pow(2);
    let cube = 6 * (yard.box_quads as u64 + 1).pow(2);
    let sphere = faceted(&stderr, "sphere");
    let torus = faceted(&stderr, "torus");
    assert_eq!(
        count(&j, "vertices"),
        ground + cube + sphere + torus,
        "ground {ground}, box {cube}, sphere {sphere}, torus {torus}: {j}"
    );
    // The ground's 6 q^2 triangle corners weld to its (q + 1)^2 grid points, at least.
    let q = yard.ground_quads as u64;
    assert_eq!(
        count(&j, "loaded_vertices") - count(&j, "vertices"),
        count(&j, "welded_vertices"),
        "{j}"
    );
    assert!(
        count(&j, "welded_vertices") >= 6 * q * q - ground,
        "too little was welded: {j}"
    );
    assert!(
        stderr.lines().any(|l| l.contains("mesh \"sphere\"")
            && l.contains("probably meant to be smooth")
            && l.contains("missing_normals = \"smooth\"")),
        "{stderr}"
    );
    assert!(
        !stderr.contains("mesh \"ground\" has no normals"),
        "{stderr}"
    );

    // missing_normals = "smooth": the same vertices as the file with normals.
    let (j, stderr) = bake_yard(
        &flat,
        &dir.path().join("smooth"),
        "missing_normals = \"smooth\"",
    );
    assert_eq!(count(&j, "vertices"), glb_vertices, "{j}");
    assert!(!stderr.contains("has no normals"), "{stderr}");
}
