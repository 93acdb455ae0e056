//! Primary rays: a pinhole or thin-lens camera from the scene state's `Camera`.

use glam::{Vec2, Vec3};
use gridlight_actors::state::{Camera, Resolution};

/// Precomputed camera basis for generating rays through pixel positions.
#[derive(Clone, Copy, Debug)]
pub struct CameraRays {
    origin: Vec3,
    forward: Vec3,
    /// Unit right and up vectors.
    right: Vec3,
    up: Vec3,
    /// Half extents of the image plane at distance one.
    half_w: f32,
    half_h: f32,
    inv_width: f32,
    inv_height: f32,
    aperture: f32,
    focus_distance: f32,
}

/// Why a camera cannot be used.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum CameraError {
    #[error("camera position equals look_at or a vector is not finite")]
    Degenerate,
    #[error("camera up vector is parallel to the viewing direction")]
    UpParallel,
    #[error("vertical field of view {0}° is outside (0, 180)")]
    Fov(f32),
    #[error("resolution {0}x{1} has no pixels")]
    Resolution(u32, u32),
}

impl CameraRays {
    pub fn new(camera: &Camera, resolution: Resolution) -> Result<Self, CameraError> {
        if resolution.width == 0 || resolution.height == 0 {
            return Err(CameraError::Resolution(resolution.width, resolution.height));
        }
        let finite =
            camera.position.is_finite() && camera.look_at.is_finite() && camera.up.is_finite();
        let view = camera.look_at - camera.position;
        if !finite || view.length_squared() == 0.0 {
            return Err(CameraError::Degenerate);
        }
        if !(camera.vfov_deg > 0.0 && camera.vfov_deg < 180.0) {
            return Err(CameraError::Fov(camera.vfov_deg));
        }
        let forward = view.normalize();
        let right = forward.cross(camera.up);
        if right.length_squared() < 1e-12 {
            return Err(CameraError::UpParallel);
        }
        let right = right.normalize();
        let up = right.cross(forward);
        let half_h = (camera.vfov_deg.to_radians() * 0.5).tan();
        let aspect = resolution.width as f32 / resolution.height as f32;
        let aperture = if camera.aperture.is_finite() { camera.aperture.max(0.0) } else { 0.0 };
        let focus_distance = if camera.focus_distance.is_finite() && camera.focus_distance > 0.0 {
            camera.focus_distance
        } else {
            view.length()
        };
        Ok(Self {
            origin: camera.position,
            forward,
            right,
            up,
            half_w: half_h * aspect,
            half_h,
            inv_width: 1.0 / resolution.width as f32,
            inv_height: 1.0 / resolution.height as f32,
            aperture,
            focus_distance,
        })
    }

    /// The ray through image position `pixel` (in pixels, y down from the top
    /// edge); `lens` in [0,1)² picks the point on a thin lens.
    #[inline]
    pub fn ray(&self, pixel: Vec2, lens: Vec2) -> (Vec3, Vec3) {
        let x = (2.0 * pixel.x * self.inv_width - 1.0) * self.half_w;
        let y = (1.0 - 2.0 * pixel.y * self.inv_height) * self.half_h;
        let dir = (self.forward + self.right * x + self.up * y).normalize();
        if self.aperture == 0.0 {
            return (self.origin, dir);
        }
        // Uniform point on the lens disc; rays converge on the plane in focus.
        let r = self.aperture * lens.x.sqrt();
        let phi = std::f32::consts::TAU * lens.y;
        let offset = self.right * (r * phi.cos()) + self.up * (r * phi.sin());
        let focus = self.origin + dir * (self.focus_distance / dir.dot(self.forward));
        let origin = self.origin + offset;
        (origin, (focus - origin).normalize())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera() -> Camera {
        Camera {
            position: Vec3::new(0.0, 0.0, 5.0),
            look_at: Vec3::ZERO,
            up: Vec3::Y,
            vfov_deg: 90.0,
            aperture: 0.0,
            focus_distance: 0.0,
        }
    }

    #[test]
    fn centre_ray_looks_at_target_and_top_row_is_up() {
        let c = CameraRays::new(&camera(), Resolution { width: 200, height: 100 }).unwrap();
        let (o, d) = c.ray(Vec2::new(100.0, 50.0), Vec2::ZERO);
        assert_eq!(o, Vec3::new(0.0, 0.0, 5.0));
        assert!((d - Vec3::NEG_Z).length() < 1e-6);
        let (_, top) = c.ray(Vec2::new(100.0, 0.0), Vec2::ZERO);
        assert!((top - Vec3::new(0.0, 1.0, -1.0).normalize()).length() < 1e-5);
        let (_, right) = c.ray(Vec2::new(200.0, 50.0), Vec2::ZERO);
        assert!((right - Vec3::new(2.0, 0.0, -1.0).normalize()).length() < 1e-5);
    }

    #[test]
    fn bad_cameras_are_rejected() {
        let res = Resolution { width: 4, height: 4 };
        let mut c = camera();
        c.look_at = c.position;
        assert_eq!(CameraRays::new(&c, res).unwrap_err(), CameraError::Degenerate);
        let mut c = camera();
        c.up = Vec3::Z;
        assert_eq!(CameraRays::new(&c, res).unwrap_err(), CameraError::UpParallel);
        let mut c = camera();
        c.vfov_deg = f32::NAN;
        assert!(CameraRays::new(&c, res).is_err());
        assert!(CameraRays::new(&camera(), Resolution { width: 0, height: 4 }).is_err());
    }

    #[test]
    fn thin_lens_rays_meet_in_the_focal_plane() {
        let mut c = camera();
        c.aperture = 0.5;
        c.focus_distance = 5.0;
        let cam = CameraRays::new(&c, Resolution { width: 64, height: 64 }).unwrap();
        let px = Vec2::new(20.0, 40.0);
        let (o1, d1) = cam.ray(px, Vec2::new(0.3, 0.1));
        let (o2, d2) = cam.ray(px, Vec2::new(0.9, 0.7));
        let p1 = o1 + d1 * ((0.0 - o1.z) / d1.z);
        let p2 = o2 + d2 * ((0.0 - o2.z) / d2.z);
        assert!((p1 - p2).length() < 1e-4);
        assert!((o1 - o2).length() > 1e-3);
    }
}
