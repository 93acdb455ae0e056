// The accumulate pass (first of every frame): add this frame's samples to the running average
// (rgb: sum, a: count), restarting it when the scene state changed. Ping-pong: reads the
// previous sums, writes the new ones.

@group(0) @binding(1) var samples: texture_2d<f32>;   // rgb radiance, a = 1 where calculated
@group(0) @binding(2) var prev_sum: texture_2d<f32>;
@group(0) @binding(3) var next_sum: texture_storage_2d<rgba32float, write>;

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if (outside(id)) {
        return;
    }
    let p = vec2<i32>(id.xy);
    let s = textureLoad(samples, p, 0);
    var a = textureLoad(prev_sum, p, 0);
    if (params.reset != 0u) {
        a = vec4<f32>(0.0);
    }
    if (s.a > 0.0) {
        a = a + vec4<f32>(s.rgb, 1.0);
    }
    textureStore(next_sum, p, a);
}
