//! Shell completions and the man page, generated from the same clap definitions as
//! `--help`, so that they cannot say other than the program does.

use clap::CommandFactory;

use super::args::Cli;
use super::write_stdout;

/// `raytracer completions SHELL`: the completion script for `shell` on stdout.
pub fn completions(shell: clap_complete::Shell) -> anyhow::Result<()> {
    let mut command = Cli::command();
    let mut out = Vec::new();
    clap_complete::generate(shell, &mut command, "raytracer", &mut out);
    write_stdout(&out)
}

/// `raytracer man`: the man page raytracer(1), in roff, on stdout. After the main
/// page's sections comes one section per visible subcommand (`render`, `bench`,
/// `info`), with its synopsis and every flag, so that one page holds them all.
pub fn man_page() -> anyhow::Result<()> {
    let command = Cli::command();
    let main = clap_mangen::Man::new(command.clone());
    let mut out = Vec::new();
    // The main page's sections but its list of subcommands, which would point to
    // pages raytracer-render(1) and so on that are not installed: the subcommands'
    // own sections below take its place.
    main.render_title(&mut out)?;
    main.render_name_section(&mut out)?;
    main.render_synopsis_section(&mut out)?;
    main.render_description_section(&mut out)?;
    main.render_options_section(&mut out)?;
    for sub in command.get_subcommands().filter(|s| !s.is_hide_set()) {
        let name = format!("raytracer {}", sub.get_name());
        let man = clap_mangen::Man::new(sub.clone().bin_name(name.clone()));
        let mut synopsis = Vec::new();
        man.render_synopsis_section(&mut synopsis)?;
        let mut options = Vec::new();
        man.render_options_section(&mut options)?;
        // Each render starts a top-level section (`.SH SYNOPSIS`, `.SH OPTIONS`): here
        // they become one section named after the subcommand, with subsections.
        let synopsis = String::from_utf8(synopsis)?.replacen(
            ".SH SYNOPSIS",
            &format!(
                ".SH \"{}\"\n{}\n.SS Synopsis",
                name.to_uppercase(),
                about(sub)
            ),
            1,
        );
        let options = String::from_utf8(options)?.replacen(".SH OPTIONS", ".SS Options", 1);
        out.extend_from_slice(synopsis.as_bytes());
        out.extend_from_slice(options.as_bytes());
    }
    main.render_version_section(&mut out)?;
    write_stdout(&out)
}

/// A subcommand's one-line description, escaped for roff (a line starting with a dot
/// or a quote would be read as a request).
fn about(command: &clap::Command) -> String {
    let about = command
        .get_about()
        .map(|a| a.to_string())
        .unwrap_or_default();
    format!("\\&{}", about.replace('\\', "\\e"))
}
