//! Analytic checks of the reference path tracer: cases with a closed-form answer.

use glam::Vec3;
use prt_bake::accel::Accel;
use prt_bake::brdf::BrdfParams;
use prt_bake::integrator::Integrator;
use prt_bake::lights::LightSet;
use prt_bake::reference::{render, unit_coefficients, TrueBrdfModel};
use prt_bake::scene::Scene;
use prt_bake::testing::{furnace_scene, look_at, SceneBuilder};

fn render_scene(
    scene: &Scene,
    reflections: usize,
    w: u32,
    h: u32,
    spp: u32,
) -> prt_bake::reference::Render {
    let accel = Accel::build(scene);
    let lights = LightSet::new(scene);
    let integ = Integrator::new(scene, &accel, &lights, reflections, w, h);
    let model = TrueBrdfModel::new(scene);
    render(
        &integ,
        &model,
        &unit_coefficients(scene.materials.len()),
        spp,
        7,
        None,
    )
}

/// White furnace: a convex Lambert object under a constant environment of radiance 1 reflects
/// exactly its albedo, whatever the number of reflections (no interreflection on a convex
/// object).
#[test]
fn furnace_sphere_radiance_equals_albedo() {
    let albedo = Vec3::new(0.5, 0.3, 0.8);
    let scene = furnace_scene(albedo, Vec3::ONE);
    for reflections in [1, 3] {
        let r = render_scene(&scene, reflections, 32, 32, 16);
        let (mean, n) = r.material_means[0];
        let mean = mean.expect("sphere covers samples");
        assert!(n > 1000, "sphere covers {n} samples");
        let rel = ((mean - albedo) / albedo).abs().max_element();
        eprintln!("furnace reflections {reflections}: mean {mean} rel {rel}");
        assert!(
            rel < 0.01,
            "reflections {reflections}: sphere mean {mean} vs albedo {albedo} (rel {rel})"
        );
        // The background sees the environment itself.
        let (bg, _) = r.background_mean;
        assert!(
            (bg.expect("background visible") - Vec3::ONE)
                .abs()
                .max_element()
                < 1e-6
        );
    }
}

/// Irradiance at `p` (normal `n`) from a polygon of uniform radiance `le` (Lambert's formula).
fn polygon_irradiance(p: Vec3, n: Vec3, poly: &[Vec3], le: f32) -> f32 {
    let mut sum = 0.0f64;
    for i in 0..poly.len() {
        let a = (poly[i] - p).normalize().as_dvec3();
        let b = (poly[(i + 1) % poly.len()] - p).normalize().as_dvec3();
        let theta = a.dot(b).clamp(-1.0, 1.0).acos();
        let g = a.cross(b).normalize();
        sum += theta * n.as_dvec3().dot(g);
    }
    (0.5 * sum.abs() * le as f64) as f32
}

/// A diffuse plane lit by a square area light: the rendered radiance is Kd/pi times the
/// closed-form irradiance, averaged over each pixel's footprint.
#[test]
fn diffuse_plane_under_polygonal_light_matches_closed_form() {
    let kd = 0.8;
    let le = 5.0;
    let mut b = SceneBuilder::new();
    let floor = b.material(
        "floor",
        BrdfParams::diffuse(Vec3::splat(kd)),
        Vec3::ZERO,
        false,
    );
    let light = b.material(
        "light",
        BrdfParams::diffuse(Vec3::ZERO),
        Vec3::splat(le),
        false,
    );
    b.quad(
        [
            Vec3::new(-2.0, 0.0, -2.0),
            Vec3::new(-2.0, 0.0, 2.0),
            Vec3::new(2.0, 0.0, 2.0),
            Vec3::new(2.0, 0.0, -2.0),
        ],
        floor,
    );
    // Light at y = 1, offset in x so the irradiance varies across the view; faces down.
    let poly = [
        Vec3::new(0.0, 1.0, -0.3),
        Vec3::new(0.6, 1.0, -0.3),
        Vec3::new(0.6, 1.0, 0.3),
        Vec3::new(0.0, 1.0, 0.3),
    ];
    b.quad(poly, light);
    b.camera(look_at(
        Vec3::new(0.0, 0.6, 0.0),
        Vec3::ZERO,
        Vec3::Z,
        60f32.to_radians(),
    ));
    let scene = b.build();
    let (w, h) = (8u32, 8u32);
    let r = render_scene(&scene, 1, w, h, 4096);

    let accel = Accel::build(&scene);
    let lights = LightSet::new(&scene);
    let integ = Integrator::new(&scene, &accel, &lights, 1, w, h);
    let mut worst = 0.0f32;
    let mut total_err = 0.0f32;
    for y in 0..h {
        for x in 0..w {
            // Average the closed form over a sub-pixel grid (the renderer box-filters).
            let mut expected = 0.0;
            let grid = 8;
            for sy in 0..grid {
                for sx in 0..grid {
                    let fx = x as f32 + (sx as f32 + 0.5) / grid as f32;
                    let fy = y as f32 + (sy as f32 + 0.5) / grid as f32;
                    let (o, d) = integ.camera_ray(fx, fy);
                    let t = -o.y / d.y;
                    let p = o + d * t;
                    expected +=
                        kd / std::f32::consts::PI * polygon_irradiance(p, Vec3::Y, &poly, le);
                }
            }
            expected /= (grid * grid) as f32;
            let got = r.pixels[(y * w + x) as usize];
            let rel = (got - Vec3::splat(expected)).abs().max_element() / expected;
            worst = worst.max(rel);
            total_err += rel;
        }
    }
    let mean_err = total_err / (w * h) as f32;
    eprintln!("polygon light: mean rel err {mean_err}, worst {worst}");
    assert!(mean_err < 0.01, "mean relative error {mean_err}");
    assert!(worst < 0.03, "worst pixel relative error {worst}");
}

/// The same render on 1 and on 3 threads is bit-identical.
#[test]
fn render_is_identical_on_any_thread_count() {
    let scene = furnace_scene(Vec3::splat(0.5), Vec3::new(1.0, 0.5, 0.25));
    let run = |threads| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("pool");
        pool.install(|| render_scene(&scene, 2, 24, 16, 4).pixels)
    };
    let a = run(1);
    let b = run(3);
    assert_eq!(a.len(), b.len());
    for (p, q) in a.iter().zip(&b) {
        assert_eq!(
            p.to_array().map(f32::to_bits),
            q.to_array().map(f32::to_bits)
        );
    }
}
