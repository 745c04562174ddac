//! The `raytracer` command: parses flags, calls the library, maps errors to exit 2.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use anyhow::Context;
use clap::{Parser, Subcommand, ValueEnum};
use raytracer::benchmark::{RayWorkload, count_occluded, median_time, trace_closest};
use raytracer::math::Vec3;
use raytracer::stats::peak_memory_bytes;
use raytracer::{BvhParams, Mode, RenderOptions, Scene, render_counted, scene};

/// A Whitted-style ray tracer for Wavefront OBJ/MTL scenes.
#[derive(Parser, Debug)]
#[command(version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Render a scene to a PNG image.
    Render(RenderArgs),
    /// Measure parsing, BVH build and ray throughput on a scene; prints JSON.
    Bench(BenchArgs),
}

#[derive(clap::Args, Debug)]
struct BenchArgs {
    #[command(flatten)]
    view: ViewArgs,
    /// Runs per measurement; the median is reported.
    #[arg(long, default_value_t = 5, value_name = "N")]
    repeat: usize,
}

#[derive(clap::Args, Debug)]
struct RenderArgs {
    #[command(flatten)]
    view: ViewArgs,
    /// Where to write the PNG image (replaced atomically).
    #[arg(short, long, value_name = "OUT.png")]
    output: PathBuf,
    /// Print the time of each stage, BVH size and quality, rays traced and peak memory
    /// on stderr.
    #[arg(long)]
    stats: bool,
}

/// The scene and how to look at it: shared by `render` and `bench`.
#[derive(clap::Args, Debug)]
struct ViewArgs {
    /// The scene: a Wavefront .obj file (its .mtl files are found beside it).
    #[arg(value_name = "SCENE.obj")]
    scene: PathBuf,
    /// Image width in pixels (1..=65536).
    #[arg(long, default_value_t = 640, value_name = "PIXELS")]
    width: u32,
    /// Image height in pixels (1..=65536; at most 16384x16384 pixels in all).
    #[arg(long, default_value_t = 480, value_name = "PIXELS")]
    height: u32,
    /// Vertical field of view in degrees, strictly between 0 and 180.
    #[arg(long, default_value_t = 90.0, value_name = "DEGREES")]
    fov: f32,
    /// Camera position.
    #[arg(long, default_value = "0,0,0", value_name = "X,Y,Z", value_parser = parse_vec3, allow_hyphen_values = true)]
    look_from: Vec3,
    /// Point the camera looks at (world up is +y).
    #[arg(long, default_value = "0,0,-1", value_name = "X,Y,Z", value_parser = parse_vec3, allow_hyphen_values = true)]
    look_to: Vec3,
    /// Recursion depth of full mode (1..=64): 1 traces primary and shadow rays only.
    #[arg(long, default_value_t = 4, value_name = "N")]
    depth: u32,
    /// What to render.
    #[arg(long, value_enum, default_value_t = ModeArg::Full)]
    mode: ModeArg,
    /// Worker threads; 0 uses every core.
    #[arg(short = 'j', long, default_value_t = 0, value_name = "N")]
    threads: usize,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
enum ModeArg {
    /// Phong lighting, shadows, reflection and refraction, tone mapped.
    Full,
    /// Distance to the nearest hit, normalized by the farthest (misses white).
    Depth,
    /// Surface normal facing the camera as colour, n/2 + 1/2 (misses black).
    Normal,
}

impl From<ModeArg> for Mode {
    fn from(m: ModeArg) -> Mode {
        match m {
            ModeArg::Full => Mode::Full,
            ModeArg::Depth => Mode::Depth,
            ModeArg::Normal => Mode::Normal,
        }
    }
}

/// Parses `X,Y,Z` into a vector of three finite numbers.
fn parse_vec3(s: &str) -> Result<Vec3, String> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    let [x, y, z] = parts[..] else {
        return Err(format!("expected X,Y,Z (three numbers), got '{s}'"));
    };
    let number = |t: &str| match t.parse::<f32>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => Err(format!("'{t}' is not a finite number in '{s}'")),
    };
    Ok(Vec3::new(number(x)?, number(y)?, number(z)?))
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("error: {err:#}");
            ExitCode::from(2)
        }
    }
}

fn run(cli: Cli) -> anyhow::Result<()> {
    let view = match &cli.command {
        Command::Render(args) => &args.view,
        Command::Bench(args) => &args.view,
    };
    let options = view.options();
    options.validate()?;
    rayon::ThreadPoolBuilder::new()
        .num_threads(view.threads)
        .build_global()
        .context("cannot start worker threads")?;
    match &cli.command {
        Command::Render(args) => run_render(args, &options),
        Command::Bench(args) => run_bench(args, &options),
    }
}

impl ViewArgs {
    fn options(&self) -> RenderOptions {
        RenderOptions {
            width: self.width,
            height: self.height,
            fov_degrees: self.fov,
            look_from: self.look_from,
            look_to: self.look_to,
            depth: self.depth,
            mode: self.mode.into(),
        }
    }
}

fn run_render(args: &RenderArgs, options: &RenderOptions) -> anyhow::Result<()> {
    let start = Instant::now();
    let description = scene::load_obj(&args.view.scene)?;
    let parsed = Instant::now();
    let scene = Scene::build(description, &BvhParams::default());
    let built = Instant::now();
    for warning in &scene.warnings {
        eprintln!("warning: {warning}");
    }
    let (film, rays) = render_counted(&scene, options);
    let rendered = Instant::now();
    let image = film.to_image(options.mode);
    let processed = Instant::now();
    image.write_png(&args.output)?;
    let written = Instant::now();
    if args.stats {
        let ms = |a: Instant, b: Instant| (b - a).as_secs_f64() * 1e3;
        let render_ms = ms(built, rendered);
        let bvh = scene.bvh();
        eprintln!("parse        {:9.1} ms", ms(start, parsed));
        eprintln!(
            "build        {:9.1} ms  {} primitives, {} nodes, depth {}, SAH cost {:.1}",
            ms(parsed, built),
            scene.prim_count(),
            bvh.nodes.len(),
            bvh.max_depth,
            bvh.sah_cost(&BvhParams::default())
        );
        eprintln!(
            "render       {render_ms:9.1} ms  {} rays ({} primary, {} shadow, {} reflected, {} refracted), {:.1} Mrays/s",
            rays.total(),
            rays.primary,
            rays.shadow,
            rays.reflected,
            rays.refracted,
            rays.total() as f64 / render_ms / 1e3
        );
        eprintln!("post-process {:9.1} ms", ms(rendered, processed));
        eprintln!("write        {:9.1} ms", ms(processed, written));
        eprintln!("total        {:9.1} ms", ms(start, written));
        if let Some(peak) = peak_memory_bytes() {
            eprintln!("peak memory  {:9.1} MB", peak as f64 / 1e6);
        }
    }
    Ok(())
}

fn run_bench(args: &BenchArgs, options: &RenderOptions) -> anyhow::Result<()> {
    let path = &args.view.scene;
    let file_bytes = std::fs::metadata(path).map(|m| m.len()).unwrap_or(0);
    let (description, parse_s) = median_time(args.repeat, || scene::load_obj(path));
    let description = description?;
    let triangles = description.triangles.len();
    let params = BvhParams::default();
    let (scene, build_s) = median_time(args.repeat, || Scene::build(description.clone(), &params));
    let workload = RayWorkload::new(&scene, options);
    let (hits, primary_s) = median_time(args.repeat, || trace_closest(&scene, &workload.primary));
    debug_assert_eq!(hits.iter().flatten().count(), workload.primary_hits);
    let (occluded, shadow_s) =
        median_time(args.repeat, || count_occluded(&scene, &workload.shadow));
    let (_, render_s) = median_time(args.repeat, || render_counted(&scene, options));
    let mrays = |n: usize, s: f64| n as f64 / s / 1e6;
    println!(
        concat!(
            "{{\"file_bytes\": {}, \"triangles\": {}, \"parse_ms\": {:.2}, \"parse_mb_per_s\": {:.1}, ",
            "\"build_ms\": {:.2}, \"bvh_nodes\": {}, \"sah_cost\": {:.2}, ",
            "\"primary_rays\": {}, \"primary_hits\": {}, \"primary_ms\": {:.2}, \"primary_mrays_per_s\": {:.2}, ",
            "\"shadow_rays\": {}, \"shadow_occluded\": {}, \"shadow_ms\": {:.2}, \"shadow_mrays_per_s\": {:.2}, ",
            "\"render_ms\": {:.2}}}"
        ),
        file_bytes,
        triangles,
        parse_s * 1e3,
        file_bytes as f64 / parse_s / 1e6,
        build_s * 1e3,
        scene.bvh().nodes.len(),
        scene.bvh().sah_cost(&params),
        workload.primary.len(),
        workload.primary_hits,
        primary_s * 1e3,
        mrays(workload.primary.len(), primary_s),
        workload.shadow.len(),
        occluded,
        shadow_s * 1e3,
        mrays(workload.shadow.len(), shadow_s),
        render_s * 1e3,
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vectors_take_negative_components_and_reject_garbage() {
        assert_eq!(parse_vec3("-0.5,1.5,0.98"), Ok(Vec3::new(-0.5, 1.5, 0.98)));
        assert!(parse_vec3("1,2").is_err());
        assert!(parse_vec3("1,2,x").is_err());
        assert!(parse_vec3("1,2,inf").is_err());
    }

    #[test]
    fn negative_vectors_parse_in_both_spellings() {
        for argv in [
            [
                "raytracer",
                "render",
                "s.obj",
                "-o",
                "o.png",
                "--look-from",
                "-1,2,-3",
            ],
            [
                "raytracer",
                "render",
                "s.obj",
                "-o",
                "o.png",
                "--look-from=-1,2,-3",
                "--mode=full",
            ],
        ] {
            let Command::Render(args) = Cli::try_parse_from(argv).unwrap().command else {
                panic!("not render")
            };
            assert_eq!(args.view.look_from, Vec3::new(-1.0, 2.0, -3.0));
        }
    }
}
