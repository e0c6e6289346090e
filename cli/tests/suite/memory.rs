//! The memory estimate `bake` prints (and checks `--max-memory` against) compared with the
//! peak resident memory the process really reached, in both regimes: where the basis build is
//! the peak and where the trace and write are.

use std::path::{Path, PathBuf};
use std::process::Command;

use serde_json::Value;

fn scenes() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes")
}

/// Bakes `scene` at `size`x`size`, 1 spp, and returns the `--json` summary.
fn bake_json(scene: &str, size: u32, dir: &Path) -> Value {
    let out = dir.join(format!("{scene}-{size}.prtbake"));
    let size = size.to_string();
    let run = Command::new(env!("CARGO_BIN_EXE_bake"))
        .arg(scenes().join(scene))
        .args(["--width", &size, "--height", &size, "--spp", "1", "--json"])
        .arg("--out")
        .arg(&out)
        .output()
        .expect("spawn bake");
    assert!(
        run.status.success(),
        "bake {scene} failed: {}",
        String::from_utf8_lossy(&run.stderr)
    );
    serde_json::from_slice(&run.stdout).expect("--json output parses")
}

fn bytes(v: &Value, key: &str) -> f64 {
    v[key]
        .as_f64()
        .unwrap_or_else(|| panic!("'{key}' missing from {v}"))
}

#[cfg(target_os = "linux")]
#[test]
fn memory_estimate_is_within_25_percent_of_the_measured_peak() {
    let dir = tempfile::tempdir().expect("tempdir");
    // (scene, size, which phase the estimate says is the peak)
    let cases = [
        ("cornell", 128, "basis"),
        ("cornell", 1536, "trace"),
        ("furnace/furnace.glb", 256, "trace"),
    ];
    let mut failures = Vec::new();
    for (scene, size, phase) in cases {
        let j = bake_json(scene, size, dir.path());
        let est = bytes(&j, "estimated_bytes");
        let peak = bytes(&j, "peak_resident_bytes");
        let (basis, trace) = (
            bytes(&j, "estimated_basis_bytes"),
            bytes(&j, "estimated_trace_bytes"),
        );
        let predicted = if basis > trace { "basis" } else { "trace" };
        let ratio = est / peak;
        eprintln!(
            "{scene} {size}x{size}: estimate {:.1} MiB (basis {:.1}, trace {:.1}), peak {:.1} MiB, ratio {ratio:.3}",
            est / 1048576.0,
            basis / 1048576.0,
            trace / 1048576.0,
            peak / 1048576.0
        );
        assert_eq!(
            predicted, phase,
            "{scene} {size}: the case must test the {phase} phase"
        );
        if !(0.75..=1.25).contains(&ratio) {
            failures.push(format!("{scene} {size}: estimate/peak = {ratio:.3}"));
        }
    }
    assert!(failures.is_empty(), "{failures:?}");
}
