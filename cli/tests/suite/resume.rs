//! A per-vertex bake killed part-way (SIGKILL, no chance to clean up) and resumed with
//! `--resume` gives the same bytes as an uninterrupted bake, on another thread count; a resume
//! with other inputs and a bake that would silently reuse a checkpoint are refused; progress
//! goes to a non-terminal stderr as plain lines, and not with `--quiet`.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use crate::bad_input::{fails, s};
use crate::vertex::diffuse_vitrine;

const BAKE: &str = env!("CARGO_BIN_EXE_bake");

/// The finished units' pieces in a checkpoint folder (none when it does not exist).
fn pieces(dir: &Path) -> Vec<String> {
    let mut out: Vec<String> = std::fs::read_dir(dir)
        .map(|d| {
            d.filter_map(|e| e.ok()?.file_name().into_string().ok())
                .filter(|n| n.starts_with("unit") && n.ends_with(".piece"))
                .collect()
        })
        .unwrap_or_default();
    out.sort();
    out
}

/// Starts `bake args` on `threads` threads, waits until its checkpoint holds more than
/// `before` pieces, kills it (SIGKILL) and returns its stderr. Fails if it finishes first.
fn bake_and_kill(args: &[&str], threads: &str, checkpoint: &Path, before: usize) -> String {
    let mut child = Command::new(BAKE)
        .args(args)
        .env("RAYON_NUM_THREADS", threads)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn bake");
    let start = Instant::now();
    while pieces(checkpoint).len() <= before {
        if let Some(status) = child.try_wait().expect("poll bake") {
            let o = child.wait_with_output().expect("bake output");
            panic!(
                "bake ended ({status}) before its checkpoint grew past {before} pieces: {}",
                String::from_utf8_lossy(&o.stderr)
            );
        }
        assert!(start.elapsed() < Duration::from_secs(300), "no checkpoint");
        std::thread::sleep(Duration::from_millis(20));
    }
    child.kill().expect("SIGKILL");
    let o = child.wait_with_output().expect("bake output");
    assert!(!o.status.success(), "killed bake exited with {}", o.status);
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Runs `bake args` on `threads` threads to success; returns its stderr.
fn bake(args: &[&str], threads: &str) -> String {
    let o = Command::new(BAKE)
        .args(args)
        .env("RAYON_NUM_THREADS", threads)
        .output()
        .expect("spawn bake");
    let stderr = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(o.status.success(), "bake {args:?}: {stderr}");
    stderr
}

/// `config` with `from` replaced by `to`, written to `name` beside it.
fn edited(config: &Path, from: &str, to: &str, name: &str) -> PathBuf {
    let text = std::fs::read_to_string(config).expect("config");
    assert!(text.contains(from), "{from} not in {text}");
    let path = config.with_file_name(name);
    std::fs::write(&path, text.replace(from, to)).expect("write config");
    path
}

#[test]
fn a_killed_vertex_bake_resumes_to_the_same_bytes_and_refuses_other_inputs() {
    let dir = tempfile::tempdir().expect("temp dir");
    let config = diffuse_vitrine(dir.path());
    // In a folder that does not exist yet: the bake makes it (and the checkpoint in it).
    let whole = dir.path().join("new/whole.prtbake");
    let resumed = dir.path().join("resumed.prtbake");
    let checkpoint = dir.path().join("resumed.prtbake.partial");

    // Uninterrupted, two threads; stderr is a pipe, so progress comes as plain lines.
    let log = bake(&[s(&config), "--out", s(&whole)], "2");
    let progress: Vec<&str> = log
        .lines()
        .filter(|l| l.starts_with("baking vertices: ") && l.contains("/3106"))
        .collect();
    assert!(
        progress.len() >= 3 && progress.iter().any(|l| l.contains(" eta ")),
        "want progress lines with an ETA on a non-terminal stderr: {log}"
    );
    assert!(
        !dir.path().join("new/whole.prtbake.partial").exists(),
        "the checkpoint outlived a finished bake"
    );
    let want = std::fs::read(&whole).expect("uninterrupted bake");

    // Killed once its first wave is saved; --quiet shows no progress.
    let args = [s(&config), "--out", s(&resumed)];
    let quiet = bake_and_kill(&[args[0], args[1], args[2], "--quiet"], "2", &checkpoint, 0);
    assert!(
        !quiet.contains("baking vertices"),
        "--quiet printed progress: {quiet}"
    );
    assert!(!resumed.exists(), "a killed bake left an output");
    let saved = pieces(&checkpoint);

    // Without --resume the checkpoint is refused, not reused or overwritten.
    fails(
        BAKE,
        &args,
        &["resumed.prtbake.partial", "--resume"],
        &resumed,
    );
    // A resume with other inputs is refused, naming them.
    let seed = edited(&config, "seed = 3", "seed = 4", "seed.toml");
    fails(
        BAKE,
        &[s(&seed), "--out", s(&resumed), "--resume"],
        &["seed (3 in the checkpoint, 4 now)"],
        &resumed,
    );
    fails(
        BAKE,
        &[args[0], args[1], args[2], "--resume", "--spp", "5"],
        &["spp (4 in the checkpoint, 5 now)"],
        &resumed,
    );
    let kd = edited(
        &config,
        "kd = [0.5, 0.5, 0.5]",
        "kd = [0.5, 0.5, 0.6]",
        "kd.toml",
    );
    fails(
        BAKE,
        &[s(&kd), "--out", s(&resumed), "--resume"],
        &["materials"],
        &resumed,
    );
    assert_eq!(
        pieces(&checkpoint),
        saved,
        "a refused run touched the checkpoint"
    );

    // Resumed on one thread and killed again after one more wave, then resumed to the end.
    let resume = [args[0], args[1], args[2], "--resume"];
    bake_and_kill(&resume, "1", &checkpoint, saved.len());
    let log = bake(&resume, "1");
    assert!(log.contains("resuming from"), "{log}");
    assert!(
        !checkpoint.exists(),
        "the checkpoint outlived a finished bake"
    );
    let got = std::fs::read(&resumed).expect("resumed bake");
    assert_eq!(got.len(), want.len(), "file sizes differ");
    let first = got.iter().zip(&want).position(|(a, b)| a != b);
    assert_eq!(
        first, None,
        "the resumed file differs from byte {first:?} on"
    );
}

#[test]
fn kept_traced_tensors_recompress_with_other_compression_keys_without_tracing() {
    let dir = tempfile::tempdir().expect("temp dir");
    let config = diffuse_vitrine(dir.path());
    let kept = dir.path().join("kept.prtbake");
    let checkpoint = dir.path().join("kept.prtbake.partial");
    bake(&[s(&config), "--out", s(&kept), "--keep-traced"], "2");
    assert!(checkpoint.exists(), "--keep-traced removed the checkpoint");
    let first = std::fs::read(&kept).expect("first bake");

    // Other compression keys: not part of the checkpoint's inputs.
    let other = config.with_file_name("other.toml");
    let text = std::fs::read_to_string(&config).expect("config");
    std::fs::write(
        &other,
        format!("{text}\n[vertex]\ncompress_error = 0.3\nlight_rank = 4\n"),
    )
    .expect("write config");
    let fresh = dir.path().join("fresh.prtbake");
    bake(&[s(&other), "--out", s(&fresh), "--no-checkpoint"], "2");
    let want = std::fs::read(&fresh).expect("fresh bake");
    assert_ne!(want, first, "the compression keys changed nothing");

    // Resumed on one thread: every unit comes from its traced tensors (none is done: the
    // finished pieces were compressed with the old keys), the bytes are a fresh bake's with the
    // new keys, and the checkpoint goes once the file is written.
    let log = bake(&[s(&other), "--out", s(&kept), "--resume"], "1");
    let units = log
        .split(": 0 of ")
        .nth(1)
        .and_then(|rest| rest.split(' ').next())
        .unwrap_or_else(|| panic!("no 'resuming from ...: 0 of U units' line: {log}"));
    assert!(
        log.contains(&format!(
            "0 of {units} units already done, {units} to compress again from their traced tensors"
        )),
        "the resume traced again: {log}"
    );
    assert_eq!(
        std::fs::read(&kept).expect("recompressed bake"),
        want,
        "recompressing from the checkpoint differs from a fresh bake"
    );
    assert!(
        !checkpoint.exists(),
        "the checkpoint outlived a bake without --keep-traced"
    );
}
