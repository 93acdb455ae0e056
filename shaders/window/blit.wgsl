// Draws the window's picture texture over the current viewport with one full-screen
// triangle. The render pass's viewport places and scales it (src/window/layout.rs), so the
// shader needs no uniforms. Texture and target share their encoding (both sRGB or both
// unorm), which makes the copy exact.

struct VertexOut {
    @builtin(position) position: vec4<f32>,
    @location(0) uv: vec2<f32>,
};

@vertex
fn vs_main(@builtin(vertex_index) index: u32) -> VertexOut {
    // Vertices (-1,-1), (3,-1), (-1,3) cover the viewport; uv y grows downwards so the
    // picture's first row lands at the top.
    let x = f32((index << 1u) & 2u);
    let y = f32(index & 2u);
    var out: VertexOut;
    out.position = vec4<f32>(x * 2.0 - 1.0, 1.0 - y * 2.0, 0.0, 1.0);
    out.uv = vec2<f32>(x, y);
    return out;
}

@group(0) @binding(0) var picture: texture_2d<f32>;
@group(0) @binding(1) var picture_sampler: sampler;

@fragment
fn fs_main(in: VertexOut) -> @location(0) vec4<f32> {
    return vec4<f32>(textureSample(picture, picture_sampler, in.uv).rgb, 1.0);
}
