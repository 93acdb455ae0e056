//! The winit application: owns the window, its GPU surface and egui, turns input into
//! camera, picking and panel actions, and draws the newest composed frame.
//!
//! It runs on the main thread (winit requires it). Frames arrive through a newest-only
//! slot filled by another thread, which wakes the loop with [`UserEvent::FrameReady`];
//! edits leave through the [`MasterControl`], which never blocks. So neither side waits for the
//! other.
//!
//! Files: this one (the application's state and winit's callbacks), `input.rs` (gestures
//! and keys), `draw.rs` (drawing and panel actions).

use std::sync::Arc;
use std::time::{Duration, Instant};

use glam::Vec2;
use winit::application::ApplicationHandler;
use winit::dpi::PhysicalSize;
use winit::event::{ElementState, MouseButton, MouseScrollDelta, WindowEvent};
use winit::event_loop::{ActiveEventLoop, ControlFlow};
use winit::keyboard::{KeyCode, PhysicalKey};
use winit::window::{Window, WindowId};

use super::blit::BlitPass;
use super::camera::{CameraController, MoveKeys};
use super::edits::{EditQueue, WindowEdit};
use super::follow::FollowWindow;
use super::gpu::{Acquired, Gpu};
use super::latest::Latest;
use super::layout::{self, Rect};
use super::manipulate::{self, Nudge};
use super::panel::{self, PanelAction, PanelModel, PanelSettings};
use super::record::Recorder;
use super::status::{FpsMeter, LatencyMeter, StatusView};
use super::{MasterControl, ReadyFrame, UserEvent, WindowOptions};
use crate::gpu::DeviceOffer;

mod draw;
mod input;

use input::Gesture;

/// Environment variable naming a file the window writes its panel layout to (tests).
pub const PANEL_PROBE_ENV: &str = "GRIDLIGHT_PANEL_PROBE";

/// Everything created once the window exists.
struct Surface {
    window: Arc<Window>,
    gpu: Gpu,
    blit: BlitPass,
    egui_state: egui_winit::State,
    egui_renderer: egui_wgpu::Renderer,
}

/// The window application.
pub struct App {
    options: WindowOptions,
    master: Box<dyn MasterControl>,
    frames: Arc<Latest<ReadyFrame>>,
    /// Where the window offers its device to the compose thread.
    offer: DeviceOffer,
    surface: Option<Surface>,
    egui: egui::Context,
    /// The window's copy of the scene state, edits applied at once.
    scene: gridlight_actors::state::SceneState,
    controller: CameraController,
    keys: MoveKeys,
    last_move: Instant,
    gesture: Gesture,
    cursor: Vec2,
    selected: Option<u32>,
    edits: EditQueue,
    recorder: Recorder,
    settings: PanelSettings,
    status: StatusView,
    fps: FpsMeter,
    latency: LatencyMeter,
    /// Edits of frames taken but not yet presented: their latency ends at the present.
    edits_unpresented: Vec<Instant>,
    /// The newest composed frame, kept for redraws, screenshots and picking.
    shown: Option<ReadyFrame>,
    /// Where the picture was drawn last, in physical pixels.
    picture_rect: Option<Rect>,
    message: String,
    /// `--resolution window`: the render size follows the picture area.
    follow: Option<FollowWindow>,
    /// Set when the window must close (closed by the user, or the master stopped).
    closing: bool,
}

impl App {
    /// An application that shows frames from `frames` and sends edits to `master`.
    pub fn new(
        options: WindowOptions,
        master: Box<dyn MasterControl>,
        frames: Arc<Latest<ReadyFrame>>,
        offer: DeviceOffer,
    ) -> Self {
        let scene = master.initial_state();
        let settings = PanelSettings {
            view: options.view,
            method: master.method(),
            camera_mode: Default::default(),
            pacing: master.pacing(),
            shot_format: Default::default(),
            recording: options.record,
        };
        let follow = options.follow_window.map(FollowWindow::new);
        let mut recorder = Recorder::default();
        recorder.set_recording(options.record, Instant::now());
        Self {
            controller: CameraController::new(scene.camera),
            scene,
            options,
            master,
            frames,
            offer,
            surface: None,
            egui: egui::Context::default(),
            keys: MoveKeys::default(),
            last_move: Instant::now(),
            gesture: Gesture::None,
            cursor: Vec2::ZERO,
            selected: None,
            edits: EditQueue::default(),
            recorder,
            settings,
            status: StatusView::default(),
            fps: FpsMeter::new(Duration::from_secs(2)),
            latency: LatencyMeter::default(),
            edits_unpresented: Vec::new(),
            shown: None,
            picture_rect: None,
            message: String::new(),
            follow,
            closing: false,
        }
    }

    fn create_surface(&mut self, event_loop: &ActiveEventLoop) -> Result<(), String> {
        let res = self.scene.resolution;
        let monitor =
            event_loop.primary_monitor().or_else(|| event_loop.available_monitors().next());
        let scale = monitor.as_ref().map_or(1.0, |m| m.scale_factor()) as f32;
        let screen = monitor.map(|m| (m.size().width, m.size().height));
        let (width, height) = layout::initial_window_size(
            (res.width, res.height),
            (panel::PANEL_WIDTH * scale) as u32,
            screen,
        );
        let attributes = Window::default_attributes()
            .with_title(self.options.title.clone())
            .with_inner_size(PhysicalSize::new(width, height));
        let window = Arc::new(
            event_loop
                .create_window(attributes)
                .map_err(|e| format!("cannot open a window: {e}"))?,
        );
        let gpu = Gpu::new(Arc::clone(&window)).map_err(|e| e.to_string())?;
        // The compose thread reconstructs on this device from the first frame on.
        if gpu.reconstructs {
            self.offer.offer(Arc::clone(&gpu.ctx));
        } else {
            self.offer.withdraw();
        }
        let device = &gpu.ctx.device;
        let blit = BlitPass::new(device, gpu.config.format);
        let egui_state = egui_winit::State::new(
            self.egui.clone(),
            egui::ViewportId::ROOT,
            &window,
            Some(window.scale_factor() as f32),
            None,
            Some(device.limits().max_texture_dimension_2d as usize),
        );
        let egui_renderer = egui_wgpu::Renderer::new(device, gpu.config.format, Default::default());
        let info = &gpu.ctx.adapter_info;
        self.status.adapter = format!("{} ({:?})", info.name, info.backend);
        self.surface = Some(Surface { window, gpu, blit, egui_state, egui_renderer });
        Ok(())
    }

    fn close(&mut self, event_loop: &ActiveEventLoop) {
        if !self.closing {
            tracing::info!("window closing: stopping the master and local workers");
            self.closing = true;
            self.offer.withdraw();
            self.frames.close();
            self.master.shutdown();
        }
        event_loop.exit();
    }

    /// Queues an edit and applies it to the window's copy of the state.
    fn edit(&mut self, edit: WindowEdit) {
        match edit.apply(&mut self.scene) {
            Ok(()) => self.edits.push(edit, Instant::now()),
            Err(err) => tracing::warn!(cause = %err, "edit ignored"),
        }
    }

    fn request_redraw(&self) {
        if let Some(s) = &self.surface {
            s.window.request_redraw();
        }
    }
}

impl ApplicationHandler<UserEvent> for App {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.surface.is_some() {
            return;
        }
        if let Err(err) = self.create_surface(event_loop) {
            tracing::error!(cause = %err, "the window cannot be shown");
            self.close(event_loop);
        }
    }

    fn user_event(&mut self, event_loop: &ActiveEventLoop, event: UserEvent) {
        match event {
            UserEvent::FrameReady => self.request_redraw(),
            UserEvent::Quit => self.close(event_loop),
        }
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        let consumed = match &mut self.surface {
            Some(s) => s.egui_state.on_window_event(&s.window, &event).consumed,
            None => false,
        };
        match event {
            WindowEvent::CloseRequested | WindowEvent::Destroyed => self.close(event_loop),
            WindowEvent::Resized(size) => {
                if let Some(s) = &mut self.surface {
                    s.gpu.resize(size.width, size.height);
                }
                self.request_redraw();
            }
            WindowEvent::RedrawRequested => self.redraw(),
            WindowEvent::CursorMoved { position, .. } => {
                self.on_cursor(Vec2::new(position.x as f32, position.y as f32));
                self.request_redraw();
            }
            WindowEvent::MouseInput { state, button, .. } => {
                match state {
                    ElementState::Pressed if !consumed && !self.egui.egui_wants_pointer_input() => {
                        self.on_press(button)
                    }
                    ElementState::Released => self.on_release(),
                    _ => {}
                }
                self.request_redraw();
            }
            WindowEvent::MouseWheel { delta, .. }
                if !consumed && self.picture_pixel(self.cursor).is_some() =>
            {
                let notches = match delta {
                    MouseScrollDelta::LineDelta(_, y) => y,
                    MouseScrollDelta::PixelDelta(p) => p.y as f32 / 40.0,
                };
                let camera = self.controller.wheel(&self.scene.camera, notches);
                self.edit(WindowEdit::Camera(camera));
                self.request_redraw();
            }
            WindowEvent::KeyboardInput { event, .. } => {
                let wants_keys = consumed || self.egui.egui_wants_keyboard_input();
                if let PhysicalKey::Code(code) = event.physical_key {
                    // Releases always go through so that held movement keys never stick.
                    if !wants_keys || event.state == ElementState::Released {
                        self.on_key(code, event.state == ElementState::Pressed);
                    }
                }
                self.request_redraw();
            }
            _ => {
                if consumed {
                    self.request_redraw();
                }
            }
        }
        self.controller.mode = self.settings.camera_mode;
    }

    fn about_to_wait(&mut self, event_loop: &ActiveEventLoop) {
        event_loop.set_control_flow(ControlFlow::Wait);
    }
}
