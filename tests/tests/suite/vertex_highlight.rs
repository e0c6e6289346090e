//! The per-vertex last reflection of a light smaller than the shading basis' grid cells (a
//! sun): the split's width-0 term was fitted as a unit on one cell, so the runtime renders it
//! as the environment averaged over a cell (`ShadingBasis::spike_width_deg`), not the
//! environment at the mirror direction.

use glam::Vec3;
use prt_bake::brdf::{BrdfParams, Family};
use prt_bake::scene::Environment;
use prt_bake::testing::{look_at, SceneBuilder};
use prt_runtime::VertexRelighter;
use prt_tests::relative_l2;

use crate::normal_maps::{bake_per_vertex_f32, mapped_square};

/// A dim sky (0.2) with a sun one texel of a 512 x 256 map wide (0.7 degrees, radiance
/// 2000) at `sun`: smaller than a cell of the shading grid and than the light's 64-cube texels.
fn sky_with_sun(sun: Vec3) -> Environment {
    let (width, height) = (512u32, 256u32);
    let mut texels = vec![Vec3::splat(0.2); (width * height) as usize];
    let (best, _) = (0..texels.len())
        .map(|i| {
            let (x, y) = (i % width as usize, i / width as usize);
            let (u, v) = prt_formats::latlong::texel_centre(x, y, width as usize, height as usize);
            let d = Vec3::from_array(prt_formats::latlong::uv_to_direction(u, v));
            (i, d.dot(sun))
        })
        .fold((0, f32::MIN), |a, b| if b.1 > a.1 { b } else { a });
    texels[best] = Vec3::new(2000.0, 1900.0, 1700.0);
    Environment::LatLong {
        width,
        height,
        texels,
    }
}

/// A glossy square (GGX alpha 0.1, no diffuse part) seen from 45 degrees up, with the sun at
/// the mirror direction of the view at its centre, so the highlight is in the image; baked
/// per vertex (f32, N1 = 16) and relit at 64 x 64 against the reference (one reflection,
/// 1024 spp). The square sees only the sky, so the difference is the last reflection's.
/// Measured: 16.3 % relative L2, the highlight's peak 1.07 times the reference's; with the
/// width-0 term read unfiltered (the light's cube at the mirror direction: the sun's own sharp
/// image) 24.9 % and 3.05 times. Bounds: 20 %, 1.5 times.
#[test]
fn a_sun_smaller_than_a_cell_gives_the_lobe_shaped_highlight() {
    let eye = Vec3::new(0.0, 1.2, 1.2);
    let sun = Vec3::new(0.0, 1.0, -1.0).normalize();
    let mut b = SceneBuilder::new();
    let glossy = BrdfParams {
        family: Family::Ggx,
        kd: Vec3::ZERO,
        ks: Vec3::splat(0.9),
        param: 0.1,
    };
    let m = b.material("square", glossy, Vec3::ZERO, false);
    mapped_square(&mut b, 12, m);
    b.environment(sky_with_sun(sun));
    b.camera(look_at(eye, Vec3::ZERO, Vec3::Y, 30f32.to_radians()));
    let scene = b.build();

    let path = bake_per_vertex_f32(&scene, "vertex-highlight");
    let (w, h) = (64, 64);
    let mut r = VertexRelighter::open(&path).expect("open");
    r.set_size(w, h).expect("size");
    let relit = r.render().expect("relight").pixels;
    let reference: Vec<[f32; 3]> =
        prt_bake::reference::render_true(&scene, 1, w, h, 1024, 1, 5, None)
            .pixels
            .iter()
            .map(|p| p.to_array())
            .collect();
    let peak = |img: &[[f32; 3]]| img.iter().map(|p| p[0]).fold(0.0f32, f32::max);
    let err = relative_l2(&relit, &reference);
    eprintln!(
        "glossy square under a sun: relit vs reference {err:.4}, peaks {} and {}",
        peak(&relit),
        peak(&reference)
    );
    let _ = std::fs::remove_file(&path);
    // The highlight is in the image: the sky alone reflects at most 0.9 x 0.2.
    assert!(
        peak(&reference) > 1.0,
        "no highlight: peak {}",
        peak(&reference)
    );
    assert!(
        peak(&relit) < 1.5 * peak(&reference),
        "the highlight peaks at {} where the reference's does at {}: the sun's own image?",
        peak(&relit),
        peak(&reference)
    );
    assert!(
        err < 0.20,
        "the highlight is {err:.4} off the reference (peaks: relit {}, reference {})",
        peak(&relit),
        peak(&reference)
    );
}
