//! Image error metrics: RMSE on linear colour and SSIM on display luma. The perceptual
//! metric (FLIP) is in [`super::flip`].

use glam::Vec3;

use super::filter::{gaussian_kernel, Plane};

/// Root-mean-square error over all channels.
pub fn rmse(reference: &[Vec3], test: &[Vec3]) -> f64 {
    assert_eq!(reference.len(), test.len(), "images of different sizes");
    if reference.is_empty() {
        return 0.0;
    }
    let sum: f64 = reference
        .iter()
        .zip(test)
        .map(|(a, b)| {
            let d = (*a - *b).as_dvec3();
            d.dot(d)
        })
        .sum();
    (sum / (3 * reference.len()) as f64).sqrt()
}

/// Luma (Rec. 601 weights) of display-referred values in [0, 1].
pub fn luma(display: &[Vec3]) -> Vec<f32> {
    display.iter().map(|c| 0.299 * c.x + 0.587 * c.y + 0.114 * c.z).collect()
}

/// Mean structural similarity (Wang et al. 2004: 11-tap Gaussian window, σ = 1.5,
/// K1 = 0.01, K2 = 0.03, dynamic range 1) of two display images' luma. 1 means identical.
pub fn ssim(reference: &[Vec3], test: &[Vec3], width: usize, height: usize) -> f64 {
    assert_eq!(reference.len(), test.len(), "images of different sizes");
    let (c1, c2) = (0.01f32 * 0.01, 0.03f32 * 0.03);
    let k = gaussian_kernel(1.5, 5);
    let x = Plane::new(width, height, luma(reference));
    let y = Plane::new(width, height, luma(test));
    let blur = |p: &Plane| p.separable(&k, &k);
    let product = |a: &Plane, b: &Plane| {
        Plane::new(width, height, a.data.iter().zip(&b.data).map(|(u, v)| u * v).collect())
    };
    let (mx, my) = (blur(&x), blur(&y));
    let (sxx, syy, sxy) = (blur(&product(&x, &x)), blur(&product(&y, &y)), blur(&product(&x, &y)));
    let mut total = 0.0f64;
    for i in 0..width * height {
        let (ux, uy) = (mx.data[i], my.data[i]);
        let vx = sxx.data[i] - ux * ux;
        let vy = syy.data[i] - uy * uy;
        let cxy = sxy.data[i] - ux * uy;
        let s =
            ((2.0 * ux * uy + c1) * (2.0 * cxy + c2)) / ((ux * ux + uy * uy + c1) * (vx + vy + c2));
        total += s as f64;
    }
    total / (width * height).max(1) as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rmse_of_a_constant_offset() {
        let a = vec![Vec3::ZERO; 10];
        let b = vec![Vec3::splat(0.5); 10];
        assert!((rmse(&a, &b) - 0.5).abs() < 1e-9);
        assert_eq!(rmse(&a, &a), 0.0);
    }

    #[test]
    fn ssim_is_one_for_identical_images_and_falls_with_noise() {
        let (w, h) = (32, 24);
        let img: Vec<Vec3> =
            (0..w * h).map(|i| Vec3::splat(((i % w) as f32 / w as f32) * 0.8)).collect();
        assert!((ssim(&img, &img, w, h) - 1.0).abs() < 1e-4);
        let noisy = |amp: f32| -> Vec<Vec3> {
            img.iter()
                .enumerate()
                .map(|(i, c)| *c + Vec3::splat(if i % 2 == 0 { amp } else { -amp }))
                .collect()
        };
        let (s1, s2) = (ssim(&img, &noisy(0.05), w, h), ssim(&img, &noisy(0.2), w, h));
        assert!(s1 < 0.99 && s2 < s1, "{s1} {s2}");
    }
}
