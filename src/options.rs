//! What to render: image size, camera and mode, validated once at the boundary.

use crate::integrators::Mode;
use crate::math::{Float, Vec3, try_unit};
use crate::sampler::MAX_SAMPLES_PER_PIXEL;

/// Largest width or height accepted.
pub const MAX_DIMENSION: u32 = 65_536;
/// Largest pixel count accepted (a 16k x 16k image); the linear film alone takes
/// 12 bytes per pixel.
pub const MAX_PIXELS: u64 = 16_384 * 16_384;
/// Largest recursion depth accepted; the recursion uses the call stack.
pub const MAX_RECURSION_DEPTH: u32 = 64;

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
