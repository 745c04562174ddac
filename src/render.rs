//! The parallel pixel loop: the one place the renderer uses threads.

use rayon::prelude::*;

use crate::camera::Camera;
use crate::film::Film;
use crate::integrators;
use crate::options::RenderOptions;
use crate::sampler::PixelSampler;
use crate::scene::Scene;

/// Renders `scene` as `options` say into a linear film. Rows are spread over rayon's
/// current thread pool; every pixel is a pure function of scene and position, so the
/// film is bit-identical for any number of threads.
///
/// See also [`render_with_progress`], which reports finished rows.
pub fn render(scene: &Scene, options: &RenderOptions) -> Film {
    render_with_progress(scene, options, &|_| {})
}

/// [`render`], calling `row_done(row)` once after each row is finished, from the
/// worker thread that rendered it (rows finish in no fixed order). It is called
/// `height` times per render, never per ray, so it may take a lock or draw a
/// progress bar.
pub fn render_with_progress(
    scene: &Scene,
    options: &RenderOptions,
    row_done: &(dyn Fn(u32) + Sync),
) -> Film {
    let camera = Camera::new(
        options.look_from,
        options.look_to,
        options.fov_degrees,
        options.width,
        options.height,
    );
    let sampler = PixelSampler::new(options.samples_per_pixel_in_mode());
    let width = options.width as usize;
    let mut pixels = vec![glam::Vec3::ZERO; width * options.height as usize];
    pixels
        .par_chunks_mut(width)
        .enumerate()
        .for_each(|(row, line)| {
            for (column, pixel) in line.iter_mut().enumerate() {
                *pixel = sampler.average(column as u32, row as u32, options.width, |x, y| {
                    integrators::sample(scene, &camera.ray(x, y), options.mode, options.depth)
                });
            }
            row_done(row as u32);
        });
    Film {
        width: options.width,
        height: options.height,
        pixels,
    }
}
