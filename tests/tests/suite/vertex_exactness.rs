//! The per-vertex mode's exactness, end to end (docs/vertex.md, section 6): a small scene is
//! baked per vertex in f32 to a file, opened with the runtime's `VertexRelighter` and relit
//! for a new environment and new material parameters; at every vertex, the runtime's
//! incident light (`vertex_incident`: irradiance E, the incident projections U, I1's SH
//! coefficients, I2) must equal an independent computation from the same traced paths and
//! the direct texels, to the rounding of f32 storage and f32 sums.
//!
//! What makes "exact" possible:
//!
//! - **T0.** The runtime's `sum_terms C0[index] value` is `integral L T0~ dw` only for a light
//!   whose Haar coefficients lie in the kept terms. The runtime takes a lat-long map and
//!   resamples it into the 6x64x64 cube (supersampled bilinear lookups, so no lat-long map
//!   gives a chosen cube exactly), and in the area-weighted Haar basis even a constant light
//!   has detail coefficients; so instead the bake keeps *every* term (`t0_terms` = 6 x 64 x 64):
//!   then every environment lies in the kept terms and, by Parseval in the solid-angle metric,
//!   the sparse dot equals the texel sum `sum_t L_t T0~_t dOmega_t`. The texel sum here traces
//!   its own shadow rays and evaluates the shading basis' `U^i` rows in the frame of
//!   `prt_formats::vertex::vertex_frame`, so it checks the Haar transform, the kept indices,
//!   the storage and the runtime's dot (and the rows' frame).
//! - **T1 and T2.** The runtime contracts T1 with C1, the environment's box projection on the
//!   6x8x8 bins (the solid-angle mean over each bin), and with the slot coefficients. The
//!   independent sum takes every escaping path from `VertexTracer::record_paths` and adds, per
//!   slot k of its first hit y (global slot j), `(2 pi / N1) Y_s(w1_local) f_k w2_weight / N2
//!   c_j C1[l(w2)]` to I1_s, with `w1_local` recomputed from `w1_world` in the runtime's
//!   vertex frame, `l(w2)` the bin of w2 and C1 the bin means computed here from the cube's
//!   texels and exact solid angles; T2 paths likewise with the 6x2x2 bins of w3. This holds
//!   for any sampling of w2 (BRDF draws, light-bin draws, any MIS weights): whatever the
//!   bake's density, `w2_weight` is what the path adds.
//! - **The constants.** E adds `sum_s Ehat[s] I1_s + pi I2` (Ehat in closed form); U adds
//!   `sum_s Cwi[s][c] I1_s + Cconst[c] I2`, with Cwi and Cconst integrated here on panels cut
//!   at the shading basis' grid nodes (where its bilinear rows have kinks) with 6-point
//!   Gauss-Legendre both ways, a different rule from the runtime's.

use std::f64::consts::{PI, TAU};

use glam::Vec3;
use prt_bake::accel::Accel;
use prt_bake::basis::shading::default_shading_basis;
use prt_bake::brdf::{BrdfParams, Family};
use prt_bake::integrator::Integrator;
use prt_bake::lights::LightSet;
use prt_bake::pixel::SlotPlan;
use prt_bake::scene::{Environment, Scene};
use prt_bake::testing::SceneBuilder;
use prt_bake::vertex::{
    bake_vertex_with, prepare_scene, VertexBakeOptions, VertexPlan, VertexTracer, T0_TEXELS,
};
use prt_formats::basis::{ShadingBasis, MAX_SHADING_RANK};
use prt_formats::lighting::cubemap::{
    direction_to_texel, texel_at, texel_centre_direction, texel_index, texel_solid_angle,
};
use prt_formats::lighting::quadrature::gauss_legendre;
use prt_formats::lighting::sh::{sh_eval, SH_COUNT};
use prt_formats::lighting::CubeMap;
use prt_formats::pixel::Precision;
use prt_formats::vertex::{vertex_frame, DIRECT_CUBE, T1_LIGHT_CUBE, T2_LIGHT_CUBE};
use prt_runtime::VertexRelighter;
use prt_tests::{small_basis, temp_path};

/// N1: first directions per vertex.
const N1: u32 = 96;
/// N2: directions per first hit.
const N2: u32 = 4;
/// The environment's rotation about +Y, degrees.
const ROTATION_DEG: f32 = 30.0;

/// Allowed difference, as a fraction of the sum of the magnitudes of the terms that make up
/// each value (the scale of its rounding error, which holds for values that cancel to near
/// zero, as SH coefficients do), for values with a T0 part (E, U). The runtime sums a row's
/// 6 x 64 x 64 terms (every term kept) in f32, each the f32 product of an f32-stored Haar value
/// and an f32 Haar coefficient of the light (each a chain of f32 roundings over 7 levels):
/// rounding errors of 2^-24 = 6e-8 over 24 576 terms add up, as a random walk, to about
/// sqrt(24 576) x 6e-8 = 1e-5 of the scale. Measured at most 2.8e-5 (U; E 1.7e-5).
const TOLERANCE_T0: f64 = 1e-4;
/// The same for I1 and I2: sums over 384 (or 24) light bins and the slots, in f32. Measured at
/// most 1.3e-6. The bugs the test was run against (the commit message lists them) made
/// differences of 0.1 or more of the scale in the first value they reached, except E without
/// its `pi I2` term: 5.9e-4, six times [`TOLERANCE_T0`].
const TOLERANCE_T1: f64 = 1e-5;

/// The edits of both editable materials the relit scene is checked under.
pub(crate) const EDITS: [&str; 4] = [
    "floor.kd=0.3,0.5,0.7",
    "ball.kd=0.2,0.1,0.05",
    "ball.ks=0.9,0.6,0.3",
    "ball.alpha=0.25",
];

/// A diffuse floor (6 x 6 grid, editable), an editable GGX ball above it (42 vertices) and a
/// fixed glossy GGX back wall, so that every group sees the others: T1 and T2 have blocks of
/// a diffuse slot, PCA basis slots and a fixed material's slot.
pub(crate) fn scene() -> Scene {
    let mut b = SceneBuilder::new();
    let floor = b.material(
        "floor",
        BrdfParams::diffuse(Vec3::new(0.6, 0.5, 0.4)),
        Vec3::ZERO,
        true,
    );
    let ball = b.material(
        "ball",
        BrdfParams {
            family: Family::Ggx,
            kd: Vec3::splat(0.2),
            ks: Vec3::splat(0.5),
            param: 0.3,
        },
        Vec3::ZERO,
        true,
    );
    let wall = b.material(
        "wall",
        BrdfParams {
            family: Family::Ggx,
            kd: Vec3::new(0.1, 0.3, 0.5),
            ks: Vec3::splat(0.3),
            param: 0.2,
        },
        Vec3::ZERO,
        false,
    );
    // Floor: y = 0, facing +Y, [-1.2, 1.2]^2.
    let n = 6usize;
    let at = |k: usize| -1.2 + 2.4 * k as f32 / (n - 1) as f32;
    let mut positions = Vec::new();
    for j in 0..n {
        for i in 0..n {
            positions.push(Vec3::new(at(i), 0.0, at(j)));
        }
    }
    let mut triangles = Vec::new();
    for j in 0..n - 1 {
        for i in 0..n - 1 {
            let v = |i: usize, j: usize| (j * n + i) as u32;
            for t in [
                [v(i, j), v(i, j + 1), v(i + 1, j)],
                [v(i + 1, j), v(i, j + 1), v(i + 1, j + 1)],
            ] {
                let p = t.map(|k| positions[k as usize]);
                let up = (p[1] - p[0]).cross(p[2] - p[0]).y > 0.0;
                triangles.push(if up { t } else { [t[0], t[2], t[1]] });
            }
        }
    }
    b.mesh(
        &positions,
        &vec![Vec3::Y; positions.len()],
        &triangles,
        floor,
    );
    b.sphere(Vec3::new(0.1, 0.45, 0.05), 0.4, 1, ball);
    b.quad(
        [
            Vec3::new(-1.2, 0.0, -1.0),
            Vec3::new(1.2, 0.0, -1.0),
            Vec3::new(1.2, 1.5, -1.0),
            Vec3::new(-1.2, 1.5, -1.0),
        ],
        wall,
    );
    b.environment(Environment::Constant(Vec3::ONE));
    b.build()
}

/// A lat-long map that is neither constant nor symmetric: a gradient, a band and a bright,
/// coloured spot, so that bins, faces and channels all differ.
pub(crate) fn environment() -> (usize, usize, Vec<[f32; 3]>) {
    let (w, h) = (128usize, 64usize);
    let texels = (0..w * h)
        .map(|k| {
            let (x, y) = ((k % w) as f32 / w as f32, (k / w) as f32 / h as f32);
            let base = 0.5 + 0.8 * x + 0.6 * (1.0 - y) + 0.3 * (9.0 * x + 2.0 * y).sin();
            let spot = if (0.6..0.7).contains(&x) && (0.25..0.35).contains(&y) {
                20.0
            } else {
                0.0
            };
            [
                base + spot,
                0.8 * base + 0.3 * spot,
                1.2 * base + 0.1 * spot,
            ]
        })
        .collect();
    (w, h, texels)
}

/// `Ehat[s] = integral_H Y_s(w) w.z dw` in closed form (only m = 0 terms are nonzero).
fn ehat(s: usize) -> f64 {
    match s {
        0 => PI.sqrt() / 2.0,
        2 => (PI / 3.0).sqrt(),
        6 => (5.0 * PI).sqrt() / 8.0,
        _ => 0.0,
    }
}

/// `Cwi[s][c] = integral_H Y_s U^i(w, c) w.z dw` (`[16][r]`) and `Cconst[c] = integral_H
/// U^i(w, c) w.z dw`: panels with edges at the basis grid's node rings and columns (and at
/// the pole, the horizon and the seam), each cut in 2 x 2, 6-point Gauss-Legendre in z and
/// in phi.
fn shading_constants(b: &ShadingBasis) -> (Vec<f64>, Vec<f64>) {
    let r = b.ranks.i;
    let mut zs: Vec<f64> = (0..b.dirs.n_theta).map(|j| b.dirs.z(j)).collect();
    zs.extend([0.0, 1.0]);
    zs.sort_by(f64::total_cmp);
    let mut phis: Vec<f64> = (0..b.dirs.n_phi).map(|k| b.dirs.phi(k)).collect();
    phis.extend([0.0, TAU]);
    phis.sort_by(f64::total_cmp);
    let split = |edges: &[f64]| -> Vec<(f64, f64)> {
        edges
            .windows(2)
            .flat_map(|e| {
                let m = 0.5 * (e[0] + e[1]);
                [(e[0], m), (m, e[1])]
            })
            .collect()
    };
    let (x, wx) = gauss_legendre(6);
    let nodes = |(a, b): (f64, f64)| -> Vec<(f64, f64)> {
        x.iter()
            .zip(&wx)
            .map(|(x, w)| (0.5 * (a + b) + 0.5 * (b - a) * x, 0.5 * (b - a) * w))
            .collect()
    };
    let mut cwi = vec![0.0f64; SH_COUNT * r];
    let mut cconst = vec![0.0f64; r];
    let mut u = [0.0f32; MAX_SHADING_RANK];
    let phi_nodes: Vec<(f64, f64)> = split(&phis).into_iter().flat_map(nodes).collect();
    for zp in split(&zs) {
        for (z, wz) in nodes(zp) {
            let s = (1.0 - z * z).max(0.0).sqrt();
            for &(phi, wp) in &phi_nodes {
                let w = [s * phi.cos(), s * phi.sin(), z];
                b.u_i_row(w.map(|c| c as f32), &mut u);
                let y = sh_eval(w);
                let cos_dw = z * wz * wp;
                for c in 0..r {
                    let uc = u[c] as f64 * cos_dw;
                    cconst[c] += uc;
                    for (sh, ys) in y.iter().enumerate() {
                        cwi[sh * r + c] += ys * uc;
                    }
                }
            }
        }
    }
    (cwi, cconst)
}

/// The solid-angle mean of `cube` (6 x 64 x 64) over each texel of the cube of side `size`,
/// from the fine texels and their exact solid angles.
fn bin_means(cube: &CubeMap, size: usize) -> Vec<[f64; 3]> {
    let fine = cube.size();
    let k = fine / size;
    (0..6 * size * size)
        .map(|l| {
            let (face, bi, bj) = texel_at(size, l).expect("bin index");
            let mut acc = [0.0f64; 4];
            for j in bj * k..(bj + 1) * k {
                for i in bi * k..(bi + 1) * k {
                    let omega = texel_solid_angle(fine, i, j);
                    let v = cube.texels()[texel_index(fine, face, i, j)];
                    for ch in 0..3 {
                        acc[ch] += omega * v[ch] as f64;
                    }
                    acc[3] += omega;
                }
            }
            [acc[0] / acc[3], acc[1] / acc[3], acc[2] / acc[3]]
        })
        .collect()
}

/// The bin of world direction `d` on the cube of side `size`.
fn bin(size: usize, d: Vec3) -> usize {
    let (face, i, j) = direction_to_texel(size, d.as_dvec3().to_array());
    texel_index(size, face, i, j)
}

/// A value computed here: per channel, the sum and the sum of the magnitudes of its terms.
#[derive(Clone, Copy, Default)]
struct Sum {
    value: [f64; 3],
    scale: [f64; 3],
}

impl Sum {
    fn add(&mut self, ch: usize, x: f64) {
        self.value[ch] += x;
        self.scale[ch] += x.abs();
    }

    /// `self + a x` with `a` a constant.
    fn add_scaled(&mut self, a: f64, x: &Sum) {
        for ch in 0..3 {
            self.value[ch] += a * x.value[ch];
            self.scale[ch] += a.abs() * x.scale[ch];
        }
    }
}

#[test]
fn relit_incident_light_equals_an_independent_projection_of_the_traced_paths() {
    // Welded and ordered by unit, as every per-vertex bake is: the tracer below sees the same
    // vertices as the file.
    let prepared = prepare_scene(&scene());
    let scene = prepared.scene;
    let bases = vec![small_basis(Family::Ggx, 4)];
    let shading = vec![default_shading_basis(Family::Ggx).expect("GGX shading basis")];
    let opts = VertexBakeOptions {
        samples: N1,
        secondary: N2,
        reflections: 3,
        // Every Haar term: every environment lies in the kept terms (module documentation).
        t0_terms: T0_TEXELS,
        precision: Precision::F32,
        ..Default::default()
    };
    let counts: Vec<_> = bases.iter().map(|b| (b.family, b.num_bases)).collect();
    let slots = SlotPlan::per_unit_radiance(&scene, &counts).expect("slot plan");
    let accel = Accel::build(&scene);
    let lights = LightSet::new(&scene);
    let integ = Integrator::new(&scene, &accel, &lights, opts.reflections as usize, 1, 1);
    let plan = VertexPlan::new(&integ, slots, &opts, prepared.units, None).expect("vertex plan");
    let path = temp_path("exactness-vertex.prt");
    bake_vertex_with(&integ, &plan, &bases, &shading, &opts, &path, None).expect("the vertex bake");
    // The same plan, layout and options as the bake: the same paths.
    let layout = plan.layout(&bases).expect("layout");
    let tracer = VertexTracer::new(&integ, &plan, &layout, &shading, &opts).expect("vertex tracer");

    // The runtime: a new environment, turned, and new parameters of both editable materials.
    let mut r = VertexRelighter::open(&path).expect("open the vertex bake");
    let (w, h, texels) = environment();
    r.set_environment_texels(w, h, texels.as_flattened())
        .expect("environment");
    r.set_environment_rotation(ROTATION_DEG).expect("rotation");
    for e in EDITS {
        prt_tests::edit_vertex(&mut r, e).expect("edit applies");
    }
    let (coeff, clamped) = r.coefficients();
    assert!(!clamped, "a parameter lies outside its basis' range");
    let meta = r.meta().clone();
    assert_eq!(meta.t0_terms as usize, T0_TEXELS);

    // The environment as the per-vertex mode defines it: the map resampled (turned) into the
    // 6x64x64 cube, the shared definition the runtime lights with; its bin means computed here.
    let cube =
        CubeMap::from_latlong(&texels, w, h, DIRECT_CUBE, ROTATION_DEG as f64).expect("cube map");
    let c1 = bin_means(&cube, T1_LIGHT_CUBE);
    let c2 = bin_means(&cube, T2_LIGHT_CUBE);
    let direct: Vec<(Vec3, f64)> = (0..T0_TEXELS)
        .map(|t| {
            let (face, i, j) = texel_at(DIRECT_CUBE, t).expect("texel");
            let d = texel_centre_direction(DIRECT_CUBE, face, i, j).map(|x| x as f32);
            (Vec3::from_array(d), texel_solid_angle(DIRECT_CUBE, i, j))
        })
        .collect();
    let basis = &shading[0];
    let (cwi, cconst) = shading_constants(basis);
    let ri = basis.ranks.i;
    let is_t2_slot: Vec<bool> = (0..coeff.len() as u32)
        .map(|j| meta.t2_slots.contains(&j))
        .collect();
    let (n1, n2) = (N1 as f64, N2 as f64);

    let mut worst = [0.0f64; 4];
    // Per vertex, T0's texel sums (the U rows, then E): the direct light alone, checked below.
    let mut direct_sums: Vec<Vec<Sum>> = Vec::new();
    // Per group: vertices whose I1, I2 were nonzero (so no group passes vacuously).
    let mut lit = vec![[0usize; 2]; meta.groups.len()];
    for v in 0..scene.positions.len() {
        let got = r
            .vertex_incident(v)
            .expect("vertex incident light")
            .expect("every vertex is in a group");
        let g = tracer.group_of(v as u32).expect("group");
        assert_eq!(got.group, g, "vertex {v}");
        let lobe = tracer.group_shading(g).is_some();
        let rows = if lobe { ri + 1 } else { 1 };
        let p = scene.positions[v];
        let n = plan.normals[v];
        let (t, b) = vertex_frame(n.to_array());
        let (t, b) = (Vec3::from_array(t), Vec3::from_array(b));

        // T0: the texel sum, with its own shadow rays and U^i rows in the vertex frame.
        let origin = p + n * integ.eps();
        let light = cube.texels();
        let mut t0 = vec![Sum::default(); rows];
        let mut u = [0.0f32; MAX_SHADING_RANK];
        for (k, &(d, omega)) in direct.iter().enumerate() {
            let cos = d.dot(n);
            if cos <= 0.0 || accel.occluded(origin, d, 0.0, f32::INFINITY) {
                continue;
            }
            if lobe {
                basis.u_i_row([d.dot(t), d.dot(b), cos], &mut u);
            }
            for (row, sum) in t0.iter_mut().enumerate() {
                let f = if row < rows - 1 { u[row] * cos } else { cos };
                for (ch, &l) in light[k].iter().enumerate() {
                    sum.add(ch, l as f64 * f as f64 * omega);
                }
            }
        }

        direct_sums.push(t0.clone());

        // T1 and T2: every escaping path, projected here.
        let mut i1 = [Sum::default(); SH_COUNT];
        let mut i2 = Sum::default();
        let offset = |m: u32| meta.materials[m as usize].slot_offset as usize;
        for path in tracer.record_paths(v as u32).expect("paths") {
            let w1 = path.w1_world;
            let local = Vec3::new(w1.dot(t), w1.dot(b), w1.dot(n));
            assert!(
                (local - path.w1_local).abs().max_element() < 1e-5,
                "vertex {v}: w1 {w1:?} is {:?} in the vertex frame, the bake says {:?}",
                local,
                path.w1_local
            );
            let first = TAU / n1 * path.w2_weight as f64 / n2;
            let y_off = offset(path.y_material);
            match &path.second {
                None => {
                    let sh = sh_eval(local.as_dvec3().to_array());
                    let l = bin(T1_LIGHT_CUBE, path.w2_world);
                    for (k, f) in path.y_slots.iter().enumerate() {
                        let c = coeff[y_off + k];
                        for ch in 0..3 {
                            let x = first * f[ch] as f64 * c[ch] as f64 * c1[l][ch];
                            for (s, ys) in sh.iter().enumerate() {
                                i1[s].add(ch, x * ys);
                            }
                        }
                    }
                }
                Some(z) => {
                    let wgt = local.z as f64 / PI * first * z.w3_weight as f64;
                    let l = bin(T2_LIGHT_CUBE, z.w3_world);
                    let z_off = offset(z.z_material);
                    for (k, fy) in path.y_slots.iter().enumerate() {
                        let cy = coeff[y_off + k];
                        for (q, fz) in z.z_slots.iter().enumerate() {
                            if !is_t2_slot[z_off + q] {
                                continue;
                            }
                            let cz = coeff[z_off + q];
                            for ch in 0..3 {
                                let x = wgt
                                    * (fy[ch] as f64 * cy[ch] as f64)
                                    * (fz[ch] as f64 * cz[ch] as f64)
                                    * c2[l][ch];
                                i2.add(ch, x);
                            }
                        }
                    }
                }
            }
        }
        if i1.iter().any(|s| s.scale.iter().any(|&x| x > 0.0)) {
            lit[g][0] += 1;
        }
        if i2.scale.iter().any(|&x| x > 0.0) {
            lit[g][1] += 1;
        }

        // E and U from their parts.
        let mut e = t0[rows - 1];
        for (s, x) in i1.iter().enumerate() {
            e.add_scaled(ehat(s), x);
        }
        e.add_scaled(PI, &i2);
        let mut us = Vec::new();
        if lobe {
            for c in 0..ri {
                let mut uc = t0[c];
                for (s, x) in i1.iter().enumerate() {
                    uc.add_scaled(cwi[s * ri + c], x);
                }
                uc.add_scaled(cconst[c], &i2);
                us.push(uc);
            }
        }
        assert_eq!(got.incident.len(), us.len(), "vertex {v}: U's rank");

        let mut compare = |what: String, kind: usize, got: [f32; 3], want: &Sum| {
            let tolerance = if kind == 1 || kind == 2 {
                TOLERANCE_T1
            } else {
                TOLERANCE_T0
            };
            for (ch, &x) in got.iter().enumerate() {
                let d = (x as f64 - want.value[ch]).abs();
                let rel = if want.scale[ch] > 0.0 {
                    d / want.scale[ch]
                } else {
                    d
                };
                worst[kind] = worst[kind].max(rel);
                assert!(
                    rel <= tolerance,
                    "vertex {v} (group {g}) {what} channel {ch}: runtime {} vs independent {} \
                     (difference {d:.3e}, {rel:.2e} of the terms' magnitude {:.3e})",
                    x,
                    want.value[ch],
                    want.scale[ch]
                );
            }
        };
        // I1 and I2 first: their bounds are the tighter, and a failure there names the
        // tensor at fault.
        for (s, x) in i1.iter().enumerate() {
            compare(format!("I1[{s}]"), 1, got.one_bounce_sh[s], x);
        }
        compare("I2".into(), 2, got.two_bounce, &i2);
        compare("E".into(), 0, got.irradiance, &e);
        for (c, x) in us.iter().enumerate() {
            compare(format!("U[{c}]"), 3, got.incident[c], x);
        }
    }
    eprintln!(
        "vertex exactness: {} vertices; largest difference / terms' magnitude: E {:.2e}, I1 {:.2e}, I2 {:.2e}, U {:.2e} (bounds {TOLERANCE_T0:.0e}, {TOLERANCE_T1:.0e}, {TOLERANCE_T1:.0e}, {TOLERANCE_T0:.0e}); vertices with I1, I2 per group {lit:?}",
        scene.positions.len(),
        worst[0],
        worst[1],
        worst[2],
        worst[3]
    );
    for (g, gm) in meta.groups.iter().enumerate() {
        let name = &meta.materials[gm.material as usize].name;
        assert!(
            lit[g][0] > 0 && lit[g][1] > 0,
            "group {g} ({name}): no vertex receives one- and two-reflection light ({:?})",
            lit[g]
        );
    }

    // The budget's direct-light switch: the same vertices with I1 and I2 switched off have
    // T0's texel sums alone as E and U, and no one- or two-reflection light.
    r.set_direct_light_only(true);
    let mut worst_direct = 0.0f64;
    for (v, t0) in direct_sums.iter().enumerate() {
        let got = r
            .vertex_incident(v)
            .expect("vertex incident light")
            .expect("every vertex is in a group");
        let zero = [0.0f32; 3];
        assert!(
            got.one_bounce_sh.iter().all(|s| *s == zero) && got.two_bounce == zero,
            "vertex {v}: direct light only, yet I1 {:?}, I2 {:?}",
            got.one_bounce_sh,
            got.two_bounce
        );
        let rows = t0.len();
        let wanted = std::iter::once(("E".to_string(), got.irradiance, &t0[rows - 1])).chain(
            got.incident
                .iter()
                .zip(t0)
                .enumerate()
                .map(|(c, (&u, sum))| (format!("U[{c}]"), u, sum)),
        );
        for (what, got, want) in wanted {
            for (ch, &x) in got.iter().enumerate() {
                let d = (x as f64 - want.value[ch]).abs();
                let rel = if want.scale[ch] > 0.0 {
                    d / want.scale[ch]
                } else {
                    d
                };
                worst_direct = worst_direct.max(rel);
                assert!(
                    rel <= TOLERANCE_T0,
                    "vertex {v}, direct light only: {what} channel {ch} is {x} where T0's texel \
                     sum is {} ({rel:.2e} of its magnitude)",
                    want.value[ch]
                );
            }
        }
    }
    eprintln!(
        "vertex exactness, direct light only: largest difference / magnitude {worst_direct:.2e}"
    );
    let _ = std::fs::remove_file(&path);
}
