// The variance of each pixel's estimate: from its temporal moments where it has
// TEMPORAL_MIN samples, else from the moments pooled over its surface in a 5 x 5
// neighbourhood; divided by the pixel's samples. Writes the filled radiance (rgb) with
// the variance (a) for the a-trous iterations. CPU reference: `reconstruct::svgf::variance`.

@group(0) @binding(2) var hist_sum: texture_2d<f32>;
@group(0) @binding(3) var hist_lum: texture_2d<f32>;
@group(0) @binding(4) var filled: texture_2d<f32>;
@group(0) @binding(5) var normals: texture_2d<f32>;
@group(0) @binding(6) var positions: texture_2d<f32>;
@group(0) @binding(7) var out: texture_storage_2d<rgba32float, write>;

const TEMPORAL_MIN: f32 = 4.0;
const REACH: i32 = 2;

// One sample's variance from n samples' sums of l and l^2 (valid for n >= 2).
fn sample_variance(count: f32, s1: f32, s2: f32) -> f32 {
    let n = max(count, 2.0);
    let mean = s1 / n;
    return max((s2 / n - mean * mean) * n / (n - 1.0), 0.0);
}

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if (outside(id)) {
        return;
    }
    let p = vec2<i32>(id.xy);
    let n = textureLoad(hist_sum, p, 0).a;
    let m = textureLoad(hist_lum, p, 0).xy;
    let c = textureLoad(filled, p, 0).rgb;
    var v = sample_variance(n, m.x, m.y);
    if (n < TEMPORAL_MIN) {
        let ni = textureLoad(normals, p, 0).xyz;
        let pi = textureLoad(positions, p, 0).xyz;
        var wn = n;
        var w1 = m.x;
        var w2 = m.y;
        for (var dy = -REACH; dy <= REACH; dy++) {
            for (var dx = -REACH; dx <= REACH; dx++) {
                let q = p + vec2<i32>(dx, dy);
                if ((dx == 0 && dy == 0) || !inside(q)) {
                    continue;
                }
                let g = geometry(ni, pi, textureLoad(normals, q, 0).xyz,
                    textureLoad(positions, q, 0).xyz);
                let mq = textureLoad(hist_lum, q, 0).xy;
                wn += g * textureLoad(hist_sum, q, 0).a;
                w1 += g * mq.x;
                w2 += g * mq.y;
            }
        }
        let l = luminance(c);
        v = select(l * l, sample_variance(wn, w1, w2), wn >= 2.0);
    }
    textureStore(out, p, vec4<f32>(c, v / max(n, 1.0)));
}
