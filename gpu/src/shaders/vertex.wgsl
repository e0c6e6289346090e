// The per-vertex view stage (docs/vertex.md, sections 3 and 4; docs/gpu.md): the mesh is
// drawn by the rasterizer, which interpolates each fragment's barycentric weights
// perspective-correctly; the fragment shader blends the triangle's three vertex records with
// them and shades the last reflection towards the eye (Tucker shading with the specular
// split), the CPU runtime's `shade` step for step. Pixels no triangle covers show the
// environment (the `background` entry points).
//
// Why the records are blended here and not passed as vertex outputs: a record is up to
// 6 + 48 + 3 r_i floats (78 for the thesis' ranks), beyond the 16 four-float locations a
// vertex may pass to the rasterizer; the weights it interpolates are the same ones.

struct Frame {
    eye: vec4<f32>,
    right: vec4<f32>,
    up: vec4<f32>,
    forward: vec4<f32>,
    // Rows of R_y(-rotation): radiance from world direction d is the map's from back d.
    back0: vec4<f32>,
    back1: vec4<f32>,
    back2: vec4<f32>,
    tan_half_fov: f32,
    aspect: f32,
    near: f32,
    turned: u32,
    width: f32,
    height: f32,
    env_width: u32,
    env_height: u32,
    // Offsets into `geometry` (floats) and `index` (words).
    normals_at: u32,
    uvs_at: u32,
    materials_of_at: u32,
    vertex_info_at: u32,
    texture_info_at: u32,
    cube_size_at: u32,
    // The open sky's irradiance table among the cubes, or -1.
    open_sky_cube: i32,
    // Sub-samples per side of a background pixel (VertexSurface::background_samples).
    background_samples: u32,
    // The compact lights in `environment` (8 floats each: the unturned direction, 0, the
    // power, 0) and how many (VertexSurface::compact_lights).
    lights_at: u32,
    n_lights: u32,
    pad0: u32,
    pad1: u32,
}

struct Material {
    kd: vec3<f32>,
    // Its group, or -1: no data, shown black.
    group: i32,
    ks: vec3<f32>,
    // Its texture, or -1.
    texture: i32,
    // Its shading basis, or -1: diffuse only.
    basis: i32,
    // Where its contracted core (r_o x r_i) starts in `cores`.
    core_at: u32,
    taps_len: u32,
    tap0: u32,
    tap0_w: f32,
    tap1: u32,
    tap1_w: f32,
    // Its normal map (a texture of decoded vectors), or -1.
    normal_map: i32,
    // Its family (FAMILY_*) and parameter: the compact lights' true lobe.
    family: u32,
    param: f32,
    pad0: u32,
    pad1: u32,
}

struct Basis {
    n_theta: u32,
    n_phi: u32,
    r_o: u32,
    r_i: u32,
    n_widths: u32,
    n_dirs: u32,
    // Offsets into `tables` (floats).
    u_o_at: u32,
    u_o_pole_at: u32,
    refl_at: u32,
    refl_pole_at: u32,
    // Per split width 8 floats: the prefiltered cube (bits of a u32; width 0 too), then the
    // 4 SH band factors, then the Gaussian's spread in radians (`cosine_centroid`).
    widths_at: u32,
    pad: u32,
}

@group(0) @binding(0) var<uniform> frame: Frame;
// Positions (3 per vertex), then normals, then texture coordinates (2 per vertex).
@group(0) @binding(1) var<storage, read> geometry: array<f32>;
// Triangles (3 per triangle), their materials, per vertex (record offset, visibility
// offset in bytes), per texture (offset in `tables`, width, height, 0), per cube its side.
@group(0) @binding(2) var<storage, read> index: array<u32>;
@group(0) @binding(3) var<storage, read> records: array<f32>;
@group(0) @binding(4) var<storage, read> visibility: array<u32>;
@group(0) @binding(5) var<storage, read> materials: array<Material>;
@group(0) @binding(6) var<storage, read> bases: array<Basis>;
// The bases' tables and the textures' texels (3 per texel).
@group(0) @binding(7) var<storage, read> tables: array<f32>;
// The lighting map's texels (3 per texel), then its compact lights (Frame::lights_at), and
// the materials' contracted cores.
@group(0) @binding(8) var<storage, read> environment: array<f32>;
@group(0) @binding(9) var<storage, read> cores: array<f32>;
// The prefiltered cubes, cube c in layers 6 c .. 6 c + 5 (face order +X -X +Y -Y +Z -Z),
// each in the top-left side x side texels.
@group(0) @binding(10) var cubes: texture_2d_array<f32>;

const PI: f32 = 3.14159265358979;
const TAU: f32 = 6.28318530717959;
const E_AT: u32 = 0u;
const I2_AT: u32 = 3u;
const I1_AT: u32 = 6u;
const U_AT: u32 = 54u;
const VISIBILITY_CUBE: u32 = 16u;
const MAX_RANK: u32 = 32u;
const MAX_WIDTHS: u32 = 8u;
const FAMILY_BLINN_PHONG: u32 = 1u;
const FAMILY_GGX: u32 = 2u;

// The family's specular lobe at local unit directions (prt_formats::lobe::specular_lobe).
fn specular_lobe(family: u32, param: f32, wo: vec3<f32>, wi: vec3<f32>) -> f32 {
    if !(wo.z > 0.0) || !(wi.z > 0.0) {
        return 0.0;
    }
    let h = wi + wo;
    let len = length(h);
    if len <= 1e-12 {
        return 0.0;
    }
    let cos_h = clamp(h.z / len, 0.0, 1.0);
    if family == FAMILY_BLINN_PHONG {
        if cos_h <= 0.0 {
            return select(0.0, 1.0 / PI, param == 0.0);
        }
        return (param + 2.0) * (0.5 / PI) * exp(param * log(cos_h));
    }
    if family == FAMILY_GGX {
        let a2 = param * param;
        let c2 = cos_h * cos_h;
        let denom = a2 * c2 + max(1.0 - c2, 0.0);
        if denom <= 0.0 {
            return 0.0;
        }
        let d = a2 / (PI * denom * denom);
        let g1i = 2.0 * wi.z / (wi.z + sqrt(a2 + (1.0 - a2) * wi.z * wi.z));
        let g1o = 2.0 * wo.z / (wo.z + sqrt(a2 + (1.0 - a2) * wo.z * wo.z));
        return d * g1i * g1o / (4.0 * wi.z * wo.z);
    }
    return 0.0;
}

struct MeshOut {
    @builtin(position) position: vec4<f32>,
    // The weights of the triangle's vertices 1 and 2 (vertex 0's is 1 minus both).
    @location(0) bary: vec2<f32>,
    @location(1) @interpolate(flat) triangle: u32,
}

fn position_of(v: u32) -> vec3<f32> {
    return vec3<f32>(geometry[3u * v], geometry[3u * v + 1u], geometry[3u * v + 2u]);
}

fn normal_of(v: u32) -> vec3<f32> {
    let at = frame.normals_at + 3u * v;
    return vec3<f32>(geometry[at], geometry[at + 1u], geometry[at + 2u]);
}

fn uv_of(v: u32) -> vec2<f32> {
    let at = frame.uvs_at + 2u * v;
    return vec2<f32>(geometry[at], geometry[at + 1u]);
}

// Non-indexed draw of 3 T vertices: vertex k of the draw is corner k % 3 of triangle k / 3.
@vertex
fn mesh_vertex(@builtin(vertex_index) k: u32) -> MeshOut {
    let t = k / 3u;
    let corner = k % 3u;
    let p = position_of(index[3u * t + corner]) - frame.eye.xyz;
    let x = dot(p, frame.right.xyz);
    let y = dot(p, frame.up.xyz);
    let z = dot(p, frame.forward.xyz);
    var out: MeshOut;
    // The film formula (docs/conventions.md, "Camera"): x_ndc = (x / z) / (tan aspect), and
    // reversed depth near / z (1 at the near plane, towards 0 far away; compared "greater").
    out.position = vec4<f32>(x / (frame.tan_half_fov * frame.aspect), y / frame.tan_half_fov, frame.near, z);
    out.bary = vec2<f32>(select(0.0, 1.0, corner == 1u), select(0.0, 1.0, corner == 2u));
    out.triangle = t;
    return out;
}

@fragment
fn mesh_fragment(in: MeshOut) -> @location(0) vec4<f32> {
    return vec4<f32>(shade(in.triangle, in.bary), 1.0);
}

struct BackgroundOut {
    @builtin(position) position: vec4<f32>,
}

// One triangle covering the image at depth 0 (the far end of the reversed depth).
@vertex
fn background_vertex(@builtin(vertex_index) k: u32) -> BackgroundOut {
    let xy = vec2<f32>(f32((k << 1u) & 2u), f32(k & 2u)) * 2.0 - 1.0;
    var out: BackgroundOut;
    out.position = vec4<f32>(xy, 0.0, 1.0);
    return out;
}

// The radiance through film position (x, y) in pixels (the film formula).
fn film_radiance(x: f32, y: f32) -> vec3<f32> {
    let sx = (2.0 * x / frame.width - 1.0) * frame.tan_half_fov * frame.aspect;
    let sy = (1.0 - 2.0 * y / frame.height) * frame.tan_half_fov;
    let d = normalize(frame.forward.xyz + frame.right.xyz * sx + frame.up.xyz * sy);
    return radiance(d);
}

// The map averaged over k x k film positions at the centres of a regular grid over the pixel
// (k = frame.background_samples; 1: its centre), summed row by row as the CPU sums them.
@fragment
fn background_fragment(in: BackgroundOut) -> @location(0) vec4<f32> {
    let k = max(frame.background_samples, 1u);
    if k == 1u {
        return vec4<f32>(film_radiance(in.position.x, in.position.y), 1.0);
    }
    let corner = floor(in.position.xy);
    let step = 1.0 / f32(k);
    var sum = vec3<f32>(0.0);
    for (var j = 0u; j < k; j++) {
        for (var i = 0u; i < k; i++) {
            let at = corner + (vec2<f32>(f32(i), f32(j)) + 0.5) * step;
            sum += film_radiance(at.x, at.y);
        }
    }
    return vec4<f32>(sum / f32(k * k), 1.0);
}

// R_y(-rotation) d.
fn turn_back(d: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(dot(frame.back0.xyz, d), dot(frame.back1.xyz, d), dot(frame.back2.xyz, d));
}

fn env_texel(x: u32, y: u32) -> vec3<f32> {
    let at = 3u * (y * frame.env_width + x);
    return vec3<f32>(environment[at], environment[at + 1u], environment[at + 2u]);
}

// The environment's radiance from world direction d: the lat-long map at back d, bilinear
// (`latlong_bilinear`, shaders/latlong.wgsl).
fn radiance(d: vec3<f32>) -> vec3<f32> {
    return latlong_bilinear(turn_back(d), frame.env_width, frame.env_height);
}

// prt_formats::lighting::cubemap::direction_to_face_st: (face, s, t).
struct FaceSt {
    face: u32,
    s: f32,
    t: f32,
}

fn face_st(d: vec3<f32>) -> FaceSt {
    let a = abs(d);
    var out: FaceSt;
    if !(a.x < 3.4e38 && a.y < 3.4e38 && a.z < 3.4e38) || (a.x == 0.0 && a.y == 0.0 && a.z == 0.0) {
        out.face = 0u;
        out.s = 0.5;
        out.t = 0.5;
        return out;
    }
    var u = 0.0;
    var v = 0.0;
    var major = 1.0;
    if a.x >= a.y && a.x >= a.z {
        major = a.x;
        if d.x > 0.0 {
            out.face = 0u; u = -d.z; v = -d.y;
        } else {
            out.face = 1u; u = d.z; v = -d.y;
        }
    } else if a.y >= a.z {
        major = a.y;
        if d.y > 0.0 {
            out.face = 2u; u = d.x; v = d.z;
        } else {
            out.face = 3u; u = d.x; v = -d.z;
        }
    } else {
        major = a.z;
        if d.z > 0.0 {
            out.face = 4u; u = d.x; v = -d.y;
        } else {
            out.face = 5u; u = -d.x; v = -d.y;
        }
    }
    out.s = clamp(0.5 * (u / major + 1.0), 0.0, 1.0);
    out.t = clamp(0.5 * (v / major + 1.0), 0.0, 1.0);
    return out;
}

// The direction of face coordinates (a, b) in [-1, 1] (unnormalized).
fn face_ab_to_vector(face: u32, a: f32, b: f32) -> vec3<f32> {
    switch face {
        case 0u: { return vec3<f32>(1.0, -b, -a); }
        case 1u: { return vec3<f32>(-1.0, -b, a); }
        case 2u: { return vec3<f32>(a, 1.0, b); }
        case 3u: { return vec3<f32>(a, -1.0, -b); }
        case 4u: { return vec3<f32>(a, -b, 1.0); }
        default: { return vec3<f32>(-a, -b, -1.0); }
    }
}

// Texel (i, j) of face f of a cube of side n as (face, x, y), where (i, j) may lie one texel
// off the face: then the texel of the neighbouring face holding that point
// (prt_formats::lighting::cubemap::bilinear_taps).
fn wrapped_texel(n: u32, f: u32, i: i32, j: i32) -> vec3<u32> {
    if i < 0 || j < 0 || i >= i32(n) || j >= i32(n) {
        let nf = f32(n);
        let a = 2.0 * (f32(i) + 0.5) / nf - 1.0;
        let b = 2.0 * (f32(j) + 0.5) / nf - 1.0;
        let at = face_st(face_ab_to_vector(f, a, b));
        return vec3<u32>(at.face, min(u32(at.s * nf), n - 1u), min(u32(at.t * nf), n - 1u));
    }
    return vec3<u32>(f, u32(i), u32(j));
}

// Cube c's texel (i, j) of face f, continued across its edges (wrapped_texel).
fn cube_texel(c: u32, n: u32, f: u32, i: i32, j: i32) -> vec3<f32> {
    let k = wrapped_texel(n, f, i, j);
    return textureLoad(cubes, vec2<i32>(i32(k.y), i32(k.z)), i32(6u * c + k.x), 0).xyz;
}

// The standard normal distribution for t >= 0 given g = exp(-t^2 / 2) (the runtime's
// `normal_cdf`: Abramowitz and Stegun 7.1.26 for erf, the same coefficients).
fn normal_cdf(t: f32, g: f32) -> f32 {
    let x = t * 0.70710677;
    let k = 1.0 / (1.0 + 0.3275911 * x);
    let poly = k * (0.2548296 + k * (-0.28449674 + k * (1.4214137 + k * (-1.453152 + k * 1.0614054))));
    return 0.5 * (1.0 + (1.0 - poly * g));
}

// Where a split Gaussian of spread sigma about the local mirror direction r is read: r raised
// towards the normal by the cosine-weighted centroid's tilt (prt_formats::basis::
// cosine_centroid, the same formula).
fn cosine_centroid(r: vec3<f32>, sigma: f32) -> vec3<f32> {
    let z = max(r.z, 0.0);
    let h = sqrt(r.x * r.x + r.y * r.y);
    if sigma <= 0.0 || h <= 1e-6 * z {
        return r;
    }
    let t = z / (h * sigma);
    var delta = sigma / t;
    if t <= 12.0 {
        let g = exp(-0.5 * t * t);
        let cdf = normal_cdf(t, g);
        delta = sigma * cdf / (t * cdf + g * 0.3989423);
    }
    if delta <= 0.0 {
        return r;
    }
    let sd = sin(delta);
    let cd = cos(delta);
    let h2 = h * cd - z * sd;
    if h2 <= 0.0 {
        return vec3<f32>(0.0, 0.0, 1.0);
    }
    let k = h2 / h;
    return vec3<f32>(r.x * k, r.y * k, z * cd + h * sd);
}

// The visible fraction in the visibility cube starting at byte `at`, texel (i, j) of face f
// continued across its edges.
fn visible_texel(at: u32, f: u32, i: i32, j: i32) -> f32 {
    let k = wrapped_texel(VISIBILITY_CUBE, f, i, j);
    return visible_byte(at + (k.x * VISIBILITY_CUBE + k.z) * VISIBILITY_CUBE + k.y);
}

// The visibility cube starting at byte `at` at (face, s, t), bilinear across face edges as
// cube_bilinear is (the CPU runtime's view stage).
fn visible_bilinear(at: u32, p: FaceSt) -> f32 {
    let k = bilinear_cell(VISIBILITY_CUBE, p);
    return visible_texel(at, p.face, k.i, k.j) * ((1.0 - k.tx) * (1.0 - k.ty))
        + visible_texel(at, p.face, k.i + 1, k.j) * (k.tx * (1.0 - k.ty))
        + visible_texel(at, p.face, k.i, k.j + 1) * ((1.0 - k.tx) * k.ty)
        + visible_texel(at, p.face, k.i + 1, k.j + 1) * (k.tx * k.ty);
}

// The bilinear cell of (face, s, t) in a cube of side n: the lower texel (i, j), which may lie
// one texel off the face, and the weights (tx, ty) of the next ones.
struct Cell {
    i: i32,
    j: i32,
    tx: f32,
    ty: f32,
}

fn bilinear_cell(n: u32, at: FaceSt) -> Cell {
    let nf = f32(n);
    let fx = at.s * nf - 0.5;
    let fy = at.t * nf - 0.5;
    let x0 = floor(fx);
    let y0 = floor(fy);
    return Cell(i32(x0), i32(y0), fx - x0, fy - y0);
}

// Cube c at (face, s, t), bilinear across face edges.
fn cube_bilinear(c: u32, at: FaceSt) -> vec3<f32> {
    let n = index[frame.cube_size_at + c];
    let k = bilinear_cell(n, at);
    return cube_texel(c, n, at.face, k.i, k.j) * ((1.0 - k.tx) * (1.0 - k.ty))
        + cube_texel(c, n, at.face, k.i + 1, k.j) * (k.tx * (1.0 - k.ty))
        + cube_texel(c, n, at.face, k.i, k.j + 1) * ((1.0 - k.tx) * k.ty)
        + cube_texel(c, n, at.face, k.i + 1, k.j + 1) * (k.tx * k.ty);
}

// prt_formats::vertex::vertex_frame: the tangent and bitangent of normal n.
fn vertex_frame_t(n: vec3<f32>) -> vec3<f32> {
    let a = vec3<f32>(0.13018891, 0.39056673, 0.9113224);
    let b = vec3<f32>(0.9113224, 0.13018891, -0.39056673);
    var t = cross(a, n);
    var len2 = dot(t, t);
    if len2 < 0.02 {
        t = cross(b, n);
        len2 = dot(t, t);
    }
    return t * (1.0 / sqrt(len2));
}

// The 16 real SH basis functions of order 4 at unit d (prt_formats::lighting::sh::sh_eval).
fn sh_eval(d: vec3<f32>, y: ptr<function, array<f32, 16>>) {
    let x = d.x;
    let yy = d.y;
    let z = d.z;
    let x2 = x * x;
    let y2 = yy * yy;
    let z2 = z * z;
    (*y)[0] = 0.28209479177387814;
    (*y)[1] = -0.4886025119029199 * yy;
    (*y)[2] = 0.4886025119029199 * z;
    (*y)[3] = -0.4886025119029199 * x;
    (*y)[4] = 1.0925484305920792 * x * yy;
    (*y)[5] = -1.0925484305920792 * yy * z;
    (*y)[6] = 0.31539156525252005 * (3.0 * z2 - 1.0);
    (*y)[7] = -1.0925484305920792 * x * z;
    (*y)[8] = 0.5462742152960396 * (x2 - y2);
    (*y)[9] = -0.5900435899266435 * yy * (3.0 * x2 - y2);
    (*y)[10] = 2.890611442640554 * x * yy * z;
    (*y)[11] = -0.4570457994644658 * yy * (5.0 * z2 - 1.0);
    (*y)[12] = 0.3731763325901154 * z * (5.0 * z2 - 3.0);
    (*y)[13] = -0.4570457994644658 * x * (5.0 * z2 - 1.0);
    (*y)[14] = 1.445305721320277 * z * (x2 - y2);
    (*y)[15] = -0.5900435899266435 * x * (x2 - 3.0 * y2);
}

fn sh_band(s: u32) -> u32 {
    if s == 0u {
        return 0u;
    }
    if s <= 3u {
        return 1u;
    }
    if s <= 8u {
        return 2u;
    }
    return 3u;
}

// HemiGrid::weights: the four surrounding nodes of a local direction and the pole's weight.
struct HemiWeights {
    n: array<u32, 4>,
    w: array<f32, 4>,
    pole: f32,
}

fn hemi_weights(w: vec3<f32>, nt: u32, np: u32) -> HemiWeights {
    var out: HemiWeights;
    let len2 = dot(w, w);
    if !(len2 > 0.0 && len2 < 3.4e38) {
        out.pole = 1.0;
        return out;
    }
    let z = clamp(w.z / sqrt(len2), -1.0, 1.0);
    let v = (1.0 - z) * f32(nt) - 0.5;
    var j0 = 0u;
    var j1 = 0u;
    var fz = 0.0;
    var pole = 0.0;
    if v <= 0.0 {
        pole = min(-2.0 * v, 1.0);
    } else if v >= f32(nt - 1u) {
        j0 = nt - 1u;
        j1 = nt - 1u;
    } else {
        j0 = min(u32(v), nt - 2u);
        j1 = j0 + 1u;
        fz = clamp(v - f32(j0), 0.0, 1.0);
    }
    let u = atan2(w.y, w.x) * (f32(np) / TAU) - 0.5;
    let uf = floor(u);
    let fp = clamp(u - uf, 0.0, 1.0);
    let k0 = u32(((i32(uf) % i32(np)) + i32(np)) % i32(np));
    let k1 = select(k0 + 1u, 0u, k0 + 1u >= np);
    let ring = 1.0 - pole;
    let a = ring * (1.0 - fz);
    let b = ring * fz;
    out.n = array<u32, 4>(j0 * np + k0, j0 * np + k1, j1 * np + k0, j1 * np + k1);
    out.w = array<f32, 4>(a * (1.0 - fp), a * fp, b * (1.0 - fp), b * fp);
    out.pole = pole;
    return out;
}

fn texture_rgb(t: u32, uv: vec2<f32>) -> vec3<f32> {
    let info = frame.texture_info_at + 4u * t;
    let at = index[info];
    let width = index[info + 1u];
    let height = index[info + 2u];
    if width == 0u || height == 0u || !(abs(uv.x) < 3.4e38 && abs(uv.y) < 3.4e38) {
        return vec3<f32>(1.0);
    }
    // prt_formats::texture::sample_bilinear: wrapped.
    let x = uv.x * f32(width) - 0.5;
    let y = uv.y * f32(height) - 0.5;
    let x0 = floor(x);
    let y0 = floor(y);
    let fx = x - x0;
    let fy = y - y0;
    let xa = u32(((i32(x0) % i32(width)) + i32(width)) % i32(width));
    let xb = u32(((i32(x0 + 1.0) % i32(width)) + i32(width)) % i32(width));
    let ya = u32(((i32(y0) % i32(height)) + i32(height)) % i32(height));
    let yb = u32(((i32(y0 + 1.0) % i32(height)) + i32(height)) % i32(height));
    let t00 = tex_texel(at, ya * width + xa);
    let t01 = tex_texel(at, ya * width + xb);
    let t10 = tex_texel(at, yb * width + xa);
    let t11 = tex_texel(at, yb * width + xb);
    return t00 * ((1.0 - fx) * (1.0 - fy)) + t01 * (fx * (1.0 - fy)) + t10 * ((1.0 - fx) * fy)
        + t11 * (fx * fy);
}

fn tex_texel(at: u32, i: u32) -> vec3<f32> {
    let k = at + 3u * i;
    return vec3<f32>(tables[k], tables[k + 1u], tables[k + 2u]);
}

fn visible_byte(at: u32) -> f32 {
    let word = visibility[at >> 2u];
    return f32((word >> (8u * (at & 3u))) & 255u) / 255.0;
}

// Whether the data side of triangle (v0, v1, v2) (the side its normal n is on) faces the eye.
fn data_side_faces_eye(v0: u32, v1: u32, v2: u32, n: vec3<f32>, wo: vec3<f32>) -> bool {
    let p0 = position_of(v0);
    var ng = cross(position_of(v1) - p0, position_of(v2) - p0);
    if dot(ng, n) < 0.0 {
        ng = -ng;
    }
    return dot(ng, wo) > 0.0;
}

// prt_formats::normal_map::triangle_uv_axes: dP/du and dP/dv of a triangle.
struct UvAxes {
    dpdu: vec3<f32>,
    dpdv: vec3<f32>,
    ok: bool,
}

fn triangle_uv_axes(
    p0: vec3<f32>,
    p1: vec3<f32>,
    p2: vec3<f32>,
    t0: vec2<f32>,
    t1: vec2<f32>,
    t2: vec2<f32>,
) -> UvAxes {
    var out: UvAxes;
    let e1 = p1 - p0;
    let e2 = p2 - p0;
    let d1 = t1 - t0;
    let d2 = t2 - t0;
    let det = d1.x * d2.y - d2.x * d1.y;
    if !(abs(det) >= 1e-20 && abs(det) < 3.4e38) {
        return out;
    }
    let r = 1.0 / det;
    out.dpdu = (e1 * d2.y - e2 * d1.y) * r;
    out.dpdv = (e2 * d1.x - e1 * d2.x) * r;
    let huge = vec3<f32>(3.4e38);
    out.ok = all(abs(out.dpdu) < huge) && all(abs(out.dpdv) < huge);
    return out;
}

// prt_formats::normal_map::perturb: n bent by the map's sample m in the frame of the axes.
fn perturb(n: vec3<f32>, axes: UvAxes, m: vec3<f32>) -> vec3<f32> {
    var t = axes.dpdu - n * dot(n, axes.dpdu);
    let len = sqrt(dot(t, t));
    if !(len > 1e-12 * sqrt(dot(axes.dpdu, axes.dpdu))) || !(len < 3.4e38) {
        return n;
    }
    t = t * (1.0 / len);
    var b = cross(n, t);
    if dot(b, axes.dpdv) > 0.0 {
        b = -b;
    }
    let out = t * m.x + b * m.y + n * m.z;
    let l = sqrt(dot(out, out));
    if !(l > 0.0) || !(l < 3.4e38) {
        return n;
    }
    return out * (1.0 / l);
}

// The radiance towards the eye from triangle t at barycentrics bary (runtime `shade`).
fn shade(t: u32, bary: vec2<f32>) -> vec3<f32> {
    let v0 = index[3u * t];
    let v1 = index[3u * t + 1u];
    let v2 = index[3u * t + 2u];
    let m = materials[index[frame.materials_of_at + t]];
    let w = vec3<f32>(1.0 - bary.x - bary.y, bary.x, bary.y);
    let n = normalize(w.x * normal_of(v0) + w.y * normal_of(v1) + w.z * normal_of(v2));
    let p = w.x * position_of(v0) + w.y * position_of(v1) + w.z * position_of(v2);
    let wo = normalize(frame.eye.xyz - p);
    if m.group < 0 {
        return vec3<f32>(0.0);
    }
    let glossy = m.basis >= 0;
    // The shading normal: n, or n bent by the material's normal map (runtime `shade`); the
    // records stay in the frame of n.
    var ns = n;
    var bent = false;
    if m.normal_map >= 0 {
        let u0 = uv_of(v0);
        let u1 = uv_of(v1);
        let u2 = uv_of(v2);
        let axes = triangle_uv_axes(position_of(v0), position_of(v1), position_of(v2), u0, u1, u2);
        if axes.ok {
            let uv = w.x * u0 + w.y * u1 + w.z * u2;
            ns = perturb(n, axes, texture_rgb(u32(m.normal_map), uv));
            bent = true;
        }
    }
    if bent && !(dot(n, wo) > 0.0) && !data_side_faces_eye(v0, v1, v2, n, wo) {
        // A bent normal may face the eye from the side without data: black there too.
        return vec3<f32>(0.0);
    }
    let n_dot_wo = dot(ns, wo);
    var tangent = vec3<f32>(0.0);
    var bitangent = vec3<f32>(0.0);
    var wo_l = vec3<f32>(0.0, 0.0, 1.0);
    if glossy || !(n_dot_wo > 0.0) {
        tangent = vertex_frame_t(ns);
        bitangent = cross(ns, tangent);
        wo_l = vec3<f32>(dot(tangent, wo), dot(bitangent, wo), dot(ns, wo));
        if !(wo_l.z > 0.0) {
            // Seen from below the shading normal's horizon (the back of a surface, or a
            // silhouette where the interpolated normal turns away): black, as on the CPU.
            return vec3<f32>(0.0);
        }
    }
    let r0 = index[frame.vertex_info_at + 2u * v0];
    let r1 = index[frame.vertex_info_at + 2u * v1];
    let r2 = index[frame.vertex_info_at + 2u * v2];
    var tex = vec3<f32>(1.0);
    if m.texture >= 0 {
        let uv = w.x * uv_of(v0) + w.y * uv_of(v1) + w.z * uv_of(v2);
        tex = texture_rgb(u32(m.texture), uv);
    }
    var e_scale = vec3<f32>(1.0);
    if bent && frame.open_sky_cube >= 0 {
        // The open sky's irradiance at the bent normal over that at n (runtime
        // `bent_irradiance_scale`); a channel the sky leaves dark at n keeps its irradiance.
        let c = u32(frame.open_sky_cube);
        let open_n = cube_bilinear(c, face_st(n));
        let open_nb = cube_bilinear(c, face_st(ns));
        let horizon = 0.5 * (1.0 + dot(n, ns));
        e_scale = select(vec3<f32>(1.0), horizon * open_nb / open_n, open_n > vec3<f32>(1e-12));
    }
    let e = rec3(r0, r1, r2, w, E_AT);
    var b = m.kd * tex * (1.0 / PI) * (e * e_scale);
    if !glossy {
        // The irradiance's kept Haar terms and SH can ring below 0 too.
        return max(b, vec3<f32>(0.0));
    }
    let basis = bases[u32(m.basis)];
    // The mirror direction, local and world.
    let r_l = vec3<f32>(-wo_l.x, -wo_l.y, wo_l.z);
    let r_w = tangent * r_l.x + bitangent * r_l.y + ns * r_l.z;
    // I1's SH is in the frame of the data's normal n.
    var r_sh = r_l;
    if bent {
        let t_n = vertex_frame_t(n);
        let b_n = cross(n, t_n);
        r_sh = vec3<f32>(dot(t_n, r_w), dot(b_n, r_w), dot(n, r_w));
    }
    // I1's SH at r, summed per band.
    var y: array<f32, 16>;
    sh_eval(r_sh, &y);
    var bands: array<vec3<f32>, 4>;
    for (var s = 0u; s < 16u; s = s + 1u) {
        let l = sh_band(s);
        bands[l] = bands[l] + rec3(r0, r1, r2, w, I1_AT + 3u * s) * y[s];
    }
    let i2 = rec3(r0, r1, r2, w, I2_AT);
    var prefiltered: array<vec3<f32>, 8>;
    for (var k = 0u; k < basis.n_widths; k = k + 1u) {
        let wat = basis.widths_at + 8u * k;
        // The environment and the visibility are read where the width's Gaussian, weighted
        // by the cosine, looks: r raised towards the normal (`cosine_centroid`).
        let c_l = cosine_centroid(r_l, tables[wat + 5u]);
        let c_w = tangent * c_l.x + bitangent * c_l.y + ns * c_l.z;
        let at = face_st(c_w);
        // Visible fraction, bilinear in the 16-cube, interpolated over the vertices.
        let visible = w.x * visible_bilinear(index[frame.vertex_info_at + 2u * v0 + 1u], at)
            + w.y * visible_bilinear(index[frame.vertex_info_at + 2u * v1 + 1u], at)
            + w.z * visible_bilinear(index[frame.vertex_info_at + 2u * v2 + 1u], at);
        var pat = at;
        if frame.turned != 0u {
            pat = face_st(turn_back(c_w));
        }
        let ibar = cube_bilinear(bitcast<u32>(tables[wat]), pat);
        let sh = tables[wat + 1u] * bands[0] + tables[wat + 2u] * bands[1]
            + tables[wat + 3u] * bands[2] + tables[wat + 4u] * bands[3];
        prefiltered[k] = visible * ibar + sh + i2;
    }
    // U^o(wo) and the split reflectances share wo's grid weights.
    let dw = hemi_weights(wo_l, basis.n_theta, basis.n_phi);
    var spec = vec3<f32>(0.0);
    for (var bo = 0u; bo < basis.r_o; bo = bo + 1u) {
        var uo = dw.pole * tables[basis.u_o_pole_at + bo];
        for (var q = 0u; q < 4u; q = q + 1u) {
            uo = uo + dw.w[q] * tables[basis.u_o_at + dw.n[q] * basis.r_o + bo];
        }
        var s = vec3<f32>(0.0);
        for (var c = 0u; c < basis.r_i; c = c + 1u) {
            s = s + cores[m.core_at + bo * basis.r_i + c] * rec3(r0, r1, r2, w, U_AT + 3u * c);
        }
        spec = spec + uo * s;
    }
    let nw = basis.n_widths;
    let slab = basis.n_dirs * nw;
    for (var k = 0u; k < nw; k = k + 1u) {
        var rw = 0.0;
        for (var tap = 0u; tap < m.taps_len; tap = tap + 1u) {
            let j = select(m.tap0, m.tap1, tap == 1u);
            let sw = select(m.tap0_w, m.tap1_w, tap == 1u);
            for (var q = 0u; q < 4u; q = q + 1u) {
                rw = rw + dw.w[q] * sw * tables[basis.refl_at + j * slab + dw.n[q] * nw + k];
            }
            rw = rw + dw.pole * sw * tables[basis.refl_pole_at + j * nw + k];
        }
        spec = spec + rw * prefiltered[k];
    }
    // The compact lights, which the records' U and the prefiltered cubes leave out: each
    // through the true lobe, shadowed by the same visibility (runtime `shade`).
    for (var k = 0u; k < frame.n_lights; k = k + 1u) {
        let at = frame.lights_at + 8u * k;
        let dm = vec3<f32>(environment[at], environment[at + 1u], environment[at + 2u]);
        // Into the world: the transpose of R_y(-rotation).
        let d = frame.back0.xyz * dm.x + frame.back1.xyz * dm.y + frame.back2.xyz * dm.z;
        let wi_l = vec3<f32>(dot(tangent, d), dot(bitangent, d), dot(ns, d));
        if !(wi_l.z > 0.0) {
            continue;
        }
        let f = specular_lobe(m.family, m.param, wo_l, wi_l) * wi_l.z;
        if !(f > 0.0) {
            continue;
        }
        let lat = face_st(d);
        let visible = w.x * visible_bilinear(index[frame.vertex_info_at + 2u * v0 + 1u], lat)
            + w.y * visible_bilinear(index[frame.vertex_info_at + 2u * v1 + 1u], lat)
            + w.z * visible_bilinear(index[frame.vertex_info_at + 2u * v2 + 1u], lat);
        let power = vec3<f32>(environment[at + 4u], environment[at + 5u], environment[at + 6u]);
        spec = spec + (f * visible) * power;
    }
    b = b + m.ks * spec;
    // Radiance is never negative, but its approximations can ring below 0 next to sharp
    // features: clamp them, as the CPU runtime does.
    return max(b, vec3<f32>(0.0));
}

// The RGB part of the records at `at`, blended with the weights w.
fn rec3(r0: u32, r1: u32, r2: u32, w: vec3<f32>, at: u32) -> vec3<f32> {
    let a = vec3<f32>(records[r0 + at], records[r0 + at + 1u], records[r0 + at + 2u]);
    let b = vec3<f32>(records[r1 + at], records[r1 + at + 1u], records[r1 + at + 2u]);
    let c = vec3<f32>(records[r2 + at], records[r2 + at + 1u], records[r2 + at + 2u]);
    return w.x * a + w.y * b + w.z * c;
}
