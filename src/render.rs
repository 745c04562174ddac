//! The parallel pixel loop: the one place the renderer uses threads.

use std::fmt;
use std::time::{Duration, Instant};

use rayon::prelude::*;

use crate::bvh::PACKET_SIZE;
use crate::camera::Camera;
use crate::film::Film;
use crate::integrators::whitted::PacketScratch;
use crate::integrators::{
    DepthIntegrator, Integrator, NormalIntegrator, PathIntegrator, WhittedIntegrator,
};
use crate::math::{Ray, Vec3};
use crate::options::{Mode, RenderOptions};
use crate::sampler::PixelSampler;
use crate::scene::Scene;
use crate::stats::RayCounts;

/// A rectangle of the image in pixels: columns `x..x + width`, rows `y..y + height`,
/// row 0 at the top.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Tile {
    /// The leftmost column.
    pub x: u32,
    /// The top row.
    pub y: u32,
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
}

impl Tile {
    /// The whole image of `options`.
    pub fn whole(options: &RenderOptions) -> Tile {
        Tile {
            x: 0,
            y: 0,
            width: options.width,
            height: options.height,
        }
    }
}

impl fmt::Display for Tile {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{}x{} at ({}, {})",
            self.width, self.height, self.x, self.y
        )
    }
}

/// A tile that [`render_tile`] cannot render.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum TileError {
    /// The tile is 0 pixels wide or high.
    #[error("tile {tile} has no pixels")]
    Empty {
        /// The tile asked for.
        tile: Tile,
    },
    /// Part of the tile lies outside the image.
    #[error("tile {tile} does not lie inside the {width}x{height} image")]
    Outside {
        /// The tile asked for.
        tile: Tile,
        /// The image's width.
        width: u32,
        /// The image's height.
        height: u32,
    },
}

/// Renders `scene` as `options` say into a linear film.
///
/// See also [`render_with_progress`], which reports finished rows and rays traced, and
/// [`render_tile`], which renders part of the image.
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
    let (film, rays, _) = render_region(scene, options, Tile::whole(options), row_done, false);
    (film, rays)
}

/// How the render's time divided between tracing rays and shading, where the two are
/// separate stages: in full mode at one sample per pixel, where camera and shadow rays
/// are traced as packets apart from the shading that uses them.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RenderTimes {
    /// Of the threads' time in the pixel loop, the fraction spent tracing camera and
    /// shadow ray packets; the rest is shading (with the reflected and refracted rays
    /// it traces one by one). `None` where tracing and shading are not separate
    /// stages (a path tracer traces and shades in turn, ray by ray).
    pub trace_fraction: Option<f64>,
}

/// [`render_with_progress`], also timing the tracing of ray packets apart from the
/// shading where the render has them as separate stages ([`RenderTimes`]), for
/// `--stats`. The clock is read a few times per 4x4 tile, never per ray.
pub fn render_with_stats(
    scene: &Scene,
    options: &RenderOptions,
    row_done: &(dyn Fn(u32) + Sync),
) -> (Film, RayCounts, RenderTimes) {
    render_region(scene, options, Tile::whole(options), row_done, true)
}

/// The pixels of `tile` of the image `options` describe, as a film of the tile's size:
/// bit-identical to the same pixels of [`render`]'s film (the same camera rays and
/// sample values), on any number of threads. So tiles rendered apart, on other threads
/// or machines, put together make exactly the whole image; post-processing
/// ([`Film::to_image`]) needs the whole film, as it divides by image-wide maxima.
///
/// # Errors
/// [`TileError`] when the tile has no pixels or does not lie inside the image.
pub fn render_tile(scene: &Scene, options: &RenderOptions, tile: Tile) -> Result<Film, TileError> {
    if tile.width == 0 || tile.height == 0 {
        return Err(TileError::Empty { tile });
    }
    // In u64: `x + width` may not fit in a u32.
    let fits = |start: u32, length: u32, size: u32| start as u64 + length as u64 <= size as u64;
    if !fits(tile.x, tile.width, options.width) || !fits(tile.y, tile.height, options.height) {
        return Err(TileError::Outside {
            tile,
            width: options.width,
            height: options.height,
        });
    }
    Ok(render_region(scene, options, tile, &|_| {}, false).0)
}

/// Chooses the integrator of `options.mode`, once for the whole region.
/// With `timed`, also measures what [`RenderTimes`] holds.
fn render_region(
    scene: &Scene,
    options: &RenderOptions,
    tile: Tile,
    row_done: &(dyn Fn(u32) + Sync),
    timed: bool,
) -> (Film, RayCounts, RenderTimes) {
    let untimed = |(film, rays)| (film, rays, RenderTimes::default());
    match options.mode {
        Mode::Depth => untimed(render_with(
            scene,
            options,
            &DepthIntegrator,
            tile,
            row_done,
        )),
        Mode::Normal => untimed(render_with(
            scene,
            options,
            &NormalIntegrator,
            tile,
            row_done,
        )),
        Mode::Full => {
            let whitted = WhittedIntegrator {
                max_depth: options.depth,
            };
            // Packets of pixel centres' rays need the pinhole's shared eye.
            if options.samples_per_pixel_in_mode() == 1 && Camera::for_options(options).is_pinhole()
            {
                render_whitted_packets(scene, options, &whitted, tile, row_done, timed)
            } else {
                untimed(render_with(scene, options, &whitted, tile, row_done))
            }
        }
        Mode::Path => {
            let path = PathIntegrator::new(scene, options.depth, options.default_light);
            untimed(render_with(scene, options, &path, tile, row_done))
        }
    }
}

/// The pixel loop over `tile` (which lies inside the image), compiled once per
/// integrator so that no call per ray is dynamic. Pixels are indexed in the whole
/// image, so the sampler gives a pixel the same values whatever tile holds it.
fn render_with<I: Integrator>(
    scene: &Scene,
    options: &RenderOptions,
    integrator: &I,
    tile: Tile,
    row_done: &(dyn Fn(u32) + Sync),
) -> (Film, RayCounts) {
    let camera = Camera::for_options(options);
    let sampler = PixelSampler::new(options.samples_per_pixel_in_mode(), integrator.dimensions())
        .with_seed(options.seed);
    let width = tile.width as usize;
    let mut pixels = vec![Vec3::ZERO; width * tile.height as usize];
    let rays = pixels
        .par_chunks_mut(width)
        .zip(tile.y..tile.y + tile.height)
        .map(|(line, row)| {
            let mut rays = RayCounts::default();
            for (pixel, column) in line.iter_mut().zip(tile.x..) {
                *pixel = integrator.pixel(
                    scene,
                    &camera,
                    &sampler,
                    (column, row, options.width),
                    &mut rays,
                );
            }
            row_done(row);
            rays
        })
        .reduce(RayCounts::default, |mut a, b| {
            a += b;
            a
        });
    let film = Film {
        width: tile.width,
        height: tile.height,
        pixels,
    };
    (film, rays)
}

/// Side of the square pixel tiles whose camera rays are traced as one packet.
const PACKET_TILE: u32 = 4;
const _: () = assert!((PACKET_TILE * PACKET_TILE) as usize == PACKET_SIZE);

/// [`render_with`] for the Whitted integrator at one sample per pixel: the pixel
/// centres' camera rays of each 4x4 tile, and their shadow rays, are traced as packets
/// ([`WhittedIntegrator::radiance_packet`]); the film is bit-identical to
/// [`render_with`]'s. Bands of four rows are spread over the threads.
fn render_whitted_packets(
    scene: &Scene,
    options: &RenderOptions,
    integrator: &WhittedIntegrator,
    tile: Tile,
    row_done: &(dyn Fn(u32) + Sync),
    timed: bool,
) -> (Film, RayCounts, RenderTimes) {
    let camera = Camera::for_options(options);
    let width = tile.width as usize;
    let band_pixels = width * PACKET_TILE as usize;
    let mut pixels = vec![Vec3::ZERO; width * tile.height as usize];
    let rays = pixels
        .par_chunks_mut(band_pixels)
        .zip(
            (tile.y..tile.y + tile.height)
                .into_par_iter()
                .step_by(PACKET_TILE as usize),
        )
        .map(|(band, top)| {
            let band_start = timed.then(Instant::now);
            let mut rays = RayCounts::default();
            let mut scratch = PacketScratch::default();
            scratch.time_tracing(timed);
            let rows = (band.len() / width) as u32;
            let mut camera_rays = [Ray::new(Vec3::ZERO, Vec3::Z); PACKET_SIZE];
            let mut values = [Vec3::ZERO; PACKET_SIZE];
            for left in (tile.x..tile.x + tile.width).step_by(PACKET_TILE as usize) {
                let columns = (tile.x + tile.width - left).min(PACKET_TILE);
                camera.tile_rays(left, top, columns, rows, &mut camera_rays);
                let count = (columns * rows) as usize;
                rays.primary += count as u64;
                integrator.radiance_packet(
                    scene,
                    &camera_rays[..count],
                    &mut values[..count],
                    &mut rays,
                    &mut scratch,
                );
                let mut values = values[..count].iter();
                for row in 0..rows as usize {
                    let start = row * width + (left - tile.x) as usize;
                    for pixel in &mut band[start..start + columns as usize] {
                        *pixel = *values.next().expect("one value per pixel");
                    }
                }
            }
            for row in top..top + rows {
                row_done(row);
            }
            let band_time = band_start.map_or(Duration::ZERO, |start| start.elapsed());
            (rays, scratch.tracing_time(), band_time)
        })
        .reduce(
            || (RayCounts::default(), Duration::ZERO, Duration::ZERO),
            |mut a, b| {
                a.0 += b.0;
                (a.0, a.1 + b.1, a.2 + b.2)
            },
        );
    let (rays, tracing, total) = rays;
    let film = Film {
        width: tile.width,
        height: tile.height,
        pixels,
    };
    let times = RenderTimes {
        trace_fraction: (timed && !total.is_zero())
            .then(|| tracing.as_secs_f64() / total.as_secs_f64()),
    };
    (film, rays, times)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Ray;
    use crate::sampler::PixelSample;
    use crate::scene::Scene;

    /// An integrator as a path tracer uses the sampler: three dimensions per camera
    /// ray, mixed with where the ray goes.
    struct Probe;

    impl Integrator for Probe {
        fn dimensions(&self) -> u32 {
            3
        }

        fn radiance(
            &self,
            _: &Scene,
            ray: &Ray,
            sample: &mut PixelSample,
            _: &mut RayCounts,
        ) -> Vec3 {
            let a = sample.next_1d();
            let b = sample.next_2d();
            Vec3::new(a, b.x, b.y) + ray.dir
        }
    }

    fn empty_scene() -> Scene {
        Scene::build(Default::default(), &Default::default())
    }

    fn probe(options: &RenderOptions, tile: Tile) -> Film {
        render_with(&empty_scene(), options, &Probe, tile, &|_| {}).0
    }

    #[test]
    fn sample_dimensions_of_a_tile_are_those_of_the_whole_image() {
        let options = RenderOptions {
            width: 23,
            height: 17,
            samples_per_pixel: 5,
            ..RenderOptions::default()
        };
        let whole = probe(&options, Tile::whole(&options));
        let pixels: std::collections::HashSet<_> = whole
            .pixels
            .iter()
            .map(|v| v.to_array().map(f32::to_bits))
            .collect();
        assert_eq!(pixels.len(), whole.pixels.len(), "pixels repeat");
        for (x, y, width, height) in [(0, 0, 1, 1), (22, 16, 1, 1), (5, 3, 7, 9), (16, 10, 7, 7)] {
            let tile = Tile {
                x,
                y,
                width,
                height,
            };
            let part = probe(&options, tile);
            for row in 0..height {
                let got = &part.pixels[(row * width) as usize..][..width as usize];
                let start = ((y + row) * options.width + x) as usize;
                assert_eq!(
                    got,
                    &whole.pixels[start..][..width as usize],
                    "{tile}, row {row}"
                );
            }
        }
    }

    /// The packet loop of full mode makes exactly the film of the ray-by-ray loop,
    /// with the same ray counts, for whole images and for tiles whose edges cut the
    /// 4x4 packets.
    #[test]
    fn whitted_packets_render_exactly_the_single_ray_film() {
        let scene = crate::scene::packet_tests::generated_scene(60, true, 3);
        let options = RenderOptions {
            width: 70,
            height: 45,
            look_from: Vec3::new(0.3, 1.2, 1.8),
            look_to: Vec3::new(0.0, 0.1, 0.0),
            fov_degrees: 55.0,
            depth: 4,
            ..RenderOptions::default()
        };
        let whitted = WhittedIntegrator { max_depth: 4 };
        for tile in [
            Tile::whole(&options),
            Tile {
                x: 3,
                y: 5,
                width: 29,
                height: 18,
            },
        ] {
            let (single, single_rays) = render_with(&scene, &options, &whitted, tile, &|_| {});
            let (packets, packet_rays, _) =
                render_whitted_packets(&scene, &options, &whitted, tile, &|_| {}, false);
            let bits = |film: &Film| -> Vec<[u32; 3]> {
                film.pixels
                    .iter()
                    .map(|v| v.to_array().map(f32::to_bits))
                    .collect()
            };
            for (i, (a, b)) in bits(&single).iter().zip(&bits(&packets)).enumerate() {
                assert_eq!(a, b, "{tile}: pixel {i}");
            }
            assert_eq!(single_rays, packet_rays, "{tile}");
            assert!(
                single_rays.shadow > 200
                    && single_rays.reflected > 20
                    && single_rays.refracted > 20,
                "{single_rays:?}"
            );
        }
    }

    #[test]
    fn sample_dimensions_do_not_depend_on_the_thread_count() {
        let options = RenderOptions {
            width: 31,
            height: 9,
            samples_per_pixel: 3,
            ..RenderOptions::default()
        };
        let on = |threads| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| probe(&options, Tile::whole(&options)))
        };
        assert_eq!(on(1), on(3));
    }
}
