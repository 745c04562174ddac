//! Environment maps and colours as `--env` and a TOML `[environment]` name them: a
//! colour `R,G,B`, or an equirectangular image (Radiance `.hdr`, OpenEXR, a JPEG with
//! an HDR gain map ([`super::gain_map`]), or any texture format), read under the
//! texture limits ([`crate::textures`]).

use std::path::Path;
use std::sync::Arc;

use crate::description::SceneDescription;
use crate::lights::environment::{EnvironmentDesc, EnvironmentRadiance};
use crate::math::{Float, Vec3};
use crate::options::{Background, OptionDef, OptionId, PartialOptions};
use crate::textures::Texture;

/// The environment and background a command line (`--env`, `--env-strength`,
/// `--env-rotation`, `--background`) or a Python call (`env=`, ...) gives, applied
/// over a scene file's by [`EnvironmentOptions::apply`]: one place for both, so their
/// rules cannot drift apart.
#[derive(Clone, Debug, Default)]
pub struct EnvironmentOptions {
    /// An image file, or a colour `R,G,B`.
    pub env: Option<String>,
    /// Multiplies the environment's radiance (0 or more).
    pub strength: Option<Float>,
    /// Turns the environment about +Y, in degrees.
    pub rotation: Option<Float>,
    /// What camera rays that leave the scene see instead of the environment.
    pub background: Option<Vec3>,
}

/// How the caller spells each of [`EnvironmentOptions`]' values in messages: the
/// command line's flags or Python's keywords.
#[derive(Clone, Copy, Debug)]
pub struct EnvironmentNames {
    /// `--env` or `env`.
    pub env: &'static str,
    /// `--env-strength` or `env_strength`.
    pub strength: &'static str,
    /// `--env-rotation` or `env_rotation`.
    pub rotation: &'static str,
}

impl EnvironmentNames {
    /// The command line's flags.
    pub fn flags() -> EnvironmentNames {
        EnvironmentNames {
            env: OptionDef::of(OptionId::Env).flag,
            strength: OptionDef::of(OptionId::EnvStrength).flag,
            rotation: OptionDef::of(OptionId::EnvRotation).flag,
        }
    }

    /// Python's keywords.
    pub fn keywords() -> EnvironmentNames {
        EnvironmentNames {
            env: OptionDef::of(OptionId::Env).python,
            strength: OptionDef::of(OptionId::EnvStrength).python,
            rotation: OptionDef::of(OptionId::EnvRotation).python,
        }
    }
}

impl EnvironmentOptions {
    /// The environment values of `options` (a transparent background is a black one:
    /// premultiplied, a camera ray that leaves the scene adds nothing to the colour,
    /// and its pixel's alpha says how much of it was covered).
    pub fn from_options(options: &PartialOptions) -> EnvironmentOptions {
        EnvironmentOptions {
            env: options.env.as_ref().map(|e| e.value.clone()),
            strength: options.env_strength.as_ref().map(|s| s.value),
            rotation: options.env_rotation.as_ref().map(|r| r.value),
            background: options.background.as_ref().map(|b| match b.value {
                Background::Colour(colour) => colour,
                Background::Transparent => Vec3::ZERO,
            }),
        }
    }

    /// Whether no value is given.
    pub fn is_empty(&self) -> bool {
        self.env.is_none()
            && self.strength.is_none()
            && self.rotation.is_none()
            && self.background.is_none()
    }

    /// Sets the environment `env` names (a colour `R,G,B`, else a file) and applies
    /// the strength, rotation and background over the scene's; a strength or rotation
    /// with no environment to apply to is a warning in `description.warnings`.
    ///
    /// # Errors
    /// A negative or NaN strength, a colour that is not finite and 0 or more, a file
    /// that [`load_environment_map`] refuses; each message names the value as `names`
    /// spells it.
    pub fn apply(
        &self,
        description: &mut SceneDescription,
        names: EnvironmentNames,
    ) -> Result<(), String> {
        let strength = self.strength.unwrap_or(1.0);
        for (id, value, name) in [
            (OptionId::EnvStrength, self.strength, names.strength),
            (OptionId::EnvRotation, self.rotation, names.rotation),
        ] {
            if let Some(value) = value {
                OptionDef::of(id)
                    .range
                    .check(value.into())
                    .map_err(|e| format!("invalid {name}: {e}"))?;
            }
        }
        if let Some(env) = &self.env {
            let colour: Vec<Float> = env
                .split(',')
                .filter_map(|c| c.trim().parse().ok())
                .collect();
            description.environment = Some(match colour[..] {
                [r, g, b] if env.split(',').count() == 3 => {
                    let colour = Vec3::new(r, g, b);
                    if !colour.is_finite() || colour.min_element() < 0.0 {
                        return Err(format!(
                            "{} {env}: a colour's components must be finite and 0 or more",
                            names.env
                        ));
                    }
                    environment_colour(colour, strength)
                }
                _ => {
                    let (desc, warning) = load_environment_map(Path::new(env), strength, 0.0)
                        .map_err(|e| format!("{} {e}", names.env))?;
                    description.warnings.extend(warning);
                    desc
                }
            });
        }
        if let Some(environment) = &mut description.environment {
            if let Some(strength) = self.strength {
                environment.strength = strength;
            }
            if let Some(rotation) = self.rotation {
                environment.rotation_degrees = rotation;
            }
        } else if self.strength.is_some() || self.rotation.is_some() {
            description.warnings.push(format!(
                "{} and {} apply to an environment ({}, or a scene file's [environment]); the scene has none",
                names.strength, names.rotation, names.env
            ));
        }
        if let Some(background) = self.background {
            description.background = Some(background);
        }
        Ok(())
    }
}

/// The environment of the image file `path`, times `strength`, turned by
/// `rotation_degrees` about +Y; with a warning if some texels are NaN, infinite or
/// negative (they emit nothing).
///
/// # Errors
/// A file that cannot be read or is not an image (naming the file), an image over the
/// texture limits.
pub fn load_environment_map(
    path: &Path,
    strength: Float,
    rotation_degrees: Float,
) -> Result<(EnvironmentDesc, Option<String>), String> {
    let shown = path.display();
    if path.is_dir() {
        return Err(format!("{shown}: is a directory"));
    }
    let mut texture = crate::textures::load_texture(path).map_err(|e| format!("{shown}: {e}"))?;
    let mut warning = None;
    // A JPEG with an HDR gain map (Ultra HDR) at its full range, not its SDR image.
    if texture.is_8bit()
        && let Some(bytes) = read_at_most(path, crate::textures::MAX_TEXTURE_BYTES)
    {
        match super::gain_map::hdr_from_gain_map(&bytes, &texture, path) {
            Some(Ok(hdr)) => texture = Arc::new(hdr),
            Some(Err(e)) => warning = Some(format!("{shown}: {e}; read as its SDR image")),
            None => {}
        }
    }
    let warning = warning.or_else(|| {
        bad_texels(&texture).map(|count| {
            format!("{shown}: {count} texels are NaN, infinite or negative; they emit nothing")
        })
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

/// The bytes of the file at `path` if it holds at most `limit` of them: read again
/// for its gain map after the texture reader checked its size, so bounded again in
/// case the file changed in between.
fn read_at_most(path: &Path, limit: u64) -> Option<Vec<u8>> {
    use std::io::Read;
    let mut bytes = Vec::new();
    let file = std::fs::File::open(path).ok()?;
    file.take(limit + 1).read_to_end(&mut bytes).ok()?;
    (bytes.len() as u64 <= limit).then_some(bytes)
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
