//! Ray-throughput measurements on a built scene, as the `bench` command reports them:
//! closest-hit primary rays and any-hit shadow rays, without shading, so that the
//! numbers compare with ray-query libraries such as Embree on the same rays.

use std::time::Instant;

use rayon::prelude::*;

use crate::camera::Camera;
use crate::math::{Float, Ray};
use crate::options::RenderOptions;
use crate::scene::{Hit, Scene};

/// The rays of one benchmark: one primary ray per pixel centre, and from every
/// primary hit one shadow ray to each light.
pub struct RayWorkload {
    /// Camera rays, row by row.
    pub primary: Vec<Ray>,
    /// Shadow rays with their distance to the light.
    pub shadow: Vec<(Ray, Float)>,
    /// How many primary rays hit something.
    pub primary_hits: usize,
}

impl RayWorkload {
    /// Generates the rays for `options`' camera (tracing the primary rays once to find
    /// where the shadow rays start).
    pub fn new(scene: &Scene, options: &RenderOptions) -> RayWorkload {
        let camera = Camera::for_options(options);
        let primary: Vec<Ray> = (0..options.height)
            .flat_map(|row| (0..options.width).map(move |column| camera.pixel_ray(column, row)))
            .collect();
        let hits = trace_closest(scene, &primary);
        let primary_hits = hits.iter().flatten().count();
        let shadow = hits
            .iter()
            .flatten()
            .flat_map(|hit| {
                scene
                    .lights
                    .iter()
                    .map(|light| hit.spawn_ray_to(light.position))
            })
            .collect();
        RayWorkload {
            primary,
            shadow,
            primary_hits,
        }
    }
}

/// Closest hits of `rays`, in parallel.
pub fn trace_closest(scene: &Scene, rays: &[Ray]) -> Vec<Option<Hit>> {
    let mut hits = Vec::with_capacity(rays.len());
    rays.par_iter()
        .map(|ray| scene.intersect(ray))
        .collect_into_vec(&mut hits);
    hits
}

/// The primitive each of `rays` hits first (`u32::MAX` for a miss), in parallel:
/// closest-hit queries without shading, as a ray-query library such as Embree
/// answers them (its Python binding returns an array of primitive ids).
pub fn trace_closest_primitives(scene: &Scene, rays: &[Ray]) -> Vec<u32> {
    let mut ids = Vec::with_capacity(rays.len());
    rays.par_iter()
        .map(|ray| {
            scene
                .intersect_primitive(ray)
                .map_or(u32::MAX, |(prim, _)| prim)
        })
        .collect_into_vec(&mut ids);
    ids
}

/// How many of `rays` are blocked before their distance, in parallel.
pub fn count_occluded(scene: &Scene, rays: &[(Ray, Float)]) -> usize {
    rays.par_iter()
        .filter(|(ray, t_max)| scene.occluded(ray, *t_max))
        .count()
}

/// Runs `f` `repeat` times (at least once) and returns its last result and the median
/// wall time in seconds.
pub fn median_time<T>(repeat: usize, mut f: impl FnMut() -> T) -> (T, f64) {
    median_time_with(repeat, || (), |()| f())
}

/// [`median_time`] of `f` on a fresh `input()` each time, made before the clock
/// starts; the previous result is dropped before it starts too, so that only `f` is
/// timed.
pub fn median_time_with<I, T>(
    repeat: usize,
    mut input: impl FnMut() -> I,
    mut f: impl FnMut(I) -> T,
) -> (T, f64) {
    let mut times = Vec::with_capacity(repeat.max(1));
    let mut result = None;
    for _ in 0..repeat.max(1) {
        drop(result.take());
        let input = input();
        let start = Instant::now();
        result = Some(f(input));
        times.push(start.elapsed().as_secs_f64());
    }
    times.sort_by(f64::total_cmp);
    let result = result.expect("ran at least once");
    (result, times[times.len() / 2])
}
