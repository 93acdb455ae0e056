// The SVGF accumulation: on a new scene state first the temporal gradient's factor
// (interpolated between tile centres) rescales the reprojected history, then this frame's
// samples are added to the sums and luminance moments. CPU reference:
// `reconstruct::svgf::gradient` and `SvgfReconstructor::reconstruct_into`.

@group(0) @binding(2) var hist_sum: texture_2d<f32>;
@group(0) @binding(3) var hist_lum: texture_2d<f32>;
@group(0) @binding(4) var samples: texture_2d<f32>;
@group(0) @binding(5) var factor: texture_2d<f32>;
@group(0) @binding(6) var out_sum: texture_storage_2d<rgba32float, write>;
@group(0) @binding(7) var out_lum: texture_storage_2d<rgba32float, write>;

const TILE: f32 = 8.0;

fn factor_at(x: i32, y: i32) -> f32 {
    let t = vec2<i32>(min(x, i32(svgf.tiles_x) - 1), min(y, i32(svgf.tiles_y) - 1));
    return textureLoad(factor, t, 0).x;
}

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if (outside(id)) {
        return;
    }
    let p = vec2<i32>(id.xy);
    var sum = textureLoad(hist_sum, p, 0);
    var lum = textureLoad(hist_lum, p, 0).xy;
    if (svgf.gradient == 1u) {
        // Tile centres at (t + 1/2) TILE: the pixel's position among them.
        let fx = max((f32(p.x) + 0.5) / TILE - 0.5, 0.0);
        let fy = max((f32(p.y) + 0.5) / TILE - 0.5, 0.0);
        let x0 = i32(fx);
        let y0 = i32(fy);
        let wx = fract(fx);
        let wy = fract(fy);
        let top = factor_at(x0, y0) * (1.0 - wx) + factor_at(x0 + 1, y0) * wx;
        let bottom = factor_at(x0, y0 + 1) * (1.0 - wx) + factor_at(x0 + 1, y0 + 1) * wx;
        let k = top * (1.0 - wy) + bottom * wy;
        sum = vec4<f32>(sum.rgb * k, sum.a);
        lum = vec2<f32>(lum.x * k, lum.y * (k * k));
    }
    let s = textureLoad(samples, p, 0);
    if (s.a > 0.0) {
        let l = luminance(s.rgb);
        sum += vec4<f32>(s.rgb, 1.0);
        lum += vec2<f32>(l, l * l);
    }
    textureStore(out_sum, p, sum);
    textureStore(out_lum, p, vec4<f32>(lum, 0.0, 0.0));
}
