//! The BVH against brute force (random and structured scenes), watertightness at shared edges
//! and vertices of closed meshes, rays starting next to a wall, the collapse's invariants and
//! its extreme cost models, the AVX2 path against the portable one, and streams against single
//! queries.

use glam::{Vec2, Vec3};
use obvhs::triangle::Triangle;

use super::bvh8::NODE_TRIANGLES;
use super::collapse::{collapse, CollapseCost, SlotKind};
use super::{brute_force_intersect, build_bvh2, Accel, Found, Ray, Simd};
use crate::sampling::{uniform_sphere, Rng};

fn tri(a: Vec3, b: Vec3, c: Vec3) -> Triangle {
    Triangle {
        v0: a.into(),
        v1: b.into(),
        v2: c.into(),
    }
}

fn rand3(rng: &mut Rng) -> Vec3 {
    Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32())
}

fn random_triangles(n: usize, rng: &mut Rng) -> Vec<Triangle> {
    (0..n)
        .map(|_| {
            let c = rand3(rng) * 4.0 - 2.0;
            let mut v = || c + (rand3(rng) - 0.5) * 0.6;
            tri(v(), v(), v())
        })
        .collect()
}

/// Closed mesh: a cube [-1, 1]^3, each face an n x n grid of quads split in two, vertices
/// shared (computed once per grid point, so shared edges are bit-identical).
fn grid_cube(n: usize) -> (Vec<Vec3>, Vec<[usize; 3]>) {
    let mut pos = Vec::new();
    let mut idx = Vec::new();
    for axis in 0..3 {
        for side in [-1.0f32, 1.0] {
            let base = pos.len();
            for i in 0..=n {
                for j in 0..=n {
                    let s = -1.0 + 2.0 * i as f32 / n as f32;
                    let t = -1.0 + 2.0 * j as f32 / n as f32;
                    let mut p = [0.0f32; 3];
                    p[axis] = side;
                    p[(axis + 1) % 3] = s;
                    p[(axis + 2) % 3] = t;
                    pos.push(Vec3::from(p));
                }
            }
            for i in 0..n {
                for j in 0..n {
                    let a = base + i * (n + 1) + j;
                    let (b, c, d) = (a + n + 1, a + n + 2, a + 1);
                    idx.push([a, b, c]);
                    idx.push([a, c, d]);
                }
            }
        }
    }
    // Weld the duplicated cube edges/corners: identical coordinates, one index.
    let mut welded: Vec<Vec3> = Vec::new();
    let remap: Vec<usize> = pos
        .iter()
        .map(|p| match welded.iter().position(|q| q == p) {
            Some(k) => k,
            None => {
                welded.push(*p);
                welded.len() - 1
            }
        })
        .collect();
    let idx = idx
        .iter()
        .map(|t| [remap[t[0]], remap[t[1]], remap[t[2]]])
        .collect();
    (welded, idx)
}

/// Closed mesh: an octahedron subdivided `levels` times onto the unit sphere, then moved off
/// the origin (vertices shared by index).
fn sphere(levels: usize, center: Vec3) -> (Vec<Vec3>, Vec<[usize; 3]>) {
    let mut pos = vec![Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z];
    let mut idx = vec![
        [0, 2, 4],
        [2, 1, 4],
        [1, 3, 4],
        [3, 0, 4],
        [2, 0, 5],
        [1, 2, 5],
        [3, 1, 5],
        [0, 3, 5],
    ];
    for _ in 0..levels {
        let mut mid = std::collections::HashMap::new();
        let mut next = Vec::new();
        for t in &idx {
            let mut m = [0usize; 3];
            for k in 0..3 {
                let (a, b) = (t[k].min(t[(k + 1) % 3]), t[k].max(t[(k + 1) % 3]));
                m[k] = *mid.entry((a, b)).or_insert_with(|| {
                    pos.push((pos[a] + pos[b]).normalize());
                    pos.len() - 1
                });
            }
            next.push([t[0], m[0], m[2]]);
            next.push([m[0], t[1], m[1]]);
            next.push([m[2], m[1], t[2]]);
            next.push([m[0], m[1], m[2]]);
        }
        idx = next;
    }
    let pos = pos.iter().map(|p| *p * 1.7 + center).collect();
    (pos, idx)
}

fn triangles(mesh: &(Vec<Vec3>, Vec<[usize; 3]>)) -> Vec<Triangle> {
    mesh.1
        .iter()
        .map(|t| tri(mesh.0[t[0]], mesh.0[t[1]], mesh.0[t[2]]))
        .collect()
}

/// Checks the BVH's closest hit and occlusion against brute force; returns the hits.
fn check_against_brute_force(
    accel: &Accel,
    tris: &[Triangle],
    o: Vec3,
    d: Vec3,
    tmax: f32,
) -> bool {
    let a = accel.intersect(o, d, 0.0, tmax);
    let b = brute_force_intersect(tris, o, d, 0.0, tmax);
    match (a, b) {
        (None, None) => {}
        (Some(a), Some(b)) => {
            // The same test on the same triangle: bit-identical t; another triangle only on an
            // exact tie (a shared edge).
            assert_eq!(a.t, b.t, "ray {o} {d}: bvh {a:?} vs brute force {b:?}");
            if a.triangle == b.triangle {
                assert_eq!(a.bary, b.bary);
            }
        }
        (a, b) => panic!("ray {o} {d}: bvh {a:?} vs brute force {b:?}"),
    }
    // Occlusion agrees on the open segment, just short of and just past the hit.
    let tb = b.map_or(10.0, |h| h.t);
    assert!(!accel.occluded(o, d, 0.0, tb * 0.999) || b.is_none());
    assert_eq!(
        accel.occluded(o, d, 0.0, tb * 0.999),
        brute_force_intersect(tris, o, d, 0.0, tb * 0.999).is_some()
    );
    if b.is_some() {
        assert!(
            accel.occluded(o, d, 0.0, tb * 1.001),
            "ray {o} {d}: occlusion missed"
        );
    }
    b.is_some()
}

#[test]
fn random_scene_matches_brute_force() {
    let mut rng = Rng::for_sample(1, 2, 3);
    let tris = random_triangles(3000, &mut rng);
    let accel = Accel::from_triangles(&tris);
    let mut hits = 0;
    for i in 0..4000 {
        let o = rand3(&mut rng) * 6.0 - 3.0;
        let d = uniform_sphere(rng.next_vec2());
        // Some rays axis-aligned (zero direction components).
        let d = match i % 8 {
            0 => Vec3::new(d.x.signum(), 0.0, 0.0),
            1 => Vec3::new(0.0, d.y, d.z).normalize(),
            _ => d,
        };
        let tmax = if i % 3 == 0 { 2.0 } else { f32::INFINITY };
        hits += check_against_brute_force(&accel, &tris, o, d, tmax) as usize;
    }
    assert!(hits > 400, "only {hits} rays hit: the test would be weak");
}

#[test]
fn structured_scenes_match_brute_force() {
    let mut rng = Rng::for_sample(4, 5, 6);
    // A cube grid (axis-aligned faces: zero-thickness boxes), a sphere, and both at once.
    let cube = triangles(&grid_cube(12));
    let ball = triangles(&sphere(4, Vec3::new(3.0, 0.5, 0.0)));
    let both: Vec<Triangle> = cube.iter().chain(ball.iter()).copied().collect();
    for tris in [&cube, &ball, &both] {
        let accel = Accel::from_triangles(tris);
        let mut hits = 0;
        for _ in 0..3000 {
            let o = rand3(&mut rng) * 8.0 - 4.0;
            let d = uniform_sphere(rng.next_vec2());
            hits += check_against_brute_force(&accel, tris, o, d, f32::INFINITY) as usize;
        }
        assert!(hits > 150, "only {hits} rays hit");
    }
}

/// Rays from inside closed meshes aimed exactly at vertices and at points of shared edges
/// never miss, with the BVH or brute force, closest hit or occlusion.
#[test]
fn closed_meshes_are_watertight() {
    let meshes = [grid_cube(7), sphere(3, Vec3::new(0.25, -0.5, 0.125))];
    for (m, mesh) in meshes.iter().enumerate() {
        let tris = triangles(mesh);
        let accel = Accel::from_triangles(&tris);
        let center = mesh.0.iter().copied().sum::<Vec3>() / mesh.0.len() as f32;
        let origins = [
            center,
            center + Vec3::new(0.3, -0.2, 0.1),
            center + Vec3::new(-0.61, 0.37, 0.53),
        ];
        let mut targets: Vec<Vec3> = mesh.0.clone();
        for t in &mesh.1 {
            for k in 0..3 {
                let (a, b) = (mesh.0[t[k]], mesh.0[t[(k + 1) % 3]]);
                for s in [0.5f32, 0.25, 1.0 / 3.0, 0.9] {
                    targets.push(a + (b - a) * s);
                }
            }
        }
        let mut checked = 0;
        for o in origins {
            for p in &targets {
                let d = (*p - o).normalize();
                let h = accel.intersect(o, d, 0.0, f32::INFINITY);
                assert!(h.is_some(), "mesh {m}: ray {o} -> {p} escaped (bvh)");
                assert!(
                    accel.occluded(o, d, 0.0, f32::INFINITY),
                    "mesh {m}: {o} -> {p} occlusion"
                );
                let b = brute_force_intersect(&tris, o, d, 0.0, f32::INFINITY);
                assert!(
                    b.is_some(),
                    "mesh {m}: ray {o} -> {p} escaped (brute force)"
                );
                let (h, b) = (h.unwrap(), b.unwrap());
                if h.t != b.t {
                    let tb = tris[b.triangle as usize];
                    let th = tris[h.triangle as usize];
                    let again = accel.intersect(o, d, 0.0, h.t);
                    panic!("mesh {m} o {o} p {p} d {d}: bvh {h:?} brute {b:?} tb {tb:?} th {th:?} again {again:?}");
                }
                checked += 1;
            }
        }
        assert!(checked > 1000);
    }
}

/// A ray leaving a wall next to a corner hits the adjacent wall however close (obvhs' own
/// traversal culled boxes nearer than 1e-4). The cube is small (half size 0.01) so the boxes'
/// conservative growth (about 1e-6 of the scene's size) stays below the distances tested.
#[test]
fn rays_leaving_next_to_a_corner_hit_the_adjacent_wall() {
    let s = 0.01;
    let mesh = grid_cube(4);
    let small = (mesh.0.iter().map(|p| *p * s).collect(), mesh.1);
    let tris = triangles(&small);
    let accel = Accel::from_triangles(&tris);
    for k in 0..50 {
        let gap = 2e-6 * (1 + k) as f32;
        // On the floor y = -s, gap away from the wall x = -s, heading to it and up.
        let o = Vec3::new(-s + gap, -s + s * 1e-5, 0.3 * s);
        let d = Vec3::new(-1.0, 0.5, 0.1).normalize();
        let h = accel
            .intersect(o, d, 0.0, f32::INFINITY)
            .expect("the adjacent wall");
        assert!(
            (h.t - gap / -d.x).abs() < gap * 1e-3,
            "t {} for gap {gap}",
            h.t
        );
        assert!(accel.occluded(o, d, 0.0, 1.0), "gap {gap}: occlusion");
    }
}

/// Random triangles inside a grid cube, and long diagonal slivers across it (pre-split into
/// several boxes, so they sit in several leaves).
fn mixed_scene() -> Vec<Triangle> {
    let mut rng = Rng::for_sample(10, 11, 12);
    let mut tris = random_triangles(2500, &mut rng);
    for _ in 0..20 {
        let (a, b) = (rand3(&mut rng) - 3.0, rand3(&mut rng) + 2.0);
        tris.push(tri(a, b, b + rand3(&mut rng) * 0.2));
    }
    tris.extend(triangles(&grid_cube(3)).iter().map(|t| Triangle {
        v0: t.v0 * 2.5,
        v1: t.v1 * 2.5,
        v2: t.v2 * 2.5,
    }));
    tris
}

/// Cost models at the extremes: one triangle per leaf (the deepest tree), and leaves as big
/// as a node holds (so whole nodes overflow and leaves must become nodes).
const EXTREME_COSTS: [CollapseCost; 2] = [
    CollapseCost {
        max_leaf: 1,
        tri_cost: 10.0,
    },
    CollapseCost {
        max_leaf: NODE_TRIANGLES as u32,
        tri_cost: 1e-3,
    },
];

/// The collapse keeps every leaf reference of obvhs' tree exactly once, fits each node's
/// leaves in one node (at most `NODE_TRIANGLES` triangles), and nests every child's boxes in
/// its slot's box; under the default cost and the extremes.
#[test]
fn collapse_keeps_every_triangle_once_within_node_capacity() {
    let tris = mixed_scene();
    let bvh2 = build_bvh2(&tris);
    assert!(bvh2.primitive_indices.len() > tris.len(), "no pre-split");
    let mut want = bvh2.primitive_indices.clone();
    want.sort_unstable();
    let mut fullest = [0; 3];
    for (c, cost) in [CollapseCost::DEFAULT]
        .iter()
        .chain(&EXTREME_COSTS)
        .enumerate()
    {
        let tree = collapse(&bvh2, *cost, NODE_TRIANGLES);
        let mut got = tree.primitives.clone();
        got.sort_unstable();
        assert_eq!(got, want, "cost {cost:?}: leaf references differ");
        let mut referenced = vec![0u32; tree.nodes.len()];
        for node in &tree.nodes {
            let mut in_node = 0;
            for slot in node.slots.iter().flatten() {
                match slot.kind {
                    SlotKind::Leaf { count, .. } => {
                        assert!(count <= cost.max_leaf.max(1), "{cost:?}: leaf of {count}");
                        in_node += count as usize;
                    }
                    SlotKind::Inner(i) => {
                        referenced[i as usize] += 1;
                        for inner in tree.nodes[i as usize].slots.iter().flatten() {
                            assert!(slot.bounds.min.cmple(inner.bounds.min).all());
                            assert!(slot.bounds.max.cmpge(inner.bounds.max).all());
                        }
                    }
                }
            }
            assert!(in_node <= NODE_TRIANGLES, "{cost:?}: node of {in_node}");
            fullest[c] = fullest[c].max(in_node);
        }
        assert_eq!(referenced[0], 0);
        assert!(
            referenced[1..].iter().all(|&r| r == 1),
            "{cost:?}: a node referenced other than once"
        );
    }
    // The big-leaf extreme fills nodes to the brim, so its overflow handling was exercised.
    assert!(fullest[2] > 20, "fullest nodes {fullest:?}");
}

/// Trees from the extreme cost models answer as brute force does.
#[test]
fn extreme_collapses_match_brute_force() {
    let tris = mixed_scene();
    let bvh2 = build_bvh2(&tris);
    let top = Accel::from_triangles(&[]).simd;
    for cost in EXTREME_COSTS {
        let accel = Accel::from_bvh2(&tris, &bvh2, cost, top);
        let mut rng = Rng::for_sample(13, 14, 15);
        let mut hits = 0;
        for _ in 0..3000 {
            let o = rand3(&mut rng) * 8.0 - 4.0;
            let d = uniform_sphere(rng.next_vec2());
            hits += check_against_brute_force(&accel, &tris, o, d, f32::INFINITY) as usize;
        }
        assert!(hits > 1000, "{cost:?}: only {hits} rays hit");
    }
}

#[test]
fn simd_and_portable_paths_agree_bit_for_bit() {
    let top = Accel::from_triangles(&[]).simd;
    let paths: Vec<Simd> = [Simd::Avx2, Simd::Avx512]
        .into_iter()
        .filter(|&p| p == Simd::Avx2 && top != Simd::Portable || p == top)
        .collect();
    if paths.is_empty() {
        eprintln!("no AVX2 on this CPU: nothing to compare");
        return;
    }
    let mut rng = Rng::for_sample(7, 8, 9);
    let mut tris = random_triangles(2000, &mut rng);
    tris.extend(triangles(&grid_cube(5)));
    let accel = Accel::from_triangles(&tris);
    let bits = |h: Option<(u32, f32, f32, f32)>| {
        h.map(|h| (h.0, h.1.to_bits(), h.2.to_bits(), h.3.to_bits()))
    };
    for _ in 0..5000 {
        let o = rand3(&mut rng) * 6.0 - 3.0;
        let d = uniform_sphere(rng.next_vec2());
        let p = accel.query::<false>(o, d, 0.0, f32::INFINITY, Simd::Portable);
        let po = accel.query::<true>(o, d, 0.0, 1.5, Simd::Portable);
        for &path in &paths {
            let a = accel.query::<false>(o, d, 0.0, f32::INFINITY, path);
            assert_eq!(bits(a), bits(p), "{path:?}");
            let a = accel.query::<true>(o, d, 0.0, 1.5, path);
            assert_eq!(a.map(|h| h.0), po.map(|h| h.0), "{path:?}");
        }
    }
}

#[test]
fn empty_scene_has_no_hits() {
    let accel = Accel::from_triangles(&[]);
    assert!(accel
        .intersect(Vec3::ZERO, Vec3::X, 0.0, f32::INFINITY)
        .is_none());
    assert!(!accel.occluded(Vec3::ZERO, Vec3::X, 0.0, f32::INFINITY));
    let one = [tri(
        Vec3::new(1.0, -1.0, -1.0),
        Vec3::new(1.0, 1.0, -1.0),
        Vec3::new(1.0, 0.0, 1.0),
    )];
    let h = Accel::from_triangles(&one).intersect(Vec3::ZERO, Vec3::X, 0.0, f32::INFINITY);
    assert_eq!(h.map(|h| h.t), Some(1.0));
    let _ = Vec2::ZERO;
}

/// The sixteen-lane leaf test gives, on every SIMD path, bit for bit what the one-triangle
/// test gives on each active lane's triangle (closest: least t, lowest lane on ties;
/// occlusion: any), ignores the inactive lanes (they hold a triangle every ray hits), and
/// takes the f64 path on edges like the one-triangle test.
#[test]
fn sixteen_lane_leaf_test_equals_the_one_triangle_test() {
    use super::triangle::{intersect, intersect16, Lanes, Portable16, RayTri, Tri};
    let mut rng = Rng::for_sample(10, 11, 12);
    let big = tri(
        Vec3::new(-50.0, -50.0, 0.01),
        Vec3::new(50.0, -50.0, 0.02),
        Vec3::new(0.0, 50.0, 0.015),
    );
    let top = Accel::from_triangles(&[]).simd;
    let (mut hits, mut edges) = (0, 0);
    for case in 0..20000 {
        // Blocks of 1 to 24 triangles (a node's leaves) around the origin, some of them
        // inactive; a ray from a random point aimed at a random vertex, edge point or
        // interior point of an active one (edges: the f64 path).
        let n = 1 + case % 24;
        let mut tris: Vec<Triangle> = random_triangles(n, &mut rng)
            .iter()
            .map(|t| {
                let s = |v: glam::Vec3A| (Vec3::from(v) * 0.3).into();
                Triangle {
                    v0: s(t.v0),
                    v1: s(t.v1),
                    v2: s(t.v2),
                }
            })
            .collect();
        if case % 7 == 0 && n > 1 {
            // Two triangles sharing an edge, bit-identical vertices.
            tris[1].v0 = tris[0].v1;
            tris[1].v1 = tris[0].v0;
        }
        let block = if n > 16 && case % 2 == 1 { 1 } else { 0 };
        let lanes = (n - 16 * block).min(16);
        let mut active = (rng.next_f32() * 65536.0) as u32 & ((1u32 << lanes) - 1);
        let aim = 16 * block + (case / 24) % lanes;
        active |= 1 << (aim - 16 * block);
        let inactive: Vec<usize> = (0..n)
            .filter(|&i| i / 16 != block || active >> (i % 16) & 1 == 0)
            .collect();
        for &i in &inactive {
            tris[i] = big;
        }
        // Rows of n as in the BVH, the pad past them holding the big triangle too.
        let mut rows = vec![0.0f32; 9 * n + 16];
        for k in 0..3 {
            for axis in 0..3 {
                for (lane, t) in tris.iter().enumerate() {
                    rows[(3 * k + axis) * n + lane] = [t.v0, t.v1, t.v2][k][axis];
                }
            }
        }
        for (i, x) in rows.iter_mut().enumerate().skip(9 * n) {
            *x = [big.v0, big.v1, big.v2][2][i % 3];
        }
        let t0 = tris[aim];
        let (a, b, c) = (Vec3::from(t0.v0), Vec3::from(t0.v1), Vec3::from(t0.v2));
        let target = match case % 4 {
            0 => a,
            1 => a + (b - a) * rng.next_f32(),
            _ => {
                let (u, v) = (rng.next_f32(), rng.next_f32());
                let (u, v) = if u + v > 1.0 {
                    (1.0 - u, 1.0 - v)
                } else {
                    (u, v)
                };
                a + (b - a) * u + (c - a) * v
            }
        };
        let o = rand3(&mut rng) * 4.0 - 2.0;
        let d = (target - o).normalize();
        let r = RayTri::new(o, d);
        let tmax = if case % 5 == 0 { 1.0 } else { f32::INFINITY };
        let mut expect: Option<(usize, f32, f32, f32)> = None;
        for lane in 0..lanes {
            if active >> lane & 1 == 0 {
                continue;
            }
            let t = tris[16 * block + lane];
            let one = Tri {
                v: [t.v0, t.v1, t.v2],
            };
            if let Some((t, b1, b2)) = intersect(&one, &r, 0.0, tmax) {
                if expect.is_none_or(|e| t < e.1) {
                    expect = Some((lane, t, b1, b2));
                }
            }
        }
        let bits = |h: Option<(usize, f32, f32, f32)>| {
            h.map(|h| (h.0, h.1.to_bits(), h.2.to_bits(), h.3.to_bits()))
        };
        let p = rows[16 * block..].as_ptr();
        // SAFETY: rows of n from p, sixteen lanes each: 8 n + 16 values, within `rows`;
        // each path is taken only where `top` says the CPU has it.
        unsafe fn both<L: Lanes>(
            p: *const f32,
            n: usize,
            active: u32,
            r: &RayTri,
            tmax: f32,
        ) -> (Option<(usize, f32, f32, f32)>, bool) {
            unsafe {
                (
                    intersect16::<false, L>(p, n, active, r, 0.0, tmax),
                    intersect16::<true, L>(p, n, active, r, 0.0, tmax).is_some(),
                )
            }
        }
        let mut got = vec![unsafe { both::<Portable16>(p, n, active, &r, tmax) }];
        #[cfg(target_arch = "x86_64")]
        {
            use super::triangle::{Avx2x16, Avx512x16};
            if top != Simd::Portable {
                got.push(unsafe { avx2_both(p, n, active, &r, tmax) });
            }
            if top == Simd::Avx512 {
                got.push(unsafe { avx512_both(p, n, active, &r, tmax) });
            }
            #[target_feature(enable = "avx2")]
            unsafe fn avx2_both(
                p: *const f32,
                n: usize,
                active: u32,
                r: &RayTri,
                tmax: f32,
            ) -> (Option<(usize, f32, f32, f32)>, bool) {
                unsafe { both::<Avx2x16>(p, n, active, r, tmax) }
            }
            #[target_feature(enable = "avx2,avx512f")]
            unsafe fn avx512_both(
                p: *const f32,
                n: usize,
                active: u32,
                r: &RayTri,
                tmax: f32,
            ) -> (Option<(usize, f32, f32, f32)>, bool) {
                unsafe { both::<Avx512x16>(p, n, active, r, tmax) }
            }
        }
        for (path, (closest, any)) in got.into_iter().enumerate() {
            assert_eq!(
                bits(closest),
                bits(expect),
                "case {case} path {path}: {tris:?} o {o} d {d}"
            );
            assert_eq!(any, expect.is_some(), "case {case} path {path}: occlusion");
        }
        hits += expect.is_some() as usize;
        edges += (case % 4 < 2) as usize;
    }
    assert!(
        hits > 8000 && edges > 8000,
        "{hits} hits, {edges} edge rays"
    );
}

/// A stream's answers are each ray's single query's, bit for bit, on every SIMD path: the
/// walks take turns, but each visits its nodes in its own order. Odd lengths, one ray and none
/// included (the last walk runs alone), finite tmax and tmin (culling by the ray's interval).
#[test]
fn streams_answer_as_single_queries_bit_for_bit() {
    let top = Accel::from_triangles(&[]).simd;
    let paths: Vec<Simd> = [Simd::Portable, Simd::Avx2, Simd::Avx512]
        .into_iter()
        .filter(|&p| match p {
            Simd::Portable => true,
            Simd::Avx2 => top != Simd::Portable,
            Simd::Avx512 => top == Simd::Avx512,
        })
        .collect();
    let mut rng = Rng::for_sample(3, 1, 4);
    let mut tris = random_triangles(1500, &mut rng);
    tris.extend(triangles(&grid_cube(4)));
    tris.extend(triangles(&sphere(3, Vec3::new(0.5, 0.2, -0.3))));
    let accel = Accel::from_triangles(&tris);
    let rays: Vec<Ray> = (0..2001)
        .map(|i| {
            let origin = rand3(&mut rng) * 6.0 - 3.0;
            let dir = uniform_sphere(rng.next_vec2());
            let (tmin, tmax) = match i % 3 {
                0 => (0.0, f32::INFINITY),
                1 => (0.0, 2.0 * rng.next_f32()),
                _ => (rng.next_f32(), 1.0 + 3.0 * rng.next_f32()),
            };
            Ray {
                origin,
                dir,
                tmin,
                tmax,
            }
        })
        .collect();
    let bits = |h: Found| h.map(|h| (h.0, h.1.to_bits(), h.2.to_bits(), h.3.to_bits()));
    let mut hits = 0;
    for &path in &paths {
        for n in [0, 1, 2, 3, rays.len()] {
            let rays = &rays[..n];
            let mut closest = vec![None; n];
            let mut any = vec![None; n];
            accel.stream::<false>(rays, path, |i, f| closest[i] = Some(bits(f)));
            accel.stream::<true>(rays, path, |i, f| any[i] = Some(f.is_some()));
            for (i, r) in rays.iter().enumerate() {
                let single = accel.query::<false>(r.origin, r.dir, r.tmin, r.tmax, path);
                assert_eq!(closest[i], Some(bits(single)), "{path:?}, ray {i} of {n}");
                let blocked = accel.query::<true>(r.origin, r.dir, r.tmin, r.tmax, path);
                assert_eq!(any[i], Some(blocked.is_some()), "{path:?}, ray {i} of {n}");
                hits += single.is_some() as usize;
            }
        }
    }
    // The rays must both hit and miss for the comparison to mean something.
    assert!(hits > 500 && hits < 1500 * paths.len(), "{hits} hits");
    // The public wrappers and the empty tree.
    let mut h = vec![None; 5];
    let mut b = vec![true; 5];
    accel.intersect_stream(&rays[..5], &mut h);
    accel.occluded_stream(&rays[..5], &mut b);
    for (i, r) in rays[..5].iter().enumerate() {
        assert_eq!(h[i], accel.intersect(r.origin, r.dir, r.tmin, r.tmax));
        assert_eq!(b[i], accel.occluded(r.origin, r.dir, r.tmin, r.tmax));
    }
    let empty = Accel::from_triangles(&[]);
    empty.intersect_stream(&rays[..5], &mut h);
    empty.occluded_stream(&rays[..5], &mut b);
    assert!(h.iter().all(Option::is_none) && b.iter().all(|&b| !b));
}
