// A per-pixel frame buffer drawn into a caller's texture (docs/gpu.md): one triangle over the
// whole target, each fragment the RGB of its pixel (the buffer's layout: row-major, top row
// first, three floats a pixel), alpha 1.

@group(0) @binding(0) var<storage, read> image: array<f32>;
// The image's width and height.
@group(0) @binding(1) var<uniform> size: vec4<u32>;

@vertex
fn present_vertex(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    let x = f32((i << 1u) & 2u) * 2.0 - 1.0;
    let y = f32(i & 2u) * 2.0 - 1.0;
    return vec4<f32>(x, y, 0.0, 1.0);
}

@fragment
fn present_fragment(@builtin(position) p: vec4<f32>) -> @location(0) vec4<f32> {
    // Fragment coordinates are pixel centres, the origin the top-left corner.
    let x = min(u32(p.x), size.x - 1u);
    let y = min(u32(p.y), size.y - 1u);
    let k = 3u * (y * size.x + x);
    return vec4<f32>(image[k], image[k + 1u], image[k + 2u], 1.0);
}
