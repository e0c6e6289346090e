//! Asset pipelines expect reproducible files: the same config and seed give a byte-identical
//! bake file on any thread count, and on a second run (no timings or other run-dependent
//! figures in the file).

use std::path::{Path, PathBuf};

use prt_bake::pixel::Precision;
use prt_bake::progress::Silent;
use prt_bake::run::{load, run_pixel, PixelRunSettings};
use prt_tests::temp_path;

fn config(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("../scenes/{name}/bake.toml"))
}

/// Bakes `scene` small through the whole pipeline (bases, layout, bake, compression, file) on
/// `threads` threads; returns the file's bytes.
fn bake_bytes(scene: &str, threads: usize, precision: Precision, tag: &str) -> Vec<u8> {
    let (config, loaded) = load(&config(scene), &Silent).expect("load");
    let out = temp_path(&format!("reproducible-{scene}-{tag}.prtbake"));
    let settings = PixelRunSettings {
        width: Some(24),
        height: Some(20),
        spp: Some(2),
        output: Some(out.clone()),
        precision: Some(precision),
        compress_rank: Some(3),
        basis_count: Some(3),
        ..Default::default()
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("pool");
    pool.install(|| run_pixel(&config, &loaded, &settings, &Silent).expect("bake"));
    let bytes = std::fs::read(&out).expect("read bake file");
    let _ = std::fs::remove_file(&out);
    bytes
}

#[test]
fn same_inputs_give_a_byte_identical_file_on_any_thread_count() {
    for (scene, precision) in [("cornell", Precision::F32), ("ring", Precision::F16)] {
        let one = bake_bytes(scene, 1, precision, "1");
        let two = bake_bytes(scene, 2, precision, "2");
        // A second run on the same thread count catches run-dependent content (timings).
        let again = if scene == "cornell" {
            bake_bytes(scene, 2, precision, "2-again")
        } else {
            two.clone()
        };
        assert!(!one.is_empty());
        let first_difference = |a: &[u8], b: &[u8]| {
            a.iter()
                .zip(b)
                .position(|(x, y)| x != y)
                .unwrap_or(a.len().min(b.len()))
        };
        assert!(
            one == two,
            "{scene}: 1 vs 2 threads differ (sizes {} and {}, first difference at byte {})",
            one.len(),
            two.len(),
            first_difference(&one, &two)
        );
        assert!(
            two == again,
            "{scene}: two runs on 2 threads differ (first difference at byte {})",
            first_difference(&two, &again)
        );
    }
}
