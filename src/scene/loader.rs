//! Asset data for a scene state: meshes, textures and environment maps, read through an
//! [`AssetResolver`] (the master's search path or a worker's cache).
//!
//! Textures keep their 8-bit codes: albedo sRGB, linearised at lookup, data (glTF's
//! metallic-roughness) linear (`assets::Texels`);
//! environment maps (Radiance `.hdr`, OpenEXR) are linear already and are only checked.

use std::sync::Arc;

use glam::Vec3;
use gridlight_actors::state::{Geometry, Material, SceneState, TextureUse};

use super::error::AssetError;
use super::gltf::{is_gltf, read_gltf, GltfData};
use super::mtl;
use super::obj::read_obj;
use super::search::AssetResolver;
use crate::assets::{Assets, Mesh, Texture};
use crate::shapes;

/// A mesh file read: an OBJ with its MTL materials, or a glTF file.
#[derive(Debug, Clone)]
pub struct MeshFile {
    pub mesh: Mesh,
    /// The file's materials in slot order (the last slot, "no material", is not listed),
    /// each named `MESH:NAME`.
    pub materials: Vec<Material>,
    /// Asset paths of the files it named and that were read (MTL, buffers, images).
    pub companions: Vec<String>,
    /// Textures the file decoded itself (a glTF's), by texture key and use.
    pub textures: Vec<(String, TextureUse, Texture)>,
    /// What the file asks that is not rendered, one line per feature.
    pub warnings: Vec<String>,
}

/// Reads the OBJ or glTF file at asset path `asset` (by its extension).
pub fn read_mesh_file(asset: &str, resolver: &dyn AssetResolver) -> Result<MeshFile, AssetError> {
    if is_gltf(asset) {
        return Ok(gltf_mesh_file(asset, read_gltf(asset, resolver)?));
    }
    let data = read_obj(asset, resolver)?;
    Ok(MeshFile {
        mesh: data.mesh,
        materials: data
            .materials
            .iter()
            .map(|m| mtl::convert(m, asset, format!("{asset}:{}", m.name)))
            .collect(),
        companions: data.mtl_assets,
        textures: Vec::new(),
        warnings: Vec::new(),
    })
}

/// The mesh file of the glTF file at asset path `asset`, read as `data`.
pub fn gltf_mesh_file(asset: &str, data: GltfData) -> MeshFile {
    MeshFile {
        mesh: data.mesh,
        materials: data
            .materials
            .into_iter()
            .map(|m| Material { name: format!("{asset}:{}", m.name), ..m.material })
            .collect(),
        companions: data.companions,
        textures: data.textures,
        warnings: data.warnings.into_vec(),
    }
}

/// Every asset `state` refers to. A worker calls this with its cache as the resolver.
pub fn load_assets(state: &SceneState, resolver: &dyn AssetResolver) -> Result<Assets, AssetError> {
    let mut assets = Assets::default();
    for object in &state.objects {
        if assets.meshes.contains_key(&object.geometry) {
            continue;
        }
        let mesh = match &object.geometry {
            Geometry::Obj { path } | Geometry::Gltf { path } => {
                let file = read_mesh_file(path, resolver)?;
                assets.mesh_companions.insert(path.clone(), file.companions);
                for (key, usage, texture) in file.textures {
                    assets.insert_texture(key, usage, Arc::new(texture));
                }
                file.mesh
            }
            builtin => load_mesh(builtin, resolver)?,
        };
        assets.meshes.insert(object.geometry.clone(), Arc::new(mesh));
    }
    for material in &state.materials {
        for (path, usage) in material.textures() {
            if assets.texture(path, usage).is_none() {
                let texture = Arc::new(load_texture(path, usage, resolver)?);
                assets.insert_texture(path.to_owned(), usage, texture);
            }
        }
    }
    if let Some(path) = state.environment.as_ref().and_then(|e| e.map.as_ref()) {
        assets.environments.insert(path.clone(), Arc::new(load_environment(path, resolver)?));
    }
    Ok(assets)
}

/// The mesh of one geometry: a built-in shape, an OBJ or a glTF file.
pub fn load_mesh(geometry: &Geometry, resolver: &dyn AssetResolver) -> Result<Mesh, AssetError> {
    match geometry {
        Geometry::Obj { path } | Geometry::Gltf { path } => {
            Ok(read_mesh_file(path, resolver)?.mesh)
        }
        builtin => Ok(shapes::mesh(builtin).expect("every other geometry is a built-in shape")),
    }
}

/// An 8-bit texture (PNG, JPEG, TGA …) read as `usage` says; alpha is kept for colour
/// maps only.
pub fn load_texture(
    asset: &str,
    usage: TextureUse,
    resolver: &dyn AssetResolver,
) -> Result<Texture, AssetError> {
    Ok(texture_of(&resolver.read(asset)?.decode_image()?, usage))
}

/// A decoded image as a texture read as `usage` says; alpha is kept for colour maps only.
pub fn texture_of(image: &image::DynamicImage, usage: TextureUse) -> Texture {
    match usage {
        TextureUse::Color | TextureUse::Emission => albedo_texture(image),
        TextureUse::Data | TextureUse::Normal => {
            let rgb = image.to_rgb8();
            let codes = rgb.pixels().map(|p| p.0).collect();
            Texture::unorm8(rgb.width(), rgb.height(), codes)
        }
    }
}

/// A decoded image as an sRGB albedo texture, with its alpha channel as coverage where
/// some texel is not opaque (alpha masks and blending read it).
pub fn albedo_texture(image: &image::DynamicImage) -> Texture {
    if image.color().has_alpha() {
        let rgba = image.to_rgba8();
        let codes = rgba.pixels().map(|p| [p.0[0], p.0[1], p.0[2]]).collect();
        let alpha = rgba.pixels().map(|p| p.0[3]).collect();
        return Texture::srgb8(rgba.width(), rgba.height(), codes).with_alpha(alpha);
    }
    let rgb = image.to_rgb8();
    let codes = rgb.pixels().map(|p| p.0).collect();
    Texture::srgb8(rgb.width(), rgb.height(), codes)
}

/// A linear HDR environment map; non-finite or negative texels are set to zero.
pub fn load_environment(asset: &str, resolver: &dyn AssetResolver) -> Result<Texture, AssetError> {
    let image = resolver.read(asset)?.decode_image()?;
    let rgb = image.to_rgb32f();
    let texels = rgb
        .pixels()
        .map(|p| {
            let v = Vec3::new(p[0], p[1], p[2]);
            if v.is_finite() {
                v.max(Vec3::ZERO)
            } else {
                Vec3::ZERO
            }
        })
        .collect();
    Ok(Texture::linear(rgb.width(), rgb.height(), texels))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::assets::srgb_to_linear;
    use crate::scene::search::AssetSearchPath;

    #[test]
    fn srgb_endpoints_and_midpoint() {
        assert_eq!(srgb_to_linear(0), 0.0);
        assert!((srgb_to_linear(255) - 1.0).abs() < 1e-6);
        // sRGB 188 is about 50 % linear.
        assert!((srgb_to_linear(188) - 0.5).abs() < 0.01);
    }

    #[test]
    fn albedo_textures_are_linearised_and_data_textures_are_not() {
        let dir = tempfile::tempdir().expect("tempdir");
        let img =
            image::RgbImage::from_fn(2, 1, |x, _| image::Rgb([if x == 0 { 0 } else { 188 }; 3]));
        img.save(dir.path().join("t.png")).expect("save png");
        let resolver = AssetSearchPath::from_dirs(vec![dir.path().into()]);
        let tex = load_texture("t.png", TextureUse::Color, &resolver).expect("load");
        assert_eq!((tex.width, tex.height), (2, 1));
        assert_eq!(tex.texels.get(0), Vec3::ZERO);
        assert!((tex.texels.get(1).x - 0.5).abs() < 0.01);
        let data = load_texture("t.png", TextureUse::Data, &resolver).expect("load");
        assert_eq!(data.texels.get(1), Vec3::splat(188.0 / 255.0));
    }
}
