//! Image textures: decoded texels ([`Texture`]), how a material uses one
//! ([`TextureMap`]: which file, with which MTL options), and filtered lookups.
//!
//! Where textures live: the file readers ([`crate::formats`]) load the images a
//! material names, through [`load_texture`], which decodes each file once and shares
//! it (an [`Arc`]) with every material and every scene that names it; the
//! [`crate::Material`] holds the maps; the scene interpolates texture coordinates at a
//! hit; the integrators sample the maps through [`crate::Material::at`].
//!
//! Conventions (those of Blender and tinyobjloader): `u` to the right, `v` up; texel
//! `x = u * W - 0.5`, `y = (1 - v) * H - 0.5`, row 0 being the top row of the image
//! file; bilinear filtering between texel centres; repeat addressing unless the map
//! says to clamp. 8-bit colour maps are sRGB-encoded: every texel is decoded to linear
//! before filtering. Alpha channels and scalar maps are linear.

use std::collections::HashMap;
use std::fmt;
use std::io::Cursor;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, PoisonError, Weak};
use std::time::SystemTime;

use crate::math::{Float, Vec2, Vec3};

/// Largest width or height of a texture, in texels: larger images are refused with a
/// warning rather than decoded (a corrupt header may claim billions).
pub const MAX_TEXTURE_SIZE: u32 = 32_768;

/// Most bytes decoding one texture may allocate, and most bytes its file and its
/// texels (after conversion to `f32`, for deep images) may each take: an 8192 x 8192
/// RGBA image fits. With the file, the decoded image and the converted texels alive
/// at once, loading one texture stays under 768 MiB whatever its header claims.
pub const MAX_TEXTURE_BYTES: u64 = 256 << 20;

/// The texels of a decoded image.
#[derive(Clone)]
enum Texels {
    /// 8 bits per channel, as stored in the file.
    U8(Vec<u8>),
    /// Deeper images (16-bit, floating point), scaled to 0..1 for integer formats.
    F32(Vec<f32>),
}

/// A decoded image: 1 (grey), 2 (grey, alpha), 3 (RGB) or 4 (RGBA) channels, row 0
/// at the top.
#[derive(Clone)]
pub struct Texture {
    /// The file it was read from, for messages.
    pub path: PathBuf,
    width: u32,
    height: u32,
    channels: u32,
    texels: Texels,
}

impl fmt::Debug for Texture {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        // Not the texels: a material's debug output must stay readable.
        write!(
            f,
            "Texture({}, {}x{}, {} channels)",
            self.path.display(),
            self.width,
            self.height,
            self.channels
        )
    }
}

/// How texel values are turned into linear values.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Encoding {
    /// Colour channels are sRGB-encoded (colour maps); alpha stays linear.
    Srgb,
    /// Every channel is linear (alpha, shininess, bump and normal maps).
    Linear,
}

/// What to do with texture coordinates outside `[0, 1]`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Wrap {
    /// Tile the image (MTL's default, glTF's `REPEAT`).
    #[default]
    Repeat,
    /// Extend the edge texels (MTL's `-clamp on`, glTF's `CLAMP_TO_EDGE`).
    Clamp,
    /// Tile, every other copy mirrored (glTF's `MIRRORED_REPEAT`).
    Mirror,
}

/// The channel a scalar map (`map_d`, `map_Ns`, `bump`) reads: MTL's `-imfchan`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Channel {
    /// The map's own default: alpha if the image has one and the map is `map_d`,
    /// else luminance.
    #[default]
    Auto,
    /// `-imfchan r`.
    Red,
    /// `-imfchan g`.
    Green,
    /// `-imfchan b`.
    Blue,
    /// `-imfchan m`: the matte (alpha) channel, 1 where the image has none.
    Alpha,
    /// `-imfchan l` (and `z`): Rec. 709 luminance of the linear channels.
    Luminance,
}

/// The options of an MTL map statement. Those the renderer applies are fields; the
/// others (`-t`, `-blendu`, `-blendv`, `-boost`, `-texres`, `-type`, `-cc`) are parsed,
/// so that they never end up in the file name, and ignored.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TextureOptions {
    /// `-o u v w`: added to the texture coordinates (after `scale`).
    pub offset: Vec2,
    /// `-s u v w`: multiplies the texture coordinates.
    pub scale: Vec2,
    /// Cosine and sine of an angle by which the scaled coordinates turn
    /// counter-clockwise (in `u` right, `v` up) before `offset` is added: glTF's
    /// `KHR_texture_transform`; MTL has none (angle 0: `(1, 0)`).
    pub rotation: Vec2,
    /// `-clamp on` (and glTF's samplers).
    pub wrap_u: Wrap,
    /// As `wrap_u`, for `v`.
    pub wrap_v: Wrap,
    /// `-mm base gain`: values become `base + gain * value`.
    pub base: Float,
    /// See `base`.
    pub gain: Float,
    /// `-imfchan`.
    pub channel: Channel,
    /// `-bm`: the bump multiplier.
    pub bump_multiplier: Float,
}

impl Default for TextureOptions {
    fn default() -> Self {
        TextureOptions {
            offset: Vec2::ZERO,
            scale: Vec2::ONE,
            rotation: Vec2::X,
            wrap_u: Wrap::Repeat,
            wrap_v: Wrap::Repeat,
            base: 0.0,
            gain: 1.0,
            channel: Channel::Auto,
            bump_multiplier: 1.0,
        }
    }
}

impl TextureOptions {
    /// Where the map reads the image for texture coordinates `uv`: scaled, turned,
    /// then offset. Without a rotation exactly `uv * scale + offset` (for finite `uv`).
    #[inline]
    pub fn transform(&self, uv: Vec2) -> Vec2 {
        let s = uv * self.scale;
        let Vec2 { x: c, y: sin } = self.rotation;
        Vec2::new(c * s.x - sin * s.y, sin * s.x + c * s.y) + self.offset
    }

    /// A direction given in the image's own coordinates (`x` along its width, `y` up
    /// its height: a normal map's red and green, an anisotropy map's direction) in
    /// those of the texture coordinates before the transform, which the surface's
    /// tangent frame follows: turned back by the rotation, and flipped along an axis
    /// that a negative scale mirrors. (The transpose of the transform's linear part,
    /// its scale reduced to signs: how a slope in the image becomes one in the
    /// texture coordinates, with the length that a scale would add left out, as
    /// model viewers leave it; a turn alone is exact for directions and slopes
    /// alike.) Without a rotation or a negative scale, `d` itself.
    #[inline]
    pub fn image_to_surface(&self, d: Vec2) -> Vec2 {
        let Vec2 { x: c, y: sin } = self.rotation;
        let turned_back = Vec2::new(c * d.x + sin * d.y, -sin * d.x + c * d.y);
        turned_back * self.scale.signum()
    }
}

/// A texture as a material uses it: the image and the options.
#[derive(Clone, Debug)]
pub struct TextureMap {
    /// The image, shared by every map that names the same file.
    pub texture: Arc<Texture>,
    /// How it is applied.
    pub options: TextureOptions,
}

impl PartialEq for TextureMap {
    /// The same image (not merely equal texels) with the same options.
    fn eq(&self, other: &TextureMap) -> bool {
        Arc::ptr_eq(&self.texture, &other.texture) && self.options == other.options
    }
}

impl TextureMap {
    /// A map of `texture` with default options.
    pub fn new(texture: Arc<Texture>) -> TextureMap {
        TextureMap {
            texture,
            options: TextureOptions::default(),
        }
    }

    /// The filtered linear RGB at `uv`, after `-s`, the rotation, `-o` and `-mm`.
    #[inline]
    pub fn colour(&self, uv: Vec2, encoding: Encoding) -> Vec3 {
        let o = &self.options;
        let [r, g, b, _] = self
            .texture
            .bilinear(o.transform(uv), o.wrap_u, o.wrap_v, encoding);
        Vec3::new(r, g, b) * o.gain + Vec3::splat(o.base)
    }

    /// The mean linear RGB of the map's image after `-mm` (not weighted by how much
    /// of the image any surface shows): what light sampling weighs emitters by.
    pub fn mean_colour(&self, encoding: Encoding) -> Vec3 {
        let o = &self.options;
        self.texture.mean_colour(encoding) * o.gain + Vec3::splat(o.base)
    }

    /// The filtered linear value of the map's channel at `uv`, after `-s`, `-o` and
    /// `-mm`; `alpha_by_default` says whether [`Channel::Auto`] means alpha (for
    /// `map_d`) when the image has an alpha channel.
    #[inline]
    pub fn scalar(&self, uv: Vec2, alpha_by_default: bool) -> Float {
        let o = &self.options;
        let [r, g, b, a] =
            self.texture
                .bilinear(o.transform(uv), o.wrap_u, o.wrap_v, Encoding::Linear);
        let luminance = || 0.2126 * r + 0.7152 * g + 0.0722 * b;
        let value = match o.channel {
            Channel::Auto if alpha_by_default && self.texture.has_alpha() => a,
            Channel::Auto | Channel::Luminance => luminance(),
            Channel::Red => r,
            Channel::Green => g,
            Channel::Blue => b,
            Channel::Alpha => a,
        };
        o.base + o.gain * value
    }
}

impl Texture {
    /// A texture of `width` x `height` texels of `channels` 8-bit channels each, row 0
    /// at the top; `None` if the sizes do not match `texels` or are zero.
    pub fn from_u8(
        path: PathBuf,
        width: u32,
        height: u32,
        channels: u32,
        texels: Vec<u8>,
    ) -> Option<Texture> {
        let expected = (width as usize)
            .checked_mul(height as usize)?
            .checked_mul(channels as usize)?;
        (width > 0 && height > 0 && (1..=4).contains(&channels) && texels.len() == expected)
            .then_some(Texture {
                path,
                width,
                height,
                channels,
                texels: Texels::U8(texels),
            })
    }

    /// A texture of `width` x `height` texels of `channels` floating-point channels
    /// each (colour channels stored as they would be decoded from a file: sRGB for
    /// colour maps), row 0 at the top; `None` if the sizes do not match `texels`, are
    /// zero or exceed [`MAX_TEXTURE_SIZE`].
    pub fn from_f32(
        path: PathBuf,
        width: u32,
        height: u32,
        channels: u32,
        texels: Vec<f32>,
    ) -> Option<Texture> {
        let expected = (width as usize)
            .checked_mul(height as usize)?
            .checked_mul(channels as usize)?;
        let fits = width.max(height) <= MAX_TEXTURE_SIZE;
        (fits && width > 0 && height > 0 && (1..=4).contains(&channels) && texels.len() == expected)
            .then_some(Texture {
                path,
                width,
                height,
                channels,
                texels: Texels::F32(texels),
            })
    }

    /// Width and height in texels.
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// How many channels the image has: 1 (grey), 2 (grey, alpha), 3 (RGB) or 4
    /// (RGBA).
    pub fn channels(&self) -> u32 {
        self.channels
    }

    /// Whether the image has an alpha channel.
    pub fn has_alpha(&self) -> bool {
        self.channels == 2 || self.channels == 4
    }

    /// Whether the image looks like a tangent-space normal map rather than a height
    /// map: colour, with red and green near one half and blue high on average (the
    /// pale blue of normal maps), over a grid of at most 64 x 64 texels. Exporters
    /// write normal maps as `bump` as often as height maps.
    pub fn looks_like_normal_map(&self) -> bool {
        if self.channels < 3 {
            return false;
        }
        let (step_x, step_y) = ((self.width / 64).max(1), (self.height / 64).max(1));
        let mut sum = [0.0f64; 3];
        let mut count = 0.0;
        for y in (0..self.height).step_by(step_y as usize) {
            for x in (0..self.width).step_by(step_x as usize) {
                let texel = self.texel(x as usize, y as usize, Encoding::Linear);
                for (s, t) in sum.iter_mut().zip(texel) {
                    *s += f64::from(t);
                }
                count += 1.0;
            }
        }
        let [r, g, b] = sum.map(|s| s / count);
        (0.35..0.65).contains(&r) && (0.35..0.65).contains(&g) && b > 0.7
    }

    /// The mean linear RGB of the image, over a grid of at most 256 x 256 texels
    /// (every texel of smaller images).
    pub fn mean_colour(&self, encoding: Encoding) -> Vec3 {
        let (step_x, step_y) = (
            self.width.div_ceil(256).max(1),
            self.height.div_ceil(256).max(1),
        );
        let mut sum = [0.0f64; 3];
        let mut count = 0.0;
        for y in (0..self.height).step_by(step_y as usize) {
            for x in (0..self.width).step_by(step_x as usize) {
                let texel = self.texel(x as usize, y as usize, encoding);
                for (s, t) in sum.iter_mut().zip(texel) {
                    *s += f64::from(t);
                }
                count += 1.0;
            }
        }
        let [r, g, b] = sum.map(|s| (s / count) as Float);
        Vec3::new(r, g, b)
    }

    /// Bytes the texels take.
    pub fn memory(&self) -> usize {
        match &self.texels {
            Texels::U8(t) => t.len(),
            Texels::F32(t) => 4 * t.len(),
        }
    }

    /// Decodes an image file's bytes; `path` names it in messages and is kept.
    ///
    /// # Errors
    /// An unknown or unsupported format, a malformed file, or an image larger than
    /// [`MAX_TEXTURE_SIZE`] on a side.
    pub fn decode(bytes: &[u8], path: &Path) -> Result<Texture, String> {
        if bytes.starts_with(&KTX2_IDENTIFIER) {
            return decode_ktx2(bytes, path);
        }
        let mut reader = image::ImageReader::new(Cursor::new(bytes))
            .with_guessed_format()
            .map_err(|e| e.to_string())?;
        if reader.format().is_none() {
            return Err("not an image format the renderer reads (PNG, JPEG, WebP, TGA, BMP, GIF, DDS, Radiance HDR, OpenEXR, KTX2 of Basis Universal)".into());
        }
        let mut limits = image::Limits::default();
        limits.max_image_width = Some(MAX_TEXTURE_SIZE);
        limits.max_image_height = Some(MAX_TEXTURE_SIZE);
        limits.max_alloc = Some(MAX_TEXTURE_BYTES);
        reader.limits(limits);
        let image = reader.decode().map_err(|e| match e {
            // Say what the header claims: a corrupt or hostile one, most likely.
            image::ImageError::Limits(_) => match image::ImageReader::new(Cursor::new(bytes))
                .with_guessed_format()
                .ok()
                .and_then(|r| r.into_dimensions().ok())
            {
                Some((w, h)) => format!(
                    "its header claims {w}x{h} texels, more than a texture may have (at most {MAX_TEXTURE_SIZE} on a side and {} MiB decoded)",
                    MAX_TEXTURE_BYTES >> 20
                ),
                None => e.to_string(),
            },
            _ => e.to_string(),
        })?;
        let (width, height) = (image.width(), image.height());
        if width == 0 || height == 0 {
            return Err("the image is empty".into());
        }
        use image::DynamicImage as D;
        let (channels, texels) = match image {
            D::ImageLuma8(i) => (1, Texels::U8(i.into_raw())),
            D::ImageLumaA8(i) => (2, Texels::U8(i.into_raw())),
            D::ImageRgb8(i) => (3, Texels::U8(i.into_raw())),
            D::ImageRgba8(i) => (4, Texels::U8(i.into_raw())),
            other => {
                let channels = u32::from(other.color().channel_count());
                let bytes =
                    u64::from(width) * u64::from(height) * u64::from(channels.clamp(1, 4)) * 4;
                if bytes > MAX_TEXTURE_BYTES {
                    return Err(format!(
                        "{width}x{height} texels of {channels} channels take {} MiB as floats, more than the {} MiB a texture may",
                        bytes >> 20,
                        MAX_TEXTURE_BYTES >> 20
                    ));
                }
                let texels = match channels {
                    1 | 2 => {
                        let grey = other.to_luma_alpha32f();
                        let raw = grey.into_raw();
                        if channels == 1 {
                            raw.chunks_exact(2).map(|p| p[0]).collect()
                        } else {
                            raw
                        }
                    }
                    3 => other.to_rgb32f().into_raw(),
                    _ => other.to_rgba32f().into_raw(),
                };
                (channels.clamp(1, 4), Texels::F32(texels))
            }
        };
        Ok(Texture {
            path: path.to_path_buf(),
            width,
            height,
            channels,
            texels,
        })
    }

    /// Whether the texels are 8-bit (colours stored sRGB-encoded by convention),
    /// not floating point.
    pub fn is_8bit(&self) -> bool {
        matches!(self.texels, Texels::U8(_))
    }

    /// Texel `(x, y)` (in range, row 0 at the top) as linear RGBA: what
    /// [`Texture::bilinear`] filters.
    #[inline(always)]
    pub fn texel(&self, x: usize, y: usize, encoding: Encoding) -> [Float; 4] {
        let channels = self.channels as usize;
        let at = (y * self.width as usize + x) * channels;
        let colour = |value: Float| match encoding {
            Encoding::Srgb => srgb_to_linear(value),
            Encoding::Linear => value,
        };
        match &self.texels {
            Texels::U8(t) => {
                let c = |i: usize| -> Float {
                    let byte = t[at + i];
                    match encoding {
                        Encoding::Srgb => SRGB_TO_LINEAR[byte as usize],
                        Encoding::Linear => Float::from(byte) / 255.0,
                    }
                };
                let a = |i: usize| Float::from(t[at + i]) / 255.0;
                match channels {
                    1 => {
                        let l = c(0);
                        [l, l, l, 1.0]
                    }
                    2 => {
                        let l = c(0);
                        [l, l, l, a(1)]
                    }
                    3 => [c(0), c(1), c(2), 1.0],
                    _ => [c(0), c(1), c(2), a(3)],
                }
            }
            Texels::F32(t) => {
                let c = |i: usize| colour(t[at + i]);
                match channels {
                    1 => {
                        let l = c(0);
                        [l, l, l, 1.0]
                    }
                    2 => {
                        let l = c(0);
                        [l, l, l, t[at + 1]]
                    }
                    3 => [c(0), c(1), c(2), 1.0],
                    _ => [c(0), c(1), c(2), t[at + 3]],
                }
            }
        }
    }

    /// Bilinear lookup at `uv` (`v` up), each texel decoded to linear first.
    #[inline]
    pub fn bilinear(&self, uv: Vec2, wrap_u: Wrap, wrap_v: Wrap, encoding: Encoding) -> [Float; 4] {
        let x = uv.x * self.width as Float - 0.5;
        let y = (1.0 - uv.y) * self.height as Float - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        // Non-finite coordinates (a degenerate UV layout) give fx = NaN: read texel 0
        // and weigh it whole rather than spread NaN into the image.
        let (fx, fy) = (
            if fx.is_finite() { fx } else { 0.0 },
            if fy.is_finite() { fy } else { 0.0 },
        );
        let (x0, y0) = (x0 as i64, y0 as i64);
        let xs = [
            address(x0, self.width, wrap_u),
            address(x0.saturating_add(1), self.width, wrap_u),
        ];
        let ys = [
            address(y0, self.height, wrap_v),
            address(y0.saturating_add(1), self.height, wrap_v),
        ];
        let t00 = self.texel(xs[0], ys[0], encoding);
        let t10 = self.texel(xs[1], ys[0], encoding);
        let t01 = self.texel(xs[0], ys[1], encoding);
        let t11 = self.texel(xs[1], ys[1], encoding);
        let mut out = [0.0; 4];
        for i in 0..4 {
            let top = t00[i] + (t10[i] - t00[i]) * fx;
            let bottom = t01[i] + (t11[i] - t01[i]) * fx;
            out[i] = top + (bottom - top) * fy;
        }
        out
    }
}

/// The first twelve bytes of every KTX2 file.
const KTX2_IDENTIFIER: [u8; 12] = [
    0xAB, b'K', b'T', b'X', b' ', b'2', b'0', 0xBB, b'\r', b'\n', 0x1A, b'\n',
];

/// A KTX2 file of Basis Universal texels (glTF's `KHR_texture_basisu`: ETC1S or
/// UASTC, optionally zstd-supercompressed), its base level transcoded to 8-bit RGBA
/// (stored as the file's values, as a PNG's are: a colour map's sRGB is decoded at
/// lookup), under the texture limits; the transcoder runs under
/// [`crate::foreign::catch_quietly`], so that corrupt data is an error, never a panic.
fn decode_ktx2(bytes: &[u8], path: &Path) -> Result<Texture, String> {
    use basisu::{DecodeFlags, Error, TargetFormat, Transcoder};
    let describe = |error: Error| match error {
        Error::InvalidData | Error::Truncated => {
            "a KTX2 file that is not Basis Universal (ETC1S or UASTC) or is corrupt".to_string()
        }
        Error::Unsupported { source, .. } => {
            format!("a KTX2 file of {source:?} texels, which this renderer does not read (HDR)")
        }
        other => format!("a KTX2 file that cannot be transcoded ({other:?})"),
    };
    check_ktx2_header(bytes)?;
    let transcoded = crate::foreign::catch_quietly(|| -> Result<(u32, u32, Vec<u8>), String> {
        let texture = Transcoder::new(bytes).map_err(describe)?;
        let (width, height) = texture.base_dimensions();
        if width == 0 || height == 0 {
            return Err("the image is empty".into());
        }
        let decoded = u64::from(width) * u64::from(height) * 4;
        if width.max(height) > MAX_TEXTURE_SIZE || decoded > MAX_TEXTURE_BYTES {
            return Err(format!(
                "its header claims {width}x{height} texels, more than a texture may have (at most {MAX_TEXTURE_SIZE} on a side and {} MiB decoded)",
                MAX_TEXTURE_BYTES >> 20
            ));
        }
        let rgba = (texture.transcode(0, TargetFormat::Rgba32, DecodeFlags::NONE))
            .map_err(describe)?;
        Ok((width, height, rgba))
    })
    .ok_or("a corrupt KTX2 file (the Basis Universal transcoder failed)")??;
    let (width, height, rgba) = transcoded;
    Texture::from_u8(path.to_path_buf(), width, height, 4, rgba)
        .ok_or_else(|| "a KTX2 file whose texels do not fill its size".to_string())
}

/// Refuses a KTX2 file whose key/value data runs past its end, or whose base level
/// claims to inflate to more bytes than its texels can take (4x4 blocks of 16
/// bytes, times its layers, faces and depth) or a texture may: the transcoder
/// allocates what the level index claims before inflating (a fuzzed file asked for
/// 9 PB). A file too short for its header is left to the transcoder to refuse.
fn check_ktx2_header(bytes: &[u8]) -> Result<(), String> {
    let word = |at: usize| -> Option<u64> {
        let b = bytes.get(at..at + 4)?;
        Some(u64::from(u32::from_le_bytes([b[0], b[1], b[2], b[3]])))
    };
    let long = |at: usize| -> Option<u64> { Some(word(at)? | word(at + 4)? << 32) };
    let (Some(width), Some(height), Some(depth), Some(layers), Some(faces), Some(claimed)) = (
        word(20),
        word(24),
        word(28),
        word(32),
        word(36),
        long(80 + 16),
    ) else {
        return Ok(());
    };
    // The transcoder walks the key/value data without checking that an entry's
    // padding stays inside it (it then reads past the file and panics): refused
    // here, where the walk is the same.
    if let (Some(offset), Some(length)) = (word(56), word(60))
        && length > 0
    {
        let (start, end) = (offset, offset.saturating_add(length));
        let mut at = start;
        while end <= bytes.len() as u64 && end.saturating_sub(at) > 4 {
            let Some(entry) = word(at as usize) else {
                break;
            };
            at += 4;
            if entry < 2 || end - at < entry {
                break;
            }
            at += entry;
            at += (4 - (at & 3)) & 3;
            if at > end {
                return Err("a KTX2 file whose key/value data runs past its end".into());
            }
        }
    }
    let blocks = u128::from(width.div_ceil(4)) * u128::from(height.div_ceil(4));
    let images = u128::from(depth.max(1)) * u128::from(layers.max(1)) * u128::from(faces.max(1));
    let most = (blocks * 16 * images).min(u128::from(MAX_TEXTURE_BYTES));
    if u128::from(claimed) > most {
        return Err(format!(
            "a KTX2 file whose base level claims {claimed} bytes, more than its {width}x{height} texels take or a texture may"
        ));
    }
    Ok(())
}

/// Texel index `i` brought into `0..size` by the wrap mode.
#[inline(always)]
fn address(i: i64, size: u32, wrap: Wrap) -> usize {
    let n = i64::from(size);
    (match wrap {
        Wrap::Repeat => i.rem_euclid(n),
        Wrap::Clamp => i.clamp(0, n - 1),
        Wrap::Mirror => {
            let m = i.rem_euclid(2 * n);
            if m < n { m } else { 2 * n - 1 - m }
        }
    }) as usize
}

/// The sRGB transfer function's inverse, for values in 0..1.
#[inline]
pub fn srgb_to_linear(value: Float) -> Float {
    if value <= 0.04045 {
        value / 12.92
    } else {
        ((value + 0.055) / 1.055).powf(2.4)
    }
}

/// The sRGB transfer function, the inverse of [`srgb_to_linear`] (also beyond 0..1:
/// both extend the linear segment below 0 and the power curve above 1).
#[inline]
pub fn linear_to_srgb(value: Float) -> Float {
    if value <= 0.003_130_8 {
        value * 12.92
    } else {
        1.055 * value.powf(1.0 / 2.4) - 0.055
    }
}

/// [`srgb_to_linear`] of `i / 255`, rounded to `f32`: one lookup per 8-bit texel.
/// (Written out rather than computed at start-up, so that the lookup needs no lazy
/// initialisation on the per-ray path; a test checks it against the formula.)
#[rustfmt::skip]
static SRGB_TO_LINEAR: [f32; 256] = [
    0.0e+00, 3.03527e-04, 6.07054e-04, 9.10581e-04, 1.214108e-03, 1.517635e-03, 1.821162e-03, 2.1246888e-03,
    2.428216e-03, 2.7317428e-03, 3.03527e-03, 3.3465358e-03, 3.6765074e-03, 4.024717e-03, 4.391442e-03, 4.7769533e-03,
    5.1815165e-03, 5.6053917e-03, 6.048833e-03, 6.5120906e-03, 6.99541e-03, 7.499032e-03, 8.023193e-03, 8.568126e-03,
    9.134059e-03, 9.721218e-03, 1.0329823e-02, 1.0960094e-02, 1.1612245e-02, 1.2286488e-02, 1.29830325e-02, 1.3702083e-02,
    1.4443844e-02, 1.5208514e-02, 1.5996294e-02, 1.6807375e-02, 1.7641954e-02, 1.850022e-02, 1.9382361e-02, 2.0288562e-02,
    2.121901e-02, 2.2173885e-02, 2.3153367e-02, 2.4157632e-02, 2.518686e-02, 2.6241222e-02, 2.7320892e-02, 2.842604e-02,
    2.9556835e-02, 3.0713445e-02, 3.1896032e-02, 3.3104766e-02, 3.4339808e-02, 3.5601314e-02, 3.688945e-02, 3.8204372e-02,
    3.9546236e-02, 4.09152e-02, 4.231141e-02, 4.373503e-02, 4.5186203e-02, 4.6665087e-02, 4.8171826e-02, 4.9706567e-02,
    5.1269457e-02, 5.2860647e-02, 5.4480277e-02, 5.612849e-02, 5.780543e-02, 5.9511237e-02, 6.1246052e-02, 6.3010015e-02,
    6.4803265e-02, 6.662594e-02, 6.847817e-02, 7.0360094e-02, 7.227185e-02, 7.421357e-02, 7.618538e-02, 7.818742e-02,
    8.021982e-02, 8.228271e-02, 8.437621e-02, 8.650046e-02, 8.865558e-02, 9.084171e-02, 9.3058966e-02, 9.530747e-02,
    9.758735e-02, 9.9898726e-02, 1.0224173e-01, 1.04616486e-01, 1.07023105e-01, 1.0946171e-01, 1.1193243e-01, 1.14435375e-01,
    1.16970666e-01, 1.1953843e-01, 1.22138776e-01, 1.2477182e-01, 1.2743768e-01, 1.3013647e-01, 1.3286832e-01, 1.3563333e-01,
    1.3843161e-01, 1.4126329e-01, 1.4412847e-01, 1.4702727e-01, 1.4995979e-01, 1.5292615e-01, 1.5592647e-01, 1.5896083e-01,
    1.6202937e-01, 1.651322e-01, 1.682694e-01, 1.7144111e-01, 1.746474e-01, 1.7788842e-01, 1.8116425e-01, 1.8447499e-01,
    1.8782078e-01, 1.9120169e-01, 1.9461784e-01, 1.9806932e-01, 2.0155625e-01, 2.0507874e-01, 2.0863687e-01, 2.1223076e-01,
    2.158605e-01, 2.195262e-01, 2.2322796e-01, 2.2696587e-01, 2.3074006e-01, 2.3455058e-01, 2.3839757e-01, 2.4228112e-01,
    2.4620132e-01, 2.5015828e-01, 2.541521e-01, 2.5818285e-01, 2.6225066e-01, 2.663556e-01, 2.704978e-01, 2.746773e-01,
    2.7889428e-01, 2.8314874e-01, 2.8744084e-01, 2.9177064e-01, 2.9613826e-01, 3.0054379e-01, 3.049873e-01, 3.0946892e-01,
    3.1398872e-01, 3.1854677e-01, 3.231432e-01, 3.277781e-01, 3.3245152e-01, 3.3716363e-01, 3.4191442e-01, 3.4670407e-01,
    3.515326e-01, 3.5640013e-01, 3.613068e-01, 3.662526e-01, 3.712377e-01, 3.7626213e-01, 3.8132602e-01, 3.8642943e-01,
    3.9157248e-01, 3.9675522e-01, 4.0197778e-01, 4.072402e-01, 4.125426e-01, 4.1788507e-01, 4.2326766e-01, 4.286905e-01,
    4.3415365e-01, 4.3965718e-01, 4.452012e-01, 4.507858e-01, 4.5641103e-01, 4.62077e-01, 4.677838e-01, 4.7353148e-01,
    4.7932017e-01, 4.8514995e-01, 4.9102086e-01, 4.9693298e-01, 5.028865e-01, 5.0888133e-01, 5.149177e-01, 5.2099556e-01,
    5.271151e-01, 5.332764e-01, 5.394795e-01, 5.4572445e-01, 5.5201143e-01, 5.583404e-01, 5.647115e-01, 5.7112485e-01,
    5.7758045e-01, 5.8407843e-01, 5.9061885e-01, 5.9720176e-01, 6.0382736e-01, 6.1049557e-01, 6.172066e-01, 6.239604e-01,
    6.3075715e-01, 6.3759685e-01, 6.444797e-01, 6.5140563e-01, 6.5837485e-01, 6.653873e-01, 6.7244315e-01, 6.795425e-01,
    6.866853e-01, 6.9387174e-01, 7.011019e-01, 7.0837575e-01, 7.156935e-01, 7.230551e-01, 7.3046076e-01, 7.379104e-01,
    7.454042e-01, 7.529422e-01, 7.605245e-01, 7.6815116e-01, 7.758222e-01, 7.835378e-01, 7.912979e-01, 7.991027e-01,
    8.0695224e-01, 8.148466e-01, 8.2278574e-01, 8.307699e-01, 8.38799e-01, 8.468732e-01, 8.549926e-01, 8.631572e-01,
    8.713671e-01, 8.796224e-01, 8.879231e-01, 8.962694e-01, 9.046612e-01, 9.1309863e-01, 9.2158186e-01, 9.301109e-01,
    9.386857e-01, 9.473065e-01, 9.559733e-01, 9.646863e-01, 9.734453e-01, 9.822506e-01, 9.911021e-01, 1.0e+00,
];

/// The identity of a file's contents for the texture cache: its canonical path, size
/// and modification time, so that a file rewritten between two loads is read again.
type CacheKey = (PathBuf, u64, Option<SystemTime>);

/// Textures decoded so far, while any scene holds them.
static CACHE: Mutex<Option<HashMap<CacheKey, Weak<Texture>>>> = Mutex::new(None);

/// Reads and decodes the image file at `path`, or returns the texture already decoded
/// from it, if any scene still holds it: each file is decoded once and shared.
/// (The cache's lock is taken while loading scenes only, never while rendering.)
///
/// # Errors
/// The file cannot be read or decoded; the message does not repeat the path.
pub fn load_texture(path: &Path) -> Result<Arc<Texture>, String> {
    let canonical = std::fs::canonicalize(path).map_err(|e| e.to_string())?;
    let mut options = std::fs::OpenOptions::new();
    options.read(true);
    // Opening a FIFO would wait for a writer, maybe forever, before its type could be
    // checked; on a regular file the flag changes nothing.
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        options.custom_flags(libc::O_NONBLOCK);
    }
    let mut file = options.open(&canonical).map_err(|e| e.to_string())?;
    // Of the file opened, so that it cannot be swapped between the check and the read.
    let metadata = file.metadata().map_err(|e| e.to_string())?;
    if metadata.is_dir() {
        return Err("is a directory, not an image".into());
    }
    // A device (`/dev/zero`, `/dev/urandom`) or a FIFO would be read forever.
    if !metadata.is_file() {
        return Err("is not a regular file".into());
    }
    if metadata.len() > MAX_TEXTURE_BYTES {
        return Err(format!(
            "is too large for a texture ({} MiB; at most {} MiB)",
            metadata.len() >> 20,
            MAX_TEXTURE_BYTES >> 20
        ));
    }
    let key = (canonical, metadata.len(), metadata.modified().ok());
    let cached = |key: &CacheKey| {
        let cache = CACHE.lock().unwrap_or_else(PoisonError::into_inner);
        cache
            .as_ref()
            .and_then(|c| c.get(key))
            .and_then(Weak::upgrade)
    };
    if let Some(texture) = cached(&key) {
        return Ok(texture);
    }
    let mut bytes = Vec::with_capacity(metadata.len() as usize);
    // No more than the size checked, should the file grow meanwhile.
    std::io::Read::read_to_end(
        &mut std::io::Read::take(&mut file, MAX_TEXTURE_BYTES),
        &mut bytes,
    )
    .map_err(|e| e.to_string())?;
    let texture = Arc::new(Texture::decode(&bytes, path)?);
    drop(bytes);
    let mut cache = CACHE.lock().unwrap_or_else(PoisonError::into_inner);
    let cache = cache.get_or_insert_with(HashMap::new);
    // Forget textures no scene holds any more, so the map does not grow forever.
    cache.retain(|_, weak| weak.strong_count() > 0);
    // Two threads may have decoded the same file at once: keep the first.
    if let Some(existing) = cache.get(&key).and_then(Weak::upgrade) {
        return Ok(existing);
    }
    cache.insert(key, Arc::downgrade(&texture));
    Ok(texture)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn texture(width: u32, height: u32, channels: u32, texels: &[u8]) -> Texture {
        Texture::from_u8("t.png".into(), width, height, channels, texels.to_vec()).unwrap()
    }

    /// A direction in the image, brought back to the texture coordinates, is the one
    /// along which the transform moves a point that way in the image: `M^-1 d` for
    /// the transform's linear part `M`, here measured by the transform's own
    /// differences (turns, tiling, mirrors; equal scales on both axes, where
    /// directions and slopes agree).
    #[test]
    fn image_directions_come_back_to_the_surface_as_the_transform_moves_them() {
        for (angle, scale) in [
            (0.0f32, [1.0f32, 1.0]),
            (std::f32::consts::FRAC_PI_2, [1.0, 1.0]),
            (0.7, [3.0, 3.0]),
            (0.0, [-1.0, 1.0]),
            (-2.0, [2.0, -2.0]),
            (2.5, [-0.5, -0.5]),
        ] {
            let options = TextureOptions {
                scale: Vec2::from(scale),
                rotation: Vec2::new(angle.cos(), angle.sin()),
                offset: Vec2::new(0.3, -0.2),
                ..TextureOptions::default()
            };
            let origin = Vec2::new(0.4, 0.1);
            let column = |d: Vec2| options.transform(origin + d) - options.transform(origin);
            let (a, b) = (column(Vec2::X), column(Vec2::Y));
            let det = a.x * b.y - b.x * a.y;
            let inverse = |d: Vec2| Vec2::new(b.y * d.x - b.x * d.y, a.x * d.y - a.y * d.x) / det;
            for d in [Vec2::X, Vec2::Y, Vec2::new(0.6, -0.8)] {
                let got = options.image_to_surface(d);
                let want = inverse(d).normalize();
                assert!(
                    (got.normalize() - want).abs().max_element() < 1e-5,
                    "angle {angle}, scale {scale:?}: {d} -> {got}, want {want}"
                );
            }
        }
    }

    #[test]
    fn the_table_matches_the_formula() {
        for (i, &value) in SRGB_TO_LINEAR.iter().enumerate() {
            let exact = srgb_to_linear(i as Float / 255.0);
            assert!(
                (value - exact).abs() <= 1e-6 * exact.max(1e-3),
                "{i}: {value} vs {exact}"
            );
        }
        assert_eq!(SRGB_TO_LINEAR[0], 0.0);
        assert_eq!(SRGB_TO_LINEAR[255], 1.0);
    }

    #[test]
    fn texel_centres_are_exact_and_v_points_up() {
        // 2x2 grey: top row 0 and 100, bottom row 200 and 255.
        let t = texture(2, 2, 1, &[0, 100, 200, 255]);
        let at = |u: Float, v: Float| {
            t.bilinear(Vec2::new(u, v), Wrap::Clamp, Wrap::Clamp, Encoding::Linear)[0]
        };
        assert_eq!(at(0.25, 0.75), 0.0);
        assert_eq!(at(0.75, 0.75), 100.0 / 255.0);
        assert_eq!(at(0.25, 0.25), 200.0 / 255.0);
        assert_eq!(at(0.75, 0.25), 1.0);
        // Half-way between two centres: the mean.
        assert!((at(0.5, 0.75) - 50.0 / 255.0).abs() < 1e-6);
    }

    #[test]
    fn repeat_mirror_and_clamp_addressing() {
        assert_eq!(address(-1, 4, Wrap::Repeat), 3);
        assert_eq!(address(4, 4, Wrap::Repeat), 0);
        assert_eq!(address(-1, 4, Wrap::Clamp), 0);
        assert_eq!(address(9, 4, Wrap::Clamp), 3);
        assert_eq!(address(4, 4, Wrap::Mirror), 3);
        assert_eq!(address(-1, 4, Wrap::Mirror), 0);
        assert_eq!(address(i64::MIN, 4, Wrap::Repeat), 0);
        // Far outside [0, 1] and even non-finite coordinates read some texel.
        let t = texture(1, 1, 3, &[10, 20, 30]);
        for uv in [
            Vec2::new(1e30, -1e30),
            Vec2::new(Float::NAN, 0.5),
            Vec2::new(Float::INFINITY, 0.0),
        ] {
            let v = t.bilinear(uv, Wrap::Repeat, Wrap::Repeat, Encoding::Linear);
            assert_eq!(v, [10.0 / 255.0, 20.0 / 255.0, 30.0 / 255.0, 1.0], "{uv}");
        }
    }
}
