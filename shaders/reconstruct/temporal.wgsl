// The temporal pass (while interacting): blend each pixel with its filled values in the previous
// frames (texture-array layers), weighted by w = 1/(F_i - F_j) times the temporal D
// against that frame's G-buffer at the same pixel. The current frame has w = 1.

@group(0) @binding(1) var current: texture_2d<f32>;
@group(0) @binding(2) var normals: texture_2d<f32>;
@group(0) @binding(3) var positions: texture_2d<f32>;
@group(0) @binding(4) var past_radiance: texture_2d_array<f32>;
@group(0) @binding(5) var past_normals: texture_2d_array<f32>;
@group(0) @binding(6) var past_positions: texture_2d_array<f32>;
@group(0) @binding(7) var blended: texture_storage_2d<rgba32float, write>;

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if (outside(id)) {
        return;
    }
    let p = vec2<i32>(id.xy);
    let ni = textureLoad(normals, p, 0).xyz;
    let zi = textureLoad(positions, p, 0).xyz;
    let li = textureLoad(current, p, 0).rgb;
    let d0 = discontinuity(ni, ni, zi, zi);
    var acc = li * d0;
    var wsum = d0;
    for (var k = 0; k < 4; k++) {
        let weight = params.history_weight[k];
        if (weight <= 0.0) {
            continue;
        }
        let nj = textureLoad(past_normals, p, k, 0).xyz;
        let zj = textureLoad(past_positions, p, k, 0).xyz;
        let dw = discontinuity(ni, nj, zi, zj) * weight;
        acc += textureLoad(past_radiance, p, k, 0).rgb * dw;
        wsum += dw;
    }
    var out = li;
    if (wsum > 0.0) {
        out = acc / wsum;
    }
    textureStore(blended, p, vec4<f32>(out, 1.0));
}
