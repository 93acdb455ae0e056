//! Where the rendered picture sits in the window, and the way back from a window pixel to a
//! render pixel (for picking and dragging).
//!
//! The render resolution is the scene's and does not follow the window: the picture is
//! scaled uniformly to fit the area left of the side panel and centred there, with bars
//! where the aspect ratios differ. [`initial_window_size`] picks a first window size that
//! fits the screen the window opens on.

use glam::Vec2;

/// An axis-aligned rectangle in physical window pixels.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rect {
    pub x: f32,
    pub y: f32,
    pub width: f32,
    pub height: f32,
}

impl Rect {
    /// True when `p` lies inside (left/top edges inclusive, right/bottom exclusive).
    pub fn contains(&self, p: Vec2) -> bool {
        p.x >= self.x && p.y >= self.y && p.x < self.x + self.width && p.y < self.y + self.height
    }
}

/// The smallest window the panel is designed for (its sections scroll below this height).
pub const MIN_WINDOW: (u32, u32) = (800, 600);

/// Share of the screen a new window may take at most, leaving room for the desktop's bars
/// and the window's decorations.
pub const SCREEN_SHARE: f32 = 0.9;

/// The first window size: the picture at its render size beside the panel (all in
/// physical pixels), at least [`MIN_WINDOW`]; on a known `screen`, at most
/// [`SCREEN_SHARE`] of it but never less than [`MIN_WINDOW`] a screen can hold, and never
/// more than the screen.
pub fn initial_window_size(
    picture: (u32, u32),
    panel_width: u32,
    screen: Option<(u32, u32)>,
) -> (u32, u32) {
    let wanted = ((picture.0 + panel_width + 16).max(MIN_WINDOW.0), picture.1.max(MIN_WINDOW.1));
    match screen {
        Some((w, h)) if w > 0 && h > 0 => {
            let cap = |s: u32, min: u32| ((s as f32 * SCREEN_SHARE) as u32).max(min.min(s));
            (wanted.0.min(cap(w, MIN_WINDOW.0)), wanted.1.min(cap(h, MIN_WINDOW.1)))
        }
        _ => wanted,
    }
}

/// The largest rectangle with the picture's aspect ratio that fits in `area`, centred.
/// `None` when either the area or the picture is empty.
pub fn fit(area: Rect, picture_width: u32, picture_height: u32) -> Option<Rect> {
    if area.width < 1.0 || area.height < 1.0 || picture_width == 0 || picture_height == 0 {
        return None;
    }
    let scale = (area.width / picture_width as f32).min(area.height / picture_height as f32);
    let (width, height) = (picture_width as f32 * scale, picture_height as f32 * scale);
    Some(Rect {
        x: area.x + (area.width - width) * 0.5,
        y: area.y + (area.height - height) * 0.5,
        width,
        height,
    })
}

/// The render-pixel coordinates (continuous, (0,0) the top-left corner of the picture) under
/// window position `p`, or `None` when `p` is outside the picture.
pub fn window_to_picture(
    shown: Rect,
    picture_width: u32,
    picture_height: u32,
    p: Vec2,
) -> Option<Vec2> {
    if !shown.contains(p) {
        return None;
    }
    Some(Vec2::new(
        (p.x - shown.x) / shown.width * picture_width as f32,
        (p.y - shown.y) / shown.height * picture_height as f32,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_first_window_fits_the_screen() {
        // Room enough: the picture at its size beside the panel, at least 800×600.
        assert_eq!(initial_window_size((640, 480), 300, Some((1920, 1080))), (956, 600));
        assert_eq!(initial_window_size((1280, 720), 300, Some((2560, 1440))), (1596, 720));
        // A smaller screen caps it at 90 %, but not below 800×600 where the screen has it.
        assert_eq!(initial_window_size((1280, 720), 300, Some((1280, 800))), (1152, 720));
        assert_eq!(initial_window_size((640, 480), 300, Some((800, 600))), (800, 600));
        assert_eq!(initial_window_size((640, 480), 300, Some((640, 480))), (640, 480));
        // Unknown screen: what the picture wants.
        assert_eq!(initial_window_size((640, 480), 300, None), (956, 600));
    }

    #[test]
    fn wide_area_gets_side_bars() {
        let area = Rect { x: 0.0, y: 0.0, width: 1000.0, height: 480.0 };
        let shown = fit(area, 640, 480).expect("non-empty");
        assert_eq!(shown, Rect { x: 180.0, y: 0.0, width: 640.0, height: 480.0 });
    }

    #[test]
    fn tall_area_gets_top_and_bottom_bars_and_scales() {
        let area = Rect { x: 10.0, y: 0.0, width: 320.0, height: 1000.0 };
        let shown = fit(area, 640, 480).expect("non-empty");
        assert_eq!(shown.width, 320.0);
        assert_eq!(shown.height, 240.0);
        assert_eq!(shown.x, 10.0);
        assert_eq!(shown.y, 380.0);
    }

    #[test]
    fn empty_inputs_fit_nothing() {
        let area = Rect { x: 0.0, y: 0.0, width: 0.0, height: 100.0 };
        assert!(fit(area, 640, 480).is_none());
        let area = Rect { x: 0.0, y: 0.0, width: 100.0, height: 100.0 };
        assert!(fit(area, 0, 480).is_none());
    }

    #[test]
    fn window_to_picture_maps_corners_and_rejects_bars() {
        let shown = Rect { x: 180.0, y: 0.0, width: 320.0, height: 240.0 };
        let at = |x, y| window_to_picture(shown, 640, 480, Vec2::new(x, y));
        assert_eq!(at(180.0, 0.0), Some(Vec2::ZERO));
        assert_eq!(at(340.0, 120.0), Some(Vec2::new(320.0, 240.0)));
        assert_eq!(at(179.0, 10.0), None);
        assert_eq!(at(500.0, 10.0), None, "the right edge is exclusive");
    }
}
