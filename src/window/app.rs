//! The winit application: owns the window, its GPU surface and egui, turns input into
//! camera, picking and panel actions, and draws the newest composed frame.
//!
//! It runs on the main thread (winit requires it). Frames arrive through a newest-only
//! slot filled by another thread, which wakes the loop with [`UserEvent::FrameReady`];
//! edits leave through the [`Session`], which never blocks. So neither side waits for the
//! other.

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
use super::edits::{EditQueue, SceneEdit};
use super::gpu::{Acquired, Gpu};
use super::latest::Latest;
use super::layout::{self, Rect};
use super::manipulate::{self, Nudge};
use super::panel::{self, PanelAction, PanelModel, PanelSettings};
use super::record::Recorder;
use super::status::{FpsMeter, LatencyMeter, StatusView};
use super::{Composed, Session, UserEvent, WindowOptions};

/// Environment variable naming a file the window writes its panel layout to (tests).
pub const PANEL_PROBE_ENV: &str = "GRIDLIGHT_PANEL_PROBE";

/// Pixels the mouse may move between press and release and still count as a click.
const CLICK_SLOP: f32 = 4.0;

/// Fraction of the camera's distance to its target that one nudge key moves an object.
const NUDGE_FRACTION: f32 = 0.02;

/// The mouse gesture in progress.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Gesture {
    None,
    /// Button down, not yet far enough to be a drag: a click on release.
    Pressed {
        at: Vec2,
        button: MouseButton,
    },
    /// Dragging the camera.
    Camera {
        last: Vec2,
    },
    /// Dragging the selected object.
    Object {
        object: u32,
        last: Vec2,
    },
}

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
    session: Box<dyn Session>,
    frames: Arc<Latest<Composed>>,
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
    shown: Option<Composed>,
    /// Where the picture was drawn last, in physical pixels.
    picture_rect: Option<Rect>,
    message: String,
    /// Set when the window must close (closed by the user, or the session ended).
    closing: bool,
}

impl App {
    /// An application that shows frames from `frames` and sends edits to `session`.
    pub fn new(
        options: WindowOptions,
        session: Box<dyn Session>,
        frames: Arc<Latest<Composed>>,
    ) -> Self {
        let scene = session.initial_state();
        let settings = PanelSettings {
            view: options.view,
            camera_mode: Default::default(),
            pacing: session.pacing(),
            shot_format: Default::default(),
            recording: options.record,
        };
        let mut recorder = Recorder::default();
        recorder.set_recording(options.record, Instant::now());
        Self {
            controller: CameraController::new(scene.camera),
            scene,
            options,
            session,
            frames,
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
        let blit = BlitPass::new(&gpu.device, gpu.config.format);
        let egui_state = egui_winit::State::new(
            self.egui.clone(),
            egui::ViewportId::ROOT,
            &window,
            Some(window.scale_factor() as f32),
            None,
            Some(gpu.device.limits().max_texture_dimension_2d as usize),
        );
        let egui_renderer =
            egui_wgpu::Renderer::new(&gpu.device, gpu.config.format, Default::default());
        self.status.adapter = format!("{} ({:?})", gpu.adapter_info.name, gpu.adapter_info.backend);
        self.surface = Some(Surface { window, gpu, blit, egui_state, egui_renderer });
        Ok(())
    }

    fn close(&mut self, event_loop: &ActiveEventLoop) {
        if !self.closing {
            tracing::info!("window closing: stopping the master and local workers");
            self.closing = true;
            self.frames.close();
            self.session.shutdown();
        }
        event_loop.exit();
    }

    /// Queues an edit and applies it to the window's copy of the state.
    fn edit(&mut self, edit: SceneEdit) {
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

    /// The render pixel under window position `p`, if the picture is there.
    fn picture_pixel(&self, p: Vec2) -> Option<Vec2> {
        let res = self.scene.resolution;
        layout::window_to_picture(self.picture_rect?, res.width, res.height, p)
    }

    /// Scale from window pixels to render pixels.
    fn picture_scale(&self) -> f32 {
        match self.picture_rect {
            Some(r) if r.height > 0.0 => self.scene.resolution.height as f32 / r.height,
            _ => 1.0,
        }
    }

    fn on_press(&mut self, button: MouseButton) {
        if self.picture_pixel(self.cursor).is_some() {
            self.gesture = Gesture::Pressed { at: self.cursor, button };
        }
    }

    fn on_release(&mut self) {
        if let Gesture::Pressed { at, button: MouseButton::Left } = self.gesture {
            // A click: pick what is under the mouse (the shown frame's scene).
            if let Some(px) = self.picture_pixel(at) {
                self.selected = self.session.pick(px.x, px.y);
                self.message = match self.selected.and_then(|i| self.scene.objects.get(i as usize))
                {
                    Some(o) => format!("selected {}", o.name),
                    None => "nothing there to select".into(),
                };
            }
        }
        self.gesture = Gesture::None;
    }

    fn on_cursor(&mut self, p: Vec2) {
        self.cursor = p;
        match self.gesture {
            Gesture::Pressed { at, button } if (p - at).length() > CLICK_SLOP => {
                // Dragging with the left button from the selected object moves it.
                let over_selected = button == MouseButton::Left
                    && self.selected.is_some()
                    && self.picture_pixel(at).and_then(|px| self.session.pick(px.x, px.y))
                        == self.selected;
                self.gesture = match (over_selected, self.selected) {
                    (true, Some(object)) => Gesture::Object { object, last: at },
                    _ => Gesture::Camera { last: at },
                };
                self.on_cursor(p);
            }
            Gesture::Camera { last } => {
                let d = p - last;
                let camera = self.controller.drag(&self.scene.camera, d.x, d.y);
                self.edit(SceneEdit::Camera(camera));
                self.gesture = Gesture::Camera { last: p };
            }
            Gesture::Object { object, last } => {
                let d = (p - last) * self.picture_scale();
                if let Some(o) = self.scene.objects.get(object as usize) {
                    let offset = manipulate::drag_offset(
                        &self.scene.camera,
                        o.transform.translation,
                        d.x,
                        d.y,
                        self.scene.resolution.height,
                    );
                    let transform = manipulate::moved(o.transform, offset);
                    self.edit(SceneEdit::ObjectTransform { object, transform });
                }
                self.gesture = Gesture::Object { object, last: p };
            }
            _ => {}
        }
    }

    fn on_key(&mut self, code: KeyCode, pressed: bool) {
        let keys = &mut self.keys;
        match code {
            KeyCode::KeyW => keys.forward = pressed,
            KeyCode::KeyS => keys.back = pressed,
            KeyCode::KeyA => keys.left = pressed,
            KeyCode::KeyD => keys.right = pressed,
            KeyCode::KeyE => keys.up = pressed,
            KeyCode::KeyQ => keys.down = pressed,
            _ if !pressed => {}
            KeyCode::KeyR => self.edit(SceneEdit::Camera(self.controller.reset())),
            KeyCode::F12 | KeyCode::KeyP => self.screenshot(),
            KeyCode::Escape => self.selected = None,
            KeyCode::Digit1
            | KeyCode::Digit2
            | KeyCode::Digit3
            | KeyCode::Digit4
            | KeyCode::Digit5
            | KeyCode::Digit6 => {
                let i = match code {
                    KeyCode::Digit1 => 0,
                    KeyCode::Digit2 => 1,
                    KeyCode::Digit3 => 2,
                    KeyCode::Digit4 => 3,
                    KeyCode::Digit5 => 4,
                    _ => 5,
                };
                self.settings.view = crate::view::View::ALL[i];
            }
            KeyCode::ArrowLeft => self.nudge(Nudge::Left),
            KeyCode::ArrowRight => self.nudge(Nudge::Right),
            KeyCode::ArrowUp => self.nudge(Nudge::Away),
            KeyCode::ArrowDown => self.nudge(Nudge::Towards),
            KeyCode::PageUp => self.nudge(Nudge::Up),
            KeyCode::PageDown => self.nudge(Nudge::Down),
            _ => {}
        }
        self.last_move = Instant::now();
    }

    fn nudge(&mut self, nudge: Nudge) {
        let Some(object) = self.selected else { return };
        let Some(o) = self.scene.objects.get(object as usize) else { return };
        let cam = &self.scene.camera;
        let step = (cam.look_at - cam.position).length() * NUDGE_FRACTION;
        let transform = manipulate::moved(o.transform, manipulate::nudge_offset(cam, nudge, step));
        self.edit(SceneEdit::ObjectTransform { object, transform });
    }

    fn screenshot(&mut self) {
        self.message = match &self.shown {
            Some(shown) => match super::screenshot::save(
                &self.options.shot_dir,
                shown,
                self.settings.shot_format,
            ) {
                Ok(path) => format!("wrote {}", path.display()),
                Err(err) => format!("screenshot failed: {err}"),
            },
            None => "no frame to save yet".into(),
        };
        tracing::info!(message = %self.message, "screenshot");
    }

    fn apply_actions(&mut self, actions: Vec<PanelAction>) {
        for action in actions {
            match action {
                PanelAction::Edit(edit) => self.edit(edit),
                PanelAction::Pacing(pacing) => self.session.set_pacing(pacing),
                PanelAction::ResetCamera => self.edit(SceneEdit::Camera(self.controller.reset())),
                PanelAction::Deselect => self.selected = None,
                PanelAction::Screenshot => self.screenshot(),
                PanelAction::SaveScript => {
                    self.message = match self.session.save_script(self.recorder.entries()) {
                        Ok(path) => format!("wrote {}", path.display()),
                        Err(err) => format!("saving the script failed: {err}"),
                    }
                }
            }
        }
        self.recorder.set_recording(self.settings.recording, Instant::now());
    }

    /// Writes the panel's layout to `$GRIDLIGHT_PANEL_PROBE` (JSON) when set: how the
    /// window tests check that every section can be reached and nothing is cut off,
    /// at whatever size the window got.
    fn probe_panel(&self, layout: panel::PanelLayout, s: &Surface) {
        let Some(path) = std::env::var_os(PANEL_PROBE_ENV) else { return };
        let size = s.window.inner_size();
        let probe = serde_json::json!({
            "window": [size.width, size.height],
            "last_section_visible": layout.last_section_visible(),
            "clipped_horizontally": layout.clipped_horizontally(),
            "layout": layout,
        });
        // Written whole, then renamed, so a reader never sees half a file.
        let tmp = std::path::PathBuf::from(&path).with_extension("tmp");
        if std::fs::write(&tmp, probe.to_string())
            .and_then(|()| std::fs::rename(&tmp, &path))
            .is_err()
        {
            tracing::warn!("cannot write the panel probe");
        }
    }

    /// Fly movement for the time since the last step, while movement keys are held.
    fn fly_step(&mut self) {
        let now = Instant::now();
        let dt = now.duration_since(self.last_move).as_secs_f32().min(0.1);
        self.last_move = now;
        if self.keys.any() {
            let camera = self.controller.fly(&self.scene.camera, self.keys, dt);
            self.edit(SceneEdit::Camera(camera));
        }
    }

    fn redraw(&mut self) {
        self.fly_step();
        let now = Instant::now();
        for (edit, at) in self.edits.drain() {
            self.recorder.record(&edit, now);
            self.session.edit(edit, at);
        }
        self.session.set_view(self.settings.view);
        if let Some(frame) = self.frames.take() {
            let now = Instant::now();
            self.fps.tick(now);
            // The edits this frame shows first (with those of frames replaced before the
            // window took one) end their latency when it is presented (`draw`).
            self.edits_unpresented.extend_from_slice(&frame.status.edits_at);
            self.status = StatusView {
                fps: self.fps.fps(),
                frames_replaced: self.frames.replaced(),
                adapter: std::mem::take(&mut self.status.adapter),
                edit_latency_ms: self.latency.summary(),
                ..frame.status.clone()
            };
            if let Some(s) = &mut self.surface {
                s.blit.upload(&s.gpu.device, &s.gpu.queue, &frame.picture);
            }
            self.shown = Some(frame);
        }
        self.session.refresh_status(&mut self.status);
        let Some(mut s) = self.surface.take() else { return };
        let actions = self.draw(&mut s);
        self.surface = Some(s);
        self.apply_actions(actions);
        if self.keys.any() || !self.edits.is_empty() {
            self.request_redraw();
        }
    }

    /// The picture of the newest frame was just presented: the edit-to-display latency of
    /// the edits it shows first ends now (a headless master's ends when it composed the
    /// frame: there is nothing more to present).
    fn end_edit_latencies(&mut self) {
        if self.edits_unpresented.is_empty() {
            return;
        }
        let now = Instant::now();
        for at in self.edits_unpresented.drain(..) {
            self.latency.record(now.saturating_duration_since(at).as_secs_f32() * 1e3);
        }
        self.status.edit_latency_ms = self.latency.summary();
    }

    fn draw(&mut self, s: &mut Surface) -> Vec<PanelAction> {
        let raw_input = s.egui_state.take_egui_input(&s.window);
        let mut actions = Vec::new();
        let model = PanelModel {
            scene: &self.scene,
            selected: self.selected,
            status: &self.status,
            environment_maps: &self.options.environment_maps,
            recorded: self.recorder.entries().len(),
            message: &self.message,
        };
        let settings = &mut self.settings;
        let mut panel_layout = panel::PanelLayout::default();
        let output = self.egui.run_ui(raw_input, |ui| {
            (actions, panel_layout) = panel::show(ui, &model, settings);
        });
        self.probe_panel(panel_layout, s);
        s.egui_state.handle_platform_output(&s.window, output.platform_output);
        let ppp = output.pixels_per_point;
        let (width, height) = (s.gpu.config.width, s.gpu.config.height);
        // The panel has a fixed width; the picture gets the rest of the window.
        let picture_width = (width as f32 - panel::PANEL_WIDTH * ppp).max(0.0);
        let area = Rect { x: 0.0, y: 0.0, width: picture_width, height: height as f32 };
        let res = self.scene.resolution;
        self.picture_rect = layout::fit(area, res.width, res.height);

        // egui's texture changes must be applied even when this frame is not drawn.
        for (id, deltas) in &output.textures_delta.set {
            for delta in deltas {
                s.egui_renderer.update_texture(&s.gpu.device, &s.gpu.queue, *id, delta);
            }
        }
        let mut textures_delta = output.textures_delta;
        textures_delta.set.clear();
        let free = std::mem::take(&mut textures_delta.free);
        let Acquired::Frame(frame) = s.gpu.acquire() else {
            free.iter().for_each(|id| s.egui_renderer.free_texture(id));
            self.request_redraw();
            return actions;
        };
        let view = frame.texture.create_view(&wgpu::TextureViewDescriptor::default());
        let paint_jobs = self.egui.tessellate(output.shapes, ppp);
        let screen =
            egui_wgpu::ScreenDescriptor { size_in_pixels: [width, height], pixels_per_point: ppp };
        let mut encoder = s
            .gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("window") });
        let extra = s.egui_renderer.update_buffers(
            &s.gpu.device,
            &s.gpu.queue,
            &mut encoder,
            &paint_jobs,
            &screen,
        );
        {
            let mut pass = encoder
                .begin_render_pass(&wgpu::RenderPassDescriptor {
                    label: Some("window"),
                    color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                        view: &view,
                        resolve_target: None,
                        ops: wgpu::Operations {
                            load: wgpu::LoadOp::Clear(wgpu::Color {
                                r: 0.02,
                                g: 0.02,
                                b: 0.02,
                                a: 1.0,
                            }),
                            store: wgpu::StoreOp::Store,
                        },
                        depth_slice: None,
                    })],
                    depth_stencil_attachment: None,
                    timestamp_writes: None,
                    occlusion_query_set: None,
                    multiview_mask: None,
                })
                .forget_lifetime();
            if let Some(rect) = self.picture_rect {
                s.blit.encode(&mut pass, rect);
            }
            pass.set_viewport(0.0, 0.0, width as f32, height as f32, 0.0, 1.0);
            s.egui_renderer.render(&mut pass, &paint_jobs, &screen);
        }
        s.gpu.queue.submit(extra.into_iter().chain([encoder.finish()]));
        s.window.pre_present_notify();
        s.gpu.queue.present(frame);
        self.end_edit_latencies();
        free.iter().for_each(|id| s.egui_renderer.free_texture(id));
        let repaint_soon = output
            .viewport_output
            .get(&egui::ViewportId::ROOT)
            .is_some_and(|v| v.repaint_delay < Duration::from_millis(100));
        if repaint_soon {
            s.window.request_redraw();
        }
        actions
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
                self.edit(SceneEdit::Camera(camera));
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
