//! The eye check (`view.rs`): the shared rule applied by the runtime's brute-force check.

use super::*;

/// Per-vertex normals of a mesh: the area-weighted sum of its faces' normals.
fn vertex_normals(m: &Mesh, outward: bool) -> Vec<[f32; 3]> {
    let mut n = vec![[0.0f32; 3]; m.positions.len()];
    for t in &m.triangles {
        let [a, b, c] = t.map(|v| f64s(m.positions[v as usize]));
        let f = cross(sub(b, a), sub(c, a));
        for v in t {
            for i in 0..3 {
                n[*v as usize][i] += if outward { f[i] } else { -f[i] } as f32;
            }
        }
    }
    n
}

/// The runtime's brute-force eye check applies the shared rule: inside a closed object it is
/// refused naming the object's material, outside it and inside a room facing inwards it is not.
#[test]
fn the_eye_check_finds_an_eye_inside_an_object() {
    let mut rng = Lcg::new(5);
    let ball = sphere([0.0, 0.0, 0.0], 1.0, 24, 48, 0.0);
    let mut scene = floor(-1.0, 10.0, 8, &mut rng);
    let floor_tris = scene.triangles.len();
    scene.add(&ball);
    let mut normals = vertex_normals(&scene, true);
    // The floor's normals point up.
    let floor_verts = 81;
    normals[..floor_verts].fill([0.0, 1.0, 0.0]);
    let mut materials = vec![0u32; floor_tris];
    materials.resize(scene.triangles.len(), 3);
    let verdict = |eye: [f32; 3], normals: &[[f32; 3]]| {
        eye_verdict(&scene.positions, normals, &scene.triangles, &materials, eye).expect("check")
    };
    for eye in [[0.0, 0.0, 0.0], [0.3, -0.5, 0.2], [0.0, 0.0, 0.95]] {
        let v = verdict(eye, &normals);
        assert!(v.inside, "{eye:?}: {v:?}");
        assert_eq!((v.material, v.total), (Some(3), 26), "{eye:?}");
        assert!(v.back >= 22);
    }
    for eye in [
        [0.0, 0.0, 4.0],
        [1.05, 0.0, 0.0],
        [3.0, 3.0, 3.0],
        [0.0, -3.0, 0.0],
    ] {
        let v = verdict(eye, &normals);
        assert!(!v.inside, "{eye:?}: {v:?}");
    }
    // A room: the same sphere with its normals facing inwards.
    let room_normals: Vec<[f32; 3]> = vertex_normals(&scene, false);
    let v = verdict([0.1, 0.2, -0.3], &room_normals);
    assert!(!v.inside && v.back <= 1, "{v:?}");
}
