//! The side panel (egui): status, view and camera mode, pacing sliders, and editors for
//! the selected object's material, the lights and the environment.
//!
//! The panel draws plain data ([`PanelModel`]) and reports what the user did as
//! [`PanelAction`]s; the app turns those into edits and master messages. Editors work on
//! copies and emit an action only when a value really changed.

use glam::Vec3;
use gridlight_actors::state::{Environment, Light, MaterialKind, SceneState};

use super::camera::CameraMode;
use super::edits::{join_power, split_power, WindowEdit};
use super::status::{human_bytes, StatusView};
use crate::master::view::View;
use crate::reconstruct::Method;
use gridlight_actors::pacing::{Heuristic, Pacing};

/// Pacing of frames as the panel edits it (paper §4.3).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PacingChoice {
    /// The wait heuristic with its four bounds.
    Heuristic { q_min: f32, q_max: f32, i_min: f32, i_max: f32 },
    /// A fixed frame rate.
    FixedFps(f32),
}

impl From<Pacing> for PacingChoice {
    fn from(p: Pacing) -> Self {
        match p {
            Pacing::Heuristic(h) => PacingChoice::Heuristic {
                q_min: h.q_min as f32,
                q_max: h.q_max as f32,
                i_min: h.i_min as f32,
                i_max: h.i_max as f32,
            },
            Pacing::FixedFps(fps) => PacingChoice::FixedFps(fps),
        }
    }
}

impl From<PacingChoice> for Pacing {
    fn from(p: PacingChoice) -> Self {
        match p {
            PacingChoice::Heuristic { q_min, q_max, i_min, i_max } => {
                Pacing::Heuristic(Heuristic {
                    q_min: f64::from(q_min),
                    q_max: f64::from(q_max),
                    i_min: f64::from(i_min),
                    i_max: f64::from(i_max),
                })
            }
            PacingChoice::FixedFps(fps) => Pacing::FixedFps(fps),
        }
    }
}

/// File format of the screenshot key.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ShotFormat {
    /// Tonemapped sRGB, what the window shows.
    #[default]
    Png,
    /// Linear radiance (final colour before tonemapping).
    Exr,
}

/// Panel settings that live as long as the window.
#[derive(Clone, Debug, PartialEq)]
pub struct PanelSettings {
    pub view: View,
    /// The reconstruction of the frames shown.
    pub method: Method,
    pub camera_mode: CameraMode,
    pub pacing: PacingChoice,
    pub shot_format: ShotFormat,
    /// True while the edits are being recorded.
    pub recording: bool,
}

/// What the panel shows this frame.
pub struct PanelModel<'a> {
    /// The window's copy of the scene state (edits already applied).
    pub scene: &'a SceneState,
    /// Index of the picked object.
    pub selected: Option<u32>,
    pub status: &'a StatusView,
    /// Environment maps the scene offers (asset paths).
    pub environment_maps: &'a [String],
    /// Recorded edits so far.
    pub recorded: usize,
    /// A line about the last screenshot or script save, or an error.
    pub message: &'a str,
}

/// Something the user did in the panel.
#[derive(Clone, Debug, PartialEq)]
pub enum PanelAction {
    Edit(WindowEdit),
    Pacing(PacingChoice),
    ResetCamera,
    Deselect,
    Screenshot,
    SaveScript,
}

/// Width of the side panel in logical points.
pub const PANEL_WIDTH: f32 = 300.0;

/// Where the panel's content ended up, for the window's layout checks (see
/// [`super::app`]'s `GRIDLIGHT_PANEL_PROBE`): all in logical points.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct PanelLayout {
    /// The visible part of the scrolled content (the viewport), top and bottom.
    pub viewport_top: f32,
    pub viewport_bottom: f32,
    /// Width available to the content, and the widest the content became.
    pub viewport_width: f32,
    pub content_width: f32,
    /// Height of all the content, and how far it is scrolled.
    pub content_height: f32,
    pub scroll_offset: f32,
    /// The last section's heading, top and bottom (screen coordinates).
    pub last_heading_top: f32,
    pub last_heading_bottom: f32,
}

impl PanelLayout {
    /// True when the last section's heading is inside the visible part of the panel.
    pub fn last_section_visible(&self) -> bool {
        self.last_heading_top >= self.viewport_top - 0.5
            && self.last_heading_bottom <= self.viewport_bottom + 0.5
    }

    /// True when something is wider than the panel (and so cut off on the right).
    pub fn clipped_horizontally(&self) -> bool {
        self.content_width > self.viewport_width + 0.5
    }
}

/// Draws the panel, [`PANEL_WIDTH`] wide, on the right of `ui` and returns the user's actions
/// and where its content went. Its sections scroll vertically (solid scroll bar beside
/// the content, never over it); long values wrap instead of widening the panel.
pub fn show(
    ui: &mut egui::Ui,
    model: &PanelModel,
    settings: &mut PanelSettings,
) -> (Vec<PanelAction>, PanelLayout) {
    let mut actions = Vec::new();
    let mut layout = PanelLayout::default();
    egui::Panel::right("gridlight-panel").resizable(false).exact_size(PANEL_WIDTH).show(ui, |ui| {
        ui.spacing_mut().scroll = egui::style::ScrollStyle::solid();
        let out = egui::ScrollArea::vertical().auto_shrink([false, false]).show(ui, |ui| {
            let content_left = ui.min_rect().left();
            status_section(ui, model.status);
            ui.separator();
            view_section(ui, settings, &mut actions);
            ui.separator();
            pacing_section(ui, settings, &mut actions);
            ui.separator();
            selection_section(ui, model, &mut actions);
            ui.separator();
            lights_section(ui, model.scene, &mut actions);
            ui.separator();
            environment_section(ui, model, &mut actions);
            ui.separator();
            let heading = record_section(ui, model, settings, &mut actions);
            (heading, ui.min_rect().right() - content_left)
        });
        let (heading, content_width) = out.inner;
        layout = PanelLayout {
            viewport_top: out.inner_rect.top(),
            viewport_bottom: out.inner_rect.bottom(),
            viewport_width: out.inner_rect.width(),
            content_width,
            content_height: out.content_size.y,
            scroll_offset: out.state.clamped_offset().y,
            last_heading_top: heading.top(),
            last_heading_bottom: heading.bottom(),
        };
    });
    (actions, layout)
}

/// One label/value row of a two-column grid; the value wraps within the panel.
fn grid_row(ui: &mut egui::Ui, label: &str, value: impl Into<String>) {
    ui.label(label);
    ui.add(egui::Label::new(value.into()).wrap());
    ui.end_row();
}

fn status_section(ui: &mut egui::Ui, s: &StatusView) {
    ui.heading("Status");
    // The value column gets what the label column leaves, so long values wrap.
    let value_width = (ui.available_width() - 130.0).max(60.0);
    egui::Grid::new("status").num_columns(2).max_col_width(value_width).show(ui, |ui| {
        grid_row(ui, "fps", format!("{:.1}", s.fps));
        grid_row(ui, "frame / state", format!("{} / v{}", s.frame, s.state_version));
        grid_row(ui, "Q_t", format!("{:.2} ({}/{} jobs)", s.q, s.jobs_back, s.jobs_total));
        grid_row(ui, "I_t", format!("{:.2}", s.i));
        let latency = match s.edit_latency_ms {
            Some(l) => format!("{:.0} ms (median {:.0}, p95 {:.0})", l.last, l.median, l.p95),
            None => "no edit shown yet".into(),
        };
        grid_row(ui, "edit to display", latency);
        grid_row(ui, "frames skipped", s.frames_skipped.to_string());
        grid_row(ui, "dropped late", s.dropped_late.to_string());
        grid_row(ui, "not drawn", format!("{} (a newer frame came)", s.frames_replaced));
        grid_row(
            ui,
            "bytes in / out",
            format!("{} / {}", human_bytes(s.bytes_in), human_bytes(s.bytes_out)),
        );
        grid_row(ui, "reconstruction", s.reconstructor.clone());
        grid_row(ui, "adapter", s.adapter.clone());
        grid_row(ui, "drawn from device", s.device_frames.to_string());
        grid_row(
            ui,
            "uploaded / read back",
            format!("{} / {}", s.picture_uploads, s.frames_read_back),
        );
    });
    egui::CollapsingHeader::new(format!("Workers ({})", s.workers.len()))
        .default_open(true)
        .show(ui, |ui| workers_list(ui, &s.workers));
}

/// Each worker with its colour in the workers view (the legend), host and counts.
fn workers_list(ui: &mut egui::Ui, workers: &[super::status::WorkerRow]) {
    if workers.is_empty() {
        ui.label("no worker connected");
    }
    for w in workers {
        ui.horizontal(|ui| {
            let [r, g, b] = crate::master::view::worker_colour(w.id);
            let (rect, _) = ui.allocate_exact_size(egui::vec2(12.0, 12.0), egui::Sense::hover());
            ui.painter().rect_filled(rect, 2.0, egui::Color32::from_rgb(r, g, b));
            let cores = if w.cores == 1 { "core" } else { "cores" };
            ui.add(
                egui::Label::new(format!("{} on {}, {} {cores}", w.name, w.host, w.cores)).wrap(),
            );
        });
        let rate = match &w.paused {
            Some(why) => format!("paused: {why}"),
            None => format!("{:.1} jobs/s", w.jobs_per_second),
        };
        ui.add(
            egui::Label::new(
                egui::RichText::new(format!(
                    "{} jobs, {} late, {:.1} ms/job, {rate}, seen {:.1} s ago",
                    w.jobs, w.late, w.mean_job_ms, w.last_seen_s
                ))
                .small(),
            )
            .wrap(),
        );
    }
}

fn view_section(ui: &mut egui::Ui, settings: &mut PanelSettings, actions: &mut Vec<PanelAction>) {
    ui.heading("View");
    ui.horizontal_wrapped(|ui| {
        for view in View::ALL {
            ui.selectable_value(&mut settings.view, view, view.label());
        }
    });
    ui.horizontal_wrapped(|ui| {
        ui.label("reconstruction:");
        for method in Method::ALL {
            ui.radio_value(&mut settings.method, method, method.name());
        }
    });
    ui.horizontal_wrapped(|ui| {
        ui.label("camera:");
        ui.radio_value(&mut settings.camera_mode, CameraMode::Orbit, "orbit");
        ui.radio_value(&mut settings.camera_mode, CameraMode::Fly, "fly");
        if ui.button("reset (R)").clicked() {
            actions.push(PanelAction::ResetCamera);
        }
    });
    ui.add(
        egui::Label::new(
            egui::RichText::new(
                "drag: orbit/look · wheel: zoom · WASD/QE: fly · click: pick · arrows/PgUp/PgDn: nudge · 1–6: views",
            )
            .small(),
        )
        .wrap(),
    );
}

fn pacing_section(ui: &mut egui::Ui, settings: &mut PanelSettings, actions: &mut Vec<PanelAction>) {
    ui.heading("Pacing");
    let before = settings.pacing;
    let mut fixed = matches!(settings.pacing, PacingChoice::FixedFps(_));
    ui.horizontal_wrapped(|ui| {
        ui.radio_value(&mut fixed, false, "quality heuristic");
        ui.radio_value(&mut fixed, true, "fixed frame rate");
    });
    settings.pacing = match (fixed, settings.pacing) {
        (true, PacingChoice::Heuristic { .. }) => PacingChoice::FixedFps(10.0),
        (false, PacingChoice::FixedFps(_)) => {
            PacingChoice::Heuristic { q_min: 0.2, q_max: 0.5, i_min: 2.0, i_max: 4.0 }
        }
        (_, pacing) => pacing,
    };
    match &mut settings.pacing {
        PacingChoice::Heuristic { q_min, q_max, i_min, i_max } => {
            ui.add(egui::Slider::new(q_min, 0.0..=1.0).text("Q_min"));
            ui.add(egui::Slider::new(q_max, 0.0..=1.0).text("Q_max"));
            ui.add(egui::Slider::new(i_min, 0.1..=10.0).text("I_min"));
            ui.add(egui::Slider::new(i_max, 0.1..=20.0).text("I_max"));
            // Keep the bounds ordered so the heuristic stays meaningful.
            *q_max = q_max.max(*q_min);
            *i_max = i_max.max(*i_min);
        }
        PacingChoice::FixedFps(fps) => {
            ui.add(egui::Slider::new(fps, 1.0..=120.0).logarithmic(true).text("frames/s"));
        }
    }
    if settings.pacing != before {
        actions.push(PanelAction::Pacing(settings.pacing));
    }
}

fn selection_section(ui: &mut egui::Ui, model: &PanelModel, actions: &mut Vec<PanelAction>) {
    ui.heading("Selection");
    let Some(object) =
        model.selected.and_then(|i| model.scene.objects.get(i as usize).map(|o| (i, o)))
    else {
        ui.label("click an object in the picture to select it");
        return;
    };
    let (index, object) = object;
    ui.horizontal(|ui| {
        ui.strong(&object.name);
        if ui.button("deselect").clicked() {
            actions.push(PanelAction::Deselect);
        }
    });
    let mut transform = object.transform;
    ui.horizontal(|ui| {
        ui.label("position");
        vec3_drag(ui, &mut transform.translation, 0.01);
    });
    if transform != object.transform {
        actions.push(PanelAction::Edit(WindowEdit::ObjectTransform { object: index, transform }));
    }
    let mut seen = Vec::new();
    for &id in &object.materials {
        if seen.contains(&id) {
            continue;
        }
        seen.push(id);
        let Some(material) = model.scene.materials.get(id as usize) else { continue };
        let mut m = material.clone();
        ui.collapsing(format!("material {}", m.name), |ui| {
            egui::ComboBox::from_id_salt(("kind", id)).selected_text(kind_label(m.kind)).show_ui(
                ui,
                |ui| {
                    for kind in [
                        MaterialKind::Diffuse,
                        MaterialKind::Glossy,
                        MaterialKind::Conductor,
                        MaterialKind::Dielectric,
                        MaterialKind::Pbr,
                    ] {
                        ui.selectable_value(&mut m.kind, kind, kind_label(kind));
                    }
                },
            );
            ui.horizontal(|ui| {
                ui.label("base colour");
                colour_edit(ui, &mut m.base_color);
            });
            ui.add(egui::Slider::new(&mut m.roughness, 0.0..=1.0).text("roughness"));
            if m.kind == MaterialKind::Pbr {
                ui.add(egui::Slider::new(&mut m.metallic, 0.0..=1.0).text("metallic"));
                ui.add(egui::Slider::new(&mut m.transmission, 0.0..=1.0).text("transmission"));
            }
            if matches!(m.kind, MaterialKind::Dielectric | MaterialKind::Glossy | MaterialKind::Pbr)
            {
                ui.add(egui::Slider::new(&mut m.ior, 1.0..=2.5).text("IOR"));
            }
            let (mut colour, mut strength) = split_power(m.emission);
            ui.horizontal(|ui| {
                ui.label("emission");
                colour_edit(ui, &mut colour);
            });
            ui.add(egui::Slider::new(&mut strength, 0.0..=50.0).text("emission strength"));
            m.emission = join_power(colour, strength);
        });
        if &m != material {
            actions.push(PanelAction::Edit(WindowEdit::Material { id, material: Box::new(m) }));
        }
    }
}

fn lights_section(ui: &mut egui::Ui, scene: &SceneState, actions: &mut Vec<PanelAction>) {
    ui.heading("Lights");
    if scene.lights.is_empty() {
        ui.label("no lights besides emissive surfaces (edit those as materials)");
    }
    for (index, light) in scene.lights.iter().enumerate() {
        let mut l = *light;
        ui.collapsing(format!("{} {index}", light_label(light)), |ui| light_editor(ui, &mut l));
        if l != *light {
            actions.push(PanelAction::Edit(WindowEdit::Light { index: index as u32, light: l }));
        }
    }
}

fn light_editor(ui: &mut egui::Ui, light: &mut Light) {
    let power = match light {
        Light::Point { position, intensity } => {
            labelled_vec3(ui, "position", position, 0.01);
            intensity
        }
        Light::Spot { position, direction, intensity, inner_deg, outer_deg } => {
            labelled_vec3(ui, "position", position, 0.01);
            labelled_vec3(ui, "direction", direction, 0.01);
            ui.add(egui::Slider::new(inner_deg, 0.0..=90.0).text("inner °"));
            ui.add(egui::Slider::new(outer_deg, 0.0..=90.0).text("outer °"));
            *outer_deg = outer_deg.max(*inner_deg);
            intensity
        }
        Light::Sun { direction, radiance, angular_radius_deg } => {
            labelled_vec3(ui, "direction", direction, 0.01);
            ui.add(egui::Slider::new(angular_radius_deg, 0.05..=10.0).text("radius °"));
            radiance
        }
        Light::Quad { corner, radiance, .. } => {
            labelled_vec3(ui, "corner", corner, 0.01);
            radiance
        }
    };
    let (mut colour, mut intensity) = split_power(*power);
    ui.horizontal(|ui| {
        ui.label("colour");
        colour_edit(ui, &mut colour);
    });
    let max = (intensity * 4.0).max(10.0);
    ui.add(egui::Slider::new(&mut intensity, 0.0..=max).text("intensity"));
    *power = join_power(colour, intensity);
}

fn environment_section(ui: &mut egui::Ui, model: &PanelModel, actions: &mut Vec<PanelAction>) {
    ui.heading("Environment");
    let before = model.scene.environment.clone();
    let mut env = before.clone();
    let current = env
        .as_ref()
        .map_or("none".to_string(), |e| e.map.clone().unwrap_or_else(|| "constant colour".into()));
    egui::ComboBox::from_id_salt("environment").selected_text(current).show_ui(ui, |ui| {
        if ui.selectable_label(env.is_none(), "none").clicked() {
            env = None;
        }
        let constant = env.as_ref().is_some_and(|e| e.map.is_none());
        if ui.selectable_label(constant, "constant colour").clicked() {
            env =
                Some(Environment { map: None, ..env.clone().unwrap_or_else(default_environment) });
        }
        for map in model.environment_maps {
            let chosen = env.as_ref().is_some_and(|e| e.map.as_ref() == Some(map));
            if ui.selectable_label(chosen, map).clicked() {
                env = Some(Environment {
                    map: Some(map.clone()),
                    ..env.clone().unwrap_or_else(default_environment)
                });
            }
        }
    });
    if let Some(e) = env.as_mut() {
        ui.horizontal(|ui| {
            ui.label(if e.map.is_some() { "tint" } else { "colour" });
            colour_edit(ui, &mut e.color);
        });
        ui.add(egui::Slider::new(&mut e.intensity, 0.0..=10.0).text("intensity"));
        ui.add(egui::Slider::new(&mut e.rotation_deg, 0.0..=360.0).text("rotation °"));
    }
    if env != before {
        actions.push(PanelAction::Edit(WindowEdit::Environment(env)));
    }
}

/// The last section; returns its heading's rectangle.
fn record_section(
    ui: &mut egui::Ui,
    model: &PanelModel,
    settings: &mut PanelSettings,
    actions: &mut Vec<PanelAction>,
) -> egui::Rect {
    let heading = ui.heading("Recording and screenshots").rect;
    ui.checkbox(&mut settings.recording, format!("record edits ({} so far)", model.recorded));
    ui.horizontal_wrapped(|ui| {
        if ui.button("save script").clicked() {
            actions.push(PanelAction::SaveScript);
        }
        ui.radio_value(&mut settings.shot_format, ShotFormat::Png, "PNG");
        ui.radio_value(&mut settings.shot_format, ShotFormat::Exr, "EXR");
        if ui.button("screenshot (F12)").clicked() {
            actions.push(PanelAction::Screenshot);
        }
    });
    if !model.message.is_empty() {
        ui.add(egui::Label::new(egui::RichText::new(model.message).small()).wrap());
    }
    heading
}

fn default_environment() -> Environment {
    Environment { map: None, color: Vec3::splat(0.5), intensity: 1.0, rotation_deg: 0.0 }
}

fn kind_label(kind: MaterialKind) -> &'static str {
    match kind {
        MaterialKind::Diffuse => "diffuse",
        MaterialKind::Glossy => "glossy (plastic)",
        MaterialKind::Conductor => "metal",
        MaterialKind::Dielectric => "glass",
        MaterialKind::Pbr => "glTF metallic-roughness",
    }
}

fn light_label(light: &Light) -> &'static str {
    match light {
        Light::Point { .. } => "point",
        Light::Spot { .. } => "spot",
        Light::Sun { .. } => "sun",
        Light::Quad { .. } => "area",
    }
}

fn vec3_drag(ui: &mut egui::Ui, v: &mut Vec3, speed: f32) {
    ui.add(egui::DragValue::new(&mut v.x).speed(speed).prefix("x "));
    ui.add(egui::DragValue::new(&mut v.y).speed(speed).prefix("y "));
    ui.add(egui::DragValue::new(&mut v.z).speed(speed).prefix("z "));
}

fn labelled_vec3(ui: &mut egui::Ui, label: &str, v: &mut Vec3, speed: f32) {
    ui.horizontal(|ui| {
        ui.label(label);
        vec3_drag(ui, v, speed);
    });
}

fn colour_edit(ui: &mut egui::Ui, c: &mut Vec3) {
    let mut rgb = c.to_array();
    ui.color_edit_button_rgb(&mut rgb);
    *c = Vec3::from_array(rgb);
}
