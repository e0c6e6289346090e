// A lat-long map's bilinear lookup (prt_formats::latlong::lookup_bilinear), shared by the
// shaders that read the lighting map: prepended to each (`concat!`), which defines
// `env_texel(x, y)`, the map's texel at column x and row y.

// The radiance of a `w x h` lat-long map in unit direction r (the map's own frame): texel
// values at texel centres, wrapped across the seam, the rows next to the poles clamped.
fn latlong_bilinear(r: vec3<f32>, w: u32, h: u32) -> vec3<f32> {
    // theta = acos(y), phi = atan2(x, -z), with `arc_tangent` (below) rather than the
    // driver's: a sharp light (a sun in the map, seen in a mirror or behind the mesh) moves
    // with the rounding of the angles, and drivers' acos/atan2 differ by more than f32's
    // (lavapipe: 1 % at a sun's edge against the CPU runtime).
    let theta = arc_tangent(length(r.xz), r.y);
    let phi = arc_tangent(r.x, -r.z);
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

// atan2(y, x) to about one f32 ulp of the angle: Cephes' `atanf` (range reduction to
// |t| <= tan(pi/8), then an odd polynomial), quadrants by the signs.
fn arc_tangent(y: f32, x: f32) -> f32 {
    let ax = abs(x);
    let ay = abs(y);
    if ax == 0.0 && ay == 0.0 {
        return select(0.0, 3.14159265358979, x < 0.0 || (x == 0.0 && 1.0 / x < 0.0)) * sign_or_one(y);
    }
    // a = atan(ay / ax) in [0, pi/2].
    var t = 0.0;
    var base = 0.0;
    if ay > 2.414213562373095 * ax {
        base = 1.5707963267948966;
        t = -ax / ay;
    } else if ay > 0.4142135623730950 * ax {
        base = 0.7853981633974483;
        t = (ay - ax) / (ay + ax);
    } else {
        t = ay / ax;
    }
    let z = t * t;
    let p = (((8.05374449538e-2 * z - 1.38776856032e-1) * z + 1.99777106478e-1) * z
        - 3.33329491539e-1) * z * t + t;
    var a = base + p;
    if x < 0.0 {
        a = 3.14159265358979 - a;
    }
    return select(a, -a, y < 0.0);
}

fn sign_or_one(v: f32) -> f32 {
    return select(1.0, -1.0, v < 0.0);
}
