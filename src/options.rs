//! What to render: image size, camera and mode, validated once at the boundary.

use crate::math::{Float, Vec3, try_unit};
use crate::sampler::MAX_SAMPLES_PER_PIXEL;

/// Largest width or height accepted.
pub const MAX_DIMENSION: u32 = 65_536;
/// Largest pixel count accepted (a 16k x 16k image); the linear film alone takes
/// 12 bytes per pixel.
pub const MAX_PIXELS: u64 = 16_384 * 16_384;
/// Largest recursion depth accepted; the recursion uses the call stack.
pub const MAX_RECURSION_DEPTH: u32 = 64;

/// What the renderer computes per pixel.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Mode {
    /// Distance to the nearest hit, normalized by the image's largest.
    Depth,
    /// The unit normal at the nearest hit, facing the ray (zero on a miss); shown as
    /// the colour `n / 2 + 1/2`.
    Normal,
    /// Whitted lighting, tone mapped and gamma corrected.
    #[default]
    Full,
}

/// Options of one render. Build with [`Default`] and field updates, then
/// [`RenderOptions::validate`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderOptions {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Vertical field of view in degrees, strictly between 0 and 180.
    pub fov_degrees: Float,
    /// Camera position.
    pub look_from: Vec3,
    /// Point the camera looks at.
    pub look_to: Vec3,
    /// World up direction (need not be unit length); +y by default.
    pub up: Vec3,
    /// Recursion depth of full mode: 1 means primary and shadow rays only.
    pub depth: u32,
    /// What to compute.
    pub mode: Mode,
    /// Camera rays per pixel in full mode, averaged in linear space: 1 traces the
    /// pixel centre, more take stratified jittered positions (see
    /// [`crate::sampler`]). Depth and normal modes always take one sample per pixel:
    /// see [`RenderOptions::samples_per_pixel_in_mode`].
    pub samples_per_pixel: u32,
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
            width: 640,
            height: 480,
            fov_degrees: 90.0,
            look_from: Vec3::ZERO,
            look_to: Vec3::NEG_Z,
            up: Vec3::Y,
            depth: 4,
            mode: Mode::Full,
            samples_per_pixel: 1,
        }
    }
}

/// An option value outside its allowed range.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("invalid {option}: {message}")]
pub struct OptionsError {
    /// The option's name, as the command line spells it.
    pub option: &'static str,
    /// What is allowed.
    pub message: String,
}

impl RenderOptions {
    /// Checks every value, so that rendering can trust them.
    ///
    /// # Errors
    /// The first option out of range, with the allowed range.
    pub fn validate(&self) -> Result<(), OptionsError> {
        let fail = |option, message: String| Err(OptionsError { option, message });
        for (option, value) in [("--width", self.width), ("--height", self.height)] {
            if value == 0 || value > MAX_DIMENSION {
                return fail(option, format!("{value} is not in 1..={MAX_DIMENSION}"));
            }
        }
        let pixels = self.width as u64 * self.height as u64;
        if pixels > MAX_PIXELS {
            return fail(
                "--width/--height",
                format!(
                    "{}x{} has more than {MAX_PIXELS} pixels",
                    self.width, self.height
                ),
            );
        }
        if !(self.fov_degrees > 0.0 && self.fov_degrees < 180.0) {
            return fail(
                "--fov",
                format!("{} is not strictly between 0 and 180", self.fov_degrees),
            );
        }
        if !self.look_from.is_finite() || !self.look_to.is_finite() {
            return fail("--look-from/--look-to", "components must be finite".into());
        }
        if self.look_from == self.look_to {
            return fail(
                "--look-from/--look-to",
                "the camera cannot look at its own position".into(),
            );
        }
        if try_unit(self.look_from - self.look_to).is_none() {
            return fail(
                "--look-from/--look-to",
                "the points are too far apart (their distance overflows)".into(),
            );
        }
        if try_unit(self.up).is_none() {
            return fail("--up", "components must be finite and not all zero".into());
        }
        if self.depth == 0 || self.depth > MAX_RECURSION_DEPTH {
            return fail(
                "--depth",
                format!("{} is not in 1..={MAX_RECURSION_DEPTH}", self.depth),
            );
        }
        if self.samples_per_pixel == 0 || self.samples_per_pixel > MAX_SAMPLES_PER_PIXEL {
            return fail(
                "--spp",
                format!(
                    "{} is not in 1..={MAX_SAMPLES_PER_PIXEL}",
                    self.samples_per_pixel
                ),
            );
        }
        Ok(())
    }

    /// The samples per pixel the renderer takes: [`RenderOptions::samples_per_pixel`]
    /// in full mode, 1 in depth and normal modes. An average of distances across a
    /// silhouette is no surface's distance and an average of normals is no unit
    /// normal, so those modes keep exact values (as Blender's depth pass does).
    pub fn samples_per_pixel_in_mode(&self) -> u32 {
        match self.mode {
            Mode::Full => self.samples_per_pixel,
            Mode::Depth | Mode::Normal => 1,
        }
    }
}

/// [`RenderOptions`] with every value optional: what one source (the command line or a
/// scene file) says, before sources are merged. Precedence is explicit:
/// `flags.or(file).resolve()` takes each value from the flags, else from the file, else
/// from [`RenderOptions::default`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PartialOptions {
    /// Image width in pixels.
    pub width: Option<u32>,
    /// Image height in pixels.
    pub height: Option<u32>,
    /// Vertical field of view in degrees.
    pub fov_degrees: Option<Float>,
    /// Camera position.
    pub look_from: Option<Vec3>,
    /// Point the camera looks at.
    pub look_to: Option<Vec3>,
    /// World up direction.
    pub up: Option<Vec3>,
    /// Recursion depth of full mode.
    pub depth: Option<u32>,
    /// What to compute.
    pub mode: Option<Mode>,
    /// Camera rays per pixel in full mode.
    pub samples_per_pixel: Option<u32>,
}

impl PartialOptions {
    /// Each value from `self` if set, else from `fallback`.
    pub fn or(self, fallback: PartialOptions) -> PartialOptions {
        PartialOptions {
            width: self.width.or(fallback.width),
            height: self.height.or(fallback.height),
            fov_degrees: self.fov_degrees.or(fallback.fov_degrees),
            look_from: self.look_from.or(fallback.look_from),
            look_to: self.look_to.or(fallback.look_to),
            up: self.up.or(fallback.up),
            depth: self.depth.or(fallback.depth),
            mode: self.mode.or(fallback.mode),
            samples_per_pixel: self.samples_per_pixel.or(fallback.samples_per_pixel),
        }
    }

    /// The complete options, unset values taken from [`RenderOptions::default`]. Not
    /// validated: call [`RenderOptions::validate`].
    pub fn resolve(self) -> RenderOptions {
        let d = RenderOptions::default();
        // A full struct literal, so that a new option cannot be forgotten here.
        RenderOptions {
            width: self.width.unwrap_or(d.width),
            height: self.height.unwrap_or(d.height),
            fov_degrees: self.fov_degrees.unwrap_or(d.fov_degrees),
            look_from: self.look_from.unwrap_or(d.look_from),
            look_to: self.look_to.unwrap_or(d.look_to),
            up: self.up.unwrap_or(d.up),
            depth: self.depth.unwrap_or(d.depth),
            mode: self.mode.unwrap_or(d.mode),
            samples_per_pixel: self.samples_per_pixel.unwrap_or(d.samples_per_pixel),
        }
    }
}

#[cfg(test)]
mod partial_tests {
    use super::*;

    #[test]
    fn set_values_win_then_fallback_then_defaults() {
        let flags = PartialOptions {
            width: Some(10),
            mode: Some(Mode::Depth),
            ..PartialOptions::default()
        };
        let file = PartialOptions {
            width: Some(20),
            height: Some(30),
            up: Some(Vec3::Z),
            ..PartialOptions::default()
        };
        let options = flags.or(file).resolve();
        assert_eq!((options.width, options.height), (10, 30));
        assert_eq!((options.mode, options.up), (Mode::Depth, Vec3::Z));
        assert_eq!(options.fov_degrees, RenderOptions::default().fov_degrees);
        assert_eq!(
            PartialOptions::default().resolve(),
            RenderOptions::default()
        );
    }

    #[test]
    fn up_must_be_finite_and_non_zero() {
        for up in [Vec3::ZERO, Vec3::new(0.0, Float::NAN, 0.0)] {
            let err = RenderOptions {
                up,
                ..RenderOptions::default()
            }
            .validate()
            .unwrap_err();
            assert_eq!(err.option, "--up");
        }
    }
}
