//! A vertex's frame and ray origin, and its first rays' directions (a shifted lattice): what the
//! pre-pass (`plan.rs`), the direct light (`direct.rs`) and the transfer (`trace.rs`) share.

use glam::{Vec2, Vec3};
use prt_formats::vertex::vertex_frame;

use crate::sampling::Rng;

/// A vertex's position, frame (`prt_formats::vertex::vertex_frame`) and ray origin.
#[derive(Clone, Debug)]
pub(crate) struct VertexFrame {
    pub t: Vec3,
    pub b: Vec3,
    pub n: Vec3,
    /// `p + n eps`: where its rays start.
    pub origin: Vec3,
}

impl VertexFrame {
    pub fn new(p: Vec3, n: Vec3, eps: f32) -> VertexFrame {
        let (t, b) = vertex_frame(n.to_array());
        VertexFrame {
            t: Vec3::from_array(t),
            b: Vec3::from_array(b),
            n,
            origin: p + n * eps,
        }
    }

    #[inline]
    pub fn to_world(&self, l: Vec3) -> Vec3 {
        self.t * l.x + self.b * l.y + self.n * l.z
    }

    #[inline]
    pub fn to_local(&self, d: Vec3) -> Vec3 {
        Vec3::new(d.dot(self.t), d.dot(self.b), d.dot(self.n))
    }
}

/// The N1 first directions of a vertex: a randomly shifted rank-1 lattice over the local
/// upper hemisphere (uniform in `cos theta` and azimuth, pdf 1/(2 pi)).
///
/// Why not N1 independent directions: T1 is a Monte Carlo projection over them, and its
/// per-vertex noise (mottling on a diffuse object lit by a bright floor) falls much faster
/// with a low-discrepancy set. The lattice `(i / N1, i g / N1)`, g near `N1 / phi` and
/// coprime with N1, covers the square evenly for any N1; shifting it by a per-vertex uniform
/// offset (mod 1) makes every direction uniform on its own, so the estimate stays unbiased,
/// and the shift comes from the vertex's own stream, so the set does not depend on the thread
/// count.
#[derive(Clone, Copy, Debug)]
pub(crate) struct FirstDirections {
    n1: u32,
    g: u32,
    shift: Vec2,
}

/// Sample index that keys a vertex's lattice shift (above the w3 and light-bin streams).
const SHIFT_STREAM: u64 = 3 << 40;

impl FirstDirections {
    pub fn new(seed: u64, vertex: u32, n1: u32) -> FirstDirections {
        let n1 = n1.max(1);
        let shift = Rng::for_sample(seed, vertex as u64, SHIFT_STREAM).next_vec2();
        FirstDirections {
            n1,
            g: lattice_generator(n1),
            shift,
        }
    }

    /// Direction `i` (0..N1) in the local frame.
    #[inline]
    pub fn get(&self, i: u32) -> Vec3 {
        let n = self.n1 as u64;
        let i = i as u64 % n;
        let a = (i as f64 / n as f64 + self.shift.x as f64).fract();
        let b = ((i * self.g as u64 % n) as f64 / n as f64 + self.shift.y as f64).fract();
        hemisphere_direction(Vec2::new(a as f32, b as f32))
    }
}

/// The generator of the rank-1 lattice of `n` points: the integer nearest `n / phi` that is
/// coprime with `n` (so the second coordinate visits every `k / n` once), searching outwards.
fn lattice_generator(n: u32) -> u32 {
    if n <= 2 {
        return 1;
    }
    let target = n as f64 * 0.618_033_988_749_894_8;
    let gcd = |mut a: u32, mut b: u32| {
        while b != 0 {
            (a, b) = (b, a % b);
        }
        a
    };
    let start = target.round() as i64;
    for d in 0..n as i64 {
        for g in [start - d, start + d] {
            if g >= 1 && g < n as i64 && gcd(g as u32, n) == 1 {
                return g as u32;
            }
        }
    }
    1
}

/// The direction of the uniform hemisphere density at the point `u` of the unit square:
/// `cos theta = u.x`, azimuth `2 pi u.y`.
#[inline]
fn hemisphere_direction(u: Vec2) -> Vec3 {
    let z = u.x;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = std::f32::consts::TAU * u.y;
    Vec3::new(r * phi.cos(), r * phi.sin(), z)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every `k / n` appears once in each coordinate of the unshifted lattice, for square,
    /// prime and awkward n alike.
    #[test]
    fn the_lattice_is_a_permutation_in_each_coordinate() {
        for n in [1u32, 2, 3, 16, 61, 64, 100, 1000, 1024] {
            let g = lattice_generator(n);
            let mut seen = vec![false; n as usize];
            for i in 0..n as u64 {
                let k = (i * g as u64 % n as u64) as usize;
                assert!(!seen[k], "n {n}, g {g}: {k} twice");
                seen[k] = true;
            }
        }
        assert_eq!(lattice_generator(64), 39);
    }

    /// The directions are unit, in the upper hemisphere, and integrate `cos theta` to pi (the
    /// projected solid angle) far better than independent ones would at this count: the
    /// first coordinate is `cos theta`, evenly spaced by 1/N1 whatever the shift, so the
    /// error is at most 1/N1 relative (1.6 % at N1 = 64), against a standard deviation of
    /// 7 % for independent directions.
    #[test]
    fn shifted_lattice_integrates_the_cosine() {
        for v in 0..20 {
            let dirs = FirstDirections::new(7, v, 64);
            let mut sum = 0.0f64;
            for i in 0..64 {
                let d = dirs.get(i);
                assert!((d.length() - 1.0).abs() < 1e-5 && d.z >= 0.0);
                sum += d.z as f64;
            }
            let estimate = std::f64::consts::TAU * sum / 64.0;
            let pi = std::f64::consts::PI;
            assert!(
                (estimate - pi).abs() <= pi / 64.0 + 1e-6,
                "vertex {v}: {estimate}"
            );
        }
    }
}
