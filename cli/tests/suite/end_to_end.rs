//! The binaries as a user calls them: `bake` a tiny scene, `relight` it with edits to a PNG
//! and an EXR, render the `reference` with the same edits; exit codes, `--json` figures and
//! the files written.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use serde_json::Value;

fn scenes() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes")
}

/// Runs a binary; panics with its stderr unless it exits 0. Returns the parsed `--json` line.
fn run_json(bin: &str, args: &[&std::ffi::OsStr]) -> Value {
    let out: Output = Command::new(bin).args(args).output().expect("spawn");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.success(),
        "{bin} {args:?} exited {:?}: {stderr}",
        out.status.code()
    );
    let stdout = String::from_utf8(out.stdout).expect("utf-8 stdout");
    serde_json::from_str(stdout.trim())
        .unwrap_or_else(|e| panic!("{bin}: --json output does not parse ({e}): {stdout}"))
}

fn num(v: &Value, key: &str) -> f64 {
    v[key]
        .as_f64()
        .unwrap_or_else(|| panic!("key '{key}' missing or not a number in {v}"))
}

fn nonempty(p: &Path) {
    let len = std::fs::metadata(p)
        .unwrap_or_else(|e| panic!("{} not written: {e}", p.display()))
        .len();
    assert!(len > 0, "{} is empty", p.display());
}

/// Bakes `input` 16x16 at 2 spp into `dir`; checks the summary; returns the bake file.
fn bake(input: &Path, dir: &Path) -> PathBuf {
    let out = dir.join("scene.prtbake");
    let j = run_json(
        env!("CARGO_BIN_EXE_bake"),
        &[
            input.as_os_str(),
            "--width".as_ref(),
            "16".as_ref(),
            "--height".as_ref(),
            "16".as_ref(),
            "--spp".as_ref(),
            "2".as_ref(),
            "--out".as_ref(),
            out.as_os_str(),
            "--json".as_ref(),
        ],
    );
    assert_eq!(j["output"].as_str().map(PathBuf::from), Some(out.clone()));
    let bytes = num(&j, "file_bytes");
    assert_eq!(
        bytes as u64,
        std::fs::metadata(&out).expect("bake file").len()
    );
    assert!(
        num(&j, "seconds") >= 0.0 && num(&j, "estimated_bytes") > 0.0,
        "{j}"
    );
    assert!(j["timings"].is_object() && j["stats"].is_object(), "{j}");
    out
}

/// Relights `bake` with `set` into `image`; checks the figures; returns them.
fn relight(bake: &Path, set: &[&str], image: &Path) -> Value {
    let mut args: Vec<&std::ffi::OsStr> = vec![bake.as_os_str()];
    for s in set {
        args.push("--set".as_ref());
        args.push(s.as_ref());
    }
    args.extend(["--out".as_ref(), image.as_os_str(), "--json".as_ref()]);
    let j = run_json(env!("CARGO_BIN_EXE_relight"), &args);
    assert_eq!((num(&j, "width"), num(&j, "height")), (16.0, 16.0), "{j}");
    assert_eq!(j["variant"], "full");
    assert_eq!(
        j["out"].as_str().map(PathBuf::from),
        Some(image.to_path_buf())
    );
    assert!(num(&j, "bytes_read_per_frame") > 0.0, "{j}");
    assert!(num(&j, "seconds_per_frame_median") >= 0.0, "{j}");
    assert!(j["clamped"].is_boolean(), "{j}");
    nonempty(image);
    j
}

/// Renders the reference of `config` with `set` into `dir`; returns its figures.
fn reference(config: &Path, set: &[&str], dir: &Path) -> Value {
    let out = dir.join("reference.exr");
    let mut args: Vec<&std::ffi::OsStr> = vec![config.as_os_str()];
    for s in set {
        args.push("--set".as_ref());
        args.push(s.as_ref());
    }
    args.extend(
        ["--width", "16", "--height", "16", "--spp", "2", "--json"]
            .iter()
            .map(std::ffi::OsStr::new),
    );
    args.extend(["--out".as_ref(), out.as_os_str()]);
    let j = run_json(env!("CARGO_BIN_EXE_reference"), &args);
    assert_eq!((num(&j, "width"), num(&j, "height")), (16.0, 16.0), "{j}");
    assert_eq!(num(&j, "spp"), 2.0);
    assert_eq!(num(&j, "samples"), 16.0 * 16.0 * 2.0);
    assert!(num(&j, "rays") > 0.0, "{j}");
    let mean = j["mean_radiance"].as_array().expect("mean_radiance");
    assert_eq!(mean.len(), 3);
    assert!(
        mean.iter()
            .all(|v| v.as_f64().is_some_and(|v| v.is_finite() && v >= 0.0)),
        "{j}"
    );
    nonempty(&out);
    nonempty(&out.with_extension("png"));
    j
}

#[test]
fn cornell_bakes_relights_and_renders_its_reference() {
    let dir = tempfile::tempdir().expect("temp dir");
    let bake_file = bake(&scenes().join("cornell"), dir.path());
    let set = ["bunny.kd=0.8,0.2,0.2", "bunny.shininess=120"];
    relight(&bake_file, &set, &dir.path().join("relit.png"));
    relight(&bake_file, &set, &dir.path().join("relit.exr"));
    let j = reference(&scenes().join("cornell/bake.toml"), &set, dir.path());
    let bunny = &j["material_mean_radiance"]["bunny"]["mean_radiance"];
    assert!(bunny.is_array(), "no bunny in {j}");
}

/// A glTF file baked with the default config; the furnace's sphere is diffuse (albedo 0.5
/// under a white sky), so its reference mean radiance is near 0.5 in every channel.
#[test]
fn furnace_glb_bakes_relights_and_renders_its_reference() {
    let dir = tempfile::tempdir().expect("temp dir");
    let bake_file = bake(&scenes().join("furnace/furnace.glb"), dir.path());
    relight(&bake_file, &[], &dir.path().join("relit.png"));
    relight(
        &bake_file,
        &["sphere.kd=0.25"],
        &dir.path().join("relit.exr"),
    );
    let j = reference(&scenes().join("furnace/bake.toml"), &[], dir.path());
    let sphere = j["material_mean_radiance"]["sphere"]["mean_radiance"]
        .as_array()
        .unwrap_or_else(|| panic!("no sphere in {j}"))
        .iter()
        .map(|v| v.as_f64().expect("number"))
        .collect::<Vec<_>>();
    assert!(
        sphere.iter().all(|v| (v - 0.5).abs() < 0.05),
        "furnace sphere radiance {sphere:?}, expected 0.5"
    );
}
