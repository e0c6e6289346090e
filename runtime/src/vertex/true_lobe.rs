//! The true BRDF at the last reflection: a measurement switch of the error budget
//! (`VertexRelighter::set_true_lobe`, feature `hooks`).
//!
//! The view stage shades a glossy pixel's specular part with the Tucker shading basis and the
//! specular split (`shade.rs`). With this switch it integrates the material's true lobe
//! instead, by Monte Carlo over directions the caller's sampler draws, against the same
//! incident light the basis sees: the environment times the vertices' visible fraction (the
//! 6x16x16 cubes, interpolated), plus I1's order-4 SH and I2. The two images then differ by
//! the shading basis alone (its Tucker truncation, the split's Gaussians, where they are read,
//! the incident projections' interpolation), which no other part of the budget isolates.
//! The runtime cannot evaluate the true lobes itself (they live with the baker, which it does
//! not depend on), hence the caller's [`TrueLobe`].

use prt_formats::envmap::LatLongMap;
use prt_formats::latlong::{direction_to_uv, uv_to_direction, uv_to_texel};
use prt_formats::Family;

/// A family's true specular lobe (`Ks = 1`, no `Kd`), as the budget's caller gives it.
pub trait TrueLobe: Send + Sync {
    /// A direction `wi` (local frame, normal `+z`) drawn for the view `wo` (local, above the
    /// horizon) from the uniform pair `u` (`None`: no direction, e.g. below the horizon).
    fn sample(&self, family: Family, param: f32, wo: [f32; 3], u: [f32; 2]) -> Option<[f32; 3]>;
    /// `f(wo, wi) cos(wi)` and the density (per solid angle) with which [`TrueLobe::sample`]
    /// draws `wi`.
    fn eval(&self, family: Family, param: f32, wo: [f32; 3], wi: [f32; 3]) -> (f32, f32);
}

/// Draws directions of a lat-long map in proportion to the light each texel sends (its
/// luminance times its solid angle), so that a sun smaller than the lobe is found: the true
/// lobe's integral combines these draws with the lobe's own (multiple importance sampling,
/// the balance heuristic), as a path tracer does.
pub(super) struct EnvSampler {
    width: usize,
    height: usize,
    /// Cumulative probabilities of the texels (row-major), the last 1.
    cdf: Vec<f64>,
    /// Per texel, its probability over its solid angle: the density of its directions.
    density: Vec<f32>,
}

impl EnvSampler {
    /// `None` for a black map (nothing to draw towards).
    pub(super) fn new(map: &LatLongMap) -> Option<EnvSampler> {
        let (w, h) = (map.width, map.height);
        let pi = std::f64::consts::PI;
        let solid_angle = |y: usize| {
            let c0 = (pi * y as f64 / h as f64).cos();
            let c1 = (pi * (y + 1) as f64 / h as f64).cos();
            2.0 * pi / w as f64 * (c0 - c1)
        };
        let lum: Vec<f64> = map
            .texels
            .iter()
            .map(|t| {
                (0.2126 * f64::from(t[0]) + 0.7152 * f64::from(t[1]) + 0.0722 * f64::from(t[2]))
                    .max(0.0)
            })
            .collect();
        // The map is read bilinearly, so a texel's square also shows its neighbours' light
        // (a one-texel sun lights the four squares around its centre): each square is drawn
        // by the brightest of its 3 x 3 neighbourhood (wrapping in u), or a sun's bilinear
        // skirt would be drawn as rarely as the sky beside it and its light would come in
        // rare, huge samples.
        let mut weights: Vec<f64> = Vec::with_capacity(w * h);
        for y in 0..h {
            for x in 0..w {
                let mut m = 0.0f64;
                for yy in y.saturating_sub(1)..=(y + 1).min(h - 1) {
                    for dx in [w - 1, 0, 1] {
                        m = m.max(lum[yy * w + (x + dx) % w]);
                    }
                }
                weights.push(m * solid_angle(y));
            }
        }
        let total: f64 = weights.iter().sum();
        if total <= 0.0 || !total.is_finite() {
            return None;
        }
        let mut acc = 0.0;
        let mut cdf = Vec::with_capacity(w * h);
        let mut density = Vec::with_capacity(w * h);
        for (k, wt) in weights.iter().enumerate() {
            acc += wt / total;
            cdf.push(acc);
            density.push((wt / total / solid_angle(k / w)) as f32);
        }
        if let Some(last) = cdf.last_mut() {
            *last = 1.0;
        }
        Some(EnvSampler {
            width: w,
            height: h,
            cdf,
            density,
        })
    }

    /// A direction of the map's own frame drawn from `u`, uniform in solid angle over its
    /// texel, and its density.
    fn sample(&self, u: [f32; 2]) -> ([f32; 3], f32) {
        let u0 = f64::from(u[0]);
        let k = self
            .cdf
            .partition_point(|&c| c <= u0)
            .min(self.cdf.len() - 1);
        let lo = if k == 0 { 0.0 } else { self.cdf[k - 1] };
        let t = ((u0 - lo) / (self.cdf[k] - lo).max(1e-300)).clamp(0.0, 1.0) as f32;
        let (x, y) = (k % self.width, k / self.width);
        let h = self.height as f32;
        let pi = std::f32::consts::PI;
        let (c0, c1) = ((pi * y as f32 / h).cos(), (pi * (y + 1) as f32 / h).cos());
        let cos_theta = c0 + (c1 - c0) * u[1];
        let v = cos_theta.clamp(-1.0, 1.0).acos() / pi;
        let d = uv_to_direction((x as f32 + t) / self.width as f32, v);
        (d, self.density[k])
    }

    /// The density of [`EnvSampler::sample`] at the map-frame direction `d`.
    fn density(&self, d: [f32; 3]) -> f32 {
        let (u, v) = direction_to_uv(d);
        let (x, y) = uv_to_texel(u, v, self.width, self.height);
        self.density[y * self.width + x]
    }
}

/// The switch as the view stage reads it: the lobe, the samples per pixel and the
/// environment's sampler.
#[derive(Clone, Copy)]
pub(super) struct TrueLobeSwitch<'a> {
    pub lobe: &'a dyn TrueLobe,
    /// Per side of the stratified grid of each strategy (draws per pixel: twice its square).
    pub side: u32,
    /// The lighting map's sampler (`None`: the map is black, lobe draws only).
    pub env: Option<&'a EnvSampler>,
}

impl TrueLobeSwitch<'_> {
    /// The light the true lobe of `(family, param)` reflects towards `wo` (local) at a pixel: `side x side`
    /// stratified draws of the lobe and as many of the map, combined by the balance
    /// heuristic, each grid shifted per pixel by `seed` (Cranley-Patterson) so neighbouring
    /// pixels' errors do not line up. `incident(wi)` is the incident radiance from a local
    /// direction, `to_map` and `from_map` turn local directions into the map's frame and back.
    pub(super) fn reflected(
        &self,
        (family, param): (Family, f32),
        wo: [f32; 3],
        seed: u32,
        incident: impl Fn([f32; 3]) -> [f32; 3],
        to_map: impl Fn([f32; 3]) -> [f32; 3],
        from_map: impl Fn([f32; 3]) -> [f32; 3],
    ) -> [f32; 3] {
        let n = self.side.max(1);
        let step = 1.0 / n as f32;
        let mut sum = [0.0f64; 3];
        let mut add = |wi: [f32; 3], f_cos: f32, pdf_sum: f32| {
            if wi[2] <= 0.0 || pdf_sum.is_nan() || pdf_sum <= 0.0 || !f_cos.is_finite() {
                return;
            }
            let l = incident(wi);
            for c in 0..3 {
                sum[c] += f64::from(f_cos) * f64::from(l[c]) / f64::from(pdf_sum);
            }
        };
        let env_density = |wi: [f32; 3]| self.env.map_or(0.0, |e| e.density(to_map(wi)));
        for (strategy, salt) in [(0u32, 0u32), (1, 0x5bd1_e995)] {
            if strategy == 1 && self.env.is_none() {
                break;
            }
            let shift = [
                unit(hash(seed ^ salt)),
                unit(hash(seed ^ salt ^ 0x9e37_79b9)),
            ];
            for j in 0..n {
                for i in 0..n {
                    let u = [
                        ((i as f32 + 0.5) * step + shift[0]).fract(),
                        ((j as f32 + 0.5) * step + shift[1]).fract(),
                    ];
                    let wi = match (strategy, self.env) {
                        (0, _) => self.lobe.sample(family, param, wo, u),
                        (_, Some(env)) => Some(from_map(env.sample(u).0)),
                        _ => None,
                    };
                    let Some(wi) = wi else { continue };
                    if wi[2] <= 0.0 {
                        continue;
                    }
                    let (f_cos, pdf) = self.lobe.eval(family, param, wo, wi);
                    add(wi, f_cos, pdf + env_density(wi));
                }
            }
        }
        let count = f64::from(n * n);
        sum.map(|v| (v / count) as f32)
    }
}
/// A 32-bit integer hash (Wellons' lowbias32).
fn hash(mut x: u32) -> u32 {
    x ^= x >> 16;
    x = x.wrapping_mul(0x7feb_352d);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846c_a68b);
    x ^= x >> 16;
    x
}

/// `x` as a float in `[0, 1)`.
fn unit(x: u32) -> f32 {
    (x >> 8) as f32 / (1u32 << 24) as f32
}
