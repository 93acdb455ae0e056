//! The image layout of the CPU passes: planes of f32 (structure of arrays) with a border.
//!
//! The filters read each pixel's neighbours at fixed offsets. Planar storage puts
//! [`WIDTH`] neighbouring pixels' values at consecutive addresses, one vector load, and a
//! border at least as wide as the widest filter radius (plus a tail for the last run of
//! lanes) spares every tap an edge case: what the border holds is chosen per plane so that
//! taps falling on it add exactly 0 (see [`GuidePlanes`]), and the innermost loops may skip
//! bounds checks that the layout makes unnecessary (see [`Layout::plane_len`]).
//!
//! Passes that compute one row of output planes at a time run through [`write_rows`].

use std::ops::Deref;
use std::sync::atomic::{AtomicUsize, Ordering};

use glam::Vec3;
use rayon::prelude::*;

use super::rows::{run_rows, store, RowKernel};
use crate::render::isa::Isa;
use crate::render::lanes::{F32s, Vec3s, WIDTH};

/// Three planes of one layout (x, y, z or r, g, b).
pub type Planes3 = [Plane; 3];

/// Entries of f32 in a 4 KiB page.
const PAGE: usize = 1024;

/// One plane of f32 that starts at its own offset within a 4 KiB page.
///
/// The filters read a dozen or more planes at the same index at once. Large allocations
/// all start at the same page offset, so without the stagger those reads would fall into
/// the same few L1 cache sets and evict each other (4 KiB aliasing).
#[derive(Debug)]
pub struct Plane {
    buf: Vec<f32>,
    start: usize,
    len: usize,
}

impl Plane {
    /// `len` zeros.
    pub fn zeroed(len: usize) -> Self {
        static NEXT: AtomicUsize = AtomicUsize::new(0);
        // Successive planes start 11 cache lines (of 16 entries) apart modulo a page, which
        // gives 64 planes 64 different lines.
        let line = NEXT.fetch_add(1, Ordering::Relaxed) * 11 % 64;
        let buf = vec![0.0; len + PAGE];
        let page_offset = buf.as_ptr() as usize / size_of::<f32>() % PAGE;
        Self { start: (line * 16 + PAGE - page_offset) % PAGE, buf, len }
    }

    pub fn as_mut_slice(&mut self) -> &mut [f32] {
        &mut self.buf[self.start..self.start + self.len]
    }
}

impl Deref for Plane {
    type Target = [f32];

    #[inline(always)]
    fn deref(&self) -> &[f32] {
        &self.buf[self.start..self.start + self.len]
    }
}

impl std::ops::DerefMut for Plane {
    #[inline(always)]
    fn deref_mut(&mut self) -> &mut [f32] {
        self.as_mut_slice()
    }
}

/// Where each pixel of a `width`×`height` image lives in a plane with a border.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Layout {
    pub width: usize,
    pub height: usize,
    /// Border width on every side.
    pub pad: usize,
    /// Distance between vertically adjacent pixels: width + 2·pad.
    pub stride: usize,
}

impl Layout {
    pub fn new(width: u32, height: u32, pad: usize) -> Self {
        let (width, height) = (width as usize, height as usize);
        Self { width, height, pad, stride: width + 2 * pad }
    }

    /// Entries of one plane: the padded rows, then a tail of [`WIDTH`] so that a run of
    /// lanes starting at most `pad` pixels right of and below any pixel stays inside.
    pub fn plane_len(&self) -> usize {
        self.stride * (self.height + 2 * self.pad) + WIDTH
    }

    /// Index of pixel (x, y) of the image.
    #[inline(always)]
    pub fn index(&self, x: usize, y: usize) -> usize {
        (y + self.pad) * self.stride + self.pad + x
    }

    /// Index difference of the pixel (dx, dy) away.
    pub fn offset(&self, dx: i32, dy: i32) -> isize {
        dy as isize * self.stride as isize + dx as isize
    }

    /// Three planes of zeros.
    pub fn zeroed3(&self) -> Planes3 {
        [(); 3].map(|_| Plane::zeroed(self.plane_len()))
    }
}

/// A G-buffer's normals and positions as planes. The border has no surface (normal 0) and
/// lies infinitely far away (position ∞), so D against it is exactly 0: the position
/// factor is max(0, 1 − ∞) = 0 and the orientation factor is finite.
#[derive(Debug)]
pub struct GuidePlanes {
    pub normal: Planes3,
    pub position: Planes3,
}

impl GuidePlanes {
    pub fn new(layout: &Layout) -> Self {
        Self { normal: layout.zeroed3(), position: layout.zeroed3() }
    }

    pub fn view(&self) -> GuideView<'_> {
        GuideView { normal: view(&self.normal), position: view(&self.position) }
    }

    /// Fills the planes from a G-buffer's normals and positions (one per pixel, row-major).
    pub fn split(&mut self, normal: &[Vec3], position: &[Vec3], layout: &Layout) {
        split(normal, layout, 0.0, &mut self.normal);
        split(position, layout, f32::INFINITY, &mut self.position);
    }
}

/// Three planes borrowed as slices: the inner loops read these, so that a plane's own
/// bounds are looked up once per pass rather than at every tap.
pub type View3<'a> = [&'a [f32]; 3];

pub fn view(planes: &Planes3) -> View3<'_> {
    planes.each_ref().map(|p| &**p)
}

/// A G-buffer's planes borrowed as slices.
#[derive(Clone, Copy)]
pub struct GuideView<'a> {
    pub normal: View3<'a>,
    pub position: View3<'a>,
}

/// The pixel at `i` of three planes.
#[inline(always)]
pub fn at<P: Deref<Target = [f32]>>(planes: &[P; 3], i: usize) -> Vec3 {
    Vec3::new(planes[0][i], planes[1][i], planes[2][i])
}

/// Writes the weighted means `sum / wsum` of a run of pixels starting at `x0` (those inside
/// the row), or `fallback` where the weights sum to 0.
#[inline(always)]
pub fn normalise<I: Isa>(
    sum: Vec3s<I>,
    wsum: F32s<I>,
    fallback: Vec3s<I>,
    x0: usize,
    out: &mut PlaneRow<'_>,
) {
    // Every lane is divided and the quotient dropped where wsum is 0.
    let mean = Vec3s::select(wsum.gt(F32s::splat(0.0)), sum.div_by(wsum), fallback);
    let n = WIDTH.min(out[0].len() - x0);
    for (o, m) in out.iter_mut().zip(mean.to_array()) {
        store(&mut o[x0..x0 + n], &m.0);
    }
}

/// Splits `src` (one vector per pixel, row-major) into the planes of `dst` and sets their
/// border (and tail) to `border`.
pub fn split(src: &[Vec3], layout: &Layout, border: f32, dst: &mut Planes3) {
    let (w, pad) = (layout.width, layout.pad);
    padded_rows(dst.each_mut().map(Plane::as_mut_slice), layout)
        .into_par_iter()
        .enumerate()
        .for_each(|(py, rows)| {
            let y = py.checked_sub(pad).filter(|&y| y < layout.height);
            for (k, row) in rows.into_iter().enumerate() {
                let Some(y) = y else {
                    row.fill(border);
                    continue;
                };
                let (left, rest) = row.split_at_mut(pad);
                let (image, right) = rest.split_at_mut(w);
                left.fill(border);
                right.fill(border);
                for (o, v) in image.iter_mut().zip(&src[y * w..(y + 1) * w]) {
                    *o = v[k];
                }
            }
        });
}

/// The rows of the image in `planes` (border excluded), each with its y, for parallel
/// writing.
pub fn image_rows<'a, const N: usize>(
    planes: [&'a mut [f32]; N],
    layout: &Layout,
) -> Vec<(usize, [&'a mut [f32]; N])> {
    let (pad, w) = (layout.pad, layout.width);
    padded_rows(planes, layout)
        .into_iter()
        .skip(pad)
        .take(layout.height)
        .enumerate()
        .map(|(y, rows)| (y, rows.map(|r| &mut r[pad..pad + w])))
        .collect()
}

/// Every padded row of `planes` (the tail last, as a short row).
fn padded_rows<'a, const N: usize>(
    planes: [&'a mut [f32]; N],
    layout: &Layout,
) -> Vec<[&'a mut [f32]; N]> {
    let count = layout.plane_len().div_ceil(layout.stride);
    let mut chunks = planes.map(|p| {
        assert_eq!(p.len(), layout.plane_len(), "plane of another layout");
        p.chunks_mut(layout.stride)
    });
    (0..count).map(|_| chunks.each_mut().map(|c| c.next().expect("equal planes"))).collect()
}

/// One image row of three output planes.
pub type PlaneRow<'a> = [&'a mut [f32]; 3];

/// Runs `kernel` on every image row of `out`, in parallel.
pub fn write_rows<K>(kernel: &K, layout: &Layout, out: &mut Planes3)
where
    K: for<'a> RowKernel<PlaneRow<'a>>,
{
    run_rows(kernel, image_rows(out.each_mut().map(Plane::as_mut_slice), layout));
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn split_places_pixels_and_sets_the_border() {
        let layout = Layout::new(3, 2, 2);
        let src: Vec<Vec3> = (0..6).map(|i| Vec3::new(i as f32, 10.0 + i as f32, 0.5)).collect();
        let mut planes = layout.zeroed3();
        split(&src, &layout, -1.0, &mut planes);
        for (i, v) in src.iter().enumerate() {
            assert_eq!(at(&planes, layout.index(i % 3, i / 3)), *v);
        }
        let inside = layout.width * layout.height;
        for p in &planes {
            assert_eq!(p.iter().filter(|&&x| x == -1.0).count(), layout.plane_len() - inside);
        }
        assert_eq!(
            layout.index(1, 1) as isize + layout.offset(-1, -1),
            layout.index(0, 0) as isize
        );
    }

    #[test]
    fn image_rows_are_the_rows_without_border() {
        let layout = Layout::new(4, 3, 1);
        let mut planes = layout.zeroed3();
        for (y, [a, b, c]) in image_rows(planes.each_mut().map(Plane::as_mut_slice), &layout) {
            assert_eq!(a.len(), 4);
            a.fill(y as f32 + 1.0);
            b.fill(1.0);
            c.fill(1.0);
        }
        assert_eq!(planes[0][layout.index(3, 2)], 3.0);
        assert_eq!(planes[0].iter().sum::<f32>(), 4.0 * (1.0 + 2.0 + 3.0));
    }
}
