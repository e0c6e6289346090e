//! Texture lookup shared by the baker (textures at path vertices) and the per-vertex runtime
//! (the visible surface's base colour per pixel), so both see the same colour.

/// Bilinear lookup with repeat wrapping of a linear-RGB texture, row-major, top row first
/// (glTF UV (0, 0) is the top-left corner; texel centres at half-integers). A texture with no
/// texels, or a non-finite `uv`, reads as white.
pub fn sample_bilinear(texels: &[[f32; 3]], width: usize, height: usize, uv: [f32; 2]) -> [f32; 3] {
    if texels.len() < width * height {
        return [1.0; 3];
    }
    sample_bilinear_by(width, height, uv, |i| texels[i])
}

/// [`sample_bilinear`] over texels given by index (`y * width + x`), for callers that store
/// them in another type; `texel` is called with indices below `width * height` only.
pub fn sample_bilinear_by(
    width: usize,
    height: usize,
    uv: [f32; 2],
    texel: impl Fn(usize) -> [f32; 3],
) -> [f32; 3] {
    if width == 0 || height == 0 || !uv.iter().all(|v| v.is_finite()) {
        return [1.0; 3];
    }
    let x = uv[0] * width as f32 - 0.5;
    let y = uv[1] * height as f32 - 0.5;
    let x0 = x.floor();
    let y0 = y.floor();
    let fx = x - x0;
    let fy = y - y0;
    let wrap = |v: f32, n: usize| (v as i64).rem_euclid(n as i64) as usize;
    let (xa, xb) = (wrap(x0, width), wrap(x0 + 1.0, width));
    let (ya, yb) = (wrap(y0, height), wrap(y0 + 1.0, height));
    let w = [
        (1.0 - fx) * (1.0 - fy),
        fx * (1.0 - fy),
        (1.0 - fx) * fy,
        fx * fy,
    ];
    let t = [
        texel(ya * width + xa),
        texel(ya * width + xb),
        texel(yb * width + xa),
        texel(yb * width + xb),
    ];
    let mut out = [0.0f32; 3];
    for (c, o) in out.iter_mut().enumerate() {
        *o = t[0][c] * w[0] + t[1][c] * w[1] + t[2][c] * w[2] + t[3][c] * w[3];
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bilinear_hits_texel_centres_and_wraps() {
        let texels = [
            [0.0, 0.0, 0.0],
            [1.0, 2.0, 3.0],
            [4.0, 4.0, 4.0],
            [8.0, 8.0, 8.0],
        ];
        // Texel (1, 0)'s centre.
        assert_eq!(
            sample_bilinear(&texels, 2, 2, [0.75, 0.25]),
            [1.0, 2.0, 3.0]
        );
        // Halfway between (0, 1) and (1, 1).
        assert_eq!(sample_bilinear(&texels, 2, 2, [0.5, 0.75]), [6.0, 6.0, 6.0]);
        // Repeat: u = 1.75 is u = 0.75.
        assert_eq!(
            sample_bilinear(&texels, 2, 2, [1.75, 0.25]),
            [1.0, 2.0, 3.0]
        );
        // At u = 0 the lookup blends the first and the last column.
        assert_eq!(sample_bilinear(&texels, 2, 2, [0.0, 0.25]), [0.5, 1.0, 1.5]);
        assert_eq!(sample_bilinear(&texels, 2, 2, [f32::NAN, 0.0]), [1.0; 3]);
    }
}
