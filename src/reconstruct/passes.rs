//! The CPU reference of each reconstruction step, one function per GPU pass.
//!
//! Every function does exactly what its WGSL twin in `shaders/` does, in the same order of
//! operations, so that the parity test can hold the two to a tight tolerance. Rows are
//! processed in parallel with rayon.

use glam::{Vec3, Vec4};
use rayon::prelude::*;

use super::discontinuity::{discontinuity, is_surface};
use super::params::{ReconstructParams, MAX_GAUSS_WIDTH, MAX_HISTORY};
use super::tonemap::to_rgba8;

/// Entries of the 1-D Gaussian table (radius 0..=MAX_GAUSS_WIDTH/2).
pub const GAUSS_TABLE: usize = (MAX_GAUSS_WIDTH as usize / 2) + 1;

/// The numbers every pass needs, derived once per frame from the parameters and the scene
/// scale (the GPU uniform is built from this very value).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PassConsts {
    pub width: u32,
    pub height: u32,
    pub alpha: f32,
    /// Position threshold in scene units.
    pub beta: f32,
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
            alpha: params.alpha,
            beta: params.beta * scene_scale,
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
    rows(out, c.width).for_each(|(y, row)| {
        let y = y as i32;
        for (x, o) in row.iter_mut().enumerate() {
            let x = x as i32;
            let i = (y * w + x) as usize;
            let a = accum[i];
            if a.w > 0.0 {
                *o = a.truncate() / a.w;
                continue;
            }
            let (n_i, z_i) = (guide.normal[i], guide.position[i]);
            if !is_surface(n_i) {
                *o = Vec3::ZERO;
                continue;
            }
            let mut acc = Vec3::ZERO;
            let mut wsum = 0.0f32;
            let mut plain = Vec3::ZERO;
            let mut plain_n = 0.0f32;
            for dy in -c.radius..=c.radius {
                let yy = y + dy;
                if yy < 0 || yy >= h {
                    continue;
                }
                for dx in -c.radius..=c.radius {
                    let xx = x + dx;
                    if xx < 0 || xx >= w || dx * dx + dy * dy > c.radius * c.radius {
                        continue;
                    }
                    let j = (yy * w + xx) as usize;
                    let b = accum[j];
                    if b.w <= 0.0 {
                        continue;
                    }
                    let l_j = b.truncate() / b.w;
                    let n_j = guide.normal[j];
                    let d = discontinuity(n_i, n_j, z_i, guide.position[j], c.alpha, c.beta);
                    acc += l_j * d;
                    wsum += d;
                    if is_surface(n_j) {
                        plain += l_j;
                        plain_n += 1.0;
                    }
                }
            }
            *o = if wsum > 0.0 {
                acc / wsum
            } else if plain_n > 0.0 {
                plain / plain_n
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
            let d0 = discontinuity(n_i, n_i, z_i, z_i, c.alpha, c.beta);
            let mut acc = current[i] * d0;
            let mut wsum = d0;
            for p in past.iter().filter(|p| p.weight > 0.0) {
                let d = discontinuity(
                    n_i,
                    p.guide.normal[i],
                    z_i,
                    p.guide.position[i],
                    c.alpha,
                    c.beta,
                );
                let dw = d * p.weight;
                acc += p.radiance[i] * dw;
                wsum += dw;
            }
            *o = if wsum > 0.0 { acc / wsum } else { current[i] };
        }
    });
}

/// Step 3: the edge-aware Gaussian (width 2·gauss_radius + 1) weighted by D.
pub fn gaussian(src: &[Vec3], guide: Guide, c: &PassConsts, out: &mut [Vec3]) {
    let (w, h) = (c.width as i32, c.height as i32);
    let r = c.gauss_radius;
    rows(out, c.width).for_each(|(y, row)| {
        let y = y as i32;
        for (x, o) in row.iter_mut().enumerate() {
            let x = x as i32;
            let i = (y * w + x) as usize;
            let (n_i, z_i) = (guide.normal[i], guide.position[i]);
            let mut acc = Vec3::ZERO;
            let mut wsum = 0.0f32;
            for dy in -r..=r {
                let yy = y + dy;
                if yy < 0 || yy >= h {
                    continue;
                }
                let gy = c.gauss[dy.unsigned_abs() as usize];
                for dx in -r..=r {
                    let xx = x + dx;
                    if xx < 0 || xx >= w {
                        continue;
                    }
                    let j = (yy * w + xx) as usize;
                    let d = discontinuity(
                        n_i,
                        guide.normal[j],
                        z_i,
                        guide.position[j],
                        c.alpha,
                        c.beta,
                    );
                    let g = gy * c.gauss[dx.unsigned_abs() as usize] * d;
                    acc += src[j] * g;
                    wsum += g;
                }
            }
            *o = if wsum > 0.0 { acc / wsum } else { src[i] };
        }
    });
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
            for (x, (co, d)) in crow.iter_mut().zip(drow.iter_mut()).enumerate() {
                let i = base + x;
                *co = albedo[i] * radiance[i] + emission[i];
                *d = to_rgba8(*co, c.exposure);
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
