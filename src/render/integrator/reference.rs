//! The one-path kernel, kept as the reference the stream kernel's bits are tested
//! against: each camera path traced to its end before the next starts.

use glam::{Vec2, Vec3};

use super::path::{arrive, scatter, trace, PathState, EMPTY_SAMPLE};
use super::ShadowRay;
use super::{primary_block_in, primary_hit, render_pixels_in, RenderStats, Strategy, PRIMARY_TILE};
use crate::render::isa::{Cpu, Isa, IsaLevel};
use crate::render::sampler::SampleStream;
use crate::render::{PixelSample, RenderScene};

/// One camera path: its reflected radiance and G-buffer values (the one-path kernel).
fn trace_path<I: Isa>(
    cpu: Cpu<I>,
    scene: &RenderScene,
    stream: SampleStream,
    pixel_pos: Vec2,
    max_depth: u32,
    strategy: Strategy,
    rays: &mut u64,
) -> PixelSample {
    let nee = strategy == Strategy::NeeMis;
    let mut path = PathState::start(stream);
    let (mut o, mut d) = camera_ray(scene, &mut path.stream, pixel_pos);
    let mut out = EMPTY_SAMPLE;
    // The last vertex's shadow ray, traced together with the next bounce's ray.
    let mut shadow: Option<ShadowRay> = None;
    loop {
        *rays += 1;
        let hit = trace(cpu, scene, (o, d), shadow.take(), &mut path.indirect);
        let arrived = arrive(scene, &mut path, (o, d), hit, max_depth, nee, &mut out);
        let Some((surface, albedo)) = arrived else { break };
        let (alive, s) = scatter(scene, &mut path, (&mut o, &mut d), &surface, albedo, nee, rays);
        shadow = s;
        if !alive {
            break;
        }
    }
    if let Some(s) = shadow {
        s.settle(cpu, scene, &mut path.indirect);
    }
    out.reflected = path.indirect;
    out
}

/// A path's camera ray through `pixel_pos`, from its sample stream's first draw (the
/// stream kernel makes sixteen at once, `stream::Group::start`).
fn camera_ray(scene: &RenderScene, stream: &mut SampleStream, pixel_pos: Vec2) -> (Vec3, Vec3) {
    let cam = stream.next4();
    scene.camera.ray(pixel_pos + Vec2::new(cam[0], cam[1]), Vec2::new(cam[2], cam[3]))
}

/// The one-path kernel: each camera path traced to its end before the next starts, in
/// the baseline build. The stream kernel replaced it; it stays as the reference the
/// stream kernel's bits are tested against.
pub(crate) fn render_pixels_one_path(
    scene: &RenderScene,
    frame: u64,
    pixels: &[u32],
    out: &mut Vec<PixelSample>,
    strategy: Strategy,
) -> RenderStats {
    out.clear();
    let state = scene.state();
    let width = state.resolution.width.max(1);
    let spp = state.render.spp.max(1);
    let inv = 1.0 / spp as f32;
    let mut stats = RenderStats::default();
    for &pixel in pixels {
        let pos = Vec2::new((pixel % width) as f32, (pixel / width) as f32);
        let mut acc = PixelSample::default();
        for index in 0..spp {
            let stream = SampleStream::new(state.seed, frame, pixel, index);
            let s = trace_path(
                Cpu::BASELINE,
                scene,
                stream,
                pos,
                state.render.max_depth,
                strategy,
                &mut stats.rays,
            );
            acc.reflected += s.reflected;
            acc.emission += s.emission;
            if index == 0 {
                acc.albedo = s.albedo;
                acc.normal = s.normal;
                acc.position = s.position;
                acc.object = s.object;
            }
        }
        acc.reflected *= inv;
        acc.emission *= inv;
        out.push(acc);
    }
    stats.samples = pixels.len() as u64 * spp as u64;
    stats
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::testscenes;
    use gridlight_actors::state::{AlphaMode, MaterialKind};

    /// Every build of the stream kernel must give the one-path reference's results bit
    /// for bit, for every material kind (a grid mixes CPUs).
    #[test]
    fn every_kernel_build_matches_the_one_path_reference_bit_for_bit() {
        let test = "every_kernel_build_matches_the_one_path_reference_bit_for_bit";
        let (builds, missing): (Vec<_>, Vec<_>) =
            IsaLevel::ALL.into_iter().partition(|b| b.available());
        for build in missing {
            let why = format!("the CPU lacks {}, so that build was not checked", build.name());
            crate::testing::skip(test, crate::testing::Missing::CpuFeature, &why);
        }
        // (kind, roughness, metallic, transmission, textured, alpha). Textured cases texture
        // the walls (uvs 0..1 reach both ends of the texel wrap). The glTF cases cover its
        // plastic, a half metal, the smooth plastic (a delta layer over a diffuse base),
        // glass mixed in, and a textured mix. The alpha cases cut the walls by the map's
        // alpha (camera, bounce and shadow rays pass the cut-outs) or blend them.
        let opaque = (AlphaMode::Opaque, 1.0);
        let kinds = [
            (MaterialKind::Diffuse, 1.0, 0.0, 0.0, false, opaque),
            (MaterialKind::Conductor, 0.3, 0.0, 0.0, false, opaque),
            (MaterialKind::Glossy, 0.2, 0.0, 0.0, false, opaque),
            (MaterialKind::Dielectric, 0.0, 0.0, 0.0, false, opaque),
            (MaterialKind::Dielectric, 0.4, 0.0, 0.0, false, opaque),
            (MaterialKind::Diffuse, 1.0, 0.0, 0.0, true, opaque),
            (MaterialKind::Pbr, 0.4, 0.5, 0.0, false, opaque),
            (MaterialKind::Pbr, 0.0, 0.0, 0.0, false, opaque),
            (MaterialKind::Pbr, 0.3, 0.2, 0.6, true, opaque),
            (MaterialKind::Diffuse, 1.0, 0.0, 0.0, true, (AlphaMode::Mask, 0.9)),
            (MaterialKind::Glossy, 0.2, 0.0, 0.0, false, (AlphaMode::Blend, 0.6)),
            (MaterialKind::Pbr, 0.3, 0.2, 0.0, true, (AlphaMode::Blend, 0.7)),
        ];
        // Diffuse and glossy vertices take the stream kernel's vector stage (the others,
        // glTF's included, their lane's one-path step): lit by the box's area light alone,
        // its light samples are vector code; with an environment too, drawn lane by lane.
        let cases = kinds.into_iter().flat_map(|k| [(k, true), (k, false)]);
        for ((kind, roughness, metallic, transmission, textured, alpha), environment) in cases {
            let (assets, mut state) = testscenes::cornell_box(40, 30);
            state.materials[0].kind = kind;
            state.materials[0].roughness = roughness;
            state.materials[0].metallic = metallic;
            state.materials[0].transmission = transmission;
            (state.materials[0].alpha_mode, state.materials[0].alpha) = alpha;
            let mut assets = (*assets).clone();
            if textured {
                let texels = (0..15).map(|i| Vec3::new(0.2, (i % 4) as f32 / 4.0, 0.7)).collect();
                let coverage = (0..15).map(|i| [0, 255, 120][i % 3]).collect();
                let texture = crate::assets::Texture::linear(5, 3, texels).with_alpha(coverage);
                assets.textures.insert("checker.png".into(), std::sync::Arc::new(texture));
                state.materials[0].base_color_texture = Some("checker.png".into());
            }
            let assets = std::sync::Arc::new(assets);
            state.environment = environment.then_some(gridlight_actors::state::Environment {
                color: Vec3::new(0.3, 0.4, 0.5),
                intensity: 1.0,
                map: None,
                rotation_deg: 0.0,
            });
            // A thin lens in half the cases: camera rays are lane code too.
            state.camera.aperture = if environment { 0.05 } else { 0.0 };
            let scene = RenderScene::new(assets, &state).unwrap();
            assert_eq!(scene.lights.area_only(), !environment);
            assert_eq!(scene.cutouts, alpha != opaque, "{kind:?} {alpha:?}");
            let pixels: Vec<u32> = (0..40 * 30).collect();
            for strategy in [Strategy::NeeMis, Strategy::BsdfOnly] {
                let mut reference = Vec::new();
                let a = render_pixels_one_path(&scene, 3, &pixels, &mut reference, strategy);
                assert!(a.rays > a.samples, "{kind:?}: paths did not bounce");
                for &build in &builds {
                    let mut out = Vec::new();
                    let b = render_pixels_in(build, &scene, 3, &pixels, &mut out, strategy);
                    let case = format!("{kind:?}, {strategy:?}, {build:?}");
                    // The stream kernel's stage counters are its own.
                    let work = ((a.samples, a.rays), (b.samples, b.rays));
                    assert_eq!(work.0, work.1, "{case}: work counters differ");
                    for (i, (x, y)) in reference.iter().zip(&out).enumerate() {
                        assert_eq!(x, y, "{case}: pixel {i} differs");
                    }
                }
            }
            // The G-buffer's primary hits too, traced a tile at a time in each build.
            for &build in &builds {
                let mut hits = Vec::new();
                for y in (0..30).step_by(PRIMARY_TILE as usize) {
                    let mut block = vec![PixelSample::default(); 40 * 4];
                    let height = PRIMARY_TILE.min(30 - y);
                    block.truncate(40 * height as usize);
                    primary_block_in(build, &scene, (0, y), (40, height), &mut block);
                    hits.extend(block);
                }
                for (i, h) in hits.iter().enumerate() {
                    let case = format!("{kind:?}, {build:?}: G-buffer pixel {i}");
                    assert_eq!(*h, primary_hit(&scene, i as u32), "{case}");
                }
                assert!(hits.iter().any(|h| h.object != u32::MAX), "{kind:?}: no primary hit");
            }
        }
    }
}
