//! The asset manifest: every file a scene state needs, with its SHA-256 and length.
//!
//! The master sends it to each worker on connect (DESIGN.md decision 4); the worker fetches
//! what its cache lacks and then loads the state's assets through a resolver over its cache.
//! The list holds each OBJ, the material libraries it names, every albedo texture the state's
//! materials use and the environment map, each once, in that order.

use std::fs::File;
use std::io::Read;

use gridlight_actors::protocol::{AssetEntry, AssetHash};
use gridlight_actors::state::{Geometry, SceneState};
use sha2::{Digest, Sha256};

use super::error::AssetError;
use super::obj::read_obj;
use super::search::AssetResolver;

/// The manifest of `state`, with files found through `resolver`.
pub fn manifest(
    state: &SceneState,
    resolver: &dyn AssetResolver,
) -> Result<Vec<AssetEntry>, AssetError> {
    let mut paths: Vec<String> = Vec::new();
    let push = |p: &str, paths: &mut Vec<String>| {
        if !paths.iter().any(|x| x == p) {
            paths.push(p.to_owned());
        }
    };
    for object in &state.objects {
        if let Geometry::Obj { path } = &object.geometry {
            if paths.contains(path) {
                continue;
            }
            push(path, &mut paths);
            for mtl in read_obj(path, resolver)?.mtl_assets {
                push(&mtl, &mut paths);
            }
        }
    }
    for material in &state.materials {
        if let Some(texture) = &material.base_color_texture {
            push(texture, &mut paths);
        }
    }
    if let Some(map) = state.environment.as_ref().and_then(|e| e.map.as_ref()) {
        push(map, &mut paths);
    }
    paths.into_iter().map(|path| entry(path, resolver)).collect()
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
