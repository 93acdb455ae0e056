//! LDR-ꟻLIP (Andersson et al., "FLIP: A Difference Evaluator for Alternating Images",
//! HPG 2020), implemented after NVIDIA's reference `flip.py`: a per-pixel perceptual
//! difference in [0, 1] between two sRGB display images, and its mean.
//!
//! Colour pipeline: sRGB → linear → YCxCz, contrast-sensitivity filtering per channel,
//! back to linear RGB (clamped), CIELab with the Hunt adjustment, HyAB distance,
//! compressed and redistributed. Feature pipeline: edge and point detectors (first and
//! second Gaussian derivatives) on the achromatic channel. The two combine as
//! ΔE = ΔE_c^(1 − ΔE_f). Filters repeat the border pixel outside the image, as NVIDIA's
//! C++ FLIP does (`tests/flip_known_answer.rs` checks us against it). No FLIP crate in pure Rust exists (`nv-flip` binds the C++
//! library), hence this implementation.

use glam::{Mat3, Vec3};

use super::filter::Plane;

/// Pixels per degree of the reference viewing setup (0.7 m from a 0.7 m wide 4K monitor).
pub const DEFAULT_PPD: f32 = 67.0;

const QC: f32 = 0.7;
const QF: f32 = 0.5;
const PC: f32 = 0.4;
const PT: f32 = 0.95;

/// Per-pixel FLIP values and their mean.
#[derive(Clone, Debug)]
pub struct FlipResult {
    pub mean: f64,
    pub map: Vec<f32>,
}

fn linrgb_to_xyz() -> Mat3 {
    // Rows of flip.py's matrix, given column-major to glam.
    Mat3::from_cols_array(&[
        10135552.0 / 24577794.0,
        2613072.0 / 12288897.0,
        1425312.0 / 73733382.0,
        8788810.0 / 24577794.0,
        8788810.0 / 12288897.0,
        8788810.0 / 73733382.0,
        4435075.0 / 24577794.0,
        887015.0 / 12288897.0,
        70074185.0 / 73733382.0,
    ])
}

fn white() -> Vec3 {
    linrgb_to_xyz() * Vec3::ONE
}

fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

fn xyz_to_ycxcz(xyz: Vec3) -> Vec3 {
    let n = xyz / white();
    Vec3::new(116.0 * n.y - 16.0, 500.0 * (n.x - n.y), 200.0 * (n.y - n.z))
}

fn ycxcz_to_xyz(c: Vec3) -> Vec3 {
    let y = (c.x + 16.0) / 116.0;
    Vec3::new(c.y / 500.0 + y, y, y - c.z / 200.0) * white()
}

fn xyz_to_lab(xyz: Vec3) -> Vec3 {
    let n = xyz / white();
    let delta = 6.0f32 / 29.0;
    let f = |t: f32| {
        if t > delta * delta * delta {
            t.cbrt()
        } else {
            t / (3.0 * delta * delta) + 4.0 / 29.0
        }
    };
    let (fx, fy, fz) = (f(n.x), f(n.y), f(n.z));
    Vec3::new(116.0 * fy - 16.0, 500.0 * (fx - fy), 200.0 * (fy - fz))
}

fn hunt(lab: Vec3) -> Vec3 {
    Vec3::new(lab.x, 0.01 * lab.x * lab.y, 0.01 * lab.x * lab.z)
}

fn hyab(a: Vec3, b: Vec3) -> f32 {
    let d = a - b;
    d.x.abs() + (d.y * d.y + d.z * d.z).sqrt()
}

/// One term a·sqrt(π/b)·exp(−π²x²/b) of a contrast-sensitivity function, sampled at
/// x = k/ppd degrees for |k| ≤ radius (not normalised: the terms are summed first).
fn csf_term(a: f32, b: f32, ppd: f32, radius: usize) -> Vec<f32> {
    let pi = std::f32::consts::PI;
    (-(radius as isize)..=radius as isize)
        .map(|k| {
            let x = k as f32 / ppd;
            a.sqrt() * (pi / b).sqrt().sqrt() * (-pi * pi * x * x / b).exp()
        })
        .collect()
}

/// Filters one YCxCz channel with its CSF: a sum of one or two separable Gaussians,
/// normalised so the whole 2-D kernel sums to 1.
fn csf_filter(plane: &Plane, terms: &[(f32, f32)], ppd: f32, radius: usize) -> Plane {
    // a·sqrt(π/b)·exp(−π²(x²+y²)/b) = [sqrt(a)·(π/b)^¼·exp(−π²x²/b)] · [same in y].
    let kernels: Vec<Vec<f32>> = terms.iter().map(|&(a, b)| csf_term(a, b, ppd, radius)).collect();
    let total: f32 = kernels.iter().map(|k| k.iter().sum::<f32>().powi(2)).sum();
    let mut out = vec![0.0; plane.data.len()];
    for k in &kernels {
        let filtered = plane.separable_clamped(k, k);
        for (o, v) in out.iter_mut().zip(filtered.data) {
            *o += v / total;
        }
    }
    Plane::new(plane.width, plane.height, out)
}

/// Edge (first derivative) or point (second derivative) detector kernels in x: the
/// derivative factor, normalised so its positive and negative parts each sum to ±1 over
/// the 2-D kernel, and the Gaussian factor in y.
fn feature_kernels(ppd: f32, point: bool) -> (Vec<f32>, Vec<f32>) {
    let sd = 0.5 * 0.082 * ppd;
    let radius = (3.0 * sd).ceil() as isize;
    let g: Vec<f32> =
        (-radius..=radius).map(|x| (-((x * x) as f32) / (2.0 * sd * sd)).exp()).collect();
    let d: Vec<f32> = (-radius..=radius)
        .zip(&g)
        .map(
            |(x, gx)| {
                if point {
                    ((x * x) as f32 / (sd * sd) - 1.0) * gx
                } else {
                    -(x as f32) * gx
                }
            },
        )
        .collect();
    let gsum: f32 = g.iter().sum();
    let pos: f32 = d.iter().filter(|v| **v > 0.0).sum::<f32>() * gsum;
    let neg: f32 = -d.iter().filter(|v| **v < 0.0).sum::<f32>() * gsum;
    let dx = d.iter().map(|v| if *v < 0.0 { v / neg } else { v / pos }).collect();
    (dx, g)
}

fn feature_magnitude(y: &Plane, ppd: f32, point: bool) -> Vec<f32> {
    let (d, g) = feature_kernels(ppd, point);
    let fx = y.separable_clamped(&d, &g);
    let fy = y.separable_clamped(&g, &d);
    fx.data.iter().zip(&fy.data).map(|(a, b)| (a * a + b * b).sqrt()).collect()
}

/// FLIP between a reference and a test image, both sRGB-encoded display values in [0, 1].
pub fn flip(
    reference: &[Vec3],
    test: &[Vec3],
    width: usize,
    height: usize,
    ppd: f32,
) -> FlipResult {
    let linear = |img: &[Vec3]| -> Vec<Vec3> {
        img.iter()
            .map(|c| Vec3::new(srgb_to_linear(c.x), srgb_to_linear(c.y), srgb_to_linear(c.z)))
            .collect()
    };
    flip_linear(&linear(reference), &linear(test), width, height, ppd)
}

/// FLIP between two linear-RGB display images (clamped to [0, 1]), as HDR-FLIP gives
/// its tone-mapped exposures ([`super::hdr_flip`]).
pub fn flip_linear(
    reference: &[Vec3],
    test: &[Vec3],
    width: usize,
    height: usize,
    ppd: f32,
) -> FlipResult {
    assert_eq!(reference.len(), test.len(), "images of different sizes");
    assert_eq!(reference.len(), width * height, "image size");
    let m = linrgb_to_xyz();
    let to_ycxcz = |img: &[Vec3]| -> Vec<Vec3> {
        img.iter().map(|lin| xyz_to_ycxcz(m * lin.clamp(Vec3::ZERO, Vec3::ONE))).collect()
    };
    let (r, t) = (to_ycxcz(reference), to_ycxcz(test));

    // Colour pipeline.
    let csf: [&[(f32, f32)]; 3] =
        [&[(1.0, 0.0047)], &[(1.0, 0.0053)], &[(34.1, 0.04), (13.5, 0.025)]];
    let radius =
        (3.0 * (0.04f32 / (2.0 * std::f32::consts::PI.powi(2))).sqrt() * ppd).ceil() as usize;
    let m_inv = m.inverse();
    let filtered = |img: &[Vec3]| -> Vec<Vec3> {
        let channels: Vec<Plane> = (0..3)
            .map(|c| {
                let p = Plane::new(width, height, img.iter().map(|v| v[c]).collect());
                csf_filter(&p, csf[c], ppd, radius)
            })
            .collect();
        (0..width * height)
            .map(|i| {
                let ycxcz =
                    Vec3::new(channels[0].data[i], channels[1].data[i], channels[2].data[i]);
                let lin = (m_inv * ycxcz_to_xyz(ycxcz)).clamp(Vec3::ZERO, Vec3::ONE);
                hunt(xyz_to_lab(m * lin))
            })
            .collect()
    };
    let (rf, tf) = (filtered(&r), filtered(&t));
    let cmax = hyab(hunt(xyz_to_lab(m * Vec3::Y)), hunt(xyz_to_lab(m * Vec3::Z))).powf(QC);
    let pccmax = PC * cmax;

    // Feature pipeline on normalised achromatic values.
    let achromatic = |img: &[Vec3]| {
        Plane::new(width, height, img.iter().map(|v| (v.x + 16.0) / 116.0).collect())
    };
    let (ry, ty) = (achromatic(&r), achromatic(&t));
    let (re, te) = (feature_magnitude(&ry, ppd, false), feature_magnitude(&ty, ppd, false));
    let (rp, tp) = (feature_magnitude(&ry, ppd, true), feature_magnitude(&ty, ppd, true));

    let map: Vec<f32> = (0..width * height)
        .map(|i| {
            let c = hyab(rf[i], tf[i]).powf(QC);
            let c = if c < pccmax {
                (PT / pccmax) * c
            } else {
                PT + ((c - pccmax) / (cmax - pccmax)) * (1.0 - PT)
            };
            let f = (re[i] - te[i]).abs().max((rp[i] - tp[i]).abs());
            let f = (std::f32::consts::FRAC_1_SQRT_2 * f).powf(QF);
            c.powf(1.0 - f)
        })
        .collect();
    let mean = map.iter().map(|&v| v as f64).sum::<f64>() / map.len().max(1) as f64;
    FlipResult { mean, map }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gradient(w: usize, h: usize) -> Vec<Vec3> {
        (0..w * h)
            .map(|i| Vec3::new((i % w) as f32 / w as f32, (i / w) as f32 / h as f32, 0.3))
            .collect()
    }

    #[test]
    fn identical_images_score_zero() {
        let img = gradient(40, 30);
        assert!(flip(&img, &img, 40, 30, DEFAULT_PPD).mean < 1e-6);
    }

    #[test]
    fn white_against_black_is_near_the_maximum() {
        let (w, h) = (24, 24);
        let r = flip(&vec![Vec3::ONE; w * h], &vec![Vec3::ZERO; w * h], w, h, DEFAULT_PPD);
        assert!(r.mean > 0.85 && r.mean <= 1.0, "{}", r.mean);
    }

    #[test]
    fn more_noise_scores_higher() {
        let (w, h) = (48, 36);
        let img = gradient(w, h);
        let noisy = |amp: f32| -> Vec<Vec3> {
            img.iter()
                .enumerate()
                .map(|(i, c)| {
                    (*c + Vec3::splat(if (i * 7919) % 3 == 0 { amp } else { -amp * 0.5 }))
                        .clamp(Vec3::ZERO, Vec3::ONE)
                })
                .collect()
        };
        let a = flip(&img, &noisy(0.03), w, h, DEFAULT_PPD).mean;
        let b = flip(&img, &noisy(0.15), w, h, DEFAULT_PPD).mean;
        assert!(a > 0.0 && b > a, "{a} {b}");
    }
}
