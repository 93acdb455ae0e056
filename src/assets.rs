//! Loaded asset data: triangle meshes, textures and environment maps.
//!
//! Scene states name assets by path (see `gridlight_actors::state`); the scene loader
//! turns those names into the values here, once per process, and the renderer, the
//! G-buffer and the worker share them read-only behind `Arc`s.

use std::collections::HashMap;
use std::sync::{Arc, OnceLock};

use glam::{Affine2, Mat2, Vec2, Vec3};
use gridlight_actors::state::{Geometry, MapLookup, TextureUse, Wrap};

/// Triangles of one [`Geometry`], in object space.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    pub positions: Vec<Vec3>,
    /// Per-vertex shading normals; empty means "use the geometric normal".
    pub normals: Vec<Vec3>,
    /// Per-vertex texture coordinates; empty means none.
    pub uvs: Vec<Vec2>,
    /// Vertex indices of each triangle.
    pub indices: Vec<[u32; 3]>,
    /// Material slot of each triangle (see `Object::materials`).
    pub slots: Vec<u32>,
    /// Number of material slots; every entry of `slots` is below it.
    pub slot_count: u32,
}

impl Mesh {
    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.indices.len()
    }

    /// Material slot of `triangle` (slot 0 when the mesh lists none).
    #[inline]
    pub fn slot(&self, triangle: usize) -> u32 {
        self.slots.get(triangle).copied().unwrap_or(0)
    }
}

/// A 2-D image of linear RGB values: an albedo map, or an environment map's radiance.
#[derive(Clone, Debug, PartialEq)]
pub struct Texture {
    pub width: u32,
    pub height: u32,
    /// Row-major, top row first.
    pub texels: Texels,
    /// Coverage codes (alpha × 255, linear) in texel order, kept only for a base colour
    /// map some of whose texels are not opaque: one byte a texel where it matters, none
    /// for the opaque maps that are most of a scene's.
    pub alpha: Option<Vec<u8>>,
}

/// How a texture's texels are stored.
///
/// An 8-bit sRGB albedo map keeps its codes (three bytes a texel) and linearises them
/// through a 256-entry table at lookup: the same values, bit for bit, as decoding the
/// whole image to floats on load, in a quarter of the memory. The smaller image is what
/// matters: a bounce ray's texture lookup lands anywhere in the map and its first texel
/// load was a cache miss costing 11 % of a Sponza frame with twelve bytes a texel.
#[derive(Clone, Debug, PartialEq)]
pub enum Texels {
    /// Linear RGB floats (environment maps, computed textures).
    Linear(Vec<Vec3>),
    /// 8-bit sRGB codes, decoded by [`srgb_to_linear`].
    Srgb8(Vec<[u8; 3]>),
    /// 8-bit linear codes, read as code / 255 (data such as glTF's metallic-roughness).
    Unorm8(Vec<[u8; 3]>),
}

impl Texels {
    pub fn len(&self) -> usize {
        match self {
            Self::Linear(t) => t.len(),
            Self::Srgb8(t) | Self::Unorm8(t) => t.len(),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Texel `i` in linear RGB.
    #[inline(always)]
    pub fn get(&self, i: usize) -> Vec3 {
        match self {
            Self::Linear(t) => t[i],
            Self::Srgb8(t) => srgb8_to_linear(t[i], srgb_table()),
            Self::Unorm8(t) => unorm8(t[i]),
        }
    }

    /// Every texel in linear RGB, in order.
    pub fn iter(&self) -> impl Iterator<Item = Vec3> + '_ {
        (0..self.len()).map(|i| self.get(i))
    }
}

impl Texture {
    /// A texture of linear RGB texels.
    pub fn linear(width: u32, height: u32, texels: Vec<Vec3>) -> Self {
        Self { width, height, texels: Texels::Linear(texels), alpha: None }
    }

    /// A texture of 8-bit sRGB texels.
    pub fn srgb8(width: u32, height: u32, codes: Vec<[u8; 3]>) -> Self {
        Self { width, height, texels: Texels::Srgb8(codes), alpha: None }
    }

    /// A texture of 8-bit linear texels (code / 255).
    pub fn unorm8(width: u32, height: u32, codes: Vec<[u8; 3]>) -> Self {
        Self { width, height, texels: Texels::Unorm8(codes), alpha: None }
    }

    /// This texture with coverage codes (one per texel, code / 255), dropped when all are
    /// 255: an opaque map costs nothing more than one without alpha.
    pub fn with_alpha(mut self, codes: Vec<u8>) -> Self {
        debug_assert_eq!(codes.len(), self.texels.len());
        self.alpha = codes.iter().any(|&c| c < 255).then_some(codes);
        self
    }

    /// Bilinear coverage at `uv` looked up as [`Texture::sample_with`]; 1 without alpha
    /// codes.
    #[inline(always)]
    pub fn sample_alpha(&self, uv: Vec2, lookup: Option<&Lookup>) -> f32 {
        let Some(a) = &self.alpha else { return 1.0 };
        let (uv, wrap) = Lookup::apply(lookup, uv);
        self.bilinear(uv, wrap, |i| a[i] as f32 * (1.0 / 255.0))
    }

    /// Bilinear lookup with wrap-around; `uv` (0,0) is the bottom-left corner as in OBJ.
    #[inline(always)]
    pub fn sample(&self, uv: Vec2) -> Vec3 {
        self.sample_with(uv, None)
    }

    /// Bilinear lookup as `lookup` says (wrap modes, texture transform); `None` is
    /// [`Texture::sample`]'s repeat, untransformed.
    #[inline(always)]
    pub fn sample_with(&self, uv: Vec2, lookup: Option<&Lookup>) -> Vec3 {
        let (uv, wrap) = Lookup::apply(lookup, uv);
        match &self.texels {
            Texels::Linear(t) => self.bilinear(uv, wrap, |i| t[i]),
            Texels::Srgb8(t) => {
                let table = srgb_table();
                self.bilinear(uv, wrap, |i| srgb8_to_linear(t[i], table))
            }
            Texels::Unorm8(t) => self.bilinear(uv, wrap, |i| unorm8(t[i])),
        }
    }

    /// The wrap costs two float remainders and four texel-index wraps per lookup; done
    /// with `rem_euclid` they were 16 % of a Sponza frame (a libm `fmodf` call each and
    /// 64-bit divisions), so both are done here without division, with the same results.
    /// Inlined into each dispatched build of the kernel (floor is an instruction on
    /// x86-64-v3).
    /// Clamped and mirrored axes read the edge texel where a repeated one reads the
    /// opposite edge's.
    #[inline(always)]
    fn bilinear<T: Lerp>(&self, uv: Vec2, [ws, wt]: [Wrap; 2], texel: impl Fn(usize) -> T) -> T {
        let (w, h) = (self.width as f32, self.height as f32);
        let x = unit_coordinate(uv.x, ws) * w - 0.5;
        let y = (1.0 - unit_coordinate(uv.y, wt)) * h - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        // x, y lie in [-0.5, size - 0.5], so the texel indices lie in [-1, size].
        let (xs, ys) = (self.width as i64, self.height as i64);
        let (cx0, cy0) = (x0 as i64, y0 as i64);
        let (cx0, cx1) = (texel_index(cx0, xs, ws), texel_index(cx0 + 1, xs, ws));
        let (cy0, cy1) = (texel_index(cy0, ys, wt), texel_index(cy0 + 1, ys, wt));
        let row = self.width as usize;
        let at = |xi: usize, yi: usize| texel(yi * row + xi);
        let top = at(cx0, cy0).lerp(at(cx1, cy0), fx);
        let bottom = at(cx0, cy1).lerp(at(cx1, cy1), fx);
        top.lerp(bottom, fy)
    }
}

/// A map's lookup as the kernel does it where it is not the default (repeat,
/// untransformed): the wrap per axis and the texture transform as an affine map of
/// gridlight's texture coordinates (v up).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lookup {
    pub wrap: [Wrap; 2],
    pub transform: Affine2,
}

impl Lookup {
    /// The kernel's form of `l`; `None` for the default lookup, so that untransformed
    /// repeating maps are looked up exactly as before.
    pub fn new(l: &MapLookup) -> Option<Self> {
        if l.is_plain() {
            return None;
        }
        // glTF's transform acts on v-down coordinates: flip v, transform, flip back.
        let flip =
            Affine2::from_mat2_translation(Mat2::from_diagonal(Vec2::new(1.0, -1.0)), Vec2::Y);
        let (sin, cos) = l.rotation.sin_cos();
        let turn =
            Mat2::from_cols(Vec2::new(cos, -sin) * l.scale.x, Vec2::new(sin, cos) * l.scale.y);
        let gltf = Affine2::from_mat2_translation(turn, l.offset);
        Some(Self { wrap: l.wrap, transform: flip * gltf * flip })
    }

    /// The coordinates to look up at and the wrap to look up with.
    #[inline(always)]
    fn apply(lookup: Option<&Self>, uv: Vec2) -> (Vec2, [Wrap; 2]) {
        match lookup {
            None => (uv, [Wrap::Repeat; 2]),
            Some(l) => (l.transform.transform_point2(uv), l.wrap),
        }
    }

    /// `uv` transformed (for tangent frames of transformed normal maps).
    #[inline(always)]
    pub fn transform(lookup: Option<&Self>, uv: Vec2) -> Vec2 {
        Self::apply(lookup, uv).0
    }
}

/// A texture coordinate brought into [0, 1] as `wrap` says.
#[inline(always)]
fn unit_coordinate(x: f32, wrap: Wrap) -> f32 {
    match wrap {
        Wrap::Repeat => unit_wrap(x),
        Wrap::ClampToEdge => x.clamp(0.0, 1.0),
        Wrap::MirroredRepeat => {
            let m = unit_wrap(x * 0.5) * 2.0;
            if m > 1.0 {
                2.0 - m
            } else {
                m
            }
        }
    }
}

/// A texel index in [-1, n] brought into [0, n) as `wrap` says.
#[inline(always)]
fn texel_index(i: i64, n: i64, wrap: Wrap) -> usize {
    match wrap {
        Wrap::Repeat => index_wrap(i, n),
        Wrap::ClampToEdge | Wrap::MirroredRepeat => i.clamp(0, n - 1) as usize,
    }
}

/// Linear interpolation of texel values (colours, coverage).
trait Lerp: Copy {
    fn lerp(self, to: Self, t: f32) -> Self;
}

impl Lerp for Vec3 {
    #[inline(always)]
    fn lerp(self, to: Self, t: f32) -> Self {
        Vec3::lerp(self, to, t)
    }
}

impl Lerp for f32 {
    #[inline(always)]
    fn lerp(self, to: Self, t: f32) -> Self {
        self + (to - self) * t
    }
}

/// The sRGB electro-optical transfer function for one 8-bit code.
pub fn srgb_to_linear(code: u8) -> f32 {
    let c = code as f32 / 255.0;
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// [`srgb_to_linear`] of every code.
#[inline]
pub fn srgb_table() -> &'static [f32; 256] {
    static TABLE: OnceLock<[f32; 256]> = OnceLock::new();
    TABLE.get_or_init(|| std::array::from_fn(|i| srgb_to_linear(i as u8)))
}

#[inline(always)]
fn srgb8_to_linear(c: [u8; 3], table: &[f32; 256]) -> Vec3 {
    Vec3::new(table[c[0] as usize], table[c[1] as usize], table[c[2] as usize])
}

#[inline(always)]
fn unorm8(c: [u8; 3]) -> Vec3 {
    Vec3::new(c[0] as f32, c[1] as f32, c[2] as f32) * (1.0 / 255.0)
}

/// `x.rem_euclid(1.0)` bit for bit up to the sign of a zero result (which the lookup
/// cannot see): `x - x.trunc()` is exact (Sterbenz), as `x % 1.0` is, and both round
/// the negative case's `+ 1.0` once.
#[inline]
fn unit_wrap(x: f32) -> f32 {
    let r = x - x.trunc();
    if r < 0.0 {
        r + 1.0
    } else {
        r
    }
}

/// `i.rem_euclid(n)` for `i` in [-n, 2n), which is every index [`Texture::sample`] forms
/// (a NaN coordinate casts to 0), without a 64-bit division.
#[inline]
fn index_wrap(i: i64, n: i64) -> usize {
    debug_assert!((-n..2 * n).contains(&i), "texel index {i} outside [-{n}, {})", 2 * n);
    (if i < 0 {
        i + n
    } else if i >= n {
        i - n
    } else {
        i
    }) as usize
}

/// All asset data a set of scene states refers to.
#[derive(Clone, Debug, Default)]
pub struct Assets {
    /// Geometry of every object, keyed by what the state names.
    pub meshes: HashMap<Geometry, Arc<Mesh>>,
    /// Colour textures (albedo, emission) by asset path (sRGB codes, read as linear RGB).
    pub textures: HashMap<String, Arc<Texture>>,
    /// Data textures (glTF's metallic-roughness and normal maps) by asset path (linear
    /// codes).
    pub data_textures: HashMap<String, Arc<Texture>>,
    /// Equirectangular environment maps by asset path (linear RGB radiance).
    pub environments: HashMap<String, Arc<Texture>>,
    /// The files each mesh file named (an OBJ's MTL libraries, a glTF's external buffers
    /// and images), by the mesh's asset path: what the manifest lists after it, known from
    /// loading so that the master need not parse the mesh file again.
    pub mesh_companions: HashMap<String, Vec<String>>,
}

impl Assets {
    /// The texture a material reads from asset path `path` as `usage`.
    pub fn texture(&self, path: &str, usage: TextureUse) -> Option<&Arc<Texture>> {
        self.texture_map(usage).get(path)
    }

    /// Stores the texture a material reads from asset path `path` as `usage`.
    pub fn insert_texture(&mut self, path: String, usage: TextureUse, texture: Arc<Texture>) {
        let map = match usage {
            TextureUse::Color | TextureUse::Emission => &mut self.textures,
            TextureUse::Data | TextureUse::Normal => &mut self.data_textures,
        };
        map.insert(path, texture);
    }

    fn texture_map(&self, usage: TextureUse) -> &HashMap<String, Arc<Texture>> {
        match usage {
            TextureUse::Color | TextureUse::Emission => &self.textures,
            TextureUse::Data | TextureUse::Normal => &self.data_textures,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Texel (x, y) of a `w`×`h` texture whose colour names its column and row.
    fn grid(w: u32, h: u32) -> Texture {
        let texels = (0..w * h).map(|i| Vec3::new((i % w) as f32, (i / w) as f32, 1.0));
        Texture::linear(w, h, texels.collect())
    }

    /// `None` for repeat on both axes: the default lookup.
    fn lookup(wrap: [Wrap; 2]) -> Option<Lookup> {
        Lookup::new(&MapLookup { wrap, ..MapLookup::default() })
    }

    #[test]
    fn wrap_modes_repeat_clamp_and_mirror_each_axis_on_its_own() {
        let t = grid(2, 2);
        // Texel centres: u 0.25 → column 0, 0.75 → column 1; v 0.75 → row 0 (v is up).
        let at = |u: f32, v: f32, wrap| t.sample_with(Vec2::new(u, v), lookup(wrap).as_ref());
        let (r, c, m) = (Wrap::Repeat, Wrap::ClampToEdge, Wrap::MirroredRepeat);
        assert_eq!(at(1.25, 0.75, [r, r]), Vec3::new(0.0, 0.0, 1.0));
        assert_eq!(at(1.25, 0.75, [c, r]), Vec3::new(1.0, 0.0, 1.0));
        assert_eq!(at(-0.3, 0.75, [c, r]), Vec3::new(0.0, 0.0, 1.0));
        assert_eq!(at(1.25, 0.75, [m, r]), Vec3::new(1.0, 0.0, 1.0));
        assert_eq!(at(-0.25, 0.75, [m, r]), Vec3::new(0.0, 0.0, 1.0));
        assert_eq!(at(2.25, 0.75, [m, r]), Vec3::new(0.0, 0.0, 1.0));
        // The second axis follows its own mode: v −0.25 repeats to 0.75 (row 0), clamps to
        // 0 and mirrors to 0.25 (row 1); v 1.25 repeats to 0.25 (row 1) and clamps to 1.
        assert_eq!(at(0.25, -0.25, [r, r]).y, 0.0);
        assert_eq!(at(0.25, -0.25, [r, c]).y, 1.0);
        assert_eq!(at(0.25, -0.25, [r, m]).y, 1.0);
        assert_eq!(at(0.25, 1.25, [c, r]).y, 1.0);
        assert_eq!(at(0.25, 1.25, [r, c]).y, 0.0);
        // Clamped edges blend with themselves, not with the opposite edge.
        assert_eq!(at(0.0, 0.75, [c, r]), Vec3::new(0.0, 0.0, 1.0));
        assert_eq!(at(0.0, 0.75, [r, r]), Vec3::new(0.5, 0.0, 1.0));
        assert!(lookup([r, r]).is_none() && lookup([c, r]).is_some());
        assert_eq!(t.sample_alpha(Vec2::ZERO, lookup([c, m]).as_ref()), 1.0);
    }

    /// KHR_texture_transform's own example: offset (0, 1), rotation π/2, scale 0.5 use
    /// "only the lower left quadrant of the source image, rotated clockwise 90°": the
    /// quad's top edge runs up the quadrant's left column, its left edge along the
    /// quadrant's bottom row. Turned the other way it would read another quadrant.
    #[test]
    fn the_texture_transform_is_the_extensions_example() {
        let t = grid(4, 4);
        let example = MapLookup {
            offset: Vec2::new(0.0, 1.0),
            rotation: std::f32::consts::FRAC_PI_2,
            scale: Vec2::splat(0.5),
            ..MapLookup::default()
        };
        let l = Lookup::new(&example).expect("a transform");
        // gridlight's uv (v up) → the expected texel (column, row from the top).
        for (uv, texel) in
            [((0.25, 0.75), (0.0, 3.0)), ((0.75, 0.75), (0.0, 2.0)), ((0.25, 0.25), (1.0, 3.0))]
        {
            let got = t.sample_with(Vec2::new(uv.0, uv.1), Some(&l));
            let want = Vec3::new(texel.0, texel.1, 1.0);
            assert!((got - want).abs().max_element() < 1e-3, "{uv:?}: {got} for {want}");
        }
        assert!(Lookup::new(&MapLookup::default()).is_none(), "the default lookup is none");
    }

    /// The lookup as first written, with `rem_euclid` wraps: the reference the cheaper
    /// wraps must match bit for bit (CPU and GPU pictures depend on it).
    fn sample_by_rem_euclid(t: &Texture, uv: Vec2) -> Vec3 {
        let (w, h) = (t.width as f32, t.height as f32);
        let x = uv.x.rem_euclid(1.0) * w - 0.5;
        let y = (1.0 - uv.y.rem_euclid(1.0)) * h - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let texel = |xi: f32, yi: f32| {
            let xi = (xi as i64).rem_euclid(t.width as i64) as usize;
            let yi = (yi as i64).rem_euclid(t.height as i64) as usize;
            t.texels.get(yi * t.width as usize + xi)
        };
        let top = texel(x0, y0).lerp(texel(x0 + 1.0, y0), fx);
        let bottom = texel(x0, y0 + 1.0).lerp(texel(x0 + 1.0, y0 + 1.0), fx);
        top.lerp(bottom, fy)
    }

    #[test]
    fn wrapped_lookup_matches_rem_euclid_and_srgb_codes_match_floats_bit_for_bit() {
        let special = [
            0.0,
            -0.0,
            1.0,
            -1.0,
            2.0,
            -3.0,
            0.5,
            -0.5,
            1e-9,
            -1e-9,
            0.999_999_9,
            -0.999_999_9,
            1e7,
            -1e7,
            3e9,
            -3e9,
            f32::MAX,
            f32::MIN,
            f32::EPSILON,
            -f32::EPSILON,
        ];
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut coords: Vec<f32> = special.to_vec();
        coords.extend((0..2000).map(|_| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            ((state >> 40) as f32 / (1u64 << 24) as f32 - 0.5) * 40.0
        }));
        for (w, h) in [(1, 1), (2, 3), (7, 5), (64, 32)] {
            let texels =
                (0..w * h).map(|i| Vec3::new(i as f32, 1.0 / (1 + i) as f32, 0.5)).collect();
            let t = Texture::linear(w, h, texels);
            for (i, &u) in coords.iter().enumerate() {
                let v = coords[(i * 7 + 3) % coords.len()];
                let (a, b) = (t.sample(Vec2::new(u, v)), sample_by_rem_euclid(&t, Vec2::new(u, v)));
                assert_eq!(
                    a.to_array().map(f32::to_bits),
                    b.to_array().map(f32::to_bits),
                    "{w}x{h} at ({u}, {v})"
                );
            }
        }
        // An 8-bit sRGB texture gives what decoding it to floats gives, bit for bit.
        let (w, h) = (7u32, 5u32);
        let codes: Vec<[u8; 3]> =
            (0..w * h).map(|i| [i as u8 * 7, 255 - i as u8, (i * 37 % 256) as u8]).collect();
        let floats = codes.iter().map(|c| Vec3::from_array(c.map(srgb_to_linear))).collect();
        let (srgb, linear) = (Texture::srgb8(w, h, codes), Texture::linear(w, h, floats));
        for (i, &u) in coords.iter().enumerate() {
            let uv = Vec2::new(u, coords[(i * 5 + 1) % coords.len()]);
            let (a, b) = (srgb.sample(uv), linear.sample(uv));
            assert_eq!(a.to_array().map(f32::to_bits), b.to_array().map(f32::to_bits), "{uv}");
        }
        assert_eq!(
            srgb.texels.iter().collect::<Vec<_>>(),
            linear.texels.iter().collect::<Vec<_>>()
        );
        // Non-finite coordinates give the same NaNs.
        let t = Texture::linear(2, 2, vec![Vec3::ONE; 4]);
        for uv in [Vec2::new(f32::NAN, 0.3), Vec2::new(f32::INFINITY, 0.3)] {
            assert!(t.sample(uv).is_nan() && sample_by_rem_euclid(&t, uv).is_nan());
        }
    }
}
