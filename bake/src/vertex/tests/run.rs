//! The bake as a whole: determinism across thread counts, the refusals, the allocation report
//! and `--max-memory`, the file.
use std::sync::Mutex;

use glam::Vec3;

use super::*;
use prt_formats::clustered::CompressionSettings;
use prt_formats::vertex::{names, VertexBakeMeta};

use crate::progress::Progress;
use crate::scene::PunctualLight;
#[test]
fn the_file_does_not_depend_on_the_thread_count() {
    let scene = floor_and_ball();
    let opts = VertexBakeOptions {
        samples: 32,
        reflections: 3,
        ..Default::default()
    };
    let bytes = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            bake_bytes(&scene, &[], &opts, &format!("threads{threads}"))
                .unwrap()
                .1
        })
    };
    let one = bytes(1);
    assert!(one == bytes(2), "1 and 2 threads give different files");
}

/// With compression on, the clusters are chosen per unit and the T0 terms per group (the
/// 642-vertex ball makes several units): the choice must not depend on the thread count
/// either.
#[test]
fn the_compressed_file_does_not_depend_on_the_thread_count() {
    let mut b = SceneBuilder::new();
    let floor = b.material("floor", lambert(0.5), Vec3::ZERO, true);
    let ball = b.material("ball", lambert(0.7), Vec3::ZERO, true);
    let s = 1.5;
    b.quad(
        [
            Vec3::new(-s, 0.0, s),
            Vec3::new(s, 0.0, s),
            Vec3::new(s, 0.0, -s),
            Vec3::new(-s, 0.0, -s),
        ],
        floor,
    );
    b.sphere(Vec3::new(0.0, 0.7, 0.0), 0.5, 3, ball);
    b.environment(crate::scene::Environment::Constant(Vec3::ONE));
    let scene = b.build();
    let opts = VertexBakeOptions {
        samples: 4,
        secondary: 1,
        t0_terms: 32,
        compression: Some(default_compression()),
        ..Default::default()
    };
    let bytes = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let (r, bytes) = bake_bytes(&scene, &[], &opts, &format!("cthreads{threads}")).unwrap();
            assert!(r.meta.groups.iter().all(|g| g.t0_terms.is_some()));
            bytes
        })
    };
    let one = bytes(1);
    assert!(one == bytes(2), "1 and 2 threads give different files");
}

#[test]
fn refusals_name_the_problem() {
    let opts = VertexBakeOptions {
        samples: 4,
        ..Default::default()
    };
    let mut lit = open_plane();
    lit.lights.push(PunctualLight::Point {
        position: Vec3::Y,
        intensity: Vec3::ONE,
    });
    let e = bake_bytes(&lit, &[], &opts, "lit")
        .err()
        .unwrap()
        .to_string();
    assert!(
        e.contains("1 punctual light (1 point)") && e.contains("environment only"),
        "{e}"
    );

    let mut b = SceneBuilder::new();
    let floor = b.material("floor", lambert(0.5), Vec3::ZERO, false);
    let lamp = b.material("lamp", lambert(0.0), Vec3::splat(5.0), false);
    b.quad(
        [Vec3::ZERO, Vec3::X, Vec3::new(1.0, 0.0, -1.0), Vec3::NEG_Z],
        floor,
    );
    b.quad(
        [
            Vec3::Y,
            Vec3::new(0.0, 1.0, -1.0),
            Vec3::new(1.0, 1.0, -1.0),
            Vec3::new(1.0, 1.0, 0.0),
        ],
        lamp,
    );
    let e = bake_bytes(&b.build(), &[], &opts, "lamp")
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("area lights (emissive materials: lamp)"), "{e}");

    for reflections in [1, 4] {
        let o = VertexBakeOptions {
            reflections,
            ..opts.clone()
        };
        let e = bake_bytes(&open_plane(), &[], &o, "reflections")
            .err()
            .unwrap()
            .to_string();
        assert!(
            e.contains(&format!("reflections = {reflections}")) && e.contains("2 (T0"),
            "{e}"
        );
    }
}

/// Records the notes and stages a run reports.
#[derive(Default)]
struct Recorder(Mutex<Vec<String>>);

impl Progress for Recorder {
    fn start(&self, stage: &str, _total: u64) {
        self.0.lock().unwrap().push(format!("stage: {stage}"));
    }
    fn note(&self, text: &str) {
        self.0.lock().unwrap().push(text.to_string());
    }
}

#[test]
fn a_run_reports_the_allocation_and_refuses_max_memory_before_tracing() {
    let scene = floor_and_ball();
    let dir = std::env::temp_dir().join(format!("prt-vertex-run-{}", std::process::id()));
    let mut config = crate::config::BakeConfig::with_defaults(dir.join("x.gltf"));
    config.mode = crate::config::Mode::Vertex;
    config.spp = 256;
    config.output = dir.join("refused.prtbake");
    let rec = Recorder::default();
    let settings = crate::run::VertexRunSettings {
        max_memory: Some(1 << 20),
        ..Default::default()
    };
    let e = crate::run::run_vertex(&config, &scene, &settings, &rec)
        .err()
        .unwrap();
    assert!(
        matches!(e, crate::error::BakeError::MemoryLimit { .. }),
        "{e}"
    );
    assert!(!config.output.exists());
    let log = rec.0.lock().unwrap().clone();
    assert!(
        !log.iter().any(|l| l == "stage: baking vertices"),
        "{log:?}"
    );
    let report = log
        .iter()
        .find(|l| l.starts_with("allocation"))
        .expect("allocation note");
    assert!(
        report.contains("floor: 4 vertices x (T0 1 x 96, T1 384 x 1 x 16)")
            && report.contains("ball: 42 vertices")
            && report.contains("memory estimate"),
        "{report}"
    );
    // The pixel run refuses a vertex config, and the vertex run a pixel one.
    let e = crate::run::run_pixel(&config, &scene, &Default::default(), &rec)
        .err()
        .unwrap();
    assert!(e.to_string().contains("run_vertex"), "{e}");
}

#[test]
fn the_file_holds_the_schema() {
    let scene = floor_and_ball();
    let opts = VertexBakeOptions {
        samples: 256,
        reflections: 3,
        t0_terms: 40,
        ..Default::default()
    };
    let (bake, file) = bake_file(&scene, &opts, "schema");
    assert_eq!(bake.file_bytes, file.file_bytes().len() as u64);
    let meta: VertexBakeMeta = serde_json::from_value(file.metadata().clone()).unwrap();
    meta.validate().unwrap();
    assert_eq!(meta, bake.meta);
    assert_eq!((meta.vertices, meta.triangles, meta.channels), (46, 82, 1));
    assert_eq!(meta.t2_slots, vec![0, 1]);
    let shape = |name: &str| file.tensor(name).unwrap().shape().to_vec();
    assert_eq!(shape(names::POSITIONS), vec![46, 3]);
    assert_eq!(shape(names::TRIANGLES), vec![82, 3]);
    // The prepared scene, traced directly: the file holds its vertices' T1, placed in order.
    let prepared = prepare_scene(&scene);
    let integ_scene = &prepared.scene;
    let mut first = 0usize;
    with_tracer_units(
        integ_scene,
        prepared.units.clone(),
        &opts,
        |tracer, plan| {
            for (g, gm) in meta.groups.iter().enumerate() {
                let v = gm.vertices as usize;
                assert_eq!(shape(&names::t0_index(g)), vec![v, 1, 40]);
                // Diffuse groups (no lobe) store no visibility.
                assert_eq!(shape(&names::visibility(g)), vec![v, 0]);
                assert_eq!(shape(&names::t1(g)), vec![v, 384, 1, 16, 1]);
                assert_eq!(shape(&names::t2(g)), vec![v, 24, 1, 2, 1]);
                let ids = file
                    .tensor(&names::vertices(g))
                    .unwrap()
                    .as_u32()
                    .unwrap()
                    .to_vec();
                assert_eq!(ids, (first as u32..(first + v) as u32).collect::<Vec<_>>());
                // f16 with the group's scale: the largest stored magnitude is 2^14.
                let t1 = file.tensor(&names::t1(g)).unwrap().to_f32_vec().unwrap();
                let max = t1.iter().fold(0.0f32, |m, x| m.max(x.abs()));
                assert_eq!(max, 16384.0);
                // The last vertex of the group, traced again, is its last row times the scale.
                let last = plan.groups[g].vertices[v - 1];
                assert_eq!(last as usize, first + v - 1);
                let traced = tracer.trace(last).unwrap().t1;
                let row = &t1[(v - 1) * traced.len()..v * traced.len()];
                let top = traced.iter().fold(0.0f32, |m, x| m.max(x.abs()));
                for (a, b) in traced.iter().zip(row) {
                    assert!((a - b * gm.scale_t1).abs() <= 1e-3 * top, "{a} vs {b}");
                }
                first += v;
            }
        },
    );
    assert!(meta.stats.rays > 0 && meta.stats.t0_truncation_error.len() == 2);
    assert!(meta
        .stats
        .t0_truncation_error
        .iter()
        .all(|e| (0.0..0.5).contains(e)));
}

#[test]
fn unusable_compression_settings_are_refused_naming_the_key() {
    let base = crate::vertex::default_compression();
    for (settings, key) in [
        (
            CompressionSettings {
                error_target: 1.0,
                ..base
            },
            "vertex.compress_error",
        ),
        (
            CompressionSettings {
                error_target: f32::NAN,
                ..base
            },
            "vertex.compress_error",
        ),
        (
            CompressionSettings {
                cluster_vertices: Some(0),
                ..base
            },
            "vertex.cluster_vertices",
        ),
        (
            CompressionSettings {
                max_light_rank: 0,
                ..base
            },
            "vertex.light_rank",
        ),
        (
            CompressionSettings {
                max_element_rank: 0,
                ..base
            },
            "vertex.element_rank",
        ),
        (
            CompressionSettings {
                max_vertex_rank: 0,
                ..base
            },
            "vertex.vertex_rank",
        ),
    ] {
        let opts = VertexBakeOptions {
            compression: Some(settings),
            ..Default::default()
        };
        let e = opts.validate().unwrap_err().to_string();
        assert!(e.contains(key), "expected {key} in: {e}");
    }
}
