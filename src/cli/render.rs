//! `raytracer render`: load, build, render, write, with optional `--stats`.

use std::time::Duration;

use raytracer::integrators::path::material_warnings;
use raytracer::postprocess::{
    Image, NEARLY_BLACK_FRACTION, NEARLY_BLACK_THRESHOLD, PostProcessing, RIG_WHITE_POINT,
    alpha_bytes, default_backdrop,
};
use raytracer::stats::{Mark, RayCounts, Usage, peak_memory_bytes};
use raytracer::{
    Aov, BvhParams, ImageFormat, Mode, Outputs, RenderOptions, Scene, output,
    render_outputs_with_stats,
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
    let aovs = args.aovs.as_ref().map_or(&[][..], |list| &list.0[..]);
    if !aovs.is_empty() && format != ImageFormat::Exr {
        anyhow::bail!(
            "--aovs writes its outputs as layers of an OpenEXR file: name the output .exr, not {}",
            args.output.display()
        );
    }
    let transparent = args.view.transparent();
    // The coverage is rendered for a transparent background too.
    let mut wanted = aovs.to_vec();
    if transparent && !wanted.contains(&Aov::Alpha) {
        wanted.push(Aov::Alpha);
    }
    let warn = |message: &str| {
        if !quiet {
            eprintln!("warning: {message}");
        }
    };
    // The scene's warnings, gathered to be printed once the scene is built, with those
    // of one kind on one line.
    let mut warnings = Vec::new();
    if args.denoise {
        // Before any work: a build without the denoiser says so at once.
        raytracer::postprocess::check_denoiser()?;
    }

    let start = Mark::now();
    let loading = Progress::start("loading the scene", None, !quiet);
    let (description, options, rig) = super::load_scene_noting_rig(&args.view, !aovs.is_empty())?;
    let options = &options;
    let parsed = Mark::now();
    let params = BvhParams::default();
    let mut scene = Scene::build(description, &params);
    // Full mode's one ray a pixel composites blended surfaces rather than dithering.
    scene.set_blend_in_layers(options.mode == Mode::Full);
    let built = Mark::now();
    drop(loading);
    if options.samples_per_pixel_in_mode() != options.samples_per_pixel {
        warnings.push(format!(
            "--spp {} applies to full and path modes only; {} mode takes one sample per pixel",
            options.samples_per_pixel,
            options.mode.name()
        ));
    }
    warnings.extend(scene.warnings.iter().cloned());
    if options.mode == Mode::Path {
        warnings.extend(material_warnings(&scene.materials));
    }
    for warning in raytracer::warnings::coalesce(&warnings) {
        warn(&warning);
    }

    let samples_per_row = u64::from(options.width) * u64::from(options.samples_per_pixel_in_mode());
    let rendering = Progress::with_rate(
        "rendering",
        Some(options.height.into()),
        samples_per_row,
        !quiet,
    );
    // Full mode's default rig shows a grey backdrop where camera rays miss, in the PNG
    // (not behind an empty scene, which stays black): the coverage says where.
    let backdrop = rig && !transparent && format == ImageFormat::Png && scene.prim_count() > 0;
    if backdrop && !wanted.contains(&Aov::Alpha) {
        wanted.push(Aov::Alpha);
    }
    // The denoiser's guides (OIDN's albedo and normal images), rendered with the
    // colour, written only if asked for.
    let denoising = args.denoise && options.mode == Mode::Path;
    let mut rendered_aovs = wanted.clone();
    for guide in [Aov::Albedo, Aov::Normal] {
        if denoising && !rendered_aovs.contains(&guide) {
            rendered_aovs.push(guide);
        }
    }
    // Timing the tracing apart reads the clock a few times per tile: only when asked.
    let (outputs, rays, times) = render_outputs_with_stats(
        &scene,
        options,
        &rendered_aovs,
        &|_row| rendering.inc(),
        args.stats,
    );
    drop(rendering);
    let Outputs {
        film,
        aovs: mut planes,
    } = outputs;
    // The coverage as alpha, out of the extra outputs unless asked for as one.
    let coverage = match aovs.contains(&Aov::Alpha) {
        true => planes.alpha.clone(),
        false => planes.alpha.take(),
    };
    let (alpha, backdrop) = match transparent {
        true => (coverage, None),
        false => (None, coverage.filter(|_| backdrop)),
    };
    let film = match (args.denoise, options.mode) {
        (true, Mode::Path) => {
            let film = film.denoised(&planes)?;
            if !wanted.contains(&Aov::Albedo) {
                planes.albedo = None;
            }
            if !wanted.contains(&Aov::Normal) {
                planes.normal = None;
            }
            film
        }
        (true, mode) => {
            warn(&format!(
                "--denoise applies to path mode only; {} mode is written as rendered",
                mode.name()
            ));
            film
        }
        (false, _) => film,
    };
    let rendered = Mark::now();
    // Post-processing and encoding apart, so that `--stats` shows each.
    let (processed, encoded) = match format {
        ImageFormat::Png => {
            // PNG keeps colour and alpha apart: the colour of what was hit.
            let post = PostProcessing {
                least_white_point: if rig { RIG_WHITE_POINT } else { 0.0 },
                ..PostProcessing::from(options)
            };
            let mut image = match &alpha {
                Some(alpha) => film.unpremultiplied(alpha).to_image(post),
                None => film.to_image(post),
            };
            if let Some(coverage) = &backdrop {
                image.over_backdrop(coverage, default_backdrop());
            }
            let processed = Mark::now();
            if scene.prim_count() > 0 && alpha.is_none() {
                warn_if_nearly_black(&image, options, &warn);
            }
            let alpha = alpha.as_deref().map(alpha_bytes);
            let bytes = image
                .encode_png_with_alpha(alpha.as_deref())
                .map_err(|error| output::WriteError {
                    path: args.output.clone(),
                    error,
                })?;
            let encoded = Mark::now();
            output::write_png_bytes(&bytes, &args.output)?;
            (processed, encoded)
        }
        // OpenEXR holds the film as rendered: no post-processing; encoded while written.
        ImageFormat::Exr => {
            let film = if wanted.is_empty() {
                film.write(options, format, &args.output)?;
                film
            } else {
                let outputs = Outputs { film, aovs: planes };
                outputs.write_exr(options.mode, alpha.as_deref(), &args.output)?;
                outputs.film
            };
            let written = Mark::now();
            // The check sees what a PNG would show (an empty scene is warned of as
            // such already).
            if scene.prim_count() > 0 && alpha.is_none() {
                warn_if_nearly_black(&film.to_image(options), options, &warn);
            }
            (rendered, written)
        }
    };
    let written = Mark::now();
    let file_bytes = std::fs::metadata(&args.output).map(|m| m.len()).ok();

    if args.stats {
        let cost = |from: &Mark, to: &Mark| Cost::from(from.to(to));
        let render = cost(&built, &rendered);
        let stages = Stages {
            parse: cost(&start, &parsed),
            build: cost(&parsed, &built),
            trace: times.trace_fraction.map(|f| f * render.wall.as_secs_f64()),
            render,
            post: cost(&rendered, &processed),
            encode: cost(&processed, &encoded),
            write: cost(&encoded, &written),
            encode_and_write: cost(&processed, &written),
            total: cost(&start, &written),
        };
        let samples = samples_per_row * u64::from(options.height);
        print_stats(&scene, &stages, &rays, samples, format, file_bytes);
    }
    Ok(())
}

/// Warns, in one line with what to try, when a full or path mode image of a scene
/// with shapes is nearly black after post-processing: more than [`NEARLY_BLACK_FRACTION`] of its pixels
/// below [`NEARLY_BLACK_THRESHOLD`] in every channel.
fn warn_if_nearly_black(image: &Image, options: &RenderOptions, warn: &impl Fn(&str)) {
    let dark = image.dark_fraction(NEARLY_BLACK_THRESHOLD);
    if dark <= NEARLY_BLACK_FRACTION {
        return;
    }
    let what_to_try = match options.mode {
        Mode::Full => {
            "try --mode path (lit by --env, or by the studio environment when the scene has no lights), or lights in the scene"
        }
        Mode::Path => {
            "try --exposure 2 (or more), --env R,G,B or --env FILE.hdr (an environment lighting the scene), or lights in the scene"
        }
        Mode::Depth | Mode::Normal => return,
    };
    warn(&format!(
        "the image is nearly black ({:.1}% of its pixels below {NEARLY_BLACK_THRESHOLD}/255): {what_to_try}",
        dark * 100.0
    ));
}

/// What a stage spent: wall time, and CPU time on all threads and page faults where
/// the OS reports them.
#[derive(Clone, Copy)]
struct Cost {
    wall: Duration,
    usage: Option<Usage>,
}

impl From<(Duration, Option<Usage>)> for Cost {
    fn from((wall, usage): (Duration, Option<Usage>)) -> Cost {
        Cost { wall, usage }
    }
}

impl Cost {
    /// The stage's columns of `--stats`: wall time, CPU time, page faults.
    fn columns(&self) -> String {
        columns(self.wall, self.usage)
    }
}

/// `--stats` columns for a wall time and the usage over it (blank where the OS
/// reports none).
fn columns(wall: Duration, usage: Option<Usage>) -> String {
    let wall = format!("{:9.1} ms", wall.as_secs_f64() * 1e3);
    match usage {
        Some(usage) => format!(
            "{wall} {:9.1} ms CPU {:7} faults",
            usage.cpu.as_secs_f64() * 1e3,
            usage.minor_faults
        ),
        None => format!("{wall} {:30}", ""),
    }
}

/// What each stage spent.
struct Stages {
    parse: Cost,
    build: Cost,
    /// The pixel loop: tracing and shading.
    render: Cost,
    /// Seconds of `render` spent tracing ray packets, where it is a stage apart.
    trace: Option<f64>,
    post: Cost,
    encode: Cost,
    /// Writing the encoded file: the temporary file, its sync to disk, the rename.
    write: Cost,
    /// `encode` and `write` together, which OpenEXR's writer does in one.
    encode_and_write: Cost,
    /// From the start of loading to the written file.
    total: Cost,
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
    let render_seconds = stages.render.wall.as_secs_f64();
    // Zero for a negative or NaN number of seconds, which `Duration` refuses.
    let seconds = |s: f64| Duration::try_from_secs_f64(s).unwrap_or_default();
    eprintln!(
        "{:17}{:>12}{:>16}{:>15}  (CPU time of all threads; page faults without I/O)",
        "stage", "wall", "CPU", "page faults"
    );
    eprintln!("parse            {}", stages.parse.columns());
    eprintln!(
        "BVH build        {}  {} primitives, {} binary nodes (depth {}, SAH cost {:.2}) -> {} 8-wide nodes (SAH cost {:.2}), {} packets",
        stages.build.columns(),
        scene.prim_count(),
        bvh.nodes,
        bvh.max_depth,
        bvh.sah_cost,
        bvh.wide_nodes,
        bvh.wide_sah_cost,
        bvh.packets,
    );
    let steps = scene.build_times();
    let usage = steps.usage;
    eprintln!(
        "  binary tree    {}  binned SAH over the primitives' boxes",
        columns(steps.tree, usage.map(|u| u.tree))
    );
    eprintln!(
        "  8-wide collapse{}  SAH-optimal, into the nodes rays traverse",
        columns(steps.collapse, usage.map(|u| u.collapse))
    );
    eprintln!(
        "  packets        {}  triangles and shading data in leaf order (fresh memory)",
        columns(steps.packets, usage.map(|u| u.packets))
    );
    let rays_line = format!(
        "{} rays: {} primary, {} shadow, {} reflected, {} refracted, {} scattered; {:.1} Mrays/s",
        rays.total(),
        rays.primary,
        rays.shadow,
        rays.reflected,
        rays.refracted,
        rays.scattered,
        rays.total() as f64 / render_seconds / 1e6
    );
    match stages.trace {
        Some(trace) => {
            eprintln!(
                "trace            {}  camera and shadow rays in 4x4 packets: {} rays, {:.1} Mrays/s",
                columns(seconds(trace), None),
                rays.primary + rays.shadow,
                (rays.primary + rays.shadow) as f64 / trace / 1e6
            );
            eprintln!(
                "shading          {}  with the reflected and refracted rays it traces",
                columns(seconds(render_seconds - trace), None)
            );
            eprintln!("  render total   {}  {rays_line}", stages.render.columns());
        }
        None => eprintln!(
            "trace + shading  {}  {rays_line} (traced and shaded in turn, ray by ray)",
            stages.render.columns()
        ),
    }
    eprintln!(
        "                 {:9} samples (paths in path mode), {:.2} M samples/s",
        samples,
        samples as f64 / render_seconds / 1e6
    );
    match format {
        ImageFormat::Png => {
            eprintln!("post-processing  {}", stages.post.columns());
            eprintln!(
                "PNG encoding     {}  {}",
                stages.encode.columns(),
                file_size(file_bytes)
            );
            eprintln!(
                "file write       {}  temporary file, sync to disk, rename",
                stages.write.columns()
            );
        }
        ImageFormat::Exr => eprintln!(
            "EXR encoding     {}  {} (linear film, no post-processing; written, synced and renamed)",
            stages.encode_and_write.columns(),
            file_size(file_bytes)
        ),
    }
    eprintln!("total            {}", stages.total.columns());
    if let Some(peak) = peak_memory_bytes() {
        eprintln!("peak memory      {:9.1} MB", peak as f64 / 1e6);
    }
}

/// The size of the written file, for `--stats`.
fn file_size(bytes: Option<u64>) -> String {
    bytes.map_or_else(String::new, |b| format!("{:.1} kB written", b as f64 / 1e3))
}
