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

/// A `--camera` eye inside a closed object is refused, naming the object; eyes outside it, and
/// inside a room whose walls face inwards (the closed-sphere scene), are accepted. The frame a
/// `--camera` spec gives is the scene camera's, field for field.
#[test]
fn an_eye_inside_an_object_is_refused() {
    use prt_bake::testing::inside_sphere_scene;
    use prt_bake::view::{camera_from_frame, check_eye_outside, ViewError};
    use prt_formats::view::CameraSpec;

    let scene = furnace_scene(Vec3::splat(0.5), Vec3::ONE);
    let accel = Accel::build(&scene);
    for eye in [
        Vec3::ZERO,
        Vec3::new(0.3, -0.5, 0.2),
        Vec3::new(0.0, 0.0, 0.95),
    ] {
        match check_eye_outside(&scene, &accel, eye) {
            Err(ViewError::InsideGeometry {
                material,
                back,
                total,
                ..
            }) => {
                assert_eq!(material, "sphere");
                assert!(back >= 22 && total == 26, "{back} of {total}");
            }
            other => panic!("eye {eye} inside the unit sphere: {other:?}"),
        }
    }
    for eye in [
        Vec3::new(0.0, 0.0, 4.0),
        Vec3::new(1.05, 0.0, 0.0),
        Vec3::splat(3.0),
    ] {
        check_eye_outside(&scene, &accel, eye).unwrap_or_else(|e| panic!("eye {eye}: {e}"));
    }
    let room = inside_sphere_scene(Vec3::splat(0.5), Vec3::splat(0.5), Vec3::ONE, false);
    let room_accel = Accel::build(&room);
    check_eye_outside(&room, &room_accel, Vec3::new(0.1, 0.2, -0.3))
        .unwrap_or_else(|e| panic!("inside an inward-facing room: {e}"));

    let spec: CameraSpec = "eye=0,0,4 target=0,0,0 fov=35".parse().expect("spec");
    let cam = camera_from_frame(&spec.frame().expect("frame"));
    let s = &scene.camera;
    assert!((cam.position - s.position).length() < 1e-6);
    assert!((cam.forward - s.forward).length() < 1e-6);
    assert!((cam.right - s.right).length() < 1e-6);
    assert!((cam.up - s.up).length() < 1e-6);
    assert!((cam.yfov - s.yfov).abs() < 1e-6);
}
