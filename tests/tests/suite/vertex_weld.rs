//! Welding (docs/vertex.md, "Bounded memory"): a flat ground grid from a glTF without normals
//! (faceted by the glTF rule: six corners at every inner grid point) bakes one vertex per grid
//! point, and relights like the bake of every corner on its own, within the Monte Carlo noise:
//! the noise is measured as the distance between two unwelded bakes with different seeds.

use glam::Vec3;
use prt_bake::accel::Accel;
use prt_bake::config::BakeConfig;
use prt_bake::integrator::Integrator;
use prt_bake::lights::LightSet;
use prt_bake::pixel::SlotPlan;
use prt_bake::scene::{Environment, Scene};
use prt_bake::testing::{GltfMaterial, GltfMesh, GltfWriter};
use prt_bake::vertex::{
    bake_vertex_with, prepare_scene, prepare_scene_unwelded, PreparedScene, VertexBakeOptions,
    VertexPlan,
};
use prt_formats::pixel::Precision;
use prt_tests::{relative_l2, temp_path};

/// Quads per side of the ground.
const QUADS: u32 = 24;

/// The ground (no normals) and a box standing on it (no normals either: its flat faces weld,
/// its edges do not), written as glTF and loaded as a user's scene is, under a sky whose light
/// comes mostly from one side, so the box's shadow and the ground's shading vary.
fn scene() -> Scene {
    let dir = tempfile_dir();
    let mut w = GltfWriter::new();
    let ground = w.material(GltfMaterial {
        name: "ground".into(),
        base_color: [0.6, 0.55, 0.5],
        metallic: 0.0,
        roughness: 1.0,
    });
    let block = w.material(GltfMaterial {
        name: "block".into(),
        base_color: [0.3, 0.5, 0.7],
        metallic: 0.0,
        roughness: 1.0,
    });
    let n = QUADS;
    let mut g = GltfMesh {
        name: "ground".into(),
        material: ground,
        ..Default::default()
    };
    for j in 0..=n {
        for i in 0..=n {
            let (u, v) = (i as f32 / n as f32, j as f32 / n as f32);
            g.positions.push([(u - 0.5) * 4.0, 0.0, (v - 0.5) * 4.0]);
        }
    }
    let at = |i: u32, j: u32| j * (n + 1) + i;
    for j in 0..n {
        for i in 0..n {
            g.triangles.push([at(i, j), at(i, j + 1), at(i + 1, j + 1)]);
            g.triangles.push([at(i, j), at(i + 1, j + 1), at(i + 1, j)]);
        }
    }
    w.mesh(g);
    // A box, 8 shared corners: faceted, its corners split three ways.
    let c: Vec<[f32; 3]> = (0..8)
        .map(|k| {
            [
                if k & 1 == 0 { -0.5 } else { 0.5 },
                if k & 2 == 0 { 0.0 } else { 1.0 },
                if k & 4 == 0 { -0.5 } else { 0.5 },
            ]
        })
        .collect();
    w.mesh(GltfMesh {
        name: "block".into(),
        positions: c,
        triangles: vec![
            [0, 1, 3],
            [0, 3, 2],
            [4, 6, 7],
            [4, 7, 5],
            [0, 4, 5],
            [0, 5, 1],
            [2, 3, 7],
            [2, 7, 6],
            [0, 2, 6],
            [0, 6, 4],
            [1, 5, 7],
            [1, 7, 3],
        ],
        material: block,
        ..Default::default()
    });
    w.camera([3.0, 2.5, 3.5], [0.0, 0.3, 0.0], 45.0);
    let path = w.write(&dir, "weld").expect("write glTF");
    let mut scene = prt_bake::scene::load(&BakeConfig::with_defaults(path)).expect("load");
    assert!(
        scene.normals.len() == scene.positions.len()
            && scene.positions.len() == 6 * (n * n + 6) as usize,
        "the loader should split every triangle's corners: {} vertices",
        scene.positions.len()
    );
    // A bright patch of sky on one side over a dim dome: a lat-long map.
    let (w, h) = (64usize, 32usize);
    let mut texels = vec![Vec3::splat(0.2); w * h];
    for y in 4..12 {
        for x in 8..20 {
            texels[y * w + x] = Vec3::new(8.0, 7.0, 6.0);
        }
    }
    scene.environment = Environment::LatLong {
        width: w as u32,
        height: h as u32,
        texels,
    };
    scene
}

fn tempfile_dir() -> std::path::PathBuf {
    let dir = temp_path("weld-scene");
    std::fs::create_dir_all(&dir).expect("dir");
    dir
}

/// Bakes `prepared` (dense, f32) and relights it at its camera; returns the image.
fn relit(prepared: PreparedScene, seed: u64, name: &str) -> (usize, Vec<[f32; 3]>) {
    let scene = prepared.scene;
    let vertices = scene.positions.len();
    let opts = VertexBakeOptions {
        samples: 32,
        secondary: 2,
        reflections: 2,
        precision: Precision::F32,
        compression: None,
        seed,
        ..Default::default()
    };
    let slots = SlotPlan::per_unit_radiance(&scene, &[]).expect("slot plan");
    let accel = Accel::build(&scene);
    let lights = LightSet::new(&scene);
    let integ = Integrator::new(&scene, &accel, &lights, 2, 1, 1);
    let plan = VertexPlan::new(&integ, slots, &opts, prepared.units, None).expect("plan");
    let path = temp_path(name);
    bake_vertex_with(&integ, &plan, &[], &[], &opts, &path, None).expect("bake");
    let mut r = prt_runtime::open(&path).expect("open");
    if let prt_runtime::Relighter::Vertex(v) = &mut r {
        v.set_size(160, 120).expect("size");
    }
    let image = r.render().expect("render");
    let _ = std::fs::remove_file(&path);
    (vertices, image.pixels)
}

fn mean(p: &[[f32; 3]]) -> f64 {
    p.iter().map(|c| (c[0] + c[1] + c[2]) as f64).sum::<f64>() / p.len() as f64
}

#[test]
fn a_faceted_flat_grid_bakes_one_vertex_per_grid_point_and_relights_like_the_unwelded_bake() {
    let scene = scene();
    let welded = prepare_scene(&scene);
    let n = QUADS as usize;
    // Ground: one per grid point; the box: each flat face's four corners (6 x 4), its faces
    // meeting at right angles.
    assert_eq!(welded.scene.positions.len(), (n + 1) * (n + 1) + 24);
    let (wv, w) = relit(welded, 7, "weld-welded");
    let (uv, u) = relit(prepare_scene_unwelded(&scene), 7, "weld-unwelded");
    let (_, u2) = relit(prepare_scene_unwelded(&scene), 8, "weld-unwelded-2");
    assert!(uv > 5 * wv, "{uv} vs {wv} vertices");
    let noise = relative_l2(&u2, &u);
    let welding = relative_l2(&w, &u);
    let means = (mean(&w) / mean(&u) - 1.0).abs();
    eprintln!("welded vs unwelded {welding:.4}, two unwelded seeds {noise:.4}, means {means:.4}");
    assert!(noise > 0.0 && noise < 0.1, "noise {noise}");
    assert!(
        welding <= 1.5 * noise,
        "the welded bake is {welding:.4} from the unwelded one, the noise {noise:.4}"
    );
    assert!(means < 0.02, "the mean moved by {means:.4}");
}
