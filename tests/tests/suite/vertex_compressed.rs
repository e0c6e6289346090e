//! Compressed per-vertex transfer end to end (docs/vertex.md "Compression"): the exactness
//! scene baked once dense and several times compressed (clustered Tucker, the same traced
//! paths), each written and opened with `VertexRelighter`, lit by a turned, asymmetric map
//! with edited materials.
//!
//! - At full rank (error target 0, no cap binding) the compressed file must relight like the
//!   dense one: every vertex's I1, I2, E and U within 1e-4 of the magnitudes (the Tucker
//!   factors are exact to f64 eigen-solver rounding, stored in f32).
//! - With an error target the ranks drop, the error each group reports stays within the
//!   target, and the relit image moves away from the dense one by no more than the target
//!   allows (the image is T0's direct light plus the compressed part, so its error is a
//!   fraction of the tensors').

use prt_bake::accel::Accel;
use prt_bake::basis::shading::default_shading_basis;
use prt_bake::brdf::Family;
use prt_bake::integrator::Integrator;
use prt_bake::lights::LightSet;
use prt_bake::pixel::SlotPlan;
use prt_bake::vertex::{bake_vertex_with, prepare_scene, VertexBakeOptions, VertexPlan};
use prt_formats::clustered::CompressionSettings;
use prt_formats::pixel::Precision;
use prt_runtime::hooks::VertexIncident;
use prt_runtime::VertexRelighter;
use prt_tests::{relative_l2, small_basis, temp_path};

use super::vertex_exactness::{environment, scene, EDITS};

/// Bakes the exactness scene with `compression` (None: dense) and opens it relit.
fn relit(name: &str, compression: Option<CompressionSettings>) -> VertexRelighter {
    // Welded and ordered by unit, as every per-vertex bake is: the tracer below sees the same
    // vertices as the file.
    let prepared = prepare_scene(&scene());
    let scene = prepared.scene;
    let bases = vec![small_basis(Family::Ggx, 4)];
    let shading = vec![default_shading_basis(Family::Ggx).expect("GGX shading basis")];
    let opts = VertexBakeOptions {
        samples: 32,
        secondary: 2,
        reflections: 3,
        precision: Precision::F32,
        compression,
        ..Default::default()
    };
    let counts: Vec<_> = bases.iter().map(|b| (b.family, b.num_bases)).collect();
    let slots = SlotPlan::per_unit_radiance(&scene, &counts).expect("slot plan");
    let accel = Accel::build(&scene);
    let lights = LightSet::new(&scene);
    let integ = Integrator::new(&scene, &accel, &lights, 3, 1, 1);
    let plan = VertexPlan::new(&integ, slots, &opts, prepared.units, None).expect("vertex plan");
    let path = temp_path(name);
    bake_vertex_with(&integ, &plan, &bases, &shading, &opts, &path, None).expect("bake");
    let mut r = VertexRelighter::open(&path).expect("open");
    let (w, h, texels) = environment();
    r.set_environment_texels(w, h, texels.as_flattened())
        .expect("environment");
    r.set_environment_rotation(30.0).expect("rotation");
    for e in EDITS {
        prt_tests::edit_vertex(&mut r, e).expect("edit applies");
    }
    r
}

fn settings(target: f32, caps: u32) -> CompressionSettings {
    CompressionSettings {
        error_target: target,
        cluster_vertices: Some(24),
        max_light_rank: caps.min(384),
        max_element_rank: caps,
        max_vertex_rank: caps,
    }
}

/// Every vertex's incident terms, flat (I1, I2, E, U).
fn incident(r: &mut VertexRelighter) -> Vec<f32> {
    let n = r.meta().vertices as usize;
    let mut out = Vec::new();
    for v in 0..n {
        let Some(VertexIncident {
            irradiance,
            one_bounce_sh,
            two_bounce,
            incident,
            ..
        }) = r.vertex_incident(v).expect("stages")
        else {
            continue;
        };
        out.extend(one_bounce_sh.iter().flatten());
        out.extend(two_bounce);
        out.extend(irradiance);
        out.extend(incident.iter().flatten());
    }
    out
}

fn image(r: &mut VertexRelighter) -> Vec<[f32; 3]> {
    r.set_size(48, 36).expect("size");
    r.render().expect("render").pixels
}

#[test]
fn full_rank_compression_relights_like_the_dense_bake() {
    let mut dense = relit("compressed-dense.prt", None);
    let mut full = relit("compressed-full.prt", Some(settings(0.0, 100_000)));
    for g in &full.meta().groups {
        let c = g.compression.as_ref().expect("compressed group");
        assert!(c.t1.error < 1e-6, "full rank reports error {}", c.t1.error);
    }
    let (a, b) = (incident(&mut dense), incident(&mut full));
    assert_eq!(a.len(), b.len());
    let scale = a.iter().fold(0.0f32, |m, x| m.max(x.abs()));
    let worst = a
        .iter()
        .zip(&b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0f32, f32::max);
    println!("full rank: largest incident difference {worst:e} of {scale:e}");
    assert!(scale > 0.0 && worst <= 1e-4 * scale, "{worst} of {scale}");
    let e = relative_l2(&image(&mut full), &image(&mut dense));
    assert!(e < 1e-4, "image rel. L2 {e}");
}

#[test]
fn the_error_target_bounds_the_reported_error_and_the_image_follows() {
    let mut dense = relit("compressed-ref.prt", None);
    let reference = image(&mut dense);
    let mut last = 0.0;
    for target in [0.02f32, 0.2, 0.5] {
        let mut r = relit(
            &format!("compressed-{target}.prt"),
            Some(settings(target, 100_000)),
        );
        // The target bounds the error beyond the dense tensors' noise n; against the dense
        // tensor, the discarded energy is at most target^2 of the signal plus the noise, so
        // error^2 <= target^2 (1 - n^2) + n^2 (docs/vertex.md, "What the error target means").
        let mut allowed = f64::from(target);
        for (gi, g) in r.meta().groups.iter().enumerate() {
            let c = g.compression.as_ref().expect("compressed group");
            for (what, t) in [("T1", Some(c.t1)), ("T2", c.t2)] {
                let t = t.expect("T1 and T2 compressed");
                let beyond = t.beyond_noise.expect("the error beyond the noise");
                let n = f64::from(t.noise.expect("the noise"));
                assert!(
                    beyond <= target + 1e-5,
                    "target {target}, group {gi}: {what} error beyond the noise {beyond}"
                );
                let bound = (f64::from(target).powi(2) * (1.0 - n * n) + n * n).sqrt();
                assert!(
                    f64::from(t.error) <= bound + 1e-5,
                    "target {target}, group {gi}: {what} error {} above {bound} (noise {n})",
                    t.error
                );
                allowed = allowed.max(bound);
            }
        }
        let e = relative_l2(&image(&mut r), &reference);
        println!("target {target}: image rel. L2 against dense {e:.5}");
        // The image error never exceeds the tensors' and grows as the target loosens.
        assert!(
            e <= allowed,
            "target {target}: image error {e} above {allowed}"
        );
        assert!(
            e >= last,
            "target {target}: {e} below the tighter target's {last}"
        );
        last = e;
    }
    assert!(last > 1e-3, "a 50 % target changed nothing ({last})");
}
