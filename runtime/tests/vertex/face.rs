//! The face both kinds share (`prt_runtime::open`, `Relighter`) on a per-vertex bake: the
//! kind is read from the file (either kind), a render into a caller's buffer is the owned
//! render's bits or refused, and the environment setters (a map in memory, its intensity)
//! light the scene as they say.

use prt_formats::pixel::Precision;
use prt_runtime::{BakeKind, LatLongMap, Relighter, RuntimeError, DEFAULT_IMAGE_SIDE};

use crate::common::*;
use crate::pixel_synthetic::Synthetic;

/// The glossy, textured grid in f32, dense or compressed as exact identity factors.
fn bake(path: &std::path::Path, compressed: bool) {
    let mut bake = glossy_grid();
    bake.meta.precision = Precision::F32;
    bake.compress_as_identity = compressed;
    bake.write(path);
}

const CAMERA_EYE: [f32; 3] = [0.4, 1.5, 2.0];

#[test]
fn open_reads_each_kind_as_its_own() {
    let dir = tempfile::tempdir().expect("temp dir");
    let vertex = dir.path().join("vertex.prtbake");
    bake(&vertex, false);
    let pixel = dir.path().join("pixel.prtbake");
    Synthetic::new(1, None, 3).write(&pixel, Precision::F32);
    let v = prt_runtime::open(&vertex).expect("open the per-vertex bake");
    assert_eq!(v.kind(), BakeKind::Vertex);
    assert!(matches!(v, Relighter::Vertex(_)));
    assert_eq!(v.size(), (DEFAULT_IMAGE_SIDE, DEFAULT_IMAGE_SIDE));
    let names: Vec<String> = v.materials().into_iter().map(|m| m.name).collect();
    assert_eq!(names, ["metal", "wall"]);
    let p = prt_runtime::open(&pixel).expect("open the per-pixel bake");
    assert_eq!(p.kind(), BakeKind::Pixel);
    assert!(matches!(p, Relighter::Pixel(_)));
}

#[test]
fn a_buffer_rendered_through_the_face_is_the_owned_render_or_refused() {
    let dir = tempfile::tempdir().expect("temp dir");
    for compressed in [false, true] {
        let path = dir.path().join(format!("vertex-{compressed}.prtbake"));
        bake(&path, compressed);
        let mut r = prt_runtime::open(&path).expect("open");
        let Relighter::Vertex(v) = &mut r else {
            panic!("a per-vertex bake opened as {:?}", r.kind());
        };
        v.set_size(40, 30).expect("size");
        v.set_camera(camera(CAMERA_EYE, 60.0)).expect("camera");
        v.set_environment_rotation(25.0).expect("rotation");
        r.set_params("metal", &[prt_runtime::OverrideValue::Alpha(0.5)])
            .expect("edit");
        let owned = r.render().expect("render");
        assert_eq!((owned.width, owned.height), (40, 30));
        let lit = owned.pixels.iter().filter(|p| p[0] > 0.0).count();
        assert!(lit > owned.pixels.len() / 2, "mostly black: {lit} lit");
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        for poison in [f32::NAN, 7.0] {
            let mut out = vec![poison; 3 * 40 * 30];
            let stats = r.render_into(&mut out).expect("render into");
            assert!(stats.view_s.is_some() && stats.bytes_read.is_none());
            assert_eq!(
                bits(&out),
                bits(owned.pixels.as_flattened()),
                "compressed {compressed}: render_into over {poison} differs from render"
            );
        }
        for len in [0, 3 * 40 * 30 - 1, 3 * 40 * 31] {
            let mut out = vec![7.0f32; len];
            match r.render_into(&mut out) {
                Err(RuntimeError::BufferSize {
                    width,
                    height,
                    expected,
                    got,
                    ..
                }) => assert_eq!((width, height, expected, got), (40, 30, 3600, len)),
                other => panic!("a buffer of {len} floats: {other:?}"),
            }
            assert!(
                out.iter().all(|&v| v == 7.0),
                "a refused buffer was written"
            );
        }
    }
}

#[test]
fn the_environment_setters_light_the_scene_as_they_say() {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("vertex.prtbake");
    bake(&path, false);
    let open = || {
        let mut r = prt_runtime::VertexRelighter::open(&path).expect("open");
        r.set_size(24, 20).expect("size");
        r.set_camera(camera(CAMERA_EYE, 60.0)).expect("camera");
        r
    };
    let image = |r: &mut prt_runtime::VertexRelighter| r.render().expect("render").pixels;
    // Another map, handed over as a flat H x W x 3 array or as a checked map: the same light.
    let (w, h) = (48, 24);
    let flat: Vec<f32> = asymmetric_map(w, h).iter().map(|v| 0.5 * v + 0.1).collect();
    let mut a = open();
    a.set_environment_texels(w, h, &flat).expect("texels");
    a.set_environment_rotation(30.0).expect("rotation");
    let mut b = open();
    let texels = flat.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
    let map = LatLongMap::new(w, h, texels, 1.0).expect("map").0;
    b.set_environment(map.clone()).expect("map");
    b.set_environment_rotation(30.0).expect("rotation");
    let lit = image(&mut a);
    assert!(lit == image(&mut b), "texels and map differ");
    assert_eq!(a.environment_map(), &map);
    // Relighting is linear in the light, and scaling by two is exact in floating point: the
    // image at intensity 2 is the image at 1 doubled, bit for bit (the sky seen directly too).
    // The prefilter, most of a light change's cost, runs once per map: an intensity change
    // scales its cubes (the prefilter is linear), a turn looks them up turned.
    let prefilters = a.prefilter_runs();
    a.set_environment_intensity(2.0).expect("intensity");
    assert_eq!(a.environment_intensity(), 2.0);
    let doubled: Vec<[f32; 3]> = lit.iter().map(|p| p.map(|c| 2.0 * c)).collect();
    assert!(
        image(&mut a) == doubled,
        "intensity 2 is not twice the light"
    );
    // Back to 1: the image it started from; a new map keeps the intensity.
    a.set_environment_intensity(1.0).expect("intensity");
    assert!(image(&mut a) == lit, "intensity 1 after 2");
    a.set_environment_rotation(45.0).expect("rotation");
    a.set_environment_intensity(0.3).expect("intensity");
    image(&mut a);
    assert_eq!(
        a.prefilter_runs(),
        prefilters,
        "an intensity change or a turn prefiltered the map again"
    );
    a.set_environment_rotation(30.0).expect("rotation");
    a.set_environment_intensity(2.0).expect("intensity");
    a.set_environment(map).expect("map");
    assert!(image(&mut a) == doubled, "a new map dropped the intensity");
    assert_eq!(
        a.prefilter_runs(),
        prefilters + 1,
        "a new map was not prefiltered"
    );
}
