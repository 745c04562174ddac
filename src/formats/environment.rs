//! Environment maps and colours as `--env` and a TOML `[environment]` name them: a
//! colour `R,G,B`, or an equirectangular image (Radiance `.hdr`, OpenEXR, or any
//! texture format), read under the texture limits ([`crate::textures`]).

use std::path::Path;
use std::sync::Arc;

use crate::lights::environment::{EnvironmentDesc, EnvironmentRadiance};
use crate::math::{Float, Vec3};
use crate::textures::Texture;

/// The environment of the image file `path`, times `strength`, turned by
/// `rotation_degrees` about +Y; with a warning if some texels are NaN, infinite or
/// negative (they emit nothing).
///
/// # Errors
/// A file that cannot be read or is not an image (naming the file), an OpenEXR file
/// of a compression the decoder cannot read (DWAA, DWAB: naming it and a fix), an
/// image over the texture limits.
pub fn load_environment_map(
    path: &Path,
    strength: Float,
    rotation_degrees: Float,
) -> Result<(EnvironmentDesc, Option<String>), String> {
    let shown = path.display();
    if path.is_dir() {
        return Err(format!("{shown}: is a directory"));
    }
    if let Some(compression) = unreadable_exr_compression(path) {
        return Err(format!(
            "{shown}: OpenEXR compressed with {compression}, which the renderer's decoder cannot read; convert it to ZIP or PIZ (for example `oiiotool {shown} --compression zip -o out.exr`) or use the .hdr version of the map"
        ));
    }
    let texture = crate::textures::load_texture(path).map_err(|e| format!("{shown}: {e}"))?;
    let warning = bad_texels(&texture).map(|count| {
        format!("{shown}: {count} texels are NaN, infinite or negative; they emit nothing")
    });
    Ok((
        EnvironmentDesc {
            radiance: EnvironmentRadiance::Map(texture),
            strength,
            rotation_degrees,
        },
        warning,
    ))
}

/// A uniform environment of `colour`.
pub fn environment_colour(colour: Vec3, strength: Float) -> EnvironmentDesc {
    EnvironmentDesc {
        radiance: EnvironmentRadiance::Constant(colour),
        strength,
        rotation_degrees: 0.0,
    }
}

/// The number of texels with a channel that is not finite or is negative, if any.
fn bad_texels(texture: &Arc<Texture>) -> Option<usize> {
    let (width, height) = texture.size();
    let mut bad = 0;
    for y in 0..height {
        for x in 0..width {
            let uv = crate::math::Vec2::new(
                (x as Float + 0.5) / width as Float,
                1.0 - (y as Float + 0.5) / height as Float,
            );
            let t = texture.bilinear(
                uv,
                crate::textures::Wrap::Clamp,
                crate::textures::Wrap::Clamp,
                crate::textures::Encoding::Linear,
            );
            if t[..3].iter().any(|c| !c.is_finite() || *c < 0.0) {
                bad += 1;
            }
        }
    }
    (bad > 0).then_some(bad)
}

/// The compression of an OpenEXR file that the `exr` crate cannot decode.
fn unreadable_exr_compression(path: &Path) -> Option<&'static str> {
    let is_exr = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("exr"));
    if !is_exr {
        return None;
    }
    let meta = exr::meta::MetaData::read_from_file(path, false).ok()?;
    meta.headers.iter().find_map(|h| match h.compression {
        exr::compression::Compression::DWAA(_) => Some("DWAA"),
        exr::compression::Compression::DWAB(_) => Some("DWAB"),
        _ => None,
    })
}
