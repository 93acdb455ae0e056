//! White furnaces and sampling pdfs of the glTF material, lobe by lobe and mixed.

use std::sync::Arc;

use glam::Vec3;
use gridlight_actors::state::Material;

use super::*;
use crate::render::bsdf::tests::{assert_sampled_pdf_matches, directions, uniforms};
use crate::render::testscenes::furnace;
use crate::render::{render_pixels, RenderScene};

/// Every corner of (metallic, roughness, transmission), and the middle of each edge.
fn corners() -> Vec<(String, Bsdf)> {
    let mut out = Vec::new();
    for metallic in [0.0, 0.5, 1.0] {
        for roughness in [0.0, 0.3, 1.0] {
            for transmission in [0.0, 0.5, 1.0] {
                let name = format!("m {metallic} r {roughness} t {transmission}");
                out.push((name, Bsdf::pbr(Vec3::ONE, metallic, roughness, transmission, 1.5)));
            }
        }
    }
    out
}

/// `wo` on both sides: a transmissive surface is seen from inside too.
fn both_sides(directions: Vec<Vec3>) -> Vec<Vec3> {
    directions.into_iter().flat_map(|w| [w, Vec3::new(w.x, w.y, -w.z)]).collect()
}

/// The mean sample weight at `wo`: the directional albedo.
fn albedo(bsdf: &Bsdf, wo: Vec3, n: u32) -> Vec3 {
    let mut sum = Vec3::ZERO;
    for u in uniforms(n, 23) {
        if let Some(s) = bsdf.sample(wo, u) {
            assert!(s.weight.is_finite() && s.weight.min_element() >= 0.0, "weight {}", s.weight);
            sum += s.weight;
        }
    }
    sum / n as f32
}

/// Seen from outside, down to grazing views (from inside, radiance leaving glass is
/// expanded by η², so its weights exceed one by design).
#[test]
fn white_furnace_energy_is_at_most_one_at_every_corner() {
    for (name, bsdf) in corners() {
        for wo in directions() {
            let a = albedo(&bsdf, wo, 20_000);
            // Entering glass compresses radiance by 1/η²; nothing gains energy.
            assert!(a.max_element() <= 1.0 + 5e-3, "{name}: albedo {a} at {wo}");
        }
    }
}

/// The glTF metal is the conductor kind, and its glass the dielectric kind: their
/// directional albedos agree.
#[test]
fn the_metal_and_glass_lobes_are_the_conductor_and_dielectric_kinds() {
    use gridlight_actors::state::MaterialKind::{Conductor, Dielectric};
    let tint = Vec3::new(0.9, 0.6, 0.3);
    for roughness in [0.0, 0.3, 0.8] {
        let pairs = [
            (Bsdf::pbr(tint, 1.0, roughness, 0.0, 1.5), Bsdf::new(Conductor, tint, roughness, 1.5)),
            (
                Bsdf::pbr(tint, 0.0, roughness, 1.0, 1.5),
                Bsdf::new(Dielectric, tint, roughness, 1.5),
            ),
        ];
        for (pbr, old) in pairs {
            for wo in both_sides(directions()) {
                if pbr.two_sided() && wo.z < 0.0 {
                    continue;
                }
                let (a, b) = (albedo(&pbr, wo, 20_000), albedo(&old, wo, 20_000));
                let what = format!("{:?} at roughness {roughness}, {wo}", old.kind);
                assert!((a - b).abs().max_element() < 0.02 * b.max_element(), "{what}: {a} vs {b}");
            }
        }
    }
}

#[test]
fn a_white_metal_keeps_nearly_all_energy_and_a_smooth_one_all() {
    for wo in directions() {
        let smooth = albedo(&Bsdf::pbr(Vec3::ONE, 1.0, 0.0, 0.0, 1.5), wo, 1000);
        assert_eq!(smooth, Vec3::ONE, "smooth metal at {wo}");
        let rough = albedo(&Bsdf::pbr(Vec3::ONE, 1.0, 0.3, 0.0, 1.5), wo, 20_000);
        // Single-scattering microfacets lose a little at grazing angles.
        assert!(rough.min_element() > 0.9, "rough metal at {wo}: {rough}");
    }
}

/// The lobes mixed with their glTF weights: with metallic 0, a black base and no
/// transmission only the dielectric layer reflects, ≈ Schlick's F0 at normal incidence.
#[test]
fn the_dielectric_layer_reflects_its_fresnel_share() {
    let layer = Bsdf::pbr(Vec3::ZERO, 0.0, 0.0, 0.0, 1.5);
    let wo = Vec3::Z;
    assert!((albedo(&layer, wo, 1000).x - 0.04).abs() < 1e-6);
    let grey = Bsdf::pbr(Vec3::splat(0.5), 0.0, 1.0, 0.0, 1.5);
    let a = albedo(&grey, wo, 40_000);
    // Half the light the layer lets through comes back from the base (Lambert 0.5).
    assert!(a.x > 0.45 && a.x < 0.55, "rough grey plastic: {a}");
}

#[test]
fn sampled_pdfs_match_evaluated_pdfs_for_every_lobe_and_their_mixes() {
    let cases = [
        ("diffuse alone", Bsdf::pbr(Vec3::ONE, 0.0, 1.0, 0.0, 1.0001)),
        ("layer over black", Bsdf::pbr(Vec3::ZERO, 0.0, 0.4, 0.0, 1.5)),
        ("rough metal", Bsdf::pbr(Vec3::new(0.9, 0.6, 0.3), 1.0, 0.5, 0.0, 1.5)),
        ("rough glass", Bsdf::pbr(Vec3::ONE, 0.0, 0.4, 1.0, 1.5)),
        ("plastic", Bsdf::pbr(Vec3::new(0.7, 0.5, 0.3), 0.0, 0.3, 0.0, 1.5)),
        ("half metal", Bsdf::pbr(Vec3::new(0.7, 0.5, 0.3), 0.5, 0.6, 0.0, 1.5)),
        ("half glass", Bsdf::pbr(Vec3::new(0.7, 0.5, 0.3), 0.2, 0.5, 0.5, 1.5)),
        ("smooth plastic's base", Bsdf::pbr(Vec3::new(0.7, 0.5, 0.3), 0.0, 0.0, 0.0, 1.5)),
    ];
    for (name, bsdf) in cases {
        assert!(!bsdf.is_delta(), "{name}");
        // Grazing views are left out, as in the other kinds' test (the midpoint rule
        // misjudges their peaked lobes).
        let front: Vec<Vec3> = directions().into_iter().take(3).collect();
        let sides = if bsdf.two_sided() { front } else { both_sides(front) };
        for wo in sides {
            assert_sampled_pdf_matches(name, &bsdf, wo);
        }
    }
}

#[test]
fn smooth_lobes_are_deltas_unless_a_diffuse_base_remains() {
    assert!(Bsdf::pbr(Vec3::ONE, 1.0, 0.0, 0.0, 1.5).is_delta());
    assert!(Bsdf::pbr(Vec3::ONE, 0.0, 0.0, 1.0, 1.5).is_delta());
    assert!(Bsdf::pbr(Vec3::ONE, 0.4, 0.0, 1.0, 1.5).is_delta());
    assert!(!Bsdf::pbr(Vec3::ONE, 0.0, 0.0, 0.0, 1.5).is_delta());
    assert!(!Bsdf::pbr(Vec3::ONE, 1.0, 0.2, 0.0, 1.5).is_delta());
    // Smooth glass in the glTF model is the dielectric kind's smooth glass.
    let glass = Bsdf::pbr(Vec3::ONE, 0.0, 0.0, 1.0, 1.5);
    let old = Bsdf::new(gridlight_actors::state::MaterialKind::Dielectric, Vec3::ONE, 0.0, 1.5);
    for wo in both_sides(directions()) {
        let (a, b) = (albedo(&glass, wo, 4000), albedo(&old, wo, 4000));
        assert!((a - b).abs().max_element() < 1e-5, "at {wo}: {a} vs {b}");
    }
}

/// A metallic-1, roughness-0 white sphere in a uniform environment is invisible: every
/// pixel is the environment.
#[test]
fn a_smooth_white_metal_sphere_in_a_furnace_is_the_environment() {
    let env = Vec3::new(0.8, 0.6, 0.4);
    let (assets, state) = furnace(Material::pbr("mirror", Vec3::ONE, 1.0, 0.0), env, 8, 4);
    let scene = RenderScene::new(assets, &state).unwrap();
    let pixels: Vec<u32> = (0..state.resolution.pixels() as u32).collect();
    let mut out = Vec::new();
    render_pixels(&scene, 0, &pixels, &mut out);
    let sphere = out.iter().filter(|s| s.object == 0).count();
    assert!(sphere > 20, "the sphere is too small");
    // A mirror of the tessellated sphere's interpolated normals sends a few grazing
    // samples into the surface, where they are trapped until the depth limit: those
    // pixels lose a sample; none gains.
    let mut exact = 0;
    for (i, s) in out.iter().enumerate() {
        let c = s.reflected + s.emission;
        assert!(c.cmple(env + Vec3::splat(1e-5)).all(), "pixel {i}: {c}");
        exact += usize::from((c - env).abs().max_element() < 1e-5);
    }
    assert!(
        exact + sphere / 20 >= out.len(),
        "{} of {} pixels differ",
        out.len() - exact,
        out.len()
    );
}

/// Rough and mixed spheres in the furnace return at most the environment; a white
/// plastic nearly all of it (single-scattering metals lose up to 60 % at roughness 1).
#[test]
fn furnace_spheres_never_gain_energy() {
    let cases = [
        (0.0, 1.0, 0.0, 0.8),
        (1.0, 1.0, 0.0, 0.3),
        (0.5, 0.5, 0.0, 0.6),
        (0.0, 0.3, 1.0, 0.85),
        (0.0, 0.0, 0.0, 0.8),
    ];
    for (metallic, roughness, transmission, at_least) in cases {
        let mut m = Material::pbr("ball", Vec3::ONE, metallic, roughness);
        m.transmission = transmission;
        let (assets, state) = furnace(m, Vec3::ONE, 16, 16);
        let scene = RenderScene::new(Arc::clone(&assets), &state).unwrap();
        let pixels: Vec<u32> = (0..state.resolution.pixels() as u32).collect();
        let mut out = Vec::new();
        render_pixels(&scene, 0, &pixels, &mut out);
        let hits: Vec<Vec3> = out
            .iter()
            .filter(|s| s.object == 0 && s.emission == Vec3::ZERO)
            .map(|s| s.reflected)
            .collect();
        let mean = hits.iter().sum::<Vec3>() / hits.len() as f32;
        let case = format!("m {metallic} r {roughness} t {transmission}");
        eprintln!("{case}: {mean}");
        assert!(mean.max_element() < 1.02 && mean.min_element() > at_least, "{case}: {mean}");
    }
}

/// An emitter whose emission map is white everywhere lights the Cornell box as the same
/// emitter without a map does: found by BSDF sampling alone (not in the light table), it
/// converges to the same mean, noisier (131 072 paths: about 1 % noise on the mean).
#[test]
fn a_mapped_emitter_lights_the_box_as_its_unmapped_self_does() {
    let mean = |mapped: bool| {
        let (assets, mut state) = crate::render::testscenes::cornell_box(32, 32);
        state.render.spp = 128;
        let light = &mut state.materials[3];
        light.kind = gridlight_actors::state::MaterialKind::Pbr;
        let mut assets = (*assets).clone();
        if mapped {
            let white = crate::assets::Texture::srgb8(2, 2, vec![[255; 3]; 4]);
            assets.textures.insert("white.png".into(), Arc::new(white));
            light.emissive_texture = Some("white.png".into());
        }
        let scene = RenderScene::new(Arc::new(assets), &state).unwrap();
        assert_eq!(scene.lights.areas.is_empty(), mapped, "mapped emitters are not sampled");
        let pixels: Vec<u32> = (0..32 * 32).collect();
        let mut out = Vec::new();
        render_pixels(&scene, 0, &pixels, &mut out);
        out.iter().map(|s| s.reflected + s.emission).sum::<Vec3>() / out.len() as f32
    };
    let (plain, mapped) = (mean(false), mean(true));
    let ratio = mapped / plain;
    assert!((ratio - Vec3::ONE).abs().max_element() < 0.05, "{mapped} against {plain}");
}
