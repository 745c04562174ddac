//! Flag definitions (clap derive), converted to the library's [`PartialOptions`].

use std::path::PathBuf;

use clap::{Parser, Subcommand, ValueEnum};
use raytracer::Mode;
use raytracer::math::Vec3;
use raytracer::options::{MAX_DIMENSION, MAX_RECURSION_DEPTH, PartialOptions};

use super::values::{MAX_THREADS, fov_degrees, whole_number};

/// A Whitted-style ray tracer for OBJ/MTL, PLY and TOML scenes.
#[derive(Parser, Debug)]
#[command(version, about)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
    /// Print nothing but errors: no progress bar, no warnings.
    #[arg(short, long, global = true)]
    pub quiet: bool,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Render a scene to a PNG or OpenEXR image.
    Render(RenderArgs),
    /// Measure parsing, BVH build and ray throughput on a scene; prints JSON.
    Bench(BenchArgs),
    /// Describe a scene: counts, bounds, materials, memory a render needs, warnings.
    Info {
        /// The scene: OBJ, PLY or TOML, optionally gzip-compressed.
        scene: PathBuf,
    },
}

/// Flags of `bench`.
#[derive(clap::Args, Debug)]
pub struct BenchArgs {
    #[command(flatten)]
    pub view: ViewArgs,
    /// Runs per measurement; the median is reported.
    #[arg(long, default_value_t = 5, value_name = "N")]
    pub repeat: usize,
}

/// Flags of `render`.
#[derive(clap::Args, Debug)]
pub struct RenderArgs {
    #[command(flatten)]
    pub view: ViewArgs,
    /// Where to write the image, replaced atomically; the extension picks the format:
    /// .png (8-bit, post-processed) or .exr (32-bit float, linear, before post-processing).
    #[arg(short, long, value_name = "OUT.png|OUT.exr")]
    pub output: PathBuf,
    /// Print the time of each stage, BVH size and quality, rays traced and peak memory
    /// on stderr.
    #[arg(long)]
    pub stats: bool,
}

/// The scene and how to look at it: shared by `render` and `bench`. Camera and render
/// flags are optional so that a TOML scene's values show through: a flag overrides
/// the file, the file overrides the default shown.
#[derive(clap::Args, Debug)]
pub struct ViewArgs {
    /// The scene: OBJ (MTL files beside it), PLY, or a TOML scene file
    /// (docs/scene-format.md); any may be gzip-compressed.
    #[arg(value_name = "SCENE")]
    pub scene: PathBuf,
    /// Image width in pixels (1..=65536) [default: 640].
    #[arg(
        long,
        value_name = "PIXELS",
        allow_hyphen_values = true,
        value_parser = whole_number(1, MAX_DIMENSION),
    )]
    pub width: Option<u32>,
    /// Image height in pixels (1..=65536; at most 16384x16384 pixels in all)
    /// [default: 480].
    #[arg(
        long,
        value_name = "PIXELS",
        allow_hyphen_values = true,
        value_parser = whole_number(1, MAX_DIMENSION),
    )]
    pub height: Option<u32>,
    /// Vertical field of view in degrees, strictly between 0 and 180 [default: 90].
    #[arg(
        long,
        value_name = "DEGREES",
        allow_hyphen_values = true,
        value_parser = fov_degrees,
    )]
    pub fov: Option<f32>,
    /// Camera position [default: 0,0,0].
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_vec3, allow_hyphen_values = true)]
    pub look_from: Option<Vec3>,
    /// Point the camera looks at [default: 0,0,-1].
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_vec3, allow_hyphen_values = true)]
    pub look_to: Option<Vec3>,
    /// World up direction of the camera [default: 0,1,0].
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_vec3, allow_hyphen_values = true)]
    pub up: Option<Vec3>,
    /// Recursion depth of full mode (1..=64): 1 traces primary and shadow rays only.
    /// With glass, each level can double the rays per pixel [default: 4].
    #[arg(
        long,
        value_name = "N",
        allow_hyphen_values = true,
        value_parser = whole_number(1, MAX_RECURSION_DEPTH),
    )]
    pub depth: Option<u32>,
    /// What to render [default: full].
    #[arg(long, value_enum)]
    pub mode: Option<ModeArg>,
    /// Samples per pixel in full mode (1..=65536): 1 traces pixel centres, more take
    /// stratified jittered positions with a fixed seed (same image every run)
    /// [default: 1].
    #[arg(long, value_name = "N", allow_hyphen_values = true)]
    pub spp: Option<u32>,
    /// Worker threads (0..=1024); 0 uses every core.
    #[arg(
        short = 'j',
        long,
        default_value_t = 0,
        value_name = "N",
        allow_hyphen_values = true,
        value_parser = whole_number(0, MAX_THREADS),
    )]
    pub threads: u32,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum ModeArg {
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

impl ViewArgs {
    /// The options these flags set; unset ones stay unset, for a scene file's values
    /// or the defaults to fill in.
    pub fn options(&self) -> PartialOptions {
        PartialOptions {
            width: self.width,
            height: self.height,
            fov_degrees: self.fov,
            look_from: self.look_from,
            look_to: self.look_to,
            up: self.up,
            depth: self.depth,
            mode: self.mode.map(Mode::from),
            samples_per_pixel: self.spp,
        }
    }
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
                panic!("not render");
            };
            assert_eq!(args.view.look_from, Some(Vec3::new(-1.0, 2.0, -3.0)));
            assert_eq!(args.view.width, None);
        }
    }
}
