//! The vector kernels (AVX2, F16C) and the portable scalar kernels give bit-identical frames,
//! for f32 and f16 bakes and the low-rank variant. On a CPU without the vector instructions
//! both runs take the scalar path and the test checks nothing more than determinism.

use glam::Vec3;
use prt_bake::pixel::Precision;
use prt_runtime::hooks::Kernel;
use prt_runtime::{PixelRelighter, Variant};
use prt_tests::{bake_to_file, bases_for, small_options, test_scene};

#[test]
fn scalar_and_vector_kernels_give_bit_identical_frames() {
    #[cfg(target_arch = "x86_64")]
    eprintln!(
        "avx2: {}, f16c: {}",
        std::arch::is_x86_feature_detected!("avx2"),
        std::arch::is_x86_feature_detected!("f16c")
    );
    let scene = test_scene(Vec3::new(1.0, 0.8, 0.6), Vec3::new(0.05, 0.1, 0.2));
    let bases = bases_for(&scene, 4);
    for precision in [Precision::F32, Precision::F16] {
        // 29 pixels per row: groups have pixel runs that are not multiples of the tiles (8
        // wide portable, 16 wide AVX2), so the remainder loops run too.
        let mut opts = small_options(29, 18, 2, 2, precision);
        opts.compress_rank = Some(3);
        let (_, path) = bake_to_file(
            &scene,
            &bases,
            &opts,
            &format!("kernels-{}.prtbake", precision.name()),
        );
        let settings: [&[&str]; 2] = [
            &[],
            &[
                "shiny.shininess=120",
                "metal.alpha=0.08",
                "block.kd=0.9,0.3,0.1",
            ],
        ];
        for edits in settings {
            let mut r = PixelRelighter::open(&path).expect("open");
            for e in edits {
                prt_tests::edit_pixel(&mut r, e).expect("apply");
            }
            for variant in [Variant::Full, Variant::Compressed] {
                r.set_variant(variant).expect("variant");
                r.set_kernel(Kernel::Auto);
                let fast = r.render().expect("render").pixels;
                r.set_kernel(Kernel::Scalar);
                let scalar = r.render().expect("render").pixels;
                assert_eq!(fast.len(), scalar.len());
                assert!(fast.iter().flatten().any(|&v| v > 0.0), "black frame");
                let differ: Vec<usize> = (0..fast.len())
                    .filter(|&i| (0..3).any(|c| fast[i][c].to_bits() != scalar[i][c].to_bits()))
                    .collect();
                assert!(
                    differ.is_empty(),
                    "{} {variant:?} {edits:?}: {} pixels differ between the vector and scalar \
                     kernels, first {} ({:?} vs {:?})",
                    precision.name(),
                    differ.len(),
                    differ[0],
                    fast[differ[0]],
                    scalar[differ[0]]
                );
            }
        }
        let _ = std::fs::remove_file(&path);
    }
}
