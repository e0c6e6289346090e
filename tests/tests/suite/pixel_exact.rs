//! Exactness: relighting a bake with coefficients c equals the reference render with the
//! projected BRDFs sum_i c_i rho~_i, traced with the same random streams (docs/pixel.md,
//! "Exactness"). Any slot-bookkeeping bug in the baker, the file or the runtime shows here.

use glam::Vec3;
use prt_bake::accel::Accel;
use prt_bake::integrator::Integrator;
use prt_bake::lights::LightSet;
use prt_bake::pixel::{BakeModel, Precision, SlotLayout};
use prt_bake::reference::render;
use prt_bake::scene::Scene;
use prt_formats::overrides::parse_override;
use prt_formats::pixel::MaterialParams;
use prt_runtime::PixelRelighter;
use prt_tests::{assert_same_size, bake_to_file, bases_for, small_options, test_scene};

/// The projected-BRDF reference for the layout's materials with `edits` applied.
fn projected_reference(
    scene: &Scene,
    layout: &SlotLayout,
    edits: &[(usize, MaterialParams)],
    opts: &prt_bake::pixel::PixelBakeOptions,
) -> Vec<[f32; 3]> {
    let accel = Accel::build(scene);
    let lights = LightSet::new(scene);
    let integ = Integrator::new(
        scene,
        &accel,
        &lights,
        opts.reflections as usize,
        opts.width,
        opts.height,
    );
    let model = BakeModel::new(scene, layout);
    let coeff = layout.coefficients_per_material(edits);
    render(
        &integ,
        &model,
        &coeff,
        opts.spp,
        opts.emission_oversampling,
        opts.seed,
        None,
    )
    .pixels
    .iter()
    .map(|p| p.to_array())
    .collect()
}

fn check_exact(scene: &Scene, reflections: u32, expect_channels: u32) {
    let bases = bases_for(scene, 4);
    let opts = small_options(20, 14, 3, reflections, Precision::F32);
    let (layout, path) = bake_to_file(
        scene,
        &bases,
        &opts,
        &format!("exact-{reflections}-{expect_channels}.prtbake"),
    );
    let mut relight = PixelRelighter::open(&path).expect("open bake");
    assert_eq!(relight.meta().channels, expect_channels);

    let settings: [&[&str]; 3] = [
        &[],
        &[
            "shiny.kd=0.1,0.8,0.3",
            "shiny.shininess=150",
            "metal.alpha=0.05",
            "metal.ks=0.2,0.9,0.9",
        ],
        // Far outside the sampled ranges and large coefficients: the identity still holds.
        &[
            "shiny.shininess=1000",
            "shiny.ks=3",
            "block.kd=2,0.1,5",
            "metal.alpha=0.9",
        ],
    ];
    for edits in settings {
        let mut params: Vec<(usize, MaterialParams)> = Vec::new();
        for e in edits {
            let o = parse_override(e).expect("override");
            relight.set_params(&o.material, &[o.value]).expect("apply");
            let i = scene.material_index(&o.material).expect("material");
            params.push((i, relight.params(&o.material).expect("params")));
        }
        let frame = relight.render().expect("relight");
        let reference = projected_reference(scene, &layout, &params, &opts);
        let peak = reference
            .iter()
            .flatten()
            .fold(0.0f32, |m, v| m.max(v.abs()));
        assert!(peak > 0.0);
        assert_same_size(&frame.pixels, &reference);
        let mut worst = 0.0f32;
        for (a, b) in frame.pixels.iter().zip(&reference) {
            for c in 0..3 {
                // Relative per pixel, with a floor at 1e-3 of the image's peak for black pixels.
                let rel = (a[c] - b[c]).abs() / b[c].abs().max(1e-3 * peak);
                worst = worst.max(rel);
            }
        }
        assert!(
            worst < 1e-4,
            "edits {edits:?}: worst per-pixel relative difference {worst}"
        );
    }
    let _ = std::fs::remove_file(&path);
}

#[test]
fn relight_equals_projected_reference_gray_two_reflections() {
    // One light colour: gray tensors with the colour factored out.
    check_exact(&test_scene(Vec3::new(1.0, 0.8, 0.6), Vec3::ZERO), 2, 1);
}

#[test]
fn relight_equals_projected_reference_rgb_three_reflections() {
    // A differently coloured environment forces RGB tensors; three reflections exercise T2.
    check_exact(
        &test_scene(Vec3::new(1.0, 0.8, 0.6), Vec3::new(0.05, 0.1, 0.2)),
        3,
        3,
    );
}

#[test]
fn relight_equals_projected_reference_one_reflection() {
    check_exact(&test_scene(Vec3::ONE, Vec3::ZERO), 1, 1);
}

/// A textured editable material (its own Kd slot carrying the texture, RGB tensors) is exact
/// too.
#[test]
fn relight_equals_projected_reference_with_a_textured_editable_material() {
    let mut scene = test_scene(Vec3::ONE, Vec3::ZERO);
    scene.textures.push(prt_bake::scene::Texture {
        name: "checker".into(),
        width: 2,
        height: 2,
        texels: vec![
            Vec3::new(1.0, 0.2, 0.2),
            Vec3::new(0.2, 1.0, 0.2),
            Vec3::new(0.2, 0.2, 1.0),
            Vec3::new(0.9, 0.9, 0.1),
        ],
    });
    // UVs vary over the sphere so the texture varies across pixels.
    for (i, p) in scene.positions.clone().iter().enumerate() {
        scene.uvs[i] = glam::Vec2::new(p.x * 1.7, p.y * 2.3);
    }
    let shiny = scene.material_index("shiny").expect("shiny");
    scene.materials[shiny].base_color_texture = Some(0);
    check_exact(&scene, 2, 3);
}

/// The same config and seed give the same bake, bit for bit, on any thread count (the
/// low-rank variant included).
#[test]
fn bake_is_identical_on_any_thread_count() {
    let scene = test_scene(Vec3::new(1.0, 0.8, 0.6), Vec3::new(0.02, 0.03, 0.05));
    let bases = bases_for(&scene, 4);
    let layout = prt_bake::pixel::SlotLayout::new(&scene, &bases).expect("layout");
    let mut opts = small_options(20, 14, 3, 2, Precision::F32);
    opts.compress_rank = Some(4);
    let run = |threads| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("pool");
        pool.install(|| prt_bake::pixel::bake(&scene, &layout, &opts, None).expect("bake"))
    };
    let a = run(1);
    let b = run(3);
    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&a.emission), bits(&b.emission));
    assert_eq!(a.meta.groups, b.meta.groups);
    assert_eq!(a.groups.len(), b.groups.len());
    for (x, y) in a.groups.iter().zip(&b.groups) {
        assert_eq!(x.pixels, y.pixels);
        assert_eq!(bits(&x.rows), bits(&y.rows));
        let (cx, cy) = (
            x.compressed.as_ref().expect("compressed"),
            y.compressed.as_ref().expect("compressed"),
        );
        assert_eq!(bits(&cx.components), bits(&cy.components));
        assert_eq!(bits(&cx.weights), bits(&cy.weights));
        assert_eq!(bits(&cx.mean), bits(&cy.mean));
    }
}
