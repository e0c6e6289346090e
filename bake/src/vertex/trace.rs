//! One vertex traced into dense arrays: T0's rows at the 6x64x64 texel centres (before the
//! Haar transform) and the visible fractions at 6x16x16 (both from [`DirectCube`]), T1 and T2
//! over the group's active slots ([`VertexResult`]).
//!
//! The quantities are those `prt_formats::vertex` documents. For T1 and T2, N1 directions w1
//! leave the vertex, each uniform over its hemisphere (pdf 1/(2 pi)), together a shifted
//! lattice ([`FirstDirections`], shared with the pre-pass, which so sees the bake's very
//! rays); at a first hit y, N2 directions w2 come from y's coefficient-independent mixture
//! ([`BakeModel`]) and, with three reflections, each w2 that hits z continues with one w3 from
//! z's mixture. Every sample i of vertex v draws from its own stream
//! `Rng::for_sample(seed, v, i)`: 2 numbers per w2 whatever happens. The w3 directions (three reflections) draw from a second stream,
//! `Rng::for_sample(seed, v, W3_STREAM + i)`, 2 numbers per w2 whether or not a w3 is
//! needed: T1 is then the same, bit for bit, whether T2 is baked or not.
//!
//! With `light_bins` (the default), each first hit y also draws one direction in every T1
//! light bin above its horizon (`bins.rs`; 2 numbers per bin from a third stream,
//! `Rng::for_sample(seed, v, 2^41 + i)`), traces a shadow ray, and T1 combines these draws
//! with the escaping w2 by the balance heuristic: every bin is visited at every first hit, so
//! a bright, small part of a later environment (a lamp, the sun) no longer depends on a few
//! lucky w2. T2 keeps the BRDF draws alone (its integrand over w2 is not binned).
//!
//! The tensors are per unit radiance: the light is the runtime's input, so unlike the
//! per-pixel mode there is no light colour (`SlotLayout::tint`) in them.

use std::f64::consts::{PI, TAU};

use glam::Vec3;
use prt_formats::basis::ShadingBasis;
use prt_formats::lighting::sh::sh_eval;
use prt_formats::vertex::{cube_len, SH_TERMS, T1_LIGHT_CUBE, T2_LIGHT_CUBE};

use crate::integrator::{Integrator, MaterialModel, Slots};
use crate::pixel::{BakeModel, SlotLayout};
use crate::sampling::Rng;

use super::bins::{bin_density, light_bin, sample_bin};
use super::direct::DirectCube;
use super::error::VertexError;
use super::frame::{FirstDirections, VertexFrame};
use super::plan::VertexPlan;
use super::VertexBakeOptions;

/// Offset of the sample index that keys the w3 stream (above any N1).
const W3_STREAM: u64 = 1 << 40;

/// Offset of the sample index that keys the light-bin stream (above the w3 stream).
const BIN_STREAM: u64 = 2 << 40;

/// One vertex's transfer, dense and in f32 (what [`VertexTracer::trace`] returns).
#[derive(Clone, Debug)]
pub struct VertexResult {
    /// The vertex.
    pub vertex: u32,
    /// Its group (index into `VertexPlan::groups`).
    pub group: usize,
    /// Rows of T0: the shading basis' `r_i` plus the irradiance row.
    pub t0_rows: usize,
    /// `[t0_rows][6 * 64 * 64]`: T0~ at each direct texel's centre (cube-map order), before
    /// the Haar transform; 0 below the horizon and where occluded.
    pub t0: Vec<f32>,
    /// `[6 * 64 * 64]`: the irradiance row's occluded part, `(w . n)+ (1 - V)`.
    pub t0_occluded: Vec<f32>,
    /// `[6 * 16 * 16]`: the fraction of each texel's 4 x 4 direct texels that are above the
    /// horizon and visible.
    pub visibility: Vec<f32>,
    /// `[384][J][16][channels]`, J the group's active slots.
    pub t1: Vec<f32>,
    /// `[24][J][I][channels]` (empty with two reflections).
    pub t2: Vec<f32>,
    /// The estimated Monte Carlo noise energy of `t1` and `t2` (the expected squared distance
    /// from the converged tensors), from independent halves of the N1 directions
    /// ([`half_noise`]).
    pub t1_noise: f64,
    pub t2_noise: f64,
    /// Rays traced for this vertex.
    pub rays: u64,
}

/// The noise energy of a Monte Carlo estimate `full` (a sum over N1 samples, `n1` of them)
/// from the part `odd` the odd-numbered samples added: the even and odd halves are independent
/// estimates (as sums scaled to N1 samples, `A = even N1 / n_even`, `B = odd N1 / n_odd`), so
/// `E|A - B|^2 = Var(sample) (1/n_even + 1/n_odd)`, and the full estimate's noise energy is
/// `Var(sample) / N1 = |A - B|^2 / (N1 (1/n_even + 1/n_odd))`. With the lattice of first
/// directions this overestimates the noise a little (a half-lattice converges more slowly than
/// the whole); docs/vertex.md, "What the error target means", measures it. 0 for N1 < 2.
pub fn half_noise(full: &[f64], odd: &[f64], n1: u32) -> f64 {
    if n1 < 2 {
        return 0.0;
    }
    let n = n1 as f64;
    let n_odd = (n1 / 2) as f64;
    let n_even = n - n_odd;
    let diff: f64 = full
        .iter()
        .zip(odd)
        .map(|(&f, &o)| {
            let (a, b) = ((f - o) * n / n_even, o * n / n_odd);
            (a - b) * (a - b)
        })
        .sum();
    diff / (n * (1.0 / n_even + 1.0 / n_odd))
}

impl VertexResult {
    /// The visible fractions as stored: `round(255 f)`.
    pub fn visibility_u8(&self) -> Vec<u8> {
        self.visibility
            .iter()
            .map(|f| (f * 255.0).round().clamp(0.0, 255.0) as u8)
            .collect()
    }
}

/// A path from a vertex that reached the environment after one reflection (T1) or two (T2),
/// as traced: what a test needs to project it independently.
#[doc(hidden)]
#[derive(Clone, Debug)]
pub struct EscapingPath {
    /// Sample index i (0..N1).
    pub sample: u32,
    /// w1 in the vertex frame.
    pub w1_local: Vec3,
    /// w1, world space.
    pub w1_world: Vec3,
    /// The material at y.
    pub y_material: u32,
    /// y's slot values for (wo = -w1, wi = w2), RGB.
    pub y_slots: Vec<Vec3>,
    /// w2, world space.
    pub w2_world: Vec3,
    /// The path adds `rho(y) * w2_weight / N2` (times w1's SH weight) to its light bin:
    /// `(w2 . n_y) / pdf(w2)` for a BRDF draw without bin sampling; with it (and for the bin
    /// draws), `N2 (w2 . n_y) / (p_bin(w2) + N2 pdf(w2))`, the balance heuristic.
    pub w2_weight: f32,
    /// For a T2 path: the reflection at z.
    pub second: Option<SecondBounce>,
}

/// The reflection at z of a T2 path.
#[doc(hidden)]
#[derive(Clone, Debug)]
pub struct SecondBounce {
    /// The material at z.
    pub z_material: u32,
    /// z's slot values for (wo = -w2, wi = w3).
    pub z_slots: Vec<Vec3>,
    /// w3, world space (it escapes).
    pub w3_world: Vec3,
    /// `(w3 . n_z) / pdf(w3)`.
    pub w3_weight: f32,
}

/// One escaping path as the walk reports it (borrowing the walk's slot buffers).
struct Bounce<'s> {
    sample: u32,
    w1_local: Vec3,
    w1_world: Vec3,
    y: &'s Slots,
    w2: Vec3,
    /// The weight `EscapingPath::w2_weight` documents.
    f2: f32,
    second: Option<(&'s Slots, Vec3, f32)>,
}

/// Traces vertices of a plan: the direct cube, each group's shading basis and slot maps.
pub struct VertexTracer<'a> {
    integ: &'a Integrator<'a>,
    plan: &'a VertexPlan,
    layout: &'a SlotLayout,
    model: BakeModel<'a>,
    opts: VertexBakeOptions,
    direct: DirectCube,
    /// Per group: the shading basis of its material's family, if it has a lobe.
    shading: Vec<Option<&'a ShadingBasis>>,
    /// Per group: global slot -> j (u32::MAX when inactive).
    active_index: Vec<Vec<u32>>,
    /// Global slot -> i of T2 (u32::MAX when not a T2 slot).
    t2_index: Vec<u32>,
    /// Per vertex: its group.
    vertex_group: Vec<Option<u32>>,
}

impl<'a> VertexTracer<'a> {
    /// A tracer for `plan`'s groups; `layout` must be the plan's ([`VertexPlan::layout`]),
    /// `shading` must hold a valid basis of every family with a lobe that a group uses.
    pub fn new(
        integ: &'a Integrator<'a>,
        plan: &'a VertexPlan,
        layout: &'a SlotLayout,
        shading: &'a [ShadingBasis],
        opts: &VertexBakeOptions,
    ) -> Result<VertexTracer<'a>, VertexError> {
        opts.validate()?;
        if layout.materials != plan.slots.materials {
            return Err(VertexError::Inconsistent(
                "the slot layout is not the plan's".into(),
            ));
        }
        let scene = integ.scene;
        let mut group_shading = Vec::with_capacity(plan.groups.len());
        for g in &plan.groups {
            let Some(family) = g.lobe else {
                group_shading.push(None);
                continue;
            };
            let Some(b) = shading.iter().find(|b| b.family == family) else {
                return Err(VertexError::MissingShading {
                    material: scene.materials[g.material as usize].name.clone(),
                    family,
                });
            };
            b.validate().map_err(|e| VertexError::BadShading {
                family,
                message: e.to_string(),
            })?;
            group_shading.push(Some(b));
        }
        let total = layout.total_slots;
        let active_index = plan
            .groups
            .iter()
            .map(|g| {
                let mut map = vec![u32::MAX; total];
                for (j, &s) in g.active.iter().enumerate() {
                    map[s as usize] = j as u32;
                }
                map
            })
            .collect();
        let mut t2_index = vec![u32::MAX; total];
        for (i, &s) in plan.t2_slots.iter().enumerate() {
            t2_index[s as usize] = i as u32;
        }
        let mut vertex_group = vec![None; scene.positions.len()];
        for (gi, g) in plan.groups.iter().enumerate() {
            for &v in &g.vertices {
                vertex_group[v as usize] = Some(gi as u32);
            }
        }
        let direct = DirectCube::new()?;
        Ok(VertexTracer {
            integ,
            plan,
            layout,
            model: BakeModel::new(scene, layout),
            opts: opts.clone(),
            direct,
            shading: group_shading,
            active_index,
            t2_index,
            vertex_group,
        })
    }

    /// The shading basis of group `g` (None for a diffuse material).
    pub fn group_shading(&self, g: usize) -> Option<&'a ShadingBasis> {
        self.shading[g]
    }

    /// The group of vertex `v`.
    pub fn group_of(&self, v: u32) -> Option<usize> {
        self.vertex_group
            .get(v as usize)
            .copied()
            .flatten()
            .map(|g| g as usize)
    }

    fn frame(&self, v: u32) -> VertexFrame {
        VertexFrame::new(
            self.integ.scene.positions[v as usize],
            self.plan.normals[v as usize],
            self.integ.eps(),
        )
    }

    /// Traces vertex `v`: T0 rows, visibility, T1 and T2, dense.
    pub fn trace(&self, v: u32) -> Result<VertexResult, VertexError> {
        let g = self.group_of(v).ok_or(VertexError::NoGroup { vertex: v })?;
        let frame = self.frame(v);
        let shading = self.shading[g];
        let (t0, t0_rows, t0_occluded, visibility, direct_rays) =
            self.direct.trace(self.integ.accel, &frame, shading);

        let c = self.plan.slots.channels;
        let jn = self.plan.groups[g].active.len();
        let i_n = self.plan.t2_slots.len();
        let mut t1 = vec![0.0f64; cube_len(T1_LIGHT_CUBE) * jn * SH_TERMS * c];
        let mut t2 = vec![0.0f64; cube_len(T2_LIGHT_CUBE) * jn * i_n * c];
        // What the odd-numbered samples add, for the noise estimate (`half_noise`).
        let mut t1_odd = vec![0.0f64; t1.len()];
        let mut t2_odd = vec![0.0f64; t2.len()];
        let j_of = &self.active_index[g];
        let n1 = self.opts.samples as f64;
        let n2 = self.opts.secondary as f64;
        let walk_rays = self.walk(v, &frame, |b| {
            let off_y = self.layout.materials[b.y.material as usize].slot_offset as usize;
            let f2 = b.f2 as f64 / n2;
            let odd = b.sample % 2 == 1;
            match b.second {
                None => {
                    // Monte Carlo SH projection over x's hemisphere (pdf 1/(2 pi)) of the
                    // radiance y reflects from unit radiance in bin l(w2).
                    let w = TAU / n1 * f2;
                    let sh = sh_eval(b.w1_local.as_dvec3().to_array());
                    let l = light_bin(T1_LIGHT_CUBE, b.w2);
                    for (k, val) in b.y.as_slice().iter().enumerate() {
                        let j = j_of[off_y + k];
                        if j == u32::MAX {
                            continue;
                        }
                        let base = (l * jn + j as usize) * SH_TERMS * c;
                        for (s, y_s) in sh.iter().enumerate() {
                            let a = w * y_s;
                            for ch in 0..c {
                                let x = a * val[ch] as f64;
                                t1[base + s * c + ch] += x;
                                if odd {
                                    t1_odd[base + s * c + ch] += x;
                                }
                            }
                        }
                    }
                }
                Some((z, w3, f3)) => {
                    // The uniform radiance of the same irradiance: (1/pi) integral I2 cos.
                    let w = b.w1_local.z as f64 / PI * (TAU / n1) * f2 * f3 as f64;
                    let off_z = self.layout.materials[z.material as usize].slot_offset as usize;
                    let l = light_bin(T2_LIGHT_CUBE, w3);
                    for (k, vy) in b.y.as_slice().iter().enumerate() {
                        let j = j_of[off_y + k];
                        if j == u32::MAX {
                            continue;
                        }
                        for (q, vz) in z.as_slice().iter().enumerate() {
                            let i = self.t2_index[off_z + q];
                            if i == u32::MAX {
                                continue;
                            }
                            let base = ((l * jn + j as usize) * i_n + i as usize) * c;
                            for ch in 0..c {
                                let x = w * (vy[ch] as f64 * vz[ch] as f64);
                                t2[base + ch] += x;
                                if odd {
                                    t2_odd[base + ch] += x;
                                }
                            }
                        }
                    }
                }
            }
        });
        if let Some(x) = t1.iter().chain(&t2).find(|x| !x.is_finite()) {
            return Err(VertexError::NonFinite {
                vertex: v,
                message: format!("T1 or T2 holds {x} (a material's BRDF or sampling density)"),
            });
        }
        Ok(VertexResult {
            vertex: v,
            group: g,
            t0_rows,
            t0,
            t0_occluded,
            visibility,
            t1_noise: half_noise(&t1, &t1_odd, self.opts.samples),
            t2_noise: half_noise(&t2, &t2_odd, self.opts.samples),
            t1: t1.iter().map(|&x| x as f32).collect(),
            t2: t2.iter().map(|&x| x as f32).collect(),
            rays: direct_rays + walk_rays,
        })
    }

    /// Every path of vertex `v` that reaches the environment after one or two reflections,
    /// in the order the bake accumulates them (for tests that project them independently).
    #[doc(hidden)]
    pub fn record_paths(&self, v: u32) -> Result<Vec<EscapingPath>, VertexError> {
        self.group_of(v).ok_or(VertexError::NoGroup { vertex: v })?;
        let frame = self.frame(v);
        let mut out = Vec::new();
        self.walk(v, &frame, |b| {
            out.push(EscapingPath {
                sample: b.sample,
                w1_local: b.w1_local,
                w1_world: b.w1_world,
                y_material: b.y.material,
                y_slots: b.y.as_slice().to_vec(),
                w2_world: b.w2,
                w2_weight: b.f2,
                second: b.second.map(|(z, w3, f3)| SecondBounce {
                    z_material: z.material,
                    z_slots: z.as_slice().to_vec(),
                    w3_world: w3,
                    w3_weight: f3,
                }),
            })
        });
        Ok(out)
    }

    /// The paths of T1 and T2 from vertex `v`: calls `visit` for each that escapes after one
    /// reflection (T1) or two (T2, three reflections only). Returns the rays traced.
    fn walk(&self, v: u32, frame: &VertexFrame, mut visit: impl FnMut(&Bounce)) -> u64 {
        let integ = self.integ;
        let accel = integ.accel;
        let eps = integ.eps();
        let three = self.opts.reflections >= 3;
        let bins = self.opts.light_bins;
        let n2 = self.opts.secondary as f32;
        let usable = |pdf: f32, f: f32| pdf > 0.0 && pdf.is_finite() && f.is_finite();
        let mut ys = Slots::EMPTY;
        let mut zs = Slots::EMPTY;
        let mut rays = 0u64;
        let first = FirstDirections::new(self.opts.seed, v, self.opts.samples);
        for i in 0..self.opts.samples {
            let mut rng = Rng::for_sample(self.opts.seed, v as u64, i as u64);
            let mut rng3 =
                three.then(|| Rng::for_sample(self.opts.seed, v as u64, W3_STREAM + i as u64));
            let w1_local = first.get(i);
            let w1 = frame.to_world(w1_local);
            rays += 1;
            let Some(hit) = accel.intersect(frame.origin, w1, 0.0, f32::INFINITY) else {
                continue;
            };
            let y = integ.surface(&hit, w1);
            let wo_y = y.to_local(-w1);
            if wo_y.z <= 0.0 || self.layout.materials[y.material as usize].slots.is_empty() {
                continue;
            }
            let y_origin = y.p + y.ng * eps;
            for _ in 0..self.opts.secondary {
                let bs = self.model.sample(&y, wo_y, &mut rng);
                // This w2's point of the w3 stream (what `sample` draws), used or not.
                let mut u3 = rng3.as_mut().map(|r| {
                    let before = r.clone();
                    r.next_vec2();
                    before
                });
                let Some(bs) = bs else { continue };
                let w2 = y.to_world(bs.wi).normalize();
                let f2 = bs.wi.z / bs.pdf;
                if bs.wi.z <= 0.0 || w2.dot(y.ng) <= 0.0 || !usable(bs.pdf, f2) {
                    continue;
                }
                self.model.eval(&y, 1, wo_y, bs.wi, &mut ys);
                rays += 1;
                let Some(hit2) = accel.intersect(y_origin, w2, 0.0, f32::INFINITY) else {
                    // T1 combines this sample with the bin draws (balance heuristic); T2's
                    // integrand is not binned by w2, so a w2 that hits z keeps `f2`.
                    let weight = if bins {
                        n2 * bs.wi.z / (bin_density(w2) + n2 * bs.pdf)
                    } else {
                        f2
                    };
                    visit(&Bounce {
                        sample: i,
                        w1_local,
                        w1_world: w1,
                        y: &ys,
                        w2,
                        f2: weight,
                        second: None,
                    });
                    continue;
                };
                let Some(rng3) = u3.as_mut() else {
                    continue;
                };
                let z = integ.surface(&hit2, w2);
                let wo_z = z.to_local(-w2);
                if wo_z.z <= 0.0 || self.layout.materials[z.material as usize].slots.is_empty() {
                    continue;
                }
                let Some(bs3) = self.model.sample(&z, wo_z, rng3) else {
                    continue;
                };
                let w3 = z.to_world(bs3.wi).normalize();
                let f3 = bs3.wi.z / bs3.pdf;
                if bs3.wi.z <= 0.0 || w3.dot(z.ng) <= 0.0 || !usable(bs3.pdf, f3) {
                    continue;
                }
                self.model.eval(&z, 2, wo_z, bs3.wi, &mut zs);
                rays += 1;
                if accel.occluded(z.p + z.ng * eps, w3, 0.0, f32::INFINITY) {
                    continue;
                }
                visit(&Bounce {
                    sample: i,
                    w1_local,
                    w1_world: w1,
                    y: &ys,
                    w2,
                    f2,
                    second: Some((&zs, w3, f3)),
                });
            }
            if !bins {
                continue;
            }
            // One draw in every light bin above y's horizon, 2 numbers per bin whether or not
            // it is traced, from the sample's own bin stream.
            let mut rng_bins = Rng::for_sample(self.opts.seed, v as u64, BIN_STREAM + i as u64);
            for bin in 0..cube_len(T1_LIGHT_CUBE) {
                let u = rng_bins.next_vec2();
                let Some((w2, p_bin)) = sample_bin(bin, u) else {
                    break;
                };
                let wi = y.to_local(w2);
                if wi.z <= 0.0 || w2.dot(y.ng) <= 0.0 {
                    continue;
                }
                let weight = n2 * wi.z / (p_bin + n2 * self.model.pdf(&y, wo_y, wi));
                if !weight.is_finite() {
                    continue;
                }
                rays += 1;
                if accel.occluded(y_origin, w2, 0.0, f32::INFINITY) {
                    continue;
                }
                self.model.eval(&y, 1, wo_y, wi, &mut ys);
                visit(&Bounce {
                    sample: i,
                    w1_local,
                    w1_world: w1,
                    y: &ys,
                    w2,
                    f2: weight,
                    second: None,
                });
            }
        }
        rays
    }

    /// T0's rows of a traced vertex, area-weighted-Haar transformed, each truncated to its
    /// `t0_terms` largest terms padded with (index 0, value 0), the irradiance row visible or
    /// occluded, whichever drops less (`direct.rs`).
    /// The transform is orthonormal in the solid-angle metric, so `sum_t C0[index_t]
    /// value_t` is `integral L T0~ dw` for a light whose Haar coefficients are C0.
    pub fn haar_terms(&self, r: &VertexResult) -> Result<super::direct::HaarTerms, VertexError> {
        self.direct
            .haar_terms(r.vertex, &r.t0, &r.t0_occluded, self.opts.t0_terms)
    }
}
