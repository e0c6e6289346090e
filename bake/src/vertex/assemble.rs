//! The per-vertex bake file assembled from its units' pieces (docs/vertex.md, "Bounded
//! memory"), streamed: whether the pieces come from this run's checkpoint folder or from merged
//! shard files (`crate::shard`), the same common part and pieces give the same bytes, and no
//! more than one piece is in memory at a time.
//!
//! First every piece's summary is read, and the figures that need a whole group are made from
//! the sums of its units' (in unit order): T0's kept Haar terms (`t0_choice.rs`), the f16
//! scales (the largest magnitudes), the compression errors, the clusters' numbering and the
//! vertex factor's width. Then the file is laid out as before (`prt_formats::vertex::names`),
//! each group's tensors produced unit by unit by a [`TensorSource`] when the writer asks.

use std::io::{self, Write};
use std::path::Path;

use half::f16;
use prt_formats::clustered::{GroupCompression, TensorCompression};
use prt_formats::container::{element_bytes, TensorSource};

use crate::shard::{FnSource, StreamedFile};
use prt_formats::pixel::Precision;
use prt_formats::vertex::{
    cube_len, names, VertexBakeMeta, SH_TERMS, T1_LIGHT_CUBE, T2_LIGHT_CUBE, VISIBILITY_CUBE,
};
use prt_formats::{Dtype, FormatError};

use crate::shard::{CommonTensor, PieceSource};

use super::compress::ClusterFigures;
use super::error::VertexError;
use super::t0_choice::{choose_from_energy, cut_rows, T0Choice, T0_ERROR_SHARE};
use super::unit::UnitSummary;

/// What the assembly needs besides the pieces: the metadata with every figure known before
/// tracing (the groups' scales, kept terms, compression figures and the truncation errors are
/// filled in here), the units, and how many of the common tensors come before the groups'.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct VertexCommon {
    pub meta: VertexBakeMeta,
    /// Per unit, in order: its group and vertex count (units are contiguous in vertex order).
    pub units: Vec<(usize, usize)>,
    /// Common tensors written before the groups' (the mesh, the environment); the rest come
    /// after (shading tables, basis tables, textures).
    pub before_groups: usize,
}

/// What one group adds up over its units.
#[derive(Default)]
struct GroupSums {
    units: Vec<usize>,
    first_vertex: usize,
    vertices: usize,
    rays: u64,
    t0_total: f64,
    t0_dropped: f64,
    t0_energy_at: Vec<f64>,
    t0_max: f32,
    t0_terms: usize,
    t0_rows: usize,
    visibility: Option<bool>,
    dense_max: [f32; 2],
    /// Compressed: per tensor, every cluster's ranks and the figures and core maximum.
    clusters: [Vec<[usize; 3]>; 2],
    figures: [ClusterFigures; 2],
    core_max: [f32; 2],
    parts: [usize; 3],
    /// Compressed: the vertices of each cluster, in order (T1's and T2's are the same).
    cluster_sizes: Vec<usize>,
}

/// What the assembly reports.
#[derive(Clone, Debug, Default)]
pub struct Assembled {
    /// The file's metadata as written.
    pub meta: Option<VertexBakeMeta>,
    /// Bytes written.
    pub file_bytes: u64,
    /// One line per group: what was chosen and the errors (for the progress notes).
    pub notes: Vec<String>,
    /// Warnings: groups missing their error target, with what would meet it.
    pub warnings: Vec<String>,
}

/// Writes the bake file at `path` (atomically) from `common`, its `tensors` and the pieces of
/// every unit.
pub fn assemble_vertex_file(
    common: &VertexCommon,
    tensors: &[CommonTensor<'_>],
    pieces: &dyn PieceSource,
    path: &Path,
) -> Result<Assembled, VertexError> {
    let mut meta = common.meta.clone();
    let ngroups = meta.groups.len();
    let mut sums: Vec<GroupSums> = (0..ngroups).map(|_| GroupSums::default()).collect();
    let mut vertex = 0usize;
    for (u, &(g, n)) in common.units.iter().enumerate() {
        let piece = pieces.piece(u)?;
        let s: UnitSummary = serde_json::from_value(piece.summary().clone())
            .map_err(|e| piece.bad(format!("its summary: {e}")))?;
        if s.group != g || s.vertices != n || s.unit != u {
            return Err(piece
                .bad(format!(
                    "it is unit {} of group {} with {} vertices, expected unit {u} of group \
                     {g} with {n}",
                    s.unit, s.group, s.vertices
                ))
                .into());
        }
        let gs = sums
            .get_mut(g)
            .ok_or_else(|| VertexError::Inconsistent(format!("unit {u}: group {g}")))?;
        if gs.units.is_empty() {
            gs.first_vertex = vertex;
            gs.t0_energy_at = vec![0.0; s.t0_terms];
            gs.t0_terms = s.t0_terms;
            gs.t0_rows = s.t0_rows;
        }
        vertex += n;
        gs.units.push(u);
        gs.vertices += n;
        gs.rays += s.rays;
        gs.t0_total += s.t0_total;
        gs.t0_dropped += s.t0_dropped;
        for (a, b) in gs.t0_energy_at.iter_mut().zip(&s.t0_energy_at) {
            *a += b;
        }
        gs.t0_max = gs.t0_max.max(s.t0_max);
        match gs.visibility {
            None => gs.visibility = Some(s.visibility),
            Some(v) if v != s.visibility => {
                return Err(piece
                    .bad("its visibility differs from its group's other units".into())
                    .into())
            }
            _ => {}
        }
        if let Some([m1, m2]) = s.dense_max {
            gs.dense_max = [gs.dense_max[0].max(m1), gs.dense_max[1].max(m2)];
        }
        if let Some(t) = &s.t1 {
            gs.cluster_sizes.extend_from_slice(&t.sizes);
        }
        for (k, t) in [&s.t1, &s.t2].into_iter().enumerate() {
            if let Some(t) = t {
                gs.clusters[k].extend_from_slice(&t.ranks);
                gs.figures[k].add(&t.figures);
                gs.core_max[k] = gs.core_max[k].max(t.core_max);
            }
        }
        if let Some(p) = s.parts {
            gs.parts[match p {
                1 => 0,
                2 => 1,
                _ => 2,
            }] += 1;
        }
    }

    let precision = meta.precision;
    let compression = meta.compression;
    let mut assembled = Assembled::default();
    let mut truncation = Vec::with_capacity(ngroups);
    let mut choices: Vec<T0Choice> = Vec::with_capacity(ngroups);
    let mut rays = meta.stats.rays;
    for (g, (gm, gs)) in meta.groups.iter_mut().zip(&sums).enumerate() {
        if gs.vertices != gm.vertices as usize {
            return Err(VertexError::Inconsistent(format!(
                "group {g}: its units hold {} vertices, the plan {}",
                gs.vertices, gm.vertices
            )));
        }
        rays += gs.rays;
        let choice = match &compression {
            Some(c) => {
                choose_from_energy(&gs.t0_energy_at, f64::from(c.error_target * T0_ERROR_SHARE))
            }
            None => T0Choice {
                terms: gs.t0_terms,
                cut: 0.0,
                stored: gs.t0_energy_at.iter().sum(),
            },
        };
        truncation.push(if gs.t0_total > 0.0 {
            ((gs.t0_dropped + choice.cut) / gs.t0_total).sqrt() as f32
        } else {
            0.0
        });
        gm.scale_t0 = scale(gs.t0_max, precision);
        gm.t0_rows = gs.t0_rows as u32;
        if let Some(settings) = &compression {
            gm.t0_terms = Some(choice.terms as u32);
            let tensor = |k: usize| {
                let f = &gs.figures[k];
                TensorCompression {
                    vertex_rank: gs.clusters[k].iter().map(|r| r[2]).max().unwrap_or(0) as u32,
                    error: f.error() as f32,
                    noise: Some(f.noise() as f32),
                    beyond_noise: Some(f.beyond_noise() as f32),
                }
            };
            let has_t2 = meta.reflections >= 3;
            gm.compression = Some(GroupCompression {
                clusters: gs.clusters[0].len() as u32,
                t1: tensor(0),
                t2: has_t2.then(|| tensor(1)),
            });
            gm.scale_t1 = scale(gs.core_max[0], precision);
            gm.scale_t2 = if has_t2 {
                scale(gs.core_max[1], precision)
            } else {
                1.0
            };
            let name = meta
                .materials
                .get(gm.material as usize)
                .map_or("?", |m| m.name.as_str())
                .to_string();
            let (note, warning) =
                describe_group(&name, gs, &choice, has_t2, meta.t0_terms as usize, settings);
            assembled.notes.push(note);
            assembled.warnings.extend(warning);
        } else {
            gm.scale_t1 = scale(gs.dense_max[0], precision);
            gm.scale_t2 = if meta.reflections >= 3 {
                scale(gs.dense_max[1], precision)
            } else {
                1.0
            };
        }
        choices.push(choice);
    }
    meta.stats.rays = rays;
    meta.stats.t0_truncation_error = truncation;
    meta.validate().map_err(VertexError::Inconsistent)?;

    let err = |source: FormatError| VertexError::Write {
        path: path.to_path_buf(),
        source: Box::new(source),
    };
    let mut w = StreamedFile::new();
    let (before, after) = tensors.split_at(common.before_groups.min(tensors.len()));
    for t in before {
        w.add_bytes(&t.name, t.dtype, &t.shape, t.bytes.as_ref());
    }
    let store = |p: Precision| match p {
        Precision::F32 => Dtype::F32,
        Precision::F16 => Dtype::F16,
    };
    let vb = super::write::value_bytes(precision);
    for (g, (gm, gs)) in meta.groups.iter().zip(&sums).enumerate() {
        let v = gs.vertices;
        let rows = gs.t0_rows;
        let k = choices[g].terms;
        let stored = gs.t0_terms;
        let units = gs.units.clone();
        let first = gs.first_vertex as u32;
        w.add_streamed(
            &names::vertices(g),
            Dtype::U32,
            &[v],
            4 * v,
            source(move |out| {
                let ids: Vec<u32> = (first..first + v as u32).collect();
                out.write_all(&element_bytes(&ids))
            }),
        );

        let t0 = T0Stream {
            pieces,
            units: units.clone(),
            stored,
            keep: k,
            precision,
            scale: gm.scale_t0,
            indices: false,
        };
        let t0_index = T0Stream {
            indices: true,
            ..t0.clone()
        };
        w.add_streamed(
            &names::t0_index(g),
            Dtype::U16,
            &[v, rows, k],
            2 * v * rows * k,
            source(move |out| t0_index.write(out)),
        );

        w.add_streamed(
            &names::t0_value(g),
            store(precision),
            &[v, rows, k],
            vb * v * rows * k,
            source(move |out| t0.write(out)),
        );

        let open_units = units.clone();
        w.add_streamed(
            &names::t0_open(g),
            Dtype::U8,
            &[v],
            v,
            source(move |out| {
                for &u in &open_units {
                    let p = pieces.piece(u).map_err(io::Error::other)?;
                    let b = p.values::<u8>("t0.open").map_err(io::Error::other)?;
                    out.write_all(&b)?;
                }
                Ok(())
            }),
        );

        let width = if gs.visibility == Some(true) {
            cube_len(VISIBILITY_CUBE)
        } else {
            0
        };
        let vis_units = units.clone();
        w.add_streamed(
            &names::visibility(g),
            Dtype::U8,
            &[v, width],
            v * width,
            source(move |out| {
                if width == 0 {
                    return Ok(());
                }
                for &u in &vis_units {
                    let p = pieces.piece(u).map_err(io::Error::other)?;
                    let b = p.values::<u8>("visibility").map_err(io::Error::other)?;
                    out.write_all(&b)?;
                }
                Ok(())
            }),
        );

        match &gm.compression {
            Some(c) => add_compressed(&mut w, &meta, g, gs, c, pieces),
            None => {
                for k in 0..2usize {
                    if k == 1 && meta.reflections < 3 {
                        continue;
                    }
                    let (name, shape) = dense_shape(&meta, gm, g, k, v);
                    let len: usize = shape.iter().product();
                    let scale = if k == 0 { gm.scale_t1 } else { gm.scale_t2 };
                    let units = units.clone();
                    let section = if k == 0 { "t1" } else { "t2" };
                    w.add_streamed(
                        &name,
                        store(precision),
                        &shape,
                        vb * len,
                        source(move |out| {
                            for &u in &units {
                                let p = pieces.piece(u).map_err(io::Error::other)?;
                                let x = p.values::<f32>(section).map_err(io::Error::other)?;
                                write_values(out, &x, precision, scale)?;
                            }
                            Ok(())
                        }),
                    );
                }
            }
        }
    }
    for t in after {
        w.add_bytes(&t.name, t.dtype, &t.shape, t.bytes.as_ref());
    }
    // The metadata is plain numbers, strings and lists: it always serializes.
    w.set_metadata(serde_json::to_value(&meta).unwrap_or(serde_json::Value::Null));
    assembled.file_bytes = w.write(path).map_err(err)?;
    assembled.meta = Some(meta);
    Ok(assembled)
}

/// The name and shape of a dense T1 (`k` 0) or T2 (`k` 1) of group `g` with `v` vertices.
fn dense_shape(
    meta: &VertexBakeMeta,
    gm: &prt_formats::vertex::VertexGroupMeta,
    g: usize,
    k: usize,
    v: usize,
) -> (String, Vec<usize>) {
    let c = meta.channels as usize;
    let j = gm.active.len();
    if k == 0 {
        (
            names::t1(g),
            vec![v, cube_len(T1_LIGHT_CUBE), j, SH_TERMS, c],
        )
    } else {
        (
            names::t2(g),
            vec![v, cube_len(T2_LIGHT_CUBE), j, meta.t2_slots.len(), c],
        )
    }
}

/// The four tensors of a compressed T1 or T2 of group `g` (`prt_formats::clustered`).
fn add_compressed<'a>(
    w: &mut StreamedFile<'a>,
    meta: &VertexBakeMeta,
    g: usize,
    gs: &GroupSums,
    c: &GroupCompression,
    pieces: &'a dyn PieceSource,
) {
    let gm = &meta.groups[g];
    let precision = meta.precision;
    let vb = super::write::value_bytes(precision);
    let dtype = match precision {
        Precision::F32 => Dtype::F32,
        Precision::F16 => Dtype::F16,
    };
    let cluster_of: Vec<u32> = gs
        .cluster_sizes
        .iter()
        .enumerate()
        .flat_map(|(c, &n)| std::iter::repeat_n(c as u32, n))
        .collect();
    w.add_bytes(
        &names::clusters(g),
        Dtype::U32,
        &[gs.vertices],
        element_bytes(&cluster_of).into_owned(),
    );
    for (k, tensor) in [(0usize, names::T1), (1, names::T2)] {
        let figures = match k {
            0 => Some(c.t1),
            _ => c.t2,
        };
        let Some(figures) = figures else { continue };
        let name = |part| names::tucker(g, tensor, part);
        let section = |part: &str| format!("t{}.{part}", k + 1);
        let ranks: Vec<u32> = gs.clusters[k]
            .iter()
            .flat_map(|r| r.map(|x| x as u32))
            .collect();
        let nclusters = gs.clusters[k].len();
        w.add_bytes(
            &name(names::TUCKER_RANKS),
            Dtype::U32,
            &[nclusters, 3],
            element_bytes(&ranks).into_owned(),
        );
        let (bins, width) = tucker_dims(meta, gm, k);
        let factors: usize = gs.clusters[k]
            .iter()
            .map(|[a, r, _]| bins * a + width * r)
            .sum();
        let core: usize = gs.clusters[k].iter().map(|[a, r, b]| a * r * b).sum();
        let scale = if k == 0 { gm.scale_t1 } else { gm.scale_t2 };
        for (part, len, scaled) in [
            (names::TUCKER_FACTORS, factors, false),
            (names::TUCKER_CORE, core, true),
        ] {
            let units = gs.units.clone();
            let sec = section(if scaled { "core" } else { "factors" });
            w.add_streamed(
                &name(part),
                dtype,
                &[len],
                vb * len,
                source(move |out| {
                    for &u in &units {
                        let p = pieces.piece(u).map_err(io::Error::other)?;
                        let x = p.values::<f32>(&sec).map_err(io::Error::other)?;
                        write_values(out, &x, precision, if scaled { scale } else { 1.0 })?;
                    }
                    Ok(())
                }),
            );
        }
        let b_max = figures.vertex_rank as usize;
        let v = gs.vertices;
        let units = gs.units.clone();
        let sec = section("vertex");
        let ranks_sec = section("ranks");
        w.add_streamed(
            &name(names::TUCKER_VERTEX),
            dtype,
            &[v, b_max],
            vb * v * b_max,
            source(move |out| {
                for &u in &units {
                    let p = pieces.piece(u).map_err(io::Error::other)?;
                    let rows = p.values::<f32>(&sec).map_err(io::Error::other)?;
                    let ranks = p.values::<u32>(&ranks_sec).map_err(io::Error::other)?;
                    let s: UnitSummary =
                        serde_json::from_value(p.summary().clone()).map_err(io::Error::other)?;
                    let t = if k == 0 { &s.t1 } else { &s.t2 };
                    let t = t
                        .as_ref()
                        .ok_or_else(|| io::Error::other("a compressed unit without figures"))?;
                    let mut at = 0usize;
                    let mut padded: Vec<f32> = Vec::new();
                    for (ci, n) in t.sizes.iter().enumerate() {
                        let b = ranks[3 * ci + 2] as usize;
                        for r in 0..*n {
                            padded.clear();
                            padded.extend_from_slice(&rows[at + r * b..at + (r + 1) * b]);
                            padded.resize(b_max, 0.0);
                            write_values(out, &padded, precision, 1.0)?;
                        }
                        at += n * b;
                    }
                    if at != rows.len() {
                        return Err(io::Error::other(format!(
                            "unit {u}: {} vertex-factor values, its clusters make {at}",
                            rows.len()
                        )));
                    }
                }
                Ok(())
            }),
        );
    }
}

/// Light bins and element width of T1 (`k` 0) or T2 (`k` 1) of group `gm`.
fn tucker_dims(
    meta: &VertexBakeMeta,
    gm: &prt_formats::vertex::VertexGroupMeta,
    k: usize,
) -> (usize, usize) {
    let c = meta.channels as usize;
    let j = gm.active.len();
    if k == 0 {
        (cube_len(T1_LIGHT_CUBE), j * SH_TERMS * c)
    } else {
        (cube_len(T2_LIGHT_CUBE), j * meta.t2_slots.len() * c)
    }
}

/// The f16 scale of values whose largest magnitude is `max` (the per-pixel writer's rule:
/// the largest maps to 2^14), or 1 for f32.
fn scale(max: f32, precision: Precision) -> f32 {
    match precision {
        Precision::F32 => 1.0,
        Precision::F16 => {
            if max > 0.0 && max.is_finite() {
                max / 16384.0
            } else {
                1.0
            }
        }
    }
}

/// Writes `values` divided by `scale` in the storage precision.
fn write_values(
    out: &mut dyn Write,
    values: &[f32],
    precision: Precision,
    scale: f32,
) -> io::Result<()> {
    match precision {
        Precision::F32 => out.write_all(&element_bytes(values)),
        Precision::F16 => {
            let inv = 1.0 / scale;
            let h: Vec<f16> = values.iter().map(|v| f16::from_f32(v * inv)).collect();
            out.write_all(&element_bytes(&h))
        }
    }
}

fn source<'a, F: Fn(&mut dyn Write) -> io::Result<()> + 'a>(f: F) -> Box<dyn TensorSource + 'a> {
    Box::new(FnSource(f))
}

/// A group's T0 rows, unit by unit, each cut to `keep` of its `stored` terms: the indices
/// (`indices`) or the values.
#[derive(Clone)]
struct T0Stream<'a> {
    pieces: &'a dyn PieceSource,
    units: Vec<usize>,
    stored: usize,
    keep: usize,
    precision: Precision,
    scale: f32,
    indices: bool,
}

impl T0Stream<'_> {
    fn write(&self, out: &mut dyn Write) -> io::Result<()> {
        for &u in &self.units {
            let p = self.pieces.piece(u).map_err(io::Error::other)?;
            let mut index = p
                .values::<u16>("t0.index")
                .map_err(io::Error::other)?
                .into_owned();
            let mut value = p
                .values::<f32>("t0.value")
                .map_err(io::Error::other)?
                .into_owned();
            cut_rows(&mut index, &mut value, self.stored, self.keep);
            if self.indices {
                out.write_all(&element_bytes(&index))?;
            } else {
                write_values(out, &value, self.precision, self.scale)?;
            }
        }
        Ok(())
    }
}

/// The progress line of a compressed group, and a warning when it misses its target.
fn describe_group(
    name: &str,
    gs: &GroupSums,
    choice: &T0Choice,
    has_t2: bool,
    t0_terms: usize,
    settings: &prt_formats::clustered::CompressionSettings,
) -> (String, Option<String>) {
    let target = settings.error_target;
    let t0_target = target * T0_ERROR_SHARE;
    let clusters = gs.clusters[0].len().max(1);
    let mut note = format!(
        "compressed {name}: T0 {} of {t0_terms} Haar terms per row (error {:.2} % against the \
         {t0_terms} terms, target {:.2} %); {} units as 1 / 2 / 4 clusters: {} / {} / {} \
         ({clusters} clusters of {} vertices on average)",
        choice.terms,
        100.0 * choice.error(),
        100.0 * t0_target,
        gs.units.len(),
        gs.parts[0],
        gs.parts[1],
        gs.parts[2],
        gs.vertices.div_ceil(clusters),
    );
    let mut misses = Vec::new();
    let mut capped = [false; 3];
    let mut fallbacks = 0;
    for (k, label) in [(0usize, "T1"), (1, "T2")] {
        if k == 1 && !has_t2 {
            continue;
        }
        let c = &gs.clusters[k];
        let f = &gs.figures[k];
        let n = c.len().max(1) as f64;
        let mean = |i: usize| c.iter().map(|r| r[i] as f64).sum::<f64>() / n;
        let max = |i: usize| c.iter().map(|r| r[i]).max().unwrap_or(0);
        note.push_str(&format!(
            "; {label} ranks light {:.1} (max {}), element {:.1} (max {}), vertex {:.1} (max \
             {}), error {:.2} % against the dense tensor whose noise is {:.2} %: {:.2} % \
             beyond the noise (target {:.1} %)",
            mean(0),
            max(0),
            mean(1),
            max(1),
            mean(2),
            max(2),
            100.0 * f.error(),
            100.0 * f.noise(),
            100.0 * f.beyond_noise(),
            100.0 * target,
        ));
        if f.beyond_noise() > f64::from(target) * (1.0 + 1e-4) {
            misses.push(format!(
                "{label} at {:.1} % beyond its Monte Carlo noise",
                100.0 * f.beyond_noise()
            ));
        }
        for (a, b) in capped.iter_mut().zip(f.capped) {
            *a |= b;
        }
        fallbacks += f.fallbacks;
    }
    if fallbacks > 0 {
        note.push_str(&format!(
            "; {fallbacks} eigendecomposition(s) fell back to the Jacobi method"
        ));
    }
    let warning = (!misses.is_empty()).then(|| {
        let keys: Vec<String> = [
            ("vertex.light_rank", settings.max_light_rank),
            ("vertex.element_rank", settings.max_element_rank),
            ("vertex.vertex_rank", settings.max_vertex_rank),
        ]
        .iter()
        .zip(capped)
        .filter(|(_, c)| *c)
        .map(|((k, v), _)| format!("{k} (now {v})"))
        .collect();
        let fix = if keys.is_empty() {
            "set vertex.cluster_vertices = 64 (smaller clusters)".to_string()
        } else {
            format!(
                "raise {} (the caps that bound), or set vertex.cluster_vertices = 64 (smaller \
                 clusters)",
                keys.join(", ")
            )
        };
        format!(
            "{name}: compressed {} against a {:.1} % target (compress_error): {fix}",
            misses.join(" and "),
            100.0 * target
        )
    });
    (note, warning)
}
