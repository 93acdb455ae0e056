//! The asset manifest: every file a scene state needs, with its SHA-256 and length.
//!
//! The master sends it to each worker on connect (docs/design.md, decision 4); the worker fetches
//! what its cache lacks and then loads the state's assets through a resolver over its cache.
//! The list holds each mesh file (OBJ or glTF) and the files it names (MTL libraries, glTF
//! buffers and images), every albedo texture the state's materials use and the environment
//! map, each once, in that order. A texture embedded in a glTF file travels inside it.

use std::fs::File;
use std::io::Read;

use gridlight_actors::protocol::{AssetEntry, AssetHash};
use gridlight_actors::state::{Geometry, SceneState};
use sha2::{Digest, Sha256};

use super::error::AssetError;
use super::gltf::embedded_image;
use super::loader::read_mesh_file;
use super::search::AssetResolver;
use crate::assets::Assets;

/// The manifest of `state`, with files found through `resolver`, each read and hashed
/// here (a mesh file is parsed for the files it names). The master does not call it: it
/// lists [`asset_paths`] from the assets it loaded and its asset store hashes each file
/// as it adds it, so that every asset is read and hashed once at start.
pub fn manifest(
    state: &SceneState,
    resolver: &dyn AssetResolver,
) -> Result<Vec<AssetEntry>, AssetError> {
    let paths = paths_with(state, |mesh| Ok(read_mesh_file(mesh, resolver)?.companions))?;
    paths.into_iter().map(|path| entry(path, resolver)).collect()
}

/// The asset paths of `state`'s manifest, in manifest order, each once, with the files
/// each mesh file names taken from `assets` (loaded with the state, so nothing is read
/// again).
pub fn asset_paths(state: &SceneState, assets: &Assets) -> Result<Vec<String>, AssetError> {
    paths_with(state, |mesh| {
        let companions = assets.mesh_companions.get(mesh).cloned();
        companions.ok_or_else(|| AssetError::NotLoaded(mesh.to_owned()))
    })
}

/// The manifest's paths; `companions` gives the files a mesh file names.
fn paths_with(
    state: &SceneState,
    companions: impl Fn(&str) -> Result<Vec<String>, AssetError>,
) -> Result<Vec<String>, AssetError> {
    let mut paths: Vec<String> = Vec::new();
    let push = |p: &str, paths: &mut Vec<String>| {
        if !paths.iter().any(|x| x == p) {
            paths.push(p.to_owned());
        }
    };
    for object in &state.objects {
        if let Geometry::Obj { path } | Geometry::Gltf { path } = &object.geometry {
            if paths.contains(path) {
                continue;
            }
            push(path, &mut paths);
            for companion in companions(path)? {
                push(&companion, &mut paths);
            }
        }
    }
    for material in &state.materials {
        for (texture, _) in material.textures() {
            if embedded_image(texture).is_some() {
                continue;
            }
            push(texture, &mut paths);
        }
    }
    if let Some(map) = state.environment.as_ref().and_then(|e| e.map.as_ref()) {
        push(map, &mut paths);
    }
    Ok(paths)
}

fn entry(path: String, resolver: &dyn AssetResolver) -> Result<AssetEntry, AssetError> {
    let file = resolver.resolve(&path)?;
    let read_err = |source| AssetError::Read { file: file.clone(), source };
    let mut reader = File::open(&file).map_err(read_err)?;
    let mut hasher = Sha256::new();
    let mut buf = vec![0u8; 1 << 16];
    let mut len = 0u64;
    loop {
        let n = reader.read(&mut buf).map_err(read_err)?;
        if n == 0 {
            break;
        }
        hasher.update(&buf[..n]);
        len += n as u64;
    }
    let hash: AssetHash = hasher.finalize().into();
    Ok(AssetEntry { path, hash, len })
}
