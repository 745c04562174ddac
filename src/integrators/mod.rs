//! Integrators: what a camera ray is worth, one per mode. [`debug`] gives depth and
//! normals, [`whitted`] SPEC's recursive Phong lighting, [`path`] physically based
//! global illumination.
//!
//! Each integrator owns how it traces a band of image rows
//! ([`Integrator::trace_band`]), as pbrt-v4's `ImageTileIntegrator` owns its tile
//! loop: by default pixel by pixel ([`Integrator::pixel`]), while full mode at one
//! sample per pixel traces 4x4 tiles of camera and shadow rays as packets. `render`
//! knows none of them: it builds the [`ModeIntegrator`] of the options (a closed enum,
//! matched once per band, so that the per-ray calls inside a band are static and can
//! be inlined), spreads bands over the threads and gathers the film. A new
//! integrator is a struct here and one [`ModeIntegrator`] variant.

pub mod aov;
pub mod debug;
pub mod path;
mod phong_lanes;
pub mod whitted;

pub use debug::{DepthIntegrator, NormalIntegrator};
pub use path::PathIntegrator;
pub use whitted::WhittedIntegrator;

use aov::{BandAovs, PixelAovs};

use std::time::{Duration, Instant};

use crate::camera::Camera;
use crate::math::{Float, Ray, Vec3};
use crate::options::{Mode, RenderOptions};
use crate::sampler::{PixelSample, PixelSampler};
use crate::scene::{Hit, Scene};
use crate::stats::RayCounts;

/// What every band of one render shares: the scene, the camera, the sampler placing
/// each pixel's samples, and the whole image's width (pixels are indexed in the
/// whole image, so a pixel gets the same samples whatever tile or band holds it).
#[derive(Clone, Copy, Debug)]
pub struct TileContext<'a> {
    /// The scene rendered.
    pub scene: &'a Scene,
    /// The camera of the whole image.
    pub camera: &'a Camera,
    /// The samples of each pixel, built for the integrator's
    /// [`Integrator::dimensions`].
    pub sampler: &'a PixelSampler,
    /// The whole image's width in pixels.
    pub image_width: u32,
}

/// A band of rows of the image to trace: columns `left..left + width` of rows
/// `top..top + rows`, into `pixels` (`width * rows` values, row by row), with the
/// extra outputs of the same pixels taken from the camera rays' hits (`aovs`).
#[derive(Debug)]
pub struct Band<'a> {
    /// The leftmost column, in the whole image.
    pub left: u32,
    /// The top row, in the whole image.
    pub top: u32,
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub rows: u32,
    /// The band's linear values, row by row.
    pub pixels: &'a mut [Vec3],
    /// The band's extra outputs, filled from the hits of its camera rays.
    pub aovs: BandAovs<'a>,
}

/// Adds up the time spent tracing ray packets apart from shading, for `--stats`,
/// where an integrator has them as separate stages; free when not asked for.
#[derive(Clone, Copy, Debug, Default)]
pub struct TraceClock(Option<Duration>);

impl TraceClock {
    /// A clock that adds up time if `timed`, else does nothing.
    pub fn new(timed: bool) -> TraceClock {
        TraceClock(timed.then_some(Duration::ZERO))
    }

    /// The time added up so far; `None` when not timed, or when the integrator
    /// traced no packets apart (a path tracer traces and shades in turn).
    pub fn time(&self) -> Option<Duration> {
        self.0
    }

    /// Runs `f`, adding its time if timed.
    #[inline(always)]
    pub fn trace<T>(&mut self, f: impl FnOnce() -> T) -> T {
        match self.0 {
            None => f(),
            Some(before) => {
                let start = Instant::now();
                let result = f();
                self.0 = Some(before + start.elapsed());
                result
            }
        }
    }
}

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
    #[inline]
    fn radiance(
        &self,
        scene: &Scene,
        ray: &Ray,
        sample: &mut PixelSample,
        rays: &mut RayCounts,
    ) -> Vec3 {
        self.radiance_of(scene, ray, scene.intersect(ray), sample, rays)
    }

    /// [`Integrator::radiance`] of the camera ray `ray` whose closest hit the caller
    /// traced (`hit`: [`Scene::intersect`]'s answer), so that the extra outputs take
    /// the same hit ([`PixelAovs::intersect`]).
    fn radiance_of(
        &self,
        scene: &Scene,
        ray: &Ray,
        hit: Option<Hit>,
        sample: &mut PixelSample,
        rays: &mut RayCounts,
    ) -> Vec3;

    /// The linear value of pixel (`column`, `row`) of an image `width` pixels wide:
    /// the mean of [`Integrator::radiance`] over the camera rays `sampler` places in
    /// it, each counted as a primary ray in `rays`, their hits added to the pixel's
    /// extra outputs `aovs`. An integrator may override this to trace the pixel's
    /// rays together, if it gives each the same value and the same hit.
    #[inline]
    fn pixel(
        &self,
        scene: &Scene,
        camera: &Camera,
        sampler: &PixelSampler,
        (column, row, width): (u32, u32, u32),
        rays: &mut RayCounts,
        aovs: &mut PixelAovs,
    ) -> Vec3 {
        sampler.average(column, row, width, |x: Float, y: Float, sample| {
            rays.primary += 1;
            let ray = camera.sample_ray(x, y, sample);
            let hit = aovs.intersect(scene, &ray);
            self.radiance_of(scene, &ray, hit, sample, rays)
        })
    }

    /// How many rows [`Integrator::trace_band`] takes at once (the render's bands are
    /// this high, but for the last): 1 unless the integrator traces tiles of several
    /// rows together.
    fn band_rows(&self, _: &TileContext) -> u32 {
        1
    }

    /// Traces `band` into its pixels, counting rays in `rays` and, where the
    /// integrator traces packets apart from shading, their time on `clock`. By
    /// default pixel by pixel through [`Integrator::pixel`]; an integrator may trace
    /// the band's rays together, if each pixel gets the same value.
    #[inline]
    fn trace_band(
        &self,
        context: &TileContext,
        band: Band<'_>,
        rays: &mut RayCounts,
        _clock: &mut TraceClock,
    ) {
        trace_band_by_pixel(self, context, band, rays);
    }
}

/// [`Integrator::trace_band`]'s default: each pixel of `band` through
/// [`Integrator::pixel`].
#[inline]
pub fn trace_band_by_pixel<I: Integrator + ?Sized>(
    integrator: &I,
    context: &TileContext,
    band: Band<'_>,
    rays: &mut RayCounts,
) {
    let width = band.width as usize;
    let mut aovs = band.aovs;
    let mut i = 0;
    for (line, row) in band.pixels.chunks_exact_mut(width).zip(band.top..) {
        for (pixel, column) in line.iter_mut().zip(band.left..) {
            *pixel = integrator.pixel(
                context.scene,
                context.camera,
                context.sampler,
                (column, row, context.image_width),
                rays,
                &mut aovs.pixel(i),
            );
            i += 1;
        }
    }
}

/// The integrator of each [`Mode`], a closed set: `render` traces every band through
/// this enum, matched once per band, never per ray.
#[derive(Clone, Debug)]
pub enum ModeIntegrator {
    /// Depth mode.
    Depth(DepthIntegrator),
    /// Normal mode.
    Normal(NormalIntegrator),
    /// Full mode: SPEC's Whitted renderer.
    Full(WhittedIntegrator),
    /// Path mode.
    Path(Box<PathIntegrator>),
}

impl ModeIntegrator {
    /// The integrator `options.mode` names, set up for `scene`.
    pub fn new(scene: &Scene, options: &RenderOptions) -> ModeIntegrator {
        match options.mode {
            Mode::Depth => ModeIntegrator::Depth(DepthIntegrator),
            Mode::Normal => ModeIntegrator::Normal(NormalIntegrator),
            Mode::Full => ModeIntegrator::Full(WhittedIntegrator {
                max_depth: options.depth,
            }),
            Mode::Path => ModeIntegrator::Path(Box::new(PathIntegrator::new(
                scene,
                options.depth,
                options.default_light,
            ))),
        }
    }
}

/// Calls `$call` on the integrator inside `$self`, whichever it is.
macro_rules! each {
    ($self:expr, $i:ident => $call:expr) => {
        match $self {
            ModeIntegrator::Depth($i) => $call,
            ModeIntegrator::Normal($i) => $call,
            ModeIntegrator::Full($i) => $call,
            ModeIntegrator::Path($i) => $call,
        }
    };
}

impl Integrator for ModeIntegrator {
    fn dimensions(&self) -> u32 {
        each!(self, i => i.dimensions())
    }

    fn radiance(
        &self,
        scene: &Scene,
        ray: &Ray,
        sample: &mut PixelSample,
        rays: &mut RayCounts,
    ) -> Vec3 {
        each!(self, i => i.radiance(scene, ray, sample, rays))
    }

    fn radiance_of(
        &self,
        scene: &Scene,
        ray: &Ray,
        hit: Option<Hit>,
        sample: &mut PixelSample,
        rays: &mut RayCounts,
    ) -> Vec3 {
        each!(self, i => i.radiance_of(scene, ray, hit, sample, rays))
    }

    fn pixel(
        &self,
        scene: &Scene,
        camera: &Camera,
        sampler: &PixelSampler,
        pixel: (u32, u32, u32),
        rays: &mut RayCounts,
        aovs: &mut PixelAovs,
    ) -> Vec3 {
        each!(self, i => i.pixel(scene, camera, sampler, pixel, rays, aovs))
    }

    fn band_rows(&self, context: &TileContext) -> u32 {
        each!(self, i => i.band_rows(context))
    }

    fn trace_band(
        &self,
        context: &TileContext,
        band: Band<'_>,
        rays: &mut RayCounts,
        clock: &mut TraceClock,
    ) {
        each!(self, i => i.trace_band(context, band, rays, clock))
    }
}
