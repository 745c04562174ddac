//! The command line: flag definitions ([`args`]), the commands, and the progress
//! bar. The library knows nothing of clap or terminals.

mod args;
mod bench;
mod info;
mod interrupt;
pub mod progress;
mod render;
mod values;

pub use args::Cli;
use args::{Command, ViewArgs};

use anyhow::Context;
use raytracer::formats::{self, SceneFormat};
use raytracer::{RenderOptions, SceneDescription};

/// Sets up the thread pool and runs the command.
pub fn run(cli: Cli) -> anyhow::Result<()> {
    let view = match &cli.command {
        Command::Render(args) => &args.view,
        Command::Bench(args) => &args.view,
        Command::Info { scene } => return info::run(scene),
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
    }
}

/// Loads the scene and the validated options: each from the flag if given, else
/// from the scene file (TOML), else the default.
fn load_scene(view: &ViewArgs) -> anyhow::Result<(SceneDescription, RenderOptions)> {
    let flags = view.options();
    // OBJ and PLY files set no options, so the flags can be checked before a long
    // load; a TOML file's values must be merged first.
    if SceneFormat::require(&view.scene)? != SceneFormat::Toml {
        flags.resolve().validate()?;
    }
    let loaded = formats::load(&view.scene)?;
    let options = flags.or(loaded.options).resolve();
    options.validate()?;
    Ok((loaded.description, options))
}
