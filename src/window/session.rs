//! The window plugged into a running master: a frame sink that turns shown frames into
//! pictures (G-buffer, reconstruction, the chosen view), and the [`Session`] the window
//! talks to (edits, picking, status, scripts, shutdown).
//!
//! The sink runs on the master's sink thread, never on the actors' or the window's: it
//! builds the picture, leaves it in the newest-only slot and wakes the event loop. A failed
//! wake-up means the window is gone, which the sink reports as `SinkError::Closed`.

use std::path::PathBuf;
use std::sync::atomic::{AtomicU8, Ordering};
use std::sync::{Arc, RwLock};
use std::time::Duration;

use gridlight_actors::edit::Edit;
use gridlight_actors::edit::{CameraEdit, EnvironmentEdit, MaterialEdit, ObjectEdit};
use gridlight_actors::master::MasterHandle;
use gridlight_actors::sink::{FrameSink, ShownFrame, SinkError};
use gridlight_actors::state::SceneState;
use rayon::prelude::*;
use serde::Serialize;
use winit::event_loop::EventLoopProxy;

use super::edits::SceneEdit;
use super::latest::Latest;
use super::panel::PacingChoice;
use super::picture::{self, Picture, View, ViewInputs};
use super::status::StatusView;
use super::{Composed, Session, UserEvent};
use crate::assets::Assets;
use crate::reconstruct::{self, Backend, FrameInputs, GBuffer, ReconstructParams, Reconstructor};
use crate::render::{self, RenderScene};

/// The render scene of the shown frame, shared by the sink (G-buffer) and the window (picking).
pub type SharedScene = Arc<RwLock<Option<RenderScene>>>;

/// The view the window wants, shared with the sink (index into [`View::ALL`]).
pub type SharedView = Arc<AtomicU8>;

/// Frame sink that composes pictures for the window.
pub struct WindowSink {
    assets: Arc<Assets>,
    scene: SharedScene,
    view: SharedView,
    frames: Arc<Latest<Composed>>,
    proxy: EventLoopProxy<UserEvent>,
    params: ReconstructParams,
    /// G-buffer of the last state version seen.
    gbuffer: Option<(u64, GBuffer)>,
    reconstructor: Option<Reconstructor>,
}

impl WindowSink {
    pub fn new(
        assets: Arc<Assets>,
        scene: SharedScene,
        view: SharedView,
        frames: Arc<Latest<Composed>>,
        proxy: EventLoopProxy<UserEvent>,
    ) -> Self {
        Self {
            assets,
            scene,
            view,
            frames,
            proxy,
            params: ReconstructParams::default(),
            gbuffer: None,
            reconstructor: None,
        }
    }

    /// The G-buffer of `state`, recomputed (and the shared render scene updated) when its
    /// version changed.
    fn gbuffer(&mut self, state: &SceneState) -> Result<&GBuffer, SinkError> {
        if self.gbuffer.as_ref().is_none_or(|(v, _)| *v != state.version) {
            let mut guard = self.scene.write().unwrap_or_else(|p| p.into_inner());
            match guard.as_mut() {
                Some(scene) => scene.set_state(state),
                None => RenderScene::new(Arc::clone(&self.assets), state).map(|s| *guard = Some(s)),
            }
            .map_err(|e| SinkError::Other(e.to_string()))?;
            let scene = guard.as_ref().ok_or_else(|| SinkError::Other("no render scene".into()))?;
            let res = state.resolution;
            let samples: Vec<_> = (0..res.pixels() as u32)
                .into_par_iter()
                .map(|p| render::primary_hit(scene, p))
                .collect();
            let mut g = GBuffer::empty(
                res.width,
                res.height,
                reconstruct::scene_scale(state, &self.assets),
            );
            for (i, s) in samples.iter().enumerate() {
                g.normal[i] = s.normal;
                g.position[i] = s.position;
                g.albedo[i] = s.albedo;
                g.emission[i] = s.emission;
                g.object[i] = s.object;
            }
            self.gbuffer = Some((state.version, g));
        }
        match &self.gbuffer {
            Some((_, g)) => Ok(g),
            None => Err(SinkError::Other("no G-buffer".into())),
        }
    }

    fn compose(&mut self, frame: &ShownFrame) -> Result<Composed, SinkError> {
        let res = frame.state.resolution;
        if self.reconstructor.is_none() {
            let r = Reconstructor::new(res.width, res.height, self.params, Backend::Cpu)
                .map_err(|e| SinkError::Other(e.to_string()))?;
            self.reconstructor = Some(r);
        }
        let exposure = self.params.exposure;
        let view =
            View::ALL.get(self.view.load(Ordering::Relaxed) as usize).copied().unwrap_or_default();
        self.gbuffer(&frame.state)?;
        let (Some((_, g)), Some(r)) = (&self.gbuffer, &mut self.reconstructor) else {
            return Err(SinkError::Other("reconstruction not ready".into()));
        };
        let inputs = FrameInputs {
            frame: frame.frame,
            state_version: frame.state.version,
            radiance: &frame.current,
            mask: &frame.current_mask,
            gbuffer: g,
        };
        // Reconstruct every frame, whatever the view, so that the history stays complete.
        let out = r.reconstruct(&inputs).map_err(|e| SinkError::Other(e.to_string()))?;
        let status = status_of(frame, r.describe());
        let (picture, linear) = match view {
            View::Final => (
                Picture::from_pixels(res.width, res.height, &out.display),
                Some(Arc::new(out.colour)),
            ),
            other => {
                let planes = ViewInputs {
                    width: res.width,
                    height: res.height,
                    radiance: &frame.current,
                    mask: &frame.current_mask,
                    albedo: &g.albedo,
                    emission: &g.emission,
                    normal: &g.normal,
                };
                (
                    picture::diagnostic(other, &planes, |c| {
                        reconstruct::tonemap::to_rgba8(c, exposure)
                    }),
                    None,
                )
            }
        };
        let picture = picture
            .ok_or_else(|| SinkError::Other("picture size does not match the frame".into()))?;
        Ok(Composed { picture, linear, status })
    }
}

impl FrameSink for WindowSink {
    fn show(&mut self, frame: ShownFrame) -> Result<(), SinkError> {
        let composed = self.compose(&frame)?;
        if !self.frames.put(composed) || self.proxy.send_event(UserEvent::FrameReady).is_err() {
            return Err(SinkError::Closed);
        }
        Ok(())
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
        ..Default::default()
    }
}

/// The window's edit as the master's [`Edit`] (absolute values for every field).
pub fn to_master_edit(edit: &SceneEdit, state: &SceneState) -> Option<Edit> {
    Some(match edit {
        SceneEdit::Camera(c) => Edit::Camera(CameraEdit {
            position: Some(c.position),
            look_at: Some(c.look_at),
            up: Some(c.up),
            vfov_deg: Some(c.vfov_deg),
            aperture: Some(c.aperture),
            focus_distance: Some(c.focus_distance),
        }),
        SceneEdit::ObjectTransform { object, transform } => Edit::Object(ObjectEdit {
            name: state.objects.get(*object as usize)?.name.clone(),
            translation: Some(transform.translation),
            rotation: Some(transform.rotation),
            rotation_deg: None,
            scale: Some(transform.scale),
            visible: None,
        }),
        SceneEdit::Material { id, material } => Edit::Material(MaterialEdit {
            name: state.materials.get(*id as usize)?.name.clone(),
            kind: Some(material.kind),
            base_color: Some(material.base_color),
            roughness: Some(material.roughness),
            ior: Some(material.ior),
            emission: Some(material.emission),
        }),
        SceneEdit::Light { index, light } => Edit::Light { index: *index as usize, light: *light },
        SceneEdit::Environment(None) => Edit::ClearEnvironment,
        SceneEdit::Environment(Some(e)) => Edit::Environment(EnvironmentEdit {
            map: e.map.clone(),
            color: Some(e.color),
            intensity: Some(e.intensity),
            rotation_deg: Some(e.rotation_deg),
        }),
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

/// The [`Session`] over a running master.
pub struct MasterSession {
    handle: Option<MasterHandle>,
    initial: SceneState,
    /// The window's view of the state, to name objects and materials in master edits.
    state: SceneState,
    pacing: PacingChoice,
    scene: SharedScene,
    view: SharedView,
    script_path: PathBuf,
    /// Stops what else the session started (the demo's local workers).
    on_shutdown: Option<Box<dyn FnOnce()>>,
}

impl MasterSession {
    pub fn new(
        handle: MasterHandle,
        initial: SceneState,
        pacing: PacingChoice,
        scene: SharedScene,
        view: SharedView,
        script_path: PathBuf,
        on_shutdown: Option<Box<dyn FnOnce()>>,
    ) -> Self {
        Self {
            handle: Some(handle),
            state: initial.clone(),
            initial,
            pacing,
            scene,
            view,
            script_path,
            on_shutdown,
        }
    }
}

impl Session for MasterSession {
    fn initial_state(&self) -> SceneState {
        self.initial.clone()
    }

    fn pacing(&self) -> PacingChoice {
        self.pacing
    }

    fn edit(&mut self, edit: SceneEdit) {
        let Some(master_edit) = to_master_edit(&edit, &self.state) else { return };
        if edit.apply(&mut self.state).is_err() {
            return;
        }
        // The script path: a message to the scene holder, never a wait on the actors.
        if let Some(h) = &self.handle {
            h.play_script(vec![(Duration::ZERO, master_edit)]);
        }
    }

    fn set_pacing(&mut self, pacing: PacingChoice) {
        // The master has no run-time pacing message yet; say so instead of pretending.
        tracing::warn!(
            ?pacing,
            "changing the pacing at run time is not supported by the master yet"
        );
    }

    fn set_view(&mut self, view: View) {
        let index = View::ALL.iter().position(|v| *v == view).unwrap_or(0);
        self.view.store(index as u8, Ordering::Relaxed);
    }

    fn pick(&self, x: f32, y: f32) -> Option<u32> {
        let guard = self.scene.read().unwrap_or_else(|p| p.into_inner());
        render::pick(guard.as_ref()?, x, y)
    }

    fn refresh_status(&mut self, status: &mut StatusView) {
        if let Some(stats) = self.handle.as_ref().and_then(|h| h.stats()) {
            status.workers.clear();
            if status.frame == 0 {
                status.frame = stats.frame;
            }
        }
    }

    fn save_script(&self, entries: &[(Duration, SceneEdit)]) -> Result<PathBuf, String> {
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
            if let Err(err) = handle.stop() {
                tracing::warn!(cause = %err, "master did not stop cleanly");
            }
        }
        if let Some(stop) = self.on_shutdown.take() {
            stop();
        }
    }
}

/// Starts a master whose frames go to a window and runs the window on this thread until
/// it closes; closing it stops the master, then calls `on_shutdown` (e.g. to stop the
/// demo's local workers). The entry point for the windowed `gridlight demo`/`master`.
pub fn run_master_window(
    options: super::WindowOptions,
    config: gridlight_actors::master::MasterConfig,
    state: SceneState,
    assets: Arc<Assets>,
    store: gridlight_actors::asset_store::AssetStore,
    on_shutdown: Option<Box<dyn FnOnce()>>,
) -> Result<(), super::WindowError> {
    let script_path = options.shot_dir.join("gridlight-session.toml");
    let pacing = match config.pacing {
        gridlight_actors::wait_heuristic::Pacing::Heuristic(h) => PacingChoice::Heuristic {
            q_min: h.q_min as f32,
            q_max: h.q_max as f32,
            i_min: h.i_min as f32,
            i_max: h.i_max as f32,
        },
        gridlight_actors::wait_heuristic::Pacing::FixedFps(fps) => PacingChoice::FixedFps(fps),
    };
    super::run(options, move |proxy, frames| {
        let scene: SharedScene = Arc::new(RwLock::new(None));
        let view: SharedView = Arc::new(AtomicU8::new(0));
        let sink = WindowSink::new(assets, Arc::clone(&scene), Arc::clone(&view), frames, proxy);
        let handle = gridlight_actors::master::start(config, state.clone(), store, Box::new(sink))
            .map_err(|e| format!("cannot start the master: {e}"))?;
        tracing::info!(address = %handle.local_addr(), "master listening");
        Ok(Box::new(MasterSession::new(
            handle,
            state,
            pacing,
            scene,
            view,
            script_path,
            on_shutdown,
        )))
    })
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
        let state = SceneState {
            version: 1,
            seed: 0,
            resolution: gridlight_actors::state::Resolution { width: 4, height: 4 },
            camera,
            objects: vec![],
            materials: vec![],
            lights: vec![light],
            environment: None,
            render: Default::default(),
        };
        let edits: Vec<(Duration, Edit)> = [
            SceneEdit::Camera(camera),
            SceneEdit::Environment(Some(env)),
            SceneEdit::Light { index: 0, light },
            SceneEdit::Environment(None),
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
