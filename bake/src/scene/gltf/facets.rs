//! Meshes without NORMAL attributes: what baking them faceted costs, and whether they look
//! meant to be smooth (config `missing_normals`, docs/config.md).
//!
//! The glTF rule (spec 3.7.2.1) gives such a mesh flat normals: every triangle corner is its own
//! vertex. A per-vertex bake welds corners that share position and normal (a flat ground costs
//! nothing), so what faceting costs is the number of distinct (position, face normal) pairs
//! against the number of positions. A sphere or torus exported without normals is usually an
//! exporter's omission, not a wish for facets: its neighbouring faces meet at small angles,
//! where a box's meet at right angles. The loader warns with both figures and, for the former,
//! names the key that computes smooth normals.

use std::collections::{HashMap, HashSet};

use glam::Vec3;

/// Faces meeting at less than this (degrees, median over the edges where they are not
/// coplanar) look like a tessellated smooth surface.
const SMOOTH_MEDIAN_DEGREES: f32 = 30.0;

/// Edges whose faces meet at less than this (degrees) count as coplanar.
const COPLANAR_DEGREES: f32 = 0.5;

/// The bits of `v` with -0 read as +0: normals that differ only in the sign of a zero are the
/// same normal (and weld: `vertex/prepare.rs` keys them the same way).
fn key_bits(v: Vec3) -> [u32; 3] {
    v.to_array().map(|c| (c + 0.0).to_bits())
}

/// What faceting one mesh primitive costs.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct Facets {
    /// Vertices after welding with flat normals: distinct (position, face normal) pairs.
    pub faceted_vertices: usize,
    /// Vertices with smooth normals: distinct positions used.
    pub smooth_vertices: usize,
    /// The median angle (degrees) between neighbouring faces that are not coplanar; None when
    /// every edge is between coplanar faces (or shared by no two faces).
    pub median_crease_degrees: Option<f32>,
}

impl Facets {
    /// Whether the mesh looks like a smooth surface tessellated (see the module documentation).
    pub fn looks_smooth(&self) -> bool {
        self.median_crease_degrees
            .is_some_and(|a| a < SMOOTH_MEDIAN_DEGREES)
    }

    /// Whether faceting changes anything: some neighbouring faces are not coplanar.
    pub fn creased(&self) -> bool {
        self.median_crease_degrees.is_some()
    }
}

/// Analyses triangles (position indices, each with its unit face normal).
pub(super) fn analyse(triangles: &[([u32; 3], Vec3)]) -> Facets {
    let mut pairs: HashSet<(u32, [u32; 3])> = HashSet::new();
    let mut used: HashSet<u32> = HashSet::new();
    let mut edges: HashMap<(u32, u32), (Vec3, u32)> = HashMap::new();
    let mut creases: Vec<f32> = Vec::new();
    for &(tri, n) in triangles {
        for k in 0..3 {
            let v = tri[k];
            pairs.insert((v, key_bits(n)));
            used.insert(v);
            let w = tri[(k + 1) % 3];
            let key = (v.min(w), v.max(w));
            let entry = edges.entry(key).or_insert((n, 0));
            entry.1 += 1;
            if entry.1 == 2 {
                let degrees = entry.0.dot(n).clamp(-1.0, 1.0).acos().to_degrees();
                if degrees > COPLANAR_DEGREES {
                    creases.push(degrees);
                }
            }
        }
    }
    let median_crease_degrees = if creases.is_empty() {
        None
    } else {
        let mid = creases.len() / 2;
        let (_, m, _) = creases.select_nth_unstable_by(mid, f32::total_cmp);
        Some(*m)
    };
    Facets {
        faceted_vertices: pairs.len(),
        smooth_vertices: used.len(),
        median_crease_degrees,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::icosphere;

    fn faces(positions: &[Vec3], tris: &[[u32; 3]]) -> Vec<([u32; 3], Vec3)> {
        tris.iter()
            .map(|&t| {
                let [a, b, c] = t.map(|i| positions[i as usize]);
                (t, (b - a).cross(c - a).normalize())
            })
            .collect()
    }

    #[test]
    fn a_sphere_looks_smooth_a_box_does_not_and_a_plane_is_not_creased() {
        let (p, t) = icosphere(3);
        let sphere = analyse(&faces(&p, &t));
        assert!(sphere.looks_smooth(), "{sphere:?}");
        // Every face has its own normal: three vertices per triangle corner position share
        // a position, so the faceted count is the number of corners.
        assert_eq!(sphere.faceted_vertices, 3 * t.len());
        assert_eq!(sphere.smooth_vertices, p.len());

        // A cube: 8 positions, 12 triangles; faceted, each corner is 3 vertices.
        let p: Vec<Vec3> = (0..8)
            .map(|i| Vec3::new((i & 1) as f32, ((i >> 1) & 1) as f32, ((i >> 2) & 1) as f32))
            .collect();
        let t = [
            [0, 2, 1],
            [1, 2, 3],
            [4, 5, 6],
            [5, 7, 6],
            [0, 1, 4],
            [1, 5, 4],
            [2, 6, 3],
            [3, 6, 7],
            [0, 4, 2],
            [2, 4, 6],
            [1, 3, 5],
            [3, 7, 5],
        ];
        let cube = analyse(&faces(&p, &t));
        assert!(cube.creased() && !cube.looks_smooth(), "{cube:?}");
        assert_eq!((cube.faceted_vertices, cube.smooth_vertices), (24, 8));

        // A 4 x 4 grid: faceting costs nothing.
        let p: Vec<Vec3> = (0..25)
            .map(|i| Vec3::new((i % 5) as f32, 0.0, (i / 5) as f32))
            .collect();
        let t: Vec<[u32; 3]> = (0..16u32)
            .flat_map(|q| {
                let (x, z) = (q % 4, q / 4);
                let a = z * 5 + x;
                [[a, a + 5, a + 1], [a + 1, a + 5, a + 6]]
            })
            .collect();
        let grid = analyse(&faces(&p, &t));
        assert!(!grid.creased(), "{grid:?}");
        assert_eq!((grid.faceted_vertices, grid.smooth_vertices), (25, 25));
    }
}
