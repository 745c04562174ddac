//! `raytracer info`: a scene's counts, bounds, materials, memory needs and warnings.

use std::path::Path;

use raytracer::formats;
use raytracer::scene::SceneSummary;

/// Prints the summary of the scene at `path` on stdout, for the image size its file
/// sets (or the default). The file's camera and render values must be valid: there
/// are no flags to replace them.
pub fn run(path: &Path) -> anyhow::Result<()> {
    let loaded = formats::load(path)?;
    let summary = SceneSummary::new(&loaded.description, &loaded.options.resolve()?);
    super::write_stdout(summary.to_string().as_bytes())
}
