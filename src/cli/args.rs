//! Flag definitions (clap derive), converted to the library's [`PartialOptions`].

use std::path::PathBuf;

use clap::{Parser, Subcommand, ValueEnum};
use raytracer::Mode;
use raytracer::math::{Float, Vec3};
use raytracer::options::{Origin, PartialOptions, Sourced, ToneMap};

use super::values::{
    AovList, Background, LOOK_FROM, LOOK_TO, UP, aov_list, background, number, thread_count,
    vector, whole_number,
};

/// A CPU ray tracer for OBJ/MTL, PLY, glTF 2.0 and TOML scenes, to PNG or OpenEXR.
///
/// Four modes: full (the default: Phong lighting, hard shadows, mirror reflection and
/// refraction, tone mapped), depth, normal, and path (a physically based path tracer
/// with area lights). `raytracer render SCENE -o OUT.png` frames and lights a scene
/// that sets no camera and no light.
#[derive(Parser, Debug)]
#[command(name = "raytracer", version)]
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
        /// The scene: OBJ (MTL files beside it), PLY, glTF 2.0 (.gltf, .glb) or a TOML
        /// scene file; any may be gzip-compressed.
        #[arg(value_name = "SCENE")]
        scene: PathBuf,
    },
    /// Print a shell completion script for SHELL on stdout.
    ///
    /// For example `raytracer completions bash > ~/.local/share/bash-completion/completions/raytracer`.
    #[command(hide = true)]
    Completions {
        /// The shell to complete in.
        #[arg(value_enum)]
        shell: clap_complete::Shell,
    },
    /// Print the man page, raytracer(1), in roff on stdout: `raytracer man > raytracer.1`.
    #[command(hide = true)]
    Man,
}

/// Flags of `bench`.
#[derive(clap::Args, Debug)]
pub struct BenchArgs {
    #[command(flatten)]
    pub view: ViewArgs,
    /// Runs per measurement; the median is reported.
    #[arg(long, default_value_t = 5, value_name = "N")]
    pub repeat: usize,
    /// Also write the scene's triangles and the benchmark's rays to this file, for
    /// the Embree benchmark in bench/embree/ to trace the same rays.
    #[arg(long, value_name = "FILE")]
    pub dump_rays: Option<PathBuf>,
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
    /// Print the time of each stage (wall, and where the OS reports them CPU time of
    /// all threads and page faults), BVH size and quality, rays traced and peak memory
    /// on stderr.
    #[arg(long)]
    pub stats: bool,
    /// Remove path mode's Monte Carlo noise with Intel Open Image Denoise before the
    /// image is written (PNG and EXR). Needs a build with `--features denoise`.
    #[arg(long)]
    pub denoise: bool,
    /// Extra outputs rendered in the same pass, written as layers of one OpenEXR file
    /// after the colour (the output must be .exr): a comma-separated list of depth
    /// (z-depth along the view axis, inf on a miss), normal (world-space shading
    /// normal), albedo (reflectance colour), alpha (coverage), object_id and
    /// material_id (of the ray through the pixel centre, -1 on a miss).
    #[arg(long, value_name = "LIST", value_parser = aov_list)]
    pub aovs: Option<AovList>,
}

/// The scene and how to look at it: shared by `render` and `bench`. Camera and render
/// flags are optional so that a TOML scene's values show through: a flag overrides
/// the file, the file overrides the default shown. Their parsers check the syntax
/// only; ranges are checked once the flags are merged over the file.
#[derive(clap::Args, Debug)]
pub struct ViewArgs {
    /// The scene: OBJ (MTL files beside it), PLY, glTF 2.0 (.gltf, .glb) or a TOML
    /// scene file (docs/scene-format.md); any may be gzip-compressed.
    #[arg(value_name = "SCENE")]
    pub scene: PathBuf,
    /// Image width in pixels (1..=65536) [default: 640].
    ///
    /// Given without --height, the height keeps the aspect ratio of the scene file's
    /// image size (640x480 if it sets none), rounded to the nearest pixel: --width 320
    /// renders 320x240.
    #[arg(long, value_name = "PIXELS", allow_hyphen_values = true, value_parser = whole_number)]
    pub width: Option<i64>,
    /// Image height in pixels (1..=65536; at most 16384x16384 pixels in all)
    /// [default: 480].
    ///
    /// Given without --width, the width keeps the aspect ratio of the scene file's
    /// image size (640x480 if it sets none), rounded to the nearest pixel: --height 240
    /// renders 320x240.
    #[arg(long, value_name = "PIXELS", allow_hyphen_values = true, value_parser = whole_number)]
    pub height: Option<i64>,
    /// Vertical field of view in degrees, strictly between 0 and 180 [default: 90; 40
    /// when the camera frames the scene].
    ///
    /// The scene file's field of view, if it sets one, wins over both. The narrower
    /// field of view of a camera that frames the scene (see --look-from) is a model
    /// viewer's: the model is seen with little distortion.
    #[arg(long, value_name = "DEGREES", allow_hyphen_values = true, value_parser = number)]
    pub fov: Option<Float>,
    /// Camera position, three numbers with commas and no spaces [default: framed].
    ///
    /// When neither --look-from nor --look-to is given (here or in a scene file), the
    /// camera frames the scene as a model viewer does: from the front (+z, where glTF
    /// models face; -y when --up is 0,0,1) and above, 22 degrees up and 30 degrees to
    /// the right, from as close as lets the corners of the scene's bounds fit 92% of
    /// the image's limiting dimension, centred; a scene flat in x, y or z (one polygon,
    /// a floor) is seen face-on, along -x, -y or -z. Given alone, it looks at the
    /// centre of the bounds. An empty scene, or --look-to alone, keeps 0,0,0.
    #[arg(long, value_name = "X,Y,Z", allow_hyphen_values = true, value_parser = vector(LOOK_FROM))]
    pub look_from: Option<Vec3>,
    /// Point the camera looks at [default: framed].
    ///
    /// When the camera frames the scene (see --look-from), the point level with the
    /// centre of the scene's bounds that centres their projection; the centre itself
    /// when only --look-from is given; 0,0,-1 when the scene is empty.
    #[arg(long, value_name = "X,Y,Z", allow_hyphen_values = true, value_parser = vector(LOOK_TO))]
    pub look_to: Option<Vec3>,
    /// World up direction of the camera [default: 0,1,0].
    #[arg(long, value_name = "X,Y,Z", allow_hyphen_values = true, value_parser = vector(UP))]
    pub up: Option<Vec3>,
    /// Recursion depth of full mode (1..=64): 1 traces primary and shadow rays only
    /// [default: 4; 64 in path mode].
    ///
    /// With glass, each level can double the rays per pixel. In path mode, the most
    /// path segments (1..=1024; Mitsuba's max_depth). Depth and normal modes ignore it.
    #[arg(long, value_name = "N", allow_hyphen_values = true, value_parser = whole_number)]
    pub depth: Option<i64>,
    /// What to render [default: full].
    #[arg(long, value_enum)]
    pub mode: Option<ModeArg>,
    /// Samples per pixel in full and path modes (1..=65536): 1 traces pixel centres,
    /// more take stratified jittered positions with a fixed seed (same image every
    /// run) [default: 1; 64 in path mode].
    #[arg(long, value_name = "N", allow_hyphen_values = true, value_parser = whole_number)]
    pub spp: Option<i64>,
    /// Path mode's exposure in stops: PNG values are the radiance times 2^STOPS, then
    /// the sRGB curve (-64..=64) [default: 0].
    #[arg(long, value_name = "STOPS", allow_hyphen_values = true, value_parser = number)]
    pub exposure: Option<Float>,
    /// Path mode's tone map of PNG output, after the exposure [default: khronos-neutral].
    ///
    /// standard clamps at 1 (earlier versions' look), khronos-neutral keeps base colours
    /// and rolls highlights off to white, agx and aces are the filmic curves of Blender
    /// and three.js. Full mode keeps SPEC's tone map and ignores this; EXR output stays
    /// linear.
    #[arg(long, value_enum, value_name = "OPERATOR")]
    pub tonemap: Option<ToneMapArg>,
    /// Radius of the camera's thin lens in scene units, 0 or more [default: 0].
    ///
    /// Points nearer or farther than --focus-distance blur into discs; 0 is a pinhole,
    /// everything sharp. Full and path modes only (depth and normal modes and
    /// orthographic cameras keep a pinhole); take more --spp to smooth the blur.
    #[arg(long, value_name = "R", allow_hyphen_values = true, value_parser = number)]
    pub aperture_radius: Option<Float>,
    /// Distance in scene units from the lens to the plane in focus, along the view
    /// direction, greater than 0 [default: the distance from --look-from to --look-to].
    ///
    /// Used with --aperture-radius.
    #[arg(long, value_name = "D", allow_hyphen_values = true, value_parser = number)]
    pub focus_distance: Option<Float>,
    /// Seed of the random numbers (0..=4294967295): another seed, another equally
    /// valid image; the same seed, the same image on any number of threads [default: 0].
    #[arg(long, value_name = "N", allow_hyphen_values = true, value_parser = whole_number)]
    pub seed: Option<i64>,
    /// Render a scene with no light ('P', a scene file's [[light]]) and no emitter
    /// ('Ke') as it is: black but for its ambient colour in full mode, black in path
    /// mode. By default such a scene gets a light rig at the camera (full mode) or a
    /// studio environment before a grey backdrop (path mode), with a warning.
    #[arg(long)]
    pub no_default_light: bool,
    /// Path mode's environment, lighting the scene from infinitely far away and seen
    /// where camera rays leave it: an equirectangular image (Radiance .hdr, OpenEXR,
    /// PNG or JPEG; +Y up, oriented as three.js and Blender show it) or a colour
    /// R,G,B. Replaces the scene file's [environment] [default: the scene's; none].
    #[arg(long, value_name = "FILE|R,G,B")]
    pub env: Option<String>,
    /// Multiplies the environment's radiance (0..) [default: the scene's; 1].
    #[arg(long, value_name = "X", value_parser = number)]
    pub env_strength: Option<Float>,
    /// Turns the environment about +Y by DEGREES, right-handed: at 90, what was seen
    /// along +X is seen along -Z [default: the scene's; 0].
    #[arg(long, value_name = "DEGREES", allow_hyphen_values = true, value_parser = number)]
    pub env_rotation: Option<Float>,
    /// What camera rays that leave the scene see, instead of the environment (which
    /// still lights the scene): a colour R,G,B (path mode), or `transparent` (both
    /// modes): an RGBA PNG, or an EXR with `A`, whose alpha is the fraction of each
    /// pixel's camera rays that hit the scene [default: the environment].
    #[arg(long, value_name = "R,G,B|transparent", value_parser = background)]
    pub background: Option<Background>,
    /// Worker threads (0..=1024); 0 uses every core.
    #[arg(
        short = 'j',
        long,
        default_value_t = 0,
        value_name = "N",
        allow_hyphen_values = true,
        value_parser = thread_count,
    )]
    pub threads: u32,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum ModeArg {
    /// Whitted-style: Phong lighting, hard shadows, reflection and refraction, tone
    /// mapped.
    Full,
    /// Distance to the nearest hit, normalized by the farthest (misses white).
    Depth,
    /// Surface normal facing the camera as colour, n/2 + 1/2 (misses black).
    Normal,
    /// Physically based path tracing: area lights from Ke, global illumination.
    Path,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum ToneMapArg {
    /// Exposure, clamp at 1, sRGB curve.
    Standard,
    /// Khronos PBR Neutral: true base colours, highlights compressed towards white.
    KhronosNeutral,
    /// AgX (Blender, three.js): filmic, desaturates bright colours.
    Agx,
    /// ACES filmic (Stephen Hill's fit, as three.js).
    Aces,
}

impl From<ToneMapArg> for ToneMap {
    fn from(t: ToneMapArg) -> ToneMap {
        match t {
            ToneMapArg::Standard => ToneMap::Standard,
            ToneMapArg::KhronosNeutral => ToneMap::KhronosNeutral,
            ToneMapArg::Agx => ToneMap::Agx,
            ToneMapArg::Aces => ToneMap::Aces,
        }
    }
}

impl From<ModeArg> for Mode {
    fn from(m: ModeArg) -> Mode {
        match m {
            ModeArg::Full => Mode::Full,
            ModeArg::Depth => Mode::Depth,
            ModeArg::Normal => Mode::Normal,
            ModeArg::Path => Mode::Path,
        }
    }
}

impl ViewArgs {
    /// The options these flags set; unset ones stay unset, for a scene file's values
    /// or the defaults to fill in.
    pub fn options(&self) -> PartialOptions {
        fn flag<T>(value: Option<T>, name: &'static str) -> Option<Sourced<T>> {
            value.map(|value| Sourced::new(value, Origin::Flag(name)))
        }
        PartialOptions {
            width: flag(self.width, "--width"),
            height: flag(self.height, "--height"),
            fov_degrees: flag(self.fov, "--fov"),
            look_from: flag(self.look_from, LOOK_FROM.name),
            look_to: flag(self.look_to, LOOK_TO.name),
            up: flag(self.up, UP.name),
            depth: flag(self.depth, "--depth"),
            mode: flag(self.mode.map(Mode::from), "--mode"),
            samples_per_pixel: flag(self.spp, "--spp"),
            exposure: flag(self.exposure, "--exposure"),
            seed: flag(self.seed, "--seed"),
            default_light: self
                .no_default_light
                .then(|| Sourced::new(false, Origin::Flag("--no-default-light"))),
            tonemap: flag(self.tonemap.map(ToneMap::from), "--tonemap"),
            aperture_radius: flag(self.aperture_radius, "--aperture-radius"),
            focus_distance: flag(self.focus_distance, "--focus-distance"),
            projection: None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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

    #[test]
    fn each_value_names_the_flag_that_set_it() {
        let argv = [
            "raytracer",
            "render",
            "s.obj",
            "-o",
            "o.png",
            "--width",
            "-1",
            "--height",
            "2",
            "--fov",
            "300",
            "--look-from",
            "1,2,3",
            "--look-to",
            "4,5,6",
            "--up",
            "0,0,1",
            "--depth",
            "0",
            "--mode",
            "depth",
            "--spp",
            "6",
        ];
        let Command::Render(args) = Cli::try_parse_from(argv).unwrap().command else {
            panic!("not render");
        };
        let o = args.view.options();
        assert_eq!(o.width.as_ref().map(|w| w.value), Some(-1));
        assert_eq!(o.fov_degrees.as_ref().map(|f| f.value), Some(300.0));
        let origins = [
            o.width.map(|v| v.origin),
            o.height.map(|v| v.origin),
            o.fov_degrees.map(|v| v.origin),
            o.look_from.map(|v| v.origin),
            o.look_to.map(|v| v.origin),
            o.up.map(|v| v.origin),
            o.depth.map(|v| v.origin),
            o.mode.map(|v| v.origin),
            o.samples_per_pixel.map(|v| v.origin),
        ];
        for origin in origins {
            let Some(Origin::Flag(name)) = origin else {
                panic!("{origin:?}");
            };
            assert!(argv.contains(&name), "{name}");
        }
    }
}
