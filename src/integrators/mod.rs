//! Integrators: what a camera ray is worth. [`debug`] gives depth and normals,
//! [`whitted`] SPEC's recursive Phong lighting.

pub mod debug;
pub mod whitted;

use crate::math::{Ray, Vec3};
use crate::options::Mode;
use crate::scene::Scene;
use crate::stats::RayCounts;

/// The linear value of one camera ray in `mode`. For depth mode this is the distance
/// in every channel, or infinity where the ray hits nothing; for normal mode the
/// unit normal, or zero where the ray hits nothing. Rays traced are added to `rays`.
#[inline]
pub fn sample(scene: &Scene, ray: &Ray, mode: Mode, max_depth: u32, rays: &mut RayCounts) -> Vec3 {
    rays.primary += 1;
    match mode {
        Mode::Depth => debug::depth(scene, ray),
        Mode::Normal => debug::normal(scene, ray),
        Mode::Full => whitted::radiance(scene, ray, max_depth, rays),
    }
}
