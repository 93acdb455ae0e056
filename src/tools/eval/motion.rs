//! `gridlight eval motion` (issue 41): how each reconstruction method copes with motion
//! and edits, against converged images of the same views.
//!
//! The script, on one scene, with the frames every method sees rendered once:
//! 1. a resting view: `rest_frames` frames of one state, each with `rest_sets` of the
//!    `sets` pixel sets (the frames accumulate);
//! 2. an orbit: `orbit_views` new camera states, `step_deg` apart about the look-at
//!    point, each shown once with `move_sets` sets (a new state's first frame is shown
//!    with its first results: paper §4.3, the master's new-view rule);
//! 3. after resting again, a material edit (the first material's base colour halved) and,
//!    after another rest, a light edit (every emission halved), each shown once with
//!    `move_sets` sets.
//!
//! Each shown frame is compared with a `gold_spp` render of its state (LDR-FLIP of the
//! tonemapped colour). Reported per method: the first orbit frame (the first frame after
//! a camera edit), the orbit's mean, each edit's first frame, stability (the mean
//! frame-to-frame FLIP of the resting view, from its second frame) and the median
//! reconstruction milliseconds per frame. Sets are taken in order, a cursor running over
//! them, so that successive frames cover new pixels as the grid's jobs would.

use std::sync::Arc;
use std::time::Instant;

use glam::{Quat, Vec3};
use gridlight_actors::protocol::{Partition, SetsConfig};
use gridlight_actors::sets::SetTable;
use gridlight_actors::state::SceneState;
use rayon::prelude::*;
use serde::Serialize;

use super::compare;
use super::oidn::{Noisy, Oidn};
use crate::assets::Assets;
use crate::gbuffer::{scene_scale, GBuffer};
use crate::gpu::Backend;
use crate::master::compose::demodulate;
use crate::reconstruct::{FrameInputs, Method, ReconstructParams, Reconstructor};
use crate::render::{render_pixels, PixelSample, RenderScene};

/// The script's sizes.
#[derive(Clone, Debug, Serialize)]
pub struct Script {
    pub sets: u32,
    pub rest_frames: usize,
    pub rest_sets: u32,
    pub orbit_views: usize,
    pub step_deg: f32,
    pub move_sets: u32,
    pub gold_spp: u32,
}

impl Script {
    /// The figures: 20 frames at rest, 1-2 of 64 jobs in a new state's first frame,
    /// 512-spp references.
    pub fn full() -> Self {
        Self {
            sets: 64,
            rest_frames: 20,
            rest_sets: 8,
            orbit_views: 16,
            step_deg: 1.5,
            move_sets: 2,
            gold_spp: 512,
        }
    }

    /// A few minutes on two cores.
    pub fn quick() -> Self {
        Self { orbit_views: 6, gold_spp: 64, ..Self::full() }
    }
}

/// One method's figures on one scene.
#[derive(Clone, Debug, Serialize)]
pub struct MethodResult {
    pub method: &'static str,
    pub first_frame_flip: f64,
    pub orbit_mean_flip: f64,
    pub material_edit_flip: f64,
    pub light_edit_flip: f64,
    pub stability: f64,
    pub cpu_ms: f64,
    /// FLIP of every orbit frame.
    pub orbit_flip: Vec<f64>,
}

/// One shown frame of the script: its state, sets and whether it starts a new state.
struct Shown {
    state: Arc<SceneState>,
    sets: u32,
    accumulated: u32,
    kind: Kind,
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum Kind {
    Rest { first_rest: bool },
    Orbit,
    MaterialEdit,
    LightEdit,
}

/// The script's shown frames from `base`.
fn frames(base: &SceneState, s: &Script) -> Vec<Shown> {
    let mut out = Vec::new();
    let mut version = base.version;
    let mut state = |edit: &dyn Fn(&mut SceneState)| {
        let mut st = base.clone();
        edit(&mut st);
        version += 1;
        st.version = version;
        Arc::new(st)
    };
    let rest = |out: &mut Vec<Shown>, st: &Arc<SceneState>, first_rest: bool| {
        for k in 0..s.rest_frames {
            let kind = Kind::Rest { first_rest };
            let st = Arc::clone(st);
            out.push(Shown { state: st, sets: s.rest_sets, accumulated: k as u32 + 1, kind });
        }
    };
    let orbit = |st: &mut SceneState, view: usize| {
        let cam = &mut st.camera;
        let turn = Quat::from_axis_angle(
            cam.up.normalize_or(Vec3::Y),
            (s.step_deg * view as f32).to_radians(),
        );
        cam.position = cam.look_at + turn * (cam.position - cam.look_at);
    };
    rest(&mut out, &state(&|_| {}), true);
    let views = s.orbit_views;
    for view in 1..=views {
        let st = state(&|st| orbit(st, view));
        out.push(Shown { state: st, sets: s.move_sets, accumulated: 1, kind: Kind::Orbit });
    }
    let last = state(&|st| orbit(st, views));
    rest(&mut out, &last, false);
    let material = |st: &mut SceneState| {
        orbit(st, views);
        if let Some(m) = st.materials.first_mut() {
            m.base_color *= 0.5;
        }
    };
    let edited = state(&material);
    out.push(Shown { state: edited, sets: s.move_sets, accumulated: 1, kind: Kind::MaterialEdit });
    let rested = state(&material);
    rest(&mut out, &rested, false);
    let light = state(&|st| {
        material(st);
        for m in &mut st.materials {
            m.emission *= 0.5;
        }
        for l in &mut st.lights {
            scale_light(l, 0.5);
        }
        if let Some(env) = &mut st.environment {
            env.intensity *= 0.5;
        }
    });
    out.push(Shown { state: light, sets: s.move_sets, accumulated: 1, kind: Kind::LightEdit });
    out
}

/// Scales a light's power (sky light too: the environment).
fn scale_light(light: &mut gridlight_actors::state::Light, k: f32) {
    use gridlight_actors::state::Light;
    match light {
        Light::Point { intensity, .. } | Light::Spot { intensity, .. } => *intensity *= k,
        Light::Sun { radiance, .. } | Light::Quad { radiance, .. } => *radiance *= k,
    }
}

/// Renders what the script needs of one state: its G-buffer and gold image, cached.
struct Renderer {
    scene: RenderScene,
    assets: Arc<Assets>,
    gold_spp: u32,
    cached: Option<(u64, Arc<GBuffer>, Arc<Vec<Vec3>>)>,
}

impl Renderer {
    fn set(&mut self, state: &SceneState) -> anyhow::Result<(Arc<GBuffer>, Arc<Vec<Vec3>>)> {
        if let Some((v, g, gold)) = &self.cached {
            if *v == state.version {
                return Ok((Arc::clone(g), Arc::clone(gold)));
            }
        }
        let gold = Arc::new(self.complete(state, self.gold_spp, u64::MAX / 2)?);
        let g = Arc::new(GBuffer::from_scene(&self.scene, scene_scale(state, &self.assets)));
        self.cached = Some((state.version, Arc::clone(&g), Arc::clone(&gold)));
        Ok((g, gold))
    }

    /// Every pixel of `state` with `spp` samples (reflected plus emitted radiance) of
    /// frame `frame`'s seed; the scene is left at `state`.
    fn complete(&mut self, state: &SceneState, spp: u32, frame: u64) -> anyhow::Result<Vec<Vec3>> {
        let mut at_spp = state.clone();
        at_spp.render.spp = spp;
        self.scene.set_state(&at_spp)?;
        let all: Vec<u32> = (0..state.resolution.pixels() as u32).collect();
        let samples = self.render(&all, frame);
        self.scene.set_state(state)?;
        Ok(samples.iter().map(|s| s.reflected + s.emission).collect())
    }

    /// Samples of `pixels` (in order), on all cores.
    fn render(&self, pixels: &[u32], frame: u64) -> Vec<PixelSample> {
        let scene = &self.scene;
        pixels
            .par_chunks(4096)
            .map(|chunk| {
                let mut out = Vec::with_capacity(chunk.len());
                render_pixels(scene, frame, chunk, &mut out);
                out
            })
            .collect::<Vec<_>>()
            .concat()
    }
}

/// Runs the script on `state` for each of `methods`, with `params` otherwise (the scene
/// file's `[render.reconstruction]`), then the `anchor` (method `oidn`) if given.
pub fn run(
    assets: Arc<Assets>,
    state: &SceneState,
    script: &Script,
    methods: &[Method],
    params: ReconstructParams,
    anchor: Option<&Anchor>,
) -> anyhow::Result<Vec<MethodResult>> {
    let res = state.resolution;
    let (w, h) = (res.width, res.height);
    let table =
        SetTable::new(res, SetsConfig { sets: script.sets, partition: Partition::QuasiRandom })?;
    let scene = RenderScene::new(Arc::clone(&assets), state)?;
    let mut renderer = Renderer { scene, assets, gold_spp: script.gold_spp, cached: None };
    let mut reconstructors = methods
        .iter()
        .map(|&method| {
            Reconstructor::new(w, h, ReconstructParams { method, ..params }, Backend::Cpu, None)
        })
        .collect::<Result<Vec<_>, _>>()?;
    let mut tracks: Vec<Track> = methods.iter().map(|_| Track::default()).collect();
    // The anchor's frames, denoised after the script: complete frames of the shown ones'
    // states, each with its kind and reference.
    let (mut anchor_frames, mut noisy) = (Vec::new(), Vec::new());
    let mut cursor = 0u32;
    let (mut radiance, mut demodulated) = (vec![Vec3::ZERO; res.pixels()], Vec::new());
    for (k, shown) in frames(state, script).iter().enumerate() {
        let frame = k as u64 + 1;
        let (g, gold) = renderer.set(&shown.state)?;
        let mut mask = vec![false; res.pixels()];
        let mut pixels = Vec::new();
        for s in 0..shown.sets {
            pixels.extend_from_slice(table.pixels((cursor + s) % script.sets).unwrap_or(&[]));
        }
        cursor = (cursor + shown.sets) % script.sets;
        pixels.sort_unstable();
        radiance.fill(Vec3::ZERO);
        for (p, sample) in pixels.iter().zip(renderer.render(&pixels, frame)) {
            (mask[*p as usize], radiance[*p as usize]) = (true, sample.reflected);
        }
        demodulate(&radiance, &g.albedo, &mut demodulated);
        let inputs = FrameInputs {
            frame,
            state_version: shown.state.version,
            accumulated_frames: shown.accumulated,
            radiance: &demodulated,
            mask: &mask,
            gbuffer: &g,
            scene: Some(&shown.state),
        };
        for (r, t) in reconstructors.iter_mut().zip(&mut tracks) {
            let started = Instant::now();
            let out = r.reconstruct(&inputs)?;
            let ms = started.elapsed().as_secs_f64() * 1e3;
            t.record(shown.kind, out.colour, &gold, (w, h), ms);
        }
        if let (Some(a), true) = (anchor, shown.kind != Kind::Rest { first_rest: false }) {
            let colour = renderer.complete(&shown.state, a.spp, frame)?;
            let (albedo, normal) = (g.albedo.clone(), g.normal.clone());
            anchor_frames.push((shown.kind, gold));
            noisy.push(Noisy { colour, albedo, normal });
        }
    }
    let mut results: Vec<MethodResult> =
        methods.iter().zip(tracks).map(|(m, t)| t.result(m.name())).collect();
    if let Some(a) = anchor {
        let denoised = a.oidn.denoise(&noisy, w, h)?;
        let mut t = Track::default();
        for ((kind, gold), d) in anchor_frames.iter().zip(denoised) {
            t.record(*kind, d.colour, gold, (w, h), d.ms);
        }
        results.push(t.result("oidn"));
    }
    Ok(results)
}

/// The external anchor of [`run`]: OIDN on complete frames of `spp` samples per pixel
/// of each measured frame's state (it cannot fill the holes of missing sets).
#[derive(Clone, Debug)]
pub struct Anchor {
    pub oidn: Oidn,
    pub spp: u32,
}

/// One method's figures as the script goes.
#[derive(Default)]
struct Track {
    orbit: Vec<f64>,
    material: Option<f64>,
    light: Option<f64>,
    stability: Vec<f64>,
    ms: Vec<f64>,
    /// The last frame of the first rest, for stability.
    last: Option<Vec<Vec3>>,
}

impl Track {
    /// Scores a frame of kind `kind` shown as `colour` against its reference `gold`.
    fn record(
        &mut self,
        kind: Kind,
        colour: Vec<Vec3>,
        gold: &[Vec3],
        (w, h): (u32, u32),
        ms: f64,
    ) {
        self.ms.push(ms);
        let flip = || compare(gold, &colour, w, h, 0.0).flip;
        match kind {
            Kind::Rest { first_rest: true } => {
                if let Some(last) = &self.last {
                    self.stability.push(compare(last, &colour, w, h, 0.0).flip);
                }
            }
            Kind::Rest { first_rest: false } => {}
            Kind::Orbit => self.orbit.push(flip()),
            Kind::MaterialEdit => self.material = Some(flip()),
            Kind::LightEdit => self.light = Some(flip()),
        }
        self.last = matches!(kind, Kind::Rest { first_rest: true }).then_some(colour);
    }

    fn result(self, method: &'static str) -> MethodResult {
        MethodResult {
            method,
            first_frame_flip: self.orbit.first().copied().unwrap_or(f64::NAN),
            orbit_mean_flip: mean(&self.orbit),
            material_edit_flip: self.material.unwrap_or(f64::NAN),
            light_edit_flip: self.light.unwrap_or(f64::NAN),
            stability: mean(&self.stability),
            cpu_ms: median(self.ms),
            orbit_flip: self.orbit,
        }
    }
}

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len().max(1) as f64
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn svgf_keeps_the_rested_samples_through_an_orbit_and_beats_the_papers_filter() {
        let (assets, state) = crate::render::testscenes::cornell_box(96, 72);
        let script = Script { orbit_views: 3, gold_spp: 32, ..Script::full() };
        let methods = [Method::Paper, Method::Svgf];
        let r = run(assets, &state, &script, &methods, Default::default(), None).expect("a run");
        let (paper, svgf) = (&r[0], &r[1]);
        eprintln!("{paper:?}\n{svgf:?}");
        assert_eq!((paper.method, svgf.method), ("paper", "svgf"));
        assert_eq!(svgf.orbit_flip.len(), 3);
        assert!(svgf.first_frame_flip < paper.first_frame_flip, "{svgf:?} against {paper:?}");
        assert!(svgf.orbit_mean_flip < paper.orbit_mean_flip, "{svgf:?} against {paper:?}");
        assert!(svgf.stability < paper.stability, "{svgf:?} against {paper:?}");
    }
}
