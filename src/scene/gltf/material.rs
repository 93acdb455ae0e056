//! glTF metallic-roughness materials → the closest existing gridlight material kind.
//!
//! gridlight does not render glTF's BRDF yet (a later step), so each material becomes:
//! - `KHR_materials_transmission` factor ≥ 0.5 → **dielectric**, tinted by the base
//!   colour, with `KHR_materials_ior` (1.5 by default) and the roughness factor;
//! - else metallic factor ≥ 0.5 → **conductor** with the base colour as reflectance;
//! - else roughness < 0.9 → **glossy** (diffuse base under a clear coat of the material's
//!   IOR: glTF's non-metal is exactly a diffuse base with an F0 = 0.04 dielectric layer);
//! - else **diffuse** (at such roughness the coat's lobe is nearly Lambertian and only
//!   adds noise).
//!
//! `baseColorTexture` becomes the albedo texture (not on dielectrics, as for MTL);
//! `emissiveFactor × KHR_materials_emissive_strength` is the emission. What is not rendered
//! (normal, occlusion, metallic-roughness and emissive maps, alpha modes, texture sets
//! other than 0, wrap modes other than repeat, factors between the kinds) is warned about
//! once per feature. The parameters the later PBR step needs are kept in [`Pbr`].

use glam::Vec3;
use gltf::material::AlphaMode;
use gltf::texture::WrappingMode;
use gridlight_actors::state::{Material, MaterialKind};

use super::{image_key, Warnings};

/// Transmission and metallic factors at or above this pick the dielectric / conductor kind.
const KIND_THRESHOLD: f32 = 0.5;
/// Non-metals at or above this roughness are diffuse.
const DIFFUSE_ROUGHNESS: f32 = 0.9;
/// glTF's default index of refraction (F0 = 0.04).
pub const DEFAULT_IOR: f32 = 1.5;

/// One glTF material: what gridlight renders now, and the file's parameters.
#[derive(Debug, Clone, PartialEq)]
pub struct GltfMaterial {
    /// The glTF name (or `material{index}` for unnamed ones).
    pub name: String,
    /// The approximation rendered today; its name is [`GltfMaterial::name`].
    pub material: Material,
    pub pbr: Pbr,
}

/// glTF metallic-roughness parameters, kept for the PBR step; textures as texture keys.
#[derive(Debug, Clone, PartialEq)]
pub struct Pbr {
    /// Linear RGBA.
    pub base_color_factor: [f32; 4],
    pub metallic: f32,
    pub roughness: f32,
    pub transmission: f32,
    pub ior: f32,
    pub metallic_roughness_texture: Option<String>,
    pub normal_texture: Option<String>,
    pub occlusion_texture: Option<String>,
    pub emissive_texture: Option<String>,
    pub alpha_mode: AlphaMode,
    pub double_sided: bool,
}

/// Converts material `m` of the glTF file at asset path `asset`.
pub fn convert(m: &gltf::Material, asset: &str, warnings: &mut Warnings) -> GltfMaterial {
    let name =
        m.name().map_or_else(|| format!("material{}", m.index().unwrap_or(0)), str::to_owned);
    let pbr = m.pbr_metallic_roughness();
    let base_color_texture = pbr.base_color_texture().map(|i| texture_key(asset, &i, warnings));
    let [r, g, b, alpha] = pbr.base_color_factor();
    let clean = |v: f32| if v.is_finite() { v.clamp(0.0, 1.0) } else { 0.0 };
    let metallic = clean(pbr.metallic_factor());
    let roughness = clean(pbr.roughness_factor());
    let transmission = m.transmission().map_or(0.0, |t| clean(t.transmission_factor()));
    let ior = m.ior().filter(|n| (1.0..=4.0).contains(n)).unwrap_or(DEFAULT_IOR);
    let emission = Vec3::from(m.emissive_factor()) * m.emissive_strength().unwrap_or(1.0);
    let emission = if emission.is_finite() { emission.max(Vec3::ZERO) } else { Vec3::ZERO };

    let pbr_params = Pbr {
        base_color_factor: [clean(r), clean(g), clean(b), clean(alpha)],
        metallic,
        roughness,
        transmission,
        ior,
        metallic_roughness_texture: pbr
            .metallic_roughness_texture()
            .map(|i| image_key(asset, &i.texture().source())),
        normal_texture: m.normal_texture().map(|t| image_key(asset, &t.texture().source())),
        occlusion_texture: m.occlusion_texture().map(|t| image_key(asset, &t.texture().source())),
        emissive_texture: m.emissive_texture().map(|i| image_key(asset, &i.texture().source())),
        alpha_mode: m.alpha_mode(),
        double_sided: m.double_sided(),
    };
    warn_unrendered(&pbr_params, m, warnings);

    let kind = if transmission >= KIND_THRESHOLD {
        MaterialKind::Dielectric
    } else if metallic >= KIND_THRESHOLD {
        MaterialKind::Conductor
    } else if roughness < DIFFUSE_ROUGHNESS {
        MaterialKind::Glossy
    } else {
        MaterialKind::Diffuse
    };
    let material = Material {
        name: name.clone(),
        kind,
        base_color: Vec3::new(clean(r), clean(g), clean(b)),
        base_color_texture: if kind == MaterialKind::Dielectric {
            None
        } else {
            base_color_texture
        },
        roughness,
        ior,
        emission,
    };
    GltfMaterial { name, material, pbr: pbr_params }
}

/// The texture key of a texture reference, warning about what the lookup ignores.
fn texture_key(asset: &str, info: &gltf::texture::Info, warnings: &mut Warnings) -> String {
    if info.tex_coord() != 0 {
        warnings.push("textures on TEXCOORD_1 or above: looked up with TEXCOORD_0");
    }
    let sampler = info.texture().sampler();
    if sampler.wrap_s() != WrappingMode::Repeat || sampler.wrap_t() != WrappingMode::Repeat {
        warnings.push("texture wrap modes other than REPEAT: textures repeat");
    }
    image_key(asset, &info.texture().source())
}

fn warn_unrendered(p: &Pbr, m: &gltf::Material, warnings: &mut Warnings) {
    let pairs = [
        (p.normal_texture.is_some(), "normal maps (normalTexture): not rendered"),
        (p.occlusion_texture.is_some(), "occlusion maps (occlusionTexture): not rendered"),
        (
            p.metallic_roughness_texture.is_some(),
            "metallicRoughnessTexture: not rendered (the metallic and roughness factors are used)",
        ),
        (
            p.emissive_texture.is_some(),
            "emissiveTexture: not rendered (the emissive factor is used uniformly)",
        ),
        (
            m.transmission().is_some_and(|t| t.transmission_texture().is_some()),
            "transmissionTexture: not rendered (the transmission factor is used)",
        ),
        (p.alpha_mode == AlphaMode::Mask, "alphaMode MASK: drawn opaque"),
        (p.alpha_mode == AlphaMode::Blend, "alphaMode BLEND: drawn opaque"),
        (
            p.metallic > 0.0 && p.metallic < 1.0,
            "metallic factors between 0 and 1: rounded to metal or non-metal",
        ),
        (
            p.transmission > 0.0 && p.transmission < 1.0,
            "transmission factors between 0 and 1: rounded to glass or opaque",
        ),
    ];
    for (used, warning) in pairs {
        if used {
            warnings.push(warning);
        }
    }
}
