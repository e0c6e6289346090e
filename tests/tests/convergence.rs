//! Convergence (issue 4 test (b)): a bake relit for several material settings against the
//! true-BRDF reference at a high sample count, on the example scenes at small sizes. The
//! yardstick is a true-BRDF path trace with the bake's own sample count (another seed): the
//! bake must be about as close to the converged image as a render of equal cost, plus the
//! basis' projection error.

use std::path::PathBuf;

use prt_bake::pixel::{self, PixelBakeOptions, Precision, SlotLayout};
use prt_bake::progress::Silent;
use prt_bake::reference::render_true;
use prt_bake::run::{apply_override, build_bases, load, BasisCount};
use prt_bake::scene::Scene;
use prt_formats::overrides::parse_override;
use prt_runtime::{Relighter, Variant};
use prt_tests::{relative_l2, temp_path};

fn scene_config(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join("scenes")
        .join(name)
        .join("bake.toml")
}

fn reference(
    scene: &Scene,
    reflections: usize,
    w: u32,
    h: u32,
    spp: u32,
    seed: u64,
) -> Vec<[f32; 3]> {
    render_true(scene, reflections, w, h, spp, seed, None)
        .pixels
        .iter()
        .map(|p| p.to_array())
        .collect()
}

fn check_scene(
    name: &str,
    settings: &[&[&str]],
    size: (u32, u32),
    spp: u32,
    ref_spp: u32,
    slack: f64,
) {
    let (config, scene) = load(&scene_config(name), &Silent).expect("load scene");
    let reflections = config.reflections as usize;
    let bases = build_bases(&scene, BasisCount::Fixed(6), &Silent).expect("bases");
    let layout = SlotLayout::new(&scene, &bases).expect("layout");
    let opts = PixelBakeOptions {
        width: size.0,
        height: size.1,
        spp,
        reflections: config.reflections,
        seed: 1,
        precision: Precision::F32,
        max_memory: None,
        compress_rank: None,
    };
    let bake = pixel::bake(&scene, &layout, &opts, None).expect("bake");
    let path = temp_path(&format!("convergence-{name}.prtbake"));
    pixel::write_bake_file(&bake, &path, Precision::F32).expect("write");
    for edits in settings {
        let mut relight = Relighter::open(&path).expect("open");
        let mut truth = scene.clone();
        for e in *edits {
            let o = parse_override(e).expect("override");
            relight.apply(&o).expect("apply");
            apply_override(&mut truth, &o).expect("apply to scene");
        }
        let relit = relight.render(Variant::Full).expect("relight").pixels;
        let converged = reference(&truth, reflections, size.0, size.1, ref_spp, 1000);
        let equal_cost = reference(&truth, reflections, size.0, size.1, spp, 2000);
        let e_bake = relative_l2(&relit, &converged);
        let e_path = relative_l2(&equal_cost, &converged);
        eprintln!("{name} {edits:?}: bake {e_bake:.4}, path trace at equal spp {e_path:.4}");
        assert!(
            e_bake < 1.5 * e_path + slack,
            "{name} {edits:?}: relative L2 error {e_bake} vs {e_path} for a path trace of equal spp"
        );
    }
    let _ = std::fs::remove_file(&path);
}

#[test]
fn cornell_relit_converges_to_the_reference() {
    check_scene(
        "cornell",
        &[
            &[],
            &["bunny.kd=0.8,0.2,0.2", "bunny.shininess=150"],
            &[
                "tall_box.alpha=0.05",
                "tall_box.ks=0.8",
                "bunny.shininess=5",
            ],
        ],
        (32, 32),
        32,
        1024,
        0.02,
    );
}

#[test]
fn ring_relit_converges_to_the_reference() {
    check_scene(
        "ring",
        &[
            &[],
            &["ring.shininess=30"],
            &["ring.shininess=120", "ring.ks=0.5,0.4,0.1"],
        ],
        (32, 32),
        32,
        1024,
        0.02,
    );
}
