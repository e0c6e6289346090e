// The per-pixel relight (docs/pixel.md, "Storage and relighting"; docs/gpu.md): one
// invocation per pixel of a group's chunk of stored rows, contracting the rows with the
// frame's weights and adding the result into the image.
//
// `values` holds the chunk's rows element-major as the file stores them (`[rows, P]`, pixels
// fastest), so the invocations of a workgroup read consecutive words of every row. f32 values
// are one word each; f16 values two per word (wgsl's `f16` type needs a device feature, so
// they are unpacked with `unpack2x16float`, which every device has).

struct Chunk {
    // Pixels of the group.
    pixels: u32,
    // The chunk's columns: `columns[col_start .. col_start + col_count]`.
    col_start: u32,
    col_count: u32,
    // Workgroups per row of the dispatch grid (a grid row holds at most 65535).
    groups_x: u32,
    // Radiance every pixel of the chunk starts from (the low-rank mean's, in the first chunk
    // of a group; else 0).
    init: vec4<f32>,
}

@group(0) @binding(0) var<storage, read> values: array<u32>;
@group(0) @binding(1) var<storage, read> pixel_index: array<u32>;
// Per column: its row in the chunk (bits of a u32) and its RGB weight.
@group(0) @binding(2) var<storage, read> columns: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read_write> image: array<f32>;
@group(0) @binding(4) var<uniform> chunk: Chunk;

const WORKGROUP: u32 = 256u;

fn add_to_image(k: u32, acc: vec3<f32>) {
    let at = 3u * pixel_index[k];
    image[at] = image[at] + acc.x;
    image[at + 1u] = image[at + 1u] + acc.y;
    image[at + 2u] = image[at + 2u] + acc.z;
}

@compute @workgroup_size(256)
fn contract_f32(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) li: u32) {
    let k = (wg.y * chunk.groups_x + wg.x) * WORKGROUP + li;
    if k >= chunk.pixels {
        return;
    }
    var acc = chunk.init.xyz;
    for (var c = chunk.col_start; c < chunk.col_start + chunk.col_count; c = c + 1u) {
        let col = columns[c];
        let row = bitcast<u32>(col.x);
        let x = bitcast<f32>(values[row * chunk.pixels + k]);
        acc = acc + col.yzw * x;
    }
    add_to_image(k, acc);
}

@compute @workgroup_size(256)
fn contract_f16(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) li: u32) {
    let k = (wg.y * chunk.groups_x + wg.x) * WORKGROUP + li;
    if k >= chunk.pixels {
        return;
    }
    var acc = chunk.init.xyz;
    for (var c = chunk.col_start; c < chunk.col_start + chunk.col_count; c = c + 1u) {
        let col = columns[c];
        let i = bitcast<u32>(col.x) * chunk.pixels + k;
        let pair = unpack2x16float(values[i >> 1u]);
        let x = select(pair.x, pair.y, (i & 1u) == 1u);
        acc = acc + col.yzw * x;
    }
    add_to_image(k, acc);
}
