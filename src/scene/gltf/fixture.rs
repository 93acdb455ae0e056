//! Small glTF files written from code: the fixtures of the glTF tests (the repository ships
//! no sample models). One binary buffer; accessors, meshes, nodes, materials, images,
//! cameras and lights are added as JSON and the file is written as `.gltf` (+ `.bin` or a
//! `data:` URI) or as `.glb`. The JSON stays editable, so tests can break it on purpose.

use std::path::Path;

use base64::Engine as _;
use serde_json::{json, Value};

/// Where the binary buffer goes when writing a `.gltf`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Bin {
    /// `NAME.bin` beside the `.gltf`.
    File,
    /// A base64 `data:` URI inside the JSON.
    DataUri,
}

/// A glTF document under construction.
#[derive(Debug, Clone)]
pub struct Fixture {
    pub json: Value,
    pub bin: Vec<u8>,
}

impl Default for Fixture {
    fn default() -> Self {
        Self::new()
    }
}

impl Fixture {
    pub fn new() -> Self {
        let json = json!({
            "asset": { "version": "2.0", "generator": "gridlight fixture" },
            "scene": 0,
            "scenes": [{ "nodes": [] }],
        });
        Self { json, bin: Vec::new() }
    }

    /// Appends `value` to the top-level array `key`, returning its index.
    pub fn push(&mut self, key: &str, value: Value) -> usize {
        let array = self.json.as_object_mut().expect("object").entry(key).or_insert(json!([]));
        let array = array.as_array_mut().expect("array");
        array.push(value);
        array.len() - 1
    }

    /// A buffer view over `bytes`, appended to the buffer (4-byte aligned).
    pub fn view(&mut self, bytes: &[u8]) -> usize {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        let offset = self.bin.len();
        self.bin.extend_from_slice(bytes);
        self.push(
            "bufferViews",
            json!({ "buffer": 0, "byteOffset": offset, "byteLength": bytes.len() }),
        )
    }

    /// A float accessor of `N`-vectors (`VEC3`, `VEC2`); positions get their min/max.
    pub fn floats<const N: usize>(&mut self, data: &[[f32; N]]) -> usize {
        let bytes: Vec<u8> = data.iter().flatten().flat_map(|f| f.to_le_bytes()).collect();
        let view = self.view(&bytes);
        let kind = match N {
            2 => "VEC2",
            3 => "VEC3",
            4 => "VEC4",
            _ => "SCALAR",
        };
        let mut min = [f32::INFINITY; N];
        let mut max = [f32::NEG_INFINITY; N];
        for v in data {
            for i in 0..N {
                min[i] = min[i].min(v[i]);
                max[i] = max[i].max(v[i]);
            }
        }
        self.push(
            "accessors",
            json!({ "bufferView": view, "componentType": 5126, "count": data.len(),
                    "type": kind, "min": min.to_vec(), "max": max.to_vec() }),
        )
    }

    /// An index accessor `bytes` wide (1, 2 or 4).
    pub fn indices(&mut self, indices: &[u32], bytes: usize) -> usize {
        let data: Vec<u8> = indices
            .iter()
            .flat_map(|&i| match bytes {
                1 => vec![i as u8],
                2 => (i as u16).to_le_bytes().to_vec(),
                _ => i.to_le_bytes().to_vec(),
            })
            .collect();
        let view = self.view(&data);
        let component = match bytes {
            1 => 5121,
            2 => 5123,
            _ => 5125,
        };
        self.push(
            "accessors",
            json!({ "bufferView": view, "componentType": component,
                    "count": indices.len(), "type": "SCALAR" }),
        )
    }

    /// A mesh of one triangle primitive; `attributes` as glTF writes them.
    pub fn mesh(
        &mut self,
        attributes: Value,
        indices: Option<usize>,
        material: Option<usize>,
    ) -> usize {
        let mut primitive = json!({ "attributes": attributes });
        if let Some(i) = indices {
            primitive["indices"] = json!(i);
        }
        if let Some(m) = material {
            primitive["material"] = json!(m);
        }
        self.push("meshes", json!({ "primitives": [primitive] }))
    }

    /// A unit quad in the xy-plane facing +z (two triangles), with normals and UVs,
    /// indices `index_bytes` wide.
    pub fn quad_mesh(&mut self, material: Option<usize>, index_bytes: usize) -> usize {
        let p =
            self.floats(&[[-0.5, -0.5, 0.0], [0.5, -0.5, 0.0], [0.5, 0.5, 0.0], [-0.5, 0.5, 0.0]]);
        let n = self.floats(&[[0.0, 0.0, 1.0]; 4]);
        let t = self.floats(&[[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]]);
        let i = self.indices(&[0, 1, 2, 0, 2, 3], index_bytes);
        self.mesh(json!({ "POSITION": p, "NORMAL": n, "TEXCOORD_0": t }), Some(i), material)
    }

    /// A node; it is a root of the scene when `root`.
    pub fn node(&mut self, node: Value, root: bool) -> usize {
        let index = self.push("nodes", node);
        if root {
            self.json["scenes"][0]["nodes"].as_array_mut().expect("nodes").push(json!(index));
        }
        index
    }

    /// A PNG image of `w`×`h` RGB pixels, in a buffer view, as a `data:` URI, or as the
    /// file `uri` beside the glTF (written by [`Fixture::write_gltf`] into `files`).
    pub fn png(&mut self, w: u32, h: u32, rgb: &[[u8; 3]], file: Option<&str>) -> (usize, Vec<u8>) {
        let img = image::RgbImage::from_fn(w, h, |x, y| image::Rgb(rgb[(y * w + x) as usize]));
        let mut png = Vec::new();
        img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png).expect("png");
        let image = match file {
            Some(uri) => json!({ "uri": uri }),
            None => {
                let view = self.view(&png);
                json!({ "bufferView": view, "mimeType": "image/png" })
            }
        };
        (self.push("images", image), png)
    }

    /// A PNG image of `w`×`h` RGBA pixels, in a buffer view.
    pub fn png_rgba(&mut self, w: u32, h: u32, rgba: &[[u8; 4]]) -> usize {
        let img = image::RgbaImage::from_fn(w, h, |x, y| image::Rgba(rgba[(y * w + x) as usize]));
        let mut png = Vec::new();
        img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png).expect("png");
        let view = self.view(&png);
        self.push("images", json!({ "bufferView": view, "mimeType": "image/png" }))
    }

    /// A texture of image `image` (default sampler).
    pub fn texture(&mut self, image: usize) -> usize {
        self.push("textures", json!({ "source": image }))
    }

    /// Declares an extension as used.
    pub fn uses(&mut self, extension: &str) {
        self.push("extensionsUsed", json!(extension));
    }

    fn with_buffer(&self, uri: Option<String>) -> Value {
        let mut json = self.json.clone();
        let mut buffer = json!({ "byteLength": self.bin.len() });
        if let Some(uri) = uri {
            buffer["uri"] = json!(uri);
        }
        if !self.bin.is_empty() {
            json["buffers"] = json!([buffer]);
        }
        json
    }

    /// Writes `dir/NAME.gltf` (and `dir/NAME.bin` for [`Bin::File`]).
    pub fn write_gltf(&self, dir: &Path, name: &str, bin: Bin) {
        let uri = match bin {
            Bin::File => {
                std::fs::write(dir.join(format!("{name}.bin")), &self.bin).expect("write bin");
                format!("{name}.bin")
            }
            Bin::DataUri => format!(
                "data:application/octet-stream;base64,{}",
                base64::engine::general_purpose::STANDARD.encode(&self.bin)
            ),
        };
        let text = serde_json::to_string_pretty(&self.with_buffer(Some(uri))).expect("json");
        std::fs::write(dir.join(format!("{name}.gltf")), text).expect("write gltf");
    }

    /// The `.glb` bytes: JSON chunk, then the buffer as the BIN chunk.
    pub fn glb(&self) -> Vec<u8> {
        let mut json = serde_json::to_vec(&self.with_buffer(None)).expect("json");
        while !json.len().is_multiple_of(4) {
            json.push(b' ');
        }
        let mut bin = self.bin.clone();
        while !bin.len().is_multiple_of(4) {
            bin.push(0);
        }
        let total = 12 + 8 + json.len() + if bin.is_empty() { 0 } else { 8 + bin.len() };
        let mut out = Vec::with_capacity(total);
        out.extend_from_slice(b"glTF");
        out.extend_from_slice(&2u32.to_le_bytes());
        out.extend_from_slice(&(total as u32).to_le_bytes());
        out.extend_from_slice(&(json.len() as u32).to_le_bytes());
        out.extend_from_slice(b"JSON");
        out.extend_from_slice(&json);
        if !bin.is_empty() {
            out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
            out.extend_from_slice(b"BIN\0");
            out.extend_from_slice(&bin);
        }
        out
    }
}

/// A lit scene for render tests: a large grey floor quad facing +z, a smaller orange quad
/// in front of it, a camera on +z looking at them (4:3), and a point light; the orange
/// quad's material is `material` (JSON) with the material index 0.
pub fn lit_scene(material: Value) -> Fixture {
    let mut f = Fixture::new();
    let orange = f.push("materials", material);
    let grey = f.push(
        "materials",
        json!({ "name": "grey", "pbrMetallicRoughness":
                { "baseColorFactor": [0.5, 0.5, 0.5, 1.0], "metallicFactor": 0.0,
                  "roughnessFactor": 1.0 } }),
    );
    let back = f.quad_mesh(Some(grey), 2);
    let front = f.quad_mesh(Some(orange), 2);
    f.node(
        json!({ "mesh": back, "scale": [4.0, 4.0, 1.0], "translation": [0.0, 0.0, -1.0] }),
        true,
    );
    f.node(json!({ "mesh": front }), true);
    let camera = f.push(
        "cameras",
        json!({ "type": "perspective",
                "perspective": { "yfov": 0.8, "aspectRatio": 1.3333334, "znear": 0.1 } }),
    );
    f.node(json!({ "camera": camera, "translation": [0.0, 0.0, 3.0] }), true);
    f.uses("KHR_lights_punctual");
    f.json["extensions"] = json!({ "KHR_lights_punctual": { "lights": [
        { "type": "point", "color": [1.0, 1.0, 1.0], "intensity": 20.0 } ] } });
    f.node(
        json!({ "translation": [0.0, 0.5, 2.0],
                   "extensions": { "KHR_lights_punctual": { "light": 0 } } }),
        true,
    );
    f
}
