//! Tangent-space normal maps (glTF `normalTexture`), shared by the baker (every path vertex
//! and the reference tracer) and the per-vertex runtime (the last reflection, CPU and GPU), so
//! that all of them bend the shading normal the same way.
//!
//! glTF stores a map texel `c` (linear, in [0, 1]) as the tangent-space normal `2c - 1`, with
//! +X to the right of the image (+u) and +Y up in it, and `normalTexture.scale` multiplying X
//! and Y. glTF texture coordinates put (0, 0) at the image's top-left corner, so "up in the
//! image" is -v on the surface.
//!
//! **Tangents come from each triangle's texture coordinates** (dP/du and -dP/dv), made
//! orthogonal to the interpolated normal, as pbrt-v4 and Mitsuba 3's `normalmap` do, rather
//! than from the glTF `TANGENT` attribute or MikkTSpace: the per-vertex runtime can then find
//! the same frame from what its file already holds (positions, UVs), and the reference, the
//! bakers and the runtime agree by construction. Where a mesh's UV layout is smooth the two
//! differ little; across a UV seam the frame turns with the triangle.

/// A texel of a normal map (linear, in [0, 1]) as the tangent-space vector it encodes, with
/// the map's `scale` applied to X and Y (glTF: `(2c - 1) * (scale, scale, 1)`), not
/// normalized: texels are stored decoded, and a bilinear lookup of decoded texels is the
/// decoding of the bilinear lookup (the map is affine), normalized where it is used.
pub fn decode_texel(c: [f32; 3], scale: f32) -> [f32; 3] {
    [
        (2.0 * c[0] - 1.0) * scale,
        (2.0 * c[1] - 1.0) * scale,
        2.0 * c[2] - 1.0,
    ]
}

/// A triangle's texture axes: `(dP/du, dP/dv)` for positions `p` and texture coordinates
/// `uv` of its three corners, or `None` where the coordinates are degenerate (all equal, or
/// on one line): then no map can be applied on it.
pub fn triangle_uv_axes(p: [[f32; 3]; 3], uv: [[f32; 2]; 3]) -> Option<([f32; 3], [f32; 3])> {
    let e1 = sub(p[1], p[0]);
    let e2 = sub(p[2], p[0]);
    let (du1, dv1) = (uv[1][0] - uv[0][0], uv[1][1] - uv[0][1]);
    let (du2, dv2) = (uv[2][0] - uv[0][0], uv[2][1] - uv[0][1]);
    let det = du1 * dv2 - du2 * dv1;
    if !det.is_finite() || det.abs() < 1e-20 {
        return None;
    }
    let r = 1.0 / det;
    let dpdu = [
        (e1[0] * dv2 - e2[0] * dv1) * r,
        (e1[1] * dv2 - e2[1] * dv1) * r,
        (e1[2] * dv2 - e2[2] * dv1) * r,
    ];
    let dpdv = [
        (e2[0] * du1 - e1[0] * du2) * r,
        (e2[1] * du1 - e1[1] * du2) * r,
        (e2[2] * du1 - e1[2] * du2) * r,
    ];
    (dpdu.iter().chain(&dpdv).all(|x| x.is_finite())).then_some((dpdu, dpdv))
}

/// The shading normal that a map's (decoded, bilinear) sample `m` gives at a point with unit
/// interpolated normal `n` on a triangle with texture axes `(dpdu, dpdv)`
/// ([`triangle_uv_axes`]): `normalize(t m.x + b m.y + n m.z)` with `t` dP/du made orthogonal
/// to `n` and `b = +-(n x t)`, the sign that points up the image (-dP/dv), so a mirrored UV
/// layout bends the normal the way its image shows. Returns `n` where the frame or the result
/// is degenerate (dP/du along `n`, a zero sample).
pub fn perturb(n: [f32; 3], axes: ([f32; 3], [f32; 3]), m: [f32; 3]) -> [f32; 3] {
    let (dpdu, dpdv) = axes;
    let t = sub(dpdu, scale(n, dot(n, dpdu)));
    let len = dot(t, t).sqrt();
    // NaN fails both tests.
    let usable = len > 1e-12 * dot(dpdu, dpdu).sqrt() && len.is_finite();
    if !usable {
        return n;
    }
    let t = scale(t, 1.0 / len);
    let mut b = cross(n, t);
    if dot(b, dpdv) > 0.0 {
        // +v runs down the image: "up" is -dP/dv.
        b = scale(b, -1.0);
    }
    let out = [
        t[0] * m[0] + b[0] * m[1] + n[0] * m[2],
        t[1] * m[0] + b[1] * m[1] + n[1] * m[2],
        t[2] * m[0] + b[2] * m[1] + n[2] * m[2],
    ];
    let len = dot(out, out).sqrt();
    let usable = len > 0.0 && len.is_finite();
    if !usable {
        return n;
    }
    scale(out, 1.0 / len)
}

fn sub(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn scale(a: [f32; 3], s: f32) -> [f32; 3] {
    [a[0] * s, a[1] * s, a[2] * s]
}

fn dot(a: [f32; 3], b: [f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: [f32; 3], b: [f32; 3]) -> bool {
        (0..3).all(|i| (a[i] - b[i]).abs() < 1e-5)
    }

    /// A quad in the XZ plane facing +Y, its image laid so that +u runs along +X and the
    /// image's top row (v = 0) lies at -Z: "up in the image" is -Z.
    fn quad_axes(mirror_u: bool) -> ([f32; 3], [f32; 3]) {
        let p = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]];
        let u1 = if mirror_u { -1.0 } else { 1.0 };
        let uv = [[0.0, 0.0], [u1, 0.0], [0.0, 1.0]];
        triangle_uv_axes(p, uv).expect("a proper UV layout")
    }

    #[test]
    fn a_flat_texel_keeps_the_normal_and_tilts_follow_the_image_axes() {
        let n = [0.0, 1.0, 0.0];
        let axes = quad_axes(false);
        assert!(close(axes.0, [1.0, 0.0, 0.0]) && close(axes.1, [0.0, 0.0, 1.0]));
        // (0.5, 0.5, 1) encodes (0, 0, 1): the normal itself.
        let flat = decode_texel([0.5, 0.5, 1.0], 1.0);
        assert!(close(perturb(n, axes, flat), n));
        // Tilted towards +X (the image's right) by 45 degrees.
        let s = std::f32::consts::FRAC_1_SQRT_2;
        assert!(close(perturb(n, axes, [s, 0.0, s]), [s, s, 0.0]));
        // Tilted up the image, which is -Z here.
        assert!(close(perturb(n, axes, [0.0, s, s]), [0.0, s, -s]));
        // A mirrored u axis turns "right" over; "up" stays.
        let m = quad_axes(true);
        assert!(close(perturb(n, m, [s, 0.0, s]), [-s, s, 0.0]));
        assert!(close(perturb(n, m, [0.0, s, s]), [0.0, s, -s]));
    }

    #[test]
    fn scale_bends_x_and_y_only_and_degenerate_layouts_keep_the_normal() {
        assert_eq!(decode_texel([1.0, 0.0, 0.5], 0.5), [0.5, -0.5, 0.0]);
        let p = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]];
        assert!(triangle_uv_axes(p, [[0.3, 0.3]; 3]).is_none());
        assert!(triangle_uv_axes(p, [[0.0, 0.0], [1.0, 1.0], [2.0, 2.0]]).is_none());
        // dP/du along the normal: no tangent to build a frame on.
        let n = [1.0, 0.0, 0.0];
        assert_eq!(perturb(n, quad_axes(false), [0.7, 0.0, 0.7]), n);
        // A zero sample (a map of 0.5 grey with z = 0.5) keeps the normal.
        let up = [0.0, 1.0, 0.0];
        assert_eq!(perturb(up, quad_axes(false), [0.0, 0.0, 0.0]), up);
    }
}
