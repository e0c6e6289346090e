//! Tests of the per-vertex bake on scenes built in code: the Haar metric, T0 and the
//! visibility against direct texel sums, T1 against the closed form of a Lambert wall and
//! against an independent projection of the traced paths, the pre-pass's active slots,
//! determinism across thread counts, the refusals, the file.
#![allow(clippy::needless_range_loop)]

use std::f64::consts::PI;
use std::sync::Mutex;

use glam::{Mat3, Vec3};
use prt_formats::basis::{HemiGrid, ShadingBasis, TuckerRanks};
use prt_formats::lighting::cubemap::{
    direction_to_texel, texel_at, texel_centre_direction, texel_index, texel_solid_angle, Face,
};
use prt_formats::lighting::sh::sh_eval;
use prt_formats::lighting::HaarCube;
use prt_formats::pixel::Precision;
use prt_formats::vertex::{
    cube_len, names, vertex_frame, VertexBakeMeta, DIRECT_CUBE, SH_TERMS, T1_LIGHT_CUBE,
    T2_LIGHT_CUBE, VISIBILITY_CUBE,
};
use prt_formats::BakeFile;

use super::*;
use crate::brdf::{BrdfParams, Family};
use crate::progress::Progress;
use crate::sampling::Rng;
use crate::scene::{Environment, PunctualLight};
use crate::testing::SceneBuilder;

fn lambert(kd: f32) -> BrdfParams {
    BrdfParams::diffuse(Vec3::splat(kd))
}

/// A 40 x 40 Lambert floor at y = 0 facing +Y, under unit constant radiance.
fn open_plane() -> Scene {
    let mut b = SceneBuilder::new();
    let m = b.material("floor", lambert(0.5), Vec3::ZERO, true);
    let s = 20.0;
    b.quad(
        [
            Vec3::new(-s, 0.0, s),
            Vec3::new(s, 0.0, s),
            Vec3::new(s, 0.0, -s),
            Vec3::new(-s, 0.0, -s),
        ],
        m,
    );
    b.environment(Environment::Constant(Vec3::ONE));
    b.build()
}

/// A 3 x 3 Lambert floor with a Lambert sphere of radius 0.5 above it (centre at y = 0.7,
/// subdivided once: 42 vertices), both editable, under unit constant radiance.
fn floor_and_ball() -> Scene {
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
    b.sphere(Vec3::new(0.0, 0.7, 0.0), 0.5, 1, ball);
    b.environment(Environment::Constant(Vec3::ONE));
    b.build()
}

/// The wall scene of the T1 closed form, turned so that no direction is along an axis: a
/// small patch (0.02 across, material `patch`) at the origin facing `n`, and a square Lambert
/// wall (material `wall`, 2a x 2a, facing the patch) at distance `d` along `n`.
fn patch_facing_wall(a: f32, d: f32, kd: f32) -> (Scene, Vec3) {
    let rot = Mat3::from_axis_angle(Vec3::new(1.0, 2.0, 3.0).normalize(), 0.7);
    let (u, v, n) = (rot * Vec3::X, rot * Vec3::Y, rot * Vec3::Z);
    let mut b = SceneBuilder::new();
    let patch = b.material("patch", lambert(0.5), Vec3::ZERO, true);
    let wall = b.material("wall", lambert(kd), Vec3::ZERO, true);
    let e = 0.01;
    b.quad(
        [-u * e - v * e, u * e - v * e, u * e + v * e, -u * e + v * e],
        patch,
    );
    let c = n * d;
    // Counter-clockwise seen from the patch: the wall faces -n.
    b.quad(
        [
            c - u * a - v * a,
            c - u * a + v * a,
            c + u * a + v * a,
            c + u * a - v * a,
        ],
        wall,
    );
    b.environment(Environment::Constant(Vec3::ONE));
    (b.build(), n)
}

/// A tiny GGX shading basis (24 directions, ranks 2 x 3 x 3): cheap to build, enough to
/// exercise the U^i rows.
fn tiny_ggx_shading() -> ShadingBasis {
    let spec = crate::basis::FamilySpec::default_for(Family::Ggx).unwrap();
    let grid = HemiGrid {
        n_theta: 3,
        n_phi: 8,
    };
    crate::basis::shading::shading_basis(spec, 3, grid, TuckerRanks { h: 2, o: 3, i: 3 }).unwrap()
}

/// Runs `f` with a tracer of `scene`'s plan (no PCA bases: editable materials are diffuse or
/// the scene has none editable and glossy).
fn with_tracer<R>(
    scene: &Scene,
    shading: &[ShadingBasis],
    opts: &VertexBakeOptions,
    f: impl FnOnce(&VertexTracer, &VertexPlan, &Integrator) -> R,
) -> R {
    let slots = SlotPlan::per_unit_radiance(scene, &[]).unwrap();
    let accel = Accel::build(scene);
    let lights = LightSet::new(scene);
    let integ = Integrator::new(scene, &accel, &lights, opts.reflections as usize, 1, 1);
    let plan = VertexPlan::new(&integ, slots, opts, None).unwrap();
    let layout = plan.layout(&[]).unwrap();
    let tracer = VertexTracer::new(&integ, &plan, &layout, shading, opts).unwrap();
    f(&tracer, &plan, &integ)
}

/// Texel directions (f32, as traced) and exact solid angles of the direct cube.
fn direct_texels() -> Vec<(Vec3, f64)> {
    (0..T0_TEXELS)
        .map(|t| {
            let (face, i, j) = texel_at(DIRECT_CUBE, t).unwrap();
            let d = texel_centre_direction(DIRECT_CUBE, face, i, j).map(|x| x as f32);
            (Vec3::from_array(d), texel_solid_angle(DIRECT_CUBE, i, j))
        })
        .collect()
}

/// `sum_terms C0[index] value` of row `row` of a vertex's stored T0 terms.
fn sparse_dot(index: &[u16], value: &[f32], terms: usize, row: usize, c0: &[f32]) -> f64 {
    let r = row * terms..(row + 1) * terms;
    index[r.clone()]
        .iter()
        .zip(&value[r])
        .map(|(&i, &v)| c0[i as usize] as f64 * v as f64)
        .sum()
}

#[test]
fn haar_is_orthonormal_in_the_solid_angle_metric() {
    let haar = HaarCube::new(DIRECT_CUBE).unwrap();
    let texels = direct_texels();
    let mut rng = Rng::for_sample(7, 0, 0);
    let a: Vec<f64> = (0..T0_TEXELS).map(|_| rng.next_f64() - 0.3).collect();
    let b: Vec<f64> = (0..T0_TEXELS).map(|_| rng.next_f64() * 2.0).collect();
    let (ha, hb) = (haar.forward_f64(&a).unwrap(), haar.forward_f64(&b).unwrap());
    let coeff_dot: f64 = ha.iter().zip(&hb).map(|(x, y)| x * y).sum();
    let texel_dot: f64 = (0..T0_TEXELS).map(|t| a[t] * b[t] * texels[t].1).sum();
    assert!(
        (coeff_dot - texel_dot).abs() <= 1e-12 * texel_dot.abs(),
        "{coeff_dot} vs {texel_dot}"
    );
    // The plain sum (no solid angles) differs by far more than rounding: the weighting matters.
    let plain: f64 = (0..T0_TEXELS).map(|t| a[t] * b[t]).sum::<f64>() * 4.0 * PI / 24576.0;
    assert!((plain - texel_dot).abs() > 1e-4 * texel_dot.abs());
}

#[test]
fn t0_rows_dotted_with_a_light_equal_the_direct_texel_sum() {
    // A floor vertex under a tilted roof panel: part of its sky is occluded.
    let mut b = SceneBuilder::new();
    let floor = b.material("floor", lambert(0.5), Vec3::ZERO, true);
    let roof = b.material("roof", lambert(0.5), Vec3::ZERO, true);
    let s = 2.0;
    b.quad(
        [
            Vec3::new(-s, 0.0, s),
            Vec3::new(s, 0.0, s),
            Vec3::new(s, 0.0, -s),
            Vec3::new(-s, 0.0, -s),
        ],
        floor,
    );
    b.quad(
        [
            Vec3::new(-1.0, 0.8, 1.0),
            Vec3::new(-1.0, 1.2, -1.0),
            Vec3::new(1.0, 1.2, -1.0),
            Vec3::new(1.0, 0.8, 1.0),
        ],
        roof,
    );
    let scene = b.build();
    let opts = VertexBakeOptions {
        samples: 4,
        t0_terms: T0_TEXELS,
        ..Default::default()
    };
    let texels = direct_texels();
    // A light that is neither constant nor aligned with the faces.
    let light: Vec<f32> = texels
        .iter()
        .map(|(d, _)| 1.0 + 0.5 * d.x + 0.3 * d.y * d.y + 0.2 * (4.0 * d.z).sin())
        .collect();
    let c0 = HaarCube::new(DIRECT_CUBE).unwrap().forward(&light).unwrap();
    with_tracer(&scene, &[], &opts, |tracer, plan, integ| {
        for v in [0u32, 1, 2, 3] {
            let r = tracer.trace(v).unwrap();
            let (index, value, _, dropped) = tracer.haar_terms(&r).unwrap();
            assert_eq!(dropped, 0.0, "every term is kept");
            let got = sparse_dot(&index, &value, opts.t0_terms, 0, &c0);
            // Independently: cos (w . n)+ V from the vertex's own origin, per texel.
            let n = plan.normals[v as usize];
            let origin = scene.positions[v as usize] + n * integ.eps();
            let mut want = 0.0f64;
            let mut occluded = 0;
            for (t, (d, omega)) in texels.iter().enumerate() {
                let cos = d.dot(n);
                if cos <= 0.0 {
                    continue;
                }
                if integ.accel.occluded(origin, *d, 0.0, f32::INFINITY) {
                    occluded += 1;
                    continue;
                }
                want += cos as f64 * light[t] as f64 * omega;
            }
            assert!(
                occluded > 0 || v != 0,
                "vertex {v}: the roof occludes nothing"
            );
            assert!(
                (got - want).abs() <= 1e-5 * want,
                "vertex {v}: sparse dot {got} vs texel sum {want}"
            );
        }
    });
}

#[test]
fn unoccluded_irradiance_row_under_unit_radiance_is_pi() {
    let scene = open_plane();
    let c0 = HaarCube::new(DIRECT_CUBE)
        .unwrap()
        .forward(&vec![1.0; T0_TEXELS])
        .unwrap();
    // All terms: pi up to the cube's discretisation (the texel-centre cosine times the exact
    // texel solid angle: 8e-5 here). The default 96 terms: the truncation adds about 1.5e-3
    // (a constant light's area-weighted Haar coefficients are not only the face means, so the
    // dropped detail terms count).
    for (terms, tol) in [(T0_TEXELS, 2e-4), (96, 2e-3)] {
        let opts = VertexBakeOptions {
            samples: 4,
            t0_terms: terms,
            ..Default::default()
        };
        with_tracer(&scene, &[], &opts, |tracer, _, _| {
            let r = tracer.trace(0).unwrap();
            assert_eq!(r.t0_rows, 1);
            let (index, value, total, dropped) = tracer.haar_terms(&r).unwrap();
            let e = sparse_dot(&index, &value, terms, 0, &c0);
            assert!(
                (e - PI).abs() < tol * PI,
                "{terms} terms: irradiance {e}, expected pi"
            );
            let kept = 1.0 - (dropped / total).sqrt();
            assert!(kept > 0.9, "{terms} terms keep {kept} of the row's norm");
        });
    }
}

#[test]
fn visibility_of_a_vertex_on_an_open_plane_is_full_above_and_zero_below() {
    let scene = open_plane();
    with_tracer(
        &scene,
        &[],
        &VertexBakeOptions::default(),
        |tracer, _, _| {
            let vis = tracer.trace(2).unwrap().visibility_u8();
            assert_eq!(vis.len(), cube_len(VISIBILITY_CUBE));
            for face in Face::ALL {
                for j in 0..VISIBILITY_CUBE {
                    for i in 0..VISIBILITY_CUBE {
                        let d = texel_centre_direction(VISIBILITY_CUBE, face, i, j);
                        let want = if d[1] > 0.0 { 255 } else { 0 };
                        let got = vis[texel_index(VISIBILITY_CUBE, face, i, j)];
                        assert_eq!(got, want, "{} texel ({i}, {j}): {d:?}", face.name());
                    }
                }
            }
        },
    );
}

#[test]
fn glossy_t0_rows_are_the_shading_basis_in_the_vertex_frame() {
    let mut b = SceneBuilder::new();
    let mut ggx = lambert(0.3);
    ggx.family = Family::Ggx;
    ggx.ks = Vec3::splat(0.5);
    ggx.param = 0.3;
    let m = b.material("ball", ggx, Vec3::ZERO, false);
    b.sphere(Vec3::ZERO, 1.0, 1, m);
    let scene = b.build();
    let shading = [tiny_ggx_shading()];
    let opts = VertexBakeOptions {
        samples: 4,
        ..Default::default()
    };
    with_tracer(&scene, &shading, &opts, |tracer, plan, _| {
        let basis = &shading[0];
        for v in [0u32, 5, 17] {
            let r = tracer.trace(v).unwrap();
            assert_eq!(r.t0_rows, basis.ranks.i + 1);
            let n = plan.normals[v as usize];
            let (t, bt) = vertex_frame(n.to_array());
            let mut u = [0.0f32; 8];
            for (tex, (d, _)) in direct_texels().iter().enumerate() {
                let cos = d.dot(n);
                // A convex sphere sees the whole sky above each vertex.
                let local = [d.dot(Vec3::from_array(t)), d.dot(Vec3::from_array(bt)), cos];
                basis.u_i_row(local, &mut u);
                for k in 0..r.t0_rows {
                    let want = if cos <= 0.0 {
                        0.0
                    } else if k < basis.ranks.i {
                        u[k] * cos
                    } else {
                        cos
                    };
                    let got = r.t0[k * T0_TEXELS + tex];
                    assert!(
                        (got - want).abs() <= 1e-6,
                        "vertex {v} row {k} texel {tex}: {got} vs {want}"
                    );
                }
            }
        }
    });
    // Without the basis the bake refuses, naming the material and family.
    let e = bake_vertex(&scene, &[], &[], &opts, None)
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("'ball'") && e.contains("ggx"), "{e}");
}

/// Solid angle of a 2a x 2a square seen from a point on its axis at distance d.
fn square_solid_angle(a: f64, d: f64) -> f64 {
    4.0 * (a * a / (a * a + d * d)).asin()
}

/// Projected solid angle (integral of cos) of the same square: pi times the form factor
/// from a differential area to a parallel rectangle, four corner rectangles.
fn square_projected_solid_angle(a: f64, d: f64) -> f64 {
    let x = a / d;
    let s = (1.0 + x * x).sqrt();
    let corner = (2.0 * x / s * (x / s).atan()) / (2.0 * PI);
    PI * 4.0 * corner
}

#[test]
fn t1_of_a_vertex_facing_a_lambert_wall_has_the_closed_form() {
    let (a, d, kd) = (2.0f32, 1.0f32, 0.5f32);
    let (scene, n) = patch_facing_wall(a, d, kd);
    let opts = VertexBakeOptions {
        samples: 16384,
        secondary: 4,
        ..Default::default()
    };
    with_tracer(&scene, &[], &opts, |tracer, plan, _| {
        let v = 0u32;
        let r = tracer.trace(v).unwrap();
        let g = &plan.groups[r.group];
        // The wall's one slot (Kd, value 1/pi, coefficient Kd) is the only active one.
        assert_eq!(g.active, vec![1]);
        let bins = cube_len(T1_LIGHT_CUBE);
        let sum_bins = |s: usize| -> f64 { (0..bins).map(|l| r.t1[l * SH_TERMS + s] as f64).sum() };
        // Closed form per unit Kd (the coefficient): the wall's radiance is Kd E / pi with
        // E = pi (it sees unit sky over its front, the patch is negligible), so
        // I1_s / Kd = integral over the wall's directions of Y_s.
        let y0 = sh_eval([0.0, 0.0, 1.0])[0];
        let c1 = sh_eval([0.0, 0.0, 1.0])[2];
        let want0 = y0 * square_solid_angle(a as f64, d as f64);
        let want2 = c1 * square_projected_solid_angle(a as f64, d as f64);
        // Monte Carlo error from the per-sample contributions of the traced paths.
        let paths = tracer.record_paths(v).unwrap();
        let mut per_sample = vec![[0.0f64; 2]; opts.samples as usize];
        for p in &paths {
            let sh = sh_eval(p.w1_local.as_dvec3().to_array());
            let w = 2.0 * PI / opts.samples as f64 * p.w2_weight as f64 / opts.secondary as f64
                * p.y_slots[0].x as f64;
            per_sample[p.sample as usize][0] += w * sh[0];
            per_sample[p.sample as usize][1] += w * sh[2];
        }
        for (s, want) in [(0usize, want0), (1, want2)] {
            let xs: Vec<f64> = per_sample.iter().map(|x| x[s]).collect();
            let mean = xs.iter().sum::<f64>() / xs.len() as f64;
            let var = xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (xs.len() - 1) as f64;
            let sigma = (var * xs.len() as f64).sqrt();
            let got = sum_bins(if s == 0 { 0 } else { 2 });
            assert!(
                (got - want).abs() <= 4.0 * sigma + 1e-3 * want,
                "SH {s}: {got} vs closed form {want} (sigma {sigma})"
            );
            assert!(
                sigma < 0.02 * want,
                "sigma {sigma} too large to test {want}"
            );
        }
        // By symmetry the other band-1 coefficients vanish (within the error).
        for s in [1usize, 3] {
            assert!(sum_bins(s).abs() < 0.02 * want0, "SH {s}: {}", sum_bins(s));
        }
        // Light reaches the wall from its front only: bins well inside x's side are empty.
        for l in 0..bins {
            let (face, i, j) = texel_at(T1_LIGHT_CUBE, l).unwrap();
            let c = Vec3::from_array(
                texel_centre_direction(T1_LIGHT_CUBE, face, i, j).map(|x| x as f32),
            );
            if c.dot(n) > 0.5 {
                for s in 0..SH_TERMS {
                    assert_eq!(r.t1[l * SH_TERMS + s], 0.0, "bin {l} ({c:?}) SH {s}");
                }
            }
        }
    });
}

#[test]
fn t1_and_t2_are_the_projection_of_the_recorded_paths() {
    let scene = floor_and_ball();
    let opts = VertexBakeOptions {
        samples: 4096,
        secondary: 3,
        reflections: 3,
        seed: 11,
        ..Default::default()
    };
    with_tracer(&scene, &[], &opts, |tracer, plan, _| {
        let layout = plan.layout(&[]).unwrap();
        let mut t2_paths = 0;
        // A floor vertex (sees the ball) and a ball vertex on its underside (sees the floor).
        let low = (4..scene.positions.len() as u32)
            .min_by(|&a, &b| {
                scene.positions[a as usize]
                    .y
                    .total_cmp(&scene.positions[b as usize].y)
            })
            .unwrap();
        for v in [0u32, low] {
            let r = tracer.trace(v).unwrap();
            let g = &plan.groups[r.group];
            let (jn, i_n) = (g.active.len(), plan.t2_slots.len());
            assert!(jn > 0, "vertex {v} sees nothing");
            let mut t1 = vec![0.0f64; r.t1.len()];
            let mut t2 = vec![0.0f64; r.t2.len()];
            let (n1, n2) = (opts.samples as f64, opts.secondary as f64);
            for p in tracer.record_paths(v).unwrap() {
                let off = layout.materials[p.y_material as usize].slot_offset;
                let sh = sh_eval(p.w1_local.as_dvec3().to_array());
                for (k, val) in p.y_slots.iter().enumerate() {
                    let j = g.active.iter().position(|&s| s == off + k as u32).unwrap();
                    let f2 = p.w2_weight as f64 / n2 * val.x as f64;
                    match &p.second {
                        None => {
                            let (face, i, jj) =
                                direction_to_texel(T1_LIGHT_CUBE, p.w2_world.as_dvec3().to_array());
                            let l = texel_index(T1_LIGHT_CUBE, face, i, jj);
                            for s in 0..SH_TERMS {
                                t1[(l * jn + j) * SH_TERMS + s] += 2.0 * PI / n1 * f2 * sh[s];
                            }
                        }
                        Some(z) => {
                            t2_paths += 1;
                            let (face, i, jj) =
                                direction_to_texel(T2_LIGHT_CUBE, z.w3_world.as_dvec3().to_array());
                            let l = texel_index(T2_LIGHT_CUBE, face, i, jj);
                            let zoff = layout.materials[z.z_material as usize].slot_offset as usize;
                            for (q, vz) in z.z_slots.iter().enumerate() {
                                t2[(l * jn + j) * i_n + zoff + q] += p.w1_local.z as f64 / PI
                                    * (2.0 * PI / n1)
                                    * f2
                                    * (vz.x * z.w3_weight) as f64;
                            }
                        }
                    }
                }
            }
            for (name, got, want) in [("T1", &r.t1, &t1), ("T2", &r.t2, &t2)] {
                let max = want.iter().fold(0.0f64, |m, x| m.max(x.abs()));
                assert!(max > 0.0 || name == "T2", "vertex {v}: {name} is empty");
                for (e, (g, w)) in got.iter().zip(want.iter()).enumerate() {
                    assert!(
                        (*g as f64 - w).abs() <= 1e-5 * max,
                        "vertex {v} {name}[{e}]: {g} vs {w}"
                    );
                }
            }
        }
        assert!(t2_paths > 0);
    });
}

#[test]
fn objects_that_cannot_see_each_other_get_no_block() {
    let scene = floor_and_ball();
    let opts = VertexBakeOptions {
        samples: 256,
        ..Default::default()
    };
    with_tracer(&scene, &[], &opts, |_, plan, _| {
        // Slots: floor 0, ball 1. The floor sees the ball only, the (convex) ball the floor only.
        let active: Vec<(u32, Vec<u32>)> = plan
            .groups
            .iter()
            .map(|g| (g.material, g.active.clone()))
            .collect();
        assert_eq!(active, vec![(0, vec![1]), (1, vec![0])]);
    });
}

#[test]
fn t1_does_not_depend_on_whether_t2_is_baked() {
    let scene = floor_and_ball();
    let two = VertexBakeOptions {
        samples: 256,
        reflections: 2,
        precision: Precision::F32,
        ..Default::default()
    };
    let three = VertexBakeOptions {
        reflections: 3,
        ..two.clone()
    };
    let a = bake_vertex(&scene, &[], &[], &two, None).unwrap();
    let b = bake_vertex(&scene, &[], &[], &three, None).unwrap();
    for (ga, gb) in a.groups.iter().zip(&b.groups) {
        assert!(!ga.t1.is_empty());
        assert_eq!(ga.t1, gb.t1);
        assert!(ga.t2.is_empty() && !gb.t2.is_empty());
    }
}

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
            let bake = bake_vertex(&scene, &[], &[], &opts, None).unwrap();
            vertex_file_bytes(&bake).unwrap()
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
    let e = bake_vertex(&lit, &[], &[], &opts, None)
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
    let e = bake_vertex(&b.build(), &[], &[], &opts, None)
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("area lights (emissive materials: lamp)"), "{e}");

    for reflections in [1, 4] {
        let o = VertexBakeOptions {
            reflections,
            ..opts.clone()
        };
        let e = bake_vertex(&open_plane(), &[], &[], &o, None)
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
    let bake = bake_vertex(&scene, &[], &[], &opts, None).unwrap();
    let path = std::env::temp_dir().join(format!("prt-vertex-file-{}.prtbake", std::process::id()));
    let size = write_vertex_file(&bake, &path).unwrap();
    let file = BakeFile::open(&path).unwrap();
    std::fs::remove_file(&path).ok();
    assert_eq!(size, file.file_bytes().len() as u64);
    let meta: VertexBakeMeta = serde_json::from_value(file.metadata().clone()).unwrap();
    meta.validate().unwrap();
    assert_eq!(meta, bake.meta);
    assert_eq!((meta.vertices, meta.triangles, meta.channels), (46, 82, 1));
    assert_eq!(meta.t2_slots, vec![0, 1]);
    let shape = |name: &str| file.tensor(name).unwrap().shape().to_vec();
    assert_eq!(shape(names::POSITIONS), vec![46, 3]);
    assert_eq!(shape(names::TRIANGLES), vec![82, 3]);
    for (g, gm) in meta.groups.iter().enumerate() {
        let v = gm.vertices as usize;
        assert_eq!(shape(&names::t0_index(g)), vec![v, 1, 40]);
        assert_eq!(shape(&names::visibility(g)), vec![v, 1536]);
        assert_eq!(shape(&names::t1(g)), vec![v, 384, 1, 16, 1]);
        assert_eq!(shape(&names::t2(g)), vec![v, 24, 1, 2, 1]);
        // f16 with the group's scale: the largest stored magnitude is 2^14.
        let t1 = file.tensor(&names::t1(g)).unwrap().to_f32_vec().unwrap();
        let max = t1.iter().fold(0.0f32, |m, x| m.max(x.abs()));
        assert_eq!(max, 16384.0);
        let dense = bake.groups[g].t1.to_f32();
        assert_eq!(dense, t1);
    }
    assert!(meta.stats.rays > 0 && meta.stats.t0_truncation_error.len() == 2);
    assert!(meta
        .stats
        .t0_truncation_error
        .iter()
        .all(|e| (0.0..0.5).contains(e)));
}
