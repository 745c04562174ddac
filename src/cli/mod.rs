//! The command line: flag definitions ([`args`]), the commands, and the progress
//! bar. The library knows nothing of clap or terminals.

mod args;
mod bench;
mod interrupt;
pub mod progress;
mod render;
mod values;

pub use args::Cli;
use args::Command;

use anyhow::Context;

/// Validates the options, sets up the thread pool and runs the command.
pub fn run(cli: Cli) -> anyhow::Result<()> {
    let view = match &cli.command {
        Command::Render(args) => &args.view,
        Command::Bench(args) => &args.view,
    };
    let options = view.options();
    options.validate()?;
    rayon::ThreadPoolBuilder::new()
        .num_threads(view.threads as usize)
        .build_global()
        .context("cannot start worker threads")?;
    match &cli.command {
        Command::Render(args) => render::run(args, &options, cli.quiet),
        Command::Bench(args) => bench::run(args, &options),
    }
}
