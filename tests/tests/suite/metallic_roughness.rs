//! A glTF metallicRoughnessTexture on a fixed material: its BRDF varies over the surface in
//! the reference tracer and in the per-pixel bake (one slot holding the material's own BRDF,
//! `SlotKind::Own`), which relit equals the reference.

use std::f32::consts::PI;

use glam::Vec3;
use prt_bake::brdf::BrdfParams;
use prt_bake::pixel::{PixelBakeOptions, Precision};
use prt_bake::scene::{GltfPbr, MetallicRoughnessMap, PunctualLight, Texture};
use prt_bake::testing::{look_at, SceneBuilder};
use prt_runtime::PixelRelighter;
use prt_tests::{bake_to_file, relative_l2};

use super::normal_maps::{mapped_square, square_uvs};

/// The square lit from 40 degrees off vertical towards +X, seen from above; its material's
/// factors say "rough metal" (metallic 1, roughness 1, the common export) and its texture,
/// 8 x 1 texels, makes the left half (u < 1/2) a rough dielectric (G = 1, B = 0: exactly
/// Lambertian, Kd = base) and the right half a smoother metal (G = 0.5, B = 1: GGX alpha
/// 0.25, Kd = 0, Ks = base). Returns the scene and the left half's closed-form radiance.
fn painted_square() -> (prt_bake::scene::Scene, f32) {
    let base = Vec3::new(0.8, 0.5, 0.3);
    let mut b = SceneBuilder::new();
    let pbr = GltfPbr {
        base,
        metallic: 1.0,
        roughness: 1.0,
    };
    let m = b.material(
        "painted",
        BrdfParams::from_gltf_pbr(pbr.base, pbr.metallic, pbr.roughness),
        Vec3::ZERO,
        false,
    );
    mapped_square(&mut b, 2, m);
    b.light(PunctualLight::Directional {
        direction: -towards_light(),
        irradiance: Vec3::splat(2.0),
    });
    b.camera(look_at(
        Vec3::new(0.0, 3.0, 1.0),
        Vec3::ZERO,
        Vec3::Y,
        20f32.to_radians(),
    ));
    let mut scene = b.build();
    square_uvs(&mut scene);
    let texels = (0..8)
        .map(|x| {
            if x < 4 {
                Vec3::new(0.0, 1.0, 0.0)
            } else {
                Vec3::new(0.0, 0.5, 1.0)
            }
        })
        .collect();
    scene.textures.push(Texture {
        name: "metallic-roughness".into(),
        width: 8,
        height: 1,
        texels,
    });
    scene.materials[m as usize].metallic_roughness = Some(MetallicRoughnessMap { texture: 0, pbr });
    (scene, base.x / PI * 2.0 * towards_light().y)
}

/// Where the light comes from: 40 degrees off vertical towards +X.
fn towards_light() -> Vec3 {
    let a = 40f32.to_radians();
    Vec3::new(a.sin(), a.cos(), 0.0)
}

/// Where the centre of pixel (x, y) of a `w x h` image of the scene's camera meets the
/// square's plane (y = 0).
fn pixel_hit(scene: &prt_bake::scene::Scene, w: u32, h: u32, x: u32, y: u32) -> Vec3 {
    let cam = &scene.camera;
    let t = (cam.yfov * 0.5).tan();
    let sx = (2.0 * (x as f32 + 0.5) / w as f32 - 1.0) * t * (w as f32 / h as f32);
    let sy = (1.0 - 2.0 * (y as f32 + 0.5) / h as f32) * t;
    let dir = (cam.forward + cam.right * sx + cam.up * sy).normalize();
    cam.position + dir * (-cam.position.y / dir.y)
}

/// The left half is the Lambertian closed form at every pixel; the right half the smoother
/// metal's BRDF (within 5 %: a pixel's samples spread over its footprint); and the
/// per-pixel bake relit equals the reference to float rounding (the same paths, one slot
/// holding the true BRDF). Ignoring the texture (the factors' rough metal everywhere) fails
/// the first check; evaluating the slot with the factors fails the last.
#[test]
fn a_metallic_roughness_texture_varies_the_brdf_in_the_reference_and_the_per_pixel_bake() {
    let (scene, lambert) = painted_square();
    let metal = BrdfParams {
        family: prt_bake::brdf::Family::Ggx,
        kd: Vec3::ZERO,
        ks: Vec3::new(0.8, 0.5, 0.3),
        param: 0.25,
    };
    let (w, h) = (32, 32);
    let reference = prt_bake::reference::render_true(&scene, 2, w, h, 4, 1, 5, None);
    let (mut left, mut right) = (0, 0);
    for y in 0..h {
        for x in 0..w {
            let p = pixel_hit(&scene, w, h, x, y);
            let v = reference.pixels[(y * w + x) as usize];
            // Pure texels: u in [1/16, 7/16] (left) and [9/16, 15/16] (right), with a margin
            // for the pixel's footprint.
            if (-0.75..-0.25).contains(&p.x) {
                left += 1;
                assert!(
                    (v.x - lambert).abs() <= 1e-4 * lambert,
                    "left half, pixel ({x}, {y}): {v} where a Lambertian base colour gives {lambert}"
                );
            } else if (0.25..0.75).contains(&p.x) {
                right += 1;
                // The metal's BRDF at the pixel's centre (the footprint's samples spread a
                // little around it), in a frame whose z is the normal +Y.
                let local = |d: Vec3| Vec3::new(d.x, d.z, d.y);
                let wo = local((scene.camera.position - p).normalize());
                let wi = local(towards_light());
                let want = metal.eval(wo, wi).x * 2.0 * wi.z;
                assert!(
                    (v.x - want).abs() <= 0.05 * want,
                    "right half, pixel ({x}, {y}): {v} where the metal gives {want}"
                );
            }
        }
    }
    assert!(
        left > 100 && right > 100,
        "{left} and {right} pixels checked"
    );

    let opts = PixelBakeOptions {
        width: w,
        height: h,
        spp: 4,
        emission_oversampling: 1,
        reflections: 2,
        seed: 5,
        precision: Precision::F32,
        max_memory: None,
        compress_rank: None,
    };
    let (layout, path) = bake_to_file(&scene, &[], &opts, "metallic-roughness.prt");
    assert_eq!(
        layout.materials[0].slots,
        vec![prt_formats::pixel::SlotKind::Own]
    );
    let relighter = PixelRelighter::open(&path).expect("open");
    // Listed as varying (`relight --list` says so).
    let info = &relighter.materials()[0];
    assert!(info.varying && !info.editable, "{info:?}");
    let relit = relighter.render().expect("relight");
    let reference: Vec<[f32; 3]> = reference.pixels.iter().map(|p| p.to_array()).collect();
    let err = relative_l2(&relit.pixels, &reference);
    assert!(err < 1e-5, "relit vs reference: {err:.2e}");
}
