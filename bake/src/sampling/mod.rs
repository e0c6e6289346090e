//! Deterministic random streams and sampling utilities.
//!
//! Every random number a path uses comes from a stream keyed by (seed, pixel, sample), so a
//! render or bake is identical whatever the thread count or scheduling: no stream is shared
//! between pixels. The baker and the reference tracer draw from the same streams in the same
//! order, which is what makes the bake-vs-reference exactness test possible.

/// Longest path in reflections: what the path samplers prepare draws for (`sobol.rs` sizes its
/// tables by it), the integrator's limit and the config's (`reflections`).
pub const MAX_REFLECTIONS: usize = 4;
/// Largest accepted samples per pixel (or directions per vertex, N1).
pub const MAX_SPP: u32 = 1 << 20;
/// Default samples per pixel (or directions per vertex, N1).
pub const DEFAULT_SPP: u32 = 64;

mod sobol;

pub use sobol::{PathSampler, PixelSampler};

use glam::{Vec2, Vec3};

/// A source of uniform numbers in [0, 1): what BRDF and light sampling draw from. The camera
/// paths draw from a [`PathSampler`] (stratified over a pixel's samples), the per-vertex
/// baker from an [`Rng`].
pub trait Draw {
    fn next_f32(&mut self) -> f32;
    fn next_vec2(&mut self) -> Vec2;
}

impl Draw for Rng {
    #[inline]
    fn next_f32(&mut self) -> f32 {
        Rng::next_f32(self)
    }
    #[inline]
    fn next_vec2(&mut self) -> Vec2 {
        Rng::next_vec2(self)
    }
}

impl Draw for PathSampler<'_> {
    #[inline]
    fn next_f32(&mut self) -> f32 {
        PathSampler::next_f32(self)
    }
    #[inline]
    fn next_vec2(&mut self) -> Vec2 {
        PathSampler::next_vec2(self)
    }
}

/// The largest f32 below 1.
const ONE_MINUS_EPS: f32 = 1.0 - f32::EPSILON / 2.0;

/// Picks component i of a mixture with probability `weights[i]` (non-negative, summing to 1)
/// from a uniform `u`, and returns `u` rescaled to [0, 1) within the picked interval.
///
/// Why one number does both: the camera paths' 2D draws are stratified over a pixel's samples,
/// and a separate uniform choosing the component would hand each component a random subset of
/// the strata, losing most of the stratification (measured: a relit bake, whose sampling
/// mixture has four components, had 1.3x a fresh render's error even with no edit). With the
/// choice made from the draw's first coordinate, each component gets the points of a strip of
/// the square, which stay stratified once rescaled. (The same as [`Distribution1D::sample`]
/// for a handful of fixed weights: a linear scan, no table.)
#[inline]
pub fn pick_component(u: f32, weights: &[f32]) -> (usize, f32) {
    let last = weights.len().saturating_sub(1);
    let mut lo = 0.0;
    for (i, &w) in weights.iter().enumerate() {
        if i == last || u < lo + w {
            let r = if w > 0.0 { (u - lo) / w } else { u };
            return (i, r.clamp(0.0, ONE_MINUS_EPS));
        }
        lo += w;
    }
    (0, u)
}

/// SplitMix64 finaliser: a good 64-bit mix for deriving stream seeds from keys.
#[inline]
pub fn mix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// PCG-XSH-RR 32-bit generator (O'Neill 2014) with a per-stream increment.
#[derive(Clone, Debug)]
pub struct Rng {
    state: u64,
    inc: u64,
}

impl Rng {
    /// The stream for one sample of one pixel (or vertex) of a run with `seed`.
    pub fn for_sample(seed: u64, pixel: u64, sample: u64) -> Rng {
        let a = mix64(seed ^ mix64(pixel.wrapping_mul(0xD134_2543_DE82_EF95)));
        let b = mix64(a ^ sample.wrapping_mul(0xA24B_AED4_963E_E407));
        let mut rng = Rng {
            state: 0,
            inc: (mix64(b ^ 0x5851_F42D_4C95_7F2D) << 1) | 1,
        };
        rng.next_u32();
        rng.state = rng.state.wrapping_add(b);
        rng.next_u32();
        rng
    }

    #[inline]
    pub fn next_u32(&mut self) -> u32 {
        let old = self.state;
        self.state = old
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(self.inc);
        let xorshifted = (((old >> 18) ^ old) >> 27) as u32;
        let rot = (old >> 59) as u32;
        xorshifted.rotate_right(rot)
    }

    /// Uniform in [0, 1): 24 random bits, so the result is never rounded up to 1.
    #[inline]
    pub fn next_f32(&mut self) -> f32 {
        (self.next_u32() >> 8) as f32 * (1.0 / 16_777_216.0)
    }

    /// Uniform in [0, 1) with 53 random bits (two draws), for f64 estimators.
    #[inline]
    pub fn next_f64(&mut self) -> f64 {
        let hi = (self.next_u32() >> 5) as u64; // 27 bits
        let lo = (self.next_u32() >> 6) as u64; // 26 bits
        ((hi << 26) | lo) as f64 * (1.0 / 9_007_199_254_740_992.0)
    }

    #[inline]
    pub fn next_vec2(&mut self) -> Vec2 {
        let x = self.next_f32();
        Vec2::new(x, self.next_f32())
    }
}

/// Uniform point on a triangle as barycentric weights (b1, b2) of vertices 1 and 2.
#[inline]
pub fn uniform_triangle(u: Vec2) -> Vec2 {
    // Square-root parameterization: area preserving.
    let su = u.x.sqrt();
    Vec2::new(su * (1.0 - u.y), su * u.y)
}

/// Uniform direction on the unit sphere.
#[inline]
pub fn uniform_sphere(u: Vec2) -> Vec3 {
    let z = 1.0 - 2.0 * u.x;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = 2.0 * std::f32::consts::PI * u.y;
    Vec3::new(r * phi.cos(), r * phi.sin(), z)
}

/// A piecewise-constant 1D distribution over `n` bins, sampled by inverting its CDF.
#[derive(Clone, Debug)]
pub struct Distribution1D {
    /// cdf[0] = 0, cdf[n] = 1.
    cdf: Vec<f64>,
    /// Normalised probabilities per bin.
    pmf: Vec<f32>,
    total: f64,
}

impl Distribution1D {
    /// `None` when there is no bin with positive finite weight.
    pub fn new(weights: &[f32]) -> Option<Distribution1D> {
        let mut cdf = Vec::with_capacity(weights.len() + 1);
        cdf.push(0.0f64);
        let mut total = 0.0f64;
        for &w in weights {
            if w.is_finite() && w > 0.0 {
                total += w as f64;
            }
            cdf.push(total);
        }
        if total <= 0.0 || !total.is_finite() {
            return None;
        }
        for c in cdf.iter_mut() {
            *c /= total;
        }
        let pmf = weights
            .iter()
            .map(|&w| {
                if w.is_finite() && w > 0.0 {
                    (w as f64 / total) as f32
                } else {
                    0.0
                }
            })
            .collect();
        Some(Distribution1D { cdf, pmf, total })
    }

    pub fn len(&self) -> usize {
        self.pmf.len()
    }

    pub fn is_empty(&self) -> bool {
        self.pmf.is_empty()
    }

    /// Sum of the input weights.
    pub fn total(&self) -> f64 {
        self.total
    }

    /// Probability of bin `i`.
    #[inline]
    pub fn pmf(&self, i: usize) -> f32 {
        self.pmf.get(i).copied().unwrap_or(0.0)
    }

    /// Picks a bin with probability pmf; returns (bin, offset within the bin in [0,1)).
    #[inline]
    pub fn sample(&self, u: f32) -> (usize, f32) {
        let u = u as f64;
        // First index whose cdf exceeds u, minus one; skips zero-probability bins.
        let mut lo = 0usize;
        let mut hi = self.pmf.len();
        while lo + 1 < hi {
            let mid = (lo + hi) / 2;
            if self.cdf[mid] <= u {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        while self.pmf[lo] == 0.0 && lo + 1 < self.pmf.len() {
            lo += 1;
        }
        let width = self.cdf[lo + 1] - self.cdf[lo];
        let offset = if width > 0.0 {
            ((u - self.cdf[lo]) / width).clamp(0.0, 0.999_999_9)
        } else {
            0.5
        };
        (lo, offset as f32)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Evenly spaced numbers split by `pick_component` (and by `Distribution1D::sample`, which
    /// the area lights use the same way) stay evenly spaced within each component: each
    /// component gets its share, and its rescaled numbers are spaced 1 / share apart over
    /// [0, 1), so the strata of a stratified draw survive the choice.
    #[test]
    fn picking_a_component_keeps_stratification() {
        let weights = [0.4f32, 0.3, 0.15, 0.15];
        let dist = Distribution1D::new(&weights).expect("positive weights");
        let n = 1000;
        let by_pick = |u: f32| pick_component(u, &weights);
        let by_table = |u: f32| dist.sample(u);
        for pick in [&by_pick as &dyn Fn(f32) -> (usize, f32), &by_table] {
            let mut rescaled = vec![Vec::new(); weights.len()];
            for i in 0..n {
                let (k, x) = pick((i as f32 + 0.5) / n as f32);
                assert!((0.0..1.0).contains(&x), "{x}");
                rescaled[k].push(x);
            }
            for (k, xs) in rescaled.iter().enumerate() {
                let want = weights[k] as f64 * n as f64;
                assert!(
                    (xs.len() as f64 - want).abs() <= 1.0,
                    "component {k}: {}",
                    xs.len()
                );
                let gap = 1.0 / xs.len() as f32;
                assert!(
                    xs[0] < gap && xs[xs.len() - 1] > 1.0 - gap,
                    "component {k}: ends"
                );
                for w in xs.windows(2) {
                    assert!(
                        (w[1] - w[0] - gap).abs() < 1e-3 * gap + 1e-5,
                        "component {k}"
                    );
                }
            }
        }
        // Zero weights are never picked; the top of [0, 1) stays inside.
        assert_eq!(pick_component(0.3, &[0.0, 1.0]), (1, 0.3));
        assert_eq!(pick_component(0.3, &[1.0, 0.0]).0, 0);
        let (k, x) = pick_component(ONE_MINUS_EPS, &[0.5, 0.5]);
        assert!(k == 1 && x < 1.0);
    }
}
