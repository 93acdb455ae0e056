//! Camera controllers: orbit (drag around a point), fly (WASD + mouse look), zoom and reset.
//!
//! They are pure: each call takes the current [`Camera`] and returns a new one, which the
//! window sends to the master as an edit. Nothing here knows about winit, so the maths is
//! unit-tested directly. Angles are measured about the camera's `up` vector, so a scene with
//! +z up orbits as naturally as one with +y up.

use glam::{Quat, Vec3};
use gridlight_actors::state::Camera;

/// Closest the view direction may come to straight up or down, in radians, so that the
/// look-at frame never degenerates (forward parallel to up).
const PITCH_LIMIT: f32 = 89.0_f32 * std::f32::consts::PI / 180.0;

/// Nearest an orbiting camera may come to its target, in scene units.
const MIN_DISTANCE: f32 = 1e-3;

/// How the mouse moves the camera.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum CameraMode {
    /// Dragging rotates the camera around its look-at point.
    #[default]
    Orbit,
    /// Dragging turns the camera in place; WASD/QE move it.
    Fly,
}

/// Directions of travel held down this frame (fly mode), as unit steps in camera space.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MoveKeys {
    pub forward: bool,
    pub back: bool,
    pub left: bool,
    pub right: bool,
    pub up: bool,
    pub down: bool,
}

impl MoveKeys {
    /// Camera-space direction (x right, y up, z forward); zero when nothing or opposites are held.
    pub fn direction(&self) -> Vec3 {
        let axis = |plus: bool, minus: bool| (plus as i32 - minus as i32) as f32;
        Vec3::new(
            axis(self.right, self.left),
            axis(self.up, self.down),
            axis(self.forward, self.back),
        )
    }

    /// True when any movement key is held.
    pub fn any(&self) -> bool {
        self.direction() != Vec3::ZERO
    }
}

/// Turns mouse and keyboard input into new cameras; remembers the camera to reset to.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraController {
    pub mode: CameraMode,
    /// The scene's camera when the window opened; the reset key returns to it.
    pub home: Camera,
    /// Radians of rotation per pixel dragged.
    pub radians_per_pixel: f32,
    /// Fly speed in scene units per second.
    pub fly_speed: f32,
    /// Fraction of the distance to the target that one wheel notch zooms in.
    pub zoom_per_notch: f32,
}

impl CameraController {
    /// A controller whose reset goes back to `home`; the fly speed scales with the distance
    /// from the camera to its target so that small and large scenes feel the same.
    pub fn new(home: Camera) -> Self {
        let distance = (home.look_at - home.position).length().max(MIN_DISTANCE);
        Self {
            mode: CameraMode::Orbit,
            home,
            radians_per_pixel: 0.005,
            fly_speed: distance * 0.5,
            zoom_per_notch: 0.1,
        }
    }

    /// The camera after a mouse drag of `(dx, dy)` pixels in the current mode.
    pub fn drag(&self, camera: &Camera, dx: f32, dy: f32) -> Camera {
        let (yaw, pitch) = (-dx * self.radians_per_pixel, -dy * self.radians_per_pixel);
        match self.mode {
            // Dragging up lifts the eye over the target, so the view itself pitches down.
            CameraMode::Orbit => orbit(camera, yaw, -pitch),
            CameraMode::Fly => look(camera, yaw, pitch),
        }
    }

    /// The camera after `notches` wheel steps (positive = towards the target).
    pub fn wheel(&self, camera: &Camera, notches: f32) -> Camera {
        zoom(camera, (1.0 - self.zoom_per_notch).powf(notches))
    }

    /// The camera after holding `keys` for `seconds` (fly movement; works in both modes).
    pub fn fly(&self, camera: &Camera, keys: MoveKeys, seconds: f32) -> Camera {
        translate_local(camera, keys.direction() * self.fly_speed * seconds)
    }

    /// The camera the reset key returns to.
    pub fn reset(&self) -> Camera {
        self.home
    }
}

/// Orthonormal camera frame: (right, true up, forward).
fn frame(camera: &Camera) -> (Vec3, Vec3, Vec3) {
    let forward = (camera.look_at - camera.position).normalize_or(Vec3::NEG_Z);
    let up = camera.up.normalize_or(Vec3::Y);
    let right = forward.cross(up).normalize_or(Vec3::X);
    (right, right.cross(forward), forward)
}

/// Rotates `offset` by `yaw` about `up` and by `pitch` about the horizontal axis, keeping
/// the angle to `up` within [`PITCH_LIMIT`].
fn rotate_offset(offset: Vec3, up: Vec3, yaw: f32, pitch: f32) -> Vec3 {
    let up = up.normalize_or(Vec3::Y);
    let length = offset.length();
    let dir = offset / length;
    // Elevation of `dir` above the horizon, clamped after adding the pitch.
    let elevation = dir.dot(up).clamp(-1.0, 1.0).asin();
    let target = (elevation + pitch).clamp(-PITCH_LIMIT, PITCH_LIMIT);
    let horizontal = (dir - up * dir.dot(up)).normalize_or(up.any_orthonormal_vector());
    let horizontal = Quat::from_axis_angle(up, yaw) * horizontal;
    (horizontal * target.cos() + up * target.sin()) * length
}

/// Rotates the camera position around its look-at point (the target stays put); `pitch`
/// turns the view direction up (positive) or down, as in [`look`].
pub fn orbit(camera: &Camera, yaw: f32, pitch: f32) -> Camera {
    let offset = camera.position - camera.look_at;
    if offset.length() < MIN_DISTANCE {
        return *camera;
    }
    // Moving the eye up means looking down: the pitch of the offset is the negated view pitch.
    let offset = rotate_offset(offset, camera.up, yaw, -pitch);
    Camera { position: camera.look_at + offset, ..*camera }
}

/// Turns the view direction in place (the position stays put; the target moves).
pub fn look(camera: &Camera, yaw: f32, pitch: f32) -> Camera {
    let offset = camera.look_at - camera.position;
    if offset.length() < MIN_DISTANCE {
        return *camera;
    }
    let offset = rotate_offset(offset, camera.up, yaw, pitch);
    Camera { look_at: camera.position + offset, ..*camera }
}

/// Scales the distance to the target by `factor` (< 1 moves closer), never reaching it.
pub fn zoom(camera: &Camera, factor: f32) -> Camera {
    let offset = camera.position - camera.look_at;
    let length = offset.length();
    if length < MIN_DISTANCE || !factor.is_finite() || factor <= 0.0 {
        return *camera;
    }
    let new_length = (length * factor).max(MIN_DISTANCE);
    Camera { position: camera.look_at + offset * (new_length / length), ..*camera }
}

/// Moves camera and target together by `delta` given in camera space (x right, y up, z forward).
pub fn translate_local(camera: &Camera, delta: Vec3) -> Camera {
    let (right, up, forward) = frame(camera);
    let world = right * delta.x + up * delta.y + forward * delta.z;
    Camera { position: camera.position + world, look_at: camera.look_at + world, ..*camera }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cornell() -> Camera {
        Camera {
            position: Vec3::new(0.0, 0.0, 4.0),
            look_at: Vec3::ZERO,
            up: Vec3::Y,
            vfov_deg: 39.3,
            aperture: 0.0,
            focus_distance: 4.0,
        }
    }

    fn close(a: Vec3, b: Vec3) -> bool {
        (a - b).length() < 1e-4
    }

    #[test]
    fn orbit_keeps_target_and_distance() {
        let cam = orbit(&cornell(), 0.7, 0.3);
        assert_eq!(cam.look_at, Vec3::ZERO);
        assert!((cam.position.length() - 4.0).abs() < 1e-4);
        assert!(!close(cam.position, cornell().position));
    }

    #[test]
    fn orbit_quarter_turn_moves_to_the_side() {
        // A positive yaw about +y turns +z towards +x.
        let cam = orbit(&cornell(), std::f32::consts::FRAC_PI_2, 0.0);
        assert!(close(cam.position, Vec3::new(4.0, 0.0, 0.0)), "{:?}", cam.position);
    }

    #[test]
    fn orbit_pitch_is_clamped_short_of_the_pole() {
        let cam = orbit(&cornell(), 0.0, -10.0);
        let dir = (cam.position - cam.look_at).normalize();
        let elevation = dir.dot(Vec3::Y).asin();
        assert!(elevation <= PITCH_LIMIT + 1e-4 && elevation > PITCH_LIMIT - 1e-3);
        // The frame stays well defined.
        let (right, up, forward) = frame(&cam);
        assert!(right.is_finite() && up.is_finite() && forward.is_finite());
    }

    #[test]
    fn dragging_up_in_orbit_raises_the_eye() {
        let ctl = CameraController::new(cornell());
        // Mouse moves up (negative dy): the eye goes up and looks down at the target.
        let cam = ctl.drag(&cornell(), 0.0, -50.0);
        assert!(cam.position.y > 0.1, "{:?}", cam.position);
    }

    #[test]
    fn look_keeps_position_and_turns_view() {
        let cam = look(&cornell(), 0.2, 0.1);
        assert_eq!(cam.position, cornell().position);
        let forward = (cam.look_at - cam.position).normalize();
        assert!(forward.y > 0.0 && forward.x < 0.0, "{forward:?}");
    }

    #[test]
    fn zoom_moves_along_the_view_and_never_passes_the_target() {
        let cam = zoom(&cornell(), 0.5);
        assert!(close(cam.position, Vec3::new(0.0, 0.0, 2.0)));
        let cam = zoom(&cornell(), 0.0);
        assert_eq!(cam, cornell(), "a zero factor is ignored");
        let ctl = CameraController::new(cornell());
        let mut cam = cornell();
        for _ in 0..1000 {
            cam = ctl.wheel(&cam, 1.0);
        }
        assert!(cam.position.z >= MIN_DISTANCE * 0.999, "never reaches the target");
    }

    #[test]
    fn fly_moves_camera_and_target_together() {
        let ctl = CameraController::new(cornell());
        let keys = MoveKeys { forward: true, right: true, ..Default::default() };
        let cam = ctl.fly(&cornell(), keys, 1.0);
        let step = ctl.fly_speed;
        assert!(close(cam.position, Vec3::new(step, 0.0, 4.0 - step)), "{:?}", cam.position);
        assert!(close(cam.look_at - cam.position, cornell().look_at - cornell().position));
        let none = ctl.fly(&cornell(), MoveKeys::default(), 1.0);
        assert_eq!(none, cornell());
    }

    #[test]
    fn opposite_keys_cancel() {
        let keys = MoveKeys { left: true, right: true, up: true, ..Default::default() };
        assert_eq!(keys.direction(), Vec3::Y);
        assert!(!MoveKeys { forward: true, back: true, ..Default::default() }.any());
    }

    #[test]
    fn reset_returns_home_after_any_moves() {
        let ctl = CameraController::new(cornell());
        let moved = ctl.wheel(&ctl.drag(&cornell(), 30.0, 10.0), 3.0);
        assert_ne!(moved, cornell());
        assert_eq!(ctl.reset(), cornell());
    }

    #[test]
    fn z_up_scenes_orbit_about_z() {
        let cam = Camera { position: Vec3::new(4.0, 0.0, 0.0), up: Vec3::Z, ..cornell() };
        let turned = orbit(&cam, 0.5, 0.0);
        assert!((turned.position.z).abs() < 1e-4, "yaw stays in the xy-plane");
    }
}
