//! The pinhole LookAt camera of SPEC: focal length 1, vertical field of view, square
//! pixels, rays through pixel centres, row 0 at the top. Also a thin lens (depth of
//! field, [`Camera::with_thin_lens`]), an orthographic projection
//! ([`Camera::orthographic`]), OpenCV's pinhole intrinsics ([`Camera::with_intrinsics`])
//! and poses given as camera-to-world matrices ([`pose_from_matrix`]), which become
//! LookAt values so that every mode sees the same camera either way.

use wide::f32x16;

use crate::bvh::PACKET_SIZE;
use crate::math::{Float, Ray, Vec2, Vec3, dot_lanes, try_unit, view_basis};
use crate::options::{Mode, Projection, RenderOptions};
use crate::sampler::PixelSample;

/// What the rays leave from.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Lens {
    /// Every ray from the eye: SPEC's camera.
    Pinhole,
    /// A thin lens of `radius` focused at `focus` (both in scene units, positive).
    Thin { radius: Float, focus: Float },
    /// Parallel rays along the view direction from the image rectangle (whose
    /// half-extents are then in scene units).
    Orthographic,
}

/// How an image position becomes a point of the image plane at distance 1.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Screen {
    /// SPEC's: the vertical field of view spans the image height, square pixels.
    Fov,
    /// OpenCV's pinhole intrinsics in pixels: focal lengths `fx`, `fy` and the
    /// principal point (`cx`, `cy`), the top-left pixel's centre being (0, 0).
    Intrinsics {
        fx: Float,
        fy: Float,
        cx: Float,
        cy: Float,
    },
}

/// A camera placed by LookAt: a pinhole, a thin lens or orthographic.
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
    lens: Lens,
    screen: Screen,
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

    /// The camera `options` describe (position, target, up, field of view, size,
    /// projection, and in full and path modes the lens: depth and normal modes keep a
    /// pinhole, one exact value per pixel).
    pub fn for_options(options: &RenderOptions) -> Camera {
        let camera = Camera::with_up(
            options.look_from,
            options.look_to,
            options.up,
            options.fov_degrees,
            options.width,
            options.height,
        );
        let camera = match options.projection {
            Projection::Orthographic { half_height } => return camera.orthographic(half_height),
            Projection::Intrinsics { fx, fy, cx, cy } => camera.with_intrinsics(fx, fy, cx, cy),
            Projection::Perspective => camera,
        };
        match options.mode {
            Mode::Full | Mode::Path if options.aperture_radius > 0.0 => {
                let focus = options
                    .focus_distance
                    .unwrap_or_else(|| options.look_from.distance(options.look_to));
                camera.with_thin_lens(options.aperture_radius, focus)
            }
            _ => camera,
        }
    }

    /// This camera with a thin lens of radius `radius` focused at distance `focus`
    /// along the view direction (scene units): a point at distance `z` is seen as a
    /// uniform disc of radius `radius * |z - focus| / (z * focus)` on the image plane
    /// at distance 1 (times the focal length in pixels, `height / (2 tan(fov / 2))`,
    /// in pixels). A radius of 0 (or a focus that is not a positive finite number)
    /// leaves the pinhole.
    pub fn with_thin_lens(self, radius: Float, focus: Float) -> Camera {
        let lens = if radius > 0.0 && focus > 0.0 && focus.is_finite() {
            Lens::Thin { radius, focus }
        } else {
            Lens::Pinhole
        };
        Camera { lens, ..self }
    }

    /// This camera made orthographic: rays parallel to the view direction from the
    /// points of an image rectangle `2 * half_height` scene units high (as wide as the
    /// image's aspect ratio makes it) centred on the eye. glTF's `ymag` is
    /// `half_height`.
    pub fn orthographic(self, half_height: Float) -> Camera {
        Camera {
            half_height,
            half_width: half_height * self.width as Float / self.height as Float,
            lens: Lens::Orthographic,
            ..self
        }
    }

    /// This camera with OpenCV's pinhole intrinsics in pixels instead of its field of
    /// view: focal lengths `fx`, `fy` and principal point (`cx`, `cy`), where the
    /// top-left pixel's centre is (0, 0), so `cx = (width - 1) / 2` is the image's
    /// centre. The camera-space point (x, y, z) (OpenCV's axes: +x right, +y down, +z
    /// ahead) is seen at pixel (`fx x / z + cx`, `fy y / z + cy`).
    pub fn with_intrinsics(self, fx: Float, fy: Float, cx: Float, cy: Float) -> Camera {
        Camera {
            screen: Screen::Intrinsics { fx, fy, cx, cy },
            ..self
        }
    }

    /// The image plane's horizontal coordinate (at distance 1, along `right`) of
    /// image position `x` in pixels from the left edge.
    #[inline]
    fn screen_x(&self, x: Float) -> Float {
        match self.screen {
            Screen::Fov => (2.0 * x / self.width as Float - 1.0) * self.half_width,
            Screen::Intrinsics { fx, cx, .. } => (x - 0.5 - cx) / fx,
        }
    }

    /// The image plane's vertical coordinate (along `up`) of image position `y` in
    /// pixels from the top edge.
    #[inline]
    fn screen_y(&self, y: Float) -> Float {
        match self.screen {
            Screen::Fov => (1.0 - 2.0 * y / self.height as Float) * self.half_height,
            Screen::Intrinsics { fy, cy, .. } => (cy - (y - 0.5)) / fy,
        }
    }

    /// Whether every ray leaves from the eye through its pixel position
    /// ([`Camera::ray`] is the whole story): the pinhole of SPEC, which
    /// [`Camera::tile_rays`] computes in packets.
    pub fn is_pinhole(&self) -> bool {
        self.lens == Lens::Pinhole
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
        let (right, up) = view_basis(backward, up);
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
            lens: Lens::Pinhole,
            screen: Screen::Fov,
        }
    }

    /// The ray through image position (`x`, `y`) in pixels from the top-left corner:
    /// pixel (i, j) has its centre at (i + 0.5, j + 0.5).
    ///
    /// Through the centre of a thin lens: a camera with a lens takes its rays from
    /// [`Camera::sample_ray`].
    #[inline]
    pub fn ray(&self, x: Float, y: Float) -> Ray {
        let (sx, sy) = (self.screen_x(x), self.screen_y(y));
        if self.lens == Lens::Orthographic {
            let origin = self.origin + self.right * sx + self.up * sy;
            return Ray::new(origin, -self.backward);
        }
        let dir = self.right * sx + self.up * sy - self.backward;
        Ray::new(self.origin, dir)
    }

    /// The camera ray through image position (`x`, `y`) of a camera sample: for a
    /// thin lens, from the point of the lens that the sample's lens value
    /// ([`PixelSample::lens`]) picks; otherwise [`Camera::ray`], bit for bit.
    #[inline]
    pub fn sample_ray(&self, x: Float, y: Float, sample: &PixelSample) -> Ray {
        match self.lens {
            Lens::Thin { radius, focus } => self.lens_ray(x, y, sample.lens(), radius, focus),
            _ => self.ray(x, y),
        }
    }

    /// The ray through image position (`x`, `y`) from the lens point that `u` (in
    /// `[0, 1)^2`) picks, uniformly over the lens's disc: the pinhole ray's point at
    /// distance `focus` along the view direction stays where it is.
    fn lens_ray(&self, x: Float, y: Float, u: Vec2, radius: Float, focus: Float) -> Ray {
        let (sx, sy) = (self.screen_x(x), self.screen_y(y));
        let on_plane = self.right * (sx * focus) + self.up * (sy * focus) - self.backward * focus;
        let disc = concentric_disc(u) * radius;
        let from = self.right * disc.x + self.up * disc.y;
        Ray::new(self.origin + from, on_plane - from)
    }

    /// The unit view direction (the optical axis): a point's z-depth is its distance
    /// from the eye along it.
    #[inline]
    pub fn forward(&self) -> Vec3 {
        -self.backward
    }

    /// The ray through the centre of pixel (`column`, `row`).
    #[inline]
    pub fn pixel_ray(&self, column: u32, row: u32) -> Ray {
        self.ray(column as Float + 0.5, row as Float + 0.5)
    }

    /// The rays through the pixel centres of the `columns` x `rows` tile (at most 4 x 4)
    /// whose top left pixel is (`left`, `top`), row by row, into `rays`: bit for bit
    /// [`Camera::pixel_ray`] of each, with each column's and each row's offset computed
    /// once and the sixteen directions normalized in SIMD lanes (the same operations:
    /// glam's `normalize` multiplies by `1 / sqrt(dot)`).
    ///
    /// # Panics
    /// If the tile is wider or taller than 4 pixels, or `rays` is shorter than the tile.
    #[inline]
    pub fn tile_rays(&self, left: u32, top: u32, columns: u32, rows: u32, rays: &mut [Ray]) {
        let count = (columns * rows) as usize;
        assert!(
            columns <= 4 && rows <= 4 && rays.len() >= count,
            "a tile of at most 4 x 4 pixels"
        );
        // The same operations as `pixel_ray`'s, so the same bits.
        let centre = |pixel: u32| pixel as Float + 0.5;
        let sx: [Float; 4] = std::array::from_fn(|c| self.screen_x(centre(left + c as u32)));
        let sy: [Float; 4] = std::array::from_fn(|r| self.screen_y(centre(top + r as u32)));
        let (mut x, mut y) = ([0.0; PACKET_SIZE], [0.0; PACKET_SIZE]);
        for k in 0..count {
            x[k] = sx[k % columns as usize];
            y[k] = sy[k / columns as usize];
        }
        let (x, y) = (f32x16::from(x), f32x16::from(y));
        let [rx, ry, rz] = self.right.to_array().map(f32x16::splat);
        let [ux, uy, uz] = self.up.to_array().map(f32x16::splat);
        let [bx, by, bz] = self.backward.to_array().map(f32x16::splat);
        // `right * sx + up * sy - backward`, then `Ray::new`'s `normalize`.
        let dir = [
            rx * x + ux * y - bx,
            ry * x + uy * y - by,
            rz * x + uz * y - bz,
        ];
        let recip = f32x16::ONE / dot_lanes(dir, dir).sqrt();
        let [dx, dy, dz] = dir.map(|c| (c * recip).to_array());
        for (k, ray) in rays[..count].iter_mut().enumerate() {
            *ray = Ray {
                origin: self.origin,
                dir: Vec3::new(dx[k], dy[k], dz[k]),
            };
        }
    }
}

/// Shirley and Chiu's concentric map of `[0, 1)^2` onto the unit disc, uniform in
/// area (*Physically Based Rendering*, 4th ed., `SampleUniformDiskConcentric`).
#[inline]
pub fn concentric_disc(u: Vec2) -> Vec2 {
    let o = u * 2.0 - Vec2::ONE;
    if o == Vec2::ZERO {
        return Vec2::ZERO;
    }
    let quarter = std::f32::consts::FRAC_PI_4;
    let (r, theta) = if o.x.abs() > o.y.abs() {
        (o.x, quarter * (o.y / o.x))
    } else {
        (o.y, 2.0 * quarter - quarter * (o.x / o.y))
    };
    Vec2::new(theta.cos(), theta.sin()) * r
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

    /// Every ray of a thin lens through an image position passes through the pinhole
    /// ray's point at the focus distance, from a point of the lens's disc; the
    /// lens's centre gives the pinhole's ray; a radius of 0 is the pinhole.
    #[test]
    fn thin_lens_rays_meet_at_the_focus_plane() {
        let pinhole = Camera::new(
            Vec3::new(1.0, 2.0, 3.0),
            Vec3::new(0.0, 1.0, -2.0),
            50.0,
            64,
            48,
        );
        assert_eq!(pinhole.with_thin_lens(0.0, 4.0), pinhole);
        assert!(pinhole.is_pinhole());
        let (radius, focus) = (0.25, 4.0);
        let lens = pinhole.with_thin_lens(radius, focus);
        assert!(!lens.is_pinhole());
        let forward = -pinhole.backward;
        for (x, y) in [(0.0, 0.0), (32.0, 24.0), (63.5, 10.25)] {
            let centre = pinhole.ray(x, y);
            let target = centre.origin + centre.dir * (focus / centre.dir.dot(forward));
            let middle = lens.lens_ray(x, y, Vec2::splat(0.5), radius, focus);
            assert!((middle.dir - centre.dir).length() < 1e-6);
            for u in [Vec2::ZERO, Vec2::new(0.9, 0.1), Vec2::new(0.3, 0.99)] {
                let ray = lens.lens_ray(x, y, u, radius, focus);
                let offset = ray.origin - pinhole.origin;
                assert!(offset.dot(forward).abs() < 1e-6 && offset.length() <= radius + 1e-6);
                let at =
                    ray.origin + ray.dir * ((focus - offset.dot(forward)) / ray.dir.dot(forward));
                assert!((at - target).length() < 1e-4, "{at} {target}");
            }
        }
    }

    #[test]
    fn concentric_disc_is_uniform_in_area() {
        // A grid of the square, counted in four rings of equal area.
        let n = 256;
        let mut rings = [0u32; 4];
        for i in 0..n {
            for j in 0..n {
                let u = Vec2::new(i as Float + 0.5, j as Float + 0.5) / n as Float;
                let p = concentric_disc(u);
                assert!(p.length() <= 1.0 + 1e-6);
                rings[((p.length_squared() * 4.0) as usize).min(3)] += 1;
            }
        }
        let quarter = (n * n / 4) as f64;
        for count in rings {
            // The grid steps past a ring by up to one row: 2% at this size.
            assert!((f64::from(count) / quarter - 1.0).abs() < 0.03, "{rings:?}");
        }
    }

    /// OpenCV's intrinsics: the ray through pixel (u, v)'s centre has the camera-space
    /// direction ((u - cx)/fx, -(v - cy)/fy, -1) in the renderer's axes (y up, looking
    /// down -z), and intrinsics matching the field of view give its rays.
    #[test]
    fn intrinsics_rays_follow_opencv_pixel_centres() {
        let (fx, fy, cx, cy) = (40.0, 30.0, 12.5, 7.25);
        let camera =
            Camera::new(Vec3::ZERO, Vec3::NEG_Z, 60.0, 32, 24).with_intrinsics(fx, fy, cx, cy);
        for (u, v) in [(0u32, 0u32), (31, 23), (12, 7), (5, 20)] {
            let expected =
                Vec3::new((u as Float - cx) / fx, -(v as Float - cy) / fy, -1.0).normalize();
            assert!(
                (camera.pixel_ray(u, v).dir - expected).length() < 1e-6,
                "{u},{v}"
            );
        }
        let fov = Camera::new(Vec3::ZERO, Vec3::NEG_Z, 60.0, 32, 24);
        let f = 12.0 / (30.0 as Float).to_radians().tan();
        let same = fov.with_intrinsics(f, f, 15.5, 11.5);
        for (u, v) in [(0, 0), (31, 23), (16, 3)] {
            assert!((same.pixel_ray(u, v).dir - fov.pixel_ray(u, v).dir).length() < 1e-6);
        }
    }

    /// Orthographic rays are parallel to the view direction, from the image rectangle
    /// centred on the eye.
    #[test]
    fn orthographic_rays_are_parallel() {
        let camera =
            Camera::new(Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, 60.0, 40, 20).orthographic(1.0);
        assert!(!camera.is_pinhole());
        let corner = camera.ray(0.0, 0.0);
        assert_eq!(corner.dir, Vec3::NEG_Z);
        assert!((corner.origin - Vec3::new(-2.0, 1.0, 5.0)).length() < 1e-6);
        let centre = camera.pixel_ray(20, 10);
        assert!((centre.origin - Vec3::new(0.05, -0.05, 5.0)).length() < 1e-6);
    }

    #[test]
    fn tile_rays_are_the_pixel_rays_bit_for_bit() {
        let cameras = [
            Camera::new(
                Vec3::new(0.09, 0.21, 0.27),
                Vec3::new(-0.005, 0.12, -0.005),
                45.0,
                37,
                23,
            ),
            Camera::new(
                Vec3::new(3.0, -2.0, 1e4),
                Vec3::new(0.5, 7.0, -3.0),
                120.0,
                19,
                41,
            ),
            Camera::with_up(
                Vec3::ONE,
                Vec3::ZERO,
                Vec3::new(0.3, 0.1, 1.0),
                10.0,
                1021,
                7,
            ),
            Camera::new(Vec3::new(0.5, 1.0, 4.0), Vec3::ZERO, 60.0, 37, 23)
                .with_intrinsics(31.0, 27.5, 17.25, 11.0),
        ];
        for camera in cameras {
            let mut rays = [Ray::new(Vec3::ZERO, Vec3::Z); PACKET_SIZE];
            for top in (0..camera.height).step_by(4) {
                for left in (0..camera.width).step_by(4) {
                    let (columns, rows) =
                        ((camera.width - left).min(4), (camera.height - top).min(4));
                    camera.tile_rays(left, top, columns, rows, &mut rays);
                    for (k, ray) in rays[..(columns * rows) as usize].iter().enumerate() {
                        let expected =
                            camera.pixel_ray(left + k as u32 % columns, top + k as u32 / columns);
                        let bits = |r: &Ray| {
                            [r.origin.to_array(), r.dir.to_array()].map(|v| v.map(Float::to_bits))
                        };
                        assert_eq!(bits(ray), bits(&expected), "pixel {k} of ({left}, {top})");
                    }
                }
            }
        }
    }
}
