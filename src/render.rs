//! The parallel pixel loop: the one place the renderer uses threads.

use rayon::prelude::*;

use crate::camera::Camera;
use crate::film::Film;
use crate::integrators;
use crate::math::Vec3;
use crate::options::RenderOptions;
use crate::scene::Scene;
use crate::stats::RayCounts;

/// Renders `scene` as `options` say into a linear film.
///
/// See also [`render_counted`], which also reports the rays traced.
pub fn render(scene: &Scene, options: &RenderOptions) -> Film {
    render_counted(scene, options).0
}

/// Renders `scene` and counts the rays traced by kind. Rows are spread over rayon's
/// current thread pool; every pixel is a pure function of scene and position, so the
/// film is bit-identical for any number of threads. Counts are kept per row and
/// summed, so threads share nothing while tracing.
pub fn render_counted(scene: &Scene, options: &RenderOptions) -> (Film, RayCounts) {
    let camera = Camera::new(
        options.look_from,
        options.look_to,
        options.fov_degrees,
        options.width,
        options.height,
    );
    let width = options.width as usize;
    let mut pixels = vec![Vec3::ZERO; width * options.height as usize];
    let rays = pixels
        .par_chunks_mut(width)
        .enumerate()
        .map(|(row, line)| {
            let mut rays = RayCounts::default();
            for (column, pixel) in line.iter_mut().enumerate() {
                let ray = camera.pixel_ray(column as u32, row as u32);
                *pixel = integrators::sample(scene, &ray, options.mode, options.depth, &mut rays);
            }
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
