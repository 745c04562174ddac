//! The linear framebuffer the integrators fill: one value per pixel, before any
//! post-processing ([`crate::postprocess`]) or encoding ([`crate::output`]).

use crate::math::Vec3;

/// Linear per-pixel values, row 0 at the top: radiance in full mode, the distance in
/// every channel in depth mode (infinity on a miss), the unit normal in normal mode
/// (zero on a miss).
#[derive(Clone, Debug, PartialEq)]
pub struct Film {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `width * height` values, row by row.
    pub pixels: Vec<Vec3>,
}
