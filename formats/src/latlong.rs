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
#[inline]
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
}
