//! Shards through the binaries, as a cluster runs them: N `bake --shard I/N` processes at once
//! (per pixel and per vertex), `bake merge` of their files gives the unsharded bake's bytes; a
//! shard killed part-way resumes with `--resume`; merge refuses a missing, duplicated, truncated
//! or foreign shard, naming it, and writes nothing.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use crate::bad_input::{fails, s, scenes};
use crate::vertex::diffuse_vitrine;

const BAKE: &str = env!("CARGO_BIN_EXE_bake");

/// Runs `bake args` to success on `threads` threads; returns its stderr.
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

fn spawn(args: &[String], threads: &str) -> Child {
    Command::new(BAKE)
        .args(args)
        .env("RAYON_NUM_THREADS", threads)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn bake")
}

/// The shard files `bake --out out --shard I/N` writes, I = 0..N.
fn shard_files(out: &Path, count: u32) -> Vec<PathBuf> {
    (0..count)
        .map(|i| PathBuf::from(format!("{}.shard-{i}-of-{count}", out.display())))
        .collect()
}

/// Bakes `base` unsharded, then as `count` shard processes running at once (one thread each),
/// merges them (given in reverse order) and asserts the merged file is the unsharded one's bytes.
/// Returns the shard files.
fn sharded_equals_whole(base: &[&str], dir: &Path, count: u32) -> (PathBuf, Vec<PathBuf>) {
    let whole = dir.join("whole.prtbake");
    let mut args: Vec<&str> = base.to_vec();
    args.extend(["--out", s(&whole), "--quiet"]);
    bake(&args, "2");
    let want = std::fs::read(&whole).expect("whole bake");

    let out = dir.join("sharded.prtbake");
    let children: Vec<Child> = (0..count)
        .map(|i| {
            let mut args: Vec<String> = base.iter().map(|a| a.to_string()).collect();
            args.extend([
                "--out".into(),
                s(&out).into(),
                "--quiet".into(),
                "--shard".into(),
                format!("{i}/{count}"),
            ]);
            spawn(&args, "1")
        })
        .collect();
    for child in children {
        let o = child.wait_with_output().expect("shard");
        assert!(
            o.status.success(),
            "shard failed: {}",
            String::from_utf8_lossy(&o.stderr)
        );
    }
    assert!(!out.exists(), "a shard wrote the bake file itself");
    let shards = shard_files(&out, count);
    let mut merge: Vec<&str> = vec!["merge"];
    merge.extend(shards.iter().rev().map(|p| s(p)));
    merge.extend(["--out", s(&out)]);
    bake(&merge, "2");
    let got = std::fs::read(&out).expect("merged bake");
    assert_eq!(got.len(), want.len(), "merged and whole sizes differ");
    let first = got.iter().zip(&want).position(|(a, b)| a != b);
    assert_eq!(
        first, None,
        "the merged file differs from byte {first:?} on"
    );
    (out, shards)
}

#[test]
fn pixel_shards_baked_at_once_merge_to_the_unsharded_bytes() {
    let dir = tempfile::tempdir().expect("temp dir");
    let cornell = scenes().join("cornell/bake.toml");
    let base = [s(&cornell), "--width", "24", "--height", "20", "--spp", "2"];
    sharded_equals_whole(&base, dir.path(), 4);
}

#[test]
fn vertex_shards_merge_to_the_unsharded_bytes_resume_and_merge_refuses_bad_sets() {
    let dir = tempfile::tempdir().expect("temp dir");
    let config = diffuse_vitrine(dir.path());
    let (out, shards) = sharded_equals_whole(&[s(&config)], dir.path(), 4);

    // A shard killed once its checkpoint holds a finished unit resumes to the same file.
    let again = dir.path().join("again.prtbake");
    let args: Vec<String> = [s(&config), "--out", s(&again), "--shard", "2/4"]
        .iter()
        .map(|a| a.to_string())
        .collect();
    let checkpoint = PathBuf::from(format!("{}.shard-2-of-4.partial", again.display()));
    let mut child = spawn(&args, "1");
    let start = Instant::now();
    let has_piece = |dir: &Path| {
        std::fs::read_dir(dir).is_ok_and(|d| {
            d.filter_map(|e| e.ok())
                .any(|e| e.file_name().to_string_lossy().ends_with(".piece"))
        })
    };
    while !has_piece(&checkpoint) {
        if let Some(status) = child.try_wait().expect("poll") {
            let o = child.wait_with_output().expect("output");
            panic!(
                "the shard ended ({status}) before saving a unit: {} (checkpoint {})",
                String::from_utf8_lossy(&o.stderr),
                checkpoint.display()
            );
        }
        assert!(start.elapsed() < Duration::from_secs(300), "no checkpoint");
        std::thread::sleep(Duration::from_millis(10));
    }
    child.kill().expect("SIGKILL");
    let _ = child.wait();
    let mut resume: Vec<&str> = args.iter().map(String::as_str).collect();
    resume.push("--resume");
    let log = bake(&resume, "2");
    assert!(log.contains("resuming from"), "{log}");
    let resumed = std::fs::read(format!("{}.shard-2-of-4", again.display())).expect("shard");
    assert_eq!(
        resumed,
        std::fs::read(&shards[2]).expect("shard"),
        "a resumed shard differs from one baked at once"
    );

    // Merge refuses bad sets, naming the problem, and writes nothing.
    let merged = dir.path().join("refused.prtbake");
    let m = |files: &[&Path]| -> Vec<String> {
        let mut a: Vec<String> = vec!["merge".into()];
        a.extend(files.iter().map(|p| s(p).to_string()));
        a.extend(["--out".into(), s(&merged).into()]);
        a
    };
    let refuse = |files: &[&Path], expect: &[&str]| {
        let args = m(files);
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        fails(BAKE, &args, expect, &merged);
    };
    let [a, b, c, d] = [&shards[0], &shards[1], &shards[2], &shards[3]].map(PathBuf::as_path);
    refuse(&[a, b, d], &["4 shards", "shard 2 is missing"]);
    refuse(&[a, b, c, d, c], &["both shard 2/4"]);
    let truncated = dir.path().join("truncated.shard");
    let bytes = std::fs::read(c).expect("shard");
    std::fs::write(&truncated, &bytes[..bytes.len() * 2 / 3]).expect("write");
    refuse(&[a, b, &truncated, d], &["truncated.shard"]);
    let foreign = dir.path().join("foreign.prtbake");
    let seed = config.with_file_name("seed.toml");
    let text = std::fs::read_to_string(&config).expect("config");
    std::fs::write(&seed, text.replace("seed = 3", "seed = 4")).expect("write");
    bake(
        &[s(&seed), "--out", s(&foreign), "--shard", "2/4", "--quiet"],
        "2",
    );
    let foreign_shard = PathBuf::from(format!("{}.shard-2-of-4", foreign.display()));
    refuse(
        &[a, b, &foreign_shard, d],
        &["foreign.prtbake.shard-2-of-4", "another bake", "seed"],
    );
    let scene = scenes().join("vitrine/vitrine.gltf");
    refuse(&[a, b, &scene, d], &["vitrine.gltf"]);
    assert!(out.exists());
}
