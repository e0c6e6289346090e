//! The lat-long environment: its bilinear radiance lookup and an importance sampler whose
//! density follows that same bilinear function exactly.
//!
//! Radiance is interpolated bilinearly between texel centres ([`prt_formats::latlong::bilinear`]),
//! as pbrt and Mitsuba do; a nearest-texel lookup makes the background of a close-up view
//! blocky. The sampler draws directions with a density in image space proportional to the
//! bilinear interpolation of `luminance(texel) * sin(theta_row)` (the sine at the texel row's
//! centre accounts for the map's rows shrinking towards the poles), like Mitsuba's continuous
//! `Marginal2D`: rows by a piecewise-linear marginal, then a column by the piecewise-linear
//! conditional of the interpolated row. So the density is positive wherever the looked-up
//! radiance is, and matches it within a texel, not only on average over texels.
//!
//! The image-space layout is that of the lookup: texel values sit at texel centres, columns wrap
//! around the seam, and the half-texel bands next to the poles take the first and last row.

use glam::{Vec2, Vec3};
use prt_formats::latlong;
use std::f32::consts::PI;

use super::color::luminance;
use crate::sampling::Distribution1D;

/// Bilinearly interpolated radiance of a lat-long map (`width x height`, row-major, top row
/// first) arriving from direction `dir` (unit, world space, towards the sky).
#[inline]
pub(crate) fn latlong_radiance(width: usize, height: usize, texels: &[Vec3], dir: Vec3) -> Vec3 {
    let (u, v) = latlong::direction_to_uv(dir.to_array());
    latlong::bilinear(u, v, width, height)
        .iter()
        .map(|&(i, w)| texels[i] * w)
        .sum()
}

/// Importance sampling of a lat-long map by its bilinearly interpolated luminance.
pub(crate) struct LatLongSampler {
    width: usize,
    height: usize,
    /// Sampling weight at each texel centre: `luminance * sin(theta)` of its row.
    nodes: Vec<f32>,
    /// Per row, `width + 1` running sums of the column segments' masses: segment `i` runs from
    /// column `i`'s centre to column `i + 1`'s (the last one wraps to column 0) and holds
    /// `(node_i + node_{i+1}) / 2` (in units of one column's width).
    prefix: Vec<f64>,
    /// Per row, the integral of its interpolated weight over u: `sum(nodes) / width`.
    row_integrals: Vec<f64>,
    /// Over v: the top half-texel band, the `height - 1` spans between row centres, the bottom
    /// band (`height + 1` segments), weighted by their mass.
    rows: Distribution1D,
    /// Integral of the interpolated weight over the whole image, `sum` of the segments.
    total: f64,
}

impl LatLongSampler {
    /// `None` for an empty, mis-sized or black map (nothing to sample).
    pub(crate) fn new(width: usize, height: usize, texels: &[Vec3]) -> Option<LatLongSampler> {
        if width == 0 || height == 0 || texels.len() != width * height {
            return None;
        }
        let mut nodes = Vec::with_capacity(width * height);
        let mut prefix = Vec::with_capacity((width + 1) * height);
        let mut row_integrals = Vec::with_capacity(height);
        for y in 0..height {
            let sin_t = (std::f64::consts::PI * (y as f64 + 0.5) / height as f64).sin();
            let row_start = nodes.len();
            nodes.extend(texels[y * width..(y + 1) * width].iter().map(|&c| {
                let w = (luminance(c) as f64 * sin_t) as f32;
                if w.is_finite() && w > 0.0 {
                    w
                } else {
                    0.0
                }
            }));
            let row = &nodes[row_start..];
            let mut sum = 0.0f64;
            prefix.push(0.0);
            for i in 0..width {
                let next = row[if i + 1 == width { 0 } else { i + 1 }];
                sum += 0.5 * (row[i] as f64 + next as f64);
                prefix.push(sum);
            }
            row_integrals.push(sum / width as f64);
        }
        let h = height as f64;
        let mut masses = Vec::with_capacity(height + 1);
        masses.push(row_integrals[0] * 0.5 / h);
        for y in 0..height - 1 {
            masses.push(0.5 * (row_integrals[y] + row_integrals[y + 1]) / h);
        }
        masses.push(row_integrals[height - 1] * 0.5 / h);
        let total: f64 = masses.iter().sum();
        if !(total > 0.0 && total.is_finite()) {
            return None;
        }
        let weights: Vec<f32> = masses.iter().map(|&m| m as f32).collect();
        let rows = Distribution1D::new(&weights)?;
        Some(LatLongSampler {
            width,
            height,
            nodes,
            prefix,
            row_integrals,
            rows,
            total,
        })
    }

    /// A direction and its solid-angle density, or `None` on the (measure-zero) poles.
    pub(crate) fn sample(&self, u: Vec2) -> Option<(Vec3, f32)> {
        let (w, h) = (self.width, self.height);
        // The row span: the top band, a span between two row centres, or the bottom band.
        let (segment, xi) = self.rows.sample(u.y);
        let (y0, y1, ty, v) = if segment == 0 {
            (0, 0, 0.0, xi as f64 * 0.5 / h as f64)
        } else if segment == h {
            (
                h - 1,
                h - 1,
                0.0,
                (h as f64 - 0.5 + 0.5 * xi as f64) / h as f64,
            )
        } else {
            let y0 = segment - 1;
            let t = invert_linear(
                self.row_integrals[y0],
                self.row_integrals[y0 + 1],
                xi as f64,
            );
            (y0, y0 + 1, t, (y0 as f64 + 0.5 + t) / h as f64)
        };
        // The column, by the interpolated row's piecewise-linear profile.
        let p0 = &self.prefix[y0 * (w + 1)..(y0 + 1) * (w + 1)];
        let p1 = &self.prefix[y1 * (w + 1)..(y1 + 1) * (w + 1)];
        let mixed = |i: usize| (1.0 - ty) * p0[i] + ty * p1[i];
        let target = u.x as f64 * mixed(w);
        let (mut lo, mut hi) = (0usize, w);
        while lo + 1 < hi {
            let mid = (lo + hi) / 2;
            if mixed(mid) <= target {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        // Zero-mass segments cannot hold the sample.
        while mixed(lo + 1) <= mixed(lo) && lo + 1 < w {
            lo += 1;
        }
        let (m0, m1) = (mixed(lo), mixed(lo + 1));
        let xi_x = if m1 > m0 {
            ((target - m0) / (m1 - m0)).clamp(0.0, 1.0)
        } else {
            0.5
        };
        let node = |y: usize, x: usize| self.nodes[y * w + x] as f64;
        let next = if lo + 1 == w { 0 } else { lo + 1 };
        let a = (1.0 - ty) * node(y0, lo) + ty * node(y1, lo);
        let b = (1.0 - ty) * node(y0, next) + ty * node(y1, next);
        let t = invert_linear(a, b, xi_x);
        let uu = ((lo as f64 + 0.5 + t) / w as f64).rem_euclid(1.0) as f32;
        let vv = (v as f32).clamp(0.0, 1.0);
        let dir = Vec3::from_array(latlong::uv_to_direction(uu, vv));
        let pdf = self.pdf_uv(uu, vv) / jacobian(vv)?;
        (pdf > 0.0 && pdf.is_finite()).then_some((dir, pdf))
    }

    /// Solid-angle density of [`LatLongSampler::sample`] for direction `dir`.
    pub(crate) fn pdf(&self, dir: Vec3) -> f32 {
        let (u, v) = latlong::direction_to_uv(dir.to_array());
        match jacobian(v) {
            Some(j) => self.pdf_uv(u, v) / j,
            None => 0.0,
        }
    }

    /// Density in image space: the interpolated weight over its integral.
    fn pdf_uv(&self, u: f32, v: f32) -> f32 {
        let weight: f64 = latlong::bilinear(u, v, self.width, self.height)
            .iter()
            .map(|&(i, w)| self.nodes[i] as f64 * w as f64)
            .sum();
        (weight / self.total) as f32
    }
}

/// `d(solid angle) / d(u v) = 2 pi^2 sin(theta)`; `None` on the poles.
#[inline]
fn jacobian(v: f32) -> Option<f32> {
    let j = 2.0 * PI * PI * (PI * v).sin();
    (j > 0.0).then_some(j)
}

/// The `t` in `[0, 1]` where the CDF of the density `(1 - t) a + t b` (a, b >= 0) reaches
/// `xi`: the root of `(b - a) t^2 / 2 + a t = xi (a + b) / 2`, in the form that stays accurate
/// when `a` or `b - a` is small.
#[inline]
fn invert_linear(a: f64, b: f64, xi: f64) -> f64 {
    // (NaN or no mass: any t is as good; keep the uniform one.)
    if a + b <= 0.0 || (a + b).is_nan() {
        return xi;
    }
    let d = (a * a + (b * b - a * a) * xi).max(0.0);
    let denom = a + d.sqrt();
    if denom > 0.0 {
        (xi * (a + b) / denom).clamp(0.0, 1.0)
    } else {
        xi
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Rng;

    /// A small map with a sun, a dark band and a black column (so some segments have no mass).
    fn test_map(w: usize, h: usize) -> Vec<Vec3> {
        (0..w * h)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                if x == 3 {
                    Vec3::ZERO
                } else if (x, y) == (9, 2) {
                    Vec3::new(300.0, 200.0, 100.0)
                } else {
                    Vec3::splat(0.2 + 0.1 * ((x * 7 + y * 3) % 5) as f32)
                }
            })
            .collect()
    }

    #[test]
    fn inverting_a_linear_density() {
        for &(a, b) in &[
            (1.0, 1.0),
            (0.0, 1.0),
            (1.0, 0.0),
            (2.0, 5.0),
            (5.0, 2.0),
            (1e-9, 3.0),
        ] {
            for k in 0..=10 {
                let xi = k as f64 / 10.0;
                let t = invert_linear(a, b, xi);
                let cdf = (a * t + 0.5 * (b - a) * t * t) / (0.5 * (a + b));
                assert!(
                    (cdf - xi).abs() < 1e-9,
                    "a {a} b {b} xi {xi}: t {t} cdf {cdf}"
                );
            }
        }
        assert_eq!(invert_linear(0.0, 0.0, 0.3), 0.3);
    }

    #[test]
    fn density_integrates_to_one_over_the_sphere() {
        let (w, h) = (16, 8);
        let s = LatLongSampler::new(w, h, &test_map(w, h)).expect("sampler");
        // Midpoint rule in (u, v) with the exact Jacobian: 8 x 8 cells per texel.
        let (nu, nv) = (w * 8, h * 8);
        let mut total = 0.0f64;
        for j in 0..nv {
            for i in 0..nu {
                let (u, v) = ((i as f32 + 0.5) / nu as f32, (j as f32 + 0.5) / nv as f32);
                let d = Vec3::from_array(latlong::uv_to_direction(u, v));
                let jac = 2.0 * PI * PI * (PI * v).sin();
                total += (s.pdf(d) * jac) as f64 / (nu * nv) as f64;
            }
        }
        assert!(
            (total - 1.0).abs() < 2e-3,
            "integral of the density: {total}"
        );
    }

    #[test]
    fn sampled_density_agrees_with_pdf_and_is_positive_where_radiance_is() {
        let (w, h) = (16, 8);
        let map = test_map(w, h);
        let s = LatLongSampler::new(w, h, &map).expect("sampler");
        let mut rng = Rng::for_sample(1, 2, 3);
        for _ in 0..20_000 {
            let u = Vec2::new(rng.next_f32(), rng.next_f32());
            let Some((d, pdf)) = s.sample(u) else {
                continue;
            };
            let again = s.pdf(d);
            // Next to a pole the direction's azimuth (so its u) is known only roughly.
            let tol = if d.y.abs() < 0.999 { 1e-3 } else { 1e-2 };
            assert!(
                (pdf - again).abs() <= tol * pdf,
                "{d}: sampled pdf {pdf}, pdf() {again}"
            );
            // Every sample lands where the looked-up radiance is positive.
            assert!(luminance(latlong_radiance(w, h, &map, d)) > 0.0, "{d}");
        }
        for _ in 0..20_000 {
            let u = rng.next_f32();
            let v = rng.next_f32();
            let d = Vec3::from_array(latlong::uv_to_direction(u, v));
            // (The poles themselves, where f32 rounds y to +-1, are a set of measure zero.)
            if luminance(latlong_radiance(w, h, &map, d)) > 0.0 && d.y.abs() < 1.0 {
                assert!(
                    s.pdf(d) > 0.0,
                    "zero density at {d} where radiance is positive"
                );
            }
        }
    }

    /// Samples fall into cells of a fine (u, v) grid as often as the density says: every cell
    /// within 5 standard deviations of its expected count (a binomial), with more cells than
    /// texels so that a density right on average per texel but wrong inside it fails.
    #[test]
    fn samples_follow_the_density() {
        let (w, h) = (16, 8);
        let s = LatLongSampler::new(w, h, &test_map(w, h)).expect("sampler");
        let (nu, nv) = (w * 2, h * 2);
        let n = 400_000;
        let mut counts = vec![0u32; nu * nv];
        let mut rng = Rng::for_sample(7, 0, 0);
        for _ in 0..n {
            let u = Vec2::new(rng.next_f32(), rng.next_f32());
            if let Some((d, _)) = s.sample(u) {
                let (uu, vv) = latlong::direction_to_uv(d.to_array());
                let (x, y) = latlong::uv_to_texel(uu, vv, nu, nv);
                counts[y * nu + x] += 1;
            }
        }
        // Expected probability per cell: a 16 x 16 midpoint rule of the density in (u, v).
        let sub = 16;
        for cy in 0..nv {
            for cx in 0..nu {
                let mut p = 0.0f64;
                for j in 0..sub {
                    for i in 0..sub {
                        let u = (cx as f32 + (i as f32 + 0.5) / sub as f32) / nu as f32;
                        let v = (cy as f32 + (j as f32 + 0.5) / sub as f32) / nv as f32;
                        p += s.pdf_uv(u, v) as f64;
                    }
                }
                p /= (sub * sub * nu * nv) as f64;
                let expect = p * n as f64;
                let sd = (expect * (1.0 - p)).sqrt().max(1.0);
                let got = counts[cy * nu + cx] as f64;
                assert!(
                    (got - expect).abs() <= 5.0 * sd + 1e-3 * expect,
                    "cell ({cx}, {cy}): {got} samples, expected {expect:.1} (sd {sd:.1})"
                );
            }
        }
    }

    #[test]
    fn radiance_is_bilinear_between_texel_centres() {
        let (w, h) = (4, 2);
        let mut map = vec![Vec3::ZERO; w * h];
        map[1] = Vec3::new(1.0, 2.0, 4.0);
        // At texel (1, 0)'s centre: its value; half-way to texel (2, 0): half of it.
        let at = |u: f32, v: f32| {
            latlong_radiance(w, h, &map, Vec3::from_array(latlong::uv_to_direction(u, v)))
        };
        assert!((at(1.5 / 4.0, 0.25) - map[1]).abs().max_element() < 1e-5);
        assert!((at(2.0 / 4.0, 0.25) - map[1] * 0.5).abs().max_element() < 1e-5);
        assert!((at(1.5 / 4.0, 0.5) - map[1] * 0.5).abs().max_element() < 1e-5);
        assert!(at(3.5 / 4.0, 0.25).max_element() < 1e-6);
    }

    #[test]
    fn black_or_mis_sized_maps_have_no_sampler() {
        assert!(LatLongSampler::new(4, 2, &[Vec3::ZERO; 8]).is_none());
        assert!(LatLongSampler::new(4, 2, &[Vec3::ONE; 7]).is_none());
        assert!(LatLongSampler::new(0, 2, &[]).is_none());
        let single = LatLongSampler::new(1, 1, &[Vec3::ONE]).expect("1 x 1");
        let (d, pdf) = single.sample(Vec2::new(0.3, 0.6)).expect("sample");
        // A constant map samples by the interpolated sin(theta) of its one row: constant in
        // image space, so the density is 1 / (2 pi^2 sin theta).
        let v = latlong::direction_to_uv(d.to_array()).1;
        assert!((pdf - 1.0 / (2.0 * PI * PI * (PI * v).sin())).abs() < 1e-4 * pdf);
    }
}
