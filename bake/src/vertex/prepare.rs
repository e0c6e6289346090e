//! The mesh a per-vertex bake stores transfer for (docs/vertex.md, "Model only what the scene
//! needs"): the scene's vertices **welded** where they share position, baked normal, texture
//! coordinate and group, unused vertices dropped, and the rest **ordered** by group and unit
//! (`units.rs`), so that every group and every unit is a contiguous range of vertex indices.
//!
//! Welding: a glTF mesh without normals gets flat normals, one vertex per triangle corner (the
//! glTF rule); on a flat ground the corners meeting at a grid point then share position and
//! normal, so their transfer is the same: one vertex is traced, not six. Vertices of
//! different groups (materials) are never welded, so every triangle keeps its vertices'
//! group, and the shading basis its T0 rows follow.
//!
//! Ordering: a unit's vertices are traced, compressed and written together, and a group's
//! tensors are the concatenation of its units' rows; contiguous ranges let the bake stream
//! them to the file in order without holding a group. The triangles keep their order (a
//! vertex's group is that of its lowest-indexed triangle, unchanged by renumbering).

use std::collections::HashMap;

use glam::Vec3;

use crate::scene::Scene;

use super::plan::{first_triangles, vertex_normals};
use super::units::{plan_units, Unit, UNIT_VERTICES};

/// What welds two vertices: the bits of position, normal and texture coordinate, and the group.
type WeldKey = ([u32; 3], [u32; 3], [u32; 2], u32);

/// A scene prepared for the per-vertex bake.
pub struct PreparedScene {
    /// The scene with welded, reordered vertices (normals: the baked ones, unit length).
    pub scene: Scene,
    /// The units, in order; each one's vertices are a contiguous ascending range.
    pub units: Vec<Unit>,
    /// Vertices before welding (the loaded scene's).
    pub loaded_vertices: usize,
    /// Vertices merged into another by welding.
    pub welded: usize,
    /// Vertices no triangle uses (dropped).
    pub unused: usize,
}

/// Welds and orders `scene`'s vertices for the per-vertex bake, in units of up to
/// [`UNIT_VERTICES`] (`super::prepare_scene_for` sizes them for the compression settings).
pub fn prepare_scene(scene: &Scene) -> PreparedScene {
    prepare_scene_with(scene, UNIT_VERTICES)
}

/// [`prepare_scene`] without the welding: every used vertex stays its own (for comparing a
/// welded bake with the one welding saves, `tests/tests/suite/vertex_weld.rs`).
pub fn prepare_scene_unwelded(scene: &Scene) -> PreparedScene {
    prepare(scene, UNIT_VERTICES, false)
}

/// [`prepare_scene`] with units of up to `max_unit` vertices.
pub(crate) fn prepare_scene_with(scene: &Scene, max_unit: usize) -> PreparedScene {
    prepare(scene, max_unit, true)
}

fn prepare(scene: &Scene, max_unit: usize, weld: bool) -> PreparedScene {
    let loaded = scene.positions.len();
    let first = first_triangles(scene);
    let normals = vertex_normals(scene, &first);
    let group_of: Vec<Option<u32>> = first
        .iter()
        .map(|t| t.map(|t| scene.triangle_material[t as usize]))
        .collect();

    // Weld: the first vertex (by index) with a key stands for every later one.
    let mut key_to_new: HashMap<WeldKey, u32> = HashMap::new();
    let mut old_to_welded = vec![u32::MAX; loaded];
    let mut welded_src: Vec<u32> = Vec::new();
    let mut unused = 0;
    for v in 0..loaded {
        let Some(m) = group_of[v] else {
            unused += 1;
            continue;
        };
        // -0 and +0 are one value: a face normal (0, -0, 1) welds with (0, 0, 1).
        let bits = |c: f32| (c + 0.0).to_bits();
        let key = (
            scene.positions[v].to_array().map(bits),
            normals[v].to_array().map(bits),
            scene.uvs[v].to_array().map(bits),
            m,
        );
        let id = if weld {
            *key_to_new.entry(key).or_insert_with(|| {
                welded_src.push(v as u32);
                (welded_src.len() - 1) as u32
            })
        } else {
            welded_src.push(v as u32);
            (welded_src.len() - 1) as u32
        };
        old_to_welded[v] = id;
    }
    drop(key_to_new);
    let welded = loaded - unused - welded_src.len();

    // Groups (material order) and units on the welded vertices.
    let positions: Vec<Vec3> = welded_src
        .iter()
        .map(|&v| scene.positions[v as usize])
        .collect();
    let w_normals: Vec<Vec3> = welded_src.iter().map(|&v| normals[v as usize]).collect();
    let mut members: Vec<Vec<u32>> = vec![Vec::new(); scene.materials.len()];
    for (w, &v) in welded_src.iter().enumerate() {
        if let Some(m) = group_of[v as usize] {
            members[m as usize].push(w as u32);
        }
    }
    let group_lists: Vec<&[u32]> = members
        .iter()
        .filter(|m| !m.is_empty())
        .map(|m| m.as_slice())
        .collect();
    let mut units = plan_units(&group_lists, &positions, &w_normals, max_unit);

    // Renumber in unit order.
    let mut welded_to_new = vec![u32::MAX; welded_src.len()];
    let mut order: Vec<u32> = Vec::with_capacity(welded_src.len());
    for u in &mut units {
        for v in &mut u.vertices {
            welded_to_new[*v as usize] = order.len() as u32;
            order.push(*v);
            *v = (order.len() - 1) as u32;
        }
    }
    let mut out = Scene {
        positions: order.iter().map(|&w| positions[w as usize]).collect(),
        normals: order.iter().map(|&w| w_normals[w as usize]).collect(),
        uvs: order
            .iter()
            .map(|&w| scene.uvs[welded_src[w as usize] as usize])
            .collect(),
        triangles: Vec::with_capacity(scene.triangles.len()),
        triangle_material: scene.triangle_material.clone(),
        materials: scene.materials.clone(),
        textures: scene.textures.clone(),
        lights: scene.lights.clone(),
        camera: scene.camera,
        environment: scene.environment.clone(),
        environment_rotation: scene.environment_rotation,
        skipped_triangles: scene.skipped_triangles,
    };
    out.triangles = scene
        .triangles
        .iter()
        .map(|t| t.map(|v| welded_to_new[old_to_welded[v as usize] as usize]))
        .collect();
    PreparedScene {
        scene: out,
        units,
        loaded_vertices: loaded,
        welded,
        unused,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::brdf::BrdfParams;
    use crate::testing::SceneBuilder;

    /// A flat n x n grid of quads, faceted like a glTF without normals: every triangle its own
    /// three vertices.
    fn faceted_grid(n: u32, material: &str) -> Scene {
        let mut b = SceneBuilder::new();
        let m = b.material(
            material,
            BrdfParams::diffuse(Vec3::splat(0.5)),
            Vec3::ZERO,
            false,
        );
        let p = |i: u32, j: u32| Vec3::new(i as f32, 0.0, j as f32);
        for j in 0..n {
            for i in 0..n {
                for t in [
                    [p(i, j), p(i, j + 1), p(i + 1, j + 1)],
                    [p(i, j), p(i + 1, j + 1), p(i + 1, j)],
                ] {
                    b.mesh(&t, &[Vec3::Y; 3], &[[0, 1, 2]], m);
                }
            }
        }
        b.build()
    }

    #[test]
    fn a_faceted_flat_grid_welds_to_one_vertex_per_grid_point() {
        let s = faceted_grid(10, "ground");
        assert_eq!(s.positions.len(), 600);
        let p = prepare_scene(&s);
        assert_eq!(p.scene.positions.len(), 121);
        assert_eq!(p.welded, 600 - 121);
        assert_eq!(p.unused, 0);
        // The same triangles over the same points, in the same order.
        for (t0, t1) in s.triangles.iter().zip(&p.scene.triangles) {
            for k in 0..3 {
                assert_eq!(
                    s.positions[t0[k] as usize],
                    p.scene.positions[t1[k] as usize]
                );
            }
        }
        // Units cover the vertices in order, as contiguous ranges.
        let mut next = 0u32;
        for u in &p.units {
            for &v in &u.vertices {
                assert_eq!(v, next);
                next += 1;
            }
        }
        assert_eq!(next as usize, p.scene.positions.len());
    }

    #[test]
    fn different_normals_uvs_or_groups_are_not_welded_and_unused_vertices_go() {
        let mut b = SceneBuilder::new();
        let a = b.material("a", BrdfParams::diffuse(Vec3::ONE), Vec3::ZERO, false);
        let c = b.material("c", BrdfParams::diffuse(Vec3::ONE), Vec3::ZERO, false);
        let tri = [Vec3::ZERO, Vec3::X, Vec3::Z];
        // Same positions: facing up, facing up again with -0 components (welds: a cross
        // product's zeros come with either sign), facing down, another material.
        b.mesh(&tri, &[Vec3::Y; 3], &[[0, 2, 1]], a);
        b.mesh(&tri, &[Vec3::new(-0.0, 1.0, -0.0); 3], &[[0, 2, 1]], a);
        b.mesh(&tri, &[Vec3::NEG_Y; 3], &[[0, 1, 2]], a);
        b.mesh(&tri, &[Vec3::Y; 3], &[[0, 2, 1]], c);
        let mut s = b.build();
        // An unused vertex.
        s.positions.push(Vec3::ONE);
        s.normals.push(Vec3::Y);
        s.uvs.push(glam::Vec2::ZERO);
        let p = prepare_scene(&s);
        assert_eq!(p.scene.positions.len(), 9);
        assert_eq!((p.welded, p.unused), (3, 1));
        assert_eq!(p.scene.triangles[0], p.scene.triangles[1]);
        assert_ne!(p.scene.triangles[0], p.scene.triangles[3]);
        // A different UV keeps its vertex.
        let mut s2 = s.clone();
        s2.uvs[3] = glam::Vec2::new(0.5, 0.5);
        assert_eq!(prepare_scene(&s2).scene.positions.len(), 10);
    }
}
