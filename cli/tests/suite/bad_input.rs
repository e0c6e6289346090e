//! Bad input to the binaries: a non-zero exit, one `error: ...` line on stderr naming the
//! problem, and no output file.

use std::path::{Path, PathBuf};
use std::process::Command;

pub(crate) fn scenes() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes")
}

/// Runs `bin` with `args`; asserts a failure whose stderr has an `error:` line containing
/// every string of `expect`, and that `out` was not created.
pub(crate) fn fails(bin: &str, args: &[&str], expect: &[&str], out: &Path) {
    let o = Command::new(bin).args(args).output().expect("spawn");
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success(),
        "{bin} {args:?} succeeded; stderr: {stderr}"
    );
    let errors: Vec<&str> = stderr.lines().filter(|l| l.starts_with("error:")).collect();
    assert_eq!(
        errors.len(),
        1,
        "{bin} {args:?}: want one error line: {stderr}"
    );
    for e in expect {
        assert!(
            errors[0].contains(e),
            "{bin} {args:?}: error line does not name '{e}': {}",
            errors[0]
        );
    }
    assert!(
        !out.exists(),
        "{bin} {args:?} failed but wrote {}",
        out.display()
    );
}

pub(crate) fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 path")
}

const BAKE: &str = env!("CARGO_BIN_EXE_bake");
const RELIGHT: &str = env!("CARGO_BIN_EXE_relight");
const REFERENCE: &str = env!("CARGO_BIN_EXE_reference");

#[test]
fn bake_refuses_bad_input() {
    let dir = tempfile::tempdir().expect("temp dir");
    let out = dir.path().join("out.prtbake");
    let small = [
        "--width",
        "8",
        "--height",
        "8",
        "--spp",
        "1",
        "--out",
        s(&out),
    ];
    let run = |input: &str, expect: &[&str]| {
        let mut args = vec![input];
        args.extend(small);
        fails(BAKE, &args, expect, &out);
    };
    let missing = dir.path().join("missing.toml");
    run(s(&missing), &["missing.toml"]);
    let empty_dir = dir.path().join("nothing-here");
    std::fs::create_dir(&empty_dir).expect("mkdir");
    run(s(&empty_dir), &["nothing-here", "bake.toml"]);
    let garbage = dir.path().join("garbage.toml");
    std::fs::write(&garbage, "this is = = not toml [[[").expect("write");
    run(s(&garbage), &["garbage.toml"]);
    let vertex = dir.path().join("vertex.toml");
    let cornell = scenes().join("cornell/cornell.gltf");
    std::fs::write(
        &vertex,
        format!("scene = {:?}\nmode = \"vertex\"\n", s(&cornell)),
    )
    .expect("write");
    run(s(&vertex), &["vertex"]);
}

#[test]
fn relight_refuses_bad_input() {
    let dir = tempfile::tempdir().expect("temp dir");
    let bake_file = dir.path().join("cornell.prtbake");
    let baked = Command::new(BAKE)
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
            s(&bake_file),
        ])
        .output()
        .expect("spawn");
    assert!(
        baked.status.success(),
        "{}",
        String::from_utf8_lossy(&baked.stderr)
    );
    let png = dir.path().join("relit.png");
    let p = s(&png);
    let b = s(&bake_file);
    fails(
        RELIGHT,
        &[b, "--set", "nosuch.kd=1", "--out", p],
        &["nosuch"],
        &png,
    );
    fails(
        RELIGHT,
        &[b, "--set", "bunny.kd", "--out", p],
        &["bunny.kd"],
        &png,
    );
    fails(
        RELIGHT,
        &[b, "--set", "bunny.shininess=abc", "--out", p],
        &["abc"],
        &png,
    );
    let missing = dir.path().join("missing.prtbake");
    fails(
        RELIGHT,
        &[s(&missing), "--out", p],
        &["missing.prtbake"],
        &png,
    );
    let mut bytes = std::fs::read(&bake_file).expect("read");
    let n = bytes.len();
    bytes[n - 9] ^= 0x10;
    let corrupt = dir.path().join("corrupt.prtbake");
    std::fs::write(&corrupt, &bytes).expect("write");
    fails(
        RELIGHT,
        &[s(&corrupt), "--out", p],
        &["corrupt.prtbake"],
        &png,
    );
    let cut = dir.path().join("cut.prtbake");
    std::fs::write(&cut, &bytes[..n / 2]).expect("write");
    fails(RELIGHT, &[s(&cut), "--out", p], &["cut.prtbake"], &png);
}

#[test]
fn reference_refuses_bad_input() {
    let dir = tempfile::tempdir().expect("temp dir");
    let exr = dir.path().join("ref.exr");
    let config = scenes().join("cornell/bake.toml");
    let small = [
        "--width",
        "8",
        "--height",
        "8",
        "--spp",
        "1",
        "--out",
        s(&exr),
    ];
    let run = |args: &[&str], expect: &[&str]| {
        let mut a = args.to_vec();
        a.extend(small);
        fails(REFERENCE, &a, expect, &exr);
    };
    run(&[s(&config), "--set", "nosuch.kd=1"], &["nosuch"]);
    run(&[s(&config), "--set", "bunny=1"], &["bunny=1"]);
    run(&[s(&dir.path().join("missing.toml"))], &["missing.toml"]);
    // Views: inside the bunny (at its centre), zero field of view, straight down.
    let cfg = s(&config);
    run(
        &[cfg, "--camera", "eye=0.093,0.06,-0.2 target=0,0.2,0 fov=40"],
        &["inside", "bunny"],
    );
    run(
        &[cfg, "--camera", "eye=0,1,3 target=0,0,0 fov=0"],
        &["fov", "(0, 180)"],
    );
    run(
        &[cfg, "--camera", "eye=0,1,0 target=0,0,0 fov=40"],
        &["vertical"],
    );
    run(
        &[cfg, "--camera", "eye=0,1,3 fov=40"],
        &["target is missing"],
    );
    // Environments: rotating a scene without a map; unreadable, non-finite and missing maps.
    run(&[cfg, "--env-rotate", "90"], &["--env-rotate", "not a map"]);
    let garbage = dir.path().join("garbage.exr");
    std::fs::write(&garbage, b"not an exr").expect("write");
    run(&[cfg, "--env", s(&garbage)], &["garbage.exr", "OpenEXR"]);
    let nan = dir.path().join("nan.exr");
    let mut texels = vec![[1.0f32; 3]; 8];
    texels[5] = [1.0, f32::NAN, 1.0];
    prt_formats::write_exr(&nan, 4, 2, &texels).expect("write");
    run(
        &[cfg, "--env", s(&nan)],
        &["nan.exr", "NaN or infinite", "column 1, row 1"],
    );
    run(
        &[cfg, "--env", s(&dir.path().join("none.exr"))],
        &["none.exr"],
    );
    let sky = scenes().join("envmaps/studio.exr");
    run(
        &[cfg, "--env", s(&sky), "--env-rotate", "400"],
        &["--env-rotate", "400"],
    );
    run(
        &[cfg, "--env", s(&sky), "--env-intensity", "-1"],
        &["intensity", "-1"],
    );
    // What `bake` accepts besides a config: a folder without bake.toml is refused, naming it;
    // a scene folder renders.
    run(&[s(dir.path())], &["bake.toml"]);
    let folder = scenes().join("cornell");
    let o = std::process::Command::new(REFERENCE)
        .args([s(&folder)])
        .args(small)
        .output()
        .expect("spawn reference");
    assert!(
        o.status.success() && exr.exists(),
        "reference on a scene folder: {}",
        String::from_utf8_lossy(&o.stderr)
    );
}
