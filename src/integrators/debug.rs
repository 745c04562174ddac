//! Depth and normal modes.

use crate::math::{Float, Ray, Vec3};
use crate::scene::Scene;

/// Distance from the ray origin to the nearest hit in every channel; infinity on a
/// miss (post-processing turns it white).
#[inline]
pub fn depth(scene: &Scene, ray: &Ray) -> Vec3 {
    Vec3::splat(scene.intersect(ray).map_or(Float::INFINITY, |hit| hit.t))
}

/// `n / 2 + 1/2` for the shading normal facing the ray; black on a miss.
#[inline]
pub fn normal(scene: &Scene, ray: &Ray) -> Vec3 {
    scene
        .intersect(ray)
        .map_or(Vec3::ZERO, |hit| hit.ns * 0.5 + Vec3::splat(0.5))
}
