// The temporal gradient's first step: per tile of TILE x TILE pixels, over the pixels with a
// new sample and a history: sum of new luminance, sum of history mean luminance, sum of
// their squared differences, count. One invocation per tile. CPU reference:
// `reconstruct::svgf::gradient`.

@group(0) @binding(2) var hist_sum: texture_2d<f32>;
@group(0) @binding(3) var hist_lum: texture_2d<f32>;
@group(0) @binding(4) var samples: texture_2d<f32>;
@group(0) @binding(5) var tiles: texture_storage_2d<rgba32float, write>;

const TILE: i32 = 8;

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= svgf.tiles_x || id.y >= svgf.tiles_y) {
        return;
    }
    let t = vec2<i32>(id.xy);
    var acc = vec4<f32>(0.0);
    for (var y = t.y * TILE; y < min((t.y + 1) * TILE, i32(params.height)); y++) {
        for (var x = t.x * TILE; x < min((t.x + 1) * TILE, i32(params.width)); x++) {
            let p = vec2<i32>(x, y);
            let s = textureLoad(samples, p, 0);
            let m = textureLoad(hist_sum, p, 0);
            if (s.a > 0.0 && m.a > 0.0) {
                let now = luminance(s.rgb);
                let old = textureLoad(hist_lum, p, 0).x / m.a;
                acc += vec4<f32>(now, old, (now - old) * (now - old), 1.0);
            }
        }
    }
    textureStore(tiles, t, acc);
}
