//! The parallel pixel loop: the one place the renderer uses threads.

use rayon::prelude::*;

use crate::camera::Camera;
use crate::film::Film;
use crate::integrators;
use crate::math::Vec3;
use crate::options::RenderOptions;
use crate::sampler::PixelSampler;
use crate::scene::Scene;
use crate::stats::RayCounts;

/// Renders `scene` as `options` say into a linear film.
///
/// See also [`render_with_progress`], which reports finished rows and rays traced.
pub fn render(scene: &Scene, options: &RenderOptions) -> Film {
    render_with_progress(scene, options, &|_| {}).0
}

/// [`render`], calling `row_done(row)` once after each row is finished, from the
/// worker thread that rendered it (rows finish in no fixed order), and counting the
/// rays traced by kind. `row_done` is called `height` times per render, never per
/// ray, so it may take a lock or draw a progress bar.
///
/// Rows are spread over rayon's current thread pool; every pixel is a pure function
/// of scene and position, so the film is bit-identical for any number of threads.
/// Counts are kept per row and summed, so threads share nothing while tracing.
pub fn render_with_progress(
    scene: &Scene,
    options: &RenderOptions,
    row_done: &(dyn Fn(u32) + Sync),
) -> (Film, RayCounts) {
    let camera = Camera::for_options(options);
    let sampler = PixelSampler::new(options.samples_per_pixel_in_mode());
    let width = options.width as usize;
    let mut pixels = vec![Vec3::ZERO; width * options.height as usize];
    let rays = pixels
        .par_chunks_mut(width)
        .enumerate()
        .map(|(row, line)| {
            let mut rays = RayCounts::default();
            for (column, pixel) in line.iter_mut().enumerate() {
                *pixel = sampler.average(column as u32, row as u32, options.width, |x, y| {
                    let ray = camera.ray(x, y);
                    integrators::sample(scene, &ray, options.mode, options.depth, &mut rays)
                });
            }
            row_done(row as u32);
            rays
        })
        .reduce(RayCounts::default, |mut a, b| {
            a += b;
            a
        });
    let film = Film {
        width: options.width,
        height: options.height,
        pixels,
    };
    (film, rays)
}
