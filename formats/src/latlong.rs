//! The lat-long (equirectangular) mapping between image coordinates and directions, shared by
//! the baker (environment lighting) and the runtime (projecting environments).
//!
//! # Convention
//!
//! The world is right-handed with **+Y up** (as glTF). An image coordinate `(u, v)` in
//! `[0, 1]^2` has u growing to the right and v growing down; row 0 of a map (v = 0) is its top.
//! Texel `(x, y)` of a `width x height` map has its centre at
//! `((x + 0.5) / width, (y + 0.5) / height)`. The direction of `(u, v)` is
//!
//! ```text
//! theta = pi * v                      (polar angle from +Y)
//! phi   = 2 pi (u - 0.5)              (azimuth about +Y, 0 towards -Z)
//! direction = (sin theta sin phi, cos theta, -sin theta cos phi)
//! ```
//!
//! so:
//!
//! * v = 0 (the top row) looks straight up (+Y), v = 1 straight down (-Y), v = 0.5 at the
//!   horizon;
//! * u = 0.5 (the centre column) looks down **-Z**, u = 0.75 along **+X**, u = 0.25 along
//!   **-X**;
//! * the **seam** u = 0 (= u = 1) looks along **+Z**, behind the map's centre.
//!
//! Seen from inside the sphere (as a viewer looking at the sky), u increases clockwise when
//! looking down from +Y: -Z, then +X, then +Z, then -X. This is the layout of the usual
//! "HDRI" panoramas seen from a camera looking down -Z. The same convention is written out in
//! `docs/conventions.md` (section "Environment maps").
//!
//! The arithmetic here is the baker's renderer's, bit for bit: bakes depend on it.

use std::f32::consts::PI;

/// The unit direction `[x, y, z]` that image coordinate `(u, v)` looks at (see the module
/// documentation for the convention). `u` and `v` are normally in `[0, 1]`; other values give
/// the same formula's direction (u wraps around, v beyond the poles is mirrored).
#[inline]
pub fn uv_to_direction(u: f32, v: f32) -> [f32; 3] {
    let theta = PI * v;
    let phi = 2.0 * PI * (u - 0.5);
    let st = theta.sin();
    [st * phi.sin(), theta.cos(), -st * phi.cos()]
}

/// The image coordinate `(u, v)` of a unit direction `[x, y, z]`: the inverse of
/// [`uv_to_direction`]. `u` is in `[0, 1)` (the seam direction +Z gives `u = 0`; directions
/// just to its +X side approach 1, just to its -X side approach 0) and `v` in `[0, 1]`.
/// The poles give
/// `v = 0` (+Y) and `v = 1` (-Y) with an arbitrary `u`. A `y` slightly outside `[-1, 1]`
/// (an almost-unit vector) is clamped.
#[inline(always)]
pub fn direction_to_uv(d: [f32; 3]) -> (f32, f32) {
    let [x, y, z] = d;
    let theta = y.clamp(-1.0, 1.0).acos();
    let phi = x.atan2(-z);
    let u = (phi / (2.0 * PI) + 0.5).rem_euclid(1.0);
    (u, (theta / PI).clamp(0.0, 1.0))
}

/// The texel `(x, y)` of a `width x height` map holding image coordinate `(u, v)` (nearest
/// lookup: the texel whose square contains the point; `u = 1` or `v = 1` fall in the last
/// column or row). `width` and `height` must be at least 1.
#[inline]
pub fn uv_to_texel(u: f32, v: f32, width: usize, height: usize) -> (usize, usize) {
    let x = ((u * width as f32) as usize).min(width - 1);
    let y = ((v * height as f32) as usize).min(height - 1);
    (x, y)
}

/// The image coordinate `(u, v)` of the centre of texel `(x, y)` of a `width x height` map.
#[inline]
pub fn texel_centre(x: usize, y: usize, width: usize, height: usize) -> (f32, f32) {
    (
        (x as f32 + 0.5) / width as f32,
        (y as f32 + 0.5) / height as f32,
    )
}

/// The four texels and weights of the **bilinear** lookup at image coordinate `(u, v)` of a
/// `width x height` map, as `[(texel index y * width + x, weight); 4]` (weights >= 0, summing
/// to 1).
///
/// Texel values sit at texel centres and are interpolated linearly between them, as pbrt and
/// Mitsuba interpolate environment maps (a nearest lookup makes the background of a
/// close-up view blocky). Horizontally the map wraps around the seam (u = 0 = 1); vertically the
/// half-texel bands next to the poles take the first and last row (clamped), so the value at a
/// pole is the row's value at that azimuth. `width` and `height` must be at least 1.
#[inline(always)]
pub fn bilinear(u: f32, v: f32, width: usize, height: usize) -> [(usize, f32); 4] {
    // Wrap u into [0, 1) first so that large |u| and the seam behave alike.
    let fx = u.rem_euclid(1.0) * width as f32 - 0.5;
    let x_floor = fx.floor();
    let tx = (fx - x_floor).clamp(0.0, 1.0);
    // x_floor is in [-1, width - 1]: -1 wraps to the last column.
    let x0 = (x_floor as i64).rem_euclid(width as i64) as usize;
    let x1 = if x0 + 1 == width { 0 } else { x0 + 1 };
    let fy = v.clamp(0.0, 1.0) * height as f32 - 0.5;
    let (y0, y1, ty) = if fy <= 0.0 {
        (0, 0, 0.0)
    } else if fy >= (height - 1) as f32 {
        (height - 1, height - 1, 0.0)
    } else {
        let y_floor = fy.floor();
        let y0 = (y_floor as usize).min(height - 1);
        (y0, (y0 + 1).min(height - 1), (fy - y_floor).clamp(0.0, 1.0))
    };
    [
        (y0 * width + x0, (1.0 - tx) * (1.0 - ty)),
        (y0 * width + x1, tx * (1.0 - ty)),
        (y1 * width + x0, (1.0 - tx) * ty),
        (y1 * width + x1, tx * ty),
    ]
}

/// The bilinearly interpolated value (see [`bilinear`]) of an RGB `width x height` map,
/// row-major with the top row first, in direction `d` (unit).
#[inline(always)]
pub fn lookup_bilinear(texels: &[[f32; 3]], width: usize, height: usize, d: [f32; 3]) -> [f32; 3] {
    let (u, v) = direction_to_uv(d);
    let mut out = [0.0f32; 3];
    for (i, w) in bilinear(u, v, width, height) {
        let t = texels[i];
        out[0] += w * t[0];
        out[1] += w * t[1];
        out[2] += w * t[2];
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: [f32; 3], b: [f32; 3], tol: f32) -> bool {
        a.iter().zip(b.iter()).all(|(p, q)| (p - q).abs() <= tol)
    }

    #[test]
    fn documented_axes() {
        assert!(close(uv_to_direction(0.5, 0.0), [0.0, 1.0, 0.0], 1e-6));
        assert!(close(uv_to_direction(0.5, 1.0), [0.0, -1.0, 0.0], 1e-6));
        assert!(close(uv_to_direction(0.5, 0.5), [0.0, 0.0, -1.0], 1e-6));
        assert!(close(uv_to_direction(0.75, 0.5), [1.0, 0.0, 0.0], 1e-6));
        assert!(close(uv_to_direction(0.25, 0.5), [-1.0, 0.0, 0.0], 1e-6));
        assert!(close(uv_to_direction(0.0, 0.5), [0.0, 0.0, 1.0], 1e-6));
        assert!(close(uv_to_direction(1.0, 0.5), [0.0, 0.0, 1.0], 1e-6));
        assert_eq!(direction_to_uv([0.0, 0.0, -1.0]), (0.5, 0.5));
        let (u, v) = direction_to_uv([1.0, 0.0, 0.0]);
        assert!((u - 0.75).abs() < 1e-6 && (v - 0.5).abs() < 1e-6);
    }

    #[test]
    fn directions_are_unit() {
        for i in 0..=20 {
            for j in 0..=20 {
                let d = uv_to_direction(i as f32 / 20.0, j as f32 / 20.0);
                let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                assert!((n - 1.0).abs() < 1e-5, "{i} {j}: {n}");
            }
        }
    }

    #[test]
    fn round_trips_away_from_poles_and_seam() {
        for i in 1..40 {
            for j in 1..20 {
                let (u, v) = (i as f32 / 40.0, j as f32 / 20.0);
                let (u2, v2) = direction_to_uv(uv_to_direction(u, v));
                assert!(
                    (u - u2).abs() < 1e-5 && (v - v2).abs() < 1e-5,
                    "{u} {v} -> {u2} {v2}"
                );
            }
        }
        // direction -> uv -> direction, for directions in every octant.
        for &d in &[
            [0.3f32, 0.5, -0.8],
            [-0.6, -0.2, 0.7],
            [0.9, 0.1, 0.4],
            [-0.1, 0.95, -0.2],
        ] {
            let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            let d = [d[0] / n, d[1] / n, d[2] / n];
            let (u, v) = direction_to_uv(d);
            assert!(close(uv_to_direction(u, v), d, 1e-5), "{d:?}");
        }
    }

    #[test]
    fn poles_and_seam() {
        // The poles: v is exactly 0 or 1, u is in range (any value is right).
        for d in [[0.0, 1.0, 0.0], [0.0, -1.0, 0.0], [-0.0, 1.0, -0.0]] {
            let (u, v) = direction_to_uv(d);
            assert!((0.0..=1.0).contains(&u), "{d:?} {u}");
            assert_eq!(v, if d[1] > 0.0 { 0.0 } else { 1.0 });
        }
        // Slightly non-unit y is clamped rather than giving NaN.
        let (u, v) = direction_to_uv([0.0, 1.000001, 0.0]);
        assert!(u.is_finite() && v == 0.0);
        let (_, v) = direction_to_uv([0.0, -1.000001, 0.0]);
        assert_eq!(v, 1.0);
        // The seam (+Z): u = 0. Its -X side is at the start of [0, 1), its +X side at the end.
        assert_eq!(direction_to_uv([0.0, 0.0, 1.0]).0, 0.0);
        let (u_minus, _) = direction_to_uv([-1e-3, 0.0, 1.0]);
        let (u_plus, _) = direction_to_uv([1e-3, 0.0, 1.0]);
        assert!(u_minus > 0.0 && u_minus < 1e-3, "{u_minus}");
        assert!(u_plus < 1.0 && u_plus > 1.0 - 1e-3, "{u_plus}");
        // Ever closer to the seam from +X: u stays in [0, 1) and its texel in range.
        for k in 1..40 {
            let x = 10f32.powi(-k);
            let (u, _) = direction_to_uv([x, 0.0, 1.0]);
            assert!((0.0..1.0).contains(&u), "{x}: {u}");
            assert!(uv_to_texel(u, 0.5, 8, 4).0 <= 7);
        }
        // u = 1 or v = 1 (allowed inputs) fall in the last column and row.
        assert_eq!(uv_to_texel(1.0, 1.0, 8, 4), (7, 3));
        assert_eq!(uv_to_texel(0.0, 0.0, 8, 4), (0, 0));
    }

    #[test]
    fn every_texel_centre_maps_back_to_its_texel() {
        for &(w, h) in &[
            (1, 1),
            (2, 1),
            (4, 2),
            (7, 3),
            (64, 32),
            (1024, 512),
            (4096, 2048),
        ] {
            // All texels of small maps; a sparse grid plus the borders of large ones.
            let step = |n: usize| if n <= 64 { 1 } else { n / 61 };
            let xs: Vec<usize> = (0..w).step_by(step(w)).chain([w - 1]).collect();
            let ys: Vec<usize> = (0..h).step_by(step(h)).chain([h - 1]).collect();
            for &y in &ys {
                for &x in &xs {
                    let (u, v) = texel_centre(x, y, w, h);
                    let (u2, v2) = direction_to_uv(uv_to_direction(u, v));
                    let (x2, y2) = uv_to_texel(u2, v2, w, h);
                    // A 1-texel-high map's only row is centred on the horizon; a 1-texel-wide
                    // map has one column: both are trivially themselves.
                    assert_eq!(
                        (x2, y2),
                        (x, y),
                        "{w}x{h}: texel ({x}, {y}) -> ({u2}, {v2})"
                    );
                }
            }
        }
    }

    #[test]
    fn bilinear_hits_texel_centres_and_interpolates_between() {
        let (w, h) = (8, 4);
        for y in 0..h {
            for x in 0..w {
                let (u, v) = texel_centre(x, y, w, h);
                let taps = bilinear(u, v, w, h);
                let total: f32 = taps.iter().map(|t| t.1).sum();
                assert!((total - 1.0).abs() < 1e-6);
                let at_centre: f32 = taps.iter().filter(|t| t.0 == y * w + x).map(|t| t.1).sum();
                assert!((at_centre - 1.0).abs() < 1e-5, "({x}, {y}): {taps:?}");
            }
        }
        // Half-way between the centres of texels (2, 1) and (3, 1): half each.
        let taps = bilinear(3.0 / 8.0, 1.5 / 4.0, w, h);
        let weight_of = |i: usize| -> f32 { taps.iter().filter(|t| t.0 == i).map(|t| t.1).sum() };
        assert!((weight_of(8 + 2) - 0.5).abs() < 1e-6 && (weight_of(8 + 3) - 0.5).abs() < 1e-6);
        // A quarter of the way from row 1's centre to row 2's centre.
        let taps = bilinear(2.5 / 8.0, 1.75 / 4.0, w, h);
        let weight_of = |i: usize| -> f32 { taps.iter().filter(|t| t.0 == i).map(|t| t.1).sum() };
        assert!((weight_of(8 + 2) - 0.75).abs() < 1e-6 && (weight_of(16 + 2) - 0.25).abs() < 1e-6);
    }

    #[test]
    fn bilinear_wraps_at_the_seam_and_clamps_at_the_poles() {
        let (w, h) = (8, 4);
        let weight_of = |taps: [(usize, f32); 4], i: usize| -> f32 {
            taps.iter().filter(|t| t.0 == i).map(|t| t.1).sum()
        };
        // On the seam (u = 0 and u = 1): half the first column, half the last.
        for u in [0.0, 1.0, 1e-9, 1.0 - 1e-7] {
            let taps = bilinear(u, 1.5 / 4.0, w, h);
            assert!((weight_of(taps, 8) - 0.5).abs() < 1e-3, "{u}: {taps:?}");
            assert!((weight_of(taps, 8 + 7) - 0.5).abs() < 1e-3, "{u}: {taps:?}");
        }
        // Above the first row's centre and below the last row's: that row only.
        for v in [0.0, 0.05, 0.125] {
            let taps = bilinear(2.5 / 8.0, v, w, h);
            assert!((weight_of(taps, 2) - 1.0).abs() < 1e-6, "{v}: {taps:?}");
        }
        for v in [1.0, 0.95, 0.875] {
            let taps = bilinear(2.5 / 8.0, v, w, h);
            assert!(
                (weight_of(taps, 24 + 2) - 1.0).abs() < 1e-6,
                "{v}: {taps:?}"
            );
        }
        // A 1 x 1 map: everything is its one texel.
        for (u, v) in [(0.0, 0.0), (0.3, 0.7), (1.0, 1.0)] {
            assert!((weight_of(bilinear(u, v, 1, 1), 0) - 1.0).abs() < 1e-6);
        }
    }

    #[test]
    fn bilinear_lookup_is_continuous_and_reproduces_linear_ramps() {
        // A map that is linear in the column index between centres: the lookup must be the
        // same ramp (up to the wrap-around segment), i.e. no blocky steps.
        let (w, h) = (16, 8);
        let texels: Vec<[f32; 3]> = (0..w * h)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                [x as f32, y as f32, 1.0]
            })
            .collect();
        for k in 0..100 {
            let u = (0.5 + k as f32 * (w as f32 - 1.0) / 100.0) / w as f32;
            let v = (0.5 + k as f32 * (h as f32 - 1.0) / 100.0) / h as f32;
            let d = uv_to_direction(u, v);
            let c = lookup_bilinear(&texels, w, h, d);
            assert!((c[0] - (u * w as f32 - 0.5)).abs() < 2e-3, "{k}: {c:?}");
            assert!((c[1] - (v * h as f32 - 0.5)).abs() < 2e-3, "{k}: {c:?}");
            assert!((c[2] - 1.0).abs() < 1e-5);
        }
    }
}
