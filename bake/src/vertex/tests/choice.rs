//! What the compressed bake chooses from the error target: the split of each unit
//! (`cluster_choice.rs`, through `compress_unit`) and the T0 Haar terms each group keeps
//! (`t0_choice.rs`, through a whole bake).

use glam::Vec3;
use prt_formats::clustered::CompressionSettings;
use prt_formats::pixel::Precision;
use prt_formats::vertex::{cube_len, SH_TERMS, T1_LIGHT_CUBE};

use super::super::cluster_choice::PartsCandidate;
use super::super::unit::{compress_unit, TracedUnit};
use super::*;

/// A Lambert sphere subdivided 3 times (642 vertices), prepared: its units and normals.
fn sphere() -> (Vec<Unit>, Vec<Vec3>) {
    let mut b = SceneBuilder::new();
    let m = b.material("ball", lambert(0.5), Vec3::ZERO, true);
    b.sphere(Vec3::ZERO, 1.0, 3, m);
    b.environment(Environment::Constant(Vec3::ONE));
    let p = prepare_scene(&b.build());
    let normals: Vec<Vec3> = p.scene.positions.iter().map(|q| q.normalize()).collect();
    (p.units, normals)
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

fn settings(target: f32, cluster_vertices: Option<u32>) -> CompressionSettings {
    CompressionSettings {
        error_target: target,
        cluster_vertices,
        max_light_rank: 24,
        max_element_rank: 16,
        max_vertex_rank: 12,
    }
}

/// A unit's traced tensors with the synthetic T1 (no noise estimate).
fn traced(unit: &Unit, normals: &[Vec3]) -> TracedUnit {
    let n: Vec<Vec3> = unit.vertices.iter().map(|&v| normals[v as usize]).collect();
    TracedUnit {
        t1: synthetic_t1(&n),
        t1_noise: vec![0.0; n.len()],
        t2_noise: vec![0.0; n.len()],
        ..Default::default()
    }
}

fn compress(unit: &Unit, t: &TracedUnit, s: &CompressionSettings) -> (usize, Vec<PartsCandidate>) {
    let dims = (cube_len(T1_LIGHT_CUBE), SH_TERMS, 0, 0);
    let (parts, _, _, tried) = compress_unit(unit, t, dims, false, s, 2).unwrap();
    (parts, tried)
}

#[test]
fn an_explicit_cluster_size_compresses_once_with_the_nearest_split() {
    let (units, normals) = sphere();
    for u in units.iter().filter(|u| u.vertices.len() > 128) {
        let n = u.vertices.len() as u32;
        for (size, parts) in [
            (n / 4, 4),
            (n / 2 - 5, 2),
            (n / 2 + 5, 2),
            (n - 10, 1),
            (n, 1),
        ] {
            let (got, tried) = compress(u, &traced(u, &normals), &settings(0.1, Some(size)));
            assert_eq!((got, tried.len()), (parts, 1), "size {size}");
            assert_eq!(tried[0].parts, parts);
        }
    }
}

#[test]
fn each_unit_keeps_the_smallest_split_that_meets_the_target() {
    let (units, normals) = sphere();
    assert!(units.len() >= 3, "{} units", units.len());
    let mut met_and_missed = (false, false);
    let mut kept_meeting = Vec::new();
    for target in [0.003f32, 0.02, 0.05, 0.1, 0.2] {
        for u in &units {
            let t = traced(u, &normals);
            let (parts, tried) = compress(u, &t, &settings(target, None));
            // Halves first, then one cluster when they met the target, quarters when not.
            let next = if tried[0].meets(target) { 1 } else { 4 };
            let order: Vec<usize> = tried.iter().map(|c| c.parts).collect();
            assert_eq!(order, [2, next], "target {target}");
            // Each candidate is what that split alone gives (an explicit size of its
            // clusters), figures and all: to rounding, since the search sums the whole
            // unit's element Gram matrix from its halves' where the split alone sums its rows.
            for c in &tried {
                let size = (u.vertices.len() / c.parts) as u32;
                let (_, alone) = compress(u, &t, &settings(target, Some(size)));
                let a = &alone[0];
                assert_eq!((a.parts, a.bytes), (c.parts, c.bytes), "target {target}");
                assert_eq!(a.errors.len(), c.errors.len());
                for (x, y) in a.errors.iter().zip(&c.errors) {
                    assert!((x - y).abs() <= 1e-9 * x.abs().max(1e-6), "{a:?} vs {c:?}");
                }
            }
            let c = tried.iter().find(|c| c.parts == parts).unwrap();
            if c.meets(target) {
                met_and_missed.0 = true;
                kept_meeting.push(parts);
                for o in &tried {
                    assert!(!o.meets(target) || o.bytes >= c.bytes, "{c:?} over {o:?}");
                }
            } else {
                met_and_missed.1 = true;
                assert!(tried.iter().all(|o| !o.meets(target)));
                assert_eq!(parts, 2, "target {target}: neither meets it, halves stay");
            }
            assert!(tried.windows(2).all(|w| w[0].bytes != w[1].bytes));
        }
    }
    assert_eq!(met_and_missed, (true, true), "both branches exercised");
    assert!(
        kept_meeting.contains(&1) && kept_meeting.contains(&4),
        "{kept_meeting:?}"
    );
}

/// The floor-and-ball scene baked with `compression`, at f32 so that values compare exactly.
fn floor_and_ball_bake(
    compression: Option<CompressionSettings>,
    name: &str,
) -> (VertexBakeResult, prt_formats::BakeFile) {
    let opts = VertexBakeOptions {
        samples: 8,
        t0_terms: 64,
        precision: Precision::F32,
        compression,
        ..Default::default()
    };
    bake_file(&floor_and_ball(), &opts, name)
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
    use prt_formats::vertex::names;
    let (dense, dense_file) = floor_and_ball_bake(None, "t0-dense");
    let mut settings = crate::vertex::default_compression();
    let mut cut_somewhere = false;
    for target in [0.1f32, 0.4, 0.8] {
        settings.error_target = target;
        let (compressed, file) = floor_and_ball_bake(Some(settings), &format!("t0-{target}"));
        let t0_target = f64::from(target * super::super::t0_choice::T0_ERROR_SHARE);
        for (g, gm) in compressed.meta.groups.iter().enumerate() {
            assert_eq!(
                dense.meta.groups[g].t0_terms, None,
                "dense groups store all"
            );
            let k = gm.t0_terms.expect("a compressed group says its terms") as usize;
            assert!((1..=64).contains(&k));
            let value = dense_file
                .tensor(&names::t0_value(g))
                .unwrap()
                .to_f32_vec()
                .unwrap();
            let index = dense_file
                .tensor(&names::t0_index(g))
                .unwrap()
                .as_u16()
                .unwrap()
                .to_vec();
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
            let ci = file
                .tensor(&names::t0_index(g))
                .unwrap()
                .as_u16()
                .unwrap()
                .to_vec();
            let cv = file
                .tensor(&names::t0_value(g))
                .unwrap()
                .to_f32_vec()
                .unwrap();
            assert_eq!(
                file.tensor(&names::t0_index(g)).unwrap().shape()[2],
                k,
                "the file's shape says K"
            );
            assert_eq!((ci.len(), cv.len()), (rows * k, rows * k));
            for r in 0..rows {
                let kept: Vec<(u16, f32)> = (0..k)
                    .map(|t| (ci[r * k + t], cv[r * k + t]))
                    .filter(|&(_, v)| v != 0.0)
                    .collect();
                let mut largest: Vec<(u16, f32)> = (0..64)
                    .map(|t| (index[r * 64 + t], value[r * 64 + t]))
                    .filter(|&(_, v)| v != 0.0)
                    .collect();
                largest.sort_by(|a, b| b.1.abs().total_cmp(&a.1.abs()).then(a.0.cmp(&b.0)));
                largest.truncate(k);
                largest.sort_by_key(|&(i, _)| i);
                assert_eq!(kept, largest, "target {target}, group {g}, row {r}");
            }
        }
    }
    assert!(cut_somewhere, "no target cut any T0 terms");
}
