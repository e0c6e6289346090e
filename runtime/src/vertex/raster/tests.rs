//! The rasterizer's tests. Against an independent ray caster: f64 Moller-Trumbore at every
//! pixel centre, with the view direction re-derived here from the documented convention
//! (docs/conventions.md, "Camera"). Pixels whose centre lies within a hair (1e-9 rad) of a
//! triangle's edge, as the caster sees it, may go either way; they are counted and bounded.
//! Then its parts: the tie rule of shared edges, the film mapping, and the eye check
//! (`view.rs`).

use prt_formats::view::CameraSpec;
use rayon::prelude::*;

use super::*;
use crate::vertex::view::eye_verdict;

mod eye;
mod parts;
mod samples;
mod timing;

/// A small deterministic generator (an LCG) for the test geometry.
struct Lcg(u64);

impl Lcg {
    fn new(seed: u64) -> Lcg {
        Lcg(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1)
    }
    /// Uniform in [lo, hi).
    fn uniform(&mut self, lo: f32, hi: f32) -> f32 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let u = (self.0 >> 40) as f32 / (1u64 << 24) as f32;
        lo + (hi - lo) * u
    }
}

type V3 = [f64; 3];

fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn cross(a: V3, b: V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
fn f64s(p: [f32; 3]) -> V3 {
    p.map(f64::from)
}

#[derive(Clone, Default)]
struct Mesh {
    positions: Vec<[f32; 3]>,
    triangles: Vec<[u32; 3]>,
}

impl Mesh {
    fn add(&mut self, other: &Mesh) {
        let base = self.positions.len() as u32;
        self.positions.extend_from_slice(&other.positions);
        self.triangles
            .extend(other.triangles.iter().map(|t| t.map(|v| v + base)));
    }

    /// A closed surface of revolution-like grid: `point(i, j)` for i in 0..=rows (its first and
    /// last rows collapse to poles when `poles`), j wrapping around `cols`.
    fn wrapped(rows: u32, cols: u32, point: impl Fn(u32, u32) -> [f32; 3], poles: bool) -> Mesh {
        let mut m = Mesh::default();
        if poles {
            // Shared pole vertices: fans of thin triangles around them.
            m.positions.push(point(0, 0));
            for i in 1..rows {
                for j in 0..cols {
                    m.positions.push(point(i, j));
                }
            }
            m.positions.push(point(rows, 0));
            let ring = |i: u32, j: u32| 1 + (i - 1) * cols + j % cols;
            let south = m.positions.len() as u32 - 1;
            for j in 0..cols {
                m.triangles.push([0, ring(1, j + 1), ring(1, j)]);
                m.triangles
                    .push([south, ring(rows - 1, j), ring(rows - 1, j + 1)]);
            }
            for i in 1..rows - 1 {
                for j in 0..cols {
                    let (a, b) = (ring(i, j), ring(i, j + 1));
                    let (c, d) = (ring(i + 1, j), ring(i + 1, j + 1));
                    m.triangles.push([a, b, d]);
                    m.triangles.push([a, d, c]);
                }
            }
        } else {
            // A torus-like grid wrapping in both directions.
            for i in 0..rows {
                for j in 0..cols {
                    m.positions.push(point(i, j));
                }
            }
            let at = |i: u32, j: u32| (i % rows) * cols + j % cols;
            for i in 0..rows {
                for j in 0..cols {
                    let (a, b, c, d) = (at(i, j), at(i, j + 1), at(i + 1, j), at(i + 1, j + 1));
                    m.triangles.push([a, b, d]);
                    m.triangles.push([a, d, c]);
                }
            }
        }
        m
    }
}

/// A UV sphere (poles: fans of thin triangles), outward winding, optionally bumpy.
fn sphere(center: [f32; 3], radius: f32, rows: u32, cols: u32, bump: f32) -> Mesh {
    Mesh::wrapped(
        rows,
        cols,
        |i, j| {
            let th = std::f32::consts::PI * i as f32 / rows as f32;
            let ph = 2.0 * std::f32::consts::PI * j as f32 / cols as f32;
            let r = radius * (1.0 + bump * (5.0 * th).sin() * (7.0 * ph).cos());
            [
                center[0] + r * th.sin() * ph.cos(),
                center[1] + r * th.cos(),
                center[2] + r * th.sin() * ph.sin(),
            ]
        },
        true,
    )
}

/// A bumpy torus around +Y: `2 rows cols` triangles, closed, self-occluding.
fn torus(center: [f32; 3], big: f32, small: f32, rows: u32, cols: u32) -> Mesh {
    Mesh::wrapped(
        rows,
        cols,
        |i, j| {
            let u = 2.0 * std::f32::consts::PI * i as f32 / rows as f32;
            let v = 2.0 * std::f32::consts::PI * j as f32 / cols as f32;
            let r = small * (1.0 + 0.15 * (3.0 * u).sin() * (4.0 * v).sin());
            let ring = big + r * v.cos();
            [
                center[0] + ring * u.cos(),
                center[1] + r * v.sin(),
                center[2] + ring * u.sin(),
            ]
        },
        false,
    )
}

/// A floor at height `y`: `n x n` quads over [-half, half]^2, slightly jittered in height.
fn floor(y: f32, half: f32, n: u32, rng: &mut Lcg) -> Mesh {
    let mut m = Mesh::default();
    for i in 0..=n {
        for j in 0..=n {
            let x = -half + 2.0 * half * i as f32 / n as f32;
            let z = -half + 2.0 * half * j as f32 / n as f32;
            m.positions.push([x, y + rng.uniform(-0.02, 0.02), z]);
        }
    }
    for i in 0..n {
        for j in 0..n {
            let a = i * (n + 1) + j;
            let (b, c, d) = (a + 1, a + n + 1, a + n + 2);
            m.triangles.push([a, b, d]);
            m.triangles.push([a, d, c]);
        }
    }
    m
}

/// Large triangles at different depths, overlapping on screen, tilted, with random windings.
fn overlapping(rng: &mut Lcg) -> Mesh {
    let mut m = Mesh::default();
    for k in 0..12 {
        let z = -2.0 - 0.7 * k as f32;
        let c = [rng.uniform(-1.5, 1.5), rng.uniform(-1.0, 1.0), z];
        let (r, turn) = (rng.uniform(1.5, 2.5), rng.uniform(0.0, 2.1));
        let base = m.positions.len() as u32;
        for v in 0..3 {
            let a = turn + 2.094 * v as f32;
            m.positions.push([
                c[0] + r * a.cos(),
                c[1] + r * a.sin(),
                c[2] + rng.uniform(-0.3, 0.3),
            ]);
        }
        m.triangles.push(if k % 2 == 0 {
            [base, base + 1, base + 2]
        } else {
            [base, base + 2, base + 1]
        });
    }
    m
}

/// A closed disk of `n` thin triangles sharing its centre vertex, tilted.
fn fan(center: [f32; 3], radius: f32, n: u32) -> Mesh {
    let mut m = Mesh {
        positions: vec![center],
        triangles: Vec::new(),
    };
    for k in 0..n {
        let a = 2.0 * std::f32::consts::PI * k as f32 / n as f32;
        let (s, c) = a.sin_cos();
        m.positions.push([
            center[0] + radius * c,
            center[1] + radius * s * 0.6,
            center[2] + radius * s * 0.8,
        ]);
        m.triangles.push([0, 1 + k, 1 + (k + 1) % n]);
    }
    m
}

fn camera(spec: &str) -> CameraFrame {
    spec.parse::<CameraSpec>()
        .expect("camera spec")
        .frame()
        .expect("frame")
}

/// The view direction of pixel (x, y)'s centre, re-derived from the convention: image x grows
/// along `right`, y downward along `-up`; the film spans tan(yfov/2) vertically and W/H times
/// that horizontally.
fn oracle_dir(cam: &CameraFrame, w: u32, h: u32, x: u32, y: u32) -> V3 {
    let t = (f64::from(cam.yfov) / 2.0).tan();
    let sx = (2.0 * (f64::from(x) + 0.5) / f64::from(w) - 1.0) * t * f64::from(w) / f64::from(h);
    let sy = (1.0 - 2.0 * (f64::from(y) + 0.5) / f64::from(h)) * t;
    let (f, r, u) = (f64s(cam.forward), f64s(cam.right), f64s(cam.up));
    let d: V3 = std::array::from_fn(|i| f[i] + r[i] * sx + u[i] * sy);
    let len = dot(d, d).sqrt();
    d.map(|c| c / len)
}

/// A triangle as the caster wants it.
struct OTri {
    a: V3,
    e1: V3,
    e2: V3,
    /// Unit normals of the planes through the eye and each edge, positive inside.
    edges: Option<[V3; 3]>,
    /// Bounding sphere (centre, squared radius with a margin).
    center: V3,
    r2: f64,
}

struct Oracle {
    eye: V3,
    tris: Vec<OTri>,
}

/// What the caster sees through one pixel centre.
struct OPixel {
    /// (triangle, t, u, v) of the nearest hit.
    hit: Option<(usize, f64, f64, f64)>,
    /// Triangles no farther than the hit whose edge passes within 1e-9 rad of the ray.
    near_edge: Vec<usize>,
}

const EDGE_EPS: f64 = 1e-9;

impl Oracle {
    fn new(mesh: &Mesh, eye: [f32; 3]) -> Oracle {
        let eye = f64s(eye);
        let tris = mesh
            .triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|v| f64s(mesh.positions[v as usize]));
                let rel = [a, b, c].map(|p| sub(p, eye));
                let n = [
                    cross(rel[1], rel[2]),
                    cross(rel[2], rel[0]),
                    cross(rel[0], rel[1]),
                ];
                let det = dot(rel[0], n[0]);
                let edges = (det != 0.0 && n.iter().all(|e| dot(*e, *e) > 0.0)).then(|| {
                    n.map(|e| {
                        let s = det.signum() / dot(e, e).sqrt();
                        e.map(|x| x * s)
                    })
                });
                let center: V3 = std::array::from_fn(|i| (a[i] + b[i] + c[i]) / 3.0);
                let r2 = [a, b, c]
                    .iter()
                    .map(|p| dot(sub(*p, center), sub(*p, center)))
                    .fold(0.0, f64::max);
                OTri {
                    a,
                    e1: sub(b, a),
                    e2: sub(c, a),
                    edges,
                    center,
                    r2: r2 * (1.0 + 1e-6) + 1e-12,
                }
            })
            .collect();
        Oracle { eye, tris }
    }

    fn cast(&self, d: V3) -> OPixel {
        let mut hit: Option<(usize, f64, f64, f64)> = None;
        let mut candidates = Vec::new();
        for (k, t) in self.tris.iter().enumerate() {
            // Bounding-sphere rejection, then Moller-Trumbore.
            let oc = sub(t.center, self.eye);
            let tca = dot(oc, d);
            let far = dot(oc, oc) - tca * tca > t.r2 * (1.0 + 1e-6) + 1e-12;
            if far && dot(oc, oc) > t.r2 {
                continue;
            }
            let p = cross(d, t.e2);
            let det = dot(t.e1, p);
            if det == 0.0 {
                continue;
            }
            let s = sub(self.eye, t.a);
            let q = cross(s, t.e1);
            let tt = dot(t.e2, q) / det;
            if tt <= 0.0 {
                continue;
            }
            if let Some(e) = &t.edges {
                let margin = e.iter().map(|n| dot(*n, d)).fold(f64::INFINITY, f64::min);
                if margin.abs() < EDGE_EPS {
                    candidates.push((k, tt));
                }
            }
            let u = dot(s, p) / det;
            let v = dot(d, q) / det;
            if u < 0.0 || v < 0.0 || u + v > 1.0 {
                continue;
            }
            if hit.is_none_or(|h| tt < h.1) {
                hit = Some((k, tt, u, v));
            }
        }
        let limit = hit.map_or(f64::INFINITY, |h| h.1 * (1.0 + 1e-9));
        OPixel {
            hit,
            near_edge: candidates
                .into_iter()
                .filter(|c| c.1 <= limit)
                .map(|c| c.0)
                .collect(),
        }
    }
}

/// Agreement of one frame with the caster.
#[derive(Debug, Default)]
struct Agreement {
    pixels: usize,
    covered: usize,
    near_edge: usize,
    near_edge_differ: usize,
    max_bary: f64,
    max_depth_rel: f64,
}

fn compare(mesh: &Mesh, cam: &CameraFrame, w: u32, h: u32) -> (VisibilityBuffer, Agreement) {
    let vb = rasterize(&mesh.positions, &mesh.triangles, cam, w, h).expect("rasterize");
    let oracle = Oracle::new(mesh, cam.position);
    let cast: Vec<OPixel> = (0..w * h)
        .into_par_iter()
        .map(|p| oracle.cast(oracle_dir(cam, w, h, p % w, p / w)))
        .collect();
    let mut a = Agreement {
        pixels: (w * h) as usize,
        ..Agreement::default()
    };
    for (p, o) in cast.iter().enumerate() {
        let f = vb.fragments[p];
        let (x, y) = (p as u32 % w, p as u32 / w);
        if !f.is_empty() {
            a.covered += 1;
        }
        let seen = (!f.is_empty()).then_some(f.triangle as usize);
        if !o.near_edge.is_empty() {
            a.near_edge += 1;
            let want = o.hit.map(|h| h.0);
            if seen != want {
                a.near_edge_differ += 1;
                // Either way round an edge, but never something else.
                let ok = match seen {
                    Some(t) => o.near_edge.contains(&t),
                    None => want.is_none_or(|t| o.near_edge.contains(&t)),
                };
                assert!(
                    ok,
                    "pixel ({x}, {y}) near an edge: saw {seen:?}, caster {want:?}"
                );
            }
            continue;
        }
        assert_eq!(
            seen,
            o.hit.map(|h| h.0),
            "pixel ({x}, {y}): triangle seen (w {w}, h {h})"
        );
        if let Some((_, t, u, v)) = o.hit {
            let db = (f64::from(f.bary[0]) - u)
                .abs()
                .max((f64::from(f.bary[1]) - v).abs());
            let dd = (f64::from(f.distance) - t).abs() / t;
            assert!(
                db < 1e-4,
                "pixel ({x}, {y}): bary {:?} vs ({u}, {v})",
                f.bary
            );
            assert!(
                dd < 1e-5,
                "pixel ({x}, {y}): distance {} vs {t}",
                f.distance
            );
            a.max_bary = a.max_bary.max(db);
            a.max_depth_rel = a.max_depth_rel.max(dd);
        }
    }
    (vb, a)
}

fn scenes() -> Vec<(&'static str, Mesh)> {
    let mut rng = Lcg::new(7);
    let mut floor_scene = floor(0.0, 40.0, 24, &mut rng);
    floor_scene.add(&sphere([0.0, 1.0, -3.0], 1.0, 24, 48, 0.0));
    vec![
        ("sphere", sphere([0.2, -0.1, 0.0], 1.0, 32, 64, 0.1)),
        ("floor", floor_scene),
        ("overlapping", overlapping(&mut rng)),
        ("fan", fan([0.0, 0.0, -2.0], 1.5, 300)),
        ("torus 20K", torus([0.0, 0.0, 0.0], 1.2, 0.45, 128, 80)),
    ]
}

#[test]
fn the_triangle_seen_barycentrics_and_distance_match_an_independent_ray_caster() {
    let views: &[(&str, &str, u32, u32)] = &[
        ("sphere", "eye=0.3,0.8,3.2 target=0,0,0 fov=45", 64, 48),
        ("sphere", "eye=-1,0.6,-1.3 target=0.2,0,0 fov=100", 37, 53),
        ("sphere", "eye=0,0.2,9 target=0.1,0,0 fov=8", 50, 50),
        // The floor runs under and behind the eye (crossing the camera plane).
        ("floor", "eye=0.3,1.5,2 target=0,0.6,-3 fov=60", 80, 45),
        ("floor", "eye=0,0.4,0 target=1,0.1,-1 fov=150", 61, 41),
        ("floor", "eye=0,2,3 target=0,0,-1 fov=30", 33, 65),
        ("overlapping", "eye=0,0,3 target=0,0,-4 fov=70", 64, 48),
        ("overlapping", "eye=4,1,2 target=0,0,-4 fov=40", 45, 45),
        ("fan", "eye=0.1,0.2,0 target=0,0,-2 fov=75", 64, 64),
        ("fan", "eye=-3,0.5,1 target=0,0,-2 fov=25", 71, 40),
        ("torus 20K", "eye=0.5,2.2,3 target=0,0,0 fov=50", 96, 72),
        ("torus 20K", "eye=2,0.3,0 target=-1,0,-1 fov=120", 80, 60),
    ];
    let scenes = scenes();
    let (mut pixels, mut near_edge, mut differ) = (0, 0, 0);
    for (name, spec, w, h) in views {
        let mesh = &scenes.iter().find(|s| s.0 == *name).expect("scene").1;
        let (_, a) = compare(mesh, &camera(spec), *w, *h);
        eprintln!(
            "{name:12} {w:3}x{h:<3} {spec:40} {} tris: {a:?}",
            mesh.triangles.len()
        );
        assert!(
            a.covered > a.pixels / 10,
            "{name} {spec}: the view sees little"
        );
        pixels += a.pixels;
        near_edge += a.near_edge;
        differ += a.near_edge_differ;
    }
    // Pixel centres on an edge are rare in generic views; the floor seen from x = 0 with an odd
    // width puts its middle column exactly on the grid's line x = 0 (a deliberate tie).
    eprintln!(
        "{pixels} pixels; {near_edge} within {EDGE_EPS} rad of an edge, of which {differ} differ \
         from the caster"
    );
    assert!(
        near_edge * 100 <= pixels,
        "{near_edge} of {pixels} pixels near an edge"
    );
}

#[test]
fn a_closed_mesh_around_the_eye_leaves_no_pixel_empty() {
    // (mesh, an eye inside it)
    let meshes = [
        (
            sphere([0.1, 0.05, -0.1], 2.0, 40, 80, 0.05),
            [0.0, 0.0, 0.0],
        ),
        (sphere([0.0, 0.0, 0.0], 1.0, 6, 7, 0.0), [0.0, 0.0, 0.0]),
        (sphere([0.0, 0.0, 0.0], 1.0, 64, 128, 0.0), [0.1, -0.2, 0.3]),
        // Inside the tube of a torus.
        (torus([0.0, 0.0, 0.0], 1.0, 0.5, 64, 40), [1.0, 0.0, 0.0]),
    ];
    // (direction looked in, vertical fov, width, height)
    let views = [
        ([0.0, 0.0, -1.0], 60, 64, 48),
        ([0.3, 0.9, -1.0], 160, 51, 51),
        ([-1.0, -2.0, 0.3], 20, 40, 70),
        ([0.0, -0.99, 0.01], 90, 33, 33),
        ([0.0, 0.0, 1.0], 120, 90, 30),
    ];
    for (m, (mesh, eye)) in meshes.iter().enumerate() {
        for (dir, fov, w, h) in views {
            let target: [f32; 3] = std::array::from_fn(|i| eye[i] + dir[i]);
            let [a, b, c] = *eye;
            let [x, y, z] = target;
            let spec = format!("eye={a},{b},{c} target={x},{y},{z} fov={fov}");
            let cam = camera(&spec);
            let vb = rasterize(&mesh.positions, &mesh.triangles, &cam, w, h).expect("raster");
            let empty = vb.fragments.iter().filter(|f| f.is_empty()).count();
            assert_eq!(empty, 0, "mesh {m}, {spec}: {empty} empty pixels");
        }
    }
}

/// A square of 8 coplanar triangles facing the camera, its centre vertex on the centre pixel's
/// centre and its axis-aligned spokes through whole rows and columns of pixel centres, at an
/// exactly equal depth: every centre on a shared edge or the shared vertex must go to exactly
/// one triangle, so which geometric triangle a pixel sees cannot depend on the triangles'
/// order (with double coverage, equal depths would hand it to the lowest index), and none may
/// be left empty.
#[test]
fn shared_edges_through_pixel_centres_are_covered_exactly_once() {
    let spokes: [[f32; 2]; 8] = [
        [1.0, 0.0],
        [1.0, 1.0],
        [0.0, 1.0],
        [-1.0, 1.0],
        [-1.0, 0.0],
        [-1.0, -1.0],
        [0.0, -1.0],
        [1.0, -1.0],
    ];
    let mut positions = vec![[0.0, 0.0, -2.0]];
    positions.extend(spokes.iter().map(|s| [s[0], s[1], -2.0]));
    let geometric: Vec<[u32; 3]> = (0..8).map(|k| [0, 1 + k, 1 + (k + 1) % 8]).collect();
    for (w, h) in [(41, 41), (41, 31), (63, 17)] {
        let cam = camera("eye=0,0,0 target=0,0,-1 fov=60");
        let mut reference: Option<Vec<u32>> = None;
        let orders: [Vec<usize>; 4] = [
            (0..8).collect(),
            (0..8).rev().collect(),
            (0..8).map(|k| (k + 3) % 8).collect(),
            vec![5, 0, 7, 2, 4, 1, 6, 3],
        ];
        for order in orders {
            for flip in [false, true] {
                let triangles: Vec<[u32; 3]> = order
                    .iter()
                    .map(|&k| {
                        let t = geometric[k];
                        if flip && k % 2 == 0 {
                            [t[0], t[2], t[1]]
                        } else {
                            t
                        }
                    })
                    .collect();
                let vb = rasterize(&positions, &triangles, &cam, w, h).expect("raster");
                let seen: Vec<u32> = vb
                    .fragments
                    .iter()
                    .map(|f| {
                        if f.is_empty() {
                            NO_TRIANGLE
                        } else {
                            order[f.triangle as usize] as u32
                        }
                    })
                    .collect();
                // The square spans +-1 at depth 2: film offsets within +-0.5.
                let rays = ViewRays::new(&cam, w, h).expect("rays");
                for (p, s) in seen.iter().enumerate() {
                    let (x, y) = (p as u32 % w, p as u32 / w);
                    let (sx, sy) = rays.film(f64::from(x) + 0.5, f64::from(y) + 0.5);
                    if sx.abs() < 0.499 && sy.abs() < 0.499 {
                        assert_ne!(*s, NO_TRIANGLE, "{w}x{h}: pixel ({x}, {y}) is empty");
                    }
                }
                match &reference {
                    None => reference = Some(seen),
                    Some(r) => {
                        let differ = r.iter().zip(&seen).filter(|(a, b)| a != b).count();
                        assert_eq!(differ, 0, "{w}x{h}, order {order:?}, flip {flip}");
                    }
                }
            }
        }
    }
}

/// Interpolating a function linear in world space with the barycentrics reproduces it at the
/// point the pixel's ray meets the triangle's plane (computed here independently), whatever the
/// perspective: the barycentrics are perspective-correct, not affine in the image.
#[test]
fn barycentrics_interpolate_a_linear_function_exactly() {
    let mut rng = Lcg::new(3);
    let mut mesh = floor(-1.0, 30.0, 6, &mut rng);
    mesh.add(&overlapping(&mut rng));
    let f = |p: V3| 0.7 * p[0] - 1.3 * p[1] + 0.4 * p[2] + 2.0;
    for (spec, w, h) in [
        ("eye=0,0.5,2 target=0,-0.2,-3 fov=90", 64, 48),
        ("eye=-2,0,1 target=1,-0.5,-5 fov=35", 48, 64),
    ] {
        let cam = camera(spec);
        let vb = rasterize(&mesh.positions, &mesh.triangles, &cam, w, h).expect("raster");
        let eye = f64s(cam.position);
        let mut worst = 0.0f64;
        for (p, frag) in vb.fragments.iter().enumerate() {
            if frag.is_empty() {
                continue;
            }
            let [a, b, c] =
                mesh.triangles[frag.triangle as usize].map(|v| f64s(mesh.positions[v as usize]));
            let (u, v) = (f64::from(frag.bary[0]), f64::from(frag.bary[1]));
            let interp = (1.0 - u - v) * f(a) + u * f(b) + v * f(c);
            // Where the ray meets the plane: (a - eye) . n / (d . n).
            let d = oracle_dir(&cam, w, h, p as u32 % w, p as u32 / w);
            let n = cross(sub(b, a), sub(c, a));
            let t = dot(sub(a, eye), n) / dot(d, n);
            let exact = f(std::array::from_fn(|i| eye[i] + t * d[i]));
            let scale = [a, b, c].iter().map(|q| f(*q).abs()).fold(1.0, f64::max);
            worst = worst.max((interp - exact).abs() / scale);
        }
        assert!(
            worst < 1e-4,
            "{spec}: linear function off by {worst} of its scale"
        );
        eprintln!("{spec}: linear function reproduced to {worst:.2e}");
    }
}

#[test]
fn frames_are_identical_on_one_and_four_threads() {
    let mut rng = Lcg::new(11);
    let mut mesh = floor(-1.5, 20.0, 40, &mut rng);
    mesh.add(&torus([0.0, 0.0, 0.0], 1.2, 0.45, 128, 80));
    mesh.add(&overlapping(&mut rng));
    let cam = camera("eye=0.4,1.2,3.5 target=0,0,0 fov=55");
    let render = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("pool")
            .install(|| rasterize(&mesh.positions, &mesh.triangles, &cam, 123, 77).expect("raster"))
    };
    let one = render(1);
    assert!(one == render(4), "1 and 4 threads differ");
    assert!(one.fragments.iter().filter(|f| !f.is_empty()).count() > 123 * 77 / 2);
}

/// A kept rasterizer reuses its memory between frames of different meshes, cameras and sizes;
/// nothing of an earlier frame may leak into a later one.
#[test]
fn a_kept_rasterizer_renders_what_a_fresh_one_does() {
    let mut rng = Lcg::new(13);
    let mut big = floor(-1.5, 20.0, 30, &mut rng);
    big.add(&torus([0.0, 0.0, 0.0], 1.2, 0.45, 64, 40));
    let small = overlapping(&mut rng);
    let mut r = Rasterizer::new();
    let mut out = rasterize(
        &small.positions,
        &small.triangles,
        &camera("eye=0,0,3 target=0,0,-4 fov=70"),
        3,
        2,
    )
    .expect("raster");
    for (mesh, spec, w, h) in [
        (&big, "eye=0.4,1.2,3.5 target=0,0,0 fov=55", 97, 61),
        (&small, "eye=0,0,3 target=0,0,-4 fov=70", 40, 30),
        (&big, "eye=2,0.3,0 target=-1,0,-1 fov=120", 64, 64),
        (&small, "eye=4,1,2 target=0,0,-4 fov=40", 130, 20),
    ] {
        let cam = camera(spec);
        r.render(&mesh.positions, &mesh.triangles, &cam, w, h, &mut out)
            .expect("render");
        let fresh = rasterize(&mesh.positions, &mesh.triangles, &cam, w, h).expect("raster");
        assert!(out == fresh, "{spec} {w}x{h}: a kept rasterizer differs");
    }
    // A refused frame leaves the buffer as it was.
    let before = out.clone();
    let e = r.render(
        &small.positions,
        &small.triangles,
        &camera("eye=0,0,3 target=0,0,-4 fov=70"),
        0,
        5,
        &mut out,
    );
    assert!(e.is_err() && out == before);
}

#[test]
fn degenerate_and_non_finite_triangles_are_skipped() {
    let good = [[-1.0, -1.0, -3.0], [1.0, -1.0, -3.0], [0.0, 1.0, -3.0]];
    let mut positions = good.to_vec();
    positions.extend([
        [0.0, 0.0, -2.0],
        [0.5, 0.5, -2.0],
        [1.0, 1.0, -2.0],      // collinear with the two before
        [f32::NAN, 0.0, -1.0], // 6
        [f32::INFINITY, 0.0, -1.0],
        [0.0, 0.3, -1.0],
        [0.3, 0.0, -1.0],
    ]);
    let triangles = vec![
        [3, 4, 5], // zero area
        [3, 3, 4], // a repeated vertex
        [6, 8, 9], // NaN
        [7, 8, 9], // infinite
        [0, 1, 2], // the one to see
        [9, 9, 9],
    ];
    let cam = camera("eye=0,0,0 target=0,0,-1 fov=60");
    let all = rasterize(&positions, &triangles, &cam, 32, 24).expect("raster");
    let alone = rasterize(&good, &[[0, 1, 2]], &cam, 32, 24).expect("raster");
    assert!(alone.fragments.iter().any(|f| !f.is_empty()));
    for (a, b) in all.fragments.iter().zip(&alone.fragments) {
        assert_eq!(a.is_empty(), b.is_empty());
        if !a.is_empty() {
            assert_eq!((a.triangle, a.bary, a.distance), (4, b.bary, b.distance));
        }
    }
    // Nothing to draw at all.
    let none = rasterize(&[], &[], &cam, 5, 3).expect("empty mesh");
    assert!(none.fragments.iter().all(|f| f.is_empty()) && none.fragments.len() == 15);
}

#[test]
fn bad_inputs_are_refused_with_clear_errors() {
    let cam = camera("eye=0,0,3 target=0,0,0 fov=40");
    let p = [[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    let t = [[0u32, 1, 2]];
    let msg = |e: RasterError| e.to_string();
    for (w, h) in [(0, 10), (10, 0), (100_000, 10), (10, 1 << 20)] {
        let e = rasterize(&p, &t, &cam, w, h).expect_err("bad size");
        assert!(matches!(e, RasterError::ImageSize { .. }), "{e:?}");
        assert!(msg(e).contains(&format!("{w}x{h}")));
    }
    let e = rasterize(&p, &[[0, 1, 2], [2, 3, 1]], &cam, 8, 8).expect_err("bad index");
    assert_eq!(
        msg(e),
        "triangle 1 refers to vertex 3, but there are only 3 vertices"
    );
    let mut bad = cam;
    bad.position[1] = f32::NAN;
    let e = msg(rasterize(&p, &t, &bad, 8, 8).expect_err("nan eye"));
    assert!(e.contains("not finite"), "{e}");
    let mut bad = cam;
    bad.yfov = f32::INFINITY;
    assert!(msg(rasterize(&p, &t, &bad, 8, 8).expect_err("inf fov")).contains("not finite"));
    for fov in [0.0, -0.1, std::f32::consts::PI, 4.0] {
        let mut bad = cam;
        bad.yfov = fov;
        let e = msg(rasterize(&p, &t, &bad, 8, 8).expect_err("fov"));
        assert!(e.contains("(0, 180)"), "{e}");
    }
    let mut bad = cam;
    bad.up = bad.right;
    let e = msg(rasterize(&p, &t, &bad, 8, 8).expect_err("flat frame"));
    assert!(e.contains("span"), "{e}");

    let n = [[0.0f32, 0.0, 1.0]; 3];
    let e = eye_verdict(&p, &n[..2], &t, &[0], [0.0, 0.0, 2.0]).expect_err("normals");
    assert_eq!(msg(e), "vertex normals: 2 entries, expected 3");
    let e = eye_verdict(&p, &n, &t, &[], [0.0, 0.0, 2.0]).expect_err("materials");
    assert_eq!(msg(e), "triangle materials: 0 entries, expected 1");
    let e = eye_verdict(&p, &n, &t, &[0], [0.0, f32::NAN, 2.0]).expect_err("eye");
    assert!(msg(e).contains("not finite"));
    let e = eye_verdict(&p, &n, &[[0, 1, 7]], &[0], [0.0, 0.0, 2.0]).expect_err("index");
    assert!(msg(e).contains("vertex 7"));
}
