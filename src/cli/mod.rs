//! The command line: flag definitions ([`args`]), the commands, and the progress
//! bar. The library knows nothing of clap or terminals.

mod args;
mod bench;
mod generated;
mod info;
mod interrupt;
pub mod progress;
mod render;
mod values;

use args::{Cli, Command, ViewArgs};

use anyhow::Context;
use clap::{Parser, error::ErrorKind};
use raytracer::formats::{self, SceneFormat};
use raytracer::{RenderOptions, SceneDescription};

/// The command line, parsed; on an error, prints it and exits with status 2 (help and
/// version print and exit 0), as clap does. A vector flag given as separate numbers
/// gets a message that shows how to write it.
pub fn parse() -> Cli {
    let args: Vec<std::ffi::OsString> = std::env::args_os().collect();
    Cli::try_parse_from(&args).unwrap_or_else(|error| {
        let shown = matches!(
            error.kind(),
            ErrorKind::DisplayHelp | ErrorKind::DisplayVersion
        );
        match values::split_vector(&args).filter(|_| !shown) {
            Some(message) => clap::Error::raw(ErrorKind::ValueValidation, message + "\n").exit(),
            None => error.exit(),
        }
    })
}

/// Sets up the thread pool and runs the command.
pub fn run(cli: Cli) -> anyhow::Result<()> {
    let view = match &cli.command {
        Command::Render(args) => &args.view,
        Command::Bench(args) => &args.view,
        Command::Info { scene } => return info::run(scene),
        Command::Completions { shell } => return generated::completions(*shell),
        Command::Man => return generated::man_page(),
    };
    // Before loading: readers use the global pool, which can be set up only once.
    rayon::ThreadPoolBuilder::new()
        .num_threads(view.threads as usize)
        .build_global()
        .context("cannot start worker threads")?;
    match &cli.command {
        Command::Render(args) => render::run(args, cli.quiet),
        Command::Bench(args) => bench::run(args),
        Command::Info { scene } => info::run(scene),
        Command::Completions { .. } | Command::Man => unreachable!("run above"),
    }
}

/// Loads the scene and the options: each value from the flag if given, else from the
/// scene file (TOML, or a glTF camera), else the default, the camera framing the scene
/// if none is given; checked once, after merging, so that a flag can replace a bad value
/// of the file. An unlit scene gets the default lighting
/// ([`formats::LoadedScene::resolve`]).
fn load_scene(view: &ViewArgs) -> anyhow::Result<(SceneDescription, RenderOptions)> {
    load_scene_noting_rig(view, false).map(|(description, options, _)| (description, options))
}

/// [`load_scene`], also telling whether full mode's default light rig lights the
/// scene (it had no light of its own): its misses then show a grey backdrop; for a
/// render asked for `extra_outputs` (`--aovs`), which keeps one sample a pixel under
/// the rig ([`raytracer::options::PartialOptions::resolve_for`]).
fn load_scene_noting_rig(
    view: &ViewArgs,
    extra_outputs: bool,
) -> anyhow::Result<(SceneDescription, RenderOptions, bool)> {
    let flags = view.options();
    // OBJ and PLY files set no options, so the flags can be checked before a long
    // load; a TOML or glTF file's values (a glTF camera) must be merged first.
    if !matches!(
        SceneFormat::require(&view.scene)?,
        SceneFormat::Toml | SceneFormat::Gltf
    ) {
        flags.check_before_loading()?;
    }
    let mut loaded = formats::load(&view.scene)?;
    environment_flags(view, &mut loaded.description)?;
    let unlit = loaded.description.is_unlit();
    let (description, options) = loaded.resolve_with(flags, extra_outputs)?;
    let rig = options.lit_by_rig(unlit);
    Ok((description, options, rig))
}

/// Sets the environment `--env` names (a file or a colour), and applies
/// `--env-strength`, `--env-rotation` and `--background` over the scene's.
fn environment_flags(view: &ViewArgs, description: &mut SceneDescription) -> anyhow::Result<()> {
    use raytracer::formats::environment::{EnvironmentNames, EnvironmentOptions};
    EnvironmentOptions::from_options(&view.options())
        .apply(description, EnvironmentNames::flags())
        .map_err(anyhow::Error::msg)
}

/// Writes `bytes` to stdout; a closed pipe (`raytracer info FILE | head`,
/// `raytracer man | head`) is no error, as for any command whose reader stopped early.
fn write_stdout(bytes: &[u8]) -> anyhow::Result<()> {
    use std::io::Write;
    match std::io::stdout().lock().write_all(bytes) {
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
        result => Ok(result?),
    }
}
