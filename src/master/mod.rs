//! The master process's glue around the `gridlight-actors` runtime: starting it from a
//! scene, and what a shown frame becomes.
//!
//! - [`launch`]: running a master from a scene file (`master` and `demo` commands).
//! - [`compose`]: a shown frame → G-buffer, demodulation, reconstruction, the chosen view;
//!   shared by the headless sink and the window.
//! - [`view`]: the views a frame can be shown as (final image, radiance, G-buffer planes,
//!   workers).
//! - [`headless`]: the headless frame sink (PNG frames and statistics).
//!
//! The interactive sink is `crate::window`.

pub mod compose;
pub mod headless;
pub mod launch;
pub mod view;
