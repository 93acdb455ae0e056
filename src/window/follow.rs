//! `--resolution window`: the render size follows the window.
//!
//! The picture area (the window left of the panel, in physical pixels, so a HiDPI screen
//! gets its own pixel count) times `--scale` becomes the scene's resolution. A drag of
//! the window's edge produces a resize per input event, and every new resolution is a new
//! scene state that restarts accumulation and re-derives the pixel sets on the master and
//! every worker; so a size is asked for only once it has stayed the same for [`SETTLE`].

use std::time::{Duration, Instant};

use gridlight_actors::state::Resolution;

/// How long the picture area must keep one size before the render size follows it.
pub const SETTLE: Duration = Duration::from_millis(200);

/// The smallest side asked for: the master refuses an image with fewer pixels than pixel
/// sets, and a picture narrower than this is a window being minimised, not a size to render.
pub const MIN_SIDE: u32 = 64;

/// The render size's side of the window.
#[derive(Clone, Debug)]
pub struct FollowWindow {
    scale: f32,
    /// A size seen and since when, not yet asked for.
    pending: Option<(Resolution, Instant)>,
    /// The last size asked for (not asked again while the area keeps it).
    asked: Option<Resolution>,
}

impl FollowWindow {
    /// Follows the window at `scale` render pixels per window pixel.
    pub fn new(scale: f32) -> Self {
        Self { scale, pending: None, asked: None }
    }

    /// The render size for a picture area of `width × height` physical pixels.
    pub fn target(&self, width: f32, height: f32) -> Resolution {
        let side = |v: f32| {
            let v = (v * self.scale).round();
            if v.is_finite() {
                (v as u32).clamp(MIN_SIDE, Resolution::MAX_SIDE)
            } else {
                MIN_SIDE
            }
        };
        Resolution { width: side(width), height: side(height) }
    }

    /// Sees the picture area at `now` while the scene renders at `current`: the size to ask
    /// the master for, once the area has kept it for [`SETTLE`].
    pub fn observe(
        &mut self,
        width: f32,
        height: f32,
        current: Resolution,
        now: Instant,
    ) -> Option<Resolution> {
        let target = self.target(width, height);
        if target == current || Some(target) == self.asked {
            self.pending = None;
            return None;
        }
        match self.pending {
            Some((size, since)) if size == target => {
                if now.duration_since(since) < SETTLE {
                    return None;
                }
                self.pending = None;
                self.asked = Some(target);
                Some(target)
            }
            _ => {
                self.pending = Some((target, now));
                None
            }
        }
    }

    /// Whether a size is waiting to settle (the window must draw again to ask for it).
    pub fn is_pending(&self) -> bool {
        self.pending.is_some()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const R640: Resolution = Resolution { width: 640, height: 480 };

    #[test]
    fn a_size_is_asked_for_once_it_has_settled_and_only_once() {
        let t0 = Instant::now();
        let mut f = FollowWindow::new(1.0);
        assert_eq!(f.observe(800.0, 600.0, R640, t0), None, "first seen: wait");
        assert!(f.is_pending());
        assert_eq!(f.observe(800.0, 600.0, R640, t0 + SETTLE / 2), None, "not settled yet");
        let want = Resolution { width: 800, height: 600 };
        assert_eq!(f.observe(800.0, 600.0, R640, t0 + SETTLE), Some(want));
        assert!(!f.is_pending());
        // Until the master's state has it, the same size is not asked again.
        assert_eq!(f.observe(800.0, 600.0, R640, t0 + SETTLE * 3), None);
        assert_eq!(f.observe(800.0, 600.0, want, t0 + SETTLE * 4), None, "rendering it now");
    }

    #[test]
    fn a_drag_restarts_the_wait_at_every_new_size() {
        let t0 = Instant::now();
        let mut f = FollowWindow::new(1.0);
        let step = SETTLE / 2;
        for (i, w) in [700.0, 720.0, 740.0, 760.0].into_iter().enumerate() {
            assert_eq!(f.observe(w, 500.0, R640, t0 + step * i as u32), None, "size {w}");
        }
        let settled = f.observe(760.0, 500.0, R640, t0 + step * 3 + SETTLE);
        assert_eq!(settled, Some(Resolution { width: 760, height: 500 }));
    }

    #[test]
    fn scale_hidpi_and_tiny_areas_give_sane_sizes() {
        // A 2x HiDPI area of 3840x2160 physical pixels at half scale renders 1920x1080.
        let half = FollowWindow::new(0.5);
        assert_eq!(half.target(3840.0, 2160.0), Resolution { width: 1920, height: 1080 });
        let one = FollowWindow::new(1.0);
        assert_eq!(one.target(0.0, 10.0), Resolution { width: MIN_SIDE, height: MIN_SIDE });
        assert_eq!(one.target(1e9, f32::NAN).width, Resolution::MAX_SIDE);
        assert_eq!(one.target(1e9, f32::NAN).height, MIN_SIDE);
        // The area back at the rendered size cancels a pending change.
        let mut f = FollowWindow::new(1.0);
        let t0 = Instant::now();
        f.observe(900.0, 700.0, R640, t0);
        assert_eq!(f.observe(640.0, 480.0, R640, t0 + SETTLE), None);
        assert!(!f.is_pending());
    }
}
