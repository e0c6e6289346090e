//! The pinhole camera's field of view on a non-square image: `yfov` spans the height, the width
//! spans `2 atan(tan(yfov / 2) * width / height)` (docs/conventions.md). Square images cannot
//! tell the aspect ratio's use apart from its inverse.

use glam::Vec3;
use prt_bake::accel::Accel;
use prt_bake::integrator::Integrator;
use prt_bake::lights::LightSet;
use prt_bake::testing::furnace_scene;

#[test]
fn field_of_view_spans_the_height_and_the_aspect_widens_it() {
    let scene = furnace_scene(Vec3::splat(0.5), Vec3::ONE);
    let accel = Accel::build(&scene);
    let lights = LightSet::new(&scene);
    let cam = &scene.camera;
    for (w, h) in [(64u32, 32u32), (30, 90)] {
        let integ = Integrator::new(&scene, &accel, &lights, 1, w, h);
        let angle = |x: f32, y: f32| {
            let (o, d) = integ.camera_ray(x, y);
            assert_eq!(o, cam.position);
            d.dot(cam.forward).clamp(-1.0, 1.0).acos()
        };
        let half_v = 0.5 * cam.yfov;
        let half_h = (half_v.tan() * w as f32 / h as f32).atan();
        let (cx, cy) = (0.5 * w as f32, 0.5 * h as f32);
        assert!(angle(cx, cy) < 1e-3, "the image centre looks along forward");
        for (x, y, want, edge) in [
            (cx, 0.0, half_v, "top"),
            (cx, h as f32, half_v, "bottom"),
            (0.0, cy, half_h, "left"),
            (w as f32, cy, half_h, "right"),
        ] {
            let got = angle(x, y);
            assert!(
                (got - want).abs() < 1e-5,
                "{w}x{h}: {edge} edge at {got} rad from forward, expected {want}"
            );
        }
        // Up is up and right is right (y grows downwards on the film).
        assert!(integ.camera_ray(cx, 0.0).1.dot(cam.up) > 0.0);
        assert!(integ.camera_ray(w as f32, cy).1.dot(cam.right) > 0.0);
    }
}
