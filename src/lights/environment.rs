//! Light from infinitely far away: a constant colour, or an equirectangular image
//! (Radiance `.hdr`, OpenEXR, or any texture) oriented as three.js,
//! three-gpu-pathtracer and Blender (after a glTF import) show the same file, +Y up:
//! a unit direction `d` maps to `u = 0.5 + atan2(d.z, d.x) / (2 pi)`,
//! `v = 0.5 + asin(d.y) / pi`, `v = 1` being the top row, filtered bilinearly between
//! texel centres. A rotation of `A` degrees turns the environment about +Y,
//! right-handed: at 90, what was seen along +X is seen along -Z.
//!
//! An image is importance-sampled: a texel is picked in proportion to its luminance
//! times the solid angle it covers (`sin` of its polar angle), then a point uniformly
//! in it, so that a small bright sun in a dim sky is found by light sampling rather
//! than by chance (path mode weighs both strategies by multiple importance sampling).

use std::f32::consts::{FRAC_1_PI, PI};
use std::sync::Arc;

use glam::Vec4;
use wide::f32x16;

use crate::math::{Float, ONE_BELOW_ONE, Vec2, Vec3};
use crate::textures::{Encoding, Texture};

/// What the environment shows, as a scene description gives it.
#[derive(Clone, Debug)]
pub enum EnvironmentRadiance {
    /// The same radiance from every direction.
    Constant(Vec3),
    /// An equirectangular image.
    Map(Arc<Texture>),
}

/// An environment as described: its radiance, a multiplier and a turn about +Y.
#[derive(Clone, Debug)]
pub struct EnvironmentDesc {
    /// Constant or image.
    pub radiance: EnvironmentRadiance,
    /// Multiplies the radiance.
    pub strength: Float,
    /// Degrees about +Y, right-handed.
    pub rotation_degrees: Float,
}

/// An environment ready to be looked up and sampled.
#[derive(Clone, Debug)]
pub struct Environment {
    radiance: Radiance,
    strength: Float,
    /// Sine and cosine of the rotation.
    rotation: (Float, Float),
    /// Mean radiance over the sphere, for weighing the environment against other
    /// lights.
    mean_radiance: Float,
}

/// What an [`Environment`] looks up: a colour, or its own copy of an image's texels
/// (shared, so that an integrator's copy of the environment costs nothing).
#[derive(Clone, Debug)]
enum Radiance {
    Constant(Vec3),
    Map(Arc<EnvironmentMap>),
}

/// An equirectangular image in the form its lookups and sampling want: linear `f32`
/// texels read with no decoding or format branches (the generic texture path decoded
/// sRGB and matched the channel count at every lookup), and the cumulative
/// distributions of the rows and of the texels within each row, inverted through
/// guide tables.
///
/// Inversion rather than Walker's alias tables (the sampler before): it maps `[0,
/// 1)^2` onto the image in order, row by `v` and texel by `u`, so that a pixel's
/// stratified light samples ([`crate::sampler`]) land on a small bright light in
/// the proportion its share of the density says; an alias table scatters
/// neighbouring values over unrelated texels, and the light was hit in a random
/// number of them (a white sphere in the studio at 64 samples: 0.36x the noise of
/// independent samples and the alias tables). A guide table keeps the inversion to
/// about one read a level, as the alias table was: slot `k` of `n` names the first
/// item whose range reaches `k / n` with the bounds of its range and the next
/// item's, and a bright texel covers its slots alone (two binary searches, before the
/// alias tables, were a fifth of an environment-lit render; with a slot naming one
/// item and not the next, the scans past it were 8% of one).
///
/// Two levels rather than one table over all texels: a single table's slot is uniform
/// over the whole image, so every pick missed the caches (measured: half the time of
/// sampling was that one load); picked by rows, the tables and texels read are those
/// of the bright rows, which stay cached.
///
/// Memory: 36 bytes a texel (16 for RGB and density, 20 for the row's distribution
/// and its guide slot), against the 4 of the first cumulative distribution; the texture
/// limits bound the texels, and lookups no longer need the decoded texture once this
/// is made.
#[derive(Debug)]
struct EnvironmentMap {
    width: u32,
    height: u32,
    /// Row 0 at the top: linear RGB as the image holds it (NaN and negative values
    /// too: lookups clamp what they interpolate), then the density in `(u, v)` with
    /// which [`Environment::sample`] picks the texel's points, so that the pdf of a
    /// direction reads the same cache line as its radiance.
    texels: Vec<[Float; 4]>,
    /// The rows' distribution, top to bottom; empty for a black image, which is
    /// never sampled.
    rows: Inversion,
    /// Each row's distribution over its texels, `width` entries a row in the order
    /// of `texels`: a sample reads one guide slot at random among `width * height`,
    /// most often a cache miss, and mostly finds there all it needs, the texel's
    /// density too, from its share (reading the density from `texels` cost a second
    /// miss).
    columns: Inversion,
}

/// Piecewise-constant distributions over items, sampled by inverting their
/// cumulative distribution with a guide table: one or, concatenated, several of `n`
/// items each (the rows of an image).
#[derive(Debug, Default)]
struct Inversion {
    /// The cumulative distribution at the end of each item: non-decreasing, the last
    /// item's exactly 1.
    ends: Vec<f32>,
    /// Slot `k` of `n`: the first item whose end exceeds `k / n`.
    guide: Vec<GuideSlot>,
}

/// A slot of a guide table: the first item whose range of the cumulative
/// distribution reaches into the slot's share of `[0, 1)`, and the bounds of that
/// item's range and of the next one's: `[bounds[0], bounds[1])` and `[bounds[1],
/// bounds[2])`. A slot most often meets one or two items, and then finds all it
/// needs here, with one read.
#[derive(Clone, Copy, Debug)]
#[repr(align(16))]
struct GuideSlot {
    first: u32,
    bounds: [f32; 3],
}

impl Inversion {
    /// Appends the distribution of `weights` (uniform if they are all 0).
    fn push(&mut self, weights: &[f64]) {
        let n = weights.len();
        let start = self.ends.len();
        let total: f64 = weights.iter().sum();
        let mut sum = 0.0f64;
        for (i, w) in weights.iter().enumerate() {
            sum += w;
            let end = if total > 0.0 {
                sum / total
            } else {
                (i + 1) as f64 / n as f64
            };
            self.ends.push(end as f32);
        }
        let ends = &mut self.ends[start..];
        ends[n - 1] = 1.0;
        let mut first = 0;
        for k in 0..n {
            let slot_start = k as f32 / n as f32;
            while first < n - 1 && ends[first] <= slot_start {
                first += 1;
            }
            let (low, high) = item_range(ends, first);
            self.guide.push(GuideSlot {
                first: first as u32,
                bounds: [low, high, ends[(first + 1).min(n - 1)]],
            });
        }
    }

    /// The width of item `i` of the distribution at `offset`: its share as drawn.
    fn width(&self, offset: usize, i: usize) -> f32 {
        let (low, high) = item_range(&self.ends[offset..], i);
        high - low
    }

    /// The item of the distribution at `offset` (its first item's index, `n` items)
    /// that `u` in `[0, 1)` picks, `u`'s place within the item's range in `[0, 1)`,
    /// and the item's width (its probability).
    #[inline(always)]
    fn pick(&self, offset: usize, n: usize, u: f32) -> (usize, f32, f32) {
        let k = ((u * n as f32) as usize).min(n - 1);
        let GuideSlot {
            first,
            bounds: [b0, b1, b2],
        } = self.guide[offset + k];
        let first = first as usize;
        let (i, low, high) = if u >= b0 && u < b1 {
            (first, b0, b1)
        } else if u >= b1 && u < b2 {
            (first + 1, b1, b2)
        } else {
            let ends = &self.ends[offset..offset + n];
            // Rounding of `u * n` may put `u` a little below the slot's start.
            let mut i = first;
            while i > 0 && u < ends[i - 1] {
                i -= 1;
            }
            while i < n - 1 && u >= ends[i] {
                i += 1;
            }
            let (low, high) = item_range(ends, i);
            (i, low, high)
        };
        let width = high - low;
        let within = ((u - low) / width).clamp(0.0, ONE_BELOW_ONE);
        (i, within, width)
    }

    /// Asks for the guide slot [`Inversion::pick`] reads first.
    #[inline(always)]
    fn prefetch(&self, offset: usize, n: usize, u: f32) {
        let k = ((u * n as f32) as usize).min(n - 1);
        prefetch(&self.guide[offset + k]);
    }
}

/// The density in `(u, v)` of a texel of an image `width` texels wide whose share of
/// its row is `texel_width` and whose row's share of the image, times its height,
/// is `row_scale`: the same value the map stores with the texel.
#[inline(always)]
fn texel_density(texel_width: f32, width: usize, row_scale: f64) -> Float {
    (f64::from(texel_width) * width as f64 * row_scale) as Float
}

/// Item `i`'s range `[low, high)` of the cumulative distribution whose item ends
/// are `ends`.
#[inline(always)]
fn item_range(ends: &[f32], i: usize) -> (f32, f32) {
    (if i == 0 { 0.0 } else { ends[i - 1] }, ends[i])
}

/// A direction drawn towards the environment ([`Environment::sample_direction`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DirectionSample {
    /// The unit direction, in the world.
    pub direction: Vec3,
    /// Its density in solid angle.
    pub pdf: Float,
    /// Where it lies on the map (unused for a constant environment).
    uv: Vec2,
}

/// A point of an environment map drawn by light sampling
/// ([`Environment::sample_map`]), not yet turned into a direction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MapSample {
    /// Map coordinates.
    pub uv: Vec2,
    /// The density in `(u, v)` of the texel picked.
    pub density: Float,
}

/// A direction leaving the scene towards the environment, with its map coordinates
/// ([`Environment::leaving`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Leaving {
    d: Vec3,
    /// Unused for a constant environment.
    uv: Vec2,
}

/// Luminance of linear Rec. 709 RGB.
#[inline]
fn luminance(c: Vec3) -> Float {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

impl Environment {
    /// The environment `desc` describes, with its sampling tables.
    pub fn new(desc: &EnvironmentDesc) -> Environment {
        let rotation = desc.rotation_degrees.to_radians().sin_cos();
        let strength = desc.strength.max(0.0);
        let (radiance, mean_radiance) = match &desc.radiance {
            EnvironmentRadiance::Constant(c) => (
                Radiance::Constant(*c),
                luminance(c.max(Vec3::ZERO)) * strength,
            ),
            EnvironmentRadiance::Map(texture) => {
                let (map, mean) = EnvironmentMap::new(texture);
                (Radiance::Map(Arc::new(map)), mean * strength)
            }
        };
        Environment {
            radiance,
            strength,
            rotation,
            mean_radiance,
        }
    }

    /// Whether the radiance is the same from every direction.
    pub fn is_constant(&self) -> bool {
        matches!(self.radiance, Radiance::Constant(_))
    }

    /// The mean luminance over all directions (times the strength).
    pub fn mean_radiance(&self) -> Float {
        self.mean_radiance
    }

    /// `d` in the environment's own frame (the rotation undone).
    #[inline]
    fn world_to_map(&self, d: Vec3) -> Vec3 {
        let (sin, cos) = self.rotation;
        // Turning by -A about +Y.
        Vec3::new(d.x * cos - d.z * sin, d.y, d.x * sin + d.z * cos)
    }

    /// A direction of the environment's own frame in the world (turned by A).
    #[inline]
    fn map_to_world(&self, d: Vec3) -> Vec3 {
        let (sin, cos) = self.rotation;
        Vec3::new(d.x * cos + d.z * sin, d.y, -d.x * sin + d.z * cos)
    }

    /// The radiance arriving from the unit direction `d` (seen along `d`).
    #[inline]
    pub fn radiance(&self, d: Vec3) -> Vec3 {
        self.radiance_leaving(&self.leaving(d))
    }

    /// The radiance arriving from the unit direction `d` and the density in solid
    /// angle with which [`Environment::sample`] picks `d`: both of
    /// [`Environment::radiance`] and [`Environment::pdf`] for one conversion of `d`
    /// to map coordinates, as a path that leaves the scene needs them.
    #[inline]
    pub fn radiance_and_pdf(&self, d: Vec3) -> (Vec3, Float) {
        self.radiance_and_pdf_leaving(&self.leaving(d))
    }

    /// The unit direction `d` of a path leaving the scene, converted to map
    /// coordinates once, and the texels its radiance reads asked of memory: a path
    /// tracer converts its batch's leaving paths first, so that their cache misses
    /// overlap, and reads them with [`Environment::radiance_leaving`] or
    /// [`Environment::radiance_and_pdf_leaving`].
    #[inline]
    pub fn leaving(&self, d: Vec3) -> Leaving {
        let uv = match &self.radiance {
            Radiance::Constant(_) => Vec2::ZERO,
            Radiance::Map(map) => {
                let uv = direction_to_uv(self.world_to_map(d));
                map.prefetch_texels(uv);
                uv
            }
        };
        Leaving { d, uv }
    }

    /// [`Environment::radiance`] of a leaving path's direction.
    #[inline]
    pub fn radiance_leaving(&self, leaving: &Leaving) -> Vec3 {
        self.radiance_at(leaving.uv)
    }

    /// The radiance at map coordinates `uv` (of a constant environment, anywhere).
    #[inline(always)]
    fn radiance_at(&self, uv: Vec2) -> Vec3 {
        match &self.radiance {
            Radiance::Constant(c) => *c * self.strength,
            Radiance::Map(map) => self.texel_radiance(map.bilinear(uv)),
        }
    }

    /// Starts fetching the texels [`Environment::radiance_at`] reads at `uv`.
    #[inline(always)]
    fn prefetch_at(&self, uv: Vec2) {
        if let Radiance::Map(map) = &self.radiance {
            map.prefetch_texels(uv);
        }
    }

    /// [`Environment::radiance_and_pdf`] of a leaving path's direction.
    #[inline]
    pub fn radiance_and_pdf_leaving(&self, leaving: &Leaving) -> (Vec3, Float) {
        match &self.radiance {
            Radiance::Constant(_) => (self.radiance_leaving(leaving), self.pdf(leaving.d)),
            Radiance::Map(map) => (
                self.texel_radiance(map.bilinear(leaving.uv)),
                map.pdf(leaving.uv, leaving.d),
            ),
        }
    }

    /// A filtered texel as radiance: NaN and negative texels emit nothing, infinite
    /// ones the most a float holds.
    #[inline(always)]
    fn texel_radiance(&self, texel: Vec4) -> Vec3 {
        Vec3::new(texel.x, texel.y, texel.z)
            .max(Vec3::ZERO)
            .min(Vec3::splat(Float::MAX))
            * self.strength
    }

    /// A direction towards the environment by `u`, its radiance and its density in
    /// solid angle; `None` for a black environment.
    #[inline]
    pub fn sample(&self, u: Vec2) -> Option<(Vec3, Vec3, Float)> {
        let sample = self.sample_direction(u)?;
        Some((sample.direction, self.sampled_radiance(&sample), sample.pdf))
    }

    /// A direction towards the environment by `u` and its density in solid angle,
    /// its radiance left to [`Environment::sampled_radiance`]: light sampling needs
    /// it only where the BSDF scatters towards the direction (half of them are
    /// below an opaque surface), and a filtered lookup reads four texels. `None`
    /// for a black environment.
    #[inline]
    pub fn sample_direction(&self, u: Vec2) -> Option<DirectionSample> {
        let map = match &self.radiance {
            Radiance::Constant(c) => {
                if *c == Vec3::ZERO || self.strength == 0.0 {
                    return None;
                }
                // Uniform over the sphere.
                let z = 1.0 - 2.0 * u.x;
                let r = (1.0 - z * z).max(0.0).sqrt();
                let phi = 2.0 * PI * u.y;
                let d = Vec3::new(r * phi.cos(), r * phi.sin(), z);
                return Some(DirectionSample {
                    direction: d,
                    pdf: 0.25 * FRAC_1_PI,
                    uv: Vec2::ZERO,
                });
            }
            Radiance::Map(map) => map,
        };
        let (uv, density) = map.sample(u)?;
        let (d, cos_latitude) = sampled_direction_and_cos(uv);
        // The density of the texel picked, per solid angle: dw = 2 pi^2 cos(latitude)
        // du dv. It is the density of what was sampled, even for a point so near a
        // texel's edge that `pdf` of the direction, rounded, reads the neighbour.
        let pdf = density / (2.0 * PI * PI * cos_latitude);
        if !(pdf > 0.0 && pdf.is_finite()) {
            return None;
        }
        Some(DirectionSample {
            direction: self.map_to_world(d),
            pdf,
            uv,
        })
    }

    /// The first half of [`Environment::sample_direction`] for an image: the point of
    /// the map that `u` picks and its texel's density in `(u, v)`, for a batch of
    /// paths to turn into directions sixteen at a time
    /// ([`Environment::directions_of`]); `None` for a black image, and for a
    /// constant environment (which [`Environment::sample_direction`] samples alone).
    #[inline]
    pub fn sample_map(&self, u: Vec2) -> Option<MapSample> {
        match &self.radiance {
            Radiance::Constant(_) => None,
            Radiance::Map(map) => map.sample(u).map(|(uv, density)| MapSample { uv, density }),
        }
    }

    /// [`Environment::sample_direction`]'s second half for sixteen map points at once
    /// (`u` and `v` and their texels' densities, lane by lane): the world directions'
    /// `x`, `y` and `z`, and their densities in solid angle, lane for lane what
    /// `sample_direction` gives, bit for bit (the sines and cosines from the `wide`
    /// crate's same polynomial, sixteen lanes wide rather than two of four). A lane
    /// whose density is not positive and finite has no sample.
    #[inline(always)]
    pub fn directions_of(&self, uv: [f32x16; 2], density: f32x16) -> ([f32x16; 3], f32x16) {
        let phi = (uv[0] - f32x16::splat(0.5)) * f32x16::splat(2.0) * f32x16::splat(PI);
        let latitude = (uv[1] - f32x16::splat(0.5)) * f32x16::splat(PI);
        let (sin_lat, cos_lat) = latitude.sin_cos();
        let (sin_phi, cos_phi) = phi.sin_cos();
        let pdf = density / (f32x16::splat(2.0 * PI * PI) * cos_lat);
        let (x, y, z) = (cos_lat * cos_phi, sin_lat, cos_lat * sin_phi);
        // `map_to_world`.
        let (sin, cos) = (
            f32x16::splat(self.rotation.0),
            f32x16::splat(self.rotation.1),
        );
        ([x * cos + z * sin, y, -x * sin + z * cos], pdf)
    }

    /// The radiance arriving along the direction of a map point that
    /// [`Environment::sample_map`] drew ([`Environment::sampled_radiance`]).
    #[inline]
    pub fn map_sample_radiance(&self, sample: &MapSample) -> Vec3 {
        self.radiance_at(sample.uv)
    }

    /// Starts fetching the texels [`Environment::map_sample_radiance`] reads.
    #[inline]
    pub fn prefetch_map_sample(&self, sample: &MapSample) {
        self.prefetch_at(sample.uv);
    }

    /// Starts fetching what [`Environment::sample_direction`] reads from memory for
    /// `u` (for a large map, a slot of its alias table at random), without drawing
    /// anything: a path tracer asks for its batch's paths before shading them one by
    /// one.
    #[inline]
    pub fn prefetch(&self, u: Vec2) {
        if let Radiance::Map(map) = &self.radiance {
            map.prefetch(u);
        }
    }

    /// Starts fetching the texels [`Environment::sampled_radiance`] reads for
    /// `sample`, to be read after other work.
    #[inline]
    pub fn prefetch_radiance(&self, sample: &DirectionSample) {
        self.prefetch_at(sample.uv);
    }

    /// The radiance arriving along a direction [`Environment::sample_direction`]
    /// drew.
    #[inline]
    pub fn sampled_radiance(&self, sample: &DirectionSample) -> Vec3 {
        self.radiance_at(sample.uv)
    }

    /// The density in solid angle with which [`Environment::sample`] picks `d`.
    #[inline]
    pub fn pdf(&self, d: Vec3) -> Float {
        match &self.radiance {
            Radiance::Constant(c) => {
                if *c == Vec3::ZERO || self.strength == 0.0 {
                    0.0
                } else {
                    0.25 * FRAC_1_PI
                }
            }
            Radiance::Map(map) => map.pdf(direction_to_uv(self.world_to_map(d)), d),
        }
    }
}

impl EnvironmentMap {
    /// The image's texels in linear `f32` and their alias table, and the image's
    /// mean luminance over the sphere.
    ///
    /// A texel weighs the greatest luminance of itself and its eight neighbours
    /// (bilinear filtering spreads each texel's value over its neighbours' cells: a
    /// density following the texel alone would leave a sun's fringe to rare samples
    /// of huge weight), times `sin` of the polar angle of its row's centre, the solid
    /// angle it covers.
    fn new(texture: &Texture) -> (EnvironmentMap, Float) {
        let (width, height) = texture.size();
        let (w, h) = (width as usize, height as usize);
        // 8-bit images (PNG, JPEG) hold sRGB, floating point ones (HDR, EXR) linear.
        let encoding = if texture.is_8bit() {
            Encoding::Srgb
        } else {
            Encoding::Linear
        };
        let mut texels = Vec::with_capacity(w * h);
        let mut luminances = Vec::with_capacity(w * h);
        let mut radiance_sum = 0.0f64;
        for y in 0..h {
            let sin_polar = row_sin_polar(y, h);
            for x in 0..w {
                let [r, g, b, _] = texture.texel(x, y, encoding);
                texels.push([r, g, b, 0.0]);
                let l = luminance(Vec3::new(r, g, b));
                // NaN and negative texels weigh nothing (the reader warns of them).
                let l = if l.is_finite() && l > 0.0 { l } else { 0.0 };
                radiance_sum += f64::from(l) * sin_polar;
                luminances.push(l);
            }
        }
        let mut weights = Vec::with_capacity(w * h);
        for y in 0..h {
            let sin_polar = row_sin_polar(y, h);
            for x in 0..w {
                let mut greatest: Float = 0.0;
                for ny in y.saturating_sub(1)..(y + 2).min(h) {
                    for dx in [w - 1, 0, 1] {
                        greatest = greatest.max(luminances[ny * w + (x + dx) % w]);
                    }
                }
                weights.push(f64::from(greatest) * sin_polar);
            }
        }
        drop(luminances);
        let row_weights: Vec<f64> = weights.chunks(w).map(|row| row.iter().sum()).collect();
        let total: f64 = row_weights.iter().sum();
        let (mut rows, mut columns) = (Inversion::default(), Inversion::default());
        if total > 0.0 && total.is_finite() {
            // A texel's density in (u, v) is its share of the distribution, as
            // drawn (the `f32` distributions' steps), over its share of the square,
            // 1 / (w h): a row's share times the texel's share of its row.
            rows.push(&row_weights);
            columns.ends.reserve_exact(w * h);
            columns.guide.reserve_exact(w * h);
            for (y, row) in weights.chunks(w).enumerate() {
                let row_scale = f64::from(rows.width(0, y)) * h as f64;
                columns.push(row);
                for (x, texel) in texels[y * w..(y + 1) * w].iter_mut().enumerate() {
                    texel[3] = texel_density(columns.width(y * w, x), w, row_scale);
                }
            }
        }
        // The mean over the sphere of luminance: the sum of luminance times solid
        // angle (2 pi^2 sin / (w h) per texel) over 4 pi.
        let mean = (radiance_sum * std::f64::consts::PI / (2.0 * (w * h) as f64)) as Float;
        (
            EnvironmentMap {
                width,
                height,
                texels,
                rows,
                columns,
            },
            mean,
        )
    }

    /// Bilinear lookup at `uv` (`v` up) between texel centres, repeating in `u` and
    /// clamped in `v`, as `Texture::bilinear` does, in the same order of operations.
    #[inline]
    fn bilinear(&self, uv: Vec2) -> Vec4 {
        let (width, height) = (self.width as i64, self.height as i64);
        let x = uv.x * self.width as Float - 0.5;
        let y = (1.0 - uv.y) * self.height as Float - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        // Non-finite coordinates give fx = NaN: read a texel and weigh it whole rather
        // than spread NaN into the image.
        let (fx, fy) = (
            if fx.is_finite() { fx } else { 0.0 },
            if fy.is_finite() { fy } else { 0.0 },
        );
        // `u` from a direction lies in [0, 1], so x0 in [-1, width - 1]: wrapping
        // is a comparison, not a division (the clamp keeps any other input in range).
        let x0 = (x0 as i64).clamp(-1, width - 1);
        let xs = [
            if x0 < 0 { width - 1 } else { x0 },
            if x0 + 1 >= width { 0 } else { x0 + 1 },
        ];
        let y0 = y0 as i64;
        let ys = [y0.clamp(0, height - 1), (y0 + 1).clamp(0, height - 1)];
        let at = |x: i64, y: i64| Vec4::from_array(self.texels[(y * width + x) as usize]);
        let (t00, t10) = (at(xs[0], ys[0]), at(xs[1], ys[0]));
        let (t01, t11) = (at(xs[0], ys[1]), at(xs[1], ys[1]));
        let top = t00 + (t10 - t00) * fx;
        let bottom = t01 + (t11 - t01) * fx;
        top + (bottom - top) * fy
    }

    /// The density in solid angle of the direction `d` at map coordinates `uv`: its
    /// texel's density in `(u, v)` over `dw / (du dv)`.
    #[inline]
    fn pdf(&self, uv: Vec2, d: Vec3) -> Float {
        if self.rows.ends.is_empty() {
            return 0.0;
        }
        let (width, height) = (self.width as usize, self.height as usize);
        let x = ((uv.x * self.width as Float) as usize).min(width - 1);
        let y = (((1.0 - uv.y) * self.height as Float) as usize).min(height - 1);
        let density = self.texels[y * width + x][3];
        // sin(polar) = cos(latitude), from x and z: accurate near the poles, where
        // 1 - y^2 rounds to 0 (and the same in the map's frame as in the world's).
        let sin_polar = (d.x * d.x + d.z * d.z).sqrt();
        if sin_polar <= 0.0 {
            return 0.0;
        }
        density / (2.0 * PI * PI * sin_polar)
    }

    /// A point of the map by `u` and its texel's density in `(u, v)`: `u.y` picks
    /// the row and the point's height in it, `u.x` the texel in the row and the
    /// point's place along it, each by inversion, so that stratified values give
    /// stratified points.
    #[inline]
    fn sample(&self, u: Vec2) -> Option<(Vec2, Float)> {
        if self.rows.ends.is_empty() {
            return None;
        }
        let (width, height) = (self.width as usize, self.height as usize);
        let (y, fy, row_width) = self.rows.pick(0, height, u.y);
        let (x, fx, texel_width) = self.columns.pick(y * width, width, u.x);
        let row_scale = f64::from(row_width) * height as f64;
        let density = texel_density(texel_width, width, row_scale);
        let uv = Vec2::new(
            (x as Float + fx) / self.width as Float,
            1.0 - (y as Float + fy) / self.height as Float,
        );
        Some((uv, density))
    }

    /// Asks the processor to fetch the texels [`EnvironmentMap::bilinear`] reads at
    /// `uv` (their cache lines in both rows).
    #[inline(always)]
    fn prefetch_texels(&self, uv: Vec2) {
        let (width, height) = (self.width as i64, self.height as i64);
        let x = uv.x * self.width as Float - 0.5;
        let y = (1.0 - uv.y) * self.height as Float - 0.5;
        // Out-of-range or NaN coordinates saturate into the clamps.
        let x0 = (x.floor() as i64).clamp(0, width - 1);
        let x1 = (x0 + 1).min(width - 1);
        let y0 = (y.floor() as i64).clamp(0, height - 1);
        let y1 = (y0 + 1).min(height - 1);
        for row in [y0, y1] {
            prefetch(&self.texels[(row * width + x0) as usize]);
            prefetch(&self.texels[(row * width + x1) as usize]);
        }
    }

    /// Asks the processor to fetch the guide slot of the row's distribution that
    /// [`EnvironmentMap::sample`] reads for `u`, so that several paths' misses
    /// overlap rather than follow one another.
    #[inline]
    fn prefetch(&self, u: Vec2) {
        if self.rows.ends.is_empty() {
            return;
        }
        let (width, height) = (self.width as usize, self.height as usize);
        let (y, _, _) = self.rows.pick(0, height, u.y);
        self.columns.prefetch(y * width, width, u.x);
    }
}

/// A hint to bring `value`'s cache line in (nothing where the target has no such
/// instruction).
#[inline(always)]
fn prefetch<T>(value: &T) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: a prefetch does not access memory in a way that can fault; the
    // pointer comes from a reference anyway.
    unsafe {
        use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
        _mm_prefetch::<_MM_HINT_T0>(std::ptr::from_ref(value).cast());
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = value;
}

/// `sin` of the polar angle of the centre of row `y` of `h` (row 0 at the top).
fn row_sin_polar(y: usize, h: usize) -> f64 {
    let v = 1.0 - (y as Float + 0.5) / h as Float;
    f64::from((PI * v).sin())
}

/// What camera rays that leave an unlit scene see in path mode: a neutral mid grey,
/// against which white and black models both stand out.
pub const STUDIO_BACKDROP: Vec3 = Vec3::splat(0.2);

/// The direction of the studio's key light (not unit length).
pub const STUDIO_KEY: Vec3 = Vec3::new(-0.6, 0.6, 0.55);
/// The least ratio of the irradiance of a surface facing the studio's key light to
/// that of one facing away from it: three stops.
pub const STUDIO_KEY_RATIO: Float = 6.0;
/// The most irradiance the studio gives a surface facing its key light: a white
/// (0.8) Lambertian surface there has radiance `0.8 * 4.5 / pi`, about 1.15.
pub const STUDIO_KEY_IRRADIANCE: Float = 4.5;

/// The radiance of [`studio`] in the unit direction `d`, seen through a lobe about
/// `spread` radians wide (0: as the map holds it): each soft light widened to the
/// angular radius `sqrt(radius^2 + spread^2)` and dimmed by the ratio of the two
/// discs' solid angles, so that it keeps its power, as a blur by the lobe would. The
/// dome varies slowly and is left as it is. Full mode reflects it on physically
/// based surfaces under the default rig (`integrators::whitted`), `spread` growing
/// with their roughness.
pub fn studio_radiance(d: Vec3, spread: Float) -> Float {
    let spread_degrees = spread.max(0.0).to_degrees();
    let soft_box = |centre: Vec3, radius_degrees: Float| {
        let (radius, dimming) = if spread_degrees > 0.0 {
            let widened = radius_degrees.hypot(spread_degrees);
            (widened, (radius_degrees / widened).powi(2))
        } else {
            (radius_degrees, 1.0)
        };
        let inner = radius.to_radians().cos();
        let outer = (radius * 1.4).to_radians().cos();
        let t = ((d.dot(centre.normalize()) - outer) / (inner - outer)).clamp(0.0, 1.0);
        t * t * (3.0 - 2.0 * t) * dimming
    };
    let t = ((d.y + 0.3) / 0.9).clamp(0.0, 1.0);
    let dome = 0.12 + 0.25 * t * t * (3.0 - 2.0 * t);
    let light = 5.0 * soft_box(STUDIO_KEY, 22.0)
        + 0.9 * soft_box(Vec3::new(0.75, 0.3, 0.45), 16.0)
        + 0.4 * soft_box(Vec3::Y, 25.0);
    dome + light
}

/// Path mode's default light for a scene that has none: a procedural studio, +Y up,
/// facing a camera on +Z (the default framing): a dim dome brighter above than below,
/// a large soft key light above and to the left of the camera, a smaller fill to the
/// right and a soft top light. Made as a 256 x 128 map, so it is sampled as any
/// environment map is.
///
/// The key dominates, as a model viewer's studio does (three.js's `RoomEnvironment`,
/// a photographer's 3:1 to 8:1 key-to-fill): a surface facing the key receives
/// [`STUDIO_KEY_RATIO`] times the irradiance of one facing away from it, one facing the
/// camera's left twice that of one facing its right, and a white surface facing the
/// key stays near the tone map's shoulder (irradiance at most [`STUDIO_KEY_IRRADIANCE`]),
/// so a white model shows its shape instead of a flat white (an earlier studio's dome
/// gave 4.9, 1.6 and 6.0).
pub fn studio() -> EnvironmentDesc {
    let (width, height) = (256u32, 128u32);
    let mut texels = Vec::with_capacity((width * height * 3) as usize);
    for row in 0..height {
        let v = 1.0 - (row as Float + 0.5) / height as Float;
        for column in 0..width {
            let u = (column as Float + 0.5) / width as Float;
            let c = studio_radiance(uv_to_direction(Vec2::new(u, v)), 0.0);
            texels.extend([c, c, c]);
        }
    }
    let texture = Texture::from_f32("studio".into(), width, height, 3, texels)
        .expect("the studio map's size matches its texels");
    EnvironmentDesc {
        radiance: EnvironmentRadiance::Map(Arc::new(texture)),
        strength: 1.0,
        rotation_degrees: 0.0,
    }
}

/// Whether area lights of `power` (the sum of their areas times their mean
/// emission) light a scene of bounding radius `radius` enough to do without a
/// default light: as much as a disc the scene's size at 1% of a white sky's
/// radiance would. LEDs and labels on a model are decorations, not lighting.
pub fn emitters_light_the_scene(power: Float, radius: Float) -> bool {
    power > 0.01 * PI * radius * radius
}

/// The equirectangular coordinates of the unit direction `d`: its angles from the
/// `wide` crate's vector `atan2` and `asin` (Agner Fog's, within a few units in the
/// last place of the C library's), inlined where the C library's two calls were
/// most of what a path leaving the scene cost before its texel lookup.
#[inline]
pub fn direction_to_uv(d: Vec3) -> Vec2 {
    use wide::f32x4;
    let longitude = f32x4::splat(d.z).atan2(f32x4::splat(d.x)).as_array()[0];
    let latitude = f32x4::splat(d.y.clamp(-1.0, 1.0)).asin().as_array()[0];
    Vec2::new(0.5 + longitude / (2.0 * PI), 0.5 + latitude / PI)
}

/// The unit direction at equirectangular coordinates `uv`.
#[inline]
pub fn uv_to_direction(uv: Vec2) -> Vec3 {
    uv_to_direction_and_cos(uv).0
}

/// The unit direction at equirectangular coordinates `uv` and the cosine of its
/// latitude (`sin` of its polar angle).
#[inline]
fn uv_to_direction_and_cos(uv: Vec2) -> (Vec3, Float) {
    let phi = (uv.x - 0.5) * 2.0 * PI;
    let latitude = (uv.y - 0.5) * PI;
    let (sin_lat, cos_lat) = latitude.sin_cos();
    let (sin_phi, cos_phi) = phi.sin_cos();
    (
        Vec3::new(cos_lat * cos_phi, sin_lat, cos_lat * sin_phi),
        cos_lat,
    )
}

/// [`uv_to_direction_and_cos`] for light sampling, the sines and cosines of both
/// angles from one vector evaluation (the `wide` crate's, as [`crate::math::sin_cos`])
/// instead of two calls to the C library, which were a tenth of the light
/// sampling's time; the same to float rounding.
#[inline(always)]
fn sampled_direction_and_cos(uv: Vec2) -> (Vec3, Float) {
    let phi = (uv.x - 0.5) * 2.0 * PI;
    let latitude = (uv.y - 0.5) * PI;
    let (sin, cos) = wide::f32x4::from([latitude, phi, 0.0, 0.0]).sin_cos();
    let ([sin_lat, sin_phi, ..], [cos_lat, cos_phi, ..]) = (sin.to_array(), cos.to_array());
    (
        Vec3::new(cos_lat * cos_phi, sin_lat, cos_lat * sin_phi),
        cos_lat,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::xorshift;

    /// The coordinates of directions all over the sphere are the C library's
    /// angles' to float rounding.
    #[test]
    fn coordinates_are_the_c_librarys() {
        for i in 0..=360 {
            for j in 0..=180 {
                let (phi, theta) = ((i as Float).to_radians(), (j as Float).to_radians());
                let d = Vec3::new(
                    theta.sin() * phi.cos(),
                    theta.cos(),
                    theta.sin() * phi.sin(),
                );
                let uv = direction_to_uv(d);
                let libm = Vec2::new(
                    0.5 + d.z.atan2(d.x) / (2.0 * PI),
                    0.5 + d.y.clamp(-1.0, 1.0).asin() / PI,
                );
                // The seam: both sides name the same texels.
                let du = (uv.x - libm.x).abs();
                let du = du.min((du - 1.0).abs());
                assert!(
                    du < 1e-6 && (uv.y - libm.y).abs() < 1e-6,
                    "{d}: {uv} vs {libm}"
                );
            }
        }
    }

    /// Light sampling's directions are the equirectangular map's to float
    /// rounding, over the whole map, poles and seam included.
    #[test]
    fn sampled_directions_are_the_maps() {
        for i in 0..=256 {
            for j in 0..=128 {
                let uv = Vec2::new(i as Float / 256.0, j as Float / 128.0);
                let (d, cos) = sampled_direction_and_cos(uv);
                let (d0, cos0) = uv_to_direction_and_cos(uv);
                assert!((d - d0).abs().max_element() < 1e-6, "{uv}: {d} vs {d0}");
                assert!((cos - cos0).abs() < 1e-6, "{uv}: {cos} vs {cos0}");
                assert!(cos >= 0.0 && cos0 >= 0.0 || cos.abs() < 1e-6, "{uv}: {cos}");
            }
        }
    }

    fn map(width: u32, height: u32, texel: impl Fn(Vec3) -> Vec3) -> Arc<Texture> {
        let mut texels = Vec::new();
        for y in 0..height {
            for x in 0..width {
                let uv = Vec2::new(
                    (x as Float + 0.5) / width as Float,
                    1.0 - (y as Float + 0.5) / height as Float,
                );
                let c = texel(uv_to_direction(uv));
                texels.extend([c.x, c.y, c.z]);
            }
        }
        Arc::new(Texture::from_f32("map.hdr".into(), width, height, 3, texels).unwrap())
    }

    #[test]
    fn directions_and_coordinates_are_inverse_and_oriented_as_three_js() {
        // +X is the centre of the image, +Z a quarter to the right, +Y the top.
        assert!((direction_to_uv(Vec3::X) - Vec2::new(0.5, 0.5)).length() < 1e-6);
        assert!((direction_to_uv(Vec3::Z) - Vec2::new(0.75, 0.5)).length() < 1e-6);
        assert!((direction_to_uv(Vec3::Y).y - 1.0).abs() < 1e-6);
        for d in [Vec3::new(0.3, -0.4, 0.2), Vec3::new(-0.9, 0.1, -0.3)] {
            let d = d.normalize();
            assert!((uv_to_direction(direction_to_uv(d)) - d).length() < 1e-5);
        }
    }

    #[test]
    fn a_quarter_turn_shows_along_minus_z_what_was_along_plus_x() {
        let texture = map(64, 32, |d| Vec3::new(d.x.max(0.0), d.z.max(0.0), 0.0));
        let turned = Environment::new(&EnvironmentDesc {
            radiance: EnvironmentRadiance::Map(texture.clone()),
            strength: 1.0,
            rotation_degrees: 90.0,
        });
        let still = Environment::new(&EnvironmentDesc {
            radiance: EnvironmentRadiance::Map(texture),
            strength: 1.0,
            rotation_degrees: 0.0,
        });
        assert!((turned.radiance(-Vec3::Z) - still.radiance(Vec3::X)).length() < 1e-5);
    }

    /// A widened studio keeps its power: the integral of its radiance over the
    /// sphere (midpoint quadrature) moves by under 3% for lobes up to 20 degrees, as
    /// a blur's would not move at all, while its peak falls.
    #[test]
    fn a_widened_studio_keeps_its_power() {
        let power = |spread: Float| {
            let (rows, columns) = (720, 1440);
            let mut sum = 0.0f64;
            for row in 0..rows {
                let theta = PI * (row as Float + 0.5) / rows as Float;
                for column in 0..columns {
                    let phi = 2.0 * PI * (column as Float + 0.5) / columns as Float;
                    let d = Vec3::new(
                        theta.sin() * phi.cos(),
                        theta.cos(),
                        theta.sin() * phi.sin(),
                    );
                    sum += f64::from(studio_radiance(d, spread) * theta.sin());
                }
            }
            sum * f64::from(PI / rows as Float * 2.0 * PI / columns as Float)
        };
        let sharp = power(0.0);
        for spread in [0.1, 0.2, 0.35] {
            let widened = power(spread);
            assert!(
                (widened / sharp - 1.0).abs() < 0.03,
                "{spread}: {widened} against {sharp}"
            );
        }
        let key = STUDIO_KEY.normalize();
        assert!(studio_radiance(key, 0.35) < 0.6 * studio_radiance(key, 0.0));
    }

    #[test]
    fn the_studio_key_light_models_a_white_surface() {
        // Irradiance E(n) = integral of L(d) max(0, n.d) over the sphere, by the
        // midpoint rule on a 1024 x 512 grid in (u, v), dw = cos(latitude) du dv
        // 2 pi^2: independent of the sampling code.
        let (nu, nv) = (1024, 512);
        let irradiance_in = |environment: &Environment, n: Vec3| {
            let n = n.normalize();
            let mut sum = 0.0f64;
            for j in 0..nv {
                for i in 0..nu {
                    let uv = Vec2::new(
                        (i as Float + 0.5) / nu as Float,
                        (j as Float + 0.5) / nv as Float,
                    );
                    let d = uv_to_direction(uv);
                    let cos = f64::from(n.dot(d).max(0.0));
                    let latitude = (f64::from(uv.y) - 0.5) * std::f64::consts::PI;
                    let dw = latitude.cos() * 2.0 * std::f64::consts::PI.powi(2) / (nu * nv) as f64;
                    sum += f64::from(environment.radiance(d).x) * cos * dw;
                }
            }
            sum as Float
        };
        // A constant environment of 1 gives pi: the rule is accurate.
        let white = Environment::new(&EnvironmentDesc {
            radiance: EnvironmentRadiance::Constant(Vec3::ONE),
            strength: 1.0,
            rotation_degrees: 0.0,
        });
        let e = irradiance_in(&white, Vec3::new(0.3, 0.5, -0.2));
        assert!((e - PI).abs() < 1e-3 * PI, "{e}");
        let studio = Environment::new(&studio());
        let irradiance = |n: Vec3| irradiance_in(&studio, n);
        let (toward, away) = (irradiance(STUDIO_KEY), irradiance(-STUDIO_KEY));
        assert!(toward / away >= STUDIO_KEY_RATIO, "{toward} / {away}");
        assert!(toward <= STUDIO_KEY_IRRADIANCE, "{toward}");
        let (left, right) = (irradiance(Vec3::NEG_X), irradiance(Vec3::X));
        assert!(left / right >= 2.0, "{left} / {right}");
        // The shadowed side is lit, not black: a tenth of the key side at least.
        assert!(away >= 0.1 * toward, "{away}");
    }

    /// Sixteen map points turned into directions at once (`directions_of`) give
    /// what `sample_direction` gives each, lane by lane and bit for bit (a lane
    /// mixed up or computed otherwise fails), over a turned map, poles included.
    #[test]
    fn sixteen_directions_at_once_are_sample_directions() {
        let environment = Environment::new(&EnvironmentDesc {
            radiance: EnvironmentRadiance::Map(map(64, 32, |d| Vec3::new(1.0 + d.y, 0.5, 2.0))),
            strength: 1.0,
            rotation_degrees: 37.0,
        });
        let mut next = xorshift(0x9E37_79B9_7F4A_7C15);
        for batch in 0..200 {
            let u: [Vec2; 16] = std::array::from_fn(|lane| match (batch, lane) {
                (0, 0) => Vec2::ZERO,
                (0, 1) => Vec2::splat(1.0 - Float::EPSILON / 2.0),
                _ => Vec2::new(next(), next()),
            });
            let samples = u.map(|u| environment.sample_map(u).unwrap());
            let (d, pdf) = environment.directions_of(
                [
                    f32x16::from(samples.map(|s| s.uv.x)),
                    f32x16::from(samples.map(|s| s.uv.y)),
                ],
                f32x16::from(samples.map(|s| s.density)),
            );
            for (lane, &u) in u.iter().enumerate() {
                let expected = environment.sample_direction(u);
                let pdf = pdf.as_array()[lane];
                let got = Vec3::new(
                    d[0].as_array()[lane],
                    d[1].as_array()[lane],
                    d[2].as_array()[lane],
                );
                match expected {
                    Some(e) => {
                        assert_eq!(
                            got.to_array().map(Float::to_bits),
                            e.direction.to_array().map(Float::to_bits),
                            "lane {lane}: {u}"
                        );
                        assert_eq!(pdf.to_bits(), e.pdf.to_bits(), "lane {lane}: {u}");
                    }
                    None => assert!(!(pdf > 0.0 && pdf.is_finite()), "lane {lane}: {u}: {pdf}"),
                }
            }
        }
    }

    #[test]
    fn sampling_follows_the_pdf_and_favours_the_sun() {
        // A dim sky with a bright 2-degree-ish sun.
        let sun = Vec3::new(0.3, 0.8, -0.5).normalize();
        let texture = map(256, 128, |d| {
            if d.dot(sun) > 0.9995 {
                Vec3::splat(5000.0)
            } else {
                Vec3::new(0.2, 0.3, 0.5)
            }
        });
        let env = Environment::new(&EnvironmentDesc {
            radiance: EnvironmentRadiance::Map(texture),
            strength: 1.0,
            rotation_degrees: 37.0,
        });
        // The estimate of the irradiance on an upward plane: its mean over many
        // samples must equal a quadrature, and sampled directions must carry their
        // own pdf.
        let mut next = xorshift(0x2545_F491_4F6C_DD1D);
        // The sun as the rotated environment shows it.
        let seen_sun = env.map_to_world(sun);
        let n = 200_000;
        let mut estimate = 0.0f64;
        let mut toward_sun = 0;
        for _ in 0..n {
            let (d, radiance, pdf) = env.sample(Vec2::new(next(), next())).unwrap();
            assert!(
                (env.pdf(d) - pdf).abs() <= 1e-3 * pdf,
                "{d}: {} vs {pdf}",
                env.pdf(d)
            );
            toward_sun += usize::from(d.dot(seen_sun) > 0.999);
            estimate += f64::from(luminance(radiance) * d.y.max(0.0) / pdf);
        }
        estimate /= n as f64;
        let (nz, nphi) = (2000, 2000);
        let mut quadrature = 0.0f64;
        for i in 0..nz {
            let z = (i as f64 + 0.5) / nz as f64;
            let r = (1.0 - z * z).sqrt();
            for j in 0..nphi {
                let phi = (j as f64 + 0.5) / nphi as f64 * 2.0 * std::f64::consts::PI;
                let d = Vec3::new(
                    (r * phi.cos()) as Float,
                    z as Float,
                    (r * phi.sin()) as Float,
                );
                quadrature += f64::from(luminance(env.radiance(d))) * z;
            }
        }
        quadrature *= 2.0 * std::f64::consts::PI / (nz * nphi) as f64;
        assert!(
            (estimate - quadrature).abs() < 0.02 * quadrature,
            "{estimate} vs {quadrature}"
        );
        // Most of the light is the sun's: so are most samples.
        assert!(toward_sun > n / 2, "{toward_sun} of {n}");
    }

    #[test]
    fn stratified_values_land_on_a_small_light_in_proportion() {
        // A 3-degree sun in a dim sky: a grid of 16 x 16 values, one in each cell of
        // [0, 1)^2, must put as many points on the sun as its share of the density
        // says, give or take the cells the sun's edge crosses (a sampler that
        // scatters neighbouring values over unrelated texels, as an alias table
        // does, gives a binomial count instead). Sampling keeps order too: a greater
        // `u.y` never picks a higher row, nor a greater `u.x` an earlier texel in it.
        let sun = Vec3::new(0.3, 0.6, -0.5).normalize();
        let texture = map(512, 256, |d| {
            Vec3::splat(if d.dot(sun) > 3.0f32.to_radians().cos() {
                200.0
            } else {
                0.2
            })
        });
        let env = Environment::new(&EnvironmentDesc {
            radiance: EnvironmentRadiance::Map(texture),
            strength: 1.0,
            rotation_degrees: 0.0,
        });
        let on_sun = |d: Vec3| d.dot(sun) > 4.5f32.to_radians().cos();
        let (mut hits, mut share) = (0, 0.0f64);
        let n = 32;
        let mut last: Option<Vec2> = None;
        for i in 0..n * n {
            let u = Vec2::new(
                ((i % n) as Float + 0.5) / n as Float,
                ((i / n) as Float + 0.5) / n as Float,
            );
            let sample = env.sample_map(u).unwrap();
            if let Some(previous) = last {
                if i % n == 0 {
                    assert!(sample.uv.y <= previous.y, "{u}: {sample:?}");
                } else {
                    assert!(sample.uv.x >= previous.x, "{u}: {sample:?}");
                }
            }
            last = Some(sample.uv);
            let (d, _, _) = env.sample(u).unwrap();
            hits += usize::from(on_sun(d));
        }
        // The sun's share of the density, by a fine quadrature of `pdf`.
        let m = 2048;
        for i in 0..m * m / 2 {
            let uv = Vec2::new(
                ((i % m) as Float + 0.5) / m as Float,
                ((i / m) as Float + 0.5) / (m / 2) as Float,
            );
            let d = uv_to_direction(uv);
            if on_sun(d) {
                let cos_latitude = ((uv.y - 0.5) * PI).cos();
                share += f64::from(env.pdf(d) * cos_latitude * 2.0 * PI * PI) / (m * m / 2) as f64;
            }
        }
        let expected = share * (n * n) as f64;
        assert!(
            (hits as f64 - expected).abs() <= 3.0,
            "{hits} of {} points on the sun, {expected:.1} expected",
            n * n
        );
    }

    #[test]
    fn sampled_texels_follow_the_pdf() {
        // Chi-square of how often samples land in each texel of a small map against
        // the pdf integrated over the texel by the midpoint rule on an 8 x 8 grid:
        // what `pdf` says, not how `sample` picks. A sun, a gradient, and a black
        // band below the horizon that must never be sampled.
        let (width, height) = (24u32, 12u32);
        let sun = Vec3::new(-0.4, 0.5, 0.6).normalize();
        let texture = map(width, height, |d| {
            if d.y < -0.4 {
                Vec3::ZERO
            } else {
                Vec3::splat(0.05 + 0.2 * (d.x + 1.0) + 40.0 * d.dot(sun).max(0.0).powi(16))
            }
        });
        let env = Environment::new(&EnvironmentDesc {
            radiance: EnvironmentRadiance::Map(texture),
            strength: 1.0,
            rotation_degrees: 0.0,
        });
        let texels = (width * height) as usize;
        let cell = |d: Vec3| {
            let uv = direction_to_uv(d);
            let x = ((uv.x * width as Float) as usize).min(width as usize - 1);
            let y = (((1.0 - uv.y) * height as Float) as usize).min(height as usize - 1);
            y * width as usize + x
        };
        let mut expected = vec![0.0f64; texels];
        let sub = 8;
        for (i, e) in expected.iter_mut().enumerate() {
            let (x, y) = (i % width as usize, i / width as usize);
            for j in 0..sub * sub {
                let uv = Vec2::new(
                    (x as Float + ((j % sub) as Float + 0.5) / sub as Float) / width as Float,
                    1.0 - (y as Float + ((j / sub) as Float + 0.5) / sub as Float)
                        / height as Float,
                );
                let d = uv_to_direction(uv);
                let dw = (uv.y - 0.5) * PI;
                *e += f64::from(env.pdf(d) * dw.cos() * 2.0 * PI * PI)
                    / f64::from(width * height)
                    / (sub * sub) as f64;
            }
        }
        let total: f64 = expected.iter().sum();
        assert!((total - 1.0).abs() < 1e-3, "the pdf integrates to {total}");
        let mut next = xorshift(0x9E37_79B9_7F4A_7C15);
        let n = 200_000;
        let mut counts = vec![0u32; texels];
        for _ in 0..n {
            let (d, _, pdf) = env.sample(Vec2::new(next(), next())).unwrap();
            assert!(pdf > 0.0);
            counts[cell(d)] += 1;
        }
        let (mut chi2, mut dof) = (0.0f64, 0);
        let (mut rare_seen, mut rare_expected) = (0u32, 0.0f64);
        for (&seen, &p) in counts.iter().zip(&expected) {
            let e = p * n as f64;
            if p == 0.0 {
                assert_eq!(seen, 0, "a texel of density 0 was sampled");
            } else if e < 5.0 {
                rare_seen += seen;
                rare_expected += e;
            } else {
                chi2 += (f64::from(seen) - e).powi(2) / e;
                dof += 1;
            }
        }
        if rare_expected > 0.0 {
            chi2 += (f64::from(rare_seen) - rare_expected).powi(2) / rare_expected.max(1.0);
            dof += 1;
        }
        // Five standard deviations above the chi-square's mean: a right sampler
        // fails with probability below 1e-6, a wrong one by far.
        let bound = f64::from(dof) + 5.0 * (2.0 * f64::from(dof)).sqrt();
        assert!(dof > 100, "{dof} cells");
        assert!(
            chi2 < bound,
            "chi-square {chi2} over {dof} cells (bound {bound})"
        );
    }
}
