//! The `raytracer` command: parses flags, calls the library, maps errors to exit 2.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use clap::{Parser, Subcommand, ValueEnum};
use raytracer::math::Vec3;
use raytracer::options::{MAX_DIMENSION, MAX_RECURSION_DEPTH};
use raytracer::{BvhParams, Mode, RenderOptions, Scene, film, render, scene};

mod cli_values;
mod interrupt;

use cli_values::{MAX_THREADS, check_not_input, fov_degrees, whole_number};

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
}

#[derive(clap::Args, Debug)]
struct RenderArgs {
    /// The scene: a Wavefront .obj file (its .mtl files are found beside it).
    #[arg(value_name = "SCENE.obj")]
    scene: PathBuf,
    /// Where to write the PNG image (replaced atomically: an error or Ctrl-C leaves the
    /// previous file as it was).
    #[arg(short, long, value_name = "OUT.png")]
    output: PathBuf,
    /// Image width in pixels (1..=65536).
    #[arg(
        long,
        default_value_t = 640,
        value_name = "PIXELS",
        allow_hyphen_values = true,
        value_parser = whole_number(1, MAX_DIMENSION),
    )]
    width: u32,
    /// Image height in pixels (1..=65536; at most 16384x16384 pixels in all).
    #[arg(
        long,
        default_value_t = 480,
        value_name = "PIXELS",
        allow_hyphen_values = true,
        value_parser = whole_number(1, MAX_DIMENSION),
    )]
    height: u32,
    /// Vertical field of view in degrees, strictly between 0 and 180.
    #[arg(
        long,
        default_value_t = 90.0,
        value_name = "DEGREES",
        allow_hyphen_values = true,
        value_parser = fov_degrees,
    )]
    fov: f32,
    /// Camera position.
    #[arg(long, default_value = "0,0,0", value_name = "X,Y,Z", value_parser = parse_vec3, allow_hyphen_values = true)]
    look_from: Vec3,
    /// Point the camera looks at (world up is +y).
    #[arg(long, default_value = "0,0,-1", value_name = "X,Y,Z", value_parser = parse_vec3, allow_hyphen_values = true)]
    look_to: Vec3,
    /// Recursion depth of full mode (1..=64): 1 traces primary and shadow rays only.
    /// With glass, each level can double the rays per pixel.
    #[arg(
        long,
        default_value_t = 4,
        value_name = "N",
        allow_hyphen_values = true,
        value_parser = whole_number(1, MAX_RECURSION_DEPTH),
    )]
    depth: u32,
    /// What to render.
    #[arg(long, value_enum, default_value_t = ModeArg::Full)]
    mode: ModeArg,
    /// Worker threads (0..=1024); 0 uses every core.
    #[arg(
        short = 'j',
        long,
        default_value_t = 0,
        value_name = "N",
        allow_hyphen_values = true,
        value_parser = whole_number(0, MAX_THREADS),
    )]
    threads: u32,
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
    match cli.command {
        Command::Render(args) => run_render(args),
    }
}

fn run_render(args: RenderArgs) -> anyhow::Result<()> {
    let options = RenderOptions {
        width: args.width,
        height: args.height,
        fov_degrees: args.fov,
        look_from: args.look_from,
        look_to: args.look_to,
        depth: args.depth,
        mode: args.mode.into(),
    };
    interrupt::install(args.output.clone())?;
    options.validate()?;
    film::check_output(&args.output)?;
    check_not_input(&args.scene, &args.output)?;
    rayon::ThreadPoolBuilder::new()
        .num_threads(args.threads as usize)
        .build_global()
        .context("cannot start worker threads")?;

    let description = scene::load_obj(&args.scene)?;
    let scene = Scene::build(description, &BvhParams::default());
    for warning in &scene.warnings {
        eprintln!("warning: {warning}");
    }
    let film = render(&scene, &options);
    film.to_image(options.mode).write_png(&args.output)?;
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
            let Command::Render(args) = Cli::try_parse_from(argv).unwrap().command;
            assert_eq!(args.look_from, Vec3::new(-1.0, 2.0, -3.0));
        }
    }
}
