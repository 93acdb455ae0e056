//! The CPU reference of each reconstruction step, one function per GPU pass.
//!
//! Every function does exactly what its WGSL twin in `shaders/` does, in the same order of
//! operations, so that the parity test can hold the two to a tight tolerance. Rows are
//! processed in parallel with rayon.

use glam::{Vec3, Vec4};
use rayon::prelude::*;

use super::discontinuity::{is_surface, Thresholds};
use super::params::{ReconstructParams, MAX_GAUSS_WIDTH, MAX_HISTORY};
#[cfg(test)]
use super::tonemap::to_rgba8;
use super::tonemap::{exposure_scale, to_rgba8_fast};

/// Entries of the 1-D Gaussian table (radius 0..=MAX_GAUSS_WIDTH/2).
pub const GAUSS_TABLE: usize = (MAX_GAUSS_WIDTH as usize / 2) + 1;

/// The numbers every pass needs, derived once per frame from the parameters and the scene
/// scale (the GPU uniform is built from this very value).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PassConsts {
    pub width: u32,
    pub height: u32,
    /// α and β (β in scene units) of the discontinuity function.
    pub d: Thresholds,
    pub radius: i32,
    pub gauss_radius: i32,
    /// Exposure in stops.
    pub exposure: f32,
    /// exp(−d²/2σ²) for d = 0, 1, …; the 2-D weight is the product of two entries.
    pub gauss: [f32; GAUSS_TABLE],
}

impl PassConsts {
    pub fn new(width: u32, height: u32, params: &ReconstructParams, scene_scale: f32) -> Self {
        let mut gauss = [0.0; GAUSS_TABLE];
        for (d, g) in gauss.iter_mut().enumerate() {
            let d = d as f32;
            *g = (-(d * d) / (2.0 * params.sigma * params.sigma)).exp();
        }
        Self {
            width,
            height,
            d: Thresholds::new(params.alpha, params.beta * scene_scale),
            radius: params.radius as i32,
            gauss_radius: params.gauss_radius(),
            exposure: params.exposure,
            gauss,
        }
    }
}

/// The G-buffer planes the filters read.
#[derive(Clone, Copy)]
pub struct Guide<'a> {
    pub normal: &'a [Vec3],
    pub position: &'a [Vec3],
}

/// One previous frame as the temporal filter sees it.
#[derive(Clone, Copy)]
pub struct PastFrame<'a> {
    /// Weight w = 1/(F_i − F_j); 0 disables the slot.
    pub weight: f32,
    pub radiance: &'a [Vec3],
    pub guide: Guide<'a>,
}

fn rows<T: Send>(
    out: &mut [T],
    width: u32,
) -> impl IndexedParallelIterator<Item = (usize, &mut [T])> {
    out.par_chunks_mut(width as usize).enumerate()
}

/// Step 4 (and the start of every frame): accumulates this frame's results. `reset` starts
/// a new average (the scene state changed); rgb is the sum, w the number of samples.
pub fn accumulate(reset: bool, radiance: &[Vec3], mask: &[bool], accum: &mut [Vec4], width: u32) {
    rows(accum, width).for_each(|(y, row)| {
        let base = y * width as usize;
        for (x, a) in row.iter_mut().enumerate() {
            let i = base + x;
            let prev = if reset { Vec4::ZERO } else { *a };
            *a = if mask[i] { prev + radiance[i].extend(1.0) } else { prev };
        }
    });
}

/// Step 1: fills pixels without samples from calculated neighbours within the radius,
/// weighted by D (k = 1). Where every neighbour has D = 0 the plain mean of the calculated
/// surface neighbours is used; where there are none the value is 0 (a hole stays black).
/// Pixels that hit no surface have radiance 0 by convention.
pub fn fill(accum: &[Vec4], guide: Guide, c: &PassConsts, out: &mut [Vec3]) {
    let (w, h) = (c.width as i32, c.height as i32);
    let n = accum.len();
    // Planar copies: each pixel's mean (the same division the GPU does per tap; 0 where
    // nothing was calculated), whether it was calculated and whether it is a surface.
    // Taps then need no branches: an uncalculated neighbour adds exactly 0 to each sum.
    let mut mean = [vec![0.0f32; n], vec![0.0f32; n], vec![0.0f32; n]];
    let mut calc = vec![0.0f32; n];
    let mut surf_calc = vec![0.0f32; n];
    for (i, a) in accum.iter().enumerate() {
        if a.w > 0.0 {
            let m = a.truncate() / a.w;
            (mean[0][i], mean[1][i], mean[2][i]) = (m.x, m.y, m.z);
            calc[i] = 1.0;
            surf_calc[i] = if is_surface(guide.normal[i]) { 1.0 } else { 0.0 };
        }
    }
    let planes = Planes::new(&[], guide);
    let r = c.radius;
    // Half-width of the disc on each row offset.
    let half: Vec<i32> = (-r..=r)
        .map(|dy| (0..=r).take_while(|dx| dx * dx + dy * dy <= r * r).count() as i32 - 1)
        .collect();
    rows(out, c.width).for_each(|(y, row)| {
        let y = y as i32;
        for (x, o) in row.iter_mut().enumerate() {
            let x = x as i32;
            let i = (y * w + x) as usize;
            if calc[i] > 0.0 {
                *o = Vec3::new(mean[0][i], mean[1][i], mean[2][i]);
                continue;
            }
            let (n_i, z_i) = (guide.normal[i], guide.position[i]);
            if !is_surface(n_i) {
                *o = Vec3::ZERO;
                continue;
            }
            let (mut a0, mut a1, mut a2, mut wsum) = (0.0f32, 0.0f32, 0.0f32, 0.0f32);
            let (mut p0, mut p1, mut p2, mut plain_n) = (0.0f32, 0.0f32, 0.0f32, 0.0f32);
            for dy in -r..=r {
                let yy = y + dy;
                if yy < 0 || yy >= h {
                    continue;
                }
                let hw = half[(dy + r) as usize];
                let (x0, x1) = ((x - hw).max(0), (x + hw).min(w - 1));
                let base = (yy * w) as usize;
                for j in base + x0 as usize..=base + x1 as usize {
                    let dot =
                        n_i.x * planes.n[0][j] + n_i.y * planes.n[1][j] + n_i.z * planes.n[2][j];
                    let (e0, e1, e2) =
                        (z_i.x - planes.z[0][j], z_i.y - planes.z[1][j], z_i.z - planes.z[2][j]);
                    let d =
                        c.d.orientation(dot) * c.d.position(e0 * e0 + e1 * e1 + e2 * e2) * calc[j];
                    let (l0, l1, l2) = (mean[0][j], mean[1][j], mean[2][j]);
                    a0 += l0 * d;
                    a1 += l1 * d;
                    a2 += l2 * d;
                    wsum += d;
                    let s = surf_calc[j];
                    p0 += l0 * s;
                    p1 += l1 * s;
                    p2 += l2 * s;
                    plain_n += s;
                }
            }
            *o = if wsum > 0.0 {
                Vec3::new(a0, a1, a2) / wsum
            } else if plain_n > 0.0 {
                Vec3::new(p0, p1, p2) / plain_n
            } else {
                Vec3::ZERO
            };
        }
    });
}

/// Step 2: blends each pixel with its values in previous frames, weighted by the temporal
/// D (same pixel, that frame's G-buffer) times w = 1/(F_i − F_j); the current frame has
/// w = 1.
pub fn temporal(
    current: &[Vec3],
    guide: Guide,
    past: &[PastFrame],
    c: &PassConsts,
    out: &mut [Vec3],
) {
    assert!(past.len() <= MAX_HISTORY as usize);
    rows(out, c.width).for_each(|(y, row)| {
        let base = y * c.width as usize;
        for (x, o) in row.iter_mut().enumerate() {
            let i = base + x;
            let (n_i, z_i) = (guide.normal[i], guide.position[i]);
            let d0 = c.d.d(n_i, n_i, z_i, z_i);
            let mut acc = current[i] * d0;
            let mut wsum = d0;
            for p in past.iter().filter(|p| p.weight > 0.0) {
                let dw = c.d.d(n_i, p.guide.normal[i], z_i, p.guide.position[i]) * p.weight;
                acc += p.radiance[i] * dw;
                wsum += dw;
            }
            *o = if wsum > 0.0 { acc / wsum } else { current[i] };
        }
    });
}

/// Step 3: the edge-aware Gaussian (width 2·gauss_radius + 1) weighted by D.
///
/// Evaluated tap by tap over whole rows on planar copies of the inputs so that the inner
/// loop vectorises (AVX2 where the CPU has it); every pixel still sums its taps in the
/// same (dy, dx) order as the WGSL pass.
pub fn gaussian(src: &[Vec3], guide: Guide, c: &PassConsts, out: &mut [Vec3]) {
    let planes = Planes::new(src, guide);
    let avx2 = avx2();
    rows(out, c.width).for_each(|(y, row)| {
        // SAFETY: `gaussian_row_avx2` is only called when the CPU supports AVX2.
        unsafe {
            if avx2 {
                gaussian_row_avx2(&planes, c, y, row)
            } else {
                gaussian_row(&planes, c, y, row)
            }
        }
    });
}

fn avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::is_x86_feature_detected!("avx2")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// Planar (structure-of-arrays) copies of the radiance and guide.
struct Planes {
    src: [Vec<f32>; 3],
    n: [Vec<f32>; 3],
    z: [Vec<f32>; 3],
}

impl Planes {
    /// Splits `src` (may be empty) and the guide into planes.
    fn new(src: &[Vec3], guide: Guide) -> Self {
        let split =
            |v: &[Vec3]| -> [Vec<f32>; 3] { [0, 1, 2].map(|k| v.iter().map(|p| p[k]).collect()) };
        Self { src: split(src), n: split(guide.normal), z: split(guide.position) }
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn gaussian_row_avx2(p: &Planes, c: &PassConsts, y: usize, out: &mut [Vec3]) {
    gaussian_row(p, c, y, out)
}

#[cfg(not(target_arch = "x86_64"))]
unsafe fn gaussian_row_avx2(p: &Planes, c: &PassConsts, y: usize, out: &mut [Vec3]) {
    gaussian_row(p, c, y, out)
}

#[inline(always)]
fn sl(v: &[f32], s: usize, n: usize) -> &[f32] {
    &v[s..s + n]
}

#[inline(always)]
fn gaussian_row(p: &Planes, c: &PassConsts, y: usize, out: &mut [Vec3]) {
    let (w, h) = (c.width as usize, c.height as i32);
    let r = c.gauss_radius;
    let mut acc = [vec![0.0f32; w], vec![0.0f32; w], vec![0.0f32; w]];
    let mut wsum = vec![0.0f32; w];
    let i0 = y * w;
    for dy in -r..=r {
        let yy = y as i32 + dy;
        if yy < 0 || yy >= h {
            continue;
        }
        let gy = c.gauss[dy.unsigned_abs() as usize];
        for dx in -r..=r {
            // Output pixels x whose tap x + dx lies inside the row.
            let x0 = (-dx).max(0) as usize;
            let x1 = (w as i32 - dx.max(0)) as usize;
            if x1 <= x0 {
                continue;
            }
            let g = gy * c.gauss[dx.unsigned_abs() as usize];
            let j0 = (yy as usize * w) as isize + x0 as isize + dx as isize;
            let (j0, n) = (j0 as usize, x1 - x0);
            tap(
                [sl(&p.n[0], i0 + x0, n), sl(&p.n[1], i0 + x0, n), sl(&p.n[2], i0 + x0, n)],
                [sl(&p.z[0], i0 + x0, n), sl(&p.z[1], i0 + x0, n), sl(&p.z[2], i0 + x0, n)],
                [sl(&p.n[0], j0, n), sl(&p.n[1], j0, n), sl(&p.n[2], j0, n)],
                [sl(&p.z[0], j0, n), sl(&p.z[1], j0, n), sl(&p.z[2], j0, n)],
                [sl(&p.src[0], j0, n), sl(&p.src[1], j0, n), sl(&p.src[2], j0, n)],
                &mut acc,
                &mut wsum,
                x0,
                g,
                &c.d,
            );
        }
    }
    for (x, o) in out.iter_mut().enumerate() {
        *o = if wsum[x] > 0.0 {
            Vec3::new(acc[0][x], acc[1][x], acc[2][x]) / wsum[x]
        } else {
            Vec3::new(p.src[0][i0 + x], p.src[1][i0 + x], p.src[2][i0 + x])
        };
    }
}

/// One tap (fixed offset) for a run of output pixels starting at `x0`.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn tap(
    ni: [&[f32]; 3],
    zi: [&[f32]; 3],
    nj: [&[f32]; 3],
    zj: [&[f32]; 3],
    sj: [&[f32]; 3],
    acc: &mut [Vec<f32>; 3],
    wsum: &mut [f32],
    x0: usize,
    g: f32,
    d: &Thresholds,
) {
    let n = ni[0].len();
    let [a0, a1, a2] = acc;
    let (a0, a1, a2, ws) =
        (&mut a0[x0..x0 + n], &mut a1[x0..x0 + n], &mut a2[x0..x0 + n], &mut wsum[x0..x0 + n]);
    for k in 0..n {
        let dot = ni[0][k] * nj[0][k] + ni[1][k] * nj[1][k] + ni[2][k] * nj[2][k];
        let (e0, e1, e2) = (zi[0][k] - zj[0][k], zi[1][k] - zj[1][k], zi[2][k] - zj[2][k]);
        let dist2 = e0 * e0 + e1 * e1 + e2 * e2;
        let wgt = g * (d.orientation(dot) * d.position(dist2));
        a0[k] += sj[0][k] * wgt;
        a1[k] += sj[1][k] * wgt;
        a2[k] += sj[2][k] * wgt;
        ws[k] += wgt;
    }
}

/// Step 5: remodulates the albedo, adds the directly seen emission (linear colour) and
/// tonemaps it for display (8-bit sRGB RGBA).
pub fn remodulate(
    radiance: &[Vec3],
    albedo: &[Vec3],
    emission: &[Vec3],
    c: &PassConsts,
    colour: &mut [Vec3],
    display: &mut [[u8; 4]],
) {
    colour
        .par_chunks_mut(c.width as usize)
        .zip(display.par_chunks_mut(c.width as usize))
        .enumerate()
        .for_each(|(y, (crow, drow))| {
            let base = y * c.width as usize;
            let scale = exposure_scale(c.exposure);
            for (x, (co, d)) in crow.iter_mut().zip(drow.iter_mut()).enumerate() {
                let i = base + x;
                *co = albedo[i] * radiance[i] + emission[i];
                *d = to_rgba8_fast(*co, scale);
            }
        });
}

#[cfg(test)]
mod tests {
    use super::*;

    fn consts(w: u32, h: u32) -> PassConsts {
        PassConsts::new(w, h, &ReconstructParams::default(), 1.0)
    }

    fn flat(n: usize) -> (Vec<Vec3>, Vec<Vec3>) {
        (vec![Vec3::Z; n], (0..n).map(|i| Vec3::new(i as f32 * 1e-3, 0.0, 0.0)).collect())
    }

    #[test]
    fn accumulate_averages_and_resets() {
        let mut acc = vec![Vec4::ZERO; 2];
        accumulate(true, &[Vec3::ONE, Vec3::ONE], &[true, false], &mut acc, 2);
        accumulate(false, &[Vec3::splat(3.0), Vec3::ONE], &[true, true], &mut acc, 2);
        assert_eq!(acc, vec![Vec4::new(4.0, 4.0, 4.0, 2.0), Vec4::new(1.0, 1.0, 1.0, 1.0)]);
        accumulate(true, &[Vec3::ONE, Vec3::ONE], &[false, false], &mut acc, 2);
        assert_eq!(acc, vec![Vec4::ZERO; 2]);
    }

    #[test]
    fn fill_reproduces_a_constant_and_keeps_calculated_pixels() {
        let (w, h) = (16, 12);
        let n = (w * h) as usize;
        let (normal, position) = flat(n);
        let accum: Vec<Vec4> = (0..n)
            .map(|i| if i % 3 == 0 { Vec4::ZERO } else { Vec4::new(0.5, 0.25, 1.0, 1.0) })
            .collect();
        let mut out = vec![Vec3::ZERO; n];
        fill(&accum, Guide { normal: &normal, position: &position }, &consts(w, h), &mut out);
        for v in out {
            assert!((v - Vec3::new(0.5, 0.25, 1.0)).abs().max_element() < 1e-6, "{v}");
        }
    }

    #[test]
    fn fill_does_not_cross_a_depth_edge() {
        // Left half at z = 0 with radiance 1, right half at z = 5 with radiance 0; the
        // missing pixel on the left must take only left values.
        let (w, h) = (12, 4);
        let n = (w * h) as usize;
        let normal = vec![Vec3::Z; n];
        let position: Vec<Vec3> =
            (0..n).map(|i| Vec3::new(0.0, 0.0, if i % 12 < 6 { 0.0 } else { 5.0 })).collect();
        let mut accum: Vec<Vec4> = (0..n)
            .map(|i| if i % 12 < 6 { Vec4::ONE } else { Vec4::new(0.0, 0.0, 0.0, 1.0) })
            .collect();
        accum[12 + 5] = Vec4::ZERO;
        let mut out = vec![Vec3::ZERO; n];
        fill(&accum, Guide { normal: &normal, position: &position }, &consts(w, h), &mut out);
        assert_eq!(out[12 + 5], Vec3::ONE);
    }

    #[test]
    fn temporal_weights_follow_frame_distance() {
        let n = 1;
        let (normal, position) = flat(n);
        let guide = Guide { normal: &normal, position: &position };
        let old = [Vec3::splat(4.0)];
        let past = [PastFrame { weight: 1.0 / 3.0, radiance: &old, guide }];
        let mut out = [Vec3::ZERO];
        temporal(&[Vec3::ZERO], guide, &past, &consts(1, 1), &mut out);
        // (0·1 + 4·1/3) / (1 + 1/3) = 1
        assert!((out[0] - Vec3::ONE).abs().max_element() < 1e-5, "{}", out[0]);
        let moved = [Vec3::new(0.0, 0.0, 9.0)];
        let past = [PastFrame {
            weight: 1.0,
            radiance: &old,
            guide: Guide { normal: &normal, position: &moved },
        }];
        temporal(&[Vec3::ZERO], guide, &past, &consts(1, 1), &mut out);
        assert_eq!(out[0], Vec3::ZERO, "a different surface in the past frame is ignored");
    }

    #[test]
    fn gaussian_smooths_noise_but_keeps_edges() {
        let (w, h) = (16, 16);
        let n = (w * h) as usize;
        let normal: Vec<Vec3> =
            (0..n).map(|i| if i % 16 < 8 { Vec3::Z } else { Vec3::X }).collect();
        let position = vec![Vec3::ZERO; n];
        let src: Vec<Vec3> = (0..n)
            .map(|i| {
                if i % 16 < 8 {
                    Vec3::splat(if i % 2 == 0 { 0.0 } else { 2.0 })
                } else {
                    Vec3::splat(10.0)
                }
            })
            .collect();
        let mut out = vec![Vec3::ZERO; n];
        gaussian(&src, Guide { normal: &normal, position: &position }, &consts(w, h), &mut out);
        let left = 8 * 16 + 4;
        assert!((out[left].x - 1.0).abs() < 0.3, "{}", out[left]);
        assert_eq!(out[8 * 16 + 8], Vec3::splat(10.0), "nothing leaks across the normal edge");
    }

    #[test]
    fn remodulate_multiplies_albedo_and_adds_emission() {
        let c = consts(1, 1);
        let mut colour = [Vec3::ZERO];
        let mut display = [[0u8; 4]];
        remodulate(
            &[Vec3::splat(2.0)],
            &[Vec3::new(0.5, 0.25, 0.0)],
            &[Vec3::Z],
            &c,
            &mut colour,
            &mut display,
        );
        assert_eq!(colour[0], Vec3::new(1.0, 0.5, 1.0));
        assert_eq!(display[0], to_rgba8(colour[0], 0.0));
    }
}
