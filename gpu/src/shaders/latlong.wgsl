// A lat-long map's bilinear lookup (prt_formats::latlong::lookup_bilinear), shared by the
// shaders that read the lighting map: prepended to each (`concat!`), which defines
// `env_texel(x, y)`, the map's texel at column x and row y.

// The radiance of a `w x h` lat-long map in unit direction r (the map's own frame): texel
// values at texel centres, wrapped across the seam, the rows next to the poles clamped.
fn latlong_bilinear(r: vec3<f32>, w: u32, h: u32) -> vec3<f32> {
    let theta = acos(clamp(r.y, -1.0, 1.0));
    let phi = atan2(r.x, -r.z);
    let uu = phi / TAU + 0.5;
    return latlong_bilinear_uv(uu - floor(uu), clamp(theta / PI, 0.0, 1.0), w, h);
}

// The same at image coordinate (u, v) (prt_formats::latlong::bilinear).
fn latlong_bilinear_uv(u: f32, v: f32, w: u32, h: u32) -> vec3<f32> {
    let fx = (u - floor(u)) * f32(w) - 0.5;
    let x_floor = floor(fx);
    let tx = clamp(fx - x_floor, 0.0, 1.0);
    let x0 = u32(((i32(x_floor) % i32(w)) + i32(w)) % i32(w));
    let x1 = select(x0 + 1u, 0u, x0 + 1u == w);
    let fy = v * f32(h) - 0.5;
    var y0 = 0u;
    var y1 = 0u;
    var ty = 0.0;
    if fy <= 0.0 {
        y0 = 0u;
        y1 = 0u;
    } else if fy >= f32(h - 1u) {
        y0 = h - 1u;
        y1 = h - 1u;
    } else {
        let y_floor = floor(fy);
        y0 = min(u32(y_floor), h - 1u);
        y1 = min(y0 + 1u, h - 1u);
        ty = clamp(fy - y_floor, 0.0, 1.0);
    }
    return env_texel(x0, y0) * ((1.0 - tx) * (1.0 - ty)) + env_texel(x1, y0) * (tx * (1.0 - ty))
        + env_texel(x0, y1) * ((1.0 - tx) * ty) + env_texel(x1, y1) * (tx * ty);
}
