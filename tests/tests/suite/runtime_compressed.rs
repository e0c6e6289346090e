//! The low-rank (PCA over pixels) variant against the full one: at full rank the compressed
//! relight is the full relight up to float rounding; at a low rank it differs, and per pixel
//! by no more than the rows' reconstruction error allows (Cauchy-Schwarz:
//! |W (x - x^)| <= ||W|| ||x - x^|| per group, summed over the pixel's groups).

use glam::Vec3;
use prt_bake::pixel::Precision;
use prt_formats::pixel::{group_weights, names};
use prt_formats::BakeFile;
use prt_runtime::{PixelRelighter, Variant};
use prt_tests::{
    assert_same_size, bake_to_file, bases_for, relative_l2, small_options, test_scene,
};

const EDITS: [&[&str]; 2] = [
    &[],
    &[
        "shiny.kd=0.1,0.8,0.3",
        "shiny.shininess=150",
        "metal.alpha=0.05",
        "block.kd=0.9,0.2,0.1",
    ],
];

fn relit(
    path: &std::path::Path,
    edits: &[&str],
    variant: Variant,
) -> (PixelRelighter, Vec<[f32; 3]>) {
    let mut r = PixelRelighter::open(path).expect("open");
    for e in edits {
        prt_tests::edit_pixel(&mut r, e).expect("apply");
    }
    r.set_variant(variant).expect("variant");
    let px = r.render().expect("render").pixels;
    (r, px)
}

/// Per-pixel bound on |full - compressed| for the relighter's current settings: for every
/// group, ||W_c|| times the norm of the pixel's row reconstruction error.
fn cauchy_schwarz_bound(r: &PixelRelighter, file: &BakeFile) -> Vec<[f64; 3]> {
    let meta = r.meta();
    let (coeff, _) = r.coefficients();
    let mut bound = vec![[0.0f64; 3]; (meta.width * meta.height) as usize];
    for (g, gm) in meta.groups.iter().enumerate() {
        let m = &meta.materials[gm.material as usize];
        let w = group_weights(
            gm,
            m,
            &coeff,
            meta.reflections as usize,
            meta.channels as usize,
            meta.tint,
        );
        let len = gm.row_len as usize;
        let wn: Vec<f64> = (0..3)
            .map(|c| {
                w[c * len..(c + 1) * len]
                    .iter()
                    .map(|&v| (v as f64).powi(2))
                    .sum::<f64>()
                    .sqrt()
            })
            .collect();
        let pixels = file.tensor(&names::pixels(g)).expect("pixels");
        let pixels = pixels.as_u32().expect("u32");
        let np = pixels.len();
        let t = file.tensor(&names::transfer(g)).expect("t");
        let t = t.as_f32().expect("f32 bake");
        let k = gm.compressed_rank.expect("compressed") as usize;
        let mean = file.tensor(&names::mean(g)).expect("mean");
        let mean = mean.as_f32().expect("f32");
        let comps = file.tensor(&names::components(g)).expect("components");
        let comps = comps.as_f32().expect("f32");
        let z = file.tensor(&names::weights(g)).expect("weights");
        let z = z.as_f32().expect("f32");
        for (i, &p) in pixels.iter().enumerate() {
            let mut err2 = 0.0f64;
            for e in 0..len {
                let approx = mean[e] as f64
                    + (0..k)
                        .map(|r| comps[r * len + e] as f64 * z[r * np + i] as f64)
                        .sum::<f64>();
                err2 += (t[e * np + i] as f64 - approx).powi(2);
            }
            for c in 0..3 {
                bound[p as usize][c] += wn[c] * err2.sqrt();
            }
        }
    }
    bound
}

#[test]
fn full_rank_compression_relights_like_the_full_variant() {
    let scene = test_scene(Vec3::new(1.0, 0.8, 0.6), Vec3::new(0.05, 0.1, 0.2));
    let bases = bases_for(&scene, 4);
    // 6 x 5 pixels: every group has fewer pixels than values per row, so a rank of 64 keeps
    // every component the data has.
    let mut opts = small_options(6, 5, 4, 2, Precision::F32);
    opts.compress_rank = Some(64);
    let (_, path) = bake_to_file(&scene, &bases, &opts, "compressed-full-rank.prtbake");
    let r = PixelRelighter::open(&path).expect("open");
    for g in &r.meta().groups {
        // The data's rank is at most min(pixels, row length): 64 must not be what caps it.
        let data_rank_cap = g.pixels.min(g.row_len) as usize;
        assert!(
            data_rank_cap <= 64 && g.compressed_rank.is_some(),
            "a group of {} pixels with rows of {}: rank 64 may be below the data's rank",
            g.pixels,
            g.row_len
        );
    }
    for edits in EDITS {
        let (_, full) = relit(&path, edits, Variant::Full);
        let (_, comp) = relit(&path, edits, Variant::Compressed);
        assert_same_size(&comp, &full);
        let peak = full.iter().flatten().fold(0.0f32, |m, v| m.max(v.abs()));
        assert!(peak > 0.0, "black image");
        let mut worst = 0.0f32;
        for (a, b) in comp.iter().zip(&full) {
            for c in 0..3 {
                worst = worst.max((a[c] - b[c]).abs() / b[c].abs().max(1e-2 * peak));
            }
        }
        eprintln!("full rank {edits:?}: worst relative difference {worst:.2e}");
        assert!(
            worst < 1e-4,
            "{edits:?}: full-rank compressed relight differs from full by {worst} (relative)"
        );
    }
    let _ = std::fs::remove_file(&path);
}

#[test]
fn low_rank_compression_differs_within_its_reconstruction_error() {
    let scene = test_scene(Vec3::new(1.0, 0.8, 0.6), Vec3::new(0.05, 0.1, 0.2));
    let bases = bases_for(&scene, 4);
    let mut opts = small_options(24, 16, 4, 2, Precision::F32);
    opts.compress_rank = Some(2);
    let (_, path) = bake_to_file(&scene, &bases, &opts, "compressed-rank-2.prtbake");
    let file = BakeFile::open(&path).expect("file");
    for edits in EDITS {
        let (_, full) = relit(&path, edits, Variant::Full);
        let (r, comp) = relit(&path, edits, Variant::Compressed);
        assert_same_size(&comp, &full);
        let err = relative_l2(&comp, &full);
        eprintln!("rank 2 {edits:?}: relative L2 vs full {err:.3e}");
        assert!(
            err > 1e-4,
            "{edits:?}: rank 2 relights like full ({err}): is the compressed variant used?"
        );
        let bound = cauchy_schwarz_bound(&r, &file);
        for (i, ((a, b), bd)) in comp.iter().zip(&full).zip(&bound).enumerate() {
            for c in 0..3 {
                let d = (a[c] - b[c]).abs() as f64;
                // The bound is exact arithmetic; allow f32 rounding of the two contractions.
                let slack = 1e-5 * (b[c].abs() as f64 + bd[c]) + 1e-7;
                assert!(
                    d <= bd[c] + slack,
                    "{edits:?}: pixel {i} channel {c}: |full - rank 2| = {d:.3e} exceeds \
                     the rows' reconstruction bound {:.3e}",
                    bd[c]
                );
            }
        }
    }
    let _ = std::fs::remove_file(&path);
}
