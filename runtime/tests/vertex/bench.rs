//! What each stage costs on a synthetic bake of gallery size (ignored by default: it writes a
//! file of several GB). Run with
//!
//! ```text
//! VERTEX_BENCH_VERTICES=50000 VERTEX_BENCH_FILE=/tmp/bench.prtbake \
//!     cargo test --release -p prt-runtime --test vertex bench -- --ignored --nocapture
//! ```
//!
//! A grid of `VERTEX_BENCH_VERTICES` vertices (default 50 000) facing +Y, one GGX group with
//! the thesis' ranks (4 x 8 x 8, 9 T0 rows of 96 terms), 7 active slots, 2 T2 slots, f16
//! storage, rendered at 512 x 512. With `VERTEX_BENCH_FILE` the file is kept and reused.

use std::time::Instant;

use half::f16;
use prt_formats::basis::{HemiGrid, ParamWarp, ShadingBasis, TuckerRanks, SHADING_SCHEMA_VERSION};
use prt_formats::pixel::Precision;
use prt_formats::Family;
use prt_runtime::VertexRelighter;

use crate::common::*;

fn values(n: usize, seed: f32, scale: f32) -> Vec<f32> {
    (0..n)
        .map(|k| ((k as f32 * 0.731 + seed).sin() * scale).abs())
        .collect()
}

/// A basis of the thesis' size with arbitrary (finite, nonnegative) tables.
fn thesis_sized_basis() -> ShadingBasis {
    let dirs = HemiGrid {
        n_theta: 16,
        n_phi: 64,
    };
    let nd = dirs.len();
    let np = 32;
    let ranks = TuckerRanks::THESIS;
    ShadingBasis {
        version: SHADING_SCHEMA_VERSION,
        family: Family::Ggx,
        method: "bench".into(),
        param_range: [0.05, 1.0],
        param_warp: ParamWarp::Linear,
        param_samples: (0..np)
            .map(|k| 0.05 + 0.95 * k as f32 / (np - 1) as f32)
            .collect(),
        dirs,
        ranks,
        u_h: values(np * ranks.h, 0.1, 0.3),
        u_o: values(nd * ranks.o, 0.2, 1.0),
        u_o_pole: values(ranks.o, 0.3, 1.0),
        u_i: values(nd * ranks.i, 0.4, 1.0),
        u_i_pole: values(ranks.i, 0.5, 1.0),
        core: values(ranks.h * ranks.o * ranks.i, 0.6, 0.1),
        split_widths_deg: vec![0.0, 7.0, 14.0, 21.0],
        reflectances: values(np * nd * 4, 0.7, 0.2),
        reflectances_pole: values(np * 4, 0.8, 0.2),
    }
}

fn write_bench(path: &std::path::Path, vertices: usize) {
    let side = (vertices as f64).sqrt().round().max(2.0) as usize;
    let mesh = Mesh::grid(side, [0.0, 1.0, 0.0], 0);
    let nv = mesh.positions.len();
    let (nj, ni, rows, terms) = (7usize, 2usize, 9usize, 96usize);
    let basis = thesis_sized_basis();
    let mut g = Group::new((0..nv as u32).collect(), &[], 0, ni, 1);
    let mut state = 1u64;
    let mut next = move || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 40) as u32
    };
    g.t0_shape = [nv, rows, terms];
    g.t0_index = (0..nv * rows * terms)
        .map(|_| (next() % 24576) as u16)
        .collect();
    g.t0_value = (0..nv * rows * terms)
        .map(|_| (next() % 1000) as f32 * 1e-5)
        .collect();
    g.t1_shape = [nv, 384, nj, 16, 1];
    g.t1 = Vec::new();
    g.t1_f16 = Some(
        (0..nv * 384 * nj * 16)
            .map(|_| f16::from_f32((next() % 2048) as f32 * 1e-6))
            .collect(),
    );
    g.t2_shape = [nv, 24, nj, ni, 1];
    g.t2 = (0..nv * 24 * nj * ni)
        .map(|_| (next() % 100) as f32 * 1e-5)
        .collect();
    let mut materials = vec![material(
        "metal",
        Family::Ggx,
        [0.3, 0.3, 0.3],
        [0.5; 3],
        0.3,
    )];
    for k in 0..5 {
        materials.push(material(
            &format!("wall{k}"),
            Family::Diffuse,
            [0.5; 3],
            [0.0; 3],
            0.0,
        ));
    }
    let mut bake = Bake::new(
        mesh,
        materials,
        vec![(0, g, Some(0))],
        vec![basis],
        [1.0; 3],
    );
    bake.meta.precision = Precision::F16;
    bake.meta.reflections = 3;
    bake.set_latlong(512, 256, asymmetric_map(512, 256), 0.0);
    bake.write(path);
}

#[test]
#[ignore = "writes a multi-GB file; run by hand for the stage costs"]
fn bench_stage_costs() {
    let vertices: usize = std::env::var("VERTEX_BENCH_VERTICES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(50_000);
    let dir = tempfile::tempdir().expect("temp dir");
    let path = std::env::var_os("VERTEX_BENCH_FILE")
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|| dir.path().join("bench.prtbake"));
    if !path.exists() {
        let t = Instant::now();
        write_bench(&path, vertices);
        println!(
            "wrote {} in {:.1} s",
            path.display(),
            t.elapsed().as_secs_f64()
        );
    }
    let t = Instant::now();
    let mut r = VertexRelighter::open(&path).expect("open");
    println!(
        "open (checksums, validation, constants): {:.2} s; {} vertices, {} threads",
        t.elapsed().as_secs_f64(),
        r.meta().vertices,
        rayon::current_num_threads()
    );
    let cam = camera([0.3, 1.2, 1.6], 50.0);
    let (w, h) = (512, 512);
    let mut out = vec![0.0f32; 3 * w * h];
    let mut run = |r: &mut VertexRelighter, what: &str| {
        let s = frame(r, &cam, w as u32, h as u32, &mut out).expect("render");
        println!(
            "{what:<28} light {:>8} material {:>8} view {:>8.1} ms",
            s.light_s
                .map_or("-".into(), |x| format!("{:.1} ms", x * 1e3)),
            s.material_s
                .map_or("-".into(), |x| format!("{:.1} ms", x * 1e3)),
            s.view_s.unwrap_or(0.0) * 1e3
        );
    };
    run(&mut r, "first frame (all stages)");
    run(&mut r, "view only");
    set(&mut r, "metal.kd=0.9,0.2,0.2").expect("edit");
    run(&mut r, "material edit");
    r.set_environment_rotation(45.0).expect("rotation");
    run(&mut r, "rotation (light)");
}

#[test]
#[ignore = "timing"]
fn bench_light_coefficients() {
    let texels: Vec<[f32; 3]> = asymmetric_map(512, 256)
        .chunks_exact(3)
        .map(|c| [c[0], c[1], c[2]])
        .collect();
    let map = prt_formats::envmap::LatLongMap::new(512, 256, texels, 1.0)
        .expect("map")
        .0;
    for widths in [vec![], vec![7.0], vec![14.0], vec![21.0]] {
        let t = Instant::now();
        prt_runtime::hooks::LightCoefficients::from_latlong(&map, 10.0, &widths).expect("light");
        println!("{widths:?}: {:.1} ms", t.elapsed().as_secs_f64() * 1e3);
    }
}
