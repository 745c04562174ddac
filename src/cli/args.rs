//! Flag definitions (clap derive), converted to the library's [`PartialOptions`].

use std::path::PathBuf;

use clap::builder::{PossibleValue, PossibleValuesParser};
use clap::error::ErrorKind;
use clap::{Arg, ArgAction, ArgMatches, Parser, Subcommand};
use raytracer::math::{Float, Vec3};
use raytracer::options::defs::{Kind, Value};
use raytracer::options::{OPTIONS, OptionDef, Origin, PartialOptions};

use super::values::{
    AovList, Background, aov_list, background, number, thread_count, vector, vector_flag,
    whole_number,
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

/// The scene and how to look at it: shared by `render` and `bench`.
#[derive(clap::Args, Debug)]
pub struct ViewArgs {
    /// The scene: OBJ (MTL files beside it), PLY, glTF 2.0 (.gltf, .glb) or a TOML
    /// scene file (docs/scene-format.md); any may be gzip-compressed.
    #[arg(value_name = "SCENE")]
    pub scene: PathBuf,
    /// The render options, as [`raytracer::options::OPTIONS`] defines their flags.
    #[command(flatten)]
    pub options: OptionFlags,
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

impl ViewArgs {
    /// The options these flags set; unset ones stay unset, for a scene file's values
    /// or the defaults to fill in.
    pub fn options(&self) -> PartialOptions {
        self.options.0.clone()
    }

    /// Whether `--background transparent` is given.
    pub fn transparent(&self) -> bool {
        self.options
            .0
            .background
            .as_ref()
            .is_some_and(|b| b.value == Background::Transparent)
    }
}

/// The flags of every render option, made from [`OPTIONS`]: optional, so that a TOML
/// scene's values show through (a flag overrides the file, the file overrides the
/// default shown). Their parsers check the syntax only; ranges are checked once the
/// flags are merged over the file.
#[derive(Debug, Clone, Default)]
pub struct OptionFlags(pub PartialOptions);

/// The clap argument of `def`, if the command line has its flag.
fn argument(def: &'static OptionDef) -> Option<Arg> {
    if !def.cli {
        return None;
    }
    let help = def.help.strip_suffix('.').unwrap_or(def.help);
    let arg = Arg::new(def.python)
        .long(def.flag.trim_start_matches("--"))
        .help(help);
    let arg = match def.details {
        "" => arg,
        details => arg.long_help(format!("{}\n\n{details}", def.help)),
    };
    if def.kind == Kind::SwitchOff {
        return Some(arg.action(ArgAction::SetTrue));
    }
    let valued = arg
        .value_name(def.value_name)
        .action(ArgAction::Set)
        .allow_hyphen_values(true);
    Some(match def.kind {
        Kind::Whole => valued.value_parser(whole_number),
        Kind::Number => valued.value_parser(number),
        Kind::Vector => valued.value_parser(vector(vector_flag(def))),
        Kind::Choice(choices) => {
            valued
                .allow_hyphen_values(false)
                .value_parser(PossibleValuesParser::new(
                    choices
                        .iter()
                        .map(|(name, help)| PossibleValue::new(*name).help(*help)),
                ))
        }
        Kind::SwitchOff => unreachable!("a switch: above"),
        Kind::FileOrColour => valued.allow_hyphen_values(false),
        Kind::Background => valued.allow_hyphen_values(false).value_parser(background),
        Kind::Matrix | Kind::Intrinsics => unreachable!("no flag: {def:?}"),
    })
}

impl clap::Args for OptionFlags {
    fn augment_args(command: clap::Command) -> clap::Command {
        command.args(OPTIONS.iter().filter_map(argument))
    }

    fn augment_args_for_update(command: clap::Command) -> clap::Command {
        Self::augment_args(command)
    }
}

impl clap::FromArgMatches for OptionFlags {
    fn from_arg_matches(matches: &ArgMatches) -> Result<Self, clap::Error> {
        let mut options = PartialOptions::default();
        for def in OPTIONS.iter().filter(|d| d.cli) {
            let id = def.python;
            let value = match def.kind {
                Kind::Whole => matches.get_one::<i64>(id).copied().map(Value::Whole),
                Kind::Number => matches.get_one::<Float>(id).copied().map(Value::Number),
                Kind::Vector => matches.get_one::<Vec3>(id).copied().map(Value::Vector),
                Kind::Choice(_) => matches.get_one::<String>(id).cloned().map(Value::Name),
                Kind::SwitchOff => matches.get_flag(id).then_some(Value::Switch(false)),
                Kind::FileOrColour => matches.get_one::<String>(id).cloned().map(Value::Text),
                Kind::Background => matches
                    .get_one::<Background>(id)
                    .copied()
                    .map(Value::Background),
                Kind::Matrix | Kind::Intrinsics => None,
            };
            if let Some(value) = value {
                def.store(&mut options, value, Origin::Flag(def.flag))
                    .map_err(|e| clap::Error::raw(ErrorKind::ValueValidation, e))?;
            }
        }
        Ok(OptionFlags(options))
    }

    fn update_from_arg_matches(&mut self, matches: &ArgMatches) -> Result<(), clap::Error> {
        *self = Self::from_arg_matches(matches)?;
        Ok(())
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
            let options = args.view.options();
            assert_eq!(
                options.look_from.map(|v| v.value),
                Some(Vec3::new(-1.0, 2.0, -3.0))
            );
            assert_eq!(options.width, None);
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
