//! Depth and normal modes: the nearest hit alone, no lighting.

use super::Integrator;
use crate::math::{Float, Ray, Vec3};
use crate::sampler::PixelSample;
use crate::scene::{Hit, Scene};
use crate::stats::RayCounts;

/// Depth mode: the distance from the ray origin to the nearest hit in every channel;
/// infinity on a miss (post-processing divides by the image's largest finite distance
/// and turns misses white).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DepthIntegrator;

impl Integrator for DepthIntegrator {
    fn dimensions(&self) -> u32 {
        0
    }

    #[inline]
    fn radiance_of(
        &self,
        _: &Scene,
        _: &Ray,
        hit: Option<Hit>,
        _: &mut PixelSample,
        _: &mut RayCounts,
    ) -> Vec3 {
        Vec3::splat(hit.map_or(Float::INFINITY, |hit| hit.t))
    }
}

/// Normal mode: the unit shading normal facing the ray; the zero vector on a miss
/// (post-processing maps it to the colour `n / 2 + 1/2`, misses black).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct NormalIntegrator;

impl Integrator for NormalIntegrator {
    fn dimensions(&self) -> u32 {
        0
    }

    #[inline]
    fn radiance_of(
        &self,
        _: &Scene,
        _: &Ray,
        hit: Option<Hit>,
        _: &mut PixelSample,
        _: &mut RayCounts,
    ) -> Vec3 {
        hit.map_or(Vec3::ZERO, |hit| hit.ns)
    }
}
