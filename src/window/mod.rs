//! The window: an interactive master with live scene editing (issue 5).
//!
//! Frames reconstructed from the grid's results appear in a winit window through a wgpu
//! surface; the user moves the camera, picks and moves objects, and edits materials,
//! lights and the environment in an egui side panel. Every edit goes to the master, which
//! makes a new scene state that the next frames use.
//!
//! # Threads
//! winit owns the main thread ([`run`]). The master's actor system runs on its own thread,
//! and a compose thread turns the master's shown frames into pictures; the newest picture
//! waits in a [`latest::Latest`] slot and an [`EventLoopProxy`] wakes the window. The
//! window never waits for the master and the master never waits for the window.
//!
//! # One device
//! The window opens its device on the event-loop thread and offers it to the compose
//! thread ([`DeviceOffer`]); GPU reconstruction runs there and hands the window each final
//! frame as a texture of its own ([`picture::FrameImage::Device`]), which the blit pass
//! samples with no read-back and no upload (ARCHITECTURE.md, "One device on the master").
//!
//! # Files
//! - [`app`]: the winit application (input, drawing).
//! - [`gpu`], [`blit`]: the wgpu surface and the picture pass (`blit.wgsl`).
//! - [`camera`], [`manipulate`]: camera controllers and object moves (pure maths).
//! - [`edits`]: scene edits, their coalescing and local application; [`follow`]: the
//!   render size following the window (`--resolution window`).
//! - [`panel`], [`status`]: the egui side panel over plain data.
//! - [`picture`]: pictures and the diagnostic views; [`layout`]: where the picture sits.
//! - [`latest`]: the newest-only hand-off; [`record`]: edit recording; [`screenshot`].
//! - [`master_control`]: the window on a running master (frame sink, edits, picking, scripts).

use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

use gridlight_actors::state::SceneState;
use thiserror::Error;
use winit::event_loop::{EventLoop, EventLoopProxy};

pub mod app;
pub mod blit;
pub mod camera;
pub mod edits;
pub mod follow;
pub mod gpu;
pub mod latest;
pub mod layout;
pub mod manipulate;
pub mod master_control;
pub mod panel;
pub mod picture;
pub mod record;
pub mod screenshot;
pub mod status;

use crate::gpu::DeviceOffer;
use crate::master::view::View;
use crate::reconstruct::Method;
use edits::WindowEdit;
use latest::Latest;
use panel::PacingChoice;
use picture::FrameImage;
use status::StatusView;

/// Events that other threads send to the window's event loop.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum UserEvent {
    /// A new picture waits in the slot.
    FrameReady,
    /// The master stopped on its own, or Ctrl-C/SIGTERM came:
    /// close the window.
    Quit,
}

/// One frame ready to draw.
#[derive(Clone, Debug)]
pub struct ReadyFrame {
    /// What the window shows for the selected view.
    pub image: FrameImage,
    /// The frame's statistics.
    pub status: StatusView,
}

/// The master as the window sees it. Every call returns at once: edits and pacing are
/// messages, never waits.
pub trait MasterControl {
    /// The scene state the window starts from.
    fn initial_state(&self) -> SceneState;
    /// The pacing the master started with.
    fn pacing(&self) -> PacingChoice;
    /// Sends an edit made at `at` (its input event); the master makes a new scene state
    /// from it.
    fn edit(&mut self, edit: WindowEdit, at: std::time::Instant);
    /// Changes how the master paces frames.
    fn set_pacing(&mut self, pacing: PacingChoice);
    /// Chooses the view the next composed frames show.
    fn set_view(&mut self, view: View);
    /// The reconstruction method the master started with.
    fn method(&self) -> Method;
    /// Chooses the reconstruction method of the next composed frames.
    fn set_method(&mut self, method: Method);
    /// The object (index into the state's objects) under render pixel (x, y) of the
    /// shown frame's scene.
    fn pick(&self, x: f32, y: f32) -> Option<u32>;
    /// Adds what the master knows beyond the last frame's statistics (workers, …).
    fn refresh_status(&mut self, status: &mut StatusView);
    /// Saves recorded edits as an interaction script; returns its path.
    fn save_script(&self, entries: &[(Duration, WindowEdit)]) -> Result<PathBuf, String>;
    /// Stops the master and its local workers; returns once they are told to stop.
    fn shutdown(&mut self);
}

/// What the window looks like and where it writes.
#[derive(Clone, Debug)]
pub struct WindowOptions {
    pub title: String,
    /// The view shown first.
    pub view: View,
    /// Start with edit recording on.
    pub record: bool,
    /// Folder for screenshots.
    pub shot_dir: PathBuf,
    /// Environment maps the panel offers (asset paths).
    pub environment_maps: Vec<String>,
    /// `--resolution window`: render at the picture area's physical size times this scale.
    pub follow_window: Option<f32>,
}

impl Default for WindowOptions {
    fn default() -> Self {
        Self {
            title: "gridlight".into(),
            view: View::Final,
            record: false,
            shot_dir: PathBuf::from("."),
            environment_maps: Vec::new(),
            follow_window: None,
        }
    }
}

/// Why the window could not run.
#[derive(Debug, Error)]
pub enum WindowError {
    #[error("cannot start the window system's event loop: {0}")]
    EventLoop(#[from] winit::error::EventLoopError),
    #[error("cannot start the window: {0}")]
    Start(String),
}

/// True when a display server is reachable by its usual variables (X11 or Wayland).
pub fn display_available() -> bool {
    ["DISPLAY", "WAYLAND_DISPLAY"]
        .iter()
        .any(|v| std::env::var_os(v).is_some_and(|s| !s.is_empty()))
}

/// Opens the window on the current thread (the main thread in the binary) and runs until it
/// closes. `start` receives the proxy, the frame slot and the offer of the window's device
/// and starts the master (and the compose thread); it runs once the event loop exists,
/// before the window opens.
pub fn run<F>(options: WindowOptions, start: F) -> Result<(), WindowError>
where
    F: FnOnce(
        EventLoopProxy<UserEvent>,
        Arc<Latest<ReadyFrame>>,
        DeviceOffer,
    ) -> Result<Box<dyn MasterControl>, String>,
{
    let event_loop = new_event_loop()?;
    // Ctrl-C and SIGTERM close the window the way its close button does.
    let quit = event_loop.create_proxy();
    crate::signals::on_stop_signal(move |_| {
        let _ = quit.send_event(UserEvent::Quit);
    })
    .map_err(|e| WindowError::Start(format!("cannot install the Ctrl-C handler: {e}")))?;
    let frames = Arc::new(Latest::new());
    let offer = DeviceOffer::new();
    let master = start(event_loop.create_proxy(), Arc::clone(&frames), offer.clone())
        .map_err(WindowError::Start)?;
    let mut app = app::App::new(options, master, frames, offer);
    event_loop.run_app(&mut app)?;
    Ok(())
}

#[cfg(target_os = "linux")]
fn new_event_loop() -> Result<EventLoop<UserEvent>, winit::error::EventLoopError> {
    use winit::platform::wayland::EventLoopBuilderExtWayland;
    use winit::platform::x11::EventLoopBuilderExtX11;
    // The binary calls this on the main thread; allowing others lets tests drive it too.
    let mut builder = EventLoop::<UserEvent>::with_user_event();
    EventLoopBuilderExtX11::with_any_thread(&mut builder, true);
    EventLoopBuilderExtWayland::with_any_thread(&mut builder, true);
    builder.build()
}

#[cfg(not(target_os = "linux"))]
fn new_event_loop() -> Result<EventLoop<UserEvent>, winit::error::EventLoopError> {
    EventLoop::<UserEvent>::with_user_event().build()
}
