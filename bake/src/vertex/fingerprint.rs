//! What a per-vertex bake's pieces depend on ([`crate::shard::Fingerprint`]): the program and
//! vertex schema, every option that reaches the traced tensors, the units' size, the scene as
//! prepared (welded and ordered) with the normals it is baked with, and the plan (groups and the
//! pre-pass's active slots); the finished pieces also depend on the compression settings,
//! the traced ones (`bake --keep-traced`) do not.

use prt_formats::vertex::VERTEX_SCHEMA_VERSION;

use crate::scene::Scene;
use crate::shard::{scene_entries, Fingerprint, StoreFingerprints};

use super::cluster_choice::unit_vertices;
use super::plan::VertexPlan;
use super::VertexBakeOptions;

/// The fingerprints of baking `plan` (made from the prepared `scene`) with `opts`.
pub fn vertex_fingerprints(
    scene: &Scene,
    plan: &VertexPlan,
    opts: &VertexBakeOptions,
) -> StoreFingerprints {
    let mut traced = Fingerprint::new();
    traced.literal(
        "program",
        format!(
            "prt-bake {} (vertex schema {VERTEX_SCHEMA_VERSION})",
            env!("CARGO_PKG_VERSION")
        ),
    );
    traced.literal("spp", opts.samples);
    traced.literal("vertex.secondary", opts.secondary);
    traced.literal("reflections", opts.reflections);
    traced.literal("seed", opts.seed);
    traced.literal("vertex.t0_terms", opts.t0_terms);
    traced.literal("precision", opts.precision.name());
    traced.literal("vertex.light_bins", opts.light_bins);
    traced.literal(
        "unit vertices",
        unit_vertices(opts.compression.and_then(|c| c.cluster_vertices)),
    );
    scene_entries(
        &mut traced,
        scene,
        &plan.normals,
        &format!("{:?} {:?}", plan.slots.materials, plan.slots.basis_families),
    );
    traced.hashed("groups and active slots", |h| {
        h.str(&format!("{:?}", plan.groups))
    });
    let mut pieces = traced.clone();
    match &opts.compression {
        None => pieces.literal("vertex.compress", false),
        Some(c) => {
            pieces.literal("vertex.compress", true);
            pieces.literal("vertex.compress_error", c.error_target);
            pieces.literal(
                "vertex.cluster_vertices",
                c.cluster_vertices
                    .map_or("chosen".to_string(), |n| n.to_string()),
            );
            pieces.literal("vertex.light_rank", c.max_light_rank);
            pieces.literal("vertex.element_rank", c.max_element_rank);
            pieces.literal("vertex.vertex_rank", c.max_vertex_rank);
        }
    }
    StoreFingerprints {
        mode: "vertex".into(),
        pieces,
        traced,
    }
}
