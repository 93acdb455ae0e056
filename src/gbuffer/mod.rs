//! The G-buffer: per-pixel primary-hit data that guides reconstruction and remodulation,
//! all of it in this folder.
//!
//! Computed on the master for every pixel of a frame's scene state (docs/design.md), by the
//! CPU path ([`GBuffer::from_scene`], `primary_hit` of every pixel, traced a tile of
//! pixels at a time in the dispatched kernel build) or the wgpu raster pass ([`GpuGBuffer`]: `gpu.rs` with its device
//! objects in `raster.rs` and its WGSL in `raster.wgsl`); [`GBufferSource`] picks one
//! and caches by state version. `emission.rs` refines the directly seen emission of
//! converging frames; `ahead.rs` computes a new state's G-buffer on its own thread before
//! its first frame is composed (`--gbuffer-ahead`).
//! Stored as separate planes (structure of arrays) because each pass reads only some of
//! them and the GPU uploads each as its own texture.

use std::sync::Arc;

use glam::Vec3;
use gridlight_actors::state::{SceneState, StateVersion};

use rayon::prelude::*;

use crate::assets::Assets;
use crate::gpu::{Backend, GpuContext, GpuError};

pub mod ahead;
pub mod emission;
pub mod gpu;
mod raster;

use crate::render::isa::IsaLevel;
use crate::render::{primary_block_in, PixelSample, RenderError, RenderScene, PRIMARY_TILE};
pub use gpu::GpuGBuffer;

/// Object id of pixels whose camera ray hit no object.
pub const NO_OBJECT: u32 = u32::MAX;

/// Primary-hit planes of one frame, row-major with y = 0 the top row.
#[derive(Clone, Debug, PartialEq)]
pub struct GBuffer {
    pub width: u32,
    pub height: u32,
    /// World shading normal; zero where the camera ray escaped.
    pub normal: Vec<Vec3>,
    /// World position of the primary hit.
    pub position: Vec<Vec3>,
    /// Albedo of the primary hit (textured); 1 where the ray escaped.
    pub albedo: Vec<Vec3>,
    /// Emission seen directly by the camera ray (environment for escaping rays).
    pub emission: Vec<Vec3>,
    /// Index into `SceneState::objects`, or [`NO_OBJECT`].
    pub object: Vec<u32>,
    /// Scene units per unit of the relative position threshold β (see [`scene_scale`]).
    pub scene_scale: f32,
}

impl GBuffer {
    /// A G-buffer where every camera ray escapes into a black environment.
    pub fn empty(width: u32, height: u32, scene_scale: f32) -> Self {
        let n = width as usize * height as usize;
        Self {
            width,
            height,
            normal: vec![Vec3::ZERO; n],
            position: vec![Vec3::ZERO; n],
            albedo: vec![Vec3::ONE; n],
            emission: vec![Vec3::ZERO; n],
            object: vec![NO_OBJECT; n],
            scene_scale,
        }
    }

    /// The G-buffer planes of per-pixel samples (pixel order), e.g. from `render_pixels`
    /// or `primary_hit`.
    pub fn from_samples(
        width: u32,
        height: u32,
        samples: &[PixelSample],
        scene_scale: f32,
    ) -> Self {
        Self {
            width,
            height,
            normal: samples.iter().map(|s| s.normal).collect(),
            position: samples.iter().map(|s| s.position).collect(),
            albedo: samples.iter().map(|s| s.albedo).collect(),
            emission: samples.iter().map(|s| s.emission).collect(),
            object: samples.iter().map(|s| s.object).collect(),
            scene_scale,
        }
    }

    /// The CPU G-buffer of a scene state: one primary ray through each pixel centre
    /// (`render::primary_hit`), with `scene_scale` given (it depends on the objects only:
    /// [`GBufferSource`] keeps it while only the camera moves).
    ///
    /// Bands of rows run on every thread of the pool; each traces blocks of a few rows'
    /// pixels into a small buffer (one call into the dispatched kernel build, whose rays go
    /// a tile of 4×4 at a time: `render::primary_block_in`) and writes them straight into
    /// its rows of the planes, which are allocated zeroed and so faulted in by the
    /// threads that write them.
    pub fn from_scene(scene: &RenderScene, scene_scale: f32) -> Self {
        let mut g = Self::empty(0, 0, scene_scale);
        g.trace(scene, scene_scale);
        g
    }

    /// [`Self::from_scene`] into this G-buffer's planes, which it no longer needs: a moving
    /// camera makes a G-buffer every frame, and fresh planes (about 100 MB at 1920×1080)
    /// cost their page faults every time; planes of the right length are overwritten.
    pub fn retrace(mut self, scene: &RenderScene, scene_scale: f32) -> Self {
        self.trace(scene, scene_scale);
        self
    }

    /// Every pixel's primary hit into the planes (see [`Self::from_scene`]).
    fn trace(&mut self, scene: &RenderScene, scene_scale: f32) {
        let res = scene.state().resolution;
        let (w, n) = (res.width as usize, res.pixels());
        (self.width, self.height, self.scene_scale) = (res.width, res.height, scene_scale);
        sized(&mut self.normal, n);
        sized(&mut self.position, n);
        sized(&mut self.albedo, n);
        sized(&mut self.emission, n);
        sized(&mut self.object, n);
        // About four bands per thread, to share out rows of unequal cost, each a whole
        // number of tiles tall.
        let (rows, tile) = (res.height as usize, PRIMARY_TILE as usize);
        let band = rows.div_ceil(4 * rayon::current_num_threads()).max(1).next_multiple_of(tile);
        let build = IsaLevel::best();
        self.bands(band * w).into_par_iter().for_each(|(first, mut band)| {
            let mut hits = [PixelSample::default(); BLOCK * PRIMARY_TILE as usize];
            let y0 = first / w;
            for y in (0..band.len() / w).step_by(tile) {
                let height = tile.min(band.len() / w - y);
                for x in (0..w).step_by(BLOCK) {
                    let width = BLOCK.min(w - x);
                    let block = &mut hits[..width * height];
                    let (corner, size) = ((x, y0 + y), (width, height));
                    primary_block_in(build, scene, cast(corner), cast(size), block);
                    for (row, samples) in block.chunks(width).enumerate() {
                        band.write((y + row) * w + x, samples);
                    }
                }
            }
        });
    }

    /// The planes cut into bands of `pixels` consecutive pixels, each with its first pixel.
    fn bands(&mut self, pixels: usize) -> Vec<(usize, Band<'_>)> {
        let mut position = self.position.chunks_mut(pixels);
        let mut albedo = self.albedo.chunks_mut(pixels);
        let mut emission = self.emission.chunks_mut(pixels);
        let mut object = self.object.chunks_mut(pixels);
        let mut bands = Vec::new();
        for normal in self.normal.chunks_mut(pixels) {
            let band = Band {
                normal,
                position: position.next().expect("planes of one length"),
                albedo: albedo.next().expect("planes of one length"),
                emission: emission.next().expect("planes of one length"),
                object: object.next().expect("planes of one length"),
            };
            bands.push((bands.len() * pixels, band));
        }
        bands
    }

    /// Number of pixels.
    pub fn len(&self) -> usize {
        self.width as usize * self.height as usize
    }

    /// Whether the image has no pixels.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Checks that every plane has one entry per pixel and the scale is usable.
    pub fn validate(&self, width: u32, height: u32) -> Result<(), GBufferError> {
        if (self.width, self.height) != (width, height) {
            return Err(GBufferError::SizeMismatch {
                expected: (width, height),
                got: (self.width, self.height),
            });
        }
        let n = self.len();
        let planes = [
            ("normal", self.normal.len()),
            ("position", self.position.len()),
            ("albedo", self.albedo.len()),
            ("emission", self.emission.len()),
            ("object", self.object.len()),
        ];
        for (plane, len) in planes {
            if len != n {
                return Err(GBufferError::PlaneLength { plane, expected: n, got: len });
            }
        }
        if !(self.scene_scale.is_finite() && self.scene_scale > 0.0) {
            return Err(GBufferError::BadScale(self.scene_scale));
        }
        Ok(())
    }
}

/// Makes `v` `n` entries long, keeping its memory when it already is (its entries are
/// all overwritten); new memory is zeroed, which the OS maps lazily, so the threads that
/// write it fault it in, in parallel.
fn sized<T: bytemuck::Zeroable>(v: &mut Vec<T>, n: usize) {
    if v.len() != n {
        *v = bytemuck::zeroed_vec(n);
    }
}

/// Columns of a block of pixels traced per call into the kernel build (one tile tall):
/// a buffer of their samples stays in L1.
const BLOCK: usize = 16;

/// A pair of pixel counts (a corner or a size) as the kernel takes them.
fn cast((x, y): (usize, usize)) -> (u32, u32) {
    (x as u32, y as u32)
}

/// Consecutive pixels of every plane, written by one thread.
struct Band<'a> {
    normal: &'a mut [Vec3],
    position: &'a mut [Vec3],
    albedo: &'a mut [Vec3],
    emission: &'a mut [Vec3],
    object: &'a mut [u32],
}

impl Band<'_> {
    fn len(&self) -> usize {
        self.normal.len()
    }

    /// Writes `samples` into the band's pixels from `start` on.
    fn write(&mut self, start: usize, samples: &[PixelSample]) {
        let end = start + samples.len();
        let planes = self.normal[start..end]
            .iter_mut()
            .zip(&mut self.position[start..end])
            .zip(&mut self.albedo[start..end])
            .zip(&mut self.emission[start..end])
            .zip(&mut self.object[start..end]);
        for (((((n, p), a), e), o), s) in planes.zip(samples) {
            (*n, *p, *a, *e, *o) = (s.normal, s.position, s.albedo, s.emission, s.object);
        }
    }
}

/// The scene's size for the relative position threshold: half the largest extent of the
/// world-space bounding box of all visible objects (1 for the classic 2-unit Cornell box).
/// Falls back to 1 for an empty scene.
pub fn scene_scale(state: &SceneState, assets: &Assets) -> f32 {
    let mut lo = Vec3::splat(f32::INFINITY);
    let mut hi = Vec3::splat(f32::NEG_INFINITY);
    for object in state.objects.iter().filter(|o| o.visible) {
        let builtin;
        let mesh = match assets.meshes.get(&object.geometry) {
            Some(mesh) => mesh.as_ref(),
            None => match crate::shapes::mesh(&object.geometry) {
                Some(mesh) => {
                    builtin = mesh;
                    &builtin
                }
                None => continue,
            },
        };
        let matrix = object.transform.matrix();
        for &p in &mesh.positions {
            let w = matrix.transform_point3(p);
            lo = lo.min(w);
            hi = hi.max(w);
        }
    }
    let extent = (hi - lo).max_element() * 0.5;
    if extent.is_finite() && extent > 0.0 {
        extent
    } else {
        1.0
    }
}

/// [`scene_scale`] kept for the objects it was computed from: it depends on the visible
/// objects' geometry and transforms only, so a camera move reuses it instead of walking
/// every vertex again.
#[derive(Debug, Default)]
pub struct SceneScale {
    last: Option<(Vec<gridlight_actors::state::Object>, f32)>,
}

impl SceneScale {
    /// `scene_scale(state, assets)`, recomputed only when `state`'s objects changed.
    pub fn get(&mut self, state: &SceneState, assets: &Assets) -> f32 {
        match &self.last {
            Some((objects, scale)) if *objects == state.objects => *scale,
            _ => {
                let scale = scene_scale(state, assets);
                self.last = Some((state.objects.clone(), scale));
                scale
            }
        }
    }
}

/// Why a G-buffer could not be computed.
#[derive(Debug, thiserror::Error)]
pub enum GBufferError {
    #[error("scene state cannot be drawn: {0}")]
    Scene(#[from] RenderError),
    #[error("GPU G-buffer: {0}")]
    Gpu(#[from] GpuError),
    #[error("G-buffer is {}×{}, the reconstructor is {}×{}", got.0, got.1, expected.0, expected.1)]
    SizeMismatch { expected: (u32, u32), got: (u32, u32) },
    #[error("G-buffer plane `{plane}` has {got} entries, expected {expected}")]
    PlaneLength { plane: &'static str, expected: usize, got: usize },
    #[error("scene scale {0} is not a positive number")]
    BadScale(f32),
}

/// Both boxed: each holds a whole `RenderScene`.
enum Engine {
    Cpu(Box<RenderScene>),
    Gpu(Box<GpuGBuffer>),
}

/// The master's G-buffers: one per scene-state version, from the raster pass or the CPU
/// path (they agree; `tests/gbuffer_parity.rs`), computed only when the version is new.
pub struct GBufferSource {
    assets: Arc<Assets>,
    engine: Engine,
    /// Why `Auto` ended up on the CPU, if it did.
    fallback: Option<String>,
    current: Option<(StateVersion, Arc<GBuffer>)>,
    /// The CPU path's scene scale.
    scale: SceneScale,
}

impl GBufferSource {
    /// Prepares G-buffers of scene states over `assets`, starting from `initial`; `Auto` and
    /// `Gpu` open the default adapter.
    pub fn new(
        assets: Arc<Assets>,
        initial: &SceneState,
        backend: Backend,
    ) -> Result<Self, GBufferError> {
        let ctx = match backend {
            Backend::Cpu => Ok(None),
            Backend::Auto => GpuContext::new_hardware().map(|c| Some(c.shared())),
            Backend::Gpu => GpuContext::new().map(|c| Some(c.shared())),
        };
        match ctx {
            Ok(ctx) => Self::with_context(assets, initial, backend, ctx),
            Err(err) if backend == Backend::Auto => {
                let mut source = Self::with_context(assets, initial, Backend::Cpu, None)?;
                source.fallback = Some(err.to_string());
                Ok(source)
            }
            Err(err) => Err(err.into()),
        }
    }

    /// Like [`Self::new`] on a device that is already open (the reconstructor's), or on
    /// none (`ctx` `None`: `Auto` means the CPU path, `Gpu` is an error).
    pub fn with_context(
        assets: Arc<Assets>,
        initial: &SceneState,
        backend: Backend,
        ctx: Option<Arc<GpuContext>>,
    ) -> Result<Self, GBufferError> {
        let cpu = |assets: &Arc<Assets>| -> Result<Engine, GBufferError> {
            Ok(Engine::Cpu(Box::new(RenderScene::new(Arc::clone(assets), initial)?)))
        };
        let (engine, fallback) = match (backend, ctx) {
            (Backend::Cpu, _) => (cpu(&assets)?, None),
            (Backend::Auto, None) => (cpu(&assets)?, Some("no GPU context".to_string())),
            (Backend::Gpu, None) => {
                return Err(GpuError::NoAdapter("no GPU context was given".into()).into())
            }
            (backend, Some(ctx)) => match GpuGBuffer::new(ctx, Arc::clone(&assets), initial) {
                Ok(gpu) => (Engine::Gpu(Box::new(gpu)), None),
                Err(GBufferError::Gpu(err)) if backend == Backend::Auto => {
                    (cpu(&assets)?, Some(err.to_string()))
                }
                Err(err) => return Err(err),
            },
        };
        if let Some(why) = &fallback {
            tracing::info!(why = %why, "G-buffer on the CPU");
        }
        Ok(Self { assets, engine, fallback, current: None, scale: SceneScale::default() })
    }

    /// Whether G-buffers come from the raster pass.
    pub fn is_gpu(&self) -> bool {
        matches!(self.engine, Engine::Gpu(_))
    }

    /// The render scene of the last state asked for (picking uses the same BVH).
    pub fn scene(&self) -> &RenderScene {
        match &self.engine {
            Engine::Cpu(scene) => scene,
            Engine::Gpu(gpu) => gpu.scene(),
        }
    }

    /// Why `Auto` chose the CPU path, if it did.
    pub fn fallback_reason(&self) -> Option<&str> {
        self.fallback.as_deref()
    }

    /// Makes `g`, `state`'s G-buffer computed elsewhere (`ahead`), the
    /// current one, and the render scene `state`'s, as [`Self::get`] would have.
    pub fn adopt(
        &mut self,
        state: &SceneState,
        g: Arc<GBuffer>,
    ) -> Result<Arc<GBuffer>, GBufferError> {
        match &mut self.engine {
            Engine::Gpu(gpu) => gpu.set_state(state)?,
            Engine::Cpu(scene) if scene.state().version != state.version => {
                scene.set_state(state)?
            }
            Engine::Cpu(_) => {}
        }
        self.current = Some((state.version, Arc::clone(&g)));
        Ok(g)
    }

    /// The G-buffer of `state`, computed only when its version is new.
    pub fn get(&mut self, state: &SceneState) -> Result<Arc<GBuffer>, GBufferError> {
        if let Some((version, g)) = &self.current {
            if *version == state.version {
                return Ok(Arc::clone(g));
            }
        }
        let g = match &mut self.engine {
            Engine::Gpu(gpu) => gpu.compute(state)?,
            Engine::Cpu(scene) => {
                if scene.state().version != state.version {
                    scene.set_state(state)?;
                }
                let scale = self.scale.get(state, &self.assets);
                // The last G-buffer's planes, unless someone still holds it.
                match self.current.take().and_then(|(_, g)| Arc::try_unwrap(g).ok()) {
                    Some(old) => old.retrace(scene, scale),
                    None => GBuffer::from_scene(scene, scale),
                }
            }
        };
        let g = Arc::new(g);
        self.current = Some((state.version, Arc::clone(&g)));
        Ok(g)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn validate_names_the_short_plane() {
        let mut g = GBuffer::empty(4, 3, 1.0);
        g.validate(4, 3).expect("consistent");
        g.albedo.pop();
        let err = g.validate(4, 3).expect_err("short plane").to_string();
        assert!(err.contains("albedo"), "{err}");
        let err = GBuffer::empty(4, 3, 1.0).validate(5, 3).expect_err("size").to_string();
        assert!(err.contains("4×3"), "{err}");
    }

    #[test]
    fn from_scene_is_every_pixels_primary_hit() {
        // Sizes whose bands and runs end mid-row, a thin lens, and a scene with an
        // environment (escaping rays' emission).
        for (w, h, aperture) in [(37, 23, 0.0), (130, 7, 0.05), (5, 40, 0.0)] {
            let (assets, mut state) = crate::render::testscenes::cornell_box(w, h);
            state.camera.aperture = aperture;
            state.environment = Some(gridlight_actors::state::Environment {
                map: None,
                color: Vec3::new(0.2, 0.3, 0.4),
                intensity: 1.0,
                rotation_deg: 0.0,
            });
            let scene = RenderScene::new(assets, &state).unwrap();
            let g = GBuffer::from_scene(&scene, 1.5);
            let want: Vec<PixelSample> =
                (0..w * h).map(|p| crate::render::primary_hit(&scene, p)).collect();
            let escaped = want.iter().filter(|s| s.object == NO_OBJECT).count();
            assert!(escaped > 0 && escaped < want.len(), "{escaped} rays escape");
            assert_eq!(g, GBuffer::from_samples(w, h, &want, 1.5), "{w}×{h}");
        }
    }

    /// Every plane's bits (so that −0 and +0, or two NaNs, count as different).
    fn plane_bits(g: &GBuffer) -> Vec<Vec<u32>> {
        let vec3 = |p: &[Vec3]| p.iter().flat_map(|v| v.to_array().map(f32::to_bits)).collect();
        let planes = [&g.normal, &g.position, &g.albedo, &g.emission];
        let mut bits: Vec<Vec<u32>> = planes.into_iter().map(|p| vec3(p)).collect();
        bits.push(g.object.clone());
        bits
    }

    /// A scene for the tile path's bit-for-bit test: the Cornell box (flattened small
    /// instances: walls, boxes, an emissive quad) with a glTF-style Pbr cube whose colour,
    /// metallic-roughness and normal maps are textures, two large spheres (entered through
    /// their own BLAS), one Pbr with the same maps, one emissive glossy, a quad light and
    /// a coloured environment.
    fn many_materials(w: u32, h: u32) -> (Arc<Assets>, SceneState) {
        use gridlight_actors::state::{Geometry, Light, Material, MaterialKind, Object};
        let (assets, mut state) = crate::render::testscenes::cornell_box(w, h);
        let mut assets = (*assets).clone();
        let texture = |seed: u32| {
            let texel = |i: u32, k: u32| {
                ((i.wrapping_mul(2654435761).wrapping_add(seed * 97 + k * 40503)) % 997) as f32
            };
            let texels = (0..64)
                .map(|i| Vec3::new(texel(i, 1), texel(i, 2), texel(i, 3)) / 997.0 * 0.9)
                .collect();
            Arc::new(crate::assets::Texture::linear(8, 8, texels))
        };
        assets.textures.insert("color.png".into(), texture(1));
        assets.data_textures.insert("mr.png".into(), texture(2));
        assets.data_textures.insert("normal.png".into(), texture(3));
        let mut pbr = Material::pbr("pbr", Vec3::new(0.9, 0.8, 0.7), 0.5, 0.4);
        pbr.base_color_texture = Some("color.png".into());
        pbr.metallic_roughness_texture = Some("mr.png".into());
        pbr.normal_texture = Some("normal.png".into());
        pbr.normal_scale = 0.8;
        let mut glow = crate::render::testscenes::material(
            "glow",
            MaterialKind::Glossy,
            Vec3::new(0.2, 0.5, 0.3),
            0.3,
        );
        glow.emission = Vec3::new(1.0, 2.0, 0.5);
        let place = |name: &str, geometry, translation: Vec3, scale: f32| {
            let mut o = Object::new(name, geometry);
            o.transform.translation = translation;
            o.transform.rotation = glam::Quat::from_euler(glam::EulerRot::XYZ, 0.3, 0.7, 0.1);
            o.transform.scale = Vec3::splat(scale);
            o
        };
        let sphere = Geometry::Sphere { subdivisions: 3 };
        state = state
            .with_object(
                place("pbr-cube", Geometry::Cube, Vec3::new(0.5, 0.3, 0.2), 0.4),
                pbr.clone(),
            )
            .with_object(place("pbr-ball", sphere.clone(), Vec3::new(-0.5, 0.4, 0.3), 0.3), pbr)
            .with_object(place("glow-ball", sphere, Vec3::new(0.1, -0.5, 0.6), 0.25), glow);
        state.lights.push(Light::Quad {
            corner: Vec3::new(-0.9, -0.9, -0.5),
            edge_u: Vec3::new(0.5, 0.0, 0.0),
            edge_v: Vec3::new(0.0, 0.6, 0.1),
            radiance: Vec3::new(3.0, 2.0, 1.0),
        });
        state.environment = Some(gridlight_actors::state::Environment {
            map: None,
            color: Vec3::new(0.2, 0.3, 0.4),
            intensity: 1.0,
            rotation_deg: 0.0,
        });
        (Arc::new(assets), state)
    }

    #[test]
    fn the_tile_path_is_every_pixels_one_ray_hit_bit_for_bit() {
        // Sizes whose tiles and bands end mid-tile; views from inside and outside the box
        // (rays escaping past the walls), a thin lens, and a view whose tiles straddle
        // the axes where direction components change sign.
        let views = [
            (37, 23, Vec3::new(0.0, 0.0, 3.9), 0.0),
            (64, 48, Vec3::new(0.4, 0.2, 0.9), 0.03),
            (30, 41, Vec3::new(-2.5, 1.5, 4.0), 0.0),
        ];
        let (mut seen, mut lit) = (std::collections::HashSet::new(), false);
        for (w, h, eye, aperture) in views {
            let (assets, mut state) = many_materials(w, h);
            state.camera.position = eye;
            state.camera.aperture = aperture;
            state.camera.focus_distance = 3.0;
            let scene = RenderScene::new(assets, &state).unwrap();
            let g = GBuffer::from_scene(&scene, 1.5);
            let want: Vec<PixelSample> =
                (0..w * h).map(|p| crate::render::primary_hit(&scene, p)).collect();
            let want = GBuffer::from_samples(w, h, &want, 1.5);
            seen.extend(want.object.iter().copied());
            lit |= want.emission.iter().any(|e| *e == Vec3::new(3.0, 2.0, 1.0));
            for (i, (got, want)) in plane_bits(&g).iter().zip(plane_bits(&want)).enumerate() {
                let differ = got.iter().zip(&want).filter(|(a, b)| a != b).count();
                assert_eq!(differ, 0, "{w}×{h} from {eye}: plane {i}, {differ} values differ");
            }
        }
        // Every object (8 of the box, 3 added) and the quad light were seen, and rays
        // escaped.
        assert_eq!(seen.len(), 12, "objects seen: {seen:?}");
        assert!(lit, "the quad light was not seen");
    }

    #[test]
    fn a_retraced_gbuffer_is_the_new_states_whatever_it_held() {
        let (assets, mut state) = crate::render::testscenes::cornell_box(29, 17);
        let scene = RenderScene::new(Arc::clone(&assets), &state).unwrap();
        let first = GBuffer::from_scene(&scene, 1.0);
        state.camera.position.x += 0.3;
        state.version += 1;
        let scene = RenderScene::new(assets, &state).unwrap();
        let want = GBuffer::from_scene(&scene, 2.0);
        assert_ne!(first, want, "the camera moved");
        assert_eq!(first.clone().retrace(&scene, 2.0), want, "planes of the right size");
        assert_eq!(GBuffer::empty(3, 2, 1.0).retrace(&scene, 2.0), want, "planes resized");
    }

    #[test]
    fn the_scene_scale_is_kept_while_only_the_camera_moves() {
        let (assets, mut state) = crate::render::testscenes::cornell_box(8, 6);
        let mut scale = SceneScale::default();
        let first = scale.get(&state, &assets);
        assert_eq!(first, scene_scale(&state, &assets));
        state.camera.position.x += 1.0;
        assert_eq!(scale.get(&state, &assets), first);
        // Scaling every object doubles the scene's extent.
        for object in &mut state.objects {
            object.transform.scale *= 2.0;
            object.transform.translation *= 2.0;
        }
        let doubled = scale.get(&state, &assets);
        assert!((doubled - 2.0 * first).abs() < 1e-4 * first, "{doubled} against {first}");
    }
}
