//! The BVH's closest hits and occlusion queries agree with brute-force intersection.

use glam::Vec3;
use obvhs::triangle::Triangle;
use prt_bake::accel::{brute_force_intersect, Accel};
use prt_bake::sampling::{uniform_sphere, Rng};

fn random_triangles(n: usize, rng: &mut Rng) -> Vec<Triangle> {
    (0..n)
        .map(|_| {
            let c = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 4.0 - 2.0;
            let mut v =
                || c + (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5) * 0.6;
            Triangle {
                v0: v().into(),
                v1: v().into(),
                v2: v().into(),
            }
        })
        .collect()
}

#[test]
fn bvh_closest_hit_equals_brute_force() {
    let mut rng = Rng::for_sample(1, 2, 3);
    let tris = random_triangles(2000, &mut rng);
    let accel = Accel::from_triangles(&tris);
    let mut hits = 0;
    for _ in 0..3000 {
        let origin = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 6.0 - 3.0;
        let dir = uniform_sphere(rng.next_vec2());
        let a = accel.intersect(origin, dir, 0.0, f32::INFINITY);
        let b = brute_force_intersect(&tris, origin, dir, 0.0, f32::INFINITY);
        match (a, b) {
            (None, None) => {}
            (Some(a), Some(b)) => {
                hits += 1;
                assert!(
                    (a.t - b.t).abs() <= 1e-5 * b.t.max(1.0),
                    "t {} vs {}",
                    a.t,
                    b.t
                );
                if a.triangle != b.triangle {
                    // Only acceptable for an exact tie in distance.
                    assert_eq!(a.t, b.t);
                } else {
                    assert!((a.bary - b.bary).abs().max_element() < 1e-4);
                }
            }
            (a, b) => panic!("bvh {a:?} vs brute force {b:?}"),
        }
        // Occlusion within the hit distance agrees too.
        let tmax = b.map_or(10.0, |h| h.t * 0.999);
        let occl = accel.occluded(origin, dir, 0.0, tmax);
        let brute = brute_force_intersect(&tris, origin, dir, 0.0, tmax).is_some();
        assert_eq!(occl, brute);
    }
    assert!(hits > 300, "only {hits} rays hit: the test would be weak");
}

#[test]
fn empty_scene_has_no_hits() {
    let accel = Accel::from_triangles(&[]);
    assert!(accel
        .intersect(Vec3::ZERO, Vec3::X, 0.0, f32::INFINITY)
        .is_none());
    assert!(!accel.occluded(Vec3::ZERO, Vec3::X, 0.0, f32::INFINITY));
}
