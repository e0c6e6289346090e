//! The `view` binary as a user starts it: where it listens (only this machine unless told,
//! and then with a warning), and a clear error line, never a panic, for a bake file it
//! cannot use.

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::OnceLock;

use prt_bake::progress::Silent;
use prt_bake::run::{load, run_pixel, PixelRunSettings};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// A tiny per-pixel bake of cornell (8x8, one sample: only that it opens matters).
fn bake() -> &'static Path {
    static BAKE: OnceLock<PathBuf> = OnceLock::new();
    BAKE.get_or_init(|| {
        let dir = std::env::temp_dir().join(format!("prt-viewer-cli-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("temp dir");
        let path = dir.join("cornell.prtbake");
        let (config, scene) = load(&root().join("scenes/cornell"), &Silent).expect("cornell");
        let settings = PixelRunSettings {
            spp: Some(1),
            width: Some(8),
            height: Some(8),
            output: Some(path.clone()),
            ..Default::default()
        };
        run_pixel(&config, &scene, &settings, &Silent).expect("cornell bake");
        path
    })
}

/// Starts `view` with `args` and reads until it serves: the address it printed on stdout
/// and what it wrote on stderr before serving. The server is stopped before returning.
fn start(args: &[&str]) -> (String, String) {
    let mut child: Child = Command::new(env!("CARGO_BIN_EXE_view"))
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("view starts");
    let mut address = String::new();
    BufReader::new(child.stdout.take().expect("stdout"))
        .read_line(&mut address)
        .expect("stdout line");
    let mut stderr = String::new();
    let mut lines = BufReader::new(child.stderr.take().expect("stderr"));
    // Everything up to the line that says it serves.
    while !stderr.contains("serving until interrupted") {
        let before = stderr.len();
        lines.read_line(&mut stderr).expect("stderr line");
        if stderr.len() == before {
            break;
        }
    }
    // The test's own child, stopped by its id.
    child.kill().expect("stop view");
    child.wait().expect("view stopped");
    (address.trim().to_string(), stderr)
}

#[test]
fn listens_only_on_this_machine_unless_told_and_then_warns() {
    let bake = bake().to_str().expect("utf-8 path");
    let (address, stderr) = start(&[bake, "--port", "0"]);
    assert!(
        address.starts_with("http://127.0.0.1:") && address.ends_with('/'),
        "default address {address:?}"
    );
    assert!(!stderr.contains("warning"), "{stderr}");
    assert!(stderr.contains("serving until interrupted"), "{stderr}");

    let (address, stderr) = start(&[bake, "--port", "0", "--listen", "0.0.0.0"]);
    assert!(address.starts_with("http://0.0.0.0:"), "{address:?}");
    assert!(
        stderr.contains("warning: listening on 0.0.0.0") && stderr.contains("no authentication"),
        "no warning for a non-local address: {stderr}"
    );
}

/// Runs `view` on a file it cannot use: it must exit with failure and one error line naming
/// the file, without panicking or serving.
fn refused(bake: &Path) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_view"))
        .arg(bake)
        .args(["--port", "0"])
        .output()
        .expect("view runs");
    let stderr = String::from_utf8_lossy(&out.stderr).to_string();
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        out.stdout.is_empty(),
        "printed an address: {:?}",
        out.stdout
    );
    assert!(stderr.starts_with("error: "), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    stderr
}

#[test]
fn a_bake_file_it_cannot_use_is_a_clear_error() {
    let dir = tempfile::tempdir().expect("temp dir");
    let missing = dir.path().join("missing.prtbake");
    let stderr = refused(&missing);
    assert!(stderr.contains("missing.prtbake"), "{stderr}");

    let not_a_bake = dir.path().join("notes.prtbake");
    std::fs::write(&not_a_bake, "these are notes, not a bake\n").expect("write");
    let stderr = refused(&not_a_bake);
    assert!(stderr.contains("notes.prtbake"), "{stderr}");

    // A real bake cut short.
    let bytes = std::fs::read(bake()).expect("read bake");
    let cut = dir.path().join("cut.prtbake");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).expect("write");
    let stderr = refused(&cut);
    assert!(stderr.contains("cut.prtbake"), "{stderr}");
}
