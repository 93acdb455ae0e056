//! glTF metallic-roughness materials → gridlight's [`MaterialKind::Pbr`], which renders the
//! specification's BRDF (`render::pbr`): base colour (factor × texture), metallic and
//! roughness (factors × the metallic-roughness texture's B and G), `KHR_materials_ior`,
//! `KHR_materials_transmission`'s factor, `emissiveFactor` × `emissiveTexture` (sRGB) ×
//! `KHR_materials_emissive_strength`, alpha (the base colour factor's, times the base
//! colour texture's alpha channel) with `alphaMode` MASK and BLEND (`render::alpha`).
//! `doubleSided` is kept in the material too.
//!
//! `normalTexture` is rendered too (`render::normal_map`), with tangents from each
//! triangle's texture coordinates. What is not rendered (occlusion maps, the
//! transmission texture, texture sets other than 0, wrap modes other than
//! repeat) and the normal maps' tangents are warned about once per feature.

use glam::Vec3;
use gltf::texture::WrappingMode;
use gridlight_actors::state::{AlphaMode, Material, MaterialKind};

use super::{image_key, Warnings};

/// glTF's default index of refraction (F0 = 0.04).
pub const DEFAULT_IOR: f32 = 1.5;

/// One glTF material as gridlight renders it.
#[derive(Debug, Clone, PartialEq)]
pub struct GltfMaterial {
    /// The glTF name (or `material{index}` for unnamed ones).
    pub name: String,
    /// A [`MaterialKind::Pbr`] material; its name is [`GltfMaterial::name`].
    pub material: Material,
}

/// Converts material `m` of the glTF file at asset path `asset`.
pub fn convert(m: &gltf::Material, asset: &str, warnings: &mut Warnings) -> GltfMaterial {
    let name =
        m.name().map_or_else(|| format!("material{}", m.index().unwrap_or(0)), str::to_owned);
    let pbr = m.pbr_metallic_roughness();
    let [r, g, b, alpha] = pbr.base_color_factor();
    let clean = |v: f32| if v.is_finite() { v.clamp(0.0, 1.0) } else { 0.0 };
    let emission = Vec3::from(m.emissive_factor());
    let emission = if emission.is_finite() { emission.max(Vec3::ZERO) } else { Vec3::ZERO };
    let strength = m.emissive_strength().filter(|s| s.is_finite() && *s >= 0.0).unwrap_or(1.0);
    let (alpha_mode, alpha_cutoff) = match m.alpha_mode() {
        gltf::material::AlphaMode::Opaque => (AlphaMode::Opaque, 0.5),
        gltf::material::AlphaMode::Mask => {
            (AlphaMode::Mask, clean(m.alpha_cutoff().unwrap_or(0.5)))
        }
        gltf::material::AlphaMode::Blend => (AlphaMode::Blend, 0.5),
    };
    let normal = m.normal_texture();
    let material = Material {
        name: name.clone(),
        kind: MaterialKind::Pbr,
        base_color: Vec3::new(clean(r), clean(g), clean(b)),
        base_color_texture: pbr.base_color_texture().map(|i| texture_key(asset, &i, warnings)),
        roughness: clean(pbr.roughness_factor()),
        ior: m.ior().filter(|n| (1.0..=4.0).contains(n)).unwrap_or(DEFAULT_IOR),
        emission,
        emission_strength: strength,
        metallic: clean(pbr.metallic_factor()),
        transmission: m.transmission().map_or(0.0, |t| clean(t.transmission_factor())),
        alpha: clean(alpha),
        alpha_mode,
        alpha_cutoff,
        double_sided: m.double_sided(),
        metallic_roughness_texture: pbr
            .metallic_roughness_texture()
            .map(|i| texture_key(asset, &i, warnings)),
        normal_texture: normal.as_ref().map(|t| image_key(asset, &t.texture().source())),
        normal_scale: normal.as_ref().map_or(1.0, |t| t.scale()),
        emissive_texture: m.emissive_texture().map(|i| texture_key(asset, &i, warnings)),
    };
    warn_unrendered(&material, m, warnings);
    GltfMaterial { name, material }
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

fn warn_unrendered(p: &Material, m: &gltf::Material, warnings: &mut Warnings) {
    let pairs = [
        (
            p.normal_texture.is_some(),
            "normal maps: tangents from each triangle's texture coordinates (the file's \
             TANGENT attribute and MikkTSpace tangents are not used yet)",
        ),
        (m.occlusion_texture().is_some(), "occlusion maps (occlusionTexture): not rendered"),
        (
            m.transmission().is_some_and(|t| t.transmission_texture().is_some()),
            "transmissionTexture: not rendered (the transmission factor is used)",
        ),
    ];
    for (used, warning) in pairs {
        if used {
            warnings.push(warning);
        }
    }
}
