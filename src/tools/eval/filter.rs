//! Separable 2-D convolution of a float plane with mirrored borders (the "symmetric"
//! boundary of scipy's `convolve2d`, which the FLIP reference uses).

/// A `width`×`height` plane of floats, row-major.
#[derive(Clone, Debug, PartialEq)]
pub struct Plane {
    pub width: usize,
    pub height: usize,
    pub data: Vec<f32>,
}

impl Plane {
    pub fn new(width: usize, height: usize, data: Vec<f32>) -> Self {
        debug_assert_eq!(data.len(), width * height);
        Self { width, height, data }
    }

    /// Convolves with `kx` along rows, then `ky` along columns (odd lengths, centred).
    pub fn separable(&self, kx: &[f32], ky: &[f32]) -> Plane {
        let tmp = self.pass(kx, true);
        tmp.pass(ky, false)
    }

    fn pass(&self, k: &[f32], horizontal: bool) -> Plane {
        let r = (k.len() / 2) as isize;
        let (w, h) = (self.width as isize, self.height as isize);
        let mut out = vec![0.0; self.data.len()];
        for y in 0..h {
            for x in 0..w {
                let mut acc = 0.0;
                for (t, &kv) in k.iter().enumerate() {
                    // Convolution flips the kernel: tap t reads offset r − t.
                    let o = r - t as isize;
                    let (xx, yy) =
                        if horizontal { (mirror(x + o, w), y) } else { (x, mirror(y + o, h)) };
                    acc += kv * self.data[(yy * w + xx) as usize];
                }
                out[(y * w + x) as usize] = acc;
            }
        }
        Plane::new(self.width, self.height, out)
    }
}

/// Index reflected at the borders with the edge repeated (-1 → 0, n → n−1).
fn mirror(i: isize, n: isize) -> isize {
    let period = 2 * n;
    let m = i.rem_euclid(period);
    if m < n {
        m
    } else {
        period - 1 - m
    }
}

/// A normalised 1-D Gaussian of the given radius.
pub fn gaussian_kernel(sigma: f32, radius: usize) -> Vec<f32> {
    let k: Vec<f32> = (-(radius as isize)..=radius as isize)
        .map(|x| (-((x * x) as f32) / (2.0 * sigma * sigma)).exp())
        .collect();
    let sum: f32 = k.iter().sum();
    k.into_iter().map(|v| v / sum).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mirror_repeats_the_edge() {
        assert_eq!(
            [mirror(-1, 4), mirror(-2, 4), mirror(4, 4), mirror(5, 4), mirror(2, 4)],
            [0, 1, 3, 2, 2]
        );
    }

    #[test]
    fn normalised_blur_keeps_a_constant_and_shifts_follow_the_kernel() {
        let p = Plane::new(5, 4, vec![2.0; 20]);
        let k = gaussian_kernel(1.0, 2);
        for v in p.separable(&k, &k).data {
            assert!((v - 2.0).abs() < 1e-5);
        }
        // A derivative kernel [1, 0, -1] (convolution) gives f(x+1) - f(x-1)... flipped:
        // out(x) = k0 f(x+1) + k2 f(x-1).
        let ramp = Plane::new(4, 1, vec![0.0, 1.0, 2.0, 3.0]);
        let d = ramp.separable(&[1.0, 0.0, -1.0], &[1.0]);
        assert_eq!(d.data[1], 2.0);
    }
}
