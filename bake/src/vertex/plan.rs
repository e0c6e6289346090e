//! What a per-vertex bake will compute, before any expensive work: the refusals, the groups
//! (one per material with vertices), the active slots of each group (a pre-pass over the same
//! first rays the bake traces), the allocation report and the memory estimate, so that
//! `--max-memory` refuses before the bases are built and the vertices traced.

use std::collections::BTreeSet;

use glam::Vec3;
use prt_formats::basis::TuckerRanks;
use prt_formats::pixel::BasisMeta;
use prt_formats::vertex::{cube_len, SH_TERMS, T1_LIGHT_CUBE, T2_LIGHT_CUBE, VISIBILITY_CUBE};
use prt_formats::Family;
use rayon::prelude::*;

use crate::integrator::Integrator;
use crate::pixel::{SlotLayout, SlotPlan};
use crate::progress::{Progress, Stage};
use crate::scene::{PunctualLight, Scene};
use crate::units::human_bytes;

use super::error::VertexError;
use super::frame::{FirstDirections, VertexFrame};
use super::units::Unit;
use super::write::value_bytes;
use super::VertexBakeOptions;

/// Vertices per parallel work item of the pre-pass and the bake (results do not depend on it).
pub(crate) const BLOCK_VERTICES: usize = 4;

/// Refuses a scene with lights other than the environment (emissive materials used by a
/// triangle, punctual lights), naming them: the per-vertex mode relights distant light only.
pub fn check_scene(scene: &Scene) -> Result<(), VertexError> {
    let mut used = vec![false; scene.materials.len()];
    for &m in &scene.triangle_material {
        used[m as usize] = true;
    }
    let emissive: Vec<&str> = scene
        .materials
        .iter()
        .zip(&used)
        .filter(|(m, &u)| u && m.is_emissive())
        .map(|(m, _)| m.name.as_str())
        .collect();
    let mut parts = Vec::new();
    if !emissive.is_empty() {
        parts.push(format!(
            "area lights (emissive materials: {})",
            emissive.join(", ")
        ));
    }
    if !scene.lights.is_empty() {
        let count = |f: fn(&PunctualLight) -> bool| scene.lights.iter().filter(|l| f(l)).count();
        let kinds = [
            (count(|l| matches!(l, PunctualLight::Point { .. })), "point"),
            (count(|l| matches!(l, PunctualLight::Spot { .. })), "spot"),
            (
                count(|l| matches!(l, PunctualLight::Directional { .. })),
                "directional",
            ),
        ];
        let kinds: Vec<String> = kinds
            .iter()
            .filter(|(n, _)| *n > 0)
            .map(|(n, k)| format!("{n} {k}"))
            .collect();
        parts.push(format!(
            "{} punctual light{} ({})",
            scene.lights.len(),
            if scene.lights.len() == 1 { "" } else { "s" },
            kinds.join(", ")
        ));
    }
    if parts.is_empty() {
        Ok(())
    } else {
        Err(VertexError::Lights {
            what: parts.join(" and "),
        })
    }
}

/// Per vertex, its material: that of the lowest-indexed triangle using it (None for a vertex
/// no triangle uses).
pub fn vertex_materials(scene: &Scene) -> Vec<Option<u32>> {
    first_triangles(scene)
        .iter()
        .map(|t| t.map(|t| scene.triangle_material[t as usize]))
        .collect()
}

/// Per vertex, the lowest-indexed triangle using it.
pub(crate) fn first_triangles(scene: &Scene) -> Vec<Option<u32>> {
    let mut first = vec![None; scene.positions.len()];
    for (t, tri) in scene.triangles.iter().enumerate() {
        for &v in tri {
            first[v as usize].get_or_insert(t as u32);
        }
    }
    first
}

/// The unit normal each vertex is baked with: the scene's vertex normal, normalized; where it
/// is unusable, the facet normal of the vertex's first triangle; +Y for a vertex no triangle
/// uses.
pub(crate) fn vertex_normals(scene: &Scene, first: &[Option<u32>]) -> Vec<Vec3> {
    scene
        .normals
        .iter()
        .zip(first)
        .map(|(n, t)| {
            let n = n.normalize_or_zero();
            if n != Vec3::ZERO {
                return n;
            }
            let facet = t.map_or(Vec3::ZERO, |t| {
                let [a, b, c] = scene.triangles[t as usize].map(|v| scene.positions[v as usize]);
                (b - a).cross(c - a).normalize_or_zero()
            });
            if facet == Vec3::ZERO {
                Vec3::Y
            } else {
                facet
            }
        })
        .collect()
}

/// The vertices of one material and the slots that carry light into them.
#[derive(Clone, Debug, PartialEq)]
pub struct PlannedGroup {
    /// The material (index into the scene's materials).
    pub material: u32,
    /// Global vertex indices, ascending.
    pub vertices: Vec<u32>,
    /// Global slots of the materials the pre-pass's first rays reach (j of T1 and T2),
    /// ascending.
    pub active: Vec<u32>,
    /// The material's family when it has a lobe (its T0 rows follow that shading basis).
    pub lobe: Option<Family>,
}

impl PlannedGroup {
    /// T0 rows with the family's default shading basis (the thesis' ranks): `r_i + 1`, or 1.
    pub fn planned_t0_rows(&self) -> usize {
        self.lobe
            .and_then(TuckerRanks::thesis)
            .map_or(1, |r| r.i + 1)
    }
}

/// The plan of a per-vertex bake: slots, groups, active slots.
#[derive(Clone, Debug)]
pub struct VertexPlan {
    /// The slots of every material ([`SlotPlan::per_unit_radiance`]).
    pub slots: SlotPlan,
    /// One per material with vertices, in material order.
    pub groups: Vec<PlannedGroup>,
    /// Global slots i of T2 (every slot, ascending; empty for 2 reflections).
    pub t2_slots: Vec<u32>,
    /// The unit normal of every vertex, as baked (and stored in `mesh.normals`).
    pub normals: Vec<Vec3>,
    /// The units (super-clusters), in order: each group's vertices, unit after unit.
    pub units: Vec<Unit>,
    /// Rays the pre-pass traced.
    pub prepass_rays: u64,
}

impl VertexPlan {
    /// Checks the options and the scene's lights, groups the vertices, checks that `units`
    /// cover the groups in order (the scene must be prepared: [`super::prepare_scene`]), and
    /// runs the pre-pass: from every grouped vertex the first rays of the bake (the same
    /// random draws), keeping per group the slots of the materials they reach from the front
    /// (objects that cannot see each other get no block). `progress` advances once per block
    /// of vertices.
    pub fn new(
        integ: &Integrator,
        slots: SlotPlan,
        opts: &VertexBakeOptions,
        units: Vec<Unit>,
        progress: Option<&dyn Progress>,
    ) -> Result<VertexPlan, VertexError> {
        opts.validate()?;
        let scene = integ.scene;
        check_scene(scene)?;
        let first = first_triangles(scene);
        let normals = vertex_normals(scene, &first);
        let nmat = scene.materials.len();
        let mut members: Vec<Vec<u32>> = vec![Vec::new(); nmat];
        for (v, t) in first.iter().enumerate() {
            if let Some(t) = t {
                members[scene.triangle_material[*t as usize] as usize].push(v as u32);
            }
        }
        check_units(&members, &units)?;
        let all: Vec<(usize, u32)> = members
            .iter()
            .enumerate()
            .flat_map(|(m, vs)| vs.iter().map(move |&v| (m, v)))
            .collect();
        let stage = Stage::start(progress, "finding active slots", all.len() as u64);
        let reached: Vec<(Vec<(usize, u32)>, u64)> = all
            .par_chunks(BLOCK_VERTICES)
            .map(|block| {
                let mut out = Vec::new();
                let mut rays = 0;
                for &(m, v) in block {
                    let (hit, r) = materials_reached(integ, &slots, &normals, v, opts);
                    rays += r;
                    out.extend(hit.into_iter().map(|h| (m, h)));
                }
                stage.advance(block.len() as u64);
                (out, rays)
            })
            .collect();
        drop(stage);
        let mut seen: Vec<BTreeSet<u32>> = vec![BTreeSet::new(); nmat];
        let mut prepass_rays = 0;
        for (pairs, rays) in reached {
            prepass_rays += rays;
            for (m, h) in pairs {
                seen[m].insert(h);
            }
        }
        let groups = members
            .into_iter()
            .enumerate()
            .filter(|(_, vs)| !vs.is_empty())
            .map(|(m, vertices)| {
                let active = seen[m]
                    .iter()
                    .flat_map(|&h| {
                        let meta = &slots.materials[h as usize];
                        meta.slot_offset..meta.slot_offset + meta.slots.len() as u32
                    })
                    .collect();
                let family = scene.materials[m].brdf.family;
                PlannedGroup {
                    material: m as u32,
                    vertices,
                    active,
                    lobe: (family != Family::Diffuse).then_some(family),
                }
            })
            .collect();
        let t2_slots = if opts.reflections >= 3 {
            (0..slots.total_slots as u32).collect()
        } else {
            Vec::new()
        };
        Ok(VertexPlan {
            slots,
            groups,
            t2_slots,
            normals,
            units,
            prepass_rays,
        })
    }

    /// The slot layout with the PCA bases built for the plan's families.
    pub fn layout(
        &self,
        bases: &[prt_formats::basis::BrdfBasis],
    ) -> Result<SlotLayout, VertexError> {
        Ok(self.slots.clone().with_bases(bases)?)
    }

    /// The families whose shading basis the groups need, in order of first use.
    pub fn shading_families(&self) -> Vec<Family> {
        let mut out = Vec::new();
        for f in self.groups.iter().filter_map(|g| g.lobe) {
            if !out.contains(&f) {
                out.push(f);
            }
        }
        out
    }

    /// Vertices in groups (the bake's progress total).
    pub fn grouped_vertices(&self) -> usize {
        self.groups.iter().map(|g| g.vertices.len()).sum()
    }

    /// Values per vertex of group `g` with `t0_rows` T0 rows: (T0 terms, T1, T2).
    pub(crate) fn values_per_vertex(
        &self,
        g: &PlannedGroup,
        t0_rows: usize,
        opts: &VertexBakeOptions,
    ) -> (usize, usize, usize) {
        let c = self.slots.channels;
        let j = g.active.len();
        let t1 = cube_len(T1_LIGHT_CUBE) * j * SH_TERMS * c;
        let t2 = cube_len(T2_LIGHT_CUBE) * j * self.t2_slots.len() * c;
        (t0_rows * opts.t0_terms, t1, t2)
    }

    /// Stored bytes per vertex of group `g` (planned T0 rows): vertex index, T0 indices and
    /// values, visibility, T1, T2.
    pub fn bytes_per_vertex(&self, g: &PlannedGroup, opts: &VertexBakeOptions) -> u64 {
        let (t0, t1, t2) = self.values_per_vertex(g, g.planned_t0_rows(), opts);
        let p = value_bytes(opts.precision);
        (4 + t0 * (2 + p) + cube_len(VISIBILITY_CUBE) + (t1 + t2) * p) as u64
    }

    /// The allocation as the bake prints it before tracing: the slots and why, then per group
    /// vertices x (T0 rows x terms, T1 384 x J x 16, T2 24 x J x I) and its bytes, the total.
    pub fn report(&self, scene: &Scene, opts: &VertexBakeOptions) -> String {
        let c = self.slots.channels;
        let ch = if c == 1 {
            String::new()
        } else {
            format!(" x {c}")
        };
        let mut r = format!(
            "allocation ({} global slots, {} vertices in {} groups, N1 = {} directions, N2 = {}):",
            self.slots.total_slots,
            self.grouped_vertices(),
            self.groups.len(),
            opts.samples,
            opts.secondary,
        );
        for reason in &self.slots.reasons {
            r.push_str(&format!("\n  {reason}"));
        }
        let mut total = 0u64;
        for g in &self.groups {
            let name = &scene.materials[g.material as usize].name;
            let bytes = self.bytes_per_vertex(g, opts) * g.vertices.len() as u64;
            total += bytes;
            let j = g.active.len();
            let t2 = if opts.reflections >= 3 {
                format!(", T2 24 x {j} x {}{ch}", self.t2_slots.len())
            } else {
                String::new()
            };
            r.push_str(&format!(
                "\n  {name}: {} vertices x (T0 {} x {}, T1 384 x {j} x 16{ch}{t2}) = {}",
                g.vertices.len(),
                g.planned_t0_rows(),
                opts.t0_terms,
                human_bytes(bytes),
            ));
            let reached: Vec<&str> = scene
                .materials
                .iter()
                .zip(&self.slots.materials)
                .filter(|(_, m)| {
                    m.slots
                        .iter()
                        .enumerate()
                        .any(|(k, _)| g.active.contains(&(m.slot_offset + k as u32)))
                })
                .map(|(s, _)| s.name.as_str())
                .collect();
            r.push_str(&format!(
                "; light after one reflection from: {}",
                if reached.is_empty() {
                    "nothing".to_string()
                } else {
                    reached.join(", ")
                }
            ));
        }
        r.push_str(&format!(
            "\n  total: {} stored as {}",
            human_bytes(total),
            opts.precision.name()
        ));
        if let Some(c) = &opts.compression {
            r.push_str(&format!(
                " before compression: T1 and T2 are stored compressed ({}, error target {} %, \
                 ranks at most {} light x {} element x {} vertex; the clusters, ranks and T0 \
                 terms chosen are reported per group)",
                match c.cluster_vertices {
                    Some(n) => format!("clusters of about {n} vertices"),
                    None => format!(
                        "units of up to {} vertices as 2 clusters, or 1 or 4 where that is \
                         the smallest result meeting the target",
                        super::units::UNIT_VERTICES
                    ),
                },
                100.0 * c.error_target,
                c.max_light_rank,
                c.max_element_rank,
                c.max_vertex_rank
            ));
        }
        r
    }
}

/// Checks that `units` hold each non-empty group of `members` (per material, ascending), group
/// after group, as contiguous ranges in order: what the streaming assembly writes.
fn check_units(members: &[Vec<u32>], units: &[Unit]) -> Result<(), VertexError> {
    let mut next = units.iter();
    for (g, vs) in members.iter().filter(|m| !m.is_empty()).enumerate() {
        let mut at = 0;
        while at < vs.len() {
            let Some(u) = next.next() else { break };
            if u.group != g || vs.get(at..at + u.vertices.len()) != Some(&u.vertices[..]) {
                break;
            }
            at += u.vertices.len();
        }
        if at != vs.len() || vs.windows(2).any(|w| w[1] != w[0] + 1) {
            return Err(VertexError::Inconsistent(
                "the scene's vertices are not in unit order: bake a scene prepared by \
                 vertex::prepare_scene"
                    .into(),
            ));
        }
    }
    if next.next().is_some() {
        return Err(VertexError::Inconsistent(
            "more units than the groups' vertices".into(),
        ));
    }
    Ok(())
}

/// The materials (with slots) that the first rays of vertex `v` reach from their front, and
/// the rays traced: the bake's own first rays (same draws, same tests).
fn materials_reached(
    integ: &Integrator,
    slots: &SlotPlan,
    normals: &[Vec3],
    v: u32,
    opts: &VertexBakeOptions,
) -> (Vec<u32>, u64) {
    let scene = integ.scene;
    let frame = VertexFrame::new(
        scene.positions[v as usize],
        normals[v as usize],
        integ.eps(),
    );
    let mut out: Vec<u32> = Vec::new();
    let first = FirstDirections::new(opts.seed, v, opts.samples);
    for i in 0..opts.samples {
        let w1 = frame.to_world(first.get(i));
        let Some(hit) = integ.accel.intersect(frame.origin, w1, 0.0, f32::INFINITY) else {
            continue;
        };
        let y = integ.surface(&hit, w1);
        if y.to_local(-w1).z <= 0.0 || slots.materials[y.material as usize].slots.is_empty() {
            continue;
        }
        if !out.contains(&y.material) {
            out.push(y.material);
        }
    }
    (out, opts.samples as u64)
}

/// The PCA bases as stored (re-exported for the bake's metadata).
pub(crate) fn persisted(layout: &SlotLayout) -> (Vec<BasisMeta>, Vec<Vec<f32>>) {
    crate::pixel::persisted_bases(&layout.bases)
}
