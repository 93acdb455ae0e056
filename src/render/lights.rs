//! The light table of one scene state and next-event estimation sampling.
//!
//! Lights are grouped into strategies chosen with equal probability: all area
//! emitters together (emissive triangles and `Light::Quad`s, picked by power, so
//! that the pdf of hitting one by chance is `Le / total power` per unit area), each
//! point or spot light, the sun, and the environment. Every pdf returned here
//! includes the probability of choosing the strategy, so that the integrator can
//! weight light samples against BSDF samples with MIS.

use std::f32::consts::PI;

use glam::{Vec2, Vec3};
use gridlight_actors::state::Light;

use super::envmap::Environment;
use super::microfacet::Frame;

/// A one-sided emitting triangle or parallelogram in world space.
#[derive(Clone, Copy, Debug)]
pub struct AreaLight {
    pub v0: Vec3,
    pub e1: Vec3,
    pub e2: Vec3,
    /// Unit normal of the emitting side.
    pub normal: Vec3,
    pub radiance: Vec3,
    pub parallelogram: bool,
}

impl AreaLight {
    pub fn area(&self) -> f32 {
        let a = self.e1.cross(self.e2).length();
        if self.parallelogram {
            a
        } else {
            0.5 * a
        }
    }

    /// Sampling weight: emitted power up to a constant.
    fn power(&self) -> f32 {
        (self.radiance.x + self.radiance.y + self.radiance.z).max(0.0) * self.area()
    }
}

/// A sampled light direction for next-event estimation.
#[derive(Clone, Copy, Debug)]
pub struct LightSample {
    pub wi: Vec3,
    /// Distance to the light (infinite for the sun and the environment).
    pub dist: f32,
    pub radiance: Vec3,
    /// Solid-angle pdf including the strategy choice; 0 marks a delta light
    /// whose `radiance` is already divided by its selection probability.
    pub pdf: f32,
}

/// The sun as seen from the scene.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Sun {
    pub(crate) frame: Frame,
    pub(crate) radiance: Vec3,
    pub(crate) cos_max: f32,
}

/// A point or spot light.
#[derive(Clone, Copy, Debug)]
pub(crate) struct PointLight {
    pub(crate) position: Vec3,
    pub(crate) intensity: Vec3,
    /// Spot axis and smooth-step cosines; `None` for an isotropic point light.
    pub(crate) spot: Option<(Vec3, f32, f32)>,
}

/// All lights of one scene state.
#[derive(Clone, Debug, Default)]
pub struct Lights {
    pub areas: Vec<AreaLight>,
    pub(crate) area_cdf: Vec<f32>,
    pub(crate) area_power: f32,
    pub(crate) points: Vec<PointLight>,
    pub(crate) sun: Option<Sun>,
    pub environment: Option<Environment>,
    /// Probability of each strategy (1 / number of strategies).
    pub(crate) strategy_pmf: f32,
    pub(crate) strategies: u32,
}

impl Lights {
    /// Builds the table from area emitters (triangles of emissive objects), the
    /// state's explicit lights and the environment.
    pub fn new(
        mut areas: Vec<AreaLight>,
        lights: &[Light],
        environment: Option<Environment>,
    ) -> Self {
        let mut points = Vec::new();
        let mut sun = None;
        for light in lights {
            match *light {
                Light::Point { position, intensity } => {
                    points.push(PointLight { position, intensity, spot: None })
                }
                Light::Spot { position, direction, intensity, inner_deg, outer_deg } => {
                    let outer = outer_deg.to_radians().cos();
                    let inner = inner_deg.min(outer_deg).to_radians().cos();
                    let axis = direction.normalize_or(Vec3::NEG_Y);
                    points.push(PointLight {
                        position,
                        intensity,
                        spot: Some((axis, inner, outer)),
                    })
                }
                Light::Sun { direction, radiance, angular_radius_deg } => {
                    let dir = direction.normalize_or(Vec3::Y);
                    let cos_max = angular_radius_deg.clamp(0.0, 90.0).to_radians().cos();
                    sun = Some(Sun { frame: Frame::new(dir), radiance, cos_max });
                }
                Light::Quad { corner, edge_u, edge_v, radiance } => {
                    let normal = edge_u.cross(edge_v).normalize_or_zero();
                    if normal != Vec3::ZERO {
                        areas.push(AreaLight {
                            v0: corner,
                            e1: edge_u,
                            e2: edge_v,
                            normal,
                            radiance,
                            parallelogram: true,
                        });
                    }
                }
            }
        }
        areas.retain(|a| a.power() > 0.0);
        let mut area_cdf = Vec::with_capacity(areas.len());
        let mut acc = 0.0f64;
        for a in &areas {
            acc += a.power() as f64;
            area_cdf.push(acc as f32);
        }
        let area_power = acc as f32;
        let strategies = u32::from(!areas.is_empty())
            + points.len() as u32
            + u32::from(sun.is_some())
            + u32::from(environment.is_some());
        let strategy_pmf = if strategies > 0 { 1.0 / strategies as f32 } else { 0.0 };
        Self { areas, area_cdf, area_power, points, sun, environment, strategy_pmf, strategies }
    }

    /// Whether there is anything to sample.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.strategies == 0
    }

    /// Quad lights (not part of the BVH) for intersection tests.
    pub fn quads(&self) -> impl Iterator<Item = &AreaLight> {
        self.areas.iter().filter(|a| a.parallelogram)
    }

    /// Samples a light as seen from `p` with three uniform numbers.
    #[inline(always)]
    pub fn sample(&self, p: Vec3, u: [f32; 3]) -> Option<LightSample> {
        if self.strategies == 0 {
            return None;
        }
        let pick = ((u[0] * self.strategies as f32) as u32).min(self.strategies - 1);
        let u2 = Vec2::new(u[1], u[2]);
        let mut k = pick;
        if !self.areas.is_empty() {
            if k == 0 {
                // Reuse the strategy's share of u[0] to pick the emitter.
                let ua = self.area_u(u[0], pick);
                return self.sample_area(p, ua, u2);
            }
            k -= 1;
        }
        if (k as usize) < self.points.len() {
            return Some(self.sample_point(&self.points[k as usize], p));
        }
        k -= self.points.len() as u32;
        if let Some(sun) = &self.sun {
            if k == 0 {
                return Some(self.sample_sun(sun, u2));
            }
            k -= 1;
        }
        debug_assert_eq!(k, 0);
        let env = self.environment.as_ref()?;
        let (wi, radiance, pdf) = env.sample(u2);
        (pdf > 0.0).then_some(LightSample {
            wi,
            dist: f32::INFINITY,
            radiance,
            pdf: pdf * self.strategy_pmf,
        })
    }

    /// Whether every light sample is an area emitter's (one strategy): the case the
    /// stream kernel's vector stage handles.
    #[inline]
    pub(crate) fn area_only(&self) -> bool {
        self.strategies == 1 && !self.areas.is_empty()
    }

    /// The area emitter light sampling picks with `u` (by power).
    #[inline(always)]
    pub(crate) fn pick_area(&self, u: f32) -> usize {
        let target = u * self.area_power;
        self.area_cdf.partition_point(|&c| c <= target).min(self.areas.len() - 1)
    }

    /// `u[0]` of a light sample as the area emitters' strategy reuses it (`pick` = 0
    /// where the scene has area emitters only).
    #[inline(always)]
    pub(crate) fn area_u(&self, u0: f32, pick: u32) -> f32 {
        (u0 * self.strategies as f32 - pick as f32).clamp(0.0, 0.999_999)
    }

    #[inline(always)]
    fn sample_area(&self, p: Vec3, u: f32, u2: Vec2) -> Option<LightSample> {
        let a = &self.areas[self.pick_area(u)];
        let (s, t) = if a.parallelogram {
            (u2.x, u2.y)
        } else {
            let r = u2.x.sqrt();
            (1.0 - r, u2.y * r)
        };
        let q = a.v0 + a.e1 * s + a.e2 * t;
        let d = q - p;
        let dist2 = d.length_squared();
        let dist = dist2.sqrt();
        let wi = d / dist;
        let cos_light = -wi.dot(a.normal);
        if cos_light <= 0.0 || dist2 == 0.0 {
            return None;
        }
        let pdf = self.area_pdf(a.radiance, dist2, cos_light);
        Some(LightSample { wi, dist, radiance: a.radiance, pdf })
    }

    /// Solid-angle pdf of reaching an area emitter with radiance `radiance` at
    /// squared distance `dist2` and cosine `cos_light` by light sampling.
    #[inline]
    pub fn area_pdf(&self, radiance: Vec3, dist2: f32, cos_light: f32) -> f32 {
        if self.area_power <= 0.0 || cos_light <= 0.0 {
            return 0.0;
        }
        let per_area = (radiance.x + radiance.y + radiance.z) / self.area_power;
        self.strategy_pmf * per_area * dist2 / cos_light
    }

    fn sample_point(&self, light: &PointLight, p: Vec3) -> LightSample {
        let d = light.position - p;
        let dist2 = d.length_squared().max(1e-12);
        let dist = dist2.sqrt();
        let wi = d / dist;
        let mut radiance = light.intensity / dist2;
        if let Some((axis, cos_inner, cos_outer)) = light.spot {
            let cos = (-wi).dot(axis);
            let falloff = if cos_inner > cos_outer {
                let x = ((cos - cos_outer) / (cos_inner - cos_outer)).clamp(0.0, 1.0);
                x * x * (3.0 - 2.0 * x)
            } else {
                f32::from(cos >= cos_outer)
            };
            radiance *= falloff;
        }
        LightSample { wi, dist, radiance: radiance / self.strategy_pmf, pdf: 0.0 }
    }

    fn sample_sun(&self, sun: &Sun, u: Vec2) -> LightSample {
        if sun.cos_max >= 1.0 {
            // A sun of zero size: a directional light with `radiance` as irradiance.
            let radiance = sun.radiance / self.strategy_pmf;
            return LightSample { wi: sun.frame.n, dist: f32::INFINITY, radiance, pdf: 0.0 };
        }
        let cos = 1.0 - u.x * (1.0 - sun.cos_max);
        let sin = (1.0 - cos * cos).max(0.0).sqrt();
        let phi = 2.0 * PI * u.y;
        let (sin_phi, cos_phi) = super::trig::sin_cos(phi);
        let wi = sun.frame.to_world(Vec3::new(sin * cos_phi, sin * sin_phi, cos));
        let pdf = self.strategy_pmf / (2.0 * PI * (1.0 - sun.cos_max));
        LightSample { wi, dist: f32::INFINITY, radiance: sun.radiance, pdf }
    }

    /// Radiance arriving along an escaping ray `dir` from the environment and from
    /// the sun disc, each with the pdf with which light sampling would have chosen
    /// that direction (they are separate strategies, so MIS weighs them apart).
    #[inline]
    pub fn escaped(&self, dir: Vec3) -> [(Vec3, f32); 2] {
        let mut out = [(Vec3::ZERO, 0.0); 2];
        if let Some(env) = &self.environment {
            out[0] = (env.eval(dir), env.pdf(dir) * self.strategy_pmf);
        }
        if let Some(sun) = &self.sun {
            if sun.cos_max < 1.0 && dir.dot(sun.frame.n) >= sun.cos_max {
                out[1] = (sun.radiance, self.strategy_pmf / (2.0 * PI * (1.0 - sun.cos_max)));
            }
        }
        out
    }
}
