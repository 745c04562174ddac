//! Post-processing: a linear [`Film`] to an 8-bit [`Image`] as each mode displays it
//! (SPEC's tone map and gamma in full mode, distance over the farthest in depth mode,
//! `n / 2 + 1/2` in normal mode, an exposure and a tone map ([`ToneMap`], in
//! [`tonemap`]) in path mode).
//! Encoding to a file is [`crate::output`]'s job.

mod gamma;
pub mod tonemap;

pub use tonemap::ToneMap;

use rayon::prelude::*;
use wide::f32x16;

use crate::film::{AovPlanes, Film};
use crate::math::{Float, Vec3};
use crate::options::{Mode, RenderOptions};

/// How a film is shown: its mode and, in path mode, the exposure and tone map.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PostProcessing {
    /// The mode the film was rendered in.
    pub mode: Mode,
    /// Path mode's exposure in stops ([`RenderOptions::exposure`]).
    pub exposure: Float,
    /// Path mode's tone map ([`RenderOptions::tonemap`]); other modes ignore it.
    pub tonemap: ToneMap,
    /// Full mode: the least white point `C` of SPEC's tone curve, whose `C` is the
    /// image's largest channel. 0 for SPEC's images; [`RIG_WHITE_POINT`] for a scene
    /// lit by the default light rig.
    pub least_white_point: Float,
}

/// The least white point of full mode's tone curve for a scene that the default light
/// rig lights ([`PostProcessing::least_white_point`]). SPEC's curve with `C = 1` is the
/// identity below 1: a dark model is shown as dark as it is. With `C` the image's
/// largest value, as SPEC's scenes with their own lights take it, a model of `Kd 0.05`
/// showed its brightest face white (path mode shows it dark grey).
pub const RIG_WHITE_POINT: Float = 1.0;

impl From<Mode> for PostProcessing {
    /// `mode` with no exposure change and the default tone map.
    fn from(mode: Mode) -> PostProcessing {
        PostProcessing {
            mode,
            exposure: 0.0,
            tonemap: ToneMap::default(),
            least_white_point: 0.0,
        }
    }
}

impl From<&RenderOptions> for PostProcessing {
    fn from(options: &RenderOptions) -> PostProcessing {
        PostProcessing {
            mode: options.mode,
            exposure: options.exposure,
            tonemap: options.tonemap,
            least_white_point: 0.0,
        }
    }
}

/// An 8-bit RGB image, row 0 at the top.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Image {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `3 * width * height` bytes, RGB, row by row.
    pub rgb: Vec<u8>,
}

impl Image {
    /// The fraction of the pixels whose every channel is below `threshold` (0 for an
    /// image without pixels): `render` warns when it is above
    /// [`NEARLY_BLACK_FRACTION`] with [`NEARLY_BLACK_THRESHOLD`].
    pub fn dark_fraction(&self, threshold: u8) -> f64 {
        let pixels = self.rgb.len() / 3;
        if pixels == 0 {
            return 0.0;
        }
        let dark = self
            .rgb
            .chunks_exact(3)
            .filter(|p| p.iter().all(|&c| c < threshold))
            .count();
        dark as f64 / pixels as f64
    }
}

/// The 8-bit value below which `render` counts a channel as black (about 0.1% of
/// white in linear light, after the sRGB curve).
pub const NEARLY_BLACK_THRESHOLD: u8 = 8;
/// The fraction of black pixels (see [`NEARLY_BLACK_THRESHOLD`]) above which `render`
/// warns that the image is nearly black.
pub const NEARLY_BLACK_FRACTION: f64 = 0.99;

impl Film {
    /// Post-processes the film for its mode (a [`Mode`], or [`PostProcessing`] with
    /// an exposure) into 8 bits per channel: depth divides by the largest distance
    /// (misses white), normal maps `n` to `n / 2 + 1/2` (misses black), full applies
    /// SPEC's tone mapping and gamma, path multiplies by `2^exposure` and applies its
    /// [`ToneMap`] (which ends in the sRGB curve).
    ///
    /// See also [`Film::write`], which also writes linear OpenEXR files.
    pub fn to_image(&self, post: impl Into<PostProcessing>) -> Image {
        // In parallel: the gamma curve's `powf` on every channel of a megapixel film
        // took 30-40 ms on one thread.
        const CHUNK: usize = 4096;
        let encoding = self.encoding(post.into());
        let mut rgb = vec![0u8; self.pixels.len() * 3];
        if let Encoding::Full { brightest } = encoding {
            // Channel by channel, sixteen at a time: the tone map's divisions in SIMD.
            let channels: &[Float] = bytemuck::cast_slice(&self.pixels);
            rgb.par_chunks_mut(3 * CHUNK)
                .zip(channels.par_chunks(3 * CHUNK))
                .for_each(|(bytes, values)| full_bytes(values, brightest, bytes));
        } else {
            rgb.par_chunks_mut(3 * CHUNK)
                .zip(self.pixels.par_chunks(CHUNK))
                .for_each(|(bytes, pixels)| {
                    for (rgb, &v) in bytes.chunks_exact_mut(3).zip(pixels) {
                        rgb.copy_from_slice(&encoding.apply(v).to_array().map(to_byte));
                    }
                });
        }
        Image {
            width: self.width,
            height: self.height,
            rgb,
        }
    }

    /// The post-processed value of every pixel, row by row, before quantization to
    /// 8 bits: what [`Film::to_image`] encodes.
    pub fn display_values(
        &self,
        post: impl Into<PostProcessing>,
    ) -> impl Iterator<Item = Vec3> + '_ {
        let encoding = self.encoding(post.into());
        self.pixels.iter().map(move |&v| encoding.apply(v))
    }

    /// How `mode` maps this film's values for display (which needs the film's
    /// largest value).
    fn encoding(&self, post: PostProcessing) -> Encoding {
        match post.mode {
            Mode::Depth => Encoding::Depth {
                farthest: self.max_channel(|v| v.x.is_finite()),
            },
            Mode::Normal => Encoding::Normal,
            Mode::Full => Encoding::Full {
                brightest: self.max_channel(|_| true).max(post.least_white_point),
            },
            Mode::Path => Encoding::Exposed {
                scale: post.exposure.exp2(),
                tonemap: post.tonemap,
            },
        }
    }

    /// The largest channel value over the pixels that `keep` accepts (0 if none).
    fn max_channel(&self, keep: impl Fn(Vec3) -> bool + Sync) -> Float {
        self.pixels
            .par_iter()
            .filter(|&&v| keep(v))
            .map(|v| v.max_element())
            .reduce(|| 0.0, Float::max)
    }
}

impl Film {
    /// The film divided by the coverage `alpha` (one value a pixel, in [0, 1]) where
    /// it is above 0: the colour of what the pixel's hits saw, for images that keep
    /// colour and alpha apart (PNG), from a film whose misses added nothing.
    pub fn unpremultiplied(&self, alpha: &[Float]) -> Film {
        let pixels = self
            .pixels
            .iter()
            .zip(alpha)
            .map(|(&v, &a)| if a > 0.0 { v / a } else { v })
            .collect();
        Film {
            width: self.width,
            height: self.height,
            pixels,
        }
    }
}

impl Image {
    /// This image over the colour `backdrop` (bytes as shown), by the coverage
    /// `alpha` (one value a pixel, in [0, 1]): `v a + backdrop (1 - a)`, rounded. After
    /// the tone map, so that the backdrop neither takes part in SPEC's brightest
    /// channel nor changes the model's pixels.
    pub fn over_backdrop(&mut self, alpha: &[Float], backdrop: [u8; 3]) {
        for (rgb, &a) in self.rgb.chunks_exact_mut(3).zip(alpha) {
            if a >= 1.0 {
                continue;
            }
            for (c, &b) in rgb.iter_mut().zip(&backdrop) {
                *c = to_byte((Float::from(*c) * a + Float::from(b) * (1.0 - a)) / 255.0);
            }
        }
    }
}

/// The grey behind a model that full mode lights with its default rig, where no
/// camera ray hit: path mode's studio backdrop
/// ([`crate::lights::environment::STUDIO_BACKDROP`]) as path mode's PNG shows it, so
/// that a black model stands out in both modes.
pub fn default_backdrop() -> [u8; 3] {
    let film = Film {
        width: 1,
        height: 1,
        pixels: vec![crate::lights::environment::STUDIO_BACKDROP],
    };
    let rgb = film.to_image(Mode::Path).rgb;
    [rgb[0], rgb[1], rgb[2]]
}

/// Coverage in [0, 1] as 8-bit alpha, rounded.
pub fn alpha_bytes(alpha: &[Float]) -> Vec<u8> {
    alpha.iter().map(|&a| to_byte(a)).collect()
}

/// Why a film could not be denoised.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum DenoiseError {
    /// This build has no denoiser.
    #[error(
        "this build has no denoiser: rebuild with `cargo build --release --features denoise`, with OIDN_DIR naming Intel Open Image Denoise (for example the `oidn` folder of PyPI's `pyoidn` wheel)"
    )]
    NotBuilt,
    /// Open Image Denoise failed.
    #[error("Open Image Denoise failed: {0}")]
    Failed(String),
}

/// Whether this build can denoise ([`Film::denoised`]), so that a caller can say so
/// before a long render.
///
/// # Errors
/// [`DenoiseError::NotBuilt`] in builds without the `denoise` feature.
pub fn check_denoiser() -> Result<(), DenoiseError> {
    if cfg!(feature = "denoise") {
        Ok(())
    } else {
        Err(DenoiseError::NotBuilt)
    }
}

/// The albedo and normal planes of `guides` that Open Image Denoise can take for a
/// film of `pixels` pixels, as flat `f32` triples: the albedo alone, or both (OIDN
/// takes a normal only with an albedo); none when no albedo was rendered.
pub fn denoise_guides(guides: &AovPlanes, pixels: usize) -> Option<(Vec<f32>, Option<Vec<f32>>)> {
    let flat = |plane: &Option<Vec<Vec3>>| {
        plane
            .as_ref()
            .filter(|values| values.len() == pixels)
            .map(|values| {
                values
                    .iter()
                    .flat_map(|v| v.to_array())
                    .collect::<Vec<f32>>()
            })
    };
    let albedo = flat(&guides.albedo)?;
    Some((albedo, flat(&guides.normal)))
}

impl Film {
    /// The film with Monte Carlo noise removed by Intel Open Image Denoise's
    /// ray-tracing filter (HDR, linear), for path mode, guided by the albedo and
    /// shading normal of `guides` when they were rendered (as OIDN recommends: edges
    /// and texture detail the noisy colour hides are kept; see [`denoise_guides`]).
    /// The guides are antialiased, so not flagged as noise-free (`cleanAux`).
    /// Available in builds with the `denoise` feature; others return
    /// [`DenoiseError::NotBuilt`].
    ///
    /// # Errors
    /// No denoiser in this build, or the library failed (no CPU device, say).
    pub fn denoised(&self, guides: &AovPlanes) -> Result<Film, DenoiseError> {
        #[cfg(feature = "denoise")]
        {
            let failed = |e: oidn::Error| DenoiseError::Failed(format!("{e:?}"));
            let device = oidn::Device::cpu().map_err(failed)?;
            let mut color: Vec<f32> = self.pixels.iter().flat_map(|v| v.to_array()).collect();
            let mut filter = oidn::RayTracing::try_new(&device).map_err(failed)?;
            filter
                .srgb(false)
                .hdr(true)
                .image_dimensions(self.width as usize, self.height as usize);
            let guides = denoise_guides(guides, self.pixels.len());
            match &guides {
                Some((albedo, Some(normal))) => {
                    filter.albedo_normal(albedo, normal);
                }
                Some((albedo, None)) => {
                    filter.albedo(albedo);
                }
                None => {}
            }
            filter.filter_in_place(&mut color).map_err(failed)?;
            device.get_error().map_err(failed)?;
            Ok(Film {
                width: self.width,
                height: self.height,
                pixels: color
                    .chunks_exact(3)
                    .map(|c| Vec3::new(c[0], c[1], c[2]))
                    .collect(),
            })
        }
        #[cfg(not(feature = "denoise"))]
        {
            let _ = guides;
            Err(DenoiseError::NotBuilt)
        }
    }
}

/// Post-processing of one mode, with the image-wide maximum it needs.
#[derive(Clone, Copy)]
enum Encoding {
    /// Distance over the farthest hit; misses white.
    Depth { farthest: Float },
    /// `n / 2 + 1/2`; misses (zero normal) black.
    Normal,
    /// Tone mapping by the brightest channel, then gamma 2.2.
    Full { brightest: Float },
    /// Radiance times `scale`, through a tone map that ends in the sRGB curve: one
    /// bright sample cannot darken the rest of the image, as a maximum-based map
    /// would.
    Exposed { scale: Float, tonemap: ToneMap },
}

/// Full mode's bytes of the channel values `values` into `bytes`: bit for bit
/// [`tone_map`], then `powf(1 / 2.2)` and [`to_byte`] (by table: [`gamma::gamma_byte`]),
/// the tone map sixteen channels at a time (each lane the scalar operations).
fn full_bytes(values: &[Float], brightest: Float, bytes: &mut [u8]) {
    const LANES: usize = 16;
    let mut values_chunks = values.chunks_exact(LANES);
    let mut bytes_chunks = bytes.chunks_exact_mut(LANES);
    if brightest > 0.0 {
        let c = f32x16::splat(brightest);
        for (values, bytes) in (&mut values_chunks).zip(&mut bytes_chunks) {
            let v = f32x16::from(<[Float; LANES]>::try_from(values).expect("16 lanes"));
            // `max` as `f32::max`: NaN becomes 0 (the SIMD max returns its second
            // operand when the first is NaN). A -0 passes; the curve maps it to +0.
            let v = v.fast_max(f32x16::ZERO);
            let r = v / c;
            let mapped = (v + r * r) / (f32x16::ONE + v);
            for (byte, &m) in bytes.iter_mut().zip(mapped.as_array()) {
                *byte = gamma::gamma_byte(m);
            }
        }
    }
    let done = if brightest > 0.0 {
        values.len() - values_chunks.remainder().len()
    } else {
        0
    };
    for (byte, &v) in bytes[done..].iter_mut().zip(&values[done..]) {
        *byte = gamma::gamma_byte(tone_map_channel(v, brightest));
    }
}

impl Encoding {
    #[inline]
    fn apply(self, v: Vec3) -> Vec3 {
        match self {
            Encoding::Depth { farthest } => {
                if !v.x.is_finite() {
                    Vec3::ONE
                } else if farthest > 0.0 {
                    v / farthest
                } else {
                    Vec3::ZERO
                }
            }
            Encoding::Normal => {
                if v == Vec3::ZERO {
                    Vec3::ZERO
                } else {
                    v * 0.5 + Vec3::splat(0.5)
                }
            }
            Encoding::Full { brightest } => tone_map(v, brightest).powf(1.0 / 2.2),
            Encoding::Exposed { scale, tonemap } => tonemap.apply(v * scale),
        }
    }
}

/// SPEC's tone curve `v (1 + v / c^2) / (1 + v)` with `c` the image's largest
/// channel; an all-black image (`c = 0`) stays black.
///
/// Written as `(v + (v/c)^2) / (1 + v)`: with `0 <= v <= c` every term stays in
/// range, where `c * c` would overflow for large `c` or vanish for tiny ones.
/// Negative values (negative colours or lights in the scene) are black.
#[inline]
fn tone_map(v: Vec3, c: Float) -> Vec3 {
    v.to_array().map(|v| tone_map_channel(v, c)).into()
}

/// [`tone_map`] of one channel.
#[inline]
fn tone_map_channel(v: Float, c: Float) -> Float {
    if c <= 0.0 {
        return 0.0;
    }
    let v = v.max(0.0);
    let r = v / c;
    (v + r * r) / (1.0 + v)
}

/// The sRGB transfer curve (IEC 61966-2-1) of a linear value in `[0, 1]`; NaN is 0.
#[inline]
fn srgb(v: Float) -> Float {
    if v.is_nan() {
        0.0
    } else if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

/// Scales 0..1 to 0..255, rounding to nearest; out-of-range values clamp.
#[inline]
fn to_byte(v: Float) -> u8 {
    (v * 255.0).round().clamp(0.0, 255.0) as u8
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tone_map_keeps_the_brightest_channel_and_black() {
        let c = 4.0;
        assert!((tone_map(Vec3::splat(c), c).x - 1.0).abs() < 1e-6);
        assert_eq!(tone_map(Vec3::ZERO, c), Vec3::ZERO);
        assert_eq!(tone_map(Vec3::ZERO, 0.0), Vec3::ZERO);
    }

    /// Full mode's bytes (SIMD tone map, table gamma) are those of the scalar
    /// definition, `to_byte(tone_map(v)^(1/2.2))`, on films of odd sizes (a tail
    /// past the sixteen-lane chunks) with zeros, negatives, tiny and huge values, and
    /// on an all-black film.
    #[test]
    fn full_mode_bytes_are_the_scalar_definition() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand::rngs::StdRng::seed_from_u64(22);
        for (width, height, scale) in [(37, 29, 3.0), (64, 64, 1e-3), (5, 3, 0.0), (1, 1, 7.0)] {
            let pixels = (0..width * height)
                .map(|_| {
                    let mut channel = || match rng.random_range(0..10) {
                        0 => 0.0,
                        1 => -rng.random_range(0.0..1.0),
                        2 => rng.random_range(0.0..1e-6),
                        3 => rng.random_range(0.0..100.0) * scale,
                        _ => rng.random_range(0.0..1.0) * scale,
                    };
                    Vec3::new(channel(), channel(), channel())
                })
                .collect();
            let film = Film {
                width,
                height,
                pixels,
            };
            let expected: Vec<u8> = film
                .display_values(Mode::Full)
                .flat_map(|v| v.to_array().map(to_byte))
                .collect();
            assert_eq!(film.to_image(Mode::Full).rgb, expected, "{width}x{height}");
        }
        let black = Film {
            width: 9,
            height: 3,
            pixels: vec![Vec3::new(0.0, -1.0, -0.0); 27],
        };
        assert_eq!(black.to_image(Mode::Full).rgb, vec![0; 81]);
    }

    #[test]
    fn path_mode_applies_the_exposure_then_the_srgb_curve_clamped() {
        let film = Film {
            width: 4,
            height: 1,
            pixels: vec![
                Vec3::splat(0.25),
                Vec3::new(0.001, 0.0, -1.0),
                Vec3::splat(100.0),
                Vec3::splat(Float::NAN),
            ],
        };
        let exposed = |stops| {
            film.to_image(PostProcessing {
                mode: Mode::Path,
                exposure: stops,
                tonemap: ToneMap::Standard,
                least_white_point: 0.0,
            })
            .rgb
        };
        // 0.25 * 2 = 0.5 -> sRGB 0.7354 -> 188; the linear segment below 0.0031308;
        // clamped above 1 and below 0; NaN black. One bright pixel changes nothing else.
        assert_eq!(
            exposed(1.0),
            [188, 188, 188, 7, 0, 0, 255, 255, 255, 0, 0, 0]
        );
        assert_eq!(&exposed(0.0)[..3], [137, 137, 137]);
        let standard = PostProcessing {
            tonemap: ToneMap::Standard,
            ..PostProcessing::from(Mode::Path)
        };
        assert_eq!(film.to_image(standard).rgb, exposed(0.0));
    }

    /// Full mode keeps SPEC's tone map whatever tone map is asked for; path mode's
    /// operators each give their own bytes.
    #[test]
    fn the_tone_map_is_path_modes_alone() {
        let film = Film {
            width: 3,
            height: 1,
            pixels: vec![Vec3::splat(0.3), Vec3::new(4.0, 1.0, 0.2), Vec3::splat(0.9)],
        };
        let with = |mode, tonemap| {
            film.to_image(PostProcessing {
                mode,
                exposure: 0.0,
                tonemap,
                least_white_point: 0.0,
            })
            .rgb
        };
        let mut path = Vec::new();
        for (_, tonemap) in ToneMap::NAMES {
            assert_eq!(with(Mode::Full, tonemap), film.to_image(Mode::Full).rgb);
            path.push(with(Mode::Path, tonemap));
        }
        path.dedup();
        assert_eq!(path.len(), ToneMap::NAMES.len());
    }

    #[test]
    fn depth_normalizes_by_farthest_hit_and_misses_are_white() {
        let film = Film {
            width: 3,
            height: 1,
            pixels: vec![
                Vec3::splat(2.0),
                Vec3::splat(4.0),
                Vec3::splat(Float::INFINITY),
            ],
        };
        let image = film.to_image(Mode::Depth);
        assert_eq!(image.rgb, vec![128, 128, 128, 255, 255, 255, 255, 255, 255]);
    }
}
