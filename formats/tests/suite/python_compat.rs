//! Python/numpy compatibility: a bake file must load with `safetensors.numpy.load_file`, and
//! its checksums must be reproducible from the documented spec by an independent
//! implementation (formats/tests/python/check_numpy.py).
//!
//! Ignored by default because it needs a Python with `safetensors` and `numpy`, which the
//! project does not require:
//!
//! ```text
//! python3 -m venv /tmp/prt-pyenv && /tmp/prt-pyenv/bin/pip install safetensors numpy
//! PRT_PYTHON=/tmp/prt-pyenv/bin/python cargo test -p prt-formats --test suite python_compat -- --ignored
//! ```

use std::path::Path;
use std::process::Command;

use half::f16;
use prt_formats::BakeWriter;
use serde_json::json;

#[test]
#[ignore = "needs PRT_PYTHON pointing at a Python with safetensors and numpy"]
fn python_numpy_reads_bake_files() {
    let python = std::env::var("PRT_PYTHON")
        .expect("set PRT_PYTHON to a Python interpreter with safetensors and numpy installed");
    let dir = std::env::temp_dir().join(format!("prt-python-{}", std::process::id()));
    let path = dir.join("sample.prtbake");

    let t0: Vec<f32> = (0..24).map(|i| i as f32 * 0.25 - 3.0).collect();
    let half: Vec<f16> = (0..5).map(|i| f16::from_f32(i as f32 * 1.5)).collect();
    let ids = [0u32, 1, u32::MAX];
    let small: Vec<u16> = (0..7).map(|i| i * 1000).collect();
    let mask: Vec<u8> = (0..13).collect();
    let signed = [i32::MIN, -1, 0, i32::MAX];
    let mut w = BakeWriter::new();
    w.add_u8("mask", &[13], &mask).unwrap();
    w.add_f32("t0", &[2, 3, 4], &t0).unwrap();
    w.add_f16("half", &[5], &half).unwrap();
    w.add_u32("ids", &[3], &ids).unwrap();
    w.add_u16("small", &[7], &small).unwrap();
    w.add_i32("signed", &[2, 2], &signed).unwrap();
    w.set_metadata(json!({"materials": [{"name": "bunny", "family": "ggx"}]}));
    w.write_atomic(&path).unwrap();

    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/python/check_numpy.py");
    let out = Command::new(&python)
        .arg(&script)
        .arg(&path)
        .output()
        .unwrap_or_else(|e| panic!("cannot run {python}: {e}"));
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    println!("{stdout}{stderr}");
    assert!(
        out.status.success(),
        "Python check failed:\n{stdout}\n{stderr}"
    );
    assert!(stdout.starts_with("OK:"));
    let _ = std::fs::remove_dir_all(&dir);
}
