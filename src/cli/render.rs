//! `raytracer render`: load, build, render, write, with optional `--stats`.

use std::time::Instant;

use raytracer::integrators::path::material_warnings;
use raytracer::stats::{RayCounts, peak_memory_bytes};
use raytracer::{
    BvhParams, ImageFormat, Mode, RenderTimes, Scene, output, render_with_progress,
    render_with_stats,
};

use super::args::RenderArgs;
use super::interrupt;
use super::progress::Progress;
use super::values::check_not_input;

/// Renders as `args` say.
pub fn run(args: &RenderArgs, quiet: bool) -> anyhow::Result<()> {
    interrupt::install(args.output.clone())?;
    // Before any work, so that a typo or a read-only folder does not cost a render.
    output::check_output(&args.output)?;
    check_not_input(&args.view.scene, &args.output)?;
    let format = ImageFormat::from_path(&args.output)?;
    let warn = |message: &str| {
        if !quiet {
            eprintln!("warning: {message}");
        }
    };
    if args.denoise {
        // Before any work: a build without the denoiser says so at once.
        raytracer::postprocess::check_denoiser()?;
    }

    let start = Instant::now();
    let loading = Progress::start("loading the scene", None, !quiet);
    let (description, options) = super::load_scene(&args.view)?;
    let options = &options;
    let parsed = Instant::now();
    let params = BvhParams::default();
    let scene = Scene::build(description, &params);
    let built = Instant::now();
    drop(loading);
    if options.samples_per_pixel_in_mode() != options.samples_per_pixel {
        warn(&format!(
            "--spp {} applies to full and path modes only; {} mode takes one sample per pixel",
            options.samples_per_pixel,
            options.mode.name()
        ));
    }
    for warning in &scene.warnings {
        warn(warning);
    }
    if options.mode == Mode::Path {
        for warning in material_warnings(&scene.materials) {
            warn(&warning);
        }
    }

    let samples_per_row = u64::from(options.width) * u64::from(options.samples_per_pixel_in_mode());
    let rendering = Progress::with_rate(
        "rendering",
        Some(options.height.into()),
        samples_per_row,
        !quiet,
    );
    // Timing the tracing apart reads the clock a few times per tile: only when asked.
    let (film, rays, times) = if args.stats {
        render_with_stats(&scene, options, &|_row| rendering.inc())
    } else {
        let (film, rays) = render_with_progress(&scene, options, &|_row| rendering.inc());
        (film, rays, RenderTimes::default())
    };
    drop(rendering);
    let film = match (args.denoise, options.mode) {
        (true, Mode::Path) => film.denoised()?,
        (true, mode) => {
            warn(&format!(
                "--denoise applies to path mode only; {} mode is written as rendered",
                mode.name()
            ));
            film
        }
        (false, _) => film,
    };
    let rendered = Instant::now();
    // Post-processing and encoding apart, so that `--stats` shows each.
    let (processed, encoded) = match format {
        ImageFormat::Png => {
            let image = film.to_image(options);
            let processed = Instant::now();
            let bytes = image.encode_png().map_err(|error| output::WriteError {
                path: args.output.clone(),
                error,
            })?;
            let encoded = Instant::now();
            output::write_png_bytes(&bytes, &args.output)?;
            (processed, encoded)
        }
        // OpenEXR holds the film as rendered: no post-processing; encoded while written.
        ImageFormat::Exr => {
            film.write(options, format, &args.output)?;
            (rendered, Instant::now())
        }
    };
    let written = Instant::now();
    let file_bytes = std::fs::metadata(&args.output).map(|m| m.len()).ok();

    if args.stats {
        let render = (rendered - built).as_secs_f64();
        let stages = Stages {
            parse: (parsed - start).as_secs_f64(),
            build: (built - parsed).as_secs_f64(),
            render,
            trace: times.trace_fraction.map(|f| f * render),
            post: (processed - rendered).as_secs_f64(),
            encode: (encoded - processed).as_secs_f64(),
            write: (written - encoded).as_secs_f64(),
        };
        let samples = samples_per_row * u64::from(options.height);
        print_stats(&scene, &stages, &rays, samples, format, file_bytes);
    }
    Ok(())
}

/// Seconds spent in each stage.
struct Stages {
    parse: f64,
    build: f64,
    /// The pixel loop: tracing and shading.
    render: f64,
    /// The part of `render` spent tracing ray packets, where it is a stage apart.
    trace: Option<f64>,
    post: f64,
    encode: f64,
    /// Writing the encoded file: the temporary file, its sync to disk, the rename.
    write: f64,
}

/// `samples` is the number of camera samples (paths, in path mode); `file_bytes` the
/// size of the image written.
fn print_stats(
    scene: &Scene,
    stages: &Stages,
    rays: &RayCounts,
    samples: u64,
    format: ImageFormat,
    file_bytes: Option<u64>,
) {
    let bvh = scene.bvh_summary();
    let ms = |s: f64| s * 1e3;
    eprintln!("parse            {:9.1} ms", ms(stages.parse));
    eprintln!(
        "BVH build        {:9.1} ms  {} primitives, {} binary nodes (depth {}, SAH cost {:.2}) -> {} 8-wide nodes (SAH cost {:.2}), {} packets",
        ms(stages.build),
        scene.prim_count(),
        bvh.nodes,
        bvh.max_depth,
        bvh.sah_cost,
        bvh.wide_nodes,
        bvh.wide_sah_cost,
        bvh.packets,
    );
    let steps = scene.build_times();
    eprintln!(
        "  binary tree    {:9.1} ms  binned SAH over the primitives' boxes",
        ms(steps.tree.as_secs_f64())
    );
    eprintln!(
        "  8-wide collapse{:9.1} ms  SAH-optimal, into the nodes rays traverse",
        ms(steps.collapse.as_secs_f64())
    );
    eprintln!(
        "  packets        {:9.1} ms  triangles and shading data in leaf order (fresh memory)",
        ms(steps.packets.as_secs_f64())
    );
    let rays_line = format!(
        "{} rays: {} primary, {} shadow, {} reflected, {} refracted, {} scattered; {:.1} Mrays/s",
        rays.total(),
        rays.primary,
        rays.shadow,
        rays.reflected,
        rays.refracted,
        rays.scattered,
        rays.total() as f64 / stages.render / 1e6
    );
    match stages.trace {
        Some(trace) => {
            eprintln!(
                "trace            {:9.1} ms  camera and shadow rays in 4x4 packets: {} rays, {:.1} Mrays/s",
                ms(trace),
                rays.primary + rays.shadow,
                (rays.primary + rays.shadow) as f64 / trace / 1e6
            );
            eprintln!(
                "shading          {:9.1} ms  with the reflected and refracted rays it traces",
                ms(stages.render - trace)
            );
            eprintln!("  render total   {:9.1} ms  {rays_line}", ms(stages.render));
        }
        None => eprintln!(
            "trace + shading  {:9.1} ms  {rays_line} (traced and shaded in turn, ray by ray)",
            ms(stages.render)
        ),
    }
    eprintln!(
        "                 {:9} samples (paths in path mode), {:.2} M samples/s",
        samples,
        samples as f64 / stages.render / 1e6
    );
    match format {
        ImageFormat::Png => {
            eprintln!("post-processing  {:9.1} ms", ms(stages.post));
            eprintln!(
                "PNG encoding     {:9.1} ms  {}",
                ms(stages.encode),
                file_size(file_bytes)
            );
            eprintln!(
                "file write       {:9.1} ms  temporary file, sync to disk, rename",
                ms(stages.write)
            );
        }
        ImageFormat::Exr => eprintln!(
            "EXR encoding     {:9.1} ms  {} (linear film, no post-processing; written, synced and renamed)",
            ms(stages.encode + stages.write),
            file_size(file_bytes)
        ),
    }
    let total =
        stages.parse + stages.build + stages.render + stages.post + stages.encode + stages.write;
    eprintln!("total            {:9.1} ms", ms(total));
    if let Some(peak) = peak_memory_bytes() {
        eprintln!("peak memory      {:9.1} MB", peak as f64 / 1e6);
    }
}

/// The size of the written file, for `--stats`.
fn file_size(bytes: Option<u64>) -> String {
    bytes.map_or_else(String::new, |b| format!("{:.1} kB written", b as f64 / 1e3))
}
