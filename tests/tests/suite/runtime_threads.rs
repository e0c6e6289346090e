//! The runtime is deterministic on any thread count: relighting on 1 and on 3 threads gives
//! bit-identical frames (each band of rows is contracted by one thread, in a fixed order), for
//! the full and the low-rank variant and for f32 and f16 storage.

use glam::Vec3;
use prt_bake::pixel::Precision;
use prt_runtime::{PixelRelighter, Variant};
use prt_tests::{bake_to_file, bases_for, small_options, test_scene};

fn bits(px: &[[f32; 3]]) -> Vec<u32> {
    px.iter().flatten().map(|v| v.to_bits()).collect()
}

#[test]
fn relight_is_bit_identical_on_one_and_three_threads() {
    let scene = test_scene(Vec3::new(1.0, 0.8, 0.6), Vec3::new(0.05, 0.1, 0.2));
    let bases = bases_for(&scene, 4);
    for precision in [Precision::F32, Precision::F16] {
        // 40 rows: several bands of rows, so the threads share the image.
        let mut opts = small_options(36, 40, 2, 2, precision);
        opts.compress_rank = Some(3);
        let (_, path) = bake_to_file(
            &scene,
            &bases,
            &opts,
            &format!("threads-{}.prtbake", precision.name()),
        );
        let mut r = PixelRelighter::open(&path).expect("open");
        for e in ["shiny.shininess=90", "metal.ks=0.3,0.9,0.6", "block.kd=0.2"] {
            prt_tests::edit_pixel(&mut r, e).expect("apply");
        }
        for variant in [Variant::Full, Variant::Compressed] {
            r.set_variant(variant).expect("variant");
            let frame = |threads| {
                rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .expect("pool")
                    .install(|| r.render().expect("render").pixels)
            };
            let (one, three) = (frame(1), frame(3));
            assert_eq!(one.len(), (36 * 40) as usize);
            assert!(one.iter().flatten().any(|&v| v > 0.0), "black frame");
            let diff = bits(&one)
                .iter()
                .zip(bits(&three))
                .filter(|(a, b)| **a != *b)
                .count();
            assert!(
                one.len() == three.len() && diff == 0,
                "{} {variant:?}: {diff} values differ between 1 and 3 threads",
                precision.name()
            );
        }
        let _ = std::fs::remove_file(&path);
    }
}
