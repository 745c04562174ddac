//! A Whitted-style CPU ray tracer for Wavefront OBJ/MTL scenes.
//!
//! Data flows one way, one module per stage:
//! files ([`scene::load_obj`]) -> [`SceneDescription`] -> [`Scene`] (with its [`Bvh`])
//! -> [`render`] (a [`Camera`] and an integrator per pixel) -> linear [`Film`]
//! -> [`Image`] (post-processing) -> PNG.
//!
//! ```no_run
//! use raytracer::{BvhParams, Mode, RenderOptions, Scene, render, scene};
//!
//! let description = scene::load_obj("examples/cornell-box/scene.obj".as_ref())?;
//! let scene = Scene::build(description, &BvhParams::default());
//! let options = RenderOptions { mode: Mode::Full, ..RenderOptions::default() };
//! options.validate()?;
//! let film = render(&scene, &options);
//! film.to_image(options.mode).write_png("out.png".as_ref())?;
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
#![deny(missing_docs)]

pub mod bvh;
pub mod camera;
pub mod film;
pub mod integrators;
pub mod material;
pub mod math;
pub mod options;
pub mod output;
mod render;
pub mod sampler;
pub mod scene;
pub mod shapes;

pub use bvh::{Bvh, BvhParams};
pub use camera::Camera;
pub use film::{Film, Image};
pub use integrators::Mode;
pub use material::{Material, MaterialId, PointLight};
pub use options::RenderOptions;
pub use output::ImageFormat;
pub use render::{render, render_with_progress};
pub use sampler::PixelSampler;
pub use scene::{Hit, Scene, SceneDescription, SceneError};
