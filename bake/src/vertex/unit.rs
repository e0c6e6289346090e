//! One unit of a per-vertex bake, from trace to piece (docs/vertex.md, "Bounded memory"):
//! its vertices traced ([`trace_units`], several units at once over all threads), then its T0
//! figures and its T1 and T2 compressed ([`finish_unit`]) into a [`PieceOut`] that holds what
//! the file needs of the unit and the figures the assembly adds up per group.
//!
//! A piece's sections: `t0.index` (u16) and `t0.value` (f32), `[vertices, rows, t0_terms]`,
//! every row's stored Haar terms before any cut; `t0.open` (u8, `[vertices]`: 1 where the
//! irradiance row is the occluded part, `direct.rs`); `visibility` (u8, `[vertices, 1536]`, groups
//! with a lobe only); dense `t1`, `t2` (f32) or, compressed, per tensor `T.ranks` (u32,
//! `(a, r, b)` per cluster), `T.factors`, `T.core` and `T.vertex` (f32, cluster after
//! cluster; `T.vertex` holds each cluster's `n_c x b_c` rows). Its summary holds the figures
//! ([`UnitSummary`]).

use prt_formats::clustered::CompressionSettings;
use prt_formats::vertex::{cube_len, SH_TERMS, T1_LIGHT_CUBE, T2_LIGHT_CUBE, VISIBILITY_CUBE};
use rayon::prelude::*;

use crate::shard::{Piece, PieceOut, ShardError};

use super::cluster_choice::{next_parts, pick, PartsCandidate};
use super::compress::{compress_clusters, ClusterFigures, ClusterTucker, ElementGrams};
use super::error::VertexError;
use super::plan::{VertexPlan, BLOCK_VERTICES};
use super::t0_choice::energy_at;
use super::trace::VertexTracer;
use super::units::Unit;
use super::VertexBakeOptions;

/// A unit's tensors as traced, dense and in f32 (what compression reads, and what
/// `bake --keep-traced` keeps).
#[derive(Debug, Default)]
pub(crate) struct TracedUnit {
    pub t0_index: Vec<u16>,
    pub t0_value: Vec<f32>,
    /// Per vertex, 1 when its irradiance row is the occluded part (`direct.rs`).
    pub t0_open: Vec<u8>,
    /// Empty for a group without a lobe.
    pub visibility: Vec<u8>,
    pub t1: Vec<f32>,
    pub t2: Vec<f32>,
    /// Per vertex, the noise energy of its T1 and T2 rows.
    pub t1_noise: Vec<f64>,
    pub t2_noise: Vec<f64>,
    pub rays: u64,
    /// Sums of squares of the T0 coefficients, all and dropped by the trace's truncation.
    pub t0_total: f64,
    pub t0_dropped: f64,
}

impl TracedUnit {
    fn append(&mut self, o: TracedUnit) {
        self.t0_index.extend(o.t0_index);
        self.t0_value.extend(o.t0_value);
        self.t0_open.extend(o.t0_open);
        self.visibility.extend(o.visibility);
        self.t1.extend(o.t1);
        self.t2.extend(o.t2);
        self.t1_noise.extend(o.t1_noise);
        self.t2_noise.extend(o.t2_noise);
        self.rays += o.rays;
        self.t0_total += o.t0_total;
        self.t0_dropped += o.t0_dropped;
    }
}

/// The figures of a compressed tensor of a unit.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub(crate) struct TuckerSummary {
    /// Clusters' `(a, r, b)`, in order.
    pub ranks: Vec<[usize; 3]>,
    /// Clusters' vertices, in order.
    pub sizes: Vec<usize>,
    /// Their figures, added.
    pub figures: ClusterFigures,
    /// The largest magnitude in the cores (the group's f16 scale takes the largest).
    pub core_max: f32,
}

/// What a piece's summary holds.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub(crate) struct UnitSummary {
    pub unit: usize,
    pub group: usize,
    pub vertices: usize,
    pub rays: u64,
    pub t0_rows: usize,
    /// Terms stored per T0 row (the bake's `t0_terms`).
    pub t0_terms: usize,
    pub t0_total: f64,
    pub t0_dropped: f64,
    /// [`energy_at`] of the unit's T0 rows.
    pub t0_energy_at: Vec<f64>,
    /// The largest T0 magnitude.
    pub t0_max: f32,
    pub visibility: bool,
    /// Dense pieces: the largest T1 and T2 magnitudes; compressed pieces: None.
    pub dense_max: Option<[f32; 2]>,
    /// Per vertex, noise energy of T1 and of T2 (kept so that a traced piece compresses
    /// again to the same bytes).
    pub t1_noise: Vec<f64>,
    pub t2_noise: Vec<f64>,
    /// Compressed pieces: the split chosen (1, 2 or 4 clusters), every split tried, T1 and
    /// T2.
    pub parts: Option<usize>,
    pub tried: Vec<PartsCandidate>,
    pub t1: Option<TuckerSummary>,
    pub t2: Option<TuckerSummary>,
}

/// Traces the vertices of `units` (indices into `all`) over all threads; returns each unit's
/// tensors in order. `progress` is called with each block's vertex count as it finishes and
/// says whether to go on (false: the caller cancelled; the batch stops with
/// [`crate::progress::Cancelled`]).
pub(crate) fn trace_units(
    tracer: &VertexTracer,
    all: &[Unit],
    units: &[usize],
    progress: &(dyn Fn(u64) -> bool + Sync),
) -> Result<Vec<TracedUnit>, VertexError> {
    let items: Vec<(usize, &[u32])> = units
        .iter()
        .enumerate()
        .flat_map(|(k, &u)| all[u].vertices.chunks(BLOCK_VERTICES).map(move |b| (k, b)))
        .collect();
    let blocks: Vec<(usize, TracedUnit)> = items
        .par_iter()
        .map(|&(k, block)| {
            let t = trace_block(tracer, block)?;
            if !progress(block.len() as u64) {
                return Err(crate::progress::Cancelled.into());
            }
            Ok((k, t))
        })
        .collect::<Result<_, VertexError>>()?;
    let mut out: Vec<TracedUnit> = (0..units.len()).map(|_| TracedUnit::default()).collect();
    for (k, b) in blocks {
        out[k].append(b);
    }
    Ok(out)
}

/// Traces `vertices` in order.
fn trace_block(tracer: &VertexTracer, vertices: &[u32]) -> Result<TracedUnit, VertexError> {
    let mut out = TracedUnit::default();
    for &v in vertices {
        let r = tracer.trace(v)?;
        let terms = tracer.haar_terms(&r)?;
        out.t0_index.extend(terms.index);
        out.t0_value.extend(terms.value);
        out.t0_open.push(u8::from(terms.open));
        if tracer.group_shading(r.group).is_some() {
            // Only the specular lobes read the visibility (docs/vertex.md, section 3).
            out.visibility.extend(r.visibility_u8());
        }
        out.t1.extend(r.t1);
        out.t2.extend(r.t2);
        out.t1_noise.push(r.t1_noise);
        out.t2_noise.push(r.t2_noise);
        out.rays += r.rays;
        out.t0_total += terms.total;
        out.t0_dropped += terms.dropped;
    }
    Ok(out)
}

/// The shape of a group's T1 and T2 rows: (T1 light bins, T1 width, T2 light bins, T2 width).
pub(crate) fn tensor_widths(plan: &VertexPlan, group: usize) -> (usize, usize, usize, usize) {
    let c = plan.slots.channels;
    let j = plan.groups[group].active.len();
    (
        cube_len(T1_LIGHT_CUBE),
        j * SH_TERMS * c,
        cube_len(T2_LIGHT_CUBE),
        j * plan.t2_slots.len() * c,
    )
}

fn max_abs(v: &[f32]) -> f32 {
    v.iter().fold(0.0f32, |m, x| m.max(x.abs()))
}

/// Stored bytes of a candidate: ranks, factors, cores, vertex rows at `value_bytes` each.
fn stored_bytes(clusters: &[ClusterTucker], value_bytes: u64) -> u64 {
    clusters
        .iter()
        .map(|c| 12 + value_bytes * (c.factors.len() + c.core.len() + c.vertex.len()) as u64)
        .sum()
}

/// A unit's piece: its T0 figures and sections, its visibility, and T1 and T2 compressed with
/// `compression` (the split chosen per `cluster_choice.rs`) or dense when None.
pub(crate) fn finish_unit(
    index: usize,
    unit: &Unit,
    traced: &TracedUnit,
    plan: &VertexPlan,
    opts: &VertexBakeOptions,
    t0_rows: usize,
) -> Result<PieceOut, VertexError> {
    let n = unit.vertices.len();
    let (b1, w1, b2, w2) = tensor_widths(plan, unit.group);
    let three = opts.reflections >= 3;
    let mut summary = UnitSummary {
        unit: index,
        group: unit.group,
        vertices: n,
        rays: traced.rays,
        t0_rows,
        t0_terms: opts.t0_terms,
        t0_total: traced.t0_total,
        t0_dropped: traced.t0_dropped,
        t0_energy_at: energy_at(&traced.t0_value, opts.t0_terms),
        t0_max: max_abs(&traced.t0_value),
        visibility: !traced.visibility.is_empty(),
        dense_max: None,
        t1_noise: traced.t1_noise.clone(),
        t2_noise: traced.t2_noise.clone(),
        parts: None,
        tried: Vec::new(),
        t1: None,
        t2: None,
    };
    let compressed = match &opts.compression {
        None => None,
        Some(settings) => {
            let value_bytes = super::write::value_bytes(opts.precision) as u64;
            Some(compress_unit(
                unit,
                traced,
                (b1, w1, b2, w2),
                three,
                settings,
                value_bytes,
            )?)
        }
    };
    let tucker_summary = |c: &[ClusterTucker]| {
        let mut figures = ClusterFigures::default();
        for k in c {
            figures.add(&k.figures);
        }
        TuckerSummary {
            ranks: c.iter().map(|k| k.ranks).collect(),
            sizes: c.iter().map(|k| k.vertices).collect(),
            figures,
            core_max: c.iter().map(|k| max_abs(&k.core)).fold(0.0, f32::max),
        }
    };
    match &compressed {
        None => summary.dense_max = Some([max_abs(&traced.t1), max_abs(&traced.t2)]),
        Some((parts, t1, t2, tried)) => {
            summary.parts = Some(*parts);
            summary.tried = tried.clone();
            summary.t1 = Some(tucker_summary(t1));
            summary.t2 = t2.as_deref().map(tucker_summary);
        }
    }
    let mut piece = PieceOut::new(
        serde_json::to_value(&summary)
            .map_err(|e| VertexError::Inconsistent(format!("unit {index}'s summary: {e}")))?,
    );
    piece.add("t0.index", &traced.t0_index);
    piece.add("t0.value", &traced.t0_value);
    piece.add("t0.open", &traced.t0_open);
    if !traced.visibility.is_empty() {
        piece.add("visibility", &traced.visibility);
    }
    match &compressed {
        None => {
            piece.add("t1", &traced.t1);
            piece.add("t2", &traced.t2);
        }
        Some((_, t1, t2, _)) => {
            add_tucker(&mut piece, "t1", t1);
            if let Some(t2) = t2 {
                add_tucker(&mut piece, "t2", t2);
            }
        }
    }
    Ok(piece)
}

fn add_tucker(p: &mut PieceOut, tensor: &str, clusters: &[ClusterTucker]) {
    let ranks: Vec<u32> = clusters
        .iter()
        .flat_map(|c| c.ranks.map(|r| r as u32))
        .collect();
    let cat = |f: fn(&ClusterTucker) -> &Vec<f32>| -> Vec<f32> {
        clusters.iter().flat_map(|c| f(c).iter().copied()).collect()
    };
    p.add(&format!("{tensor}.ranks"), &ranks);
    p.add(&format!("{tensor}.factors"), &cat(|c| &c.factors));
    p.add(&format!("{tensor}.core"), &cat(|c| &c.core));
    p.add(&format!("{tensor}.vertex"), &cat(|c| &c.vertex));
}

pub(crate) type Compressed = (
    usize,
    Vec<ClusterTucker>,
    Option<Vec<ClusterTucker>>,
    Vec<PartsCandidate>,
);

/// Compresses a unit's T1 and T2 with the split the search picks (`cluster_choice.rs`): each
/// split tried compresses both tensors; only the best so far is kept.
pub(crate) fn compress_unit(
    unit: &Unit,
    traced: &TracedUnit,
    (b1, w1, b2, w2): (usize, usize, usize, usize),
    three: bool,
    settings: &CompressionSettings,
    value_bytes: u64,
) -> Result<Compressed, VertexError> {
    let n = unit.vertices.len();
    let mut tried: Vec<PartsCandidate> = Vec::new();
    let mut best: Option<(usize, Vec<ClusterTucker>, Option<Vec<ClusterTucker>>)> = None;
    // The splits tried share their element Gram matrices (the whole unit's is its halves').
    let (mut grams1, mut grams2) = (ElementGrams::default(), ElementGrams::default());
    while let Some(parts) = next_parts(settings.cluster_vertices, n, &tried, settings.error_target)
    {
        let ranges = unit.clusters(parts);
        let c1 = compress_clusters(
            &traced.t1,
            b1,
            w1,
            &ranges,
            &traced.t1_noise,
            settings,
            &mut grams1,
        )?;
        let c2 = if three {
            Some(compress_clusters(
                &traced.t2,
                b2,
                w2,
                &ranges,
                &traced.t2_noise,
                settings,
                &mut grams2,
            )?)
        } else {
            None
        };
        let beyond = |c: &[ClusterTucker]| {
            let mut f = ClusterFigures::default();
            for k in c {
                f.add(&k.figures);
            }
            f.beyond_noise()
        };
        tried.push(PartsCandidate {
            parts,
            bytes: stored_bytes(&c1, value_bytes)
                + c2.as_deref().map_or(0, |c| stored_bytes(c, value_bytes)),
            errors: std::iter::once(beyond(&c1))
                .chain(c2.as_deref().map(beyond))
                .collect(),
        });
        // Keep this candidate if it is the pick among those tried so far: the pick of all is
        // then the last one kept (`pick` prefers the earlier candidate on ties).
        if pick(&tried, settings.error_target) == Some(tried.len() - 1) {
            best = Some((parts, c1, c2));
        }
    }
    let (parts, c1, c2) = best
        .ok_or_else(|| VertexError::Compression("no split of the unit to compress with".into()))?;
    Ok((parts, c1, c2, tried))
}

/// A unit's traced tensors as a piece (`bake --keep-traced`): the dense form.
pub(crate) fn traced_piece(
    index: usize,
    unit: &Unit,
    traced: &TracedUnit,
    plan: &VertexPlan,
    opts: &VertexBakeOptions,
    t0_rows: usize,
) -> Result<PieceOut, VertexError> {
    let dense = VertexBakeOptions {
        compression: None,
        ..opts.clone()
    };
    finish_unit(index, unit, traced, plan, &dense, t0_rows)
}

/// The traced tensors of a piece [`traced_piece`] wrote.
pub(crate) fn traced_from_piece(piece: &Piece) -> Result<TracedUnit, ShardError> {
    let s: UnitSummary = serde_json::from_value(piece.summary().clone())
        .map_err(|e| piece.bad(format!("its summary: {e}")))?;
    let visibility = if s.visibility {
        piece.values::<u8>("visibility")?.into_owned()
    } else {
        Vec::new()
    };
    let t = TracedUnit {
        t0_index: piece.values::<u16>("t0.index")?.into_owned(),
        t0_value: piece.values::<f32>("t0.value")?.into_owned(),
        t0_open: piece.values::<u8>("t0.open")?.into_owned(),
        visibility,
        t1: piece.values::<f32>("t1")?.into_owned(),
        t2: piece.values::<f32>("t2")?.into_owned(),
        t1_noise: s.t1_noise,
        t2_noise: s.t2_noise,
        rays: s.rays,
        t0_total: s.t0_total,
        t0_dropped: s.t0_dropped,
    };
    let visibility_len = if s.visibility {
        s.vertices * cube_len(VISIBILITY_CUBE)
    } else {
        0
    };
    if t.visibility.len() != visibility_len {
        return Err(piece.bad("its visibility has the wrong size".into()));
    }
    if t.t0_open.len() != s.vertices {
        return Err(piece.bad("its T0 open flags have the wrong size".into()));
    }
    Ok(t)
}
