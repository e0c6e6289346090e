//! The reference path tracer: renders the camera view with the true BRDFs for an exact number
//! of reflections, using the shared [`Integrator`], so it is the ground truth for a bake with
//! the same reflection count.

use std::time::Instant;

use glam::Vec3;
use rayon::prelude::*;

use crate::brdf::{BrdfParams, BrdfSample};
use crate::integrator::{Integrator, MaterialModel, PathSink, Slots, Surface};
use crate::progress::{Progress, Stage};
use crate::sampling::{Draw, PixelSampler};
use crate::scene::Scene;

/// Every material with its true BRDF (base-colour texture applied to Kd): one slot per vertex,
/// sampled by the BRDF's own importance sampling.
pub struct TrueBrdfModel<'a> {
    scene: &'a Scene,
    brdfs: Vec<BrdfParams>,
}

impl<'a> TrueBrdfModel<'a> {
    /// Uses the BRDFs of the scene's materials.
    pub fn new(scene: &'a Scene) -> Self {
        let brdfs = scene.materials.iter().map(|m| m.brdf).collect();
        TrueBrdfModel { scene, brdfs }
    }

    /// Uses the given BRDF per material (same order as `scene.materials`).
    pub fn with_brdfs(scene: &'a Scene, brdfs: Vec<BrdfParams>) -> Self {
        TrueBrdfModel { scene, brdfs }
    }

    #[inline]
    fn brdf_at(&self, s: &Surface) -> BrdfParams {
        let m = s.material as usize;
        self.scene.brdf_at(m, self.brdfs[m], s.uv)
    }
}

impl MaterialModel for TrueBrdfModel<'_> {
    #[inline]
    fn eval(&self, s: &Surface, _depth: usize, wo: Vec3, wi: Vec3, out: &mut Slots) {
        out.material = s.material;
        out.len = 1;
        out.values[0] = self.brdf_at(s).eval(wo, wi);
    }

    #[inline]
    fn sample<D: Draw>(&self, s: &Surface, wo: Vec3, rng: &mut D) -> Option<BrdfSample> {
        self.brdf_at(s).sample(wo, rng.next_vec2())
    }

    #[inline]
    fn pdf(&self, s: &Surface, wo: Vec3, wi: Vec3) -> f32 {
        self.brdf_at(s).pdf(wo, wi)
    }
}

/// Contracts each path's slot values with per-material coefficients into one colour.
pub struct ContractSink<'a> {
    /// `coefficients[material][slot]`, RGB.
    pub coefficients: &'a [Vec<Vec3>],
    /// What the paths reflected towards the camera.
    pub reflected: Vec3,
    /// What the camera saw directly (non-finite values dropped, as the bake drops them).
    pub emission: Vec3,
    pub first_material: Option<u32>,
}

impl<'a> ContractSink<'a> {
    pub fn new(coefficients: &'a [Vec<Vec3>]) -> Self {
        ContractSink {
            coefficients,
            reflected: Vec3::ZERO,
            emission: Vec3::ZERO,
            first_material: None,
        }
    }

    /// The camera sample's radiance: reflected plus directly seen.
    pub fn value(&self) -> Vec3 {
        self.reflected + self.emission
    }

    #[inline]
    fn contract(&self, s: &Slots) -> Vec3 {
        let c = &self.coefficients[s.material as usize];
        s.as_slice()
            .iter()
            .zip(c.iter())
            .fold(Vec3::ZERO, |acc, (v, c)| acc + *v * *c)
    }
}

impl PathSink for ContractSink<'_> {
    fn camera_emission(&mut self, radiance: Vec3) {
        if radiance.is_finite() {
            self.emission += radiance;
        }
    }

    fn first_hit(&mut self, surface: &Surface) {
        self.first_material = Some(surface.material);
    }

    #[inline]
    fn path(&mut self, prefix: &[Slots], last: &Slots, weight: Vec3) {
        let mut v = weight * self.contract(last);
        for s in prefix {
            v *= self.contract(s);
        }
        if v.is_finite() {
            self.reflected += v;
        }
    }
}

/// Coefficients that select the single true-BRDF slot of every material.
pub fn unit_coefficients(material_count: usize) -> Vec<Vec<Vec3>> {
    vec![vec![Vec3::ONE]; material_count]
}

/// An image with the figures of the run that made it.
#[derive(Clone, Debug)]
pub struct Render {
    pub width: u32,
    pub height: u32,
    /// Row-major, top row first, linear RGB radiance.
    pub pixels: Vec<Vec3>,
    pub spp: u32,
    pub rays: u64,
    pub seconds: f64,
    /// Mean radiance of the camera samples whose first hit is each material (None when the
    /// material covers no sample), and the number of such samples.
    pub material_means: Vec<(Option<Vec3>, u64)>,
    /// Mean radiance of samples that hit nothing.
    pub background_mean: (Option<Vec3>, u64),
}

impl Render {
    pub fn mean(&self) -> Vec3 {
        self.pixels.iter().copied().sum::<Vec3>() / self.pixels.len().max(1) as f32
    }
}

/// Renders `integrator`'s view with `model`, contracting with `coefficients`, `spp` samples per
/// pixel (what the camera sees directly with `emission_oversampling` times as many,
/// `crate::film_emission`), streams keyed by `seed`. Deterministic for any thread
/// count: each pixel owns its streams and pixels are reduced in a fixed order.
pub fn render<M: MaterialModel>(
    integrator: &Integrator,
    model: &M,
    coefficients: &[Vec<Vec3>],
    spp: u32,
    emission_oversampling: u32,
    seed: u64,
    progress: Option<&dyn Progress>,
) -> Render {
    let start = Instant::now();
    let (w, h) = (integrator.width, integrator.height);
    let nmat = integrator.scene.materials.len();
    struct RowOut {
        pixels: Vec<Vec3>,
        rays: u64,
        sums: Vec<(Vec3, u64)>,
    }
    let plan = integrator.emission_plan(emission_oversampling);
    let stage = Stage::start(progress, "rendering", h as u64);
    let rows: Vec<RowOut> = (0..h)
        .into_par_iter()
        .map(|y| {
            let mut out = RowOut {
                pixels: Vec::with_capacity(w as usize),
                rays: 0,
                sums: vec![(Vec3::ZERO, 0); nmat + 1],
            };
            // One per row: it keeps the shuffle tables' memory between pixels.
            let mut sampler = PixelSampler::new(spp, integrator.draws_per_sample());
            for x in 0..w {
                let pixel = y as u64 * w as u64 + x as u64;
                let mut reflected = Vec3::ZERO;
                let mut emission = Vec3::ZERO;
                sampler.start(seed, pixel);
                for s in 0..spp {
                    let mut rng = sampler.sample(s);
                    let mut sink = ContractSink::new(coefficients);
                    out.rays += integrator.trace_sample(model, &mut sink, x, y, &mut rng) as u64;
                    reflected += sink.reflected;
                    emission += sink.emission;
                    let bucket = sink.first_material.map_or(nmat, |m| m as usize);
                    out.sums[bucket].0 += sink.value();
                    out.sums[bucket].1 += 1;
                }
                // The same sums and scalings as the pixel bake, so that relighting matches
                // this render to float rounding.
                let oversampling = plan.oversampling(x, y);
                let (emission, rays) =
                    integrator.pixel_emission(&sampler, x, y, spp, oversampling, emission);
                out.rays += rays;
                out.pixels
                    .push(reflected * (1.0 / spp.max(1) as f32) + emission);
            }
            stage.advance(1);
            out
        })
        .collect();
    drop(stage);
    let mut pixels = Vec::with_capacity((w * h) as usize);
    let mut rays = plan.probe_rays();
    let mut sums = vec![(glam::DVec3::ZERO, 0u64); nmat + 1];
    for r in rows {
        pixels.extend(r.pixels);
        rays += r.rays;
        for (acc, (v, n)) in sums.iter_mut().zip(r.sums) {
            acc.0 += v.as_dvec3();
            acc.1 += n;
        }
    }
    let mean = |(v, n): (glam::DVec3, u64)| ((n > 0).then(|| (v / n as f64).as_vec3()), n);
    let background_mean = mean(sums[nmat]);
    let material_means = sums[..nmat].iter().map(|&s| mean(s)).collect();
    Render {
        width: w,
        height: h,
        pixels,
        spp,
        rays,
        seconds: start.elapsed().as_secs_f64(),
        material_means,
        background_mean,
    }
}

/// The ground truth in one call: builds the ray-query structure and lights for `scene` and
/// renders its camera view `width` x `height` with the true BRDFs, `reflections` reflections,
/// `spp` samples per pixel (what the camera sees directly with `emission_oversampling` times
/// as many) and streams keyed by `seed`.
#[allow(clippy::too_many_arguments)]
pub fn render_true(
    scene: &Scene,
    reflections: usize,
    width: u32,
    height: u32,
    spp: u32,
    emission_oversampling: u32,
    seed: u64,
    progress: Option<&dyn Progress>,
) -> Render {
    let accel = crate::accel::Accel::build(scene);
    let lights = crate::lights::LightSet::new(scene);
    let integ = Integrator::new(scene, &accel, &lights, reflections, width, height);
    let model = TrueBrdfModel::new(scene);
    render(
        &integ,
        &model,
        &unit_coefficients(scene.materials.len()),
        spp,
        emission_oversampling,
        seed,
        progress,
    )
}
