//! Moving the selected object: dragging it across the picture and nudging it with keys.
//!
//! Pure maths on the camera and the object's transform. A drag moves the object in the
//! plane through it that faces the camera, so it stays under the mouse; nudges step along
//! the camera's horizontal right and forward directions and the world's up.

use glam::Vec3;
use gridlight_actors::state::{Camera, Transform};

/// World offset that keeps an object at `position` under the mouse after the mouse moved
/// `(dx, dy)` render pixels (y down) in a picture `picture_height` pixels tall.
pub fn drag_offset(camera: &Camera, position: Vec3, dx: f32, dy: f32, picture_height: u32) -> Vec3 {
    let forward = (camera.look_at - camera.position).normalize_or(Vec3::NEG_Z);
    let right = forward.cross(camera.up.normalize_or(Vec3::Y)).normalize_or(Vec3::X);
    let up = right.cross(forward);
    // Distance along the view axis: the plane's depth; objects behind the camera don't move.
    let depth = (position - camera.position).dot(forward);
    if depth <= 0.0 || picture_height == 0 {
        return Vec3::ZERO;
    }
    let world_per_pixel =
        2.0 * depth * (camera.vfov_deg.to_radians() * 0.5).tan() / picture_height as f32;
    (right * dx - up * dy) * world_per_pixel
}

/// Direction of a nudge key, relative to the view.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Nudge {
    Left,
    Right,
    /// Away from the camera, along the ground.
    Away,
    /// Towards the camera, along the ground.
    Towards,
    Up,
    Down,
}

/// World offset of one nudge of `step` scene units. Away/towards follow the camera's view
/// projected onto the plane perpendicular to `camera.up`.
pub fn nudge_offset(camera: &Camera, nudge: Nudge, step: f32) -> Vec3 {
    let up = camera.up.normalize_or(Vec3::Y);
    let view = camera.look_at - camera.position;
    let ground = (view - up * view.dot(up)).normalize_or(up.any_orthonormal_vector());
    let right = ground.cross(up);
    step * match nudge {
        Nudge::Left => -right,
        Nudge::Right => right,
        Nudge::Away => ground,
        Nudge::Towards => -ground,
        Nudge::Up => up,
        Nudge::Down => -up,
    }
}

/// `transform` moved by `offset`.
pub fn moved(transform: Transform, offset: Vec3) -> Transform {
    Transform { translation: transform.translation + offset, ..transform }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera() -> Camera {
        Camera {
            position: Vec3::new(0.0, 0.0, 4.0),
            look_at: Vec3::ZERO,
            up: Vec3::Y,
            vfov_deg: 90.0,
            aperture: 0.0,
            focus_distance: 4.0,
        }
    }

    #[test]
    fn dragging_the_full_height_moves_the_full_visible_height() {
        // 90° fov at depth 4: the picture spans 8 units vertically.
        let off = drag_offset(&camera(), Vec3::ZERO, 0.0, -100.0, 100);
        assert!((off - Vec3::new(0.0, 8.0, 0.0)).length() < 1e-4, "{off:?}");
        let off = drag_offset(&camera(), Vec3::ZERO, 50.0, 0.0, 100);
        assert!((off - Vec3::new(4.0, 0.0, 0.0)).length() < 1e-4, "{off:?}");
    }

    #[test]
    fn objects_behind_the_camera_do_not_move() {
        assert_eq!(drag_offset(&camera(), Vec3::new(0.0, 0.0, 9.0), 10.0, 10.0, 100), Vec3::ZERO);
    }

    #[test]
    fn nudges_follow_the_view_on_the_ground() {
        let mut cam = camera();
        cam.position = Vec3::new(0.0, 3.0, 4.0); // looking down at the origin
        let away = nudge_offset(&cam, Nudge::Away, 0.5);
        assert!((away - Vec3::new(0.0, 0.0, -0.5)).length() < 1e-5, "{away:?}");
        assert!((nudge_offset(&cam, Nudge::Right, 1.0) - Vec3::X).length() < 1e-5);
        assert_eq!(nudge_offset(&cam, Nudge::Up, 2.0), Vec3::new(0.0, 2.0, 0.0));
        let t = moved(Transform::default(), Vec3::X);
        assert_eq!(t.translation, Vec3::X);
    }
}
