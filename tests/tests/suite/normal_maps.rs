//! Normal maps (glTF `normalTexture`, `prt_formats::normal_map`) in every mode that shades
//! with a per-point normal: the reference tracer and the per-pixel bake at every path vertex
//! (a closed form), and the per-vertex runtime at the last reflection (against the reference).

use std::f32::consts::PI;

use glam::{Vec2, Vec3};
use prt_bake::brdf::{BrdfParams, Family};
use prt_bake::pixel::{PixelBakeOptions, Precision};
use prt_bake::scene::{Environment, PunctualLight, Scene, Texture};
use prt_bake::testing::{look_at, SceneBuilder};
use prt_runtime::{PixelRelighter, VertexRelighter};
use prt_tests::{bake_to_file, relative_l2, temp_path};

/// A square of side 2 in the XZ plane facing +Y, made of `n x n` cells, with texture
/// coordinates u = (x + 1) / 2 and v = (z + 1) / 2 once [`square_uvs`] sets them: the image's
/// right is +X and, since glTF's v runs down the image, its up is -Z.
pub(crate) fn mapped_square(b: &mut SceneBuilder, n: u32, material: u32) {
    let mut p = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            let (x, z) = (i as f32 / n as f32, j as f32 / n as f32);
            p.push(Vec3::new(2.0 * x - 1.0, 0.0, 2.0 * z - 1.0));
        }
    }
    let mut t = Vec::new();
    let at = |i: u32, j: u32| j * (n + 1) + i;
    for j in 0..n {
        for i in 0..n {
            // Counter-clockwise seen from +Y.
            t.push([at(i, j), at(i, j + 1), at(i + 1, j + 1)]);
            t.push([at(i, j), at(i + 1, j + 1), at(i + 1, j)]);
        }
    }
    b.mesh(&p, &vec![Vec3::Y; p.len()], &t, material);
}

/// Gives the scene's vertices the square's texture coordinates (every vertex lies on it).
pub(crate) fn square_uvs(scene: &mut Scene) {
    scene.uvs = scene
        .positions
        .iter()
        .map(|p| Vec2::new((p.x + 1.0) / 2.0, (p.z + 1.0) / 2.0))
        .collect();
}

/// Gives the scene's vertices the square's texture coordinates and material `m` a constant
/// normal map encoding `tilt` (unit, tangent space), stored decoded as the loader does.
fn add_map(scene: &mut Scene, m: usize, tilt: Vec3) {
    square_uvs(scene);
    // The texel that encodes `tilt` (c = (t + 1) / 2), decoded at scale 1.
    let c = ((tilt + Vec3::ONE) * 0.5).to_array();
    let decoded = Vec3::from_array(prt_formats::normal_map::decode_texel(c, 1.0));
    scene.textures.push(Texture {
        name: "tilt".into(),
        width: 4,
        height: 4,
        texels: vec![decoded; 16],
    });
    scene.materials[m].normal_texture = Some(scene.textures.len() - 1);
}

/// A unit vector tilted `deg` degrees from +Z towards `towards` (a unit vector of the XY
/// plane): the tangent-space normal of a map bent that way.
fn tilted(deg: f32, towards: Vec2) -> Vec3 {
    let a = deg.to_radians();
    Vec3::new(towards.x * a.sin(), towards.y * a.sin(), a.cos())
}

/// The diffuse square under a directional light coming from 40 degrees off vertical, on the
/// side `from` (a unit vector of the XZ plane), with a normal map tilted 25 degrees; seen from
/// above so that every pixel sees the square.
fn lit_square(tilt: Vec3, from: Vec3) -> (Scene, f32) {
    let mut b = SceneBuilder::new();
    let kd = 0.6;
    let m = b.material(
        "plane",
        BrdfParams::diffuse(Vec3::splat(kd)),
        Vec3::ZERO,
        true,
    );
    mapped_square(&mut b, 2, m);
    let a = 40f32.to_radians();
    let towards_light = (from * a.sin() + Vec3::Y * a.cos()).normalize();
    let irradiance = 2.0;
    b.light(PunctualLight::Directional {
        direction: -towards_light,
        irradiance: Vec3::splat(irradiance),
    });
    b.camera(look_at(
        Vec3::new(0.0, 3.0, 1.0),
        Vec3::ZERO,
        Vec3::Y,
        20f32.to_radians(),
    ));
    let mut scene = b.build();
    add_map(&mut scene, m as usize, tilt);
    // The map's tangent frame on this square: +u is +X, up the image is -Z, the normal +Y.
    let bent = (Vec3::X * tilt.x - Vec3::Z * tilt.y + Vec3::Y * tilt.z).normalize();
    let radiance = kd / PI * irradiance * bent.dot(towards_light).max(0.0);
    (scene, radiance)
}

/// A diffuse square lit by one directional light has the radiance `kd / pi E cos` with the
/// cosine taken about the **bent** normal, at every pixel and every sample (a delta light and
/// nothing else to hit: no noise), in the reference and in the per-pixel bake relit. Two maps:
/// one tilted towards the image's right (+u) under a light from +X, one towards its top (-v)
/// under a light from -Z; each gives cos(15 degrees), where an ignored map gives cos(40) and
/// a map read upside down or mirrored cos(65).
#[test]
fn a_normal_map_bends_the_reference_and_the_per_pixel_bake_by_its_closed_form() {
    let cases = [
        ("right", tilted(25.0, Vec2::X), Vec3::X),
        ("up", tilted(25.0, Vec2::Y), -Vec3::Z),
    ];
    for (name, tilt, from) in cases {
        let (scene, want) = lit_square(tilt, from);
        assert!(
            (want / (0.6 / PI * 2.0) - 15f32.to_radians().cos()).abs() < 1e-5,
            "{name}: the closed form is the cosine of 15 degrees"
        );
        let (w, h) = (24, 24);
        let reference = prt_bake::reference::render_true(&scene, 2, w, h, 4, 1, 7, None);
        for (i, p) in reference.pixels.iter().enumerate() {
            assert!(
                (p.x - want).abs() <= 1e-4 * want,
                "{name}: reference pixel {i}: {p} where the closed form gives {want}"
            );
        }
        let opts = PixelBakeOptions {
            width: w,
            height: h,
            spp: 4,
            emission_oversampling: 1,
            reflections: 2,
            seed: 7,
            precision: Precision::F32,
            max_memory: None,
            compress_rank: None,
        };
        let (_, path) = bake_to_file(&scene, &[], &opts, &format!("normal-map-{name}.prt"));
        let relighter = PixelRelighter::open(&path).expect("open");
        assert!(
            !relighter.materials()[0].varying,
            "a normal map alone varies no parameter"
        );
        let relit = relighter.render().expect("relight");
        for (i, p) in relit.pixels.iter().enumerate() {
            assert!(
                (p[0] - want).abs() <= 1e-4 * want,
                "{name}: relit pixel {i}: {p:?} where the closed form gives {want}"
            );
        }
    }
}

/// A linear sky, `L(d) = 1 + 0.9 d.x`, as a lat-long map: smooth, so that the per-vertex
/// mode's approximations (Tucker shading basis, prefiltered lookups) stay small, and bright
/// towards +X, so that a reflection turned towards +X is visibly brighter.
fn linear_sky() -> Environment {
    let (width, height) = (128u32, 64u32);
    let mut texels = Vec::with_capacity((width * height) as usize);
    for y in 0..height {
        for x in 0..width {
            let (u, v) = prt_formats::latlong::texel_centre(
                x as usize,
                y as usize,
                width as usize,
                height as usize,
            );
            let d = prt_formats::latlong::uv_to_direction(u, v);
            texels.push(Vec3::splat(1.0 + 0.9 * d[0]));
        }
    }
    Environment::LatLong {
        width,
        height,
        texels,
    }
}

/// Bakes `scene` per vertex (f32, N1 = 16, the default GGX shading basis) into a temporary
/// file named after `name`; returns its path.
pub(crate) fn bake_per_vertex_f32(scene: &Scene, name: &str) -> std::path::PathBuf {
    let shading =
        vec![prt_bake::basis::shading::default_shading_basis(Family::Ggx).expect("shading basis")];
    let opts = prt_bake::vertex::VertexBakeOptions {
        samples: 16,
        precision: Precision::F32,
        ..Default::default()
    };
    let path = temp_path(&format!("{name}.prt"));
    prt_bake::vertex::bake_vertex(scene, &[], &shading, &opts, &path, None).expect("bake");
    path
}

/// Bakes `scene` per vertex ([`bake_per_vertex_f32`]) and relights it at `w x h` from its
/// camera; renders the reference with its normal map and without; returns (relit vs
/// reference, the map's own effect on the reference), relative L2.
fn per_vertex_against_reference(scene: &Scene, m: usize, name: &str) -> (f64, f64) {
    let path = bake_per_vertex_f32(scene, &format!("normal-map-{name}"));
    let (w, h) = (48, 48);
    let mut r = VertexRelighter::open(&path).expect("open");
    r.set_size(w, h).expect("size");
    let relit = r.render().expect("relight").pixels;
    let render = |scene: &Scene| -> Vec<[f32; 3]> {
        prt_bake::reference::render_true(scene, 2, w, h, 256, 1, 3, None)
            .pixels
            .iter()
            .map(|p| p.to_array())
            .collect()
    };
    let reference = render(scene);
    let mut flat = scene.clone();
    flat.materials[m].normal_texture = None;
    let unbent = render(&flat);
    let err = relative_l2(&relit, &reference);
    let map_effect = relative_l2(&unbent, &reference);
    eprintln!("{name}: relit vs reference {err:.4}, the map's effect {map_effect:.4}");
    (err, map_effect)
}

/// The square under the linear sky, seen along -Z from 45 degrees up, its material `brdf`
/// with a map tilted `deg` degrees towards +X; returns the scene and the material.
fn square_under_sky(brdf: BrdfParams, deg: f32) -> (Scene, usize) {
    let mut b = SceneBuilder::new();
    let m = b.material("square", brdf, Vec3::ZERO, false);
    mapped_square(&mut b, 8, m);
    b.environment(linear_sky());
    b.camera(look_at(
        Vec3::new(0.0, 1.2, 1.2),
        Vec3::ZERO,
        Vec3::Y,
        30f32.to_radians(),
    ));
    let mut scene = b.build();
    add_map(&mut scene, m as usize, tilted(deg, Vec2::X));
    (scene, m as usize)
}

/// The per-vertex runtime bends the normal of the last reflection per pixel: a glossy
/// square (GGX alpha 0.15, no diffuse part) under the linear sky with a map tilted 15 degrees
/// towards +X, which turns every mirror direction 30 degrees towards the bright side. The
/// square sees nothing but the sky, so the relit image differs from the reference only by the
/// last reflection's approximations: measured 0.7 % relative L2 (bound 3 %); the map ignored
/// at the last reflection gives 21.9 %, the map's own effect on the reference.
#[test]
fn the_per_vertex_last_reflection_follows_the_normal_map() {
    let glossy = BrdfParams {
        family: Family::Ggx,
        kd: Vec3::ZERO,
        ks: Vec3::splat(0.9),
        param: 0.15,
    };
    let (scene, m) = square_under_sky(glossy, 15.0);
    let (err, map_effect) = per_vertex_against_reference(&scene, m, "glossy");
    // The map matters here: the reference with and without it differ far beyond the bound.
    assert!(
        map_effect > 0.15,
        "the map changes the reference by {map_effect:.3} only"
    );
    assert!(
        err < 0.03,
        "the per-vertex image is {err:.4} off the reference (the map's own effect: {map_effect:.3})"
    );
}

/// The per-vertex diffuse part follows the map too: the irradiance at a pixel is the vertex's
/// scaled by the open sky's irradiance at the bent normal over that at the interpolated one,
/// times the share of the bent hemisphere above the square's plane (the square hides the rest
/// in the reference), exact under a uniform open sky. A diffuse square under the linear sky
/// with a map tilted 20 degrees towards +X: the map changes the reference by 13.2 %; the
/// relit image is measured 1.4 % off it (bound 3 %); the irradiance left unscaled:
/// 13.2 %, the map's whole effect; without the horizon share: 4.6 %.
#[test]
fn the_per_vertex_irradiance_follows_the_normal_map() {
    let (scene, m) = square_under_sky(BrdfParams::diffuse(Vec3::splat(0.7)), 20.0);
    let (err, map_effect) = per_vertex_against_reference(&scene, m, "diffuse");
    assert!(
        map_effect > 0.1,
        "the map changes the reference by {map_effect:.3} only"
    );
    assert!(
        err < 0.03,
        "the per-vertex image is {err:.4} off the reference (the map's own effect: {map_effect:.3})"
    );
}
