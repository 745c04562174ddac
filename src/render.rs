//! The parallel pixel loop: the one place the renderer uses threads.

use std::fmt;
use std::time::{Duration, Instant};

use rayon::prelude::*;

use crate::camera::Camera;
use crate::film::{Aov, AovPlanes, Film, Outputs};
use crate::integrators::aov::{AovPixel, AovSet, BandAovs, finish_band};
use crate::integrators::{Band, Integrator, ModeIntegrator, TileContext, TraceClock};
use crate::math::Vec3;
use crate::options::RenderOptions;
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

    /// The tile itself if it has pixels and lies inside the image of `options`, as
    /// [`render_tile`] requires.
    ///
    /// # Errors
    /// [`TileError::Empty`] or [`TileError::Outside`].
    pub fn check(self, options: &RenderOptions) -> Result<Tile, TileError> {
        let tile = self;
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
        Ok(tile)
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
    let (outputs, rays, _) =
        render_region(scene, options, Tile::whole(options), &[], row_done, false);
    (outputs.film, rays)
}

/// [`render`] with the extra outputs `aovs` ([`Aov`]: depth, normal, albedo, alpha,
/// object and material ids) in the same pass: from the hits of the camera rays the
/// colour's integrator traces (and, for the ids at more than one sample per pixel,
/// a ray through each pixel centre).
pub fn render_outputs(scene: &Scene, options: &RenderOptions, aovs: &[Aov]) -> Outputs {
    render_outputs_with_stats(scene, options, aovs, &|_| {}, false).0
}

/// [`render_outputs`], calling `row_done` and counting rays as
/// [`render_with_progress`] does, and with `timed` timing the tracing as
/// [`render_with_stats`] does. The counts are those of the colour's rays: the
/// centre rays of the ids at more than one sample per pixel are not counted.
pub fn render_outputs_with_stats(
    scene: &Scene,
    options: &RenderOptions,
    aovs: &[Aov],
    row_done: &(dyn Fn(u32) + Sync),
    timed: bool,
) -> (Outputs, RayCounts, RenderTimes) {
    render_region(scene, options, Tile::whole(options), aovs, row_done, timed)
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
    let (outputs, rays, times) =
        render_region(scene, options, Tile::whole(options), &[], row_done, true);
    (outputs.film, rays, times)
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
    render_tile_outputs(scene, options, tile, &[]).map(|outputs| outputs.film)
}

/// [`render_tile`] with the extra outputs `aovs` of the tile's pixels, as
/// [`render_outputs`] gives them for the whole image (bit for bit the same values).
///
/// # Errors
/// As [`render_tile`].
pub fn render_tile_outputs(
    scene: &Scene,
    options: &RenderOptions,
    tile: Tile,
    aovs: &[Aov],
) -> Result<Outputs, TileError> {
    let tile = tile.check(options)?;
    Ok(render_region(scene, options, tile, aovs, &|_| {}, false).0)
}

/// Renders `tile` with the integrator of `options.mode` ([`ModeIntegrator`]), and
/// the outputs `aovs`. With `timed`, also measures what [`RenderTimes`] holds.
fn render_region(
    scene: &Scene,
    options: &RenderOptions,
    tile: Tile,
    aovs: &[Aov],
    row_done: &(dyn Fn(u32) + Sync),
    timed: bool,
) -> (Outputs, RayCounts, RenderTimes) {
    let integrator = ModeIntegrator::new(scene, options);
    render_with(scene, options, &integrator, tile, aovs, row_done, timed)
}

/// The pixel loop over `tile` (which lies inside the image): bands of
/// [`Integrator::band_rows`] rows spread over the threads, each traced as the
/// integrator traces a band ([`Integrator::trace_band`]). Pixels are indexed in the
/// whole image, so the sampler gives a pixel the same values whatever tile holds it.
fn render_with<I: Integrator>(
    scene: &Scene,
    options: &RenderOptions,
    integrator: &I,
    tile: Tile,
    aovs: &[Aov],
    row_done: &(dyn Fn(u32) + Sync),
    timed: bool,
) -> (Outputs, RayCounts, RenderTimes) {
    let camera = Camera::for_options(options);
    let sampler = PixelSampler::new(options.samples_per_pixel_in_mode(), integrator.dimensions())
        .with_seed(options.seed);
    let context = TileContext {
        scene,
        camera: &camera,
        sampler: &sampler,
        image_width: options.width,
    };
    let wanted = AovSet::of(aovs);
    let band_rows = integrator.band_rows(&context).max(1);
    let width = tile.width as usize;
    let band_len = width * band_rows as usize;
    let mut pixels = vec![Vec3::ZERO; width * tile.height as usize];
    // Every pixel's extra outputs, if any are asked for, cut into the bands' parts
    // (each band sets its own before tracing).
    let mut extra = SpareAovPixels::take();
    extra.resize(if wanted.any() { pixels.len() } else { 0 }, AovPixel::MISS);
    let mut extra_bands: Vec<&mut [AovPixel]> = extra.chunks_mut(band_len).collect();
    extra_bands.resize_with(pixels.len().div_ceil(band_len), Default::default);
    // Bands in order.
    let bands: Vec<(RayCounts, Duration, Duration)> = pixels
        .par_chunks_mut(band_len)
        .zip(extra_bands)
        .zip(
            (tile.y..tile.y + tile.height)
                .into_par_iter()
                .step_by(band_rows as usize),
        )
        .map(|((pixels, extra), top)| {
            let band_start = timed.then(Instant::now);
            let mut rays = RayCounts::default();
            let mut clock = TraceClock::new(timed);
            let rows = (pixels.len() / width) as u32;
            let aovs = if wanted.any() {
                BandAovs::new(&context, wanted, extra)
            } else {
                BandAovs::none()
            };
            let band = Band {
                left: tile.x,
                top,
                width: tile.width,
                rows,
                pixels,
                aovs,
            };
            integrator.trace_band(&context, band, &mut rays, &mut clock);
            if wanted.any() {
                finish_band(&context, wanted, extra, (tile.x, top, tile.width));
            }
            for row in top..top + rows {
                row_done(row);
            }
            let band_time = band_start.map_or(Duration::ZERO, |start| start.elapsed());
            (rays, clock.time().unwrap_or_default(), band_time)
        })
        .collect();
    let mut planes = AovPlanes::new(aovs, pixels.len());
    for (i, pixel) in extra.iter().enumerate() {
        planes.set(i, pixel);
    }
    SpareAovPixels::give_back(extra);
    let (mut rays, mut tracing, mut total) = (RayCounts::default(), Duration::ZERO, Duration::ZERO);
    for (band_rays, band_tracing, band_total) in bands {
        rays += band_rays;
        tracing += band_tracing;
        total += band_total;
    }
    let film = Film {
        width: tile.width,
        height: tile.height,
        pixels,
    };
    // An integrator that traced no packets apart from shading timed nothing.
    let times = RenderTimes {
        trace_fraction: (timed && !tracing.is_zero() && !total.is_zero())
            .then(|| tracing.as_secs_f64() / total.as_secs_f64()),
    };
    (Outputs { film, aovs: planes }, rays, times)
}

/// The extra outputs' working buffer of the last render, kept for the next: a
/// program rendering frame after frame (a Dask worker, whose nanny sets
/// `MALLOC_TRIM_THRESHOLD_` so that glibc maps every large block afresh) would
/// otherwise take a page fault on every page of it each frame. Locked twice a render;
/// a render that finds it taken (another render on another thread) allocates its own.
struct SpareAovPixels;

/// [`SpareAovPixels`]'s buffer.
static SPARE_AOV_PIXELS: std::sync::Mutex<Vec<AovPixel>> = std::sync::Mutex::new(Vec::new());

impl SpareAovPixels {
    /// Buffers larger than this (about 1,600 x 1,600 pixels) are not kept.
    const MAX_KEPT_BYTES: usize = 100 << 20;

    /// The spare buffer, empty (its capacity kept), or a new one.
    fn take() -> Vec<AovPixel> {
        let mut spare = match SPARE_AOV_PIXELS.try_lock() {
            Ok(mut spare) => std::mem::take(&mut *spare),
            Err(_) => Vec::new(),
        };
        spare.clear();
        spare
    }

    /// Keeps `buffer` for the next render, unless it is too large or one is kept.
    fn give_back(buffer: Vec<AovPixel>) {
        if buffer.capacity() * std::mem::size_of::<AovPixel>() > Self::MAX_KEPT_BYTES {
            return;
        }
        if let Ok(mut spare) = SPARE_AOV_PIXELS.try_lock()
            && spare.capacity() < buffer.capacity()
        {
            *spare = buffer;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::integrators::WhittedIntegrator;
    use crate::integrators::aov::PixelAovs;
    use crate::math::Ray;
    use crate::options::Mode;
    use crate::sampler::PixelSample;
    use crate::scene::{Hit, Scene};

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
            self.radiance_of(&empty_scene(), ray, None, sample, &mut RayCounts::default())
        }

        fn radiance_of(
            &self,
            _: &Scene,
            ray: &Ray,
            _: Option<Hit>,
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
        render_with(&empty_scene(), options, &Probe, tile, &[], &|_| {}, false)
            .0
            .film
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

    /// Full mode's packet bands make exactly the film and the extra outputs of the
    /// ray-by-ray loop, with the same ray counts, for whole images and for tiles
    /// whose edges cut the 4x4 packets.
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
            let (single, single_rays, _) = render_with(
                &scene,
                &options,
                &ByPixel(whitted),
                tile,
                &Aov::ALL,
                &|_| {},
                false,
            );
            let (packets, packet_rays, times) =
                render_with(&scene, &options, &whitted, tile, &Aov::ALL, &|_| {}, true);
            assert_eq!(
                format!("{:?}", single.aovs),
                format!("{:?}", packets.aovs),
                "{tile}: outputs"
            );
            let (single, packets) = (single.film, packets.film);
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
            assert!(times.trace_fraction.is_some(), "packets are timed apart");
        }
    }

    /// An integrator traced pixel by pixel, whatever its own bands.
    struct ByPixel<I>(I);

    impl<I: Integrator> Integrator for ByPixel<I> {
        fn dimensions(&self) -> u32 {
            self.0.dimensions()
        }

        fn radiance_of(
            &self,
            scene: &Scene,
            ray: &Ray,
            hit: Option<Hit>,
            sample: &mut PixelSample,
            rays: &mut RayCounts,
        ) -> Vec3 {
            self.0.radiance_of(scene, ray, hit, sample, rays)
        }
    }

    /// An integrator whose every pixel traces the one ray it holds (the centre
    /// pixel's), whatever the pixel: its outputs must be those of the rays it
    /// traced, not of a pass of their own.
    struct Axis(Ray);

    impl Integrator for Axis {
        fn dimensions(&self) -> u32 {
            0
        }

        fn radiance_of(
            &self,
            _: &Scene,
            _: &Ray,
            hit: Option<Hit>,
            _: &mut PixelSample,
            _: &mut RayCounts,
        ) -> Vec3 {
            Vec3::splat(hit.map_or(-1.0, |hit| hit.t))
        }

        fn pixel(
            &self,
            scene: &Scene,
            _: &Camera,
            _: &PixelSampler,
            _: (u32, u32, u32),
            _: &mut RayCounts,
            aovs: &mut PixelAovs,
        ) -> Vec3 {
            Vec3::splat(aovs.intersect(scene, &self.0).map_or(-1.0, |hit| hit.t))
        }
    }

    /// The outputs are those of the hits the integrator found for its camera rays:
    /// an integrator tracing the centre pixel's ray for every pixel gets its depth
    /// and object in every pixel, though the camera's own rays see other depths.
    #[test]
    fn outputs_are_the_hits_of_the_integrators_rays() {
        let scene = crate::scene::packet_tests::generated_scene(60, true, 3);
        let options = RenderOptions {
            width: 21,
            height: 15,
            look_from: Vec3::new(0.3, 1.2, 1.8),
            look_to: Vec3::new(0.0, 0.1, 0.0),
            fov_degrees: 55.0,
            ..RenderOptions::default()
        };
        let (column, row) = (options.width / 2, options.height / 2);
        let axis = Axis(Camera::for_options(&options).pixel_ray(column, row));
        let whole = Tile::whole(&options);
        let aovs = [Aov::Depth, Aov::ObjectId];
        let axis = render_with(&scene, &options, &axis, whole, &aovs, &|_| {}, false).0;
        let seen = render_region(&scene, &options, whole, &aovs, &|_| {}, false).0;
        let centre = (row * options.width + column) as usize;
        let depths = |o: &Outputs| o.aovs.depth.clone().unwrap();
        let (axis_depth, seen_depth) = (depths(&axis), depths(&seen));
        let at_centre = seen_depth[centre];
        assert!(at_centre.is_finite(), "the axis hits the scene");
        assert!(axis_depth.iter().all(|&d| d == at_centre), "{axis_depth:?}");
        assert!(seen_depth.iter().any(|&d| d != at_centre), "{seen_depth:?}");
        let objects = axis.aovs.object_id.unwrap();
        let centre_object = seen.aovs.object_id.unwrap()[centre];
        assert!(objects.iter().all(|&o| o == centre_object), "{objects:?}");
    }

    /// Asking for every output leaves the colour bit for bit as it was, in full
    /// mode's packets and pixel by pixel and in path mode's batches; at one sample
    /// and at several, the ids of the latter from a ray through the pixel centre.
    #[test]
    fn outputs_leave_the_colour_as_it_was() {
        let scene = crate::scene::packet_tests::generated_scene(60, true, 3);
        for (mode, samples_per_pixel) in [
            (Mode::Full, 1),
            (Mode::Full, 3),
            (Mode::Path, 1),
            (Mode::Path, 5),
        ] {
            let options = RenderOptions {
                width: 19,
                height: 13,
                look_from: Vec3::new(0.3, 1.2, 1.8),
                look_to: Vec3::new(0.0, 0.1, 0.0),
                fov_degrees: 55.0,
                mode,
                samples_per_pixel,
                ..RenderOptions::default()
            };
            let whole = Tile::whole(&options);
            let plain = render_region(&scene, &options, whole, &[], &|_| {}, false);
            let all = render_region(&scene, &options, whole, &Aov::ALL, &|_| {}, false);
            let label = format!("{mode:?} at {samples_per_pixel}");
            assert_eq!(plain.0.film, all.0.film, "{label}");
            assert_eq!(plain.1, all.1, "{label}: rays");
            let alpha = all.0.aovs.alpha.unwrap();
            assert!(alpha.contains(&1.0), "{label}");
            assert!(alpha.contains(&0.0), "{label}");
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
