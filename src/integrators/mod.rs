//! Integrators: what a camera ray is worth, one per mode. [`debug`] gives depth and
//! normals, [`whitted`] SPEC's recursive Phong lighting, [`path`] physically based
//! global illumination.
//!
//! The integrator is chosen once per render: `render` matches on the mode and runs a
//! pixel loop compiled for that integrator, so the per-ray calls are static and can be
//! inlined. A new mode adds a struct here and one arm to that match.

pub mod debug;
pub mod path;
mod phong_lanes;
pub mod whitted;

pub use debug::{DepthIntegrator, NormalIntegrator};
pub use path::PathIntegrator;
pub use whitted::WhittedIntegrator;

use crate::camera::Camera;
use crate::math::{Float, Ray, Vec3};
use crate::sampler::{PixelSample, PixelSampler};
use crate::scene::Scene;
use crate::stats::RayCounts;

/// Computes the linear value of camera rays. Shared by every rendering thread, so it
/// holds settings only: everything that changes per ray lives on the stack.
pub trait Integrator: Sync {
    /// How many dimensions [`Integrator::radiance`] draws from its `sample` per camera
    /// ray, at most (see [`PixelSample`]); 0 for a deterministic integrator. The
    /// renderer's sampler is built for this many.
    fn dimensions(&self) -> u32;

    /// The linear value of the camera ray `ray`, drawing from `sample` the random
    /// values it needs; the secondary rays it traces are added to `rays` (the camera
    /// ray is counted by the caller).
    fn radiance(
        &self,
        scene: &Scene,
        ray: &Ray,
        sample: &mut PixelSample,
        rays: &mut RayCounts,
    ) -> Vec3;

    /// The linear value of pixel (`column`, `row`) of an image `width` pixels wide:
    /// the mean of [`Integrator::radiance`] over the camera rays `sampler` places in
    /// it, each counted as a primary ray in `rays`. An integrator may override this to
    /// trace the pixel's rays together, if it gives each the same value.
    #[inline]
    fn pixel(
        &self,
        scene: &Scene,
        camera: &Camera,
        sampler: &PixelSampler,
        (column, row, width): (u32, u32, u32),
        rays: &mut RayCounts,
    ) -> Vec3 {
        sampler.average(column, row, width, |x: Float, y: Float, sample| {
            rays.primary += 1;
            let ray = camera.sample_ray(x, y, sample);
            self.radiance(scene, &ray, sample, rays)
        })
    }
}
