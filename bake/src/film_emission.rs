//! What the camera sees directly (an emitter, the environment), estimated with more film
//! samples than the paths in the pixels where it varies: the reference tracer and the pixel
//! bake both call [`Integrator::emission_plan`] once and [`Integrator::pixel_emission`] per
//! pixel, so their images agree to float rounding.
//!
//! Why: where a bright emitter's edge crosses a pixel, the pixel's value is mostly the
//! fraction of its area the emitter covers, estimated by where the film samples land. On the
//! comparison's Cornell box, 100 such pixels (of 65536) held two thirds of a 256-spp render's
//! variance. A camera ray that only looks for emission is cheap (no shading, no light
//! sampling), and stratified film points estimate an edge's coverage with an error falling
//! faster than 1/sqrt(n) (docs/pixel.md, "Oversampled emission").
//!
//! Why a plan: rays through the corners of every pixel, traced once before the pixels, decide
//! which pixels get the extra samples. The decision never looks at a pixel's random samples,
//! so each pixel's average stays unbiased whatever it decides (a wrong decision costs only
//! variance), and pixels whose emission is constant (a wall, an evenly lit sky) pay nothing.

use glam::Vec3;
use rayon::prelude::*;

use crate::integrator::Integrator;
use crate::sampling::PixelSampler;

/// Camera samples per path sample, in pixels where what the camera sees directly varies: the
/// default of the config's `emission_oversampling`. Measured on the comparison's Cornell box
/// (docs/compare.md, "2026-11-26 (late night)").
pub const DEFAULT_EMISSION_OVERSAMPLING: u32 = 8;

/// Corner values differing by more than this share of the largest (in any channel) mark a
/// pixel whose emission varies. An emitter's or the sky's edge against a surface differs by
/// all of it; a smooth sky by a few percent, which stratified film points already integrate
/// almost exactly. Measured on `scenes/vitrine` rendered per pixel (sky map, 128 x 128,
/// 64 spp): 1 % flagged a third of the pixels, for 28 % more time and the same noise; 5 %,
/// 10 % and 25 % flagged 2.9 %, 1.4 % and 1.4 % (the objects' outlines), the same noise, no
/// measurable time. On the comparison's Cornell box 1 % and 25 % flag the same pixels.
const VARIES_ABOVE: f32 = 0.25;

/// Which pixels take extra emission samples (see the module comment).
#[derive(Clone, Debug)]
pub struct EmissionPlan {
    width: u32,
    oversampling: u32,
    /// Per pixel, row-major: whether its corners saw different emission.
    varies: Vec<bool>,
    probe_rays: u64,
}

impl EmissionPlan {
    /// The film-sample multiple of pixel (x, y): `oversampling` where its emission varies,
    /// else 1.
    #[inline]
    pub fn oversampling(&self, x: u32, y: u32) -> u32 {
        let i = y as usize * self.width as usize + x as usize;
        if self.varies.get(i).copied().unwrap_or(false) {
            self.oversampling
        } else {
            1
        }
    }

    /// Rays the plan traced.
    pub fn probe_rays(&self) -> u64 {
        self.probe_rays
    }

    /// Pixels that take extra samples.
    pub fn oversampled_pixels(&self) -> usize {
        self.varies.iter().filter(|&&v| v).count()
    }
}

/// True when the values differ by more than [`VARIES_ABOVE`] of the largest.
fn varies(values: [Vec3; 4]) -> bool {
    let (lo, hi) = values[1..]
        .iter()
        .fold((values[0], values[0]), |(lo, hi), v| {
            (lo.min(*v), hi.max(*v))
        });
    (hi - lo).max_element() > VARIES_ABOVE * hi.max_element()
}

impl Integrator<'_> {
    /// Radiance the camera sees directly through film point (x, y) (pixels, y down): what an
    /// emitter or the environment sends along the ray, zero where it sees a surface that does
    /// not emit. One ray, nothing shaded.
    pub fn direct_view(&self, x: f32, y: f32) -> Vec3 {
        let (origin, dir) = self.camera_ray(x, y);
        match self.accel.intersect(origin, dir, 0.0, f32::INFINITY) {
            None => self.lights.environment_radiance(dir),
            Some(hit) => self
                .hit_emission(hit.triangle, hit.bary, dir)
                .map_or(Vec3::ZERO, |(le, _)| le),
        }
    }

    /// The plan for `oversampling` times the film samples where emission varies: one ray
    /// through each pixel corner ((width + 1) x (height + 1) rays, rows in parallel, the same
    /// answer on any thread count); none when `oversampling` is 1.
    pub fn emission_plan(&self, oversampling: u32) -> EmissionPlan {
        let (w, h) = (self.width, self.height);
        if oversampling <= 1 {
            return EmissionPlan {
                width: w,
                oversampling: 1,
                varies: Vec::new(),
                probe_rays: 0,
            };
        }
        let corners: Vec<Vec<Vec3>> = (0..=h)
            .into_par_iter()
            .map(|y| {
                (0..=w)
                    .map(|x| {
                        let le = self.direct_view(x as f32, y as f32);
                        // Non-finite values count as zero, as the sinks count them.
                        if le.is_finite() {
                            le
                        } else {
                            Vec3::ZERO
                        }
                    })
                    .collect()
            })
            .collect();
        let mut flags = Vec::with_capacity(w as usize * h as usize);
        for y in 0..h as usize {
            for x in 0..w as usize {
                flags.push(varies([
                    corners[y][x],
                    corners[y][x + 1],
                    corners[y + 1][x],
                    corners[y + 1][x + 1],
                ]));
            }
        }
        EmissionPlan {
            width: w,
            oversampling,
            varies: flags,
            probe_rays: (w as u64 + 1) * (h as u64 + 1),
        }
    }

    /// The directly seen radiance of pixel (px, py) ([`crate::integrator::PathSink::camera_emission`])
    /// averaged over its `spp` path samples, whose sum is `paths_sum`, and
    /// `(oversampling - 1) x spp` more camera samples at the film points that continue theirs
    /// ([`PixelSampler::extra_film_point`]); `oversampling` comes from the [`EmissionPlan`].
    /// `sampler` must have been started on this pixel. Returns the mean and the rays cast.
    /// Non-finite values count as zero, as the sinks count them.
    pub fn pixel_emission(
        &self,
        sampler: &PixelSampler,
        px: u32,
        py: u32,
        spp: u32,
        oversampling: u32,
        paths_sum: Vec3,
    ) -> (Vec3, u64) {
        let extra = spp.saturating_mul(oversampling.max(1) - 1);
        let mut sum = paths_sum;
        for j in 0..extra {
            let u = sampler.extra_film_point(j);
            let le = self.direct_view(px as f32 + u.x, py as f32 + u.y);
            if le.is_finite() {
                sum += le;
            }
        }
        let samples = (spp as f64 + extra as f64).max(1.0);
        (sum * (1.0 / samples) as f32, extra as u64)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn corners_vary_beyond_a_share_of_the_largest() {
        let flat = [Vec3::splat(2.0); 4];
        assert!(!varies(flat));
        assert!(!varies([Vec3::ZERO; 4]));
        // An edge: one corner on the emitter.
        assert!(varies([
            Vec3::ZERO,
            Vec3::ZERO,
            Vec3::ZERO,
            Vec3::splat(17.0)
        ]));
        // A smooth sky: up to 10 % apart (a 1 % threshold flagged a third of a sky's pixels).
        let sky = [
            Vec3::new(1.0, 2.0, 3.0),
            Vec3::new(1.05, 2.0, 3.0),
            Vec3::new(1.0, 2.2, 3.0),
            Vec3::new(1.0, 2.0, 2.7),
        ];
        assert!(!varies(sky));
        // A sun's rim: half the brightness gone at one corner.
        assert!(varies([
            Vec3::splat(10.0),
            Vec3::splat(10.0),
            Vec3::splat(10.0),
            Vec3::splat(5.0)
        ]));
        // A coloured edge: red against blue of the same brightness.
        assert!(varies([Vec3::X, Vec3::X, Vec3::Z, Vec3::Z]));
    }
}
