//! Primary rays: a pinhole or thin-lens camera from the scene state's `Camera`.

use glam::{Mat4, Vec2, Vec3, Vec4};
use gridlight_actors::state::{Camera, Resolution};

use super::lanes::{F32s, Isa, Vec3s};

/// Precomputed camera basis for generating rays through pixel positions.
#[derive(Clone, Copy, Debug)]
pub struct CameraRays {
    pub(crate) origin: Vec3,
    pub(crate) forward: Vec3,
    /// Unit right and up vectors.
    pub(crate) right: Vec3,
    pub(crate) up: Vec3,
    /// Half extents of the image plane at distance one.
    pub(crate) half_w: f32,
    pub(crate) half_h: f32,
    pub(crate) inv_width: f32,
    pub(crate) inv_height: f32,
    pub(crate) aperture: f32,
    pub(crate) focus_distance: f32,
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
    #[inline(always)]
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
        let (sin, cos) = super::trig::sin_cos(phi);
        let offset = self.right * (r * cos) + self.up * (r * sin);
        let focus = self.origin + dir * (self.focus_distance / dir.dot(self.forward));
        let origin = self.origin + offset;
        (origin, (focus - origin).normalize())
    }

    /// [`Self::ray`] of sixteen lanes: image positions `(px, py)` and lens samples
    /// `(lx, ly)`, each lane the same operations in the same order, so the same bits.
    #[inline(always)]
    pub(crate) fn ray_lanes<I: Isa>(
        &self,
        (px, py): (F32s<I>, F32s<I>),
        (lx, ly): (F32s<I>, F32s<I>),
    ) -> (Vec3s<I>, Vec3s<I>) {
        let c = F32s::<I>::splat;
        let (forward, right, up) =
            (Vec3s::splat(self.forward), Vec3s::splat(self.right), Vec3s::splat(self.up));
        let x = (c(2.0) * px * c(self.inv_width) - c(1.0)) * c(self.half_w);
        let y = (c(1.0) - c(2.0) * py * c(self.inv_height)) * c(self.half_h);
        let dir = (forward + right.scale(x) + up.scale(y)).normalize();
        let eye = Vec3s::splat(self.origin);
        if self.aperture == 0.0 {
            return (eye, dir);
        }
        let r = c(self.aperture) * lx.sqrt();
        let (sin, cos) = super::trig::sin_cos_lanes(c(std::f32::consts::TAU) * ly);
        let offset = right.scale(r * cos) + up.scale(r * sin);
        let focus = eye + dir.scale(c(self.focus_distance) / dir.dot(forward));
        let origin = eye + offset;
        (origin, (focus - origin).normalize())
    }

    /// The rays of [`Self::ray`] with lens sample (0.5, 0.5) — the G-buffer's primary rays
    /// (`primary_hit`) — as a rasteriser's camera: the eye and a world-to-clip matrix for
    /// wgpu (NDC y up, depth in [0, 1]). Depth is reverse-Z with an infinite far plane:
    /// `near / view depth`, 1 at `near`, so nothing beyond the near plane is clipped.
    /// A thin lens moves that eye off-axis; its rays still meet on the plane in focus,
    /// which shifts the principal point instead of tilting the image plane.
    pub fn raster_view(&self, near: f32) -> (Vec3, Mat4) {
        let (eye, _) = self.ray(Vec2::ZERO, Vec2::splat(0.5));
        // The lens offset over the focus distance: how far the focus points of the rays
        // sit to the side of a pinhole at `eye` (image plane at distance one).
        let lens = eye - self.origin;
        let (sx, sy) = if self.aperture == 0.0 {
            (0.0, 0.0)
        } else {
            (lens.dot(self.right) / self.focus_distance, lens.dot(self.up) / self.focus_distance)
        };
        let view = |axis: Vec3| axis.extend(-axis.dot(eye));
        let (r, u, f) = (view(self.right), view(self.up), view(self.forward));
        // Rows of clip = P · V · p: x and y over the half extents, w = view depth.
        let rows = [
            (r + f * sx) / self.half_w,
            (u + f * sy) / self.half_h,
            Vec4::new(0.0, 0.0, 0.0, near),
            f,
        ];
        (eye, Mat4::from_cols(rows[0], rows[1], rows[2], rows[3]).transpose())
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

    /// Lane rays equal the scalar ones bit for bit, pinhole and thin lens, across the
    /// image and the lens.
    fn lanes_match_scalar<I: Isa>() {
        use crate::render::lanes::WIDTH;
        let res = Resolution { width: 64, height: 48 };
        let mut cam = camera();
        for aperture in [0.0, 0.1] {
            cam.aperture = aperture;
            cam.focus_distance = 3.0;
            cam.position = Vec3::new(0.3, -0.2, 4.1);
            let c = CameraRays::new(&cam, res).unwrap();
            for round in 0..64u32 {
                let f = |k: u32| {
                    F32s::<I>::new(std::array::from_fn(|l| {
                        let h = (round * WIDTH as u32 + l as u32).wrapping_mul(0x9e37_79b9 + k);
                        (h >> 8) as f32 / 16_777_216.0
                    }))
                };
                let (px, py) = (f(1) * F32s::splat(64.0), f(2) * F32s::splat(48.0));
                let (lx, ly) = (f(3), f(4));
                let (o, d) = c.ray_lanes((px, py), (lx, ly));
                for l in 0..WIDTH {
                    let pixel = Vec2::new(px.0[l], py.0[l]);
                    let (eo, ed) = c.ray(pixel, Vec2::new(lx.0[l], ly.0[l]));
                    assert_eq!(
                        o.lane(l).to_array().map(f32::to_bits),
                        eo.to_array().map(f32::to_bits)
                    );
                    assert_eq!(
                        d.lane(l).to_array().map(f32::to_bits),
                        ed.to_array().map(f32::to_bits)
                    );
                }
            }
        }
    }

    crate::render::lanes::tests::isa_tests!(lanes_match_scalar: sse2_lane_rays_are_the_scalar_bits,
        avx2_lane_rays_are_the_scalar_bits, avx512_lane_rays_are_the_scalar_bits);

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
    fn raster_view_projects_primary_rays_onto_their_pixels() {
        let res = Resolution { width: 64, height: 48 };
        let mut lens = camera();
        lens.aperture = 0.3;
        lens.focus_distance = 4.0;
        lens.position = Vec3::new(0.5, 1.0, 5.0);
        for c in [camera(), lens] {
            let cam = CameraRays::new(&c, res).unwrap();
            let (eye, m) = cam.raster_view(0.01);
            for px in [Vec2::new(0.5, 0.5), Vec2::new(40.5, 7.5), Vec2::new(63.5, 47.5)] {
                let (o, d) = cam.ray(px, Vec2::splat(0.5));
                assert!((o - eye).length() < 1e-6);
                for t in [0.5, 3.0, 40.0] {
                    let clip = m * (o + d * t).extend(1.0);
                    let ndc = clip.truncate() / clip.w;
                    let pixel = Vec2::new((ndc.x + 1.0) * 32.0, (1.0 - ndc.y) * 24.0);
                    assert!((pixel - px).length() < 1e-3, "{pixel} vs {px}");
                    assert!(ndc.z > 0.0 && ndc.z < 1.0);
                }
            }
        }
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
