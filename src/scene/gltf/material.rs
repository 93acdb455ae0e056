//! glTF metallic-roughness materials → gridlight's [`MaterialKind::Pbr`], which renders the
//! specification's BRDF (`render::pbr`): base colour (factor × texture), metallic and
//! roughness (factors × the metallic-roughness texture's B and G), `KHR_materials_ior`,
//! `KHR_materials_transmission`'s factor, `emissiveFactor` × `emissiveTexture` (sRGB) ×
//! `KHR_materials_emissive_strength`, alpha (the base colour factor's, times the base
//! colour texture's alpha channel) with `alphaMode` MASK and BLEND (`render::alpha`).
//! `doubleSided` is kept in the material too.
//!
//! `normalTexture` is rendered too (`render::normal_map`), with tangents from each
//! triangle's texture coordinates. Every map keeps its sampler's wrap modes and its
//! `KHR_texture_transform` (`MapLookup`, read from the extension's JSON: the crate parses
//! it for some texture references only). What is not rendered (occlusion maps, the
//! transmission texture, texture sets other than 0) and the normal maps' tangents are
//! warned about once per feature.

use glam::{Vec2, Vec3};
use gltf::texture::WrappingMode;
use gridlight_actors::state::{AlphaMode, MapLookup, MapLookups, Material, MaterialKind, Wrap};

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
    let mut lookups = MapLookups::default();
    let mut map = |info: Option<gltf::texture::Info>, lookup: &mut MapLookup| {
        let info = info?;
        let texture = info.texture();
        *lookup = map_lookup(&texture, info.extension_value(TRANSFORM), warnings);
        check_tex_coord(
            info.tex_coord(),
            lookup_tex_coord(info.extension_value(TRANSFORM)),
            warnings,
        );
        Some(image_key(asset, &texture.source()))
    };
    let base_color_texture = map(pbr.base_color_texture(), &mut lookups.base_color);
    let metallic_roughness_texture =
        map(pbr.metallic_roughness_texture(), &mut lookups.metallic_roughness);
    let emissive_texture = map(m.emissive_texture(), &mut lookups.emissive);
    let normal_texture = normal.as_ref().map(|t| {
        let texture = t.texture();
        lookups.normal = map_lookup(&texture, t.extension_value(TRANSFORM), warnings);
        check_tex_coord(t.tex_coord(), lookup_tex_coord(t.extension_value(TRANSFORM)), warnings);
        image_key(asset, &texture.source())
    });
    let material = Material {
        name: name.clone(),
        kind: MaterialKind::Pbr,
        base_color: Vec3::new(clean(r), clean(g), clean(b)),
        base_color_texture,
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
        metallic_roughness_texture,
        normal_texture,
        normal_scale: normal.as_ref().map_or(1.0, |t| t.scale()),
        emissive_texture,
        lookups,
    };
    warn_unrendered(&material, m, warnings);
    GltfMaterial { name, material }
}

/// The extension a texture reference's transform is in.
const TRANSFORM: &str = "KHR_texture_transform";

/// How a texture reference looks its image up: its sampler's wrap modes and its
/// `KHR_texture_transform` (`transform`, the extension's JSON; malformed numbers are
/// warned about and left at their defaults).
fn map_lookup(
    texture: &gltf::Texture,
    transform: Option<&serde_json::Value>,
    warnings: &mut Warnings,
) -> MapLookup {
    let sampler = texture.sampler();
    let wrap = |mode| match mode {
        WrappingMode::Repeat => Wrap::Repeat,
        WrappingMode::ClampToEdge => Wrap::ClampToEdge,
        WrappingMode::MirroredRepeat => Wrap::MirroredRepeat,
    };
    let mut lookup =
        MapLookup { wrap: [wrap(sampler.wrap_s()), wrap(sampler.wrap_t())], ..Default::default() };
    let Some(t) = transform else { return lookup };
    let pair = |key: &str, default: Vec2, warnings: &mut Warnings| match t.get(key) {
        None => default,
        Some(v) => match serde_json::from_value::<[f32; 2]>(v.clone()) {
            Ok(p) if Vec2::from(p).is_finite() => Vec2::from(p),
            _ => {
                warnings.push(format!("{TRANSFORM}: a malformed {key} is ignored"));
                default
            }
        },
    };
    lookup.offset = pair("offset", Vec2::ZERO, warnings);
    lookup.scale = pair("scale", Vec2::ONE, warnings);
    match t.get("rotation").map(|r| r.as_f64().map(|r| r as f32)) {
        None => {}
        Some(Some(r)) if r.is_finite() => lookup.rotation = r,
        Some(_) => warnings.push(format!("{TRANSFORM}: a malformed rotation is ignored")),
    }
    lookup
}

/// A transform's `texCoord` override.
fn lookup_tex_coord(transform: Option<&serde_json::Value>) -> Option<u64> {
    transform?.get("texCoord")?.as_u64()
}

/// Warns where a texture reference asks for a texture coordinate set other than 0.
fn check_tex_coord(tex_coord: u32, overridden: Option<u64>, warnings: &mut Warnings) {
    if overridden.unwrap_or(tex_coord as u64) != 0 {
        warnings.push("textures on TEXCOORD_1 or above: looked up with TEXCOORD_0");
    }
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
