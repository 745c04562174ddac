//! Encoded image files, written atomically ([`check_output`], [`lock_commits`]): the
//! format follows the output file's extension. PNG holds the
//! post-processed 8-bit image; OpenEXR holds the film's linear values before any
//! post-processing, as 32-bit floats.
//!
//! | mode   | PNG                                   | OpenEXR channels                    |
//! |--------|---------------------------------------|-------------------------------------|
//! | full   | tone mapped, gamma 2.2                | `R`, `G`, `B`: linear radiance      |
//! | depth  | distance / farthest, misses white     | `Z`: distance, `+inf` on a miss     |
//! | normal | `n / 2 + 1/2`, misses black           | `R`, `G`, `B`: `n.x`, `n.y`, `n.z`, zero on a miss |

use std::ffi::OsStr;
use std::io;
use std::path::{Path, PathBuf};

use exr::prelude::{
    AnyChannel, AnyChannels, Encoding, FlatSamples, Image as ExrImage, ImageAttributes,
    IntegerBounds, Layer, LayerAttributes, SmallVec, SpecificChannels, Vec2 as ExrVec2,
    WritableImage,
};

mod atomic;
mod png;

pub use atomic::{Commits, WriteError, check_output, lock_commits, remove_temp_files};
pub use png::write_png_bytes;

use crate::film::{Film, Outputs};
use crate::math::{Float, Vec3};
use crate::options::Mode;
use crate::postprocess::PostProcessing;
use atomic::write_atomically;

/// The kinds of image file the renderer writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ImageFormat {
    /// 8-bit RGB PNG of the post-processed image (`.png`).
    Png,
    /// 32-bit float OpenEXR of the linear film (`.exr`).
    Exr,
}

/// An output path whose extension names no format the renderer writes.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("cannot write {}: {}", path.display(), reason(extension.as_deref()))]
pub struct UnknownFormatError {
    /// The output path.
    pub path: PathBuf,
    /// Its extension, if it has one.
    pub extension: Option<String>,
}

fn reason(extension: Option<&str>) -> String {
    match extension {
        Some(e) => format!("unknown image format '.{e}' (use .png or .exr)"),
        None => "no file extension to choose the image format (use .png or .exr)".into(),
    }
}

impl ImageFormat {
    /// The format named by `path`'s extension, in any letter case: `.png` or `.exr`.
    ///
    /// # Errors
    /// The extension is missing or names another format.
    pub fn from_path(path: &Path) -> Result<ImageFormat, UnknownFormatError> {
        let extension = path.extension().map(OsStr::to_string_lossy);
        match extension.as_deref().map(str::to_ascii_lowercase).as_deref() {
            Some("png") => Ok(ImageFormat::Png),
            Some("exr") => Ok(ImageFormat::Exr),
            _ => Err(UnknownFormatError {
                path: path.to_path_buf(),
                extension: extension.map(String::from),
            }),
        }
    }
}

impl Film {
    /// Writes the film rendered in `mode` to `path` as `format` says, atomically
    /// (see [`Image::write_png`](crate::Image::write_png)): PNG after [`Film::to_image`], OpenEXR via
    /// [`Film::write_exr`].
    ///
    /// # Errors
    /// The file cannot be created or written.
    pub fn write(
        &self,
        post: impl Into<PostProcessing>,
        format: ImageFormat,
        path: &Path,
    ) -> Result<(), WriteError> {
        let post = post.into();
        match format {
            ImageFormat::Png => self.to_image(post).write_png(path),
            ImageFormat::Exr => self.write_exr(post.mode, path),
        }
    }

    /// Writes the film's linear values, before tone mapping or normalization, as a
    /// 32-bit float OpenEXR file (ZIP compressed scan lines, top row first),
    /// atomically like [`crate::Image::write_png`]. Full and normal modes write the
    /// channels `R`, `G`, `B` (radiance; normal components); depth mode writes the
    /// distance as the single channel `Z`, infinite where the ray hit nothing.
    ///
    /// # Errors
    /// The file cannot be created or written.
    pub fn write_exr(&self, mode: Mode, path: &Path) -> Result<(), WriteError> {
        let size = (self.width as usize, self.height as usize);
        let width = self.width as usize;
        let at = move |p: ExrVec2<usize>| self.pixels[p.y() * width + p.x()];
        // ZIP over 16 scan lines, written in increasing order, keeps files small and
        // byte-identical from run to run (tiles written in completion order would not be).
        let encoding = Encoding::SMALL_LOSSLESS;
        write_atomically(path, "exr", |file| {
            let written = match mode {
                Mode::Full | Mode::Normal | Mode::Path => {
                    let channels = SpecificChannels::rgb(|p| {
                        let v = at(p);
                        (v.x, v.y, v.z)
                    });
                    let layer = Layer::new(size, LayerAttributes::default(), encoding, channels);
                    ExrImage::from_layer(layer).write().to_unbuffered(file)
                }
                Mode::Depth => {
                    let channels = SpecificChannels::build()
                        .with_channel("Z")
                        .with_pixel_fn(|p| (at(p).x,));
                    let layer = Layer::new(size, LayerAttributes::default(), encoding, channels);
                    ExrImage::from_layer(layer).write().to_unbuffered(file)
                }
            };
            written.map_err(io::Error::other)
        })
    }
}

impl Outputs {
    /// Writes the colour and every extra output as layers (parts) of one 32-bit float
    /// OpenEXR file, atomically like [`Film::write_exr`]. The colour comes first, as
    /// the film's channels (`R`, `G`, `B`, or `Z` in depth mode) and, with `alpha`
    /// (the coverage, [`crate::Aov::Alpha`]), `A` (the colour is premultiplied by it,
    /// as OpenEXR expects, when the camera rays that miss add nothing). It is named
    /// `color` when other layers follow. Then, by name: `depth` (`Z`), `normal` (`X`, `Y`, `Z`), `albedo`
    /// (`R`, `G`, `B`), `alpha` (`A`), `object_id` and `material_id` (`id`, as floats,
    /// exact up to 2^24; -1 on a miss).
    ///
    /// # Errors
    /// The file cannot be created or written.
    pub fn write_exr(
        &self,
        mode: Mode,
        alpha: Option<&[Float]>,
        path: &Path,
    ) -> Result<(), WriteError> {
        let film = &self.film;
        let size = (film.width as usize, film.height as usize);
        let encoding = Encoding::SMALL_LOSSLESS;
        let floats = |values: Vec<Float>| FlatSamples::F32(values);
        let vectors = |values: &[Vec3], names: [&str; 3]| -> Vec<AnyChannel<FlatSamples>> {
            (0..3)
                .map(|c| {
                    let plane = values.iter().map(|v| v[c]).collect();
                    AnyChannel::new(names[c], floats(plane))
                })
                .collect()
        };
        let ids = |values: &[i32]| floats(values.iter().map(|&id| id as Float).collect());
        let mut colour = match mode {
            Mode::Depth => vec![AnyChannel::new(
                "Z",
                floats(film.pixels.iter().map(|v| v.x).collect()),
            )],
            Mode::Full | Mode::Normal | Mode::Path => vectors(&film.pixels, ["R", "G", "B"]),
        };
        let planes = &self.aovs;
        if let Some(alpha) = alpha {
            colour.push(AnyChannel::new("A", floats(alpha.to_vec())));
        }
        let mut layers: Vec<(Option<&str>, Vec<AnyChannel<FlatSamples>>)> = vec![(None, colour)];
        if let Some(depth) = &planes.depth {
            layers.push((
                Some("depth"),
                vec![AnyChannel::new("Z", floats(depth.clone()))],
            ));
        }
        if let Some(normal) = &planes.normal {
            layers.push((Some("normal"), vectors(normal, ["X", "Y", "Z"])));
        }
        if let Some(albedo) = &planes.albedo {
            layers.push((Some("albedo"), vectors(albedo, ["R", "G", "B"])));
        }
        if let Some(alpha) = &planes.alpha {
            layers.push((
                Some("alpha"),
                vec![AnyChannel::new("A", floats(alpha.clone()))],
            ));
        }
        if let Some(object) = &planes.object_id {
            layers.push((Some("object_id"), vec![AnyChannel::new("id", ids(object))]));
        }
        if let Some(material) = &planes.material_id {
            layers.push((
                Some("material_id"),
                vec![AnyChannel::new("id", ids(material))],
            ));
        }
        let several = layers.len() > 1;
        let layers: Vec<_> = layers
            .into_iter()
            .map(|(name, channels)| {
                let attributes = match (name, several) {
                    (Some(name), _) => LayerAttributes::named(name),
                    (None, true) => LayerAttributes::named("color"),
                    (None, false) => LayerAttributes::default(),
                };
                let channels = AnyChannels::sort(SmallVec::from_vec(channels));
                Layer::new(size, attributes, encoding, channels)
            })
            .collect();
        let attributes = ImageAttributes::new(IntegerBounds::from_dimensions(size));
        let image = ExrImage::from_layers(attributes, layers);
        write_atomically(path, "exr", |file| {
            image.write().to_unbuffered(file).map_err(io::Error::other)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_extension_chooses_the_format_in_any_case() {
        for (name, format) in [
            ("a.png", ImageFormat::Png),
            ("dir.x/B.PNG", ImageFormat::Png),
            ("c.exr", ImageFormat::Exr),
            ("d.Exr", ImageFormat::Exr),
        ] {
            assert_eq!(ImageFormat::from_path(name.as_ref()), Ok(format), "{name}");
        }
    }

    #[test]
    fn unknown_or_missing_extensions_are_named_in_the_error() {
        let err = ImageFormat::from_path("out.jpg".as_ref()).unwrap_err();
        assert_eq!(err.extension.as_deref(), Some("jpg"));
        assert!(err.to_string().contains("'.jpg'"), "{err}");
        assert!(err.to_string().contains("out.jpg"), "{err}");
        let err = ImageFormat::from_path("out".as_ref()).unwrap_err();
        assert_eq!(err.extension, None);
        assert!(err.to_string().contains("no file extension"), "{err}");
    }
}
