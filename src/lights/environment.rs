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

use crate::math::{Float, Vec2, Vec3};
use crate::textures::{Encoding, Texture, Wrap};

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
    radiance: EnvironmentRadiance,
    strength: Float,
    /// Sine and cosine of the rotation.
    rotation: (Float, Float),
    /// For an image: the cumulative distribution of its rows (`height + 1` values
    /// from 0 to 1) and of the texels within each row (`height * (width + 1)`).
    rows: Vec<Float>,
    columns: Vec<Float>,
    /// Sum of texel weights over texel count: the density in `(u, v)` of texel
    /// `(x, y)` is its weight over this.
    mean_weight: Float,
    /// Mean radiance over the sphere, for weighing the environment against other
    /// lights.
    mean_radiance: Float,
}

/// How an image's texels are read: 8-bit images (PNG, JPEG) as sRGB, floating
/// point ones (HDR, EXR) as linear.
#[inline]
fn encoding(texture: &Texture) -> Encoding {
    if texture.is_8bit() {
        Encoding::Srgb
    } else {
        Encoding::Linear
    }
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
        let mut environment = Environment {
            radiance: desc.radiance.clone(),
            strength,
            rotation,
            rows: Vec::new(),
            columns: Vec::new(),
            mean_weight: 0.0,
            mean_radiance: 0.0,
        };
        match &desc.radiance {
            EnvironmentRadiance::Constant(c) => {
                environment.mean_radiance = luminance(c.max(Vec3::ZERO)) * strength;
            }
            EnvironmentRadiance::Map(texture) => environment.tabulate(texture),
        }
        environment
    }

    /// The cumulative distributions of texel weights: the greatest luminance of the
    /// texel and its eight neighbours (bilinear filtering spreads each texel's value
    /// over its neighbours' cells: a density following the texel alone would leave a
    /// sun's fringe to rare samples of huge weight), times `sin` of the polar angle of
    /// the texel's centre row.
    fn tabulate(&mut self, texture: &Texture) {
        let (width, height) = texture.size();
        let (w, h) = (width as usize, height as usize);
        let mut luminances = Vec::with_capacity(w * h);
        let mut radiance_sum = 0.0f64;
        for y in 0..h {
            let v = 1.0 - (y as Float + 0.5) / height as Float;
            let sin_polar = f64::from((PI * v).sin());
            for x in 0..w {
                let u = (x as Float + 0.5) / width as Float;
                let texel = texture.bilinear(
                    Vec2::new(u, v),
                    Wrap::Repeat,
                    Wrap::Clamp,
                    encoding(texture),
                );
                let l = luminance(Vec3::new(texel[0], texel[1], texel[2]));
                // NaN and negative texels weigh nothing (the reader warns of them).
                let l = if l.is_finite() && l > 0.0 { l } else { 0.0 };
                radiance_sum += f64::from(l) * sin_polar;
                luminances.push(l);
            }
        }
        self.columns = Vec::with_capacity(h * (w + 1));
        self.rows = Vec::with_capacity(h + 1);
        self.rows.push(0.0);
        let mut total = 0.0f64;
        for y in 0..h {
            let v = 1.0 - (y as Float + 0.5) / height as Float;
            let sin_polar = f64::from((PI * v).sin());
            let mut row = 0.0f64;
            self.columns.push(0.0);
            for x in 0..w {
                let mut greatest: Float = 0.0;
                for ny in y.saturating_sub(1)..(y + 2).min(h) {
                    for dx in [w - 1, 0, 1] {
                        greatest = greatest.max(luminances[ny * w + (x + dx) % w]);
                    }
                }
                row += f64::from(greatest) * sin_polar;
                self.columns.push(row as Float);
            }
            let start = self.columns.len() - (w + 1);
            if row > 0.0 {
                for c in &mut self.columns[start..] {
                    *c = (f64::from(*c) / row) as Float;
                }
            } else {
                // A black row: uniform, though it is never picked.
                for (i, c) in self.columns[start..].iter_mut().enumerate() {
                    *c = i as Float / w as Float;
                }
            }
            total += row;
            self.rows.push(total as Float);
        }
        if total > 0.0 {
            for r in &mut self.rows {
                *r = (f64::from(*r) / total) as Float;
            }
        }
        self.mean_weight = (total / (w * h) as f64) as Float;
        // The mean over the sphere of luminance: the sum of luminance times solid
        // angle (2 pi^2 sin / (w h) per texel) over 4 pi.
        self.mean_radiance =
            (radiance_sum * std::f64::consts::PI / (2.0 * (w * h) as f64)) as Float * self.strength;
    }

    /// Whether the radiance is the same from every direction.
    pub fn is_constant(&self) -> bool {
        matches!(self.radiance, EnvironmentRadiance::Constant(_))
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
        match &self.radiance {
            EnvironmentRadiance::Constant(c) => *c * self.strength,
            EnvironmentRadiance::Map(texture) => {
                let uv = direction_to_uv(self.world_to_map(d));
                let [r, g, b, _] =
                    texture.bilinear(uv, Wrap::Repeat, Wrap::Clamp, encoding(texture));
                // NaN and negative texels emit nothing, infinite ones the most a
                // float holds.
                Vec3::new(r, g, b)
                    .max(Vec3::ZERO)
                    .min(Vec3::splat(Float::MAX))
                    * self.strength
            }
        }
    }

    /// A direction towards the environment by `u`, its radiance and its density in
    /// solid angle; `None` for a black environment.
    #[inline]
    pub fn sample(&self, u: Vec2) -> Option<(Vec3, Vec3, Float)> {
        let texture = match &self.radiance {
            EnvironmentRadiance::Constant(c) => {
                if *c == Vec3::ZERO || self.strength == 0.0 {
                    return None;
                }
                // Uniform over the sphere.
                let z = 1.0 - 2.0 * u.x;
                let r = (1.0 - z * z).max(0.0).sqrt();
                let phi = 2.0 * PI * u.y;
                let d = Vec3::new(r * phi.cos(), r * phi.sin(), z);
                return Some((d, *c * self.strength, 0.25 * FRAC_1_PI));
            }
            EnvironmentRadiance::Map(texture) => texture,
        };
        if self.mean_weight <= 0.0 {
            return None;
        }
        let (width, height) = texture.size();
        let w = width as usize;
        let (y, fy) = pick(&self.rows, u.y);
        let (x, fx) = pick(&self.columns[y * (w + 1)..(y + 1) * (w + 1)], u.x);
        let uv = Vec2::new(
            (x as Float + fx) / width as Float,
            1.0 - (y as Float + fy) / height as Float,
        );
        let d = self.map_to_world(uv_to_direction(uv));
        let pdf = self.pdf(d);
        (pdf > 0.0).then(|| (d, self.radiance(d), pdf))
    }

    /// The density in solid angle with which [`Environment::sample`] picks `d`.
    #[inline]
    pub fn pdf(&self, d: Vec3) -> Float {
        let texture = match &self.radiance {
            EnvironmentRadiance::Constant(c) => {
                return if *c == Vec3::ZERO || self.strength == 0.0 {
                    0.0
                } else {
                    0.25 * FRAC_1_PI
                };
            }
            EnvironmentRadiance::Map(texture) => texture,
        };
        if self.mean_weight <= 0.0 {
            return 0.0;
        }
        let (width, height) = texture.size();
        let (w, h) = (width as usize, height as usize);
        let uv = direction_to_uv(self.world_to_map(d));
        let x = ((uv.x * width as Float) as usize).min(w - 1);
        let y = (((1.0 - uv.y) * height as Float) as usize).min(h - 1);
        let row = &self.columns[y * (w + 1)..(y + 1) * (w + 1)];
        let row_probability = self.rows[y + 1] - self.rows[y];
        let texel_probability = row_probability * (row[x + 1] - row[x]);
        // Density in (u, v), then per solid angle: dw = 2 pi^2 sin(polar) du dv.
        let density_uv = texel_probability * (w * h) as Float;
        // sin(polar) = cos(latitude), from x and z: accurate near the poles, where
        // 1 - y^2 rounds to 0.
        let sin_polar = (d.x * d.x + d.z * d.z).sqrt();
        if sin_polar <= 0.0 {
            return 0.0;
        }
        density_uv / (2.0 * PI * PI * sin_polar)
    }
}

/// The index `i` with `cdf[i] <= u < cdf[i + 1]`, and where `u` lies between them.
#[inline]
fn pick(cdf: &[Float], u: Float) -> (usize, Float) {
    let n = cdf.len() - 1;
    // The first entry greater than u, less one; never an empty bin of zero width.
    let mut i = cdf.partition_point(|&c| c <= u).clamp(1, n) - 1;
    while i + 1 < n && cdf[i + 1] <= cdf[i] {
        i += 1;
    }
    let width = cdf[i + 1] - cdf[i];
    let f = if width > 0.0 {
        ((u - cdf[i]) / width).clamp(0.0, 0.999_999)
    } else {
        0.5
    };
    (i, f)
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
    let soft_box = |d: Vec3, centre: Vec3, radius_degrees: Float| {
        let inner = radius_degrees.to_radians().cos();
        let outer = (radius_degrees * 1.4).to_radians().cos();
        let t = ((d.dot(centre.normalize()) - outer) / (inner - outer)).clamp(0.0, 1.0);
        t * t * (3.0 - 2.0 * t)
    };
    let mut texels = Vec::with_capacity((width * height * 3) as usize);
    for row in 0..height {
        let v = 1.0 - (row as Float + 0.5) / height as Float;
        for column in 0..width {
            let u = (column as Float + 0.5) / width as Float;
            let d = uv_to_direction(Vec2::new(u, v));
            let t = ((d.y + 0.3) / 0.9).clamp(0.0, 1.0);
            let dome = 0.12 + 0.25 * t * t * (3.0 - 2.0 * t);
            let light = 5.0 * soft_box(d, STUDIO_KEY, 22.0)
                + 0.9 * soft_box(d, Vec3::new(0.75, 0.3, 0.45), 16.0)
                + 0.4 * soft_box(d, Vec3::Y, 25.0);
            let c = dome + light;
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

/// The equirectangular coordinates of the unit direction `d`.
#[inline]
pub fn direction_to_uv(d: Vec3) -> Vec2 {
    Vec2::new(
        0.5 + d.z.atan2(d.x) / (2.0 * PI),
        0.5 + d.y.clamp(-1.0, 1.0).asin() / PI,
    )
}

/// The unit direction at equirectangular coordinates `uv`.
#[inline]
pub fn uv_to_direction(uv: Vec2) -> Vec3 {
    let phi = (uv.x - 0.5) * 2.0 * PI;
    let latitude = (uv.y - 0.5) * PI;
    let (sin_lat, cos_lat) = latitude.sin_cos();
    Vec3::new(cos_lat * phi.cos(), sin_lat, cos_lat * phi.sin())
}

#[cfg(test)]
mod tests {
    use super::*;

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
        let mut state = 0x2545_F491_4F6C_DD1Du64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 40) as Float / (1u64 << 24) as Float
        };
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
}
