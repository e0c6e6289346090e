//! Silhouettes antialiased (docs/vertex.md, "Silhouettes are antialiased"): a pixel that an
//! outline crosses shows the average of what it holds, as the reference's jittered camera rays
//! see it, not whichever surface its centre meets.

use glam::Vec3;
use prt_bake::brdf::{BrdfParams, Family};
use prt_bake::scene::{Environment, Scene};
use prt_bake::testing::{look_at, SceneBuilder};
use prt_runtime::VertexRelighter;
use prt_tests::relative_l2;

use crate::normal_maps::bake_per_vertex_f32;

const SIDE: u32 = 40;

/// A diffuse square (Kd 0.8) turned 25 degrees in its plane, facing the camera, under a sky of
/// radiance 1: 0.8 inside, 1 around it, and nothing else in view, so the pixels its outline
/// crosses are the only ones a renderer can get wrong.
fn turned_square() -> Scene {
    let mut b = SceneBuilder::new();
    let grey = BrdfParams {
        family: Family::Diffuse,
        kd: Vec3::splat(0.8),
        ks: Vec3::ZERO,
        param: 0.0,
    };
    let m = b.material("square", grey, Vec3::ZERO, false);
    let (c, s) = (25f32.to_radians().cos(), 25f32.to_radians().sin());
    let corner = |x: f32, y: f32| Vec3::new(c * x - s * y, c * y + s * x, 0.0);
    b.quad(
        [
            corner(-0.6, -0.6),
            corner(0.6, -0.6),
            corner(0.6, 0.6),
            corner(-0.6, 0.6),
        ],
        m,
    );
    b.environment(Environment::Constant(Vec3::ONE));
    b.camera(look_at(
        Vec3::new(0.3, 0.2, 3.0),
        Vec3::ZERO,
        Vec3::Y,
        30f32.to_radians(),
    ));
    b.build()
}

/// The outline's pixels against the reference (4096 jittered rays per pixel): within 2 %
/// relative L2 and each within 0.025 of it (a sixteenth of the square's contrast 0.2 is
/// 0.0125; the reference's own noise about 0.002); the image's total within 0.3 %. Centre
/// sampling alone (the switch off, planted) is several times further on the outline.
#[test]
fn an_outline_shows_what_each_pixel_holds() {
    let scene = turned_square();
    let path = bake_per_vertex_f32(&scene, "antialias-square");
    let reference: Vec<[f32; 3]> =
        prt_bake::reference::render_true(&scene, 1, SIDE, SIDE, 4096, 1, 7, None)
            .pixels
            .iter()
            .map(|p| p.to_array())
            .collect();
    // The outline: pixels the reference shows as part square, part sky.
    let outline: Vec<usize> = (0..reference.len())
        .filter(|&i| (0.81..0.99).contains(&reference[i][0]))
        .collect();
    assert!(
        outline.len() > 2 * SIDE as usize,
        "the outline covers {} pixels",
        outline.len()
    );
    let mut r = VertexRelighter::open(&path).expect("open");
    r.set_size(SIDE, SIDE).expect("size");
    assert!(r.antialias(), "antialiasing is on by default");
    let mut measure = |on: bool| -> (f64, f32, f64) {
        r.set_antialias(on);
        let relit = r.render().expect("relight").pixels;
        let pick =
            |img: &[[f32; 3]]| -> Vec<[f32; 3]> { outline.iter().map(|&i| img[i]).collect() };
        let err = relative_l2(&pick(&relit), &pick(&reference));
        let worst = outline
            .iter()
            .map(|&i| (relit[i][0] - reference[i][0]).abs())
            .fold(0.0f32, f32::max);
        let total = |img: &[[f32; 3]]| img.iter().map(|p| f64::from(p[0])).sum::<f64>();
        let total_ratio = total(&relit) / total(&reference);
        eprintln!(
            "antialias {on}: outline ({} px) {err:.4}, worst pixel {worst:.4}, total {total_ratio:.4}",
            outline.len()
        );
        (err, worst, total_ratio)
    };
    let (err, worst, total) = measure(true);
    assert!(err < 0.02, "outline: {err}");
    assert!(worst < 0.025, "outline: a pixel off by {worst}");
    assert!((total - 1.0).abs() < 0.003, "total {total}");
    let (centre_err, _, _) = measure(false);
    assert!(
        centre_err > 2.0 * err,
        "centre sampling {centre_err} against {err}"
    );
}
