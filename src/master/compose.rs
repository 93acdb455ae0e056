//! Turning a shown frame into pixels: the G-buffer of its scene state, reconstruction, and
//! the [`View`] asked for.
//!
//! G-buffers come from the wgpu raster pass on a hardware adapter and from primary rays on
//! the CPU otherwise ([`GBufferSource`]); reconstruction likewise (`--reconstruct`).
//!
//! Workers send reflected radiance (not demodulated); the composer divides it by the
//! frame's G-buffer albedo before reconstruction, which multiplies the same albedo back in,
//! so wherever no filter moves light between pixels (a converged static view) the master's
//! image is exactly the workers' mean colour. (Workers used to demodulate every sample by
//! its own primary hit: remodulated by the pixel centre's albedo, each pixel on an edge
//! between two albedos a and b came out brighter, a/b + b/a > 2, and the Cornell box
//! 0.7–1.0 % brighter than `gridlight render`; `tests/master_matches_render.rs`.)
//!
//! One composer serves both the headless sink and the window, so that what a headless
//! master writes is exactly what the window shows. A window composer is given the
//! window's device ([`Composer::with_window_device`]): GPU reconstruction then runs on it
//! and the final view stays there ([`Image::Device`]) for the window to draw, with no
//! read-back; the diagnostic views are made on the CPU from the frame's planes. Every frame is reconstructed, whatever
//! the view, so that the temporal history and the accumulation stay complete when the user
//! switches back to the final view.

use std::mem::take;
use std::sync::{Arc, RwLock};
use std::time::Instant;

use glam::Vec3;
use gridlight_actors::sink::{Preparer, ShownFrame};
use gridlight_actors::state::{SceneState, StateVersion};
use rayon::prelude::*;
use thiserror::Error;

use crate::assets::Assets;
use crate::gbuffer::ahead::GBufferAhead;
use crate::gbuffer::emission::area_mean_emission;
use crate::gbuffer::{GBuffer, GBufferError, GBufferSource};
use crate::gpu::{Backend, DeviceOffer};
use crate::master::view::{self, View, ViewInputs};
use crate::reconstruct::{
    DeviceImage, ForDisplay, FrameInputs, Method, ReconstructError, ReconstructParams,
    Reconstructed, Reconstructor,
};

/// The G-buffers of a run's frames, shared with whoever picks objects in the shown frame's
/// scene (the window): picking reads the same render scene the G-buffer was made from.
pub type SharedScene = Arc<RwLock<GBufferSource>>;

/// Why a frame could not be composed.
#[derive(Debug, Error)]
pub enum ComposeError {
    #[error(transparent)]
    GBuffer(#[from] GBufferError),
    #[error("reconstruction: {0}")]
    Reconstruct(#[from] ReconstructError),
    #[error("the frame's planes do not match its {width}×{height} resolution")]
    Size { width: u32, height: u32 },
    #[error("cannot start the G-buffer thread: {0}")]
    Thread(std::io::Error),
}

/// How long a window composer waits for the window to offer its device (it opens it as
/// the window appears, normally well before the first frame).
const WINDOW_DEVICE_WAIT: std::time::Duration = std::time::Duration::from_secs(30);

/// One composed frame.
#[derive(Clone, Debug)]
pub struct Composed {
    pub width: u32,
    pub height: u32,
    pub image: Image,
    /// Where the compose time went (written to `stats.jsonl`).
    pub timings: ComposeTimings,
}

/// The pixels of a composed frame.
#[derive(Clone, Debug)]
pub enum Image {
    /// On the CPU.
    Host {
        /// The chosen view, display-encoded RGBA (tonemapped sRGB for colour views).
        rgba: Vec<[u8; 4]>,
        /// Final linear colour (albedo · radiance + emission), only for the final view.
        linear: Option<Vec<Vec3>>,
    },
    /// The final view, left on the window's device by the GPU reconstruction.
    Device(DeviceImage),
}

/// A composed frame's pixels on the CPU: display RGBA, and the linear colour for the final
/// view.
pub type HostPixels = (Vec<[u8; 4]>, Option<Vec<Vec3>>);

impl Image {
    /// The pixels on the CPU (an [`Image::Device`] is read back).
    pub fn into_host(self) -> Result<HostPixels, ComposeError> {
        match self {
            Image::Host { rgba, linear } => Ok((rgba, linear)),
            Image::Device(image) => {
                let (rgba, linear) = image.read_back().map_err(ReconstructError::from)?;
                Ok((rgba, Some(linear)))
            }
        }
    }
}

/// Milliseconds each step of one compose took: what the edit-to-display latency spends on
/// the master after the display decided to show a frame.
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct ComposeTimings {
    /// Getting the frame's G-buffer (0 when it was ready: cached or prepared).
    pub gbuffer_ms: f64,
    /// Demodulation and reconstruction.
    pub reconstruct_ms: f64,
    /// The whole compose, the chosen view included.
    pub compose_ms: f64,
}

/// G-buffer, reconstruction and views for a run's shown frames.
pub struct Composer {
    assets: Arc<Assets>,
    gbuffers: SharedScene,
    /// New states' G-buffers computed ahead, once [`Composer::preparer`] was asked for.
    ahead: Option<GBufferAhead>,
    /// Whether a frame sink asks for [`Composer::preparer`] (`--gbuffer-ahead`).
    ahead_for_sink: bool,
    params: ReconstructParams,
    backend: Backend,
    /// The reconstructor and the frame size it was made for: a new size (a resized
    /// window) starts a new one, its history dropped.
    reconstructor: Option<(Reconstructor, (u32, u32))>,
    /// The shown frame's radiance divided by the G-buffer albedo (reused between frames).
    demodulated: Vec<Vec3>,
    /// The CPU reconstruction's output, whose buffers that stay on the master are reused.
    reconstructed: Reconstructed,
    /// The G-buffer of the state being accumulated, its emission as pixel area means.
    converging: Option<(StateVersion, Arc<GBuffer>)>,
    /// The window's device, once offered ([`Composer::with_window_device`]).
    window_device: Option<DeviceOffer>,
    /// The device the final view is left on: the window's, when the reconstruction runs
    /// there.
    display_device: Option<wgpu::Device>,
}

impl Composer {
    /// A composer for frames of scenes over `assets`, starting from `state`.
    pub fn new(
        assets: Arc<Assets>,
        state: &SceneState,
        params: ReconstructParams,
        backend: Backend,
    ) -> Result<Self, ComposeError> {
        params.validate()?;
        let source = GBufferSource::new(Arc::clone(&assets), state, backend)?;
        Ok(Self {
            assets,
            gbuffers: Arc::new(RwLock::new(source)),
            ahead: None,
            ahead_for_sink: false,
            params,
            backend,
            reconstructor: None,
            demodulated: Vec::new(),
            reconstructed: Reconstructed::empty(0),
            converging: None,
            window_device: None,
            display_device: None,
        })
    }

    /// GPU reconstruction (`--reconstruct gpu`, or `auto` on a hardware adapter) runs on
    /// the device the window offers, and the final view stays there for the window to
    /// draw. Without an offer in time, the reconstruction opens its own device and reads
    /// its frames back.
    pub fn with_window_device(mut self, offer: DeviceOffer) -> Self {
        self.window_device = Some(offer);
        self
    }

    /// The reconstruction method of the next frames.
    pub fn method(&self) -> Method {
        self.params.method
    }

    /// Switches the reconstruction method (the window's panel): the next frame starts a new
    /// reconstructor, as one method's history means nothing to the other.
    pub fn set_method(&mut self, method: Method) {
        if method != self.params.method {
            self.params.method = method;
            self.reconstructor = None;
        }
    }

    /// Frames read back from the GPU reconstruction so far.
    pub fn read_backs(&self) -> u64 {
        self.reconstructor.as_ref().map_or(0, |(r, _)| r.read_backs())
    }

    /// The G-buffer source, whose render scene is the last composed frame's (for picking).
    pub fn scene(&self) -> SharedScene {
        Arc::clone(&self.gbuffers)
    }

    /// "cpu" or the GPU adapter's name, once the first frame chose.
    pub fn reconstructor(&self) -> Option<String> {
        self.reconstructor.as_ref().map(|(r, _)| r.describe())
    }

    /// Reconstructs `frame` and makes `view` of it.
    pub fn compose(&mut self, frame: &ShownFrame, view: View) -> Result<Composed, ComposeError> {
        let started = Instant::now();
        let ms = |from: Instant| from.elapsed().as_secs_f64() * 1e3;
        let res = frame.state.resolution;
        let (width, height) = (res.width, res.height);
        let ready = self.ahead.as_ref().and_then(|a| a.take(frame.state.version));
        let g = {
            let mut source = self.gbuffers.write().unwrap_or_else(|p| p.into_inner());
            match ready {
                Some(g) => source.adopt(&frame.state, g)?,
                None => source.get(&frame.state)?,
            }
        };
        let accumulated = frame.stats.accumulated_frames;
        let g = self.for_accumulation(g, frame.state.version, accumulated);
        let mut timings = ComposeTimings { gbuffer_ms: ms(started), ..Default::default() };
        let reconstructing = Instant::now();
        if frame.current.len() != g.albedo.len() {
            return Err(ComposeError::Size { width, height });
        }
        demodulate(&frame.current, &g.albedo, &mut self.demodulated);
        if self.reconstructor.as_ref().is_none_or(|(_, size)| *size != (width, height)) {
            self.reconstructor = None;
            self.reconstructor = Some((self.new_reconstructor(width, height)?, (width, height)));
        }
        let (reconstructor, _) = self.reconstructor.as_mut().expect("made above");
        let inputs = FrameInputs {
            frame: frame.frame,
            state_version: frame.state.version,
            accumulated_frames: accumulated,
            radiance: &self.demodulated,
            mask: &frame.current_mask,
            gbuffer: &g,
            scene: Some(&frame.state),
        };
        let image = match &self.display_device {
            Some(device) => match reconstructor.reconstruct_for_display(&inputs, device)? {
                ForDisplay::Host(out) => {
                    Image::Host { rgba: out.display, linear: Some(out.colour) }
                }
                ForDisplay::Device(image) => Image::Device(image),
            },
            None => {
                let out = &mut self.reconstructed;
                reconstructor.reconstruct_into(&inputs, out)?;
                // The pictures leave with the frame; the radiance's buffer stays for the next.
                let (rgba, linear) = (take(&mut out.display), take(&mut out.colour));
                Image::Host { rgba, linear: Some(linear) }
            }
        };
        timings.reconstruct_ms = ms(reconstructing);
        if view == View::Final {
            timings.compose_ms = ms(started);
            return Ok(Composed { width, height, image, timings });
        }
        let owner = if view == View::Workers {
            frame.owners.per_pixel(frame.current.len())
        } else {
            Vec::new()
        };
        let planes = ViewInputs {
            width,
            height,
            radiance: &self.demodulated,
            mask: &frame.current_mask,
            albedo: &g.albedo,
            emission: &g.emission,
            normal: &g.normal,
            owner: &owner,
        };
        let exposure = self.params.exposure;
        let rgba =
            view::diagnostic(view, &planes, |c| crate::reconstruct::tonemap::to_rgba8(c, exposure))
                .ok_or(ComposeError::Size { width, height })?;
        timings.compose_ms = ms(started);
        Ok(Composed { width, height, image: Image::Host { rgba, linear: None }, timings })
    }

    /// The reconstructor for the first frame: on the window's device when one is offered
    /// and the backend asks for a GPU (the CPU backend never waits for the offer).
    fn new_reconstructor(
        &mut self,
        width: u32,
        height: u32,
    ) -> Result<Reconstructor, ComposeError> {
        let device = match (&self.window_device, self.backend) {
            (None, _) | (Some(_), Backend::Cpu) => None,
            (Some(offer), _) => {
                let device = offer.wait(WINDOW_DEVICE_WAIT);
                if device.is_none() {
                    tracing::warn!("the window offered no device: reconstruction reads back");
                }
                device
            }
        };
        let r = Reconstructor::new(width, height, self.params, self.backend, device.clone())?;
        if let (Reconstructor::Gpu(_), Some(ctx)) = (&r, device) {
            tracing::info!(adapter = %ctx.adapter_info.name, "reconstructing on the window's device");
            self.display_device = Some(ctx.device.clone());
        }
        Ok(r)
    }
}

impl Composer {
    /// Computes the G-buffers of new scene states ahead from now on, on a thread of its
    /// own with a G-buffer source of its own (`crate::gbuffer::ahead`): the master's
    /// display tells the returned preparer each new state as soon as the scene changes.
    pub fn preparer(&mut self) -> Result<Preparer, ComposeError> {
        let current =
            self.gbuffers.read().unwrap_or_else(|p| p.into_inner()).scene().state().clone();
        let source = GBufferSource::new(Arc::clone(&self.assets), &current, self.backend)?;
        let ahead = GBufferAhead::spawn(source).map_err(ComposeError::Thread)?;
        let handle = ahead.handle();
        self.ahead = Some(ahead);
        Ok(Box::new(move |state| handle.want(state)))
    }

    /// Whether the frame sinks compute G-buffers ahead ([`Composer::sink_preparer`]).
    pub fn with_gbuffer_ahead(mut self, on: bool) -> Self {
        self.ahead_for_sink = on;
        self
    }

    /// [`Composer::preparer`] for a frame sink, when asked for (`with_gbuffer_ahead`);
    /// without it, or when the thread cannot start, every G-buffer is computed when its
    /// frame is composed.
    pub fn sink_preparer(&mut self) -> Option<Preparer> {
        if !self.ahead_for_sink {
            return None;
        }
        self.preparer()
            .map_err(|e| tracing::warn!(cause = %e, "G-buffers are not computed ahead"))
            .ok()
    }

    /// From the second frame of a scene state on (accumulation, which converges), the
    /// G-buffer with each pixel's directly seen emission averaged over its area
    /// (`gbuffer::emission`), made once per state; the first frame of a state (while
    /// interacting) keeps the centre's, which costs nothing extra.
    fn for_accumulation(
        &mut self,
        g: Arc<GBuffer>,
        version: StateVersion,
        accumulated_frames: u32,
    ) -> Arc<GBuffer> {
        if accumulated_frames <= 1 {
            return g;
        }
        if let Some((v, converging)) = &self.converging {
            if *v == version {
                return Arc::clone(converging);
            }
        }
        let mut area = (*g).clone();
        let source = self.gbuffers.read().unwrap_or_else(|p| p.into_inner());
        let n = area_mean_emission(&mut area, source.scene());
        tracing::debug!(version, pixels = n, "emission averaged over pixel areas");
        let area = Arc::new(area);
        self.converging = Some((version, Arc::clone(&area)));
        area
    }
}

/// `out[i] = radiance[i] / albedo[i]`: what reconstruction filters (paper §4.3.1). The
/// G-buffer's albedo is clamped away from zero where it comes from; the floor here only
/// keeps a degenerate plane from making infinities.
pub fn demodulate(radiance: &[Vec3], albedo: &[Vec3], out: &mut Vec<Vec3>) {
    const FLOOR: f32 = 1e-6;
    out.clear();
    out.par_extend(radiance.par_iter().zip(albedo).map(|(l, a)| *l / a.max(Vec3::splat(FLOOR))));
}

#[cfg(test)]
mod tests {
    use super::*;
    use gridlight_actors::master::FrameStats;

    fn cornell() -> (Arc<Assets>, SceneState) {
        crate::render::testscenes::cornell_box(16, 12)
    }

    fn frame(state: &SceneState, covered: impl Fn(usize) -> bool) -> ShownFrame {
        let n = state.resolution.pixels();
        let mask: Vec<bool> = (0..n).map(covered).collect();
        let radiance: Vec<Vec3> =
            mask.iter().map(|&m| if m { Vec3::splat(0.5) } else { Vec3::ZERO }).collect();
        ShownFrame {
            frame: 1,
            state: Arc::new(state.clone()),
            current: radiance.clone(),
            current_mask: mask.clone(),
            owners: Default::default(),
            stats: FrameStats { frame: 1, ..FrameStats::default() },
        }
    }

    #[test]
    fn the_final_view_fills_holes_that_the_partial_view_shows() {
        let (assets, state) = cornell();
        let mut c =
            Composer::new(assets, &state, ReconstructParams::default(), Backend::Cpu).unwrap();
        // Every other pixel lost: the final view must cover them from their neighbours.
        let f = frame(&state, |i| i % 2 == 0);
        let g = c.gbuffers.write().unwrap().get(&state).unwrap();
        let (partial, no_linear) = c.compose(&f, View::Partial).unwrap().image.into_host().unwrap();
        let (last, linear) = c.compose(&f, View::Final).unwrap().image.into_host().unwrap();
        assert!(linear.is_some() && no_linear.is_none());
        let hit_holes: Vec<usize> = (0..g.len())
            .filter(|&i| i % 2 == 1 && g.object[i] != crate::gbuffer::NO_OBJECT)
            .collect();
        assert!(hit_holes.len() > 50, "the box's surfaces cover most holes");
        for &i in &hit_holes {
            assert_eq!(partial[i], [0, 0, 0, 255], "pixel {i}: a hole in the partial view");
            assert_ne!(last[i], [0, 0, 0, 255], "pixel {i}: filled in the final view");
        }
    }

    #[test]
    fn a_fully_covered_accumulated_frame_is_the_radiance_sent_plus_emission() {
        // Demodulating by the G-buffer albedo and remodulating by it cancel: the final
        // colour of an accumulating frame with every pixel covered is what workers sent.
        let (assets, state) = cornell();
        let mut c =
            Composer::new(assets, &state, ReconstructParams::default(), Backend::Cpu).unwrap();
        let g = c.gbuffers.write().unwrap().get(&state).unwrap();
        let mut f = frame(&state, |_| true);
        f.current = (0..g.len()).map(|i| Vec3::new(0.1, 0.2, 0.3) * (1 + i % 7) as f32).collect();
        f.stats.accumulated_frames = 1;
        c.compose(&f, View::Final).unwrap(); // the first frame of a state is filtered
        f.frame = 2;
        f.stats.accumulated_frames = 2; // as the frame assembler decides it
        let out = c.compose(&f, View::Final).unwrap().image.into_host().unwrap().1.unwrap();
        // Accumulating: the emission is the pixel-area mean (`gbuffer::emission`).
        let area = Arc::clone(&c.converging.as_ref().expect("an accumulating G-buffer").1);
        for (i, got) in out.iter().enumerate() {
            let want = f.current[i] + area.emission[i];
            let err = (*got - want).abs().max_element();
            assert!(err <= 1e-5 * want.max_element().max(1.0), "pixel {i}: {got} vs {want}");
        }
    }

    #[test]
    fn a_new_frame_size_and_a_method_switch_each_start_a_new_reconstructor() {
        let (assets, state) = cornell();
        let mut c =
            Composer::new(assets, &state, ReconstructParams::default(), Backend::Cpu).unwrap();
        let mut f = frame(&state, |i| i % 3 != 0);
        // Noisy radiance: the two filters smooth it differently (a constant they would not).
        for (i, r) in f.current.iter_mut().enumerate().filter(|(i, _)| i % 3 != 0) {
            *r = Vec3::splat(0.1 + 0.2 * (i * 7 % 5) as f32);
        }
        let paper = c.compose(&f, View::Final).unwrap().image.into_host().unwrap().0;
        // A resized window: the next state has another size, and its frame composes.
        let resized = SceneState {
            resolution: gridlight_actors::state::Resolution { width: 24, height: 10 },
            version: state.version + 1,
            ..state.clone()
        };
        let big = c.compose(&frame(&resized, |_| true), View::Final).unwrap();
        assert_eq!((big.width, big.height, big.image.into_host().unwrap().0.len()), (24, 10, 240));
        // The panel's switch: the same frame through SVGF is filtered differently.
        assert_eq!(c.method(), Method::Paper);
        c.set_method(Method::Svgf);
        assert_eq!(c.method(), Method::Svgf);
        let svgf = c.compose(&f, View::Final).unwrap().image.into_host().unwrap().0;
        assert_eq!(svgf.len(), paper.len());
        assert_ne!(svgf, paper, "svgf's filter is not the paper's");
    }

    #[test]
    fn bad_parameters_are_refused_before_any_frame() {
        let (assets, state) = cornell();
        let params = ReconstructParams { radius: 999, ..ReconstructParams::default() };
        let err = Composer::new(assets, &state, params, Backend::Cpu)
            .err()
            .expect("radius 999 is refused");
        assert!(err.to_string().contains("radius"), "{err}");
    }
}
