//! The pinhole LookAt camera of SPEC: focal length 1, vertical field of view, square
//! pixels, rays through pixel centres, row 0 at the top.

use crate::math::{Float, Ray, Vec3, try_unit};
use crate::options::RenderOptions;

/// A pinhole camera placed by LookAt.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    origin: Vec3,
    /// Camera-space axes in world space: `world_from_camera` as three columns.
    right: Vec3,
    up: Vec3,
    /// The camera's +z axis, pointing from the target back to the eye.
    backward: Vec3,
    /// Half-extent of the screen at distance 1: `tan(fov / 2)` vertically.
    half_height: Float,
    half_width: Float,
    width: u32,
    height: u32,
}

impl Camera {
    /// A camera at `look_from` looking at `look_to` with world up +y, vertical field
    /// of view `fov_degrees`, for an image of `width` x `height` pixels.
    ///
    /// When the view direction is parallel to +y (looking straight up or down) the
    /// cross product with up vanishes and `right` is taken as +x, as SPEC says.
    /// `look_from` must differ from `look_to` (checked by [`crate::RenderOptions::validate`]).
    pub fn new(
        look_from: Vec3,
        look_to: Vec3,
        fov_degrees: Float,
        width: u32,
        height: u32,
    ) -> Camera {
        Camera::with_up(look_from, look_to, Vec3::Y, fov_degrees, width, height)
    }

    /// The camera `options` describe (position, target, up, field of view, size).
    pub fn for_options(options: &RenderOptions) -> Camera {
        Camera::with_up(
            options.look_from,
            options.look_to,
            options.up,
            options.fov_degrees,
            options.width,
            options.height,
        )
    }

    /// As [`Camera::new`] with world up `up` (any non-zero length) instead of +y.
    ///
    /// When the view direction is parallel to `up`, `right` is +x made perpendicular
    /// to the view direction (+x itself in SPEC's case of up = +y), or +z if the camera
    /// looks along x.
    pub fn with_up(
        look_from: Vec3,
        look_to: Vec3,
        up: Vec3,
        fov_degrees: Float,
        width: u32,
        height: u32,
    ) -> Camera {
        // `try_unit` keeps points 1e-30 apart apart; `validate` refused the rest.
        let backward = try_unit(look_from - look_to).unwrap_or(Vec3::Z);
        let up = try_unit(up).unwrap_or(Vec3::Y);
        let right = up.cross(backward).try_normalize().unwrap_or_else(|| {
            (Vec3::X - backward * Vec3::X.dot(backward))
                .try_normalize()
                .unwrap_or(Vec3::Z)
        });
        let up = backward.cross(right);
        let half_height = (fov_degrees.to_radians() * 0.5).tan();
        let half_width = half_height * width as Float / height as Float;
        Camera {
            origin: look_from,
            right,
            up,
            backward,
            half_height,
            half_width,
            width,
            height,
        }
    }

    /// The ray through image position (`x`, `y`) in pixels from the top-left corner:
    /// pixel (i, j) has its centre at (i + 0.5, j + 0.5).
    #[inline]
    pub fn ray(&self, x: Float, y: Float) -> Ray {
        let sx = (2.0 * x / self.width as Float - 1.0) * self.half_width;
        let sy = (1.0 - 2.0 * y / self.height as Float) * self.half_height;
        let dir = self.right * sx + self.up * sy - self.backward;
        Ray::new(self.origin, dir)
    }

    /// The ray through the centre of pixel (`column`, `row`).
    #[inline]
    pub fn pixel_ray(&self, column: u32, row: u32) -> Ray {
        self.ray(column as Float + 0.5, row as Float + 0.5)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn centre_ray_looks_at_target_and_corners_span_the_fov() {
        let cam = Camera::new(
            Vec3::new(1.0, 2.0, 3.0),
            Vec3::new(1.0, 2.0, 0.0),
            90.0,
            200,
            100,
        );
        let centre = cam.ray(100.0, 50.0);
        assert!((centre.dir - Vec3::NEG_Z).length() < 1e-6);
        let top = cam.ray(100.0, 0.0);
        // 90 degrees vertically: the top edge is 45 degrees up.
        assert!((top.dir - Vec3::new(0.0, 1.0, -1.0).normalize()).length() < 1e-6);
        let right = cam.ray(200.0, 50.0);
        assert!((right.dir - Vec3::new(2.0, 0.0, -1.0).normalize()).length() < 1e-6);
    }

    #[test]
    fn points_a_hair_apart_still_give_the_view_direction() {
        let cam = Camera::new(Vec3::ZERO, Vec3::new(0.0, 0.0, -1e-30), 90.0, 10, 10);
        let centre = cam.ray(5.0, 5.0);
        assert!((centre.dir - Vec3::NEG_Z).length() < 1e-6, "{}", centre.dir);
    }

    #[test]
    fn looking_straight_down_uses_x_as_right() {
        let cam = Camera::new(Vec3::new(0.0, 2.0, 0.0), Vec3::ZERO, 90.0, 100, 100);
        let centre = cam.ray(50.0, 50.0);
        assert!((centre.dir - Vec3::NEG_Y).length() < 1e-6);
        let right = cam.ray(100.0, 50.0);
        assert!(right.dir.x > 0.5 && right.dir.is_finite());
        // camera up = forward x right = (0,1,0) x (1,0,0) = (0,0,-1): the top row looks to -z.
        assert!(cam.ray(50.0, 0.0).dir.z < -0.5);
    }

    #[test]
    fn up_z_camera_is_the_up_y_camera_rotated() {
        // Rotating the world by +90 degrees about x maps +y to +z and -z to +y.
        let y_up = Camera::new(Vec3::ZERO, Vec3::NEG_Z, 60.0, 40, 30);
        let z_up = Camera::with_up(Vec3::ZERO, Vec3::Y, Vec3::Z, 60.0, 40, 30);
        let rotate = |v: Vec3| Vec3::new(v.x, -v.z, v.y);
        for (x, y) in [(0.0, 0.0), (40.0, 0.0), (13.0, 29.0), (20.0, 15.0)] {
            let expected = rotate(y_up.ray(x, y).dir);
            assert!((z_up.ray(x, y).dir - expected).length() < 1e-6, "{x},{y}");
        }
        assert_eq!(
            Camera::with_up(Vec3::ONE, Vec3::ZERO, Vec3::Y * 3.0, 45.0, 8, 8),
            Camera::new(Vec3::ONE, Vec3::ZERO, 45.0, 8, 8)
        );
    }

    #[test]
    fn view_parallel_to_a_general_up_still_gives_a_frame() {
        for (from, up) in [(Vec3::X, Vec3::X), (Vec3::new(0.0, 0.0, 2.0), Vec3::NEG_Z)] {
            let cam = Camera::with_up(from, Vec3::ZERO, up, 90.0, 10, 10);
            let corner = cam.ray(0.0, 0.0).dir;
            assert!(corner.is_finite());
            let centre = cam.ray(5.0, 5.0).dir;
            assert!((centre + from.normalize()).length() < 1e-6);
            assert!(corner.dot(centre) < 0.99);
        }
    }
}
