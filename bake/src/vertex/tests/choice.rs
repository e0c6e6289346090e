//! What the compressed bake chooses from the error target: the cluster size of each group
//! (`cluster_choice.rs`, through `compress_group`) and the T0 Haar terms it keeps
//! (`t0_choice.rs`, through a whole bake).

use glam::Vec3;
use prt_formats::clustered::CompressionSettings;
use prt_formats::pixel::Precision;
use prt_formats::vertex::{cube_len, SH_TERMS, T1_LIGHT_CUBE};

use super::super::cluster::cluster_vertices;
use super::super::compress::{compress_group, compress_tensor, GroupShape};
use super::*;

/// A Lambert sphere subdivided 3 times (642 vertices), its vertices and normals.
fn sphere() -> (Scene, Vec<u32>, Vec<Vec3>) {
    let mut b = SceneBuilder::new();
    let m = b.material("ball", lambert(0.5), Vec3::ZERO, true);
    b.sphere(Vec3::ZERO, 1.0, 3, m);
    b.environment(Environment::Constant(Vec3::ONE));
    let scene = b.build();
    let normals: Vec<Vec3> = scene.positions.iter().map(|p| p.normalize()).collect();
    let vertices = (0..scene.positions.len() as u32).collect();
    (scene, vertices, normals)
}

/// A T1 for one active slot, gray: per vertex a function of its normal over the light bins
/// and SH terms, plus a little per-vertex noise, so that small clusters need lower ranks than
/// large ones and the error target bites.
fn synthetic_t1(normals: &[Vec3]) -> Vec<f32> {
    let bins = cube_len(T1_LIGHT_CUBE);
    let mut s = 0x2545_f491_4f6c_dd1du64;
    let mut noise = move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 40) as f32 / (1u64 << 24) as f32 - 0.5
    };
    let mut t = Vec::with_capacity(normals.len() * bins * SH_TERMS);
    for n in normals {
        for l in 0..bins {
            let x = l as f32 / bins as f32;
            for w in 0..SH_TERMS {
                let y = w as f32 / SH_TERMS as f32;
                // A bump over the bins that moves with the vertex's azimuth: the light a
                // vertex sees depends on where it faces, as a sky seen past a horizon does.
                let azimuth = n.z.atan2(n.x) / std::f32::consts::TAU + 0.5;
                let d = (x - azimuth).abs().min(1.0 - (x - azimuth).abs());
                let v = (-(d / 0.06).powi(2)).exp() * (1.0 + y * n.y)
                    + 0.3 * (2.0 * n.y - 5.0 * x * y).cos();
                t.push(v + 0.05 * noise());
            }
        }
    }
    t
}

const SHAPE: GroupShape = GroupShape {
    active: 1,
    t2_slots: 0,
    channels: 1,
    reflections: 2,
};

fn settings(target: f32, cluster_vertices: Option<u32>) -> CompressionSettings {
    CompressionSettings {
        error_target: target,
        cluster_vertices,
        max_light_rank: 24,
        max_element_rank: 16,
        max_vertex_rank: 12,
    }
}

#[test]
fn an_explicit_cluster_size_compresses_as_before() {
    let (scene, vertices, normals) = sphere();
    let t1 = synthetic_t1(&normals);
    let s = settings(0.1, Some(100));
    let got = compress_group(
        &scene,
        &normals,
        &vertices,
        &t1,
        &[],
        SHAPE,
        &s,
        Precision::F16,
    )
    .unwrap();
    // The path before clusters were chosen: ceil(V / cluster_vertices) clusters, one
    // compression.
    let positions: Vec<[f32; 3]> = scene.positions.iter().map(|p| p.to_array()).collect();
    let nrm: Vec<[f32; 3]> = normals.iter().map(|n| n.to_array()).collect();
    let (clusters, count) = cluster_vertices(&positions, &nrm, vertices.len().div_ceil(100));
    let width = SHAPE.active * SH_TERMS * SHAPE.channels;
    let before = compress_tensor(&t1, cube_len(T1_LIGHT_CUBE), width, &clusters, count, &s)
        .unwrap()
        .store(Precision::F16);
    assert_eq!(got.tried.len(), 1);
    assert_eq!(got.meta.clusters as usize, count);
    assert_eq!(got.data.clusters, clusters);
    assert_eq!(got.data.t1, before.0);
    assert_eq!(got.scale_t1, before.1);
    assert!(!got.summary.contains("tried"), "{}", got.summary);
}

#[test]
fn auto_clusters_keep_the_smallest_candidate_that_meets_the_target() {
    let (scene, vertices, normals) = sphere();
    let t1 = synthetic_t1(&normals);
    let mut met_and_missed = (false, false);
    let mut kept_meeting = Vec::new();
    for target in [0.003f32, 0.02, 0.05, 0.1, 0.2] {
        let auto = compress_group(
            &scene,
            &normals,
            &vertices,
            &t1,
            &[],
            SHAPE,
            &settings(target, None),
            Precision::F16,
        )
        .unwrap();
        // The default first, then larger clusters when it met the target, smaller when not.
        let sizes: Vec<u32> = auto.tried.iter().map(|c| c.cluster_vertices).collect();
        let next = if auto.tried[0].meets(target) { 256 } else { 64 };
        assert_eq!(sizes, [128, next], "target {target}");
        // Each candidate is what an explicit size gives, figures and all.
        let mut explicit = Vec::new();
        for c in &auto.tried {
            let e = compress_group(
                &scene,
                &normals,
                &vertices,
                &t1,
                &[],
                SHAPE,
                &settings(target, Some(c.cluster_vertices)),
                Precision::F16,
            )
            .unwrap();
            assert_eq!(&e.tried[0], c, "target {target}");
            explicit.push(e);
        }
        let chosen = auto
            .tried
            .iter()
            .position(|c| c.clusters == auto.meta.clusters as usize)
            .expect("the chosen count is a candidate's");
        let c = &auto.tried[chosen];
        println!("target {target}: kept {c:?} of {:?}", auto.tried);
        assert_eq!(auto.data.t1, explicit[chosen].data.t1, "target {target}");
        if c.meets(target) {
            met_and_missed.0 = true;
            kept_meeting.push(c.cluster_vertices);
            // Never larger than another candidate that meets the target.
            for o in &auto.tried {
                assert!(
                    !o.meets(target) || o.bytes >= c.bytes,
                    "target {target}: kept {c:?} over {o:?}"
                );
            }
            assert!(auto.summary.contains("the smallest meeting the target"));
        } else {
            met_and_missed.1 = true;
            assert!(auto.tried.iter().all(|o| !o.meets(target)));
            // Neither meets it: the default size stays.
            assert_eq!(c.cluster_vertices, 128, "target {target}");
            assert!(auto.summary.contains("none meets the target"));
        }
        // The candidates differ: the choice matters.
        assert!(auto.tried.windows(2).all(|w| w[0].bytes != w[1].bytes));
    }
    assert_eq!(met_and_missed, (true, true), "both branches exercised");
    // The size kept depends on the target: neither the smallest nor the largest always wins.
    assert!(
        kept_meeting.contains(&64) && kept_meeting.contains(&256),
        "{kept_meeting:?}"
    );
}

/// The floor-and-ball scene baked with `compression`, at f32 so that values compare exactly.
fn floor_and_ball_bake(compression: Option<CompressionSettings>) -> VertexBake {
    let opts = VertexBakeOptions {
        samples: 8,
        t0_terms: 64,
        precision: Precision::F32,
        compression,
        ..Default::default()
    };
    bake_vertex(&floor_and_ball(), &[], &[], &opts, None).unwrap()
}

/// Relative L2 over a group of keeping each row's `k` largest of its `terms` stored values.
fn cut_error(value: &[f32], terms: usize, k: usize) -> f64 {
    let (mut cut, mut all) = (0.0f64, 0.0f64);
    for row in value.chunks_exact(terms) {
        let mut sq: Vec<f64> = row.iter().map(|&x| f64::from(x).powi(2)).collect();
        sq.sort_by(|a, b| b.total_cmp(a));
        all += sq.iter().sum::<f64>();
        cut += sq[k..].iter().sum::<f64>();
    }
    (cut / all).sqrt()
}

#[test]
fn compressed_groups_keep_the_fewest_t0_terms_meeting_their_target() {
    let dense = floor_and_ball_bake(None);
    let mut settings = crate::vertex::default_compression();
    let mut cut_somewhere = false;
    for target in [0.1f32, 0.4, 0.8] {
        settings.error_target = target;
        let compressed = floor_and_ball_bake(Some(settings));
        let t0_target = f64::from(target * super::super::t0_choice::T0_ERROR_SHARE);
        for (g, (gm, (d, c))) in compressed
            .meta
            .groups
            .iter()
            .zip(dense.groups.iter().zip(&compressed.groups))
            .enumerate()
        {
            assert_eq!(
                dense.meta.groups[g].t0_terms, None,
                "dense groups store all"
            );
            let k = gm.t0_terms.expect("a compressed group says its terms") as usize;
            assert!((1..=64).contains(&k));
            let value = d.t0_value.to_f32();
            let e = cut_error(&value, 64, k);
            assert!(
                e <= t0_target + 1e-9,
                "target {target}, group {g}: K {k}: {e}"
            );
            if k > 1 {
                assert!(
                    cut_error(&value, 64, k - 1) > t0_target,
                    "target {target}, group {g}: K - 1 = {} meets it",
                    k - 1
                );
            }
            cut_somewhere |= k < 64;
            // The rows are the dense bake's cut to their K largest, the layout kept.
            let rows = value.len() / 64;
            let (ci, cv) = (&c.t0_index, c.t0_value.to_f32());
            assert_eq!((ci.len(), cv.len()), (rows * k, rows * k));
            for r in 0..rows {
                let kept: Vec<(u16, f32)> = (0..k)
                    .map(|t| (ci[r * k + t], cv[r * k + t]))
                    .filter(|&(_, v)| v != 0.0)
                    .collect();
                let mut largest: Vec<(u16, f32)> = (0..64)
                    .map(|t| (d.t0_index[r * 64 + t], value[r * 64 + t]))
                    .filter(|&(_, v)| v != 0.0)
                    .collect();
                largest.sort_by(|a, b| b.1.abs().total_cmp(&a.1.abs()).then(a.0.cmp(&b.0)));
                largest.truncate(k);
                largest.sort_by_key(|&(i, _)| i);
                assert_eq!(kept, largest, "target {target}, group {g}, row {r}");
            }
        }
        // The file says so and reads back.
        let path = std::env::temp_dir().join(format!(
            "prt-vertex-t0-choice-{}-{target}.prtbake",
            std::process::id()
        ));
        write_vertex_file(&compressed, &path).unwrap();
        let file = prt_formats::BakeFile::open(&path).unwrap();
        std::fs::remove_file(&path).ok();
        let meta: prt_formats::vertex::VertexBakeMeta =
            serde_json::from_value(file.metadata().clone()).unwrap();
        meta.validate().unwrap();
        for (g, gm) in meta.groups.iter().enumerate() {
            let k = gm.t0_terms.unwrap() as usize;
            let shape = file
                .tensor(&prt_formats::vertex::names::t0_index(g))
                .unwrap()
                .shape()
                .to_vec();
            assert_eq!(shape[2], k);
        }
    }
    assert!(cut_somewhere, "no target cut any T0 terms");
}
