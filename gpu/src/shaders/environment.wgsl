// The light stage's per-environment part on the device (docs/vertex.md, sections 1 and 4;
// the CPU runtime's `light.rs`): each time the light changes, the lighting map turned into the
// 6x64x64 cube map direct light is stored against, its area-weighted Haar coefficients C0, the
// solid-angle means C1 (6x8x8) and C2 (6x2x2), and the open sky's irradiance per normal
// (6x32x32, from the cube halved to 6x32x32). One invocation per output value; C0, C1, C2 and
// the open sky land in `light`, which the vertex kernels (shaders/stages.wgsl) read.
// Prepended: shaders/latlong.wgsl.

struct Env {
    // The rotation in turns (degrees / 360): a turn about +Y moves every direction's
    // lat-long u by it (radiance from d is the map's from R_y(-rotation) d, whose azimuth is
    // d's plus the rotation) and leaves v.
    turns: f32,
    // Where the map read lies in `map` (floats: the lighting map at 0, the map less its
    // compact lights after it) and where C0 goes in `light` (entries): the glossy rows' C0
    // is a second pass over the map less its lights.
    map_at: u32,
    c0_at: u32,
    pad5: u32,
    env_width: u32,
    env_height: u32,
    // Sub-samples per cube texel side (`subsamples_per_texel`), and per face side.
    m: u32,
    ns: u32,
    // In `tables`: per sub-sample of the 6 x ns x ns grid its solid angle and the lat-long
    // (u, v) of its direction unturned (three floats), sqrt of the 64-cube's texel solid
    // angles, those solid angles, the 32-cube's, and its texel centre directions (4 floats).
    weights_at: u32,
    sqrt_omega_at: u32,
    omega_at: u32,
    omega32_at: u32,
    dirs32_at: u32,
    // In `light`: C1, C2, the open sky.
    c1_at: u32,
    c2_at: u32,
    open_sky_at: u32,
    // In `cube`: the 6x32x32 source of the open sky (after the 6x64x64 cube).
    source_at: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

const PI: f32 = 3.14159265358979;
const TAU: f32 = 6.28318530717959;
const WORKGROUP: u32 = 64u;
// The cube's side and texels per face.
const N: u32 = 64u;
const PER_FACE: u32 = 4096u;
const N32: u32 = 32u;

@group(0) @binding(0) var<uniform> env: Env;
// The lighting map (intensity applied), RGB, row-major, top row first.
@group(0) @binding(1) var<storage, read> map: array<f32>;
@group(0) @binding(2) var<storage, read> tables: array<f32>;
@group(0) @binding(3) var<storage, read_write> cube: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read_write> light: array<vec4<f32>>;

fn env_texel(x: u32, y: u32) -> vec3<f32> {
    let at = env.map_at + 3u * (y * env.env_width + x);
    return vec3<f32>(map[at], map[at + 1u], map[at + 2u]);
}

fn invocation(wg: vec3<u32>, n: vec3<u32>, li: u32) -> u32 {
    return (wg.y * n.x + wg.x) * WORKGROUP + li;
}

// One texel of the turned cube: the solid-angle-weighted mean of the map over its m x m
// sub-samples (`LatLongToCube::face`). The sub-samples' lat-long coordinates come from the
// tables (computed in f64 on the host, as the CPU computes the directions): a sharp light
// would move by the rounding of f32 trigonometry otherwise.
@compute @workgroup_size(64)
fn resample(@builtin(workgroup_id) wg: vec3<u32>, @builtin(num_workgroups) n: vec3<u32>,
            @builtin(local_invocation_index) li: u32) {
    let id = invocation(wg, n, li);
    if id >= 6u * PER_FACE {
        return;
    }
    let face = id / PER_FACE;
    let j = (id % PER_FACE) / N;
    let i = id % N;
    var acc = vec3<f32>(0.0);
    var weight = 0.0;
    for (var l = j * env.m; l < (j + 1u) * env.m; l = l + 1u) {
        for (var k = i * env.m; k < (i + 1u) * env.m; k = k + 1u) {
            let at = env.weights_at + 3u * ((face * env.ns + l) * env.ns + k);
            let w = tables[at];
            let uu = tables[at + 1u] + env.turns;
            let v = tables[at + 2u];
            acc = acc + w * latlong_bilinear_uv(uu - floor(uu), v, env.env_width, env.env_height);
            weight = weight + w;
        }
    }
    cube[id] = vec4<f32>(acc / weight, 0.0);
}

// The weighted sum of one face's texels in rows [y0, y0 + h), columns [x0, x0 + w): row
// by row, then the rows' sums (up to 4096 terms in f32: two levels keep the rounding near the
// CPU's f64 sum).
fn block_sum(face: u32, x0: u32, y0: u32, w: u32, h: u32) -> vec3<f32> {
    var acc = vec3<f32>(0.0);
    for (var y = y0; y < y0 + h; y = y + 1u) {
        var row = vec3<f32>(0.0);
        for (var x = x0; x < x0 + w; x = x + 1u) {
            row = row + cube[face * PER_FACE + y * N + x].xyz * tables[env.sqrt_omega_at + y * N + x];
        }
        acc = acc + row;
    }
    return acc;
}

// One area-weighted Haar coefficient (prt_formats::lighting::haar): the face's scaling
// coefficient (its weighted sum over N), or a square's difference of its halves or diagonal
// quadrants over the square's side, the same as the level-by-level transform.
@compute @workgroup_size(64)
fn haar(@builtin(workgroup_id) wg: vec3<u32>, @builtin(num_workgroups) n: vec3<u32>,
        @builtin(local_invocation_index) li: u32) {
    let id = invocation(wg, n, li);
    if id >= 6u * PER_FACE {
        return;
    }
    let face = id / PER_FACE;
    let o = id % PER_FACE;
    if o == 0u {
        light[env.c0_at + id] = vec4<f32>(block_sum(face, 0u, 0u, N, N) / f32(N), 0.0);
        return;
    }
    // Level l holds [4^l, 4^(l+1)): 2^l x 2^l squares, three kinds of 4^l each.
    var h = 1u;
    while h * h * 4u <= o {
        h = h * 2u;
    }
    let at = o - h * h;
    let kind = at / (h * h);
    let k = at % (h * h);
    let side = N / h;
    let half = side / 2u;
    let x0 = (k % h) * side;
    let y0 = (k / h) * side;
    let tl = block_sum(face, x0, y0, half, half);
    let tr = block_sum(face, x0 + half, y0, half, half);
    let bl = block_sum(face, x0, y0 + half, half, half);
    let br = block_sum(face, x0 + half, y0 + half, half, half);
    var c: vec3<f32>;
    if kind == 0u {
        c = tl - tr + bl - br;
    } else if kind == 1u {
        c = tl + tr - bl - br;
    } else {
        c = tl - tr - bl + br;
    }
    light[env.c0_at + id] = vec4<f32>(c / f32(side), 0.0);
}

// The solid-angle-weighted mean of the cube over one texel of a coarser cube of side
// `size` (CubeMap::downsample, repeated): C1 (8), C2 (2), and the open sky's source (32).
@compute @workgroup_size(64)
fn coarse(@builtin(workgroup_id) wg: vec3<u32>, @builtin(num_workgroups) n: vec3<u32>,
          @builtin(local_invocation_index) li: u32) {
    let id = invocation(wg, n, li);
    var size = 8u;
    var k = id;
    var out = env.c1_at;
    if k >= 384u {
        k = k - 384u;
        size = 2u;
        out = env.c2_at;
        if k >= 24u {
            k = k - 24u;
            size = N32;
            if k >= 6u * N32 * N32 {
                return;
            }
        }
    }
    let face = k / (size * size);
    let j = (k % (size * size)) / size;
    let i = k % size;
    let f = N / size;
    var acc = vec3<f32>(0.0);
    var weight = 0.0;
    for (var y = j * f; y < (j + 1u) * f; y = y + 1u) {
        for (var x = i * f; x < (i + 1u) * f; x = x + 1u) {
            let w = tables[env.omega_at + y * N + x];
            acc = acc + w * cube[face * PER_FACE + y * N + x].xyz;
            weight = weight + w;
        }
    }
    let mean = vec4<f32>(acc / weight, 0.0);
    if size == N32 {
        cube[env.source_at + k] = mean;
    } else {
        light[out + k] = mean;
    }
}

fn dir32(k: u32) -> vec3<f32> {
    let at = env.dirs32_at + 4u * k;
    return vec3<f32>(tables[at], tables[at + 1u], tables[at + 2u]);
}

// The open sky's irradiance at one 6x32x32 texel's centre normal: the source's texels
// times their solid angles times the clamped cosine (IrradianceSource::irradiance).
@compute @workgroup_size(64)
fn open_sky(@builtin(workgroup_id) wg: vec3<u32>, @builtin(num_workgroups) n: vec3<u32>,
            @builtin(local_invocation_index) li: u32) {
    let id = invocation(wg, n, li);
    let count = 6u * N32 * N32;
    if id >= count {
        return;
    }
    let normal = dir32(id);
    // Row by row, then the rows' sums (6144 terms in f32; see `block_sum`).
    var acc = vec3<f32>(0.0);
    for (var r = 0u; r < 6u * N32; r = r + 1u) {
        var row = vec3<f32>(0.0);
        for (var k = r * N32; k < (r + 1u) * N32; k = k + 1u) {
            let c = max(dot(dir32(k), normal), 0.0);
            let w = tables[env.omega32_at + k % (N32 * N32)];
            row = row + (c * w) * cube[env.source_at + k].xyz;
        }
        acc = acc + row;
    }
    light[env.open_sky_at + id] = vec4<f32>(acc, 0.0);
}
