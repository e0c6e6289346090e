//! The light and material stages against sums written out here: T1 and T2 with one nonzero
//! light bin per coefficient contracted with a known light (C1, C2 from the runtime's
//! `LightCoefficients`, tested on its own) and known slot coefficients; T0 against the cube's
//! irradiance integral under a rotated, asymmetric environment.

use prt_formats::lighting::irradiance::irradiance_table;
use prt_formats::pixel::Precision;
use prt_formats::vertex::{cube_len, SH_TERMS, T1_LIGHT_CUBE, T2_LIGHT_CUBE};
use prt_formats::Family;
use prt_runtime::hooks::LightCoefficients;
use prt_runtime::VertexRelighter;

use crate::common::*;

const UP: [f32; 3] = [0.0, 1.0, 0.0];

/// `Ehat[s]` in closed form (only m = 0 terms are nonzero).
fn ehat(s: usize) -> f64 {
    let pi = std::f64::consts::PI;
    match s {
        0 => pi.sqrt() / 2.0,
        2 => (pi / 3.0).sqrt(),
        6 => (5.0 * pi).sqrt() / 8.0,
        _ => 0.0,
    }
}

fn bin1(v: usize, j: usize, s: usize) -> usize {
    (v * 37 + j * 11 + s * 5) % cube_len(T1_LIGHT_CUBE)
}

fn bin2(v: usize, j: usize, i: usize) -> usize {
    (v * 5 + j * 3 + i * 7) % cube_len(T2_LIGHT_CUBE)
}

/// Exactly representable in f16.
fn val(a: usize, b: usize, c: usize, ch: usize) -> f32 {
    (0.25 + 0.125 * ((a + 2 * b + c) % 5) as f32) * [1.0, 0.5, 0.75][ch]
}

#[test]
fn one_nonzero_bin_gives_i1_and_i2_exactly() {
    let (mw, mh) = (64, 32);
    let map = asymmetric_map(mw, mh);
    let rotation = 30.0f32;
    // Each case dense, then through the compressed path (identity factors: the same tensors).
    for (precision, channels, reflections, compressed) in [
        (Precision::F32, 1usize, 3u32, false),
        (Precision::F16, 3, 3, false),
        (Precision::F32, 3, 2, false),
        (Precision::F16, 1, 2, false),
        (Precision::F32, 1, 3, true),
        (Precision::F16, 3, 3, true),
        (Precision::F32, 3, 2, true),
        (Precision::F16, 1, 2, true),
    ] {
        let mesh = Mesh::quad(UP, 0);
        let rows: Vec<_> = (0..4).map(|_| t0_rows(UP, None)).collect();
        let (nj, ni) = (4usize, 2usize);
        let mut g = Group::new(vec![0, 1, 2, 3], &rows, nj, ni, channels);
        // Vertex 3 stores its irradiance row as the occluded part (zero: nothing occludes
        // the quad) with its open flag: its E is the open sky's table at its normal.
        g.t0_open[3] = 1;
        let (nrows, nterms) = (g.t0_shape[1], g.t0_shape[2]);
        let at = (3 * nrows + nrows - 1) * nterms;
        g.t0_value[at..at + nterms].fill(0.0);
        for v in 0..4 {
            for j in 0..nj {
                for s in 0..SH_TERMS {
                    for ch in 0..channels {
                        let l = bin1(v, j, s);
                        g.t1[(((v * 384 + l) * nj + j) * SH_TERMS + s) * channels + ch] =
                            val(v, j, s, ch);
                    }
                }
                for i in 0..ni {
                    for ch in 0..channels {
                        let l = bin2(v, j, i);
                        g.t2[(((v * 24 + l) * nj + j) * ni + i) * channels + ch] = val(v, i, j, ch);
                    }
                }
            }
        }
        let materials = vec![
            material("floor", Family::Diffuse, [0.5, 0.6, 0.7], [0.0; 3], 0.0),
            material("red", Family::Diffuse, [0.9, 0.1, 0.2], [0.0; 3], 0.0),
            material("shiny", Family::Ggx, [0.1, 0.2, 0.3], [0.7, 0.8, 0.9], 0.2),
        ];
        let mut bake = Bake::new(mesh, materials, vec![(0, g, None)], Vec::new(), [1.0; 3]);
        bake.meta.precision = precision;
        bake.meta.reflections = reflections;
        bake.meta.groups[0].scale_t1 = 0.5;
        bake.meta.groups[0].scale_t2 = 0.25;
        bake.meta.groups[0].scale_t0 = 2.0;
        // T0 stored halved: the scale restores it (f16 rounding of T0 is not under test).
        if precision == Precision::F32 {
            for x in bake.groups[0].t0_value.iter_mut() {
                *x *= 0.5;
            }
        } else {
            bake.meta.groups[0].scale_t0 = 1.0;
        }
        bake.set_latlong(mw, mh, map.clone(), rotation);
        bake.compress_as_identity = compressed;
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("v.prtbake");
        bake.write(&path);
        let mut r = VertexRelighter::open(&path).expect("open");

        // The light, independently of the runtime's stages.
        let texels: Vec<[f32; 3]> = map.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
        let ll = prt_formats::envmap::LatLongMap::new(mw, mh, texels, 1.0)
            .expect("map")
            .0;
        let light = LightCoefficients::from_latlong(&ll, rotation as f64, &[]).expect("light");
        let c1 = light.one_bounce.texels();
        let c2 = light.two_bounce.texels();
        let (coeff, _) = r.coefficients();
        assert_eq!(coeff.len(), 4);
        // Irradiance from T0: the midpoint rule of L cos over the cube.
        let direct: Vec<f64> = (0..3)
            .map(|ch| {
                direct_texels()
                    .iter()
                    .zip(light.cube.texels())
                    .map(|((d, w), l)| d[1].max(0.0) * w * l[ch] as f64)
                    .sum()
            })
            .collect();
        let open_sky = irradiance_table(&light.cube).expect("irradiance table");
        let up = UP.map(f64::from);
        let open = open_sky.lookup_bilinear(up);
        for ch in 0..3 {
            // The table against the texel sum: within its quadrature and interpolation.
            let rel = (f64::from(open[ch]) - direct[ch]).abs() / direct[ch];
            assert!(
                rel < 5e-3,
                "open sky {} vs texel sum {}",
                open[ch],
                direct[ch]
            );
        }
        for v in 0..4 {
            let inc = r
                .vertex_incident(v)
                .expect("stages")
                .expect("vertex in a group");
            let what = format!("{precision:?} x{channels} r{reflections} c{compressed} vertex {v}");
            let ch_of = |ch: usize| if channels == 3 { ch } else { 0 };
            let mut e = [0.0f64; 3];
            for s in 0..SH_TERMS {
                for ch in 0..3 {
                    let want: f64 = (0..nj)
                        .map(|j| {
                            coeff[j][ch] as f64
                                * c1[bin1(v, j, s)][ch] as f64
                                * val(v, j, s, ch_of(ch)) as f64
                                * 0.5
                        })
                        .sum();
                    let got = inc.one_bounce_sh[s][ch] as f64;
                    assert!(
                        (got - want).abs() <= 1e-5 * want.abs().max(1e-3),
                        "{what}: I1[{s}][{ch}] = {got}, want {want}"
                    );
                    e[ch] += ehat(s) * want;
                }
            }
            for ch in 0..3 {
                let want: f64 = if reflections < 3 {
                    0.0
                } else {
                    (0..nj)
                        .flat_map(|j| (0..ni).map(move |i| (j, i)))
                        .map(|(j, i)| {
                            coeff[j][ch] as f64
                                * coeff[i][ch] as f64
                                * c2[bin2(v, j, i)][ch] as f64
                                * val(v, i, j, ch_of(ch)) as f64
                                * 0.25
                        })
                        .sum()
                };
                let got = inc.two_bounce[ch] as f64;
                assert!(
                    (got - want).abs() <= 1e-5 * want.abs().max(1e-3),
                    "{what}: I2[{ch}] = {got}, want {want}"
                );
                let t0_part = if v == 3 {
                    f64::from(open[ch])
                } else {
                    direct[ch]
                };
                e[ch] += std::f64::consts::PI * want + t0_part;
                let got = inc.irradiance[ch] as f64;
                let tol = if precision == Precision::F16 {
                    2e-3
                } else {
                    1e-4
                };
                assert!(
                    (got - e[ch]).abs() <= tol * e[ch],
                    "{what}: E[{ch}] = {got}, want {}",
                    e[ch]
                );
            }
            assert!(inc.incident.is_empty());
        }
        // Out of range: no vertex.
        assert!(r.vertex_incident(4).expect("stages").is_none());
    }
}

#[test]
fn material_edits_reweigh_the_slots_without_the_light_stage() {
    let mesh = Mesh::quad(UP, 0);
    let rows: Vec<_> = (0..4).map(|_| t0_rows(UP, None)).collect();
    let mut g = Group::new(vec![0, 1, 2, 3], &rows, 2, 0, 1);
    // Slot 1 (the wall's Kd) sends light from every bin into SH 0.
    for v in 0..4 {
        for l in 0..384 {
            g.t1[((v * 384 + l) * 2 + 1) * SH_TERMS] = 1.0;
        }
    }
    let materials = vec![
        material("floor", Family::Diffuse, [0.5; 3], [0.0; 3], 0.0),
        material("wall", Family::Diffuse, [0.2, 0.4, 0.6], [0.0; 3], 0.0),
    ];
    let bake = Bake::new(mesh, materials, vec![(0, g, None)], Vec::new(), [2.0; 3]);
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("v.prtbake");
    bake.write(&path);
    let mut r = VertexRelighter::open(&path).expect("open");
    // Constant light 2: C1 = 2 in all 384 bins.
    let i1 = r
        .vertex_incident(0)
        .expect("stages")
        .expect("vertex")
        .one_bounce_sh[0];
    for (ch, kd) in [0.2f32, 0.4, 0.6].into_iter().enumerate() {
        let want = kd * 2.0 * 384.0;
        assert!((i1[ch] - want).abs() <= 1e-3 * want, "{i1:?}");
    }
    set(&mut r, "wall.kd=1,0,0.5").expect("edit");
    let i1 = r
        .vertex_incident(0)
        .expect("stages")
        .expect("vertex")
        .one_bounce_sh[0];
    for (ch, kd) in [1.0f32, 0.0, 0.5].into_iter().enumerate() {
        let want = kd * 2.0 * 384.0;
        assert!((i1[ch] - want).abs() <= 1e-3 * want.max(1.0), "{i1:?}");
    }
}
