// The temporal gradient's second step: each tile pools its neighbours' sums until it holds
// MIN_SAMPLES, and the factor its history is scaled by follows from the pooled difference
// in units of its spread. One invocation per tile. CPU reference:
// `reconstruct::svgf::gradient`.

@group(0) @binding(2) var tiles: texture_2d<f32>;
@group(0) @binding(3) var factor: texture_storage_2d<rgba32float, write>;

const MIN_SAMPLES: f32 = 24.0;
const MAX_REACH: i32 = 4;
const Z_NOISE: f32 = 1.5;
const Z_SURE: f32 = 3.0;
const MAX_RATIO: f32 = 16.0;

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= svgf.tiles_x || id.y >= svgf.tiles_y) {
        return;
    }
    let c = vec2<i32>(id.xy);
    let tx = i32(svgf.tiles_x);
    let ty = i32(svgf.tiles_y);
    var pooled = vec4<f32>(0.0);
    for (var reach = 0; reach <= MAX_REACH; reach++) {
        pooled = vec4<f32>(0.0);
        for (var y = max(c.y - reach, 0); y < min(c.y + reach + 1, ty); y++) {
            for (var x = max(c.x - reach, 0); x < min(c.x + reach + 1, tx); x++) {
                pooled += textureLoad(tiles, vec2<i32>(x, y), 0);
            }
        }
        if (pooled.w >= MIN_SAMPLES) {
            break;
        }
    }
    // pooled: Σ new, Σ old, Σ d², count.
    var k = 1.0;
    if (!(pooled.w < 2.0 || pooled.z <= 0.0 || pooled.y <= 0.0)) {
        let z = abs(pooled.x - pooled.y) / sqrt(pooled.z);
        let confidence = clamp((z - Z_NOISE) / (Z_SURE - Z_NOISE), 0.0, 1.0);
        let ratio = min(pooled.x / pooled.y, MAX_RATIO);
        k = 1.0 + confidence * (ratio - 1.0);
    }
    textureStore(factor, c, vec4<f32>(k, 0.0, 0.0, 0.0));
}
