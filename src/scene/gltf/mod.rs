//! glTF 2.0 files (`.gltf` with its buffers and images, or a self-contained `.glb`) read
//! into what the OBJ path produces: one [`Mesh`] with a material slot per glTF material,
//! gridlight [`Material`]s, decoded textures (base colour, metallic-roughness) and the list of companion files a
//! worker must fetch. The view ([`view`]) turns the file's camera and lights into a
//! scene description, so that `gridlight render model.glb` needs no TOML.
//!
//! - Everything is read through the [`AssetResolver`] (external buffers and images are
//!   assets beside the glTF file), so the master and a worker's cache build the same data.
//! - [`geometry`]: the default scene's node hierarchy, flattened into one mesh.
//! - [`material`]: metallic-roughness → gridlight's `MaterialKind::Pbr`.
//! - Embedded images (`data:` URIs, GLB buffer views) have no file of their own; their
//!   texture key is `FILE#imageN` ([`embedded_image`]) and they travel inside the file.
//! - What the file asks that gridlight does not render yet (normal maps, alpha modes,
//!   unknown extensions …) becomes one warning per feature in [`GltfData::warnings`];
//!   a malformed file is a [`GltfError`] naming the element (`accessors[3]`).

pub mod fixture;
pub mod geometry;
pub mod material;
#[cfg(test)]
mod tests;
pub mod view;

use std::borrow::Cow;
use std::path::PathBuf;

use base64::Engine as _;
use gltf::json::validation::Validate;
use gridlight_actors::state::TextureUse;

use super::error::AssetError;
use super::search::{check_asset_path, sibling_asset, AssetBytes, AssetResolver};
use crate::assets::{Mesh, Texture};
pub use material::GltfMaterial;
pub use view::{PlacedCamera, PlacedLight};

/// Extensions whose meaning is rendered (approximately, as [`material`] documents); any
/// other extension the file uses is named in a warning.
pub const HANDLED_EXTENSIONS: &[&str] = &[
    "KHR_lights_punctual",
    "KHR_materials_emissive_strength",
    "KHR_materials_ior",
    "KHR_materials_transmission",
    "KHR_texture_transform",
];

/// A glTF file that cannot be read. `element` names the offending part as glTF's JSON
/// path does (`accessors[3]`, `meshes[0].primitives[1]`, `images[2]`).
#[derive(Debug, thiserror::Error)]
pub enum GltfError {
    /// Not JSON/GLB, or the glTF validator's findings (index out of range …).
    #[error("not a valid glTF 2.0 file: {0}")]
    Parse(#[from] gltf::Error),
    #[error("{element}: {reason}")]
    Invalid { element: String, reason: String },
    /// A buffer or image file that cannot be read or decoded.
    #[error("{element}: {source}")]
    Asset { element: String, source: Box<AssetError> },
    #[error("its default scene has no triangles")]
    NoTriangles,
}

impl GltfError {
    pub(crate) fn invalid(element: impl Into<String>, reason: impl Into<String>) -> Self {
        Self::Invalid { element: element.into(), reason: reason.into() }
    }
}

/// What one glTF file yields.
#[derive(Debug, Clone)]
pub struct GltfData {
    /// The default scene's triangles in the file's world space; slot `i` is
    /// `materials[i]`, the last slot holds primitives without a material.
    pub mesh: Mesh,
    pub materials: Vec<GltfMaterial>,
    /// Decoded textures, keyed as the materials name them, with how each is read.
    pub textures: Vec<(String, TextureUse, Texture)>,
    /// Asset paths of the external buffers and images the file names and that were read.
    pub companions: Vec<String>,
    /// Camera instances in node order.
    pub cameras: Vec<PlacedCamera>,
    /// KHR_lights_punctual instances in node order.
    pub lights: Vec<PlacedLight>,
    /// One line per feature the file uses that is not rendered, each once.
    pub warnings: Warnings,
}

/// Warnings, each kept once, in the order first met.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Warnings(Vec<String>);

impl Warnings {
    pub fn push(&mut self, warning: impl Into<String>) {
        let warning = warning.into();
        if !self.0.contains(&warning) {
            self.0.push(warning);
        }
    }

    pub fn as_slice(&self) -> &[String] {
        &self.0
    }

    pub fn into_vec(self) -> Vec<String> {
        self.0
    }
}

/// True for asset paths that name a glTF file (`.gltf` or `.glb`, any case).
pub fn is_gltf(asset: &str) -> bool {
    let lower = asset.to_ascii_lowercase();
    lower.ends_with(".gltf") || lower.ends_with(".glb")
}

/// The texture key of image `index` embedded in the glTF file `asset`.
pub fn embedded_key(asset: &str, index: usize) -> String {
    format!("{asset}#image{index}")
}

/// The glTF file and image index of an embedded image's texture key, `None` for a file.
pub fn embedded_image(key: &str) -> Option<(&str, usize)> {
    let (file, index) = key.rsplit_once("#image")?;
    (is_gltf(file) && !index.is_empty()).then_some(())?;
    Some((file, index.parse().ok()?))
}

/// Reads the glTF file at asset path `asset`, its buffers and its base-colour images.
pub fn read_gltf(asset: &str, resolver: &dyn AssetResolver) -> Result<GltfData, AssetError> {
    let AssetBytes { file, bytes } = resolver.read(asset)?;
    read_bytes(asset, &bytes, resolver).map_err(|source| AssetError::Gltf { file, source })
}

/// The document and its buffers' bytes, with the warnings reading gave.
pub(crate) struct Document {
    pub doc: gltf::Document,
    pub buffers: Vec<Vec<u8>>,
    pub companions: Vec<String>,
    pub warnings: Warnings,
}

fn read_bytes(
    asset: &str,
    bytes: &[u8],
    resolver: &dyn AssetResolver,
) -> Result<GltfData, GltfError> {
    let mut d = parse(asset, bytes, resolver)?;
    let materials: Vec<GltfMaterial> =
        d.doc.materials().map(|m| material::convert(&m, asset, &mut d.warnings)).collect();
    let mut textures = Vec::new();
    for image in d.doc.images() {
        let key = image_key(asset, &image);
        // Each use once: an image may be a colour and a data texture both.
        let mut uses: Vec<TextureUse> = materials
            .iter()
            .flat_map(|m| m.material.textures())
            .filter(|(path, _)| *path == key)
            .map(|(_, usage)| usage)
            .collect();
        uses.sort_by_key(|u| *u as u8);
        uses.dedup();
        if uses.is_empty() {
            continue;
        }
        let decoded = decode_image(asset, &image, &d, resolver)?;
        if embedded_image(&key).is_none() && !d.companions.contains(&key) {
            d.companions.push(key.clone());
        }
        for usage in uses {
            textures.push((key.clone(), usage, super::loader::texture_of(&decoded, usage)));
        }
    }
    let placed = geometry::flatten(&d.doc, &d.buffers, &mut d.warnings, materials.len() as u32)?;
    Ok(GltfData {
        mesh: placed.mesh,
        materials,
        textures,
        companions: d.companions,
        cameras: placed.cameras,
        lights: placed.lights,
        warnings: d.warnings,
    })
}

/// Parses and validates the document and loads its buffers.
fn parse(asset: &str, bytes: &[u8], resolver: &dyn AssetResolver) -> Result<Document, GltfError> {
    let gltf = gltf::Gltf::from_slice_without_validation(bytes)?;
    let mut warnings = Warnings::default();
    let root = gltf.document.as_json();
    // Required extensions that the crate cannot parse are warned about, not refused: most
    // (texture transform, quantised meshes …) still give a recognisable picture, and those
    // that cannot (compressed geometry) fail below naming the accessor.
    check_position_indices(root)?;
    let mut errors = Vec::new();
    root.validate(root, gltf::json::Path::new, &mut |path, error| errors.push((path(), error)));
    errors.retain(|(path, _)| !path.as_str().starts_with("extensionsRequired"));
    if !errors.is_empty() {
        return Err(gltf::Error::Validation(errors).into());
    }
    for ext in root.extensions_used.iter().chain(&root.extensions_required) {
        if !HANDLED_EXTENSIONS.contains(&ext.as_str()) {
            warnings.push(format!("extension {ext}: not supported, ignored"));
        }
    }
    if !root.animations.is_empty() {
        warnings.push("animations: not played (nodes keep their rest transforms)");
    }
    if !root.skins.is_empty() {
        warnings.push("skins: not applied (skinned meshes are drawn in their bind pose)");
    }
    let mut buffers = Vec::with_capacity(root.buffers.len());
    let mut companions = Vec::new();
    for buffer in gltf.document.buffers() {
        let element = format!("buffers[{}]", buffer.index());
        let data = match buffer.source() {
            gltf::buffer::Source::Bin => gltf.blob.clone().ok_or_else(|| {
                GltfError::invalid(&element, "names the GLB binary chunk, which the file lacks")
            })?,
            gltf::buffer::Source::Uri(uri) => {
                let (data, file) = read_uri(asset, uri, &element, resolver)?;
                companions.extend(file);
                data
            }
        };
        if data.len() < buffer.length() {
            return Err(GltfError::invalid(
                element,
                format!(
                    "holds {} bytes, fewer than its byteLength {}",
                    data.len(),
                    buffer.length()
                ),
            ));
        }
        buffers.push(data);
    }
    Ok(Document { doc: gltf.document, buffers, companions, warnings })
}

/// gltf-json's validator indexes `accessors` with a primitive's POSITION before checking
/// it (and panics when it is out of range): that one is checked first.
fn check_position_indices(root: &gltf::json::Root) -> Result<(), GltfError> {
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            let position =
                gltf::json::validation::Checked::Valid(gltf::json::mesh::Semantic::Positions);
            if let Some(index) = primitive.attributes.get(&position) {
                if index.value() >= root.accessors.len() {
                    return Err(GltfError::invalid(
                        format!("meshes[{m}].primitives[{p}].attributes.POSITION"),
                        format!("accessor {} does not exist", index.value()),
                    ));
                }
            }
        }
    }
    Ok(())
}

/// The bytes a URI names: a `data:` URI's payload, or an asset beside the glTF file (and
/// then its asset path).
fn read_uri(
    asset: &str,
    uri: &str,
    element: &str,
    resolver: &dyn AssetResolver,
) -> Result<(Vec<u8>, Option<String>), GltfError> {
    if let Some(rest) = uri.strip_prefix("data:") {
        let (header, payload) = rest
            .split_once(',')
            .ok_or_else(|| GltfError::invalid(element, "data URI without a `,`"))?;
        if !header.ends_with(";base64") {
            return Err(GltfError::invalid(element, "data URI is not base64"));
        }
        let data = base64::engine::general_purpose::STANDARD
            .decode(payload)
            .map_err(|e| GltfError::invalid(element, format!("data URI: {e}")))?;
        return Ok((data, None));
    }
    if uri.contains("://") {
        return Err(GltfError::invalid(
            element,
            format!("URI `{uri}`: only files beside the glTF and data URIs are read"),
        ));
    }
    let name = percent_encoding::percent_decode_str(uri).decode_utf8_lossy();
    let path = sibling_asset(asset, &name);
    let failed = |e: AssetError| GltfError::Asset { element: element.to_owned(), source: e.into() };
    check_asset_path(&path).map_err(|e| failed(e.into()))?;
    let bytes = resolver.read(&path).map_err(failed)?.bytes.into_owned();
    Ok((bytes, Some(path)))
}

/// The texture key of `image`: its file's asset path, or an embedded key.
pub(crate) fn image_key(asset: &str, image: &gltf::Image) -> String {
    match image.source() {
        gltf::image::Source::Uri { uri, .. } if !uri.starts_with("data:") => {
            sibling_asset(asset, &percent_encoding::percent_decode_str(uri).decode_utf8_lossy())
        }
        _ => embedded_key(asset, image.index()),
    }
}

/// Decodes one image.
fn decode_image(
    asset: &str,
    image: &gltf::Image,
    d: &Document,
    resolver: &dyn AssetResolver,
) -> Result<image::DynamicImage, GltfError> {
    let element = format!("images[{}]", image.index());
    let (bytes, name): (Cow<[u8]>, PathBuf) = match image.source() {
        gltf::image::Source::View { view, mime_type } => {
            let data = view_bytes(&view, &d.buffers)
                .ok_or_else(|| GltfError::invalid(&element, "its bufferView exceeds its buffer"))?;
            (Cow::Borrowed(data), PathBuf::from(format!("{element}.{}", mime_ext(mime_type))))
        }
        gltf::image::Source::Uri { uri, mime_type } => {
            let (data, file) = read_uri(asset, uri, &element, resolver)?;
            let name =
                file.unwrap_or_else(|| format!("{element}.{}", mime_ext(mime_type.unwrap_or(""))));
            (Cow::Owned(data), PathBuf::from(name))
        }
    };
    AssetBytes { file: name, bytes }
        .decode_image()
        .map_err(|e| GltfError::Asset { element: element.clone(), source: Box::new(e) })
}

/// A file extension for a MIME type, so that the image decoder knows the format.
fn mime_ext(mime: &str) -> &'static str {
    match mime {
        "image/png" => "png",
        "image/jpeg" => "jpg",
        _ => "bin",
    }
}

/// The bytes of a buffer view, `None` when it exceeds its buffer.
pub(crate) fn view_bytes<'b>(
    view: &gltf::buffer::View,
    buffers: &'b [Vec<u8>],
) -> Option<&'b [u8]> {
    let start = view.offset();
    let end = start.checked_add(view.length())?;
    buffers.get(view.buffer().index())?.get(start..end)
}
