//! Tests of the per-vertex bake on scenes built in code (this file: the scenes and helpers;
//! `direct`: the Haar metric, T0 and the visibility against direct texel sums; `transfer`: T1
//! against the closed form of a Lambert wall and against an independent projection of the
//! traced paths, the pre-pass's active slots; `run`: determinism across thread counts, the
//! refusals, the allocation report and `--max-memory`, the file; `choice`: the clusters and
//! T0 terms chosen from the error target).
#![allow(clippy::needless_range_loop)]

mod choice;
mod direct;
mod run;
mod transfer;

use glam::{Mat3, Vec3};
use prt_formats::basis::{HemiGrid, ShadingBasis, TuckerRanks};
use prt_formats::lighting::cubemap::{texel_at, texel_centre_direction, texel_solid_angle};
use prt_formats::vertex::DIRECT_CUBE;

use super::*;
use crate::brdf::{BrdfParams, Family};
use crate::scene::Environment;
use crate::testing::SceneBuilder;

pub(super) fn lambert(kd: f32) -> BrdfParams {
    BrdfParams::diffuse(Vec3::splat(kd))
}

/// A 40 x 40 Lambert floor at y = 0 facing +Y, under unit constant radiance.
pub(super) fn open_plane() -> Scene {
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
pub(super) fn floor_and_ball() -> Scene {
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
pub(super) fn patch_facing_wall(a: f32, d: f32, kd: f32) -> (Scene, Vec3) {
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
pub(super) fn tiny_ggx_shading() -> ShadingBasis {
    let spec = crate::basis::FamilySpec::default_for(Family::Ggx).unwrap();
    let grid = HemiGrid {
        n_theta: 3,
        n_phi: 8,
    };
    crate::basis::shading::shading_basis(spec, 3, grid, TuckerRanks { h: 2, o: 3, i: 3 }).unwrap()
}

/// Runs `f` with a tracer of `scene`'s plan (no PCA bases: editable materials are diffuse or
/// the scene has none editable and glossy).
pub(super) fn with_tracer<R>(
    scene: &Scene,
    shading: &[ShadingBasis],
    opts: &VertexBakeOptions,
    f: impl FnOnce(&VertexTracer, &VertexPlan, &Integrator) -> R,
) -> R {
    let slots = SlotPlan::per_unit_radiance(scene, &[]).unwrap();
    let accel = Accel::build(scene);
    let lights = LightSet::new(scene);
    let integ = Integrator::new(scene, &accel, &lights, opts.reflections as usize, 1, 1);
    let plan = VertexPlan::new(&integ, slots, opts, units_in_place(scene), None).unwrap();
    let layout = plan.layout(&[]).unwrap();
    let tracer = VertexTracer::new(&integ, &plan, &layout, shading, opts).unwrap();
    f(&tracer, &plan, &integ)
}

/// Runs `f` with a tracer of `scene`'s plan made of `units`.
pub(super) fn with_tracer_units<R>(
    scene: &Scene,
    units: Vec<Unit>,
    opts: &VertexBakeOptions,
    f: impl FnOnce(&VertexTracer, &VertexPlan) -> R,
) -> R {
    let slots = SlotPlan::per_unit_radiance(scene, &[]).unwrap();
    let accel = Accel::build(scene);
    let lights = LightSet::new(scene);
    let integ = Integrator::new(scene, &accel, &lights, opts.reflections as usize, 1, 1);
    let plan = VertexPlan::new(&integ, slots, opts, units, None).unwrap();
    let layout = plan.layout(&[]).unwrap();
    let tracer = VertexTracer::new(&integ, &plan, &layout, &[], opts).unwrap();
    f(&tracer, &plan)
}

/// Units over `scene`'s vertices as they are (not welded or reordered, so tests keep their
/// vertex indices): each group's vertices in order, cut every 256, halves and quarters by
/// index. The groups must be contiguous, as `SceneBuilder` makes them mesh by mesh.
pub(super) fn units_in_place(scene: &Scene) -> Vec<Unit> {
    let mut members: Vec<Vec<u32>> = vec![Vec::new(); scene.materials.len()];
    for (v, m) in vertex_materials(scene).iter().enumerate() {
        if let Some(m) = m {
            members[*m as usize].push(v as u32);
        }
    }
    let mut out = Vec::new();
    for (g, vs) in members.iter().filter(|m| !m.is_empty()).enumerate() {
        for chunk in vs.chunks(UNIT_VERTICES) {
            let n = chunk.len();
            let half = n / 2;
            out.push(Unit {
                group: g,
                vertices: chunk.to_vec(),
                half,
                quarters: [half / 2, half, half + (n - half) / 2, n],
            });
        }
    }
    out
}

/// A scratch path for a bake file of this test process.
pub(super) fn scratch_file(name: &str) -> std::path::PathBuf {
    std::env::temp_dir().join(format!("prt-vertex-{name}-{}.prtbake", std::process::id()))
}

/// Bakes `scene` into a scratch file and returns what the bake said and the file's bytes.
pub(super) fn bake_bytes(
    scene: &Scene,
    shading: &[ShadingBasis],
    opts: &VertexBakeOptions,
    name: &str,
) -> Result<(VertexBakeResult, Vec<u8>), VertexError> {
    let path = scratch_file(name);
    let r = bake_vertex(scene, &[], shading, opts, &path, None)?;
    let bytes = std::fs::read(&path).expect("the bake file");
    std::fs::remove_file(&path).ok();
    Ok((r, bytes))
}

/// Bakes `scene` into a scratch file and opens it.
pub(super) fn bake_file(
    scene: &Scene,
    opts: &VertexBakeOptions,
    name: &str,
) -> (VertexBakeResult, prt_formats::BakeFile) {
    let path = scratch_file(name);
    let r = bake_vertex(scene, &[], &[], opts, &path, None).expect("bake");
    let f = prt_formats::BakeFile::open(&path).expect("open");
    std::fs::remove_file(&path).ok();
    (r, f)
}

/// Texel directions (f32, as traced) and exact solid angles of the direct cube.
pub(super) fn direct_texels() -> Vec<(Vec3, f64)> {
    (0..T0_TEXELS)
        .map(|t| {
            let (face, i, j) = texel_at(DIRECT_CUBE, t).unwrap();
            let d = texel_centre_direction(DIRECT_CUBE, face, i, j).map(|x| x as f32);
            (Vec3::from_array(d), texel_solid_angle(DIRECT_CUBE, i, j))
        })
        .collect()
}

/// `sum_terms C0[index] value` of row `row` of a vertex's stored T0 terms.
pub(super) fn sparse_dot(
    index: &[u16],
    value: &[f32],
    terms: usize,
    row: usize,
    c0: &[f32],
) -> f64 {
    let r = row * terms..(row + 1) * terms;
    index[r.clone()]
        .iter()
        .zip(&value[r])
        .map(|(&i, &v)| c0[i as usize] as f64 * v as f64)
        .sum()
}
