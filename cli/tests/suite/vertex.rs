//! The per-vertex mode through the binaries, as a user calls them: `bake` a vertex config,
//! `relight` it for a new environment, rotation, camera, size and material, and the refusals
//! (bad cameras, unreadable or non-finite maps, flags of the other mode): a non-zero exit, one
//! `error:` line naming the problem, nothing written.

use std::path::{Path, PathBuf};

use crate::bad_input::{fails, s, scenes};
use std::process::Command;

use serde_json::Value;

const BAKE: &str = env!("CARGO_BIN_EXE_bake");
const RELIGHT: &str = env!("CARGO_BIN_EXE_relight");

/// A vertex config for vitrine with every material diffuse (no shading basis to build, so the
/// bake takes seconds), written next to the scene's own files in `dir`.
pub(crate) fn diffuse_vitrine(dir: &Path) -> PathBuf {
    let scene = scenes().join("vitrine/vitrine.gltf");
    let map = scenes().join("envmaps/sky.exr");
    let config = dir.join("vitrine-diffuse.toml");
    let text = format!(
        "scene = {:?}\nmode = \"vertex\"\nspp = 4\nreflections = 2\nseed = 3\n\n\
         [environment]\nmap = {:?}\nintensity = 0.25\n\n\
         [materials.sphere]\neditable = true\nfamily = \"diffuse\"\nkd = [0.5, 0.5, 0.5]\n\n\
         [materials.bunny]\neditable = true\nfamily = \"diffuse\"\nkd = [0.8, 0.4, 0.18]\n",
        s(&scene),
        s(&map)
    );
    std::fs::write(&config, text).expect("write config");
    config
}

#[test]
fn a_vertex_bake_relights_any_view_light_and_material_and_refuses_bad_input() {
    let dir = tempfile::tempdir().expect("temp dir");
    let config = diffuse_vitrine(dir.path());
    let bake_file = dir.path().join("vitrine.prtbake");
    let o = Command::new(BAKE)
        .args([s(&config), "--quiet", "--json", "--out", s(&bake_file)])
        .output()
        .expect("spawn bake");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let j: Value = serde_json::from_slice(&o.stdout).expect("bake --json");
    assert_eq!(
        j["file_bytes"].as_u64(),
        Some(std::fs::metadata(&bake_file).expect("bake file").len()),
        "{j}"
    );
    assert_eq!(j["vertices"].as_u64(), Some(3106), "{j}");

    // A new light, rotation, camera, size and material.
    let png = dir.path().join("relit.png");
    let b = s(&bake_file);
    let p = s(&png);
    let sunset = scenes().join("envmaps/sunset.exr");
    let camera = "eye=0.5,0.3,0.6 target=0,0.1,0 fov=45";
    let o = Command::new(RELIGHT)
        .args([
            b,
            "--env",
            s(&sunset),
            "--env-rotate",
            "45",
            "--camera",
            camera,
            "--width",
            "40",
            "--height",
            "30",
            "--set",
            "bunny.kd=0.2,0.3,0.4",
            "--out",
            p,
            "--json",
        ])
        .output()
        .expect("spawn relight");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let j: Value = serde_json::from_slice(&o.stdout).expect("relight --json");
    assert_eq!(
        (j["width"].as_u64(), j["height"].as_u64()),
        (Some(40), Some(30)),
        "{j}"
    );
    assert_eq!(j["kind"], "vertex", "{j}");
    assert!(j["stages"]["light_s"].as_f64().is_some(), "{j}");
    let img = std::fs::read(&png).expect("relit image");
    assert!(img.len() > 100, "tiny PNG");
    std::fs::remove_file(&png).expect("remove");

    // Bad cameras.
    fails(
        RELIGHT,
        &[
            b,
            "--camera",
            "eye=0,0.3,0.8 target=0,0.1,0 fov=0",
            "--out",
            p,
        ],
        &["fov"],
        &png,
    );
    // The eye at the sphere's centre.
    fails(
        RELIGHT,
        &[
            b,
            "--camera",
            "eye=-0.17,0.119,0 target=0,0.1,0 fov=40",
            "--out",
            p,
        ],
        &["inside", "sphere"],
        &png,
    );
    // Unreadable and non-finite maps.
    let missing = dir.path().join("missing.exr");
    fails(
        RELIGHT,
        &[b, "--env", s(&missing), "--out", p],
        &["missing.exr"],
        &png,
    );
    let nan_map = dir.path().join("nan.exr");
    let mut texels = vec![[0.5f32; 3]; 8 * 4];
    texels[9] = [f32::NAN, 0.0, 0.0];
    prt_formats::write_exr(&nan_map, 8, 4, &texels).expect("write NaN map");
    fails(
        RELIGHT,
        &[b, "--env", s(&nan_map), "--out", p],
        &["nan.exr"],
        &png,
    );
    fails(
        RELIGHT,
        &[b, "--compressed", "--out", p],
        &["per-vertex"],
        &png,
    );

    // The per-pixel mode's options on a vertex bake, and the vertex mode's on a pixel bake.
    fails(
        BAKE,
        &[
            s(&config),
            "--width",
            "8",
            "--out",
            s(&dir.path().join("w.prtbake")),
        ],
        &["--width"],
        &dir.path().join("w.prtbake"),
    );
    let pixel_file = dir.path().join("cornell.prtbake");
    let o = Command::new(BAKE)
        .args([
            s(&scenes().join("cornell")),
            "--width",
            "8",
            "--height",
            "8",
            "--spp",
            "1",
            "--quiet",
            "--out",
            s(&pixel_file),
        ])
        .output()
        .expect("spawn bake");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    fails(
        RELIGHT,
        &[s(&pixel_file), "--env", s(&sunset), "--out", p],
        &["--env"],
        &png,
    );
    fails(
        RELIGHT,
        &[s(&pixel_file), "--camera", camera, "--out", p],
        &["--camera"],
        &png,
    );
    fails(
        RELIGHT,
        &[s(&pixel_file), "--width", "32", "--out", p],
        &["--width"],
        &png,
    );
    fails(
        RELIGHT,
        &[s(&pixel_file), "--repeat", "2", "--turn", "5", "--out", p],
        &["--turn"],
        &png,
    );
    fails(
        RELIGHT,
        &[s(&pixel_file), "--no-compact-lights", "--out", p],
        &["--no-compact-lights", "per-pixel bake"],
        &png,
    );
    fails(
        RELIGHT,
        &[s(&pixel_file), "--no-antialias", "--out", p],
        &["--no-antialias", "per-pixel bake"],
        &png,
    );
    fails(
        RELIGHT,
        &[b, "--repeat", "2", "--turn", "nan", "--out", p],
        &["--turn", "finite"],
        &png,
    );
    let kept = dir.path().join("kept.prtbake");
    fails(
        BAKE,
        &[
            s(&scenes().join("cornell")),
            "--width",
            "8",
            "--height",
            "8",
            "--spp",
            "1",
            "--keep-traced",
            "--out",
            s(&kept),
        ],
        &["--keep-traced", "per-vertex"],
        &kept,
    );
}
