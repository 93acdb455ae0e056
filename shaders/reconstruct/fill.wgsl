// The fill pass: fill pixels without samples from calculated neighbours within the radius,
// weighted by D (k = 1). Fallbacks as the CPU reference: the plain mean of calculated
// surface neighbours when every D is 0, else 0; pixels with no surface get 0.

@group(0) @binding(1) var sums: texture_2d<f32>;
@group(0) @binding(2) var normals: texture_2d<f32>;
@group(0) @binding(3) var positions: texture_2d<f32>;
@group(0) @binding(4) var filled: texture_storage_2d<rgba32float, write>;

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if (outside(id)) {
        return;
    }
    let p = vec2<i32>(id.xy);
    let a = textureLoad(sums, p, 0);
    if (a.a > 0.0) {
        textureStore(filled, p, vec4<f32>(a.rgb / a.a, 1.0));
        return;
    }
    let ni = textureLoad(normals, p, 0).xyz;
    let zi = textureLoad(positions, p, 0).xyz;
    if (!is_surface(ni)) {
        textureStore(filled, p, vec4<f32>(0.0, 0.0, 0.0, 1.0));
        return;
    }
    let w = i32(params.width);
    let h = i32(params.height);
    let r = params.radius;
    var acc = vec3<f32>(0.0);
    var wsum = 0.0;
    var plain = vec3<f32>(0.0);
    var plain_n = 0.0;
    for (var dy = -r; dy <= r; dy++) {
        let yy = p.y + dy;
        if (yy < 0 || yy >= h) {
            continue;
        }
        for (var dx = -r; dx <= r; dx++) {
            let xx = p.x + dx;
            if (xx < 0 || xx >= w || dx * dx + dy * dy > r * r) {
                continue;
            }
            let q = vec2<i32>(xx, yy);
            let b = textureLoad(sums, q, 0);
            if (b.a <= 0.0) {
                continue;
            }
            let lj = b.rgb / b.a;
            let nj = textureLoad(normals, q, 0).xyz;
            let d = discontinuity(ni, nj, zi, textureLoad(positions, q, 0).xyz);
            acc += lj * d;
            wsum += d;
            if (is_surface(nj)) {
                plain += lj;
                plain_n += 1.0;
            }
        }
    }
    var out = vec3<f32>(0.0);
    if (wsum > 0.0) {
        out = acc / wsum;
    } else if (plain_n > 0.0) {
        out = plain / plain_n;
    }
    textureStore(filled, p, vec4<f32>(out, 1.0));
}
