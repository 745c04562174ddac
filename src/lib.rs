//! A CPU ray tracer for Wavefront OBJ/MTL, PLY, glTF 2.0 and TOML scenes.
//!
//! Four modes ([`Mode`]): full, the default, a Whitted-style renderer (Phong lighting,
//! hard shadows, mirror reflection and refraction, tone mapping and gamma: the rules
//! are in `docs/spec-renderer.md`); depth and normal, the distance and the surface
//! normal at each pixel; and path, a physically based path tracer with area lights
//! ([`integrators::PathIntegrator`]). Images are written as PNG or OpenEXR.
//!
//! Data flows one way, one module per stage:
//! files ([`formats::load`]: OBJ/MTL, PLY, glTF 2.0 or a TOML scene, any of them
//! gzip-compressed; glTF and TOML files may also set [`options::PartialOptions`]) -> [`SceneDescription`] -> [`Scene`] (with its [`Bvh`])
//! -> [`render`] (a [`Camera`], a [`PixelSampler`] and an [`Integrator`] chosen once per
//! render, which traces bands of rows as it chooses; [`render_tile`] renders part of
//! the image, bit-identical to the whole; [`render_outputs`] adds depth, normal,
//! albedo, alpha and object and material ids ([`Aov`]) in the same pass)
//! -> linear [`Film`] (with the [`AovPlanes`] asked for: [`Outputs`]) -> either
//! [`Image`] (post-processing) -> PNG, or the film's linear values -> OpenEXR
//! ([`output`], the extra outputs as layers).
//!
//! # Example
//!
//! Render the bundled Cornell box at 64x48 with 4 samples per pixel, then save the
//! tone-mapped PNG and the linear OpenEXR file:
//!
//! ```
//! use raytracer::math::Vec3;
//! use raytracer::{BvhParams, ImageFormat, Mode, RenderOptions, Scene, formats, render};
//!
//! let description = formats::load_obj("examples/cornell-box/scene.obj".as_ref())?;
//! let scene = Scene::build(description, &BvhParams::default());
//! let options = RenderOptions {
//!     width: 64,
//!     height: 48,
//!     fov_degrees: 60.0,
//!     look_from: Vec3::new(0.0, 0.7, 1.75),
//!     look_to: Vec3::new(0.0, 0.7, 0.0),
//!     samples_per_pixel: 4,
//!     ..RenderOptions::default()
//! };
//! options.validate()?;
//! let film = render(&scene, &options);
//!
//! let dir = tempfile::tempdir()?;
//! film.to_image(Mode::Full).write_png(&dir.path().join("cornell.png"))?;
//! film.write(Mode::Full, ImageFormat::Exr, &dir.path().join("cornell.exr"))?;
//! assert!(dir.path().join("cornell.exr").is_file());
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! # Conventions
//!
//! - World space is right-handed. In camera space the eye looks down -z with y up
//!   and x to the right (world up is +y unless [`RenderOptions::up`] says otherwise).
//! - Images and films are stored row by row, row 0 at the top.
//! - Surface normals are flipped to face the incoming ray.
//! - Colours are linear from the integrators through the [`Film`]; only
//!   post-processing ([`Film::to_image`]) tone maps and gamma-encodes them.
//! - One float type, [`math::Float`] (`f32`), everywhere.
#![deny(missing_docs)]

pub mod benchmark;
pub mod bvh;
pub mod bxdfs;
pub mod camera;
pub mod description;
pub mod film;
pub mod foreign;
pub mod formats;
pub mod integrators;
pub mod lights;
pub mod material;
pub mod math;
pub mod memory;
pub mod options;
pub mod output;
pub mod postprocess;
mod render;
pub mod sampler;
pub mod scene;
pub mod shapes;
pub mod stats;
pub mod textures;
pub mod warnings;

pub use bvh::{Bvh, BvhParams};
pub use camera::Camera;
pub use description::SceneDescription;
pub use film::{Aov, AovPlanes, Film, Outputs};
pub use formats::SceneError;
pub use integrators::Integrator;
pub use material::{Light, LightKind, Material, MaterialId};
pub use options::{Mode, RenderOptions};
pub use output::ImageFormat;
pub use postprocess::Image;
pub use render::{
    RenderTimes, Tile, TileError, render, render_outputs, render_outputs_with_stats, render_tile,
    render_tile_outputs, render_with_progress, render_with_stats,
};
pub use sampler::{PixelSample, PixelSampler};
pub use scene::{Hit, Scene};
