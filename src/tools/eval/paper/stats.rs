//! Small statistics of the report: correlation and medians.

/// Pearson's correlation of `(x, y)` pairs; `None` when either is constant or there are
/// fewer than 3 pairs.
pub fn correlation(pairs: &[(f64, f64)]) -> Option<f64> {
    if pairs.len() < 3 {
        return None;
    }
    let n = pairs.len() as f64;
    let (sx, sy) = pairs.iter().fold((0.0, 0.0), |(a, b), (x, y)| (a + x, b + y));
    let (mx, my) = (sx / n, sy / n);
    let (mut sxy, mut sxx, mut syy) = (0.0, 0.0, 0.0);
    for (x, y) in pairs {
        sxy += (x - mx) * (y - my);
        sxx += (x - mx).powi(2);
        syy += (y - my).powi(2);
    }
    (sxx > 0.0 && syy > 0.0).then(|| sxy / (sxx * syy).sqrt())
}

/// A correlation (or another optional number) for the report's text: two decimals, or
/// "undefined".
pub fn two_places(v: Option<f64>) -> String {
    v.map_or("undefined".to_string(), |v| format!("{v:.2}"))
}

/// Median of `values` (0 when empty).
pub fn median(values: &[f64]) -> f64 {
    let mut v: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(f64::total_cmp);
    let m = v.len() / 2;
    if v.len() % 2 == 1 {
        v[m]
    } else {
        (v[m - 1] + v[m]) / 2.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn correlation_of_lines_and_of_noise() {
        let up: Vec<_> = (0..10).map(|i| (i as f64, 2.0 * i as f64 + 1.0)).collect();
        assert!((correlation(&up).unwrap() - 1.0).abs() < 1e-9);
        let down: Vec<_> = (0..10).map(|i| (i as f64, -(i as f64))).collect();
        assert!((correlation(&down).unwrap() + 1.0).abs() < 1e-9);
        let flat: Vec<_> = (0..10).map(|i| (i as f64, 3.0)).collect();
        assert_eq!(correlation(&flat), None);
    }

    #[test]
    fn medians() {
        assert_eq!(median(&[3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&[4.0, 1.0, 2.0, 3.0]), 2.5);
        assert_eq!(median(&[]), 0.0);
    }
}
