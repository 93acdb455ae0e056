//! Drawing the window: the newest composed frame, the panel and status, and what the
//! panel asks for (actions, screenshots, the layout probe of the tests).

// The application's imports and types (a split of one file, not a separate concern).
use super::*;

impl App {
    pub(super) fn screenshot(&mut self) {
        let saved = self.shown.as_ref().map(|shown| {
            let (picture, linear) = shown.image.to_host()?;
            let shot = crate::window::screenshot::Shot {
                frame: shown.status.frame,
                picture: &picture,
                linear: linear.as_deref().map(Vec::as_slice),
            };
            crate::window::screenshot::save(
                &self.options.shot_dir,
                &shot,
                self.settings.shot_format,
            )
            .map_err(|e| e.to_string())
        });
        self.message = match saved {
            Some(Ok(path)) => format!("wrote {}", path.display()),
            Some(Err(err)) => format!("screenshot failed: {err}"),
            None => "no frame to save yet".into(),
        };
        tracing::info!(message = %self.message, "screenshot");
    }

    pub(super) fn apply_actions(&mut self, actions: Vec<PanelAction>) {
        for action in actions {
            match action {
                PanelAction::Edit(edit) => self.edit(edit),
                PanelAction::Pacing(pacing) => self.master.set_pacing(pacing),
                PanelAction::ResetCamera => self.edit(WindowEdit::Camera(self.controller.reset())),
                PanelAction::Deselect => self.selected = None,
                PanelAction::Screenshot => self.screenshot(),
                PanelAction::SaveScript => {
                    self.message = match self.master.save_script(self.recorder.entries()) {
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
    pub(super) fn probe_panel(&self, layout: panel::PanelLayout, s: &Surface) {
        let Some(path) = std::env::var_os(PANEL_PROBE_ENV) else { return };
        let size = s.window.inner_size();
        let picture = self.picture_rect.map(|r| [r.x, r.y, r.width, r.height]);
        let probe = serde_json::json!({
            "window": [size.width, size.height],
            "picture": picture,
            "display": {
                "frame": self.status.frame,
                "reconstructor": self.status.reconstructor,
                "frames_read_back": self.status.frames_read_back,
                "picture_uploads": self.status.picture_uploads,
                "device_frames": self.status.device_frames,
            },
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

    pub(super) fn redraw(&mut self) {
        self.fly_step();
        let now = Instant::now();
        for (edit, at) in self.edits.drain() {
            self.recorder.record(&edit, now);
            self.master.edit(edit, at);
        }
        self.master.set_view(self.settings.view);
        self.master.set_method(self.settings.method);
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
                s.blit.show(&s.gpu.ctx.device, &s.gpu.ctx.queue, &frame.image);
                let counts = s.blit.counts();
                self.status.picture_uploads = counts.uploads;
                self.status.device_frames = counts.device_frames;
            }
            self.shown = Some(frame);
        }
        self.master.refresh_status(&mut self.status);
        let Some(mut s) = self.surface.take() else { return };
        let actions = self.draw(&mut s);
        self.surface = Some(s);
        self.apply_actions(actions);
        if self.keys.any() || !self.edits.is_empty() {
            self.request_redraw();
        }
    }

    /// Under `--resolution window`, asks for the picture area's size once it has settled;
    /// true while a size waits to settle (the window must draw again to ask for it).
    fn follow_window(&mut self, area: Rect) -> bool {
        let Some(follow) = &mut self.follow else { return false };
        let current = self.scene.resolution;
        if let Some(size) = follow.observe(area.width, area.height, current, Instant::now()) {
            tracing::info!(
                width = size.width,
                height = size.height,
                "render size follows the window"
            );
            self.edit(WindowEdit::Resolution(size));
        }
        self.follow.as_ref().is_some_and(FollowWindow::is_pending)
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

    pub(super) fn draw(&mut self, s: &mut Surface) -> Vec<PanelAction> {
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
        if self.follow_window(area) {
            s.window.request_redraw();
        }
        let res = self.scene.resolution;
        self.picture_rect = layout::fit(area, res.width, res.height);

        // egui's texture changes must be applied even when this frame is not drawn.
        for (id, deltas) in &output.textures_delta.set {
            for delta in deltas {
                s.egui_renderer.update_texture(&s.gpu.ctx.device, &s.gpu.ctx.queue, *id, delta);
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
        let (device, queue) = (&s.gpu.ctx.device, &s.gpu.ctx.queue);
        let mut encoder = device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("window") });
        let extra =
            s.egui_renderer.update_buffers(device, queue, &mut encoder, &paint_jobs, &screen);
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
        queue.submit(extra.into_iter().chain([encoder.finish()]));
        s.window.pre_present_notify();
        queue.present(frame);
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
