//! A [`RenderScene`] as the GPU tracer's buffers: the [`Params`] uniform (mirror of
//! `Params` in `shaders/trace/scene.wgsl`), one array of words with every table (BVHs from
//! `accel::export`, materials, lights, the environment's CDFs, the Sobol tables) and one
//! array of texel floats (albedo textures and the environment map, RGB).
//!
//! Everything is taken from the CPU tracer's own structures after they were built
//! (`Lights`, `Environment`, `Bsdf::new`), so the two tracers sample the same
//! distributions; nothing is re-derived here.

use bytemuck::{Pod, Zeroable};
use glam::Vec3;
use gridlight_actors::state::MaterialKind;

use crate::render::accel::export;
use crate::render::bsdf::Bsdf;
use crate::render::envmap::{Distribution1D, Environment};
use crate::render::sampler;
use crate::render::RenderScene;

/// Words per material (`MATERIAL_WORDS` in `shaders/trace/path.wgsl`).
const MATERIAL_WORDS: usize = 16;
/// Words per area light (`AREA_WORDS` in `shaders/trace/lights.wgsl`).
const AREA_WORDS: usize = 16;
/// Words per point or spot light (`POINT_WORDS`).
const POINT_WORDS: usize = 12;

/// The uniform of the trace pass, field for field `Params` in `scene.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct Params {
    pub image: [u32; 4],
    pub job: [u32; 4],
    pub cam_origin: [f32; 4],
    pub cam_forward: [f32; 4],
    pub cam_right: [f32; 4],
    pub cam_up: [f32; 4],
    pub cam_inv: [f32; 4],
    pub sec_a: [u32; 4],
    pub sec_b: [u32; 4],
    pub sec_c: [u32; 4],
    pub sec_d: [u32; 4],
    pub sec_e: [u32; 4],
    pub geo: [u32; 4],
    pub lights_a: [u32; 4],
    pub lights_b: [f32; 4],
    pub sun_dir: [f32; 4],
    pub sun_radiance: [f32; 4],
    pub env: [u32; 4],
    pub env_scale: [f32; 4],
    pub env_rot: [f32; 4],
}

const _: () = assert!(std::mem::size_of::<Params>() == 20 * 16);

/// The packed scene: `params.job` is left for the dispatch to fill.
#[derive(Debug)]
pub struct PackedScene {
    pub params: Params,
    pub words: Vec<u32>,
    pub texels: Vec<f32>,
}

fn v4(v: Vec3, w: f32) -> [f32; 4] {
    [v.x, v.y, v.z, w]
}

/// Appends sections and remembers where each starts.
#[derive(Default)]
struct Words(Vec<u32>);

impl Words {
    fn section(&mut self, words: impl IntoIterator<Item = u32>) -> u32 {
        let at = self.0.len() as u32;
        self.0.extend(words);
        at
    }

    fn floats(&mut self, floats: &[f32]) -> u32 {
        self.section(floats.iter().map(|f| f.to_bits()))
    }
}

/// The kind's code in `material.wgsl`; `None` for the kinds the WGSL tracer lacks.
fn kind_code(kind: MaterialKind) -> Option<u32> {
    match kind {
        MaterialKind::Diffuse => Some(0),
        MaterialKind::Conductor => Some(1),
        MaterialKind::Glossy => Some(2),
        MaterialKind::Dielectric => Some(3),
        MaterialKind::Pbr => None,
    }
}

/// Why a scene cannot be packed for the GPU tracer.
#[derive(Debug, thiserror::Error)]
pub enum PackError {
    /// The WGSL tracer has no glTF metallic-roughness BSDF yet: it refuses rather than
    /// render such a material as something else.
    #[error(
        "material `{material}` is a glTF metallic-roughness (pbr) material, which the GPU \
         tracer does not render yet: render this scene on the CPU"
    )]
    UnsupportedMaterial { material: String },
    /// The WGSL tracer has no alpha test: it refuses rather than draw a cut-out or
    /// blended surface opaque.
    #[error(
        "material `{material}` is alpha-masked or blended, which the GPU tracer does not \
         render yet: render this scene on the CPU"
    )]
    UnsupportedAlpha { material: String },
}

fn distribution(d: &Distribution1D) -> impl Iterator<Item = u32> + '_ {
    [d.integral.to_bits(), d.func.len() as u32]
        .into_iter()
        .chain(d.cdf.iter().chain(&d.func).map(|f| f.to_bits()))
}

/// Packs `scene` for the trace pass; refuses a material kind the WGSL tracer lacks.
pub fn pack(scene: &RenderScene) -> Result<PackedScene, PackError> {
    if let Some(i) = scene.materials.iter().position(|m| kind_code(m.kind).is_none()) {
        let material = scene.state().materials.get(i).map_or("?", |m| &m.name).to_owned();
        return Err(PackError::UnsupportedMaterial { material });
    }
    if let Some(i) = scene.materials.iter().position(|m| m.cutout) {
        let material = scene.state().materials.get(i).map_or("?", |m| &m.name).to_owned();
        return Err(PackError::UnsupportedAlpha { material });
    }
    let state = scene.state();
    let mut p = Params::default();
    let mut w = Words::default();
    let mut texels: Vec<f32> = Vec::new();
    let c = &scene.camera;
    p.image =
        [state.resolution.width, state.resolution.height, state.render.spp, state.render.max_depth];
    p.cam_origin = v4(c.origin, c.aperture);
    p.cam_forward = v4(c.forward, c.focus_distance);
    p.cam_right = v4(c.right, c.half_w);
    p.cam_up = v4(c.up, c.half_h);
    p.cam_inv = [c.inv_width, c.inv_height, 0.0, 0.0];

    let a = export::export(&scene.tlas);
    p.sec_a = [
        w.section(a.nodes.iter().copied()),
        w.floats(&a.tris),
        w.section(a.leaves.iter().copied()),
        w.section(a.instances.iter().copied()),
    ];
    p.sec_b = [
        w.section(a.large.iter().copied()),
        w.section(a.flat_owner.iter().copied()),
        w.section(a.mesh_indices.iter().copied()),
        w.floats(&a.normals),
    ];
    p.geo = [a.flat_triangles, a.tlas_root, a.large.len() as u32, 0];

    // Materials, with their textures appended to the texels once each.
    let mut texture_at: std::collections::HashMap<*const crate::assets::Texture, u32> =
        std::collections::HashMap::new();
    let mut materials = Vec::with_capacity(scene.materials.len() * MATERIAL_WORDS);
    for m in &scene.materials {
        let bsdf = Bsdf::new(m.kind, m.base_color, m.roughness, m.ior);
        let (offset, tw, th) = match &m.texture {
            Some(t) => {
                let offset = *texture_at.entry(std::sync::Arc::as_ptr(t)).or_insert_with(|| {
                    let at = texels.len() as u32;
                    texels.extend(t.texels.iter().flat_map(|v| v.to_array()));
                    at
                });
                (offset, t.width, t.height)
            }
            None => (0, 0, 0),
        };
        let f = |x: f32| x.to_bits();
        materials.extend_from_slice(&[
            kind_code(m.kind).unwrap_or_default(),
            offset,
            tw,
            th,
            f(m.base_color.x),
            f(m.base_color.y),
            f(m.base_color.z),
            f(bsdf.ggx.alpha),
            f(bsdf.eta),
            f(m.emission.x),
            f(m.emission.y),
            f(m.emission.z),
            u32::from(m.texture.is_some()),
            0,
            0,
            0,
        ]);
    }
    p.sec_c = [
        w.floats(&a.uvs),
        w.section(materials),
        w.section(scene.slot_materials.iter().copied()),
        0,
    ];

    let lights = &scene.lights;
    let mut areas = Vec::with_capacity(lights.areas.len() * AREA_WORDS);
    for l in &lights.areas {
        for v in [l.v0, l.e1, l.e2, l.normal, l.radiance] {
            areas.extend(v.to_array().map(f32::to_bits));
        }
        areas.push(u32::from(l.parallelogram));
    }
    p.sec_c[3] = w.section(areas);
    let mut points = Vec::with_capacity(lights.points.len() * POINT_WORDS);
    for l in &lights.points {
        let (axis, inner, outer) = l.spot.unwrap_or((Vec3::ZERO, 0.0, 0.0));
        for v in [l.position, l.intensity, axis] {
            points.extend(v.to_array().map(f32::to_bits));
        }
        points.extend_from_slice(&[inner.to_bits(), outer.to_bits(), u32::from(l.spot.is_some())]);
    }
    let quads: Vec<u32> = (0..lights.areas.len() as u32)
        .filter(|&i| lights.areas[i as usize].parallelogram)
        .collect();
    let sobol = sampler::sobol_tables().iter().flatten().flatten().copied();
    p.sec_d = [
        w.floats(&lights.area_cdf),
        w.section(points),
        w.section(quads.iter().copied()),
        w.section(sobol),
    ];
    p.lights_a = [
        lights.areas.len() as u32,
        lights.points.len() as u32,
        lights.strategies,
        quads.len() as u32,
    ];
    p.lights_b = [lights.area_power, lights.strategy_pmf, 1.0, 0.0];
    if let Some(sun) = &lights.sun {
        p.lights_b[2] = sun.cos_max;
        p.lights_b[3] = 1.0;
        p.sun_dir = v4(sun.frame.n, 0.0);
        p.sun_radiance = v4(sun.radiance, 0.0);
    }

    match &lights.environment {
        None => {}
        Some(Environment::Constant(c)) => {
            p.env = [1, 0, 0, 0];
            p.env_scale = v4(*c, 0.0);
            p.env_rot = [1.0, 0.0, 0.0, 0.0];
        }
        Some(Environment::Map(m)) => {
            p.env = [2, m.texture.width, m.texture.height, 0];
            p.env_scale = v4(m.scale, 0.0);
            // to_world is a rotation about +y: (cos, 0, -sin) is its first column.
            p.env_rot = [m.to_world.x_axis.x, -m.to_world.x_axis.z, 0.0, 0.0];
            let marginal = w.section(distribution(&m.marginal));
            let rows = w.section(m.conditional.iter().flat_map(distribution));
            let at = texels.len() as u32;
            texels.extend(m.texture.texels.iter().flat_map(|v| v.to_array()));
            p.sec_e = [marginal, rows, at, 0];
        }
    }
    // wgpu refuses empty bindings.
    if texels.is_empty() {
        texels.extend_from_slice(&[0.0; 4]);
    }
    Ok(PackedScene { params: p, words: w.0, texels })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::testscenes::furnace;
    use gridlight_actors::state::Material;

    #[test]
    fn a_pbr_material_is_refused_by_name_and_the_old_kinds_pack() {
        let (assets, state) = furnace(Material::pbr("brass", Vec3::ONE, 1.0, 0.2), Vec3::ONE, 4, 1);
        let scene = RenderScene::new(assets, &state).unwrap();
        let Err(err) = pack(&scene) else { panic!("a pbr material must be refused") };
        assert!(err.to_string().contains("`brass`"), "{err}");
        let (assets, state) = furnace(Material::diffuse("white", Vec3::ONE), Vec3::ONE, 4, 1);
        assert!(pack(&RenderScene::new(assets, &state).unwrap()).is_ok());
    }

    #[test]
    fn an_alpha_masked_or_blended_material_is_refused_by_name_and_an_opaque_one_packs() {
        use gridlight_actors::state::AlphaMode;
        for (mode, alpha, refused) in [
            (AlphaMode::Mask, 0.2, true),
            (AlphaMode::Blend, 0.5, true),
            // Coverage 1 everywhere: nothing to cut, nothing refused.
            (AlphaMode::Mask, 1.0, false),
            (AlphaMode::Opaque, 0.2, false),
        ] {
            let leaf = Material { alpha, alpha_mode: mode, ..Material::diffuse("leaf", Vec3::ONE) };
            let (assets, state) = furnace(leaf, Vec3::ONE, 4, 1);
            let packed = pack(&RenderScene::new(assets, &state).unwrap());
            match packed {
                Err(err) => {
                    assert!(refused, "{mode:?} {alpha}: {err}");
                    assert!(
                        err.to_string().contains("`leaf`") && err.to_string().contains("alpha")
                    );
                }
                Ok(_) => assert!(!refused, "{mode:?} {alpha} must be refused"),
            }
        }
    }
}
