// The remodulate pass (last): remodulate the G-buffer albedo, add directly seen emission (linear colour, kept
// for EXR) and tonemap for display: exposure, ACES filmic (Narkowicz fit), sRGB. The same
// curve as `image_io::display_pixel`.

@group(0) @binding(1) var radiance: texture_2d<f32>;
@group(0) @binding(2) var albedo: texture_2d<f32>;
@group(0) @binding(3) var emission: texture_2d<f32>;
@group(0) @binding(4) var colour: texture_storage_2d<rgba32float, write>;
@group(0) @binding(5) var display: texture_storage_2d<rgba8unorm, write>;

fn aces_filmic(x: vec3<f32>) -> vec3<f32> {
    let num = x * (x * 2.51 + vec3<f32>(0.03));
    let den = x * (x * 2.43 + vec3<f32>(0.59)) + vec3<f32>(0.14);
    return clamp(num / den, vec3<f32>(0.0), vec3<f32>(1.0));
}

fn srgb_encode(x: f32) -> f32 {
    let c = clamp(x, 0.0, 1.0);
    if (c <= 0.0031308) {
        return 12.92 * c;
    }
    return 1.055 * pow(c, 1.0 / 2.4) - 0.055;
}

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if (outside(id)) {
        return;
    }
    let p = vec2<i32>(id.xy);
    let c = textureLoad(albedo, p, 0).rgb * textureLoad(radiance, p, 0).rgb + textureLoad(emission, p, 0).rgb;
    textureStore(colour, p, vec4<f32>(c, 1.0));
    let t = aces_filmic(max(c * params.exposure, vec3<f32>(0.0)));
    textureStore(display, p, vec4<f32>(srgb_encode(t.x), srgb_encode(t.y), srgb_encode(t.z), 1.0));
}
