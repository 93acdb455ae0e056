//! How much light a GGX dielectric layer lets through to the Lambertian base under it:
//! the energy-conserving, reciprocal weight of glTF's `fresnel_mix` base ([`super::pbr`]).
//!
//! The base is weighed by `(1 − E(μo)) (1 − E(μi)) / (1 − E_avg)`, where `E(μ)` is the
//! layer's directional albedo (GGX with height-correlated Smith masking and Schlick's
//! Fresnel, integrated over the hemisphere) and `E_avg = 2∫E(μ)μ dμ` its cosine-weighted
//! mean. A white base then returns exactly what the layer does not reflect, `1 − E(μo)`,
//! at every view (Kulla and Conty's normalisation, 2017), and the weight is symmetric in
//! the two directions. The appendix's `1 − F(v·h)` gains energy at grazing views, and
//! `(1 − F(μo))(1 − F(μi))` — this module's predecessor — lost up to a quarter of a rough
//! grey floor's light at grazing views against Cycles (`tests/gltf_cycles.rs`), which
//! weighs its base by the layer's albedo as here.
//!
//! Schlick's Fresnel is linear in F0, so E = F0·E₁ + (1 − F0)·E₅ with E₁ (F = 1) and E₅
//! (F = (1 − v·h)⁵) tabulated once over μ and roughness √α by a fixed stratified
//! integration: the tables are the same on every machine, so every kernel agrees.

use std::sync::OnceLock;

use glam::{Vec2, Vec3};

use super::microfacet::{reflect, Ggx};

/// Table points along μ and along √α (both 0..=1).
const N: usize = 32;
/// Stratified samples per side of each table entry's integration.
const STRATA: usize = 24;

/// E₁ and E₅ over (√α, μ), and their cosine-weighted means over √α.
struct Tables {
    e1: [[f32; N]; N],
    e5: [[f32; N]; N],
    avg1: [f32; N],
    avg5: [f32; N],
}

fn tables() -> &'static Tables {
    static TABLES: OnceLock<Tables> = OnceLock::new();
    TABLES.get_or_init(build)
}

/// μ of table column `j`; the first is kept off 0, where the view is degenerate.
fn mu_at(j: usize) -> f32 {
    (j as f32 / (N - 1) as f32).max(1e-3)
}

fn build() -> Tables {
    let mut t = Tables { e1: [[0.0; N]; N], e5: [[0.0; N]; N], avg1: [0.0; N], avg5: [0.0; N] };
    for r in 0..N {
        let roughness = r as f32 / (N - 1) as f32;
        let ggx = Ggx { alpha: roughness * roughness };
        for j in 0..N {
            let mu = mu_at(j);
            let (e1, e5) = if ggx.alpha < Ggx::SMOOTH {
                // A mirror: E is Schlick's Fresnel at μ.
                (1.0, (1.0 - mu).powi(5))
            } else {
                integrate(ggx, mu)
            };
            (t.e1[r][j], t.e5[r][j]) = (e1, e5);
        }
        (t.avg1[r], t.avg5[r]) = (mean_over_mu(&t.e1[r]), mean_over_mu(&t.e5[r]));
    }
    t
}

/// (E₁, E₅) at view cosine `mu`: visible-normal samples weighted by G2/G1 (the
/// estimator of ∫ D G2 F / (4 μo) dωi under that pdf).
fn integrate(ggx: Ggx, mu: f32) -> (f32, f32) {
    let o = Vec3::new((1.0 - mu * mu).max(0.0).sqrt(), 0.0, mu);
    let (mut e1, mut e5) = (0.0f64, 0.0f64);
    for a in 0..STRATA {
        for b in 0..STRATA {
            let u = Vec2::new((a as f32 + 0.5) / STRATA as f32, (b as f32 + 0.5) / STRATA as f32);
            let h = ggx.sample_visible(o, u);
            let i = reflect(o, h);
            if i.z <= 0.0 {
                continue;
            }
            let w = (ggx.g2(o, i) / ggx.g1(o)) as f64;
            e1 += w;
            e5 += w * ((1.0 - o.dot(h).clamp(0.0, 1.0)) as f64).powi(5);
        }
    }
    let n = (STRATA * STRATA) as f64;
    ((e1 / n) as f32, (e5 / n) as f32)
}

/// 2∫E(μ)μ dμ of a row, E taken as the piecewise-linear interpolant [`lookup`] reads,
/// so that a white base's albedo is exactly 1 − E(μo).
fn mean_over_mu(row: &[f32; N]) -> f32 {
    const STEPS: usize = 1024;
    let sum: f32 = (0..STEPS)
        .map(|k| {
            let mu = (k as f32 + 0.5) / STEPS as f32;
            along_mu(row, mu) * mu
        })
        .sum();
    2.0 * sum / STEPS as f32
}

/// A row's value at `mu`, linear between columns.
#[inline]
fn along_mu(row: &[f32; N], mu: f32) -> f32 {
    let x = mu.clamp(0.0, 1.0) * (N - 1) as f32;
    let j = (x as usize).min(N - 2);
    let f = x - j as f32;
    row[j] * (1.0 - f) + row[j + 1] * f
}

/// The row index and weight of roughness `alpha` (rows are √α).
#[inline]
fn row_of(alpha: f32) -> (usize, f32) {
    let x = alpha.max(0.0).sqrt().min(1.0) * (N - 1) as f32;
    let r = (x as usize).min(N - 2);
    (r, x - r as f32)
}

/// The layer's directional albedo E(μ) for normal-incidence reflectance `f0`.
#[inline]
pub fn albedo(f0: f32, alpha: f32, mu: f32) -> f32 {
    let t = tables();
    let (r, f) = row_of(alpha);
    let at =
        |rows: &[[f32; N]; N]| along_mu(&rows[r], mu) * (1.0 - f) + along_mu(&rows[r + 1], mu) * f;
    f0 * at(&t.e1) + (1.0 - f0) * at(&t.e5)
}

/// The layer's cosine-weighted mean albedo E_avg.
#[inline]
pub fn average(f0: f32, alpha: f32) -> f32 {
    let t = tables();
    let (r, f) = row_of(alpha);
    let at = |row: &[f32; N]| row[r] * (1.0 - f) + row[r + 1] * f;
    f0 * at(&t.avg1) + (1.0 - f0) * at(&t.avg5)
}

/// What of the base reaches the viewer: `(1 − E(μo))(1 − E(μi)) / (1 − E_avg)`.
#[inline]
pub fn base_weight(f0: f32, alpha: f32, cos_o: f32, cos_i: f32) -> f32 {
    let through = |mu: f32| 1.0 - albedo(f0, alpha, mu);
    through(cos_o) * through(cos_i) / (1.0 - average(f0, alpha)).max(1e-6)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn schlick(f0: f32, mu: f32) -> f32 {
        f0 + (1.0 - f0) * (1.0 - mu).powi(5)
    }

    #[test]
    fn a_smooth_layer_reflects_schlicks_fresnel() {
        // Linear between columns 1/31 apart: (1 − μ)⁵ bends most near μ = 0.
        for mu in [0.05, 0.3, 0.7, 1.0] {
            let (got, want) = (albedo(0.04, 0.0, mu), schlick(0.04, mu));
            assert!((got - want).abs() < 4e-3, "μ {mu}: {got} vs {want}");
        }
        // 2∫F(μ)μ dμ = F0 + (1 − F0)/21 for Schlick's Fresnel.
        assert!((average(0.04, 0.0) - (0.04 + 0.96 / 21.0)).abs() < 1e-3);
    }

    #[test]
    fn a_rough_layer_reflects_less_than_its_fresnel_at_grazing_views() {
        let (f0, rough) = (0.04, 0.5);
        assert!(albedo(f0, rough, 0.1) < schlick(f0, 0.1) - 0.1, "{}", albedo(f0, rough, 0.1));
        // Always between 0 and 1, and a white mirror-Fresnel layer keeps less with roughness.
        for mu in [0.1, 0.5, 1.0] {
            let (smooth, rough) = (albedo(1.0, 0.0, mu), albedo(1.0, 1.0, mu));
            assert!(rough < smooth && rough > 0.3, "μ {mu}: {rough} against {smooth}");
        }
    }

    #[test]
    fn a_white_base_returns_exactly_what_the_layer_lets_through() {
        for alpha in [0.0, 0.09, 0.25, 1.0] {
            for mu_o in [0.1, 0.5, 0.9] {
                // 2∫ base_weight(μo, μi) μi dμi, by the midpoint rule.
                let steps = 4000;
                let through: f32 = (0..steps)
                    .map(|k| {
                        let mu_i = (k as f32 + 0.5) / steps as f32;
                        base_weight(0.04, alpha, mu_o, mu_i) * mu_i
                    })
                    .sum::<f32>()
                    * 2.0
                    / steps as f32;
                let want = 1.0 - albedo(0.04, alpha, mu_o);
                assert!((through - want).abs() < 1e-3, "α {alpha} μo {mu_o}: {through} vs {want}");
            }
        }
    }
}
