// The Gaussian pass (while interacting): edge-aware Gaussian, (2 gauss_radius + 1)^2 taps, each
// weighted by g(dx) g(dy) D.

@group(0) @binding(1) var src: texture_2d<f32>;
@group(0) @binding(2) var normals: texture_2d<f32>;
@group(0) @binding(3) var positions: texture_2d<f32>;
@group(0) @binding(4) var filtered: texture_storage_2d<rgba32float, write>;

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if (outside(id)) {
        return;
    }
    let p = vec2<i32>(id.xy);
    let w = i32(params.width);
    let h = i32(params.height);
    let r = params.gauss_radius;
    let ni = textureLoad(normals, p, 0).xyz;
    let zi = textureLoad(positions, p, 0).xyz;
    var acc = vec3<f32>(0.0);
    var wsum = 0.0;
    for (var dy = -r; dy <= r; dy++) {
        let yy = p.y + dy;
        if (yy < 0 || yy >= h) {
            continue;
        }
        let gy = gauss_weight(dy);
        for (var dx = -r; dx <= r; dx++) {
            let xx = p.x + dx;
            if (xx < 0 || xx >= w) {
                continue;
            }
            let q = vec2<i32>(xx, yy);
            let d = discontinuity(ni, textureLoad(normals, q, 0).xyz, zi, textureLoad(positions, q, 0).xyz);
            let g = gy * gauss_weight(dx) * d;
            acc += textureLoad(src, q, 0).rgb * g;
            wsum += g;
        }
    }
    var out = textureLoad(src, p, 0).rgb;
    if (wsum > 0.0) {
        out = acc / wsum;
    }
    textureStore(filtered, p, vec4<f32>(out, 1.0));
}
