//! T1's light bins as a sampling strategy: the 6x8x8 cube texels that T1 resolves the light
//! into, and a direction drawn in one of them.
//!
//! T1 holds the response to unit radiance from each bin, so every bin matters whatever
//! environment the runtime brings later. Sampling only the first hit's BRDF mixture finds a
//! small bin (a lamp, the sun) by chance, a few times per vertex, which shows as speckle
//! under lamp-like maps. Drawing one direction in every bin per first hit, combined with the
//! BRDF samples by the balance heuristic, visits every bin at every first hit; a sample of
//! either kind then weighs `f cos / (p_bin + N2 p_brdf)`.
//!
//! A direction is drawn uniformly in the bin's square on the cube face (coordinates
//! `a, b` in `[-1, 1]`, the face at unit distance), so its solid-angle density is
//! `(1 + a^2 + b^2)^(3/2) / A`, A the square's area `(2 / n)^2`: no trigonometry, exact.

use glam::{Vec2, Vec3};
use prt_formats::lighting::cubemap::{
    direction_to_face_st, direction_to_texel, face_st_to_direction, texel_at, texel_index,
};
use prt_formats::vertex::T1_LIGHT_CUBE;

/// The light bin (texel of a cube of side `size`) holding world direction `d`.
#[inline]
pub(super) fn light_bin(size: usize, d: Vec3) -> usize {
    let (face, i, j) = direction_to_texel(size, d.as_dvec3().to_array());
    texel_index(size, face, i, j)
}

/// The solid-angle density at face coordinates `(s, t)` of drawing uniformly in one texel of
/// a face of a cube of side `n`.
#[inline]
fn density_at_st(n: usize, s: f64, t: f64) -> f32 {
    let (a, b) = (2.0 * s - 1.0, 2.0 * t - 1.0);
    let r2 = 1.0 + a * a + b * b;
    let texel_area = (2.0 / n as f64).powi(2);
    (r2 * r2.sqrt() / texel_area) as f32
}

/// A direction in T1 light bin `bin` from the uniform numbers `u`, with its solid-angle
/// density within the bin; `None` past the last bin.
#[inline]
pub(super) fn sample_bin(bin: usize, u: Vec2) -> Option<(Vec3, f32)> {
    let n = T1_LIGHT_CUBE;
    let (face, i, j) = texel_at(n, bin)?;
    // Keep the point strictly inside the texel so that it maps back to this bin.
    let inside = |k: usize, x: f32| (k as f64 + (x as f64).clamp(1e-6, 1.0 - 1e-6)) / n as f64;
    let (s, t) = (inside(i, u.x), inside(j, u.y));
    let d = face_st_to_direction(face, s, t);
    Some((
        Vec3::new(d[0] as f32, d[1] as f32, d[2] as f32),
        density_at_st(n, s, t),
    ))
}

/// The density of [`sample_bin`] at world direction `d` for the bin that holds `d` (the bin
/// strategy's density there: each bin is drawn once).
#[inline]
pub(super) fn bin_density(d: Vec3) -> f32 {
    let (_, s, t) = direction_to_face_st(d.as_dvec3().to_array());
    density_at_st(T1_LIGHT_CUBE, s, t)
}

#[cfg(test)]
mod tests {
    use super::*;
    use prt_formats::lighting::cubemap::texel_solid_angle;
    use prt_formats::vertex::cube_len;

    /// Every draw lands in its bin, and the density the draw reports is the one
    /// `bin_density` gives for that direction.
    #[test]
    fn draws_land_in_their_bin_with_a_consistent_density() {
        for bin in 0..cube_len(T1_LIGHT_CUBE) {
            for k in 0..16 {
                let u = Vec2::new((k % 4) as f32 / 4.0 + 0.1, (k / 4) as f32 / 4.0 + 0.2);
                let (d, p) = sample_bin(bin, u).unwrap();
                assert!((d.length() - 1.0).abs() < 1e-6);
                assert_eq!(light_bin(T1_LIGHT_CUBE, d), bin, "draw {k} of bin {bin}");
                let q = bin_density(d);
                assert!((p - q).abs() <= 1e-5 * p, "bin {bin}: {p} vs {q}");
            }
        }
        assert!(sample_bin(cube_len(T1_LIGHT_CUBE), Vec2::splat(0.5)).is_none());
    }

    /// The density is normalised over each bin: the mean of `1 / p` over draws is the bin's
    /// exact solid angle (a 64x64 midpoint grid of `u` integrates the smooth `1 / p` over the
    /// square to about 1e-5).
    #[test]
    fn the_density_integrates_to_one_over_each_bin() {
        let n = T1_LIGHT_CUBE;
        let grid = 64;
        for (i, j) in [(0, 0), (3, 4), (7, 2), (7, 7)] {
            let bin = texel_index(n, prt_formats::lighting::cubemap::Face::NegY, i, j);
            let mut sum = 0.0f64;
            for a in 0..grid {
                for b in 0..grid {
                    let u = Vec2::new(
                        (a as f32 + 0.5) / grid as f32,
                        (b as f32 + 0.5) / grid as f32,
                    );
                    let (_, p) = sample_bin(bin, u).unwrap();
                    sum += 1.0 / p as f64;
                }
            }
            let mean = sum / (grid * grid) as f64;
            let omega = texel_solid_angle(n, i, j);
            assert!(
                (mean - omega).abs() < 1e-4 * omega,
                "texel ({i}, {j}): {mean} vs {omega}"
            );
        }
    }
}
