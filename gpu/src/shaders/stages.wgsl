// The per-vertex light and material stages on the device (docs/vertex.md, sections 3 and 4;
// docs/gpu.md, "Per-vertex"): the CPU runtime's `incident.rs` and `clustered.rs`, one group
// at a time, each kernel one dispatch.
//
// - light stage (when the environment changes): `t0_dot` (T0's sparse Haar rows dotted with
//   C0), and per tensor (T1: `which` 0, T2: 1) either `dense_light` (the stored tensor
//   contracted over its light bins) or, compressed, `cluster_p`, `cluster_q`, `cluster_s`
//   (per cluster `P = C light_c`, `Q = P core_c`, `S = scale Q element_c`);
// - material stage (when materials change): compressed, `cluster_m` (the slot contraction per
//   cluster row), then `records` (per vertex `E`, `I2`, `I1[16]`, `U[r_i]`, the record the
//   view stage reads).
//
// Sums run in the CPU's order (light bins, then `a`, then `r`, ascending), so the results
// differ from the CPU's only by rounding.

struct Tensor {
    // 0: none, 1: dense, 2: clustered.
    kind: u32,
    // Dense values stored as f16 (two per word).
    f16: u32,
    // In `data`: dense values, or the clustered factors.
    values_at: u32,
    core_at: u32,
    vertex_at: u32,
    // Per cluster six words: a, r, b, factor_at, core_at, rows_at.
    table_at: u32,
    // Per per-cluster row, its cluster.
    row_cluster_at: u32,
    clusters: u32,
    max_a: u32,
    max_r: u32,
    max_b: u32,
    vertex_rank: u32,
    // Elements per channel (T1: J x 16, T2: J x I).
    elements: u32,
    // Light bins, and the first in `light`.
    bins: u32,
    light_at: u32,
    scale: f32,
    // In `work`: P, Q, S (dense: the contracted tensor L), M.
    p_at: u32,
    q_at: u32,
    s_at: u32,
    m_at: u32,
    // Per-cluster result rows.
    rows: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

struct Group {
    vertices: u32,
    // T0 rows and Haar terms per row.
    rows: u32,
    terms: u32,
    t0_f16: u32,
    t0_index_at: u32,
    t0_values_at: u32,
    // Per vertex nine words: open flag, then four (texel, weight) taps of the open sky; NONE:
    // no vertex of the group has an open row.
    open_at: u32,
    t0dot_at: u32,
    scale_t0: f32,
    channels: u32,
    // Active slots J, and the slots I of T2.
    j: u32,
    n_i: u32,
    // In `coeff`: the group's J coefficients, then the bake's I.
    coeff_at: u32,
    ci_at: u32,
    // In `data`: each vertex's cluster (compressed groups).
    cluster_of_at: u32,
    // The group's records: floats per vertex, first float in `records`.
    stride: u32,
    record_at: u32,
    // r_i of the shading basis (0 without one) and its constants in `data`.
    rank: u32,
    cwi_at: u32,
    cconst_at: u32,
    ehat_at: u32,
    // Which tensor the light kernels and `cluster_m` work on (T1: 0, T2: 1).
    which: u32,
    open_sky_at: u32,
    // In `light`: C0 of the map less its compact lights, which the glossy rows (all but the
    // last, the irradiance) read (the map's own C0 when it has no compact lights).
    glossy_c0_at: u32,
    t: array<Tensor, 2>,
}

const NONE: u32 = 0xffffffffu;
const SH_COUNT: u32 = 16u;
const PI: f32 = 3.14159265358979;
const WORKGROUP: u32 = 64u;

@group(0) @binding(0) var<uniform> g: Group;
// C0 (6x64x64 Haar coefficients), C1 (6x8x8), C2 (6x2x2), the open sky's irradiance (6x32x32),
// the glossy rows' C0 (6x64x64): RGB per entry.
@group(0) @binding(1) var<storage, read> light: array<vec4<f32>>;
// Per group its J slot coefficients, then T2's I.
@group(0) @binding(2) var<storage, read> coeff: array<vec4<f32>>;
// The group's stored tensors, tables and constants (f32 as bits, f16 and u16 two per word).
@group(0) @binding(3) var<storage, read> data: array<u32>;
// T0's dots, the dense contractions, P, Q, S and M.
@group(0) @binding(4) var<storage, read_write> work: array<f32>;
@group(0) @binding(5) var<storage, read_write> records: array<f32>;

fn invocation(wg: vec3<u32>, n: vec3<u32>, li: u32) -> u32 {
    return (wg.y * n.x + wg.x) * WORKGROUP + li;
}

fn f32_at(at: u32) -> f32 {
    return bitcast<f32>(data[at]);
}

// Element `i` of stored values from word `at`: f32, or f16 two per word (low half first).
fn stored(at: u32, half: u32, i: u32) -> f32 {
    if half == 1u {
        let pair = unpack2x16float(data[at + (i >> 1u)]);
        return select(pair.x, pair.y, (i & 1u) == 1u);
    }
    return bitcast<f32>(data[at + i]);
}

fn u16_at(at: u32, i: u32) -> u32 {
    let w = data[at + (i >> 1u)];
    return select(w & 0xffffu, w >> 16u, (i & 1u) == 1u);
}

fn work3(at: u32) -> vec3<f32> {
    return vec3<f32>(work[at], work[at + 1u], work[at + 2u]);
}

fn set_work3(at: u32, v: vec3<f32>) {
    work[at] = v.x;
    work[at + 1u] = v.y;
    work[at + 2u] = v.z;
}

// T0dot[v][k] = scale sum_n x[v][k][n] C0[index[v][k][n]]; a vertex whose irradiance row is
// the occluded part gets the open sky's irradiance at its normal minus that.
@compute @workgroup_size(64)
fn t0_dot(@builtin(workgroup_id) wg: vec3<u32>, @builtin(num_workgroups) n: vec3<u32>,
          @builtin(local_invocation_index) li: u32) {
    let id = invocation(wg, n, li);
    if id >= g.vertices * g.rows {
        return;
    }
    let v = id / g.rows;
    let k = id % g.rows;
    var acc = vec3<f32>(0.0);
    let base = id * g.terms;
    let c0_at = select(g.glossy_c0_at, 0u, k + 1u == g.rows);
    for (var t = 0u; t < g.terms; t = t + 1u) {
        let x = stored(g.t0_values_at, g.t0_f16, base + t);
        let c = light[c0_at + u16_at(g.t0_index_at, base + t)].xyz;
        acc = acc + x * c;
    }
    acc = acc * g.scale_t0;
    if k + 1u == g.rows && g.open_at != NONE {
        let o = g.open_at + 9u * v;
        if data[o] != 0u {
            var open = vec3<f32>(0.0);
            for (var q = 0u; q < 4u; q = q + 1u) {
                let texel = data[o + 1u + 2u * q];
                let w = f32_at(o + 2u + 2u * q);
                open = open + w * light[g.open_sky_at + texel].xyz;
            }
            acc = open - acc;
        }
    }
    set_work3(g.t0dot_at + 3u * id, acc);
}

// A dense T1 or T2 contracted over its light bins: L[v][e] = scale sum_l C[l] T[v][l][e]
// (gray: one value per element; RGB: three interleaved).
@compute @workgroup_size(64)
fn dense_light(@builtin(workgroup_id) wg: vec3<u32>, @builtin(num_workgroups) n: vec3<u32>,
               @builtin(local_invocation_index) li: u32) {
    let t = g.t[g.which];
    let id = invocation(wg, n, li);
    if id >= g.vertices * t.elements {
        return;
    }
    let v = id / t.elements;
    let e = id % t.elements;
    let width = t.elements * g.channels;
    var acc = vec3<f32>(0.0);
    for (var l = 0u; l < t.bins; l = l + 1u) {
        let c = light[t.light_at + l].xyz;
        let row = (v * t.bins + l) * width;
        if g.channels == 1u {
            acc = acc + c * stored(t.values_at, t.f16, row + e);
        } else {
            let x = vec3<f32>(
                stored(t.values_at, t.f16, row + 3u * e),
                stored(t.values_at, t.f16, row + 3u * e + 1u),
                stored(t.values_at, t.f16, row + 3u * e + 2u),
            );
            acc = acc + c * x;
        }
    }
    set_work3(t.s_at + 3u * id, t.scale * acc);
}

// Cluster k's ranks and offsets: a, r, b, factor_at, core_at, rows_at.
fn cluster(t: Tensor, k: u32, field: u32) -> u32 {
    return data[t.table_at + 6u * k + field];
}

// P[k][a] = sum_l C[l] light_k[l][a].
@compute @workgroup_size(64)
fn cluster_p(@builtin(workgroup_id) wg: vec3<u32>, @builtin(num_workgroups) n: vec3<u32>,
             @builtin(local_invocation_index) li: u32) {
    let t = g.t[g.which];
    let id = invocation(wg, n, li);
    let k = id / max(t.max_a, 1u);
    let aa = id % max(t.max_a, 1u);
    if k >= t.clusters || aa >= cluster(t, k, 0u) {
        return;
    }
    let a = cluster(t, k, 0u);
    let factor = t.values_at + cluster(t, k, 3u);
    var acc = vec3<f32>(0.0);
    for (var l = 0u; l < t.bins; l = l + 1u) {
        acc = acc + light[t.light_at + l].xyz * f32_at(factor + l * a + aa);
    }
    set_work3(t.p_at + 3u * id, acc);
}

// Q[k][b][r] = sum_a P[k][a] core_k[b][a][r].
@compute @workgroup_size(64)
fn cluster_q(@builtin(workgroup_id) wg: vec3<u32>, @builtin(num_workgroups) n: vec3<u32>,
             @builtin(local_invocation_index) li: u32) {
    let t = g.t[g.which];
    let id = invocation(wg, n, li);
    let per = max(t.max_b * t.max_r, 1u);
    let k = id / per;
    let bb = (id % per) / max(t.max_r, 1u);
    let rr = id % max(t.max_r, 1u);
    if k >= t.clusters {
        return;
    }
    let a = cluster(t, k, 0u);
    let r = cluster(t, k, 1u);
    let b = cluster(t, k, 2u);
    if bb >= b || rr >= r {
        return;
    }
    let core = t.core_at + cluster(t, k, 4u);
    var acc = vec3<f32>(0.0);
    for (var aa = 0u; aa < a; aa = aa + 1u) {
        acc = acc + work3(t.p_at + 3u * (k * t.max_a + aa)) * f32_at(core + (bb * a + aa) * r + rr);
    }
    set_work3(t.q_at + 3u * id, acc);
}

// S[row][e] = scale sum_r Q[k][b][r] element_k[w][r] for the per-cluster rows (cluster k's
// row b); w = e (gray) or 3e + channel (RGB).
@compute @workgroup_size(64)
fn cluster_s(@builtin(workgroup_id) wg: vec3<u32>, @builtin(num_workgroups) n: vec3<u32>,
             @builtin(local_invocation_index) li: u32) {
    let t = g.t[g.which];
    let id = invocation(wg, n, li);
    if id >= t.rows * t.elements {
        return;
    }
    let row = id / t.elements;
    let e = id % t.elements;
    let k = data[t.row_cluster_at + row];
    let a = cluster(t, k, 0u);
    let r = cluster(t, k, 1u);
    let bb = row - cluster(t, k, 5u);
    let width = t.elements * g.channels;
    let element = t.values_at + cluster(t, k, 3u) + t.bins * a;
    let q = t.q_at + 3u * ((k * t.max_b + bb) * t.max_r);
    var acc = vec3<f32>(0.0);
    for (var rr = 0u; rr < r; rr = rr + 1u) {
        let qr = work3(q + 3u * rr);
        if g.channels == 1u {
            acc = acc + qr * f32_at(element + rr * width + e);
        } else {
            let x = vec3<f32>(
                f32_at(element + rr * width + 3u * e),
                f32_at(element + rr * width + 3u * e + 1u),
                f32_at(element + rr * width + 3u * e + 2u),
            );
            acc = acc + qr * x;
        }
    }
    set_work3(t.s_at + 3u * id, t.scale * acc);
}

// The slot contraction per cluster row: T1 (`which` 0): M[row][s] = sum_j c_j S[row][j, s];
// T2: M[row] = sum_(j,i) c_j c_i S[row][j, i].
@compute @workgroup_size(64)
fn cluster_m(@builtin(workgroup_id) wg: vec3<u32>, @builtin(num_workgroups) n: vec3<u32>,
             @builtin(local_invocation_index) li: u32) {
    let t = g.t[g.which];
    let id = invocation(wg, n, li);
    let per = select(1u, SH_COUNT, g.which == 0u);
    if id >= t.rows * per {
        return;
    }
    let row = id / per;
    let s = id % per;
    let src = t.s_at + 3u * row * t.elements;
    var acc = vec3<f32>(0.0);
    if g.which == 0u {
        for (var j = 0u; j < g.j; j = j + 1u) {
            acc = acc + coeff[g.coeff_at + j].xyz * work3(src + 3u * (j * SH_COUNT + s));
        }
    } else {
        for (var j = 0u; j < g.j; j = j + 1u) {
            let cj = coeff[g.coeff_at + j].xyz;
            for (var i = 0u; i < g.n_i; i = i + 1u) {
                acc = acc + cj * coeff[g.ci_at + i].xyz * work3(src + 3u * (j * g.n_i + i));
            }
        }
    }
    set_work3(t.m_at + 3u * id, acc);
}

// sum_b u[v][b] M[rows_at(k) + b][..] for vertex v of cluster k: element `s` of `per`.
fn expand(t: Tensor, k: u32, v: u32, per: u32, s: u32) -> vec3<f32> {
    let b = cluster(t, k, 2u);
    let m = t.m_at + 3u * (cluster(t, k, 5u) * per + s);
    var acc = vec3<f32>(0.0);
    for (var bb = 0u; bb < b; bb = bb + 1u) {
        acc = acc + f32_at(t.vertex_at + v * t.vertex_rank + bb) * work3(m + 3u * bb * per);
    }
    return acc;
}

fn set_record(at: u32, v: vec3<f32>) {
    records[at] = v.x;
    records[at + 1u] = v.y;
    records[at + 2u] = v.z;
}

// One vertex's record: E, I2, I1[16], U[r_i] (the view stage's layout).
@compute @workgroup_size(64)
fn records_of(@builtin(workgroup_id) wg: vec3<u32>, @builtin(num_workgroups) n: vec3<u32>,
              @builtin(local_invocation_index) li: u32) {
    let v = invocation(wg, n, li);
    if v >= g.vertices {
        return;
    }
    var i1: array<vec3<f32>, 16>;
    var i2 = vec3<f32>(0.0);
    let t1 = g.t[0];
    let t2 = g.t[1];
    if t1.kind == 2u {
        let k = data[g.cluster_of_at + v];
        for (var s = 0u; s < SH_COUNT; s = s + 1u) {
            i1[s] = expand(t1, k, v, SH_COUNT, s);
        }
        if t2.kind == 2u {
            i2 = expand(t2, k, v, 1u, 0u);
        }
    } else {
        // I1[s] = sum_j c_j L1[j][s]; I2 = sum_(j,i) c_j c_i L2[j][i].
        for (var s = 0u; s < SH_COUNT; s = s + 1u) {
            i1[s] = vec3<f32>(0.0);
        }
        let l1 = t1.s_at + 3u * v * t1.elements;
        for (var j = 0u; j < g.j; j = j + 1u) {
            let c = coeff[g.coeff_at + j].xyz;
            for (var s = 0u; s < SH_COUNT; s = s + 1u) {
                i1[s] = i1[s] + c * work3(l1 + 3u * (j * SH_COUNT + s));
            }
        }
        if t2.kind == 1u {
            let l2 = t2.s_at + 3u * v * t2.elements;
            for (var j = 0u; j < g.j; j = j + 1u) {
                let a = coeff[g.coeff_at + j].xyz;
                for (var i = 0u; i < g.n_i; i = i + 1u) {
                    i2 = i2 + a * coeff[g.ci_at + i].xyz * work3(l2 + 3u * (j * g.n_i + i));
                }
            }
        }
    }
    let t0 = g.t0dot_at + 3u * v * g.rows;
    // E = T0dot[last] + sum_s Ehat[s] I1[s] + pi I2.
    var e = work3(t0 + 3u * (g.rows - 1u));
    for (var s = 0u; s < SH_COUNT; s = s + 1u) {
        e = e + f32_at(g.ehat_at + s) * i1[s];
    }
    e = e + PI * i2;
    let rec = g.record_at + v * g.stride;
    set_record(rec, e);
    set_record(rec + 3u, i2);
    for (var s = 0u; s < SH_COUNT; s = s + 1u) {
        set_record(rec + 6u + 3u * s, i1[s]);
    }
    // U[c] = T0dot[c] + sum_s Cwi[s][c] I1[s] + Cconst[c] I2.
    for (var c = 0u; c < g.rank; c = c + 1u) {
        var u = work3(t0 + 3u * c);
        for (var s = 0u; s < SH_COUNT; s = s + 1u) {
            u = u + f32_at(g.cwi_at + s * g.rank + c) * i1[s];
        }
        u = u + f32_at(g.cconst_at + c) * i2;
        set_record(rec + 6u + 3u * SH_COUNT + 3u * c, u);
    }
}
