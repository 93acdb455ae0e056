// One variance-guided a-trous iteration (step svgf.step): each pixel blended with its eight
// neighbours step pixels away, weighted by the 3 x 3 B-spline kernel, the geometric and the
// luminance edge-stopping; the variance (a) filtered alongside with the squared weights.
// CPU reference: `reconstruct::svgf::atrous`.

@group(0) @binding(2) var src: texture_2d<f32>;
@group(0) @binding(3) var normals: texture_2d<f32>;
@group(0) @binding(4) var positions: texture_2d<f32>;
@group(0) @binding(5) var dst: texture_storage_2d<rgba32float, write>;

// Keeps 1/(sigma_l sigma_i) finite where the variance is 0.
const MIN_DEVIATION: f32 = 1e-6;

fn kernel(d: i32) -> f32 {
    return select(0.25, 0.5, d == 0);
}

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if (outside(id)) {
        return;
    }
    let p = vec2<i32>(id.xy);
    let ci = textureLoad(src, p, 0);
    let ni = textureLoad(normals, p, 0).xyz;
    if (!is_surface(ni)) {
        textureStore(dst, p, ci);
        return;
    }
    let pi = textureLoad(positions, p, 0).xyz;
    let li = luminance(ci.rgb);
    let deviation = svgf.sigma_luminance * sqrt(ci.a);
    let inv = 1.0 / max(deviation, MIN_DEVIATION);
    let centre = 0.5 * 0.5;
    var sum = ci.rgb * centre;
    var wsum = centre;
    var vsum = centre * centre * ci.a;
    for (var dy = -1; dy <= 1; dy++) {
        for (var dx = -1; dx <= 1; dx++) {
            let q = p + vec2<i32>(dx, dy) * svgf.step;
            if ((dx == 0 && dy == 0) || !inside(q)) {
                continue;
            }
            let cj = textureLoad(src, q, 0);
            let g = geometry(ni, pi, textureLoad(normals, q, 0).xyz,
                textureLoad(positions, q, 0).xyz);
            let w = kernel(dx) * kernel(dy) * g * luminance_weight(li - luminance(cj.rgb), inv);
            sum += cj.rgb * w;
            wsum += w;
            vsum += w * w * cj.a;
        }
    }
    textureStore(dst, p, vec4<f32>(sum / wsum, vsum / (wsum * wsum)));
}
