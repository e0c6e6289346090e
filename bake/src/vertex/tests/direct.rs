//! T0 and the visibility: the Haar metric, rows against direct texel sums, the irradiance of
//! an open vertex, the visible fractions, the shading basis' rows in the vertex frame.
use std::f64::consts::PI;

use glam::Vec3;

use super::*;
use prt_formats::lighting::cubemap::{texel_centre_direction, texel_index, Face};
use prt_formats::lighting::irradiance::irradiance_table;
use prt_formats::lighting::{CubeMap, HaarCube, SparseVector};
use prt_formats::vertex::{cube_len, vertex_frame, DIRECT_CUBE, VISIBILITY_CUBE};

use crate::sampling::Rng;
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

/// A floor whose vertices sit under a tilted roof panel: part of their sky is occluded.
fn roofed_plane() -> Scene {
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
    b.build()
}

#[test]
fn t0_rows_dotted_with_a_light_equal_the_direct_texel_sum() {
    let scene = roofed_plane();
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
            let h = tracer.haar_terms(&r).unwrap();
            let (index, value, dropped, open) = (h.index, h.value, h.dropped, h.open);
            assert_eq!(dropped, 0.0, "every term is kept");
            assert!(
                !open,
                "vertex {v}: with every term kept the visible part is exact"
            );
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
    let sky = irradiance_table(&CubeMap::constant(DIRECT_CUBE, [1.0; 3]).unwrap()).unwrap();
    // All terms: the visible part, pi up to the cube's discretisation (the texel-centre cosine
    // times the exact texel solid angle: 8e-5 here). The default 96 terms: the visible part
    // would drop detail terms (about 1.5e-3 of pi under this constant light, 6 % of a floor
    // under small lamps), so the row is the occluded part, zero here, and the irradiance is
    // the open sky's table (within its quadrature, 2e-3).
    for (terms, tol, open_sky) in [(T0_TEXELS, 2e-4, false), (96, 2e-3, true)] {
        let opts = VertexBakeOptions {
            samples: 4,
            t0_terms: terms,
            ..Default::default()
        };
        with_tracer(&scene, &[], &opts, |tracer, plan, _| {
            let r = tracer.trace(0).unwrap();
            assert_eq!(r.t0_rows, 1);
            let h = tracer.haar_terms(&r).unwrap();
            let (index, value, dropped, open) = (h.index, h.value, h.dropped, h.open);
            assert_eq!(open, open_sky, "{terms} terms");
            let dot = sparse_dot(&index, &value, terms, 0, &c0);
            let e = if open {
                assert!(
                    value.iter().all(|&x| x == 0.0),
                    "nothing occludes the plane"
                );
                assert_eq!(dropped, 0.0);
                let n = plan.normals[0].to_array().map(f64::from);
                f64::from(sky.lookup_bilinear(n)[0]) - dot
            } else {
                dot
            };
            assert!(
                (e - PI).abs() < tol * PI,
                "{terms} terms: irradiance {e}, expected pi"
            );
        });
    }
}

#[test]
fn partly_occluded_irradiance_keeps_the_form_that_drops_less() {
    // A plane under a roof over part of its sky, lit by a sky with a small bright lamp: at
    // 96 terms each vertex's irradiance (the visible part's dot, or the open sky's table minus
    // the occluded part's) against the texel sum, and the same with the visible part forced.
    let scene = roofed_plane();
    let texels = direct_texels();
    let lamp = Vec3::new(0.35, 0.9, -0.25).normalize();
    let light: Vec<f32> = texels
        .iter()
        .map(|(d, _)| {
            if d.dot(lamp) > 0.995 {
                400.0
            } else {
                0.5 + 0.3 * d.y.max(0.0)
            }
        })
        .collect();
    let cube = CubeMap::new(DIRECT_CUBE, light.iter().map(|&l| [l; 3]).collect()).unwrap();
    let haar = HaarCube::new(DIRECT_CUBE).unwrap();
    let c0 = haar.forward(&light).unwrap();
    let sky = irradiance_table(&cube).unwrap();
    let opts = VertexBakeOptions {
        samples: 4,
        ..Default::default()
    };
    let terms = opts.t0_terms;
    with_tracer(&scene, &[], &opts, |tracer, plan, integ| {
        let (mut chosen, mut visible_only) = (0.0f64, 0.0f64);
        let mut opened = 0;
        for v in [0u32, 1, 2, 3] {
            let r = tracer.trace(v).unwrap();
            let n = plan.normals[v as usize];
            let origin = scene.positions[v as usize] + n * integ.eps();
            let want: f64 = texels
                .iter()
                .enumerate()
                .filter(|(_, (d, _))| {
                    d.dot(n) > 0.0 && !integ.accel.occluded(origin, *d, 0.0, f32::INFINITY)
                })
                .map(|(t, (d, omega))| d.dot(n) as f64 * light[t] as f64 * omega)
                .sum();
            let h = tracer.haar_terms(&r).unwrap();
            let (index, value, open) = (h.index, h.value, h.open);
            let dot = sparse_dot(&index, &value, terms, 0, &c0);
            let got = if open {
                opened += 1;
                f64::from(sky.lookup_bilinear(n.to_array().map(f64::from))[0]) - dot
            } else {
                dot
            };
            // The visible part's 96 largest terms, as every vertex stored them before.
            let row = &r.t0[(r.t0_rows - 1) * T0_TEXELS..];
            let kept = SparseVector::keep_largest(&haar.forward(row).unwrap(), terms).unwrap();
            let visible: f64 = kept
                .indices()
                .iter()
                .zip(kept.values())
                .map(|(&i, &x)| f64::from(x) * f64::from(c0[i as usize]))
                .sum();
            chosen = chosen.max((got - want).abs() / want);
            visible_only = visible_only.max((visible - want).abs() / want);
        }
        eprintln!("irradiance error at 96 terms: chosen form {chosen:.2e}, visible part only {visible_only:.2e}; {opened} of 4 vertices open");
        assert!(opened > 0, "some vertex sees most of the sky");
        assert!(
            chosen < 3e-3,
            "the chosen form is {chosen} off the texel sum"
        );
    });
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
    let e = bake_bytes(&scene, &[], &opts, "no-basis")
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("'ball'") && e.contains("ggx"), "{e}");
}
