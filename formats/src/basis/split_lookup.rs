//! Where a split Gaussian's prefiltered light is read (docs/brdf-basis.md, "Shading basis").
//!
//! The split's term `w` reflects `R_w` times the light seen through its Gaussian `G_w` about
//! the mirror direction `r` **weighted by the cosine** and cut at the horizon:
//! `∫_H G_w(angle(w, r)) I(w) cos(theta_w) dw / ∫_H G_w cos dw` (the reflectance `R_w` holds
//! `∫_H G_w cos`). A prefiltered map gives the unweighted average `Ibar_w`, so reading it at
//! `r` takes the cosine as constant over the lobe: near grazing the Gaussian's upper half
//! (towards the normal) weighs more than its lower half, and part of it lies below the
//! horizon, so the light the lobe sees is that of a direction above `r`. Read at `r`, a
//! glossy surface at grazing views was too dark wherever the sky above the horizon is
//! brighter than the horizon (39 % at 88 degrees in the basis' accuracy table).
//!
//! [`cosine_centroid`] gives the direction at which to read instead: `r` raised towards the
//! normal by the cosine-weighted centroid's tilt `delta` of a Gaussian of per-axis spread
//! `sigma` about a direction `e` above the horizon. In the tangent-plane approximation (`x`
//! the offset towards the normal, weight `(e + x)+`), `delta = sigma Phi(t) / (t Phi(t) +
//! phi(t))` with `t = e / sigma` (`Phi`, `phi` the standard normal's distribution and
//! density). Taking `t = tan(e) / sigma` instead keeps both limits of the sphere: at the
//! horizon `delta = sigma sqrt(pi / 2)` (the half Gaussian's cosine-weighted mean), high
//! above it `delta ~ sigma^2 cot(e)` (the first-order tilt of a Gaussian under `cos`), and
//! `delta = 0` along the normal. Against the centroid integrated over the sphere it is within
//! 0.5 degrees for widths up to 21 degrees at every elevation (tested).

/// The standard normal distribution `Phi(t)` for `t >= 0` (Abramowitz and Stegun 7.1.26 for
/// `erf`, absolute error below 1.5e-7) given `g = exp(-t^2 / 2)`, which the density shares:
/// written out so the GPU backend can evaluate the same formula (WGSL has no `erf`).
#[inline(always)]
fn normal_cdf(t: f32, g: f32) -> f32 {
    let x = t * std::f32::consts::FRAC_1_SQRT_2;
    let k = 1.0 / (1.0 + 0.327_591_1 * x);
    let poly = k
        * (0.254_829_6
            + k * (-0.284_496_74 + k * (1.421_413_7 + k * (-1.453_152 + k * 1.061_405_4))));
    let erf = 1.0 - poly * g;
    0.5 * (1.0 + erf)
}

/// `(sin d, cos d)`: Taylor series up to `d = 0.8` (errors below 1e-7, and cheaper than the
/// library's call in the view stage's inner loop), the library beyond.
#[inline(always)]
fn sin_cos_small(d: f32) -> (f32, f32) {
    if d > 0.8 {
        return d.sin_cos();
    }
    let d2 = d * d;
    let s = d * (1.0 - d2 / 6.0 * (1.0 - d2 / 20.0 * (1.0 - d2 / 42.0 * (1.0 - d2 / 72.0))));
    let c = 1.0
        - d2 / 2.0 * (1.0 - d2 / 12.0 * (1.0 - d2 / 30.0 * (1.0 - d2 / 56.0 * (1.0 - d2 / 90.0))));
    (s, c)
}

/// The tilt (radians) towards the normal of the cosine-weighted centroid of a Gaussian of
/// per-axis spread `sigma` (radians) about a direction whose height above the tangent plane
/// is `z` and whose length in it is `h` (`z = sin e`, `h = cos e`; `z >= 0`).
#[inline(always)]
pub fn cosine_centroid_tilt(sigma: f32, z: f32, h: f32) -> f32 {
    if sigma <= 0.0 || h <= 1e-6 * z {
        return 0.0;
    }
    let t = z / (h * sigma);
    if t > 12.0 {
        // Phi(t) = 1 and phi(t) = 0 in f32 (and exp would take libm's slow underflow path).
        return sigma / t;
    }
    // exp(-t^2 / 2) serves the distribution and the density.
    let g = (-0.5 * t * t).exp();
    let cdf = normal_cdf(t, g);
    let pdf = g * 0.398_942_3;
    sigma * cdf / (t * cdf + pdf)
}

/// The local direction (normal `+z`) at which a prefiltered map of Gaussian spread `sigma`
/// (radians) is read for the split term about the mirror direction `r` (unit, `r.z >= 0`):
/// `r` raised towards the normal by [`cosine_centroid_tilt`], stopping at the normal.
#[inline(always)]
pub fn cosine_centroid(r: [f32; 3], sigma: f32) -> [f32; 3] {
    let z = r[2].max(0.0);
    let h = (r[0] * r[0] + r[1] * r[1]).sqrt();
    let delta = cosine_centroid_tilt(sigma, z, h);
    if delta <= 0.0 {
        return r;
    }
    let (sd, cd) = sin_cos_small(delta);
    // cos and sin of the raised elevation.
    let h2 = h * cd - z * sd;
    if h2 <= 0.0 {
        return [0.0, 0.0, 1.0];
    }
    let z2 = z * cd + h * sd;
    let k = h2 / h;
    [r[0] * k, r[1] * k, z2]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The cosine-weighted centroid's tilt integrated over the sphere (f64, polar grid about
    /// the direction at elevation `e`).
    fn integrated_tilt(sigma: f64, e: f64) -> f64 {
        let th = std::f64::consts::FRAC_PI_2 - e;
        let r = [th.sin(), 0.0, th.cos()];
        let e1 = [th.cos(), 0.0, -th.sin()];
        let (na, nb) = (600, 256);
        let amax = (5.0 * sigma).min(std::f64::consts::PI);
        let mut c = [0.0f64; 3];
        for i in 0..na {
            let a = (i as f64 + 0.5) / na as f64 * amax;
            let g = (-a * a / (2.0 * sigma * sigma)).exp() * a.sin();
            for j in 0..nb {
                let b = (j as f64 + 0.5) / nb as f64 * std::f64::consts::TAU;
                let w: [f64; 3] = std::array::from_fn(|k| {
                    a.cos() * r[k]
                        + a.sin() * b.cos() * e1[k]
                        + if k == 1 { a.sin() * b.sin() } else { 0.0 }
                });
                let wt = g * w[2].max(0.0);
                for k in 0..3 {
                    c[k] += wt * w[k];
                }
            }
        }
        c[2].atan2(c[0]) - e
    }

    #[test]
    fn the_tilt_is_the_integrated_centroids_within_half_a_degree() {
        for sigma_deg in [1.3f64, 7.0, 14.0, 21.0] {
            let sigma = sigma_deg.to_radians();
            for e_deg in [
                0.0f64, 0.5, 2.0, 5.0, 10.0, 20.0, 30.0, 45.0, 60.0, 80.0, 89.0,
            ] {
                let e = e_deg.to_radians();
                let want = integrated_tilt(sigma, e).to_degrees();
                let got = f64::from(cosine_centroid_tilt(
                    sigma as f32,
                    e.sin() as f32,
                    e.cos() as f32,
                ))
                .to_degrees();
                assert!(
                    (got - want).abs() < 0.5,
                    "sigma {sigma_deg} elevation {e_deg}: {got} vs integrated {want}"
                );
            }
        }
    }

    #[test]
    fn the_short_sine_and_cosine_are_the_librarys() {
        for k in 0..=1000 {
            let d = k as f32 * 1.2e-3;
            let (s, c) = sin_cos_small(d);
            let (ws, wc) = f64::from(d).sin_cos();
            assert!((f64::from(s) - ws).abs() < 2e-7, "sin {d}: {s} vs {ws}");
            assert!((f64::from(c) - wc).abs() < 2e-7, "cos {d}: {c} vs {wc}");
        }
    }

    #[test]
    fn the_centroid_is_raised_in_the_plane_of_r_and_the_normal() {
        let sigma = 14f32.to_radians();
        for r in [[0.6f32, -0.79, 0.1], [0.0, 0.999, 0.045], [0.3, 0.4, 0.866]] {
            let n = (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]).sqrt();
            let r = r.map(|x| x / n);
            let c = cosine_centroid(r, sigma);
            let len = (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt();
            assert!((len - 1.0).abs() < 1e-5, "{c:?} not unit");
            assert!(c[2] > r[2], "{c:?} not above {r:?}");
            // Same azimuth.
            assert!(
                (c[0] * r[1] - c[1] * r[0]).abs() < 1e-6,
                "{c:?} turned from {r:?}"
            );
            let raised = c[2].asin() - r[2].asin();
            let want = cosine_centroid_tilt(sigma, r[2], (1.0 - r[2] * r[2]).sqrt());
            assert!((raised - want).abs() < 1e-4, "{raised} vs {want}");
        }
        // Along the normal, or with no width, nothing moves.
        assert_eq!(cosine_centroid([0.0, 0.0, 1.0], sigma), [0.0, 0.0, 1.0]);
        assert_eq!(cosine_centroid([0.6, 0.0, 0.8], 0.0), [0.6, 0.0, 0.8]);
        // A wide Gaussian on the horizon is raised by sigma sqrt(pi / 2), at most to the normal.
        let wide = cosine_centroid([1.0, 0.0, 0.0], 1.5);
        assert_eq!(wide, [0.0, 0.0, 1.0]);
    }
}
