//! The window plugged into a running master: a frame sink that turns shown frames into
//! pictures (G-buffer, reconstruction, the chosen view), and the [`MasterControl`] the window
//! talks to (edits, picking, status, scripts, shutdown).
//!
//! The sink runs on the master's sink thread, never on the actors' or the window's: it
//! builds the picture, leaves it in the newest-only slot and wakes the event loop. A failed
//! wake-up means the window is gone, which the sink reports as `SinkError::Closed`.

use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::atomic::{AtomicU8, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use gridlight_actors::edit::Edit;
use gridlight_actors::edit::{CameraEdit, EnvironmentEdit, MaterialEdit, ObjectEdit};
use gridlight_actors::master::{MasterHandle, MasterReport};
use gridlight_actors::sink::{FrameSink, Preparer, ShownFrame, SinkError};
use gridlight_actors::state::SceneState;
use serde::Serialize;
use winit::event_loop::EventLoopProxy;

use super::edits::WindowEdit;
use super::latest::Latest;
use super::panel::PacingChoice;
use super::picture::FrameImage;
use super::status::{StatusView, WorkerRow};
use super::{MasterControl, ReadyFrame, UserEvent};
use crate::master::compose::{Composer, SharedScene};
use crate::master::view::View;
use crate::reconstruct::Method;
use crate::render;

/// What the window's panel chooses for the next composed frames, shared with the sink.
#[derive(Debug, Default)]
pub struct ComposeChoice {
    /// Index into [`View::ALL`].
    view: AtomicU8,
    /// Index into [`Method::ALL`].
    method: AtomicU8,
}

impl ComposeChoice {
    /// The view and the method the composer starts with.
    pub fn new(view: View, method: Method) -> Self {
        let choice = Self::default();
        choice.set_view(view);
        choice.set_method(method);
        choice
    }

    pub fn view(&self) -> View {
        View::ALL.get(self.view.load(Ordering::Relaxed) as usize).copied().unwrap_or_default()
    }

    pub fn set_view(&self, view: View) {
        let index = View::ALL.iter().position(|v| *v == view).unwrap_or(0);
        self.view.store(index as u8, Ordering::Relaxed);
    }

    pub fn method(&self) -> Method {
        Method::ALL.get(self.method.load(Ordering::Relaxed) as usize).copied().unwrap_or_default()
    }

    pub fn set_method(&self, method: Method) {
        let index = Method::ALL.iter().position(|m| *m == method).unwrap_or(0);
        self.method.store(index as u8, Ordering::Relaxed);
    }
}

/// The panel's choices, shared by the window and its sink.
pub type SharedChoice = Arc<ComposeChoice>;

/// Frame sink that composes pictures for the window.
pub struct WindowSink {
    composer: Composer,
    choice: SharedChoice,
    frames: Arc<Latest<ReadyFrame>>,
    proxy: EventLoopProxy<UserEvent>,
}

impl WindowSink {
    pub fn new(
        composer: Composer,
        choice: SharedChoice,
        frames: Arc<Latest<ReadyFrame>>,
        proxy: EventLoopProxy<UserEvent>,
    ) -> Self {
        Self { composer, choice, frames, proxy }
    }

    fn compose(&mut self, frame: &ShownFrame) -> Result<ReadyFrame, SinkError> {
        self.composer.set_method(self.choice.method());
        let c = self
            .composer
            .compose(frame, self.choice.view())
            .map_err(|e| SinkError::Other(e.into()))?;
        let image = FrameImage::from_composed(c.width, c.height, c.image)
            .ok_or_else(|| SinkError::Other("picture size does not match the frame".into()))?;
        let mut status = status_of(frame, self.composer.reconstructor().unwrap_or_default());
        status.frames_read_back = self.composer.read_backs();
        Ok(ReadyFrame { image, status })
    }
}

impl FrameSink for WindowSink {
    fn show(&mut self, frame: ShownFrame) -> Result<(), SinkError> {
        let composed = self.compose(&frame)?;
        // A frame the window never draws hands the edits it was the first to show on to
        // the newer one (whose state includes them): their latency ends when that is drawn.
        let carry = |old: ReadyFrame, new: &mut ReadyFrame| {
            new.status.edits_at.splice(0..0, old.status.edits_at).for_each(drop);
        };
        if !self.frames.put_merging(composed, carry)
            || self.proxy.send_event(UserEvent::FrameReady).is_err()
        {
            return Err(SinkError::Closed);
        }
        Ok(())
    }

    fn preparer(&mut self) -> Option<Preparer> {
        self.composer.sink_preparer()
    }

    fn finish(&mut self) {
        // The master stopped: close the window too (ignored when it is already gone).
        let _ = self.proxy.send_event(UserEvent::Quit);
    }
}

fn status_of(frame: &ShownFrame, reconstructor: String) -> StatusView {
    let s = &frame.stats;
    StatusView {
        frame: s.frame,
        state_version: s.state_version,
        q: s.q as f32,
        i: s.i as f32,
        jobs_back: s.jobs_back as u64,
        jobs_total: s.jobs_total as u64,
        frames_skipped: s.skipped,
        dropped_late: s.dropped_late,
        bytes_in: s.bytes_in,
        bytes_out: s.bytes_out,
        reconstructor,
        edits_at: s.edits_at.clone(),
        ..Default::default()
    }
}

/// The window's edit as the master's [`Edit`] (absolute values for every field).
pub fn to_master_edit(edit: &WindowEdit, state: &SceneState) -> Option<Edit> {
    Some(match edit {
        WindowEdit::Camera(c) => Edit::Camera(CameraEdit {
            position: Some(c.position),
            look_at: Some(c.look_at),
            up: Some(c.up),
            vfov_deg: Some(c.vfov_deg),
            aperture: Some(c.aperture),
            focus_distance: Some(c.focus_distance),
        }),
        WindowEdit::ObjectTransform { object, transform } => Edit::Object(ObjectEdit {
            name: state.objects.get(*object as usize)?.name.clone(),
            translation: Some(transform.translation),
            rotation: Some(transform.rotation),
            rotation_deg: None,
            scale: Some(transform.scale),
            visible: None,
        }),
        WindowEdit::Material { id, material } => Edit::Material(MaterialEdit {
            name: state.materials.get(*id as usize)?.name.clone(),
            kind: Some(material.kind),
            base_color: Some(material.base_color),
            roughness: Some(material.roughness),
            ior: Some(material.ior),
            emission: Some(material.emission),
            emission_strength: Some(material.emission_strength),
            metallic: Some(material.metallic),
            transmission: Some(material.transmission),
        }),
        WindowEdit::Light { index, light } => Edit::Light { index: *index as usize, light: *light },
        WindowEdit::Environment(None) => Edit::ClearEnvironment,
        WindowEdit::Environment(Some(e)) => Edit::Environment(EnvironmentEdit {
            map: e.map.clone(),
            color: Some(e.color),
            intensity: Some(e.intensity),
            rotation_deg: Some(e.rotation_deg),
        }),
        WindowEdit::Resolution(r) => Edit::Resolution(*r),
    })
}

#[derive(Serialize)]
struct ScriptFile {
    edit: Vec<ScriptEntry>,
}

#[derive(Serialize)]
struct ScriptEntry {
    at: f64,
    #[serde(flatten)]
    edit: Edit,
}

/// Recorded edits as interaction-script TOML (the format `--script` reads). TOML cannot
/// hold the unit edit `ClearEnvironment`, so it is written as an environment of intensity
/// 0, which renders the same (black).
pub fn script_toml(entries: &[(Duration, Edit)]) -> Result<String, toml::ser::Error> {
    let edit = entries
        .iter()
        .map(|(at, e)| ScriptEntry { at: at.as_secs_f64(), edit: scriptable(e) })
        .collect();
    toml::to_string(&ScriptFile { edit })
}

/// `edit` in a form TOML can hold (see [`script_toml`]).
fn scriptable(edit: &Edit) -> Edit {
    match edit {
        Edit::ClearEnvironment => {
            Edit::Environment(EnvironmentEdit { intensity: Some(0.0), ..Default::default() })
        }
        other => other.clone(),
    }
}

/// The [`MasterControl`] over a running master.
pub struct LiveMaster {
    handle: Option<MasterHandle>,
    initial: SceneState,
    /// The window's view of the state, to name objects and materials in master edits.
    state: SceneState,
    pacing: PacingChoice,
    scene: SharedScene,
    choice: SharedChoice,
    script_path: PathBuf,
    /// Stops what else was started beside the master (the demo's local workers).
    on_shutdown: Option<Box<dyn FnOnce()>>,
    /// The master's report once it stopped, for whoever started the window.
    report: SharedReport,
}

/// Where the master's report is left when it stops.
pub type SharedReport = Arc<Mutex<Option<MasterReport>>>;

impl LiveMaster {
    pub fn new(
        handle: MasterHandle,
        initial: SceneState,
        pacing: PacingChoice,
        scene: SharedScene,
        choice: SharedChoice,
        script_path: PathBuf,
        on_shutdown: Option<Box<dyn FnOnce()>>,
    ) -> Self {
        Self {
            report: SharedReport::default(),
            handle: Some(handle),
            state: initial.clone(),
            initial,
            pacing,
            scene,
            choice,
            script_path,
            on_shutdown,
        }
    }
}

impl LiveMaster {
    /// Leaves the master's report in `report` when the window stops it.
    pub fn reporting_to(mut self, report: SharedReport) -> Self {
        self.report = report;
        self
    }
}

impl MasterControl for LiveMaster {
    fn initial_state(&self) -> SceneState {
        self.initial.clone()
    }

    fn pacing(&self) -> PacingChoice {
        self.pacing
    }

    fn edit(&mut self, edit: WindowEdit, at: std::time::Instant) {
        let Some(master_edit) = to_master_edit(&edit, &self.state) else { return };
        if edit.apply(&mut self.state).is_err() {
            return;
        }
        // A message to the scene holder, never a wait on the actors.
        if let Some(h) = &self.handle {
            h.edit_made(master_edit, at);
        }
    }

    fn set_pacing(&mut self, pacing: PacingChoice) {
        let Some(h) = &self.handle else { return };
        match h.set_pacing(pacing.into()) {
            Ok(()) => self.pacing = pacing,
            Err(err) => tracing::warn!(?pacing, cause = %err, "pacing not changed"),
        }
    }

    fn set_view(&mut self, view: View) {
        self.choice.set_view(view);
    }

    fn method(&self) -> Method {
        self.choice.method()
    }

    fn set_method(&mut self, method: Method) {
        self.choice.set_method(method);
    }

    fn pick(&self, x: f32, y: f32) -> Option<u32> {
        let guard = self.scene.read().unwrap_or_else(|p| p.into_inner());
        render::pick(guard.scene(), x, y)
    }

    fn refresh_status(&mut self, status: &mut StatusView) {
        let Some(h) = &self.handle else { return };
        status.workers = h
            .workers()
            .into_iter()
            .map(|w| WorkerRow {
                id: w.id,
                name: w.name,
                host: w.host,
                cores: w.cores,
                jobs_per_second: w.jobs_per_second as f32,
                jobs: w.jobs,
                late: w.late,
                mean_job_ms: w.mean_job_time.as_secs_f32() * 1e3,
                last_seen_s: w.last_seen.as_secs_f32(),
                paused: w.paused.map(|r| r.to_string()),
            })
            .collect();
        if let Some(stats) = h.stats() {
            if status.frame == 0 {
                status.frame = stats.frame;
            }
        }
    }

    fn save_script(&self, entries: &[(Duration, WindowEdit)]) -> Result<PathBuf, String> {
        let mut state = self.initial.clone();
        let mut edits = Vec::new();
        for (at, e) in entries {
            if let Some(m) = to_master_edit(e, &state) {
                edits.push((*at, m));
            }
            let _ = e.apply(&mut state);
        }
        let text = script_toml(&edits).map_err(|e| e.to_string())?;
        std::fs::write(&self.script_path, text)
            .map_err(|e| format!("{}: {e}", self.script_path.display()))?;
        Ok(self.script_path.clone())
    }

    fn shutdown(&mut self) {
        if let Some(handle) = self.handle.take() {
            match handle.stop() {
                Ok(report) => *self.report.lock().unwrap_or_else(|p| p.into_inner()) = Some(report),
                Err(err) => tracing::warn!(cause = %err, "master did not stop cleanly"),
            }
        }
        if let Some(stop) = self.on_shutdown.take() {
            stop();
        }
    }
}

/// What a windowed master starts with.
pub struct MasterStart {
    pub config: gridlight_actors::master::MasterConfig,
    pub state: SceneState,
    pub store: gridlight_actors::asset_store::AssetStore,
    pub composer: Composer,
    /// Interaction script played from the start.
    pub script: Option<Vec<(Duration, Edit)>>,
    /// Called with the address workers should use, once the master accepts connections.
    pub on_listening: Box<dyn FnOnce(SocketAddr) -> Result<(), String>>,
    /// Called after the master stopped (e.g. to stop the demo's local workers).
    pub on_shutdown: Option<Box<dyn FnOnce()>>,
}

/// Starts a master whose frames go to a window and runs the window on this thread until
/// it closes (or Ctrl-C/SIGTERM); closing it stops the master, then calls `on_shutdown`.
/// The entry point for the windowed `gridlight demo`/`master`; returns the master's report.
pub fn run_master_window(
    options: super::WindowOptions,
    start: MasterStart,
) -> Result<MasterReport, super::WindowError> {
    let script_path = options.shot_dir.join("gridlight-session.toml");
    let MasterStart { config, state, store, composer, script, on_listening, on_shutdown } = start;
    let pacing = PacingChoice::from(config.pacing);
    let report: SharedReport = Arc::default();
    let live_report = Arc::clone(&report);
    super::run(options, move |proxy, frames, offer| {
        let composer = composer.with_window_device(offer);
        let scene = composer.scene();
        let choice = Arc::new(ComposeChoice::new(View::default(), composer.method()));
        let sink = WindowSink::new(composer, Arc::clone(&choice), frames, proxy);
        let handle = gridlight_actors::master::start(config, state.clone(), store, Box::new(sink))
            .map_err(|e| format!("cannot start the master: {e}"))?;
        let mut live =
            LiveMaster::new(handle, state, pacing, scene, choice, script_path, on_shutdown)
                .reporting_to(live_report);
        let addr = live.handle.as_ref().map(|h| h.local_addr());
        if let Some(addr) = addr {
            if let Err(e) = on_listening(addr) {
                live.shutdown();
                return Err(e);
            }
        }
        if let (Some(script), Some(h)) = (script, &live.handle) {
            h.play_script(script);
        }
        Ok(Box::new(live))
    })?;
    let report = report.lock().unwrap_or_else(|p| p.into_inner()).take();
    report
        .ok_or_else(|| super::WindowError::Start("the master did not report how it stopped".into()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;
    use gridlight_actors::state::{Camera, Environment, Light};

    #[test]
    fn recorded_edits_save_as_a_script_the_master_parses_back() {
        let camera = Camera {
            position: Vec3::new(1.0, 2.0, 3.0),
            look_at: Vec3::ZERO,
            up: Vec3::Y,
            vfov_deg: 40.0,
            aperture: 0.0,
            focus_distance: 3.0,
        };
        let env = Environment { map: None, color: Vec3::ONE, intensity: 2.0, rotation_deg: 30.0 };
        let light = Light::Point { position: Vec3::Y, intensity: Vec3::splat(3.0) };
        let resolution = gridlight_actors::state::Resolution { width: 4, height: 4 };
        let state = SceneState { lights: vec![light], ..SceneState::empty(resolution, camera) };
        let edits: Vec<(Duration, Edit)> = [
            WindowEdit::Camera(camera),
            WindowEdit::Environment(Some(env)),
            WindowEdit::Light { index: 0, light },
            WindowEdit::Environment(None),
        ]
        .iter()
        .enumerate()
        .map(|(i, e)| {
            (Duration::from_millis(500 * i as u64), to_master_edit(e, &state).expect("convertible"))
        })
        .collect();
        let text = script_toml(&edits).expect("serialises");
        let parsed = gridlight_actors::script::parse(&text, "recorded.toml").expect("parses back");
        let expected: Vec<_> = edits.iter().map(|(t, e)| (*t, scriptable(e))).collect();
        assert_eq!(parsed, expected);
        assert!(matches!(
            parsed[3].1,
            Edit::Environment(EnvironmentEdit { intensity: Some(0.0), .. })
        ));
    }
}
