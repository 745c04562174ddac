//! The parallel pixel loop: the one place the renderer uses threads.

use rayon::prelude::*;

use crate::camera::Camera;
use crate::film::Film;
use crate::integrators;
use crate::options::RenderOptions;
use crate::scene::Scene;

/// Renders `scene` as `options` say into a linear film. Rows are spread over rayon's
/// current thread pool; every pixel is a pure function of scene and position, so the
/// film is bit-identical for any number of threads.
pub fn render(scene: &Scene, options: &RenderOptions) -> Film {
    let camera = Camera::new(
        options.look_from,
        options.look_to,
        options.fov_degrees,
        options.width,
        options.height,
    );
    let width = options.width as usize;
    let mut pixels = vec![glam::Vec3::ZERO; width * options.height as usize];
    pixels
        .par_chunks_mut(width)
        .enumerate()
        .for_each(|(row, line)| {
            for (column, pixel) in line.iter_mut().enumerate() {
                let ray = camera.pixel_ray(column as u32, row as u32);
                *pixel = integrators::sample(scene, &ray, options.mode, options.depth);
            }
        });
    Film {
        width: options.width,
        height: options.height,
        pixels,
    }
}
