//! Depth and normal modes.

use crate::math::{Float, Ray, Vec3};
use crate::scene::Scene;

/// Distance from the ray origin to the nearest hit in every channel; infinity on a
/// miss (post-processing turns it white).
#[inline]
pub fn depth(scene: &Scene, ray: &Ray) -> Vec3 {
    Vec3::splat(scene.intersect(ray).map_or(Float::INFINITY, |hit| hit.t))
}

/// The unit shading normal facing the ray; the zero vector on a miss.
/// Post-processing maps it to the colour `n / 2 + 1/2` (misses black).
#[inline]
pub fn normal(scene: &Scene, ray: &Ray) -> Vec3 {
    scene.intersect(ray).map_or(Vec3::ZERO, |hit| hit.ns)
}
