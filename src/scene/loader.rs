//! Asset data for a scene state: meshes, textures and environment maps, read through an
//! [`AssetResolver`] (the master's search path or a worker's cache).
//!
//! Albedo textures keep their 8-bit sRGB codes, linearised at lookup (`assets::Texels`);
//! environment maps (Radiance `.hdr`, OpenEXR) are linear already and are only checked.

use std::sync::Arc;

use glam::Vec3;
use gridlight_actors::state::{Geometry, SceneState};

use super::error::AssetError;
use super::obj::read_obj;
use super::search::AssetResolver;
use crate::assets::{Assets, Mesh, Texture};
use crate::shapes;

/// Every asset `state` refers to. A worker calls this with its cache as the resolver.
pub fn load_assets(state: &SceneState, resolver: &dyn AssetResolver) -> Result<Assets, AssetError> {
    let mut assets = Assets::default();
    for object in &state.objects {
        if assets.meshes.contains_key(&object.geometry) {
            continue;
        }
        let mesh = match &object.geometry {
            Geometry::Obj { path } => {
                let data = read_obj(path, resolver)?;
                assets.obj_libraries.insert(path.clone(), data.mtl_assets);
                data.mesh
            }
            builtin => load_mesh(builtin, resolver)?,
        };
        assets.meshes.insert(object.geometry.clone(), Arc::new(mesh));
    }
    for material in &state.materials {
        if let Some(path) = &material.base_color_texture {
            if !assets.textures.contains_key(path) {
                assets
                    .textures
                    .insert(path.clone(), Arc::new(load_albedo_texture(path, resolver)?));
            }
        }
    }
    if let Some(path) = state.environment.as_ref().and_then(|e| e.map.as_ref()) {
        assets.environments.insert(path.clone(), Arc::new(load_environment(path, resolver)?));
    }
    Ok(assets)
}

/// The mesh of one geometry: a built-in shape or an OBJ file.
pub fn load_mesh(geometry: &Geometry, resolver: &dyn AssetResolver) -> Result<Mesh, AssetError> {
    match geometry {
        Geometry::Obj { path } => Ok(read_obj(path, resolver)?.mesh),
        builtin => Ok(shapes::mesh(builtin).expect("every non-OBJ geometry is a built-in shape")),
    }
}

/// An 8-bit sRGB albedo texture (PNG, JPEG, TGA …) decoded to linear RGB; alpha is dropped.
pub fn load_albedo_texture(
    asset: &str,
    resolver: &dyn AssetResolver,
) -> Result<Texture, AssetError> {
    let image = resolver.read(asset)?.decode_image()?;
    let rgb = image.to_rgb8();
    let codes = rgb.pixels().map(|p| p.0).collect();
    Ok(Texture::srgb8(rgb.width(), rgb.height(), codes))
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
    fn albedo_textures_are_linearised() {
        let dir = tempfile::tempdir().expect("tempdir");
        let img =
            image::RgbImage::from_fn(2, 1, |x, _| image::Rgb([if x == 0 { 0 } else { 188 }; 3]));
        img.save(dir.path().join("t.png")).expect("save png");
        let resolver = AssetSearchPath::from_dirs(vec![dir.path().into()]);
        let tex = load_albedo_texture("t.png", &resolver).expect("load");
        assert_eq!((tex.width, tex.height), (2, 1));
        assert_eq!(tex.texels.get(0), Vec3::ZERO);
        assert!((tex.texels.get(1).x - 0.5).abs() < 0.01);
    }
}
