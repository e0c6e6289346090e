//! A vertex's frame and ray origin, and the direction density of its first rays: what the
//! pre-pass (`plan.rs`), the direct light (`direct.rs`) and the transfer (`trace.rs`) share.

use glam::Vec3;
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

/// A direction uniform over the local upper hemisphere (pdf 1/(2 pi)); draws 2 numbers.
#[inline]
pub(crate) fn first_direction(rng: &mut Rng) -> Vec3 {
    let u = rng.next_vec2();
    let z = u.x;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = std::f32::consts::TAU * u.y;
    Vec3::new(r * phi.cos(), r * phi.sin(), z)
}
